"""Scoring identified models: the paper's Γ, predictions on held-out intervals and their scores.

Γ = 1 − Σ|model − truth| / Σ|template − truth| compares a model with the
phase-only template (the mean velocity at each phase): 1 is perfect, 0 is no
better than the template.  Output channels are named ``xi_*`` (body velocity),
``rdot_<joint>`` (passive joint velocities) and ``tau_<joint>`` (actuator effort).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsDataError

BODY_CHANNELS = ("xi_x", "xi_y", "xi_theta")


def gamma(pred: FloatArray, template: FloatArray, truth: FloatArray) -> float:
    """Γ = 1 − Σ|pred − truth| / Σ|template − truth| over all samples and channels given."""
    num = float(np.abs(pred - truth).sum())
    den = float(np.abs(template - truth).sum())
    if den == 0:
        raise SudsDataError("Γ undefined: the template reproduces the truth exactly")
    return 1.0 - num / den


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
    """

    t: FloatArray
    phase: FloatArray
    channels: tuple[str, ...]
    truth: FloatArray
    model: FloatArray
    template: FloatArray

    def columns(self, prefix: str) -> list[int]:
        """Indices of the channels whose name starts with ``prefix``."""
        return [i for i, c in enumerate(self.channels) if c.startswith(prefix)]


@dataclass(frozen=True)
class Scores:
    """Held-out accuracy.

    ``gamma_body``/``gamma_passive``: Γ over the body-velocity / passive-velocity channels;
    ``rms_model``/``rms_template``: per-channel RMS errors.
    """

    gamma_body: float
    gamma_passive: float
    gamma_torque: float | None
    rms_model: dict[str, float]
    rms_template: dict[str, float]
    n_samples: int

    def as_dict(self) -> dict[str, object]:
        """JSON-ready dictionary."""
        return {
            "gamma_body": self.gamma_body,
            "gamma_passive": self.gamma_passive,
            "gamma_torque": self.gamma_torque,
            "rms_model": self.rms_model,
            "rms_template": self.rms_template,
            "n_samples": self.n_samples,
        }


def score_prediction(p: Prediction) -> Scores:
    """Γ per channel group and per-channel RMS of a :class:`Prediction`."""
    body = p.columns("xi_")
    # channels with no motion at all (1-D swimmers' ξy, ξθ) carry no information
    body = [i for i in body if np.abs(p.template[:, i]).max() > 1e-9 or np.abs(p.truth[:, i]).max() > 1e-9]
    pas = p.columns("rdot_")
    tor = p.columns("tau_")

    def g(cols: list[int]) -> float:
        if not cols:
            return float("nan")
        return gamma(p.model[:, cols], p.template[:, cols], p.truth[:, cols])

    rms_m = {c: float(np.sqrt(np.mean((p.model[:, i] - p.truth[:, i]) ** 2))) for i, c in enumerate(p.channels)}
    rms_t = {c: float(np.sqrt(np.mean((p.template[:, i] - p.truth[:, i]) ** 2))) for i, c in enumerate(p.channels)}
    return Scores(
        gamma_body=g(body),
        gamma_passive=g(pas),
        gamma_torque=g(tor) if tor else None,
        rms_model=rms_m,
        rms_template=rms_t,
        n_samples=int(p.t.size),
    )
