"""``bench``: run the benchmark and write its files (``hgo-mj bench``).

``OUT/scores.parquet`` (one row per observer x task x seed x state, every score with its
unit), ``OUT/leaderboard.parquet`` and ``OUT/leaderboard.md`` (per task and overall, with
intervals), and the figures a reader looks at: ``score_matrix.png`` (observers x tasks,
coloured by normalized rank, the normalized RMSE in the cells), per task
``task_<name>.png`` (each observer's normalized RMSE with its interval, the untuned default
beside it) and ``traj_<name>.png`` (the best and the worst observer against the truth, one
scoring seed), and a rerun recording ``<name>.rrd`` of each task's best and worst observer.
"""

from __future__ import annotations

import io
import json
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .._io import write_bytes, write_text
from ..exceptions import DesignError
from .runner import parts_of
from .scores import leaderboard, score_rows
from .tasks import SUITE_OBSERVERS, Task, task_hash, tasks_of

__all__ = ["BenchResult", "bench", "default_observers", "markdown"]


@dataclass
class BenchResult:
    """What :func:`bench` returns.

    Parameters
    ----------
    leaderboard : pandas.DataFrame
        Per task and observer, then the overall rows.
    scores : pandas.DataFrame
        Every score row.
    table : str
        The leaderboard as Markdown (what ``leaderboard.md`` holds and the command prints).
    seconds : float
        Wall time.

    Examples
    --------
    Returned by :func:`bench` (its example).
    >>> BenchResult.__dataclass_fields__.keys()
    dict_keys(['leaderboard', 'scores', 'table', 'seconds'])
    """

    leaderboard: Any
    scores: Any
    table: str
    seconds: float


def default_observers() -> list[str]:
    """Every registered observer family except the bank (its members are families).

    Returns
    -------
    list of str

    Examples
    --------
    >>> "high_gain" in default_observers(), "bank" in default_observers()
    (True, False)
    """
    from ..observers import registered

    return sorted(k for k in registered() if k != "bank")


def _nominal(tasks: Sequence[Task]) -> dict[str, str]:
    """A task of the mismatch or friction tier -> the nominal task of the same plant, sensor
    and input (the robustness score's reference)."""
    def bare(t: Task) -> dict[str, Any]:
        return {k: v for k, v in t.plant.items() if k != "model_fields"}

    def tier(t: Task) -> bool:
        return bool(t.mismatch or t.model_fields or t.plant.get("model_fields"))

    out = {}
    for t in tasks:
        if not tier(t):
            continue
        for u in tasks:
            if (not tier(u) and bare(u) == bare(t) and u.sensor == t.sensor
                    and u.sensor_params == t.sensor_params and u.input == t.input
                    and u.sample_period == t.sample_period):
                out[t.name] = u.name
    return out


