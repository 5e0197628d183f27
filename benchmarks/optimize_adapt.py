"""Adaptation measured: the run → fit → step loop on a robot that changes mid-run, unannounced.

The simulated robot (default OU perturbation, 100 Hz, 1 mm / 1 mrad noise, seeded) starts from
its nominal gait; after ``change`` cycles it becomes the nominal system with catalogue effects
(``optimize_loop(..., changes=...)``: the loop is not told).  The loop runs with ``watch`` on
(at convergence it keeps re-measuring its incumbent, as a deployed robot would) and its default
change tests (``change_sigmas`` = 2.5 on the measured speed and rotation; ``passive_alpha`` = 0.01
on a rerun's passive shapes against its standing runs'; ``model_miss`` on the model's prediction
along a rejected candidate's own shapes, which has the incumbent re-run, calibrated here on both robots).  After the run
every incumbent is evaluated on the physics in force at that cycle (before the change the
nominal, after it the changed one) at its passive periodic steady state; the limits are the
physics optimiser's best gaits (order 3, 4 starts) on the nominal and the changed physics.

    python benchmarks/optimize_adapt.py run purcell3 snake5     # → docs/results/optimize_adapt_<case>.json
    python benchmarks/optimize_adapt.py report                  # → docs/results/optimize_adapt.md
"""

from __future__ import annotations

import json
import statistics
import time

import numpy as np
from _common import RESULTS, SNAKE5, machine, run_report_cli, stamp, write

from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.core.json_text import dumps
from suds_ros.core.optimize.data import learn_model, motion_miss
from suds_ros.core.optimize.loop import LoopConfig, measure_recording, model_rotation, optimize_loop
from suds_ros.core.optimize.physics import OptimizeConfig, evaluate_gait, optimize_gait
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.gait import Gait, gait_limits, nominal_gait
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import load_system

#: case: (robot spec, cycle of the change, effects, budget, what the change stands for)
CASES = {
    "purcell3": ("purcell3", 30, [{"name": "stiffness_to_drag_error", "scale": 3.0}], 70,
                 "the passive spring 3× stiffer against the drag (a colder, stiffer material): about half as fast"),
    "snake5": (SNAKE5, 40, [{"name": "spring_rest_offset", "joint": "joint_3", "offset": 0.7}], 80,
               "joint_3's spring rest bent by 0.7 rad (damage): the old gait curves off the straight course"),
}
AFTER = (5, 10, 15, 20, 30, 40)  # cycles after the change at which the incumbent is read
MISS_TRAIN, MISS_SEEDS = (100, 101, 102), tuple(range(6))  # the change test's calibration: model and stretch seeds
#: where the changed robot's limit sits on the rotation bound: the best gait under these tighter bounds
TIGHT_BOUNDS, SCATTER_SEEDS = (0.015, 0.025, 0.035), tuple(range(12))


def _true(system, gait):  # type: ignore[no-untyped-def]
    e = evaluate_gait(system, gait)
    return {"speed": e["speed"], "rotation": e["rotation"]}


def _scaled(gait: Gait, k: float) -> Gait:
    """The gait with its harmonics' amplitudes times ``k`` (offsets kept)."""
    off, c, s = gait.arrays()
    return Gait(system=gait.system, gait_hz=gait.gait_hz, joints=gait.joints, offset=tuple(off),
                cos=tuple(map(tuple, c * k)), sin=tuple(map(tuple, s * k)))


def miss_calibration(nominal, changed) -> dict:  # type: ignore[no-untyped-def]
    """The loop's change test (``motion_miss``) where it must stay quiet and where it must speak.

    Models of the nominal gait's 5 cycles (training seeds 100–102) predict 4-cycle stretches (seeds 0–5)
    of: the same gait, the gait at 0.85× and 1.15× amplitude (a step off the model's data), all on the
    unchanged robot; and the same gait on the changed robot.
    """
    gait = nominal_gait(nominal)
    kinds = {"same gait": (nominal, gait), "0.85× amplitude": (nominal, _scaled(gait, 0.85)),
             "1.15× amplitude": (nominal, _scaled(gait, 1.15)), "changed robot": (changed, gait)}
    out: dict = {k: [] for k in kinds}
    for train_seed in MISS_TRAIN:
        model = learn_model(simulate(nominal, SimConfig(cycles=5, seed=train_seed, gait=gait, gait_hz=gait.gait_hz)))
        for kind, (system, g) in kinds.items():
            for seed in MISS_SEEDS:
                m = motion_miss(model, simulate(system, SimConfig(cycles=4, seed=seed, gait=g, gait_hz=g.gait_hz)))
                out[kind].append({"train_seed": train_seed, "seed": seed, "translation": m.translation,
                                  "rotation": m.rotation, "size": m.size()})
    return out


