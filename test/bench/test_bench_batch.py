"""``bench --batch`` on small workloads: every engine runs every round, its tables equal
the one-process table, and the bar counts the runs."""
from __future__ import annotations

from hecker_dynamics.bench import batch

SEC = 1_000_000_000


class _Bar:
    def __init__(self, label: str, parts: int) -> None:
        self.label, self.parts, self.fractions = label, parts, []

    def __call__(self, fraction: float) -> None:
        self.fractions.append(fraction)

    def close(self) -> None:
        self.fractions.append("closed")


def test_bench_batch_times_every_engine_on_every_workload(monkeypatch):
    monkeypatch.setattr(batch, "WORKLOADS", {"short": (4, SEC // 50), "long": (2, SEC // 10)})
    bars: list[_Bar] = []

    def bar(label: str, parts: int) -> _Bar:
        bars.append(_Bar(label, parts))
        return bars[-1]

    lines: list[str] = []
    medians = batch.bench_batch(rounds=2, workers=2, report=lines.append, bar=bar)
    engines = list(batch._engines(2))
    assert set(medians) == {(w, e) for w in ("short", "long") for e in engines}
    assert all(wall > 0 for wall in medians.values())
    assert len(lines) == 1 + 2 * len(engines) and lines[1].strip().endswith("1.00x")
    (only,) = bars
    assert only.parts == 2 * 2 * len(engines)
    assert only.fractions[-2:] == [1.0, "closed"] and len(only.fractions) == only.parts + 1
