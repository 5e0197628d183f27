"""Model-based gait optimisation on the physics (``suds optimize --physics``; ``shared/spec/gait.md``).

The objective of a gait is read at its **passive periodic steady state**: the passive joints
start where one cycle brings them back (r_p(T) = r_p(0), T = 1/f), and g_c = g(0)⁻¹ g(T) is
the net motion of the pose frame over that cycle (the pose starts at the identity).

* ``speed`` (m/s) = |translation of g_c|·f, subject to |angle of g_c| ≤ ``max_rotation`` rad;
* ``turn`` (rad/s) = |angle of g_c|·f, subject to a speed ≥ the nominal gait's;
* ``efficiency`` (m/J) = |translation of g_c| / W, W = ∫ τ_a·ṙ_a dt over the cycle (τ_a the
  system's ``actuator_effort``), subject to the rotation bound of ``speed`` and, our addition
  (the spec names none), a speed ≥ the nominal gait's: distance and work both scale as the
  amplitude squared, so without it the best "efficiency" is a vanishing gait that goes nowhere.

How it is made fast
-------------------
* One cycle of many candidate gaits is integrated at once (:class:`CycleEvaluator`): RK4 on the
  passive joints and the commutator-free Lie-group step on the pose (as
  :mod:`~suds_ros.core.physics.integrate`), with the gait's exact r_a(t), ṙ_a(t) at every stage,
  every velocity evaluation one batched call over the candidates.
* The steady state is found by Newton shooting on r_p(0): one batch holds the gait and its n_p
  perturbed starts, giving the cycle map P, its Jacobian Φ = ∂P/∂r_p(0) and the outputs'
  Jacobian G; r_p ← r_p + (I − Φ)⁻¹ (P(r_p) − r_p), warm-started from the last steady state.
* Gradients by forward differences, all perturbed gaits in one batch, each integrated for a
  single cycle from the base gait's steady state and moved to its own steady state by the
  base's linearisation: y* = y + G (I − Φ)⁻¹ (P − r_p*) (error second order in the step).
* The joint range and speed bounds are linear in the Fourier coefficients: they enter SLSQP as
  linear inequalities on a grid of N = ``points_per_harmonic``·K times per cycle, tightened by
  cos(π/N) (the most the fundamental can rise between grid points); the gait returned is scaled
  (if need be) to meet them on a 4096-point grid as well.  The nonlinear constraints are met
  with a relative margin of 1e-3 inside the optimiser (the speed floor is nominal·1.001, the
  rotation bound 0.04995 rad), so that the final scaling cannot break them.

Several starts run SLSQP: the nominal gait (padded to order K), any given gaits, random feasible
gaits, and the best of a screen.  The landscape has many local optima (a wave running one way
or the other, with one wavelength or another), so ``screen`` candidate gaits — travelling waves
of every lag at the largest amplitude the bounds allow, first harmonics of random phase per
joint, random Fourier gaits — are run to their steady state in one batch (a fraction of a
second) and the ``screened`` best distinct ones, by the objective with a penalty for a broken
rotation bound or speed floor, are started from too.  They are added to the random starts, not
put in their place: the screen's best can all lie in one basin (the nominal gait's, on a 7-link
robot; a worse one than random starts found on purcell3 with stiffer springs), and the random
starts are drawn and run first, as before, so the screened ends add to theirs.  Each runs
with the time origin pinned; a gait that turns goes further counted from some points of its
cycle than from others, so each end that would beat the best counted from its best point is
shifted there and optimised again with every coefficient free (``free_origin``).  The best
feasible result is returned with its own steady-state evaluation.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import minimize

from suds_ros.core import se2
from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.core.physics.gait import (
    DEFAULT_MAX_ORDER,
    MAX_ORDER,
    OBJECTIVES,
    Gait,
    GaitLimits,
    check_gait,
    constraint_grid,
    gait_extremes,
    gait_limits,
    nominal_gait,
    shifted_harmonics,
    time_shifted,
    with_predicted,
)
from suds_ros.core.physics.sim import _rest_angles, _still, passive_rate
from suds_ros.core.physics.system import SudsSystem

#: relative margin by which the optimiser meets the nonlinear constraints (rotation bound, speed floor)
MARGIN = 1e-3
#: code of an objective the physics cannot evaluate
UNSUPPORTED_OBJECTIVE = "unsupported_objective"
#: relative gain of another time origin below which an optimised gait is not shifted and polished
ORIGIN_GAIN = 1e-4


@dataclass(frozen=True)
class OptimizeConfig:
    """Settings of :func:`optimize_gait`.

    Parameters
    ----------
    objective : str
        ``speed``, ``turn`` or ``efficiency``.
    order : int
        Harmonics K of the optimised gait (1 ≤ K ≤ 8; the spec's default bound is 3).
    starts : int
        SLSQP starts: the nominal gait, then ``starts − 1`` random feasible gaits.
    screen : int
        Candidate gaits run to their steady state to choose ``screened`` more starts from; 0: no
        screen (as before 2026-12-05).
    screened : int
        More starts: the best distinct gaits of the screen (:func:`screen_starts`), after the
        random ones.
    seed : int
        Seed of the random starts and then of the screen's random candidates.
    max_rotation : float
        Bound on the net rotation per cycle for ``speed`` and ``efficiency``, rad.
    points_per_harmonic : int
        Constraint grid: this many times K points per cycle.
    steps_per_cycle : int or None
        RK4 steps per cycle; None: from the fastest passive relaxation rate λ (:func:`auto_steps`).
    maxiter : int
        SLSQP iterations per start.
    ftol : float
        SLSQP's tolerance on the objective (in units of the scaled objective, ≈ relative).
    fd_step : float
        Forward-difference step on the coefficients, rad.
    free_origin : bool
        Count each gait's cycle from its best point (``speed`` and ``efficiency``).  The spec counts
        the cycle from the gait file's time zero, and a gait that turns goes further counted from
        some points of its cycle than from others (:func:`origin_distances`); the coefficients hold
        the origin, so a gait shifted in time is another gait under the same bounds.  The starts
        run with the origin pinned (:func:`phase_pinned`); then every end that would beat the best
        from another origin is shifted there and optimised again with every coefficient free.
        False: the pinned origin only.
    origin_rounds : int
        Rounds of shift and re-optimisation at most.
    """

    objective: str = "speed"
    order: int = DEFAULT_MAX_ORDER
    starts: int = 4
    screen: int = 256
    screened: int = 2
    seed: int = 0
    max_rotation: float = 0.05
    points_per_harmonic: int = 64
    steps_per_cycle: int | None = None
    maxiter: int = 100
    ftol: float = 1e-8
    fd_step: float = 1e-6
    free_origin: bool = True
    origin_rounds: int = 2

    def __post_init__(self) -> None:
        if self.objective not in OBJECTIVES:
            raise SudsConfigError(f"`objective`: expected one of {list(OBJECTIVES)}, got {self.objective!r}")
        checks = [("order", 1 <= self.order <= MAX_ORDER, f"1..{MAX_ORDER}"), ("starts", self.starts >= 1, "≥ 1"),
                  ("screen", self.screen >= 0, "≥ 0"), ("screened", self.screened >= 0, "≥ 0"),
                  ("max_rotation", self.max_rotation > 0, "> 0"),
                  ("points_per_harmonic", self.points_per_harmonic >= 8, "≥ 8"),
                  ("steps_per_cycle", self.steps_per_cycle is None or self.steps_per_cycle >= 8, "≥ 8"),
                  ("maxiter", self.maxiter >= 1, "≥ 1"), ("ftol", self.ftol > 0, "> 0"),
                  ("fd_step", self.fd_step > 0, "> 0"), ("origin_rounds", self.origin_rounds >= 0, "≥ 0")]
        for name, ok, expected in checks:
            if not ok:
                raise SudsConfigError(f"`{name}`: expected {expected}, got {getattr(self, name)!r}")


@dataclass(frozen=True)
class CycleResult:
    """Outputs of one cycle at the periodic steady state, per candidate (leading axis B).

    Attributes
    ----------
    g_c : (B, 3) net motion over the cycle (x m, y m, angle rad) in the starting pose frame.
    work : (B,) actuator work ∫ τ_a·ṙ_a dt over the cycle, J (NaN when not computed).
    r_p : (B, np) passive joints at the start of the cycle, rad.
    """

    g_c: FloatArray
    work: FloatArray
    r_p: FloatArray


class PeriodicShooting:
    """Passive periodic steady states by Newton shooting on any one-cycle map.

    A subclass provides ``np`` (passive joints), ``gait_hz`` and
    ``cycle(X, rp0) -> (r_p(T), g_c, work)`` for candidate gaits X (B, p) started at r_p(0) = ``rp0``
    (B, np) and the identity pose: the physics (:class:`CycleEvaluator`) or a learned model
    (:class:`~suds_ros.core.optimize.data.LearnedCycle`).
    """

    np: int
    gait_hz: float

    def cycle(self, X: FloatArray, rp0: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """One cycle of each candidate: r_p(T) (B, np), g_c (B, 3), work (B,)."""
        raise NotImplementedError

    def steady(self, X: FloatArray, rp_guess: FloatArray, tol: float = 1e-11, max_iter: int = 8
               ) -> tuple[CycleResult, FloatArray, FloatArray]:
        """The periodic steady state of candidates X (B, p) by Newton shooting from ``rp_guess`` (B, np).

        Returns
        -------
        result : CycleResult
            At the steady state (outputs moved there by the last linearisation).
        phi : (B, np, np) ∂P/∂r_p(0) at the last iterate.
        gy : (B, 4, np) ∂(g_c, work)/∂r_p(0) at the last iterate.

        Raises
        ------
        FloatingPointError
            When Newton does not converge in ``max_iter`` iterations.
        """
        X = np.atleast_2d(X)
        B, m = X.shape[0], self.np
        if m == 0:  # fully actuated: no passive state, so every cycle is the periodic one
            P, g, w = self.cycle(X, np.zeros((B, 0)))
            return CycleResult(g_c=g, work=w, r_p=P), np.zeros((B, 0, 0)), np.zeros((B, 4, 0))
        rp = np.array(rp_guess, dtype=float).reshape(B, m)
        eps = 1e-6
        eye = np.eye(m)
        for _ in range(max_iter):
            starts = np.concatenate([rp[:, None, :], rp[:, None, :] + eps * eye[None]], axis=1)  # (B, m+1, m)
            P, g, w = self.cycle(np.repeat(X, m + 1, axis=0), starts.reshape(-1, m))
            P, y = P.reshape(B, m + 1, m), np.concatenate([g, w[:, None]], axis=1).reshape(B, m + 1, 4)
            phi = ((P[:, 1:] - P[:, :1]) / eps).transpose(0, 2, 1)  # (B, m, m): column i = ∂P/∂rp_i
            gy = ((y[:, 1:] - y[:, :1]) / eps).transpose(0, 2, 1)  # (B, 4, m)
            F = P[:, 0] - rp
            step = np.linalg.solve(eye - phi, F[..., None])[..., 0]
            new = rp + step
            y0 = y[:, 0] + np.einsum("bij,bj->bi", gy, step)
            done = np.max(np.abs(F)) < tol or np.max(np.abs(step)) < tol
            rp = new
            if done:
                return CycleResult(g_c=y0[:, :3], work=y0[:, 3], r_p=rp), phi, gy
        raise FloatingPointError(
            f"no periodic steady state after {max_iter} Newton steps (|F| = {np.max(np.abs(F)):.3g})")

    def moved(self, X: FloatArray, base: CycleResult, phi: FloatArray, gy: FloatArray) -> CycleResult:
        """Candidates X (B, p) near a base gait: one cycle from the base's steady state, moved to their own.

        ``base``, ``phi``, ``gy`` are of one gait (leading axis 1); y* = y + G (I − Φ)⁻¹ (P − r_p*).
        """
        X = np.atleast_2d(X)
        B = X.shape[0]
        rp0 = np.repeat(base.r_p, B, axis=0)
        P, g, w = self.cycle(X, rp0)
        corr = np.linalg.solve(np.eye(self.np) - phi[0], (P - rp0).T).T  # (B, np)
        y = np.concatenate([g, w[:, None]], axis=1) + corr @ gy[0].T
        return CycleResult(g_c=y[:, :3], work=y[:, 3], r_p=rp0 + corr)


class CycleEvaluator(PeriodicShooting):
    """One gait cycle of many candidate gaits at once, and their passive periodic steady states.

    Parameters
    ----------
    system : SudsSystem
        The physics (a background flow is left out: the objective is the motion through the fluid).
    joints : tuple of str
        The actuated joints in the system's order (the gait's).
    gait_hz : float
        Cycle frequency, Hz.
    order : int
        Harmonics K of the candidates; a candidate is the flat vector of :meth:`Gait.to_vector`.
    steps : int
        RK4 steps per cycle.
    work : bool
        Also integrate the actuator work (one more solve per stage).
    """

    def __init__(self, system: SudsSystem, gait_hz: float, order: int, steps: int, work: bool = False) -> None:
        self.system, _ = _still(system)
        self.gait_hz, self.order, self.steps, self.with_work = float(gait_hz), int(order), int(steps), work
        self.act = np.asarray(system.actuated, dtype=int)
        self.pas = np.asarray(system.passive, dtype=int)
        self.na, self.np = self.act.size, self.pas.size
        self.nj = self.na + self.np
        h = 1.0 / (self.gait_hz * self.steps)
        self.h = h
        # stage times: step n at n·h, n·h + h/2, (n + 1)·h  → basis rows [1, cos kθ, sin kθ] and their rates
        t = h * np.concatenate([np.arange(self.steps), np.arange(self.steps) + 0.5, [self.steps]])
        k = np.arange(1, order + 1)
        w = 2 * np.pi * self.gait_hz * k
        th = np.outer(t, w)
        self._basis = np.concatenate([np.ones((t.size, 1)), np.cos(th), np.sin(th)], axis=1)  # (T, 2K+1)
        self._dbasis = np.concatenate([np.zeros((t.size, 1)), -np.sin(th) * w, np.cos(th) * w], axis=1)
        self.cycles_run = 0  # candidate-cycles integrated (cost counter)

    def _drive(self, X: FloatArray) -> tuple[FloatArray, FloatArray]:
        """r_a and ṙ_a at every stage time: (T, B, na) each, for candidates X (B, p)."""
        coef = X.reshape(X.shape[0], self.na, 2 * self.order + 1)
        return (np.einsum("tc,bjc->tbj", self._basis, coef), np.einsum("tc,bjc->tbj", self._dbasis, coef))

    def cycle(self, X: FloatArray, rp0: FloatArray, poses: list[FloatArray] | None = None
              ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Integrate one cycle from r_p(0) = ``rp0`` (B, np) and the identity pose.

        ``poses``, if given, receives the pose (B, 3) after every step (``steps`` arrays).

        Returns
        -------
        r_p(T) (B, np), g_c (B, 3), work (B,) (NaN unless ``work``).
        """
        X = np.atleast_2d(X)
        B, n = X.shape[0], self.steps
        ra, va = self._drive(X)
        rp = np.array(rp0, dtype=float).reshape(B, self.np)
        pose = np.zeros((B, 3))
        work = np.zeros(B)
        full = np.empty((B, self.nj))
        vel = self.system.velocities
        h = self.h

        def f(i: int, rp_: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
            full[:, self.act] = ra[i]
            full[:, self.pas] = rp_
            xi, rpd = vel(full, va[i])
            if not self.with_work:
                return xi, rpd, work
            rdot = np.empty((B, self.nj))
            rdot[:, self.act] = va[i]
            rdot[:, self.pas] = rpd
            power = np.einsum("bj,bj->b", self.system.actuator_effort(full, rdot), va[i])
            return xi, rpd, power

        for s in range(n):
            i0, im, i1 = s, n + s, (2 * n if s == n - 1 else s + 1)
            xi1, k1, p1 = f(i0, rp)
            xi2, k2, p2 = f(im, rp + (h / 2) * k1)
            xi3, k3, p3 = f(im, rp + (h / 2) * k2)
            xi4, k4, p4 = f(i1, rp + h * k3)
            rp = rp + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
            if self.with_work:
                work = work + (h / 6.0) * (p1 + 2 * p2 + 2 * p3 + p4)
            pose = se2.exp_step(pose, h * (xi1 / 4 + xi2 / 6 + xi3 / 6 - xi4 / 12))
            pose = se2.exp_step(pose, h * (-xi1 / 12 + xi2 / 6 + xi3 / 6 + xi4 / 4))
            if poses is not None:
                poses.append(pose)
        self.cycles_run += B
        return rp, pose, (work if self.with_work else np.full(B, np.nan))


def objective_values(res: CycleResult, gait_hz: float) -> dict[str, FloatArray]:
    """``speed`` (m/s), ``turn`` (rad/s, signed), ``efficiency`` (m/J), ``rotation`` (rad/cycle) of results."""
    dist = np.hypot(res.g_c[:, 0], res.g_c[:, 1])
    return {"speed": dist * gait_hz, "turn": res.g_c[:, 2] * gait_hz, "rotation": res.g_c[:, 2],
            "efficiency": dist / res.work, "distance": dist}


def origin_distances(ev: CycleEvaluator, x: FloatArray, res: CycleResult) -> FloatArray:
    """Distance per cycle of one gait x counted from each step time k/steps of its cycle (k = 0 … steps − 1), m.

    ``res`` is the gait's periodic steady state (leading axis 1).  There the body velocity is
    periodic, so g(s + T) = g_c·g(s), and the cycle counted from s is g(s)⁻¹ g_c g(s): the same net
    rotation θ, and for g(s) = (p_s, a_s), g_c = (q, θ) the translation R(a_s)ᵀ (q + (R_θ − I) p_s),
    whose length |q + (R_θ − I) p_s| is the same at every s only when θ = 0.
    """
    poses: list[FloatArray] = []
    ev.cycle(np.atleast_2d(x)[:1], res.r_p[:1], poses=poses)
    p = np.concatenate([np.zeros((1, 2)), np.stack(poses[:-1])[:, 0, :2]])  # (steps, 2): p_s at s = k/steps
    return origin_chords(res.g_c[0], p)


def origin_chords(g_c: FloatArray, p: FloatArray) -> FloatArray:
    """|q + (R_θ − I) p_s|: the length of a cycle g_c = (q, θ) counted from points at positions p (n, 2).

    p_s is the position at s in the frame of the cycle's start (:func:`origin_distances`; measured,
    :func:`~suds_ros.core.optimize.loop.measured_origin`).
    """
    q, th = np.asarray(g_c[:2], dtype=float), float(g_c[2])
    c, sn = math.cos(th) - 1.0, math.sin(th)
    return np.hypot(q[0] + (c * p[:, 0] - sn * p[:, 1]), q[1] + (sn * p[:, 0] + c * p[:, 1]))  # q + ((R_θ − I) p)


def best_origin(ev: CycleEvaluator, x: FloatArray, rp_guess: FloatArray) -> tuple[float, float]:
    """Where the gait x's cycle goes furthest from, in cycles, and the distance's gain there.

    The best of the step times (:func:`origin_distances`), refined by a parabola through it and its
    neighbours.  Returns the shift s0 (the gait counted from there is
    :func:`~suds_ros.core.physics.gait.time_shifted` by s0) and the ratio of its estimated distance
    per cycle to the unshifted one's.
    """
    res, _, _ = ev.steady(np.atleast_2d(x)[:1], rp_guess)
    d = origin_distances(ev, x, res)
    n, k = d.size, int(np.argmax(d))
    lo, mid, hi = d[(k - 1) % n], d[k], d[(k + 1) % n]
    curv = lo - 2 * mid + hi
    frac = 0.0 if curv >= 0 else float(np.clip(0.5 * (lo - hi) / curv, -0.5, 0.5))
    peak = mid + 0.25 * (hi - lo) * frac  # the parabola's vertex
    return (k + frac) / n, float(peak / max(d[0], 1e-300))


def auto_steps(system: SudsSystem, gait_hz: float) -> int:
    """RK4 steps per cycle with h·λ ≤ 1.5 for the fastest passive relaxation λ, at least 64.

    At 64 steps the objectives of purcell3 and swimmer9's nominal gaits are within 3e-5 of
    their 512-step values (docs/results/optimize.md); h·λ ≤ 1.5 keeps RK4 well inside its
    stability bound 2.78.
    """
    lam = passive_rate(_still(system)[0])
    return max(64, int(math.ceil(lam / (1.5 * gait_hz))))


@dataclass(frozen=True)
class OptimizeResult:
    """What :func:`optimize_gait` found.

    Attributes
    ----------
    gait : Gait
        The best gait (``objective`` and ``predicted`` set), meeting the bounds.
    value, nominal_value : float
        Its objective and the nominal gait's (units of the objective).
    values, nominal_values : dict
        speed, turn, rotation, efficiency, distance of each.
    starts : list of dict
        Per start: kind (nominal / random), value, feasible, iterations, SLSQP message.
    seconds : float
        Wall-clock time.
    cycles : int
        Candidate cycles integrated (cost).
    limits : GaitLimits
        The bounds honoured.
    speed_over_origins : (float, float) or None
        The smallest and largest speed of the same motion counted from other points of its cycle
        (every integration step; :func:`origin_distances`), m/s.  A gait that runs straight reads
        the same from every point; one that turns does not (with ``free_origin`` the gait is counted
        from its best point).  None for ``turn``.
    """

    gait: Gait
    value: float
    nominal_value: float
    values: dict[str, float]
    nominal_values: dict[str, float]
    starts: list[dict[str, Any]] = field(default_factory=list)
    seconds: float = 0.0
    cycles: int = 0
    limits: GaitLimits | None = None
    speed_over_origins: tuple[float, float] | None = None


class SteadyStateProblem:
    """One objective's value, constraints and their gradients at x, from one batch, cached per x.

    The batch holds the gait started at the current guess r_p and at r_p + ε e_i (the cycle map's
    linearisation Φ, G) and the p forward-difference gaits started at r_p; every output is moved
    to its own steady state by y* = y + G (I − Φ)⁻¹ (P − r_p), and r_p takes the Newton step until
    it is below ``tol`` (one or two batches per x: the guess is the last x's steady state).
    """

    def __init__(self, ev: PeriodicShooting, cfg: OptimizeConfig, nominal_speed: float, scale: float,
                 sign: float, rp0: FloatArray, free: FloatArray, tol: float = 1e-9, max_iter: int = 8,
                 rotation_centre: float = 0.0) -> None:
        self.ev, self.cfg, self.nominal_speed, self.scale, self.sign = ev, cfg, nominal_speed, scale, sign
        self.free = np.asarray(free)
        self.rp = np.array(rp0, dtype=float).reshape(-1)
        self.tol, self.max_iter = tol, max_iter
        self.failed = 0  # evaluations without a steady state
        self.rotation_centre = float(rotation_centre)  # the rotation bound is |rotation − this| ≤ max_rotation
        self._key: bytes | None = None
        self._val = np.empty(3)
        self._nc = {"speed": 2, "turn": 1, "efficiency": 3}[cfg.objective]
        self._grad = np.empty((0, 1 + self._nc))

    def _outputs(self, g_c: FloatArray, work: FloatArray) -> FloatArray:
        """Rows (B, 1 + nc): minimised objective (scaled), then the nonlinear constraints (≥ 0).

        speed: rotation within ±max_rotation of ``rotation_centre`` (default 0); turn: speed ≥ the
        nominal's; efficiency: both.
        """
        v = objective_values(CycleResult(g_c=g_c, work=work, r_p=np.empty((g_c.shape[0], 0))), self.ev.gait_hz)
        cfg = self.cfg
        cols = [(-self.sign * v["turn"] if cfg.objective == "turn" else -v[cfg.objective]) / self.scale]
        rot = cfg.max_rotation * (1 - MARGIN)
        if cfg.objective in ("speed", "efficiency"):
            turned = v["rotation"] - self.rotation_centre
            cols += [1.0 - turned / rot, 1.0 + turned / rot]
        if cfg.objective in ("turn", "efficiency"):
            cols.append(v["speed"] / (max(self.nominal_speed, 1e-12) * (1 + MARGIN)) - 1.0)
        return np.stack(cols, axis=1)

    def _evaluate(self, x: FloatArray) -> None:
        ev, m, p = self.ev, self.ev.np, self.free.size
        eps, step_fd = 1e-6, self.cfg.fd_step
        X = np.concatenate([np.repeat(x[None], m + 1, axis=0), x[None] + step_fd * np.eye(x.size)[self.free]])
        eye = np.eye(m)
        rp = self.rp.copy()
        for it in range(2 * self.max_iter):
            if it == self.max_iter:  # Newton from the last steady state failed: relax by plain cycles, retry
                for _ in range(20):
                    rp = ev.cycle(x[None], rp[None])[0][0]
                if not np.all(np.isfinite(rp)):
                    raise FloatingPointError("a candidate gait's cycle is not finite")
            starts = np.concatenate([rp[None], rp[None] + eps * eye, np.repeat(rp[None], p, axis=0)])
            P, g, w = ev.cycle(X, starts)
            y = np.concatenate([g, w[:, None]], axis=1)
            phi = ((P[1:m + 1] - P[0]) / eps).T  # (m, m): column i = ∂P/∂rp_i
            gy = ((y[1:m + 1] - y[0]) / eps).T  # (4, m)
            moves = np.linalg.solve(eye - phi, (P - rp).T).T  # (B, m): each run's steady state − rp
            ys = y + moves @ gy.T
            step = moves[0]
            rp = rp + step
            if not np.all(np.isfinite(ys[:, :3])):
                raise FloatingPointError("a candidate gait's cycle is not finite")
            if np.max(np.abs(step), initial=0.0) <= self.tol:
                break
        else:
            raise FloatingPointError(f"no periodic steady state after {2 * self.max_iter} Newton steps")
        self.rp = rp
        out = self._outputs(ys[:, :3], ys[:, 3])
        self._val = out[0]
        self._grad = (out[m + 1:] - out[0]) / step_fd  # (p, 1 + nc)

    def values(self, x: FloatArray) -> FloatArray:
        """[objective, constraint 1, constraint 2] at x (a copy: the caller may keep or change it)."""
        key = x.tobytes()
        if key != self._key:
            try:
                with np.errstate(all="ignore"):
                    self._evaluate(x)
            except (FloatingPointError, np.linalg.LinAlgError, SudsDataError):
                # a trial point without a steady state (far outside the bounds, or the integration
                # broke down; a learned model refuses the non-finite states it led to): much worse
                # than anything seen and infeasible, so the line search backs off
                self.failed += 1
                self._val = np.array([10.0] + [-1.0] * self._nc)
                self._grad = np.zeros((self.free.size, 1 + self._nc))
            self._key = key
        return self._val.copy()

    def grads(self, x: FloatArray) -> FloatArray:
        """Their gradients (p_free, 1 + nc) at x (a copy)."""
        self.values(x)
        return self._grad.copy()


def phase_pinned(x: FloatArray, na: int, order: int) -> FloatArray:
    """The same gait shifted in time so that joint 1's first harmonic is a pure sine of amplitude ≥ 0.

    A time shift leaves the bounds, the net rotation and the work per cycle unchanged, and the
    speed too for a gait that runs straight, so fixing ``cos_1`` of the first joint at 0 removes
    the flat direction the optimiser would otherwise wander along.  A gait that turns has a speed
    that depends on where its cycle is counted from (:func:`~suds_ros.core.physics.gait.time_shifted`):
    the starts count from this pinned origin, and ``OptimizeConfig.free_origin`` then moves each
    end to its best one (:func:`best_origin`).
    """
    m = np.array(x, dtype=float).reshape(na, 2 * order + 1)
    psi = math.atan2(m[0, 1], m[0, order + 1])
    m[:, 1:order + 1], m[:, order + 1:] = shifted_harmonics(m[:, 1:order + 1], m[:, order + 1:],
                                                            -(np.arange(1, order + 1) * psi))
    m[0, 1] = 0.0
    return m.ravel()


def linear_bounds(gait: Gait, order: int, limits: GaitLimits, per_harmonic: int) -> tuple[FloatArray, FloatArray]:
    """M (rows, p), b (rows,) with M x ≤ b the range and speed bounds on the constraint grid."""
    na = len(gait.joints)
    t = constraint_grid(order, gait.gait_hz, per_harmonic)
    k = np.arange(1, order + 1)
    w = 2 * np.pi * gait.gait_hz * k
    th = np.outer(t, w)
    A = np.concatenate([np.ones((t.size, 1)), np.cos(th), np.sin(th)], axis=1)
    dA = np.concatenate([np.zeros((t.size, 1)), -np.sin(th) * w, np.cos(th) * w], axis=1)
    p = na * (2 * order + 1)
    # between grid points the fundamental peaks at most 1/cos(π/N) above its largest grid value
    # (N = per_harmonic·K points): the bounds are tightened by that factor (higher harmonics may
    # still rise a little more; the final scaling on a 4096-point grid takes care of that)
    margin = math.cos(math.pi / (per_harmonic * order))
    rows, bounds = [], []
    for j in range(na):
        for basis, bound in ((A, limits.limit[j]), (dA, limits.speed_limit[j])):
            block = np.zeros((t.size, p))
            block[:, j * (2 * order + 1):(j + 1) * (2 * order + 1)] = basis
            rows += [block / bound, -block / bound]  # rows scaled to bound 1 (well-conditioned QP)
            bounds += [np.full(t.size, margin)] * 2
    return np.concatenate(rows), np.concatenate(bounds)


def feasible_scale(gait: Gait, limits: GaitLimits) -> float:
    """Largest s ≤ 1 with s·gait within the bounds (they are homogeneous in s; :func:`gait_extremes`)."""
    r, v = gait_extremes(gait)
    ratio = np.concatenate([np.asarray(limits.limit) / np.maximum(r, 1e-300),
                            np.asarray(limits.speed_limit) / np.maximum(v, 1e-300)])
    return float(min(1.0, ratio.min()))


def random_gait(na: int, limits: GaitLimits, order: int, rng: np.random.Generator) -> FloatArray:
    """A random gait vector of ``order`` harmonics for ``na`` joints, not yet scaled into the bounds.

    Offsets uniform within ±0.2 of each joint's range limit; harmonic k's coefficients normal of
    size limit/k.
    """
    lim = np.asarray(limits.limit)
    x = np.zeros((na, 2 * order + 1))
    x[:, 0] = rng.uniform(-0.2, 0.2, na) * lim
    amp = lim[:, None] / np.arange(1, order + 1)[None]
    x[:, 1:order + 1] = rng.normal(size=(na, order)) * amp
    x[:, order + 1:] = rng.normal(size=(na, order)) * amp
    return x.ravel()


def screen_candidates(nominal: Gait, limits: GaitLimits, order: int, count: int,
                      rng: np.random.Generator) -> FloatArray:
    """``count`` candidate gait vectors (count, p) on the bounds for :func:`screen_starts`.

    A quarter are travelling waves r_j = a_j sin(ωt − jλ) at evenly spread lags λ ∈ [−π, π) (both
    directions, and the standing wave), a quarter first harmonics of random phase per joint, both
    at the largest first-harmonic amplitude a_j the range and speed bounds allow; the rest random
    Fourier gaits (:func:`random_gait`).  Every candidate is scaled onto the bounds.
    """
    na = len(nominal.joints)
    amp = np.minimum(np.asarray(limits.limit), np.asarray(limits.speed_limit) / (2 * np.pi * nominal.gait_hz))
    n_wave = count // 4
    n_phase = count // 4
    phases = np.concatenate([np.outer(np.linspace(-np.pi, np.pi, n_wave, endpoint=False), np.arange(na)),
                             rng.uniform(-np.pi, np.pi, (n_phase, na))])
    first = np.zeros((phases.shape[0], na, 2 * order + 1))
    first[:, :, 1] = -amp * np.sin(phases)  # a sin(ωt − φ) = −a sin φ · cos ωt + a cos φ · sin ωt
    first[:, :, order + 1] = amp * np.cos(phases)
    X = np.concatenate([first.reshape(phases.shape[0], -1),
                        np.array([random_gait(na, limits, order, rng)
                                  for _ in range(count - phases.shape[0])]).reshape(-1, first[0].size)])
    scale = np.array([feasible_scale(nominal.from_vector(x, order), limits) for x in X])
    return X * scale[:, None]


def screen_starts(ev: CycleEvaluator, X: FloatArray, rp_guess: FloatArray, objective: str, max_rotation: float,
                  speed_floor: float | None, n: int) -> list[FloatArray]:
    """The ``n`` best distinct candidates X (B, p) at their steady state (one batch), best first.

    Scored by the objective, times bound/|rotation| for ``speed`` and ``efficiency`` where the
    rotation bound is broken (scaling a gait down brings its rotation in); with a ``speed_floor``
    (``turn``, ``efficiency``) the candidates at or above it come first, then the rest scored times
    speed/floor (only a faster gait meets the floor, and turning costs speed).  The steady state
    is Newton's from a few plain cycles; where Newton fails for the batch, the last plain cycle's
    outputs are used (close for a dissipative system).  Two candidates are distinct
    when their time-pinned coefficient vectors (:func:`phase_pinned`) differ by more than a quarter
    of the length of the better one.  Candidates without a finite cycle are left out.
    """
    B = X.shape[0]
    with np.errstate(all="ignore"):
        rp = np.repeat(np.asarray(rp_guess, dtype=float).reshape(1, -1), B, axis=0)
        for _ in range(4):
            rp, g, w = ev.cycle(X, rp)
        try:
            res, _, _ = ev.steady(X, rp)
            g, w = res.g_c, res.work
        except (FloatingPointError, np.linalg.LinAlgError):
            pass
        v = objective_values(CycleResult(g_c=g, work=w, r_p=rp), ev.gait_hz)
        score = np.abs(v["turn"]) if objective == "turn" else v[objective].copy()
        if objective != "turn":
            score = score * np.minimum(1.0, max_rotation / np.abs(v["rotation"]))
        above = np.ones(B, dtype=bool)
        if speed_floor is not None:
            above = v["speed"] >= speed_floor
            score = score * np.minimum(1.0, v["speed"] / max(speed_floor, 1e-12))
    score[~np.isfinite(score)] = -np.inf
    na, K = ev.na, ev.order
    picked: list[FloatArray] = []
    for i in np.lexsort((-score, ~above)):  # those above the floor first, each group best first
        if len(picked) == n or not np.isfinite(score[i]):
            break
        x = phase_pinned(X[i], na, K)
        if all(np.linalg.norm(x - y) > 0.25 * np.linalg.norm(x) for y in picked):
            picked.append(x)
    return picked


def evaluate_gait(system: SudsSystem, gait: Gait, *, steps: int | None = None,
                  work: bool = True) -> dict[str, float]:
    """Objective values of one gait at its passive periodic steady state (:func:`objective_values`)."""
    steps = auto_steps(system, gait.gait_hz) if steps is None else steps
    ev = CycleEvaluator(system, gait.gait_hz, gait.order, steps, work=work)
    # a few plain cycles from rest first: Newton then starts close to the attracting cycle
    rp = _rest_angles(system)[None]
    X = gait.to_vector()[None]
    for _ in range(2):
        rp, _, _ = ev.cycle(X, rp)
    res, _, _ = ev.steady(X, rp)
    return {k: float(v[0]) for k, v in objective_values(res, gait.gait_hz).items()}


def optimize_gait(system: SudsSystem, config: OptimizeConfig = OptimizeConfig(), *,
                  nominal: Gait | None = None, limits: GaitLimits | None = None,
                  log: Callable[[str], None] | None = None, initial: Sequence[Gait] = ()) -> OptimizeResult:
    """Optimise a gait of ``system`` on its physics (see the module docstring).

    Parameters
    ----------
    system : SudsSystem
        The physics (an RFT chain or any system with a nominal sinusoidal gait).
    config : OptimizeConfig
        Objective, order, starts, tolerances.
    nominal : Gait, optional
        The nominal gait (default: the system's, :func:`~suds_ros.core.physics.gait.nominal_gait`).
    limits : GaitLimits, optional
        The bounds (default :func:`~suds_ros.core.physics.gait.gait_limits`).
    log : callable, optional
        Receives one line per start.
    initial : sequence of Gait
        More starts, run after the nominal gait and before the random ones (e.g. the gait optimised
        on a model file, when optimising on that model corrected by a diagnosis: the random starts
        can miss the optimum it lies near).  Each is scaled into the bounds if it is outside them.

    Raises
    ------
    SudsConfigError
        A system without a nominal gait; no start reached a feasible gait; an ``initial`` gait for
        other joints or with more harmonics than ``config.order``.
    """
    t_start = time.perf_counter()
    cfg = config
    nominal = nominal_gait(system) if nominal is None else nominal
    limits = gait_limits(system, nominal) if limits is None else limits
    K = cfg.order
    if nominal.order > K:
        raise SudsConfigError(f"`order`: the nominal gait has {nominal.order} harmonics, more than {K}")
    steps = auto_steps(system, nominal.gait_hz) if cfg.steps_per_cycle is None else cfg.steps_per_cycle
    ev = CycleEvaluator(system, nominal.gait_hz, K, steps, work=cfg.objective == "efficiency")
    x_nom = nominal.to_vector(K)
    rp = _rest_angles(system)[None]
    for _ in range(2):
        rp, _, _ = ev.cycle(x_nom[None], rp)
    nom_res, _, _ = ev.steady(x_nom[None], rp)
    nom_vals = {k: float(v[0]) for k, v in objective_values(nom_res, nominal.gait_hz).items()}
    nominal_value = abs(nom_vals[cfg.objective]) if cfg.objective == "turn" else nom_vals[cfg.objective]
    if cfg.objective == "efficiency" and not (np.isfinite(nominal_value) and nom_res.work[0] > 0):
        raise SudsConfigError(f"`objective`: efficiency needs a positive actuator work per cycle; "
                              f"the nominal gait's is {nom_res.work[0]!r} J", code=UNSUPPORTED_OBJECTIVE)
    # objective scale: the nominal value (a nominal gait that does not turn: the rotation bound's rate)
    scale = max(abs(nominal_value), cfg.max_rotation * nominal.gait_hz if cfg.objective == "turn" else 1e-9)
    M, b = linear_bounds(nominal, K, limits, cfg.points_per_harmonic)
    rng = np.random.default_rng(cfg.seed)
    starts: list[tuple[str, FloatArray]] = [("nominal", x_nom)]
    for i, g in enumerate(initial):
        g = check_gait(g, system, f"`initial[{i}]`")
        if g.order > K:
            raise SudsConfigError(f"`initial[{i}]`: expected at most {K} harmonics (`order`), got {g.order}")
        starts.append(("given", g.to_vector(K) * min(1.0, feasible_scale(g, limits))))
    na = len(nominal.joints)
    for _ in range(cfg.starts - 1):  # drawn first: the same random starts as without a screen
        x = random_gait(na, limits, K, rng)
        s = feasible_scale(nominal.from_vector(x, K), limits) * rng.uniform(0.6, 0.95)
        starts.append(("random", s * x))
    report: list[dict[str, Any]] = []
    p_all = x_nom.size
    pinned = np.flatnonzero(np.arange(p_all) != 1)  # joint 1's cos_1 stays 0 (phase_pinned)

    def solve(kind: str, x0: FloatArray, free: FloatArray) -> tuple[float, FloatArray] | None:
        """SLSQP from x0 over the coefficients ``free``: (value, x) of a feasible end, else None."""
        Mf = M[:, free]

        def embed(z: FloatArray) -> FloatArray:
            x = x0.copy()
            x[free] = z
            return x

        sign = 1.0
        if cfg.objective == "turn":
            r0, _, _ = ev.steady(x0[None], nom_res.r_p) if kind != "nominal" else (nom_res, None, None)
            sign = 1.0 if r0.g_c[0, 2] >= 0 else -1.0
        prob = SteadyStateProblem(ev, cfg, nom_vals["speed"], scale, sign, nom_res.r_p[0], free)
        cons = [{"type": "ineq", "fun": lambda z: b - Mf @ z, "jac": lambda z: -Mf},
                {"type": "ineq", "fun": lambda z: prob.values(embed(z))[1:],
                 "jac": lambda z: np.ascontiguousarray(prob.grads(embed(z))[:, 1:].T)}]
        try:
            sol = minimize(lambda z: float(prob.values(embed(z))[0]), x0[free],
                           jac=lambda z: np.ascontiguousarray(prob.grads(embed(z))[:, 0]),
                           method="SLSQP", constraints=cons,
                           options={"maxiter": cfg.maxiter, "ftol": cfg.ftol})
            x_end, msg, nit = embed(sol.x), str(sol.message), int(sol.nit)
        except FloatingPointError as exc:  # a candidate without a steady state: this start failed
            report.append({"kind": kind, "value": None, "feasible": False, "iterations": None, "message": str(exc)})
            if log is not None:
                log(f"start {len(report)} ({kind}): failed ({exc})")
            return None
        g_end = nominal.from_vector(x_end, K)
        x_end = x_end * feasible_scale(g_end, limits)
        vals = prob.values(x_end)
        start_vals = prob.values(x0)
        if (start_vals[0] < vals[0] and np.all(start_vals[1:] >= -MARGIN)
                and feasible_scale(nominal.from_vector(x0, K), limits) == 1.0):
            x_end, vals, msg = x0, start_vals, msg + "; kept the start, which was better"
        value = -float(vals[0]) * scale
        feasible = bool(np.all(vals[1:] >= -MARGIN))  # the true bounds, to ~1e-6
        if prob.failed:
            msg += f"; {prob.failed} trial point(s) without a steady state"
        report.append({"kind": kind, "value": value, "feasible": feasible, "iterations": nit, "message": msg})
        if log is not None:
            log(f"start {len(report)} ({kind}): {cfg.objective} {value:.6g}, "
                f"{'feasible' if feasible else 'infeasible'}, {nit} iterations ({msg})")
        return (value, x_end) if feasible else None

    ends = [e for kind, x0 in starts if (e := solve(kind, phase_pinned(x0, na, K), pinned)) is not None]
    if cfg.screen > 0 and cfg.screened > 0:
        # after the other starts have run: SLSQP's ends are sensitive to the last bit of every number,
        # so running the screen first could move them (and the screen's candidates come after the
        # random starts from the same generator)
        X = screen_candidates(nominal, limits, K, cfg.screen, rng)
        floor = nom_vals["speed"] if cfg.objective in ("turn", "efficiency") else None
        for x in screen_starts(ev, X, nom_res.r_p[0], cfg.objective, cfg.max_rotation, floor, cfg.screened):
            if (e := solve("screened", x, pinned)) is not None:
                ends.append(e)
    if not ends:
        extra = {"speed": "", "turn": " and a speed ≥ the nominal gait's",
                 "efficiency": " and a speed ≥ the nominal gait's"}[cfg.objective]
        raise SudsConfigError(f"`objective` {cfg.objective}: no start reached a gait within the joint bounds"
                              f"{extra} ({len(starts)} starts, order {K}); try a higher --order or more --starts")
    best = max(ends, key=lambda e: e[0])
    if cfg.free_origin and cfg.objective != "turn":
        # the pinned origin is one point of the cycle; a turning end may go further counted from another
        # one (origin_distances): shift each end that would then beat the best there, and go on from it
        # with every coefficient free (the shift is a direction of the coefficients)
        every = np.arange(p_all)
        queue = sorted(ends, key=lambda e: -e[0])
        for _ in range(cfg.origin_rounds):
            moved = []
            for value, x in queue:
                s0, gain = best_origin(ev, x, nom_res.r_p)
                if value * gain > best[0] * (1 + ORIGIN_GAIN):
                    end = solve("origin", time_shifted(nominal.from_vector(x, K), s0).to_vector(K), every)
                    if end is not None:
                        moved.append(end)
                        best = max(best, end, key=lambda e: e[0])
            if not moved:
                break
            queue = moved
    gait = nominal.from_vector(best[1], K)
    res, _, _ = ev.steady(best[1][None], nom_res.r_p)
    vals = {k: float(v[0]) for k, v in objective_values(res, nominal.gait_hz).items()}
    value = abs(vals["turn"]) if cfg.objective == "turn" else vals[cfg.objective]
    predicted = {cfg.objective: value}
    gait = with_predicted(gait, cfg.objective, predicted)
    origins = None
    if cfg.objective != "turn":
        d = origin_distances(ev, best[1], res) * nominal.gait_hz
        origins = (float(min(d.min(), vals["speed"])), float(max(d.max(), vals["speed"])))
    return OptimizeResult(gait=gait, value=value, nominal_value=nominal_value, values=vals,
                          nominal_values=nom_vals, starts=report, seconds=time.perf_counter() - t_start,
                          cycles=ev.cycles_run, limits=limits, speed_over_origins=origins)