def rotation_window(changed, limit_new, gait: Gait) -> dict:  # type: ignore[no-untyped-def]
    """How narrow the band of fast, straight enough gaits is, against how well a stretch reads a rotation.

    When the changed robot's best gait turns at the speed objective's bound, a gait within some
    fraction of that limit must turn by nearly as much: the limit under tighter bounds (order 3,
    8 starts) gives the band.  Against it, the scatter of the rotation the loop measures over one
    candidate's 4 cycles (after 1 settling cycle; seeds 0–11) of ``gait`` on the changed robot: the
    mean of the cycles, and the SUDS model of those cycles at δ = 0 (``model_rotation``: what the loop
    judges the bound on where the model fits).
    """
    bound = OptimizeConfig().max_rotation
    out: dict = {"bound": bound, "limit_rotation": _true(changed, limit_new.gait)["rotation"], "tight": [],
                 "scatter": [], "model_scatter": []}
    if abs(out["limit_rotation"]) >= 0.9 * bound:
        for b in TIGHT_BOUNDS:
            r = optimize_gait(changed, OptimizeConfig(order=3, starts=8, max_rotation=b))
            out["tight"].append({"max_rotation": b, "speed": r.value})
    spc = SimConfig().samples_per_cycle
    for seed in SCATTER_SEEDS:
        rec = simulate(changed, SimConfig(cycles=5, seed=seed, gait=gait, gait_hz=gait.gait_hz))
        cycles = rec.slice(spc - 1, rec.n_samples)
        out["scatter"].append(measure_recording(cycles, spc, gait.gait_hz).rotation)
        try:
            out["model_scatter"].append(model_rotation(learn_model(cycles), gait, draws=0)[0])
        except (SudsDataError, SudsConfigError, FloatingPointError, np.linalg.LinAlgError):
            pass  # (no model: the loop reads the mean there)
    return out


def run(name: str, seeds: list[int]) -> None:
    spec, change, effects, budget, _ = CASES[name]
    nominal = load_system(spec)
    changed = RFTChain(apply_effects(nominal.model, effects)[0])  # type: ignore[attr-defined]
    t0 = time.perf_counter()
    calibration = miss_calibration(nominal, changed)
    for kind, rows in calibration.items():
        print(f"{name}: model miss, {kind}: largest {max(r['size'] for r in rows):.3f}, "
              f"smallest {min(r['size'] for r in rows):.3f}", flush=True)
    limit_old = optimize_gait(nominal, OptimizeConfig(order=3, starts=4))
    limit_new = optimize_gait(changed, OptimizeConfig(order=3, starts=4))
    doc = {"case": name, "robot": spec, "change": change, "effects": effects, "budget": budget,
           "limit_old": limit_old.value, "limit_new": limit_new.value,
           "old_best_on_new": _true(changed, limit_old.gait), "limit_seconds": time.perf_counter() - t0,
           "miss_calibration": calibration,
           "rotation_window": rotation_window(changed, limit_new, nominal_gait(nominal)), "runs": []}
    print(f"{name}: limits {limit_old.value:.5f} → {limit_new.value:.5f}; the old best gait on the changed robot "
          f"{doc['old_best_on_new']['speed']:.5f} (rotation {doc['old_best_on_new']['rotation']:+.3f})", flush=True)
    limits = gait_limits(nominal)
    for seed in seeds:
        t1 = time.perf_counter()
        res = optimize_loop(nominal, LoopConfig(budget_cycles=budget, seed=seed, watch=True),
                            start=nominal_gait(nominal), limits=limits, changes=[(change, effects)])
        rows, incumbent = [], None
        for it in res.iterations:
            before = it.cycles_used - it.cycles  # the run's first cycle
            physics = nominal if it.cycles_used <= change else changed
            if it.accepted:
                incumbent = it.gait
            rows.append({"index": it.index, "cycles_used": it.cycles_used, "first_cycle": before,
                         "accepted": it.accepted, "note": it.note, "measured": it.measured.speed,
                         "measured_rotation": it.measured.rotation,
                         "incumbent_true_old": _true(nominal, incumbent),
                         "incumbent_true_new": _true(changed, incumbent),
                         "physics": "nominal" if physics is nominal else "changed"})
        doc["runs"].append({"seed": seed, "rows": rows, "cycles_used": res.cycles_used, "stopped": res.stopped,
                            "seconds": time.perf_counter() - t1,
                            "returned_true_new": _true(changed, res.gait)})
        print(f"  seed {seed}: {res.cycles_used} cycles, {time.perf_counter() - t1:.0f} s; {res.stopped}", flush=True)
        (RESULTS / f"optimize_adapt_{name}.json").write_text(dumps(doc))


