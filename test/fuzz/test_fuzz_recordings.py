"""A fuzzer of live recordings: honest recordings of the node's loop (``live_session.py``),
tampered with message by message, checked with ``replay SCENE BAG --check --atol 0``.

The mutations are those of a hostile user and of a lossy recorder, on every kind of
message (each output topic, the session record, keyframes, input and world events, the
input messages): one dropped, duplicated, moved after the next one of its topic, a bit of
one of its fields flipped, a bit of its bytes flipped, its bytes cut short; stretches of
one topic or of all outputs cut at the start, in the middle or at the end; a topic
removed. Each must be detected (exit 1 with a ``mismatch:`` verdict, or exit 2 with one
line) or be harmless: the check passes, and either its report changed (it names what it
no longer has) or the mutation touched only what the check does not claim to verify
(``HARMLESS``, as docs/replay.md lists it). Never a traceback or a hang. Seeded;
``--fuzz-seconds`` sets how long it runs.
"""
from __future__ import annotations

import contextlib
import dataclasses
import io
import random
import signal
import struct
import sys
import time
from pathlib import Path
from typing import Any, Optional

import numpy as np
import pytest

from hecker_dynamics.bags import io as bags
from hecker_dynamics.bags.coverage import INPUT_LAG_NS
from hecker_dynamics.bags.io import BagWriter, read_bag
from hecker_dynamics.cli import main
from hecker_dynamics.scene import load_scene

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bags"))
from live_session import S, record, run_live  # noqa: E402

#: Seconds one check may take (two seconds of a session): a hang is a failure, not a wait.
CASE_TIMEOUT = 60
BALL = "{shape: circle, radius: 0.15, mass: 1.0, position: [0.5, 4.0]}"
#: Honest recordings to tamper with: scene, seed, options of the run, how late the recorder
#: starts and when it stops (None: after the node).
BASES = [
    ("sample", 3, {"world": 2, "inputs": 12}, 0, None),
    ("sample", 4, {"inputs": 10, "reset_at": 1_300_000_000,
                   "bodies": [(600_000_000, ("spawn", "ball", BALL, ()))]}, 0, None),
    ("gears", 5, {"motors": 6, "inputs": 4, "lockstep": True}, 400_000_000, 1_800_000_000),
]
#: (message type, field) whose changes the check does not claim to see, unless they change
#: an output: the session record's version, scene name, reason and catch-up cap, and its
#: play_script, lockstep and keyframe period (seen through the script's commands, the
#: resumes and the keyframes they change); the reason texts of events; an input event's
#: arrival time; what a refused service call asked for. The keyframe a replay starts from
#: (a session's first, at its step 0) is checked through what follows it.
HARMLESS = {(bags.SESSION_INFO, f) for f in ("version", "scene", "reason", "max_catch_up_steps",
                                             "play_script", "lockstep",
                                             "keyframe_period_ns")} | {
    (bags.INPUT_EVENT, "reason"), (bags.INPUT_EVENT, "arrival"), (bags.WORLD_EVENT, "reason")}
SLOTS = {0: "applied_wrench", 1: "wrench_stamped", 2: "motor_speed"}


@dataclasses.dataclass
class Message:
    topic: str
    msgtype: str
    log_ns: int
    raw: bytes


def _base(tmp_path_factory, index: int, cache: dict) -> tuple[str, list[Message],
                                                              dict[str, str], str]:
    """An honest recording of ``BASES[index]`` as a message list, its topics, and the
    verdict of its check."""
    if index not in cache:
        name, seed, options, late, stop = BASES[index]
        session = run_live(load_scene(name), seed, duration_ns=2 * S, **options)
        path = record(session, tmp_path_factory.mktemp("base") / "live", seed, late_ns=late,
                      stop_ns=stop)
        bag = read_bag(path)
        code, out, err = _check(name, path)
        assert code == 0, out + err
        cache[index] = (name, [Message(m.topic, m.msgtype, m.log_ns, m.raw)
                               for m in bag.messages], dict(bag.topics), _verdict(out))
    return cache[index]


