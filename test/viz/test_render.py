"""Animations read back: the frame count and rate, a bag drawing the same pixels as the
run that produced it, deterministic stills, and one-line errors for bad options."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib", reason="matplotlib is not installed (the viz extra)")
pytest.importorskip("PIL", reason="Pillow is not installed (the viz extra)")
from PIL import Image  # noqa: E402

from hecker_dynamics.cli import main  # noqa: E402
from hecker_dynamics.scene import load_scene  # noqa: E402
from hecker_dynamics.viz.draw import ARROW_COLOR, parse_trail  # noqa: E402
from hecker_dynamics.viz.frames import bag_timeline, run_timeline  # noqa: E402
from hecker_dynamics.viz.render import frame_pixels, timeline_frames  # noqa: E402

SPAN_NS = 2_000_000_000


def _one_line_error(capsys, argv) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("hecker-dynamics: error: "), err
    return err


@pytest.fixture(scope="module")
def replayed(tmp_path_factory):
    """Per scene: the bag 'replay' writes (poses and, copied, the inputs) from the scene's
    script over the first 2 s."""
    def make(name: str) -> Path:
        directory = tmp_path_factory.mktemp(name)
        assert main(["script", name, "-o", str(directory / "in"), "--duration", "2"]) == 0
        assert main(["replay", name, str(directory / "in"), "-o", str(directory / "out"),
                     "--with-inputs", "--no-progress"]) == 0
        return directory / "out"
    return {name: make(name) for name in ("ship", "sample")}


@pytest.mark.parametrize("name, trails, contacts", [("ship", ["ship/left_engine"], False),
                                                    ("sample", ["left", "right"], True)])
def test_bag_draws_the_pixels_of_its_run(replayed, name, trails, contacts):
    scene = load_scene(name)
    run = run_timeline(scene, SPAN_NS)
    bag = bag_timeline(scene, str(replayed[name]))
    assert (bag.start_ns, bag.end_ns) == (0, SPAN_NS)
    assert bag.commands == run.commands
    fps = 10.0
    frames_run = timeline_frames(run, 0, SPAN_NS, fps)
    frames_bag = timeline_frames(bag, 0, SPAN_NS, fps)
    assert frames_bag == frames_run
    options = dict(trails=[parse_trail(scene, t) for t in trails], contacts=contacts)
    pixels_run = list(frame_pixels(run, frames_run, (240, 180), **options))
    pixels_bag = list(frame_pixels(bag, frames_bag, (240, 180), **options))
    assert len(pixels_run) == len(pixels_bag) == 20
    for a, b in zip(pixels_run, pixels_bag):
        assert np.array_equal(a, b)
    # The pictures move: consecutive frames differ (a bag of constant poses would also
    # draw equal pictures, and this test would prove nothing about reading poses).
    assert not np.array_equal(pixels_run[0], pixels_run[-1])
    if name == "ship":  # both engines push from t = 0: their arrows are drawn
        red = np.array([int(ARROW_COLOR[i:i + 2], 16) for i in (1, 3, 5)])
        assert (pixels_bag[5][:, :, :3] == red).all(axis=2).sum() > 20


def test_bag_gif_equals_run_gif(replayed, tmp_path, capsys):
    common = ["--duration", "2", "--fps", "5", "--size", "160x120", "--trail", "ship"]
    assert main(["render", "ship", "-o", str(tmp_path / "run.gif"), *common]) == 0
    assert main(["render", "ship", "--bag", str(replayed["ship"]),
                 "-o", str(tmp_path / "bag.gif"), *common]) == 0
    assert (tmp_path / "run.gif").read_bytes() == (tmp_path / "bag.gif").read_bytes()


@pytest.mark.parametrize("duration, fps, count", [("1.5", "8", 12), ("0.7", "10", 7),
                                                  ("2", "2.5", 5)])
def test_frame_count_is_span_times_fps(tmp_path, duration, fps, count):
    output = tmp_path / "ship.gif"
    assert main(["render", "ship", "-o", str(output), "--duration", duration, "--fps", fps,
                 "--size", "64x48"]) == 0
    with Image.open(output) as gif:
        assert gif.n_frames == count
        assert gif.size == (64, 48)
        # GIF delays are whole centiseconds: 1/8 s is stored as 0.12 s.
        assert gif.info["duration"] == 10 * round(100 / float(fps))


def test_start_shifts_the_frames():
    scene = load_scene("ship")
    timeline = run_timeline(scene, 3 * 10**9)
    frames = timeline_frames(timeline, 10**9, 2 * 10**9, 4.0)
    assert [f.time_ns for f in frames] == [10**9 + k * 250_000_000 for k in range(8)]
    # Published every 20 ms: a frame at a publish instant shows that instant's pose.
    k = timeline.stamps.index(1_500_000_000)
    assert frames[2].poses == timeline.poses[k]


@pytest.mark.parametrize("suffix", [".png", ".svg"])
def test_still_is_the_same_file_every_time(tmp_path, suffix):
    paths = [tmp_path / f"a{suffix}", tmp_path / f"b{suffix}"]
    for path in paths:
        assert main(["render", "sample", "-o", str(path), "--duration", "0.5", "--fps", "10",
                     "--trail", "left", "--contacts"]) == 0
    assert paths[0].read_bytes() == paths[1].read_bytes()
    if suffix == ".png":
        with Image.open(paths[0]) as png:
            assert png.size == (480, 360)


def test_view_box_sets_the_picture(tmp_path):
    # The ship starts with its body frame at the origin: a view far away shows background.
    output = tmp_path / "empty.png"
    assert main(["render", "ship", "-o", str(output), "--duration", "0.1",
                 "--view", "100,100,104,103", "--size", "80x60"]) == 0
    with Image.open(output) as png:
        pixels = np.asarray(png.convert("RGB"))
    text_free = pixels[20:, :]  # below the sim time label
    assert (text_free == 255).all()


def test_bad_options_end_in_one_line_errors(tmp_path, capsys, replayed):
    out = str(tmp_path / "x.gif")
    assert "unknown body 'hull'" in _one_line_error(
        capsys, ["render", "ship", "-o", out, "--trail", "hull"])
    assert "has no point 'nose'" in _one_line_error(
        capsys, ["render", "ship", "-o", out, "--trail", "ship/nose"])
    # An empty point name drew the CM's trail as if none were given.
    assert "name a point of 'ship' after the '/'" in _one_line_error(
        capsys, ["render", "ship", "-o", out, "--trail", "ship/"])
    assert "zero size" in _one_line_error(
        capsys, ["render", "ship", "-o", out, "--view", "0,0,0,1"])
    assert "zero size" in _one_line_error(
        capsys, ["render", "ship", "-o", out, "--view", "0,2,1,1"])
    assert "four finite numbers" in _one_line_error(
        capsys, ["render", "ship", "-o", out, "--view", "0,0,1"])
    assert "unknown picture type '.jpg'" in _one_line_error(
        capsys, ["render", "ship", "-o", str(tmp_path / "x.jpg")])
    assert "--fps" in _one_line_error(capsys, ["render", "ship", "-o", out, "--fps", "0"])
    assert "--size" in _one_line_error(capsys, ["render", "ship", "-o", out, "--size", "big"])
    assert "gives no frame" in _one_line_error(
        capsys, ["render", "ship", "-o", out, "--duration", "0.01", "--fps", "10"])
    # Quoted as given, not as the whole nanoseconds it rounds to ("--duration 0 s").
    assert "--duration 1e-10 s at --fps 20 gives no frame" in _one_line_error(
        capsys, ["render", "ship", "-o", out, "--duration", "1e-10"])
    # A bag with inputs but no poses (what 'script' writes), and no bag at all.
    assert main(["script", "ship", "-o", str(tmp_path / "inputs"), "--duration", "1"]) == 0
    capsys.readouterr()
    assert "no poses" in _one_line_error(
        capsys, ["render", "ship", "--bag", str(tmp_path / "inputs"), "-o", out])
    assert "no such bag" in _one_line_error(
        capsys, ["render", "ship", "--bag", str(tmp_path / "nothing"), "-o", out])
    # A bag with the pose topic declared and not one message on it.
    from hecker_dynamics.bags.io import POSE_STAMPED, BagWriter
    with BagWriter(tmp_path / "empty") as writer:
        writer.add_topic("/ship/pose", POSE_STAMPED)
    assert "no instant with a pose" in _one_line_error(
        capsys, ["render", "ship", "--bag", str(tmp_path / "empty"), "-o", out])
    # Another scene's bag.
    assert "no poses" in _one_line_error(
        capsys, ["render", "sample", "--bag", str(replayed["ship"]), "-o", out])
    assert not Path(out).exists()


def test_mp4_without_encoder_is_a_one_line_error(tmp_path, capsys, monkeypatch):
    import sys
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # import fails
    assert "imageio-ffmpeg" in _one_line_error(
        capsys, ["render", "ship", "-o", str(tmp_path / "x.mp4")])


def test_run_view_without_display_is_a_one_line_error(capsys, monkeypatch):
    import sys
    if not sys.platform.startswith("linux"):
        pytest.skip("the display check is the X11/Wayland one")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert "no display" in _one_line_error(capsys, ["run", "ship", "--view"])



def test_mp4_reads_back_frame_for_frame(tmp_path):
    """An MP4 from the encoder imageio-ffmpeg ships: the frame count and rate asked for,
    the body's fill inside it and the background outside it, and every frame close to the
    exact pixels (the encoder stores colour at half resolution and rounds: a few levels)."""
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg", reason="no MP4 encoder installed")
    from hecker_dynamics.viz.draw import BACKGROUND, BODY_COLORS, View

    output = tmp_path / "ship.mp4"
    view, size = View(-6.0, -4.5, 6.0, 4.5), (480, 360)  # 40 px per metre
    assert main(["render", "ship", "-o", str(output), "--duration", "1", "--fps", "10",
                 "--view=-6,-4.5,6,4.5", "--size", "480x360"]) == 0
    reader = imageio_ffmpeg.read_frames(str(output))
    meta = next(reader)
    frames = [np.frombuffer(f, dtype=np.uint8).reshape(360, 480, 3) for f in reader]
    assert tuple(meta["size"]) == size and meta["fps"] == 10.0 and len(frames) == 10
    timeline = run_timeline(load_scene("ship"), SPAN_NS)
    exact = list(frame_pixels(timeline, timeline_frames(timeline, 0, 10**9, 10.0), size,
                              view=view))
    for got, want in zip(frames, exact):
        assert np.abs(got.astype(int) - want[:, :, :3]).mean() < 2.0

    def pixel(x: float, y: float) -> np.ndarray:
        column, row = int((x - view.xmin) * 40), int((view.ymax - y) * 40)
        return frames[0][row, column].astype(int)

    def rgb(color: str) -> np.ndarray:
        return np.array([int(color[i:i + 2], 16) for i in (1, 3, 5)])

    # At t = 0 the ship's frame is the fixed frame: its hull spans x -2.5..3, y -1..1.
    assert np.abs(pixel(-1.5, -0.5) - rgb(BODY_COLORS[0])).max() <= 8
    assert np.abs(pixel(-1.5, -2.0) - rgb(BACKGROUND)).max() <= 8


def test_run_view_without_a_window_backend_is_a_one_line_error(capsys, monkeypatch):
    import matplotlib
    monkeypatch.setenv("DISPLAY", ":0")  # a display named, but pyplot on Agg
    previous = matplotlib.get_backend()
    matplotlib.use("Agg")
    try:
        assert "no window backend" in _one_line_error(capsys, ["run", "ship", "--view"])
    finally:
        matplotlib.use(previous)


def test_view_loop_shows_every_frame_in_turn_and_stops_when_closed():
    """The loop of ``run --view`` (no X server here, so on an Agg canvas): each pause shows
    the next frame's pixels, filling the window; closing the window ends the loop."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from hecker_dynamics.viz.render import play

    timeline = run_timeline(load_scene("sample"), SPAN_NS)
    size = (240, 180)
    pixels = list(frame_pixels(timeline, timeline_frames(timeline, 0, SPAN_NS, 5.0), size))
    assert len(pixels) == 10 and not np.array_equal(pixels[0], pixels[-1])
    figure = Figure(figsize=(2.4, 1.8), dpi=100)
    canvas = FigureCanvasAgg(figure)
    shown, pauses = [], []

    def pause(seconds):
        pauses.append(seconds)
        canvas.draw()
        shown.append(np.asarray(canvas.buffer_rgba()).copy())

    assert play(figure, iter(pixels), 5.0, pause=pause, is_open=lambda: True) == 10
    assert pauses == [0.2] * 10
    for window, frame in zip(shown, pixels):
        assert np.array_equal(window[:, :, :3], frame[:, :, :3])
    figure = Figure(figsize=(2.4, 1.8), dpi=100)
    canvas = FigureCanvasAgg(figure)
    shown.clear()
    assert play(figure, iter(pixels), 5.0, pause=pause,
                is_open=lambda: len(shown) < 3) == 3


