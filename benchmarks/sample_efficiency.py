"""Sample efficiency on swimmer9: held-out Γ vs training cycles for regressor sets 1, 2, 3.

Training on the first 5, 10, 20, 30 cycles, testing on the same 30 held-out cycles (31–60),
three seeds.  Writes docs/results/sample_efficiency.md and .png.

    python benchmarks/sample_efficiency.py [--seeds 0 1 2]
"""

from __future__ import annotations

import argparse

import numpy as np

from _common import RESULTS, machine, stamp, write

from suds_ros.core.ident.identify import IdentifyConfig, SudsIdentifier
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.ident.sysid import SudsConfig
from suds_ros.core.physics.systems import make_system

TRAIN = (5, 10, 20, 30)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--system", default="swimmer9")
    args = ap.parse_args()
    res = {}  # (set, n_train) -> list of (Γb, Γp, params)
    for seed in args.seeds:
        rec = simulate(make_system(args.system), SimConfig(cycles=60, seed=seed))
        test = rec.slice(3000, 6000)
        for n in TRAIN:
            train = rec.slice(3000 - n * 100, 3000)
            for k in (1, 2, 3):
                cfg = IdentifyConfig(suds=SudsConfig(regressors=k), regressor_grid=(k,), kernel_grid=())
                ident = SudsIdentifier(cfg).fit(train)
                sc = ident.scores(test)
                res.setdefault((k, n), []).append((sc.gamma_body, sc.gamma_passive, ident.n_parameters))
                print(f"seed {seed} train {n:2d} set {k}: Γb {sc.gamma_body:.3f} Γp {sc.gamma_passive:.3f} "
                      f"({ident.n_parameters} parameters)", flush=True)
    lines = [
        f"# Sample efficiency on {args.system}: held-out Γ (cycles 31–60) vs training cycles",
        "",
        f"Measured {stamp()} on {machine()} by `python benchmarks/sample_efficiency.py`; seeds {args.seeds}.",
        "Training cycles are the ones just before the test block. Parameters per output after the",
        "cross-validated choice of Fourier orders (so they can differ between runs).",
        "",
        "| training cycles | set 1 Γ body / passive | set 2 Γ body / passive | set 3 Γ body / passive "
        "| parameters (1 / 2 / 3) |",
        "|---|---|---|---|---|",
    ]
    for n in TRAIN:
        cells = []
        pars = []
        for k in (1, 2, 3):
            a = np.array(res[(k, n)])
            cells.append(f"{a[:, 0].mean():.3f} / {a[:, 1].mean():.3f}")
            pars.append(str(int(np.median(a[:, 2]))))
        lines.append(f"| {n} | " + " | ".join(cells) + f" | {' / '.join(pars)} |")
    write("sample_efficiency.md", "\n".join(lines) + "\n")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, col, label in ((axes[0], 0, "Γ body"), (axes[1], 1, "Γ passive")):
        for k, style in ((1, "o-"), (2, "s-"), (3, "^-")):
            m = [np.mean([v[col] for v in res[(k, n)]]) for n in TRAIN]
            s = [np.std([v[col] for v in res[(k, n)]]) for n in TRAIN]
            ax.errorbar(TRAIN, m, yerr=s, fmt=style, capsize=3, label=f"set {k}")
        ax.set_xlabel("training cycles")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend()
    fig.suptitle(f"{args.system}: held-out Γ vs training data")
    fig.tight_layout()
    fig.savefig(RESULTS / "sample_efficiency.png", dpi=110)


if __name__ == "__main__":
    main()
