"""Live mismatch monitor: is the robot still the simulator?  No ROS; the ``monitor`` node adapts it.

Residual (equation error of the nominal physics, no integration)
----------------------------------------------------------------
Paired samples k (shape r_k incl. passive joints, pose g_k at the same stamp) give intervals
k → k+1 with midpoint shape r̄ and actuated rate ṙ_a = Δr_a/Δt (exact for a servo set-point
stream).  The nominal system predicts the passive rates and the body velocity on each interval
(``system.velocities``).  Over a sliding window of ``diff_window`` samples (enough to beat the
differencing noise) the monitor compares, per channel,

* passive joint j: the measured mean rate (r_j[k+w] − r_j[k]) / T with the time average of the
  predicted ṙ_j (rad/s);
* ``xi_x``, ``xi_y``, ``xi_theta``: the measured body velocity log(g_k⁻¹ g_{k+w}) / T with the
  composition of the predicted interval velocities (the same SE(2) estimator on both sides).

Noise floor (from the data's high-frequency content)
----------------------------------------------------
The raw signals cannot give it directly (the actuated drive is rough: its servo set-points carry a
random perturbation whose fourth differences dwarf the sensor noise), but the one-interval
residual can: its noise is a first difference of white noise m_k (each signal's sensor noise,
combined as the physics combines them), so the accumulated residual S_k = Σ e1_i Δt_i is m_k
plus whatever the model misses — smooth, or kinked at a few stick-slip samples.  Its fourth
difference keeps only m: σ_m = 1.4826·MAD(Δ⁴S)/√70 over the last ``floor_cycles`` cycles, and
a window of span T carries the noise power 2σ_m²/T² (:func:`residual_floor`).

Calibration
-----------
The interval equation error is not exactly zero for an exact model: with stiff passive joints
(swimmer9 relaxes at ~135 1/s, 1.35 per 10 ms sample) the midpoint rule misses the motion inside
an interval.  That discretisation error is measured once, over the first
``calibration_cycles`` cycles (assumed nominal), as the mean excess of the residual power over
the noise floor (clipped at 0), and added to the floor afterwards.  No status is reported
before.  (A robot that is already mismatched when the monitor starts is therefore partly
absorbed: start the monitor on a robot known to be nominal, or set ``calibration_cycles`` to 0
for systems the midpoint rule resolves, such as purcell3, where the excess is ≈ 0.)

Statistic and levels
--------------------
Every ``update_every`` samples, per channel F = mean(residual²) / (floor + calibrated excess)
over the last ``window_cycles`` gait cycles (≈ 1 when the nominal physics holds; a systematic
error adds its power on top).  Level OK (F ≤ ``warn``), WARN (``warn`` < F ≤ ``error``), ERROR (F > ``error``),
``since`` = the stamp at which the channel entered its level.  The thresholds are calibrated so
that nominal 60-cycle runs never alarm: purcell3 stays OK (F ≤ 2.2 over seeds), swimmer9 below
ERROR (F ≤ 3.8; the per-cycle spread of its discretisation error) —
``test/unit/diagnosis/test_monitor.py``.

Diagnosis
---------
When some channel has been in ERROR for ``persist_cycles`` gait cycles the monitor hands out a
:class:`DiagnosisRequest`: the last ``persist_cycles`` whole cycles (all inside the ERROR
episode, so after the change) as a :class:`~suds_ros.core.recording.Recording`.  One request per
episode; the episode ends when every channel is back to OK.  :class:`DiagnosisWorker` runs
:func:`~suds_ros.core.diagnosis.pipeline.diagnose` in a separate process so the caller keeps up
with the stream.
"""

from __future__ import annotations

import json
import math
import multiprocessing
from collections import deque
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from suds_ros.core import se2
from suds_ros.core._typing import FloatArray
from suds_ros.core.config import check_settings, setting
from suds_ros.core.diagnosis.report import BODY, DiagnoseConfig
from suds_ros.core.errors import SudsConfigError
from suds_ros.core.physics.rft import ChainModel
from suds_ros.core.physics.system import SudsSystem
from suds_ros.core.recording import Recording, samples_per_cycle

OK, WARN, ERROR = 0, 1, 2
LEVEL_NAMES = ("OK", "WARN", "ERROR")


