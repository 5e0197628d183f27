"""Seeded corruptions of our own bags and what reading them gives, by kind (docs/results/fuzz.md).

Run: ``python benchmarks/fuzz_bags.py [--cases N] [--quick]`` (N per kind and
compression, default 60).

Each case corrupts a 3-cycle simulated purcell3 bag (zstd, lz4 or no
compression, as ``write_recording`` writes it) in one of the ways of
``test/io/_fuzz.py`` and reads it the way ``suds info`` and ``suds identify``
do, in-process.  Outcomes: *intact* (nothing lost), *damage reported* (a result
with the skipped parts listed, every sample read is the original's),
*truncated* (a prefix, cut between records), *clear error* (a ``SudsError``:
one ``ERROR:`` line on the command line); and the failures *crash* (any other
exception), *hang* (over 10 s) and *silent change* (a result differing from
the original without damage reported).  Peak memory (tracemalloc) is measured
per case, to show that corrupted length fields cause no
large allocations.
"""

from __future__ import annotations

import argparse
import random
import sys
import tempfile
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import ROOT, machine, stamp, write  # noqa: E402

sys.path.insert(0, str(ROOT / "test" / "io"))
from _fuzz import COMPRESSIONS, GOOD, KINDS, corrupt, make_bags, run_case  # noqa: E402

OUTCOMES = ("intact", "damage reported", "truncated", "clear error", "crash", "hang",
            "silent change")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=60, help="cases per kind and compression")
    ap.add_argument("--quick", action="store_true", help="10 cases per kind and compression")
    args = ap.parse_args(argv)
    n = 10 if args.quick else args.cases
    counts: Counter[tuple[str, str]] = Counter()
    by_comp: Counter[tuple[str, str]] = Counter()
    errors: Counter[str] = Counter()
    failures, worst_s, worst_ratio = [], 0.0, 0.0
    with tempfile.TemporaryDirectory() as tmp:
        original, data = make_bags(Path(tmp))
        path = Path(tmp) / "case.mcap"
        for c in COMPRESSIONS:
            for kind in KINDS:
                for seed in range(n):
                    path.write_bytes(corrupt(data[c], kind, random.Random(f"{c}/{kind}/{seed}")))
                    out = run_case(path, original, measure_memory=True)
                    counts[(kind, out.kind)] += 1
                    by_comp[(c, out.kind)] += 1
                    worst_s = max(worst_s, out.seconds)
                    worst_ratio = max(worst_ratio, out.peak_bytes / 2**20)
                    if out.kind == "clear error":
                        errors[_error_class(out.detail)] += 1
                    if out.kind not in GOOD:
                        failures.append(f"{c} / {kind} / seed {seed}: {out.kind}: {out.detail}")
        sizes = {c: len(b) for c, b in data.items()}
    write("fuzz.md", _report(n, counts, by_comp, errors, failures, worst_s, worst_ratio, sizes))
    return 1 if failures else 0


def _error_class(detail: str) -> str:
    """The error message without the path and numbers, to group errors."""
    text = detail.split(": ", 1)[-1]
    for key in ("is not in the bag", "has no messages", "no 'system'", "no 'actuated'",
                "stamps are not sorted", "duplicate stamp", "has type", "cannot decode",
                "truncated MCAP file", "not an MCAP file", "header"):
        if key in text:
            return key
    return text[:60]


def _report(n: int, counts: Counter, by_comp: Counter, errors: Counter, failures: list[str],
            worst_s: float, worst_ratio: float, sizes: dict[str, int]) -> str:
    total = sum(counts.values())
    cols = [o for o in OUTCOMES if any(counts[(k, o)] for k in KINDS) or o in GOOD]
    lines = [
        "# Fuzzing the bag reader", "",
        f"{stamp()} · {machine()} · `python benchmarks/fuzz_bags.py --cases {n}`", "",
        f"{total} seeded corruptions ({n} per kind and compression) of a 3-cycle simulated "
        "purcell3 bag (600 messages; "
        + ", ".join(f"{c} {s} bytes" for c, s in sizes.items()) + "), each read the way "
        "`suds info` and `suds identify` read it.  Failures (crash, hang, silent change): "
        f"**{len(failures)}**.  Slowest case {worst_s * 1e3:.0f} ms (with memory tracing); "
        f"highest peak of traced memory {worst_ratio:.1f} MiB (reading and decoding included: "
        "corrupted length fields cause no large allocation).", "",
        "| corruption | " + " | ".join(cols) + " |",
        "|---|" + "---:|" * len(cols),
    ]
    for kind in KINDS:
        lines.append(f"| {kind} | " + " | ".join(str(counts[(kind, o)]) for o in cols) + " |")
    lines.append("| **all** | " + " | ".join(
        str(sum(counts[(k, o)] for k in KINDS)) for o in cols) + " |")
    lines += ["", "By compression:", "", "| compression | " + " | ".join(cols) + " |",
              "|---|" + "---:|" * len(cols)]
    for c in COMPRESSIONS:
        lines.append(f"| {c} | " + " | ".join(str(by_comp[(c, o)]) for o in cols) + " |")
    lines += ["", "Clear errors, by message:", ""]
    lines += [f"- {k}: {v}" for k, v in errors.most_common()] or ["- none"]
    lines += ["", "Outcomes: *intact* nothing lost (the corruption hit nothing the reader "
              "uses, e.g. a message index it checked and found consistent); *damage reported* "
              "the intact rest was read and every skipped part listed (`suds info` "
              "`damage:` section, a one-line `WARNING:` for identify/diagnose); *truncated* a "
              "prefix of the recording, cut between records; *clear error* a one-line "
              "`ERROR:` (typically: everything holding the topics or the metadata was lost)."]
    if failures:
        lines += ["", "Failures:", ""] + [f"- {f}" for f in failures[:30]]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
