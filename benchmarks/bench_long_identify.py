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
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import ROOT, machine, stamp, write  # noqa: E402

#: the stages of ``suds identify`` tabulated by ``--breakdown``: (name, module path end, function)
STAGES = [
    ("read the bag", "io/recording_bag.py", "read_recording_report"),
    ("fit (everything below)", "core/ident/identify.py", "fit"),
    ("· phase (phaser fit and transform)", "core/ident/identify.py", "_phase"),
    ("· interval data, rows, template (first pass)", "core/ident/identify.py", "_block_data"),
    ("· model selection (cross-validation)", "core/ident/identify.py", "_select_model"),
    ("· regression on every training row", "core/ident/sysid.py", "partial_fit"),
    ("held-out scores", "core/ident/identify.py", "scores"),
]

NOTES = [
    "",
    "How (this commit): the reader hands each chunk's messages of one channel to the decoder",
    "together; when they share one layout (the same frame, joint names and value counts, checked",
    "byte for byte against the first) their stamps and values are read as numpy arrays in one",
    "step, else one message at a time as before (`io/cdr.py` `parse_joint_states`,",
    "`parse_pose_stampeds`; the message-index entries are read as one array too).  `suds identify`",
    "on a long aligned recording (more than `block_samples` samples, one pose per shape sample)",
    "makes the interval data and regressor rows a block at a time, twice: the first pass fits the",
    "output template and keeps every k-th training row for the model selection (at most",
    "`select_max_rows`), the second adds every row to the regression's normal equations.  The",
    "held-out cycles are scored a block at a time (`ScoreSums`).  What stays whole is the",
    "`Recording` (13 float64 per sample) and the phase (one per sample).  Recordings at or below",
    "`block_samples` samples take the same path as before, so their Γ is unchanged.",
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


def main(argv: list[str] | None = None) -> int:
    """Measure, print and write ``docs/results/long_identify.md``."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("runs", nargs="+", help="BAG or BAG:CYCLES (train half, test half; default every cycle)")
    p.add_argument("--compare", type=Path, help="another checkout to measure the same way (before)")
    p.add_argument("--compare-label", default="before", help="the compared code's name in the table")
    p.add_argument("--label", default="this commit", help="this checkout's name in the table")
    p.add_argument("--breakdown", action="store_true", help="profile one run of the first recording")
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
    cmd = "python benchmarks/bench_long_identify.py " + " ".join(argv if argv is not None else sys.argv[1:])
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
    if args.append:
        from _common import RESULTS

        head = (RESULTS / args.output).read_text()
        lines[0] = "## Again"
        write(args.output, head + "\n" + "\n".join(lines) + "\n")
    else:
        write(args.output, "\n".join(lines + NOTES) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
