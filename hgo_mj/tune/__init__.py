"""Tuning any observer automatically: :func:`tune` searches an observer's tuning space
(:meth:`hgo_mj.observers.Observer.tuning_space`) with Optuna, each round of trials scored as
one batch (:mod:`hgo_mj.tune.scoring`), with or without ground truth
(:mod:`hgo_mj.tune.objectives`), robust to a wrong model (``mismatch=``); ``hgo-mj tune`` is
its command."""

from __future__ import annotations

from .objectives import OBJECTIVES, Objective, objective_values
from .scoring import Scores, Setup, evaluate, setup
from .tuner import SAMPLERS, TuneResult, best_toml, check_space, tune

__all__ = ["OBJECTIVES", "SAMPLERS", "Objective", "Scores", "Setup", "TuneResult", "best_toml",
           "check_space", "evaluate", "objective_values", "setup", "tune"]
