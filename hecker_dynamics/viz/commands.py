"""The command line's picture commands: ``render``, ``plot`` and ``run --view``.

Registered by :mod:`hecker_dynamics.cli`; matplotlib is imported only when one of them
runs, so the rest of the command line works without the ``viz`` extra.
"""
from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

from ..bags.coverage import seconds
from ..files import check_file, file_path, path_argument, replacing
from ..scene import Scene, load_scene
from ..scene.parameters import seconds_text
from .frames import Timeline, VizError
from .progress import Progress

__all__ = ["add_viz_commands", "view_run", "render_command", "plot_command"]

#: The default picture size in pixels and the frame rate of ``run --view``.
DEFAULT_SIZE = "480x360"
VIEW_FPS = 20.0


def _viz() -> tuple[ModuleType, ModuleType, ModuleType]:
    """The drawing modules; a one-line error where matplotlib or Pillow is missing."""
    try:
        from . import draw, plot, render
    except ImportError as error:
        raise VizError(f"pictures need matplotlib and Pillow ({error}): "
                       "pip install 'hecker_dynamics[viz]'") from None
    return draw, plot, render


def _fps(text: str) -> float:
    try:
        fps = float(text)
    except ValueError:
        fps = math.nan
    if not 0.0 < fps <= 1000.0:
        raise VizError(f"--fps {text}: must be a number of frames per second above 0, "
                       "at most 1000")
    return fps


def view_run(scene: Scene) -> None:
    """Show a run of ``scene`` in a window, at real-time pace."""
    draw, _, render = _viz()
    from .frames import run_timeline

    render.require_display()  # before the run: fail fast
    render.span_times(0, scene.duration_ns, VIEW_FPS)
    render.check_run(scene, scene.duration_ns)
    timeline = run_timeline(scene, scene.duration_ns)
    frames = render.timeline_frames(timeline, 0, scene.duration_ns, VIEW_FPS)
    render.show_live(timeline, frames, draw.parse_size(DEFAULT_SIZE), VIEW_FPS)


def render_command(args: argparse.Namespace) -> int:
    """Draw a run of a scene, or the poses of a bag, to an animation or a still."""
    draw, _, render = _viz()
    from .frames import bag_timeline, run_timeline

    scene = load_scene(args.scene)
    output = file_path(args.output if args.output is not None
                       else f"{Path(scene.source).stem}.gif")
    render.check_output(output)
    check_file(output, overwrite=args.overwrite)
    fps, size = _fps(args.fps), draw.parse_size(args.size)
    view = draw.parse_view(args.view) if args.view is not None else None
    trails = [draw.parse_trail(scene, text) for text in args.trail or []]
    timeline = bag_timeline(scene, args.bag) if args.bag else None
    start = args.start if args.start is not None else \
        (timeline.start_ns if timeline is not None else 0)
    duration = args.duration if args.duration is not None else \
        ((timeline.end_ns - start) if timeline is not None else scene.duration_ns)
    if timeline is not None:
        _check_in_session(timeline, start, duration)
    given = None if args.duration is None else args.duration.given
    render.check_span(output, size, start, duration, fps, given)  # before the run: fail fast
    if timeline is None:
        render.check_run(scene, start + duration)
        timeline = run_timeline(scene, start + duration)
    progress = Progress("render", duration * 1e-9)  # drawn when stderr is a terminal
    try:
        count = render.render(timeline, output, fps=fps, size=size, start_ns=start,
                              duration_ns=duration, view=view, trails=trails,
                              contacts=args.contacts, progress=progress,
                              overwrite=args.overwrite)
    finally:
        progress.close()
    print(f"wrote {count} frame(s) of {args.bag or args.scene}, sim time "
          f"{seconds(start)} s to {seconds(start + duration)} s, to {output}")
    return 0


def _check_in_session(timeline: Timeline, start_ns: int, duration_ns: int) -> None:
    """A bag's span must lie in its session: past its end every frame would show the last
    poses held, labelled with times the bag never reached."""
    first, last = seconds_text(timeline.start_ns), seconds_text(timeline.end_ns)
    if not timeline.start_ns <= start_ns < timeline.end_ns:
        raise VizError(f"--start {seconds_text(start_ns)} s: outside the bag's session, "
                       f"{first} s to {last} s")
    if start_ns + duration_ns > timeline.end_ns:
        raise VizError(f"--duration {seconds_text(duration_ns)} s: from --start "
                       f"{seconds_text(start_ns)} s it ends after the bag's session, at {last} s")