def bench(suite: str | None = "quick", *, tasks: Sequence[str] = (),
          task_files: Sequence[str | Path] = (), observers: Sequence[str] | None = None,
          budget: int = 24, out: str | Path | None = None, resume: bool = False,
          backend: str = "local", jobs: int = 1, record: bool = True,
          progress: bool = True) -> BenchResult:
    """Run the benchmark (module docstring and :mod:`hgo_mj.bench.runner`).

    Parameters
    ----------
    suite : {"quick", "full"} or None
        The built-in suite (None: only ``tasks`` and ``task_files``).
    tasks : sequence of str
        Built-in task names.
    task_files : sequence of path
        A user's task TOML files.
    observers : sequence of str, optional
        Registered names or ``module:Class`` (default: the suite's,
        :data:`~hgo_mj.bench.tasks.SUITE_OBSERVERS`, else every family).
    budget : int
        Tuning trials per observer and task, the same for all (>= 2).
    out : path, optional
        The results folder (parts kept for ``resume``).
    resume : bool
        Reuse the finished parts in ``out``.
    backend : {"local", "ray"}
        Where the work runs (see ``jobs``).
    jobs : int
        Local: the (task, observer) parts run in this process and ``jobs - 1`` workers; Ray:
        the workers of each tuning round. The results do not depend on it.
    record : bool
        Write each task's rerun recording of its best and worst observer.
    progress : bool

    Returns
    -------
    BenchResult

    Raises
    ------
    DesignError
        An unknown suite, task or observer, a bad task file, a bad budget or backend, all
        before any work.

    Examples
    --------
    >>> r = bench(None, tasks=["pendulum/encoder-v1"], observers=["high_gain", "jo_son"],
    ...           budget=4, record=False, progress=False)
    >>> r.leaderboard.loc[r.leaderboard["task"] != "overall", ["observer", "status"]].values.tolist()
    [['high_gain', 'scored'], ['jo_son', 'not applicable']]
    """
    t0 = time.perf_counter()
    chosen = tasks_of(suite, tasks, task_files)
    obs = (list(observers) if observers else
           list(SUITE_OBSERVERS.get(suite or "", ())) or default_observers())
    _check(obs, budget, backend, jobs)
    folder = None
    if out is not None:
        from .._io import check_writable

        folder = check_writable("out", out, folder=True)
        folder.mkdir(parents=True, exist_ok=True)
        write_text(folder / "tasks.json", json.dumps(
            {t.name: {"hash": task_hash(t), "description": t.description} for t in chosen},
            indent=1))
    parts = parts_of(chosen, obs, budget, out=folder, resume=resume, backend=backend,
                     jobs=jobs, progress=progress)
    import pandas as pd

    rows = score_rows(parts, {t.name: t.scoring_seeds for t in chosen})
    board = leaderboard(rows, parts, _nominal(chosen))
    scores = pd.DataFrame(rows)
    table = markdown(board, chosen, budget)
    if folder is not None:
        for name, frame in (("scores", scores), ("leaderboard", board)):
            buf = io.BytesIO()
            frame.to_parquet(buf, index=False)  # numbers stay numbers, text text
            write_bytes(folder / f"{name}.parquet", buf.getvalue())
        write_text(folder / "leaderboard.md", table + "\n")
        from .figures import write_figures

        write_figures(folder, board, scores, chosen, parts, record=record)
    return BenchResult(board, scores, table, time.perf_counter() - t0)


def _check(observers: Sequence[str], budget: Any, backend: Any, jobs: Any) -> None:
    from ..observers import registered

    known = registered()
    for o in observers:
        if not isinstance(o, str) or (":" not in o and o not in known):
            raise DesignError(f"unknown observer {o!r}; valid: {sorted(known)}, or "
                              f"'module:Class' (an Observer subclass)")
        if ":" in o:
            from .._validate import import_class
            from ..observers.base import Observer

            import_class("observer", o, Observer)  # type: ignore[type-abstract]
    if isinstance(budget, bool) or not isinstance(budget, int) or budget < 2:
        raise DesignError(f"budget must be an integer >= 2; found {budget!r}")
    if backend not in ("local", "ray"):
        raise DesignError(f"backend must be 'local' or 'ray'; found {backend!r}")
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise DesignError(f"jobs must be an integer >= 1; found {jobs!r}")


def _cell(m: Any, lo: Any, hi: Any, inf: str = "diverged") -> str:
    if m is None or m is _pd_na() or (isinstance(m, float) and math.isnan(m)):
        return "-"
    if math.isinf(m):
        return inf
    if lo is None or (isinstance(lo, float) and math.isnan(lo)) or lo == hi:
        return f"{m:.3g}"
    return f"{m:.3g} [{lo:.3g}, {hi:.3g}]"


def _pd_na() -> Any:
    """pandas' missing value (a leaderboard cell never filled)."""
    import pandas as pd

    return pd.NA


