"""The live estimator on a jittered shape stream: raw stamps against its live grid, beside the batch identifier.

A servo loop stamped by the host that reads it gives samples at the drive's set-point times plus
stamp jitter.  The drive bends at the set-points, so differences over the raw stamps cut each bend
that falls inside an interval.  The batch identifier brings the shape stream onto its fitted grid
first (`core/resample.on_shape_grid`); the streaming estimator (the estimator node, `suds identify
--streaming`) now does the same as the samples arrive (`core/resample.LiveGrid`, `OnlineConfig.regrid`).
Here lab recordings (pose 120 Hz from 3.7 ms later, 1 % of each stream lost, 60 cycles: 40 train /
20 held out) at five levels of stamp jitter; every model is scored on the held-out cycles brought
onto their grid, as the batch identifier scores.  Writes docs/results/streaming_jitter.md.

    python benchmarks/streaming_jitter.py [--systems purcell3 swimmer9] [--seeds 0 1 2]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from _common import machine, stamp, write

from suds_ros.core.ident.identify import IdentifyConfig, SudsIdentifier, split_cycles
from suds_ros.core.ident.online import OnlineConfig, fit_streaming
from suds_ros.core.ident.predictor import evaluate_model
from suds_ros.core.ident.scoring import score_prediction
from suds_ros.core.physics.lab import LabConditions, simulate_lab
from suds_ros.core.physics.sim import SimConfig
from suds_ros.core.physics.systems import make_system
from suds_ros.core.resample import on_shape_grid

JITTERS = (0.0, 0.0004, 0.001, 0.002, 0.003)  # stamp jitter, s: none, the lab default, then busy hosts


def one(system: object, seed: int, jitter: float) -> tuple[list[float], str]:
    """Γ body, Γ passive for batch, streaming on raw stamps and streaming on its live grid; the live grid's mode."""
    rec = simulate_lab(system, SimConfig(cycles=60, seed=seed), LabConditions(jitter=jitter))  # type: ignore[arg-type]
    train, test = split_cycles(rec, 40, 20)
    on_grid = on_shape_grid(test)
    batch = SudsIdentifier(IdentifyConfig()).fit(train).scores(test)
    out = [batch.gamma_body, batch.gamma_passive]
    mode = ""
    for regrid in (False, True):
        est = fit_streaming(train, OnlineConfig(regrid=regrid))
        s = score_prediction(evaluate_model(est.model(), on_grid))
        out += [s.gamma_body, s.gamma_passive]
        if est.regrid is not None:
            mode = est.regrid.mode
    return out, mode


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--systems", nargs="+", default=["purcell3", "swimmer9"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    args = ap.parse_args()
    t0 = time.perf_counter()
    lines = ["| system | jitter ms | live grid | batch (body / passive) | streaming, raw stamps | streaming, live grid "
             "| Δ body, live grid − raw | Δ body, live grid − batch |",
             "|---|---|---|---|---|---|---|---|"]
    for name in args.systems:
        system = make_system(name)
        for jitter in JITTERS:
            rows, modes = [], set()
            for seed in args.seeds:
                g, mode = one(system, seed, jitter)
                rows.append(g)
                modes.add(mode)
                print(name, jitter, seed, mode, np.round(g, 4), flush=True)
            g = np.asarray(rows)
            m, lo, hi = g.mean(axis=0), g.min(axis=0), g.max(axis=0)
            up, gap = g[:, 4] - g[:, 2], g[:, 4] - g[:, 0]
            cells = [f"{m[i]:.3f} / {m[i + 1]:.3f}" for i in (0, 2, 4)]
            lines.append(f"| {name} | {1e3 * jitter:g} | {', '.join(sorted(modes))} | " + " | ".join(cells)
                         + f" | {up.mean():+.3f} ({up.min():+.3f} … {up.max():+.3f}) "
                         f"| {gap.mean():+.3f} ({gap.min():+.3f} … {gap.max():+.3f}) |")
            print(lines[-1], f"body range batch {lo[0]:.3f}-{hi[0]:.3f}", flush=True)
    text = "\n".join([
        "# The live estimator on a jittered shape stream", "",
        f"Measured {stamp()} on {machine()} by `python benchmarks/streaming_jitter.py` (seeds "
        f"{args.seeds}, {time.perf_counter() - t0:.0f} s).", "",
        "Lab recordings: shape at 100 Hz read at its set-point times plus Gaussian stamp jitter of the given "
        "standard deviation (clipped at 0.4 periods, `core/physics/lab.py`), pose at 120 Hz from 3.7 ms later "
        "with the same jitter, 1 % of each stream lost; 60 cycles, 40 train / 20 held out.  *batch*: `suds "
        "identify` (the shipped model selection).  *streaming*: the estimator node's algorithm (`suds identify "
        "--streaming`) fed the samples in stamp order, with `regrid` off (raw stamps, as before) and on (the "
        "live grid, `core/resample.LiveGrid`).  Every model is scored on the held-out cycles brought onto their "
        "fitted grid, as the batch identifier scores.  Cells are means over the seeds; the Δ columns give the "
        "mean and the range over the seeds.  *live grid*: the mode the stage chose (raw: the stamps were "
        "uniform and passed on unchanged).", "",
        *lines, "",
        "How to read it: without jitter the stage passes the stamps on and the two streaming columns are the "
        "same model.  With jitter the raw intervals cut the drive's bends, and the loss grows with the jitter "
        "(and with the robot's stiffness: swimmer9's passive joints follow their drive within a sample); on the "
        "live grid the streaming model stays as close to the batch identifier as it is without jitter, at the "
        "cost of holding each shape sample until samples four grid points later arrived (0.04 s at 100 Hz, plus "
        "up to 16 samples per release).  That remaining difference from the batch column is the streaming "
        "estimator's own (its fixed regressor sets against the batch's cross-validated choice: ahead on "
        "purcell3, behind on swimmer9), the same at every jitter.",
        ""])
    write("streaming_jitter.md", text)


if __name__ == "__main__":
    main()
