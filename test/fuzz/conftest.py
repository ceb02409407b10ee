"""Options of the fuzzers: ``--fuzz-seconds`` (or HECKER_FUZZ_SECONDS) sets how long each
one runs (default 3 s, for CI), ``--fuzz-seed`` (or HECKER_FUZZ_SEED) its seed."""
from __future__ import annotations

import os


def pytest_addoption(parser):
    parser.addoption("--fuzz-seconds", type=float,
                     default=float(os.environ.get("HECKER_FUZZ_SECONDS", "3")),
                     help="seconds each fuzzer runs (default 3, or HECKER_FUZZ_SECONDS)")
    parser.addoption("--fuzz-seed", type=int,
                     default=int(os.environ.get("HECKER_FUZZ_SEED", "15")),
                     help="seed of the fuzzers (default 15, or HECKER_FUZZ_SEED)")
