"""Randomised check of ``suds diagnose`` on recordings like the held-back ones (seeded).

Each case draws a system (purcell3 or swimmer9), one catalogue effect, a passive joint
for joint effects and a magnitude from the ranges below (the public recordings' effects
sit in the same ranges), simulates 60 cycles with a fresh seed (as the public bags), and
diagnoses it with the nominal model.  A case passes when the top effect has the injected
name and target, every parameter is within 25 % (flows: within 25 % of |U|), and the
held-out residual falls by at least 50 %; null cases pass when no mismatch is reported.

Usage: PYTHONPATH=. .venv/bin/python benchmarks/diagnose_sweep.py [--cases 16] [--seed 0]
Writes docs/results/diagnose_sweep.md.
"""

from __future__ import annotations

import argparse
import platform
import time
from pathlib import Path

import numpy as np

from suds_ros.core.diagnosis import diagnose
from suds_ros.core.physics.effects import EFFECTS, apply_effects
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import purcell3_model, swimmer9_model

MODELS = {"purcell3": purcell3_model, "swimmer9": swimmer9_model}
PASSIVE = {"purcell3": ["joint_2"], "swimmer9": ["joint_5", "joint_6", "joint_7", "joint_8"]}


def draw_effect(rng: np.random.Generator, system: str) -> dict:
    """One effect with a magnitude of the size a robot/simulator mismatch has."""
    catalogue = [n for n, spec in EFFECTS.items() if spec.kind == "catalogue" and n != "joint_stiffness_error"]
    name = str(rng.choice(catalogue + ["null"]))
    sign = float(rng.choice([-1.0, 1.0]))
    joint = str(rng.choice(PASSIVE[system]))
    if name == "null":
        return {}
    if name == "joint_coulomb_friction":
        return dict(name=name, joint=joint, mu=float(rng.uniform(0.3, 0.9)))
    if name == "joint_viscous_damping":
        return dict(name=name, joint=joint, d=float(rng.uniform(0.1, 0.5)))
    if name == "spring_rest_offset":
        return dict(name=name, joint=joint, offset=sign * float(rng.uniform(0.1, 0.3)))
    if name == "spring_nonlinearity":
        return dict(name=name, joint=joint, k3=sign * float(rng.uniform(1.0, 4.0)))
    if name == "stiffness_to_drag_error":
        return dict(name=name, scale=float(rng.choice([rng.uniform(0.6, 0.8), rng.uniform(1.25, 1.6)])))
    if name == "drag_anisotropy_error":
        return dict(name=name, ratio=float(rng.choice([rng.uniform(1.4, 1.75), rng.uniform(2.3, 3.0)])))
    if name == "background_flow":
        ang, speed = rng.uniform(0, 2 * np.pi), rng.uniform(0.04, 0.15)
        return dict(name=name, vx=float(speed * np.cos(ang)), vy=float(speed * np.sin(ang)))
    if name == "sensor_time_offset":
        return dict(name=name, dt=0.01 * int(rng.integers(1, 6)))
    raise AssertionError(name)


def judge(effect: dict, rep) -> tuple[bool, str]:  # type: ignore[no-untyped-def]
    if not effect:
        return (not rep.mismatch), ("no mismatch" if not rep.mismatch else
                                    f"false alarm: {[e.name for e in rep.effects]}")
    if not rep.mismatch:
        return False, "missed (no mismatch reported)"
    if rep.unexplained or not rep.effects:
        return False, "reported as unexplained"
    top = rep.effects[0]
    params = {k: v for k, v in effect.items() if k not in ("name", "joint")}
    got = ", ".join(f"{k}={v:.4g}" for k, v in top.parameters.items())
    text = f"{top.name} {top.target or ''} {got}; improvement {rep.improvement:.2f}"
    if top.name != effect["name"] or (effect.get("joint") and top.target != effect["joint"]):
        confounded = any(effect["name"] in group for group in rep.confounded_with)
        return False, text + (" (confounded, said so)" if confounded else "")
    if effect["name"] == "background_flow":
        err = np.hypot(top.parameters["vx"] - params["vx"], top.parameters["vy"] - params["vy"])
        ok_p = err <= 0.25 * np.hypot(params["vx"], params["vy"])
    else:
        ok_p = all(abs(top.parameters[k] - v) <= 0.25 * abs(v) for k, v in params.items())
    return bool(ok_p and rep.improvement >= 0.5), text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=16)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cycles", type=int, default=60)
    ap.add_argument("--out", default="docs/results/diagnose_sweep.md")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    rows, passed = [], 0
    for i in range(args.cases):
        system = ["purcell3", "swimmer9"][i % 2]
        effect = draw_effect(rng, system)
        sim_seed = int(rng.integers(100, 10_000))
        model, delay = apply_effects(MODELS[system](), [effect] if effect else [])
        rec = simulate(RFTChain(model), SimConfig(cycles=args.cycles, seed=sim_seed, pose_delay=delay))
        t0 = time.perf_counter()
        rep = diagnose(rec, MODELS[system]())
        wall = time.perf_counter() - t0
        ok, text = judge(effect, rep)
        passed += ok
        injected = "none" if not effect else " ".join(
            f"{k}={v:.4g}" if isinstance(v, float) else str(v) for k, v in effect.items())
        rows.append(f"| {i} | {system} | {sim_seed} | {injected} | {text} | {'yes' if ok else 'NO'} | {wall:.1f} |")
        print(rows[-1], flush=True)
    lines = [
        "# Randomised diagnosis sweep",
        "",
        f"Generated by `benchmarks/diagnose_sweep.py --cases {args.cases} --seed {args.seed}` "
        f"({args.cycles} cycles per recording) on {platform.machine()}, Python {platform.python_version()}, "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}.  Pass: right effect and target, "
        "parameters within 25 %, held-out improvement ≥ 0.5 (null: no mismatch reported).",
        "",
        f"**{passed} of {args.cases} cases pass.**",
        "",
        "| case | system | sim seed | injected | diagnosed (top effect) | pass | wall (s) |",
        "|---|---|---|---|---|---|---|",
        *rows,
        "",
    ]
    Path(args.out).write_text("\n".join(lines))
    print(f"{passed}/{args.cases} passed; wrote {args.out}")


if __name__ == "__main__":
    main()
