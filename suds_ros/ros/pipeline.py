"""``pipeline``: run simulator, estimator, predictor (and recorder) as separate processes.

A small supervisor for installs without the ``launch`` package.  Each node runs
as ``python -m suds_ros.ros.<module> --ros-args -p ...``; its output is
printed prefixed with ``[name]``.  When the simulator has finished its cycles
(and ``--drain`` s more, so the last predictions are recorded),
on Ctrl-C or on SIGTERM, every child is stopped (SIGINT, then SIGTERM, then
SIGKILL, each after a timeout).  The exit code is 0 only if every child ended
cleanly; a child that fails stops the others.

When the recorder ran, the recorded live predictions are scored at the end
(:func:`suds_ros.report.live_score.score_live_predictions`, as ``suds score BAG``; in a namespace
as ``suds score BAG --namespace NS``).

``--namespace /robot1`` starts every node in that namespace (``-r __ns:=``), so
its topics are ``/robot1/suds/...`` and several robots can run side by side.
Parameters passed on: simulator ``system``, ``cycles``, ``rate``, ``seed``,
``real_time_factor``; estimator/predictor ``system``; recorder ``output``,
``system``, ``actuated``, ``passive`` (the recorder runs only with ``--output``).
The simulator also gets ``wait_for_subscribers`` = the number of the other nodes started
that listen to ``suds/shape``: its stream starts once they all run (on 2 busy cores
their imports alone take seconds, and at 5× real time the stream would otherwise be tens of
cycles ahead of the estimator).  The recorder gets ``drain_timeout`` = 0.6 × ``--stop-timeout``,
so it writes what is still queued after SIGINT before the supervisor escalates.

``--optimize OBJECTIVE`` (speed, turn or efficiency) also starts the ``optimizer`` node
(:mod:`suds_ros.ros.optimizer_node`, ``-p objective:=OBJECTIVE``, the robot's ``system`` or
``model_file``, ``--optimize-budget`` cycles): it commands gaits on ``suds/gait_command``, which the
simulator switches to at its next cycle boundary, and the estimator starts afresh on each new gait.
For efficiency the simulator also publishes its actuator effort (``-p effort:=true``).

``--foxglove PORT`` (default 0: off) also starts ``foxglove_bridge``
(:mod:`suds_ros.ros.foxglove_node`, ``-p port:=PORT``): the Foxglove app then shows
the live topics at ``ws://127.0.0.1:PORT`` without a ROS installation.

With ``--model FILE`` (or ``--system`` given a path) the robot model file is loaded
here first (a bad file stops the pipeline before any node starts): the simulator
gets ``model_file`` (and ``rate`` = 100 samples per cycle at the file's ``gait_hz``
unless ``--rate``), the estimator the file's ``actuated`` joints and ``gait_hz``,
the predictor and recorder its name, roles and ``gait_hz``.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Mapping, Sequence
from typing import IO

from suds_ros.core.errors import SudsError
from suds_ros.executables import EXECUTABLES
from suds_ros.io.recording_bag import valid_namespace

#: the nodes the pipeline can start: name → module (``python -m <module>``)
NODES = {name: EXECUTABLES[name]
         for name in ("simulator", "estimator", "predictor", "recorder", "foxglove_bridge", "optimizer")}
#: the nodes that subscribe to the simulator's suds/shape (the simulator waits for them)
SHAPE_LISTENERS = ("estimator", "predictor", "recorder", "foxglove_bridge", "optimizer")
#: exit codes that count as a clean stop after we asked a child to stop
_STOPPED_OK = {0, -signal.SIGINT, -signal.SIGTERM, 130, 143}


def _pump(name: str, stream: IO[bytes], out: IO[str], lock: threading.Lock) -> None:
    for raw in iter(stream.readline, b""):
        line = raw.decode(errors="replace").rstrip("\n")
        with lock:
            print(f"[{name}] {line}", file=out, flush=True)
    stream.close()


def stop_children(procs: Mapping[str, subprocess.Popen], timeouts: tuple[float, float] = (5.0, 3.0)
                  ) -> set[str]:
    """Stop every running child: SIGINT, SIGTERM, then SIGKILL; returns the names that needed SIGKILL."""
    for sig, timeout in ((signal.SIGINT, timeouts[0]), (signal.SIGTERM, timeouts[1])):
        running = [p for p in procs.values() if p.poll() is None]
        for p in running:
            p.send_signal(sig)
        deadline = time.monotonic() + timeout
        for p in running:
            try:
                p.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                pass
    killed = {n for n, p in procs.items() if p.poll() is None}
    for name in killed:
        try:
            os.killpg(procs[name].pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        procs[name].wait()
    return killed


def supervise(commands: Mapping[str, Sequence[str]], *, main: str | None = "simulator",
              env: Mapping[str, str] | None = None, timeouts: tuple[float, float] = (5.0, 3.0),
              out: IO[str] = sys.stdout, drain: float = 0.0) -> int:
    """Run ``commands`` (name → argv) until ``main`` exits, a child fails or we are interrupted.

    After ``main`` exits cleanly the others run ``drain`` s more (the last predictions
    reach the recorder) before they are stopped.
    Returns 0 when every child ended cleanly, else 1 (each failure is reported).
    """
    procs: dict[str, subprocess.Popen] = {}
    lock, pumps = threading.Lock(), []
    interrupted = False
    drain_until: float | None = None
    previous = signal.signal(signal.SIGTERM, signal.default_int_handler)
    # Ctrl-C must reach us even when we were started with SIGINT ignored (a background job of a
    # non-interactive shell inherits SIG_IGN, and Python then installs no handler of its own)
    previous_int = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        for name, cmd in commands.items():
            procs[name] = subprocess.Popen(
                list(cmd), env=None if env is None else dict(env), stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT, start_new_session=True)  # we forward Ctrl-C ourselves
            t = threading.Thread(target=_pump, args=(name, procs[name].stdout, out, lock), daemon=True)
            t.start()
            pumps.append(t)
        while True:
            done = {n: p.returncode for n, p in procs.items() if p.poll() is not None}
            if any(code != 0 for code in done.values()) or len(done) == len(procs):
                break
            if main in done:
                if drain_until is None:
                    drain_until = time.monotonic() + drain
                if time.monotonic() >= drain_until:
                    break
            time.sleep(0.1)
    except KeyboardInterrupt:
        interrupted = True
        with lock:
            print("[pipeline] interrupted: stopping the nodes", file=out, flush=True)
    finally:
        signal.signal(signal.SIGTERM, previous)
        signal.signal(signal.SIGINT, previous_int)
        ended_alone = {n: p.returncode for n, p in procs.items() if p.poll() is not None}
        killed = stop_children(procs, timeouts)
        for t in pumps:
            t.join(timeout=2.0)
    failed = []
    for name, p in procs.items():
        code = p.returncode
        if name in killed:
            failed.append(f"{name} did not stop and was killed")
        elif name in ended_alone and code != 0 and not (interrupted and code in _STOPPED_OK):
            failed.append(f"{name} exited with code {code}")
        elif name not in ended_alone and code not in _STOPPED_OK:
            failed.append(f"{name} exited with code {code} when stopped")
    for msg in failed:
        print(f"[pipeline] ERROR: {msg}", file=out, flush=True)
    return 1 if failed else 0


def _param(name: str, value: object) -> list[str]:
    text = repr(value) if isinstance(value, float) else str(value)
    return ["-p", f"{name}:={text}"]


def model_file(args: argparse.Namespace) -> str | None:
    """Return the robot model file of ``--model`` (or ``--system`` given a path), absolute, or None."""
    from suds_ros.core.physics.systems import is_model_file

    path = args.model or (args.system if is_model_file(args.system) else None)
    return None if path is None else os.path.abspath(path)


def _role_names(names: Sequence[str], indices: Sequence[int]) -> str:
    return ",".join(names[i] for i in indices)


def _model_params(path: str, args: argparse.Namespace) -> dict[str, list[str]]:
    """Node parameters for a robot model file (see the module doc)."""
    from suds_ros.core.physics.robot_model import load_model

    model = load_model(path)
    names = model.joint_names
    sim = _param("model_file", path)
    if args.rate is None:
        sim += _param("rate", 100.0 * model.gait_hz)
    gait = _param("gait_hz", float(model.gait_hz))
    params = {"simulator": sim,
              "estimator": _param("actuated", f"[{_role_names(names, model.actuated)}]") + gait,
              "predictor": _param("system", model.name),
              "optimizer": _param("model_file", path)}
    if args.output:
        params["recorder"] = (_param("system", model.name)
                              + _param("actuated", _role_names(names, model.actuated))
                              + _param("passive", _role_names(names, model.passive)) + gait)
    return params


def _system_params(args: argparse.Namespace) -> dict[str, list[str]]:
    """Node parameters for a built-in system id."""
    params = {"simulator": _param("system", args.system), "estimator": _param("system", args.system),
              "predictor": _param("system", args.system), "optimizer": _param("system", args.system)}
    if args.output:
        from suds_ros.core.physics.systems import make_system

        system = make_system(args.system)
        names = system.joint_names
        params["recorder"] = (_param("system", args.system)
                              + _param("actuated", _role_names(names, system.actuated))
                              + _param("passive", _role_names(names, system.passive)))
    return params


def build_commands(args: argparse.Namespace) -> dict[str, list[str]]:
    """The argv of every node to start, from the parsed pipeline options.

    Raises
    ------
    SudsError
        For unknown nodes, an unknown system id or a model file that does not load.
    """
    nodes = [n for n in args.nodes.split(",") if n]
    unknown = [n for n in nodes if n not in NODES]
    if unknown:
        raise SudsError(f"--nodes: unknown node(s) {unknown}; expected some of {list(NODES)}")
    path = model_file(args)
    params = _system_params(args) if path is None else _model_params(path, args)
    for opt, pname in (("cycles", "cycles"), ("rate", "rate"), ("seed", "seed"),
                       ("realtime_factor", "real_time_factor")):
        if getattr(args, opt) is not None:
            params["simulator"] += _param(pname, getattr(args, opt))
    if "recorder" in params:
        params["recorder"] = (_param("output", os.path.abspath(args.output)) + params["recorder"]
                              + _param("overwrite", "true" if args.overwrite else "false"))
    if args.optimize:
        params["optimizer"] += _param("objective", args.optimize) + _param("budget_cycles", args.optimize_budget)
        if args.optimize == "efficiency" and "simulator" in params:  # the work is measured from the effort
            params["simulator"] += _param("effort", "true")
        if "optimizer" not in nodes:
            nodes.append("optimizer")
    if args.foxglove:
        params["foxglove_bridge"] = _param("port", args.foxglove)
        if "foxglove_bridge" not in nodes:
            nodes.append("foxglove_bridge")
    listeners = [n for n in nodes if n in SHAPE_LISTENERS and n in params]
    if "simulator" in params and listeners:
        # the stream starts once every other node started here listens to suds/shape
        params["simulator"] += _param("wait_for_subscribers", len(listeners))
    if "recorder" in params:
        # the recorder writes its backlog after SIGINT within our stop timeout
        params["recorder"] += _param("drain_timeout", round(0.6 * args.stop_timeout, 3))
    ns = ["-r", f"__ns:={args.namespace}"] if args.namespace else []
    return {
        n: [sys.executable, "-m", NODES[n], "--ros-args", *ns, *params[n], *args.ros_args]
        for n in nodes if n in params
    }


def prepare_output(path: str, overwrite: bool) -> None:
    """Create the bag's directory; refuse an existing bag unless ``overwrite`` (before any node starts)."""
    out = os.path.abspath(path)
    if os.path.isdir(out):
        raise SudsError(f"--output {path}: is a directory, expected a .mcap file path")
    if os.path.exists(out) and not overwrite:
        raise SudsError(f"--output {path}: file exists; pass --overwrite to replace it "
                        "or choose another path")
    try:
        os.makedirs(os.path.dirname(out), exist_ok=True)
    except OSError as exc:
        raise SudsError(f"--output {path}: cannot create its directory: {exc.strerror}") from None


