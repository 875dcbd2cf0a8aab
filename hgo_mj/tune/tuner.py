"""``tune``: an Optuna search over an observer's tuning space, each round one batch.

The search (Optuna: TPE for one objective, NSGA-II for several, CMA-ES on request; every
sampler seeded, so the same call gives the same trials) runs **ask and tell in rounds**: it asks
for a round of trials, :func:`~hgo_mj.tune.scoring.evaluate` scores the whole round as one
batch (one plant run replayed, every trial x seed a member with its own parameters), and tells
the values back. The first trial is the constructor's parameters (the untuned default), so a
tuning always reports the default beside the best.

With ``out``, the Optuna study lives in ``out/study.db`` (SQLite) and every told trial is
committed there: a killed tuning resumes with ``resume=True``, losing no finished trial and
repeating none (a trial asked but not told when it was killed is scored on resume with its
stored parameters). Resuming with another scenario, observer, space, objective or seeds is
refused. After each round ``out/trials.parquet`` is rewritten (atomically).

``backend="ray"`` scores a round's trials in ``jobs`` parts as Ray tasks (Optuna's ask/tell
stays in this process; each part is a batch on a worker). The result equals the local one for
the same seed: the round's composition and the trials' parameters come from the same seeded
sampler, and each member's score is the same whichever batch it runs in. (Ray Tune's
OptunaSearch was not chosen: it hands Optuna one trial at a time, which would break the
batched rounds that make tuning fast.)
"""

from __future__ import annotations

import hashlib
import json
import math
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._io import check_writable, write_bytes, write_text
from ..exceptions import DesignError
from ..observers.base import Dimension, Observer
from .objectives import AGGREGATES, Objective, objective_values
from .scoring import Scores, Setup, evaluate, setup

__all__ = ["SAMPLERS", "TuneResult", "check_space", "tune"]

SAMPLERS = ("tpe", "cmaes", "nsga2", "random")
#: the tables a tuning scenario may have
SCENARIO_TABLES = frozenset({"name", "plant", "sensor", "observers", "input", "run"})
#: trials per round by default (a round is one batch of trials x seeds)
ROUND = 16
STUDY_NAME = "hgo_mj-tune"


@dataclass
class TuneResult:
    """What :func:`tune` returns.

    Parameters
    ----------
    best : dict
        The best trial's search values (one objective: the lowest; several: the lowest
        first objective on the Pareto front).
    best_parameters : dict
        Its parameter values for the observer (:meth:`Observer.parameters`).
    default : dict
        The constructor's search values (trial 0).
    values : dict
        ``{"default": [...], "best": [...]}``: each one's objective values.
    trials : pandas.DataFrame
        Every trial: number, state, each search value, each objective value.
    pareto : list of int
        The trial numbers on the Pareto front (several objectives), else the best's.
    figures : dict
        Name -> matplotlib Figure (``convergence``; ``pareto`` for several objectives).
    summary : str
        The printed table: default against tuned, per scored state, with units.
    seconds : float
        Wall time of the tuning.

    Examples
    --------
    Returned by :func:`tune`:

    >>> sc = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.2, 0.0]},
    ...       "observers": [{"type": "high_gain", "name": "hgo", "k": 5.0}],
    ...       "run": {"duration": 1.0}}
    >>> r = tune(sc, "hgo", budget=4, seeds=1, progress=False)
    >>> isinstance(r, TuneResult), sorted(r.figures), list(r.trials.columns[:3])
    (True, ['convergence'], ['number', 'state', 'k'])
    """

    best: dict[str, float]
    best_parameters: dict[str, Any]
    default: dict[str, float]
    values: dict[str, list[float]]
    trials: Any
    pareto: list[int]
    figures: dict[str, Any] = field(default_factory=dict)
    summary: str = ""
    seconds: float = 0.0


