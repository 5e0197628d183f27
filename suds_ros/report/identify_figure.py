"""Figures in the style of the paper's Figure 1 (matplotlib, Agg backend, imported lazily)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from suds_ros.core.ident.identify import SudsIdentifier
from suds_ros.core.ident.scoring import Prediction
from suds_ros.core.recording import Recording


def identify_figure(
    ident: SudsIdentifier,
    train: Recording,
    test: Recording,
    pred: Prediction,
    path: str | Path,
    title: str = "",
) -> Path:
    """Write a four-panel figure of gait data, residuals and predicted vs true velocities.

    The panels: gait data (train/test) with the phase average, residuals of the data-driven model
    vs the template for body and passive velocity, and predicted vs true velocities.  A fully
    actuated chain has no passive panel (three panels; its gait is shown in two actuated joints).

    Returns the path written (PNG or any format matplotlib infers from the suffix).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    groups = [(p, lab) for p, lab in (("xi_", "body velocity"), ("rdot_", "passive velocity")) if pred.columns(p)]
    fig, axes = plt.subplots(1, 2 + len(groups), figsize=(4.5 * (2 + len(groups)), 4.2))
    ax = axes[0]
    ph_te = np.mod(pred.phase, 2 * np.pi)
    j0 = int(train.actuated_index[0])
    if train.passive:
        jp = int(train.passive_index[0])
    else:  # fully actuated: the gait in two driven joints (the same one if there is only one)
        jp = int(train.actuated_index[min(1, len(train.actuated) - 1)])
    ax.plot(train.r[:, j0], train.r[:, jp], ".", ms=1, color="tab:red", alpha=0.3, label="train")
    ax.plot(test.r[:, j0], test.r[:, jp], ".", ms=1, color="tab:blue", alpha=0.3, label="test")
    grid = np.linspace(0, 2 * np.pi, 200)
    th = ident.template_.predict(grid)
    ax.plot(th[:, j0], th[:, jp], "k-", lw=2, label="phase average θ")
    ax.set_xlabel(f"{train.joint_names[j0]} (actuated)")
    ax.set_ylabel(f"{train.joint_names[jp]} ({'passive' if train.passive else 'actuated'})")
    ax.set_title("gait data")
    ax.legend(loc="best", fontsize=7, markerscale=8)

    for ax, (prefix, label) in zip(axes[1:], groups):
        cols = pred.columns(prefix)
        res_t = np.linalg.norm(pred.template[:, cols] - pred.truth[:, cols], axis=1)
        res_m = np.linalg.norm(pred.model[:, cols] - pred.truth[:, cols], axis=1)
        ax.plot(ph_te, res_t, ".", ms=1.5, color="0.6", label="template residual")
        ax.plot(ph_te, res_m, ".", ms=1.5, color="tab:blue" if prefix == "xi_" else "tab:red",
                label="SUDS model residual")
        ax.set_xlabel("phase (rad)")
        ax.set_ylabel(f"|{label} residual|")
        ax.set_title(f"{label}: residuals (test)")
        ax.legend(loc="upper right", fontsize=7, markerscale=6)

    ax = axes[-1]
    n = min(300, pred.t.size)
    tt = pred.t[:n] - pred.t[0]
    for i, c in enumerate(pred.channels[:4]):
        ax.plot(tt, pred.truth[:n, i], "k-", lw=0.8)
        ax.plot(tt, pred.template[:n, i], "-", color="0.7", lw=0.8)
        ax.plot(tt, pred.model[:n, i], "--", lw=1.0, label=c)
    ax.set_xlabel("time (s)")
    ax.set_title("truth (black), template (grey), model (dashed)")
    ax.legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
