"""Nav2 ``map_server`` maps (a YAML file and its image) read as nav2 reads them, and their
occupied cells merged into boxes: the static geometry that bodies collide with and lasers
see.

The YAML keys and the image's cells follow nav2_map_server's ``map_io``:

- ``image`` (a path relative to the YAML file's directory unless absolute), ``resolution``
  (m per cell), ``origin`` [x, y, yaw] (the pose of the lower-left corner of the map's
  cell (0, 0) in the fixed frame), ``occupied_thresh``, ``free_thresh`` and ``negate``
  (0/1 or a boolean) are required; ``mode`` is ``trinary`` (the default), ``scale`` or
  ``raw``;
- a pixel's grey is what GraphicsMagick (Q16, through which nav2 reads images) gives for
  it: samples as 16-bit quantums (an 8-bit sample v is ``257 v``), a colour's Rec. 601
  luma ``0.299 R + 0.587 G + 0.114 B`` (float32 tables, rounded), cut to 8 bits by whole
  division by 257 (not the channels' mean, as nav2 read them up to 1.3.6);
  its occupancy is ``1 - grey / 255`` (``grey / 255`` when ``negate``), in float32;
- trinary: 100 (occupied) when ``occupancy >= occupied_thresh``, else 0 (free) when
  ``occupancy <= free_thresh``, else -1 (unknown); scale: the same, but the cells between
  the thresholds get ``round((occupancy - free) / (occupied - free) * 100)`` (float32, half
  away from zero); in both, a pixel whose alpha is below 255 is unknown; raw: the grey
  itself when it is 0..100, else unknown, whatever the alpha;
- image row 0 is the map's top: ``OccupancyGrid`` row ``height - 1 - y`` holds image row
  ``y``.

Cells of value 100 are walls of the world. :func:`cell_boxes` merges them into rectangles:
each grid row's runs of occupied cells, a run extended upwards while the next row has the
same run. Every occupied cell lies in exactly one box, and the order is fixed by the grid
alone (by bottom row, then left column).

Images: PGM (P2 any maxval, P5 any but 1, whose bytes GraphicsMagick reads as bits; a
maxval other than 255 or 65535 scaled as GraphicsMagick 1.3 scales it, see
:func:`_pgm_quantums`) and 8-bit non-interlaced PNG (grey, grey and alpha,
RGB, RGBA, palette, and ``tRNS`` transparency), the formats ``map_saver`` writes.

These are nav2_map_server's rules since 1.3.7 (jazzy's ``map_io.cpp`` at 1.3.13, Eigen
masks over GraphicsMagick's grey), checked cell for cell against that code built on
GraphicsMagick 1.3.40 Q16.
"""
from __future__ import annotations

import math
import re
import struct
import sys
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .parameters import SceneError, number_text

__all__ = ["MAP_MODES", "OCCUPIED", "FREE", "UNKNOWN", "MAX_CELLS", "OccupancyMap",
           "MAX_EXTENT", "MapSpec", "read_map", "occupancy", "cell_boxes"]

MAP_MODES = ("trinary", "scale", "raw")
OCCUPIED, FREE, UNKNOWN = 100, 0, -1
#: The most cells a map image may hold (8192 x 8192, 410 m square at 5 cm a cell): reading
#: one takes up to some 100 bytes a cell (an RGBA PNG's channels as 64-bit integers and
#: floats), 6.7 GB here.
#: The header's size is checked before any pixel is read, so a small file claiming a huge
#: image (a PNG's pixels compress a thousandfold) is refused without the memory.
MAX_CELLS = 8192 * 8192


@dataclass(frozen=True)
class OccupancyMap:
    """A map as ``nav_msgs/OccupancyGrid`` holds it, and its occupied cells as boxes.

    ``data``: width x height cells, row-major from the bottom row (int8 values as bytes);
    ``boxes``: rectangles of occupied cells (column, row of the first cell; column, row
    past the last), see :func:`cell_boxes`."""

    resolution: float
    origin: tuple[float, float, float]
    width: int
    height: int
    data: bytes
    boxes: tuple[tuple[int, int, int, int], ...]

    def cells(self) -> np.ndarray:
        """The cell values (height, width), int8, row 0 the map's bottom."""
        return np.frombuffer(self.data, dtype=np.int8).reshape(self.height, self.width)

    def corner(self, column: float, row: float) -> tuple[float, float]:
        """The fixed-frame point at (column, row) in cell units from the origin's corner."""
        x, y, yaw = self.origin
        u, v = column * self.resolution, row * self.resolution
        c, s = math.cos(yaw), math.sin(yaw)
        return x + c * u - s * v, y + s * u + c * v

    def box_vertices(self) -> np.ndarray:
        """Each box's corners (B, 4, 2) in the fixed frame, counter-clockwise."""
        return np.array([[self.corner(i0, j0), self.corner(i1, j0), self.corner(i1, j1),
                          self.corner(i0, j1)] for i0, j0, i1, j1 in self.boxes],
                        dtype=float).reshape(-1, 4, 2)


