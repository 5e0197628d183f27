"""The ``suds`` command: simulate, inspect, identify, score and diagnose recordings.

Every subcommand is a function ``cmd_<name>(args) -> int``; deliberate errors
(:class:`~suds_ros.core.errors.SudsError`) print one ``ERROR: …`` line and
return 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path
from typing import Sequence

import numpy as np

from suds_ros.core.errors import SudsConfigError, SudsError

EPILOG_SIMULATE = """\
examples:
  suds simulate purcell3 -o purcell3.mcap                 # 60 cycles, seed 0, noise 1e-3
  suds simulate swimmer9 -o s9.mcap --cycles 30 --seed 4 --effect spring_rest_offset:joint_6:offset=0.25
  suds simulate nlink15 -o n15.mcap --noise 0             # a 15-link chain, noise free

The drive is r_a = r_ref(t) + η(t), η an Ornstein–Uhlenbeck process
(dη = −κη dt + σ dW, σ = ou_std·√(2κ)), linearly interpolated between samples.
"""

EPILOG_IDENTIFY = """\
The first --train-cycles cycles are used to estimate the gait phase (phaser),
the phase-averaged gait θ(φ) and the SUDS regression
  (g°, ṙ_p) ~ C(φ) + C_r(φ) δ + B(φ) δ̇_a + B_r(φ) δ⊗δ̇_a ;
the next --test-cycles cycles are held out.  Γ = 1 − Σ|model − truth| / Σ|template − truth|
compares the model with the phase-only template on the held-out cycles
(Γ = 0: no better than the template, Γ = 1: perfect).

examples:
  suds identify run.mcap                      # 30 train / 30 test cycles, regressor set 2
  suds identify run.mcap --regressors 1 --json
  suds identify run.mcap --figure fig.png --actuated joint_1 --system purcell3
