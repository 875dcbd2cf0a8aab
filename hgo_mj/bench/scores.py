"""The benchmark's scores, their intervals and the leaderboard.

Per observer, task, scoring seed and scored state (``scores.parquet``, one row each, with the
untuned default and the tuned observer as ``variant``):

* ``rmse_norm``: the steady-state RMSE (after the task's transient) over the state's range over
  the run; ``rmse`` the same in the state's unit;
* ``noise_amplification``: the steady-state RMSE over the sensor's standard deviation (the
  preset's), in the state's unit per the output's unit (``rad/s / rad`` = 1/s for a velocity:
  how much of the sensor's noise the estimate passes on, per second of differentiation);
* ``settling``: seconds into a band of 5 % of the state's range (inf: never);
* ``peak_norm``: the largest error over the state's range.

Per observer, task and seed (the same in each state's row): ``iae`` (the integral of the
normalized error norm over the first second: the transient), ``peaking`` (the largest
normalized error norm over the initial one), ``nis`` (a filter's mean normalized innovation
squared) and ``nis_band`` (the share of its samples inside the chi-square 95 % band), ``nees``
(a filter's mean normalized estimation error squared over the plant states it estimates, read
at about 200 instants after the transient: :func:`hgo_mj.metrics.nees`) and ``nees_band``
(the share of those instants inside the band; a consistent filter has NIS and NEES near their
number of channels and states, and about 0.95 inside the band), ``diverged``,
``update_time`` (seconds per update, warm, compile excluded).

The **leaderboard** gives per task and observer the mean over the scoring seeds of each score
with a 95 % bootstrap confidence interval (:func:`bootstrap_ci`: the seeds resampled, the BCa
interval of :func:`scipy.stats.bootstrap`), the default's normalized RMSE in its own column,
the divergence rate, the warm cost per update, the certified sample period where the family
has one, and the robustness (on a task with model mismatch: its normalized RMSE over the
same observer's on the nominal task of the same plant and sensor). **The rank** of an
observer on a task orders the mean normalized steady-state RMSE (a diverged observer last),
ties broken by the transient ``iae``; the overall rank orders the mean over the tasks an
observer was scored on of its normalized rank ``(rank - 1) / (n - 1)`` (0 best, 1 worst), so a
family that applies to fewer tasks is neither rewarded nor punished for it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["bootstrap_ci", "leaderboard", "score_rows"]

CONFIDENCE = 0.95
#: the consistency scores of a filter (NaN for an observer without a covariance)
CONSISTENCY = ("nis", "nis_band", "nees", "nees_band")
RESAMPLES = 2000


def bootstrap_ci(values: Sequence[float], *, seed: int = 0) -> tuple[float, float, float]:
    """The mean of ``values`` and its 95 % bootstrap confidence interval (BCa,
    :func:`scipy.stats.bootstrap`, 2,000 resamples, seeded): ``(mean, low, high)``.
    Non-finite values (a diverged seed) make the mean inf and the interval NaN; one value, or
    all equal, gives the value itself as both ends.

    Parameters
    ----------
    values : sequence of float
        One value per scoring seed.
    seed : int
        The resampling's seed.

    Returns
    -------
    tuple of float

    Examples
    --------
    >>> m, lo, hi = bootstrap_ci([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    >>> m, lo < m < hi
    (3.5, True)
    """
    a = np.asarray(values, dtype=float)
    if a.size == 0:
        return math.nan, math.nan, math.nan
    if not np.all(np.isfinite(a)):
        return math.inf, math.nan, math.nan
    m = float(a.mean())
    if a.size < 2 or np.all(a == a[0]):
        return m, m, m
    from scipy.stats import bootstrap

    res = bootstrap((a,), np.mean, n_resamples=RESAMPLES, confidence_level=CONFIDENCE,
                    method="BCa", rng=np.random.default_rng(seed))
    lo, hi = float(res.confidence_interval.low), float(res.confidence_interval.high)
    if not (math.isfinite(lo) and math.isfinite(hi)):  # BCa undefined: the percentile one
        res = bootstrap((a,), np.mean, n_resamples=RESAMPLES, confidence_level=CONFIDENCE,
                        method="percentile", rng=np.random.default_rng(seed))
        lo, hi = float(res.confidence_interval.low), float(res.confidence_interval.high)
    return m, lo, hi


def score_rows(parts: Sequence[Mapping[str, Any]], seeds: Mapping[str, Sequence[int]]
               ) -> list[dict[str, Any]]:
    """The rows of ``scores.parquet`` from the benchmark's parts (module docstring).

    Parameters
    ----------
    parts : sequence of mapping
        :func:`~hgo_mj.bench.runner.run_task_observer`'s results.
    seeds : mapping
        Task name -> its scoring seeds.

    Returns
    -------
    list of dict

    Examples
    --------
    >>> part = {"task": "t-v1", "hash": "h", "observer": "o", "status": "scored",
    ...         "states": ["angle"], "units": ["rad"], "output_unit": "rad", "ranges": [2.0],
    ...         "sensor_std": 0.01, "parameters": {}, "tune_seconds": 1.0,
    ...         "certified_period": None, "default": None,
    ...         "tuned": {"rmse": [[0.02]], "peak": [[0.4]], "settling": [[0.1]],
    ...                   "iae": [0.3], "peaking": [1.0], "nis": [None], "diverged": [False],
    ...                   "message": [None], "update_time": 1e-7, "n_states": 1}}
    >>> row = score_rows([part], {"t-v1": [101]})[0]
    >>> row["rmse_norm"], row["noise_amplification"], row["noise_amplification_unit"]
    (0.01, 2.0, 'rad / rad')
    """
    rows = []
    for p in parts:
        if p.get("status") != "scored":
            continue
        for variant in ("default", "tuned"):
            v = p.get(variant)
            if not v:
                continue
            for j, seed in enumerate(seeds[p["task"]]):
                for i, (state, unit) in enumerate(zip(p["states"], p["units"])):
                    rng = p["ranges"][i]
                    rmse = _num(v["rmse"][j][i])
                    peak = _num(v["peak"][j][i])
                    rows.append({
                        "task": p["task"], "task_hash": p["hash"], "observer": p["observer"],
                        "variant": variant, "seed": int(seed), "state": state, "unit": unit,
                        "rmse": rmse, "rmse_norm": rmse / rng,
                        "noise_amplification": rmse / p["sensor_std"],
                        "noise_amplification_unit": f"{unit} / {p['output_unit']}",
                        "settling": _num(v["settling"][j][i]),
                        "peak_norm": peak / rng, "iae": _num(v["iae"][j]),
                        "peaking": _num(v["peaking"][j]), "nis": _num(v["nis"][j], math.nan),
                        **{c: _num((v.get(c) or [None] * (j + 1))[j], math.nan)
                           for c in ("nis_band", "nees", "nees_band")},
                        "diverged": bool(v["diverged"][j]),
                        "update_time": float(v["update_time"])})
    return rows


def _num(v: Any, never: float = math.inf) -> float:
    return never if v is None else float(v)


def leaderboard(rows: Sequence[Mapping[str, Any]], parts: Sequence[Mapping[str, Any]],
                nominal: Mapping[str, str] | None = None) -> Any:
    """The leaderboard (a pandas DataFrame, one row per task and observer, then the overall
    rows, ``task == "overall"``), from the score rows and the parts (module docstring).

    Parameters
    ----------
    rows : sequence of mapping
        :func:`score_rows`.
    parts : sequence of mapping
        The benchmark's parts (for the not-applicable observers, the tuned parameters, the
        certified period).
    nominal : mapping, optional
        Task with model mismatch -> its nominal task (robustness).

    Returns
    -------
    pandas.DataFrame

    Examples
    --------
    >>> part = {"task": "t-v1", "hash": "h", "observer": "o", "status": "scored",
    ...         "states": ["angle"], "units": ["rad"], "output_unit": "rad", "ranges": [2.0],
    ...         "sensor_std": 0.01, "parameters": {"k": 5.0}, "tune_seconds": 1.0,
    ...         "certified_period": None, "default": None,
    ...         "tuned": {"rmse": [[0.02], [0.04]], "peak": [[0.4], [0.4]],
    ...                   "settling": [[0.1], [0.1]], "iae": [0.3, 0.3], "peaking": [1.0, 1.0],
    ...                   "nis": [None, None], "diverged": [False, False],
    ...                   "message": [None, None], "update_time": 1e-7, "n_states": 1}}
    >>> board = leaderboard(score_rows([part], {"t-v1": [101, 102]}), [part])
    >>> r = board.loc[0]
    >>> r["task"], r["observer"], int(r["rank"]), float(r["rmse_norm"])
    ('t-v1', 'o', 1, 0.015)
    """
    import pandas as pd

    frame = pd.DataFrame(list(rows))
    out: list[dict[str, Any]] = []
    by_part = {(p["task"], p["observer"]): p for p in parts}
    for (task, observer), part in by_part.items():
        entry: dict[str, Any] = {"task": task, "observer": observer, "status": part["status"],
                                 "reason": part.get("reason")}
        if part["status"] == "scored" and not frame.empty:
            sel = frame[(frame["task"] == task) & (frame["observer"] == observer)]
            tuned = sel[sel["variant"] == "tuned"]
            per_seed = tuned.groupby("seed")
            for col in ("rmse_norm", "noise_amplification", "settling", "peak_norm"):
                vals = per_seed[col].mean().to_numpy()
                m, lo, hi = bootstrap_ci(vals)
                entry.update({col: m, f"{col}_low": lo, f"{col}_high": hi})
            for col in ("iae", "peaking") + CONSISTENCY:
                vals = per_seed[col].first().to_numpy()
                m, lo, hi = bootstrap_ci(vals) if col not in CONSISTENCY or np.isfinite(
                    vals).all() else (math.nan, math.nan, math.nan)
                entry.update({col: m, f"{col}_low": lo, f"{col}_high": hi})
            default = sel[sel["variant"] == "default"].groupby("seed")["rmse_norm"].mean()
            entry["default_rmse_norm"] = float(default.mean()) if len(default) else math.nan
            entry["divergence_rate"] = float(per_seed["diverged"].first().mean())
            entry["update_time"] = float(tuned["update_time"].iloc[0])
            cert = part.get("certified_period")
            entry["certified_period"] = math.nan if cert is None else float(cert)
            entry["parameters"] = ", ".join(
                f"{k} = {_short(v)}" for k, v in part.get("parameters", {}).items())
            entry["tune_seconds"] = float(part.get("tune_seconds") or math.nan)
        out.append(entry)
    board = pd.DataFrame(out)
    if board.empty:
        return board
    board["rank"] = pd.NA
    for _, grp in board[board["status"] == "scored"].groupby("task"):
        key = grp["rmse_norm"].replace(math.inf, 1e300).fillna(1e300)
        order = sorted(grp.index, key=lambda i: (key[i], grp.loc[i, "iae"]))
        for r, i in enumerate(order, 1):
            board.loc[i, "rank"] = r
        n = len(order)
        for i in order:
            board.loc[i, "normalized_rank"] = 0.0 if n == 1 else (board.loc[i, "rank"] - 1) / (n - 1)
    for task, base in (nominal or {}).items():
        for i in board.index[board["task"] == task]:
            ref = board[(board["task"] == base) & (board["observer"] == board.loc[i, "observer"])]
            if len(ref) and ref["rmse_norm"].notna().all():
                board.loc[i, "robustness"] = board.loc[i, "rmse_norm"] / float(
                    ref["rmse_norm"].iloc[0])
    scored = board[board["status"] == "scored"]
    overall = []
    for observer, grp in scored.groupby("observer"):
        overall.append({"task": "overall", "observer": observer, "status": "scored",
                        "normalized_rank": float(grp["normalized_rank"].mean()),
                        "tasks_scored": int(len(grp)),
                        "divergence_rate": float(grp["divergence_rate"].mean())})
    ov = pd.DataFrame(overall).sort_values(["normalized_rank", "observer"])
    ov["rank"] = range(1, len(ov) + 1)
    out_frame = pd.concat([board, ov], ignore_index=True)
    out_frame["rank"] = out_frame["rank"].astype("Int64")  # NA: not applicable
    return out_frame


def _short(v: Any) -> str:
    a = np.asarray(v, dtype=float)
    if a.ndim == 0:
        return f"{float(a):.3g}"
    if a.ndim == 2 and a.shape[0] == a.shape[1]:
        return "diag[" + ", ".join(f"{x:.2g}" for x in np.diag(a)) + "]"
    return "[" + ", ".join(f"{x:.3g}" for x in a.ravel()) + "]"
