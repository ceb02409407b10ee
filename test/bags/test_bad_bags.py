"""Hostile bags and bag commands: each refused in one line (exit 2), none read partly.

A bag that is corrupt, truncated or disagrees with its metadata is refused rather than
read in part; no command writes over its own input; ``--atol 0`` means bit-identical;
session times must fit a ROS stamp (int32 seconds).
"""
from __future__ import annotations

import contextlib
import errno
import os
import shutil
import socket
import sqlite3
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from hecker_dynamics.bags.compare import compare_bags
from hecker_dynamics.bags.io import (
    POSE_STAMPED,
    TWIST,
    BagError,
    BagWriter,
    default_message,
    read_bag,
)
from hecker_dynamics.cli import main
from hecker_dynamics.ros import fields
from hecker_dynamics.scene.load import load_scene

GOLDEN = Path(__file__).resolve().parents[1] / "golden"
SEC = 1_000_000_000


def _cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _one_line_error(capsys, *argv: str) -> str:
    code, out, err = _cli(capsys, *argv)
    assert code == 2, (out, err)
    assert err.count("\n") == 1 and err.startswith("hecker-dynamics: error: "), err
    return err


@pytest.fixture
def sample_out(tmp_path) -> Path:
    """A copy of the sample scene's golden output bag."""
    path = tmp_path / "out"
    shutil.copytree(GOLDEN / "sample" / "output", path)
    return path


def _metadata(bag: Path) -> dict:
    return yaml.safe_load((bag / "metadata.yaml").read_text())


def _set_metadata(bag: Path, change) -> None:
    info = _metadata(bag)
    change(info["rosbag2_bagfile_information"])
    (bag / "metadata.yaml").write_text(yaml.safe_dump(info))


# ------------------------------------------------------------------ the writer

@pytest.mark.parametrize("output", ["/proc/x", "/", ".", "..", "/proc/self/x/y"])
def test_writer_refuses_outputs_it_cannot_create(tmp_path, capsys, output, monkeypatch):
    # An empty -o is argparse's refusal (test_output_paths.py: an empty path).
    monkeypatch.chdir(tmp_path)
    err = _one_line_error(capsys, "script", "sample", "-o", output, "--overwrite")
    assert "Traceback" not in err


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes anywhere")
def test_writer_refuses_an_unwritable_directory(tmp_path, capsys):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        err = _one_line_error(capsys, "script", "sample", "-o", str(locked / "bag"))
        assert str(locked / "bag") in err
    finally:
        locked.chmod(0o700)


def test_a_file_where_the_partial_directory_goes_is_replaced(tmp_path, capsys):
    """The temporary '.<name>.partial' is the writer's own: a stale file there (a killed
    run) is removed, a directory too; the bag is then written."""
    (tmp_path / ".bag.partial").write_text("stale")
    code, _, err = _cli(capsys, "script", "sample", "-o", str(tmp_path / "bag"))
    assert code == 0, err
    assert read_bag(tmp_path / "bag").messages
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]


@pytest.mark.skipif(sys.platform == "win32", reason="no flock: a killed writer's files stay")
def test_a_killed_writers_files_are_removed_by_the_next_and_a_live_ones_kept(tmp_path):
    """A writer killed with SIGKILL cannot clean up: the next writer of the bag removes its
    temporary directory (whose lock no process holds now), and leaves a live writer's."""
    path = tmp_path / "bag"
    killed = subprocess.Popen(
        [sys.executable, "-c", "import sys, time; from hecker_dynamics.bags.io import "
         "BagWriter; BagWriter(sys.argv[1]).open(); print(flush=True); time.sleep(60)",
         str(path)], stdout=subprocess.PIPE, text=True)
    try:
        assert killed.stdout.readline() == "\n"
    finally:
        killed.kill()
        killed.wait()
    left = [p.name for p in tmp_path.iterdir()]
    assert len(left) == 1 and left[0].startswith(".bag.partial-")
    live = BagWriter(tmp_path / "other")  # a live writer of another bag ...
    live.open()
    same = BagWriter(path, overwrite=True)  # ... and of this one
    same.open()
    _pose_bag(path, 3.0)  # writes and closes a third writer of the bag
    assert _pose_of(path) == 3.0
    names = sorted(p.name for p in tmp_path.iterdir())
    assert left[0] not in names and len(names) == 3  # bag, other's and same's directories
    same.abort()
    live.abort()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]
    # Kept: a writer's of another host (a lock there says nothing here), and a directory
    # whose lock is no file (a FIFO, which an open for reading would wait on forever).
    elsewhere, fifo = tmp_path / ".bag.partial-elsewhere", tmp_path / ".bag.partial-fifo"
    elsewhere.mkdir()
    (elsewhere / "writer.lock").write_text(socket.gethostname() + ".other")
    fifo.mkdir()
    os.mkfifo(fifo / "writer.lock")
    _pose_bag(tmp_path / "again", 4.0)
    writer = BagWriter(path, overwrite=True)
    writer.open()
    writer.abort()
    assert elsewhere.exists() and fifo.exists()


def test_a_bag_overwritten_by_a_writer_that_fails_at_the_end_is_kept(tmp_path, monkeypatch):
    """--overwrite moves the old bag aside before the new one takes its name; when that
    last move fails, the old bag goes back (it was removed with the writer's files)."""
    import hecker_dynamics.bags.io as io
    path = tmp_path / "bag"
    _pose_bag(path, 1.0)
    writer = BagWriter(path, overwrite=True)
    writer.open()
    writer.write("/b/pose", POSE_STAMPED, SEC, _pose_message(2.0))
    replace = os.replace

    def failing(source, target):
        if Path(target) == path and Path(source).name == "bag":
            raise OSError(errno.EXDEV, "Invalid cross-device link")
        return replace(source, target)
    monkeypatch.setattr(io.os, "replace", failing)
    with pytest.raises(BagError, match=r"bag: cannot finish the bag \(Invalid cross-device "):
        writer.close()
    assert _pose_of(path) == 1.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]


