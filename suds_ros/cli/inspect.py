"""``suds info`` (what a bag holds) and ``suds score`` (how good its recorded live predictions are)."""

from __future__ import annotations

import argparse

from suds_ros.cli.common import add_bag_argument, add_recording_options, existing_bag, load_recording
from suds_ros.core.json_text import dumps

SCORE_DESCRIPTION = (
    "Γ of the predictor's recorded /suds/predicted/* messages against the velocities measured "
    "from the same bag's shape and pose, on the cycles after --train-cycles, with the "
    "phase-only template fitted on the cycles before.  Each live prediction was made before "
    "its sample was learnt, so all are out of sample.")


def add_parsers(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``info`` and ``score`` on the ``suds`` subcommand parser."""
    p = subparsers.add_parser("info", help="summarise a recording (topics, counts, time range, "
                                           "metadata, damage)")
    add_bag_argument(p)
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=run_info)

    p = subparsers.add_parser("score", help="score the live predictions recorded in a bag "
                                            "(pipeline output)", description=SCORE_DESCRIPTION)
    add_bag_argument(p)
    p.add_argument("--train-cycles", type=float, default=None,
                   help="cycles for the reference template (default: half of the recording)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    add_recording_options(p)
    p.set_defaults(func=run_score)


def run_info(args: argparse.Namespace) -> int:
    """Execute ``suds info``: every field of the bag's summary, one per line (or JSON).

    The ``damage:`` section lists each skipped part of a damaged bag (offset, record,
    reason, log-time range, messages lost), or says ``none``.
    """
    from suds_ros.io.mcap import bag_info

    bag = bag_info(existing_bag(args.bag))
    info = bag.as_dict()
    if args.json:
        print(dumps(info, indent=2, default=str))
        return 0
    for key, value in info.items():
        if key == "damage":
            print("damage: none" if not bag.damage else "damage:")
            for d in bag.damage:
                print(f"  {d.describe()}")
        elif key == "messages_lost":
            print(f"messages_lost: {'unknown' if value is None else value}")
        elif isinstance(value, dict):
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


def run_score(args: argparse.Namespace) -> int:
    """Execute ``suds score``; returns the exit code."""
    from suds_ros.report.live_score import score_live_predictions

    rec = load_recording(args.bag, args)
    score = score_live_predictions(args.bag, args.train_cycles, recording=rec, namespace=args.namespace)
    if args.json:
        print(dumps(score.as_dict(), indent=2))
    else:
        print(score.summary())
        passive = "none" if score.rms_passive is None else f"{score.rms_passive:.4g} rad/s"
        print(f"RMS error: body velocity {score.rms_body:.4g} (m/s and rad/s pooled), "
              f"passive velocity {passive}")
    return 0
