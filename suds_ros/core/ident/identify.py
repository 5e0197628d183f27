"""The identification pipeline on recordings: phase → template → δ, δ̇ → SUDS regression → Γ.

:class:`SudsIdentifier` fits on one recording (the training cycles) and
predicts / scores another (held-out cycles).  Outputs are the body velocity
(ξx, ξy, ξθ) followed by the passive joint velocities; with ``effort`` recorded
the actuator torques are identified the same way (``torque=True``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import TOO_LITTLE_DATA, SudsConfigError, SudsDataError
from suds_ros.core.estimator import BaseEstimator, check_is_fitted
from suds_ros.core.fourier import fourier_basis
from suds_ros.core.ident.intervals import (
    Intervals,
    PoseIntervals,
    interval_features,
    make_intervals,
    measured_intervals,
    pose_intervals,
    segment_states,
)
from suds_ros.core.recording import Recording
from suds_ros.core.ident.scoring import (
    BODY_CHANNELS,
    PoseIntervalPrediction,
    Prediction,
    Scores,
    score_prediction,
)
from suds_ros.core.ident.shape_kernel import gait_kernel_scale
from suds_ros.core.ident.sysid import (
    AveragedTargets,
    SudsConfig,
    SudsRegressor,
    averaged_design_rows,
    feature_layout,
    interval_state,
    regressor_design,
    segment_state,
)

_BODY = list(range(len(BODY_CHANNELS)))  # the body channels lead every output vector


@dataclass(frozen=True)
class _Samples:
    """Regression data of one recording.

    ``Y`` (m, c) holds every channel on the shape intervals (the body channels from the pose
    interpolated at the shape stamps); ``pose`` the body velocity as measured over the pose
    intervals, or None when the streams share their stamps (then the two are the same);
    ``seg_ph``, ``seg_r``, ``seg_rdot`` the state at the pose intervals' segments' midpoints,
    ``row_ph``, ``row_r`` the phase and state their regression rows use
    (:func:`~suds_ros.core.ident.sysid.segment_state`).
    """

    iv: Intervals
    ph: FloatArray
    Y: FloatArray
    pose: PoseIntervals | None
    seg_ph: FloatArray | None = None
    seg_r: FloatArray | None = None
    seg_rdot: FloatArray | None = None
    row_ph: FloatArray | None = None
    row_r: FloatArray | None = None

    @property
    def direct(self) -> FloatArray:
        """The outputs fitted on the shape intervals themselves."""
        return self.Y if self.pose is None else self.Y[:, len(_BODY):]


@dataclass(frozen=True)
class IdentifyConfig:
    """Settings of the identification pipeline.

    Parameters
    ----------
    suds : SudsConfig
        Regression hyperparameters (regressor set, Fourier orders, ridge, forgetting).
    template_order : int
        Fourier order of the nominal shape θ(φ) and of the phase-only output template.
    window : int
        Differencing window, samples (1 = consecutive samples).
    phase : str
        ``"phaser"`` (estimate from the shape data alone) or ``"truth"`` (a simulator's
        reference phase in ``Recording.truth["phase"]``; for validation only).
    phaser_order : int
        Fourier order of the phaser's protophase correction.
    order_grid : tuple of (linear_order, bilinear_order)
        Candidate Fourier orders of the gains.  With ``regressor_grid`` and ``ridge_grid`` they
        span the candidates chosen from by cross-validation over contiguous blocks of training
        cycles (``cv_folds``; :mod:`~suds_ros.core.ident.model_selection`), so the model's size
        and regularisation follow the amount of data.  Empty keeps ``suds`` as given (no
        selection at all).
    regressor_grid : tuple of int
        Candidate regressor sets (empty: ``suds.regressors``).
    ridge_grid : tuple of float
        Candidate relative ridges (empty: ``suds.ridge``).
    kernel_grid : tuple of int
        Candidate numbers of random shape features (0: none; the others go with regressor set 1
        only, see :mod:`~suds_ros.core.ident.shape_kernel`; empty: ``suds.kernel_features``).
    kernel_max_rows : int
        Random-feature candidates are tried only on training sets of at most this many interval
        rows.  They win with little data (5–10 swimmer9 cycles in ``docs/results/peers.md``);
        beyond about 20 cycles the Fourier model has won on every benchmark system, and their
        cross-validation there would cost more than the rest of the fit.
    max_parameters : int
        Candidates with more regression parameters per output are left out (the cost of a fit
        grows with their cube; long chains reach it with set 3 and high orders); the smallest
        candidate is always kept.
    cv_folds : int
        Number of contiguous folds for the selection.
    block_samples : int
        Recordings with more shape samples, whose pose stamps are shape stamps (one pose per
        shape sample, possibly missing at the ends), are processed a block of this many
        intervals at a time: the interval data, regressor rows and held-out scores are made
        per block and the per-sample intermediates of the whole recording are never held
        (the same sums, added in another order; see ``docs/results/long_identify.md``).
    phaser_fit_samples : int
        The phaser is fitted on at most this many leading samples of the training recording;
        the rest is phased with the learned corrections (``phase_block_samples`` at a time).
    select_max_rows : int
        The model selection of a recording processed block by block runs on every k-th training
        interval, k the smallest stride that leaves at most this many rows (the regression is then
        fitted on all of them).  Neighbouring rows of a 1 kHz stream say almost the same thing;
        the selection's cost grows with its rows.
    phase_block_samples, phase_margin_samples : int
        Longer series are phased in blocks of this many samples, each transformed with this
        many samples of context on both sides (the Hilbert transform's edges), and joined
        into one unwrapped phase.
    regrid : bool
        Bring an asynchronous shape stream (jittered stamps, drops, a pose stream of its own)
        onto its fitted uniform sampling grid first (:func:`~suds_ros.core.resample.on_shape_grid`:
        the drive's set-point kinks then fall on interval ends).  Aligned recordings are unchanged.
    """

    suds: SudsConfig = field(default_factory=SudsConfig)
    template_order: int = 8
    window: int = 1
    phase: str = "phaser"
    phaser_order: int = 10
    order_grid: tuple[tuple[int, int], ...] = ((1, 0), (2, 1), (4, 2), (6, 3))
    regressor_grid: tuple[int, ...] = (1, 2, 3)
    ridge_grid: tuple[float, ...] = (1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2)
    kernel_grid: tuple[int, ...] = (0, 300)
    kernel_max_rows: int = 1500
    max_parameters: int = 1600
    cv_folds: int = 3
    regrid: bool = True
    block_samples: int = 100_000
    select_max_rows: int = 200_000
    phaser_fit_samples: int = 300_000
    phase_block_samples: int = 200_000
    phase_margin_samples: int = 30_000

    @property
    def regrids(self) -> bool:
        """Whether fit and predict bring the shape stream onto its grid: ``regrid``, unless the phase is the truth."""
        return self.regrid and self.phase != "truth"

    def __post_init__(self) -> None:
        for name in ("block_samples", "select_max_rows", "phaser_fit_samples", "phase_block_samples"):
            if getattr(self, name) < 1:
                raise SudsConfigError(f"`{name}`: expected ≥ 1, got {getattr(self, name)!r}")
        if self.phase_margin_samples < 0:
            raise SudsConfigError(f"`phase_margin_samples`: expected ≥ 0, got {self.phase_margin_samples!r}")
        if self.phase not in ("phaser", "truth"):
            raise SudsConfigError(f"`phase`: expected 'phaser' or 'truth', got {self.phase!r}")
        if self.window < 1:
            raise SudsConfigError(f"`window`: expected ≥ 1, got {self.window!r}")
        if self.template_order < 1:
            raise SudsConfigError(f"`template_order`: expected ≥ 1, got {self.template_order!r}")


class SudsIdentifier(BaseEstimator):
    """Phase estimation, gait template and SUDS regression on recordings.

    Parameters
    ----------
    config : IdentifyConfig
    torque : bool
        Also identify actuator effort (requires ``Recording.effort``).

    Attributes
    ----------
    phaser_ : Phaser (``config.phase == "phaser"``)
    omega_ : float, mean phase rate ω̄ of the training recording, rad/s.
    template_ : FourierTemplate, the gait θ(φ).
    kernel_scale_ : KernelScale, the gait's scales for random shape features.
    output_template_coef_ : (2·To + 1, c) phase-only template of the outputs.
    cv_scores_ : dict, the model selection's score of every candidate.
    regressor_ : SudsRegressor, the selected regression fitted on all training rows.
    joint_names_, actuated_, passive_, channels_ : the training recording's joints and outputs.
    """

    def __init__(self, config: IdentifyConfig = IdentifyConfig(), torque: bool = False) -> None:
        self.config = config
        self.torque = torque

    def __sklearn_is_fitted__(self) -> bool:
        """Fitted once :meth:`fit` has finished (``channels_`` is its last result)."""
        return "channels_" in vars(self)

    # ------------------------------------------------------------ phase
    def _phase(self, rec: Recording, fit: bool) -> FloatArray:
        if self.config.phase == "truth":
            if "phase" not in rec.truth:
                raise SudsDataError("phase='truth' needs a simulated recording with truth['phase']")
            return np.asarray(rec.truth["phase"], dtype=float)
        cfg = self.config
        n = rec.n_samples
        if fit:
            head = self._fit_phaser(rec.r)
            return head if head.size == n else self._phase_blocks(rec.r, head)
        if n <= cfg.phase_block_samples:
            return self.phaser_.transform(rec.r)
        return self._phase_blocks(rec.r, np.empty(0))

    def _fit_phaser(self, r: FloatArray) -> FloatArray:
        """Fit ``phaser_`` on the first ``config.phaser_fit_samples`` samples of ``r``; their phase."""
        from suds_ros.core.phase.phaser import Phaser, PhaserConfig

        self.phaser_ = Phaser(PhaserConfig(order=self.config.phaser_order))
        return self.phaser_.fit_transform(r[:self.config.phaser_fit_samples])

    def _phase_blocks(self, r: FloatArray, head: FloatArray) -> FloatArray:
        """Phase (n,) of ``r`` after the known ``head``, transformed a block at a time.

        Each block is transformed with ``phase_margin_samples`` of context on either side and
        joined to the phase before it by the whole turns that best match the overlap.
        """
        cfg = self.config
        n, B, M = r.shape[0], cfg.phase_block_samples, cfg.phase_margin_samples
        out = np.empty(n)
        out[:head.size] = head
        for a in range(head.size, n, B):
            b = min(a + B, n)
            lo, hi = max(0, a - M), min(n, b + M)
            if hi - lo < 2 * (cfg.phaser_order + 2):  # a short tail: take more context before it
                lo = max(0, hi - 2 * (cfg.phaser_order + 2) - M)
            ph = self.phaser_.transform(r[lo:hi])
            turns = 0.0
            if a > lo:
                turns = np.round(np.mean(out[lo:a] - ph[:a - lo]) / (2.0 * np.pi))
            out[a:b] = ph[a - lo:b - lo] + 2.0 * np.pi * turns
        return out

    # --------------------------------------------------------- features
    def channels(self, rec: Recording) -> tuple[str, ...]:
        """Output channel names for a recording."""
        names = list(BODY_CHANNELS) + [f"rdot_{j}" for j in rec.passive]
        if self.torque:
            names += [f"tau_{j}" for j in rec.actuated]
        return tuple(names)

    def _samples(self, rec: Recording, phase: FloatArray, pose_rows: bool = False) -> _Samples:
        """The regression data of one recording.

        ``pose_rows``: with the pose-interval rows even when they are the shape intervals
        themselves (a bout fitted beside bouts with a pose stream of their own needs them).
        """
        w = self.config.window
        iv = make_intervals(rec, w)
        ph = 0.5 * (phase[:-w] + phase[w:])
        Y = np.concatenate([iv.xi, iv.rdot[:, rec.passive_index]], axis=1)
        if self.torque:
            if iv.effort is None:
                raise SudsDataError("torque identification needs recorded `effort` on /suds/shape")
            Y = np.concatenate([Y, iv.effort], axis=1)
        t0, t1 = rec.t[:-w], rec.t[w:]
        keep = measured_intervals(rec, w)
        if keep is not None:  # no interval over shapes bridged across lost samples; no pose interval over those
            iv = Intervals(t=iv.t[keep], k=iv.k[keep], r=iv.r[keep], rdot=iv.rdot[keep], xi=iv.xi[keep],
                           effort=None if iv.effort is None else iv.effort[keep], dt=iv.dt[keep])
            ph, Y, t0, t1 = ph[keep], Y[keep], t0[keep], t1[keep]
        pv = pose_intervals(rec, t0, t1, w)
        if pv.is_identity(iv.t) and not pose_rows:
            return _Samples(iv, ph, Y, None)
        k = np.asarray(iv.k, dtype=np.int64)[pv.seg_k]  # seg_k: rows of iv; k: their first shape samples
        frac = (pv.seg_t - rec.t[k]) / (rec.t[k + w] - rec.t[k])
        row = segment_state(self.config.suds, phase[k], phase[k + w], rec.r[k], rec.r[k + w], frac)
        return _Samples(iv, ph, Y, pv, *segment_states(rec, replace(pv, seg_k=k), phase, w), *row)

    def _targets(self, rec: Recording, X: FloatArray, s: _Samples) -> tuple[FloatArray, AveragedTargets | None]:
        """Row targets and averaged (pose-interval) targets of the regression."""
        if s.pose is None:
            return s.Y, None
        return s.direct, AveragedTargets(X=self._segment_features(rec, s), weights=s.pose.weights,
                                         y=s.pose.xi, columns=tuple(_BODY))

    def _segment_features(self, rec: Recording, s: _Samples) -> FloatArray:
        """Regressor rows of the pose intervals' segments (:func:`~suds_ros.core.ident.sysid.segment_state`)."""
        return self._features(rec, s.row_r, s.seg_rdot, s.row_ph)  # type: ignore[arg-type]

    def _fit_output_template(self, s: _Samples) -> FloatArray:
        """Coefficients (2·To + 1, c) of the phase-only template of every output channel."""
        from suds_ros.core.phase.template import FourierTemplate, FourierTemplateConfig

        tcfg = FourierTemplateConfig(order=self.config.template_order)
        if s.pose is None:
            return FourierTemplate(tcfg).fit(s.ph, s.Y).coef_
        body = FourierTemplate(tcfg).fit(s.seg_ph, s.pose.xi, mix=s.pose.weights).coef_
        rest = FourierTemplate(tcfg).fit(s.ph, s.direct).coef_
        return np.concatenate([body, rest], axis=1)

    def output_template(self, phase: FloatArray) -> FloatArray:
        """Phase-only template predictions (n, c) of every output channel."""
        return fourier_basis(phase, self.config.template_order) @ self.output_template_coef_

    def features(self, rec: Recording, iv: Intervals, phase_mid: FloatArray) -> FloatArray:
        """Regressor input X = [φ, δ, δ̇_a, r, ṙ_a] (m, 1 + 2·(nj + na)) from interval data.

        δ is taken at the state :func:`~suds_ros.core.ident.sysid.interval_state` names
        (the interval's first sample by default), φ at the interval's midpoint.
        """
        k = iv.k.astype(int)
        r = interval_state(self.config.suds, rec.r[k], rec.r[k + self.config.window])
        return self._features(rec, r, iv.rdot, phase_mid)

    def _features(self, rec: Recording, r: FloatArray, rdot: FloatArray, phase_mid: FloatArray) -> FloatArray:
        return interval_features(self.template_, self.omega_, rec.actuated_index, phase_mid, r, rdot)

    # -------------------------------------------------------------- API
    def fit(self, rec: Recording | Sequence[Recording]) -> "SudsIdentifier":
        """Estimate phase, template and the SUDS regression from a training recording.

        ``rec`` may also be a sequence of recordings of the same joints: the bouts of an
        intermittent run (:func:`split_bouts`).  The phaser is fitted on their samples together,
        each bout's phase is then taken on its own, and intervals never span two bouts.
        """
        from suds_ros.core.phase.template import FourierTemplate, FourierTemplateConfig

        self._reset_learned()
        if not isinstance(self.config, IdentifyConfig):
            raise SudsConfigError(f"`config`: expected an IdentifyConfig, got {self.config!r}")
        recs = [self._prepared(r) for r in _recordings(rec)]
        rec = recs[0]
        if len(recs) == 1 or self.config.phase == "truth":
            phases = [self._phase(r, fit=True) for r in recs]
        else:
            self._fit_phaser(_joined(recs).r)  # fitted on the bouts together, each bout phased alone
            phases = [self._phase(r, fit=False) for r in recs]
        span = sum(r.t[-1] - r.t[0] for r in recs)
        self.omega_ = float(sum(p[-1] - p[0] for p in phases) / span)
        if not self.omega_ > 0:
            raise SudsDataError(f"estimated phase does not advance (rate {self.omega_:.3g} rad/s)")
        tcfg = FourierTemplateConfig(order=self.config.template_order)
        blockwise = len(recs) == 1 and self._blockwise(rec, training=True)
        if blockwise:  # the same normal equations, a block of samples at a time
            phase = phases[0]
            self.template_ = FourierTemplate(tcfg)
            for a, b in _ranges(rec.n_samples, self.config.block_samples):
                self.template_.partial_fit(phase[a:b], rec.r[a:b])
            self.template_.fit_check()
        else:
            self.template_ = FourierTemplate(tcfg).fit(np.concatenate(phases), np.concatenate([r.r for r in recs]))
        self.kernel_scale_ = gait_kernel_scale(self.template_, self.omega_, rec.actuated_index)
        if blockwise:  # rows made a block at a time, twice: for the selection's share, then for the fit
            picked, Xs = self._block_data(rec, phase, FourierTemplate(tcfg))
            suds = self._select_model(rec, Xs, picked, self.output_template(picked.ph))
            del Xs, picked
            self.regressor_ = SudsRegressor(suds, n_actuated=len(rec.actuated), kernel_scale=self.kernel_scale_)
            fitted = False
            for _, Xb, Yb, _ in self._blocks(rec, phase):
                if Yb.shape[0]:
                    (self.regressor_.partial_fit if fitted else self.regressor_.fit)(Xb, Yb)
                    fitted = True
        else:
            parts = [self._samples(r, p) for r, p in zip(recs, phases)]
            if len(parts) > 1 and any(p.pose is not None for p in parts):  # every bout on its pose intervals
                parts = [p if p.pose is not None else self._samples(r, ph, pose_rows=True)
                         for r, ph, p in zip(recs, phases, parts)]
            X = np.concatenate([self.features(r, p.iv, p.ph) for r, p in zip(recs, parts)])
            s = parts[0] if len(parts) == 1 else _merged(parts)
            self.output_template_coef_ = self._fit_output_template(s)
            suds = self._select_model(rec, X, s, self.output_template(s.ph))
            self.regressor_ = SudsRegressor(suds, n_actuated=len(rec.actuated), kernel_scale=self.kernel_scale_)
            self.regressor_.fit(X, *self._targets(rec, X, s))
        self.joint_names_ = rec.joint_names
        self.actuated_ = rec.actuated
        self.passive_ = rec.passive
        self.channels_ = self.channels(rec)
        return self

    # ------------------------------------------------------- long recordings
    def _blockwise(self, rec: Recording, training: bool) -> bool:
        """Process ``rec`` a block at a time: long, and every pose stamp a shape stamp.

        Training needs a pose at every shape stamp; held-out data may lack poses at the ends
        (their intervals then score the joints only, as the pose intervals would).  Bridged
        shape samples are left out block by block (:meth:`_blocks`), as the whole path leaves them out.
        """
        t, pt = rec.t, rec.pose_t
        if rec.n_samples <= self.config.block_samples or pt.size < 2:
            return False
        if training:
            return pt.size == t.size and bool(np.array_equal(pt, t))
        i0 = int(np.searchsorted(t, pt[0]))
        return i0 + pt.size <= t.size and bool(np.array_equal(t[i0:i0 + pt.size], pt))

    def _blocks(self, rec: Recording, phase: FloatArray):  # type: ignore[no-untyped-def]
        """(k, X, Y, phase) of consecutive blocks of intervals (see :meth:`_samples`); k: each row's interval.

        Intervals over a bridged shape sample are left out
        (:func:`~suds_ros.core.ident.intervals.measured_intervals`), so a block's rows need not be
        consecutive.  Y's body channels are NaN on intervals without a pose at both ends.
        """
        w = self.config.window
        for a, b in _ranges(rec.n_samples - w, self.config.block_samples):
            sub = rec.slice(a, b + w)
            iv = make_intervals(sub, w)
            ph = 0.5 * (phase[a:b] + phase[a + w:b + w])
            Y = np.concatenate([iv.xi, iv.rdot[:, sub.passive_index]], axis=1)
            if self.torque:
                if iv.effort is None:
                    raise SudsDataError("torque identification needs recorded `effort` on /suds/shape")
                Y = np.concatenate([Y, iv.effort], axis=1)
            X, k = self.features(sub, iv, ph), np.arange(a, b)
            keep = measured_intervals(sub, w)
            if keep is not None:
                X, Y, ph, k = X[keep], Y[keep], ph[keep], k[keep]
            yield k, X, Y, ph

    def _block_data(self, rec: Recording, phase: FloatArray, out: object) -> tuple[_Samples, FloatArray]:
        """The output template and the model selection's data of an aligned recording, made block by block.

        ``out`` (an unfitted FourierTemplate) is fitted to every interval's outputs and becomes
        ``output_template_coef_``.  Returns the outputs, phases and regressor rows of the measured
        intervals (none over a bridged sample) whose index is a multiple of ``step``: every one up
        to ``config.select_max_rows`` intervals, else the smallest stride that leaves at most that
        many.  Nothing is held for every interval.
        """
        m = rec.n_samples - self.config.window
        step = max(1, -(-m // self.config.select_max_rows))
        n = len(range(0, m, step))  # at most this many rows (fewer when some are bridged)
        Xs = Ys = None
        ph = np.empty(n)
        got = 0
        for k, Xb, Yb, pb in self._blocks(rec, phase):
            out.partial_fit(pb, Yb)  # type: ignore[attr-defined]
            if Xs is None:
                Xs, Ys = np.empty((n, Xb.shape[1])), np.empty((n, Yb.shape[1]))
            on = k % step == 0
            rows = slice(got, got + int(on.sum()))
            Xs[rows], Ys[rows], ph[rows] = Xb[on], Yb[on], pb[on]  # type: ignore[index]
            got = rows.stop
        self.output_template_coef_ = out.fit_check().coef_  # type: ignore[attr-defined]
        return _Samples(None, ph[:got], Ys[:got], None), Xs[:got]  # type: ignore[arg-type, index]

    def _block_scores(self, rec: Recording) -> Scores:
        """:meth:`scores` of a long recording, a block of intervals at a time (nothing held whole)."""
        from suds_ros.core.ident.scoring import ScoreSums

        phase = self._phase(rec, fit=False)
        sums = ScoreSums(self.channels_)
        nb = len(_BODY)
        for _, X, Y, ph in self._blocks(rec, phase):
            if not Y.shape[0]:
                continue
            sums.add(Y, self.regressor_.predict(X), self.output_template(ph), np.isfinite(Y[:, :nb]).all(axis=1))
        return sums.scores()

    def _select_model(self, rec: Recording, X: FloatArray, s: _Samples, Yt: FloatArray) -> SudsConfig:
        """Pick regressor set, gain orders and ridge by blocked cross-validation on the training data.

        See :mod:`~suds_ros.core.ident.model_selection`; the table of scores is kept in
        ``cv_scores_`` (keyed by regressors, linear order, bilinear order, ridge, kernel features).
        """
        from suds_ros.core.ident import model_selection as ms

        cfg = self.config
        self.cv_scores_: dict[tuple[int, int, int, float, int], float] = {}
        k = cfg.cv_folds
        if not cfg.order_grid or k < 2 or X.shape[0] < 10 * k:
            return cfg.suds
        nj, na = len(rec.joint_names), len(rec.actuated)
        kernels = tuple(m for m in cfg.kernel_grid if not m or X.shape[0] <= cfg.kernel_max_rows) or (0,)
        cands = ms.candidates(cfg.suds, cfg.regressor_grid, cfg.order_grid, cfg.ridge_grid, kernels)
        size = {c: feature_layout(c, nj, na).n_columns for c in cands}
        cands = [c for c in cands if size[c] <= cfg.max_parameters] or [min(cands, key=size.__getitem__)]
        names = self.channels(rec)
        groups = tuple(tuple(i for i, c in enumerate(names) if c.startswith(p)) for p in ("xi_", "rdot_", "tau_"))
        edges = np.linspace(0, X.shape[0], k + 1).astype(int)
        columns = tuple(range(0 if s.pose is None else len(_BODY), len(names)))
        if s.pose is not None:
            block = np.searchsorted(edges, np.arange(X.shape[0]), side="right") - 1
            onehot = (block[s.pose.seg_k][:, None] == np.arange(k)[None, :]).astype(float)
            Xs = self._segment_features(rec, s)
        best, best_score = cfg.suds, np.inf
        for family in ms.families(cands):  # designs nest within a family (same random features)
            big = ms.largest(family)
            P = feature_layout(big, nj, na).n_columns
            averaged = None
            if s.pose is not None:
                W = s.pose.weights
                averaged = ms.AveragedRows(
                    A=ms.LazyDesign(W.shape[0], P, _averaged_rows(big, Xs, W, na, self.kernel_scale_, P)),
                    y=s.pose.xi, template=np.asarray(W @ self.output_template(s.seg_ph)[:, _BODY]),
                    columns=tuple(_BODY), fold_frac=np.asarray(W @ onehot))
            problem = ms.CVProblem(A=ms.LazyDesign(X.shape[0], P, _rows(big, X, na, self.kernel_scale_)),
                                   y=s.Y[:, list(columns)],
                                   template=Yt[:, list(columns)], columns=columns,
                                   groups=tuple(g for g in groups if g), edges=edges, averaged=averaged)
            chosen, scores = ms.select(problem, family, nj, na)
            self.cv_scores_.update(scores)
            if scores[ms.key(chosen)] < best_score:
                best, best_score = chosen, scores[ms.key(chosen)]
        return best

    def _prepared(self, rec: Recording) -> Recording:
        """``rec`` on its shape grid (``config.regrid``), refused when no interval of it was measured."""
        if self.config.regrids:
            from suds_ros.core.resample import on_shape_grid

            rec = on_shape_grid(rec)
        _check_measured(rec, self.config.window)
        return rec

    def _check(self, rec: Recording) -> None:
        check_is_fitted(self)
        if rec.joint_names != self.joint_names_ or rec.actuated != self.actuated_:
            raise SudsDataError(
                f"recording joints {list(rec.joint_names)} (actuated {list(rec.actuated)}) differ "
                f"from the training joints {list(self.joint_names_)} (actuated {list(self.actuated_)})"
            )

    def predict(self, rec: Recording | Sequence[Recording]) -> Prediction:
        """Model and template predictions with the measured outputs of ``rec``.

        A sequence of recordings (held-out bouts) gives their predictions one after the other.
        """
        if not isinstance(rec, Recording):
            preds = [self.predict(r) for r in _recordings(rec)]
            if len(preds) == 1:
                return preds[0]
            if any(p.body is not None for p in preds):
                raise SudsDataError(_POSE_STAMPS_MSG)
            return Prediction(t=np.concatenate([p.t for p in preds]), phase=np.concatenate([p.phase for p in preds]),
                              channels=preds[0].channels, truth=np.concatenate([p.truth for p in preds]),
                              model=np.concatenate([p.model for p in preds]),
                              template=np.concatenate([p.template for p in preds]))
        self._check(rec)
        rec = self._prepared(rec)
        phase = self._phase(rec, fit=False)
        s = self._samples(rec, phase)
        X = self.features(rec, s.iv, s.ph)
        model = self.regressor_.predict(X)
        template = self.output_template(s.ph)
        body = None
        if s.pose is not None:
            W = s.pose.weights
            body = PoseIntervalPrediction(
                t=0.5 * (s.pose.t0 + s.pose.t1), truth=s.pose.xi,
                model=np.asarray(W @ self.regressor_.predict(self._segment_features(rec, s))[:, _BODY]),
                template=np.asarray(W @ self.output_template(s.seg_ph)[:, _BODY]),
            )
        return Prediction(t=s.iv.t, phase=s.ph, channels=self.channels_, truth=s.Y, model=model,
                          template=template, body=body)

    def scores(self, rec: Recording | Sequence[Recording]) -> Scores:
        """Γ per output group and RMS errors of the model and the template on ``rec`` (held-out data).

        A long recording (``config.block_samples``) is scored a block at a time: the same
        scores as ``score_prediction(predict(rec))`` without holding the predictions.
        """
        if isinstance(rec, Recording) and rec.n_samples > self.config.block_samples:  # else as predict does
            self._check(rec)
            prepared = self._prepared(rec)
            if self._blockwise(prepared, training=False):
                return self._block_scores(prepared)
        return score_prediction(self.predict(rec))

    def score(self, rec: Recording | Sequence[Recording]) -> float:
        """One number for ``rec`` (held-out data): the mean Γ over the output groups it has.

        The groups are the body velocity, the passive rates and (``torque``) the actuator
        efforts; a group whose Γ is undefined (no such channels) is left out.  :meth:`scores`
        gives each group's Γ and the per-channel errors.
        """
        sc = self.scores(rec)
        groups = [g for g in (sc.gamma_body, sc.gamma_passive, sc.gamma_torque) if g is not None and np.isfinite(g)]
        return float(np.mean(groups)) if groups else float("nan")

    @property
    def n_parameters(self) -> int:
        """Regression parameters per output channel."""
        check_is_fitted(self)
        return self.regressor_.n_parameters


_POSE_STAMPS_MSG = ("bouts: predictions over several bouts need the pose sampled at the shape stamps "
                    "(as `suds import` writes it); this recording's pose stream has stamps of its own")


def _recordings(rec: Recording | Sequence[Recording]) -> list[Recording]:
    """``rec`` as a non-empty list of recordings of the same joints and roles."""
    recs = [rec] if isinstance(rec, Recording) else list(rec)
    if not recs or not all(isinstance(r, Recording) for r in recs):
        raise SudsConfigError(f"`rec`: expected a Recording or a non-empty sequence of them, got {rec!r}")
    first = recs[0]
    for k, r in enumerate(recs[1:], 1):
        if r.joint_names != first.joint_names or r.actuated != first.actuated:
            raise SudsDataError(f"`rec`: recording {k} has joints {list(r.joint_names)} (actuated "
                                f"{list(r.actuated)}), recording 0 {list(first.joint_names)} (actuated "
                                f"{list(first.actuated)}): expected the same")
    return recs


def _joined(recs: list[Recording]) -> Recording:
    """The bouts' shape samples end to end on one uniform clock (for the phaser only)."""
    r = np.concatenate([x.r for x in recs])
    dt = float(np.median([x.dt for x in recs]))
    t = recs[0].t[0] + dt * np.arange(r.shape[0])
    return replace(recs[0], t=t, r=r, pose_t=t[[0, -1]], pose=np.zeros((2, 3)), effort=None, truth={}, bridged=None)


def _check_measured(rec: Recording, window: int) -> None:
    """Refuse a recording in which every interval spans a bridged shape sample (nothing measured to use).

    Raises
    ------
    SudsDataError
        (code ``too_little_data``) naming how many shape samples were bridged and over what span.
    """
    keep = measured_intervals(rec, window)
    if keep is None or keep.any():
        return
    lost = np.flatnonzero(rec.bridged)
    raise SudsDataError(
        f"`rec`: every interval of {window} sample(s) spans a shape sample that was bridged across a run of "
        f"lost messages ({lost.size} of {rec.n_samples} shape samples, between stamps {rec.t[lost[0]]:.3f} and "
        f"{rec.t[lost[-1]]:.3f} s): no measured interval is left to fit or score", code=TOO_LITTLE_DATA)


def _merged(parts: list[_Samples]) -> _Samples:
    """The regression data of several bouts, one after the other (``iv.k`` indexes each bout's own samples).

    With pose intervals (every part has them, or none): their segments point into the merged
    shape intervals, and their weights are the bouts' weights block by block.
    """
    import scipy.sparse

    ivs = [p.iv for p in parts]
    effort = None if ivs[0].effort is None else np.concatenate([iv.effort for iv in ivs])  # type: ignore[misc]
    iv = Intervals(t=np.concatenate([iv.t for iv in ivs]), k=np.concatenate([iv.k for iv in ivs]),
                   r=np.concatenate([iv.r for iv in ivs]), rdot=np.concatenate([iv.rdot for iv in ivs]),
                   xi=np.concatenate([iv.xi for iv in ivs]), effort=effort,
                   dt=np.concatenate([iv.dt for iv in ivs]))
    ph, Y = np.concatenate([p.ph for p in parts]), np.concatenate([p.Y for p in parts])
    if all(p.pose is None for p in parts):
        return _Samples(iv, ph, Y, None)
    poses = [p.pose for p in parts]
    if any(pv is None for pv in poses):
        raise SudsDataError("bouts: expected pose intervals in every bout or in none")
    offsets = np.cumsum([0] + [p.iv.t.size for p in parts[:-1]])
    pose = PoseIntervals(t0=np.concatenate([pv.t0 for pv in poses]), t1=np.concatenate([pv.t1 for pv in poses]),
                         xi=np.concatenate([pv.xi for pv in poses]),
                         seg_k=np.concatenate([pv.seg_k + off for pv, off in zip(poses, offsets)]),
                         seg_t=np.concatenate([pv.seg_t for pv in poses]),
                         weights=scipy.sparse.block_diag([pv.weights for pv in poses], format="csr"))

    def cat(name: str) -> FloatArray:
        return np.concatenate([getattr(p, name) for p in parts])

    return _Samples(iv, ph, Y, pose, cat("seg_ph"), cat("seg_r"), cat("seg_rdot"), cat("row_ph"), cat("row_r"))


def _ranges(n: int, step: int) -> list[tuple[int, int]]:
    """Consecutive ranges [a, b) of at most ``step`` covering 0 … n − 1."""
    return [(a, min(a + step, n)) for a in range(0, n, step)]


def _rows(config: SudsConfig, X: FloatArray, n_actuated: int, kernel_scale: object) -> object:
    """Rows a … b − 1 of the design of regressor rows X, on demand."""
    return lambda a, b: regressor_design(config, X[a:b], n_actuated, kernel_scale)  # type: ignore[arg-type]


def _averaged_rows(config: SudsConfig, Xs: FloatArray, W: object, n_actuated: int, kernel_scale: object,
                   n_columns: int) -> object:
    """Rows a … b − 1 of the averaged design W·A(Xs), on demand (:func:`averaged_design_rows`)."""
    import scipy.sparse

    Wc = scipy.sparse.csr_matrix(W)
    return lambda a, b: averaged_design_rows(config, Xs, Wc, n_actuated, kernel_scale,  # type: ignore[arg-type]
                                             n_columns, a, b)


def split_cycles(rec: Recording, n_train: int, n_test: int | None = None) -> tuple[Recording, Recording]:
    """Split a recording into the first ``n_train`` gait cycles and the next ``n_test`` (default: the rest).

    Cycles are counted in time from the first shape stamp, at ``rec.gait_hz`` (default 1 Hz):
    cycle c covers [t_0 + c/f, t_0 + (c + 1)/f), and the recording holds as many whole cycles as
    its span plus one sampling period (the last sample's own period) covers, within half a
    median period, so dropped samples and jittered stamps do not change the count.  Stamps within
    half a period before a cycle boundary count as the later cycle (jitter, round-off).
    """
    hz = rec.gait_hz or 1.0
    dt = rec.dt
    n_cycles = int(np.floor((rec.t[-1] - rec.t[0] + 1.5 * dt) * hz))
    if n_train < 1 or n_train >= n_cycles:
        raise SudsDataError(
            f"cannot train on {n_train} cycles: the recording holds {n_cycles} cycles of "
            f"{1.0 / hz:g} s ({rec.t[-1] - rec.t[0] + dt:.3f} s of shape stamps)"
            + (f"; train on fewer, e.g. {n_cycles // 2} (the first half)" if n_cycles >= 2 else ""),
            code=TOO_LITTLE_DATA,
        )
    stop = n_cycles if n_test is None else min(n_cycles, n_train + n_test)
    k_train, k_stop = np.searchsorted(rec.t, rec.t[0] + np.array([n_train, stop]) / hz - 0.5 * dt)
    if stop == n_cycles:
        k_stop = rec.n_samples
    return rec.slice(0, int(k_train)), rec.slice(int(k_train), int(k_stop))


def split_bouts(rec: Recording, n_train: int, n_test: int | None = None
                ) -> tuple[list[Recording], list[Recording]]:
    """Whole bouts for training and for the held-out test, from ``rec.bouts``.

    The first bouts in time whose cycles (duration × ``rec.gait_hz``, each bout's duration
    counting its last sample's period) reach ``n_train`` train; the following bouts, up to
    ``n_test`` cycles (default: every bout left), are held out.  No bout is cut.

    Raises
    ------
    SudsDataError
        (code ``too_little_data``) no bouts, fewer than two, or too few cycles in them to train
        on ``n_train`` cycles and still hold out one whole bout; the message names the bouts
        and cycles there are.
    """
    hz = rec.gait_hz or 1.0
    dt = rec.dt
    pieces: list[Recording] = []
    for a, b in rec.bouts:
        eps = 1e-9 * max(1.0, abs(b))  # stamps round-tripped through the metadata text
        k0 = int(np.searchsorted(rec.t, a - eps, side="left"))
        k1 = int(np.searchsorted(rec.t, b + eps, side="right"))
        if k1 - k0 >= 2:
            pieces.append(rec.slice(k0, k1))
    cycles = [float((p.t[-1] - p.t[0] + dt) * hz) for p in pieces]
    total = sum(cycles)
    what = (f"the recording's {len(pieces)} bouts hold {total:.1f} cycles of {1.0 / hz:g} s "
            f"({', '.join(f'{c:.1f}' for c in cycles) or 'none'})")
    if len(pieces) < 2:
        raise SudsDataError(f"cannot hold out whole bouts: {what}; need at least 2 bouts (one to train on, "
                            "one to hold out)", code=TOO_LITTLE_DATA)
    if n_train < 1:
        raise SudsDataError(f"cannot train on {n_train} cycles: expected at least 1", code=TOO_LITTLE_DATA)
    done, k = 0.0, 0
    while k < len(pieces) and done < n_train - 1e-9:
        done += cycles[k]
        k += 1
    if done < n_train - 1e-9 or k >= len(pieces):
        most = total - cycles[-1]
        raise SudsDataError(f"cannot train on {n_train} cycles of whole bouts and hold out a whole bout: {what}; "
                            f"at most {most:.1f} cycles can train (pass --train-cycles {int(np.floor(most))} or "
                            "fewer)", code=TOO_LITTLE_DATA)
    test: list[Recording] = []
    held = 0.0
    for p, c in zip(pieces[k:], cycles[k:]):
        if n_test is not None and test and held >= n_test - 1e-9:
            break
        test.append(p)
        held += c
    return pieces[:k], test
