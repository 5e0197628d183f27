"""CMA-ES against the run → fit → step loop, on the same simulated robot with the same cycle budget.

Both see only what the robot's streams measure.  The robot is the loop's
(`suds_ros.core.optimize.loop`: default OU perturbation, 100 Hz, 1 mm / 1 mrad noise, seeded alike),
every candidate gait is switched in at a cycle boundary and run 1 settling + 4 measured cycles
(the loop's own candidate cost; every cycle counted), after the robot's nominal gait (the start,
1 + 4 cycles, as the loop measures it): the nominal gait, or half its amplitude (a poor start).

CMA-ES (the `cma` package, a benchmark-only dependency) searches the order-3 gait vector from
the nominal gait with σ0 = 0.25 × the mean joint range limit; a candidate outside the joint range
or speed bounds is scaled into them (`feasible_scale`, the bounds are homogeneous) before it runs,
so no gait outside the bounds is ever run; the fitness is the measured speed, minus 10 × the
measured |rotation| beyond the 0.05 rad/cycle bound.  The gait it would return at a budget is the
best *measured* feasible gait so far (the loop's rule).  The loop's figures are its runs in
`docs/results/optimize_loop_<robot>.json` (nominal start, same seeds).  Every returned gait is then
evaluated on the true physics against the limit stored there (the loop's, read at report time).

    pip install cma                                  # benchmarks/requirements-peers.txt
    python benchmarks/optimize_cma.py run purcell3 snake5    # → docs/results/optimize_cma_<robot>.json
    python benchmarks/optimize_cma.py report                 # → docs/results/optimize_cma.md
"""

from __future__ import annotations

import json
import time

import numpy as np
from _common import RESULTS, machine, run_report_cli, stamp, write
from optimize_loop import ABLATIONS, DEFAULTS, ROBOTS, starts

from suds_ros.core.json_text import dumps
from suds_ros.core.optimize.loop import LoopConfig, _Robot, _trim, measure_cycles
from suds_ros.core.optimize.physics import evaluate_gait, feasible_scale
from suds_ros.core.physics.gait import check_constraints, gait_limits, nominal_gait
from suds_ros.core.physics.systems import load_system

ORDER = 3
SETTLE, MEASURED, FIRST = DEFAULTS.settle_cycles, DEFAULTS.step_cycles, DEFAULTS.first_cycles  # as the loop runs them
MAX_ROTATION = 0.05
START_KINDS = ("nominal", "half amplitude")  # the loop benchmark's starts (optimize_loop.starts)
CHECKPOINTS = {"purcell3": (15, 25, 40), "snake5": (25, 40, 60), "swimmer9": (45, 90)}


def run(name: str, seeds: list[int]) -> None:
    import cma

    spec, budget, _ = ROBOTS[name]
    system = load_system(spec)
    limits = gait_limits(system)
    nom = nominal_gait(system)
    loop_doc = json.loads((RESULTS / f"optimize_loop_{name}.json").read_text())
    limit = loop_doc["limit"]
    doc = {"robot": name, "budget": budget, "limit": limit, "cma_version": cma.__version__, "runs": []}
    sigma0 = 0.25 * float(np.mean(limits.limit))
    for kind, seed in [(k, sd) for k in START_KINDS for sd in seeds]:
        start = starts(nom)[kind]
        x0 = start.to_vector(ORDER)
        t0 = time.perf_counter()
        cfg = LoopConfig(budget_cycles=budget, seed=seed, order=ORDER)
        robot = _Robot(system, start, cfg)
        es = cma.CMAEvolutionStrategy(x0, sigma0, {"seed": seed + 1, "verbose": -9})
        evals: list[dict] = []
        best: list = []  # [measured speed, gait] of the best feasible gait measured

        def measure(g, cycles: int) -> float:  # type: ignore[no-untyped-def]
            rec, _ = robot.run(g, cycles)
            m = measure_cycles(_trim(rec, SETTLE, robot.spc).pose, robot.spc, g.gait_hz)
            over = max(0.0, abs(m.rotation) - MAX_ROTATION)
            if over == 0 and (not best or m.speed > best[0]):
                best[:] = [m.speed, g]
            true = evaluate_gait(system, best[1]) if best else None
            evals.append({"cycles_used": robot.cycles_run, "measured": m.speed, "measured_rotation": m.rotation,
                          "best_true": None if true is None else true["speed"],
                          "best_true_rotation": None if true is None else true["rotation"]})
            return -m.speed + 10.0 * over

        measure(start, SETTLE + FIRST)  # the start gait first, measured as long as the loop measures it
        while robot.cycles_run + SETTLE + MEASURED <= budget:
            xs = es.ask()
            fits = []
            for x in xs:
                if robot.cycles_run + SETTLE + MEASURED > budget:
                    fits.append(np.inf)  # unevaluated: the budget is spent
                    continue
                g = nom.from_vector(np.asarray(x), ORDER)
                g = g.from_vector(feasible_scale(g, limits) * g.to_vector(ORDER), ORDER)
                check_constraints(g, limits)
                fits.append(measure(g, SETTLE + MEASURED))
            if all(np.isfinite(fits)):
                es.tell(xs, fits)
        doc["runs"].append({"start": kind, "seed": seed, "evals": evals, "seconds": time.perf_counter() - t0})
        last = evals[-1]
        print(f"{name} {kind} seed {seed}: {len(evals)} gaits, {last['cycles_used']} cycles, best measured gait "
              f"{100 * (last['best_true'] or 0) / limit:.1f} % of the limit", flush=True)
        (RESULTS / f"optimize_cma_{name}.json").write_text(dumps(doc))


