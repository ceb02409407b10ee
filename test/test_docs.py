"""The documentation matches the code: every parameter the scene loader reads is in
docs/scenes.md, every shipped scene is in the README, and the README's CLI lines parse."""
from __future__ import annotations

import argparse
import re
import shlex
from pathlib import Path

import pytest
from scene_builders import EVERY_FORCE, make_scene

from hecker_dynamics.cli import parser
from hecker_dynamics.scene import parameters
from hecker_dynamics.scene.load import shipped_scenes

ROOT = Path(__file__).resolve().parent.parent
SCENES_DOC = (ROOT / "docs" / "scenes.md").read_text()
README = (ROOT / "README.md").read_text()

EVERY_FEATURE = dict(
    EVERY_FORCE, frame_id="world", integrator="rk4", tolerance=1e-6, duration=2.0,
    input_timeout=0.5, input_max_lead=5.0, twist_frame="world", restitution_threshold=0.01,
    publish={"odometry": True, "markers": True, "diagnostics": True, "tf": True},
    walls={"floor": {"point": [0.0, -3.0], "normal": [0.0, 1.0], "restitution": 0.5,
                     "friction": 0.2, "bodies": ["a", "b"]}},
    collisions={"all": {"bodies": ["a", "b"], "restitution": 0.1, "friction": 0.4}},
    wrench_topics={"jet": {"topic": "a/jet", "body": "a", "frame_id": "a/tip"}},
    joints={"pin": {"type": "revolute", "body_a": "a", "point_a": [0.0, 0.0], "body_b": "c",
                    "point_b": [2.0, -0.5], "lower": -1.0, "upper": 1.0,
                    "motor": {"speed": 1.0, "max_torque": 2.0}, "collide_connected": True,
                    "spring": {"stiffness": 1.0, "damping": 0.1, "rest_angle": 0.0}},
            "rail": {"type": "prismatic", "body_b": "b", "axis": [1.0, 0.0], "lower": -1.0,
                     "upper": 1.0, "motor": {"speed": 0.0, "max_force": 1.0}},
            "glue": {"type": "weld", "body_a": "b", "body_b": "c", "frequency": 2.0,
                     "damping_ratio": 0.5},
            "rod": {"type": "distance", "body_a": "a", "body_b": "b", "length": 1.0},
            "rope": {"type": "distance", "body_a": "a", "body_b": "c", "max_length": 9.0},
            "mesh": {"type": "gear", "joint_a": "pin", "joint_b": "hinge", "ratio": 2.0},
            "hinge": {"type": "revolute", "body_b": "b"}},
    sensors={"scan": {"type": "laser", "body": "a", "position": [0.1, 0.0], "angle": 0.0,
                      "angle_min": -1.0, "angle_max": 1.0, "count": 11, "range_min": 0.1,
                      "range_max": 5.0, "rate": 10.0, "noise": 0.01, "seed": 3},
             "gyro": {"type": "imu", "body": "b", "orientation_noise": 0.1,
                      "angular_velocity_noise": 0.1, "linear_acceleration_noise": 0.1}},
    drives={"base": {"type": "diff_drive", "body": "a", "center": [0.0, 0.0],
                     "separation": 0.4, "max_force": 5.0, "traction": 4.0,
                     "lateral_damping": 10.0, "linear_kp": 1.0, "linear_ki": 1.0,
                     "angular_kp": 1.0, "angular_ki": 1.0, "rate": 100.0,
                     "cmd_vel_timeout": 0.5, "script": [0.0, 1.0, 0.0]}},
    script={"kick": {"time": 0.5, "body": "a", "id": "k", "frame_id": "a", "point": [0.1, 0.0],
                     "force": [1.0, 0.0], "torque": 0.1, "duration": 0.2}},
)


