"""End to end, each node in its own process: simulator → estimator → predictor, recorded.

The predictor's live output on the cycles after the training cycles is scored
against the velocities measured from the recorded shape and pose
(:func:`suds_ros.report.live_score.score_live_predictions`: Γ against the phase-only
template fitted on the training cycles).
"""

from __future__ import annotations

import time

import pytest

from suds_ros.report.live_score import score_live_predictions

try:  # pytest imports test/ros modules top-level (rootdir-relative) or as a package
    from ._ros_helpers import last_model, stop, wait_for
except ImportError:
    from _ros_helpers import last_model, stop, wait_for

pytestmark = pytest.mark.ros

TRAIN_CYCLES, TEST_CYCLES = 30, 10
RECORD = ("topics:=['/suds/shape', '/suds/body_pose', '/suds/predicted/*', '/suds/model', "
          "'/suds/status']", "system:=purcell3", "actuated:=joint_1", "passive:=joint_2")


def test_live_pipeline_predicts_test_cycles(start_process, node_command, tmp_path):
    bag = tmp_path / "live.mcap"
    rec = start_process(node_command("recorder_node", f"output:={bag}", *RECORD), "recorder")
    est = start_process(node_command("estimator_node"), "estimator")
    pred = start_process(node_command("predictor_node"), "predictor")
    wait_for(lambda: "recording [" in rec.output(), 30, "the recorder")
    time.sleep(2.0)  # the estimator and predictor import and start
    sim = start_process(node_command(
        "simulator_node", "system:=purcell3", "real_time_factor:=5.0", "seed:=3",
        f"cycles:={TRAIN_CYCLES + TEST_CYCLES}"), "simulator")
    assert sim.wait(120) == 0, sim.output()
    wait_for(lambda: est.output().count("joints") >= 1, 5, "the estimator to start")
    time.sleep(3.0)  # idle flush of the last chunk, last predictions
    assert stop(pred) == 0, pred.output()
    assert stop(est) == 0, est.output()
    assert stop(rec) == 0, rec.output()
    print(pred.output()[-400:])
    score = score_live_predictions(bag, TRAIN_CYCLES)
    print(score.summary())
    assert score.coverage >= 0.95, score
    assert score.gamma_body >= 0.8 and score.gamma_passive >= 0.8, score
    model = last_model(bag)
    assert model.n_samples == (TRAIN_CYCLES + TEST_CYCLES) * 100 - 1
