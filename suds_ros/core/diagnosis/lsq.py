"""Forward-difference Jacobians with absolute steps for :func:`scipy.optimize.least_squares`.

least_squares' own finite differences step by ``diff_step·|x|``: at a parameter's neutral value
of 0 (a time offset, a flow, a rest offset) the step falls back to ~1e-8, far below what the
residual resolves (a pose-stamp shift of 1e-8 s disappears in stamps of 1.7e9 s, and the fit
stopped at once on a zero gradient: a 10 ms offset with 3950 nats of evidence was fitted as 0).
Here each parameter's step is ``max(rel·|x_i|, floor_i)``, with ``floor_i`` a fraction of the
parameter's typical scale, and it steps away from an upper bound it would cross.  With
``parallel`` the columns are computed in worker processes (:func:`suds_ros.core.parallel.fork_map`,
as many as the caller's :func:`~suds_ros.core.parallel.workers` block allows): worth it when one
evaluation is a replay of the recording, not a fraction of a second.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.parallel import fork_map


def fd_jacobian(
    fun: Callable[..., FloatArray], x: FloatArray, f0: FloatArray, steps: FloatArray, hi: FloatArray,
    *args: Any, parallel: bool = False,
) -> FloatArray:
    """Forward differences of ``fun(x, *args)`` (value ``f0`` at ``x``) with absolute ``steps``."""
    points = []
    for i in range(x.size):
        h = float(steps[i]) if x[i] + steps[i] <= hi[i] else -float(steps[i])
        xp = np.array(x, dtype=float)
        xp[i] += h
        points.append(xp)
    values = fork_map(lambda xp: np.ravel(fun(xp, *args)), points, None if parallel else 1)
    J = np.empty((np.size(f0), x.size))
    for i, (xp, v) in enumerate(zip(points, values)):
        J[:, i] = (v - np.ravel(f0)) / (xp[i] - x[i])
    return J


def with_jacobian(
    fun: Callable[..., FloatArray], rel: float, floor: FloatArray, hi: FloatArray, parallel: bool = False,
) -> tuple[Callable[..., FloatArray], Callable[..., FloatArray]]:
    """``(fun, jac)`` for least_squares with steps ``max(rel·|x_i|, floor_i)`` (``parallel``: as :func:`fd_jacobian`).

    The returned ``fun`` remembers its last value, so ``jac`` at the same point costs one
    evaluation per parameter.
    """
    last: dict[str, Any] = {}

    def value(x: FloatArray, *args: Any) -> FloatArray:
        out = fun(x, *args)
        last.update(x=np.array(x, dtype=float), f=out, args=args)
        return out

    def jac(x: FloatArray, *args: Any) -> FloatArray:
        same = ("x" in last and np.array_equal(last["x"], x) and len(last["args"]) == len(args)
                and all(a is b for a, b in zip(last["args"], args)))
        f0 = last["f"] if same else fun(x, *args)
        return fd_jacobian(fun, x, f0, np.maximum(rel * np.abs(x), floor), hi, *args, parallel=parallel)

    return value, jac
