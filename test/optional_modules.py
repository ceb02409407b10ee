"""The skip of the tests whose optional modules are missing (installed by test/conftest.py).

Where rosbags, matplotlib or Pillow is not installed (a ROS machine need not have them: the
node uses none of them), every test that imports one, at collection or while it runs,
directly or through the package's tools (the bag tools, the pictures, the command line that
imports them), skips with that reason instead of failing: :class:`SkipWithoutModule`
stands first among the import finders and turns the import into pytest's skip.
``HECKER_TEST_HIDE=rosbags`` (or ``matplotlib,PIL``) hides an installed one the same way,
to see on any machine what runs where it is missing."""
from __future__ import annotations

import importlib.abc
import importlib.machinery
import importlib.util
import os
import sys
from collections.abc import Sequence
from types import ModuleType
from typing import Optional

import pytest

#: Modules a test may need that a machine running the suite may lack, and why they skip.
OPTIONAL_MODULES = {
    "rosbags": "rosbags is not installed (pip install rosbags): the bag tools, and the "
               "command line that imports them, need it",
    "matplotlib": "matplotlib is not installed (the viz extra): pictures need it",
    "PIL": "Pillow is not installed (the viz extra): pictures need it",
}


class SkipWithoutModule(importlib.abc.MetaPathFinder):
    """An import finder that skips the importing test for the missing ``modules``, the
    reason naming the test file and line that imported it (pytest would name this file)."""

    def __init__(self, modules: dict[str, str]) -> None:
        self.modules = modules

    def find_spec(self, fullname: str, path: Optional[Sequence[str]] = None,
                  target: Optional[ModuleType] = None) -> Optional[importlib.machinery.ModuleSpec]:
        reason = self.modules.get(fullname.partition(".")[0])
        if reason is not None:
            pytest.skip(f"{reason} (imported from {_test_line()})", allow_module_level=True)
        return None


def _test_line() -> str:
    """The innermost test file's line on the stack: the test or module doing the import."""
    frame = sys._getframe(1)
    while frame is not None:
        name = os.path.basename(frame.f_code.co_filename)
        if name.startswith("test_") and name.endswith(".py"):
            return f"{os.path.relpath(frame.f_code.co_filename)}:{frame.f_lineno}"
        frame = frame.f_back
    return "outside the tests"


def install() -> None:
    """Put the finder in place for the optional modules missing (or hidden) here."""
    hidden = set(filter(None, os.environ.get("HECKER_TEST_HIDE", "").split(",")))
    missing = {name: reason for name, reason in OPTIONAL_MODULES.items()
               if name in hidden or importlib.util.find_spec(name) is None}
    if missing:
        sys.meta_path.insert(0, SkipWithoutModule(missing))
