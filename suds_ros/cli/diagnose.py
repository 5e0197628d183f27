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
    p.add_argument("--propose-experiment", metavar="DIR", default=None,
                   help="for an ambiguous finding, write to DIR the gait (suds-gait/1) that best tells the "
                        "explanations apart, and say how many cycles of it would")
    p.add_argument("--ambiguity-band", type=float, default=None, metavar="NATS",
                   help="explanations whose held-out evidence after replay is within this many nats of the "
                        "reported one are listed with it as alternatives (default 10)")
    p.add_argument("--jobs", type=int, default=None, metavar="N",
                   help="worker processes for the candidate fits and refinements (default: the CPUs this "
                        "process may use); the report does not depend on it")
    p.add_argument("-o", "--output", metavar="REPORT_DIR",
                   help="write figures, report.json and summary.txt here")
    add_recording_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute ``suds diagnose``; returns the exit code."""
    from suds_ros.core.diagnosis import DiagnoseConfig, diagnose_recording
    from suds_ros.report.diagnosis import summary_text, write_figures

    for flag, value in (("-o", args.output), ("--propose-experiment", args.propose_experiment)):
        if value and Path(value).exists() and not Path(value).is_dir():
            raise SudsConfigError(f"{flag} {value!r}: exists and is not a directory")
    if args.jobs is not None and args.jobs < 1:
        raise SudsConfigError(f"--jobs: expected a positive number of processes, got {args.jobs}")
    rec, model = load_recording_and_model(args.bag, args)
    ref = load_recording(args.sim, args) if args.sim else None
    quiet = args.json or not sys.stderr.isatty()
    progress = None if quiet else (lambda s: print(f"  … {s}", file=sys.stderr, flush=True))
    system = None if model is not None else args.system
    band = {} if args.ambiguity_band is None else {"ambiguity_band": args.ambiguity_band}
    config = DiagnoseConfig(model_suspects=not args.catalogue_only, jobs=args.jobs or _cpus(), **band)
    rep = diagnose_recording(rec, system=system, config=config, reference=ref, progress=progress, model=model)
    paths = write_figures(rep, args.output) if args.output else []
    experiments: list[dict[str, object]] = []
    lines: list[str] = []
    if args.propose_experiment:
        experiments, lines = _experiments(rep, rec, model, system, config, Path(args.propose_experiment))
    if args.json:
        if args.propose_experiment:
            from suds_ros.core.json_text import dumps

            print(dumps({**rep.to_dict(), "experiments": experiments}))
        else:
            print(rep.to_json())
        return 0
    print(summary_text(rep, str(args.bag)))
    for line in lines:
        print(line)
    for p in paths:
        print(f"  wrote {p}")
    return 0


def _cpus() -> int:
    """The CPUs this process may run on (its affinity), at least 1."""
    import os

    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def _experiments(rep, rec, model, system, config,  # type: ignore[no-untyped-def]
                 out: Path) -> tuple[list[dict[str, object]], list[str]]:
    """Propose a settling experiment for each alternative of the finding; write the gaits to ``out``.

    Returns the JSON entries and the report lines.  Nothing is overwritten: an existing file of
    the same name is an error.
    """
    from suds_ros.core.diagnosis.experiment import ExperimentConfig, propose_for_report, recorded_drive
    from suds_ros.core.physics.gait import dump_gait
    from suds_ros.core.physics.systems import load_system

    chain = model if model is not None else load_system(system or rec.system).model
    chain = chain.with_(gait_hz=rec.gait_hz or chain.gait_hz)
    # the baseline: the drive this recording ran (the proposal is never worse than running it longer)
    run = recorded_drive(rec, chain, ExperimentConfig().order)
    proposals = propose_for_report(rep, chain, rec.dt, config, run=run)
    if not proposals:
        return [], ["  experiment: none proposed (the finding has no alternatives)"]
    out.mkdir(parents=True, exist_ok=True)
    entries: list[dict[str, object]] = []
    lines = ["  experiments that settle the ambiguity (suds simulate --gait FILE, or run it on the robot):"]
    for i, p in enumerate(proposals, start=1):
        entry = p.as_dict()
        if p.gait is None:
            entry["gait_file"] = None
            lines.append(f"    {p.reported} OR {p.alternative}: no drive within the joint range and speed "
                         f"separates them ({p.nats_per_cycle:.3g} nats per cycle at best): for this robot they "
                         "are the same physics")
        else:
            path = out / f"experiment_{i}.yaml"
            if path.exists():
                raise SudsConfigError(f"--propose-experiment: {str(path)!r} exists; nothing overwritten")
            path.write_text(dump_gait(p.gait))
            entry["gait_file"] = str(path)
            already = "the drive this recording ran" if p.baseline == "recorded" else "the nominal gait"
            if p.is_baseline:
                lines.append(f"    {p.reported} OR {p.alternative}: no drive tried within the joint range and speed "
                             f"separates them better than {already} ({path}): run {p.cycles} cycles of it "
                             f"({p.nats_per_cycle:.3g} nats per cycle between them; {p.threshold:g} nats settle it)")
            else:
                lines.append(f"    {p.reported} OR {p.alternative}: run {path} for {p.cycles} cycles "
                             f"({p.nats_per_cycle:.3g} nats per cycle between them, against "
                             f"{p.baseline_nats_per_cycle:.3g} under {already}; {p.threshold:g} nats settle it)")
            if p.mismatch_power < config.f_threshold - 1.0:
                lines.append(f"      caution: under this drive the mismatch's power per sample is "
                             f"{p.mismatch_power:.2g} of the noise floor's (F ≈ {1 + p.mismatch_power:.2f}, "
                             f"threshold {config.f_threshold:g}): the new run may not locate it at all, however long")
        entries.append(entry)
    return entries, lines
