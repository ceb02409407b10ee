"""Plots against time from bags: the series are the bag's states, the energy is the
simulation's own, and the difference of two bags is zero for a bag and itself and is the
pose difference for two runs that differ."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib", reason="matplotlib is not installed (the viz extra)")
pytest.importorskip("PIL", reason="Pillow is not installed (the viz extra)")
from PIL import Image  # noqa: E402

from hecker_dynamics.cli import main  # noqa: E402
from hecker_dynamics.dynamics import Simulation  # noqa: E402
from hecker_dynamics.scene import load_scene  # noqa: E402
from hecker_dynamics.viz.plot import differences, energy, read_series  # noqa: E402


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    """The door's script over 2 s as an input bag, and its replay."""
    directory = tmp_path_factory.mktemp("door")
    assert main(["script", "door", "-o", str(directory / "in"), "--duration", "2"]) == 0
    assert main(["replay", "door", str(directory / "in"), "-o", str(directory / "fine"),
                 "--no-progress"]) == 0
    return directory


def test_series_are_the_simulated_states(bags):
    scene = load_scene("door")
    series = read_series(str(bags / "fine"), scene)
    sim = Simulation(scene)
    snapshots = {s.time_ns: s for s in sim.play(scene.script, 2 * 10**9)}
    for name, s in series.items():
        assert len(s.time) == len(snapshots)
        for t, row in zip(s.time[::25], s.values[::25]):
            state = next(b for b in snapshots[round(t * 1e9)].bodies if b.name == name)
            assert row[0] == state.position[0] and row[1] == state.position[1]
            # The angle through the quaternion and back: equal to a few ulps.
            assert math.isclose(row[2], state.angle, rel_tol=0, abs_tol=1e-15)
            assert tuple(row[3:5]) == pytest.approx(state.linear_velocity, abs=1e-12)
            assert row[5] == state.angular_velocity


def test_energy_from_a_bag_is_the_simulations(bags):
    scene = load_scene("door")
    times, values = energy(scene, read_series(str(bags / "fine"), scene))
    sim = Simulation(scene)
    expected = {s.time_ns: s.energy for s in sim.play(scene.script, 2 * 10**9)}
    assert len(times) == len(expected)
    scale = max(abs(e) for e in expected.values())
    for t, e in zip(times, values):
        # CM states rebuilt from origin poses: equal to rounding of a few operations.
        assert e == pytest.approx(expected[round(t * 1e9)], abs=1e-12 * scale)


def test_difference_of_a_bag_and_itself_is_zero(bags):
    series = read_series(str(bags / "fine"))
    for times, difference in differences(series, series).values():
        assert len(times) == len(series["door"].time)
        assert not difference.any()


def test_difference_shows_where_two_runs_part(bags, tmp_path):
    # The same script with RK4 instead of the scene's semi-implicit Euler: the poses part.
    other = tmp_path / "other.yaml"
    text = Path(load_scene("door").source).read_text()
    other.write_text(text.replace("integrator:", "integrator: rk4  #", 1))
    assert "integrator: rk4" in other.read_text()
    assert main(["replay", str(other), str(bags / "in"), "-o", str(tmp_path / "rk4"),
                 "--no-progress"]) == 0
    fine, rk4 = read_series(str(bags / "fine")), read_series(str(tmp_path / "rk4"))
    times, difference = differences(fine, rk4)["door"]
    k = len(times) - 1
    assert difference[k, 2] == pytest.approx(
        math.remainder(rk4["door"].values[k, 2] - fine["door"].values[k, 2], 2 * math.pi),
        abs=1e-15)
    assert np.abs(difference[:, 2]).max() > 1e-6


