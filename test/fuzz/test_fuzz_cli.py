"""Fuzzers of the command lines that write and read files: ``sweep``, ``render``, ``plot``
and ``regress``, with hostile arguments: output paths of every kind (``/proc``,
``/dev/null``, folders, missing folders, files used as folders, empty, existing files,
names with spaces, line breaks, bytes that are not UTF-8, a leading dash, 255 and 300
characters), numbers (0, negative, NaN, inf, 1e300, huge counts and grids) and metric
expressions of every shape.

Each case knows whether its arguments are all valid. A valid case must exit 0 and write
its file (a sweep's metric columns equal to an independent evaluation of the expression);
an invalid one must exit 2 in one line (argparse's refusals too) and change nothing in
its folder. Never a traceback, a hang or a silent pass. Seeded; ``--fuzz-seconds`` sets
how long each runs.
"""
from __future__ import annotations

import csv
import importlib.util
import math
import os
import random
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from harness import judge, run_cli

GOLDEN = Path(__file__).resolve().parents[1] / "golden"
#: A case starts a Python with numpy and matplotlib, and may run a sweep's pool: under a
#: machine's full load that can take a minute; a hang is a case past this.
CASE_TIMEOUT = 180.0
SAMPLE_BAG = str(GOLDEN / "sample" / "output")


@dataclass
class Case:
    """One command line, and whether every argument in it is one the command must take."""

    argv: list[str] = field(default_factory=list)
    valid: bool = True
    output: Optional[str] = None  # what a valid case writes (relative to its folder)
    notes: list[str] = field(default_factory=list)

    def add(self, *args: str, valid: bool = True, note: str = "") -> None:
        self.argv += args
        self.valid = self.valid and valid
        if note:
            self.notes.append(note)


def _sandbox(folder: Path) -> None:
    """What the paths below refer to: existing files and a folder named like outputs."""
    folder.mkdir()
    for suffix in (".csv", ".parquet", ".gif", ".png", ".svg", ".pdf", ".mp4"):
        (folder / f"old{suffix}").write_text("old")
        (folder / f"folder{suffix}").mkdir()


def _listing(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() if p.is_file() else b"<dir>"
            for p in sorted(folder.rglob("*"))}


def _output_path(rng: random.Random, suffixes: list[str], good: str) -> tuple[str, bool]:
    """An output path, and whether the command must accept it; ``good`` is a suffix the
    command writes."""
    odd_names = ["with space", "ünïcødé", "new\nline", "\udcff\udcfe", "tab\tname",
                 "x" * 240, "semi;colon", "quote'\"", "*?[glob]", "-dash"]
    kind = rng.randrange(12)
    if kind == 0:
        return "", False
    if kind == 1:
        return rng.choice([".", "..", "folder/", "/", "./"]), False
    if kind == 2:
        return f"folder{rng.choice([s for s in suffixes if s])}", False
    if kind == 3:
        return rng.choice(["/dev/null", "/dev/zero", "/proc/self/status"]), False
    if kind == 4:
        return f"/proc/x{good}", False
    if kind == 5:
        return f"missing/deeper/x{good}", False
    if kind == 6:
        return f"old.csv/x{good}", False
    if kind == 7:
        return f"old{good}", False  # exists, no --overwrite
    if kind == 8:
        return "y" * 300 + good, False
    if kind == 9:
        return f"{rng.choice(odd_names)}{good}", True
    if kind == 10:
        return f"new{rng.choice(suffixes)}", True  # the command's own rule decides
    return f"new{good}", True


def _option_output(case: Case, option: str, path: str, valid: bool) -> None:
    """``-o PATH``; a path that starts with a dash as ``--output=PATH``."""
    if path.startswith("-"):
        case.add(f"{option}={path}", valid=valid)
    else:
        case.add(option, path, valid=valid)
    if valid:
        case.output = path


def _pick(rng: random.Random, good: list[str], bad: list[str]) -> tuple[str, bool]:
    if rng.random() < 0.75:
        return rng.choice(good), True
    return rng.choice(bad), False


# ----------------------------------------------------------------------------- metrics

