"""The estimator session without ROS: pairing by stamps under adversarial delivery, roles, resume, cadence.

Every test feeds the samples of one simulated run in some delivery order and
checks that no sample that could be paired was dropped: the estimator took
every shape sample, none as ``dropped_no_pose``, none still waits, and the
model equals the one of an in-order run.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pytest

from suds_ros.core.errors import DUPLICATE_STAMP, OUT_OF_ORDER_STAMP, QUEUE_FULL, WRONG_JOINT_NAMES
from suds_ros.core.ident.online import OnlineConfig, fit_streaming
from suds_ros.core.ident.session import EstimatorSession, SessionConfig
from suds_ros.io import checkpoint

N = 1200  # 12 gait cycles at 100 Hz


class Shape(NamedTuple):
    stamp: float
    names: tuple[str, ...]
    position: np.ndarray


class Pose(NamedTuple):
    stamp: float
    x: float
    y: float
    yaw: float


@pytest.fixture(scope="module")
def rec(purcell3_run):
    return purcell3_run.slice(0, N)


@pytest.fixture(scope="module")
def reference(rec):
    return fit_streaming(rec, SessionConfig().online_config(1.0)).model()


def shape(rec, k: int) -> Shape:
    return Shape(float(rec.t[k]), rec.joint_names, rec.r[k])


def pose(rec, k: int) -> Pose:
    return Pose(float(rec.pose_t[k]), *map(float, rec.pose[k]))


def run(rec, order, session: EstimatorSession | None = None, **cfg) -> EstimatorSession:
    """Deliver ``order`` = [("s" | "p", k), ...]; the wall clock never advances (no time rule can act)."""
    s = session or EstimatorSession(SessionConfig(actuated=tuple(rec.actuated), **cfg))
    for kind, k in order:
        if kind == "s":
            s.on_shape(shape(rec, k), now=0.0)
        else:
            s.on_pose(pose(rec, k), now=0.0)
    return s


def assert_nothing_lost(s: EstimatorSession, reference, n: int = N) -> None:
    est = s.est
    values = s.status_values()
    assert est.n_shape == n and est.n_pose == n, values
    assert est.dropped_no_pose == 0 and values["waiting_for_pose"] == "0", values
    got = est.model()
    assert got.n_samples == reference.n_samples
    np.testing.assert_allclose(got.coef, reference.coef, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got.template_coef, reference.template_coef, rtol=0, atol=1e-12)


def test_in_order(rec, reference) -> None:
    assert_nothing_lost(run(rec, [(c, k) for k in range(N) for c in "sp"]), reference)


@pytest.mark.parametrize("lag", [1, 37, 400])
def test_poses_late_by_many_samples(rec, reference, lag: int) -> None:
    order = []
    for k in range(N + lag):
        if k < N:
            order.append(("s", k))
        if k >= lag:
            order.append(("p", k - lag))
    assert_nothing_lost(run(rec, order), reference)


def test_shapes_late_by_many_samples(rec, reference) -> None:
    order = [("p", k) for k in range(300)] + [x for k in range(300, N) for x in (("p", k), ("s", k - 300))]
    order += [("s", k) for k in range(N - 300, N)]
    assert_nothing_lost(run(rec, order), reference)


def test_bursts(rec, reference) -> None:
    """Whole bursts of one stream, then of the other, of irregular lengths (up to 4.5 s of stamps)."""
    rng = np.random.default_rng(3)
    order, ks, kp = [], 0, 0
    while ks < N or kp < N:
        b = int(rng.integers(1, 450))
        order += [("s", k) for k in range(ks, min(N, ks + b))]
        ks = min(N, ks + b)
        b = int(rng.integers(1, 450))
        order += [("p", k) for k in range(kp, min(N, kp + b))]
        kp = min(N, kp + b)
    assert_nothing_lost(run(rec, order, pose_stall=5.0), reference)


@pytest.mark.parametrize("first", ["s", "p"])
def test_history_burst_of_one_whole_stream_then_the_other(rec, reference, first: str) -> None:
    """A restarted node gets the history of one topic long before the other's (seen under load)."""
    second = "p" if first == "s" else "s"
    assert_nothing_lost(run(rec, [(first, k) for k in range(N)] + [(second, k) for k in range(N)]), reference)


def test_pose_stream_stalls_then_resumes_with_its_backlog(rec, reference) -> None:
    """Poses of stamps 3–7 s arrive only after the shapes up to 7.5 s (the stream stalled 4.5 s)."""
    order = [x for k in range(300) for x in (("s", k), ("p", k))]
    order += [("s", k) for k in range(300, 750)]
    order += [("p", k) for k in range(300, 750)]
    order += [x for k in range(750, N) for x in (("s", k), ("p", k))]
    s = run(rec, order[:1050], pose_stall=5.0)
    assert s.pose_stalled() is None  # 4.5 s ahead: within pose_stall
    assert_nothing_lost(run(rec, order[1050:], session=s), reference)


