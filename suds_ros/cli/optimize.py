"""``suds optimize``: the best gait of a robot under its joint bounds.

On its physics (``--physics``), from a recording (BAG), or by the offline run → fit → step loop on
a simulated robot (``--simulate``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from suds_ros.core.errors import SudsConfigError

if TYPE_CHECKING:  # the core is imported lazily at run time
    from suds_ros.core.optimize.loop import LoopIteration, Measurement
    from suds_ros.core.physics.gait import Gait

EPILOG = """\
examples:
  suds optimize --physics --system purcell3 -o p3_fast.yaml            # speed, order 3, 4 starts
  suds optimize run.mcap --system purcell3 -o p3_step.yaml              # one step from a recording
  suds optimize --physics --model robot.yaml --objective turn --order 2 -o turn.yaml --json
  suds simulate purcell3 --gait p3_fast.yaml -o fast.mcap                # run the gait it wrote
  suds optimize --simulate purcell3 --budget-cycles 30 --seed 0 -o p3_loop.yaml   # the offline loop
  suds optimize --simulate purcell3 --budget-cycles 60 --watch -o p3.yaml \
      --change '30:[{"name": "stiffness_to_drag_error", "scale": 3.0}]'           # a robot that changes

The objective is read at the passive periodic steady state (shared/spec/gait.md): speed (m/s)
at a net rotation ≤ 0.05 rad per cycle, turn (rad/s) at a speed ≥ the nominal gait's,
efficiency (m/J: distance per cycle / actuator work per cycle) at both (a speed floor is our
addition: distance and work both scale as the amplitude squared, so without one the best
efficiency is a gait that barely moves).  Every gait honours
|r_j| ≤ limit_j and |ṙ_j| ≤ speed_limit_j (the model file's `limit` / `speed_limit`, else the
nominal gait's range and largest speed) at the frequency of the nominal gait.  The gait file
written loads back with `suds simulate --gait`.  On the physics SLSQP runs from the nominal gait,
random gaits and the best distinct gaits of a screen (--screen candidates: travelling waves of
every lag and random gaits, all run to their steady state at once): a robot's gaits have many
local optima.

From a recording (BAG, no --physics): the SUDS model fitted to the whole recording predicts
each candidate gait's cycle (passive joints by the learned ṙ_p, the pose by the learned body
velocity on SE(2)), and one SLSQP step is taken inside the trust region the data supports:
|δ_a| and |δ̇_a| within --trust standard deviations of the recording's spread around its gait
template.  The predicted objective is reported with its spread over coefficient draws
(--draws).  The robot (--system/--model, or else the recording's own range and speed) gives
the joint bounds; with it the proposed and the recorded gait are also run on its physics (the
"simulated" values).  Efficiency needs a learned torque model: a recording with effort.

The loop (--simulate ROBOT, a built-in id or a model file): the robot is simulated with its
usual OU perturbation (seeded by --seed) and the optimiser sees only its recorded streams.  It
runs the start gait (--start, else the nominal gait), fits the SUDS model to the incumbent
gait's cycles, takes one trust-region step, runs the proposed gait (one settling cycle, then
--step-cycles measured cycles), and keeps it only if the *measured* objective is higher (and,
for speed and efficiency, the measured rotation ≤ 0.05 rad per cycle; for turn and efficiency, a
measured speed no lower than the start gait's, within a standard error); else it shrinks the
trust region.  For efficiency the simulated robot records its actuator effort, and a gait's work
per cycle is measured from the phase averages of the effort and the actuated angles.  It
stops when the next candidate would overrun --budget-cycles (every cycle run counts), when the
model predicts no gain, or when the trust region has shrunk below its floor, and writes the
best gait it measured.  The physics optimiser's limit is computed for comparison with
--limit yes (default auto: only for robots of at most 5 joints, where it takes seconds).
--change CYCLE:EFFECTS changes the simulated robot unannounced after CYCLE cycles (adaptation):
the loop notices it from its own measurements (an incumbent re-measured off its standing value
drops its old data); --watch keeps it re-measuring after convergence instead of stopping.  With
changes, the returned gait and the limit are judged on the robot as it is at the end.
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``optimize`` on the ``suds`` subcommand parser."""
    p = subparsers.add_parser("optimize", help="optimise a gait (suds-gait/1 file) on the physics",
                              epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("bag", nargs="?", default=None,
                   help="a recording (.mcap or rosbag2 directory): one data-driven step from its gait")
    p.add_argument("--physics", action="store_true", help="optimise on the model's physics (no BAG)")
    p.add_argument("--simulate", metavar="ROBOT",
                   help="run the offline loop on this simulated robot (built-in id or model file; no BAG)")
    p.add_argument("--budget-cycles", type=int, default=None, metavar="N",
                   help="--simulate: gait cycles the robot may run in all (required with --simulate)")
    p.add_argument("--step-cycles", type=int, default=4, metavar="N",
                   help="--simulate: measured cycles of each candidate gait, ≥ 4 (default 4)")
    p.add_argument("--watch", action="store_true",
                   help="--simulate: at convergence keep re-measuring the incumbent until the budget is spent")
    p.add_argument("--change", action="append", default=[], metavar="CYCLE:EFFECTS",
                   help="--simulate: the robot changes unannounced after CYCLE cycles to the nominal model with "
                        "EFFECTS (a JSON list of catalogue effects); repeatable")
    p.add_argument("--first-cycles", type=int, default=4, metavar="N",
                   help="--simulate: measured cycles of the start gait, ≥ 4 (default 4)")
    p.add_argument("--limit", choices=("auto", "yes", "no"), default="auto",
                   help="--simulate: also compute the physics optimiser's limit for comparison (auto: robots "
                        "of at most 5 joints)")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--model", metavar="FILE", help="robot model file (suds-robot/1)")
    src.add_argument("--system", metavar="ID", help="built-in system id (purcell3, swimmer9, nlinkN)")
    p.add_argument("--objective", choices=("speed", "turn", "efficiency"), default="speed",
                   help="what to maximise (default speed)")
    p.add_argument("--order", type=int, default=3, metavar="K", help="harmonics of the gait, 1..8 (default 3)")
    p.add_argument("--starts", type=int, default=4,
                   help="SLSQP starts: the nominal gait and random feasible gaits (default 4)")
    p.add_argument("--screen", type=int, default=256, metavar="N",
                   help="candidate gaits (travelling waves, random phases, random Fourier gaits) run to their "
                        "steady state to choose --screened more starts from (default 256; 0: no screen)")
    p.add_argument("--screened", type=int, default=2, metavar="M",
                   help="more SLSQP starts: the best distinct gaits of the screen (default 2)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random starts and the screen (default 0)")
    p.add_argument("--start", metavar="GAIT",
                   help="BAG: the gait that drove the recording (default: the bag's suds_gait record, else the "
                        "robot's nominal gait with --system/--model, else the recording's gait template); "
                        "--simulate: the gait the loop starts from (default: the nominal gait); --physics: one "
                        "more SLSQP start after the nominal gait (e.g. the gait optimised on the model file, when "
                        "optimising on the model `suds diagnose` corrected)")
    p.add_argument("--trust", type=float, default=2.0, metavar="KAPPA",
                   help="BAG: trust region in standard deviations of the data's δ spread (default 2); "
                        "--simulate: its initial radius, centred on the incumbent gait")
    p.add_argument("--half-wave", choices=("auto", "yes", "no"), default="auto",
                   help="steps move only the odd harmonics, so a half-wave symmetric gait (a travelling sine) stays "
                        "one and runs straight on a mirror-symmetric robot. auto: with --simulate from a half-wave "
                        "incumbent measured on course (speed, efficiency), never with BAG; yes: BAG too; no: never")
    p.add_argument("--scale-step", type=float, default=1.25, metavar="S",
                   help="--simulate: right after the start, a start whose oscillation can grow by S or more inside "
                        "the joint bounds is run scaled to them (speed, turn; default 1.25; inf: never)")
    p.add_argument("--reverse-trial", action=argparse.BooleanOptionalAction, default=True,
                   help="--simulate: once, after the (scaled) start, when the model of its cycles (or most of its "
                        "coefficient draws) predicts it better, run the incumbent backwards in time, the travelling "
                        "wave the other way, and go on from whichever measures better (the steps are local: they "
                        "do not turn a wave round; costs one run; default on)")
    p.add_argument("--pool-incumbents", type=int, default=0, metavar="N",
                   help="--simulate: also fit each step's model to the newest N stretches of the earlier incumbents "
                        "(default 0: the incumbent's and the rejected candidates' only)")
    p.add_argument("--rotation-margin", type=float, default=None, metavar="F",
                   help="--simulate: each step asks the model for a rotation within F times the straight-course "
                        "bound, in (0, 1] (default: LoopConfig.rotation_margin; the model's rotation errs by a few "
                        "hundredths of a radian per cycle)")
    p.add_argument("--rotation-from-model", action=argparse.BooleanOptionalAction, default=True,
                   help="--simulate: judge the straight-course bound (speed, efficiency) on the rotation of the SUDS "
                        "model fitted to each run's own cycles, at its steady state, where it fits; else on the "
                        "mean of the cycles (default on: the closer reading)")
    p.add_argument("--body-frame", choices=("shape", "pose"), default="shape",
                   help="the body frame the SUDS models are fitted in: 'shape', the recorded yaw turned by the "
                        "combination of joint angles it follows (default: the net motion a larger share of what "
                        "the model predicts on a robot whose pose frame swings with its shape), or 'pose', the "
                        "recorded frame as it is; the objectives are the same in both")
    p.add_argument("--draws", type=int, default=None, metavar="M",
                   help="coefficient draws for the predicted objective's uncertainty (default 16 with BAG, 0 "
                        "with --simulate: there the measurement judges each step)")
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

    if args.simulate is not None:
        return _loop(args)
    if args.budget_cycles is not None:
        raise SudsConfigError("--budget-cycles: only with --simulate ROBOT")
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
                             screen=args.screen, screened=args.screened, steps_per_cycle=args.steps)
    except SudsConfigError as exc:
        name = str(exc).split("`")[1] if str(exc).count("`") >= 2 else ""
        flag = {"steps_per_cycle": "steps"}.get(name, name)
        raise SudsConfigError(f"--{flag}: {exc}", code=exc.code) from None
    log = None if args.json else (lambda line: print(f"  {line}", file=sys.stderr))
    start = _given_start(args, system)
    res = optimize_gait(system, cfg, log=log, initial=[] if start is None else [start])
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
            "speed_over_time_origins": None if res.speed_over_origins is None else list(res.speed_over_origins),
            "limits": {"limit": list(res.limits.limit), "speed_limit": list(res.limits.speed_limit)}
            if res.limits is not None else None}))
    else:
        unit = {"speed": "m/s", "turn": "rad/s", "efficiency": "m/J"}[args.objective]
        again = sum(x["kind"] == "origin" for x in res.starts)  # ends re-optimised from a better time origin
        print(f"wrote {out}: {system.name}, {args.objective} {res.value:.6g} {unit} "
              f"(nominal gait {res.nominal_value:.6g}, {100 * gain:+.2f} %), order {args.order}, "
              f"{len(res.starts) - again} start(s)"
              + (f" and {again} re-optimised from a better time origin" if again else "")
              + f", {res.seconds:.1f} s")
        lo, hi = res.speed_over_origins or (0.0, 0.0)
        if hi > lo * (1 + 1e-3):
            print(f"  note: the gait turns ({res.values['rotation']:+.4f} rad/cycle), so its speed depends on where "
                  f"a cycle is counted from: {lo:.6g}–{hi:.6g} m/s over the cycle's start "
                  f"({res.values['speed']:.6g} from the gait's time zero"
                  + (", its best point)" if cfg.free_origin else ")"))
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
        cfg = DataOptimizeConfig(objective=args.objective, order=args.order, trust=args.trust,
                                 draws=16 if args.draws is None else args.draws, seed=args.seed,
                                 half_wave=args.half_wave == "yes")
    except SudsConfigError as exc:
        name = str(exc).split("`")[1] if str(exc).count("`") >= 2 else ""
        raise SudsConfigError(f"--{name.replace('_', '-')}: {exc}", code=exc.code) from None
    ns = argparse.Namespace(system=args.system, model=args.model, actuated=None, passive=None, gait_hz=None,
                            namespace="")
    rec, _ = load_recording_and_model(args.bag, ns)
    robot = args.model or args.system
    system = load_system(robot) if robot else None
    if args.objective == "efficiency" and rec.effort is None:
        raise SudsConfigError("--objective efficiency: no learned torque model: the recording has no effort on "
                              "/suds/shape (record it, e.g. `suds simulate --effort`); efficiency is unavailable "
                              "from this data", code="unsupported_objective")
    model = learn_model(rec, torque=args.objective == "efficiency", frame=args.body_frame)
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
            "passive_excursion": res.passive_excursion if model.passive else None,
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
    passive = (f"passive joints up to {res.passive_excursion:.2f} σ of the data's spread" if model.passive
               else "no passive joint (fully actuated)")
    print(f"  trust region used {res.trust_used:.2f} of {res.trust_radius:.3g} σ; {passive}")
    return 0


def _given_start(args: argparse.Namespace, system: object) -> Gait | None:
    """The ``--start`` gait file, loaded (against ``system`` when given), or None without ``--start``."""
    from suds_ros.core.physics.gait import load_gait

    if not args.start:
        return None
    if not Path(args.start).is_file():
        raise SudsConfigError(f"--start: no such file {args.start!r}")
    return load_gait(args.start, system)  # type: ignore[arg-type]


def _start_gait(args: argparse.Namespace, system: object) -> tuple[object, str]:
    """The gait that drove the recording and where it came from (None: the recording's template)."""
    from suds_ros.core.physics.gait import loads_gait, nominal_gait
    from suds_ros.io.mcap import read_metadata
    from suds_ros.io.recording_bag import GAIT_METADATA_NAME, META_GAIT_YAML

    given = _given_start(args, system)
    if given is not None:
        return given, f"--start {args.start}"
    bag = Path(args.bag)
    files = [bag] if bag.is_file() else sorted(bag.glob("*.mcap"))
    text = read_metadata(files[0]).get(GAIT_METADATA_NAME, {}).get(META_GAIT_YAML) if files else None
    if text:
        return loads_gait(text, f"{bag}: suds_gait"), "the bag's suds_gait record"
    if system is not None:
        return nominal_gait(system), "the robot's nominal gait"  # type: ignore[arg-type]
    return None, "the recording's gait template"


#: robots of at most this many joints get the physics limit with ``--limit auto`` (seconds, not minutes)
CHEAP_LIMIT_JOINTS = 5


def _loop(args: argparse.Namespace) -> int:
    """``suds optimize --simulate ROBOT``: the offline run → fit → step loop."""
    from suds_ros.core.json_text import dumps
    from suds_ros.core.optimize.loop import LoopConfig, motion_doubt, optimize_loop
    from suds_ros.core.optimize.physics import OptimizeConfig, evaluate_gait, optimize_gait
    from suds_ros.core.physics.gait import load_gait, save_gait
    from suds_ros.core.physics.systems import load_system

    if args.physics or args.bag:
        what = "--physics" if args.physics else f"BAG {args.bag!r}"
        raise SudsConfigError(f"--simulate and {what}: give one (the loop simulates its own robot)")
    if args.model or args.system:
        raise SudsConfigError("--simulate ROBOT names the robot; --model/--system are not taken with it")
    if args.budget_cycles is None:
        raise SudsConfigError("--budget-cycles: required with --simulate (gait cycles the robot may run)")
    out = _check_output(args)
    system = load_system(args.simulate)
    start = _given_start(args, system)
    changes = [_change(text) for text in args.change]
    try:
        cfg = LoopConfig(budget_cycles=args.budget_cycles, seed=args.seed, objective=args.objective,
                         order=args.order, trust=args.trust, draws=0 if args.draws is None else args.draws,
                         first_cycles=args.first_cycles, step_cycles=args.step_cycles, watch=args.watch,
                         half_wave=args.half_wave != "no", scale_step=args.scale_step,
                         reverse_trial=args.reverse_trial, rotation_from_model=args.rotation_from_model,
                         pool_incumbents=args.pool_incumbents, body_frame=args.body_frame,
                         **({} if args.rotation_margin is None else {"rotation_margin": args.rotation_margin}))
    except SudsConfigError as exc:
        name = str(exc).split("`")[1] if str(exc).count("`") >= 2 else ""
        raise SudsConfigError(f"--{name.replace('_', '-')}: {exc}", code=exc.code) from None
    key = args.objective
    unit = {"speed": "m/s", "turn": "rad/s", "efficiency": "m/J"}[key]

    def text_line(it: LoopIteration) -> None:
        print(_iteration_text(it, key), file=sys.stderr, flush=True)

    judge = _changed_robot(system, changes)  # the robot as it is at the end
    res = optimize_loop(system, cfg, start=start, log=None if args.json else text_line, changes=changes)
    save_gait(res.gait, out)
    load_gait(out, system)  # it loads back

    # judged afterwards on the physics (never seen by the loop)
    def true_value(g: object) -> float:
        v = evaluate_gait(judge, g)  # type: ignore[arg-type]
        return abs(v["turn"]) if key == "turn" else v[key]

    true_final, true_start = true_value(res.gait), true_value(res.iterations[0].gait)
    limit, limit_note = None, "skipped: --limit no"
    if args.limit == "yes" or (args.limit == "auto" and len(system.joint_names) <= CHEAP_LIMIT_JOINTS):
        limit_cfg = OptimizeConfig(objective=key, order=args.order, seed=args.seed)
        limit = optimize_gait(judge, limit_cfg).value
        limit_note = (f"the physics optimiser (order {args.order}, {limit_cfg.starts} starts and {limit_cfg.screened} "
                      f"from a screen of {limit_cfg.screen} gaits)")
    elif args.limit == "auto":
        limit_note = (f"skipped: {len(system.joint_names)} joints > {CHEAP_LIMIT_JOINTS} (minutes on 2 cores; "
                      "--limit yes computes it)")
    m = res.measured
    doubt = motion_doubt(m, key)
    if args.json:
        print(dumps({
            "objective": key, "gait": str(out), "system": system.name, "order": args.order, "seed": args.seed,
            "budget_cycles": args.budget_cycles, "cycles_used": res.cycles_used, "stopped": res.stopped,
            "changes": [{"cycle": c, "effects": e} for c, e in changes],
            "changes_taken": [res.iterations[i].cycles_used for i in res.changes],
            "predicted": res.predicted, "predicted_std": res.predicted_std, "measured": m.value(key),
            "measured_detail": _measurement(m), "motion_warning": doubt,
            "simulated": {"returned": true_final, "start": true_start},
            "limit": limit, "limit_note": limit_note,
            "percent_of_limit": None if not limit else 100 * true_final / limit,
            "iterations": [{"index": it.index, "cycles": it.cycles, "cycles_used": it.cycles_used,
                            "predicted": it.predicted, "predicted_std": it.predicted_std,
                            "predicted_incumbent": it.predicted_incumbent, "measured": it.measured.value(key),
                            "measured_detail": _measurement(it.measured), "accepted": it.accepted,
                            "trust": it.trust, "trust_used": it.trust_used, "note": it.note}
                           for it in res.iterations],
            "time": res.seconds,
            "limits": {"limit": list(res.limits.limit), "speed_limit": list(res.limits.speed_limit)}}))
        return 0
    pred = "n/a" if res.predicted is None else f"{res.predicted:.5g}"
    spread = ""
    if res.predicted_std is not None:  # (only a model's prediction has one)
        pred += f" ± {res.predicted_std:.2g}"
        spread = " (± the sd over the model's coefficient draws)"
    print(f"wrote {out}: {system.name}, {key} after {res.cycles_used} of {args.budget_cycles} cycles "
          f"({len(res.iterations)} gaits run), {res.seconds:.1f} s; {res.stopped}")
    print(f"  returned gait (run {res.index}): measured {m.value(key):.5g} {unit} (rotation "
          f"{m.rotation:+.3f} rad/cycle), predicted {pred} {unit}{spread}")
    if doubt:
        print(f"  warning: {doubt}")
    lim = "" if not limit else f", {100 * true_final / limit:.1f} % of the limit {limit:.5g} {unit}"
    print(f"  on the physics (not seen by the loop): {true_final:.5g} {unit}, start gait {true_start:.5g} "
          f"{unit}{lim}")
    if not limit:
        print(f"  physics limit {limit_note}")
    return 0


def _change(text: str) -> tuple[int, list[dict[str, object]]]:
    """Parse ``--change CYCLE:EFFECTS`` (EFFECTS a JSON list of catalogue effects)."""
    import json

    cycle, sep, effects = text.partition(":")
    try:
        n = int(cycle)
        doc = json.loads(effects)
        if not sep or n < 0 or not isinstance(doc, list) or not all(isinstance(e, dict) for e in doc):
            raise ValueError
    except ValueError:
        raise SudsConfigError(f"--change: expected CYCLE:[{{effect}}, ...] with CYCLE ≥ 0 and a JSON list of "
                              f"effects, got {text!r}") from None
    return n, doc


def _changed_robot(system: object, changes: list[tuple[int, list[dict[str, object]]]]) -> object:
    """The robot after the last change (each change checked against it first), or ``system`` without changes."""
    from suds_ros.core.physics.effects import apply_effects
    from suds_ros.core.physics.rft import ChainModel, RFTChain

    if not changes:
        return system
    model = getattr(system, "model", None)
    if not isinstance(model, ChainModel):
        raise SudsConfigError(f"--change: only RFT chain robots take effects, got {getattr(system, 'name', system)!r}")
    for _, effects in changes:
        try:
            changed, delay = apply_effects(model, effects)
        except SudsConfigError as exc:
            raise SudsConfigError(f"--change: {exc}", code=exc.code) from None
        if delay:
            raise SudsConfigError("--change: sensor_time_offset cannot change a running robot")
    return RFTChain(changed) if changes[-1][1] else system


def _measurement(m: Measurement) -> dict[str, object]:
    out: dict[str, object] = {"speed": m.speed, "speed_se": m.speed_se, "rotation": m.rotation,
                              "rotation_se": m.rotation_se, "turn": m.turn, "cycles": m.cycles,
                              "translation_p": m.translation_p}
    if m.model_rotation is not None:  # the rotation the straight-course bound was judged on
        out.update(model_rotation=m.model_rotation, model_rotation_se=m.model_rotation_se)
    if m.work is not None:  # measured from the recorded effort (objective efficiency)
        out.update(work=m.work, efficiency=m.efficiency, efficiency_se=m.efficiency_se)
    return out


def _iteration_text(it: LoopIteration, key: str) -> str:
    pred = "—" if it.predicted is None else f"{it.predicted:.5g}"
    m = it.measured
    return (f"  [{it.index}] cycles {it.cycles_used:3d}  predicted {pred}  measured {m.value(key):.5g} "
            f"(rotation {m.rotation:+.3f})  {it.note}")
