"""Shared fixtures: short simulated runs (session scoped) and the public test recordings.

Tests marked ``ros`` (anywhere in the suite) are skipped when rclpy cannot be
imported; this is the suite's one check of rclpy's availability.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import pytest

SHARED_BAGS = Path(__file__).resolve().parents[1].parent / "shared" / "bags"


@functools.cache
def rclpy_missing() -> str:
    """Why rclpy cannot be imported, "" when it can (imported at the first ``ros`` test only)."""
    try:
        import rclpy  # noqa: F401
    except ImportError as exc:  # pragma: no cover - depends on the environment
        return f"rclpy cannot be imported ({exc})"
    return ""


#: ``SUDS_TEST_PART`` (set by scripts/run_tests.sh, which runs the suite as two processes side by side):
#: ``heavy`` keeps the CPU-bound diagnosis tests, ``rest`` everything else; unset keeps every test
HEAVY_PARTS = ("unit/diagnosis/", "cli/test_model_end_to_end.py")
HEAVY_EXCEPT = ("unit/diagnosis/test_refine.py",)  # moved to the other part to balance the two


def _heavy(item: pytest.Item) -> bool:
    rel = Path(str(item.fspath)).resolve().relative_to(Path(__file__).resolve().parent).as_posix()
    return rel.startswith(HEAVY_PARTS) and not rel.startswith(HEAVY_EXCEPT)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Keep the part of the suite ``SUDS_TEST_PART`` names (``heavy`` or ``rest``; unset: all)."""
    part = os.environ.get("SUDS_TEST_PART", "")
    if part not in ("heavy", "rest"):
        return
    keep, drop = [], []
    for item in items:
        (keep if _heavy(item) == (part == "heavy") else drop).append(item)
    if drop:
        config.hook.pytest_deselected(items=drop)
        items[:] = keep


def pytest_runtest_setup(item: pytest.Item) -> None:
    """Skip ``ros`` tests where rclpy cannot be imported."""
    if item.get_closest_marker("ros") and rclpy_missing():
        pytest.skip(rclpy_missing())


def _shared_bag(name: str) -> Path:
    path = SHARED_BAGS / name
    if not path.exists():
        pytest.skip(f"public recording {path} not available")
    return path


@pytest.fixture(scope="session")
def shared_bag():
    """Function name -> path of a public recording; skips the test when the shared folder is absent."""
    return _shared_bag


@pytest.fixture(scope="session")
def purcell3_run():
    """purcell3, 20 cycles, seed 11, default noise."""
    from suds_ros.core.physics.sim import SimConfig, simulate
    from suds_ros.core.physics.systems import make_system

    return simulate(make_system("purcell3"), SimConfig(cycles=20, seed=11))


@pytest.fixture(scope="session")
def swimmer9_run():
    """swimmer9, 20 cycles, seed 12, default noise."""
    from suds_ros.core.physics.sim import SimConfig, simulate
    from suds_ros.core.physics.systems import make_system

    return simulate(make_system("swimmer9"), SimConfig(cycles=20, seed=12))


#: a fully actuated robot model file (8 links, all 7 joints driven, c⊥/c∥ = 2)
WORM8 = Path(__file__).resolve().parent / "data" / "robots" / "worm8.yaml"


@pytest.fixture(scope="session")
def worm8_model():
    """The fully actuated test robot of ``test/data/robots/worm8.yaml``."""
    from suds_ros.core.physics.robot_model import load_model

    return load_model(WORM8)


@pytest.fixture(scope="session")
def worm8_run(worm8_model):
    """worm8 (fully actuated), 20 cycles, seed 13, default noise."""
    from suds_ros.core.physics.rft import RFTChain
    from suds_ros.core.physics.sim import SimConfig, simulate

    return simulate(RFTChain(worm8_model), SimConfig(cycles=20, seed=13))
