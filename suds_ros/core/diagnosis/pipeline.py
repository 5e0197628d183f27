"""Simulator-versus-recording diagnosis: locate, name, fit and show a physical mismatch.

Method (as implemented)
-----------------------
Data.  Cycles are counted with the recording's ``gait_hz`` (default 1 Hz) from the first stamp;
the first half of the whole cycles is the *training* half, the rest the *held-out* half.  Every
number in the report is computed on the held-out half.

1. Replay (output error).  The simulator is driven with the recorded actuated angles r_a
   (piecewise linear between samples, as the servo stream) from the recorded passive angles and
   pose at the start of each half (:func:`~suds_ros.core.diagnosis.replay.replay`; batched RK4
   over independent segments, the pose by the same integrator as the simulator,
   :func:`~suds_ros.core.physics.integrate.integrate_batch`).  Channels: each
   passive angle r_j (rad) and the body velocity ξx, ξy (m/s), ξθ (rad/s), the latter estimated
   from the pose by the exact SE(2) logarithm of g_k⁻¹g_{k+w} over ``window`` seconds, with the
   *same* estimator applied to the simulated pose.  With ``reference=`` a simulated recording of
   the same actuated trajectory replaces the replay.  A fully actuated chain (every joint driven,
   the paper's kinematic connection) has the body-velocity channels only; its suspects are the
   global effects and the model's parameters (joint effects and ``stiffness_to_drag_error`` act
   through passive joints), and there is no torque formula to discover (step 5).

2. Locate.  The noise floor is estimated from the data, not assumed: the fourth difference of the
   replay residual removes everything smooth (gait-correlated errors) and keeps the white part
   (measurement noise plus the noise the recorded r_a injects into the replay); a median-absolute
   estimate of its spread over √70 gives σ per channel (pose σ for ξ, scaled by √2/(w·dt)).
   Per channel the statistic is F = mean(residual²) / floor² on the held-out half (≈ 1 when the
   simulator matches); the channel is located if F > ``f_threshold``.  Phase intervals: the held-out
   residual is averaged in ``phase_bins`` bins per cycle, cycles serve as replicates, and bins whose
   mean is significant (Bonferroni t-test across cycles) are merged into ranges [a, b] of the gait
   phase in rad: the phaser's phase (:class:`~suds_ros.core.phase.phaser.Phaser`) of the recorded shape,
   shared by the replay (same r_a), zero at the upward crossing of the shape's first principal
   component; the clock phase 2π·gait_hz·(t − t0) only if the phaser fails (noted in the report).
   Conditions (sign of ṙ_p, |r_p − rest|, heading, position, lag of the cross-correlation with the
   recorded signals) and the paper's structure (SUDS coefficients C, C_r, B, B_r identified from
   the recording and from the replay on the same gait, compared phase by phase against a
   split-half noise scale) are attached to the report for the human summary.

3. Name (equation error).  On interval data (sample k → k+1, midpoint shape, ṙ = Δr/Δt, which is
   exact for the piecewise-linear servo stream) the still-fluid RFT metric gives, without
   integrating anything, the torque each passive joint's unmodelled effects must supply,
   τ_res = (D q̇)_p − τ_spring, and the body velocity the shape motion implies.  Both are averaged
   over windows of ``eq_window`` samples (the SE(2) displacements composed, so the recorded and
   predicted body velocities go through one estimator).  Every catalogue candidate — each joint
   effect on each passive joint, and the global ones — is a parametric modification of these
   residuals evaluated with the physics (Coulomb's set-valued stick/slip as a dead zone; the drag
   ratio by re-evaluating the metric; the time offset by re-sampling the pose stream; the flow by
   R(−yaw)U).  Candidates are the catalogue effects and, by default, the robot model's own
   parameters (``model_suspects``).  Sets of up to ``max_effects`` of them are chosen by stepwise
   selection (:mod:`.selection`): each is fitted on the training half (weighted least squares,
   weights re-estimated once) and scored on the held-out half by the Gaussian profile
   log-likelihood gain Σ_c (n_eff/2)·log(RSS0_c/RSS_c) over channels, minus a BIC penalty
   (p/2)·log n_eff; an effect joins (and stays) only if it adds more than ``evidence_threshold``
   nats on its own.  Candidates within ``confound_margin`` of a step's winner are reported as
   confounded.  Runners-up of the first step within ``arbitrate_rel`` of the winner (other than
   confounded ones) start selections of their own (:func:`~.selection.name_mismatch`).

4. Fit and show (output error).  The chosen effect(s) are refined inside the simulator:
   least squares of the noise-floor-weighted replay residuals over short training segments
   (scipy ``least_squares``, forward-difference Jacobian with absolute steps, :mod:`.lsq`), over
   one-cycle segments spread over the training half.  When the naming left alternative sets,
   each is refined too and the set whose replay has the most evidence on the training half
   (:meth:`~suds_ros.core.diagnosis.locate.ChannelTable.evidence`) is reported (the equation
   error has biases of its own; a note says so).  Sets that
   swap a member of the selection for one it was confounded with in the equation error are refined
   too (``swap_max``), and so is the selection without the member it added last (the
   equation error can add one the motion does not show).  Then the forward selection's members
   that the reported set lacks and the effects of the leading sets of the forward step that
   failed the threshold (``extend_max``) are scored on top of the reported set in output error
   (a score test, :func:`_extension`); the best is refined with it and added only when its replay
   evidence is more than ``evidence_threshold`` above the set's on both halves (the equation
   error can hold a real effect back; a note says so).  Ambiguity: every refined set whose
   held-out output-error evidence
   (:meth:`~suds_ros.core.diagnosis.locate.ChannelTable.evidence`) lies within ``ambiguity_band``
   nats of the reported set's is reported with it, as ``alternatives`` of its first effect (the
   finding is one, its explanation is not); so is the nominal model when the reported set's own
   evidence is within the band (a mismatch located, but not yet shown beyond the band).  A
   confounded member whose swap the replay does tell apart is no longer called confounded.
   Standard errors come from the cluster-robust sandwich (clusters = segments) with CR1
   and t(B − p) small-sample factors, floored by the model-based error (calibrated against
   seed-to-seed spread in the tests).  The whole-recording replays run each half as 3-cycle pieces
   in one batch, each after a 3 s warm-up from the recorded state (equal to the sequential replay
   to < 1e-4 rad).  The fitted model is replayed on the held-out
   half; held-out RMS per channel before/after, and improvement = 1 − Σ e_after / Σ e_before over
   the located channels with e = √max(F − 1, 0) the RMS of the residual in excess of the noise
   floor, in floor units (:func:`~suds_ros.core.diagnosis.locate.excess_improvement`): the
   fraction of the mismatch removed.  (The plain RMS ratio would be capped by the noise, which no
   model removes, on weakly affected channels.)  A mismatch whose best explanation leaves a
   significant excess (more than ``unexplained_fraction`` of the excess residual power, in total
   or on any located channel) is reported as unexplained, with its location kept; if that fit also
   improves the held-out residual by less than half, no effect is reported (the attempt is in
   ``notes``).

5. Discover.  A sparse regression of the torque residual left by the reported effects (the
   nominal model's if none) over a library of physical terms proposes a formula per passive joint
   (:mod:`.discovery`); the formulas are added to the simulator (:mod:`.resimulate`) and the
   held-out improvement of that replay is reported with them, measured as for the catalogue fits.
   When the mismatch stays unexplained ``unexplained`` is kept.  When named effects explain it,
   a formula is still reported if its terms earn their held-out evidence on top of them: a
   catalogue effect can stand in for physics it is not (viscous damping removes most of a
   quadratic drag's mismatch), and the formula (e.g. −c·|ṙ|ṙ + d·ṙ on top of a damping d) says so.

Modules: :mod:`.report` (config and report), :mod:`.data` (prepare a recording), :mod:`.replay`,
:mod:`.floor`, :mod:`.locate`, :mod:`.naming`, :mod:`.selection`, :mod:`.refine`,
:mod:`.discovery`, :mod:`.resimulate`; this module runs the stages.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.diagnosis.data import Data, prepare, xi_noise_gain
from suds_ros.core.diagnosis.floor import Floors, noise_floor
from suds_ros.core.diagnosis.locate import (
    ChannelTable,
    channel_conditions,
    coefficient_comparison,
    excess_improvement,
    locate_channels,
)
from suds_ros.core.diagnosis.discovery import discover, formula
from suds_ros.core.diagnosis.naming import Candidate
from suds_ros.core.diagnosis.refine import Refined, extension_gains, fitted_effects, is_neutral, refine_choice
from suds_ros.core.diagnosis.null import null_recording
from suds_ros.core.diagnosis.replay import RecordingReplay, piece_starts, replay, replay_recording
from suds_ros.core.diagnosis.report import (
    NO_EFFECT, Alternative, Channels, DiagnoseConfig, DiagnosisReport, Discovered, FittedEffect, Located,
    effect_label,
)
from suds_ros.core.diagnosis.selection import Naming, _compatible, name_mismatch
from suds_ros.core.errors import SudsConfigError, SudsDataError, SudsSimulationError
from suds_ros.core.parallel import fork_map, workers
from suds_ros.core.physics.effects import EFFECTS, apply_effects, neutral_params
from suds_ros.core.physics.rft import ChainModel, RFTChain
from suds_ros.core.physics.sim import auto_substeps
from suds_ros.core.recording import Recording


@dataclass(frozen=True)
class _Nominal:
    """Stage 1: the recording, the nominal replay and its residuals, floors and F statistics."""

    data: Data
    model: ChainModel
    config: DiagnoseConfig
    w: int  # body-velocity window, samples
    substeps: int
    chunk: int  # replay piece, samples
    warm: int  # replay warm-up, samples
    table: ChannelTable
    cycle: FloatArray  # gait cycle of each sample (replicates of the phase test)
    replay: RecordingReplay
    floors: Floors
    floor: dict[str, float]
    E0: FloatArray
    rms0: dict[str, float]
    F0: dict[str, float]
    xi_gain: float  # the windowed body velocity's noise gain (:func:`~.data.xi_noise_gain`), once per recording
    referenced: bool = False  # ``replay`` is a reference recording's, not the nominal model's replay


@dataclass
class _Clock:
    """Cumulative stage timings, s."""

    tick: float = field(default_factory=time.perf_counter)
    timings: dict[str, float] = field(default_factory=dict)

    def mark(self, stage: str) -> None:
        self.timings[stage] = time.perf_counter() - self.tick


def diagnose(
    rec: Recording,
    model: ChainModel,
    config: DiagnoseConfig = DiagnoseConfig(),
    *,
    reference: Recording | None = None,
    progress: Callable[[str], None] | None = None,
) -> DiagnosisReport:
    """Diagnose where the simulator ``model`` disagrees with the recording ``rec``.

    Parameters
    ----------
    rec : Recording
        The (real) recording.
    model : ChainModel
        The nominal physics (e.g. :func:`~suds_ros.core.physics.systems.swimmer9_model`).
    config : DiagnoseConfig
        Settings.
    reference : Recording, optional
        A simulated recording driven by the same actuated trajectory, used as the reference
        for locating instead of replaying ``model``.
    progress : callable, optional
        Receives short stage messages.

    Returns
    -------
    DiagnosisReport
    """
    with workers(config.jobs):
        return _diagnose(rec, model, config, reference, progress)


def _diagnose(
    rec: Recording, model: ChainModel, config: DiagnoseConfig, reference: Recording | None,
    progress: Callable[[str], None] | None,
) -> DiagnosisReport:
    """:func:`diagnose` within its worker budget."""
    say = progress or (lambda s: None)
    clock = _Clock()
    data = prepare(rec, model)
    say("replaying the nominal simulator")
    nom = replay_nominal(data, model, config, reference)
    clock.mark("replay")
    say("locating")
    located = locate_channels(nom.F0, nom.E0, nom.table, nom.cycle, config)
    coeffs: tuple[tuple[str, str, float, tuple[tuple[float, float], ...]], ...] = ()
    if located and reference is None:
        try:
            coeffs = coefficient_comparison(nom.data, nom.replay.rp, nom.replay.pose, config.eq_window)
        except (SudsDataError, np.linalg.LinAlgError, ValueError):
            coeffs = ()
    clock.mark("locate")
    if not located:
        return _report(nom, nom.replay, clock.timings, coefficients=coeffs)
    say("ranking catalogue candidates (equation error)")
    naming = name_mismatch(nom.data, model, config, nom.floors[0], null=_null_maker(nom))
    clock.mark("name")
    say(f"fitting {naming.chosen.cand.label} inside the simulator")
    fit = _refine(nom, naming, located, clock)
    return _show(nom, naming, fit, coeffs, clock)


def rank_effects(
    rec: Recording, model: ChainModel, config: DiagnoseConfig = DiagnoseConfig()
) -> tuple[Naming, tuple[Located, ...]]:
    """The locate and naming stages alone (no refinement in the simulator), for calibrations.

    Returns the stepwise selection (:func:`~suds_ros.core.diagnosis.selection.name_mismatch`, run
    whether or not a channel is located) and the located channels of the nominal replay.
    """
    data = prepare(rec, model)
    nom = replay_nominal(data, model, config, None)
    located = locate_channels(nom.F0, nom.E0, nom.table, nom.cycle, config)
    return name_mismatch(nom.data, model, config, nom.floors[0], null=_null_maker(nom)), tuple(located)


def _null_maker(nom: _Nominal) -> Callable[[Candidate, FloatArray], Data] | None:
    """Null recordings of sets of effects for the selection's calibration (None: not calibrated).

    The noise is seeded by ``calibration_seed`` and the set, so a diagnosis is reproducible.
    """
    config, data = nom.config, nom.data
    if not config.calibrate:
        return None
    starts = piece_starts(data, nom.w, nom.chunk, nom.warm)
    gain = nom.xi_gain

    def make(cand: Candidate, x: FloatArray) -> Data:
        fitted, delay = apply_effects(nom.model, cand.effects(x))
        rep = (nom.replay if not cand.parts and not nom.referenced
               else replay_recording(data, fitted, delay, nom.w, nom.substeps, None, nom.chunk, nom.warm))
        # the floors with this set's replay (a mismatch left in the nominal residual inflates them)
        sig_rp, s_xy, s_th = noise_floor(*rep.floor_arrays, nom.w, data.dt, gain)
        floors = (np.fmin(sig_rp, nom.floors[0]), min(s_xy, nom.floors[1]), min(s_th, nom.floors[2]))
        seed = [config.calibration_seed] + [ord(ch) for ch in cand.label]
        return null_recording(data, rep, starts, floors, nom.w, np.random.default_rng(seed))

    return make


def discover_formulas(
    rec: Recording, model: ChainModel, effects: tuple[FittedEffect, ...] = (),
    config: DiagnoseConfig = DiagnoseConfig(),
) -> tuple[Discovered, ...]:
    """Discovery (:mod:`.discovery`) on the residual left by ``effects``, re-simulated.

    The stage :func:`diagnose` runs when the mismatch stays unexplained, callable on its own (e.g.
    to ask what formula a residual needs beyond a catalogue fit the report accepted).  Each formula
    carries the held-out improvement of the replay with every formula found added to the simulator
    (over the channels located against the nominal replay; 0 when none is located).
    """
    data = prepare(rec, model)
    nom = replay_nominal(data, model, config, None)
    located = locate_channels(nom.F0, nom.E0, nom.table, nom.cycle, config)
    notes: list[str] = []
    return _discover(nom, list(effects), nom.F0, nom.floor, [loc.channel for loc in located], notes)


def replay_nominal(data: Data, model: ChainModel, config: DiagnoseConfig, reference: Recording | None) -> _Nominal:
    """Stage 1: replay the nominal model (or take ``reference``), noise floors, residuals, F.

    The returned ``data`` has its shape gaps widened by the replay's memory and the passive angles' residual
    noise power set (:func:`_settle_gaps`).
    """
    w = max(1, int(round(config.window / data.dt)))
    substeps = config.substeps or min(auto_substeps(RFTChain(model), data.dt, accuracy=0.4), 8)
    chunk = int(round(config.replay_chunk * data.spc))
    warm = int(round(config.replay_warm / data.dt))
    rep = replay_recording(data, model, 0.0, w, substeps, reference, chunk, warm)
    xi_gain = xi_noise_gain(data, w)
    floors = noise_floor(*rep.floor_arrays, w, data.dt, xi_gain)
    data = _settle_gaps(data, model, substeps, floors[0])
    table = ChannelTable.of(data, w)
    floor = table.floor(floors)
    E0 = table.residuals(rep.rp, rep.xi)
    return _Nominal(
        data=data, model=model, config=config, w=w, substeps=substeps, chunk=chunk, warm=warm,
        table=table, cycle=np.floor(data.phase[:data.n_used] / (2 * np.pi)), replay=rep,
        floors=floors, floor=floor, E0=E0, rms0=table.rms(E0), F0=table.fstats(E0, floor), xi_gain=xi_gain,
        referenced=reference is not None,
    )


def _settle_gaps(data: Data, model: ChainModel, substeps: int, sig_rp: FloatArray) -> Data:
    """``data`` with each shape gap widened while the replay forgets its restart, and the noise left.

    Across a shape gap the drive is not known, so the replay restarts its passive joints from the
    recorded angles at the first sample after it (:attr:`Data.anchors`).  Those carry the
    measurement noise: the replay then starts off by about the noise floor ``sig_rp`` on each
    passive joint, and carries that error on for the joints' own relaxation time.  (Replaying
    across the gap instead, on actuated angles interpolated over the lost kinks, carries an error
    that grows with the gap: measured, a Coulomb friction was named as viscous damping with 30 %
    of the shape samples lost in 0.3 s bursts, and 10 % single losses left a friction 4σ low and
    masked every sample of a swimmer9 recording.)  How long the restart matters is measured on the
    nominal model: a few training segments are replayed from their recorded start and again with
    one passive joint's start moved by its floor, for each passive joint.  The summed energy of the
    responses gives z_k², in units of the floors, k samples after the restart (over one gait cycle).

    Each gap is followed by S masked samples; the u = spacing − S left before the next gap (on
    average) carry the remainder Σ_{k≥S} z_k² as extra noise, so the passive angles' replay
    residual has the noise power (1 + Σ_{k≥S} z_k²/u)·floor² there (:attr:`Data.rp_noise_power`,
    which the F statistics and the refinement's weights use).  S (1 to one gait cycle) maximises
    the information left, u²/(u + Σ_{k≥S} z_k²): a joint that forgets its start quickly is masked
    a few samples, one that forgets slowly between frequent gaps is kept with its noise raised
    rather than masked whole.
    """
    if data.shape_gap is None or not data.shape_gap.any() or not data.pas.size:
        return data
    sig = np.asarray(sig_rp, dtype=float)
    if not np.all(np.isfinite(sig)) or not np.all(sig > 0):
        return data
    length = min(data.spc, data.n_train // 2)
    if length < 8:
        return data
    starts = np.linspace(0, data.n_train - length, 4).astype(np.intp)
    free = dataclasses.replace(data, anchors=None)  # the response runs on past later restarts
    base = replay(model, 0.0, free, starts, length, 1, substeps)
    z2 = np.zeros(length)
    for j, col in enumerate(data.pas):
        r = data.r.copy()
        r[starts, col] += sig[j]
        off = replay(model, 0.0, dataclasses.replace(free, r=r), starts, length, 1, substeps)
        z2 += np.mean(((off.rp - base.rp) / sig) ** 2, axis=(0, 2))
    gap = data.shape_gap[: data.n_used]
    events = max(int(np.sum(gap[1:] & ~gap[:-1]) + gap[0]), 1)
    spacing = data.n_used / events
    tail = np.concatenate([np.cumsum(z2[::-1])[::-1], [0.0]])  # tail[S] = Σ_{k ≥ S} z_k²
    S = np.arange(1, tail.size)
    u = np.maximum(spacing - S, 1e-9)
    settle = int(S[np.argmax(u**2 / (u + tail[S]))])
    power = 1.0 + float(tail[settle]) / max(spacing - settle, 1.0)
    gap = data.shape_gap.copy()
    ends = np.flatnonzero(data.shape_gap[:-1] & ~data.shape_gap[1:])  # last sample of each gap run
    for k in range(1, settle):
        gap[np.minimum(ends + k, gap.size - 1)] = True
    return dataclasses.replace(data, shape_gap=gap, rp_noise_power=power)


@dataclass(frozen=True)
class _Fit:
    """Stage 4: the refined effects, the fitted replay, and the floor, F and location they revise."""

    effects: list[FittedEffect]
    replay: RecordingReplay
    E1: FloatArray
    floor: dict[str, float]
    F0: dict[str, float]
    located: list[Located]
    conditions: dict[str, tuple[str, ...]]
    confounded: tuple[tuple[str, ...], ...]
    unexplained: bool  # no candidate has positive held-out evidence (nothing refined)
    notes: tuple[str, ...] = ()  # e.g. the simulator's arbitration between near-tied sets


def _refine(nom: _Nominal, naming: Naming, located: list[Located], clock: _Clock) -> _Fit:
    """Stage 4: refine the chosen effect in the simulator, replay it, re-locate with the better floor."""
    data, model, config, table = nom.data, nom.model, nom.config, nom.table
    conditions = channel_conditions([loc.channel for loc in located], nom.E0, table, model)
    if naming.chosen.score.score <= 0:
        return _Fit([], nom.replay, nom.E0, nom.floor, nom.F0, located, conditions, naming.confounded, True)
    # the selection, those started from the first step's runners-up, and swaps of confounded
    # members: each is refined in the simulator, which arbitrates
    tried = fork_map(lambda opt: _try(nom, opt), _options(naming, config))  # each its own refinement
    failed = [t for t in tried if t.failed]
    if len(failed) == len(tried):
        raise SudsSimulationError(failed[0].failed)
    # the output error arbitrates: replay evidence on the training half
    best = max(range(len(tried)), key=lambda i: tried[i].train_evidence)
    win = tried[best]
    notes = []
    if best:
        diff = naming.chosen.score.score - win.option.eq_score
        eq = ("" if not np.isfinite(diff)
              else f"; equation-error evidence {abs(diff):.0f} nats {'higher' if diff > 0 else 'lower'}")
        own = ("could not be replayed" if tried[0].failed
               else f"{tried[0].train_evidence:.1f}{eq}")  # a set left out has no evidence (−inf) to print
        notes.append(f"the simulator preferred {win.option.cand.label} (replay evidence on the training half "
                     f"{win.train_evidence:.1f} nats) to the forward selection's {naming.chosen.cand.label} "
                     f"({own})")
    notes += [f"{t.option.cand.label} left out: {t.failed}" for t in failed]
    extended, note = _extension(nom, naming, win)
    if extended is not None:
        win = extended
        tried.append(extended)
    if note:
        notes.append(note)
    alternatives = _ambiguous(win, tried, config, model)
    if alternatives:
        notes.append(f"ambiguous: {len(alternatives)} other explanation(s) within {config.ambiguity_band:g} nats "
                     f"of held-out evidence after replay (see the first effect's alternatives)")
    cand, x, dropped, rep1, E1 = win.cand, win.x, win.refined.dropped, win.replay, win.E1
    notes.extend(_misfit_notes(win.refined))
    ranked, member_ev, groups = win.option, win.option.member_ev, win.option.groups
    clock.mark("refine")
    # floor with the better model (effects can leak into the fourth differences)
    better = table.floor(noise_floor(*rep1.floor_arrays, nom.w, data.dt, nom.xi_gain))
    floor = {c: float(min(nom.floor[c], v)) for c, v in better.items()}
    F0 = table.fstats(nom.E0, floor)
    located = locate_channels(F0, nom.E0, table, nom.cycle, config)
    new = [loc.channel for loc in located if loc.channel not in conditions]
    conditions.update(channel_conditions(new, nom.E0, table, model))
    evidence = {effect_label(*p): e for p, e in zip(ranked.cand.parts, member_ev)}
    kept = {effect_label(*p) for p in cand.parts}
    told_apart = _told_apart(win, tried, config.ambiguity_band)
    confounded = tuple(kept_g for g in groups if g[0] not in dropped and g[0] in kept
                       for kept_g in [tuple(lab for lab in g if lab == g[0] or lab not in told_apart)]
                       if len(kept_g) > 1)
    effects = fitted_effects(cand, x, win.refined.stderr, evidence)
    notes += [f"{effect_label(e.name, e.target)} {k}: the fit stopped at the {end} end of its admissible range "
              f"({e.parameters[k]:.4g}): the recording asks for a {'larger' if end == 'upper' else 'smaller'} "
              "value, so read it as a limit; it has no stderr"
              for e in effects for k, end in e.at_bound.items()]
    if effects and alternatives:
        effects[0] = dataclasses.replace(effects[0], alternatives=alternatives)
    return _Fit(effects, rep1, E1, floor, F0,
                located, conditions, confounded, False, tuple(notes))


def _told_apart(win: _Tried, tried: list[_Tried], band: float) -> set[str]:
    """Effects the replay tells apart from a member of ``win`` (the labels).

    Each is in a refined set in place of exactly one of ``win``'s members, and that set's held-out
    evidence is more than ``band`` below ``win``'s.  A set that also lacks another member (the
    selection without its last) falls short for that member, and tells nothing apart.
    """
    kept = {effect_label(*p) for p in win.cand.parts}
    out: set[str] = set()
    for t in tried:
        if t.failed:  # a set that could not be replayed tells nothing apart
            continue
        theirs = {effect_label(*q) for q in t.cand.parts}
        if (t is not win and win.evidence - t.evidence > band
                and len(theirs - kept) == 1 and len(kept - theirs) == 1):
            out |= theirs - kept
    return out


def _misfit_notes(refined: Refined) -> list[str]:
    """Notes for the refined parameters whose estimates from the channels and gait phases disagree."""
    out = []
    for (nme, tgt), sl in zip(refined.cand.parts, refined.cand.slices()):
        for pn, spread, p, se in zip(EFFECTS[nme].param_names, refined.spread[sl], refined.misfit_p[sl],
                                     refined.se[sl]):
            if spread > 0:
                out.append(
                    f"{effect_label(nme, tgt)} {pn}: the estimates from single channels and quarters of the gait "
                    f"cycle disagree beyond their noise (p = {p:.1g}), so the model still lacks something; its "
                    f"stderr includes their spread {spread:.3g} (sampling alone {se:.3g})")
    return out


@dataclass(frozen=True)
class _Option:
    """A set of effects to refine in the simulator: start values, members' evidence, its origin."""

    cand: Candidate
    x: FloatArray
    member_ev: tuple[float, ...]
    groups: tuple[tuple[str, ...], ...]
    eq_score: float  # equation-error evidence of the set (nats; NaN if never scored as a whole)


