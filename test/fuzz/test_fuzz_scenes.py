"""A scene fuzzer: the shipped scenes, mutated (values replaced by hostile ones, keys
dropped, duplicated or misspelt, bytes flipped, lines cut), run with ``run``.

Every case must exit 0 with a finite summary, or exit 2 with one line naming the file;
never a traceback or a hang. Seeded; ``--fuzz-seconds`` sets how long it runs.
"""
from __future__ import annotations

import math
import random
import time

from harness import judge, run_cli

from hecker_dynamics.scene.load import scene_path, shipped_scenes

HOSTILE = ["1e-9", "1.0e9", "1:30", "-1", "0", "1e308", "-1e308", ".nan", ".inf", "-.inf",
           "9" * 400, "0x7fffffffffffffff", "''", "~", "yes", "[]", "[1.0]", "{}", "[[1]]",
           "'x'", "1e-300", "2.5e-324", "!!str 1.0", "&a 1", "*a", "[1.0, 2]", "1_0",
           "\"\\u0000\"", "1e200", "[1e200, 1e200]", "4294967296"]


def _mutate(text: str, rng: random.Random) -> str:
    lines = text.splitlines()
    kind = rng.randrange(6)
    i = rng.randrange(len(lines))
    line = lines[i]
    if kind <= 1 and ":" in line:  # replace a value
        key = line.split(":", 1)[0]
        lines[i] = f"{key}: {rng.choice(HOSTILE)}"
    elif kind == 2:  # drop a line
        del lines[i]
    elif kind == 3:  # duplicate a line
        lines.insert(i, line)
    elif kind == 4 and line.strip():  # misspell a key, or break the indentation
        lines[i] = (" " + line) if rng.random() < 0.5 else line.replace(":", "x:", 1)
    else:  # flip a byte
        data = bytearray("\n".join(lines).encode())
        data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
        return data.decode("utf-8", errors="surrogateescape")
    return "\n".join(lines) + "\n"


def test_mutated_scenes_fail_cleanly_or_run(tmp_path, request):
    seconds = request.config.getoption("--fuzz-seconds")
    rng = random.Random(request.config.getoption("--fuzz-seed"))
    texts = {name: scene_path(name).read_text() for name in shipped_scenes()}
    deadline = time.monotonic() + seconds
    cases = 0
    while time.monotonic() < deadline or cases < 3:
        name = rng.choice(sorted(texts))
        text = texts[name]
        for _ in range(rng.randint(1, 3)):
            text = _mutate(text, rng)
        path = tmp_path / f"case{cases}.yaml"
        path.write_bytes(text.encode("utf-8", errors="surrogateescape"))
        outcome = run_cli("run", str(path), "--duration", "0.05")
        what = f"case {cases} from {name}:\n{text}"
        judge(outcome, what)
        if outcome.code == 2:
            assert str(path) in outcome.err, what
        else:
            energy = [line for line in outcome.out.splitlines() if line.startswith("energy")]
            assert energy and all(math.isfinite(float(x)) for x in
                                  energy[0].split()[1::3][:1] + [energy[0].split()[-2]]), what
        cases += 1
