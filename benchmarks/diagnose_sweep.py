"""Randomised check of ``suds diagnose`` with 0–3 simultaneous effects (seeded).

Each case draws a system (``--systems``: built-ins and robot model files; by default purcell3,
swimmer9 and the model files snake5, eel4 and tail6), recording conditions (``--lab`` of the
cases are recorded the lab way: pose at 100, 120 or 50 Hz from its own start, 0.4 ms jitter, 1 %
drops per stream; the rest aligned) and 0 (null, 10 %), 1, 2 or 3 (30 % each)
distinct effects from the catalogue *and* the model-parameter errors (``link_length_error``,
``link_drag_error``, ``joint_stiffness_error``, ``pose_frame_offset``), each with a target
(passive joint or link) and a magnitude from the ranges below, simulates 60 cycles with a fresh
seed, and diagnoses it with the nominal model (every suspect on, the default).  A case is *fully
correct* when exactly the injected effects are reported, each on its target (an injected effect
reported as confounded with the reported one counts as named), each parameter vector within 25 %
(‖x̂ − x‖ ≤ 0.25‖x‖ for vector parameters such as a flow or a pose offset), and the held-out
mismatch falls by at least half; a null case when no mismatch is reported.  An injected effect
listed among the ``alternatives`` of a reported effect counts as named (the finding is ambiguous
and says so), and so does an alternative that is, as a whole set (the reported effects but those
it replaces, with its own), exactly the injected one.  A *false discovery* is a reported effect
that was not injected and is not an alternative of one.  With ``--max-effects 1`` and
``--catalogue-only`` it is the earlier single-effect sweep.  Cases run in ``--jobs`` processes.
A drawn robot the simulator cannot run (a softening spring past its stable range) is listed, not
counted, and replaced by the next draw, so a full sweep counts ``--cases`` simulated cases.

``--lose STREAM FRACTION BURST`` makes every recording lose frames of one stream, singly or in
bursts (:func:`frame_loss.kept`), as a motion-capture occlusion or a congested encoder bus does.

Usage: PYTHONPATH=. .venv/bin/python benchmarks/diagnose_sweep.py [--cases 24] [--seed 0] [--jobs 2]
       [--lose shape 0.3 0.3 --out docs/results/diagnose_sweep_frame_loss.md]
       (also --lose pose 0.3 0.3: diagnose_sweep_pose_loss.md; --lose shape 0.1 0: diagnose_sweep_single_loss.md)
Writes docs/results/diagnose_sweep_lab.md (docs/results/diagnose_sweep.md is the earlier built-in-only, aligned sweep).
"""

from __future__ import annotations

import argparse
import platform
import time
from collections.abc import Iterator
from dataclasses import replace
from itertools import count
from pathlib import Path

import numpy as np

from frame_loss import kept
from suds_ros.core.diagnosis import diagnose
from suds_ros.core.diagnosis.report import effect_label
from suds_ros.core.errors import SudsError
from suds_ros.core.physics.effects import EFFECTS, apply_effects
from suds_ros.core.physics.lab import LabConditions, simulate_lab
from suds_ros.core.physics.rft import ChainModel, RFTChain
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import load_system
from suds_ros.core.recording import Recording

ROOT = Path(__file__).resolve().parents[1]
SYSTEMS = ["purcell3", "swimmer9", str(ROOT.parent / "shared" / "robots" / "snake5.yaml"),
           str(ROOT / "test" / "data" / "robots" / "eel4.yaml"), str(ROOT / "test" / "data" / "robots" / "tail6.yaml")]


def chain(system: str) -> ChainModel:
    """The nominal chain of a built-in id or a robot model file."""
    return load_system(system).model


def short(system: str) -> str:
    return Path(system).stem if system.endswith((".yaml", ".yml")) else system


MODEL_ERRORS = ["link_length_error", "link_drag_error", "joint_stiffness_error", "pose_frame_offset"]


def _catalogue() -> list[str]:
    return [n for n, spec in EFFECTS.items() if spec.kind == "catalogue" and n != "joint_stiffness_error"]