def check_space(ob: Observer, space: Mapping[str, Any] | None) -> dict[str, Dimension]:
    """The observer's tuning space with the user's bounds: ``space`` maps a search variable
    of :meth:`Observer.tuning_space` to ``(low, high)`` or ``(low, high, "log"|"linear")``;
    a variable left out keeps its family's bounds; ``space`` given keeps only the variables
    it names. Each bound must be one the family accepts (checked with
    :meth:`Observer.parameters` at both ends), before any work.

    Parameters
    ----------
    ob : Observer
    space : mapping or None

    Returns
    -------
    dict of str to Dimension

    Raises
    ------
    DesignError
        An unknown variable (the valid ones listed), bounds that are empty or not numbers,
        a log scale over non-positive bounds, a bound the observer refuses (its message), or
        an observer with nothing to tune.

    Examples
    --------
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.systems import SYSTEMS
    >>> ob = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
    >>> check_space(ob, {"k": (2.0, 200.0)})["k"]
    Dimension(name='k', low=2.0, high=200.0, log=True, default=10.0)
    >>> check_space(ob, {"k": (-2.0, 200.0, "linear")})
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: space k: the observer refuses the bound -2: k must be > 0; found -2.0
    """
    base = ob.tuning_space()
    if not base:
        raise DesignError(f"observer {ob.name!r} declares no tunable parameter")
    if space is None:
        return base
    if not isinstance(space, Mapping) or not space:
        raise DesignError(f"space must be a non-empty table of search variable -> (low, high); "
                          f"found {space!r}")
    out: dict[str, Dimension] = {}
    for name, bounds in space.items():
        if name not in base:
            raise DesignError(f"space names {name!r}, not a search variable of {ob.name!r}; "
                              f"valid: {list(base)}")
        if isinstance(bounds, (str, bytes)) or not isinstance(bounds, Sequence) or len(
                bounds) not in (2, 3):
            raise DesignError(f"space {name}: expected (low, high) or (low, high, 'log' | "
                              f"'linear'); found {bounds!r}")
        low, high = bounds[0], bounds[1]
        scale = bounds[2] if len(bounds) == 3 else ("log" if base[name].log else "linear")
        for v in (low, high):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise DesignError(f"space {name}: bounds must be finite numbers; found "
                                  f"{bounds!r}")
        if scale not in ("log", "linear"):
            raise DesignError(f"space {name}: the scale must be 'log' or 'linear'; found "
                              f"{scale!r}")
        if not low < high:
            raise DesignError(f"space {name}: empty bounds, low must be < high; found "
                              f"{low!r} >= {high!r}")
        if scale == "log" and low <= 0:
            raise DesignError(f"space {name}: a log scale needs low > 0; found {low!r}")
        for v in (low, high):
            try:
                ob.parameters(1, **ob.tuned_parameters({name: float(v)}))
            except DesignError as exc:
                raise DesignError(f"space {name}: the observer refuses the bound {v:g}: "
                                  f"{exc}") from None
        out[name] = Dimension(name, float(low), float(high), scale == "log", base[name].default)
    return out


def _sampler(name: str, n_objectives: int, seed: int) -> Any:
    import optuna

    if name not in SAMPLERS:
        raise DesignError(f"sampler must be one of {list(SAMPLERS)}; found {name!r}")
    if n_objectives > 1 and name not in ("nsga2", "random"):
        name = "nsga2"
    if name == "tpe":
        return optuna.samplers.TPESampler(seed=seed, multivariate=True, n_startup_trials=10)
    if name == "cmaes":
        return optuna.samplers.CmaEsSampler(seed=seed, warn_independent_sampling=False)
    if name == "nsga2":
        return optuna.samplers.NSGAIISampler(seed=seed)
    return optuna.samplers.RandomSampler(seed=seed)


def _fingerprint(scenario: Mapping[str, Any], observer: str, space: Mapping[str, Dimension],
                 objective: Objective, seeds: Sequence[int], mismatch: Any,
                 aggregate: str, states: Any) -> str:
    doc = json.dumps({"scenario": scenario, "observer": observer,
                      "space": {k: [d.low, d.high, d.log] for k, d in space.items()},
                      "objective": objective.terms, "seeds": list(seeds),
                      "mismatch": mismatch, "aggregate": aggregate, "states": states},
                     sort_keys=True, default=str)
    return hashlib.sha256(doc.encode()).hexdigest()


