"""Nav2 maps: cells as nav2's map_io reads them (modes, negate, thresholds, alpha, row 0 at
the top, origin and yaw), occupied cells merged into boxes that cover them exactly once,
the boxes seen by a laser at the closed-form distance and stopping bodies, and one-line
errors for bad map files."""
from __future__ import annotations

import dataclasses
import math
import os
import struct
import tracemalloc
import zlib
from pathlib import Path

import numpy as np
import pytest
import yaml
from scene_builders import make_scene, write_scene

from hecker_dynamics.cli import main
from hecker_dynamics.dynamics import kernel
from hecker_dynamics.dynamics.model import Model
from hecker_dynamics.dynamics.simulation import Simulation
from hecker_dynamics.scene.fingerprint import scene_fingerprint
from hecker_dynamics.scene.load import load_scene, scene_path, with_map
from hecker_dynamics.scene.maps import (
    MAX_CELLS,
    OCCUPIED,
    UNKNOWN,
    cell_boxes,
    read_image,
    read_map,
)
from hecker_dynamics.scene.parameters import SceneError
from hecker_dynamics.scene.world import deleted, spawned
from hecker_dynamics.sensors.laser import Laser


def write_pgm(path: Path, rows: list[list[int]], maxval: int = 255) -> None:
    """A binary PGM; ``rows[0]`` is the image's top row."""
    data = np.array(rows, dtype=np.uint8 if maxval < 256 else ">u2")
    header = f"P5\n# comment\n{data.shape[1]} {data.shape[0]}\n{maxval}\n".encode()
    path.write_bytes(header + data.tobytes())


def _paeth(left: int, up: int, corner: int) -> int:
    p = left + up - corner
    pa, pb, pc = abs(p - left), abs(p - up), abs(p - corner)
    return left if pa <= pb and pa <= pc else up if pb <= pc else corner


def chunk(kind: bytes, data: bytes) -> bytes:
    """A PNG chunk: its length, kind, data and CRC."""
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def write_png(path: Path, pixels: np.ndarray, colour: int, palette: bytes = b"",
              transparency: bytes = b"") -> None:
    """An 8-bit PNG of ``pixels`` (rows, columns, channels), row r filtered with filter
    type r % 5 (none, sub, up, average, Paeth), so every filter is undone once; ``palette``
    and ``transparency`` are the PLTE and tRNS chunks' data, if any."""
    rows, columns, k = pixels.shape
    packed = b""
    previous = [0] * (columns * k)
    for r in range(rows):
        raw = pixels[r].reshape(-1).tolist()
        kind = r % 5
        out = []
        for i, value in enumerate(raw):
            left = raw[i - k] if i >= k else 0
            corner = previous[i - k] if i >= k else 0
            predicted = [0, left, previous[i], (left + previous[i]) // 2,
                         _paeth(left, previous[i], corner)][kind]
            out.append((value - predicted) & 0xFF)
        packed += bytes([kind, *out])
        previous = raw

    path.write_bytes(b"\x89PNG\r\n\x1a\n"
                     + chunk(b"IHDR", struct.pack(">IIBBBBB", columns, rows, 8, colour, 0, 0, 0))
                     + (chunk(b"PLTE", palette) if palette else b"")
                     + (chunk(b"tRNS", transparency) if transparency else b"")
                     + chunk(b"IDAT", zlib.compress(packed)) + chunk(b"IEND", b""))


def write_map(directory: Path, image: str, name: str = "map.yaml", **keys) -> Path:
    values = {"image": image, "resolution": 0.5, "origin": [0.0, 0.0, 0.0], "negate": 0,
              "occupied_thresh": 0.75, "free_thresh": 0.25, **keys}
    path = directory / name
    path.write_text(yaml.safe_dump(values))
    return path


# ----------------------------------------------------------------------------- boxes

@pytest.mark.parametrize("seed", range(6))
def test_boxes_cover_every_occupied_cell_exactly_once(seed):
    rng = np.random.default_rng(seed)
    occupied = rng.random((23, 31)) < [0.2, 0.5, 0.8][seed % 3]
    occupied[5:12, 3:20] = True  # a block, which must come out as few boxes
    boxes = cell_boxes(occupied)
    cover = np.zeros(occupied.shape, dtype=int)
    for i0, j0, i1, j1 in boxes:
        assert 0 <= i0 < i1 <= occupied.shape[1] and 0 <= j0 < j1 <= occupied.shape[0]
        cover[j0:j1, i0:i1] += 1
    assert np.array_equal(cover, occupied.astype(int))  # the union, and no overlap
    assert cell_boxes(occupied.copy()) == boxes  # the same grid, the same boxes
    assert len(boxes) < occupied.sum()


def test_a_rectangle_is_one_box_and_an_l_two():
    grid = np.zeros((6, 8), dtype=bool)
    grid[1:4, 2:7] = True
    assert cell_boxes(grid) == ((2, 1, 7, 4),)
    grid[4:6, 2:4] = True  # the L's upright: a different run from row 4 up
    assert cell_boxes(grid) == ((2, 1, 7, 4), (2, 4, 4, 6))
    assert cell_boxes(np.zeros((3, 3), dtype=bool)) == ()


# ----------------------------------------------------------------------------- nav2 rules

