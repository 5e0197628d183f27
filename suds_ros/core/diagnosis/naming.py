"""Naming a mismatch: the equation error of every candidate effect.

Each candidate is fitted on the training half and scored on the held-out half (the stepwise choice
among them is :mod:`.selection`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.optimize

from suds_ros.core import se2
from suds_ros.core._typing import BoolArray, FloatArray
from suds_ros.core.diagnosis.data import Data
from suds_ros.core.diagnosis.lsq import fd_jacobian, with_jacobian
from suds_ros.core.diagnosis.replay import window_xi
from suds_ros.core.diagnosis.report import set_label
from suds_ros.core.errors import SudsConfigError
from suds_ros.core.physics.effects import EFFECTS, EquationTerms, neutral_params
from suds_ros.core.physics.rft import ChainModel, RFTChain
from suds_ros.core.resample import knot_fit, window_any


# =============================================================================== equation error
class _EqError:
    """Equation-error residuals of the passive torque balance and the body velocity.

    Interval i (sample k → k+1): midpoint shape r̄_i, ṙ_i = Δr/Δt (exact for the piecewise-linear
    servo stream).  Torque residuals are per interval (so Coulomb's stick/slip switching is not
    smeared); body velocities are compared over windows of w intervals (SE(2) composition).
    The nominal model's own passive-joint terms (its damping, cubic spring, dry friction and
    stiffness scale, as in :class:`~suds_ros.core.physics.rft.RFTChain`) are part of every
    residual; a candidate's terms add to them, as its ``apply`` adds to the model.
    """

    def __init__(self, data: Data, model: ChainModel, lo: int, hi: int, w: int) -> None:
        self.model = model
        self.w = w
        self.dt = data.dt
        r = data.r[lo:hi]
        self.rbar = 0.5 * (r[1:] + r[:-1])  # (n−1, nj)
        self.rdot = np.diff(r, axis=0) / data.dt
        self.pas = data.pas
        self.act = data.act
        self.k = np.asarray(model.stiffness, dtype=float)[data.pas]
        self.rest = np.asarray(model.rest, dtype=float)[data.pas]
        # the nominal model's passive terms beside the linear spring (zero for the built-in swimmers)
        self.k3 = np.asarray(model.k3, dtype=float)[data.pas]
        self.d = np.asarray(model.damping, dtype=float)[data.pas]
        self.mu = np.asarray(model.coulomb, dtype=float)[data.pas]
        self.stiffness_scale = float(model.stiffness_scale)
        self.t = data.t[lo:hi]
        self.pose_t = data.pose_t
        self.pose_raw = data.pose_raw
        self.resampled = data.resampled
        self.yaw_mid = 0.5 * (data.pose[lo:hi - 1, 2] + data.pose[lo + 1:hi, 2])
        self._metric_cache: dict[tuple[float, ...], tuple[FloatArray, FloatArray]] = {}
        self._link_cache: dict[tuple[float, ...], tuple[FloatArray, FloatArray]] = {}
        self._xi_rec_cache: dict[float, FloatArray] = {}
        self.nint = self.rbar.shape[0]
        self.nwin = self.nint - w + 1
        self.rdot_p = self.rdot[:, self.pas]
        # Intervals with an end at or next to a lost shape sample (:attr:`Data.shape_lost`) are not
        # measured: across the gap Δr/Δt is the slope of the bridge, not the joint's rate, and a
        # passive joint's torque balance there is wrong by whatever the lost samples held (measured:
        # a Coulomb friction named as viscous damping with 30 % of the shape samples lost in bursts).
        # They are left out of the torque channels, and so is every ξ window that composes one, or
        # whose end is at or next to a lost pose sample.
        lost = np.zeros(hi - lo, dtype=bool) if data.shape_lost is None else data.shape_lost[lo:hi]
        self.measured = ~(lost[:-1] | lost[1:])
        win_ok = ~window_any(lost, w)  # the w intervals i … i + w − 1 span samples i … i + w
        if data.pose_gap is not None:
            pg = data.pose_gap[lo:hi]
            win_ok &= ~(pg[: self.nwin] | pg[w:])
        self.win_measured = win_ok

    def _win(self, x: FloatArray) -> FloatArray:
        """Moving average over w intervals along axis 0."""
        c = np.cumsum(np.concatenate([np.zeros((1,) + x.shape[1:]), x], axis=0), axis=0)
        return (c[self.w:] - c[:-self.w]) / self.w

    def drag_terms(self, p: EquationTerms) -> tuple[FloatArray, FloatArray, tuple[FloatArray, FloatArray]]:
        """Per-interval (D q̇)_p (nint, np), windowed still-fluid ξ (nwin, 3) and the rows of the reduced drag.

        (D q̇)_p = M ṙ with the reduced drag matrix M (nint, np, nj); ξ is the pose frame's.  The
        rows of M are returned as (own, others): each passive joint's entry for its own rate
        (nint, np) and the sum of squares of its other entries (nint, np), what :meth:`_noise_gain`
        needs.

        The geometric terms of ``p`` (drag ratio, link lengths and drag, pose frame) are applied.
        The drag metric does not depend on the pose frame, so the metric's products are cached
        without it and a pose-frame change costs only the frame change and the composition.
        """
        key = p.geometry_key()
        hit = self._metric_cache.get(key)
        if hit is not None:
            return hit
        p0 = dataclasses.replace(p, pose=(0.0, 0.0, 0.0))
        key0 = p0.geometry_key()
        base = self._link_cache.get(key0)
        if base is None:
            chain = RFTChain(p0.chain_model(self.model))
            D = chain.drag_metric(self.rbar)  # (m, 3+nj, 3+nj)
            rdot = self.rdot
            # ξ = −D_bb⁻¹ D_br ṙ, and the passive drag torques τ_p = D_pb ξ + D_pr ṙ = M ṙ with the
            # reduced drag matrix M = D_pr − D_pb D_bb⁻¹ D_br (also the torques' sensitivity to ṙ)
            A = np.linalg.solve(D[:, :3, :3], D[:, :3, 3:])  # (m, 3, nj)
            xi = -np.einsum("bij,bj->bi", A, rdot)
            M = D[:, 3 + self.pas, 3:] - np.einsum("bpk,bkj->bpj", D[:, 3 + self.pas, :3], A)
            tau = np.einsum("bpj,bj->bp", M, rdot)
            # for the noise gain: M's own-joint entries (a candidate's damping adds to them) and the
            # sum of squares of the others (the same for every candidate of this geometry)
            ar = np.arange(self.pas.size)
            own = M[:, ar, self.pas]
            off = M.copy()
            off[:, ar, self.pas] = 0.0
            base = (tau, xi, (own, np.sum(off**2, axis=2)))
            if len(self._link_cache) > 64:
                self._link_cache.clear()
            self._link_cache[key0] = base
        tau, xi, drag_rows = base
        chain = RFTChain(p.chain_model(self.model))
        xi_w = self._compose(chain.to_pose_frame(xi))  # the recorded ξ is the pose frame's
        if len(self._metric_cache) > 64:
            self._metric_cache.clear()
        self._metric_cache[key] = (tau, xi_w, drag_rows)
        return tau, xi_w, drag_rows

    def _compose(self, xi: FloatArray) -> FloatArray:
        """Windowed body velocity: log of the product of the w per-interval exponentials."""
        tw = xi * self.dt
        n = tw.shape[0] - self.w + 1
        P = np.zeros((n, 3))
        for i in range(self.w):
            P = se2.exp_step(P, tw[i:i + n])
        return se2.log(P) / (self.w * self.dt)

    def xi_recorded(self, delay: float) -> FloatArray:
        """Windowed recorded body velocity with pose re-sampled at t + delay (undoing a stamp lag)."""
        key = round(float(delay), 9)
        hit = self._xi_rec_cache.get(key)
        if hit is not None:
            return hit
        # times from the first pose stamp: a shift of a few µs is lost in absolute stamps (1.7e9 s
        # resolve 0.24 µs), and the time-offset fit differentiates with respect to it
        t0 = self.pose_t[0]
        ts = (self.t - t0) + delay
        if self.resampled:  # a stream of its own: the spline with knots where the drive has its kinks
            P = knot_fit(self.pose_t - t0, self.pose_raw, ts)
        else:
            P = np.stack([np.interp(ts, self.pose_t - t0, self.pose_raw[:, c]) for c in range(3)], axis=1)
        out = window_xi(P, self.w, self.dt)
        if len(self._xi_rec_cache) > 256:
            self._xi_rec_cache.clear()
        self._xi_rec_cache[key] = out
        return out

    def _noise_gain(self, drag_rows: tuple[FloatArray, FloatArray], damping: FloatArray,
                    stiffness: FloatArray) -> FloatArray:
        """How much each interval's torque residual moves per radian of joint-angle noise (nint, np).

        The residual is an equation error, not a measurement: its noise comes from the noisy
        joint angles, through ṙ = Δr/Δt (each joint, σ·√2/Δt) into the drag and damping torques
        M ṙ + d ṙ_p, and through r̄ (σ/√2) into the spring.  A candidate that raises the drag
        (a larger drag ratio) therefore raises the residual's noise, and a plain least-squares
        likelihood counted that against it: anisotropy errors were named as stiffness-to-drag
        errors, which lower the drag relative to the spring.  Dividing by this gain (the noise
        assumed alike on every joint) leaves residuals whose noise is the same for every
        candidate, as an errors-in-variables fit weighs its equation errors.
        """
        own, others = drag_rows
        # ∂τ_p/∂ṙ is the row of M, with the passive joint's own damping d·ṙ_p added to its own entry
        g2 = (2.0 / self.dt**2) * (others + (own + damping) ** 2) + 0.5 * stiffness**2
        return np.sqrt(np.maximum(g2, 1e-300))

    def valid(self, delay_max: float) -> BoolArray:
        """Measured windows whose re-sampled pose stays away from the ends of the span."""
        ok = self.win_measured.copy()
        n_edge = int(np.ceil(abs(delay_max) / self.dt)) + 1
        ok[:n_edge] = False
        ok[-n_edge:] = False
        return ok

    def residuals(self, p: EquationTerms, rdot_thr: FloatArray,
                  normalised: bool = False) -> tuple[FloatArray, FloatArray]:
        """Torque residuals, shape (nint, np), and body-velocity residuals, shape (nwin, 3), under parameters ``p``.

        ``normalised``: each torque residual divided by its sensitivity to the joint-angle noise
        (:meth:`_noise_gain`), so it is in radians and its noise part does not depend on ``p``.
        """
        tau, xi_w, drag_rows = self.drag_terms(p)
        e_spring = self.rbar[:, self.pas] - self.rest - p.offset
        scale = p.scale * self.stiffness_scale
        spring = -scale * p.kscale * self.k * e_spring - scale * (self.k3 + p.k3) * e_spring**3
        e = tau + (self.d + p.d) * self.rdot_p - spring
        # Intervals where a joint's measured velocity is within noise of zero are left out of its
        # torque channel for every candidate: there the joint may be stuck (any friction torque
        # in [−mu, mu] is admissible) and sign(ṙ) is noise, so a dead zone would "explain" noise.
        v = self.rdot_p
        slip = (np.abs(v) > rdot_thr) & self.measured[:, None]
        e = np.where(slip, e + (self.mu + p.mu) * np.sign(v), 0.0)
        if normalised:
            k_local = scale * (p.kscale * self.k + 3.0 * (self.k3 + p.k3) * e_spring**2)  # −∂spring/∂r̄
            e = e / self._noise_gain(drag_rows, self.d + p.d, k_local)
        xi_pred = xi_w
        if p.flow[0] != 0.0 or p.flow[1] != 0.0:
            c, s = np.cos(self.yaw_mid), np.sin(self.yaw_mid)
            U = np.stack([c * p.flow[0] + s * p.flow[1], -s * p.flow[0] + c * p.flow[1]], axis=1)
            xi_pred = xi_w.copy()
            xi_pred[:, :2] += self._win(U)
        ex = self.xi_recorded(p.delay) - xi_pred
        return e, ex


# =============================================================================== candidates
@dataclass(frozen=True)
class Candidate:
    """A set of catalogue effects with free parameters (empty: the nominal model)."""

    parts: tuple[tuple[str, str | None], ...]  # (effect id, target joint name or None)

    @property
    def label(self) -> str:
        return set_label(self.parts)

    def bounds(self) -> tuple[list[float], list[float]]:
        lo, hi = [], []
        for n, _ in self.parts:
            for p in EFFECTS[n].params:
                lo.append(p.lower)
                hi.append(p.upper)
        return lo, hi

    def neutral(self, model: ChainModel | None = None) -> FloatArray:
        """The parameters that leave ``model``'s physics unchanged (:func:`~.effects.neutral_params`)."""
        return np.array([v for n, _ in self.parts for v in neutral_params(n, model).values()], dtype=float)

    def scales(self) -> FloatArray:
        return np.array([p.scale for n, _ in self.parts for p in EFFECTS[n].params])

    def slices(self) -> list[slice]:
        """Each part's parameters in the canonical parameter vector (the order of :meth:`bounds`)."""
        ends = np.cumsum([len(EFFECTS[n].params) for n, _ in self.parts], dtype=int)
        return [slice(int(e) - len(EFFECTS[n].params), int(e)) for (n, _), e in zip(self.parts, ends)]

    def effects(self, x: FloatArray) -> list[dict[str, object]]:
        out: list[dict[str, object]] = []
        i = 0
        for n, tgt in self.parts:
            spec = EFFECTS[n]
            e: dict[str, object] = {"name": n, ("link" if spec.needs_link else "joint"): tgt}
            for p in EFFECTS[n].params:
                e[p.name] = float(x[i])
                i += 1
            out.append(e)
        return out


