"""Scene files as ROS 2 reads them, and hostile ones refused in one line.

The YAML rules are those of rcl_yaml_param_parser (libyaml events, then its own typing of
each scalar: booleans from a fixed word list, integers by strtoll base 0, doubles by
strtod, anything else a string; quoted scalars are strings; aliases refused). Every bad
file gives a :class:`SceneError` whose message is one line naming the file, and the
command line exits 2 with one line of stderr, never a traceback.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

import hecker_dynamics as hd
from hecker_dynamics.cli import main
from hecker_dynamics.scene.load import SceneError, load_scene
from hecker_dynamics.scene.rosyaml import DuplicateParameterWarning

HEAD = "dynamics_node:\n  ros__parameters:\n"
BODY = ("    bodies:\n      b:\n        shape: box\n        size: [1.0, 0.5]\n"
        "        mass: {mass}\n")


def _scene_text(mass: str = "2.0", extra: str = "") -> str:
    return HEAD + BODY.format(mass=mass) + extra


def _write(tmp_path: Path, text, name: str = "scene.yaml") -> Path:
    path = tmp_path / name
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    return path


def _refused_in_one_line(path: Path, capsys, *fragments: str) -> str:
    """The file is refused by load_scene and by ``run`` (exit 2, one line of stderr that
    names the file and holds ``fragments``); returns that line."""
    with pytest.raises(SceneError) as caught:
        load_scene(path)
    message = str(caught.value)
    assert "\n" not in message and str(path) in message
    capsys.readouterr()
    assert main(["run", str(path), "--duration", "0.01"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("hecker-dynamics: error: ")
    assert str(path) in err
    for fragment in fragments:
        assert fragment in err
    assert len(err) < 400  # the bad value is quoted by a short prefix at most
    return err


# ------------------------------------------------------------------ ROS 2 number forms

@pytest.mark.parametrize("text, mass", [
    ("1e-9", 1e-9), ("1.0e9", 1.0e9), ("1E3", 1e3), ("+2", 2.0), ("0x10", 16.0),
    ("010", 8.0), (".5", 0.5), ("5.", 5.0), ("0x1p-2", 0.25),
])
def test_numbers_are_read_as_ros2_reads_them(tmp_path, text, mass):
    """strtoll (base 0: hex, octal) then strtod: '1e-9' is a double, as ROS 2 reads it
    (PyYAML's YAML 1.1 resolver made it the string '1e-9')."""
    scene = load_scene(_write(tmp_path, _scene_text(text)))
    assert scene.bodies[0].mass.mass == mass


@pytest.mark.parametrize("text", ["1:30", "'2.0'", "\"2.0\"", "!!str 2.0", "1_000", "0b11",
                                  "~", "null", "2.0.0"])
def test_strings_that_pyyaml_reads_as_numbers_are_strings_in_ros2(tmp_path, capsys, text):
    """'1:30' is not sexagesimal 90, '1_000' not 1000, '0b11' not 3, '~' not null: ROS 2
    reads them as strings, so a number parameter refuses them."""
    _refused_in_one_line(_write(tmp_path, _scene_text(text)), capsys, "bodies.b.mass",
                         "must be a number")


def test_ros2_booleans_words(tmp_path):
    for word, value in (("yes", True), ("On", True), ("n", False), ("OFF", False)):
        scene = load_scene(_write(tmp_path, _scene_text(
            extra=f"    publish:\n      odometry: {word}\n")))
        assert scene.publish_odometry is value


def test_a_huge_integer_is_a_string_to_ros2_and_quoted_by_a_prefix(tmp_path, capsys):
    digits = "9" * 5000
    err = _refused_in_one_line(_write(tmp_path, _scene_text(digits)), capsys, "bodies.b.mass")
    assert "9" * 100 not in err and "..." in err


# ------------------------------------------------------------------ sections and keys

def test_wildcard_and_node_sections_merge_node_first(tmp_path):
    """ROS 2 applies '/**' and then the node's own section: both sets of parameters
    count, the node's value wins where both give one."""
    text = ("/**:\n  ros__parameters:\n    step: 0.002\n    duration: 3.0\n"
            "    bodies:\n      b:\n        mass: 5.0\n        position: [1.0, 2.0]\n"
            + _scene_text("2.0"))
    scene = load_scene(_write(tmp_path, text))
    assert scene.step_ns == 2_000_000 and scene.duration_ns == 3_000_000_000
    assert scene.bodies[0].mass.mass == 2.0 and scene.bodies[0].position == (1.0, 2.0)
    # the order of the sections in the file does not matter
    text = _scene_text("2.0") + "/**:\n  ros__parameters:\n    bodies:\n      b:\n" \
                                "        mass: 5.0\n"
    assert load_scene(_write(tmp_path, text)).bodies[0].mass.mass == 2.0


def test_duplicate_keys_as_ros2_treats_them(tmp_path, capsys):
    """rcl keeps one value per parameter name, the last one written; a repeated mapping
    (a node section, 'bodies') adds its parameters to the earlier one's. A value given
    again loses the earlier one, so it warns, naming the line and the parameter."""
    text = (_scene_text("2.0") + "    step: 0.002\n    step: 0.004\n"
            "    bodies:\n      c:\n        shape: circle\n        radius: 0.5\n"
            "        mass: 1.0\n"
            "dynamics_node:\n  ros__parameters:\n    duration: 2.0\n"
            "    bodies:\n      b:\n        mass: 3.0\n")
    path = _write(tmp_path, text)
    with pytest.warns(DuplicateParameterWarning) as caught:
        scene = load_scene(path)
    assert [str(w.message) for w in caught] == [
        f"{path}: line 9: parameter 'step' is given again; ROS 2 keeps the last value",
        f"{path}: line 15: parameter 'bodies.b.mass' is given again; ROS 2 keeps the last "
        "value"]
    assert scene.step_ns == 4_000_000 and scene.duration_ns == 2_000_000_000
    assert [b.name for b in scene.bodies] == ["b", "c"] and scene.bodies[0].mass.mass == 3.0
    assert main(["run", str(path), "--duration", "0.01"]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 2 and err.startswith(
        f"hecker-dynamics: warning: {path}: line 9: parameter 'step' is given again")


def test_multiple_documents_merge_as_ros2_reads_them(tmp_path):
    text = _scene_text("2.0") + "---\ndynamics_node:\n  ros__parameters:\n    duration: 2.0\n"
    scene = load_scene(_write(tmp_path, text))
    assert scene.duration_ns == 2_000_000_000 and scene.bodies[0].mass.mass == 2.0


def test_scene_parameter_with_scene_parameters_is_refused(tmp_path, capsys):
    """As the node refuses it: one of the two would silently win."""
    path = _write(tmp_path, _scene_text("2.0", "    scene: sample\n"))
    _refused_in_one_line(path, capsys, "'scene'", "not both")


def test_scene_parameter_alone_names_the_scene_to_run(tmp_path):
    path = _write(tmp_path, HEAD + "    scene: sample\n    use_sim_time: false\n")
    assert load_scene(path).source == load_scene("sample").source
    loop = _write(tmp_path, HEAD + f"    scene: {tmp_path / 'loop.yaml'}\n", "loop.yaml")
    with pytest.raises(SceneError, match="loop.yaml.*names another scene"):
        load_scene(loop)


# ------------------------------------------------------------------ hostile files

@pytest.mark.parametrize("text, fragment", [
    ("dynamics_node: {ros__parameters: [unclosed\n", "line 2"),
    ("dynamics_node:\n  ros__parameters:\n    a: b: c\n", "line 3"),
    ("dynamics_node:\n\tros__parameters: {}\n", "line 2"),
    (_scene_text("") , "bodies.b.mass"),
])
def test_yaml_syntax_errors_are_one_line(tmp_path, capsys, text, fragment):
    _refused_in_one_line(_write(tmp_path, text), capsys, fragment)


@pytest.mark.parametrize("data", [
    _scene_text("2.0", "    frame_id: w\xe9lt\n").encode("latin-1"),
    b"\x00\x01\x02\xff\xfe binary",
    b"\xff\xfe" + "x: [".encode("utf-16-le"),
])
def test_files_that_are_not_utf8_are_refused(tmp_path, capsys, data):
    _refused_in_one_line(_write(tmp_path, data), capsys)


def test_utf16_with_a_byte_order_mark_reads_as_libyaml_reads_it(tmp_path):
    text = _scene_text("2.0")
    path = _write(tmp_path, b"\xff\xfe" + text.encode("utf-16-le"))
    assert load_scene(path).bodies[0].mass.mass == 2.0


def test_billion_laughs_is_refused_at_once(tmp_path, capsys):
    """ROS 2 refuses aliases ('Will not support aliasing'): refused before anything is
    expanded."""
    lines = ["a0: &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    for i in range(1, 10):
        refs = ", ".join([f"*a{i - 1}"] * 10)
        lines.append(f"a{i}: &a{i} [{refs}]")
    text = HEAD + "".join(f"    {line}\n" for line in lines)
    _refused_in_one_line(_write(tmp_path, text), capsys, "alias")


def test_a_yaml_merge_key_is_refused_naming_it(tmp_path, capsys):
    """A YAML merge key ('<<: {shape: circle, ...}'), which rcl reads as a name '<<' and
    merges nothing: it was refused as "bodies.c.shape is required but missing", beside
    the shape the file shows; now the merge key is named. Quoted, '<<' is a name as any
    other (refused as no parameter of the scene)."""
    text = _scene_text(extra="      c:\n        <<: {shape: circle, radius: 0.1}\n"
                             "        mass: 1.0\n")
    _refused_in_one_line(_write(tmp_path, text), capsys, "line 9, column 9: merge keys ('<<') "
                         "are not allowed in a ROS 2 parameters file (ROS 2 reads '<<' as a "
                         "name)")
    text = _scene_text(extra="      c:\n        '<<': {shape: circle, radius: 0.1}\n"
                             "        mass: 1.0\n")
    assert "merge keys" not in _refused_in_one_line(_write(tmp_path, text, "quoted.yaml"), capsys)


def test_deep_nesting_is_refused(tmp_path, capsys):
    text = HEAD + "    x: " + "{a: " * 900 + "1" + "}" * 900 + "\n"
    _refused_in_one_line(_write(tmp_path, text), capsys, "nested")
    text = HEAD + "    x: " + "[" * 900 + "]" * 900 + "\n"
    _refused_in_one_line(_write(tmp_path, text), capsys)


def test_a_huge_file_is_refused_before_it_is_parsed(tmp_path, capsys):
    path = tmp_path / "huge.yaml"
    with path.open("w") as out:
        out.write(_scene_text("2.0") + "    # " + "x" * (17 << 20) + "\n")
    _refused_in_one_line(path, capsys, "MiB")


def test_absurd_radius_is_refused(tmp_path, capsys):
    text = HEAD + "    bodies:\n      b:\n        shape: circle\n        radius: 1.0e200\n" \
                  "        mass: 1.0\n"
    _refused_in_one_line(_write(tmp_path, text), capsys, "body 'b'")


@pytest.mark.parametrize("mass", ["1.0", "2.5"])
def test_a_circle_too_small_to_integrate_quotes_the_mass_given(tmp_path, capsys, mass):
    """A 1e-160 m circle: its unit-density figures underflow (mass 3.142e-320, moment of
    inertia 0), and the error quoted them as the body's mass; it now quotes the mass given
    and the shape's area."""
    text = HEAD + "    bodies:\n      b:\n        shape: circle\n        radius: 1.0e-160\n" \
                  f"        mass: {mass}\n"
    err = _refused_in_one_line(_write(tmp_path, text), capsys, "body 'b'",
                               f"its mass of {float(mass):g} kg cannot be spread over it",
                               "area 3.142e-320 m^2")
    assert "e-320)" not in err.split("area")[0]


def test_polygon_vertex_count_is_bounded_and_a_big_one_loads_fast(tmp_path, capsys):
    """A 1000-vertex polygon loads (it took 9 s: a pair-by-pair simplicity check), with the
    mass properties of the disc it approximates; beyond the bound one line names the
    parameter."""
    import math
    n = 1000
    flat = []
    for k in range(n):
        flat += [math.cos(2 * math.pi * k / n), math.sin(2 * math.pi * k / n)]
    text = HEAD + "    bodies:\n      b:\n        shape: polygon\n        mass: 1.0\n" \
                  f"        vertices: [{', '.join(repr(x) for x in flat)}]\n"
    scene = load_scene(_write(tmp_path, text))
    assert len(scene.bodies[0].shapes[0].vertices) == n
    assert abs(scene.bodies[0].mass.moment_of_inertia - 0.5) < 1e-4  # a unit disc: m r^2 / 2
    many = [0.0, 0.0] * 5000
    text = HEAD + "    bodies:\n      b:\n        shape: polygon\n        mass: 1.0\n" \
                  f"        vertices: [{', '.join(repr(x) for x in many)}]\n"
    _refused_in_one_line(_write(tmp_path, text, "many.yaml"), capsys, "bodies.b.vertices")


@pytest.mark.parametrize("force, parameter, speed", [
    ("{type: gravity, acceleration: [0.0, -1.0e308]}", "forces.f.acceleration", "1e+305"),
    ("{type: constant_force, body: b, force: [1.5e308, 0.0]}", "forces.f.force", "7.5e+304"),
])
def test_a_force_no_double_holds_a_step_of_is_refused_at_load(tmp_path, capsys, force,
                                                               parameter, speed):
    """Gravity of 1e308 m/s^2 (or a constant force as big) on a 2 kg body: one step from
    rest gives it an energy of motion past a double. It was stopped at the first step as
    a divergence; the masses are known at load, so the file is refused there."""
    text = _scene_text(extra=f"    forces:\n      f: {force}\n")
    _refused_in_one_line(_write(tmp_path, text), capsys, f"parameter '{parameter}'",
                         f"speed of {speed} m/s", "past what a double holds")


@pytest.mark.parametrize("spring, parameter, speed", [
    ("stiffness: 1.0e308", "stiffness", "5e+304"),
    ("stiffness: 1.0, damping: 1.0e308", "damping", "2.5e+301"),
])
def test_a_spring_no_double_holds_a_step_of_is_refused_at_load(tmp_path, capsys, spring,
                                                                parameter, speed):
    """A spring 1 m long at the start with a stiffness of 1e308 N/m (or a dashpot of 1e308
    N s/m, pulled by the spring's 1 N) on a 2 kg body: its first step gives the body an
    energy of motion past a double. It was stopped at the first step ('dopri5: the
    sub-step size underflowed'); the file is refused at load, naming the parameter, and
    World.add_spring refuses it when the spring is added."""
    text = _scene_text(extra="    forces:\n      s: {type: spring, body_a: b, anchor: [1.0, 0.0], "
                             f"{spring}}}\n")
    _refused_in_one_line(_write(tmp_path, text), capsys, f"parameter 'forces.s.{parameter}'",
                         f"speed of {speed} m/s", "past what a double holds")
    world = hd.World()
    body = world.add_body("b", hd.Box(1.0, 0.5), mass=2.0)
    values = dict(item.split(": ") for item in spring.split(", "))
    words = f"'forces.s.{parameter}': would give body 'b' (2 kg), in its first step of " \
            f"0.001 s, a speed of {speed} m/s"
    with pytest.raises(SceneError, match=re.escape(words)):
        world.add_spring("s", "b", anchor=(1.0, 0.0),
                         **{key: float(value) for key, value in values.items()})
    world.add_spring("s", "b", anchor=(1.0, 0.0), stiffness=1.0)  # the refused one is gone
    world.step()
    assert body.position[0] > 0.0  # pulled towards the anchor


@pytest.mark.parametrize("topic, taken", [
    ("/b/pose", "an output of the node (geometry_msgs/msg/PoseStamped)"),
    ("b/twist", "an output of the node (geometry_msgs/msg/Twist)"),
    ("/tf", "an output of the node (tf2_msgs/msg/TFMessage)"),
    ("/clock", "the clock's topic"),
    ("applied_wrench", "the AppliedWrench input"),
    ("/other", "the topic of wrench_topics.a")])
def test_a_wrench_topic_that_is_another_topic_of_the_node_is_refused(tmp_path, capsys, topic,
                                                                     taken):
    """A WrenchStamped input on a topic the node publishes, on its other inputs or on
    /clock ran as if nothing were wrong: ROS 2 would not match it to the node's publisher
    of another type, and a replay took the topic as one input only (the other lost) or
    wrote two types on it. Refused by run and replay in one line, naming the parameter."""
    path = _write(tmp_path, _scene_text(extra=(
        "    wrench_topics:\n      a:\n        topic: /other\n        body: b\n"
        f"      z:\n        topic: {topic}\n        body: b\n")))
    load_scene(path)  # a scene of the core; the node's topics are the runner's to check
    expected = (f"{path}: parameter 'wrench_topics.z.topic': '{topic}' is already {taken}")
    bag = str(tmp_path / "in")
    assert main(["script", str(path), "-o", bag]) == 0
    for argv in (["run", str(path), "--duration", "0.01"],
                 ["replay", str(path), bag, "-o", str(tmp_path / "out")]):
        capsys.readouterr()
        assert main(argv) == 2
        assert capsys.readouterr().err == f"hecker-dynamics: error: {expected}\n"
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("drive, width", [
    ("type: diff_drive\n        separation: 0.5", 3),
    ("type: omni\n        wheels: [0.0, 0.5, 0.0, 0.5, 0.0, 1.5708, -0.5, 0.0, -1.5708]", 4)])
@pytest.mark.parametrize("time", ["1.0e+300", "2.0e+9"])
def test_a_drive_script_time_past_a_scene_s_longest_is_refused(tmp_path, capsys, drive,
                                                                 width, time):
    """A drive's scripted command at 1e300 s overflowed its nanoseconds (a traceback), and
    one at 2e9 s took a stamp past an int64's; a scene's times end at 1e9 s."""
    command = ", ".join([time] + ["0.0"] * (width - 1))
    path = _write(tmp_path, _scene_text(extra=(
        f"    drives:\n      d:\n        {drive}\n        body: b\n        max_force: 1.0\n"
        f"        linear_kp: 1.0\n        angular_kp: 1.0\n        script: [{command}]\n")))
    _refused_in_one_line(path, capsys, "parameter 'drives.d.script'", "from 0 to 1e+09 s")


@pytest.mark.parametrize("groups, pair, first", [
    ([["a", "b", "c"], ["d", "c", "a"]], ("c", "a"), "g0"),
    ([["a", "b"], ["b", "c"], ["c", "a", "b"]], ("c", "b"), "g1"),
    ([["a", "b", "c"], ["a", "b", "d"], ["d", "b", "a"]], ("a", "b"), "g0"),
])
def test_a_pair_in_two_collision_groups_is_named_with_its_first_group(tmp_path, capsys,
                                                                       groups, pair, first):
    """The first pair of the later group's list that an earlier group holds, and the first
    group holding it; groups that share one body only are fine."""
    bodies = "".join(f"      {n}:\n        shape: box\n        size: [1.0, 0.5]\n"
                     f"        mass: 1.0\n        position: [{3.0 * k}, 0.0]\n"
                     for k, n in enumerate("abcd"))
    listed = "".join(f"      g{k}:\n        bodies: [{', '.join(members)}]\n"
                     for k, members in enumerate(groups))
    text = HEAD + "    bodies:\n" + bodies + "    collisions:\n" + listed
    _refused_in_one_line(_write(tmp_path, text), capsys, "collisions.g",
                         f"bodies '{pair[0]}' and '{pair[1]}' are already in collision "
                         f"group '{first}'")
    fine = HEAD + "    bodies:\n" + bodies + "    collisions:\n" + \
        "      g0:\n        bodies: [a, b, c]\n      g1:\n        bodies: [c, d]\n"
    assert [g.bodies for g in load_scene(_write(tmp_path, fine, "fine.yaml")).collisions] == \
        [("a", "b", "c"), ("c", "d")]


@pytest.mark.parametrize("duration, seconds", [("1.0e-9", "1e-09"), ("0.0005", "0.0005"),
                                               ("1.0e-10", "1e-10")])
def test_a_script_force_shorter_than_one_step_is_refused(tmp_path, capsys, duration, seconds):
    """A force acts over whole steps: a scripted kick of 1e-9 s at steps of 1 ms gave the
    impulse of a whole step, a million times the one written, without a word; 1e-10 s,
    0 ns once rounded, was held until the input timeout."""
    path = _write(tmp_path, _scene_text(extra=(
        "    step: 0.001\n    script:\n      kick:\n        time: 0.0\n        body: b\n"
        f"        force: [1.0, 0.0]\n        duration: {duration}\n")))
    _refused_in_one_line(path, capsys,
                         f"parameter 'script.kick.duration': {seconds} s is shorter than one "
                         "step (0.001 s), over which a force acts whole")


def test_a_motor_whose_power_overflows_is_refused(tmp_path, capsys):
    """The energy bound takes a motor's work at its largest torque times its speed: inf
    there let the bound take any energy of the bodies it joins."""
    path = _write(tmp_path, _scene_text(extra=(
        "    joints:\n      axle:\n        type: revolute\n        body_b: b\n"
        "        motor: {speed: 1.0e+200, max_torque: 1.0e+200}\n")))
    _refused_in_one_line(path, capsys, "parameter 'joints.axle.motor.speed': 1e+200 times "
                         "the motor's largest effort 1e+200 is a power past what a double "
                         "holds")