@dataclass(frozen=True)
class _Tried:
    """An option refined and replayed: the refined set, its residuals and its two figures of merit."""

    option: _Option
    refined: Refined
    replay: RecordingReplay
    E1: FloatArray
    train_evidence: float  # output-error evidence on the training half, nats: the arbitration
    evidence: float  # output-error evidence on the held-out half, nats: the ambiguity band
    failed: str = ""  # the simulator's message when the option's motion diverged (evidence −∞)

    @property
    def cand(self) -> Candidate:
        return self.refined.cand

    @property
    def x(self) -> FloatArray:
        return self.refined.x

    @property
    def se(self) -> FloatArray:
        """Sampling standard errors: what the alternatives' neutrality test uses.

        Smaller than the reported errors where a misfit spreads the estimates, so an alternative is
        set aside as "the same explanation" only when even sampling cannot tell it from neutral:
        listing one too many errs on the side of saying both.  Members are dropped from a set on
        the reported errors (:func:`~.refine.refine_choice`).
        """
        return self.refined.se


def _options(naming: Naming, config: DiagnoseConfig) -> list[_Option]:
    """The selection, its runners-up's selections, the selection without its last member, and swaps.

    The selections are those started from the first step's runners-up; the shorter set is
    :func:`_prefix`'s.  A swap replaces one member of the chosen set by a candidate it was
    confounded with in the equation error (within the confounding margin at its step), started
    from the chosen set's parameters and the swapped-in candidate's own single fit; at most
    ``config.swap_max``.
    """
    chosen = naming.chosen
    out = [_Option(chosen.cand, chosen.x, naming.evidence, naming.confounded, chosen.score.score)]
    out += [_Option(a.cur.cand, a.cur.x, a.evidence, a.groups, a.cur.score.score) for a in naming.alternatives]
    seen = {frozenset(o.cand.parts) for o in out}
    slices = {effect_label(*part): (part, chosen.x[sl]) for part, sl in zip(chosen.cand.parts, chosen.cand.slices())}
    swaps: list[_Option] = []
    for group in naming.confounded:
        if group[0] not in slices:
            continue
        for label in group[1:]:
            single = naming.fits.get(label)
            if single is None or len(single.cand.parts) != 1 or len(swaps) >= config.swap_max:
                continue
            parts, xs = [], []
            for lab, (part, xp) in slices.items():
                parts.append(single.cand.parts[0] if lab == group[0] else part)
                xs.append(single.x if lab == group[0] else xp)
            if len(set(parts)) < len(parts) or frozenset(parts) in seen:
                continue
            cand = Candidate(tuple(parts))
            seen.add(frozenset(parts))
            whole = naming.fits.get(cand.label)
            # the confounded groups as seen from the swapped set: the swapped-in member leads its group
            mine = {effect_label(*q) for q in parts}
            led = [(label, g) if g is group else (g[0], g[1:]) for g in naming.confounded]
            groups = tuple(g for lead, rest in led if lead in mine
                           for g in [(lead,) + tuple(lab for lab in rest if lab not in mine)] if len(g) > 1)
            swaps.append(_Option(cand, np.concatenate(xs), (), groups,
                                 whole.score.score if whole is not None else float("nan")))
    return out + _prefix(naming, seen) + swaps + _weak_rivals(naming, config, seen)


