"""Live mismatch monitor: is the robot still the simulator?  No ROS; the ``monitor`` node adapts it.

Residual (prediction error of the nominal physics, interval by interval)
------------------------------------------------------------------------
Paired samples k (shape r_k incl. passive joints, pose g_k at the shape stamp) give intervals
k → k+1.  On each interval the nominal physics is replayed (:class:`IntervalPhysics`): integrated
(RK4 and the Lie-group pose step, :func:`~suds_ros.core.physics.integrate.integrate_batch`) from
the measured passive angles at k, under the measured drive (the actuated joints on straight lines
between their samples, bent where the servo set-points bend: :func:`drive_kinks`).  The replay's
mean rates over the interval are the prediction.  Over a sliding window of ``diff_window`` samples
(enough to beat the differencing noise) the monitor compares, per channel,

* passive joint j: the measured mean rate (r_j[k+w] − r_j[k]) / T with the time average of the
  predicted ṙ_j (rad/s);
* ``xi_x``, ``xi_y``, ``xi_theta``: the measured body velocity log(g_k⁻¹ g_{k+w}) / T with the
  composition of the predicted interval motions (the same SE(2) estimator on both sides).

Nothing is learnt from the robot: no baseline from its first cycles
-------------------------------------------------------------------
A cheaper prediction, the physics at each interval's midpoint shape, misses the motion inside an
interval wherever the passive joints are stiff (swimmer9 relaxes at ~135 1/s, 1.35 per 10 ms
sample) by far more than the sensor noise; a monitor built on it has to learn that error from the
robot's first cycles, and a robot wrong from its first sample then looks nominal.  The replay has
no such error (≈ 1e-3 of the midpoint rule's on swimmer9), so the statistic is right from the
first report on, whatever the robot did before.  Each interval is replayed once, when the sample
after its end has arrived (that sample gives the slope at a bend near the end; with stamp jitter
``REPLAY_AHEAD`` samples, see *Lab streams*).

Lab streams
-----------
* The drive bends at its set-point times, the points of the uniform grid the shape stamps scatter
  about; with stamp jitter a bend falls inside an interval, and the replay bends there too
  (:func:`drive_kinks`).  A passive joint that follows its drive within a sample (swimmer9) reads
  any error in that drive as a misfit, so three things are taken care of (measured on noise-free
  nominal swimmer9 runs read late with 2 ms of jitter, the replay's own error per interval, against
  ≈ 0.14 rad/s of sensor noise: 0.11–0.19 rad/s as until 2026-12-06, 0.003–0.005 with all three):

  - where the grid lies: the shape clock's line (:class:`~suds_ros.core.resample.LiveGrid`, below)
    counts the stamps once and keeps its count, and each sample keeps the grid point it had when
    the clock released it (:meth:`~suds_ros.core.resample.LiveGrid.grid_point`).  A line refitted
    to the history at every update now and then took another count with 3 ms of jitter and put
    every bend up to 9 ms off; and samples released while that count is unconfirmed are held, as
    below, and then given their grid points on the line as it stands once a recount confirms it
    (through them: the lock block's own line and the first blocks' jumps put bends off by up to
    700 µs at 3 ms, F 5.1 on a nominal swimmer9);
  - the angle at a bend, the least-squares linear spline of the samples with its knots on the grid
    (:func:`drive_kinks`): a knot at the fit's edge is held by the ridge more than by the data, so
    the fit takes ``REPLAY_BEHIND`` samples before each batch of intervals and each interval is
    replayed only when ``REPLAY_AHEAD`` samples after its end are at hand (one, as before: 0.03–0.05
    rad/s with the true grid; an interval now and then 15 times the noise, a nominal swimmer9 in ERROR).
    An edge knot's error passes to the next knot damped by up to 0.4/0.6 (samples up to 0.4 periods
    off their grid points): with three a nominal swimmer9 at 3 ms still read F 4.6 on one seed of 12,
    with six 2.4;
  - the grid's own error: its place is known to ≈ 2σ/√n (120 µs at 2 ms of jitter over 1000
    samples; :attr:`~suds_ros.core.resample.LiveGrid.offset_se`), so the data is also replayed on
    the grid ``GRID_SHIFT`` later, and the misfit of one offset within ``TIME_BASE_SIGMAS`` standard
    errors is taken out of each statistic (:meth:`MismatchMonitor._time_base`).
* Stamped late, not read late: a device sampling on its own clock whose messages the host stamps as
  they arrive puts the jitter in the stamps alone (:func:`~suds_ros.core.resample.values_on_grid`).
  Timed at its stamps such a stream misleads the replay (each interval as long as two delays make it,
  a bend where there is none): a nominal swimmer9 went to ERROR on its passive joints at 2 ms.  So the
  shape samples first pass the estimator's grid stage (:class:`~suds_ros.core.resample.LiveGrid`,
  ``raw_values``): a uniform stream at once; a jittered one after its lock block (256 samples or more)
  and then a few grid points late, unchanged while read late, and at their grid points from when the
  stage judges the stream stamped late (:attr:`MismatchMonitor.stamped_late`).  The pose is read at
  those times.  :meth:`MismatchMonitor.flush` passes on what the stage holds at a stream's end.
  Such a time base is itself an estimate, and the statistics allow for it:

  - each sample so timed is its own set-point (the drive bends at it); a straight line refitted to
    those times, whose line moved as stamps came in, put bends some µs off the samples and split
    the intervals there (swimmer9's passive joints read it as a misfit, F 5–7 at 1 ms of jitter);
  - the stage releases them on a slewed clock (no interval off by the line's moves, which reached
    90 µs at block boundaries);
  - samples released while the stage's count came from a phase lock that no recount has yet
    confirmed (:attr:`~suds_ros.core.resample.LiveGrid.confirmed`; heavy jitter) are held until a
    recount agrees and left out (:attr:`MonitorRecord.unconfirmed`) if one replaces the count
    (:attr:`~suds_ros.core.resample.LiveGrid.counts`): a lock one count off slips a step every few
    hundred samples, and a nominal swimmer9 read F 6–7 on its body channels at 3 ms.  Until
    2026-12-06 (late) they were all left out, and at 3 ms the first report came 10.6 s in, not 3 s;
  - the line's place is known to its standard error (:attr:`~suds_ros.core.resample.LiveGrid.offset_se`,
    ≈ 2σ/√n, 70 µs at 1 ms of jitter over the last 8 of 12 cycles), and swimmer9's body channels see a lag of
    20 µs: the phase-coherent statistic first takes out what a time base off by up to
    ``TIME_BASE_SIGMAS`` of those errors can leave (:func:`time_base_misfit`: a lag and a stretch
    of the clock, within bounds), and the windowed statistic one offset of the shape stream against
    the pose stream within the same bound (:meth:`MismatchMonitor._time_base`): the line's error
    wanders with the stamps, and one nominal swimmer9 at 2 ms had its time base 560 µs off (3.4
    standard errors) for a second, body F 4.2 without that.  A real lag beyond that still scores,
    smaller by the allowance.
* A pose stream of its own rate is read at a shape stamp by linear interpolation between the pose
  samples around it, plus the replay's own departure from that straight line (the body velocity
  jumps at every bend of the drive, so the line cuts corners; :meth:`MismatchMonitor._read_poses`).
  A sample's pose is final once the replay reaches the next pose sample.
* A lost message: windows across an interval whose grid points lie more than ``gap`` sample
  periods apart (or next to one),
  or ending on a pose read across a lost pose or shape sample, are not scored.  A statistic needs
  ``min_scored`` of its span's windows clean; with fewer it takes the newest clean windows of the
  kept history, and with too few even there (or no noise floor measured yet: ``FLOOR_LEAST``
  fourth differences) the channel is STALE, the diagnostic_msgs level for "no current data".
  With 20 % of each stream lost a ten-interval window is clean about one time in fifteen, and
  before this rule a nominal robot went to ERROR on two or three windows
  (``docs/results/monitor_loss.md``).

Noise floor (from the data's high-frequency content, shaped by the model)
------------------------------------------------------------------------
The raw signals cannot give it directly (the actuated drive is rough: its servo set-points carry a
random perturbation whose fourth differences dwarf the sensor noise), but the one-interval
residual can: were its noise a first difference of white noise m_k, the accumulated residual
S_k = Σ e1_i Δt_i would be m_k plus whatever the model misses — smooth, or kinked at a few
stick-slip samples — and its fourth difference would keep only m: σ_m² from the mean square of
Δ⁴S/√70 (clipped at 4 robust standard deviations), a window of span T carrying the noise power
2σ_m²/T² (:func:`noise_power`).

The model shapes the noise otherwise: a stiff passive joint forgets part of each measurement within
one interval, so its window collects noise from every sample inside it, not only from the two ends;
a joint's noise reaches its neighbours' channels through the coupling; a pose interpolated between
pose samples is smoother than measured.  The monitor measures these gains on the model, along the
recorded trajectory: for each signal group (:func:`noise_groups`: the actuated joints, each passive
joint, the pose) a twin of the data carries a synthetic white noise (fixed seed, 1e-6 rad or m,
interpolated onto the shape stamps as the pose is) through the same replays and pose reading.  The
groups' noise levels are fitted to the measured floors of all channels, and a channel's floor is
κ · 2σ_m²/T² with κ its fitted window power over its fitted high-frequency power
(:func:`fitted_gain`; ≈ 1 wherever the first-difference picture holds).  The floor is renewed every
``FLOOR_EVERY`` updates over the last ``floor_cycles`` cycles.  It is never below
``FLOOR_RELATIVE`` (1e-4) of each channel's predicted rms, squared, nor is the noise the
phase-coherent statistic compares against: with noise-free data the measured floor is round-off
while the replay's own error is not, and a nominal purcell3 read F ≈ 25 000.  Measured limit: on
swimmer9's stiff passive joints the replay's own error repeats with the gait, and with sensor
noise of 1e-5 rad or less (1e-4 is fine) the phase-coherent statistic still flags a nominal run.

Statistic and levels
--------------------
Every ``update_every`` samples, once ``floor_cycles`` cycles are at hand (the first report), per
channel F = mean(residual²) / floor over the last ``window_cycles`` gait cycles (≈ 1 when the
nominal physics holds; a systematic error adds its power on top).  A misfit that repeats with the
gait but is small next to one cycle's noise (a pose stream a few ms late) is seen better over
several cycles: from ``MIN_COHERENT`` whole cycles on, the channel's F is the larger of that and
the phase-coherent score over the last ``coherent_cycles`` cycles (:func:`coherent_statistic`:
the residual's power at the first ``harmonics`` gait harmonics against the power between them,
scored by its tail probability under noise: WARN at 1e-5, ERROR at 1e-6 per update).  The body
channels take at least the score of one misfit of known shape over them all: a pose stream τ late
on the shape stream leaves −τ times the derivative of the predicted body velocity, so τ is fitted
to every body channel and harmonic at once and scored the same way (:func:`lag_statistic`, one
degree of freedom: a lag far too small for any one channel's statistic; :attr:`MonitorRecord.lag`
keeps it at its largest score, and ``suds monitor`` says the lag when that score passes WARN and the lag
explains most of the body channels' misfit).
Level OK (F ≤ ``warn``), WARN
(``warn`` < F ≤ ``error``), ERROR (F > ``error``), STALE (too little clean data to test the
channel, see *Lab streams*; ranked between OK and WARN for the worst level reached, never a
warning and never the end of an ERROR episode), ``since`` = the stamp at which the channel
entered its level.  :attr:`MismatchMonitor.record` keeps, per channel, the worst level, the stamps
of the first WARN (or worse) and of the first ERROR, and the largest F (``suds monitor`` prints
them).  Nominal runs stay below ERROR and robots wrong from the first sample reach it at the first
report: ``docs/results/monitor.md`` (``benchmarks/monitor_delay.py``),
``test/unit/diagnosis/test_monitor.py``.

Diagnosis
---------
When some channel has been in ERROR for ``persist_cycles`` gait cycles the monitor hands out a
:class:`DiagnosisRequest`: the last ``persist_cycles`` whole cycles (all inside the ERROR
episode, so after the change) as a :class:`~suds_ros.core.recording.Recording`.  One request per
episode; the episode ends when every channel is back to OK.  :class:`DiagnosisWorker` runs
:func:`~suds_ros.core.diagnosis.pipeline.diagnose` in a separate process so the caller keeps up
with the stream.

Offline
-------
:func:`monitor_recording` feeds a recording's two streams, in stamp order, through the same
:meth:`MismatchMonitor.on_shape` / :meth:`MismatchMonitor.on_pose` the node calls, and returns
the :class:`MonitorRecord` (``suds monitor``).
"""

from __future__ import annotations

