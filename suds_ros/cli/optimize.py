"""``suds optimize``: the best gait of a robot under its joint bounds, on its physics or from a recording (BAG)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from suds_ros.core.errors import SudsConfigError

EPILOG = """\
examples:
  suds optimize --physics --system purcell3 -o p3_fast.yaml            # speed, order 3, 4 starts
  suds optimize run.mcap --system purcell3 -o p3_step.yaml              # one step from a recording
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

From a recording (BAG, no --physics): the SUDS model fitted to the whole recording predicts
each candidate gait's cycle (passive joints by the learned ṙ_p, the pose by the learned body
velocity on SE(2)), and one SLSQP step is taken inside the trust region the data supports:
|δ_a| and |δ̇_a| within --trust standard deviations of the recording's spread around its gait
template.  The predicted objective is reported with its spread over coefficient draws
(--draws).  The robot (--system/--model, or else the recording's own range and speed) gives
the joint bounds; with it the proposed and the recorded gait are also run on its physics (the
"simulated" values).  Efficiency needs a learned torque model: a recording with effort.
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``optimize`` on the ``suds`` subcommand parser."""
    p = subparsers.add_parser("optimize", help="optimise a gait (suds-gait/1 file) on the physics",
                              epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("bag", nargs="?", default=None,
                   help="a recording (.mcap or rosbag2 directory): one data-driven step from its gait")
    p.add_argument("--physics", action="store_true", help="optimise on the model's physics (no BAG)")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--model", metavar="FILE", help="robot model file (suds-robot/1)")
    src.add_argument("--system", metavar="ID", help="built-in system id (purcell3, swimmer9, nlinkN)")
    p.add_argument("--objective", choices=("speed", "turn", "efficiency"), default="speed",
                   help="what to maximise (default speed)")
    p.add_argument("--order", type=int, default=3, metavar="K", help="harmonics of the gait, 1..8 (default 3)")
    p.add_argument("--starts", type=int, default=4,
                   help="SLSQP starts: the nominal gait and random feasible gaits (default 4)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random starts (default 0)")
    p.add_argument("--start", metavar="GAIT",
                   help="BAG: the gait that drove the recording (default: the bag's suds_gait record, else the "
                        "robot's nominal gait with --system/--model, else the recording's gait template)")
    p.add_argument("--trust", type=float, default=2.0, metavar="KAPPA",
                   help="BAG: trust region in standard deviations of the data's δ spread (default 2)")
    p.add_argument("--draws", type=int, default=16, metavar="M",
                   help="BAG: coefficient draws for the predicted objective's uncertainty (default 16)")
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

    if args.physics and args.bag:
        raise SudsConfigError(f"--physics and BAG {args.bag!r}: give one (the physics, or a recording to learn from)")
    if not args.physics and not args.bag:
        raise SudsConfigError("nothing to optimise on: give --physics (with --model/--system) or a recording BAG")
    if not args.physics:
        return _from_data(args)
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


def _check_output(args: argparse.Namespace) -> Path:
    out = Path(args.output)
    if out.exists() and not args.overwrite:
        raise SudsConfigError(f"output {str(out)!r} exists; pass --overwrite to replace it")
    if not out.parent.is_dir():
        raise SudsConfigError(f"-o: directory {str(out.parent)!r} does not exist")
    return out


def _from_data(args: argparse.Namespace) -> int:
    """``suds optimize BAG``: one trust-region step on the SUDS model of the recording."""
    from suds_ros.cli.common import load_recording_and_model
    from suds_ros.core.json_text import dumps
    from suds_ros.core.optimize.data import DataOptimizeConfig, learn_model, optimize_from_data
    from suds_ros.core.optimize.physics import evaluate_gait
    from suds_ros.core.physics.gait import check_constraints, gait_limits, load_gait, save_gait
    from suds_ros.core.physics.systems import load_system

    if args.model and not Path(args.model).is_file():
        raise SudsConfigError(f"--model: no such file {args.model!r}")
    out = _check_output(args)
    try:
        cfg = DataOptimizeConfig(objective=args.objective, order=args.order, trust=args.trust, draws=args.draws,
                                 seed=args.seed)
    except SudsConfigError as exc:
        name = str(exc).split("`")[1] if str(exc).count("`") >= 2 else ""
        raise SudsConfigError(f"--{name}: {exc}", code=exc.code) from None
    ns = argparse.Namespace(system=args.system, model=args.model, actuated=None, passive=None, gait_hz=None,
                            namespace="")
    rec, _ = load_recording_and_model(args.bag, ns)
    robot = args.model or args.system
    system = load_system(robot) if robot else None
    if args.objective == "efficiency" and rec.effort is None:
        raise SudsConfigError("--objective efficiency: no learned torque model: the recording has no effort on "
                              "/suds/shape (record it, e.g. `suds simulate --effort`); efficiency is unavailable "
                              "from this data", code="unsupported_objective")
    model = learn_model(rec, torque=args.objective == "efficiency")
    limits = gait_limits(system) if system is not None else None
    start, start_from = _start_gait(args, system)
    res = optimize_from_data(model, cfg, limits=limits, start=start)
    check_constraints(res.gait, res.limits)
    save_gait(res.gait, out)
    load_gait(out, system)  # it loads back (and is a gait of the robot)
    key = args.objective
    simulated = None
    if system is not None:
        def true_value(g: object) -> float:
            v = evaluate_gait(system, g)  # type: ignore[arg-type]
            return abs(v["turn"]) if key == "turn" else v[key]

        simulated = {"proposed": true_value(res.gait), "recorded": true_value(res.recorded)}
    if args.json:
        print(dumps({
            "objective": key, "gait": str(out), "system": rec.system, "order": args.order,
            "cycles_used": model.cycles, "step_taken": res.step_taken, "start": start_from,
            "predicted": {"proposed": res.value, "proposed_std": res.value_std, "recorded": res.recorded_value,
                          "recorded_std": res.recorded_std, "gain": res.value - res.recorded_value,
                          "gain_std": res.gain_std},
            "simulated": simulated, "values": res.values, "recorded_values": res.recorded_values,
            "trust": args.trust, "trust_radius": res.trust_radius, "trust_used": res.trust_used,
            "passive_excursion": res.passive_excursion,
            "message": res.message, "time": res.seconds,
            "limits": {"limit": list(res.limits.limit), "speed_limit": list(res.limits.speed_limit)}}))
        return 0
    unit = {"speed": "m/s", "turn": "rad/s", "efficiency": "m/J"}[key]

    def pm(v: float, s: float | None) -> str:
        return f"{v:.5g}" + ("" if s is None else f" ± {s:.2g}")

    print(f"wrote {out}: {rec.system}, {key} from {model.cycles:.1f} recorded cycles "
          f"({'step taken' if res.step_taken else 'no step: the recorded gait'}), {res.seconds:.1f} s; "
          f"recorded gait: {start_from}")
    print(f"  predicted {key}: proposed {pm(res.value, res.value_std)} {unit}, recorded "
          f"{pm(res.recorded_value, res.recorded_std)} {unit}, gain {pm(res.value - res.recorded_value, res.gain_std)}")
    if simulated is not None:
        gain = simulated["proposed"] / simulated["recorded"] - 1.0 if simulated["recorded"] else float("nan")
        name = system.name  # type: ignore[union-attr]
        print(f"  simulated {key} on {name}: proposed {simulated['proposed']:.5g} {unit}, "
              f"recorded {simulated['recorded']:.5g} {unit} ({100 * gain:+.2f} %)")
    print(f"  trust region used {res.trust_used:.2f} of {res.trust_radius:.3g} σ; passive joints up to "
          f"{res.passive_excursion:.2f} σ of the data's spread")
    return 0


def _start_gait(args: argparse.Namespace, system: object) -> tuple[object, str]:
    """The gait that drove the recording and where it came from (None: the recording's template)."""
    from suds_ros.core.physics.gait import loads_gait, load_gait, nominal_gait
    from suds_ros.io.mcap import read_metadata
    from suds_ros.io.recording_bag import GAIT_METADATA_NAME, META_GAIT_YAML

    if args.start:
        if not Path(args.start).is_file():
            raise SudsConfigError(f"--start: no such file {args.start!r}")
        return load_gait(args.start, system), f"--start {args.start}"  # type: ignore[arg-type]
    bag = Path(args.bag)
    files = [bag] if bag.is_file() else sorted(bag.glob("*.mcap"))
    text = read_metadata(files[0]).get(GAIT_METADATA_NAME, {}).get(META_GAIT_YAML) if files else None
    if text:
        return loads_gait(text, f"{bag}: suds_gait"), "the bag's suds_gait record"
    if system is not None:
        return nominal_gait(system), "the robot's nominal gait"  # type: ignore[arg-type]
    return None, "the recording's gait template"
