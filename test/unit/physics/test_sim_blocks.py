"""Simulating a few cycles at a time: the blocks are exactly the whole-run recording.

Short runs on a coarse grid (25 samples per cycle, 1 s warm-up) keep these quick; the grid
does not matter to what is tested.
"""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.errors import SudsConfigError
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.lab import LabConditions, simulate_lab, simulate_lab_blocks
from suds_ros.core.physics.sim import (
    SimConfig,
    YawUnwrap,
    ou_path,
    recording_from_blocks,
    simulate,
    simulate_blocks,
)
from suds_ros.core.physics.systems import make_system
from suds_ros.core.recording import Recording


def assert_same_run(a: Recording, b: Recording) -> None:
    """Bit for bit: stamps, measurements and every truth series."""
    for name in ("t", "r", "pose_t", "pose"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.truth.keys() == b.truth.keys()
    for key in a.truth:
        np.testing.assert_array_equal(a.truth[key], b.truth[key], err_msg=f"truth {key}")


def flowing_purcell3():  # type: ignore[no-untyped-def]
    p3 = make_system("purcell3")
    model, _ = apply_effects(p3.model, [{"name": "background_flow", "vx": 0.01, "vy": -0.004}])
    return type(p3)(model)


#: a coarse sample grid and a short warm-up
QUICK = {"samples_per_cycle": 25, "warmup": 1.0}


@pytest.mark.parametrize("config", [
    SimConfig(cycles=4, seed=3, **QUICK),
    SimConfig(cycles=4, seed=3, pose_delay=0.0573, **QUICK),  # the pose read from the past
    SimConfig(cycles=4, seed=3, pose_delay=-0.0613, **QUICK),  # ... and ahead: it waits for the integration
    SimConfig(cycles=3, seed=1, samples_per_cycle=25, warmup=0.0, noise_std=0.0),
], ids=["plain", "late_pose", "early_pose", "no_warmup"])
def test_one_cycle_blocks_give_the_whole_run(config: SimConfig) -> None:
    p3 = make_system("purcell3")
    whole = simulate(p3, config, block_cycles=config.cycles)
    assert_same_run(simulate(p3, config, block_cycles=1), whole)
    assert_same_run(simulate(p3, config, block_cycles=3), whole)
    blocks = list(simulate_blocks(p3, config, block_cycles=1))
    assert len(blocks) == config.cycles and all(b.t.size == config.samples_per_cycle for b in blocks)


def test_blocks_with_a_flow_and_a_nine_link_chain() -> None:
    cfg = SimConfig(cycles=3, seed=2, **QUICK)
    for system in (flowing_purcell3(), make_system("swimmer9")):
        assert_same_run(simulate(system, cfg, block_cycles=1), simulate(system, cfg, block_cycles=3))


@pytest.mark.parametrize("lab", [
    LabConditions(),
    LabConditions(pose_hz=30.0, jitter=3e-3, drop=0.05, oversample=3),
], ids=["default", "30Hz"])
@pytest.mark.parametrize("delay", [0.0, 0.052, -0.0551])
def test_lab_blocks_give_the_whole_run(lab: LabConditions, delay: float) -> None:
    p3 = make_system("purcell3")
    cfg = SimConfig(cycles=4, seed=7, pose_delay=delay, **QUICK)
    whole = simulate_lab(p3, cfg, lab, block_cycles=4)
    blocks = list(simulate_lab_blocks(p3, cfg, lab, block_cycles=1))
    assert len(blocks) == 4 and all(b.t.size > 0.8 * cfg.samples_per_cycle for b in blocks)
    assert_same_run(recording_from_blocks(p3, cfg.gait_hz, blocks), whole)


def test_lab_blocks_with_a_flow() -> None:
    cfg = SimConfig(cycles=3, seed=4, **QUICK)
    p3 = flowing_purcell3()
    assert_same_run(simulate_lab(p3, cfg, LabConditions(), block_cycles=1),
                    simulate_lab(p3, cfg, LabConditions(), block_cycles=3))


def test_ou_path_continued_is_one_path() -> None:
    whole = ou_path(np.random.default_rng(5), 300, 2, 0.01, 8.0, 0.175)
    rng = np.random.default_rng(5)
    first = ou_path(rng, 120, 2, 0.01, 8.0, 0.175)
    rest = ou_path(rng, 180, 2, 0.01, 8.0, 0.175, prev=first[-1])
    np.testing.assert_array_equal(np.concatenate([first, rest]), whole)
    assert ou_path(rng, 0, 2, 0.01, 8.0, 0.175).shape == (0, 2)


def test_yaw_unwrap_continued_is_numpys_unwrap_of_the_whole() -> None:
    rng = np.random.default_rng(0)
    yaw = np.cumsum(rng.normal(scale=2.0, size=500))  # many jumps beyond π
    yaw = np.angle(np.exp(1j * yaw))  # wrapped into (−π, π]
    unwrap = YawUnwrap()
    cuts = [0, 1, 2, 40, 40, 41, 300, 500]
    got = np.concatenate([unwrap(yaw[a:b]) for a, b in zip(cuts[:-1], cuts[1:])])
    np.testing.assert_array_equal(got, np.unwrap(yaw))


def test_arguments_are_checked_before_the_first_block() -> None:
    p3 = make_system("purcell3")
    with pytest.raises(SudsConfigError, match="`block_cycles`: expected a whole number ≥ 1, got 0"):
        simulate_blocks(p3, SimConfig(cycles=2), block_cycles=0)
    with pytest.raises(SudsConfigError, match="`pose_delay`: 30.0 s exceeds the simulated span"):
        simulate_blocks(p3, SimConfig(cycles=2, pose_delay=30.0))
    with pytest.raises(SudsConfigError, match="`pose_delay`: expected |delay| <"):
        simulate_lab_blocks(p3, SimConfig(cycles=2, pose_delay=-1.5))
