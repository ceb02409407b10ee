"""The ROS package files, checked without ROS: manifest, build rules, interface, launch, node.

``catkin_pkg`` validates ``package.xml`` as ``rosdep`` and ``colcon`` read it; rosbags'
message parser reads ``msg/AppliedWrench.msg`` as ``rosidl`` would and round-trips a
message through CDR. The launch file and node module need ROS to run, so here they are
compiled only.
"""
from __future__ import annotations

import ast
import os
import py_compile
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = "hecker_dynamics"
MSG_TYPE = "hecker_dynamics/msg/AppliedWrench"

#: Messages and services the node imports, each with the package that provides it.
NODE_INTERFACES = ("builtin_interfaces", "diagnostic_msgs", "geometry_msgs", "nav_msgs",
                   "rcl_interfaces", "rosgraph_msgs", "sensor_msgs", "std_msgs", "std_srvs",
                   "tf2_msgs", "visualization_msgs")


@pytest.fixture(scope="module")
def manifest():
    package = pytest.importorskip("catkin_pkg.package", reason="catkin_pkg is not installed")
    parsed = package.parse_package(str(ROOT / "package.xml"))
    parsed.validate()
    return parsed


@pytest.fixture(scope="module")
def cmake() -> str:
    text = (ROOT / "CMakeLists.txt").read_text()
    return "\n".join(line.split("#", 1)[0] for line in text.splitlines())  # drop comments


def _names(dependencies) -> set[str]:
    return {d.name for d in dependencies}


def test_manifest_is_format_3_and_names_the_package(manifest, cmake):
    assert manifest.package_format == 3
    assert manifest.name == PACKAGE
    assert re.search(r"project\(\s*hecker_dynamics\s*\)", cmake)
    assert manifest.get_build_type() == "ament_cmake"
    assert "rosidl_interface_packages" in {g.name for g in manifest.member_of_groups}


def test_manifest_declares_every_dependency(manifest):
    buildtool = _names(manifest.buildtool_depends)
    assert {"ament_cmake", "ament_cmake_python", "rosidl_default_generators"} <= buildtool
    build = _names(manifest.build_depends)
    execute = _names(manifest.exec_depends)
    for interface in ("builtin_interfaces", "geometry_msgs", "std_msgs"):  # used by the .msg
        assert interface in build and interface in execute, interface
    for interface in NODE_INTERFACES:
        assert interface in execute, interface
    assert {"rclpy", "rosidl_default_runtime", "python3-numpy", "python3-yaml", "launch",
            "launch_ros"} <= execute
    assert "ament_cmake_pytest" in _names(manifest.test_depends)
    assert "python3-dev" in build  # Python.h for the compiled kernel (rosdep's python.yaml)
    # rosbags has only a pip rosdep key (python3-rosbags-pip in rosdistro's python.yaml):
    # the tests may use it, the node and the build must not need it.
    assert not any("rosbags" in name for name in build | execute | buildtool)
    assert "python3-rosbags-pip" in _names(manifest.test_depends)


def test_node_interfaces_are_the_node_modules_imports():
    """Every ``<package>.msg`` / ``<package>.srv`` the node imports is in NODE_INTERFACES
    (so the manifest test above covers it); the package's own messages aside."""
    tree = ast.parse((ROOT / PACKAGE / "ros" / "node.py").read_text())
    imported = {node.module.split(".")[0] for node in ast.walk(tree)
                if isinstance(node, ast.ImportFrom) and node.module and node.level == 0
                and node.module.split(".")[-1] in ("msg", "srv")}
    assert imported and imported <= set(NODE_INTERFACES), imported - set(NODE_INTERFACES)


def test_manifest_version_matches_setup_py(manifest):
    setup = ROOT / "setup.py"
    if not setup.exists():
        pytest.skip("setup.py is not in the tree")
    match = re.search(r"version\s*=\s*['\"]([^'\"]+)['\"]", setup.read_text())
    assert match and match.group(1) == manifest.version


