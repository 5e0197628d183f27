"""Diagnosis against a robot model file (``suds-robot/1``): per-link lengths and drag, a body link
that is not the middle one, a pose-frame offset; through the core and through ``suds diagnose --model``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from suds_ros.core.diagnosis import diagnose, diagnose_recording
from suds_ros.core.diagnosis.data import prepare
from suds_ros.core.errors import SudsConfigError
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.rft import ChainModel, RFTChain
from suds_ros.core.physics.robot_model import load_model
from suds_ros.core.physics.sim import SimConfig, simulate

SHARED = Path(__file__).resolve().parents[4] / "shared"

EEL4 = """\
format: suds-robot/1
name: eel4
gait_hz: 1.0
drag: {c_par: 1.0, c_perp: 2.2}
links:
  - {length: 0.9}
  - {length: 1.1, c_par: 1.2}
  - {length: 1.0}
  - {length: 0.8, c_perp: 2.8}
body: {link: 4, offset: [0.25, -0.1, 0.3]}
joints:
  - {name: neck, actuated: true, gait: {amplitude: 1.2, phase: 0.0}}
  - {name: waist, actuated: true, gait: {amplitude: 1.0, phase: 0.9}}
  - {name: tail, stiffness: 3.0}
"""


@pytest.fixture(scope="module")
def eel4(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, ChainModel]:
    path = tmp_path_factory.mktemp("robots") / "eel4.yaml"
    path.write_text(EEL4)
    model = load_model(path)
    assert model.body_link == 3 and model.pose_offset == (0.25, -0.1, 0.3)
    return path, model


def _record(  # type: ignore[no-untyped-def]
    model: ChainModel, effects: list[dict[str, object]], cycles: int, seed: int,
):
    m, delay = apply_effects(model, effects)
    return simulate(RFTChain(m), SimConfig(cycles=cycles, seed=seed, pose_delay=delay))


def test_prepare_uses_the_model_files_joint_names(eel4) -> None:  # type: ignore[no-untyped-def]
    _, model = eel4
    data = prepare(_record(model, [], 4, 1), model)
    assert data.names == ("neck", "waist", "tail") and list(data.pas) == [2]


def test_diagnose_recording_takes_a_model_or_a_model_file(eel4) -> None:  # type: ignore[no-untyped-def]
    path, model = eel4
    rec = _record(model, [], 8, 2)
    with pytest.raises(SudsConfigError, match="`system`"):
        diagnose_recording(rec, system="purcell3", model=model)
    a = diagnose_recording(rec, model=model)
    b = diagnose_recording(rec, system=str(path))
    assert a.system == b.system == "eel4"
    assert a.statistics == pytest.approx(b.statistics)


@pytest.mark.slow
def test_offset_frame_nominal_is_clean_and_damping_is_named(  # type: ignore[no-untyped-def]
    eel4, check_recovered,
) -> None:
    _, model = eel4
    null = diagnose(_record(model, [], 20, 5), model)
    assert null.mismatch is False, null.statistics
    assert all(f < 1.6 for f in null.statistics.values()), null.statistics
    effects = [dict(name="joint_viscous_damping", joint="tail", d=0.3)]
    check_recovered(diagnose(_record(model, effects, 20, 6), model), effects)


@pytest.mark.slow
def test_cli_diagnoses_the_public_snake5_lab_bag(capsys: pytest.CaptureFixture[str]) -> None:
    from suds_ros.cli.main import main

    bag, robot = SHARED / "bags" / "snake5_lab_damping.mcap", SHARED / "robots" / "snake5.yaml"
    if not bag.exists() or not robot.exists():
        pytest.skip("public snake5 files not present")
    assert main(["diagnose", "--model", str(robot), "--json", str(bag)]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["mismatch"] is True and d["unexplained"] is False
    [eff] = d["effects"]
    assert (eff["name"], eff["target"]) == ("joint_viscous_damping", "joint_4")
    assert eff["parameters"]["d"] == pytest.approx(0.6, rel=0.25)
    assert np.isfinite(eff["stderr"]["d"])
