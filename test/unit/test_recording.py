"""The recording's own helpers (:mod:`suds_ros.core.recording`): a stream's sampling period."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.errors import SudsDataError
from suds_ros.core.recording import stream_period


def test_the_stream_period_is_the_unbroken_intervals_median_however_many_messages_are_lost() -> None:
    """The median interval drifts up as messages are lost (across a loss it is two periods or more);
    the period of the intervals between messages received in a row does not."""
    rng = np.random.default_rng(0)
    n, period = 3000, 0.01
    t = period * np.arange(n) + rng.normal(0.0, 0.001, n)  # 1 ms of stamp jitter, as on a busy machine
    assert stream_period(t) == pytest.approx(period, rel=0.01)
    for lost in (0.3, 0.45, 0.6):
        keep = rng.random(n) >= lost
        ts = t[keep]
        assert stream_period(ts) == pytest.approx(period, rel=0.02), lost
        if lost >= 0.45:
            assert np.median(np.diff(ts)) > 1.1 * period  # what the median would have said
    assert stream_period(period * np.arange(5)) == pytest.approx(period)  # no jitter: exactly
    with pytest.raises(SudsDataError, match="at least 2 distinct stamps") as exc:
        stream_period(np.array([1.0, 1.0]))
    assert exc.value.code == "too_little_data"
