"""The skip of the tests that need ROS 2 Jazzy with this package built and sourced."""
from __future__ import annotations

from types import ModuleType

import pytest


def require_jazzy() -> ModuleType:
    """rclpy, or skip the calling test module with the reason (call it at module level,
    before the ROS imports)."""
    rclpy = pytest.importorskip(
        "rclpy", reason="rclpy is not installed: the node tests need ROS 2 Jazzy "
                        "(source /opt/ros/jazzy/setup.bash)")
    pytest.importorskip(
        "hecker_dynamics.msg", reason="the generated hecker_dynamics.msg module is missing: "
                                      "build with colcon and source install/setup.bash")
    return rclpy