#: Grey levels on and around the thresholds 0.8 and 0.2, as nav2 (1.3.7 on) computes in
#: float32: 51 / 255 is 0.2f and 1 - 0.2f rounds to 0.8f, so grey 51's occupancy is the
#: occupied threshold itself; 204 / 255 is 0.8f and 1 - 0.8f is 0.19999999f, under 0.2f.
EDGE_GREYS = [0, 51, 52, 102, 127, 128, 203, 204, 255]
EDGES = {"occupied_thresh": 0.8, "free_thresh": 0.2}


def edge_image(directory: Path, kind: str, greys: list[int] = EDGE_GREYS,
               alpha: list[int] | None = None) -> str:
    """One row of ``greys`` in one of the image formats nav2 reads, opaque unless ``alpha``
    (PNG with an alpha channel, or a palette's tRNS)."""
    row = np.array([greys], dtype=np.uint8)
    opacity = np.array([alpha or [255] * len(greys)], dtype=np.uint8)
    name = f"{kind}.{'pgm' if kind.startswith('pgm') else 'png'}"
    if kind == "pgm":
        write_pgm(directory / name, row.tolist())
    elif kind == "pgm-ascii":
        (directory / name).write_text(f"P2\n{len(greys)} 1\n255\n{' '.join(map(str, greys))}\n")
    elif kind == "palette":  # entry i is grey greys[-1 - i]: the indices are not the greys
        table = np.repeat(row[0, ::-1, None], 3, axis=1)
        write_png(directory / name, (len(greys) - 1 - np.arange(len(greys)))[None, :, None]
                  .astype(np.uint8), 3, palette=table.tobytes(),
                  transparency=opacity[0, ::-1].tobytes() if alpha else b"")
    else:
        k = {"grey": (0, 1), "grey-alpha": (4, 1), "rgb": (2, 3), "rgba": (6, 3)}[kind]
        pixels = np.repeat(row[..., None], k[1], axis=2)
        if k[0] in (4, 6):
            pixels = np.concatenate([pixels, opacity[..., None]], axis=2)
        write_png(directory / name, pixels, k[0])
    return name


FORMATS = ["pgm", "pgm-ascii", "grey", "grey-alpha", "rgb", "rgba", "palette"]


@pytest.mark.parametrize("kind", FORMATS)
def test_trinary_thresholds_include_their_edges_and_negate_flips(tmp_path, kind):
    image = edge_image(tmp_path, kind)
    cells = read_map(write_map(tmp_path, image, **EDGES)).cells()
    # occupancy 1 - grey / 255: grey 51 is 0.8f >= 0.8 (occupied; nav2 <= 1.3.6's strict
    # '<' said unknown), 52 is 0.796 (unknown), 203 is 0.204 (unknown), 204 is 0.19999999f
    # <= 0.2 (free)
    assert cells.tolist() == [[100, 100, -1, -1, -1, -1, -1, 0, 0]]
    negated = read_map(write_map(tmp_path, image, negate=1, **EDGES)).cells()
    # occupancy grey / 255: 51 is 0.2f <= 0.2 (free), 204 is 0.8f >= 0.8 (occupied)
    assert negated.tolist() == [[0, 0, -1, -1, -1, -1, -1, 100, 100]]


@pytest.mark.parametrize("kind", FORMATS)
def test_scale_mode_rounds_between_the_thresholds(tmp_path, kind):
    image = edge_image(tmp_path, kind)
    cells = read_map(write_map(tmp_path, image, mode="scale", **EDGES)).cells()
    # between: round((occupancy - 0.2) / 0.6 * 100): grey 52, occupancy 0.79608: 99.35;
    # 102 (0.6): 66.67; 127 (0.50196): 50.33; 128 (0.49804): 49.67; 203 (0.20392): 0.65
    assert cells.tolist() == [[100, 100, 99, 67, 50, 50, 1, 0, 0]]
    negated = read_map(write_map(tmp_path, image, mode="scale", negate=1, **EDGES)).cells()
    # occupancy grey / 255: 52 is 0.20392 (0.65), 102 is 0.4 (33.33), 203 is 0.79608
    assert negated.tolist() == [[0, 0, 1, 33, 50, 50, 99, 100, 100]]


def test_thresholds_of_0_and_1_are_reached_by_black_and_white(tmp_path):
    image = edge_image(tmp_path, "pgm")
    bounds = {"occupied_thresh": 1.0, "free_thresh": 0.0}
    # black's occupancy is 1.0 >= 1 and white's 0.0 <= 0 (both unknown before 1.3.7)
    cells = read_map(write_map(tmp_path, image, **bounds)).cells()
    assert cells.tolist() == [[100, -1, -1, -1, -1, -1, -1, -1, 0]]
    # scale: occupancy * 100, 51 -> 80, 52 -> 79.61, 102 -> 60, 203 -> 20.39, 204 -> 20
    cells = read_map(write_map(tmp_path, image, mode="scale", **bounds)).cells()
    assert cells.tolist() == [[100, 80, 80, 60, 50, 50, 20, 20, 0]]


