"""What one variant of a sweep reports: the summary row of its run.

A variant runs as the node runs its scene with ``play_script`` (the :class:`Runner` loop
the offline replay uses too, with a wall clock that stands still), tick by publish tick,
for the scene's duration. At every publish instant the row follows the total energy
(kinetic plus the potentials of gravity and springs), each body's x, y and speed, and the
contacts the contact pass finds there; at the end it holds the final state of each body.
A divergence ends the run at the last finite state and is reported, not raised.

User metrics are expressions over the row's numbers, e.g. ``right.x - left.x`` or
``hypot(left.vx, left.vy)``, evaluated by a small evaluator that walks the parsed syntax
tree and knows only numbers, names (dotted names read as one column), arithmetic,
comparisons and a few math functions: no attribute access, indexing or calls to anything
else, so an expression cannot reach Python. Its size is bounded before it is parsed
(:data:`MAX_LENGTH` characters, :data:`MAX_DEPTH` levels of nesting), each function's
number of arguments is checked, and ``**`` is ``math.pow`` (a negative number to a
fractional power is undefined, an empty cell, not a complex number).
"""
from __future__ import annotations

import ast
import math
import operator
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Optional, Union

from ..dynamics.simulation import Snapshot
from ..ros.runner import Runner
from ..scene.load import Scene
from ..scene.parameters import SceneError

__all__ = ["Metric", "parse_metric", "summarize", "STATE_FIELDS", "MAX_LENGTH", "MAX_DEPTH"]

Cell = Union[float, int, str, bool, None]

#: Final-state columns of each body, ``<body>.<field>``.
STATE_FIELDS = ("x", "y", "angle", "vx", "vy", "omega", "speed")

_BINARY: dict[type, Callable[[Any, Any], Any]] = {
    ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
    ast.Div: operator.truediv, ast.FloorDiv: operator.floordiv, ast.Mod: operator.mod,
    ast.Pow: math.pow}
_UNARY: dict[type, Callable[[Any], Any]] = {ast.UAdd: operator.pos, ast.USub: operator.neg,
                                            ast.Not: operator.not_}
_COMPARE: dict[type, Callable[[Any, Any], Any]] = {
    ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt, ast.GtE: operator.ge,
    ast.Eq: operator.eq, ast.NotEq: operator.ne}
_FUNCTIONS: dict[str, Callable[..., float]] = {
    "abs": abs, "min": min, "max": max, "sqrt": math.sqrt, "hypot": math.hypot,
    "sin": math.sin, "cos": math.cos, "tan": math.tan, "atan2": math.atan2, "exp": math.exp,
    "log": math.log, "floor": math.floor, "ceil": math.ceil}
#: How many arguments each function takes: (at least, at most; None: any number).
_ARITY: dict[str, tuple[int, Optional[int]]] = {
    "abs": (1, 1), "min": (2, None), "max": (2, None), "sqrt": (1, 1), "hypot": (1, None),
    "sin": (1, 1), "cos": (1, 1), "tan": (1, 1), "atan2": (2, 2), "exp": (1, 1),
    "log": (1, 2), "floor": (1, 1), "ceil": (1, 1)}
#: The longest expression, in characters, and its deepest nesting, in syntax-tree levels:
#: far above any formula over a row, far below what the parser and the evaluator's
#: recursion can take.
MAX_LENGTH = 1000
MAX_DEPTH = 200


def _dotted(node: ast.expr) -> Optional[str]:
    """``left.x`` as the column name ``"left.x"``; None if ``node`` is not a dotted name."""
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        head = _dotted(node.value)
        return None if head is None else f"{head}.{node.attr}"
    return None


@dataclass(frozen=True)
class Metric:
    """A named user metric: ``NAME=EXPRESSION`` (or just the expression, named by itself)."""

    name: str
    text: str
    tree: ast.Expression

    def names(self) -> set[str]:
        """The columns the expression reads (a function called is not one)."""
        called = {id(node.func) for node in ast.walk(self.tree) if isinstance(node, ast.Call)}
        found = set()
        for node in ast.walk(self.tree):
            if isinstance(node, (ast.Name, ast.Attribute)) and id(node) not in called:
                found.add(_dotted(node))
        # A dotted name's heads (``left`` of ``left.x``) are parts of it, not columns.
        return {n for n in found if n is not None
                and not any(o is not None and o.startswith(n + ".") for o in found)}

    def check(self, columns: set[str]) -> None:
        """Raise :class:`SceneError` if the expression reads a column the rows do not have."""
        unknown = sorted(self.names() - columns)
        if unknown:
            raise SceneError(f"--metric {self.text}: unknown name(s) {', '.join(unknown)} "
                             f"(known: {', '.join(sorted(columns))})")

    def evaluate(self, row: Mapping[str, Cell]) -> Optional[float]:
        """The value on ``row``; None where it is undefined (a math domain error, a division
        by zero, a missing value)."""
        try:
            value = _evaluate(self.tree.body, row)
        except (ArithmeticError, ValueError, TypeError):
            return None
        return float(value)


