"""Writing the results: ``results.csv``, ``ring.csv``, ``report.md`` and the figure
``work_precision.png`` (matplotlib, imported only here and only if installed)."""
from __future__ import annotations

import csv
import math
import statistics
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Optional

from ..integrators.methods import ADAPTIVE
from .bounce import bounce_table, write_bounce_csv
from .measure import Row
from .scenes import STIFF_SEESAW

if TYPE_CHECKING:
    from .run import Results

__all__ = ["THRESHOLDS", "write_csv", "cheapest", "Headline", "headline", "MARKERS",
           "agg_pyplot", "figure", "RING_LIMITS", "ring_table", "targets", "REPORT_FILES",
           "new_report_folder", "write_report"]

THRESHOLDS = (1e-3, 1e-6, 1e-9)
ENGINES = ("hecker_dynamics", "pymunk", "box2d", "mujoco")


def _g(x: Optional[float], digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return ""
    return f"{x:.{digits}g}"


def write_csv(rows: list[Row], path: Path) -> None:
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=Row.FIELDS)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: (_g(v, 6) if isinstance(v, float) else v)
                             for k, v in row.as_dict().items()})


def cheapest(rows: list[Row], scene: str, engine: str, threshold: float) -> Optional[Row]:
    """The cheapest ok row of ``engine`` on ``scene`` with position error <= threshold."""
    fits = [r for r in rows if r.scene == scene and r.engine == engine and r.status == "ok"
            and r.position_error <= threshold and not math.isnan(r.cost)]
    return min(fits, key=lambda r: r.cost, default=None)


def _config(row: Row | None) -> str:
    if row is None:
        return "none reaches"
    tol = f", tol {row.tolerance:g}" if not math.isnan(row.tolerance) else ""
    return f"{row.method} h={row.step:g}{tol}: {row.cost:.3g}"


@dataclass
class Headline:
    """On ``scene`` at the final position error ``threshold``: each engine's cheapest
    configuration reaching it (None: none does), hecker_dynamics' cost over each peer's
    that ran (0: only ours reaches; inf: only the peer; nan: neither), and the engines
    with configurations skipped for the run budget."""

    scene: str
    threshold: float
    best: dict[str, Optional[Row]]
    skipped: set[str]
    ratios: dict[str, float] = field(default_factory=dict)


def headline(rows: list[Row]) -> list[Headline]:
    """Per scene and threshold: the cheapest configuration of each engine, and ratios."""
    out = []
    for scene in dict.fromkeys(r.scene for r in rows):
        ran = {r.engine for r in rows if r.scene == scene}
        skipped = {r.engine for r in rows if r.scene == scene and r.status == "skipped"}
        for threshold in THRESHOLDS:
            best = {e: cheapest(rows, scene, e, threshold) for e in ENGINES}
            entry = Headline(scene, threshold, best, skipped)
            ours = best["hecker_dynamics"]
            for peer in ENGINES[1:]:
                if peer not in ran:
                    continue
                other = best[peer]
                if ours is None:
                    entry.ratios[peer] = math.inf if other is not None else math.nan
                elif other is None:
                    entry.ratios[peer] = 0.0
                else:
                    entry.ratios[peer] = ours.cost / other.cost
            out.append(entry)
    return out


def _ratio_text(x: float, skipped: bool = False) -> str:
    """The verdict on one ratio; ``skipped``: the peer had configurations left out for the
    run budget, which might have reached the error."""
    if math.isnan(x):
        return "neither reaches"
    if x == 0.0:
        return ("peer reaches it in no configuration run (some skipped for the run budget)"
                if skipped else "peer never reaches")
    if math.isinf(x):
        return "only the peer reaches (missed)"
    return f"{x:.2f} ({'met' if x <= 0.5 else 'missed'})"


#: Each engine's marker in the bench's figures.
MARKERS = {"hecker_dynamics": "o", "pymunk": "s", "box2d": "^", "box2d_v3": "v", "mujoco": "D"}