#: Functions and their arities, with the reference meaning of each.
FUNCTIONS: dict[str, tuple[int, Callable[..., float]]] = {
    "abs": (1, abs), "sqrt": (1, math.sqrt), "exp": (1, math.exp), "log": (1, math.log),
    "sin": (1, math.sin), "floor": (1, math.floor), "atan2": (2, math.atan2),
    "hypot": (2, math.hypot), "min": (2, min), "max": (3, max)}
BINARY: dict[str, Callable[[float, float], float]] = {
    "+": lambda a, b: a + b, "-": lambda a, b: a - b, "*": lambda a, b: a * b,
    "/": lambda a, b: a / b, "//": lambda a, b: a // b, "%": lambda a, b: a % b,
    "**": math.pow, "<": lambda a, b: float(a < b), ">=": lambda a, b: float(a >= b)}


def _expression(rng: random.Random, depth: int) -> tuple[str, Callable[[dict], float]]:
    """A random expression over the row's ``variant`` and ``bodies.left.mass`` and its
    meaning, built side by side (the reference the evaluator is checked against)."""
    if depth <= 0 or rng.random() < 0.3:
        leaf = rng.choice(["variant", "bodies.left.mass", "2", "-3", "0", "0.5", "1e308",
                           "1e-300", "7"])
        if leaf[0].isalpha():
            return leaf, lambda row, name=leaf: float(row[name])
        return leaf, lambda row, value=float(leaf): value
    kind = rng.randrange(3)
    if kind == 0:
        name = rng.choice(sorted(FUNCTIONS))
        arity, function = FUNCTIONS[name]
        parts = [_expression(rng, depth - 1) for _ in range(arity)]
        return (f"{name}({', '.join(text for text, _ in parts)})",
                lambda row: function(*(f(row) for _, f in parts)))
    if kind == 1:
        text, inner = _expression(rng, depth - 1)
        return f"-({text})", lambda row: -inner(row)
    op = rng.choice(sorted(BINARY))
    (left, f), (right, g) = _expression(rng, depth - 1), _expression(rng, depth - 1)
    return f"({left}) {op} ({right})", lambda row: BINARY[op](f(row), g(row))


def _reference(meaning: Callable[[dict], float], row: dict) -> Optional[float]:
    try:
        value = float(meaning(row))
    except (ArithmeticError, ValueError):
        return None
    return value


BAD_METRICS = ["x=__import__('os')", "x=left.x.__class__", "x=[1][0]", "x='a'", "x=min(1)",
               "x=atan2(1)", "x=sqrt()", "x=lambda: 1", "x=" + "+".join(["1"] * 2000),
               "x=" + "-" * 500 + "1", "x=" + "(" * 300 + "1" + ")" * 300, "status=0",
               "message=1", "variant=2", "left.x", "x=nosuch + 1", "x=", "=1", "x=1 +",
               "x=f'{1}'", "x=(y := 1)", "x=*a", "x=1 if 2", "x=abs(x=1)", "energy=1"]


def _sweep_case(rng: random.Random) -> tuple[Case, list[tuple[str, Callable]]]:
    case = Case(["sweep", "sample", "--workers", "1", "--no-progress"])
    counts = rng.choice([("bodies.left.mass=1,2", True), ("bodies.left.mass=0.5:1:3", True),
                         ("bodies.left.mass=1:2:1000000", False),
                         ("bodies.left.mass=nan,1", False), ("bodies.lefft.mass=1", False),
                         ("bodies.left.mass=", False), ("bodies.left.mass=0", False),
                         ("bodies.left.mass=1:2", None), ("=1", False),
                         ("bodies.left.mass=1e300", True)])
    setting, valid = counts
    samples = rng.random() < 0.4
    case.add("--set", setting, valid=(samples if valid is None else bool(valid)))
    if rng.random() < 0.2:
        case.add("--set", rng.choice(["bodies.left.mass=3", "bodies.right.mass=1:2:1000000",
                                      "bodies.right.mass=-1"]), valid=False)
    if samples:
        value, valid = _pick(rng, ["1", "2"], ["0", "-1", "10000000", "1e3", "x", ""])
        case.add("--samples", value, valid=valid)
        if rng.random() < 0.5:
            value, valid = _pick(rng, ["0", "7", str(2 ** 64 - 1)],
                                 ["-1", str(2 ** 64), "1.5", "nan", "9" * 5000])
            case.add("--seed", value, valid=valid)
    elif rng.random() < 0.1:
        case.add("--seed", "3", valid=False)  # --seed needs --samples
    value, valid = _pick(rng, ["0.02", "0.04"], ["-1", "nan", "inf", "2e9", "1e999999", "x"])
    case.add("--duration", value, valid=valid)
    metrics: list[tuple[str, Callable]] = []
    for k in range(rng.choice([0, 1, 1, 2])):
        if rng.random() < 0.7:
            text, meaning = _expression(rng, rng.randint(0, 4))
            case.add("--metric", f"m{k}={text}", valid=len(text) <= 1000 - 3)
            metrics.append((f"m{k}", meaning))
        else:
            case.add("--metric", rng.choice(BAD_METRICS), valid=False)
    if rng.random() < 0.2:
        value, valid = _pick(rng, ["bags"], ["old.csv", "/proc/bags", "", "old.csv/bags"])
        case.add("--bags", value, valid=valid)
    path, valid = _output_path(rng, [".csv", ".parquet", ".gif", ""], ".csv")
    _option_output(case, "-o", path, valid)  # any other suffix: .parquet (or .csv) is added
    if rng.random() < 0.1:
        case.add("--workers", rng.choice(["0", "-1", "100000", "x"]), valid=False)
    return case, metrics


