"""core.ident.pairing: frames whose shape and pose share a stamp, joined (FrameJoiner)."""

from __future__ import annotations

import math

import numpy as np

from suds_ros.core.ident.pairing import FrameJoiner


def test_frames_join_on_equal_stamps_in_any_arrival_order() -> None:
    j = FrameJoiner(max_wait=1.0)
    j.add_pose(0.0, 0.0, 0.0, 3.1)
    assert j.frames() == []
    j.add_shape(0.0, np.array([1.0]))
    j.add_shape(0.1, np.array([2.0]))
    j.add_pose(0.1, 1.0, 0.0, -3.1)  # across ±π: unwrapped
    got = j.frames()
    assert [t for t, _, _ in got] == [0.0, 0.1] and [float(r[0]) for _, r, _ in got] == [1.0, 2.0]
    np.testing.assert_allclose(got[1][2], [1.0, 0.0, 2 * math.pi - 3.1])
    assert j.waiting == 0 and j.dropped_shapes == j.dropped_poses == 0


def test_a_lost_pose_is_interpolated_a_lost_shape_drops_its_pose_and_a_stall_drops_in_stamp_time() -> None:
    j = FrameJoiner(max_wait=0.25)
    for t in (0.0, 0.1, 0.2, 0.3):
        j.add_shape(t, np.array([t]))
    for t in (0.0, 0.2, 0.25, 0.3):  # the pose of 0.1 lost; a pose at 0.25 without its shape
        j.add_pose(t, 10 * t, 0.0, 0.0)
    got = j.frames()
    assert [t for t, _, _ in got] == [0.0, 0.1, 0.2, 0.3]
    np.testing.assert_allclose(got[1][2], [1.0, 0.0, 0.0])  # between the poses at 0.0 and 0.2
    assert j.dropped_poses == 1 and j.dropped_shapes == 0
    for t in (0.4, 0.5, 0.6):  # the pose stream stops
        j.add_shape(t, np.array([t]))
    assert j.frames() == [] and j.waiting == 3
    j.add_shape(0.7, np.array([0.7]))  # 0.4 is now 0.3 s behind: given up, as the pairer would
    assert j.frames() == [] and j.waiting == 3 and j.dropped_shapes == 1
    early = FrameJoiner(max_wait=1.0)
    early.add_shape(0.0, np.array([0.0]))
    early.add_pose(0.05, 0.0, 0.0, 0.0)
    assert early.frames() == [] and early.dropped_shapes == 1  # before the first pose: never covered