def _evaluate(node: ast.expr, row: Mapping[str, Cell]) -> Any:
    # In floats only: an integer power such as 10 ** 10 ** 10 would take forever.
    if isinstance(node, ast.Constant):  # a number or a boolean: _allowed admits no other
        return float(node.value)  # type: ignore[arg-type]
    name = _dotted(node)
    if name is not None:
        value = row[name]
        if value is None:
            raise ValueError(name)
        return float(value)
    if isinstance(node, ast.BinOp):
        return _BINARY[type(node.op)](_evaluate(node.left, row), _evaluate(node.right, row))
    if isinstance(node, ast.UnaryOp):
        return _UNARY[type(node.op)](_evaluate(node.operand, row))
    if isinstance(node, ast.Compare):
        left = _evaluate(node.left, row)
        for op, right_node in zip(node.ops, node.comparators):
            right = _evaluate(right_node, row)
            if not _COMPARE[type(op)](left, right):
                return False
            left = right
        return True
    if isinstance(node, ast.BoolOp):
        values = [_evaluate(v, row) for v in node.values]
        return all(values) if isinstance(node.op, ast.And) else any(values)
    if isinstance(node, ast.IfExp):
        return _evaluate(node.body if _evaluate(node.test, row) else node.orelse, row)
    assert isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
    return _FUNCTIONS[node.func.id](*(_evaluate(a, row) for a in node.args))


def _allowed(node: ast.AST) -> bool:
    if isinstance(node, ast.Call):
        return (isinstance(node.func, ast.Name) and node.func.id in _FUNCTIONS
                and not node.keywords)
    if isinstance(node, ast.Constant):
        return isinstance(node.value, (int, float)) and not isinstance(node.value, bool) \
            or node.value is True or node.value is False
    if isinstance(node, ast.Attribute):
        return _dotted(node) is not None
    return isinstance(node, (ast.Expression, ast.Name, ast.Load, ast.BinOp, ast.UnaryOp,
                             ast.Compare, ast.BoolOp, ast.IfExp, ast.And, ast.Or,
                             *_BINARY, *_UNARY, *_COMPARE))


def _depth(tree: ast.AST) -> int:
    """The deepest nesting of ``tree`` (without recursion: it is not yet known to be small)."""
    deepest, stack = 0, [(tree, 1)]
    while stack:
        node, depth = stack.pop()
        deepest = max(deepest, depth)
        stack.extend((child, depth + 1) for child in ast.iter_child_nodes(node))
    return deepest


def _check_call(text: str, node: ast.Call) -> None:
    assert isinstance(node.func, ast.Name)
    low, high = _ARITY[node.func.id]
    given = len(node.args)
    if given < low or (high is not None and given > high):
        wanted = f"{low}" if low == high else f"{low} or more" if high is None \
            else f"{low} to {high}"
        raise SceneError(f"--metric {text}: {node.func.id}() takes {wanted} argument(s), "
                         f"not {given}")


def parse_metric(text: str) -> Metric:
    """Parse ``[NAME=]EXPRESSION``; :class:`SceneError` for anything outside the grammar
    or its bounds."""
    if len(text) > MAX_LENGTH:
        raise SceneError(f"--metric {text[:40]}...: longer than {MAX_LENGTH} characters")
    name, equals, expression = text.partition("=")
    if not equals or not name.strip().isidentifier() or expression.startswith("="):
        name, expression = text.strip(), text
    try:
        tree = ast.parse(expression.strip(), mode="eval")
    except SyntaxError as error:
        raise SceneError(f"--metric {text}: not an expression ({error.msg})") from None
    except (MemoryError, RecursionError, ValueError):  # ValueError: a NUL character
        raise SceneError(f"--metric {text}: not an expression the parser can read") from None
    if _depth(tree) > MAX_DEPTH:
        raise SceneError(f"--metric {text}: nested deeper than {MAX_DEPTH} levels")
    for node in ast.walk(tree):
        if not _allowed(node):
            raise SceneError(f"--metric {text}: '{ast.unparse(node)}' is not allowed (numbers, "
                             f"names, arithmetic, comparisons and {', '.join(_FUNCTIONS)})")
        if isinstance(node, ast.Call):
            _check_call(text, node)
    return Metric(name.strip(), text, tree)


