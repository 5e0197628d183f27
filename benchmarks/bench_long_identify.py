"""Peak memory and wall time of ``suds identify`` on long recordings (issue 19's one-hour target).

Each run is a fresh process ``python -m suds_ros.cli.main identify BAG --train-cycles N/2
--test-cycles N/2 --json`` (N defaults to every whole cycle the bag holds); its peak resident
memory is the child's own ``ru_maxrss`` (``os.wait4``), so nothing else in this process counts.
The machine's load averages at the end of each run are recorded beside it: on a machine shared
with other work the wall times grow with the load.

    python benchmarks/bench_long_identify.py s9_part.mcap:669 s9_hour_tiled.mcap:3600
    python benchmarks/bench_long_identify.py s9_240.mcap:240 --compare /tmp/old-checkout --append
    python benchmarks/bench_long_identify.py s9_part.mcap:669 --breakdown --append

``--compare SRC`` runs the same recordings with the code of another checkout (before/after).
``--breakdown`` also runs the first recording once under cProfile and tabulates where the wall
time of that run went (cumulative times of the pipeline's stages; the profiler itself slows the
Python-heavy stages).  Make the recordings first: ``suds simulate swimmer9 -o s9.mcap --cycles N
--rate 1000``, or tile a shorter one in time with ``benchmarks/tile_recording.py`` (say so).
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import ROOT, machine, stamp, write  # noqa: E402

#: the stages of ``suds identify`` tabulated by ``--breakdown``: (name, module path end, function)
STAGES = [
    ("read the bag", "io/recording_bag.py", "read_recording_report"),
    ("fit on the training cycles (the next four rows but the held-out phase)", "core/ident/identify.py", "fit"),
    ("· phase of the training and the held-out cycles (phaser fit, transform)", "core/ident/identify.py", "_phase"),
    ("· first pass: interval data, output template, the selection's rows", "core/ident/identify.py", "_block_data"),
    ("· model selection (cross-validation)", "core/ident/identify.py", "_select_model"),
    ("· second pass: regression on every training row", "core/ident/sysid.py", "partial_fit"),
    ("held-out scores (their phase included)", "core/ident/identify.py", "scores"),
]

#: ``--read``: the reader with each decoder in a fresh process (the others switched off for the run)
READ_SNIPPET = """
import sys, time
from suds_ros.io import cdr, recording_bag
how = sys.argv[2]
if how != "arrays":  # no chunk-at-a-time decoding: one message at a time
    cdr.parse_joint_states = cdr.parse_pose_stampeds = lambda *a: None
if how == "library":  # every message through the rosbags decoder (the fallback of the fast paths)
    def refuse(*a):
        raise ValueError("off")
    recording_bag.cdr.JointStateParser = lambda: refuse
    cdr.parse_pose_stamped = refuse
