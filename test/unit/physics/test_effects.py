"""The effect catalogue: registry, exact mapping onto the chain model, validation."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.physics.effects import EFFECTS, EquationTerms, apply_effect, apply_effects, neutral_params
from suds_ros.core.errors import SudsConfigError
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.systems import purcell3_model, swimmer9_model

SPEC = {
    "joint_coulomb_friction": ("mu",),
    "joint_viscous_damping": ("d",),
    "spring_rest_offset": ("offset",),
    "spring_nonlinearity": ("k3",),
    "stiffness_to_drag_error": ("scale",),
    "drag_anisotropy_error": ("ratio",),
    "background_flow": ("vx", "vy"),
    "sensor_time_offset": ("dt",),
}


def test_registry_covers_the_specification() -> None:
    for name, params in SPEC.items():
        assert EFFECTS[name].param_names == params
    assert EFFECTS["joint_coulomb_friction"].needs_joint
    assert not EFFECTS["background_flow"].needs_joint
    assert "joint_stiffness_error" in EFFECTS


def test_joint_effects_map_onto_the_model() -> None:
    m = swimmer9_model()
    assert apply_effect(m, "joint_coulomb_friction", joint="joint_7", mu=0.5).coulomb[6] == 0.5
    assert apply_effect(m, "joint_viscous_damping", joint="joint_5", d=1.0).damping[4] == 1.0
    assert apply_effect(m, "spring_rest_offset", joint="joint_6", offset=0.25).rest[5] == 0.25
    assert apply_effect(m, "spring_nonlinearity", joint="joint_8", k3=3.0).k3[7] == 3.0
    assert apply_effect(m, "joint_stiffness_error", joint="joint_6", scale=0.5).stiffness[5] == 7.5


def test_global_effects_map_onto_the_model() -> None:
    m = purcell3_model()
    assert apply_effect(m, "stiffness_to_drag_error", scale=1.3).stiffness_scale == 1.3
    assert apply_effect(m, "drag_anisotropy_error", ratio=2.6).c_perp == pytest.approx((2.6,) * m.n_links)
    assert apply_effect(m, "background_flow", vx=0.1, vy=-0.2).flow == (0.1, -0.2)
    assert apply_effect(m, "sensor_time_offset", dt=0.03) == m


def test_combinations_add_and_return_the_pose_delay() -> None:
    m, delay = apply_effects(
        swimmer9_model(),
        [
            {"name": "spring_rest_offset", "joint": "joint_6", "offset": 0.1},
            {"name": "spring_rest_offset", "target": "joint_6", "offset": 0.15},
            {"name": "sensor_time_offset", "dt": 0.02},
            {"name": "sensor_time_offset", "dt": 0.01},
            {"name": "joint_coulomb_friction", "joint": "joint_5", "mu": 0.3},
        ],
    )
    assert m.rest[5] == pytest.approx(0.25)
    assert m.coulomb[4] == 0.3
    assert delay == pytest.approx(0.03)


def test_stiffness_scale_equals_drag_divided() -> None:
    """effects.md: k·scale ⇔ all drag / scale, so ṙ_p and ξ agree exactly."""
    m = apply_effect(purcell3_model(), "stiffness_to_drag_error", scale=1.3)
    m2 = purcell3_model().with_(c_par=1 / 1.3, c_perp=2 / 1.3)
    rng = np.random.default_rng(0)
    r, va = rng.normal(size=(50, 2)), rng.normal(size=(50, 1))
    a = RFTChain(m).velocities(r, va)
    b = RFTChain(m2).velocities(r, va)
    np.testing.assert_allclose(a[0], b[0], atol=1e-12)
    np.testing.assert_allclose(a[1], b[1], atol=1e-12)


def test_offset_shifts_the_spring_equilibrium() -> None:
    m = apply_effect(purcell3_model(), "spring_rest_offset", joint="joint_2", offset=0.25)
    tau = RFTChain(m).passive_torque(np.array([[0.0, 0.25]]))
    assert tau[0, 0] == pytest.approx(0.0)


def test_neutral_parameters_leave_the_model_unchanged() -> None:
    m = swimmer9_model()
    for name, spec in EFFECTS.items():
        joint = "link_9" if spec.needs_link else "joint_6" if spec.needs_joint else None
        out, delay = apply_effects(m, [{"name": name, "joint": joint, **neutral_params(name)}])
        assert delay == 0.0
        assert out == m.with_(c_perp=out.c_perp) and out.c_perp == pytest.approx(m.c_perp), name


def test_the_neutral_drag_ratio_is_the_models_own() -> None:
    m = swimmer9_model()
    m = m.with_(c_par=tuple(0.8 for _ in m.c_par), c_perp=tuple(1.9 for _ in m.c_perp))
    assert neutral_params("drag_anisotropy_error", m)["ratio"] == pytest.approx(1.9 / 0.8)
    assert neutral_params("drag_anisotropy_error")["ratio"] == 2.0
    out, _ = apply_effects(m, [{"name": "drag_anisotropy_error", **neutral_params("drag_anisotropy_error", m)}])
    assert out.c_perp == pytest.approx(m.c_perp)


def test_errors_name_the_problem() -> None:
    m = purcell3_model()
    with pytest.raises(SudsConfigError, match="unknown effect 'bogus'"):
        apply_effect(m, "bogus")
    with pytest.raises(SudsConfigError, match="joint 'joint_1' is actuated"):
        apply_effect(m, "joint_viscous_damping", joint="joint_1", d=0.1)
    with pytest.raises(SudsConfigError, match="`joint` must be one of"):
        apply_effect(m, "joint_viscous_damping", joint="joint_9", d=0.1)
    with pytest.raises(SudsConfigError, match="`mu` must lie in"):
        apply_effect(m, "joint_coulomb_friction", joint="joint_2", mu=-1.0)
    with pytest.raises(SudsConfigError, match="missing parameter"):
        apply_effect(m, "background_flow", vx=0.1)
    with pytest.raises(TypeError, match="unknown parameter"):
        apply_effect(m, "background_flow", vx=0.1, vy=0.0, vz=1.0)
    with pytest.raises(SudsConfigError, match="acts on the whole chain"):
        apply_effect(m, "background_flow", joint="joint_2", vx=0.1, vy=0.0)
    with pytest.raises(SudsConfigError, match="missing `name`"):
        apply_effects(m, [{"mu": 1.0}])


def _terms_from_model(base, model, delay: float) -> EquationTerms:  # type: ignore[no-untyped-def]
    """Equation-error terms read off the change an effect made to the chain model."""
    pas = list(base.passive)
    diff = lambda new, old: np.asarray(new, dtype=float)[pas] - np.asarray(old, dtype=float)[pas]  # noqa: E731
    return EquationTerms(
        mu=diff(model.coulomb, base.coulomb), d=diff(model.damping, base.damping),
        offset=diff(model.rest, base.rest), k3=diff(model.k3, base.k3),
        kscale=np.asarray(model.stiffness, dtype=float)[pas] / np.asarray(base.stiffness, dtype=float)[pas],
        scale=model.stiffness_scale / base.stiffness_scale, ratio=model.drag_ratio,
        flow=(model.flow[0] - base.flow[0], model.flow[1] - base.flow[1]), delay=delay,
    )


def _flat(t: EquationTerms) -> np.ndarray:
    return np.concatenate([t.mu, t.d, t.offset, t.k3, t.kscale, [t.scale, t.ratio, *t.flow, t.delay]])


def test_a_fully_actuated_chain_takes_only_effects_that_need_no_passive_joint(  # type: ignore[no-untyped-def]
        worm8_model) -> None:
    """Joint effects and the spring scale act through passive joints: refused, never a silent no-op."""
    assert {n for n, s in EFFECTS.items() if s.needs_passive} == {
        n for n, s in EFFECTS.items() if s.needs_joint} | {"stiffness_to_drag_error"}
    with pytest.raises(SudsConfigError, match="'stiffness_to_drag_error' acts through the passive joints; "
                                              "'worm8' has none"):
        apply_effect(worm8_model, "stiffness_to_drag_error", scale=2.0)
    with pytest.raises(SudsConfigError, match="'joint_viscous_damping' acts through the passive joints"):
        apply_effect(worm8_model, "joint_viscous_damping", joint="j3", d=1.0)
    m, delay = apply_effects(worm8_model, [{"name": "drag_anisotropy_error", "ratio": 3.0},
                                           {"name": "background_flow", "vx": 0.1, "vy": 0.0},
                                           {"name": "sensor_time_offset", "dt": 0.02}])
    assert m.drag_ratio == pytest.approx(3.0) and m.flow == (0.1, 0.0) and delay == 0.02
    # still allowed where a passive joint exists
    assert apply_effect(purcell3_model(), "stiffness_to_drag_error", scale=2.0).stiffness_scale == 2.0


def test_every_effect_has_both_parts_and_they_agree() -> None:
    """One registry entry carries the simulator change (``apply``) and the equation-error form
    (``equation``); for every effect, at a non-neutral value, both describe the same physics."""
    base = swimmer9_model()
    joint = "joint_6"
    k = list(base.passive).index(5)
    for name, spec in EFFECTS.items():
        assert callable(spec.apply) and callable(spec.equation), name
        if spec.kind == "model":  # geometric terms: test_naming checks EquationTerms.chain_model
            continue
        values = {p.name: float(np.clip(p.neutral + 1.5 * p.scale, p.lower, p.upper)) for p in spec.params}
        model, delay = apply_effects(base, [{"name": name, "joint": joint if spec.needs_joint else None, **values}])
        terms = EquationTerms.neutral(len(base.passive), base.drag_ratio)
        neutral = EquationTerms.neutral(len(base.passive), base.drag_ratio)
        spec.equation(terms, k if spec.needs_joint else None, values)
        want = _terms_from_model(base, model, delay)
        for field in ("mu", "d", "offset", "k3", "kscale"):
            np.testing.assert_allclose(getattr(terms, field), getattr(want, field), atol=1e-12,
                                       err_msg=f"{name}.{field}")
        for field in ("scale", "ratio", "delay"):
            assert getattr(terms, field) == pytest.approx(getattr(want, field), abs=1e-12), (name, field)
        assert terms.flow == pytest.approx(want.flow, abs=1e-12), name
        assert np.abs(_flat(terms) - _flat(neutral)).max() > 0.01, name  # the value was not neutral


def test_specified_effects_are_the_specification() -> None:
    assert {n for n, s in EFFECTS.items() if s.specified} == set(SPEC)
