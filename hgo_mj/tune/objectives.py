"""What a tuning minimizes: scores of a round's members, reduced to one value per trial.

With ground truth (the simulated plant's state):

* ``rmse``: the RMSE of each scored state after the transient over that state's range, the
  mean over the scored states (dimensionless: states of different units weigh alike);
* ``peak``: the largest error of each scored state over its range, the mean over the states;
* ``settling``: the longest time any scored state takes into its 5 % band (seconds).

Without ground truth (what a user has on a real rig):

* ``output_error``: the RMS output prediction error after the transient (output units),
  :meth:`hgo_mj.observers.Observer.predicted_output` against the next measurement;
* ``whiteness``: how far those errors (a filter's innovations) are from white, the Box-Pierce
  statistic over 10 lags divided by 10 (about 1 for white errors; an observer too slow leaves
  its errors positively correlated, one too fast, chasing the noise, negatively): on its own
  or weighted beside ``output_error`` (:mod:`hgo_mj.tune.scoring`);
* ``nis``: ``|log(mean NIS / p)|``, how far a filter's mean normalized innovation squared is
  from its expected value ``p`` (the number of measured outputs; Bar-Shalom, Li and
  Kirubarajan, *Estimation with Applications to Tracking and Navigation*, sec. 5.4.2): zero for
  a consistent filter, the same for an over- and an under-confident one by the same factor.

A trial's value is the members' values aggregated over the seeds and the model mismatches, by
their ``mean`` or their ``worst`` (the largest). A diverged member scores ``inf``, so a trial
with one diverged member scores ``inf`` under either.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..exceptions import DesignError
from .scoring import Scores, Setup

Array = NDArray[np.float64]

__all__ = ["AGGREGATES", "NO_TRUTH", "OBJECTIVES", "TRUTH", "Objective", "objective_values"]

TRUTH = ("rmse", "peak", "settling")
NO_TRUTH = ("output_error", "whiteness", "nis")
OBJECTIVES = TRUTH + NO_TRUTH
AGGREGATES = ("mean", "worst")


class Objective:
    """One or several objectives to minimize, each a weighted sum of the named scores.

    Parameters
    ----------
    spec : str, sequence of str, or mapping of str to float
        One score (``"rmse"``); several, one objective each (a Pareto front:
        ``["rmse", "peak"]``); or a weighted sum as one objective (``{"rmse": 1.0,
        "peak": 0.1}``).

    Attributes
    ----------
    terms : list of dict
        Per objective, score name -> weight.
    names : list of str
        Per objective, a label (``"rmse"``, ``"1*rmse+0.1*peak"``).

    Raises
    ------
    DesignError
        An unknown score (the valid ones listed), an empty spec, a weight that is not a
        positive finite number.

    Examples
    --------
    >>> Objective("rmse").names, Objective(["rmse", "peak"]).names
    (['rmse'], ['rmse', 'peak'])
    >>> Objective({"rmse": 1.0, "peak": 0.1}).names
    ['1*rmse+0.1*peak']
    >>> Objective("rms")
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: objective 'rms' is not a score; valid: ['rmse', 'peak', ...]
    """

    def __init__(self, spec: Any) -> None:
        if isinstance(spec, str):
            terms = [{spec: 1.0}]
        elif isinstance(spec, Mapping):
            terms = [dict(spec)]
        elif isinstance(spec, Sequence) and spec:
            terms = [{s: 1.0} if isinstance(s, str) else dict(s) for s in spec]
        else:
            raise DesignError(f"objective must be a score name, a list of them or a mapping of "
                              f"weights; found {spec!r}")
        for t in terms:
            if not t:
                raise DesignError("an objective needs at least one score")
            for name, w in t.items():
                if name not in OBJECTIVES:
                    raise DesignError(f"objective {name!r} is not a score; valid: "
                                      f"{list(OBJECTIVES)}")
                if isinstance(w, bool) or not isinstance(w, (int, float)) or not (
                        np.isfinite(w) and w > 0):
                    raise DesignError(f"the weight of {name!r} must be a positive number; "
                                      f"found {w!r}")
        self.terms = [{k: float(v) for k, v in t.items()} for t in terms]
        self.names = [next(iter(t)) if len(t) == 1 and next(iter(t.values())) == 1.0 else
                      "+".join(f"{v:g}*{k}" for k, v in t.items()) for t in self.terms]

    @property
    def needs_truth(self) -> bool:
        """Whether a score of ground truth is used."""
        return any(k in TRUTH for t in self.terms for k in t)

    @property
    def scores(self) -> list[str]:
        """Every score used."""
        return list(dict.fromkeys(k for t in self.terms for k in t))


def member_scores(s: Setup, sc: Scores) -> dict[str, Array]:
    """Each score per member, ``(R, S)``, from a round's :class:`Scores`."""
    with np.errstate(invalid="ignore"):
        rmse = np.mean(sc.rmse / s.ranges, axis=2)
        peak = np.mean(sc.peak / s.ranges, axis=2)
        nis = np.abs(np.log(sc.nis / s.n_outputs))
    return {"rmse": rmse, "peak": peak, "settling": np.max(sc.settling, axis=2),
            "output_error": sc.output_error, "whiteness": sc.whiteness, "nis": nis}


def objective_values(objective: Objective, s: Setup, rounds: Sequence[Scores],
                     aggregate: str = "mean") -> Array:
    """The trials' objective values ``(R, n_objectives)`` from their scores on each model
    (one :class:`Scores` per mismatch, the same trials).

    Parameters
    ----------
    objective : Objective
    s : Setup
    rounds : sequence of Scores
        One per model mismatch (one for a nominal tuning).
    aggregate : {"mean", "worst"}
        Over the seeds and the models.

    Returns
    -------
    ndarray
        ``(R, n_objectives)``; inf for a trial with a diverged member, NaN where a score is
        not available for this observer.

    Raises
    ------
    DesignError
        ``aggregate`` not one of :data:`AGGREGATES`.

    Examples
    --------
    >>> from hgo_mj.tune.scoring import evaluate, setup
    >>> sc = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.3, 0.0]},
    ...       "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
    ...       "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...       "input": {"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]},
    ...       "run": {"duration": 2.0}}
    >>> st = setup(sc, "hgo")
    >>> v = objective_values(Objective("rmse"), st, [evaluate(st, [{"k": 5.0}, {"k": 40.0}],
    ...                                                        [1, 2])])
    >>> v.shape, bool(v[1, 0] < v[0, 0])
    ((2, 1), True)
    """
    if aggregate not in AGGREGATES:
        raise DesignError(f"aggregate must be one of {list(AGGREGATES)}; found {aggregate!r}")
    per = [member_scores(s, sc) for sc in rounds]
    R = per[0]["rmse"].shape[0]
    out = np.empty((R, len(objective.terms)))
    for i, terms in enumerate(objective.terms):
        stacked = np.stack([sum(w * p[name] for name, w in terms.items()) for p in per],
                           axis=1)  # (R, models, S)
        flat = stacked.reshape(R, -1)
        with np.errstate(invalid="ignore"):
            if aggregate == "mean":
                out[:, i] = np.where(np.isinf(flat).any(axis=1), np.inf, flat.mean(axis=1))
            else:
                out[:, i] = flat.max(axis=1)
    return out