"""


def _progress(label: str):  # type: ignore[no-untyped-def]
    if not sys.stderr.isatty():
        return None

    def cb(done: int, total: int) -> None:
        frac = done / max(total, 1)
        bar = "#" * int(30 * frac)
        sys.stderr.write(f"\r{label} [{bar:<30}] {100 * frac:5.1f}%")
        if done >= total:
            sys.stderr.write("\n")
        sys.stderr.flush()

    return cb


def _parse_effect(text: str) -> dict[str, object]:
    """``name[:target][:p=v[,p=v]]`` → effect dict."""
    parts = text.split(":")
    out: dict[str, object] = {"name": parts[0]}
    for part in parts[1:]:
        if "=" in part:
            for kv in part.split(","):
                k, _, v = kv.partition("=")
                try:
                    out[k.strip()] = float(v)
                except ValueError:
                    raise SudsConfigError(f"--effect {text!r}: parameter {k!r} needs a number, got {v!r}") from None
        elif part:
            out["joint"] = part
    return out


# --------------------------------------------------------------------- simulate
def cmd_simulate(args: argparse.Namespace) -> int:
    from suds_ros.core.physics.sim import SimConfig, simulate
    from suds_ros.core.physics.systems import make_system
    from suds_ros.io.bags import write_recording

    out = Path(args.output)
    if out.exists() and not args.overwrite:
        raise SudsConfigError(f"output {str(out)!r} exists; pass --overwrite to replace it")
    system = make_system(args.system)
    pose_delay = 0.0
    if args.effect:
        from suds_ros.core.physics.effects import apply_effects

        model, pose_delay = apply_effects(system.model, [_parse_effect(e) for e in args.effect])  # type: ignore[attr-defined]
        system = type(system)(model)  # type: ignore[call-arg]
    cfg = SimConfig(
        cycles=args.cycles,
        seed=args.seed,
        noise_std=args.noise,
        ou_std=args.ou_std,
        kappa=args.kappa,
        substeps=args.substeps,
        gait_hz=args.gait_hz,
        pose_delay=pose_delay,
    )
    rec = simulate(system, cfg, progress=_progress(f"simulating {args.system}"))
    if args.effort:
        eff = np.zeros_like(rec.r)
        eff[:, rec.actuated_index] = rec.truth["effort"]
        rec = replace(rec, effort=eff)
    write_recording(out, rec, overwrite=args.overwrite)
    print(f"wrote {out}: {args.system}, {args.cycles} cycles, {rec.n_samples} samples, seed {args.seed}")
    return 0


# ------------------------------------------------------------------------- info
def cmd_info(args: argparse.Namespace) -> int:
    from suds_ros.io.bags import bag_info

    info = bag_info(args.bag)
    if args.json:
        print(json.dumps(info, indent=2, default=str))
        return 0
    for key, value in info.items():
        if isinstance(value, dict):
            print(f"{key}:")
            for k, v in value.items():
                print(f"  {k}: {v}")
        elif isinstance(value, list):
            print(f"{key}:")
            for v in value:
                print(f"  {v}")
        else:
            print(f"{key}: {value}")
    return 0


def cmd_score(args: argparse.Namespace) -> int:
    from suds_ros.report.live_score import score_live_predictions

    if not Path(args.bag).exists():
        raise SudsConfigError(f"no such file: {args.bag!r}")
    score = score_live_predictions(args.bag, args.train_cycles)
    if args.json:
        print(json.dumps(score.as_dict(), indent=2))
    else:
        print(score.summary())
        print(f"RMS error: body velocity {score.rms_body:.4g} (m/s and rad/s pooled), "
              f"passive velocity {score.rms_passive:.4g} rad/s")
    return 0


# --------------------------------------------------------------------- identify
def load_recording(args: argparse.Namespace):  # type: ignore[no-untyped-def]
    """Read ``args.bag`` with the metadata overrides of the common options."""
    from suds_ros.io.bags import read_recording

    path = Path(args.bag)
    if not path.exists():
        raise SudsConfigError(f"no such file: {str(path)!r}")
    split = lambda s: [x.strip() for x in s.split(",") if x.strip()] if s else None  # noqa: E731
    rec = read_recording(path, system=args.system, actuated=split(args.actuated), passive=split(args.passive))
    if args.gait_hz:
        rec = replace(rec, gait_hz=args.gait_hz)
    return rec


def cmd_identify(args: argparse.Namespace) -> int:
    from suds_ros.core.ident.identify import IdentifyConfig, SudsIdentifier, split_cycles
    from suds_ros.core.ident.sysid import SudsConfig

    from suds_ros.core.ident.scoring import score_prediction

    rec = load_recording(args)
    if args.test_cycles == 0:
        train, test = rec, None
    else:
        train, test = split_cycles(rec, args.train_cycles, args.test_cycles)
    if args.streaming:
        return _identify_streaming(args, rec, train, test)
    if test is None:
        raise SudsConfigError("--test-cycles 0 is only supported with --streaming (nothing to score)")
    cfg = IdentifyConfig(suds=SudsConfig(regressors=args.regressors), window=args.window)
    torque = bool(args.torque)
    if torque and rec.effort is None:
        raise SudsConfigError("--torque: the recording has no effort on /suds/shape")
    ident = SudsIdentifier(cfg, torque=torque).fit(train)
    pred = ident.predict(test)
    sc = score_prediction(pred)
    result = {
        "bag": str(args.bag),
        "system": rec.system,
        "train_cycles": args.train_cycles,
        "test_cycles": int(round((test.t[-1] - test.t[0] + test.dt) * (rec.gait_hz or 1.0))),
        "regressors": args.regressors,
        "parameters_per_output": ident.n_parameters,
        "fourier_orders": {
            "intercept": ident.regressor_.config.intercept_order,
            "linear": ident.regressor_.config.linear_order,
            "bilinear": ident.regressor_.config.bilinear_order,
        },
        **sc.as_dict(),
    }
    if args.figure:
        from suds_ros.report.identify_figure import identify_figure

        identify_figure(ident, train, test, pred, args.figure, title=f"{rec.system}: {Path(args.bag).name}")
        result["figure"] = str(args.figure)
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    print(f"{rec.system}: {args.bag}")
    print(f"  train {args.train_cycles} cycles, test {result['test_cycles']} cycles, regressor set "
          f"{args.regressors}, {ident.n_parameters} parameters per output")
    print(f"  {'':<14}{'Γ':>8}")
    print(f"  {'body':<14}{sc.gamma_body:>8.3f}")
    print(f"  {'passive':<14}{sc.gamma_passive:>8.3f}")
    if sc.gamma_torque is not None:
        print(f"  {'torque':<14}{sc.gamma_torque:>8.3f}")
    print(f"  {'channel':<16}{'RMS model':>12}{'RMS template':>14}")
    for c in pred.channels:
        print(f"  {c:<16}{sc.rms_model[c]:>12.4g}{sc.rms_template[c]:>14.4g}")
    if args.figure:
        print(f"  figure: {args.figure}")
    return 0


def _identify_streaming(args: argparse.Namespace, rec, train, test) -> int:  # type: ignore[no-untyped-def]
    """The live estimator's algorithm run offline (same model as the estimator node on this data)."""
    from suds_ros.core.ident.scoring import score_prediction
    from suds_ros.core.ident.online import OnlineConfig, fit_streaming
    from suds_ros.core.ident.predictor import evaluate_model

    cfg = OnlineConfig(
        suds=replace(OnlineConfig().suds, regressors=args.regressors),
        init_cycles=args.init_cycles,
        gait_hz=rec.gait_hz or 1.0,
    )
    est = fit_streaming(train, cfg)
    model = est.model()
    result: dict[str, object] = {
        "bag": str(args.bag),
        "system": rec.system,
        "mode": "streaming",
        "samples": model.n_samples,
        "running_gamma": est.running_gamma(),
        "parameters_per_output": int(model.coef.shape[0]),
    }
    if test is not None:
        result.update(score_prediction(evaluate_model(model, test)).as_dict())
    if args.model_out:
        Path(args.model_out).write_text(json.dumps(model.to_dict()))
        result["model"] = str(args.model_out)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        for k, v in result.items():
            if k not in ("rms_model", "rms_template"):
                print(f"{k}: {v}")
    return 0


