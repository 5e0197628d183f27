"""Seeded corruptions of our own bags and the outcome of reading them (test_fuzz.py, benchmarks/fuzz_bags.py).

A case corrupts one bag in one way (:data:`KINDS`), then runs the two reading
paths of the command line in-process: ``suds info`` (:func:`bag_info`) and
``suds identify``/``diagnose`` (:func:`read_recording_report`, what
``load_recording`` calls).  :func:`run_case` returns one :class:`Outcome`:

* ``intact``: nothing lost, the recording equals the original;
* ``damage reported``: a result, with the skipped parts in ``damage``, and
  every sample read is a sample of the original;
* ``truncated``: a result ending early, no record damaged (the cut fell
  between records): a prefix of the original;
* ``clear error``: a :class:`~suds_ros.core.errors.SudsError` (the CLI prints it as
  one ``ERROR:`` line);
* failures the test refuses: ``crash`` (any other exception), ``hang``
  (over :data:`TIME_LIMIT_S`), ``silent change`` (a result that differs from the
  original with no damage reported, or samples the original does not have).
"""

from __future__ import annotations

import random
import signal
import time
import tracemalloc
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np

from suds_ros.core.errors import SudsError
from suds_ros.core.recording import Recording
from suds_ros.io.mcap import bag_info
from suds_ros.io.recording_bag import read_recording_report, write_recording

KINDS = ("bit flips", "zeroed range", "truncation", "shuffled records", "duplicated chunk",
         "huge length")
COMPRESSIONS = ("zstd", "lz4", "none")
GOOD = ("intact", "damage reported", "truncated", "clear error")
TIME_LIMIT_S = 10.0


def make_bags(folder: Path, cycles: int = 3, seed: int = 5) -> tuple[Recording, dict[str, bytes]]:
    """A ``cycles``-cycle simulated purcell3 recording and its bytes in each compression."""
    from suds_ros.core.physics.sim import SimConfig, simulate
    from suds_ros.core.physics.systems import make_system

    rec = simulate(make_system("purcell3"), SimConfig(cycles=cycles, seed=seed))
    out = {}
    for c in COMPRESSIONS:
        path = folder / f"purcell3_{c}.mcap"
        write_recording(path, rec, compression=c, overwrite=True)
        out[c] = path.read_bytes()
    return rec, out


def records(data: bytes) -> list[tuple[int, int, int]]:
    """``(offset, opcode, end)`` of the top-level records after the header, up to the footer."""
    pos, out = 8, []
    while pos + 9 <= len(data):
        op, length = data[pos], int.from_bytes(data[pos + 1:pos + 9], "little")
        end = pos + 9 + length
        if end > len(data):
            break
        out.append((pos, op, end))
        if op == 0x02:
            break
        pos = end
    return out


def corrupt(data: bytes, kind: str, rng: random.Random) -> bytes:
    """``data`` corrupted one way (``kind`` from :data:`KINDS`), chosen by ``rng``."""
    buf = bytearray(data)
    n = len(buf)
    if kind == "bit flips":
        for _ in range(rng.randint(1, 4)):
            buf[rng.randrange(n)] ^= 1 << rng.randrange(8)
    elif kind == "zeroed range":
        i = rng.randrange(n)
        k = min(n - i, rng.randint(1, 512))
        buf[i:i + k] = bytes(k)
    elif kind == "truncation":
        del buf[rng.randrange(n):]
    elif kind in ("shuffled records", "duplicated chunk"):
        recs = records(data)
        data_recs = [r for r in recs[1:] if r[1] != 0x0F and r[0] < _data_end(recs)]
        if kind == "shuffled records":
            pieces = [bytes(data[a:b]) for a, _, b in data_recs]
            rng.shuffle(pieces)
            lo, hi = data_recs[0][0], data_recs[-1][2]
            buf[lo:hi] = b"".join(pieces)
        else:
            chunks = [r for r in data_recs if r[1] == 0x06]
            a, _, b = rng.choice(chunks)
            at = rng.choice([r[2] for r in data_recs])
            buf[at:at] = data[a:b]
    elif kind == "huge length":
        pos, _, _ = rng.choice(records(data)[1:])
        value = rng.choice([2**32 + rng.randrange(2**32), 2**63 + rng.randrange(2**62),
                            n + rng.randrange(1, 2**20)])
        buf[pos + 1:pos + 9] = value.to_bytes(8, "little")
    else:
        raise ValueError(f"kind: expected one of {KINDS}, got {kind!r}")
    return bytes(buf)


