"""The loop's change tests on robots that did and did not change: how often a re-run reads as "changed".

A re-run of the incumbent is taken to show a changed robot by one of two tests.  The body's:
the re-run misses the model of the standing data (``motion_miss``) by more than ``LoopConfig.model_miss``
(0.15: a fraction of the measured translation, or rad of yaw per cycle), by more than one standard error;
since this round used only on a robot without passive joints.  The passive shapes': the re-run's
passive joint angles (each cycle's mean, cosine and sine) differ from the standing stretch's by a
two-sample T² at ``LoopConfig.passive_alpha`` (0.01, Bonferroni over the joints), its last cycle nearer
the new shapes (``change.passive_shift``).  Here, on the robot as the loop drives it (the streaming
simulator, OU perturbation and noise at the loop's defaults, seeded): for each robot and gait, the start
(1 settling + 4 measured cycles) and then a re-run of the same gait (1 + 4), over 10 seeds; on the
unchanged robots every alarm is false (the loop would drop the incumbent's data and start afresh), on
the changed ones (the change at the re-run's start, as in ``optimize_adapt.py``) every quiet reading is a
change missed.

    python benchmarks/optimize_miss.py            # → docs/results/optimize_miss.md
"""

from __future__ import annotations

import importlib.util
import statistics

from _common import ROOT, SNAKE5, machine, stamp, write

from suds_ros.core.optimize.change import passive_shift
from suds_ros.core.optimize.data import learn_model, motion_miss
from suds_ros.core.optimize.loop import LoopConfig, _Robot, _trim, measure_recording
from suds_ros.core.optimize.physics import evaluate_gait
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.gait import nominal_gait, time_reversed
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.systems import load_system

DATA = ROOT / "test" / "data" / "robots"
ROBOTS = {"purcell3": "purcell3", "snake5": SNAKE5, "swimmer9": "swimmer9", "eel4": str(DATA / "eel4.yaml"),
          "tail6": str(DATA / "tail6.yaml"), "neck4": str(DATA / "neck4.yaml")}
SEEDS = range(10)


def _adapt_cases() -> dict:
    """The changes of ``optimize_adapt.py`` (robot spec, cycle, effects, budget, words), by robot."""
    spec = importlib.util.spec_from_file_location("optimize_adapt", ROOT / "benchmarks" / "optimize_adapt.py")
    mod = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    spec.loader.exec_module(mod)  # type: ignore[union-attr]
    return mod.CASES


def gaits(nom):  # type: ignore[no-untyped-def]
    """The nominal gait, half its amplitude, and the wave run backwards (the loop benchmark's starts)."""
    return {"nominal": nom, "half amplitude": nom.from_vector(0.5 * nom.to_vector(), nom.order),
            "wave reversed": time_reversed(nom)}


def main() -> None:
    cfg = LoopConfig(budget_cycles=10)
    n = cfg.settle_cycles + cfg.step_cycles
    rows = ["| robot | gait | changed | true speed (m/s) | measured speed, median (m/s) | body miss: median | "
            "largest | body alarms (> model_miss, > 1 se) | passive p: smallest | median | "
            "passive alarms (p < passive_alpha) |", "|" + "---|" * 11]
    cases = [(name, spec, kind, gait, None) for name, spec in ROBOTS.items()
             for kind, gait in gaits(nominal_gait(load_system(spec))).items()]
    for name, (spec, _, effects, _, _) in _adapt_cases().items():
        for kind, gait in gaits(nominal_gait(load_system(spec))).items():
            if kind != "wave reversed":
                cases.append((name, spec, kind, gait, effects))
    for name, spec, kind, gait, effects in cases:
        system = load_system(spec)
        sizes, speeds, ps, alarms = [], [], [], 0
        for seed in SEEDS:
            robot = _Robot(system, gait, LoopConfig(budget_cycles=10, seed=seed),
                           changes=[(n, effects)] if effects else ())
            first, second = (_trim(robot.run(gait, n)[0], cfg.settle_cycles, robot.spc) for _ in range(2))
            sizes.append(motion_miss(learn_model(first), second).size())
            speeds.append(measure_recording(first, robot.spc, gait.gait_hz).speed)
            shift = passive_shift(first, second, gait.gait_hz)
            if shift is not None:
                ps.append(shift.p)
                alarms += shift.p < cfg.passive_alpha and shift.start is not None
        body = sum(s > cfg.model_miss for s in sizes)
        truth = system if not effects else RFTChain(apply_effects(system.model, effects)[0])  # type: ignore
        p_text = (f"{min(ps):.2g} | {statistics.median(ps):.2g} | {alarms} of {len(ps)}" if ps
                  else "— | — | no passive joint")
        rows.append(f"| {name} | {kind} | {'yes' if effects else 'no'} | "
                    f"{evaluate_gait(truth, gait, work=False)['speed']:.4f} | "
                    f"{statistics.median(speeds):.4f} | {statistics.median(sizes):.3f} | {max(sizes):.3f} | "
                    f"{body} of {len(sizes)} | {p_text} |")
        print(rows[-1], flush=True)
    text = "\n".join([
        "# The loop's change tests on unchanged and changed robots", "",
        f"Measured {stamp()} on {machine()} by `benchmarks/optimize_miss.py`.", "",
        __doc__.split("\n\n")[1].replace("\n", " ").strip(), "",
        "'body miss' = `MotionMiss.size()`: the larger of the translation missed (fraction of the measured) and "
        "the rotation missed (rad/cycle), of those over one standard error (0 if neither).  'passive p': "
        "`PassiveShift.p`.  'changed': the robot as `optimize_adapt.py` changes it, from the re-run on "
        "(the true speed is the changed robot's); the measured speed is the first stretch's.", "",
        *rows, ""])
    write("optimize_miss.md", text)


if __name__ == "__main__":
    main()
