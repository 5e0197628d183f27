"""``suds diagnose``: where does the simulator disagree with a recording, and which physics explains it.

``add_parser(subparsers)`` registers the subcommand; ``run(args)`` executes it and returns the
exit code (2 with one ``ERROR: …`` line on a deliberate suds error, never a traceback).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from suds_ros.core.errors import SudsConfigError, SudsError

EPILOG = """\
The nominal simulator is driven with the recorded actuated angles from the recorded
initial passive state (or, with --sim, a simulated recording of the same actuated
trajectory is the reference).  Training uses the first half of the gait cycles; every
reported number is on the held-out second half.

  1. locate: channels (passive angles, ξx, ξy, ξθ) whose residual power exceeds the
     noise floor estimated from the data (F statistic), phase intervals, conditions
  2. name:   catalogue effects and pairs ranked by held-out evidence (equation error)
  3. fit:    the chosen effect(s) refined inside the simulator, with standard errors
  4. show:   held-out RMS before/after per channel, improvement, figures in -o DIR

examples:
  suds diagnose --system purcell3 real.mcap
  suds diagnose --system swimmer9 real.mcap --json -o report/
  suds diagnose --system swimmer9 real.mcap --sim replayed_sim.mcap
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``diagnose`` on the ``suds`` sub-command parser."""
    p = subparsers.add_parser(
        "diagnose",
        help="locate, name and fit the physics where a simulator disagrees with a recording",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("bag", metavar="REAL.mcap", help="the recording to diagnose")
    p.add_argument("--system", help="system id of the nominal simulator (default: the bag's metadata)")
    p.add_argument("--sim", metavar="SIM.mcap", help="reference recording driven by the same actuated trajectory")
    p.add_argument("--json", action="store_true", help="print the machine-readable report only")
    p.add_argument("-o", "--output", metavar="REPORT_DIR", help="write figures, report.json and summary.txt here")
    p.add_argument("--actuated", help="comma-separated actuated joint names (overrides metadata)")
    p.add_argument("--passive", help="comma-separated passive joint names (overrides metadata)")
    p.add_argument("--gait-hz", type=float, help="gait frequency, Hz (overrides metadata)")
    p.set_defaults(func=run)


def _split(text: str | None) -> list[str] | None:
    return [x.strip() for x in text.split(",") if x.strip()] if text else None


def _load(path_text: str, args: argparse.Namespace):  # type: ignore[no-untyped-def]
    from suds_ros.io.bags import read_recording

    path = Path(path_text)
    if not path.exists():
        raise SudsConfigError(f"no such file: {str(path)!r}")
    rec = read_recording(
        path, system=getattr(args, "system", None),
        actuated=_split(getattr(args, "actuated", None)), passive=_split(getattr(args, "passive", None)),
    )
    gait_hz = getattr(args, "gait_hz", None)
    if gait_hz:
        rec = replace(rec, gait_hz=gait_hz)
    return rec


def run(args: argparse.Namespace) -> int:
    """Execute ``suds diagnose``; returns the exit code."""
    try:
        return _run(args)
    except SudsError as exc:
        print(f"ERROR: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}", file=sys.stderr)
        return 2


def _run(args: argparse.Namespace) -> int:
    from suds_ros.core.diagnosis import diagnose_recording
    from suds_ros.report.diagnosis import summary_text, write_figures

    if args.output:
        out = Path(args.output)
        if out.exists() and not out.is_dir():
            raise SudsConfigError(f"-o {str(out)!r}: exists and is not a directory")
    rec = _load(args.bag, args)
    ref = _load(args.sim, args) if args.sim else None
    quiet = args.json or not sys.stderr.isatty()
    progress = None if quiet else (lambda s: print(f"  … {s}", file=sys.stderr, flush=True))
    rep = diagnose_recording(rec, system=args.system, reference=ref, progress=progress)
    paths = write_figures(rep, args.output) if args.output else []
    if args.json:
        print(rep.to_json())
        return 0
    print(summary_text(rep, str(args.bag)))
    for p in paths:
        print(f"  wrote {p}")
    return 0
