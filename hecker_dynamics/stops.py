"""How a command stops on a signal: SIGTERM (a CI job's timeout, ``kill``) raised in the
main thread as :class:`Terminated`, so that the command unwinds as on Ctrl-C (the writers
remove what they had begun, a sweep stops its workers), and one line saying why, with the
shell's status for the signal. Imports nothing heavy: the console script stops on either
signal with that line while it imports the command line (:mod:`hecker_dynamics.console`)."""
from __future__ import annotations

import signal
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, NoReturn

__all__ = ["Terminated", "keeping_stops", "raise_kept_stop", "raise_terminated", "stop_line",
           "stopped"]


class Terminated(BaseException):
    """SIGTERM, raised in the main thread by :func:`raise_terminated`."""


def raise_terminated(signum: int, frame: object) -> NoReturn:
    """A SIGTERM handler: unwind the main thread as Ctrl-C does."""
    raise Terminated


#: Stops that Python dropped: raised in a ``__del__`` or a weakref callback (matplotlib
#: runs many while it draws), where Python prints an exception and goes on without it.
_kept: list[BaseException] = []


@contextmanager
def keeping_stops() -> Iterator[None]:
    """While the command runs: keep a Ctrl-C or SIGTERM that Python would drop (and print
    as "Exception ignored in ..."), for :func:`raise_kept_stop` to raise again."""
    previous: Callable[[Any], object] = sys.unraisablehook

    def keep(unraisable: Any) -> None:
        if isinstance(unraisable.exc_value, (KeyboardInterrupt, Terminated)):
            _kept.append(unraisable.exc_value)
        else:
            previous(unraisable)

    sys.unraisablehook = keep
    try:
        yield
    finally:
        sys.unraisablehook = previous
        _kept.clear()


def raise_kept_stop() -> None:
    """Raise the stop :func:`keeping_stops` kept, if one came: where the work checks in
    (each step of a progress bar) and once more when the command is done."""
    if _kept:
        stop = _kept[0]
        _kept.clear()
        raise stop


def stop_line(signum: int) -> str:
    """The line that says a command stopped on ``signum`` (SIGINT or SIGTERM)."""
    return f"hecker-dynamics: {'interrupted' if signum == signal.SIGINT else 'terminated'}"


def stopped(stop: KeyboardInterrupt | Terminated) -> int:
    """Say on stderr that the command stopped on ``stop``; its exit status, 128 + the
    signal's number."""
    signum = signal.SIGINT if isinstance(stop, KeyboardInterrupt) else signal.SIGTERM
    print(stop_line(signum), file=sys.stderr)
    return 128 + signum
