"""A shape stream stamped late, not read late: values on the device's clock, jitter in the stamps alone.

A host that stamps each joint-state message as it arrives from a device sampling on its own regular
clock (a serial encoder, a USB servo bus) gives the values of the device's ticks with stamps that
carry the transport's varying delay.  The grid stage fitted each value at its stamp (right for a
host that *reads* the joints at irregular times and stamps each reading, the contract's stamps and
the lab recordings'), so there it moved every value by the delay.  `core/resample.values_on_grid`
now tells the two apart from the data (Δr over an interval follows the stamps' Δt when read late,
the grid step when stamped late) and takes a stamped-late stream's values at their grid points, in
the batch grid (`on_shape_grid`) and the live one (`LiveGrid`, mode ``snap``).

Here: lab recordings stamped on arrival (`LabConditions(stamping="arrival")`: pose 120 Hz from 3.7 ms
later, 1 % of each stream lost, 60 cycles: 40 train / 20 held out; each shape value at its tick, each
stamp the tick plus Gaussian jitter clipped at 0.4 periods).  Every
model is scored on the held-out cycles with their true (unjittered) stamps.  *before*: the grid as it
was (values at their stamps; `SNAP_SIGMAS` = inf).  A second table counts how often the lab
recordings themselves (read late) were taken for stamped late; a third gives the live monitor's
statistics on nominal 12-cycle runs stamped on arrival, with and without a mean delay.  Writes
docs/results/stamped_late.md.

    python benchmarks/stamped_late.py [--systems purcell3 swimmer9] [--seeds 0 1]
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from _common import machine, stamp, write

import suds_ros.core.resample as resample
from suds_ros.core.diagnosis.monitor import ERROR, WARN, monitor_recording
from suds_ros.core.errors import SudsDataError
from suds_ros.core.ident.identify import IdentifyConfig, SudsIdentifier, split_cycles
from suds_ros.core.ident.online import OnlineConfig, fit_streaming
from suds_ros.core.ident.predictor import evaluate_model
from suds_ros.core.ident.scoring import score_prediction
from suds_ros.core.physics.lab import LabConditions, simulate_lab
from suds_ros.core.physics.sim import SimConfig
from suds_ros.core.physics.systems import make_system

JITTERS = (0.0004, 0.001, 0.002, 0.003)  # stamp delay jitter, s
SNAP = resample.SNAP_SIGMAS


def stamped_late(system: object, seed: int, jitter: float) -> tuple[object, object]:
    """(the recording stamped on arrival, the same recording on its true stamps: the same values at the ticks)."""
    config = SimConfig(cycles=60, seed=seed)
    late = simulate_lab(system, config, LabConditions(jitter=jitter, stamping="arrival"))  # type: ignore[arg-type]
    rec = simulate_lab(system, config, LabConditions(jitter=0.0))  # type: ignore[arg-type]
    return replace(late, truth={}), rec


MONITOR_JITTERS = (0.001, 0.002, 0.003)
LATENCIES = (0.0, 0.002)  # the transport's mean delay, s


def monitor_run(system: object, seed: int, jitter: float, latency: float) -> dict[str, tuple[float, float, float]]:
    """The monitor on a nominal 12-cycle run stamped on arrival: (largest F passive, largest F body, lag ms)."""
    rec = simulate_lab(system, SimConfig(cycles=12, seed=seed),  # type: ignore[arg-type]
                       LabConditions(jitter=jitter, stamping="arrival", latency=latency))
    out = {}
    for label, snap in (("before", float("inf")), ("now", SNAP)):
        resample.SNAP_SIGMAS = snap
        try:
            record = monitor_recording(rec, system)  # type: ignore[arg-type]
        finally:
            resample.SNAP_SIGMAS = SNAP
        passive = max(c.max_statistic for c in record.channels if c.channel.startswith("joint"))
        body = max(c.max_statistic for c in record.channels if c.channel.startswith("xi"))
        lag = 1e3 * record.lag.seconds if record.lag is not None else float("nan")
        out[label] = (passive, body, lag)
    return out


def nominal_sweep(systems: list[str], seeds: int) -> list[str]:
    """Markdown rows: the monitor as shipped on nominal 12-cycle runs stamped on arrival, no latency, many seeds."""
    rows = ["| system | jitter ms | seeds | largest F passive | largest F body | runs with WARN or worse | "
            "samples left out (median) | the lag's score ≥ 4 | runs without a report |",
            "|---|---|---|---|---|---|---|---|---|"]
    for name in systems:
        system = make_system(name)
        for jitter in MONITOR_JITTERS:
            out, silent = [], 0
            for seed in range(seeds):
                rec = simulate_lab(system, SimConfig(cycles=12, seed=seed),  # type: ignore[arg-type]
                                   LabConditions(jitter=jitter, stamping="arrival"))
                try:
                    record = monitor_recording(rec, system)  # type: ignore[arg-type]
                except SudsDataError:  # too few samples once the unconfirmed ones are left out: no report
                    silent += 1
                    continue
                passive = max((c.max_statistic for c in record.channels if c.channel.startswith("joint")),
                              default=0.0)
                body = max(c.max_statistic for c in record.channels if c.channel.startswith("xi"))
                lag = record.lag.score if record.lag is not None else 0.0
                out.append((passive, body, record.worst in (WARN, ERROR), record.unconfirmed, lag >= 4.0))
            x = np.array(out, dtype=float).reshape(-1, 5)
            if not x.size:
                rows.append(f"| {name} | {1e3 * jitter:g} | {seeds} | — | — | — | — | — | {silent} |")
                continue
            rows.append(f"| {name} | {1e3 * jitter:g} | {seeds} | {x[:, 0].max():.1f} | {x[:, 1].max():.1f} | "
                        f"{int(x[:, 2].sum())} | {np.median(x[:, 3]):.0f} | {int(x[:, 4].sum())} | {silent} |")
            print(rows[-1], flush=True)
    return rows


def monitor_table(systems: list[str], seeds: list[int]) -> list[str]:
    """Markdown rows of :func:`monitor_run` over systems, jitters, latencies (worst over the seeds)."""
    rows = ["| system | jitter ms | latency ms | before: F passive / F body / lag ms | "
            "now: F passive / F body / lag ms |", "|---|---|---|---|---|"]
    for name in systems:
        system = make_system(name)
        for jitter in MONITOR_JITTERS:
            for latency in LATENCIES:
                runs = [monitor_run(system, seed, jitter, latency) for seed in seeds]
                cells = []
                for label in ("before", "now"):
                    x = np.array([r[label] for r in runs])
                    lags = ", ".join(f"{v:+.2f}" for v in x[:, 2])
                    cells.append(f"{x[:, 0].max():.1f} / {x[:, 1].max():.1f} / {lags}")
                rows.append(f"| {name} | {1e3 * jitter:g} | {1e3 * latency:g} | " + " | ".join(cells) + " |")
                print(rows[-1], flush=True)
    return rows


def fits(train: object, truth_test: object) -> dict[str, tuple[float, float, str]]:
    """Γ body, Γ passive on the true stamps, and the grid's verdict, per method."""
    out: dict[str, tuple[float, float, str]] = {}
    for label, snap in (("before", float("inf")), ("now", SNAP)):
        resample.SNAP_SIGMAS = snap
        try:
            snapped = resample.Grid.of(train).snapped  # type: ignore[arg-type]
            s = SudsIdentifier(IdentifyConfig()).fit(train).scores(truth_test)  # type: ignore[arg-type]
            out[f"batch {label}"] = (s.gamma_body, s.gamma_passive, "snap" if snapped else "grid")
            est = fit_streaming(train, OnlineConfig())  # type: ignore[arg-type]
            s = score_prediction(evaluate_model(est.model(), truth_test))  # type: ignore[arg-type]
            out[f"streaming {label}"] = (s.gamma_body, s.gamma_passive, est.regrid.mode)  # type: ignore[union-attr]
        finally:
            resample.SNAP_SIGMAS = SNAP
    est = fit_streaming(train, OnlineConfig(regrid=False))  # type: ignore[arg-type]
    s = score_prediction(evaluate_model(est.model(), truth_test))  # type: ignore[arg-type]
    out["streaming raw"] = (s.gamma_body, s.gamma_passive, "off")
    return out