def plot_command(args: argparse.Namespace) -> int:
    """Plot the poses, twists (and, with a scene, energy) in one bag or two against time."""
    _, plot, _ = _viz()
    output = file_path(args.output)
    if output.suffix.lower() not in (".png", ".svg", ".pdf"):
        raise VizError(f"-o {output}: unknown plot type '{output.suffix}' (use .png, .svg, .pdf)")
    check_file(output, overwrite=args.overwrite)
    scene = load_scene(args.scene) if args.scene else None
    with replacing(output, overwrite=args.overwrite) as scratch:
        plot.plot_bags(scratch, args.bag, args.bag2, scene=scene)
    print(f"wrote {output}")
    return 0


def add_viz_commands(commands: argparse._SubParsersAction[argparse.ArgumentParser],
                     seconds: Callable[[str], int]) -> None:
    """Register ``render`` and ``plot``; ``seconds`` reads a time option into ns (an int
    whose ``given`` is the text read, for messages)."""
    render_parser = commands.add_parser(
        "render", help="draw a run of a scene or a bag's poses to GIF, MP4, PNG or SVG",
        description="Draw the bodies (filled, with their CM and a mark along their x axis), "
                    "springs, walls, the map's boxes, the applied forces as arrows from their "
                    "points of application, lasers' rays to their hits, optional contact "
                    "points and trails, and the sim time; "
                    "from a run of the scene with its script, or from the /<body>/pose "
                    "messages (and the inputs, where present) of a recorded or replayed bag. "
                    "A bag draws the same pixels as the run that produced it, but for the "
                    "drives' wheel forces, which a bag does not hold. PNG and SVG "
                    "show the last frame of the span with the whole span's trails.")
    render_parser.add_argument("scene", type=path_argument,
                               help="shipped scene name or path to a parameters file")
    render_parser.add_argument("-o", "--output", metavar="FILE",
                               help="FILE.gif, .mp4 (needs imageio-ffmpeg), .png or .svg "
                                    "(default: <scene>.gif)")
    render_parser.add_argument("--bag", type=path_argument,
                               help="draw this bag's poses instead of a run")
    render_parser.add_argument("--fps", default="20",
                               help="frames per second (default 20; a GIF at most 50)")
    render_parser.add_argument("--size", default=DEFAULT_SIZE,
                               help=f"WIDTHxHEIGHT in pixels (default {DEFAULT_SIZE})")
    render_parser.add_argument("--start", type=seconds, metavar="S",
                               help="sim time of the first frame, s (default: the "
                                    "session's start)")
    render_parser.add_argument("--duration", type=seconds, metavar="S",
                               help="span, s (default: the scene's duration or the bag's session)")
    render_parser.add_argument("--view", metavar="XMIN,YMIN,XMAX,YMAX",
                               help="the part of the plane to show, m (default: fits the "
                                    "bodies over the span and the walls near them)")
    render_parser.add_argument("--trail", action="append", metavar="BODY[/POINT]",
                               help="draw the path of a body's CM or named point (repeatable)")
    render_parser.add_argument("--contacts", action="store_true",
                               help="mark the contact points with walls and between bodies")
    render_parser.add_argument("--overwrite", action="store_true",
                               help="replace FILE if it exists")
    render_parser.set_defaults(handler=render_command)

    plot_parser = commands.add_parser(
        "plot", help="plot poses, twists and energy against time from one bag or two",
        description="Plot x, y, angle, vx, vy and omega of every body against sim time from "
                    "a bag's /<body>/pose and /<body>/twist messages, and the total energy "
                    "with --scene. With BAG2, overlay it (dashed) and plot BAG2 - BAG at the "
                    "stamps both hold.")
    plot_parser.add_argument("bag", metavar="BAG", type=path_argument)
    plot_parser.add_argument("bag2", metavar="BAG2", nargs="?", type=path_argument)
    plot_parser.add_argument("-o", "--output", default="plot.png", metavar="FILE.png",
                             help="picture to write (default plot.png)")
    plot_parser.add_argument("--scene", type=path_argument,
                             help="scene of the bag: adds the energy row")
    plot_parser.add_argument("--overwrite", action="store_true",
                             help="replace FILE.png if it exists")
    plot_parser.set_defaults(handler=plot_command)
