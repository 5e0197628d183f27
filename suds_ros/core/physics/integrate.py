"""The one integrator of the package: batched RK4 for the passive joints, a Lie-group step for the pose.

The actuated joints follow set-points given at the sample times and linearly interpolated
between them (a servo set-point stream), so ṙ_a is constant within each sample interval.  The
passive joints are integrated with classical RK4 (``substeps`` steps per sample interval), and
the body pose with the fourth-order commutator-free Lie-group method (Celledoni, Marthinsen &
Owren 2003) built on the same RK4 stages, using exact SE(2) exponentials
(:func:`suds_ros.core.se2.exp_step`):

    g_{n+1} = g_n · exp(h(¼ξ₁ + ⅙ξ₂ + ⅙ξ₃ − 1/12 ξ₄)) · exp(h(−1/12 ξ₁ + ⅙ξ₂ + ⅙ξ₃ + ¼ξ₄))

for ġ = g ξ with ξ the body velocity.  B independent runs (segments) are integrated at once:
every velocity evaluation is one batched call.  The simulator (:mod:`suds_ros.core.physics.sim`)
integrates one run (B = 1); the diagnosis replays many recorded segments (B > 1).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from suds_ros.core import se2
from suds_ros.core._typing import FloatArray, IntArray
from suds_ros.core.errors import SudsSimulationError

#: ``velocities(r, ṙ_a) -> (ξ, ṙ_p)`` for shapes r (B, nj) and set-point rates ṙ_a (B, na): the
#: still-fluid body velocity (B, 3) and passive joint velocities (B, np), as
#: :meth:`~suds_ros.core.physics.system.SudsSystem.velocities`.
Velocities = Callable[[FloatArray, FloatArray], tuple[FloatArray, FloatArray]]


def integrate_batch(
    velocities: Velocities,
    actuated: IntArray,
    passive: IntArray,
    r_a: FloatArray,
    r_p0: FloatArray,
    pose0: FloatArray,
    dt: float | FloatArray,
    substeps: int,
    progress: Callable[[int, int], None] | None = None,
    reset: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Integrate B independent runs under piecewise-linear actuated set-points (still fluid).

    Parameters
    ----------
    velocities : callable
        ``velocities(r, rdot_a) -> (xi, rdot_p)``, batched over the first axis (see :data:`Velocities`).
    actuated, passive : (na,), (np,) int
        Column of each actuated / passive joint in the full shape vector.
    r_a : (B, m, na) float
        Actuated set-points at the m sample times (spacing ``dt``).
    r_p0 : (B, np) float
        Passive joint values at the first sample.
    pose0 : (B, 3) float
        World pose (x, y, yaw) at the first sample.
    dt : float or (B,) float
        Sample interval, s: one for every run, or one per run (each run on its own uniform grid).
    substeps : int
        RK4 steps per sample interval.
    progress : callable, optional
        Called as ``progress(done, total)`` about every 1 % of the samples (and once at the end).
    reset : (B, m, np) float, optional
        Passive joint values the runs restart from at a sample (NaN: integrate on); a run
        re-anchored to a measured state after a stretch whose drive is unknown.

    Returns
    -------
    r_p : (B, m, np) float
        Passive joint values at the samples.
    pose : (B, m, 3) float
        Still-fluid world pose at the samples (add a uniform flow as U·t afterwards).
    """
    B, m, _ = r_a.shape
    act = np.asarray(actuated, dtype=int)
    pas = np.asarray(passive, dtype=int)
    rp = np.array(r_p0, dtype=float).reshape(B, pas.size)
    pose = np.array(pose0, dtype=float).reshape(B, 3)
    RP = np.empty((B, m, pas.size))
    P = np.empty((B, m, 3))
    RP[:, 0] = rp
    P[:, 0] = pose
    full = np.empty((B, act.size + pas.size))
    step = dt if np.ndim(dt) == 0 else np.asarray(dt, dtype=float).reshape(B, 1)
    h = step / substeps

    def f(ra: FloatArray, rp_: FloatArray, va: FloatArray) -> tuple[FloatArray, FloatArray]:
        full[:, act] = ra
        full[:, pas] = rp_
        return velocities(full, va)

    every = max(1, m // 100)
    with np.errstate(over="ignore", invalid="ignore"):  # a diverging run is refused below, with its reason
        for k in range(m - 1):
            if progress is not None and k % every == 0:
                progress(k, m - 1)
            va = (r_a[:, k + 1] - r_a[:, k]) / step
            for s in range(substeps):
                ra0 = r_a[:, k] + va * (s * h)
                xi1, k1 = f(ra0, rp, va)
                xi2, k2 = f(ra0 + va * (h / 2), rp + (h / 2) * k1, va)
                xi3, k3 = f(ra0 + va * (h / 2), rp + (h / 2) * k2, va)
                xi4, k4 = f(ra0 + va * h, rp + h * k3, va)
                rp = rp + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
                pose = se2.exp_step(pose, h * (xi1 / 4 + xi2 / 6 + xi3 / 6 - xi4 / 12))
                pose = se2.exp_step(pose, h * (-xi1 / 12 + xi2 / 6 + xi3 / 6 + xi4 / 4))
            if reset is not None:
                rk = reset[:, k + 1]
                rp = np.where(np.isfinite(rk), rk, rp)
            RP[:, k + 1] = rp
            P[:, k + 1] = pose
    if progress is not None:
        progress(m - 1, m - 1)
    # a run whose drive and start are finite must stay finite (callers may pass NaN starts on purpose)
    fed = np.isfinite(r_a).all(axis=(1, 2)) & np.isfinite(RP[:, 0]).all(axis=1)
    finite = np.isfinite(RP[fed]).all(axis=(0, 2))
    if not finite.all():
        k = int(np.argmin(finite))
        raise SudsSimulationError(
            f"the simulated motion diverged: the passive joints are not finite from sample {k} "
            f"of {m} ({k * float(np.max(step)):.3g} s) on; a passive joint is unstable (a softening cubic "
            "spring, k3 < 0, pushes a joint away beyond |r − rest| = √(k/|k3|)) or the time step is too long")
    return RP, P