#: two true speeds this close (relative) are level: the start gait's, evaluated where the loop ran and where
#: CMA-ES ran, differ by a few units in the last place (purcell3: 0.08664591258028093 against ...095)
REL_LEVEL = 1e-9


def _at(rows: list[dict], cycles: int, key: str) -> float | None:
    done = [r for r in rows if r["cycles_used"] <= cycles and r.get(key) is not None]
    return done[-1][key] if done else None


def _cells(doc: dict, loop: dict, cps: tuple[int, ...]) -> tuple[list[str], int, int]:
    """Table rows (loop / CMA-ES at each checkpoint), and the cells where the loop is ahead or level, of all."""
    lim = loop["limit"]  # the robot's limit as the loop's runs hold it (`optimize_loop.py limit` keeps it current)
    rows, ahead, total = [], 0, 0
    for r in doc["runs"]:
        kind = r.get("start", "nominal")
        lr = [x for x in loop["runs"] if x["start"] == kind and x["seed"] == r["seed"]]
        if not lr:
            continue
        cells = [kind, str(r["seed"])]
        for c in cps:
            ours = _at(lr[0]["rows"], c, "incumbent_true")
            theirs = _at(r["evals"], c, "best_true")
            fmt = [("—" if v is None else f"{100 * v / lim:.1f}") for v in (ours, theirs)]
            cells.append(" / ".join(fmt))
            total += 1
            # level within REL_LEVEL: the same gait evaluated on two machines differs in its last bits
            ahead += int(ours is not None and (theirs is None or ours >= theirs * (1 - REL_LEVEL)))
        rows.append("| " + " | ".join(cells) + " |")
    return rows, ahead, total


def report() -> None:
    lines = ["# CMA-ES against the loop at the same cycle budget", "",
             f"Measured {stamp()} on {machine()} by `benchmarks/optimize_cma.py`.", "",
             "Each cell: the true speed (on the physics, at its passive periodic steady state) of the gait each "
             "method would return after that many robot cycles, as a % of the limit, from the same start.  CMA-ES "
             "returns its best measured gait within the rotation bound; the loop its incumbent "
             "(`optimize_loop_<robot>.json`).  A '—': nothing measured yet within the bound.", ""]
    for name in CHECKPOINTS:
        path = RESULTS / f"optimize_cma_{name}.json"
        if not path.exists():
            continue
        doc = json.loads(path.read_text())
        loop = json.loads((RESULTS / f"optimize_loop_{name}.json").read_text())
        lim = loop["limit"]
        cps = CHECKPOINTS[name]
        lines += [f"## {name} (limit {lim:.5f} m/s; cma {doc['cma_version']})", "",
                  "| start | seed | " + " | ".join(f"{c} cycles: loop / CMA-ES" for c in cps) + " |",
                  "|---" * (2 + len(cps)) + "|"]
        rows, ahead, total = _cells(doc, loop, cps)
        lines += rows + ["", f"The loop is ahead or level at {ahead} of {total} (seed, budget) cells.", ""]
        for key, (field_name, value, *_) in ABLATIONS.items():  # the loop's ablations (optimize_loop.py --ablation)
            other = RESULTS / f"optimize_loop_{name}_{key}.json"
            if other.exists():
                a_doc = json.loads(other.read_text())
                _, a_ahead, a_total = _cells(doc, a_doc, cps)
                shown = value if a_doc.get(field_name) is None else a_doc[field_name]  # (inf is stored as null)
                lines += [f"With the loop's `{field_name}` = {shown} "
                          f"(`{other.name}`): ahead or level at {a_ahead} of {a_total}.", ""]
    write("optimize_cma.md", "\n".join(lines) + "\n")


def main() -> None:
    run_report_cli(__doc__, sorted(CHECKPOINTS), lambda n, a: run(n, a.seeds), report)


if __name__ == "__main__":
    main()