# ------------------------------------------------------------------ stamps

def test_script_start_past_what_a_stamp_holds_is_refused(tmp_path, capsys):
    err = _one_line_error(capsys, "script", "sample", "-o", str(tmp_path / "b"),
                          "--start", "3e9")
    assert "--start" in err and "2147483647" in err
    assert not (tmp_path / "b").exists()
    err = _one_line_error(capsys, "script", "sample", "-o", str(tmp_path / "b"),
                          "--duration", "1e18")
    assert "--duration" in err


@pytest.mark.parametrize("key, value, fragment", [
    ("start_ns", "3000000000000000000", "start"), ("start_ns", "-5000000000", "start"),
    ("duration_ns", "100000000000000000000", "duration"),
])
def test_bag_session_times_past_a_stamp_are_refused_naming_the_bag(
        tmp_path, capsys, key, value, fragment):
    bag = tmp_path / "in"
    shutil.copytree(GOLDEN / "sample" / "input", bag)
    _set_metadata(bag, lambda info: info["custom_data"].__setitem__(
        f"hecker_dynamics.{key}", value))
    err = _one_line_error(capsys, "replay", "sample", str(bag), "-o", str(tmp_path / "o"))
    assert str(bag) in err and fragment in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("value, words", [
    ("-1700000000750000001", "start -1700000000.750000001 s is before 0"),
    ("3000000000750000001", "start 3000000000.750000001 s is after 2147483647 s"),
])
def test_refused_session_times_are_named_to_the_nanosecond(tmp_path, capsys, value, words):
    """The refusal names the recorded start exactly, as --start reads it back (through a
    double, 3000000000.750000001 s printed as 3.0e9 or 3000000000.750000000)."""
    bag = tmp_path / "in"
    shutil.copytree(GOLDEN / "sample" / "input", bag)
    _set_metadata(bag, lambda info: info["custom_data"].__setitem__(
        "hecker_dynamics.start_ns", value))
    err = _one_line_error(capsys, "replay", "sample", str(bag), "-o", str(tmp_path / "o"))
    assert words in err


@pytest.mark.parametrize("duration_ns", ["999999", "0"])
def test_a_recorded_session_shorter_than_one_step_is_refused(tmp_path, capsys, duration_ns):
    """A bag whose custom data records a session shorter than one step (1 ms) would replay
    no step: a bag of no output written with exit 0, or a check failing on every recorded
    output as missing. Refused in one line, as a --duration that short is."""
    recording = tmp_path / "rec"
    assert main(["replay", "sample", str(GOLDEN / "sample" / "input"), "-o", str(recording),
                 "--with-inputs"]) == 0
    _set_metadata(recording, lambda info: info["custom_data"].__setitem__(
        "hecker_dynamics.duration_ns", duration_ns))
    for extra in (["-o", str(tmp_path / "o")], ["--check"]):
        err = _one_line_error(capsys, "replay", "sample", str(recording), *extra)
        assert err == (f"hecker-dynamics: error: {recording}: the session's duration "
                       f"{int(duration_ns) * 1e-9:g} s is shorter than one step (0.001 s): "
                       "no step would be taken\n")
        assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("topic", ["/applied_wrench", "/nope"])
def test_a_topic_that_is_no_output_is_refused_before_the_replay(tmp_path, capsys, topic,
                                                                monkeypatch):
    """--topic naming no output of the scene (an input topic, a typo) is a usage error,
    found before the replay runs: it was refused only after the whole replay, its line
    already printed."""
    import sys

    recording = str(tmp_path / "rec")
    assert main(["replay", "sample", str(GOLDEN / "sample" / "input"), "-o", recording,
                 "--with-inputs"]) == 0
    capsys.readouterr()

    def no_replay(*args, **kwargs):
        raise AssertionError("replayed")
    monkeypatch.setattr(sys.modules["hecker_dynamics.bags.replay"], "replay_outputs", no_replay)
    code, out, err = _cli(capsys, "replay", "sample", recording, "--check", "--topic", topic)
    assert (code, out) == (2, "")
    assert err == (f"hecker-dynamics: error: --topic {topic}: not an output the node "
                   f"publishes for {load_scene('sample').source} (its "
                   "outputs: /left/pose, /left/twist, /right/pose, /right/twist)\n")
    code, out, err = _cli(capsys, "regress", recording, "--topic", topic)
    assert code == 2 and "not an output the node publishes" in out + err


def test_replay_start_past_the_bag_is_refused(tmp_path, capsys):
    """--start past the bag's end (its last message and recorded session, 4 s) would
    replay none of it: refused in one line, no bag written, rather than a silent run of
    the scene alone (or a check that can only fail)."""
    recording = str(tmp_path / "rec")
    assert main(["replay", "sample", str(GOLDEN / "sample" / "input"), "-o", recording,
                 "--with-inputs"]) == 0
    for extra in (["-o", str(tmp_path / "o")], ["--check"]):
        err = _one_line_error(capsys, "replay", "sample", recording, "--start", "100", *extra)
        assert "--start 100 s" in err and "after the end of the bag, at 4 s" in err
        assert not (tmp_path / "o").exists()
    code, _, err = _cli(capsys, "replay", "sample", recording, "--start", "4", "--duration",
                        "0.001", "-o", str(tmp_path / "o"))  # the end itself is in the bag
    assert code == 0, err


