"""``suds monitor``: the live mismatch monitor replayed offline over a recording.

``add_parser(subparsers)`` registers the subcommand; ``run(args)`` executes it and returns the
exit code (errors are reported by :func:`suds_ros.cli.main.main`).  The work is
:func:`~suds_ros.core.diagnosis.monitor.monitor_recording`: the recording's shape and pose
streams fed, in stamp order, through the same
:class:`~suds_ros.core.diagnosis.monitor.MismatchMonitor` the ``monitor`` node runs.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from suds_ros.core import json_text
from suds_ros.cli.common import add_bag_argument, add_recording_options, load_recording_and_model
from suds_ros.core.errors import WRONG_JOINT_NAMES, SudsConfigError, SudsDataError

if TYPE_CHECKING:
    from suds_ros.core.physics.system import SudsSystem
    from suds_ros.core.recording import Recording

EPILOG = """\
What the live monitor (`ros2 run suds_ros monitor`) would have said had it watched this
recording: per channel (each passive joint, xi_x, xi_y, xi_theta) the equation error of the
nominal physics over 0.1 s windows, as mean square over the last gait cycle divided by its
noise floor (F; WARN above 4, ERROR above 8), every 10 samples from the first report on (after
3 gait cycles).  The nominal physics is the system's (--system, or the bag's metadata) or a
robot model file's (--model).

Printed per channel: the worst level reached, the stamps of the first WARN (or worse) and of
the first ERROR, in seconds after the recording's first stamp, the largest F, and the reports at
STALE.  A channel is STALE, not OK, when lost messages leave too few clean windows to test it
(fewer than half a cycle's worth over the kept history) or no noise floor could be measured;
STALE ranks between OK and WARN.  --json prints one object:
  {"worst": "OK"|"STALE"|"WARN"|"ERROR",
   "channels": {name: {"worst": ..., "first_warn_s": s or null, "first_error_s": s or null,
                       "stale_reports": n}}}

examples:
  suds monitor run.mcap
  suds monitor run.mcap --system swimmer9 --json
  suds monitor run.mcap --model robot.yaml
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``monitor`` on the ``suds`` subcommand parser."""
    p = subparsers.add_parser(
        "monitor",
        help="replay the live mismatch monitor over a recording: the level each channel reached, and when",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_bag_argument(p)
    p.add_argument("--json", action="store_true", help="print one JSON object (levels and first stamps)")
    add_recording_options(p)
    p.set_defaults(func=run)


def nominal_system(rec: Recording, args: argparse.Namespace, model: object) -> SudsSystem:
    """The nominal physics: the model file's chain, else the recording's system id (``--system`` wins)."""
    from suds_ros.core.physics.rft import ChainModel, RFTChain
    from suds_ros.core.physics.systems import load_system

    if isinstance(model, ChainModel):
        return RFTChain(model)
    return load_system(args.system or rec.system)


def check_joints(rec: Recording, system: SudsSystem) -> None:
    """The recording must hold the system's joints, with the same ones actuated.

    Raises
    ------
    SudsDataError
        (code ``wrong_joint_names``) naming the missing joints or the differing roles.
    """
    names = tuple(system.joint_names)
    missing = [n for n in names if n not in rec.joint_names]
    if missing:
        raise SudsDataError(f"the recording's joints {list(rec.joint_names)} lack {missing} of system "
                            f"{system.name!r} (joints {list(names)})", code=WRONG_JOINT_NAMES)
    actuated = {names[i] for i in system.actuated}
    if rec.actuated and set(rec.actuated) != actuated:
        raise SudsConfigError(f"the recording's actuated joints {sorted(rec.actuated)} differ from those of "
                              f"system {system.name!r}: {sorted(actuated)}", code=WRONG_JOINT_NAMES)


def run(args: argparse.Namespace) -> int:
    """Execute ``suds monitor``; returns the exit code."""
    from suds_ros.core.diagnosis.monitor import LAG_SHARE, monitor_recording, recording_config

    rec, model = load_recording_and_model(args.bag, args)
    system = nominal_system(rec, args, model)
    check_joints(rec, system)
    gait_hz = rec.gait_hz or getattr(getattr(system, "model", None), "gait_hz", None)
    config = recording_config(rec, gait_hz)
    record = monitor_recording(rec, system, config)
    origin = float(min(rec.t[0], rec.pose_t[0]))
    if args.json:
        print(json_text.dumps(record.to_dict(origin)))
        return 0

    def when(stamp: float | None) -> str:
        return "-" if stamp is None else f"{stamp - origin:.2f} s"

    span = (float(rec.t[-1]) - float(rec.t[0])) * config.gait_hz
    first = record.first_report
    print(f"{args.bag}: system {system.name}, {span:.1f} gait cycles at {config.gait_hz:g} Hz, shape "
          f"{config.rate:g} Hz; first report at {when(first)}, {record.updates} reports "
          f"(WARN F > {config.warn:g}, ERROR F > {config.error:g})")
    width = max(len("channel"), *(len(c.channel) for c in record.channels))
    print(f"  {'channel':<{width}}  {'level':<5}  {'first WARN':>10}  {'first ERROR':>11}  {'max F':>8}  "
          f"{'STALE':>5}")
    for c in record.channels:
        print(f"  {c.channel:<{width}}  {c.worst_name:<5}  {when(c.first_warn):>10}  {when(c.first_error):>11}  "
              f"{c.max_statistic:8.3g}  {c.stale:>5}")
    stale = max((c.stale for c in record.channels), default=0)
    if stale:
        print(f"{stale} of {record.updates} reports STALE: too few windows free of lost messages to test a channel "
              f"(`suds diagnose` uses the whole recording)")
    lag = record.lag
    if lag is not None and lag.score > config.warn and lag.share >= LAG_SHARE:
        print(f"the body channels' misfit is mostly ({100 * lag.share:.0f} %) what a pose stream "
              f"{1e3 * lag.seconds:+.2f} ms late on the shape stream leaves (score {lag.score:.3g}): check the "
              f"streams' stamps (`suds diagnose` tells a lag from other causes)")
    if record.stamped_late is not None:
        left = (f"; {record.unconfirmed} samples before that were left out while its count of a heavily jittered "
                f"stream was unconfirmed" if record.unconfirmed else "")
        print(f"the shape stamps look stamped late (each value on the device's clock, the jitter in the stamps "
              f"alone: a host stamping messages as they arrive): the monitor's grid stage took each shape sample "
              f"at its grid point from {when(record.stamped_late)} on{left}; the statistics allow for that time "
              f"base's own uncertainty, but the shape stream's mean delay cannot be told from its stamps, so a "
              f"misfit of the body channels may be that delay against the pose stream (README, 'Stamped late')")
    print(f"worst: {record.to_dict()['worst']}")
    return 0
