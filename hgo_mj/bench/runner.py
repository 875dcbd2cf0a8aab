"""Running the benchmark: every applicable observer tuned by the same budget, then scored.

For each task and each observer (the registered families, or those asked for, or a user's
``module:Class``):

1. **Applicability.** :meth:`Observer.applicability` on the task's system, then the observer is
   built at its hand-set parameters (:data:`DEFAULTS`, per plant where a family needs its
   own); an observer that does not apply, or cannot be built, is listed with its reason and not
   scored.
2. **Default.** The untuned observer is scored on the task's scoring seeds (its own column).
3. **Tuning.** :func:`hgo_mj.tune.tune` on the task's **tuning seeds** with the same
   ``budget`` for every observer (objective: the normalized steady-state RMSE).
4. **Scores.** The tuned observer on the **scoring seeds**, disjoint from the tuning seeds, as
   one batch (:func:`hgo_mj.tune.scoring`): per seed and scored state (``scores.parquet``).

Each (task, observer) result is kept in ``OUT/parts/`` as soon as it is done (atomically), so a
killed run resumes (``resume=True``) with no lost or repeated work; a part is reused only for
the same task hash, observer, budget and defaults. Results do not depend on the backend: the
tuning's Ray backend gives the local result.
"""

from __future__ import annotations

import hashlib
import json
import math
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._io import write_text
from ..exceptions import DesignError, HgoError, MissingExtraError
from .tasks import Task, task_hash

__all__ = ["DEFAULTS", "observer_spec", "run_task_observer"]

#: the hand-set parameters each family starts from (its "default" column); per plant where
#: the family needs its own
DEFAULTS: dict[str, dict[str, Any]] = {
    "high_gain": {"k": 20.0},
    "high_gain_multi": {"k": 20.0},
    "adaptive_gain": {"lam": 0.04, "lam_hat": 0.08, "gamma": 200.0, "k0": 20.0,
                      "k_max": 2000.0},
    "riccati": {"gamma": 20.0},
    "q_integral": {"gamma": 20.0, "q": 1},
    "ekf": {"R": 1e-6},
    "ukf": {"R": 1e-6},
    "ekf_mujoco": {"R": 1e-6},
    "ukf_mujoco": {"R": 1e-6},
    "besancon": {"lam": 10.0},
    "bastin_gevers": {},
    "jo_son": {"lam": 2.0, "gamma": 5.0},
}
PLANT_DEFAULTS: dict[str, dict[str, dict[str, Any]]] = {
    "bioreactor_bullinger": {
        "high_gain": {"k": 2.0}, "high_gain_multi": {"k": 2.0},
        "adaptive_gain": {"lam": 1e-4, "lam_hat": 2e-4, "gamma": 1.0, "k0": 2.0,
                          "k_max": 50.0},
        "riccati": {"gamma": 2.0}, "q_integral": {"gamma": 2.0, "q": 1},
        "ekf": {"R": 1e-8}, "ukf": {"R": 1e-8}},
    "bioreactor_bastin_gevers": {
        "bastin_gevers": {"c1": 5.0, "gamma": 20.0, "theta_hat0": [-3.0, -0.1, -0.1],
                          "z_hat0": [1.0, 1.0]},
        "ekf": {"R": 1e-6}, "ukf": {"R": 1e-6}},
    "elastic_joint": {"high_gain": {"k": 100.0}, "high_gain_multi": {"k": 100.0},
                      "riccati": {"gamma": 100.0}, "q_integral": {"gamma": 100.0, "q": 1},
                      "besancon": {"lam": 20.0, "theta_hat0": [1.0, 9.0, 9.0],
                                   "gain": [1e-5, 1e-7, 1e-7], "method": "rk4"}},
}


def observer_spec(kind: str, plant: str, label: str | None = None) -> dict[str, Any]:
    """The scenario spec of ``kind`` at its hand-set parameters on ``plant``.

    Parameters
    ----------
    kind : str
        A registered name or ``module:Class``.
    plant : str
        The task's plant name.
    label : str, optional
        The observer's label (default ``kind``).

    Returns
    -------
    dict

    Examples
    --------
    >>> observer_spec("high_gain", "elastic_joint")
    {'type': 'high_gain', 'name': 'high_gain', 'k': 100.0}
    """
    params = PLANT_DEFAULTS.get(plant, {}).get(kind, DEFAULTS.get(kind, {}))
    return {"type": kind, "name": label or kind, **json.loads(json.dumps(params))}


def _part_key(task: Task, kind: str, budget: int) -> str:
    doc = json.dumps({"task": task_hash(task), "observer": kind, "budget": budget,
                      "spec": observer_spec(kind, str(task.plant.get("name", "")))},
                     sort_keys=True)
    return hashlib.sha256(doc.encode()).hexdigest()[:16]


def _label(kind: str) -> str:
    return kind.replace(":", ".").replace("/", ".")