def test_cmake_generates_the_interface_and_installs_beside_it(cmake):
    generate = re.search(r"rosidl_generate_interfaces\((.*?)\)", cmake, re.S)
    assert generate and '"msg/AppliedWrench.msg"' in generate.group(1)
    interfaces = sorted(f"{p.parent.name}/{p.name}" for folder in ("msg", "srv")
                        for p in (ROOT / folder).glob("*.*"))
    assert "srv/SpawnBody.srv" in interfaces and "srv/DeleteBody.srv" in interfaces
    assert re.findall(r'"((?:msg|srv)/[^"]+)"', generate.group(1)) == interfaces
    for dependency in ("builtin_interfaces", "geometry_msgs", "std_msgs"):
        assert dependency in generate.group(1)
        assert f"find_package({dependency} REQUIRED)" in cmake
    # ros2/rosidl_python#141: the generator already installs a Python package of this name.
    assert "ament_python_install_package" not in cmake
    install_python = re.search(
        r'install\(DIRECTORY \$\{PROJECT_NAME\}/\s+DESTINATION "\$\{PYTHON_INSTALL_DIR\}/'
        r'\$\{PROJECT_NAME\}"\s+PATTERN "__pycache__" EXCLUDE', cmake)
    assert install_python, "the hand-written package must be installed as a directory"
    assert cmake.index("find_package(ament_cmake_python REQUIRED)") < install_python.start()
    assert generate.start() < install_python.start()
    assert re.search(r"install\(PROGRAMS scripts/dynamics_node\s+DESTINATION "
                     r"lib/\$\{PROJECT_NAME\}", cmake)
    assert re.search(r"install\(DIRECTORY config launch rviz\s+DESTINATION "
                     r"share/\$\{PROJECT_NAME\}", cmake)
    assert "ament_export_dependencies(rosidl_default_runtime)" in cmake
    assert cmake.rstrip().endswith("ament_package()")


