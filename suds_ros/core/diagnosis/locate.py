"""Locating a mismatch: channel residuals, F statistics, phase ranges, conditions, coefficients."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.stats

from suds_ros.core._typing import BoolArray, FloatArray, IntArray
from suds_ros.core.diagnosis.data import Data
from suds_ros.core.diagnosis.floor import Floors
from suds_ros.core.diagnosis.replay import midpoint_xi, window_xi
from suds_ros.core.diagnosis.report import BODY, DiagnoseConfig, Located
from suds_ros.core.fourier import fourier_basis, fourier_basis_and_derivative
from suds_ros.core.ident.sysid import SudsConfig, SudsRegressor, regressor_input
from suds_ros.core.physics.rft import ChainModel
from suds_ros.core.resample import window_any


@dataclass(frozen=True)
class ChannelTable:
    """The diagnosis channels (passive angles, then ξx, ξy, ξθ) and their held-out statistics.

    ``xi_rec`` (n_used, 3) is the recorded windowed body velocity at the window midpoints;
    ``held`` marks the held-out samples among the first n_used.
    """

    data: Data
    channels: tuple[str, ...]
    held: BoolArray
    xi_rec: FloatArray
    w: int = 1

    @classmethod
    def of(cls, data: Data, w: int) -> "ChannelTable":
        """The table of a prepared recording with the body velocity over ``w``-sample windows."""
        channels = tuple(data.names[j] for j in data.pas) + BODY
        held = np.arange(data.n_used) >= data.n_train
        return cls(data, channels, held, midpoint_xi(data.pose, data, w), w)

    def residuals(self, rp_sim: FloatArray, xi_sim: FloatArray) -> FloatArray:
        """Recorded minus simulated, (n_used, channels); NaN where a stream had no sample (:func:`.grid.gaps`).

        A passive angle is left out at a shape gap; a body velocity where its window starts or
        ends at a pose gap, or holds a shape gap anywhere (the replay's drive, and so its pose, is
        interpolated there; measured: a nominal swimmer9 with 10 % of its shape samples lost was
        located on ξ_y, F 2.2, when only the window ends were checked).
        """
        data, n = self.data, self.data.n_used
        e = np.full((n, len(self.channels)), np.nan)
        e[:, : data.pas.size] = data.r[:n][:, data.pas] - rp_sim
        e[:, data.pas.size:] = self.xi_rec - xi_sim
        if data.shape_gap is not None and data.pose_gap is not None:
            e[data.shape_gap[:n], : data.pas.size] = np.nan
            # the replayed pose follows the drive, so a shape gap also bends the simulated ξ
            out = _window_touches(data.pose_gap[:n], self.w) | _window_holds(data.shape_gap[:n], self.w)
            e[out, data.pas.size:] = np.nan
        return e

    def rms(self, E: FloatArray) -> dict[str, float]:
        """Held-out RMS of each channel's residual (NaN for a channel without a usable sample)."""
        return {c: float(np.sqrt(_mean_square(E[self.held, i]))) for i, c in enumerate(self.channels)}

    def fstats(self, E: FloatArray, floor: Mapping[str, float], held: bool = True) -> dict[str, float]:
        """F = mean(residual²) / floor² per channel, on the held-out half (``held``) or the training half.

        NaN for a channel without a usable sample there (never located; the report says so).
        """
        rows = self.held if held else ~self.held
        return {c: float(_mean_square(E[rows, i]) / floor[c] ** 2) for i, c in enumerate(self.channels)}

    def untested(self, E: FloatArray) -> list[str]:
        """The channels without a usable held-out sample in ``E`` (every one left out at a gap)."""
        return [c for i, c in enumerate(self.channels) if not np.isfinite(E[self.held, i]).any()]

    def evidence(self, E0: FloatArray, E1: FloatArray, n_params: int, held: bool = True) -> float:
        """Output-error evidence of the residuals ``E1`` over ``E0``, nats.

        On the held-out half (``held``) or the training half.
        Gaussian profile log-likelihood gain Σ_c (n_c/2)·log(RSS0_c/RSS1_c) over the channels,
        minus the BIC penalty (n_params/2)·log(median n_c); n_c counts the finite residuals of a
        passive angle, and those of a body velocity over the window ``w`` (its windowed estimate
        is correlated over a window).
        """
        rows = self.held if held else ~self.held
        held0, held1 = E0[rows], E1[rows]
        ok = np.isfinite(held0) & np.isfinite(held1)
        rss0 = np.sum(np.where(ok, held0, 0.0) ** 2, axis=0)
        rss1 = np.sum(np.where(ok, held1, 0.0) ** 2, axis=0)
        npas = self.data.pas.size
        n = ok.sum(axis=0).astype(float)
        n[npas:] /= self.w
        use = (n > 0) & (rss0 > 0)
        gain = 0.5 * np.sum(n[use] * np.log(rss0[use] / np.maximum(rss1[use], 1e-300)))
        return float(gain - 0.5 * n_params * np.log(max(float(np.median(n[use])) if use.any() else 2.0, 2.0)))

    def floor(self, floors: Floors) -> dict[str, float]:
        """Noise floor per channel from :func:`~suds_ros.core.diagnosis.floor.noise_floor`'s output."""
        sig_rp, s_xy, s_th = floors
        sig_rp = np.asarray(sig_rp, dtype=float) * np.sqrt(self.data.rp_noise_power)  # restarts' share (:class:`Data`)
        return dict(zip(self.channels, list(sig_rp) + [s_xy, s_xy, s_th]))