import heapq
import math
import multiprocessing
from collections import deque
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from suds_ros.core import json_text
from suds_ros.core import se2
from suds_ros.core._typing import BoolArray, ComplexArray, FloatArray, IntArray
from suds_ros.core.config import check_settings, setting
from suds_ros.core.diagnosis.report import BODY, DiagnoseConfig
from suds_ros.core.errors import TOO_LITTLE_DATA, SudsConfigError, SudsDataError
from suds_ros.core.ident.model import joint_order
from suds_ros.core.physics.integrate import integrate_batch
from suds_ros.core.physics.rft import ChainModel, flow_in_body
from suds_ros.core.physics.sim import _still, auto_substeps, passive_rate
from suds_ros.core.physics.system import SudsSystem
from suds_ros.core.recording import Recording, samples_per_cycle
from suds_ros.core.resample import LIVE_LOCK_MAX, LiveGrid, fit_grid, knots_around

OK, WARN, ERROR, STALE = 0, 1, 2, 3
LEVEL_NAMES = ("OK", "WARN", "ERROR", "STALE")  # diagnostic_msgs' own levels
#: how bad each level is, for the worst one reached: a channel that could not be checked (STALE) is worse
#: than OK and better than WARN
SEVERITY = (0, 2, 3, 1)


def worse(a: int, b: int) -> int:
    """The worse of two levels (:data:`SEVERITY`)."""
    return a if SEVERITY[a] >= SEVERITY[b] else b


#: std of the synthetic noise that measures the noise gain (rad or m; small: the response stays linear)
SYNTHETIC_NOISE = 1e-6
#: RK4 steps of the interval replays: h·λ_max ≤ this (λ the fastest passive relaxation; ≈1e-4 of the
#: passive motion in one interval, far below the sensor noise)
REPLAY_ACCURACY = 0.5
#: an interval whose passive relaxation is this many times the fastest over random shapes is not scored
STIFF = 2.0
#: most RK4 steps per straight piece of the drive in one interval replay
MAX_STEPS = 64
#: samples after an interval's end at hand before it is replayed, and samples before its start the drive's knot
#: fit also takes (:func:`drive_kinks`): a knot next to the fit's edge is held by one sample on one side
#: only, and with stamp jitter it is the fit's ridge, not the data, that places it
REPLAY_AHEAD = 6
REPLAY_BEHIND = 6
#: most shape samples held while the shape clock's count awaits a recount's confirmation (the lock block, up
#: to LIVE_LOCK_MAX, and the samples to the first recount after it); older ones are left out
HELD_MAX = 2 * LIVE_LOCK_MAX
#: s: the data is also replayed with its set-point grid moved this much later, for the statistic's
#: sensitivity to where the grid fitted to jittered stamps lies (:meth:`MismatchMonitor._time_base`)
GRID_SHIFT = 5e-5
#: statistics updates between two renewals of the noise floor (it spans ``floor_cycles``: it changes slowly)
FLOOR_EVERY = 5
#: fewest fourth differences (four clean intervals in a row) a noise floor is measured from; with fewer (many
#: lost messages) the floor before stands, or, before the first, the channels are STALE
FLOOR_LEAST = 50
#: weight of the pull of the fitted noise levels toward one common level (relative to one channel's fit)
LEVEL_PRIOR = 1e-2
#: the floor's fourth differences are clipped at this many robust standard deviations before their mean square
CLIP = 4.0
#: E[min(z², CLIP²)] for a standard normal z: the clipped mean square of Gaussian noise is this times its variance
CLIP_MEAN = float(1.0 - math.erfc(CLIP / math.sqrt(2.0)) * (1.0 - CLIP**2)
                  - 2.0 * CLIP * math.exp(-CLIP**2 / 2.0) / math.sqrt(2.0 * math.pi))
#: seed of the synthetic noise (one stream per monitor: the statistics are reproducible)
SYNTHETIC_SEED = 0
#: the noise floor is at least this share of each channel's predicted rms, squared: the replay's own error
#: (a few 1e-6 of the signal on purcell3) is smooth and escapes the fourth differences, so with noise-free
#: data the floor fell to round-off and a nominal robot read F ≈ 25 000 (measurements with any noise, 1e-6
#: rad or more, have a floor far above this)
FLOOR_RELATIVE = 1e-4
#: fewest whole gait cycles of the phase-coherent statistic (with fewer, its few noise bins make false alarms)
MIN_COHERENT = 4
#: the phase-coherent statistic's score: 0 down to this tail probability under noise, then SCORE_PER_DECADE per
#: decade below it (with the default levels WARN at a 1e-5 tail, ERROR at 1e-6)
SCORE_ZERO = 1e-4
SCORE_PER_DECADE = 4.0
#: a pose lag is named (``suds monitor``) only when its fit explains at least this share of the body channels'
#: weighted misfit at the gait harmonics (:func:`lag_statistic`; friction or damping lean the same way, partly)
LAG_SHARE = 0.5
#: on a shape stream timed at its grid points (stamped late), the time base may sit this many of its standard
#: errors (:attr:`~suds_ros.core.resample.LiveGrid.offset_se`) off the device's ticks before its misfit counts
TIME_BASE_SIGMAS = 4.0


@dataclass(frozen=True)
class MonitorConfig:
    """Settings of :class:`MismatchMonitor` (rates and windows in samples or gait cycles).

    Parameters
    ----------
    gait_hz : float
        Gait frequency, Hz (cycles are counted with it).
    rate : float
        Nominal sample rate of the shape stream, Hz; ``rate / gait_hz`` samples per cycle.
    diff_window : int
        Samples per residual window (the velocity differences span this many intervals).
    window_cycles : float
        Gait cycles over which the mean-square residual is taken.
    floor_cycles : float
        Gait cycles of data whose residuals give the noise floor and its gain; the first report
        comes once they are at hand.
    warn, error : float
        Thresholds on F = mean-square residual / noise floor (error > warn > 1).
    gap : float
        An interval between paired samples whose set-point grid points (the grid fitted to the
        shape stamps) lie more than this many nominal sample periods apart is a gap (a lost
        sample): the windows across it are not scored.  On the grid, not on the stamps: with 3 ms
        of stamp jitter on a 100 Hz stream one interval in eight is longer than 1.5 periods with
        nothing lost (``docs/results/monitor_jitter.md``).
    persist_cycles : int
        Cycles a channel must stay in ERROR before the recent window is diagnosed (≥ 4:
        the diagnosis trains on half of it and scores on the other half).
    history_cycles : float
        Cycles of paired samples kept (≥ ``persist_cycles`` and the statistic's windows).
    update_every : int
        Paired samples between two updates of the statistics.
    coherent_cycles : int
        Whole gait cycles (at most) of the phase-coherent statistic (:func:`coherent_statistic`;
        taken from ``MIN_COHERENT`` cycles of data on; 0: off).
    harmonics : int
        Gait harmonics the phase-coherent statistic tests.
    min_scored : float
        Share of the ``window_cycles`` span's windows that must be clean for a statistic.  With
        fewer (lost messages) the statistic takes the newest clean windows of the whole history,
        as many as that share of the span holds; when even the history has too few, or no noise
        floor could be measured yet, the channel is STALE (it cannot be tested, so it is not
        called OK).
    """

    gait_hz: float = setting(1.0, "gait frequency, Hz", gt=0.0, le=1000.0)
    rate: float = setting(100.0, "sample rate of the shape stream, Hz (rate / gait_hz samples per cycle)",
                          gt=0.0, le=100000.0)
    diff_window: int = setting(10, "samples per residual window", ge=1, le=10000)
    window_cycles: float = setting(1.0, "gait cycles of the mean-square residual", gt=0.0, le=100.0)
    floor_cycles: float = setting(3.0, "gait cycles of data for the noise floor (the first report comes "
                                       "after them)", gt=0.0, le=100.0)
    warn: float = setting(4.0, "WARN when F = mean-square residual / floor exceeds this", gt=1.0, le=1e9)
    error: float = setting(8.0, "ERROR when F exceeds this (> warn)", gt=1.0, le=1e9)
    gap: float = setting(1.5, "intervals whose grid points lie more than this many sample periods apart are gaps "
                              "(lost samples): windows across them are not scored", gt=1.0, le=1000.0)
    persist_cycles: int = setting(6, "cycles in ERROR before the recent window is diagnosed (≥ 4)", ge=4)
    history_cycles: float = setting(12.0, "cycles of samples kept", ge=1.0, le=10000.0)
    update_every: int = setting(10, "samples between statistics updates (and suds/mismatch messages)",
                                ge=1, le=100000)
    coherent_cycles: int = setting(8, "whole gait cycles of the phase-coherent statistic (0: off)", ge=0, le=1000)
    min_scored: float = setting(0.5, "share of the statistic's windows that must be clean (no lost message in or "
                                     "next to them); with fewer it reaches back into the history, else STALE",
                                gt=0.0, le=1.0)
    harmonics: int = setting(2, "gait harmonics the phase-coherent statistic tests", ge=1, le=100)

    def __post_init__(self) -> None:
        check_settings(self)
        if not self.error > self.warn:
            raise SudsConfigError(f"`error`: expected a threshold > warn ({self.warn}), got {self.error!r}")
        if not self.history_cycles >= max(self.persist_cycles, self.window_cycles, self.floor_cycles,
                                          self.coherent_cycles):
            raise SudsConfigError(f"`history_cycles`: expected ≥ persist_cycles, window_cycles, floor_cycles and "
                                  f"coherent_cycles ({self.persist_cycles}, {self.window_cycles}, "
                                  f"{self.floor_cycles}, {self.coherent_cycles}), got {self.history_cycles!r}")
        spc = self.rate / self.gait_hz
        if abs(spc - round(spc)) > 1e-9 * spc or round(spc) < 8:
            raise SudsConfigError(f"`rate`: rate / gait_hz must be an integer ≥ 8 (samples per cycle), "
                                  f"got {self.rate!r} / {self.gait_hz!r} = {spc:.6g}")

    @property
    def samples_per_cycle(self) -> int:
        """Samples per gait cycle."""
        return samples_per_cycle(1.0 / self.rate, self.gait_hz)

    @property
    def first_report_samples(self) -> int:
        """Paired samples before the first statistics (the floor's cycles, at least one statistic window)."""
        spc = self.samples_per_cycle
        return max(int(round(self.window_cycles * spc)) + self.diff_window, int(round(self.floor_cycles * spc)))


class ChannelStatus(NamedTuple):
    """The state of one channel: level (0 OK, 1 WARN, 2 ERROR, 3 STALE), F, since when (stamp, s), why STALE."""

    channel: str
    level: int
    statistic: float
    since: float
    note: str = ""

    @property
    def level_name(self) -> str:
        return LEVEL_NAMES[self.level]


@dataclass(frozen=True)
class DiagnosisRequest:
    """A recent window to diagnose: the recording, the channels in ERROR and since when."""

    recording: Recording
    channels: tuple[str, ...]
    since: float


@dataclass(frozen=True)
class ChannelRecord:
    """What one channel went through: worst level, first stamps at WARN (or above) and at ERROR, largest F.

    Stamps in s (the recording's clock), None when never reached; ``stale`` the reports at STALE
    (too little clean data to test the channel, :data:`SEVERITY` ranks it between OK and WARN).
    """

    channel: str
    worst: int = OK
    first_warn: float | None = None
    first_error: float | None = None
    max_statistic: float = 0.0
    stale: int = 0

    @property
    def worst_name(self) -> str:
        return LEVEL_NAMES[self.worst]

    def seen(self, status: ChannelStatus, stamp: float) -> ChannelRecord:
        """This record updated with one status reported at ``stamp``."""
        warn = self.first_warn if self.first_warn is not None or status.level not in (WARN, ERROR) else stamp
        error = self.first_error if self.first_error is not None or status.level != ERROR else stamp
        f = status.statistic if math.isfinite(status.statistic) else 0.0
        return ChannelRecord(self.channel, worse(self.worst, status.level), warn, error,
                             max(self.max_statistic, f), self.stale + (status.level == STALE))


