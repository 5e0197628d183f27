"""The offline loop on the efficiency objective: distance per cycle over the actuators' work, from data.

Runs ``optimize_loop(objective="efficiency")`` on simulated robots that record their actuator
effort, from the nominal gait (the loop's speed floor is its start gait's measured speed, and the
spec's floor is the nominal gait's), and judges every returned gait on the
physics (its passive periodic steady state) against the physics optimiser's best gait under the
same constraints (order 3, 4 starts, speed no lower than the nominal gait's, straight course).

    python benchmarks/optimize_efficiency.py            # writes docs/results/optimize_efficiency.md
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _common import SNAKE5, machine, stamp, write

from suds_ros.core.optimize.loop import LoopConfig, measure_cycles, optimize_loop
from suds_ros.core.optimize.physics import OptimizeConfig, evaluate_gait, optimize_gait
from suds_ros.core.physics.gait import constraint_violations, gait_limits, nominal_gait
from suds_ros.core.physics.sim import SimConfig
from suds_ros.core.physics.stream import StreamingSimulator
from suds_ros.core.physics.systems import load_system

ROBOTS = {"purcell3": ("purcell3", 40), "snake5": (SNAKE5, 60)}  # name: (spec, budget cycles)


def work_ratios(system: object, gait: object, seeds: list[int], cycles: int = 5) -> tuple[list[float], list[float]]:
    """Per seed: the raw Σ τ·Δr per cycle and the phase-averaged work, each over the physics' work.

    Measured on ``cycles`` cycles of ``gait`` run with the loop robot's default excitation, after
    one settling cycle.
    """
    cfg = LoopConfig(budget_cycles=cycles + 1)
    true = evaluate_gait(system, gait)  # type: ignore[arg-type]
    w_true = true["distance"] / true["efficiency"]
    raw, phased = [], []
    for seed in seeds:
        sim = StreamingSimulator(system, SimConfig(samples_per_cycle=cfg.samples_per_cycle, gait_hz=gait.gait_hz,
                                                   kappa=cfg.kappa, ou_std=cfg.ou_std, noise_std=cfg.noise_std,
                                                   warmup=0.0, seed=seed, gait=gait), effort=True)
        sim.step(cfg.samples_per_cycle)  # the settling cycle
        c = sim.step(cycles * cfg.samples_per_cycle + 1)
        ra = c.r[:, list(system.actuated)]  # type: ignore[attr-defined]
        raw.append(float(np.sum(c.effort[1:] * np.diff(ra, axis=0))) / cycles / w_true)
        phased.append(measure_cycles(c.pose, cfg.samples_per_cycle, gait.gait_hz, [(ra, c.effort)]).work / w_true)
    return raw, phased


def run(name: str, seeds: list[int]) -> list[str]:
    spec, budget = ROBOTS[name]
    system = load_system(spec)
    nom = nominal_gait(system)
    limits = gait_limits(system)
    t0 = time.perf_counter()
    best = optimize_gait(system, OptimizeConfig(order=3, starts=4, objective="efficiency"))
    t_limit = time.perf_counter() - t0
    limit = best.value
    nominal = evaluate_gait(system, nom)
    raw, phased = work_ratios(system, nom, seeds)
    lines = [f"## {name}", "",
             f"Limit {limit:.5f} m/J ({t_limit:.0f} s) at speed {evaluate_gait(system, best.gait)['speed']:.4f} m/s; "
             f"the nominal gait: {nominal['efficiency']:.5f} m/J ({100 * nominal['efficiency'] / limit:.1f} % of "
             f"the limit) at {nominal['speed']:.4f} m/s (the speed floor). Budget {budget} cycles.", "",
             "The nominal gait's work per cycle measured over 5 cycles under the excitation, over its work on "
             "the physics, seeds " + ", ".join(map(str, seeds)) + ": raw Σ τ·Δr "
             + ", ".join(f"{x:.2f}" for x in raw) + "; phase-averaged (what the loop uses) "
             + ", ".join(f"{x:.2f}" for x in phased) + ".", "",
             "| start | seed | start: true % of limit | returned: true % of limit | returned: true speed / floor | "
             "returned: true rotation | returned: measured (m/J) ± se | returned: predicted | start: measured / true "
             "| gaits run (accepted) | in bounds | time s |", "|" + "---|" * 12]
    for kind, start in (("nominal", nom),):  # the loop's speed floor is its start gait's: the spec's is the nominal's
        for seed in seeds:
            t1 = time.perf_counter()
            res = optimize_loop(system, LoopConfig(budget_cycles=budget, seed=seed, objective="efficiency"),
                                start=start, limits=limits)
            secs = time.perf_counter() - t1
            first = evaluate_gait(system, start)
            out = evaluate_gait(system, res.gait)
            its = res.iterations
            kept = sum(it.accepted and not it.note.startswith("incumbent re-run") for it in its[1:])
            bounds = all(not constraint_violations(it.gait, limits) for it in its)
            m0 = its[0].measured
            lines.append(
                f"| {kind} | {seed} | {100 * first['efficiency'] / limit:.1f} | {100 * out['efficiency'] / limit:.1f} "
                f"| {out['speed'] / nominal['speed']:.3f} | {out['rotation']:+.3f} | "
                f"{res.measured.efficiency:.5f} ± {res.measured.efficiency_se:.5f} | {res.predicted:.5f} | "
                f"{m0.efficiency / first['efficiency']:.2f} | {len(its)} ({kept}) | {'yes' if bounds else 'NO'} | "
                f"{secs:.0f} |")
            print(lines[-1], flush=True)
    return lines + [""]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", nargs="+", choices=list(ROBOTS), default=list(ROBOTS))
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    args = ap.parse_args()
    np.seterr(all="ignore")
    lines = ["# `suds optimize --simulate … --objective efficiency`: the loop on measured work", "",
             f"Measured {stamp()} on {machine()} by `benchmarks/optimize_efficiency.py`.", "",
             "The loop's defaults (`optimize_loop.md`), objective `efficiency`: the simulated robot records its "
             "actuator effort (the effort over each sample period, as `suds simulate --effort` does). A gait's "
             "measured efficiency is its measured distance per cycle over the work ∮ τ̄·dθ̄ of its cycles' "
             "phase-averaged effort and actuated angles (the excitation's zero-mean work averages out to first "
             "order); its standard error is the jackknife's over the cycles. A candidate is kept when it measures "
             "more efficient, with a |rotation| ≤ 0.05 rad/cycle (read off the SUDS model of its own cycles: "
             "`rotation_from_model`) and a measured speed no more than 1 se "
             "(of the difference) under the start gait's (`floor_sigmas`). The step predicts with the learned "
             "torque model. 'true' = on the physics at the passive periodic steady state, after the run; the "
             "loop never sees it. 'returned: true speed / floor' below 1 means the returned gait breaks the "
             "spec's speed floor on the physics (its % of the limit then overstates it).", ""]
    for name in args.robots:
        lines += run(name, args.seeds)
    lines += ["## Notes", "",
              "- Only the nominal start: the loop holds the speed at no less than its *start* gait's, the spec "
              "at no less than the nominal gait's, so from a poorer start the two limits differ.",
              "- The measured speed of a slow, efficient gait is noisy (the excitation moves the robot as much "
              "as the gait does), so a gait well under the floor can measure within a standard error of it and "
              "be kept: the 'true speed / floor' column says when that happened.",
              "- 'start: measured / true' shows what the excitation does to a measured efficiency: the robot "
              "measured under the OU drive is less efficient than the same gait without it, and only "
              "differences between gaits matter to the loop.", ""]
    print(write("optimize_efficiency.md", "\n".join(lines)))


if __name__ == "__main__":
    main()