@dataclass(frozen=True)
class MapSpec:
    """A scene's map: its cells, and the bodies that collide with its boxes."""

    file: str
    occupancy: OccupancyMap
    restitution: float
    friction: float
    bodies: tuple[str, ...]


def _fail(source: str, problem: str) -> SceneError:
    return SceneError(f"{source}: {problem}")


def _number(document: dict[str, Any], key: str, source: str) -> float:
    if key not in document:
        raise _fail(source, f"missing '{key}'")
    value = document[key]
    if isinstance(value, str) and _DECIMAL.fullmatch(value.strip()):
        raise _fail(source, f"'{key}' is read as the string {value!r}: {_as_number(value)}")
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(value):
        raise _fail(source, f"'{key}' must be a finite number, not {value!r}")
    return float(value)


#: A decimal number as C's strtod reads it (nav2's yaml-cpp too), which YAML 1.1 may take
#: for text: ``1e-3`` (an exponent without a dot), or any number quoted.
_DECIMAL = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


class _MapLoader(yaml.SafeLoader):  # type: ignore[misc]  # PyYAML has no type hints
    """PyYAML's safe loader, except that a whole number YAML 1.1 reads otherwise than as its
    decimal digits (octal ``010``, hex ``0x10``, ``1_000``, ``1:30``) stays text: nav2 reads
    the file with yaml-cpp, which takes ``010`` for 10 where YAML 1.1 takes 8, and fails on
    the others, so :func:`_number` refuses them with a spelling that both read alike."""


def _plain_int(loader: Any, node: Any) -> Any:
    text, value = loader.construct_scalar(node), loader.construct_yaml_int(node)
    if re.fullmatch(r"[-+]?[0-9]+", text) and int(text, 10) == value:  # 07 is 7 to both
        return value
    return text


_MapLoader.add_constructor("tag:yaml.org,2002:int", _plain_int)


def _as_number(text: str) -> str:
    """How to write ``text`` so that YAML 1.1 reads the number strtod reads in it."""
    plain = text.strip()
    read = yaml.safe_load(plain)
    if not isinstance(read, str) and read == float(plain):  # it was quoted
        return "a quoted number is text in YAML; write it unquoted"
    # YAML 1.1 takes an exponent only after a dot and with its sign (1e-3 and 1.0e3 are
    # text), and a whole number with a leading 0 for octal (010 is 8) or text (08).
    mantissa, e, exponent = plain.replace("E", "e").partition("e")
    if "." not in mantissa:
        mantissa += ".0"
    if not e:
        return (f"YAML 1.1 reads a whole number with a leading 0 as octal or text; "
                f"write {mantissa}")
    if exponent[:1] not in ("+", "-"):
        exponent = "+" + exponent
    return (f"YAML 1.1 reads an exponent as a number only after a dot and with its sign; "
            f"write {mantissa}e{exponent}")


def _check_regular(path: Path, what: str) -> None:
    """Refuse a device or a pipe (``/dev/zero``, a FIFO), whose reading never ends; a
    missing file is left to the reader's error."""
    if path.exists() and not path.is_file():
        raise _fail(str(path), f"cannot read the {what} (a folder, device or pipe, not a "
                               "regular file)")


