"""The ROS side: message fields, markers and diagnostics (``mapping``), the run loop both
the node and the offline replay drive (``mapping.Runner``), log rate limiting, and the
rclpy node itself (``node``, the only module that imports rclpy; import it directly)."""
from .mapping import NodeOptions, Runner, applied_wrench_to_command, wrench_stamped_to_command

__all__ = ["NodeOptions", "Runner", "applied_wrench_to_command", "wrench_stamped_to_command"]
