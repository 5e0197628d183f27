"""core.midline: chain fit to tracked points, its inverse, lost frames, gait frequency, head–tail swaps."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.core.midline import (
    NO_MIDLINE,
    TOO_FEW_POINTS,
    chain_points,
    dominant_frequency,
    fit_chain,
    fit_gait,
    frame_gaps,
    head_tail_swaps,
    link_fractions,
    lost_frames,
    lost_runs,
    max_links,
    resample,
    time_gaps,
    wrap,
)

LENGTHS = np.array([0.14, 0.13, 0.13, 0.13, 0.13, 0.12, 0.11, 0.11])


def wave(n: int = 400, hz: float = 1.3, nj: int = 7) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(n) / 50.0
    r = 0.6 * np.sin(2 * np.pi * hz * t[:, None] - 0.8 * np.arange(nj)) + 0.05
    pose = np.column_stack([0.3 * np.cos(t), 0.2 * np.sin(t), 2.5 * t - 1.0])
    return t, r, pose


def densify(q: np.ndarray, per_link: int) -> np.ndarray:
    """``per_link`` points on each straight link (its head end first), then the tail point."""
    a = np.arange(per_link) / per_link
    parts = [q[:, i:i + 1] + (q[:, i + 1:i + 2] - q[:, i:i + 1]) * a[None, :, None] for i in range(q.shape[1] - 1)]
    return np.concatenate(parts + [q[:, -1:]], axis=1)


def test_fit_inverts_the_forward_kinematics_on_joint_points() -> None:
    t, r, pose = wave()
    for body in (0, 3, 7):
        q = chain_points(r, pose, LENGTHS, body)
        fit = fit_chain(q, 8, body)
        assert fit.body_link == body
        np.testing.assert_allclose(fit.r, r, atol=1e-12)
        np.testing.assert_allclose(fit.pose[:, :2], pose[:, :2], atol=1e-12)
        np.testing.assert_allclose(wrap(fit.pose[:, 2] - pose[:, 2]), 0.0, atol=1e-12)
        np.testing.assert_allclose(fit.lengths, np.broadcast_to(LENGTHS, fit.lengths.shape), atol=1e-12)


def test_dense_midline_resampled_at_the_link_fractions_gives_the_same_chain() -> None:
    t, r, pose = wave()
    q = chain_points(r, pose, LENGTHS, 3)
    fit = fit_chain(densify(q, 5), 8, 3, fractions=LENGTHS * 10)  # any scale: normalised
    np.testing.assert_allclose(fit.r, r, atol=1e-9)
    np.testing.assert_allclose(fit.joints, q, atol=1e-12)
    np.testing.assert_allclose(fit.mean_lengths, LENGTHS, atol=1e-12)


def test_equal_links_by_default_and_the_middle_link_carries_the_pose() -> None:
    t, r, pose = wave(nj=5)
    q = chain_points(r, pose, [0.1] * 6, 2)
    fit = fit_chain(densify(q, 4), 6)
    assert fit.body_link == 2  # ⌈6/2⌉ = 3, 1-based
    np.testing.assert_allclose(fit.r, r, atol=1e-9)
    np.testing.assert_allclose(fit.pose[:, :2], pose[:, :2], atol=1e-12)


def test_fewer_links_than_points_support_fit_a_coarser_chain() -> None:
    t, r, pose = wave(nj=4)
    q = chain_points(r, pose, [0.1] * 5, 2)  # 6 keypoints
    assert max_links(6) == 5
    fit = fit_chain(q, 3)
    assert fit.r.shape == (t.size, 2) and np.all(np.abs(fit.r) <= np.pi)


def test_the_chain_of_the_points_is_the_simulator_chain(worm8_model) -> None:  # type: ignore[no-untyped-def]
    """Link centres relative to the body frame agree with RFTChain's geometry (same convention)."""
    from suds_ros.core.physics.rft import RFTChain

    chain = RFTChain(worm8_model)
    _, r, _ = wave(n=50)
    m = worm8_model.body_link
    q = chain_points(r, np.zeros((r.shape[0], 3)), worm8_model.link_length, m)
    centres = 0.5 * (q[:, :-1] + q[:, 1:])
    alpha = r @ chain._S.T
    np.testing.assert_allclose(centres[..., 0], np.cos(alpha) @ chain._W.T, atol=1e-12)
    np.testing.assert_allclose(centres[..., 1], np.sin(alpha) @ chain._W.T, atol=1e-12)


def test_resample_hits_the_ends_and_midpoints() -> None:
    pts = np.array([[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]])
    out = resample(pts, np.array([0.0, 0.25, 0.5, 1.0]))
    np.testing.assert_allclose(out[0], [[0, 0], [0.5, 0], [1, 0], [1, 1]], atol=1e-15)


