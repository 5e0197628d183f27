"""The experiment that settles an ambiguous finding (:mod:`suds_ros.core.diagnosis.experiment`)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from suds_ros.core.diagnosis.experiment import ExperimentConfig, effect_sets, propose
from suds_ros.core.diagnosis.report import Alternative, FittedEffect
from suds_ros.core.physics.gait import constraint_violations, gait_limits, nominal_gait
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.systems import purcell3_model

FLOORS = {"joint_2": 1.3e-3, "xi_x": 0.0145, "xi_y": 0.0145, "xi_theta": 0.015}
FAST = ExperimentConfig(candidates=12, refit=2)


def _cycles(nats: float, threshold: float = 60.0, z: float = 2.0) -> int:
    """Cycles whose held-out half gives E nats with E − z·√(2E) = threshold."""
    target = (z / np.sqrt(2) + np.sqrt(z**2 / 2 + threshold)) ** 2
    return max(8, int(np.ceil(2 * target / nats)))


def test_the_same_physics_is_not_separable() -> None:
    """With one passive joint, its stiffness and the global stiffness-to-drag scale are one
    parameter: no drive tells them apart, and no gait is proposed."""
    base = purcell3_model()
    p = propose(base, [dict(name="stiffness_to_drag_error", scale=0.7)],
                [dict(name="joint_stiffness_error", joint="joint_2", scale=0.9)], FLOORS, 0.01, 10, 60.0, FAST)
    assert p.gait is None and p.cycles is None and not p.separable
    assert p.nats_per_cycle < 0.05


def test_a_cubic_spring_and_a_stiffer_spring_are_told_apart_by_a_drive_within_the_limits() -> None:
    """Under the nominal gait a cubic spring looks much like a stiffer linear one; the proposal
    finds a drive (within joint range and speed) that separates them better, after refitting."""
    base = purcell3_model()
    a = [dict(name="spring_nonlinearity", joint="joint_2", k3=3.0)]
    b = [dict(name="joint_stiffness_error", joint="joint_2", scale=1.2)]
    p = propose(base, a, b, FLOORS, 0.01, 10, 60.0, FAST)
    assert p.separable and p.gait is not None
    assert p.nats_per_cycle >= p.baseline_nats_per_cycle > 0
    assert p.cycles >= _cycles(p.nats_per_cycle)
    system = RFTChain(base)
    assert constraint_violations(p.gait, gait_limits(system, nominal_gait(system))) == []
    assert p.gait.joints == tuple(system.joint_names[i] for i in system.actuated)
    assert p.as_dict()["separable"] is True
    # it separates better than the nominal gait: the proposal says it is not that gait
    assert p.nats_per_cycle > p.baseline_nats_per_cycle and p.as_dict()["baseline_drive"] is False


def test_effect_sets_swap_the_alternative_for_what_it_replaces() -> None:
    effects = (FittedEffect("joint_viscous_damping", "joint_2", {"d": 0.3}, {"d": 0.01}, 70.0,
                            (Alternative("joint_coulomb_friction", "joint_2", {"mu": 0.1}, 3.0,
                                         instead_of=("joint_viscous_damping:joint_2",)),)),
               FittedEffect("background_flow", None, {"vx": 0.1, "vy": 0.0}, {"vx": 0.01, "vy": 0.01}, 200.0))
    a, b = effect_sets(effects, effects[0].alternatives[0])
    assert [e["name"] for e in a] == ["joint_viscous_damping", "background_flow"]
    assert [e["name"] for e in b] == ["background_flow", "joint_coulomb_friction"]
    assert b[1] == {"name": "joint_coulomb_friction", "joint": "joint_2", "mu": pytest.approx(0.1)}


def test_one_run_can_be_proposed_against_several_alternatives() -> None:
    """A cubic spring against a stiffer linear spring *and* a damping: the joint proposal's
    separation is the smaller of the two at its gait, and its cycles reach the threshold for
    both and make the mismatch itself visible."""
    from suds_ros.core.diagnosis.experiment import propose_all

    base = purcell3_model()
    a = [dict(name="spring_nonlinearity", joint="joint_2", k3=3.0)]
    b1 = [dict(name="joint_stiffness_error", joint="joint_2", scale=1.2)]
    b2 = [dict(name="joint_viscous_damping", joint="joint_2", d=0.05)]
    p = propose_all(base, a, [b1, b2], FLOORS, 0.01, 10, 60.0, FAST, ("cubic", "stiffer | damped"))
    assert p.separable and p.alternative == "stiffer | damped"
    only1 = propose(base, a, b1, FLOORS, 0.01, 10, 60.0, FAST)
    assert p.nats_per_cycle <= only1.nats_per_cycle * (1 + 1e-9) + 1e-9  # no better than the easier pair alone
    assert p.cycles >= _cycles(p.nats_per_cycle)
    system = RFTChain(base)
    assert constraint_violations(p.gait, gait_limits(system, nominal_gait(system))) == []
    with pytest.raises(Exception, match="alternatives"):
        propose_all(base, a, [], FLOORS, 0.01, 10, 60.0, FAST)


def test_against_the_nominal_model_only_the_effects_departure_counts() -> None:
    """"A friction, or nothing at all": the friction at 0 mimics the nominal model exactly, so the
    separation is the nominal model's misfit of the friction.  The cycles bring the held-out
    evidence past the threshold after the friction's BIC penalty, with a margin of two spreads."""
    from suds_ros.core.diagnosis.experiment import _Simulator

    base = purcell3_model()
    a = [dict(name="joint_coulomb_friction", joint="joint_2", mu=0.01)]
    p = propose(base, a, [], FLOORS, 0.01, 10, 60.0, FAST, ("friction", "none"))
    assert p.separable and p.nats_per_cycle > 0.05 and p.cycles is not None
    sim = _Simulator(base, FLOORS, RFTChain(base).joint_names, 0.01, 10, FAST.warm_cycles)

    def margin(n: float) -> float:
        E = 0.5 * n * p.nats_per_cycle
        return E - 2.0 * np.sqrt(2.0 * E) - 0.5 * np.log(sim.samples(int(np.ceil(n))))

    assert margin(p.cycles) >= 60.0 - 1e-6
    assert margin(0.95 * p.cycles) < 60.0 or p.cycles == 8
    assert p.cycles > int(np.ceil(2 * 60.0 / p.nats_per_cycle))


