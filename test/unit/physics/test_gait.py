"""Gait files (suds-gait/1): round trip, each refusal, evaluation, nominal conversion, constraints."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from suds_ros.core.errors import MODEL_MISMATCH, SudsConfigError
from suds_ros.core.physics.gait import (
    BAD_GAIT_FILE,
    GAIT_CONSTRAINT,
    Gait,
    check_constraints,
    check_gait,
    constraint_violations,
    dump_gait,
    gait_limits,
    load_gait,
    loads_gait,
    nominal_gait,
    save_gait,
)
from suds_ros.core.physics.robot_model import dump_model, load_model
from suds_ros.core.physics.systems import builtin_model, load_system, make_system

SPEC_EXAMPLE = """
format: suds-gait/1
system: eel6
gait_hz: 0.8
joints:
  joint_1: {offset: 0.0, cos: [0.0, 0.05, 0.0], sin: [1.0, 0.0, -0.02]}
  joint_2: {offset: 0.0, cos: [-0.87, 0.0, 0.01], sin: [0.5, 0.03, 0.0]}
objective: speed
predicted: {speed: 0.45}
"""


def test_spec_example_loads_and_round_trips(tmp_path: Path) -> None:
    g = loads_gait(SPEC_EXAMPLE)
    assert g.system == "eel6" and g.gait_hz == 0.8 and g.joints == ("joint_1", "joint_2")
    assert g.order == 3 and g.cos[1] == (-0.87, 0.0, 0.01) and g.objective == "speed"
    assert g.predicted == (("speed", 0.45),)
    path = tmp_path / "g.yaml"
    save_gait(g, path)
    assert load_gait(path) == g
    g2 = g.from_vector(np.random.default_rng(1).normal(size=g.to_vector().size), 3)
    assert loads_gait(dump_gait(g2)) == g2  # floats written exactly


def test_shorter_list_means_zeros() -> None:
    g = loads_gait("format: suds-gait/1\nsystem: x\ngait_hz: 1\njoints: {a: {cos: [1.0], sin: [0, 0, 2]}}\n")
    assert g.cos == ((1.0, 0.0, 0.0),) and g.sin == ((0.0, 0.0, 2.0),) and g.offset == (0.0,)


def _doc() -> dict:  # type: ignore[type-arg]
    return yaml.safe_load(SPEC_EXAMPLE)


@pytest.mark.parametrize("change, key", [
    (lambda d: d.update(colour="red"), "`colour`"),
    (lambda d: d["joints"]["joint_1"].update(amp=1.0), "`joints.joint_1.amp`"),
    (lambda d: d["joints"]["joint_2"]["sin"].__setitem__(1, float("nan")), r"`joints.joint_2.sin\[1\]`"),
    (lambda d: d["joints"]["joint_1"].update(offset=float("inf")), "`joints.joint_1.offset`"),
    (lambda d: d["joints"]["joint_1"].update(cos=[0.1] * 9), "`joints.joint_1.cos`"),
    (lambda d: d.update(format="suds-gait/2"), "`format`"),
    (lambda d: d.update(gait_hz=0), "`gait_hz`"),
    (lambda d: d.pop("gait_hz"), "`gait_hz`"),
    (lambda d: d.update(objective="fast"), "`objective`"),
    (lambda d: d["joints"]["joint_1"].update(sin="1.0"), "`joints.joint_1.sin`"),
])
def test_bad_files_are_refused_naming_the_key(tmp_path: Path, change, key: str) -> None:  # type: ignore[no-untyped-def]
    doc = _doc()
    change(doc)
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(SudsConfigError, match=key) as info:
        load_gait(path)
    assert info.value.code == BAD_GAIT_FILE


def test_duplicate_key_and_missing_file_are_refused(tmp_path: Path) -> None:
    with pytest.raises(SudsConfigError, match="duplicate key 'joint_1'"):
        loads_gait(SPEC_EXAMPLE.replace("objective:", "  joint_1: {sin: [1]}\nobjective:"))
    with pytest.raises(SudsConfigError, match="cannot read the gait file"):
        load_gait(tmp_path / "none.yaml")


def _purcell_gait(**changes: object) -> Gait:
    g = Gait(system="purcell3", gait_hz=1.0, joints=("joint_1",), offset=(0.0,), cos=((0.0,),), sin=((1.0,),))
    return Gait(**{**g.__dict__, **changes})  # type: ignore[arg-type]


def test_check_against_the_system() -> None:
    system = make_system("purcell3")
    assert check_gait(_purcell_gait(), system).joints == ("joint_1",)
    with pytest.raises(SudsConfigError, match="`system`: the gait is for 'swimmer9'") as info:
        check_gait(_purcell_gait(system="swimmer9"), system)
    assert info.value.code == MODEL_MISMATCH
    with pytest.raises(SudsConfigError, match="`joints.joint_2`: a passive joint"):
        check_gait(_purcell_gait(joints=("joint_1", "joint_2"), offset=(0, 0), cos=((0,), (0,)),
                                 sin=((1,), (1,))), system)
    with pytest.raises(SudsConfigError, match="`joints.joint_9`: not a joint of 'purcell3'"):
        check_gait(_purcell_gait(joints=("joint_9",)), make_system("purcell3"))
    s9 = make_system("swimmer9")
    four = nominal_gait(s9)
    with pytest.raises(SudsConfigError, match="`joints.joint_4`: actuated joint missing"):
        check_gait(Gait(system="swimmer9", gait_hz=1.0, joints=four.joints[:3], offset=four.offset[:3],
                        cos=four.cos[:3], sin=four.sin[:3]), s9)
    # given in another order: returned in the system's actuated order
    rev = Gait(system="swimmer9", gait_hz=1.0, joints=four.joints[::-1], offset=four.offset[::-1],
               cos=four.cos[::-1], sin=four.sin[::-1])
    assert check_gait(rev, s9) == four


@pytest.mark.parametrize("name", ["purcell3", "swimmer9"])
def test_nominal_conversion_matches_the_sinusoid(name: str) -> None:
    system = make_system(name)
    g = nominal_gait(system)
    assert g.order == 1
    s = np.linspace(-2.0, 3.0, 501)
    np.testing.assert_allclose(g.at_phase(s), system.reference(s), atol=1e-13)
    # ṙ against a central difference
    t = np.linspace(0, 1, 57)
    h = 1e-6
    np.testing.assert_allclose(g.rdot(t), (g.r(t + h) - g.r(t - h)) / (2 * h), atol=1e-6)


def test_vector_round_trip_and_padding() -> None:
    g = nominal_gait(make_system("swimmer9"))
    x = g.to_vector(3)
    assert x.size == 4 * 7
    g3 = g.from_vector(x, 3)
    t = np.linspace(0, 1, 33)
    np.testing.assert_array_equal(g3.r(t), g.r(t))
    with pytest.raises(SudsConfigError, match="`order`"):
        g3.to_vector(2)


def test_half_wave_symmetry_is_odd_harmonics_only() -> None:
    g = nominal_gait(make_system("swimmer9")).from_vector(nominal_gait(make_system("swimmer9")).to_vector(3), 3)
    assert g.is_half_wave()  # a travelling sine wave: r(t + T/2) = −r(t)
    t = np.linspace(0, 1, 41)
    np.testing.assert_allclose(g.r(t + 0.5 / g.gait_hz), -g.r(t), atol=1e-12)
    x = g.to_vector(3).reshape(4, 7)
    for col, name in ((0, "offset"), (2, "cos_2"), (5, "sin_2")):
        bent = x.copy()
        bent[1, col] = 1e-3
        assert not g.from_vector(bent.ravel(), 3).is_half_wave(), name
        assert g.from_vector(bent.ravel(), 3).is_half_wave(atol=2e-3), name
    odd = x.copy()
    odd[:, 3] = 0.2  # a third harmonic keeps the symmetry
    assert g.from_vector(odd.ravel(), 3).is_half_wave()


def test_default_limits_come_from_the_nominal_gait() -> None:
    system = make_system("swimmer9")
    lim = gait_limits(system)
    assert lim.limit == pytest.approx((1.4,) * 4) and lim.speed_limit == pytest.approx((2 * np.pi * 1.4,) * 4)
    g = nominal_gait(system)
    assert constraint_violations(g, lim) == []
    fast = g.from_vector(np.concatenate([[0, 0, 0, 1.0, 0, 0, 0]] + [g.to_vector(3)[7:]]), 3)
    bad = constraint_violations(fast, lim)
    assert len(bad) == 1 and bad[0].startswith("joint_1: |ṙ|")
    with pytest.raises(SudsConfigError, match=r"joint_1: \|ṙ\| reaches") as info:
        check_constraints(fast, lim)
    assert info.value.code == GAIT_CONSTRAINT


def test_model_file_limits_load_write_and_apply(tmp_path: Path) -> None:
    model = builtin_model("purcell3").with_(limit=(1.0, None), speed_limit=(5.0, None))
    path = tmp_path / "p.yaml"
    path.write_text(dump_model(model).replace("name: purcell3", "name: purcell3"))
    back = load_model(path)
    assert back.limit == (1.0, None) and back.speed_limit == (5.0, None)
    assert back == model
    lim = gait_limits(load_system(str(path)))
    assert lim.limit == (1.0,) and lim.speed_limit == (5.0,)
    doc = yaml.safe_load(path.read_text())
    doc["joints"][0]["limit"] = -1.0
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(SudsConfigError, match=r"`joints\[0\].limit`: expected a number > 0"):
        load_model(path)


def test_a_recorded_drive_is_fitted_as_a_gait_whatever_its_start() -> None:
    """Two harmonics, noise 1e-3 rad, a lost stretch (NaN rows), stamps from t = 3.25 s: the
    coefficients come back to 1e-4 rad, with the phase of the first stamp as the origin."""
    from suds_ros.core.errors import SudsDataError
    from suds_ros.core.physics.gait import fitted_gait

    g = nominal_gait(make_system("swimmer9"))
    x = g.to_vector(2) + np.random.default_rng(0).normal(0.0, 0.05, g.to_vector(2).size)
    truth = g.from_vector(x, 2)
    t = 3.25 + np.arange(0.0, 20.0, 0.01)
    r = truth.r(t - t[0]) + np.random.default_rng(1).normal(0.0, 1e-3, (t.size, len(g.joints)))
    r[500:700] = np.nan
    got = fitted_gait(g, t, r, 2)
    assert got.joints == g.joints and got.gait_hz == g.gait_hz and got.order == 2
    assert np.max(np.abs(got.to_vector(2) - x)) < 1e-4
    with pytest.raises(SudsDataError, match="finite samples"):
        fitted_gait(g, t[:3], r[:3], 2)
    with pytest.raises(SudsDataError, match="shape"):
        fitted_gait(g, t, r[:, :2], 2)


def test_a_time_shift_keeps_the_motion_and_moves_a_turning_gaits_chord() -> None:
    """time_shifted is the same drive from another start: r'(s) = r(s + s0).  Bounds and net rotation
    stay; the speed stays for a straight gait and moves for one that turns."""
    from suds_ros.core.optimize.physics import evaluate_gait
    from suds_ros.core.physics.gait import gait_extremes, time_shifted

    system = make_system("purcell3")
    nom = nominal_gait(system)
    s = np.linspace(0.0, 1.0, 101)
    moved = time_shifted(nom, 0.3)
    np.testing.assert_allclose(moved.r(s), nom.r(s + 0.3), atol=1e-12)
    np.testing.assert_allclose(gait_extremes(moved), gait_extremes(nom), rtol=1e-3)
    bent = nom.from_vector(np.r_[0.3, nom.to_vector()[1:]], 1)  # an offset: it turns
    for gait, turns in ((nom, False), (bent, True)):
        a, b = evaluate_gait(system, gait), evaluate_gait(system, time_shifted(gait, 0.3))
        assert b["rotation"] == pytest.approx(a["rotation"], abs=1e-9)
        assert (abs(b["speed"] / a["speed"] - 1) > 1e-3) == turns, (a, b)


def test_a_time_reversal_runs_the_drive_backwards_within_the_same_bounds(tmp_path: Path) -> None:
    """time_reversed is r'(s) = r(−s): the same range and joint speed; on a robot of actuated joints only
    (principally kinematic) the body retraces its cycle, as fast and turning the other way."""
    from suds_ros.core.optimize.physics import evaluate_gait
    from suds_ros.core.physics.gait import gait_extremes, time_reversed
    from suds_ros.core.physics.systems import load_system

    model = tmp_path / "driven3.yaml"
    model.write_text("format: suds-robot/1\nname: driven3\nlinks: [{length: 0.3}, {length: 0.3}, {length: 0.3}]\n"
                     "joints:\n  - {actuated: true, gait: {amplitude: 0.6, phase: 0.0, offset: 0.2}}\n"
                     "  - {actuated: true, gait: {amplitude: 0.6, phase: 1.3}}\n")
    system = load_system(str(model))
    nom = nominal_gait(system)
    x = nom.to_vector(3)
    x[[2, 5, 9, 12]] = [0.05, -0.04, 0.03, 0.02]  # second and third harmonics too
    gait = nom.from_vector(x, 3)
    back = time_reversed(gait)
    s = np.linspace(0.0, 1.0, 101)
    np.testing.assert_allclose(back.r(s), gait.r(-s), atol=1e-12)
    np.testing.assert_allclose(back.rdot(s), -gait.rdot(-s), atol=1e-12)
    np.testing.assert_allclose(gait_extremes(back), gait_extremes(gait), rtol=1e-3)
    a, b = evaluate_gait(system, gait, work=False), evaluate_gait(system, back, work=False)
    assert abs(a["rotation"]) > 1e-3  # (the offset makes it turn)
    assert b["speed"] == pytest.approx(a["speed"], rel=1e-6)
    assert b["rotation"] == pytest.approx(-a["rotation"], rel=1e-6)


def test_a_reversal_is_a_time_shift_only_for_one_joint_at_one_harmonic_or_joints_in_phase() -> None:
    """reversal_shift: purcell3's single driven sinusoid runs backwards as itself started elsewhere (with a
    second harmonic in cosine still, in sine not), so do two joints in phase; a travelling wave does not."""
    from suds_ros.core.physics.gait import reversal_shift, time_reversed, time_shifted

    p3 = nominal_gait(make_system("purcell3"))
    s0 = reversal_shift(p3)
    assert s0 is not None
    np.testing.assert_allclose(time_shifted(p3, s0).to_vector(), time_reversed(p3).to_vector(), atol=1e-12)
    two = Gait(system="x", gait_hz=1.0, joints=("a", "b"), offset=(0.1, 0.0), cos=((0.3,), (0.6,)),
               sin=((0.4,), (0.8,)))  # in phase: one shape loop of zero area
    assert reversal_shift(two) is not None
    wave = Gait(system="x", gait_hz=1.0, joints=("a", "b"), offset=(0.1, 0.0), cos=((0.3,), (0.6,)),
                sin=((0.4,), (-0.8,)))
    assert reversal_shift(wave) is None
    x = p3.to_vector(2)  # [offset, cos 1, cos 2, sin 1, sin 2]
    assert reversal_shift(p3.from_vector(np.r_[x[:2], 0.05, x[3:]], 2)) is not None  # cos 2: still a shift
    harmonics = p3.from_vector(np.r_[x[:4], 0.05], 2)  # sin 2: not
    assert reversal_shift(harmonics) is None
