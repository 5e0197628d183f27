"""The pipeline's own mechanisms (:mod:`suds_ros.core.diagnosis.pipeline`), each exercised directly."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from suds_ros.core.diagnosis import DiagnoseConfig, diagnose
from suds_ros.core.diagnosis.data import prepare
from suds_ros.core.diagnosis.locate import locate_channels
from suds_ros.core.diagnosis.naming import Candidate, Scorer
from suds_ros.core.diagnosis.pipeline import _Clock, _options, _refine, _told_apart, _weak_rivals, replay_nominal
from suds_ros.core.diagnosis.report import CandidateScore
from suds_ros.core.diagnosis.selection import Naming, Ranked, _Path, _Selector
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.lab import LabConditions, simulate_lab
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import load_system, purcell3_model

ROBOTS = Path(__file__).resolve().parents[2] / "data" / "robots"


@pytest.mark.slow
def test_the_simulator_arbitrates_between_selections_by_replay_evidence() -> None:
    """A forward selection that took a wrong path and one started from a runner-up: the simulator
    refines both and keeps the one whose replay explains the recording, and says so.

    purcell3 with a drag anisotropy 1.68 and a Coulomb friction 0.66 on joint_2: the wrong set is
    the friction with a stiffness-to-drag error (what a selection that held the friction at its
    single fit reached, ``docs/results/diagnose_sweep_lab.md`` case 0); the right one is offered
    as the alternative path.  Offered the other way round, the right set stays and no note is made.
    """
    base = purcell3_model()
    truth = [dict(name="drag_anisotropy_error", ratio=1.68),
             dict(name="joint_coulomb_friction", joint="joint_2", mu=0.66)]
    model, _ = apply_effects(base, truth)
    rec = simulate(RFTChain(model), SimConfig(cycles=30, seed=11))
    config = DiagnoseConfig()
    nom = replay_nominal(prepare(rec, base), base, config, None)
    located = locate_channels(nom.F0, nom.E0, nom.table, nom.cycle, config)
    assert located
    sel = _Selector(Scorer(nom.data, base, config.eq_window, nom.floors[0]), config)
    wrong = sel.fit(Candidate((("joint_coulomb_friction", "joint_2"), ("stiffness_to_drag_error", None))),
                    np.array([0.77, 1.19]))
    right = sel.fit(Candidate((("joint_coulomb_friction", "joint_2"), ("drag_anisotropy_error", None))),
                    np.array([0.66, 1.68]))

    def naming(first, second) -> Naming:  # type: ignore[no-untyped-def]
        path = _Path(second, (), (100.0, 100.0), (), ())
        return Naming((), first, (), (100.0, 100.0), alternatives=(path,), fits={})

    fit = _refine(nom, naming(wrong, right), list(located), _Clock())
    got = {(e.name, e.target): e.parameters for e in fit.effects}
    assert set(got) == {("joint_coulomb_friction", "joint_2"), ("drag_anisotropy_error", None)}, fit.notes
    assert got[("drag_anisotropy_error", None)]["ratio"] == pytest.approx(1.68, rel=0.05)
    assert got[("joint_coulomb_friction", "joint_2")]["mu"] == pytest.approx(0.66, rel=0.05)
    assert any(n.startswith("the simulator preferred") for n in fit.notes), fit.notes
    again = _refine(nom, naming(right, wrong), list(located), _Clock())
    assert {(e.name, e.target) for e in again.effects} == set(got)
    assert not any(n.startswith("the simulator preferred") for n in again.notes), again.notes


def _ranked(parts: tuple[tuple[str, str | None], ...], score: float) -> Ranked:
    cand = Candidate(parts)
    return Ranked(CandidateScore(cand.label, (), 1, score, 0.0), cand, np.zeros(len(parts)))


def test_a_weakly_named_effect_gets_rivals_on_its_joint_first_then_the_best_of_the_rest() -> None:
    """Below the evidence threshold the equation error's ranking does not exclude the others."""
    chosen = _ranked((("joint_viscous_damping", "joint_2"),), 7.0)
    fits = {r.cand.label: r for r in [
        chosen,
        _ranked((("sensor_time_offset", None),), 14.0),
        _ranked((("joint_coulomb_friction", "joint_2"),), -3.0),  # below zero, but on the same joint
        _ranked((("spring_rest_offset", "joint_2"),), 1.0),
        _ranked((("background_flow", None),), -1.0),  # neither: not a rival
        _ranked((("drag_anisotropy_error", None),), 2.0),
        _ranked((("joint_viscous_damping", "joint_2"), ("sensor_time_offset", None)), 20.0),  # a pair: not one
    ]}
    naming = Naming((), chosen, (), (7.0,), fits=fits)
    seen = {frozenset(chosen.cand.parts)}
    got = [o.cand.label for o in _weak_rivals(naming, DiagnoseConfig(), seen)]
    assert got == ["spring_rest_offset:joint_2", "joint_coulomb_friction:joint_2", "sensor_time_offset",
                   "drag_anisotropy_error"]
    assert [o.cand.label for o in _weak_rivals(naming, DiagnoseConfig(weak_max=2), seen)] == got[:2]
    assert _weak_rivals(naming, DiagnoseConfig(weak_max=0), seen) == []
    # named with evidence above the threshold, or as a set: the equation error's pick stands
    strong = Naming((), _ranked(chosen.cand.parts, 80.0), (80.0,), fits=fits)
    assert _weak_rivals(strong, DiagnoseConfig(), seen) == []
    pair = Naming((), fits["joint_viscous_damping:joint_2 + sensor_time_offset"], (), fits=fits)
    assert _weak_rivals(pair, DiagnoseConfig(), seen) == []


