"""How a command stops on a signal: SIGTERM (a CI job's timeout, ``kill``) raised in the
main thread as :class:`Terminated`, so that the command unwinds as on Ctrl-C (the writers
remove what they had begun, a sweep stops its workers), and one line saying why, with the
shell's status for the signal. Imports nothing heavy: the console script stops on either
signal with that line while it imports the command line (:mod:`hecker_dynamics.console`)."""
from __future__ import annotations

import signal
import sys
from typing import NoReturn

__all__ = ["Terminated", "raise_terminated", "stop_line", "stopped"]


class Terminated(BaseException):
    """SIGTERM, raised in the main thread by :func:`raise_terminated`."""


def raise_terminated(signum: int, frame: object) -> NoReturn:
    """A SIGTERM handler: unwind the main thread as Ctrl-C does."""
    raise Terminated


def stop_line(signum: int) -> str:
    """The line that says a command stopped on ``signum`` (SIGINT or SIGTERM)."""
    return f"hecker-dynamics: {'interrupted' if signum == signal.SIGINT else 'terminated'}"


def stopped(stop: KeyboardInterrupt | Terminated) -> int:
    """Say on stderr that the command stopped on ``stop``; its exit status, 128 + the
    signal's number."""
    signum = signal.SIGINT if isinstance(stop, KeyboardInterrupt) else signal.SIGTERM
    print(stop_line(signum), file=sys.stderr)
    return 128 + signum
