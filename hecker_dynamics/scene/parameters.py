"""Typed, checked reading of ROS 2 parameters, with errors that name the file and parameter.

A scene is a ROS 2 parameters file. rclpy hands a node its parameters as flat dotted names
(``bodies.left.size``); a YAML file holds them as nested mappings. Both are turned into a
nested mapping here and read through :class:`ParameterReader`, which checks each value's
type the way ROS 2 does (arrays are homogeneous; an integer is accepted where a double is
expected) and remembers which names were read, so a misspelt parameter is an error too.
"""
from __future__ import annotations

import array
import math
import re
from collections.abc import Iterator, Mapping
from typing import Any, NoReturn, Optional

__all__ = ["NAME_MAX", "NAME_PATTERN", "NAME_RULE", "quoted", "number_text", "seconds_text",
           "SceneError", "unflatten", "flatten", "ParameterReader", "REQUIRED", "MAX_SECONDS",
           "MAX_STAMP_NS", "stamp_time", "bad_name"]

#: A name's longest: two of them make a topic (``/<body>/<sensor>/scan``) that stays within
#: ROS 2's 247 characters (RMW_TOPIC_MAX_NAME_LENGTH) with room for a namespace.
NAME_MAX = 100
NAME_PATTERN = re.compile(rf"[A-Za-z][A-Za-z0-9_]{{0,{NAME_MAX - 1}}}")  # used with fullmatch
#: What :data:`NAME_PATTERN` takes, for error messages.
NAME_RULE = f"letters, digits and underscores, starting with a letter, at most {NAME_MAX}"
#: Most characters of a bad value quoted in an error message (a hostile file may hold
#: megabytes in one value).
QUOTE = 60


def bad_name(value: object) -> Optional[str]:
    """Why ``value`` is no name of the scene's (a body, a point, the fixed frame: a ROS name
    segment and tf frame, :data:`NAME_PATTERN`), or None for a name."""
    if isinstance(value, str) and NAME_PATTERN.fullmatch(value):
        return None
    return f"{quoted(value)} is not a valid name ({NAME_RULE})"


def quoted(value: Any) -> str:
    """``repr(value)``, cut to :data:`QUOTE` characters with '...' and the full length."""
    if isinstance(value, int) and value.bit_length() > 4 * QUOTE:
        return f"an integer of {value.bit_length()} bits"  # repr would be slow or refused
    text = repr(value)
    if len(text) <= QUOTE:
        return text
    return f"{text[:QUOTE]}... ({len(text)} characters)"


#: The latest time a ROS stamp holds (``builtin_interfaces/Time``: int32 seconds), ns.
MAX_STAMP_NS = (2 ** 31 - 1) * 1_000_000_000 + 999_999_999


def stamp_time(ns: int, argument: str) -> int:
    """``ns``, a sim time to start at, if the node's messages can be stamped with it: from 0
    (a ROS clock and a bag's log times do not go below it) to :data:`MAX_STAMP_NS`; else a
    ValueError that names ``argument``."""
    if ns < 0:
        raise ValueError(f"{argument}: {seconds_text(ns)} s is before 0, where a ROS clock "
                         "and a bag's log times start")
    if ns > MAX_STAMP_NS:
        raise ValueError(f"{argument}: {seconds_text(ns)} s is after "
                         f"{MAX_STAMP_NS // 1_000_000_000} s, the latest time a ROS stamp "
                         "(int32 seconds) holds")
    return ns


def number_text(value: float) -> str:
    """A number for a message: a whole one without ``.0`` (a count of 0 read as "not
    0.0"), any other by ``repr``, the shortest text that reads back as the same double."""
    if isinstance(value, int):
        return str(value)
    if math.isfinite(value) and value.is_integer() and abs(value) < 1e16:
        return str(int(value))
    return repr(value)


def seconds_text(ns: int, all_places: bool = False) -> str:
    """``ns`` nanoseconds as seconds for a message, exactly, in whole numbers: a step of
    4166667 ns reads 0.004166667 and a ROS time of 1700000000750000001 ns
    1700000000.750000001, which reads back as the same nanoseconds (a double holds a ROS
    time only to 256 ns: ``ns * 1e-9`` printed 1700000000.750000238). Trailing zeros are
    dropped, unless ``all_places`` keeps the nine, as reports line times up
    (:func:`..bags.coverage.seconds`)."""
    whole, part = divmod(abs(int(ns)), 1_000_000_000)
    fraction = f".{part:09d}"
    if not all_places:
        fraction = fraction.rstrip("0").rstrip(".")
    return f"{'-' if ns < 0 else ''}{whole}{fraction}"


