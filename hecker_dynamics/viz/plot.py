"""Poses, twists and energy of every body against time, from a bag; and two bags overlaid
with their difference (what a failed ``replay --check`` reports in numbers, as a picture).

The energy is the model's (kinetic plus the potential of gravity and springs) at the CM
states the poses and twists imply, so it needs the scene (``--scene``): a bag holds no
masses. Twists are read in the frame the scene publishes them in (``twist_frame``) and
drawn in fixed-frame axes. Without a scene the twists are drawn as the bag has them.
"""
from __future__ import annotations

import bisect
import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..bags.io import POSE_STAMPED, TWIST, BagError, BagMessage, read_bag, stamp_ns_of
from ..dynamics import Model
from ..scene import Scene
from .draw import BODY_COLORS
from .frames import VizError, pose_from_fields

__all__ = ["Series", "read_series", "energy", "differences", "plot_bags", "QUANTITIES"]

#: The rows of a plot: a label and a unit per quantity of a body's pose and twist.
QUANTITIES = (("x", "m"), ("y", "m"), ("angle", "rad"), ("vx", "m/s"), ("vy", "m/s"),
              ("omega", "rad/s"))


@dataclass
class Series:
    """One body's pose and twist at the stamps of its poses, from one bag."""

    body: str
    time: np.ndarray  # s
    values: np.ndarray  # (n, 6): x, y, angle, vx, vy, omega


def _body_names(path: str, bag_topics: dict[str, str]) -> list[str]:
    """Bodies with both ``/<body>/pose`` and ``/<body>/twist`` in the bag, sorted; a
    warning names each other body either topic names, and why it is not drawn."""
    names = []
    for body in sorted({topic[1:].rpartition("/")[0] for topic in bag_topics
                        if topic.endswith(("/pose", "/twist"))} - {""}):
        found = [(topic, bag_topics.get(topic), msgtype) for topic, msgtype in
                 ((f"/{body}/pose", POSE_STAMPED), (f"/{body}/twist", TWIST))]
        wrong = [f"{topic} is {kind or 'not in the bag'}" + (f", not {msgtype}" if kind else "")
                 for topic, kind, msgtype in found if kind != msgtype]
        if wrong:
            warnings.warn(f"{path}: body '{body}' is not drawn: {'; '.join(wrong)}",
                          stacklevel=2)
        else:
            names.append(body)
    return names


def _twists_of(poses: list[BagMessage], stamps: list[int],
               twists: list[BagMessage]) -> dict[int, BagMessage]:
    """The twist of each pose (by its index), as the node publishes the two together: a
    pose and a twist each the only one of its topic logged within half a publish period
    (the poses' smallest step of stamps) of the other. A bag logged at sim time logs them
    at one time; a recording logs each on arrival, a little after its publication, where
    the same time would pair nothing; poses published in a burst (a timer that caught up)
    are within reach of several twists, which could be any of them: not paired. A Twist
    has no stamp, so the pairing assumes a pose and its twist arrive within half a
    period of each other: a recorder that logged every twist more than that after its
    pose would pair each twist with the next pose, a period late, and nothing could say."""
    steps = np.diff(np.unique(stamps))
    reach = int(steps.min()) // 2 if steps.size else 0
    pose_times = [message.log_ns for message in poses]  # log order, as read_bag gives them
    twist_times = [message.log_ns for message in twists]

    def near(times: list[int], log_ns: int) -> list[int]:
        return list(range(bisect.bisect_left(times, log_ns - reach),
                          bisect.bisect_right(times, log_ns + reach)))

    paired = {}
    for index, twist in enumerate(twists):
        candidates = near(pose_times, twist.log_ns)
        if len(candidates) == 1 and near(twist_times, pose_times[candidates[0]]) == [index]:
            paired[candidates[0]] = twist
    return paired


def read_series(path: str, scene: Optional[Scene] = None) -> dict[str, Series]:
    """Every body's series in the bag at ``path`` (a twist pairs with the pose logged with
    it, :func:`_twists_of`)."""
    try:
        bag = read_bag(path)
    except BagError as error:
        raise VizError(str(error)) from None
    names = _body_names(path, bag.topics)
    series = {}
    for name in names:
        rows, times = [], []
        poses = bag.on(f"/{name}/pose")
        decoded = [message.decode() for message in poses]
        stamps = [stamp_ns_of(msg) or 0 for msg in decoded]  # a PoseStamped has a header
        twists = _twists_of(poses, stamps, bag.on(f"/{name}/twist"))
        alone = len(poses) - len(twists)
        if alone:  # a lossy recording: a gap in the lines, said
            warnings.warn(f"{path}: {alone} of {len(poses)} message(s) on /{name}/pose have no "
                          f"/{name}/twist logged with them and are not drawn", stacklevel=2)
        for index, (msg, stamp) in enumerate(zip(decoded, stamps)):
            if index not in twists:
                continue
            p, o = msg.pose.position, msg.pose.orientation
            x, y, angle = pose_from_fields((p.x, p.y), (o.x, o.y, o.z, o.w))
            twist = twists[index].decode()
            vx, vy = twist.linear.x, twist.linear.y
            if scene is not None and scene.twist_frame == "body":  # to fixed-frame axes
                c, s = math.cos(angle), math.sin(angle)
                vx, vy = c * vx - s * vy, s * vx + c * vy
            times.append(stamp * 1e-9)
            rows.append((x, y, angle, vx, vy, twist.angular.z))
        if rows:
            series[name] = Series(name, np.array(times), np.array(rows))
    if not series:
        raise VizError(f"{path}: no body has both /<body>/pose and /<body>/twist messages "
                       "(an input bag? plot a bag written by 'replay' or recorded from the node)")
    return series


