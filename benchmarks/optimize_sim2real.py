"""The sim-to-real payoff measured: three gaits for a robot that differs from its model file.

The true robot is the nominal model with concealed catalogue effects.  Three gaits, each run on
the true robot at its passive periodic steady state and compared with the true robot's limit
(the physics optimiser's best gait on the true physics, order 3, 8 starts and gait 1 as a ninth, or
a faster straight gait found here):

1. **nominal**: the physics optimiser's best gait on the *nominal* model (what a user with only
   the model file would run);
2. **loop**: the data-driven loop (`optimize_loop`, defaults) run on the true robot for the
   budget, from the nominal gait; it sees only the recorded streams;
2b. **refined**: the same loop started from gait 1 (what a user who optimised on the model file
   would do next: refine that gait on the robot);
3. **diagnosed**: `diagnose` on a recording of the true robot (the nominal gait, ``--cycles``
   cycles, default noise), the reported effects with their fitted values put into the model,
   and the physics optimiser run on that corrected model (8 starts and gait 1, where a user who
   optimised on the model file would start).

The speed objective's straight-course bound (|net rotation| ≤ 0.05 rad/cycle) is part of the
result: a gait that breaks it on the true robot does not meet the spec, whatever its speed.

    python benchmarks/optimize_sim2real.py run snake5_bent purcell3_stiff   # → docs/results/optimize_sim2real_*.json
    python benchmarks/optimize_sim2real.py report                           # → docs/results/optimize_sim2real.md
"""

from __future__ import annotations

import json
import time

from _common import RESULTS, SNAKE5, machine, run_report_cli, stamp, write

from suds_ros.core.diagnosis.experiment import reported_effects
from suds_ros.core.diagnosis.pipeline import diagnose
from suds_ros.core.json_text import dumps
from suds_ros.core.optimize.loop import LoopConfig, optimize_loop
from suds_ros.core.optimize.physics import OptimizeConfig, evaluate_gait, optimize_gait
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.gait import gait_limits, nominal_gait
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import load_system

MAX_ROTATION = 0.05
#: case: (robot spec, concealed effects, loop budget in cycles, what they stand for)
CASES = {
    "snake5_bent": (SNAKE5,
                    [{"name": "spring_rest_offset", "joint": "joint_3", "offset": 0.6},
                     {"name": "joint_viscous_damping", "joint": "joint_4", "d": 0.5}], 60,
                    "joint_3's spring rest bent by 0.6 rad and a damper on joint_4"),
    "purcell3_stiff": ("purcell3",
                       [{"name": "stiffness_to_drag_error", "scale": 2.0},
                        {"name": "spring_rest_offset", "joint": "joint_2", "offset": 0.5}], 40,
                       "springs 2× stiffer against the drag and a rest offset of 0.5 rad"),
}


def _true(system, gait) -> dict:  # type: ignore[no-untyped-def]
    e = evaluate_gait(system, gait)
    return {"speed": e["speed"], "rotation": e["rotation"], "straight": abs(e["rotation"]) <= MAX_ROTATION}


def run(name: str, seeds: list[int], cycles: int) -> None:
    spec, effects, budget, _ = CASES[name]
    nominal = load_system(spec)
    model = nominal.model  # type: ignore[attr-defined]
    true = RFTChain(apply_effects(model, effects)[0])
    cfg = OptimizeConfig(order=3, starts=8)  # 8 starts: purcell3 has a second local optimum (0.057 m/s)
    t0 = time.perf_counter()
    nom_best = optimize_gait(nominal, cfg)
    # the nominal model's best gait is a start too: on snake5 with a bent spring a loop started from it found
    # a straight gait 2.5 % faster on the truth than the 8 starts did (2026-11-28)
    limit = optimize_gait(true, cfg, initial=[nom_best.gait])
    doc = {"case": name, "robot": spec, "effects": effects, "budget": budget, "cycles": cycles,
           "limit": limit.value, "limit_true": _true(true, limit.gait),
           "nominal": _true(true, nom_best.gait), "nominal_on_model": nom_best.value,
           "seconds": time.perf_counter() - t0, "runs": []}
    print(f"{name}: true limit {limit.value:.5f}; the nominal model's best gait on the true robot "
          f"{doc['nominal']['speed']:.5f} (rotation {doc['nominal']['rotation']:+.3f})", flush=True)
    limits = gait_limits(nominal)
    for seed in seeds:
        t1 = time.perf_counter()
        loop = optimize_loop(nominal, LoopConfig(budget_cycles=budget, seed=seed), start=nominal_gait(nominal),
                             limits=limits, changes=[(0, effects)])
        t_loop = time.perf_counter() - t1
        refined = optimize_loop(nominal, LoopConfig(budget_cycles=budget, seed=seed), start=nom_best.gait,
                                limits=limits, changes=[(0, effects)])
        rec = simulate(true, SimConfig(cycles=cycles, seed=seed, gait_hz=model.gait_hz))
        t2 = time.perf_counter()
        rep = diagnose(rec, model)
        named = reported_effects(rep.effects)
        corrected = RFTChain(apply_effects(model, named)[0]) if named else nominal
        diag_best = optimize_gait(corrected, cfg, initial=[nom_best.gait])  # a user starts from the model's best
        t_diag = time.perf_counter() - t2
        doc["runs"].append({
            "seed": seed, "loop": _true(true, loop.gait), "loop_cycles": loop.cycles_used,
            "loop_measured": loop.measured.speed, "loop_predicted": loop.predicted, "loop_seconds": t_loop,
            "refined": _true(true, refined.gait), "refined_cycles": refined.cycles_used,
            "named": named, "confounded_with": [list(g) for g in rep.confounded_with],
            "unexplained": rep.unexplained, "diagnosed": _true(true, diag_best.gait),
            "diagnosed_on_model": diag_best.value, "diagnose_seconds": t_diag})
        r = doc["runs"][-1]
        print(f"  seed {seed}: loop {r['loop']['speed']:.5f} ({r['loop']['rotation']:+.3f}), refined "
              f"{r['refined']['speed']:.5f} ({r['refined']['rotation']:+.3f}), diagnosed "
              f"{r['diagnosed']['speed']:.5f} ({r['diagnosed']['rotation']:+.3f}); named {named}", flush=True)
        (RESULTS / f"optimize_sim2real_{name}.json").write_text(dumps(doc))