def _prefix(naming: Naming, seen: set[frozenset]) -> list[_Option]:
    """The selection without the member it added last, refined on its own (none for a single effect).

    The equation error adds members one at a time and can add one that the recording's motion
    does not show (a drag anisotropy beside a link drag and a pose offset on a four-link body:
    656 nats in the equation error, 1.5 nats in the replay); refined on its own, the set without
    it lets the output error judge that last step as it judges the rest.  When it is preferred,
    the member it lacks is among the effects scored on top of it (:func:`_extension`), so a member
    the replay does show is put back.
    """
    chosen = naming.chosen
    parts = chosen.cand.parts
    if len(parts) < 2 or frozenset(parts[:-1]) in seen:
        return []
    cand = Candidate(parts[:-1])
    seen.add(frozenset(cand.parts))
    x = chosen.x[:chosen.cand.slices()[-1].start]
    mine = {effect_label(*p) for p in cand.parts}
    groups = tuple(g for g in naming.confounded if g[0] in mine)
    whole = naming.fits.get(cand.label)
    return [_Option(cand, x, (), groups, whole.score.score if whole is not None else float("nan"))]


def _weak_rivals(naming: Naming, config: DiagnoseConfig, seen: set[frozenset]) -> list[_Option]:
    """Single effects to refine beside a weakly named one (``config.weak_max``; none otherwise).

    A lone effect whose equation-error evidence is below the threshold is named only because the
    replay located a mismatch; the equation error's ranking is then too weak to exclude the
    others (its noise blurs sign(ṙ), so a weak friction can score below a damping).  The
    simulator judges: the other effects on the same target first, then the best of the rest.
    """
    chosen = naming.chosen
    if (not config.weak_max or len(chosen.cand.parts) != 1
            or chosen.score.score >= config.evidence_threshold):
        return []
    target = chosen.cand.parts[0][1]
    singles = sorted((r for r in naming.fits.values() if len(r.cand.parts) == 1
                      and frozenset(r.cand.parts) not in seen), key=lambda r: -r.score.score)
    same = [r for r in singles if target is not None and r.cand.parts[0][1] == target]
    rest = [r for r in singles if r not in same and r.score.score > 0]
    return [_Option(r.cand, r.x, (), (), r.score.score) for r in (same + rest)[:config.weak_max]]