def read_map(path: Path) -> OccupancyMap:
    """The map of a nav2 map YAML file; :class:`SceneError` (one line) if it is missing or
    bad."""
    source = str(path)
    _check_regular(path, "map file")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        reason = getattr(error, "strerror", None) or error
        raise _fail(source, f"cannot read the map file ({reason})") from None
    try:
        document = yaml.load(text, Loader=_MapLoader)  # noqa: S506 (a safe loader)
    except yaml.YAMLError as error:
        raise _fail(source, f"not YAML ({' '.join(str(error).split())})") from None
    if not isinstance(document, dict):
        raise _fail(source, "expected a mapping of nav2 map keys (image, resolution, ...)")
    image = document.get("image")
    if not isinstance(image, str) or not image:
        raise _fail(source, "'image' must name the map's image file")
    resolution = _number(document, "resolution", source)
    if resolution <= 0.0:
        raise _fail(source, f"'resolution' must be positive, not {resolution}")
    origin = document.get("origin")
    if not isinstance(origin, list) or len(origin) != 3:
        raise _fail(source, f"'origin' must be [x, y, yaw], not {origin!r}")
    ox, oy, yaw = (_number({"origin": v}, "origin", source) for v in origin)
    occupied = _number(document, "occupied_thresh", source)
    free = _number(document, "free_thresh", source)
    mode = document.get("mode", "trinary")
    if mode not in MAP_MODES:
        raise _fail(source, f"'mode' must be one of {', '.join(MAP_MODES)}, not {mode!r}")
    # nav2's loader takes any thresholds without a word, but its map_saver refuses all but
    # 0 <= free < occupied <= 1, and its loaders disagree outside them (jazzy's since 1.3.7
    # lets free override occupied): 65 for 0.65 would make a map of no walls.
    if mode != "raw" and not 0.0 <= free < occupied <= 1.0:
        raise _fail(source, f"'free_thresh' {number_text(free)} and 'occupied_thresh' "
                            f"{number_text(occupied)} must be fractions with 0 <= free_thresh "
                            f"< occupied_thresh <= 1 in {mode} mode")
    negate = document.get("negate")
    if negate not in (0, 1) or isinstance(negate, float):
        raise _fail(source, f"'negate' must be 0, 1, true or false, not {negate!r}")
    image_path = path.parent / image
    grey, alpha = read_image(image_path)
    cells = occupancy(grey, alpha, mode=mode, negate=bool(negate),
                      occupied_thresh=occupied, free_thresh=free)
    grid = np.ascontiguousarray(cells[::-1])  # image row 0 is the map's top
    grid_map = OccupancyMap(resolution, (ox, oy, yaw), grid.shape[1], grid.shape[0],
                            grid.tobytes(), cell_boxes(grid == OCCUPIED))
    _check_extent(grid_map, source)
    return grid_map


#: Largest coordinate of a map's corner (m): a box's centre is the mean of its four
#: corners (the laser's and the contact pass's fixed bodies), whose sum must be a double.
MAX_EXTENT = sys.float_info.max / 4.0


def _check_extent(grid_map: OccupancyMap, source: str) -> None:
    """Refuse a map whose corners lie past :data:`MAX_EXTENT` (a huge ``resolution`` or
    ``origin``): its boxes' centres would be infinite, their corners and rays NaN."""
    corners = [grid_map.corner(column, row) for column in (0, grid_map.width)
               for row in (0, grid_map.height)]
    if not all(abs(value) <= MAX_EXTENT for corner in corners for value in corner):
        x, y, yaw = grid_map.origin
        raise _fail(source, f"'resolution' {number_text(grid_map.resolution)} over "
                            f"{grid_map.width} x {grid_map.height} cells from 'origin' "
                            f"[{number_text(x)}, {number_text(y)}, {number_text(yaw)}] puts "
                            f"the map's corners past {MAX_EXTENT:.4g} m, where its boxes' "
                            f"centres are no doubles")


def occupancy(grey: np.ndarray, alpha: np.ndarray | None, *, mode: str, negate: bool,
              occupied_thresh: float, free_thresh: float) -> np.ndarray:
    """nav2's cell values (int8, image rows) of an image's ``grey`` levels and ``alpha``
    (uint8, None: no alpha channel), see :func:`read_image`."""
    if mode == "raw":  # nav2 casts the grey to int8: 101..255 fall outside 0..100
        return np.where(grey <= OCCUPIED, grey, UNKNOWN).astype(np.int8)
    # nav2 computes in float32, the thresholds cast to it: the >= and <= edges are float32's.
    shade = grey.astype(np.float32) / np.float32(255.0)
    occupied = shade if negate else np.float32(1.0) - shade
    occupied_edge, free_edge = np.float32(occupied_thresh), np.float32(free_thresh)
    cells = np.full(grey.shape, UNKNOWN, dtype=np.int8)
    cells[occupied >= occupied_edge] = OCCUPIED
    cells[occupied <= free_edge] = FREE  # after occupied, as nav2 applies them
    if mode == "scale":
        between = (occupied > free_edge) & (occupied < occupied_edge)
        scaled = (occupied - free_edge) / np.float32(occupied_thresh - free_thresh) \
            * np.float32(100.0)
        # std::round, half away from zero: exact in float64 for these positive float32s
        cells[between] = np.floor(scaled[between].astype(np.float64) + 0.5)
    if alpha is not None:
        cells[alpha < 255] = UNKNOWN
    return cells


