"""Regression rows from a stream of phased samples, a block at a time.

The live estimator hands over each paired, phased sample (t, r, pose, φ); this module turns
them into the rows the SUDS regression learns from, exactly as the batch identifier does over
a whole recording, but vectorised over blocks of samples:

* **shape intervals** k → k + 1: X = [φ̄, δ, δ̇_a, r, ṙ_a] at the state ``suds.state`` names,
  Y = [ξ, ṙ_p] (the passive rates are fitted row by row; ξ is kept for publishing);
* **pose intervals**: each pose interval lying inside the shape samples seen so far becomes
  one averaged body row: the duration-weighted mean of the segment rows over the shape
  intervals it overlaps (:func:`~suds_ros.core.ident.intervals.segment_features`), against
  the measured twist log(g₀⁻¹g₁)/(t₁ − t₀).

A block is turned into rows when :meth:`StreamFeaturiser.rows` is called; a pose interval
becomes a row in the first call whose last shape stamp is at or after its end, so the split of
a stream into blocks does not change which rows a block holds.  Between blocks only the last
sample (the next interval's start) and the shape samples a pending pose interval can still
need are kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from suds_ros.core import se2
from suds_ros.core._typing import FloatArray, IntArray
from suds_ros.core.ident.intervals import covered_segments, interval_features, segment_features
from suds_ros.core.ident.sysid import SudsConfig, interval_state
from suds_ros.core.phase.template import FourierTemplate


@dataclass(frozen=True)
class Rows:
    """The rows of one block.

    Attributes
    ----------
    t : (m,) stamps of the shape intervals' end samples, s.
    X : (m, 1 + 2·(nj + na)) shape-interval regressor rows.
    Y : (m, 3 + np) measured [ξ, ṙ_p] of the shape intervals.
    seg_X : (s, 1 + 2·(nj + na)) regressor rows of the pose intervals' segments.
    seg_w : (s,) each segment's share of its pose interval.
    seg_row : (s,) int, the pose interval (0 … q − 1) of each segment.
    xi : (q, 3) measured body velocity of each pose interval.
    """

    t: FloatArray
    X: FloatArray
    Y: FloatArray
    seg_X: FloatArray
    seg_w: FloatArray
    seg_row: IntArray
    xi: FloatArray


class StreamFeaturiser:
    """Rows from phased samples (see module docstring).

    Parameters
    ----------
    suds : SudsConfig
        Gives the interval state (``suds.state``).
    template : FourierTemplate
        θ(φ), fitted.
    omega : float
        Mean phase rate ω̄, rad/s.
    act, pas : (na,), (np,) int
        Joint indices of the actuated and passive joints.
    max_interval : float
        Longest shape interval, s, that counts as measured.  A longer one spans a run of lost
        samples: it gives no row, and nor does a pose interval that overlaps it (as the batch
        identifier leaves out what was bridged, :data:`~suds_ros.core.resample.BRIDGED_RUN`).
    """

    def __init__(self, suds: SudsConfig, template: FourierTemplate, omega: float, act: IntArray,
                 pas: IntArray, max_interval: float = float("inf")) -> None:
        self.suds = suds
        self.max_interval = float(max_interval)
        self.template = template
        self.omega = float(omega)
        self.act = np.asarray(act, dtype=int)
        self.pas = np.asarray(pas, dtype=int)
        nj = int(template.coef_.shape[1])
        self.n_joints = nj
        # samples given but not yet turned into rows; the first of them may be the carried last one
        self._t: list[float] = []
        self._r: list[FloatArray] = []
        self._p: list[FloatArray] = []
        self._ph: list[float] = []
        self._carried = False  # True when the buffers start with the previous block's last sample
        self.first_stamp = float("nan")
        # shape samples a pending pose interval may still need: stamps, joints, phases
        self._hist_t = np.zeros(0)
        self._hist_r = np.zeros((0, nj))
        self._hist_ph = np.zeros(0)
        # poses not yet used as a pose-interval start
        self._pose_t = np.zeros(0)
        self._pose = np.zeros((0, 3))
        self._new_pose_t: list[float] = []
        self._new_pose: list[tuple[float, float, float]] = []

    @property
    def pending(self) -> int:
        """Shape intervals given but not yet turned into rows."""
        return max(len(self._t) - 1, 0)

    def add_pose(self, t: float, pose: tuple[float, float, float]) -> None:
        """A pose sample (stamp s; x, y m; unwrapped yaw rad), in stamp order."""
        self._new_pose_t.append(t)
        self._new_pose.append(pose)

    def add(self, t: float, r: FloatArray, pose: FloatArray, phase: float) -> None:
        """A paired, phased shape sample, in stamp order."""
        if np.isnan(self.first_stamp):
            self.first_stamp = t
        self._t.append(t)
        self._r.append(r)
        self._p.append(pose)
        self._ph.append(phase)

    def rows(self) -> Rows:
        """Turn what was given since the last call into rows."""
        T = np.asarray(self._t, dtype=float)
        nj = self.n_joints
        R = np.asarray(self._r, dtype=float).reshape(T.size, nj)
        P = np.asarray(self._p, dtype=float).reshape(T.size, 3)
        PH = np.asarray(self._ph, dtype=float)
        new = slice(1 if self._carried else 0, None)
        if T.size:  # carry the last sample: it starts the next block's first interval
            self._t, self._r, self._p, self._ph = [self._t[-1]], [self._r[-1]], [self._p[-1]], [self._ph[-1]]
            self._carried = True
        shape = self._shape_rows(T, R, P, PH)
        self._hist_t = np.concatenate([self._hist_t, T[new]])
        self._hist_r = np.concatenate([self._hist_r, R[new]])
        self._hist_ph = np.concatenate([self._hist_ph, PH[new]])
        seg = self._pose_rows(T[-1] if T.size else -np.inf)
        return Rows(*shape, *seg)

    def _shape_rows(self, T: FloatArray, R: FloatArray, P: FloatArray, PH: FloatArray
                    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        d = 1 + 2 * (self.n_joints + self.act.size)
        if T.size < 2:
            return np.zeros(0), np.zeros((0, d)), np.zeros((0, 3 + self.pas.size))
        dt = T[1:] - T[:-1]
        rdot = (R[1:] - R[:-1]) / dt[:, None]
        X = interval_features(self.template, self.omega, self.act, 0.5 * (PH[:-1] + PH[1:]),
                              interval_state(self.suds, R[:-1], R[1:]), rdot)
        xi = se2.log(se2.relative(P[:-1], P[1:])) / dt[:, None]
        keep = dt <= self.max_interval
        return T[1:][keep], X[keep], np.concatenate([xi, rdot[:, self.pas]], axis=1)[keep]

    def _pose_rows(self, t_now: float) -> tuple[FloatArray, FloatArray, IntArray, FloatArray]:
        if self._new_pose_t:
            self._pose_t = np.concatenate([self._pose_t, self._new_pose_t])
            self._pose = np.concatenate([self._pose, np.asarray(self._new_pose, dtype=float).reshape(-1, 3)])
            self._new_pose_t, self._new_pose = [], []
        pt = self._pose_t
        n_done = int(np.searchsorted(pt, t_now, side="right"))  # poses at or before t_now
        d = 1 + 2 * (self.n_joints + self.act.size)
        empty = (np.zeros((0, d)), np.zeros(0), np.zeros(0, dtype=int), np.zeros((0, 3)))
        if n_done < 2:
            return empty
        t0, t1 = pt[: n_done - 1], pt[1:n_done]
        g0, g1 = self._pose[: n_done - 1], self._pose[1:n_done]
        keep = t0 >= self.first_stamp
        t0, t1, g0, g1 = t0[keep], t1[keep], g0[keep], g1[keep]
        # the last pose at or before t_now starts the next pose interval
        self._pose_t, self._pose = pt[n_done - 1:], self._pose[n_done - 1:]
        H = self._hist_t
        out = empty
        if t0.size and H.size >= 2:
            # a pose interval over a shape interval too long to be measured (lost samples): no row
            measured = np.flatnonzero(np.diff(H) <= self.max_interval)
            whole, rows, k, s0, s1, share = covered_segments(H[:-1][measured], H[1:][measured], t0, t1)
            k = measured[k]
            t0, t1, g0, g1 = t0[whole], t1[whole], g0[whole], g1[whole]
            Xs = segment_features(self.suds, self.template, self.omega, self.act, H, self._hist_r,
                                  self._hist_ph, k, 0.5 * (s0 + s1))
            xi = se2.log(se2.relative(g0, g1)) / (t1 - t0)[:, None]
            out = (Xs, share, rows, xi)
        # forget the shape samples no later pose interval can need (keep the one at or before its start)
        start = self._pose_t[0]
        i = max(int(np.searchsorted(H, start, side="right")) - 1, 0)
        self._hist_t, self._hist_r, self._hist_ph = H[i:], self._hist_r[i:], self._hist_ph[i:]
        return out