def _try(nom: _Nominal, opt: _Option) -> _Tried:
    """Refine an option in the simulator and replay the whole recording with it.

    An option whose simulated motion diverges (its refinement, or the replay of the whole recording
    with its refined parameters) is a failed option: −∞ evidence, the nominal replay, and the
    simulator's message in ``failed``.
    """
    data, model, table = nom.data, nom.model, nom.table
    try:
        got = refine_choice(opt.cand, opt.x, model, data, nom.config, nom.w, nom.substeps, nom.floors)
        fitted_model, delay = apply_effects(model, got.cand.effects(got.x))
        rep1 = replay_recording(data, fitted_model, delay, nom.w, nom.substeps, None, nom.chunk, nom.warm)
    except SudsSimulationError as exc:
        nan = np.full(opt.x.size, np.nan)
        return _Tried(opt, Refined(opt.cand, np.asarray(opt.x, dtype=float), nan, nan, nan), nom.replay, nom.E0,
                      -math.inf, -math.inf, failed=str(exc))
    E1 = table.residuals(rep1.rp, rep1.xi)
    return _Tried(opt, got, rep1, E1,
                  table.evidence(nom.E0, E1, got.x.size, held=False), table.evidence(nom.E0, E1, got.x.size))


def _extension(nom: _Nominal, naming: Naming, win: _Tried) -> tuple[_Tried | None, str]:
    """The reported set with one more effect, if the replay shows it.

    The effects to try: the forward selection's members that the reported set lacks (when the
    simulator preferred another option), and the effects of the leading sets of the forward step
    that failed the threshold (``Naming.rejected``: the equation error held them back).  Each is
    scored against the refined set in output error by a score test
    (:func:`~.refine.extension_gains`, one replay per parameter); the best, if its first-order
    gain passes ``evidence_threshold``, is refined with the set, and replaces it only when its
    replay evidence is more than ``evidence_threshold`` above the set's on the training half *and*
    the held-out half.  Returns (the extended set or None, a note or '').
    """
    config = nom.config
    parts, starts, origin = [], {}, {}
    # the forward selection's own members that the reported set lacks (the simulator preferred a
    # set without them: one may still belong on top of it), then the held-back effects
    chosen = naming.chosen
    for part, sl in zip(chosen.cand.parts, chosen.cand.slices()):
        if part not in win.cand.parts and part not in parts and _compatible(win.cand, part):
            parts.append(part)
            starts[part] = chosen.x[sl]
            origin[part] = "which the forward selection had chosen"
    for r in naming.rejected:
        part = r.cand.parts[-1]
        if part not in parts and _compatible(win.cand, part):
            parts.append(part)
            starts[part] = r.x[r.cand.slices()[-1]]
            origin[part] = "which the equation error held back"
    if not parts:
        return None, ""
    gains = extension_gains(win.cand, win.x, parts, nom.model, nom.data, config, nom.w, nom.substeps, nom.floors)
    k = int(np.argmax(gains))
    label = effect_label(*parts[k])
    if not gains[k] > config.evidence_threshold:
        return None, ""
    cand = Candidate(win.cand.parts + (parts[k],))
    ext = _try(nom, _Option(cand, np.concatenate([win.x, starts[parts[k]]]), naming.evidence, naming.confounded,
                            float("nan")))
    if ext.failed:
        return None, f"{label} tried on top of {win.cand.label} in the simulator and not kept: {ext.failed}"
    d_train, d_held = ext.train_evidence - win.train_evidence, ext.evidence - win.evidence
    if parts[k] in ext.cand.parts and min(d_train, d_held) > config.evidence_threshold:
        return ext, (f"the simulator added {label}, {origin[parts[k]]}: replay evidence "
                     f"{d_train:.0f} nats above {win.cand.label} on the training half and {d_held:.0f} held out")
    return None, (f"{label} tried on top of {win.cand.label} in the simulator (first-order gain {gains[k]:.0f} "
                  f"nats) and not kept: {d_train:.0f} nats on the training half, {d_held:.0f} held out")


