"""The joint section of the benchmark (hecker_dynamics.bench.joints) on small runs."""
from __future__ import annotations

import numpy as np
import pytest

from hecker_dynamics.bench.joints import Case, Run, chain, joint_bench, measure, renaming, targets
from hecker_dynamics.bench.scenes import bench_scene, pinned_by_springs
from hecker_dynamics.dynamics.model import Model
from hecker_dynamics.scene.joints import RevoluteJoint
from hecker_dynamics.scene.load import load_scene


def _installed(peer: str) -> bool:
    try:
        __import__({"pymunk": "pymunk", "box2d": "Box2D"}[peer])
    except ImportError:
        return False
    return True


def test_our_chain_holds_its_joints_where_the_peers_let_them_stretch():
    """20 links for 0.5 s at h = 1/240 s: our pins hold to 1e-9 m; each installed peer's
    gap is what its iterations leave, larger than ours (it can fail: the peers are
    measured, not assumed)."""
    scene = chain(20, 1.0 / 240.0, 0.5)
    model = Model(scene)
    ours = measure("hecker_dynamics", scene, model)
    assert ours.gap < 1e-9 and ours.cost is not None and ours.failure is None
    for peer in (p for p in ("pymunk", "box2d") if _installed(p)):
        assert measure(peer, scene, model).gap > ours.gap


@pytest.mark.parametrize("name", ["seesaw", "door"])
def test_springs_replace_the_world_pins(name):
    scene, springs = load_scene(name), pinned_by_springs(name)
    pins = [j for j in scene.joints if isinstance(j, RevoluteJoint) and j.body_a is None]
    assert pins and not [j for j in springs.joints if isinstance(j, RevoluteJoint)]
    assert len(springs.forces) == len(scene.forces) + len(pins)
    assert bench_scene(f"{name}_springs") == springs


def test_the_door_on_its_joint_holds_the_pin_better_than_on_a_spring():
    door = load_scene("door")
    joints = measure("hecker_dynamics", door, Model(door), 1.0)
    springs = pinned_by_springs("door")
    on_springs = measure("hecker_dynamics", springs, Model(springs), 1.0, pins=door)
    assert joints.gap < 1e-5 < on_springs.gap


def test_renaming_a_chain_keeps_its_bits():
    results = renaming(60, 0.1, 1)
    assert set(results) == {"padded", "unpadded", "shuffled"}
    first = results["padded"][1]
    assert all(np.array_equal(state, first) for _, state in results.values())


def _case(name: str, runs: dict[str, list[Run]]) -> Case:
    case = Case(name, lambda: chain(2, 1.0 / 240.0, 0.1))
    case.runs = runs
    return case


def test_the_targets_say_met_missed_or_not_measured():
    """Target 1 misses on a failed or stretched chain, target 2 is not measured without
    Box2D v3 and judged where it ran, target 3 misses on a spread of costs or bits."""
    same = np.zeros((2, 6))
    renamed = {"padded": (1.0, same), "unpadded": (1.05, same), "shuffled": (0.97, same)}
    good = [_case("chain of 2, h = 1/240 s", {"hecker_dynamics": [Run(1e-6, 1e-12)]}),
            _case("chain of 2, h = 1/60 s", {"hecker_dynamics": [Run(1e-6, 1e-12)]})]
    verdicts = [verdict for _, _, verdict in targets(good, renamed)]
    assert verdicts == ["met", "not measured", "met"]
    good[0].runs["box2d_v3"] = [Run(2e-6, 1e-3)]
    assert targets(good, renamed)[1][2] == "met"
    good[0].runs["box2d_v3"] = [Run(0.5e-6, 1e-3)]
    assert targets(good, renamed)[1][2] == "missed"
    bad = [_case("chain of 2, h = 1/60 s", {"hecker_dynamics": [Run(None, 0.0, "diverged")]})]
    assert targets(bad, renamed)[0][2] == "missed"
    stretched = [_case("chain of 2, h = 1/60 s", {"hecker_dynamics": [Run(1e-6, 2e-9)]})]
    assert targets(stretched, renamed)[0][2] == "missed"
    spread = {**renamed, "unpadded": (1.2, same)}
    assert targets(good, spread)[2][2] == "missed"
    other_bits = {**renamed, "shuffled": (1.0, same + 1e-16)}
    assert targets(good, other_bits)[2][2] == "missed"


def test_joint_bench_writes_its_table_and_targets(tmp_path):
    cases = [Case("chain of 2, h = 1/240 s", lambda: chain(2, 1.0 / 240.0, 0.05)),
             Case("door on joints", lambda: load_scene("door"), 0.05, ("hecker_dynamics",))]
    renamed = {"padded": (1.0, np.zeros(1)), "unpadded": (1.0, np.zeros(1)),
               "shuffled": (1.0, np.zeros(1))}
    verdicts = joint_bench([], tmp_path, "hecker-dynamics bench --joints", log=lambda _: None,
                           cases=cases, rounds=1, renamed=renamed)
    text = (tmp_path / "joints.md").read_text()
    assert "| chain of 2, h = 1/240 s | hecker_dynamics |" in text
    assert "| chain of 2, h = 1/240 s | box2d_v3 | not measured |" in text
    assert "| door on joints | hecker_dynamics |" in text
    assert [v for _, _, v in verdicts] == ["met", "not measured", "met"]
    assert text.count("| met |") == 2 and "| not measured |" in text
    assert len((tmp_path / "joints.csv").read_text().splitlines()) == 1 + 4 + 1
