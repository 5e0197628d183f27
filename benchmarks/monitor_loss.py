"""The live monitor when many messages are lost: nominal runs and a fault, before and after STALE.

The monitor scores a channel on windows of ``diff_window`` intervals with no lost message in or
next to them.  Until the evening of 2026-12-05 it took the mean square over the clean windows of the last cycle
however few there were (F = 0, OK, when there were none), and measured its noise floor from
however few runs of four clean intervals it found.  With 20 % of each stream lost a window of ten
intervals is clean about one time in twenty: F then rested on two or three windows and a floor
from a handful of fourth differences, and a nominal robot went to ERROR, or a broken one to OK.
Now a statistic needs half a cycle's worth of clean windows, reaching back into the kept history
for them, and a floor needs ``FLOOR_LEAST`` fourth differences; with fewer the channel is STALE.
'before' emulates the old rule in the same process.  Lab recordings (pose 120 Hz from 3.7 ms
later, 0.4 ms jitter), each stream losing the given share of its messages at random; 12 cycles,
1 s warm-up, seeds 11 and 12.  Writes docs/results/monitor_loss.md.

    python benchmarks/monitor_loss.py
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from dataclasses import replace

import numpy as np

from _common import machine, stamp, write
from monitor_delay import to_error

import suds_ros.core.diagnosis.monitor as monitor_mod
from suds_ros.core.diagnosis.monitor import LEVEL_NAMES, MonitorRecord, monitor_recording, recording_config
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.lab import LabConditions, simulate_lab
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.sim import SimConfig
from suds_ros.core.physics.system import SudsSystem
from suds_ros.core.physics.systems import load_system

LOSSES = (0.01, 0.05, 0.1, 0.2, 0.3)
SEEDS = (11, 12)
#: the longer history of the second table: its cycles, and the losses it is tried at
LONG = 30
LONG_LOSSES = (0.2, 0.3)
#: a fault from the first sample, 3× its detection limit (docs/results/monitor.md)
FAULTS = {"purcell3": {"name": "joint_viscous_damping", "joint": "joint_2", "d": 0.009},
          "swimmer9": {"name": "joint_viscous_damping", "joint": "joint_7", "d": 0.03}}


@contextlib.contextmanager
def old_rule() -> Iterator[None]:
    """The old rule: any number of clean windows (none: F = 0), a floor from any fourth differences, no lower bound.

    Emulated, not the old code: a floor that cannot be measured at all keeps the one before, as now.
    """
    saved = (monitor_mod.MismatchMonitor._scored, monitor_mod.FLOOR_LEAST, monitor_mod.FLOOR_RELATIVE)

    def scored(self: object, ready: int, E: np.ndarray, win_ok: np.ndarray, span: int) -> tuple[np.ndarray, int]:
        return E[-span:][win_ok[-span:]], 0

    try:
        monitor_mod.MismatchMonitor._scored = scored  # type: ignore[method-assign]
        monitor_mod.FLOOR_LEAST, monitor_mod.FLOOR_RELATIVE = 1, 0.0
        yield
    finally:
        (monitor_mod.MismatchMonitor._scored, monitor_mod.FLOOR_LEAST,  # type: ignore[method-assign]
         monitor_mod.FLOOR_RELATIVE) = saved


def record(system: SudsSystem, effects: list[dict[str, object]], cycles: int, loss: float, seed: int,
           history: float | None = None, jitter: float = LabConditions().jitter) -> MonitorRecord:
    """Simulate ``system`` with ``effects`` from the first sample, the lab way, and monitor it against the nominal.

    Each stream loses ``loss`` of its messages; stamps have ``jitter`` s of jitter.
    """
    sim = RFTChain(apply_effects(system.model, effects)[0]) if effects else system  # type: ignore[attr-defined]
    rec = simulate_lab(sim, SimConfig(cycles=cycles, seed=seed, warmup=1.0), LabConditions(drop=loss, jitter=jitter))
    cfg = recording_config(rec)
    return monitor_recording(rec, system, cfg if history is None else replace(cfg, history_cycles=history))


def cells(mon: MonitorRecord, old: bool) -> tuple[str, str, str, str]:
    """Worst level, reports STALE, largest F, cycles from the first report to ERROR."""
    stale = max(c.stale for c in mon.channels)
    top = max(mon.channels, key=lambda c: c.max_statistic)
    err = to_error(mon, 1.0)
    worst = LEVEL_NAMES[mon.worst]
    if old and worst == "STALE":  # the old rule had no STALE: a channel without windows read F = 0, OK
        worst = "OK"
    largest = "—" if top.max_statistic == 0.0 else f"{top.channel} {top.max_statistic:.3g}"  # 0: never tested
    return worst, "—" if old else f"{stale}/{mon.updates}", largest, "—" if err is None else f"{err:.1f}"


def cases(losses: tuple[float, ...]) -> Iterator[tuple[str, SudsSystem, str, list[dict[str, object]], float, int]]:
    """Every robot, nominal and with its fault, at every loss and seed: (name, system, case, effects, loss, seed)."""
    for name, fault in FAULTS.items():
        system = load_system(name)
        for case, effects in (("nominal", []), (f"{fault['name']} {fault['joint']} d = {fault['d']}", [fault])):
            for loss in losses:
                for seed in SEEDS:
                    yield name, system, case, list(effects), loss, seed


def main() -> None:
    t0 = time.perf_counter()
    lines = ["| robot | case | lost per stream | seed | before: worst | before: largest F | before: to ERROR "
             "| now: worst | now: STALE reports | now: largest F | now: to ERROR |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, system, case, effects, loss, seed in cases(LOSSES):
        with old_rule():
            before = record(system, effects, 12, loss, seed)
        b = cells(before, True)
        lines.append(f"| {name} | {case} | {100 * loss:.0f} % | {seed} | {b[0]} | {b[2]} | {b[3]} | "
                     f"{' | '.join(cells(record(system, effects, 12, loss, seed), False))} |")
        print(lines[-1], flush=True)
    longer = ["| robot | case | lost per stream | seed | worst | STALE reports | largest F | to ERROR |",
              "|---|---|---|---|---|---|---|---|"]
    for name, system, case, effects, loss, seed in cases(LONG_LOSSES):
        mon = record(system, effects, LONG, loss, seed, history=float(LONG))
        longer.append(f"| {name} | {case} | {100 * loss:.0f} % | {seed} | {' | '.join(cells(mon, False))} |")
        print(longer[-1], flush=True)
    text = "\n".join([
        "# The live monitor when many messages are lost", "",
        f"Measured {stamp()} on {machine()} by `python benchmarks/monitor_loss.py` "
        f"({(time.perf_counter() - t0) / 60:.1f} min).", "",
        "Lab recordings (shape 100 Hz, pose 120 Hz from 3.7 ms later, 0.4 ms stamp jitter; 12 cycles, 1 s warm-up), "
        "each stream losing the given share of its messages at random, monitored against the nominal physics "
        "(`core/diagnosis/monitor.py`, default settings: windows of 10 intervals, WARN F > 4, ERROR F > 8).  "
        "*before*: the rule until the evening of 2026-12-05, emulated in the same process (the mean square over "
        "whatever clean windows the last cycle had, F = 0 and OK with none; a noise floor from any number of "
        "fourth differences and no lower bound; a floor that cannot be measured at all keeps the one before, as "
        "now).  "
        "*now*: a statistic needs half a cycle's worth of clean windows (50), taken from the kept history (12 "
        "cycles) when the last cycle has too few, and a noise floor needs "
        f"{monitor_mod.FLOOR_LEAST} fourth differences; otherwise the channel is STALE.  *STALE reports*: of the "
        "run's reports, the most at STALE on one channel.  *to ERROR*: cycles from the first report to the first "
        "ERROR on any channel.  The fault: a viscous damping on a passive joint from the first sample, 3× its "
        "detection limit (`docs/results/monitor.md`).", "",
        *lines, "",
        f"## A longer history ({LONG} cycles kept, `history_cycles`), {LONG}-cycle recordings", "",
        "The statistic and the floor reach back as far as the history goes, so a longer history lets the monitor "
        "test a robot that loses more, later.  Columns as above.", "",
        *longer, "",
        "How to read it: a window of 10 intervals is clean only when none of its 12 shape intervals and neither "
        "end's pose read spans a lost message, about 0.9^12 ≈ 28 % of them with 10 % lost per stream and "
        "0.8^12 ≈ 7 % with 20 %.  With fewer clean windows than the statistic needs the monitor cannot test "
        "the robot, and says so (STALE, the diagnostic_msgs level for 'no current data') instead of OK or a "
        "false ERROR; `suds diagnose` on the recording uses all of it (`docs/results/frame_loss.md`).", ""])
    write("monitor_loss.md", text)


if __name__ == "__main__":
    main()
