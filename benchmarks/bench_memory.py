"""Peak memory and speed of `suds simulate` against the length of the run.

Each run is a fresh process (``python -m suds_ros.cli.main simulate SYSTEM --cycles N``); its
peak resident set size is the kernel's ``ru_maxrss`` of that child (``os.wait4``), its speed
the simulated seconds (cycles / gait Hz) per wall-clock second.  ``--compare SRC`` also runs
the code of another checkout (e.g. the commit before streaming) for a before/after table.

    python benchmarks/bench_memory.py                       # 60, 240, 960 cycles of swimmer9
    python benchmarks/bench_memory.py --cycles 20 80 --compare /tmp/old-checkout
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import ROOT, machine, stamp, write


#: what the figures mean and where the time goes (profile of a short swimmer9 run)
NOTES = [
    "",
    "How: `suds simulate` integrates ten gait cycles at a time (`simulate_blocks`, carrying the",
    "integrator state, the OU drive and the random streams) and hands each block to",
    "`RecordingWriter`, which writes its messages as soon as no later block can precede them; the",
    "bag is byte-for-byte the one the whole run written at once gives.  Before, the whole run was",
    "held, and the effort evaluation over all samples at once (about 5.5 kB of intermediate",
    "arrays per sample for swimmer9's Jacobians) made the peak grow with the run.",
    "",
    "Where the time goes: the run is integrated as one trajectory (B = 1), 4 RK4 stages × 7",
    "substeps (swimmer9's automatic step) = 28 velocity evaluations per sample, each about",
    "0.1-0.3 ms, mostly numpy's per-call overhead on (1, 9, 3, 12) arrays (`RFTChain._jacobians_perm`",
    "builds J by ten slice assignments into a zeroed array; `solve`, `passive_torque`,",
    "`se2.exp_step`).  RK4 is sequential in time, so one run cannot be vectorised over samples;",
    "the easy win is across runs: `integrate_batch` already takes B runs at once (the diagnosis",
    "replays use it), so several seeds or systems of the same size simulated together cost",
    "little more than one.  Building J with one `np.stack` instead of the slice assignments is",
    "pure data movement (no change of numerics) and would trim the per-call overhead.  Neither is",
    "done here.",
]


def run_once(src: Path, system: str, cycles: int, seed: int, out: Path) -> tuple[float, float]:
    """Run ``suds simulate`` with the code in ``src``; returns (peak RSS MB, wall s)."""
    env = {**os.environ, "PYTHONPATH": str(src)}
    cmd = [sys.executable, "-m", "suds_ros.cli.main", "simulate", system, "-o", str(out),
           "--cycles", str(cycles), "--seed", str(seed), "--overwrite"]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=src)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode() if proc.stderr else ""
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}): {err}")
    return usage.ru_maxrss / 1024.0, wall  # ru_maxrss is in KiB on Linux


def main(argv: list[str] | None = None) -> int:
    """Measure, print and write ``docs/results/memory.md``."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--system", default="swimmer9")
    p.add_argument("--cycles", type=int, nargs="+", default=[60, 240, 960])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--compare", type=Path, help="another checkout to measure the same way (before)")
    p.add_argument("--compare-label", default="before", help="the compared code's name in the table")
    p.add_argument("--compare-cycles", type=int, nargs="+",
                   help="cycles to run with --compare (default: --cycles)")
    p.add_argument("--output", default="memory.md", help="file name under docs/results")
    p.add_argument("--append", action="store_true",
                   help="add the table to the file (e.g. a back-to-back speed check) instead of replacing it")
    args = p.parse_args(argv)
    gait_hz = 1.0  # every built-in system's gait; simulated seconds = cycles / gait_hz
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "run.mcap"
        for label, src, cycles in [("this commit", ROOT, args.cycles)] + (
                [(args.compare_label, args.compare, args.compare_cycles or args.cycles)] if args.compare else []):
            for n in cycles:
                rss, wall = run_once(Path(src), args.system, n, args.seed, bag)
                size = bag.stat().st_size / 1e6
                load = os.getloadavg()[1]  # 5-minute load average at the end of the run
                rows.append((label, n, rss, wall, n / gait_hz / wall, size, load))
                print(f"{label}: {n} cycles: peak RSS {rss:.0f} MB, {wall:.1f} s, "
                      f"{n / gait_hz / wall:.2f}x real time, bag {size:.1f} MB, load {load:.1f}", flush=True)
    cmd = "python benchmarks/bench_memory.py " + " ".join(argv if argv is not None else sys.argv[1:])
    lines = [
        "# `suds simulate`: peak memory and speed against the run's length",
        "",
        f"Measured {stamp()} on {machine()} by `{cmd.strip()}`.",
        "",
        f"Each row is one fresh process `python -m suds_ros.cli.main simulate {args.system} -o run.mcap "
        f"--cycles N --seed {args.seed}` (zstd bag); peak RSS is the child's `ru_maxrss` "
        "(`os.wait4`), speed the simulated time (cycles at 1 Hz) over the wall time, on a machine "
        "shared with other work: the last column is the machine's 5-minute load average at the end of "
        f"the run ({os.cpu_count()} cores); wall times grow with it.",
        "",
        "| code | cycles | samples | peak RSS (MB) | wall (s) | × real time | bag (MB) | load |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for label, n, rss, wall, speed, size, load in rows:
        lines.append(f"| {label} | {n} | {n * 100} | {rss:.0f} | {wall:.1f} | {speed:.2f} | {size:.1f} | "
                     f"{load:.1f} |")
    if args.append:
        from _common import RESULTS

        head = (RESULTS / args.output).read_text()
        lines[0] = "## Back to back" if args.compare else "## Again"
        write(args.output, head + "\n" + "\n".join(lines) + "\n")
    else:
        write(args.output, "\n".join(lines + NOTES) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
