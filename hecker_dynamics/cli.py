"""``hecker-dynamics``: run scenes without ROS.

    hecker-dynamics run [SCENE] [--duration S] [--integrator NAME] [--step S] [--view]
    hecker-dynamics scenes
    hecker-dynamics script SCENE -o INPUT_BAG
    hecker-dynamics replay SCENE INPUT_BAG -o OUTPUT_BAG [--check]
    hecker-dynamics compare EXPECTED_BAG ACTUAL_BAG [--atol A]
    hecker-dynamics bench [--quick|--full] [--out DIR] [--scenes ...] [--peers|--no-peers]
    hecker-dynamics bench --node
    hecker-dynamics bench --joints
    hecker-dynamics bench --sensors
    hecker-dynamics render SCENE [-o FILE] [--bag BAG] [--fps F] [--size WxH] [--start S]
                           [--duration S] [--view X0,Y0,X1,Y1] [--trail BODY[/POINT]] [--contacts]
    hecker-dynamics plot BAG [BAG2] [-o FILE.png] [--scene SCENE]
    hecker-dynamics sweep SCENE --set NAME=VALUES ... [--samples N --seed S] -o RESULTS
    hecker-dynamics regress BAG_DIR ... [--scene SCENE] [--workers N] [--cluster ADDRESS]
"""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import decimal
import math
import os
import re
import signal
import sys
import threading
import time
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn, Optional

import numpy as np

from .bags.io import STORAGES, BagError
from .batch.engines import EngineError
from .batch.variants import MAX_VARIANTS
from .dynamics.simulation import PROGRESS_UPDATES, DivergenceError
from .files import OutputError, check_folder, path_argument
from .scene.commands import InputError
from .scene.load import (
    INTEGRATORS,
    Scene,
    SceneError,
    check_takes_a_step,
    load_scene,
    scene_summary,
    shipped_scenes,
    with_map,
)
from .scene.parameters import seconds_text
from .stops import Terminated, keeping_stops, raise_kept_stop, raise_terminated, stopped
from .viz.commands import add_viz_commands, view_run
from .viz.frames import VizError
from .viz.progress import Progress, stderr_is_terminal

if TYPE_CHECKING:
    from .bags.check import RecordingCheck
    from .bags.compare import Tolerances
    from .bags.io import BagContents
    from .batch.engines import Engine
    from .ros.runner import Runner

__all__ = ["configure", "run_command", "scenes_command", "script_command", "replay_command",
           "compare_command", "bench_command", "sweep_command", "regress_command", "parser", "main"]


class _Nanoseconds(int):
    """Nanoseconds read from a command line's seconds, with the seconds as ``given``: a
    message quotes those, not the whole nanoseconds they round to (1e-10 s is 0 ns)."""

    given: str


def _time_ns(text: str) -> int:
    """Seconds (exactly, however many digits: stamps of live bags are ~1.7e9 s) to ns."""
    try:
        value = decimal.Decimal(text)
    except decimal.InvalidOperation:
        raise argparse.ArgumentTypeError(f"not a number of seconds: {text}") from None
    if not value.is_finite() or value < 0:
        raise argparse.ArgumentTypeError(f"must be a non-negative number of seconds, not {text}")
    if value.adjusted() > 18:  # beyond any stamp; the nanoseconds would overflow the context
        raise argparse.ArgumentTypeError(f"must be at most 1e18 seconds, not {text}")
    ns = _Nanoseconds((value * 1_000_000_000).to_integral_value(decimal.ROUND_HALF_EVEN))
    ns.given = text
    return ns


def _duration_ns(text: str) -> int:
    """A sim duration: seconds, exactly as :func:`_time_ns` reads them, up to 1e9 s."""
    ns = _time_ns(text)
    if ns > 1_000_000_000 * 1_000_000_000:
        raise argparse.ArgumentTypeError(f"must be a number of seconds from 0 to 1e9, not {text}")
    return ns


def _step_ns(text: str) -> int:
    """A physics step: as :func:`_duration_ns`, and at least one whole nanosecond."""
    ns = _duration_ns(text)
    if ns < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1 ns, not {text}")
    return ns


def _positive(text: str) -> float:
    value = float(text)
    if not 0.0 < value <= 1e9:
        raise argparse.ArgumentTypeError(f"must be positive and at most 1e9, not {text}")
    return value


def configure(scene: Scene, args: argparse.Namespace) -> Scene:
    """Apply the command line's overrides (integrator, step, tolerance, map) to a scene.

    A step reads the scene's file again with it, as the node's ``-p step:=`` does: the
    publish, sensor and drive periods come anew from their rates, each a whole number of
    the new steps or refused (kept from the file's step, they would not be the rates)."""
    if args.step is not None:
        try:
            scene = load_scene(scene.source, step_ns=args.step)
        except SceneError as error:
            step = f"{decimal.Decimal(args.step).scaleb(-9).normalize():f}"  # as given, exactly
            raise SceneError(f"--step {step}: {error}") from None
    changes = {}
    if args.integrator:
        changes["integrator"] = args.integrator
    if args.tolerance is not None:
        changes["tolerance"] = args.tolerance
    if args.duration is not None:
        changes["duration_ns"] = int(args.duration)
    if args.map is not None:
        scene = with_map(scene, args.map)
    return dataclasses.replace(scene, **changes)


