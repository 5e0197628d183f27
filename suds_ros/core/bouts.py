"""Bouts of intermittent motion: the steady stretches of a recording (numerics only).

Larval fish swim in bouts of a few tail beats separated by glides and rests; a worm pauses.
Identification needs the steady stretches and must not difference across a pause.  Here a
measure of activity is computed per sample over a centred window of one gait cycle, and a
*bout* is a run of samples whose activity stays at or above a threshold for at least a
minimum number of gait cycles:

* ``speed``: the body frame's displacement across the window divided by the window's
  duration and the body length (body lengths per second);
* ``amplitude``: the largest, over the joints, of √2 × the standard deviation of the joint
  angle in the window (rad; a sinusoid's amplitude).

Bouts are intervals of stamps ``(t_first, t_last)`` (both samples inside the bout), as the
recording metadata lists them (``shared/spec/recording.md``, key ``bouts``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import TOO_LITTLE_DATA, SudsConfigError, SudsDataError

#: activity measures and their units
MEASURES = {"speed": "body lengths/s", "amplitude": "rad"}


@dataclass(frozen=True)
class BoutRule:
    """How bouts are found.

    Parameters
    ----------
    measure : str
        ``"speed"`` (body lengths per second) or ``"amplitude"`` (rad).
    threshold : float
        Activity at or above which a sample belongs to a bout (> 0, in the measure's unit).
    min_cycles : float
        Shortest bout kept, in gait cycles (> 0; default 2).
    window_cycles : float
        Width of the centred activity window, in gait cycles (> 0; default 1).
    """

    measure: str
    threshold: float
    min_cycles: float = 2.0
    window_cycles: float = 1.0

    def __post_init__(self) -> None:
        if self.measure not in MEASURES:
            raise SudsConfigError(f"`measure`: expected one of {', '.join(MEASURES)}, got {self.measure!r}")
        for name in ("threshold", "min_cycles", "window_cycles"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise SudsConfigError(f"`{name}`: expected a number > 0, got {v!r}")

    @classmethod
    def parse(cls, text: str, min_cycles: float = 2.0) -> "BoutRule":
        """``"speed:0.5"`` or ``"amplitude:0.2"`` → a rule (the ``--segment`` syntax)."""
        measure, sep, value = text.partition(":")
        if not sep or measure.strip() not in MEASURES:
            raise SudsConfigError(f"--segment: expected speed:THRESH or amplitude:THRESH, got {text!r}")
        try:
            threshold = float(value)
        except ValueError:
            raise SudsConfigError(f"--segment: expected a number after {measure.strip()}:, got {value!r}") from None
        if not (np.isfinite(threshold) and threshold > 0):
            raise SudsConfigError(f"--segment: expected a threshold > 0, got {value!r}")
        return cls(measure.strip(), threshold, min_cycles)


def _window_bounds(t: FloatArray, half: float) -> tuple[np.ndarray, np.ndarray]:
    """Index ranges [lo, hi) of the samples within ±``half`` s of each sample."""
    lo = np.searchsorted(t, t - half, side="left")
    hi = np.searchsorted(t, t + half, side="right")
    return lo, hi


def windowed_amplitude(t: FloatArray, r: FloatArray, window: float) -> FloatArray:
    """Largest joint amplitude (√2 × windowed standard deviation, rad) per sample, shape (n,).

    Parameters
    ----------
    t : (n,) float
        Stamps, s, increasing.
    r : (n, nj) float
        Joint angles, rad.
    window : float
        Window width, s (centred on each sample).
    """
    t = np.asarray(t, dtype=float)
    r = np.asarray(r, dtype=float).reshape(t.size, -1)
    lo, hi = _window_bounds(t, 0.5 * window)
    c1 = np.vstack([np.zeros(r.shape[1]), np.cumsum(r - r.mean(axis=0), axis=0)])
    c2 = np.vstack([np.zeros(r.shape[1]), np.cumsum((r - r.mean(axis=0)) ** 2, axis=0)])
    n = (hi - lo)[:, None].astype(float)
    mean = (c1[hi] - c1[lo]) / n
    var = np.maximum((c2[hi] - c2[lo]) / n - mean ** 2, 0.0)
    return np.asarray(np.sqrt(2.0 * var).max(axis=1), dtype=float)


def windowed_speed(t: FloatArray, pose: FloatArray, window: float, body_length: float) -> FloatArray:
    """Body speed across a centred window, in body lengths per second, shape (n,).

    The displacement of the body frame's origin between the first and last sample within
    ±window/2 of each sample, over the time between them (a sample whose window holds one
    sample gets speed 0).

    Parameters
    ----------
    t : (n,) float
        Stamps, s, increasing.
    pose : (n, 3) float
        Body pose x (m), y (m), yaw (rad) at ``t``.
    window : float
        Window width, s.
    body_length : float
        Body length, m (> 0).
    """
    if not body_length > 0:
        raise SudsConfigError(f"`body_length`: expected > 0 m, got {body_length!r}")
    t = np.asarray(t, dtype=float)
    pose = np.asarray(pose, dtype=float)
    lo, hi = _window_bounds(t, 0.5 * window)
    a, b = lo, hi - 1
    span = t[b] - t[a]
    dist = np.hypot(pose[b, 0] - pose[a, 0], pose[b, 1] - pose[a, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        v = np.where(span > 0, dist / np.where(span > 0, span, 1.0), 0.0)
    return np.asarray(v / body_length, dtype=float)


def find_bouts(t: FloatArray, active: np.ndarray, min_duration: float) -> list[tuple[float, float]]:
    """Runs of active samples lasting at least ``min_duration`` s, as (t_first, t_last) stamps.

    A run's duration counts its last sample's own interval (the median interval): n samples at
    interval dt last n·dt.
    """
    t = np.asarray(t, dtype=float)
    active = np.asarray(active, dtype=bool)
    if t.size < 2:
        return []
    dt = float(np.median(np.diff(t)))
    edges = np.diff(np.concatenate([[0], active.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    return [(float(t[a]), float(t[b])) for a, b in zip(starts, stops)
            if t[b] - t[a] + dt >= min_duration - 1e-9 * max(1.0, min_duration)]


def segment_bouts(rule: BoutRule, t: FloatArray, r: FloatArray, pose: FloatArray, gait_hz: float,
                  body_length: float) -> tuple[list[tuple[float, float]], FloatArray]:
    """The bouts of a recording under ``rule``, and the activity they were found from.

    Parameters
    ----------
    rule : BoutRule
    t : (n,) float
        Stamps, s.
    r : (n, nj) float
        Joint angles, rad.
    pose : (n, 3) float
        Body pose at ``t``.
    gait_hz : float
        Gait frequency, Hz (sets the window and the minimum bout length).
    body_length : float
        m, for ``speed``.

    Returns
    -------
    bouts : list of (t_first, t_last)
    activity : (n,) float, in the measure's unit.

    Raises
    ------
    SudsDataError
        (code ``too_little_data``) fewer than 2 samples.
    """
    t = np.asarray(t, dtype=float)
    if t.size < 2:
        raise SudsDataError(f"`t`: expected at least 2 samples to find bouts, got {t.size}", code=TOO_LITTLE_DATA)
    if not gait_hz > 0:
        raise SudsConfigError(f"`gait_hz`: expected > 0 Hz, got {gait_hz!r}")
    window = rule.window_cycles / gait_hz
    if rule.measure == "speed":
        activity = windowed_speed(t, pose, window, body_length)
    else:
        activity = windowed_amplitude(t, r, window)
    return find_bouts(t, activity >= rule.threshold, rule.min_cycles / gait_hz), activity


def bouts_text(bouts: tuple[tuple[float, float], ...] | list[tuple[float, float]]) -> str:
    """Bouts as the metadata value: ``t_first:t_last`` pairs (s, repr floats), comma-joined."""
    return ",".join(f"{a!r}:{b!r}" for a, b in bouts)


def parse_bouts(text: str) -> tuple[tuple[float, float], ...]:
    """The metadata value of :func:`bouts_text` → bouts; checked (finite, increasing, disjoint).

    Raises
    ------
    SudsDataError
        A pair that is not two numbers ``a:b`` with a ≤ b, or bouts out of order or overlapping.
    """
    out: list[tuple[float, float]] = []
    for item in (x.strip() for x in text.split(",") if x.strip()):
        a, sep, b = item.partition(":")
        try:
            pair = (float(a), float(b))
        except ValueError:
            pair = (np.nan, np.nan)
        if not sep or not all(np.isfinite(pair)) or pair[0] > pair[1]:
            raise SudsDataError(f"bouts: expected t_first:t_last pairs of seconds (t_first ≤ t_last), got {item!r}")
        if out and pair[0] <= out[-1][1]:
            raise SudsDataError(f"bouts: expected bouts in time order without overlap, got {item!r} after "
                                f"{out[-1][0]!r}:{out[-1][1]!r}")
        out.append(pair)
    return tuple(out)
