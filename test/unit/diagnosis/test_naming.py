"""Naming a mismatch by equation error (:mod:`suds_ros.core.diagnosis.naming`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from suds_ros.core.diagnosis import DiagnoseConfig, catalogue_candidates
from suds_ros.core.diagnosis.data import prepare
from suds_ros.core.diagnosis.naming import Candidate, equation_terms
from suds_ros.core.diagnosis.selection import name_mismatch
from suds_ros.core.physics.effects import EFFECTS, apply_effects
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import purcell3_model, swimmer9_model


def test_catalogue_covers_every_effect_on_every_passive_joint() -> None:
    model = swimmer9_model()
    labels = [c.label for c in catalogue_candidates(model)]
    passive = [f"joint_{j + 1}" for j in model.passive]
    for eid, spec in EFFECTS.items():
        if spec.kind != "catalogue":
            assert not any(lab.split(":")[0] == eid for lab in labels)
        elif spec.needs_joint:
            assert [lab for lab in labels if lab.startswith(eid + ":")] == [f"{eid}:{j}" for j in passive]
        else:
            assert labels.count(eid) == 1
    assert len(labels) == len(set(labels))


def test_equation_terms_come_from_the_registry(swimmer9_run) -> None:  # type: ignore[no-untyped-def]
    model = swimmer9_model()
    data = prepare(swimmer9_run, model)
    null = equation_terms(Candidate(()), np.zeros(0), data, model)
    assert null.ratio == pytest.approx(model.drag_ratio) and null.scale == 1.0
    assert not null.mu.any() and (null.kscale == 1.0).all() and null.flow == (0.0, 0.0)
    cand = Candidate((("joint_coulomb_friction", "joint_7"), ("background_flow", None),
                      ("joint_stiffness_error", "joint_7"), ("stiffness_to_drag_error", None)))
    t = equation_terms(cand, np.array([0.5, 0.1, -0.2, 0.7, 1.3]), data, model)
    k = list(data.pas).index(6)  # joint_7 among the passive joints
    assert t.mu[k] == 0.5 and t.mu.sum() == 0.5
    assert t.flow == (0.1, -0.2)
    assert t.kscale[k] == pytest.approx(0.7) and t.scale == pytest.approx(1.3)


def test_naming_finds_an_injected_offset() -> None:
    base = purcell3_model()
    model, _ = apply_effects(base, [dict(name="spring_rest_offset", joint="joint_2", offset=-0.2)])
    rec = simulate(RFTChain(model), SimConfig(cycles=12, seed=5))
    data = prepare(rec, base)
    naming = name_mismatch(data, base, DiagnoseConfig(), np.array([1e-3]))
    assert naming.chosen.cand.label == "spring_rest_offset:joint_2"
    assert naming.chosen.x[0] == pytest.approx(-0.2, abs=0.02)
    assert naming.ranking[0].score >= naming.ranking[-1].score


def test_model_suspects_add_every_link_and_the_pose_frame() -> None:
    model = swimmer9_model()
    labels = [c.label for c in catalogue_candidates(model, model_suspects=True)]
    links = [f"link_{i + 1}" for i in range(model.n_links)]
    for eid in ("link_length_error", "link_drag_error"):
        assert [lab for lab in labels if lab.startswith(eid + ":")] == [f"{eid}:{k}" for k in links]
    assert labels.count("pose_frame_offset") == 1


def test_a_model_parameter_has_the_same_physics_in_both_forms(swimmer9_run) -> None:  # type: ignore[no-untyped-def]
    """link_length_error in equation-error form builds the same chain as applied to the model."""
    model = swimmer9_model()
    data = prepare(swimmer9_run, model)
    t = equation_terms(Candidate((("link_length_error", "link_9"),)), np.array([1.3]), data, model)
    applied, _ = apply_effects(model, [dict(name="link_length_error", link="link_9", scale=1.3)])
    assert t.chain_model(model).link_length == pytest.approx(applied.link_length)
    assert applied.link_length[8] == pytest.approx(1.3)


def test_the_nominal_models_own_joint_terms_are_in_the_equation_error() -> None:
    """A model with its own damping, cubic spring and dry friction leaves no torque residual.

    The equation error once left the nominal model's damping, k3 and Coulomb terms out, so on a
    robot whose passive joint carries them the nominal model "lacked" a damping of exactly its own.
    """
    from suds_ros.core.diagnosis.naming import Scorer

    base = purcell3_model()
    model = base.with_(damping=(0.0, 0.05), k3=(0.0, 0.4), coulomb=(0.0, 0.004))
    data = prepare(simulate(RFTChain(model), SimConfig(cycles=6, seed=4)), model)
    sc = Scorer(data, model, 10, np.full(data.pas.size, 1e-4))
    x, _, g_te = sc.fit(Candidate((("joint_viscous_damping", base.joint_names[1]),)))
    assert abs(x[0]) < 5e-3 and g_te < 5.0
    # the model without its own terms is what a robot carrying them is measured against
    bare = Scorer(data, base, 10, np.full(data.pas.size, 1e-4))
    assert bare.rss0_train[0] > 3 * sc.rss0_train[0]


def test_friction_on_a_joint_stuck_most_of_the_time_is_fitted_at_its_value() -> None:
    """The stuck threshold stays above the noise when the joint is stuck for most intervals.

    purcell3's passive joint with mu = 1.6 is stuck about 80 % of the time; a threshold capped at a
    low quantile of |ṙ_p| fell inside the noise, and the stuck intervals' random sign(ṙ) cancelled
    the friction.
    """
    from suds_ros.core.diagnosis.naming import Scorer

    base = purcell3_model()
    rec = simulate(RFTChain(base.with_(coulomb=(0.0, 1.6))), SimConfig(cycles=8, seed=2))
    data = prepare(rec, base)
    v = np.abs(np.diff(rec.r[:, 1])) / np.diff(rec.t)
    assert np.mean(v < 0.3) > 0.7  # mostly stuck
    sc = Scorer(data, base, 10, np.full(1, 1e-3))
    x, _, g_te = sc.fit(Candidate((("joint_coulomb_friction", "joint_2"),)))
    assert abs(x[0] - 1.6) < 0.1 * 1.6 and g_te > 100


def test_a_larger_drag_ratio_is_not_taken_for_a_weaker_spring() -> None:
    """The equation error weighs its residuals by their sensitivity to the joint-angle noise.

    Joint-angle noise enters the torque residual through ṙ = Δr/Δt times the drag, so a candidate
    that raises the drag raised the residual's noise, and a plain least-squares likelihood held
    that against it: on tail6 with its drag ratio 2.5 → 3.6, `stiffness_to_drag_error` (which lowers
    the drag relative to the springs) out-scored the true `drag_anisotropy_error`.
    """
    from suds_ros.core.diagnosis.naming import Scorer
    from suds_ros.core.physics.systems import load_system

    base = load_system(str(Path(__file__).resolve().parents[2] / "data" / "robots" / "tail6.yaml")).model
    model, _ = apply_effects(base, [{"name": "drag_anisotropy_error", "ratio": 3.6}])
    rec = simulate(RFTChain(model), SimConfig(cycles=16, seed=11, gait_hz=base.gait_hz))
    data = prepare(rec, base)
    sc = Scorer(data, base, 10, np.full(data.pas.size, 1e-3))
    x_a, _, g_a = sc.fit(Candidate((("drag_anisotropy_error", None),)))
    x_s, _, g_s = sc.fit(Candidate((("stiffness_to_drag_error", None),)))
    assert abs(x_a[0] - 3.6) < 0.05 * 3.6
    assert g_a > g_s + 20.0, (g_a, g_s)


def test_a_candidates_neutral_drag_ratio_is_the_robots() -> None:
    m = swimmer9_model()
    m = m.with_(c_perp=tuple(2.5 * c for c in m.c_par))
    cand = Candidate((("joint_viscous_damping", "joint_2"), ("drag_anisotropy_error", None)))
    assert cand.neutral(m) == pytest.approx([0.0, 2.5])
    # without a model, the catalogue's value
    assert cand.neutral() == pytest.approx([0.0, 2.0])


def test_candidate_slices_index_each_part_in_the_parameter_vector() -> None:
    """A 3-, a 1- and a 2-parameter effect: slices 0:3, 3:4, 4:6, covering the bounds' order."""
    cand = Candidate((("pose_frame_offset", None), ("joint_viscous_damping", "joint_2"), ("background_flow", None)))
    assert cand.slices() == [slice(0, 3), slice(3, 4), slice(4, 6)]
    assert cand.slices()[-1].stop == len(cand.bounds()[0])
    assert Candidate(()).slices() == []


def test_a_body_channel_without_a_usable_window_adds_nothing_to_a_candidates_evidence() -> None:
    """Every ξ window at a gap (heavy shape losses): the channel's mean squared residual is the same tiny
    constant for every candidate, not the NaN of an empty mean, so the evidence stays finite."""
    from suds_ros.core.diagnosis.naming import Scorer

    e = np.ones((50, 1))
    ex = np.full((40, 3), 2.0)
    none = np.zeros(40, dtype=bool)
    rss = Scorer._rss(e, ex, none, 25)
    np.testing.assert_allclose(rss, [2.0, 1e-30, 1e-30, 1e-30])
    assert np.isfinite(Scorer.gain(None, rss, rss, np.array([25.0, 0.0, 0.0, 0.0])))  # type: ignore[arg-type]
    some = np.arange(40) < 10
    np.testing.assert_allclose(Scorer._rss(e, ex, some, 25), [2.0, 4.0, 4.0, 4.0], rtol=1e-12)
