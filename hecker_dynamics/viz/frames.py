"""What a picture shows at one instant, read from a run of a scene or from a recorded bag.

No matplotlib here: this module turns a run or a bag into the same records, so that a
bag and the run that produced it draw the same picture. Both go through the published pose
(``geometry_msgs/PoseStamped`` fields: the body frame's origin and a yaw quaternion),
read back the same way; the forces are the wrench commands active at each instant, found
with the simulation's own input buffer rules (:class:`~hecker_dynamics.dynamics.inputs.InputBuffer`)
from the commands the run pushed (its script and its drives' wheel forces) and from the
input messages for a bag (which hold the drives' velocity commands, not their forces: a
bag draws no wheel forces). Each laser's rays are cast at every frame's poses, noise off
(:class:`~hecker_dynamics.sensors.laser.Laser`), each from the laser to its hit.
"""
from __future__ import annotations

import bisect
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import NamedTuple, Optional

import numpy as np

from ..bags.io import POSE_STAMPED, BagContents, BagError, read_bag, stamp_ns_of
from ..bags.replay import input_topics, output_types, session_times
from ..drives.control import play_with_drives
from ..dynamics import Model, Simulation
from ..dynamics.inputs import InputBuffer
from ..dynamics.simulation import DrivenWheels, Snapshot
from ..ros.cmd_vel import CmdVelTopic
from ..ros.fields import applied_wrench_to_command, body_pose, wrench_stamped_to_command
from ..ros.joint_states import MotorTopic
from ..scene import InputError, Scene, WrenchCommand
from ..scene.parameters import seconds_text
from ..scene.sensors import LaserSpec
from ..sensors.laser import Laser

__all__ = ["VizError", "BodyPose", "Arrow", "Ray", "Frame", "Timeline", "pose_from_fields",
           "run_timeline", "bag_timeline", "frame_times", "world_point"]

NS_PER_S = 1_000_000_000


class VizError(ValueError):
    """A picture that cannot be made; the message names the option or file and why."""


class BodyPose(NamedTuple):
    """The body frame's origin and angle in the fixed frame (as ``<body>/pose`` has it)."""

    x: float
    y: float
    angle: float


class Arrow(NamedTuple):
    """A force at its point of application, both in the fixed frame."""

    point: tuple[float, float]
    force: tuple[float, float]


#: A laser ray from the laser's origin to its hit, in the fixed frame.
Ray = tuple[tuple[float, float], tuple[float, float]]


class Frame(NamedTuple):
    """One picture's worth of state: sim time, every body's pose, the acting forces, the
    lasers' rays that hit."""

    time_ns: int
    poses: tuple[BodyPose, ...]  # in the scene's body order
    arrows: tuple[Arrow, ...]
    rays: tuple[Ray, ...] = ()


def pose_from_fields(position: Sequence[float], orientation: Sequence[float]) -> BodyPose:
    """A pose from a position and a yaw quaternion (x, y, z, w): the angle 2 atan2(z, w)."""
    return BodyPose(float(position[0]), float(position[1]),
                    2.0 * math.atan2(float(orientation[2]), float(orientation[3])))


def world_point(pose: BodyPose, local: Sequence[float]) -> tuple[float, float]:
    """A body-frame point in the fixed frame: origin + R(angle) local."""
    c, s = math.cos(pose.angle), math.sin(pose.angle)
    return (pose.x + c * local[0] - s * local[1], pose.y + s * local[0] + c * local[1])