@pytest.mark.parametrize("kind", ["grey-alpha", "rgba", "palette"])
def test_a_pixel_not_fully_opaque_is_unknown_but_in_raw_mode(tmp_path, kind):
    image = edge_image(tmp_path, kind, greys=[0, 0, 0, 255, 100], alpha=[255, 254, 0, 1, 0])
    for mode in ("trinary", "scale"):  # nav2 >= 1.3.7: alpha < 255 is unknown in both
        cells = read_map(write_map(tmp_path, image, mode=mode)).cells()
        assert cells.tolist() == [[OCCUPIED, UNKNOWN, UNKNOWN, UNKNOWN, UNKNOWN]]
    raw = read_map(write_map(tmp_path, image, mode="raw")).cells()
    assert raw.tolist() == [[0, 0, 0, UNKNOWN, 100]]  # the grey alone


def test_colour_is_graphicsmagick_s_rec601_luma(tmp_path):
    """A colour pixel's grey is GraphicsMagick's: 0.299f R + 0.587f G + 0.114f B on 16-bit
    quantums (257 v), rounded, then whole-divided by 257; not the channels' mean."""
    pixels = np.array([[[255, 0, 0], [0, 255, 0], [0, 0, 255], [0, 38, 255], [0, 40, 255],
                        [255, 167, 255], [255, 169, 255]]], dtype=np.uint8)
    # red 0.299 * 65535 = 19594.97 -> 19595 // 257 = 76; green 38469.05 -> 149; blue
    # 7470.99 -> 29; (0, 38, 255): 5732.64 + 7470.99 = 13203.63 -> 13204 // 257 = 51 (its
    # mean 97.7); (0, 40, 255): 13505.35 -> 52; (255, 167, 255): 52259.40 -> 203;
    # (255, 169, 255): 52561.1 -> 204
    greys = [76, 149, 29, 51, 52, 203, 204]
    write_png(tmp_path / "m.png", pixels, 2)
    write_png(tmp_path / "m-alpha.png", np.concatenate(
        [pixels, np.full((1, 7, 1), 255, dtype=np.uint8)], axis=2), 6)
    write_png(tmp_path / "m-palette.png", np.arange(7, dtype=np.uint8).reshape(1, 7, 1), 3,
              palette=pixels.tobytes())
    for image in ("m.png", "m-alpha.png", "m-palette.png"):
        raw = read_map(write_map(tmp_path, image, mode="raw")).cells()
        assert raw.tolist() == [[76, UNKNOWN, 29, 51, 52, UNKNOWN, UNKNOWN]]
        assert read_image(tmp_path / image)[0].tolist() == [greys]
        cells = read_map(write_map(tmp_path, image, **EDGES)).cells()
        assert cells.tolist() == [[-1, -1, 100, 100, -1, -1, 0]]


def test_raw_mode_keeps_values_up_to_100(tmp_path):
    write_pgm(tmp_path / "m.pgm", [[0, 37, 100, 101, 255]])
    cells = read_map(write_map(tmp_path, "m.pgm", mode="raw")).cells()
    assert cells.tolist() == [[0, 37, 100, UNKNOWN, UNKNOWN]]


def test_raw_mode_reads_no_threshold_and_takes_any(tmp_path):
    """Raw mode's cells are the pixels' values: thresholds nav2 requires but never reads
    there are not refused."""
    write_pgm(tmp_path / "m.pgm", [[0, 100]])
    path = write_map(tmp_path, "m.pgm", mode="raw", occupied_thresh=65, free_thresh=80)
    assert read_map(path).cells().tolist() == [[0, 100]]


def test_the_image_s_top_row_is_the_map_s_top_and_the_origin_its_lower_left_corner(tmp_path):
    write_pgm(tmp_path / "m.pgm", [[0, 255, 255], [255, 255, 255]])  # black: top left
    grid = read_map(write_map(tmp_path, "m.pgm", origin=[1.0, -2.0, 0.0]))
    assert (grid.width, grid.height) == (3, 2)
    assert grid.cells().tolist() == [[0, 0, 0], [OCCUPIED, 0, 0]]
    assert grid.boxes == ((0, 1, 1, 2),)
    assert grid.box_vertices().tolist() == [[[1.0, -1.5], [1.5, -1.5], [1.5, -1.0],
                                             [1.0, -1.0]]]


def test_the_origin_s_yaw_turns_the_map_about_its_corner(tmp_path):
    write_pgm(tmp_path / "m.pgm", [[255, 0]])
    grid = read_map(write_map(tmp_path, "m.pgm", origin=[1.0, 2.0, math.pi / 2]))
    c, s = math.cos(math.pi / 2), math.sin(math.pi / 2)
    # cell (1, 0) spans u in [0.5, 1], v in [0, 0.5]; turned: (x - s v + c u, y + s u + c v)
    expected = [[1.0 + c * u - s * v, 2.0 + s * u + c * v]
                for u, v in [(0.5, 0.0), (1.0, 0.0), (1.0, 0.5), (0.5, 0.5)]]
    assert grid.box_vertices()[0].tolist() == expected


@pytest.mark.parametrize("colour", [0, 2, 4, 6])
def test_png_pixels_are_read_through_every_filter(tmp_path, colour):
    rng = np.random.default_rng(colour)
    grey = rng.choice([0, 100, 128, 254], size=(7, 4))
    k = {0: 1, 2: 3, 4: 2, 6: 4}[colour]
    pixels = np.repeat(grey[..., None], k, axis=2)
    if colour in (4, 6):
        pixels[..., -1] = 255  # opaque: scale mode reads the colour alone
    write_png(tmp_path / "m.png", pixels.astype(np.uint8), colour)
    write_pgm(tmp_path / "m.pgm", grey.tolist())
    png = read_map(write_map(tmp_path, "m.png", name="png.yaml", mode="scale")).cells()
    pgm = read_map(write_map(tmp_path, "m.pgm", name="pgm.yaml", mode="scale")).cells()
    assert np.array_equal(png, pgm) and len(set(pgm.ravel().tolist())) > 2