def equation_terms(cand: Candidate, x: FloatArray, data: Data, model: ChainModel) -> EquationTerms:
    """The candidate's effects at parameters ``x`` in equation-error form (each effect's ``equation``)."""
    pas = list(data.pas)
    terms = EquationTerms.neutral(len(pas), model.drag_ratio, model.n_links)
    i = 0
    for n, tgt in cand.parts:
        spec = EFFECTS[n]
        if tgt is None:
            j = None
        elif spec.needs_link:
            j = int(tgt.rsplit("_", 1)[1]) - 1
        else:
            j = pas.index(data.names.index(tgt))
        spec.equation(terms, j, {p.name: x[i + k] for k, p in enumerate(spec.params)})
        i += len(spec.params)
    return terms


def catalogue_candidates(model: ChainModel, model_suspects: bool = False) -> list[Candidate]:
    """Every single-effect candidate for a system: joint effects on each passive joint, global effects.

    With ``model_suspects`` the robot model's own parameters are suspects too (effects whose
    ``kind`` is ``"model"``: per link, per passive joint or global); test-only effects never are.
    A fully actuated chain (no passive joint) has no candidate that acts through passive joints
    (``EffectSpec.needs_passive``): only the global effects and the model's parameters.
    """
    names = model.joint_names
    out: list[Candidate] = []
    for eid, spec in EFFECTS.items():
        if spec.kind == "test" or (spec.kind == "model" and not model_suspects):
            continue
        if spec.needs_passive and not model.passive:
            continue
        if spec.needs_link:
            out.extend(Candidate(((eid, f"link_{i + 1}"),)) for i in range(model.n_links))
            continue
        if spec.needs_joint:
            for j in model.passive:
                out.append(Candidate(((eid, names[j]),)))
        else:
            out.append(Candidate(((eid, None),)))
    return out


