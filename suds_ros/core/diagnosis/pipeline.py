"""Simulator-versus-recording diagnosis: locate, name, fit and show a physical mismatch.

Method (as implemented)
-----------------------
Data.  Cycles are counted with the recording's ``gait_hz`` (default 1 Hz) from the first stamp;
the first half of the whole cycles is the *training* half, the rest the *held-out* half.  Every
number in the report is computed on the held-out half.

1. Replay (output error).  The simulator is driven with the recorded actuated angles r_a
   (piecewise linear between samples, as the servo stream) from the recorded passive angles and
   pose at the start of each half (:func:`replay`; batched RK4 over independent segments, the
   pose by the same commutator-free Lie-group step as :mod:`suds_ros.core.physics.sim`).  Channels: each
   passive angle r_j (rad) and the body velocity ξx, ξy (m/s), ξθ (rad/s), the latter estimated
   from the pose by the exact SE(2) logarithm of g_k⁻¹g_{k+w} over ``window`` seconds, with the
   *same* estimator applied to the simulated pose.  With ``reference=`` a simulated recording of
   the same actuated trajectory replaces the replay.

2. Locate.  The noise floor is estimated from the data, not assumed: the fourth difference of the
   replay residual removes everything smooth (gait-correlated errors) and keeps the white part
   (measurement noise plus the noise the recorded r_a injects into the replay); a median-absolute
   estimate of its spread over √70 gives σ per channel (pose σ for ξ, scaled by √2/(w·dt)).
   Per channel the statistic is F = mean(residual²) / floor² on the held-out half (≈ 1 when the
   simulator matches); the channel is located if F > ``f_threshold``.  Phase intervals: the held-out
   residual is averaged in ``phase_bins`` bins per cycle, cycles serve as replicates, and bins whose
   mean is significant (Bonferroni t-test across cycles) are merged into ranges [a, b] of the gait
   phase in rad: the phaser's phase (:class:`~suds_ros.core.phase.phaser.Phaser`) of the recorded shape,
   shared by the replay (same r_a), zero at the upward crossing of the shape's first principal
   component; the clock phase 2π·gait_hz·(t − t0) only if the phaser fails (noted in the report).  Conditions (sign of ṙ_p, |r_p − rest|, heading, position, lag of
   the cross-correlation with the recorded signals) and the paper's structure (SUDS coefficients
   C, C_r, B, B_r identified from the recording and from the replay on the same gait, compared
   phase by phase against a split-half noise scale) are attached to the report for the human
   summary.

3. Name (equation error).  On interval data (sample k → k+1, midpoint shape, ṙ = Δr/Δt, which is
   exact for the piecewise-linear servo stream) the still-fluid RFT metric gives, without
   integrating anything, the torque each passive joint's unmodelled effects must supply,
   τ_res = (D q̇)_p − τ_spring, and the body velocity the shape motion implies.  Both are averaged
   over windows of ``eq_window`` samples (the SE(2) displacements composed, so the recorded and
   predicted body velocities go through one estimator).  Every catalogue candidate — each joint
   effect on each passive joint, and the global ones — is a parametric modification of these
   residuals evaluated with the physics (Coulomb's set-valued stick/slip as a dead zone; the drag
   ratio by re-evaluating the metric; the time offset by re-sampling the pose stream; the flow by
   R(−yaw)U).  Each candidate and each pair of the leading candidates is fitted on the training
   half (weighted least squares, weights re-estimated once) and scored on the held-out half by the
   Gaussian profile log-likelihood gain Σ_c (n_eff/2)·log(RSS0_c/RSS_c) over channels, minus a BIC
   penalty (p/2)·log n_eff.  Candidates within ``confound_margin`` of the winner are reported as
   confounded; a pair is preferred to the best single only if it adds a clear gain.

4. Fit and show (output error).  The chosen effect(s) are refined inside the simulator:
   least squares of the noise-floor-weighted replay residuals over short training segments
   (scipy ``least_squares``, finite-difference Jacobian), over one-cycle segments spread over the
   training half; standard errors from the cluster-robust sandwich (clusters = segments) with CR1
   and t(B − p) small-sample factors, floored by the model-based error (calibrated against
   seed-to-seed spread in the tests).  The whole-recording replays run each half as 3-cycle pieces
   in one batch, each after a 3 s warm-up from the recorded state (equal to the sequential replay
   to < 1e-4 rad).  The fitted model is replayed on the held-out
   half; held-out RMS per channel before/after, and improvement = 1 − Σ e_after / Σ e_before over
   the located channels with e = √max(F − 1, 0) the RMS of the residual in excess of the noise
   floor, in floor units (:func:`excess_improvement`): the fraction of the mismatch removed.  (The
   plain RMS ratio would be capped by the noise, which no model removes, on weakly affected
   channels.)  A mismatch whose best explanation leaves a significant excess (more than
   ``unexplained_fraction`` of the excess residual power, in total or on any located channel) is
   reported as unexplained, with its location kept; if that fit also improves the held-out
   residual by less than half, no effect is reported (the attempt is in ``notes``).
"""

from __future__ import annotations

import itertools
import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.optimize
import scipy.stats

from suds_ros.core import se2
from suds_ros.core._typing import FloatArray
from suds_ros.core.physics.effects import EFFECTS, apply_effects
from suds_ros.core.errors import SudsConfigError, SudsDataError, SudsPhaseError
from suds_ros.core.recording import Recording
from suds_ros.core.physics.rft import ChainModel, RFTChain
from suds_ros.core.physics.sim import auto_substeps, se2_exp_step

BODY = ("xi_x", "xi_y", "xi_theta")
SPEC_IDS = (
    "joint_coulomb_friction",
    "joint_viscous_damping",
    "spring_rest_offset",
    "spring_nonlinearity",
    "stiffness_to_drag_error",
    "drag_anisotropy_error",
    "background_flow",
    "sensor_time_offset",
)


# =============================================================================== config / report
@dataclass(frozen=True)
class DiagnoseConfig:
    """Settings of :func:`diagnose`.

    Parameters
    ----------
    window : float
        Body-velocity estimation window, s (pose log over this span).
    eq_window : int
        Samples averaged per equation-error window.
    f_threshold : float
        A channel is located when its held-out residual power exceeds this multiple of the noise
        floor power.
    phase_bins : int
        Phase bins per cycle for the phase-interval test.
    phase_alpha : float
        Family-wise significance of the phase-bin test (Bonferroni over bins).
    top_pairs : int
        Number of leading single candidates combined into pairs.
    confound_margin : float
        Held-out log-likelihood margin (nats) within which candidates are called confounded;
        the margin grows as ``confound_rel`` × the winner's gain.
    confound_rel : float
        Relative part of the confounding margin.
    pair_rel : float
        A pair replaces the best single candidate only if it adds more than this fraction of the
        single's gain (and more than the BIC penalty).
    unexplained_fraction : float
        Maximum fraction of the excess residual power (over the floor) that may remain after the
        fit for the mismatch to count as explained.
    segment_cycles : int
        Cycles per segment in the output-error refinement.
    refine_cycles : int
        Training cycles (spread over the training half) used by the output-error refinement.
    refine_nfev : int
        Maximum simulator evaluations per refined parameter (least-squares budget).
    member_z : float
        After refining a pair, a member whose parameters all lie within ``member_z`` standard
        errors of their neutral values is dropped (the pair falls back to the other member).
    substeps : int or None
        RK4 steps per sample interval; None picks them from the stiffest passive mode.
    replay_chunk : float
        The whole-recording replays run each half as independent pieces of this many cycles in
        one batch (0: each half in one piece, sequentially — slow).
    replay_warm : float
        Seconds of warm-up simulated before each piece (from the recorded state) and discarded;
        the passive joints forget their initial state well within it.
    """

    window: float = 0.1
    eq_window: int = 5
    f_threshold: float = 2.0
    phase_bins: int = 20
    phase_alpha: float = 0.01
    top_pairs: int = 5
    confound_margin: float = 3.0
    confound_rel: float = 0.01
    pair_rel: float = 0.05
    unexplained_fraction: float = 0.25
    segment_cycles: int = 1
    refine_cycles: int = 30
    refine_nfev: int = 5
    member_z: float = 4.0
    substeps: int | None = None
    replay_chunk: float = 3.0
    replay_warm: float = 3.0

    def __post_init__(self) -> None:
        checks = [
            ("window", self.window > 0),
            ("eq_window", self.eq_window >= 1),
            ("f_threshold", self.f_threshold > 1),
            ("phase_bins", self.phase_bins >= 4),
            ("phase_alpha", 0 < self.phase_alpha < 1),
            ("top_pairs", self.top_pairs >= 0),
            ("confound_margin", self.confound_margin >= 0),
            ("confound_rel", self.confound_rel >= 0),
            ("pair_rel", self.pair_rel >= 0),
            ("unexplained_fraction", 0 < self.unexplained_fraction < 1),
            ("segment_cycles", self.segment_cycles >= 1),
            ("refine_nfev", self.refine_nfev >= 1),
            ("refine_cycles", self.refine_cycles >= 1),
            ("member_z", self.member_z >= 0),
            ("substeps", self.substeps is None or self.substeps >= 1),
            ("replay_chunk", self.replay_chunk >= 0),
            ("replay_warm", self.replay_warm >= 0),
        ]
        for name, ok in checks:
            if not ok:
                raise SudsConfigError(f"`{name}`: value {getattr(self, name)!r} is out of range")