def _seeds(seeds: Any) -> list[int]:
    if isinstance(seeds, bool):
        raise DesignError(f"seeds must be a count or a list of seeds; found {seeds!r}")
    if isinstance(seeds, int):
        if not 1 <= seeds <= 10_000:
            raise DesignError(f"seeds must be between 1 and 10000; found {seeds}")
        return list(range(1, seeds + 1))
    if isinstance(seeds, Sequence) and seeds and all(
            isinstance(s, int) and not isinstance(s, bool) and 0 <= s < 2 ** 32 for s in seeds):
        if len(set(seeds)) != len(seeds):
            raise DesignError(f"seeds must be distinct; found {list(seeds)}")
        return list(seeds)
    raise DesignError(f"seeds must be a count or a list of seeds (ints in [0, 2**32)); found "
                      f"{seeds!r}")


def _mismatches(mismatch: Any) -> list[dict[str, Any] | None]:
    if mismatch is None:
        return [None]
    if isinstance(mismatch, Mapping):
        mismatch = [mismatch]
    if not isinstance(mismatch, Sequence) or isinstance(mismatch, (str, bytes)) or not mismatch:
        raise DesignError(f"mismatch must be a table of the observer model's parameters or a "
                          f"list of them; found {mismatch!r}")
    out: list[dict[str, Any] | None] = []
    for m in mismatch:
        if m is None or (isinstance(m, Mapping) and not m):
            out.append(None)
        elif isinstance(m, Mapping):
            out.append(dict(m))
        else:
            raise DesignError(f"each model mismatch is a table of parameters; found {m!r}")
    return out


def _progress(msg: str, progress: bool) -> None:
    if progress:
        print(msg, file=sys.stderr, flush=True)


