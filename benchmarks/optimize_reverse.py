"""The reverse trial's hint: whether the model of a gait's few cycles knows which way round the wave runs faster.

``optimize_loop`` runs the incumbent backwards in time (``LoopConfig.reverse_trial``) when the SUDS
model of the incumbent's cycles, extrapolated to the reversed drive, predicts it better, or, where
that point prediction says no, when more than half of its coefficient draws that predict both
drives say so (``reverse_odds``, 16 draws, at least 8 predicting).  Here, for robots and gaits (the
built-in and test robots' nominal gait, its time reversal, half its amplitude; the sweep's random
model-file robots' nominal gait), 3 seeds each: the start's 1 settling + 4 measured cycles on the
loop's robot (default OU perturbation and noise), the model fitted to them (``learn_model``), its
predicted speed of the reversed drive over that of the gait (``predict_value``) and the draws that
predict it faster, against the same ratio on the true physics.  A model with no steady state for
either drive predicts nothing ('—'): the loop then does not try.  Robots whose reversed drive is the
same drive started elsewhere (one driven joint at one harmonic) are left out: the loop never tries.

    python benchmarks/optimize_reverse.py            # → docs/results/optimize_reverse.md
"""
from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import yaml
from _common import ROOT, SNAKE5, machine, stamp, write
from optimize_sweep import random_robot

from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.core.optimize.data import learn_model
from suds_ros.core.optimize.loop import (RESULT_DRAWS, LoopConfig, _Robot, _trim, most_draws_faster, predict_value,
                                         reverse_odds)
from suds_ros.core.optimize.physics import evaluate_gait
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.gait import nominal_gait, reversal_shift, time_reversed
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.systems import load_system

DATA = ROOT / "test" / "data" / "robots"
BENT = [{"name": "spring_rest_offset", "joint": "joint_3", "offset": 0.6},
        {"name": "joint_viscous_damping", "joint": "joint_4", "d": 0.5}]  # optimize_sim2real.py's snake5_bent
CASES = (("swimmer9", "swimmer9", ()), ("snake5", SNAKE5, ()), ("eel4", str(DATA / "eel4.yaml"), ()),
         ("tail6", str(DATA / "tail6.yaml"), ()), ("neck4", str(DATA / "neck4.yaml"), ()),
         ("snake5 bent (sim to real)", SNAKE5, BENT))
RANDOM_ROBOTS, RANDOM_SEED = 16, 20261202  # optimize_sweep.py's robots (its defaults: --seed, 16 with --robots 16)
SEEDS = (0, 1, 2)
CYCLES = LoopConfig(budget_cycles=10).settle_cycles + LoopConfig(budget_cycles=10).step_cycles  # one trial run


def _fit(system, gait, effects, seed):  # type: ignore[no-untyped-def]
    """(point ratio or None, draws saying faster, draws predicting) of one start's model."""
    robot = _Robot(system, gait, LoopConfig(budget_cycles=10, seed=seed),
                   changes=[(0, list(effects))] if effects else ())
    model = learn_model([_trim(robot.run(gait, CYCLES)[0], 1, robot.spc)])
    try:
        ratio = predict_value(model, time_reversed(gait), "speed") / predict_value(model, gait, "speed")
    except (SudsDataError, SudsConfigError, FloatingPointError):
        return None, 0, 0
    wins, told = reverse_odds(model, gait, "speed", draws=RESULT_DRAWS, seed=seed)  # as the loop: its seed
    return ratio, wins, told


def _tries(ratio, wins, told) -> tuple[bool, bool]:  # type: ignore[no-untyped-def]
    """(the point rule tries, the loop's rule tries)."""
    if ratio is None:
        return False, False
    point = ratio > 1
    return point, point or most_draws_faster(wins, told, RESULT_DRAWS)


def main() -> None:
    rows = ["| robot | gait | true speed (m/s) | true ratio reversed / gait | predicted ratios [draws faster / "
            "predicting] (seeds 0, 1, 2) | trial by the point prediction | trial by the loop's rule |",
            "|" + "---|" * 7]
    # truly faster reversed?: [point rule tries, loop rule tries, fits]
    hits = {True: [0, 0, 0], False: [0, 0, 0]}
    with tempfile.TemporaryDirectory() as tmp:
        rng = np.random.default_rng(RANDOM_SEED)
        cases = list(CASES)
        for i in range(RANDOM_ROBOTS):
            path = Path(tmp) / f"rand{i}.yaml"
            path.write_text(yaml.safe_dump(random_robot(rng, f"rand{i}"), sort_keys=False))
            cases.append((f"rand{i} (random)", str(path), ()))
        for name, spec, effects in cases:
            system = load_system(spec)
            true = RFTChain(apply_effects(system.model, list(effects))[0]) if effects else system
            nom = nominal_gait(system)
            gaits = [("nominal", nom)]
            if "random" not in name:
                gaits += [("wave reversed", time_reversed(nom)),
                          ("half amplitude", nom.from_vector(0.5 * nom.to_vector(), nom.order))]
            for kind, gait in gaits:
                if reversal_shift(gait) is not None:
                    continue
                fits = [_fit(system, gait, effects, seed) for seed in SEEDS]
                v0, v1 = (evaluate_gait(true, g, work=False)["speed"] for g in (gait, time_reversed(gait)))
                faster = v1 > v0
                tries = [_tries(*f) for f in fits]
                hits[faster][0] += sum(t[0] for t in tries)
                hits[faster][1] += sum(t[1] for t in tries)
                hits[faster][2] += len(fits)
                shown = ", ".join("—" if r is None else f"{r:.2f} [{w}/{n}]" for r, w, n in fits)
                rows.append(f"| {name} | {kind} | {v0:.4f} | {v1 / v0:.2f} | {shown} | "
                            f"{sum(t[0] for t in tries)} of {len(fits)} | {sum(t[1] for t in tries)} of {len(fits)} |")
                print(rows[-1], flush=True)
    text = "\n".join([
        "# The reverse trial's hint", "", f"Measured {stamp()} on {machine()} by `benchmarks/optimize_reverse.py`.", "",
        __doc__.split("\n\n")[1].replace("\n", " ").strip(), "", *rows, "",
        f"Where the reversed drive is truly faster ({hits[True][2]} fits), the point prediction said so in "
        f"{hits[True][0]}, the loop's rule (the point prediction, or most draws) in {hits[True][1]}: trial runs "
        f"that pay.  Where it is not ({hits[False][2]} fits), the point prediction said so in {hits[False][0]}, the "
        f"loop's rule in {hits[False][1]}: trials of {CYCLES} cycles spent.", ""])
    write("optimize_reverse.md", text)


if __name__ == "__main__":
    main()
