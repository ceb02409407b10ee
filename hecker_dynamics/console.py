"""The ``hecker-dynamics`` console script.

Importing the command line (numpy, the scene reader, the bag tools) takes most of a second,
and a signal in it ended the process without a word (SIGTERM, Python's default) or with a
traceback (Ctrl-C). Nothing is begun then, so the script ends at once on either, with the
line and status every command gives (:mod:`hecker_dynamics.stops`). It does not raise: an
exception in an import may come out as another (numpy's C import reports one as "could not
import module datetime"). The package imports its API on first use, so nothing heavy runs
before this; what is left is Python's own start, before any code of the package runs.
"""
from __future__ import annotations

import os
import signal
from collections.abc import Sequence
from typing import Optional

from .stops import stop_line

__all__ = ["main"]


def _stop_now(signum: int, frame: object) -> None:
    os.write(2, (stop_line(signum) + "\n").encode())
    os._exit(128 + signum)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the command line (:func:`hecker_dynamics.cli.main`, which takes the signals from
    there) after importing it with SIGTERM and Ctrl-C ending the process at once. A Ctrl-C
    ignored from the start (``cmd &`` in a script) stays ignored."""
    interruptible = signal.getsignal(signal.SIGINT) is signal.default_int_handler
    signal.signal(signal.SIGTERM, _stop_now)
    if interruptible:
        signal.signal(signal.SIGINT, _stop_now)
    from .cli import main as command_line

    if interruptible:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    return command_line(argv)
