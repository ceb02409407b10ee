"""The node as a process and under a flood, on ROS 2 Jazzy (skips without rclpy).

- SIGINT (Ctrl-C, ``ros2 launch``'s shutdown) and SIGTERM end a running node with exit
  status 0, one info line and no traceback; a lockstep run ends the same way.
- ``/tf`` carries every body and ``/tf_static`` (transient_local) each named point.
- A real publisher floods the node with 25,000 AppliedWrench messages (good and NaN, 50
  ids); the node's reachable Python heap (tracemalloc after a collection) stays flat
  across the second half.

Run where the package is built and sourced (``colcon build``, ``source install/setup.bash``).
"""
from __future__ import annotations

import gc
import math
import os
import signal
import subprocess
import sys
import time
import tracemalloc

import pytest
from jazzy import require_jazzy

rclpy = require_jazzy()

from hecker_dynamics.msg import AppliedWrench  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402

from hecker_dynamics.ros.lifecycle import POLL_S  # noqa: E402
from hecker_dynamics.ros.node import DynamicsNode  # noqa: E402
from hecker_dynamics.scene.load import DEFAULT_SCENE, scene_path  # noqa: E402

DOMAIN_ID = 40 + (os.getpid() + 7) % 50
STARTUP_S = 30.0
#: Messages published before the flood waits for the node to take them: below the
#: subscription's keep-last depth of 10, so none is dropped.
BURST = 8