class Hang(Exception):
    pass


def _alarm(signum: int, frame: Any) -> None:
    raise Hang()


def _check(scene: str, path: Path, what: str = "") -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(CASE_TIMEOUT)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(["replay", scene, str(path), "--check", "--atol", "0"])
    except Hang:
        raise AssertionError(f"hang: the check of {path} ran over {CASE_TIMEOUT} s: "
                             f"{what}") from None
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    return code, out.getvalue(), err.getvalue()


def _verdict(out: str) -> str:
    last = out.strip().splitlines()[-1] if out.strip() else ""
    assert last.startswith("check against the recording "), out
    return last.split(": ", 1)[1]


# ----------------------------------------------------------------------------- field flips

def _leaves(msg: Any, path: tuple = ()) -> list[tuple[tuple, Any, Any]]:
    """(path, holder, key) of every leaf value of a rosbags message."""
    found = []
    for field in dataclasses.fields(msg):
        if field.name == "__msgtype__":
            continue
        value = getattr(msg, field.name)
        here = path + (field.name,)
        if dataclasses.is_dataclass(value):
            found += _leaves(value, here)
        elif isinstance(value, np.ndarray):
            value = value.copy()  # a decoded array is a read-only view of the bytes
            setattr(msg, field.name, value)
            found += [(here + (i,), value, i) for i in range(len(value))]
        elif isinstance(value, list):
            for i, item in enumerate(value):
                if dataclasses.is_dataclass(item):
                    found += _leaves(item, here + (i,))
                else:
                    found.append((here + (i,), value, i))
        else:
            found.append((here, msg, field.name))
    return found


def _flipped(value: Any, rng: random.Random) -> Any:
    if isinstance(value, (bool, np.bool_)):
        return not value
    if isinstance(value, (float, np.floating)):
        bits = struct.unpack("<Q", struct.pack("<d", float(value)))[0] ^ (1 << rng.randrange(64))
        return type(value)(struct.unpack("<d", struct.pack("<Q", bits))[0])
    if isinstance(value, (int, np.integer)):
        return type(value)(int(value) ^ (1 << rng.randrange(7)))
    if isinstance(value, str):
        if not value:
            return "x"
        i = rng.randrange(len(value))
        return value[:i] + chr(ord(value[i]) ^ (1 << rng.randrange(6))) + value[i + 1:]
    return value


def _flip_field(message: Message, rng: random.Random) -> Optional[tuple[bytes, tuple]]:
    """The message with one bit of one field flipped, and the field's path."""
    store = bags.typestore()
    msg = store.deserialize_cdr(message.raw, message.msgtype)
    leaves = _leaves(msg)
    for _ in range(20):
        path, holder, key = rng.choice(leaves)
        old = holder[key] if isinstance(key, int) else getattr(holder, key)
        new = _flipped(old, rng)
        if isinstance(key, int):
            holder[key] = new
        else:
            setattr(holder, key, new)
        try:
            raw = bytes(store.serialize_cdr(msg, message.msgtype))
        except Exception:
            raw = None
        if raw is not None and raw != message.raw:
            return raw, path
        if isinstance(key, int):
            holder[key] = old
        else:
            setattr(holder, key, old)
    return None


# ----------------------------------------------------------------------------- mutations

KINDS = {"output": lambda m: not m.msgtype.startswith("hecker_dynamics/")
         and m.msgtype not in (bags.FLOAT64, bags.WRENCH_STAMPED),
         "session": lambda m: m.msgtype == bags.SESSION_INFO,
         "keyframe": lambda m: m.msgtype == bags.KEYFRAME,
         "input event": lambda m: m.msgtype == bags.INPUT_EVENT,
         "world event": lambda m: m.msgtype == bags.WORLD_EVENT,
         "input": lambda m: m.msgtype in (bags.APPLIED_WRENCH, bags.FLOAT64)}