def draw_one(rng: np.random.Generator, system: str, name: str) -> dict:
    """One effect ``name`` with a target and a magnitude of the size a robot/simulator mismatch has."""
    sign = float(rng.choice([-1.0, 1.0]))
    model = chain(system)
    joint = str(rng.choice([model.joint_names[j] for j in model.passive]))
    n_links = model.n_links
    link = f"link_{int(rng.integers(1, n_links + 1))}"

    def either(a: tuple[float, float], b: tuple[float, float]) -> float:
        return float(rng.uniform(*a) if rng.random() < 0.5 else rng.uniform(*b))

    if name == "joint_coulomb_friction":
        return dict(name=name, joint=joint, mu=float(rng.uniform(0.3, 0.9)))
    if name == "joint_viscous_damping":
        return dict(name=name, joint=joint, d=float(rng.uniform(0.1, 0.5)))
    if name == "spring_rest_offset":
        return dict(name=name, joint=joint, offset=sign * float(rng.uniform(0.1, 0.3)))
    if name == "spring_nonlinearity":
        return dict(name=name, joint=joint, k3=sign * float(rng.uniform(1.0, 4.0)))
    if name == "stiffness_to_drag_error":
        return dict(name=name, scale=either((0.6, 0.8), (1.25, 1.6)))
    if name == "drag_anisotropy_error":  # relative to the robot's own c⊥/c∥ (2 for the built-ins)
        return dict(name=name, ratio=model.drag_ratio * either((0.7, 0.875), (1.15, 1.5)))
    if name == "background_flow":
        ang, speed = rng.uniform(0, 2 * np.pi), rng.uniform(0.04, 0.15)
        return dict(name=name, vx=float(speed * np.cos(ang)), vy=float(speed * np.sin(ang)))
    if name == "sensor_time_offset":
        return dict(name=name, dt=0.01 * int(rng.integers(1, 6)))
    if name == "joint_stiffness_error":
        return dict(name=name, joint=joint, scale=either((0.6, 0.8), (1.25, 1.6)))
    if name == "link_length_error":
        return dict(name=name, link=link, scale=either((0.7, 0.8), (1.25, 1.4)))
    if name == "link_drag_error":
        return dict(name=name, link=link, scale=either((0.5, 0.7), (1.4, 2.0)))
    if name == "pose_frame_offset":
        return dict(name=name, x=sign * float(rng.uniform(0.05, 0.15)), y=float(rng.uniform(-0.15, 0.15)),
                    yaw=float(rng.uniform(-0.2, 0.2)))
    raise AssertionError(name)


def _target(e: dict) -> str | None:
    return e.get("joint") or e.get("link")


def draw_effects(rng: np.random.Generator, system: str, max_effects: int, catalogue_only: bool) -> list[dict]:
    """0–``max_effects`` distinct effects (never the same id twice on one target, nor a global twice).

    On purcell3 (one passive joint) ``joint_stiffness_error`` ≡ ``stiffness_to_drag_error``; it is
    not drawn there.
    """
    probs = np.array([0.1] + [0.9 / max_effects] * max_effects)
    k = int(rng.choice(np.arange(max_effects + 1), p=probs))
    pool = _catalogue() + ([] if catalogue_only else MODEL_ERRORS)
    if len(chain(system).passive) == 1:  # one passive joint: its stiffness ≡ the global scale
        pool = [n for n in pool if n != "joint_stiffness_error"]
    out: list[dict] = []
    while len(out) < k:
        e = draw_one(rng, system, str(rng.choice(pool)))
        if any(o["name"] == e["name"] and (_target(o) == _target(e) or _target(e) is None) for o in out):
            continue
        out.append(e)
    return out


def _params(e: dict) -> dict[str, float]:
    return {k: v for k, v in e.items() if k not in ("name", "joint", "link")}


def _close(got: dict[str, float], want: dict[str, float]) -> bool:
    if len(want) == 1:
        (k, v), = want.items()
        return abs(got[k] - v) <= 0.25 * abs(v)
    err = np.sqrt(sum((got[k] - v) ** 2 for k, v in want.items()))
    return bool(err <= 0.25 * np.sqrt(sum(v**2 for v in want.values())))


