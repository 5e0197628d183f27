"""Detection limit of the diagnosis: the smallest magnitude of each effect named correctly.

For each system and catalogue effect, a ladder of magnitudes is searched by bisection (the named
fraction is taken to grow with the magnitude): at a rung, ``--seeds`` seeded recordings of
``--cycles`` cycles are simulated with the effect injected and diagnosed against the nominal model
(:func:`suds_ros.core.diagnosis.diagnose`, every suspect on); the rung passes when the effect is
named on its target (or reported confounded with the named one) in ≥ 90 % of them.  A rung is
abandoned as soon as it can no longer reach 90 %.  The detection limit is the smallest passing
rung ("> largest" when none passes, "≤ smallest" when the smallest passes).

The reference, "the best any method could do": at every rung tried, the true effect's held-out
evidence with its parameters *known* (equation error, no fitting: log-likelihood gain minus the
BIC penalty, :class:`suds_ros.core.diagnosis.naming.Scorer`), averaged over the seeds; the
magnitude at which it crosses ``DiagnoseConfig.evidence_threshold`` is interpolated (log–log).
Below it even the true model would not earn a place against the null with our evidence rule.
Null recordings' false-positive rate: ``docs/results/evidence_threshold.md``.

Usage (from the repository root):
  PYTHONPATH=. .venv/bin/python benchmarks/detection_limit.py [--systems purcell3 swimmer9]
      [--seeds 10] [--cycles 60] [--budget 1500] [--out docs/results/detection_limit.md]
  PYTHONPATH=. .venv/bin/python benchmarks/detection_limit.py --quick   (smoke run, no file written)
``--budget`` (s) stops starting new effects once spent; the file says exactly what was covered.
``--combine FILE…`` runs nothing: it writes ``--out`` from earlier results files, a later file's row
replacing an earlier one's for the same (system, effect), and lists every run that made the rows (a
long search split over several runs, e.g. one per core with ``--effects``).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common  # noqa: E402,F401  (puts the repository on sys.path)
from _common import machine, stamp  # noqa: E402

from suds_ros.core.diagnosis import DiagnoseConfig, diagnose  # noqa: E402
from suds_ros.core.diagnosis.data import prepare  # noqa: E402
from suds_ros.core.diagnosis.naming import Candidate, Scorer  # noqa: E402
from suds_ros.core.diagnosis.pipeline import replay_nominal  # noqa: E402
from suds_ros.core.diagnosis.report import effect_label  # noqa: E402
from suds_ros.core.physics.effects import EFFECTS, apply_effects  # noqa: E402
from suds_ros.core.physics.rft import RFTChain  # noqa: E402
from suds_ros.core.physics.sim import SimConfig, simulate  # noqa: E402
from suds_ros.core.physics.systems import purcell3_model, swimmer9_model  # noqa: E402

MODELS = {"purcell3": purcell3_model, "swimmer9": swimmer9_model}
PASS = 0.9

# effect id → (target per system, magnitude ladder, magnitude → parameters)
LADDERS: dict[str, tuple[dict[str, str | None], list[float], Any]] = {
    "joint_coulomb_friction": ({"purcell3": "joint_2", "swimmer9": "joint_7"}, [0.001, 0.003, 0.01, 0.03, 0.1, 0.3],
                               lambda m: {"mu": m}),
    "joint_viscous_damping": ({"purcell3": "joint_2", "swimmer9": "joint_7"}, [0.0003, 0.001, 0.003, 0.01, 0.03, 0.1],
                              lambda m: {"d": m}),
    "spring_rest_offset": ({"purcell3": "joint_2", "swimmer9": "joint_6"}, [0.0005, 0.001, 0.002, 0.005, 0.02, 0.05],
                           lambda m: {"offset": m}),
    "spring_nonlinearity": ({"purcell3": "joint_2", "swimmer9": "joint_7"}, [0.03, 0.1, 0.3, 1.0],
                            lambda m: {"k3": m}),
    "stiffness_to_drag_error": ({"purcell3": None, "swimmer9": None}, [0.001, 0.002, 0.005, 0.02, 0.05, 0.15],
                                lambda m: {"scale": 1.0 - m}),
    "drag_anisotropy_error": ({"purcell3": None, "swimmer9": None}, [0.01, 0.03, 0.1, 0.3],
                              lambda m: {"ratio": 2.0 + m}),
    "background_flow": ({"purcell3": None, "swimmer9": None}, [0.001, 0.003, 0.01, 0.03],
                        lambda m: {"vx": 0.8 * m, "vy": -0.6 * m}),
    "sensor_time_offset": ({"purcell3": None, "swimmer9": None}, [0.001, 0.003, 0.01, 0.03],
                           lambda m: {"dt": m}),
}
UNITS = {"joint_coulomb_friction": "N·m", "joint_viscous_damping": "N·m·s/rad", "spring_rest_offset": "rad",
         "spring_nonlinearity": "N·m/rad³", "stiffness_to_drag_error": "abs(1 − scale)",
         "drag_anisotropy_error": "ratio − 2", "background_flow": "speed m/s", "sensor_time_offset": "s"}


@dataclasses.dataclass
class Rung:
    """Outcome at one magnitude: named count, recordings run, mean known-parameter evidence."""

    magnitude: float
    named: int
    runs: int
    evidence: float
    stopped: bool = False  # abandoned once 90 % was out of reach

    @property
    def passed(self) -> bool:
        return not self.stopped and self.runs > 0 and self.named >= PASS * self.runs


def _effect(name: str, target: str | None, m: float) -> dict[str, Any]:
    eff: dict[str, Any] = {"name": name, **LADDERS[name][2](m)}
    if target is not None:
        eff["joint"] = target
    return eff


def _named(rep, name: str, target: str | None) -> bool:  # type: ignore[no-untyped-def]
    """Whether the report names the effect on its target (or confounded with the named one)."""
    label = effect_label(name, target)
    if any(e.name == name and e.target == target for e in rep.effects):
        return True
    return any(label in g for g in rep.confounded_with)


def _known_evidence(rec, base, eff: dict[str, Any], cfg: DiagnoseConfig) -> float:  # type: ignore[no-untyped-def]
    """Held-out evidence of the true effect with its parameters known (equation error, nats)."""
    data = prepare(rec, base)
    nom = replay_nominal(data, base, cfg, None)
    scorer = Scorer(data, base, cfg.eq_window, nom.floors[0])
    cand = Candidate(((eff["name"], eff.get("joint")),))
    x = np.array([eff[p.name] for p in EFFECTS[eff["name"]].params])
    pen = 0.5 * np.log(max(float(np.median(scorer.n_eff_train)), 2.0)) * x.size
    return scorer.heldout_gain(cand, x) - pen


def rung(system: str, name: str, m: float, seeds: int, cycles: int, cfg: DiagnoseConfig) -> Rung:
    """Diagnose ``seeds`` recordings at magnitude ``m``; stops once 90 % is out of reach."""
    base = MODELS[system]()
    target = LADDERS[name][0][system]
    eff = _effect(name, target, m)
    model, delay = apply_effects(base, [eff])
    named = runs = 0
    ev = []
    allowed_fail = seeds - int(np.ceil(PASS * seeds))
    for s in range(seeds):
        rec = simulate(RFTChain(model), SimConfig(cycles=cycles, seed=7000 + 31 * s, pose_delay=delay))
        ok = _named(diagnose(rec, base, cfg), name, target)
        named += ok
        runs += 1
        ev.append(_known_evidence(rec, base, eff, cfg))
        if runs - named > allowed_fail:
            break
    return Rung(m, named, runs, float(np.mean(ev)), stopped=runs - named > allowed_fail)


def search(system: str, name: str, seeds: int, cycles: int, cfg: DiagnoseConfig,
           ladder: list[float] | None = None) -> list[Rung]:
    """Bisection over the ladder for the smallest passing rung; returns every rung tried."""
    ladder = ladder or LADDERS[name][1]
    lo, hi = 0, len(ladder) - 1
    tried: dict[int, Rung] = {}
    while lo <= hi:
        mid = (lo + hi) // 2
        tried[mid] = rung(system, name, ladder[mid], seeds, cycles, cfg)
        print(f"  {system} {name} {ladder[mid]:g}: named {tried[mid].named}/{tried[mid].runs}, "
              f"known-parameter evidence {tried[mid].evidence:.1f}", flush=True)
        if tried[mid].passed:
            hi = mid - 1
        else:
            lo = mid + 1
    return [tried[k] for k in sorted(tried)]


def limit(rungs: list[Rung], ladder: list[float] | None = None) -> str:
    """The smallest passing rung; "≤ x" when it is the ladder's lowest, "> x" when none passes."""
    ok = [r.magnitude for r in rungs if r.passed]
    if not ok:
        return f"> {max(r.magnitude for r in rungs):g}"
    low = min(ladder) if ladder else None
    return f"≤ {min(ok):g}" if low is not None and min(ok) <= low else f"{min(ok):g}"


