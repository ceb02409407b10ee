"""docs/architecture.md and the comments of the compiled kernel name files that exist.

The kernel's C comments say which Python module each function repeats; a module that moves
leaves them pointing nowhere. Each such path names its directory below hecker_dynamics/
(a bare ``solver.py`` could be any of several), and docs/architecture.md's table maps every
C file of src/kernel to its Python twin and the test that proves they agree.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "hecker_dynamics"
KERNEL = ROOT / "src" / "kernel"
ARCHITECTURE = ROOT / "docs" / "architecture.md"
#: A Python path as comments write it: words and slashes ending in .py.
PYTHON_PATH = re.compile(r"(?<![\w./])((?:[\w]+/)*\w+\.py)\b")
#: Files the repository root holds rather than the package.
AT_ROOT = {"setup.py"}


def _kernel_files() -> list[Path]:
    return sorted(KERNEL.glob("*.[ch]"))


def _resolves(path: str) -> bool:
    """Whether ``path`` names a file: below hecker_dynamics/ (with or without that
    prefix), or at the repository's root."""
    if path in AT_ROOT or path.startswith("test/"):
        return (ROOT / path).is_file()
    if "/" not in path:
        return False  # a bare module name: which directory is meant?
    return (ROOT / path).is_file() or (PACKAGE / path).is_file()


@pytest.mark.parametrize("source", _kernel_files(), ids=lambda p: p.name)
def test_every_python_path_in_the_kernel_exists(source):
    named = sorted(set(PYTHON_PATH.findall(source.read_text())))
    missing = [path for path in named if not _resolves(path)]
    assert not missing, f"{source.name} names {missing}"


def test_every_path_in_the_architecture_page_exists():
    text = ARCHITECTURE.read_text()
    named = set(PYTHON_PATH.findall(text))
    missing = [path for path in sorted(named) if not _resolves(path)]
    kernel = set(re.findall(r"`([\w]+\.[ch])`", text))
    missing += [name for name in sorted(kernel) if not (KERNEL / name).is_file()]
    assert not missing, f"docs/architecture.md names {missing}"


def test_the_architecture_table_maps_every_kernel_file():
    table = [line for line in ARCHITECTURE.read_text().splitlines() if line.startswith("| ")]
    mapped = {name for line in table for name in re.findall(r"`([\w]+\.[ch])`", line)}
    unmapped = [path.name for path in _kernel_files() if path.name not in mapped]
    assert not unmapped, f"docs/architecture.md's table lacks {unmapped}"


def test_the_tests_the_table_names_exist():
    """Each test named in the table as proof of agreement is a test function of its file."""
    table = [line for line in ARCHITECTURE.read_text().splitlines() if line.startswith("| ")]
    for line in table[2:]:
        proof = line.rstrip(" |").rsplit(" | ", 1)[-1]
        files = re.findall(r"`(test/[\w/]+\.py)`", proof)
        assert files, f"no test proves the row {line!r}"
        functions = re.findall(r"`(test_\w+)`", proof)
        sources = "".join((ROOT / path).read_text() for path in files)
        for function in functions:
            assert f"def {function}(" in sources, f"{function} is in none of {files}"
