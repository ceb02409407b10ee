"""``hecker-dynamics``: run scenes without ROS.

    hecker-dynamics run [SCENE] [--duration S] [--integrator NAME] [--step S]
    hecker-dynamics scenes
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections.abc import Sequence
from typing import Optional

from .commands import InputError
from .scene import INTEGRATORS, Scene, SceneError, load_scene, shipped_scenes
from .simulation import DivergenceError, Simulation


def _seconds(text: str) -> float:
    value = float(text)
    if not value >= 0.0:
        raise argparse.ArgumentTypeError(f"must be a non-negative number of seconds, not {text}")
    return value


def _positive(text: str) -> float:
    value = float(text)
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f"must be positive, not {text}")
    return value


def configure(scene: Scene, args: argparse.Namespace) -> Scene:
    """Apply the command line's overrides (integrator, step, tolerance) to a scene."""
    changes = {}
    if args.integrator:
        changes["integrator"] = args.integrator
    if args.tolerance is not None:
        changes["tolerance"] = args.tolerance
    if args.step is not None:
        step_ns = round(args.step * 1e9)
        if step_ns < 1 or scene.publish_period_ns % step_ns:
            raise SceneError(f"--step {args.step}: the publish period "
                             f"{scene.publish_period_ns * 1e-9:g} s must be a whole number of steps")
        changes["step_ns"] = step_ns
    if args.duration is not None:
        changes["duration_ns"] = round(args.duration * 1e9)
    return dataclasses.replace(scene, **changes)


def run(args: argparse.Namespace) -> int:
    """Run a scene with its scripted inputs and print a summary."""
    scene = configure(load_scene(args.scene), args)
    sim = Simulation(scene)
    first = sim.snapshot()
    started = time.perf_counter()
    sim.play(scene.script, scene.duration_ns)
    wall = time.perf_counter() - started
    last = sim.snapshot()
    sim_seconds = (last.time_ns - first.time_ns) * 1e-9
    print(f"scene       {scene.source}")
    print(f"integrator  {sim.integrator.name}" + (" (auto)" if scene.integrator == "auto" else ""))
    print(f"step        {scene.step_ns * 1e-9:g} s, {last.steps} steps, "
          f"{sim.integrator.counters.evaluations} force evaluations")
    print(f"sim time    {sim_seconds:g} s in {wall:.3f} s wall "
          f"({sim_seconds / wall if wall > 0 else float('inf'):.1f}x real time)")
    print(f"energy      {first.energy:.6g} J -> {last.energy:.6g} J")
    print(f"{'body':<12}{'x':>12}{'y':>12}{'angle':>12}{'vx':>12}{'vy':>12}{'omega':>12}")
    for body in last.bodies:
        print(f"{body.name:<12}{body.position[0]:>12.5f}{body.position[1]:>12.5f}"
              f"{body.angle:>12.5f}{body.linear_velocity[0]:>12.5f}"
              f"{body.linear_velocity[1]:>12.5f}{body.angular_velocity:>12.5f}")
    return 0


def scenes(args: argparse.Namespace) -> int:
    """List the shipped scenes."""
    for name in shipped_scenes():
        print(name)
    return 0


def parser() -> argparse.ArgumentParser:
    top = argparse.ArgumentParser(
        prog="hecker-dynamics",
        description="2D rigid-body dynamics after Chris Hecker's 'Physics, Part 2: Angular "
                    "Effects', without ROS.")
    commands = top.add_subparsers(dest="command", required=True, metavar="COMMAND")

    run_parser = commands.add_parser(
        "run", help="run a scene with its scripted inputs and print a summary",
        description="Run a scene (a shipped scene name or a ROS 2 parameters file; the "
                    "default scene when none is given) with its scripted inputs.")
    run_parser.add_argument("scene", nargs="?", default=None,
                            help="shipped scene name or path to a parameters file")
    run_parser.add_argument("--duration", type=_seconds, help="sim seconds (default: the scene's)")
    run_parser.add_argument("--integrator", choices=INTEGRATORS, help="override the integrator")
    run_parser.add_argument("--step", type=_positive, help="override the physics step, s")
    run_parser.add_argument("--tolerance", type=_positive,
                            help="override the tolerance of dopri5 / auto")
    run_parser.set_defaults(handler=run)

    list_parser = commands.add_parser("scenes", help="list the shipped scenes",
                                      description="List the shipped scenes.")
    list_parser.set_defaults(handler=scenes)
    return top


def main(argv: Optional[Sequence[str]] = None) -> int:
    args = parser().parse_args(argv)
    try:
        return args.handler(args)
    except (SceneError, InputError, DivergenceError) as error:
        print(f"hecker-dynamics: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
