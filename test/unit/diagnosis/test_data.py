"""Preparing a recording for diagnosis (:mod:`suds_ros.core.diagnosis.data`): checks, halves, phase."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from suds_ros.core.diagnosis import diagnose
from suds_ros.core.diagnosis.data import gait_phase, prepare
from suds_ros.core.errors import TOO_LITTLE_DATA, WRONG_JOINT_NAMES, SudsConfigError, SudsDataError
from suds_ros.core.phase.phaser import Phaser
from suds_ros.core.physics.systems import purcell3_model, swimmer9_model


def test_halves_are_whole_cycles(purcell3_run) -> None:  # type: ignore[no-untyped-def]
    data = prepare(purcell3_run, purcell3_model())
    assert data.spc == 100 and data.n_used == 2000 and data.n_train == 1000
    assert data.names == ("joint_1", "joint_2")
    assert list(data.act) == [0] and list(data.pas) == [1]


def test_phase_comes_from_the_phaser(purcell3_run) -> None:  # type: ignore[no-untyped-def]
    data = prepare(purcell3_run, purcell3_model())
    assert data.phase_source == "phaser" and data.phase_note == ""
    np.testing.assert_allclose(data.phase, Phaser().fit_transform(data.r))


def test_clock_phase_when_the_phaser_fails(purcell3_run) -> None:  # type: ignore[no-untyped-def]
    """2.5 gait cycles of motion declared at 2 Hz: five whole cycles for the diagnosis, too few
    detectable cycles for the phaser, so the clock phase 2π·gait_hz·(t − t0) is used, with a note."""
    short = dataclasses.replace(purcell3_run.slice(0, 250), gait_hz=2.0)
    data = prepare(short, purcell3_model())
    assert data.spc == 50 and data.n_used == 250
    assert data.phase_source == "clock"
    assert "phaser failed" in data.phase_note and "2π·2 Hz" in data.phase_note
    np.testing.assert_allclose(data.phase, 2 * np.pi * 2.0 * (short.t - short.t[0]))


def test_gait_phase_falls_back_on_too_few_cycles(purcell3_run) -> None:  # type: ignore[no-untyped-def]
    short = purcell3_run.slice(0, 250)
    phase, source, note = gait_phase(short.r, short.t, 1.0)
    assert source == "clock" and "phaser failed" in note
    np.testing.assert_allclose(phase, 2 * np.pi * (short.t - short.t[0]))


def test_too_short_recording_is_refused(purcell3_run) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(SudsDataError, match="at least 4") as err:
        prepare(purcell3_run.slice(0, 250), purcell3_model())
    assert err.value.code == TOO_LITTLE_DATA
    with pytest.raises(SudsDataError, match="at least 4"):
        diagnose(purcell3_run.slice(0, 250), purcell3_model())


def test_errors_name_the_core_arguments(purcell3_run) -> None:  # type: ignore[no-untyped-def]
    """Core errors name ``rec`` and ``model`` (never command-line flags)."""
    with pytest.raises(SudsDataError, match="`rec`: joints .* `model` 'swimmer9'") as err:
        prepare(purcell3_run, swimmer9_model())
    assert err.value.code == WRONG_JOINT_NAMES and "--" not in str(err.value)
    swapped = dataclasses.replace(purcell3_run, actuated=("joint_2",), passive=("joint_1",))
    with pytest.raises(SudsConfigError, match="`rec`: actuated joints \\['joint_2'\\]") as err2:
        prepare(swapped, purcell3_model())
    assert err2.value.code == WRONG_JOINT_NAMES and "--" not in str(err2.value)
