"""Live prediction with an identified model, and the policy for switching models mid-stream.

:class:`StreamingPredictor` turns a stream of shape samples into predictions of
the body and passive-joint velocities over each interval; :func:`carry_over`
decides how a new model takes over a running stream without a gap;
:func:`evaluate_model` runs a predictor over a recording for scoring.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsDataError, SudsError
from suds_ros.core.ident.intervals import make_intervals
from suds_ros.core.ident.model import SudsModel, check_shape_sample, check_stamp, model_template
from suds_ros.core.ident.scoring import Prediction, average_over_pose_intervals
from suds_ros.core.phase.phase_tracker import PhaseTracker
from suds_ros.core.ident.sysid import interval_state
from suds_ros.core.recording import Recording


class JointSample(Protocol):
    """A shape sample: stamp (s), joint names and positions."""

    stamp: float
    names: tuple[str, ...]
    position: FloatArray


def nearest_phase(template: object, r: FloatArray, n_grid: int = 720) -> float:
    """Phase in [0, 2π) whose θ(φ) is closest to the shape ``r`` (nj,) (grid search)."""
    grid = np.linspace(0.0, 2 * np.pi, n_grid, endpoint=False)
    theta = template.predict(grid)  # type: ignore[attr-defined]
    scale = theta.std(axis=0)
    scale = np.where(scale > 1e-9, scale, 1.0)
    d = (((theta - r) / scale) ** 2).sum(axis=1)
    return float(grid[int(np.argmin(d))])


class StreamingPredictor:
    """Live predictions of (ξ, ṙ_p) from shape samples with an identified :class:`SudsModel`.

    Each shape sample closes the interval from the previous one; the prediction is the
    model's output for that interval (the state its ``suds.state`` names, midpoint phase,
    forward-difference rate),
    i.e. the mean body and passive velocity over the interval ending at the sample.
    The phase is initialised at the template point nearest the first sample and then tracked.
    """

    def __init__(self, model: SudsModel) -> None:
        self.model = model
        self.template = model_template(model)
        self.passive = model.passive
        self._tracker: PhaseTracker | None = None
        self._prev: tuple[float, FloatArray, float] | None = None
        self.last_stamp = -np.inf
        self.last_phase = float("nan")  # tracked phase at the last sample, rad
        self.last_mid_phase = float("nan")  # phase at the last predicted interval's midpoint, rad

    def shares_phase_with(self, model: SudsModel) -> bool:
        """True when ``model`` has this predictor's joints, template and phase rate (phase carries over)."""
        return (model.joint_names == self.model.joint_names
                and model.omega == self.model.omega
                and np.array_equal(model.template_coef, self.model.template_coef))

    def with_model(self, model: SudsModel) -> StreamingPredictor:
        """A predictor for ``model`` that continues this one's stream without a restart.

        When the new model shares this one's template and phase rate (a refit of the same
        gait), the phase tracker, the last sample and the stamp check carry over, so the
        next sample is predicted at once and the phase is continuous.  Otherwise the new
        predictor is fresh: it re-initialises its phase at the next sample.
        """
        new = StreamingPredictor(model)
        if self._tracker is not None and self.shares_phase_with(model):
            new._tracker = self._tracker
            new._prev = self._prev
            new.last_stamp = self.last_stamp
        return new

    def update(self, t: float, names: tuple[str, ...], position: FloatArray) -> tuple[FloatArray, FloatArray] | None:
        """Predicted ξ (3,) and ṙ_p (np,) for the interval ending at ``t``; None for the first sample.

        Raises
        ------
        SudsDataError
            Wrong joint names or count, NaN, duplicate or out-of-order stamp.
        """
        r = check_shape_sample(t, tuple(names), position, self.model.joint_names)
        check_stamp("shape", t, self.last_stamp)
        self.last_stamp = t
        if self._tracker is None:
            phase = nearest_phase(self.template, r)
            self._tracker = PhaseTracker(self.template, self.model.omega, phase, t)
        else:
            phase = float(self._tracker.update(t, r))
        prev = self._prev
        self._prev = (t, r, phase)
        self.last_phase = phase
        if prev is None:
            return None
        tp, rp, php = prev
        self.last_mid_phase = 0.5 * (php + phase)
        out = self.model.predict(
            np.array([0.5 * (php + phase)]), interval_state(self.model.suds, rp, r)[None], ((r - rp) / (t - tp))[None]
        )[0]
        return out[:3], out[3 : 3 + len(self.passive)]


def carry_over(old: StreamingPredictor | None, model: SudsModel,
               last: JointSample | None) -> tuple[StreamingPredictor, str]:
    """A predictor for ``model`` that keeps the running state of ``old`` or is primed with ``last``.

    Returns the predictor and how continuity was kept: ``"tracker"`` (same template and
    phase rate: the phase tracker carries over), ``"primed"`` (fed the last shape sample
    ``last`` — anything with ``stamp``, ``names`` and ``position`` — so the next one is
    predicted) or ``"fresh"``.
    """
    if old is not None and old.last_stamp > -np.inf and old.shares_phase_with(model):
        return old.with_model(model), "tracker"
    new = StreamingPredictor(model)
    if last is not None:
        try:
            new.update(last.stamp, last.names, last.position)
            return new, "primed"
        except SudsError:
            pass
    return new, "fresh"


def evaluate_model(model: SudsModel, rec: Recording) -> Prediction:
    """Run :class:`StreamingPredictor` over a recording and compare with its measured velocities.

    Returns a :class:`~suds_ros.core.ident.scoring.Prediction` whose ``template`` column is the model's
    phase-only template at the tracked phases (score it with ``score_prediction``).
    """
    if rec.joint_names != model.joint_names or rec.actuated != model.actuated:
        raise SudsDataError(
            f"recording joints {list(rec.joint_names)} (actuated {list(rec.actuated)}) differ from the "
            f"model's {list(model.joint_names)} (actuated {list(model.actuated)})"
        )
    pred = StreamingPredictor(model)
    out, phases = [], []
    for k in range(rec.n_samples):
        o = pred.update(float(rec.t[k]), rec.joint_names, rec.r[k])
        if o is not None:
            out.append(np.concatenate(o))
            phases.append(pred.last_mid_phase)
    iv = make_intervals(rec)
    ph = np.asarray(phases)
    truth = np.concatenate([iv.xi, iv.rdot[:, rec.passive_index]], axis=1)
    pred_rows, template = np.asarray(out), model.template(ph)
    return Prediction(
        t=iv.t, phase=ph, channels=model.channels, truth=truth, model=pred_rows, template=template,
        body=average_over_pose_intervals(rec, pred_rows, template),
    )