def judge(effects: list[dict], rep) -> tuple[bool, bool, str]:  # type: ignore[no-untyped-def]
    """(fully correct, false discovery, text) of a report against the injected ``effects``."""
    named = {(e.name, e.target) for e in rep.effects}
    alts = {(n, t) for e in rep.effects for a in e.alternatives for n, t, _ in a.added}
    injected = {(e["name"], _target(e)) for e in effects}
    # a named effect that an alternative holding an injected effect would replace is one side of an
    # "A or B" finding, not a false discovery
    replaced: set[tuple[str, str | None]] = set()
    for e in rep.effects:
        for a in e.alternatives:
            if {(n, t) for n, t, _ in a.added} & injected:
                replaced |= {(lbl.split(":", 1)[0], lbl.split(":", 1)[1] if ":" in lbl else None)
                             for lbl in a.instead_of}
    false = bool(named - injected - alts - replaced) if rep.mismatch else False
    if not effects:
        return (not rep.mismatch), bool(rep.effects), ("no mismatch" if not rep.mismatch else
                                                       f"false alarm: {[e.name for e in rep.effects]}")
    if not rep.mismatch:
        return False, False, "missed (no mismatch reported)"
    text = "; ".join(
        f"{e.name} {e.target or ''} " + ", ".join(f"{k}={v:.4g}" for k, v in e.parameters.items())
        + "".join(f" [or {a.label} {', '.join(f'{k}={v:.4g}' for k, v in a.parameters.items())}, "
                  f"gap {a.evidence_gap:.1f}]" for a in e.alternatives)
        for e in rep.effects) or "none"
    text += f"; improvement {rep.improvement:.2f}"
    if rep.confounded_with:
        text += " (confounded: " + " / ".join(", ".join(g) for g in rep.confounded_with) + ")"
    if rep.discovered:  # every injected effect is in the lists: a formula is a false discovery
        text += "; discovered " + "; ".join(
            f"{d.joint}: " + " + ".join(f"{v:.3g}·{k}" for k, v in d.terms.items()) for d in rep.discovered)
    if rep.unexplained:
        return False, false, text + " — unexplained"
    got = {(e.name, e.target): e for e in rep.effects}
    alt_params = {(a.name, a.target): a.parameters for e in rep.effects for a in e.alternatives}
    ok = rep.improvement >= 0.5 and not rep.discovered and not false
    for eff in effects:
        key = (eff["name"], _target(eff))
        label = effect_label(eff["name"], key[1])
        if key in got:
            ok &= _close(dict(got[key].parameters), _params(eff))
        elif key in alt_params:
            ok &= _close(dict(alt_params[key]), _params(eff))
        else:
            ok &= any(label in g for g in rep.confounded_with)
    if not ok and rep.improvement >= 0.5 and not rep.discovered and not false:
        ok = any(_matches(alt_set, effects) for alt_set in _alternative_sets(rep))
    return bool(ok), false, text


def _alternative_sets(rep) -> list[dict]:  # type: ignore[no-untyped-def]
    """Each alternative as a whole set: the reported effects but those it replaces, and its own."""
    out = []
    for e in rep.effects:
        for a in e.alternatives:
            s = {(f.name, f.target): dict(f.parameters) for f in rep.effects
                 if effect_label(f.name, f.target) not in a.instead_of}
            s.update({(n, t): dict(p) for n, t, p in a.added})
            out.append(s)
    return out


def _matches(got: dict, effects: list[dict]) -> bool:
    """Whether a set of effects is exactly the injected one, each parameter vector within 25 %."""
    want = {(e["name"], _target(e)): _params(e) for e in effects}
    return set(got) == set(want) and all(_close(got[k], v) for k, v in want.items())


LAB_POSE_HZ = (100.0, 120.0, 50.0)


