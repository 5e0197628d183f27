"""`suds optimize --simulate` measured: the offline run → fit → step loop against the physics limit.

For each robot, start and seed the loop runs on the simulated robot (default OU perturbation,
100 Hz, 1 mm / 1 mrad noise) until its cycle budget is spent.  After the fact (never inside the
loop) every gait it ran is evaluated on the true physics at its passive periodic steady state.
The loop's history does not depend on its budget (the budget only decides when it stops), so
one run at the largest budget gives the gait it would return at every smaller budget: the
incumbent (best measured) gait after each run.  The limit is the physics optimiser's best gait
(order 3, 4 starts), computed here.

    python benchmarks/optimize_loop.py run purcell3 snake5     # → docs/results/optimize_loop_<robot>.json
    python benchmarks/optimize_loop.py run swimmer9 --seeds 0 --reuse-limit   # the limit of an earlier run
    python benchmarks/optimize_loop.py limit purcell3 snake5 swimmer9   # new limits into the stored runs
    python benchmarks/optimize_loop.py report                    # → docs/results/optimize_loop.md
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import math
import time
from pathlib import Path

import numpy as np
from _common import NECK4, RESULTS, SNAKE5, machine, stamp, write

from suds_ros.core import se2
from suds_ros.core.json_text import dumps
from suds_ros.core.optimize.loop import GaitSearch, LoopConfig, _resampled, along_se, optimize_loop
from suds_ros.core.optimize.physics import OptimizeConfig, evaluate_gait, optimize_gait
from suds_ros.core.physics.gait import Gait, constraint_violations, gait_limits, nominal_gait, time_reversed
from suds_ros.core.physics.systems import load_system

#: how the loop reads a run's speed (``loop.measure_cycles``), stored in each JSON
SPEED_READING = "from every point of the cycle"
MAX_ROTATION = LoopConfig.max_rotation  # the default bound on |rotation| per cycle for the speed objective
DEFAULTS = LoopConfig(budget_cycles=10)  # the loop's defaults, as the reports describe them
ROBOTS = {"purcell3": ("purcell3", 40, 15), "snake5": (SNAKE5, 60, 25),
          "swimmer9": ("swimmer9", 90, 45),
          "neck4": (NECK4, 50, 20)}  # name: (spec, budget, the target cycles: 5 per link)
PEERS = {"purcell3": "Deng et al. ≈ 30 (10 per link)", "snake5": "Deng et al. ≈ 50 (10 per link)",
         "swimmer9": "Deng et al. ≈ 90; Bittner et al. 900", "neck4": "Deng et al. ≈ 40 (10 per link)"}


def starts(nom: Gait) -> dict[str, Gait]:
    """The nominal gait and two poor starts: half its amplitude, and the wave run backwards in time."""
    return {"nominal": nom, "half amplitude": nom.from_vector(0.5 * nom.to_vector(), nom.order),
            "wave reversed": time_reversed(nom)}


#: the ablations: name → (the LoopConfig field changed from its default, its value, the section's title and text)
ABLATIONS = {
    "no-confirm": ("confirm_sigmas", 0.0, "every gain kept on its first measurement",
                   "`LoopConfig.confirm_sigmas` = 0 (`--ablation no-confirm`; the default runs a candidate again "
                   "when both its measured and its predicted gain are within 1 standard error of the difference, "
                   "and judges both stretches pooled): every candidate that measures better is kept at once, as "
                   "before 2026-11-28.", "confirmations (default)"),
    "no-pool": ("pool_rejected", 0, "the model of the incumbent's cycles alone",
                "`LoopConfig.pool_rejected` = 0 (`--ablation no-pool`; the default pools the newest 2 stretches "
                "of the candidates rejected since the incumbent was set into the incumbent's model, refitted "
                "after each rejection): each step's model is fitted to the incumbent's own cycles only, as before "
                "2026-11-27.", "rejections (ablation)"),
    "no-scale": ("scale_step", math.inf, "no scaled start",
                 "`LoopConfig.scale_step` = inf (`--ablation no-scale`; the default runs a start whose oscillation "
                 "can grow by 1.25× or more inside the bounds scaled to them, right after the start): every step "
                 "is the trust region's, as before 2026-12-01.", "rejections (ablation)"),
    "no-reverse": ("reverse_trial", False, "no trial of the wave run backwards",
                   "`LoopConfig.reverse_trial` = False (`--ablation no-reverse`, `--no-reverse-trial`; the default "
                   "runs the incumbent backwards in time, r(−t), the travelling wave the other way, as the step "
                   "after the scaled start or, when the start is not scaled, after the start, when the model of "
                   "the incumbent's cycles predicts it better, judged by measurement like every candidate; not "
                   "where backwards is the same drive started elsewhere, as purcell3's): every step is the trust "
                   "region's, as before 2026-12-02.",
                   "rejections (ablation)"),
    "mean-rotation": ("rotation_from_model", False, "the rotation bound judged on the mean of the cycles",
                      "`LoopConfig.rotation_from_model` = False (`--ablation mean-rotation`, "
                      "`--no-rotation-from-model`; the default reads each run's rotation off the SUDS model fitted "
                      "to its own cycles, at δ = 0, where it fits: `docs/results/optimize_rotation.md`): the "
                      "straight-course bound is judged on the mean of the measured cycles' rotations, as before "
                      "2026-12-04.", "rejections (ablation)"),
    "pool-incumbents": ("pool_incumbents", 2, "the earlier incumbents' newest 2 stretches pooled too (an option)",
                        "`LoopConfig.pool_incumbents` = 2 (`--ablation pool-incumbents`, `--pool-incumbents 2`; the "
                        "default, 0, fits each step's model to the incumbent's stretches and the rejected candidates' "
                        "only): the newest 2 stretches of the gaits that were the incumbent before the current one "
                        "are pooled into its model too.  Not an ablation of a default but an option measured against "
                        "it: the model of a few cycles over-predicts a step's gain on swimmer9 "
                        "(`optimize_step_aim.md`), and more data nearby narrows that.", "rejections (option)"),
    "pool-all": ("pool_incumbents", 1000, "every earlier incumbent's stretches pooled too (an option)",
                 "`LoopConfig.pool_incumbents` = 1000 (`--ablation pool-all`, `--pool-incumbents 1000`; the "
                 "default, 0, fits each step's model to the incumbent's stretches and the rejected candidates' "
                 "only): every stretch of every gait that was the incumbent since the start or the last change "
                 "is pooled into the step's model too.  An option measured against the default: the model of "
                 "swimmer9's first 4 cycles is 8-80 % off along a step's true shapes, one of 40 cycles 4.5 % "
                 "(`optimize_step_aim.md`), so all the data the loop has gathered may aim better than the "
                 "newest few cycles.", "rejections (option)"),
    "pose-frame": ("body_frame", "pose", "models fitted in the recorded pose frame",
                   "`LoopConfig.body_frame` = 'pose' (`--ablation pose-frame`, `--body-frame pose`; the default "
                   "fits every model in the shape frame, the recorded yaw turned by the combination of joint "
                   "angles it follows: `data.shape_frame`, `optimize_step_aim.md`): every model is fitted to the "
                   "recorded pose as it is, as before 2026-12-04.  These runs are the default runs of 2026-12-04 "
                   "22:08 UTC, made just before the option existed by the same code path (the JSON's `note`).",
                   "rejections (ablation)"),
    "trust4": ("trust", 4.0, "a first trust radius of 4 σ (an option)",
               "`LoopConfig.trust` = 4 (`--ablation trust4`; the default starts the trust region at 2 σ of the "
               "data's spread and doubles it after a confirmed full step, up to 8): every step starts twice as "
               "far out.  Measured once the steps aimed (the shape frame) and the speed was read from every "
               "point of the cycle; in the pose frame, with the speed read from the cycle starts, it lowered "
               "swimmer9 (README).", "rejections (option)"),
    "no-kernel": ("random_features", False, "models without random shape features",
                  "`LoopConfig.random_features` = False (`--ablation no-kernel`; the default lets every model's "
                  "cross-validation choose among the identifier's random-feature models of the whole shape too, "
                  "which it does on purcell3 and swimmer9 from a few cycles): every model is the Fourier SUDS "
                  "regression.  Measured because those models' steps are predicted far above what they measure, "
                  "which a smooth regression might extrapolate better.", "rejections (ablation)"),
    "margin5": ("rotation_margin", 0.5, "steps aimed at half the rotation bound (the default until 2026-12-05)",
                "`LoopConfig.rotation_margin` = 0.5 (`--ablation margin5`; the default, 0.8 since 2026-12-05, asks "
                "each step's model for a rotation within 0.8 of the 0.05 rad/cycle bound: of zero for a full step, "
                "of the incumbent's own for a half-wave one): the steps plan deeper inside the bound, as before "
                "2026-12-05.  These are the default runs of 2026-12-05 03:06–03:14 UTC, made by the same code "
                "with the old default (each JSON's `measured`).  The ablations above and below that were run "
                "before the change are compared with these runs, not with the new default (their tables say so).",
                "rejections (ablation)"),
    "start-speed": ("speed_reading", "from the cycle starts", "speeds read from the cycle starts",
                    "Every run's speed is read as |mean of g(t)⁻¹ g(t + 1/f)| · f over its cycle starts t, "
                    "with the se of the cycles' components along their mean (`--ablation start-speed`; the "
                    "benchmark's `_StartSpeedSearch`; the loop's reading until 2026-12-05).  The default counts "
                    "every point of the cycle (`measure_cycles`): counted from the starts, a perturbation's turn "
                    "per cycle times the body point's sideways offset there enters each cycle's chord "
                    "(`optimize_noise.md`).", "rejections (ablation)"),
    "oracle": ("judge", "truth", "candidates judged on the true physics (a bound, not a method)",
               "Every run is judged on its gait's *true* speed and rotation at the passive periodic steady state "
               "(`--ablation oracle`; the benchmark's `_OracleSearch`), with no measurement noise; the change "
               "tests are off (`change_sigmas` = inf). The model, its data and the steps are the loop's own. "
               "What this gains over the default is what noise in the measured objective costs; what it still "
               "misses at the target is the limit of the steps themselves (a model of 4–5 cycles, a trust region "
               "of its spread).", "rejections (ablation)"),
}


def from_cycle_starts(poses: list[np.ndarray], spc: int, hz: float) -> tuple[float, float, int]:
    """Speed of pose series counted from their cycle starts, m/s, its se and the cycles (the loop's until 2026-12-05).

    |mean of g(t)⁻¹ g(t + 1/f)| · f over the cycle starts t of every stretch, with the se of the cycles'
    components along their mean.
    """
    g = np.concatenate([se2.relative(p[np.arange(k) * spc], p[np.arange(1, k + 1) * spc])[:, :2]
                        for p in poses for k in [(p.shape[0] - 1) // spc]])
    return float(np.hypot(*g.mean(axis=0))) * hz, along_se(g) * hz, len(g)


class _StartSpeedSearch(GaitSearch):
    """The loop's search with each run's speed read from its cycle starts (:func:`from_cycle_starts`)."""

    def _measure(self, data, gait):
        m = super()._measure(data, gait)
        poses, _ = _resampled(data, self.config.samples_per_cycle, gait.gait_hz, False)
        speed, se, k = from_cycle_starts(poses, self.config.samples_per_cycle, gait.gait_hz)
        return dataclasses.replace(m, speed=speed, speed_se=se, speed_dof=k - 1.0 if k > 1 else math.inf)


class _OracleSearch(GaitSearch):
    """The loop's search, but each run is judged on its gait's true objective on the physics (never the method).

    Only the measured speed and rotation are replaced (standard errors ~0); the model is still fitted to
    the recorded cycles.
    """

    def __init__(self, system, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._system, self._truth = system, {}

    def _measure(self, data, gait):
        m = super()._measure(data, gait)
        key = gait.to_vector().tobytes()
        if key not in self._truth:
            self._truth[key] = evaluate_gait(self._system, gait)
        true = self._truth[key]
        tiny = 1e-12
        return dataclasses.replace(m, speed=true["speed"], rotation=true["rotation"],
                                   turn=true["rotation"] * gait.gait_hz, speed_se=tiny, rotation_se=tiny,
                                   model_rotation=None, model_rotation_se=None)  # (the bound judged on the truth)


def _path(name: str, ablation: str | None) -> Path:
    """The JSON of a robot's runs: the loop's defaults, or an ablation's."""
    return RESULTS / (f"optimize_loop_{name}.json" if ablation is None else f"optimize_loop_{name}_{ablation}.json")


def run(name: str, seeds: list[int], kinds: list[str], reuse_limit: bool = False, ablation: str | None = None) -> None:
    spec, budget, target = ROBOTS[name]
    system = load_system(spec)
    nom = nominal_gait(system)
    limits = gait_limits(system)
    path = _path(name, ablation)
    src = _path(name, None)  # the limit is the robot's, whatever the loop's settings
    change = {} if ablation is None else {ABLATIONS[ablation][0]: ABLATIONS[ablation][1]}
    loop_change = {"change_sigmas": math.inf} if ablation == "oracle" else {} if ablation == "start-speed" else change
    old = json.loads(src.read_text()) if src.exists() else {}
    if reuse_limit and old.get("limit"):  # the physics limit does not depend on the loop: reuse it
        limit, secs = old["limit"], old["limit_seconds"]
    else:
        t0 = time.perf_counter()
        limit = optimize_gait(system, OptimizeConfig(order=3, starts=4)).value
        secs = time.perf_counter() - t0
    doc = {"robot": name, "budget": budget, "target": target, "limit": limit, "limit_seconds": secs,
           "ablation": ablation, "rotation_from_model": DEFAULTS.rotation_from_model,
           "body_frame": DEFAULTS.body_frame, "speed_reading": SPEED_READING,
           "rotation_margin": DEFAULTS.rotation_margin, **change,
           "machine": machine(), "measured": f"{stamp()} on {machine()}", "runs": []}
    print(f"{name}: limit {limit:.5f} ({doc['limit_seconds']:.0f} s)", flush=True)
    for kind, start in starts(nom).items():
        if kind not in kinds:
            continue
        for seed in (seeds if kind != "wave reversed" else seeds[:1]):
            t1 = time.perf_counter()
            cfg = LoopConfig(budget_cycles=budget, seed=seed, **loop_change)
            judge = (functools.partial(_OracleSearch, system) if ablation == "oracle"
                     else _StartSpeedSearch if ablation == "start-speed" else GaitSearch)
            res = optimize_loop(system, cfg, start=start, limits=limits, search=judge)
            secs = time.perf_counter() - t1
            rows, incumbent = [], None
            for it in res.iterations:
                true = evaluate_gait(system, it.gait)
                if it.accepted:
                    replaced, incumbent = incumbent, true
                else:
                    replaced = incumbent
                rows.append({"index": it.index, "cycles_used": it.cycles_used, "accepted": it.accepted,
                             "predicted": it.predicted, "measured": it.measured.speed,
                             "measured_rotation": it.measured.rotation, "true": true["speed"],
                             "true_rotation": true["rotation"], "incumbent_true": incumbent["speed"],
                             "incumbent_true_rotation": incumbent["rotation"],
                             "replaced_true": None if replaced is None else replaced["speed"],
                             "confirming": it.note.startswith("to be confirmed"),
                             "in_bounds": not constraint_violations(it.gait, limits)})
            doc["runs"].append({"start": kind, "seed": seed, "rows": rows, "cycles_used": res.cycles_used,
                                "stopped": res.stopped, "seconds": secs})
            last = rows[-1]
            print(f"  {kind} seed {seed}: {res.cycles_used} cycles, {100 * last['incumbent_true'] / limit:.1f} % "
                  f"of the limit, {secs:.0f} s; {res.stopped}", flush=True)
            path.write_text(dumps(doc))


def relimit(name: str) -> None:
    """The robot's limit from the physics optimiser as it is now, into every JSON of its loop runs (and ablations).

    The runs never see the limit (every row holds the true speed of the gait run, not its share), so a
    better limit re-scores them without running them again; the CMA report reads it from here too.
    """
    system = load_system(ROBOTS[name][0])
    t0 = time.perf_counter()
    limit = optimize_gait(system, OptimizeConfig(order=3, starts=4)).value
    secs = time.perf_counter() - t0
    for path in [_path(name, None), *(_path(name, a) for a in ABLATIONS)]:
        if path.exists():
            doc = json.loads(path.read_text())
            old = doc.get("limit")
            doc["limit"] = limit
            if "limit_seconds" in doc:
                doc["limit_seconds"] = secs
            path.write_text(dumps(doc))
            print(f"{path.name}: limit {old:.5f} → {limit:.5f} m/s ({secs:.0f} s)", flush=True)


def _cycles_to(rows: list[dict], limit: float, frac: float) -> str:
    for r in rows:
        if r["incumbent_true"] >= frac * limit:
            return str(r["cycles_used"])
    return "—"


def _at(rows: list[dict], cycles: int) -> dict | None:
    done = [r for r in rows if r["cycles_used"] <= cycles]
    return done[-1] if done else None


def aggregates() -> list[str]:
    """One line per robot: how many runs met the targets, the spread of the results, the side conditions."""
    out = []
    for name in ROBOTS:
        path = RESULTS / f"optimize_loop_{name}.json"
        if not path.exists():
            out.append(f"- {name}: not run.")
            continue
        doc = json.loads(path.read_text())
        limit, target, runs = doc["limit"], doc["target"], doc["runs"]
        if not runs:
            out.append(f"- {name}: no finished run.")
            continue
        at_t = [(_at(r["rows"], target) or r["rows"][0])["incumbent_true"] / limit for r in runs]
        at_b = [r["rows"][-1]["incumbent_true"] / limit for r in runs]
        c95 = [_cycles_to(r["rows"], limit, 0.95) for r in runs]
        rot = [abs(r["rows"][-1]["incumbent_true_rotation"]) for r in runs]
        ratios = [x["true"] / x["replaced_true"] for r in runs for x in r["rows"] if x["replaced_true"]]
        slow = sum(q < 0.95 for q in ratios)
        # kept: accepted rows of another gait (a re-run incumbent reads the same true speed as the one it "replaced")
        kept = [x["true"] / x["replaced_true"] for r in runs for x in r["rows"]
                if x["replaced_true"] and x["accepted"] and x["true"] != x["replaced_true"]]
        worse = sum(b < r["rows"][0]["true"] / limit - 1e-9 for b, r in zip(at_b, runs))
        out.append(
            f"- {name} ({len(runs)} runs): ≥ 95 % of the limit at the target {target} cycles in "
            f"{sum(q >= 0.95 for q in at_t)} of {len(runs)} (range {100 * min(at_t):.1f}–{100 * max(at_t):.1f} %); "
            f"at the budget {100 * min(at_b):.1f}–{100 * max(at_b):.1f} %; cycles to 95 %: {', '.join(c95)}; "
            f"returned gait worse on the physics than the start in {worse} run(s); returned gait's true |rotation| "
            f"> 0.05 rad/cycle in {sum(x > 0.05 for x in rot)} run(s) (largest {max(rot):.3f}); gaits run more than "
            f"5 % slower than the incumbent: {slow} of {len(ratios)}; gaits kept (accepted) more than 5 % slower than "
            f"the incumbent they replaced: {sum(q < 0.95 for q in kept)} of {len(kept)}"
            f"{f' (the slowest kept at {100 * min(kept):.1f} % of the speed it replaced)' if kept else ''}.")
    return out


def ablation() -> list[str]:
    """Tables of the default loop against each of the ABLATIONS that was run, run by run."""
    out = []
    for key, (field_name, value, title, text, counted) in ABLATIONS.items():
        section: list[str] = []
        oracle_lines: list[str] = []
        for name in ROBOTS:
            other = _path(name, key)
            if not other.exists():
                continue
            b = json.loads(other.read_text())
            a, base_note = _baseline(name, key, b)
            if a is None:
                continue
            limit, target = a["limit"], a["target"]
            runs_b = {(r["start"], r["seed"]): r for r in b["runs"]}
            if not section:
                section += [f"## Ablation: {title}", "",
                            f"{text}  % of the limit of the incumbent at the target and at the budget, default / "
                            f"ablation; the same seeds, so the two differ only from the first decision the "
                            "setting changes on.", "",
                            f"| robot | start | seed | {field_name} | at the target: default / ablation | "
                            f"at the budget: default / ablation | {counted} |", "|" + "---|" * 7]
            sums = [0.0, 0.0]
            rot_rejected = rejected = 0
            for ra in a["runs"]:
                rb = runs_b.get((ra["start"], ra["seed"]))
                if rb is None:
                    continue
                ta, tb = (_at(r["rows"], target) or r["rows"][0] for r in (ra, rb))
                ba, bb = ra["rows"][-1]["incumbent_true"] / limit, rb["rows"][-1]["incumbent_true"] / limit
                sums[0] += ba
                sums[1] += bb
                n = (sum(bool(x.get("confirming")) for x in ra["rows"]) if key == "no-confirm"
                     else sum(not x["accepted"] for x in rb["rows"]))
                rejected += sum(not x["accepted"] for x in rb["rows"])
                rot_rejected += sum(not x["accepted"] and abs(x["true_rotation"]) > MAX_ROTATION for x in rb["rows"])
                shown = value if b.get(field_name) is None else b[field_name]  # (inf is stored as null)
                section.append(f"| {name} | {ra['start']} | {ra['seed']} | {shown} | "
                               f"{100 * ta['incumbent_true'] / limit:.1f} / {100 * tb['incumbent_true'] / limit:.1f} | "
                               f"{100 * ba:.1f} / {100 * bb:.1f} | {n} |")
            section.append(f"| {name} | **sum at the budget** | | | | {100 * sums[0]:.1f} / {100 * sums[1]:.1f} | |")
            if base_note:
                section.append(base_note)
            if key != "margin5" and _margin(a) != _margin(b):
                section.append(f"| {name} | *other code*: the default's steps aimed at {_margin(a):g} of the rotation "
                               f"bound, the ablation's at {_margin(b):g} | | | | | |")
            if a.get("machine") != b.get("machine"):  # the runs' paths turn on last bits: say where each ran
                section.append(f"| {name} | *measured apart*: default on {a.get('machine', 'an earlier setup')}, "
                               f"ablation on {b.get('machine', 'an earlier setup')} | | | | | |")
            if key != "mean-rotation" and _reading(a) != _reading(b):  # an ablation run before the model's reading
                section.append(f"| {name} | *other code*: the default's bound read on {_reading(a)}, the "
                               f"ablation's on {_reading(b)} | | | | | |")
            if key != "pose-frame" and _frame(a) != _frame(b):  # an ablation run before the shape frame
                section.append(f"| {name} | *other code*: the default's models fitted in the {_frame(a)} frame, the "
                               f"ablation's in the {_frame(b)} frame | | | | | |")
            if _speed_reading(a) != _speed_reading(b):  # an ablation run before the every-point reading
                section.append(f"| {name} | *other code*: the default's speeds read {_speed_reading(a)}, the "
                               f"ablation's {_speed_reading(b)} | | | | | |")
            if key == "oracle":
                oracle_lines.append(f"- {name}: {rot_rejected} of the {rejected} rejected candidates break the "
                                    f"rotation bound ({MAX_ROTATION} rad/cycle) on the physics.")
        if oracle_lines:  # judged on the truth, a rejection is the step's own fault: which bound it broke
            section += ["", "Judged on the truth, a candidate is rejected only for its own true speed or rotation:",
                        "", *oracle_lines]
        out += section + [""] if section else []
    return out


def _frame(doc: dict) -> str:
    """The body frame a run's models were fitted in (runs before the option: the pose frame)."""
    return str(doc.get("body_frame") or "pose")


def _speed_reading(doc: dict) -> str:
    """How a run's speeds were measured (runs before 2026-12-05 stored nothing: from the cycle starts)."""
    return str(doc.get("speed_reading") or "from the cycle starts")


def _margin(doc: dict) -> float:
    """The rotation margin a run's steps were aimed with (runs before 2026-12-05 stored none: 0.5)."""
    return float(doc.get("rotation_margin") or 0.5)


def _baseline(name: str, key: str, other: dict) -> tuple[dict | None, str]:
    """The runs an ablation is compared with, and a note when they are not the current default's.

    An ablation run before the default's rotation margin changed differs from the current default in
    that too; it is compared with the default runs made at its own margin (``margin5``), when there.
    """
    base = _path(name, None)
    if not base.exists():
        return None, ""
    doc = json.loads(base.read_text())
    old = _path(name, "margin5")
    if key != "margin5" and _margin(doc) != _margin(other) and old.exists():
        prior = json.loads(old.read_text())
        if _margin(prior) == _margin(other):
            return prior, (f"| {name} | *default* here: the runs at rotation_margin {_margin(prior):g}, the default "
                           f"when this ablation was run (`margin5`), not the current {_margin(doc):g} | | | | | |")
    return doc, ""


def _reading(doc: dict) -> str:
    """What a run's rotation bound was judged on (runs before 2026-12-04 stored nothing: the cycles' mean)."""
    return "the model's rotation" if doc.get("rotation_from_model", False) else "the cycles' mean rotation"


def limit_info() -> dict[str, tuple[float, float]]:
    """Robot → (limit m/s, seconds the physics optimiser took) from the JSON files."""
    out = {}
    for name in ROBOTS:
        path = RESULTS / f"optimize_loop_{name}.json"
        if path.exists():
            doc = json.loads(path.read_text())
            out[name] = (doc["limit"], doc["limit_seconds"])
    return out


def nominal_shares() -> dict[str, float]:
    """Robot → the nominal gait's true speed as a % of the limit (the first row of a nominal-start run)."""
    out = {}
    for name in ROBOTS:
        path = RESULTS / f"optimize_loop_{name}.json"
        if path.exists():
            doc = json.loads(path.read_text())
            nominal = [r["rows"][0]["true"] for r in doc["runs"] if r["start"] == "nominal"]
            if nominal:
                out[name] = 100 * nominal[0] / doc["limit"]
    return out


def _verdict(row: dict, rerun: bool) -> str:
    """A run's outcome as the per-run tables say it."""
    if rerun:
        return "re-run of the incumbent"
    if row["accepted"]:
        return "yes"
    return "to be confirmed" if row.get("confirming") else "no"


def report() -> None:
    when = []
    for name in ROBOTS:  # each JSON's runs keep the time they were made (those before 2026-12-05 03:00 did not)
        path = _path(name, None)
        if path.exists():
            when.append(f"{name} {json.loads(path.read_text()).get('measured', 'at a time not recorded')}")
    lines = ["# `suds optimize --simulate`: the offline run → fit → step loop, measured", "",
             f"Report written {stamp()} by `benchmarks/optimize_loop.py` from its runs (the defaults' measured: "
             f"{'; '.join(when)}; each ablation's machine where it differs; nice 5, the 2 cores shared with other "
             "work, so times are rough).", "",
             f"The loop (`suds_ros/core/optimize/loop.py`, defaults): the start gait runs {DEFAULTS.settle_cycles} "
             f"settling + {DEFAULTS.first_cycles} measured cycles; each candidate {DEFAULTS.settle_cycles} settling "
             f"+ {DEFAULTS.step_cycles} measured cycles (every cycle counted); right after the start, a start "
             f"whose oscillation can grow by {DEFAULTS.scale_step:g}× inside its bounds is run scaled to them, and "
             "the step after that runs the incumbent backwards in time, the travelling wave the other way, "
             "when the model of its cycles predicts that better (`reverse_trial`; not where backwards is the "
             "same drive started elsewhere, as purcell3's single sinusoid); each is kept if it measures better; "
             "then the SUDS model is fitted "
             "to the incumbent gait's measured cycles and to the newest 2 stretches of the candidates rejected "
             "since it became the incumbent (refitted after each rejection); one trust-region step (κ = 2 σ, "
             "doubled after a confirmed full step up to 8, halved after a rejection and after an accepted step "
             "that measured under a quarter of its predicted gain, not below 2 there); from a half-wave symmetric "
             "incumbent measured on course (every start here but neck4's, whose drive has an offset) the step moves "
             "only the odd harmonics, so every gait run from there is half-wave symmetric and runs straight on "
             "the mirror-symmetric robots, and the model's "
             f"rotation is held within {DEFAULTS.rotation_margin * MAX_ROTATION:g} rad/cycle of its value for the "
             f"incumbent (of zero for a full step: `rotation_margin` = {DEFAULTS.rotation_margin:g} of the "
             "bound); a step is kept only if the "
             "*measured* speed (the net motion per cycle counted from every point of the cycle: "
             "`measure_cycles`, `optimize_noise.md`) is higher and its |rotation| (read off the SUDS model "
             "fitted to the run's own cycles, at δ = 0: `rotation_from_model`; the per-run tables show the "
             "cycles' mean) is ≤ 0.05 rad/cycle or over it by at most "
             f"{DEFAULTS.rotation_sigmas:g} standard error; a measured gain within {DEFAULTS.confirm_sigmas:g} "
             "standard error of the difference, for a step whose predicted gain is within as much, is run again "
             "and judged on both stretches pooled. "
             "Robot: the simulator with its default OU perturbation (0.175 rad, κ = 8 /s), 100 Hz, 1 mm / 1 mrad "
             "noise, seeded. 'true' = a gait on the physics at its passive periodic steady state, computed after "
             "the run; the loop never sees it. The gait returned at a budget is the incumbent at that point.", ""]
    lines += ["## Summary", "",
              "| robot | limit (m/s) | start | seed | start % | % at the target (cycles) | % at the budget (cycles) "
              "| cycles to 90 / 95 / 99 % | returned gait's true rotation | worst true run / incumbent | "
              "gaits run (accepted) | all in bounds | stopped | time s |", "|" + "---|" * 14]
    details = []
    for name in ROBOTS:
        path = RESULTS / f"optimize_loop_{name}.json"
        if not path.exists():
            lines.append(f"| {name} | not run | | | | | | | | | | | | |")
            continue
        doc = json.loads(path.read_text())
        limit, target = doc["limit"], doc["target"]
        for run_ in doc["runs"]:
            rows = run_["rows"]
            at_t, last = _at(rows, target), rows[-1]
            worst = min((r["true"] / r["replaced_true"] for r in rows if r["replaced_true"]), default=float("nan"))
            lines.append(
                f"| {name} | {limit:.5f} | {run_['start']} | {run_['seed']} | {100 * rows[0]['true'] / limit:.1f} | "
                + (f"{100 * at_t['incumbent_true'] / limit:.1f} ({target})" if at_t else "—") + " | "
                f"{100 * last['incumbent_true'] / limit:.1f} ({run_['cycles_used']} of {doc['budget']}) | "
                f"{' / '.join(_cycles_to(rows, limit, f) for f in (0.90, 0.95, 0.99))} | "
                f"{last['incumbent_true_rotation']:+.3f} | {worst:.3f} | "
                f"{len(rows)} ({sum(r['accepted'] for r in rows)}) | "
                f"{'yes' if all(r['in_bounds'] for r in rows) else 'NO'} | {run_['stopped'].split(':')[0]} | "
                f"{run_['seconds']:.0f} |")
            details += [f"### {name}, {run_['start']}, seed {run_['seed']}", "",
                        "| run | cycles used | predicted (m/s) | measured (m/s) | measured rotation | true (m/s) | "
                        "true rotation | accepted | incumbent true, % of limit |", "|" + "---|" * 9]
            for i, r in enumerate(rows):
                pred = "—" if r["predicted"] is None else f"{r['predicted']:.4f}"
                # the same gait as the incumbent, run again after a collapsed trust region (same true value)
                rerun = i > 0 and r["accepted"] and r["true"] == rows[i - 1]["incumbent_true"]
                details.append(
                    f"| {r['index']} | {r['cycles_used']} | {pred} | {r['measured']:.4f} | "
                    f"{r['measured_rotation']:+.3f} | {r['true']:.4f} | {r['true_rotation']:+.3f} | "
                    f"{_verdict(r, rerun)} | "
                    f"{100 * r['incumbent_true'] / limit:.1f} |")
            details.append("")
    lines += ["", "## Aggregates (computed from the table)", "", *aggregates(), ""]
    lines += ["", "Target cycles = the issue's 5 cycles per link (purcell3 15, snake5 25, swimmer9 45, neck4 20). "
              "neck4 (`test/data/robots/neck4.yaml`) is a robot of ours whose nominal wave runs the slow way (a "
              "passive neck). Peers: "
              + "; ".join(f"{k}: {v}" for k, v in PEERS.items()) + ". 'worst true run / incumbent' = the lowest "
              "ratio of a gait's true speed to that of the incumbent it was run against (the issue asks ≥ 0.95). "
              "Predicted values are the model's at the step (for run 0: the first model's fit of the start gait).",
              "", "## Notes", "",
              "- Cycles to x % counts the start gait's cycles too; a start already above x % reads as the start's "
              f"{DEFAULTS.settle_cycles + DEFAULTS.first_cycles} cycles (the designer's nominal sinusoids are at "
              + ", ".join(f"{k} {v:.1f} %" for k, v in nominal_shares().items()) + " of the limit).",
              "- The limits count a gait's cycle from its best point (the physics optimiser's `free_origin`): a gait "
              "at the rotation bound goes further counted from some points of its cycle than from others, and the "
              "speed optima of snake5 and swimmer9 turn at the bound.  The loop's half-wave gaits run straight, so "
              "the origin gives them nothing: their family's own optimum is below these limits by the turn's share "
              "(README, 'the time origin').",
              "- 'Bounds': every gait the loop ran or returned is within the joint range and speed bounds (checked "
              "on the spec's grid). The simulator's OU perturbation (0.175 rad) acts on top of the gait's set-points, "
              "so the perturbed set-points themselves do leave the bounds by up to about that much; that is the "
              "simulated robot's behaviour, not a gait the loop chose.",
              "- The measured speed of 4 cycles under this perturbation scatters by 1–9 % of the speed on these "
              "robots' near-limit gaits and by 18 % on neck4's nominal one (`optimize_noise.md`; counted from "
              "the cycle starts, as before 2026-12-05, up to 16 % on swimmer9: the perturbation's turn times the "
              "head point's sideways offset), so near the limit a candidate can still be "
              "accepted on a lucky measurement (the 'returned gait worse than the start' count); a collapsed "
              "trust region re-runs the incumbent and pools its measurements, which corrects some of these.",
              "- The mean rotation of 4 cycles is noisy: under this perturbation its error reaches "
              "±0.1–0.2 rad/cycle on swimmer9 (per-run tables), larger than the 0.05 bound.  The bound is judged "
              "on the model of the run's cycles instead (rms error 0.045 against the mean's 0.095 rad/cycle on "
              "swimmer9's nominal gait: `optimize_rotation.md`; the ablation `mean-rotation` below); straight "
              "gaits are refused only when over the bound by more than a standard error, and when the incumbent "
              "itself reads outside that, the smaller violation wins. "
              "'incumbent true, % of limit' counts an accepted gait whatever its true rotation; the summary's "
              "rotation column is the returned gait's.",
              "- Predictions are optimistic (the model extrapolates beyond the incumbent's data); the loop never "
              "acts on a prediction alone.",
              "- Not measured here: CMA-ES at the same budget (`optimize_cma.md`), the turn objective, efficiency "
              "(`optimize_efficiency.md`). The limits were computed by this script (the physics optimiser, "
              "order 3, 4 starts, the time origin free; with `--reuse-limit` taken from the robot's earlier JSON, "
              "and `limit` recomputes them into the stored runs): "
              + ", ".join(f"{k} {v[0]:.5f} m/s in {v[1]:.0f} s" for k, v in limit_info().items()) + ".",
              "", *ablation(), "## Per run", "", *details]
    write("optimize_loop.md", "\n".join(lines) + "\n")


def main() -> None:
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("robots", nargs="+", choices=list(ROBOTS))
    r.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    r.add_argument("--starts", nargs="+", default=["nominal", "half amplitude", "wave reversed"])
    r.add_argument("--reuse-limit", action="store_true", help="take the limit from an earlier run's JSON")
    r.add_argument("--ablation", choices=list(ABLATIONS),
                   help="run an ablation (ABLATIONS) instead of the defaults: writes optimize_loop_<robot>_<name>.json")
    lim = sub.add_parser("limit", help="recompute the robots' limits and store them in every JSON of their loop runs")
    lim.add_argument("robots", nargs="+", choices=list(ROBOTS))
    sub.add_parser("report")
    args = ap.parse_args()
    if args.cmd == "run":
        for name in args.robots:
            run(name, args.seeds, args.starts, args.reuse_limit, args.ablation)
    elif args.cmd == "limit":
        for name in args.robots:
            relimit(name)
    else:
        report()


if __name__ == "__main__":
    main()
