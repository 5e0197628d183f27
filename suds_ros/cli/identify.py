"""``suds identify``: fit the SUDS model to a recording and score it on held-out cycles."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from suds_ros.cli.common import add_bag_argument, add_recording_options, load_recording
from suds_ros.core.errors import SudsConfigError
from suds_ros.core.json_text import dumps
from suds_ros.core.recording import Recording

EPILOG = """\
The first --train-cycles cycles are used to estimate the gait phase (phaser),
the phase-averaged gait θ(φ) and the SUDS regression
  (g°, ṙ_p) ~ C(φ) + C_r(φ) δ + B(φ) δ̇_a + B_r(φ) δ⊗δ̇_a ;
the next --test-cycles cycles are held out.  Γ = 1 − Σ|model − truth| / Σ|template − truth|
compares the model with the phase-only template on the held-out cycles
(Γ = 0: no better than the template, Γ = 1: perfect).

A recording with bouts (`suds import --segment`; metadata key `bouts`) is split
into whole bouts instead: the first bouts until --train-cycles cycles train, the
following bouts (up to --test-cycles cycles) are held out; no interval spans a
pause.  Too few bouts or cycles for that end in an ERROR naming how many there
are.  --ignore-bouts splits by time as for a steady run.

examples:
  suds identify run.mcap                      # 30 train / 30 test cycles, regressor set 2
  suds identify larva.mcap --train-cycles 12 --test-cycles 6   # whole bouts
  suds identify run.mcap --regressors 1 --json
  suds identify run.mcap --figure fig.png --actuated joint_1 --system purcell3
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``identify`` on the ``suds`` subcommand parser."""
    p = subparsers.add_parser("identify", help="fit the SUDS model and report Γ on held-out cycles",
                              epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_bag_argument(p)
    p.add_argument("--train-cycles", type=int, default=30, help="training cycles (default 30)")
    p.add_argument("--test-cycles", type=int, default=30,
                   help="held-out cycles (default 30; fewer if the bag is short; 0 with "
                        "--streaming: train on everything)")
    p.add_argument("--regressors", type=int, choices=(1, 2, 3), default=None,
                   help="regressor set: 1 [1,δ,δ̇_a], 2 [1,δ,δ̇_a,δ⊗δ̇_a], 3 full second order "
                        "(default: chosen with the Fourier orders and ridge by cross-validation on the "
                        "training cycles; with --streaming the estimator's set 2)")
    p.add_argument("--ignore-bouts", action="store_true",
                   help="split by time even when the recording lists bouts (metadata `bouts`)")
    p.add_argument("--window", type=int, default=1,
                   help="differencing window in samples (default 1)")
    p.add_argument("--torque", action="store_true",
                   help="also identify actuator effort (needs effort in the bag)")
    p.add_argument("--streaming", action="store_true",
                   help="run the live estimator's algorithm (phaser on the first --init-cycles, "
                        "then phase tracking and incremental fitting); gives the estimator "
                        "node's model")
    p.add_argument("--init-cycles", type=float, default=None,
                   help="with --streaming: cycles before the phaser initialises (default: the "
                        "estimator's)")
    p.add_argument("--model-out", help="with --streaming: write the model JSON (as on /suds/model) here")
    p.add_argument("--figure", help="write a Figure-1-style plot to this path (PNG)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    add_recording_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute ``suds identify``; returns the exit code."""
    from suds_ros.core.ident.identify import split_bouts, split_cycles

    rec = load_recording(args.bag, args)
    if rec.bouts and not args.ignore_bouts:
        if args.streaming:
            raise SudsConfigError("--streaming: the recording lists bouts (intermittent motion) and the live "
                                  "estimator runs on one continuous stream; pass --ignore-bouts to run it anyway")
        if args.test_cycles == 0:
            raise SudsConfigError("--test-cycles 0 is only supported with --streaming (nothing to score)")
        train_bouts, test_bouts = split_bouts(rec, args.train_cycles, args.test_cycles)
        return _batch(args, rec, train_bouts, test_bouts)
    if args.test_cycles == 0:
        train, test = rec, None
    else:
        train, test = split_cycles(rec, args.train_cycles, args.test_cycles)
    if args.streaming:
        return _streaming(args, rec, train, test)
    if test is None:
        raise SudsConfigError("--test-cycles 0 is only supported with --streaming (nothing to score)")
    return _batch(args, rec, train, test)


def _cycles(recs: list[Recording], gait_hz: float) -> float:
    """Gait cycles in recordings (each counting its last sample's period)."""
    return sum((r.t[-1] - r.t[0] + r.dt) * gait_hz for r in recs)


def _end_to_end(recs: list[Recording]) -> Recording:
    """Bouts as one recording for the figure's gait panel (samples in time order, pauses left out)."""
    from dataclasses import replace

    if len(recs) == 1:
        return recs[0]
    return replace(recs[0], t=np.concatenate([r.t for r in recs]), r=np.concatenate([r.r for r in recs]),
                   pose_t=np.concatenate([r.pose_t for r in recs]), pose=np.concatenate([r.pose for r in recs]),
                   effort=None, truth={})


