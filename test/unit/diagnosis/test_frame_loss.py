"""Diagnosis of lab recordings that lost many shape or pose samples, single or in bursts.

A lost shape sample hides the drive between its neighbours.  The equation error leaves out the
intervals at a lost sample, and the replay restarts its passive joints from the recorded angles
after each run of lost samples (:attr:`~suds_ros.core.diagnosis.data.Data.anchors`).  Across lost
pose samples the fitted pose is an interpolation: the body velocity's noise gain leaves out the
windows that end there, and the pose noise is measured over evenly spaced samples only.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from suds_ros.core.diagnosis import diagnose
from suds_ros.core.diagnosis.data import prepare
from suds_ros.core.diagnosis.naming import _EqError
from suds_ros.core.diagnosis.replay import replay
from suds_ros.core.physics.effects import EquationTerms, apply_effects
from suds_ros.core.physics.lab import LabConditions, simulate_lab
from suds_ros.core.physics.rft import ChainModel, RFTChain
from suds_ros.core.physics.sim import SimConfig
from suds_ros.core.physics.systems import load_system
from suds_ros.core.recording import Recording


def _lossy(system: str, effects: list[dict[str, Any]], fraction: float, burst: float,
           seed: int = 3, stream: str = "shape") -> tuple[Recording, ChainModel]:
    """A 60-cycle lab recording that lost ``fraction`` of one stream's samples, singly or in bursts of ``burst`` s."""
    base = load_system(system).model
    model, delay = apply_effects(base, effects)
    rec = simulate_lab(RFTChain(model), SimConfig(cycles=60, seed=seed, noise_std=1e-3, pose_delay=delay),
                       LabConditions())
    rng = np.random.default_rng(100 + seed)
    t = rec.t if stream == "shape" else rec.pose_t
    if burst == 0:
        keep = rng.random(t.size) >= fraction
    else:
        keep = np.ones(t.size, bool)
        while 1 - keep.mean() < fraction:
            start = rng.uniform(t[0], t[-1])
            keep &= ~((t >= start) & (t < start + rng.exponential(burst)))
    keep[[0, -1]] = True
    if stream == "pose":
        return replace(rec, pose_t=t[keep], pose=rec.pose[keep], truth={}), base
    return replace(rec, t=t[keep], r=rec.r[keep], truth={}), base


def test_intervals_at_a_lost_shape_sample_are_left_out_of_the_equation_error() -> None:
    rec, base = _lossy("purcell3", [], 0.1, 0.0)
    data = prepare(rec, base)
    assert data.shape_lost is not None and data.shape_lost.sum() > 0.15 * data.t.size
    eq = _EqError(data, base, 0, data.n_train, 10)
    lost = data.shape_lost[: data.n_train]
    np.testing.assert_array_equal(eq.measured, ~(lost[:-1] | lost[1:]))
    e, _ = eq.residuals(EquationTerms.neutral(data.pas.size, base.drag_ratio, base.n_links), np.zeros(1))
    assert np.all(e[~eq.measured] == 0.0) and np.count_nonzero(e[eq.measured]) > 0.9 * eq.measured.sum()
    # a ξ window is measured only if every interval it composes is
    bad = np.concatenate([[0], np.cumsum(~eq.measured)])
    assert not np.any(eq.win_measured & (bad[10:] > bad[:-10]))


def test_the_replay_restarts_the_passive_joints_after_each_run_of_lost_samples() -> None:
    rec, base = _lossy("purcell3", [], 0.3, 0.3)
    data = prepare(rec, base)
    assert data.anchors is not None and data.anchors.size > 10
    assert np.all(data.shape_lost[data.anchors])  # the first sample after a gap is its neighbour
    rep = replay(base, 0.0, data, [0], data.n_train, 10, 2)
    inside = data.anchors[(data.anchors > 0) & (data.anchors < data.n_train)]
    np.testing.assert_array_equal(rep.rp[0, inside], data.r[inside][:, data.pas])
    free = replay(base, 0.0, replace(data, anchors=None), [0], data.n_train, 10, 2)
    assert np.max(np.abs(free.rp[0, inside] - data.r[inside][:, data.pas])) > 5e-3  # bridged, it had drifted


def test_bursts_of_lost_shape_samples_do_not_turn_a_friction_into_damping() -> None:
    """30 % of the shape samples lost in bursts of 0.3 s (once named viscous damping, d 0.18)."""
    rec, base = _lossy("purcell3", [{"name": "joint_coulomb_friction", "joint": "joint_2", "mu": 0.7}], 0.3, 0.3)
    rep = diagnose(rec, base)
    assert [(e.name, e.target) for e in rep.effects] == [("joint_coulomb_friction", "joint_2")]
    mu, se = rep.effects[0].parameters["mu"], rep.effects[0].stderr["mu"]
    assert abs(mu - 0.7) < 0.01 and abs(mu - 0.7) < 4 * se