def test_the_selection_without_its_last_member_is_refined_too() -> None:
    """The simulator judges the forward selection's last step: the set without the member added last
    is an option of its own, started from the selection's values, with the confounded groups its
    members lead and the equation-error evidence it had; none for a single effect or a set already offered."""
    drag, offset, ratio = ("link_drag_error", "link_2"), ("pose_frame_offset", None), ("drag_anisotropy_error", None)
    chosen = Ranked(CandidateScore("", (), 1, 900.0, 0.0), Candidate((drag, offset, ratio)),
                    np.array([1.77, -0.12, 0.08, -0.17, 2.23]))
    pair = _ranked((drag, offset), 700.0)
    groups = (("link_drag_error:link_2", "link_drag_error:link_3"), ("drag_anisotropy_error", "background_flow"))
    naming = Naming((), chosen, groups, (500.0, 800.0, 200.0), fits={pair.cand.label: pair})
    got = [o for o in _options(naming, DiagnoseConfig()) if o.cand.parts == (drag, offset)]
    assert len(got) == 1
    np.testing.assert_array_equal(got[0].x, [1.77, -0.12, 0.08, -0.17])
    assert got[0].groups == groups[:1]
    assert got[0].eq_score == 700.0
    single = Naming((), _ranked((drag,), 300.0), (), (300.0,), fits={})
    assert [o.cand.parts for o in _options(single, DiagnoseConfig())] == [(drag,)]
    offered = Naming((), chosen, (), (500.0, 800.0, 200.0), alternatives=(_Path(pair, (), (1.0, 1.0), (), ()),),
                     fits={})
    assert [o.cand.parts for o in _options(offered, DiagnoseConfig())] == [(drag, offset, ratio), (drag, offset)]