@dataclass(frozen=True)
class MonitorRecord:
    """What the monitor reported over a run: per channel :class:`ChannelRecord`, the first and last report.

    ``first_report`` / ``last_report``: stamps (s) of the first and last statistics update, None
    before the first.  ``updates``: how many there were.  ``lag``: the :func:`lag_statistic` at its
    largest score so far (None before the first).  ``stamped_late``: the stamp of the first shape
    sample the monitor timed at its grid point (its grid stage judged the stream stamped late; None:
    never), ``unconfirmed``: shape samples left out while the stage's count was unconfirmed (heavy jitter).
    """

    channels: tuple[ChannelRecord, ...]
    first_report: float | None = None
    last_report: float | None = None
    updates: int = 0
    lag: Lag | None = None
    stamped_late: float | None = None
    unconfirmed: int = 0

    @property
    def worst(self) -> int:
        """Worst level any channel reached (:data:`SEVERITY`; OK before the first report)."""
        out = OK
        for c in self.channels:
            out = worse(out, c.worst)
        return out

    def to_dict(self, origin: float = 0.0) -> dict[str, Any]:
        """JSON-ready: ``{"worst", "channels": {name: {"worst", "first_warn_s", "first_error_s", "stale_reports"}}}``.

        Stamps become seconds after ``origin`` (e.g. the recording's first stamp); None (JSON null)
        when never reached.
        """
        def rel(x: float | None) -> float | None:
            return None if x is None else float(x - origin)

        return {"worst": LEVEL_NAMES[self.worst],
                "channels": {c.channel: {"worst": c.worst_name, "first_warn_s": rel(c.first_warn),
                                         "first_error_s": rel(c.first_error), "stale_reports": c.stale}
                             for c in self.channels}}


# ------------------------------------------------------------------ prediction
def channel_names(system: SudsSystem) -> tuple[str, ...]:
    """Monitored channels: the passive joints, then the body velocity (x only for 1-D swimmers)."""
    body = BODY if getattr(system, "planar", True) else BODY[:1]
    return tuple(system.joint_names[j] for j in system.passive) + body


class Kinks(NamedTuple):
    """Where a piecewise-linear drive bends inside B sample intervals (times from each interval's start).

    ``ta`` ≤ ``tb`` (B,) s; ``ka``, ``kb`` (B, na) the actuated angles there.  An interval without
    a bend near its start has ``ta`` = 0 and ``ka`` = its first sample; likewise ``tb`` = its
    length and ``kb`` = its last sample.
    """

    ta: FloatArray
    ka: FloatArray
    tb: FloatArray
    kb: FloatArray


def drive_kinks(t: FloatArray, ra: FloatArray, grid: FloatArray, period: float) -> Kinks:
    """The bends of the drive inside the intervals of t[1:-2] → t[2:-1] (the outer samples give slopes).

    A servo set-point stream bends at its set-point times: the points ``grid`` (n,) of the
    uniform grid the shape stamps scatter about (the monitor: the shape clock's,
    :meth:`MismatchMonitor._grid`), one next to each stamp of ``t`` (n,).  Sampled with jitter, a
    stamp t_j sits ε_j = t_j − g_j off its grid point, so one interval can hold the bend of either
    end.  The angle at each bend is the
    value of the least-squares linear spline of the samples with its knots at the grid points
    (:func:`~suds_ros.core.resample.knots_around`, as the batch identifier reads a jittered stream):
    the drive is exactly such a spline.  (Until 2026-12-05 it was the sample's own angle moved
    along the chord to its neighbour, which cuts the neighbour's bend too: with 2–3 ms of jitter
    at 100 Hz that missed the drive by 1.5–2× the sensor noise, and a nominal swimmer9's stiff
    passive joints went to WARN or ERROR; ``docs/results/monitor_jitter.md``.)  Bends within
    1e-3 ``period`` of a sample are not split off.  ``ra`` (n, na) the actuated angles.
    """
    idx = np.round((grid - grid[0]) / period).astype(int)  # each sample's grid point, counted from the first
    # the knots on the straight line through all the grid points (they may come from a clock whose line moved
    # between them, or, at a stream's start, from a stamp: one point off by 1 ms put every knot 1 ms off)
    step, first = np.polyfit(idx, grid, 1) if idx[-1] > 0 else (period, grid[0])
    knot = knots_around(t, ra, 0, idx[-1], float(first), float(step))[idx[1:-1]]  # samples 1 … n − 2
    return bends(t, ra, grid, period, knot)


def bends(t: FloatArray, ra: FloatArray, grid: FloatArray, period: float, knot: FloatArray) -> Kinks:
    """The :class:`Kinks` of the intervals t[1:-2] → t[2:-1] (:func:`drive_kinks`).

    ``knot`` (n − 2, na): the drive's angle at the grid points of samples 1 … n − 2.
    """
    eps = t - grid
    tol = 1e-3 * period
    e0, e1 = eps[1:-2], eps[2:-1]  # each interval's start and end sample
    t0 = t[1:-2]
    start = e0 < -tol  # the start sample's grid point lies inside, after it
    end = e1 > tol  # the end sample's grid point lies inside, before it
    ta = np.where(start, -e0, 0.0)
    tb = np.where(end, grid[2:-1] - t0, t[2:-1] - t0)
    tb = np.maximum(tb, ta)
    ka = np.where(start[:, None], knot[:-1], ra[1:-2])
    kb = np.where(end[:, None], knot[1:], ra[2:-1])
    return Kinks(ta, ka, tb, kb)


def lost_samples(t: FloatArray, grid: FloatArray, gap: float) -> BoolArray:
    """Intervals of the stamps ``t`` (n,) holding a lost sample: their grid points ``grid`` more than ``gap`` s apart.

    Counted on the grid fitted to the stamps, not on the stamps: with stamp jitter an interval can
    be long with nothing lost (3 ms of jitter at 100 Hz: one in eight longer than 1.5 periods).
    """
    return np.diff(grid) > gap


def _piecewise(s: FloatArray, times: FloatArray, values: FloatArray) -> FloatArray:
    """Row-wise linear interpolation at ``s`` (B, M) of the polylines through ``times`` (B, K, rising), ``values``.

    ``values`` (B, K, d); returns (B, M, d).
    """
    K = times.shape[1]
    seg = np.clip((s[:, :, None] >= times[:, None, 1:-1]).sum(axis=2), 0, K - 2)  # (B, M)
    t0 = np.take_along_axis(times, seg, axis=1)
    t1 = np.take_along_axis(times, seg + 1, axis=1)
    v0 = np.take_along_axis(values, seg[:, :, None], axis=1)
    v1 = np.take_along_axis(values, seg[:, :, None] + 1, axis=1)
    span = t1 - t0
    frac = np.where(span > 0, (s - t0) / np.where(span > 0, span, 1.0), 0.0)
    return v0 + frac[:, :, None] * (v1 - v0)


