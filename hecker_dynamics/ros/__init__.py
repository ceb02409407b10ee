"""The ROS side, without ROS: what messages mean and what the node publishes.

- ``fields``: input messages to commands, states to plain message fields (poses, twists,
  odometry, stamps);
- ``markers`` and ``diagnostics``: RViz markers of the shapes, the node's health status;
- ``outputs``: the node's output topics and the messages of one snapshot;
- ``runner``: the node's options, clock decisions and the run loop (:class:`Runner`) that
  both the rclpy node and the offline replay drive;
- ``ratelimit``: one log line per kind of warning every few seconds;
- ``node``: the rclpy node, the only module that imports rclpy (import it directly).
"""
from .fields import applied_wrench_to_command, wrench_stamped_to_command
from .outputs import OutputKind, output_topics, snapshot_outputs
from .runner import NodeOptions, Runner, node_setup

__all__ = ["applied_wrench_to_command", "wrench_stamped_to_command", "OutputKind",
           "output_topics", "snapshot_outputs", "NodeOptions", "Runner", "node_setup"]
