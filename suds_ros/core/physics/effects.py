"""Catalogue of physical effects a simulator can include (``shared/spec/effects.md``).

Every effect is a parametric physical term of the RFT chain (:class:`~suds_ros.core.physics.rft.ChainModel`)
or of the recording's time base (:class:`~suds_ros.core.physics.sim.SimConfig` ``pose_delay``), off by
default.  The registry :data:`EFFECTS` maps each id to an :class:`EffectSpec` that documents its
parameters (names, units, admissible range, the value meaning "no effect") and carries the
effect's physics in both forms the package uses:

* ``apply``: how it modifies the simulator's :class:`~suds_ros.core.physics.rft.ChainModel`
  (and the pose delay), for simulation and for the diagnosis's output-error refinement;
* ``equation``: the terms it adds to the passive torque balance and to the measured body
  velocity (:class:`EquationTerms`), for the diagnosis's equation-error scoring.

Adding an effect means adding one entry here (both parts next to each other).

Combining effects (:func:`apply_effects`) applies them in order; offsets and joint terms add
(friction bounds, damping, rest offsets, cubic coefficients, flow components, time offsets),
scales multiply (``stiffness_to_drag_error``, ``joint_stiffness_error``) and the drag ratio is
set (``drag_anisotropy_error``).

Additions to the specification
------------------------------
``joint_stiffness_error(joint, scale)``
    The spring constant of one passive joint is ``scale`` × nominal (a mis-specified or aged
    spring on one joint; common on real robots where springs are cut or 3-D printed).  Unlike
    ``stiffness_to_drag_error`` it changes one joint only.  On a system with a single passive
    joint the two are the same physics, and the diagnosis reports them as confounded.

Model parameters as suspects
----------------------------
``link_length_error(link, scale)``, ``link_drag_error(link, scale)`` and
``pose_frame_offset(x, y, yaw)`` change a parameter of the robot model itself (``kind="model"``):
the diagnosis suspects them alongside the catalogue by default (``DiagnoseConfig.model_suspects``).
Link effects name their link ``link_k`` (1-based, head to tail).  Units and meanings: ``docs/effects.md``.

Joint effects act only on passive joints (actuated joints follow their set-points whatever
the torque); naming an actuated joint raises :class:`~suds_ros.core.errors.SudsConfigError`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsConfigError
from suds_ros.core.physics.rft import ChainModel


@dataclass(frozen=True)
class ParamSpec:
    """One parameter of an effect.

    Parameters
    ----------
    name : str
        Keyword used in :func:`apply_effect` and in diagnosis reports.
    unit : str
        SI unit (drag units of the spec: c∥ = 1, L = 1).
    lower, upper : float
        Admissible range (inclusive; ±inf for unbounded).
    neutral : float
        The value that leaves the nominal physics unchanged.
    scale : float
        Typical magnitude, used to start searches and as a finite-difference scale.
    """

    name: str
    unit: str
    lower: float
    upper: float
    neutral: float
    scale: float

    def check(self, effect: str, value: float) -> float:
        v = float(value)
        if not np.isfinite(v) or not self.lower <= v <= self.upper:
            raise SudsConfigError(
                f"effect {effect!r}: parameter `{self.name}` must lie in [{self.lower}, {self.upper}] "
                f"{self.unit}, got {value!r}"
            )
        return v


@dataclass
class EquationTerms:
    """Effects in equation-error form: what they add to the passive torque balance and to ξ.

    The residual of passive joint j on an interval with midpoint shape r̄ and rate ṙ is
    (D q̇)_j + d_j ṙ_j − τ_spring,j + mu_j sign(ṙ_j) with
    τ_spring,j = −scale·kscale_j·k_j (r̄_j − rest_j − offset_j) − scale·k3_j (r̄_j − rest_j − offset_j)³,
    D the drag metric at c⊥/c∥ = ``ratio``; the predicted body velocity gains R(−yaw)·``flow``
    and the recorded pose is re-sampled ``delay`` later.  Arrays hold one value per passive joint
    (in the model's passive order).  Built neutral by :meth:`neutral` and modified in place by
    each effect's ``equation`` (see :class:`EffectSpec`).
    """

    mu: FloatArray
    d: FloatArray
    offset: FloatArray
    k3: FloatArray
    kscale: FloatArray
    scale: float = 1.0
    ratio: float = 2.0
    flow: tuple[float, float] = (0.0, 0.0)
    delay: float = 0.0
    length: FloatArray | None = None
    drag: FloatArray | None = None
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @classmethod
    def neutral(cls, n_passive: int, ratio: float, n_links: int = 0) -> "EquationTerms":
        """No effect on ``n_passive`` passive joints and ``n_links`` links, nominal c⊥/c∥ = ``ratio``."""
        z = np.zeros(n_passive)
        return cls(mu=z.copy(), d=z.copy(), offset=z.copy(), k3=z.copy(), kscale=np.ones(n_passive),
                   ratio=ratio, length=np.ones(n_links), drag=np.ones(n_links))

    def geometry_key(self) -> tuple[float, ...]:
        """The terms that change the drag metric or the pose frame (a cache key, rounded)."""
        vals = [self.ratio, *self.pose]
        for a in (self.length, self.drag):
            if a is not None:
                vals.extend(a)
        return tuple(round(float(v), 12) for v in vals)

    def chain_model(self, model: ChainModel) -> ChainModel:
        """``model`` with the geometric terms (link lengths, link drag, pose frame, drag ratio) applied."""
        changes: dict[str, object] = {}
        if self.length is not None and np.any(self.length != 1.0):
            changes["link_length"] = tuple(float(v) for v in np.asarray(model.link_length) * self.length)
        if self.drag is not None and np.any(self.drag != 1.0):
            changes["c_par"] = tuple(float(v) for v in np.asarray(model.c_par) * self.drag)
            changes["c_perp"] = tuple(float(v) for v in np.asarray(model.c_perp) * self.drag)
        if any(v != 0.0 for v in self.pose):
            changes["pose_offset"] = tuple(float(a + b) for a, b in zip(model.pose_offset, self.pose))
        out = model.with_(**changes) if changes else model
        return out.with_drag_ratio(self.ratio)


_Applier = Callable[[ChainModel, "int | None", Mapping[str, float]], tuple[ChainModel, float]]
_Equation = Callable[[EquationTerms, "int | None", Mapping[str, float]], None]


@dataclass(frozen=True)
class EffectSpec:
    """A catalogue entry.

    Attributes
    ----------
    id : str
        Catalogue id (``joint_coulomb_friction`` …).
    params : tuple of ParamSpec
        Parameters in canonical order.
    needs_joint : bool
        True for joint effects (a passive joint is the target).
    description : str
        Exact physical meaning.
    apply : callable
        ``apply(model, joint_index_or_None, params) -> (model, pose_delay_increment)``.
    equation : callable
        ``equation(terms, passive_position_or_None, params)``: adds the effect to the
        :class:`EquationTerms` in place (the position is the joint's rank among the passive joints).
    specified : bool
        True for the effects of the specification (``shared/spec/effects.md``), False for the
        additions; among equally good explanations the diagnosis prefers specified effects.
    kind : str
        ``"catalogue"`` (physics the nominal model leaves out), ``"model"`` (an error in one of the
        robot model's own parameters) or ``"test"`` (for tests only: never a diagnosis suspect).
    target : str
        ``"joint"`` (a passive joint), ``"link"`` (a link, ``link_k``) or ``""`` (the whole chain).
    needs_passive : bool
        The effect acts only through the passive joints (joint effects, and
        ``stiffness_to_drag_error``, which scales their springs): it does not exist on a fully
        actuated chain, so it is refused there and never a diagnosis suspect.
    """

    id: str
    params: tuple[ParamSpec, ...]
    needs_joint: bool
    description: str
    apply: _Applier
    equation: _Equation
    specified: bool = True
    kind: str = "catalogue"
    target: str = ""
    needs_passive: bool = False

    def __post_init__(self) -> None:
        if self.needs_joint and not self.target:
            object.__setattr__(self, "target", "joint")
        if self.needs_joint:
            object.__setattr__(self, "needs_passive", True)

    @property
    def needs_link(self) -> bool:
        return self.target == "link"

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)


def _joint_tuple(values: tuple[float, ...], j: int, op: Callable[[float], float]) -> tuple[float, ...]:
    out = list(values)
    out[j] = op(out[j])
    return tuple(out)


def _coulomb(m: ChainModel, j: int | None, p: Mapping[str, float]) -> tuple[ChainModel, float]:
    assert j is not None
    return m.with_(coulomb=_joint_tuple(m.coulomb, j, lambda v: v + p["mu"])), 0.0  # type: ignore[arg-type]


def _coulomb_eq(t: EquationTerms, j: int | None, p: Mapping[str, float]) -> None:
    t.mu[j] += p["mu"]


def _damping(m: ChainModel, j: int | None, p: Mapping[str, float]) -> tuple[ChainModel, float]:
    assert j is not None
    return m.with_(damping=_joint_tuple(m.damping, j, lambda v: v + p["d"])), 0.0  # type: ignore[arg-type]


def _damping_eq(t: EquationTerms, j: int | None, p: Mapping[str, float]) -> None:
    t.d[j] += p["d"]


def _rest(m: ChainModel, j: int | None, p: Mapping[str, float]) -> tuple[ChainModel, float]:
    assert j is not None
    return m.with_(rest=_joint_tuple(m.rest, j, lambda v: v + p["offset"])), 0.0  # type: ignore[arg-type]


def _rest_eq(t: EquationTerms, j: int | None, p: Mapping[str, float]) -> None:
    t.offset[j] += p["offset"]


def _cubic(m: ChainModel, j: int | None, p: Mapping[str, float]) -> tuple[ChainModel, float]:
    assert j is not None
    return m.with_(k3=_joint_tuple(m.k3, j, lambda v: v + p["k3"])), 0.0  # type: ignore[arg-type]


def _cubic_eq(t: EquationTerms, j: int | None, p: Mapping[str, float]) -> None:
    t.k3[j] += p["k3"]


def _joint_stiffness(m: ChainModel, j: int | None, p: Mapping[str, float]) -> tuple[ChainModel, float]:
    assert j is not None
    return m.with_(stiffness=_joint_tuple(m.stiffness, j, lambda v: v * p["scale"])), 0.0  # type: ignore[arg-type]


def _joint_stiffness_eq(t: EquationTerms, j: int | None, p: Mapping[str, float]) -> None:
    t.kscale[j] *= p["scale"]


def _stiffness_scale(m: ChainModel, j: int | None, p: Mapping[str, float]) -> tuple[ChainModel, float]:
    return m.with_(stiffness_scale=m.stiffness_scale * p["scale"]), 0.0


def _stiffness_scale_eq(t: EquationTerms, j: int | None, p: Mapping[str, float]) -> None:
    t.scale *= p["scale"]


def _anisotropy(m: ChainModel, j: int | None, p: Mapping[str, float]) -> tuple[ChainModel, float]:
    return m.with_drag_ratio(p["ratio"]), 0.0


def _anisotropy_eq(t: EquationTerms, j: int | None, p: Mapping[str, float]) -> None:
    t.ratio = float(p["ratio"])


def _flow(m: ChainModel, j: int | None, p: Mapping[str, float]) -> tuple[ChainModel, float]:
    return m.with_(flow=(m.flow[0] + p["vx"], m.flow[1] + p["vy"])), 0.0


def _flow_eq(t: EquationTerms, j: int | None, p: Mapping[str, float]) -> None:
    t.flow = (t.flow[0] + float(p["vx"]), t.flow[1] + float(p["vy"]))


def _time_offset(m: ChainModel, j: int | None, p: Mapping[str, float]) -> tuple[ChainModel, float]:
    return m, p["dt"]


def _time_offset_eq(t: EquationTerms, j: int | None, p: Mapping[str, float]) -> None:
    t.delay += float(p["dt"])


def _link_length(m: ChainModel, j: int | None, p: Mapping[str, float]) -> tuple[ChainModel, float]:
    assert j is not None
    return m.with_(link_length=_joint_tuple(m.link_length, j, lambda v: v * p["scale"])), 0.0  # type: ignore[arg-type]


def _link_length_eq(t: EquationTerms, j: int | None, p: Mapping[str, float]) -> None:
    assert t.length is not None
    t.length[j] *= p["scale"]


def _link_drag(m: ChainModel, j: int | None, p: Mapping[str, float]) -> tuple[ChainModel, float]:
    assert j is not None
    return m.with_(
        c_par=_joint_tuple(m.c_par, j, lambda v: v * p["scale"]),  # type: ignore[arg-type]
        c_perp=_joint_tuple(m.c_perp, j, lambda v: v * p["scale"]),  # type: ignore[arg-type]
    ), 0.0


def _link_drag_eq(t: EquationTerms, j: int | None, p: Mapping[str, float]) -> None:
    assert t.drag is not None
    t.drag[j] *= p["scale"]


def _pose_frame(m: ChainModel, j: int | None, p: Mapping[str, float]) -> tuple[ChainModel, float]:
    o = m.pose_offset
    return m.with_(pose_offset=(o[0] + p["x"], o[1] + p["y"], o[2] + p["yaw"])), 0.0


def _pose_frame_eq(t: EquationTerms, j: int | None, p: Mapping[str, float]) -> None:
    t.pose = (t.pose[0] + float(p["x"]), t.pose[1] + float(p["y"]), t.pose[2] + float(p["yaw"]))


_INF = float("inf")

EFFECTS: dict[str, EffectSpec] = {
    spec.id: spec
    for spec in (
        EffectSpec(
            "joint_coulomb_friction",
            (ParamSpec("mu", "N·m", 0.0, _INF, 0.0, 0.3),),
            True,
            "dry friction −mu·sign(ṙ_j) while slipping, any torque in [−mu, mu] while stuck (exact)",
            _coulomb,
            _coulomb_eq,
        ),
        EffectSpec(
            "joint_viscous_damping",
            (ParamSpec("d", "N·m·s/rad", 0.0, _INF, 0.0, 0.3),),
            True,
            "internal damping torque −d·ṙ_j",
            _damping,
            _damping_eq,
        ),
        EffectSpec(
            "spring_rest_offset",
            (ParamSpec("offset", "rad", -np.pi, np.pi, 0.0, 0.1),),
            True,
            "spring rest angle r_rest + offset: torque −k_j (r_j − r_rest − offset)",
            _rest,
            _rest_eq,
        ),
        EffectSpec(
            "spring_nonlinearity",
            (ParamSpec("k3", "N·m/rad³", -_INF, _INF, 0.0, 1.0),),
            True,
            "extra spring torque −k3·(r_j − r_rest)³ (effective rest angle if offset too)",
            _cubic,
            _cubic_eq,
        ),
        EffectSpec(
            "stiffness_to_drag_error",
            (ParamSpec("scale", "–", 1e-3, 1e3, 1.0, 0.1),),
            False,
            "every passive k_j (and k3) × scale ⇔ every drag coefficient / scale",
            _stiffness_scale,
            _stiffness_scale_eq,
            needs_passive=True,
        ),
        EffectSpec(
            "drag_anisotropy_error",
            (ParamSpec("ratio", "–", 1e-2, 1e2, 2.0, 0.2),),
            False,
            "c⊥/c∥ = ratio with c∥ kept (nominal 2); link drag diag(L, ratio·L, ratio·L³/12)",
            _anisotropy,
            _anisotropy_eq,
        ),
        EffectSpec(
            "background_flow",
            (ParamSpec("vx", "m/s", -_INF, _INF, 0.0, 0.05), ParamSpec("vy", "m/s", -_INF, _INF, 0.0, 0.05)),
            False,
            "uniform world-frame current U = (vx, vy): the chain is advected, ξ gains R(−yaw)·U",
            _flow,
            _flow_eq,
        ),
        EffectSpec(
            "sensor_time_offset",
            (ParamSpec("dt", "s", -1.0, 1.0, 0.0, 0.02),),
            False,
            "pose stamps late by dt: the pose stamped s is the true pose at s − dt",
            _time_offset,
            _time_offset_eq,
        ),
        EffectSpec(
            "joint_stiffness_error",
            (ParamSpec("scale", "–", 1e-3, 1e3, 1.0, 0.1),),
            True,
            "spring constant of one passive joint × scale (addition to the spec)",
            _joint_stiffness,
            _joint_stiffness_eq,
            specified=False,
        ),
        EffectSpec(
            "link_length_error",
            (ParamSpec("scale", "–", 0.2, 5.0, 1.0, 0.1),),
            False,
            "length of one link × scale (its drag scales with it: c∥L, c⊥L, c⊥L³/12)",
            _link_length,
            _link_length_eq,
            specified=False,
            kind="model",
            target="link",
        ),
        EffectSpec(
            "link_drag_error",
            (ParamSpec("scale", "–", 0.05, 20.0, 1.0, 0.1),),
            False,
            "both drag coefficients (c∥, c⊥) of one link × scale",
            _link_drag,
            _link_drag_eq,
            specified=False,
            kind="model",
            target="link",
        ),
        EffectSpec(
            "pose_frame_offset",
            (ParamSpec("x", "m", -2.0, 2.0, 0.0, 0.05), ParamSpec("y", "m", -2.0, 2.0, 0.0, 0.05),
             ParamSpec("yaw", "rad", -np.pi, np.pi, 0.0, 0.05)),
            False,
            "the recorded pose frame sits at (x, y, yaw) from where the model puts it (body-link frame)",
            _pose_frame,
            _pose_frame_eq,
            specified=False,
            kind="model",
        ),
    )
}


def joint_index(model: ChainModel, joint: object, effect: str) -> int:
    """0-based index of the passive joint named ``joint`` (``"joint_k"``, 1-based, head to tail)."""
    names = list(model.joint_names)
    if isinstance(joint, str) and joint in names:
        j = names.index(joint)
    else:
        raise SudsConfigError(
            f"effect {effect!r}: `joint` must be one of {names}, got {joint!r}"
        )
    if j not in model.passive:
        passive = [names[i] for i in model.passive]
        raise SudsConfigError(
            f"effect {effect!r}: joint {joint!r} is actuated; joint effects act on the passive joints {passive}"
        )
    return j


def link_index(model: ChainModel, link: object, effect: str) -> int:
    """0-based index of the link named ``link`` (``"link_k"``, 1-based, head to tail)."""
    names = [f"link_{i + 1}" for i in range(model.n_links)]
    if not (isinstance(link, str) and link in names):
        raise SudsConfigError(f"effect {effect!r}: `link` must be one of {names}, got {link!r}")
    return names.index(link)


def _apply(model: ChainModel, name: str, joint: object, params: Mapping[str, object]) -> tuple[ChainModel, float]:
    spec = EFFECTS.get(name)
    if spec is None:
        raise SudsConfigError(f"unknown effect {name!r}; catalogue: {', '.join(EFFECTS)}")
    unknown = set(params) - set(spec.param_names)
    if unknown:
        raise TypeError(f"effect {name!r}: unknown parameter(s) {sorted(unknown)}; expected {list(spec.param_names)}")
    missing = [p for p in spec.param_names if p not in params]
    if missing:
        raise SudsConfigError(f"effect {name!r}: missing parameter(s) {missing}")
    values = {p.name: p.check(name, params[p.name]) for p in spec.params}  # type: ignore[arg-type]
    if spec.needs_passive and not model.passive:
        raise SudsConfigError(
            f"effect {name!r} acts through the passive joints; {model.name!r} has none (every joint "
            "is actuated): on a fully actuated chain use the global effects (background_flow, "
            "drag_anisotropy_error, sensor_time_offset) or the model parameters"
        )
    if spec.needs_link:
        j: int | None = link_index(model, joint, name)
    elif spec.needs_joint:
        j = joint_index(model, joint, name)
    else:
        if joint is not None:
            raise SudsConfigError(f"effect {name!r} acts on the whole chain; got a joint {joint!r}")
        j = None
    return spec.apply(model, j, values)


def apply_effect(model: ChainModel, name: str, joint: str | None = None, **params: float) -> ChainModel:
    """The model with one effect added.

    ``sensor_time_offset`` does not change the physics (it acts on the recording's pose stamps):
    the model is returned unchanged; use :func:`apply_effects` to obtain the pose delay.

    Examples
    --------
    >>> m = apply_effect(purcell3_model(), "joint_coulomb_friction", joint="joint_2", mu=0.7)
    """
    return _apply(model, name, joint, params)[0]


def apply_effects(model: ChainModel, effects: Sequence[Mapping[str, object]]) -> tuple[ChainModel, float]:
    """Apply effects in order; returns the model and the pose delay (s) for ``SimConfig.pose_delay``.

    Each effect is a mapping ``{"name": id, "joint" (or "target"): "joint_k" | None, <param>: value, …}``.
    """
    delay = 0.0
    for i, eff in enumerate(effects):
        eff = dict(eff)
        if "name" not in eff:
            raise SudsConfigError(f"effect #{i}: missing `name` (one of {', '.join(EFFECTS)})")
        name = str(eff.pop("name"))
        joint = eff.pop("joint", None)
        if joint is None:
            joint = eff.pop("link", None)
        target = eff.pop("target", None)
        if joint is None:
            joint = target
        elif target is not None and target != joint:
            raise SudsConfigError(f"effect {name!r}: `joint` {joint!r} and `target` {target!r} disagree")
        model, d = _apply(model, name, joint, eff)
        delay += d
    return model, delay


def neutral_params(name: str, model: ChainModel | None = None) -> dict[str, float]:
    """The parameter values of ``name`` that leave ``model``'s nominal physics unchanged.

    The drag ratio is absolute, so its neutral value is the model's own c⊥/c∥ (a model-file robot
    with c⊥ = 1.9, c∥ = 0.8 has 2.375); without a model, the catalogue's 2.
    """
    out = {p.name: p.neutral for p in EFFECTS[name].params}
    if model is not None and name == "drag_anisotropy_error":
        out["ratio"] = model.drag_ratio
    return out