@pytest.mark.parametrize("keys, problem", [
    ({"resolution": None}, "'resolution' must be a finite number"),
    ({"resolution": 0.0}, "'resolution' must be positive"),
    ({"origin": [0.0, 0.0]}, "'origin' must be [x, y, yaw]"),
    ({"mode": "fancy"}, "'mode' must be one of trinary, scale, raw"),
    ({"negate": 2}, "'negate' must be 0, 1, true or false"),
    ({"image": "missing.pgm"}, "cannot read the map image"),
    ({"image": "map.yaml"}, "must be a PGM (P2, P5) or PNG file"),
    ({"resolution": "1e-300"}, "'resolution' is read as the string '1e-300': YAML 1.1 reads "
                               "an exponent as a number only after a dot and with its sign; "
                               "write 1.0e-300"),
    ({"free_thresh": "0.25"}, "'free_thresh' is read as the string '0.25': a quoted number "
                              "is text in YAML; write it unquoted"),
    ({"occupied_thresh": 65}, "'free_thresh' 0.25 and 'occupied_thresh' 65 must be fractions "
                              "with 0 <= free_thresh < occupied_thresh <= 1 in trinary mode"),
    ({"free_thresh": -0.1}, "'free_thresh' -0.1 and 'occupied_thresh' 0.75 must be"),
    ({"free_thresh": 0.75}, "'free_thresh' 0.75 and 'occupied_thresh' 0.75 must be"),
    ({"free_thresh": 0.8, "mode": "scale"}, "occupied_thresh <= 1 in scale mode"),
    # A box's centre, the mean of its corners, would be inf and its corners' offsets NaN.
    ({"resolution": 1e308}, "'resolution' 1e+308 over 1 x 1 cells from 'origin' [0, 0, 0] "
                            "puts the map's corners past 4.494e+307 m"),
    ({"origin": [-1e308, 0.0, 0.5]}, "'origin' [-1e+308, 0, 0.5] puts the map's corners past"),
])
def test_a_bad_map_file_is_one_line_naming_it(tmp_path, keys, problem):
    write_pgm(tmp_path / "m.pgm", [[0]])
    path = write_map(tmp_path, **{"image": "m.pgm", **keys})
    with pytest.raises(SceneError) as error:
        read_map(path)
    assert problem in str(error.value) and "\n" not in str(error.value)


@pytest.mark.parametrize("image", [False, True])
@pytest.mark.parametrize("special", ["/dev/zero", "fifo", "folder"])
def test_a_map_file_or_image_that_is_no_regular_file_is_refused(tmp_path, image, special):
    """/dev/zero or a pipe, as the map file or its image, would be read for ever: refused
    in one line before reading."""
    if special == "fifo":
        special = str(tmp_path / "pipe")
        os.mkfifo(special)
    elif special == "folder":
        special = str(tmp_path)
    path = write_map(tmp_path, special) if image else Path(special)
    with pytest.raises(SceneError) as error:
        read_map(path)
    what = "map image" if image else "map file"
    assert f"cannot read the {what} (a folder, device or pipe" in str(error.value)
    assert "\n" not in str(error.value)


# ----------------------------------------------------------------------------- scenes

def map_scene(tmp_path: Path, rows: list[list[int]], body: dict, **extra) -> Path:
    write_pgm(tmp_path / "m.pgm", rows)
    write_map(tmp_path, "m.pgm", origin=[-1.0, -1.0, 0.0])
    return write_scene(tmp_path, {"step": 0.001, "bodies": {"ball": body},
                                  "map": {"file": "map.yaml", **extra}})


def test_the_map_file_is_relative_to_the_scene_file_and_in_the_fingerprint(tmp_path):
    ball = {"shape": "circle", "radius": 0.1, "mass": 1.0}
    path = map_scene(tmp_path, [[0, 255]], ball)
    scene = load_scene(path)
    assert scene.map is not None and scene.map.occupancy.boxes == ((0, 0, 1, 1),)
    assert scene.map.bodies == ("ball",) and scene.map.file == "map.yaml"
    write_pgm(tmp_path / "m.pgm", [[255, 0]])
    assert scene_fingerprint(load_scene(path)) != scene_fingerprint(scene)
    # a shipped scene by name or by path: one fingerprint
    assert scene_fingerprint(load_scene("warehouse")) == \
        scene_fingerprint(load_scene(scene_path("warehouse").resolve()))


