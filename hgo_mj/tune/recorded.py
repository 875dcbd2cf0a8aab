"""Tuning on recorded data: several independent Optuna studies asked and told in lockstep, each
round of every study scored as one batch by the caller.

:func:`hgo_mj.tune.tune` tunes an observer of an hgo_mj *scenario* (its plant simulated once).
Where the plant is not an hgo_mj plant (a Gymnasium environment), the caller records a run of
it and scores candidate parameters by running the observer over the recorded measurements
(:meth:`hgo_mj.observers.Observer.step` with per-member parameters); :func:`search_rounds` is the
search around that scoring. Studies whose objectives are separable (one model-free chain per
measured signal: each chain's error depends on its own gain only) are searched as independent
studies, the ``r``-th trial of every study put into member ``r`` of one batch.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..exceptions import DesignError
from ..observers.base import Dimension

__all__ = ["SearchResult", "search_rounds"]


@dataclass
class SearchResult:
    """What :func:`search_rounds` returns, per study.

    Parameters
    ----------
    best : list of dict
        Per study, the best trial's search values (the lowest score; ties: the earliest).
    best_score, default_score : list of float
        Per study, the best trial's score and the first trial's (the search space's defaults).
    trials : int
        Trials per study.

    Examples
    --------
    >>> r = SearchResult([{"k": 2.0}], [0.5], [1.0], 4)
    >>> r.best[0]["k"], r.best_score[0] < r.default_score[0]
    (2.0, True)
    """

    best: list[dict[str, float]]
    best_score: list[float]
    default_score: list[float]
    trials: int


def search_rounds(spaces: Sequence[Mapping[str, Dimension]],
                  score: Callable[[list[list[dict[str, float]]]], np.ndarray], *,
                  budget: int = 48, round_size: int = 16, seed: int = 0) -> SearchResult:
    """Search ``len(spaces)`` independent studies (Optuna's TPE, multivariate, study ``i``
    seeded ``seed + i``) in rounds: each round asks ``round_size`` trials of every study and
    hands them to ``score`` as one batch; the first trial of every study is its defaults.

    Parameters
    ----------
    spaces : sequence of mapping of str to Dimension
        Per study, its search variables (e.g. :meth:`Observer.tuning_space`).
    score : callable
        ``score(candidates) -> (R, len(spaces))`` array: ``candidates[r][i]`` is the values of
        study ``i``'s ``r``-th trial of the round; non-finite scores rank last.
    budget : int
        Trials per study, >= 2.
    round_size : int
        Trials per round, >= 1.
    seed : int
        The samplers' seed.

    Returns
    -------
    SearchResult

    Raises
    ------
    DesignError
        No study, an empty space, or a budget or round size out of range.

    Examples
    --------
    Two separable quadratic bowls searched together:

    >>> sp = [{"x": Dimension("x", 0.1, 10.0, True, 1.0)}] * 2
    >>> f = lambda c: np.array([[(v[0]["x"] - 3) ** 2, (v[1]["x"] - 5) ** 2] for v in c])
    >>> r = search_rounds(sp, f, budget=24, round_size=8)
    >>> r.best_score[0] < r.default_score[0] and r.best_score[1] < r.default_score[1]
    True
    """
    import optuna

    _check(spaces, budget, round_size)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    studies = [optuna.create_study(sampler=optuna.samplers.TPESampler(
        seed=seed + i, multivariate=True, n_startup_trials=min(10, budget)))
        for i in range(len(spaces))]
    dists: list[dict[str, Any]] = [{k: optuna.distributions.FloatDistribution(d.low, d.high, log=d.log)
              for k, d in sp.items()} for sp in spaces]
    for st, sp in zip(studies, spaces):
        st.enqueue_trial({k: d.default for k, d in sp.items()})
    done = 0
    while done < budget:
        n = min(round_size, budget - done)
        asked = [[st.ask(ds) for _ in range(n)] for st, ds in zip(studies, dists)]
        cands = [[dict(asked[i][r].params) for i in range(len(studies))] for r in range(n)]
        values = np.asarray(score(cands), dtype=float).reshape(n, len(studies))
        for i, st in enumerate(studies):
            for r in range(n):
                v = values[r, i]
                st.tell(asked[i][r], float(v) if math.isfinite(v) else 1e300)
        done += n
    return _result(studies, budget)


def _check(spaces: Sequence[Mapping[str, Dimension]], budget: Any, round_size: Any) -> None:
    if not spaces or any(not s for s in spaces):
        raise DesignError("search_rounds needs at least one study, each with a search variable")
    if isinstance(budget, bool) or not isinstance(budget, int) or budget < 2:
        raise DesignError(f"budget must be an integer >= 2; found {budget!r}")
    if isinstance(round_size, bool) or not isinstance(round_size, int) or round_size < 1:
        raise DesignError(f"round_size must be a positive integer; found {round_size!r}")


def _result(studies: list[Any], budget: int) -> SearchResult:
    best, best_v, default_v = [], [], []
    for st in studies:
        trials = [t for t in st.get_trials(deepcopy=False) if t.values is not None]
        top = min(trials, key=lambda t: (t.values[0], t.number))
        best.append(dict(top.params))
        best_v.append(_finite(top.values[0]))
        default_v.append(_finite(min(trials, key=lambda t: t.number).values[0]))
    return SearchResult(best, best_v, default_v, budget)


def _finite(v: float) -> float:
    return math.inf if v >= 1e300 else float(v)