@dataclass
class Timeline:
    """Poses at their stamps and the commands that acted, for one scene.

    ``start_ns`` and ``end_ns`` bound the session; ``stamps`` are increasing; ``poses[k]``
    holds every body's pose at ``stamps[k]``; ``commands`` are in the order they were
    pushed (stamps absolute).
    """

    scene: Scene
    start_ns: int
    end_ns: int
    stamps: list[int]
    poses: list[tuple[BodyPose, ...]]
    commands: list[WrenchCommand]

    def pose_at(self, time_ns: int) -> tuple[BodyPose, ...]:
        """The latest poses at or before ``time_ns`` (the first ones before the first stamp)."""
        k = bisect.bisect_right(self.stamps, time_ns) - 1
        return self.poses[max(k, 0)]

    def frames(self, times: Sequence[int]) -> Iterator[Frame]:
        """The frames at increasing ``times``: held poses and the commands acting then."""
        buffer = InputBuffer(self.scene.input_timeout_ns, max_pending=len(self.commands) + 1,
                             max_active=len(self.commands) + 1)
        pending = sorted(range(len(self.commands)), key=lambda i: self.commands[i].stamp_ns)
        next_command = 0
        index = {body.name: i for i, body in enumerate(self.scene.bodies)}
        model = Model(self.scene)
        lasers = [Laser(spec, self.scene, model.cm_local) for spec in self.scene.sensors
                  if isinstance(spec, LaserSpec)]
        for time_ns in times:
            while next_command < len(pending) and \
                    self.commands[pending[next_command]].stamp_ns <= time_ns:
                # The frames draw the command only, never its force row.
                buffer.add(self.commands[pending[next_command]], ())  # type: ignore[arg-type]
                next_command += 1
            buffer.update(time_ns)
            poses = self.pose_at(time_ns)
            arrows = tuple(self._arrow(held.command, poses, index) for held in buffer.active()
                           if held.command.force != (0.0, 0.0))
            rays = tuple(ray for laser in lasers for ray in _rays(laser, poses, model))
            yield Frame(time_ns, poses, arrows, rays)

    def _arrow(self, command: WrenchCommand, poses: tuple[BodyPose, ...],
               index: dict[str, int]) -> Arrow:
        """A command's force and point in the fixed frame, from the pose of its frame."""
        if command.frame_id == self.scene.frame_id:
            return Arrow(command.point, command.force)
        name, _, point_name = command.frame_id.partition("/")
        body = index[name]
        origin = self.scene.bodies[body].points[point_name] if point_name else (0.0, 0.0)
        pose = poses[body]
        point = world_point(pose, (origin[0] + command.point[0], origin[1] + command.point[1]))
        c, s = math.cos(pose.angle), math.sin(pose.angle)
        fx, fy = command.force
        return Arrow(point, (c * fx - s * fy, s * fx + c * fy))

    def contact_points(self, poses: tuple[BodyPose, ...],
                       model: Optional[Model] = None) -> list[tuple[float, float]]:
        """Where the bodies at ``poses`` touch the walls and each other (the contact
        pass's own detection, at the CMs the poses imply)."""
        model = model or Model(self.scene)
        if model.contacts is None:
            return []
        q = np.array([[*world_point(pose, model.cm_local[i]), pose.angle]
                      for i, pose in enumerate(poses)])
        return [(contact[2][0], contact[2][1]) for contact in model.contacts.detect(q)]


def _rays(laser: Laser, poses: tuple[BodyPose, ...], model: Model) -> list[Ray]:
    """The rays of ``laser`` that hit, cast at the CM state the poses imply."""
    q = np.array([[*world_point(pose, model.cm_local[i]), pose.angle]
                  for i, pose in enumerate(poses)])
    ranges = laser.distances(q)
    (ox, oy), heading = laser.origin_and_heading(q)
    hit = np.isfinite(ranges)
    angles = heading + laser.angles[hit]
    ends = np.column_stack([ox + ranges[hit] * np.cos(angles),
                            oy + ranges[hit] * np.sin(angles)]).tolist()
    return [((ox, oy), (x, y)) for x, y in ends]


class _Pushes(Simulation):
    """A simulation that keeps every command pushed into it (a run's script and its
    drives' wheel forces), to draw them."""

    def __init__(self, scene: Scene) -> None:
        super().__init__(scene)
        self.pushed: list[WrenchCommand] = []

    def push(self, command: WrenchCommand) -> None:
        super().push(command)
        self.pushed.append(command)

    def push_replacements(self, commands: Sequence[WrenchCommand]) -> None:
        for command in commands:  # each through push, to keep it
            self.push(command)

    def run_drives(self, t_ns: int, max_steps: Optional[int], keep: bool,
                   wheels: DrivenWheels) -> Optional[list[Snapshot]]:
        return None  # no control instant inside the kernel's runs: each pushes its wheels


