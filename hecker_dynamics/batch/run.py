"""Sweeps and regression suites: the tasks the workers run, and the loops that hand them
to an engine and gather the results.

The task functions are module-level and take one picklable argument, so a process pool
or a Dask worker can run them; they import only the core (no engine).
"""
from __future__ import annotations

import re
import tempfile
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Optional

import yaml

from ..bags.check import check_recording
from ..bags.compare import Tolerances
from ..bags.io import BagError, read_bag
from ..bags.replay import replay_to_bag, script_to_bag
from ..dynamics.simulation import DivergenceError
from ..files import OutputError, replacing
from ..scene.commands import InputError
from ..scene.load import load_scene, shipped_scenes
from ..scene.names import NODE_NAME
from ..scene.parameters import SceneError, quoted, unflatten
from ..viz.progress import Progress
from .engines import Engine, stop_point
from .metrics import STATE_FIELDS, Cell, Metric, summarize
from .table import PartialRows, partial_path, table_path, write_table
from .variants import Variant

__all__ = ["SweepTask", "run_variant", "sweep", "check_metrics", "bag_names", "BagTask",
           "BagResult", "check_bag", "find_bags", "regress", "progress_bar"]


# ----------------------------------------------------------------------------- progress

def progress_bar(items: Iterator[Any], total: int, label: str, show: bool) -> Iterator[Any]:
    """``items``, counted on a bar on stderr if ``show``."""
    bar = Progress(label, total, unit="runs", enabled=show)
    try:
        for done, item in enumerate(items, 1):
            bar(done / total)
            yield item
    finally:
        bar.close()


# ----------------------------------------------------------------------------- sweep

@dataclass(frozen=True)
class SweepTask:
    """One variant to run, the metrics to evaluate on it and where to write its bag."""

    variant: Variant
    metrics: tuple[Metric, ...] = ()
    bags: Optional[Path] = None


def _numbers(row: Mapping[str, Cell]) -> dict[str, Cell]:
    """The names a metric may read: the row's columns, and ``energy`` for the final energy."""
    return {**row, "energy": row["energy_end"]}


def run_variant(task: SweepTask) -> dict[str, Cell]:
    """The table row of one variant: its index and values, its summary, its metrics. It
    may stop at each publish instant of its runs (:func:`~.engines.stop_point`), its bag
    and parameters file removed."""
    variant = task.variant
    row: dict[str, Cell] = {"variant": variant.index, **dict(variant.values)}
    row.update(summarize(variant.scene, between=stop_point))
    names = _numbers(row)
    row.update({metric.name: metric.evaluate(names) for metric in task.metrics})
    if task.bags is not None:
        _write_bag(variant, task.bags)
    return row


def _bag_name(variant: Variant) -> str:
    return f"variant-{variant.index:06d}"


def _write_bag(variant: Variant, directory: Path) -> None:
    """The variant's parameters file and a bag of its scripted inputs and outputs, as
    ``replay --check`` reads them (``regress`` finds the file next to the bag)."""
    name = _bag_name(variant)
    scene_file = directory / f"{name}.yaml"
    # Whole or not at all, as the bag is: regress would read a cut file as the scene.
    with replacing(scene_file, option="--bags", overwrite=True) as scratch:
        scratch.write_text(yaml.safe_dump(
            {NODE_NAME: {"ros__parameters": unflatten(variant.parameters)}}, sort_keys=True))
    scene = replace(variant.scene, source=str(scene_file))
    try:
        with tempfile.TemporaryDirectory() as scratch_bags:
            script_to_bag(scene, Path(scratch_bags) / "inputs")
            replay_to_bag(scene, read_bag(Path(scratch_bags) / "inputs"), directory / name,
                          with_inputs=True, overwrite=True, progress=lambda _: stop_point())
    except BaseException:
        scene_file.unlink(missing_ok=True)  # the parameters of a bag that is not there
        raise


def summary_columns(variant: Variant) -> set[str]:
    """The names a metric may read on ``variant``'s row (without running it)."""
    fixed = {"variant", "time", "steps", "energy", "energy_start", "energy_end", "energy_max",
             "contacts_end", "contacts_max", *(column for column, _ in variant.values)}
    extrema = ("x_min", "x_max", "y_min", "y_max", "speed_max")
    return fixed | {f"{body.name}.{field}" for body in variant.scene.bodies
                    for field in (*STATE_FIELDS, *extrema)}


#: Columns of every row that hold text, not numbers: no metric reads them or takes their name.
TEXT_COLUMNS = ("status", "message")


