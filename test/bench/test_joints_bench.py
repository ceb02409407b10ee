"""The joint section of the benchmark (hecker_dynamics.bench.joints) on small runs."""
from __future__ import annotations

import pytest

from hecker_dynamics.bench.joints import chain_engines, interleaved, joint_bench, pinned_engines
from hecker_dynamics.bench.peers import available
from hecker_dynamics.bench.scenes import bench_scene, pinned_by_springs
from hecker_dynamics.contact.joints import RevoluteJoint
from hecker_dynamics.scene.load import load_scene


def test_our_chain_holds_its_joints_where_the_peers_let_them_stretch():
    """20 links for 0.2 s: our pins hold to 1e-9 m; each installed peer's error is what
    its iterations leave, larger than ours (it can fail: the peers are measured, not
    assumed)."""
    peers = [name for name in ("pymunk", "box2d", "box2d_v3") if available(name)]
    result = interleaved(lambda: chain_engines(20, peers), 200, rounds=2)
    assert result["hecker_dynamics"][1] < 1e-9
    for name in peers:
        assert result[name][1] > result["hecker_dynamics"][1]


@pytest.mark.parametrize("name", ["seesaw", "door"])
def test_springs_replace_the_world_pins(name):
    scene, springs = load_scene(name), pinned_by_springs(name)
    pins = [j for j in scene.joints if isinstance(j, RevoluteJoint) and j.body_a is None]
    assert pins and not [j for j in springs.joints if isinstance(j, RevoluteJoint)]
    assert len(springs.forces) == len(scene.forces) + len(pins)
    assert bench_scene(f"{name}_springs") == springs


def test_the_door_on_its_joint_holds_the_pin_better_than_on_a_spring():
    result = interleaved(lambda: pinned_engines("door"), 1000, rounds=1)
    assert result["joints"][1] < 1e-5 < result["springs"][1]


def test_joint_bench_writes_its_table(tmp_path, monkeypatch):
    monkeypatch.setattr("hecker_dynamics.bench.joints.LINKS", 5)
    monkeypatch.setattr("hecker_dynamics.bench.joints.DURATION", 0.05)
    joint_bench([], tmp_path, "hecker-dynamics bench --joints", log=lambda _: None)
    text = (tmp_path / "joints.md").read_text()
    assert "| chain of 5 | hecker_dynamics |" in text and "| door" in text
    assert len((tmp_path / "joints.csv").read_text().splitlines()) == 1 + 1 + 2 * 2
