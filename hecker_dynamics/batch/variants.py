"""The variants of a sweep: scene parameters set over a grid or a seeded random sample.

``--set NAME=VALUES`` names a scene parameter as docs/scenes.md spells it, dotted
(``bodies.left.mass``), optionally one element of an array (``bodies.left.position[1]``).
VALUES is one of

- a list ``a,b,c`` of YAML scalars (numbers, ``true``/``false``, names);
- ``start:stop:count``, ``count`` evenly spaced numbers from ``start`` to ``stop``, both
  included (numpy's ``linspace``; a count of 1 only with ``start`` equal to ``stop``);
- ``start:stop``, the interval itself: only with ``--samples``, which draws uniformly in it.

Without ``--samples`` the variants are the grid of every combination, the last ``--set``
varying fastest. With ``--samples N --seed S`` each of N variants draws every parameter
independently from a ``numpy.random.Generator`` seeded with S (a list or a grid: one of
its values, equally likely; an interval: uniform), so the same seed gives the same
variants wherever they run. Every variant is built into a :class:`Scene` by the scene
loader before any work starts, so a bad name or value fails like a bad scene file does.
A sweep has at most :data:`MAX_VARIANTS` variants (a grid's size is known from its
counts before any is made), and a parameter is set by one ``--set`` only.
"""
from __future__ import annotations

import copy
import itertools
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Optional, Union

import numpy as np
import yaml

from ..scene.load import Scene, check_takes_a_step, scene_from_parameters, scene_parameters
from ..scene.parameters import SceneError, flatten

__all__ = ["Setting", "Variant", "parse_setting", "grid", "sample", "make_variants",
           "MAX_VARIANTS"]

#: The most variants of one sweep. Each is a scene built before any runs (about 10 kB and
#: 10 ms here), so this is some 1 GB and a quarter of an hour of building: past it, a
#: mistyped count would exhaust the memory before the first run.
MAX_VARIANTS = 100_000

Value = Union[float, int, bool, str]
_NAME = re.compile(r"(?P<name>[A-Za-z][A-Za-z0-9_]*(?:\.[A-Za-z][A-Za-z0-9_]*)*)"
                   r"(?:\[(?P<index>\d+)\])?")


@dataclass(frozen=True)
class Setting:
    """One ``--set``: a parameter (and array element) and the values it takes.

    ``values`` holds the list or grid points; ``interval`` is set instead for ``start:stop``.
    """

    text: str
    name: str
    index: Optional[int]
    values: tuple[Value, ...] = ()
    interval: Optional[tuple[float, float]] = None

    @property
    def column(self) -> str:
        return self.name if self.index is None else f"{self.name}[{self.index}]"


@dataclass(frozen=True)
class Variant:
    """One run of a sweep: its index, the values set (column -> value), its scene and the
    flat parameters it was built from."""

    index: int
    values: tuple[tuple[str, Value], ...]
    scene: Scene
    parameters: Mapping[str, Any]


def _scalar(text: str, setting: str) -> Value:
    """A number (as Python reads it: ``1e-3`` too, which YAML 1.1 reads as text), a YAML
    boolean, or a name."""
    for kind in (int, float):
        try:
            value = kind(text)
        except ValueError:
            continue
        if not math.isfinite(value):
            break
        return value
    else:
        try:
            loaded = yaml.safe_load(text) if text else None
        except yaml.YAMLError:  # a list's bracket, cut at its commas: "[100", "0]"
            loaded = None
        if isinstance(loaded, (bool, str)):
            return loaded
    hint = (" (set one element of an array: NAME[i]=VALUES)"
            if text.startswith("[") or text.endswith("]") else "")
    raise SceneError(f"--set {setting}: '{text}' is not a finite number, a boolean or a "
                     f"name{hint}")


def _number(text: str, setting: str) -> float:
    value = _scalar(text, setting)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"--set {setting}: '{text}' in a range is not a number")
    return float(value)


def parse_setting(text: str) -> Setting:
    """Parse ``NAME=VALUES`` (see the module docstring); :class:`SceneError` if malformed."""
    name, equals, values = text.partition("=")
    match = _NAME.fullmatch(name.strip())
    if not equals or match is None:
        raise SceneError(f"--set {text}: expected NAME=VALUES with a dotted parameter name, "
                         "e.g. bodies.left.mass=1,2,3")
    index = None if match["index"] is None else int(match["index"])
    base: dict[str, Any] = dict(text=text, name=match["name"], index=index)
    if ":" in values:
        parts = values.split(":")
        if len(parts) == 2:
            start, stop = (_number(p, text) for p in parts)
            return Setting(**base, interval=(start, stop))
        if len(parts) == 3:
            start, stop = _number(parts[0], text), _number(parts[1], text)
            count = _scalar(parts[2], text)
            if isinstance(count, bool) or not isinstance(count, int) or count < 1:
                raise SceneError(f"--set {text}: the count '{parts[2]}' is not a positive "
                                 "whole number")
            if count == 1 and start != stop:
                # linspace gives start alone: the stop, said to be included, would be lost.
                raise SceneError(f"--set {text}: one value cannot include both ends; give "
                                 f"a count of 2 or more, or start equal to stop")
            if count > MAX_VARIANTS:
                raise SceneError(f"--set {text}: the count {count} is over the "
                                 f"{MAX_VARIANTS} variants a sweep may have")
            return Setting(**base, values=tuple(np.linspace(start, stop, count).tolist()))
        raise SceneError(f"--set {text}: a range is start:stop:count or start:stop")
    items = [item.strip() for item in values.split(",")]
    if not all(items):
        raise SceneError(f"--set {text}: empty value in the list")
    return Setting(**base, values=tuple(_scalar(item, text) for item in items))


