"""Discovery of a torque outside every list (:mod:`suds_ros.core.diagnosis.discovery`).

The physics injected here, a quadratic drag torque −c·|ṙ|ṙ on a passive joint, is in no
catalogue: the simulator gets it only through the test-only chain below.
"""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.diagnosis import DiagnoseConfig, diagnose
from suds_ros.core.diagnosis.data import prepare
from suds_ros.core.diagnosis.discovery import discover, formula
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import purcell3_model


class _QuadraticDragChain(RFTChain):
    """Test only: an extra torque −c·|ṙ_p|ṙ_p on every passive joint (Newton on the balance)."""

    def __init__(self, model, c: float) -> None:  # type: ignore[no-untyped-def]
        super().__init__(model)
        self.c = c

    def solve(self, r, rdot_a):  # type: ignore[no-untyped-def]
        r = np.atleast_2d(np.asarray(r, dtype=float))
        rdot_a = np.atleast_2d(np.asarray(rdot_a, dtype=float))
        D = self._metric_perm(r)
        nu = self._nu
        A = D[:, :nu, :nu]
        b = -np.matmul(D[:, :nu, nu:], rdot_a[..., None])[..., 0]
        b[:, 3:] += self.passive_torque(r)
        u = np.linalg.solve(A, b[..., None])[..., 0]
        for _ in range(30):  # F(u) = A u + c|u_p|u_p − b = 0, Jacobian A + diag(2c|u_p|)
            F = np.einsum("bij,bj->bi", A, u) - b
            F[:, 3:] += self.c * np.abs(u[:, 3:]) * u[:, 3:]
            J = A.copy()
            idx = np.arange(3, nu)
            J[:, idx, idx] += 2 * self.c * np.abs(u[:, 3:])
            step = np.linalg.solve(J, F[..., None])[..., 0]
            u = u - step
            if np.max(np.abs(step)) < 1e-12:
                break
        return u[:, :3], u[:, 3:], D


@pytest.fixture(scope="module")
def quadratic_run():  # type: ignore[no-untyped-def]
    return simulate(_QuadraticDragChain(purcell3_model(), 0.3), SimConfig(cycles=16, seed=8))


def test_quadratic_drag_is_discovered_on_the_right_joint(quadratic_run) -> None:  # type: ignore[no-untyped-def]
    base = purcell3_model()
    found = discover(prepare(quadratic_run, base), base, DiagnoseConfig(), np.array([1e-3]))
    (d,) = found
    assert d.joint == "joint_2"
    assert "|rdot|rdot" in d.terms, formula(d)
    # torque on r_j: −c·|ṙ|ṙ, c = 0.3; the rates' noise shared with the residual biases it by ~1 %
    assert d.terms == {"|rdot|rdot": pytest.approx(-0.3, rel=0.05)}, formula(d)
    assert d.stderr["|rdot|rdot"] > 0
    assert "quadratic (form) drag" in d.physics
    assert d.heldout_reduction >= 0.5


def test_nothing_is_discovered_in_a_nominal_recording(purcell3_run) -> None:  # type: ignore[no-untyped-def]
    base = purcell3_model()
    assert discover(prepare(purcell3_run, base), base, DiagnoseConfig(), np.array([1e-3])) == ()


@pytest.fixture(scope="module")
def quadratic_run_60():  # type: ignore[no-untyped-def]
    return simulate(_QuadraticDragChain(purcell3_model(), 0.3), SimConfig(cycles=60, seed=9))


@pytest.mark.slow
def test_the_report_discovers_quadratic_drag_beyond_the_catalogue(  # type: ignore[no-untyped-def]
    quadratic_run_60,
) -> None:
    """Issue 10, through the whole pipeline on a 60-cycle recording: viscous damping stands in
    for the quadratic drag (it removes most of the mismatch), and the formula on top of it names
    the |ṙ|ṙ term on joint_2 with the damping cancelled; re-simulated, the mismatch is gone."""
    rep = diagnose(quadratic_run_60, purcell3_model())
    d = rep.to_dict()
    assert d["mismatch"] is True
    (found,) = d["discovered"]  # type: ignore[misc]
    assert set(found) == {"joint", "terms", "stderr", "physics", "heldout_reduction",
                          "resimulated_improvement"}
    assert found["joint"] == "joint_2", found
    # torque on r_j: −c·|ṙ|ṙ with c = 0.3
    assert found["terms"]["|rdot|rdot"] == pytest.approx(-0.3, rel=0.25), found
    assert "quadratic (form) drag" in found["physics"]
    # whatever the catalogue named, catalogue + formula must model damping-free quadratic drag:
    # the formula's linear term (if any) cancels the named damping to within 25 % of it
    named_d = sum(e["parameters"]["d"] for e in d["effects"] if e["name"] == "joint_viscous_damping")
    assert found["terms"].get("rdot", 0.0) == pytest.approx(named_d, rel=0.25, abs=0.02), (found, d["effects"])
    # re-simulated with the formula, the held-out mismatch (the catalogue fits' measure) drops
    # by at least half
    assert found["resimulated_improvement"] >= 0.5, found
    assert any("discovered" in n and "|rdot|rdot" in n for n in rep.notes), rep.notes


def test_the_discovered_torque_chain_matches_the_true_physics(quadratic_run) -> None:  # type: ignore[no-untyped-def]
    """The re-simulation chain with the true formula gives the true chain's velocities."""
    from suds_ros.core.diagnosis.resimulate import DiscoveredTorqueChain

    base = purcell3_model()
    truth = _QuadraticDragChain(base, 0.3)
    mine = DiscoveredTorqueChain(base, {"joint_2": {"|rdot|rdot": -0.3}})
    r = quadratic_run.r[:50]
    rdot_a = np.diff(quadratic_run.r[:51], axis=0)[:, list(base.actuated)] / 0.01
    xi_t, v_t = truth.velocities(r, rdot_a)
    xi_m, v_m = mine.velocities(r, rdot_a)
    np.testing.assert_allclose(v_m, v_t, atol=1e-9)
    np.testing.assert_allclose(xi_m, xi_t, atol=1e-9)


def test_the_discovered_formula_re_simulated_removes_most_of_the_mismatch(  # type: ignore[no-untyped-def]
    quadratic_run,
) -> None:
    """Issue 10: quadratic drag −c·|ṙ|ṙ discovered as a |ṙ|ṙ term on joint_2 and, added to the
    simulator, the held-out mismatch (the catalogue fits' measure) drops by at least half."""
    from suds_ros.core.diagnosis import discover_formulas

    found = discover_formulas(quadratic_run, purcell3_model())
    (d,) = found
    assert d.joint == "joint_2" and "|rdot|rdot" in d.terms, formula(d)
    assert d.resimulated_improvement is not None and d.resimulated_improvement >= 0.5, d


def test_nothing_to_re_simulate_in_a_nominal_recording(purcell3_run) -> None:  # type: ignore[no-untyped-def]
    from suds_ros.core.diagnosis import discover_formulas

    assert discover_formulas(purcell3_run, purcell3_model()) == ()