def test_only_a_one_for_one_swap_tells_a_confounded_member_apart() -> None:
    """A refined set with one effect in place of one reported member, well below the reported set,
    tells that effect apart; the selection without its last member also lacks a member, and its
    deficit says nothing about the effect it holds instead of another (the lab sweep's case 10:
    joint_2 stiffness or stiffness-to-drag, beside an anisotropy the shorter set lacks)."""
    def tried(parts, evidence, failed=""):  # type: ignore[no-untyped-def]
        return SimpleNamespace(cand=Candidate(parts), evidence=evidence, failed=failed)

    offset, ratio = ("sensor_time_offset", None), ("drag_anisotropy_error", None)
    stiff, s2d, damp = ("joint_stiffness_error", "joint_2"), ("stiffness_to_drag_error", None), \
        ("joint_viscous_damping", "joint_2")
    win = tried((offset, stiff, ratio), 5000.0)
    shorter = tried((offset, s2d), 2000.0)  # s2d for stiff, and no anisotropy
    swap = tried((offset, damp, ratio), 4000.0)  # damping for stiff, one for one
    close = tried((offset, s2d, ratio), 4999.0)  # inside the band: not told apart
    assert _told_apart(win, [win, shorter, close], 10.0) == set()  # type: ignore[arg-type]
    got = _told_apart(win, [win, shorter, swap, close], 10.0)  # type: ignore[arg-type]
    assert got == {"joint_viscous_damping:joint_2"}
    diverged = tried((offset, damp, ratio), -np.inf, "the simulated motion diverged")  # could not be replayed
    assert _told_apart(win, [win, shorter, diverged, close], 10.0) == set()  # type: ignore[arg-type]


@pytest.mark.slow
def test_a_last_member_the_replay_does_not_show_is_left_out() -> None:
    """eel4 with a link_2 drag error and a pose-frame offset, recorded the lab way (the lab sweep's
    case 88): the equation error adds a drag anisotropy 2.23 (eel4's own ratio is 2.34) on top of
    the pair, and the replay cannot tell it apart (1.5 nats over the whole recording).  The set
    without it, refined on its own, is preferred; the anisotropy may be listed as an alternative,
    never named."""
    base = load_system(str(ROBOTS / "eel4.yaml")).model
    effects = [dict(name="link_drag_error", link="link_2", scale=1.7725453390519708),
               dict(name="pose_frame_offset", x=-0.1187914521389034, y=0.07769970068461904, yaw=-0.16984450452226094)]
    model, delay = apply_effects(base, effects)
    rec = simulate_lab(RFTChain(model), SimConfig(cycles=60, seed=5136, pose_delay=delay, gait_hz=base.gait_hz),
                       LabConditions(pose_hz=120.0))
    rep = diagnose(rec, base)
    got = {(e.name, e.target): e.parameters for e in rep.effects}
    assert set(got) == {("link_drag_error", "link_2"), ("pose_frame_offset", None)}, (got, rep.notes)
    assert got[("link_drag_error", "link_2")]["scale"] == pytest.approx(1.7725, rel=0.05)
    assert any(n.startswith("the simulator preferred link_drag_error:link_2 + pose_frame_offset") for n in rep.notes)


def test_a_weak_friction_is_not_named_as_a_damping() -> None:
    """purcell3, Coulomb friction 0.04 on joint_2, 16 cycles with angle noise 5e-3.

    The noise blurs sign(ṙ), and the equation error ranks a viscous damping above the friction
    (which it scores below zero).  Without the weak-evidence rivals (``weak_max=0``) the damping is
    named, and the friction is nowhere in the report.  With them the simulator refines the friction
    too and names it, by far more than the ambiguity band; nor is the damping then called confounded.
    """
    base = purcell3_model()
    model, _ = apply_effects(base, [dict(name="joint_coulomb_friction", joint="joint_2", mu=0.04)])
    rec = simulate(RFTChain(model), SimConfig(cycles=16, seed=11, noise_std=5e-3))
    rep = diagnose(rec, base)
    assert [(e.name, e.target) for e in rep.effects] == [("joint_coulomb_friction", "joint_2")], rep.notes
    assert rep.effects[0].parameters["mu"] == pytest.approx(0.04, rel=0.1)
    assert not rep.effects[0].alternatives
    assert not any("joint_viscous_damping:joint_2" in g for g in rep.confounded_with), rep.confounded_with
    assert any(n.startswith("the simulator preferred joint_coulomb_friction") for n in rep.notes), rep.notes
    before = diagnose(rec, base, DiagnoseConfig(weak_max=0))
    assert [(e.name, e.target) for e in before.effects] == [("joint_viscous_damping", "joint_2")]