def _mutate(messages: list[Message], rng: random.Random
            ) -> tuple[list[Message], str, bool, Optional[set[str]]]:
    """A mutated copy of ``messages``, what was done, whether it is harmless by the rules
    of the module docstring, and the topics to leave out of the bag (None: keep all)."""
    out = [dataclasses.replace(m) for m in messages]
    kind = rng.choice(sorted(KINDS))
    pool = [i for i, m in enumerate(out) if KINDS[kind](m)]
    if not pool:
        return out, "nothing of kind " + kind, True, None
    action = rng.choice(["drop", "duplicate", "reorder", "flip", "flip", "raw flip",
                         "truncate", "cut", "remove topic"])
    i = rng.choice(pool)
    target = out[i]
    what = f"{action} {kind} {target.topic} #{i} at {target.log_ns}"
    if action == "drop":
        del out[i]
    elif action == "duplicate":
        out.insert(i + 1, dataclasses.replace(target, log_ns=target.log_ns + rng.randrange(2)))
        identical_record = target.msgtype.startswith("hecker_dynamics/msg/") \
            and target.msgtype != bags.APPLIED_WRENCH
        return out, what, identical_record, None
    elif action == "reorder":
        later = [j for j in range(i + 1, len(out)) if out[j].topic == target.topic]
        if not later:
            return out, what + " (no later one)", True, None
        j = later[0] if rng.random() < 0.7 else rng.choice(later)
        out[i].raw, out[j].raw = out[j].raw, out[i].raw
        # Input messages may reach the recorder in another order than the node within
        # INPUT_LAG_NS (two publishers): their order is not checked closer than that.
        close = kind == "input" and out[j].log_ns - out[i].log_ns <= INPUT_LAG_NS
        return out, what + f" with #{j}", out[i].raw == out[j].raw or close, None
    elif action == "flip":
        flipped = _flip_field(target, rng)
        if flipped is None:
            return out, what + " (no field)", True, None
        target.raw = flipped[0]
    elif action == "raw flip":
        data = bytearray(target.raw)
        data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
        target.raw = bytes(data)
    elif action == "truncate":
        target.raw = target.raw[:rng.randrange(len(target.raw))]
    if action in ("flip", "raw flip", "truncate"):
        changed = _changed_fields(messages[i], target.raw)
        return out, what + f" fields {sorted(changed or ['(undecodable)'])}", \
            _harmless(messages[i], changed, messages), None
    elif action == "cut":
        topics = {target.topic} if rng.random() < 0.5 else {
            m.topic for m in out if KINDS["output"](m)}
        logs = [m.log_ns for m in out]
        first, last = min(logs), max(logs)
        where = rng.choice(["head", "middle", "tail"])
        a = first + int((last - first) * rng.uniform(0.0, 0.6))
        b = a + int((last - first) * rng.uniform(0.1, 0.4))
        lo, hi = {"head": (first, b), "middle": (a, b), "tail": (a, last)}[where]
        out = [m for m in out if not (m.topic in topics and lo <= m.log_ns <= hi)]
        what = f"cut {where} of {sorted(topics)} from {lo} to {hi}"
    else:
        out = [m for m in out if m.topic != target.topic]
        what = f"remove topic {target.topic}"
        return out, what, False, {target.topic} if rng.random() < 0.5 else None
    return out, what, False, None


def _changed_fields(original: Message, raw: bytes) -> Optional[set[str]]:
    """The top-level fields whose values differ once ``raw`` is decoded (None: it cannot
    be)."""
    store = bags.typestore()
    try:
        mutated = store.deserialize_cdr(raw, original.msgtype)
    except Exception:
        return None
    before = {path: _value(h, k) for path, h, k in _leaves(store.deserialize_cdr(
        original.raw, original.msgtype))}
    after = {path: _value(h, k) for path, h, k in _leaves(mutated)}
    return {str(path[0]) for path in set(before) | set(after)
            if before.get(path) != after.get(path)
            and not _same_float(before.get(path), after.get(path))}