def test_a_drive_that_hides_the_mismatch_is_not_proposed() -> None:
    """A weak link-drag error against a link-length error (noise three times the usual): the
    drive that separates them best shows the drag error at a third of its per-sample power under
    the nominal gait, where the locator would not find it.  Only drives that keep it as visible
    as the nominal gait (or at ``visible_power``) are proposed."""
    from suds_ros.core.diagnosis.experiment import _Simulator

    base = purcell3_model()
    floors = {k: 3.0 * v for k, v in FLOORS.items()}
    a = [dict(name="link_drag_error", link="link_1", scale=0.944)]
    b = [dict(name="link_length_error", link="link_1", scale=0.9866)]
    sim = _Simulator(base, floors, RFTChain(base).joint_names, 0.01, 10, FAST.warm_cycles)
    nominal = nominal_gait(RFTChain(base))

    def powers(cfg: ExperimentConfig) -> np.ndarray:
        p = propose(base, a, b, floors, 0.01, 10, 60.0, cfg)
        assert p.gait is not None
        return sim.power(sim.outputs(a, [p.gait, nominal]), sim.outputs([], [p.gait, nominal]))

    blind = powers(ExperimentConfig(candidates=12, refit=2, visible_power=1e-9))
    assert blind[0] < 0.5 * min(blind[1], 2.0)  # what the check is for
    seen = powers(FAST)
    assert seen[0] >= min(seen[1], FAST.visible_power) * (1 - 1e-6)


def test_the_baseline_is_the_drive_the_recording_ran() -> None:
    """A recording made with half the nominal amplitude: its drive, fitted from the recording, is
    the baseline of the proposal (never worse than running it longer), not the nominal gait."""
    from suds_ros.core.diagnosis.experiment import recorded_drive
    from suds_ros.core.physics.sim import SimConfig, simulate

    base = purcell3_model()
    system = RFTChain(base)
    nominal = nominal_gait(system)
    half = nominal.from_vector(0.5 * nominal.to_vector(2), 2)
    rec = simulate(system, SimConfig(cycles=12, seed=3, gait=half, noise_std=1e-3))
    run = recorded_drive(rec, base, 2)
    # the OU perturbation on top of the drive averages out to a few hundredths of a radian
    assert np.max(np.abs(run.to_vector(2) - half.to_vector(2))) < 0.06
    a = [dict(name="joint_viscous_damping", joint="joint_2", d=0.01)]
    b = [dict(name="joint_coulomb_friction", joint="joint_2", mu=0.005)]
    at_run = propose(base, a, b, FLOORS, 0.01, 10, 60.0, FAST, run=run)
    at_nominal = propose(base, a, b, FLOORS, 0.01, 10, 60.0, FAST)
    assert at_run.baseline == "recorded" and at_nominal.baseline == "nominal"
    assert at_run.as_dict()["baseline"] == "recorded"
    assert at_run.nats_per_cycle >= at_run.baseline_nats_per_cycle > 0
    # the half-amplitude drive separates them differently from the nominal one
    assert abs(at_run.baseline_nats_per_cycle / at_nominal.baseline_nats_per_cycle - 1) > 0.05
    with pytest.raises(Exception, match="`run`"):
        propose(base, a, b, FLOORS, 0.01, 10, 60.0, FAST,
                run=dataclasses.replace(run, joints=("elsewhere",) * len(run.joints)))
