"""The live monitor under heavy stamp jitter: nominal runs and a fault, before and after two changes.

The monitor replays each shape interval with the drive bent at its set-point times, the points of
the grid fitted to the shape stamps (`core/diagnosis/monitor.drive_kinks`).  Until 2026-12-05 the
angle at a bend was the sample's own, moved along the chord to its neighbour sample ('before',
emulated here); with 2–3 ms of jitter on a 100 Hz stream that chord often holds the neighbour's
bend too, and the replayed drive missed by more than the sensor noise.  Now the angle is the value
of the least-squares linear spline with its knots on the grid (`core/resample.knot_fit`).  And a
lost sample was an interval longer than 1.5 periods on the stamps, which jitter alone makes (with
3 ms at 100 Hz one interval in eight): now it is counted on the grid (`lost_samples`).  Lab
recordings (pose 120 Hz from 3.7 ms later, 1 % of each stream lost) at four levels of stamp
jitter; 12 cycles, 1 s warm-up, seeds 11 and 12; the fault of `monitor_loss.py` (a viscous damping
on a passive joint, 3× its detection limit).  Writes docs/results/monitor_jitter.md.

    python benchmarks/monitor_jitter.py
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator

import numpy as np

from _common import machine, stamp, write
from monitor_delay import to_error
from monitor_loss import FAULTS, SEEDS, record

import suds_ros.core.diagnosis.monitor as monitor_mod
from suds_ros.core.diagnosis.monitor import LEVEL_NAMES, Kinks, MonitorRecord, bends
from suds_ros.core.physics.lab import LabConditions
from suds_ros.core.physics.systems import load_system

JITTERS = (0.0004, 0.001, 0.002, 0.003)  # stamp jitter (standard deviation), s
LOSS = LabConditions().drop  # messages lost per stream: the lab default


def chord_kinks(t: np.ndarray, ra: np.ndarray, grid: np.ndarray, period: float) -> Kinks:
    """The rule before: each bend's angle is its sample's, moved along the chord to the neighbour on the bend's side."""
    eps = t - grid
    fwd = np.diff(ra, axis=0) / np.diff(t)[:, None]  # chord j → j + 1
    slope = np.where((eps[1:-1] > 0)[:, None], fwd[1:], fwd[:-1])  # samples 1 … n − 2
    return bends(t, ra, grid, period, ra[1:-1] - eps[1:-1, None] * slope)


def stamp_gaps(t: np.ndarray, grid: np.ndarray, gap: float) -> np.ndarray:
    """The rule before: an interval longer than ``gap`` s on the stamps holds a lost sample."""
    return np.diff(t) > gap


@contextlib.contextmanager
def old_rule() -> Iterator[None]:
    """Both rules before 2026-12-05: bends along the chord, lost samples from the stamps' intervals."""
    saved = monitor_mod.drive_kinks, monitor_mod.lost_samples
    try:
        monitor_mod.drive_kinks, monitor_mod.lost_samples = chord_kinks, stamp_gaps
        yield
    finally:
        monitor_mod.drive_kinks, monitor_mod.lost_samples = saved


def cells(mon: MonitorRecord) -> str:
    """Worst level, the channel with the largest F and that F, cycles from the first report to ERROR."""
    top = max(mon.channels, key=lambda c: c.max_statistic)
    err = to_error(mon, 1.0)
    return (f"{LEVEL_NAMES[mon.worst]} | {top.channel} {top.max_statistic:.3g} | "
            f"{'—' if err is None else f'{err:.1f}'}")


def main() -> None:
    t0 = time.perf_counter()
    lines = ["| robot | case | jitter ms | seed | before: worst | before: largest F | before: to ERROR "
             "| now: worst | now: largest F | now: to ERROR |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for name, fault in FAULTS.items():
        system = load_system(name)
        for case, effects in (("nominal", []), (f"{fault['name']} {fault['joint']} d = {fault['d']}", [fault])):
            for jitter in JITTERS:
                for seed in SEEDS:
                    with old_rule():
                        before = record(system, list(effects), 12, LOSS, seed, jitter=jitter)
                    now = record(system, list(effects), 12, LOSS, seed, jitter=jitter)
                    lines.append(f"| {name} | {case} | {1e3 * jitter:g} | {seed} | {cells(before)} | {cells(now)} |")
                    print(lines[-1], flush=True)
    rows = [ln.split("|") for ln in lines[2:]]
    nominal = [r for r in rows if r[2].strip() == "nominal"]
    faulty = [r for r in rows if r[2].strip() != "nominal"]
    calm = [sum(r[i].strip() != "OK" for r in nominal) for i in (5, 8)]
    caught = [sum(r[i].strip() == "ERROR" for r in faulty) for i in (5, 8)]
    text = "\n".join([
        "# The live monitor under heavy stamp jitter", "",
        f"Measured {stamp()} on {machine()} by `python benchmarks/monitor_jitter.py` "
        f"({(time.perf_counter() - t0) / 60:.1f} min).", "",
        "Lab recordings (shape 100 Hz read at its set-point times plus Gaussian stamp jitter of the given standard "
        "deviation, clipped at 0.4 periods; pose 120 Hz from 3.7 ms later with the same jitter; 1 % of each "
        "stream lost; 12 cycles, 1 s warm-up), monitored against the nominal physics with the default settings "
        "(windows of 10 intervals, WARN F > 4, ERROR F > 8).  The replay bends the drive at the grid points "
        "fitted to the shape stamps; *before*: each bend's angle is its sample's moved along the chord to the "
        "neighbour sample (the rule until 2026-12-05, emulated in the same process); *now*: the least-squares "
        "linear spline of the samples with its knots on the grid (`core/resample.knot_fit`).  *to ERROR*: cycles "
        "from the first report to the first ERROR on any channel.  The fault: a viscous damping on a passive "
        "joint from the first sample, 3× its detection limit (`docs/results/monitor.md`).", "",
        *lines, "",
        f"Nominal runs not OK (WARN, ERROR or STALE): {calm[0]} of {len(nominal)} before, {calm[1]} of "
        f"{len(nominal)} now.  Runs with the fault in ERROR: {caught[0]} of {len(faulty)} before, {caught[1]} of "
        f"{len(faulty)} now.", "",
        "How to read it: with 0.4 ms of jitter (the lab default) the two readings agree to within the noise and "
        "so do the rows.  With 2–3 ms a sample is often a fifth to a third of a period off its set-point time: "
        "the chord to its neighbour then spans the neighbour's bend as well, and the replayed drive was off by "
        "one to two times the sensor noise, which swimmer9's stiff passive joints, following their drive within "
        "a sample, showed as WARN; and with 3 ms one interval in eight is longer than 1.5 periods with nothing "
        "lost, so purcell3's windows were mostly 'unclean' and the channels STALE.  The spline fits the drive's "
        "bends from every sample around them, and the grid counts a lost message only where one is.", ""])
    write("monitor_jitter.md", text)


if __name__ == "__main__":
    main()