def _render_case(rng: random.Random) -> tuple[Case, list]:
    case = Case(["render", rng.choice(["sample", "ship"]) if rng.random() < 0.95 else
                 "nonesuch"])
    case.valid = case.argv[1] != "nonesuch"
    bag = rng.random() < 0.3 and case.argv[1] == "sample"
    if bag:
        value, valid = _pick(rng, [SAMPLE_BAG], ["old.csv", "/proc", "missing", "",
                                                 str(GOLDEN / "ship" / "output")])
        case.add("--bag", value, valid=valid)
    value, valid = _pick(rng, ["5", "10", "20"], ["0", "-1", "nan", "inf", "1e300", "x",
                                                  "1001"])
    case.add("--fps", value, valid=valid)
    value, valid = _pick(rng, ["0.2", "0.3"], ["-1", "nan", "inf", "1e9", "1e300", "0"])
    case.add("--duration", value, valid=valid)
    if rng.random() < 0.5:
        value, valid = _pick(rng, ["0", "0.1"], ["-1", "nan", "1e6", "1e300", "x"])
        case.add("--start", value, valid=valid)
    if rng.random() < 0.4:
        value, valid = _pick(rng, ["32x24", "64x48"], ["0x0", "5000x10", "x", "1e9x1",
                                                       "-16x16", "16"])
        case.add("--size", value, valid=valid)
    else:
        case.add("--size", "48x36")
    if rng.random() < 0.2:
        value, valid = _pick(rng, ["-3,-3,3,3"], ["0,0,0,0", "nan,0,1,1", "1,2,3", "a,b,c,d",
                                                  "0,0,inf,1"])
        case.add(f"--view={value}", valid=valid)
    suffixes = [".gif", ".png", ".svg", ".jpg", ".txt", ""]
    good = rng.choice([".gif", ".png", ".svg"])
    path, valid = _output_path(rng, suffixes, good)
    _option_output(case, "-o", path, valid and path.endswith((".gif", ".png", ".svg")))
    return case, []


def _plot_case(rng: random.Random) -> tuple[Case, list]:
    case = Case(["plot"])
    value, valid = _pick(rng, [SAMPLE_BAG], ["missing", "old.csv", "/proc", "",
                                             str(GOLDEN / "sample" / "input")])
    case.add(value, valid=valid)
    if rng.random() < 0.3:
        value, valid = _pick(rng, [SAMPLE_BAG], ["missing", str(GOLDEN / "ship" / "output")])
        case.add(value, valid=valid)
    if rng.random() < 0.3:
        value, valid = _pick(rng, ["sample"], ["nonesuch", "/etc/passwd", ""])
        case.add("--scene", value, valid=valid)
    path, valid = _output_path(rng, [".png", ".svg", ".pdf", ".jpg", ""], ".png")
    _option_output(case, "-o", path, valid and path.endswith((".png", ".svg", ".pdf")))
    return case, []


