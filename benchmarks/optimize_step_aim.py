"""Where a step's predicted gain goes wrong: the model's body velocity, or the passive shapes it predicts.

The loop's step maximises the speed the SUDS model predicts for a candidate gait: the model's own
periodic steady state along it, passive joints included (``loop.predict_value``).  Here one model
per seed (the loop's start run of the robot's nominal gait: 1 settling + 4 cycles, its default
perturbation) proposes the loop's step at several trust radii κ (half-wave, as from a symmetric
start), and each candidate is judged against the physics:

- **model gain**: the model's prediction of the candidate minus its prediction of the nominal gait;
- **true gain**: the same on the physics (``evaluate_gait``, passive periodic steady state);
- **body-only gain**: the gain the model predicts when its passive shapes are replaced by the true
  ones.  Each gait (nominal and candidate) is run on the physics without perturbation or noise, and
  the model's cycle (``LearnedCycle.cycle``) is driven along one of its whole cycles with the passive
  joints prescribed (``passive=``); the speed is the chord of that cycle.  The model's own cycle is
  measured the same way (the chord of its steady state from its phase zero), so the model gain
  minus the body-only gain is what the predicted passive shapes add, and the body-only gain minus
  the true gain is the body regression's own error;
- **body error**: the model's speed along the candidate's true shapes over its true speed, minus 1;
  'with the true yaw rate' / 'with the true translation': the same with that part of the model's
  body velocity replaced, step by step, by the physics run's own (the twist between its poses);
- **passive excursion**: the step's largest predicted |δ_p| over the data's σ_δp (reported by the
  step, not bounded by it): how far the candidate's predicted passive shapes leave the data.

The chord gains (model, body-only) are counted from the model's phase zero and are not the
origin-corrected ``predict_value``; where the model's cycle turns they differ a little.

Each robot is measured three ways: the shipped model selection (``IdentifyConfig()``; on a few
cycles it often picks random features of the whole shape, ``kernel_grid``) and the Fourier designs
only (``kernel_grid=(0,)``), both fitted to the recorded pose frame (``learn_model(frame="pose")``),
and the shipped selection in the shape frame (``frame="shape"``, the loop's default since
2026-12-04: the recorded yaw turned by the combination of joint angles it follows,
``data.shape_frame``).  'model' names the design the selection chose.  The body velocities swapped
in are the physics run's own in the model's frame.

    python benchmarks/optimize_step_aim.py [ROBOT ...]      # → docs/results/optimize_step_aim.md
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from _common import SNAKE5, machine, stamp, write

from suds_ros.core import se2
from suds_ros.core.ident.identify import IdentifyConfig
from suds_ros.core.optimize.data import (DataOptimizeConfig, LearnedCycle, LearnedModel, align_shift, learn_model,
                                         optimize_from_data)
from suds_ros.core.optimize.loop import LoopConfig, _Robot, _trim, predict_value, time_shifted
from suds_ros.core.optimize.physics import evaluate_gait
from suds_ros.core.physics.gait import Gait, gait_limits, nominal_gait
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.system import SudsSystem
from suds_ros.core.physics.systems import load_system

ROBOTS = {"purcell3": "purcell3", "snake5": SNAKE5, "swimmer9": "swimmer9"}
SEEDS = (0, 1, 2)
#: the models compared: (identification settings, body frame) — the shipped selection in the recorded
#: pose frame, the Fourier designs alone in it, and the shipped selection in the shape frame (the default)
SELECTIONS = {"shipped, pose frame": (IdentifyConfig(), "pose"),
              "Fourier only, pose frame": (IdentifyConfig(kernel_grid=(0,)), "pose"),
              "shipped, shape frame": (IdentifyConfig(), "shape")}
KAPPAS = (1.0, 2.0, 4.0)


def chord_speeds(system: SudsSystem, model: LearnedModel, gait: Gait, seed: int) -> tuple[float, ...]:
    """Four chords from phase zero, as speeds, of the model's cycles along ``gait``.

    They are: the model's own cycle; the model along the gait's true shapes; the same with its yaw
    rate replaced by the true one; and with its translation velocity replaced.  The true shapes are
    the second whole cycle of a run on the physics (no perturbation, no noise, a whole number of
    cycles of warm-up, sampled at the model cycle's own steps); the true body velocity of each step
    is the twist between the run's consecutive poses (``se2.body_velocity``).
    """
    g = time_shifted(gait, align_shift(model, gait))
    ev = LearnedCycle(model, g.gait_hz, g.order)
    x = g.to_vector()
    own = ev.steady_of(x)
    n, hz = ev.steps, g.gait_hz
    clean = simulate(system, SimConfig(cycles=3, samples_per_cycle=n, gait_hz=hz, gait=g, ou_std=0.0,
                                       noise_std=0.0, warmup=math.ceil(5.0 * hz) / hz, seed=seed))
    shapes = clean.r[n:2 * n + 1]
    ra = g.r(ev.h * np.arange(n + 1))  # the gait's actuated shapes at the model cycle's step times
    if np.max(np.abs(shapes[:, model.act] - ra)) > 1e-6:
        raise RuntimeError("the physics run is not on the model cycle's step times (actuated shapes differ)")
    poses: list[np.ndarray] = []
    ev.cycle(x[None], None, poses=poses, passive=shapes[:, None, model.pas])
    path = np.concatenate([np.zeros((1, 3)), np.concatenate(poses)])
    xi_model = se2.body_velocity(path, ev.h)
    true_path = model.in_frame(clean).pose[n:2 * n + 1]  # (the model's body frame; a Recording's yaw is unwrapped)
    xi_true = se2.body_velocity(true_path, ev.h)

    def chord(xi: np.ndarray) -> float:
        pose = np.zeros((1, 3))
        for row in xi:
            pose = se2.exp_step(pose, ev.h * row[None])
        return float(np.hypot(*pose[0, :2]) * hz)

    true_yaw, true_xy = xi_model.copy(), xi_true.copy()
    true_yaw[:, 2], true_xy[:, 2] = xi_true[:, 2], xi_model[:, 2]
    return float(np.hypot(*own.g_c[0, :2]) * hz), chord(xi_model), chord(true_yaw), chord(true_xy)


def measure(lines: list[str], summary: list[str], name: str, sel: str, icfg: IdentifyConfig, frame: str,
            system: SudsSystem, nom: Gait, limits: object, v0: float, t0: float) -> None:
    """One robot under one model selection: a row per seed and κ into ``lines``, a line into ``summary``."""
    model_g, true_g, body_g, body_err, yaw_err, xy_err = [], [], [], [], [], []
    for seed in SEEDS:
        cfg = LoopConfig(budget_cycles=10, seed=seed)
        rec, _ = _Robot(system, nom, cfg).run(nom, cfg.settle_cycles + cfg.first_cycles)
        model = learn_model(_trim(rec, cfg.settle_cycles, cfg.samples_per_cycle), config=icfg, frame=frame)
        d = model.suds
        design = (f"set {d.regressors}, orders {d.linear_order}/{d.bilinear_order}, ridge {d.ridge:g}"
                  + (f", {d.kernel_features} features" if d.kernel_features else ""))
        p0 = predict_value(model, nom, "speed")
        own0, body0, _, _ = chord_speeds(system, model, nom, seed)
        for kappa in KAPPAS:
            dcfg = DataOptimizeConfig(objective="speed", order=3, trust=kappa, draws=0, min_gain_sigmas=0.0,
                                      seed=seed, max_rotation=cfg.max_rotation * cfg.rotation_margin,
                                      half_wave=True)
            step = optimize_from_data(model, dcfg, limits=limits, start=nom)
            gait = step.gait
            mg = predict_value(model, gait, "speed") - p0
            vt = evaluate_gait(system, gait)["speed"]
            tg = vt - v0
            own1, body1, yaw1, xy1 = chord_speeds(system, model, gait, seed)
            bg = body1 - body0
            model_g.append(mg)
            true_g.append(tg)
            body_g.append(bg)
            body_err.append(body1 / vt - 1)
            yaw_err.append(yaw1 / vt - 1)
            xy_err.append(xy1 / vt - 1)
            ratio = f"{mg / tg:.1f}" if abs(tg) > 1e-3 * v0 else "—"
            lines.append(f"| {name} | {sel} | {seed} | {design} | {kappa:g} | {mg:+.4f} | {tg:+.4f} | {ratio} | "
                         f"{bg:+.4f} | {body0 / v0 - 1:+.3f} | {body1 / vt - 1:+.3f} | {yaw1 / vt - 1:+.3f} | "
                         f"{xy1 / vt - 1:+.3f} | {step.passive_excursion:.1f} |")
            print(lines[-1], f"(own chords {own0:.4f} → {own1:.4f})", flush=True)
    mg_a, tg_a, bg_a = np.asarray(model_g), np.asarray(true_g), np.asarray(body_g)
    summary.append(
        f"- {name}, {sel} selection: correlation with the true gain: model gain {np.corrcoef(mg_a, tg_a)[0, 1]:+.2f}, "
        f"body-only gain {np.corrcoef(bg_a, tg_a)[0, 1]:+.2f} ({mg_a.size} steps); median |gain − true gain|: "
        f"model {np.median(np.abs(mg_a - tg_a)):.4f}, body-only {np.median(np.abs(bg_a - tg_a)):.4f} m/s, "
        f"against a median true gain of {np.median(tg_a):+.4f}; the model's speed along the candidates' true "
        f"shapes off by {np.median(np.abs(body_err)):.1%} (median), {np.max(np.abs(body_err)):.1%} (largest); "
        f"with the true yaw rate in place of the model's {np.median(np.abs(yaw_err)):.1%} (median), with the true "
        f"translation velocity {np.median(np.abs(xy_err)):.1%} ({time.perf_counter() - t0:.0f} s).")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("robots", nargs="*", metavar="ROBOT", help=f"of {', '.join(ROBOTS)} (default: all)")
    args = ap.parse_args()
    robots = args.robots or list(ROBOTS)
    if set(robots) - set(ROBOTS):
        ap.error(f"ROBOT: expected some of {list(ROBOTS)}, got {sorted(set(robots) - set(ROBOTS))}")
    lines = ["# Where a step's predicted gain goes wrong", "",
             f"Measured {stamp()} on {machine()} by `benchmarks/optimize_step_aim.py`.", "",
             "\n\n".join(__doc__.split("\n\n")[1:5]), "",
             "| robot | selection | seed | model | κ | model gain (m/s) | true gain (m/s) | model / true gain | "
             "body-only gain (m/s) | body error, nominal | body error, candidate | with the true yaw rate | "
             "with the true translation | passive excursion (σ) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    summary = []
    for name in robots:
        system = load_system(ROBOTS[name])
        nom, limits = nominal_gait(system), gait_limits(system)
        v0 = evaluate_gait(system, nom)["speed"]
        for sel, (icfg, frame) in SELECTIONS.items():
            measure(lines, summary, name, sel, icfg, frame, system, nom, limits, v0, time.perf_counter())
    lines += ["", "## Summary", "", *summary, ""]
    write("optimize_step_aim.md", "\n".join(lines))


if __name__ == "__main__":
    main()
