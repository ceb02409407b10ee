"""The sensor section of the benchmark (hecker_dynamics.bench.sensors), never its speed:
the room it scans holds its 100 bodies apart inside its walls, the casters it times cast
the same rays (kernel and numpy to the bit, Box2D v3 to its float32), the robot node's run
serializes every sensor reading, and the report states the target as measured."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hecker_dynamics.bench import box2d_v3, sensors
from hecker_dynamics.bench.node import node_run, tick_targets
from hecker_dynamics.cli import main
from hecker_dynamics.dynamics import kernel
from hecker_dynamics.dynamics.model import Model
from hecker_dynamics.geometry.shapes import Circle
from hecker_dynamics.ros.cdr import serialize_output
from hecker_dynamics.ros.outputs import OutputKind
from hecker_dynamics.ros.runner import Runner, tick_target
from hecker_dynamics.sensors.laser import Laser


def _reach(body) -> float:
    """The bounding radius of a body of one shape about its body-frame origin."""
    shape = body.shapes[0]
    if isinstance(shape, Circle):
        return math.hypot(*shape.center) + shape.radius
    return float(np.max(np.hypot(*np.asarray(shape.vertices).T)))


def test_the_room_holds_its_bodies_apart_inside_its_walls():
    scene = sensors.scan_scene()
    side = sensors.MAP_CELLS * sensors.CELL
    assert len(scene.bodies) == sensors.SCAN_BODIES + 1 and len(scene.walls) == 4
    centers = np.array([b.position for b in scene.bodies])
    reach = np.array([_reach(b) for b in scene.bodies])
    assert np.all(centers - reach[:, None] > 0.0) and np.all(centers + reach[:, None] < side)
    gaps = np.hypot(*(centers[:, None] - centers[None]).transpose(2, 0, 1)) \
        - reach[:, None] - reach[None]
    assert np.min(gaps + np.diag(np.full(len(gaps), np.inf))) > 0.0
    spec = scene.sensors[0]
    assert spec.count == sensors.RAYS and spec.range_max > math.hypot(side, side)
    assert sensors.scan_scene(robot=False).bodies == scene.bodies[:-1]  # robot: last by name


def test_the_casters_cast_the_same_rays():
    """One round of two scans; the kernel's and numpy's ranges are the same bits, and
    Box2D v3 (where installed) hits every ray the kernel hits, to its float32."""
    costs = sensors.scan_costs(rounds=1, scans=2)
    assert costs.numpy > 0.0 and costs.rounds == 1
    assert (costs.kernel is not None) == kernel.built()
    if box2d_v3.available():
        assert costs.box2d_v3 is not None and costs.box2d_v3 > 0.0
        assert costs.peer_misses == 0 and costs.peer_difference is not None
        assert 0.0 < costs.peer_difference <= sensors.PEER_AGREEMENT
    if kernel.built():
        scene = sensors.scan_scene()
        model = Model(scene)
        q, _ = model.initial_state()
        python, compiled = (Laser(scene.sensors[0], scene, model.cm_local, compiled=c)
                            for c in (False, True))
        ranges = compiled.distances(q)
        assert np.all(np.isfinite(ranges)) and ranges.tobytes() == python.distances(q).tobytes()


def test_the_robot_node_serializes_every_reading(monkeypatch):
    """1 s of the robot at 1 kHz: its 10 Hz scans and 50 Hz IMU readings, each serialized
    once (the snapshots go through SnapshotSerializer); the sensors read an instant on
    leaving it, so the run's last instant, 1 s, has not read yet."""
    scene = sensors.robot_at_1khz()
    assert scene.step_ns == 1_000_000 and {s.name for s in scene.sensors} == {"laser", "imu"}
    assert {s.name for s in sensors.robot_at_1khz(laser=False).sensors} == {"imu"}
    kinds = []
    monkeypatch.setattr("hecker_dynamics.bench.node.serialize_output",
                        lambda output: kinds.append(output.kind))
    advance, outputs = node_run(scene, 1.0)
    assert advance > 0.0 and outputs > 0.0
    assert kinds.count(OutputKind.LASER_SCAN) == 9 and kinds.count(OutputKind.IMU) == 49