def tune(scenario: Mapping[str, Any], observer: str, *, space: Mapping[str, Any] | None = None,
         objective: Any = "rmse", budget: int = 64, seeds: Any = 8,
         mismatch: Any = None, aggregate: str = "mean", states: Sequence[str] | None = None,
         t_transient: float | None = None, sampler: str = "tpe", seed: int = 0,
         round_size: int = ROUND, out: str | Path | None = None, resume: bool = False,
         backend: str = "local", jobs: int = 1, address: str | None = None,
         progress: bool = True) -> TuneResult:
    """Tune the scenario's observer ``observer`` by an Optuna search (module docstring).

    Parameters
    ----------
    scenario : mapping
        A scenario (``hgo-mj run``'s format, open-loop ``[input]``).
    observer : str
        The label of the observer to tune.
    space : mapping, optional
        Bounds of the search variables (:func:`check_space`); default the family's space.
    objective : str, list or mapping
        The score(s) to minimize (:class:`~hgo_mj.tune.objectives.Objective`): ``"rmse"``,
        ``"peak"``, ``"settling"`` (ground truth), ``"output_error"``, ``"whiteness"``,
        ``"nis"`` (no truth);
        a list is a multi-objective search (a Pareto front), a mapping a weighted sum.
    budget : int
        Trials in all (the default's included), >= 2.
    seeds : int or list of int
        The tuning seeds of the sensor chain (a count: 1 .. N).
    mismatch : mapping or list of mappings, optional
        Parameters of the observer's model (its ``system_params``; for a MuJoCo filter, model
        fields ``"body_mass[link1]"`` written into its copy of the MJCF, its
        ``model_fields``), one table per model the objective is aggregated over (robust
        tuning); ``{}`` is the nominal model.
    aggregate : {"mean", "worst"}
        Over the seeds and the models.
    states : sequence of str, optional
        The scored states (default: every plant state the observer estimates).
    t_transient : float, optional
        Start of the steady-state window (default 0.2 times the duration).
    sampler : {"tpe", "cmaes", "nsga2", "random"}
        Optuna's sampler (several objectives: NSGA-II unless ``"random"``).
    seed : int
        The sampler's seed.
    round_size : int
        Trials per round (one batch).
    out : path, optional
        Folder of the study (``study.db``), ``trials.parquet``, ``best.toml`` and figures.
    resume : bool
        Go on with the study in ``out``.
    backend : {"local", "ray"}
    jobs : int
        Parts a round is split into on Ray (workers).
    address : str, optional
        A Ray cluster's address (default: a local instance on 127.0.0.1).
    progress : bool
        A line per round on stderr.

    Returns
    -------
    TuneResult

    Raises
    ------
    DesignError
        Any bad argument (named, with what was expected), before any work; a study in ``out``
        without ``resume``, or one of another tuning with it.

    Examples
    --------
    >>> sc = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.3, 0.0]},
    ...       "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
    ...       "observers": [{"type": "high_gain", "name": "hgo", "k": 5.0}],
    ...       "input": {"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]},
    ...       "run": {"duration": 2.0}}
    >>> r = tune(sc, "hgo", budget=8, seeds=2, round_size=4, progress=False)
    >>> r.values["best"][0] < r.values["default"][0], len(r.trials)
    (True, 8)
    """
    t_start = time.perf_counter()
    obj = Objective(objective)
    _check_arguments(budget, round_size, aggregate, backend, seed, sampler)
    seed_list = _seeds(seeds)
    models = _mismatches(mismatch)
    from ..scenario import scenario_run

    if not isinstance(scenario, Mapping):
        raise DesignError(f"scenario must be a table (a parsed scenario file); found "
                          f"{type(scenario).__name__}")
    if "controller" in scenario:
        raise DesignError("tuning replays one plant run to every trial: it needs an open-loop "
                          "[input], not a [controller]")
    built = scenario_run(dict(scenario))["observers"]
    if observer not in built:
        raise DesignError(f"observer {observer!r} is not in the scenario; it has "
                          f"{list(built)}")
    ob: Observer = built[observer]
    dims = check_space(ob, space)
    for name in ("output_error", "whiteness"):
        if name in obj.scores and ob.predicted_output(
                np.zeros((1, len(ob.state_names))), np.zeros((1, ob.n))) is None:
            raise DesignError(f"objective {name}: observer {ob.name!r} predicts no output")
    if "nis" in obj.scores and "nis" not in ob.diagnostic_names:
        raise DesignError(f"objective nis: observer {ob.name!r} reports no NIS (a Kalman "
                          f"filter does)")
    _check_out(out, resume)
    st = setup(scenario, observer, states=states, t_transient=t_transient, mismatches=models)
    study, folder = _study(obj, dims, sampler, seed, out, resume,
                           _fingerprint(st.scenario, observer, dims, obj, seed_list, models,
                                        aggregate, states))
    runner = _runner(backend, jobs, address)
    if not study.trials:
        study.enqueue_trial({k: d.default for k, d in dims.items()})
    _finish_pending(study, st, obj, dims, ob, seed_list, models, aggregate, runner)
    while len(_done(study)) < budget:
        n = min(round_size, budget - len(_done(study)))
        trials = [study.ask(_distributions(dims)) for _ in range(n)]
        values = _score(st, obj, ob, [t.params for t in trials], seed_list, models,
                        aggregate, runner)
        for t, v in zip(trials, values):
            study.tell(t, _told(v))
        done = _done(study)
        best = min((t.values[0] for t in done if t.values is not None), default=math.inf)
        _progress(f"tune {observer}: {len(done)}/{budget} trials, best {obj.names[0]} "
                  f"{best:.6g}", progress)
        if folder is not None:
            _write_trials(folder / "trials.parquet", study, dims, obj, seed_list)
    return _result(study, st, ob, obj, dims, seed_list, models, aggregate, folder, runner,
                   time.perf_counter() - t_start)


def _check_arguments(budget: Any, round_size: Any, aggregate: Any, backend: Any, seed: Any,
                     sampler: Any) -> None:
    """:func:`tune`'s plain arguments, each named with what was expected."""
    if isinstance(budget, bool) or not isinstance(budget, int) or budget < 2:
        raise DesignError(f"budget must be an integer >= 2 (the default and one trial); found "
                          f"{budget!r}")
    if isinstance(round_size, bool) or not isinstance(round_size, int) or round_size < 1:
        raise DesignError(f"round_size must be a positive integer; found {round_size!r}")
    if aggregate not in AGGREGATES:
        raise DesignError(f"aggregate must be one of {list(AGGREGATES)}; found {aggregate!r}")
    if backend not in ("local", "ray"):
        raise DesignError(f"backend must be 'local' or 'ray'; found {backend!r}")
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise DesignError(f"seed must be an integer; found {seed!r}")
    if sampler not in SAMPLERS:
        raise DesignError(f"sampler must be one of {list(SAMPLERS)}; found {sampler!r}")


def _distributions(dims: Mapping[str, Dimension]) -> dict[str, Any]:
    import optuna

    return {k: optuna.distributions.FloatDistribution(d.low, d.high, log=d.log)
            for k, d in dims.items()}