def _mean_square(x: FloatArray) -> float:
    """Mean of x² over the finite values (NaN, without a warning, when there is none)."""
    x = x[np.isfinite(x)]
    return float(np.mean(x**2)) if x.size else float("nan")


def _window_touches(gap: BoolArray, w: int) -> BoolArray:
    """Window midpoints i (windows [i − w//2, i − w//2 + w]) with an end at a ``gap`` point."""
    out = np.zeros(gap.size, dtype=bool)
    g = np.flatnonzero(gap)
    for end in (g + w // 2, g - w + w // 2):
        ok = (end >= 0) & (end < gap.size)
        out[end[ok]] = True
    return out


def _window_holds(gap: BoolArray, w: int) -> BoolArray:
    """Window midpoints i (windows [i − w//2, i − w//2 + w]) with a ``gap`` point anywhere in the window."""
    h = w // 2
    return window_any(np.concatenate([np.zeros(h, dtype=bool), gap, np.zeros(w - h, dtype=bool)]), w)


def locate_channels(
    F: Mapping[str, float], E0: FloatArray, table: ChannelTable, cycle: FloatArray, config: DiagnoseConfig
) -> list[Located]:
    """Channels with F above ``config.f_threshold``, with the phase ranges of their residual ``E0``.

    ``cycle`` (n_used,) numbers the gait cycles of the phase (the replicates of the phase test); a
    located channel without a significant phase bin gets the whole cycle.
    """
    held, phase = table.held, table.data.phase[: table.data.n_used]
    out: list[Located] = []
    for i, c in enumerate(table.channels):
        if F[c] > config.f_threshold:
            ranges = phase_ranges(phase[held], E0[held, i], cycle[held], config.phase_bins, config.phase_alpha)
            if not ranges:
                ranges = ((0.0, round(2 * np.pi, 4)),)
            out.append(Located(c, ranges, F[c]))
    return out


def channel_conditions(
    channels: Sequence[str], E0: FloatArray, table: ChannelTable, model: ChainModel
) -> dict[str, tuple[str, ...]]:
    """:func:`conditions` of each of ``channels`` (held-out residual ``E0``)."""
    held = table.held
    idx = np.flatnonzero(held)
    return {c: conditions(E0[held, table.channels.index(c)], idx, table.data, model) for c in channels}


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


def phase_ranges(
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
    nc = np.sum(np.isfinite(M), axis=0)
    tested = nc >= 2  # a bin seen in fewer than two cycles (frames lost) has no spread to test against
    tstat = np.zeros(bins)
    if tested.any():
        mean = np.nanmean(M[:, tested], axis=0)
        sd = np.nanstd(M[:, tested], axis=0, ddof=1)
        tstat[tested] = mean / np.maximum(sd / np.sqrt(nc[tested]), 1e-300)
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


def conditions(
    e: FloatArray, idx: IntArray, data: Data, model: ChainModel
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
            out.append((abs(t), f"sign of ṙ({nm}): mean residual {a.mean():+.3g} when ṙ>0 "
                                f"vs {b.mean():+.3g} when ṙ<0 (t={t:.1f})"))
        dev = r[:, j] - rest[j]
        c = np.corrcoef(e, dev)[0, 1]
        c3 = np.corrcoef(e, dev**3)[0, 1]
        big = np.abs(dev) > np.quantile(np.abs(dev), 0.75)
        ratio = np.sqrt(np.mean(e[big] ** 2) / max(np.mean(e[~big] ** 2), 1e-300))
        out.append((abs(c) * np.sqrt(e.size),
                    f"r({nm}) − rest: correlation {c:+.2f} (cubic {c3:+.2f}); RMS at large |r − rest| ×{ratio:.2f}"))
    yaw = data.pose[idx, 2]
    X = np.stack([np.cos(yaw), np.sin(yaw), np.ones_like(yaw)], axis=1)
    coef, *_ = np.linalg.lstsq(X, e, rcond=None)
    r2 = 1 - np.var(e - X @ coef) / max(np.var(e), 1e-300)
    out.append((r2 * np.sqrt(e.size) * 3,
                f"heading: residual ≈ {coef[0]:+.3g}·cos(yaw) {coef[1]:+.3g}·sin(yaw) (R²={r2:.2f})"))
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
        out.append((abs(best[0]) * np.sqrt(e.size),
                    f"lag: peak cross-correlation {best[0]:+.2f} with ṙ({best[2]}) "
                    f"at {best[1] * data.dt * 1e3:+.0f} ms"))
    out.sort(key=lambda z: -z[0])
    return tuple(s for _, s in out[:4])


def coefficient_comparison(
    data: Data, sim_rp: FloatArray, sim_pose: FloatArray, w: int
) -> tuple[tuple[str, str, float, tuple[tuple[float, float], ...]], ...]:
    """Compare SUDS coefficients identified from the recording and from the replay (training half).

    Returns (group, output, z, phase ranges) sorted by z, where z is the RMS over phase of the
    coefficient difference divided by a split-half noise scale of the recording's coefficients.
    Outputs are taken on ``w``-sample intervals (the same estimator for both).
    """
    X, Y_rec, Y_sim, ok, half = _regression_data(data, sim_rp, sim_pose, w)
    cfg = SudsConfig(regressors=2, intercept_order=6, linear_order=2, bilinear_order=1, ridge=1e-6)
    na = data.act.size
    fits = {}
    for key, Y, sel in (
        ("rec", Y_rec, ok),
        ("sim", Y_sim, ok),
        ("a", Y_rec, ok & half),
        ("b", Y_rec, ok & ~half),
    ):
        fits[key] = SudsRegressor(cfg, n_actuated=na).fit(X[sel], Y[sel])
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
            rows.append((g, oname, z, _runs(d > 3 * sc)))
    rows.sort(key=lambda r_: -r_[2])
    return tuple(rows)


def _runs(sig: BoolArray) -> tuple[tuple[float, float], ...]:
    """Phase ranges (rad, rounded to 1e-3) of the runs of True in ``sig`` over one cycle (no wrap)."""
    ranges: list[tuple[float, float]] = []
    width = 2 * np.pi / sig.size
    i = 0
    while i < sig.size:
        if sig[i]:
            j = i
            while j + 1 < sig.size and sig[j + 1]:
                j += 1
            ranges.append((round(i * width, 3), round((j + 1) * width, 3)))
            i = j + 1
        else:
            i += 1
    return tuple(ranges)


def _regression_data(
    data: Data, sim_rp: FloatArray, sim_pose: FloatArray, w: int
) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray, BoolArray]:
    """SUDS regressors X and outputs of the recording and of the replay on the training half.

    Returns X (phase, δr, δṙ_a, r, ṙ_a: :func:`~suds_ros.core.ident.sysid.regressor_input`), Y_rec,
    Y_sim (ξ and ṙ_p over w-sample intervals), the rows where both are finite, and the rows of the
    first half (for the split-half noise scale).
    """
    n = data.n_train
    r = data.r[:n]
    ph = data.phase[:n]
    xi_rec = window_xi(data.pose[:n], w, data.dt)
    rp_rec = r[:, data.pas]
    rp_sim = sim_rp[:n]
    sp = sim_pose[:n] if data.pose_sampling is None else data.pose_sampling.apply(sim_pose[None, :n], [0])[0]
    xi_sim = window_xi(sp, w, data.dt)
    mid = np.arange(n - w)
    phm = 0.5 * (ph[:-w] + ph[w:])
    rmid = 0.5 * (r[:-w] + r[w:])
    rdot = (r[w:] - r[:-w]) / (w * data.dt)
    Fb = fourier_basis(ph, 6)
    coef, *_ = np.linalg.lstsq(Fb, r, rcond=None)
    Fm, dF = fourier_basis_and_derivative(phm, 6)
    theta = Fm @ coef
    omega = ((ph[w:] - ph[:-w]) / (w * data.dt))[:, None]  # local phase rate (phaser phase)
    dtheta = (dF @ coef) * omega
    delta = rmid - theta
    dda = (rdot - dtheta)[:, data.act]
    X = regressor_input(phm, delta, dda, rmid, rdot[:, data.act])
    Y_rec = np.column_stack([xi_rec, (rp_rec[w:] - rp_rec[:-w]) / (w * data.dt)])
    Y_sim = np.column_stack([xi_sim, (rp_sim[w:] - rp_sim[:-w]) / (w * data.dt)])
    ok = np.all(np.isfinite(Y_sim), axis=1) & np.all(np.isfinite(Y_rec), axis=1)
    half = mid < (n - w) // 2
    return X, Y_rec, Y_sim, ok, half
