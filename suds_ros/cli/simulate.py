"""``suds simulate``: simulate a system and write its recording as an MCAP bag."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

from suds_ros.cli.common import progress_bar
from suds_ros.core.errors import SudsConfigError

EPILOG = """\
examples:
  suds simulate purcell3 -o purcell3.mcap                 # 60 cycles, seed 0, noise 1e-3
  suds simulate swimmer9 -o s9.mcap --cycles 30 --seed 4 --effect spring_rest_offset:joint_6:offset=0.25
  suds simulate nlink15 -o n15.mcap --noise 0             # a 15-link chain, noise free

The drive is r_a = r_ref(t) + η(t), η an Ornstein–Uhlenbeck process
(dη = −κη dt + σ dW, σ = ou_std·√(2κ)), linearly interpolated between samples.
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``simulate`` on the ``suds`` subcommand parser."""
    p = subparsers.add_parser("simulate", help="simulate a system and write an MCAP recording",
                              epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("system", help="purcell3, swimmer9, linear_passive, pushmepullyou or nlinkN")
    p.add_argument("-o", "--output", required=True,
                   help="output .mcap (never overwritten without --overwrite)")
    p.add_argument("--cycles", type=int, default=60, help="gait cycles to record (default 60)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--noise", type=float, default=1e-3,
                   help="measurement noise std, rad and m (default 1e-3)")
    p.add_argument("--ou-std", type=float, default=0.175,
                   help="stationary std of the OU drive perturbation, rad")
    p.add_argument("--kappa", type=float, default=8.0, help="OU attraction rate κ, 1/s (default 8)")
    p.add_argument("--gait-hz", type=float, default=1.0, help="gait frequency, Hz (default 1)")
    p.add_argument("--substeps", type=int, default=None,
                   help="RK4 steps per sample (default: from the stiffest passive mode)")
    p.add_argument("--effect", action="append", metavar="NAME[:JOINT][:P=V,...]",
                   help="inject a physical effect (repeatable), e.g. "
                        "joint_coulomb_friction:joint_2:mu=0.7")
    p.add_argument("--effort", action="store_true", help="record actuator effort on /suds/shape")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    p.set_defaults(func=run)


def parse_effect(text: str) -> dict[str, object]:
    """``name[:target][:p=v[,p=v]]`` → effect dict (``name``, ``joint``, parameters)."""
    parts = text.split(":")
    out: dict[str, object] = {"name": parts[0]}
    for part in parts[1:]:
        if "=" in part:
            for kv in part.split(","):
                k, _, v = kv.partition("=")
                try:
                    out[k.strip()] = float(v)
                except ValueError:
                    raise SudsConfigError(f"--effect {text!r}: parameter {k!r} needs a number, "
                                          f"got {v!r}") from None
        elif part:
            out["joint"] = part
    return out


def run(args: argparse.Namespace) -> int:
    """Execute ``suds simulate``; returns the exit code."""
    from suds_ros.core.physics.sim import SimConfig, simulate
    from suds_ros.core.physics.systems import make_system
    from suds_ros.io.recording_bag import write_recording

    out = Path(args.output)
    if out.exists() and not args.overwrite:
        raise SudsConfigError(f"output {str(out)!r} exists; pass --overwrite to replace it")
    system = make_system(args.system)
    pose_delay = 0.0
    if args.effect:
        from suds_ros.core.physics.effects import apply_effects

        model, pose_delay = apply_effects(system.model,  # type: ignore[attr-defined]
                                          [parse_effect(e) for e in args.effect])
        system = type(system)(model)  # type: ignore[call-arg]
    cfg = SimConfig(cycles=args.cycles, seed=args.seed, noise_std=args.noise, ou_std=args.ou_std,
                    kappa=args.kappa, substeps=args.substeps, gait_hz=args.gait_hz,
                    pose_delay=pose_delay)
    rec = simulate(system, cfg, progress=progress_bar(f"simulating {args.system}"))
    if args.effort:
        eff = np.zeros_like(rec.r)
        eff[:, rec.actuated_index] = rec.truth["effort"]
        rec = replace(rec, effort=eff)
    write_recording(out, rec, overwrite=args.overwrite)
    print(f"wrote {out}: {args.system}, {args.cycles} cycles, {rec.n_samples} samples, "
          f"seed {args.seed}")
    return 0
