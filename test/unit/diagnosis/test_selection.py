"""Stepwise selection of effects on absolute evidence (:mod:`suds_ros.core.diagnosis.selection`)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from suds_ros.core.diagnosis import DiagnoseConfig
from suds_ros.core.diagnosis.data import prepare
from suds_ros.core.diagnosis.naming import Candidate
from suds_ros.core.diagnosis.selection import _compatible, _in_span, name_mismatch
from suds_ros.core.errors import SudsConfigError
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import make_system, purcell3_model


def test_compatible_refuses_a_member_twice_and_a_global_effect_twice() -> None:
    cur = Candidate((("spring_rest_offset", "joint_6"), ("background_flow", None)))
    assert not _compatible(cur, ("spring_rest_offset", "joint_6"))
    assert not _compatible(cur, ("background_flow", None))
    assert _compatible(cur, ("spring_rest_offset", "joint_7"))
    assert _compatible(cur, ("sensor_time_offset", None))


def test_config_rejects_bad_selection_settings() -> None:
    for bad in (dict(max_effects=0), dict(step_candidates=0), dict(evidence_threshold=-1.0),
                dict(arbitrate_max=-1), dict(arbitrate_rel=-0.1), dict(arbitrate_margin=-1.0)):
        with pytest.raises(SudsConfigError):
            DiagnoseConfig(**bad)  # type: ignore[arg-type]


def _naming(effects, cycles: int, seed: int, **cfg):  # type: ignore[no-untyped-def]
    base = purcell3_model()
    model, delay = apply_effects(base, effects)
    rec = simulate(RFTChain(model), SimConfig(cycles=cycles, seed=seed, pose_delay=delay))
    config = dataclasses.replace(DiagnoseConfig(), **cfg)
    return name_mismatch(prepare(rec, base), base, config, np.array([1e-3]))


def test_a_weak_second_effect_is_kept_on_its_own_evidence() -> None:
    """The issue's case: a large rest offset and a weak flow; the flow's evidence is judged on its
    own, not against the offset's (the old relative rule threw it away)."""
    effects = [dict(name="spring_rest_offset", joint="joint_2", offset=0.2),
               dict(name="background_flow", vx=0.015, vy=0.010)]
    n = _naming(effects, 40, 3)
    assert n.chosen.cand.label == "spring_rest_offset:joint_2 + background_flow", n.steps
    assert len(n.evidence) == 2 and n.evidence[1] > DiagnoseConfig().evidence_threshold
    assert n.evidence[0] > 10 * n.evidence[1]  # the flow is weak next to the offset and still kept
    assert n.chosen.x[1:] == pytest.approx([0.015, 0.010], rel=0.25)
    # the same data with a threshold above the flow's evidence names the offset alone
    n2 = _naming(effects, 40, 3, evidence_threshold=n.evidence[1] + 1.0)
    assert n2.chosen.cand.label == "spring_rest_offset:joint_2"
    assert n2.gains[1] == pytest.approx(n.evidence[1], rel=0.05)


def test_a_nominal_recording_gives_no_evidence_above_the_threshold(  # type: ignore[no-untyped-def]
    purcell3_run,
) -> None:
    base = purcell3_model()
    n = name_mismatch(prepare(purcell3_run, base), base, DiagnoseConfig(), np.array([1e-3]))
    assert n.gains[0] < DiagnoseConfig().evidence_threshold


def test_max_effects_caps_the_set() -> None:
    effects = [dict(name="spring_rest_offset", joint="joint_2", offset=0.2),
               dict(name="background_flow", vx=0.05, vy=0.0)]
    n = _naming(effects, 16, 4, max_effects=1)
    assert len(n.chosen.cand.parts) == 1 and len(n.gains) == 1


# ------------------------------------------------------------------------------ end to end
@pytest.mark.slow
def test_three_effects_at_once_swimmer9(run_case, check_recovered) -> None:  # type: ignore[no-untyped-def]
    effects = [
        dict(name="spring_rest_offset", joint="joint_6", offset=0.2),
        dict(name="joint_viscous_damping", joint="joint_8", d=0.5),
        dict(name="background_flow", vx=0.03, vy=-0.02),
    ]
    rep = run_case("swimmer9", effects, cycles=30, seed=7)
    check_recovered(rep, effects)
    assert all(e["evidence"] > DiagnoseConfig().evidence_threshold for e in rep.to_dict()["effects"])


