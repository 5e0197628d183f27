"""``suds optimize --physics``: the best gait of a robot under its joint bounds, on its physics."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from suds_ros.core.errors import SudsConfigError

EPILOG = """\
examples:
  suds optimize --physics --system purcell3 -o p3_fast.yaml            # speed, order 3, 4 starts
  suds optimize --physics --model robot.yaml --objective turn --order 2 -o turn.yaml --json
  suds simulate purcell3 --gait p3_fast.yaml -o fast.mcap                # run the gait it wrote

The objective is read at the passive periodic steady state (shared/spec/gait.md): speed (m/s)
at a net rotation ≤ 0.05 rad per cycle, turn (rad/s) at a speed ≥ the nominal gait's,
efficiency (m/J: distance per cycle / actuator work per cycle) at both (a speed floor is our
addition: distance and work both scale as the amplitude squared, so without one the best
efficiency is a gait that barely moves).  Every gait honours
|r_j| ≤ limit_j and |ṙ_j| ≤ speed_limit_j (the model file's `limit` / `speed_limit`, else the
nominal gait's range and largest speed) at the frequency of the nominal gait.  The gait file
written loads back with `suds simulate --gait`.
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``optimize`` on the ``suds`` subcommand parser."""
    p = subparsers.add_parser("optimize", help="optimise a gait (suds-gait/1 file) on the physics",
                              epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--physics", action="store_true",
                   help="optimise on the model's physics (the only method so far; required)")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--model", metavar="FILE", help="robot model file (suds-robot/1)")
    src.add_argument("--system", metavar="ID", help="built-in system id (purcell3, swimmer9, nlinkN)")
    p.add_argument("--objective", choices=("speed", "turn", "efficiency"), default="speed",
                   help="what to maximise (default speed)")
    p.add_argument("--order", type=int, default=3, metavar="K", help="harmonics of the gait, 1..8 (default 3)")
    p.add_argument("--starts", type=int, default=4,
                   help="SLSQP starts: the nominal gait and random feasible gaits (default 4)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random starts (default 0)")
    p.add_argument("--steps", type=int, default=None, metavar="N",
                   help="RK4 steps per cycle (default: from the stiffest passive joint, ≥ 64)")
    p.add_argument("-o", "--output", required=True, help="gait file to write (suds-gait/1 YAML)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute ``suds optimize``; returns the exit code."""
    from suds_ros.core.json_text import dumps
    from suds_ros.core.optimize.physics import OptimizeConfig, optimize_gait
    from suds_ros.core.physics.gait import check_constraints, load_gait, save_gait
    from suds_ros.core.physics.systems import load_system

    if not args.physics:
        raise SudsConfigError("--physics: required (the model-based optimiser is the only one so far)")
    if not (args.model or args.system):
        raise SudsConfigError("no robot: give --model FILE or --system ID")
    if args.model and not Path(args.model).is_file():
        raise SudsConfigError(f"--model: no such file {args.model!r}")
    out = Path(args.output)
    if out.exists() and not args.overwrite:
        raise SudsConfigError(f"output {str(out)!r} exists; pass --overwrite to replace it")
    if not out.parent.is_dir():
        raise SudsConfigError(f"-o: directory {str(out.parent)!r} does not exist")
    system = load_system(args.model or args.system)
    try:
        cfg = OptimizeConfig(objective=args.objective, order=args.order, starts=args.starts, seed=args.seed,
                             steps_per_cycle=args.steps)
    except SudsConfigError as exc:
        name = str(exc).split("`")[1] if str(exc).count("`") >= 2 else ""
        flag = {"steps_per_cycle": "steps"}.get(name, name)
        raise SudsConfigError(f"--{flag}: {exc}", code=exc.code) from None
    log = None if args.json else (lambda line: print(f"  {line}", file=sys.stderr))
    res = optimize_gait(system, cfg, log=log)
    check_constraints(res.gait, res.limits)  # type: ignore[arg-type]
    save_gait(res.gait, out)
    load_gait(out, system)  # it loads back
    gain = res.value / res.nominal_value - 1.0 if res.nominal_value else float("nan")
    if args.json:
        print(dumps({
            "objective": args.objective, "value": res.value, "nominal_value": res.nominal_value,
            "gain": gain, "gait": str(out), "system": system.name, "order": args.order,
            "values": res.values, "nominal_values": res.nominal_values, "starts": res.starts,
            "time": res.seconds, "cycles": res.cycles,
            "limits": {"limit": list(res.limits.limit), "speed_limit": list(res.limits.speed_limit)}
            if res.limits is not None else None}))
    else:
        unit = {"speed": "m/s", "turn": "rad/s", "efficiency": "m/J"}[args.objective]
        print(f"wrote {out}: {system.name}, {args.objective} {res.value:.6g} {unit} "
              f"(nominal gait {res.nominal_value:.6g}, {100 * gain:+.2f} %), order {args.order}, "
              f"{len(res.starts)} starts, {res.seconds:.1f} s")
    return 0