def _start_node(*ros_args: str) -> subprocess.Popen:
    env = {**os.environ, "ROS_DOMAIN_ID": str(DOMAIN_ID), "PYTHONUNBUFFERED": "1",
           "RCUTILS_LOGGING_BUFFERED_STREAM": "0"}
    code = "import sys; from hecker_dynamics.ros.node import main; sys.exit(main())"
    return subprocess.Popen([sys.executable, "-c", code, "--ros-args", *ros_args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def _wait_for_line(process: subprocess.Popen, needle: str) -> list[str]:
    lines = []
    deadline = time.monotonic() + STARTUP_S
    while time.monotonic() < deadline:
        line = process.stdout.readline()
        if not line:
            break
        lines.append(line)
        if needle in line:
            return lines
    process.kill()
    pytest.fail(f"the node never logged {needle!r}:\n{''.join(lines)}")


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
@pytest.mark.parametrize("lockstep", [False, True])
def test_a_signal_ends_the_node_with_status_zero_and_one_line(signum, lockstep):
    # The default scene's file with more outputs on (scene parameters replace the
    # ``scene`` parameter, so the file comes too).
    args = ["--params-file", str(scene_path(DEFAULT_SCENE)), "-p", "publish.markers:=true",
            "-p", "publish.diagnostics:=true"]
    if lockstep:
        args += ["-p", "lockstep:=true", "-p", "duration:=1000.0"]
    process = _start_node(*args)
    before = _wait_for_line(process, "publishing every")
    time.sleep(1.0)  # let it publish for a while (timer ticks, and /clock in lockstep)
    process.send_signal(signum)
    out, _ = process.communicate(timeout=10 * POLL_S + 10.0)
    text = "".join(before) + out
    assert process.returncode == 0, text
    assert "Traceback" not in text and "RCLError" not in text, text
    closing = [line for line in out.splitlines() if "received: shutting down" in line]
    assert len(closing) == 1 and signal.Signals(signum).name in closing[0], text


@pytest.fixture
def ros():
    context = Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    executor = SingleThreadedExecutor(context=context)
    helper = rclpy.create_node("hecker_dynamics_flood", context=context)
    executor.add_node(helper)
    yield context, executor, helper
    executor.shutdown()
    helper.destroy_node()
    rclpy.shutdown(context=context)


def _spin(executor, condition, limit_s: float = 30.0) -> None:
    deadline = time.monotonic() + limit_s
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        executor.spin_once(timeout_sec=0.01)


def test_tf_carries_every_body_and_the_named_points(ros):
    context, executor, helper = ros
    node = DynamicsNode(context=context)
    executor.add_node(node)
    dynamic: list = []
    static: list = []
    helper.create_subscription(TFMessage, "/tf", dynamic.append, 100)
    helper.create_subscription(TFMessage, "/tf_static", static.append, QoSProfile(
        depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    try:
        _spin(executor, lambda: len(dynamic) >= 3 and static)
        bodies = [b.name for b in node.scene.bodies]
        for message in dynamic:
            assert [t.child_frame_id for t in message.transforms] == bodies
            assert {t.header.frame_id for t in message.transforms} == {node.scene.frame_id}
        points = [(b.name, f"{b.name}/{p}") for b in node.scene.bodies for p in b.points]
        assert [(t.header.frame_id, t.child_frame_id) for t in static[-1].transforms] == points
    finally:
        executor.remove_node(node)
        node.destroy_node()


def _live_traced() -> int:
    """The traced heap that is still reachable: tracemalloc also counts objects in reference
    cycles that the collector has not reached yet, and during a flood those pile up between
    its rare full collections (on Jazzy, 1,500-message batches: +15 to +126 kB a batch
    without a collection, within +-5 kB after one), more the longer a loaded machine takes
    over the flood. A leak of reachable objects, like the ~115 bytes per message this test
    guards against, survives the collection."""
    gc.collect()
    return tracemalloc.get_traced_memory()[0]


def test_a_flood_from_a_real_publisher_keeps_the_node_flat(ros):
    context, executor, helper = ros
    # The default scene's file and one more output, as a user would start it: a scene
    # parameter alone (publish.markers) would be a scene of its own, with no bodies.
    node = DynamicsNode(context=context, cli_args=[
        "--ros-args", "--params-file", str(scene_path(DEFAULT_SCENE)),
        "-p", "publish.markers:=true"])
    executor.add_node(node)
    publisher = helper.create_publisher(AppliedWrench, "applied_wrench", 10)
    body = node.scene.bodies[0].name
    messages = []
    for i in range(100):
        msg = AppliedWrench(body=body, id=f"sender{i % 50}")
        msg.wrench.force.x = math.nan if i >= 50 else 1.0
        messages.append(msg)
    received = lambda: node.runner.accepted + node.runner.rejected  # noqa: E731

    def flood(count: int) -> None:
        # In bursts of BURST, each spun until the node has taken all of it: a turn of
        # rclpy's executor may run no callback at all, so publishing on with one turn per
        # message overflows the keep-last-10 reader (half the messages were lost so here).
        for start in range(0, count, BURST):
            target = received() + BURST
            for k in range(start, start + BURST):
                publisher.publish(messages[k % 100])
            _spin(executor, lambda target=target: received() >= target)
    try:
        _spin(executor, lambda: node.runner.started)
        flood(5_000)                      # warm-up: every structure at its steady size
        tracemalloc.start()
        flood(10_000)
        settled = _live_traced()
        flood(10_000)
        final = _live_traced()
        tracemalloc.stop()
        assert node.runner.accepted > 0 and node.runner.rejected > 0
        # The leak this guards against was ~115 bytes per message (1.15 MB per 10,000).
        assert final - settled < 64 * 1024, (settled, final)
    finally:
        executor.remove_node(node)
        node.destroy_node()


def _rss_bytes(pid: int) -> int:
    with open(f"/proc/{pid}/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise AssertionError("no VmRSS")


@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="needs Linux /proc")
def test_a_flood_leaves_the_node_process_resident_size_flat(ros):
    """The symptom seen on Jazzy: +115 bytes of resident memory per message received, from
    the done-callbacks that ``spin_until_future_complete`` piled on a never-done future."""
    _, executor, helper = ros
    process = _start_node()
    try:
        _wait_for_line(process, "starting the simulation")
        publisher = helper.create_publisher(AppliedWrench, "applied_wrench", 10)
        _spin(executor, lambda: publisher.get_subscription_count() > 0)
        messages = []
        for i in range(100):
            msg = AppliedWrench(body="left", id=f"sender{i % 50}")
            msg.wrench.force.x = math.nan if i >= 50 else 1.0
            messages.append(msg)

        def flood(count: int) -> None:
            for k in range(count):
                publisher.publish(messages[k % 100])
                if k % 1000 == 999:
                    time.sleep(0.05)   # about 20,000 a second: what the node keeps up with
        flood(50_000)
        settled = _rss_bytes(process.pid)
        flood(100_000)
        final = _rss_bytes(process.pid)
        # The leak would add 11 MB over these 100,000 messages.
        assert final - settled < 3 * 1024 * 1024, (settled, final)
    finally:
        process.send_signal(signal.SIGINT)
        out, _ = process.communicate(timeout=15.0)
    assert process.returncode == 0 and "Traceback" not in out, out