@pytest.mark.slow
def test_a_longer_tail_link_is_named_as_a_model_parameter_error() -> None:
    """swimmer9 whose tail link is 30 % longer than the model says, model parameters suspected."""
    from suds_ros.core.diagnosis import diagnose
    from suds_ros.core.physics.systems import swimmer9_model

    base = swimmer9_model()
    model, _ = apply_effects(base, [dict(name="link_length_error", link="link_9", scale=1.3)])
    rec = simulate(RFTChain(model), SimConfig(cycles=20, seed=5))
    d = diagnose(rec, base, DiagnoseConfig(model_suspects=True)).to_dict()
    assert d["unexplained"] is False
    (e,) = d["effects"]  # type: ignore[misc]
    assert (e["name"], e["target"]) == ("link_length_error", "link_9"), d
    assert e["parameters"]["scale"] == pytest.approx(1.3, rel=0.25)


@pytest.mark.slow
def test_the_equation_error_names_a_drag_anisotropy_without_the_simulators_help(  # type: ignore[no-untyped-def]
    check_recovered,
) -> None:
    """A drag anisotropy 2.1 on purcell3 (60 cycles, seed 1).

    While the torque residuals were not weighed by their sensitivity to the joint-angle noise, the
    equation error put a stiffness-to-drag error 49 nats ahead of the anisotropy (a larger drag
    ratio amplified the ṙ noise in its residual), and only the simulator's arbitration named the
    anisotropy.  Now the equation error names it, with the arbitration on or off.
    """
    from suds_ros.core.diagnosis import diagnose

    effects = [dict(name="drag_anisotropy_error", ratio=2.1)]
    n = _naming(effects, 60, 1)
    assert n.chosen.cand.label == "drag_anisotropy_error", n.steps  # the equation error's choice
    base = purcell3_model()
    model, delay = apply_effects(base, effects)
    rec = simulate(RFTChain(model), SimConfig(cycles=60, seed=1, pose_delay=delay))
    for config in (DiagnoseConfig(), dataclasses.replace(DiagnoseConfig(), arbitrate_max=0)):
        rep = diagnose(rec, base, config)
        check_recovered(rep, effects)
        assert rep.effects[0].parameters["ratio"] == pytest.approx(2.1, abs=0.01)


# ------------------------------------------------------------------ exact reparameterisations
def test_in_span_tells_a_combination_from_a_new_direction() -> None:
    rng = np.random.default_rng(0)
    A = rng.normal(size=(200, 2))
    assert _in_span(A, A @ np.array([[0.3], [-2.0]]))
    assert not _in_span(A, rng.normal(size=(200, 1)))
    assert not _in_span(A, np.zeros((200, 1)))  # a candidate that changes nothing is no swap


def _nlink5_naming(effects):  # type: ignore[no-untyped-def]
    base = make_system("nlink5").model
    model, delay = apply_effects(base, effects)
    rec = simulate(RFTChain(model), SimConfig(cycles=12, seed=5, pose_delay=delay, gait_hz=base.gait_hz))
    config = DiagnoseConfig(max_effects=2)  # the pair; a third step is another test's business
    return name_mismatch(prepare(rec, base), base, config, np.array([1e-3, 1e-3]))


def test_a_set_that_another_set_reparameterises_reports_the_swaps_as_confounded() -> None:
    """Two passive joints p, q: stiffness_to_drag_error 1.4 + q's stiffness × 0.8 is the same physics
    as p × 1.4 + q × 1.12.  Whichever of the three equivalent pairs the forward selection reaches,
    the member that another candidate replaces is reported confounded with it; a single joint's
    stiffness error has no such partner (the global scale would move both joints)."""
    base = make_system("nlink5").model
    p, q = (base.joint_names[j] for j in base.passive)
    n = _nlink5_naming([dict(name="stiffness_to_drag_error", scale=1.4),
                        dict(name="joint_stiffness_error", joint=q, scale=0.8)])
    jp, jq, s2d = f"joint_stiffness_error:{p}", f"joint_stiffness_error:{q}", "stiffness_to_drag_error"
    chosen = set(n.chosen.cand.label.split(" + "))
    assert len(chosen) == 2 and chosen <= {jp, jq, s2d}, n.steps
    named = chosen | {lab for g in n.confounded for lab in g}
    assert named == {jp, jq, s2d}, (n.steps, n.confounded)
    assert any(line.startswith("equivalent:") for line in n.steps)
    n1 = _nlink5_naming([dict(name="joint_stiffness_error", joint=p, scale=1.4)])
    assert n1.chosen.cand.parts[0] == ("joint_stiffness_error", p), n1.steps
    assert not any(s2d in g for g in n1.confounded), (n1.steps, n1.confounded)
