"""``suds simulate``: simulate a system and write its recording as an MCAP bag."""

from __future__ import annotations

import argparse
from pathlib import Path

from suds_ros.cli.common import progress_bar
from suds_ros.core.errors import SudsConfigError

EPILOG = """\
examples:
  suds simulate purcell3 -o purcell3.mcap                 # 60 cycles, seed 0, noise 1e-3
  suds simulate swimmer9 -o s9.mcap --cycles 30 --seed 4 --effect spring_rest_offset:joint_6:offset=0.25
  suds simulate nlink15 -o n15.mcap --noise 0             # a 15-link chain, noise free
  suds simulate --model robot.yaml -o robot.mcap           # your own robot (suds-robot/1 file)
  suds simulate purcell3 -o opt.mcap --gait fast.yaml --ou-std 0  # a gait file, unperturbed
  suds simulate purcell3 -o lab.mcap --pose-rate 120 --pose-phase-ms 3.7 --jitter-ms 0.4 \
      --drop 0.01 --compression lz4                        # recorded the way a lab records
  suds simulate swimmer9 -o serial.mcap --pose-rate 120 --jitter-ms 2 --stamped-late --latency-ms 3
                                                           # encoders stamped by the host on arrival

Lab options (--pose-rate, --pose-phase-ms, --jitter-ms, --drop, --sensor-offset-ms,
--stamped-late, --latency-ms) record shape and pose as separate streams at their own stamps
from the same physics, drive and seed as the aligned run; an option not given is ideal (pose
at the shape rate and stamps, no jitter, nothing dropped, shape values read at their stamps).
With --stamped-late the shape values are the device's, sampled at the nominal ticks, and only
the stamps carry the jitter (and --latency-ms), as when a host stamps messages on arrival.

The drive is r_a = r_ref(t) + η(t), η an Ornstein–Uhlenbeck process
(dη = −κη dt + σ dW, σ = ou_std·√(2κ)), linearly interpolated between samples; r_ref is the
system's nominal gait or the --gait file (suds-gait/1: its `system` must be the simulated one
and its joints the actuated ones; the bag then carries it in a `suds_gait` metadata record).
--ou-std 0 switches the perturbation off.
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``simulate`` on the ``suds`` subcommand parser."""
    p = subparsers.add_parser("simulate", help="simulate a system and write an MCAP recording",
                              epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("system", nargs="?",
                   help="purcell3, swimmer9, linear_passive, pushmepullyou, nlinkN, or a model file")
    p.add_argument("--model", metavar="FILE", help="robot model file (suds-robot/1) instead of SYSTEM")
    p.add_argument("-o", "--output", required=True,
                   help="output .mcap (never overwritten without --overwrite)")
    p.add_argument("--cycles", type=int, default=60, help="gait cycles to record (default 60)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--noise", type=float, default=1e-3,
                   help="measurement noise std, rad and m (default 1e-3)")
    p.add_argument("--ou-std", type=float, default=0.175,
                   help="stationary std of the OU drive perturbation, rad")
    p.add_argument("--kappa", type=float, default=8.0, help="OU attraction rate κ, 1/s (default 8)")
    p.add_argument("--gait-hz", type=float, default=None,
                   help="gait frequency, Hz (default: the gait file's, else the model file's gait_hz, else 1)")
    p.add_argument("--gait", metavar="FILE",
                   help="gait file (suds-gait/1) to drive the actuated joints instead of the nominal gait")
    p.add_argument("--rate", type=float, default=None, metavar="HZ",
                   help="shape (encoder) sample rate, Hz: a whole number of samples per gait cycle "
                        "(default 100 per cycle)")
    p.add_argument("--substeps", type=int, default=None,
                   help="RK4 steps per sample (default: from the stiffest passive mode)")
    p.add_argument("--effect", action="append", metavar="NAME[:JOINT][:P=V,...]",
                   help="inject a physical effect (repeatable), e.g. "
                        "joint_coulomb_friction:joint_2:mu=0.7")
    p.add_argument("--effort", action="store_true", help="record actuator effort on /suds/shape")
    lab = p.add_argument_group("lab recording conditions")
    lab.add_argument("--pose-rate", type=float, metavar="HZ",
                     help="pose (motion capture) rate, Hz (default: the shape rate)")
    lab.add_argument("--pose-phase-ms", type=float, metavar="MS",
                     help="start of the pose stream after the shape stream, ms (default 0)")
    lab.add_argument("--jitter-ms", type=float, metavar="MS",
                     help="std of each stamp around its nominal grid point, ms (default 0)")
    lab.add_argument("--drop", type=float, metavar="FRACTION",
                     help="fraction of messages lost on each stream (default 0)")
    lab.add_argument("--sensor-offset-ms", type=float, metavar="MS",
                     help="pose stamps late by this much, ms (any value; default 0)")
    lab.add_argument("--stamped-late", action="store_const", const="arrival", dest="stamping",
                     help="shape values sampled on the device's regular clock, the jitter in their stamps "
                          "alone (a host stamping messages as they arrive); default: read at their stamps")
    lab.add_argument("--latency-ms", type=float, metavar="MS",
                     help="shape stamps late by this much, ms (≥ 0; with --stamped-late the transport's "
                          "mean delay; default 0)")
    p.add_argument("--compression", choices=("zstd", "lz4", "none"), default="zstd",
                   help="chunk compression of the bag (default zstd)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    p.set_defaults(func=run)


#: lab option (argparse dest) → the LabConditions field it sets and its unit factor
LAB_OPTIONS = {"pose_rate": ("pose_hz", 1.0), "pose_phase_ms": ("pose_phase", 1e-3),
               "jitter_ms": ("jitter", 1e-3), "drop": ("drop", 1.0), "latency_ms": ("latency", 1e-3)}


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


def _system_spec(args: argparse.Namespace) -> str:
    """Return the system id or model file path of SYSTEM / --model (exactly one of them)."""
    if args.system and args.model:
        raise SudsConfigError(f"SYSTEM {args.system!r} and --model {args.model!r}: give one of them")
    if not (args.system or args.model):
        raise SudsConfigError("no system: give SYSTEM (e.g. purcell3) or --model FILE")
    return str(args.model or args.system)


def lab_conditions(args: argparse.Namespace) -> object | None:
    """Build the :class:`~suds_ros.core.physics.lab.LabConditions` of the lab options; None when none is given.

    Raises
    ------
    SudsConfigError
        For a value out of range, naming the option.
    """
    from suds_ros.core.physics.lab import LabConditions

    given = {dest: getattr(args, dest) for dest in (*LAB_OPTIONS, "sensor_offset_ms", "stamping")
             if getattr(args, dest, None) is not None}
    if not given:
        return None
    values: dict[str, object] = {"pose_hz": None, "pose_phase": 0.0, "jitter": 0.0, "drop": 0.0}
    for dest, (name, unit) in LAB_OPTIONS.items():
        if dest in given:
            values[name] = given[dest] * unit
    if "stamping" in given:
        values["stamping"] = given["stamping"]
    try:
        return LabConditions(**values)  # type: ignore[arg-type]
    except SudsConfigError as exc:
        flags = {name: dest for dest, (name, _) in LAB_OPTIONS.items()}
        name = str(exc).split("`")[1] if str(exc).count("`") >= 2 else ""
        flag = "--" + flags.get(name, name).replace("_", "-")
        raise SudsConfigError(f"{flag}: {exc}", code=exc.code) from None


def run(args: argparse.Namespace) -> int:
    """Execute ``suds simulate``; returns the exit code.

    The run is integrated a few cycles at a time and each block is written as it is made
    (:func:`~suds_ros.core.physics.sim.simulate_blocks`, :class:`~suds_ros.io.recording_bag.RecordingWriter`),
    so memory does not grow with ``--cycles``; the bag is the one the whole run written at once
    would give.  A run that fails midway leaves no file behind.
    """
    from suds_ros.core.physics.sim import SimConfig, effort_by_joint, simulate_blocks
    from suds_ros.core.physics.systems import load_system
    from suds_ros.io.recording_bag import RecordingWriter

    out = Path(args.output)
    if out.exists() and not args.overwrite:
        raise SudsConfigError(f"output {str(out)!r} exists; pass --overwrite to replace it")
    system = load_system(_system_spec(args))
    gait = None
    if args.gait is not None:
        from suds_ros.core.physics.gait import dump_gait, load_gait

        if not Path(args.gait).is_file():
            raise SudsConfigError(f"--gait: no such file {args.gait!r}")
        gait = load_gait(args.gait, system)
        if args.gait_hz is not None and args.gait_hz != gait.gait_hz:
            raise SudsConfigError(f"--gait-hz {args.gait_hz:g}: the gait file {args.gait!r} runs at "
                                  f"{gait.gait_hz:g} Hz; leave --gait-hz out or give the same")
    lab = lab_conditions(args)
    if lab is not None and args.effort:
        raise SudsConfigError("--effort: not recorded with the lab options (effort is defined on "
                              "the aligned sample grid)")
    gait_hz = args.gait_hz or (gait.gait_hz if gait is not None
                               else getattr(getattr(system, "model", None), "gait_hz", 1.0))
    pose_delay = 1e-3 * (args.sensor_offset_ms or 0.0)
    if args.effect:
        from suds_ros.core.physics.effects import apply_effects

        model, effect_delay = apply_effects(system.model,  # type: ignore[attr-defined]
                                            [parse_effect(e) for e in args.effect])
        system = type(system)(model)  # type: ignore[call-arg]
        pose_delay += effect_delay
    per_cycle = SimConfig.samples_per_cycle
    if args.rate is not None:
        per_cycle = int(round(args.rate / gait_hz))
        if not (args.rate > 0 and per_cycle >= 4 and abs(per_cycle * gait_hz - args.rate) <= 1e-9 * args.rate):
            raise SudsConfigError(f"--rate: expected a whole number (≥ 4) of samples per gait cycle of "
                                  f"{gait_hz:g} Hz, got {args.rate:g} Hz")
    cfg = SimConfig(cycles=args.cycles, seed=args.seed, noise_std=args.noise, ou_std=args.ou_std,
                    kappa=args.kappa, substeps=args.substeps, gait_hz=gait_hz,
                    pose_delay=pose_delay, samples_per_cycle=per_cycle, gait=gait)
    progress = progress_bar(f"simulating {system.name}")
    if lab is None:
        blocks = simulate_blocks(system, cfg, progress=progress)
    else:
        from suds_ros.core.physics.lab import simulate_lab_blocks

        blocks = simulate_lab_blocks(system, cfg, lab, progress=progress)  # type: ignore[arg-type]
    names = system.joint_names
    act = list(system.actuated)
    writer = RecordingWriter(out, system=system.name, joint_names=names,
                             actuated=[names[i] for i in act], passive=[names[i] for i in system.passive],
                             gait_hz=gait_hz, overwrite=args.overwrite, compression=args.compression,
                             gait_yaml=None if gait is None else dump_gait(gait))
    try:
        with writer:
            for b in blocks:
                eff = effort_by_joint(system, b.truth["effort"]) if args.effort else None
                writer.write(b.t, b.r, b.pose_t, b.pose, eff)
    except BaseException:
        out.unlink(missing_ok=True)  # half a run is not the recording asked for
        raise
    n_shape, n_pose = writer.counts
    poses = "" if lab is None else f", {n_pose} poses"
    driven = "" if gait is None else f", gait {args.gait}"
    print(f"wrote {out}: {system.name}, {args.cycles} cycles at {gait_hz:g} Hz, {n_shape} samples"
          f"{poses}, seed {args.seed}{driven}")
    return 0