def test_the_report_does_not_depend_on_the_worker_processes() -> None:
    """DiagnoseConfig.jobs forks workers for the candidate fits, the refinements and the Jacobian
    columns; the report (which holds no timings) is the serial one, to the last digit."""
    from suds_ros.core.json_text import dumps

    base = purcell3_model()
    truth = [dict(name="joint_coulomb_friction", joint="joint_2", mu=0.3),
             dict(name="background_flow", vx=0.05, vy=0.02)]
    model, _ = apply_effects(base, truth)
    rec = simulate(RFTChain(model), SimConfig(cycles=12, seed=5))
    docs = []
    for jobs in (1, 2):
        docs.append(dumps(diagnose(rec, base, DiagnoseConfig(jobs=jobs)).to_dict()))
    assert docs[0] == docs[1]
    assert {e["name"] for e in json.loads(docs[1])["effects"]} == {"joint_coulomb_friction", "background_flow"}


def _tried(parts, x, se, evidence):  # type: ignore[no-untyped-def]
    """A refined set as ``_ambiguous`` reads it (no replay)."""
    from suds_ros.core.diagnosis.pipeline import _Option, _Tried
    from suds_ros.core.diagnosis.refine import Refined

    cand = Candidate(tuple(parts))
    x, se = np.asarray(x, dtype=float), np.asarray(se, dtype=float)
    opt = _Option(cand, x, (), (), 0.0)
    refined = Refined(cand, x, se, np.zeros_like(se), np.ones_like(se))
    return _Tried(opt, refined, None, None, evidence, evidence)  # type: ignore[arg-type]


def test_the_nominal_model_is_an_alternative_when_the_finding_is_within_the_band() -> None:
    """A located pose offset with 21 nats against a band of 60: the nominal model is listed
    (``none``), and a refined damping of 0.00025 ± 0.0001 in its place, which is the nominal
    model again, is not; a real friction within the band is."""
    from suds_ros.core.diagnosis.pipeline import _ambiguous
    from suds_ros.core.diagnosis.report import NO_EFFECT

    base = purcell3_model()
    config = DiagnoseConfig(ambiguity_band=60.0)
    win = _tried([("pose_frame_offset", None)], [0.01, 0.01, 0.02], [1e-3, 1e-3, 1e-3], 21.0)
    null_damping = _tried([("joint_viscous_damping", "joint_2")], [0.00025], [0.0001], 0.1)
    friction = _tried([("joint_coulomb_friction", "joint_2")], [0.02], [0.001], 5.0)
    alts = _ambiguous(win, [win, null_damping, friction], config, base)
    assert [a.name for a in alts] == ["joint_coulomb_friction", NO_EFFECT]
    assert alts[0].parameters == {"mu": pytest.approx(0.02)}
    none = alts[1]
    assert none.label == NO_EFFECT and none.evidence_gap == pytest.approx(21.0)
    assert none.instead_of == ("pose_frame_offset",) and none.parameters == {}
    assert json.loads(json.dumps(none.as_dict()))["target"] is None
    # beyond the band the nominal model is not an alternative
    strong = _tried([("pose_frame_offset", None)], [0.01, 0.01, 0.02], [1e-3, 1e-3, 1e-3], 400.0)
    assert _ambiguous(strong, [strong, null_damping], config, base) == ()


def test_a_drag_ratio_at_the_robots_own_value_is_no_alternative() -> None:
    """On a robot whose c⊥/c∥ is 2.5, an anisotropy refined to 2.5 ± 0.01 is the nominal model."""
    from suds_ros.core.diagnosis.pipeline import _ambiguous

    base = purcell3_model()
    base = base.with_(c_perp=tuple(2.5 * c for c in base.c_par))
    win = _tried([("joint_viscous_damping", "joint_2")], [0.02], [0.001], 30.0)
    ratio = _tried([("drag_anisotropy_error", None)], [2.5 + 1e-3], [0.01], 25.0)
    alts = _ambiguous(win, [win, ratio], DiagnoseConfig(ambiguity_band=60.0), base)
    assert [a.name for a in alts] == ["none"]
    # the same value is a real alternative on a robot of ratio 2
    assert [a.name for a in _ambiguous(win, [win, ratio], DiagnoseConfig(ambiguity_band=60.0),
                                       purcell3_model())] == ["drag_anisotropy_error", "none"]


