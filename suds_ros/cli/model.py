"""``suds model``: robot model files (``suds-robot/1``): export a built-in one, check a file.

``suds model export NAME`` writes the model file of a built-in chain (``purcell3``,
``swimmer9``, ``nlinkN``): exactly the physics the built-in id means, so the file is a
starting point for one's own robot.  ``suds model check FILE`` loads a file with the
strict loader and prints what it understood, then simulates one gait cycle of the
nominal drive and summarises it, so a wrong sign or unit shows before any recording.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from suds_ros.core.errors import EXISTS, SudsConfigError
from suds_ros.core.json_text import dumps

if TYPE_CHECKING:
    from suds_ros.core.physics.rft import ChainModel

EPILOG = """\
examples:
  suds model export purcell3 -o purcell3.yaml   # the built-in purcell3 as a model file
  suds model export nlink6                       # print an N-link chain's file
  suds model check robot.yaml                    # what the loader understood + one simulated cycle
  suds simulate --model robot.yaml -o run.mcap   # then every command takes --model robot.yaml

The format is documented in shared/spec/robot_model.md (suds-robot/1).
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``model export`` and ``model check`` on the ``suds`` subcommand parser."""
    p = subparsers.add_parser("model", help="robot model files: export a built-in one, check a file",
                              description=__doc__.splitlines()[0], epilog=EPILOG,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="model_command", metavar="ACTION")
    sub.required = True
    e = sub.add_parser("export", help="write the model file of a built-in chain (or re-write a file)")
    e.add_argument("name", metavar="NAME", help="purcell3, swimmer9, nlinkN, or a model file to normalise")
    e.add_argument("-o", "--output", metavar="FILE", help="write here (default: print)")
    e.add_argument("--overwrite", action="store_true", help="replace an existing FILE")
    e.set_defaults(func=run_export)
    c = sub.add_parser("check", help="load a model file and print what it describes, with one "
                                     "simulated gait cycle")
    c.add_argument("file", metavar="FILE", help="robot model file (suds-robot/1)")
    c.add_argument("--json", action="store_true", help="machine-readable output")
    c.set_defaults(func=run_check)


def chain_model(spec: str) -> ChainModel:
    """Return the :class:`ChainModel` of a built-in chain id or of a model file path."""
    from suds_ros.core.physics.robot_model import load_model
    from suds_ros.core.physics.systems import builtin_model, is_model_file

    return load_model(spec) if is_model_file(spec) else builtin_model(spec)


def run_export(args: argparse.Namespace) -> int:
    """Execute ``suds model export``; returns the exit code."""
    from suds_ros.core.physics.robot_model import dump_model

    if args.output and Path(args.output).exists() and not args.overwrite:
        raise SudsConfigError(f"output {args.output!r} exists; pass --overwrite to replace it", code=EXISTS)
    text = dump_model(chain_model(args.name))
    if not args.output:
        print(text, end="")
        return 0
    try:
        Path(args.output).write_text(text, encoding="utf-8")
    except OSError as exc:
        raise SudsConfigError(f"-o {args.output!r}: cannot write ({exc.strerror})") from None
    print(f"wrote {args.output}")
    return 0


def cycle_summary(model: ChainModel, samples_per_cycle: int = 100) -> dict[str, Any]:
    """One gait cycle of the nominal drive (no perturbation, no noise) after the default warm-up.

    Returns
    -------
    dict
        ``forward``, ``lateral`` (m): displacement over the cycle along and across the cycle-mean
        heading of the pose frame (its x axis);
        ``turn`` (rad); ``speed`` (m/s): forward displacement × gait_hz; ``passive_amplitude``,
        ``passive_mean`` (rad): per passive joint, half the peak-to-peak and the mean angle.
    """
    import numpy as np

    from suds_ros.core.physics.rft import RFTChain
    from suds_ros.core.physics.sim import SimConfig, simulate

    cfg = SimConfig(cycles=1, samples_per_cycle=samples_per_cycle, gait_hz=model.gait_hz,
                    ou_std=0.0, noise_std=0.0, seed=0)
    rec = simulate(RFTChain(model), cfg)
    pose, r = rec.truth["pose"], rec.truth["r"]
    d = pose[-1, :2] - pose[0, :2]
    heading = math.atan2(float(np.mean(np.sin(pose[:, 2]))), float(np.mean(np.cos(pose[:, 2]))))
    c, s = math.cos(heading), math.sin(heading)
    forward, lateral = c * d[0] + s * d[1], -s * d[0] + c * d[1]
    names = model.joint_names
    rp = r[:, list(model.passive)]
    return {
        "gait_hz": model.gait_hz, "samples": int(rec.n_samples),
        "forward": float(forward), "lateral": float(lateral), "turn": float(pose[-1, 2] - pose[0, 2]),
        "speed": float(forward * model.gait_hz),
        "passive_amplitude": {names[j]: float(np.ptp(rp[:, k]) / 2) for k, j in enumerate(model.passive)},
        "passive_mean": {names[j]: float(np.mean(rp[:, k])) for k, j in enumerate(model.passive)},
    }


def _joint_line(model: ChainModel, j: int) -> str:
    name = model.joint_names[j]
    if j in model.actuated:
        amp, _, phase, offset = model.gait[model.actuated.index(j)]
        return (f"  {name:<12} actuated  drive {offset:g} + {amp:g}·sin(2π·{model.gait_hz:g}·t − {phase:g}) rad")
    parts = [f"stiffness {model.stiffness[j]:g} N·m/rad", f"rest {model.rest[j]:g} rad"]  # type: ignore[index]
    for key, unit in (("damping", "N·m·s/rad"), ("k3", "N·m/rad³"), ("coulomb", "N·m")):
        value = getattr(model, key)[j]
        if value:
            parts.append(f"{key} {value:g} {unit}")
    return f"  {name:<12} passive   " + ", ".join(parts)


def describe(model: ChainModel, source: str, summary: dict[str, Any]) -> str:
    """Format what ``suds model check`` prints."""
    lines = [f"{source}: robot {model.name!r}, {model.n_links} links, {model.n_links - 1} joints "
             f"({len(model.actuated)} actuated), gait {model.gait_hz:g} Hz",
             "links (head to tail):", f"  {'link':<6}{'length m':>10}{'c_par':>8}{'c_perp':>8}"]
    for i in range(model.n_links):
        lines.append(f"  {i + 1:<6}{model.link_length[i]:>10g}{model.c_par[i]:>8g}"  # type: ignore[index]
                     f"{model.c_perp[i]:>8g}")  # type: ignore[index]
    x, y, yaw = model.pose_offset
    lines.append(f"body frame: link {model.body_link + 1}, offset x {x:g} m, y {y:g} m, "  # type: ignore[operator]
                 f"yaw {yaw:g} rad from its centre")
    lines.append("joints (head to tail):")
    lines += [_joint_line(model, j) for j in range(model.n_links - 1)]
    lines.append(f"flow: ({model.flow[0]:g}, {model.flow[1]:g}) m/s")
    lines.append(f"one gait cycle ({summary['samples']} samples, nominal drive, no noise):")
    lines.append(f"  displacement forward {summary['forward']:.4g} m, lateral {summary['lateral']:.4g} m, "
                 f"turn {math.degrees(summary['turn']):.3g}° (along/across the mean heading)")
    lines.append(f"  mean forward speed {summary['speed']:.4g} m/s")
    amps = ", ".join(f"{n} ±{a:.3g} rad (mean {summary['passive_mean'][n]:.3f})"
                     for n, a in summary["passive_amplitude"].items())
    lines.append(f"  passive joint amplitudes: {amps or 'none (fully actuated)'}")
    return "\n".join(lines)


def run_check(args: argparse.Namespace) -> int:
    """Execute ``suds model check``; returns the exit code."""
    from suds_ros.core.physics.robot_model import load_model, model_to_dict

    model = load_model(args.file)
    summary = cycle_summary(model)
    if args.json:
        print(dumps({"file": args.file, "model": model_to_dict(model), "cycle": summary}, indent=2))
    else:
        print(describe(model, args.file, summary))
    return 0
