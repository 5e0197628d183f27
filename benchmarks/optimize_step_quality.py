"""How much the loop's predicted gains say about the true ones, read from the loop benchmark's runs.

For every candidate gait the loop ran (not a re-run of its incumbent), the gain its step's model
predicted, prediction − the incumbent's true speed, against the true gain, the candidate's true
speed − the incumbent's, both on the physics at the passive periodic steady state
(``docs/results/optimize_loop_<robot>.json`` and the oracle ablation's ``…_oracle.json``, whose runs
are judged on the truth, so their incumbents are the truly better gaits).  The model's bias on the
incumbent itself is part of each predicted gain: the rows store the candidate's prediction only.

    python benchmarks/optimize_step_quality.py      # → docs/results/optimize_step_quality.md

It runs nothing: it reads the stored runs (re-run ``optimize_loop.py`` first to measure new code).
"""

from __future__ import annotations

import json

import numpy as np
from _common import RESULTS, stamp, write
from optimize_loop import ROBOTS


def gains(doc: dict) -> tuple[np.ndarray, np.ndarray]:
    """(predicted gain, true gain) of every candidate in a loop benchmark JSON, m/s."""
    pred, true = [], []
    for run in doc["runs"]:
        rows = run["rows"]
        for prev, row in zip(rows, rows[1:]):
            inc = prev["incumbent_true"]
            if row["predicted"] is None or row["true"] == inc:  # (no model step, or the incumbent run again)
                continue
            pred.append(row["predicted"] - inc)
            true.append(row["true"] - inc)
    return np.asarray(pred), np.asarray(true)


def main() -> None:
    lines = ["# The loop's steps: predicted gain against true gain", "",
             f"Read {stamp()} by `benchmarks/optimize_step_quality.py` from the stored loop runs "
             "(their machines and dates are in `optimize_loop.md`).", "",
             __doc__.split("\n\n")[1].replace("\n", " "), "",
             "| robot | runs | candidates | median predicted gain (m/s) | median true gain (m/s) | "
             "true gain > 0 | correlation (predicted, true) | median true / predicted gain, where predicted > 0 |",
             "|---|---|---|---|---|---|---|---|"]
    for name in ROBOTS:
        for tag, suffix in (("default", ""), ("oracle", "_oracle")):
            path = RESULTS / f"optimize_loop_{name}{suffix}.json"
            if not path.exists():
                continue
            pred, true = gains(json.loads(path.read_text()))
            if pred.size < 3:
                continue
            pos = pred > 0
            ratio = np.median(true[pos] / pred[pos]) if pos.any() else float("nan")
            lines.append(f"| {name} ({tag}) | {len(json.loads(path.read_text())['runs'])} | {pred.size} | "
                         f"{np.median(pred):+.4f} | {np.median(true):+.4f} | {np.mean(true > 0):.2f} | "
                         f"{np.corrcoef(pred, true)[0, 1]:+.2f} | {ratio:+.2f} |")
    lines += ["", "A correlation near zero: the step's model ranks candidates no better than chance, so a "
              "candidate is as likely to be slower as faster, whatever the model predicted; the trust region "
              "then only bounds how far a step strays.", ""]
    write("optimize_step_quality.md", "\n".join(lines))


if __name__ == "__main__":
    main()
