"""The bodies' transforms (``tf2_msgs/TFMessage`` fields), without ROS.

``/tf`` carries, at every publish instant, one ``geometry_msgs/TransformStamped`` per body:
the fixed frame (``Scene.frame_id``) to the body frame (named after the body), the same
pose as ``<body>/pose`` (REP 103: yaw about z). ``/tf_static`` carries the bodies' named
points once: the body frame to ``<body>/<point>``, a translation in the body frame, which
is how a scene and an input's ``header.frame_id`` already name them
(:meth:`Scene.has_frame`).
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple, Optional

from ..scene.load import Scene
from .fields import Header, Pose, Quaternion, Vec3, body_pose, header

__all__ = ["TransformFields", "body_transforms", "point_transforms", "IDENTITY"]

#: The rotation of a named point's frame: the body frame's axes.
IDENTITY: Quaternion = (0.0, 0.0, 0.0, 1.0)


class TransformFields(NamedTuple):
    """``geometry_msgs/TransformStamped``: parent frame in the header, child frame, and the
    child frame's origin and orientation in the parent frame."""

    header: Header
    child_frame_id: str
    translation: Vec3
    rotation: Quaternion


def body_transforms(head: Header, states: Sequence[Any],
                    poses: Optional[Sequence[Pose]] = None) -> tuple[TransformFields, ...]:
    """``/tf``: the fixed frame and stamp of ``head`` to each body frame, from ``BodyState``
    values (and their body poses, :func:`~.fields.body_pose`, where the caller has them).
    All transforms share ``head`` (a named tuple, never changed), as the node's poses of the
    same instant do."""
    if poses is None:
        poses = [body_pose(state) for state in states]
    return tuple(TransformFields(head, state.name, pose.position, pose.orientation)
                 for state, pose in zip(states, poses))


def point_transforms(scene: Scene, stamp_ns: int) -> tuple[TransformFields, ...]:
    """``/tf_static``: each body frame to ``<body>/<point>`` for the body's named points,
    in the order the scene declares bodies and points (empty without named points)."""
    transforms = []
    for body in scene.bodies:
        head = header(body.name, stamp_ns)
        for point, (x, y) in body.points.items():
            transforms.append(TransformFields(head, f"{body.name}/{point}",
                                              (float(x), float(y), 0.0), IDENTITY))
    return tuple(transforms)