t0 = time.perf_counter()
rec = recording_bag.read_recording(sys.argv[1])
print(time.perf_counter() - t0, rec.n_samples)
"""
READ_WAYS = [("arrays", "a chunk's messages of one layout at once (numpy; this commit)"),
             ("per message", "one message at a time, hand-written decoders (JointStateParser, parse_pose_stamped)"),
             ("library", "one message at a time through rosbags (`cdr.decode`)")]

NOTES = [
    "",
    "## The recordings",
    "",
    "- `s9_part.mcap`: the first 669.5 s of a one-hour 1 kHz run, `suds simulate swimmer9 -o s9_hour.mcap",
    "  --cycles 3600 --rate 1000`, stopped early (the file ends without its footer; the tolerant reader",
    "  reads every message up to there).  A simulated hour takes about half an hour of a core",
    "  (`suds simulate` speed in `docs/results/memory.md`), so the hour was tiled instead:",
    "- `s9_hour_tiled.mcap`: **tiled, not simulated**: `python benchmarks/tile_recording.py s9_part.mcap",
    "  s9_hour_tiled.mcap --tiles 6 --cycles 600` repeats the first 600 cycles of `s9_part.mcap` six",
    "  times, stamps shifted by 600 s per tile and the pose moved rigidly so that it is continuous; the",
    "  joints jump at the 5 seams (one interval each).  The same noise and drive repeat every 600",
    "  cycles, so its Γ says that the pipeline runs at this length, not how well an hour of new data",
    "  identifies the robot.",
    "- `s9_240.mcap`: an ordinary recording (`suds simulate swimmer9 --cycles 240 --seed 2`, 100 Hz): it takes",
    "  the whole-recording path, so its Γ must not change.",
    "",
    "## How",
    "",
    "Reading: the scan hands each chunk's messages of one channel to the decoder together; when they",
    "share one layout (the same encapsulation, frame id, joint names and value counts, checked byte for",
    "byte against the first message) their stamps and values are read as numpy arrays in one step",
    "(`io/cdr.py` `parse_joint_states`, `parse_pose_stampeds`), else one message at a time as before",
    "(the hand-written decoders, then rosbags).  The record offsets of a chunk whose record lengths",
    "repeat are predicted from the period and checked at once, and message-index entries are read as",
    "one array.  The recording read is the same array for array (`test/io/test_recording_bag.py`).",
    "The reading table below is why the decoders of our own stay: the library decoder (rosbags, itself",
    "faster than mcap-ros2-support on our messages, `docs/results/codec.md`) is the slowest row.",
    "",
    "Identification: a recording of more than `block_samples` samples whose pose stamps are shape",
    "stamps is processed a block of intervals at a time.  Interval data and regressor rows are made",
    "per block twice and never held whole: the first pass sums the output template's normal",
    "equations and keeps every k-th training row for the model selection (k the smallest stride",
    "leaving at most `select_max_rows` rows), the second adds every training row to the regression's",
    "normal equations.  The phaser is fitted on the first `phaser_fit_samples` samples and applied",
    "in blocks with context; the held-out cycles are scored a block at a time (`ScoreSums`).  The",
    "design matrices are written in place (one array, no concatenated copy).  Recordings of at most",
    "`block_samples` samples take the whole-recording path as before.",
    "",
    "What still grows with the recording: the `Recording` itself (t, r, pose: 13 float64 per sample)",
    "and the phase (one float64 per sample); while reading, the decoded arrays before they become the",
    "`Recording` (stamps as seconds and nanoseconds, the pose as 7 values per sample).  Bounding those",
    "would need the reader to hand blocks to the identifier as it scans.  Where the time goes is in",
    "the profiled table: after reading, the phaser's corrections (trigonometric functions of every",
    "sample, 10 harmonics per channel) and the regression's Gram matrix over every training row",
    "(n·p² with p = 719 parameters for the chosen regressor set 3) are the largest stages.",
]


def _run(cmd: list[str], src: Path) -> tuple[str, float, float]:
    """Run ``cmd`` with the package of ``src``; (stdout, wall s, peak RSS MB) from os.wait4 on the child."""
    import subprocess

    env = dict(os.environ, PYTHONPATH=str(src))
    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        proc = subprocess.Popen(cmd, env=env, stdout=out, stderr=err, cwd=src)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        if proc.returncode:
            raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{err.read().decode()}")
        return out.read().decode(), wall, usage.ru_maxrss / 1024.0  # ru_maxrss is in KiB on Linux


def _parse_run(text: str) -> tuple[Path, int | None]:
    bag, _, cycles = text.rpartition(":") if text.rpartition(":")[2].isdigit() else (text, "", "")
    return Path(bag).resolve(), int(cycles) if cycles else None


def _identify(bag: Path, cycles: int | None, info: dict) -> list[str]:
    if cycles is None:
        gait_hz = float(info.get("metadata", {}).get("suds", {}).get("gait_hz") or 1.0)
        cycles = int(info["duration_s"] * gait_hz)
    return ["identify", str(bag), "--json", "--train-cycles", str(cycles // 2),
            "--test-cycles", str(cycles - cycles // 2)]


def _breakdown(bag: Path, cycles: int | None, info: dict) -> list[str]:
    """Cumulative seconds of each stage of one profiled run of this checkout."""
    import pstats

    with tempfile.TemporaryDirectory() as tmp:
        prof = Path(tmp) / "identify.prof"
        cmd = [sys.executable, "-m", "cProfile", "-o", str(prof), "-m", "suds_ros.cli.main"] + \
            _identify(bag, cycles, info)
        _, wall, rss = _run(cmd, ROOT)
        stats = pstats.Stats(str(prof)).stats  # type: ignore[attr-defined]
    rows = ["", f"### Where the time of one run went ({bag.name}, under cProfile)", "",
            f"Profiled run: {wall:.1f} s wall, peak RSS {rss:.0f} MB, load at the end "
            f"{os.getloadavg()[0]:.1f} (1 min) / {os.getloadavg()[1]:.1f} (5 min).  Cumulative time of "
            "each stage, every call included.", "",
            "| stage | calls | cumulative (s) |", "|---|---:|---:|"]
    for name, path, func in STAGES:
        hits = [(v[1], v[3]) for (f, _, fn), v in stats.items() if f.endswith(path) and fn == func]
        if hits:
            # a stage calling itself (nested calls) counts once: the largest cumulative entry
            calls, cum = sum(h[0] for h in hits), max(h[1] for h in hits)
            rows.append(f"| {name} | {calls} | {cum:.1f} |")
    return rows


def _read_table(bag: Path) -> list[str]:
    """Read ``bag`` with each decoder in a fresh process: wall time of the read, peak RSS."""
    rows = ["", f"### Reading {bag.name} with each decoder", "",
            "Each row is a fresh process reading the bag with `read_recording` (the same tolerant scan; "
            "only the decoding differs).", "",
            "| decoder | read (s) | process wall (s) | peak RSS (MB) | load 1 min |", "|---|---:|---:|---:|---:|"]
    for how, text in READ_WAYS:
        out, wall, rss = _run([sys.executable, "-c", READ_SNIPPET, str(bag), how], ROOT)
        rows.append(f"| {text} | {float(out.split()[0]):.1f} | {wall:.1f} | {rss:.0f} | {os.getloadavg()[0]:.1f} |")
        print(rows[-1], flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    """Measure, print and write ``docs/results/long_identify.md``."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("runs", nargs="+", help="BAG or BAG:CYCLES (train half, test half; default every cycle)")
    p.add_argument("--compare", type=Path, help="another checkout to measure the same way (before)")
    p.add_argument("--compare-label", default="before", help="the compared code's name in the table")
    p.add_argument("--label", default="this commit", help="this checkout's name in the table")
    p.add_argument("--breakdown", action="store_true", help="profile one run of the first recording")
    p.add_argument("--read", type=Path, help="also time reading this bag with each decoder")
    p.add_argument("--output", default="long_identify.md", help="file name under docs/results")
    p.add_argument("--append", action="store_true", help="add the tables to the file instead of replacing it")
    args = p.parse_args(argv)
    runs = [_parse_run(r) for r in args.runs]
    suds = [sys.executable, "-m", "suds_ros.cli.main"]
    infos = {bag: json.loads(_run(suds + ["info", str(bag), "--json"], ROOT)[0]) for bag, _ in runs}
    rows = []
    for label, src in [(args.label, ROOT)] + ([(args.compare_label, args.compare)] if args.compare else []):
        for bag, cycles in runs:
            out, wall, rss = _run(suds + _identify(bag, cycles, infos[bag]), Path(src))
            res = json.loads(out)
            load = os.getloadavg()
            rows.append((label, bag, res, wall, rss, load))
            print(f"{label}: {bag.name}: {res['train_cycles']} + {res['test_cycles']} cycles, {wall:.1f} s, "
                  f"{rss:.0f} MB, Γ {res['gamma_body']:.3f} / {res['gamma_passive']:.3f}, "
                  f"load {load[0]:.1f} / {load[1]:.1f}", flush=True)
    cmd = "python benchmarks/bench_long_identify.py " + shlex.join(argv if argv is not None else sys.argv[1:])
    lines = ["# `suds identify` on long recordings: peak memory and wall time", "",
             f"Measured {stamp()} on {machine()} by `{cmd.strip()}`.", "",
             "Each row is one fresh process `python -m suds_ros.cli.main identify BAG --train-cycles N "
             "--test-cycles M --json`; peak RSS is the child's `ru_maxrss` (`os.wait4`).  The machine "
             f"({os.cpu_count()} cores) is shared with other work: the last columns are its 1- and 5-minute "
             "load averages at the end of the run; wall times grow with them.", "",
             "The recordings:", ""]
    for bag, info in infos.items():
        counts = {t: v["count"] for t, v in info["topics"].items()}
        state = (f"{len(info['damage'])} damaged part(s) skipped" if info.get("damage") else "intact")
        lines.append(f"- `{bag.name}`: {counts.get('/suds/shape', 0)} shape samples, "
                     f"{counts.get('/suds/body_pose', 0)} poses over {info['duration_s']:.1f} s ({state})")
    lines += ["", "| code | recording | cycles (train + test) | wall (s) | peak RSS (MB) | Γ body | Γ passive | "
              "load 1 min | load 5 min |", "|---|---|---|---:|---:|---:|---:|---:|---:|"]
    for label, bag, res, wall, rss, load in rows:
        lines.append(f"| {label} | {bag.name} | {res['train_cycles']} + {res['test_cycles']} | {wall:.1f} | "
                     f"{rss:.0f} | {res['gamma_body']:.3f} | {res['gamma_passive']:.3f} | {load[0]:.1f} | "
                     f"{load[1]:.1f} |")
    if args.breakdown:
        lines += _breakdown(*runs[0], infos[runs[0][0]])
    if args.read:
        lines += _read_table(args.read.resolve())
    if args.append:
        from _common import RESULTS

        head = (RESULTS / args.output).read_text()
        lines[0] = "## Before and after" if args.compare else "## Again"
        write(args.output, head + "\n" + "\n".join(lines) + "\n")
    else:
        write(args.output, "\n".join(lines + NOTES) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