# ------------------------------------------------------------------ metadata and storage

@pytest.mark.parametrize("count", [0, -5, "many", 1e12, 2000, 2002])
def test_message_count_must_match_what_was_read(sample_out, capsys, count):
    _set_metadata(sample_out, lambda info: info.__setitem__("message_count", count))
    err = _one_line_error(capsys, "compare", str(sample_out), str(GOLDEN / "sample" / "output"))
    assert str(sample_out) in err and "message_count" in err


def test_topic_message_count_must_match_what_was_read(sample_out, capsys):
    def change(info):
        info["topics_with_message_count"][0]["message_count"] += 1
    _set_metadata(sample_out, change)
    err = _one_line_error(capsys, "compare", str(sample_out), str(GOLDEN / "sample" / "output"))
    assert "message_count" in err


def _edit_file_entry(key, value):
    def change(info):
        entry = info["files"][0]
        if isinstance(entry[key], dict):
            (inner,) = entry[key]
            entry[key][inner] += value
        elif isinstance(value, str):
            entry[key] = value
        else:
            entry[key] += value
    return change


@pytest.mark.parametrize("command", ["compare", "replay"])
@pytest.mark.parametrize("key, value, fragment", [
    ("message_count", -1, "files hold {less} messages but the bag message_count {total};"),
    ("message_count", 1, "files hold {more} messages but the bag message_count {total};"),
    ("message_count", "many", "message_count of file '{file}' in the metadata is 'many'"),
    ("starting_time", 1, "span other times than the bag"),
    ("duration", -1, "span other times than the bag"),
    ("path", "other.mcap", "files (other.mcap) are not its relative_file_paths")])
def test_an_edited_file_entry_of_the_metadata_is_refused(tmp_path, sample_out, capsys, command,
                                                          key, value, fragment):
    """rosbag2's per-file entries (``files``) must add up to the bag: a per-file message
    count edited by one (or the file's times, or its name) is named in one line by
    ``compare`` and ``replay --check``, never a match."""
    golden = str(GOLDEN / "sample" / "output")
    if command == "compare":
        bag, argv = sample_out, ["compare", str(sample_out), golden]
    else:  # a session recorded with its inputs, which its check passes untouched
        bag = tmp_path / "recording"
        assert main(["replay", "sample", str(GOLDEN / "sample" / "input"), "-o", str(bag),
                     "--with-inputs", "--no-progress"]) == 0
        argv = ["replay", "sample", str(bag), "--check"]
        assert main(argv) == 0
        capsys.readouterr()
    info = _metadata(bag)["rosbag2_bagfile_information"]
    total, file = info["message_count"], info["files"][0]["path"]
    _set_metadata(bag, _edit_file_entry(key, value))
    err = _one_line_error(capsys, *argv)
    expected = fragment.format(less=total - 1, more=total + 1, total=total, file=file)
    assert str(bag) in err and expected in err, err


def test_empty_relative_file_paths_is_refused(sample_out, capsys):
    _set_metadata(sample_out, lambda info: info.__setitem__("relative_file_paths", []))
    err = _one_line_error(capsys, "replay", "sample", str(sample_out), "--check")
    assert str(sample_out) in err


def test_every_single_bit_flip_of_an_mcap_is_refused_or_read_whole(sample_out):
    """Flip one bit at each of 200 places spread over the file: the bag is refused, or
    read whole: every message of every topic. Never a part of it. (A flip inside a
    payload or a log time can go unseen: rosbags writes no CRCs, 0 in every chunk and the
    data end, so no reader can tell; the counts and the log-time span are checked.)"""
    original = read_bag(sample_out)
    mcap = sample_out / "output.mcap"
    data = mcap.read_bytes()
    rng = np.random.default_rng(15)
    refused = 0
    for offset in rng.choice(len(data), 200, replace=False):
        flipped = bytearray(data)
        flipped[offset] ^= 1 << int(rng.integers(8))
        mcap.write_bytes(bytes(flipped))
        try:
            bag = read_bag(sample_out)
        except BagError as error:
            assert "\n" not in str(error)
            refused += 1
            continue
        assert sorted((m.topic, len(m.raw)) for m in bag.messages) == \
            sorted((m.topic, len(m.raw)) for m in original.messages), offset
    assert refused  # a flip in the framing (magic, opcodes, lengths) is always seen


# ------------------------------------------------------------------ replay and compare

def test_replay_never_writes_over_its_input(tmp_path, capsys, sample_out):
    before = {p.name: p.read_bytes() for p in sample_out.iterdir()}
    for output in (sample_out, tmp_path, sample_out / "sub", Path(str(sample_out) + "/")):
        err = _one_line_error(capsys, "replay", "sample", str(sample_out), "-o", str(output),
                              "--overwrite")
        assert "input" in err
    assert {p.name: p.read_bytes() for p in sample_out.iterdir()} == before


