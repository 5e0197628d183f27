"""The reverse trial's hint: whether the model of a gait's few cycles knows which way round the wave runs faster.

``optimize_loop`` runs the incumbent backwards in time (``LoopConfig.reverse_trial``) only when the
SUDS model of the incumbent's cycles, extrapolated to the reversed drive, predicts it better.  Here,
for robots and gaits (the nominal gait, its time reversal, half its amplitude), 3 seeds each: the
start's 1 settling + 4 measured cycles on the loop's robot (default OU perturbation and noise), the
model fitted to them (``learn_model``), its predicted speed of the reversed drive over that of the
gait (``predict_value``), against the same ratio on the true physics.  A model with no steady state
for either drive predicts nothing ('—'): the loop then does not try.

    python benchmarks/optimize_reverse.py            # → docs/results/optimize_reverse.md
"""

from __future__ import annotations

from _common import ROOT, SNAKE5, machine, stamp, write

from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.core.optimize.data import learn_model
from suds_ros.core.optimize.loop import LoopConfig, _Robot, _trim, predict_value
from suds_ros.core.optimize.physics import evaluate_gait
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.gait import nominal_gait, time_reversed
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.systems import load_system

DATA = ROOT / "test" / "data" / "robots"
BENT = [{"name": "spring_rest_offset", "joint": "joint_3", "offset": 0.6},
        {"name": "joint_viscous_damping", "joint": "joint_4", "d": 0.5}]  # optimize_sim2real.py's snake5_bent
CASES = (("swimmer9", "swimmer9", ()), ("snake5", SNAKE5, ()), ("eel4", str(DATA / "eel4.yaml"), ()),
         ("tail6", str(DATA / "tail6.yaml"), ()), ("neck4", str(DATA / "neck4.yaml"), ()),
         ("snake5 bent (sim to real)", SNAKE5, BENT))
SEEDS = (0, 1, 2)
CYCLES = LoopConfig(budget_cycles=10).settle_cycles + LoopConfig(budget_cycles=10).step_cycles  # one trial run


def main() -> None:
    rows = ["| robot | gait | true speed (m/s) | true ratio reversed / gait | predicted ratios (seeds 0, 1, 2) | "
            "trial run (predicted > 1) |", "|" + "---|" * 6]
    hits = {True: [0, 0], False: [0, 0]}  # truly faster reversed?: [fits that say faster, fits]
    for name, spec, effects in CASES:
        system = load_system(spec)
        true = RFTChain(apply_effects(system.model, list(effects))[0]) if effects else system
        nom = nominal_gait(system)
        for kind, gait in (("nominal", nom), ("wave reversed", time_reversed(nom)),
                           ("half amplitude", nom.from_vector(0.5 * nom.to_vector(), nom.order))):
            ratios = []
            for seed in SEEDS:
                robot = _Robot(system, gait, LoopConfig(budget_cycles=10, seed=seed),
                               changes=[(0, list(effects))] if effects else ())
                model = learn_model([_trim(robot.run(gait, CYCLES)[0], 1, robot.spc)])
                try:
                    back = predict_value(model, time_reversed(gait), "speed")
                    ratios.append(back / predict_value(model, gait, "speed"))
                except (SudsDataError, SudsConfigError, FloatingPointError):
                    ratios.append(None)
            v0, v1 = (evaluate_gait(true, g, work=False)["speed"] for g in (gait, time_reversed(gait)))
            faster = v1 > v0
            said = sum(r is not None and r > 1 for r in ratios)
            hits[faster][0] += said
            hits[faster][1] += len(ratios)
            shown = ", ".join("—" if r is None else f"{r:.2f}" for r in ratios)
            rows.append(f"| {name} | {kind} | {v0:.4f} | {v1 / v0:.2f} | {shown} | {said} of {len(ratios)} |")
            print(rows[-1], flush=True)
    text = "\n".join([
        "# The reverse trial's hint", "", f"Measured {stamp()} on {machine()} by `benchmarks/optimize_reverse.py`.", "",
        __doc__.split("\n\n")[1].replace("\n", " ").strip(), "", *rows, "",
        f"Where the reversed drive is truly faster, the model said so in {hits[True][0]} of {hits[True][1]} fits (a "
        f"trial run that pays); where it is not, in {hits[False][0]} of {hits[False][1]} (a trial of "
        f"{CYCLES} cycles spent).", ""])
    write("optimize_reverse.md", text)


if __name__ == "__main__":
    main()