def test_stall_longer_than_pose_stall_gives_up_only_what_cannot_be_paired(rec) -> None:
    """The pose stream stops for good at 6 s: the shapes after it are given up, the rest are paired."""
    logs: list[tuple[str, str]] = []
    s = EstimatorSession(SessionConfig(actuated=tuple(rec.actuated), pose_stall=1.0,
                                       online=OnlineConfig(max_pose_wait=1.0)),
                         log=lambda level, text: logs.append((level, text)))
    run(rec, [x for k in range(N) for x in ((("s", k), ("p", k)) if k < 600 else (("s", k),))], session=s)
    assert s.pose_stalled() == pytest.approx(rec.t[N - 1] - rec.t[599])
    model, status = s.tick(now=10.0)
    assert status.level == "WARN" and "pose stream stalled since 6.0 s" in status.message
    s.tick(now=20.0)
    assert [t for _, t in logs].count("pose stream stalled since 6.0 s") == 1
    est = s.est
    # every shape is taken; those within max_pose_wait (1 s) of the newest still wait, older ones
    # after the last pose are given up, every one up to the last pose is paired
    waiting = int(status.values["waiting_for_pose"])
    assert est.n_shape == N and 99 <= waiting <= 101
    assert est.dropped_no_pose == N - 600 - waiting
    assert est.n_rows + 1 + est.dropped_no_pose + waiting == N


def test_duplicates_and_out_of_order_are_skipped_with_codes(rec, reference) -> None:
    order = []
    for k in range(N):
        order += [("s", k), ("p", k)]
        if k % 97 == 5:
            order += [("s", k), ("p", k), ("s", k - 3), ("p", k - 3)]  # re-sent and stale samples
    s = run(rec, order)
    assert_nothing_lost(s, reference)
    n = len([k for k in range(N) if k % 97 == 5])
    assert s.skipped == {f"shape.{DUPLICATE_STAMP}": n, f"pose.{DUPLICATE_STAMP}": n,
                         f"shape.{OUT_OF_ORDER_STAMP}": n, f"pose.{OUT_OF_ORDER_STAMP}": n}


def test_out_of_order_delivery_within_each_stream_is_reported_not_reordered(rec) -> None:
    s = run(rec, [("s", 1), ("s", 0), ("p", 0), ("p", 1)])
    assert s.skipped == {f"shape.{OUT_OF_ORDER_STAMP}": 1}
    assert s.est.n_shape == 1 and s.est.dropped_no_pose == 0


def test_roles_from_a_system_description_arrive_after_the_samples(rec, reference) -> None:
    s = EstimatorSession(SessionConfig())
    assert s.needs_system and s.status().message.startswith("waiting for joint roles")
    run(rec, [x for k in range(500) for x in (("p", k), ("s", k))], session=s)
    assert s.est is None and s.status_values()["waiting_for_pose"] == "500"
    s.on_system({"joint_names": list(rec.joint_names), "actuated": list(rec.actuated), "gait_hz": 1.0,
                 "system": "purcell3"})
    assert not s.needs_system
    assert_nothing_lost(run(rec, [x for k in range(500, N) for x in (("s", k), ("p", k))], session=s), reference)


def test_wrong_joints_and_full_queue(rec) -> None:
    s = EstimatorSession(SessionConfig(history_depth=5))
    for k in range(7):
        s.on_shape(shape(rec, k), now=0.0)
    assert s.skipped == {f"shape.{QUEUE_FULL}": 2}
    s = run(rec, [("s", 0)])
    s.on_shape(Shape(float(rec.t[1]), ("a", "b"), rec.r[1]), now=0.0)
    assert s.skipped == {f"shape.{WRONG_JOINT_NAMES}": 1}


def test_resume_from_checkpoint_with_replayed_history(rec, reference, tmp_path) -> None:
    """Killed after 700 samples; restarted, it gets the whole history back in adversarial order."""
    ckpt = str(tmp_path / "est.ckpt")
    cfg = dict(checkpoint=ckpt, checkpoint_period=1.0)
    first = EstimatorSession(SessionConfig(actuated=tuple(rec.actuated), **cfg), checkpoints=checkpoint)
    run(rec, [x for k in range(700) for x in (("s", k), ("p", k))], session=first)
    first.tick(now=2.0)  # the periodic checkpoint
    logs: list[str] = []
    s = EstimatorSession(SessionConfig(actuated=tuple(rec.actuated), **cfg), log=lambda lv, t: logs.append(t),
                         checkpoints=checkpoint)
    assert s.resumed_from == ckpt and any("resumed from checkpoint" in t for t in logs)
    order = [("s", k) for k in range(0, 1000)] + [("p", k) for k in range(0, N)] + [("s", k) for k in range(1000, N)]
    run(rec, order, session=s)
    assert s.replayed == 700 and s.replayed_pose == 700
    assert_nothing_lost(s, reference)


