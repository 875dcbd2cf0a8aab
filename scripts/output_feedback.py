"""Output feedback through a high-gain observer: ``studies/output_feedback.toml``, reported in
``docs/results/output_feedback.md`` with its figure.

Usage::

    python scripts/output_feedback.py [--out runs/output_feedback] [--jobs 2]

Runs the study afresh in ``--out``: an LQR state feedback designed on each plant's
linearization, applied to the high-gain observer's estimate (with and without saturation of
the estimate fed to the law) and to the true state, on the cart pendulum of paper 004 (eq. 66)
and the elastic joint, at two noise levels, over the observer's gain. It draws the closed
loop's cost ``sum (x'Qx + u'Ru) Ts`` and its peak input against the gain, median and quartiles
over the seeds, and writes what they show.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from pathlib import Path

import numpy as np

from hgo_mj._bench import machine_line, versions_line
from hgo_mj._io import atomic_path, write_text
from hgo_mj.study import Study

ROOT = Path(__file__).resolve().parent.parent
STUDY = ROOT / "studies" / "output_feedback.toml"
DOC = ROOT / "docs" / "results" / "output_feedback.md"
FIG = ROOT / "docs" / "results" / "output_feedback.png"
K, SAT, SRC, SIGMA, PLANT = ("observers.hgo.k", "controller.saturate", "controller.source",
                             "sensor.stages.0.std", "plant.name")


def runs(table):
    """One row per run (cost and peak input are the run's), diverged runs kept."""
    return table.drop_duplicates(["cell", "seed"])


def curves(r):
    """Per plant and noise: for each of (estimate, saturated), (estimate, unsaturated) the
    median, quartiles of cost and peak input and the diverged fraction over the seeds per k,
    and the true-state cost."""
    out = {}
    for (plant, sigma), g in r.groupby([PLANT, SIGMA], sort=False):
        true = g[g[SRC] == "true"]
        entry = {"true_cost": float(true["cost"].median()),
                 "true_peak": float(true["peak_input"].median())}
        for sat in (True, False):
            e = g[(g[SRC] == "estimate") & (g[SAT] == sat)]
            by = e.groupby(K)
            entry[sat] = {"k": np.array(sorted(e[K].unique()), dtype=float),
                          "cost": by["cost"].median().to_numpy(float),
                          "cost_q25": by["cost"].quantile(0.25).to_numpy(float),
                          "cost_q75": by["cost"].quantile(0.75).to_numpy(float),
                          "peak": by["peak_input"].median().to_numpy(float),
                          "diverged": by["diverged"].mean().to_numpy(float)}
        out[(plant, float(sigma))] = entry
    return out


def figure(res):
    from matplotlib.figure import Figure

    from hgo_mj.systems import SYSTEMS

    keys = list(res)
    fig = Figure(figsize=(4.2 * len(keys), 6.6))
    grid = fig.subplots(2, len(keys), squeeze=False)
    for c, key in enumerate(keys):
        plant, sigma = key
        e = res[key]
        unit = SYSTEMS[plant].input_names[0]
        for sat, color, label in ((True, "C0", "estimate, saturated"),
                                  (False, "C3", "estimate, not saturated")):
            d = e[sat]
            ok = np.isfinite(d["cost"])
            ax = grid[0, c]
            ax.plot(d["k"][ok], d["cost"][ok], "o-", color=color, ms=3.5, label=label)
            ax.fill_between(d["k"][ok], d["cost_q25"][ok], d["cost_q75"][ok], color=color,
                            alpha=0.2, lw=0)
            for k in d["k"][d["diverged"] > 0]:
                ax.axvline(k, color=color, ls=":", lw=1)
            grid[1, c].plot(d["k"][ok], d["peak"][ok], "o-", color=color, ms=3.5, label=label)
        for r, val in ((0, e["true_cost"]), (1, e["true_peak"])):
            grid[r, c].axhline(val, color="k", ls="--", lw=1, label="true state (LQR)")
        for r in (0, 1):
            ax = grid[r, c]
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.grid(True, alpha=0.3)
            ax.set_xlabel("observer gain k [1/s]", fontsize=8)
            ax.tick_params(labelsize=7)
        grid[0, c].set_title(f"{plant}, sigma = {sigma:g} rad", fontsize=9)
        grid[0, c].set_ylabel("closed-loop cost sum(x'Qx + u'Ru) Ts [-]", fontsize=8)
        in_unit = "m/s^2" if unit == "acceleration" else "N m"
        grid[1, c].set_ylabel(f"peak |u| [{in_unit}]", fontsize=8)
    grid[0, 0].legend(fontsize=7)
    fig.suptitle("LQR on the high-gain estimate: median and quartiles over the seeds (dotted: "
                 "a gain where runs diverged)", fontsize=9)
    fig.subplots_adjust(left=0.07, right=0.985, bottom=0.08, top=0.9, wspace=0.35, hspace=0.35)
    return fig


def _ratio(d, true_cost):
    return d["cost"] / true_cost


def sentences(res) -> list[str]:
    out = []
    for (plant, sigma), e in res.items():
        sat, raw = e[True], e[False]
        r = _ratio(sat, e["true_cost"])
        best = int(np.nanargmin(r))
        lo_k, hi_k = sat["k"][0], sat["k"][-1]
        div = [f"{k:g}" for k, f in zip(raw["k"], raw["diverged"]) if f > 0]
        raw_peak = raw["peak"][np.isfinite(raw["peak"])]
        out.append(
            f"{plant.replace('_', ' ')} at sigma = {sigma:g} rad: with the estimate saturated "
            f"the cost is {r[0]:.3g} times the state feedback's at k = {lo_k:g} and "
            f"{r[-1]:.3g} times at k = {hi_k:g} (best {r[best]:.3g} at k = {sat['k'][best]:g}); "
            f"without saturation the peak input grows from {raw_peak[0]:.3g} to "
            f"{raw_peak[-1]:.3g}" if raw_peak.size else "")
        if div:
            out[-1] += f" and runs diverge at k = {', '.join(div)}"
    return out


def page(res, seconds: float, n_runs: int) -> str:
    s = sentences(res)
    cp = res[("cart_pendulum", 1e-7)]
    ej_lo, ej_hi = res[("elastic_joint", 1e-7)], res[("elastic_joint", 1e-4)]
    summary = [
        "Saturating the estimate fed to the law is what makes high gain work: on the cart "
        f"pendulum the saturated loop's cost falls toward the state feedback's as k grows "
        f"({_ratio(cp[True], cp['true_cost'])[0]:.2g}x at k = {cp[True]['k'][0]:g}, "
        f"{_ratio(cp[True], cp['true_cost'])[-1]:.2g}x at k = {cp[True]['k'][-1]:g}), while "
        f"without saturation the observer's peaking reaches the plant and the peak input grows "
        f"with k, as Esfandiari and Khalil's analysis predicts.",
        f"On the elastic joint (n = 4) with the fine encoder the saturated loop's cost falls "
        f"from {np.nanmax(_ratio(ej_lo[True], ej_lo['true_cost'])):.2g}x the state "
        f"feedback's (k = {ej_lo[True]['k'][int(np.nanargmax(ej_lo[True]['cost']))]:g}) to "
        f"{_ratio(ej_lo[True], ej_lo['true_cost'])[-1]:.2g}x at k = {ej_lo[True]['k'][-1]:g}, "
        f"not yet recovered on this grid; at sigma = 1e-4 rad it rises again beyond k = "
        f"{ej_hi[True]['k'][1 + int(np.nanargmin(ej_hi[True]['cost'][1:]))]:g}, the noise "
        "amplified by k^3 in the motor velocity estimate: the performance comes back with the "
        "gain only as far as the measurement allows."]
    lines = ["# Output feedback through a high-gain observer", "",
             f"Generated by `python scripts/output_feedback.py` from "
             f"`studies/output_feedback.toml` ({n_runs} closed-loop runs in {seconds:.0f} s; "
             f"{machine_line()}; {versions_line()}).", "", "## What it shows", "",
             *summary, "", "![cost and peak input against the gain](output_feedback.png)", "",
             "## Per plant and noise level", ""]
    lines += [f"* {x}." for x in s if x]
    lines += ["", "## Setup", "",
              "* Plants: the cart pendulum of paper 004, eq. 66 (x1'' = sin x1 + u cos x1, the "
              "input a pivot acceleration; x0 = (0.3 rad, 0)), and the elastic joint "
              "(x0 = (0.3, 0.3, 0, 0)), both in MuJoCo at 1 kHz for 5 s.",
              "* Law: LQR with Q = I, R = 1 on the linearization at the origin "
              "(`hgo_mj.control.lqr`), u = -K sat(x_hat), the estimate clipped to |x| <= "
              "(0.5 rad, 1 rad/s) on the cart pendulum and (1, 1 rad, 5, 5 rad/s) on the "
              "elastic joint when saturated (Khalil, Nonlinear Systems, 3rd ed., sec. 14.5), "
              "and the same law on the true state as the target.",
              "* Observer: the high-gain observer with the model term (paper 000, eq. 2-4; "
              "`model = true`), from x_hat(0) = 0, sampled at 1 kHz (exact update).",
              "* Sensor: Gaussian noise of sigma = 1e-7 and 1e-4 rad on the measured angle; 4 "
              "seeds per cell. Cost: sum over the samples of (x'Qx + u'Ru) times 1 ms.", ""]
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "runs" / "output_feedback"))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--quiet", action="store_true", help="no plan line and no progress")
    args = ap.parse_args()
    study = Study.from_toml(STUDY)
    shutil.rmtree(args.out, ignore_errors=True)
    t0 = time.perf_counter()
    result = study.run(args.out, jobs=args.jobs, quiet=args.quiet)
    seconds = time.perf_counter() - t0
    r = runs(result.table)
    res = curves(r)
    fig = figure(res)
    with atomic_path(FIG) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    write_text(DOC, page(res, seconds, len(r)))
    print(f"wrote {DOC} and {FIG}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