def agg_pyplot() -> Optional[ModuleType]:
    """matplotlib's pyplot drawing to files (the Agg backend), or None where matplotlib is
    not installed or does not load."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except Exception:
        return None
    return plt


def figure(rows: list[Row], path: Path) -> bool:
    plt = agg_pyplot()
    if plt is None:
        return False
    scenes = list(dict.fromkeys(r.scene for r in rows))
    cols = 3
    rows_n = math.ceil(len(scenes) / cols)
    fig, axes = plt.subplots(rows_n, cols, figsize=(5 * cols, 4 * rows_n), squeeze=False)
    for ax, scene in zip(axes.ravel(), scenes):
        ax.set_prop_cycle(color=plt.cm.tab20.colors)  # up to 20 series per panel, all distinct
        groups: dict[tuple[str, str, Optional[float]], list[Row]] = {}
        for r in rows:
            if r.scene == scene and r.status == "ok" and r.position_error > 0 \
                    and not math.isnan(r.cost) and not math.isnan(r.position_error):
                key = (r.engine, r.method, r.step if r.method in ADAPTIVE else None)
                groups.setdefault(key, []).append(r)
        for (engine, method, step), group in sorted(groups.items(), key=lambda kv: str(kv[0])):
            group.sort(key=lambda r: r.cost)
            label = f"{engine if engine != 'hecker_dynamics' else 'hd'} {method}" + \
                (f" h={step:g}" if step else "")
            ax.loglog([r.cost for r in group], [max(r.position_error, 1e-16) for r in group],
                      marker=MARKERS.get(engine, "x"), ms=3, lw=1,
                      ls="-" if engine == "hecker_dynamics" else "--", label=label)
        for t in (1e-3, 1e-6, 1e-9):
            ax.axhline(t, color="grey", lw=0.5, ls=":")
        ax.set_title(scene)
        ax.set_xlabel("cost, wall s per sim s")
        ax.set_ylabel("final position error, m")
        if groups:
            ax.legend(fontsize=5, ncol=2)
        else:  # every run exact (free_spin in a short sweep): nothing on a log axis
            ax.text(0.5, 0.5, "every error 0 m", ha="center", transform=ax.transAxes)
    for ax in axes.ravel()[len(scenes):]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


#: Issue 34's third target: our ring over the C loop's, at most this at each N.
RING_LIMITS = {10: 2.0, 1000: 1.25, 10000: 1.25}


def ring_table(ring: list[Row]) -> tuple[list[tuple[str, str]], list[int],
                                         dict[tuple[str, str, int], float]]:
    sizes = sorted({int(r.omega_dt) for r in ring})
    keys = list(dict.fromkeys((r.engine, r.method) for r in ring))
    table = {}
    for r in ring:
        if r.status == "ok" and not math.isnan(r.cost):
            table[(r.engine, r.method, int(r.omega_dt))] = r.cost * r.step / r.omega_dt
    return keys, sizes, table


def targets(results: Results) -> list[tuple[str, str, str]]:
    """(target, measured, verdict) lines for the benchmark's four targets (docs/benchmark.md)."""
    lines = []
    head = headline(results.rows)
    worst: dict[tuple[str, float], list[tuple[str, float]]] = {}
    for entry in head:
        if entry.scene in ("stiff",):
            continue
        for peer, ratio in entry.ratios.items():
            key = (entry.scene, entry.threshold)
            worst.setdefault(key, []).append((peer, ratio))
    ratios = [r for v in worst.values() for _, r in v]
    met1 = all(not (math.isinf(r) or (not math.isnan(r) and r > 0.5)) for r in ratios) \
        and bool(worst)
    both = [r for r in ratios if 0.0 < r < math.inf]
    lines.append(("1. cheapest hd <= 0.5 x cheapest peer at 1e-3/1e-6/1e-9 m (scenes 1-4, "
                  "and shipped scenes where peers run)",
                  f"where both reach the error: ratio <= 0.5 in {sum(r <= 0.5 for r in both)} "
                  f"of {len(both)} comparisons (ratios {min(both, default=math.nan):.2g} to "
                  f"{max(both, default=math.nan):.2g}); only hd reaches it in "
                  f"{sum(r == 0.0 for r in ratios)}, only the peer in "
                  f"{sum(math.isinf(r) for r in ratios)} (see headline table)",
                  "met" if met1 else "missed"))
    sample = results.sample
    if "hecker_dynamics" in sample:
        for peer in ("pymunk (python forces)", "pymunk (DampedSpring)", "box2d (python forces)",
                     "box2d_v3 (python forces)"):
            if peer in sample:
                ratio = sample["hecker_dynamics"] / sample[peer]
                lines.append((f"2. default-scene step over {results.sample_duration:g} s "
                              f"<= 0.5 x {peer}",
                              f"{sample['hecker_dynamics'] * 1e6:.1f} us vs "
                              f"{sample[peer] * 1e6:.1f} us: ratio {ratio:.2f}",
                              "met" if ratio <= 0.5 else "missed"))
    keys, sizes, table = ring_table(results.ring)
    sie = {n: table[ours] for n in sizes
           if (ours := ("hecker_dynamics", "semi_implicit_euler", n)) in table}
    for n, limit in RING_LIMITS.items():
        pairs = results.ring_pairs.get(n)
        if pairs:
            ratio = statistics.median(pairs)
            lines.append((f"3a. ring, semi-implicit Euler within {limit:g}x of the C loop at "
                          f"N = {n}",
                          f"median of {len(pairs)} back-to-back pairs {ratio:.2f} "
                          f"(pairs {min(pairs):.2f} to {max(pairs):.2f})",
                          "met" if ratio <= limit else "missed"))
        for peer, method in (("pymunk", "native"), ("mujoco", "euler")):
            peer_ratios = [(n, sie[n] / table[(peer, method, n)]) for n in sizes
                           if sie.get(n) and (peer, method, n) in table]
            if peer_ratios:
                bad = [f"N={n}: {r:.2f}" for n, r in peer_ratios if r >= 1.0]
                lines.append((f"3b. ring, semi-implicit Euler cheaper than {peer} at every N",
                              "ratios " + ", ".join(f"N={n}: {r:.2f}" for n, r in peer_ratios),
                              "met" if not bad else "missed"))
    stiff = [r for r in results.rows if r.scene in ("stiff", STIFF_SEESAW)
             and r.method in ("implicit_midpoint", "backward_euler")]
    for scene in ("stiff", STIFF_SEESAW):
        mine = [r for r in stiff if r.scene == scene]
        if not mine:
            continue
        top = max((r.omega_dt for r in mine if r.status == "ok"), default=math.nan)
        unstable = [r for r in mine if r.status != "ok" and r.status != "skipped"]
        lines.append((f"4. {scene}: implicit methods stable up to omega*dt = 100",
                      f"largest omega*dt run and stable: {top:.3g}; "
                      f"{len(unstable)} implicit runs diverged",
                      "met" if top >= 99 and not unstable else "missed"))
    return lines


