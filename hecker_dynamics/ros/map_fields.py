"""A scene's map as ``nav_msgs/OccupancyGrid`` fields (no ROS import), for the node to
publish once, latched, on :data:`~.names.MAP_TOPIC`, as nav2's ``map_server`` does."""
from __future__ import annotations

from typing import NamedTuple, Optional

from ..scene.load import Scene
from .fields import Header, Pose, header, quaternion_from_yaw, stamp_from_ns

__all__ = ["OccupancyGridFields", "occupancy_grid_fields"]


class OccupancyGridFields(NamedTuple):
    """``nav_msgs/OccupancyGrid``: header, the ``MapMetaData`` (load time as (sec,
    nanosec), resolution, width, height, origin) and the cells (int8 as bytes, row-major
    from the map's bottom row)."""

    header: Header
    map_load_time: tuple[int, int]
    resolution: float
    width: int
    height: int
    origin: Pose
    data: bytes


def occupancy_grid_fields(scene: Scene, stamp_ns: int) -> Optional[OccupancyGridFields]:
    """The scene's map in its fixed frame, stamped and loaded at ``stamp_ns`` (the session's
    start, so a replay gives the same bytes); None without a map."""
    if scene.map is None:
        return None
    grid = scene.map.occupancy
    x, y, yaw = grid.origin
    return OccupancyGridFields(header(scene.frame_id, stamp_ns), stamp_from_ns(stamp_ns),
                               grid.resolution, grid.width, grid.height,
                               Pose((x, y, 0.0), quaternion_from_yaw(yaw)), grid.data)