def _ambiguous(win: _Tried, tried: list[_Tried], config: DiagnoseConfig,
               model: ChainModel) -> tuple[Alternative, ...]:
    """The refined sets other than ``win`` within the ambiguity band of its held-out evidence (closest first).

    The nominal model is one (:data:`~.report.NO_EFFECT`) when ``win``'s own evidence is within
    the band.  A set whose added effects are all within ``member_z`` stderr of neutral (a damping
    of 0.0002 ± 0.0001 in place of a located pose offset) is the nominal model again, or the
    reported set again, and is not listed.
    """
    band = config.ambiguity_band
    mine = {effect_label(*p) for p in win.cand.parts}
    reported = {effect_label(e.name, e.target): e for e in fitted_effects(win.cand, win.x, win.se)}
    out: list[tuple[float, Alternative]] = []
    if win.evidence <= band:
        out.append((win.evidence, Alternative(NO_EFFECT, None, {}, float(win.evidence), (), tuple(sorted(mine)))))
    seen = {frozenset(win.cand.parts)}
    for t in tried:
        key = frozenset(t.cand.parts)
        gap = win.evidence - t.evidence
        if key in seen or not t.cand.parts or abs(gap) > band:
            continue
        seen.add(key)
        fits = fitted_effects(t.cand, t.x, t.se)
        added = [e for e in fits if effect_label(e.name, e.target) not in mine]
        if all(_is_neutral(e, model, config.member_z) for e in added):  # none added, or only near-zero ones
            continue
        new = [(e.name, e.target, e.parameters) for e in added]
        # a member both sets share but the alternative needs at other values (a reparameterisation:
        # stiffness_to_drag_error 1.37 + joint_4 × 0.79 for joint_3 × 1.37 + joint_4 × 1.08) is
        # listed with its values, and the reported one it replaces in ``instead_of``
        refitted = [e for e in fits if effect_label(e.name, e.target) in mine
                    and _moved(e, reported[effect_label(e.name, e.target)])]
        theirs = {effect_label(*p) for p in t.cand.parts}
        (name, target, params), rest = new[0], tuple(new[1:])
        rest += tuple((e.name, e.target, e.parameters) for e in refitted)
        instead = (mine - theirs) | {effect_label(e.name, e.target) for e in refitted}
        out.append((gap, Alternative(name, target, params, float(gap), rest, tuple(sorted(instead)))))
    return tuple(a for _, a in sorted(out, key=lambda ga: ga[0]))


