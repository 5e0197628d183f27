"""Score the live predictions recorded in a bag against the velocities measured in it.

The predictor publishes, for every shape sample k, the body velocity
(``/suds/predicted/body_velocity``, TwistStamped, body frame) and passive joint
velocity (``/suds/predicted/passive_velocity``, JointState ``velocity``) over
the interval [t_{k−1}, t_k], stamped t_k.  Each prediction is made with the
model the estimator had published *before* sample k arrived, so every one is
out of sample (prequential): no held-out split of the training data is needed
to score it honestly.

The measured velocities are the forward differences of the recorded shape and
pose over the same intervals (:mod:`suds_ros.core.ident.intervals`).  On a shape
stream with stamp jitter the predictor predicts the intervals of its live grid,
stamped with grid times; such predictions are scored on the recording's fitted
grid (the identifier's), each interval whose two ends were predicted.  The reference
is the phase-only template of the paper's Γ: the phaser is fitted on the first
``train_cycles`` of the recording and the template (a Fourier series in phase)
is fitted to the measured velocities of those cycles; both are evaluated on the
later cycles, where Γ = 1 − Σ|pred − meas| / Σ|template − meas| per channel
group.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from suds_ros.core.errors import MISSING_TOPIC, WRONG_JOINT_NAMES, SudsDataError
from suds_ros.core.ident.intervals import make_intervals, pose_intervals
from suds_ros.core.ident.scoring import gamma
from suds_ros.core.phase.phaser import Phaser
from suds_ros.core.phase.template import FourierTemplate, FourierTemplateConfig
from suds_ros.core.recording import Recording
from suds_ros.io.mcap import decode_message, iter_raw_messages
from suds_ros.io.recording_bag import PREDICTED_BODY_TOPIC, PREDICTED_PASSIVE_TOPIC, namespaced, read_recording
from suds_ros.io.stamps import float_to_ns, join_ns, ns_to_float


@dataclass(frozen=True)
class LiveScore:
    """Accuracy of a bag's recorded live predictions on its cycles after ``train_cycles``.

    Attributes
    ----------
    gamma_body, gamma_passive : Γ of the live predictions against the phase-only template
        (``gamma_passive`` None for a fully actuated chain: no passive joint to score).
    rms_body, rms_passive : RMS prediction error (m/s and rad/s mixed for the body; rad/s; None
        like ``gamma_passive``).
    n_scored : intervals scored (after ``train_cycles`` and with both predictions).
    n_intervals : intervals after ``train_cycles``.
    n_predictions : predicted intervals in the whole bag.
    first_prediction_s : time of the first prediction after the first shape sample, s.
    train_cycles, test_cycles : cycles used for the template / scored.
    """

    gamma_body: float
    gamma_passive: float | None
    rms_body: float
    rms_passive: float | None
    n_scored: int
    n_intervals: int
    n_predictions: int
    first_prediction_s: float
    train_cycles: float
    test_cycles: float

    @property
    def coverage(self) -> float:
        """Fraction of the scored cycles' intervals that have a live prediction."""
        return self.n_scored / self.n_intervals if self.n_intervals else 0.0

    def as_dict(self) -> dict[str, float | None]:
        """JSON-ready dictionary (with ``coverage``; None for a score that does not apply)."""
        out = {k: None if v is None else float(v) for k, v in self.__dict__.items()}
        out["coverage"] = self.coverage
        return out

    def summary(self) -> str:
        """One line for a terminal."""
        passive = ("none (fully actuated: no passive joint)" if self.gamma_passive is None
                   else f"{self.gamma_passive:.3f}")
        return (f"live predictions on cycles {self.train_cycles:g}–"
                f"{self.train_cycles + self.test_cycles:g} (out of sample): Γ body "
                f"{self.gamma_body:.3f}, Γ passive {passive}; "
                f"{self.n_scored} of {self.n_intervals} intervals predicted; first prediction "
                f"{self.first_prediction_s:.1f} s into the run")


def _stamp_ns(msg: object) -> int:
    st = msg.header.stamp  # type: ignore[attr-defined]
    return join_ns(st.sec, st.nanosec)