def test_every_parameter_the_loader_reads_is_documented(monkeypatch):
    read: set[str] = set()
    original = parameters.ParameterReader._get

    def spy(self, key, default):
        read.add(key)
        return original(self, key, default)

    monkeypatch.setattr(parameters.ParameterReader, "_get", spy)
    make_scene(EVERY_FEATURE)
    # Names of this scene's own bodies, forces, ... are not parameters.
    own = {"a", "b", "c", "tip", "hull", "ball", "floor", "all", "jet", "kick",
           *EVERY_FORCE["forces"], "pin", "rail", "glue", "rod", "rope", "mesh", "hinge",
           "scan", "gyro", "base"}
    undocumented = sorted(key for key in read - own
                          if not re.search(rf"`([a-z_]+\.)?{re.escape(key)}[`.]", SCENES_DOC))
    assert not undocumented, f"parameters missing from docs/scenes.md: {undocumented}"
    assert len(read - own) > 40  # the spy saw the whole loader, not a part of it


@pytest.mark.parametrize("name", shipped_scenes())
def test_every_shipped_scene_is_described_in_the_readme(name):
    assert f"| `{name}`" in README


@pytest.mark.parametrize("page", ["README.md", "docs/cli.md"])
def test_the_command_lines_of_the_guides_parse(page):
    lines = [line.split("#")[0].strip() for line in (ROOT / page).read_text().splitlines()
             if line.startswith("hecker-dynamics ")]
    assert len(lines) >= 5
    for line in lines:
        words = shlex.split(line.replace("[", "").replace("]", ""))
        args = [{"SCENE": "sample", "INPUT_BAG": "in", "OUTPUT_BAG": "out",
                 "RECORDED_BAG": "rec", "EXPECTED_BAG": "a", "ACTUAL_BAG": "b", "S": "1",
                 "NAME": "rk4", "T": "1e-6", "A": "1e-6"}.get(w, w) for w in words[1:]]
        parser().parse_args(args)


#: The article's equations by their numbers in "Physics, Part 2: Angular Effects" (the
#: README's "The article, step by step, in the code"), each with the words of which one must
#: stand in the text that cites it, so that a citation with the wrong number fails: F = M a
#: is Eq. 5, not Eq. 4.
EQUATION_WORDS = {
    1: ("derivative",),
    3: ("center of mass", "centroid"),
    5: ("f = m a", "force"),
    6: ("angle", "angular acceleration"),
    9: ("body point", "point's velocity", "v_p =", "omega perp("),
    10: ("angular momentum",),
    11: ("torque",),
    13: ("moment of inertia",),
    14: ("tau = i alpha", "torque / i", "over inertia", "angular acceleration"),
}
_CITATION = re.compile(r"\b(?:Eq|Eqs|Equation|Equations)\.?\s*\d+"
                       r"(?:(?:\s*,\s*|\s+and\s+)(?:(?:Eq|Eqs|Equation|Equations)\.?\s*)?\d+)*")
#: How far before a citation its words may stand (they must also follow the previous one).
_REACH = 160
_SOURCES = ("*.py", "*.md", "*.c", "*.h", "*.txt", "*.toml", "*.cfg", "*.xml", "run")


def _citations() -> list[tuple[str, list[int], str, str]]:
    """(file, cited numbers, the citation as written, the text before it) across the tree."""
    found = []
    for pattern in _SOURCES:
        for path in sorted(ROOT.rglob(pattern)):
            relative = path.relative_to(ROOT)
            if path == Path(__file__).resolve() or any(
                    part.startswith((".", "build")) for part in relative.parts):
                continue
            # Lines joined, with the comment leaders of C, Python and Markdown dropped.
            text = re.sub(r"\s*\n\s*(?:\*|#+|//|\|)?\s*", " ", path.read_text(errors="replace"))
            end = 0
            for match in _CITATION.finditer(text):
                before = text[max(end, match.start() - _REACH):match.start()]
                numbers = [int(n) for n in re.findall(r"\d+", match.group())]
                found.append((str(relative), numbers, match.group(), before))
                end = match.end()
    return found


def test_equation_citations_name_the_right_numbers():
    citations = _citations()
    assert len(citations) >= 15  # the scan reached the docstrings, the docs and the C
    wrong = [f"{file}: {cited!r} after ...{before[-60:]!r}"
             for file, numbers, cited, before in citations for n in numbers
             if not any(word in before.lower() for word in EQUATION_WORDS.get(n, ()))]
    assert not wrong, "equation numbers that do not fit their text:\n" + "\n".join(wrong)


def test_equations_are_cited_in_one_form():
    forms = {re.match(r"\D+", cited).group().strip() for _, _, cited, _ in _citations()}
    assert forms == {"Eq."}


