"""Animations and stills of a timeline: GIF (Pillow), MP4 (imageio-ffmpeg, when installed),
PNG and SVG.

A still (PNG, SVG) shows the last frame of the span, with the trails of the whole span. The
frames are those of :func:`~hecker_dynamics.viz.frames.frame_times`: ``round(span x fps)``
instants from the start, each drawn from the latest published pose at or before it.

A picture is bounded before any work: at most :data:`MAX_FRAMES` frames, an animation's
frames at most :data:`MAX_PIXELS` pixels together and a GIF's (all held until it is
written) at most :data:`GIF_PIXELS`, a run at most :data:`MAX_RUN_POSES` published
instants, a GIF at most :data:`GIF_MAX_FPS` frames a second. The file is written beside
its name and moved into place (:func:`hecker_dynamics.files.replacing`).
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any, Optional

import numpy as np

from ..files import replacing
from ..scene import Scene
from ..scene.parameters import seconds_text
from .draw import BACKGROUND, DRAWING_COLORS, Drawing, Trail, View, fit_view
from .frames import NS_PER_S, Frame, Timeline, VizError, frame_times

__all__ = ["FORMATS", "check_output", "check_run", "gif_delays", "span_times",
           "timeline_frames", "frame_pixels", "render", "require_display", "show_live", "play",
           "MAX_FRAMES", "MAX_PIXELS", "MAX_RUN_POSES", "GIF_PIXELS", "GIF_MAX_FPS"]

#: Output extensions and what they hold.
FORMATS = {".gif": "animation", ".mp4": "animation", ".png": "still", ".svg": "still"}
#: Colors of a GIF's one palette: enough for the fills, edges and anti-aliasing.
GIF_COLORS = 64
#: The most frames of one picture (each is drawn, some 15 ms here: a few minutes).
MAX_FRAMES = 10_000
#: A GIF's frames are all held until it is written, a byte a pixel: at most 256 MiB of them
#: (some 1,500 frames of 480 x 360).
GIF_PIXELS = 2 ** 28
#: The most pixels of an animation, all frames together: 2**32 is the 10,000 frames of
#: 480 x 360 many times over, or 256 frames of 4096 x 4096 (drawing those takes minutes).
MAX_PIXELS = 2 ** 32
#: GIF players show a delay under 2 centiseconds as 10: faster GIFs play slow. A delay is
#: at most 65535 centiseconds.
GIF_MAX_FPS = 50.0
GIF_MIN_FPS = 100 / 65535
#: The most instants a run drawn from its scene publishes (every pose is kept: some 2 kB
#: an instant for two bodies, and a few minutes of running at the most).
MAX_RUN_POSES = 100_000


def check_output(path: Path) -> str:
    """The kind of file ``path`` asks for; raises :class:`VizError` for another extension
    or for MP4 without its encoder."""
    kind = FORMATS.get(path.suffix.lower())
    if kind is None:
        raise VizError(f"-o {path}: unknown picture type '{path.suffix}' (use "
                       f"{', '.join(FORMATS)})")
    if path.suffix.lower() == ".mp4":
        try:
            import imageio_ffmpeg  # noqa: F401
        except ImportError:
            raise VizError(f"-o {path}: MP4 needs an encoder: pip install imageio-ffmpeg "
                           "(or write a .gif)") from None
    return kind


def span_times(start_ns: int, duration_ns: int, fps: float,
               given: str | None = None) -> list[int]:
    """The frame instants of ``[start, start + duration)`` at ``fps``; raises
    :class:`VizError` when there are none or more than :data:`MAX_FRAMES`, quoting the
    duration as ``given`` on the command line if it was (1e-10 s is 0 ns)."""
    count = round(duration_ns * fps / NS_PER_S)
    seconds = seconds_text(duration_ns) if given is None else given
    if count > MAX_FRAMES:
        raise VizError(f"--duration {seconds} s at --fps {fps:g} is {count:.3g} "
                       f"frames, over the {MAX_FRAMES} a picture may have")
    times = frame_times(start_ns, duration_ns, fps)
    if not times:
        raise VizError(f"--duration {seconds} s at --fps {fps:g} gives no frame")
    return times


def check_run(scene: Scene, end_ns: int) -> None:
    """Raise :class:`VizError` if a run of ``scene`` to ``end_ns`` publishes more than
    :data:`MAX_RUN_POSES` instants (the run keeps them all)."""
    instants = end_ns // scene.publish_period_ns
    if instants > MAX_RUN_POSES:
        raise VizError(f"--start and --duration: a run of {scene.source} to "
                       f"{seconds_text(end_ns)} s publishes {instants:.3g} poses, over the "
                       f"{MAX_RUN_POSES} a picture keeps; draw an earlier span, or a bag")


def gif_delays(count: int, fps: float) -> list[int]:
    """Each of ``count`` frames' delay in milliseconds, whole centiseconds as a GIF stores
    them: frame k shows from round(100 k / fps) cs on, so the delays (12 and 13 cs at 8 fps)
    add up to the span, and the GIF plays at the speed asked. Raises :class:`VizError`
    over :data:`GIF_MAX_FPS`."""
    if fps > GIF_MAX_FPS:
        raise VizError(f"--fps {fps:g}: a GIF plays at most {GIF_MAX_FPS:g} frames a second "
                       "(players show shorter delays as 0.1 s); use a lower --fps or .mp4")
    if fps < GIF_MIN_FPS:
        raise VizError(f"--fps {fps:g}: a GIF shows a frame for at most 655.35 s")
    starts = [round(100 * k / fps) for k in range(count + 1)]
    return [10 * (b - a) for a, b in zip(starts, starts[1:])]


def timeline_frames(timeline: Timeline, start_ns: int, duration_ns: int,
                    fps: float) -> list[Frame]:
    """The frames of ``[start, start + duration)`` at ``fps``."""
    return list(timeline.frames(span_times(start_ns, duration_ns, fps)))


def frame_pixels(timeline: Timeline, frames: Sequence[Frame], size: tuple[int, int], *,
                 view: Optional[View] = None, trails: Sequence[Trail] = (),
                 contacts: bool = False,
                 progress: Optional[Callable[[float], None]] = None) -> Iterator[np.ndarray]:
    """Each frame's pixels, (height, width, 4) uint8."""
    drawing = Drawing(timeline, view or fit_view(timeline.scene, frames, size), size,
                      trails=trails, contacts=contacts)
    for k, frame in enumerate(frames):
        drawing.draw(frame)
        yield drawing.rgba()
        if progress is not None:
            progress((k + 1) / len(frames))


