"""ROS 2 parameters files read as ROS 2 reads them, with bounded work for any input.

rcl_yaml_param_parser (rcl 9.2, Jazzy) walks libyaml's events and types each scalar on
its own: a ``!!str`` tag or quotes make a string; otherwise one of its boolean words
(``true``, ``yes``, ``on``, ``y`` ... and their negatives) is a bool, text that ``strtoll``
reads whole (base 0: ``0x1f`` hex, ``010`` octal) an integer, text that ``strtod`` reads
whole (``1e-9``, ``5.``, ``inf``, ``0x1p-2``) a double, and anything else, ``1:30``,
``1_000``, ``~`` or a number too large for a double, a string. An empty plain value is an
error, an alias is refused ("will not support aliasing"; a YAML merge key ``<<``, which rcl
reads as a name and merges nothing, is refused too), a parameter given twice keeps
its last value, and a mapping given twice (a node section, ``bodies``) adds its
parameters to the first's; every document of the stream counts.

:func:`read_parameters_file` does the same with PyYAML's event parser, and bounds the
work: the file's size (:data:`MAX_BYTES`) is checked before it is parsed, nesting deeper
than :data:`MAX_DEPTH` is refused, and, with aliases refused, nothing is expanded.
Errors are one :class:`SceneError` line naming the file, quoting at most
:data:`QUOTE` characters of a bad value.
"""
from __future__ import annotations

import math
import re
import sys
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import yaml

from .parameters import SceneError, quoted

__all__ = ["DuplicateParameterWarning", "MAX_BYTES", "MAX_DEPTH", "merge_parameters",
           "read_parameters_file", "read_parameters_text", "ros_scalar"]

#: Largest parameters file read (bytes): a scene with thousands of bodies is far smaller.
MAX_BYTES = 16 << 20
#: Deepest nesting of mappings and sequences (a scene needs 6: node, ros__parameters,
#: bodies, a body, parts, a part).
MAX_DEPTH = 32

_TRUE = frozenset(["Y", "y", "yes", "Yes", "YES", "true", "True", "TRUE", "on", "On", "ON"])
_FALSE = frozenset(["N", "n", "no", "No", "NO", "false", "False", "FALSE", "off", "Off", "OFF"])
_STR_TAG = "tag:yaml.org,2002:str"
# What strtoll(value, &end, 0) reads whole, and strtod: decimal, hex, inf and nan forms.
_INTEGER = re.compile(r"[+-]?(0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)")
_DECIMAL = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?")
_HEX_FLOAT = re.compile(r"[+-]?0[xX]([0-9a-fA-F]+\.?[0-9a-fA-F]*|\.[0-9a-fA-F]+)([pP][+-]?[0-9]+)?")
_SPECIAL = re.compile(r"[+-]?(inf|infinity|nan(\([0-9a-zA-Z_]*\))?)", re.IGNORECASE)
_YAML_SPECIAL = frozenset(f"{sign}.{word}" for sign in ("", "+", "-")
                          for word in ("inf", "Inf", "INF")) | {".nan", ".NaN", ".NAN"}
INT64 = 1 << 63


class DuplicateParameterWarning(UserWarning):
    """A parameters file gives one parameter twice: ROS 2 keeps the last value."""

#: libyaml's parser where PyYAML was built with it (as rcl's is; ten times faster), else
#: PyYAML's own: the same events.
_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def _double(text: str) -> float | None:
    """strtod's reading of ``text`` when it reads all of it without a range error
    (overflow, or underflow below the normal doubles: glibc sets ERANGE for both)."""
    if text in _YAML_SPECIAL:
        return float(text.replace(".", ""))
    if _SPECIAL.fullmatch(text):
        return float(text.split("(")[0])
    hexadecimal = _HEX_FLOAT.fullmatch(text)
    number = hexadecimal or _DECIMAL.fullmatch(text)
    if number is None:
        return None
    try:
        value = float.fromhex(text) if hexadecimal else float(text)
    except OverflowError:
        return None
    if math.isinf(value) or abs(value) < sys.float_info.min and \
            any(c not in "0." for c in number.group(1)):
        return None
    return value


