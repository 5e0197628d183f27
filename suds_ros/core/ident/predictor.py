"""Live prediction with an identified model, and the policy for switching models mid-stream.

:class:`StreamingPredictor` turns a stream of shape samples into predictions of
the body and passive-joint velocities over each interval; :func:`carry_over`
decides how a new model takes over a running stream without a gap;
:class:`GridPredictor` puts the live shape grid in front of both (the predictor
node's logic); :func:`evaluate_model` runs a predictor over a recording for scoring.
"""

from __future__ import annotations

from typing import NamedTuple, Protocol

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsDataError, SudsError
from suds_ros.core.ident.intervals import make_intervals, measured_intervals
from suds_ros.core.ident.model import SudsModel, check_shape_sample, check_stamp, joint_order, model_template
from suds_ros.core.ident.scoring import Prediction, average_over_pose_intervals
from suds_ros.core.phase.phase_tracker import PhaseTracker
from suds_ros.core.ident.sysid import interval_state
from suds_ros.core.recording import Recording
from suds_ros.core.resample import LiveGrid


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


class _Sample(NamedTuple):
    """A shape sample released by the grid stage: stamp (s), joint names, positions."""

    stamp: float
    names: tuple[str, ...]
    position: FloatArray


class GridPredictor:
    """The predictor node's logic without ROS: the live shape grid, then :class:`StreamingPredictor`.

    The estimator fits a shape stream with stamp jitter on its fitted uniform grid
    (:class:`~suds_ros.core.resample.LiveGrid`, ``OnlineConfig.regrid``), where each interval
    is one of the drive's straight segments; predicting the raw intervals instead cuts each
    segment's bend and reads worse than the model is (``docs/results/streaming_jitter.md``).
    With ``regrid`` this class runs the same stage on the same samples, so its predictions are
    for the grid intervals and stamped with their grid times, the times of the estimator's
    measured rows.  On a uniform stream (every simulator stream, an aligned bag) the stage
    passes each sample at once and unchanged: each prediction is made, and stamped, at the
    sample that closes its interval.  On a jittered one it costs latency: the first
    ``LIVE_LOCK`` samples (up to ``LIVE_LOCK_MAX`` while a heavily jittered lock is unclear)
    are held to lock the grid, then samples come out
    ``LIVE_DELAY`` to ``LIVE_DELAY + LIVE_BLOCK`` grid points late
    (:mod:`~suds_ros.core.resample`); :meth:`drain` releases what is held when the stream
    stops.

    Every sample enters the grid, before the first model too (so the grid is the estimator's,
    which also reads from the first sample); the newest released sample primes a new model's
    predictor (:func:`carry_over`).  Samples are taken with all the joints of their message, in
    its order (a robot's ``/joint_states``); a change of joint names drains the stage and
    starts it afresh.  The model's joints are picked by name as each sample is predicted.

    Attributes
    ----------
    predictor : StreamingPredictor or None
        The predictor of the newest model (None before the first).
    last : the newest sample released by the grid stage (stamp, names, position), or None.
    last_stamp : float
        Newest stamp taken (s, as given), −inf before the first.
    errors : list of SudsError
        Released samples the predictor refused (e.g. the model's joints missing from the
        message), in order; the caller reports and clears them.
    """

    def __init__(self, regrid: bool = True) -> None:
        self.regrid = bool(regrid)
        self.grid: LiveGrid | None = LiveGrid() if self.regrid else None
        self.names: tuple[str, ...] | None = None
        self.predictor: StreamingPredictor | None = None
        self.last: _Sample | None = None
        self.last_stamp = -np.inf
        self.errors: list[SudsError] = []
        self._pick: tuple[tuple[str, ...], tuple[str, ...], np.ndarray | None] | None = None

    @property
    def held(self) -> int:
        """Samples held by the grid stage (not yet released)."""
        return 0 if self.grid is None else self.grid.held

    @property
    def mode(self) -> str:
        """The grid stage's mode: ``off``, ``lock``, ``raw``, ``grid`` or ``snap`` (see :class:`LiveGrid`)."""
        return "off" if self.grid is None else self.grid.mode

    def set_model(self, model: SudsModel) -> str:
        """Predict with ``model`` from the next released sample on; returns how (:func:`carry_over`)."""
        last = self.last
        if last is not None:
            try:
                last = _Sample(last.stamp, model.joint_names, self._select(last, model.joint_names))
            except SudsDataError:
                last = None
        self.predictor, how = carry_over(self.predictor, model, last)
        return how

    def add(self, t: float, names: tuple[str, ...], position: FloatArray
            ) -> list[tuple[float, FloatArray, FloatArray]]:
        """Take a shape sample; returns the predictions (stamp s, ξ (3,), ṙ_p) it releases, in order.

        Raises
        ------
        SudsDataError
            The sample itself is bad (NaN or Inf, a position count other than the name count, a
            duplicate or out-of-order stamp); the stage is unchanged.
        """
        t, names = float(t), tuple(names)
        r = check_shape_sample(t, names, position, names)  # its own joints: count and finiteness
        check_stamp("shape", t, self.last_stamp)
        out: list[tuple[float, FloatArray, FloatArray]] = []
        if names != self.names:
            if self.names is not None:
                out = self.drain()
                self.grid = LiveGrid() if self.regrid else None
            self.names = names
        self.last_stamp = t
        ts, rs = self.grid.add(t, r) if self.grid is not None else ([t], [r])
        return out + self._predict(ts, rs)

    def drain(self) -> list[tuple[float, FloatArray, FloatArray]]:
        """Release what the grid stage holds (the stream stopped); returns those predictions."""
        if self.grid is None or self.names is None:
            return []
        return self._predict(*self.grid.drain())

    def _select(self, sample: _Sample, want: tuple[str, ...]) -> FloatArray:
        """The positions of ``want`` in ``sample`` (by name, :func:`joint_order`; cached)."""
        if self._pick is None or self._pick[:2] != (sample.names, want):
            self._pick = (sample.names, want, joint_order(sample.names, want))
        idx = self._pick[2]
        return sample.position if idx is None else sample.position[idx]

    def _predict(self, ts: list[float], rs: list[FloatArray]) -> list[tuple[float, FloatArray, FloatArray]]:
        """The released samples through the current predictor (refusals go to ``errors``)."""
        out: list[tuple[float, FloatArray, FloatArray]] = []
        assert self.names is not None
        for t, r in zip(ts, rs):
            sample = _Sample(t, self.names, r)
            self.last = sample
            if self.predictor is None:
                continue
            want = self.predictor.model.joint_names
            try:
                o = self.predictor.update(t, want, self._select(sample, want))
            except SudsError as exc:
                self.errors.append(exc)
                continue
            if o is not None:
                out.append((t, o[0], o[1]))
        return out


