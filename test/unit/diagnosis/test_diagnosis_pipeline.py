"""The pipeline's own mechanisms (:mod:`suds_ros.core.diagnosis.pipeline`), each exercised directly."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.diagnosis import DiagnoseConfig
from suds_ros.core.diagnosis.data import prepare
from suds_ros.core.diagnosis.locate import locate_channels
from suds_ros.core.diagnosis.naming import Candidate, Scorer
from suds_ros.core.diagnosis.pipeline import _Clock, _refine, replay_nominal
from suds_ros.core.diagnosis.selection import Naming, _Path, _Selector
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import purcell3_model


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