@pytest.mark.parametrize("name, start, duration", [("sample", "2.8", "0.4"),
                                                   ("door", "0.3", "0.4"),
                                                   ("car_flip", "0.8", "0.4")])
def test_gif_keeps_every_colour_of_the_drawing(tmp_path, name, start, duration):
    """A force that starts after the first frame (the sample's kick at 3 s, the door's push
    at 0.5 s) is red in the GIF as in the exact pixels (and the PNG): every pixel drawn in
    one of the drawing's colours has that colour in every frame of the GIF."""
    from hecker_dynamics.viz.draw import DRAWING_COLORS

    output = tmp_path / f"{name}.gif"
    assert main(["render", name, "-o", str(output), "--start", start, "--duration", duration,
                 "--fps", "10", "--size", "480x360", "--contacts"]) == 0
    start_ns, duration_ns = round(float(start) * 1e9), round(float(duration) * 1e9)
    timeline = run_timeline(load_scene(name), start_ns + duration_ns)
    exact = list(frame_pixels(timeline, timeline_frames(timeline, start_ns, duration_ns, 10.0),
                              (480, 360), contacts=True))
    red = np.array([int(ARROW_COLOR[i:i + 2], 16) for i in (1, 3, 5)])
    assert not (exact[0][:, :, :3] == red).all(axis=2).any()  # no force in the first frame
    assert any((frame[:, :, :3] == red).all(axis=2).sum() > 20 for frame in exact)
    with Image.open(output) as gif:
        assert gif.n_frames == len(exact)
        for k, want in enumerate(exact):
            gif.seek(k)
            got = np.asarray(gif.convert("RGB"))
            for color in set(DRAWING_COLORS):
                rgb = np.array([int(color[i:i + 2], 16) for i in (1, 3, 5)])
                drawn = (want[:, :, :3] == rgb).all(axis=2)
                assert (got[drawn] == rgb).all(), (k, color)