# ----------------------------------------------------------------------------- running

class _Extrema:
    """Running minimum and maximum of named quantities."""

    def __init__(self) -> None:
        self.low: dict[str, float] = {}
        self.high: dict[str, float] = {}

    def add(self, name: str, value: float) -> None:
        if name not in self.low:
            self.low[name] = self.high[name] = value
        else:
            self.low[name] = min(self.low[name], value)
            self.high[name] = max(self.high[name], value)


def _observe(extrema: _Extrema, snapshot: Snapshot, contacts: Optional[int]) -> None:
    extrema.add("energy", snapshot.energy)
    if contacts is not None:
        extrema.add("contacts", contacts)
    for body in snapshot.bodies:
        extrema.add(f"{body.name}.x", body.position[0])
        extrema.add(f"{body.name}.y", body.position[1])
        extrema.add(f"{body.name}.speed", math.hypot(*body.linear_velocity))


def summarize(scene: Scene, between: Callable[[], None] = lambda: None) -> dict[str, Cell]:
    """Run ``scene`` for its duration with its script and return its summary row;
    ``between`` is called before each publish tick (it may raise to stop the run).

    Columns: ``status`` (``ok``, ``diverged``, or ``rejected``: a scripted input or drive
    force was refused, the run went on without it) and ``message``; ``time``, ``steps``;
    ``energy_start``, ``energy_end``, ``energy_max``; ``contacts_end`` and ``contacts_max``
    (None for a scene without contacts); per body ``<body>.<field>`` for the final
    :data:`STATE_FIELDS` and ``<body>.x_min``, ``x_max``, ``y_min``, ``y_max``, ``speed_max``
    over the publish instants (the start included).
    """
    runner = Runner(scene, play_script=True, wall_clock=lambda: 0)
    sim = runner.sim
    detector = sim.model.contacts

    def contacts() -> Optional[int]:
        return None if detector is None else len(detector.detect(sim.q))

    first = sim.snapshot()
    extrema = _Extrema()
    _observe(extrema, first, contacts())
    started = runner.advance(0)
    halted, refused = started.diverged, list(started.script_errors)
    period = scene.publish_period_ns
    tick = 0
    while halted is None and tick + period <= scene.duration_ns:
        between()
        tick += period
        result = runner.advance(tick)
        for snapshot in result.snapshots:
            _observe(extrema, snapshot, contacts() if snapshot is result.snapshots[-1] else None)
        halted = result.diverged
        refused += result.script_errors
    last = sim.snapshot()
    final_contacts = contacts()
    if final_contacts is not None:
        extrema.add("contacts", final_contacts)
    row: dict[str, Cell] = {
        "status": "diverged" if halted else "rejected" if refused else "ok",
        "message": halted or (refused[0] if refused else ""),
        "time": last.time_ns * 1e-9, "steps": last.steps,
        "energy_start": first.energy, "energy_end": last.energy,
        "energy_max": extrema.high["energy"],
        "contacts_end": final_contacts, "contacts_max": extrema.high.get("contacts")}
    for body in last.bodies:
        (x, y), (vx, vy) = body.position, body.linear_velocity
        final = (x, y, body.angle, vx, vy, body.angular_velocity, math.hypot(vx, vy))
        row.update({f"{body.name}.{field}": value for field, value in zip(STATE_FIELDS, final)})
        row.update({f"{body.name}.x_min": extrema.low[f"{body.name}.x"],
                    f"{body.name}.x_max": extrema.high[f"{body.name}.x"],
                    f"{body.name}.y_min": extrema.low[f"{body.name}.y"],
                    f"{body.name}.y_max": extrema.high[f"{body.name}.y"],
                    f"{body.name}.speed_max": extrema.high[f"{body.name}.speed"]})
    return row
