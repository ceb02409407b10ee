"""The ROS side, without ROS: what messages mean and what the node publishes.

- ``names``: the node's name, topics, services and their QoS, as plain data;
- ``fields``: input messages to commands, states to plain message fields (poses, twists,
  odometry, stamps);
- ``tf``, ``markers`` and ``diagnostics``: the bodies' transforms, RViz markers of the
  shapes, the node's health status;
- ``outputs``: the node's output topics and the messages of one snapshot;
- ``runner``: the node's options, clock decisions and the run loop (:class:`Runner`) that
  both the rclpy node and the offline replay drive;
- ``lifecycle``: when and why the node stops, and its exit status;
- ``ratelimit``: one log line per kind of warning every few seconds;
- ``node``: the rclpy node, the only module that imports rclpy (import it directly).

The names below are imported on first use (PEP 562), so that :mod:`.names` can be
imported by the scene reader without importing the modules that read scenes.
"""
from importlib import import_module
from typing import Any

_EXPORTS = {
    "applied_wrench_to_command": "fields", "wrench_stamped_to_command": "fields",
    "OutputKind": "outputs", "output_topics": "outputs", "snapshot_outputs": "outputs",
    "NodeOptions": "runner", "Runner": "runner", "node_setup": "runner",
}

__all__ = list(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(import_module(f".{_EXPORTS[name]}", __name__), name)
