"""The identified SUDS model: a snapshot that predicts without the estimator.

:class:`SudsModel` holds the gait template θ(φ), the mean phase rate ω̄, the
regression coefficients and the phase-only output template; it round-trips
through a JSON-ready dictionary (the ``/suds/model`` message and ``--model-out``).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import (
    DUPLICATE_STAMP,
    NAN_OR_INF,
    OUT_OF_ORDER_STAMP,
    WRONG_JOINT_COUNT,
    WRONG_JOINT_NAMES,
    SudsDataError,
)
from suds_ros.core.fourier import fourier_basis, fourier_basis_and_derivative
from suds_ros.core.ident.shape_kernel import KernelScale
from suds_ros.core.ident.sysid import SudsConfig, design_matrix, feature_layout
from suds_ros.core.phase.template import FourierTemplate, FourierTemplateConfig


@dataclass(frozen=True)
class SudsModel:
    """A snapshot of an identified model, enough to predict without the estimator.

    Attributes
    ----------
    joint_names, actuated, passive : joint bookkeeping.
    template_coef : (2·To + 1, nj) Fourier coefficients of θ(φ).
    template_residual_var : (nj,) residual variance of the shape about θ (phase-tracking weights).
    template_order : int
    omega : mean phase rate ω̄, rad/s.
    suds : SudsConfig
    coef : (p, n_out) regression coefficients.
    output_template_coef : (2·To + 1, n_out) phase-only template of the outputs.
    channels : output names.
    n_samples : interval rows the model was fitted on.
    kernel_scale : KernelScale or None, the gait's scales for random shape features
        (``suds.kernel_features`` > 0).
    """

    joint_names: tuple[str, ...]
    actuated: tuple[str, ...]
    passive: tuple[str, ...]
    template_coef: FloatArray
    template_residual_var: FloatArray
    template_order: int
    omega: float
    suds: SudsConfig
    coef: FloatArray
    output_template_coef: FloatArray
    channels: tuple[str, ...]
    n_samples: int
    kernel_scale: KernelScale | None = None

    @functools.cached_property
    def _actuated_index(self) -> list[int]:
        return [self.joint_names.index(j) for j in self.actuated]

    @functools.cached_property
    def _basis_order(self) -> int:
        """The highest Fourier order :meth:`predict` needs: the template's or a regressor group's."""
        return max(self.template_order, feature_layout(self.suds, len(self.joint_names), len(self.actuated)).max_order)

    def predict(self, phase: FloatArray, r: FloatArray, rdot: FloatArray) -> FloatArray:
        """Outputs (n, n_out) of sampling intervals: midpoint phase (n,), r (n, nj), ṙ (n, nj).

        ``r`` is the interval's state as ``suds.state`` names it (its first sample or its
        midpoint: :func:`~suds_ros.core.ident.sysid.interval_state`), ṙ its mean rate.
        """
        phase = np.atleast_1d(np.asarray(phase, dtype=float))
        # one evaluation of the harmonics for the template and the regressors (the basis of
        # order m is the first 2m + 1 columns of the basis of any higher order)
        B, dB = fourier_basis_and_derivative(phase, self._basis_order)
        nt = 2 * self.template_order + 1
        delta = np.atleast_2d(r) - B[:, :nt] @ self.template_coef
        ddelta = np.atleast_2d(rdot) - (dB[:, :nt] @ self.template_coef) * self.omega
        act = self._actuated_index
        rdot_a = np.atleast_2d(rdot)[:, act]
        return design_matrix(self.suds, phase, delta, ddelta[:, act], np.atleast_2d(r), rdot_a,
                             self.kernel_scale, basis=B) @ self.coef

    def template(self, phase: FloatArray) -> FloatArray:
        """Phase-only template prediction (n, n_out)."""
        return fourier_basis(np.atleast_1d(phase), self.template_order) @ self.output_template_coef

    def to_dict(self) -> dict[str, object]:
        """JSON-ready description (coefficients as nested lists)."""
        return {
            "joint_names": list(self.joint_names),
            "actuated": list(self.actuated),
            "passive": list(self.passive),
            "template_order": self.template_order,
            "template_coef": self.template_coef.tolist(),
            "template_residual_var": self.template_residual_var.tolist(),
            "omega": self.omega,
            "suds": {
                "regressors": self.suds.regressors,
                "intercept_order": self.suds.intercept_order,
                "linear_order": self.suds.linear_order,
                "bilinear_order": self.suds.bilinear_order,
                "ridge": self.suds.ridge,
                "forgetting": self.suds.forgetting,
                "state": self.suds.state,
                "kernel_features": self.suds.kernel_features,
                "kernel_gamma": self.suds.kernel_gamma,
                "kernel_seed": self.suds.kernel_seed,
            },
            "kernel_scale": None if self.kernel_scale is None else self.kernel_scale.to_dict(),
            "coef": self.coef.tolist(),
            "output_template_coef": self.output_template_coef.tolist(),
            "channels": list(self.channels),
            "n_samples": self.n_samples,
        }

    @classmethod
    def from_dict(cls, d: dict[str, object]) -> "SudsModel":
        """Inverse of :meth:`to_dict`."""
        s = dict(d["suds"])  # type: ignore[call-overload]
        s.setdefault("state", "midpoint")  # models saved before the choice existed used midpoints
        return cls(
            joint_names=tuple(d["joint_names"]),  # type: ignore[arg-type]
            actuated=tuple(d["actuated"]),  # type: ignore[arg-type]
            passive=tuple(d["passive"]),  # type: ignore[arg-type]
            template_coef=np.asarray(d["template_coef"], dtype=float),
            template_residual_var=np.asarray(d["template_residual_var"], dtype=float),
            template_order=int(d["template_order"]),  # type: ignore[call-overload]
            omega=float(d["omega"]),  # type: ignore[arg-type]
            suds=SudsConfig(**s),
            coef=np.asarray(d["coef"], dtype=float),
            output_template_coef=np.asarray(d["output_template_coef"], dtype=float),
            channels=tuple(d["channels"]),  # type: ignore[arg-type]
            n_samples=int(d["n_samples"]),  # type: ignore[call-overload]
            kernel_scale=None if d.get("kernel_scale") is None
            else KernelScale.from_dict(d["kernel_scale"]),  # type: ignore[arg-type]
        )


def model_template(model: SudsModel) -> FourierTemplate:
    """The fitted :class:`FourierTemplate` θ(φ) stored in a :class:`SudsModel`."""
    tmpl = FourierTemplate(FourierTemplateConfig(order=model.template_order))
    tmpl.coef_ = np.asarray(model.template_coef, dtype=float)
    tmpl.residual_var_ = np.asarray(model.template_residual_var, dtype=float)
    tmpl.n_features_in_ = tmpl.coef_.shape[1]
    return tmpl


def check_stamp(stream: str, t: float, last: float) -> None:
    """Raise unless the ``stream`` sample stamp ``t`` (s) comes after ``last``.

    Raises
    ------
    SudsDataError
        Code ``duplicate_stamp`` or ``out_of_order_stamp``.
    """
    if t <= last:
        kind, code = ("duplicate", DUPLICATE_STAMP) if t == last else ("out-of-order", OUT_OF_ORDER_STAMP)
        raise SudsDataError(f"{kind} {stream} stamp {t:.6f} s (last {last:.6f} s)", code=code)


def joint_order(have: tuple[str, ...], want: tuple[str, ...]) -> np.ndarray | None:
    """Where each joint of ``want`` sits in ``have`` (a message's names): indices, or None when equal.

    Raises
    ------
    SudsDataError
        Code ``wrong_joint_names`` when a joint of ``want`` is not in ``have``.
    """
    if have == want:
        return None
    index = {n: i for i, n in enumerate(have)}
    missing = [n for n in want if n not in index]
    if missing:
        raise SudsDataError(f"`name`: joints {missing} are missing; the message has {list(have)}",
                            code=WRONG_JOINT_NAMES)
    return np.array([index[n] for n in want], dtype=int)


def check_shape_sample(t: float, names: tuple[str, ...], position: FloatArray,
                       joint_names: tuple[str, ...]) -> FloatArray:
    """The positions of a shape sample as floats (nj,), checked against the model's ``joint_names``.

    Raises
    ------
    SudsDataError
        Code ``wrong_joint_names``, ``wrong_joint_count`` or ``nan_or_inf``.
    """
    position = np.asarray(position, dtype=float)
    if tuple(names) != joint_names:
        raise SudsDataError(f"shape sample at {t:.6f} s has joints {list(names)}; expected {list(joint_names)}",
                            code=WRONG_JOINT_NAMES)
    if position.shape != (len(joint_names),):
        raise SudsDataError(
            f"shape sample at {t:.6f} s has {position.size} positions for {len(joint_names)} joints",
            code=WRONG_JOINT_COUNT)
    # a finite sum is the fast test; only a non-finite one (NaN, Inf or an overflow) looks closer
    if not math.isfinite(t) or (not math.isfinite(float(position.sum())) and not np.all(np.isfinite(position))):
        raise SudsDataError(f"shape sample at {t!r} s contains NaN or Inf", code=NAN_OR_INF)
    return position