def _is_neutral(e: FittedEffect, model: ChainModel, z: float) -> bool:
    """Whether every parameter of ``e`` lies within ``z`` standard errors of its neutral value on ``model``."""
    neutral = neutral_params(e.name, model)
    keys = list(e.parameters)
    return is_neutral(np.array([e.parameters[k] for k in keys]), np.array([e.stderr.get(k, np.nan) for k in keys]),
                      np.array([neutral[k] for k in keys]), z)


def _moved(alt: FittedEffect, mine: FittedEffect) -> bool:
    """Whether a shared effect's alternative value is off the reported one by > 3 stderr and > 1 %."""
    for k, v in mine.parameters.items():
        d = abs(alt.parameters[k] - v)
        se = max(alt.stderr.get(k, 0.0), mine.stderr.get(k, 0.0))
        if np.isfinite(d) and d > 3.0 * (se if np.isfinite(se) else 0.0) and d > 0.01 * max(abs(v), 1e-12):
            return True
    return False


def _show(
    nom: _Nominal, naming: Naming, fit: _Fit,
    coeffs: tuple[tuple[str, str, float, tuple[tuple[float, float], ...]], ...], clock: _Clock,
) -> DiagnosisReport:
    """Stage 5: held-out improvement, the explained/unexplained verdict, notes and the report."""
    data, config, table = nom.data, nom.config, nom.table
    effects, confounded, rep1, E1, floor, F0 = fit.effects, fit.confounded, fit.replay, fit.E1, fit.floor, fit.F0
    F1 = table.fstats(E1, floor)
    affected = [loc.channel for loc in fit.located]
    improvement = excess_improvement(F0, F1, affected)
    unexplained, left = _unexplained(F0, F1, affected, config, fit.unexplained)
    notes: list[str] = ([data.phase_note] if data.phase_note else []) + list(fit.notes)
    rms1 = table.rms(E1)
    if unexplained and effects and improvement < 0.5:
        # the best catalogue fit does not explain the mismatch: do not force it onto an entry
        tried = "; ".join(
            f"{e.name}{':' + e.target if e.target else ''} "
            + ", ".join(f"{k}={v:.4g}" for k, v in e.parameters.items())
            for e in effects
        )
        notes.append(
            f"best catalogue fit ({tried}) left held-out improvement {improvement:.3f}; not reported as an effect"
        )
        effects, confounded = [], ()
        rep1, E1 = nom.replay, nom.E0
        F1 = table.fstats(E1, floor)
    if unexplained:
        notes.append(
            "unexplained mismatch remains on " + ", ".join(left or affected)
            + " (F after the best catalogue fit > "
            + f"{1.5 * config.f_threshold:g} and > {config.unexplained_fraction:g} of its excess before)"
        )
    if unexplained and not effects:
        rms1 = dict(nom.rms0)
        improvement = 0.0
    # beyond named effects too (judged against what they explain): a catalogue entry may stand in
    # for physics outside the catalogue
    discovered: tuple[Discovered, ...] = ()
    if unexplained or effects:
        discovered = _discover(nom, effects, F0, floor, affected, notes,
                               None if unexplained else float(improvement))
    clock.mark("total")
    return _report(
        nom, rep1, clock.timings, mismatch=True, located=tuple(fit.located), effects=tuple(effects),
        confounded_with=confounded, unexplained=unexplained, heldout_rms_after=rms1,
        improvement=float(improvement), noise_floor=floor, statistics=F0, statistics_after=F1,
        ranking=naming.ranking, conditions=fit.conditions, coefficients=coeffs, notes=tuple(notes),
        discovered=discovered,
    )