def _integer(text: str) -> int | None:
    """strtoll(text, &end, 0) when it reads all of ``text`` into an int64."""
    if len(text) > 24 or not _INTEGER.fullmatch(text):
        return None
    digits = text.lstrip("+-")
    if digits[:2] in ("0x", "0X"):
        value = int(digits[2:], 16)
    elif len(digits) > 1 and digits[0] == "0":
        value = int(digits, 8)
    else:
        value = int(digits)
    value = -value if text.startswith("-") else value
    return value if -INT64 <= value < INT64 else None


def ros_scalar(text: str, tag: str | None, plain: bool) -> Any:
    """The value rcl gives a scalar: bool, int (int64), float or str."""
    if tag == _STR_TAG or not plain:
        return text
    if text in _TRUE:
        return True
    if text in _FALSE:
        return False
    value = _integer(text)
    if value is not None:
        return value
    number = _double(text)
    return text if number is None else number


class _Builder:
    """Builds the merged parameters of a stream of YAML events (rcl's rules above)."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, event: yaml.Event, problem: str) -> SceneError:
        mark = event.start_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else "?"
        return SceneError(f"{self.source}: {where}: {problem}")

    def value(self, events: Iterator[yaml.Event], event: yaml.Event, depth: int,
              path: str = "") -> Any:
        """The value that starts with ``event``; ``path`` names it (dotted) in errors."""
        if isinstance(event, yaml.AliasEvent):
            raise self.fail(event, "aliases are not allowed in a ROS 2 parameters file "
                                   "(ROS 2 will not read them)")
        if depth > MAX_DEPTH:
            raise self.fail(event, f"nested more than {MAX_DEPTH} levels deep")
        if isinstance(event, yaml.ScalarEvent):
            plain = not event.style  # None (PyYAML) or "" (libyaml) for a plain scalar
            if plain and event.value == "":
                parameter = path.split("ros__parameters.", 1)[-1]
                raise self.fail(event, f"parameter '{parameter}' has no value (ROS 2 refuses empty "
                                       "values; quote an empty string: '')")
            return ros_scalar(event.value, event.tag, plain)
        if isinstance(event, yaml.SequenceStartEvent):
            items: list[Any] = []
            for item in events:
                if isinstance(item, yaml.SequenceEndEvent):
                    return items
                if isinstance(item, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
                    raise self.fail(item, "a ROS 2 parameter array holds only numbers, "
                                          "strings or booleans")
                items.append(self.value(events, item, depth + 1, path))
        if isinstance(event, yaml.MappingStartEvent):
            mapping: dict[Any, Any] = {}
            for key_event in events:
                if isinstance(key_event, yaml.MappingEndEvent):
                    return mapping
                if not isinstance(key_event, yaml.ScalarEvent):
                    raise self.fail(key_event, "a key must be a plain name")
                key = ros_scalar(key_event.value, key_event.tag, not key_event.style)
                if key == "<<" and not key_event.style:
                    raise self.fail(key_event, "merge keys ('<<') are not allowed in a ROS 2 "
                                               "parameters file (ROS 2 reads '<<' as a name)")
                name = repr(str(key_event.value))[1:-1][:120]
                if not isinstance(key, str):
                    raise self.fail(key_event, _not_a_name(f"{path}.{name}" if path else name,
                                                           name, key))
                child = self.value(events, next(events), depth + 1,
                                   f"{path}.{name}" if path else name)
                self.merge(mapping, key, child, key_event)
        raise self.fail(event, f"unexpected {type(event).__name__}")

    def merge(self, mapping: dict[Any, Any], key: Any, value: Any, event: yaml.Event) -> None:
        for name in _replaced(mapping, {key: value}):
            # rcl keeps the last value; the earlier one, likely a slip, is lost: say so.
            mark = event.start_mark
            warnings.warn(f"{self.source}: line {mark.line + 1}: parameter "
                          f"'{name.split('ros__parameters.', 1)[-1]}' is given again; ROS 2 "
                          "keeps the last value", DuplicateParameterWarning, stacklevel=2)
        try:
            merge_parameters(mapping, {key: value})
        except SceneError as error:
            raise self.fail(event, str(error)) from None

    def stream(self, events: Iterator[yaml.Event], top: str) -> dict[str, Any]:
        """The merged mappings of every document; ``top`` says what a document holds."""
        merged: dict[Any, Any] = {}
        for event in events:
            if isinstance(event, (yaml.StreamStartEvent, yaml.StreamEndEvent,
                                  yaml.DocumentStartEvent, yaml.DocumentEndEvent)):
                continue
            document = self.value(events, event, 1)
            if not isinstance(document, dict):
                raise self.fail(event, f"expected {top} at the top")
            for key, section in document.items():
                self.merge(merged, key, section, event)
        return merged


def _not_a_name(path: str, written: str, key: Any) -> str:
    """Why a key ``written`` that YAML reads as ``key`` (y as True, 1 as 1) names nothing:
    the reader's check would name what YAML read ("'joints.True'"), never written."""
    parameter = path.split("ros__parameters.", 1)[-1]
    return (f"parameter '{parameter}': names must be strings, and YAML reads {written} as "
            f"{quoted(key)}: quote it ('{written}')")


