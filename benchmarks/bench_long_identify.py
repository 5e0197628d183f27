"""Peak memory and wall time of ``suds identify`` on long recordings (issue 19's one-hour target).

Run: ``python benchmarks/bench_long_identify.py BAG [--cycles N ...]`` (writes
docs/results/long_identify.md).  Make the recording first, e.g. an hour of swimmer9 at 1 kHz:
``suds simulate swimmer9 -o s9_hour.mcap --cycles 3600 --rate 1000 --seed 1``.  A bag cut short
(a simulation stopped early) is read up to where it ends: the reader reports the damage and the
table says how many samples were read.

For each N, ``suds identify BAG --train-cycles N/2 --test-cycles N/2 --json`` runs in a child
process (N defaults to every cycle the bag holds); its peak resident memory comes from the
child's own resource usage (``os.wait4``), so nothing else in this process counts.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import ROOT, machine, stamp, write  # noqa: E402


def _measure(cmd: list[str]) -> tuple[dict, float, float]:
    """Run ``cmd``; (JSON output, wall s, peak RSS MB) from os.wait4 on the child."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    out_r, out_w = os.pipe()
    err_r, err_w = os.pipe()
    t0 = time.perf_counter()
    pid = os.fork()
    if pid == 0:  # child: exec the command with its output on the pipes
        os.dup2(out_w, 1)
        os.dup2(err_w, 2)
        os.execvpe(cmd[0], cmd, env)
    os.close(out_w)
    os.close(err_w)
    with os.fdopen(out_r) as fo, os.fdopen(err_r) as fe:
        import threading

        err: list[str] = []
        t = threading.Thread(target=lambda: err.append(fe.read()))
        t.start()
        out = fo.read()
        t.join()
    _, status, usage = os.wait4(pid, 0)
    wall = time.perf_counter() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{err[0] if err else ''}")
    return json.loads(out), wall, usage.ru_maxrss / 1024.0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("bag", help="the recording (suds simulate … --rate 1000)")
    p.add_argument("--cycles", type=int, nargs="*", default=[],
                   help="cycles to use (train half, test half); default: the whole bag")
    a = p.parse_args(argv)
    suds = [sys.executable, "-m", "suds_ros.cli.main"]
    info, _, _ = _measure(suds + ["info", a.bag, "--json"])
    counts = {t: v["count"] for t, v in info["topics"].items()}
    n_shape = counts.get("/suds/shape", 0)
    rows = []
    gait_hz = float(info.get("metadata", {}).get("suds", {}).get("gait_hz") or 1.0)
    whole = int(info["duration_s"] * gait_hz)  # whole cycles the bag spans
    for n in a.cycles or [whole]:
        cmd = suds + ["identify", a.bag, "--json", "--train-cycles", str(n // 2), "--test-cycles", str(n - n // 2)]
        res, wall, mb = _measure(cmd)
        rows.append((n, res, wall, mb))
        print(rows[-1][0], wall, mb, res["gamma_body"], res["gamma_passive"], flush=True)
    damage = (f"cut short or damaged: {len(info['damage'])} damaged part(s) skipped" if info.get("damage")
              else "intact")
    lines = ["# `suds identify` on long recordings: peak memory and wall time", "",
             f"Measured {stamp()} on {machine()} with `python benchmarks/bench_long_identify.py "
             f"{Path(a.bag).name}{' --cycles ' + ' '.join(map(str, a.cycles)) if a.cycles else ''}` "
             f"(peak RSS of the `suds identify` process from `os.wait4`).", "",
             f"The recording: {n_shape} shape samples and {counts.get('/suds/body_pose', 0)} poses "
             f"({damage}).", "",
             "| cycles used (train + test) | shape samples read | wall (s) | peak RSS (MB) | Γ body | Γ passive |",
             "|---|---|---|---|---|---|"]
    for n, res, wall, mb in rows:
        lines.append(f"| {n} ({n // 2} + {n - n // 2}) | {n_shape} | {wall:.1f} | {mb:.0f} | "
                     f"{res['gamma_body']:.3f} | {res['gamma_passive']:.3f} |")
    lines.append("")
    write("long_identify.md", "\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