def cell_boxes(occupied: np.ndarray) -> tuple[tuple[int, int, int, int], ...]:
    """Rectangles (column, row, column past, row past) covering the True cells of
    ``occupied`` (rows, columns) exactly once: each row's runs, a run carried up while the
    row above has the same run; sorted by first row, then first column."""
    rows, columns = occupied.shape
    boxes: list[tuple[int, int, int, int]] = []
    open_runs: dict[tuple[int, int], int] = {}  # run (first, past) -> its first row
    for row in range(rows + 1):
        runs: list[tuple[int, int]] = []
        if row < rows:
            edges = np.flatnonzero(np.diff(np.concatenate(
                ([0], occupied[row].astype(np.int8), [0]))))
            runs = [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])]
        carried = {run: open_runs.pop(run, row) for run in runs}
        boxes.extend((first, start, past, row) for (first, past), start in open_runs.items())
        open_runs = carried
    return tuple(sorted(boxes, key=lambda box: (box[1], box[0])))


# ----------------------------------------------------------------------------- images

#: GraphicsMagick's largest quantum (Q16, as Debian and Ubuntu build it): nav2 reads an
#: image's samples on this scale, an 8-bit sample v as ``257 v``.
QUANTUM = 65535


def read_image(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """An image's grey levels and alpha (uint8, rows x columns; alpha None when the image
    has none) as nav2's map_io takes them from GraphicsMagick; :class:`SceneError` if it
    cannot be read."""
    _check_regular(path, "map image")
    try:
        raw = path.read_bytes()
    except OSError as error:
        raise _fail(str(path), f"cannot read the map image ({error.strerror})") from None
    if raw[:8] != b"\x89PNG\r\n\x1a\n" and raw[:2] not in (b"P2", b"P5"):
        raise _fail(str(path), "the map image must be a PGM (P2, P5) or PNG file")
    try:
        if raw[:2] in (b"P2", b"P5"):
            quantums, alpha = _read_pgm(raw)[..., None], None
        else:
            quantums, alpha = _read_png(raw)
    except (ValueError, IndexError, zlib.error, struct.error) as error:
        raise _fail(str(path), f"bad map image ({error})") from None
    return grey_levels(quantums), None if alpha is None else (alpha // 257).astype(np.uint8)


def grey_levels(quantums: np.ndarray) -> np.ndarray:
    """GraphicsMagick's 8-bit grey of Q16 samples (rows, columns, 1 grey or 3 RGB), as nav2
    takes it (``type(GrayscaleType)``, then the ``I`` channel as chars). A colour image's
    quantums become their Rec. 601 luma, GraphicsMagick's tables in float32 (``0.299f *
    R``, ``0.587f * G``, ``0.114f * B``, summed in float32) rounded half up; a grey image's
    stay; the quantum is then cut to a char by whole division by 257."""
    if quantums.shape[2] == 1:
        luma = quantums[..., 0]
    else:
        samples = quantums.astype(np.float32)
        total = np.float32(0.299) * samples[..., 0] + np.float32(0.587) * samples[..., 1] \
            + np.float32(0.114) * samples[..., 2]
        luma = np.minimum(np.floor(total.astype(np.float64) + 0.5), QUANTUM).astype(np.int64)
    return (luma // 257).astype(np.uint8)


def _read_pgm(raw: bytes) -> np.ndarray:
    # Whitespace ends the magic number (the format's rule): 'P58 6 255' is no PGM of width 8.
    if not (raw[2:3].isspace() or raw[2:3] == b"#"):
        raise ValueError(f"PGM magic number {raw[:2].decode()} is not followed by whitespace")
    numbers: list[int] = []
    at = 2
    for what in ("width", "height", "maxval"):  # '#' starts a comment to the line end
        while raw[at:at + 1].isspace() or raw[at:at + 1] == b"#":
            if raw[at:at + 1] == b"#":
                newline = raw.find(b"\n", at)
                at = len(raw) if newline < 0 else newline  # a comment to the file's end
            at += 1
        end = at
        while end < len(raw) and not (raw[end:end + 1].isspace() or raw[end:end + 1] == b"#"):
            end += 1
        numbers.append(_pgm_number(raw[at:end], what))
        at = end
    if raw[at:at + 1] == b"#":  # one whitespace character parts the maxval from the pixels
        raise ValueError("PGM maxval followed by a comment, not by one whitespace character")
    width, height, maxval = numbers
    if not (width > 0 and height > 0 and 0 < maxval < 65536):
        raise ValueError(f"PGM size {width} x {height}, maxval {maxval}")
    _check_size("PGM", width, height)
    if raw[:2] == b"P5" and maxval == 1:
        raise ValueError("P5 PGM of maxval 1, whose bytes GraphicsMagick (so nav2) reads as "
                         "bits; write maxval 255")
    count = width * height
    if raw[:2] == b"P5":
        dtype = np.dtype(np.uint8) if maxval < 256 else np.dtype(">u2")
        body = raw[at + 1:at + 1 + count * dtype.itemsize]
        if len(body) < count * dtype.itemsize:
            raise ValueError("PGM pixels cut short")
        values = np.frombuffer(body, dtype=dtype).astype(float)
    else:
        values = np.array(raw[at:].split()[:count], dtype=float)
        if len(values) < count:
            raise ValueError("PGM pixels cut short")
        odd = values[(values < 0) | (values != np.floor(values))]
        if odd.size:
            raise ValueError(f"PGM pixel {odd[0]:g} is not a whole number from 0 to {maxval}")
    if values.max() > maxval:  # a shade past white: no image of that maxval holds it
        raise ValueError(f"PGM pixel {values.max():g} is above its maxval {maxval}")
    return _pgm_quantums(values.astype(np.int64), maxval, raw[:2] == b"P5") \
        .reshape(height, width)


def _pgm_quantums(values: np.ndarray, maxval: int, binary: bool) -> np.ndarray:
    """GraphicsMagick 1.3's Q16 levels of PGM samples (its ``pnm`` coder). An image of at
    least ``maxval`` cells is read as a palette of ``maxval + 1`` greys, level i at
    ``i * (65535 // maxval)``; a smaller one at ``round(65535 i / maxval)`` (P2) or its
    sample scaled to 16 bits (P5). P5 levels are then stretched by ``65535 / top``, ``top``
    being maxval's rounded share of 65535 (a palette level twice: maxval 4 reads 1 as
    white). maxval 255 and 65535 read every sample as itself on 16 bits."""
    if values.size >= maxval:
        levels = values * (QUANTUM // maxval)
    elif binary:
        levels = values * (257 if maxval < 256 else 1)
    else:
        levels = np.floor(QUANTUM * values / maxval + 0.5).astype(np.int64)
    if binary:
        top = math.floor(QUANTUM * maxval / (255 if maxval < 256 else QUANTUM) + 0.5)
        if top != QUANTUM:
            stretched = np.floor(QUANTUM / top * levels + 0.5)
            levels = np.minimum(stretched, QUANTUM).astype(np.int64)
    return levels


def _check_size(kind: str, width: int, height: int) -> None:
    if width * height > MAX_CELLS:
        raise ValueError(f"{kind} of {width} x {height} pixels, more than the "
                         f"{MAX_CELLS:,} cells a map may hold")


def _pgm_number(token: bytes, what: str) -> int:
    """A number of a PGM header: ASCII digits only (``int`` would also take a sign, an
    underscore or other scripts' digits, which no PGM writer writes)."""
    if not token:
        raise ValueError(f"PGM header cut short before its {what}")
    if not (token.isdigit() and token.isascii()):
        raise ValueError(f"PGM {what} {token.decode(errors='replace')!r} is not a whole number")
    return int(token)


_PNG_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}
_PNG_CRITICAL = (b"IHDR", b"PLTE", b"IDAT", b"IEND")


def _read_png(raw: bytes) -> tuple[np.ndarray, np.ndarray | None]:
    at, header, palette, transparency, data = 8, b"", b"", b"", []
    while at < len(raw):
        length, kind = struct.unpack(">I4s", raw[at:at + 8])
        chunk = raw[at + 8:at + 8 + length]
        crc = raw[at + 8 + length:at + 12 + length]
        at += 12 + length
        name = kind.decode("ascii", errors="replace")
        if len(crc) < 4:
            raise ValueError(f"PNG cut short in its {name} chunk")
        # A critical chunk whose CRC fails is a damaged file, which libpng (and so nav2's
        # map_server) refuses: a changed palette byte would be a map of other cells.
        if kind in _PNG_CRITICAL and struct.unpack(">I", crc)[0] != zlib.crc32(kind + chunk):
            raise ValueError(f"PNG {name} chunk fails its CRC check (a damaged file)")
        if kind == b"IHDR":
            header = chunk
        elif kind == b"PLTE":
            palette = chunk
        elif kind == b"tRNS":
            transparency = chunk
        elif kind == b"IDAT":
            data.append(chunk)
        elif kind == b"IEND":
            break
    width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", header)
    if depth != 8 or colour not in _PNG_CHANNELS or interlace:
        raise ValueError(f"PNG of bit depth {depth}, colour type {colour}, interlace "
                         f"{interlace}; only 8-bit non-interlaced images are read")
    if not (width > 0 and height > 0):
        raise ValueError(f"PNG size {width} x {height}")
    _check_size("PNG", width, height)
    k = _PNG_CHANNELS[colour]
    stride = width * k
    size = height * (stride + 1)
    # Never inflate past the size the header gives: a byte more tells too much data.
    inflate = zlib.decompressobj()
    packed = inflate.decompress(b"".join(data), size + 1)
    if len(packed) != size or not inflate.eof:
        raise ValueError("PNG pixel data of the wrong size")
    pixels = np.zeros((height, stride), dtype=np.uint8)
    previous = np.zeros(stride, dtype=np.int64)
    for row in range(height):
        line = packed[row * (stride + 1):(row + 1) * (stride + 1)]
        current = _unfilter(line[0], np.frombuffer(line[1:], dtype=np.uint8), previous, k)
        pixels[row] = current
        previous = current.astype(np.int64)
    image = pixels.reshape(height, width, k).astype(np.int64)
    alpha = None
    if colour in (4, 6):
        image, alpha = image[..., :k - 1], image[..., k - 1]
    elif colour == 3:
        # tRNS gives the first palette entries' alphas, the rest opaque
        table = np.frombuffer(palette, dtype=np.uint8).reshape(-1, 3).astype(np.int64)
        opacity = np.full(len(table), 255, dtype=np.int64)
        opacity[:len(transparency)] = np.frombuffer(transparency, dtype=np.uint8)[:len(table)]
        index = image[..., 0]
        image = table[index]
        alpha = opacity[index] if transparency else None
    elif transparency:
        # The one transparent colour, 16-bit samples that GraphicsMagick 1.3 compares with
        # the quantums: a grey's key scaled to 16 bits, an RGB key not (only black matches).
        key = np.frombuffer(transparency[:2 * k], dtype=">u2").astype(np.int64)
        alpha = np.where((image * 257 == key * (257 if k == 1 else 1)).all(axis=2), 0, 255)
    return image * 257, None if alpha is None else alpha * 257


def _unfilter(kind: int, line: np.ndarray, above: np.ndarray, k: int) -> np.ndarray:
    """One PNG scanline with its filter (0 none, 1 sub, 2 up, 3 average, 4 Paeth) undone."""
    if kind == 0:
        return line.copy()
    if kind == 2:
        return ((line.astype(np.int64) + above) & 0xFF).astype(np.uint8)
    if kind not in (1, 3, 4):
        raise ValueError(f"PNG filter type {kind}")
    out = [0] * len(line)
    up = above.tolist()
    for i, value in enumerate(line.tolist()):
        left = out[i - k] if i >= k else 0
        if kind == 1:
            predicted = left
        elif kind == 3:
            predicted = (left + up[i]) // 2
        else:
            corner = up[i - k] if i >= k else 0
            p = left + up[i] - corner
            pa, pb, pc = abs(p - left), abs(p - up[i]), abs(p - corner)
            predicted = left if pa <= pb and pa <= pc else up[i] if pb <= pc else corner
        out[i] = (value + predicted) & 0xFF
    return np.array(out, dtype=np.uint8)
