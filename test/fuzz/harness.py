"""Run one ``hecker-dynamics`` command line on a mutated input, in a child process with a
timeout, and judge its outcome: exit 0 (and valid where it must be), or exit 1/2 with one
line of stderr (an option argparse refuses too). A traceback, a hang, a crash or several
lines of error fail."""
from __future__ import annotations

import subprocess
import sys
from dataclasses import dataclass
from typing import Optional

import pytest

# The command line imports rosbags as it starts: without it every case would fail alike.
pytest.importorskip("rosbags", reason="rosbags is not installed: the command line needs it")

#: Seconds one case may take (a scene of 0.05 s sim time, a bag of a few thousand
#: messages): a hang is a failure, not a wait.
CASE_TIMEOUT = 30.0


@dataclass
class Outcome:
    code: int
    out: str
    err: str


def run_cli(*argv: str, timeout: float = CASE_TIMEOUT, cwd: Optional[str] = None) -> Outcome:
    try:
        done = subprocess.run([sys.executable, "-m", "hecker_dynamics.cli", *argv],
                              capture_output=True, text=True, timeout=timeout,
                              errors="replace", cwd=cwd)
    except subprocess.TimeoutExpired:
        raise AssertionError(f"hang: {' '.join(argv)} ran over {timeout:g} s") from None
    return Outcome(done.returncode, done.stdout, done.stderr)


def judge(outcome: Outcome, what: str) -> None:
    """Fail on a traceback, a crash, or an error that is not one line."""
    assert "Traceback" not in outcome.err, f"{what}: traceback\n{outcome.err[-3000:]}"
    assert outcome.code in (0, 1, 2), f"{what}: exit {outcome.code}\n{outcome.err[-2000:]}"
    if outcome.code == 2:
        lines = [line for line in outcome.err.splitlines()
                 if not line.startswith("hecker-dynamics: warning: ")]
        assert len(lines) == 1 and lines[0].startswith("hecker-dynamics: error: "), \
            f"{what}: error not one line:\n{outcome.err[-2000:]}"