def test_a_missing_map_file_is_one_line_naming_the_parameter(tmp_path, capsys):
    path = write_scene(tmp_path, {"bodies": {"ball": {"shape": "circle", "radius": 0.1,
                                                      "mass": 1.0}},
                                  "map": {"file": "nowhere.yaml"}})
    assert main(["run", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "parameter 'map.file'" in err and "nowhere.yaml" in err
    assert main(["run", "warehouse", "--map", str(tmp_path / "none.yaml")]) == 2
    assert "--map: parameter 'map.file'" in capsys.readouterr().err


def test_the_cli_map_replaces_the_scene_s(tmp_path, capsys):
    write_pgm(tmp_path / "m.pgm", [[0]])
    path = write_map(tmp_path, "m.pgm", origin=[-5.0, 0.0, 0.0])
    assert main(["run", "warehouse", "--map", str(path), "--duration", "0.01",
                 "--no-progress"]) == 0


def test_a_ball_thrown_at_a_map_wall_bounces_with_its_restitution(tmp_path):
    # A wall cell spanning x in [-1, -0.5] (and y in [-1, -0.5]); the ball at y = -0.75.
    ball = {"shape": "circle", "radius": 0.1, "mass": 1.0, "position": [0.0, -0.75],
            "velocity": [-2.0, 0.0]}
    scene = load_scene(map_scene(tmp_path, [[0, 255, 255]], ball, restitution=0.5))
    sim = Simulation(scene)
    sim.advance_to(400_000_000)
    state = sim.snapshot().bodies[0]
    # Contact normal through the CM, no friction and no other force: v = -e v0 exactly.
    assert state.linear_velocity == pytest.approx((1.0, 0.0), abs=1e-12)
    assert state.angular_velocity == 0.0
    assert state.position[0] > -0.5 + 0.1 - 5e-3  # stopped at the wall's face


def test_a_laser_sees_a_map_cell_s_wall_at_the_closed_form_distance(tmp_path):
    # Occupied column 3 (x in [-1 + 1.5, -1 + 2.0]) across all rows; map turned by yaw.
    rows = [[255, 255, 255, 0, 255]] * 5
    write_pgm(tmp_path / "m.pgm", rows)
    yaw = 0.3
    write_map(tmp_path, "m.pgm", origin=[-1.0, -1.0, yaw])
    scene = make_scene({"step": 0.001,
                        "bodies": {"robot": {"shape": "circle", "radius": 0.05, "mass": 1.0}},
                        "map": {"file": str(tmp_path / "map.yaml")},
                        "sensors": {"front": {"type": "laser", "body": "robot",
                                              "angle_min": -0.5, "angle_max": 0.5,
                                              "count": 11, "range_max": 50.0}}})
    laser = Laser(scene.sensors[0], scene, Model(scene).cm_local)
    ranges = laser.distances(np.array([[0.2, 0.1, 0.1]]))
    # The cell column's near face: u = 1.5 in map axes (the map's x turned by yaw).
    c, s = math.cos(yaw), math.sin(yaw)
    u_origin = c * (0.2 + 1.0) + s * (0.1 + 1.0)  # the sensor's u in map axes
    directions = 0.1 - yaw + laser.angles  # the rays' angles in map axes
    expected = (1.5 - u_origin) / np.cos(directions)
    assert np.max(np.abs(ranges - expected)) < 1e-12


@pytest.mark.skipif(not kernel.built(), reason="compares the kernel with Python")
def test_the_kernel_casts_the_map_s_boxes_with_the_bits_of_python():
    """The warehouse's map boxes are fixed bodies of the cast: the kernel culls them as it
    culls bodies and gives the numpy twin's bits, at every pose of a turning robot."""
    scene = load_scene("warehouse")
    cm_local = Model(scene).cm_local
    compiled = Laser(scene.sensors[0], scene, cm_local, compiled=True)
    plain = Laser(scene.sensors[0], scene, cm_local, compiled=False)
    rng = np.random.default_rng(3)
    q = Model(scene).initial_state()[0]
    robot = [b.name for b in scene.bodies].index(scene.sensors[0].body)
    hits = 0
    for _ in range(20):
        q[robot] = [rng.uniform(-3.5, 3.5), rng.uniform(-2.5, 2.5), rng.uniform(-4, 4)]
        ranges = compiled.distances(q)
        assert ranges.tobytes() == plain.distances(q).tobytes()
        hits += int(np.isfinite(ranges).sum())
    assert hits > 0


@pytest.mark.skipif(not kernel.enabled(), reason="compares the kernel with Python")
@pytest.mark.parametrize("sleep", [False, True])
def test_the_kernel_resolves_map_contacts_with_the_bits_of_python(tmp_path, sleep):
    """A ball and a box that collide with each other and a crate in no collision group fall
    on a map's floor with a step in it and slide into the step (and the box and crate fall
    asleep with ``sleep``): the kernel's contact pass gives Python's positions, velocities
    and warm-start impulses exactly, every 0.1 s, and the map holds every body."""
    rows = [[255] * 8, [255] * 8, [255] * 6 + [0, 0], [0] * 8]  # a floor, a step on the right
    write_pgm(tmp_path / "m.pgm", rows)
    write_map(tmp_path, "m.pgm", origin=[-1.0, -1.0, 0.0])
    bodies = {"ball": {"shape": "circle", "radius": 0.1, "mass": 1.0, "position": [0.0, 0.2],
                       "velocity": [2.0, 0.0]},
              "box": {"shape": "box", "size": [0.3, 0.2], "mass": 2.0, "position": [0.5, 0.4],
                      "angular_velocity": 3.0},
              "crate": {"shape": "box", "size": [0.4, 0.4], "mass": 1.0,
                        "position": [1.2, 0.6], "velocity": [1.0, 0.0]}}
    scene = make_scene({"step": 0.002, "integrator": "velocity_verlet",
                        "contacts": {"sleep": sleep}, "bodies": bodies,
                        "forces": {"gravity": {"type": "gravity",
                                               "acceleration": [0.0, -9.81]}},
                        "collisions": {"pair": {"bodies": ["ball", "box"], "friction": 0.3}},
                        "map": {"file": str(tmp_path / "map.yaml"), "friction": 0.5,
                                "restitution": 0.2}})
    fast, slow = Simulation(scene), Simulation(scene)
    slow.model.use_python()
    assert fast.model.contacts.compiled and not slow.model.contacts.compiled
    assert fast.model.contacts.colliding != fast.model.contacts.swept  # the crate is swept
    for until in range(100_000_000, 3_000_000_001, 100_000_000):
        fast.advance_to(until)
        slow.advance_to(until)
        assert fast.q.tobytes() == slow.q.tobytes() and fast.v.tobytes() == slow.v.tobytes()
    state = fast.model.contacts.export_state()
    assert state and state == slow.model.contacts.export_state()
    lowest = [y - fast.model.contacts.reach[i] for i, y in enumerate(fast.q[:, 1].tolist())]
    assert min(lowest) > -0.5 - 0.3  # no body fell through the floor's top at y = -0.5
    assert fast.q[:, 0].max() < 2.0  # nor through the step's face at x = 2


def test_a_map_or_contact_events_change_the_fingerprint_and_their_absence_does_not_count():
    scene = load_scene("robot")
    assert scene.map is None and not scene.publish_contacts
    contacts = dataclasses.replace(scene, publish_contacts=True)
    assert scene_fingerprint(contacts) != scene_fingerprint(scene)
    mapped = with_map(scene, str(scene_path("warehouse").parent / "maps" / "warehouse.yaml"))
    assert scene_fingerprint(mapped) != scene_fingerprint(scene)


def test_a_spawned_body_joins_a_map_that_holds_every_body_and_a_deleted_one_leaves_it():
    scene = load_scene("warehouse")
    spec = "{shape: circle, radius: 0.1, mass: 1.0, position: [2.0, 2.0]}"
    grown = spawned(scene, "ball", spec)
    assert grown.map is not None and grown.map.bodies == ("ball", "crate", "robot")
    assert deleted(grown, "ball").map == scene.map
    assert Simulation(scene).with_world(grown).model.contacts.static_bodies == [0, 1, 2]
    only_robot = dataclasses.replace(scene, map=dataclasses.replace(scene.map,
                                                                    bodies=("robot",)))
    assert spawned(only_robot, "ball", spec).map.bodies == ("robot",)


@pytest.mark.parametrize("raw, problem", [
    (b"P58 6 255\n" + bytes(48), "PGM magic number P5 is not followed by whitespace"),
    (b"P28 1 255\n0 0 0 0 0 0 0 0\n", "PGM magic number P2 is not followed by whitespace"),
    (b"P5\n2_0 1\n255\n" + bytes(20), "PGM width '2_0' is not a whole number"),
    (b"P5\n2 +1\n255\n" + bytes(2), "PGM height '+1' is not a whole number"),
    (b"P5\n2 1\n# a comment to the end", "PGM header cut short before its maxval"),
    (b"P5\n2 1", "PGM header cut short before its maxval"),
    (b"P5 2 1 255#\n" + bytes(2), "PGM maxval followed by a comment, not by one whitespace"),
])
def test_a_pgm_header_that_is_not_the_format_s_is_refused(tmp_path, raw, problem):
    """The header is the magic number, whitespace, then width, height and maxval in ASCII
    digits: a width run into the magic number, or written as Python's int() reads it,
    is a bad image in one line, not a map of another size."""
    (tmp_path / "m.pgm").write_bytes(raw)
    with pytest.raises(SceneError) as error:
        read_map(write_map(tmp_path, "m.pgm"))
    assert problem in str(error.value) and "\n" not in str(error.value)


def test_a_pgm_header_may_hold_comments_anywhere_between_its_numbers(tmp_path):
    (tmp_path / "m.pgm").write_bytes(b"P5#c\n2#c\n#c\n1\n#c\n255\n" + bytes([0, 255]))
    cells = read_map(write_map(tmp_path, "m.pgm", mode="raw")).cells()
    assert cells.tolist() == [[0, UNKNOWN]]


@pytest.mark.parametrize("image, greys", [
    # a PGM of at least maxval cells is a palette, level i at i * (65535 // 4) = 16383 i;
    # P5 stretches it by 65535 / round(65535 * 4 / 255 = 1028): every level past 0 is white
    (b"P5\n5 1\n4\n" + bytes([0, 1, 2, 3, 4]), [0, 255, 255, 255, 255]),
    # P2 keeps the palette: 16383 // 257 = 63, 32766 -> 127, 65532 -> 254 (not 255)
    (b"P2\n4 1\n4\n0 1 2 4\n", [0, 63, 127, 254]),
    # fewer cells than maxval 100: P5's 257 v stretched by 65535 / 25700 (655.35 -> 655,
    # 32767.5 -> 32768); P2's round(65535 v / 100), the same; // 257: 2 and 127
    (b"P5\n3 1\n100\n" + bytes([0, 1, 50]), [0, 2, 127]),
    (b"P2\n3 1\n100\n0 1 50\n", [0, 2, 127]),
    # 16-bit samples are quantums: // 257
    (b"P5\n4 1\n65535\n" + np.array([0, 256, 257, 65535], dtype=">u2").tobytes(),
     [0, 0, 1, 255]),
])
def test_a_pgm_s_maxval_scales_its_greys_as_graphicsmagick_does(tmp_path, image, greys):
    (tmp_path / "m.pgm").write_bytes(image)
    assert read_image(tmp_path / "m.pgm") == (pytest.approx(np.array([greys])), None)
    raw = read_map(write_map(tmp_path, "m.pgm", mode="raw")).cells()
    assert raw.tolist() == [[g if g <= 100 else UNKNOWN for g in greys]]


def test_a_png_s_transparent_colour_is_graphicsmagick_s(tmp_path):
    """tRNS: a grey key makes its grey transparent (unknown); GraphicsMagick 1.3 compares an
    8-bit RGB key with 16-bit quantums, so only a black key matches anything."""
    grey = np.array([[[77], [255]]], dtype=np.uint8)
    write_png(tmp_path / "g.png", grey, 0, transparency=struct.pack(">H", 77))
    assert read_map(write_map(tmp_path, "g.png")).cells().tolist() == [[UNKNOWN, 0]]
    rgb = np.array([[[60, 0, 120], [0, 0, 0]]], dtype=np.uint8)
    write_png(tmp_path / "c.png", rgb, 2, transparency=struct.pack(">HHH", 60, 0, 120))
    # (60, 0, 120): 0.299f * 15420 + 0.114f * 30840 = 8126.4 -> grey 31, occupancy 0.88
    assert read_map(write_map(tmp_path, "c.png")).cells().tolist() == [[OCCUPIED, OCCUPIED]]
    write_png(tmp_path / "k.png", rgb, 2, transparency=bytes(6))
    assert read_map(write_map(tmp_path, "k.png")).cells().tolist() == [[OCCUPIED, UNKNOWN]]


@pytest.mark.parametrize("header, pixels, problem", [
    (b"P5\n2 1\n100\n", bytes([50, 200]), "PGM pixel 200 is above its maxval 100"),
    (b"P5\n2 1\n1000\n", bytes([0, 50, 4, 0]), "PGM pixel 1024 is above its maxval 1000"),
    (b"P5\n2 1\n1\n", bytes([0, 1]), "P5 PGM of maxval 1, whose bytes GraphicsMagick"),
    (b"P2\n2 1\n100\n", b"50 101\n", "PGM pixel 101 is above its maxval 100"),
    (b"P2\n2 1\n100\n", b"50 -1\n", "PGM pixel -1 is not a whole number from 0 to 100"),
    (b"P2\n2 1\n100\n", b"50 0.5\n", "PGM pixel 0.5 is not a whole number from 0 to 100"),
])
def test_a_pgm_pixel_outside_its_maxval_is_refused(tmp_path, header, pixels, problem):
    """A pixel above the maxval the header gives (a shade past white, which nav2's
    map_server never reads) is a bad image, not a cell that is free beyond free."""
    (tmp_path / "m.pgm").write_bytes(header + pixels)
    with pytest.raises(SceneError) as error:
        read_map(write_map(tmp_path, "m.pgm"))
    assert problem in str(error.value) and "\n" not in str(error.value)


def png_bytes(columns: int, rows: int, colour: int, idat: bytes) -> bytes:
    """A PNG of the header's size and the compressed pixel data given, whatever they hold."""
    return (b"\x89PNG\r\n\x1a\n"
            + chunk(b"IHDR", struct.pack(">IIBBBBB", columns, rows, 8, colour, 0, 0, 0))
            + chunk(b"IDAT", idat) + chunk(b"IEND", b""))


def _inflated_zeros(count: int) -> bytes:
    """``count`` zero bytes compressed, made a megabyte at a time."""
    deflate, block = zlib.compressobj(9), bytes(1 << 20)
    parts = [deflate.compress(block) for _ in range(count >> 20)]
    return b"".join(parts) + deflate.compress(bytes(count & ((1 << 20) - 1))) + \
        deflate.flush()


@pytest.mark.parametrize("image, raw", [
    ("m.png", png_bytes(100_000, 100_000, 0, zlib.compress(bytes(1000)))),
    ("m.png", png_bytes(8193, 8192, 6, zlib.compress(bytes(1000)))),
    ("m.pgm", b"P5\n100000 100000\n255\n" + bytes(1000)),
    ("m.pgm", b"P2\n8192 8193\n255\n0 0 0\n"),
], ids=["png-1e10", "png-rgba-8193x8192", "pgm-1e10", "pgm-ascii-8192x8193"])
def test_an_image_of_more_cells_than_a_map_may_hold_is_refused_by_its_header(tmp_path, image,
                                                                             raw):
    """A small file whose header claims a huge image (a PNG's zeros compress a
    thousandfold) is refused before any of its pixels is read."""
    (tmp_path / image).write_bytes(raw)
    with pytest.raises(SceneError) as error:
        read_map(write_map(tmp_path, image))
    kind = image[-3:].upper()
    assert f"{kind} of " in str(error.value) and "x" in str(error.value)
    assert f"more than the {MAX_CELLS:,} cells a map may hold" in str(error.value)
    assert "\n" not in str(error.value)


def test_png_pixel_data_past_its_header_s_size_is_never_inflated(tmp_path):
    """An IDAT of 64 MB of zeros under a 2 x 2 header is refused having inflated no more
    than the header's 2 x 3 bytes and one: memory stays that of the file."""
    (tmp_path / "m.png").write_bytes(png_bytes(2, 2, 0, _inflated_zeros(64 << 20)))
    path = write_map(tmp_path, "m.png")
    tracemalloc.start()
    try:
        with pytest.raises(SceneError, match="PNG pixel data of the wrong size"):
            read_map(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1 << 20


def test_a_png_of_no_pixels_is_refused(tmp_path):
    (tmp_path / "m.png").write_bytes(png_bytes(0, 3, 0, zlib.compress(bytes(3))))
    with pytest.raises(SceneError, match=r"bad map image \(PNG size 0 x 3\)"):
        read_map(write_map(tmp_path, "m.png"))


@pytest.mark.parametrize("at, problem", [
    (44, "PNG PLTE chunk fails its CRC check (a damaged file)"),  # white turned black
    (20, "PNG IHDR chunk fails its CRC check"),  # the height
    (-1, "PNG IEND chunk fails its CRC check"),
    (None, "PNG cut short in its IEND chunk"),
])
def test_a_damaged_png_is_refused_not_read_as_other_cells(tmp_path, at, problem):
    """A byte changed in a palette gave a map of other cells without a word: the critical
    chunks' CRCs are checked, as libpng checks them."""
    raw = bytearray(b"\x89PNG\r\n\x1a\n"
                    + chunk(b"IHDR", struct.pack(">IIBBBBB", 2, 1, 8, 3, 0, 0, 0))
                    + chunk(b"PLTE", bytes([0, 0, 0, 255, 255, 255]))
                    + chunk(b"IDAT", zlib.compress(bytes([0, 0, 1]))) + chunk(b"IEND", b""))
    (tmp_path / "m.png").write_bytes(bytes(raw))
    assert read_map(write_map(tmp_path, "m.png")).cells().tolist() == [[OCCUPIED, 0]]
    if at is None:
        del raw[-2:]
    else:
        raw[at] ^= 0xFF
    (tmp_path / "m.png").write_bytes(bytes(raw))
    with pytest.raises(SceneError) as error:
        read_map(write_map(tmp_path, "m.png"))
    assert problem in str(error.value) and "\n" not in str(error.value)


EXPONENT = "YAML 1.1 reads an exponent as a number only after a dot and with its sign"
LEADING_0 = "YAML 1.1 reads a whole number with a leading 0 as octal or text"


@pytest.mark.parametrize("written, rule, spelled", [
    ("1e3", EXPONENT, "1.0e+3"), ("1.0e3", EXPONENT, "1.0e+3"), ("5.E2", EXPONENT, "5.e+2"),
    ("-2e-1", EXPONENT, "-2.0e-1"),
    # 08 is text to YAML 1.1 and 010 octal 8: they were told '08.0e+' (text again) and,
    # quoted, 'write it unquoted' (8, not the 10 nav2 reads)
    ("08", LEADING_0, "08.0"), ("'010'", LEADING_0, "010.0"), ("'-09'", LEADING_0, "-09.0"),
    # unquoted 010 was read as 8 without a word, where nav2's yaml-cpp reads 10
    ("010", LEADING_0, "010.0"), ("-010", LEADING_0, "-010.0"),
])
def test_a_map_number_yaml_1_1_reads_otherwise_is_told_a_spelling_it_reads(tmp_path, written,
                                                                           rule, spelled):
    """An exponent without its sign is text to YAML 1.1 too: '1.0e3' was called a quoted
    number, and '1e3' told to be written '1.0e3', text again. The spelling given reads as
    the number."""
    write_pgm(tmp_path / "m.pgm", [[0]])
    path = write_map(tmp_path, "m.pgm")
    path.write_text(path.read_text().replace("resolution: 0.5", f"resolution: {written}"))
    with pytest.raises(SceneError) as error:
        read_map(path)
    text = written.strip("'")
    assert str(error.value).endswith(
        f"'resolution' is read as the string '{text}': {rule}; write {spelled}")
    assert yaml.safe_load(spelled) == float(text)


@pytest.mark.parametrize("written", ["0x10", "0b11", "1_0", "1:30"])
def test_a_map_whole_number_yaml_cpp_cannot_read_is_refused(tmp_path, written):
    """YAML 1.1 reads these as whole numbers (16, 3, 10, 90); nav2's yaml-cpp reads none of
    them as a double, so the map is refused as nav2 refuses it."""
    write_pgm(tmp_path / "m.pgm", [[0]])
    path = write_map(tmp_path, "m.pgm")
    path.write_text(path.read_text().replace("resolution: 0.5", f"resolution: {written}"))
    with pytest.raises(SceneError, match=f"'resolution' must be a finite number, not "
                                         f"'{written}'$"):
        read_map(path)
    path.write_text(path.read_text().replace(f"resolution: {written}", "resolution: 07"))
    assert read_map(path).resolution == 7.0  # YAML 1.1's octal 07 is 7, as to yaml-cpp