def _discover(
    nom: _Nominal, effects: list[FittedEffect], F0: dict[str, float], floor: dict[str, float],
    affected: list[str], notes: list[str], explained: float | None = None,
) -> tuple[Discovered, ...]:
    """Discovery on the torque residual left by the reported effects (nominal if none).

    The formulas found are re-simulated together (:mod:`.resimulate`, on top of the reported
    effects) and each gets the held-out improvement of that replay, measured as for the catalogue
    effects (:func:`~suds_ros.core.diagnosis.locate.excess_improvement` over the located channels).
    ``explained``: the held-out improvement of the reported effects when they explain the
    mismatch.  Formulas on top of them are then kept only if their replay removes at least half of
    the excess the effects leave (1 − improvement halves): the equation error can hold structure
    the simulator does not (stick-slip transitions inside an interval), and a formula that cannot
    be re-simulated (on a joint with Coulomb friction) is not checked, so not reported.
    """
    if nom.data.pas.size == 0:
        if explained is None:
            notes.append("no formula discovery: the chain is fully actuated (no passive joint whose "
                         "torque balance a formula could complete)")
        return ()
    cand = Candidate(tuple((e.name, e.target) for e in effects))
    x = np.array([v for e in effects for v in e.parameters.values()])
    found = discover(nom.data, nom.model, nom.config, nom.floors[0], cand, x)
    if found:
        model, delay = apply_effects(nom.model, cand.effects(x))
        torques = {d.joint: d.terms for d in found if d.joint is not None}
        try:
            rep = replay_recording(nom.data, model, delay, nom.w, nom.substeps, None, nom.chunk, nom.warm,
                                   torques=torques)
            F2 = nom.table.fstats(nom.table.residuals(rep.rp, rep.xi), floor)
            imp = float(excess_improvement(F0, F2, affected))
        except (SudsConfigError, FloatingPointError, np.linalg.LinAlgError) as err:
            notes.append(f"discovered formulas not re-simulated: {err}")
            imp = None
        found = tuple(dataclasses.replace(d, resimulated_improvement=imp) for d in found)
        if explained is not None and (imp is None or 1.0 - imp > 0.5 * (1.0 - explained)):
            kept = "not re-simulated" if imp is None else f"re-simulated held-out improvement {imp:.3f}"
            notes.append(f"formulas on top of {cand.label} not reported ({kept} against {explained:.3f} "
                         f"without them): " + "; ".join(formula(d) for d in found))
            return ()
    beyond = f" on top of {cand.label}" if effects else ""
    for d in found:
        resim = ("" if d.resimulated_improvement is None
                 else f"; re-simulated held-out improvement {d.resimulated_improvement:.3f}")
        notes.append(f"discovered{beyond} {formula(d)} ({', '.join(d.physics) or 'no recognised physics'}; "
                     f"held-out torque residual power −{100 * d.heldout_reduction:.0f} %{resim})")
    return found