class IntervalPhysics:
    """The nominal physics replayed over sample intervals: the mean body velocity and passive rates on each.

    ``dt`` (s) is the nominal sample interval (it sets the RK4 steps of the replays, from the
    system's fastest passive relaxation: :func:`~suds_ros.core.physics.sim.auto_substeps` at
    ``REPLAY_ACCURACY``).  A nominal background flow is added to the still-fluid replay as
    R(−yaw)·U at the interval's middle heading.  See the module docstring.
    """

    def __init__(self, system: SudsSystem, dt: float) -> None:
        self.system = system
        self.still, self.flow = _still(system)
        self.act = np.asarray(system.actuated, dtype=np.intp)
        self.pas = np.asarray(system.passive, dtype=np.intp)
        self.dt = float(dt)
        self.substeps = auto_substeps(system, dt, accuracy=REPLAY_ACCURACY)
        self.rate = passive_rate(system)  # the fastest relaxation over random shapes, 1/s

    def stiffness(self, r0: FloatArray, r1: FloatArray) -> FloatArray:
        """The fastest passive relaxation of each of B intervals, 1/s (0 without passive joints).

        The largest |eigenvalue| of ∂ṙ_p/∂r_p (finite differences, actuated joints at rest) at
        the interval's two end shapes ``r0``, ``r1`` (B, nj), as :func:`auto_substeps` takes it
        at random shapes.
        """
        pas = self.pas
        B = r0.shape[0]
        if pas.size == 0:
            return np.zeros(B)
        r = np.concatenate([r0, r1])
        h = 1e-6
        probes = np.repeat(r[None], pas.size + 1, axis=0)  # (np + 1, 2B, nj)
        probes[np.arange(1, pas.size + 1), :, pas] += h
        zero = np.zeros((probes.shape[0] * r.shape[0], self.act.size))
        _, rp = self.still.velocities(probes.reshape(-1, r.shape[1]), zero)
        rp = rp.reshape(pas.size + 1, r.shape[0], pas.size)
        jac = np.moveaxis((rp[1:] - rp[:1]) / h, 0, 2)  # (2B, row i, column j)
        ok = np.all(np.isfinite(jac), axis=(1, 2))
        lam = np.full(r.shape[0], np.inf)
        lam[ok] = np.abs(np.linalg.eigvals(jac[ok])).max(axis=1)
        return np.maximum(lam[:B], lam[B:])

    def between(self, dt: FloatArray, r0: FloatArray, r1: FloatArray, yaw: FloatArray,
                kinks: Kinks | None = None, outputs: FloatArray | None = None, lam: FloatArray | None = None
                ) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray]:
        """Body velocity (B, 3) and passive rates (B, np) on B intervals, the motion at ``outputs``, stiff ones.

        ``dt`` (B,) interval lengths, s; ``r0``, ``r1`` (B, nj) the shapes at their ends;
        ``yaw`` (B,) the heading at their middles (used only by a nominal background flow);
        ``kinks``: where the drive bends inside each interval (:func:`drive_kinks`; none: the
        actuated joints move on the straight line between the two samples).  ``outputs`` (B, M):
        times inside the intervals (s from their starts; NaN: none) at which the replayed pose is
        wanted; returned as (B, M, 3), relative to the pose at the interval's start (NaN where
        none).  The rates are the replay's mean rates over each interval.  The last item (B,) marks
        the intervals where the robot is far stiffer than usual (its :meth:`stiffness` above
        ``STIFF`` times the fastest relaxation over random shapes, e.g. a length near zero): the
        replay takes more RK4 steps there, but neither it nor a recording's own integration is
        to be trusted so close to a singular shape.  ``lam`` (B,): their :meth:`stiffness`, if at hand.
        """
        dt = np.asarray(dt, dtype=float)
        B = dt.size
        act, pas = self.act, self.pas
        ra0, ra1 = r0[:, act], r1[:, act]
        if kinks is None:
            times = np.stack([np.zeros(B), dt], axis=1)
            drive = np.stack([ra0, ra1], axis=1)
        else:
            times = np.stack([np.zeros(B), kinks.ta, kinks.tb, dt], axis=1)
            drive = np.stack([ra0, kinks.ka, kinks.kb, ra1], axis=1)
        M = 0 if outputs is None else outputs.shape[1]
        if M:  # the output times become break points too (the drive there: on its straight pieces)
            out = np.where(np.isfinite(outputs), np.clip(outputs, 0.0, dt[:, None]), dt[:, None])
            drive = np.concatenate([drive, _piecewise(out, times, drive)], axis=1)
            times = np.concatenate([times, out], axis=1)
            order = np.argsort(times, axis=1, kind="stable")
            times = np.take_along_axis(times, order, axis=1)
            drive = np.take_along_axis(drive, order[:, :, None], axis=1)
        rp, pose = r0[:, pas], np.zeros((B, 3))
        poses = [pose]
        lam = self.stiffness(r0, r1) if lam is None else lam
        stiff = ~(lam <= STIFF * max(self.rate, 1e-9))
        local = float(lam[~stiff].max()) if np.any(~stiff) else 0.0  # the stiff ones are not scored
        per_second = max(self.substeps / self.dt, local / REPLAY_ACCURACY)  # RK4 steps per second
        for i in range(times.shape[1] - 1):
            length = times[:, i + 1] - times[:, i]
            longest = float(length.max())
            if longest > 0.0:
                steps = min(MAX_STEPS, max(1, int(math.ceil(per_second * longest - 1e-9))))
                RP, P = integrate_batch(self.still.velocities, act, pas, drive[:, i:i + 2], rp, pose,
                                        np.maximum(length, 1e-12), steps)
                rp, pose = RP[:, 1], P[:, 1]
            poses.append(pose)
        xi = se2.log(pose) / dt[:, None]
        rdot_p = (rp - r0[:, pas]) / dt[:, None]
        if self.flow != (0.0, 0.0):
            xi = xi + flow_in_body(self.flow, yaw)
        at = np.full((B, M, 3), np.nan)
        if M:
            stack = np.stack(poses, axis=1)  # (B, knots, 3), at the sorted break points
            where = np.argsort(order, axis=1, kind="stable")[:, -M:]  # the outputs' places among them
            at = np.take_along_axis(stack, where[:, :, None], axis=1)
            at[~np.isfinite(outputs)] = np.nan
        return xi, rdot_p, at, stiff

    def rates(self, t: FloatArray, r: FloatArray, pose: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The body velocity (n − 1, 3) and passive joint velocities (n − 1, np) on the intervals of one series."""
        xi, rdot_p, _, _ = self.between(np.diff(t), r[:-1], r[1:], 0.5 * (pose[1:, 2] + pose[:-1, 2]))
        return xi, rdot_p


def interval_rates(system: SudsSystem, t: FloatArray, r: FloatArray,
                   pose: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Predicted body velocity (n − 1, 3) and passive rates (n − 1, np) on each sample interval.

    :meth:`IntervalPhysics.rates` at the series' median sample interval.
    """
    return IntervalPhysics(system, float(np.median(np.diff(t)))).rates(t, r, pose)


def equation_residuals(system: SudsSystem, t: FloatArray, r: FloatArray, pose: FloatArray,
                       w: int, rates: tuple[FloatArray, FloatArray] | None = None) -> FloatArray:
    """Measured minus predicted rates over every window of ``w`` intervals, shape (…, n − w, channels).

    ``t`` (n,) stamps, ``r`` (…, n, nj) joints in the system's order, ``pose`` (…, n, 3) at the
    same stamps (yaw unwrapped); ``rates``: (ξ (…, n − 1, 3), ṙ_p (…, n − 1, np)) from
    :func:`interval_rates` of the same data, if at hand (leading axes: several series on the same
    stamps at once).  Columns as :func:`channel_names`.
    """
    pas = list(system.passive)
    xi, rdot_p = interval_rates(system, t, r, pose) if rates is None else rates
    dt = np.diff(t)
    span = (t[w:] - t[:-w])[:, None]
    nwin = t.size - w
    cum = np.cumsum(rdot_p * dt[:, None], axis=-2)
    cum = np.concatenate([np.zeros_like(cum[..., :1, :]), cum], axis=-2)
    pred_p = (cum[..., w:, :] - cum[..., :-w, :]) / span
    meas_p = (r[..., w:, pas] - r[..., :-w, pas]) / span
    g = np.zeros(xi.shape[:-2] + (nwin, 3))
    for j in range(w):  # compose the predicted interval motions of each window
        g = se2.exp_step(g, xi[..., j:j + nwin, :] * dt[j:j + nwin, None])
    pred_xi = se2.log(g) / span
    meas_xi = se2.log(se2.relative(pose[..., :-w, :], pose[..., w:, :])) / span
    nb = len(channel_names(system)) - len(pas)
    return np.concatenate([meas_p - pred_p, (meas_xi - pred_xi)[..., :nb]], axis=-1)


def noise_power(t: FloatArray, e1: FloatArray, w: int, valid: FloatArray | None = None, least: int = 1) -> FloatArray:
    """Each channel's noise power in a window of ``w`` intervals, from the one-interval residuals.

    ``e1`` (n − 1, channels) the one-interval residuals over the stamps ``t`` (n,).  The noise of
    a windowed residual is (m_{k+w} − m_k)/T for a white series m; m is the white part of the
    accumulated residual S_k = Σ_{i<k} e1_i Δt_i, whose fourth difference keeps only it:
    σ_m = 1.4826·MAD(Δ⁴S)/√70, power 2σ_m²/T² (T the median window span).  ``valid`` (n − 1,)
    bool: intervals to use (a fourth difference touching another one is left out).  NaN with fewer
    than ``least`` fourth differences left.
    """
    S = np.cumsum(e1 * np.diff(t)[:, None], axis=0)
    d4 = S[4:] - 4 * S[3:-1] + 6 * S[2:-2] - 4 * S[1:-3] + S[:-4]
    if valid is not None:  # Δ⁴S at k uses the intervals k+1 … k+4
        ok = np.lib.stride_tricks.sliding_window_view(np.asarray(valid, dtype=bool)[1:], 4).all(axis=1)
        d4 = d4[ok]
    if d4.shape[0] < max(least, 1):
        return np.full(e1.shape[1], np.nan)
    dev = d4 - np.median(d4, axis=0)
    mad = 1.4826 * np.median(np.abs(dev), axis=0)
    var = np.mean(np.minimum(dev**2, (CLIP * mad) ** 2), axis=0) / CLIP_MEAN
    T = float(np.median(t[w:] - t[:-w]))
    return 2.0 * var / 70.0 / T**2


def residual_floor(system: SudsSystem, t: FloatArray, r: FloatArray, pose: FloatArray,
                   w: int, rates: tuple[FloatArray, FloatArray] | None = None) -> tuple[FloatArray, FloatArray]:
    """Residuals (n − w, channels) over windows of ``w`` intervals and each channel's :func:`noise_power`."""
    rates = interval_rates(system, t, r, pose) if rates is None else rates
    e = equation_residuals(system, t, r, pose, w, rates)
    e1 = equation_residuals(system, t, r, pose, 1, rates)
    return e, noise_power(t, e1, w)


class _Spectrum(NamedTuple):
    """Fourier coefficients of series over the last N whole gait cycles (:func:`_cycle_spectrum`)."""

    N: int  # whole cycles spanned
    span: float  # N · period, s
    j: IntArray  # bins 1 … N(H + 1) − 1 (bin j: j / span Hz)
    harm: BoolArray  # bins on a gait harmonic (j = N, 2N, …, HN)
    coef: tuple[ComplexArray, ...]  # per series (bins, columns)
    local: FloatArray  # (H, columns) mean power of the first series in the bins next to each harmonic
    noise_bins: int  # bins not on a harmonic


def _cycle_spectrum(t: FloatArray, valid: BoolArray, period: float, cycles: int, harmonics: int,
                    *series: FloatArray) -> _Spectrum | None:
    """Each series' coefficients c_j = Σ_i x_i Δt_i exp(−2πi j τ_i / L) over the last N whole cycles.

    ``series`` (n − 1, columns) values per interval over the stamps ``t`` (n,); ``valid`` (n − 1,)
    the intervals to use.  N = ``cycles`` or as many as ``t`` spans, give or take a sample (None
    below ``MIN_COHERENT``), L = N·period, τ_i the interval's middle from the span's start, bins
    j = 1 … N(H + 1) − 1 with H = ``harmonics``.  ``local``: the first series' mean power in the
    bins next to each harmonic (|j − kN| < N, harmonics left out): the noise there, where the noise
    of a differenced signal rises steeply with frequency.
    """
    N = min(int(cycles), int(math.floor((t[-1] - t[0] + np.median(np.diff(t))) / period)))  # jitter: ± a sample
    if N < MIN_COHERENT:
        return None
    L = N * period
    start = t[-1] - L
    tm = 0.5 * (t[1:] + t[:-1])
    use = np.asarray(valid, dtype=bool) & (tm >= start)
    j = np.arange(1, N * (harmonics + 1))
    basis = np.exp(-2j * np.pi * np.outer(j, (tm[use] - start) / L))
    dt = np.diff(t)[use, None]
    coef = tuple(basis @ (x[use] * dt) for x in series)
    harm = j % N == 0
    k = np.arange(1, harmonics + 1)
    near = (np.abs(j[None, :] - N * k[:, None]) < N) & ~harm  # (H, bins): the bins next to harmonic k
    local = near.astype(float) @ (np.abs(coef[0]) ** 2) / near.sum(axis=1)[:, None]
    return _Spectrum(N, L, j, harm, coef, local, int((~harm).sum()))


def _tail_score(logsf: FloatArray) -> FloatArray:
    """A statistic's natural-log tail probability under noise as a score.

    0 down to a ``SCORE_ZERO`` tail, then ``SCORE_PER_DECADE`` per decade below it.
    """
    decades = -np.asarray(logsf) / math.log(10.0)
    return SCORE_PER_DECADE * np.maximum(decades + math.log10(SCORE_ZERO), 0.0)


def harmonic_ratio(t: FloatArray, e1: FloatArray, valid: BoolArray, period: float, cycles: int,
                   harmonics: int) -> tuple[FloatArray, int]:
    """The residual's power at the gait's harmonics over the power next to them, per channel; its noise bins.

    ``e1`` (n − 1, channels) the one-interval residuals over the stamps ``t`` (n,), ``valid``
    (n − 1,) the intervals to use, ``period`` the gait period, s.  Over the last N whole cycles
    (:func:`_cycle_spectrum`; at least ``MIN_COHERENT``, else NaN) what repeats with the gait falls
    on the bins j = N, 2N, …, HN; noise of any smooth spectrum spreads over every j.  ρ = the mean
    over the harmonics k of |c_kN|² / the mean |c_j|² of the bins next to it is ≈ 1 under noise,
    about an F(2H, 2K) variable with K the other bins (returned), and 1 + N × the power ratio of a
    periodic misfit.  A misfit that does not repeat with the gait (or a gait far from ``period``)
    goes to the other bins and lowers ρ.
    """
    sp = _cycle_spectrum(t, valid, period, cycles, harmonics, e1)
    if sp is None:
        return np.full(e1.shape[1], np.nan), 0
    return _ratio(sp), sp.noise_bins


def _ratio(sp: _Spectrum) -> FloatArray:
    """:func:`harmonic_ratio`'s ρ per column of the spectrum's first series (NaN where a neighbourhood is empty)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = np.mean(np.abs(sp.coef[0][sp.harm]) ** 2 / sp.local, axis=0)
    return np.where(np.all(sp.local > 0, axis=0), rho, np.nan)


def _ratio_score(rho: FloatArray, noise_bins: int, harmonics: int) -> FloatArray:
    """:func:`coherent_statistic`'s score of ρ (an F(2H, 2K) variable under noise)."""
    from scipy.stats import f as fisher

    if noise_bins == 0:
        return rho
    return np.where(np.isfinite(rho), _tail_score(fisher.logsf(rho, 2 * harmonics, 2 * noise_bins)), np.nan)


def coherent_statistic(t: FloatArray, e1: FloatArray, valid: BoolArray, period: float, cycles: int,
                       harmonics: int) -> FloatArray:
    """How far the residual power at the gait's harmonics stands out of the noise: a score per channel.

    The :func:`harmonic_ratio` ρ (arguments as there) scored by its tail probability p under noise
    (ρ as F(2H, 2K)): 0 while p > ``SCORE_ZERO``, then ``SCORE_PER_DECADE`` per decade below it
    (NaN with too few cycles).  So the levels mean false-alarm rates per update, whatever N: with
    the default WARN 4 and ERROR 8, p < 1e-5 and p < 1e-6.  On the window statistic's own scale
    (≈ 1 under noise) its 2H = 4 degrees of freedom would put WARN at p = 3e-3: some channel of
    most nominal 60-cycle runs, whose updates are ~100 nearly independent looks per channel.
    This score can miss a misfit that does not repeat with the gait, never invent one.
    """
    return _ratio_score(*harmonic_ratio(t, e1, valid, period, cycles, harmonics), harmonics)


class Lag(NamedTuple):
    """:func:`lag_statistic`'s answer (all NaN with too few cycles or no motion)."""

    score: float  # scored like coherent_statistic (WARN 4, ERROR 8 with the default levels)
    seconds: float  # the pose stream's lag behind the shape stream, s
    share: float  # the part of the body channels' noise-weighted misfit at the harmonics that the lag explains


NO_LAG = Lag(math.nan, math.nan, math.nan)


def lag_statistic(t: FloatArray, e1: FloatArray, xi: FloatArray, valid: BoolArray, period: float, cycles: int,
                  harmonics: int) -> Lag:
    """Is the pose stream late (or early) on the shape stream?  A score, the lag (s) and how much it explains.

    ``e1`` (n − 1, b) the body channels' one-interval residuals (measured − predicted), ``xi``
    (n − 1, b) the predicted body velocity on the same intervals, the other arguments as in
    :func:`harmonic_ratio`.  A pose stamped τ late measures ξ(t − τ) ≈ ξ − τ ξ̇: its residual is
    −τ times the derivative of the prediction, the same τ in every body channel and at every
    harmonic.  At the harmonic bins, where ξ̇'s coefficient is a = 2πi j/L · X (X the prediction's),
    weighted least squares with the :func:`_cycle_spectrum` noise (P the power next to each
    harmonic, per channel) gives τ̂ = −Σ Re(ā c)/P / Σ |a|²/P, and its square against its noise,
    T = (Σ Re(ā c)/P)² / (Σ |a|²/2P), is χ²(1) under noise (taken as F(1, 2K), K the noise
    bins: P is estimated).  One degree of freedom for the misfit of every body channel and
    harmonic: a lag far too small to stand out in any one channel's :func:`coherent_statistic`
    does here.  The score is T's tail probability scored as there.  The share is the fit's part of
    the whole weighted misfit, (Σ Re(ā c)/P)² / Σ |a|²/P / Σ |c|²/P: near 1 for a lag alone, small
    for a misfit of another shape that merely leans the same way (friction, damping): a large score
    with a small share says "not a lag alone".
    """
    sp = _cycle_spectrum(t, valid, period, cycles, harmonics, e1, xi)
    return NO_LAG if sp is None else _lag(sp, slice(None))


def _lag(sp: _Spectrum, body: slice) -> Lag:
    """:func:`lag_statistic` from a spectrum.

    Its first series the residuals (the ``body`` columns used), its second the predicted body velocity.
    """
    from scipy.stats import f as fisher

    local = sp.local[:, body]
    if not np.all(local > 0):
        return NO_LAG
    c, X = sp.coef[0][sp.harm][:, body], sp.coef[1][sp.harm]
    a = 2j * np.pi * sp.j[sp.harm, None] / sp.span * X
    weight = float(np.sum(np.abs(a) ** 2 / local))
    if not weight > 0:
        return NO_LAG
    proj = float(np.sum(np.real(np.conj(a) * c) / local))
    T = proj**2 / (0.5 * weight)
    share = proj**2 / weight / float(np.sum(np.abs(c) ** 2 / local))
    return Lag(float(_tail_score(fisher.logsf(T, 1, 2 * sp.noise_bins))), -proj / weight, share)


def time_base_misfit(sp: _Spectrum, body: slice, bound: float) -> _Spectrum:
    """``sp`` with the residual that a time base off by at most ``bound`` (s) can make taken out of its harmonics.

    A shape stream timed at its fitted grid points (stamped late) sits off the device's ticks by
    a slowly wandering τ(t), |τ| ≤ ``bound`` (a few standard errors of the grid's line).  Over the
    spectrum's span L its mean is a lag, −τ̄ ξ̇ in the body channels (the pose stream is read at
    the shifted times), and its trend a stretch of the clock by ε, |ε| ≤ 3·bound/L (the steepest
    least-squares slope of a function bounded by ``bound``).  A stretched interval changes the
    measured passive velocities and the geometric part B·ṙ_a of the prediction alike, but not the
    drift C (the physics with the actuators at rest): −ε·C_p in the passive channels.  The pose's
    velocity keeps its time, so in the body channels the stretch shows in the prediction's
    geometric part alone: +ε·(ξ − C).  The first series of ``sp`` is the residual, the second the
    predicted body velocity (the ``body`` columns), the third those shapes for ε = 1, per channel.  The two
    amplitudes are fitted by noise-weighted least squares within their bounds (scipy's
    ``lsq_linear``) and subtracted at the harmonics; what exceeds the bounds stays.  A robot's own
    misfit of the same shape within the bounds is not told apart from the clock's: that is the
    limit of a stamped-late time base.
    """
    from scipy.optimize import lsq_linear

    c = sp.coef[0][sp.harm]  # (H, channels)
    if not (bound > 0 and np.all(sp.local > 0)):
        return sp
    lag = np.zeros_like(c)
    lag[:, body] = 2j * np.pi * sp.j[sp.harm, None] / sp.span * sp.coef[1][sp.harm]
    stretch = sp.coef[2][sp.harm]
    w = 1.0 / np.sqrt(sp.local)
    cols = [np.concatenate([(x * w).real.ravel(), (x * w).imag.ravel()]) for x in (lag, stretch)]
    A = np.stack(cols, axis=1)
    y = np.concatenate([(c * w).real.ravel(), (c * w).imag.ravel()])
    limits = np.array([bound, 3.0 * bound / sp.span])
    use = np.any(A != 0, axis=0)
    if not use.any():
        return sp
    fit = lsq_linear(A[:, use], y, bounds=(-limits[use], limits[use])).x
    amp = np.zeros(2)
    amp[use] = fit
    coef0 = sp.coef[0].copy()
    coef0[sp.harm] = c - amp[0] * lag - amp[1] * stretch
    return sp._replace(coef=(coef0,) + sp.coef[1:])


# ------------------------------------------------------------------ the monitor
def noise_groups(system: SudsSystem) -> tuple[tuple[str, FloatArray, float], ...]:
    """The signal groups whose noise levels the floor fits: (name, joint mask (nj,), pose weight).

    The actuated joints together (their noise reaches every channel through ṙ_a), each passive
    joint alone (a stiff one shapes its own channel's noise), and the pose.
    """
    nj = len(system.joint_names)
    out: list[tuple[str, FloatArray, float]] = []
    if system.actuated:
        mask = np.zeros(nj)
        mask[list(system.actuated)] = 1.0
        out.append(("actuated", mask, 0.0))
    for j in system.passive:
        mask = np.zeros(nj)
        mask[j] = 1.0
        out.append((system.joint_names[j], mask, 0.0))
    out.append(("pose", np.zeros(nj), 1.0))
    return tuple(out)


def fitted_gain(floor: FloatArray, P: FloatArray, W: FloatArray) -> FloatArray:
    """κ per channel from the noise groups' responses, weighted by levels fitted to the measured floors.

    ``floor`` (channels,) the :func:`noise_power` of the data; ``P`` and ``W`` (groups, channels)
    what :func:`noise_power` makes of each group's synthetic-noise response and that response's
    window power.  The group levels s ≥ 0 make Σ_g s_g P_gc match ``floor`` (relative least
    squares, :func:`scipy.optimize.nnls`), staying as close to one common level as the floors
    allow (a weak pull, ``LEVEL_PRIOR``: with fewer channels than groups the floors alone do not
    fix the levels); κ_c = Σ_g s_g W_gc / Σ_g s_g P_gc (1 where undefined).
    """
    from scipy.optimize import nnls

    good = np.isfinite(floor) & (floor > 0) & np.all(np.isfinite(P), axis=0) & np.all(np.isfinite(W), axis=0)
    A = (P[:, good] / floor[good]).T  # (channels, groups)
    weights = np.ones(P.shape[0])
    if A.size and np.all(np.isfinite(A)) and np.any(A > 0):
        total = A.sum(axis=1)
        common = float(total @ np.ones_like(total) / (total @ total))  # one level for every group
        mu = math.sqrt(LEVEL_PRIOR)
        aug = np.vstack([A * common, mu * np.eye(A.shape[1])])
        u, _ = nnls(aug, np.concatenate([np.ones(A.shape[0]), mu * np.ones(A.shape[1])]))
        if np.any(u > 0):
            weights = u
    num, den = weights @ np.where(np.isfinite(W), W, 0.0), weights @ np.where(np.isfinite(P), P, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        k = num / den
    return np.where(np.isfinite(k) & (k > 0), k, 1.0)


class _Sample(NamedTuple):
    """One paired sample: the data and its noisy twins (one per noise group), and how its pose was read.

    ``r`` (1 + groups, nj) and ``pose`` (1 + groups, 3): row 0 the data, row 1 + g the data plus
    the synthetic noise on group g's signals.  ``pose`` is interpolated between the pose samples
    at ``bracket`` = (τa, τb) (equal: a pose at this very stamp), ``yaw_a`` the yaw at τa;
    ``pose_ok`` (one element, set when the pose is read) False when that bracket spans a lost
    pose message or a lost shape sample, or lies before the first replay.  ``clock_se``: 0 for a
    sample at its own stamp; for one timed at its grid point by the shape clock (a stream stamped
    late) the standard error of that time base when it was released, s (> 0).
    """

    t: float
    r: FloatArray
    pose: FloatArray
    bracket: tuple[float, float]
    yaw_a: float
    pose_ok: BoolArray
    clock_se: float = 0.0
    grid: float = math.nan
    grid_se: float = 0.0


class _Interval(NamedTuple):
    """The replays over one interval (data and twins): the whole motion, and the motion up to pose stamps inside."""

    motion: FloatArray  # (versions, 3) relative pose at the interval's end
    stamps: FloatArray  # (M,) pose stamps inside (NaN: none)
    at: FloatArray  # (versions, M, 3) relative pose at them
    stiff: bool  # near a singular shape (:meth:`IntervalPhysics.between`): not scored
    lost: bool  # its ends' grid points more than ``gap`` periods apart: a lost shape sample inside


def _by_version(x: FloatArray, versions: int) -> FloatArray:
    """(k, versions·c) columns side by side → (versions·k, c), version after version."""
    k = x.shape[0]
    return x.reshape(k, versions, -1).transpose(1, 0, 2).reshape(versions * k, -1)


def _compose(a: FloatArray, b: FloatArray) -> FloatArray:
    """Poses (…, 3): a·b (b expressed in a's frame)."""
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack([a[..., 0] + c * b[..., 0] - s * b[..., 1], a[..., 1] + s * b[..., 0] + c * b[..., 1],
                     a[..., 2] + b[..., 2]], axis=-1)


class MismatchMonitor:
    """Pair shape and pose by stamps, track per-channel F against the noise floor, request diagnoses.

    Feed :meth:`on_shape` (stamp, names, positions — joints matched by name, extra joints
    ignored) and :meth:`on_pose` (stamp, x, y, yaw) in any interleaving; a shape sample is
    paired once the pose stream has reached its stamp, never by arrival time.  The pose at a
    shape stamp between two pose samples is their linear interpolation (yaw unwrapped) plus the
    nominal replay's own departure from a straight line there (the body velocity jumps wherever
    the drive bends, so a straight line between pose samples cuts those corners); a pose read
    across more than ``gap`` typical pose intervals (a lost pose message) is not trusted:
    windows that start or end on it are not scored.  :attr:`statuses` is the current state,
    :attr:`record` what every channel went through so far, :meth:`take_request` the pending
    diagnosis request (at most one per ERROR episode).
    """

    def __init__(self, system: SudsSystem, config: MonitorConfig = MonitorConfig()) -> None:
        self.system = system
        self.config = config
        self.channels = channel_names(system)
        self.names = tuple(system.joint_names)
        self.physics = IntervalPhysics(system, 1.0 / config.rate)
        groups = noise_groups(system)
        self._joint_masks = np.array([g[1] for g in groups])  # (G, nj)
        self._pose_masks = np.array([g[2] for g in groups])[:, None]  # (G, 1)
        spc = config.samples_per_cycle
        self._spc = spc
        keep = int(math.ceil(config.history_cycles * spc)) + config.diff_window + 8
        self._hist: deque[_Sample] = deque(maxlen=keep)
        # predicted (ξ, ṙ_p) of the data and of each twin, (1 + G, 3 + np), and the data's replay,
        # on the interval ending at each sample
        self._rates: deque[FloatArray] = deque(maxlen=keep)
        self._replays: deque[_Interval | None] = deque(maxlen=keep)
        # the data's drift on each interval: the physics' (ξ, ṙ_p) at its middle shape with the actuators at rest
        self._drifts: deque[FloatArray] = deque(maxlen=keep)
        # the data's predicted (ξ, ṙ_p) with the drive's set-point grid GRID_SHIFT later
        self._shifted: deque[FloatArray] = deque(maxlen=keep)
        self._rated = 0  # samples (counted from the first) whose interval is predicted
        self._read = 0  # samples whose pose is final (corrected with the replay)
        # samples waiting for the other stream (bounded: a stream that stops cannot fill memory)
        # (stamp, joints, the clock's standard error when timed at its grid point, else 0)
        # and its set-point time and that time's standard error (read late and jittered: the clock's line)
        self._shapes: deque[tuple[float, FloatArray, float, float, float]] = deque(maxlen=keep)
        # (stamp, pose, synthetic noise, the typical pose interval up to it: the median of the last 64, s);
        # room for the poses that arrive while the shape clock holds its lock block
        self._poses: deque[tuple[float, FloatArray, FloatArray, float]] = deque(maxlen=keep + 16 * LIVE_LOCK_MAX)
        self._pose_steps: deque[float] = deque(maxlen=64)  # recent pose intervals, s
        self._rng_r, self._rng_pose = (np.random.default_rng(sq)
                                       for sq in np.random.SeedSequence(SYNTHETIC_SEED).spawn(2))
        self._since_update = 0
        self._floor: FloatArray | None = None  # the channels' noise floors, renewed every FLOOR_EVERY updates
        self._least = np.zeros(len(self.channels))  # the floors' lower bound (FLOOR_RELATIVE), with them
        self.lag = NO_LAG  # the last lag_statistic
        self.statuses: tuple[ChannelStatus, ...] = ()
        self.record = MonitorRecord(tuple(ChannelRecord(c) for c in self.channels))
        self.updated = 0  # number of statistic updates
        self.paired = 0
        self.skipped = 0
        self.unconfirmed = 0  # jittered samples not compared (held or left out) while the clock's count was unconfirmed
        # those held, as _queue times them, and the clock's count they were timed on (LiveGrid.counts)
        self._held: list[tuple[float, FloatArray, float, float, float]] = []
        self._held_counts = 0
        self._snapped_from: float | None = None  # the first sample timed at its grid point
        # the shape samples' clock (see the module docstring, *Lab streams*): passed on at their stamps, or,
        # once the stream is recognised as stamped late, at their grid points
        self._clock = LiveGrid(raw_values=True)
        self._armed = True
        self._request: DiagnosisRequest | None = None

    # -------------------------------------------------------- input
    @property
    def stamped_late(self) -> bool:
        """True once the shape stream is taken for stamped late (its samples then timed at their grid points)."""
        return self._clock.mode == "snap"

    def on_shape(self, stamp: float, names: tuple[str, ...] | list[str], position: FloatArray) -> int:
        """Queue a shape sample; returns the number of samples paired now."""
        try:
            order = joint_order(tuple(names), self.names)
        except SudsDataError:  # a joint of the system missing: skipped, as any bad sample
            self.skipped += 1
            return 0
        pos = np.asarray(position, dtype=float)
        if pos.size != len(names):
            self.skipped += 1
            return 0
        r = pos.copy() if order is None else pos[order]  # (a copy either way: the caller's array may change)
        if not np.all(np.isfinite(r)) or not float(stamp) > self._clock.last_stamp:
            self.skipped += 1
            return 0
        return self._queue(*self._clock.add(float(stamp), r))

    @property
    def held(self) -> int:
        """Shape samples the grid stage holds (a jittered stream's lock block, then its newest few)."""
        return self._clock.held

    def flush(self) -> int:
        """Pass on the shape samples the clock holds (the stream's end); returns the number paired now."""
        return self._queue(*self._clock.drain())

    def _queue(self, stamps: list[float], values: list[FloatArray]) -> int:
        se = self._clock.offset_se if self.stamped_late else 0.0
        read = self._clock.mode == "grid"  # read late with jitter: the set-points on the clock's line
        grid_se = self._clock.offset_se if read else 0.0
        fresh = [(t, r, se, self._clock.grid_point(t) if read else t, grid_se) for t, r in zip(stamps, values)]
        if self._held and self._held_counts != self._clock.counts:
            # the count they were timed on was replaced (a recount, or a fresh lock after a pause): left out
            self._held = []
        if (se > 0 or read) and not self._clock.confirmed:
            # its count came from a phase lock no recount has agreed with yet: a time base that may be slipping
            # (milliseconds off) would be read as a misfit of the robot.  So the samples are held until a
            # recount agrees, then compared (left out if one replaces the count).  Read late, their set-points
            # are then taken from the line as it stands, through them: the lock block's own line and the
            # jumps between the first release blocks put bends the statistics' allowance does not reach (a
            # nominal swimmer9 at 3 ms read F 5.1 on the set-points as released).  Stamped late, they keep
            # the times they were released at (the offset against the poses is within the allowance).  The
            # samples before them (on another time base) are not continued from
            self.unconfirmed += len(fresh)
            if not self._held:
                self._forget()
            self._held.extend(fresh)
            self._held_counts = self._clock.counts
            del self._held[:max(0, len(self._held) - HELD_MAX)]
            return 0
        if self._held:  # confirmed: the count they were timed on holds
            self.unconfirmed -= len(self._held)
            if read:  # their set-points from the line as it stands now, through them (inside its data)
                self._held = [(t, r, s, self._clock.grid_point(t), grid_se) for t, r, s, _, _ in self._held]
            fresh, self._held = self._held + fresh, []
        n = 0
        for sample in fresh:
            if sample[2] > 0 and self._snapped_from is None:
                self._snapped_from = float(sample[0])
            self._shapes.append(sample)
            n += self._pair()
        return n

    def _forget(self) -> None:
        """Start the sample history afresh (the statistics come again once enough samples are at hand)."""
        for d in (self._hist, self._rates, self._replays, self._drifts, self._shifted, self._shapes):
            d.clear()
        self._rated = self._read = self.paired
        self._since_update = 0
        self._floor = None

    def on_pose(self, stamp: float, x: float, y: float, yaw: float) -> int:
        """Queue a pose sample; returns the number of samples paired now."""
        p = np.array([x, y, yaw], dtype=float)
        if not np.all(np.isfinite(p)) or (self._poses and stamp <= self._poses[-1][0]):
            self.skipped += 1
            return 0
        if self._poses:  # unwrap yaw against the previous pose
            prev = self._poses[-1][1][2]
            p[2] = prev + (p[2] - prev + math.pi) % (2 * math.pi) - math.pi
            self._pose_steps.append(float(stamp) - self._poses[-1][0])
        typical = float(np.median(self._pose_steps)) if self._pose_steps else math.inf
        self._poses.append((float(stamp), p, SYNTHETIC_NOISE * self._rng_pose.standard_normal(3), typical))
        return self._pair()

    def _pair(self) -> int:
        n = 0
        while self._shapes and self._poses and self._poses[-1][0] >= self._shapes[0][0]:
            t, r, se, grid, grid_se = self._shapes.popleft()
            while len(self._poses) > 1 and self._poses[1][0] <= t:
                self._poses.popleft()
            t0, p0, n0, _ = self._poses[0]
            if t0 > t:  # before the first pose: cannot be paired
                self.skipped += 1
                continue
            if t0 == t or len(self._poses) == 1:
                pose, noise, bracket, ok = p0, n0, (t, t), True
            else:
                t1, p1, n1, typical = self._poses[1]
                a = (t - t0) / (t1 - t0)
                pose, noise, bracket = p0 + (p1 - p0) * a, n0 + (n1 - n0) * a, (t0, t1)
                ok = t1 - t0 <= self.config.gap * typical  # (typical as of t1: the same however late the shape)
            self._add(t, r, pose, noise, bracket, float(p0[2]), ok, se, grid, grid_se)
            n += 1
        return n

    def add_pair(self, stamp: float, r: FloatArray, pose: FloatArray) -> None:
        """Add one already paired sample (joints in the system's order, pose x, y, unwrapped yaw)."""
        stamp = float(stamp)
        pose = np.asarray(pose, dtype=float)
        self._add(stamp, np.asarray(r, dtype=float), pose, SYNTHETIC_NOISE * self._rng_pose.standard_normal(3),
                  (stamp, stamp), float(pose[2]), True)

    def _add(self, t: float, r: FloatArray, pose: FloatArray, pose_noise: FloatArray, bracket: tuple[float, float],
             yaw_a: float, pose_ok: bool, clock_se: float = 0.0, grid: float | None = None,
             grid_se: float = 0.0) -> None:
        r_noise = SYNTHETIC_NOISE * self._rng_r.standard_normal(r.size)
        rs = np.concatenate([r[None], r + self._joint_masks * r_noise])
        poses = np.concatenate([pose[None], pose + self._pose_masks * pose_noise])
        self._hist.append(_Sample(t, rs, poses, bracket, yaw_a, np.array([pose_ok]), clock_se,
                                  t if grid is None else grid, grid_se))
        self._rates.append(np.full((rs.shape[0], 3 + len(self.system.passive)), np.nan))
        self._drifts.append(np.full(3 + len(self.system.passive), np.nan))
        self._shifted.append(np.full(3 + len(self.system.passive), np.nan))
        self._replays.append(None)
        self.paired += 1
        self._since_update += 1
        if self._since_update >= self.config.update_every:
            self._since_update = 0
            self._update()

    # -------------------------------------------------------- statistics
    def _pos(self, index: int) -> int:
        """Position in the history of the sample counted ``index`` from the first."""
        return index - (self.paired - len(self._hist))

    def samples(self, n: int | None = None) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The newest ``n`` (all when None) paired samples whose pose is final: stamps, joints, poses.

        Stamps (m,) s; joints (m, nj) in the system's order; poses (m, 3) x, y, unwrapped yaw at
        the shape stamps (read as the module docstring says).  A sample's pose is final once the
        replay reaches the pose sample after it: the newest one or two samples are not yet.
        """
        ready = len(self._hist) - (self.paired - min(self._read, self._rated))
        last = list(self._hist)[:max(ready, 0)]
        if n is not None:
            last = last[-n:] if n > 0 else []
        return (np.array([h.t for h in last]), np.array([h.r[0] for h in last]).reshape(len(last), len(self.names)),
                np.array([h.pose[0] for h in last]).reshape(len(last), 3))

    def _grid(self) -> tuple[float, FloatArray]:
        """The set-point time of every sample in the history: (reference time, times − it).

        Each sample's own stamp on a uniform stream and on one stamped late (there the shape clock
        timed it at its grid point, and refitting a line to such times would put a bend some µs off
        the sample and split the interval there); read late with jitter, its grid point on the
        shape clock's line when it was released (:meth:`~suds_ros.core.resample.LiveGrid.grid_point`:
        the clock counts the stamps once and keeps that count, where a line refitted to the
        history at every update, with 3 ms of jitter at 100 Hz, now and then took another count and
        put every bend up to 9 ms off).
        """
        g = np.array([h.grid for h in self._hist])
        return float(g[0]), g - g[0]

    def _predict_new_intervals(self) -> None:
        """Predict the intervals that ended since the last update, but the newest (its end needs the next sample).

        Data and twins in one batch; the drive bends where the grid says (:func:`drive_kinks`).  The
        replays also give the motion up to the pose stamps inside each interval (for
        :meth:`_read_poses`: each twin reads its pose with its own replay, as the data does).
        """
        m = len(self._hist)
        if m - 1 - REPLAY_AHEAD < max(self._pos(self._rated), 1):
            return
        hist = list(self._hist)
        ref, grid = self._grid()
        first = max(self._pos(self._rated), 1)  # the first interval to predict ends at this position
        k = (m - 1 - REPLAY_AHEAD) - first + 1
        lo = first - 2  # positions lo … m − 1: one more on each side gives the slopes at the ends
        behind = min(REPLAY_BEHIND, max(lo, 0))  # and more before, for the knot fit only
        last = hist[max(lo, 0) - behind:]
        t = np.array([h.t for h in last]) - ref
        g = grid[max(lo, 0) - behind:]
        R = np.array([h.r for h in last]).transpose(1, 0, 2)  # (versions, samples, nj)
        yaw = np.array([h.pose[:, 2] for h in last]).T  # (versions, samples)
        brackets = np.array([h.bracket for h in last]) - ref
        if lo < 0:  # the very first interval: no sample before it (a copy, one period earlier, on its grid point)
            t = np.concatenate([[t[0] - 1.0 / self.config.rate], t])
            g = np.concatenate([[g[0] - 1.0 / self.config.rate], g])
            R = np.concatenate([R[:, :1], R], axis=1)
            yaw = np.concatenate([yaw[:, :1], yaw], axis=1)
            brackets = np.concatenate([brackets[:1], brackets])
        act = self.physics.act
        V = R.shape[0]
        # data and twins in one knot fit: their columns side by side (versions × actuated)
        period = 1.0 / self.config.rate
        kinks = drive_kinks(t, R[:, :, act].transpose(1, 0, 2).reshape(t.size, -1), g, period)
        # the data with its set-points later, where they are the shape clock's (read late: _time_base)
        shift = any(h.grid_se > 0 for h in last)
        moved = drive_kinks(t, R[0][:, act], g + GRID_SHIFT, period) if shift else None
        # the k intervals replayed now, with one sample on each side (the context only served the knots)
        kinks = Kinks(*(x[behind:behind + k] for x in kinks))
        t, g, R, yaw, brackets = (x[behind:behind + k + 3] for x in (t, g, R.transpose(1, 0, 2), yaw.T, brackets))
        R, yaw = R.transpose(1, 0, 2), yaw.T
        t0, t1 = t[1:-2], t[2:-1]
        # pose stamps inside each interval: the start sample's next pose, the end sample's previous one
        cand = np.stack([brackets[1:-2, 1], brackets[2:-1, 0]], axis=1)
        inside = (cand > t0[:, None]) & (cand < t1[:, None])
        outputs = np.where(inside, cand - t0[:, None], np.nan)
        dt = t1 - t0
        lost = lost_samples(t, g, self.config.gap / self.config.rate)[1:-1]
        mid_yaw = 0.5 * (yaw[:, 1:-2] + yaw[:, 2:-1])
        # the data and its twins, then (read late) the data on the moved grid: V (+ 1) replays of each interval
        both = Kinks(np.tile(kinks.ta, V), _by_version(kinks.ka, V), np.tile(kinks.tb, V), _by_version(kinks.kb, V))
        r0, r1, yaws = R[:, 1:-2].reshape(V * k, -1), R[:, 2:-1].reshape(V * k, -1), mid_yaw.ravel()
        n = V
        if moved is not None:
            n = V + 1
            moved = Kinks(*(x[behind:behind + k] for x in moved))
            both = Kinks(*(np.concatenate([x, y]) for x, y in zip(both, moved)))
            r0, r1, yaws = np.concatenate([r0, R[0, 1:-2]]), np.concatenate([r1, R[0, 2:-1]]), \
                np.concatenate([yaws, mid_yaw[0]])
        lam = np.tile(self.physics.stiffness(R[0, 1:-2], R[0, 2:-1]), n)  # the twins: as the data
        xi, rp, at, stiff = self.physics.between(np.tile(dt, n), r0, r1, yaws, both,
                                                 np.tile(outputs, (n, 1)) if inside.any() else None, lam)
        shifted = (np.concatenate([xi[V * k:], rp[V * k:]], axis=1) if moved is not None
                   else np.full((k, 3 + rp.shape[1]), np.nan))  # (k, 3 + np)
        xi, rp, at, stiff = xi[:V * k], rp[:V * k], at[:V * k], stiff[:V * k]
        rates = np.concatenate([xi, rp], axis=1).reshape(V, k, -1)  # (V, k, 3 + np)
        mid = 0.5 * (R[0, 1:-2] + R[0, 2:-1])
        d_xi, d_rp = self.physics.still.velocities(mid, np.zeros((k, act.size)))
        if self.physics.flow != (0.0, 0.0):
            d_xi = d_xi + flow_in_body(self.physics.flow, mid_yaw[0])
        drifts = np.concatenate([d_xi, d_rp], axis=1)
        still = xi - (0.0 if self.physics.flow == (0.0, 0.0) else flow_in_body(self.physics.flow, mid_yaw.ravel()))
        motion = se2.exp_step(np.zeros((V * k, 3)), still * np.tile(dt, V)[:, None]).reshape(V, k, 3)
        at = at.reshape(V, k, at.shape[1], 3)
        for j in range(k):
            self._rates[first + j] = rates[:, j]
            self._drifts[first + j] = drifts[j]
            self._shifted[first + j] = shifted[j]
            self._replays[first + j] = _Interval(motion[:, j], np.where(inside[j], cand[j] + ref, np.nan), at[:, j],
                                                 bool(stiff.reshape(V, k)[:, j].any()), bool(lost[j]))
        self._rated = self.paired - REPLAY_AHEAD

    def _read_poses(self) -> None:
        """Finish the poses whose bracket the replays now cover: add the replay's departure from a straight line.

        For a shape stamp t between pose samples at τa < t < τb (weight α = (t − τa)/(τb − τa)),
        the replay gives the motion A from τa to t and B from τa to τb; the straight line between
        the pose samples misses A − α·B (x, y in τa's frame, rotated to the world by the yaw at τa).
        """
        hist = list(self._hist)
        stamps = np.array([h.t for h in hist])
        top = self._pos(self._rated) - 1  # positions ≤ top have their intervals predicted
        pos = max(self._pos(self._read), 0)
        while pos < len(hist):
            h = hist[pos]
            ta, tb = h.bracket
            if ta == tb:
                pos += 1
                continue
            ia = int(np.searchsorted(stamps, ta, side="right"))  # interval ending at position ia holds τa
            ib = int(np.searchsorted(stamps, tb, side="left"))  # … ending at ib holds τb
            if ib > top:
                break  # wait for the replay of τb's interval
            if ia < 1 or any(self._replays[i] is None for i in range(ia, ib + 1)):
                h.pose_ok[0] = False  # older than the history or than the first replay: left as interpolated
                pos += 1
                continue
            if any(self._replays[i].lost for i in range(ia, ib + 1)):  # type: ignore[union-attr]
                h.pose_ok[0] = False  # across a lost shape sample the replay does not know the drive
            a = self._motion(ia, ta, pos)  # (versions, 3)
            b = _compose(a, self._motion(pos + 1, h.t, ib, tb))
            alpha = (h.t - ta) / (tb - ta)
            d = a - alpha * b
            c, s = math.cos(h.yaw_a), math.sin(h.yaw_a)
            h.pose[:] += np.stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1], d[:, 2]], axis=1)
            pos += 1
        self._read = self.paired - (len(hist) - pos)

    def _motion(self, first: int, start: float, last: int, end: float | None = None) -> FloatArray:
        """The replayed motion (versions, 3) from ``start`` to the end of an interval, or to ``end`` inside it.

        ``start`` lies inside the interval ending at history position ``first`` (or at its start),
        the motion runs to the end of the interval ending at ``last``, or to ``end`` inside it.
        """
        g = np.zeros((len(self._joint_masks) + 1, 3))
        for i in range(first, last + 1):
            rep = self._replays[i]
            assert rep is not None
            whole = rep.motion
            if end is not None and i == last and end < self._hist[i].t:
                whole = rep.at[:, int(np.nanargmin(np.abs(rep.stamps - end)))]
            if i == first and start > self._hist[i - 1].t:
                whole = se2.relative(rep.at[:, int(np.nanargmin(np.abs(rep.stamps - start)))], whole)
            g = _compose(g, whole)
        return g

    def _update(self) -> None:
        self._predict_new_intervals()
        self._read_poses()
        cfg = self.config
        w = cfg.diff_window
        n = cfg.first_report_samples
        ready = len(self._hist) - (self.paired - min(self._rated, self._read))  # samples usable now
        if ready < n:
            return
        n_stat = int(round(cfg.window_cycles * self._spc)) + w
        fresh = self._floor is None or self.updated % FLOOR_EVERY == 0
        # the floor's span when it is renewed, else the statistic's
        t, E, win_ok, new, least = self._residuals(ready, n if fresh else n_stat, fresh, n_stat - w)
        if fresh:
            if not np.all(np.isfinite(new) & (new > 0)) and ready > n:  # lost messages: the whole kept history
                t, E, win_ok, new, least = self._residuals(ready, ready, True, n_stat - w)
            if least is not None:
                self._least = least
            new = np.maximum(new, self._least)  # NaN (unmeasured) stays
            measured = np.isfinite(new) & (new > 0)
            self._floor = np.where(measured, new, np.nan if self._floor is None else self._floor)
        floor = self._floor
        scored, need = self._scored(ready, E[0], win_ok, n_stat - w)
        ok = np.isfinite(floor) & (floor > 0) & (scored.shape[0] >= need)
        ms = np.mean(scored**2, axis=0) if scored.shape[0] else np.zeros(len(self.channels))
        F = np.where(ok, ms / np.where(ok, floor, 1.0), np.nan)
        if cfg.coherent_cycles:
            F = np.where(ok, np.fmax(F, self._coherent(ready)), np.nan)
        why = (f"{scored.shape[0]} of the {need} clean windows needed in the {ready / self._spc:.1f} cycles kept "
               f"(lost messages)" if scored.shape[0] < need else
               "no noise floor yet: too few runs of four clean intervals (lost messages)")
        self._set_levels(t[-1], F, why)

    def _residuals(self, ready: int, m: int, floor: bool, span: int | None = None
                   ) -> tuple[FloatArray, FloatArray, BoolArray, FloatArray, FloatArray | None]:
        """Stamps, window residuals, clean windows and (``floor``) noise floor over the last ``m`` of ``ready`` samples.

        The residuals are (versions, m − w, channels); the floor, before its lower bound, is NaN on
        a channel with too few clean runs (:data:`FLOOR_LEAST`), and empty when not asked for; the
        bound (:data:`FLOOR_RELATIVE` of each channel's predicted rms, squared) is None when not
        asked for or when no interval is clean.  The data's residuals (row 0) are returned with
        the misfit of the set-point grid's own error taken out (:meth:`_time_base`, fitted over the
        last ``span`` windows, None: all).
        """
        w = self.config.diff_window
        t, R, P, split, shape_ok, pose_ok = self._series(ready, m, floor)
        win_ok = (np.lib.stride_tricks.sliding_window_view(shape_ok, w).all(axis=1)
                  & pose_ok[:-w] & pose_ok[w:])
        E = equation_residuals(self.system, t, R, P, w, split)  # (versions, m − w, channels)
        data = self._time_base(ready, t, R[0], P[0], E[0], win_ok, span, (split[0][0], split[1][0]))
        if not floor:
            return t, np.concatenate([data[None], E[1:]]), win_ok, np.zeros(0), None
        valid = shape_ok & pose_ok[:-1] & pose_ok[1:]
        E1 = equation_residuals(self.system, t, R, P, 1, split)
        power = noise_power(t, E1[0], w, valid, FLOOR_LEAST)
        resp, resp1 = E[1:] - E[0], E1[1:] - E1[0]  # each noise group's response
        P_g = np.array([noise_power(t, x, w, valid, FLOOR_LEAST) for x in resp1])
        W_g = np.mean(resp[:, win_ok] ** 2, axis=1) if win_ok.any() else np.full(P_g.shape, np.nan)
        (xi, rp) = split
        predicted = np.concatenate([rp[0], xi[0][:, :E.shape[2] - rp.shape[2]]], axis=1)  # the channels' order
        least = (FLOOR_RELATIVE * np.sqrt(np.mean(predicted[valid] ** 2, axis=0))) ** 2 if valid.any() else None
        return t, np.concatenate([data[None], E[1:]]), win_ok, fitted_gain(power, P_g, W_g) * power, least

    def _time_base(self, ready: int, t: FloatArray, r: FloatArray, pose: FloatArray, E: FloatArray,
                   win_ok: BoolArray, span: int | None, rates: tuple[FloatArray, FloatArray]) -> FloatArray:
        """The data's window residuals ``E`` (windows, channels) less what the shape stream's time base can explain.

        Two time bases are estimates, each with its own standard error per sample:

        * read late with jitter, the drive's set-point times are the points of the shape clock's
          line, known to ``grid_se`` (≈ 2σ/√n at the newest sample, 120 µs at 2 ms of jitter over
          1000 samples; each sample keeps the one it was released with), and a passive joint that
          follows its drive within a sample turns such an offset into a misfit: without this 5 of 12
          nominal swimmer9 runs read late at 2 ms are called wrong (F up to 11.1;
          ``docs/results/monitor_jitter.md``), all OK on the true set-point times.  The residual's
          sensitivity comes from the data replayed on the grid moved by :data:`GRID_SHIFT`;
        * stamped late, the samples themselves are timed at those points (``clock_se``), so the
          whole shape stream may sit off the pose stream: the body channels then compare each
          window with the pose a little earlier or later.  The extrapolated line's error wanders
          with the stamps (one nominal swimmer9 at 2 ms: 560 µs at 5 s, 3.4 of its standard
          errors, as far as a least-squares line through every stamp so far; body F 4.2, WARN).
          The sensitivity: the poses moved by :data:`GRID_SHIFT` along their own rate.

        Per time base present, one offset is fitted to every channel over the clean windows of
        the last ``span`` (each channel weighted by its own mean square there), bounded by
        ``TIME_BASE_SIGMAS`` of the window's mean standard error, and its misfit taken out.  The
        phase-coherent statistic's allowance for a stamped-late time base is :func:`time_base_misfit`.
        ``rates``: the data's predicted (ξ, ṙ_p) per interval, as :meth:`_series` gave them.
        """
        m = t.size
        kept = list(self._hist)[ready - m:ready]
        use = win_ok.copy()
        if span is not None:
            use[:-span] = False
        if not use.any():
            return E
        w = self.config.diff_window
        directions = []
        se = float(np.mean([h.grid_se for h in kept]))
        if se > 0.0:  # read late: the set-points GRID_SHIFT later
            moved = np.array(list(self._shifted)[ready - m + 1:ready])
            if np.all(np.isfinite(moved)):
                directions.append((se, (moved[:, :3], moved[:, 3:]), pose))
        se = float(np.mean([h.clock_se for h in kept]))
        if se > 0.0:  # stamped late: the shape samples GRID_SHIFT later against the poses
            directions.append((se, rates, pose - GRID_SHIFT * np.gradient(pose, t, axis=0)))
        if not directions:
            return E
        weight = 1.0 / np.maximum(np.mean(E[use] ** 2, axis=0), 1e-300)
        for se, split, at in directions:
            A = (equation_residuals(self.system, t, r, at, w, split) - E) / GRID_SHIFT
            den = float(np.sum(A[use] ** 2 * weight))
            if den > 0.0:
                bound = TIME_BASE_SIGMAS * se
                E = E + float(np.clip(-np.sum(A[use] * E[use] * weight) / den, -bound, bound)) * A
        return E

    def _scored(self, ready: int, E: FloatArray, win_ok: BoolArray, span: int) -> tuple[FloatArray, int]:
        """The windows the statistic is taken over, and how many it needs.

        ``E`` (windows, channels) and ``win_ok``: the data's residuals and clean windows up to the
        newest sample, at least the statistic's own ``span`` windows (``window_cycles``).  It needs
        ``min_scored`` of that span's windows clean; with fewer (lost messages) it reaches back into
        the history (computed here unless ``E`` already covers it) for the newest clean windows, as
        many as it needs, and returns those it found when even the history holds too few.
        """
        w = self.config.diff_window
        need = max(1, int(math.ceil(self.config.min_scored * span)))
        own = win_ok[-span:]
        if np.count_nonzero(own) >= need or ready <= span + w:
            return E[-span:][own], need
        if E.shape[0] < ready - w:
            _, every, win_ok, _, _ = self._residuals(ready, ready, False)
            E = every[0]
        return E[win_ok][-need:], need

    def _series(self, ready: int, m: int, twins: bool
                ) -> tuple[FloatArray, FloatArray, FloatArray, tuple[FloatArray, FloatArray], BoolArray, BoolArray]:
        """The last ``m`` of the ``ready`` usable samples: stamps, shapes, poses, predicted rates and what to trust.

        ``R`` (versions, m, nj) and ``P`` (versions, m, 3): the data only, or with its noisy twins
        (``twins``); ``split`` their predicted (ξ, ṙ_p) per interval; ``shape_ok`` (m − 1,) the
        intervals neither across nor next to a gap (nor near a singular shape), ``pose_ok`` (m,)
        the samples whose pose was read between trusted pose samples.
        """
        last = list(self._hist)[:ready][-m:]
        m = len(last)
        versions = slice(None) if twins else slice(0, 1)
        t = np.array([h.t for h in last])
        R = np.array([h.r[versions] for h in last]).transpose(1, 0, 2)  # (versions, m, nj)
        P = np.array([h.pose[versions] for h in last]).transpose(1, 0, 2)
        rates = np.array([x[versions] for x in list(self._rates)[ready - m + 1:ready]]).transpose(1, 0, 2)
        replays = list(self._replays)[ready - m + 1:ready]
        gap = np.array([rep is None or rep.stiff or rep.lost for rep in replays])
        shape_ok = ~gap  # an interval next to a gap has a bend taken from across it
        shape_ok[1:] &= ~gap[:-1]
        shape_ok[:-1] &= ~gap[1:]
        pose_ok = np.array([bool(h.pose_ok[0]) for h in last])
        return t, R, P, (rates[..., :3], rates[..., 3:]), shape_ok, pose_ok

    def _coherent(self, ready: int) -> FloatArray:
        """The phase-coherent scores over the last ``coherent_cycles`` cycles at hand, per channel.

        Each channel's :func:`coherent_statistic`; on the body channels at least the
        :func:`lag_statistic` of them together (kept, with its lag, in :attr:`lag`).  On a time base
        of grid points (:attr:`stamped_late`) the misfit its own uncertainty can make is taken out
        first, within bounds (:func:`time_base_misfit`).
        """
        cfg = self.config
        m = cfg.coherent_cycles * self._spc + 1
        t, R, P, split, shape_ok, pose_ok = self._series(ready, m, False)
        e1 = equation_residuals(self.system, t, R, P, 1, split)[0]
        nb = len(self.body_channels)
        xi = split[0][0][:, :nb]
        drift = np.array(list(self._drifts)[ready - t.size + 1:ready])
        scale = np.concatenate([-drift[:, 3:], xi - drift[:, :nb]], axis=1)  # what a clock stretched by +1 leaves
        # one spectrum for all: the residuals of every channel, the predicted body velocity, the clock's misfits
        sp = _cycle_spectrum(t, shape_ok & pose_ok[:-1] & pose_ok[1:], 1.0 / cfg.gait_hz, cfg.coherent_cycles,
                             cfg.harmonics, e1, xi, scale)
        if sp is None:
            self.lag = NO_LAG
            return np.full(e1.shape[1], np.nan)
        sp = sp._replace(local=np.maximum(sp.local, self._least_local(t, sp)))
        body = slice(e1.shape[1] - nb, None)
        lag = _lag(sp, body)
        se = float(np.mean([h.clock_se for h in list(self._hist)[:ready][-t.size:]]))
        if se > 0:
            sp = time_base_misfit(sp, body, TIME_BASE_SIGMAS * se)
            excess = _lag(sp, body)
            lag = lag._replace(score=excess.score)
        score = _ratio_score(_ratio(sp), sp.noise_bins, cfg.harmonics)
        self.lag = lag
        score[body] = np.fmax(score[body], self.lag.score)
        return score

    def _least_local(self, t: FloatArray, sp: _Spectrum) -> FloatArray:
        """The bin power next to each harmonic (H, channels) of a noise at :data:`FLOOR_RELATIVE`'s floor.

        A window floor f over a span T is a white accumulated residual of variance σ² = f·T²/2;
        its increments put n·σ²·2(1 − cos θ) into a bin of phase step θ = 2π j Δt / L per
        interval (n intervals of Δt), j = kN next to harmonic k.
        """
        w = self.config.diff_window
        dt = float(np.median(np.diff(t)))
        T = w * dt
        n = int(round(sp.span / dt))
        theta = 2.0 * np.pi * sp.N * np.arange(1, sp.local.shape[0] + 1) * dt / sp.span
        return n * (self._least * T**2 / 2.0)[None, :] * (2.0 * (1.0 - np.cos(theta)))[:, None]

    @property
    def body_channels(self) -> tuple[str, ...]:
        """The body-velocity channels (the last ones), which the lag fit scores together."""
        return self.channels[len(self.system.passive):]

    def _set_levels(self, stamp: float, F: FloatArray, why: str = "") -> None:
        """Each channel's level from its F (NaN: STALE, for the reason ``why``)."""
        cfg = self.config
        old = {s.channel: s for s in self.statuses}
        out = []
        for name, f in zip(self.channels, F):
            level = STALE if not np.isfinite(f) else ERROR if f > cfg.error else WARN if f > cfg.warn else OK
            prev = old.get(name)
            since = prev.since if prev is not None and prev.level == level else stamp
            out.append(ChannelStatus(name, level, float(f), float(since), why if level == STALE else ""))
        self.statuses = tuple(out)
        self.updated += 1
        rec = self.record
        lag = rec.lag
        if np.isfinite(self.lag.score) and (lag is None or self.lag.score >= lag.score):
            lag = self.lag
        self.record = MonitorRecord(tuple(c.seen(s, stamp) for c, s in zip(rec.channels, out)),
                                    stamp if rec.first_report is None else rec.first_report, stamp, self.updated, lag,
                                    self._snapped_from, self.unconfirmed)
        if all(s.level == OK for s in out):
            self._armed = True
        self._maybe_request(stamp)

    def _maybe_request(self, stamp: float) -> None:
        errors = [s for s in self.statuses if s.level == ERROR]
        if not self._armed or not errors:
            return
        since = min(s.since for s in errors)
        n = self.config.persist_cycles * self._spc
        if stamp - since < self.config.persist_cycles / self.config.gait_hz - 0.5 / self.config.rate:
            return
        t, r, pose = self.samples(n)
        if t.size < n:
            return
        names = self.names
        rec = Recording(t=t, r=r, joint_names=names,
                        actuated=tuple(names[i] for i in self.system.actuated),
                        passive=tuple(names[i] for i in self.system.passive),
                        pose_t=t, pose=pose, system=self.system.name, gait_hz=self.config.gait_hz)
        self._request = DiagnosisRequest(rec, tuple(s.channel for s in errors), since)
        self._armed = False

    def take_request(self) -> DiagnosisRequest | None:
        """The pending diagnosis request (then cleared), or None."""
        req, self._request = self._request, None
        return req

    @property
    def last_stamp(self) -> float:
        """Stamp of the newest paired sample, s (nan before the first)."""
        return self._hist[-1].t if self._hist else math.nan

    @property
    def worst(self) -> int:
        """Worst level over the channels (:data:`SEVERITY`; OK before the first update)."""
        out = OK
        for s in self.statuses:
            out = worse(out, s.level)
        return out


# ------------------------------------------------------------------ diagnosis worker
def diagnosis_json(request: DiagnosisRequest, model: ChainModel,
                   config: DiagnoseConfig = DiagnoseConfig()) -> str:
    """Diagnose a request's window; the report's JSON (``suds diagnose --json`` schema) plus ``monitor``.

    ``monitor`` holds the window (first and last stamp, cycles), the channels in ERROR and since when.
    """
    from suds_ros.core.diagnosis.pipeline import diagnose

    rec = request.recording
    report = diagnose(rec, model, config)
    out = report.to_dict()
    out["monitor"] = {"window": [float(rec.t[0]), float(rec.t[-1])],
                      "cycles": int(round((rec.t[-1] - rec.t[0]) * (rec.gait_hz or 1.0))),
                      "channels": list(request.channels), "since": float(request.since)}
    return json_text.dumps(out)


class DiagnosisWorker:
    """Run :func:`diagnosis_json` in one separate process (spawned: safe next to ROS threads).

    :meth:`submit` returns False while a diagnosis is still running (the request is dropped:
    the monitor asks again in the next ERROR episode); :meth:`poll` returns finished results
    as ``(json text or None, error text or None)``.
    """

    def __init__(self, model: ChainModel, config: DiagnoseConfig = DiagnoseConfig()) -> None:
        self.model = model
        self.config = config
        self._pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"))
        self._running: Future[str] | None = None

    @property
    def busy(self) -> bool:
        return self._running is not None and not self._running.done()

    def submit(self, request: DiagnosisRequest) -> bool:
        if self.busy:
            return False
        self._running = self._pool.submit(diagnosis_json, request, self.model, self.config)
        return True

    def poll(self) -> tuple[str | None, str | None] | None:
        fut = self._running
        if fut is None or not fut.done():
            return None
        self._running = None
        exc = fut.exception()
        if exc is not None:
            return None, f"{type(exc).__name__}: {exc}"
        return fut.result(), None

    def close(self) -> None:
        self._pool.shutdown(wait=False, cancel_futures=True)


def chain_model(system: SudsSystem) -> ChainModel | None:
    """The :class:`ChainModel` of an RFT chain system (None for systems the diagnosis cannot take)."""
    model: Any = getattr(system, "model", None)
    return model if isinstance(model, ChainModel) else None


# ------------------------------------------------------------------ offline
def recording_config(rec: Recording, gait_hz: float | None = None, **overrides: Any) -> MonitorConfig:
    """The :class:`MonitorConfig` of a recording: its shape rate and gait frequency.

    The rate is the step of the grid fitted to the shape stamps (:func:`fit_grid`; the stream's
    period from its intervals alone reads 1 % long with 2 ms of stamp jitter and a few lost
    messages, 99 samples a cycle for 100), rounded to a whole number of samples per cycle.
    ``gait_hz``: the recording's when None (then 1 Hz if it has none).  ``overrides``: other
    settings.
    """
    f = gait_hz or rec.gait_hz or 1.0
    if rec.t.size < 2:
        raise SudsDataError(f"recording has {rec.t.size} shape sample(s); the monitor needs a stream",
                            code=TOO_LITTLE_DATA)
    spc = samples_per_cycle(fit_grid(rec.t - rec.t[0], rec.dt)[2], f)
    return MonitorConfig(gait_hz=f, rate=spc * f, **overrides)


def feed_recording(mon: MismatchMonitor, rec: Recording) -> None:
    """Feed ``rec``'s two streams to ``mon`` as the node would receive them, then :meth:`~MismatchMonitor.flush`.

    The streams are merged in stamp order (a pose before a shape sample of the same stamp).
    """
    names = rec.joint_names
    shapes = ((float(t), 1, k) for k, t in enumerate(rec.t))
    poses = ((float(t), 0, k) for k, t in enumerate(rec.pose_t))
    for _, kind, k in heapq.merge(poses, shapes):
        if kind:
            mon.on_shape(rec.t[k], names, rec.r[k])
        else:
            mon.on_pose(rec.pose_t[k], *rec.pose[k])
    mon.flush()


def monitor_recording(rec: Recording, system: SudsSystem, config: MonitorConfig | None = None) -> MonitorRecord:
    """Replay a recording through a :class:`MismatchMonitor`, as the live node would see it.

    The shape and pose streams are fed through :meth:`MismatchMonitor.on_shape` /
    :meth:`MismatchMonitor.on_pose` by :func:`feed_recording`.  ``config``: :func:`recording_config`
    when None.

    Raises
    ------
    SudsDataError
        (code ``too_little_data``) when the recording ends before the monitor's first report.
    """
    cfg = recording_config(rec) if config is None else config
    mon = MismatchMonitor(system, cfg)
    feed_recording(mon, rec)
    if mon.record.first_report is None:
        need = cfg.first_report_samples
        late = (f"; {mon.unconfirmed} shape samples were left out while the count of the stream's grid stage "
                f"was unconfirmed (heavy stamp jitter), and the monitor started afresh after them with "
                f"{len(mon._hist)}" if mon.unconfirmed else "")
        raise SudsDataError(
            f"recording gave {mon.paired} paired samples ({mon.paired / cfg.samples_per_cycle:.2f} gait cycles "
            f"at {cfg.gait_hz:g} Hz){late}; the monitor reports after {need} ({cfg.floor_cycles:g} cycles)",
            code=TOO_LITTLE_DATA)
    return mon.record