def reference(rungs: list[Rung], threshold: float) -> str:
    """Magnitude where the known-parameter evidence crosses the threshold (log–log interpolation)."""
    pts = sorted((r.magnitude, r.evidence) for r in rungs)
    for (m0, e0), (m1, e1) in zip(pts, pts[1:]):
        if e0 <= threshold < e1:
            if e0 <= 0:  # no log–log line through a non-positive evidence: give the bracket
                return f"{m0:g}–{m1:g}"
            f = (np.log(threshold) - np.log(e0)) / (np.log(e1) - np.log(e0))
            return f"{np.exp(np.log(m0) + f * (np.log(m1) - np.log(m0))):.3g}"
    if pts and pts[0][1] > threshold:
        return f"< {pts[0][0]:g}"
    return f"> {pts[-1][0]:g}" if pts else "–"


def run(systems: list[str], effects: list[str], seeds: int, cycles: int, budget: float,
        ladders: dict[str, list[float]] | None = None) -> tuple[list[tuple[str, str, list[Rung]]], list[str]]:
    """Search every (system, effect) pair within ``budget`` seconds; returns the results and the skipped."""
    cfg = DiagnoseConfig()
    t0 = time.time()
    out, skipped = [], []
    for system in systems:
        for name in effects:
            if time.time() - t0 > budget:
                skipped.append(f"{system} {name}")
                continue
            out.append((system, name, search(system, name, seeds, cycles, cfg, (ladders or {}).get(name))))
    return out, skipped


