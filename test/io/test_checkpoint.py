"""Checkpoints are data: npz arrays and a versioned JSON header; bad files are refused with a code."""

from __future__ import annotations

import io
import json
import pickle
import zipfile

import numpy as np
import pytest

from suds_ros.core.errors import CHECKPOINT_DAMAGED, CHECKPOINT_VERSION, SudsDataError
from suds_ros.core.ident.online import OnlineSudsEstimator, fit_streaming
from suds_ros.core.ident.session import EstimatorSession, SessionConfig
from suds_ros.io import checkpoint
from suds_ros.io.checkpoint import FORMAT_VERSION, load_estimator, save_estimator, state_from_bytes, state_to_bytes


def _feed(est: OnlineSudsEstimator, rec, k0: int, k1: int) -> None:
    for k in range(k0, k1):
        est.add_pose(float(rec.pose_t[k]), *map(float, rec.pose[k]))
        est.add_shape(float(rec.t[k]), rec.joint_names, rec.r[k])


@pytest.fixture(scope="module")
def rec(purcell3_run):
    return purcell3_run.slice(0, 1200)


@pytest.mark.parametrize("cut", [300, 700])  # before and after the phase initialisation
def test_checkpoint_resumes_to_the_same_model(rec, tmp_path, cut: int) -> None:
    ref = fit_streaming(rec)
    est = OnlineSudsEstimator(rec.joint_names, rec.actuated)
    _feed(est, rec, 0, cut)
    est.add_shape(float(rec.t[cut]), rec.joint_names, rec.r[cut])  # one shape waiting for its pose
    path = tmp_path / "est.ckpt"
    save_estimator(path, est)
    back = load_estimator(path)
    assert back.already_seen(float(rec.t[cut])) and not back.already_seen(float(rec.t[cut + 1]))
    assert back.waiting_for_pose == 1 and back.initialised == est.initialised
    back.add_pose(float(rec.pose_t[cut]), *map(float, rec.pose[cut]))
    _feed(back, rec, cut + 1, rec.n_samples)
    np.testing.assert_allclose(back.model().coef, ref.model().coef, rtol=0, atol=1e-9)
    assert back.running_gamma() == pytest.approx(ref.running_gamma(), abs=1e-9)


def test_the_file_is_an_npz_with_a_json_header_and_no_pickles(rec, tmp_path) -> None:
    est = fit_streaming(rec.slice(0, 800))
    path = tmp_path / "est.ckpt"
    save_estimator(path, est)
    with np.load(path, allow_pickle=False) as z:  # every member loads without pickle
        header = json.loads(z["header"].tobytes().decode())
        for name in z.files:
            assert z[name].dtype.kind in "fiubc"
    assert header["format"] == "suds_ros.estimator_checkpoint" and header["version"] == FORMAT_VERSION
    assert header["state"]["$obj"] == "OnlineSudsEstimator"


