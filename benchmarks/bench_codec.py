"""CDR encode and decode speed of our message types: mcap-ros2-support, rosbags, our hand-written path.

For every type io/ and the nodes write or read (JointState of a 3- and a 9-joint
robot, PoseStamped, TwistStamped, String, DiagnosticArray, Clock) it times, per
message:

* encode: from the values we hold (stamp, names, arrays, …) to CDR bytes, building
  whatever message object the library needs (mcap-ros2-support encodes a dict;
  rosbags needs its typestore classes);
* decode: CDR bytes to the library's message object (for our fast decoders, to the
  tuple of fields they return).

Our hand-written encoder is timed from ``suds_ros/io/cdr.py`` as it is at ``--baseline``
(a git revision; default: the last commit that still had the hand-written encoders),
loaded from git into a throw-away module, so the figures stay reproducible after the
encoders were removed; our fast decoders are timed as they are in the work tree.  Every
encoder's bytes are checked against rosbags' before timing.  Whole bags are read by our
tolerant reader, by the one before it was streamed (``--scan-baseline``, loaded from git the
same way) and by the mcap package's StreamReader.  Writes docs/results/codec.md.

    python benchmarks/bench_codec.py [--baseline REV] [--scan-baseline REV] [--seconds 0.2]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
import types
from collections.abc import Callable
from typing import Any

import numpy as np

from _common import ROOT, machine, stamp, write

from suds_ros.io import msgdefs

JS, PS, TS = "sensor_msgs/msg/JointState", "geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/TwistStamped"
STR, DIAG, CLOCK = "std_msgs/msg/String", "diagnostic_msgs/msg/DiagnosticArray", "rosgraph_msgs/msg/Clock"


# ---------------------------------------------------------------- the messages, as plain values
def _cases() -> list[tuple[str, str, dict[str, Any]]]:
    """``(label, type, values)``: the values as a nested dict with ROS field names."""
    rng = np.random.default_rng(0)
    hdr = {"stamp": {"sec": 1_700_000_000, "nanosec": 123_456_789}, "frame_id": ""}

    def joints(n: int) -> dict[str, Any]:
        return {"header": hdr, "name": [f"joint_{k + 1}" for k in range(n)],
                "position": rng.normal(size=n), "velocity": np.zeros(0), "effort": rng.normal(size=n)}

    pose = {"header": {**hdr, "frame_id": "world"},
            "pose": {"position": {"x": 0.1, "y": -0.2, "z": 0.0},
                     "orientation": {"x": 0.0, "y": 0.0, "z": 0.6, "w": 0.8}}}
    twist = {"header": {**hdr, "frame_id": "body"},
             "twist": {"linear": {"x": 0.1, "y": -0.2, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.3}}}
    text = {"data": '{"system": "swimmer9", "joint_names": ["joint_1", "joint_2", "joint_3"], '
                    '"actuated": ["joint_1"], "passive": ["joint_2", "joint_3"], "gait_hz": 1.0}'}
    diag = {"header": hdr, "status": [
        {"level": 0, "name": "suds_estimator", "message": "ok", "hardware_id": "",
         "values": [{"key": k, "value": v} for k, v in
                    (("phase", "1.25"), ("samples", "12000"), ("model", "set 2"), ("gamma", "0.91"),
                     ("dropped", "0"), ("lag_s", "0.004"))]}]}
    clock = {"clock": {"sec": 12, "nanosec": 5}}
    return [("JointState (3 joints)", JS, joints(3)), ("JointState (9 joints)", JS, joints(9)),
            ("PoseStamped", PS, pose), ("TwistStamped", TS, twist), ("String (JSON, 160 chars)", STR, text),
            ("DiagnosticArray (1 status, 6 values)", DIAG, diag), ("Clock", CLOCK, clock)]


# ---------------------------------------------------------------- the three paths
def _mcap_ros2(type_name: str) -> tuple[Callable[[Any], bytes], Callable[[bytes], Any]]:
    from mcap.records import Schema
    from mcap_ros2._dynamic import serialize_dynamic
    from mcap_ros2.decoder import DecoderFactory

    text = msgdefs.schema_text(type_name)
    enc = serialize_dynamic(type_name, text)[type_name]
    dec = DecoderFactory().decoder_for("cdr", Schema(1, text.encode(), "ros2msg", type_name))
    assert dec is not None
    return enc, dec


def _rosbags_builder(store: Any, type_name: str) -> Callable[[dict[str, Any]], Any]:
    """Values → rosbags message object (what a writer through rosbags would have to do)."""
    from rosbags.interfaces import Nodetype

    cls = store.types[type_name]
    plan = []
    for name, (kind, spec) in store.get_msgdef(type_name).fields:
        if kind == Nodetype.NAME:
            plan.append((name, "msg", _rosbags_builder(store, spec)))
        elif kind in (Nodetype.SEQUENCE, Nodetype.ARRAY) and spec[0][0] == Nodetype.NAME:
            plan.append((name, "msgs", _rosbags_builder(store, spec[0][1])))
        elif kind in (Nodetype.SEQUENCE, Nodetype.ARRAY) and spec[0][1][0] == "float64":
            plan.append((name, "f64", None))
        else:
            plan.append((name, "plain", None))

    def build(values: dict[str, Any]) -> Any:
        args = {}
        for name, how, sub in plan:
            v = values[name]
            if how == "msg":
                args[name] = sub(v)
            elif how == "msgs":
                args[name] = [sub(x) for x in v]
            elif how == "f64":
                args[name] = np.asarray(v, dtype=np.float64)
            else:
                args[name] = v
        return cls(**args)
    return build


def _rosbags(store: Any, type_name: str) -> tuple[Callable[[Any], bytes], Callable[[bytes], Any]]:
    build = _rosbags_builder(store, type_name)
    return (lambda v: store.serialize_cdr(build(v), type_name)), (lambda b: store.deserialize_cdr(b, type_name))


def _baseline_module(rev: str) -> types.ModuleType | None:
    """``suds_ros/io/cdr.py`` as of git revision ``rev`` (None if it had no encoders)."""
    try:
        text = subprocess.run(["git", "show", f"{rev}:suds_ros/io/cdr.py"], cwd=ROOT, check=True,
                              capture_output=True, text=True).stdout
    except subprocess.CalledProcessError:
        return None
    mod = types.ModuleType("cdr_baseline")
    exec(compile(text, f"{rev}:suds_ros/io/cdr.py", "exec"), mod.__dict__)  # noqa: S102 - our own history
    return mod if hasattr(mod, "serialize") else None


def _baseline_scan(rev: str) -> Callable[..., Any]:
    """``scan`` of ``suds_ros/io/mcap_scan.py`` as of ``rev`` (the whole-file, hand-parsed reader)."""
    mods = {}
    for name in ("mcap_records", "mcap_scan"):
        text = subprocess.run(["git", "show", f"{rev}:suds_ros/io/{name}.py"], cwd=ROOT, check=True,
                              capture_output=True, text=True).stdout
        text = text.replace("from suds_ros.io.mcap_records import", "from _baseline_mcap_records import")
        mod = types.ModuleType(f"_baseline_{name}")
        sys.modules[mod.__name__] = mod
        exec(compile(text, f"{rev}:suds_ros/io/{name}.py", "exec"), mod.__dict__)  # noqa: S102
        mods[name] = mod
    return mods["mcap_scan"].scan


def _newest_with(path: str, has: Callable[[str], bool]) -> str:
    """The newest commit (short hash) whose ``path`` satisfies ``has(text)``."""
    revs = subprocess.run(["git", "log", "--format=%h", "--", path], cwd=ROOT, check=True,
                          capture_output=True, text=True).stdout.split()
    for rev in ["HEAD", *revs]:
        shown = subprocess.run(["git", "show", f"{rev}:{path}"], cwd=ROOT, capture_output=True, text=True)
        if shown.returncode == 0 and has(shown.stdout):
            return subprocess.run(["git", "rev-parse", "--short", rev], cwd=ROOT, check=True,
                                  capture_output=True, text=True).stdout.strip()
    raise SystemExit(f"no commit of {path} has what the baseline needs")


def _newest_with_encoders() -> str:
    return _newest_with("suds_ros/io/cdr.py", lambda text: "\ndef serialize(" in text)


def _newest_whole_file_reader() -> str:
    return _newest_with("suds_ros/io/mcap_records.py", lambda text: "\ndef read_file(" in text)


# ---------------------------------------------------------------- timing
def per_call_us(fns: dict[str, Callable[[], Any]], seconds: float, rounds: int = 7
                ) -> dict[str, float]:
    """µs per call of each of ``fns``: the best of ``rounds`` timed runs of about ``seconds``.

    The functions take turns within each round, so a load change on the (shared)
    machine hits all of them alike.
    """
    reps = {}
    for name, fn in fns.items():
        n, t = 1, 0.0
        while t < seconds / 5:
            n *= 2
            t0 = time.perf_counter()
            for _ in range(n):
                fn()
            t = time.perf_counter() - t0
        reps[name] = max(1, int(n * seconds / max(t, 1e-9)))
    best = dict.fromkeys(fns, np.inf)
    for _ in range(rounds):
        for name, fn in fns.items():
            t0 = time.perf_counter()
            for _ in range(reps[name]):
                fn()
            best[name] = min(best[name], (time.perf_counter() - t0) / reps[name])
    return {name: t * 1e6 for name, t in best.items()}


def _listed(values: Any) -> Any:
    """``values`` with every numpy array as a list."""
    if isinstance(values, dict):
        return {k: _listed(v) for k, v in values.items()}
    if isinstance(values, list):
        return [_listed(v) for v in values]
    return values.tolist() if isinstance(values, np.ndarray) else values


def _same_fields(a: Any, b: Any) -> bool:
    """Whether ``a`` (decoded by mcap-ros2-support) and ``b`` (rosbags) hold the same fields."""
    if isinstance(a, (bytes, str, int, float)) or a is None:
        return a == b or (isinstance(b, (list, tuple)) and a == bytes(b))
    if isinstance(a, (list, tuple, np.ndarray)):
        return len(a) == len(b) and all(_same_fields(x, y) for x, y in zip(a, b))
    names = [k for k in getattr(a, "__slots__", ()) if not k.startswith("_")]  # mcap-ros2 class
    return all(_same_fields(getattr(a, k), getattr(b, k)) for k in names)


def main(argv: list[str] | None = None) -> int:
    from rosbags.typesys import Stores, get_typestore

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--baseline", default=None, help="git revision of the hand-written cdr.py")
    ap.add_argument("--scan-baseline", default=None,
                    help="git revision of the whole-file reader (default: the newest that had it)")
    ap.add_argument("--seconds", type=float, default=0.2, help="time per measurement (s)")
    args = ap.parse_args(argv)
    load0 = os.getloadavg()[0]
    rev = args.baseline or _newest_with_encoders()
    ours = _baseline_module(rev)
    if ours is None:
        raise SystemExit(f"{rev}:suds_ros/io/cdr.py has no hand-written encoders")
    store = get_typestore(Stores.ROS2_JAZZY)
    from suds_ros.io import cdr  # the fast decoders as they are now (kept where they pay)

    fast = cdr if hasattr(cdr, "parse_joint_state") else ours
    fast_dec = {JS: fast.parse_joint_state, PS: fast.parse_pose_stamped}

    rows = []
    for label, type_name, values in _cases():
        m_enc, m_dec = _mcap_ros2(type_name)
        listed = _listed(values)  # mcap-ros2-support takes lists, not numpy arrays
        r_enc, r_dec = _rosbags(store, type_name)
        # rosbags' serializer is the reference (strict, byte-exact with rosbag2 for these types)
        ref = bytes(r_enc(values))
        got = {"mcap-ros2-support": m_enc(listed), "ours": ours.serialize(type_name, values)}
        for name, data in got.items():
            if data != ref:
                raise SystemExit(f"{label}: {name} encodes {data.hex()}, rosbags {ref.hex()}")
        if not _same_fields(m_dec(ref), r_dec(ref)):
            raise SystemExit(f"{label}: mcap-ros2-support and rosbags decode different fields")
        enc = {"mcap-ros2-support": lambda: m_enc(listed), "rosbags": lambda: r_enc(values),
               "ours": lambda: ours.serialize(type_name, values)}
        dec = {"mcap-ros2-support": lambda: m_dec(ref), "rosbags": lambda: r_dec(ref)}
        if type_name in fast_dec:
            dec["ours"] = lambda: fast_dec[type_name](ref)
        row = {"label": label, "bytes": len(ref), "enc": per_call_us(enc, args.seconds),
               "dec": per_call_us(dec, args.seconds)}
        rows.append(row)
        print(label, {k: {n: round(v, 2) for n, v in row[k].items()} for k in ("enc", "dec")},
              file=sys.stderr)
    bags = bag_report(args.seconds, args.scan_baseline or _newest_whole_file_reader())
    load = f"Load average (1 min) {load0:.1f} at the start, {os.getloadavg()[0]:.1f} at the end (shared machine).\n"
    write("codec.md", report(rows, rev) + bags + "\n" + load)
    return 0


# ---------------------------------------------------------------- reading whole bags
def _bag(path: Any, n: int) -> int:
    """A bag of ``n`` 9-joint JointState and ``n`` PoseStamped samples (256 KiB chunks); its size."""
    from suds_ros.io import cdr
    from suds_ros.io.mcap import BagWriter

    rng = np.random.default_rng(1)
    names = [f"joint_{k + 1}" for k in range(9)]
    with BagWriter(path, overwrite=True, chunk_interval=None) as w:
        w.add_topic("/suds/shape", JS)
        w.add_topic("/suds/body_pose", PS)
        w.write_metadata("suds", {"system": "swimmer9", "actuated": "joint_1"})
        for k in range(n):
            ns = 1_700_000_000_000_000_000 + k * 10_000_000
            w.write_raw("/suds/shape", cdr.joint_state(ns, names, rng.normal(size=9)), ns)
            w.write_raw("/suds/body_pose", cdr.pose_stamped(ns, (0.1 * k, 0.0, 0.0), (0, 0, 0, 1)), ns)
    return int(path.stat().st_size)


def _peak(fn: Callable[[], Any]) -> int:
    import tracemalloc

    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def bag_report(seconds: float, rev: str) -> str:
    """Whole-bag reading: our streamed scan, the one at ``rev``, the mcap StreamReader; peak memory."""
    import tempfile
    from pathlib import Path

    from mcap.stream_reader import StreamReader

    from suds_ros.io.mcap_scan import scan
    from suds_ros.io.recording_bag import read_recording

    def mcap_reader(path: Path) -> None:
        with open(path, "rb") as f:
            for _ in StreamReader(f, validate_crcs=True).records:
                pass

    old_scan = _baseline_scan(rev)
    lines = ["", "## Reading whole bags", "",
             "Bags of n 9-joint JointState + n PoseStamped messages written by `BagWriter` (zstd, 256 KiB",
             "chunks).  `scan` is our tolerant reader (mcap records, streamed; messages inside chunks on",
             "its two-unpack fast path), keeping every payload; `mcap StreamReader` is the mcap package's",
             "sequential reader with CRC checks (every record parsed by `mcap.records`, nothing kept).",
             f"`scan` at `{rev}` is the reader before this change (whole file in memory, hand-written",
             "field readers).  `read_recording` adds the decoding (fast decoders) and checks.  Peak:",
             "tracemalloc peak of a scan without payloads (what `bag_info` does).", "",
             f"| samples n | file MB | scan ms | scan at {rev} ms | mcap StreamReader ms | scan µs/msg "
             f"| read_recording ms | peak MB | peak at {rev} MB |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    with tempfile.TemporaryDirectory() as tmp:
        for n in (5000, 20000):
            path = Path(tmp) / f"bag{n}.mcap"
            size = _bag(path, n)
            t = per_call_us({"scan": lambda: scan(path), "old": lambda: old_scan(path),
                             "mcap": lambda: mcap_reader(path), "read": lambda: read_recording(path)},
                            seconds, rounds=3)
            peak = _peak(lambda: scan(path, keep_messages=False))
            old_peak = _peak(lambda: old_scan(path, keep_messages=False))
            lines.append(f"| {n} | {size / 1e6:.2f} | {t['scan'] / 1e3:.0f} | {t['old'] / 1e3:.0f} | "
                         f"{t['mcap'] / 1e3:.0f} | {t['scan'] / (2 * n):.2f} | {t['read'] / 1e3:.0f} | "
                         f"{peak / 1e6:.2f} | {old_peak / 1e6:.2f} |")
            print(lines[-1], file=sys.stderr)
    return "\n".join(lines) + "\n"


def report(rows: list[dict[str, Any]], rev: str) -> str:
    libs = ("mcap-ros2-support", "rosbags", "ours")

    def cell(d: dict[str, float], k: str) -> str:
        return f"{d[k]:.1f}" if k in d else "–"

    lines = ["# CDR codec speed: mcap-ros2-support vs rosbags vs our hand-written path", "",
             f"Machine: {machine()}.  Date: {stamp()}.  Generated by `benchmarks/bench_codec.py`.", "",
             "µs per message (best of 7 timed runs; the paths take turns within each run).  \"ours\": encode",
             f"with the hand-written encoder of `suds_ros/io/cdr.py` at commit `{rev}` (removed since),",
             "decode with the fast decoders of `suds_ros/io/cdr.py` (JointState and PoseStamped only).",
             "Encode starts from the values (a dict for mcap-ros2-support and ours, with float arrays as lists",
             "for mcap-ros2-support and numpy arrays for ours; rosbags typestore objects built from the same",
             "values, building included); every encoder's bytes equal rosbags' before timing.",
             "Decode ends at the library's message object (ours: a tuple of the fields).", "",
             "| message | bytes | encode " + " | encode ".join(libs) + " | decode " + " | decode ".join(libs) + " |",
             "|---|---:|" + "---:|" * 6]
    for r in rows:
        lines.append(f"| {r['label']} | {r['bytes']} | " + " | ".join(cell(r["enc"], k) for k in libs)
                     + " | " + " | ".join(cell(r["dec"], k) for k in libs) + " |")
    lines += ["", "## Totals over the seven messages", ""]
    for what, key in (("encode", "enc"), ("decode", "dec")):
        tot = {k: sum(r[key][k] for r in rows) for k in libs[:2]}
        lines.append(f"- {what}: " + ", ".join(f"{k} {v:.1f} µs" for k, v in tot.items())
                     + f" (mcap-ros2-support / rosbags = {tot[libs[0]] / tot[libs[1]]:.2f})")
    enc_tot = {k: sum(r["enc"][k] for r in rows) for k in libs[:2]}
    dec_tot = {k: sum(r["dec"][k] for r in rows) for k in libs[:2]}
    lib = min(libs[:2], key=lambda k: enc_tot[k] + dec_tot[k])
    fast = [(r["label"], r["dec"][lib] / r["dec"]["ours"]) for r in rows if "ours" in r["dec"]]
    lines += ["", "## What io/cdr.py does with this", "",
              f"- Encoding and decoding go through **{lib}**, the faster library on these messages "
              f"(summed encode + decode: {enc_tot[lib] + dec_tot[lib]:.1f} µs against "
              f"{sum(enc_tot.values()) + sum(dec_tot.values()) - enc_tot[lib] - dec_tot[lib]:.1f} µs).",
              "- The hand-written encoders are gone (\"encode ours\" above is the removed code).",
              "- The fast decoders stay for the two recorded streams, where they beat " + lib + ": "
              + "; ".join(f"{label} {x:.1f}× faster" for label, x in fast) + "."]
    lines += ["", "## Ratios", ""]
    for r in rows:
        e, d = r["enc"], r["dec"]
        fastest_enc = min(("mcap-ros2-support", "rosbags"), key=lambda k: e[k])
        fastest_dec = min(("mcap-ros2-support", "rosbags"), key=lambda k: d[k])
        text = (f"- {r['label']}: encode: {fastest_enc} fastest library; mcap-ros2-support / rosbags = "
                f"{e['mcap-ros2-support'] / e['rosbags']:.2f}, ours / mcap-ros2-support = "
                f"{e['ours'] / e['mcap-ros2-support']:.2f}; decode: {fastest_dec} fastest library; "
                f"mcap-ros2-support / rosbags = {d['mcap-ros2-support'] / d['rosbags']:.2f}")
        if "ours" in d:
            text += (f", ours is {d[fastest_dec] / d['ours']:.1f}× faster than {fastest_dec} "
                     f"({d['ours']:.1f} vs {d[fastest_dec]:.1f} µs)")
        lines.append(text)
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