@pytest.mark.slow
def test_a_member_the_preferred_set_lacks_is_tried_on_top(check_recovered) -> None:  # type: ignore[no-untyped-def]
    """purcell3 with a Coulomb friction, a rest offset and a pose-frame offset (the lab sweep's case
    75): the forward selection takes damping + rest offset + pose offset, the simulator prefers
    friction + rest offset, and the pose offset, dropped with the selection, is scored on top of
    that set, refined and kept: all three are named."""
    effects = [dict(name="joint_coulomb_friction", joint="joint_2", mu=0.6060534044908222),
               dict(name="pose_frame_offset", x=-0.09535238890209351, y=0.10555721208168409, yaw=0.060078967534107464),
               dict(name="spring_rest_offset", joint="joint_2", offset=-0.2511877283114359)]
    base = purcell3_model()
    model, delay = apply_effects(base, effects)
    rec = simulate(RFTChain(model), SimConfig(cycles=60, seed=3728, pose_delay=delay, gait_hz=base.gait_hz))
    rep = diagnose(rec, base)
    check_recovered(rep, effects)
    assert any("added pose_frame_offset, which the forward selection had chosen" in n for n in rep.notes), rep.notes


def test_a_set_whose_simulated_motion_diverges_is_left_out_not_fatal(monkeypatch: pytest.MonkeyPatch) -> None:
    """A refined set whose replay diverges (a softening spring far past its data, say) is left out of the
    arbitration with a note; the diagnosis stops only when no set can be replayed."""
    import suds_ros.core.diagnosis.pipeline as pipeline
    from suds_ros.core.errors import SudsSimulationError

    base = purcell3_model()
    truth = [dict(name="joint_viscous_damping", joint="joint_2", d=0.5)]
    model, _ = apply_effects(base, truth)
    rec = simulate(RFTChain(model), SimConfig(cycles=20, seed=4))
    config = DiagnoseConfig()
    nom = replay_nominal(prepare(rec, base), base, config, None)
    located = locate_channels(nom.F0, nom.E0, nom.table, nom.cycle, config)
    sel = _Selector(Scorer(nom.data, base, config.eq_window, nom.floors[0]), config)
    damping = sel.fit(Candidate((("joint_viscous_damping", "joint_2"),)), np.array([0.5]))
    spring = sel.fit(Candidate((("spring_nonlinearity", "joint_2"),)), np.array([-10.0]))
    assert damping.score.score > 0
    naming = Naming((), damping, (), (100.0, 100.0), alternatives=(_Path(spring, (), (100.0, 100.0), (), ()),),
                    fits={})
    refine = pipeline.refine_choice
    bad = {"spring_nonlinearity"}

    def diverging(cand, *args, **kwargs):  # type: ignore[no-untyped-def]
        if any(name in bad for name, _ in cand.parts):
            raise SudsSimulationError("the simulated motion diverged (test)")
        return refine(cand, *args, **kwargs)

    monkeypatch.setattr(pipeline, "refine_choice", diverging)
    fit = _refine(nom, naming, list(located), _Clock())
    assert [(e.name, e.target) for e in fit.effects] == [("joint_viscous_damping", "joint_2")], fit.notes
    assert fit.effects[0].parameters["d"] == pytest.approx(0.5, rel=0.05)
    assert any("spring_nonlinearity:joint_2 left out: the simulated motion diverged (test)" in n
               for n in fit.notes), fit.notes
    bad.clear()
    bad.add("joint_viscous_damping")  # the forward selection's own set cannot be replayed: the note says so
    fit = _refine(nom, naming, list(located), _Clock())
    own = [n for n in fit.notes if n.startswith("the simulator preferred")]
    assert own and own[0].endswith("to the forward selection's joint_viscous_damping:joint_2 (could not be "
                                   "replayed)") and "inf" not in own[0], fit.notes
    bad.add("spring_nonlinearity")  # no set can be replayed
    with pytest.raises(SudsSimulationError, match="diverged"):
        _refine(nom, naming, list(located), _Clock())
