"""core/bouts: activity measures, bout runs, the metadata text, and the rule's checks."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.bouts import (
    BoutRule,
    bouts_text,
    find_bouts,
    parse_bouts,
    segment_bouts,
    windowed_amplitude,
    windowed_speed,
)
from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.core.recording import Recording


def bout_signal() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """2 Hz oscillation (0.4 rad) and forward motion in 3 bouts at 100 Hz, still in between."""
    t = np.arange(0, 12, 0.01)
    on = ((t >= 1) & (t < 3)) | ((t >= 5) & (t < 8)) | ((t >= 10) & (t < 10.6))
    r = np.where(on, 0.4 * np.sin(2 * np.pi * 2 * t), 0.0)[:, None] * np.array([1.0, -0.5])
    x = np.cumsum(np.where(on, 0.05, 0.0) * 0.01)  # 0.05 m/s while swimming
    pose = np.column_stack([x, np.zeros_like(t), np.zeros_like(t)])
    return t, r, pose


def test_windowed_amplitude_of_a_sinusoid_is_its_amplitude() -> None:
    t, r, _ = bout_signal()
    a = windowed_amplitude(t, r, 0.5)
    assert a[(t > 1.5) & (t < 2.5)] == pytest.approx(0.4, abs=0.02)
    assert np.all(a[(t > 3.3) & (t < 4.7)] < 1e-6)  # cumulative sums: round-off only


def test_windowed_speed_in_body_lengths_per_second() -> None:
    t, _, pose = bout_signal()
    v = windowed_speed(t, pose, 0.5, body_length=0.01)
    assert v[(t > 1.5) & (t < 2.5)] == pytest.approx(5.0, rel=0.03)
    assert np.all(v[(t > 3.3) & (t < 4.7)] == 0.0)
    with pytest.raises(SudsConfigError, match="body_length"):
        windowed_speed(t, pose, 0.5, body_length=0.0)


@pytest.mark.parametrize("measure, threshold", [("amplitude", 0.2), ("speed", 2.5)])
def test_segment_finds_the_bouts_and_drops_the_short_one(measure: str, threshold: float) -> None:
    t, r, pose = bout_signal()
    bouts, activity = segment_bouts(BoutRule(measure, threshold, min_cycles=2), t, r, pose, 2.0, 0.01)
    assert activity.shape == t.shape
    assert len(bouts) == 2  # the 0.6 s run (1.2 cycles) is shorter than 2 cycles
    for (a, b), (a0, b0) in zip(bouts, [(1.0, 2.99), (5.0, 7.99)]):
        assert a == pytest.approx(a0, abs=0.15) and b == pytest.approx(b0, abs=0.15)


def test_find_bouts_counts_the_last_samples_period() -> None:
    t = np.arange(10) * 0.1
    active = np.array([0, 1, 1, 1, 1, 0, 1, 1, 0, 0], bool)
    assert find_bouts(t, active, 0.4) == [(0.1, pytest.approx(0.4))]
    assert len(find_bouts(t, active, 0.2)) == 2


def test_bouts_text_round_trip_and_bad_text() -> None:
    bouts = ((1.0, 2.5), (1700000000.125, 1700000003.5))
    assert parse_bouts(bouts_text(bouts)) == bouts
    with pytest.raises(SudsDataError, match="t_first:t_last"):
        parse_bouts("1:x")
    with pytest.raises(SudsDataError, match="t_first ≤ t_last"):
        parse_bouts("3:2")
    with pytest.raises(SudsDataError, match="without overlap, got '2:4' after 1.0:3.0"):
        parse_bouts("1:3,2:4")


def test_rule_parse_and_checks() -> None:
    assert BoutRule.parse("speed:0.5") == BoutRule("speed", 0.5, 2.0)
    assert BoutRule.parse("amplitude:0.2", 3) == BoutRule("amplitude", 0.2, 3)
    for text, match in [("speed", "expected speed:THRESH or amplitude:THRESH, got 'speed'"),
                        ("tail:1", "got 'tail:1'"), ("speed:fast", "number after speed:, got 'fast'"),
                        ("amplitude:-1", "threshold > 0, got '-1'")]:
        with pytest.raises(SudsConfigError, match=match):
            BoutRule.parse(text)
    with pytest.raises(SudsConfigError, match="`min_cycles`: expected a number > 0, got 0"):
        BoutRule("speed", 1.0, min_cycles=0)


def test_recording_checks_its_bouts() -> None:
    t = np.arange(5.0)
    kw = dict(t=t, r=np.zeros((5, 1)), joint_names=("joint_1",), actuated=("joint_1",), passive=(),
              pose_t=t, pose=np.zeros((5, 3)))
    assert Recording(**kw, bouts=[(0, 1), (2, 3)]).bouts == ((0.0, 1.0), (2.0, 3.0))
    with pytest.raises(SudsDataError, match="without overlap"):
        Recording(**kw, bouts=[(0, 2), (2, 3)])