def _check_out(out: str | Path | None, resume: bool) -> None:
    """``out`` and ``resume`` agree with what is on disk (before any work)."""
    if out is None:
        if resume:
            raise DesignError("resume needs out (the folder of the study to go on with)")
        return
    folder = check_writable("out", out, folder=True)
    db = folder / "study.db"
    if db.exists() and not resume:
        raise DesignError(f"{db} exists: resume=True (--resume) goes on with it, or choose "
                          f"another out")
    if resume and not db.exists():
        raise DesignError(f"resume: no study in {folder} (expected {db.name})")


def _study(obj: Objective, dims: Mapping[str, Dimension], sampler: str, seed: int,
           out: str | Path | None, resume: bool, fingerprint: str) -> tuple[Any, Path | None]:
    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    directions: list[Any] = ["minimize"] * len(obj.terms)
    smp = _sampler(sampler, len(obj.terms), seed)
    if out is None:
        return optuna.create_study(sampler=smp, directions=directions), None
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    db = folder / "study.db"
    study = optuna.create_study(storage=f"sqlite:///{db}", study_name=STUDY_NAME,
                                sampler=smp, directions=directions, load_if_exists=True)
    found = study.user_attrs.get("fingerprint")
    if found is None:
        study.set_user_attr("fingerprint", fingerprint)
    elif found != fingerprint:
        raise DesignError(f"resume: the study in {db} tuned another scenario, observer, space, "
                          f"objective or seeds; start a new one in another out")
    return study, folder


def _done(study: Any) -> list[Any]:
    import optuna

    return [t for t in study.get_trials(deepcopy=False)
            if t.state in (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.FAIL)]


def _told(v: np.ndarray) -> list[float]:
    """Optuna takes finite values; a diverged trial's inf is told as a very large number,
    so that it ranks last and stays in the table (``state`` says diverged)."""
    return [float(x) if np.isfinite(x) else 1e300 for x in v]


def _finish_pending(study: Any, st: Setup, obj: Objective, dims: Mapping[str, Dimension],
                    ob: Observer, seeds: list[int], models: list[Any], aggregate: str,
                    runner: Any) -> None:
    """Score the trials asked and not told (a killed tuning) and the enqueued default."""
    import optuna

    pending = [t for t in study.get_trials(deepcopy=False)
               if t.state in (optuna.trial.TrialState.RUNNING, optuna.trial.TrialState.WAITING)]
    if not pending:
        return
    waiting = [t for t in pending if t.state == optuna.trial.TrialState.WAITING]
    asked = [study.ask(_distributions(dims)) for _ in waiting]
    running = [t for t in pending if t.state == optuna.trial.TrialState.RUNNING]
    params = [t.params for t in running] + [t.params for t in asked]
    values = _score(st, obj, ob, params, seeds, models, aggregate, runner)
    numbers = [t.number for t in running] + [t.number for t in asked]
    for number, v in zip(numbers, values):
        study.tell(number, _told(v))


def _score(st: Setup, obj: Objective, ob: Observer, params: list[dict[str, float]],
           seeds: list[int], models: list[Any], aggregate: str, runner: Any) -> np.ndarray:
    """The objective values ``(R, n_objectives)`` of the trials ``params``; a trial the
    observer refuses as a whole (a condition between its parameters, e.g. the adaptive gain's
    ``lam_hat > lam``, or an update unstable at the sample period) is not run and scores
    inf."""
    trials = [ob.tuned_parameters(p) for p in params]
    ok = []
    for t in trials:
        try:  # refused as a whole, or unstable at the sample period (a gain too high)
            ob.check_period(st.periods.sample, ob.parameters(1, **t))
            ok.append(True)
        except DesignError:
            ok.append(False)
    out = np.full((len(trials), len(obj.terms)), np.inf)
    valid = [t for t, good in zip(trials, ok) if good]
    if valid:
        rounds = [runner(st, valid, seeds, m) for m in models]
        out[np.flatnonzero(ok)] = objective_values(obj, st, rounds, aggregate)
    return out