def test_plot_writes_a_picture_of_one_and_two_bags(bags, tmp_path, capsys):
    assert main(["plot", str(bags / "fine"), "-o", str(tmp_path / "one.png"),
                 "--scene", "door"]) == 0
    assert main(["plot", str(bags / "fine"), str(bags / "fine"),
                 "-o", str(tmp_path / "two.png")]) == 0
    for name in ("one.png", "two.png"):
        with Image.open(tmp_path / name) as png:
            assert png.size == (1000, 1100)
    assert main(["plot", str(bags / "in"), "-o", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no body has both" in err
    assert main(["plot", str(bags / "fine"), "-o", str(tmp_path / "x.gif")]) == 2
    assert "unknown plot type" in capsys.readouterr().err


def test_a_body_left_out_of_a_plot_is_named_with_why(bags, tmp_path, capsys):
    """A tampered recording: the door's /door/pose of another type, every other /block/twist
    lost. Without --scene the plot drew the block alone and said nothing of the door, nor of
    the block's poses without a twist; each is now a warning line, and the plot is drawn."""
    from hecker_dynamics.bags.io import TWIST, BagWriter, read_bag

    source = read_bag(bags / "fine")
    assert set(source.topics) >= {"/door/pose", "/door/twist", "/block/pose", "/block/twist"}
    tampered = tmp_path / "tampered"
    with BagWriter(tampered, "mcap") as writer:
        writer.add_topic("/door/pose", "geometry_msgs/msg/Pose")
        writer.add_topic("/lid/twist", TWIST)  # a body with a twist but no pose
        block_twists = 0
        for message in source.messages:
            block_twists += message.topic == "/block/twist"
            if message.topic != "/door/pose" and not (
                    message.topic == "/block/twist" and block_twists % 2):
                writer.add_topic(message.topic, message.msgtype)
                writer.write_raw(message.topic, message.log_ns, message.raw)
    poses = len(source.on("/block/pose"))
    capsys.readouterr()
    assert main(["plot", str(tampered), "-o", str(tmp_path / "x.png")]) == 0
    assert capsys.readouterr().err.splitlines() == [
        f"hecker-dynamics: warning: {tampered}: body 'door' is not drawn: /door/pose is "
        "geometry_msgs/msg/Pose, not geometry_msgs/msg/PoseStamped",
        f"hecker-dynamics: warning: {tampered}: body 'lid' is not drawn: /lid/pose is not in "
        "the bag",
        f"hecker-dynamics: warning: {tampered}: {(poses + 1) // 2} of {poses} message(s) on "
        "/block/pose have no /block/twist logged with them and are not drawn"]
    assert set(read_series(str(bags / "fine"))) == {"door", "block"}


def test_a_body_in_one_bag_only_keeps_its_colour_and_is_named(bags, tmp_path, capsys,
                                                              monkeypatch):
    """Two bags, the second without the block: the door's difference was drawn in the
    block's colour (the colours went by place among the bodies both bags hold, the lines
    on the left by place among all), and the block's missing difference went unsaid."""
    from matplotlib.figure import Figure

    from hecker_dynamics.bags.io import BagWriter, read_bag
    from hecker_dynamics.viz.draw import BODY_COLORS

    source = read_bag(bags / "fine")
    blockless = tmp_path / "no_block"
    with BagWriter(blockless, "mcap") as writer:
        for message in source.messages:
            if not message.topic.startswith("/block/"):
                writer.add_topic(message.topic, message.msgtype)
                writer.write_raw(message.topic, message.log_ns, message.raw)
    figures = []
    monkeypatch.setattr(Figure, "savefig", lambda self, *a, **k: figures.append(self))
    capsys.readouterr()
    assert main(["plot", str(bags / "fine"), str(blockless), "-o",
                 str(tmp_path / "x.png")]) == 0
    assert capsys.readouterr().err.splitlines()[0] == (
        f"hecker-dynamics: warning: body 'block' is only in {bags / 'fine'}: no difference "
        "is drawn for it")
    left, right = figures[0].axes[0], figures[0].axes[1]
    door = BODY_COLORS[sorted(["block", "door"]).index("door")]
    assert [line.get_color() for line in left.lines if "door" in line.get_label()] == [door] * 2
    assert [line.get_color() for line in right.lines] == [door]