def known_evidence(rec, base: ChainModel, effects: list[dict]) -> float:  # type: ignore[no-untyped-def]
    """The weakest injected effect's evidence with every parameter known, nats (inf: none injected).

    Per injected effect: the equation error's held-out gain of the whole injected set at its true
    values, minus that of the set without the effect (the rest held at their true values), minus
    the effect's BIC penalty: the selection's evidence for the effect with nothing to fit.  A fit
    can only lose evidence (the rest absorbs part of the effect), so below the selection's
    threshold no fit names the effect: the recording does not show it.
    """
    from suds_ros.core.diagnosis import DiagnoseConfig
    from suds_ros.core.diagnosis.data import prepare
    from suds_ros.core.diagnosis.naming import Candidate, Scorer
    from suds_ros.core.diagnosis.pipeline import replay_nominal

    if not effects:
        return float("inf")
    config = DiagnoseConfig()
    nom = replay_nominal(prepare(rec, base), base, config, None)
    sc = Scorer(nom.data, base, config.eq_window, nom.floors[0])
    pen = sc.pen_unit
    parts = [(e["name"], _target(e)) for e in effects]
    xs = [np.array([e[q.name] for q in EFFECTS[e["name"]].params], dtype=float) for e in effects]
    whole = sc.heldout_gain(Candidate(tuple(parts)), np.concatenate(xs))
    out = []
    for k in range(len(effects)):
        rest = Candidate(tuple(parts[:k] + parts[k + 1:]))
        x_rest = np.concatenate(xs[:k] + xs[k + 1:]) if len(effects) > 1 else np.zeros(0)
        out.append(whole - sc.heldout_gain(rest, x_rest) - pen * xs[k].size)
    return float(min(out))


#: (stream, fraction, mean burst length in s; 0: single messages) of ``--lose``
Loss = tuple[str, float, float] | None


def lose_frames(rec: Recording, loss: Loss, seed: int) -> Recording:
    """``rec`` without the frames ``loss`` takes from one stream (seeded; the ends are kept)."""
    if loss is None:
        return rec
    stream, fraction, burst = loss
    t = rec.t if stream == "shape" else rec.pose_t
    keep = kept(t, fraction, burst, np.random.default_rng(seed))
    keep[[0, -1]] = True
    if stream == "shape":
        return replace(rec, t=rec.t[keep], r=rec.r[keep], truth={})
    return replace(rec, pose_t=rec.pose_t[keep], pose=rec.pose[keep], truth={})


def loss_label(loss: Loss) -> str:
    if loss is None:
        return ""
    stream, fraction, burst = loss
    return f"; {stream} {100 * fraction:.0f} % lost " + ("singly" if burst == 0 else f"in {burst:g} s bursts")


def run_case(args: tuple[int, str, list[dict], int, float | None, int, Loss]) -> tuple[int, str]:
    """Simulate and diagnose one case in this process; returns (case, markdown row)."""
    from suds_ros.core.blas import pin_blas_threads

    pin_blas_threads(1)
    i, system, effects, sim_seed, pose_hz, cycles, loss = args
    base = chain(system)
    model, delay = apply_effects(base, effects)
    cfg = SimConfig(cycles=cycles, seed=sim_seed, pose_delay=delay, gait_hz=base.gait_hz)
    injected = "; ".join(" ".join(
        f"{k}={v:.4g}" if isinstance(v, float) else str(v) for k, v in e.items()) for e in effects) or "none"
    cond = ("aligned" if pose_hz is None else f"lab, pose {pose_hz:g} Hz") + loss_label(loss)
    head = f"| {i} | {short(system)} | {cond} | {sim_seed} | {len(effects)} | {injected} |"
    try:
        rec = (simulate(RFTChain(model), cfg) if pose_hz is None
               else simulate_lab(RFTChain(model), cfg, LabConditions(pose_hz=pose_hz)))
        rec = lose_frames(rec, loss, sim_seed)
    except (SudsError, FloatingPointError, np.linalg.LinAlgError) as exc:
        # a drawn robot the simulator cannot run (a softening spring past its stable range): a bad
        # draw, listed and left out of the counts, not a diagnosis failure
        return i, f"{head} — | not simulated: {type(exc).__name__}: {exc} | — | — | 0.0 |"
    try:
        weak = known_evidence(rec, base, effects)
        head += f" {weak:.0f} |" if np.isfinite(weak) else " — |"
    except Exception as exc:  # noqa: BLE001 - a benchmark column, not the diagnosis
        head += f" ({type(exc).__name__}) |"
    t0 = time.perf_counter()
    try:
        rep = diagnose(rec, base)
    except Exception as exc:  # noqa: BLE001 - a crash of the diagnosis is a failed case, and the sweep goes on
        wall = time.perf_counter() - t0
        return i, f"{head} CRASH {type(exc).__name__}: {exc} | NO | no | {wall:.1f} |"
    wall = time.perf_counter() - t0
    ok, false, text = judge(effects, rep)
    return i, (f"{head} {text} | {'yes' if ok else 'NO'} | {'YES' if false else 'no'} | {wall:.1f} |")


