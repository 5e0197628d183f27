"""`suds optimize --physics` on robots nobody tuned it on: random model files, against a wider multi-start.

``python benchmarks/optimize_physics_random.py [--robots N] [--seed S] [--out NAME]`` draws N seeded random
``suds-robot/1`` files (``optimize_sweep.random_robot``: 3–7 links, random driven/passive split, springs
with damping, rest, k3 and dry friction, per-link drag, limits on some joints) and optimises each one's
speed (order 3) five ways:

* ours: the default, SLSQP from the nominal gait and 3 random feasible gaits, then from the 2 best
  distinct gaits of a screen of 256 run to their steady state in one batch, seeds 0 and 1;
* ours without the screen (``screen=0``): the nominal gait and the same 3 random feasible starts,
  the default before 2026-12-05, seeds 0 and 1;
* the check: the same SLSQP from the nominal gait and 12 random feasible starts (seed 2), a wider
  generic multi-start that shares nothing with the screen.

It writes ``docs/results/optimize_physics_random.md``: per robot each one's speed as per cent of the best
of the best of them all, and its time.  The issue's target is ours within 1 % of a multi-start generic optimiser.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml
from _common import machine, stamp, write
from optimize_sweep import random_robot

from suds_ros.core.optimize.physics import OptimizeConfig, optimize_gait
from suds_ros.core.physics.systems import load_system

#: the ways, by column
WAYS = (("ours, seed 0", OptimizeConfig()), ("ours, seed 1", OptimizeConfig(seed=1)),
        ("no screen, seed 0", OptimizeConfig(screen=0)), ("no screen, seed 1", OptimizeConfig(screen=0, seed=1)),
        ("check (13 starts, seed 2)", OptimizeConfig(screen=0, starts=13, seed=2)))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--robots", type=int, default=16, help="random robots (default 16)")
    p.add_argument("--seed", type=int, default=7, help="the robot generator's seed (default 7)")
    p.add_argument("--out", default="optimize_physics_random.md", help="the report's file name in docs/results")
    args = p.parse_args()
    rng = np.random.default_rng(args.seed)
    rows, within, shares = [], [0] * len(WAYS), [[] for _ in WAYS]
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.robots):
            doc = random_robot(rng, f"rand{i}")
            path = Path(tmp) / f"rand{i}.yaml"
            path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
            system = load_system(str(path))
            values, secs = [], []
            for _, cfg in WAYS:
                t = time.perf_counter()
                values.append(optimize_gait(system, cfg).value)
                secs.append(time.perf_counter() - t)
            best = max(values)
            pct = [100 * v / best for v in values]
            for k, q in enumerate(pct):
                within[k] += q >= 99.0
                shares[k].append(q)
            links = len(doc["links"])  # type: ignore[arg-type]
            driven = sum("gait" in j for j in doc["joints"])  # type: ignore[union-attr]
            rows.append(f"| rand{i} | {links} | {driven} of {links - 1} | {best:.5f} | "
                        + " | ".join(f"{q:.1f}" for q in pct) + " | " + " / ".join(f"{s:.0f}" for s in secs) + " |")
            print(rows[-1], flush=True)
    n = args.robots
    head = " | ".join(name for name, _ in WAYS)
    summary = "; ".join(f"{name}: within 1 % of the best in {within[k]} of {n} (lowest {min(shares[k]):.1f} %, "
                        f"mean {np.mean(shares[k]):.1f} %)" for k, (name, _) in enumerate(WAYS))
    text = "\n".join([
        "# `suds optimize --physics` on random model-file robots", "",
        f"Measured {stamp()} on {machine()} by `benchmarks/optimize_physics_random.py --robots {n} --seed "
        f"{args.seed} --out {args.out}` (one process; the machine shared with other work, so times are rough).", "",
        "Each robot is a seeded random `suds-robot/1` file (`random_robot` in `benchmarks/optimize_sweep.py`).  "
        "Speed, order 3, the rotation bound 0.05 rad/cycle, the time origin free, each way's speed as per cent "
        "of the best of them all.  'ours' is the default: SLSQP from the nominal gait and 3 random feasible "
        "gaits, then from the 2 best distinct gaits of a screen of 256 candidates (travelling waves of every "
        "lag and first harmonics of random phase at the largest amplitude the bounds allow, random Fourier "
        "gaits, all run to their steady state in one batch).  'no screen' is the default before 2026-12-05, "
        "the same nominal and random starts without the screened ones.  "
        "'check' is a wider generic multi-start, the same SLSQP from the nominal gait and 12 random "
        "feasible starts (seed 2), sharing nothing with the screen.", "",
        f"| robot | links | driven | best m/s | {head} | time s (same order) |",
        "|---|---|---|---|" + "---|" * len(WAYS) + "---|",
        *rows, "", summary + ".", ""])
    print(write(args.out, text))


if __name__ == "__main__":
    main()
