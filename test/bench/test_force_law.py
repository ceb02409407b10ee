"""The peers' lean force loop (bench/force_law.py) against the force law on states: every
kind of force term pushed through a peer's calls sums to the same wrench on each body,
and a scripted command pushes on exactly the steps its span covers."""
from __future__ import annotations

import math
import random

import pytest
from scene_builders import EVERY_FORCE, make_scene

from hecker_dynamics.bench.force_law import BodyCalls, make_program, make_stepper
from hecker_dynamics.bench.reference import PlainModel


class _Body:
    """A body for the loop: its CM state, and the force and torque pushed on it."""

    def __init__(self, state):
        self.state = state
        self.wrench = [0.0, 0.0, 0.0]
        self.woken = 0

    def calls(self) -> BodyCalls:
        x, y, a, vx, vy, w = self.state
        c, s = math.cos(a), math.sin(a)

        def point(local):
            return x + c * local[0] - s * local[1], y + s * local[0] + c * local[1]

        def point_velocity(world):  # a body point's velocity, Eq. 9
            return vx - w * (world[1] - y), vy + w * (world[0] - x)

        def push(force, world):  # the torque about the CM, Eq. 11
            self.wrench[0] += force[0]
            self.wrench[1] += force[1]
            self.wrench[2] += (world[0] - x) * force[1] - (world[1] - y) * force[0]

        def push_torque(tau):
            self.wrench[2] += tau

        return BodyCalls(point, point_velocity, push, lambda: self.state, push_torque)


def test_every_force_term_pushed_through_the_calls_sums_to_the_law():
    model = PlainModel(make_scene(EVERY_FORCE)).without(gravity=True)
    rng = random.Random(3)
    for _ in range(5):
        states = [tuple(rng.uniform(-2.0, 2.0) for _ in range(6)) for _ in range(model.n)]
        bodies = [_Body(state) for state in states]
        program = make_program(model.springs, model.drags, model.angular, model.forces,
                               model.constant, [b.calls() for b in bodies])
        program()
        for body, expected in zip(bodies, model.wrenches(states)):
            assert body.wrench == pytest.approx(expected, rel=1e-12, abs=1e-12)


def test_no_terms_no_program():
    assert make_program([], [], [], [], [[0.0, 0.0, 0.0]], [_Body((0.0,) * 6).calls()]) is None


def test_a_scripted_command_pushes_over_its_span_and_wakes_its_body():
    """A command from 2.5 ms to 6 ms at h = 1 ms acts on the steps starting at 3, 4 and
    5 ms (those whose start lies in its span), pushing 2 N up at the CM frame's point
    (1, 0) of the body itself: each step the body gets the force and a torque of 2 N m."""
    body = _Body((0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    pushed = []

    def advance():
        pushed.append(list(body.wrench))
        body.wrench[:] = [0.0, 0.0, 0.0]

    def wake(i):
        body.woken += 1

    step = make_stepper(None, [(0, 2_500_000, 6_000_000, 0, (1.0, 0.0), (0.0, 2.0), 0.0)],
                        [body.calls()], wake, advance, 1_000_000)
    assert step(8) >= 0.0
    acting = [k for k, wrench in enumerate(pushed) if any(wrench)]
    assert acting == [3, 4, 5] and body.woken == 3
    assert pushed[4] == pytest.approx([0.0, 2.0, 2.0])
