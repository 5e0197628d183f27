"""How precisely one candidate's cycles tell its rotation: the mean of the cycles against the SUDS model's.

The loop judges the speed objective's straight-course bound (0.05 rad/cycle) on one candidate's
run: 1 settling + 4 measured cycles under the simulator's OU perturbation.  Two readings of its
rotation per cycle are compared here against the true physics (the gait's net rotation at its
passive periodic steady state, ``evaluate_gait``):

- **mean**: the mean of the measured cycles' rotations (``Measurement.rotation``, with its se);
- **model**: the SUDS model fitted to those same cycles, at δ = 0 (``loop.model_rotation``, with its
  robust spread over 16 coefficient draws), which is what the loop now judges by.

For each robot and gait, seeds 0–9 of the loop's own robot (its defaults: perturbation, noise,
100 samples per cycle).  Robots: the paper's purcell3 and swimmer9, snake5, neck4, snake5 bent
off course (a gait that truly turns, about twice the bound: the reading must still refuse it),
and two of the random model files of ``optimize_sweep.py`` (rand1: 5 of 6 joints driven with
damped springs; rand6: 5 of 5 driven, a drive offset, so not half-wave).

    python benchmarks/optimize_rotation.py          # → docs/results/optimize_rotation.md
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml
from _common import NECK4, SNAKE5, machine, stamp, write
from optimize_sweep import random_robot

from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.core.optimize.data import learn_model
from suds_ros.core.optimize.loop import LoopConfig, _Robot, _trim, measure_recording, model_rotation
from suds_ros.core.optimize.physics import evaluate_gait
from suds_ros.core.physics.gait import Gait, nominal_gait
from suds_ros.core.physics.systems import load_system

SEEDS = range(10)
SWEEP_SEED = 20261202  # optimize_sweep.py's default generator seed
SWEEP_ROBOTS = ("rand1", "rand6")


def _bent(gait: Gait) -> Gait:
    """snake5's nominal wave at 0.8 amplitude with 0.5 rad of offset on its first joint: it turns."""
    x = 0.8 * gait.to_vector()
    x[0] += 0.5
    return gait.from_vector(x, gait.order)


def _cases(tmp: Path) -> list[tuple[str, object, Gait]]:
    cases = []
    for name, spec in (("purcell3", "purcell3"), ("snake5", SNAKE5), ("swimmer9", "swimmer9"), ("neck4", NECK4)):
        system = load_system(spec)
        cases.append((name, system, nominal_gait(system)))
    snake = load_system(SNAKE5)
    cases.append(("snake5 bent", snake, _bent(nominal_gait(snake))))
    rng = np.random.default_rng(SWEEP_SEED)
    for i in range(max(int(n[4:]) for n in SWEEP_ROBOTS) + 1):
        doc = random_robot(rng, f"rand{i}")  # drawn in order, as the sweep does
        if doc["name"] in SWEEP_ROBOTS:
            path = tmp / f"{doc['name']}.yaml"
            path.write_text(yaml.safe_dump(doc, sort_keys=False))
            system = load_system(str(path))
            cases.append((str(doc["name"]), system, nominal_gait(system)))
    return cases


def _rms(x: list[float]) -> float:
    return float(np.sqrt(np.mean(np.square(x)))) if x else math.nan


def main() -> None:
    lines = ["# The rotation reading of one candidate: the mean of its cycles against the SUDS model's", "",
             f"Measured {stamp()} on {machine()} by `benchmarks/optimize_rotation.py`.", "",
             "\n\n".join(__doc__.split("\n\n")[1:4]), "",
             "Errors are the reading minus the true rotation, rad/cycle, over the seeds; 'rms z' is the rms of "
             "error / stated spread (1 for a spread that is right, < 1 for one that overstates the error); "
             "'over the bound' counts the seeds whose reading is over 0.05 rad/cycle in size.", "",
             "| robot | true rotation | seeds | mean: rms error | mean: bias | mean: rms z | mean: over the bound "
             "| model: fitted | model: rms error | model: bias | model: rms z | model: over the bound | time s |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    cfg = LoopConfig(budget_cycles=10)
    bound = cfg.max_rotation
    with tempfile.TemporaryDirectory() as tmp:
        for name, system, gait in _cases(Path(tmp)):
            t0 = time.perf_counter()
            true = float(evaluate_gait(system, gait)["rotation"])
            raw_err, raw_z, mod_err, mod_z, raw_over, mod_over, fitted = [], [], [], [], 0, 0, 0
            for seed in SEEDS:
                c = LoopConfig(budget_cycles=10, seed=seed)
                rec, _ = _Robot(system, gait, c).run(gait, c.settle_cycles + c.first_cycles)
                data = _trim(rec, c.settle_cycles, c.samples_per_cycle)
                m = measure_recording(data, c.samples_per_cycle, gait.gait_hz)
                raw_err.append(m.rotation - true)
                raw_over += abs(m.rotation) > bound
                if math.isfinite(m.rotation_se) and m.rotation_se > 0:
                    raw_z.append((m.rotation - true) / m.rotation_se)
                try:
                    value, spread = model_rotation(learn_model(data), gait, seed=seed)
                except (SudsDataError, SudsConfigError, FloatingPointError, np.linalg.LinAlgError):
                    continue  # (the loop falls back to the mean here)
                fitted += 1
                mod_err.append(value - true)
                mod_over += abs(value) > bound
                if spread:
                    mod_z.append((value - true) / spread)
            secs = time.perf_counter() - t0
            row = (f"| {name} | {true:+.4f} | {len(raw_err)} | {_rms(raw_err):.4f} | {np.mean(raw_err):+.4f} | "
                   f"{_rms(raw_z):.2f} | {raw_over} | {fitted} | {_rms(mod_err):.4f} | "
                   f"{np.mean(mod_err) if mod_err else math.nan:+.4f} | {_rms(mod_z):.2f} | {mod_over} | {secs:.0f} |")
            print(row, flush=True)
            lines.append(row)
    lines += ["", "The loop reads the bound on the model's value with the smaller of its spread and the cycles' "
              "se (`Measurement.rotation_reading`); where the model cannot be fitted (too few cycles, no steady "
              "state) it reads the mean of the cycles.", ""]
    write("optimize_rotation.md", "\n".join(lines))


if __name__ == "__main__":
    main()
