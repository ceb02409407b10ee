"""A bag fuzzer: the golden bags, mutated (bytes of the storage flipped, cut or zeroed;
metadata values replaced), read by ``compare`` and ``replay``.

Every case must be refused in one line (exit 2), or read whole: ``compare`` against
the intact bag then sees every message (the counts in the metadata are checked), never
a part of them. Never a traceback or a hang. Seeded; ``--fuzz-seconds`` sets how long.
"""
from __future__ import annotations

import random
import shutil
import time
from pathlib import Path

import yaml
from harness import judge, run_cli

GOLDEN = Path(__file__).resolve().parents[1] / "golden"
HOSTILE = [0, -5, "many", 1e12, None, [], {}, "", 2 ** 64, -2 ** 63, 3e18, "1e20", True]


def _mutate_storage(bag: Path, rng: random.Random) -> str:
    storage = next(p for p in bag.iterdir() if p.suffix in (".mcap", ".db3"))
    data = bytearray(storage.read_bytes())
    kind = rng.randrange(3)
    if kind == 0:
        for _ in range(rng.randint(1, 4)):
            data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
    elif kind == 1:
        del data[rng.randrange(len(data)):]
    else:
        start = rng.randrange(len(data))
        data[start:start + rng.randint(1, 64)] = bytes(min(64, len(data) - start))
    storage.write_bytes(bytes(data))
    return f"storage mutation {kind}"


def _mutate_metadata(bag: Path, rng: random.Random) -> str:
    info = yaml.safe_load((bag / "metadata.yaml").read_text())
    top = info["rosbag2_bagfile_information"]
    choices = [(top, "message_count"), (top, "relative_file_paths"), (top, "storage_identifier"),
               (top["custom_data"], "hecker_dynamics.start_ns"),
               (top["custom_data"], "hecker_dynamics.duration_ns"),
               (top["topics_with_message_count"][0], "message_count"),
               (top["starting_time"], "nanoseconds_since_epoch"),
               (top["duration"], "nanoseconds")]
    holder, key = rng.choice(choices)
    value = rng.choice(HOSTILE)
    holder[key] = str(value) if key.startswith("hecker_dynamics.") else value
    (bag / "metadata.yaml").write_text(yaml.safe_dump(info))
    return f"metadata {key} = {value!r}"


def test_mutated_bags_are_refused_or_read_whole(tmp_path, request):
    seconds = request.config.getoption("--fuzz-seconds")
    rng = random.Random(request.config.getoption("--fuzz-seed"))
    scenes = sorted(p.name for p in GOLDEN.iterdir() if p.is_dir())
    deadline = time.monotonic() + seconds
    cases = 0
    while time.monotonic() < deadline or cases < 3:
        scene = rng.choice(scenes)
        part = rng.choice(["input", "output"])
        bag = tmp_path / f"case{cases}"
        shutil.copytree(GOLDEN / scene / part, bag)
        what = (_mutate_storage if rng.random() < 0.6 else _mutate_metadata)(bag, rng)
        what = f"case {cases}, {scene}/{part}: {what}"
        if part == "output":
            outcome = run_cli("compare", str(GOLDEN / scene / part), str(bag), "--atol", "0")
            judge(outcome, what)
            # Read whole or refused: a bag read in part would show missing messages
            # (exit 1 with 'missing'); a flipped payload can differ (no CRCs in the file).
            assert "missing" not in outcome.out, f"{what}: read in part\n{outcome.out}"
        else:
            outcome = run_cli("replay", scene, str(bag), "-o", str(tmp_path / f"out{cases}"),
                              "--duration", "0.5")
            judge(outcome, what)
        cases += 1
