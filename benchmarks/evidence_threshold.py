"""Calibrate the forward-selection threshold (``DiagnoseConfig.evidence_threshold``) on null recordings.

Null recordings: seeded 60-cycle purcell3 and swimmer9 simulations with no effect, diagnosed against
their own nominal model with every suspect on (catalogue and model parameters, the default).  For
each, the locate and naming stages alone (:func:`suds_ros.core.diagnosis.rank_effects`; threshold
0, one step) give

* the best single candidate's held-out evidence — what a spurious *first* effect would score; a
  null recording is a false positive at threshold T when that evidence exceeds T;
* whether any channel was located (the pipeline's own gate: nothing is named otherwise).

The false-positive rate at the threshold and its exact one-sided 95 % upper bound
(Clopper–Pearson) are reported.  Optionally (``--second``) recordings with one true effect give the
best *second* effect's evidence gain (a spurious addition).

Usage: PYTHONPATH=. .venv/bin/python benchmarks/evidence_threshold.py [--nulls 50] [--second 0]
Writes docs/results/evidence_threshold.md.
"""

from __future__ import annotations

import argparse
from collections import Counter
import dataclasses
import time

import numpy as np
import scipy.stats

import _common  # noqa: F401  (puts the repository on sys.path)
from _common import machine, stamp, write
from suds_ros.core.diagnosis import DiagnoseConfig, rank_effects
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import purcell3_model, swimmer9_model

MODELS = {"purcell3": purcell3_model, "swimmer9": swimmer9_model}
SINGLES = {
    "purcell3": [dict(name="spring_rest_offset", joint="joint_2", offset=0.2),
                 dict(name="joint_coulomb_friction", joint="joint_2", mu=0.4),
                 dict(name="stiffness_to_drag_error", scale=0.7)],
    "swimmer9": [dict(name="spring_rest_offset", joint="joint_6", offset=-0.15),
                 dict(name="joint_viscous_damping", joint="joint_5", d=0.5),
                 dict(name="background_flow", vx=-0.05, vy=0.08)],
}
CYCLES = 60


def gains(system: str, effects: list[dict], seed: int, steps: int) -> tuple[list[float], int, str]:
    """Best evidence gain at each forward step (threshold 0), located channels, best first label."""
    base = MODELS[system]()
    model, delay = apply_effects(base, effects)
    rec = simulate(RFTChain(model), SimConfig(cycles=CYCLES, seed=seed, pose_delay=delay))
    cfg = dataclasses.replace(DiagnoseConfig(), evidence_threshold=0.0, max_effects=steps)
    naming, located = rank_effects(rec, base, cfg)
    best = naming.ranking[0].label if naming.ranking else ""
    return list(naming.gains), len(located), best


def clopper_pearson_upper(k: int, n: int, level: float = 0.95) -> float:
    """Exact one-sided upper confidence bound on a binomial rate after k successes in n trials."""
    return float(scipy.stats.beta.ppf(level, k + 1, n - k)) if k < n else 1.0


def _parse(path: str) -> list[tuple[str, int, str, str, float, str, int]]:
    """The per-recording rows of a previous output of this script (for ``--from``)."""
    out = []
    for line in open(path, encoding="utf-8"):
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 7 and cells[0] in MODELS:
            out.append((cells[0], int(cells[1]), cells[2], cells[3], float(cells[4]), cells[5], int(cells[6])))
    return out


