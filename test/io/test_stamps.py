"""suds_ros.io.stamps: the one float ↔ ns rule, (sec, nanosec) pairs, quaternion yaw."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from suds_ros.core.errors import BAD_QUATERNION, BAD_STAMP, NAN_OR_INF, SudsDataError
from suds_ros.io.stamps import (
    float_to_ns,
    format_ns,
    join_ns,
    ns_to_float,
    quaternion_yaw,
    split_ns,
    yaw_quaternion,
)


def test_float_to_ns_scalar_and_array_agree() -> None:
    t = 1.7e9 + 0.01 * np.arange(1000) + 1e-4
    ns = float_to_ns(t)
    assert ns.dtype == np.int64
    assert [float_to_ns(float(x)) for x in t] == ns.tolist()
    assert isinstance(float_to_ns(0.1), int)
    assert float_to_ns(0.1) == 100_000_000
    assert float_to_ns(1.7e9 + 0.5) == 1_700_000_000_500_000_000
    assert float_to_ns(-0.25) == -250_000_000


def test_epoch_stamps_round_exactly() -> None:
    """Near 1.7e9 s the sub-second part times 1e9 is exact, so the rule is exact rounding."""
    rng = np.random.default_rng(3)
    t = 1.7e9 + rng.uniform(0, 1e5, 2000)
    exact = [round(Fraction(float(x)) * 10**9) for x in t]
    assert float_to_ns(t).tolist() == exact


def test_roundtrips() -> None:
    t = 1.7e9 + 0.01 * np.arange(200)
    np.testing.assert_array_equal(ns_to_float(float_to_ns(t)), t)
    assert ns_to_float(float_to_ns(1234.5678)) == 1234.5678
    for n in (1_234_567_890_123_456, 4_000_000 * 10**9 + 123_456_789):  # below 2**22 s
        assert float_to_ns(ns_to_float(n)) == n
    ns = np.array([0, 1, 999_999_999, 1_700_000_000_123_456_789], dtype=np.int64)
    np.testing.assert_array_equal(ns_to_float(ns), [ns_to_float(int(x)) for x in ns])


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
def test_non_finite_stamp(bad: float) -> None:
    with pytest.raises(SudsDataError, match="expected finite seconds") as err:
        float_to_ns(bad)
    assert err.value.code == NAN_OR_INF
    with pytest.raises(SudsDataError, match="expected finite seconds"):
        float_to_ns(np.array([1.0, bad]))


def test_split_and_join() -> None:
    assert split_ns(1_700_000_000_990_000_000) == (1_700_000_000, 990_000_000)
    assert split_ns(-1) == (-1, 999_999_999)
    assert join_ns(-1, 999_999_999) == -1
    arr = join_ns([1, 2], [5, 999_999_999])
    assert arr.dtype == np.int64 and arr.tolist() == [1_000_000_005, 2_999_999_999]
    for bad in (1_000_000_000, -1):
        with pytest.raises(SudsDataError, match=r"0 ≤ nanosec < 1e9, got") as err:
            join_ns(3, bad)
        assert err.value.code == BAD_STAMP
        with pytest.raises(SudsDataError, match=r"0 ≤ nanosec < 1e9"):
            join_ns([3, 4], [0, bad])


def test_format_ns() -> None:
    assert format_ns(1_700_000_000_050_000_000) == "1700000000.050000000 s"
    assert format_ns(-1_500_000_000) == "-1.500000000 s"


def test_yaw_from_quaternion() -> None:
    yaw = np.array([0.3, -2.9, 3.1])
    q = np.column_stack([0 * yaw, 0 * yaw, np.sin(yaw / 2), np.cos(yaw / 2)]) * 2.0
    np.testing.assert_allclose(quaternion_yaw(q), yaw)
    # roll about x then yaw: yaw is still recovered
    qx = np.array([np.sin(0.2), 0, 0, np.cos(0.2)])
    qz = np.array([0, 0, np.sin(0.35), np.cos(0.35)])
    x1, y1, z1, w1 = qz
    x2, y2, z2, w2 = qx
    qzx = np.array([w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                    w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2, w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2])
    assert quaternion_yaw(qzx) == pytest.approx(0.7)
    # an array of quaternions marks a zero one NaN; a single one raises
    assert np.isnan(quaternion_yaw(np.zeros((2, 4)))).all()
    with pytest.raises(SudsDataError, match="non-zero finite quaternion") as err:
        quaternion_yaw(np.zeros(4))
    assert err.value.code == BAD_QUATERNION


def test_yaw_quaternion_inverts_quaternion_yaw() -> None:
    yaw = np.linspace(-3.1, 3.1, 41)
    q = yaw_quaternion(yaw)
    assert q.shape == (41, 4)
    np.testing.assert_allclose(quaternion_yaw(q), yaw, atol=1e-12)
    one = yaw_quaternion(0.7)
    assert isinstance(one, tuple) and len(one) == 4
    assert quaternion_yaw(np.array(one)) == pytest.approx(0.7)
    # scalar and array forms give the same bits
    assert yaw_quaternion(float(yaw[5])) == tuple(float(v) for v in q[5])
