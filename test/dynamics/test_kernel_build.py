"""The compiled kernel was built where it could be.

pip builds ``hecker_dynamics._kernel`` as an optional extension: without a C compiler or
Python's headers the install goes on and the package uses its pure-Python path. That
fallback must not hide a broken build, so where a compiler and the headers are present the
module has to import. colcon builds it always; that the two builds agree (same sources,
same flags) is checked in test_package.py.
"""
from __future__ import annotations

import importlib
import os
import shutil
import sysconfig
from pathlib import Path

import pytest

COMPILERS = ("cc", "gcc", "clang")


def _why_not_built() -> str | None:
    """Why this machine builds no kernel, or None where it must have one."""
    if os.environ.get("HECKER_DYNAMICS_KERNEL") == "0":
        return "HECKER_DYNAMICS_KERNEL=0 switches the compiled kernel off"
    if not any(shutil.which(name) for name in COMPILERS):
        return f"no C compiler on PATH ({', '.join(COMPILERS)}): pip installs without the kernel"
    include = sysconfig.get_paths()["include"]
    if not (Path(include) / "Python.h").is_file():
        return f"no Python.h in {include} (python3-dev): pip installs without the kernel"
    return None


def test_compiled_kernel_imports_where_it_can_be_built():
    reason = _why_not_built()
    if reason:
        pytest.skip(reason)
    kernel = importlib.import_module("hecker_dynamics._kernel")
    # A compiled module next to the package, not a stray pure-Python stand-in.
    assert Path(kernel.__file__).suffix in (".so", ".pyd")
    package = importlib.import_module("hecker_dynamics")
    assert Path(kernel.__file__).parent == Path(package.__file__).parent