def markdown(board: Any, tasks: Sequence[Task], budget: int) -> str:
    """The leaderboard as Markdown: the overall ranking, then a table per task.

    Parameters
    ----------
    board : pandas.DataFrame
        :func:`~hgo_mj.bench.scores.leaderboard`.
    tasks : sequence of Task
    budget : int

    Returns
    -------
    str

    Examples
    --------
    >>> import pandas as pd
    >>> from hgo_mj.bench import TASKS
    >>> board = pd.DataFrame([{"task": "overall", "observer": "o", "status": "scored",
    ...                        "rank": 1, "normalized_rank": 0.0, "tasks_scored": 1,
    ...                        "divergence_rate": 0.0}])
    >>> "| 1 | o |" in markdown(board, [TASKS["pendulum/encoder-v1"]], 4)
    True
    """
    lines = [f"Every observer tuned with {budget} trials on each task's tuning seeds, scored on "
             f"its scoring seeds (disjoint). Scores: mean over the scoring seeds [95 % "
             f"bootstrap interval]. RMSE: steady state, over each state's range, the mean "
             f"over the scored states (lower is better).", "",
             "## Overall", "",
             "| rank | observer | mean normalized rank (0 best) | tasks scored | divergence "
             "rate |", "|---:|---|---:|---:|---:|"]
    ov = board[board["task"] == "overall"].sort_values("rank")
    for _, r in ov.iterrows():
        lines.append(f"| {int(r['rank'])} | {r['observer']} | {r['normalized_rank']:.3f} | "
                     f"{int(r['tasks_scored'])} | {r['divergence_rate']:.2f} |")
    for t in tasks:
        sel = board[board["task"] == t.name]
        if sel.empty:
            continue
        lines += ["", f"## {t.name}", "", f"{t.description} (hash `{task_hash(t)[:12]}`)", "",
                  "| rank | observer | RMSE (tuned) | RMSE (default) | transient IAE [s] | "
                  "peaking | settling [s] | NIS; NEES (in 95 % band) | diverged | cost/update [us] | "
                  "robustness | certified Ts [s] | tuned |",
                  "|---:|---|---|---:|---|---|---|---|---:|---:|---:|---:|---|"]
        scored = sel[sel["status"] == "scored"].sort_values("rank")
        for _, r in scored.iterrows():
            rob = r.get("robustness", math.nan)
            cert = r.get("certified_period")
            lines.append(
                f"| {int(r['rank'])} | {r['observer']} | "
                f"{_cell(r['rmse_norm'], r['rmse_norm_low'], r['rmse_norm_high'])} | "
                f"{_cell(r['default_rmse_norm'], None, None)} | "
                f"{_cell(r['iae'], r['iae_low'], r['iae_high'])} | "
                f"{_cell(r['peaking'], r['peaking_low'], r['peaking_high'])} | "
                f"{_cell(r['settling'], r['settling_low'], r['settling_high'], 'never')} | "
                f"{_consistency(r)} | {r['divergence_rate']:.2f} | "
                f"{r['update_time'] * 1e6:.3f} | {_cell(rob, None, None)} | "
                f"{_cell(cert, None, None)} | {r['parameters']} |")
        for _, r in sel[sel["status"] != "scored"].iterrows():
            lines.append(f"| - | {r['observer']} | not applicable: {r['reason']} | | | | | | | "
                         f"| | | |")
    return "\n".join(lines)


def _consistency(r: Any) -> str:
    """``NIS (share in band); NEES (share)`` of a filter, ``-`` for an observer without."""
    out = []
    for m, share in (("nis", "nis_band"), ("nees", "nees_band")):
        v, f = r.get(m, math.nan), r.get(share, math.nan)
        out.append("-" if v is None or not math.isfinite(v) else
                   f"{v:.3g} ({100 * f:.0f} %)" if f is not None and math.isfinite(f) else
                   f"{v:.3g}")
    return "-" if out == ["-", "-"] else "; ".join(out)
