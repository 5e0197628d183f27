"""`suds optimize BAG` measured: one data-driven step from one recording, against the physics optimum.

For each robot and seed: record N cycles of the start gait (the nominal sinusoid, or a poor start:
half its amplitude) with the default OU perturbation, fit the SUDS model to the whole recording,
take one trust-region step (κ = 2), and run the proposed gait on the true physics at its passive
periodic steady state.  The limit is the physics optimiser's best gait (order 3, 4 starts).
Writes the section "Data-driven step" into docs/results/optimize_data.md.

    python benchmarks/optimize_data.py            # purcell3, snake5, swimmer9; seeds 0-2
"""

from __future__ import annotations

import sys
import time

from _common import SNAKE5, machine, stamp, write

from suds_ros.core.optimize.data import DataOptimizeConfig, learn_model, optimize_from_data
from suds_ros.core.optimize.physics import OptimizeConfig, evaluate_gait, optimize_gait
from suds_ros.core.physics.gait import constraint_violations, gait_limits, nominal_gait
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import load_system

ROBOTS = (("purcell3", 15), (SNAKE5, 25), ("swimmer9", 45))


def main(seeds: tuple[int, ...] = (0, 1, 2)) -> None:
    rows = ["| robot | start | cycles | seed | start true | proposed true | gain | % of limit (start → proposed) "
            "| true rotation/cycle | predicted start | predicted proposed ± σ | predicted gain ± σ | trust used "
            "| within bounds | time s |", "|" + "---|" * 15]
    limits_rows = ["| robot | limit (m/s) | time s |", "|---|---|---|"]
    for spec, cycles in ROBOTS:
        system = load_system(spec)
        nom = nominal_gait(system)
        limits = gait_limits(system)
        t0 = time.perf_counter()
        best = optimize_gait(system, OptimizeConfig(order=3, starts=4)).value
        limits_rows.append(f"| {system.name} | {best:.5f} | {time.perf_counter() - t0:.0f} |")
        print(limits_rows[-1], flush=True)
        half = nom.from_vector(0.5 * nom.to_vector(), nom.order)
        for kind, start in (("nominal", nom), ("half amplitude", half)):
            for seed in (seeds if kind == "nominal" else seeds[:1]):
                t0 = time.perf_counter()
                rec = simulate(system, SimConfig(cycles=cycles, seed=seed, gait=start, gait_hz=nom.gait_hz))
                model = learn_model(rec)
                res = optimize_from_data(model, DataOptimizeConfig(seed=seed), limits=limits, start=start)
                secs = time.perf_counter() - t0
                old = evaluate_gait(system, start)
                new = evaluate_gait(system, res.gait)
                ok = "yes" if not constraint_violations(res.gait, limits) else "NO"
                g = res.value - res.recorded_value
                rows.append(
                    f"| {system.name} | {kind} | {cycles} | {seed} | {old['speed']:.5f} | {new['speed']:.5f} | "
                    f"{100 * (new['speed'] / old['speed'] - 1):+.1f} % | {100 * old['speed'] / best:.1f} → "
                    f"{100 * new['speed'] / best:.1f} % | {new['rotation']:+.3f} | {res.recorded_value:.5f} | "
                    f"{res.value:.5f} ± {res.value_std or 0:.5f} | {g:+.5f} ± {res.gain_std or 0:.5f} | "
                    f"{res.trust_used:.2f} / {res.trust_radius:.2f} | {ok} | {secs:.0f} |")
                print(rows[-1], flush=True)
    text = "\n".join([
        "# `suds optimize BAG`: one data-driven step from one recording, measured", "",
        f"Measured {stamp()} on {machine()} by `benchmarks/optimize_data.py` (one process, nice 5, the "
        "other core busy with other work).", "",
        "## The limit: the physics optimiser (`suds optimize --physics`, order 3, 4 starts)", "",
        *limits_rows, "",
        "## One step (κ = 2 σ of the data's δ spread, order 3, 16 coefficient draws)", "",
        "Recording: the start gait with the default OU perturbation (0.175 rad, κ = 8 /s), 100 Hz, "
        "1 mm / 1 mrad noise; the model fitted to the whole recording (the shipped model selection). "
        "'true' = the gait run on the physics at its passive periodic steady state; 'predicted' = the "
        "learned model's cycle; σ = spread over coefficient draws.", "",
        *rows, ""])
    write("optimize_data.md", text)


if __name__ == "__main__":
    main(tuple(int(a) for a in sys.argv[1:]) or (0, 1, 2))
