"""The loop's change test on robots that did not change: how often a re-run of the incumbent reads as "changed".

``optimize_loop`` takes the robot to have changed when a re-run of the incumbent gait misses the model of
its standing data (``motion_miss``) by more than ``LoopConfig.model_miss`` (0.15: a fraction of the
measured translation, or rad of yaw per cycle), by more than one standard error.  ``optimize_adapt.py``
calibrates it on purcell3 and snake5 at their nominal gaits.  Here, on the robot as the loop drives it
(the streaming simulator, OU perturbation and noise at the loop's defaults, seeded): for each robot and
gait, the start (1 settling + 4 measured cycles) and then a re-run of the same gait (1 + 4), the model
fitted to the first stretch and its miss on the second, over 10 seeds.  Every such reading above
``model_miss`` is a false alarm: the loop would drop the incumbent's data and start afresh.

    python benchmarks/optimize_miss.py            # → docs/results/optimize_miss.md
"""

from __future__ import annotations

import statistics

from _common import ROOT, SNAKE5, machine, stamp, write

from suds_ros.core.optimize.data import learn_model, motion_miss
from suds_ros.core.optimize.loop import LoopConfig, _Robot, _trim, measure_recording
from suds_ros.core.optimize.physics import evaluate_gait
from suds_ros.core.physics.gait import nominal_gait, time_reversed
from suds_ros.core.physics.systems import load_system

DATA = ROOT / "test" / "data" / "robots"
ROBOTS = {"purcell3": "purcell3", "snake5": SNAKE5, "swimmer9": "swimmer9", "eel4": str(DATA / "eel4.yaml"),
          "tail6": str(DATA / "tail6.yaml"), "neck4": str(DATA / "neck4.yaml")}
SEEDS = range(10)


def gaits(nom):  # type: ignore[no-untyped-def]
    """The nominal gait, half its amplitude, and the wave run backwards (the loop benchmark's starts)."""
    return {"nominal": nom, "half amplitude": nom.from_vector(0.5 * nom.to_vector(), nom.order),
            "wave reversed": time_reversed(nom)}


def main() -> None:
    cfg = LoopConfig(budget_cycles=10)
    n = cfg.settle_cycles + cfg.step_cycles
    rows = ["| robot | gait | true speed (m/s) | measured speed, median (m/s) | miss: median | largest | "
            "false alarms (> model_miss, > 1 se) |", "|" + "---|" * 7]
    for name, spec in ROBOTS.items():
        system = load_system(spec)
        for kind, gait in gaits(nominal_gait(system)).items():
            sizes, speeds = [], []
            for seed in SEEDS:
                robot = _Robot(system, gait, LoopConfig(budget_cycles=10, seed=seed))
                first, second = (_trim(robot.run(gait, n)[0], cfg.settle_cycles, robot.spc) for _ in range(2))
                sizes.append(motion_miss(learn_model(first), second).size())
                speeds.append(measure_recording(first, robot.spc, gait.gait_hz).speed)
            alarms = sum(s > cfg.model_miss for s in sizes)
            rows.append(f"| {name} | {kind} | {evaluate_gait(system, gait, work=False)['speed']:.4f} | "
                        f"{statistics.median(speeds):.4f} | {statistics.median(sizes):.3f} | {max(sizes):.3f} | "
                        f"{alarms} of {len(sizes)} |")
            print(rows[-1], flush=True)
    text = "\n".join([
        "# The loop's change test on unchanged robots", "",
        f"Measured {stamp()} on {machine()} by `benchmarks/optimize_miss.py`.", "",
        __doc__.split("\n\n")[1].replace("\n", " ").strip(), "",
        "'miss' = `MotionMiss.size()`: the larger of the translation missed (fraction of the measured) and "
        "the rotation missed (rad/cycle), of those over one standard error (0 if neither).", "",
        *rows, ""])
    write("optimize_miss.md", text)


if __name__ == "__main__":
    main()