def table(results: list[tuple[str, str, list[Rung]]], threshold: float) -> list[str]:
    lines = ["| system | effect (target) | unit | rungs tried: named / recordings (known-parameter evidence, nats) "
             "| detection limit (≥ 90 % named) | reference: known-parameter evidence = threshold |",
             "|---|---|---|---|---|---|"]
    for system, name, rungs in results:
        tgt = LADDERS[name][0][system]
        tried = "; ".join(f"{r.magnitude:g}: {r.named}/{r.runs}{' stopped' if r.stopped else ''} "
                          f"({r.evidence:.0f})" for r in rungs)
        lines.append(f"| {system} | `{name}`{' ' + tgt if tgt else ''} | {UNITS[name]} | {tried} "
                     f"| **{limit(rungs, LADDERS[name][1])}** | {reference(rungs, threshold)} |")
    return lines


def _previous(text: str) -> tuple[list[str], list[str], list[tuple[str, str]]]:
    """The run lines, table rows and their (system, effect) pairs of an earlier results file."""
    runs = [ln.split(": rows ")[0] for ln in text.splitlines() if ln.startswith(("Generated by ", "- `benchmarks/"))]
    rows, pairs = [], []
    for ln in text.splitlines():
        cells = [c.strip() for c in ln.strip().strip("|").split("|")]
        if ln.startswith("| ") and len(cells) == 6 and cells[0] in MODELS and cells[1].startswith("`"):
            rows.append(ln)
            pairs.append((cells[0], cells[1].split("`")[1]))
    return runs, rows, pairs


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    ap.add_argument("--systems", nargs="+", default=["purcell3", "swimmer9"], choices=list(MODELS))
    ap.add_argument("--effects", nargs="+", default=list(LADDERS), choices=list(LADDERS))
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--cycles", type=int, default=60)
    ap.add_argument("--budget", type=float, default=1500.0, help="seconds; no new effect is started after it")
    ap.add_argument("--out", default="docs/results/detection_limit.md")
    ap.add_argument("--combine", nargs="+", metavar="FILE",
                    help="run nothing: combine these results files (a later file's row wins) into --out")
    ap.add_argument("--quick", action="store_true", help="smoke run: purcell3 rest offset, 2 rungs, 2 seeds, 8 cycles")
    a = ap.parse_args(argv)
    thr = DiagnoseConfig().evidence_threshold
    if a.quick:
        res, _ = run(["purcell3"], ["spring_rest_offset"], 2, 8, 1e9, {"spring_rest_offset": [0.003, 0.1]})
        print("\n".join(table(res, thr)))
        return 0
    t0 = time.time()
    out = Path(a.out)
    if a.combine:
        files, by_pair, source = [], {}, {}
        for i, f in enumerate(a.combine):
            old_runs, old_rows, old_pairs = _previous(Path(f).read_text())
            files.append([ln.removeprefix("Generated by ").removeprefix("- ").rstrip(".") for ln in old_runs])
            by_pair.update(zip(old_pairs, old_rows))
            source.update((pair, i) for pair in old_pairs)
        order = [(sy, n) for sy in a.systems for n in a.effects]
        covered_pairs = [pair for pair in order if pair in by_pair]
        rows = table([], thr) + [by_pair[pair] for pair in covered_pairs]
        skipped = [f"{sy} {n}" for sy, n in order if (sy, n) not in by_pair]
        runs = [f"Combined by `benchmarks/detection_limit.py --combine` ({stamp()}); each row is from one of these "
                "runs:", ""]
        for i, file_runs in enumerate(files):
            mine = [f"{sy} {n}" for sy, n in covered_pairs if source[(sy, n)] == i]
            if mine:
                runs.append(f"- {'; '.join(file_runs)}: rows {', '.join(mine)}.")
    else:
        res, skipped = run(a.systems, a.effects, a.seeds, a.cycles, a.budget)
        rows = table(res, thr)
        command = (f"`benchmarks/detection_limit.py --systems {' '.join(a.systems)}"
                   + (f" --effects {' '.join(a.effects)}" if list(a.effects) != list(LADDERS) else "")
                   + f" --seeds {a.seeds} --cycles {a.cycles} --budget {a.budget:g}` on {machine()}, {stamp()} "
                   f"({time.time() - t0:.0f} s)")
        runs, covered_pairs = [f"Generated by {command}."], [(sy, n) for sy, n, _ in res]
    covered = ", ".join(f"{s} {n}" for s, n in covered_pairs)
    text = "\n".join([
        "# Detection limit of the diagnosis (power per effect and system)",
        "",
        *runs,
        "",
        f"Each rung: {a.seeds} seeded {a.cycles}-cycle recordings with the effect injected, diagnosed with every "
        "suspect on; *named* = the effect on its target is reported (or is in a confounded group with the "
        "reported one).  Bisection over each effect's ladder (the rungs tried are listed); a rung stops as soon "
        "as 90 % is out of reach (*stopped*: failed).  Nulls stay clean: "
        "`docs/results/evidence_threshold.md`.",
        f"Reference: the magnitude at which the true effect's held-out evidence with *known* parameters "
        f"(equation error, no fitting; mean over the seeds) crosses the threshold ({thr:g} nats), "
        "interpolated log–log between the rungs tried — below it no method using this evidence rule could "
        "name it.  Note the first effect needs only positive evidence once a channel is located, so the "
        "pipeline can name an effect below this reference.",
        "",
        f"Covered: {covered or 'nothing'}.",
        f"Not covered (budget): {', '.join(skipped) or 'none'}.",
        "",
        *rows,
        "",
    ])
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