def _runner(backend: str, jobs: int, address: str | None) -> Any:
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise DesignError(f"jobs must be a positive integer; found {jobs!r}")
    if backend == "local":
        return evaluate
    from ..study.backends import ray_init

    ray_init(jobs, address)
    import ray

    remote = ray.remote(evaluate)

    def on_ray(st: Setup, trials: list[Any], seeds: list[int], mismatch: Any) -> Scores:
        size = max(1, math.ceil(len(trials) / jobs))
        parts = [list(range(i, min(i + size, len(trials)))) for i in range(0, len(trials), size)]
        refs = [remote.remote(st, [trials[i] for i in p], seeds, mismatch) for p in parts]
        return Scores.concat(ray.get(refs))
    return on_ray


def _frame(study: Any, dims: Mapping[str, Dimension], obj: Objective, seeds: list[int]) -> Any:
    import pandas as pd

    rows = []
    for t in study.get_trials(deepcopy=False):
        row: dict[str, Any] = {"number": t.number, "state": t.state.name}
        row.update({k: t.params.get(k, math.nan) for k in dims})
        vals = t.values or [math.nan] * len(obj.terms)
        for name, v in zip(obj.names, vals):
            row[name] = math.inf if v >= 1e300 else v
        row["diverged"] = bool(t.values is not None and any(v >= 1e300 for v in t.values))
        row["seeds"] = json.dumps(seeds)
        rows.append(row)
    return pd.DataFrame(rows)


def _write_trials(path: Path, study: Any, dims: Mapping[str, Dimension], obj: Objective,
                  seeds: list[int]) -> None:
    import io

    buf = io.BytesIO()
    _frame(study, dims, obj, seeds).to_parquet(buf, index=False)
    write_bytes(path, buf.getvalue())


def _result(study: Any, st: Setup, ob: Observer, obj: Objective, dims: Mapping[str, Dimension],
            seeds: list[int], models: list[Any], aggregate: str, folder: Path | None,
            runner: Any, seconds: float) -> TuneResult:
    done = [t for t in _done(study) if t.values is not None]
    default = next(t for t in done if t.number == min(x.number for x in done))
    if len(obj.terms) == 1:
        best = min(done, key=lambda t: (t.values[0], t.number))
        pareto = [best.number]
    else:
        front = study.best_trials
        best = min(front, key=lambda t: (t.values[0], t.number))
        pareto = sorted(t.number for t in front)
    frame = _frame(study, dims, obj, seeds)
    best_params = ob.tuned_parameters(dict(best.params))
    summary = _summary(st, ob, default.params, best.params, seeds, models, runner, obj,
                       default.values, best.values)
    figures = _figures(study, obj, frame)
    res = TuneResult(dict(best.params), best_params, dict(default.params),
                     {"default": [_v(v) for v in default.values],
                      "best": [_v(v) for v in best.values]},
                     frame, pareto, figures, summary, seconds)
    if folder is not None:
        _write_trials(folder / "trials.parquet", study, dims, obj, seeds)
        write_text(folder / "best.toml", best_toml(st.scenario, st.observer, best_params))
        write_text(folder / "summary.txt", summary + "\n")
        from .._io import save_figure

        for name, fig in figures.items():
            save_figure(fig, folder / f"{name}.png")
    return res


def _v(v: float) -> float:
    return math.inf if v >= 1e300 else float(v)


def _summary(st: Setup, ob: Observer, default: Mapping[str, float], best: Mapping[str, float],
             seeds: list[int], models: list[Any], runner: Any, obj: Objective,
             dv: Sequence[float], bv: Sequence[float]) -> str:
    """Default against tuned: each scored state's RMSE (mean over the seeds, nominal model)
    with its unit, and the objective values."""
    from ..units import system_units

    units = system_units(st.plant.system)
    sc = runner(st, [ob.tuned_parameters(dict(default)), ob.tuned_parameters(dict(best))],
                seeds, None)
    with np.errstate(invalid="ignore"):
        rmse = np.mean(sc.rmse, axis=1)
    lines = [f"{'state':<24} {'unit':<10} {'default RMSE':>14} {'tuned RMSE':>14} {'ratio':>8}"]
    for j, s in enumerate(st.states):
        unit = units.get(s, "")
        d, b = rmse[0, j], rmse[1, j]
        ratio = b / d if d > 0 and np.isfinite(d) else math.nan
        lines.append(f"{s:<24} {unit:<10} {d:>14.6g} {b:>14.6g} {ratio:>8.3f}")
    for name, a, b in zip(obj.names, dv, bv):
        lines.append(f"objective {name}: default {_v(a):.6g}, tuned {_v(b):.6g}")
    lines.append("tuned: " + ", ".join(f"{k} = {v:.6g}" for k, v in best.items()))
    return "\n".join(lines)