def read_predictions(bag: str | Path, passive: tuple[str, ...], namespace: str = ""
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Recorded predictions of a bag (of the robot in ``namespace``, '' for the root).

    Returns
    -------
    body_ns : (nb,) int64 stamps, ns; body : (nb, 3) predicted (vx, vy, ωz).
    passive_ns : (npv,) int64 stamps, ns; passive_vel : (npv, len(passive)) predicted ṙ_p.

    Raises
    ------
    SudsDataError
        No predictions, or predicted passive joints other than ``passive``.  With no passive
        joint (a fully actuated chain) the passive topic may be absent or carry empty messages.
    """
    body_topic = namespaced(namespace, PREDICTED_BODY_TOPIC)
    passive_topic = namespaced(namespace, PREDICTED_PASSIVE_TOPIC)
    body_ns, body, pas_ns, pas = [], [], [], []
    for m in iter_raw_messages(bag, topics=[body_topic, passive_topic]):
        msg = decode_message(m.type_name, m.data)
        if m.topic == body_topic:
            body_ns.append(_stamp_ns(msg))
            body.append((msg.twist.linear.x, msg.twist.linear.y, msg.twist.angular.z))
        else:
            if tuple(msg.name) != passive:
                raise SudsDataError(f"{bag}: {passive_topic} names joints "
                                    f"{list(msg.name)}; the recording's passive joints are "
                                    f"{list(passive)}", code=WRONG_JOINT_NAMES)
            pas_ns.append(_stamp_ns(msg))
            pas.append(tuple(msg.velocity))
    if not body_ns or (passive and not pas_ns):
        wanted = ((body_topic, body_ns), (passive_topic, pas_ns)) if passive else ((body_topic, body_ns),)
        missing = [t for t, v in wanted if not v]
        raise SudsDataError(f"{bag}: no live predictions recorded on {missing}", code=MISSING_TOPIC)
    return (np.asarray(body_ns, dtype=np.int64), np.asarray(body, dtype=float).reshape(-1, 3),
            np.asarray(pas_ns, dtype=np.int64), np.asarray(pas, dtype=float).reshape(len(pas_ns), len(passive)))


#: a prediction stamped with its sample's own stamp matches it within this (ns): float-second
#: stamps near 1.7e9 s are only good to ~240 ns
_EXACT = 1_000
#: predictions stamped with grid times match the recording's grid points within this fraction of a step
#: (the predictor's live grid and the batch grid fitted to the whole stream differ by far less)
_GRID_MATCH = 0.25


def _prediction_grid(rec: Recording, body_ns: np.ndarray) -> tuple[Recording, int]:
    """The recording whose shape intervals the predictions are for, and the stamp tolerance (ns).

    The predictor stamps each prediction with the sample that closes its interval: its own
    stamp on a uniform stream (or with ``regrid`` off), a grid time on a stream with stamp
    jitter (its live grid, :class:`~suds_ros.core.ident.predictor.GridPredictor`).  When fewer
    than half of the predictions carry a recorded shape stamp, they are scored on the
    recording's fitted grid (:func:`~suds_ros.core.resample.on_shape_grid`, as the
    identifier fits and scores), each matched to the nearest grid point.
    """
    own = np.isfinite(_lookup(body_ns, float_to_ns(rec.t), np.zeros((rec.t.size, 1)))[:, 0])
    if own.sum() >= 0.5 * body_ns.size:
        return rec, _EXACT
    from suds_ros.core.resample import on_shape_grid

    grid = on_shape_grid(rec)
    if grid is rec:
        return rec, _EXACT
    return grid, int(_GRID_MATCH * grid.dt * 1e9)


def _lookup(stamps_ns: np.ndarray, keys_ns: np.ndarray, values: np.ndarray, tol: int = _EXACT) -> np.ndarray:
    """The values at each stamp (NaN rows where no key is within ``tol`` ns); the last duplicate wins."""
    order = np.argsort(keys_ns, kind="stable")
    keys, vals = keys_ns[order], values[order]
    idx = np.clip(np.searchsorted(keys, stamps_ns + tol, side="right") - 1, 0, keys.size - 1)
    hit = np.abs(keys[idx] - stamps_ns) <= tol
    out = np.full((stamps_ns.size, values.shape[1]), np.nan)
    out[hit] = vals[idx[hit]]
    return out


def _body_over_pose_intervals(rec: Recording, mid: np.ndarray, pred: np.ndarray, template_order: int,
                              cut: float) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """With a pose stream of its own stamps: live body predictions, measured body velocity, template.

    The live body predictions (one per shape interval, midpoint phases ``mid``) averaged over each
    pose interval after ``cut``, the measured body velocity there, and the phase-only template
    fitted before ``cut`` and averaged the same way; (None, None, None) when the streams share
    their stamps.
    """
    pv = pose_intervals(rec, rec.t[:-1], rec.t[1:])
    if pv.is_identity(0.5 * (rec.t[:-1] + rec.t[1:])):
        return None, None, None
    W = pv.over_shape(mid.size)
    train, test = pv.t1 <= cut, pv.t0 >= cut
    tmpl = FourierTemplate(FourierTemplateConfig(order=template_order)).fit(mid, pv.xi[train], mix=W[train])
    P = np.asarray(W @ pred[:, :3])  # a missing prediction leaves its pose intervals NaN
    T = np.asarray(W @ tmpl.predict(mid))
    ok = test & np.all(np.isfinite(P), axis=1)
    if not ok.any():
        return None, None, None
    return P[ok], pv.xi[ok], T[ok]


def score_live_predictions(bag: str | Path, train_cycles: float | None = None,
                           template_order: int = 8, *, recording: Recording | None = None,
                           namespace: str = "") -> LiveScore:
    """Γ of the live predictions recorded in ``bag`` on the cycles after ``train_cycles``.

    ``train_cycles`` defaults to half of the recorded cycles (cycle length from the bag's
    ``gait_hz`` metadata, else 1 Hz).  ``recording`` is the bag's recording when the caller
    has already read it (e.g. with metadata overrides); by default it is read from ``bag``.
    ``namespace``: the robot's ROS namespace in a bag of several robots (``/robot1``: its
    topics ``/robot1/suds/...``; see :func:`~suds_ros.io.recording_bag.read_recording`).

    Raises
    ------
    SudsDataError
        No predictions, too few cycles on either side, or no prediction after ``train_cycles``.
    SudsBagError
        The bag cannot be read (see :func:`~suds_ros.io.recording_bag.read_recording`).
    """
    rec = read_recording(bag, namespace=namespace) if recording is None else recording
    hz = rec.gait_hz or 1.0
    cycles = (rec.t[-1] - rec.t[0] + float(np.median(np.diff(rec.t)))) * hz  # n samples span n periods
    if train_cycles is None:
        train_cycles = float(np.floor(cycles / 2))
    if not 2 <= train_cycles <= cycles - 1:
        raise SudsDataError(f"{bag}: {cycles:.1f} cycles recorded; cannot keep {train_cycles:g} for "
                            "the template and at least 1 to score (need ≥ 2 for the template)")
    body_ns, body, pas_ns, pas = read_predictions(bag, rec.passive, namespace)
    rec, tol = _prediction_grid(rec, body_ns)

    iv = make_intervals(rec)
    k = iv.k.astype(np.int64)
    end_ns = float_to_ns(rec.t[k + 1])  # a prediction is stamped t_{k+1}
    meas = np.concatenate([iv.xi, iv.rdot[:, rec.passive_index]], axis=1)
    pred_p = _lookup(end_ns, pas_ns, pas, tol) if rec.passive else np.empty((end_ns.size, 0))
    pred = np.concatenate([_lookup(end_ns, body_ns, body, tol), pred_p], axis=1)
    if tol > _EXACT:
        # on the grid a lost sample is not released, so the prediction after it spans two grid
        # steps, while the grid's measured intervals are one step each: only intervals whose
        # both ends were predicted are the predictor's own
        start = np.all(np.isfinite(_lookup(float_to_ns(rec.t[k]), body_ns, body, tol)), axis=1)
        pred[~start] = np.nan

    cut = rec.t[0] + train_cycles / hz
    train_s = rec.t < cut
    phaser = Phaser()
    phase = phaser.fit(rec.r[train_s]).transform(rec.r)
    mid = 0.5 * (phase[k] + phase[k + 1])
    # intervals with no measured body velocity (no pose around them: motion capture started late
    # or paused) are neither template rows nor scored
    measured = np.all(np.isfinite(meas), axis=1)
    train = (iv.t < cut) & measured
    template = FourierTemplate(FourierTemplateConfig(order=template_order)).fit(mid[train], meas[train])
    tmpl = template.predict(mid)

    test = (iv.t >= cut) & measured
    scored = test & np.all(np.isfinite(pred), axis=1)
    if not scored.any():
        raise SudsDataError(f"{bag}: no live prediction after cycle {train_cycles:g}")
    b, p = slice(0, 3), slice(3, None)
    P, M, T = pred[scored], meas[scored], tmpl[scored]
    Pb, Mb, Tb = _body_over_pose_intervals(rec, mid, pred, template_order, cut)
    if Pb is None:
        Pb, Mb, Tb = P[:, b], M[:, b], T[:, b]
    has_p = bool(rec.passive)  # a fully actuated chain has no passive group to score
    streams = (body_ns, pas_ns) if has_p else (body_ns,)
    first = ns_to_float(min(int(s.min()) for s in streams)) - rec.t[0]
    return LiveScore(
        gamma_body=gamma(Pb, Tb, Mb),
        gamma_passive=gamma(P[:, p], T[:, p], M[:, p]) if has_p else None,
        rms_body=float(np.sqrt(np.mean((Pb - Mb) ** 2))),
        rms_passive=float(np.sqrt(np.mean((P[:, p] - M[:, p]) ** 2))) if has_p else None,
        n_scored=int(scored.sum()),
        n_intervals=int(test.sum()),
        n_predictions=int(min(s.size for s in streams)),
        first_prediction_s=float(first),
        train_cycles=float(train_cycles),
        test_cycles=float(cycles - train_cycles),
    )
