"""The pipeline supervisor: stop order, exit codes, missing modules, Ctrl-C.

The supervisor only starts processes, so most tests run plain Python children and need
no rclpy; only the tests that start real nodes are marked ``ros``.
"""

from __future__ import annotations

import io
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from suds_ros.io.mcap import bag_info
from suds_ros.ros import pipeline

POLITE = ("import signal, sys, time\n"
          "signal.signal(signal.SIGINT, lambda *a: sys.exit(0))\n"
          "print('up', flush=True)\n"
          "time.sleep(60)\n")
STUBBORN = ("import signal, time\n"
            "signal.signal(signal.SIGINT, signal.SIG_IGN)\n"
            "signal.signal(signal.SIGTERM, signal.SIG_IGN)\n"
            "print('up', flush=True)\n"
            "time.sleep(60)\n")


def py(code: str) -> list[str]:
    return [sys.executable, "-c", code]


def test_pipeline_imports_without_rclpy():
    code = ("import sys; sys.modules['rclpy'] = None; import suds_ros.ros.pipeline as p; "
            "assert 'rclpy' not in [m for m in sys.modules if sys.modules[m] is not None]; "
            "print(sorted(p.NODES))")
    proc = subprocess.run(py(code), capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert "recorder" in proc.stdout


def test_main_child_finishing_stops_the_others():
    out = io.StringIO()
    rc = pipeline.supervise({"simulator": py("import time; print('sim'); time.sleep(0.5)"),
                             "estimator": py(POLITE)}, out=out, timeouts=(3.0, 1.0))
    assert rc == 0, out.getvalue()
    assert "[simulator] sim" in out.getvalue() and "[estimator] up" in out.getvalue()


def test_failing_child_stops_everything_and_fails():
    out = io.StringIO()
    t0 = time.monotonic()
    rc = pipeline.supervise({"simulator": py(POLITE), "estimator": py("import sys; sys.exit(3)")},
                            out=out, timeouts=(3.0, 1.0))
    assert rc == 1
    assert "estimator exited with code 3" in out.getvalue()
    assert time.monotonic() - t0 < 10


def test_stubborn_child_is_killed_and_reported():
    out = io.StringIO()
    rc = pipeline.supervise({"simulator": py("import time; time.sleep(1.0)"),
                             "estimator": py(STUBBORN)}, out=out, timeouts=(0.5, 0.5))
    assert rc == 1
    assert "estimator did not stop and was killed" in out.getvalue()


def test_missing_node_module_is_a_clear_error(monkeypatch, capsys):
    monkeypatch.setitem(pipeline.NODES, "estimator", "suds_ros.ros.no_such_node")
    assert pipeline.main(["--nodes", "estimator"]) == 2
    err = capsys.readouterr().err
    assert "not installed: suds_ros.ros.no_such_node" in err


def test_bad_options_are_rejected(capsys):
    with pytest.raises(SystemExit, match="2"):
        pipeline.main(["--rate", "0"])
    assert "--rate: expected a value > 0" in capsys.readouterr().err
    assert pipeline.main(["--nodes", "recorder,bogus"]) == 2


def test_recorder_command_gets_joint_roles(tmp_path):
    args = pipeline.parse_args(["--system", "purcell3", "--output", str(tmp_path / "x.mcap"),
                                "--cycles", "3", "--seed", "4"])
    cmds = pipeline.build_commands(args)
    assert set(cmds) == {"simulator", "estimator", "predictor", "recorder"}
    rec = " ".join(cmds["recorder"])
    assert "actuated:=joint_1" in rec and "passive:=joint_2" in rec
    assert "cycles:=3" in " ".join(cmds["simulator"]) and "seed:=4" in " ".join(cmds["simulator"])
    # the stream waits for the estimator, predictor and recorder; the recorder drains within the stop timeout
    assert "wait_for_subscribers:=3" in cmds["simulator"]
    assert "drain_timeout:=3.0" in cmds["recorder"]
    cmds = pipeline.build_commands(pipeline.parse_args(["--nodes", "simulator,estimator", "--stop-timeout", "10"]))
    assert "wait_for_subscribers:=1" in cmds["simulator"]


def test_optimize_adds_the_optimizer_for_the_robot(tmp_path):
    cmds = pipeline.build_commands(pipeline.parse_args(["--system", "purcell3", "--optimize", "turn",
                                                        "--optimize-budget", "60"]))
    assert set(cmds) == {"simulator", "estimator", "predictor", "optimizer"}
    assert _params(cmds["optimizer"]) == ["system:=purcell3", "objective:=turn", "budget_cycles:=60"]
    assert "wait_for_subscribers:=3" in cmds["simulator"]  # the optimizer listens to the stream too
    cmds = pipeline.build_commands(pipeline.parse_args(["--model", str(EEL4), "--optimize", "speed"]))
    assert _params(cmds["optimizer"]) == [f"model_file:={EEL4}", "objective:=speed", "budget_cycles:=200"]
    assert "effort:=true" not in cmds["simulator"]
    cmds = pipeline.build_commands(pipeline.parse_args(["--system", "purcell3", "--optimize", "efficiency"]))
    assert "objective:=efficiency" in cmds["optimizer"]
    assert "effort:=true" in cmds["simulator"]  # the work is measured from the simulator's actuator effort
    with pytest.raises(SystemExit):
        pipeline.parse_args(["--optimize", "nosuch"])


@pytest.mark.ros
def test_ctrl_c_stops_recorder_cleanly(start_process, tmp_path):
    out = tmp_path / "p.mcap"
    proc = start_process([sys.executable, "-m", "suds_ros.ros.pipeline", "--nodes", "recorder",
                          "--output", out], "pipeline")
    deadline = time.monotonic() + 30
    while "[recorder]" not in proc.output():
        assert time.monotonic() < deadline, proc.output()
        time.sleep(0.1)
    proc.send_signal(signal.SIGINT)
    try:  # generous: the recorder syncs its last chunk to disk, slow under heavy I/O
        code = proc.wait(120)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the pipeline did not exit 120 s after SIGINT:\n{proc.output()}")
    assert code == 0, proc.output()
    info = bag_info(out)
    assert info.has_summary and info.metadata["suds"]["actuated"] == "joint_1"


def test_drain_lets_the_others_finish_their_work(tmp_path):
    """With a drain the others finish what they do after ``main`` exits; without one they are stopped.

    Ordered by events, not by sleeps: the estimator child says (a file) when its SIGINT handler is
    set, ``main`` exits only then (so the stop never lands in the interpreter's start-up), and
    the estimator's work waits for ``main``'s exit.
    """
    wait = ("import os, time\n"
            "def wait(path):\n"
            "    deadline = time.monotonic() + 120\n"
            "    while not os.path.exists(path):\n"
            "        assert time.monotonic() < deadline, path\n"
            "        time.sleep(0.02)\n")
    for drain, seen in ((0.0, False), (60.0, True)):
        d = tmp_path / f"drain{drain:g}"
        d.mkdir()
        ready, main_done = str(d / "ready"), str(d / "main_done")
        work_after = main_done if seen else str(d / "never")  # without a drain: stopped while waiting
        main = wait + f"wait({ready!r})\nopen({main_done!r}, 'w').close()\nprint('sim', flush=True)\n"
        late = ("import signal, sys\nsignal.signal(signal.SIGINT, lambda *a: sys.exit(0))\n" + wait
                + f"open({ready!r}, 'w').close()\nwait({work_after!r})\nprint('late', flush=True)\n")
        out = io.StringIO()
        t0 = time.monotonic()
        rc = pipeline.supervise({"simulator": py(main), "estimator": py(late)},
                                out=out, timeouts=(30.0, 10.0), drain=drain)
        assert rc == 0, out.getvalue()
        assert ("[estimator] late" in out.getvalue()) is seen, out.getvalue()
        assert time.monotonic() - t0 < 60.0, out.getvalue()  # the drain ends when the work is done


@pytest.mark.ros
def test_main_job_runs_and_scores_its_live_predictions(start_process, tmp_path):
    """The README's main job, shortened: every node, recorded, scored at the end."""
    from suds_ros.report.live_score import score_live_predictions

    out = tmp_path / "pipeline.mcap"
    proc = start_process([sys.executable, "-m", "suds_ros.ros.pipeline", "--system", "purcell3",
                          "--cycles", "24", "--real-time-factor", "2", "--output", out], "pipeline")
    assert proc.wait(180) == 0, proc.output()
    text = proc.output()
    score = score_live_predictions(out)
    assert f"[pipeline] {score.summary()}" in text, text[-2000:]
    assert score.train_cycles == 12 and score.coverage >= 0.9, score
    info = bag_info(out)
    assert info.has_summary and info.topics["/suds/predicted/body_velocity"].count > 1000


def test_output_is_prepared_before_any_node_starts(tmp_path, capsys):
    nested = tmp_path / "a" / "b" / "run.mcap"
    pipeline.prepare_output(str(nested), overwrite=False)
    assert nested.parent.is_dir() and not nested.exists()
    nested.write_bytes(b"recorded")
    assert pipeline.main(["--output", str(nested), "--nodes", "recorder"]) == 2
    assert "file exists; pass --overwrite" in capsys.readouterr().err
    assert nested.read_bytes() == b"recorded"
    assert pipeline.main(["--output", str(tmp_path), "--nodes", "recorder"]) == 2
    assert "is a directory" in capsys.readouterr().err


EEL4 = Path(__file__).resolve().parents[1] / "data" / "robots" / "eel4.yaml"  # 0.5 Hz gait


def _params(argv: list[str]) -> list[str]:
    """The ``-p`` values of one node's argv."""
    return [argv[i + 1] for i, a in enumerate(argv) if a == "-p"]


@pytest.mark.parametrize("how", [["--model", str(EEL4)], ["--system", str(EEL4)]])
def test_model_file_configures_every_node(tmp_path, how):
    args = pipeline.parse_args([*how, "--output", str(tmp_path / "x.mcap"), "--cycles", "3"])
    cmds = pipeline.build_commands(args)
    assert set(cmds) == {"simulator", "estimator", "predictor", "recorder"}
    sim = _params(cmds["simulator"])
    # 100 samples per 0.5 Hz cycle; the stream waits for the three other nodes
    assert sim == [f"model_file:={EEL4}", "rate:=50.0", "cycles:=3", "wait_for_subscribers:=3"]
    assert _params(cmds["estimator"]) == ["actuated:=[neck,waist]", "gait_hz:=0.5"]
    assert _params(cmds["predictor"]) == ["system:=eel4"]
    assert _params(cmds["recorder"]) == [f"output:={tmp_path / 'x.mcap'}", "system:=eel4", "actuated:=neck,waist",
                                         "passive:=tail", "gait_hz:=0.5", "overwrite:=false", "drain_timeout:=3.0"]


def test_model_file_with_an_explicit_rate_and_a_relative_path(tmp_path, monkeypatch):
    monkeypatch.chdir(EEL4.parent)
    cmds = pipeline.build_commands(pipeline.parse_args(["--model", EEL4.name, "--rate", "200",
                                                        "--nodes", "simulator"]))
    assert list(cmds) == ["simulator"]
    assert _params(cmds["simulator"]) == [f"model_file:={EEL4}", "rate:=200.0"]  # absolute for the child


def test_bad_model_file_stops_the_pipeline_before_any_node(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(EEL4.read_text().replace("gait_hz: 0.5", "gait_hz: fast"))
    code = ("import sys; sys.modules['rclpy'] = None\n"
            "from suds_ros.ros import pipeline\n"
            f"sys.exit(pipeline.main(['--model', {str(bad)!r}, '--output', {str(tmp_path / 'x.mcap')!r}]))")
    proc = subprocess.run(py(code), capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert proc.stderr.strip() == f"ERROR: {bad}: `gait_hz`: expected a finite number, got 'fast'"
    assert "starting" not in proc.stdout and not (tmp_path / "x.mcap").exists()
    proc = subprocess.run([sys.executable, "-m", "suds_ros.ros.pipeline", "--model", str(EEL4),
                           "--system", "purcell3"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and "--system: not allowed with argument --model" in proc.stderr
