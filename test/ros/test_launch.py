"""The launch file's decisions: the node always starts, and ``rviz:=true`` adds RViz2 only
where RViz2 is installed, else one log line saying why there is none.

Without ROS the launch file runs against small stand-ins for ``launch``, ``launch_ros``
and ``ament_index_python`` that record what it asks for; with ROS 2 (launch_ros
importable) the same decisions are checked with the real actions and a real
``LaunchContext``.
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType, SimpleNamespace
from typing import Any, Optional

import pytest

LAUNCH_FILE = Path(__file__).resolve().parents[2] / "launch" / "dynamics.launch.py"
ARGUMENTS = {"scene": "sample", "use_sim_time": "false", "markers": "auto"}


def _load_launch_file() -> ModuleType:
    spec = importlib.util.spec_from_file_location("dynamics_launch", LAUNCH_FILE)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class _Action:
    """A stand-in for a launch action: it keeps what it was made with."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.args, self.kwargs = args, kwargs


class _PackageNotFoundError(KeyError):
    pass


def _stand_ins(monkeypatch, rviz_prefix: Optional[Path]) -> list[str]:
    """Put the stand-in modules in place; returns the list of packages looked up."""
    looked_up: list[str] = []

    def get_package_prefix(name: str) -> str:
        looked_up.append(name)
        if name != "rviz2" or rviz_prefix is None:
            raise _PackageNotFoundError(name)
        return str(rviz_prefix)

    class LaunchConfiguration:
        def __init__(self, name: str) -> None:
            self.name = name

        def perform(self, context: dict) -> str:
            return context[self.name]

    modules = {
        "launch": SimpleNamespace(LaunchDescription=list),
        "launch.actions": SimpleNamespace(
            DeclareLaunchArgument=type("DeclareLaunchArgument", (_Action,), {}),
            LogInfo=type("LogInfo", (_Action,), {}),
            OpaqueFunction=type("OpaqueFunction", (_Action,), {})),
        "launch.substitutions": SimpleNamespace(LaunchConfiguration=LaunchConfiguration),
        "launch_ros": SimpleNamespace(),
        "launch_ros.actions": SimpleNamespace(Node=type("Node", (_Action,), {})),
        "launch_ros.parameter_descriptions": SimpleNamespace(
            ParameterValue=type("ParameterValue", (_Action,), {})),
        "ament_index_python": SimpleNamespace(),
        "ament_index_python.packages": SimpleNamespace(
            PackageNotFoundError=_PackageNotFoundError, get_package_prefix=get_package_prefix,
            get_package_share_directory=lambda name: f"/share/{name}"),
    }
    for name, module in modules.items():
        monkeypatch.setitem(sys.modules, name, module)
    return looked_up


def _actions(monkeypatch, rviz: str, rviz_prefix: Optional[Path]):
    looked_up = _stand_ins(monkeypatch, rviz_prefix)
    actions = _load_launch_file()._dynamics_node({**ARGUMENTS, "rviz": rviz})
    return [(type(a).__name__, a.kwargs) for a in actions], looked_up


def _rviz2_install(tmp_path: Path, executable: bool) -> Path:
    lib = tmp_path / "lib" / "rviz2"
    lib.mkdir(parents=True)
    if executable:
        (lib / "rviz2").write_text("#!/bin/sh\n")
        (lib / "rviz2").chmod(0o755)
    return tmp_path


def test_without_rviz_the_node_starts_alone_and_nothing_is_looked_up(monkeypatch):
    actions, looked_up = _actions(monkeypatch, "false", None)
    assert [(kind, kwargs["executable"]) for kind, kwargs in actions] == \
        [("Node", "dynamics_node")]
    assert looked_up == []


def test_rviz_true_without_rviz2_starts_the_node_and_says_why_in_one_line(monkeypatch):
    actions, looked_up = _actions(monkeypatch, "true", None)
    assert [kind for kind, _ in actions] == ["Node", "LogInfo"]
    assert actions[0][1]["executable"] == "dynamics_node"
    message = actions[1][1]["msg"]
    assert "\n" not in message and "no RViz" in message and "rviz2 package is not installed" \
        in message
    assert looked_up == ["rviz2"]
    # The node's markers follow rviz:=true all the same (auto: on with RViz asked for).
    assert actions[0][1]["parameters"][1]["publish.markers"] is True


def test_rviz_true_with_a_package_but_no_executable_says_so(monkeypatch, tmp_path):
    actions, _ = _actions(monkeypatch, "true", _rviz2_install(tmp_path, executable=False))
    assert [kind for kind, _ in actions] == ["Node", "LogInfo"]
    assert str(tmp_path / "lib" / "rviz2" / "rviz2") in actions[1][1]["msg"]


def test_rviz_true_with_rviz2_installed_starts_it(monkeypatch, tmp_path):
    actions, _ = _actions(monkeypatch, "true", _rviz2_install(tmp_path, executable=True))
    assert [(kind, kwargs.get("executable")) for kind, kwargs in actions] == \
        [("Node", "dynamics_node"), ("Node", "rviz2")]
    assert actions[1][1]["arguments"][:2] == ["-d", "/share/hecker_dynamics/"
                                              "rviz/hecker_dynamics.rviz"]


def test_with_ros_rviz_true_without_rviz2_gives_the_node_and_a_log_line(monkeypatch):
    """The same decision with the real launch and launch_ros (a ROS 2 machine)."""
    pytest.importorskip("launch_ros", reason="launch_ros is not installed: ROS 2 Jazzy "
                                             "(source /opt/ros/jazzy/setup.bash)")
    from ament_index_python import packages
    from launch.actions import LogInfo
    from launch_ros.actions import Node

    from launch import LaunchContext

    def no_rviz2(name: str) -> str:
        raise packages.PackageNotFoundError(name)

    monkeypatch.setattr(packages, "get_package_prefix", no_rviz2)
    context = LaunchContext()
    context.launch_configurations.update({**ARGUMENTS, "rviz": "true"})
    actions = _load_launch_file()._dynamics_node(context)
    assert [type(a) for a in actions] == [Node, LogInfo]
    message = "".join(s.perform(context) for s in actions[1].msg)
    assert "\n" not in message and "rviz2 package is not installed" in message
