"""`Recording.pose_at`: interpolation inside the pose stream's span, a clear refusal outside it.

The tolerance is absolute (1 µs), so it is as tight on epoch stamps (~1.7e9 s) as near 0.
"""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.errors import NO_POSE, SudsDataError
from suds_ros.core.recording import POSE_SPAN_TOL, Recording


def recording(t0: float) -> Recording:
    """Shape at 100 Hz, pose at 120 Hz starting 3.7 ms later, body moving at 0.5 m/s along x."""
    rng = np.random.default_rng(0)
    t = t0 + np.arange(200) * 0.01
    pose_t = t0 + 0.0037 + np.arange(230) / 120.0
    pose = np.column_stack([0.5 * (pose_t - t0), 0.1 * np.sin(pose_t - t0), 0.2 * (pose_t - t0)])
    return Recording(t=t, r=rng.normal(size=(t.size, 2)), joint_names=("a", "b"), actuated=("a",),
                     passive=("b",), pose_t=pose_t, pose=pose)


@pytest.mark.parametrize("t0", [0.0, 1.7e9])
def test_inside_the_span_interpolates(t0: float) -> None:
    rec = recording(t0)
    s = rec.pose_t[0] + np.array([0.0, 0.004, 0.5, 1.0])
    got = rec.pose_at(s)
    np.testing.assert_allclose(got[:, 0], 0.5 * (s - t0), atol=1e-6)  # x is linear in t: exact
    np.testing.assert_allclose(got[:, 2], 0.2 * (s - t0), atol=1e-6)
    # the ends themselves and stamps within the tolerance give the end poses
    ends = rec.pose_at(np.array([rec.pose_t[0] - 0.5 * POSE_SPAN_TOL, rec.pose_t[-1] + 0.5 * POSE_SPAN_TOL]))
    np.testing.assert_allclose(ends, rec.pose[[0, -1]], atol=1e-6)


@pytest.mark.parametrize("t0", [0.0, 1.7e9])
@pytest.mark.parametrize("side", ["before", "after"])
def test_outside_the_span_is_refused(t0: float, side: str) -> None:
    rec = recording(t0)
    # 1e-5 s outside: within the old relative tolerance (1e-9 × 1.7e9 s = 1.7 s) on epoch stamps
    s = rec.pose_t[0] - 1e-5 if side == "before" else rec.pose_t[-1] + 1e-5
    with pytest.raises(SudsDataError, match=r"`t`: expected stamps within the pose stream's span") as exc:
        rec.pose_at(np.array([rec.pose_t[5], s]))
    assert exc.value.code == NO_POSE
    assert "got 1 of 2 outside it" in str(exc.value)
    # the shape stream starts 3.7 ms before the pose stream: its first stamp has no pose
    with pytest.raises(SudsDataError) as exc:
        rec.pose_at(rec.t)
    assert exc.value.code == NO_POSE


def test_too_few_pose_samples_is_refused() -> None:
    rec = recording(1.7e9)
    from dataclasses import replace

    one = replace(rec, pose_t=rec.pose_t[:1], pose=rec.pose[:1])
    with pytest.raises(SudsDataError, match="`pose_t`: expected at least 2 pose samples, got 1") as exc:
        one.pose_at(rec.pose_t[:1])
    assert exc.value.code == NO_POSE


def test_intervals_outside_the_pose_span_have_no_body_velocity() -> None:
    from suds_ros.core.ident.intervals import make_intervals

    rec = recording(1.7e9)  # the first shape stamp is 3.7 ms before the first pose
    iv = make_intervals(rec)
    late = rec.t[1:] > rec.pose_t[-1]
    early = rec.t[:-1] < rec.pose_t[0]
    assert early.sum() == 1 and late.sum() > 0
    assert np.isnan(iv.xi[early | late]).all() and np.isfinite(iv.xi[~(early | late)]).all()
    ok = ~(early | late)
    speed = np.hypot(0.5, 0.1 * np.cos(iv.t[ok] - 1.7e9))  # world speed of the pose
    np.testing.assert_allclose(np.hypot(iv.xi[ok, 0], iv.xi[ok, 1]), speed, rtol=1e-2)
    assert np.isfinite(iv.rdot).all()