def _regress_case(rng: random.Random) -> tuple[Case, list]:
    """regress writes nothing: its paths are bags to read; a bad one is one line, exit 2."""
    case = Case(["regress", "--no-progress", "--workers", "1"])
    value, valid = _pick(rng, [SAMPLE_BAG], ["missing", "old.csv", "/proc/self", "",
                                             "/dev/null", "folder.csv"])
    case.add(value, valid=valid)
    if rng.random() < 0.3:
        value, valid = _pick(rng, ["sample"], ["nonesuch", "/etc/passwd", "old.csv", ""])
        case.add("--scene", value, valid=valid)
    if rng.random() < 0.3:
        value, valid = _pick(rng, ["0", "1e-9"], ["-1", "nan", "x"])
        case.add("--atol", value, valid=valid)
    if rng.random() < 0.1:
        case.add("--workers", rng.choice(["0", "100000", "x"]), valid=False)
    return case, []


def _check_table(path: Path, metrics: list[tuple[str, Callable]], what: str) -> None:
    """Every metric cell is the reference evaluation of its expression on the row."""
    with path.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert rows, what
    for row in rows:
        numbers = {"variant": float(row["variant"]),
                   "bodies.left.mass": float(row["bodies.left.mass"])}
        for name, meaning in metrics:
            want, cell = _reference(meaning, numbers), row[name]
            if want is None:
                assert cell == "", f"{what}: {name} = {cell!r}, undefined by the reference"
            else:
                got = float(cell)
                assert got == want or (math.isnan(got) and math.isnan(want)), \
                    f"{what}: {name} = {got!r}, the reference says {want!r}"


def _fuzz(request, tmp_path: Path, make: Callable[[random.Random], tuple[Case, list]]) -> None:
    seconds = request.config.getoption("--fuzz-seconds")
    rng = random.Random(request.config.getoption("--fuzz-seed"))
    deadline = time.monotonic() + seconds
    cases = 0
    while time.monotonic() < deadline or cases < 3:
        folder = tmp_path / f"case{cases}"
        _sandbox(folder)
        case, metrics = make(rng)
        before = _listing(folder)
        outcome = run_cli(*case.argv, cwd=str(folder), timeout=CASE_TIMEOUT)
        what = f"case {cases}: {case.argv!r} (valid: {case.valid})"
        if case.argv[0] == "regress" and outcome.code == 2 and not outcome.err:
            # A bag that cannot be checked: its ERROR line and the summary, on stdout.
            assert outcome.out.splitlines()[-1].endswith("error"), f"{what}\n{outcome.out}"
        else:
            judge(outcome, what)
        if case.argv[0] == "regress":
            # Checking a bag is the replay's business: a good bag may match or not.
            assert case.valid or outcome.code == 2, f"{what}: a bad path passed\n{outcome}"
        elif case.valid:
            assert outcome.code == 0, f"{what}: refused\n{outcome.err}"
            assert case.output is not None
            written = folder / Path(case.output)
            if case.argv[0] == "sweep" and written.suffix not in (".csv", ".parquet"):
                written = written.with_name(written.name + (
                    ".parquet" if importlib.util.find_spec("pyarrow") else ".csv"))
            assert written.is_file() and written.stat().st_size > 0, f"{what}: no file"
            if metrics and written.suffix == ".csv":
                _check_table(written, metrics, what)
        else:
            assert outcome.code == 2, f"{what}: a bad argument passed (exit {outcome.code})" \
                                      f"\n{outcome.out[-1000:]}{outcome.err[-1000:]}"
            assert _listing(folder) == before, f"{what}: refused, but changed its folder"
        assert os.path.exists("/dev/null") and not os.path.isfile("/dev/null")
        cases += 1


def test_fuzz_sweep(request, tmp_path):
    _fuzz(request, tmp_path, _sweep_case)


def test_fuzz_render(request, tmp_path):
    _needs_pictures()
    _fuzz(request, tmp_path, _render_case)


def test_fuzz_plot(request, tmp_path):
    _needs_pictures()
    _fuzz(request, tmp_path, _plot_case)


def _needs_pictures() -> None:
    """Skip where the cases' commands, run in Pythons of their own, cannot draw (a ROS
    machine need not have the viz extra); the import skips with the reason
    (test/optional_modules.py)."""
    import matplotlib  # noqa: F401
    import PIL  # noqa: F401


def test_fuzz_regress(request, tmp_path):
    _fuzz(request, tmp_path, _regress_case)