def _rgb(color: str) -> tuple[int, int, int]:
    return int(color[1:3], 16), int(color[3:5], 16), int(color[5:7], 16)


def _gif_palette(first: np.ndarray) -> np.ndarray:
    """The one palette of a GIF, (GIF_COLORS, 3): every colour a drawing uses, exactly, and
    each halfway to the background (the anti-aliased edges of arrows, springs and text),
    so a force or a contact that first shows in a later frame keeps its colour; the rest
    from the first frame's pixels ``first`` (Pillow's median cut)."""
    from PIL import Image

    named = list(dict.fromkeys(_rgb(c) for c in DRAWING_COLORS))
    background = _rgb(BACKGROUND)
    halfway = [tuple((a + b + 1) // 2 for a, b in zip(c, background)) for c in named
               if c != background]
    fixed = list(dict.fromkeys(named + halfway))
    rest = Image.fromarray(first).quantize(colors=GIF_COLORS - len(fixed),
                                           method=Image.Quantize.MEDIANCUT).getpalette()
    assert rest is not None  # a quantized image has a palette
    colors = fixed + [tuple(rest[3 * i:3 * i + 3]) for i in range(GIF_COLORS - len(fixed))]
    return np.array(colors, dtype=np.int64)


def _nearest(rgb: np.ndarray, palette: np.ndarray) -> np.ndarray:
    """Each pixel's index of its nearest palette colour (the first of equals), (h, w) uint8.
    Exact, unlike Pillow's quantize to a given palette, which looks colours up in a coarse
    cube and turns a pure colour into a neighbour. A frame has few distinct colours, so
    only those are compared."""
    packed = (rgb[:, :, 0].astype(np.int64) << 16 | rgb[:, :, 1].astype(np.int64) << 8
              | rgb[:, :, 2]).ravel()
    colors, inverse = np.unique(packed, return_inverse=True)
    unpacked = np.stack([colors >> 16, (colors >> 8) & 255, colors & 255], axis=1)
    distance = ((unpacked[:, None, :] - palette[None, :, :]) ** 2).sum(axis=2)
    return distance.argmin(axis=1).astype(np.uint8)[inverse.ravel()].reshape(rgb.shape[:2])


def _write_gif(path: Path, pixels: Iterator[np.ndarray], fps: float) -> int:
    """One palette (:func:`_gif_palette`), each pixel its nearest colour, no dithering:
    flat fills stay flat, and Pillow stores each later frame as its change from the one
    before, which keeps the file small. The delays are :func:`gif_delays`."""
    from PIL import Image

    images = []
    palette: Optional[np.ndarray] = None
    for rgba in pixels:
        rgb = np.ascontiguousarray(rgba[:, :, :3])
        if palette is None:
            palette = _gif_palette(rgb)
        image = Image.frombytes("P", (rgb.shape[1], rgb.shape[0]),
                                _nearest(rgb, palette).tobytes())
        image.putpalette(palette.astype(np.uint8).ravel().tolist())
        images.append(image)
    images[0].save(path, format="GIF", save_all=True, append_images=images[1:], loop=0,
                   duration=gif_delays(len(images), fps), optimize=False)
    return len(images)


def _write_mp4(path: Path, pixels: Iterator[np.ndarray], fps: float,
               size: tuple[int, int]) -> int:
    import imageio_ffmpeg

    writer = imageio_ffmpeg.write_frames(str(path), size, fps=fps, macro_block_size=1,
                                         quality=7)
    writer.send(None)  # start the encoder
    count = 0
    try:
        for rgba in pixels:
            writer.send(np.ascontiguousarray(rgba[:, :, :3]).tobytes())
            count += 1
    finally:
        writer.close()
    return count


def check_span(output: Path, size: tuple[int, int], start_ns: int, duration_ns: int,
               fps: float, given: str | None = None) -> list[int]:
    """:func:`span_times`, an animation's pixels, and for a GIF its rate and the memory its
    frames take."""
    times = span_times(start_ns, duration_ns, fps, given)
    animation = FORMATS.get(output.suffix.lower()) == "animation"
    if animation and len(times) * size[0] * size[1] > MAX_PIXELS:
        raise VizError(f"-o {output}: {len(times)} frames of {size[0]}x{size[1]} are over "
                       f"the {MAX_PIXELS:.3g} pixels a picture may have; draw fewer or "
                       "smaller frames")
    if output.suffix.lower() == ".gif":
        gif_delays(0, fps)
        if len(times) * size[0] * size[1] > GIF_PIXELS:
            raise VizError(f"-o {output}: {len(times)} frames of {size[0]}x{size[1]} are over "
                           f"the {GIF_PIXELS / 2 ** 20:g} MiB of frames a GIF is made in; "
                           "draw fewer or smaller frames, or an .mp4")
    return times


def render(timeline: Timeline, output: Path, *, fps: float, size: tuple[int, int],
           start_ns: int, duration_ns: int, view: Optional[View] = None,
           trails: Sequence[Trail] = (), contacts: bool = False,
           progress: Optional[Callable[[float], None]] = None,
           overwrite: bool = False) -> int:
    """Write the span's animation, or its last frame as a still; returns the frame count.
    ``output`` is replaced only with ``overwrite``."""
    kind = check_output(output)
    check_span(output, size, start_ns, duration_ns, fps)
    frames = timeline_frames(timeline, start_ns, duration_ns, fps)
    with replacing(output, overwrite=overwrite) as scratch:
        return _write(timeline, frames, kind, output.suffix.lower(), scratch, fps=fps,
                      size=size, view=view, trails=trails, contacts=contacts,
                      progress=progress)


def _write(timeline: Timeline, frames: list[Frame], kind: str, suffix: str, output: Path, *,
           fps: float, size: tuple[int, int], view: Optional[View], trails: Sequence[Trail],
           contacts: bool, progress: Optional[Callable[[float], None]]) -> int:
    if kind == "still":
        drawing = Drawing(timeline, view or fit_view(timeline.scene, frames, size), size,
                          trails=trails, contacts=contacts)
        for frame in frames[:-1]:  # the trails' earlier points
            drawing.follow(frame)
        drawing.draw(frames[-1])
        # No date and fixed ids in the SVG, no timestamp in the PNG: same frame, same file.
        metadata = {"Date": None} if suffix == ".svg" else {"Software": None}
        import matplotlib
        with matplotlib.rc_context({"svg.hashsalt": "hecker_dynamics"}):
            drawing.figure.savefig(output, format=suffix[1:], dpi=drawing.figure.dpi,
                                   metadata=metadata)
        return 1
    pixels = frame_pixels(timeline, frames, size, view=view, trails=trails, contacts=contacts,
                          progress=progress)
    if suffix == ".gif":
        return _write_gif(output, pixels, fps)
    return _write_mp4(output, pixels, fps, size)



def require_display() -> None:
    """Raise :class:`VizError` unless a window can open: on Linux and the BSDs an X11 or
    Wayland display must be named; elsewhere (macOS, Windows) the desktop is assumed."""
    import os
    import sys

    if sys.platform.startswith(("linux", "freebsd", "openbsd", "netbsd")) and \
            not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise VizError("--view: no display (DISPLAY and WAYLAND_DISPLAY are unset); write a "
                       "file with 'hecker-dynamics render' instead")


def show_live(timeline: Timeline, frames: Sequence[Frame], size: tuple[int, int], fps: float,
              *, view: Optional[View] = None, trails: Sequence[Trail] = (),
              contacts: bool = False) -> None:
    """Play the frames in a matplotlib window at ``fps`` until the last or until the
    window is closed; raises :class:`VizError` where no window can open."""
    require_display()
    import matplotlib.pyplot as plt  # pyplot only here: a window needs its GUI backend

    if plt.get_backend().lower() in ("agg", "pdf", "ps", "svg", "cairo", "template"):
        raise VizError(f"--view: matplotlib has no window backend here ({plt.get_backend()}); "
                       "install tkinter or PyQt, or use 'hecker-dynamics render'")
    figure = plt.figure(figsize=(size[0] / 100, size[1] / 100), dpi=100)
    try:
        play(figure, frame_pixels(timeline, frames, size, view=view, trails=trails,
                                  contacts=contacts),
             fps, pause=plt.pause, is_open=lambda: plt.fignum_exists(figure.number))
    finally:
        plt.close(figure)


def play(figure: Any, pixels: Iterable[np.ndarray], fps: float, *,
         pause: Callable[[float], None], is_open: Callable[[], bool]) -> int:
    """Show each frame's pixels in ``figure`` (filling it), then ``pause`` for 1/fps s (the
    window's event loop runs and redraws there), while ``is_open``; returns the number of
    frames shown."""
    axes = figure.add_axes((0.0, 0.0, 1.0, 1.0))
    axes.set_axis_off()
    image = None
    shown = 0
    for rgba in pixels:
        if not is_open():
            break
        if image is None:
            image = axes.imshow(rgba, interpolation="nearest")
        else:
            image.set_data(rgba)
        pause(1.0 / fps)
        shown += 1
    return shown