def _play(runner: Runner, span_ns: int, progress: Progress) -> dict[str, int]:
    """Advance ``runner`` ``span_ns`` past its start in whole publish periods, about
    ``PROGRESS_UPDATES`` times, telling ``progress``; the count of each sensor topic's
    readings."""
    period = runner.scene.publish_period_ns
    chunk = period * max(1, span_ns // (PROGRESS_UPDATES * period))
    readings: dict[str, int] = {}
    done = 0
    while done < span_ns:
        done = min(span_ns, done + chunk)
        tick = runner.advance(runner.sim.start_ns + done, keep=False)  # two states printed
        if tick.diverged is not None:
            raise DivergenceError(tick.diverged)
        if tick.script_errors:
            raise InputError(tick.script_errors[0])
        for _, reading in tick.readings:
            readings[reading.topic] = readings.get(reading.topic, 0) + 1
        progress(done / span_ns)
    return readings


def _check_takes_a_step(duration_ns: int, scene: Scene, args: argparse.Namespace) -> None:
    """:func:`check_takes_a_step`, naming ``--duration`` as given if given, else the
    scene's."""
    if args.duration is not None:
        check_takes_a_step(duration_ns, scene.step_ns, "--duration", given=args.duration.given)
    else:
        check_takes_a_step(duration_ns, scene.step_ns, f"{scene.source}: duration")


def run_command(args: argparse.Namespace) -> int:
    """Run a scene as the node runs it (its script, drives and sensors) and print a
    summary."""
    from .ros.runner import Runner

    scene = configure(load_scene(args.scene), args)
    _check_takes_a_step(scene.duration_ns, scene, args)
    if args.view:
        view_run(scene)
    runner = Runner(scene)
    sim = runner.sim
    first = sim.snapshot()
    progress = Progress("run", scene.duration_ns * 1e-9, enabled=_want_progress(args))
    started = time.perf_counter()
    try:
        readings = _play(runner, scene.duration_ns, progress)
    finally:
        progress.close()
    wall = time.perf_counter() - started
    last = sim.snapshot()
    sim_seconds = (last.time_ns - first.time_ns) * 1e-9
    print(f"scene       {scene.source}")
    print(f"integrator  {sim.integrator.name}" + (" (auto)" if scene.integrator == "auto" else ""))
    print(f"step        {seconds_text(scene.step_ns)} s, {last.steps} steps, "
          f"{sim.integrator.counters.evaluations} force evaluations")
    print(f"sim time    {sim_seconds:g} s in {wall:.3f} s wall "
          f"({sim_seconds / wall if wall > 0 else float('inf'):.1f}x real time)")
    print(f"energy      {first.energy:.6g} J -> {last.energy:.6g} J")
    if readings:
        print("sensors     " + ", ".join(f"{topic} {count}" for topic, count in readings.items()))
    print(f"{'body':<12}{'x':>12}{'y':>12}{'angle':>12}{'vx':>12}{'vy':>12}{'omega':>12}")
    for body in last.bodies:
        print(f"{body.name:<12}{body.position[0]:>12.5f}{body.position[1]:>12.5f}"
              f"{body.angle:>12.5f}{body.linear_velocity[0]:>12.5f}"
              f"{body.linear_velocity[1]:>12.5f}{body.angular_velocity:>12.5f}")
    return 0


def scenes_command(args: argparse.Namespace) -> int:
    """List the shipped scenes, each with its file's one-line summary."""
    names = shipped_scenes()
    width = max((len(name) for name in names), default=0)
    for name in names:
        print(f"{name:<{width}}  {scene_summary(name)}".rstrip())
    return 0


# ----------------------------------------------------------------------------- bags

def _tolerance(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text}") from None
    if not 0.0 <= value < math.inf:  # an infinite tolerance would compare nothing
        raise argparse.ArgumentTypeError(f"must be a finite non-negative number, not {text}")
    return value


def _want_progress(args: argparse.Namespace) -> bool:
    return args.progress if args.progress is not None else stderr_is_terminal()


def _tolerances(args: argparse.Namespace) -> Tolerances:
    from .bags.compare import Tolerances

    atol = args.atol
    return Tolerances(
        position=args.atol_position if args.atol_position is not None else atol,
        angle=args.atol_angle if args.atol_angle is not None else atol,
        velocity=args.atol_velocity if args.atol_velocity is not None else atol)


def _check_storage(args: argparse.Namespace) -> None:
    """Refuse --compress with a storage it does not apply to, rather than ignore it; then
    take mcap where --storage was not given (None until here, so that a command can tell
    an mcap asked for from the default)."""
    if args.compress and args.storage not in (None, "mcap"):
        raise BagError(f"--compress compresses mcap chunks; --storage {args.storage} has "
                       "none (leave out one of them)")
    if args.storage is None:
        args.storage = "mcap"


def script_command(args: argparse.Namespace) -> int:
    """Write a scene's scripted inputs into an input bag."""
    from .bags.replay import check_session, script_to_bag

    _check_storage(args)
    scene = load_scene(args.scene)
    duration = scene.duration_ns if args.duration is None else args.duration
    _check_takes_a_step(duration, scene, args)
    check_session(args.start, duration, "script:", ("--start", "--duration"))
    count = script_to_bag(scene, Path(args.output), storage=args.storage, start_ns=args.start,
                          duration_ns=args.duration, overwrite=args.overwrite,
                          compress=args.compress)
    print(f"wrote {count} AppliedWrench message(s) of scene {scene.source} to {args.output} "
          f"({args.storage})")
    return 0


def replay_command(args: argparse.Namespace) -> int:
    """Replay an input bag on a scene, write the outputs, optionally check them."""
    from .bags.check import RecordingCheck, check_outputs, on_the_recorded_path
    from .bags.coverage import seconds
    from .bags.io import read_bag
    from .bags.live import is_live_recording
    from .bags.replay import (
        check_distinct,
        input_topics,
        outputs_as_bag,
        recorded_output_topics,
        replay_outputs,
        replay_to_bag,
        session_times,
    )

    if args.output is None and not args.check:
        raise BagError("nothing to do: give -o OUTPUT_BAG, --check, or both")
    if (args.topic or args.partial) and not args.check:
        raise BagError("--topic and --partial say what --check compares; give --check")
    if args.output is None and (args.with_inputs or args.compress or args.overwrite
                                or args.storage is not None):
        raise BagError("--storage, --compress, --overwrite and --with-inputs say how -o writes "
                       "its bag; give -o OUTPUT_BAG")
    _check_storage(args)
    if args.output is not None:
        check_distinct(Path(args.output), [Path(args.input)])
    scene = load_scene(args.scene)
    if args.duration is not None:
        _check_takes_a_step(args.duration, scene, args)
    bag = read_bag(args.input)
    if is_live_recording(bag):
        return _replay_live(args, scene, bag)
    # A check against a recording of the node compares the TF it recorded too.
    tf = args.tf or (args.check and ("/tf" in bag.topics or "/tf" in (args.topic or ())))
    if args.check:
        recorded_output_topics(scene, bag, need_inputs=not args.play_script, tf=tf,
                               topics=args.topic)
    start, end = session_times(scene, bag, args.start, args.duration)
    options = dict(start_ns=start, duration_ns=end - start, play_script=args.play_script,
                   skip_rejected=args.skip_rejected, tf=tf)
    progress = Progress("replay", (end - start) * 1e-9, enabled=True) \
        if _want_progress(args) else None
    try:
        if args.output is not None:
            result = replay_to_bag(scene, bag, Path(args.output), storage=args.storage,
                                   overwrite=args.overwrite, with_inputs=args.with_inputs,
                                   compress=args.compress, progress=progress, **options)
        else:
            produced, result = replay_outputs(scene, bag, progress=progress, **options)
    finally:
        if progress is not None:
            progress.close()
    inputs = [t for t in input_topics(scene) if t in bag.topics]
    written = f" written to {args.output}" if args.output and not result.halted else ""
    print(f"replayed {result.inputs} input message(s) from {', '.join(inputs) or 'no topic'} "
          f"on scene {scene.source}: {result.accepted} accepted, {len(result.rejected)} "
          f"rejected; sim time {seconds(start)} s to {seconds(result.reached_ns)} s, "
          f"{result.steps} steps, {result.outputs} output message(s){written}"
          + (f"; the state diverged after {seconds(result.reached_ns)} s, so no bag was "
             "written" if result.halted and args.output else ""))
    if result.halted:
        print(f"hecker-dynamics: error: {result.halted}", file=sys.stderr)
        return 2
    for line in result.rejected[:5]:
        print(f"hecker-dynamics: warning: input rejected: {line}", file=sys.stderr)
    if len(result.rejected) > 5:
        print(f"hecker-dynamics: warning: ... and {len(result.rejected) - 5} more rejected",
              file=sys.stderr)
    for line in sorted(set(result.warnings))[:5]:
        print(f"hecker-dynamics: warning: {line}", file=sys.stderr)
    if result.ignored_after_end:
        print(f"hecker-dynamics: warning: {result.ignored_after_end} input message(s) after "
              "the end of the session were not replayed", file=sys.stderr)
    if not args.check:
        return 0
    actual = read_bag(args.output) if args.output is not None else \
        outputs_as_bag(scene, produced, tf=tf)

    def check(actual: BagContents) -> RecordingCheck:
        report, coverage = check_outputs(scene, bag, actual, tolerances=_tolerances(args),
                                         tf=tf, topics=args.topic, partial=args.partial)
        return RecordingCheck(args.input, report, coverage, live=False)

    # -o holds this path's replay; a recording of the other path is checked in memory.
    verdict, note = on_the_recorded_path(
        scene, lambda: check(outputs_as_bag(scene, replay_outputs(scene, bag, **options)[0],
                                            tf=tf)),
        lambda verdict: verdict.ok, first=check(actual))
    if note is not None:
        verdict.coverage.notes.insert(0, note)
    return _verdict(args, verdict)


def _verdict(args: argparse.Namespace, check: RecordingCheck) -> int:
    """Print a check's report and its one-line verdict; exit status 0 or 1."""
    for line in check.lines(args.verbose):
        print(line)
    print(_one_line(f"check against the recording {args.input}: {check.verdict()}"))
    return 0 if check.ok else 1


def _replay_live(args: argparse.Namespace, scene: Scene, bag: BagContents) -> int:
    """Replay a session recorded from the node with its session records (bags.live)."""
    from .bags.check import RecordingCheck, on_the_recorded_path
    from .bags.io import BagWriter
    from .bags.live import check_live
    from .bags.replay import output_types

    given = [name for name, value in (("--start", args.start is not None),
                                      ("--duration", args.duration is not None),
                                      ("--play-script", args.play_script),
                                      ("--skip-rejected", args.skip_rejected)) if value]
    if given:
        raise BagError(f"{args.input}: a recorded session replays with the options the node "
                       f"recorded; {', '.join(given)} "
                       f"{'does' if len(given) == 1 else 'do'} not apply to it")
    # Without --check, replay what the records allow (as --partial does) and write it.
    live, note = on_the_recorded_path(
        scene, lambda: check_live(scene, bag, tolerances=_tolerances(args), topics=args.topic,
                                  partial=args.partial or not args.check),
        lambda live: live.ok or live.halted is not None or not args.check)
    if note is not None:
        live.coverage.notes.insert(0, note)
    if live.halted:
        raise BagError(f"{args.input}: {live.halted}" + (
            "; no bag was written" if args.output is not None else ""))
    if args.output is not None:
        with BagWriter(Path(args.output), args.storage, overwrite=args.overwrite,
                       custom_data={"scene": Path(scene.source).stem},
                       compress=args.compress) as writer:
            for topic, msgtype in output_types(scene).items():
                writer.add_topic(topic, msgtype)
            for output in sorted(live.outputs, key=lambda o: o.log_ns):
                writer.write(output.topic, output.msgtype, output.log_ns, output.msg)
    print(f"replayed {live.sessions} session(s) of {args.input} on scene {scene.source} from "
          f"the node's records: {live.events} input and world event(s), "
          f"{live.keyframes_checked} keyframe(s) compared, {len(live.outputs)} output "
          "message(s)"
          + (f" written to {args.output}" if args.output else ""))
    if not args.check:
        for note in live.notes + live.problems:
            print(f"hecker-dynamics: note: {note}", file=sys.stderr)
        return 0
    return _verdict(args, RecordingCheck(args.input, live.report, live.coverage, live=True,
                                         sessions=live.sessions))


def compare_command(args: argparse.Namespace) -> int:
    """Compare two bags; exit 1 on a mismatch."""
    from .bags.compare import compare_bags

    report, ok = compare_bags(args.expected, args.actual, tolerances=_tolerances(args),
                              topics=args.topic or None)
    if not ok or args.verbose:
        print(report.text())
    else:
        print(report.summary())
    return 0 if ok else 1


def _add_tolerance_options(parser: argparse.ArgumentParser) -> None:
    from .bags.compare import DEFAULT_ATOL

    parser.add_argument("--atol", type=_tolerance, default=DEFAULT_ATOL,
                        help=f"absolute tolerance for positions (m), angles (rad) and "
                             f"velocities (default {DEFAULT_ATOL:g})")
    parser.add_argument("--atol-position", type=_tolerance, help="override --atol for positions")
    parser.add_argument("--atol-angle", type=_tolerance, help="override --atol for angles")
    parser.add_argument("--atol-velocity", type=_tolerance,
                        help="override --atol for linear and angular velocities")
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="print the full per-topic report even when the bags match")


