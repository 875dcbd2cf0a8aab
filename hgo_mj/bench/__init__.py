"""The nonlinear observer benchmark: versioned tasks (:mod:`hgo_mj.bench.tasks`) with sensor
presets (:mod:`hgo_mj.bench.presets`), every applicable observer tuned on the tuning seeds with
one budget and scored on disjoint scoring seeds (:mod:`hgo_mj.bench.runner`), scores with
bootstrap intervals and a leaderboard (:mod:`hgo_mj.bench.scores`); ``hgo-mj bench`` is its
command."""

from __future__ import annotations

from .presets import PRESETS, preset
from .report import BenchResult, bench
from .scores import bootstrap_ci, leaderboard
from .tasks import SUITES, TASKS, Task, load_task, task_hash, tasks_of

__all__ = ["PRESETS", "SUITES", "TASKS", "BenchResult", "Task", "bench", "bootstrap_ci",
           "leaderboard", "load_task", "preset", "task_hash", "tasks_of"]
