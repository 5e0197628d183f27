"""Model-free tests on recorded cycles: Hotelling's T², and whether a gait's passive shapes moved between runs.

The loop (:mod:`~suds_ros.core.optimize.loop`) asks two questions of the cycles it measured that no
model should answer:

* does the robot move at all under a gait (:func:`hotelling_p` on the cycles' translations, used by
  ``loop.translation_p``);
* did the robot change between two runs of the *same* gait (:func:`passive_shift`).  The passive
  joints' angles over a cycle are set by the springs against the drag, so a stiffer or bent spring,
  another drag, damping or friction shows in them directly, whatever the body does.  Each cycle of
  each passive joint is summarised by the least-squares mean, cosine and sine of its angle over the
  cycle's phase, and the two runs' cycles are compared by a two-sample T² per joint.  No model of a
  few cycles enters, so a model's error where it extrapolates cannot raise the alarm (the body's
  ``data.motion_miss`` does: ``docs/results/optimize_miss.md``).  A change that leaves the shapes as
  they were (a uniform current) does not show here; the loop's measured-speed test sees that.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import TOO_LITTLE_DATA, SudsDataError
from suds_ros.core.fourier import fourier_basis
from suds_ros.core.recording import Recording

#: per-cycle features of a passive joint: its angle's mean, cosine and sine over the cycle's phase
FEATURES = 3
#: fewest samples in a cycle for its features to be fitted
MIN_SAMPLES = 2 * FEATURES


def hotelling_p(mean: FloatArray, cov: FloatArray, n: float, dof: int) -> float:
    """P-value of Hotelling's T² = n · meanᵀ cov⁻¹ mean, with ``cov`` estimated on ``dof`` degrees of freedom.

    (dof − q + 1) T² / (q · dof) is F(q, dof − q + 1) distributed under the null (normal draws): the
    one-sample test of m rows has n = m, dof = m − 1; the two-sample test of a difference of means
    has n = 1 / (1/m₁ + 1/m₂), dof = m₁ + m₂ − 2.  Directions in which ``cov`` has no spread (a
    noise-free run) are left out of q, unless ``mean`` has a component along one: then 0.  1 where
    nothing is left, or too few degrees of freedom for what is.
    """
    from scipy import stats

    mean, cov = np.asarray(mean, dtype=float), np.atleast_2d(np.asarray(cov, dtype=float))
    w, v = np.linalg.eigh(cov)
    top = float(max(np.max(w), np.max(np.abs(mean)) ** 2, 0.0))
    if top == 0.0:
        return 1.0
    keep = w > 1e-12 * top
    z = v.T @ mean
    if np.any(np.abs(z[~keep]) > 1e-6 * math.sqrt(top)):  # a mean off every direction the rows spread in
        return 0.0
    q = int(np.count_nonzero(keep))
    if q == 0 or dof - q + 1 < 1:
        return 1.0
    t2 = n * float(np.sum(z[keep] ** 2 / w[keep]))
    return float(stats.f.sf((dof - q + 1) * t2 / (q * dof), q, dof - q + 1))


def passive_features(rec: Recording, gait_hz: float) -> FloatArray:
    """Per whole cycle from ``rec.t[0]`` (a cycle boundary), each passive joint's (mean, cos, sin) fit, rad.

    The angle over cycle c is fitted by least squares as a + b·cos φ + c·sin φ, φ = 2π (f (t − t₀) − c),
    on whatever samples the cycle has (any rate, gaps).  Returns (cycles, 3, passive joints).

    Raises
    ------
    SudsDataError
        No whole cycle, or a cycle with fewer than ``MIN_SAMPLES`` samples (code ``too_little_data``).
    """
    t = np.asarray(rec.t, dtype=float) - float(rec.t[0])
    u = t * gait_hz
    whole = int(math.floor(u[-1] + 1e-9))
    if whole < 1:
        raise SudsDataError(f"`rec`: expected at least one whole gait cycle, got {u[-1]:.3g}", code=TOO_LITTLE_DATA)
    cyc = np.floor(u + 1e-9).astype(int)
    r = np.asarray(rec.r, dtype=float)[:, rec.passive_index]
    out = np.empty((whole, FEATURES, r.shape[1]))
    for c in range(whole):
        sel = cyc == c
        if np.count_nonzero(sel) < MIN_SAMPLES:
            raise SudsDataError(f"`rec`: expected at least {MIN_SAMPLES} samples in gait cycle {c}, got "
                                f"{int(np.count_nonzero(sel))}", code=TOO_LITTLE_DATA)
        out[c] = np.linalg.lstsq(fourier_basis(2 * np.pi * (u[sel] - c), 1), r[sel], rcond=None)[0]
    return out


@dataclass(frozen=True)
class PassiveShift:
    """How a run's passive shapes differ from those of earlier runs of the same gait.

    Attributes
    ----------
    p : float, the smallest per-joint p-value of the two-sample T², times the number of passive joints
        (Bonferroni), at most 1.
    size : float, rad: that joint's RMS over the cycle of the difference of the two mean fits.
    joint : str, the joint.
    cycles : (int, int), cycles compared (earlier runs, the new run).
    start : int or None, the first of the new run's trailing cycles that each lie nearer its own
        mean than the earlier runs' (in the pooled cycles' metric): where a change began; None when
        its last cycle does not.
    """

    p: float
    size: float
    joint: str
    cycles: tuple[int, int]
    start: int | None


def passive_shift(standing: Recording | Sequence[Recording], new: Recording, gait_hz: float) -> PassiveShift | None:
    """Compare ``new``'s passive shapes with those of ``standing`` (earlier runs of the same gait).

    Every stretch starts at a cycle boundary.  None for a robot without passive joints.

    Raises
    ------
    SudsDataError
        Fewer than 5 whole cycles in all, fewer than 2 on either side, or a cycle with too few
        samples (code ``too_little_data``).
    """
    old_recs = [standing] if isinstance(standing, Recording) else list(standing)
    if not new.passive:
        return None
    a = np.concatenate([passive_features(s, gait_hz) for s in old_recs])
    b = passive_features(new, gait_hz)
    na, nb = a.shape[0], b.shape[0]
    if na < 2 or nb < 2 or na + nb < FEATURES + 2:
        raise SudsDataError(f"`standing`, `new`: expected at least 2 whole cycles each and {FEATURES + 2} in all, "
                            f"got {na} and {nb}", code=TOO_LITTLE_DATA)
    ma, mb = a.mean(axis=0), b.mean(axis=0)  # (3, np)
    da, db = a - ma, b - mb
    pooled = (np.einsum("kij,klj->jil", da, da) + np.einsum("kij,klj->jil", db, db)) / (na + nb - 2)  # (np, 3, 3)
    n_eff = 1.0 / (1.0 / na + 1.0 / nb)
    ps = np.array([hotelling_p(ma[:, j] - mb[:, j], pooled[j], n_eff, na + nb - 2) for j in range(a.shape[2])])
    j = int(np.argmin(ps))
    d = ma[:, j] - mb[:, j]
    size = math.sqrt(d[0] ** 2 + (d[1] ** 2 + d[2] ** 2) / 2)
    # where it began: each new cycle nearer the new mean or the old, in the pooled metric (all joints)
    inv = np.stack([np.linalg.pinv(pooled[i], rcond=1e-10, hermitian=True) for i in range(a.shape[2])])

    def dist(x: FloatArray, m: FloatArray) -> FloatArray:  # (nb,) summed over the joints
        e = x - m[None]
        return np.einsum("kij,jil,klj->k", e, inv, e)

    nearer_new = dist(b, mb) < dist(b, ma)
    start = None
    if nearer_new[-1]:  # just after the last cycle still nearer the old shapes (0: none is)
        older = np.flatnonzero(~nearer_new)
        start = int(older[-1] + 1) if older.size else 0
    return PassiveShift(p=float(min(1.0, ps[j] * ps.size)), size=size, joint=new.passive[j], cycles=(na, nb),
                        start=start)
