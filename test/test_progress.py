"""Progress bars of long commands: on stderr when it is a terminal (a pty here), with the
total of the work, and nothing on stderr when it is not."""
from __future__ import annotations

import os
import re
import struct
import subprocess
import sys

import pytest

from hecker_dynamics.dynamics import kernel

fcntl = pytest.importorskip("fcntl", reason="no pseudo-terminals on this platform")
termios = pytest.importorskip("termios", reason="no pseudo-terminals on this platform")
# The command line these start imports rosbags as it starts.
pytest.importorskip("rosbags", reason="rosbags is not installed: the command line needs it")


def _run(argv: list[str], terminal: bool) -> tuple[str, str]:
    """Run the command line in a process; (stdout, stderr), stderr a pty if ``terminal``."""
    command = [sys.executable, "-m", "hecker_dynamics.cli", *argv]
    env = dict(os.environ)
    if not terminal:
        done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=600)
        assert done.returncode == 0, done.stderr
        return done.stdout, done.stderr
    master, slave = os.openpty()
    # A new pty is 0 columns wide, where tqdm draws an empty line: size it as a terminal.
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 120, 0, 0))
    with subprocess.Popen(command, stdout=subprocess.PIPE, stderr=slave, env=env) as process:
        os.close(slave)
        chunks = []
        while True:
            try:
                chunk = os.read(master, 4096)
            except OSError:  # the other end closed (Linux raises EIO)
                break
            if not chunk:
                break
            chunks.append(chunk)
        out = process.stdout.read().decode()
        assert process.wait(timeout=600) == 0
    os.close(master)
    return out, b"".join(chunks).decode(errors="replace")


def _last_bar(text: str) -> str:
    return re.split(r"[\r\n]", text.strip())[-1]


def test_run_bar_counts_the_scene_duration_on_a_terminal():
    out, err = _run(["run", "ship", "--duration", "2.5"], terminal=True)
    assert out.startswith("scene ")
    bar = _last_bar(err)
    assert bar.startswith("run ") and "100% of 2.5 s sim time" in bar, err


def test_run_writes_nothing_to_stderr_when_it_is_not_a_terminal():
    out, err = _run(["run", "ship", "--duration", "2.5"], terminal=False)
    assert out.startswith("scene ") and err == ""


@pytest.mark.skipif(not kernel.enabled(), reason="the bar is the same either way, and the "
                    "bench's parts take 30 s on the Python path against 3 s in the kernel")
def test_bench_bar_counts_its_parts_on_a_terminal(tmp_path):
    """The contact section in three parts: one pyramid, one scene, the node's cost. (Off a
    terminal it draws nothing, as ``run`` above: both ask ``cli._want_progress``.)"""
    argv = ["bench", "--contacts", "2", "--scenes", "car_flip", "--no-peers",
            "--out", str(tmp_path)]
    out, err = _run(argv, terminal=True)
    assert "target 3." in out
    bar = _last_bar(err)
    assert bar.startswith("bench contacts ") and "100% of 3 parts" in bar, err