#: The most physics steps a rate's period (:meth:`ParameterReader.period_ns`) may span: past
#: it the period's count of steps, a double divided from the rate, is no longer known to
#: within the whole-number test's margin.
MOST_STEPS = 1e12
#: The longest time or duration a scene (and the World API) takes, s: its nanoseconds stay
#: within an int64 and a ROS stamp.
MAX_SECONDS = 1e9


class SceneError(ValueError):
    """A scene that cannot be loaded; the message names the source, parameter and problem."""


def unflatten(params: Mapping[str, Any]) -> dict[str, Any]:
    """Turn flat dotted parameter names into nested mappings (``a.b: 1`` -> ``{a: {b: 1}}``)."""
    nested: dict[str, Any] = {}
    for name, value in params.items():
        keys = name.split(".")
        node = nested
        for key in keys[:-1]:
            child = node.setdefault(key, {})
            if not isinstance(child, dict):
                raise SceneError(f"parameter '{name}' is nested under '{key}', which has a value")
            node = child
        if isinstance(node.get(keys[-1]), dict):
            raise SceneError(f"parameter '{name}' has a value and nested parameters")
        node[keys[-1]] = value
    return nested


def flatten(nested: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested mappings to flat dotted parameter names, as a node holds them (the inverse
    of :func:`unflatten`; lists are values, as ROS 2 arrays are)."""
    flat: dict[str, Any] = {}
    for key, value in nested.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, Mapping):
            flat.update(flatten(value, name))
        else:
            flat[name] = value
    return flat


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


class ParameterReader:
    """Reads the parameters under one prefix of a nested mapping, checking each value."""

    def __init__(self, values: Mapping[str, Any], source: str, prefix: str = "") -> None:
        for key in values:
            if not isinstance(key, str):
                name = f"{prefix}{'.' if prefix else ''}{quoted(key)}"
                raise SceneError(f"{source}: parameter '{name}': names must be strings")
        self._values = values
        self._source = source
        self._prefix = prefix
        self._read: set[str] = set()
        self._children: list[ParameterReader] = []

    @property
    def source(self) -> str:
        return self._source

    def path(self, key: str) -> str:
        """The full dotted name of ``key`` under this reader."""
        return f"{self._prefix}.{key}" if self._prefix else key

    def fail(self, key: str, problem: str) -> NoReturn:
        """Raise a :class:`SceneError` naming the source and the parameter."""
        name = repr(self.path(key))[1:-1]  # escaped: one line whatever the name holds
        if len(name) > 2 * QUOTE:
            name = name[:2 * QUOTE] + "..."
        raise SceneError(f"{self._source}: parameter '{name}': {problem}")

    def has(self, key: str) -> bool:
        return key in self._values

    def names(self) -> list[str]:
        """The names under this reader, sorted."""
        return sorted(self._values)

    def _get(self, key: str, default: Any) -> Any:
        self._read.add(key)
        if key not in self._values:
            if default is _REQUIRED:
                self.fail(key, "is required but missing")
            return default
        return self._values[key]

    def number(self, key: str, default: Any = None, *, minimum: float | None = None,
               maximum: float | None = None, positive: bool = False) -> float:
        """A finite double (an integer is accepted), optionally bounded."""
        value = self._get(key, default)
        if not _is_number(value):
            self.fail(key, f"must be a number, not {quoted(value)}")
        value = self._finite(key, value)
        if positive and value <= 0.0:
            self.fail(key, f"must be positive, not {number_text(value)}")
        if minimum is not None and value < minimum:
            self.fail(key, f"must be at least {number_text(minimum)}, not {number_text(value)}")
        if maximum is not None and value > maximum:
            self.fail(key, f"must be at most {number_text(maximum)}, not {number_text(value)}")
        return value

    def period_ns(self, key: str, step_ns: int, default_rate: float) -> int:
        """The period of the rate ``key`` (Hz), in ns: a whole number of physics steps of
        ``step_ns``, so that every sample or publish instant falls on a step."""
        rate = self.number(key, default_rate, positive=True)
        steps = 1e9 / rate / step_ns
        step = seconds_text(step_ns)
        if steps < 1.0 - 1e-6:
            self.fail(key, f"{number_text(rate)} Hz is faster than the physics step of {step} s "
                           f"can sample (at most {number_text(1e9 / step_ns)} Hz)")
        if steps >= MOST_STEPS:
            self.fail(key, f"{number_text(rate)} Hz is too slow: its period is "
                           f"{steps:.3g} physics steps of {step} s, more than "
                           f"{MOST_STEPS:.3g}")
        if abs(steps - round(steps)) > 1e-6 * steps:
            self.fail(key, f"{number_text(rate)} Hz is not a whole number of physics steps "
                           f"of {step} s")
        return round(steps) * step_ns

    def _finite(self, key: str, value: Any) -> float:
        """``value`` as a finite float (a huge integer does not fit one)."""
        try:
            result = float(value)
        except OverflowError:
            self.fail(key, f"{quoted(value)} is too large for a double")
        if not math.isfinite(result):
            self.fail(key, f"must be finite, not {result}")
        return result

    def numbers(self, key: str, default: Any = None, *, length: int | None = None,
                multiple_of: int = 1) -> tuple[float, ...]:
        """A homogeneous array of finite numbers, of a given length or multiple of one."""
        return self.check_numbers(key, self._get(key, default), length=length,
                                  multiple_of=multiple_of)

    def check_numbers(self, key: str, value: Any, *, length: int | None = None,
                      multiple_of: int = 1) -> tuple[float, ...]:
        """Check that ``value``, read from ``key``, is an array of numbers as ROS 2 allows
        (a list, a tuple, or the ``array.array`` rclpy gives for double arrays)."""
        if isinstance(value, array.array):
            value = value.tolist()
        if not isinstance(value, (list, tuple)) or not all(_is_number(x) for x in value):
            self.fail(key, f"must be an array of numbers, not {quoted(value)}")
        if len({type(x) for x in value}) > 1:
            self.fail(key, "mixes integers and doubles; ROS 2 parameter arrays must be "
                           "homogeneous (write every number with a decimal point)")
        result = tuple(self._finite(key, x) for x in value)
        if length is not None and len(result) != length:
            self.fail(key, f"must have {length} numbers, not {len(result)}")
        if len(result) % multiple_of:
            self.fail(key, f"must have a multiple of {multiple_of} numbers, not {len(result)}")
        return result

    def vector(self, key: str, default: Any = None) -> tuple[float, float]:
        """A 2-vector ``[x, y]``."""
        x, y = self.numbers(key, default, length=2)
        return (x, y)

    def string(self, key: str, default: Any = None, *, choices: tuple[str, ...] = ()) -> str:
        value = self._get(key, default)
        if not isinstance(value, str):
            self.fail(key, f"must be a string, not {quoted(value)}")
        if choices and value not in choices:
            self.fail(key, f"must be one of {', '.join(choices)}; not {quoted(value)}")
        return value

    def name(self, key: str, default: Any = None) -> str:
        """A string usable as a ROS name segment (letters, digits, underscores)."""
        value = self.string(key, default)
        problem = bad_name(value)
        if problem is not None:
            self.fail(key, problem)
        return value

    def strings(self, key: str, default: Any = None) -> tuple[str, ...]:
        value = self._get(key, default)
        if not isinstance(value, (list, tuple)) or not all(isinstance(x, str) for x in value):
            self.fail(key, f"must be an array of strings, not {quoted(value)}")
        return tuple(value)

    def boolean(self, key: str, default: Any = None) -> bool:
        value = self._get(key, default)
        if not isinstance(value, bool):
            self.fail(key, f"must be true or false, not {quoted(value)}")
        return value

    def raw(self, key: str, default: Any = None) -> Any:
        """The value as written, for parameters that accept more than one type."""
        return self._get(key, default)

    def child(self, key: str, *, required: bool = False) -> ParameterReader:
        """A reader for the nested parameters under ``key`` (empty when absent)."""
        value = self._get(key, _REQUIRED if required else {})
        if not isinstance(value, Mapping):
            self.fail(key, f"must hold nested parameters, not {quoted(value)}")
        reader = ParameterReader(value, self._source, self.path(key))
        self._children.append(reader)
        return reader

    def named_children(self, key: str) -> Iterator[tuple[str, ParameterReader]]:
        """(name, reader) for each entry under ``key``, sorted by name for determinism."""
        group = self.child(key)
        for name in group.names():
            if not NAME_PATTERN.fullmatch(name):
                group.fail(name, f"is not a valid name ({NAME_RULE})")
            yield name, group.child(name)

    def check_all_read(self, ignore: frozenset[str] = frozenset()) -> None:
        """Raise for any parameter that no reader asked for (a misspelt or unknown name)."""
        for key in sorted(self._values):
            if key not in self._read and key not in ignore:
                self.fail(key, "is not a known parameter here")
        for child in self._children:
            child.check_all_read()


_REQUIRED = object()
REQUIRED: Any = _REQUIRED