@dataclass(frozen=True)
class Located:
    """A channel whose held-out residual exceeds the noise floor.

    ``statistic`` is F = mean(residual²)/floor²; ``phase_ranges`` are [a, b] in rad (0 … 2π).
    """

    channel: str
    phase_ranges: tuple[tuple[float, float], ...]
    statistic: float


@dataclass(frozen=True)
class FittedEffect:
    """A catalogue effect with fitted parameters and standard errors."""

    name: str
    target: str | None
    parameters: Mapping[str, float]
    stderr: Mapping[str, float]

    def as_dict(self) -> dict[str, object]:
        return {
            "name": self.name,
            "target": self.target,
            "parameters": {k: float(v) for k, v in self.parameters.items()},
            "stderr": {k: float(v) for k, v in self.stderr.items()},
        }


@dataclass(frozen=True)
class CandidateScore:
    """Equation-error evidence for one candidate (single effect or pair)."""

    label: str
    effects: tuple[dict[str, object], ...]
    n_params: int
    gain_heldout: float
    penalty: float

    @property
    def score(self) -> float:
        return self.gain_heldout - self.penalty


@dataclass(frozen=True)
class Channels:
    """Per-channel held-out series for figures: phase (rad, wrapped), time (s), recorded,
    predicted before and after."""

    t: FloatArray
    phase: FloatArray
    recorded: FloatArray
    before: FloatArray
    after: FloatArray


@dataclass(frozen=True)
class DiagnosisReport:
    """Result of :func:`diagnose`.  ``to_json()`` gives the machine-readable schema; the other
    attributes feed the human report."""

    mismatch: bool
    located: tuple[Located, ...]
    effects: tuple[FittedEffect, ...]
    confounded_with: tuple[tuple[str, ...], ...]
    unexplained: bool
    heldout_rms_before: Mapping[str, float]
    heldout_rms_after: Mapping[str, float]
    improvement: float
    system: str = ""
    noise_floor: Mapping[str, float] = field(default_factory=dict)
    statistics: Mapping[str, float] = field(default_factory=dict)
    statistics_after: Mapping[str, float] = field(default_factory=dict)
    ranking: tuple[CandidateScore, ...] = ()
    conditions: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    coefficients: tuple[tuple[str, str, float, tuple[tuple[float, float], ...]], ...] = ()
    series: Mapping[str, Channels] = field(default_factory=dict, repr=False)
    train_cycles: int = 0
    heldout_cycles: int = 0
    timings: Mapping[str, float] = field(default_factory=dict)
    phase_source: str = "phaser"
    notes: tuple[str, ...] = ()

    @property
    def plain_rms_ratio(self) -> float | None:
        """1 − Σ RMS after / Σ RMS before over the located channels (None without a located channel).

        Unlike :attr:`improvement` it keeps the noise, which no model removes, in both sums.
        """
        before = sum(self.heldout_rms_before[l.channel] for l in self.located)
        after = sum(self.heldout_rms_after[l.channel] for l in self.located)
        return 1.0 - after / before if before > 0 else None

    def to_dict(self) -> dict[str, object]:
        """The JSON schema of ``suds diagnose --json`` (exactly these keys)."""
        return {
            "mismatch": bool(self.mismatch),
            "located": [
                {
                    "channel": loc.channel,
                    "phase_ranges": [[float(a), float(b)] for a, b in loc.phase_ranges],
                    "statistic": float(loc.statistic),
                }
                for loc in self.located
            ],
            "effects": [e.as_dict() for e in self.effects],
            "confounded_with": [list(g) for g in self.confounded_with],
            "unexplained": bool(self.unexplained),
            "fit": {
                "heldout_rms_before": {k: float(v) for k, v in self.heldout_rms_before.items()},
                "heldout_rms_after": {k: float(v) for k, v in self.heldout_rms_after.items()},
                "improvement": float(self.improvement),
            },
        }

    def to_json(self, indent: int | None = 2) -> str:
        """JSON text of :meth:`to_dict`."""
        return json.dumps(self.to_dict(), indent=indent)


# =============================================================================== data
@dataclass(frozen=True)
class _Data:
    t: FloatArray  # (n,) stamps
    r: FloatArray  # (n, nj) in model joint order
    pose: FloatArray  # (n, 3) at the shape stamps
    pose_t: FloatArray
    pose_raw: FloatArray
    dt: float
    spc: int  # samples per cycle
    n_train: int
    n_used: int
    phase: FloatArray  # (n,) rad, unwrapped (phaser's convention, or the clock as a fallback)
    act: FloatArray
    pas: FloatArray
    names: tuple[str, ...]
    phase_source: str = "phaser"
    phase_note: str = ""