def _cell(v: dict, limit: float) -> str:
    return f"{100 * v['speed'] / limit:.1f} % ({v['rotation']:+.3f}{'' if v['straight'] else ', NOT straight'})"


def _best_known(doc: dict) -> float:
    """The true robot's limit as far as known: the physics optimiser's value or a faster straight gait found here.

    The optimiser's 8 starts can miss the best optimum; any gait within the bounds that is straight
    on the true physics is a lower bound of the limit too.
    """
    found = [doc["nominal"]] + [r[k] for r in doc["runs"] for k in ("loop", "refined", "diagnosed") if k in r]
    return max([doc["limit"]] + [v["speed"] for v in found if v["straight"]])


def _effects(effects: list[dict]) -> str:
    return "; ".join(" ".join(f"{k}={v:.4g}" if isinstance(v, float) else str(v) for k, v in e.items())
                     for e in effects) or "none"


def report() -> None:
    lines = ["# Sim-to-real: three gaits for a robot that differs from its model file", "",
             f"Measured {stamp()} on {machine()} by `benchmarks/optimize_sim2real.py`.", "",
             "Each cell: the gait's true speed as a % of the true robot's limit (the physics optimiser on the true "
             "physics, order 3, 8 starts and the 'nominal' gait, or the fastest straight gait found here on the true "
             "physics if that is "
             "faster), and its true net rotation per cycle (the spec's straight-course bound is "
             "0.05 rad).  "
             "'nominal' = the best gait on the nominal model file; 'loop' = the data-driven loop on the true robot "
             "(budget below, every cycle counted, from the nominal gait); 'loop from the nominal-model gait' = the "
             "same loop started from the 'nominal' gait (optimise on the model file, then refine on the robot); "
             "'diagnosed' = the best gait on the model "
             "corrected by `diagnose` (a recording of the nominal gait on the true robot, the reported effects and "
             "their fitted values), optimised from 8 starts and the 'nominal' gait; the 'nominal' gait with 8 starts "
             "(purcell3 has a second local optimum near 0.057 m/s that 4 starts can end in).", ""]
    for name in CASES:
        path = RESULTS / f"optimize_sim2real_{name}.json"
        if not path.exists():
            continue
        doc = json.loads(path.read_text())
        lim = _best_known(doc)
        lines += [f"## {name}: {CASES[name][3]}", "",
                  f"Robot `{doc['robot']}`; concealed effects: {_effects(doc['effects'])}.  True limit "
                  f"{lim:.5f} m/s (the physics optimiser's own: {doc['limit']:.5f}); the nominal model's own optimum "
                  f"{doc['nominal_on_model']:.5f} m/s (on the model).  "
                  f"Loop budget {doc['budget']} cycles; diagnosis on {doc['cycles']} cycles.", "",
                  "| seed | nominal-model gait | data-driven loop | loop from the nominal-model gait | after diagnosis "
                  "| effects named by the diagnosis | confounded | time loop / diagnose+optimise (s) |",
                  "|---|---|---|---|---|---|---|---|"]
        for r in doc["runs"]:
            lines.append(f"| {r['seed']} | {_cell(doc['nominal'], lim)} | {_cell(r['loop'], lim)} | "
                         f"{_cell(r['refined'], lim) if 'refined' in r else '—'} | "
                         f"{_cell(r['diagnosed'], lim)} | {_effects(r['named'])}"
                         f"{' (unexplained left)' if r['unexplained'] else ''} | "
                         f"{'; '.join(' or '.join(g) for g in r['confounded_with']) or '—'} | "
                         f"{r['loop_seconds']:.0f} / {r['diagnose_seconds']:.0f} |")
        lines.append("")
    write("optimize_sim2real.md", "\n".join(lines) + "\n")


def main() -> None:
    run_report_cli(__doc__, sorted(CASES), lambda n, a: run(n, a.seeds, a.cycles), report,
                   extra=lambda r: r.add_argument("--cycles", type=int, default=40,
                                                  help="cycles of the recording the diagnosis reads"))


if __name__ == "__main__":
    main()
