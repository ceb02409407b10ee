"""On a ROS 2 Jazzy machine: a session of the real node recorded with ``ros2 bag record -a``
replays with ``hecker-dynamics replay sample BAG --check --atol 0``.

The node, the recorder and the publishers are the real command-line tools, as a user runs
them (``ros2 run``, ``ros2 bag record``, ``ros2 topic pub``, ``ros2 service call``), with the
recorder started before the node, three seconds after it, and with the world services
called between the kicks (pause, step, set_body_state, resume; or bodies spawned and
deleted). Skips where ROS 2 (rclpy, the ``ros2`` command and its ``bag`` verb) or rosbags
is missing. DDS stays on this machine.
"""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest

pytest.importorskip("rclpy", reason="rclpy is not installed: these tests need ROS 2 Jazzy "
                                    "(source /opt/ros/jazzy/setup.bash)")
pytest.importorskip("rosbags", reason="rosbags is not installed (pip install rosbags)")
if shutil.which("ros2") is None:
    pytest.skip("the ros2 command is not on PATH (source /opt/ros/jazzy/setup.bash)",
                allow_module_level=True)
if subprocess.run(["ros2", "bag", "-h"], capture_output=True, timeout=60).returncode != 0:
    pytest.skip("`ros2 bag` is not installed (apt install ros-jazzy-rosbag2 "
                "ros-jazzy-rosbag2-storage-mcap)", allow_module_level=True)

from hecker_dynamics.cli import main  # noqa: E402

#: Three kicks of the README's example: zero-stamped (on arrival), and two stamped "now" by
#: `ros2 topic pub`, which arrive late after it waits for a subscriber.
KICKS = [
    "{header: {frame_id: left}, body: left, id: kick, point: {x: 0.4, y: 0.2}, "
    "wrench: {force: {x: 0.0, y: 60.0}}, duration: {sec: 0, nanosec: 100000000}}",
    "{header: {stamp: now, frame_id: world}, body: left, id: kick, point: {x: 0.1, y: 0.05}, "
    "wrench: {force: {x: 40.0, y: 5.0}}, duration: {sec: 0, nanosec: 300000000}}",
    "{header: {stamp: now, frame_id: world}, body: right, id: push, point: {x: 0.0, y: 0.0}, "
    "wrench: {force: {x: -25.0, y: 0.0}}, duration: {sec: 0, nanosec: 0}}",
]


@pytest.fixture
def ros_env(tmp_path):
    env = dict(os.environ)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    env["ROS_DOMAIN_ID"] = str(40 + os.getpid() % 150)  # away from other tests' graphs
    env["ROS_LOG_DIR"] = str(tmp_path / "log")
    return env


def _start(command: list[str], env: dict[str, str]) -> subprocess.Popen:
    """A command in a process group of its own, as a shell runs a foreground job."""
    return subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, start_new_session=True)

#: How long a `ros2` command line may take, and a process to stop, on a machine whose two
#: cores run other work too (a tick's worth of Python start-up there takes seconds).
CALL_TIMEOUT = 120
STOP_TIMEOUT = 60


def _stop(process: subprocess.Popen) -> str:
    """Ctrl-C: SIGINT to the whole group. ``ros2 run`` does not pass a signal on to the
    node it starts (it waits for a node that the terminal signals too), so a SIGINT to
    its process alone leaves the node running."""
    os.killpg(process.pid, signal.SIGINT)
    try:
        # A recorder writes its bag's metadata as it stops: on a loaded machine, in tens
        # of seconds.
        output, _ = process.communicate(timeout=STOP_TIMEOUT)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        output, _ = process.communicate()
    return output


#: World changes through the node's services, made between the kicks.
SERVICES = [
    ["/pause", "std_srvs/srv/Trigger", "{}"],
    ["/step", "hecker_dynamics/srv/Step", "{steps: 100}"],
    ["/set_body_state", "hecker_dynamics/srv/SetBodyState", "{body: right, x: 1.0, y: 3.0}"],
    ["/resume", "std_srvs/srv/Trigger", "{}"],
]


#: Bodies spawned and deleted through the node's services; the second spawn and the
#: delete of a body the spring holds are refused, and recorded so.
BODY_SERVICES = [
    ["/spawn_body", "hecker_dynamics/srv/SpawnBody",
     "{name: ball, body: '{shape: circle, radius: 0.15, mass: 1.0, position: [0.5, 4.0]}'}"],
    ["/spawn_body", "hecker_dynamics/srv/SpawnBody",
     "{name: bad, body: '{shape: circle, radius: -1.0, mass: 1.0}'}"],
    ["/delete_body", "hecker_dynamics/srv/DeleteBody", "{name: left}"],
]


@pytest.mark.parametrize("recorder_delay,services", [(0.0, False), (3.0, False), (0.0, True),
                                                     (0.0, "bodies"), (3.0, "bodies")])
def test_a_recorded_session_of_the_real_node_replays_bit_for_bit(tmp_path, ros_env,
                                                                  recorder_delay, services,
                                                                  capsys):
    bag = tmp_path / "live"
    processes = []
    if recorder_delay == 0.0:
        processes.append(_start(["ros2", "bag", "record", "-s", "mcap", "-a", "-o", str(bag)],
                                ros_env))
        time.sleep(2.0)
    node = _start(["ros2", "run", "hecker_dynamics", "dynamics_node"], ros_env)
    time.sleep(recorder_delay or 2.0)
    if recorder_delay:
        processes.append(_start(["ros2", "bag", "record", "-s", "mcap", "-a", "-o", str(bag)],
                                ros_env))
        time.sleep(2.0)
    for kick in KICKS:
        # -w 2: the node's and the recorder's subscriptions, so the recorder logs each kick
        subprocess.run(["ros2", "topic", "pub", "-w", "2", "--once", "/applied_wrench",
                        "hecker_dynamics/msg/AppliedWrench", kick], env=ros_env, check=True,
                       timeout=CALL_TIMEOUT, capture_output=True)
        time.sleep(1.0)
        calls = {True: SERVICES, "bodies": BODY_SERVICES}.get(services, [])
        if services == "bodies" and kick == KICKS[-1]:  # the ball goes again, by the end
            calls = [["/delete_body", "hecker_dynamics/srv/DeleteBody", "{name: ball}"]]
        for name, srv, request in calls:
            subprocess.run(["ros2", "service", "call", name, srv, request], env=ros_env,
                           check=True, timeout=CALL_TIMEOUT, capture_output=True)
    node_output = _stop(node)
    for process in processes:
        _stop(process)
    assert node.returncode == 0, node_output
    assert Path(bag, "metadata.yaml").is_file()
    assert main(["replay", "sample", str(bag), "--check", "--atol", "0"]) == 0, \
        capsys.readouterr().out
    assert "match:" in capsys.readouterr().out
