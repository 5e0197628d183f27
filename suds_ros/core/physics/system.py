"""The interface every simulated SUDS exposes to the integrator and the tools.

A shape-underactuated dissipative system (SUDS) has joints r = r_a ⊕ r_p.  With
momentum negligible, the body velocity g° and the passive shape velocity ṙ_p
are fixed by the shape r and the driven shape velocity ṙ_a (affine in ṙ_a for
linear passive elements).  :class:`SudsSystem` is that map plus the ground-truth
extras (actuator effort, dissipated power) and the system's nominal gait.

All array arguments are batched along a leading axis: ``r`` is (B, nj),
``rdot_a`` is (B, na).  Body velocity is always returned as planar
(ξx, ξy, ξθ) in the body frame; one-dimensional swimmers return (ẋ, 0, 0).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from suds_ros.core._typing import FloatArray


@runtime_checkable
class SudsSystem(Protocol):
    """Structural type of a simulated SUDS (see module docstring)."""

    @property
    def name(self) -> str:
        """System id, e.g. ``"purcell3"``."""

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the nj joints in ``r`` column order."""

    @property
    def actuated(self) -> tuple[int, ...]:
        """Indices (0-based) of the actuated joints."""

    @property
    def passive(self) -> tuple[int, ...]:
        """Indices (0-based) of the passive joints."""

    @property
    def planar(self) -> bool:
        """True for SE(2) motion (x, y, yaw); False for motion along x only."""

    def velocities(self, r: FloatArray, rdot_a: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Body velocity (B, 3) and passive shape velocity (B, np) at shape ``r`` (B, nj)."""

    def actuator_effort(self, r: FloatArray, rdot: FloatArray) -> FloatArray:
        """Generalised force (B, na) the actuators apply on their joint coordinates."""

    def dissipation(self, r: FloatArray, rdot: FloatArray) -> FloatArray:
        """Power (B,) dissipated by drag and internal losses, W (≥ 0)."""

    def reference(self, t: FloatArray) -> FloatArray:
        """Nominal actuated set-points r_ref(t), shape (len(t), na), for gait time t (s)."""
