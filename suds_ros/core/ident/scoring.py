"""Scoring identified models: the paper's Γ, predictions on held-out intervals and their scores.

Γ = 1 − Σ|model − truth| / Σ|template − truth| compares a model with the
phase-only template (the mean velocity at each phase): 1 is perfect, 0 is no
better than the template.  Output channels are named ``xi_*`` (body velocity),
``rdot_<joint>`` (passive joint velocities) and ``tau_<joint>`` (actuator effort).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from suds_ros.core._typing import BoolArray, FloatArray
from suds_ros.core.errors import SudsDataError

if TYPE_CHECKING:
    from suds_ros.core.recording import Recording

BODY_CHANNELS = ("xi_x", "xi_y", "xi_theta")


def gamma(pred: FloatArray, template: FloatArray, truth: FloatArray) -> float:
    """Γ = 1 − Σ|pred − truth| / Σ|template − truth| over all samples and channels given."""
    num = float(np.abs(pred - truth).sum())
    den = float(np.abs(template - truth).sum())
    if den == 0:
        raise SudsDataError("Γ undefined: the template reproduces the truth exactly")
    return 1.0 - num / den


@dataclass(frozen=True)
class PoseIntervalPrediction:
    """Body velocity as measured over pose intervals, and the predictions averaged over them.

    Attributes
    ----------
    t : (q,) pose-interval midpoint stamps, s.
    truth : (q, 3) measured body velocity (pose displacement over the interval / its duration).
    model, template : (q, 3) the shape-interval predictions averaged over each pose interval.
    """

    t: FloatArray
    truth: FloatArray
    model: FloatArray
    template: FloatArray


def average_over_pose_intervals(rec: "Recording", model: FloatArray, template: FloatArray, window: int = 1,
                                keep: BoolArray | None = None) -> PoseIntervalPrediction | None:
    """Body-channel predictions on the shape intervals of ``rec``, averaged over its pose intervals.

    Returns the averaged predictions (rows: the shape intervals k → k + ``window``, or those of
    them ``keep`` marks; columns ``BODY_CHANNELS`` first) beside the measured body velocity
    there; None when both streams share their stamps (nothing to average).  A pose interval
    over a shape interval left out (a hole in ``keep``) is left out too.

    The predictions are taken as constant on each shape interval, so the average is the
    overlap-weighted mean (what a live predictor publishing one value per interval claims).
    """
    from suds_ros.core.ident.intervals import pose_intervals

    t0, t1 = rec.t[:-window], rec.t[window:]
    if keep is not None:
        t0, t1 = t0[keep], t1[keep]
    pv = pose_intervals(rec, t0, t1, window)
    mid = 0.5 * (t0 + t1)
    if pv.is_identity(mid):
        return None
    W = pv.over_shape(mid.size)
    nb = len(BODY_CHANNELS)
    return PoseIntervalPrediction(t=0.5 * (pv.t0 + pv.t1), truth=pv.xi,
                                  model=np.asarray(W @ model[:, :nb]), template=np.asarray(W @ template[:, :nb]))


@dataclass(frozen=True)
class Prediction:
    """Predictions on the intervals of one recording.

    Attributes
    ----------
    t : (m,) interval midpoint stamps, s.
    phase : (m,) gait phase at the midpoints, rad (unwrapped).
    channels : names of the m outputs' columns.
    truth : (m, c) measured outputs.
    model : (m, c) SUDS model predictions.
    template : (m, c) phase-only template predictions.
    body : PoseIntervalPrediction or None
        When the pose stream has its own stamps: the body channels as measured over the pose
        intervals, which score the body velocity (the shape-interval ``truth`` of the body
        channels then comes from interpolated poses and is only indicative).
    """

    t: FloatArray
    phase: FloatArray
    channels: tuple[str, ...]
    truth: FloatArray
    model: FloatArray
    template: FloatArray
    body: PoseIntervalPrediction | None = None

    def columns(self, prefix: str) -> list[int]:
        """Indices of the channels whose name starts with ``prefix``."""
        return [i for i, c in enumerate(self.channels) if c.startswith(prefix)]


@dataclass(frozen=True)
class Scores:
    """Held-out accuracy.

    ``gamma_body``/``gamma_passive``: Γ over the body-velocity / passive-velocity channels
    (``gamma_passive`` None for a fully actuated chain: no passive channel, the score does not
    apply); ``gamma_torque`` likewise None without effort channels;
    ``rms_model``/``rms_template``: per-channel RMS errors.
    """

    gamma_body: float
    gamma_passive: float | None
    gamma_torque: float | None
    rms_model: dict[str, float]
    rms_template: dict[str, float]
    n_samples: int

    def as_dict(self) -> dict[str, object]:
        """JSON-ready dictionary.

        None stands for a score that does not apply; write it with
        :func:`~suds_ros.core.json_text.dumps`, which also turns a non-finite Γ into null.
        """
        return {
            "gamma_body": self.gamma_body,
            "gamma_passive": self.gamma_passive,
            "gamma_torque": self.gamma_torque,
            "rms_model": self.rms_model,
            "rms_template": self.rms_template,
            "n_samples": self.n_samples,
        }


def score_prediction(p: Prediction) -> Scores:
    """Γ per channel group and per-channel RMS of a :class:`Prediction` (:class:`ScoreSums` of all of it).

    The body channels are scored over the pose intervals when ``p.body`` is given.
    """
    sums = ScoreSums(p.channels)
    if p.body is None:
        sums.add(p.truth, p.model, p.template)
    else:  # the other channels over the shape intervals, the body channels over the pose intervals
        b = p.body
        sums.add(p.truth, p.model, p.template, body=np.zeros(p.t.size, dtype=bool))
        j = [BODY_CHANNELS.index(p.channels[i]) for i in p.columns("xi_")]
        sums.add_columns(slice(0, len(j)), b.truth[:, j], b.model[:, j], b.template[:, j])
    return sums.scores()


class ScoreSums:
    """The sums behind :func:`score_prediction`, added a block of intervals at a time.

    :meth:`add` takes the measured outputs, model and template predictions of consecutive
    intervals; :meth:`scores` gives the :class:`Scores` that :func:`score_prediction` gives for
    all of them at once (the same sums, added in another order).  Rows whose body channels
    have no measurement (``body`` False: no pose at an end of the interval) count for the other
    channels only, as the pose intervals of :func:`score_prediction` would score them.

    Parameters
    ----------
    channels : names of the c output columns (``xi_*`` first, then ``rdot_*``, ``tau_*``).
    """

    def __init__(self, channels: tuple[str, ...]) -> None:
        c = len(channels)
        self.channels = tuple(channels)
        self.abs_model, self.abs_template = np.zeros(c), np.zeros(c)
        self.sq_model, self.sq_template = np.zeros(c), np.zeros(c)
        self.peak = np.zeros(c)  # max |template| and |truth|: does the channel move at all
        self.rows = np.zeros(c, dtype=np.int64)
        self.n = 0

    def add(self, truth: FloatArray, model: FloatArray, template: FloatArray,
            body: np.ndarray | None = None) -> None:
        """Add intervals: ``truth``, ``model``, ``template`` (m, c); ``body`` (m,) bool or None (all)."""
        nb = sum(1 for ch in self.channels if ch.startswith("xi_"))
        self.n += int(truth.shape[0])
        for cols, keep in ((slice(0, nb), body), (slice(nb, None), None)):
            y, m, t = truth[:, cols], model[:, cols], template[:, cols]
            if keep is not None:
                y, m, t = y[keep], m[keep], t[keep]
            self.add_columns(cols, y, m, t)

    def add_columns(self, cols: slice, truth: FloatArray, model: FloatArray, template: FloatArray) -> None:
        """Add rows of the channels ``cols`` alone (e.g. the body channels over pose intervals).

        Unlike :meth:`add` this does not count samples (``n_samples`` counts the intervals).
        """
        em, et = model - truth, template - truth
        self.abs_model[cols] += np.abs(em).sum(axis=0)
        self.abs_template[cols] += np.abs(et).sum(axis=0)
        self.sq_model[cols] += (em * em).sum(axis=0)
        self.sq_template[cols] += (et * et).sum(axis=0)
        if truth.shape[0]:
            self.peak[cols] = np.maximum(self.peak[cols], np.maximum(np.abs(template).max(axis=0),
                                                                     np.abs(truth).max(axis=0)))
        self.rows[cols] += truth.shape[0]

    def scores(self) -> Scores:
        """The :class:`Scores` of everything added."""
        ch = self.channels

        def g(prefix: str, moving: bool = False) -> float | None:
            cols = [i for i, c in enumerate(ch) if c.startswith(prefix)]
            if not cols:
                return None
            if moving:
                cols = [i for i in cols if self.peak[i] > 1e-9]
                if not cols:
                    return float("nan")
            den = float(self.abs_template[cols].sum())
            if den == 0:
                raise SudsDataError("Γ undefined: the template reproduces the truth exactly")
            return 1.0 - float(self.abs_model[cols].sum()) / den

        rows = np.maximum(self.rows, 1)
        body = g("xi_", moving=True)
        return Scores(
            gamma_body=float("nan") if body is None else body,
            gamma_passive=g("rdot_"), gamma_torque=g("tau_"),
            rms_model={c: float(np.sqrt(self.sq_model[i] / rows[i])) for i, c in enumerate(ch)},
            rms_template={c: float(np.sqrt(self.sq_template[i] / rows[i])) for i, c in enumerate(ch)},
            n_samples=self.n,
        )
