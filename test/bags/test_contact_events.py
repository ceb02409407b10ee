"""Contact events: a touch begins and ends at the steps whose contact pass first found and
no longer found the pair, and its summed impulses are the collision impulse of the article's
series, j = (1 + e) v_rel / (1/M_A + 1/M_B) for a central impact (no friction, no other
force), equal to each body's change of momentum (Eq. 5 integrated over the touch); events
replay bit for bit from a live recording, a late recorder included."""
from __future__ import annotations

import dataclasses

import pytest
from live_session import record, run_live
from scene_builders import make_scene

from hecker_dynamics.bags import read_bag
from hecker_dynamics.bags.compare import Tolerances
from hecker_dynamics.bags.live import check_live
from hecker_dynamics.ros.names import CONTACT_EVENTS_TOPIC
from hecker_dynamics.ros.runner import Runner
from hecker_dynamics.scene import load_scene
from hecker_dynamics.sensors.touch import TouchKind

S = 1_000_000_000


def events_of(params: dict, until_ns: int = S) -> tuple[list, Runner]:
    runner = Runner(make_scene({"step": 0.001, "publish": {"contacts": True}, **params}))
    tick = runner.advance(until_ns)
    return [output.fields for _, output in tick.readings
            if output.topic == CONTACT_EVENTS_TOPIC], runner


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_a_ball_against_a_wall_gets_m_one_plus_e_v(e):
    m, v = 2.0, 3.0
    ball = {"shape": "circle", "radius": 0.1, "mass": m, "position": [0.0, 0.5],
            "velocity": [0.0, -v]}
    events, runner = events_of({"bodies": {"ball": ball},
                                "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0],
                                                    "restitution": e}}}, S // 2)
    kinds = [(f.event, f.surface, f.body_a, f.body_b) for f in events]
    if e == 0.0:  # it stays touching: a begin only
        assert kinds == [(TouchKind.BEGIN, "floor", "", "ball")]
        assert runner.touches.touching[("floor", "", "ball")][0] == pytest.approx(m * v,
                                                                                  rel=1e-12)
        return
    assert kinds == [(TouchKind.BEGIN, "floor", "", "ball"), (TouchKind.END, "floor", "", "ball")]
    assert events[1].normal_impulse == pytest.approx(m * (1.0 + e) * v, rel=1e-12)
    assert events[1].tangent_impulse == 0.0
    assert runner.sim.v[0, 1] == pytest.approx(e * v, rel=1e-12)  # the impulse's momentum
    begin, end = (f.header.sec * S + f.header.nanosec for f in events)
    assert 0 < begin < end and runner.touches.touching == {}


def test_two_balls_exchange_the_collision_impulse():
    ma, mb, va, e = 1.0, 3.0, 2.0, 0.8
    bodies = {"a": {"shape": "circle", "radius": 0.1, "mass": ma, "velocity": [va, 0.0]},
              "b": {"shape": "circle", "radius": 0.1, "mass": mb, "position": [0.5, 0.0]}}
    events, runner = events_of({"bodies": bodies,
                                "collisions": {"pair": {"bodies": ["a", "b"], "restitution": e,
                                                        "friction": 0.0}}})
    assert [(f.event, f.surface, f.body_a, f.body_b) for f in events] == \
        [(TouchKind.BEGIN, "", "a", "b"), (TouchKind.END, "", "a", "b")]
    j = (1.0 + e) * va / (1.0 / ma + 1.0 / mb)
    assert events[1].normal_impulse == pytest.approx(j, rel=1e-12)
    assert mb * runner.sim.v[1, 0] == pytest.approx(j, rel=1e-12)
    assert ma * (va - runner.sim.v[0, 0]) == pytest.approx(j, rel=1e-12)


