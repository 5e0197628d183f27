"""Diagnosis of asynchronous recordings (shape and pose streams with their own stamps, jitter, drops).

Lab-condition recordings come from :func:`~suds_ros.core.physics.lab.simulate_lab`, each beside its
aligned twin (:func:`~suds_ros.core.physics.sim.simulate`, same physics and seed).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from suds_ros.core.diagnosis import diagnose
from suds_ros.core.diagnosis.data import prepare, xi_noise_gain
from suds_ros.core.resample import Grid, StreamSampling, gaps, knot_fit
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.lab import LabConditions, simulate_lab
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import purcell3_model, swimmer9_model
from suds_ros.core.recording import Recording

BAGS = Path(__file__).resolve().parents[4] / "shared" / "bags"


def _lab(effects: list[dict[str, Any]], cycles: int, seed: int, lab: LabConditions = LabConditions(),
         aligned: bool = False) -> Recording:
    model, delay = apply_effects(purcell3_model(), effects)
    cfg = SimConfig(cycles=cycles, seed=seed, pose_delay=delay)
    return simulate(RFTChain(model), cfg) if aligned else simulate_lab(RFTChain(model), cfg, lab)


# ------------------------------------------------------------------------------ grid
def test_aligned_recording_keeps_its_own_stamps() -> None:
    rec = _lab([], 4, 1, aligned=True)
    grid = Grid.of(rec)
    assert grid.resampled is False
    assert np.array_equal(grid.t, rec.t) and np.array_equal(grid.shape(rec), rec.r)
    data = prepare(rec, purcell3_model())
    assert data.n_used == 400 and not data.shape_gap.any() and not data.pose_gap.any()
    assert xi_noise_gain(data, 10) == pytest.approx(np.sqrt(2.0))


def test_knot_fit_recovers_a_piecewise_linear_drive_from_jittered_samples() -> None:
    rng = np.random.default_rng(3)
    dt = 0.01
    grid = 5.0 + dt * np.arange(400)
    knots = np.cumsum(rng.normal(0.0, 0.07, grid.size))  # kinks at every grid point (an OU-like drive)
    ts = grid + np.clip(rng.normal(0.0, 4e-4, grid.size), -0.004, 0.004)
    keep = rng.random(grid.size) > 0.02
    keep[[0, -1]] = True
    ts = ts[keep]
    y = np.interp(ts, grid, knots)[:, None]
    fit = knot_fit(ts, y, grid)[:, 0]
    gap = gaps(ts, grid)
    assert gap.sum() == (~keep).sum()
    ok = ~gap
    ok[[0, -1]] = False  # the end knots are pinned from one side only
    ok[1:] &= ~gap[:-1]
    ok[:-1] &= ~gap[1:]
    assert np.max(np.abs(fit[ok] - knots[ok])) < 1e-4  # exact up to the ridge
    plain = np.interp(grid, ts, y[:, 0])
    assert np.max(np.abs(plain[ok] - knots[ok])) > 100 * np.max(np.abs(fit[ok] - knots[ok]))


def test_xi_noise_gain_is_sqrt2_for_white_noise_on_the_grid() -> None:
    grid = np.arange(3000) * 0.01
    assert xi_noise_gain_of(grid, grid) == pytest.approx(np.sqrt(2.0), rel=0.05)
    # a 120 Hz stream fitted onto the 100 Hz grid: correlated noise, another gain
    pose_t = 0.0037 + np.arange(3590) / 120.0
    assert abs(xi_noise_gain_of(pose_t, grid) - np.sqrt(2.0)) > 0.1


def xi_noise_gain_of(pose_t: np.ndarray, grid: np.ndarray) -> float:
    from suds_ros.core.resample import xi_noise_gain

    return xi_noise_gain(pose_t, grid, 10)


def test_a_slower_stream_has_gaps_only_where_a_sample_is_missing() -> None:
    """A 50 Hz pose stream on the 100 Hz grid: the grid points between its samples are not gaps;
    those around a dropped sample are."""
    grid = np.arange(1000) * 0.01
    ts = 0.0037 + np.arange(499) * 0.02
    inside = (grid >= ts[0]) & (grid <= ts[-1])
    assert not gaps(ts, grid)[inside].any()
    g = gaps(np.delete(ts, 200), grid) & inside
    assert g.any() and np.all(np.abs(grid[g] - ts[200]) < 0.02)


def test_stream_sampling_is_the_knot_fit_of_the_signal_read_at_the_stamps() -> None:
    rng = np.random.default_rng(2)
    grid = 3.0 + np.arange(600) * 0.01
    ts = 3.0037 + np.arange(299) * 0.02 + rng.normal(0.0, 4e-4, 299)
    ts = np.delete(ts, [40, 41, 150])
    Y = np.cumsum(rng.normal(0.0, 0.05, (2, 600, 3)), axis=1)
    starts = [0, 200]
    out = StreamSampling(ts, grid).apply(Y[:, :400], starts)
    for b, s0 in enumerate(starts):
        T = grid[s0:s0 + 400]
        s = ts[(ts >= T[0]) & (ts <= T[-1])]
        at = np.stack([np.interp(s, T, Y[b, :400, c]) for c in range(3)], axis=1)
        want = knot_fit(s, at, T)
        ok = np.isfinite(out[b, :, 0])
        assert ok.sum() >= 395  # only the ends past the first / last sample are left out
        np.testing.assert_allclose(out[b][ok], want[ok], atol=1e-12)


def test_nominal_replay_is_at_the_floor_with_a_50hz_pose_stream() -> None:
    """A 50 Hz pose loses the kinks of the motion between its samples; the replay, seen through
    the same stream, loses the same ones: every channel is tested and at its floor, with drops."""
    from suds_ros.core.diagnosis import DiagnoseConfig
    from suds_ros.core.diagnosis.pipeline import replay_nominal

    model = purcell3_model()
    rec = simulate_lab(RFTChain(model), SimConfig(cycles=12, seed=6), LabConditions(pose_hz=50.0, drop=0.01))
    nom = replay_nominal(prepare(rec, model), model, DiagnoseConfig(), None)
    assert set(nom.F0) == {"joint_2", "xi_x", "xi_y", "xi_theta"}
    assert all(np.isfinite(v) and 0.6 < v < 1.4 for v in nom.F0.values()), nom.F0
    sxy = nom.floors[1] * nom.w * nom.data.dt / xi_noise_gain(nom.data, nom.w)
    assert sxy == pytest.approx(1e-3, rel=0.15)  # the pose noise, measured at the pose stamps


def test_lab_recording_is_laid_out_by_time_not_by_sample_count() -> None:
    rec = _lab([], 6, 5)
    assert rec.n_samples != 600 and rec.pose_t.size != rec.n_samples  # drops, 120 Hz pose
    data = prepare(rec, purcell3_model())
    assert data.resampled and data.spc == 100
    assert data.n_used == 600 and data.n_train == 300  # 6 cycles of time, whatever was dropped
    assert data.dt == pytest.approx(0.01, rel=1e-4)
    true_r = np.stack([np.interp(data.t, rec.t, rec.truth["r"][:, j]) for j in range(2)], axis=1)
    good = ~data.shape_gap
    assert np.sqrt(np.mean((data.r[good] - true_r[good]) ** 2)) < 5e-3


# ------------------------------------------------------------------------------ end to end
def test_lab_null_runs_and_stays_clean() -> None:
    rep = diagnose(_lab([], 12, 4), purcell3_model())
    assert rep.mismatch is False, rep.statistics
    assert rep.train_cycles == 6 and rep.heldout_cycles == 6


@pytest.mark.slow
@pytest.mark.parametrize("effects", [
    [dict(name="joint_viscous_damping", joint="joint_2", d=0.3)],
    [dict(name="background_flow", vx=0.1, vy=-0.05)],
    [dict(name="sensor_time_offset", dt=0.017)],
], ids=lambda e: e[0]["name"])
def test_lab_recording_names_the_twins_effect(  # type: ignore[no-untyped-def]
    effects: list[dict[str, Any]], check_recovered,
) -> None:
    twin = diagnose(_lab(effects, 20, 21, aligned=True), purcell3_model())
    lab = diagnose(_lab(effects, 20, 21), purcell3_model())
    check_recovered(twin, effects)
    check_recovered(lab, effects)
    for a, b in zip(twin.effects, lab.effects):
        assert (a.name, a.target) == (b.name, b.target)
        for p, v in a.parameters.items():
            assert b.parameters[p] == pytest.approx(v, rel=0.25, abs=0.005)


@pytest.mark.slow
def test_lab_with_a_50hz_pose_stream_and_half_hz_gait_stays_clean() -> None:
    model = purcell3_model()
    cfg = SimConfig(cycles=8, seed=9, gait_hz=0.5, noise_std=3e-3)
    rec = simulate_lab(RFTChain(model), cfg, LabConditions(pose_hz=50.0))
    rep = diagnose(rec, model)
    assert rep.mismatch is False, rep.statistics


@pytest.mark.slow
def test_a_current_is_named_through_a_50hz_pose_stream(check_recovered) -> None:  # type: ignore[no-untyped-def]
    effects = [dict(name="background_flow", vx=0.05, vy=0.0)]
    rep = diagnose(_lab(effects, 30, 5, LabConditions(pose_hz=50.0)), purcell3_model())
    check_recovered(rep, effects)


@pytest.mark.slow
def test_public_purcell3_lab_nominal_is_clean() -> None:
    from suds_ros.io.recording_bag import read_recording

    bag = BAGS / "purcell3_lab_nominal.mcap"
    if not bag.exists():
        pytest.skip(f"{bag} not present")
    rep = diagnose(read_recording(bag), purcell3_model())
    assert rep.mismatch is False, rep.statistics
    assert rep.train_cycles + rep.heldout_cycles == 60


def _video(effects: list[dict[str, Any]], seed: int) -> tuple[Recording, Recording]:
    """swimmer9, 40 cycles: the simulator's values, and the same with both streams stamped alike 2 ms off the ticks."""
    from dataclasses import replace

    model = swimmer9_model()
    sim = RFTChain(apply_effects(model, effects)[0]) if effects else RFTChain(model)
    rec = replace(simulate(sim, SimConfig(cycles=40, seed=seed)), system="swimmer9")
    jitter = np.clip(np.random.default_rng(seed).normal(0.0, 0.002, rec.t.size), -0.4 * rec.dt, 0.4 * rec.dt)
    return rec, replace(rec, t=rec.t + jitter, pose_t=rec.t + jitter, truth={})