def test_a_tenth_of_the_shape_samples_lost_singly_leaves_the_friction_unbiased() -> None:
    """10 % single losses: the friction was fitted 0.669 ± 0.009 before the replay restarted at gaps."""
    rec, base = _lossy("purcell3", [{"name": "joint_coulomb_friction", "joint": "joint_2", "mu": 0.7}], 0.1, 0.0)
    rep = diagnose(rec, base)
    assert [(e.name, e.target) for e in rep.effects] == [("joint_coulomb_friction", "joint_2")]
    mu, se = rep.effects[0].parameters["mu"], rep.effects[0].stderr["mu"]
    assert abs(mu - 0.7) < 0.01 and abs(mu - 0.7) < 4 * se


def test_a_nominal_swimmer_losing_a_tenth_of_its_shape_samples_is_tested_and_clean() -> None:
    """Every passive joint stays tested (all were masked before) and nothing is reported."""
    rec, base = _lossy("swimmer9", [], 0.1, 0.0)
    rep = diagnose(rec, base)
    assert not rep.mismatch and not rep.effects
    assert not any(n.startswith("not tested") and "joint_" in n for n in rep.notes)
    assert all(np.isfinite(rep.statistics[f"joint_{j}"]) for j in (5, 6, 7, 8))


@pytest.mark.slow
def test_a_drag_anisotropy_is_named_on_a_swimmer_that_lost_a_tenth_of_its_shape_samples() -> None:
    """Once nothing was tested, and so nothing found."""
    rec, base = _lossy("swimmer9", [{"name": "drag_anisotropy_error", "ratio": 2.5}], 0.1, 0.0)
    rep = diagnose(rec, base)
    assert [e.name for e in rep.effects] == ["drag_anisotropy_error"]
    ratio, se = rep.effects[0].parameters["ratio"], rep.effects[0].stderr["ratio"]
    assert abs(ratio - 2.5) < 0.01 and abs(ratio - 2.5) < 4 * se


def test_the_body_velocity_noise_gain_leaves_out_windows_ending_at_a_pose_gap() -> None:
    from suds_ros.core.resample import gaps, xi_noise_gain

    grid = np.arange(4000) * 0.01
    rng = np.random.default_rng(2)
    keep = np.ones(grid.size, bool)
    for start in rng.integers(0, grid.size - 40, 60):
        keep[start:start + 30] = False  # 30-sample bursts
    keep[[0, -1]] = True
    pose_t = grid[keep]
    gap = gaps(pose_t, grid)
    skip = gap | np.roll(gap, 1) | np.roll(gap, -1)
    measured = xi_noise_gain(pose_t, grid, 10, skip=skip)
    assert measured == pytest.approx(np.sqrt(2.0), rel=0.05)  # white noise at the window ends that are used
    assert xi_noise_gain(pose_t, grid, 10) < 0.9 * measured  # the interpolated stretches averaged in


def test_a_nominal_swimmer_losing_half_its_pose_frames_in_bursts_stays_clean() -> None:
    """Once located on ξ_θ (F 2.2): the noise gain averaged in the interpolated stretches."""
    rec, base = _lossy("swimmer9", [], 0.5, 0.3, stream="pose", seed=3)
    rep = diagnose(rec, base)
    assert not rep.mismatch and not rep.effects
    assert 0.7 < rep.statistics["xi_theta"] < 1.6


def test_a_damping_is_named_when_nearly_half_the_shape_samples_are_lost_with_jittered_stamps() -> None:
    """45 % of the encoder messages lost singly, 1 ms of stamp jitter: the shape grid keeps the encoders' period
    (the median interval is 20 % long there, and the grid counted in it came out 8 % long), every body-velocity
    window touches a gap, so only the passive joint is tested, and a candidate whose equation-error fit makes the
    replay diverge (a softening spring) starts nearer its neutral value instead of stopping the diagnosis."""
    base = load_system("purcell3").model
    effects = [{"name": "joint_viscous_damping", "joint": "joint_2", "d": 0.5}]
    model, _ = apply_effects(base, effects)
    rec = simulate_lab(RFTChain(model), SimConfig(cycles=40, seed=2, noise_std=1e-3),
                       LabConditions(pose_hz=120.0, pose_phase=0.0037, jitter=0.001, drop=0.45))
    assert np.median(np.diff(rec.t)) > 1.15 * 0.01 and rec.dt == pytest.approx(0.01, rel=0.01)
    rep = diagnose(rec, base)
    assert [(e.name, e.target) for e in rep.effects] == [("joint_viscous_damping", "joint_2")]
    d, se = rep.effects[0].parameters["d"], rep.effects[0].stderr["d"]
    assert abs(d - 0.5) < 4 * se + 0.02, (d, se)
    assert rep.ranking and all(np.isfinite(c.score) for c in rep.ranking), [c.score for c in rep.ranking]