def check_metrics(metrics: Sequence[Metric], variants: Sequence[Variant]) -> None:
    """Raise :class:`SceneError` for a metric that reads a name the rows do not have, whose
    name is already a column (``status`` too), or whose name another metric has."""
    if not variants:
        return
    columns = summary_columns(variants[0])
    named: dict[str, Metric] = {}
    for metric in metrics:
        metric.check(columns)
        if metric.name in columns or metric.name in TEXT_COLUMNS:
            raise SceneError(f"--metric {metric.text}: '{metric.name}' is already a column; "
                             "name the metric: NAME=EXPRESSION")
        if metric.name in named:
            raise SceneError(f"--metric {metric.text}: '{metric.name}' is the name of "
                             f"--metric {named[metric.name].text} too; give each its own")
        named[metric.name] = metric


def bag_names(variants: Sequence[Variant]) -> list[str]:
    """What ``sweep --bags DIR`` writes into DIR: each variant's parameters file and bag."""
    return [name for v in variants for name in (f"{_bag_name(v)}.yaml", _bag_name(v))]


def sweep(variants: Sequence[Variant], engine: Engine, output: Path, *,
          metrics: Sequence[Metric] = (), bags: Optional[Path] = None,
          function: Callable[[SweepTask], dict[str, Cell]] = run_variant,
          progress: bool = False, overwrite: bool = False) -> Path:
    """Run every variant on ``engine`` and write the table; returns its path.

    Finished rows go to the partial file as they come (kept if the sweep fails); the
    table, sorted by variant, is written at the end. ``function`` runs one task. Neither
    file, nor a bag, replaces one that exists unless ``overwrite``; an :class:`OSError`
    of the writing becomes an :class:`~hecker_dynamics.files.OutputError`.
    """
    path = table_path(output)
    partial = PartialRows(partial_path(path), overwrite=overwrite)
    tasks = [SweepTask(v, tuple(metrics), bags) for v in variants]
    rows = []
    finished = False
    try:
        if bags is not None:
            bags.mkdir(parents=True, exist_ok=True)
        for _, row in progress_bar(engine.run(function, tasks), len(tasks), "sweep", progress):
            partial.add(row)
            rows.append(row)
        write_table(path, rows, overwrite=overwrite)
        finished = True
    except OSError as error:  # a worker's bag or the partial file; the table says itself
        raise OutputError(f"cannot write the sweep's output: {error}") from None
    finally:
        partial.close(keep=not finished)
    return path


# ----------------------------------------------------------------------------- regress

@dataclass(frozen=True)
class BagTask:
    """One bag to check: its directory, the scene (None: from the bag), tolerances, where
    the scene files the bags name are (None: beside each bag), and what to check."""

    bag: Path
    scene: Optional[str]
    tolerances: Tolerances
    scene_dir: Optional[str] = None
    topics: Optional[tuple[str, ...]] = None
    partial: bool = False


@dataclass(frozen=True)
class BagResult:
    """The outcome of one check: ``ok``, ``mismatch`` or ``error``, and its line."""

    bag: Path
    status: str
    detail: str

    def line(self) -> str:
        return f"{self.status.upper():<8} {self.bag}  {self.detail}"


#: A scene name a bag may give: a file name without a directory (letters, digits, ``_``,
#: ``-`` and ``.``, not first), short enough for any file system.
SCENE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}")


def _scene_of(bag_dir: Path, name: Optional[str], scene_dir: Optional[str]) -> str:
    """The scene a bag names in its ``hecker_dynamics.scene`` custom data: a parameters
    file of that name in ``scene_dir`` (default: the directory that holds the bag, where
    ``sweep --bags`` writes them), else the shipped scene of that name. Nothing else: a
    name with a directory in it, or too long for a file, is refused."""
    if name is None:
        raise BagError(f"{bag_dir}: the bag names no scene (no 'hecker_dynamics.scene' "
                       "custom data); give --scene")
    if not SCENE_NAME.fullmatch(name):
        shown = quoted(name if len(name) <= 60 else name[:57] + "...")
        raise BagError(f"{bag_dir}: the bag's scene {shown} is not a scene name (a file name "
                       "without a directory, at most 100 letters, digits, '_', '-', '.'); "
                       "give --scene")
    directory = Path(scene_dir) if scene_dir is not None else bag_dir.parent
    beside = directory / f"{name}.yaml"
    if beside.is_file():
        return str(beside)
    if name in shipped_scenes():
        return name
    raise BagError(f"{bag_dir}: the bag's scene '{name}' is neither {beside} nor a shipped "
                   "scene; give --scene or --scene-dir")