def _figures(study: Any, obj: Objective, frame: Any) -> dict[str, Any]:
    """The convergence (each trial's value and the best so far, log scale) and, for several
    objectives, the Pareto front of the first two."""
    from ..plotting import new_figure

    figs: dict[str, Any] = {}
    fig = new_figure((7.0, 4.0), "constrained")
    ax = fig.add_subplot()
    name = obj.names[0]
    vals = frame[name].to_numpy(dtype=float)
    ok = np.isfinite(vals)
    ax.plot(frame["number"][ok], vals[ok], "o", ms=3, color="0.55", label="trial")
    best = np.minimum.accumulate(np.where(ok, vals, np.inf))
    ax.step(frame["number"], np.where(np.isfinite(best), best, np.nan), where="post",
            color="tab:red", label="best so far")
    if ok.any() and (vals[ok] > 0).all():
        ax.set_yscale("log")
    ax.set_xlabel("trial")
    ax.set_ylabel(f"{name} (lower is better)")
    ax.set_title("tuning convergence")
    ax.legend()
    figs["convergence"] = fig
    if len(obj.names) > 1:
        fig2 = new_figure((5.5, 4.5), "constrained")
        ax2 = fig2.add_subplot()
        a, b = obj.names[0], obj.names[1]
        x, y = frame[a].to_numpy(dtype=float), frame[b].to_numpy(dtype=float)
        fin = np.isfinite(x) & np.isfinite(y)
        ax2.plot(x[fin], y[fin], "o", ms=3, color="0.6", label="trial")
        front = np.array([t.number for t in study.best_trials])
        sel = frame["number"].isin(front).to_numpy() & fin
        order = np.argsort(x[sel])
        ax2.plot(x[sel][order], y[sel][order], "o-", color="tab:red", label="Pareto front")
        ax2.set_xlabel(a)
        ax2.set_ylabel(b)
        ax2.set_title("Pareto front")
        ax2.legend()
        figs["pareto"] = fig2
    return figs


def best_toml(scenario: Mapping[str, Any], observer: str, parameters: Mapping[str, Any]) -> str:
    """The scenario as TOML with the tuned observer's parameters written into its spec,
    runnable by ``hgo-mj run``.

    Parameters
    ----------
    scenario : mapping
    observer : str
        The tuned observer's label.
    parameters : mapping
        Parameter name -> value (floats, arrays).

    Returns
    -------
    str

    Examples
    --------
    >>> sc = {"plant": {"name": "pendulum"}, "observers": [{"type": "high_gain", "name": "hgo",
    ...       "k": 5.0}], "run": {"duration": 1.0}}
    >>> "k = 42.0" in best_toml(sc, "hgo", {"k": 42.0})
    True
    """
    import copy

    sc = copy.deepcopy(dict(scenario))
    for spec in sc.get("observers", []):
        if spec.get("name", spec.get("type")) == observer:
            for k, v in parameters.items():
                spec[k] = np.asarray(v).tolist()
    return _toml(sc)


def _toml(doc: Mapping[str, Any]) -> str:
    """A scenario dict as TOML (tables, arrays of tables, numbers, strings, lists)."""
    def value(v: Any) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, float)):
            return repr(float(v)) if isinstance(v, float) else str(v)
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, Mapping):
            return "{" + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + "}"
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(value(x) for x in v) + "]"
        raise DesignError(f"cannot write {v!r} to TOML")

    lines = [f"{k} = {value(v)}" for k, v in doc.items() if not isinstance(v, (Mapping, list))
             or (isinstance(v, list) and not all(isinstance(x, Mapping) for x in v))]
    for k, v in doc.items():
        if isinstance(v, Mapping):
            lines += ["", f"[{k}]"] + [f"{a} = {value(b)}" for a, b in v.items()]
        elif isinstance(v, list) and v and all(isinstance(x, Mapping) for x in v):
            for item in v:
                lines += ["", f"[[{k}]]"] + [f"{a} = {value(b)}" for a, b in item.items()]
    return "\n".join(lines) + "\n"
