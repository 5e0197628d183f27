"""What a diagnosis is told and what it returns: :class:`DiagnoseConfig` and the frozen report."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsConfigError
from suds_ros.core.json_text import dumps

BODY = ("xi_x", "xi_y", "xi_theta")


def effect_label(name: str, target: str | None) -> str:
    """The label of one effect: ``name:target`` (``name`` alone for a robot-wide effect); the one place it is built."""
    return name if target is None else f"{name}:{target}"


def set_label(parts: Sequence[tuple[str, str | None]]) -> str:
    """The label of a set of effects: their labels joined by `` + ``."""
    return " + ".join(effect_label(n, t) for n, t in parts)


@dataclass(frozen=True)
class DiagnoseConfig:
    """Settings of :func:`diagnose`.

    Parameters
    ----------
    window : float
        Body-velocity estimation window, s (pose log over this span).
    eq_window : int
        Samples averaged per equation-error window.
    f_threshold : float
        A channel is located when its held-out residual power exceeds this multiple of the noise
        floor power.
    phase_bins : int
        Phase bins per cycle for the phase-interval test.
    phase_alpha : float
        Family-wise significance of the phase-bin test (Bonferroni over bins).
    step_candidates : int
        At each forward-selection step after the first, the number of leading candidates (screened
        by a short fit of every parameter) refitted fully with the current set.
    max_effects : int
        Most effects named at once.
    evidence_threshold : float
        Held-out evidence (log-likelihood gain after the BIC penalty, nats) an effect must add to
        the set already chosen to join it, and keep to stay in it.  Calibrated on 100 seeded
        60-cycle null recordings with every suspect on (``docs/results/evidence_threshold.md``: 0
        of 100 above 60 nats, one-sided 95 % bound 3 %; it was 29 before the model-parameter
        suspects, whose tail-link drag picks up ≈ 50 nats of equation-error bias on swimmer9);
        judged on its own, never relative to another effect's gain.
    model_suspects : bool
        Also suspect the robot model's own parameters (``link_length_error``, ``link_drag_error``,
        ``pose_frame_offset``; ``docs/effects.md``) alongside the catalogue effects (default: every
        parameter of the robot model is a suspect; False restricts the search to the catalogue).
    confound_margin : float
        Held-out log-likelihood margin (nats) within which candidates are called confounded;
        the margin grows as ``confound_rel`` × the winner's gain.
    confound_rel : float
        Relative part of the confounding margin.
    arbitrate_rel, arbitrate_margin : float
        First-step runners-up whose equation-error evidence is within max(``arbitrate_margin``
        nats, ``arbitrate_rel`` × the best single's) of the best start forward selections of their
        own; each set found is refined in the simulator too, and the one with the smallest
        training-half output error is reported.  The equation error carries biases of its own
        (finite differences, the windowed body velocity), so on purcell3 a stiffness-to-drag error
        and a drag-anisotropy error can swap places there while the simulator tells them apart at
        once.
    arbitrate_max : int
        Most alternative selections refined (0: no arbitration).
    swap_max : int
        Most sets refined in the simulator that swap a member of the chosen set for one it was
        confounded with in the equation error (0: none).
    weak_max : int
        When the reported explanation is one effect whose equation-error evidence is below
        ``evidence_threshold`` (named only because a channel is located), this many rival single
        effects are refined in the simulator too: the other effects on the same passive joint,
        then the best of the rest by equation-error evidence (0: none).  A rival within
        ``ambiguity_band`` of the reported effect's replay evidence is one of its alternatives.
    extend_max : int
        At the forward step that failed the threshold, the effects of its leading candidate sets
        (at most this many) are scored on top of the reported set in output error (0: none); the
        best is refined with it and added only when its replay evidence beats the set's by more
        than ``evidence_threshold`` on the training half *and* on the held-out half.  The equation
        error can hold back a real effect (a Coulomb friction beside a damping on the same joint,
        whose sign(ṙ) the angle noise blurs); the output error does not.
    ambiguity_band : float
        Every set refined in the simulator whose held-out output-error evidence (replay log
        likelihood gain over the nominal model after the BIC penalty, nats) is within this band of
        the reported set's is reported with it as an alternative explanation of the same finding.
        The nominal model is one too (:data:`NO_EFFECT`) when the reported set's own evidence is
        within the band; a refined set whose added effects all sit within ``member_z`` standard
        errors of their neutral values is that same explanation and is not listed again.
    calibrate : bool
        Calibrate every selection step's evidence on this recording (:mod:`.null`): a candidate's
        evidence is lowered by what it gains on a null recording simulated with the effects chosen
        so far (this recording's drive, grid, gaps and noise floors), its equation-error bias here.
    calibration_max : int
        Most candidates calibrated per step (best raw evidence first; calibration stops early once
        no raw score left can beat the best calibrated one).
    calibration_seed : int
        Seed of the null recordings' noise.
    unexplained_fraction : float
        Maximum fraction of the excess residual power (over the floor) that may remain after the
        fit for the mismatch to count as explained.
    segment_cycles : int
        Cycles per segment in the output-error refinement.
    refine_cycles : int
        Training cycles (spread over the training half) used by the output-error refinement.
    refine_nfev : int
        Maximum simulator evaluations per refined parameter (least-squares budget).
    member_z : float
        After refining a set of effects, a member whose parameters all lie within ``member_z``
        reported standard errors (sampling and misfit spread in quadrature) of their neutral values
        is dropped (the others are refined again).
    misfit_alpha : float
        Significance level of the test that a refined parameter's estimates from each channel and
        quarter of the gait cycle agree; where it rejects, their spread joins the parameter's
        standard error (:func:`~suds_ros.core.diagnosis.refine.misfit_spread`).
    substeps : int or None
        RK4 steps per sample interval; None picks them from the stiffest passive mode.
    replay_chunk : float
        The whole-recording replays run each half as independent pieces of this many cycles in
        one batch (0: each half in one piece, sequentially — slow).
    replay_warm : float
        Seconds of warm-up simulated before each piece (from the recorded state) and discarded;
        the passive joints forget their initial state well within it.
    jobs : int
        Worker processes (forked, sharing the recording; :mod:`suds_ros.core.parallel`) for the
        independent pieces of work: the naming stage's candidate fits, the refinements of
        alternative sets and the refinement's Jacobian columns.  The report does not depend on it.
    """

    window: float = 0.1
    eq_window: int = 5
    f_threshold: float = 2.0
    phase_bins: int = 20
    phase_alpha: float = 0.01
    step_candidates: int = 5
    max_effects: int = 3
    evidence_threshold: float = 60.0
    model_suspects: bool = True
    confound_margin: float = 3.0
    confound_rel: float = 0.01
    arbitrate_rel: float = 0.1
    arbitrate_margin: float = 20.0
    arbitrate_max: int = 2
    swap_max: int = 3
    weak_max: int = 6
    extend_max: int = 6
    ambiguity_band: float = 10.0
    calibrate: bool = True
    calibration_max: int = 8
    calibration_seed: int = 0
    unexplained_fraction: float = 0.25
    segment_cycles: int = 1
    refine_cycles: int = 30
    refine_nfev: int = 5
    member_z: float = 4.0
    misfit_alpha: float = 0.01
    substeps: int | None = None
    replay_chunk: float = 3.0
    replay_warm: float = 3.0
    jobs: int = 1

    def __post_init__(self) -> None:
        checks = [
            ("window", self.window > 0),
            ("eq_window", self.eq_window >= 1),
            ("f_threshold", self.f_threshold > 1),
            ("phase_bins", self.phase_bins >= 4),
            ("phase_alpha", 0 < self.phase_alpha < 1),
            ("step_candidates", self.step_candidates >= 1),
            ("max_effects", self.max_effects >= 1),
            ("evidence_threshold", self.evidence_threshold >= 0),
            ("confound_margin", self.confound_margin >= 0),
            ("confound_rel", self.confound_rel >= 0),
            ("arbitrate_rel", self.arbitrate_rel >= 0),
            ("arbitrate_margin", self.arbitrate_margin >= 0),
            ("arbitrate_max", self.arbitrate_max >= 0),
            ("swap_max", self.swap_max >= 0),
            ("weak_max", self.weak_max >= 0),
            ("jobs", self.jobs >= 1),
            ("extend_max", self.extend_max >= 0),
            ("ambiguity_band", self.ambiguity_band >= 0),
            ("calibration_max", self.calibration_max >= 1),
            ("unexplained_fraction", 0 < self.unexplained_fraction < 1),
            ("segment_cycles", self.segment_cycles >= 1),
            ("refine_nfev", self.refine_nfev >= 1),
            ("refine_cycles", self.refine_cycles >= 1),
            ("member_z", self.member_z >= 0),
            ("misfit_alpha", 0.0 <= self.misfit_alpha < 1.0),
            ("substeps", self.substeps is None or self.substeps >= 1),
            ("replay_chunk", self.replay_chunk >= 0),
            ("replay_warm", self.replay_warm >= 0),
        ]
        for name, ok in checks:
            if not ok:
                raise SudsConfigError(f"`{name}`: value {getattr(self, name)!r} is out of range")


@dataclass(frozen=True)
class Located:
    """A channel whose held-out residual exceeds the noise floor.

    ``statistic`` is F = mean(residual²)/floor²; ``phase_ranges`` are [a, b] in rad (0 … 2π).
    """

    channel: str
    phase_ranges: tuple[tuple[float, float], ...]
    statistic: float


#: the name of the alternative "no effect at all": the nominal model fits within the band
NO_EFFECT = "none"


@dataclass(frozen=True)
class Alternative:
    """Another explanation that fits the recording about as well as the reported effects.

    The alternative set, refined in the simulator like the reported one, differs from it by the
    effects listed: ``name``, ``target`` and ``parameters`` of its first differing effect,
    ``with_effects`` the other effects it adds, each as (name, target, parameters), and
    ``instead_of`` the labels of the reported effects it does without.  A reported effect that
    the alternative keeps at other values (a reparameterisation of the same physics) is in both:
    its alternative values in ``with_effects``, its label in ``instead_of``.  ``evidence_gap``: the
    reported set's held-out output-error evidence minus the alternative's, nats (within
    ± ``ambiguity_band``; negative: the alternative has a little more held-out evidence, the
    reported set more on the training half, which arbitrates).  ``name`` :data:`NO_EFFECT`
    (target None, no parameters, every reported effect in ``instead_of``): the nominal model
    itself, i.e. the recording does not yet show the finding beyond the band.
    """

    name: str
    target: str | None
    parameters: Mapping[str, float]
    evidence_gap: float
    with_effects: tuple[tuple[str, str | None, Mapping[str, float]], ...] = ()
    instead_of: tuple[str, ...] = ()

    @property
    def added(self) -> tuple[tuple[str, str | None, Mapping[str, float]], ...]:
        """(name, target, parameters) of every effect the alternative adds (none for the nominal model)."""
        first = () if self.name == NO_EFFECT else ((self.name, self.target, self.parameters),)
        return first + self.with_effects

    @property
    def label(self) -> str:
        """``name:target + …`` of the effects the alternative adds (``none`` for the nominal model)."""
        return set_label([(n, t) for n, t, _ in self.added]) or NO_EFFECT

    def as_dict(self) -> dict[str, object]:
        return {
            "name": self.name,
            "target": self.target,
            "parameters": {k: float(v) for k, v in self.parameters.items()},
            "evidence_gap": float(self.evidence_gap),
            "with": [{"name": n, "target": t, "parameters": {k: float(v) for k, v in p.items()}}
                     for n, t, p in self.with_effects],
            "instead_of": list(self.instead_of),
        }


@dataclass(frozen=True)
class FittedEffect:
    """A catalogue effect with fitted parameters, standard errors and its evidence.

    ``evidence`` is the held-out log-likelihood (nats, after the BIC penalty) lost when this effect
    is left out of the named set (equation error; None when not measured).  ``alternatives`` (on
    the effect reported first only): the explanations within ``ambiguity_band`` of the reported
    set's held-out evidence after replay — the finding is ambiguous between them.  ``at_bound``:
    the parameters whose fit stopped at an end of their admissible range (``"lower"`` or
    ``"upper"``): the recording asks for a value beyond it, so the value is a limit, not an
    estimate, and its stderr is NaN (``null`` in JSON).
    """

    name: str
    target: str | None
    parameters: Mapping[str, float]
    stderr: Mapping[str, float]
    evidence: float | None = None
    alternatives: tuple[Alternative, ...] = ()
    at_bound: Mapping[str, str] = field(default_factory=dict)

    def as_dict(self) -> dict[str, object]:
        return {
            "name": self.name,
            "target": self.target,
            "parameters": {k: float(v) for k, v in self.parameters.items()},
            "stderr": {k: float(v) for k, v in self.stderr.items()},
            "evidence": None if self.evidence is None else float(self.evidence),
            "alternatives": [a.as_dict() for a in self.alternatives],
            "at_bound": dict(self.at_bound),
        }


@dataclass(frozen=True)
class Discovered:
    """A candidate formula for a torque missing from a passive joint's balance (:mod:`.discovery`).

    ``terms``: library term → coefficient (N·m per unit of the term); ``stderr`` likewise;
    ``physics``: words for the recognisable terms; ``heldout_reduction``: fraction of the joint's
    held-out equation-error residual power the formula removes; ``resimulated_improvement``: the
    held-out improvement (fraction of the located mismatch removed, the measure of the catalogue
    fits) of the replay with every discovered formula added to the simulator (None: not
    re-simulated).
    """

    joint: str | None
    terms: Mapping[str, float]
    stderr: Mapping[str, float]
    physics: tuple[str, ...]
    heldout_reduction: float
    resimulated_improvement: float | None = None

    def as_dict(self) -> dict[str, object]:
        return {
            "joint": self.joint,
            "terms": {k: float(v) for k, v in self.terms.items()},
            "stderr": {k: float(v) for k, v in self.stderr.items()},
            "physics": list(self.physics),
            "heldout_reduction": float(self.heldout_reduction),
            "resimulated_improvement": (None if self.resimulated_improvement is None
                                        else float(self.resimulated_improvement)),
        }


@dataclass(frozen=True)
class CandidateScore:
    """Equation-error evidence for one candidate (single effect or pair)."""

    label: str
    effects: tuple[dict[str, object], ...]
    n_params: int
    gain_heldout: float
    penalty: float

    @property
    def score(self) -> float:
        return self.gain_heldout - self.penalty


@dataclass(frozen=True)
class Channels:
    """Per-channel held-out series for figures.

    Phase (rad, wrapped), time (s), recorded, predicted before and after.
    """

    t: FloatArray
    phase: FloatArray
    recorded: FloatArray
    before: FloatArray
    after: FloatArray


@dataclass(frozen=True)
class DiagnosisReport:
    """Result of :func:`diagnose`.

    ``to_json()`` gives the machine-readable schema; the other attributes feed the human report.
    """

    mismatch: bool
    located: tuple[Located, ...]
    effects: tuple[FittedEffect, ...]
    confounded_with: tuple[tuple[str, ...], ...]
    unexplained: bool
    heldout_rms_before: Mapping[str, float]
    heldout_rms_after: Mapping[str, float]
    improvement: float
    system: str = ""
    noise_floor: Mapping[str, float] = field(default_factory=dict)
    statistics: Mapping[str, float] = field(default_factory=dict)
    statistics_after: Mapping[str, float] = field(default_factory=dict)
    ranking: tuple[CandidateScore, ...] = ()
    conditions: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    coefficients: tuple[tuple[str, str, float, tuple[tuple[float, float], ...]], ...] = ()
    series: Mapping[str, Channels] = field(default_factory=dict, repr=False)
    train_cycles: int = 0
    heldout_cycles: int = 0
    timings: Mapping[str, float] = field(default_factory=dict)
    phase_source: str = "phaser"
    notes: tuple[str, ...] = ()
    discovered: tuple[Discovered, ...] = ()

    @property
    def plain_rms_ratio(self) -> float | None:
        """1 − Σ RMS after / Σ RMS before over the located channels (None without a located channel).

        Unlike :attr:`improvement` it keeps the noise, which no model removes, in both sums.
        """
        before = sum(self.heldout_rms_before[loc.channel] for loc in self.located)
        after = sum(self.heldout_rms_after[loc.channel] for loc in self.located)
        return 1.0 - after / before if before > 0 else None

    def to_dict(self) -> dict[str, object]:
        """The JSON schema of ``suds diagnose --json`` (exactly these keys).

        ``discovered`` and each effect's ``evidence`` were added by the stepwise selection, each
        effect's ``alternatives`` by the ambiguity report, ``notes`` (the text report's notes: the
        simulator's arbitration, ambiguity, a parameter whose estimates from parts of the data
        disagree, …) later; nothing was removed.
        """
        return {
            "mismatch": bool(self.mismatch),
            "located": [
                {
                    "channel": loc.channel,
                    "phase_ranges": [[float(a), float(b)] for a, b in loc.phase_ranges],
                    "statistic": float(loc.statistic),
                }
                for loc in self.located
            ],
            "effects": [e.as_dict() for e in self.effects],
            "confounded_with": [list(g) for g in self.confounded_with],
            "unexplained": bool(self.unexplained),
            "fit": {
                "heldout_rms_before": {k: float(v) for k, v in self.heldout_rms_before.items()},
                "heldout_rms_after": {k: float(v) for k, v in self.heldout_rms_after.items()},
                "improvement": float(self.improvement),
            },
            "discovered": [d.as_dict() for d in self.discovered],
            "notes": [str(n) for n in self.notes],
        }

    def to_json(self, indent: int | None = 2) -> str:
        """Strict JSON text of :meth:`to_dict` (a non-finite number is written as null)."""
        return dumps(self.to_dict(), indent=indent)
