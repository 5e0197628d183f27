"""Two robots on one DDS domain: two complete pipelines in two namespaces, one recorder.

``/robot1`` runs purcell3, ``/robot2`` the snake5 robot model file: each a simulator
started with ``-r __ns:=/robotN`` and the ``pipeline`` supervisor's estimator and
predictor (``--namespace``).  One
recorder records ``/robot1/suds/*`` and ``/robot2/suds/*`` into one bag.  Each model
has its own robot's joints and exactly its own robot's samples (nothing crossed over),
and each robot's live predictions on the cycles after the training cycles reach Γ ≥ 0.8
(scored by :func:`suds_ros.report.live_score.score_live_predictions` on the namespace's
topics taken out of the shared bag into a bag of the contract's names, and the same read in
place with ``namespace``).
"""

from __future__ import annotations

import json
import sys
from collections import Counter
from pathlib import Path

import pytest

from suds_ros.io.mcap import BagWriter, iter_raw_messages
from suds_ros.report.live_score import score_live_predictions

try:  # pytest imports test/ros modules top-level (rootdir-relative) or as a package
    from ._ros_helpers import decode, recorded_so_far, stop, wait_for
except ImportError:
    from _ros_helpers import decode, recorded_so_far, stop, wait_for

pytestmark = [pytest.mark.ros, pytest.mark.slow]

SNAKE5 = Path(__file__).resolve().parents[2].parent / "shared" / "robots" / "snake5.yaml"
if not SNAKE5.exists():
    SNAKE5 = Path(__file__).resolve().parents[1] / "data" / "robots" / "eel4.yaml"
TRAIN_CYCLES, TEST_CYCLES = 30, 10
ROBOTS = {"/robot1": ["--system", "purcell3"], "/robot2": ["--model", str(SNAKE5)]}


def extract(bag: Path, namespace: str, out: Path) -> dict:
    """Write ``namespace``'s topics of ``bag`` to ``out`` under the contract's names; returns its system."""
    system = None
    with BagWriter(out) as w:
        for m in iter_raw_messages(bag):
            if not m.topic.startswith(namespace + "/"):
                continue
            topic = m.topic[len(namespace):]
            if topic == "/suds/system":
                system = json.loads(decode(m).data)
            w.add_topic(topic, m.type_name)
            w.write_raw(topic, m.data, m.log_time_ns)
        assert system is not None, f"no {namespace}/suds/system in {bag}"
        w.write_metadata("suds", {"system": system["system"], "actuated": ",".join(system["actuated"]),
                                  "passive": ",".join(system["passive"]), "gait_hz": repr(system["gait_hz"])})
    return system


def final_models(bag: Path) -> dict[str, int]:
    """``n_samples`` of the last model of each robot recorded so far."""
    from suds_ros.ros.conversions import model_from_msg

    _, last = recorded_so_far(bag)
    return {ns: model_from_msg(decode(last[f"{ns}/suds/model"])).n_samples
            for ns in ROBOTS if f"{ns}/suds/model" in last}


def test_two_robots_in_two_namespaces(start_process, tmp_path, probe):
    bag = tmp_path / "fleet.mcap"
    rec = start_process([sys.executable, "-m", "suds_ros.ros.recorder_node", "--ros-args",
                         "-p", f"output:={bag}", "-p", "flush_period:=0.2",
                         "-p", "topics:=['/robot1/suds/*', '/robot2/suds/*']"], "recorder")
    wait_for(lambda: "recording [" in rec.output(), 60, lambda: f"the recorder\n{rec.output()}")
    n = (TRAIN_CYCLES + TEST_CYCLES) * 100
    pipes = {ns: start_process([sys.executable, "-m", "suds_ros.ros.pipeline", "--namespace", ns, *which,
                                "--nodes", "estimator,predictor", "--ros-args", "-p", f"depth:={n}"],
                               f"pipeline{ns.replace('/', '-')}")
             for ns, which in ROBOTS.items()}
    graph = probe.node
    wait_for(lambda: all(graph.count_publishers(f"{ns}/suds/predicted/body_velocity") and
                         graph.count_publishers(f"{ns}/suds/status") for ns in ROBOTS), 60,
             lambda: "both estimators and predictors\n" + "\n".join(p.output() for p in pipes.values()))
    sims = {ns: start_process([sys.executable, "-m", "suds_ros.ros.simulator_node", "--ros-args",
                               "-r", f"__ns:={ns}", *(["-p", "system:=purcell3"] if "--system" in which
                                                      else ["-p", f"model_file:={SNAKE5}"]),
                               "-p", f"cycles:={TRAIN_CYCLES + TEST_CYCLES}", "-p", "real_time_factor:=5.0",
                               "-p", "seed:=4"], f"simulator{ns.replace('/', '-')}")
            for ns, which in ROBOTS.items()}
    for ns, sim in sims.items():
        assert sim.wait(180) == 0, sim.output()
    # the last models (published once each stream has been idle) are in the bag
    wait_for(lambda: final_models(bag) == {ns: n - 1 for ns in ROBOTS}, 90,
             lambda: f"both final models in {bag}: {final_models(bag)}", interval=0.5)
    for ns, p in pipes.items():
        assert stop(p) == 0, p.output()[-3000:]
    assert stop(rec) == 0, rec.output()

    counts = Counter(m.topic for m in iter_raw_messages(bag))
    for ns in ROBOTS:
        assert {f"{ns}/suds/shape", f"{ns}/suds/predicted/body_velocity", f"{ns}/suds/model"} <= set(counts)
        # nothing lost by the recorder, not even the estimator's burst of its initial cycles
        assert (counts[f"{ns}/suds/shape"], counts[f"{ns}/suds/measured/body_velocity"]) == (n, n - 1), counts
    assert not any(t.startswith("/suds/") for t in counts), counts  # nothing in the root namespace
    joints = {}
    for ns in ROBOTS:
        out = tmp_path / f"{ns.strip('/')}.mcap"
        system = extract(bag, ns, out)
        from suds_ros.ros.conversions import model_from_msg

        model = model_from_msg(decode(list(iter_raw_messages(out, topics=["/suds/model"]))[-1]))
        assert list(model.joint_names) == system["joint_names"], (ns, model.joint_names)
        joints[ns] = tuple(model.joint_names)
        score = score_live_predictions(out, TRAIN_CYCLES)
        print(ns, system["system"], score.summary())
        # read in place from the shared bag (`suds score fleet.mcap --namespace /robot1`)
        assert score_live_predictions(bag, TRAIN_CYCLES, namespace=ns) == score
        assert score.coverage >= 0.95, (ns, score)
        assert score.gamma_body >= 0.8 and score.gamma_passive >= 0.8, (ns, score)
    assert joints["/robot1"] != joints["/robot2"]
