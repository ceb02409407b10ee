"""Progress bars for long work (runs, replays, renders, the benchmark), from tqdm.

A bar goes to stderr, and by default only when stderr is a terminal, so logs and pipes
stay clean.
"""
from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Optional

from tqdm import tqdm

from ..stops import raise_kept_stop

__all__ = ["BarFactory", "Progress", "run_parts", "stderr_is_terminal"]


def stderr_is_terminal() -> bool:
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):  # replaced or closed stderr
        return False


class Progress:
    """A bar of ``total`` ``unit``; call it with the fraction done (0 to 1). Each call is
    also where a Ctrl-C or SIGTERM that Python dropped stops the work (stops.py)."""

    def __init__(self, label: str, total: float, unit: str = "s sim time",
                 enabled: Optional[bool] = None) -> None:
        self.total = total
        self.bar = tqdm(total=total, desc=label, unit=unit, file=sys.stderr, leave=True,
                        disable=not (stderr_is_terminal() if enabled is None else enabled),
                        bar_format="{desc} {bar} {percentage:3.0f}% of {total:g} {unit} "
                                   "[{elapsed}<{remaining}]")

    def __call__(self, fraction: float) -> None:
        raise_kept_stop()
        done = self.total * min(max(fraction, 0.0), 1.0)
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        self.bar.close()


#: Makes a bar for a piece of work: (label, number of parts) -> bar.
BarFactory = Callable[[str, int], Progress]


def run_parts(work: list[tuple[str, Callable[[], None]]], bar: Optional[BarFactory] = None,
              label: str = "") -> None:
    """Do each ``(name, part)`` of ``work`` in turn, on a bar of ``len(work)`` parts made by
    ``bar`` (none without it)."""
    progress = bar(label, len(work)) if bar is not None else None
    try:
        for done, (_, part) in enumerate(work, start=1):
            part()
            if progress is not None:
                progress(done / len(work))
    finally:
        if progress is not None:
            progress.close()
