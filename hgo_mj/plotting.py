"""Figures of a trajectory: true versus estimated states and the estimation error per state.

Estimates are matched to the plant's states by name (:meth:`~hgo_mj.simulate.Trajectory.
estimate`): an observer that does not estimate a plant state draws nothing in its row. The
observers' columns that are not plant states (an order-only observer's ``z1, z2, ...``, the
derivatives of a multi-output observer, parameter estimates) get rows of their own below,
estimates only (there is no true value, so no error). NaN samples (an inverse map undefined,
a dropout) are gaps; axis limits use the finite samples only.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from ._io import save_figure

TRUE_COLOR = "black"


def _finite_range(*arrays: Any) -> tuple[float, float] | None:
    """``(min, max)`` over the finite values of the arrays, or ``None`` if there are none."""
    vals = [a[np.isfinite(a)] for a in (np.asarray(v, dtype=float).ravel() for v in arrays)]
    vals = [v for v in vals if v.size]
    if not vals:
        return None
    cat = np.concatenate(vals)
    return float(cat.min()), float(cat.max())


def plot_trajectory(traj: Any, path: str | Path, *, title: str = "") -> Path:
    """Write a PNG: one row per plant state, left true vs every estimate, right the error;
    then one row per estimated quantity that is not a plant state (estimates only)."""
    n = traj.x.shape[1]
    extra: list[str] = []
    for oname in traj.observers:
        extra += [s for s in traj.extra_states(oname) if s not in extra]
    rows = n + len(extra)
    fig, axes = plt.subplots(rows, 2, figsize=(11, 2.2 * rows + 0.8), sharex=True,
                             squeeze=False)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    late = len(traj.t) // 5
    est = {oname: traj.estimate(oname) for oname in traj.observers}
    for i, name in enumerate(traj.state_names):
        ax, ae = axes[i]
        ax.plot(traj.t, traj.x[:, i], color=TRUE_COLOR, lw=1.6, label="true")
        errs = []
        for j, oname in enumerate(traj.observers):
            if not traj.estimated(oname)[i]:
                continue  # not estimated: nothing to draw
            c = colors[j % len(colors)]
            e = traj.x[:, i] - est[oname][:, i]
            ax.plot(traj.t, est[oname][:, i], color=c, lw=0.9, ls="--", alpha=0.85, label=oname)
            ae.plot(traj.t, e, color=c, lw=0.7, alpha=0.7, label=oname)
            errs.append(e[late:])
        ax.set_ylabel(name)
        rng = _finite_range(traj.x[:, i])
        if rng is not None:
            lo, hi = rng
            pad = 0.5 * (hi - lo) + 1e-9
            ax.set_ylim(lo - pad, hi + pad)  # keep the true signal readable under peaking
        ae.set_ylabel(f"error {name}")
        ae.axhline(0.0, color="0.6", lw=0.6)
        rng = _finite_range(*errs) if errs else None
        if rng is not None:
            lim = 1.5 * max(abs(rng[0]), abs(rng[1])) + 1e-12
            ae.set_ylim(-lim, lim)
        elif traj.observers:
            ae.text(0.5, 0.5, "not estimated", transform=ae.transAxes, ha="center",
                    va="center", color="0.4")
    for r, name in enumerate(extra, start=n):
        ax, ae = axes[r]
        vals = []
        for j, (oname, rec) in enumerate(traj.observers.items()):
            if name in rec.state_names:
                v = rec.x_hat[:, rec.state_names.index(name)]
                ax.plot(traj.t, v, color=colors[j % len(colors)], lw=0.9, ls="--", alpha=0.85,
                        label=oname)
                vals.append(v[late:])
        ax.set_ylabel(f"{name}\n(estimate only)")
        rng = _finite_range(*vals)
        if rng is not None:
            lo, hi = rng
            pad = 0.25 * (hi - lo) + 1e-9
            ax.set_ylim(lo - pad, hi + pad)  # fits t > 20% of the run, as the errors do
        ae.axis("off")
        ae.text(0.5, 0.5, f"{name}: not a plant state (no true value)", transform=ae.transAxes,
                ha="center", va="center", color="0.4")
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
    save_figure(fig, path)
    plt.close(fig)
    return path


def plot_monte_carlo(result: Any, path: str | Path, *, title: str = "") -> Path:
    """Write a PNG of a Monte Carlo study (:class:`hgo_mj.study.MonteCarloResult`): one panel
    per plant state (row) and observer (column), the RMSE of every seed as a dot over its box
    plot (quartiles, whiskers to 1.5 IQR, the mean as a triangle), each panel on its own scale
    so that the spread shows; runs with a NaN RMSE are left out (their count is noted)."""
    runs, agg = result.runs, result.aggregate
    observers = list(agg) or [""]
    states = list(next(iter(agg.values()))["states"]) if agg else [""]
    rows, cols = len(states), len(observers)
    fig, axes = plt.subplots(rows, cols, figsize=(2.6 * cols + 1.2, 1.9 * rows + 1.0),
                             squeeze=False)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    jitter = np.random.default_rng(0).uniform(-0.08, 0.08, len(runs))  # same figure every time
    for i, name in enumerate(states):
        for j, oname in enumerate(observers):
            ax = axes[i, j]
            if i == 0:
                ax.set_title(oname, fontsize=9)
            if j == 0:
                ax.set_ylabel(f"RMSE {name}", fontsize=8)
            ax.tick_params(labelsize=7)
            ax.set_xticks([])
            if not agg or not agg[oname]["estimated"][i]:
                ax.text(0.5, 0.5, "not estimated", transform=ax.transAxes, ha="center",
                        va="center", color="0.4", fontsize=8)
                continue
            v = np.array([r[oname]["rmse"][i] for r in runs], dtype=float)
            ok = np.isfinite(v)
            if ok.any():
                ax.boxplot(v[ok], showmeans=True, widths=0.5)
                ax.plot(1 + jitter[ok], v[ok], "o", ms=3, color=colors[j % len(colors)],
                        alpha=0.6)
                ax.set_xticks([])
            if not ok.all():
                ax.text(0.02, 0.96, f"{int((~ok).sum())} NaN", transform=ax.transAxes,
                        va="top", fontsize=7, color="0.4")
    fig.suptitle((f"{title}\n" if title else "") + f"RMSE over {len(runs)} seeds", fontsize=10)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, path)
    plt.close(fig)
    return path