def measure(nulls: int, nsecond: int) -> list[tuple[str, int, str, str, float, str, int]]:
    """Run the null (and optional one-effect) recordings; one row per recording."""
    rows = []
    for system in MODELS:
        for s in range(nulls):
            g, nloc, best = gains(system, [], 5000 + s, 1)
            rows.append((system, 5000 + s, "none", "first", g[0], best, nloc))
            print(rows[-1], flush=True)
        for s in range(nsecond):
            eff = SINGLES[system][s % len(SINGLES[system])]
            g, nloc, _ = gains(system, [eff], 6000 + s, 2)
            if len(g) > 1:
                rows.append((system, 6000 + s, str(eff["name"]), "second", g[1], "", nloc))
                print(rows[-1], flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--nulls", type=int, default=50, help="60-cycle null seeds per system")
    ap.add_argument("--second", type=int, default=0, help="60-cycle one-effect seeds per system")
    ap.add_argument("--from", dest="source", metavar="MD",
                    help="re-summarise the rows of a previous output at the current default threshold "
                         "(no recording is re-run)")
    args = ap.parse_args()
    t0 = time.time()
    data = _parse(args.source) if args.source else measure(args.nulls, args.second)
    first = [r[4] for r in data if r[3] == "first"]
    located = [r[6] > 0 for r in data if r[3] == "first"]
    second = [r[4] for r in data if r[3] == "second"]
    rows = [f"| {a} | {b} | {c} | {d} | {e:.1f} | {f} | {g} |" for a, b, c, d, e, f, g in data]
    thr = DiagnoseConfig().evidence_threshold
    allv = np.array(first)
    n = allv.size
    fp = int(np.sum(allv > thr))
    fp_pipe = int(np.sum((allv > 0) & np.array(located)))
    nloc = int(np.sum(located))
    q95 = float(np.quantile(allv, 0.95))
    # the smallest whole-nat threshold with at most one null above it (Clopper–Pearson bound < 5 %
    # from 94 nulls on)
    srt = np.sort(allv)[::-1]
    need = float(np.ceil(srt[1] if n > 1 else srt[0]))
    per = {sy: np.array([r[4] for r in data if r[0] == sy and r[3] == "first"]) for sy in MODELS}
    orig = ""
    if args.source:
        orig = next((ln.strip() for ln in open(args.source, encoding="utf-8") if ln.startswith("Generated by")), "")
        orig = " The rows were measured by: " + orig.removeprefix("Generated by ").rstrip(".") + "."
    how = ("`benchmarks/evidence_threshold.py --from PREVIOUS.md` (the rows below re-summarised at the "
           "current default; recordings not re-run)" if args.source else
           f"`benchmarks/evidence_threshold.py --nulls {args.nulls} --second {args.second}`")
    lines = [
        "# Evidence threshold of the stepwise selection (calibration on null recordings)",
        "",
        f"Generated by {how} on {machine()}, {stamp()} ({time.time() - t0:.0f} s).{orig}",
        "",
        "Null recordings: seeded 60-cycle simulations with no effect (purcell3 and swimmer9, seeds "
        "5000… each), diagnosed with every suspect on (catalogue effects and "
        "model parameters, the default).  Evidence = held-out log-likelihood gain of the equation error "
        "minus the BIC penalty (nats) of the best single candidate (*first*: a spurious first effect).",
        "",
        f"- null recordings: **{n}**; evidence largest {allv.max():.1f}, 95 % quantile {q95:.1f}, "
        f"median {np.median(allv):.1f} nats; per system: "
        + ", ".join(f"{sy} {v.size} (largest {v.max():.1f}, median {np.median(v):.1f})"
                    for sy, v in per.items() if v.size),
        f"- threshold (`DiagnoseConfig.evidence_threshold`): **{thr:g} nats**",
        f"- nulls whose best candidate passes the threshold: **{fp} of {n}** "
        f"(rate {fp / n:.3f}; exact one-sided 95 % upper bound (Clopper–Pearson) "
        f"**{clopper_pearson_upper(fp, n):.3f}**)",
        f"- smallest threshold with at most one null above it: {need:g} nats "
        f"({'the default is at or above it' if thr >= need else 'ABOVE the default: raise it'})",
        f"- the pipeline's own gate: a channel was located on {nloc} of {n} nulls; nulls on which an "
        f"effect would be named (located and positive evidence): {fp_pipe} of {n} "
        f"(95 % upper bound {clopper_pearson_upper(fp_pipe, n):.3f})",
    ]
    if second:
        sec = np.array(second)
        lines.append(
            f"- spurious additions (*second*, after one true effect): {int(np.sum(sec > thr))} of {sec.size} "
            f"pass the threshold (largest {sec.max():.1f} nats); the output-error check in the simulator "
            "(`member_z`) removes such members in the pipeline")
    lines += [
        "",
        "Most frequent best candidate on each system's nulls: " + "; ".join(
            f"{sy} `{lab}` ({k} of {len(cands)}, {min(ev):.1f} to {max(ev):.1f} nats)"
            for sy in MODELS for cands in [[r for r in data if r[0] == sy and r[3] == "first"]] if cands
            for lab, k in [Counter(r[5] for r in cands).most_common(1)[0]]
            for ev in [[r[4] for r in cands if r[5] == lab]]) + ".  "
        "A candidate that comes first on most nulls of a robot is a systematic bias of the equation error "
        "there, not noise.  It is below the noise floor of the replay (no channel located, nothing named), "
        "but it sets the bar for second and third effects and discovery terms, and being systematic it grows "
        "about linearly with the recording's length; the per-recording calibration subtracts what each "
        "candidate gains on null replays of the recording itself.",

        "",
        "| system | seed | injected | step | evidence (nats) | best candidate | located channels |",
        "|---|---|---|---|---|---|---|",
        *rows,
        "",
    ]
    write("evidence_threshold.md", "\n".join(lines))


if __name__ == "__main__":
    main()
