"""Choosing the effects: stepwise selection on held-out evidence, with a backward check.

Evidence of a set S of effects is its held-out log-likelihood gain over the nominal model minus
the BIC penalty (p/2)·log n_eff (:class:`~suds_ros.core.diagnosis.naming.Scorer`).  Forward
step: every candidate compatible with S is fitted added to S (first as a screen: a short
least-squares run of every parameter from S's fit and the candidate's own single fit; the
leading ``config.step_candidates`` are then refitted fully); the best is kept
if its evidence gain over S exceeds ``config.evidence_threshold`` (the first effect needs only a
positive gain: the located mismatch already passed the noise-floor test).  Backward check after
each step: a member whose removal costs less than the threshold no longer earns its place and is
dropped.  At most ``config.max_effects`` effects.  Candidates within the confounding margin of the
step's winner are reported as confounded with it.  The threshold is judged on its own (a
likelihood ratio against the model without the effect), never relative to another effect's
gain; its calibration on null recordings is in ``docs/results/evidence_threshold.md``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.diagnosis.data import Data
from suds_ros.core.diagnosis.naming import Candidate, Scorer, catalogue_candidates
from suds_ros.core.diagnosis.report import CandidateScore, DiagnoseConfig, effect_label
from suds_ros.core.parallel import fork_map
from suds_ros.core.physics.effects import EFFECTS
from suds_ros.core.physics.rft import ChainModel


@dataclass(frozen=True, eq=False)
class Ranked:
    """A fitted candidate: its held-out evidence, the candidate and its fitted parameters."""

    score: CandidateScore
    cand: Candidate
    x: FloatArray


@dataclass(frozen=True)
class Naming:
    """Outcome of the naming stage.

    ``ranking``: every fitted candidate's evidence (best first); ``chosen``: the selected set;
    ``confounded``: per step with a near tie, the labels of the effects that explain the data about
    equally well (the chosen one first); ``evidence``: per member of ``chosen`` (in its order), the
    evidence lost when that member is left out, nats; ``steps``: a log of the selection;
    ``gains``: the best evidence gain found at each forward step tried (the last one may have
    failed the threshold), nats; ``alternatives``: the selections started from the first step's
    runners-up (:func:`_alternatives`), for the simulator to arbitrate; ``fits``: every candidate
    fitted on the way, by label (its best fit), e.g. to start a swap of confounded members from;
    ``rejected``: the leading sets of the step that failed the threshold (at most
    ``config.extend_max``, best first), for the simulator to judge.
    """

    ranking: tuple[CandidateScore, ...]
    chosen: Ranked
    confounded: tuple[tuple[str, ...], ...]
    evidence: tuple[float, ...] = ()
    steps: tuple[str, ...] = ()
    gains: tuple[float, ...] = ()
    alternatives: tuple["_Path", ...] = ()
    fits: Mapping[str, Ranked] = field(default_factory=dict)
    rejected: tuple[Ranked, ...] = ()


class _Selector:
    """Fits candidate sets with a shared :class:`Scorer` and keeps every result for the ranking."""

    def __init__(self, scorer: Scorer, config: DiagnoseConfig) -> None:
        self.scorer = scorer
        self.config = config
        self.pen_unit = scorer.pen_unit
        self.fitted: dict[str, Ranked] = {}
        self.calibration: _Calibration | None = None

    def ranked(self, cand: Candidate, x: FloatArray, g_te: float) -> Ranked:
        r = Ranked(CandidateScore(cand.label, tuple(cand.effects(x)), x.size, g_te, self.pen_unit * x.size), cand, x)
        old = self.fitted.get(cand.label)
        if old is None or r.score.score > old.score.score:
            self.fitted[cand.label] = r
        return r

    def fit(self, cand: Candidate, x0: FloatArray | None = None) -> Ranked:
        x, _, g_te = self.scorer.fit(cand, x0)
        return self.ranked(cand, x, g_te)

    def _fits(self, jobs: Sequence[tuple[Candidate, FloatArray | None, bool]]) -> list[tuple[FloatArray, float]]:
        """(parameters, held-out gain) of each (candidate, start, quick), in worker processes.

        As many as :func:`suds_ros.core.parallel.workers` allows (``DiagnoseConfig.jobs`` within
        :func:`~suds_ros.core.diagnosis.pipeline.diagnose`); the results do not depend on it.
        """
        def one(job: tuple[Candidate, FloatArray | None, bool]) -> tuple[FloatArray, float]:
            x, _, g_te = self.scorer.fit(job[0], job[1], quick=job[2])
            return x, g_te

        return fork_map(one, jobs)

    def fit_many(self, jobs: Sequence[tuple[Candidate, FloatArray | None]]) -> list[Ranked]:
        """:meth:`fit` of each (candidate, start), in order (in worker processes, as :meth:`_fits`)."""
        out = self._fits([(c, x0, False) for c, x0 in jobs])
        return [self.ranked(c, x, g_te) for (c, _), (x, g_te) in zip(jobs, out)]

    def fit_quick(self, cand: Candidate, x0: FloatArray) -> Ranked:
        """One short least-squares run of ``cand`` from ``x0`` (no multi-start)."""
        x, _, g_te = self.scorer.fit(cand, x0, quick=True)
        return self.ranked(cand, x, g_te)

    def extend(self, cur: Ranked, singles: Sequence[Ranked]) -> list[Ranked]:
        """Every compatible single added to ``cur``: screened by a short joint fit, the best refitted fully.

        The screen moves ``cur``'s parameters too.  With them held, an effect that corrects a
        member's bias earns nothing: a Coulomb friction fitted alone at 0.77 beside an unseen
        drag anisotropy (true 0.66) left the anisotropy no gain at all with the friction held,
        while a joint step from (0.77, the anisotropy's single fit) reached the true pair, 600
        nats above every other pair (``docs/results/diagnose_sweep_lab.md``, case 0).
        """
        jobs = [(Candidate(cur.cand.parts + s.cand.parts), np.concatenate([cur.x, s.x]), True)
                for s in singles if _compatible(cur.cand, s.cand.parts[0])]
        screened = [(g_te - self.pen_unit * x.size, cand, x)
                    for (cand, _, _), (x, g_te) in zip(jobs, self._fits(jobs))]
        screened.sort(key=lambda t: -t[0])
        # a joint effect on a joint the set already acts on is refitted fully whatever its screen:
        # a short screen may not get out of the member's share (a damping fitted alone absorbs a
        # friction on its joint)
        joints = {_joint_of(p) for p in cur.cand.parts} - {None}
        keep = [t for k, t in enumerate(screened)
                if k < self.config.step_candidates or _joint_of(t[1].parts[-1]) in joints]
        out = self.fit_many([(cand, x) for _, cand, x in keep])
        return sorted(out, key=lambda r: -r.score.score)

    def without(self, cur: Ranked, k: int) -> Ranked:
        """``cur`` with its k-th member left out, refitted from the remaining parameters."""
        parts = cur.cand.parts
        if len(parts) == 1:
            return self.ranked(Candidate(()), np.zeros(0), 0.0)
        i0 = sum(len(EFFECTS[n].params) for n, _ in parts[:k])
        n_k = len(EFFECTS[parts[k][0]].params)
        x0 = np.concatenate([cur.x[:i0], cur.x[i0 + n_k:]])
        return self.fit(Candidate(parts[:k] + parts[k + 1:]), x0)

    def member_evidence(self, cur: Ranked) -> list[tuple[float, Ranked]]:
        """Per member: (evidence lost without it, the refitted set without it)."""
        out = []
        for k in range(len(cur.cand.parts)):
            rest = self.without(cur, k)
            out.append((cur.score.score - rest.score.score, rest))
        return out


def _joint_of(part: tuple[str, str | None]) -> str | None:
    """The passive joint a joint effect acts on (None for link and global effects)."""
    return part[1] if EFFECTS[part[0]].needs_joint else None


def _compatible(cand: Candidate, part: tuple[str, str | None]) -> bool:
    """Whether ``part`` may join ``cand``: not already in it, and no global effect twice."""
    return all(p != part and not (p[0] == part[0] and part[1] is None) for p in cand.parts)


NullMaker = Callable[[Candidate, FloatArray], Data]


class _Calibration:
    """Per-recording bias of the equation-error evidence (:mod:`.null`).

    For the set S chosen so far, a null recording is simulated with S at its fitted parameters
    (``make_null``); a candidate set S + c is fitted on that null as on the data, and its evidence
    gain over S there is what c gains without being present.  Nulls and fits are cached by set.
    """

    def __init__(self, make_null: NullMaker, model: ChainModel, config: DiagnoseConfig, sig_rp: FloatArray) -> None:
        self.make_null = make_null
        self.model = model
        self.config = config
        self.sig_rp = sig_rp
        self._nulls: dict[frozenset[tuple[str, str | None]], tuple[_Selector, Ranked]] = {}
        self._gains: dict[tuple[frozenset[tuple[str, str | None]], str], float] = {}
        self.log: list[str] = []

    def null_gain(self, cur: Ranked, option: Ranked) -> float:
        """Evidence ``option`` (a superset of ``cur``) gains over ``cur`` on ``cur``'s null, nats."""
        key = frozenset(cur.cand.parts)
        hit = self._gains.get((key, option.cand.label))
        if hit is not None:
            return hit
        if key not in self._nulls:
            sel = _Selector(Scorer(self.make_null(cur.cand, cur.x), self.model, self.config.eq_window,
                                   self.sig_rp), self.config)
            base = (sel.fit_quick(cur.cand, cur.x) if cur.cand.parts
                    else sel.ranked(Candidate(()), np.zeros(0), 0.0))
            self._nulls[key] = (sel, base)
        sel, base = self._nulls[key]
        # a short run from the recording's fit: the null's optimum of a biased candidate is near it
        gain = sel.fit_quick(option.cand, option.x).score.score - base.score.score
        self._gains[(key, option.cand.label)] = gain
        return gain

    def adjusted(self, cur: Ranked, options: Sequence[Ranked]) -> dict[str, float]:
        """Options' scores less their null gains over ``cur`` (when positive), by label.

        Options are taken best raw score first; the calibration stops once no raw score left can
        beat the best adjusted one (an adjustment only lowers a score), or after
        ``config.calibration_max`` candidates (the rest keep their raw scores, noted).
        """
        out = {o.cand.label: o.score.score for o in options}
        best = -np.inf
        done = 0
        for o in sorted(options, key=lambda r: -r.score.score):
            if o.score.score <= best:
                break
            if done >= self.config.calibration_max:
                self.log.append(f"calibration stopped after {done} candidates (calibration_max)")
                break
            bias = max(self.null_gain(cur, o), 0.0)
            out[o.cand.label] = o.score.score - bias
            done += 1
            if bias > 0:
                self.log.append(f"null of {cur.cand.label or 'the nominal model'}: "
                                f"{_added(o.cand, cur.cand)} gains {bias:.1f} nats without being there "
                                f"({o.score.score - cur.score.score:.1f} on the recording)")
            best = max(best, out[o.cand.label])
        return out


def name_mismatch(
    data: Data, model: ChainModel, config: DiagnoseConfig, sig_rp: FloatArray,
    candidates: Sequence[Candidate] | None = None, null: NullMaker | None = None,
) -> Naming:
    """Select the set of effects that explains the mismatch (module docstring).

    ``sig_rp`` is the noise floor of the passive angles (sets the stick threshold on |ṙ_p|);
    ``candidates`` default to :func:`~suds_ros.core.diagnosis.naming.catalogue_candidates`;
    ``null`` makes the null recording of a set of effects (:mod:`.null`): with it every step's
    evidence is calibrated on this recording (:class:`_Calibration`).
    """
    sel = _Selector(Scorer(data, model, config.eq_window, sig_rp), config)
    if null is not None:
        sel.calibration = _Calibration(null, model, config, sig_rp)
    pool = list(candidates) if candidates is not None else catalogue_candidates(model, config.model_suspects)
    singles = sorted(sel.fit_many([(c, None) for c in pool]), key=lambda r: -r.score.score)
    main = _forward(sel, singles, None)
    if main.cur.score.score > 0:
        main = _with_equivalents(sel, main, singles)
    alternatives = _alternatives(sel, singles, main) if main.cur.score.score > 0 else ()
    ranking = tuple(r.score for r in sorted(sel.fitted.values(), key=lambda r: -r.score.score) if r.cand.parts)
    log = main.log + (tuple(sel.calibration.log) if sel.calibration is not None else ())
    return Naming(ranking, main.cur, main.groups, main.evidence, log, main.gains, alternatives,
                  dict(sel.fitted), main.rejected)


@dataclass(frozen=True)
class _Path:
    """One forward selection with backward checks: the set, its confounded groups, members' evidence."""

    cur: Ranked
    groups: tuple[tuple[str, ...], ...]
    evidence: tuple[float, ...]
    log: tuple[str, ...]
    gains: tuple[float, ...]
    first_group: tuple[str, ...] = ()  # the first step's confounded group, if any
    rejected: tuple[Ranked, ...] = ()  # the leading sets of the step that failed the threshold


def _forward(sel: _Selector, singles: Sequence[Ranked], first: Ranked | None) -> _Path:
    """Forward selection from the best single (or from ``first``), each step checked backward."""
    config = sel.config
    cur = sel.ranked(Candidate(()), np.zeros(0), 0.0)
    groups: list[tuple[str, ...]] = []
    first_group: tuple[str, ...] = ()
    log: list[str] = []
    evidence: list[float] = []
    gains: list[float] = []
    rejected: tuple[Ranked, ...] = ()
    for step in range(config.max_effects):
        options = list(singles) if step == 0 else sel.extend(cur, singles)
        if not options:
            break
        score = {o.cand.label: o.score.score for o in options}
        if sel.calibration is not None:
            score = sel.calibration.adjusted(cur, options)
            options = sorted(options, key=lambda o: -score[o.cand.label])
        if step == 0 and first is not None:
            options = [first] + [o for o in options if o.cand != first.cand]
        best = options[0]
        gain = score[best.cand.label] - cur.score.score
        gains.append(float(gain))
        need = 0.0 if step == 0 else config.evidence_threshold
        raw = best.score.score - cur.score.score
        cal = f" ({raw:.1f} before calibration)" if abs(raw - gain) > 1e-9 else ""
        log.append(f"step {step + 1}: best {best.cand.label} gains {gain:.1f} nats{cal} (needs > {need:g})")
        if gain <= need:
            if step == 0:
                cur = best  # nothing has positive evidence; the pipeline reports it unexplained
            else:
                rejected = tuple(options[:config.extend_max])
            break
        margin = max(config.confound_margin, config.confound_rel * gain)
        close = [o for o in options
                 if abs(score[best.cand.label] - score[o.cand.label]) <= margin and o.cand != best.cand]
        chosen = min([best] + close, key=_preference) if close else best
        if close:
            others = [c for c in [best] + close if c is not chosen]
            groups.append(tuple(_added(o.cand, cur.cand) for o in [chosen] + others))
            if step == 0:
                first_group = groups[-1]
        cur = chosen
        cur, evidence, dropped = _backward(sel, cur, config.evidence_threshold)
        log.extend(dropped)
    if not evidence and cur.cand.parts:
        evidence = [ev for ev, _ in sel.member_evidence(cur)]
    kept = {lab for n, t in cur.cand.parts for lab in [effect_label(n, t)]}
    rejected = tuple(r for r in rejected if set(cur.cand.parts) < set(r.cand.parts))
    return _Path(cur, tuple(g for g in groups if g[0] in kept), tuple(float(e) for e in evidence), tuple(log),
                 tuple(gains), first_group, rejected)


def _with_equivalents(sel: _Selector, main: _Path, singles: Sequence[Ranked]) -> _Path:
    """``main`` with the members that another candidate replaces exactly added to its confounded groups.

    A set can be reparameterised without changing its fit: on a robot with two passive joints,
    ``stiffness_to_drag_error`` + a stiffness error on one joint is the same physics as stiffness
    errors on both, and the forward selection, which adds one effect at a time, sees only the
    path it took.  Screen, on the set's sensitivities at its fit: the candidate's columns lie in
    the span of the set's, and the member's in the span of the rest of the set and the candidate
    (relative residual ≤ ``EQUIVALENCE_TOL`` for both: the swap spans the same directions).
    Confirmed by refitting the swapped set: its evidence within ``config.confound_margin`` of the
    set's.  Confirmed swaps join the member's confounded group; the pipeline refines them in the
    simulator, which reports them as alternatives or tells them apart.
    """
    cur = main.cur
    parts = cur.cand.parts
    if not parts:
        return main
    sc = sel.scorer
    J_set = sc.sensitivity(cur.cand, cur.x)
    sizes = [len(EFFECTS[n].params) for n, _ in parts]
    starts = np.concatenate([[0], np.cumsum(sizes)])
    groups = {g[0]: list(g) for g in main.groups}
    for s in singles:
        part = s.cand.parts[0]
        if part in parts or not any(_compatible(Candidate(parts[:k] + parts[k + 1:]), part)
                                    for k in range(len(parts))):
            continue  # no member it could stand in for
        with_c = Candidate(parts + (part,))
        J_c = sc.sensitivity(with_c, np.concatenate([cur.x, s.cand.neutral(sc.model)]), first=cur.x.size)
        if not _in_span(J_set, J_c):
            continue
        for k, (m, (a, b)) in enumerate(zip(parts, zip(starts[:-1], starts[1:]))):
            rest = parts[:k] + parts[k + 1:]
            if not _compatible(Candidate(rest), part):
                continue
            keep = np.r_[0:a, b:J_set.shape[1]]
            if not _in_span(np.hstack([J_set[:, keep], J_c]), J_set[:, a:b]):
                continue
            swapped = Candidate(parts[:k] + (part,) + parts[k + 1:])
            x0 = np.concatenate([cur.x[:a], s.x, cur.x[b:]])
            alt = sel.fit(swapped, x0)
            gap = cur.score.score - alt.score.score
            m_label, c_label = effect_label(*m), effect_label(*part)
            if abs(gap) <= sel.config.confound_margin:
                group = groups.setdefault(m_label, [m_label])
                if c_label not in group:
                    group.append(c_label)
    new_groups = tuple(tuple(g) for g in groups.values() if len(g) > 1)
    if new_groups == main.groups:
        return main
    log = main.log + tuple(f"equivalent: {g[0]} or {', '.join(g[1:])} (the same fit with the rest of the set)"
                           for g in new_groups if g not in main.groups)
    return dataclasses.replace(main, groups=new_groups, log=log)


EQUIVALENCE_TOL = 1e-3


def _in_span(A: FloatArray, B: FloatArray) -> bool:
    """Whether every column of ``B`` lies in the column span of ``A`` (relative residual ≤ tolerance)."""
    norm_b = np.linalg.norm(B, axis=0)
    if not np.all(np.isfinite(A)) or not np.all(np.isfinite(B)) or np.any(norm_b == 0):
        return False
    coef, *_ = np.linalg.lstsq(A, B, rcond=None)
    return bool(np.all(np.linalg.norm(B - A @ coef, axis=0) <= EQUIVALENCE_TOL * norm_b))


def _alternatives(sel: _Selector, singles: Sequence[Ranked], main: _Path) -> tuple[_Path, ...]:
    """Forward selections from the runners-up of the first step, for the simulator to arbitrate.

    Singles within max(``arbitrate_margin``, ``arbitrate_rel`` × the best single's evidence) of
    the best, other than those reported as confounded with it (equivalent explanations, named as
    such), each start a forward selection of their own; the distinct sets found (at most
    ``arbitrate_max``) are returned.  The equation error's own biases can put a wrong first
    effect narrowly ahead, and every later step builds on it.
    """
    cfg = sel.config
    if not cfg.arbitrate_max or not singles:
        return ()
    top = singles[0].score.score
    margin = max(cfg.arbitrate_margin, cfg.arbitrate_rel * top)
    seen = [{effect_label(n, t) for n, t in main.cur.cand.parts}]
    out: list[_Path] = []
    for s in singles[1:]:
        if len(out) >= cfg.arbitrate_max or top - s.score.score > margin:
            break
        if s.score.score <= 0 or effect_label(*s.cand.parts[0]) in main.first_group:
            continue
        path = _forward(sel, singles, s)
        labels = {effect_label(n, t) for n, t in path.cur.cand.parts}
        if labels in seen:
            continue
        seen.append(labels)
        out.append(path)
    return tuple(out)


def _backward(sel: _Selector, cur: Ranked, threshold: float) -> tuple[Ranked, list[float], list[str]]:
    """Drop members (other than the newest) whose leaving out costs ≤ ``threshold``; their evidence."""
    log: list[str] = []
    while True:
        ev = sel.member_evidence(cur)
        if len(ev) < 2:
            return cur, [e for e, _ in ev], log
        k = int(np.argmin([e for e, _ in ev[:-1]]))
        if ev[k][0] > threshold:
            return cur, [e for e, _ in ev], log
        log.append(f"backward: {effect_label(*cur.cand.parts[k])} no longer earns its place ({ev[k][0]:.1f} nats)")
        cur = ev[k][1]


def _added(cand: Candidate, base: Candidate) -> str:
    """Label of the member of ``cand`` not in ``base``."""
    return " + ".join(effect_label(n, t) for n, t in cand.parts if (n, t) not in base.parts)


def _preference(s: Ranked) -> tuple[int, int]:
    """Among equivalent explanations prefer the specification's catalogue, then fewer targets."""
    extra_ids = sum(1 for nme, _ in s.cand.parts if not EFFECTS[nme].specified)
    return (extra_ids, sum(1 for _, tgt in s.cand.parts if tgt is not None))
