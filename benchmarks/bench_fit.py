"""Speed of fit / partial_fit and model size vs number of passive joints.

1. swimmer9: samples per second of SudsRegressor.fit and of partial_fit in 100-sample chunks
   (regressor set 2, Fourier orders 8/6/3).
2. N-link chains with 4 actuated joints and N − 5 passive joints, N = 5 … 33: parameters per
   output and fit time for sets 1, 2, 3 (regressors only; 3000 random rows).
Writes docs/results/bench_fit.md.

    python benchmarks/bench_fit.py
"""

from __future__ import annotations

import time

import numpy as np

from _common import machine, stamp, write

from suds_ros.core.sysid import SudsConfig, SudsRegressor


def rows(n: int, nj: int, na: int, n_out: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    X = np.concatenate(
        [np.linspace(0, 2 * np.pi * n / 100, n)[:, None], rng.normal(size=(n, nj)), rng.normal(size=(n, na))], axis=1
    )
    return X, rng.normal(size=(n, n_out))


def best_time(fn, repeat: int = 3) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    cfg = SudsConfig(regressors=2, intercept_order=8, linear_order=6, bilinear_order=3)
    X, y = rows(6000, 8, 4, 7)
    t_fit = best_time(lambda: SudsRegressor(8, 4, cfg).fit(X, y))

    def chunked() -> None:
        est = SudsRegressor(8, 4, cfg)
        for k in range(0, 6000, 100):
            est.partial_fit(X[k : k + 100], y[k : k + 100])

    t_part = best_time(chunked)
    lines = [
        "# Fit speed and model size",
        "",
        f"Measured {stamp()} on {machine()} by `python benchmarks/bench_fit.py`.",
        "",
        "## swimmer9 (8 joints, 4 actuated, 7 outputs, set 2, orders 8/6/3, "
        f"{SudsRegressor(8, 4, cfg).n_parameters} parameters per output)",
        "",
        "| operation | 6000 samples | samples/s |",
        "|---|---|---|",
        f"| fit | {t_fit * 1e3:.1f} ms | {6000 / t_fit:,.0f} |",
        f"| partial_fit, 60 chunks of 100 (re-solve after each) | {t_part * 1e3:.1f} ms | {6000 / t_part:,.0f} |",
        "",
        "## N-link chains: 4 actuated joints, N − 5 passive joints (orders 8/3/1, 3000 rows)",
        "",
        "| N | passive | set 1 params | set 2 params | set 3 params | set 1 fit ms | set 2 fit ms | set 3 fit ms |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for n_links in (5, 9, 13, 17, 21, 25, 29, 33):
        nj, na = n_links - 1, 4
        npas = nj - na
        Xn, yn = rows(3000, nj, na, 3 + npas, seed=n_links)
        params, times = [], []
        for k in (1, 2, 3):
            c = SudsConfig(regressors=k, intercept_order=8, linear_order=3, bilinear_order=1)
            params.append(SudsRegressor(nj, na, c).n_parameters)
            times.append(best_time(lambda: SudsRegressor(nj, na, c).fit(Xn, yn), repeat=2) * 1e3)
        lines.append(f"| {n_links} | {npas} | " + " | ".join(map(str, params)) + " | " + " | ".join(f"{t:.0f}" for t in times) + " |")
        print(lines[-1], flush=True)
    lines += [
        "",
        "Set 2 grows by (nj·na + …) columns per added joint: linear in the number of passive joints",
        "for a fixed number of actuators; set 3 adds O(n²) squares.",
    ]
    write("bench_fit.md", "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