COLUMNS = ("batch before", "batch now", "streaming raw", "streaming before", "streaming now")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--systems", nargs="+", default=["purcell3", "swimmer9"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1])
    ap.add_argument("--sweep-seeds", type=int, default=16, help="seeds 0 … N − 1 of the monitor's nominal sweep")
    args = ap.parse_args()
    t0 = time.perf_counter()
    lines = ["| system | jitter ms | " + " | ".join(COLUMNS) + " | verdict (batch; live) |",
             "|---|---|" + "---|" * (len(COLUMNS) + 1)]
    false = ["| system | jitter ms | recordings | taken for stamped late (batch) | (live) |", "|---|---|---|---|---|"]
    for name in args.systems:
        system = make_system(name)
        for jitter in JITTERS:
            runs = []
            wrong_batch = wrong_live = 0
            for seed in args.seeds:
                late, rec = stamped_late(system, seed, jitter)
                train, _ = split_cycles(late, 40, 20)
                _, truth_test = split_cycles(rec, 40, 20)
                runs.append(fits(train, truth_test))
                print(name, jitter, seed, {k: tuple(np.round(v[:2], 3)) + (v[2],) for k, v in runs[-1].items()},
                      flush=True)
                lab = simulate_lab(system, SimConfig(cycles=60, seed=seed),  # type: ignore[arg-type]
                                   LabConditions(jitter=jitter))
                lab_train, _ = split_cycles(lab, 40, 20)
                wrong_batch += resample.Grid.of(lab_train).snapped
                wrong_live += fit_streaming(lab_train, OnlineConfig()).regrid.mode == "snap"  # type: ignore[union-attr]
            cells = []
            for c in COLUMNS:
                g = np.array([r[c][:2] for r in runs])
                cells.append(f"{g[:, 0].mean():.3f} / {g[:, 1].mean():.3f}")
            verdict = "; ".join(", ".join(sorted({r[c][2] for r in runs})) for c in ("batch now", "streaming now"))
            lines.append(f"| {name} | {1e3 * jitter:g} | " + " | ".join(cells) + f" | {verdict} |")
            false.append(f"| {name} | {1e3 * jitter:g} | {len(args.seeds)} | {wrong_batch} | {wrong_live} |")
            print(lines[-1], false[-1], flush=True)
    monitor = monitor_table(args.systems, args.seeds)
    sweep = nominal_sweep(args.systems, args.sweep_seeds)
    text = "\n".join([
        "# A shape stream stamped late: values on the device's clock", "",
        f"Measured {stamp()} on {machine()} by `python benchmarks/stamped_late.py` (seeds {args.seeds}, "
        f"{time.perf_counter() - t0:.0f} s).", "",
        "Lab recordings stamped on arrival (`LabConditions(stamping=\"arrival\")`, `suds simulate --stamped-late`: "
        "shape 100 Hz with its values at the nominal ticks and each stamp its tick plus Gaussian jitter of the "
        "given standard deviation, clipped at 0.4 periods; pose 120 Hz from 3.7 ms later, read at its own "
        "jittered stamps; 1 % of each stream lost; 60 cycles, 40 train / 20 held out).  Cells: Γ body / "
        "Γ passive on the held-out cycles at their true stamps, means over the seeds.  *batch*: `suds identify`; "
        "*streaming*: "
        "the estimator node's algorithm; *raw*: `regrid` off; *before*: the grid stage fitting each value at "
        "its stamp (as until 2026-12-05); *now*: the stage as shipped, which judges from the data whether the "
        "values belong to their stamps or to their grid points (`core/resample.values_on_grid`).  Verdict: "
        "snap = taken at the grid points; grid = at the stamps.", "",
        *lines, "",
        "## Recordings read late (the contract's stamps), taken for stamped late", "",
        "The same systems and seeds recorded the lab way (`core/physics/lab.py`: each value read at its "
        "stamp, the stamps jittered as above), judged on their 40 training cycles.", "",
        *false, "",
        "How to read it: on a stream stamped late, fitting each value at its stamp moves it by the delay, and"
        " the model learns from intervals that are wrong by the difference of two delays: worse than the raw "
        "intervals once the jitter is a few per cent of the period.  Taken at its grid point each value is "
        "what the device sampled, and the model comes back to what the undelayed stream gives (the streaming "
        "estimator judges first on its 256-sample lock block and then every 128 samples, so its first rows "
        "may still be fitted at their stamps).  From 40 cycles 0.4 ms is recognised in three runs of four "
        "(the two readings then differ by 0.004 in Γ or less); from the lock block alone (2.5 cycles) it "
        "takes 1–2 ms.  At 3 ms (a standard deviation of 0.3 periods) a lock block of 256 stamps is too short"
        " for the phase search: on some seeds a peak of its noise beat the true step (a step 9 % long on the "
        "stamps of the first version of this table), and the live line kept that count.  Since 2026-12-06 the"
        " block doubles, up to 1024 stamps, while its peak is not clear (`core/resample.phase_search`, "
        "`LOCK_CLEAR`).",
        "",
        "## The live monitor on the same kind of stream",
        "",
        "A nominal robot, 12 cycles, stamped on arrival with the given jitter and the transport's mean delay "
        "(latency), pose read at its own stamps; `suds monitor` (the node's `MismatchMonitor`).  Cells: the "
        "largest F of the passive-joint channels and of the body channels over the run (WARN above 4, ERROR "
        "above 8), worst over the seeds, and the lag statistic's estimate per seed (the pose stream's lag "
        "behind the shape stream; a shape stream 2 ms late reads −2).  *before*: the samples timed at their "
        "stamps (as until 2026-12-06); *now*: the monitor as shipped: at their grid points once its grid stage "
        "judges the stream stamped late, and the statistics allowing for that time base's own uncertainty.",
        "",
        *monitor, "",
        "### Nominal runs, no latency, more seeds (the monitor as shipped)",
        "",
        "A false alarm here is a nominal robot called wrong.  *samples left out*: shape samples the monitor "
        "never compared, over the runs with a report: timed on a count of its grid stage that came from a "
        "phase lock (heavy jitter) and that a recount then replaced (samples timed on a count a recount "
        "confirms are held till then and compared); *runs without a report*: no recount confirmed the count "
        "in 12 cycles (a lock block of up to 1024 stamps, then 256 more; `suds monitor` then says so; the "
        "other columns leave them out).",
        "",
        *sweep, "",
        "How to read it: the passive-joint channels compare the shape stream with itself, so once its "
        "samples are timed at their ticks they are clean whatever the delay.  The body channels compare it "
        "with the pose stream, and there a shape stream's mean delay is a real lag between the streams that "
        "its own stamps cannot reveal: a 2 ms latency is measured as such (the lag column).  The time base "
        "itself is an estimate: its offset is known to about twice the jitter over the square root of the "
        "stamps (`LiveGrid.offset_se`, 70 µs at 1 ms and about 200 µs at 3 ms over the last 8 of 12 cycles), "
        "and swimmer9's body channels see lags of 20 µs.  So the phase-coherent statistic first takes out "
        "the lag and clock stretch such a time base can leave, within 4 of those standard errors "
        "(`core/diagnosis/monitor.time_base_misfit`), and the windowed one an offset of the shape stream "
        "against the poses within as many (`MismatchMonitor._time_base`; the line's error wanders with the "
        "stamps: one nominal swimmer9 at 2 ms had it 560 µs off for a second, 3.4 standard errors, body F "
        "4.2 before), and each scores what exceeds them: a real delay shows by "
        "its excess, weaker where the jitter is heavy (the 2 ms latency rows at 3 ms against those at 1 ms). "
        " Before that (the monitor of 2026-12-06 early, the same runs, seeds 0–14), nominal swimmer9 runs "
        "at 1 ms went to WARN or ERROR on 5 of 15 seeds (body F up to 9.2 from a time base 130 µs off; "
        "passive F up to 6.9 from bends the monitor put some µs off the samples), and at 3 ms a lock one "
        "count off slipped a step every few hundred samples (body F 6–7).",
        ""])
    write("stamped_late.md", text)


if __name__ == "__main__":
    main()