def _replaced(mapping: dict[Any, Any], values: dict[Any, Any], prefix: str = "") -> Iterator[str]:
    """The dotted names of the values in ``mapping`` that merging ``values`` replaces."""
    for key, value in values.items():
        old = mapping.get(key)
        name = f"{prefix}{repr(str(key))[1:-1][:120]}"
        if isinstance(old, dict) and isinstance(value, dict):
            yield from _replaced(old, value, f"{name}.")
        elif key in mapping and not isinstance(old, dict) and not isinstance(value, dict):
            yield name


def merge_parameters(mapping: dict[Any, Any], values: dict[Any, Any]) -> None:
    """Add ``values`` to ``mapping`` as rcl does, keeping one value per parameter name: a
    mapping under a name already holding one adds to it, a value replaces the old one."""
    for key, value in values.items():
        old = mapping.get(key)
        if isinstance(old, dict) and isinstance(value, dict):
            merge_parameters(old, value)
        elif key in mapping and isinstance(old, dict) != isinstance(value, dict):
            raise SceneError(f"parameter {quoted(key)} is given both a value and nested "
                             "parameters")
        else:
            mapping[key] = value


def _yaml_error(source: str, error: yaml.YAMLError, what: str) -> SceneError:
    """One line from PyYAML's multi-line error: where, and what."""
    mark = getattr(error, "problem_mark", None) or getattr(error, "context_mark", None)
    problem = getattr(error, "problem", None) or getattr(error, "reason", None) or str(error)
    problem = " ".join(str(problem).split())
    if isinstance(error, yaml.reader.ReaderError):
        return SceneError(f"{source}: not UTF-8 (or UTF-16 with a byte order mark) text: "
                          f"{error.reason} at byte {error.position}")
    where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
    return SceneError(f"{source}: cannot read {what}: {where}{problem}")


def read_parameters_file(path: Path) -> dict[str, Any]:
    """The merged node sections of a parameters file, as nested mappings (see above)."""
    source = str(path)
    try:
        size = path.stat().st_size
        if size > MAX_BYTES:
            raise SceneError(f"{source}: the file has {size / (1 << 20):.1f} MiB; a parameters "
                             f"file may have at most {MAX_BYTES >> 20} MiB")
        data = path.read_bytes()
    except OSError as error:
        raise SceneError(f"{source}: cannot read the file: {error.strerror or error}") from None
    return _parse(data, source, "node sections ('dynamics_node: ros__parameters: ...')",
                  "the file")


def read_parameters_text(text: str, source: str, top: str) -> dict[str, Any]:
    """Parameters given as YAML text (a service request's), read as a file is: the merged
    mappings of its documents, ``top`` saying what they hold in an error."""
    data = text.encode()
    if len(data) > MAX_BYTES:
        raise SceneError(f"{source}: the text has {len(data) / (1 << 20):.1f} MiB; it may have "
                         f"at most {MAX_BYTES >> 20} MiB")
    return _parse(data, source, top, "the text")


def _parse(data: bytes, source: str, top: str, what: str) -> dict[str, Any]:
    try:
        return _Builder(source).stream(iter(yaml.parse(data, Loader=_LOADER)), top)
    except yaml.YAMLError as error:
        raise _yaml_error(source, error, what) from None
