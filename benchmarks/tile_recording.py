"""Make a long recording by tiling a shorter one in time (for the long-identify benchmarks).

Run: ``python benchmarks/tile_recording.py SRC.mcap OUT.mcap --tiles 6``.  The source's first
whole gait cycles (``--cycles``, default every whole cycle it holds) are repeated ``--tiles``
times: tile k is the same samples with every stamp shifted by k whole cycles, so the gait
phase carries on across a seam up to the drive's own cycle-to-cycle drift.  The pose of each
tile is moved rigidly (an SE(2) transform) so that it starts where the previous tile ends:
the body pose is continuous and the body velocity unchanged.  The joint values jump at a seam
by whatever the source's last cycle and first cycle differ by (one interval per seam).

The file is written block by block with the project's :class:`RecordingWriter`, so memory does
not grow with the number of tiles.  A tiled recording is *not* a simulation of that length: it
holds the source's noise and drive realisation over and over; results made from it say so.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import ROOT  # noqa: E402,F401 - puts the package on sys.path

from suds_ros.io.recording_bag import RecordingWriter, read_recording_report  # noqa: E402


def _compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """SE(2) product a ∘ b of poses (x, y, yaw); ``a`` (3,), ``b`` (n, 3)."""
    c, s = np.cos(a[2]), np.sin(a[2])
    return np.column_stack([a[0] + c * b[:, 0] - s * b[:, 1], a[1] + s * b[:, 0] + c * b[:, 1], a[2] + b[:, 2]])


def _inverse(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a[2]), np.sin(a[2])
    return np.array([-c * a[0] - s * a[1], s * a[0] - c * a[1], -a[2]])


def tile(src: str | Path, out: str | Path, tiles: int, cycles: int | None = None,
         block_cycles: int = 20, overwrite: bool = False) -> tuple[int, int, int]:
    """Write ``tiles`` copies of the first ``cycles`` whole cycles of ``src`` to ``out``.

    Returns (cycles per tile, shape samples, pose samples) written.
    """
    read = read_recording_report(src)
    if read.warning():
        print(f"source: {read.warning()}", file=sys.stderr)
    rec = read.recording
    hz = rec.gait_hz or 1.0
    whole = int(np.floor((rec.t[-1] - rec.t[0]) * hz))  # the sample at t0 + whole/hz is still there
    cycles = whole if cycles is None else cycles
    if not 1 <= cycles <= whole:
        raise SystemExit(f"--cycles: expected 1 … {whole}, got {cycles}")
    period = cycles / hz
    t0 = rec.t[0]
    eps = 0.5 * rec.dt
    ks = int(np.searchsorted(rec.t, t0 + period - eps))  # shape samples of one tile
    kp0 = int(np.searchsorted(rec.pose_t, t0 - eps))
    kp1 = int(np.searchsorted(rec.pose_t, t0 + period - eps))
    # the pose one period on, relative to the first: each tile starts where the last one ended
    step = _compose(_inverse(rec.pose[kp0]), rec.pose_at(np.array([t0 + period])))[0]
    offset = np.zeros(3)
    n_shape = n_pose = 0
    with RecordingWriter(out, system=rec.system, joint_names=rec.joint_names, actuated=rec.actuated,
                         passive=rec.passive, gait_hz=rec.gait_hz, overwrite=overwrite) as w:
        for k in range(tiles):
            base = _compose(offset, _inverse(rec.pose[kp0])[None])[0]  # offset ∘ g0⁻¹
            for c0 in range(0, cycles, block_cycles):
                c1 = min(c0 + block_cycles, cycles)
                a, b = np.searchsorted(rec.t[:ks], t0 + np.array([c0, c1]) / hz - eps)
                pa, pb = np.searchsorted(rec.pose_t[kp0:kp1], t0 + np.array([c0, c1]) / hz - eps) + kp0
                shift = k * period
                w.write(rec.t[a:b] + shift, rec.r[a:b], rec.pose_t[pa:pb] + shift,
                        _compose(base, rec.pose[pa:pb]),
                        None if rec.effort is None else rec.effort[a:b])
                n_shape += b - a
                n_pose += pb - pa
            offset = _compose(offset, step[None])[0]
    return cycles, n_shape, n_pose


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("src")
    p.add_argument("out")
    p.add_argument("--tiles", type=int, required=True)
    p.add_argument("--cycles", type=int, default=None, help="whole cycles per tile (default: all)")
    p.add_argument("--overwrite", action="store_true")
    a = p.parse_args(argv)
    cycles, n_shape, n_pose = tile(a.src, a.out, a.tiles, a.cycles, overwrite=a.overwrite)
    print(f"{a.out}: {a.tiles} tiles of {cycles} cycles of {a.src}: {n_shape} shape samples, {n_pose} poses")
    return 0


if __name__ == "__main__":
    sys.exit(main())