@dataclass(frozen=True)
class MonitorConfig:
    """Settings of :class:`MismatchMonitor` (rates and windows in samples or gait cycles).

    Parameters
    ----------
    gait_hz : float
        Gait frequency, Hz (cycles are counted with it).
    rate : float
        Nominal sample rate, Hz; ``rate / gait_hz`` samples per cycle.
    diff_window : int
        Samples per residual window (the velocity differences span this many intervals).
    window_cycles : float
        Gait cycles over which the mean-square residual is taken.
    floor_cycles : float
        Gait cycles of data whose residuals' fourth differences give the noise floor.
    calibration_cycles : float
        Gait cycles, after the first full windows, over which the nominal model's own
        discretisation error is measured (the excess of the residual power over the noise floor,
        averaged; see the module docstring).  0 skips it (pure noise floor).
    warn, error : float
        Thresholds on F = mean-square residual / (noise floor + calibrated excess) (error > warn > 1).
    persist_cycles : int
        Cycles a channel must stay in ERROR before the recent window is diagnosed (≥ 4:
        the diagnosis trains on half of it and scores on the other half).
    history_cycles : float
        Cycles of paired samples kept (≥ ``persist_cycles`` and the statistic's windows).
    update_every : int
        Paired samples between two updates of the statistics.
    """

    gait_hz: float = setting(1.0, "gait frequency, Hz", gt=0.0, le=1000.0)
    rate: float = setting(100.0, "sample rate of shape and pose, Hz (rate / gait_hz samples per cycle)",
                          gt=0.0, le=100000.0)
    diff_window: int = setting(10, "samples per residual window", ge=1, le=10000)
    window_cycles: float = setting(1.0, "gait cycles of the mean-square residual", gt=0.0, le=100.0)
    floor_cycles: float = setting(3.0, "gait cycles of data for the noise floor", gt=0.0, le=100.0)
    calibration_cycles: float = setting(3.0, "cycles (assumed nominal) measuring the model's own "
                                             "discretisation error; 0: none", ge=0.0, le=1000.0)
    warn: float = setting(4.0, "WARN when F = mean-square residual / floor exceeds this", gt=1.0, le=1e9)
    error: float = setting(8.0, "ERROR when F exceeds this (> warn)", gt=1.0, le=1e9)
    persist_cycles: int = setting(6, "cycles in ERROR before the recent window is diagnosed (≥ 4)", ge=4)
    history_cycles: float = setting(12.0, "cycles of samples kept", ge=1.0, le=10000.0)
    update_every: int = setting(10, "samples between statistics updates (and suds/mismatch messages)",
                                ge=1, le=100000)

    def __post_init__(self) -> None:
        check_settings(self)
        if not self.error > self.warn:
            raise SudsConfigError(f"`error`: expected a threshold > warn ({self.warn}), got {self.error!r}")
        if not self.history_cycles >= max(self.persist_cycles, self.window_cycles, self.floor_cycles):
            raise SudsConfigError(f"`history_cycles`: expected ≥ persist_cycles, window_cycles and floor_cycles "
                                  f"({self.persist_cycles}, {self.window_cycles}, {self.floor_cycles}), "
                                  f"got {self.history_cycles!r}")
        spc = self.rate / self.gait_hz
        if abs(spc - round(spc)) > 1e-9 * spc or round(spc) < 8:
            raise SudsConfigError(f"`rate`: rate / gait_hz must be an integer ≥ 8 (samples per cycle), "
                                  f"got {self.rate!r} / {self.gait_hz!r} = {spc:.6g}")

    @property
    def samples_per_cycle(self) -> int:
        """Samples per gait cycle."""
        return samples_per_cycle(1.0 / self.rate, self.gait_hz)


class ChannelStatus(NamedTuple):
    """The state of one channel: level (0 OK, 1 WARN, 2 ERROR), F, since when (stamp, s)."""

    channel: str
    level: int
    statistic: float
    since: float

    @property
    def level_name(self) -> str:
        return LEVEL_NAMES[self.level]


@dataclass(frozen=True)
class DiagnosisRequest:
    """A recent window to diagnose: the recording, the channels in ERROR and since when."""

    recording: Recording
    channels: tuple[str, ...]
    since: float


# ------------------------------------------------------------------ residuals
def channel_names(system: SudsSystem) -> tuple[str, ...]:
    """Monitored channels: the passive joints, then the body velocity (x only for 1-D swimmers)."""
    body = BODY if getattr(system, "planar", True) else BODY[:1]
    return tuple(system.joint_names[j] for j in system.passive) + body


