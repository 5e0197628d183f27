"""The offline optimisation loop: run → fit → step on a simulated robot (``suds optimize --simulate``).

The robot is a :class:`~suds_ros.core.physics.stream.StreamingSimulator`: one continuous run with
the simulator's usual OU perturbation on top of the reference gait, seeded, switched to a new gait
at a cycle boundary (the set-points fade onto it over one cycle).  The optimiser sees only what a
recording holds (shape and pose samples with their noise); the physics is never consulted.

One iteration
-------------
1. **Fit**: the SUDS model of the incumbent gait (the best gait measured so far) is fitted to
   the incumbent's own cycles (:func:`~suds_ros.core.optimize.data.learn_model`) and, after a
   rejected step, to the newest ``pool_rejected`` stretches of the candidates rejected since it
   became the incumbent: they lie inside its trust region, so the model stays local while its
   data spread wider.  Gaits further back are not pooled: the gait template and the model are
   local.  Stretches are fitted together (no interval spans two stretches).
2. **Step**: right after the start, if the start's oscillation can grow by ``scale_step`` or more
   inside the bounds, that gait scaled to them (``speed``, ``turn``: the net motion per cycle grows
   as the amplitude squared to leading order, so a timid start is first given its headroom; a
   rejected one leaves the search as it was).  The first step after that (the scaled start's, or
   the start's when it is not scaled) is the incumbent run backwards in time, r(−t), the same
   bounds, the travelling wave the other way, if the model of its cycles predicts that better
   (``reverse_trial``).  Otherwise one trust-region step on that model
   (:func:`~suds_ros.core.optimize.data.optimize_from_data`, κ the current radius in σ of the
   data's δ spread, centred on the incumbent gait: ``trust_centre``), inside the joint range and
   speed bounds; for ``speed`` the predicted rotation is held within
   ``rotation_margin``·``max_rotation`` (the model's rotation errs).  From a half-wave symmetric
   incumbent (odd harmonics only, as a designer's travelling wave) measured on course, the step
   moves only the odd harmonics (``half_wave``): on a mirror-symmetric robot each such gait runs
   straight whatever the model says, and the model's rotation is held within that margin of its
   value for the incumbent instead, as a check on the model (it predicts a turn the robot cannot make
   only where it errs).
3. **Run**: the proposed gait is checked against the bounds (a gait outside them is never run),
   switched in at the next cycle boundary and run for ``settle_cycles`` (discarded: the fade and
   the passive transient) plus ``step_cycles`` measured cycles.
4. **Judge by measurement**: the objective measured on those cycles (the net motion per cycle,
   counted from every point of the cycle: :func:`measure_cycles`) is compared with the
   incumbent's measurement.  The step is accepted only if the measurement confirms it: a higher
   measured objective, and for ``speed``/``efficiency`` a measured |rotation| per cycle within
   ``max_rotation`` (read off the SUDS model fitted to the candidate's own cycles, at δ = 0, where
   it fits, which takes out the perturbation's share of each cycle's rotation; else the mean of
   the cycles: :meth:`Measurement.rotation_reading`; the bound is the spec's straight-course
   bound; for a half-wave gait on a robot whose
   half-wave start measured straight, over it by at most ``rotation_sigmas`` standard errors;
   for ``turn`` and ``efficiency`` a measured
   speed no lower than the start gait's).  A feasible gait always beats an infeasible one; between infeasible
   gaits the smaller violation wins.  A measured gain within ``confirm_sigmas`` standard errors
   of the difference, for a step whose *predicted* gain is within as many too, is not kept at
   once: the candidate is run again and judged on both stretches pooled (near the limit such
   gains are the measurement's noise; a step the model expects to gain more than the noise, as
   from a poor start, is kept on its first measurement).  So is a reversed gait's (the reverse
   trial's prediction is an extrapolation, so it never spares the second run).  Accepted: the
   candidate becomes the incumbent and its cycles the next model's data; the radius grows
   (× ``grow``, up to ``trust_max``) when the measured gain is at least half the predicted gain
   and the step reached the region's edge, and shrinks (× ``shrink``, not below ``trust``) when
   it is under ``POOR_RATIO`` of it.
   Rejected: the incumbent's model refitted with the rejected cycles (``pool_rejected``; else the
   same model), radius × ``shrink``.  Below ``trust_min`` the incumbent
   is run again (settling + ``step_cycles``): its stretches are pooled for a new measurement (which
   also undoes a lucky first one) and a new model, and the radius starts afresh.

When the model predicts no gain inside a shrunken region, the incumbent is re-run likewise; so too
when a model of the incumbent's single stretch predicts no gain inside a region at least the
initial radius (a few cycles' model that sees no gain anywhere is no evidence of an optimum: in
the oracle ablation of ``docs/results/optimize_loop.md`` one saw none at 94 % of snake5's limit
after 16 cycles, and the search stopped there with 44 cycles of budget left).
The loop stops when the model of two or more of the incumbent's stretches predicts no gain
inside such a region, when it would propose a gait already rejected (possible only with
``trust_centre`` = ``template``: the radius cannot shrink below the incumbent's own offset from
the template), or when the next gait's cycles would overrun ``budget_cycles``.  Every cycle the
robot runs is counted, the settling cycles and the rejected candidates' cycles included
(``shared/spec/gait.md``).
It returns the best gait it measured.

The OU perturbation acts on top of the gait's set-points (that is what makes the data
informative), so the perturbed set-points themselves can leave the joint bounds by about the OU
amplitude; the *gaits* run and proposed never do.

``efficiency`` is measured as the distance per cycle over the gait's actuator work per cycle, the
work ∮ τ̄_a · dθ̄_a of the phase averages of the recorded effort and actuated angles
(:func:`measure_cycles`; the simulated robot then records its effort, as ``suds simulate --effort``
does), and predicted by the model's learned torques
(:class:`~suds_ros.core.optimize.data.LearnedCycle`).  The phase averages keep the gait's work and
drop the zero-mean part that the excitation drives: over 5 cycles of the nominal gait at the
default drive, the raw Σ τ_a · Δr_a of purcell3 and snake5 is 1.8–2.0× the gait's own work on the
physics, the phase-averaged one 1.1–1.3× (``docs/results/optimize_efficiency.md``).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import special

from suds_ros.core import se2
from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.core.ident.identify import IdentifyConfig
from suds_ros.core.optimize.change import hotelling_p, passive_shift
from suds_ros.core.optimize.data import (
    FRAMES,
    DataOptimizeConfig,
    LearnedCycle,
    LearnedModel,
    MotionMiss,
    align_shift,
    learn_model,
    motion_miss,
    optimize_from_data,
)
from suds_ros.core.optimize.physics import UNSUPPORTED_OBJECTIVE, objective_values, origin_chords, origin_distances
from suds_ros.core.physics.gait import (
    DEFAULT_MAX_ORDER,
    MAX_ORDER,
    OBJECTIVES,
    Gait,
    GaitLimits,
    check_constraints,
    check_gait,
    constraint_violations,
    gait_limits,
    nominal_gait,
    reversal_shift,
    time_reversed,
    time_shifted,
    with_predicted,
)
from suds_ros.core.physics.sim import SimConfig, effort_by_joint
from suds_ros.core.physics.stream import StreamingSimulator
from suds_ros.core.physics.system import SudsSystem
from suds_ros.core.recording import Recording

BUDGET_TOO_SMALL = "budget_too_small"
NO_REQUEST = "no_request"
#: stretches of the incumbent pooled at most (the newest)
MAX_STRETCHES = 8
#: a rejected candidate is checked against its model's prediction (``model_miss``) only when its step's
#: trust region was at most this many σ of the data's spread, where the candidate is nearly the incumbent:
#: further out the model extrapolates (on the unchanged swimmer9 a step at 2 σ missed its rotation by
#: 0.31 rad/cycle, one at 1 σ by 0.21)
MISS_TRUST = 0.5
#: an accepted step whose measured gain is under this fraction of its predicted gain shrinks a radius that
#: had grown past ``trust`` (× ``shrink``, not below ``trust``): the model was far off that far out (snake5
#: from half amplitude: at 8 σ a step predicted +0.56 m/s measured +0.03, and the next 8 σ step halted the robot)
POOR_RATIO = 0.25
#: coefficient draws behind the returned gait's ``predicted_std`` (:func:`predicted_std`)
RESULT_DRAWS = 16


@dataclass(frozen=True)
class LoopConfig:
    """Settings of :func:`optimize_loop`.

    Parameters
    ----------
    budget_cycles : int
        Gait cycles the robot may run in all (settling and rejected cycles included).
    seed : int
        Seed of the simulated robot's OU perturbation and measurement noise.
    objective : str
        ``speed``, ``turn`` or ``efficiency`` (measured from the recorded effort).
    first_cycles : int
        Measured cycles of the start gait (≥ 4, as ``step_cycles``).  The default, as many as a
        candidate's, makes every gait cost ``settle_cycles`` + 4 = 5 cycles, so a budget of 5n cycles
        holds n gaits exactly (with 5 measured start cycles the fifth gait ended at cycle 26: one
        step fewer within the 5-per-link targets of ``docs/results/optimize_loop.md``).
    step_cycles : int
        Measured cycles of each candidate gait (≥ 4: an accepted candidate's cycles are the next
        model's data, and the phaser needs three whole cycles after the settling one is cut).
    settle_cycles : int
        Cycles run and discarded after the start and after every switch (≥ 1).
    order : int
        Harmonics K of the proposed gaits (1..8).
    trust, trust_min, trust_max : float
        Initial, smallest and largest trust-region radius κ, in σ of the data's δ spread.
    trust_centre : str
        ``start`` (default): the region is centred on the incumbent gait, around which its data
        scatter; ``template``: on the model's gait template, as ``suds optimize BAG`` does (from a
        few cycles the template is off the incumbent by about 1 σ, so the region cannot shrink
        below that and a rejected step tends to come back).
    shrink, grow : float
        Radius factors after a rejected step (0 < shrink < 1) and a confirmed full step (≥ 1).
    draws, min_gain_sigmas : int, float
        Coefficient draws and the draw gate of each step (:class:`DataOptimizeConfig`).
    max_rotation : float
        Bound on the measured |net rotation| per cycle for ``speed``, rad (judged on
        :meth:`Measurement.rotation_reading`).
    floor_sigmas : float
        ``turn`` and ``efficiency`` hold the speed at no less than the start gait's, and both speeds are
        measured: a gait counts as under that floor only when its measured speed is more than this
        many standard errors of the difference below the start gait's (0: any shortfall).  The
        efficient gaits lie on the floor, so a strict test on two noisy numbers would refuse about
        half of them.
    rotation_sigmas : float
        For ``speed`` and ``efficiency``, on a robot that looks mirror-symmetric (its half-wave start
        gait measured a rotation within this many of its standard errors of zero), a half-wave
        gait's measured |rotation| counts as over the bound only when it is over by more than this
        many of its standard errors; otherwise, and for every other gait, any excess counts.  Under
        the default excitation a few cycles' rotation of a straight gait scatters by about 0.1
        rad/cycle on swimmer9, twice the bound, so a strict test refuses straight gaits on a coin
        toss; on a robot with a bent spring the same gaits truly turn, and the bound is kept strictly.
    scale_step : float
        For ``speed`` and ``turn``: when the start gait's oscillation can grow by at least this factor
        inside the joint range and speed bounds (offsets kept), the first step after the start is that
        gait scaled to its bounds (:func:`headroom`), predicted at s² times the start's measurement:
        in a dissipative medium the net motion per cycle grows as the square of a gait's amplitude to
        leading order (the area the shape loop encloses), so a timid start wastes the headroom its
        bounds allow, and a trust region of its data's spread takes several steps to get there.  Judged
        by measurement like every candidate; if rejected, the search goes on from the start as if it
        had not been tried (radius unchanged, its cycles not pooled).  On a start that turns (or any
        that does not look mirror-symmetric) the factor is also kept to s² |rotation| ≤
        ``rotation_margin``·``max_rotation``.  ``inf``: never.
    reverse_trial : bool
        Once, as the step after the scaled start (or after the start, when it is not scaled), run the
        incumbent backwards in time, r(−t) (:func:`~suds_ros.core.physics.gait.time_reversed`: the same
        range and speed, so always inside the bounds), judged by measurement like every candidate; if
        rejected, the search goes on as if it had not been tried.  The trust-region steps are local:
        from a wave that runs the wrong way they climb the nearest optimum, which on a robot that is
        not its own fore-aft mirror image can be far below the other direction's (swimmer9's
        reversed nominal wave runs at 2 % of its limit, the nominal wave at 63 %), and the SUDS
        model, local to a gait, cannot predict the reversed one.  No data tells beforehand which way
        a robot swims faster (a passive head or tail joint can make the reversed wave the fast one),
        so it is a trial of ``settle_cycles`` + ``step_cycles`` cycles, run only when the model of the
        incumbent's cycles, extrapolated, predicts the reversed drive better than the incumbent, or,
        where its point prediction says no, when more than half of its coefficient draws that predict
        both drives say so (:func:`reverse_odds`; at least half of ``RESULT_DRAWS`` must predict).  A
        hint, far outside the model's data, where the point prediction is skewed: on 18 robot–gait
        pairs, 3 models each, the point prediction said "faster" for all 21 fits whose reversed drive
        truly is, and for 12 of 33 whose is not; on random model-file robots it missed reversed waves
        up to 6× faster that most draws saw (``docs/results/optimize_reverse.md``).  A model with no
        steady state for either drive says nothing.  Not tried where the reversed drive is the same
        drive started elsewhere in its cycle (:func:`~suds_ros.core.physics.gait.reversal_shift`: one
        actuated joint at one harmonic, as purcell3's, or joints in phase).  False: never.
    rotation_from_model : bool
        For ``speed`` and ``efficiency``, read each run's rotation for the straight-course bound off
        the SUDS model fitted to that run's own cycles, at δ = 0 (:func:`model_rotation`), where it
        fits; else (and with False) the mean of the cycles.  The regression explains the part of
        each cycle's rotation that the perturbation δ put there, so its reading is the closer one:
        rms error 1.5–5× smaller over 10 seeds of 7 robot–gait pairs, among them a gait that truly
        turns at twice the bound, which it still reads over the bound in 10 of 10
        (``docs/results/optimize_rotation.md``).  The speed stays the measured one (the model's
        speed is no closer there, and biased on purcell3).  Costs one fit per run.
    body_frame : str
        The body frame every model of the loop is fitted in (:func:`~suds_ros.core.optimize.data.learn_model`):
        ``"shape"``, the recorded yaw turned by the combination of joint angles it follows (fitted to
        the model's own stretches), or ``"pose"``, the recorded frame.  The objectives are the same
        in both; on a robot whose pose frame swings with its shape (swimmer9's head link) the shape
        frame's model predicts a step's gain far better (``docs/results/optimize_step_aim.md``).
    random_features : bool
        Whether the identifier's random-feature models of the whole shape are among the candidates
        its cross-validation picks each model from (``IdentifyConfig.kernel_grid``, tried on at most
        ``kernel_max_rows`` intervals: every model of a few cycles here).  They win that selection
        on purcell3 and swimmer9 from 5 cycles, and the loop's steps planned on them went further:
        without them swimmer9's 7 benchmark runs summed 597.0 against 648.3 per cent of the limit at
        90 cycles, the wave-reversed start 48.5 against 93.0; purcell3, snake5 and neck4 were level
        (``docs/results/optimize_loop.md``, ablation ``no-kernel``).  False: the Fourier SUDS
        regression alone.
    origin_sigmas : float
        For ``speed`` and ``efficiency``, the gait returned is counted from the point of its cycle it
        measured furthest from (:func:`measured_origin`) when its measured rotation is beyond this
        many standard errors of zero: a turning gait's chord from its time zero depends on that
        point, and the spec counts from the gait file's time zero.  The motion is the same, so no
        cycle is run for it; its measured speed counts every point of the cycle alike
        (:func:`measure_cycles`), so it stays, at most the shifted gait's.  The choice
        goes wrong only when the measured rotation has the wrong sign; for an unbiased measurement
        that is the less likely side at any noise, so the expected gain is never negative, and the
        threshold only keeps a noisy choice from being made where the gain is small.  ``inf``: the
        gait as run.
    accept_sigmas : float
        A candidate is kept only if its measured gain exceeds this many standard errors of the
        difference of the two measurements (√(se_new² + se_old²)); 0: any measured gain (≥ 0).
    confirm_sigmas : float
        A candidate that measures better than the incumbent, but by less than this many standard
        errors of the difference (√(se_new² + se_old²)), and whose step's predicted gain is also
        less than this many of them, is run again (settling + ``step_cycles``) before it is kept:
        its two stretches are pooled and judged once more (no further confirmation).  Without the
        budget for that run it is rejected.  0: every candidate is kept on its first measurement.
        Near the limit the measured gains are within the measurement's noise and keeping a lucky
        one walks the gait away from the limit (from purcell3's and snake5's nominal gaits the loop
        kept gaits 0.1–1.1 points below the start); from a poor start the model predicts gains well
        beyond the noise, and those steps are not run twice (confirming every marginal gain cost
        purcell3's half-amplitude start 24 points at 15 cycles: ``docs/results/optimize_loop.md``).
        The reverse trial's gait too, whatever its prediction (an extrapolation far outside the
        model's data): on a random 7-link robot that barely moves, its reversed wave read 0.046 ±
        0.033 m/s against the start's 0.018 ± 0.004 (truly 0.006 against 0.014); kept on that one
        reading, the run returned a gait at 33 % of the limit, run again 74 %.  Confirmed, it is
        judged as a reversed gait: rejected, the search goes on as if it had not been tried.
    rotation_margin : float
        The step asks the model for a predicted |rotation| ≤ ``rotation_margin``·``max_rotation``
        (in (0, 1]; for a half-wave step, within that much of the model's rotation for the
        incumbent): the model's rotation errs by a few hundredths of a radian per cycle, so a step
        planned at the bound often breaks it on the robot.  0.8 since 2026-12-05 (0.5 before):
        with 0.8 the loop benchmark's 7 runs per robot summed swimmer9 632.5 against 628.7 per cent
        of the limit at 45 cycles, neck4 635.4 against 628.2 at 20 (its target met in 2 runs of 7
        instead of 1), purcell3 the same and snake5 level (``docs/results/optimize_loop.md``,
        ablation ``margin5``); on a robot off course (snake5 with a bent spring) the fast gaits
        turn near the bound, where a step aimed at half of it does not go.
    pool_rejected : int
        The step's model is fitted to the incumbent's stretches and to the newest this many stretches
        of the candidates rejected since it became the incumbent (0: the incumbent's alone), refitted
        after each rejection.  The rejected gaits lie inside the incumbent's trust region: their cycles
        widen the data the next step is planned from, where the incumbent's few cycles alone leave
        the model guessing (``docs/results/optimize_loop.md``, ablation).
    pool_incumbents : int
        Also fit the step's model to the newest this many stretches of the gaits that were the
        incumbent before the current one (0, the default: none; dropped with the rest when the robot
        changes).  They lie a step or two away, so they widen the data as the rejected ones do: on
        swimmer9 the model of 4 cycles predicts a step's gain 2–13× too large, one of 40 cycles
        about right (``optimize_step_aim.md``, README).  Measured as the ablations
        ``pool-incumbents`` (2) and ``pool-all`` (1000) in ``optimize_loop.md``: up on swimmer9 at
        its target, mixed elsewhere; not the default.
    watch : bool
        When the model of the incumbent's pooled stretches predicts no gain (converged), run the
        incumbent again (its stretches pooled, the change test above applied) instead of stopping,
        until the budget is spent: a deployed robot keeps checking that its gait still is what it measured.
    change_sigmas : float
        The robot is taken to have changed when the incumbent, run again, measures more than this
        many standard errors of the difference away from its standing measurement; and the
        incumbent is run again at once after two rejected candidates in a row that each measured
        more than this many standard errors below it, and after one half-wave candidate measured
        turning past the rotation bound by more than this many on a robot that looked
        mirror-symmetric (see :class:`GaitSearch`).  Standard errors
        taken from a few cycles are read through Student's t (:func:`_sigmas`): normal-equivalent
        deviates.  ``inf``: never.
    model_miss : float
        A run whose measured body motion misses the model's prediction along the run's own measured
        shapes (:func:`~suds_ros.core.optimize.data.motion_miss`) by more than this (a fraction of the
        measured translation per cycle, or radians of yaw per cycle), and by more than its own
        standard error over the run's cycles (not noise on a robot that barely moves), is a robot
        the model no longer describes: after a rejected candidate (judged on the model its step was
        planned on, if the step's trust region was at most ``MISS_TRUST`` = 0.5 σ) the
        incumbent is run again at once, and a rerun that misses the model of the incumbent's
        standing data (its last cycle too) counts as changed; its own cycles from before the change (those up to the
        last one within ``model_miss``) are dropped too, and a stretch left shorter than
        ``step_cycles`` has the incumbent run again for more.  The speed over a few cycles
        scatters with the perturbations the robot ran; the model predicts that scatter, so a
        changed robot shows here long before its speed does.  On purcell3 and snake5 as modelled
        the miss stayed at or under 0.08, also for gaits with 15 % more or less amplitude than
        the model's data; purcell3 with its spring 3× stiffer missed by 0.19–0.99, snake5 with a
        spring rest bent by 0.7 rad by 1.4–1.7 (``docs/results/optimize_adapt.md``, the model's
        miss).  Away from a good gait it is not quiet: a re-run of the same gait on the same robot
        read over 0.15 in 4–9 of 10 seeds for 6 of 18 robot–gait pairs (the reversed waves of swimmer9,
        eel4 and snake5, eel4's half amplitude, neck4's nominal gait and half amplitude), in at most 3
        of 10 for the rest (``docs/results/optimize_miss.md``): the miss is a fraction of a translation
        that may be small, and its standard error, over 4 cycles, leaves out the model's own error
        (the coefficients' covariance, propagated, swamps even a true change: not used).  There a
        false change costs the incumbent's data and a re-run.  ``inf``: never.  On a robot with
        passive joints a rerun is judged by ``passive_alpha`` instead (a rejected candidate's miss
        still has the incumbent re-run).
    passive_alpha : float
        On a robot with passive joints, a rerun of the incumbent whose passive shapes differ from those
        of its standing stretches at this significance (:func:`~suds_ros.core.optimize.change.passive_shift`:
        per joint, a two-sample T² of each cycle's mean, cosine and sine of the angle, Bonferroni over the
        joints), its last cycle nearer the new shapes than the old, counts as changed, its cycles before
        the change dropped.  No model enters, so the model's error on a slow gait cannot raise it: on
        re-runs of the same gait on the same robot (6 robots × 3 gaits × 10 seeds) it alarmed in 1 of
        180, where ``model_miss`` alarmed in 45 (up to 9 of 10 per pair); on purcell3 with a 3× stiffer
        spring and snake5 with a spring rest bent by 0.7 rad, at the nominal gait and at half
        amplitude, it saw 39 of 40 (``docs/results/optimize_miss.md``).  A change that leaves
        the shapes alone (a uniform current) is left to ``change_sigmas``.  0: never (``model_miss``
        judges the rerun instead, as it does where a cycle has too few shape samples to compare).
    half_wave : bool
        When the incumbent gait is half-wave symmetric (r(t + T/2) = −r(t), as a designer's
        travelling wave is) and the objective is ``speed`` or ``efficiency``, the step moves only
        its odd harmonics (:attr:`DataOptimizeConfig.half_wave`): on a mirror-symmetric robot every
        such gait runs a straight course, so the model's rotation, which errs by more than the
        bound, is only held near its value for the incumbent.  The measured rotation still judges
        every candidate, and an incumbent measured off course has the full step (all harmonics,
        the model's rotation within the bound) to bring it back.
    samples_per_cycle : int
        Samples per gait cycle of the simulated robot's recording.
    ou_std, kappa, noise_std : float
        The simulator's OU perturbation (rad, 1/s) and measurement noise (rad, m).
    """

    budget_cycles: int
    seed: int = 0
    objective: str = "speed"
    first_cycles: int = 4
    step_cycles: int = 4
    settle_cycles: int = 1
    order: int = DEFAULT_MAX_ORDER
    trust: float = 2.0
    trust_min: float = 0.25
    trust_max: float = 8.0
    trust_centre: str = "start"
    shrink: float = 0.5
    grow: float = 2.0
    draws: int = 0
    min_gain_sigmas: float = 0.0
    max_rotation: float = 0.05
    rotation_margin: float = 0.8
    floor_sigmas: float = 1.0
    accept_sigmas: float = 0.0
    confirm_sigmas: float = 1.0
    pool_rejected: int = 2
    pool_incumbents: int = 0
    watch: bool = False
    change_sigmas: float = 2.5
    model_miss: float = 0.15
    passive_alpha: float = 0.01
    half_wave: bool = True
    rotation_sigmas: float = 1.0
    scale_step: float = 1.25
    reverse_trial: bool = True
    rotation_from_model: bool = True
    body_frame: str = "shape"
    random_features: bool = True
    origin_sigmas: float = 1.0
    samples_per_cycle: int = 100
    ou_std: float = 0.175
    kappa: float = 8.0
    noise_std: float = 1e-3

    def __post_init__(self) -> None:
        if self.objective not in OBJECTIVES:
            raise SudsConfigError(f"`objective`: expected one of {list(OBJECTIVES)}, got {self.objective!r}")
        checks = [("budget_cycles", self.budget_cycles >= 1, "≥ 1"),
                  ("first_cycles", self.first_cycles >= 4, "≥ 4"),
                  ("step_cycles", self.step_cycles >= 4, "≥ 4"),
                  ("settle_cycles", self.settle_cycles >= 1, "≥ 1"),
                  ("order", 1 <= self.order <= MAX_ORDER, f"1..{MAX_ORDER}"),
                  ("trust", math.isfinite(self.trust) and self.trust > 0, "> 0"),
                  ("trust_min", 0 < self.trust_min <= self.trust, f"in (0, trust = {self.trust!r}]"),
                  ("trust_max", math.isfinite(self.trust_max) and self.trust_max >= self.trust,
                   f"≥ trust = {self.trust!r}"),
                  ("shrink", 0 < self.shrink < 1, "in (0, 1)"), ("grow", self.grow >= 1, "≥ 1"),
                  ("draws", self.draws >= 0, "≥ 0"), ("min_gain_sigmas", self.min_gain_sigmas >= 0, "≥ 0"),
                  ("max_rotation", self.max_rotation > 0, "> 0"),
                  ("rotation_margin", 0 < self.rotation_margin <= 1, "in (0, 1]"),
                  ("floor_sigmas", math.isfinite(self.floor_sigmas) and self.floor_sigmas >= 0, "≥ 0"),
                  ("rotation_sigmas", math.isfinite(self.rotation_sigmas) and self.rotation_sigmas >= 0, "≥ 0"),
                  ("origin_sigmas", self.origin_sigmas >= 0, "≥ 0"),
                  ("scale_step", self.scale_step > 1, "> 1"),
                  ("accept_sigmas", math.isfinite(self.accept_sigmas) and self.accept_sigmas >= 0, "≥ 0"),
                  ("confirm_sigmas", math.isfinite(self.confirm_sigmas) and self.confirm_sigmas >= 0, "≥ 0"),
                  ("pool_rejected", self.pool_rejected >= 0, "≥ 0"),
                  ("pool_incumbents", self.pool_incumbents >= 0, "≥ 0"),
                  ("change_sigmas", self.change_sigmas > 0, "> 0"),
                  ("model_miss", self.model_miss > 0, "> 0"),
                  ("passive_alpha", 0 <= self.passive_alpha < 1, "in [0, 1)"),
                  ("samples_per_cycle", self.samples_per_cycle >= 8, "≥ 8"),
                  ("ou_std", self.ou_std >= 0, "≥ 0"), ("kappa", self.kappa > 0, "> 0"),
                  ("noise_std", self.noise_std >= 0, "≥ 0")]
        for name, ok, expected in checks:
            if not ok:
                raise SudsConfigError(f"`{name}`: expected {expected}, got {getattr(self, name)!r}")
        if self.body_frame not in FRAMES:
            raise SudsConfigError(f"`body_frame`: expected one of {list(FRAMES)}, got {self.body_frame!r}")
        if self.trust_centre not in ("start", "template"):
            raise SudsConfigError(f"`trust_centre`: expected 'start' or 'template', got {self.trust_centre!r}")
        first = self.settle_cycles + self.first_cycles
        if self.budget_cycles < first:
            raise SudsConfigError(f"`budget_cycles`: expected at least settle_cycles + first_cycles = {first} (the "
                                  f"start gait's run), got {self.budget_cycles}", code=BUDGET_TOO_SMALL)


@dataclass(frozen=True)
class Measurement:
    """The objective measured on a gait's recorded cycles (the net motion per cycle, :func:`measure_cycles`).

    Attributes
    ----------
    speed : float, m/s (counted from every point of the cycle); rotation : float, rad per cycle;
        turn : float, rad/s.
    speed_se, rotation_se : float, their standard errors (NaN for one cycle).
    cycles : int, cycles measured.
    work : float or None, the gait's actuator work per cycle, J (None: no effort measured).
    efficiency, efficiency_se : float or None, distance per cycle over work per cycle, m/J, and its
        standard error (None: no effort measured; NaN: no positive work).
    translation_p : float or None, the p-value of Hotelling's T² test that the mean translation per
        cycle is zero (None: fewer than 3 cycles).  Large: the measured speed cannot be told from no
        motion at all, and a speed measured on noise is biased up (|mean| of zero-mean cycles > 0).
    model_rotation, model_rotation_se : float or None, the rotation per cycle of the SUDS model fitted
        to these cycles, at δ = 0 (:func:`model_rotation`), and its spread over coefficient draws
        (None: no model fitted, or no spread).  The straight-course bound is judged on it
        (:meth:`rotation_reading`).
    speed_dof : float, the degrees of freedom of ``speed_se`` (the blocks, or cycles, it was estimated
        from, less one; inf: taken as known).  The change tests read a difference's standard errors
        through Student's t with them (:func:`_sigmas`).
    """

    speed: float
    rotation: float
    turn: float
    speed_se: float
    rotation_se: float
    cycles: int
    work: float | None = None
    efficiency: float | None = None
    efficiency_se: float | None = None
    translation_p: float | None = None
    model_rotation: float | None = None
    model_rotation_se: float | None = None
    speed_dof: float = math.inf

    def rotation_reading(self) -> tuple[float, float]:
        """The (rotation, se) the straight-course bound is judged by, rad/cycle.

        The model's rotation at δ = 0 where one was fitted (:func:`model_rotation`), with the smaller
        of its spread over draws and the cycles' standard error (measured, the model's value is the
        closer of the two: its se is at most the raw mean's); else the mean of the cycles.
        """
        if self.model_rotation is None:
            return self.rotation, self.rotation_se
        spreads = [x for x in (self.rotation_se, self.model_rotation_se) if x is not None and math.isfinite(x)]
        return self.model_rotation, (min(spreads) if spreads else float("nan"))

    def value(self, objective: str) -> float:
        """Return the objective: the speed, the efficiency, or for turn the |turn rate|."""
        if objective == "efficiency":
            return float("nan") if self.efficiency is None else self.efficiency
        return abs(self.turn) if objective == "turn" else self.speed

    def value_dof(self, objective: str) -> float:
        """Degrees of freedom of :meth:`value_se` (the rotation's and the work's: the cycles less one)."""
        cycles = self.cycles - 1.0 if self.cycles > 1 else math.inf
        if objective == "turn":
            return cycles
        return min(self.speed_dof, cycles) if objective == "efficiency" else self.speed_dof

    def value_se(self, objective: str) -> float:
        """Standard error of :meth:`value` (turn: of the rotation, · f)."""
        if objective == "efficiency":
            return float("nan") if self.efficiency_se is None else self.efficiency_se
        return self.rotation_se * abs(self.turn / self.rotation) if objective == "turn" and self.rotation \
            else self.speed_se


def measure_cycles(pose: FloatArray | Sequence[FloatArray], samples_per_cycle: int, gait_hz: float,
                   drive: Sequence[tuple[FloatArray, FloatArray]] | None = None) -> Measurement:
    """The net motion per cycle of a pose series, counted from every point of the cycle.

    Speed: |d̄| · f, d̄ the mean over one-cycle windows [t, t + 1/f] of the window's displacement
    expressed in the frame of its mean heading (the trapezoidal mean of the yaw over the window),
    for t at every sample of each whole cycle but the last (each point of the cycle counts equally).
    Counting from the cycle starts alone, as g(t)⁻¹ g(t + 1/f), picks up a perturbation's rotation
    per cycle times the body point's sideways offset at that point of the cycle: on swimmer9's gaits
    near its limit, under the loop's default perturbation, that coupling made the speed of 4 cycles
    scatter by 9–16 % of the speed (correlation 0.9 with the cycles' rotation); counted from every
    point, by 1–4 % (``docs/results/optimize_noise.md``).  The mean heading's frame is a property
    of the whole window, not of the swing of the body frame at its start.
    Its standard error: the windows' components along d̄ averaged over each whole cycle of starts
    (a block's mean is the step between two consecutive cycles' mean positions, and d̄ the mean
    of those steps), treated as independent draws as the cycles are; with fewer than two blocks,
    that of the cycles counted from their starts.  (Steps of a position that random-walks would
    correlate at +1/4, of one that jitters about its course at −1/2; on the loop's robots this se
    is 0.9–2.8× the readings' scatter: ``docs/results/optimize_noise.md``.)
    Rotation: the mean of yaw(t + 1/f) − yaw(t) over *every* sample t with t + 1/f in the series
    (this averages out the within-cycle yaw wiggle of the perturbations: on snake5 and purcell3 at
    the default OU drive its spread over 4-cycle windows was 0.6× and 0.3× that of cycle-start
    windows); its standard error is that of the cycles counted from their starts.
    Whether the translation is there at all: Hotelling's T² of the cycles' (x, y) translations
    g(t)⁻¹ g(t + 1/f) from the cycle starts against zero (:func:`translation_p`).  The cycles are
    treated as independent draws.

    Efficiency (with ``drive``): the distance per cycle |d̄| over the gait's work per cycle
    W = Σ_i τ̄_i · (θ̄_i − θ̄_i−1), τ̄ and θ̄ the actuated efforts and angles averaged over the
    cycles at each sample of the cycle (every stretch starts at a cycle boundary).  The averages
    cancel the zero-mean part of an excitation's work to first order.  Its standard error combines
    the distance's (above) and the work's (the jackknife's over the cycles, each left out in turn)
    as if the two were independent; they grow together, so this errs large.

    Parameters
    ----------
    pose : (n, 3) float, or a sequence of them
        x (m), y (m), unwrapped yaw (rad) at uniform samples, ``samples_per_cycle`` per cycle; several
        separate stretches of the same gait are pooled (their cycles and windows together).
    samples_per_cycle : int
    gait_hz : float
        Cycle frequency f, Hz.
    drive : sequence of ((n, na), (n, na)) float pairs, optional
        Per stretch, the actuated angles (rad) and the actuator effort over the sample period ending
        at each sample (N·m), at the same samples as ``pose``.
    """
    stretches = [np.asarray(p, dtype=float) for p in (pose if isinstance(pose, (list, tuple)) else [pose])]
    if drive is not None and [np.shape(d[0])[0] for d in drive] != [p.shape[0] for p in stretches]:
        raise SudsConfigError(f"`drive`: expected one row per pose sample {[p.shape[0] for p in stretches]}, got "
                              f"{[np.shape(d[0])[0] for d in drive]}")
    cycles, turns, windows, ra_c, tau_c = [], [], [], [], []
    spc = samples_per_cycle
    for s, p in enumerate(stretches):
        k = (p.shape[0] - 1) // spc
        if k < 1:
            raise SudsConfigError(f"`pose`: expected at least one cycle ({spc + 1} samples) per stretch, got "
                                  f"{p.shape[0]}")
        idx = np.arange(k + 1) * spc
        cycles.append(se2.relative(p[idx[:-1]], p[idx[1:]]))  # (k, 3)
        turns.append(p[spc:k * spc + 1, 2] - p[:k * spc + 1 - spc, 2])
        windows.append(_heading_windows(p, spc, (k - 1) * spc if k > 1 else 1))  # (one cycle: its start alone)
        if drive is not None:  # (k, spc + 1, na): each cycle with its end sample
            rows = idx[:-1, None] + np.arange(spc + 1)
            ra_c.append(np.asarray(drive[s][0], dtype=float)[rows])
            tau_c.append(np.asarray(drive[s][1], dtype=float)[rows])
    g = np.concatenate(cycles)
    m = g.shape[0]
    d = np.concatenate(windows)
    dbar = d.mean(axis=0)
    norm = math.hypot(dbar[0], dbar[1])
    speed = float(norm * gait_hz)
    rotation = float(np.mean(np.concatenate(turns)))
    dist_se, dof = _distance_se(windows, dbar, spc, g)
    speed_se = dist_se * gait_hz
    rot_se = float(g[:, 2].std(ddof=1) / math.sqrt(m)) if m > 1 else float("nan")
    work = eff = eff_se = None
    if drive is not None:
        ra, tau = np.concatenate(ra_c), np.concatenate(tau_c)
        work = _phase_work(ra.mean(axis=0), tau.mean(axis=0))
        eff = norm / work if work > 0 else float("nan")
        eff_se = float("nan")
        if m > 1 and work > 0 and norm > 0:  # jackknife of the work: each cycle left out of the means in turn
            w_loo = _phase_work((m * ra.mean(axis=0) - ra) / (m - 1), (m * tau.mean(axis=0) - tau) / (m - 1))
            work_se = float(np.sqrt((m - 1) / m * np.sum((w_loo - w_loo.mean()) ** 2)))
            eff_se = float(eff * math.hypot(dist_se / norm, work_se / work))
    return Measurement(speed=speed, rotation=rotation, turn=rotation * gait_hz, speed_se=speed_se,
                       rotation_se=rot_se, cycles=int(m), work=work, efficiency=eff, efficiency_se=eff_se,
                       translation_p=translation_p(g[:, :2]), speed_dof=dof)


def _heading_windows(p: FloatArray, spc: int, n: int) -> FloatArray:
    """The displacements (n, 2) over the one-cycle windows from samples 0 … n − 1, each in its mean-heading frame."""
    t = np.arange(n)
    cum = np.concatenate([[0.0], np.cumsum(p[:, 2])])
    heading = ((cum[t + spc + 1] - cum[t]) - 0.5 * (p[t, 2] + p[t + spc, 2])) / spc  # trapezoidal mean over the window
    dx, dy = p[t + spc, 0] - p[t, 0], p[t + spc, 1] - p[t, 1]
    c, s = np.cos(heading), np.sin(heading)
    return np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1)


def _distance_se(windows: Sequence[FloatArray], dbar: FloatArray, spc: int,
                 cycles: FloatArray) -> tuple[float, float]:
    """Standard error of |d̄| (:func:`measure_cycles`), m, and its degrees of freedom; NaN where nothing can say.

    Each stretch's windows are whole cycles of starts (spc each), or its one start when it holds one cycle.
    """
    norm = math.hypot(dbar[0], dbar[1])
    if norm == 0:
        return float("nan"), math.inf
    u = dbar / norm
    means = [(w @ u).reshape(-1, spc).mean(axis=1) for w in windows if w.shape[0] >= spc]
    n = sum(x.size for x in means)
    if n >= 2:
        return float(np.concatenate(means).std(ddof=1) / math.sqrt(n)), n - 1.0
    se = along_se(cycles[:, :2])
    return (se, cycles.shape[0] - 1.0) if math.isfinite(se) else (float("nan"), math.inf)


def along_se(xy: FloatArray) -> float:
    """Standard error of |mean| of the rows of ``xy`` (n, 2), treated as independent draws; NaN where none.

    |μ| moves with μ's component along itself (first order): the rows' components along their mean
    count, a sideways sway does not.  NaN for fewer than two rows or a zero mean.
    """
    n = xy.shape[0]
    mean = xy.mean(axis=0) if n else np.zeros(2)
    if n < 2 or not np.any(mean):
        return float("nan")
    return float((xy @ (mean / math.hypot(mean[0], mean[1]))).std(ddof=1) / math.sqrt(n))


def translation_p(xy: FloatArray) -> float | None:
    """P-value of Hotelling's one-sample T² test that the mean of ``xy``'s rows is zero.

    T² = m x̄ᵀ S⁻¹ x̄ over the m rows (S their covariance), and (m − 2) T² / (2 (m − 1)) is F(2, m − 2)
    distributed when the rows are independent normal draws with mean zero (:func:`change.hotelling_p`).
    Rows that all agree (a noise-free run): 0 if their mean is not zero, else 1.  None for fewer
    than 3 rows (no degree of freedom is left for S).
    """
    xy = np.asarray(xy, dtype=float)
    m = xy.shape[0]
    if m < 3 or not np.all(np.isfinite(xy)):
        return None
    return hotelling_p(xy.mean(axis=0), np.cov(xy, rowvar=False), m, m - 1)


#: a returned gait whose measured motion has a p-value over this (against none at all) is flagged
MOTION_ALPHA = 0.05


def motion_doubt(m: Measurement, objective: str, alpha: float = MOTION_ALPHA) -> str | None:
    """A warning when the measured motion behind ``objective`` cannot be told from none (p > ``alpha``).

    ``speed`` and ``efficiency``: the translation per cycle (:attr:`Measurement.translation_p`);
    ``turn``: the rotation per cycle, by Student's t over the cycles (m − 1 degrees of freedom).
    None: told apart, or too few cycles to say.
    """
    from scipy import stats

    if objective == "turn":
        if m.cycles < 2 or not math.isfinite(m.rotation_se):
            return None
        if m.rotation_se == 0.0:
            p = 1.0 if m.rotation == 0.0 else 0.0
        else:
            p = float(2 * stats.t.sf(abs(m.rotation) / m.rotation_se, m.cycles - 1))
        what = f"rotation per cycle ({m.rotation:+.3g} ± {m.rotation_se:.2g} rad)"
    else:
        if m.translation_p is None:
            return None
        p = m.translation_p
        what = f"translation per cycle (speed {m.speed:.3g} ± {m.speed_se:.2g} m/s)"
    if p <= alpha:
        return None
    return (f"the measured {what} cannot be told from none over {m.cycles} cycles (p = {p:.2f}): the robot may "
            "not move under this gait, or move too little for so few cycles to show, and a magnitude measured on "
            "noise is biased up; run it for more cycles")


def _phase_work(ra: FloatArray, tau: FloatArray) -> Any:
    """Σ_i τ_i · (r_i − r_i−1) over one cycle's samples (…, spc + 1, na) → (…) (a float for one cycle)."""
    w = np.einsum("...ij,...ij->...", tau[..., 1:, :], np.diff(ra, axis=-2))
    return float(w) if np.ndim(w) == 0 else w


def actuator_drive(rec: Recording) -> tuple[FloatArray, FloatArray]:
    """The actuated angles (n, na), rad, and efforts (n, na), N·m, of a recording with effort.

    ``rec.effort`` is the effort over the sample period ending at each sample (what a torque or
    current sensor averaged over its control period reads, and what the simulator records).

    Raises
    ------
    SudsConfigError
        The recording has no effort (code ``unsupported_objective``).
    """
    if rec.effort is None:
        raise SudsConfigError("efficiency: the recording has no actuator effort on /suds/shape (record it, e.g. "
                              "`suds simulate --effort`), so the work per cycle cannot be measured",
                              code=UNSUPPORTED_OBJECTIVE)
    act = np.asarray(rec.actuated_index, dtype=int)
    return np.asarray(rec.r, dtype=float)[:, act], np.asarray(rec.effort, dtype=float)[:, act]


def measure_recording(data: Recording | Sequence[Recording], samples_per_cycle: int,
                      gait_hz: float, *, work: bool = False) -> Measurement:
    """:func:`measure_cycles` of recordings' pose streams, at any pose rate and with any stamps.

    A pose stream sampled at exactly ``samples_per_cycle`` per cycle (the simulator's) is measured as
    it is; any other (a motion-capture rate, jitter, dropped frames) is first interpolated
    linearly, in x, y and the yaw, onto that many samples per cycle from its first stamp (the yaw
    is unwrapped already: a :class:`Recording` unwraps it on construction).
    With ``work`` the actuated angles and efforts (:func:`actuator_drive`, at the shape stamps) are
    interpolated onto the same samples, and the efficiency is measured too.
    """
    poses, drives = _resampled(data, samples_per_cycle, gait_hz, work)
    return measure_cycles(poses, samples_per_cycle, gait_hz, drives if work else None)


def measured_origin(data: Recording | Sequence[Recording], samples_per_cycle: int, gait_hz: float) -> int:
    """The sample of the cycle (0 … ``samples_per_cycle`` − 1) that a gait's recorded cycles go furthest from.

    At a periodic steady state the cycle counted from s is g(s)⁻¹ g_c g(s) (as
    :func:`~suds_ros.core.optimize.physics.origin_distances` on the physics): its length is
    |q + (R_θ − I) p_s|, with g_c = (q, θ) the net motion from the cycle starts and p_s the position
    at s in the frame of its cycle's start.  Each is measured as the mean over the recorded cycles
    (θ over every window, as :func:`measure_cycles`), so only the rotation's noise moves the choice;
    counting the cycles of a stretch from each point instead would pick the luckiest few.
    """
    poses, _ = _resampled(data, samples_per_cycle, gait_hz, False)
    spc = samples_per_cycle
    chords, inside, turns = [], [], []
    for p in poses:
        k = (p.shape[0] - 1) // spc
        if k < 1:
            continue
        starts = np.arange(k) * spc
        chords.append(se2.relative(p[starts], p[starts + spc])[:, :2])
        inside.append(se2.relative(p[starts][:, None, :], p[starts[:, None] + np.arange(spc)[None]])[..., :2])
        turns.append(p[spc:k * spc + 1, 2] - p[:k * spc + 1 - spc, 2])
    if not chords:
        return 0
    g_c = np.append(np.concatenate(chords).mean(axis=0), np.mean(np.concatenate(turns)))
    return int(np.argmax(origin_chords(g_c, np.concatenate(inside).mean(axis=0))))


def _resampled(data: Recording | Sequence[Recording], samples_per_cycle: int, gait_hz: float,
               work: bool) -> tuple[list[FloatArray], list[tuple[FloatArray, FloatArray]]]:
    """Each recording's pose (and with ``work`` its actuated angles and efforts) on ``samples_per_cycle`` per cycle."""
    recs = list(data) if isinstance(data, (list, tuple)) else [data]
    dt = 1.0 / (gait_hz * samples_per_cycle)
    poses, drives = [], []
    for rec in recs:
        t, p = np.asarray(rec.pose_t, dtype=float), np.asarray(rec.pose, dtype=float)
        if t.size > 1 and np.allclose(np.diff(t), dt, rtol=1e-6, atol=0):
            grid = t
            poses.append(p)
        else:
            n = int(math.floor((t[-1] - t[0]) / dt + 1e-9)) + 1 if t.size else 0
            grid = t[0] + dt * np.arange(n) if n else t
            poses.append(np.column_stack([np.interp(grid, t, p[:, 0]), np.interp(grid, t, p[:, 1]),
                                          np.interp(grid, t, p[:, 2])]))
        if work:
            ts = np.asarray(rec.t, dtype=float)
            ra, tau = actuator_drive(rec)
            same = ts.shape == grid.shape and np.array_equal(ts, grid)
            drives.append((ra, tau) if same else tuple(
                np.column_stack([np.interp(grid, ts, a[:, j]) for j in range(a.shape[1])]) for a in (ra, tau)))
    return poses, drives


@dataclass(frozen=True)
class LoopIteration:
    """One gait run on the robot.

    Attributes
    ----------
    index : int, 0 for the start gait.
    gait : Gait, the gait run.
    cycles : int, cycles run for it (settling included); cycles_used : int, running total.
    predicted, predicted_std : float or None, the model's prediction of its objective (std over draws).
    predicted_incumbent : float or None, the same model's prediction for the gait it would replace.
    measured : Measurement.
    accepted : bool, whether it became (or, for the start, is) the incumbent.
    trust : float or None, the radius κ of the step that proposed it; trust_used : float or None.
    note : str, why accepted or not.
    """

    index: int
    gait: Gait
    cycles: int
    cycles_used: int
    predicted: float | None
    predicted_std: float | None
    predicted_incumbent: float | None
    measured: Measurement
    accepted: bool
    trust: float | None
    trust_used: float | None
    note: str


@dataclass(frozen=True)
class LoopResult:
    """What :func:`optimize_loop` returns.

    Attributes
    ----------
    gait : Gait, the best gait measured (``objective``, ``predicted`` set when a model predicted it).
    measured : Measurement of it; predicted : float or None, the model's prediction of it.
    predicted_std : float or None, the prediction's spread over ``RESULT_DRAWS`` coefficient draws of the
        model that made it (None: no draws).  A model of few cycles on a robot that barely moves predicts
        far off its measured value, and says so here; the model's bias where it extrapolates is not in it.
    index : int, the iteration that ran it.
    iterations : tuple of LoopIteration; cycles_used : int; stopped : str, why the loop ended.
    limits : GaitLimits; seconds : float.
    changes : tuple of int, the iterations at which the search took the robot to have changed.
    """

    gait: Gait
    measured: Measurement
    predicted: float | None
    index: int
    iterations: tuple[LoopIteration, ...]
    cycles_used: int
    stopped: str
    limits: GaitLimits
    seconds: float
    changes: tuple[int, ...] = ()
    predicted_std: float | None = None


class _Robot:
    """The simulated robot as the loop sees it: run a gait for whole cycles, get a recording.

    ``changes``: (cycle, effects) pairs: from that many cycles run on, the robot is the nominal
    system with those catalogue effects (:meth:`StreamingSimulator.set_effects`); the loop is not told.
    """

    def __init__(self, system: SudsSystem, gait: Gait, cfg: LoopConfig,
                 changes: Sequence[tuple[int, Sequence[Mapping[str, object]]]] = ()) -> None:
        self.system, self.cfg = system, cfg
        self.spc = cfg.samples_per_cycle
        sim_cfg = SimConfig(cycles=1, samples_per_cycle=self.spc, gait_hz=gait.gait_hz, kappa=cfg.kappa,
                            ou_std=cfg.ou_std, noise_std=cfg.noise_std, warmup=0.0, seed=cfg.seed, gait=gait)
        self.sim = StreamingSimulator(system, sim_cfg, effort=cfg.objective == "efficiency")
        names = system.joint_names
        self.actuated = tuple(names[i] for i in system.actuated)
        self.passive = tuple(names[i] for i in system.passive)
        self.current: Gait | None = gait
        self.cycles_run = 0
        self.changes = sorted((int(c), list(e)) for c, e in changes)
        for c, e in self.changes:
            if c < 0:
                raise SudsConfigError(f"`changes`: expected cycles ≥ 0, got {c}")
            StreamingSimulator(system, sim_cfg).set_effects(e)  # a bad effect is refused before the run

    def run(self, gait: Gait, cycles: int) -> tuple[Recording, bool]:
        """``cycles`` cycles of ``gait`` (switched in at this cycle boundary); True if it was already running."""
        same = self.current is gait
        if not same:
            self.sim.set_gait(gait)
            self.current = gait
        chunks = []
        left = cycles
        while left:
            while self.changes and self.changes[0][0] <= self.cycles_run:
                self.sim.set_effects(self.changes.pop(0)[1])
            k = left if not self.changes else min(left, self.changes[0][0] - self.cycles_run)
            chunks.append(self.sim.step(k * self.spc))
            self.cycles_run += k
            left -= k
        t = np.concatenate([c.t for c in chunks])
        pose = np.concatenate([c.pose for c in chunks])
        r = np.concatenate([c.r for c in chunks])
        effort = None
        if self.sim.with_effort:  # as `suds simulate --effort` records it
            effort = effort_by_joint(self.system, np.concatenate([c.effort for c in chunks]))
        rec = Recording(t=t, r=r, joint_names=self.system.joint_names, actuated=self.actuated, passive=self.passive,
                        pose_t=t, pose=pose, system=self.system.name, gait_hz=gait.gait_hz, effort=effort)
        return rec, same


def _trim(rec: Recording, skip: int, spc: int) -> Recording:
    """The recording without its first ``skip`` cycles, from the last sample of the last skipped cycle."""
    start = max(skip * spc - 1, 0)
    return rec.slice(start, rec.n_samples)


def _change_start(miss: MotionMiss, limit: float) -> int | None:
    """Where a change began in a stretch: the first of its trailing cycles that each miss by more than ``limit``.

    None when its last cycle does not miss (a change persists: the stretch did not end on a changed robot).
    """
    over = np.asarray(miss.per_cycle) > limit
    if over.size == 0 or not over[-1]:
        return None
    return 0 if over.all() else int(over.size - np.argmin(over[::-1]))


def _from_cycle(rec: Recording, first: int, gait_hz: float) -> Recording:
    """The stretch from the start of its cycle ``first`` (it starts at a cycle boundary)."""
    t0 = rec.t[0] + first / gait_hz
    return rec.slice(int(np.searchsorted(rec.t, t0 - 1e-9 * max(1.0, abs(t0)))), rec.n_samples)


def _slow(m: Measurement, cfg: LoopConfig, speed_floor: float, floor_se: float) -> float:
    """How far a measured speed is under the floor, relative to it (0 within ``floor_sigmas`` se of the difference)."""
    if speed_floor <= 0 or m.speed >= speed_floor:
        return 0.0
    se = math.hypot(m.speed_se, floor_se)
    if math.isfinite(se) and speed_floor - m.speed <= cfg.floor_sigmas * se:
        return 0.0
    return (speed_floor - m.speed) / speed_floor


def _turned(m: Measurement, cfg: LoopConfig, sigmas: float | None = None) -> float:
    """How far a measured |rotation| is over the bound, rad/cycle (0 within ``sigmas`` se of it).

    ``sigmas``: ``cfg.rotation_sigmas`` unless given.
    """
    rot, rot_se = m.rotation_reading()
    over = abs(rot) - cfg.max_rotation
    sigmas = cfg.rotation_sigmas if sigmas is None else sigmas
    if over <= 0 or (math.isfinite(rot_se) and over <= sigmas * rot_se):
        return 0.0
    return over


def _feasible(m: Measurement, cfg: LoopConfig, speed_floor: float, floor_se: float = 0.0) -> tuple[bool, float]:
    """(within the spec's side bounds, how far outside them: rotation in rad/cycle, speed relative to the floor)."""
    off = _turned(m, cfg) if cfg.objective != "turn" else 0.0
    slow = _slow(m, cfg, speed_floor, floor_se) if cfg.objective != "speed" else 0.0
    return off == 0.0 and slow == 0.0, off + slow


def _infeasible_text(m: Measurement, cfg: LoopConfig, speed_floor: float, floor_se: float) -> str:
    """Which side bound a measurement breaks, in words."""
    parts = []
    if cfg.objective != "turn" and _turned(m, cfg) > 0:
        by = f" by over {cfg.rotation_sigmas:g} se" if cfg.rotation_sigmas > 0 else ""
        of = "the model of its cycles" if m.model_rotation is not None else "the mean of its cycles"
        parts.append(f"rotation |{m.rotation_reading()[0]:.3g}| rad/cycle ({of}) over the bound{by}")
    if cfg.objective != "speed" and _slow(m, cfg, speed_floor, floor_se) > 0:
        parts.append(f"measured speed {m.speed:.4g} m/s under the start gait's {speed_floor:.4g} by over "
                     f"{cfg.floor_sigmas:g} se")
    return "; ".join(parts)


def _sigmas(new: float, old: float, se_new: float, se_old: float, dof_new: float = math.inf,
            dof_old: float = math.inf) -> float:
    """|new − old| in standard errors of the difference (0 when they are not known).

    With standard errors estimated from few draws (``dof_*`` degrees of freedom, inf: known), the
    ratio is Welch's t; it is returned as the normal deviate of the same tail probability, so that
    a threshold in standard errors keeps its normal meaning (a t of 2.5 on 4 degrees of freedom is
    as likely as a normal deviate of 1.8).
    """
    se = math.hypot(se_new, se_old)
    if not (math.isfinite(se) and se > 0):
        return 0.0
    t = abs(new - old) / se
    den = (se_new ** 4 / dof_new if math.isfinite(dof_new) else 0.0) + \
        (se_old ** 4 / dof_old if math.isfinite(dof_old) else 0.0)
    if den <= 0 or t == 0:
        return t
    nu = se ** 4 / den  # Welch–Satterthwaite
    return float(-special.ndtri(special.stdtr(nu, -t)))


def _moved(new: Measurement, old: Measurement, cfg: LoopConfig) -> str:
    """How the same gait's new measurement left its standing one (speed or rotation), or '' if it did not."""
    ds = _sigmas(new.speed, old.speed, new.speed_se, old.speed_se, new.speed_dof, old.speed_dof)
    dr = _sigmas(new.rotation, old.rotation, new.rotation_se, old.rotation_se, new.value_dof("turn"),
                 old.value_dof("turn"))
    if max(ds, dr) <= cfg.change_sigmas:
        return ""
    if ds >= dr:
        return f"speed {new.speed - old.speed:+.4g} m/s ({ds:.1f} se)"
    return f"rotation {new.rotation - old.rotation:+.4g} rad/cycle ({dr:.1f} se)"


def _surprise(new: Measurement, old: Measurement, cfg: LoopConfig, speed_floor: float, floor_se: float) -> bool:
    """Whether a rejected candidate is far worse than the incumbent (a sign the robot changed).

    Far worse: its objective more than ``change_sigmas`` se lower, or outside the side bound by
    that much while the incumbent is within it.
    """
    obj = cfg.objective
    if _sigmas(new.value(obj), old.value(obj), new.value_se(obj), old.value_se(obj), new.value_dof(obj),
               old.value_dof(obj)) > cfg.change_sigmas and new.value(obj) < old.value(obj):
        return True
    if not _feasible(old, cfg, speed_floor, floor_se)[0] or _feasible(new, cfg, speed_floor, floor_se)[0]:
        return False
    if obj in ("turn", "efficiency") and new.speed < speed_floor \
            and _sigmas(new.speed, speed_floor, new.speed_se, floor_se) > cfg.change_sigmas:
        return True
    if obj == "turn" or abs(new.rotation) <= cfg.max_rotation:
        return False
    bound = math.copysign(cfg.max_rotation, new.rotation)
    return _sigmas(new.rotation, bound, new.rotation_se, 0.0) > cfg.change_sigmas


def is_better(new: Measurement, old: Measurement, cfg: LoopConfig, speed_floor: float = 0.0,
              floor_se: float = 0.0) -> bool:
    """Whether ``new`` beats ``old`` by measurement (feasible first, then the objective; see the module).

    ``speed_floor`` (m/s) and its standard error ``floor_se``: the start gait's measured speed, the
    floor of ``turn`` and ``efficiency``.
    """
    ok_new, viol_new = _feasible(new, cfg, speed_floor, floor_se)
    ok_old, viol_old = _feasible(old, cfg, speed_floor, floor_se)
    if ok_new != ok_old:
        return ok_new
    if not ok_new:
        return viol_new < viol_old
    gain = new.value(cfg.objective) - old.value(cfg.objective)
    if cfg.accept_sigmas > 0:
        se = math.hypot(new.value_se(cfg.objective), old.value_se(cfg.objective))
        if math.isfinite(se):
            return gain > cfg.accept_sigmas * se
    return gain > 0


@dataclass(frozen=True)
class RunRequest:
    """The next gait :class:`GaitSearch` wants run on the robot.

    Attributes
    ----------
    gait : Gait, the gait to switch to (at a cycle boundary) and run.
    cycles : int, cycles to run it: ``settle_cycles`` to discard, then the cycles to measure.
    kind : str, ``start``, ``candidate`` (a trust-region step), ``scale`` (the start scaled to its
        bounds, ``LoopConfig.scale_step``), ``reverse`` (the incumbent run backwards in time,
        ``LoopConfig.reverse_trial``), ``confirm`` (a candidate or reversed gait whose measured gain
        was within ``confirm_sigmas``, again), ``rerun`` (the incumbent again) or ``floor`` (the
        start gait again after a change: turn and efficiency keep its speed).
    origin : str, of a ``confirm``: the kind of the run it repeats (``candidate`` or ``reverse``).
    """

    gait: Gait
    cycles: int
    kind: str
    note: str = ""
    step: Any = None  # the DataStepResult of a candidate (its prediction), None otherwise
    origin: str = ""


@dataclass(frozen=True)
class ScaleStep:
    """The prediction of a ``scale`` or ``reverse`` run, in the fields :class:`GaitSearch` reads of a data step.

    value = s²·recorded_value (``LoopConfig.scale_step``); no model, so no spread, and no trust used.
    For a reversed gait (s = 1), the model's extrapolated prediction of it and of the incumbent.
    """

    factor: float
    value: float
    recorded_value: float
    trust_radius: float
    value_std: float | None = None
    trust_used: float = 0.0


def headroom(gait: Gait, limits: GaitLimits, s_max: float = 8.0) -> float:
    """The largest s ≤ ``s_max`` with the gait's offsets kept and its harmonics × s within the bounds.

    The speed bound is homogeneous in s; the range bound |o_j + s·h_j(t)| ≤ L_j is checked on the
    4096-point grid of :func:`~suds_ros.core.physics.gait.gait_extremes` and the result confirmed on
    the constraint grid (:func:`~suds_ros.core.physics.gait.constraint_violations`).
    """
    off, _, _ = gait.arrays()
    t = np.arange(4096) / (4096 * gait.gait_hz)
    h = gait.r(t) - off[None]
    v = np.abs(gait.rdot(t)).max(axis=0)
    lim, vlim = np.asarray(limits.limit, dtype=float), np.asarray(limits.speed_limit, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        up = np.where(h > 0, (lim - off)[None] / h, np.inf)
        down = np.where(h < 0, (lim + off)[None] / -h, np.inf)
        speed = np.where(v > 0, vlim / v, np.inf)
    s = float(min(s_max, np.min(up), np.min(down), np.min(speed))) * (1 - 1e-6)
    while s > 1.0 and constraint_violations(_scaled(gait, s), limits):
        s *= 0.999
    return s


def _scaled(gait: Gait, s: float) -> Gait:
    """The gait with its harmonics × s and its offsets kept."""
    m = gait.to_vector().reshape(len(gait.joints), 2 * gait.order + 1).copy()
    m[:, 1:] *= s
    return gait.from_vector(m.ravel(), gait.order, objective=None, predicted=())


class GaitSearch:
    """The run → fit → step search as ask/tell: :meth:`request` a gait, run it, :meth:`observe` its cycles.

    The offline loop (:func:`optimize_loop`) and the live ``optimizer`` node drive the same search;
    the search never sees the robot, only the recordings handed to :meth:`observe` (the measured
    cycles of the requested run, its settling cycles already cut).  Every requested run's cycles
    count against ``budget_cycles``.

    A robot that changes (damage, a new medium) makes the incumbent's measurement stale: every
    candidate is then judged against a value the robot no longer reaches.  So the incumbent is
    run again (a ``rerun``) when the trust region collapses, when the model predicts no gain, after
    two rejected candidates in a row that each measured more than ``change_sigmas`` standard errors
    below it, after a rejected candidate whose measured motion the model cannot explain along the
    candidate's own shapes (``model_miss``), after a rejected half-wave candidate on a robot that
    looked mirror-symmetric (where a half-wave gait runs straight) measured turning past the bound
    by more than ``change_sigmas`` standard errors, and when :meth:`robot_changed` is called (the
    live monitor's alarm).  A rerun that measures more than ``change_sigmas`` standard errors away from
    the standing measurement, or whose passive shapes differ from the standing stretches' at
    ``passive_alpha`` (on a robot without passive joints: whose motion misses the model of the
    standing data by ``model_miss``), or any rerun after :meth:`robot_changed`, *replaces* the incumbent's data:
    the old stretches are dropped (and the rerun's own cycles from before the change), and the
    model and the search start afresh on the changed robot.  Otherwise the
    stretches are pooled.  A candidate run again to confirm its gain is the same gait run again
    too, and gets the same tests against its first run: when they say the robot changed between
    the two, the candidate is not judged (its runs saw two robots) and the incumbent is measured
    afresh next, as after :meth:`robot_changed`.  For ``turn`` and ``efficiency``, whose floor is
    the start gait's speed, a change also has the start gait run again (a ``floor`` run, when the incumbent is another
    gait): the floor is its speed on the changed robot, and it becomes the incumbent again if it
    now measures better.

    Parameters
    ----------
    start : Gait
        The first gait run (within ``limits``).
    limits : GaitLimits
    config : LoopConfig
        Only its search fields are used here (the simulated robot's ``seed`` seeds the model draws).
    log : callable, optional
        Called with each :class:`LoopIteration` as it ends.
    """

    def __init__(self, start: Gait, limits: GaitLimits, config: LoopConfig, *,
                 log: Callable[[LoopIteration], None] | None = None) -> None:
        check_constraints(start, limits)
        self.config, self.limits, self._log = config, limits, log
        self.cycles_used = 0
        self.iterations: list[LoopIteration] = []
        self.stopped: str | None = None
        self._best_gait, self._best_data, self._best_index = start, [], 0
        self._start = start
        self._best_meas: Measurement | None = None
        self._best_pred: float | None = None
        self._pred_model: LearnedModel | None = None  # the model that made _best_pred (None: not a model's)
        self._speed_floor, self._floor_se = 0.0, 0.0
        self._work = config.objective == "efficiency"  # measure the actuators' work, learn their torques
        self._kappa = config.trust
        self._model: LearnedModel | None = None
        self._rejected: list[Gait] = []
        self._near: list[Recording] = []  # stretches of candidates rejected since the incumbent was set
        self._past: list[Recording] = []  # stretches of the earlier incumbents (pool_incumbents)
        self._low_streak = 0  # rejected candidates in a row that measured far below the incumbent
        self._fresh = False  # the next rerun replaces the incumbent's data (robot_changed)
        self._change_reason = ""
        self.changes: list[int] = []  # iterations at which a changed robot was taken
        self._pending: RunRequest | None = RunRequest(start, config.settle_cycles + config.first_cycles, "start",
                                                      "start gait")
        self._confirming: list[Recording] = []  # a candidate's first stretch while it is run again
        self._symmetric = False  # a half-wave gait of this robot measured straight: it looks mirror-symmetric
        self._strict = dataclasses.replace(config, rotation_sigmas=0.0)
        self._scale_tried = False  # the start scaled to its bounds was proposed (or could not be)
        self._reverse_tried = not config.reverse_trial  # the incumbent run backwards in time was proposed
        self._fits: list[tuple[tuple[Recording, ...], bool, LearnedModel]] = []  # the newest few (_learn)

    @property
    def best(self) -> Gait:
        """The incumbent: the best gait measured so far (the start gait before any measurement)."""
        return self._best_gait

    def robot_changed(self, reason: str) -> None:
        """Say the robot has changed: the incumbent is measured afresh next (its old data dropped).

        A run already requested stays requested (it may be running); the re-measurement follows it.
        Ignored before the start gait is measured and after the search stopped.
        """
        if self._best_meas is None or self.stopped is not None:
            return
        self._fresh = True
        self._change_reason = reason
        if self._pending is None:
            self._pending = self._rerun(f"robot changed: {reason}")

    @property
    def _step_cycles(self) -> int:
        """Cycles of every run after the start's: settling, then the measured ones."""
        return self.config.settle_cycles + self.config.step_cycles

    def _rerun(self, note: str) -> RunRequest | None:
        """The incumbent again, if the budget holds it (else the search stops)."""
        n = self._step_cycles
        if self.cycles_used + n > self.config.budget_cycles:
            self.stopped = f"{note}; no budget to re-run the incumbent"
            return None
        return RunRequest(self._best_gait, n, "rerun", note)

    def request(self) -> RunRequest | None:
        """The run wanted next (the same one until it is observed); None once the search has stopped."""
        if self._pending is None and self.stopped is None:
            self._pending = self._next()
        return self._pending

    def _next(self) -> RunRequest | None:
        """Fit the incumbent's model if needed and take one trust-region step (module docstring)."""
        cfg = self.config
        n = self._step_cycles
        if self.cycles_used + n > cfg.budget_cycles:
            self.stopped = (f"budget spent: a candidate needs {n} more cycles, "
                            f"{cfg.budget_cycles - self.cycles_used} left")
            return None
        trial = self._scale_request() or self._reverse_request()
        if trial is not None:
            return trial
        if self._model is None:
            self._model = self._learn([*self._best_data, *self._past, *self._near], torque=self._work)
        kappa = self._kappa
        # a robot whose half-wave incumbent runs off course is not symmetric: the full step, to bring it back
        half_wave = (cfg.half_wave and cfg.objective != "turn" and self._best_gait.is_half_wave()
                     and self._best_meas is not None and _turned(self._best_meas, self._rules(self._best_gait)) == 0.0)
        dcfg = DataOptimizeConfig(objective=cfg.objective, order=cfg.order, trust=kappa, draws=cfg.draws,
                                  min_gain_sigmas=cfg.min_gain_sigmas, seed=cfg.seed + len(self.iterations),
                                  max_rotation=cfg.max_rotation * cfg.rotation_margin, trust_centre=cfg.trust_centre,
                                  half_wave=half_wave)
        try:
            step = optimize_from_data(self._model, dcfg, limits=self.limits, start=self._best_gait)
        except (SudsDataError, FloatingPointError, np.linalg.LinAlgError) as exc:
            # the model of so few cycles has no steady state even at the incumbent: more data on it
            self._model = None
            return self._rerun(f"the incumbent's model cannot be used ({exc})")
        if self._best_pred is None:
            # (the step's recorded value counts the incumbent's cycle from the model's phase zero; its own zero:)
            self._best_pred, self._pred_model = predict_value(self._model, self._best_gait, cfg.objective), self._model
            self.iterations[self._best_index] = _with_prediction(self.iterations[self._best_index],
                                                                 self._best_pred, step.recorded_std)
        if not step.step_taken:
            if kappa >= cfg.trust:
                if len(self._best_data) < 2:
                    # a model of one short stretch that sees no gain anywhere is no evidence of an optimum
                    return self._rerun(f"the model of the incumbent's {self._best_meas.cycles} cycles predicts no "
                                       f"gain inside the trust region (κ = {kappa:.3g}): more of its cycles before "
                                       "calling it converged")
                converged = f"converged: the model predicts no gain inside the trust region (κ = {kappa:.3g})"
                if cfg.watch:
                    return self._rerun(f"{converged}; watching the incumbent")
                self.stopped = converged
                return None
            # a shrunken region with no predicted gain: more data on the incumbent instead
            return self._rerun(f"no gain predicted inside the shrunken trust region κ = {step.trust_radius:.3g}")
        cand = step.gait
        x = cand.to_vector(cfg.order)
        if any(np.allclose(x, g.to_vector(cfg.order), rtol=0, atol=1e-9) for g in self._rejected):
            self.stopped = ("no new step: the trust region cannot shrink further around the incumbent (it must hold "
                            "the incumbent's own offset from the template) and this gait was rejected before")
            return None
        check_constraints(cand, self.limits)  # never run a gait outside the bounds
        return RunRequest(cand, n, "candidate", step=step)

    def _scale_request(self) -> RunRequest | None:
        """The start gait scaled to its bounds, once, right after the start (``LoopConfig.scale_step``)."""
        cfg, gait, meas = self.config, self._best_gait, self._best_meas
        if (self._scale_tried or cfg.objective not in ("speed", "turn") or gait is not self._start
                or meas is None or not math.isfinite(cfg.scale_step)):
            return None
        self._scale_tried = True
        s = headroom(gait, self.limits)
        rot = meas.rotation_reading()[0]
        if cfg.objective == "speed" and not (self._symmetric and gait.is_half_wave()) and rot:
            s = min(s, math.sqrt(cfg.rotation_margin * cfg.max_rotation / abs(rot)))  # θ grows as s²
        if s < cfg.scale_step:
            return None
        cand = _scaled(gait, s)
        check_constraints(cand, self.limits)  # never run a gait outside the bounds
        if self._best_pred is None:  # the start's model prediction, as a trust-region step would have set it
            try:
                self._model = self._learn(self._best_data, torque=self._work)
                self._best_pred, self._pred_model = predict_value(self._model, gait, cfg.objective), self._model
                self.iterations[self._best_index] = _with_prediction(self.iterations[self._best_index],
                                                                     self._best_pred, None)
            except (SudsDataError, SudsConfigError, FloatingPointError, np.linalg.LinAlgError):
                self._model = None
        value = meas.value(cfg.objective)
        step = ScaleStep(factor=s, value=s * s * value, recorded_value=value, trust_radius=self._kappa)
        return RunRequest(cand, self._step_cycles, "scale", f"the start's oscillation × {s:.3g}, to its bounds",
                          step=step)

    def _reverse_request(self) -> RunRequest | None:
        """The incumbent backwards in time, once, after the scaled start, if its model (or most draws) predicts a gain.

        (``LoopConfig.reverse_trial``.)  The model of the incumbent's cycles predicts both drives; the
        reversed one lies far outside its data, so its prediction is only a hint, and the run judges.
        """
        if self._reverse_tried or self._best_meas is None:
            return None
        self._reverse_tried = True
        gait, objective = self._best_gait, self.config.objective
        if reversal_shift(gait) is not None:  # backwards it is the same drive: nothing to try
            return None
        cand = time_reversed(gait)
        if self._model is None:
            try:
                self._model = self._learn([*self._best_data, *self._past, *self._near], torque=self._work)
            except (SudsDataError, SudsConfigError, FloatingPointError, np.linalg.LinAlgError):
                return None  # (the trust-region step tries the fit again, or finds it unusable)
        try:
            here, there = predict_value(self._model, gait, objective), predict_value(self._model, cand, objective)
        except (SudsDataError, SudsConfigError, FloatingPointError, np.linalg.LinAlgError):
            return None  # no steady state for either drive: no hint (the fitted model is kept for the step)
        if self._best_pred is None:  # the incumbent's model prediction, as a trust-region step would have set it
            self._best_pred, self._pred_model = here, self._model
            self.iterations[self._best_index] = _with_prediction(self.iterations[self._best_index], here, None)
        why = ""
        if not there > here:  # the point prediction says no: ask its coefficient draws (far out, it is skewed)
            wins, told = reverse_odds(self._model, gait, objective, draws=RESULT_DRAWS, seed=self.config.seed)
            if not most_draws_faster(wins, told, RESULT_DRAWS):  # most draws expect nothing of it either
                return None
            why = f"; {wins} of {told} coefficient draws predict it faster"
        step = ScaleStep(factor=1.0, value=there, recorded_value=here, trust_radius=self._kappa)
        check_constraints(cand, self.limits)  # (the same range and speed: never outside the bounds)
        return RunRequest(cand, self._step_cycles, "reverse", "the incumbent backwards in time (the wave the "
                          f"other way{why})", step=step)

    def observe(self, data: Recording) -> LoopIteration:
        """Take the measured cycles of the requested run (settling cut) and decide; return its iteration.

        Raises
        ------
        SudsConfigError
            Nothing was requested (code ``no_request``), or ``data`` holds less than one cycle.
        """
        req = self._pending
        if req is None:
            raise SudsConfigError("`data`: expected the cycles of a requested run, but no run is requested "
                                  f"({self.stopped or 'call request() first'})", code=NO_REQUEST)
        meas = self._measure(data, req.gait)
        self._pending = None
        self.cycles_used += req.cycles
        if req.kind == "start":
            # turn, efficiency: no slower than the start gait (measured)
            self._speed_floor, self._floor_se = meas.speed, meas.speed_se
            self._symmetric = self._looks_symmetric(req.gait, meas)
            self._best_meas, self._best_data = meas, [data]
            it = LoopIteration(index=0, gait=req.gait, cycles=req.cycles, cycles_used=self.cycles_used,
                               predicted=None, predicted_std=None, predicted_incumbent=None, measured=meas,
                               accepted=True, trust=None, trust_used=None, note=req.note)
        elif req.kind == "rerun":
            it = self._rerun_done(req, meas, data)
        elif req.kind == "floor":
            it = self._floor_done(req, meas, data)
        elif req.kind == "confirm":
            first, self._confirming = self._confirming, []
            why = "" if self._fresh else self._changed_since(first, self._measure(first, req.gait), data, meas,
                                                             req.gait)[0]
            if why:  # the same gait run again: a change test as an incumbent's re-run is (_rerun_done)
                it = self._changed_in_confirmation(req, meas, why)
            else:
                stretches = [*first, data]
                it = self._judge(req, self._measure(stretches, req.gait), stretches)
        else:
            it = self._judge(req, meas, [data])
        self.iterations.append(it)
        if self._log is not None:
            self._log(it)
        return it

    def _changed_since(self, standing: list[Recording], old: Measurement, data: Recording,
                       meas: Measurement, gait: Gait) -> tuple[str, int]:
        """Whether a new stretch of a gait shows the robot changed since its ``standing`` stretches.

        Returns in words why ('' if it does not) and the stretch's first cycle on the changed robot:
        its measurement ``change_sigmas`` off the standing one; else, on a robot with passive joints,
        its passive shapes off theirs at ``passive_alpha``; else the standing stretches' model missing
        its motion along its own shapes by over ``model_miss``.
        """
        cfg = self.config
        moved = _moved(meas, old, cfg)
        if moved:
            return f"measured {moved} from its standing value", 0
        shift = None
        if data.passive and cfg.passive_alpha > 0:  # its passive shapes against the standing ones
            try:
                shift = passive_shift(standing, data, gait.gait_hz)
            except SudsDataError:  # (a cycle with too few shape samples: the body's test instead)
                shift = None
            if shift is not None and shift.p < cfg.passive_alpha and shift.start is not None:
                return (f"passive joint {shift.joint} ran {shift.size:.3g} rad (RMS over the cycle) off its shapes "
                        f"in the standing runs, p = {shift.p:.2g}"), shift.start
        if shift is None and math.isfinite(cfg.model_miss):
            try:  # the model of the standing data, on the new stretch of the same gait
                text, miss = self._miss(self._learn(standing, torque=self._work), data)
            except (SudsDataError, SudsConfigError, FloatingPointError, np.linalg.LinAlgError):
                text = ""
            start = _change_start(miss, cfg.model_miss) if text else None
            if start is not None:
                return text, start
        return "", 0

    def _rerun_done(self, req: RunRequest, meas: Measurement, data: Recording) -> LoopIteration:
        """Pool the incumbent's new stretch with its old ones, or replace them when the robot changed."""
        cfg, old = self.config, self._best_meas
        assert old is not None
        if self._fresh:
            why, first = f"said changed: {self._change_reason}", 0
        else:  # first: the stretch's first cycle on the changed robot
            why, first = self._changed_since(self._best_data, old, data, meas, req.gait)
        if why:
            note = f"incumbent re-run ({req.note}): the robot changed ({why}); its old data dropped"
            if first > 0:  # the change came inside this stretch: its cycles before it are the old robot's
                data = _from_cycle(data, first, req.gait.gait_hz)
                meas = self._measure(data, req.gait)
                note += f", and its own first {first} cycle{'s' if first > 1 else ''} (the robot before the change)"
            self._best_data, self._best_meas, self._best_pred, self._near = [data], meas, None, []
            self._past, self._pred_model = [], None
            self.changes.append(len(self.iterations))
            self._symmetric = self._looks_symmetric(req.gait, meas)  # the changed robot may not be
        else:  # pooled, the newest MAX_STRETCHES kept (a watching search re-runs its incumbent for ever)
            self._best_data = [*self._best_data, data][-MAX_STRETCHES:]
            self._best_meas = self._measure(self._best_data, req.gait)
            note = f"incumbent re-run ({req.note}): its {len(self._best_data)} stretches pooled, measured again"
        if self._best_gait is self._start:  # the floor is the start gait's speed: measured again
            self._speed_floor, self._floor_se = self._best_meas.speed, self._best_meas.speed_se
        elif why and cfg.objective != "speed":
            # the floor is the start gait's speed on the robot as it was: measure it on the changed one
            n = self._step_cycles
            if self.cycles_used + n <= cfg.budget_cycles:
                self._pending = RunRequest(self._start, n, "floor", "the start gait on the changed robot: "
                                                                    "its speed is the floor")
            else:
                self.stopped = "the robot changed and the budget cannot measure the speed floor on it again"
        self._fresh, self._low_streak = False, 0
        self._model, self._kappa, self._rejected = None, cfg.trust, []
        if why and self._pending is None and self._best_meas.cycles < cfg.step_cycles:
            self._pending = self._rerun(f"the changed robot measured for {self._best_meas.cycles} cycles only")
        it = LoopIteration(index=len(self.iterations), gait=self._best_gait, cycles=req.cycles,
                           cycles_used=self.cycles_used, predicted=self._best_pred, predicted_std=None,
                           predicted_incumbent=None, measured=self._best_meas, accepted=True, trust=None,
                           trust_used=None, note=f"{note}, model refitted, trust → {self._kappa:.3g}")
        self._best_index = it.index
        return it

    def _changed_in_confirmation(self, req: RunRequest, meas: Measurement, why: str) -> LoopIteration:
        """A candidate run again that shows the robot changed: not judged (its two runs saw two robots).

        The incumbent is measured afresh next, as after :meth:`robot_changed`: its standing data are the
        robot's before the change.
        """
        self.robot_changed(f"the candidate, run again to confirm its gain, {why}")
        step = req.step
        return LoopIteration(index=len(self.iterations), gait=req.gait, cycles=req.cycles,
                             cycles_used=self.cycles_used, predicted=step.value, predicted_std=step.value_std,
                             predicted_incumbent=step.recorded_value, measured=meas, accepted=False,
                             trust=step.trust_radius, trust_used=step.trust_used,
                             note=f"not judged: the robot changed while it was confirmed ({why}); the incumbent "
                                  "is measured afresh")

    def _floor_done(self, req: RunRequest, meas: Measurement, data: Recording) -> LoopIteration:
        """The start gait measured on a changed robot: the new speed floor; the incumbent if it now measures better."""
        cfg, old = self.config, self._best_meas
        assert old is not None
        self._speed_floor, self._floor_se = meas.speed, meas.speed_se
        taken = is_better(meas, old, self._rules(self._start), self._speed_floor, self._floor_se)
        note = f"{req.note}: floor → {meas.speed:.4g} m/s"
        if taken:
            self._take(self._start, meas, [data], None)
            self._kappa = cfg.trust
            note += "; it measures better than the incumbent, and is the incumbent again"
        return LoopIteration(index=len(self.iterations), gait=self._start, cycles=req.cycles,
                             cycles_used=self.cycles_used, predicted=None, predicted_std=None,
                             predicted_incumbent=None, measured=meas, accepted=taken, trust=None, trust_used=None,
                             note=note)

    def _miss(self, model: LearnedModel, data: Recording) -> tuple[str, MotionMiss]:
        """('' or in words how ``data``'s motion misses ``model`` along its own shapes beyond ``model_miss``; it)."""
        m = motion_miss(model, data)
        size = m.size()
        if size <= self.config.model_miss:
            return "", m
        if m.translation == size:
            return (f"moved {100 * m.translation:.0f} % of its translation away from the model's prediction along "
                    f"its own shapes ({m.translation_sigmas:.1f} se)"), m
        return (f"turned {m.rotation:.3g} rad/cycle away from the model's prediction along its own shapes "
                f"({m.rotation_sigmas:.1f} se)"), m

    def _take(self, gait: Gait, meas: Measurement, data: list[Recording], predicted: float | None,
              model: LearnedModel | None = None) -> None:
        """``gait`` becomes the incumbent (the iteration about to be logged): its data, a model to fit afresh.

        ``model``: the model that made ``predicted`` (None: not a model's, as a scaled start's s² law).
        """
        if self.config.pool_incumbents and self._best_meas is not None:  # (not the start's own first run)
            # the earlier incumbents' stretches, but none from before a change said while this one ran
            self._past = [] if self._fresh else [*self._past, *self._best_data][-self.config.pool_incumbents:]
        self._best_gait, self._best_meas, self._best_data, self._best_pred = gait, meas, data, predicted
        self._pred_model = model
        self._best_index = len(self.iterations)
        self._model, self._rejected, self._near, self._low_streak = None, [], [], 0

    def _measure(self, data: Recording | list[Recording], gait: Gait) -> Measurement:
        """The measurement of ``gait``'s cycles, with the model's rotation where the bound needs it and a model fits."""
        m = measure_recording(data, self.config.samples_per_cycle, gait.gait_hz, work=self._work)
        if self.config.objective == "turn" or not self.config.rotation_from_model:
            return m  # (turn: no straight-course bound, the turn is the objective, read from the cycles)
        # the spread is only read where the bound can be lax (_rules) or the start is judged symmetric
        draws = RESULT_DRAWS if gait.is_half_wave() and (self._best_meas is None or self._symmetric) else 0
        try:
            rot, sd = model_rotation(self._learn(data, torque=self._work), gait, draws=draws, seed=self.config.seed)
        except (SudsDataError, SudsConfigError, FloatingPointError, np.linalg.LinAlgError):
            return m  # (too few cycles, or a model with no steady state: the mean of the cycles)
        return dataclasses.replace(m, model_rotation=rot, model_rotation_se=sd)

    def _learn(self, data: Recording | Sequence[Recording], torque: bool) -> LearnedModel:
        """:func:`learn_model` of ``data``, fitted once: the same stretches (the same objects) give the same model.

        A measurement's model is fitted to the stretches the step's model is then fitted to (the new
        incumbent's, before any rejection and without earlier incumbents' stretches: ``pool_incumbents``
        = 0), so those are fitted once.
        """
        recs = (data,) if isinstance(data, Recording) else tuple(data)
        for seen, tq, model in self._fits:
            if tq == torque and len(seen) == len(recs) and all(a is b for a, b in zip(seen, recs)):
                return model
        ident = None if self.config.random_features else IdentifyConfig(kernel_grid=(0,))
        model = learn_model(list(recs), torque=torque, frame=self.config.body_frame, config=ident)
        self._fits = [*self._fits[-3:], (recs, torque, model)]
        return model

    def _rules(self, gait: Gait) -> LoopConfig:
        """The config a measurement of ``gait`` is judged by: ``rotation_sigmas`` only on a symmetric-looking robot.

        A half-wave gait runs straight on a mirror-symmetric robot, so there a measured rotation over the
        bound by a standard error or so is the measurement's noise.  A robot whose half-wave start measured
        a rotation beyond ``rotation_sigmas`` of its standard error (a bent spring, a current) is not
        symmetric, and neither is a gait that is not half-wave: there the bound is the measured number.
        """
        return self.config if self._symmetric and gait.is_half_wave() else self._strict

    def _looks_symmetric(self, gait: Gait, m: Measurement) -> bool:
        """Whether ``gait`` is half-wave and measured straight (|rotation| within ``rotation_sigmas`` se of 0)."""
        cfg = self.config
        rot, rot_se = m.rotation_reading()
        return (cfg.objective != "turn" and gait.is_half_wave() and math.isfinite(rot_se)
                and abs(rot) <= cfg.rotation_sigmas * rot_se)

    def _feasible(self, m: Measurement, gait: Gait) -> bool:
        return _feasible(m, self._rules(gait), self._speed_floor, self._floor_se)[0]

    def _judge(self, req: RunRequest, meas: Measurement, stretches: list[Recording]) -> LoopIteration:
        """Accept, confirm or reject a candidate by its measurement; schedule a re-run when the region collapsed."""
        cfg, step, cand = self.config, req.step, req.gait
        kind = req.origin or req.kind  # (a confirmation is judged as the run it repeats)
        old = self._best_meas
        assert old is not None
        rules = self._rules(cand)
        accepted = is_better(meas, old, rules, self._speed_floor, self._floor_se)
        pred_gain = step.value - step.recorded_value
        meas_gain = meas.value(cfg.objective) - old.value(cfg.objective)
        kappa_used = step.trust_radius
        confirm = ""
        marginal = (req.kind in ("candidate", "reverse") and cfg.confirm_sigmas > 0
                    and self._feasible(old, self._best_gait))
        se = math.hypot(meas.value_se(cfg.objective), old.value_se(cfg.objective))
        if accepted and marginal and se != 0:  # (se 0: exact measurements, nothing to confirm)
            z = abs(meas_gain) / se if math.isfinite(se) else 0.0  # (as _sigmas, on the se just taken)
            # NaN with an unknown se: then the measured gain alone decides; a reversed gait's prediction is an
            # extrapolation far outside the model's data (a hint to try it, not a reason to believe a reading)
            z_pred = pred_gain / se if req.kind == "candidate" else math.nan
            if z < cfg.confirm_sigmas and not z_pred >= cfg.confirm_sigmas:
                if self.cycles_used + self._step_cycles <= cfg.budget_cycles:
                    self._confirming = list(stretches)
                    self._pending = RunRequest(cand, self._step_cycles, "confirm",
                                               f"measured gain {meas_gain:+.4g} ({z:.2f} se): run again", step=step,
                                               origin=req.kind)
                    return LoopIteration(index=len(self.iterations), gait=cand, cycles=req.cycles,
                                         cycles_used=self.cycles_used, predicted=step.value,
                                         predicted_std=step.value_std, predicted_incumbent=step.recorded_value,
                                         measured=meas, accepted=False, trust=kappa_used,
                                         trust_used=step.trust_used,
                                         note=f"to be confirmed: measured gain {meas_gain:+.4g} is {z:.2f} se "
                                              f"(< {cfg.confirm_sigmas:g}); run again before it is kept")
                accepted, confirm = False, f"gain {z:.2f} se unconfirmed: no budget to run it again"
        if accepted:
            ratio = meas_gain / pred_gain if pred_gain > 0 else float("nan")
            grew = ratio >= 0.5 and step.trust_used >= 0.9 * step.trust_radius
            note = f"accepted: measured gain {meas_gain:+.4g} vs predicted {pred_gain:+.4g}"
            if kind == "reverse":
                what = req.note if req.kind == "reverse" else "the incumbent backwards in time, run again"
                note = f"accepted ({what}): measured gain {meas_gain:+.4g} vs predicted {pred_gain:+.4g}"
            if grew:
                self._kappa = min(self._kappa * cfg.grow, cfg.trust_max)
                note += f"; trust grows to {self._kappa:.3g}"
            elif ratio < POOR_RATIO and self._kappa > cfg.trust:
                # a gain, but far short of the prediction: the model was wrong that far out
                self._kappa = max(self._kappa * cfg.shrink, cfg.trust)
                note += f"; under {POOR_RATIO:g} of the prediction, trust → {self._kappa:.3g}"
            if kind == "reverse":  # (no model predicted it: the next step's model will)
                self._take(cand, meas, list(stretches), None)
            else:
                self._take(cand, meas, list(stretches), step.value, None if req.kind == "scale" else self._model)
            self._fresh = False  # measured on the robot as it is now
        elif kind in ("scale", "reverse"):  # the search goes on as if it was not tried
            why = confirm or ("measured objective not higher" if self._feasible(meas, cand)
                              else _infeasible_text(meas, rules, self._speed_floor, self._floor_se))
            what, left = ("scaled start", "start") if kind == "scale" else ("reversed gait", "incumbent")
            note = (f"{what} rejected ({why}; measured gain {meas_gain:+.4g} vs predicted {pred_gain:+.4g}); "
                    f"the search goes on from the {left}")
            if self._fresh:  # robot_changed() while it ran: the start is measured afresh first
                self._pending = self._rerun(f"robot changed: {self._change_reason}")
        else:
            miss = ""
            if self._model is not None and math.isfinite(cfg.model_miss) and not self._fresh \
                    and step.trust_radius <= MISS_TRUST:
                try:  # judged on the model the step was planned on (inside its data's spread)
                    miss = self._miss(self._model, stretches[-1])[0]
                except (SudsDataError, SudsConfigError):
                    miss = ""
            self._kappa *= cfg.shrink
            self._rejected.append(cand)
            if cfg.pool_rejected:  # its cycles join the incumbent's model: refitted for the next step
                self._near = [*self._near, *stretches][-cfg.pool_rejected:]
                self._model = None
            why = (confirm or "measured objective not higher" if self._feasible(meas, cand)
                   else _infeasible_text(meas, rules, self._speed_floor, self._floor_se))
            note = (f"rejected ({why}; measured gain {meas_gain:+.4g} vs predicted {pred_gain:+.4g}); "
                    f"trust → {self._kappa:.3g}")
            low = _surprise(meas, old, rules, self._speed_floor, self._floor_se)
            self._low_streak = self._low_streak + 1 if low else 0
            rerun = None
            if self._fresh:
                rerun = f"robot changed: {self._change_reason}"
            elif miss:
                rerun = f"the candidate {miss}: is the robot still the one modelled?"
            elif (self._symmetric and cand.is_half_wave() and _turned(meas, rules, cfg.change_sigmas) > 0
                  and self._feasible(old, self._best_gait)):
                # a half-wave gait cannot turn on a mirror-symmetric robot: this one is not, or no longer
                rerun = (f"a half-wave gait measured turning {meas.rotation_reading()[0]:+.3g} rad/cycle, over "
                         f"the bound by over {cfg.change_sigmas:g} se, on a robot that looked mirror-symmetric: "
                         "is it still?")
            elif self._low_streak >= 2:
                rerun = (f"two candidates in a row measured over {cfg.change_sigmas:g} se below the incumbent: "
                         "is it still as good?")
            elif self._kappa < cfg.trust_min:
                rerun = f"trust region below {cfg.trust_min:g} σ after rejected steps"
            if rerun is not None:
                self._pending = self._rerun(rerun)
        return LoopIteration(index=len(self.iterations), gait=cand, cycles=req.cycles, cycles_used=self.cycles_used,
                             predicted=step.value, predicted_std=step.value_std,
                             predicted_incumbent=step.recorded_value, measured=meas, accepted=accepted,
                             trust=kappa_used, trust_used=step.trust_used, note=note)

    def result(self, seconds: float = float("nan")) -> LoopResult:
        """The best gait measured, with the model's prediction of it (fitted now if no step was taken).

        Raises
        ------
        SudsConfigError
            Nothing was measured yet (code ``no_request``).
        """
        if self._best_meas is None:
            raise SudsConfigError("`result`: expected at least the start gait's cycles observed, got none",
                                  code=NO_REQUEST)
        cfg = self.config
        if self._best_pred is None:  # no step was taken (the budget held only the start): the model's view anyway
            self._pred_model = self._learn(self._best_data, torque=self._work)
            self._best_pred = predict_value(self._pred_model, self._best_gait, cfg.objective)
            self.iterations[self._best_index] = _with_prediction(self.iterations[self._best_index],
                                                                 self._best_pred, None)
        pred = self._best_pred
        gait, meas = self._best_gait, self._best_meas
        pred_std = None
        if self._pred_model is not None and pred is not None:
            pred_std = predicted_std(self._pred_model, gait, cfg.objective, seed=cfg.seed)
        if (cfg.objective != "turn" and math.isfinite(meas.rotation_se)
                and abs(meas.rotation) > cfg.origin_sigmas * meas.rotation_se):
            # it turns: count its cycle from the point it went furthest from (the same motion; its measured
            # speed counts every point of the cycle alike, so it stays)
            j = measured_origin(self._best_data, cfg.samples_per_cycle, gait.gait_hz)
            if j:
                # the prediction counted from there too: its model's distance from that point over from zero
                u = j / cfg.samples_per_cycle
                try:
                    model = (self._pred_model if self._pred_model is not None
                             else self._learn(self._best_data, torque=self._work))
                    ratio = origin_ratio(model, gait, u)
                    pred, pred_std = pred * ratio, None if pred_std is None else pred_std * ratio
                except (SudsDataError, SudsConfigError, FloatingPointError, np.linalg.LinAlgError):
                    pass  # (the model cannot say: the prediction stays that of the cycle from zero)
                gait = time_shifted(gait, u)
        out = with_predicted(gait, cfg.objective, {cfg.objective: pred})
        return LoopResult(gait=out, measured=meas, predicted=pred, index=self._best_index,
                          iterations=tuple(self.iterations), cycles_used=self.cycles_used,
                          stopped=self.stopped or "stopped by the caller", limits=self.limits, seconds=seconds,
                          changes=tuple(self.changes), predicted_std=pred_std)


def optimize_loop(system: SudsSystem, config: LoopConfig, *, start: Gait | None = None,
                  limits: GaitLimits | None = None,
                  log: Callable[[LoopIteration], None] | None = None,
                  changes: Sequence[tuple[int, Sequence[Mapping[str, object]]]] = (),
                  search: Callable[..., GaitSearch] = GaitSearch) -> LoopResult:
    """Run → fit → step on the simulated ``system`` until ``config.budget_cycles`` are spent (module docstring).

    Parameters
    ----------
    system : SudsSystem
        The simulated robot (only its recorded streams reach the optimiser).
    config : LoopConfig
    start : Gait, optional
        The first gait run (default: the robot's nominal gait).
    limits : GaitLimits, optional
        Joint bounds (default :func:`~suds_ros.core.physics.gait.gait_limits` of the robot).
    log : callable, optional
        Called with each :class:`LoopIteration` as it ends.
    changes : sequence of (cycle, effects)
        The robot changes mid-run, unannounced: from ``cycle`` cycles run on it is the nominal
        system with ``effects`` (catalogue effects, ``shared/spec/effects.md``; ``[]``: nominal again).
    search : callable
        Makes the search, called as ``search(start, limits, config, log=log)``: :class:`GaitSearch`, or
        a subclass (``benchmarks/optimize_loop.py`` judges every run on the true physics with one).

    Raises
    ------
    SudsConfigError
        A start gait of other joints, or outside the bounds (code ``gait_constraint``); a bad change.
    """
    t0 = time.perf_counter()
    cfg = config
    gait = nominal_gait(system) if start is None else check_gait(start, system, "start")
    limits = gait_limits(system) if limits is None else limits
    run = search(gait, limits, cfg, log=log)
    robot = _Robot(system, gait, cfg, changes)
    while (req := run.request()) is not None:
        rec, _ = robot.run(req.gait, req.cycles)
        run.observe(_trim(rec, cfg.settle_cycles, robot.spc))
    return run.result(seconds=time.perf_counter() - t0)


def predict_value(model: LearnedModel, gait: Gait, objective: str, coef: FloatArray | None = None) -> float:
    """The learned model's objective of ``gait`` at its predicted passive periodic steady state (turn as |rate|).

    Counted from the gait's own time zero, as the spec counts a cycle: the model's cycle runs from
    its phase zero, which is the gait's time :func:`~suds_ros.core.optimize.data.align_shift`, and a
    turning cycle's distance depends on where it is counted from (:func:`origin_ratio`).
    ``coef``: coefficients to predict with instead of the model's (a draw, :meth:`LearnedModel.draw`).
    """
    value, d, s0 = _model_cycle(model, gait, objective, coef)
    return value if d is None else value * _chord_at(d, -s0) / max(float(d[0]), 1e-300)


def predicted_std(model: LearnedModel, gait: Gait, objective: str, draws: int = RESULT_DRAWS,
                  seed: int = 0) -> float | None:
    """The spread of :func:`predict_value` over ``draws`` coefficient draws of ``model`` (:func:`draw_spread`).

    The draws come from the coefficients' covariance (:meth:`LearnedModel.draw`, seeded by ``seed``);
    a draw with no steady state is left out.  None when the model carries no covariance or fewer
    than two draws predict.
    """
    return _spread_over_draws(model, lambda coef: predict_value(model, gait, objective, coef=coef), draws, seed)


def _spread_over_draws(model: LearnedModel, value: Callable[[FloatArray], float], draws: int,
                       seed: int) -> float | None:
    """:func:`draw_spread` of ``value(coef)`` over ``draws`` seeded coefficient draws of ``model``.

    A draw with no steady state (an error, or a non-finite value) is left out.  None when the model
    carries no covariance, or fewer than two draws give a value.
    """
    return draw_spread(_draw_values(model, value, draws, seed)) if draws >= 2 else None


def _draw_values(model: LearnedModel, value: Callable[[FloatArray], float], draws: int,
                 seed: int) -> list[float]:
    """The finite values of ``value(coef)`` over ``draws`` coefficient draws of ``model``, seeded by ``seed``.

    A draw whose value raises (no steady state: :class:`SudsDataError`, a floating-point or linear-algebra
    error) or is not finite is left out; none when the model carries no covariance.
    """
    if not model.has_draws:
        return []
    rng = np.random.default_rng(seed)
    values = []
    for _ in range(draws):
        try:
            with np.errstate(over="ignore", invalid="ignore"):  # (a draw far off: non-finite, left out)
                values.append(value(model.draw(rng)))
        except (SudsDataError, FloatingPointError, np.linalg.LinAlgError):
            continue
    return [v for v in values if math.isfinite(v)]


def reverse_odds(model: LearnedModel, gait: Gait, objective: str, draws: int = RESULT_DRAWS,
                 seed: int = 0) -> tuple[int, int]:
    """Of ``draws`` seeded coefficient draws of ``model``, how many predict ``gait`` run backwards in time better.

    Returns (draws that predict the reversed drive's objective higher, draws that predict both).  A
    draw with no steady state for either drive, or a non-finite value, is left out of both counts.
    (0, 0) when the model carries no covariance.  Each draw predicts both drives with the same
    coefficients, so the count is of the comparison, not of two independent spreads.
    """
    back = time_reversed(gait)

    def faster(coef: FloatArray) -> float:  # +1 the reversed drive higher, -1 not; NaN: no comparison
        try:
            here = predict_value(model, gait, objective, coef=coef)
            there = predict_value(model, back, objective, coef=coef)
        except SudsConfigError:
            return math.nan
        return (1.0 if there > here else -1.0) if math.isfinite(here) and math.isfinite(there) else math.nan

    said = _draw_values(model, faster, draws, seed)
    return sum(v > 0 for v in said), len(said)


def most_draws_faster(wins: int, told: int, draws: int = RESULT_DRAWS) -> bool:
    """Whether :func:`reverse_odds`'s counts say the reversed drive is faster.

    More than half of the draws that predict both drives say so, and at least half of the ``draws``
    predict.
    """
    return 2 * told >= draws and 2 * wins > told


def draw_spread(values: Sequence[float]) -> float | None:
    """A robust sd of values drawn from a model's coefficients: the normal-scaled median absolute deviation.

    The finite values only; None for fewer than two.  A few cycles' model can have draws that
    predict far off (near a gait with no steady state, or where a passive joint's fit is poor): the
    sample sd follows those and says nothing of the rest (a random 5-link robot's prediction
    read 0.28 ± 8.7 m/s by the sd, before the residual variance counted the ridge fit's effective
    parameters), the median absolute deviation does not, and for normal draws
    it estimates the same sd.
    """
    from scipy import stats

    v = np.asarray([x for x in values if math.isfinite(x)], dtype=float)
    return float(stats.median_abs_deviation(v, scale="normal")) if v.size > 1 else None


def origin_ratio(model: LearnedModel, gait: Gait, at: float) -> float:
    """The model's distance per cycle of ``gait`` counted from its time ``at`` (cycles) over that from its zero.

    1 for a cycle the model predicts straight.  The objectives that scale with the distance (speed,
    efficiency) scale with it when a turning gait is counted from another point
    (:func:`~suds_ros.core.physics.gait.time_shifted` by ``at``).
    """
    _, d, s0 = _model_cycle(model, gait, "speed")
    return 1.0 if d is None else _chord_at(d, at - s0) / max(_chord_at(d, -s0), 1e-300)


def _model_cycle(model: LearnedModel, gait: Gait, objective: str,
                 coef: FloatArray | None = None) -> tuple[float, FloatArray | None, float]:
    """(objective counted from the model's phase zero, distances from each step of it or None if straight, s0).

    ``objective`` may also be ``rotation``: the signed net rotation per cycle (no distances).
    """
    s0 = align_shift(model, gait)
    g = time_shifted(gait, s0)
    ev = LearnedCycle(model, g.gait_hz, g.order, work=objective == "efficiency", coef=coef)
    x = g.to_vector()
    res = ev.steady_of(x)
    vals = objective_values(res, g.gait_hz)
    if objective in ("turn", "rotation"):
        return float(abs(vals["turn"][0]) if objective == "turn" else vals["rotation"][0]), None, s0
    d = origin_distances(ev, x, res) if res.g_c[0, 2] != 0.0 else None  # type: ignore[arg-type]
    return float(vals[objective][0]), d, s0


def _chord_at(d: FloatArray, at: float) -> float:
    """The distances ``d`` (from each of n step times k/n) interpolated linearly at ``at`` cycles (periodic)."""
    return float(np.interp(at, np.arange(d.size) / d.size, d, period=1.0))


def _with_prediction(it: LoopIteration, value: float, std: float | None) -> LoopIteration:
    return LoopIteration(index=it.index, gait=it.gait, cycles=it.cycles, cycles_used=it.cycles_used,
                         predicted=value, predicted_std=std, predicted_incumbent=it.predicted_incumbent,
                         measured=it.measured, accepted=it.accepted, trust=it.trust, trust_used=it.trust_used,
                         note=it.note)


def model_rotation(model: LearnedModel, gait: Gait, draws: int = RESULT_DRAWS,
                   seed: int = 0) -> tuple[float, float | None]:
    """The model's net rotation per cycle of ``gait`` at its steady state (δ = 0; signed, rad) and its spread.

    The value is the rotation of the model's periodic steady state along ``gait``, counted from the
    gait's own time zero.  Fitted to the measured cycles, the regression takes out the part of each
    cycle's rotation that the perturbation δ explains, so this reads the gait's own rotation more
    precisely than the mean of the cycles (``docs/results/optimize_rotation.md``).  The spread is
    :func:`draw_spread` of the value over ``draws`` seeded coefficient draws
    (:meth:`LearnedModel.draw`), leaving out draws with no steady state.  None where the model
    carries no covariance or fewer than two draws have a steady state.
    """
    def rot(coef: FloatArray | None = None) -> float:
        return _model_cycle(model, gait, "rotation", coef)[0]

    value = rot()
    if not math.isfinite(value):
        raise SudsDataError("`model`: the model's steady-state rotation is not finite", code="no_steady_state")
    return value, _spread_over_draws(model, rot, draws, seed)