@pytest.mark.parametrize("fps", ["8", "30", "33.333", "50", "0.5"])
def test_gif_plays_at_the_rate_asked(tmp_path, fps):
    """GIF delays are whole centiseconds: frame k shows from round(100 k / fps) cs on, so the
    delays (12 and 13 cs at 8 fps, 3 and 4 at 30) add up to the span."""
    output = tmp_path / "ship.gif"
    frames = 12
    duration = f"{frames / float(fps):.9f}"
    assert main(["render", "ship", "-o", str(output), "--duration", duration, "--fps", fps,
                 "--size", "64x48"]) == 0
    with Image.open(output) as gif:
        delays = []
        for k in range(gif.n_frames):
            gif.seek(k)
            delays.append(gif.info["duration"])
    assert len(delays) == frames
    assert sum(delays) == 10 * round(100 * frames / float(fps))
    assert max(delays) - min(delays) <= 10


@pytest.mark.parametrize("argv, problem", [
    (["--fps", "1000"], "a GIF plays at most 50 frames a second"),
    (["--fps", "51"], "a GIF plays at most 50"),
    (["--fps", "0.001", "--duration", "2000"], "at most 655.35 s"),
    (["--duration", "1e9"], "over the 10000 a picture may have"),
    (["--duration", "1e9", "-o", "{tmp}/x.mp4"], "over the 10000 a picture may have"),
    (["--start", "1e6", "--duration", "1"], "over the 100000 a picture keeps"),
    (["--fps", "50", "--duration", "100", "--size", "480x360"], "MiB of frames a GIF"),
    (["--duration", "100", "--size", "4096x4096", "-o", "{tmp}/x.mp4"], "pixels a picture"),
])
def test_render_spans_and_rates_are_bounded_before_the_run(tmp_path, capsys, monkeypatch,
                                                          argv, problem):
    from hecker_dynamics.viz import frames

    def no_run(*args, **kwargs):
        raise AssertionError("ran the scene before checking the span")
    monkeypatch.setattr(frames, "run_timeline", no_run)
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    output = [] if "-o" in argv else ["-o", str(tmp_path / "x.gif")]
    assert problem in _one_line_error(capsys, ["render", "sample", *output, *argv])
    assert list(tmp_path.iterdir()) == []