def _add_coverage_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--topic", action="append", metavar="TOPIC",
                        help="check only this output topic (repeatable), for a recording "
                             "that holds some topics on purpose; by default every output "
                             "topic of the scene must be recorded")
    parser.add_argument("--partial", action="store_true",
                        help="accept a recording that lacks topics, stretches of outputs or "
                             "records, and name what was not checked")


def _add_writer_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--storage", choices=STORAGES, default=None,
                        help="storage of the written bag (default mcap, as Jazzy records)")
    parser.add_argument("--compress", action="store_true",
                        help="zstd-compress the mcap chunks (like Jazzy's zstd_fast preset)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace the output bag if it exists")


def _add_progress_options(parser: argparse.ArgumentParser) -> None:
    progress_group = parser.add_mutually_exclusive_group()
    progress_group.add_argument("--progress", dest="progress", action="store_true", default=None,
                                help="show a progress bar on stderr (default: when stderr is "
                                     "a terminal)")
    progress_group.add_argument("--no-progress", dest="progress", action="store_false",
                                help="never show a progress bar")


def _add_bag_commands(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    script_parser = commands.add_parser(
        "script", help="write a scene's scripted inputs into an input bag",
        description="Turn a scene's scripted inputs into a rosbag2 bag: one "
                    "hecker_dynamics/msg/AppliedWrench message on /applied_wrench per scripted "
                    "command, stamped and logged at its start time. The scene's WrenchStamped "
                    "topics are declared too. The bag records the session start and duration, "
                    "so 'replay' reproduces the scene's run.")
    script_parser.add_argument("scene", type=path_argument,
                               help="shipped scene name or path to a parameters file")
    script_parser.add_argument("-o", "--output", required=True, metavar="INPUT_BAG",
                               type=path_argument,
                               help="bag directory to create")
    script_parser.add_argument("--start", type=_time_ns, default=0, metavar="S",
                               help="sim time at which the session starts, s (default 0)")
    script_parser.add_argument("--duration", type=_time_ns, metavar="S",
                               help="session length, s (default: the scene's duration); the "
                                    "session must end by 2147483647 s, the latest time a "
                                    "ROS stamp holds")
    _add_writer_options(script_parser)
    script_parser.set_defaults(handler=script_command)

    replay_parser = commands.add_parser(
        "replay", help="replay an input bag on a scene and write the node's outputs",
        description="Read AppliedWrench (/applied_wrench) and the scene's WrenchStamped "
                    "inputs from a rosbag2 bag (mcap or sqlite3), drive the simulation with "
                    "the node's stamp rules (a zero stamp means the log time), and write "
                    "what the node publishes (/<body>/pose, /<body>/twist and the optional "
                    "topics the scene enables) into a new bag, logged at sim time. With "
                    "--check, compare the replay with everything the input bag records (a "
                    "session recorded with 'ros2 bag record -a'): every output on every "
                    "topic the scene publishes, and the node's records; exit 1 on a "
                    "mismatch, or when a topic, a stretch of outputs or a record is missing "
                    "(see --topic, --partial).")
    replay_parser.add_argument("scene", type=path_argument,
                               help="shipped scene name or path to a parameters file")
    replay_parser.add_argument("input", metavar="INPUT_BAG", type=path_argument,
                               help="bag with the input messages")
    replay_parser.add_argument("-o", "--output", metavar="OUTPUT_BAG", type=path_argument,
                               help="bag directory to create with the outputs")
    replay_parser.add_argument("--check", action="store_true",
                               help="compare the replay with the outputs recorded in INPUT_BAG")
    replay_parser.add_argument("--start", type=_time_ns, metavar="S",
                               help="sim time at which the session starts, s (default: from "
                                    "the bag: its recorded start, one publish period before "
                                    "its first pose, or its first message); not after "
                                    "the bag's end")
    replay_parser.add_argument("--duration", type=_time_ns, metavar="S",
                               help="session length, s (default: the bag's recorded length, "
                                    "its last pose, or the scene's duration)")
    replay_parser.add_argument("--play-script", action="store_true",
                               help="also push the scene's scripted inputs (as the node does "
                                    "with play_script); off by default since 'script' bags "
                                    "hold them")
    replay_parser.add_argument("--skip-rejected", action="store_true",
                               help="drop inputs for unknown bodies or frames (as the node "
                                    "does) instead of failing")
    replay_parser.add_argument("--tf", action="store_true",
                               help="write /tf and /tf_static as the node publishes them "
                                    "(when the scene's publish.tf is on; --check against a "
                                    "bag with /tf turns it on)")
    replay_parser.add_argument("--with-inputs", action="store_true",
                               help="copy the input messages into the output bag too")
    _add_progress_options(replay_parser)
    _add_writer_options(replay_parser)
    _add_tolerance_options(replay_parser)
    _add_coverage_options(replay_parser)
    replay_parser.set_defaults(handler=replay_command)

    compare_parser = commands.add_parser(
        "compare", help="compare two bags topic by topic",
        description="Match the messages of each topic by stamp (Twist by its pose's stamp "
                    "or its log time) and report the largest position, angle and velocity "
                    "differences and the missing or extra messages and topics. Exit 0 when "
                    "the bags match within the tolerances, 1 when they do not, 2 on an error.")
    compare_parser.add_argument("expected", metavar="EXPECTED_BAG", type=path_argument)
    compare_parser.add_argument("actual", metavar="ACTUAL_BAG", type=path_argument)
    compare_parser.add_argument("--topic", action="append", metavar="TOPIC",
                                help="compare only this topic (repeatable)")
    _add_tolerance_options(compare_parser)
    compare_parser.set_defaults(handler=compare_command)


def bench_command(args: argparse.Namespace) -> int:
    """Run the work-precision benchmark and write its report (``--node``: the node's cost;
    ``--sensors``: the laser's and the robot node's; ``--contacts``: the contact section;
    ``--batch``: sweeps' speed-up)."""
    enabled = _want_progress(args)

    def bar(label: str, parts: int) -> Progress:
        return Progress(label, parts, unit="parts", enabled=enabled)

    if args.node:
        from .bench.node import TARGET_SHARE, node_cost, node_table

        costs = node_cost(bar=bar)
        print("node work per second of sim time (share of one core): 1 kHz steps, 50 Hz "
              "publishing, odometry, markers, diagnostics and TF on; medians of "
              f"{costs[0].repeats} interleaved runs of 2 s")
        print(node_table(costs))
        ten = next((c for c in costs if c.bodies == 10), None)
        if ten is not None:
            print(f"10 bodies: {100 * ten.total:.2f} % of a core "
                  f"({'within' if ten.total <= TARGET_SHARE else 'over'} the "
                  f"{100 * TARGET_SHARE:g} % target)")
        return 0
    if args.sensors:
        from .bench.sensors import node_shares, scan_costs, sensor_report

        print(sensor_report(scan_costs(peer=args.peers, bar=bar), node_shares(bar=bar)))
        return 0
    from .bench.run import run_bench
    from .bench.scenes import all_scene_names

    if args.batch:
        from .bench.batch import bench_batch

        bench_batch(rounds=args.rounds, bar=bar)
        return 0
    command = "hecker-dynamics " + " ".join(sys.argv[1:]) if sys.argv[1:2] == ["bench"] \
        else "hecker-dynamics bench"
    if args.joints:
        from .bench.joints import JOINT_FILES, joint_bench
        from .bench.joints import PEERS as JOINT_PEERS

        out = _bench_out(args, JOINT_FILES)
        with _bench_writing(out):
            joint_bench(list(JOINT_PEERS) if args.peers else [], out, command)
        print(f"wrote {out}")
        return 0
    if args.contacts is not None:
        from .bench.contacts import (
            CONTACT_FILES,
            PYRAMID_ROWS,
            contact_bench,
            contact_scene_names,
            targets,
        )
        from .bench.scene_peers import SCENE_PEERS

        known = contact_scene_names()
        for name in args.scenes or []:
            if name not in known:
                raise SceneError(f"--scenes {name}: not a contact scene (known: "
                                 f"{', '.join(known)})")
        out = _bench_out(args, CONTACT_FILES)
        with _bench_writing(out):
            results = contact_bench(args.contacts or list(PYRAMID_ROWS),
                                    list(SCENE_PEERS) if args.peers else [], out,
                                    command, scenes=args.scenes, bar=bar)
        for target, measured, verdict in targets(results):
            print(f"target {target}: {measured}: {verdict}")
        print(f"wrote {out}")
        return 0
    from .bench.report import REPORT_FILES

    known = all_scene_names()
    for name in args.scenes or []:
        if name not in known:
            raise SceneError(f"unknown benchmark scene '{name}' (known: {', '.join(known)})")
    if args.full and args.save_reference:
        raise SceneError("--save-reference: the guard's reference is a quick run's ratios")
    from .bench.regression import REFERENCE

    out = _bench_out(args, REPORT_FILES)
    with _bench_writing(out):
        run_bench("full" if args.full else "quick", out, args.scenes, args.peers,
                  command=command, bar=bar,
                  reference=None if args.full else Path(args.reference or REFERENCE),
                  save_reference=args.save_reference)
    return 0


def _bench_out(args: argparse.Namespace, names: Sequence[str]) -> Path:
    """``--out``, checked for the files the bench writes there; by default a new folder
    under the system's temporary folder, so a bench run in a clone leaves its tracked
    report alone."""
    if args.out is None:
        from .bench.report import new_report_folder

        return new_report_folder()
    return check_folder(args.out, option="--out", names=names, overwrite=args.overwrite)


@contextlib.contextmanager
def _bench_writing(out: Path) -> Iterator[None]:
    """The report is written at the end of the run: a failure then is one line too."""
    try:
        yield
    except OSError as error:
        raise OutputError(f"--out {out}: cannot write the report: {error}") from None


def _rows(text: str) -> int:
    """A pyramid's row count: a whole number from 1 to 100."""
    try:
        rows = int(text)
    except ValueError:
        rows = 0
    if not 1 <= rows <= 100:
        raise argparse.ArgumentTypeError(f"rows must be a whole number from 1 to 100, not '{text}'")
    return rows


def _add_bench_command(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    bench = commands.add_parser(
        "bench", help="measure error against cost for every integrator (work-precision)",
        description="Run every integrator over a sweep of steps (and tolerances of the "
                    "adaptive methods) on the benchmark scenes and the shipped scenes, "
                    "against exact or reference solutions, with pymunk, Box2D and MuJoCo "
                    "when installed, and the ring scale test against a plain C loop; write "
                    "CSV, Markdown and a figure.")
    size = bench.add_mutually_exclusive_group()
    size.add_argument("--quick", dest="full", action="store_false", default=False,
                      help="small sweep, about 1-2 minutes (default)")
    size.add_argument("--full", dest="full", action="store_true",
                      help="the documented sweep, up to about 20 minutes")
    bench.add_argument("--out", metavar="DIR",
                       help="folder to write the report into (default: a new folder under "
                            "the system's temporary folder, printed at the end)")
    bench.add_argument("--overwrite", action="store_true",
                       help="replace the report files in --out DIR if they exist")
    bench.add_argument("--scenes", nargs="+", metavar="SCENE", type=path_argument,
                       help="benchmark or shipped scenes to run (default: all)")
    bench.add_argument("--reference", metavar="FILE", type=path_argument,
                       help="with --quick: compare the run's cost ratios with this file's "
                            "and say which moved by more than their noise (default: "
                            "bench/reference_ratios.json in the installed package)")
    bench.add_argument("--save-reference", action="store_true",
                       help="with --quick: write the run's ratios to --reference instead")
    bench.add_argument("--joints", action="store_true",
                       help="only the joint section, with its targets: chains of 2 to 200 "
                            "links, the bridge, the ragdoll and Box2D's joint grid against "
                            "pymunk, Box2D 2.3 and Box2D v3, a chain of 1000 pins renamed, "
                            "and the seesaw and door on joints against springs (writes "
                            "joints.md and joints.csv)")
    bench.add_argument("--contacts", nargs="*", type=_rows, metavar="ROWS",
                       help="instead: the contact section against pymunk, Box2D 2.3 and "
                            "Box2D v3, with its targets: pyramids of these rows of boxes "
                            "(default 3 6 10 14 20 30 50 100), the box of 100 balls, the "
                            "many pyramids, the tumbler and the shipped contact scenes over "
                            "their full durations (--scenes narrows them), and the node's "
                            "cost with a floor (writes contacts.md, contacts.csv)")
    peers = bench.add_mutually_exclusive_group()
    peers.add_argument("--peers", dest="peers", action="store_true", default=True,
                       help="include installed peers (default)")
    peers.add_argument("--no-peers", dest="peers", action="store_false", help="core only")
    bench.add_argument("--batch", action="store_true",
                       help="instead: the speed-up of sweeps over one process (1,000 short "
                            "and 50 long variants; see docs/batch.md)")
    bench.add_argument("--rounds", type=_workers, default=1,
                       help="with --batch: interleaved rounds, medians reported (default 1)")
    bench.add_argument("--node", action="store_true",
                       help="instead: the node's own work per tick without rclpy (stepping "
                            "and output messages) on rings of 1, 10 and 100 bodies; prints a "
                            "table, writes nothing")
    bench.add_argument("--sensors", action="store_true",
                       help="instead: a 360-ray laser scan among 100 bodies against Box2D "
                            "v3's ray casts and a plain numpy caster, and the robot scene's "
                            "node cost at 1 kHz with its 10 Hz scan; prints tables, writes "
                            "nothing")
    _add_progress_options(bench)
    bench.set_defaults(handler=bench_command)


# ----------------------------------------------------------------------------- batch

def _engine(args: argparse.Namespace) -> Engine:
    from .batch.engines import make_engine

    engine = make_engine(args.workers, args.cluster)
    for note in engine.notes:
        print(f"hecker-dynamics: warning: {note}", file=sys.stderr)
    if engine.dashboard:
        print(f"hecker-dynamics: Dask dashboard at {engine.dashboard}", file=sys.stderr)
    return engine


def sweep_command(args: argparse.Namespace) -> int:
    """Run every variant of a scene and write the table of their summaries."""
    from .batch.metrics import parse_metric
    from .batch.run import bag_names, check_metrics, sweep
    from .batch.table import check_table, partial_path
    from .batch.variants import make_variants, parse_setting

    output = check_table(args.output, overwrite=args.overwrite)
    settings = [parse_setting(text) for text in args.set]
    metrics = [parse_metric(text) for text in args.metric or []]
    if args.seed is not None and args.samples is None:
        raise SceneError("--seed needs --samples")
    given = None if args.duration is None else args.duration.given
    variants = make_variants(args.scene, settings, samples=args.samples, seed=args.seed or 0,
                             duration_ns=args.duration, duration_given=given)
    check_metrics(metrics, variants)
    bags = None
    if args.bags is not None:
        bags = check_folder(args.bags, option="--bags", names=bag_names(variants),
                            overwrite=args.overwrite)
        if bags.resolve() in (output.resolve(), partial_path(output).resolve()):
            raise OutputError(f"--bags {args.bags}: is where -o writes the table")
        # A bag is written whole, in place of what was there: a table inside it would go.
        for name in bag_names(variants):
            if (bags / name).resolve() in output.resolve().parents:
                raise OutputError(f"-o {args.output}: is inside {bags / name}, a bag --bags "
                                  "writes over")
    engine = _engine(args)
    try:
        path = sweep(variants, engine, output, metrics=metrics, bags=bags,
                     progress=_want_progress(args), overwrite=args.overwrite)
    finally:
        engine.close()
    print(f"wrote {len(variants)} variant(s) of {args.scene} to {path} "
          f"({engine.workers} worker(s))")
    return 0


def regress_command(args: argparse.Namespace) -> int:
    """``replay --check`` over many bags; exit 1 on a mismatch, 2 on a bag that fails."""
    from .batch.run import find_bags, regress

    bags = find_bags([Path(p) for p in args.bags])
    if args.scene is not None:
        load_scene(args.scene)  # a bad scene fails once, before any work
    if args.scene_dir is not None and not Path(args.scene_dir).is_dir():
        raise BagError(f"--scene-dir {args.scene_dir}: " + (
            "not a folder" if Path(args.scene_dir).exists() else "no such folder"))
    engine = _engine(args)
    try:
        results = regress(bags, engine, scene=args.scene, tolerances=_tolerances(args),
                          emit=lambda result: print(_one_line(result.line()), flush=True),
                          progress=_want_progress(args), scene_dir=args.scene_dir,
                          topics=args.topic, partial=args.partial)
    finally:
        engine.close()
    counts = {status: sum(r.status == status for r in results)
              for status in ("ok", "mismatch", "error")}
    print(f"{len(results)} bag(s): {counts['ok']} ok, {counts['mismatch']} mismatch, "
          f"{counts['error']} error")
    return 2 if counts["error"] else 1 if counts["mismatch"] else 0


def _whole(text: str, low: int, high: int) -> int:
    """A whole number from ``low`` to ``high``."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text}") from None
    if not low <= value <= high:
        raise argparse.ArgumentTypeError(f"must be a whole number from {low} to {high}, "
                                         f"not {text}")
    return value


#: The most worker processes: each is a Python with numpy (some 60 MB); more than this
#: would only fill the memory.
MAX_WORKERS = 256


def _workers(text: str) -> int:
    return _whole(text, 1, MAX_WORKERS)


def _samples(text: str) -> int:
    return _whole(text, 1, MAX_VARIANTS)


def _seed(text: str) -> int:
    return _whole(text, 0, 2 ** 64 - 1)


def _add_engine_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--workers", type=_workers, metavar="N",
                        help="worker processes on this machine (default: all cores); with "
                             "--cluster local, the cluster's workers")
    parser.add_argument("--cluster", metavar="ADDRESS",
                        help="run on the Dask scheduler at ADDRESS (tcp://host:8786), or "
                             "'local' for a Dask cluster on this machine that retries the "
                             "task of a worker that dies (needs the cluster extra)")
    _add_progress_options(parser)


def _add_batch_commands(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    sweep_parser = commands.add_parser(
        "sweep", help="run a scene over a grid or a random sample of its parameters",
        description="Run the variants of a scene that --set makes (a grid of every "
                    "combination, or --samples N draws seeded by --seed) for its duration "
                    "with its script, and write one row per variant: final states, energy, "
                    "divergence, contacts, per-body extrema and --metric expressions "
                    "(Parquet if pyarrow is installed, else CSV; rows by variant, the same "
                    "bytes however many workers ran). See docs/batch.md.")
    sweep_parser.add_argument("scene", type=path_argument,
                              help="shipped scene name or path to a parameters file")
    sweep_parser.add_argument("--set", action="append", required=True, metavar="NAME=VALUES",
                              help="a parameter and its values: a,b,c (a list), "
                                   "start:stop:count (evenly spaced, both ends included) or "
                                   "start:stop (an interval, with --samples); repeatable")
    sweep_parser.add_argument("--samples", type=_samples, metavar="N",
                              help=f"draw N random variants instead of the grid (at most "
                                   f"{MAX_VARIANTS}, as many as a grid may have)")
    sweep_parser.add_argument("--seed", type=_seed, metavar="S",
                              help="seed of the random draws, 0 to 2**64 - 1 (default 0)")
    sweep_parser.add_argument("--duration", type=_duration_ns, metavar="S",
                              help="sim seconds of every variant (default: the scene's)")
    sweep_parser.add_argument("--metric", action="append", metavar="[NAME=]EXPRESSION",
                              help="a column computed from the final row, e.g. "
                                   "gap=right.x-left.x; repeatable")
    sweep_parser.add_argument("--bags", metavar="DIR",
                              help="also write each variant's inputs and outputs as a bag "
                                   "(and its parameters file) into DIR, for 'regress'")
    sweep_parser.add_argument("-o", "--output", required=True, metavar="RESULTS",
                              help="table to write (.parquet or .csv; without a suffix, "
                                   "Parquet if pyarrow is installed, else CSV)")
    sweep_parser.add_argument("--overwrite", action="store_true",
                              help="replace the table, its partial file and the bags in "
                                   "--bags DIR if they exist")
    _add_engine_options(sweep_parser)
    sweep_parser.set_defaults(handler=sweep_command)

    regress_parser = commands.add_parser(
        "regress", help="replay --check over many bags in parallel",
        description="Replay every bag and check it against what it records, as "
                    "'replay SCENE BAG --check' does; one line per bag and a summary. The "
                    "scene is --scene, else the bag's hecker_dynamics.scene custom data: a "
                    "name (no directory) of a parameters file in --scene-dir (default: the "
                    "directory that holds the bag), else of a shipped scene. Exit 0 when all "
                    "match, 1 on a mismatch, 2 when a bag cannot be checked.")
    regress_parser.add_argument("bags", nargs="+", metavar="BAG_DIR", type=path_argument,
                                help="a bag directory, or a directory that holds bag directories "
                                     "(at any depth)")
    regress_parser.add_argument("--scene", type=path_argument, help="the scene of every bag")
    regress_parser.add_argument("--scene-dir", metavar="DIR", type=path_argument,
                                help="where the parameters files the bags name are (default: "
                                     "the directory that holds each bag, as 'sweep --bags' "
                                     "writes them)")
    _add_engine_options(regress_parser)
    _add_tolerance_options(regress_parser)
    _add_coverage_options(regress_parser)
    regress_parser.set_defaults(handler=regress_command)


class _Parser(argparse.ArgumentParser):
    """argparse's parser refusing bad arguments in one line, as every other error is: the
    command, what is wrong, and where the help is (``--help`` prints the usage).

    A word that starts with a minus and a digit is a value, as Python 3.13's argparse
    takes it (no option of ours looks so): ``--view -3,0,3,5`` and ``--atol -1e-9`` reach
    their checks instead of "expected one argument"."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"-\.?\d")

    def error(self, message: str) -> NoReturn:
        command = self.prog.removeprefix("hecker-dynamics").strip()
        where = f"{command}: " if command else ""
        self.exit(2, f"hecker-dynamics: error: {where}{_one_line(message)} (see "
                     f"'{self.prog} --help')\n")


def parser() -> argparse.ArgumentParser:
    top: argparse.ArgumentParser = _Parser(
        prog="hecker-dynamics",
        description="2D rigid-body dynamics after Chris Hecker's 'Physics, Part 2: Angular "
                    "Effects', without ROS.")
    commands = top.add_subparsers(dest="command", required=True, metavar="COMMAND")

    run_parser = commands.add_parser(
        "run", help="run a scene with its scripted inputs and print a summary",
        description="Run a scene (a shipped scene name or a ROS 2 parameters file; the "
                    "default scene when none is given) with its scripted inputs.")
    run_parser.add_argument("scene", nargs="?", default=None, type=path_argument,
                            help="shipped scene name or path to a parameters file")
    run_parser.add_argument("--duration", type=_duration_ns,
                            help="sim seconds (default: the scene's)")
    run_parser.add_argument("--integrator", choices=INTEGRATORS, help="override the integrator")
    run_parser.add_argument("--step", type=_step_ns, help="override the physics step, s")
    run_parser.add_argument("--tolerance", type=_positive,
                            help="override the tolerance of dopri5, dop853 / auto")
    run_parser.add_argument("--map", metavar="FILE", type=path_argument,
                            help="a Nav2 map YAML whose occupied cells the bodies collide with "
                                 "(replaces the scene's map.file)")
    run_parser.add_argument("--view", action="store_true",
                            help="show the run in a window (needs a display and the viz extra)")
    _add_progress_options(run_parser)
    run_parser.set_defaults(handler=run_command)

    list_parser = commands.add_parser("scenes", help="list the shipped scenes",
                                      description="List the shipped scenes, one line each.")
    list_parser.set_defaults(handler=scenes_command)
    _add_bag_commands(commands)
    _add_bench_command(commands)
    _add_batch_commands(commands)
    add_viz_commands(commands, seconds=_time_ns)
    return top


def _one_line(text: str) -> str:
    """``text`` with its line breaks and other unprintable characters (a file name may hold
    any) written as escapes, so an error stays one line."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def _show_warning(message: Warning | str, category: type[Warning], *_: object,
                  **__: object) -> None:
    """A warning as one line of stderr, as errors are."""
    print(f"hecker-dynamics: warning: {_one_line(str(message))}", file=sys.stderr)


def main(argv: Optional[Sequence[str]] = None) -> int:
    if threading.current_thread() is not threading.main_thread():
        return _main(argv)  # only the main thread may take a signal
    previous = signal.signal(signal.SIGTERM, raise_terminated)
    try:
        return _main(argv)
    except Terminated as stop:
        return stopped(stop)
    finally:
        signal.signal(signal.SIGTERM, previous)


def _main(argv: Optional[Sequence[str]]) -> int:
    top = parser()
    args, unknown = top.parse_known_args(argv)
    if unknown:
        # The top parser would refuse them without naming the command they were given to.
        _Parser(prog=f"{top.prog} {args.command}").error(
            f"unrecognized arguments: {' '.join(unknown)}")
    # A file name that is not valid UTF-8 reaches Python as escapes (surrogates); printed
    # back in a report line it must not end the run with an encoding error.
    if hasattr(sys.stdout, "reconfigure"):
        sys.stdout.reconfigure(errors="backslashreplace")
    try:
        # Every result is checked for finiteness (a SceneError, a DivergenceError), so
        # numpy's overflow warnings would only add lines to the one-line error.
        with np.errstate(all="ignore"), warnings.catch_warnings(), keeping_stops():
            warnings.showwarning = _show_warning
            status: int = args.handler(args)
            raise_kept_stop()
            return status
    except (SceneError, InputError, DivergenceError, BagError, VizError, EngineError,
            OutputError) as error:
        print(f"hecker-dynamics: error: {_one_line(str(error))}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        # The reader went away (``| head``): what is left to print goes nowhere, and the
        # exit status is the shell's for a write to a closed pipe, 128 + SIGPIPE.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 128 + signal.SIGPIPE
    except KeyboardInterrupt as stop:
        # Ctrl-C: the writers have removed what they had begun (a bag's or a file's scratch
        # copy), so one line says why the command stopped, with the shell's status for it.
        return stopped(stop)


if __name__ == "__main__":
    sys.exit(main())
