"""The paper's two one-dimensional SUDS: the linear passive swimmer and the pushmepullyou.

Both move along the world x axis only (``planar = False``; the body velocity is
returned as ξ = (ẋ, 0, 0)).  Joint order is r = (r_1, r_2): r_1 is passive,
r_2 is driven.  The paper prints matrices for both systems, with typos (mostly in
the pushmepullyou), so each model below is derived again from force balances.  The
differences are listed at the end.

Common method
-------------
Take generalised velocities q̇ = (ẋ, ṙ_1, ṙ_2).  Every body part i drags
linearly on the still fluid.  The part's velocity is a_i(r)ᵀ q̇ (for a
distributed part, a per-point velocity), and the drag force is
−c_i · (its velocity).  The Rayleigh dissipation function is then

    R = ½ q̇ᵀ D(r) q̇,      D = Σ_i c_i a_i a_iᵀ   (sums become integrals for links),

so D is symmetric positive semi-definite by construction.  The generalised
drag force on coordinate j is −∂R/∂q̇_j = −(D q̇)_j.  With inertia neglected
(Stokes flow):

* row x: zero net external force, (D q̇)_x = 0;
* row r_1 (passive): drag + spring + damper = 0,
  −(D q̇)_1 − k (r_1 − r_rest) − d ṙ_1 = 0.

ṙ_2 is prescribed.  Solve the two rows for u = (ẋ, ṙ_1):

    [[D_xx, D_x1], [D_1x, D_11 + d]] u = −(D_x2, D_12) ṙ_2 − (0, k (r_1 − r_rest)).

The result is affine in ṙ_2, as the SUDS structure requires.  The actuator
effort is τ_2 = (D q̇)_2, the force the motor applies to increase r_2.  Power
balance follows from the two rows: q̇ᵀDq̇ = τ_2 ṙ_2 − d ṙ_1² − k (r_1 − r_rest) ṙ_1,
which gives

    τ_2 ṙ_2 = [q̇ᵀDq̇ + d ṙ_1²] + d/dt ½ k (r_1 − r_rest)²
            = dissipation + rate of spring energy storage.

Linear passive swimmer (:class:`LinearPassiveSwimmer`)
------------------------------------------------------
Geometry (all along x; only faces across x meet the flow):

* a payload with a face of length l, at position x, so it moves at ẋ;
* a spring-damper of length r_1 (passive) from the payload to the near end
  of the paddle's stem; the stem lies along x and has length L − r_2, and it
  is slender enough that its drag is neglected;
* the paddle crossbar, of length r_2 (driven), across x, centred on the far
  end of the stem.  It sits at x + r_1 + (L − r_2), so it moves at
  ẋ + ṙ_1 − ṙ_2.  (The bar material is shared: lengthening the crossbar
  shortens the stem.  This is the paper's pulley/"bladder" constraint.)

Drag on the payload is −c l ẋ and on the crossbar −c r_2 (ẋ + ṙ_1 − ṙ_2).
With a_P = (1, 0, 0) and a_B = (1, 1, −1):

    D = c l a_P a_Pᵀ + c r_2 a_B a_Bᵀ
      = [[c(l + r_2),  c r_2,  −c r_2],
         [c r_2,       c r_2,  −c r_2],
         [−c r_2,     −c r_2,   c r_2]].

Row x:   c l ẋ + c r_2 (ẋ + ṙ_1 − ṙ_2) = 0  (this is the paper's Pfaffian constraint);
row r_1: c r_2 (ẋ + ṙ_1 − ṙ_2) + d ṙ_1 + k (r_1 − l_k) = 0.

Write e = r_1 − l_k and Δ = c² l r_2 + c d (l + r_2).  Then

    ẋ   = c r_2 (d ṙ_2 + k e) / Δ,
    ṙ_1 = (c² l r_2 ṙ_2 − c (l + r_2) k e) / Δ.

For d = 0 these reduce to ẋ = k e / (c l): the spring tows the payload.  Also
ṙ_1 = ṙ_2 − λ(r_2) e with λ = k (l + r_2)/(c l r_2), so the spring length is a
first-order low-pass of the drive.  The gauge connection
ẋ = −r_2/(l + r_2) · (ṙ_1 − ṙ_2) has curl l/(l + r_2)² ≠ 0, so a lagging
passive response traces a loop in shape space, and the loop gives net
displacement.  As r_2 → 0 with d > 0, the paddle decouples: ẋ → 0 and
d ṙ_1 → −k e, whatever ṙ_2 is.  D depends on r_2 only, and r_1 enters only
through e (translation invariance).

A face length cannot be negative.  The implementation uses |r_2| as the face
length, so the map stays defined, and D stays PSD, for any probe shape (the
integrator's stiffness probe samples shapes at random).  Only 0 < r_2 < L is
physical.  At r_2 = 0 with d = 0 the passive row is singular (Δ = 0), and
:meth:`LinearPassiveSwimmer.velocities` raises.

Spring constant: the paper gives none.  With the default k = 2 N/m, the
relaxation rate λ(r_2) = k (l + r_2)/(c l r_2) runs from 8 1/s (r_2 = 0.5) to
≈5.3 1/s (r_2 = 1.5), and λ(1) = 6 1/s.  That brackets the drive's angular
frequency f = 2π rad/s.  A first-order lag driven at f encloses a shape-space
loop whose area is ∝ λ f / (λ² + f²), which is largest at λ = f, i.e.
k = f c l r̄_2 / (l + r̄_2) ≈ 2.09 N/m at the mean bar length r̄_2 = 1.  So
k = 2 gives about a 45° lag, a passive amplitude comparable to the drive's,
and close to the most net motion per cycle.

Pushmepullyou (:class:`PushmePullyou`)
--------------------------------------
Geometry: a central rod of length L_b along x, centred at x, and two pairs of
straight links of length L.  The left pair is hinged at the rod's left end,
the right pair at its right end.  The links of each pair open symmetrically
about the centre line.  The left links point along (−cos r_1, ±sin r_1): r_1
(passive) is the half-opening measured from −x.  The right links point along
(cos r_2, ±sin r_2): r_2 (driven) is measured from +x.  Drag is RFT: c∥ per
unit length along a link and c⊥ across it.  The rod only translates along its
own axis, so its drag is −c∥ L_b ẋ.

Consider a point at arclength s on the upper right link.  Its velocity is
(ẋ − s sin r_2 ṙ_2, s cos r_2 ṙ_2).  The tangential component is ẋ cos r_2;
the normal component is −ẋ sin r_2 + s ṙ_2.  Its Rayleigh function is

    ½ ∫_0^L [c∥ ẋ² cos² r_2 + c⊥ (s ṙ_2 − ẋ sin r_2)²] ds.

The lower link mirrors it and contributes the same amount.  On the left, the
normal component is ẋ sin r_1 + s ṙ_1.  Summing the parts:

    D_xx = c∥ L_b + 2L Σ_i (c∥ cos² r_i + c⊥ sin² r_i),
    D_x1 = +c⊥ L² sin r_1,   D_x2 = −c⊥ L² sin r_2,
    D_11 = D_22 = 2 c⊥ L³ / 3,   D_12 = 0.

The pairs interact only through ẋ.  Row x is the paper's constraint (with
c∥ = 1, c⊥ = 2).  Eliminating ẋ gives ẋ = c⊥ L² (s_2 ṙ_2 − s_1 ṙ_1)/D_xx,
the paper's motion model.  Row r_1 is

    c⊥ L² sin r_1 ẋ + (2 c⊥ L³/3 + d) ṙ_1 + k (r_1 − r_k) = 0.

The reduced passive drag is M_11 = D_11 − D_x1²/D_xx ≥ c⊥ L³/6 > 0, so the
solve is regular for every shape.

Symmetries, used in the tests:

* Mirror x → −x with the pairs swapped: D(r_1, r_2) = Pᵀ D(r_2, r_1) P with
  P the signed swap (−1 on x).
* The "fold" (r_1, r_2, x) → (π − r_1, π − r_2, −x) leaves D_xx and D_x·
  invariant.  If r_k = π/2 it maps solutions to solutions.  The drive
  π/2 + (π/3) sin(ft) then maps to itself shifted by half a period, so the
  periodic response makes no net progress.

Choice for the pushmepullyou: k = 1 N·m/rad and r_k = 0.5 rad.  The paper
gives both values in the sentence that states the torque balance.  The other
pair the paper mentions (k = 10, r_k = π/2) is ruled out by the fold
symmetry above: with r_k = π/2 the periodic response makes exactly zero net
progress (measured: |Δx| per cycle < 1e-15 m), which contradicts the "small
forward displacement over every cycle" that the paper reports.  Of the
remaining options, k = 1 keeps the passive pair soft (λ = k/M_11 between
0.75 and 1.31 1/s, well below f = 2π).  It therefore lags the drive and
gives the clearly visible oscillation that the estimation examples need
(noise-free std of r_1 ≈ 0.15 rad; net ≈ 6.5 mm per cycle).  k = 10 with
r_k = 0.5 would move faster (≈ 21 mm per cycle) but oscillate less
(std ≈ 0.09 rad).

Where this deviates from the paper's printed equations
------------------------------------------------------
Linear passive swimmer:

1. The kinematics and the Pfaffian constraint match the paper, as does the
   connection prefactor −c r_2/(c(l + r_2)) multiplying [1 −1](ṙ_1, ṙ_2).
2. The paper states the internal balance with an extra unknown world force
   ω (its eqs. internal-1/2 and the stacked 3×3 system).  Checked against
   the derivation here, those equations are consistent.  Adding the two
   internal equations and using the constraint gives ω = 0 (zero net
   external force in Stokes flow).  Subtracting them gives
   c l ẋ = k e + d ṙ_1, which is our row r_1.  We drop the redundant ω and
   solve the symmetric 2×2 system from D instead of the non-symmetric 3×3.
   The text's unknown "ṙ_3" and initial value "r_3(t=0)" are read as r_1.
3. k is not given in the paper; k = 2 N/m is chosen above.

Pushmepullyou:

1. Constraint: the paper's "2L² s_2 −ṙ_2" is read as 2L² s_2 (−ṙ_2), which
   is the coefficient of D_x2 derived here.
2. Motion model: "= 0" after α[−L s_1, L s_2]·ṙ is a typo.  The connection
   is ẋ = α L (−s_1 ṙ_1 + s_2 ṙ_2) with α = 1/(½ + c_1² + 2s_1² + c_2² +
   2s_2²) for L = 1, as derived.
3. Torque balance on the passive pair: the paper's row reads
   γ_1 ẋ + γ_2 ṙ_1 = k (r_1 − r_k), with γ_1 = 2L² s_1 and
   γ_2 = −2L³ + L³/12 < 0.  γ_1 is right: it equals D_1x = D_x1 =
   c⊥ L² s_1, the same coefficient as in the constraint row, as symmetry of
   D requires.  But the ṙ_1 drag then has the wrong sign relative to it
   (D_11 must be > 0).  The L³/12 term is a moment about the link's centre,
   which does not apply to a link hinged at its end.  Derived here:
   γ_2 = D_11 = 2 c⊥ L³/3 (= 4/3 for c⊥ = 2), and the right-hand side is
   −k (r_1 − r_k) (restoring).  Together, these flip the sign of the ẋ → r_1
   coupling relative to the paper's row.  The stray "−ṙ_2" on the paper's
   right-hand side becomes −D_x2 ṙ_2 = c⊥ L² s_2 ṙ_2 in row x and
   −D_12 ṙ_2 = 0 in row r_1.
4. The paper swaps the driven and passive joint names between paragraphs.
   Here r_1 (left pair) is passive and r_2 (right pair) is driven, as in its
   final equations.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsConfigError, SudsDataError

_TWO_PI = 2.0 * np.pi


def _check_finite(obj: object) -> None:
    for f in fields(obj):  # type: ignore[arg-type]
        value = getattr(obj, f.name)
        if isinstance(value, (int, float)) and not np.isfinite(value):
            raise SudsConfigError(f"`{f.name}`: expected a finite number, got {value!r}")


def _require(ok: bool, name: str, expected: str, value: object) -> None:
    if not ok:
        raise SudsConfigError(f"`{name}`: expected {expected}, got {value!r}")


def _batch(r: FloatArray, rdot_a: FloatArray) -> tuple[FloatArray, FloatArray]:
    r = np.atleast_2d(np.asarray(r, dtype=float))
    rdot_a = np.atleast_2d(np.asarray(rdot_a, dtype=float))
    if r.shape[1] != 2:
        raise SudsDataError(f"`r`: expected shape (B, 2), got {r.shape}")
    if rdot_a.shape != (r.shape[0], 1):
        raise SudsDataError(f"`rdot_a`: expected shape ({r.shape[0]}, 1), got {rdot_a.shape}")
    return r, rdot_a


def _full_rdot(r: FloatArray, rdot: FloatArray) -> tuple[FloatArray, FloatArray]:
    r = np.atleast_2d(np.asarray(r, dtype=float))
    rdot = np.atleast_2d(np.asarray(rdot, dtype=float))
    if rdot.shape != r.shape:
        raise SudsDataError(f"`rdot`: expected shape {r.shape}, got {rdot.shape}")
    return r, rdot


class _Swimmer1D:
    """Shared plumbing: D(r), the two-row solve, effort, dissipation (see module docstring)."""

    planar = False
    joint_names: tuple[str, ...] = ("joint_1", "joint_2")
    actuated: tuple[int, ...] = (1,)
    passive: tuple[int, ...] = (0,)
    _name = ""

    # subclasses provide these
    def drag_metric(self, r: FloatArray) -> FloatArray:  # pragma: no cover - abstract
        raise NotImplementedError

    def _spring(self) -> tuple[float, float, float]:  # pragma: no cover - abstract
        """(k, rest, d) of the passive element."""
        raise NotImplementedError

    def _drive(self) -> tuple[float, float, float]:  # pragma: no cover - abstract
        """(offset, amplitude, frequency Hz) of r_2 = offset + amplitude·sin(2π·hz·t)."""
        raise NotImplementedError

    @property
    def name(self) -> str:
        return self._name

    def reference(self, t: FloatArray) -> FloatArray:
        """The paper's drive r_2(t), shape (len(t), 1); t is gait time, s."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        off, amp, hz = self._drive()
        return (off + amp * np.sin(_TWO_PI * hz * t))[:, None]

    def rest_state(self) -> FloatArray:
        """Initial passive value(s), shape (1,): the spring rest."""
        return np.array([self._spring()[1]])

    def passive_force(self, r: FloatArray) -> FloatArray:
        """Spring force on r_1, shape (B, 1): −k (r_1 − rest) (N or N·m)."""
        k, rest, _ = self._spring()
        r = np.atleast_2d(np.asarray(r, dtype=float))
        return -k * (r[:, :1] - rest)

    def spring_energy(self, r: FloatArray) -> FloatArray:
        """Stored spring energy ½ k (r_1 − rest)², shape (B,), J."""
        k, rest, _ = self._spring()
        r = np.atleast_2d(np.asarray(r, dtype=float))
        return 0.5 * k * (r[:, 0] - rest) ** 2

    def velocities(self, r: FloatArray, rdot_a: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Body velocity ξ = (ẋ, 0, 0), shape (B, 3), and ṙ_1, shape (B, 1).

        Parameters
        ----------
        r : (B, 2) float
            Shapes (r_1, r_2).
        rdot_a : (B, 1) float
            Driven rate ṙ_2.
        """
        r, rdot_a = _batch(r, rdot_a)
        D = self.drag_metric(r)
        k, rest, d = self._spring()
        a11, a12, a22 = D[:, 0, 0], D[:, 0, 1], D[:, 1, 1] + d
        det = a11 * a22 - a12 * a12
        if np.any(det <= 0.0):
            bad = r[det <= 0.0][0]
            raise SudsDataError(f"`r`: passive balance is singular at shape {bad.tolist()} (no drag on r_1)")
        v = rdot_a[:, 0]
        b1 = -D[:, 0, 2] * v
        b2 = -D[:, 1, 2] * v - k * (r[:, 0] - rest)
        xi = np.zeros((r.shape[0], 3))
        xi[:, 0] = (a22 * b1 - a12 * b2) / det
        rdot_p = ((a11 * b2 - a12 * b1) / det)[:, None]
        return xi, rdot_p

    def full_rates(self, r: FloatArray, rdot_a: FloatArray) -> tuple[FloatArray, FloatArray]:
        """q̇ = (ẋ, ṙ_1, ṙ_2), shape (B, 3), from the dynamics, and D(r), shape (B, 3, 3)."""
        r, rdot_a = _batch(r, rdot_a)
        xi, rdot_p = self.velocities(r, rdot_a)
        qdot = np.stack([xi[:, 0], rdot_p[:, 0], rdot_a[:, 0]], axis=1)
        return qdot, self.drag_metric(r)

    def actuator_effort(self, r: FloatArray, rdot: FloatArray) -> FloatArray:
        """τ_2 = (D q̇)_2, shape (B, 1): force (N) or torque (N·m) the drive applies on r_2.

        Only the driven column ``rdot[:, 1]`` is used; ẋ and ṙ_1 are solved from the dynamics.
        """
        r, rdot = _full_rdot(r, rdot)
        qdot, D = self.full_rates(r, rdot[:, 1:2])
        return np.einsum("bj,bj->b", D[:, 2, :], qdot)[:, None]

    def dissipation(self, r: FloatArray, rdot: FloatArray) -> FloatArray:
        """Dissipated power q̇ᵀDq̇ + d ṙ_1², shape (B,), W (≥ 0).

        Only ``rdot[:, 1]`` is used; the rest of q̇ comes from the dynamics.
        """
        r, rdot = _full_rdot(r, rdot)
        qdot, D = self.full_rates(r, rdot[:, 1:2])
        d = self._spring()[2]
        return np.einsum("bi,bij,bj->b", qdot, D, qdot) + d * qdot[:, 1] ** 2


@dataclass(frozen=True)
class LinearPassiveParams:
    """Parameters of the linear passive swimmer (SI units; see the module docstring).

    Parameters
    ----------
    L : float
        Total bar length shared by the crossbar (r_2) and the stem (L − r_2), m (> 0).
    l : float
        Face length of the payload, m (> 0).
    c : float
        Drag coefficient per unit face length, N·s/m² (> 0).
    k : float
        Spring constant, N/m (≥ 0).  Not given in the paper; 2 puts the passive
        corner frequency at the 1 Hz drive (see module docstring).
    d : float
        Internal damping of the spring-damper, N·s/m (≥ 0).
    l_k : float
        Spring rest length, m (> 0).
    drive_offset, drive_amplitude : float
        Drive r_2 = offset + amplitude·sin(2π·drive_hz·t), m; the range must stay in (0, L).
    drive_hz : float
        Drive frequency, Hz (> 0).
    """

    L: float = 2.0
    l: float = 0.5
    c: float = 1.0
    k: float = 2.0
    d: float = 0.0
    l_k: float = 1.0
    drive_offset: float = 1.0
    drive_amplitude: float = -0.5
    drive_hz: float = 1.0

    def __post_init__(self) -> None:
        _check_finite(self)
        _require(self.L > 0, "L", "a bar length > 0 m", self.L)
        _require(self.l > 0, "l", "a payload face length > 0 m", self.l)
        _require(self.c > 0, "c", "a drag coefficient > 0", self.c)
        _require(self.k >= 0, "k", "a spring constant ≥ 0", self.k)
        _require(self.d >= 0, "d", "a damping ≥ 0", self.d)
        _require(self.l_k > 0, "l_k", "a rest length > 0 m", self.l_k)
        _require(self.drive_hz > 0, "drive_hz", "a frequency > 0 Hz", self.drive_hz)
        lo = self.drive_offset - abs(self.drive_amplitude)
        hi = self.drive_offset + abs(self.drive_amplitude)
        _require(
            0 < lo and hi < self.L,
            "drive_offset",
            f"a drive range inside (0, L={self.L}) m",
            (lo, hi),
        )


class LinearPassiveSwimmer(_Swimmer1D):
    """Payload + spring-damper (r_1, passive) + T paddle of crossbar length r_2 (driven).

    Implements :class:`~suds_ros.core.physics.system.SudsSystem`; keyword arguments
    override :class:`LinearPassiveParams` fields.
    """

    _name = "linear_passive"

    def __init__(self, params: LinearPassiveParams | None = None, **overrides: float) -> None:
        base = params if params is not None else LinearPassiveParams()
        self.params = LinearPassiveParams(**{**_asdict(base), **overrides}) if overrides else base

    def _spring(self) -> tuple[float, float, float]:
        p = self.params
        return p.k, p.l_k, p.d

    def _drive(self) -> tuple[float, float, float]:
        p = self.params
        return p.drive_offset, p.drive_amplitude, p.drive_hz

    def drag_metric(self, r: FloatArray) -> FloatArray:
        """D(r), shape (B, 3, 3), in (x, r_1, r_2) order; the face length is |r_2|."""
        r = np.atleast_2d(np.asarray(r, dtype=float))
        p = self.params
        cb = p.c * np.abs(r[:, 1])
        D = np.empty((r.shape[0], 3, 3))
        sign = np.array([1.0, 1.0, -1.0])
        D[:] = cb[:, None, None] * np.outer(sign, sign)
        D[:, 0, 0] += p.c * p.l
        return D


@dataclass(frozen=True)
class PushmePullyouParams:
    """Parameters of the pushmepullyou swimmer (SI units; see the module docstring).

    Parameters
    ----------
    L : float
        Length of each of the four links, m (> 0).
    body_length : float
        Length of the central rod (tangential drag only), m (> 0).
    c_par, c_perp : float
        RFT drag per unit length along and across a link, N·s/m² (> 0).
    k : float
        Torsional spring on the passive (left) pair, N·m/rad (≥ 0).
    r_k : float
        Spring rest half-opening of the passive pair, rad.
    d : float
        Internal rotary damping of the passive pair, N·m·s/rad (≥ 0).
    drive_offset, drive_amplitude : float
        Drive r_2 = offset + amplitude·sin(2π·drive_hz·t), rad.
    drive_hz : float
        Drive frequency, Hz (> 0).
    """

    L: float = 1.0
    body_length: float = 1.0
    c_par: float = 1.0
    c_perp: float = 2.0
    k: float = 1.0
    r_k: float = 0.5
    d: float = 0.0
    drive_offset: float = float(np.pi / 2)
    drive_amplitude: float = float(np.pi / 3)
    drive_hz: float = 1.0

    def __post_init__(self) -> None:
        _check_finite(self)
        _require(self.L > 0, "L", "a link length > 0 m", self.L)
        _require(self.body_length > 0, "body_length", "a rod length > 0 m", self.body_length)
        _require(self.c_par > 0, "c_par", "a drag coefficient > 0", self.c_par)
        _require(self.c_perp > 0, "c_perp", "a drag coefficient > 0", self.c_perp)
        _require(self.k >= 0, "k", "a spring constant ≥ 0", self.k)
        _require(self.d >= 0, "d", "a damping ≥ 0", self.d)
        _require(self.drive_hz > 0, "drive_hz", "a frequency > 0 Hz", self.drive_hz)


class PushmePullyou(_Swimmer1D):
    """Central rod with a passive left link pair (r_1) and a driven right pair (r_2).

    Implements :class:`~suds_ros.core.physics.system.SudsSystem`; keyword arguments
    override :class:`PushmePullyouParams` fields.
    """

    _name = "pushmepullyou"

    def __init__(self, params: PushmePullyouParams | None = None, **overrides: float) -> None:
        base = params if params is not None else PushmePullyouParams()
        self.params = PushmePullyouParams(**{**_asdict(base), **overrides}) if overrides else base

    def _spring(self) -> tuple[float, float, float]:
        p = self.params
        return p.k, p.r_k, p.d

    def _drive(self) -> tuple[float, float, float]:
        p = self.params
        return p.drive_offset, p.drive_amplitude, p.drive_hz

    def drag_metric(self, r: FloatArray) -> FloatArray:
        """D(r), shape (B, 3, 3), in (x, r_1, r_2) order."""
        r = np.atleast_2d(np.asarray(r, dtype=float))
        p = self.params
        s, c = np.sin(r), np.cos(r)
        D = np.zeros((r.shape[0], 3, 3))
        D[:, 0, 0] = p.c_par * p.body_length + 2 * p.L * (p.c_par * c**2 + p.c_perp * s**2).sum(axis=1)
        D[:, 0, 1] = D[:, 1, 0] = p.c_perp * p.L**2 * s[:, 0]
        D[:, 0, 2] = D[:, 2, 0] = -p.c_perp * p.L**2 * s[:, 1]
        D[:, 1, 1] = D[:, 2, 2] = 2 * p.c_perp * p.L**3 / 3
        return D


def _asdict(params: object) -> dict[str, float]:
    return {f.name: getattr(params, f.name) for f in fields(params)}  # type: ignore[arg-type]