def check_bag(task: BagTask) -> BagResult:
    """``replay SCENE BAG --check`` on one bag, as a result instead of an exit status."""
    try:
        bag = read_bag(task.bag)
        scene = load_scene(task.scene or _scene_of(task.bag, bag.custom_data.get(
            "hecker_dynamics.scene"), task.scene_dir))
        check = check_recording(scene, bag, tolerances=task.tolerances, topics=task.topics,
                                partial=task.partial, progress=lambda _: stop_point())
    except (SceneError, BagError, InputError, DivergenceError, OSError) as error:
        # The line names the bag first; the reason need not say it again.
        return BagResult(task.bag, "error", str(error).removeprefix(f"{task.bag}: "))
    if check.halted:
        return BagResult(task.bag, "error", check.halted)
    return BagResult(task.bag, "ok" if check.ok else "mismatch", check.verdict())


#: What rosbag2 names a bag's storage files (sqlite3, mcap, and either compressed).
_STORAGE = ("*.db3", "*.mcap", "*.db3.zstd", "*.mcap.zstd")


def _is_bag(path: Path) -> bool:
    """Whether ``path`` is a bag directory: it has ``metadata.yaml``, or a storage file
    without it (a recording cut off before rosbag2 wrote it, which the check then names
    as such: left out, it would pass unseen)."""
    return (path / "metadata.yaml").is_file() or \
        (path.is_dir() and any(next(path.glob(pattern), None) for pattern in _STORAGE))


def _bags_in(folder: Path, seen: set[Path]) -> Iterator[Path]:
    """The bag directories in ``folder`` and, in name order, in its folders, at any depth:
    a suite kept in folders (one per scene, say) is checked whole, not only its top
    folder's bags, and so is a bag inside a bag's folder (``cp -r new suite/old`` where
    ``suite/old`` is a bag puts ``new`` there). Hidden folders (a running writer's
    temporary ones) and a folder reached again (a symlink loop) are not searched; a folder
    that cannot be listed raises :class:`BagError` naming it (its bags would go
    unchecked)."""
    seen.add(folder.resolve())
    try:
        entries = sorted(folder.iterdir())
    except OSError as error:
        raise BagError(f"{folder}: cannot be listed ({error.strerror or error})") from None
    for path in entries:
        if _is_bag(path):
            yield path
        if path.is_dir() and not path.name.startswith(".") and path.resolve() not in seen:
            yield from _bags_in(path, seen)


def find_bags(paths: Sequence[Path]) -> list[Path]:
    """The bags named: each path is a bag directory (see :func:`_is_bag`), with the bags in
    its folders, or holds bag directories (:func:`_bags_in`); raises :class:`BagError` for
    a path that is neither. A bag named again (twice, by a folder and by itself, through a
    symlink) is kept once, with a warning: checked twice it would count twice in the
    summary."""
    found: dict[Path, Path] = {}  # the bag's real path -> the path it was first found by
    for path in paths:
        if _is_bag(path):
            inner = [path, *_bags_in(path, set())]
        else:
            inner = list(_bags_in(path, set())) if path.is_dir() else []
            if not inner:
                raise BagError(f"{path}: not a bag directory and holds none")
        for bag in inner:
            first = found.setdefault(bag.resolve(), bag)
            if first is not bag:
                warnings.warn(f"{bag}: given twice (as {first} before); checked once",
                              stacklevel=2)
    return list(found.values())


def regress(bags: Sequence[Path], engine: Engine, *, scene: Optional[str],
            tolerances: Tolerances, emit: Callable[[BagResult], None],
            progress: bool = False, scene_dir: Optional[str] = None,
            topics: Optional[Sequence[str]] = None, partial: bool = False) -> list[BagResult]:
    """Check every bag on ``engine``; ``emit`` gets each result as it comes. Returns the
    results in the order of ``bags``. ``scene_dir``, ``topics`` and ``partial``: see
    :class:`BagTask`."""
    tasks = [BagTask(bag, scene, tolerances, scene_dir,
                     tuple(topics) if topics is not None else None, partial) for bag in bags]
    results: list[Optional[BagResult]] = [None] * len(tasks)
    for position, result in progress_bar(engine.run(check_bag, tasks), len(tasks), "regress",
                                         progress):
        results[position] = result
        emit(result)
    return [r for r in results if r is not None]