def test_a_bag_is_drawn_only_within_its_session(replayed, tmp_path, capsys):
    """Past the end of a bag every frame would hold its last poses under later times."""
    out = str(tmp_path / "x.gif")
    bag = ["render", "sample", "--bag", str(replayed["sample"]), "-o", out]
    assert "--start 100 s: outside the bag's session, 0 s to 2 s" in _one_line_error(
        capsys, [*bag, "--start", "100"])
    assert "--start 2 s: outside" in _one_line_error(capsys, [*bag, "--start", "2"])
    assert "ends after the bag's session, at 2 s" in _one_line_error(
        capsys, [*bag, "--start", "1", "--duration", "5"])
    assert not Path(out).exists()
    assert main([*bag, "--start", "1.5", "--fps", "10"]) == 0
    with Image.open(out) as gif:
        assert gif.n_frames == 5


def test_a_recorded_session_s_span_is_told_in_exact_seconds():
    # A live recording's session runs at ROS times, past what a double holds to the
    # nanosecond: the span a user copies into --start must be the bag's own times.
    from types import SimpleNamespace

    from hecker_dynamics.viz.commands import _check_in_session
    from hecker_dynamics.viz.frames import VizError
    session = SimpleNamespace(start_ns=1_700_000_000_750_000_001, end_ns=1_700_000_012_5 * 10**8)
    with pytest.raises(VizError, match=r"session, 1700000000\.750000001 s to 1700000012\.5 s"):
        _check_in_session(session, 0, 1)
    with pytest.raises(VizError, match=r"session, at 1700000012\.5 s"):
        _check_in_session(session, session.start_ns, 12 * 10**9)


