"""The package's subpackages form a DAG: each imports only from the layers below it.

Every import statement counts, wherever it stands: at the top, under ``TYPE_CHECKING``, or
inside a function. The layers, lowest first, are the order of the README's "Layout".
"""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "hecker_dynamics"

#: Lowest first. A unit (a subpackage, a top-level module, or the package's own
#: ``__init__``, named "") may import from itself and from units of lower layers only.
#: ``_kernel`` is the compiled kernel, ``msg`` and ``srv`` the ROS interfaces colcon
#: generates; none of them imports the package.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("_version", "_kernel", "files", "stops", "msg", "srv"),
    ("geometry",),
    ("integrators",),
    ("scene",),
    ("contact",),
    ("dynamics",),
    ("sensors", "drives"),
    ("world",),
    ("ros",),
    ("bags",),
    ("viz",),
    ("batch",),
    ("bench",),
    ("cli",),
    ("console",),
    ("",),
)
RANK = {unit: rank for rank, units in enumerate(LAYERS) for unit in units}


def module_name(path: Path, package: Path) -> tuple[str, ...]:
    """``hecker_dynamics/scene/load.py`` -> ("scene", "load"); an ``__init__`` names its
    package."""
    parts = path.relative_to(package).with_suffix("").parts
    return parts[:-1] if parts[-1] == "__init__" else parts


def unit_of(parts: tuple[str, ...], package: Path) -> str:
    """The unit a module (its path below the package) belongs to."""
    if not parts:
        return ""
    first = parts[0]
    if (package / first).is_dir() or (package / f"{first}.py").exists() or first in RANK:
        return first
    return ""   # an attribute of the package's own __init__ (``from .. import x``)


def imported(path: Path, package: Path) -> list[tuple[int, tuple[str, ...]]]:
    """(line, module below the package) of every import of the package in ``path``."""
    here = module_name(path, package)
    own_package = here if path.name == "__init__.py" else here[:-1]
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name.split(".") for alias in node.names]
            found += [(node.lineno, tuple(name[1:])) for name in names
                      if name[0] == package.name]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = own_package[:len(own_package) - (node.level - 1)]
            elif (node.module or "").split(".")[0] == package.name:
                base = ()
            else:
                continue
            module = tuple((node.module or "").split(".")) if node.module else ()
            if not node.level:
                module = module[1:]
            target = base + module
            if target:
                found.append((node.lineno, target))
            else:   # ``from .. import scene``: each name is its own unit
                found += [(node.lineno, (alias.name,)) for alias in node.names]
    return found


def edges_against_layers(package: Path) -> list[str]:
    """Every import that runs upward or sideways between units, as "file:line a -> b"."""
    wrong = []
    for path in sorted(package.rglob("*.py")):
        source = unit_of(module_name(path, package), package)
        for line, target in imported(path, package):
            unit = unit_of(target, package)
            if unit == source:
                continue
            if source not in RANK or unit not in RANK:
                wrong.append(f"{path.relative_to(package.parent)}:{line} {source or '<package>'}"
                             f" -> {unit or '<package>'}: not in LAYERS; give it a layer")
            elif RANK[unit] >= RANK[source]:
                wrong.append(f"{path.relative_to(package.parent)}:{line} {source or '<package>'}"
                             f" -> {'.'.join(target)} runs against the layers")
    return wrong


def test_imports_run_down_the_layers():
    wrong = edges_against_layers(PACKAGE)
    assert not wrong, "imports against the layers:\n" + "\n".join(wrong)


def test_every_unit_has_a_layer():
    units = {unit_of(module_name(path, PACKAGE), PACKAGE) for path in PACKAGE.rglob("*.py")}
    assert units <= set(RANK), f"units without a layer: {sorted(units - set(RANK))}"


def test_the_checker_sees_every_kind_of_import(tmp_path):
    """Top-level, TYPE_CHECKING and function-level imports, relative and absolute, each
    against the layers, are each reported."""
    package = tmp_path / PACKAGE.name
    (package / "scene").mkdir(parents=True)
    (package / "ros").mkdir()
    (package / "__init__.py").write_text("")
    (package / "scene" / "__init__.py").write_text("from . import load\n")
    (package / "ros" / "__init__.py").write_text("")
    (package / "ros" / "names.py").write_text("from ..scene import load\n")
    (package / "scene" / "load.py").write_text(
        "from typing import TYPE_CHECKING\n"
        "from ..ros.names import NODE\n"
        "import hecker_dynamics.ros.names\n"
        "if TYPE_CHECKING:\n"
        "    from hecker_dynamics.ros import names\n"
        "def f():\n"
        "    from .. import ros\n"
        "    from .. import x\n")
    wrong = edges_against_layers(package)
    assert [entry.split(" ", 1)[0] for entry in wrong] == [
        f"{PACKAGE.name}/scene/load.py:{line}" for line in (2, 3, 5, 7, 8)]
    assert wrong[-1].endswith("scene -> x runs against the layers")
