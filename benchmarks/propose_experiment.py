"""Whether proposed experiments settle ambiguous diagnoses (issue 21, item 4; target ≥ 80 %).

Run: ``python benchmarks/propose_experiment.py [--cases N] [--jobs J]`` (writes
docs/results/propose_experiment.md).

Cases are drawn as in ``benchmarks/diagnose_sweep.py`` (built-in swimmers and model-file
robots, 1–3 effects, aligned recordings of ``--cycles`` cycles).  Each case is diagnosed; a case
whose first finding has alternatives gets a proposal per alternative
(:func:`~suds_ros.core.diagnosis.experiment.propose_for_report`).  The first separable proposal's
gait is then run on the *true* robot (the same effects, the usual OU perturbation on top, a new
seed) for the cycles the proposal asks for (at most ``--max-cycles``), and the new recording is
diagnosed against the nominal model.  The ambiguity counts as settled when the new report is
fully correct by the sweep's rule and no longer lists, as an alternative, what was confused.
Cases without alternatives are counted but not re-run; proposals that say "the same physics"
(no admissible drive separates them) are listed apart.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine, stamp, write  # noqa: E402
from diagnose_sweep import SYSTEMS, chain, draw_effects, judge, short  # noqa: E402

from suds_ros.core.diagnosis import DiagnoseConfig, diagnose  # noqa: E402
from suds_ros.core.diagnosis.experiment import propose_for_report  # noqa: E402
from suds_ros.core.physics.effects import apply_effects  # noqa: E402
from suds_ros.core.physics.rft import RFTChain  # noqa: E402
from suds_ros.core.physics.sim import SimConfig, simulate  # noqa: E402


def run_case(args: tuple[int, str, list[dict], int, int, int]) -> tuple[int, str, str]:
    """(case, outcome, markdown row); outcome is one of none / same / settled / unsettled."""
    from suds_ros.core.blas import pin_blas_threads

    pin_blas_threads(1)
    i, system, effects, seed, cycles, max_cycles = args
    base = chain(system)
    model, delay = apply_effects(base, effects)
    rec = simulate(RFTChain(model), SimConfig(cycles=cycles, seed=seed, pose_delay=delay, gait_hz=base.gait_hz))
    cfg = DiagnoseConfig()
    rep = diagnose(rec, base, cfg)
    injected = "; ".join(e["name"] + (f" {e.get('joint') or e.get('link')}" if e.get("joint") or e.get("link")
                                      else "") for e in effects) or "none"
    _, _, text = judge(effects, rep)
    if not rep.effects or not rep.effects[0].alternatives:
        return i, "none", f"| {i} | {short(system)} | {injected} | {text} | – | – | – |"
    props = propose_for_report(rep, base, rec.dt, cfg)
    sep = [p for p in props if p.gait is not None]
    if not sep:
        return i, "same", (f"| {i} | {short(system)} | {injected} | {text} | the same physics "
                           f"({max(p.nats_per_cycle for p in props):.3g} nats/cycle at best) | – | – |")
    p = max(sep, key=lambda q: q.nats_per_cycle)
    n = min(p.cycles or max_cycles, max_cycles)
    cfg2 = SimConfig(cycles=n, seed=seed + 1, pose_delay=delay, gait_hz=base.gait_hz, gait=p.gait)
    rec2 = simulate(RFTChain(model), cfg2)
    rep2 = diagnose(rec2, base, cfg)
    ok2, _, text2 = judge(effects, rep2)
    confused = {a.label for a in rep.effects[0].alternatives}
    still = {a.label for e in rep2.effects for a in e.alternatives} & confused
    settled = ok2 and not still
    return i, "settled" if settled else "unsettled", (
        f"| {i} | {short(system)} | {injected} | {text} | {p.alternative}: {p.nats_per_cycle:.3g} vs "
        f"{p.nominal_nats_per_cycle:.3g} nats/cycle, {p.cycles} cycles | {n} cycles: {text2} "
        f"| {'yes' if settled else 'NO'} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=20)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--cycles", type=int, default=40)
    ap.add_argument("--max-cycles", type=int, default=60)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="propose_experiment.md")
    args = ap.parse_args()
    from concurrent.futures import ProcessPoolExecutor

    rng = np.random.default_rng(args.seed)
    cases = []
    for i in range(args.cases):
        system = SYSTEMS[i % len(SYSTEMS)]
        effects = []
        while not effects:
            effects = draw_effects(rng, system, 3, catalogue_only=False)
        cases.append((i, system, effects, int(rng.integers(100, 10_000)), args.cycles, args.max_cycles))
    t0 = time.perf_counter()
    rows: dict[int, tuple[str, str]] = {}
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for i, outcome, row in pool.map(run_case, cases):
            rows[i] = (outcome, row)
            print(row, flush=True)
    count = {k: sum(1 for o, _ in rows.values() if o == k) for k in ("none", "same", "settled", "unsettled")}
    proposed = count["settled"] + count["unsettled"]
    text = "\n".join([
        "# Proposed experiments: do they settle ambiguous diagnoses?",
        "",
        f"Measured {stamp()} on {machine()} with `python benchmarks/propose_experiment.py --cases {args.cases} "
        f"--seed {args.seed} --cycles {args.cycles} --max-cycles {args.max_cycles} --jobs {args.jobs}` "
        f"({time.perf_counter() - t0:.0f} s).",
        "",
        f"{args.cases} cases drawn as in the diagnosis sweep (1–3 effects, aligned, {args.cycles} cycles). "
        f"{count['none']} had no ambiguous finding; {count['same']} were ambiguous between explanations no "
        f"admissible drive separates (the same physics for that robot, said so); {proposed} got a "
        f"proposed gait, run on the true robot: **{count['settled']} of {proposed} settled** "
        "(target ≥ 80 %).",
        "",
        "| case | robot | injected | first diagnosis | proposal | diagnosis of the proposed run | settled |",
        "|---|---|---|---|---|---|---|",
        *[rows[i][1] for i in sorted(rows)],
        "",
    ])
    write(args.out, text)


if __name__ == "__main__":
    main()