def _unexplained(
    F0: dict[str, float], F1: dict[str, float], affected: list[str], config: DiagnoseConfig, already: bool
) -> tuple[bool, list[str]]:
    """Whether the located excess power is not mostly removed, and the channels left unexplained."""
    unexplained = already
    ex0 = sum(max(F0[c] - 1.0, 0.0) for c in affected)
    ex1 = sum(max(F1[c] - 1.0, 0.0) for c in affected)
    still_sig = any(F1[c] > config.f_threshold for c in affected)
    if ex0 > 0 and ex1 / ex0 > config.unexplained_fraction and still_sig:
        unexplained = True
    # per channel: the aggregate can be dominated by one channel the fit does fix while another
    # located channel keeps (or grows) its mismatch; that channel is not explained either
    left = [
        c for c in affected
        if F1[c] > 1.5 * config.f_threshold
        and max(F1[c] - 1.0, 0.0) > config.unexplained_fraction * max(F0[c] - 1.0, 1e-12)
    ]
    if left:
        unexplained = True
    return unexplained, left


def _report(nom: _Nominal, rep1: RecordingReplay, timings: dict[str, float], **fields: object) -> DiagnosisReport:
    """Stage 5: the report.

    ``fields`` of :class:`DiagnosisReport` over the no-mismatch defaults (held-out series of the
    nominal replay and of ``rep1`` included, for the figures).
    """
    data = nom.data
    notes = tuple(fields.pop("notes", (data.phase_note,) if data.phase_note else ()))  # type: ignore[call-overload]
    untested = nom.table.untested(nom.E0)
    if untested:
        notes += (f"not tested: {', '.join(untested)} (no usable held-out sample: every one is at or next "
                  "to a gap of the shape or pose stream, or every body-velocity window touches one)",)
    base: dict[str, object] = dict(
        mismatch=False, located=(), effects=(), confounded_with=(), unexplained=False,
        heldout_rms_before=nom.rms0, heldout_rms_after=dict(nom.rms0), improvement=0.0,
        system=nom.model.name, noise_floor=nom.floor, statistics=nom.F0, statistics_after=nom.F0,
        series=_series(nom, rep1), train_cycles=data.n_train // data.spc,
        heldout_cycles=(data.n_used - data.n_train) // data.spc, timings=timings,
        phase_source=data.phase_source, notes=notes,
    )
    return DiagnosisReport(**{**base, **fields})  # type: ignore[arg-type]


def _series(nom: _Nominal, rep1: RecordingReplay) -> dict[str, Channels]:
    """Held-out recorded, nominal and fitted series of every channel, for the figures."""
    data, table, rep0 = nom.data, nom.table, nom.replay
    held = table.held
    out: dict[str, Channels] = {}
    n = data.n_used
    t = data.t[:n][held] - data.t[0]
    ph = np.mod(data.phase[:n][held], 2 * np.pi)
    npas = data.pas.size
    for i, c in enumerate(table.channels):
        if i < npas:
            recd = data.r[:n][held, data.pas[i]]
            b, a = rep0.rp[held, i], rep1.rp[held, i]
        else:
            k = i - npas
            recd = table.xi_rec[held, k]
            b, a = rep0.xi[held, k], rep1.xi[held, k]
        out[c] = Channels(t=t, phase=ph, recorded=recd, before=b, after=a)
    return out


def diagnose_recording(
    rec: Recording,
    system: str | None = None,
    config: DiagnoseConfig = DiagnoseConfig(),
    reference: Recording | None = None,
    progress: Callable[[str], None] | None = None,
    model: ChainModel | None = None,
) -> DiagnosisReport:
    """:func:`diagnose` with ``model`` (e.g. a robot model file's), else the nominal model of ``system``.

    ``system`` is a built-in chain id or the path of a robot model file; default ``rec.system``.
    """
    from suds_ros.core.physics.systems import load_system

    if model is not None:
        if system is not None and system != model.name:
            raise SudsConfigError(f"`system` {system!r} and `model` {model.name!r}: give one of them")
        return diagnose(rec, model, config, reference=reference, progress=progress)
    name = system or rec.system
    sysobj = load_system(name)
    chain = getattr(sysobj, "model", None)
    if not isinstance(chain, ChainModel):
        raise SudsConfigError(
            f"`system` {name!r}: diagnosis needs an RFT chain (purcell3, swimmer9, nlinkN or a robot "
            f"model file); got {type(sysobj).__name__}"
        )
    return diagnose(rec, chain, config, reference=reference, progress=progress)