def test_a_body_deleted_and_spawned_again_at_one_instant_ends_its_touch_and_begins_one():
    """The new body of the old one's name is another body: the old one's touch of the
    floor ends with its own impulse and the new one's begins, as in a keyframe's replay."""
    ball = {"shape": "circle", "radius": 0.1, "mass": 1.0, "position": [0.0, 0.1]}
    floor = {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0], "restitution": 0.0}}
    events, runner = events_of({"bodies": {"ball": ball, "box": {**ball, "position": [1.0, 0.1]}},
                                "forces": {"g": {"type": "gravity"}}, "walls": floor}, S // 2)
    assert [(f.event, f.body_b) for f in events] == [(TouchKind.BEGIN, "ball"),
                                                      (TouchKind.BEGIN, "box")]
    held = runner.touches.touching[("floor", "", "ball")][0]
    keyframe = runner.keyframe()
    runner.delete_body("ball")
    runner.spawn_body("ball", "{shape: circle, radius: 0.1, mass: 5.0, position: [-1.0, 0.1]}")
    tick = runner.advance(S // 2 + 2_000_000)
    events = [o.fields for _, o in tick.readings if o.topic == CONTACT_EVENTS_TOPIC]
    assert [(f.event, f.body_b) for f in events] == [(TouchKind.END, "ball"),
                                                      (TouchKind.BEGIN, "ball")]
    assert events[0].normal_impulse == held  # the old ball's alone
    assert 0.0 < events[1].normal_impulse <= 5.0 * 9.81 * 0.001  # the new ball's first step
    restored = Runner(runner.base_scene)
    restored.restore(keyframe)
    restored.delete_body("ball")
    restored.spawn_body("ball", "{shape: circle, radius: 0.1, mass: 5.0, position: [-1.0, 0.1]}")
    assert restored.advance(S // 2 + 2_000_000).readings == tick.readings


def test_without_publish_contacts_no_events_and_no_stops():
    ball = {"shape": "circle", "radius": 0.1, "mass": 1.0, "velocity": [0.0, -1.0],
            "position": [0.0, 0.2]}
    scene = make_scene({"step": 0.001, "bodies": {"ball": ball},
                        "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0]}}})
    runner = Runner(scene)
    assert runner.touches.next_stop(runner.sim) is None
    assert runner.advance(S // 2).readings == []
    with_events = Runner(dataclasses.replace(scene, publish_contacts=True))
    with_events.advance(S // 2)
    assert (with_events.sim.q == runner.sim.q).all()  # stopping every step changes no bit


# Seed 61: the crate touches the partition from 0.77 s to 1.35 s; a recorder 1.28 s late
# records the end of that touch, whose impulse sums the steps before it subscribed.
@pytest.mark.parametrize("seed,late", [(60, 0), (61, 1_280_000_000)])
def test_contact_events_replay_bit_for_bit_from_a_live_recording(tmp_path, seed, late):
    scene = dataclasses.replace(load_scene("warehouse"), publish_contacts=True)
    session = run_live(scene, seed, inputs=4, keyframe_period_ns=S // 4)
    events = [p for p in session.published if p.topic == "/" + CONTACT_EVENTS_TOPIC]
    assert "map" in {p.msg.surface for p in events}  # the crate against the map's boxes
    path = record(session, tmp_path / "live", seed, late_ns=late)
    check = check_live(scene, read_bag(path), tolerances=Tolerances(0.0, 0.0, 0.0))
    assert check.ok, check.report.text() + "\n" + "\n".join(check.problems)
    assert any(t.topic == "/" + CONTACT_EVENTS_TOPIC and t.matched for t in check.report.topics)


def test_a_run_restored_from_a_keyframe_inside_a_touch_ends_it_with_the_whole_impulse():
    scene = dataclasses.replace(load_scene("warehouse"), publish_contacts=True)
    whole = Runner(scene)  # the crate rests on the partition from about 0.8 s to 2.2 s
    whole.advance(S)
    keyframe = whole.keyframe()
    assert whole.touches.touching  # the keyframe is taken inside the touch
    later = whole.advance(3 * S).readings
    restored = Runner(scene)
    restored.restore(keyframe)
    assert restored.advance(3 * S).readings == later
    ends = [o.fields for _, o in later if o.topic == CONTACT_EVENTS_TOPIC and o.fields.event == 1]
    assert ends and ends[0].normal_impulse > 0.0