def test_fit_errors_name_the_problem() -> None:
    q = chain_points(*wave(n=10, nj=3)[1:], [0.1] * 4, 1)
    with pytest.raises(SudsDataError, match="at least 6 points") as exc:
        fit_chain(q, 5)
    assert exc.value.code == TOO_FEW_POINTS
    with pytest.raises(SudsDataError, match="no frame") as exc:
        fit_chain(q[:0], 4)
    assert exc.value.code == NO_MIDLINE
    flat = q.copy()
    flat[2] = 0.0
    with pytest.raises(SudsDataError, match="frame 2 has a link of zero length") as exc:
        fit_chain(flat, 4)
    assert exc.value.code == NO_MIDLINE
    with pytest.raises(SudsDataError, match="must be dropped"):
        fit_chain(np.where(np.arange(10)[:, None, None] == 4, np.nan, q), 4)
    with pytest.raises(SudsConfigError, match="`fractions`: expected 4 positive"):
        fit_chain(q, 4, fractions=[1, 1, 1])
    with pytest.raises(SudsConfigError, match="`body_link`: expected a link 1..4, got 5"):
        fit_chain(q, 4, body_link=4)
    with pytest.raises(SudsConfigError, match="`n_links`: expected an integer ≥ 2"):
        link_fractions(1)


def test_lost_frames_runs_and_gaps() -> None:
    pts = np.zeros((7, 3, 2))
    pts[1, 0, 0] = np.nan
    pts[2] = np.nan
    pts[6, 2, 1] = np.inf
    mask = lost_frames(pts)
    assert mask.tolist() == [False, True, True, False, False, False, True]
    assert lost_runs(mask) == [(1, 2), (6, 6)]
    assert lost_runs(np.zeros(3, bool)) == []
    assert frame_gaps(np.array([3, 4, 7, 8, 10])) == [(5, 6), (9, 9)]
    assert time_gaps(np.array([0.0, 0.1, 0.2, 0.5, 0.6])) == [(2, 0.2, 0.5)]


def test_dominant_frequency_and_drive_fit() -> None:
    t, r, _ = wave(n=1000, hz=1.3)
    keep = np.ones(t.size, bool)
    keep[100:140] = False  # a gap: interpolated across for the estimate only
    hz = dominant_frequency(t[keep], r[keep])
    assert hz == pytest.approx(1.3, rel=2e-3)
    drive = fit_gait(t, r, 1.3)
    np.testing.assert_allclose(drive[:, 0], 0.6, atol=1e-9)
    np.testing.assert_allclose(wrap(drive[:, 1] - 0.8 * np.arange(7)), 0.0, atol=1e-9)
    np.testing.assert_allclose(drive[:, 2], 0.05, atol=1e-9)
    assert dominant_frequency(t, np.zeros((t.size, 2))) is None
    with pytest.raises(SudsDataError, match="at least 8 frames"):
        dominant_frequency(t[:5], r[:5])


def test_head_tail_swaps_found_by_continuity_and_put_right() -> None:
    """Runs the tracker gave tail first are found against their neighbours, however long (short of half)."""
    t, r, pose = wave()
    q = densify(chain_points(r, pose, LENGTHS, 3), 3)
    truth = np.zeros(t.size, dtype=bool)
    truth[[0, 57]] = True
    truth[100:180] = True  # 80 of 400 frames
    truth[399] = True
    given = np.where(truth[:, None, None], q[:, ::-1], q)
    found = head_tail_swaps(given, t)
    np.testing.assert_array_equal(found.swapped, truth)
    assert found.unlinked == 0 and found.runs.max() == 0
    assert not head_tail_swaps(q, t).swapped.any()
    # the majority decides which end is the head: continuity alone cannot tell a tracker that is
    # mostly wrong, so the few frames it gave the other way round are the ones turned
    mostly = np.where(~truth[:, None, None], q[:, ::-1], q)
    np.testing.assert_array_equal(head_tail_swaps(mostly, t).swapped, truth)


def test_head_tail_swaps_are_not_guessed_where_frames_cannot_be_linked() -> None:
    """Across a long gap, or a jump as large as the body, a stretch keeps the tracker's orientation."""
    t, r, pose = wave()
    q = densify(chain_points(r, pose, LENGTHS, 3), 3)
    given = q.copy()
    given[200:] = given[200:, ::-1]  # the tracker turned round at frame 200 ...
    gap = t.copy()
    gap[200:] += 5.0  # ... after a gap of 5 s: nothing links the two stretches
    found = head_tail_swaps(given, gap)
    assert not found.swapped.any() and found.runs.max() == 1 and found.unlinked == 0
    jump = given.copy()
    jump[200:] += np.array([0.5, 0.0])  # a jump of about the body's length: the two readings alike
    found = head_tail_swaps(jump, t)
    assert not found.swapped.any() and found.runs.max() == 1 and found.unlinked == 1
    # one swapped frame inside each stretch is still found
    jump[50] = jump[50, ::-1]
    jump[300] = jump[300, ::-1]
    np.testing.assert_array_equal(np.flatnonzero(head_tail_swaps(jump, t).swapped), [50, 300])