def _batch(args: argparse.Namespace, rec: Recording, train: Recording | list[Recording],
           test: Recording | list[Recording]) -> int:
    """The batch identifier, scored on ``test`` (a recording, or held-out bouts); prints the Γ table (or JSON)."""
    from suds_ros.core.ident.identify import IdentifyConfig, SudsIdentifier
    from suds_ros.core.ident.scoring import score_prediction
    from suds_ros.core.ident.sysid import SudsConfig

    if args.regressors is None:  # the shipped choice by cross-validation
        cfg = IdentifyConfig(window=args.window)
    else:  # a fixed Fourier set (orders and ridge still chosen), no random shape features
        cfg = IdentifyConfig(suds=SudsConfig(regressors=args.regressors), regressor_grid=(args.regressors,),
                             kernel_grid=(), window=args.window)
    if args.torque and rec.effort is None:
        raise SudsConfigError("--torque: the recording has no effort on /suds/shape")
    ident = SudsIdentifier(cfg, torque=bool(args.torque)).fit(train)
    pred = ident.predict(test) if args.figure else None  # long recordings are scored a block at a time
    sc = ident.scores(test) if pred is None else score_prediction(pred)
    hz = rec.gait_hz or 1.0
    bouts = isinstance(train, list)
    train_list = train if isinstance(train, list) else [train]
    test_list = test if isinstance(test, list) else [test]
    result: dict[str, Any] = {
        "bag": str(args.bag),
        "system": rec.system,
        "train_cycles": round(_cycles(train_list, hz), 2) if bouts else args.train_cycles,
        "test_cycles": round(_cycles(test_list, hz), 2) if bouts else int(round(_cycles(test_list, hz))),
        "regressors": ident.regressor_.config.regressors,
        "ridge": ident.regressor_.config.ridge,
        "state": ident.regressor_.config.state,
        "kernel_features": ident.regressor_.config.kernel_features,
        "parameters_per_output": ident.n_parameters,
        "fourier_orders": {
            "intercept": ident.regressor_.config.intercept_order,
            "linear": ident.regressor_.config.linear_order,
            "bilinear": ident.regressor_.config.bilinear_order,
        },
        **sc.as_dict(),
    }
    if bouts:
        result["bouts"] = {
            "total": len(rec.bouts),
            "train": [[float(r.t[0]), float(r.t[-1])] for r in train_list],
            "test": [[float(r.t[0]), float(r.t[-1])] for r in test_list],
        }
    if args.figure:
        from suds_ros.report.identify_figure import identify_figure

        identify_figure(ident, _end_to_end(train_list), _end_to_end(test_list), pred, args.figure,
                        title=f"{rec.system}: {Path(args.bag).name}")
        result["figure"] = str(args.figure)
    if args.json:
        print(dumps(result, indent=2))
        return 0
    print(f"{rec.system}: {args.bag}")
    if bouts:
        print(f"  whole bouts: train {len(train_list)} bouts ({result['train_cycles']:.1f} cycles), held out "
              f"{len(test_list)} bouts ({result['test_cycles']:.1f} cycles) of {len(rec.bouts)}; regressor set "
              f"{result['regressors']}, {ident.n_parameters} parameters per output")
    else:
        print(f"  train {args.train_cycles} cycles, test {result['test_cycles']} cycles, regressor set "
              f"{result['regressors']}, {ident.n_parameters} parameters per output")
    print(f"  {'':<14}{'Γ':>8}")
    print(f"  {'body':<14}{_gamma_text(sc.gamma_body)}")
    if sc.gamma_passive is None:
        print(f"  {'passive':<14}{'none':>8} (fully actuated: no passive joint)")
    else:
        print(f"  {'passive':<14}{_gamma_text(sc.gamma_passive)}")
    if sc.gamma_torque is not None:
        print(f"  {'torque':<14}{_gamma_text(sc.gamma_torque)}")
    print(f"  {'channel':<16}{'RMS model':>12}{'RMS template':>14}")
    for c in ident.channels_:
        print(f"  {c:<16}{sc.rms_model[c]:>12.4g}{sc.rms_template[c]:>14.4g}")
    if args.figure:
        print(f"  figure: {args.figure}")
    return 0


def _plain(v: object) -> str:
    """A value of the streaming summary as text: a score that does not apply is "none"."""
    if v is None:
        return "none"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k}: {_plain(x)}" for k, x in v.items()) + "}"
    if isinstance(v, float) and not math.isfinite(v):
        return "undefined"
    return str(v)


def _gamma_text(g: float) -> str:
    """A Γ for the table, right-aligned in 8 columns ("undefined" when it is not finite)."""
    return f"{g:>8.3f}" if math.isfinite(g) else f"{'undefined':>8}"


def _streaming(args: argparse.Namespace, rec: Recording, train: Recording,
               test: Recording | None) -> int:
    """The live estimator's algorithm run offline (the estimator node's model on this data)."""
    from dataclasses import replace

    from suds_ros.core.ident.online import OnlineConfig, fit_streaming
    from suds_ros.core.ident.predictor import evaluate_model
    from suds_ros.core.ident.scoring import score_prediction
    from suds_ros.core.resample import on_shape_grid

    defaults = OnlineConfig()
    if args.regressors is None:
        args.regressors = defaults.suds.regressors
    cfg = replace(defaults, suds=replace(defaults.suds, regressors=args.regressors),
                  init_cycles=defaults.init_cycles if args.init_cycles is None else args.init_cycles,
                  gait_hz=rec.gait_hz or 1.0)
    est = fit_streaming(train, cfg)
    model = est.model()
    result: dict[str, object] = {
        "bag": str(args.bag),
        "system": rec.system,
        "mode": "streaming",
        "samples": model.n_samples,
        "running_gamma": est.running_gamma(),  # a group without channels: None
        "parameters_per_output": int(model.coef.shape[0]),
    }
    if test is not None:  # scored on the shape grid, as the batch identifier scores (aligned: unchanged)
        result.update(score_prediction(evaluate_model(model, on_shape_grid(test))).as_dict())
    if args.model_out:
        Path(args.model_out).write_text(dumps(model.to_dict()))
        result["model"] = str(args.model_out)
    if args.json:
        print(dumps(result, indent=2))
    else:
        for k, v in result.items():
            if k not in ("rms_model", "rms_template"):
                print(f"{k}: {_plain(v)}")
    return 0