def missing_modules(commands: Mapping[str, Sequence[str]]) -> list[str]:
    """Names of the nodes whose module cannot be found."""
    return [n for n in commands if importlib.util.find_spec(NODES[n]) is None]


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="pipeline", description=__doc__.splitlines()[0],
                                allow_abbrev=False)
    which = p.add_mutually_exclusive_group()
    which.add_argument("--system", default="purcell3",
                       help="system id (default purcell3), or the path of a robot model file")
    which.add_argument("--model", metavar="FILE", help="robot model file (suds-robot/1) to simulate")
    p.add_argument("--namespace", default="",
                   help="ROS namespace of every node (e.g. /robot1: topics /robot1/suds/...)")
    p.add_argument("--cycles", type=int, help="gait cycles the simulator runs before the pipeline stops")
    p.add_argument("--rate", type=float, help="simulator sample rate, Hz")
    p.add_argument("--seed", type=int, help="simulator seed")
    p.add_argument("--realtime-factor", "--real-time-factor", dest="realtime_factor", type=float,
                   help="simulated seconds per wall-clock second")
    p.add_argument("--output", metavar="BAG", help="record to this .mcap (starts the recorder)")
    p.add_argument("--overwrite", action="store_true", help="let the recorder replace BAG")
    p.add_argument("--foxglove", type=int, default=0, metavar="PORT",
                   help="also serve the topics to the Foxglove app on ws://127.0.0.1:PORT "
                        "(foxglove_bridge; default 0: off)")
    p.add_argument("--optimize", choices=("speed", "turn", "efficiency"), metavar="OBJECTIVE",
                   help="also optimise the gait live for this objective (speed, turn or efficiency; starts the "
                        "optimizer; efficiency has the simulator publish its actuator effort)")
    p.add_argument("--optimize-budget", dest="optimize_budget", type=int, default=200, metavar="CYCLES",
                   help="gait cycles the optimizer may ask for (default 200)")
    p.add_argument("--nodes", default="simulator,estimator,predictor,recorder",
                   help="comma-separated nodes to start (the recorder needs --output, "
                        "foxglove_bridge --foxglove)")
    p.add_argument("--drain", type=float, default=2.0,
                   help="s the other nodes keep running after the simulator is done (default 2)")
    p.add_argument("--no-score", dest="score", action="store_false",
                   help="do not score the recorded live predictions at the end")
    p.add_argument("--stop-timeout", type=float, default=5.0,
                   help="s to wait after SIGINT (and again after SIGTERM) before escalating")
    p.add_argument("--ros-args", dest="ros_args", nargs=argparse.REMAINDER, default=[],
                   help="extra ROS arguments for every node (e.g. -p use_sim_time:=true)")
    args = p.parse_args(argv)
    if args.namespace and not valid_namespace(args.namespace):
        p.error(f"--namespace: expected an absolute ROS namespace such as /robot1, got {args.namespace!r}")
    if not 0 <= args.foxglove <= 65535:
        p.error(f"--foxglove: expected a port in 1..65535 (0: off), got {args.foxglove}")
    if args.drain < 0:
        p.error(f"--drain: expected a value ≥ 0, got {args.drain}")
    for opt in ("cycles", "rate", "realtime_factor", "stop_timeout"):
        v = getattr(args, opt)
        if v is not None and not v > 0:
            p.error(f"--{opt.replace('_', '-')}: expected a value > 0, got {v}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Start the nodes and supervise them; see the module doc."""
    args = parse_args(sys.argv[1:] if argv is None else argv)
    try:
        commands = build_commands(args)
    except SudsError as exc:
        print(f"ERROR: {exc}", file=sys.stderr)
        return 2
    if "recorder" in commands:
        try:
            prepare_output(args.output, args.overwrite)
        except SudsError as exc:
            print(f"ERROR: {exc}", file=sys.stderr)
            return 2
    missing = missing_modules(commands)
    if missing:
        mods = ", ".join(NODES[n] for n in missing)
        print(f"ERROR: node module(s) not installed: {mods}; start the others with "
              f"--nodes {','.join(n for n in commands if n not in missing) or '...'}",
              file=sys.stderr)
        return 2
    if "recorder" not in commands and "recorder" in args.nodes.split(","):
        print("[pipeline] no --output given: not recording", flush=True)
    print(f"[pipeline] starting {', '.join(commands)}", flush=True)
    rc = supervise(commands, main="simulator" if "simulator" in commands else None,
                   timeouts=(args.stop_timeout, args.stop_timeout), drain=args.drain)
    if rc == 0 and args.score and {"recorder", "predictor"} <= set(commands):
        rc = report_score(args.output, args.namespace)
    return rc


def report_score(bag: str, namespace: str = "") -> int:
    """Print the recorded live predictions' Γ (``suds score [--namespace NS]``); 1 if they cannot be scored."""
    from suds_ros.report.live_score import score_live_predictions

    try:
        score = score_live_predictions(bag, namespace=namespace)
    except SudsError as exc:
        print(f"[pipeline] ERROR: cannot score the live predictions in {bag}: {exc}", flush=True)
        return 1
    print(f"[pipeline] recorded {bag}", flush=True)
    print(f"[pipeline] {score.summary()}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