def _setup_py_value(name: str):
    """A module-level constant of setup.py, read without running it."""
    tree = ast.parse((ROOT / "setup.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and [getattr(t, "id", "") for t in node.targets] == [name]:
            return ast.literal_eval(node.value)
    raise AssertionError(f"setup.py defines no {name}")


def test_cmake_builds_the_kernel_as_setup_py_does(cmake):
    # Two builds of one extension: pip's (setup.py, optional) and colcon's (CMakeLists.txt,
    # required). Same sources, same floating-point flags, or the two would drift apart.
    if not (ROOT / "setup.py").exists():
        pytest.skip("setup.py is not in the tree")
    setup = (ROOT / "setup.py").read_text()
    sources = _setup_py_value("KERNEL_SOURCES")
    headers = _setup_py_value("KERNEL_HEADERS")
    assert re.search(r'Extension\("hecker_dynamics\._kernel", sources=KERNEL_SOURCES,\s+'
                     r'depends=KERNEL_HEADERS,.*?optional=True\)', setup, re.S)
    library = re.search(r"Python3_add_library\(_kernel MODULE WITH_SOABI\s+(.*?)\)", cmake, re.S)
    assert library, "CMakeLists.txt builds no _kernel module"
    assert sorted(library.group(1).split()) == sorted(sources)
    kernel = ROOT / "src" / "kernel"
    if kernel.is_dir():  # every C file and header of the kernel is in both builds
        assert sorted(p.relative_to(ROOT).as_posix() for p in kernel.glob("*.c")) == \
            sorted(sources)
        assert sorted(p.relative_to(ROOT).as_posix() for p in kernel.glob("*.h")) == \
            sorted(headers)
    # The same interpreter as ament's (found in find_package(ament_cmake)), its headers added.
    find_python = cmake.index("find_package(Python3 REQUIRED COMPONENTS Interpreter "
                              "Development.Module)")
    assert cmake.index("find_package(ament_cmake REQUIRED)") < find_python < library.start()
    # GCC/Clang flags: setup.py's -std=gnu11 is CMake's C standard 11 with extensions.
    gnu_flags = _setup_py_value("GNU_FLAGS")
    assert "-ffp-contract=off" in gnu_flags and "-std=gnu11" in gnu_flags
    options = re.search(r'if\(CMAKE_C_COMPILER_ID MATCHES "GNU\|Clang"\)\s+'
                        r"target_compile_options\(_kernel PRIVATE ([^)]*)\)\s+elseif\(MSVC\)\s+"
                        r"target_compile_options\(_kernel PRIVATE ([^)]*)\)", cmake)
    assert options, "CMakeLists.txt sets no compiler flags for _kernel"
    assert options.group(1).split() == [f for f in gnu_flags if not f.startswith("-std=")]
    assert options.group(2).split() == _setup_py_value("MSVC_FLAGS")
    gcc = re.search(r'if\(CMAKE_C_COMPILER_ID STREQUAL "GNU"\)\s+'
                    r"target_compile_options\(_kernel PRIVATE ([^)]*)\)", cmake)
    assert gcc and gcc.group(1).split() == _setup_py_value("GCC_FLAGS")
    assert re.search(r"set_target_properties\(_kernel PROPERTIES C_STANDARD 11 "
                     r"C_STANDARD_REQUIRED ON C_EXTENSIONS ON\)", cmake)
    assert '["m", "pthread"]' in setup
    assert "target_link_libraries(_kernel PRIVATE m pthread)" in cmake
    assert re.search(r'install\(TARGETS _kernel\s+LIBRARY DESTINATION '
                     r'"\$\{PYTHON_INSTALL_DIR\}/\$\{PROJECT_NAME\}"\s*\)', cmake)
    # An sdist carries the kernel's sources.
    assert "recursive-include src/kernel *.c *.h" in (ROOT / "MANIFEST.in").read_text()


def test_cmake_registers_the_tests(cmake):
    """colcon runs every test file: the glob CMakeLists.txt registers matches them all,
    and their names (colcon's test names) are unique."""
    registered = re.search(r"file\(GLOB_RECURSE _tests RELATIVE \"\$\{CMAKE_CURRENT_SOURCE_DIR\}\""
                           r"\s+CONFIGURE_DEPENDS\s+([^)]*)\)", cmake)
    assert registered, "CMakeLists.txt registers no tests"
    assert re.search(r'ament_add_pytest_test\(\$\{_name\} "\$\{_test\}"', cmake)
    globbed = {path for pattern in registered.group(1).split()
               for path in ROOT.glob(pattern)}
    on_disk = set((ROOT / "test").rglob("test_*.py"))
    assert globbed == on_disk
    names = [path.stem for path in on_disk]
    assert len(names) == len(set(names)), "two test files share a name"


def test_hand_written_package_has_no_msg_subpackage():
    # The generated hecker_dynamics.msg is installed into the same directory.
    assert not (ROOT / PACKAGE / "msg").exists()


def test_message_parses_and_round_trips_through_cdr():
    typesys = pytest.importorskip("rosbags.typesys", reason="rosbags is not installed")
    text = (ROOT / "msg" / "AppliedWrench.msg").read_text()
    types = typesys.get_types_from_msg(text, MSG_TYPE)
    assert set(types) == {MSG_TYPE}
    store = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
    store.register(types)
    t = store.types
    vector3 = t["geometry_msgs/msg/Vector3"]
    msg = t[MSG_TYPE](
        header=t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=12, nanosec=345), frame_id="left/hook"),
        body="left", id="kick", point=t["geometry_msgs/msg/Point"](x=0.4, y=0.2, z=0.0),
        wrench=t["geometry_msgs/msg/Wrench"](force=vector3(x=0.0, y=60.0, z=0.0),
                                             torque=vector3(x=0.0, y=0.0, z=-1.5)),
        duration=t["builtin_interfaces/msg/Duration"](sec=0, nanosec=100_000_000))
    raw = store.serialize_cdr(msg, MSG_TYPE)
    back = store.deserialize_cdr(raw, MSG_TYPE)
    assert back == msg
    assert (back.header.frame_id, back.wrench.force.y, back.duration.nanosec) == (
        "left/hook", 60.0, 100_000_000)


def test_message_comments_state_frame_and_hold_semantics():
    text = (ROOT / "msg" / "AppliedWrench.msg").read_text()
    comments = " ".join(line.lstrip("# ") for line in text.splitlines()
                        if line.startswith("#")).lower()
    for phrase in ("header.stamp", "header.frame_id", "zero stamp", "<body>/<point>",
                   "replaces", "input timeout", "out-of-plane", "ignored"):
        assert phrase in comments, phrase


def test_python_files_compile(tmp_path):
    for relative in ("launch/dynamics.launch.py", "hecker_dynamics/ros/node.py",
                     "scripts/dynamics_node"):
        py_compile.compile(str(ROOT / relative), cfile=str(tmp_path / "out.pyc"),
                           doraise=True)


def test_node_script_is_a_tiny_executable():
    script = ROOT / "scripts" / "dynamics_node"
    assert os.access(script, os.X_OK)
    text = script.read_text()
    assert text.startswith("#!/usr/bin/env python3\n")
    assert "from hecker_dynamics.ros.node import main" in text


