"""Seeded corruptions of our bags: never a traceback, never a hang, a clear error or the damage reported.

The corruptions and the outcome classes are in ``_fuzz.py`` (shared with
``benchmarks/fuzz_bags.py``, which runs more cases and writes docs/results/fuzz.md).
"""

from __future__ import annotations

import random
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
from _fuzz import COMPRESSIONS, GOOD, KINDS, corrupt, make_bags, records, run_case

from suds_ros.io.mcap import bag_info
from suds_ros.io.recording_bag import read_recording_report

CASES_PER_KIND = 17  # × 6 kinds × 3 compressions = 306 cases


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory):
    return make_bags(tmp_path_factory.mktemp("fuzz"))


def test_seeded_corruptions(bags, tmp_path: Path) -> None:
    original, data = bags
    outcomes: Counter[tuple[str, str]] = Counter()
    bad = []
    for c in COMPRESSIONS:
        for kind in KINDS:
            for seed in range(CASES_PER_KIND):
                rng = random.Random(f"{c}/{kind}/{seed}")
                path = tmp_path / "case.mcap"
                path.write_bytes(corrupt(data[c], kind, rng))
                out = run_case(path, original)
                outcomes[(kind, out.kind)] += 1
                if out.kind not in GOOD:
                    bad.append((c, kind, seed, out.kind, out.detail))
    assert not bad, bad[:5]
    assert sum(outcomes.values()) == 306
    for kind in KINDS:  # every kind of corruption was caught at least once as damage
        assert outcomes[(kind, "damage reported")] > 0, (kind, outcomes)
    # most damage leaves a usable result rather than an error
    results = sum(n for (_, k), n in outcomes.items() if k != "clear error")
    assert results > 0.8 * 306, outcomes


def test_flipped_zstd_chunk_is_skipped_and_reported(bags, tmp_path: Path) -> None:
    original, data = bags
    raw = bytearray(data["zstd"])
    first_chunk = next(pos for pos, op, _ in records(data["zstd"]) if op == 0x06)
    raw[first_chunk + 200] ^= 0x40  # inside its compressed records
    path = tmp_path / "flip.mcap"
    path.write_bytes(bytes(raw))
    read = read_recording_report(path)
    [d] = read.damage
    assert d.record == "chunk" and d.offset == first_chunk
    assert d.start_ns == 1_700_000_000 * 10**9 and d.end_ns == d.start_ns + 500_000_000
    assert d.messages == 101 and dict(d.topics) == {"/suds/shape": 51, "/suds/body_pose": 50}
    assert read.recording.n_samples == original.n_samples - 51
    assert read.recording.t[0] == pytest.approx(original.t[51])
    assert "101 messages lost" in read.warning()
    info = bag_info(path)
    assert info.damage == read.damage and info.messages_lost == 101


def test_damaged_summary_falls_back_to_the_data_section(bags, tmp_path: Path) -> None:
    original, data = bags
    raw = bytearray(data["lz4"])
    footer = len(raw) - 8 - 29
    summary_start = int.from_bytes(raw[footer + 9:footer + 17], "little")
    raw[summary_start + 30] ^= 0xFF
    path = tmp_path / "summary.mcap"
    path.write_bytes(bytes(raw))
    read = read_recording_report(path)
    [d] = read.damage
    assert d.record == "summary" and "CRC mismatch" in d.reason and d.messages == 0
    assert read.recording.n_samples == original.n_samples


@pytest.mark.parametrize("seed", range(3))
def test_cli_prints_one_line(bags, tmp_path: Path, seed: int) -> None:
    _, data = bags
    rng = random.Random(seed)
    path = tmp_path / "cli.mcap"
    path.write_bytes(corrupt(data["zstd"], ("bit flips", "zeroed range", "huge length")[seed],
                             rng))
    for cmd in (["info", str(path)], ["identify", "--train-cycles", "2", str(path)]):
        proc = subprocess.run([sys.executable, "-m", "suds_ros.cli", *cmd], capture_output=True,
                              text=True, timeout=120)
        assert "Traceback" not in proc.stderr, proc.stderr
        lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
        assert all(ln.startswith(("WARNING: ", "ERROR: ")) for ln in lines), lines
        assert sum(ln.startswith("ERROR: ") for ln in lines) <= 1
        assert sum(ln.startswith("WARNING: ") for ln in lines) <= 1
        assert proc.returncode in (0, 2)
        if cmd[0] == "info":
            assert proc.returncode == 0 and "damage:" in proc.stdout, proc.stdout
