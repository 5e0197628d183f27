"""The identification pipeline on recordings: phase → template → δ, δ̇ → SUDS regression → Γ.

:class:`SudsIdentifier` fits on one recording (the training cycles) and
predicts / scores another (held-out cycles).  Outputs are the body velocity
(ξx, ξy, ξθ) followed by the passive joint velocities; with ``effort`` recorded
the actuator torques are identified the same way (``torque=True``).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import NotFittedError, SudsConfigError, SudsDataError
from suds_ros.core.ident.intervals import Intervals, make_intervals
from suds_ros.core.recording import Recording
from suds_ros.core.ident.scoring import BODY_CHANNELS, Prediction, Scores, score_prediction
from suds_ros.core.ident.sysid import SudsConfig, SudsRegressor

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
        Candidate Fourier orders of the gains, chosen by cross-validation over
        contiguous blocks of training cycles (``cv_folds``); empty keeps ``suds`` as given.
    cv_folds : int
        Number of contiguous folds for the order selection.
    """

    suds: SudsConfig = field(default_factory=SudsConfig)
    template_order: int = 8
    window: int = 1
    phase: str = "phaser"
    phaser_order: int = 10
    order_grid: tuple[tuple[int, int], ...] = ((1, 0), (2, 1), (4, 2), (6, 3))
    cv_folds: int = 3

    def __post_init__(self) -> None:
        if self.phase not in ("phaser", "truth"):
            raise SudsConfigError(f"`phase`: expected 'phaser' or 'truth', got {self.phase!r}")
        if self.window < 1:
            raise SudsConfigError(f"`window`: expected ≥ 1, got {self.window!r}")
        if self.template_order < 1:
            raise SudsConfigError(f"`template_order`: expected ≥ 1, got {self.template_order!r}")