def _pose_message(x: float) -> Any:
    from hecker_dynamics.bags.io import pose_stamped_message
    pose = fields.Pose((x, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    return pose_stamped_message(fields.PoseStampedFields(fields.Header(1, 0, "world"), pose))


def _pose_bag(path: Path, x: float) -> None:
    with BagWriter(path, "mcap") as writer:
        writer.write("/b/pose", POSE_STAMPED, SEC, _pose_message(x))


def _pose_of(path: Path) -> float:
    return float(read_bag(path).on("/b/pose")[0].decode().pose.position.x)


def test_two_writers_of_one_bag_never_mix_their_files(tmp_path):
    """Two commands writing one bag at once: the second took the first's temporary
    directory for a killed run's and removed it, and the first then said it wrote the bag
    it had lost (a 43-byte mcap beside its metadata). Each writes its own; the last to
    finish with --overwrite leaves its bag whole, and one without --overwrite refuses to
    remove a bag made while it ran."""
    path = tmp_path / "bag"
    message = _pose_message(1.0)
    first, second = BagWriter(path, overwrite=True), BagWriter(path, overwrite=True)
    first.open()
    second.open()  # once removed the first's files
    first.write("/b/pose", POSE_STAMPED, SEC, message)
    second.abort()  # a refused replay's
    first.close()
    assert _pose_of(path) == 1.0
    shutil.rmtree(path)
    late = BagWriter(path)
    late.open()
    _pose_bag(path, 2.0)  # another command's bag, written meanwhile over the first
    with pytest.raises(BagError, match=r"bag exists \(made while this ran\); remove it or "
                                       r"pass --overwrite$"):
        late.close()
    assert _pose_of(path) == 2.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]


def test_a_writer_that_cannot_lock_or_open_leaves_nothing_and_keeps_no_lock(tmp_path,
                                                                            monkeypatch):
    """A file system without locks (NFS without its lock daemon: ENOLCK) still takes a
    bag, written unlocked; a failure once the directory is made (its lock, or the storage
    writer's) leaves no directory behind, which no later writer could tell from a live
    one's, and no lock file open."""
    import errno

    import hecker_dynamics.bags.io as io
    if io.fcntl is None:
        pytest.skip("no flock: a writer takes no lock")
    opened = set(os.listdir("/proc/self/fd")) if Path("/proc/self/fd").is_dir() else None

    class NoLocks:
        LOCK_EX, LOCK_NB = io.fcntl.LOCK_EX, io.fcntl.LOCK_NB

        @staticmethod
        def flock(fd: int, operation: int) -> None:
            raise OSError(errno.ENOLCK, os.strerror(errno.ENOLCK))

    with monkeypatch.context() as patched:
        patched.setattr(io, "fcntl", NoLocks)
        _pose_bag(tmp_path / "bag", 1.0)
    assert _pose_of(tmp_path / "bag") == 1.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]

    def no_room(directory: Path) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    with monkeypatch.context() as patched:
        patched.setattr(io, "_hold_writer_lock", no_room)
        with pytest.raises(BagError, match=r"other: cannot create the bag \(No space left"):
            BagWriter(tmp_path / "other").open()
    import rosbags.rosbag2

    def no_writer(*args, **kwargs):
        raise OSError(errno.EACCES, os.strerror(errno.EACCES))
    with monkeypatch.context() as patched:
        patched.setattr(rosbags.rosbag2, "Writer", no_writer)
        with pytest.raises(BagError, match=r"other: cannot create the bag \(.*denied"):
            BagWriter(tmp_path / "other").open()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]
    if opened is not None:
        assert set(os.listdir("/proc/self/fd")) <= opened


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="reads /proc/self/fd")
def test_a_writer_lets_go_of_its_lock_before_removing_its_directory(tmp_path, monkeypatch):
    """NFS keeps a removed file that is still open as a '.nfs*' file in its directory, which
    then cannot be removed: every bag written there left a directory no writer removes."""
    import hecker_dynamics.bags.io as io
    if io.fcntl is None:
        pytest.skip("no flock: a writer takes no lock")
    removed = []
    rmtree = shutil.rmtree

    def checked(path, *args, **kwargs):
        held = [os.readlink(f"/proc/self/fd/{fd}") for fd in os.listdir("/proc/self/fd")
                if os.path.islink(f"/proc/self/fd/{fd}")]
        assert not any(link.startswith(str(path)) for link in held), held
        removed.append(Path(path).name)
        return rmtree(path, *args, **kwargs)
    monkeypatch.setattr(io.shutil, "rmtree", checked)
    killed = tmp_path / ".bag.partial-killed"
    killed.mkdir()
    (killed / "writer.lock").write_text(socket.gethostname())  # no process holds its lock
    _pose_bag(tmp_path / "bag", 1.0)
    writer = BagWriter(tmp_path / "bag", overwrite=True)
    writer.open()
    writer.abort()
    assert removed[0] == killed.name and len(removed) == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]


@pytest.mark.parametrize("atol", ["0", "1e-9", "1"])
@pytest.mark.parametrize("x", [float("nan"), float("inf"), float("-inf")])
def test_a_pose_that_is_not_finite_in_both_bags_is_never_a_match(tmp_path, capsys, atol, x):
    """The same NaN or infinite position in both bags is no state of a run (the divergence
    check stops one before it publishes it): --atol 0 took the equal bytes as a match, and
    any tolerance took equal infinities (0 apart)."""
    _pose_bag(tmp_path / "a", x)
    _pose_bag(tmp_path / "b", x)
    code, out, _ = _cli(capsys, "compare", str(tmp_path / "a"), str(tmp_path / "b"),
                        "--atol", atol)
    assert code == 1 and out.splitlines()[-1] == "MISMATCH", out
    assert "at 1 s: a position, angle or velocity that is not finite (NaN or " \
           "infinite) in both bags" in out


@pytest.mark.parametrize("atol", ["0", "1"])
@pytest.mark.parametrize("x", [float("nan"), float("inf")])
@pytest.mark.parametrize("msgtype, field_name", [
    ("sensor_msgs/msg/JointState", "velocity"), ("sensor_msgs/msg/JointState", "effort"),
    ("hecker_dynamics/msg/ContactEvent", "normal_impulse")])
