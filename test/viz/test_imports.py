"""The node's and the core's modules never import matplotlib; progress bars stay off
stderr unless asked for or stderr is a terminal."""
from __future__ import annotations

import subprocess
import sys

from hecker_dynamics.cli import main


def test_core_cli_and_node_logic_import_no_matplotlib():
    modules = ["hecker_dynamics", "hecker_dynamics.cli", "hecker_dynamics.geometry",
               "hecker_dynamics.scene", "hecker_dynamics.dynamics", "hecker_dynamics.contact",
               "hecker_dynamics.integrators", "hecker_dynamics.ros", "hecker_dynamics.bags",
               "hecker_dynamics.viz", "hecker_dynamics.viz.frames",
               "hecker_dynamics.viz.progress", "hecker_dynamics.viz.commands"]
    code = ("import sys\n" + "".join(f"import {m}\n" for m in modules) +
            "print(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('matplotlib', 'PIL')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"


def test_progress_bar_only_when_asked(tmp_path, capsys):
    assert main(["script", "ship", "-o", str(tmp_path / "in"), "--duration", "1"]) == 0
    capsys.readouterr()
    # stderr is captured here, not a terminal: no bar by default.
    assert main(["replay", "ship", str(tmp_path / "in"), "-o", str(tmp_path / "a")]) == 0
    assert capsys.readouterr().err == ""
    assert main(["replay", "ship", str(tmp_path / "in"), "-o", str(tmp_path / "b"),
                 "--progress"]) == 0
    err = capsys.readouterr().err
    assert "replay" in err and "100% of 1 s sim time" in err