class Scorer:
    """Fits candidates by equation error on the training half and scores them on the held-out half."""

    DELAY_MAX = 0.2
    QUICK_NFEV = 8  # least-squares evaluations of a screening fit

    def __init__(self, data: Data, model: ChainModel, w: int, sig_r: FloatArray) -> None:
        self.data = data
        self.model = model
        self.train = _EqError(data, model, 0, data.n_train, w)
        self.test = _EqError(data, model, data.n_train, data.n_used, w)
        self.w = w
        # threshold on |ṙ_p| below which a joint may be stuck: 3σ of the interval-velocity noise
        # (capped at the 97 % quantile of |ṙ_p| so a poor noise estimate cannot empty a channel).
        # The cap once was the 30 % quantile: on a joint whose friction holds it stuck 80 % of the
        # time, that put the threshold inside the noise, and the stuck intervals, their sign(ṙ)
        # random, cancelled the friction (fitted at a quarter of its value on noise-free data)
        thr = 3.0 * np.sqrt(2.0) * np.nan_to_num(sig_r, nan=1e-3) / data.dt
        cap = np.quantile(np.abs(self.train.rdot_p[self.train.measured]), 0.97, axis=0)
        self.rdot_thr = np.minimum(thr, cap)
        self.ok_train = self.train.valid(self.DELAY_MAX)
        self.ok_test = self.test.valid(self.DELAY_MAX)
        npas = data.pas.size
        self.n_meas_train, self.n_meas_test = int(self.train.measured.sum()), int(self.test.measured.sum())
        self.n_eff_train = np.array([self.n_meas_train] * npas + [self.ok_train.sum() / w] * 3, dtype=float)
        self.n_eff_test = np.array([self.n_meas_test] * npas + [self.ok_test.sum() / w] * 3, dtype=float)
        # least-squares row weights: overlapping ξ windows count 1/w each
        self.row_w = np.array([1.0] * npas + [1.0 / np.sqrt(w)] * 3)
        # the BIC penalty per parameter, (1/2)·log n_eff, nats
        self.pen_unit = 0.5 * np.log(max(float(np.median(self.n_eff_train)), 2.0))
        null = Candidate(())
        self.null = null
        e_tr, x_tr = self._res(self.train, null, np.zeros(0))
        e_te, x_te = self._res(self.test, null, np.zeros(0))
        self.rss0_train = self._rss(e_tr, x_tr, self.ok_train, self.n_meas_train)
        self.rss0_test = self._rss(e_te, x_te, self.ok_test, self.n_meas_test)

    def _res(self, eq: _EqError, cand: Candidate, x: FloatArray) -> tuple[FloatArray, FloatArray]:
        p = equation_terms(cand, x, self.data, self.model)
        return eq.residuals(p, self.rdot_thr, normalised=True)

    @staticmethod
    def _rss(e: FloatArray, ex: FloatArray, ok: FloatArray, n_measured: int) -> FloatArray:
        """Mean squared residual per channel (torques over the ``n_measured`` measured intervals, then ξ).

        A channel without a usable interval (every ξ window at a gap: n_eff 0) reads 1e-30 for
        every candidate, so it adds nothing to a gain.
        """
        ex = ex[ok]
        ex = np.where(np.isfinite(ex), ex, 0.0)
        torque = (e**2).sum(axis=0) / max(n_measured, 1)
        return np.concatenate([torque, (ex**2).sum(axis=0) / max(ex.shape[0], 1)]) + 1e-30

    def gain(self, rss: FloatArray, rss0: FloatArray, n_eff: FloatArray) -> float:
        return float(0.5 * np.sum(n_eff * np.log(rss0 / np.maximum(rss, 1e-300))))

    def _stack(self, e: FloatArray, ex: FloatArray, ok: FloatArray, wts: FloatArray) -> FloatArray:
        npas = e.shape[1]
        ex = ex[ok]
        ex = np.where(np.isfinite(ex), ex, 0.0)
        a = (e * (wts[:npas] * self.row_w[:npas])).ravel()
        b = (ex * (wts[npas:] * self.row_w[npas:])).ravel()
        return np.concatenate([a, b])

    def fit(
        self, cand: Candidate, x0: FloatArray | None = None, quick: bool = False,
    ) -> tuple[FloatArray, float, float]:
        """Fit on the training half; returns (parameters, training gain, held-out gain).

        ``x0`` is a start besides the multi-start's.  ``quick`` (a screen; needs ``x0``): one short
        least-squares run from ``x0`` alone, no multi-start and no weight re-estimation.
        """
        lo_all, hi_all = cand.bounds()
        lo, hi = np.asarray(lo_all, dtype=float), np.asarray(hi_all, dtype=float)
        scales = cand.scales()
        base = cand.neutral(self.model)
        starts = [] if x0 is None else [np.asarray(x0, dtype=float)]
        quick = quick and x0 is not None
        if not quick:
            starts.append(base + 0.0)
            # a few starts per parameter on both sides (nonconvex: Coulomb dead zone, drag ratio)
            for k, sgn in ((1.0, 1), (1.0, -1), (3.0, 1), (3.0, -1)):
                starts.append(base + sgn * k * scales)
        weights = 1.0 / np.sqrt(self.rss0_train)
        ok = self.ok_train
        # starts stay a thousandth of a scale inside the bounds: the trust-region solver's scaling
        # shrinks a step by the distance to a bound, so from a start on the bound (a neutral
        # damping or friction of 0) it stops at once, reporting the neutral value as the fit
        # (measured: a damping of 0.1 with 628 nats of known-parameter evidence fitted as 0)
        lo_in, hi_in = lo + 1e-3 * scales, hi - 1e-3 * scales

        def fun(x: FloatArray, wts: FloatArray) -> FloatArray:
            e, ex = self._res(self.train, cand, x)
            return self._stack(e, ex, ok, wts)

        value, jac = with_jacobian(fun, 1e-3, 1e-3 * scales, hi)  # steps that do not vanish at 0
        best_x, best_c = None, np.inf
        for s in starts:
            s = np.clip(s, lo_in, hi_in)
            try:
                c0 = float(np.sum(fun(s, weights) ** 2))
            except (FloatingPointError, np.linalg.LinAlgError, SudsConfigError):
                continue
            if np.isfinite(c0) and c0 < best_c:
                best_x, best_c = s, c0
        if best_x is None:
            return base + 0.0, -np.inf, -np.inf
        sols = []
        # refine from the best start and from the given one
        for s in [best_x] + ([starts[0]] if x0 is not None and not quick else []):
            x = np.clip(s, lo_in, hi_in)
            wts = weights
            for _ in range(1 if quick else 2):  # re-estimate channel weights once
                try:
                    sol = scipy.optimize.least_squares(
                        value, x, jac=jac, args=(wts,), bounds=(lo, hi), x_scale=scales,
                        max_nfev=self.QUICK_NFEV if quick else 60,
                    )
                except (FloatingPointError, np.linalg.LinAlgError, SudsConfigError, ValueError):
                    break
                x = sol.x
                e, ex = self._res(self.train, cand, x)
                wts = 1.0 / np.sqrt(np.maximum(self._rss(e, ex, ok, self.n_meas_train), 1e-300))
            e, ex = self._res(self.train, cand, x)
            sols.append((self.gain(self._rss(e, ex, ok, self.n_meas_train), self.rss0_train, self.n_eff_train), x))
        g_tr, x = max(sols, key=lambda s: s[0])
        return x, g_tr, self.heldout_gain(cand, x)

    def sensitivity(self, cand: Candidate, x: FloatArray, first: int = 0) -> FloatArray:
        """How the training residuals move with ``cand``'s parameters from index ``first`` on, at ``x``.

        Forward differences of the stacked residuals, each channel weighted by its nominal RMS as the
        fit starts; one column per parameter.  Steps are 1e-4 of the parameter (or of its scale at
        0), so an exact relation between effects shows to about that relative error.
        """
        x = np.asarray(x, dtype=float)
        weights = 1.0 / np.sqrt(self.rss0_train)
        head = x[:first]

        def fun(z: FloatArray) -> FloatArray:
            e, ex = self._res(self.train, cand, np.concatenate([head, z]))
            return self._stack(e, ex, self.ok_train, weights)

        z = x[first:]
        steps = np.maximum(1e-4 * np.abs(z), 1e-4 * cand.scales()[first:])
        return fd_jacobian(fun, z, fun(z), steps, np.asarray(cand.bounds()[1][first:], dtype=float))

    def heldout_gain(self, cand: Candidate, x: FloatArray) -> float:
        """Held-out log-likelihood gain of ``cand`` at ``x`` over the nominal model, nats."""
        e, ex = self._res(self.test, cand, x)
        return self.gain(self._rss(e, ex, self.ok_test, self.n_meas_test), self.rss0_test, self.n_eff_test)