def run_task_observer(task: Task, kind: str, budget: int, *, out: Path | None = None,
                      resume: bool = False, backend: str = "local", jobs: int = 1,
                      progress: bool = False) -> dict[str, Any]:
    """One (task, observer) of the benchmark (module docstring): its part, as a dict.

    Parameters
    ----------
    task : Task
    kind : str
        A registered observer name or ``module:Class``.
    budget : int
        Tuning trials (the default's included).
    out : Path, optional
        The benchmark's folder: the part is kept in ``out/parts`` and reused on resume.
    resume : bool
        Reuse a finished part of the same task hash, observer and budget.
    backend : {"local", "ray"}
        Where the tuning's rounds run.
    jobs : int
        Ray workers.
    progress : bool
        A line on stderr.

    Returns
    -------
    dict
        ``task``, ``hash``, ``observer``, ``status`` (``"scored"`` or ``"not applicable"``),
        ``reason``, and when scored: ``states``, ``units``, ``ranges``, ``sensor_std``,
        ``default`` and ``tuned`` (per variant: ``rmse``, ``peak``, ``settling`` per seed and
        state; ``iae``, ``peaking``, ``nis``, ``nis_band``, ``nees``, ``nees_band``,
        ``diverged``, ``message`` per seed;
        ``update_time``), ``parameters`` (the tuned ones), ``tune_seconds``,
        ``certified_period`` (paper 004's LMI bound for the Riccati observer, else None).

    Raises
    ------
    DesignError
        A bad budget or backend (before any work).

    Examples
    --------
    >>> from hgo_mj.bench import TASKS
    >>> part = run_task_observer(TASKS["pendulum/encoder-v1"], "jo_son", 4)
    >>> part["status"], part["reason"][:42]
    ('not applicable', 'needs the generalized observer canonical f')
    """
    from ..observers import registered
    from ..observers.base import Observer
    from ..scenario import scenario_run
    from ..tune import evaluate, setup, tune

    key = _part_key(task, kind, budget)
    path = None if out is None else Path(out) / "parts" / f"{key}.json"
    if resume and path is not None and path.is_file():
        return dict(json.loads(path.read_text()))
    plant = str(task.plant.get("name", task.plant.get("model", "")))
    base = {"task": task.name, "hash": task_hash(task), "observer": kind, "budget": budget}
    sc = task.scenario()
    label = _label(kind)
    spec = observer_spec(kind, plant, label)
    known = registered()
    if task.mismatch:
        spec["system_params"] = dict(task.mismatch)
    if task.model_fields and getattr(known.get(kind), "backend", None) == "mujoco":
        spec["model_fields"] = dict(task.model_fields)  # the same error in its MJCF copy
    sc["observers"] = [spec]
    reason = None
    if ":" not in kind and kind not in known:
        raise DesignError(f"unknown observer {kind!r}; valid: {sorted(known)}, or "
                          f"'module:Class'")
    try:
        plant_sys = scenario_run({**sc, "observers": []})["plant"].system
        cls = known.get(kind)
        reason = cls.applicability(plant_sys) if cls is not None else None
        if reason is None:
            ob: Observer = scenario_run(sc)["observers"][label]
    except HgoError as exc:
        reason = f"cannot be built at its hand-set parameters: {exc}"
    if reason is not None:
        part = {**base, "status": "not applicable", "reason": reason}
        _keep(path, part)
        return part
    t0 = time.perf_counter()
    try:
        st = setup(sc, label, t_transient=task.t_transient,
                   states=list(task.states) or None)
        default = evaluate(st, [{}], list(task.scoring_seeds), consistency=True)
        tuned = tune(sc, label, budget=budget, seeds=list(task.tuning_seeds),
                     t_transient=task.t_transient, states=list(task.states) or None,
                     backend=backend, jobs=jobs, progress=False)
        scored = evaluate(st, [tuned.best_parameters], list(task.scoring_seeds),
                          consistency=True)
    except HgoError as exc:
        part = {**base, "status": "not applicable", "reason": f"failed: {exc}"}
        _keep(path, part)
        return part
    seconds = time.perf_counter() - t0
    from ..units import system_units

    units = system_units(type(st.plant.system), tuple(st.plant.system.output_names))
    part = {**base, "status": "scored", "reason": None, "states": list(st.states),
            "units": [units.get(s, "") for s in st.states],
            "output_unit": units.get(st.plant.system.output_names[ob.outputs[0]], ""),
            "ranges": st.ranges.tolist(), "sensor_std": task.sensor_std,
            "default": _variant(default), "tuned": _variant(scored),
            "parameters": {k: np.asarray(v).tolist() for k, v in tuned.best_parameters.items()},
            "tune_seconds": seconds, "certified_period": _certified(ob, tuned.best_parameters,
                                                                    st.plant.system)}
    _keep(path, part)
    if progress:
        print(f"bench {task.name} {kind}: {seconds:.1f} s", file=sys.stderr, flush=True)
    return part


