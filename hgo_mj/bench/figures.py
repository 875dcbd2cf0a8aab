"""The benchmark's figures and recordings (:func:`write_figures`): the score matrix, a
dot-and-interval chart per task, a trajectory panel of each task's best and worst observer
against the truth, and its rerun recording."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .._io import save_figure
from .runner import observer_spec
from .tasks import Task

__all__ = ["interval_chart", "score_matrix", "write_figures"]


def _slug(name: str) -> str:
    return name.replace("/", "__").replace(":", "_")


def score_matrix(board: Any, *, ax: Any = None) -> Any:
    """Observers x tasks, each cell coloured by the observer's normalized rank on the task
    (0 best, green; 1 worst, red; grey: not applicable) with its normalized RMSE written in.

    Parameters
    ----------
    board : pandas.DataFrame
        :func:`~hgo_mj.bench.scores.leaderboard`.
    ax : matplotlib.axes.Axes, optional
        Where to draw; default a new figure (:func:`hgo_mj.plotting.new_figure`).

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.

    Examples
    --------
    >>> import pandas as pd
    >>> board = pd.DataFrame([
    ...     {"task": "a-v1", "observer": "x", "status": "scored", "normalized_rank": 0.0,
    ...      "rmse_norm": 0.01, "rank": 1},
    ...     {"task": "a-v1", "observer": "y", "status": "not applicable", "normalized_rank": None,
    ...      "rmse_norm": None, "rank": None}])
    >>> type(score_matrix(board)).__name__
    'Figure'
    """
    from matplotlib import colormaps

    from ..plotting import axes_grid

    cells = board[board["task"] != "overall"]
    tasks = list(dict.fromkeys(cells["task"]))
    overall = board[board["task"] == "overall"].sort_values("rank")
    observers = list(overall["observer"]) + sorted(set(cells["observer"]) - set(overall["observer"]))
    fig, grid = axes_grid(ax, (1, 1), (1.2 + 0.9 * len(tasks), 1.0 + 0.42 * len(observers)),
                          "score_matrix")
    ax = grid[0, 0]
    cmap = colormaps["RdYlGn_r"]
    M = np.full((len(observers), len(tasks)), np.nan)
    for _, r in cells.iterrows():
        if r["status"] == "scored" and r.get("normalized_rank") is not None:
            M[observers.index(r["observer"]), tasks.index(r["task"])] = float(r["normalized_rank"])
    ax.imshow(np.ma.masked_invalid(M), cmap=cmap, vmin=0.0, vmax=1.0, aspect="auto")
    ax.set_facecolor("0.85")
    for _, r in cells.iterrows():
        i, j = observers.index(r["observer"]), tasks.index(r["task"])
        if r["status"] != "scored":
            txt = "n/a"
        else:
            v = r.get("rmse_norm")
            txt = "div." if v is None or not math.isfinite(float(v)) else f"{float(v):.2g}"
        ax.text(j, i, txt, ha="center", va="center", fontsize=7)
    ax.set_xticks(range(len(tasks)), [t.replace("/", "/\n") for t in tasks], fontsize=7,
                  rotation=60, ha="right")
    ax.set_yticks(range(len(observers)), observers, fontsize=8)
    ax.set_title("normalized steady-state RMSE (tuned)\ncolour: rank on the task\n(green "
                 "best, red worst, grey: n/a)", fontsize=9)
    return fig


def interval_chart(board: Any, task: str, *, ax: Any = None) -> Any:
    """One task: each scored observer's normalized RMSE (tuned, a dot with its 95 %
    interval) and the untuned default's (a hollow marker), log scale, best at the top.

    Parameters
    ----------
    board : pandas.DataFrame
    task : str
    ax : matplotlib.axes.Axes, optional
        Where to draw; default a new figure (:func:`hgo_mj.plotting.new_figure`).

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.

    Examples
    --------
    >>> import pandas as pd
    >>> board = pd.DataFrame([{"task": "a-v1", "observer": "x", "status": "scored",
    ...     "rank": 1, "rmse_norm": 0.01, "rmse_norm_low": 0.009, "rmse_norm_high": 0.011,
    ...     "default_rmse_norm": 0.05}])
    >>> type(interval_chart(board, "a-v1")).__name__
    'Figure'
    """
    from ..plotting import axes_grid

    sel = board[(board["task"] == task) & (board["status"] == "scored")].sort_values("rank")
    fig, grid = axes_grid(ax, (1, 1), (6.5, 0.9 + 0.38 * max(len(sel), 1)), "interval_chart")
    ax = grid[0, 0]
    names = list(sel["observer"])[::-1]
    for y, (_, r) in enumerate(sel.iloc[::-1].iterrows()):
        m = float(r["rmse_norm"])
        if math.isfinite(m):
            lo, hi = float(r["rmse_norm_low"]), float(r["rmse_norm_high"])
            if math.isfinite(lo) and math.isfinite(hi):
                ax.plot([lo, hi], [y, y], color="tab:blue", lw=2)
            ax.plot(m, y, "o", color="tab:blue", label="tuned" if y == len(sel) - 1 else None)
        d = float(r["default_rmse_norm"])
        if math.isfinite(d):
            ax.plot(d, y, "o", mfc="none", color="0.4",
                    label="untuned default" if y == len(sel) - 1 else None)
    ax.set_yticks(range(len(names)), names, fontsize=8)
    ax.set_xscale("log")
    ax.set_xlabel("normalized steady-state RMSE (95 % bootstrap interval over the seeds)")
    ax.set_title(task, fontsize=10)
    ax.grid(True, axis="x", alpha=0.3)
    if len(sel):
        ax.legend(fontsize=8, loc="best")
    return fig


def write_figures(folder: Path, board: Any, scores: Any, tasks: Sequence[Task],
                  parts: Sequence[dict[str, Any]], *, record: bool = True) -> list[Path]:
    """Write the score matrix, each task's interval chart and trajectory panel, and (with
    ``record``) each task's rerun recording of its best and worst observer.

    Parameters
    ----------
    folder : Path
    board, scores : pandas.DataFrame
    tasks : sequence of Task
    parts : sequence of dict
    record : bool

    Returns
    -------
    list of Path
        The files written.

    Examples
    --------
    Called by :func:`hgo_mj.bench.report.bench`.

    >>> callable(write_figures)
    True
    """
    from ..plotting import plot_trajectory

    written = [save_figure(score_matrix(board), folder / "score_matrix.png")]
    for t in tasks:
        slug = _slug(t.name)
        written.append(save_figure(interval_chart(board, t.name), folder / f"task_{slug}.png"))
        pair = best_and_worst(board, t)
        if not pair:
            continue
        traj = trajectory(t, pair, parts)
        title = f"{t.name}: best {pair[0]}" + (f", worst {pair[-1]}" if len(pair) > 1 else "")
        written.append(save_figure(plot_trajectory(traj, title=title),
                                   folder / f"traj_{slug}.png"))
        if record:
            from ..record import record_trajectory

            path = folder / f"{slug}.rrd"
            record_trajectory(traj, path)
            written.append(path)
    return written


def _spec_for(task: Task, observer: str, params: dict[str, Any]) -> dict[str, Any]:
    plant = str(task.plant.get("name", ""))
    spec = observer_spec(observer, plant, observer.replace(":", ".").replace("/", "."))
    spec.update(params)
    if task.mismatch:
        spec["system_params"] = dict(task.mismatch)
    return spec


def best_and_worst(board: Any, task: Task) -> list[str]:
    """The task's best and worst scored observers (by rank; one if only one)."""
    sel = board[(board["task"] == task.name) & (board["status"] == "scored")].sort_values("rank")
    names = list(sel["observer"])
    return names[:1] + (names[-1:] if len(names) > 1 else [])


def trajectory(task: Task, observers: Sequence[str], parts: Sequence[dict[str, Any]]) -> Any:
    """One scoring seed of the task with the given (tuned) observers, simulated."""
    from ..scenario import scenario_run
    from ..simulate import simulate

    params = {p["observer"]: p.get("parameters", {}) for p in parts if p["task"] == task.name}
    sc = task.scenario()
    sc["observers"] = [_spec_for(task, o, params.get(o, {})) for o in observers]
    kw = scenario_run(sc)
    kw.pop("metadata", None)
    return simulate(seed=task.scoring_seeds[0], isolate=True, **kw)