# ------------------------------------------------------------------------ parser
def _add_recording_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--system", help="system id (overrides the bag's metadata)")
    p.add_argument("--actuated", help="comma-separated actuated joint names (overrides metadata)")
    p.add_argument("--passive", help="comma-separated passive joint names (overrides metadata)")
    p.add_argument("--gait-hz", type=float, help="nominal gait frequency, Hz (overrides metadata)")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``suds``."""
    parser = argparse.ArgumentParser(
        prog="suds",
        description="Identify shape-underactuated dissipative systems (SUDS) from their motion, "
        "and diagnose where a simulator disagrees with a recording.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser("simulate", help="simulate a system and write an MCAP recording",
                       epilog=EPILOG_SIMULATE, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("system", help="purcell3, swimmer9, linear_passive, pushmepullyou or nlinkN")
    p.add_argument("-o", "--output", required=True, help="output .mcap (never overwritten without --overwrite)")
    p.add_argument("--cycles", type=int, default=60, help="gait cycles to record (default 60)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--noise", type=float, default=1e-3, help="measurement noise std, rad and m (default 1e-3)")
    p.add_argument("--ou-std", type=float, default=0.175, help="stationary std of the OU drive perturbation, rad")
    p.add_argument("--kappa", type=float, default=8.0, help="OU attraction rate κ, 1/s (default 8)")
    p.add_argument("--gait-hz", type=float, default=1.0, help="gait frequency, Hz (default 1)")
    p.add_argument("--substeps", type=int, default=None, help="RK4 steps per sample (default: from the stiffest passive mode)")
    p.add_argument("--effect", action="append", metavar="NAME[:JOINT][:P=V,...]",
                   help="inject a physical effect (repeatable), e.g. joint_coulomb_friction:joint_2:mu=0.7")
    p.add_argument("--effort", action="store_true", help="record actuator effort on /suds/shape")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("info", help="summarise a recording (topics, counts, time range, metadata)")
    p.add_argument("bag")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("identify", help="fit the SUDS model and report Γ on held-out cycles",
                       epilog=EPILOG_IDENTIFY, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("bag")
    p.add_argument("--train-cycles", type=int, default=30, help="training cycles (default 30)")
    p.add_argument("--test-cycles", type=int, default=30,
                   help="held-out cycles (default 30; fewer if the bag is short; 0 with --streaming: train on everything)")
    p.add_argument("--regressors", type=int, choices=(1, 2, 3), default=2,
                   help="regressor set: 1 [1,δ,δ̇_a], 2 [1,δ,δ̇_a,δ⊗δ̇_a] (default), 3 full second order")
    p.add_argument("--window", type=int, default=1, help="differencing window in samples (default 1)")
    p.add_argument("--torque", action="store_true", help="also identify actuator effort (needs effort in the bag)")
    p.add_argument("--streaming", action="store_true",
                   help="run the live estimator's algorithm (phaser on the first --init-cycles, then phase "
                        "tracking and incremental fitting); gives the estimator node's model")
    p.add_argument("--init-cycles", type=float, default=5.0, help="with --streaming: cycles before the phaser initialises")
    p.add_argument("--model-out", help="with --streaming: write the model JSON (as on /suds/model) here")
    p.add_argument("--figure", help="write a Figure-1-style plot to this path (PNG)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    _add_recording_options(p)
    p.set_defaults(func=cmd_identify)

    p = sub.add_parser("score", help="score the live predictions recorded in a bag (pipeline output)",
                       description="Γ of the predictor's recorded /suds/predicted/* messages against "
                       "the velocities measured from the same bag's shape and pose, on the cycles after "
                       "--train-cycles, with the phase-only template fitted on the cycles before.  Each "
                       "live prediction was made before its sample was learnt, so all are out of sample.")
    p.add_argument("bag")
    p.add_argument("--train-cycles", type=float, default=None,
                   help="cycles for the reference template (default: half of the recording)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=cmd_score)

    from suds_ros.cli import diagnose as cli_diagnose

    cli_diagnose.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``suds``; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except SudsError as exc:
        print(f"ERROR: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("ERROR: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
