"""Planar N-link chain in Stokes flow under resistive force theory (RFT).

Derivation (ours; the paper points to Hatton & Choset 2013 and prints no
matrices for these swimmers):

Links i = 0..N-1 run head to tail; joint j joins links j and j+1 and its
angle is r_j = θ_{j+1} − θ_j.  The body frame is the frame of link m (the
middle link by default), x axis along the link from tail to head.  Relative to
the body frame link i has angle α_i = (S r)_i with

    S[i, j] = +1  for m ≤ j < i   (links behind the body link)
    S[i, j] = −1  for i ≤ j < m   (links ahead of the body link)

and centre p_i = Σ_k W[i, k] e(α_k), e(α) = (cos α, sin α), where W holds
±L_k/2 for k ∈ {m, i} and ±L_k for links strictly between (sign + ahead of the
body link, − behind).  With q̇ = (ξx, ξy, ξθ, ṙ) the velocity of link i's
centre and its angular rate, in the body frame, are

    v_i = (ξx − ξθ p_iy,  ξy + ξθ p_ix) + (∂p_i/∂r) ṙ,     ω_i = ξθ + S_i ṙ,

and in the link's own frame V_i = blockdiag(R(−α_i), 1) (v_i, ω_i) = J_i q̇.
RFT drag on the link is −K_i V_i with K_i = diag(c∥ L, c⊥ L, c⊥ L³/12), so the
generalised drag force on q is −D q̇ with the drag metric D = Σ_i J_iᵀ K_i J_i
(symmetric, positive semi-definite).  The first three components of D q̇ are
the net drag wrench on the chain in the body frame.

Equations of motion at zero inertia (spec ``recording.md``):
    rows ξ   : (D q̇)_ξ = 0                                      (3 equations)
    rows r_p : −(D q̇)_p − d ṙ_p + τ_spring + τ_effects = 0      (np equations)
with ṙ_a prescribed.  Solving for u = (ξ, ṙ_p) gives

    (D_uu + diag(0, d)) u = −D_ua ṙ_a + (0, τ_spring + τ_effects),

affine in ṙ_a as the SUDS structure requires.  Joint Coulomb friction is set
valued; it is solved exactly by enumerating slip(+), slip(−) and stick at each
frictional joint and keeping the consistent mode.  A uniform background flow U
advects the whole chain (in Stokes flow the relative-velocity problem is the
still-fluid one), adding R(−θ_body) U to (ξx, ξy).

The actuator effort is τ_a = (D q̇)_a (the generalised force the motors apply,
positive when it tends to increase r_a); after eliminating ξ it equals the
actuated rows of the reduced metric M ṙ of the paper (τ = −M ṙ is the drag
wrench on the shape; the actuators supply its negative).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field, replace

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsConfigError, SudsSimulationError
from suds_ros.core.recording import joint_names


def _as_tuple(value: float | tuple[float, ...] | list[float], n: int, name: str) -> tuple[float, ...]:
    if np.isscalar(value):
        out = (float(value),) * n  # type: ignore[arg-type]
    else:
        out = tuple(float(v) for v in value)  # type: ignore[union-attr]
    if len(out) != n:
        raise SudsConfigError(f"`{name}`: expected {n} values, got {len(out)}")
    if not all(np.isfinite(out)):
        raise SudsConfigError(f"`{name}`: values must be finite, got {out}")
    return out


@dataclass(frozen=True)
class ChainModel:
    """Physical parameters of a planar N-link RFT chain.

    Parameters
    ----------
    n_links : int
        Number of rigid links N ≥ 2 (nj = N − 1 joints).
    actuated : tuple of int
        0-based indices of the driven joints; every other joint is passive.
    stiffness : float or tuple of nj floats
        Spring constants k_j, N·m/rad (used on passive joints).
    rest : float or tuple
        Spring rest angles, rad.
    damping : float or tuple
        Internal viscous damping d_j, N·m·s/rad (≥ 0).
    k3 : float or tuple
        Cubic spring coefficient, torque −k3 (r − rest)³, N·m/rad³ (≥ 0 keeps the spring hardening).
    coulomb : float or tuple
        Dry-friction torque bound mu_j, N·m (≥ 0; exact stick/slip).
    link_length : float or tuple of N floats
        Link lengths L_i, m.
    c_par, c_perp : float or tuple of N floats
        RFT drag coefficients per unit length along and across each link.
    stiffness_scale : float
        Multiplies every k_j and k3_j (the ``stiffness_to_drag_error`` effect).
    flow : (float, float)
        Uniform background flow (vx, vy) in the world frame, m/s.
    body_link : int or None
        0-based index of the link that carries the body frame; default the middle link.
    name : str
        System id.
    gait : tuple
        Nominal drive per actuated joint: ((amplitude rad, frequency, phase rad, offset rad), ...),
        set-point offset + amplitude·sin(2π f t − phase), t in gait time (f = 1: once per gait cycle).
    pose_offset : (x m, y m, yaw rad)
        The pose frame (the frame of the recorded pose and of the body velocity) relative to
        the centre frame of the body link; zero puts it on the body link's centre.
    joint_names : tuple of nj str
        Joint names head to tail; default ``joint_1`` … ``joint_{N-1}``.
    gait_hz : float
        Nominal gait frequency, Hz (cycles per second of the drive).
    limit : tuple of nj (float or None)
        Joint range bound |r_j| ≤ limit_j, rad, a gait optimiser honours (``shared/spec/gait.md``);
        None (or an empty tuple: all None) leaves the default, the nominal gait's range.
    speed_limit : tuple of nj (float or None)
        Joint speed bound |ṙ_j| ≤ speed_limit_j, rad/s; None: the nominal gait's largest speed.
    """

    n_links: int
    actuated: tuple[int, ...]
    stiffness: float | tuple[float, ...] = 0.0
    rest: float | tuple[float, ...] = 0.0
    damping: float | tuple[float, ...] = 0.0
    k3: float | tuple[float, ...] = 0.0
    coulomb: float | tuple[float, ...] = 0.0
    link_length: float | tuple[float, ...] = 1.0
    c_par: float | tuple[float, ...] = 1.0
    c_perp: float | tuple[float, ...] = 2.0
    stiffness_scale: float = 1.0
    flow: tuple[float, float] = (0.0, 0.0)
    body_link: int | None = None
    name: str = "chain"
    gait: tuple[tuple[float, float, float, float], ...] = field(default=())
    pose_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    joint_names: tuple[str, ...] = ()
    gait_hz: float = 1.0
    limit: tuple[float | None, ...] = ()
    speed_limit: tuple[float | None, ...] = ()

    def __post_init__(self) -> None:
        if int(self.n_links) != self.n_links or self.n_links < 2:
            raise SudsConfigError(f"`n_links`: expected an integer ≥ 2, got {self.n_links!r}")
        nj = self.n_links - 1
        act = tuple(int(a) for a in self.actuated)
        if not act:
            raise SudsConfigError("`actuated`: at least one joint must be driven")
        if len(set(act)) != len(act) or min(act) < 0 or max(act) >= nj:
            raise SudsConfigError(f"`actuated`: expected distinct indices in [0, {nj - 1}], got {act}")
        object.__setattr__(self, "actuated", act)
        for name in ("stiffness", "rest", "damping", "k3", "coulomb"):
            object.__setattr__(self, name, _as_tuple(getattr(self, name), nj, name))
        object.__setattr__(self, "link_length", _as_tuple(self.link_length, self.n_links, "link_length"))
        if min(self.link_length) <= 0:  # type: ignore[arg-type]
            raise SudsConfigError(f"`link_length`: must be > 0, got {self.link_length}")
        for name in ("damping", "coulomb"):
            if min(getattr(self, name)) < 0:
                raise SudsConfigError(f"`{name}`: must be ≥ 0, got {getattr(self, name)}")
        for name in ("c_par", "c_perp"):
            values = _as_tuple(getattr(self, name), self.n_links, name)
            if min(values) <= 0:
                raise SudsConfigError(f"`{name}`: drag coefficients must be > 0, got {values}")
            object.__setattr__(self, name, values)
        offset = _as_tuple(self.pose_offset, 3, "pose_offset")
        object.__setattr__(self, "pose_offset", offset)
        names = tuple(str(n) for n in self.joint_names) or joint_names(nj)
        if len(names) != nj or len(set(names)) != nj or not all(names):
            raise SudsConfigError(f"`joint_names`: expected {nj} distinct non-empty names, got {names}")
        object.__setattr__(self, "joint_names", names)
        if not (np.isfinite(self.gait_hz) and self.gait_hz > 0):
            raise SudsConfigError(f"`gait_hz`: expected a frequency > 0 Hz, got {self.gait_hz!r}")
        if not self.stiffness_scale > 0:
            raise SudsConfigError(f"`stiffness_scale`: must be > 0, got {self.stiffness_scale}")
        object.__setattr__(self, "flow", (float(self.flow[0]), float(self.flow[1])))
        m = (self.n_links - 1) // 2 if self.body_link is None else int(self.body_link)
        if not 0 <= m < self.n_links:
            raise SudsConfigError(f"`body_link`: expected 0..{self.n_links - 1}, got {self.body_link}")
        object.__setattr__(self, "body_link", m)
        gait = tuple(tuple(float(x) for x in g) for g in self.gait)
        if gait and (len(gait) != len(act) or any(len(g) != 4 for g in gait)):
            raise SudsConfigError(
                f"`gait`: expected {len(act)} tuples (amplitude, frequency, phase, offset), got {gait}"
            )
        object.__setattr__(self, "gait", gait)
        for name in ("limit", "speed_limit"):
            values = tuple(getattr(self, name)) or (None,) * nj
            if len(values) != nj or not all(v is None or (np.isfinite(v) and v > 0) for v in values):
                raise SudsConfigError(f"`{name}`: expected {nj} bounds > 0 (or None), got {values}")
            object.__setattr__(self, name, tuple(None if v is None else float(v) for v in values))

    @property
    def n_joints(self) -> int:
        """Number of joints nj = N − 1."""
        return self.n_links - 1

    @property
    def passive(self) -> tuple[int, ...]:
        """0-based indices of the passive joints."""
        return tuple(j for j in range(self.n_joints) if j not in self.actuated)

    @property
    def drag_ratio(self) -> float:
        """The chain's c⊥/c∥: Σ c⊥,i L_i / Σ c∥,i L_i (the common ratio when every link has the same)."""
        L = np.asarray(self.link_length)
        return float(np.dot(self.c_perp, L) / np.dot(self.c_par, L))

    def with_drag_ratio(self, ratio: float) -> "ChainModel":
        """A copy whose every c⊥,i is scaled so that :attr:`drag_ratio` becomes ``ratio`` (c∥ kept)."""
        scale = float(ratio) / self.drag_ratio
        return self.with_(c_perp=tuple(scale * c for c in self.c_perp))  # type: ignore[union-attr]

    def with_(self, **changes: object) -> "ChainModel":
        """A copy with some parameters changed (validated again)."""
        return replace(self, **changes)  # type: ignore[arg-type]


