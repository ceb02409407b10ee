"""What the node records so that a live session replays bit for bit (without ROS).

Three kinds of record, each published by the node on a topic of its own (reliable,
transient_local, so a recorder that starts late still receives the latest ones) and read
first by :mod:`hecker_dynamics.bags.replay`:

- :class:`SessionFields` (``~/session``): which scene (its fingerprint) and options run, and
  from when; one at the start and one at each restart (reset service, clock jump).
- :class:`InputEventFields` (``~/input_events``): every input message the node took, with
  the sim time it was pushed at and the ROS time it arrived at. A command stamped behind the
  sim clock acts from the step after its push, which depends on when the node's timer fired:
  the event makes that decision replayable.
- :class:`WorldEventFields` (``~/world_events``): every change made to the running world
  through the node's services (a body moved, spawned or deleted, the simulation paused,
  resumed or stepped), at the sim time it was made; it shares the input events' sequence
  numbers, so a replay applies both in the node's order.
- :class:`KeyframeFields` (``~/keyframe``): the whole simulation state at full precision
  every ``keyframe_period`` of sim time, so a recording that starts mid-session starts at the
  nearest keyframe instead of from the scene's initial state.

The rest of a keyframe's state (commands held and pending, what the integrator and the
contact pass carry from step to step, the script's position, the input counters, and the
bodies spawned and deleted since the session's start, so that a replay starting there
has the world the node had) travels as JSON: Python writes floats with ``repr``, which
reads back to the same bits.
"""
from __future__ import annotations

import enum
import json
from typing import Any, NamedTuple

# The record topics (relative to the node: ``~`` is its own namespace) and their QoS.
from .names import (
    INPUT_EVENTS_QOS,
    INPUT_EVENTS_TOPIC,
    KEYFRAME_QOS,
    KEYFRAME_TOPIC,
    SESSION_QOS,
    SESSION_TOPIC,
    WORLD_EVENTS_QOS,
    WORLD_EVENTS_TOPIC,
)

__all__ = ["APPLIED_WRENCH_EVENT", "WRENCH_STAMPED_EVENT", "MOTOR_SPEED_EVENT", "CMD_VEL_EVENT",
           "SessionFields",
           "InputEventFields",
           "KeyframeFields", "encode_state", "decode_state", "SESSION_TOPIC", "KEYFRAME_TOPIC",
           "INPUT_EVENTS_TOPIC", "SESSION_DEPTH", "KEYFRAME_DEPTH", "INPUT_EVENTS_DEPTH",
           "WORLD_EVENTS_TOPIC", "WORLD_EVENTS_DEPTH", "WorldChange", "WorldEventFields"]

#: Keep-last depths of the record topics (their QoS and the reasons: :mod:`.names`).
SESSION_DEPTH = SESSION_QOS.depth
KEYFRAME_DEPTH = KEYFRAME_QOS.depth
INPUT_EVENTS_DEPTH = INPUT_EVENTS_QOS.depth
WORLD_EVENTS_DEPTH = WORLD_EVENTS_QOS.depth

#: ``InputEvent.kind``: which message the event holds.
APPLIED_WRENCH_EVENT = 0
WRENCH_STAMPED_EVENT = 1
MOTOR_SPEED_EVENT = 2
CMD_VEL_EVENT = 3


class SessionFields(NamedTuple):
    """``hecker_dynamics/SessionInfo``."""

    start_ns: int
    frame_id: str
    session: int
    reason: str
    scene: str
    fingerprint: str
    integrator: str
    step_ns: int
    publish_period_ns: int
    play_script: bool
    lockstep: bool
    max_catch_up_steps: int
    keyframe_period_ns: int
    next_event: int
    version: str


    def message_values(self) -> dict[str, Any]:
        """The ``SessionInfo`` fields but the header (the start and the fixed frame)."""
        values = self._asdict()
        del values["start_ns"], values["frame_id"]
        return values


class InputEventFields(NamedTuple):
    """``hecker_dynamics/InputEvent``; ``message`` is the input message as received (an
    rclpy or rosbags ``AppliedWrench``, ``WrenchStamped``, for a motor ``Float64`` or for a
    drive ``Twist``)."""

    stamp_ns: int
    session: int
    sequence: int
    topic: str
    arrival_ns: int
    kind: int
    message: Any
    accepted: bool
    reason: str


class WorldChange(enum.IntEnum):
    """``WorldEvent.kind``: what a service changed."""

    SET_STATE = 0   # values: x, y, angle of the body frame, vx, vy of its origin, omega
    PAUSE = 1
    RESUME = 2      # time_ns: the sim time the simulation goes on from
    STEP = 3        # values: the number of steps
    SPAWN = 4       # spec: the body's YAML; collisions: the collision groups it joins
    DELETE = 5


class WorldEventFields(NamedTuple):
    """``hecker_dynamics/WorldEvent``."""

    stamp_ns: int
    session: int
    sequence: int
    kind: WorldChange
    body: str
    values: tuple[float, ...]
    time_ns: int
    accepted: bool
    reason: str
    spec: str = ""
    collisions: tuple[str, ...] = ()


class KeyframeFields(NamedTuple):
    """``hecker_dynamics/Keyframe``: ``q`` and ``v`` flat, three values per body."""

    stamp_ns: int
    session: int
    steps: int
    next_event: int
    bodies: tuple[str, ...]
    q: tuple[float, ...]
    v: tuple[float, ...]
    state: str


def encode_state(state: dict[str, Any]) -> str:
    """A keyframe's JSON state (infinite sub-step sizes as ``Infinity``, as Python reads)."""
    return json.dumps(state, separators=(",", ":"))


def decode_state(text: str) -> dict[str, Any]:
    return json.loads(text)
