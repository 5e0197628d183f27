"""``suds diagnose``: where does the simulator disagree with a recording, and which physics explains it.

``add_parser(subparsers)`` registers the subcommand; ``run(args)`` executes it and returns the
exit code (errors are reported by :func:`suds_ros.cli.main.main`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from suds_ros.cli.common import add_bag_argument, add_recording_options, load_recording, load_recording_and_model
from suds_ros.core.errors import SudsConfigError

EPILOG = """\
The nominal simulator is driven with the recorded actuated angles from the recorded
initial passive state (or, with --sim, a simulated recording of the same actuated
trajectory is the reference).  Training uses the first half of the gait cycles; every
reported number is on the held-out second half.

  1. locate: channels (passive angles, ξx, ξy, ξθ) whose residual power exceeds the
     noise floor estimated from the data (F statistic), phase intervals, conditions
  2. name:   catalogue effects and robot-model parameters, stepwise on held-out evidence (≤ 3 at once)
  3. fit:    the chosen effect(s) refined inside the simulator, with standard errors
  4. show:   held-out RMS before/after per channel, improvement, figures in -o DIR

examples:
  suds diagnose --system purcell3 real.mcap
  suds diagnose --system swimmer9 real.mcap --json -o report/
  suds diagnose --system swimmer9 real.mcap --sim replayed_sim.mcap
  suds diagnose --model robot.yaml real.mcap        (a robot model file, suds-robot/1)

Shape and pose may be separate streams (own rates, start times, jitter, dropped messages):
both are brought onto one grid at the nominal shape rate before the stages run.
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``diagnose`` on the ``suds`` subcommand parser."""
    p = subparsers.add_parser(
        "diagnose",
        help="locate, name and fit the physics where a simulator disagrees with a recording",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_bag_argument(p, metavar="REAL.mcap", help="the recording to diagnose")
    p.add_argument("--sim", metavar="SIM.mcap",
                   help="reference recording driven by the same actuated trajectory")
    p.add_argument("--json", action="store_true", help="print the machine-readable report only")
    p.add_argument("--catalogue-only", action="store_true",
                   help="suspect only the catalogue effects, not the robot model's own parameters "
                        "(link lengths, link drag, pose frame; all suspected by default)")
    p.add_argument("-o", "--output", metavar="REPORT_DIR",
                   help="write figures, report.json and summary.txt here")
    add_recording_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute ``suds diagnose``; returns the exit code."""
    from suds_ros.core.diagnosis import DiagnoseConfig, diagnose_recording
    from suds_ros.report.diagnosis import summary_text, write_figures

    if args.output:
        out = Path(args.output)
        if out.exists() and not out.is_dir():
            raise SudsConfigError(f"-o {str(out)!r}: exists and is not a directory")
    rec, model = load_recording_and_model(args.bag, args)
    ref = load_recording(args.sim, args) if args.sim else None
    quiet = args.json or not sys.stderr.isatty()
    progress = None if quiet else (lambda s: print(f"  … {s}", file=sys.stderr, flush=True))
    system = None if model is not None else args.system
    config = DiagnoseConfig(model_suspects=not args.catalogue_only)
    rep = diagnose_recording(rec, system=system, config=config, reference=ref, progress=progress, model=model)
    paths = write_figures(rep, args.output) if args.output else []
    if args.json:
        print(rep.to_json())
        return 0
    print(summary_text(rep, str(args.bag)))
    for p in paths:
        print(f"  wrote {p}")
    return 0
