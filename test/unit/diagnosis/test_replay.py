"""Replaying the simulator on the recorded actuation (:mod:`suds_ros.core.diagnosis.replay`)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from suds_ros.core.diagnosis.data import prepare
from suds_ros.core.diagnosis.replay import replay, replay_recording, window_xi
from suds_ros.core.errors import SudsDataError
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import purcell3_model, swimmer9_model


@pytest.mark.parametrize("make_model", [purcell3_model, swimmer9_model], ids=["purcell3", "swimmer9"])
def test_replay_reproduces_the_simulator(make_model) -> None:  # type: ignore[no-untyped-def]
    """Simulator and replay share one integrator: replaying a noise-free simulated recording from
    its recorded state with its recorded actuation gives the simulated trajectory back.  (Stamps
    start at 0: at 1.7e9 s the median sample interval the diagnosis reads is off by ~1e-5.)"""
    model = make_model()
    rec = simulate(RFTChain(model), SimConfig(cycles=6, seed=3, noise_std=0.0, substeps=3, t0=0.0))
    data = prepare(rec, model)
    starts, length = [0, 150, 320], 200
    rep = replay(model, 0.0, data, starts, length, w=10, substeps=3)
    for b, s0 in enumerate(starts):
        truth = rec.truth["r"][s0:s0 + length]
        np.testing.assert_allclose(rep.rp[b], truth[:, data.pas], rtol=0, atol=1e-12)
        np.testing.assert_allclose(rep.pose[b], rec.truth["pose"][s0:s0 + length], rtol=0, atol=1e-9)
    # and a different integration (substeps) does not match to that precision
    other = replay(model, 0.0, data, starts, length, w=10, substeps=1)
    assert np.abs(other.rp - rep.rp).max() > 1e-9


@pytest.mark.parametrize("effect", [dict(name="background_flow", vx=0.1, vy=-0.05),
                                    dict(name="sensor_time_offset", dt=0.03)], ids=lambda e: e["name"])
def test_replay_carries_flow_and_delay(effect) -> None:  # type: ignore[no-untyped-def]
    """The measured ξ of a replay with the effect matches the recording's; without it, it does not."""
    base = purcell3_model()
    model, delay = apply_effects(base, [effect])
    rec = simulate(RFTChain(model), SimConfig(cycles=6, seed=3, noise_std=0.0, pose_delay=delay, substeps=2))
    data = prepare(rec, base)
    xi_rec = window_xi(data.pose[200:500], 10, data.dt)
    rep = replay(model, delay, data, [200], 300, w=10, substeps=2)
    ok = np.all(np.isfinite(rep.xi[0]), axis=1)
    assert ok.sum() > 250
    np.testing.assert_allclose(rep.xi[0][ok], xi_rec[ok], atol=1e-4)
    nominal = replay(base, 0.0, data, [200], 300, w=10, substeps=2)
    assert np.nanmax(np.abs(nominal.xi[0] - xi_rec)) > 2e-2


def test_chunked_replay_equals_the_whole_half_replay(purcell3_run) -> None:  # type: ignore[no-untyped-def]
    model = purcell3_model()
    data = prepare(purcell3_run, model)
    whole = replay_recording(data, model, 0.0, 10, 2, chunk=0)
    pieces = replay_recording(data, model, 0.0, 10, 2, chunk=300, warm=300)
    np.testing.assert_allclose(pieces.rp, whole.rp, atol=1e-6)
    both = np.isfinite(whole.xi) & np.isfinite(pieces.xi)
    assert both.sum() >= 0.98 * np.isfinite(whole.xi).sum()
    np.testing.assert_allclose(pieces.xi[both], whole.xi[both], atol=1e-5)


def test_reference_replaces_the_replay(purcell3_run) -> None:  # type: ignore[no-untyped-def]
    model = purcell3_model()
    data = prepare(purcell3_run, model)
    ref = replay_recording(data, model, 0.0, 10, 2, reference=purcell3_run)
    np.testing.assert_array_equal(ref.rp, data.r[:data.n_used][:, data.pas])
    with pytest.raises(SudsDataError, match="`reference`: must cover the same stamps"):
        replay_recording(data, model, 0.0, 10, 2, reference=purcell3_run.slice(0, 1000))
    shifted = dataclasses.replace(purcell3_run, r=purcell3_run.r + np.array([0.3, 0.0]))
    with pytest.raises(SudsDataError, match="`reference`: its actuated trajectory differs"):
        replay_recording(data, model, 0.0, 10, 2, reference=shifted)
