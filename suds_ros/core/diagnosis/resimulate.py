"""Re-simulating with a discovered torque: the discovery's formula inside the simulator.

A discovered formula (:mod:`.discovery`) is an extra torque τ_x,j(r, ṙ) on passive joint j, in
N·m, built from the discovery library's terms (e = r_j − rest_j, ṙ = ṙ_j, the actuated angles and
rates).  It enters the still-fluid balance of the chain exactly as the catalogue's joint torques
do: with the unknowns u = (ξ, ṙ_p) the balance A u = b of
:meth:`~suds_ros.core.physics.rft.RFTChain.solve` gains τ_x on the passive rows,

    A u = b + P τ_x(r, ṙ_p),   so   u = u₀ + A⁻¹ P τ_x(r, ṙ_p),

u₀ the chain's own solution.  τ_x depends on ṙ_p, so ṙ_p is found by Newton's method on
F(v) = v − v₀ − M τ_x(v), M = (A⁻¹)_pp, with the exact derivative of each term in its own joint's
rate (sign(ṙ) is smoothed as tanh(ṙ/ε), ε = ``SIGN_EPS``, for the derivative only).  A is the drag
metric of the chain's solution plus its viscous damping; a model with Coulomb friction has no
single linear A, so its re-simulation is refused (:class:`~suds_ros.core.errors.SudsConfigError`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsConfigError
from suds_ros.core.physics.rft import ChainModel, RFTChain

SIGN_EPS = 1e-2  # rad/s: smoothing of sign(ṙ) in the Newton derivative
NEWTON_ITERS = 20


def _term(name: str, e: FloatArray, v: FloatArray, r: FloatArray, rdot_a: FloatArray,
          act_index: Mapping[str, tuple[int, int]]) -> tuple[FloatArray, FloatArray]:
    """Value of one library term and its derivative in the joint's own rate ṙ.

    ``act_index``: actuated joint name → (index among all joints, position in ṙ_a).
    """
    one, zero = np.ones_like(v), np.zeros_like(v)
    if name == "1":
        return one, zero
    if name == "e":
        return e, zero
    if name == "e^2":
        return e**2, zero
    if name == "e^3":
        return e**3, zero
    if name == "rdot":
        return v, one
    if name == "sign(rdot)":
        return np.sign(v), (1.0 - np.tanh(v / SIGN_EPS) ** 2) / SIGN_EPS
    if name == "|rdot|rdot":
        return np.abs(v) * v, 2.0 * np.abs(v)
    if name == "e*rdot":
        return e * v, e
    for prefix, cols in (("r(", r), ("rdot(", rdot_a)):
        if name.startswith(prefix) and name.endswith(")") and name[len(prefix):-1] in act_index:
            a, pos = act_index[name[len(prefix):-1]]
            return (cols[:, a] if prefix == "r(" else cols[:, pos]), zero
    raise SudsConfigError(f"discovered term {name!r}: not a term of the discovery library")


class DiscoveredTorqueChain:
    """The velocities of ``model`` with discovered torques on passive joints (module docstring).

    ``terms`` maps a passive joint name to its formula {library term: coefficient (N·m per unit)}.
    Usable wherever a ``velocities(r, ṙ_a)`` callable is (the replay's integrator).
    """

    def __init__(self, model: ChainModel, terms: Mapping[str, Mapping[str, float]]) -> None:
        if any(c > 0 for c in np.asarray(model.coulomb, dtype=float).ravel()):
            raise SudsConfigError("`model`: re-simulating a discovered torque needs a model without Coulomb "
                                  f"friction, got coulomb={model.coulomb!r}")
        if model.flow != (0.0, 0.0):
            raise SudsConfigError(f"`model`: the replay adds the flow; pass the model without it, got {model.flow!r}")
        self.chain = RFTChain(model)
        names = model.joint_names
        pas = list(model.passive)
        self.pas = np.asarray(pas, dtype=np.intp)
        self.rest = np.asarray(model.rest, dtype=float)
        self.damping = np.broadcast_to(np.asarray(model.damping, dtype=float), (len(names),))[self.pas]
        self.act_index = {names[a]: (a, k) for k, a in enumerate(model.actuated)}
        self.terms: list[tuple[int, int, dict[str, float]]] = []
        for jname, formula in terms.items():
            if jname not in names or names.index(jname) not in pas:
                raise SudsConfigError(f"`terms`: {jname!r} is not a passive joint of {model.name!r}")
            j = names.index(jname)
            self.terms.append((pas.index(j), j, dict(formula)))

    def _torque(self, r: FloatArray, rdot_a: FloatArray, v: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Extra torque (B, np) and its derivative in each joint's own rate (B, np)."""
        tau = np.zeros_like(v)
        dtau = np.zeros_like(v)
        for jp, j, formula in self.terms:
            e = r[:, j] - self.rest[j]
            for name, coef in formula.items():
                val, der = _term(name, e, v[:, jp], r, rdot_a, self.act_index)
                tau[:, jp] += coef * val
                dtau[:, jp] += coef * der
        return tau, dtau

    def velocities(
        self, r: FloatArray, rdot_a: FloatArray, yaw: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Body velocity ξ (B, 3) of the pose frame and passive velocities ṙ_p (B, np)."""
        r = np.atleast_2d(np.asarray(r, dtype=float))
        rdot_a = np.atleast_2d(np.asarray(rdot_a, dtype=float))
        xi0, v0, D = self.chain.solve(r, rdot_a)  # D ordered (ξ, r_p, r_a)
        nu = 3 + self.pas.size
        A = D[:, :nu, :nu].copy()
        idx = np.arange(3, nu)
        A[:, idx, idx] += self.damping
        Ainv = np.linalg.inv(A)
        M = Ainv[:, 3:, 3:]
        v = v0.copy()
        eye = np.eye(self.pas.size)
        for _ in range(NEWTON_ITERS):
            tau, dtau = self._torque(r, rdot_a, v)
            F = v - v0 - np.einsum("bij,bj->bi", M, tau)
            J = eye - M * dtau[:, None, :]
            step = np.linalg.solve(J, F[..., None])[..., 0]
            v = v - step
            if np.max(np.abs(step)) < 1e-12:
                break
        tau, _ = self._torque(r, rdot_a, v)
        xi = xi0 + np.einsum("bij,bj->bi", Ainv[:, :3, 3:], tau)
        return self.chain.to_pose_frame(xi), v
