"""Long chains: held-out Γ and fit time against the number of links, ours against kernel ridge.

The paper's case for the SUDS structure is that its size grows linearly with the chain (set 2:
O(n·n_a) gains per output).  This script measures it on the general N-link chains
(`make_system('nlinkN')`): unit links, the first ⌊(N−1)/2⌋ joints driven by a travelling wave
(amplitude 1.4 rad, phase step π/4 between joints, 1 Hz) plus the simulator's OU perturbation
(κ = 8/s, std 0.175 rad) on each driven joint, the remaining joints passive springs whose
stiffness falls linearly from 20 to 5 N·m/rad toward the tail.  The wave and the perturbations
bend the passive tail through the fluid, so every passive joint moves (its RMS rate is printed).

For each N: a 60-cycle run (noise 1e-3), train on cycles 1–30, test on 31–60; ours is the
shipped `SudsIdentifier` (its own cross-validated choice), kernel ridge the RBF one of
`benchmarks/peers.py` with its blocked-CV hyperparameters, both given the same data.  Fit times
are single-threaded wall-clock seconds (ours: everything including its cross-validation;
kernel ridge: the final fit only, its CV excluded).

    python benchmarks/long_chains.py [--links 5 9 13 17 25 33] [--seeds 0] [--cycles 30]

Needs scikit-learn (benchmarks/requirements-peers.txt).  Writes docs/results/long_chains.md.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_v] = "1"

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from _common import machine, stamp, write  # noqa: E402
from peers import PINNING, data_of, groups_of, run_krr  # noqa: E402

from suds_ros.core.ident.identify import SudsIdentifier  # noqa: E402
from suds_ros.core.ident.scoring import Prediction, score_prediction  # noqa: E402
from suds_ros.core.physics.sim import SimConfig, simulate  # noqa: E402
from suds_ros.core.physics.systems import make_system  # noqa: E402


def one(n_links: int, seed: int, cycles: int) -> dict:
    """Ours and kernel ridge on one N-link run."""
    system = make_system(f"nlink{n_links}")
    rec = simulate(system, SimConfig(cycles=2 * cycles, seed=seed))
    k = cycles * 100
    train, test = rec.slice(0, k), rec.slice(k, 2 * k)
    t0 = time.perf_counter()
    ident = SudsIdentifier().fit(train)
    fit_ours = time.perf_counter() - t0
    ours = ident.scores(test)
    dtr, dte = data_of(ident, train, True), data_of(ident, test, False)
    groups = groups_of(ident.channels_)
    pred, fit_krr, info = run_krr(dtr, dte, groups, seed)
    krr = score_prediction(Prediction(t=dte.t, phase=dte.ph, channels=ident.channels_, truth=dte.Y,
                                      model=pred, template=dte.T))
    c = ident.regressor_.config
    pas_rms = float(np.sqrt(np.mean(dte.Y[:, 3:] ** 2)))
    row = dict(n=n_links, seed=seed, joints=len(rec.joint_names), actuated=len(rec.actuated),
               ours=(ours.gamma_body, ours.gamma_passive), krr=(krr.gamma_body, krr.gamma_passive),
               fit_ours=fit_ours, fit_krr=fit_krr, params=ident.n_parameters,
               choice=f"set {c.regressors}, orders {c.linear_order}/{c.bilinear_order}, ridge {c.ridge:g}"
                      + (f", {c.kernel_features} random features" if c.kernel_features else ""),
               krr_info=info, passive_rms=pas_rms)
    print(row, flush=True)
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--links", type=int, nargs="+", default=[5, 9, 13, 17, 25, 33])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--cycles", type=int, default=30, help="training cycles (as many again are held out)")
    args = ap.parse_args()
    rows = [one(n, s, args.cycles) for n in args.links for s in args.seeds]
    lines = [
        "# Long chains: Γ and fit time against the number of links (ours vs kernel ridge)",
        "",
        f"Measured {stamp()} on {machine()} by `python benchmarks/long_chains.py --links "
        f"{' '.join(map(str, args.links))} --seeds {' '.join(map(str, args.seeds))} --cycles {args.cycles}`; "
        f"BLAS threads: {PINNING}.",
        f"{args.cycles} training and {args.cycles} held-out cycles of `nlinkN` (drive and passive joints: see",
        "the script's docstring; the first ⌊(N−1)/2⌋ joints driven by a travelling wave plus OU",
        "perturbations, the rest springs). Γ body / passive on the held-out cycles, mean over seeds.",
        "",
        "| N links | joints (driven) | passive ṙ RMS, rad/s | ours Γ | kernel ridge Γ | ours fit, s "
        "| kernel ridge fit, s | ours: chosen model, parameters per output |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for n in args.links:
        rs = [r for r in rows if r["n"] == n]
        o = np.mean([r["ours"] for r in rs], axis=0)
        kr = np.mean([r["krr"] for r in rs], axis=0)
        lines.append(
            f"| {n} | {rs[0]['joints']} ({rs[0]['actuated']}) | {np.mean([r['passive_rms'] for r in rs]):.2f} "
            f"| {o[0]:.3f} / {o[1]:.3f} | {kr[0]:.3f} / {kr[1]:.3f} | {np.mean([r['fit_ours'] for r in rs]):.2f} "
            f"| {np.mean([r['fit_krr'] for r in rs]):.2f} | {'; '.join(sorted({r['choice'] for r in rs}))}, "
            f"{rs[0]['params']} |")
    write("long_chains.md", "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