def test_the_node_run_sleeps_after_each_tick_as_asked(monkeypatch):
    """With a pause, the run sleeps that long after each of its 50 Hz ticks (the node's
    sleep between ticks) and serializes the same readings; the shares run it with the
    pause as a case of its own, beside the run without."""
    scene = sensors.robot_at_1khz()
    sleeps, kinds = [], []
    monkeypatch.setattr("hecker_dynamics.bench.node.time.sleep", sleeps.append)
    monkeypatch.setattr("hecker_dynamics.bench.node.serialize_output",
                        lambda output: kinds.append(output.kind))
    node_run(scene, 0.5)
    assert sleeps == [] and len(kinds) == 4 + 24
    node_run(scene, 0.5, pause=sensors.TICK_PAUSE)
    assert sleeps == [sensors.TICK_PAUSE] * 25 and len(kinds) == 2 * (4 + 24)
    runs = []
    monkeypatch.setattr(sensors, "node_run", lambda scene, seconds, pause, spread:
                        runs.append((pause, spread)) or (0.02, 0.001))
    shares = sensors.node_shares(rounds=2, seconds=0.1)
    assert [share.case for share in shares] == [
        "robot, 10 Hz scan", "robot, no laser", "robot, 10 Hz scan, 20 ms asleep after each tick"]
    spread = sensors.TICK_SPREAD_NS
    assert runs == [(0.0, spread), (0.0, spread), (sensors.TICK_PAUSE, spread)] * 2


def test_the_node_ticks_come_off_the_step_grid_and_step_to_instants_as_live_ones_do(
        monkeypatch):
    """With a spread, the ticks' times move off their 50 Hz instants by up to the spread
    either way, about half of them before it, as a live node's wall-clock ticks do; each
    steps to the last publish instant at or before it, as the node's do, so the runner
    sees those instants; the run still ends at its length and reads the same sensors at
    the same instants."""
    scene = sensors.robot_at_1khz()
    period, spread = scene.publish_period_ns, sensors.TICK_SPREAD_NS
    targets = tick_targets(scene, 2.0, spread)
    shifts = [t - k * period for k, t in enumerate(targets, 1)]
    assert len(targets) == 100 and shifts[-1] == 0
    assert all(-spread <= s <= spread for s in shifts) and len(set(shifts)) > 90
    assert 35 <= sum(s < 0 for s in shifts) <= 65 and tick_targets(scene, 2.0) == [
        k * period for k in range(1, 101)]
    seen, kinds = {0: [], spread: []}, {0: [], spread: []}
    advance = Runner.advance
    for key in seen:
        monkeypatch.setattr(Runner, "advance", lambda runner, target, keep=True, key=key:
                            seen[key].append(target) or advance(runner, target, keep))
        monkeypatch.setattr("hecker_dynamics.bench.node.serialize_output",
                            lambda output, key=key: kinds[key].append(serialize_output(output)))
        node_run(scene, 0.5, spread_ns=key)
    assert seen[spread] == [tick_target(t, 0, period) for t in tick_targets(scene, 0.5, spread)]
    assert seen[spread] != seen[0] == tick_targets(scene, 0.5)
    assert kinds[spread] == kinds[0] and len(kinds[0]) == 4 + 24


@pytest.mark.parametrize("kernel_cost, verdict", [(1e-4, "met (0.100 x)"),
                                                  (2e-3, "missed (2.000 x)")])
def test_the_report_states_the_target_as_measured(kernel_cost, verdict):
    scan = sensors.ScanCosts(100, kernel_cost, 1e-2, 1e-3, 2e-6, 0, 7)
    shares = [sensors.NodeShare("robot, 10 Hz scan", 0.03, 0.004, 7)]
    report = sensors.sensor_report(scan, shares)
    assert f"360 ray casts: {verdict}" in report
    assert "| Box2D v3, 360 b2World_CastRayClosest | 1000 us |" in report
    assert "| robot, 10 Hz scan | 3.00 % | 0.40 % | 3.40 % |" in report
    missing = sensors.sensor_report(scan._replace(peer_misses=1), shares)
    assert "missed" in missing


def test_bench_sensors_prints_the_section(monkeypatch, capsys):
    calls = {}

    def scan_costs(peer, bar):
        calls["peer"] = peer
        return sensors.ScanCosts(100, 1e-4, 1e-2, None, None, 0, 7)

    monkeypatch.setattr(sensors, "scan_costs", scan_costs)
    monkeypatch.setattr(sensors, "node_shares",
                        lambda bar: [sensors.NodeShare("robot, 10 Hz scan", 0.03, 0.004, 7)])
    assert main(["bench", "--sensors", "--no-peers"]) == 0
    out = capsys.readouterr().out
    assert calls == {"peer": False}
    assert "| Box2D v3, 360 b2World_CastRayClosest | not measured | |" in out
    assert "| robot, 10 Hz scan |" in out
