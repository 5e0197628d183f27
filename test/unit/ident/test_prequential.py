"""Choosing among candidate regressions by their prequential loss."""

from __future__ import annotations

import numpy as np
import scipy.sparse

from suds_ros.core.ident.prequential import PrequentialSelector
from suds_ros.core.ident.sysid import AveragedTargets, SudsConfig, SudsRegressor


def _chunk(rng: np.random.Generator, m: int) -> tuple[np.ndarray, AveragedTargets]:
    """m rows of a 2-joint, fully actuated robot whose body velocity is ξ = B·ṙ_a plus noise."""
    phase = rng.uniform(0.0, 2 * np.pi, m)
    delta, rate = rng.normal(0.0, 0.1, (m, 2)), rng.normal(0.0, 1.0, (m, 2))
    X = np.column_stack([phase, delta, rate, delta, rate])  # φ, δ, δ̇_a, r, ṙ_a
    B = np.array([[0.3, -0.2], [0.1, 0.4], [-0.5, 0.2]])
    y = rate @ B.T + rng.normal(0.0, 0.05, (m, 3))
    return X, AveragedTargets(X=X, weights=scipy.sparse.identity(m, format="csr"), y=y, columns=(0, 1, 2))


def test_a_robot_without_passive_outputs_is_scored_on_its_body_velocity() -> None:
    """No passive channel (every joint driven): the body group alone decides which model is published.

    Before 2026-12-06 a chunk was scored only when both groups had errors, so on such a robot
    the first candidate stayed current whatever the data said.
    """
    rng = np.random.default_rng(0)
    big = SudsConfig(regressors=2, linear_order=6, bilinear_order=3, ridge=1e-9)
    small = SudsConfig(regressors=1, intercept_order=0, linear_order=0)
    sel = PrequentialSelector([SudsRegressor(big, n_actuated=2), SudsRegressor(small, n_actuated=2)], memory=5.0)
    for _ in range(6):
        X, avg = _chunk(rng, 60)
        sel.score_then_fit(X, np.zeros((60, 0)), avg, np.abs(avg.y), np.zeros((60, 0)))
    decay = 0.5 ** (1.0 / 5.0)
    assert np.isclose(sel.weight_, sum(decay**i for i in range(5)))  # every chunk after the first scored
    assert sel.loss_[1] < sel.loss_[0] and sel.current_ == 1 and sel.current is sel.candidates[1]
    X, avg = _chunk(rng, 200)
    err = [np.abs(c.predict(X) - avg.y).mean() for c in sel.candidates]
    assert err[1] < err[0]  # the published candidate is the one that predicts new data better
