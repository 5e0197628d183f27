"""An experiment that settles an ambiguous finding: the drive under which two explanations differ most.

When the diagnosis reports a finding with alternatives (:class:`~.report.Alternative`), the
recording cannot tell the explanations apart: under the drive that was run their predictions
agree to within the noise.  Under another drive they may not.  This module searches the robot's
admissible gaits (``shared/spec/gait.md``: joint range and joint speed per actuated joint, the
robot's gait frequency, K ≤ 3 harmonics) for the one that separates the two explanations best.

Separation of a gait, in nats per cycle: both explanations are simulated under the gait (two
warm-up cycles, then one cycle at the passive periodic steady state, batched over candidate
gaits), and the expected log-likelihood ratio of one cycle of recording between them, as the
diagnosis' output-error evidence counts it, is

    Σ_c (n_c / 2)·log(1 + P_c),   P_c = mean over the cycle of (Δ_c / σ_c)²

over the channels c (each passive angle, its n_c samples; the body velocity on n_c
non-overlapping windows), with the recording's own noise floors σ_c; for a small difference
that is ½·Σ(Δ/σ)².  Because a new
recording would refit each explanation's parameters, the final separation is measured after
refitting the alternative's parameters to the reported set's predictions under the proposed gait
(and vice versa; the smaller of the two counts): a difference that a parameter change absorbs is
no separation.  When one set is nested in the other (the nominal model, or a set with one
effect more), the smaller one is mimicked exactly by the larger at its neutral values, so only
the larger set's departure counts.  The search: the baseline drive (the one the recording ran,
fitted from it, else the nominal gait), seeded random admissible gaits around it, then random
steps around the best; the best few and the baseline are refitted,
and the best of them is proposed (so never a drive that separates less than the one already
run, when that one shows the mismatch well enough).  A drive is admitted only if it shows the
mismatch per sample (``ExperimentConfig.visible_power``; or as well as the best drive tried, when
none does): the diagnosis locates a mismatch by its power over the noise floor, which more
cycles of a drive that hides it do not raise.

Cycles needed: the diagnosis scores held-out evidence on half of the cycles, so a recording of
N cycles gives about ½·N·(nats per cycle) between the explanations; N is the smallest count (at
least 8) for which that reaches the threshold (the larger of ``evidence_threshold`` and
``ambiguity_band``) after the BIC penalty of the reported set's extra parameters, with a margin
of ``z`` spreads, and for which the reported set's own
mismatch with the nominal model reaches it too under that drive.  With several alternatives one
run can be proposed against all of them (:func:`propose_all`: the smallest separation over them
is maximised).  Explanations that no admissible drive
separates (the same physics, e.g. one passive joint's stiffness and the global stiffness-to-drag
scale) are reported as such, with no gait.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.optimize

from suds_ros.core._typing import FloatArray
from suds_ros.core.diagnosis.naming import Candidate
from suds_ros.core.diagnosis.replay import measure
from suds_ros.core.diagnosis.report import (
    NO_EFFECT,
    Alternative,
    DiagnoseConfig,
    DiagnosisReport,
    FittedEffect,
    effect_label,
    set_label,
)
from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.core.physics.effects import EFFECTS, apply_effects
from suds_ros.core.physics.gait import Gait, GaitLimits, checked_extremes, constraint_violations, gait_limits
from suds_ros.core.physics.gait import fitted_gait, nominal_gait
from suds_ros.core.physics.integrate import integrate_batch
from suds_ros.core.physics.rft import ChainModel, RFTChain
from suds_ros.core.physics.sim import auto_substeps
from suds_ros.core.recording import Recording

#: an effect as ``apply_effects`` takes it
Effect = dict[str, object]

#: below this many nats per cycle no recording of reasonable length separates two explanations
INSEPARABLE_NATS = 0.05


@dataclass(frozen=True)
class ExperimentConfig:
    """How the experiment is searched.

    Parameters
    ----------
    order : int
        Harmonics K of the proposed gait (≤ 3 per ``gait.md``).
    candidates : int
        Random admissible gaits in the first round (and again around the best in the second).
    refit : int
        Best candidates whose separation is measured after refitting the parameters.
    warm_cycles : int
        Cycles simulated before the scored cycle (the passive joints settle).
    seed : int
        Seed of the random search.
    min_cycles : int
        Fewest cycles a proposal asks for (the diagnosis needs whole halves to train and test).
    visible_power : float
        The diagnosis locates a mismatch by a channel's residual power over its noise floor
        (F = 1 + power > ``f_threshold``), which more cycles do not raise.  A drive is admitted
        only if the reported set's largest per-channel power against the nominal model under it
        (mean of (Δ/σ)²) is at least this much or, when no drive tried reaches it, at least the
        largest any does (the baseline, the first round and a climb on that power).
    z : float
        Margin of the cycles asked for: held-out evidence E has a spread of about √(2E) nats, so
        the proposal asks for E with E − z·√(2E) = the threshold.
    """

    order: int = 2
    candidates: int = 48
    refit: int = 3
    warm_cycles: int = 2
    seed: int = 0
    min_cycles: int = 8
    visible_power: float = 2.0
    z: float = 2.0

    def __post_init__(self) -> None:
        for name, ok in (("order", 1 <= self.order <= 3), ("candidates", self.candidates >= 1),
                         ("refit", self.refit >= 1), ("warm_cycles", self.warm_cycles >= 1),
                         ("min_cycles", self.min_cycles >= 4), ("visible_power", self.visible_power > 0),
                         ("z", self.z >= 0)):
            if not ok:
                raise SudsConfigError(f"`{name}`: value {getattr(self, name)!r} out of range")


@dataclass(frozen=True)
class ProposedExperiment:
    """The drive that best tells the reported explanation from one alternative.

    ``gait`` is None when no admissible drive separates them (``separable`` False).
    ``nats_per_cycle``: expected evidence between them per cycle under ``gait`` (after refitting);
    ``baseline_nats_per_cycle`` the same under the baseline drive (the one the recording ran, as
    fitted from it, or the nominal gait: ``baseline``); ``cycles`` the cycles of ``gait`` that
    give ``threshold`` nats of held-out evidence; ``is_baseline``: no admissible drive tried
    separates them better than the baseline, which is then the proposal (more cycles of it).
    ``mismatch_power``: the reported set's largest per-channel mean (Δ/σ)² against the nominal
    model under ``gait`` (the locator's F − 1 to expect; below ``f_threshold`` − 1 the new run's
    mismatch may not be located however long it is).
    """

    reported: str
    alternative: str
    gait: Gait | None
    nats_per_cycle: float
    baseline_nats_per_cycle: float
    cycles: int | None
    threshold: float
    is_baseline: bool = False
    mismatch_power: float = float("nan")
    baseline: str = "nominal"

    @property
    def separable(self) -> bool:
        return self.gait is not None

    def as_dict(self) -> dict[str, object]:
        return {
            "reported": self.reported,
            "alternative": self.alternative,
            "separable": self.separable,
            "nats_per_cycle": float(self.nats_per_cycle),
            "baseline_nats_per_cycle": float(self.baseline_nats_per_cycle),
            "cycles": self.cycles,
            "threshold": float(self.threshold),
            "baseline": self.baseline,
            "baseline_drive": self.is_baseline,
            "mismatch_power": None if not math.isfinite(self.mismatch_power) else float(self.mismatch_power),
        }


def _as_effect(name: str, target: str | None, params: Mapping[str, float]) -> Effect:
    e: Effect = {"name": name, **{k: float(v) for k, v in params.items()}}
    if target is not None:
        e["link" if EFFECTS[name].needs_link else "joint"] = target
    return e


def reported_effects(effects: Sequence[FittedEffect]) -> list[Effect]:
    """The reported effects with their fitted parameters, as effect dicts for ``apply_effects``."""
    return [_as_effect(e.name, e.target, e.parameters) for e in effects]


def effect_sets(effects: Sequence[FittedEffect], alt: Alternative) -> tuple[list[Effect], list[Effect]]:
    """The reported set and the alternative set, as effect dicts for ``apply_effects``."""
    reported = reported_effects(effects)
    dropped = set(alt.instead_of)
    keep = [e for e in effects if effect_label(e.name, e.target) not in dropped]
    other = [_as_effect(e.name, e.target, e.parameters) for e in keep]
    other.extend(_as_effect(n, t, p) for n, t, p in alt.added)
    return reported, other


class _Simulator:
    """Batched steady-cycle outputs of an explanation under candidate gaits."""

    def __init__(self, base: ChainModel, floors: Mapping[str, float], names: Sequence[str],
                 dt: float, w: int, warm_cycles: int) -> None:
        self.base = base
        self.system = RFTChain(base)
        self.act = np.asarray(base.actuated, dtype=np.intp)
        self.pas = np.asarray(base.passive, dtype=np.intp)
        self.dt, self.w = float(dt), int(w)
        self.spc = int(round(1.0 / (base.gait_hz * dt)))
        self.m = (warm_cycles + 1) * self.spc + self.w
        self.t = np.arange(self.m) * self.dt
        self.first = warm_cycles * self.spc
        sig = [floors.get(names[j], float("nan")) for j in self.pas]
        self.sig_rp = np.asarray(sig, dtype=float)
        self.sig_xi = np.array([floors.get("xi_x", np.nan), floors.get("xi_y", np.nan),
                                floors.get("xi_theta", np.nan)], dtype=float)
        self.substeps = min(auto_substeps(self.system, self.dt, accuracy=0.4), 8)

    def outputs(self, effects: Sequence[Effect], gaits: Sequence[Gait]) -> tuple[FloatArray, FloatArray]:
        """Scored cycle of r_p (B, spc, np) and non-overlapping windowed ξ (B, spc // w, 3)."""
        model, delay = apply_effects(self.base, list(effects))
        still = model.with_(flow=(0.0, 0.0))
        ra = np.stack([g.r(self.t) for g in gaits])
        B = ra.shape[0]
        nj = self.act.size + self.pas.size
        rest = np.broadcast_to(np.asarray(model.rest, dtype=float), (nj,))[self.pas]
        rp0 = np.zeros((B, self.pas.size)) + rest
        RP, P = integrate_batch(RFTChain(still).velocities, self.act, self.pas, ra, rp0, np.zeros((B, 3)),
                                self.dt, self.substeps)
        xi = measure(P, np.broadcast_to(self.t, (B, self.m)), model.flow, delay, self.w, self.dt)
        a, b = self.first, self.first + self.spc
        return RP[:, a:b], xi[:, a:b:self.w]

    def _channels(self, A: tuple[FloatArray, FloatArray],
                  Bo: tuple[FloatArray, FloatArray]) -> tuple[FloatArray, FloatArray]:
        """Per gait and channel (passive angles, then ξ): mean (Δ/σ)² over a cycle and its sample count."""
        B = A[1].shape[0]
        P_rp = np.mean(((A[0] - Bo[0]) / self.sig_rp) ** 2, axis=1) if self.pas.size else np.zeros((B, 0))
        dxi = (A[1] - Bo[1]) / self.sig_xi
        n_rp = np.full((B, self.pas.size), float(A[0].shape[1]))
        return (np.concatenate([P_rp, np.nanmean(dxi**2, axis=1)], axis=1),
                np.concatenate([n_rp, np.sum(np.isfinite(dxi), axis=1).astype(float)], axis=1))

    def nats(self, A: tuple[FloatArray, FloatArray], Bo: tuple[FloatArray, FloatArray]) -> FloatArray:
        """Expected log-likelihood ratio of one cycle between two explanations' outputs, per gait.

        The diagnosis' output-error evidence, Σ_c (n_c/2)·log(1 + P_c) with P_c the channel's
        mean (Δ/σ)² (½·Σ(Δ/σ)² while the difference is small beside the noise).
        """
        P, n = self._channels(A, Bo)
        ok = np.isfinite(P)
        return 0.5 * np.sum(np.where(ok, n * np.log1p(np.where(ok, P, 0.0)), 0.0), axis=1)

    def power(self, A: tuple[FloatArray, FloatArray], Bo: tuple[FloatArray, FloatArray]) -> FloatArray:
        """Largest per-channel mean of (Δ/σ)² between two explanations' outputs, per gait (the locator's F − 1)."""
        P, _ = self._channels(A, Bo)
        return np.nanmax(np.nan_to_num(P, nan=-np.inf), axis=1)

    def samples(self, cycles: int) -> float:
        """The median channel's sample count on the held-out half of ``cycles`` cycles (the BIC's n)."""
        per = [self.spc] * self.pas.size + [self.spc / self.w] * 3
        return max(float(np.median(per)) * cycles / 2.0, 2.0)


def _admissible(x: FloatArray, template: Gait, order: int, limits: GaitLimits) -> Gait:
    """The gait of flat parameters ``x`` shrunk per joint (towards zero) until it meets the limits."""
    g = template.from_vector(x, order, objective=None, predicted=())
    r, v = checked_extremes(g)
    lim, spd = np.asarray(limits.limit), np.asarray(limits.speed_limit)
    s = np.minimum(1.0, np.minimum(lim / np.maximum(r, 1e-300), spd / np.maximum(v, 1e-300))) * (1 - 1e-9)
    m = np.asarray(x, dtype=float).reshape(len(g.joints), 2 * order + 1) * s[:, None]
    return template.from_vector(m.ravel(), order, objective=None, predicted=())


def _refit(sim: _Simulator, fixed: Sequence[Effect], free: Sequence[Effect], gait: Gait) -> float:
    """Nats per cycle between ``fixed`` and ``free`` under ``gait`` after refitting ``free``'s parameters."""
    target = sim.outputs(fixed, [gait])
    cand = Candidate(_parts(free))
    x0 = np.array([float(e[p]) for e in free for p in EFFECTS[str(e["name"])].param_names])  # type: ignore[arg-type]
    lo, hi = (np.asarray(b, dtype=float) for b in cand.bounds())
    scale = cand.scales()
    x0 = np.clip(x0, lo + 1e-6 * scale, hi - 1e-6 * scale)

    def resid(x: FloatArray) -> FloatArray:
        try:
            rp, xi = sim.outputs(cand.effects(x), [gait])
        except (SudsConfigError, FloatingPointError, np.linalg.LinAlgError):
            return np.full(target[0].size + target[1].size, 1e3)
        drp = ((rp - target[0]) / sim.sig_rp).ravel() if sim.pas.size else np.zeros(0)
        dxi = np.nan_to_num(((xi - target[1]) / sim.sig_xi).ravel())
        return np.concatenate([drp, dxi])

    def nats(x: FloatArray) -> float:
        try:
            return float(sim.nats(target, sim.outputs(cand.effects(x), [gait]))[0])
        except (SudsConfigError, FloatingPointError, np.linalg.LinAlgError):
            return float("inf")

    if x0.size == 0:
        return nats(x0)
    sol = scipy.optimize.least_squares(resid, x0, bounds=(lo, hi), x_scale=scale, max_nfev=20 * (x0.size + 1))
    return min(nats(sol.x), nats(x0))


def propose(
    base: ChainModel, reported: Sequence[Effect], alternative: Sequence[Effect], floors: Mapping[str, float],
    dt: float, w: int, threshold: float, config: ExperimentConfig = ExperimentConfig(),
    labels: tuple[str, str] = ("reported", "alternative"), run: Gait | None = None,
) -> ProposedExperiment:
    """The admissible gait that best separates ``reported`` from ``alternative`` on ``base``.

    ``floors`` are the recording's noise floors by channel (passive joint names, ``xi_x``,
    ``xi_y``, ``xi_theta``), ``dt`` its sample period (s) and ``w`` the body-velocity window.
    ``run``: the drive the recording ran (:func:`~suds_ros.core.physics.gait.fitted_gait`), the
    baseline and the centre of the search; None: the robot's nominal gait.
    """
    return propose_all(base, reported, [alternative], floors, dt, w, threshold, config, labels, run)


def propose_all(
    base: ChainModel, reported: Sequence[Effect], alternatives: Sequence[Sequence[Effect]],
    floors: Mapping[str, float], dt: float, w: int, threshold: float, config: ExperimentConfig = ExperimentConfig(),
    labels: tuple[str, str] = ("reported", "alternatives"), run: Gait | None = None,
) -> ProposedExperiment:
    """The admissible gait that best separates ``reported`` from every one of ``alternatives`` at once.

    A gait's separation is the smallest over the alternatives (the run settles the finding only
    when it tells the reported set from each of them); otherwise as :func:`propose`.  The cycles
    asked for also make the reported set's own mismatch with the nominal model reach
    ``threshold`` under the gait (a drive that separates the explanations but hides the mismatch
    would not be diagnosed at all).
    """
    if not alternatives:
        raise SudsConfigError("`alternatives`: expected at least one alternative set, got none")
    system = RFTChain(base)
    nominal = nominal_gait(system)
    limits = gait_limits(system, nominal)
    names = system.joint_names
    sim = _Simulator(base, floors, names, dt, w, config.warm_cycles)
    order = config.order
    rng = np.random.default_rng(config.seed)
    if run is not None and run.joints != nominal.joints:
        raise SudsConfigError(f"`run`: expected a drive of the joints {list(nominal.joints)}, got {list(run.joints)}")
    centre, kind = (nominal, "nominal") if run is None else (run, "recorded")
    if centre.order > order:  # the proposal's harmonics only
        _, c, sn = centre.arrays()
        centre = dataclasses.replace(centre, cos=tuple(map(tuple, c[:, :order])), sin=tuple(map(tuple, sn[:, :order])))
    x_run = centre.to_vector(order)
    span = np.repeat(np.asarray(limits.limit), 2 * order + 1)

    mine = set(_parts(reported))

    def refitted(g: Gait) -> float:
        seps = []
        for alt in alternatives:
            theirs = set(_parts(alt))
            # a set nested in the other is mimicked exactly by the larger one at its neutral
            # values: only the larger set's departure from the smaller one can be seen
            one = [] if mine <= theirs else [_refit(sim, reported, alt, g)]
            two = [] if theirs <= mine else [_refit(sim, alt, reported, g)]
            seps.append(min(one + two) if one + two else 0.0)
        return min(seps)

    baseline = _admissible(x_run, nominal, order, limits)

    def measured(gaits: list[Gait]) -> tuple[FloatArray, FloatArray]:
        """(separation before refitting, the mismatch's per-sample power) of each gait."""
        ours = sim.outputs(reported, gaits)
        sep = np.min([sim.nats(ours, sim.outputs(alt, gaits)) for alt in alternatives], axis=0)
        return np.nan_to_num(sep, nan=-np.inf), sim.power(ours, sim.outputs([], gaits))

    pool = [baseline] + [_admissible(x_run + rng.normal(0.0, 0.6, x_run.size) * span, nominal, order, limits)
                         for _ in range(config.candidates)]
    s, power = measured(pool)
    first = np.zeros((len(nominal.joints), 2 * order + 1))
    first[:, [1, order + 1]] = 1.0
    first = first.ravel()
    for step in (0.3, 0.15, 0.08):
        if np.nanmax(power) >= config.visible_power:
            break
        # a weak mismatch: climb towards the drives that show it best too
        # (half of the steps in the fundamental alone: a harmonic spends joint speed for little motion)
        xv = pool[int(np.nanargmax(power))].to_vector(order)
        pool_v = [_admissible(xv + rng.normal(0.0, step, xv.size) * span * (first if i % 2 else 1.0),
                              nominal, order, limits) for i in range(config.candidates)]
        sv, power_v = measured(pool_v)
        pool, s, power = pool + pool_v, np.concatenate([s, sv]), np.concatenate([power, power_v])
    # a drive under which the mismatch itself would not be located settles nothing: admitted are
    # the drives that show it per sample at ``visible_power``, or as well as the best drive tried
    need = min(config.visible_power, float(np.nanmax(power)))
    s = np.where(power >= need, s, -np.inf)
    best = pool[int(np.argmax(s))]
    xb = best.to_vector(order)
    pool2 = [_admissible(xb + rng.normal(0.0, 0.2, xb.size) * span, nominal, order, limits)
             for _ in range(config.candidates)]
    s2, power2 = measured(pool2)
    allg, alls = pool + pool2, np.concatenate([s, np.where(power2 >= need, s2, -np.inf)])
    # the baseline first (when admitted): the proposal is never worse than the drive already run
    top = [baseline] + [allg[i] for i in np.argsort(-alls)[: config.refit] if i and np.isfinite(alls[i])]
    seps = [refitted(g) for g in top]
    nom_nats = seps[0]
    # the others in ``top`` are admitted by construction; the baseline only when it shows the mismatch
    k = int(np.argmax(seps if np.isfinite(alls[0]) else [-np.inf] + seps[1:]))
    nats = seps[k]
    if not nats > INSEPARABLE_NATS:
        return ProposedExperiment(labels[0], labels[1], None, nats, nom_nats, None, threshold, baseline=kind)
    gait = top[k]
    bad = constraint_violations(gait, limits)
    if bad:  # cannot happen (_admissible scales into the limits); never propose outside them
        raise SudsConfigError(f"proposed gait violates its limits: {bad}")
    ours, zero = sim.outputs(reported, [gait]), sim.outputs([], [gait])
    visible = float(sim.nats(ours, zero)[0])
    k_rep = _n_params(reported)
    extra = max(max(0, k_rep - _n_params(alt)) for alt in alternatives)
    cycles = max(config.min_cycles, _cycles(sim, nats, threshold, extra, config.z),
                 _cycles(sim, visible, threshold, k_rep, config.z) if visible > 0 else 0)
    shown = float(sim.power(ours, zero)[0])
    return ProposedExperiment(labels[0], labels[1], gait, nats, nom_nats, cycles, threshold, k == 0, shown, kind)


def _cycles(sim: _Simulator, nats: float, threshold: float, extra_params: int, z: float) -> int:
    """Cycles whose held-out half beats ``threshold`` by ``z`` spreads after the BIC penalty of ``extra_params``.

    The held-out half of N cycles gives E = ½·N·``nats`` of log-likelihood, spread about √(2E),
    less the penalty ½·k·log n of the k parameters the reported set has beyond the other one (n the
    median channel's held-out samples, which grows with N: three fixed-point steps).
    """
    n = 2.0 * threshold / nats
    for _ in range(3):
        need = threshold + 0.5 * extra_params * math.log(sim.samples(max(1, int(math.ceil(n)))))
        target = (z / math.sqrt(2.0) + math.sqrt(z**2 / 2.0 + need)) ** 2
        n = 2.0 * target / nats
    return int(math.ceil(n))


def _n_params(effects: Sequence[Effect]) -> int:
    """The free parameters of a set of effects."""
    return sum(len(EFFECTS[str(e["name"])].params) for e in effects)


def _parts(effects: Sequence[Effect]) -> tuple[tuple[str, str | None], ...]:
    """The (name, target) of each effect of a set, as :class:`~.naming.Candidate` takes them."""
    return tuple((str(e["name"]), e.get("joint") or e.get("link")) for e in effects)  # type: ignore[misc]


def recorded_drive(rec: Recording, base: ChainModel, order: int) -> Gait:
    """The drive ``rec`` ran on ``base``'s actuated joints, as a K = ``order`` gait at ``base``'s frequency."""
    template = nominal_gait(RFTChain(base))
    missing = [j for j in template.joints if j not in rec.joint_names]
    if missing:
        raise SudsDataError(f"recording: expected the actuated joints {list(template.joints)}, "
                            f"got {list(rec.joint_names)} (no {missing})")
    cols = [rec.joint_names.index(j) for j in template.joints]
    return fitted_gait(template, rec.t, np.asarray(rec.r)[:, cols], order)


def propose_for_report(
    rep: DiagnosisReport, base: ChainModel, dt: float, config: DiagnoseConfig = DiagnoseConfig(),
    experiment: ExperimentConfig = ExperimentConfig(), run: Gait | None = None,
) -> tuple[ProposedExperiment, ...]:
    """One proposal per alternative of the report's first effect (none without alternatives).

    With two or more alternatives that a drive separates, a proposal that separates the reported
    set from all of them at once (:func:`propose_all`, labelled ``all of: A; B; …``) comes first:
    the one run that settles the whole finding.  ``run``: the drive the recording ran
    (:func:`recorded_drive`), the baseline of every proposal; None: the nominal gait.
    """
    if not rep.effects or not rep.effects[0].alternatives:
        return ()
    w = max(1, int(round(config.window / dt)))
    # the new run must show the mismatch (evidence threshold) and leave the alternative outside the band
    threshold = max(config.evidence_threshold, config.ambiguity_band)
    out = []
    label = set_label([(e.name, e.target) for e in rep.effects])
    reported = reported_effects(rep.effects)
    others = []
    for alt in rep.effects[0].alternatives:
        _, other = effect_sets(rep.effects, alt)
        alt_label = set_label(_parts(other)) or NO_EFFECT
        out.append(propose(base, reported, other, rep.noise_floor, dt, w, threshold, experiment, (label, alt_label),
                           run))
        others.append(other)
    apart = [(other, p) for other, p in zip(others, out) if p.separable]
    if len(apart) >= 2:
        out.insert(0, propose_all(base, reported, [other for other, _ in apart], rep.noise_floor, dt, w,
                                  threshold, experiment,
                                  (label, "all of: " + "; ".join(p.alternative for _, p in apart)), run))
    return tuple(out)