def draw_cases(args: argparse.Namespace) -> Iterator[tuple[int, str, list[dict], int, float | None, int, Loss]]:
    """The seeded stream of cases: (index, system, effects, simulation seed, pose rate or None, cycles, loss).

    The stream is endless; a full sweep takes a further case for each drawn case the simulator cannot
    run, so the first ``--cases`` draws are the same whatever follows them.
    """
    rng = np.random.default_rng(args.seed)
    for i in count():
        system = args.systems[i % len(args.systems)]
        effects = draw_effects(rng, system, args.max_effects, args.catalogue_only)
        sim_seed = int(rng.integers(100, 10_000))
        pose_hz = float(rng.choice(LAB_POSE_HZ)) if rng.random() < args.lab else None
        yield i, system, effects, sim_seed, pose_hz, args.cycles, args.lose


def simulated(row: str) -> bool:
    """Tell whether a result ``row`` is of a case the simulator ran, so it was diagnosed and counts."""
    return row.split(" | ")[-3] != "—"


def write_table(args: argparse.Namespace, cases: list, rows: dict[int, str], total: float) -> tuple[int, int]:
    """Write the results so far (the file says how many of the cases have run); (passed, false)."""
    run = {i: row for i, row in rows.items() if simulated(row)}
    ok = {i: row.split(" | ")[-3] == "yes" for i, row in run.items()}
    false = {i: row.split(" | ")[-2] == "YES" for i, row in run.items()}
    not_simulated = len(rows) - len(run)
    passed, n_false = sum(ok.values()), sum(false.values())
    from suds_ros.core.diagnosis import DiagnoseConfig

    threshold = DiagnoseConfig().evidence_threshold

    def shown(row: str) -> bool:  # every injected effect has known-parameter evidence above the threshold
        cell = row.split(" | ")[6].strip()
        try:
            return cell == "—" or float(cell) > threshold
        except ValueError:
            return False
    visible = [i for i, row in run.items() if shown(row)]
    passed_visible = sum(ok[i] for i in visible)
    by_k: dict[int, list[int]] = {}
    for i, system, effects, *_ in cases:
        if i in ok:
            by_k.setdefault(len(effects), []).append(int(ok[i]))
    per_k = ", ".join(f"{k} effect{'s' if k != 1 else ''}: {sum(v)}/{len(v)}" for k, v in sorted(by_k.items()))
    flags = (f" --max-effects {args.max_effects} --lab {args.lab:g} --cycles {args.cycles}"
             + (" --catalogue-only" if args.catalogue_only else "")
             + (" --lose {} {:g} {:g}".format(*args.lose) if args.lose else ""))
    done = len(rows)
    partial = "" if done == len(cases) else f" **Partial: {done} of the {len(cases)} cases have run.**"
    lines = [
        "# Randomised diagnosis sweep",
        "",
        f"Generated by `benchmarks/diagnose_sweep.py --cases {args.cases} --seed {args.seed}{flags}` "
        f"on {platform.machine()}, Python {platform.python_version()}, "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {args.jobs} processes, {total / 60:.1f} min "
        f"wall.{partial}",
        "",
        "Systems in turn: " + ", ".join(short(s) for s in args.systems) + f". About {100 * args.lab:.0f} % of "
        "the recordings are made the lab way (pose at 100, 120 or 50 Hz from its own start, 0.4 ms jitter, "
        "1 % drops), the rest aligned." + (
            f"  Then every recording loses {100 * args.lose[1]:.0f} % of its {args.lose[0]} frames "
            + ("singly, at random" if args.lose[2] == 0 else
               f"in bursts of exponential length (mean {args.lose[2]:g} s) at random starts")
            + " (`--lose`, seeded by the case's simulation seed)." if args.lose else "")
        + "  Each case: 0–3 simultaneous effects drawn from the catalogue and the model-parameter "
        "errors (link length, link drag, one joint's spring constant, pose-frame offset), random "
        "targets and magnitudes (ranges in the script).  *Fully correct*: every injected "
        "effect reported on its target, or listed as an alternative of a reported effect, or reported "
        "confounded with one; parameters within 25 % (vector parameters: ‖x̂ − x‖ ≤ 0.25‖x‖); held-out "
        "improvement ≥ 0.5; no formula discovered; nothing else named.  *False discovery*: an effect "
        "named that was not injected and is not an alternative.  Null: no mismatch reported.  "
        "*Known-parameter evidence*: the weakest injected effect's held-out equation-error evidence "
        "with every parameter at its true value (the set's gain minus the set's without it, minus its "
        f"BIC penalty; `known_evidence`): a fit can only do worse, so an effect below the selection's "
        f"threshold ({threshold:g} nats) is not shown by the recording, and no diagnosis can name it.",
        "",
        f"**{passed} of {len(run)} cases fully correct** ({per_k}); **false discoveries in {n_false} of "
        f"{len(run)} cases**." + (f" {not_simulated} drawn case(s) could not be simulated (marked in the "
                                  "table): they are not counted, and each was replaced by the next draw of "
                                  "the same seeded stream (the cases numbered from "
                                  f"{args.cases} on)." if not_simulated else ""),
        "",
        f"Among the {len(visible)} cases whose every injected effect the recording shows (known-parameter "
        f"evidence above {threshold:g} nats): **{passed_visible} fully correct**.",
        "",
        "| case | system | recording | sim seed | # | injected | known-parameter evidence, weakest (nats) "
        "| diagnosed | fully correct | false discovery | wall (s) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
        *[rows[i] for i in sorted(rows)],
        "",
    ]
    Path(args.out).write_text("\n".join(lines))
    return passed, n_false


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=24)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cycles", type=int, default=60)
    ap.add_argument("--max-effects", type=int, default=3)
    ap.add_argument("--systems", nargs="+", default=SYSTEMS, help="built-in ids and robot model files, in turn")
    ap.add_argument("--lab", type=float, default=0.5, help="fraction of the cases recorded the lab way")
    ap.add_argument("--jobs", type=int, default=2, help="processes")
    ap.add_argument("--catalogue-only", action="store_true", help="no model-parameter errors drawn")
    ap.add_argument("--only", type=int, nargs="+", default=None,
                    help="run only these case indices (of the --cases drawn) and print their rows; nothing "
                         "is written unless --out is given")
    ap.add_argument("--out", default=None, help="results file (default docs/results/diagnose_sweep_lab.md)")
    ap.add_argument("--lose", nargs=3, default=None, metavar=("STREAM", "FRACTION", "BURST"),
                    help="every recording loses FRACTION of its STREAM (shape|pose) frames, singly (BURST 0) "
                         "or in bursts of mean BURST s")
    args = ap.parse_args()
    if args.lose is not None:
        if args.lose[0] not in ("shape", "pose"):
            ap.error(f"--lose: STREAM must be shape or pose, got {args.lose[0]!r}")
        args.lose = (args.lose[0], float(args.lose[1]), float(args.lose[2]))
    if args.out is None and args.only is None:
        args.out = "docs/results/diagnose_sweep_lab.md"
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    draws = draw_cases(args)
    cases = [next(draws) for _ in range(args.cases)]
    todo = cases if args.only is None else [c for c in cases if c[0] in set(args.only)]
    t_start = time.perf_counter()
    rows: dict[int, str] = {}
    passed = n_false = 0
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        pending = {pool.submit(run_case, c) for c in todo}
        while pending:
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in finished:
                i, row = future.result()
                rows[i] = row
                print(row, flush=True)
                if args.only is None and not simulated(row):  # a full sweep counts --cases simulated cases
                    extra = next(draws)
                    cases.append(extra)
                    pending.add(pool.submit(run_case, extra))
                if args.out is not None:
                    passed, n_false = write_table(args, cases, rows, time.perf_counter() - t_start)
                else:
                    passed += row.split(" | ")[-3] == "yes"
                    n_false += row.split(" | ")[-2] == "YES"
    print(f"{passed}/{sum(map(simulated, rows.values()))} fully correct, {n_false} with a false discovery"
          + (f"; wrote {args.out}" if args.out else ""))


if __name__ == "__main__":
    main()
