"""Diagnosis test helpers: simulate a recording with injected effects, check what was recovered."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest

from suds_ros.core.diagnosis import DiagnosisReport, diagnose
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import purcell3_model, swimmer9_model

MODELS = {"purcell3": purcell3_model, "swimmer9": swimmer9_model}


def _run(system: str, effects: list[dict[str, Any]], cycles: int, seed: int) -> DiagnosisReport:
    base = MODELS[system]()
    model, delay = apply_effects(base, effects)
    rec = simulate(RFTChain(model), SimConfig(cycles=cycles, seed=seed, pose_delay=delay))
    return diagnose(rec, base)


def _check_recovered(rep: DiagnosisReport, effects: list[dict[str, Any]]) -> None:
    d = rep.to_dict()
    assert d["mismatch"] is True
    assert d["unexplained"] is False
    got = {(e["name"], e["target"]): e for e in d["effects"]}  # type: ignore[index,union-attr]
    assert len(got) == len(effects), d["effects"]
    for eff in effects:
        key = (eff["name"], eff.get("joint"))
        assert key in got, (key, d["effects"], d["confounded_with"])
        for p, v in eff.items():
            if p in ("name", "joint"):
                continue
            assert got[key]["parameters"][p] == pytest.approx(v, rel=0.25, abs=0.01 * abs(v) + 1e-3), (p, got[key])
            assert got[key]["stderr"][p] >= 0
    assert d["fit"]["improvement"] >= 0.5  # type: ignore[index]
    # every injected effect is in the lists: no formula may be reported on top of them
    assert d["discovered"] == [], d["discovered"]
    for loc in d["located"]:  # type: ignore[union-attr]
        c = loc["channel"]
        after, before = d["fit"]["heldout_rms_after"][c], d["fit"]["heldout_rms_before"][c]  # type: ignore[index]
        # each located channel halves, or is back at its noise floor (weakly affected channels)
        assert after <= 0.5 * before or after <= 1.5 * rep.noise_floor[c], (c, after, before)


@pytest.fixture(scope="session")
def run_case() -> Callable[[str, list[dict[str, Any]], int, int], DiagnosisReport]:
    """Simulate with the effects injected, diagnose against the nominal model.

    Called as ``run_case(system, effects, cycles, seed)``.
    """
    return _run


@pytest.fixture(scope="session")
def check_recovered() -> Callable[[DiagnosisReport, list[dict[str, Any]]], None]:
    """Check that the injected effects were named, fitted and shown.

    Called as ``check_recovered(report, effects)``.
    """
    return _check_recovered
