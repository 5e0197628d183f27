"""Chunk-by-chunk simulation for live publishing (no fixed end).

:class:`StreamingSimulator` carries the OU drive, the passive state and the
pose from one chunk to the next, so a node can publish an unbounded run at any
rate.  It uses the same physics and integrator as :func:`suds_ros.core.physics.sim.simulate`.

Effects (``shared/spec/effects.md``) can be switched on while it runs
(:meth:`StreamingSimulator.set_effects`): the next :meth:`~StreamingSimulator.step`
integrates the nominal model with the effects applied, from the state the previous
step left (drive, passive joints, pose), so the change is a step in the physics at a
sample boundary, not a jump in the state.

The reference gait can be switched too (:meth:`StreamingSimulator.set_gait`, called at a cycle
boundary by the node): from the next sample on r_ref is the new gait plus the difference
Δ = r_old − r_new at that sample, faded out over one cycle with a raised-cosine weight, so the
actuated set-points continue without a jump and settle on the new gait a cycle later.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsConfigError
from suds_ros.core.physics.gait import Gait, check_gait
from suds_ros.core.physics.sim import (
    SimConfig,
    _effort_at_samples,
    _rest_angles,
    _still,
    auto_substeps,
    integrate,
    reference_of,
)
from suds_ros.core.physics.system import SudsSystem


@dataclass(frozen=True)
class Chunk:
    """Consecutive samples of a streamed run.

    Attributes
    ----------
    t : (n,) stamps, s.
    r : (n, nj) measured joints (noise added).
    pose : (n, 3) measured pose x, y, yaw (noise added).
    r_true, pose_true : noise-free counterparts.
    phase : (n,) reference gait phase, rad.
    effort : (n, na) actuator effort averaged over the sample period ending at each sample, N·m
        (as :func:`~suds_ros.core.physics.sim.simulate` records it), or None when not asked for.
    """

    t: FloatArray
    r: FloatArray
    pose: FloatArray
    r_true: FloatArray
    pose_true: FloatArray
    phase: FloatArray
    effort: FloatArray | None = None


class StreamingSimulator:
    """Simulate a SUDS indefinitely, ``config.samples_per_cycle`` samples per gait cycle.

    ``config.cycles`` is ignored (the caller decides when to stop); ``config.warmup``
    seconds are simulated at construction.  Pose delay is not supported here.  With ``effort``
    every chunk also carries the actuator effort (:attr:`Chunk.effort`).
    """

    def __init__(self, system: SudsSystem, config: SimConfig = SimConfig(), *, effort: bool = False) -> None:
        self.system = system
        self.with_effort = bool(effort)
        self.nominal = system
        self.config = config
        self.effects: tuple[dict[str, object], ...] = ()
        self.gait = config.gait
        self._base = reference_of(system, config)  # r_ref at gait time (cycles) without the fade
        self._fade: tuple[float, FloatArray] | None = None  # (gait time of the switch, Δ there)
        self._still, self._flow = _still(system)
        self._drift = np.zeros(2)  # position offset that keeps the pose continuous across flow changes
        ss = np.random.SeedSequence(config.seed)
        self._rng_ou, self._rng_noise = (np.random.default_rng(s) for s in ss.spawn(2))
        self._dt = config.dt
        self._substeps = config.substeps or auto_substeps(self._still, self._dt)
        na = len(system.actuated)
        self._a = np.exp(-config.kappa * self._dt)
        self._b = config.ou_std * np.sqrt(1 - self._a**2)
        self._eta = config.ou_std * self._rng_ou.standard_normal(na)
        nw = int(round(config.warmup / self._dt))
        self._k = -nw - 1  # index of the last integrated sample; the first emitted sample is k = 0
        self._ra_prev = self._setpoint(self._k)
        self._rp = _rest_angles(system)
        self._pose = np.zeros(3)
        if nw:
            self._advance(nw)

    def set_effects(self, effects: Sequence[Mapping[str, object]]) -> None:
        """Simulate the nominal system with ``effects`` (replacing any earlier ones) from the next sample on.

        ``effects`` as :func:`~suds_ros.core.physics.effects.apply_effects` takes them; an empty
        list returns to the nominal physics.

        Raises
        ------
        SudsConfigError
            For a system that is not an RFT chain, an invalid effect, or ``sensor_time_offset``
            (the stream has no pose delay).
        """
        from suds_ros.core.physics.effects import apply_effects
        from suds_ros.core.physics.rft import ChainModel, RFTChain

        model = getattr(self.nominal, "model", None)
        if not isinstance(model, ChainModel):
            raise SudsConfigError(f"`effects`: only RFT chain systems take effects, got {self.nominal.name!r}")
        effects = tuple(dict(e) for e in effects)
        new_model, delay = apply_effects(model, effects)
        if delay != 0.0:
            raise SudsConfigError(
                f"`effects`: sensor_time_offset is not supported while streaming, got dt = {delay!r} s")
        system = RFTChain(new_model) if effects else self.nominal
        still, flow = _still(system)
        tt = self._k * self._dt  # at the last sample the old flow's drift holds; the new one acts after it
        self._drift += (np.asarray(self._flow) - np.asarray(flow)) * tt
        self.system, self._still, self._flow, self.effects = system, still, flow, effects
        self._substeps = self.config.substeps or auto_substeps(still, self._dt)

    def set_gait(self, gait: Gait) -> float:
        """Follow ``gait`` from the next sample on, without a jump in the set-points (see the module docstring).

        Returns
        -------
        float
            Gait time (cycles since the first emitted sample) of the first sample on the new gait.

        Raises
        ------
        SudsConfigError
            A gait of another system or joints (code ``model_mismatch``), or at another frequency.
        """
        gait = check_gait(gait, self.nominal)
        if gait.gait_hz != self.config.gait_hz:
            raise SudsConfigError(f"`gait_hz`: the gait runs at {gait.gait_hz:g} Hz, the stream at "
                                  f"{self.config.gait_hz:g} Hz")
        s0 = (self._k + 1) * self._dt * self.config.gait_hz
        old = self.reference(np.array([s0]))[0]
        self._base = gait.at_phase
        self._fade = (s0, old - gait.at_phase(np.array([s0]))[0])
        self.gait = gait
        return s0

    def reference(self, s: FloatArray) -> FloatArray:
        """r_ref at gait times ``s`` (cycles) → (len(s), na), the fade of the last switch included."""
        s = np.asarray(s, dtype=float)
        ref = self._base(s)
        if self._fade is not None:
            s0, delta = self._fade
            u = np.clip(s - s0, 0.0, 1.0)
            ref = ref + np.outer(0.5 * (1.0 + np.cos(np.pi * u)), delta)
        return ref

    def _setpoint(self, k: int) -> FloatArray:
        t = k * self._dt * self.config.gait_hz
        return self.reference(np.array([t]))[0] + self._eta

    def _advance(self, n: int) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray | None]:
        """Integrate n more samples: sample indices (n,), r (n, nj), still-fluid pose (n, 3), effort (n, na) or None."""
        ra = np.empty((n + 1, len(self.system.actuated)))
        ra[0] = self._ra_prev
        for i in range(1, n + 1):
            self._eta = self._a * self._eta + self._b * self._rng_ou.standard_normal(self._eta.size)
            ra[i] = self._setpoint(self._k + i)
        tr = integrate(self._still, ra, self._dt, self._rp, pose0=self._pose, substeps=self._substeps)
        effort = _effort_at_samples(self._still, ra, tr.r, self._dt) if self.with_effort else None
        self._ra_prev = ra[-1]
        self._rp = tr.r[-1, list(self.system.passive)]
        self._pose = tr.pose[-1]
        k = self._k + 1 + np.arange(n)
        self._k += n
        return k, tr.r[1:], tr.pose[1:], effort

    def step(self, n: int) -> Chunk:
        """The next ``n`` samples."""
        k, r, pose, effort = self._advance(n)
        tt = k * self._dt
        pose = pose.copy()
        pose[:, 0] += self._flow[0] * tt + self._drift[0]
        pose[:, 1] += self._flow[1] * tt + self._drift[1]
        sd = self.config.noise_std
        pose_noise = sd * self._rng_noise.standard_normal(pose.shape)
        if not getattr(self.system, "planar", True):  # 1-D swimmers: y and yaw stay exactly 0
            pose_noise[:, 1:] = 0.0
        return Chunk(
            t=self.config.t0 + tt,
            r=r + sd * self._rng_noise.standard_normal(r.shape),
            pose=pose + pose_noise,
            r_true=r,
            pose_true=pose,
            phase=2 * np.pi * self.config.gait_hz * tt,
            effort=effort,
        )
