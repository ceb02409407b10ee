"""Animations and stills of a timeline: GIF (Pillow), MP4 (imageio-ffmpeg, when installed),
PNG and SVG.

A still (PNG, SVG) shows the last frame of the span, with the trails of the whole span. The
frames are those of :func:`~hecker_dynamics.viz.frames.frame_times`: ``round(span x fps)``
instants from the start, each drawn from the latest published pose at or before it.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Optional
from collections.abc import Callable, Iterable, Iterator, Sequence

import numpy as np

from .draw import Drawing, Trail, View, fit_view
from .frames import Frame, Timeline, VizError, frame_times

__all__ = ["FORMATS", "check_output", "span_times", "timeline_frames", "frame_pixels", "render",
           "require_display", "show_live", "play"]

#: Output extensions and what they hold.
FORMATS = {".gif": "animation", ".mp4": "animation", ".png": "still", ".svg": "still"}
#: Colors of a GIF's one palette: enough for the fills, edges and anti-aliasing.
GIF_COLORS = 64


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


def span_times(start_ns: int, duration_ns: int, fps: float) -> list[int]:
    """The frame instants of ``[start, start + duration)`` at ``fps``; raises
    :class:`VizError` when there are none."""
    times = frame_times(start_ns, duration_ns, fps)
    if not times:
        raise VizError(f"--duration {duration_ns * 1e-9:g} s at --fps {fps:g} gives no frame")
    return times


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


def _write_gif(path: Path, pixels: Iterator[np.ndarray], fps: float) -> int:
    """One palette from the first frame, no dithering: flat fills stay flat, and Pillow
    stores each later frame as its change from the one before, which keeps the file small.
    A GIF keeps frame delays in whole centiseconds: the nearest one to 1/fps."""
    from PIL import Image

    images = []
    palette = None
    for rgba in pixels:
        image = Image.fromarray(rgba[:, :, :3])
        if palette is None:
            palette = image.quantize(colors=GIF_COLORS, method=Image.Quantize.MEDIANCUT)
        images.append(image.quantize(palette=palette, dither=Image.Dither.NONE))
    images[0].save(path, save_all=True, append_images=images[1:], loop=0,
                   duration=10 * max(round(100 / fps), 1), optimize=False)
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


def render(timeline: Timeline, output: Path, *, fps: float, size: tuple[int, int],
           start_ns: int, duration_ns: int, view: Optional[View] = None,
           trails: Sequence[Trail] = (), contacts: bool = False,
           progress: Optional[Callable[[float], None]] = None) -> int:
    """Write the span's animation, or its last frame as a still; returns the frame count."""
    kind = check_output(output)
    frames = timeline_frames(timeline, start_ns, duration_ns, fps)
    suffix = output.suffix.lower()
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