def _check_distinct(settings: Sequence[Setting]) -> None:
    """One ``--set`` per parameter: two would make two columns of one name."""
    seen: dict[str, Setting] = {}
    for setting in settings:
        if setting.column in seen:
            raise SceneError(f"--set {setting.text}: '{setting.column}' is set by --set "
                             f"{seen[setting.column].text} too; give all its values in one")
        seen[setting.column] = setting


def grid(settings: Sequence[Setting]) -> list[tuple[Value, ...]]:
    """Every combination of the settings' values, the last setting varying fastest."""
    _check_distinct(settings)
    for setting in settings:
        if setting.interval is not None:
            raise SceneError(f"--set {setting.text}: an interval start:stop needs --samples; "
                             "give start:stop:count for a grid")
    size = math.prod(len(s.values) for s in settings)
    if size > MAX_VARIANTS:
        raise SceneError(f"--set: the grid of {' x '.join(str(len(s.values)) for s in settings)}"
                         f" values is {size:.3g} variants, over the {MAX_VARIANTS} a sweep may "
                         "have; narrow it or draw --samples")
    return list(itertools.product(*(s.values for s in settings)))


def sample(settings: Sequence[Setting], count: int, seed: int) -> list[tuple[Value, ...]]:
    """``count`` draws of every setting from a generator seeded with ``seed``, in order:
    variant by variant, setting by setting."""
    _check_distinct(settings)
    if not 1 <= count <= MAX_VARIANTS:
        raise SceneError(f"--samples {count}: must be from 1 to {MAX_VARIANTS}")
    if not 0 <= seed < 2 ** 64:
        raise SceneError(f"--seed {seed}: must be a whole number from 0 to 2**64 - 1")
    generator = np.random.default_rng(seed)
    draws = []
    for _ in range(count):
        row: list[Value] = []
        for setting in settings:
            if setting.interval is not None:
                row.append(float(generator.uniform(*setting.interval)))
            else:
                row.append(setting.values[int(generator.integers(len(setting.values)))])
        draws.append(tuple(row))
    return draws


def _set(params: dict[str, Any], setting: Setting, value: Value, source: str) -> None:
    """Set one value in the flat parameters; the name must be in the scene or be a
    parameter of a group the scene has (a default made explicit)."""
    where = f"{source}: --set {setting.text}"
    if setting.index is not None:
        array = params.get(setting.name)
        if not isinstance(array, list):
            raise SceneError(f"{where}: '{setting.name}' is not an array in the scene")
        if setting.index >= len(array):
            raise SceneError(f"{where}: '{setting.name}' has {len(array)} element(s)")
        array[setting.index] = value
        return
    group = setting.name.rpartition(".")[0]
    if setting.name not in params and group and \
            not any(key.startswith(group + ".") for key in params):
        raise SceneError(f"{where}: the scene has no parameter '{setting.name}' (and no "
                         f"group '{group}')")
    params[setting.name] = value


def make_variants(scene: str, settings: Sequence[Setting], *, samples: Optional[int] = None,
                  seed: int = 0, duration_ns: Optional[int] = None,
                  duration_given: Optional[str] = None) -> list[Variant]:
    """Load ``scene``, build and check every variant's scene (raises :class:`SceneError`);
    ``duration_given``: ``duration_ns`` as the command line wrote it, for messages."""
    source, nested = scene_parameters(scene)
    base = flatten(nested) if isinstance(nested, Mapping) else {}
    rows = grid(settings) if samples is None else sample(settings, samples, seed)
    if duration_ns is not None:
        base["duration"] = duration_ns * 1e-9  # read back to the same ns by the loader
    variants = []
    for index, row in enumerate(rows):
        params = copy.deepcopy(base)
        for setting, value in zip(settings, row):
            _set(params, setting, value, source)
        built = scene_from_parameters(params, f"{source} (variant {index})")
        check_takes_a_step(built.duration_ns, built.step_ns, f"{built.source}: " + (
            "--duration" if duration_ns is not None else "duration"), given=duration_given)
        variants.append(Variant(index, tuple((s.column, v) for s, v in zip(settings, row)),
                                built, params))
    return variants