def test_a_joint_state_or_impulse_not_finite_in_both_bags_is_never_a_match(
        tmp_path, capsys, atol, x, msgtype, field_name):
    """A joint state or contact event, compared byte for byte, with the same NaN or
    infinity in both bags: it matched, as a pose did before."""
    msg = default_message(msgtype)
    msg.header.stamp.sec = 1
    if msgtype == "sensor_msgs/msg/JointState":
        msg.name = ["hinge"]
        msg.position, msg.velocity, msg.effort = (np.zeros(1) for _ in range(3))
        getattr(msg, field_name)[0] = x
    else:
        setattr(msg, field_name, x)
    for name in "ab":
        with BagWriter(tmp_path / name) as writer:
            writer.write("/topic", msgtype, SEC, msg)
    code, out, _ = _cli(capsys, "compare", str(tmp_path / "a"), str(tmp_path / "b"),
                        "--atol", atol)
    assert code == 1 and out.splitlines()[-1] == "MISMATCH", out
    assert "at 1 s: a number that is not finite (NaN or infinite) in both bags" in out


def test_atol_zero_is_bit_identical(tmp_path, capsys):
    _pose_bag(tmp_path / "a", 0.0)
    _pose_bag(tmp_path / "b", 7.3e-304)
    code, out, _ = _cli(capsys, "compare", str(tmp_path / "a"), str(tmp_path / "b"),
                        "--atol", "0")
    assert code == 1, out
    report, ok = compare_bags(tmp_path / "a", tmp_path / "b", atol=0.0)
    assert not ok and report.largest()["position"] == 7.3e-304
    _pose_bag(tmp_path / "c", 0.0)
    assert _cli(capsys, "compare", str(tmp_path / "a"), str(tmp_path / "c"),
                "--atol", "0")[0] == 0


def test_another_type_hash_is_a_mismatch(sample_out, capsys):
    """A topic whose type hash (RIHS01, the message definition's) differs between the bags
    holds messages of another definition: a type mismatch, not a match of their bytes."""
    def change(info):
        entry = info["topics_with_message_count"][0]["topic_metadata"]
        entry["type_description_hash"] = "RIHS01_" + "0" * 64
    _set_metadata(sample_out, change)
    code, out, _ = _cli(capsys, "compare", str(GOLDEN / "sample" / "output"), str(sample_out))
    assert code == 1 and f"expected, RIHS01_{'0' * 64} actual" in out and "MISMATCH" in out


def test_two_bags_without_messages_are_no_match(tmp_path, capsys):
    """Two emptied bags (or bags whose topics hold nothing) compare nothing: refused in one
    line rather than reported as a match of 0 messages."""
    for name in ("a", "b"):
        with BagWriter(tmp_path / name, "mcap") as writer:
            writer.add_topic("/b/pose", POSE_STAMPED)
    err = _one_line_error(capsys, "compare", str(tmp_path / "a"), str(tmp_path / "b"))
    assert "neither bag holds a message; nothing to compare" in err
    err = _one_line_error(capsys, "compare", str(tmp_path / "a"), str(tmp_path / "b"),
                          "--topic", "/b/pose")
    assert "neither bag holds a message on the topics given" in err
    _pose_bag(tmp_path / "c", 0.0)  # one side's message: a mismatch, not an error
    code, out, _ = _cli(capsys, "compare", str(tmp_path / "a"), str(tmp_path / "c"))
    assert code == 1 and "MISMATCH" in out


def test_a_message_that_cannot_be_decoded_is_named_with_its_bag(tmp_path, capsys):
    """A pose emptied of its bytes in one of two bags compared: the error names that bag
    (it named only the message, so which bag was broken was a guess)."""
    good = GOLDEN / "sample" / "output"
    broken = tmp_path / "broken"
    original = read_bag(good)
    with BagWriter(broken, "mcap") as writer:
        for topic, msgtype in original.topics.items():
            writer.add_topic(topic, msgtype)
        for message in original.messages:
            writer.write_raw(message.topic, message.log_ns,
                             b"" if message.index == 12 else message.raw)
    for argv in ([str(good), str(broken)], [str(broken), str(good)]):
        err = _one_line_error(capsys, "compare", *argv)
        assert err.startswith(f"hecker-dynamics: error: {broken}: message 12 on "), err