def _variant(sc: Any) -> dict[str, Any]:
    def clean(a: Any) -> Any:
        arr = np.asarray(a, dtype=float)
        return [None if not math.isfinite(v) else float(v) for v in arr.ravel()] if arr.ndim \
            else (None if not math.isfinite(float(arr)) else float(arr))

    S, k = sc.rmse.shape[1], sc.rmse.shape[2]
    return {"rmse": [clean(sc.rmse[0, j]) for j in range(S)],
            "peak": [clean(sc.peak[0, j]) for j in range(S)],
            "settling": [[None if math.isinf(v) else float(v) for v in sc.settling[0, j]]
                         for j in range(S)],
            "iae": clean(sc.iae[0]), "peaking": clean(sc.peaking[0]), "nis": clean(sc.nis[0]),
            "nis_band": clean(sc.nis_band[0]), "nees": clean(sc.nees[0]),
            "nees_band": clean(sc.nees_band[0]),
            "diverged": [m is not None for m in sc.message[0]], "message": sc.message[0],
            "update_time": float(sc.update_time[0]), "n_states": k}


def _certified(ob: Any, params: Mapping[str, Any], system: Any) -> float | None:
    """Paper 004's LMI (63)/(65) bound on the Euler sampling period of the Riccati observer
    at its tuned ``gamma`` and ``alpha`` (Lipschitz structure ``M = rho e_n``, ``N = I``), or
    None for another family, without a finite Lipschitz constant, or without the ``lmi`` extra."""
    if getattr(ob, "name", "") != "riccati":
        return None
    rho = getattr(system, "lipschitz", float("nan"))
    if not (isinstance(rho, float) and math.isfinite(rho) and rho > 0):
        return None
    from ..design import max_sampling_period

    n = ob.n
    alpha = np.asarray(params.get("alpha", ob.alpha), dtype=float)
    gamma = float(params.get("gamma", ob.gamma_))
    M = np.zeros((n, 1))
    M[-1, 0] = rho
    try:
        return float(max_sampling_period(alpha, gamma, M, np.eye(n))["delta_max"])
    except (DesignError, MissingExtraError):  # no LMI solution, or no `lmi` extra
        return None


def _keep(path: Path | None, part: Mapping[str, Any]) -> None:
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text(path, json.dumps(part, indent=1, default=_json))


def _json(v: Any) -> Any:
    if isinstance(v, np.generic):
        return v.item()
    raise TypeError(f"not JSON: {v!r}")


def parts_of(tasks: Sequence[Task], observers: Sequence[str], budget: int, *,
             out: Path | None, resume: bool, backend: str = "local", jobs: int = 1,
             progress: bool = True) -> list[dict[str, Any]]:
    """Every (task, observer) part, in order (task by task), resuming those already kept.
    With the local backend and ``jobs > 1``, the parts run in this process and ``jobs - 1``
    worker processes (:func:`hgo_mj.study.backends._local`: spawned, they die with this one),
    handed out observer by observer (:func:`_run_order`); a part does not depend on where or
    when it ran, so neither does the result (with Ray, ``jobs`` are the workers of each tuning
    round instead)."""
    specs = [_PartSpec(task, kind, budget, out, resume, backend, jobs)
             for task in tasks for kind in observers]
    local_workers = jobs if backend == "local" else 1
    index = {id(s): i for i, s in enumerate(specs)}
    done: dict[int, dict[str, Any]] = {}
    from ..study.backends import _local

    for spec, (part,) in _local(_run_order(specs, observers), local_workers, run=_run_part):
        done[index[id(spec)]] = part
        if progress:
            print(f"bench: {len(done)}/{len(specs)} {spec.task.name} {spec.kind}: "
                  f"{part['status']}", file=sys.stderr, flush=True)
    return [done[i] for i in range(len(specs))]


def _run_order(specs: Sequence[_PartSpec], observers: Sequence[str]) -> list[_PartSpec]:
    """``specs`` observer by observer (each observer's tasks in their order): a process of the
    local backend takes its parts from one end of this list, so it compiles an observer's
    kernels once (per system) and reuses them over the tasks, and the two ends compile
    different observers (not every process every family)."""
    rank = {kind: i for i, kind in enumerate(observers)}
    return sorted(specs, key=lambda s: rank[s.kind])  # stable: the tasks keep their order


@dataclass(frozen=True, eq=False)
class _PartSpec:
    """One (task, observer) of :func:`parts_of`, as plain data for a worker process."""

    task: Task
    kind: str
    budget: int
    out: Path | None
    resume: bool
    backend: str
    jobs: int


def _run_part(spec: _PartSpec) -> list[dict[str, Any]]:
    """:func:`run_task_observer` of ``spec``, as the one row a local backend's ``run`` returns
    (module-level: a worker process calls it)."""
    return [run_task_observer(spec.task, spec.kind, spec.budget, out=spec.out,
                             resume=spec.resume, backend=spec.backend,
                             jobs=spec.jobs if spec.backend == "ray" else 1)]