def test_a_video_like_recording_is_diagnosed_as_on_its_ticks() -> None:
    """Shape and pose of one frame stamped alike, 2 ms off the camera's tick (read as stamped late).

    Both are timed at the ticks (``Grid.pose_stamps``), so the body channels' floors are those of
    the jitter-free stamps (before: 8× higher, from the poses' stamp errors, while the residuals had
    the pose a stamp error off the shape: a nominal swimmer9 read F 3.3 on the body channels, and a
    drag anisotropy was called unexplained) and the nominal robot reads clean.
    """
    model = swimmer9_model()
    clean, video = _video([], 1)
    assert Grid.of(video).snapped
    a, b = diagnose(clean, model), diagnose(video, model)
    assert b.mismatch is False, b.statistics
    for ch in ("xi_x", "xi_y", "xi_theta"):
        assert b.noise_floor[ch] == pytest.approx(a.noise_floor[ch], rel=0.1)
        assert b.heldout_rms_before[ch] == pytest.approx(a.heldout_rms_before[ch], rel=0.1)


def test_a_drag_anisotropy_is_named_through_video_like_stamps() -> None:
    effects = [dict(name="drag_anisotropy_error", ratio=2.2)]
    rep = diagnose(_video(effects, 1)[1], swimmer9_model())
    assert rep.mismatch and not rep.unexplained
    assert [e.name for e in rep.effects] == ["drag_anisotropy_error"]
    assert rep.effects[0].parameters["ratio"] == pytest.approx(2.2, abs=0.01)
