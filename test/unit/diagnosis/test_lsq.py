"""Jacobians with absolute steps (:mod:`suds_ros.core.diagnosis.lsq`) and the fits that use them."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.optimize

from suds_ros.core.diagnosis import DiagnoseConfig
from suds_ros.core.diagnosis.data import prepare
from suds_ros.core.diagnosis.lsq import fd_jacobian, with_jacobian
from suds_ros.core.diagnosis.naming import Candidate, Scorer
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import purcell3_model, swimmer9_model

STAMPS = 1.7e9 + np.arange(200) * 0.01


def _shifted(x: np.ndarray) -> np.ndarray:
    """Residual of a stamp shift x (s) against a 4 ms one, on absolute stamps (as a pose stream)."""
    return np.sin(2 * np.pi * ((STAMPS + x[0]) - 1.7e9)) - np.sin(2 * np.pi * ((STAMPS + 0.004) - 1.7e9))


def test_steps_do_not_vanish_at_zero() -> None:
    f0 = _shifted(np.zeros(1))
    J = fd_jacobian(_shifted, np.zeros(1), f0, np.array([1e-5]), np.array([1.0]))
    exact = 2 * np.pi * np.cos(2 * np.pi * (STAMPS - 1.7e9))
    np.testing.assert_allclose(J[:, 0], exact, atol=0.05 * np.abs(exact).max())
    # scipy's relative steps (diff_step·|x|) at x = 0 cannot see the shift at all
    sol = scipy.optimize.least_squares(_shifted, np.zeros(1), diff_step=1e-3)
    assert sol.x[0] == 0.0
    value, jac = with_jacobian(_shifted, 1e-3, np.array([1e-5]), np.array([1.0]))
    sol = scipy.optimize.least_squares(value, np.zeros(1), jac=jac)
    assert sol.x[0] == pytest.approx(0.004, abs=1e-5)


def test_jacobian_steps_away_from_an_upper_bound() -> None:
    J = fd_jacobian(lambda x: x**2, np.array([1.0]), np.array([1.0]), np.array([1e-3]), np.array([1.0]))
    assert J[0, 0] == pytest.approx(2.0, abs=2e-3)  # backward difference: 1.999


@pytest.mark.parametrize("system, effect, name, target", [
    # a neutral 0 on the lower bound of the damping, and a neutral 0 with starts (±0.02 s, ±0.06 s)
    # that fit worse than 0 for the time offset: both stalled at 0 before
    ("swimmer9", dict(name="joint_viscous_damping", joint="joint_7", d=0.1), "d", "joint_7"),
    ("purcell3", dict(name="sensor_time_offset", dt=0.005), "dt", None),
])
def test_equation_error_fits_leave_a_neutral_zero(system, effect, name, target) -> None:  # type: ignore[no-untyped-def]
    base = {"purcell3": purcell3_model, "swimmer9": swimmer9_model}[system]()
    model, delay = apply_effects(base, [effect])
    rec = simulate(RFTChain(model), SimConfig(cycles=16, seed=7000, pose_delay=delay))
    data = prepare(rec, base)
    scorer = Scorer(data, base, DiagnoseConfig().eq_window, np.full(len(base.passive), 1e-3))
    x, g_train, g_test = scorer.fit(Candidate(((effect["name"], target),)))
    assert x[0] == pytest.approx(effect[name], rel=0.1), x
    assert g_test > 0