def energy(scene: Scene, series: dict[str, Series]) -> tuple[np.ndarray, np.ndarray]:
    """The total mechanical energy at the instants where every scene body has a state.

    The CM of body i is origin + R(angle) c_i, where c_i is the CM in the body frame, and as a
    body point its velocity is v_origin + omega perp(R c_i) (a body point's velocity, Eq. 9).
    """
    model = Model(scene)
    names = list(model.names)
    missing = [n for n in names if n not in series]
    if missing:
        raise VizError(f"--scene {scene.source}: the bag has no states of {', '.join(missing)}")
    common = sorted(set.intersection(*(set(series[n].time.tolist()) for n in names)))
    times, values = [], []
    for t in common:
        q, v = np.zeros((len(names), 3)), np.zeros((len(names), 3))
        for i, name in enumerate(names):
            row = series[name].values[np.searchsorted(series[name].time, t)]
            x, y, angle, vx, vy, omega = row
            c, s = math.cos(angle), math.sin(angle)
            rx = c * model.cm_local[i][0] - s * model.cm_local[i][1]
            ry = s * model.cm_local[i][0] + c * model.cm_local[i][1]
            q[i] = (x + rx, y + ry, angle)
            v[i] = (vx - omega * ry, vy + omega * rx, omega)
        times.append(t)
        values.append(model.energy(q, v))
    return np.array(times), np.array(values)


def differences(first: dict[str, Series], second: dict[str, Series]
                ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per body both hold: the stamps both hold and second - first there, (n, 6), with the
    angle difference wrapped into [-pi, pi)."""
    result = {}
    for name in sorted(first.keys() & second.keys()):
        a, b = first[name], second[name]
        times, ia, ib = np.intersect1d(a.time, b.time, return_indices=True)
        difference = b.values[ib] - a.values[ia]
        difference[:, 2] = (difference[:, 2] + math.pi) % (2 * math.pi) - math.pi
        result[name] = (times, difference)
    return result


def plot_bags(output: Path, first: str, second: Optional[str] = None, *,
              scene: Optional[Scene] = None, size: tuple[int, int] = (1000, 1100)) -> None:
    """One row per quantity (and energy with a scene); with ``second``, a column of
    differences (second - first) at the stamps both bags hold."""
    bags = [read_series(first, scene)] + ([read_series(second, scene)] if second else [])
    if second is not None and not bags[0].keys() & bags[1].keys():
        raise VizError(f"{first} and {second} have no body in common")
    rows = len(QUANTITIES) + (scene is not None)
    figure = Figure(figsize=(size[0] / 100, size[1] / 100), dpi=100)
    FigureCanvasAgg(figure)
    grid = figure.subplots(rows, 2 if second else 1, sharex=True, squeeze=False)
    styles = ("-", "--")
    names = sorted(set().union(*bags))
    paths = [first] if second is None else [first, second]
    for k, bag in enumerate(bags):
        for b, name in enumerate(names):
            if name not in bag:
                continue
            s = bag[name]
            for r in range(len(QUANTITIES)):
                grid[r][0].plot(s.time, s.values[:, r], styles[k],
                                color=BODY_COLORS[b % len(BODY_COLORS)], linewidth=1.0,
                                label=f"{name} ({Path(paths[k]).name})")
        if scene is not None:
            t, e = energy(scene, bag)
            grid[-1][0].plot(t, e, styles[k], color="black", linewidth=1.0)
    if second is not None:
        for name in names:
            if name not in bags[0] or name not in bags[1]:
                warnings.warn(f"body '{name}' is only in {paths[name in bags[1]]}: no "
                              "difference is drawn for it", stacklevel=2)
        for name, (times, difference) in differences(bags[0], bags[1]).items():
            b = names.index(name)  # the body's colour on the left
            for r in range(len(QUANTITIES)):
                grid[r][1].plot(times, difference[:, r],
                                color=BODY_COLORS[b % len(BODY_COLORS)], linewidth=1.0)
        if scene is not None:
            (ta, ea), (tc, ec) = energy(scene, bags[0]), energy(scene, bags[1])
            times, ia, ic = np.intersect1d(ta, tc, return_indices=True)
            grid[-1][1].plot(times, ec[ic] - ea[ia], color="black", linewidth=1.0)
        grid[0][1].set_title(f"{Path(second).name} - {Path(first).name}", fontsize=9)
    labels = [f"{q} ({unit})" for q, unit in QUANTITIES] + (["energy (J)"] if scene else [])
    for r, label in enumerate(labels):
        grid[r][0].set_ylabel(label, fontsize=8)
        for axes in grid[r]:
            axes.tick_params(labelsize=7)
            axes.grid(True, linewidth=0.3)
    for axes in grid[-1]:
        axes.set_xlabel("sim time (s)", fontsize=8)
    grid[0][0].legend(fontsize=7, loc="best")
    figure.tight_layout()
    figure.savefig(output, format=output.suffix.lstrip(".").lower() or "png",
                   metadata={"Software": None} if output.suffix.lower() == ".png" else None)