def evaluate_model(model: SudsModel, rec: Recording) -> Prediction:
    """Run :class:`StreamingPredictor` over a recording and compare with its measured velocities.

    Returns a :class:`~suds_ros.core.ident.scoring.Prediction` whose ``template`` column is the model's
    phase-only template at the tracked phases (score it with ``score_prediction``).

    Shape samples bridged across a run of lost messages (``rec.bridged``, from
    :func:`~suds_ros.core.resample.on_shape_grid`) were never measured: the predictor does not
    see them, as a live one would not (it tracks the phase across the gap), and the intervals
    over them, and the pose intervals over those, are left out of the comparison
    (:func:`~suds_ros.core.ident.intervals.measured_intervals`), as the batch identifier leaves
    them out of its scores.  Before 2026-12-06 the bridged straight lines were fed and compared:
    `suds identify --streaming` on a lab purcell3 with 30 % of its shape messages lost in 0.3 s
    bursts read Γ body 0.54 for a model that scores 0.80 on the measured intervals.
    """
    if rec.joint_names != model.joint_names or rec.actuated != model.actuated:
        raise SudsDataError(
            f"recording joints {list(rec.joint_names)} (actuated {list(rec.actuated)}) differ from the "
            f"model's {list(model.joint_names)} (actuated {list(model.actuated)})"
        )
    pred = StreamingPredictor(model)
    seen = np.ones(rec.n_samples, dtype=bool) if rec.bridged is None else ~rec.bridged
    keep = measured_intervals(rec)  # intervals k → k + 1 with both samples seen
    out, phases, done = [], [], []
    for k in np.flatnonzero(seen):
        o = pred.update(float(rec.t[k]), rec.joint_names, rec.r[k])
        if o is not None and k >= 1 and seen[k - 1]:  # the interval k − 1 → k
            out.append(np.concatenate(o))
            phases.append(pred.last_mid_phase)
            done.append(k - 1)
    iv = make_intervals(rec)
    rows = np.flatnonzero(keep) if keep is not None else np.arange(iv.t.size)
    if not np.array_equal(np.asarray(done, dtype=int), rows):
        raise SudsError(f"the predictor gave {len(done)} interval predictions for {rows.size} measured intervals")
    ph = np.asarray(phases)
    truth = np.concatenate([iv.xi, iv.rdot[:, rec.passive_index]], axis=1)[rows]
    pred_rows, template = np.asarray(out), model.template(ph)
    t = iv.t[rows]
    return Prediction(
        t=t, phase=ph, channels=model.channels, truth=truth, model=pred_rows, template=template,
        body=average_over_pose_intervals(rec, pred_rows, template, keep=keep),
    )