def test_cadence(rec) -> None:
    cfg = SessionConfig(actuated=tuple(rec.actuated), online=OnlineConfig(chunk=50), status_period=1.0,
                        idle_flush=2.0)
    s = EstimatorSession(cfg, now=0.0)
    published = [m for k in range(700) for m in (s.on_shape(shape(rec, k), now=0.0), s.on_pose(pose(rec, k), now=0.0))]
    assert sum(m is not None for m in published) >= 1  # after the fitted chunks
    model, status = s.tick(now=0.5)
    assert model is None and status is None
    model, status = s.tick(now=2.5)  # idle: the partial chunk is published
    assert model is not None and model.n_samples == 699 and status.level == "OK"
    assert s.tick(now=3.0)[0] is None  # nothing new
    s.config = SessionConfig(actuated=tuple(rec.actuated), model_period=0.5)
    s.on_shape(shape(rec, 700), now=3.0)
    s.on_pose(pose(rec, 700), now=3.0)
    assert s.tick(now=3.6)[0] is not None
    assert s.close() is None


def test_a_new_gait_starts_the_estimator_afresh_from_a_cycle_after_the_switch(purcell3_run) -> None:
    """The template and model are local to a gait: after a switch the estimator sees only the new gait's samples
    from one cycle (the fade) after the switch stamp, and fits exactly what a fresh one fits on them."""
    long = purcell3_run  # 20 cycles: 6 of the old gait, then the new one
    n, half = long.n_samples, 600
    s = run(long, [(c, k) for k in range(half) for c in "sp"])
    old = s.est
    switched = float(long.t[half])
    assert not EstimatorSession(SessionConfig(actuated=tuple(long.actuated))).new_gait(1.0, switched)  # no roles
    assert s.new_gait(1.0, switched) and s.est is not old and s.est.n_shape == 0
    run(long, [(c, k) for k in range(half, n) for c in "sp"], session=s)
    skipped = int(np.sum(long.t[half:n] < switched + 1.0)) + int(np.sum(long.pose_t[half:n] < switched + 1.0))
    assert s.gait_settling == skipped and s.gaits == 2
    after = long.slice(half + 100, n)
    fresh = run(after, [(c, k) for k in range(after.n_samples) for c in "sp"])
    np.testing.assert_allclose(s.est.model().coef, fresh.est.model().coef, rtol=0, atol=1e-12)
    # a switch before the first sample taken is the gait the stream began with: nothing to forget
    again = run(long, [("s", 0), ("p", 0)])
    assert not again.new_gait(1.0, float(long.t[0]) - 0.5)


def test_a_jittered_stream_in_any_interleaving_gives_one_model_and_idle_releases_the_held(tmp_path) -> None:
    """The live grid sees shape stamps in order whatever the arrival; what it holds at a pause is fitted."""
    from suds_ros.core.physics.lab import LabConditions, simulate_lab
    from suds_ros.core.physics.sim import SimConfig
    from suds_ros.core.physics.systems import make_system

    lab = simulate_lab(make_system("purcell3"), SimConfig(cycles=9, seed=4), LabConditions(jitter=0.002))
    shapes = [Shape(float(t), lab.joint_names, lab.r[k]) for k, t in enumerate(lab.t)]
    poses = [Pose(float(t), *map(float, lab.pose[k])) for k, t in enumerate(lab.pose_t)]
    ref = fit_streaming(lab, SessionConfig().online_config(1.0)).model()
    in_stamp_order = sorted([(m.stamp, 1, m) for m in shapes] + [(p.stamp, 0, p) for p in poses],
                            key=lambda e: e[:2])
    shapes_first = [(0.0, 1, m) for m in shapes] + [(0.0, 0, p) for p in poses]  # the pose stream all late
    models = []
    for order in (in_stamp_order, shapes_first):
        s = EstimatorSession(SessionConfig(actuated=tuple(lab.actuated)), now=0.0)
        for _, kind, msg in order:
            (s.on_shape if kind else s.on_pose)(msg, now=0.0)
        values = s.status_values()
        assert values["shape_grid"] == "grid" and int(values["held_for_grid"]) > 0
        model, _ = s.tick(now=10.0)  # idle: the held samples are released and fitted
        assert model is not None and s.est.held == 0 and s.status_values()["held_for_grid"] == "0"
        models.append(model)
    for m in models:
        assert m.n_samples == ref.n_samples
        np.testing.assert_allclose(m.coef, ref.coef, rtol=0, atol=1e-9)
