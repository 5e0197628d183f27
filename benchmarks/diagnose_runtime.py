"""Wall time of a 60-cycle, 3-effect diagnosis: worker processes and what the calibration costs.

Run: ``python benchmarks/diagnose_runtime.py [--pose-hz HZ]`` (writes
docs/results/diagnose_runtime.md, or ``diagnose_runtime_lab.md`` with ``--pose-hz``).  Run it on
an otherwise idle machine: the figures are wall times.

The case is the slowest kind in the lab sweep (``docs/results/diagnose_sweep_lab.md`` case 1,
swimmer9 with a link-length error, a Coulomb friction and a rest offset on joint_7; 60 cycles,
seed 3067), recorded aligned or, with ``--pose-hz``, the lab way (pose at that rate from its own
start, 0.4 ms jitter, 1 % drops: the sweep's lab conditions).  It is diagnosed four times: one
process and ``--jobs`` worker processes (``DiagnoseConfig.jobs``), each with and without the
per-recording calibration of the evidence (``calibrate``).  The stage times are the report's own
(``DiagnosisReport.timings``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine, stamp, write  # noqa: E402

from suds_ros.core.blas import pin_blas_threads  # noqa: E402
from suds_ros.core.diagnosis import DiagnoseConfig, diagnose  # noqa: E402
from suds_ros.core.physics.effects import apply_effects  # noqa: E402
from suds_ros.core.physics.lab import LabConditions, simulate_lab  # noqa: E402
from suds_ros.core.physics.rft import RFTChain  # noqa: E402
from suds_ros.core.physics.sim import SimConfig, simulate  # noqa: E402
from suds_ros.core.physics.systems import swimmer9_model  # noqa: E402

EFFECTS = [dict(name="link_length_error", link="link_7", scale=1.255),
           dict(name="joint_coulomb_friction", joint="joint_7", mu=0.8179),
           dict(name="spring_rest_offset", joint="joint_7", offset=-0.1845)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=2, help="worker processes of the parallel runs")
    ap.add_argument("--pose-hz", type=float, default=None, help="record the lab way with the pose at this rate")
    ap.add_argument("--out", default=None, help="results file (default diagnose_runtime[_lab].md)")
    args = ap.parse_args()
    out = args.out or ("diagnose_runtime.md" if args.pose_hz is None else "diagnose_runtime_lab.md")
    pin_blas_threads(1)
    base = swimmer9_model()
    model, delay = apply_effects(base, EFFECTS)
    cfg = SimConfig(cycles=60, seed=3067, pose_delay=delay)
    rec = (simulate(RFTChain(model), cfg) if args.pose_hz is None
           else simulate_lab(RFTChain(model), cfg, LabConditions(pose_hz=args.pose_hz)))
    how = "aligned" if args.pose_hz is None else f"lab: pose at {args.pose_hz:g} Hz, 0.4 ms jitter, 1 % drops"
    rows, reports = [], []
    for jobs in (1, args.jobs):
        for calibrate in (True, False):
            t0 = time.perf_counter()
            rep = diagnose(rec, base, DiagnoseConfig(jobs=jobs, calibrate=calibrate))
            wall = time.perf_counter() - t0
            tm = rep.timings
            named = "; ".join(f"{e.name} {e.target or ''} " + ", ".join(f"{k}={v:.4g}" for k, v in e.parameters.items())
                              for e in rep.effects)
            stages = (f"{tm['replay']:.1f} / {tm['name'] - tm['locate']:.1f} / {tm['refine'] - tm['name']:.1f} / "
                      f"{tm['total'] - tm['refine']:.1f}")
            rows.append(f"| {jobs} | {'yes' if calibrate else 'no'} | **{wall:.1f}** | {stages} | {named} |")
            reports.append((jobs, calibrate, rep.to_json()))
            print(rows[-1], flush=True)
    same = all(r == reports[i % 2][2] for i, (_, _, r) in enumerate(reports))
    text = "\n".join([
        "# Diagnosis wall time: worker processes and the calibration's cost",
        "",
        f"Measured {stamp()} on {machine()} with `python benchmarks/diagnose_runtime.py --jobs {args.jobs}"
        + ("" if args.pose_hz is None else f" --pose-hz {args.pose_hz:g}") + "`.",
        "",
        f"swimmer9, 60 cycles ({how}, seed 3067), three effects: link_length_error link_7 × 1.255, "
        "joint_coulomb_friction joint_7 mu = 0.8179, spring_rest_offset joint_7 −0.1845 rad (the lab sweep's "
        "case 1).  Target (issue 21): at most 60 s on 2 cores, with the calibration.  Stages (s): the nominal "
        "replay / naming (equation error, with the calibration's null replays and fits) / refinement in the "
        "simulator / report and discovery.",
        "",
        "| worker processes | calibration | wall (s) | stages (s) | named |",
        "|---|---|---|---|---|",
        *rows,
        "",
        f"Reports with and without workers identical (JSON, to the last digit): **{'yes' if same else 'NO'}**.",
        "",
    ])
    write(out, text)


if __name__ == "__main__":
    main()
