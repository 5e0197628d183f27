"""Human side of a diagnosis: terminal summary text and figures (matplotlib, Agg backend)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from suds_ros.core.diagnosis import DiagnosisReport
from suds_ros.core.diagnosis.report import BODY, NO_EFFECT


def _num(v: float, width: int, fmt: str) -> str:
    """``v`` formatted right-aligned in ``width`` columns; "n/a" when it is not finite (never "nan")."""
    return f"{v:>{width}{fmt}}" if math.isfinite(v) else f"{'n/a':>{width}}"


def parameter_text(name: str, value: float, stderr: float | None, at_bound: str | None = None) -> str:
    """One fitted parameter as the reports print it: ``d = 0.3 ± 0.01``, or a limit when ``at_bound``.

    ``at_bound`` is ``"upper"`` or ``"lower"`` (:attr:`FittedEffect.at_bound`): the fit stopped at
    that end of the parameter's admissible range, so the value is a limit and has no stderr.
    """
    if at_bound:
        return (f"{name} {'≥' if at_bound == 'upper' else '≤'} {value:.4g} (at the {at_bound} end of its "
                "admissible range: a limit, no stderr)")
    return f"{name} = {value:.4g} ± {stderr:.2g}"


def summary_text(rep: DiagnosisReport, source: str = "") -> str:
    """Multi-line terminal summary of a :class:`DiagnosisReport`."""
    lines: list[str] = []
    head = f"{rep.system}: {source}" if source else rep.system
    lines.append(head)
    lines.append(f"  train {rep.train_cycles} cycles, held out {rep.heldout_cycles} cycles (all numbers held out)")
    if rep.heldout_rms_before and set(rep.heldout_rms_before) <= set(BODY):
        lines.append("  fully actuated (no passive joint): body-velocity channels only; no joint effect "
                     "applies")
    if not rep.mismatch:
        if all(math.isfinite(v) for v in rep.statistics.values()):
            lines.append("  no significant mismatch: every channel is at the noise floor")
        else:
            lines.append("  no significant mismatch on the channels tested (see the notes for the others)")
    lines.append(f"  {'channel':<10}{'floor':>10}{'RMS before':>12}{'RMS after':>12}{'F before':>10}{'F after':>9}")
    for c, b in rep.heldout_rms_before.items():
        a = rep.heldout_rms_after.get(c, b)
        fb = rep.statistics.get(c, float("nan"))
        fa = rep.statistics_after.get(c, fb)
        flag = " *" if any(loc.channel == c for loc in rep.located) else ""
        lines.append(
            f"  {c:<10}{_num(rep.noise_floor.get(c, float('nan')), 10, '.3g')}{_num(b, 12, '.4g')}"
            f"{_num(a, 12, '.4g')}{_num(fb, 10, '.1f')}{_num(fa, 9, '.1f')}{flag}"
        )
    if rep.phase_source == "phaser":
        lines.append("  phase: the phaser's gait phase of the recorded shape (rad, zero at the upward crossing")
        lines.append("         of the shape's first principal component), shared by recording and replay")
    else:
        lines.append("  phase: clock phase 2π·gait_hz·(t − t0) (rad) — the phaser could not be fitted")
    for note in rep.notes:
        lines.append(f"  note: {note}")
    if rep.mismatch:
        lines.append("  located (* above; F = residual power / noise-floor power):")
        for loc in rep.located:
            rng = ", ".join(f"[{a:.2f}, {b:.2f}]" for a, b in loc.phase_ranges) or "none phase-locked"
            lines.append(f"    {loc.channel:<10} F = {loc.statistic:9.1f}   phase (rad): {rng}")
            for cond in rep.conditions.get(loc.channel, ())[:3]:
                lines.append(f"        {cond}")
        if rep.coefficients:
            lines.append("  SUDS coefficients, recording vs simulator (z = difference / split-half noise):")
            for g, o, z, rng in rep.coefficients[:5]:
                r = ", ".join(f"[{a:.2f}, {b:.2f}]" for a, b in rng) or "-"
                lines.append(f"    {g:<4} → {o:<14} z = {z:6.1f}   phase: {r}")
        lines.append("  candidates (held-out log-likelihood gain − BIC penalty, equation error):")
        for c in rep.ranking[:6]:
            lines.append(f"    {c.score:10.1f}  {c.label}")
        if rep.unexplained:
            lines.append("  UNEXPLAINED: no catalogue effect accounts for the located mismatch")
        for e in rep.effects:
            ps = ", ".join(parameter_text(k, v, e.stderr[k], e.at_bound.get(k)) for k, v in e.parameters.items())
            tgt = f" on {e.target}" if e.target else ""
            lines.append(f"  effect: {e.name}{tgt}: {ps}")
            for a in e.alternatives:
                head = f"    OR (ambiguous: {a.evidence_gap:+.1f} nats of held-out evidence after replay): "
                if a.name == NO_EFFECT:
                    lines.append(head + "no effect at all (the nominal model): the recording does not yet show the "
                                 "finding beyond the band")
                    continue
                aps = ", ".join(f"{k} = {v:.4g}" for k, v in a.parameters.items())
                more = "".join(f" + {n}{' on ' + t if t else ''} ({', '.join(f'{k} = {v:.4g}' for k, v in q.items())})"
                               for n, t, q in a.with_effects)
                instead = f" instead of {', '.join(a.instead_of)}" if a.instead_of else ""
                lines.append(head + f"{a.name}{' on ' + a.target if a.target else ''} ({aps}){more}{instead}")
        for g in rep.confounded_with:
            lines.append(f"  confounded on this data (cannot be told apart): {', '.join(g)}")
        ratio = rep.plain_rms_ratio
        plain = f"; plain RMS ratio 1 − Σ after/Σ before {ratio:.3f}" if ratio is not None else ""
        lines.append(f"  held-out improvement over the located channels: {rep.improvement:.3f} of the "
                     f"mismatch beyond the noise floor removed{plain}")
    return "\n".join(lines)


def write_figures(rep: DiagnosisReport, out_dir: str | Path) -> list[Path]:
    """Residual vs phase before/after per channel, and predicted vs recorded time series."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths: list[Path] = []
    chans = list(rep.series)
    if not chans:
        return paths
    n = len(chans)
    fig, axes = plt.subplots(n, 1, figsize=(8, 1.9 * n + 0.6), sharex=True, squeeze=False)
    for ax, c in zip(axes[:, 0], chans):
        s = rep.series[c]
        eb = s.recorded - s.before
        ea = s.recorded - s.after
        ax.plot(s.phase, eb, ".", ms=1.0, alpha=0.35, color="tab:red", label="before")
        ax.plot(s.phase, ea, ".", ms=1.0, alpha=0.35, color="tab:blue", label="after")
        bins = np.linspace(0, 2 * np.pi, 41)
        mid = 0.5 * (bins[1:] + bins[:-1])
        for e, col in ((eb, "darkred"), (ea, "navy")):
            ok = np.isfinite(e)
            idx = np.digitize(s.phase[ok], bins) - 1
            m = [np.mean(e[ok][idx == k]) if np.any(idx == k) else np.nan for k in range(40)]
            ax.plot(mid, m, "-", color=col, lw=1.5)
        for loc in rep.located:
            if loc.channel == c:
                for a, b in loc.phase_ranges:
                    ax.axvspan(a, b, color="orange", alpha=0.12)
        fl = rep.noise_floor.get(c)
        if fl:
            ax.axhline(fl, color="gray", lw=0.6, ls=":")
            ax.axhline(-fl, color="gray", lw=0.6, ls=":")
        ax.set_ylabel(c, fontsize=8)
    axes[0, 0].legend(loc="upper right", fontsize=7, markerscale=8)
    axes[-1, 0].set_xlabel(f"gait phase (rad, {rep.phase_source})")
    fig.suptitle(f"{rep.system}: held-out residual (recorded − simulated) vs phase", fontsize=10)
    fig.tight_layout()
    p = out / "residual_vs_phase.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    paths.append(p)

    fig, axes = plt.subplots(n, 1, figsize=(10, 1.9 * n + 0.6), sharex=True, squeeze=False)
    for ax, c in zip(axes[:, 0], chans):
        s = rep.series[c]
        sel = s.t <= s.t[0] + 5.0  # five held-out cycles
        ax.plot(s.t[sel], s.recorded[sel], "k.", ms=1.5, label="recorded")
        ax.plot(s.t[sel], s.before[sel], "-", color="tab:red", lw=0.9, label="nominal simulator")
        ax.plot(s.t[sel], s.after[sel], "-", color="tab:blue", lw=0.9, label="with fitted effect(s)")
        ax.set_ylabel(c, fontsize=8)
    axes[0, 0].legend(loc="upper right", fontsize=7)
    axes[-1, 0].set_xlabel("time since start (s)")
    fig.suptitle(f"{rep.system}: predicted vs recorded (held out)", fontsize=10)
    fig.tight_layout()
    p = out / "predicted_vs_recorded.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    paths.append(p)
    (out / "report.json").write_text(rep.to_json() + "\n")
    (out / "summary.txt").write_text(summary_text(rep) + "\n")
    paths += [out / "report.json", out / "summary.txt"]
    return paths
