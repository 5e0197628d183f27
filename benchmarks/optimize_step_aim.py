"""Where a step's predicted gain goes wrong: the model's passive response, or its body velocity.

The loop's step maximises the speed the SUDS model predicts for a candidate gait: the model's own
periodic steady state along it, passive joints included (``loop.predict_value``).  Here one model
per seed (the loop's start run of the robot's nominal gait: 1 settling + 4 cycles, its default
perturbation) proposes the loop's step at several trust radii κ (half-wave, as from a symmetric
start), and each candidate is judged three ways:

- **model gain**: the model's prediction of the candidate minus its prediction of the nominal gait;
- **true gain**: the same on the physics (``evaluate_gait``, passive periodic steady state);
- **body miss**: the candidate run on the physics without perturbation or noise (1 + 4 cycles), and
  the model's body velocity along those *true* shapes (``data.motion_miss``): the cycle-mean
  translation missed, as a fraction of the true one.  Small here while the model gain is far off
  the true one: the error is in the passive shapes the model predicts, not in the body velocity.
- **passive excursion**: the step's largest predicted |δ_p| over the data's σ_δp (reported by the
  step, not bounded by it): how far the candidate's predicted passive shapes leave the data.

    python benchmarks/optimize_step_aim.py [ROBOT ...]      # → docs/results/optimize_step_aim.md
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _common import SNAKE5, machine, stamp, write

from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.core.optimize.data import DataOptimizeConfig, learn_model, motion_miss, optimize_from_data
from suds_ros.core.optimize.loop import LoopConfig, _Robot, _trim, predict_value
from suds_ros.core.optimize.physics import evaluate_gait
from suds_ros.core.physics.gait import gait_limits, nominal_gait
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import load_system

ROBOTS = {"purcell3": "purcell3", "snake5": SNAKE5, "swimmer9": "swimmer9"}
SEEDS = (0, 1, 2)
KAPPAS = (1.0, 2.0, 4.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("robots", nargs="*", metavar="ROBOT", help=f"of {', '.join(ROBOTS)} (default: all)")
    args = ap.parse_args()
    robots = args.robots or list(ROBOTS)
    if set(robots) - set(ROBOTS):
        ap.error(f"ROBOT: expected some of {list(ROBOTS)}, got {sorted(set(robots) - set(ROBOTS))}")
    lines = ["# Where a step's predicted gain goes wrong", "",
             f"Measured {stamp()} on {machine()} by `benchmarks/optimize_step_aim.py`.", "",
             "\n\n".join(__doc__.split("\n\n")[1:3]), "",
             "| robot | seed | κ | model gain (m/s) | true gain (m/s) | model / true gain | body miss | "
             "passive excursion (σ) |", "|---|---|---|---|---|---|---|---|"]
    summary = []
    for name in robots:
        t0 = time.perf_counter()
        system = load_system(ROBOTS[name])
        nom, limits = nominal_gait(system), gait_limits(system)
        v0 = evaluate_gait(system, nom)["speed"]
        model_g, true_g, body = [], [], []
        for seed in SEEDS:
            cfg = LoopConfig(budget_cycles=10, seed=seed)
            rec, _ = _Robot(system, nom, cfg).run(nom, cfg.settle_cycles + cfg.first_cycles)
            model = learn_model(_trim(rec, cfg.settle_cycles, cfg.samples_per_cycle))
            p0 = predict_value(model, nom, "speed")
            for kappa in KAPPAS:
                dcfg = DataOptimizeConfig(objective="speed", order=3, trust=kappa, draws=0, min_gain_sigmas=0.0,
                                          seed=seed, max_rotation=cfg.max_rotation * cfg.rotation_margin,
                                          half_wave=True)
                step = optimize_from_data(model, dcfg, limits=limits, start=nom)
                gait = step.gait
                mg = predict_value(model, gait, "speed") - p0
                tg = evaluate_gait(system, gait)["speed"] - v0
                clean = simulate(system, SimConfig(cycles=cfg.settle_cycles + 4, seed=seed, gait=gait,
                                                   gait_hz=gait.gait_hz, ou_std=0.0, noise_std=0.0))
                try:
                    miss = motion_miss(model, _trim(clean, cfg.settle_cycles, cfg.samples_per_cycle)).translation
                except (SudsDataError, SudsConfigError) as exc:
                    miss = float("nan")
                    print(f"{name} seed {seed} κ {kappa}: no body miss ({exc})", flush=True)
                model_g.append(mg)
                true_g.append(tg)
                body.append(miss)
                ratio = f"{mg / tg:.1f}" if abs(tg) > 1e-3 * v0 else "—"
                lines.append(f"| {name} | {seed} | {kappa:g} | {mg:+.4f} | {tg:+.4f} | {ratio} | {miss:.3f} | "
                             f"{step.passive_excursion:.1f} |")
                print(lines[-1], flush=True)
        mg_a, tg_a = np.asarray(model_g), np.asarray(true_g)
        summary.append(f"- {name}: correlation of model and true gain {np.corrcoef(mg_a, tg_a)[0, 1]:+.2f} over "
                       f"{mg_a.size} steps; median |model − true gain| {np.median(np.abs(mg_a - tg_a)):.4f} m/s "
                       f"against a median true gain of {np.median(tg_a):+.4f}; body miss median "
                       f"{np.nanmedian(body):.3f}, largest {np.nanmax(body):.3f} ({time.perf_counter() - t0:.0f} s).")
    lines += ["", "## Summary", "", *summary, ""]
    write("optimize_step_aim.md", "\n".join(lines))


if __name__ == "__main__":
    main()
