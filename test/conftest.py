"""Shared fixtures: short simulated runs (session scoped) and the public test recordings."""

from __future__ import annotations

from pathlib import Path

import pytest

SHARED_BAGS = Path(__file__).resolve().parents[1].parent / "shared" / "bags"


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