def _data_end(recs: list[tuple[int, int, int]]) -> int:
    return next((a for a, op, _ in recs if op == 0x0F), recs[-1][2])


@dataclass(frozen=True)
class Outcome:
    """What reading one corrupted bag gave."""

    kind: str  # one of GOOD, or 'crash', 'hang', 'silent change'
    detail: str
    seconds: float
    peak_bytes: int


@contextmanager
def _time_limit(seconds: float) -> Iterator[None]:
    def on_alarm(signum: int, frame: object) -> None:
        raise TimeoutError(f"no result within {seconds} s")

    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def _subset_of(rec: Recording, original: Recording) -> bool:
    """Every shape and pose sample of ``rec`` is the original's sample at that stamp."""
    for t, v, t0, v0 in ((rec.t, rec.r, original.t, original.r),
                         (rec.pose_t, rec.pose, original.pose_t, original.pose)):
        k = np.searchsorted(t0, t)
        if np.any(k >= len(t0)) or not np.array_equal(t0[np.minimum(k, len(t0) - 1)], t):
            return False
        if not np.allclose(v0[k], v, rtol=0, atol=1e-12):
            return False
    return True


def _equal(rec: Recording, original: Recording) -> bool:
    return len(rec.t) == len(original.t) and len(rec.pose_t) == len(original.pose_t) and \
        _subset_of(rec, original)


def run_case(path: Path, original: Recording, *, measure_memory: bool = False) -> Outcome:
    """Read the bag at ``path`` both ways (info, then identify's reader) and classify the result."""
    t0 = time.perf_counter()
    if measure_memory:
        tracemalloc.start()
    try:
        with _time_limit(TIME_LIMIT_S):
            info = bag_info(path)
            read = read_recording_report(path)
    except SudsError as exc:
        kind, detail = "clear error", str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if "\n" in str(exc):
            kind, detail = "crash", f"multi-line error: {exc!r}"
    except TimeoutError as exc:
        kind, detail = "hang", str(exc)
    except Exception as exc:  # noqa: BLE001 - the fuzz test counts every other exception
        kind, detail = "crash", f"{type(exc).__name__}: {exc}"
    else:
        kind, detail = _classify(info, read, original)
    finally:
        peak = tracemalloc.get_traced_memory()[1] if measure_memory else 0
        if measure_memory:
            tracemalloc.stop()
    return Outcome(kind, detail, time.perf_counter() - t0, peak)


def _classify(info, read, original: Recording) -> tuple[str, str]:  # type: ignore[no-untyped-def]
    rec = read.recording
    if tuple(info.damage) != read.damage:
        return "silent change", "bag_info and read_recording_report disagree on the damage"
    if read.damage:
        if not _subset_of(rec, original):
            return "silent change", "damage reported, but samples differ from the original"
        return "damage reported", read.damage[0].describe()
    if read.truncated:
        n = len(rec.t)
        if not _subset_of(rec, original) or not np.array_equal(rec.t, original.t[:n]):
            return "silent change", "truncated, but not a prefix of the original"
        return "truncated", info.problem or ""
    if not _equal(rec, original):
        return "silent change", f"no damage reported, {len(rec.t)} of {len(original.t)} samples"
    return "intact", ""
