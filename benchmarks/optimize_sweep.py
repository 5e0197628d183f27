"""The data-driven loop on robots nobody tuned it on: random model files, 5 cycles per link.

``python benchmarks/optimize_sweep.py [--robots N] [--seed S] [--loop-seeds L ...] [--rotation-margin F] [--out NAME]``
writes N seeded random ``suds-robot/1`` files (3–7 links, random driven/passive split, springs with
damping, rest, k3 and dry friction, per-link drag, the pose frame on any link with an offset, joint range
and speed limits on some joints), runs
``suds optimize --simulate FILE --budget-cycles 5×links --seed L --limit yes --json`` for each loop seed
L on each in its own process (the user's path: the loop sees only the recorded streams), and writes
``docs/results/optimize_sweep.md`` (with ``--rotation-margin F``, passed on to the loop,
``optimize_sweep_margin<F>.md``; ``--out`` names another file): per robot and seed the start and returned
gait as per cent of the physics limit, the start's basin (SLSQP on the physics from the start gait alone:
what a perfect local optimiser reaches from there), the returned gait's measured and predicted speed, its
motion test, and the run's errors if any.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

from _common import ROOT, machine, stamp, write

from suds_ros.core.optimize.physics import OptimizeConfig, optimize_gait
from suds_ros.core.physics.systems import load_system

#: a run that takes longer than this is reported as timed out
TIMEOUT_S = 1800


def random_robot(rng: np.random.Generator, name: str) -> dict[str, object]:
    """A random ``suds-robot/1`` document, valid by construction.

    At least one driven joint, every passive joint with a spring, the nominal gait inside any range or
    speed limit it sets.
    """
    n = int(rng.integers(3, 8))
    hz = float(rng.choice([0.5, 1.0, 1.5, 2.0]))
    c_par = round(float(rng.uniform(0.6, 1.2)), 3)
    links: list[dict[str, float]] = []
    for _ in range(n):
        link = {"length": round(float(rng.uniform(0.6, 1.4)), 3)}
        if rng.random() < 0.3:
            link["c_perp"] = round(float(rng.uniform(1.2, 3.5)), 3)
        links.append(link)
    driven = rng.random(n - 1) < 0.5
    if not driven.any():
        driven[rng.integers(n - 1)] = True
    lag = float(rng.uniform(0.5, 1.5))
    joints: list[dict[str, object]] = []
    for j in range(n - 1):
        joint: dict[str, object] = {"name": f"j{j + 1}"}
        if driven[j]:
            amp = round(float(rng.uniform(0.3, 1.1)), 3)
            gait = {"amplitude": amp, "phase": round(lag * j + float(rng.normal(0, 0.2)), 3)}
            if rng.random() < 0.3:
                gait["offset"] = round(float(rng.uniform(-0.1, 0.1)), 3)
            joint.update(actuated=True, gait=gait)
            reach = amp + abs(float(gait.get("offset", 0.0)))
            if rng.random() < 0.5:
                joint["limit"] = round(reach * float(rng.uniform(1.05, 1.6)), 3)
            if rng.random() < 0.5:
                joint["speed_limit"] = round(2 * math.pi * hz * amp * float(rng.uniform(1.05, 2.0)), 3)
        else:
            joint["stiffness"] = round(float(rng.uniform(0.3, 6.0)), 3)
            if rng.random() < 0.4:
                joint["damping"] = round(float(rng.uniform(0.05, 0.5)), 3)
            if rng.random() < 0.3:
                joint["rest"] = round(float(rng.uniform(-0.1, 0.1)), 3)
            if rng.random() < 0.2:
                joint["k3"] = round(float(rng.uniform(0.0, 2.0)), 3)
            if rng.random() < 0.15:
                joint["coulomb"] = round(float(rng.uniform(0.001, 0.02)), 4)
        joints.append(joint)
    body = {"link": int(rng.integers(1, n + 1)),
            "offset": [round(float(rng.uniform(-0.1, 0.1)), 3), round(float(rng.uniform(-0.05, 0.05)), 3),
                       round(float(rng.uniform(-0.4, 0.4)), 3)]}
    return {"format": "suds-robot/1", "name": name, "gait_hz": hz,
            "drag": {"c_par": c_par, "c_perp": round(c_par * float(rng.uniform(1.5, 3.0)), 3)},
            "links": links, "body": body, "joints": joints}


def run_one(path: Path, budget: int, seed: int, out: Path, extra: list[str]) -> tuple[dict | None, str, float]:
    """Run the CLI's loop on one file: its JSON (None on failure), the failure's last stderr line, seconds."""
    cmd = [sys.executable, "-m", "suds_ros.cli", "optimize", "--simulate", str(path), "--budget-cycles",
           str(budget), "--seed", str(seed), "--limit", "yes", "--json", "-o", str(out), "--overwrite", *extra]
    t = time.perf_counter()
    try:
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=TIMEOUT_S, check=False)
    except subprocess.TimeoutExpired:
        return None, f"timed out after {TIMEOUT_S} s", time.perf_counter() - t
    secs = time.perf_counter() - t
    if proc.returncode != 0:
        last = (proc.stderr.strip().splitlines() or [f"exit code {proc.returncode}"])[-1]
        return None, f"rc {proc.returncode}: {last}", secs
    return json.loads(proc.stdout), "", secs


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--robots", type=int, default=8, help="random robots (default 8)")
    p.add_argument("--seed", type=int, default=20261202, help="the robot generator's seed")
    p.add_argument("--loop-seeds", type=int, nargs="+", default=[0],
                   help="the loop's seeds (its OU perturbation), one run of each robot per seed (default 0)")
    p.add_argument("--rotation-margin", type=float, default=None,
                   help="passed to the loop (`--rotation-margin`); writes optimize_sweep_margin<F>.md "
                        "(default: the loop's own, into optimize_sweep.md)")
    p.add_argument("--out", default=None, help="the report's file name in docs/results (default optimize_sweep.md, "
                   "or optimize_sweep_margin<F>.md with --rotation-margin)")
    args = p.parse_args()
    extra = [] if args.rotation_margin is None else ["--rotation-margin", f"{args.rotation_margin:g}"]
    rng = np.random.default_rng(args.seed)
    rows, pcts, gains, fails, in_basin = [], [], [], 0, 0
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.robots):  # each robot drawn once, then run once per loop seed
            doc = random_robot(rng, f"rand{i}")
            path = Path(tmp) / f"rand{i}.yaml"
            path.write_text(yaml.safe_dump(doc, sort_keys=False))
            joints = doc["joints"]
            n_links = len(doc["links"])  # type: ignore[arg-type]
            n_driven = sum(1 for j in joints if j.get("actuated"))  # type: ignore[union-attr]
            extras = sorted({k for j in joints for k in j if k in ("damping", "rest", "k3", "coulomb",  # type: ignore
                                                                   "limit", "speed_limit")})
            budget = 5 * n_links
            basin = optimize_gait(load_system(str(path)), OptimizeConfig(starts=1, screened=0)).value  # start's basin
            about = (f"{n_links} | {n_driven} of {n_links - 1} | {', '.join(extras) or '—'} | {doc['gait_hz']:g} | "
                     f"{budget} |")
            for loop_seed in args.loop_seeds:
                res, err, secs = run_one(path, budget, loop_seed, Path(tmp) / f"rand{i}_gait.yaml", extra)
                head = f"| rand{i} | {loop_seed} | {about}"
                if res is None:
                    fails += 1
                    rows.append(f"{head} error: {err} | | | | | | | {secs:.0f} |")
                    print(rows[-1], flush=True)
                    continue
                lim, sim = res["limit"], res["simulated"]
                m = res["measured_detail"]
                start_pct, ret_pct = 100 * sim["start"] / lim, 100 * sim["returned"] / lim
                pcts.append(ret_pct)
                in_basin += sim["returned"] >= 0.9 * basin
                gains.append(ret_pct - start_pct)
                pred = "—" if res["predicted"] is None else f"{res['predicted']:.4f}"
                if res["predicted_std"] is not None:
                    pred += f" ± {res['predicted_std']:.4f}"
                tp = m["translation_p"]
                test = "—" if tp is None else f"{tp:.3f}{' (warned)' if res['motion_warning'] else ''}"
                rows.append(f"{head} {res['cycles_used']} | {start_pct:.1f} | {100 * basin / lim:.1f} | "
                            f"{ret_pct:.1f} | "
                            f"{m['speed']:.4f} ± {m['speed_se']:.4f} | {pred} | {test} | {lim:.4f} | {secs:.0f} |")
                print(rows[-1], flush=True)
    done = len(pcts)
    reach = {q: sum(v >= q for v in pcts) for q in (90, 95)}
    runs = args.robots * len(args.loop_seeds)
    summary = (f"{done} of {runs} runs finished ({fails} errors); returned gait ≥ 90 % of the limit in "
               f"{reach[90]}, ≥ 95 % in {reach[95]}, ≥ 90 % of the start's basin in {in_basin}; summed over the runs "
               f"{sum(pcts):.1f} % of the limit; the "
               f"returned gait's change from the start, in per cent of the limit: {min(gains):+.1f} to "
               f"{max(gains):+.1f}." if done else "no run finished.")
    seeds = " ".join(str(s) for s in args.loop_seeds)
    flag = "" if args.rotation_margin is None else f" --rotation-margin {args.rotation_margin:g}"
    lines = ["# The loop on random model-file robots (5 cycles per link)", "",
             f"Measured {stamp()} on {machine()} by `benchmarks/optimize_sweep.py --robots {args.robots} --seed "
             f"{args.seed} --loop-seeds {seeds}{flag}` (one run at a time, each in its own process).", "",
             "Each robot is a seeded random `suds-robot/1` file (the generator is `random_robot` in the script): "
             "3–7 links, each joint driven with probability ½ (a travelling sine of random amplitude and lag), "
             "the rest springs, some with damping, rest angle, cubic term or dry friction; random per-link drag; "
             "the pose frame on a random link with an offset; range and speed limits on about half of the driven "
             "joints.  The command: `suds optimize --simulate FILE --budget-cycles 5×links --seed "
             f"SEED --limit yes --json{flag}`.  Per cent figures are the physics' (the loop never sees "
             "them): the start (nominal) gait's and the returned gait's speed over the limit the physics "
             "optimiser finds (order 3, 4 starts; and 2 more from a screen of 256 gaits since 2026-12-05).  'basin' "
             "is SLSQP on the physics from the start gait alone, the same settings: what a perfect local "
             "optimiser reaches from the start; the rest of the gap to the limit lies in another basin.  "
             "'measured' is the returned gait's speed ± se over its "
             "cycles, 'predicted' the model's prediction ± its sd over coefficient draws, 'p' the motion test "
             "(Hotelling's T² of its cycles' translations against zero; warned where p > 0.05).", "",
             "| robot | seed | links | driven | passive/limit keys | gait Hz | budget | cycles used | start % | "
             "basin % | returned % | measured m/s | predicted m/s | p | limit m/s | time s |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
             *rows, "", summary, ""]
    name = args.out or ("optimize_sweep.md" if args.rotation_margin is None
                        else f"optimize_sweep_margin{args.rotation_margin:g}.md")
    write(name, "\n".join(lines))


if __name__ == "__main__":
    main()
