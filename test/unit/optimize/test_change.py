"""Model-free tests on recorded cycles: Hotelling's T² and the passive shapes' shift between runs."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.errors import SudsDataError
from suds_ros.core.optimize.change import hotelling_p, passive_features, passive_shift
from suds_ros.core.recording import Recording

HZ = 0.5


def _run(rng: np.random.Generator, cycles: int, spc: int = 40, shift_from: int | None = None,
         shift: float = 0.0, noise: float = 0.05, passive: bool = True, shift_to: int | None = None) -> Recording:
    """A 2-joint recording: joint a driven, joint p a passive angle 0.3 sin(φ − 0.4) + per-cycle noise."""
    t = np.arange(cycles * spc + 1) / (spc * HZ)
    phi = 2 * np.pi * HZ * t
    cyc = np.minimum((t * HZ + 1e-9).astype(int), cycles - 1)
    wobble = rng.normal(0.0, noise, size=(cycles, 2))  # each cycle's own offset and amplitude
    rp = (0.3 + wobble[cyc, 1]) * np.sin(phi - 0.4) + wobble[cyc, 0]
    if shift_from is not None:
        rp = rp + shift * ((cyc >= shift_from) & (cyc < (cycles if shift_to is None else shift_to)))
    r = np.column_stack([0.8 * np.sin(phi), rp])
    pose = np.column_stack([0.01 * t, np.zeros_like(t), np.zeros_like(t)])
    return Recording(t=t, r=r, joint_names=("a", "p"), actuated=("a", "p") if not passive else ("a",),
                     passive=("p",) if passive else (), pose_t=t, pose=pose, system="test", gait_hz=HZ)


def test_hotelling_p_is_calibrated_for_two_samples() -> None:
    rng = np.random.default_rng(20261202)
    ps = []
    for _ in range(2000):
        a, b = rng.normal(size=(4, 3)), rng.normal(size=(4, 3))
        pooled = (3 * np.cov(a, rowvar=False) + 3 * np.cov(b, rowvar=False)) / 6
        ps.append(hotelling_p(a.mean(0) - b.mean(0), pooled, 2.0, 6))
    ps_arr = np.array(ps)
    assert 0.035 < np.mean(ps_arr < 0.05) < 0.065 and 0.46 < np.mean(ps_arr < 0.5) < 0.54
    assert hotelling_p(np.array([1.0, 0.0]), np.zeros((2, 2)), 4, 3) == 0.0  # no spread, a mean: certain
    assert hotelling_p(np.zeros(2), np.zeros((2, 2)), 4, 3) == 1.0
    assert hotelling_p(np.ones(3), np.eye(3), 2.0, 2) == 1.0  # 3 dimensions on 2 degrees of freedom: cannot say


def test_passive_features_fit_each_cycle_at_any_rate() -> None:
    t = np.sort(np.random.default_rng(3).uniform(0, 3 / HZ, 400))  # jittered stamps, 3 cycles
    t = np.concatenate([[0.0], t, [3 / HZ]])
    phi = 2 * np.pi * HZ * t
    rp = 0.1 + 0.2 * np.cos(phi) - 0.3 * np.sin(phi)
    rec = Recording(t=t, r=np.column_stack([np.sin(phi), rp]), joint_names=("a", "p"), actuated=("a",),
                    passive=("p",), pose_t=t, pose=np.zeros((t.size, 3)), system="test", gait_hz=HZ)
    f = passive_features(rec, HZ)
    assert f.shape == (3, 3, 1) and np.allclose(f[:, :, 0], [0.1, 0.2, -0.3], atol=1e-12)
    sparse = np.linspace(0.0, 1 / HZ, 6)  # 5 samples in its one whole cycle
    rec = Recording(t=sparse, r=np.zeros((6, 2)), joint_names=("a", "p"), actuated=("a",), passive=("p",),
                    pose_t=sparse, pose=np.zeros((6, 3)), system="test", gait_hz=HZ)
    with pytest.raises(SudsDataError, match="at least 6 samples in gait cycle 0, got 5"):
        passive_features(rec, HZ)


def test_passive_shift_sees_a_shifted_spring_and_where_it_began() -> None:
    rng = np.random.default_rng(7)
    ps = [passive_shift(_run(rng, 4), _run(rng, 4), HZ).p for _ in range(300)]  # the same robot: p spread out
    assert np.mean(np.array(ps) < 0.05) < 0.07
    old = [_run(rng, 4), _run(rng, 4)]
    moved = passive_shift(old, _run(rng, 6, shift_from=2, shift=0.6), HZ)
    # (a change inside the run: its old cycles widen the spread, and the p-value stays near 0.01 however
    # large the shift; the next run, all on the changed robot, shows it fully)
    assert moved is not None and moved.p < 0.05 and moved.joint == "p" and moved.cycles == (8, 6)
    assert moved.start == 2  # its first two cycles are the robot as it was
    assert moved.size == pytest.approx(0.6 * 4 / 6, abs=0.06)  # the mean of 6 cycles, 4 of them shifted
    whole = passive_shift(old, _run(rng, 4, shift_from=0, shift=0.3), HZ)
    assert whole is not None and whole.p < 1e-3 and whole.start == 0
    back = passive_shift(old, _run(rng, 6, shift_from=0, shift=0.3, shift_to=5), HZ)  # its last cycle as before
    assert back is not None and back.p < 1e-3 and back.start is None
    assert passive_shift(_run(rng, 4, passive=False), _run(rng, 4, passive=False), HZ) is None
    with pytest.raises(SudsDataError, match="at least 2 whole cycles each"):
        passive_shift(_run(rng, 4), _run(rng, 1), HZ)