@pytest.mark.parametrize("value", [float("nan"), float("inf")])
def test_a_bag_pose_that_is_not_finite_is_a_one_line_error(replayed, tmp_path, capsys, value):
    """matplotlib refused the view of a NaN pose with a traceback."""
    from hecker_dynamics.bags.io import BagWriter, read_bag, typestore
    source = read_bag(replayed["sample"])
    target = source.on("/left/pose")[3]
    with BagWriter(tmp_path / "bad", "mcap") as writer:
        for topic, msgtype in source.topics.items():
            writer.add_topic(topic, msgtype)
        for message in source.messages:
            raw = message.raw
            if message.index == target.index and message.topic == target.topic:
                msg = message.decode()
                msg.pose.position.y = value
                raw = bytes(typestore().serialize_cdr(msg, message.msgtype))
            writer.write_raw(message.topic, message.log_ns, raw)
    out = tmp_path / "x.png"
    err = _one_line_error(capsys, ["render", "sample", "--bag", str(tmp_path / "bad"),
                                   "-o", str(out)])
    assert f"/left/pose at 0.08 s: the pose is not finite (y {value})" in err, err
    assert not out.exists()


def test_the_summary_names_a_ros_time_span_to_the_nanosecond(tmp_path, capsys):
    """A session at ROS time 1.7e9 s, which a double holds only to 256 ns: render's summary
    said "sim time 1.7e+09 s to 1.7e+09 s" for a span of 0.5 s, and replay's "to
    1700000000.750000238 s"."""
    script, bag = str(tmp_path / "in"), str(tmp_path / "out")
    assert main(["script", "sample", "-o", script, "--duration", "0.5", "--start",
                 "1700000000.25"]) == 0
    capsys.readouterr()
    assert main(["replay", "sample", script, "-o", bag, "--no-progress"]) == 0
    assert "; sim time 1700000000.250000000 s to 1700000000.750000000 s, 500 steps" in \
        capsys.readouterr().out
    assert main(["render", "sample", "--bag", bag, "-o", str(tmp_path / "f.png")]) == 0
    assert capsys.readouterr().out == (
        f"wrote 1 frame(s) of {bag}, sim time 1700000000.250000000 s to "
        f"1700000000.750000000 s, to {tmp_path / 'f.png'}\n")