def test_launch_file_declares_scene_and_use_sim_time():
    tree = ast.parse((ROOT / "launch" / "dynamics.launch.py").read_text())
    functions = {node.name for node in ast.walk(tree) if isinstance(node, ast.FunctionDef)}
    assert "generate_launch_description" in functions
    declared = {call.args[0].value for call in ast.walk(tree)
                if isinstance(call, ast.Call) and getattr(call.func, "id", "") ==
                "DeclareLaunchArgument"}
    assert declared == {"scene", "use_sim_time", "rviz", "markers"}


def _launch_tree() -> ast.Module:
    return ast.parse((ROOT / "launch" / "dynamics.launch.py").read_text())


def _launch_function(name: str):
    """One plain function of the launch file, compiled alone (launch is not installed here)."""
    tree = _launch_tree()
    [function] = [node for node in tree.body
                  if isinstance(node, ast.FunctionDef) and node.name == name]
    namespace: dict = {}
    exec(compile(ast.Module([function], []), "dynamics.launch.py", "exec"), namespace)
    return namespace[name]


def test_launch_file_turns_markers_on_with_rviz():
    markers_on = _launch_function("_markers_on")
    assert markers_on(True, "auto") is True      # RViz: markers on by default
    assert markers_on(False, "auto") is None     # no RViz: the scene decides
    assert markers_on(True, "false") is False and markers_on(False, "true") is True
    text = (ROOT / "launch" / "dynamics.launch.py").read_text()
    assert "overrides['publish.markers'] = markers" in text
    # rviz2 opens the installed config in the scene's own fixed frame.
    assert "RVIZ_CONFIG = 'rviz/hecker_dynamics.rviz'" in text
    assert "arguments=['-d', config, '-f', load_scene(params_file).frame_id]" in text


def _rviz_config() -> dict:
    import yaml

    return yaml.safe_load((ROOT / "rviz" / "hecker_dynamics.rviz").read_text())


def test_rviz_config_shows_the_nodes_tf_and_markers():
    from scene_builders import box_body, make_scene

    from hecker_dynamics.bags.io import resolve_topic
    from hecker_dynamics.ros.names import MARKERS_TOPIC
    from hecker_dynamics.ros.outputs import OutputKind, output_topics

    manager = _rviz_config()["Visualization Manager"]
    # The scene's default fixed frame (a scene that does not set frame_id).
    scene = make_scene({"bodies": {"puck": box_body()}, "publish": {"markers": True}})
    assert manager["Global Options"]["Fixed Frame"] == scene.frame_id
    displays = {d["Class"]: d for d in manager["Displays"]}
    assert {"rviz_default_plugins/TF", "rviz_default_plugins/MarkerArray"} <= set(displays)
    assert all(d["Enabled"] for d in displays.values())
    # RViz2's TF axes are 0.2 m and its names 0.1 m tall times Marker Scale: at the view's
    # 60 px/m, 0.5 gave 3 px names that nobody can read (seen under Xvfb on Jazzy).
    assert displays["rviz_default_plugins/TF"]["Marker Scale"] >= 2
    # Every topic a display subscribes to is one the node publishes, with its type.
    published = {resolve_topic(topic): kind for topic, kind in output_topics(scene).items()}
    markers = displays["rviz_default_plugins/MarkerArray"]["Topic"]
    assert markers["Value"] == resolve_topic(MARKERS_TOPIC)
    assert published[markers["Value"]] is OutputKind.MARKERS
    assert published["/tf"] is OutputKind.TF   # the TF display reads /tf and /tf_static
    # The subscription matches the publisher's QoS (reliable, volatile, keep last).
    assert (markers["Reliability Policy"], markers["Durability Policy"],
            markers["History Policy"]) == ("Reliable", "Volatile", "Keep Last")
    # RViz2 takes one array a rendered frame, slower than the node publishes: a queue
    # deeper than 1 makes the shapes trail their TF frames (seen: ~0.2 s at depth 10).
    assert markers["Depth"] == 1


def test_cmake_installs_the_rviz_config(cmake):
    assert (ROOT / "rviz" / "hecker_dynamics.rviz").is_file()
    assert re.search(r"install\(DIRECTORY [^)]*\brviz\b[^)]*DESTINATION share/", cmake)


def test_launch_file_resolves_scenes_with_the_core_rule():
    # No copy of the rule that tells a shipped scene name from a path: the launch file
    # calls the core's scene_path.
    text = (ROOT / "launch" / "dynamics.launch.py").read_text()
    assert "from hecker_dynamics.scene.load import load_scene, scene_path" in text
    assert "scene_path(LaunchConfiguration('scene').perform(context))" in text