def test_a_nan_difference_is_the_largest_overall(tmp_path):
    pose = fields.Pose((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    from hecker_dynamics.bags.io import pose_stamped_message
    for name, (a, b) in {"expected": (0.0, 0.0), "actual": (1e-3, float("nan"))}.items():
        with BagWriter(tmp_path / name, "mcap") as writer:
            for topic, x in (("/a/pose", a), ("/b/pose", b)):
                writer.write(topic, POSE_STAMPED, SEC, pose_stamped_message(
                    fields.PoseStampedFields(fields.Header(1, 0, "world"),
                                             pose._replace(position=(x, 0.0, 0.0)))))
    report, ok = compare_bags(tmp_path / "expected", tmp_path / "actual", atol=1.0)
    assert not ok
    assert np.isnan(report.largest()["position"])  # not the 1e-3 of the topic before it
    assert "largest overall: position nan," in report.text()


def test_a_topic_in_neither_bag_is_an_error_saying_so(capsys):
    bag = str(GOLDEN / "sample" / "output")
    err = _one_line_error(capsys, "compare", bag, bag, "--topic", "/nope")
    assert "/nope" in err and "neither" in err


def test_a_check_that_compares_no_output_is_a_mismatch(tmp_path, capsys):
    """A recording of a session one step long (shorter than a publish period), and one whose
    output topics hold nothing checked with --partial: the check compares no output, so it
    fails (exit 1) rather than report a match of 0 of 0 recorded outputs."""
    script = str(tmp_path / "in")
    assert main(["script", "sample", "-o", script]) == 0
    instant = str(tmp_path / "instant")
    assert main(["replay", "sample", script, "-o", instant, "--with-inputs", "--start", "2",
                 "--duration", "0.001"]) == 0
    emptied = tmp_path / "emptied"
    with BagWriter(emptied, "mcap", custom_data=read_bag(script).custom_data) as writer:
        for body in ("left", "right"):
            writer.add_topic(f"/{body}/pose", POSE_STAMPED)
            writer.add_topic(f"/{body}/twist", TWIST)
        for message in read_bag(script).messages:
            writer.add_topic(message.topic, message.msgtype)
            writer.write_raw(message.topic, message.log_ns, message.raw)
    for argv in ([instant, "--check"], [str(emptied), "--check", "--partial"]):
        capsys.readouterr()
        code, out, err = _cli(capsys, "replay", "sample", *argv)
        assert code == 1 and "Traceback" not in err
        assert out.splitlines()[-1] == (
            f"check against the recording {argv[0]}: mismatch: nothing to check: the "
            "recording holds no output of the node in the span replayed, nor a keyframe")


def test_a_pose_logged_out_of_order_is_blamed_on_its_topic(tmp_path, capsys):
    """Two poses of /left/pose swapped in log order: the check names /left/pose, out of
    order, and not /left/twist (whose twists were placed by the poses' log order)."""
    script, recording = str(tmp_path / "in"), tmp_path / "rec"
    assert main(["script", "sample", "-o", script]) == 0
    assert main(["replay", "sample", script, "-o", str(recording), "--with-inputs"]) == 0
    messages = read_bag(recording).messages
    first, second = [i for i, m in enumerate(messages) if m.topic == "/left/pose"][5:7]
    order = list(range(len(messages)))
    order[first], order[second] = second, first
    swapped = tmp_path / "swapped"
    source = read_bag(recording)
    with BagWriter(swapped, "mcap", custom_data=source.custom_data) as writer:
        for topic, msgtype in source.topics.items():
            writer.add_topic(topic, msgtype)
        for place, index in enumerate(order):  # the log times stay; the payloads swap
            writer.write_raw(messages[index].topic, messages[place].log_ns,
                             messages[index].raw)
    capsys.readouterr()
    code, out, _ = _cli(capsys, "replay", "sample", str(swapped), "--check")
    assert code == 1
    verdict = out.splitlines()[-1]
    assert verdict.endswith("mismatch: /left/pose: 1 logged after a later stamp (out of "
                            "order), first stamped 0.12 s"), verdict


def _two_connection_bag(recording: Path, path: Path, storage: str, msgtype: str,
                        rihs01: str | None) -> None:
    """``recording`` again with every other /left/pose message on a second connection of
    that topic (as two publishers, or a merge of two recordings, make), of ``msgtype``
    with the type hash ``rihs01`` (None: this package's)."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    from hecker_dynamics.bags.io import BAG_VERSION, latched_qos, typestore

    source = read_bag(recording)
    writer = Writer(path, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP
                    if storage == "mcap" else StoragePlugin.SQLITE3)
    for key, value in source.custom_data.items():
        writer.set_custom_data(key, value)
    writer.open()
    connections = {topic: writer.add_connection(topic, kind, typestore=typestore())
                   for topic, kind in source.topics.items()}
    # Another publisher's QoS, as rosbag2 records a second publisher on a topic.
    second = writer.add_connection(
        "/left/pose", msgtype, typestore=typestore(), offered_qos_profiles=latched_qos(1),
        msgdef=typestore().generate_msgdef(msgtype, ros_version=2)[0], rihs01=rihs01)
    poses = 0
    for message in source.messages:
        poses += message.topic == "/left/pose"
        on_second = message.topic == "/left/pose" and poses % 2 == 0
        writer.write(second if on_second else connections[message.topic], message.log_ns,
                     message.raw)
    writer.close()


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
@pytest.mark.parametrize("msgtype, rihs01, fragment", [
    ("geometry_msgs/msg/Pose", None, "has two types, geometry_msgs/msg/PoseStamped and "
                                     "geometry_msgs/msg/Pose"),
    (POSE_STAMPED, "RIHS01_" + "ab" * 32, f"has two definitions of {POSE_STAMPED}, type "
                                          "hashes RIHS01_")])
def test_two_connections_of_a_topic_that_disagree_are_refused(tmp_path, capsys, storage,
                                                              msgtype, rihs01, fragment):
    """A topic on two connections of different types or type hashes: which definition its
    messages have is unknown, so every command refuses the bag in one line rather than
    decode the second connection's messages as the first one's (it said "match" when only
    the second connection's hash was foreign; the first one's is checked)."""
    script, recording = str(tmp_path / "in"), tmp_path / "rec"
    assert main(["script", "sample", "-o", script]) == 0
    assert main(["replay", "sample", script, "-o", str(recording), "--with-inputs"]) == 0
    bag = tmp_path / "two"
    _two_connection_bag(recording, bag, storage, msgtype, rihs01)
    capsys.readouterr()
    for argv in (["replay", "sample", str(bag), "--check"], ["compare", str(recording), str(bag)],
                 ["compare", str(bag), str(recording)]):
        err = _one_line_error(capsys, *argv)
        assert f"{bag}: topic '/left/pose' {fragment}" in err, err
    code, out, _ = _cli(capsys, "regress", str(bag), "--scene", "sample", "--workers", "1")
    assert code == 2 and out.splitlines()[0].startswith("ERROR") and fragment in out, out


def test_a_twist_and_a_pose_lost_at_other_instants_leave_the_rest_in_place(tmp_path, capsys):
    """A bag logged at sim time that lost /left/twist at 0.42 s and /left/pose at 6.02 s:
    each twist is compared with the replay's at its own instant. Placed by the i-th
    pose's stamp instead, every twist in between met its neighbour's values and the
    check failed on velocities the replay never published otherwise."""
    script, recording = str(tmp_path / "in"), tmp_path / "rec"
    assert main(["script", "sample", "-o", script]) == 0
    assert main(["replay", "sample", script, "-o", str(recording), "--with-inputs"]) == 0
    source = read_bag(recording)
    lost = {("/left/twist", 420_000_000), ("/left/pose", 6_020_000_000)}
    assert lost <= {(m.topic, m.log_ns) for m in source.messages}
    lossy = tmp_path / "lossy"
    with BagWriter(lossy, "mcap", custom_data=source.custom_data) as writer:
        for topic, msgtype in source.topics.items():
            writer.add_topic(topic, msgtype)
        for message in source.messages:
            if (message.topic, message.log_ns) not in lost:
                writer.write_raw(message.topic, message.log_ns, message.raw)
    capsys.readouterr()
    code, out, _ = _cli(capsys, "replay", "sample", str(lossy), "--check", "--partial",
                        "--atol", "0")
    assert code == 0, out
    verdict = out.splitlines()[-1]
    assert "/left/twist: 1 outputs of the replay not recorded, at 0.420000000 s" in verdict
    assert "/left/pose: 1 outputs of the replay not recorded, at 6.020000000 s" in verdict
    code, out, _ = _cli(capsys, "compare", str(recording), str(lossy), "--topic",
                        "/left/twist", "--atol", "0")
    assert code == 1
    assert "/left/twist (geometry_msgs/msg/Twist): 499 matched of 500 expected / 499 " \
        "actual\n     missing 1: first at 0.42 s\nlargest overall: position 0, angle 0, " \
        "velocity 0, angular_velocity 0\nMISMATCH" in out, out


@pytest.mark.parametrize("overwrite", [[], ["--overwrite"]])
def test_a_broken_symlink_as_the_output_bag_is_refused_before_the_replay(
        tmp_path, capsys, overwrite):
    """``-o LINK`` with LINK dangling: one line before any work. It replayed the whole
    session, then said the name was made while it ran."""
    link = tmp_path / "out"
    link.symlink_to(tmp_path / "elsewhere" / "bag")
    for argv in (["script", "sample"], ["replay", "sample", str(GOLDEN / "sample" / "input")]):
        code, out, err = _cli(capsys, *argv, "-o", str(link), *overwrite)
        assert (code, out) == (2, "")
        assert err == f"hecker-dynamics: error: {link} is a broken symlink or a symlink " \
                      "loop; remove it or give another name\n"
        assert os.readlink(link) == str(tmp_path / "elsewhere" / "bag")


def test_two_bags_without_a_topic_in_common_are_no_match(tmp_path, capsys):
    """A scene's inputs compared with its outputs share no topic: refused in one line
    rather than reported as topics missing beside a largest difference of 0. A topic in
    both whose types differ compares no message: its report says so, not 0."""
    golden = GOLDEN / "sample"
    err = _one_line_error(capsys, "compare", str(golden / "output"), str(golden / "input"))
    assert "have no topic in common" in err and "/applied_wrench" in err \
        and "/left/pose" in err and err.rstrip().endswith("nothing to compare")
    with BagWriter(tmp_path / "twist", "mcap") as writer:
        writer.write("/b/pose", TWIST, SEC, default_message(TWIST))
    _pose_bag(tmp_path / "pose", 0.0)
    code, out, _ = _cli(capsys, "compare", str(tmp_path / "pose"), str(tmp_path / "twist"))
    assert code == 1 and "TYPE MISMATCH /b/pose" in out
    assert "largest overall: none (no message of one bag matched one of the other)" in out


@pytest.mark.parametrize("argv, words", [
    (["script", "sample", "-o", "{out}", "--storage", "sqlite3", "--compress"],
     "--compress compresses mcap chunks; --storage sqlite3 has none"),
    (["replay", "sample", "{input}", "-o", "{out}", "--storage", "sqlite3", "--compress"],
     "--compress compresses mcap chunks; --storage sqlite3 has none"),
    (["replay", "sample", "{output}", "--check", "--overwrite"], "say how -o writes its bag"),
    (["replay", "sample", "{output}", "--check", "--storage", "sqlite3"],
     "say how -o writes its bag"),
    # mcap is the default, and given by name it is an option all the same
    (["replay", "sample", "{output}", "--check", "--storage", "mcap"],
     "say how -o writes its bag"),
    (["replay", "sample", "{output}", "--check", "--with-inputs"], "say how -o writes its bag"),
])
def test_options_that_would_change_nothing_are_refused(tmp_path, capsys, argv, words):
    """--compress with sqlite3 storage wrote an uncompressed bag without a word, and the
    options of -o's bag given to a --check without -o did nothing: refused in one line,
    before any work, nothing written."""
    paths = {"out": str(tmp_path / "out"), "input": str(GOLDEN / "sample" / "input"),
             "output": str(GOLDEN / "sample" / "output")}
    err = _one_line_error(capsys, *(arg.format(**paths) for arg in argv))
    assert words in err
    assert not (tmp_path / "out").exists()


#: Flips a bit of every /left/pose message of the sqlite3 bag argv[1] in one transaction,
#: in journal mode argv[2], and ends without closing the database: a write-ahead log (WAL)
#: that holds the committed change, or a rollback journal (DELETE, pages spilled into the
#: file) that holds the old pages of the transaction cut off.
_CUT_OFF_WRITER = """
import os, sqlite3, sys
db = sqlite3.connect(sys.argv[1], isolation_level=None)
db.execute(f"PRAGMA journal_mode={sys.argv[2]}")
db.execute("PRAGMA wal_autocheckpoint=0")
db.execute("PRAGMA cache_size=1")
rows = db.execute("SELECT m.id, m.data FROM messages m JOIN topics t ON m.topic_id = t.id "
                  "WHERE t.name = '/left/pose'").fetchall()
db.execute("BEGIN")
for key, data in rows:
    db.execute("UPDATE messages SET data = ? WHERE id = ?", (data[:-9] + bytes([data[-9] ^ 64])
                                                          + data[-8:], key))
if sys.argv[2] == "WAL":
    db.execute("COMMIT")
os._exit(0)
"""


@pytest.mark.parametrize("mode, log, words", [
    ("WAL", "-wal", "holds changes not yet in"),
    ("DELETE", "-journal", "holds a transaction cut off half written into")])
def test_a_sqlite3_bag_with_a_log_left_beside_it_is_refused(tmp_path, capsys, mode, log,
                                                            words):
    """rosbags reads a .db3 as immutable: past a write-ahead log left by a writer that did
    not close it (rosbag2's resilient preset writes one), whose change SQLite and so
    ``ros2 bag play`` read, and into the half-written pages of a transaction whose hot
    journal SQLite would roll back. A bag whose WAL flipped a bit of every pose was a
    match; one with a cut-off transaction a mismatch, though what SQLite reads matched.
    Both are refused in one line that names the log."""
    script, recording = str(tmp_path / "in"), tmp_path / "rec"
    assert main(["script", "sample", "-o", script]) == 0
    assert main(["replay", "sample", script, "-o", str(recording), "--with-inputs",
                 "--storage", "sqlite3"]) == 0
    database = recording / "rec.db3"
    subprocess.run([sys.executable, "-c", _CUT_OFF_WRITER, str(database), mode], check=True)
    assert (recording / f"rec.db3{log}").stat().st_size > 0
    capsys.readouterr()
    for argv in (["replay", "sample", str(recording), "--check"],
                 ["compare", str(recording), str(recording)],
                 ["replay", "sample", str(database), "--check"]):
        err = _one_line_error(capsys, *argv)
        assert f"rec.db3{log} {words} rec.db3" in err, err
    code, out, _ = _cli(capsys, "regress", str(recording), "--scene", "sample", "--workers", "1")
    assert code == 2 and out.startswith("ERROR") and f"rec.db3{log} {words}" in out, out
    # A bag whose database is a link to this one: SQLite reads the log beside the target.
    linked = tmp_path / "linked"
    linked.mkdir()
    (linked / "metadata.yaml").write_bytes((recording / "metadata.yaml").read_bytes())
    (linked / "rec.db3").symlink_to(database)
    err = _one_line_error(capsys, "compare", str(linked), str(linked))
    assert f"rec.db3{log} {words} rec.db3" in err, err
    # The command the error gives settles the log, and the bag is read again (what the WAL
    # flipped may be an infinite pose, which no comparison matches, so not refused is all).
    advice = err.split(f"sqlite3 {database} '")[1].split("'")[0]
    with contextlib.closing(sqlite3.connect(database)) as db:
        db.execute(advice).fetchall()
    assert not (recording / f"rec.db3{log}").exists() or \
        (recording / f"rec.db3{log}").stat().st_size == 0
    code, out, err = _cli(capsys, "compare", str(recording), str(recording))
    assert code in (0, 1) and log not in out + err, (out, err)


def test_a_flood_of_inputs_is_replayed_without_holding_them_decoded(tmp_path, monkeypatch):
    """A bag of a million AppliedWrench messages took 1.9 GB to replay: every input was
    decoded before the replay and held so to the end, 1.3 kB each where its bytes take 0.2
    kB. Above HELD_DECODED inputs each is decoded again when it is pushed (set here below
    this bag's 20,000): tracemalloc's peak over the replay stays below 300 bytes an input
    (about 1,500 held). Up to it, each input is decoded once (a second decode costs about
    50 us a message, 1.65 times the replay of the million), and both ways give the same
    outputs, bit for bit."""
    import sys
    import tracemalloc

    from hecker_dynamics.bags.io import APPLIED_WRENCH, BagMessage, applied_wrench_message
    from hecker_dynamics.bags.replay import replay_outputs

    count, span = 20_000, 2 * SEC
    with BagWriter(tmp_path / "flood", "mcap", custom_data={
            "scene": "sample", "start_ns": "0", "duration_ns": str(span)}) as writer:
        for n in range(count):
            at = n * (span // count)
            writer.write("/applied_wrench", APPLIED_WRENCH, at, applied_wrench_message(
                at, "left", "left", f"f{n % 3}", (0.1, 0.0), (0.0, 1.0 + n % 7), 0.0, SEC // 50))
    bag = read_bag(tmp_path / "flood")
    scene = load_scene("sample")
    decodes = 0
    decode = BagMessage.decode

    def counted(message: BagMessage) -> object:
        nonlocal decodes
        decodes += 1
        return decode(message)

    monkeypatch.setattr(BagMessage, "decode", counted)
    held, result = replay_outputs(scene, bag)
    assert (result.inputs, result.accepted, decodes) == (count, count, count)
    monkeypatch.setattr(sys.modules["hecker_dynamics.bags.replay"], "HELD_DECODED", count - 1)
    decodes = 0
    tracemalloc.start()
    try:
        outputs, result = replay_outputs(scene, bag)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert (result.inputs, result.accepted, decodes) == (count, count, 2 * count)
    assert peak < 300 * count, peak / count
    assert outputs == held