def _rewrite_header(data: bytes, **changes) -> bytes:
    with np.load(io.BytesIO(data), allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    header = json.loads(arrays["header"].tobytes().decode())
    header.update(changes)
    arrays["header"] = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def test_bad_files_are_refused_with_a_code(rec, tmp_path) -> None:
    good = state_to_bytes(fit_streaming(rec.slice(0, 800)))
    cases = {
        "not a zip": (b"nope", CHECKPOINT_DAMAGED),
        "truncated": (good[: len(good) // 2], CHECKPOINT_DAMAGED),
        "another version": (_rewrite_header(good, version=FORMAT_VERSION - 1), CHECKPOINT_VERSION),
        "another program": (_rewrite_header(good, format="something.else"), CHECKPOINT_VERSION),
        "unknown class": (_rewrite_header(good, state={"$obj": "os.system", "attrs": {}}), CHECKPOINT_VERSION),
        "bad tree": (_rewrite_header(good, state={"$ref": "a999"}), CHECKPOINT_DAMAGED),
    }
    for name, (data, code) in cases.items():
        with pytest.raises(SudsDataError) as info:
            state_from_bytes(data, name)
        assert info.value.code == code, name
        assert name in str(info.value)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        zf.writestr("other.npy", b"x")
    with pytest.raises(SudsDataError, match="no checkpoint header") as info:
        state_from_bytes(buf.getvalue())
    assert info.value.code == CHECKPOINT_DAMAGED


def test_a_pickle_is_never_run(tmp_path) -> None:
    """An old pickle checkpoint (or a hostile one) is refused without executing anything."""
    marker = tmp_path / "ran"

    class Evil:
        def __reduce__(self):  # type: ignore[no-untyped-def]
            return (open, (str(marker), "w"))

    path = tmp_path / "est.ckpt"
    path.write_bytes(pickle.dumps(Evil()))
    with pytest.raises(SudsDataError) as info:
        load_estimator(path)
    assert info.value.code == CHECKPOINT_DAMAGED and not marker.exists()


def test_a_refused_checkpoint_is_moved_aside_and_the_session_starts_afresh(rec, tmp_path) -> None:
    path = tmp_path / "est.ckpt"
    path.write_bytes(_rewrite_header(state_to_bytes(fit_streaming(rec.slice(0, 800))), version=1))
    logs: list[tuple[str, str]] = []
    s = EstimatorSession(SessionConfig(actuated=tuple(rec.actuated), checkpoint=str(path)),
                         log=lambda lv, t: logs.append((lv, t)), checkpoints=checkpoint)
    aside = tmp_path / "est.ckpt.refused-1"
    assert aside.exists() and not path.exists() and s.est is None and s.refused_checkpoint == str(aside)
    assert any(lv == "error" and CHECKPOINT_VERSION in t and str(aside) in t for lv, t in logs)
    assert s.status_values()["refused_checkpoint"] == str(aside)
    # a second refusal does not overwrite the first one's file
    path.write_bytes(b"garbage")
    EstimatorSession(SessionConfig(actuated=tuple(rec.actuated), checkpoint=str(path)), checkpoints=checkpoint)
    assert aside.exists() and (tmp_path / "est.ckpt.refused-2").read_bytes() == b"garbage"


def test_a_checkpoint_of_other_joints_is_refused(rec, tmp_path) -> None:
    path = tmp_path / "est.ckpt"
    save_estimator(path, fit_streaming(rec.slice(0, 800)))
    s = EstimatorSession(SessionConfig(actuated=("joint_2",), checkpoint=str(path)), checkpoints=checkpoint)
    assert s.est is None and s.refused_checkpoint.endswith(".refused-1")


def test_a_checkpoint_holds_the_live_grid_of_a_jittered_stream(tmp_path) -> None:
    """Saved mid-stream with samples held for the grid, the estimator resumes to the same model."""
    from suds_ros.core.physics.lab import LabConditions, simulate_lab
    from suds_ros.core.physics.sim import SimConfig
    from suds_ros.core.physics.systems import make_system

    lab = simulate_lab(make_system("purcell3"), SimConfig(cycles=10, seed=2), LabConditions(jitter=0.002))
    events = sorted([(t, 1, k) for k, t in enumerate(lab.t)] + [(t, 0, k) for k, t in enumerate(lab.pose_t)])

    def feed(est: OnlineSudsEstimator, part) -> None:  # type: ignore[no-untyped-def]
        for t, kind, k in part:
            if kind:
                est.add_shape(float(t), lab.joint_names, lab.r[k])
            else:
                est.add_pose(float(t), *map(float, lab.pose[k]))

    ref = fit_streaming(lab)
    est = OnlineSudsEstimator(lab.joint_names, lab.actuated)
    cut = len(events) // 2
    feed(est, events[:cut])
    assert est.regrid.mode == "grid" and est.held > 0
    save_estimator(tmp_path / "est.ckpt", est)
    back = load_estimator(tmp_path / "est.ckpt")
    assert back.held == est.held and back.last_shape_stamp == est.last_shape_stamp
    feed(back, events[cut:])
    back.drain()
    np.testing.assert_allclose(back.model().coef, ref.model().coef, rtol=0, atol=1e-9)