class SudsIdentifier:
    """Phase estimation, gait template and SUDS regression on recordings.

    Parameters
    ----------
    config : IdentifyConfig
    torque : bool
        Also identify actuator effort (requires ``Recording.effort``).
    """

    def __init__(self, config: IdentifyConfig = IdentifyConfig(), torque: bool = False) -> None:
        self.config = config
        self.torque = torque

    # ------------------------------------------------------------ phase
    def _phase(self, rec: Recording, fit: bool) -> FloatArray:
        if self.config.phase == "truth":
            if "phase" not in rec.truth:
                raise SudsDataError("phase='truth' needs a simulated recording with truth['phase']")
            return np.asarray(rec.truth["phase"], dtype=float)
        from suds_ros.core.phase.phaser import Phaser, PhaserConfig

        if fit:
            self.phaser_ = Phaser(PhaserConfig(order=self.config.phaser_order))
            return self.phaser_.fit_transform(rec.r)
        return self.phaser_.transform(rec.r)

    # --------------------------------------------------------- features
    def channels(self, rec: Recording) -> tuple[str, ...]:
        """Output channel names for a recording."""
        names = list(BODY_CHANNELS) + [f"rdot_{j}" for j in rec.passive]
        if self.torque:
            names += [f"tau_{j}" for j in rec.actuated]
        return tuple(names)

    def _samples(self, rec: Recording, phase: FloatArray) -> tuple[Intervals, FloatArray, FloatArray]:
        w = self.config.window
        iv = make_intervals(rec, w)
        ph = 0.5 * (phase[:-w] + phase[w:])
        Y = np.concatenate([iv.xi, iv.rdot[:, rec.passive_index]], axis=1)
        if self.torque:
            if iv.effort is None:
                raise SudsDataError("torque identification needs recorded `effort` on /suds/shape")
            Y = np.concatenate([Y, iv.effort], axis=1)
        return iv, ph, Y

    def features(self, rec: Recording, iv: Intervals, phase_mid: FloatArray) -> FloatArray:
        """Regressor input X = [φ, δ, δ̇_a] (m, 1 + nj + na) from interval data."""
        theta = self.template_.predict(phase_mid)
        dtheta = self.template_.derivative(phase_mid)
        delta = iv.r - theta
        ddelta = iv.rdot - dtheta * self.omega_
        return np.concatenate(
            [phase_mid[:, None], delta, ddelta[:, rec.actuated_index]], axis=1
        )

    # -------------------------------------------------------------- API
    def fit(self, rec: Recording) -> "SudsIdentifier":
        """Estimate phase, template and the SUDS regression from a training recording."""
        from suds_ros.core.phase.template import FourierTemplate, FourierTemplateConfig

        phase = self._phase(rec, fit=True)
        span = rec.t[-1] - rec.t[0]
        self.omega_ = float((phase[-1] - phase[0]) / span)
        if not self.omega_ > 0:
            raise SudsDataError(f"estimated phase does not advance (rate {self.omega_:.3g} rad/s)")
        tcfg = FourierTemplateConfig(order=self.config.template_order)
        self.template_ = FourierTemplate(tcfg).fit(phase, rec.r)
        iv, ph, Y = self._samples(rec, phase)
        X = self.features(rec, iv, ph)
        self.output_template_ = FourierTemplate(tcfg).fit(ph, Y)
        suds = self._select_orders(rec, X, Y, self.output_template_.predict(ph))
        self.regressor_ = SudsRegressor(len(rec.joint_names), len(rec.actuated), suds)
        self.regressor_.fit(X, Y)
        self.joint_names_ = rec.joint_names
        self.actuated_ = rec.actuated
        self.passive_ = rec.passive
        self.channels_ = self.channels(rec)
        return self

    def _select_orders(self, rec: Recording, X: FloatArray, Y: FloatArray, Yt: FloatArray) -> SudsConfig:
        """Pick the gains' Fourier orders by blocked cross-validation on the training data.

        Score: mean over output groups (body, passive, torque) of Σ|error| / Σ|template error|
        on the held-out fold; the candidate with the lowest mean over folds wins.
        Stores the table in ``cv_scores_``.
        """
        base = self.config.suds
        grid = self.config.order_grid
        self.cv_scores_: dict[tuple[int, int], float] = {}
        k = self.config.cv_folds
        if not grid or k < 2 or X.shape[0] < 10 * k:
            return base
        groups = [
            [i for i, c in enumerate(self.channels(rec)) if c.startswith(pfx)]
            for pfx in ("xi_", "rdot_", "tau_")
        ]
        groups = [g for g in groups if g]
        edges = np.linspace(0, X.shape[0], k + 1).astype(int)
        best, best_score = base, np.inf
        for lin, bil in grid:
            cfg = replace(base, linear_order=lin, bilinear_order=bil)
            total = 0.0
            for f in range(k):
                test = np.zeros(X.shape[0], dtype=bool)
                test[edges[f] : edges[f + 1]] = True
                reg = SudsRegressor(len(rec.joint_names), len(rec.actuated), cfg).fit(X[~test], Y[~test])
                err = np.abs(reg.predict(X[test]) - Y[test])
                ref = np.abs(Yt[test] - Y[test])
                total += float(np.mean([err[:, g].sum() / max(ref[:, g].sum(), 1e-300) for g in groups]))
            score = total / k
            self.cv_scores_[(lin, bil)] = score
            if score < best_score:
                best, best_score = cfg, score
        return best

    def _check(self, rec: Recording) -> None:
        if not hasattr(self, "regressor_"):
            raise NotFittedError("SudsIdentifier is not fitted yet; call fit first")
        if rec.joint_names != self.joint_names_ or rec.actuated != self.actuated_:
            raise SudsDataError(
                f"recording joints {list(rec.joint_names)} (actuated {list(rec.actuated)}) differ "
                f"from the training joints {list(self.joint_names_)} (actuated {list(self.actuated_)})"
            )

    def predict(self, rec: Recording) -> Prediction:
        """Model and template predictions with the measured outputs of ``rec``."""
        self._check(rec)
        phase = self._phase(rec, fit=False)
        iv, ph, Y = self._samples(rec, phase)
        X = self.features(rec, iv, ph)
        return Prediction(
            t=iv.t,
            phase=ph,
            channels=self.channels_,
            truth=Y,
            model=self.regressor_.predict(X),
            template=self.output_template_.predict(ph),
        )

    def score(self, rec: Recording) -> Scores:
        """Γ and RMS errors of the model and the template on ``rec`` (held-out data)."""
        return score_prediction(self.predict(rec))

    @property
    def n_parameters(self) -> int:
        """Regression parameters per output channel."""
        if not hasattr(self, "regressor_"):
            raise NotFittedError("SudsIdentifier is not fitted yet; call fit first")
        return self.regressor_.n_parameters


def split_cycles(rec: Recording, n_train: int, n_test: int | None = None) -> tuple[Recording, Recording]:
    """Split a recording into the first ``n_train`` gait cycles and the next ``n_test`` (default: the rest).

    Cycle length comes from ``rec.gait_hz`` (default 1 Hz).
    """
    hz = rec.gait_hz or 1.0
    per = int(round(1.0 / (hz * rec.dt)))
    n_cycles = rec.n_samples // per
    if n_train < 1 or n_train >= n_cycles:
        raise SudsDataError(
            f"cannot train on {n_train} cycles: the recording holds {n_cycles} cycles of {per} samples"
        )
    stop = n_cycles if n_test is None else min(n_cycles, n_train + n_test)
    return rec.slice(0, n_train * per), rec.slice(n_train * per, stop * per)