class RFTChain:
    """The SUDS map of a :class:`ChainModel` (implements :class:`~suds_ros.core.physics.system.SudsSystem`).

    Geometry matrices are precomputed once; every method is vectorised over a
    leading batch axis.
    """

    planar = True

    def __init__(self, model: ChainModel) -> None:
        self.model = model
        n, nj, m = model.n_links, model.n_joints, model.body_link
        assert m is not None
        L = np.asarray(model.link_length, dtype=float)
        S = np.zeros((n, nj))
        W = np.zeros((n, n))
        for i in range(n):
            if i > m:
                S[i, m:i] = 1.0
                W[i, m] = -L[m] / 2
                W[i, m + 1 : i] = -L[m + 1 : i]
                W[i, i] = -L[i] / 2
            elif i < m:
                S[i, i:m] = -1.0
                W[i, m] = L[m] / 2
                W[i, i + 1 : m] = L[i + 1 : m]
                W[i, i] = L[i] / 2
        self._S = S
        self._W = W
        cpar, cperp = np.asarray(model.c_par), np.asarray(model.c_perp)
        self._K = np.stack([cpar * L, cperp * L, cperp * L**3 / 12.0], axis=1)
        self._sqrtK = np.sqrt(self._K)
        self._act = np.array(model.actuated, dtype=np.int64)
        self._pas = np.array(model.passive, dtype=np.int64)
        order = np.concatenate([self._pas, self._act])  # joint order inside the permuted metric
        self._S_perm = S[:, order]
        perm = np.concatenate([np.arange(3), 3 + order])  # permuted position -> original coordinate
        self._unperm = np.argsort(perm)  # original coordinate -> permuted position
        self._nu = 3 + self._pas.size
        scale = model.stiffness_scale
        self._k = scale * np.asarray(model.stiffness)[self._pas]
        self._k3 = scale * np.asarray(model.k3)[self._pas]
        self._rest = np.asarray(model.rest)[self._pas]
        self._d = np.asarray(model.damping)[self._pas]
        self._mu = np.asarray(model.coulomb)[self._pas]
        self._fric = np.flatnonzero(self._mu > 0)
        self._has_damping = bool(np.any(self._d > 0))
        self._damp_diag = np.zeros((self._nu, self._nu))
        self._damp_diag[3 + np.arange(self._pas.size), 3 + np.arange(self._pas.size)] = self._d
        self._modes = list(itertools.product((1, -1, 0), repeat=self._fric.size))

    # ----------------------------------------------------------- SudsSystem
    @property
    def name(self) -> str:
        return self.model.name

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.model.joint_names

    @property
    def actuated(self) -> tuple[int, ...]:
        return self.model.actuated

    @property
    def passive(self) -> tuple[int, ...]:
        return self.model.passive

    def reference(self, t: FloatArray) -> FloatArray:
        t = np.asarray(t, dtype=float)
        if not self.model.gait:
            raise SudsConfigError(f"system {self.name!r} has no nominal gait; pass a reference")
        g = np.asarray(self.model.gait)
        return g[:, 3] + g[:, 0] * np.sin(2 * np.pi * g[:, 1] * t[:, None] - g[:, 2])

    # ------------------------------------------------------------- kinematics
    def _jacobians_perm(self, r: FloatArray) -> FloatArray:
        """Link-frame Jacobians with columns ordered (ξ, r_p, r_a): shape (B, N, 3, 3 + nj)."""
        alpha = r @ self._S.T  # (B, N) link angles relative to the body link
        c, s = np.cos(alpha), np.sin(alpha)
        px = c @ self._W.T
        py = s @ self._W.T
        Sp = self._S_perm
        dpx = (self._W * -s[:, None, :]) @ Sp  # ∂p_i/∂r_j, x component (B, N, nj)
        dpy = (self._W * c[:, None, :]) @ Sp
        B = r.shape[0]
        n = self.model.n_links
        J = np.zeros((B, n, 3, 3 + Sp.shape[1]))
        J[:, :, 0, 0] = c
        J[:, :, 0, 1] = s
        J[:, :, 0, 2] = s * px - c * py
        J[:, :, 0, 3:] = c[..., None] * dpx + s[..., None] * dpy
        J[:, :, 1, 0] = -s
        J[:, :, 1, 1] = c
        J[:, :, 1, 2] = s * py + c * px
        J[:, :, 1, 3:] = c[..., None] * dpy - s[..., None] * dpx
        J[:, :, 2, 2] = 1.0
        J[:, :, 2, 3:] = Sp
        return J

    def _metric_perm(self, r: FloatArray) -> FloatArray:
        """Drag metric with coordinates ordered (ξ, r_p, r_a), shape (B, 3+nj, 3+nj)."""
        J = self._jacobians_perm(r) * self._sqrtK[None, :, :, None]
        Jf = J.reshape(J.shape[0], -1, J.shape[3])
        return np.matmul(Jf.transpose(0, 2, 1), Jf)

    def jacobians(self, r: FloatArray) -> FloatArray:
        """Link-frame Jacobians J, shape (B, N, 3, 3 + nj): V_i = J_i q̇ with q̇ = (ξ, ṙ)."""
        r = np.atleast_2d(np.asarray(r, dtype=float))
        J = self._jacobians_perm(r)
        return J[..., self._unperm]

    def drag_metric(self, r: FloatArray) -> FloatArray:
        """Drag metric D(r), shape (B, 3 + nj, 3 + nj) in (ξ, r) order; generalised drag force is −D q̇."""
        r = np.atleast_2d(np.asarray(r, dtype=float))
        D = self._metric_perm(r)
        return D[:, self._unperm[:, None], self._unperm[None, :]]

    def passive_torque(self, r: FloatArray) -> FloatArray:
        """Spring torque on the passive joints, shape (B, np), N·m (sign: on r_j)."""
        e = np.atleast_2d(r)[:, self._pas] - self._rest
        return -self._k * e - self._k3 * e**3

    # --------------------------------------------------------------- dynamics
    def solve(self, r: FloatArray, rdot_a: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Still-fluid solution: ξ (B, 3), ṙ_p (B, np) and the permuted drag metric (B, 3+nj, 3+nj).

        The returned metric is ordered (ξ, r_p, r_a); use :meth:`drag_metric` for (ξ, r) order.
        """
        r = np.atleast_2d(np.asarray(r, dtype=float))
        rdot_a = np.atleast_2d(np.asarray(rdot_a, dtype=float))
        D = self._metric_perm(r)
        nu = self._nu
        A = D[:, :nu, :nu]
        if self._has_damping:
            A = A + self._damp_diag
        b = -np.matmul(D[:, :nu, nu:], rdot_a[..., None])[..., 0]
        b[:, 3:] += self.passive_torque(r)
        if self._fric.size == 0:
            u = np.linalg.solve(A, b[..., None])[..., 0]
        else:
            u = self._solve_friction(A, b)
        return u[:, :3], u[:, 3:], D

    def _solve_friction(self, A: FloatArray, b: FloatArray) -> FloatArray:
        """Exact stick/slip: minimise ½uᵀAu − bᵀu + Σ mu_j |u_{3+j}| (unique, A ≻ 0)."""
        B = A.shape[0]
        rows = 3 + self._fric
        mu = self._mu[self._fric]
        u_out = np.full((B, A.shape[1]), np.nan)
        done = np.zeros(B, dtype=bool)
        tol = 1e-12
        for mode in self._modes:
            mode_a = np.asarray(mode)
            Am = A.copy()
            bm = b.copy()
            slip = mode_a != 0
            # slipping joints: torque −mu·sign
            bm[:, rows[slip]] -= mu[slip] * mode_a[slip]
            stick_rows = rows[~slip]
            if stick_rows.size:
                Am[:, stick_rows, :] = 0.0
                Am[:, stick_rows, stick_rows] = 1.0
                bm[:, stick_rows] = 0.0
            u = np.linalg.solve(Am, bm[..., None])[..., 0]
            ok = ~done
            if slip.any():
                v = u[:, rows[slip]] * mode_a[slip]
                ok &= np.all(v >= -tol, axis=1)
            if stick_rows.size:
                lam = np.einsum("bij,bj->bi", A[:, stick_rows, :], u) - b[:, stick_rows]
                ok &= np.all(np.abs(lam) <= mu[~slip] * (1 + 1e-9) + tol, axis=1)
            u_out[ok] = u[ok]
            done |= ok
            if done.all():
                break
        if not done.all():  # numerically on a boundary: fall back to the least-violating slip mode
            bad = np.flatnonzero(~done)
            soft = [self.model.joint_names[j] for j in self._pas[self._k3 < 0]]
            hint = (f"; joint(s) {soft} have a softening cubic spring (k3 < 0), which "
                    "pushes a joint away beyond |r − rest| = √(k/|k3|)" if soft else "")
            raise SudsSimulationError(
                f"the passive joints have no consistent stick/slip motion in {bad.size} state(s){hint}")
        return u_out

    def velocities(
        self, r: FloatArray, rdot_a: FloatArray, yaw: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Body velocity ξ (B, 3) and passive velocity ṙ_p (B, np).

        ``yaw`` (B,) is the body heading in the world, rad; needed only when the
        model has a background flow (which adds R(−yaw) U to ξx, ξy).
        """
        xi, rdot_p, _ = self.solve(r, rdot_a)
        xi = self.to_pose_frame(xi)
        if self.model.flow != (0.0, 0.0):
            if yaw is None:
                raise SudsConfigError("`yaw`: a background flow needs the heading of the pose frame, got None")
            xi = xi + flow_in_body(self.model.flow, yaw)
        return xi, rdot_p

    def to_pose_frame(self, xi_link: FloatArray) -> FloatArray:
        """Body velocity of the body link's centre frame (B, 3) → velocity of the pose frame in itself.

        For the pose frame o = (a, b, φ) fixed to the link frame, ω' = ω and
        v' = R(−φ) (vx − ω b, vy + ω a) (the adjoint of o⁻¹).
        """
        a, b, phi = self.model.pose_offset
        if a == 0.0 and b == 0.0 and phi == 0.0:
            return xi_link
        xi_link = np.atleast_2d(xi_link)
        vx = xi_link[:, 0] - xi_link[:, 2] * b
        vy = xi_link[:, 1] + xi_link[:, 2] * a
        c, s = np.cos(phi), np.sin(phi)
        return np.stack([c * vx + s * vy, -s * vx + c * vy, xi_link[:, 2]], axis=1)

    def to_link_frame(self, xi_pose: FloatArray) -> FloatArray:
        """Inverse of :meth:`to_pose_frame`: pose-frame body velocity → body-link centre frame."""
        a, b, phi = self.model.pose_offset
        if a == 0.0 and b == 0.0 and phi == 0.0:
            return xi_pose
        xi_pose = np.atleast_2d(xi_pose)
        c, s = np.cos(phi), np.sin(phi)
        vx = c * xi_pose[:, 0] - s * xi_pose[:, 1]
        vy = s * xi_pose[:, 0] + c * xi_pose[:, 1]
        w = xi_pose[:, 2]
        return np.stack([vx + w * b, vy - w * a, w], axis=1)

    def full_rates(self, r: FloatArray, rdot_a: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Still-fluid q̇ = (ξ, ṙ) (B, 3 + nj) and D (B, 3+nj, 3+nj)."""
        xi, rdot_p, Dp = self.solve(r, rdot_a)
        r = np.atleast_2d(r)
        qdot = np.zeros((r.shape[0], 3 + self.model.n_joints))
        qdot[:, :3] = xi
        qdot[:, 3 + self._act] = rdot_a
        qdot[:, 3 + self._pas] = rdot_p
        return qdot, Dp[:, self._unperm[:, None], self._unperm[None, :]]

    def actuator_effort(self, r: FloatArray, rdot: FloatArray) -> FloatArray:
        """τ_a = (D q̇)_a, N·m, for a full shape velocity ``rdot`` (B, nj) consistent with the dynamics."""
        r = np.atleast_2d(r)
        rdot = np.atleast_2d(rdot)
        qdot, D = self.full_rates(r, rdot[:, self._act])
        return np.einsum("bij,bj->bi", D[:, 3 + self._act, :], qdot)

    def dissipation(self, r: FloatArray, rdot: FloatArray) -> FloatArray:
        """Drag power q̇ᵀDq̇ + internal damping d ṙ_p² + friction mu |ṙ_p|, W."""
        r = np.atleast_2d(r)
        rdot = np.atleast_2d(rdot)
        qdot, D = self.full_rates(r, rdot[:, self._act])
        rp = qdot[:, 3 + self._pas]
        return (
            np.einsum("bi,bij,bj->b", qdot, D, qdot)
            + (self._d * rp**2).sum(axis=1)
            + (self._mu * np.abs(rp)).sum(axis=1)
        )


def flow_in_body(flow: tuple[float, float], yaw: FloatArray) -> FloatArray:
    """A world-frame uniform flow (vx, vy) expressed as a body velocity (B, 3) at headings ``yaw``."""
    yaw = np.atleast_1d(np.asarray(yaw, dtype=float))
    c, s = np.cos(yaw), np.sin(yaw)
    out = np.zeros((yaw.size, 3))
    out[:, 0] = c * flow[0] + s * flow[1]
    out[:, 1] = -s * flow[0] + c * flow[1]
    return out
