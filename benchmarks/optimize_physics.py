"""Benchmark of `suds optimize --physics` (core.optimize.physics): time, gain over the nominal gait, checks.

    python benchmarks/optimize_physics.py            # writes docs/results/optimize.md

1. Accuracy of the cycle integration: the nominal gaits' speed at 64 … 512 RK4 steps per cycle.
2. purcell3, orders 1–3, 4 starts (seed 0): value, nominal value, wall time, candidate cycles.
3. swimmer9, order 3, 4 starts (seed 0) and again with seed 1 (a second multi-start).
4. A second method on purcell3 order 3: COBYLA (derivative free, same constraints, its own
   steady state per point) from the nominal gait; the SLSQP optimum should be within 1 %.
5. Every gait written meets its bounds (constraint_violations) and its value re-evaluated from
   scratch (evaluate_gait, 512 steps) agrees.
"""

from __future__ import annotations

import time

import numpy as np
from _common import machine, stamp, write
from scipy.optimize import minimize

from suds_ros.core.optimize.physics import (
    CycleEvaluator,
    OptimizeConfig,
    linear_bounds,
    evaluate_gait,
    optimize_gait,
)
from suds_ros.core.physics.gait import constraint_violations, gait_limits, nominal_gait
from suds_ros.core.physics.systems import make_system


def accuracy() -> list[str]:
    rows = ["| system | 64 steps | 128 | 256 | 512 | rel. error at 64 |", "|---|---|---|---|---|---|"]
    for name in ("purcell3", "swimmer9"):
        system = make_system(name)
        g = nominal_gait(system)
        v = [evaluate_gait(system, g, steps=n, work=False)["speed"] for n in (64, 128, 256, 512)]
        rows.append(f"| {name} | {v[0]:.8f} | {v[1]:.8f} | {v[2]:.8f} | {v[3]:.8f} | {abs(v[0] / v[3] - 1):.1e} |")
    return rows


def run(name: str, order: int, starts: int, seed: int) -> tuple[list[str], object]:
    system = make_system(name)
    res = optimize_gait(system, OptimizeConfig(order=order, starts=starts, seed=seed))
    bad = constraint_violations(res.gait, gait_limits(system))
    check = evaluate_gait(system, res.gait, steps=512, work=False)["speed"]
    per_start = ", ".join("failed" if s["value"] is None else f"{s['value']:.5f}" for s in res.starts)
    row = (f"| {name} | {order} | {starts} | {seed} | {res.nominal_value:.5f} | {res.value:.5f} | "
           f"{100 * (res.value / res.nominal_value - 1):+.1f} % | {res.values['rotation']:+.1e} | "
           f"{check:.5f} | {'yes' if not bad else 'NO: ' + '; '.join(bad)} | {res.seconds:.1f} | {res.cycles} | "
           f"{per_start} |")
    return [row], res


def cobyla(name: str, order: int) -> tuple[float, float, int]:
    """COBYLA from the nominal gait with the same bounds; returns (speed, seconds, evaluations)."""
    system = make_system(name)
    nominal = nominal_gait(system)
    limits = gait_limits(system, nominal)
    M, b = linear_bounds(nominal, order, limits, 64)
    ev = CycleEvaluator(system, nominal.gait_hz, order, 64)
    free = np.flatnonzero(np.arange(M.shape[1]) != 1)
    state = {"rp": np.zeros((1, len(system.passive))), "n": 0}

    def out(z: np.ndarray) -> np.ndarray:
        x = np.zeros(M.shape[1])
        x[free] = z
        res, _, _ = ev.steady(x[None], state["rp"])
        state["rp"], state["n"] = res.r_p, state["n"] + 1
        return res.g_c[0]

    t = time.perf_counter()
    cons = [{"type": "ineq", "fun": lambda z: b - M[:, free] @ z},
            {"type": "ineq", "fun": lambda z: 0.05 - np.abs(out(z)[2])}]
    sol = minimize(lambda z: -np.hypot(*out(z)[:2]) * nominal.gait_hz, nominal.to_vector(order)[free],
                   method="COBYLA", constraints=cons, options={"maxiter": 3000, "rhobeg": 0.2, "tol": 1e-9})
    return -float(sol.fun), time.perf_counter() - t, state["n"]


def main() -> None:
    lines = ["# `suds optimize --physics`: measured", "",
             f"Measured {stamp()} on {machine()} by `benchmarks/optimize_physics.py` (one process, "
             "the other core busy with other work at times).", "",
             "## Cycle integration accuracy (nominal gait speed, m/s, at the passive periodic steady state)", "",
             *accuracy(), "",
             "## Optimised speed (m/s), default bounds (range and speed of the nominal gait)", "",
             "| system | K | starts | seed | nominal | optimised | gain | rotation/cycle | re-evaluated (512 steps) "
             "| within bounds | time s | cycles | per start |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, order, starts, seed in (("purcell3", 1, 4, 0), ("purcell3", 2, 4, 0), ("purcell3", 3, 4, 0),
                                      ("swimmer9", 3, 4, 0), ("swimmer9", 3, 4, 1)):
        rows, res = run(name, order, starts, seed)
        lines += rows
        print(rows[0], flush=True)
        if (name, order, seed) == ("purcell3", 3, 0):
            slsqp_p3 = res.value  # type: ignore[attr-defined]
    speed, secs, n = cobyla("purcell3", 3)
    lines += ["", "## Second method: COBYLA (derivative free) on purcell3, K = 3, from the nominal gait", "",
              f"COBYLA: {speed:.6f} m/s in {secs:.1f} s ({n} steady-state evaluations); "
              f"SLSQP multi-start: {slsqp_p3:.6f} m/s; difference {100 * (slsqp_p3 / speed - 1):+.3f} %.", ""]
    text = "\n".join(lines) + "\n"
    write("optimize.md", text)


if __name__ == "__main__":
    main()