#: Every file :func:`write_report` may write into its folder.
REPORT_FILES = ("report.md", "results.csv", "ring.csv", "bounce.csv", "work_precision.png")


def new_report_folder() -> Path:
    """Where a bench writes when it is not told: a new folder under the system's temporary
    folder, never the repository's docs/bench (a bench run in a clone would rewrite the
    tracked report)."""
    import tempfile

    return Path(tempfile.mkdtemp(prefix="hecker-dynamics-bench-"))


def write_report(results: Results, out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    write_csv(results.rows, out / "results.csv")
    write_csv(results.ring, out / "ring.csv")
    if results.bounce:
        write_bounce_csv(results.bounce, out / "bounce.csv")
    has_figure = figure(results.rows, out / "work_precision.png") if results.rows else False
    md = [f"# Benchmark results ({results.mode} mode)", "",
          f"Produced by `{results.command or 'hecker-dynamics bench'}` in "
          f"{results.seconds:.0f} s. Costs are wall seconds per simulated second (median of "
          "interleaved repeats); errors are final CM position (m) and angle (rad) against the "
          "reference. Method and references: docs/benchmark.md.", "",
          "Environment: " + "; ".join(f"{k} {v}" for k, v in results.environment.items()), ""]
    md += ["## Targets", "", "| target | measured | verdict |", "|---|---|---|"]
    md += [f"| {a} | {b} | {c} |" for a, b, c in targets(results)]
    if results.guard:
        md += ["", "## Regression guard: ratios against the reference", "",
               *[f"- {line}" for line in results.guard]]
    md += ["", "## Headline: cheapest configuration reaching each final position error", "",
           "Cost of the cheapest configuration (method, step h, tolerance) per engine; "
           "ratio = hecker_dynamics / peer (target <= 0.5).", "",
           "| scene | error <= | hecker_dynamics | pymunk | box2d | mujoco | ratios |",
           "|---|---|---|---|---|---|---|"]
    for entry in headline(results.rows):
        ratios = "; ".join(f"{p}: {_ratio_text(r, p in entry.skipped)}"
                           for p, r in entry.ratios.items())
        md.append(f"| {entry.scene} | {entry.threshold:g} | "
                  + " | ".join(_config(entry.best[e]) if any(r.engine == e
                                                             and r.scene == entry.scene
                                                       for r in results.rows) else "-"
                               for e in ENGINES) + f" | {ratios} |")
    md += ["", "## References and their own error", "",
           "| scene | reference | own position error (m) | own angle error (rad) | "
           "core dopri5 tol 1e-13 vs reference (m) |", "|---|---|---|---|---|"]
    for name, ref in results.references.items():
        md.append(f"| {name} | {ref.kind} | {ref.error:.2g} | {ref.angle_error:.2g} | "
                  f"{_g(results.cross_check.get(name, math.nan), 2)} |")
    if results.checks:
        md += ["", "## Peers against plain loops of their claimed schemes", "",
               "200 steps of h = 1e-3 s; largest difference in positions and angles.", "",
               "| peer | configuration | scheme | scene | difference | scale |",
               "|---|---|---|---|---|---|"]
        md += [f"| {c.peer} | {c.method} | {c.scheme} | {c.scene} | {c.difference:.2g} | "
               f"{c.scale:.2g} |" for c in results.checks]
    if results.sample:
        md += ["", "## One step of the default scene (sample)", "",
               f"Medians of interleaved runs over its first {results.sample_duration:g} s "
               "with its script (docs/benchmark.md: the peers' configurations).", "",
               "| engine | us per step |", "|---|---|"]
        md += [f"| {k} | {v * 1e6:.1f} |" for k, v in results.sample.items()]
    if results.declared:
        md += ["", "## Only what the scene declares: the contact pass", "",
               "A mass on a spring and a free ball 50 m away (semi-implicit Euler, h = 1 ms, "
               "1 s); a scene pays for contacts only when it declares walls or collisions.",
               "", "| declared | us per step |", "|---|---|"]
        md += [f"| {k} | {v * 1e6:.1f} |" for k, v in results.declared.items()]
    if results.bounce:
        md += ["", *bounce_table(results.bounce)]
    if results.ring:
        keys, sizes, table = ring_table(results.ring)
        md += ["", "## Ring: ns per body-step against N (h = 1 ms)", "",
               "| engine / method | " + " | ".join(f"N={n}" for n in sizes) + " |",
               "|---|" + "---|" * len(sizes)]
        for engine, method in keys:
            md.append(f"| {engine} {method} | " + " | ".join(
                _g(table[(engine, method, n)] * 1e9, 3) if (engine, method, n) in table else "-"
                for n in sizes) + " |")
        if results.ring_pairs:
            md += ["", "Our semi-implicit Euler over the C loop, runs made back to back in "
                   "pairs (the median pair, and the lowest and highest):", "",
                   "| N | median | lowest | highest | pairs |", "|---|---|---|---|---|"]
            md += [f"| {n} | {statistics.median(p):.2f} | {min(p):.2f} | {max(p):.2f} | "
                   f"{len(p)} |" for n, p in sorted(results.ring_pairs.items())]
    if results.lean:
        md += ["", "## Where the time goes (semi-implicit Euler)", "",
               "Simulation.advance_to (in the compiled kernel where it steps) against the "
               "integrator called from Python on model.accelerations, step by step.", "",
               "| scene | Simulation.advance_to us/step | integrator.step from Python "
               "us/step | ratio |", "|---|---|---|---|"]
        for name, (full, lean) in results.lean.items():
            md.append(f"| {name} | {full * 1e6:.1f} | {lean * 1e6:.1f} | {full / lean:.2f}x |")
        for name, text in results.profiles.items():
            md += ["", f"Profile of {name} (top functions by own time):", "", "```", text, "```"]
    md += ["", "## All configurations", "",
           "| scene | engine | method | h | tol | status | cost | pos err | angle err | "
           "energy drift | omega*h |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results.rows:
        md.append(f"| {r.scene} | {r.engine} | {r.method} | {r.step:g} | {_g(r.tolerance, 2)} | "
                  f"{r.status} | {_g(r.cost)} | {_g(r.position_error, 2)} | "
                  f"{_g(r.angle_error, 2)} | {_g(r.energy_drift, 2)} | {_g(r.omega_dt, 3)} |")
    if has_figure:
        md[1:1] = ["", "![work-precision](work_precision.png)"]
    (out / "report.md").write_text("\n".join(md) + "\n")