def interval_rates(system: SudsSystem, t: FloatArray, r: FloatArray,
                   pose: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Predicted body velocity (n − 1, 3) and passive rates (n − 1, np) on each sample interval.

    Midpoint shape and heading, actuated rate Δr_a/Δt: the nominal physics, no integration.
    """
    act = list(system.actuated)
    dt = np.diff(t)
    mid = 0.5 * (r[1:] + r[:-1])
    yaw = 0.5 * (pose[1:, 2] + pose[:-1, 2])
    return system.velocities(mid, np.diff(r[:, act], axis=0) / dt[:, None], yaw=yaw)


def equation_residuals(system: SudsSystem, t: FloatArray, r: FloatArray, pose: FloatArray,
                       w: int, rates: tuple[FloatArray, FloatArray] | None = None) -> FloatArray:
    """Measured minus predicted rates over every window of ``w`` intervals, shape (n − w, channels).

    ``t`` (n,) stamps, ``r`` (n, nj) joints in the system's order, ``pose`` (n, 3) at the same
    stamps (yaw unwrapped); ``rates``: :func:`interval_rates` of the same data, if at hand.
    Columns as :func:`channel_names`.
    """
    pas = list(system.passive)
    xi, rdot_p = interval_rates(system, t, r, pose) if rates is None else rates
    dt = np.diff(t)
    span = t[w:] - t[:-w]
    nwin = t.size - w
    cum = np.concatenate([np.zeros((1, len(pas))), np.cumsum(rdot_p * dt[:, None], axis=0)])
    pred_p = (cum[w:] - cum[:-w]) / span[:, None]
    meas_p = (r[w:, pas] - r[:-w, pas]) / span[:, None]
    g = np.zeros((nwin, 3))
    for j in range(w):  # compose the predicted interval motions of each window
        g = se2.exp_step(g, xi[j:j + nwin] * dt[j:j + nwin, None])
    pred_xi = se2.log(g) / span[:, None]
    meas_xi = se2.log(se2.relative(pose[:-w], pose[w:])) / span[:, None]
    nb = len(channel_names(system)) - len(pas)
    return np.concatenate([meas_p - pred_p, (meas_xi - pred_xi)[:, :nb]], axis=1)


def residual_floor(system: SudsSystem, t: FloatArray, r: FloatArray, pose: FloatArray,
                   w: int) -> tuple[FloatArray, FloatArray]:
    """Residuals (n − w, channels) over windows of ``w`` intervals and each channel's noise power.

    The noise of a windowed residual is (m_{k+w} − m_k)/T for a white series m (the measurement
    noise of the channel's signals, combined as the physics combines them); m is the white part
    of the accumulated one-interval residual S_k = Σ_{i<k} e1_i Δt_i, whose fourth difference
    keeps only it: σ_m = 1.4826·MAD(Δ⁴S)/√70, floor = 2σ_m²/T² (T the median window span).
    """
    rates = interval_rates(system, t, r, pose)
    e = equation_residuals(system, t, r, pose, w, rates)
    e1 = equation_residuals(system, t, r, pose, 1, rates)
    S = np.cumsum(e1 * np.diff(t)[:, None], axis=0)
    d4 = S[4:] - 4 * S[3:-1] + 6 * S[2:-2] - 4 * S[1:-3] + S[:-4]
    sig = 1.4826 * np.median(np.abs(d4 - np.median(d4, axis=0)), axis=0) / math.sqrt(70.0)
    T = float(np.median(t[w:] - t[:-w]))
    return e, 2.0 * sig**2 / T**2


# ------------------------------------------------------------------ the monitor
class MismatchMonitor:
    """Pair shape and pose by stamps, track per-channel F against the noise floor, request diagnoses.

    Feed :meth:`on_shape` (stamp, names, positions — joints matched by name, extra joints
    ignored) and :meth:`on_pose` (stamp, x, y, yaw) in any interleaving; a shape sample is
    paired once the pose stream has reached its stamp (pose interpolated linearly, yaw
    unwrapped), never by arrival time.  :attr:`statuses` is the current state,
    :meth:`take_request` the pending diagnosis request (at most one per ERROR episode).
    """

    def __init__(self, system: SudsSystem, config: MonitorConfig = MonitorConfig()) -> None:
        self.system = system
        self.config = config
        self.channels = channel_names(system)
        self.names = tuple(system.joint_names)
        spc = config.samples_per_cycle
        self._spc = spc
        keep = int(math.ceil(config.history_cycles * spc)) + config.diff_window + 1
        self._hist: deque[tuple[float, FloatArray, FloatArray]] = deque(maxlen=keep)
        # samples waiting for the other stream (bounded: a stream that stops cannot fill memory)
        self._shapes: deque[tuple[float, FloatArray]] = deque(maxlen=keep)
        self._poses: deque[tuple[float, FloatArray]] = deque(maxlen=keep)
        self._since_update = 0
        self.statuses: tuple[ChannelStatus, ...] = ()
        self.updated = 0  # number of statistic updates
        self.paired = 0
        self.skipped = 0
        self._armed = True
        self._request: DiagnosisRequest | None = None
        self._calib_left = int(round(config.calibration_cycles * spc / config.update_every))
        self._excess: list[FloatArray] = []
        self.bias = np.zeros(len(self.channels))  # calibrated discretisation error power per channel

    # -------------------------------------------------------- input
    def on_shape(self, stamp: float, names: tuple[str, ...] | list[str], position: FloatArray) -> int:
        """Queue a shape sample; returns the number of samples paired now."""
        index = {n: i for i, n in enumerate(names)}
        pos = np.asarray(position, dtype=float)
        if any(n not in index for n in self.names) or pos.size != len(names):
            self.skipped += 1
            return 0
        r = pos[[index[n] for n in self.names]]
        if not np.all(np.isfinite(r)) or (self._shapes and stamp <= self._shapes[-1][0]) or (
                self._hist and stamp <= self._hist[-1][0]):
            self.skipped += 1
            return 0
        self._shapes.append((float(stamp), r))
        return self._pair()

    def on_pose(self, stamp: float, x: float, y: float, yaw: float) -> int:
        """Queue a pose sample; returns the number of samples paired now."""
        p = np.array([x, y, yaw], dtype=float)
        if not np.all(np.isfinite(p)) or (self._poses and stamp <= self._poses[-1][0]):
            self.skipped += 1
            return 0
        if self._poses:  # unwrap yaw against the previous pose
            prev = self._poses[-1][1][2]
            p[2] = prev + (p[2] - prev + math.pi) % (2 * math.pi) - math.pi
        self._poses.append((float(stamp), p))
        return self._pair()

    def _pair(self) -> int:
        n = 0
        while self._shapes and self._poses and self._poses[-1][0] >= self._shapes[0][0]:
            t, r = self._shapes.popleft()
            while len(self._poses) > 1 and self._poses[1][0] <= t:
                self._poses.popleft()
            t0, p0 = self._poses[0]
            if t0 > t:  # before the first pose: cannot be paired
                self.skipped += 1
                continue
            if t0 == t or len(self._poses) == 1:
                pose = p0
            else:
                t1, p1 = self._poses[1]
                pose = p0 + (p1 - p0) * (t - t0) / (t1 - t0)
            self._add(t, r, pose)
            n += 1
        return n

    def add_pair(self, stamp: float, r: FloatArray, pose: FloatArray) -> None:
        """Add one already paired sample (joints in the system's order, pose x, y, unwrapped yaw)."""
        self._add(float(stamp), np.asarray(r, dtype=float), np.asarray(pose, dtype=float))

    def _add(self, t: float, r: FloatArray, pose: FloatArray) -> None:
        self._hist.append((t, r, pose))
        self.paired += 1
        self._since_update += 1
        if self._since_update >= self.config.update_every:
            self._since_update = 0
            self._update()

    # -------------------------------------------------------- statistics
    def _arrays(self, n: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        last = list(self._hist)[-n:]
        return (np.array([h[0] for h in last]), np.array([h[1] for h in last]),
                np.array([h[2] for h in last]))

    def _update(self) -> None:
        cfg = self.config
        w = cfg.diff_window
        n_stat = int(round(cfg.window_cycles * self._spc)) + w
        n_floor = int(round(cfg.floor_cycles * self._spc))
        n = max(n_stat, n_floor)
        if len(self._hist) < n:
            return
        t, r, pose = self._arrays(n)
        e, floor = residual_floor(self.system, t, r, pose, w)
        ms = np.mean(e[-(n_stat - w):] ** 2, axis=0)
        if self._calib_left > 0:
            self._excess.append(ms - floor)
            self._calib_left -= 1
            if self._calib_left == 0:
                self.bias = np.maximum(np.mean(self._excess, axis=0), 0.0)
            return
        ref = floor + self.bias
        F = np.where(ref > 0, ms / np.where(ref > 0, ref, 1.0), 0.0)
        self._set_levels(t[-1], F)

    def _set_levels(self, stamp: float, F: FloatArray) -> None:
        cfg = self.config
        old = {s.channel: s for s in self.statuses}
        out = []
        for name, f in zip(self.channels, F):
            level = ERROR if f > cfg.error else WARN if f > cfg.warn else OK
            prev = old.get(name)
            since = prev.since if prev is not None and prev.level == level else stamp
            out.append(ChannelStatus(name, level, float(f), float(since)))
        self.statuses = tuple(out)
        self.updated += 1
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
        if len(self._hist) < n:
            return
        t, r, pose = self._arrays(n)
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
        return self._hist[-1][0] if self._hist else math.nan

    @property
    def worst(self) -> int:
        """Highest level over the channels (OK before the first update)."""
        return max((s.level for s in self.statuses), default=OK)


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
    return json.dumps(out)


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