#: The groups of named entries (``bodies.<name>``, ...) and the nested names in them.
_GROUPS = ("bodies", "forces", "walls", "collisions", "joints", "wrench_topics", "sensors",
           "drives", "script")
_NESTED = {"parts": "<part>", "points": "<point>"}


def _canonical(path: str) -> str:
    """``bodies.left.parts.hull.size`` as docs/scenes.md writes it: ``bodies.<name>.size``
    (a part takes a body's keys), ``bodies.<name>.points.<point>``."""
    parts = path.split(".")
    if parts[0] in _GROUPS and len(parts) > 1:
        parts[1] = "<name>"
    for i in range(2, len(parts) - 1):
        if parts[i] in _NESTED:
            parts[i + 1] = _NESTED[parts[i]]
    text = ".".join(parts)
    return re.sub(r"^bodies\.<name>\.parts\.<part>\.", "bodies.<name>.", text)


def _documented_scene_keys() -> set[str]:
    """Every parameter in the tables of docs/scenes.md, by its full dotted name: the first
    column of a "Parameter" table, the "Parameters" column of a "`type`" table."""
    keys: set[str] = set()
    prefix: str | None = None
    header: list[str] | None = None
    for line in SCENES_DOC.splitlines():
        title = re.match(r"## (.*)", line)
        if title:
            group = re.fullmatch(r"`([a-z_]+)\.<[a-z]+>`", title.group(1))
            prefix = (f"{group.group(1)}.<name>." if group else
                      "" if title.group(1) in ("Top level", "`map`") else None)
            header = None
            continue
        if prefix is None or not line.startswith("|"):
            header = None
            continue
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if header is None:
            header = cells
            continue
        if set(cells[0]) <= set("- "):
            continue
        if header[0] == "Parameter":
            text = cells[0]
        elif header[:2] == ["`type`", "Parameters"]:
            keys.add(prefix + "type")
            text = cells[1]
        else:
            continue
        keys.update(prefix + token for token in re.findall(r"`([a-z_]+(?:\.[a-z_<>]+)*)`", text)
                    if token != "world")  # constant_force's axes value, not a key
    return keys


#: With EVERY_FEATURE, scenes that reach the rest of the loader: a map, soft joints, the
#: exact pass's pin gap, thrusters and an omni base, a one-shape polygon, every publish and
#: contacts switch.
_MORE_FEATURES = [
    {"bodies": {"p": {"shape": "polygon", "vertices": [0.0, 0.0, 1.0, 0.0, 0.0, 1.0],
                      "mass": 1.0},
                "q": {"shape": "circle", "radius": 0.5, "mass": 1.0, "position": [3.0, 0.0]}},
     "map": {"file": str(ROOT / "config" / "maps" / "warehouse.yaml"), "restitution": 0.1,
             "friction": 0.3, "bodies": ["p"]},
     "contacts": {"sleep": True, "events": True, "threads": 2, "converged": 1e-12},
     "publish": {"contacts": True},
     "drives": {"om": {"type": "omni", "body": "q", "center": [0.0, 0.0],
                       "wheels": [0.3, 0.0, 1.5708, -0.15, 0.26, -0.5236, -0.15, -0.26, 3.6652],
                       "max_force": 5.0, "linear_kp": 1.0, "linear_ki": 0.5,
                       "angular_kp": 1.0, "angular_ki": 0.5, "rate": 50.0,
                       "cmd_vel_timeout": 1.0, "script": [0.0, 1.0, 0.0, 0.0]}}},
    {"integrator": "semi_implicit_euler",
     "joint_solver": {"type": "soft", "substeps": 2, "hertz": 30.0, "damping_ratio": 1.0},
     "bodies": {"a": {"shape": "circle", "radius": 0.5, "mass": 1.0}},
     "joints": {"pin": {"type": "revolute", "body_b": "a"}},
     "drives": {"jets": {"type": "thrusters", "body": "a", "max_force": 1.0, "linear_kp": 1.0,
                         "angular_kp": 1.0,
                         "thrusters": [0.0, 0.3, 0.0, 0.0, -0.3, 0.0, 0.3, 0.0, 1.57,
                                       -0.3, 0.0, -1.57, 0.0, 0.3, 3.14, 0.0, -0.3, 3.14]}}},
    {"joint_solver": {"pin_gap": 1e-9},
     "bodies": {"a": {"shape": "circle", "radius": 0.5, "mass": 1.0}},
     "joints": {"pin": {"type": "revolute", "body_b": "a"}}},
]


