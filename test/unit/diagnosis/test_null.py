"""Null recordings (:mod:`suds_ros.core.diagnosis.null`) and the calibration of the selection on them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from suds_ros.core import se2
from suds_ros.core.diagnosis import DiagnoseConfig, rank_effects
from suds_ros.core.diagnosis.data import prepare, xi_noise_gain
from suds_ros.core.diagnosis.floor import noise_floor
from suds_ros.core.diagnosis.null import null_recording, pose_sigma, stitched_pose
from suds_ros.core.diagnosis.replay import piece_starts, replay_recording
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import load_system, purcell3_model

TAIL6 = Path(__file__).resolve().parents[2] / "data" / "robots" / "tail6.yaml"


def test_stitched_pose_undoes_the_restarts_of_a_piecewise_replay(purcell3_run) -> None:  # type: ignore[no-untyped-def]
    """A pose path cut into pieces, each moved rigidly (as a replay piece restarted from another
    pose), is put back together: the steps inside the pieces are kept, the step into each piece is
    the recording's, so with the recording equal to the path the stitched pose is the path."""
    data = prepare(purcell3_run, purcell3_model())
    n = data.n_used
    path = data.pose[:n].copy()
    starts = np.array([0, 130, 400, n // 2, n - 77])
    moved = path.copy()
    rng = np.random.default_rng(2)
    for a, b in zip(starts, list(starts[1:]) + [n]):
        dx, dy, dth = rng.normal(size=3)
        c, s = np.cos(dth), np.sin(dth)
        p = path[a:b]
        moved[a:b, 0] = c * p[:, 0] - s * p[:, 1] + dx
        moved[a:b, 1] = s * p[:, 0] + c * p[:, 1] + dy
        moved[a:b, 2] = p[:, 2] + dth
    moved[: starts[1]] = path[: starts[1]]  # the first piece starts at the recorded pose
    got = stitched_pose(data, moved, starts)
    np.testing.assert_allclose(got, path, atol=1e-9)
    steps = se2.relative(got[:-1], got[1:])
    np.testing.assert_allclose(steps, se2.relative(path[:-1], path[1:]), atol=1e-9)


def test_pose_sigma_inverts_the_body_velocity_floor() -> None:
    """σ_pose from the ξ floors: gain·σ/(w·dt) gives the floors back."""
    sxy, sth = pose_sigma((np.zeros(1), 0.02, 0.05), w=10, dt=0.01, gain=np.sqrt(2.0))
    assert np.sqrt(2.0) * sxy / (10 * 0.01) == pytest.approx(0.02)
    assert np.sqrt(2.0) * sth / (10 * 0.01) == pytest.approx(0.05)


def test_null_of_the_true_model_looks_like_the_recording() -> None:
    """The null of the physics that made a recording has the recording's noise floors (within
    25 %) and its passive angles stay within a few floors of the recorded ones."""
    model = purcell3_model()
    rec = simulate(RFTChain(model), SimConfig(cycles=12, seed=8, noise_std=2e-3))
    data = prepare(rec, model)
    cfg = DiagnoseConfig()
    w = int(round(cfg.window / data.dt))
    chunk, warm = int(cfg.replay_chunk * data.spc), int(round(cfg.replay_warm / data.dt))
    rep = replay_recording(data, model, 0.0, w, 4, None, chunk, warm)
    gain = xi_noise_gain(data, w)
    floors = noise_floor(*rep.floor_arrays, w, data.dt, gain)
    null = null_recording(data, rep, piece_starts(data, w, chunk, warm), floors, w, np.random.default_rng(1))
    rep0 = replay_recording(null, model, 0.0, w, 4, None, chunk, warm)
    again = noise_floor(*rep0.floor_arrays, w, data.dt, gain)
    np.testing.assert_allclose(again[0], floors[0], rtol=0.25)
    assert again[1] == pytest.approx(floors[1], rel=0.25) and again[2] == pytest.approx(floors[2], rel=0.25)
    n = data.n_used
    err = null.r[:n, data.pas] - data.r[:n, data.pas]
    assert np.sqrt(np.mean(err**2)) < 3 * float(floors[0][0])
    np.testing.assert_array_equal(null.r[:, data.act], data.r[:, data.act])  # the recorded drive


@pytest.mark.slow
def test_a_model_file_robots_offset_is_named_alone_with_or_without_calibration() -> None:
    """tail6 with a spring rest offset on j4 (40 cycles): calibrated on this recording's null, or not,
    only the offset is named.

    Uncalibrated, the selection once added a link-drag error on the tail link that passed the
    60-nat threshold on its own.  That bias came from the torque residuals' noise growing with the
    drag, and went with their weighing by their sensitivity to the joint-angle noise.
    """
    base = load_system(str(TAIL6)).model
    model, _ = apply_effects(base, [dict(name="spring_rest_offset", joint="j4", offset=0.15)])
    rec = simulate(RFTChain(model), SimConfig(cycles=40, seed=3))
    raw, _ = rank_effects(rec, base, DiagnoseConfig(calibrate=False, arbitrate_max=0))
    cal, _ = rank_effects(rec, base, DiagnoseConfig(arbitrate_max=0))
    assert raw.chosen.cand.label == "spring_rest_offset:j4", raw.steps
    assert cal.chosen.cand.label == "spring_rest_offset:j4", cal.steps