def _prepare(rec: Recording, model: ChainModel) -> _Data:
    names = tuple(f"joint_{j + 1}" for j in range(model.n_joints))
    if set(rec.joint_names) != set(names):
        raise SudsDataError(
            f"recording joints {list(rec.joint_names)} do not match system {model.name!r} joints {list(names)}"
        )
    act = [names[i] for i in model.actuated]
    if set(rec.actuated) != set(act):
        raise SudsConfigError(
            f"recording's actuated joints {list(rec.actuated)} differ from system {model.name!r}'s {act}; "
            "pass --actuated/--passive or choose the matching --system"
        )
    order = [rec.joint_names.index(nm) for nm in names]
    r = rec.r[:, order]
    dt = rec.dt
    f = rec.gait_hz or 1.0
    spc = int(round(1.0 / (f * dt)))
    n_cycles = rec.n_samples // spc
    if n_cycles < 4:
        raise SudsDataError(
            f"recording has {n_cycles} whole gait cycles at {f} Hz; diagnosis needs at least 4 "
            "(half to train, half held out)"
        )
    n_train = (n_cycles // 2) * spc
    n_used = n_cycles * spc
    t = rec.t
    pose = rec.pose_at(t)
    phase, source, note = _gait_phase(r, t, f)
    return _Data(
        t=t,
        r=r,
        pose=pose,
        pose_t=rec.pose_t,
        pose_raw=rec.pose,
        dt=dt,
        spc=spc,
        n_train=n_train,
        n_used=n_used,
        phase=phase,
        act=np.asarray(model.actuated),
        pas=np.asarray(model.passive),
        names=names,
        phase_source=source,
        phase_note=note,
    )


def _gait_phase(r: FloatArray, t: FloatArray, gait_hz: float) -> tuple[FloatArray, str, str]:
    """Unwrapped gait phase (rad) of every sample from the recorded shape data alone.

    The phaser (:class:`~suds_ros.core.phase.phaser.Phaser`) is fitted on the recording's joint angles
    (all joints; the simulator replay shares the recorded r_a, so the same phase serves both).
    Its zero is the upward mean crossing of the first principal component of the shape.  When the
    phaser fails (fewer than 3 detectable cycles, degenerate data) the clock phase
    2π·gait_hz·(t − t0) is used instead and the returned note says so.
    """
    from suds_ros.core.phase.phaser import Phaser

    try:
        ph = np.asarray(Phaser().fit_transform(r), dtype=float)
        if ph.shape != t.shape or not np.all(np.isfinite(ph)):
            raise SudsPhaseError("phaser returned a non-finite phase")
        return ph, "phaser", ""
    except (SudsPhaseError, SudsDataError, np.linalg.LinAlgError, ValueError) as exc:
        note = (
            f"phaser failed ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__}); "
            f"phase ranges use the clock phase 2π·{gait_hz:g} Hz·(t − t0) instead"
        )
        return 2 * np.pi * gait_hz * (t - t[0]), "clock", note


# =============================================================================== replay
def integrate_segments(
    chain: RFTChain, r_a: FloatArray, r_p0: FloatArray, pose0: FloatArray, dt: float, substeps: int
) -> tuple[FloatArray, FloatArray]:
    """Integrate B independent segments at once (still fluid).

    Parameters
    ----------
    chain : RFTChain
        Physics (its flow is ignored; add U·t afterwards).
    r_a : (B, m, na) float
        Actuated set-points at the samples, linearly interpolated in between.
    r_p0 : (B, np) float
        Passive angles at the first sample of each segment.
    pose0 : (B, 3) float
        World pose at the first sample.
    dt : float
        Sample interval, s.
    substeps : int
        RK4 steps per interval.

    Returns
    -------
    r_p : (B, m, np), pose : (B, m, 3)
    """
    B, m, na = r_a.shape
    act = np.asarray(chain.actuated)
    pas = np.asarray(chain.passive)
    nj = act.size + pas.size
    rp = np.array(r_p0, dtype=float).reshape(B, pas.size)
    pose = np.array(pose0, dtype=float).reshape(B, 3)
    RP = np.empty((B, m, pas.size))
    P = np.empty((B, m, 3))
    RP[:, 0] = rp
    P[:, 0] = pose
    full = np.empty((B, nj))
    h = dt / substeps

    def f(ra: FloatArray, rp_: FloatArray, va: FloatArray) -> tuple[FloatArray, FloatArray]:
        full[:, act] = ra
        full[:, pas] = rp_
        xi, rdot, _ = chain.solve(full, va)
        return xi, rdot

    for k in range(m - 1):
        va = (r_a[:, k + 1] - r_a[:, k]) / dt
        for s in range(substeps):
            ra0 = r_a[:, k] + va * (s * h)
            xi1, k1 = f(ra0, rp, va)
            xi2, k2 = f(ra0 + va * (h / 2), rp + (h / 2) * k1, va)
            xi3, k3 = f(ra0 + va * (h / 2), rp + (h / 2) * k2, va)
            xi4, k4 = f(ra0 + va * h, rp + h * k3, va)
            rp = rp + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
            pose = se2_exp_step(pose, h * (xi1 / 4 + xi2 / 6 + xi3 / 6 - xi4 / 12))
            pose = se2_exp_step(pose, h * (-xi1 / 12 + xi2 / 6 + xi3 / 6 + xi4 / 4))
        RP[:, k + 1] = rp
        P[:, k + 1] = pose
    return RP, P


def _window_xi(pose: FloatArray, w: int, dt: float) -> FloatArray:
    """Body velocity over windows of w samples, (…, m − w, 3), NaN where the pose is NaN."""
    rel = se2.relative(pose[..., :-w, :], pose[..., w:, :])
    return se2.log(rel) / (w * dt)


def _measure(
    pose: FloatArray, t_seg: FloatArray, flow: tuple[float, float], delay: float, w: int, dt: float
) -> FloatArray:
    """Simulated pose stream → windowed body velocity, with flow drift and pose-stamp delay.

    pose (B, m, 3) still-fluid poses at times t_seg (B, m) (segment-relative times start at 0).
    """
    P = pose.copy()
    tt = t_seg - t_seg[:, :1]
    if flow != (0.0, 0.0):
        P[..., 0] += flow[0] * tt
        P[..., 1] += flow[1] * tt
    if delay != 0.0:
        Q = np.full_like(P, np.nan)
        for b in range(P.shape[0]):
            ts = tt[b] - delay
            ok = (ts >= tt[b, 0] - 1e-12) & (ts <= tt[b, -1] + 1e-12)
            for c in range(3):
                Q[b, ok, c] = np.interp(ts[ok], tt[b], P[b, :, c])
        P = Q
    return _window_xi(P, w, dt)


@dataclass(frozen=True)
class _Replay:
    rp: FloatArray  # (B, m, np)
    xi: FloatArray  # (B, m − w, 3)
    pose: FloatArray  # (B, m, 3) (with flow drift, no delay)


def replay(
    model: ChainModel,
    delay: float,
    data: _Data,
    starts: Sequence[int],
    length: int,
    w: int,
    substeps: int,
) -> _Replay:
    """Replay equal-length segments [s, s + length) of the recording through ``model``."""
    idx = np.asarray(starts)[:, None] + np.arange(length)[None, :]
    chain = RFTChain(model.with_(flow=(0.0, 0.0)))
    ra = data.r[idx][:, :, data.act]
    rp0 = data.r[idx[:, 0]][:, data.pas]
    pose0 = data.pose[idx[:, 0]]
    RP, P = integrate_segments(chain, ra, rp0, pose0, data.dt, substeps)
    xi = _measure(P, data.t[idx], model.flow, delay, w, data.dt)
    tt = data.t[idx] - data.t[idx[:, :1]]
    Pf = P.copy()
    Pf[..., 0] += model.flow[0] * tt
    Pf[..., 1] += model.flow[1] * tt
    return _Replay(RP, xi, Pf)


def excess_improvement(F_before: Mapping[str, float], F_after: Mapping[str, float],
                       channels: Sequence[str]) -> float:
    """1 − Σ √max(F_after − 1, 0) / Σ √max(F_before − 1, 0) over ``channels`` (0 when none).

    ``F`` is a channel's held-out residual power over its noise-floor power, so √(F − 1) is the
    RMS of the residual beyond the noise in units of the floor: comparable across channels of
    different units, and 1 when the fit leaves only noise.
    """
    before = sum(np.sqrt(max(F_before[c] - 1.0, 0.0)) for c in channels)
    after = sum(np.sqrt(max(F_after[c] - 1.0, 0.0)) for c in channels)
    return float(1.0 - after / before) if before > 0 else 0.0


# =============================================================================== noise floor
def _mad_sigma(x: FloatArray) -> float:
    x = x[np.isfinite(x)]
    if x.size < 8:
        return float("nan")
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


def _d4(x: FloatArray, axis: int = -1) -> FloatArray:
    return np.diff(x, n=4, axis=axis)


def noise_floor(
    rec_rp: FloatArray, sim_rp: FloatArray, rec_pose: FloatArray, sim_pose: FloatArray, w: int, dt: float
) -> tuple[FloatArray, float, float]:
    """Noise floor from the white part of the replay residual.

    Arrays are per segment (B, m, ·).  Returns σ of each passive angle (np,), and the floor of
    the windowed ξ translation (m/s) and rotation (rad/s) components.
    """
    e = rec_rp - sim_rp
    sig_rp = np.array([_mad_sigma(_d4(e[..., j], axis=1).ravel()) for j in range(e.shape[-1])]) / np.sqrt(70)
    ep = rec_pose - sim_pose
    sx = _mad_sigma(_d4(ep[..., 0], axis=1).ravel())
    sy = _mad_sigma(_d4(ep[..., 1], axis=1).ravel())
    sth = _mad_sigma(_d4(ep[..., 2], axis=1).ravel())
    s_xy = np.sqrt((sx**2 + sy**2) / 2 / 70)
    s_th = sth / np.sqrt(70)
    k = np.sqrt(2) / (w * dt)
    return sig_rp, float(k * s_xy), float(k * s_th)


# =============================================================================== equation error
class _EqError:
    """Equation-error residuals of the passive torque balance and the body velocity.

    Interval i (sample k → k+1): midpoint shape r̄_i, ṙ_i = Δr/Δt (exact for the piecewise-linear
    servo stream).  Torque residuals are per interval (so Coulomb's stick/slip switching is not
    smeared); body velocities are compared over windows of w intervals (SE(2) composition).
    """

    def __init__(self, data: _Data, model: ChainModel, lo: int, hi: int, w: int) -> None:
        self.model = model
        self.w = w
        self.dt = data.dt
        r = data.r[lo:hi]
        self.rbar = 0.5 * (r[1:] + r[:-1])  # (n−1, nj)
        self.rdot = np.diff(r, axis=0) / data.dt
        self.pas = data.pas
        self.act = data.act
        self.k = np.asarray(model.stiffness)[data.pas]
        self.rest = np.asarray(model.rest)[data.pas]
        self.t = data.t[lo:hi]
        self.pose_t = data.pose_t
        self.pose_raw = data.pose_raw
        self.yaw_mid = 0.5 * (data.pose[lo:hi - 1, 2] + data.pose[lo + 1:hi, 2])
        self._metric_cache: dict[float, tuple[FloatArray, FloatArray]] = {}
        self._xi_rec_cache: dict[float, FloatArray] = {}
        self.nint = self.rbar.shape[0]
        self.nwin = self.nint - w + 1
        self.rdot_p = self.rdot[:, self.pas]

    def _win(self, x: FloatArray) -> FloatArray:
        """Moving average over w intervals along axis 0."""
        c = np.cumsum(np.concatenate([np.zeros((1,) + x.shape[1:]), x], axis=0), axis=0)
        return (c[self.w:] - c[:-self.w]) / self.w

    def drag_terms(self, ratio: float) -> tuple[FloatArray, FloatArray]:
        """Per-interval (D q̇)_p (nint, np) and windowed still-fluid ξ (nwin, 3) at drag ratio c⊥/c∥."""
        key = round(float(ratio), 12)
        hit = self._metric_cache.get(key)
        if hit is not None:
            return hit
        model = self.model.with_(c_perp=ratio * self.model.c_par)
        chain = RFTChain(model)
        D = chain.drag_metric(self.rbar)  # (m, 3+nj, 3+nj)
        rdot = self.rdot
        rhs = -np.einsum("bij,bj->bi", D[:, :3, 3:], rdot)
        xi = np.linalg.solve(D[:, :3, :3], rhs[..., None])[..., 0]
        qdot = np.concatenate([xi, rdot], axis=1)
        tau = np.einsum("bij,bj->bi", D[:, 3 + self.pas, :], qdot)
        xi_w = self._compose(xi)
        if len(self._metric_cache) > 64:
            self._metric_cache.clear()
        self._metric_cache[key] = (tau, xi_w)
        return tau, xi_w

    def _compose(self, xi: FloatArray) -> FloatArray:
        """Windowed body velocity: log of the product of the w per-interval exponentials."""
        tw = xi * self.dt
        n = tw.shape[0] - self.w + 1
        P = np.zeros((n, 3))
        for i in range(self.w):
            P = se2_exp_step(P, tw[i:i + n])
        return se2.log(P) / (self.w * self.dt)

    def xi_recorded(self, delay: float) -> FloatArray:
        """Windowed recorded body velocity with pose re-sampled at t + delay (undoing a stamp lag)."""
        key = round(float(delay), 9)
        hit = self._xi_rec_cache.get(key)
        if hit is not None:
            return hit
        ts = self.t + delay
        P = np.stack([np.interp(ts, self.pose_t, self.pose_raw[:, c]) for c in range(3)], axis=1)
        out = _window_xi(P, self.w, self.dt)
        if len(self._xi_rec_cache) > 256:
            self._xi_rec_cache.clear()
        self._xi_rec_cache[key] = out
        return out

    def valid(self, delay_max: float) -> FloatArray:
        """Windows whose re-sampled pose stays away from the ends of the span."""
        ok = np.ones(self.nwin, dtype=bool)
        n_edge = int(np.ceil(abs(delay_max) / self.dt)) + 1
        ok[:n_edge] = False
        ok[-n_edge:] = False
        return ok

    def residuals(self, p: "_Params", rdot_thr: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Torque residuals (nint, np) and body-velocity residuals (nwin, 3) under parameters ``p``."""
        tau, xi_w = self.drag_terms(p.ratio)
        e_spring = self.rbar[:, self.pas] - self.rest - p.offset
        spring = -p.scale * p.kscale * self.k * e_spring - p.scale * p.k3 * e_spring**3
        e = tau + p.d * self.rdot_p - spring
        # Intervals where a joint's measured velocity is within noise of zero are left out of its
        # torque channel for every candidate: there the joint may be stuck (any friction torque
        # in [−mu, mu] is admissible) and sign(ṙ) is noise, so a dead zone would "explain" noise.
        v = self.rdot_p
        slip = np.abs(v) > rdot_thr
        e = np.where(slip, e + p.mu * np.sign(v), 0.0)
        xi_pred = xi_w
        if p.flow[0] != 0.0 or p.flow[1] != 0.0:
            c, s = np.cos(self.yaw_mid), np.sin(self.yaw_mid)
            U = np.stack([c * p.flow[0] + s * p.flow[1], -s * p.flow[0] + c * p.flow[1]], axis=1)
            xi_pred = xi_w.copy()
            xi_pred[:, :2] += self._win(U)
        ex = self.xi_recorded(p.delay) - xi_pred
        return e, ex


@dataclass
class _Params:
    """Effect parameters in equation-error form (per passive joint where relevant)."""

    mu: FloatArray
    d: FloatArray
    offset: FloatArray
    k3: FloatArray
    kscale: FloatArray
    scale: float = 1.0
    ratio: float = 2.0
    flow: tuple[float, float] = (0.0, 0.0)
    delay: float = 0.0


# =============================================================================== candidates
@dataclass(frozen=True)
class _Candidate:
    """One or two catalogue effects with free parameters."""

    parts: tuple[tuple[str, str | None], ...]  # (effect id, target joint name or None)

    @property
    def label(self) -> str:
        return " + ".join(_label(n, t) for n, t in self.parts)

    def pnames(self) -> list[tuple[int, str]]:
        return [(i, p.name) for i, (n, _) in enumerate(self.parts) for p in EFFECTS[n].params]

    def bounds(self) -> tuple[list[float], list[float]]:
        lo, hi = [], []
        for n, _ in self.parts:
            for p in EFFECTS[n].params:
                lo.append(p.lower)
                hi.append(p.upper)
        return lo, hi

    def neutral(self) -> FloatArray:
        return np.array([p.neutral for n, _ in self.parts for p in EFFECTS[n].params])

    def scales(self) -> FloatArray:
        return np.array([p.scale for n, _ in self.parts for p in EFFECTS[n].params])

    def effects(self, x: FloatArray) -> list[dict[str, object]]:
        out: list[dict[str, object]] = []
        i = 0
        for n, tgt in self.parts:
            e: dict[str, object] = {"name": n, "joint": tgt}
            for p in EFFECTS[n].params:
                e[p.name] = float(x[i])
                i += 1
            out.append(e)
        return out


def _label(name: str, target: str | None) -> str:
    return name if target is None else f"{name}:{target}"


def _to_params(cand: _Candidate, x: FloatArray, names: tuple[str, ...], pas: FloatArray, model: ChainModel) -> _Params:
    npas = pas.size
    p = _Params(
        mu=np.zeros(npas), d=np.zeros(npas), offset=np.zeros(npas), k3=np.zeros(npas), kscale=np.ones(npas),
        ratio=model.c_perp / model.c_par,
    )
    i = 0
    for n, tgt in cand.parts:
        j = -1 if tgt is None else list(pas).index(names.index(tgt))
        if n == "joint_coulomb_friction":
            p.mu[j] += x[i]
        elif n == "joint_viscous_damping":
            p.d[j] += x[i]
        elif n == "spring_rest_offset":
            p.offset[j] += x[i]
        elif n == "spring_nonlinearity":
            p.k3[j] += x[i]
        elif n == "joint_stiffness_error":
            p.kscale[j] *= x[i]
        elif n == "stiffness_to_drag_error":
            p.scale *= x[i]
        elif n == "drag_anisotropy_error":
            p.ratio = float(x[i])
        elif n == "background_flow":
            p.flow = (p.flow[0] + float(x[i]), p.flow[1] + float(x[i + 1]))
        elif n == "sensor_time_offset":
            p.delay += float(x[i])
        i += len(EFFECTS[n].params)
    return p


def catalogue_candidates(model: ChainModel) -> list[_Candidate]:
    """Every single-effect candidate for a system: joint effects on each passive joint, global effects."""
    names = tuple(f"joint_{j + 1}" for j in range(model.n_joints))
    out: list[_Candidate] = []
    for eid, spec in EFFECTS.items():
        if spec.needs_joint:
            for j in model.passive:
                out.append(_Candidate(((eid, names[j]),)))
        else:
            out.append(_Candidate(((eid, None),)))
    return out


class _Scorer:
    """Fits candidates by equation error on the training half and scores them on the held-out half."""

    DELAY_MAX = 0.2

    def __init__(self, data: _Data, model: ChainModel, w: int, sig_r: FloatArray) -> None:
        self.data = data
        self.model = model
        self.train = _EqError(data, model, 0, data.n_train, w)
        self.test = _EqError(data, model, data.n_train, data.n_used, w)
        self.w = w
        # threshold on |ṙ_p| below which a joint may be stuck: 3σ of the interval-velocity noise
        # (capped at the 30 % quantile of |ṙ_p| so a poor noise estimate cannot empty a channel)
        thr = 3.0 * np.sqrt(2.0) * np.nan_to_num(sig_r, nan=1e-3) / data.dt
        q30 = np.quantile(np.abs(self.train.rdot_p), 0.3, axis=0)
        self.rdot_thr = np.minimum(thr, q30)
        self.ok_train = self.train.valid(self.DELAY_MAX)
        self.ok_test = self.test.valid(self.DELAY_MAX)
        npas = data.pas.size
        self.n_eff_train = np.array([self.train.nint] * npas + [self.ok_train.sum() / w] * 3, dtype=float)
        self.n_eff_test = np.array([self.test.nint] * npas + [self.ok_test.sum() / w] * 3, dtype=float)
        # least-squares row weights: overlapping ξ windows count 1/w each
        self.row_w = np.array([1.0] * npas + [1.0 / np.sqrt(w)] * 3)
        null = _Candidate(())
        self.null = null
        e_tr, x_tr = self._res(self.train, null, np.zeros(0))
        e_te, x_te = self._res(self.test, null, np.zeros(0))
        self.rss0_train = self._rss(e_tr, x_tr, self.ok_train)
        self.rss0_test = self._rss(e_te, x_te, self.ok_test)

    def _res(self, eq: _EqError, cand: _Candidate, x: FloatArray) -> tuple[FloatArray, FloatArray]:
        p = _to_params(cand, x, self.data.names, self.data.pas, self.model)
        return eq.residuals(p, self.rdot_thr)

    @staticmethod
    def _rss(e: FloatArray, ex: FloatArray, ok: FloatArray) -> FloatArray:
        """Mean squared residual per channel (torques, then ξ)."""
        ex = ex[ok]
        ex = np.where(np.isfinite(ex), ex, 0.0)
        return np.concatenate([(e**2).mean(axis=0), (ex**2).mean(axis=0)]) + 1e-30

    def gain(self, rss: FloatArray, rss0: FloatArray, n_eff: FloatArray) -> float:
        return float(0.5 * np.sum(n_eff * np.log(rss0 / np.maximum(rss, 1e-300))))

    def _stack(self, e: FloatArray, ex: FloatArray, ok: FloatArray, wts: FloatArray) -> FloatArray:
        npas = e.shape[1]
        ex = ex[ok]
        ex = np.where(np.isfinite(ex), ex, 0.0)
        a = (e * (wts[:npas] * self.row_w[:npas])).ravel()
        b = (ex * (wts[npas:] * self.row_w[npas:])).ravel()
        return np.concatenate([a, b])

    def fit(self, cand: _Candidate, x0: FloatArray | None = None) -> tuple[FloatArray, float, float]:
        """Fit on the training half; returns (parameters, training gain, held-out gain)."""
        lo, hi = cand.bounds()
        scales = cand.scales()
        starts = []
        if x0 is not None:
            starts.append(np.asarray(x0, dtype=float))
        base = cand.neutral()
        starts.append(base + 0.0)
        # a few starts per parameter on both sides (nonconvex: Coulomb dead zone, drag ratio)
        for k, sgn in ((1.0, 1), (1.0, -1), (3.0, 1), (3.0, -1)):
            starts.append(base + sgn * k * scales)
        weights = 1.0 / np.sqrt(self.rss0_train)
        ok = self.ok_train

        def fun(x: FloatArray, wts: FloatArray) -> FloatArray:
            e, ex = self._res(self.train, cand, x)
            return self._stack(e, ex, ok, wts)

        best_x, best_c = None, np.inf
        for s in starts:
            s = np.clip(s, np.asarray(lo) + 1e-9, np.asarray(hi) - 1e-9)
            try:
                c0 = float(np.sum(fun(s, weights) ** 2))
            except (FloatingPointError, np.linalg.LinAlgError, SudsConfigError):
                continue
            if not np.isfinite(c0):
                continue
            if c0 < best_c:
                best_x, best_c = s, c0
        if best_x is None:
            return base, -np.inf, -np.inf
        sols = []
        # refine from the best two starts
        for s in [best_x] + ([starts[0]] if x0 is not None else []):
            s = np.clip(s, np.asarray(lo) + 1e-9, np.asarray(hi) - 1e-9)
            wts = weights
            x = s
            for _ in range(2):  # re-estimate channel weights once
                try:
                    sol = scipy.optimize.least_squares(
                        fun, x, args=(wts,), bounds=(lo, hi), x_scale=scales, diff_step=1e-3, max_nfev=60
                    )
                except (FloatingPointError, np.linalg.LinAlgError, SudsConfigError, ValueError):
                    break
                x = sol.x
                e, ex = self._res(self.train, cand, x)
                rss = self._rss(e, ex, ok)
                wts = 1.0 / np.sqrt(np.maximum(rss, 1e-300))
            e, ex = self._res(self.train, cand, x)
            sols.append((self.gain(self._rss(e, ex, ok), self.rss0_train, self.n_eff_train), x))
        g_tr, x = max(sols, key=lambda s: s[0])
        e, ex = self._res(self.test, cand, x)
        g_te = self.gain(self._rss(e, ex, self.ok_test), self.rss0_test, self.n_eff_test)
        return x, g_tr, g_te


# =============================================================================== locate
def _phase_ranges(
    phase: FloatArray, e: FloatArray, cycle: FloatArray, bins: int, alpha: float
) -> tuple[tuple[float, float], ...]:
    """Merged phase intervals (rad) whose mean residual across cycles is significant."""
    ok = np.isfinite(e)
    ph = np.mod(phase[ok], 2 * np.pi)
    b = np.minimum((ph / (2 * np.pi) * bins).astype(int), bins - 1)
    cyc = cycle[ok].astype(int)
    cycles = np.unique(cyc)
    if cycles.size < 3:
        return ()
    M = np.full((cycles.size, bins), np.nan)
    ci = np.searchsorted(cycles, cyc)
    sums = np.zeros((cycles.size, bins))
    cnt = np.zeros((cycles.size, bins))
    np.add.at(sums, (ci, b), e[ok])
    np.add.at(cnt, (ci, b), 1.0)
    M = np.where(cnt > 0, sums / np.maximum(cnt, 1), np.nan)
    mean = np.nanmean(M, axis=0)
    sd = np.nanstd(M, axis=0, ddof=1)
    nc = np.sum(np.isfinite(M), axis=0)
    tstat = mean / np.maximum(sd / np.sqrt(np.maximum(nc, 1)), 1e-300)
    tcrit = scipy.stats.t.ppf(1 - alpha / (2 * bins), max(cycles.size - 1, 1))
    sig = np.abs(tstat) > tcrit
    if not sig.any():
        return ()
    if sig.all():
        return ((0.0, 2 * np.pi),)
    # merge runs (circular)
    width = 2 * np.pi / bins
    start = int(np.flatnonzero(~sig)[0])
    out: list[tuple[float, float]] = []
    run: list[int] = []
    for k in range(1, bins + 1):
        i = (start + k) % bins
        if sig[i]:
            run.append(i)
        elif run:
            out.append((run[0], run[-1]))
            run = []
    if run:
        out.append((run[0], run[-1]))
    ranges: list[tuple[float, float]] = []
    for a, bb in out:
        lo, hi = a * width, (bb + 1) * width
        if bb < a:  # wraps through 0
            ranges.append((lo, 2 * np.pi))
            ranges.append((0.0, hi))
        else:
            ranges.append((lo, hi))
    return tuple(sorted((round(a, 4), round(b_, 4)) for a, b_ in ranges))


def _conditions(
    ch: str, e: FloatArray, idx: FloatArray, data: _Data, model: ChainModel
) -> tuple[str, ...]:
    """Describe under which recorded conditions a held-out residual concentrates."""
    ok = np.isfinite(e)
    e, idx = e[ok], idx[ok]
    if e.size < 20:
        return ()
    out: list[tuple[float, str]] = []
    r = data.r[idx]
    rdot = np.gradient(data.r, data.dt, axis=0)[idx]
    rest = np.asarray(model.rest)
    sd = e.std() or 1.0
    for j in data.pas:
        nm = data.names[j]
        pos = rdot[:, j] > 0
        if 5 < pos.sum() < e.size - 5:
            a, b = e[pos], e[~pos]
            t = (a.mean() - b.mean()) / np.sqrt(a.var() / a.size + b.var() / b.size + 1e-300)
            out.append((abs(t), f"sign of ṙ({nm}): mean residual {a.mean():+.3g} when ṙ>0 vs {b.mean():+.3g} when ṙ<0 (t={t:.1f})"))
        dev = r[:, j] - rest[j]
        c = np.corrcoef(e, dev)[0, 1]
        c3 = np.corrcoef(e, dev**3)[0, 1]
        big = np.abs(dev) > np.quantile(np.abs(dev), 0.75)
        ratio = np.sqrt(np.mean(e[big] ** 2) / max(np.mean(e[~big] ** 2), 1e-300))
        out.append((abs(c) * np.sqrt(e.size), f"r({nm}) − rest: correlation {c:+.2f} (cubic {c3:+.2f}); RMS at large |r − rest| ×{ratio:.2f}"))
    yaw = data.pose[idx, 2]
    X = np.stack([np.cos(yaw), np.sin(yaw), np.ones_like(yaw)], axis=1)
    coef, *_ = np.linalg.lstsq(X, e, rcond=None)
    r2 = 1 - np.var(e - X @ coef) / max(np.var(e), 1e-300)
    out.append((r2 * np.sqrt(e.size) * 3, f"heading: residual ≈ {coef[0]:+.3g}·cos(yaw) {coef[1]:+.3g}·sin(yaw) (R²={r2:.2f})"))
    xy = data.pose[idx, :2]
    X = np.column_stack([xy, np.ones(e.size)])
    coef, *_ = np.linalg.lstsq(X, e, rcond=None)
    r2p = 1 - np.var(e - X @ coef) / max(np.var(e), 1e-300)
    out.append((r2p * np.sqrt(e.size) * 3, f"position: R²={r2p:.2f} against (x, y)"))
    # lag structure: cross-correlation with the recorded joint velocities
    best = (0.0, 0, "")
    max_lag = int(round(0.3 / data.dt))
    ez = (e - e.mean()) / sd
    for j in range(data.r.shape[1]):
        s = rdot[:, j]
        sz = (s - s.mean()) / (s.std() or 1.0)
        for lag in range(-max_lag, max_lag + 1, 2):
            if lag >= 0:
                c = float(np.mean(ez[lag:] * sz[: sz.size - lag])) if lag < e.size else 0.0
            else:
                c = float(np.mean(ez[:lag] * sz[-lag:]))
            if abs(c) > abs(best[0]):
                best = (c, lag, data.names[j])
    if best[2]:
        out.append((abs(best[0]) * np.sqrt(e.size), f"lag: peak cross-correlation {best[0]:+.2f} with ṙ({best[2]}) at {best[1] * data.dt * 1e3:+.0f} ms"))
    out.sort(key=lambda z: -z[0])
    return tuple(s for _, s in out[:4])


def _coefficient_comparison(
    data: _Data, sim_rp: FloatArray, sim_pose: FloatArray, w: int
) -> tuple[tuple[str, str, float, tuple[tuple[float, float], ...]], ...]:
    """Compare SUDS coefficients identified from the recording and from the replay (training half).

    Returns (group, output, z, phase ranges) sorted by z, where z is the RMS over phase of the
    coefficient difference divided by a split-half noise scale of the recording's coefficients.
    """
    try:
        from suds_ros.core.fourier import fourier_basis
        from suds_ros.core.ident.sysid import SudsConfig, SudsRegressor
    except ImportError:  # hook: the SUDS regression lives in suds_ros.core.ident.sysid
        return ()
    n = data.n_train
    r = data.r[:n]
    ph = data.phase[:n]
    # outputs on w-sample intervals (same estimator for both)
    xi_rec = _window_xi(data.pose[:n], w, data.dt)
    rp_rec = r[:, data.pas]
    rp_sim = sim_rp[:n]
    xi_sim = _window_xi(sim_pose[:n], w, data.dt)
    mid = np.arange(n - w)
    phm = 0.5 * (ph[:-w] + ph[w:])
    rmid = 0.5 * (r[:-w] + r[w:])
    rdot = (r[w:] - r[:-w]) / (w * data.dt)
    Fb = fourier_basis(ph, 6)
    coef, *_ = np.linalg.lstsq(Fb, r, rcond=None)
    Fm = fourier_basis(phm, 6)
    theta = Fm @ coef
    omega = ((ph[w:] - ph[:-w]) / (w * data.dt))[:, None]  # local phase rate (phaser phase)
    m_ = np.arange(1, 7)
    dF = np.zeros_like(Fm)
    dF[:, 1::2] = -np.sin(phm[:, None] * m_) * m_
    dF[:, 2::2] = np.cos(phm[:, None] * m_) * m_
    dtheta = (dF @ coef) * omega
    delta = rmid - theta
    dda = (rdot - dtheta)[:, data.act]
    X = np.column_stack([phm, delta, dda])
    Y_rec = np.column_stack([xi_rec, (rp_rec[w:] - rp_rec[:-w]) / (w * data.dt)])
    Y_sim = np.column_stack([xi_sim, (rp_sim[w:] - rp_sim[:-w]) / (w * data.dt)])
    ok = np.all(np.isfinite(Y_sim), axis=1) & np.all(np.isfinite(Y_rec), axis=1)
    cfg = SudsConfig(regressors=2, intercept_order=6, linear_order=2, bilinear_order=1, ridge=1e-6)
    nj, na = data.r.shape[1], data.act.size
    half = mid < (n - w) // 2
    fits = {}
    for key, Y, sel in (
        ("rec", Y_rec, ok),
        ("sim", Y_sim, ok),
        ("a", Y_rec, ok & half),
        ("b", Y_rec, ok & ~half),
    ):
        fits[key] = SudsRegressor(nj, na, cfg).fit(X[sel], Y[sel])
    grid = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    C = {k: f.coefficients(grid) for k, f in fits.items()}
    outputs = list(BODY) + [f"rdot_{data.names[j]}" for j in data.pas]
    rows = []
    for g in ("C", "C_r", "B", "B_r"):
        for o, oname in enumerate(outputs):
            def pick(c: dict[str, FloatArray]) -> FloatArray:
                v = c[g][:, o]
                return v.reshape(grid.size, -1)

            d = np.linalg.norm(pick(C["rec"]) - pick(C["sim"]), axis=1)
            noise = np.linalg.norm(pick(C["a"]) - pick(C["b"]), axis=1) / 2
            sc = float(np.sqrt(np.mean(noise**2))) or 1e-300
            z = float(np.sqrt(np.mean(d**2)) / sc)
            sig = d > 3 * sc
            ranges: list[tuple[float, float]] = []
            width = 2 * np.pi / grid.size
            i = 0
            while i < grid.size:
                if sig[i]:
                    j = i
                    while j + 1 < grid.size and sig[j + 1]:
                        j += 1
                    ranges.append((round(i * width, 3), round((j + 1) * width, 3)))
                    i = j + 1
                else:
                    i += 1
            rows.append((g, oname, z, tuple(ranges)))
    rows.sort(key=lambda r_: -r_[2])
    return tuple(rows)


# =============================================================================== refine
def _segments(lo: int, hi: int, length: int) -> list[int]:
    return list(range(lo, hi - length + 1, length))


def _residual_vector(
    data: _Data, rep: _Replay, starts: Sequence[int], length: int, w: int, sig_rp: FloatArray, s_xy: float, s_th: float
) -> FloatArray:
    """Noise-floor-weighted replay residuals, (B, k): r_p per sample, ξ on non-overlapping windows."""
    idx = np.asarray(starts)[:, None] + np.arange(length)[None, :]
    e_rp = (data.r[idx][:, :, data.pas] - rep.rp) / sig_rp
    xi_rec = _window_xi(data.pose[idx], w, data.dt)
    e_xi = (xi_rec - rep.xi) / np.array([s_xy, s_xy, s_th])
    e_xi = e_xi[:, ::w]
    e_xi = np.where(np.isfinite(e_xi), e_xi, 0.0)
    B = len(starts)
    return np.concatenate([e_rp.reshape(B, -1), e_xi.reshape(B, -1)], axis=1)


def _refine(
    cand: _Candidate,
    x0: FloatArray,
    base: ChainModel,
    data: _Data,
    cfg: DiagnoseConfig,
    w: int,
    substeps: int,
    floors: tuple[FloatArray, float, float],
) -> tuple[FloatArray, FloatArray]:
    """Output-error least squares of the candidate's parameters; returns (x, stderr)."""
    length = cfg.segment_cycles * data.spc
    starts = _segments(0, data.n_train, length)
    if not starts:
        starts, length = [0], data.n_train
    max_seg = max(1, cfg.refine_cycles // cfg.segment_cycles)
    if len(starts) > max_seg:  # spread a subset over the training half
        pick = np.unique(np.round(np.linspace(0, len(starts) - 1, max_seg)).astype(int))
        starts = [starts[i] for i in pick]
    lo, hi = (np.asarray(b, dtype=float) for b in cand.bounds())
    scales = cand.scales()

    def sim(x: FloatArray) -> FloatArray:
        model, delay = apply_effects(base, cand.effects(x))
        rep = replay(model, delay, data, starts, length, w, substeps)
        return _residual_vector(data, rep, starts, length, w, *floors)

    def fun(x: FloatArray) -> FloatArray:
        try:
            return sim(x).ravel()
        except (FloatingPointError, np.linalg.LinAlgError, SudsConfigError):
            return np.full(n_res, 1e6)

    x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
    r0 = sim(x0)
    n_res = r0.size
    c0 = float(np.sum(r0**2))
    step = np.maximum(1e-3 * np.abs(x0), 1e-2 * scales) / np.maximum(np.abs(x0), 1e-12)
    sol = scipy.optimize.least_squares(
        fun, x0, bounds=(lo, hi), x_scale=scales, diff_step=step,
        max_nfev=cfg.refine_nfev * (x0.size + 1), method="trf",
    )
    if sol.cost * 2 <= c0 and sol.jac is not None and np.all(np.isfinite(sol.jac)):
        # least_squares leaves the forward-difference Jacobian and the residuals at its solution
        x, R, J = sol.x, np.asarray(sol.fun).reshape(r0.shape), np.asarray(sol.jac)
    else:
        x, R = x0, r0
        J = np.empty((R.size, x.size))
        for i in range(x.size):
            h = max(1e-3 * abs(x[i]), 1e-2 * scales[i])
            xp = x.copy()
            xp[i] = x[i] + h if x[i] + h <= hi[i] else x[i] - h
            J[:, i] = (fun(xp) - R.ravel()) / (xp[i] - x[i])
    return x, _sandwich_stderr(J, R, x.size)


def _sandwich_stderr(J: FloatArray, R: FloatArray, p: int) -> FloatArray:
    """Standard errors of a least-squares fit with residuals clustered by segment.

    J (B·k, p) Jacobian, R (B, k) residuals (B clusters = independent segments).  The
    cluster-robust sandwich (J'J)⁻¹ (Σ_b g_b g_b') (J'J)⁻¹, g_b = J_b' R_b, is biased low with few
    clusters; it gets the CR1 factor B/(B − p) and the ratio of the t quantile with B − p degrees of
    freedom to the normal one (so ±2 se keeps roughly its nominal coverage with few clusters).  The
    larger of that and the model-based error (J'J)⁻¹·s², s² the residual variance with the
    segment-level autocorrelation taken into account through the cluster totals, is reported.
    """
    B = R.shape[0]
    JtJ = J.T @ J
    try:
        inv = np.linalg.inv(JtJ)
    except np.linalg.LinAlgError:
        return np.full(p, np.nan)
    Jb = J.reshape(B, -1, p)
    Rb = R.reshape(B, -1)
    G = np.einsum("bkp,bk->bp", Jb, Rb)
    meat = G.T @ G
    dof = max(B - p, 1)
    cov = inv @ meat @ inv * B / dof
    tfac = float(scipy.stats.t.ppf(0.975, dof) / scipy.stats.norm.ppf(0.975))
    se_sand = np.sqrt(np.maximum(np.diag(cov), 0.0)) * tfac
    s2 = float(np.sum(Rb**2)) / max(Rb.size - p, 1)
    se_model = np.sqrt(np.maximum(np.diag(inv), 0.0) * s2)
    return np.maximum(se_sand, se_model)


# =============================================================================== main entry
def _split_halves(data: _Data) -> tuple[list[int], int, list[int], int]:
    return [0], data.n_train, [data.n_train], data.n_used - data.n_train


def _channel_residuals(
    data: _Data, model: ChainModel, delay: float, w: int, substeps: int,
    reference: Recording | None = None, chunk: int = 0, warm: int = 0,
) -> tuple[FloatArray, FloatArray, FloatArray, tuple[FloatArray, FloatArray, FloatArray, FloatArray]]:
    """Whole-recording replay (train half and held-out half from their recorded initial states).

    Returns simulated r_p (n_used, np), windowed ξ (n_used, 3) aligned at window midpoints (NaN at
    the edges of each half), the simulated pose (n_used, 3) and the per-segment arrays
    (recorded r_p, simulated r_p, recorded pose, simulated pose), each (B, m, ·), for the noise
    floor.

    With ``chunk`` > 0 each half is replayed as independent pieces run in one batch: the piece
    that outputs samples [c, c + chunk) starts ``warm`` samples earlier from the recorded state
    (the first piece of a half starts at the half's recorded initial state, as the whole-half
    replay).  The passive joints are strongly damped, so after the warm-up the piece has forgotten
    its initial state and its output equals the whole-half replay's (checked to ~1e-6 rad in the
    tests); the body velocity depends only on the pose *increments* over a window, so restarting
    the pose from the recorded one changes nothing but the (unused) absolute pose, except that
    heading-dependent terms (flow) use a heading that has not drifted over a whole half.
    """
    n = data.n_used
    rp = np.full((n, data.pas.size), np.nan)
    xi = np.full((n, 3), np.nan)
    pose = np.full((n, 3), np.nan)
    halves = ((0, data.n_train), (data.n_train, n))
    if reference is not None:
        ref = _prepare(reference, model)
        if ref.n_used < n or not np.allclose(ref.t[:n], data.t[:n], atol=0.5 * data.dt):
            raise SudsDataError("--sim: the reference recording must cover the same stamps as the recording")
        dev = np.sqrt(np.mean((ref.r[:n][:, data.act] - data.r[:n][:, data.act]) ** 2))
        if dev > 0.05:
            raise SudsDataError(
                f"--sim: the reference's actuated trajectory differs from the recording's (RMS {dev:.3g} rad); "
                "it must be driven by the same recorded r_a"
            )
        for lo, hi in halves:
            rp[lo:hi] = ref.r[lo:hi][:, data.pas]
            pose[lo:hi] = ref.pose[lo:hi]
            xi[lo + w // 2: hi - w + w // 2] = _window_xi(ref.pose[lo:hi], w, data.dt)
        return rp, xi, pose, _floor_arrays(data, [(lo, hi - lo) for lo, hi in halves], rp, pose, None)
    # pieces: (segment start, output start, output end)
    pieces: list[tuple[int, int, int]] = []
    if chunk <= 0:
        pieces = [(lo, lo, hi) for lo, hi in halves]
    else:
        for lo, hi in halves:
            c = lo
            while c < hi:
                e = min(c + chunk, hi)
                pieces.append((max(lo, c - warm), c, e))
                c = e
    # equal-length batches: a piece covers its output plus the ξ window after it
    groups: dict[int, list[tuple[int, int, int]]] = {}
    for s0, c, e in pieces:
        half_hi = n if c >= data.n_train else data.n_train
        length = min(e + w, half_hi) - s0
        groups.setdefault(length, []).append((s0, c, e))
    segs: list[tuple[int, int]] = []
    seg_rp: list[FloatArray] = []
    seg_pose: list[FloatArray] = []
    for length, group in groups.items():
        starts = [g[0] for g in group]
        rep = replay(model, delay, data, starts, length, w, substeps)
        for b, (s0, c, e) in enumerate(group):
            rp[c:e] = rep.rp[b, c - s0: e - s0]
            pose[c:e] = rep.pose[b, c - s0: e - s0]
            # ξ at midpoint i comes from the window starting at i − w//2 within this piece
            half_lo = data.n_train if c >= data.n_train else 0
            half_hi = n if c >= data.n_train else data.n_train
            mids = np.arange(max(c, half_lo + w // 2), min(e, half_hi - w + w // 2))
            j = mids - w // 2 - s0
            okj = (j >= 0) & (j < rep.xi.shape[1])
            xi[mids[okj]] = rep.xi[b, j[okj]]
            segs.append((s0, length))
            seg_rp.append(rep.rp[b])
            seg_pose.append(rep.pose[b])
    return rp, xi, pose, _floor_arrays(data, segs, None, None, (seg_rp, seg_pose))


def _floor_arrays(
    data: _Data, segs: Sequence[tuple[int, int]], rp: FloatArray | None, pose: FloatArray | None,
    seg_sim: tuple[list[FloatArray], list[FloatArray]] | None,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """(recorded r_p, simulated r_p, recorded pose, simulated pose) per segment, cut to a common length."""
    m = min(length for _, length in segs)
    rr, ss, pr, ps = [], [], [], []
    for k, (s0, _) in enumerate(segs):
        rr.append(data.r[s0:s0 + m][:, data.pas])
        pr.append(data.pose[s0:s0 + m])
        if seg_sim is None:
            assert rp is not None and pose is not None
            ss.append(rp[s0:s0 + m])
            ps.append(pose[s0:s0 + m])
        else:
            ss.append(seg_sim[0][k][:m])
            ps.append(seg_sim[1][k][:m])
    return np.stack(rr), np.stack(ss), np.stack(pr), np.stack(ps)


def diagnose(
    rec: Recording,
    model: ChainModel,
    config: DiagnoseConfig = DiagnoseConfig(),
    *,
    reference: Recording | None = None,
    progress: Callable[[str], None] | None = None,
) -> DiagnosisReport:
    """Diagnose where the simulator ``model`` disagrees with the recording ``rec``.

    Parameters
    ----------
    rec : Recording
        The (real) recording.
    model : ChainModel
        The nominal physics (e.g. :func:`~suds_ros.core.physics.systems.swimmer9_model`).
    config : DiagnoseConfig
        Settings.
    reference : Recording, optional
        A simulated recording driven by the same actuated trajectory, used as the reference
        for locating instead of replaying ``model``.
    progress : callable, optional
        Receives short stage messages.

    Returns
    -------
    DiagnosisReport
    """
    import time

    say = progress or (lambda s: None)
    tick = time.perf_counter()
    timings: dict[str, float] = {}
    data = _prepare(rec, model)
    w = max(1, int(round(config.window / data.dt)))
    substeps = config.substeps or min(auto_substeps(RFTChain(model), data.dt, accuracy=0.4), 8)
    n = data.n_used
    pas_names = [data.names[j] for j in data.pas]
    channels = pas_names + list(BODY)
    cycle = np.floor(data.phase[:n] / (2 * np.pi))  # gait cycles of the phase (replicates)

    # ------------------------------------------------------------------ 1. replay
    say("replaying the nominal simulator")
    chunk = int(round(config.replay_chunk * data.spc))
    warm = int(round(config.replay_warm / data.dt))
    rp0, xi0, pose0, fa0 = _channel_residuals(data, model, 0.0, w, substeps, reference, chunk, warm)
    xi_rec = np.full((n, 3), np.nan)
    for lo, hi in ((0, data.n_train), (data.n_train, n)):
        xi_rec[lo + w // 2: hi - w + w // 2] = _window_xi(data.pose[lo:hi], w, data.dt)
    timings["replay"] = time.perf_counter() - tick

    def floors_of(fa: tuple[FloatArray, FloatArray, FloatArray, FloatArray]) -> tuple[FloatArray, float, float]:
        return noise_floor(*fa, w, data.dt)

    sig_rp, s_xy, s_th = floors_of(fa0)
    floor = dict(zip(channels, list(sig_rp) + [s_xy, s_xy, s_th]))

    def residual_table(rp_sim: FloatArray, xi_sim: FloatArray) -> FloatArray:
        e = np.full((n, len(channels)), np.nan)
        e[:, : data.pas.size] = data.r[:n][:, data.pas] - rp_sim
        e[:, data.pas.size:] = xi_rec - xi_sim
        return e

    E0 = residual_table(rp0, xi0)
    held = np.arange(n) >= data.n_train

    def rms_held(E: FloatArray) -> dict[str, float]:
        return {c: float(np.sqrt(np.nanmean(E[held, i] ** 2))) for i, c in enumerate(channels)}

    def fstats(E: FloatArray, fl: Mapping[str, float]) -> dict[str, float]:
        return {c: float(np.nanmean(E[held, i] ** 2) / fl[c] ** 2) for i, c in enumerate(channels)}

    rms0 = rms_held(E0)
    F0 = fstats(E0, floor)

    # ------------------------------------------------------------------ 2. locate
    say("locating")
    conditions: dict[str, tuple[str, ...]] = {}

    def locate(F: Mapping[str, float]) -> list[Located]:
        out: list[Located] = []
        for i, c in enumerate(channels):
            if F[c] > config.f_threshold:
                ranges = _phase_ranges(data.phase[held], E0[held, i], cycle[held], config.phase_bins, config.phase_alpha)
                if not ranges:
                    ranges = ((0.0, round(2 * np.pi, 4)),)
                out.append(Located(c, ranges, F[c]))
                if c not in conditions:
                    conditions[c] = _conditions(c, E0[held, i], np.flatnonzero(held), data, model)
        return out

    located = locate(F0)
    mismatch = bool(located)
    coeffs = ()
    if mismatch and reference is None:
        try:
            coeffs = _coefficient_comparison(data, rp0, pose0, 5)
        except (SudsDataError, np.linalg.LinAlgError, ValueError):
            coeffs = ()
    timings["locate"] = time.perf_counter() - tick

    if not mismatch:
        series = _series(data, channels, held, E0, E0, residual_table, rp0, xi0, rp0, xi0, xi_rec)
        return DiagnosisReport(
            mismatch=False, located=(), effects=(), confounded_with=(), unexplained=False,
            heldout_rms_before=rms0, heldout_rms_after=dict(rms0), improvement=0.0,
            system=model.name, noise_floor=floor, statistics=F0, statistics_after=F0,
            coefficients=coeffs, series=series,
            train_cycles=data.n_train // data.spc, heldout_cycles=(n - data.n_train) // data.spc,
            timings=timings, phase_source=data.phase_source,
            notes=(data.phase_note,) if data.phase_note else (),
        )

    # ------------------------------------------------------------------ 3. name
    say("ranking catalogue candidates (equation error)")
    scorer = _Scorer(data, model, config.eq_window, sig_rp)
    pen_unit = 0.5 * np.log(max(float(np.median(scorer.n_eff_train)), 2.0))
    singles: list[tuple[CandidateScore, _Candidate, FloatArray]] = []
    for cand in catalogue_candidates(model):
        x, _, g_te = scorer.fit(cand)
        cs = CandidateScore(cand.label, tuple(cand.effects(x)), x.size, g_te, pen_unit * x.size)
        singles.append((cs, cand, x))
    singles.sort(key=lambda s: -s[0].score)
    pairs: list[tuple[CandidateScore, _Candidate, FloatArray]] = []
    top = [s for s in singles[: config.top_pairs] if s[0].score > 0]
    for (c1, k1, x1), (c2, k2, x2) in itertools.combinations(top, 2):
        if k1.parts[0][0] == k2.parts[0][0] and k1.parts[0][0] in (
            "stiffness_to_drag_error", "drag_anisotropy_error", "background_flow", "sensor_time_offset"
        ):
            continue
        cand = _Candidate(k1.parts + k2.parts)
        x, _, g_te = scorer.fit(cand, np.concatenate([x1, x2]))
        pairs.append((CandidateScore(cand.label, tuple(cand.effects(x)), x.size, g_te, pen_unit * x.size), cand, x))
    pairs.sort(key=lambda s: -s[0].score)
    timings["name"] = time.perf_counter() - tick

    best = singles[0]
    pool = singles
    if pairs:
        bp = pairs[0]
        extra = bp[0].score - best[0].score
        if extra > max(config.pair_rel * max(best[0].gain_heldout, 0.0), pen_unit):
            best = bp
            pool = pairs
    ranking = tuple(s[0] for s in sorted(singles + pairs, key=lambda s: -s[0].score))
    # confounded: candidates of the same size within the margin of the winner
    margin = max(config.confound_margin, config.confound_rel * max(best[0].gain_heldout, 0.0))
    close = [s for s in pool if best[0].score - s[0].score <= margin and s[1] != best[1]]
    chosen = best
    group: list[tuple[CandidateScore, _Candidate, FloatArray]] = [best] + close
    if close:
        # among equivalent explanations prefer the specification's catalogue, then fewer targets
        def pref(s: tuple[CandidateScore, _Candidate, FloatArray]) -> tuple[int, int]:
            extra_ids = sum(1 for nme, _ in s[1].parts if nme not in SPEC_IDS)
            return (extra_ids, sum(1 for _, tgt in s[1].parts if tgt is not None))

        chosen = min(group, key=pref)
    confounded = (tuple(s[1].label for s in group),) if close else ()

    # ------------------------------------------------------------------ 4. refine and re-simulate
    say(f"fitting {chosen[1].label} inside the simulator")
    effects: list[FittedEffect] = []
    unexplained = False
    if chosen[0].score <= 0:
        unexplained = True
        rp1, xi1 = rp0, xi0
        E1 = E0
    else:
        cand, x0 = chosen[1], chosen[2]
        x, se = _refine(cand, x0, model, data, config, w, substeps, (sig_rp, s_xy, s_th))
        if len(cand.parts) > 1:
            # a pair member whose refined parameters are indistinguishable from neutral is dropped
            keep, i = [], 0
            for k, (nme, _) in enumerate(cand.parts):
                npar = len(EFFECTS[nme].params)
                neutral = cand.neutral()[i:i + npar]
                z = np.abs(x[i:i + npar] - neutral) / np.maximum(se[i:i + npar], 1e-300)
                if np.nanmax(z) >= config.member_z:
                    keep.append((k, i, npar))
                i += npar
            if len(keep) == 1:
                k, i, npar = keep[0]
                cand = _Candidate((cand.parts[k],))
                x, se = _refine(cand, x[i:i + npar], model, data, config, w, substeps, (sig_rp, s_xy, s_th))
                confounded = ()
        chosen = (chosen[0], cand, x)
        timings["refine"] = time.perf_counter() - tick
        fitted_model, delay = apply_effects(model, chosen[1].effects(x))
        rp1, xi1, pose1, fa1 = _channel_residuals(data, fitted_model, delay, w, substeps, None, chunk, warm)
        E1 = residual_table(rp1, xi1)
        i = 0
        for nme, tgt in chosen[1].parts:
            pn = EFFECTS[nme].param_names
            effects.append(FittedEffect(
                nme, tgt,
                {p: float(x[i + k]) for k, p in enumerate(pn)},
                {p: float(se[i + k]) for k, p in enumerate(pn)},
            ))
            i += len(pn)
        # floor with the better model (effects can leak into the fourth differences)
        f_rp, f_xy, f_th = floors_of(fa1)
        floor = {c: float(min(floor[c], v)) for c, v in zip(channels, list(f_rp) + [f_xy, f_xy, f_th])}
        F0 = fstats(E0, floor)
        located = locate(F0)
    rms1 = rms_held(E1)
    F1 = fstats(E1, floor)
    affected = [l.channel for l in located]
    improvement = excess_improvement(F0, F1, affected)
    # unexplained: the located excess power is not mostly removed
    ex0 = sum(max(F0[c] - 1.0, 0.0) for c in affected)
    ex1 = sum(max(F1[c] - 1.0, 0.0) for c in affected)
    still_sig = any(F1[c] > config.f_threshold for c in affected)
    if ex0 > 0 and ex1 / ex0 > config.unexplained_fraction and still_sig:
        unexplained = True
    # per channel: the aggregate can be dominated by one channel the fit does fix while another
    # located channel keeps (or grows) its mismatch; that channel is not explained either
    left = [
        c for c in affected
        if F1[c] > 1.5 * config.f_threshold
        and max(F1[c] - 1.0, 0.0) > config.unexplained_fraction * max(F0[c] - 1.0, 1e-12)
    ]
    if left:
        unexplained = True
    notes: list[str] = []
    if data.phase_note:
        notes.append(data.phase_note)
    if unexplained and effects and improvement < 0.5:
        # the best catalogue fit does not explain the mismatch: do not force it onto an entry
        tried = "; ".join(
            f"{e.name}{':' + e.target if e.target else ''} "
            + ", ".join(f"{k}={v:.4g}" for k, v in e.parameters.items())
            for e in effects
        )
        notes.append(
            f"best catalogue fit ({tried}) left held-out improvement {improvement:.3f}; not reported as an effect"
        )
        effects = []
        confounded = ()
        rp1, xi1, E1 = rp0, xi0, E0
        F1 = fstats(E1, floor)
    if unexplained:
        notes.append(
            "unexplained mismatch remains on " + ", ".join(left or affected)
            + " (F after the best catalogue fit > "
            + f"{1.5 * config.f_threshold:g} and > {config.unexplained_fraction:g} of its excess before)"
        )
    if unexplained and not effects:
        rms1 = dict(rms0)
        improvement = 0.0
    timings["total"] = time.perf_counter() - tick
    series = _series(data, channels, held, E0, E1, residual_table, rp0, xi0, rp1, xi1, xi_rec)
    return DiagnosisReport(
        mismatch=True,
        located=tuple(located),
        effects=tuple(effects),
        confounded_with=confounded,
        unexplained=unexplained,
        heldout_rms_before=rms0,
        heldout_rms_after=rms1,
        improvement=float(improvement),
        system=model.name,
        noise_floor=floor,
        statistics=F0,
        statistics_after=F1,
        ranking=ranking,
        conditions=conditions,
        coefficients=coeffs,
        series=series,
        train_cycles=data.n_train // data.spc,
        heldout_cycles=(n - data.n_train) // data.spc,
        timings=timings,
        phase_source=data.phase_source,
        notes=tuple(notes),
    )


def _series(
    data: _Data, channels: list[str], held: FloatArray, E0: FloatArray, E1: FloatArray,
    residual_table: Callable[..., FloatArray], rp0: FloatArray, xi0: FloatArray,
    rp1: FloatArray, xi1: FloatArray, xi_rec: FloatArray,
) -> dict[str, Channels]:
    out: dict[str, Channels] = {}
    n = data.n_used
    t = data.t[:n][held] - data.t[0]
    ph = np.mod(data.phase[:n][held], 2 * np.pi)
    npas = data.pas.size
    for i, c in enumerate(channels):
        if i < npas:
            recd = data.r[:n][held, data.pas[i]]
            b, a = rp0[held, i], rp1[held, i]
        else:
            k = i - npas
            recd = xi_rec[held, k]
            b, a = xi0[held, k], xi1[held, k]
        out[c] = Channels(t=t, phase=ph, recorded=recd, before=b, after=a)
    return out


def diagnose_recording(
    rec: Recording,
    system: str | None = None,
    config: DiagnoseConfig = DiagnoseConfig(),
    reference: Recording | None = None,
    progress: Callable[[str], None] | None = None,
) -> DiagnosisReport:
    """:func:`diagnose` with the nominal model of a named system (default ``rec.system``)."""
    from suds_ros.core.physics.systems import make_system

    name = system or rec.system
    sysobj = make_system(name)
    model = getattr(sysobj, "model", None)
    if not isinstance(model, ChainModel):
        raise SudsConfigError(
            f"system {name!r}: diagnosis needs an RFT chain (purcell3, swimmer9, nlinkN); got {type(sysobj).__name__}"
        )
    return diagnose(rec, model, config, reference=reference, progress=progress)