def frame_times(start_ns: int, duration_ns: int, fps: float) -> list[int]:
    """``round(duration x fps)`` instants from ``start_ns``, ``1/fps`` apart (whole ns)."""
    count = round(duration_ns * fps / NS_PER_S)
    return [start_ns + round(k * NS_PER_S / fps) for k in range(count)]


def run_timeline(scene: Scene, end_ns: int) -> Timeline:
    """Run ``scene`` from 0 with its script to ``end_ns``; the poses at the publish
    instants, as the node publishes them (the replay of the scene's script bag has the same).
    """
    sim = _Pushes(scene)
    snapshots = (play_with_drives(sim, scene.script, end_ns) if scene.drives
                 else sim.play(scene.script, end_ns))
    commands = sim.pushed
    stamps = [snapshot.time_ns for snapshot in snapshots]
    poses = [tuple(pose_from_fields(*body_pose(state)) for state in snapshot.bodies)
             for snapshot in snapshots]
    if not stamps:
        raise VizError(f"--duration: the run of {scene.source} publishes no pose before "
                       f"{seconds_text(end_ns)} s (publish period "
                       f"{seconds_text(scene.publish_period_ns)} s)")
    return Timeline(scene, sim.start_ns, end_ns, stamps, poses, commands)


def _bag_commands(scene: Scene, bag: BagContents) -> list[WrenchCommand]:
    """The bag's input messages that fit the scene, mapped as the node maps them."""
    topics = input_topics(scene)
    bodies = {body.name for body in scene.bodies}
    commands = []
    for message in bag.messages:
        if message.topic not in topics:
            continue
        _, wrench_topic = topics[message.topic]
        if isinstance(wrench_topic, (MotorTopic, CmdVelTopic)):
            continue  # a motor's speed or a drive's command: no force of its own to draw
        try:
            if wrench_topic is None:
                command, _ = applied_wrench_to_command(message.decode(), message.log_ns)
            else:
                command, _ = wrench_stamped_to_command(message.decode(), wrench_topic,
                                                       message.log_ns)
            command.check_finite()
        except InputError:
            continue  # the node rejects it too: it never acted
        if command.body in bodies and scene.has_frame(command.frame_id):
            commands.append(command)
    return commands


def bag_timeline(scene: Scene, path: str) -> Timeline:
    """The poses (``/<body>/pose``) and inputs of a recorded or replayed bag of ``scene``."""
    try:
        bag = read_bag(path)
    except BagError as error:
        raise VizError(f"--bag: {error}") from None
    names = [body.name for body in scene.bodies]
    pose_topics = [topic for topic, kind in output_types(scene).items()
                   if kind == POSE_STAMPED]
    missing = [t for t in pose_topics if t not in bag.topics]
    if missing:
        raise VizError(f"--bag {path}: no poses of {scene.source}'s bodies on "
                       f"{', '.join(missing)} (is it a bag of this scene?)")
    by_stamp: dict[int, dict[str, BodyPose]] = {}
    for name, topic in zip(names, pose_topics):
        bag.check_type(topic, POSE_STAMPED)
        for message in bag.on(topic):
            msg = message.decode()
            stamp = stamp_ns_of(msg)
            p, o = msg.pose.position, msg.pose.orientation
            pose = pose_from_fields((p.x, p.y), (o.x, o.y, o.z, o.w))
            if not all(map(math.isfinite, pose)):
                bad = ", ".join(f"{k} {v}" for k, v in zip(("x", "y", "angle"), pose)
                                if not math.isfinite(v))
                raise VizError(f"--bag {path}: {topic} at {seconds_text(message.log_ns)} s: the "
                               f"pose is not finite ({bad})")
            by_stamp.setdefault(message.log_ns if stamp is None else stamp, {})[name] = pose
    stamps = sorted(s for s, found in by_stamp.items() if len(found) == len(names))
    if not stamps:
        raise VizError(f"--bag {path}: the bag holds no instant with a pose of every body "
                       f"({', '.join(names)})")
    poses = [tuple(by_stamp[s][name] for name in names) for s in stamps]
    start_ns, end_ns = session_times(scene, bag)  # as 'replay' finds them
    return Timeline(scene, start_ns, end_ns, stamps, poses, _bag_commands(scene, bag))
