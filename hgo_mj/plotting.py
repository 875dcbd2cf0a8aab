"""Figures of a trajectory: true versus estimated states and the estimation error per state."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

TRUE_COLOR = "black"


def plot_trajectory(traj: Any, path: str | Path, *, title: str = "") -> Path:
    """Write a PNG: one row per state, left true vs every estimate, right the error."""
    n = traj.x.shape[1]
    fig, axes = plt.subplots(n, 2, figsize=(11, 2.2 * n + 0.8), sharex=True, squeeze=False)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, name in enumerate(traj.state_names):
        ax, ae = axes[i]
        ax.plot(traj.t, traj.x[:, i], color=TRUE_COLOR, lw=1.6, label="true")
        for j, (oname, rec) in enumerate(traj.observers.items()):
            c = colors[j % len(colors)]
            ax.plot(traj.t, rec.x_hat[:, i], color=c, lw=0.9, ls="--", alpha=0.85, label=oname)
            ae.plot(traj.t, traj.x[:, i] - rec.x_hat[:, i], color=c, lw=0.7, alpha=0.7,
                    label=oname)
        ax.set_ylabel(name)
        lo, hi = traj.x[:, i].min(), traj.x[:, i].max()
        pad = 0.5 * (hi - lo) + 1e-9
        ax.set_ylim(lo - pad, hi + pad)  # keep the true signal readable under peaking
        ae.set_ylabel(f"error {name}")
        ae.axhline(0.0, color="0.6", lw=0.6)
        if traj.observers:
            errs = [abs(traj.x[len(traj.t) // 5:, i] - r.x_hat[len(traj.t) // 5:, i]).max()
                    for r in traj.observers.values()]
            lim = 1.5 * max(errs) + 1e-12
            ae.set_ylim(-lim, lim)
    axes[0, 0].legend(loc="upper right", fontsize=8)
    axes[0, 0].set_title("true vs estimate")
    axes[0, 1].set_title("estimation error (axis fits t > 20% of the run)")
    for ax in axes[-1]:
        ax.set_xlabel("t")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