def test_the_scene_parameters_read_and_documented_are_the_same(monkeypatch):
    """Both ways, by full dotted name: a parameter the loader reads is in a table of
    docs/scenes.md under its own section, and a parameter a table lists is read."""
    read: set[str] = set()
    original = parameters.ParameterReader._get

    def spy(self, key, default):
        read.add(_canonical(self.path(key)))
        return original(self, key, default)

    monkeypatch.setattr(parameters.ParameterReader, "_get", spy)
    for scene in (EVERY_FEATURE, *_MORE_FEATURES):
        make_scene(scene)
    # The groups themselves and the mappings of nested parameters are not parameters.
    mappings = {*_GROUPS, "publish", "contacts", "joint_solver", "map"}
    leaves = {key for key in read if key not in mappings and not (
        key.split(".")[0] in _GROUPS and key.count(".") == 1)
        and not key.endswith((".points", ".parts", ".motor", ".spring"))}
    documented = _documented_scene_keys()
    assert len(documented) > 120  # the parse reached every table
    assert sorted(leaves - documented) == [], "read, but not in docs/scenes.md's tables"
    assert sorted(documented - leaves) == [], "in docs/scenes.md's tables, but never read"


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in parser()._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def test_every_option_of_every_command_is_in_the_cli_guide():
    guide = (ROOT / "docs" / "cli.md").read_text()
    missing = sorted(f"{name} {'/'.join(action.option_strings)}"
                     for name, sub in _subparsers().items() for action in sub._actions
                     if action.option_strings and "--help" not in action.option_strings
                     and not any(re.search(rf"(?<![\w-]){re.escape(option)}(?![\w-])", guide)
                                 for option in action.option_strings))
    assert not missing, f"options docs/cli.md does not name: {missing}"


@pytest.mark.parametrize("page", ["README.md", "docs/cli.md", "docs/batch.md",
                                  "docs/replay.md", "docs/ros.md"])
def test_every_option_the_guides_name_exists(page):
    options = {option for sub in _subparsers().values() for action in sub._actions
               for option in action.option_strings}
    text = (ROOT / page).read_text()
    named = set(re.findall(r"(?<![\w/.-])(--[a-z][a-z-]*)", text))
    # Options of other programs the guides quote: ros2 bag record/play, pip, colcon, dask.
    others = {"--packages-select", "--from-paths", "--ignore-src", "--params-file",
              "--ros-args", "--rate", "--once", "--verbose", "--user",
              "--break-system-packages", "--clock", "--nthreads", "--nworkers", "--numpy",
              "--installed", "--fuzz-seconds", "--fuzz-seed", "--strict", "--vs"}
    assert sorted(named - options - others) == []


def test_the_readme_layout_names_every_module_and_c_file():
    block = README[README.index("## Layout"):]
    block = block[:block.index("\n```\n", block.index("```") + 3)]
    sections = re.split(r"\n  (?=[a-z_]+/)", block)
    by_folder = {section.split("/")[0]: section for section in sections[1:]}
    package = ROOT / "hecker_dynamics"
    missing = [f"{path.parent.name}/{path.name}"
               for folder in sorted(p for p in package.iterdir() if (p / "__init__.py").exists())
               for path in sorted(folder.glob("*.py")) if path.name != "__init__.py"
               and not re.search(rf"\b{re.escape(path.name)}\b",
                                 by_folder.get(folder.name, ""))]
    missing += [path.name for path in sorted(package.glob("*.py"))
                if path.name != "__init__.py" and f"  {path.name}" not in block
                and f", {path.name}" not in block and f"; {path.name}" not in block]
    kernel = block[block.index("src/kernel/"):]
    missing += [f"src/kernel/{path.name}" for path in sorted((ROOT / "src" / "kernel").glob("*.c"))
                if path.name not in kernel and not (path.name.startswith("bind_")
                                                    and "bind_*.c" in kernel)]
    assert not missing, f"files the README's Layout does not name: {missing}"