def _incumbent_at(rows: list[dict], cycle: int) -> dict | None:
    """The incumbent in force once ``cycle`` cycles were run (the last iteration ended by then)."""
    done = [r for r in rows if r["cycles_used"] <= cycle]
    return done[-1] if done else None


def _pct(v: float, limit: float) -> str:
    return f"{100 * v / limit:.1f}"


def report() -> None:
    lines = ["# Adaptation: the loop on a robot that changes mid-run", "",
             f"Measured {stamp()} on {machine()} by `benchmarks/optimize_adapt.py`.", "",
             "The robot changes unannounced after the given cycle; the loop (`optimize_loop`, defaults, `watch` on; "
             "its change tests: a re-measured incumbent 2.5 se off its standing value, or whose passive shapes "
             "differ from its standing runs' at `passive_alpha` = 0.01 (`change.passive_shift`, no model); a "
             "rejected candidate whose motion the model misses by more than `model_miss` (table below) has the "
             "incumbent re-run at once) must notice from its own measurements.  "
             "Percentages are of the limit of the physics in force: a gait's true speed at its passive periodic "
             "steady state over the physics "
             "optimiser's best (order 3, 4 starts).  'rotation' is the true net rotation per cycle of the "
             "incumbent on the changed robot (the speed objective's straight-course bound is 0.05 rad/cycle).", ""]
    for name in CASES:
        path = RESULTS / f"optimize_adapt_{name}.json"
        if not path.exists():
            continue
        doc = json.loads(path.read_text())
        lo, ln, c = doc["limit_old"], doc["limit_new"], doc["change"]
        ob = doc["old_best_on_new"]
        lines += [f"## {name}: {CASES[name][4]}", "",
                  f"Effects {json.dumps(doc['effects'])} from cycle {c}; budget {doc['budget']} cycles.  Limits: "
                  f"{lo:.5f} m/s before, {ln:.5f} m/s after; the old physics' best gait on the changed robot: "
                  f"{_pct(ob['speed'], ln)} % of the new limit, rotation {ob['rotation']:+.3f} rad/cycle.", "",
                  "| seed | before the change (% of old limit) | right after (same gait, % of new limit; rotation) | "
                  + " | ".join(f"+{a} cycles" for a in AFTER) + " | change taken at (cycles after) | stopped |",
                  "|---" * (5 + len(AFTER)) + "|"]
        for r in doc["runs"]:
            rows = r["rows"]
            before = _incumbent_at(rows, c)
            cells = [str(r["seed"]),
                     _pct(before["incumbent_true_old"]["speed"], lo) if before else "—",
                     (f"{_pct(before['incumbent_true_new']['speed'], ln)}; "
                      f"{before['incumbent_true_new']['rotation']:+.3f}") if before else "—"]
            for a in AFTER:
                at = _incumbent_at(rows, c + a)
                if at is None or at["cycles_used"] <= c:
                    cells.append("(no run ended)")
                else:
                    new = at["incumbent_true_new"]
                    cells.append(f"{_pct(new['speed'], ln)}; {new['rotation']:+.3f}")
            taken = [row for row in rows if "robot changed" in row["note"] and row["cycles_used"] > c]
            cells.append(str(taken[0]["cycles_used"] - c) if taken else "never")
            cells.append(r["stopped"])
            lines.append("| " + " | ".join(cells) + " |")
        win = doc.get("rotation_window")
        if win:
            sd = statistics.stdev(win["scatter"])
            lines += ["", "How narrow the target is: the changed robot's limit gait turns by "
                      f"{win['limit_rotation']:+.3f} rad/cycle, against the bound {win['bound']:g}."]
            if win["tight"]:
                pts = [*((t["max_rotation"], t["speed"] / ln) for t in win["tight"]), (win["bound"], 1.0)]
                b90 = next((b0 + (0.9 - v0) * (b1 - b0) / (v1 - v0) for (b0, v0), (b1, v1) in zip(pts, pts[1:])
                            if v0 < 0.9 <= v1), None)  # the bound at which the best gait reaches 90 %
                lines += [" Its best gait under tighter bounds (order 3, 8 starts): "
                          + "; ".join(f"|rotation| ≤ {t['max_rotation']:g}: {_pct(t['speed'], ln)} %"
                                      for t in win["tight"]) + "."]
                if pts[0][1] >= 0.9:
                    lines[-1] += f"  Even at |rotation| ≤ {pts[0][0]:g} the best gait is at 90 % of the limit or more."
                elif b90 is not None:
                    lines[-1] += (f"  So a gait at 90 % of the limit or more turns by {b90:.3f} to {win['bound']:g} "
                                  f"rad/cycle (interpolated): a band {win['bound'] - b90:.3f} rad/cycle wide.")
            lines[-1] += (f"  One candidate's rotation reading (4 cycles after 1 settling; {len(win['scatter'])} "
                          f"seeds) of the nominal gait on the changed robot scatters by {sd:.3f} rad/cycle (sd), "
                          f"mean {statistics.fmean(win['scatter']):+.3f}")
            ms = win.get("model_scatter") or []
            lines[-1] += (f"; the model of the same cycles, which the loop judges the bound on, by "
                          f"{statistics.stdev(ms):.3f} (sd over {len(ms)}), mean {statistics.fmean(ms):+.3f}."
                          if len(ms) > 1 else ".")
        cal = doc.get("miss_calibration")
        if cal:
            lines += ["", f"The model's miss (`motion_miss`, the loop's change test at `model_miss` = "
                      f"{LoopConfig(budget_cycles=10).model_miss:g}): models of the nominal gait's 5 cycles "
                      f"(training seeds {', '.join(map(str, MISS_TRAIN))}) predicting 4-cycle stretches (seeds "
                      f"{MISS_SEEDS[0]}–{MISS_SEEDS[-1]}) along their own shapes; the miss is the larger of the "
                      "translation missed (fraction of the measured) and the rotation missed (rad/cycle), of those "
                      "over one standard error.", "",
                      "| stretch | smallest | median | largest |", "|---|---|---|---|"]
            for kind, rows in cal.items():
                v = sorted(r["size"] for r in rows)
                lines.append(f"| {kind} | {v[0]:.3f} | {v[len(v) // 2]:.3f} | {v[-1]:.3f} |")
        lines += ["", "Runs (seed 0):", "", "| run | cycles | accepted | measured speed | measured rotation | note |",
                  "|---|---|---|---|---|---|"]
        for row in doc["runs"][0]["rows"]:
            lines.append(f"| {row['index']} | {row['cycles_used']} | {'yes' if row['accepted'] else 'no'} | "
                         f"{row['measured']:.4f} | {row['measured_rotation']:+.3f} | {row['note']} |")
        lines.append("")
    write("optimize_adapt.md", "\n".join(lines) + "\n")


def main() -> None:
    run_report_cli(__doc__, sorted(CASES), lambda n, a: run(n, a.seeds), report)


if __name__ == "__main__":
    main()