def _value(holder: Any, key: Any) -> Any:
    return holder[key] if isinstance(key, int) else getattr(holder, key)


def _same_float(a: Any, b: Any) -> bool:
    """Both the same NaN bits (``!=`` says a NaN differs from itself)."""
    return isinstance(a, float) and isinstance(b, float) and \
        struct.pack("<d", a) == struct.pack("<d", b)


def _harmless(original: Message, changed: Optional[set[str]], messages: list[Message]) -> bool:
    """Whether changing ``changed`` fields of ``original`` is what the check does not claim
    to see (the module docstring). Outputs and input messages are compared byte for byte:
    nothing in them is. An input event's message is compared with the recorded input where
    the recorder has it, and otherwise through what it changes."""
    if changed is None or not original.msgtype.startswith("hecker_dynamics/msg/") \
            or original.msgtype == bags.APPLIED_WRENCH:
        return False
    store = bags.typestore()
    decoded = store.deserialize_cdr(original.raw, original.msgtype)
    allowed = {field for msgtype, field in HARMLESS if msgtype == original.msgtype}
    if original.msgtype == bags.INPUT_EVENT:
        slot = SLOTS.get(int(decoded.kind), "")
        held = getattr(decoded, slot, None)
        msgtype = {0: bags.APPLIED_WRENCH, 1: bags.WRENCH_STAMPED, 2: bags.FLOAT64}.get(
            int(decoded.kind))
        if held is not None and msgtype is not None and not any(
                m.topic == decoded.topic and m.raw == bytes(store.serialize_cdr(held, msgtype))
                for m in messages):
            allowed.add(slot)
    if original.msgtype == bags.WORLD_EVENT and not decoded.accepted:
        allowed |= {"body", "values", "time_ns", "spec", "collisions"}
    if original.msgtype == bags.KEYFRAME and decoded.steps == 0:
        return True  # a session's first: what a replay starts from
    return changed <= allowed


def _write(path: Path, messages: list[Message], topics: dict[str, str],
           removed: Optional[set[str]]) -> Path:
    with BagWriter(path, "mcap") as writer:
        for topic, msgtype in topics.items():
            if not removed or topic not in removed:
                writer.add_topic(topic, msgtype)
        for message in sorted(messages, key=lambda m: m.log_ns):
            writer.write_raw(message.topic, message.log_ns, message.raw)
    return path


@pytest.fixture(scope="module")
def bases() -> dict:
    return {}


def test_tampered_recordings_are_caught_or_harmless(tmp_path, tmp_path_factory, request,
                                                    bases):
    seconds = request.config.getoption("--fuzz-seconds")
    rng = random.Random(request.config.getoption("--fuzz-seed"))
    deadline = time.monotonic() + seconds
    cases = 0
    while time.monotonic() < deadline or cases < 3:
        scene, honest, topics, verdict = _base(tmp_path_factory, rng.randrange(len(BASES)),
                                               bases)
        messages, what, harmless, removed = _mutate(honest, rng)
        harmless |= messages == honest and not removed  # nothing changed
        what = f"case {cases} on {scene}: {what}"
        path = _write(tmp_path / f"case{cases}", messages, topics, removed)
        code, out, err = _check(scene, path, what)
        assert "Traceback" not in err, f"{what}: traceback\n{err[-3000:]}"
        assert code in (0, 1, 2), f"{what}: exit {code}\n{err[-2000:]}"
        if code == 2:
            assert err.count("\n") == 1 and err.startswith("hecker-dynamics: error: "), \
                f"{what}: error not one line:\n{err[-2000:]}"
        elif code == 1:
            assert _verdict(out).startswith("mismatch: "), f"{what}:\n{out[-2000:]}"
        else:
            found = _verdict(out)
            assert found.startswith("match: "), f"{what}:\n{out[-2000:]}"
            assert harmless or found != verdict, \
                f"{what}: passed and reports the same as the honest recording:\n{found}"
        cases += 1
