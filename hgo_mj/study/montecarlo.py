"""Monte Carlo over sensor-noise seeds: the same scenario run once per seed, and the spread.

A single noisy run says little about an observer. :func:`monte_carlo` runs one scenario (plant,
sensor chain, observers, input, duration, x0) once per seed, each run from fresh objects built
by ``make_run()``, computes :func:`hgo_mj.metrics.all_metrics` per run, and aggregates them per
observer and plant state (:func:`aggregate`):

* ``rmse``, ``peak``, ``final``: ``mean``, ``std`` (the sample standard deviation, ``ddof=1``;
  0 for one run), ``min``, ``median``, ``max`` over the runs;
* ``settling_time``: ``settled_fraction``, the fraction of the runs whose error settled
  (finite settling time), and ``median``, ``min``, ``max`` over the runs that settled (``inf``
  when none did);
* ``update_time``: the mean over the runs of the mean wall time per update (a timing: the only
  value that changes from one repetition of the study to the next).

A plant state the observer does not estimate has ``None`` for every statistic (as its metrics
are ``None``); a NaN metric (no finite sample to use) makes the statistics of its state NaN.
A run that diverges (:class:`~hgo_mj.exceptions.DivergenceError`: the plant or an observer
blew up) does not stop the study: it is listed in ``failed`` with its message, and the
statistics are over the runs that finished (how often an observer diverges under noise is
itself a result); only when every run diverges is the error raised.
Run ``i`` is bit-identical to ``simulate(**make_run(), seed=seeds[i])`` alone, and nothing but
``update_time`` depends on ``jobs``.

>>> from functools import partial
>>> result = monte_carlo(partial(my_scenario, k=50.0), range(20), jobs=4)  # doctest: +SKIP
>>> print(result.table())                                                  # doctest: +SKIP
"""

from __future__ import annotations

import math
import multiprocessing
import pickle
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._json import strict_json
from .._validate import positive_int
from ..exceptions import DesignError, DivergenceError

#: the metrics aggregated with mean, std, min, median, max
SPREAD_METRICS = ("rmse", "peak", "final")
#: the statistics of each of them
STATS = ("mean", "std", "min", "median", "max")


def check_seeds(seeds: Iterable[Any]) -> list[int]:
    """The seeds as a non-empty list of non-negative integers, or a :class:`DesignError`.

    Parameters
    ----------
    seeds : iterable
        The seeds to check (e.g. a list or a ``range``).

    Returns
    -------
    list of int
        The seeds as Python ints, in their order.

    Raises
    ------
    DesignError
        ``seeds`` is not iterable, is empty, or holds something other than a non-negative
        integer (a bool included).

    Examples
    --------
    >>> check_seeds(range(3))
    [0, 1, 2]
    >>> check_seeds([1, -2])
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: seeds must be non-negative integers; found -2
    """
    try:
        out = list(seeds)
    except TypeError:
        raise DesignError(f"seeds must be a sequence of integers; found {seeds!r}") from None
    if not out:
        raise DesignError("seeds must name at least one seed; found none")
    for s in out:
        if isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 0:
            raise DesignError(f"seeds must be non-negative integers; found {s!r}")
    return [int(s) for s in out]


def run_seed(make_run: Callable[[], Mapping[str, Any]], seed: int,
             metric_kw: Mapping[str, Any] | None = None) -> dict[str, dict[str, Any]]:
    """One run of the study: ``simulate(**make_run(), seed=seed)`` and its metrics.

    Parameters
    ----------
    make_run : callable ``() -> mapping``
        Builds the run: the keyword arguments of :func:`hgo_mj.simulate.simulate` except
        ``seed`` (as in :func:`monte_carlo`).
    seed : int
        The sensor chain's seed.
    metric_kw : mapping, optional
        Keyword arguments of :func:`hgo_mj.metrics.all_metrics` (``t_transient``, ``band``,
        ``relative``); default its defaults.

    Returns
    -------
    dict
        :func:`hgo_mj.metrics.all_metrics` of the run: per observer name, its ``states``,
        ``estimated``, ``rmse``, ``peak``, ``settling_time``, ``final``, ... .

    Raises
    ------
    DesignError
        ``make_run()`` sets ``seed``.
    DivergenceError
        The run diverged; the message starts with ``seed S:`` and ``exc.trajectory`` holds
        the rows up to the divergence.

    Examples
    --------
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.sensors import GaussianNoise, SensorChain
    >>> def make_run():
    ...     plant = make_plant("pendulum", dt=0.01)
    ...     return {"plant": plant, "sensor": SensorChain([GaussianNoise(std=1e-3)]),
    ...             "observers": {"hgo": HighGainObserver(plant.system, k=20.0)},
    ...             "inputs": lambda t: [0.0], "duration": 0.2, "x0": [0.5, 0.0]}
    >>> m = run_seed(make_run, seed=3)
    >>> m["hgo"]["states"], len(m["hgo"]["rmse"])
    (['angle', 'angular_velocity'], 2)
    """
    from ..metrics import all_metrics
    from ..simulate import simulate

    kw = dict(make_run())
    if "seed" in kw:
        raise DesignError("make_run() must not set seed: monte_carlo passes each seed; found "
                          f"seed = {kw['seed']!r}")
    try:
        traj = simulate(**kw, seed=seed)
    except DivergenceError as exc:
        err = DivergenceError(f"seed {seed}: {exc}")
        err.trajectory = getattr(exc, "trajectory", None)  # type: ignore[attr-defined]
        raise err from exc
    return all_metrics(traj, **dict(metric_kw or {}))


def _run_seed_job(job: tuple[Callable[[], Mapping[str, Any]], int, dict[str, Any]]
                  ) -> dict[str, dict[str, Any]] | str:
    """One run's metrics, or the message of its divergence."""
    try:
        return run_seed(*job)
    except DivergenceError as exc:
        return str(exc)


@dataclass
class MonteCarloResult:
    """Per-run metrics and their aggregate (see the module docstring).

    Made by :func:`monte_carlo` (or :meth:`from_runs`).

    Parameters
    ----------
    seeds : list of int
        The seeds of the runs that finished, in the order of ``runs``.
    runs : list of dict
        :func:`hgo_mj.metrics.all_metrics` of each run.
    aggregate : dict
        Per observer: ``states``, ``estimated``, ``runs`` and the statistics of each metric
        (:func:`aggregate`).
    failed : dict of int to str
        Seed -> message, for the runs that diverged (not in ``seeds``/``runs``).

    Examples
    --------
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.sensors import GaussianNoise, SensorChain
    >>> def make_run():
    ...     plant = make_plant("pendulum", dt=0.01)
    ...     return {"plant": plant, "sensor": SensorChain([GaussianNoise(std=1e-3)]),
    ...             "observers": {"hgo": HighGainObserver(plant.system, k=20.0)},
    ...             "inputs": lambda t: [0.0], "duration": 0.2, "x0": [0.5, 0.0]}
    >>> result = monte_carlo(make_run, seeds=[1, 2])
    >>> result.seeds, len(result.runs), result.aggregate["hgo"]["runs"], result.failed
    ([1, 2], 2, 2, {})
    """

    #: the seeds, in the order of ``runs``
    seeds: list[int]
    #: ``all_metrics`` of each run
    runs: list[dict[str, dict[str, Any]]]
    #: per observer: ``states``, ``estimated``, ``runs`` and the statistics of each metric
    aggregate: dict[str, dict[str, Any]]
    #: seed -> message, for the runs that diverged (not in ``seeds``/``runs``)
    failed: dict[int, str]

    @classmethod
    def from_runs(cls, seeds: Sequence[int], runs: Sequence[dict[str, dict[str, Any]]],
                  failed: Mapping[int, str]) -> MonteCarloResult:
        """The result of the runs at ``seeds`` (and the ``failed`` ones), aggregated.

        Parameters
        ----------
        seeds : sequence of int
            The seeds of the runs that finished.
        runs : sequence of dict
            Their :func:`hgo_mj.metrics.all_metrics`, in the order of ``seeds``.
        failed : mapping of int to str
            Seed -> message of the runs that diverged.

        Returns
        -------
        MonteCarloResult
            With ``aggregate = aggregate(runs)``.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> from hgo_mj.sensors import GaussianNoise, SensorChain
        >>> def make_run():
        ...     plant = make_plant("pendulum", dt=0.01)
        ...     return {"plant": plant, "sensor": SensorChain([GaussianNoise(std=1e-3)]),
        ...             "observers": {"hgo": HighGainObserver(plant.system, k=20.0)},
        ...             "inputs": lambda t: [0.0], "duration": 0.2, "x0": [0.5, 0.0]}
        >>> done, runs, failed = run_seeds(make_run, [1, 2])
        >>> result = MonteCarloResult.from_runs(done, runs, {7: "seed 7: diverged"})
        >>> result.seeds, sorted(result.aggregate), result.failed
        ([1, 2], ['hgo'], {7: 'seed 7: diverged'})
        """
        return cls(seeds=list(seeds), runs=list(runs), aggregate=aggregate(runs),
                   failed=dict(failed))

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict: ``seeds``, ``runs`` (``[{"seed", "metrics"}]``), ``aggregate``,
        ``failed`` (``[{"seed", "error"}]``); strict JSON: ``inf`` and ``nan`` become ``None``
        (a settling time: never; a statistic: undefined).

        Returns
        -------
        dict
            The keys ``seeds``, ``runs``, ``aggregate`` and ``failed``.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> from hgo_mj.sensors import GaussianNoise, SensorChain
        >>> def make_run():
        ...     plant = make_plant("pendulum", dt=0.01)
        ...     return {"plant": plant, "sensor": SensorChain([GaussianNoise(std=1e-3)]),
        ...             "observers": {"hgo": HighGainObserver(plant.system, k=20.0)},
        ...             "inputs": lambda t: [0.0], "duration": 0.2, "x0": [0.5, 0.0]}
        >>> js = monte_carlo(make_run, seeds=[1]).to_json()
        >>> sorted(js), js["runs"][0]["seed"], js["runs"][0]["metrics"]["hgo"]["settling_time"]
        (['aggregate', 'failed', 'runs', 'seeds'], 1, [None, None])
        """
        return strict_json({
            "seeds": list(self.seeds),
            "runs": [{"seed": s, "metrics": m} for s, m in zip(self.seeds, self.runs)],
            "aggregate": self.aggregate,
            "failed": [{"seed": s, "error": e} for s, e in self.failed.items()]})

    def table(self, units: Mapping[str, str] | None = None, time_unit: str | None = "s") -> str:
        """The aggregate as a plain-text table (:func:`format_mc_table`), and the runs that
        diverged.

        Parameters
        ----------
        units : mapping of str to str, optional
            ``{state: unit}`` (:func:`hgo_mj.units.units_of`).
        time_unit : str or None, default "s"
            The runs' time unit.

        Returns
        -------
        str
            The table, followed by the seeds where an observer diverged, each with its
            message, where there are any.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> from hgo_mj.sensors import GaussianNoise, SensorChain
        >>> def make_run():
        ...     plant = make_plant("pendulum", dt=0.01)
        ...     return {"plant": plant, "sensor": SensorChain([GaussianNoise(std=1e-3)]),
        ...             "observers": {"hgo": HighGainObserver(plant.system, k=20.0)},
        ...             "inputs": lambda t: [0.0], "duration": 0.2, "x0": [0.5, 0.0]}
        >>> done, runs, _ = run_seeds(make_run, [1, 2])
        >>> print(MonteCarloResult.from_runs(done, runs, {7: "seed 7: diverged"}).table())
        2 run(s) per observer
        observer state            unit  rmse mean  rmse std  rmse med ...
        hgo      angle            ? ...
        hgo      angular_velocity ? ...
        1 of 3 run(s) had an observer diverge, left out of that observer's statistics: seeds [7]
          seed 7: diverged
        """
        text = format_mc_table(self.aggregate, units, time_unit)
        if self.failed:
            total = len(set(self.seeds) | set(self.failed))
            text += (f"\n{len(self.failed)} of {total} run(s) had an observer diverge, left out "
                     f"of that observer's statistics: seeds {sorted(self.failed)}")
            text += "".join(f"\n  {msg}" for _, msg in sorted(self.failed.items()))
        return text


def _stats(vals: Sequence[float]) -> dict[str, float]:
    a = np.asarray(vals, dtype=float)
    with np.errstate(invalid="ignore", over="ignore"):
        mean = float(np.mean(a))
        # one run has no spread; an undefined mean (a NaN among the runs) has none either
        return {"mean": mean,
                "std": float(np.std(a, ddof=1)) if a.size > 1 else 0.0 * mean,
                "min": float(np.min(a)), "median": float(np.median(a)),
                "max": float(np.max(a))}


def _settling(vals: Sequence[float]) -> dict[str, float]:
    a = np.asarray(vals, dtype=float)
    ok = a[np.isfinite(a)]
    if not ok.size:
        return {"settled_fraction": 0.0, "median": math.inf, "min": math.inf, "max": math.inf}
    return {"settled_fraction": float(ok.size / a.size), "median": float(np.median(ok)),
            "min": float(np.min(ok)), "max": float(np.max(ok))}


def aggregate(runs: Sequence[Mapping[str, Mapping[str, Any]]]) -> dict[str, dict[str, Any]]:
    """Statistics over runs of :func:`hgo_mj.metrics.all_metrics`, per observer and state.

    Returns, per observer, ``states``, ``estimated``, ``runs`` (the number of runs it finished:
    a run holds only the observers that did not diverge in it), ``rmse``,
    ``peak``, ``final`` (each ``{"mean": [...], "std": [...], "min": ..., "median": ...,
    "max": ...}``, lists over the plant's states, ``None`` where not estimated),
    ``settling_time`` (``{"settled_fraction", "median", "min", "max"}``, the last three over
    the runs that settled) and ``update_time`` (mean, seconds).

    Parameters
    ----------
    runs : sequence of dict
        :func:`hgo_mj.metrics.all_metrics` of each run (of the observers that finished it);
        each observer has the same states and estimated flags in every run.

    Returns
    -------
    dict
        Per observer name, the statistics above.

    Raises
    ------
    DesignError
        No runs, or an observer whose states differ between runs.

    Examples
    --------
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.sensors import GaussianNoise, SensorChain
    >>> def make_run():
    ...     plant = make_plant("pendulum", dt=0.01)
    ...     return {"plant": plant, "sensor": SensorChain([GaussianNoise(std=1e-3)]),
    ...             "observers": {"hgo": HighGainObserver(plant.system, k=20.0)},
    ...             "inputs": lambda t: [0.0], "duration": 0.2, "x0": [0.5, 0.0]}
    >>> _, runs, _ = run_seeds(make_run, [1, 2])
    >>> agg = aggregate(runs)["hgo"]
    >>> agg["runs"], sorted(agg["rmse"]), agg["settling_time"]["settled_fraction"]
    (2, ['max', 'mean', 'median', 'min', 'std'], [0.0, 0.0])
    """
    if not runs or not any(runs):
        raise DesignError("aggregate needs at least one run; found none")
    # the observers in the order of a run that has them all (the first of the fullest runs)
    names = list(dict.fromkeys(name for r in sorted(runs, key=len, reverse=True) for name in r))
    out: dict[str, dict[str, Any]] = {}
    for name in names:  # each observer over the runs it finished (it may diverge in others)
        mine = [r for r in runs if name in r]
        m0 = mine[0][name]
        states, est = list(m0["states"]), list(m0["estimated"])
        for i, r in enumerate(mine):
            if list(r[name]["states"]) != states or list(r[name]["estimated"]) != est:
                raise DesignError(f"run #{i + 1}: observer {name!r} has states "
                                  f"{r[name]['states']}; expected {states}")
        agg: dict[str, Any] = {"states": states, "estimated": est, "runs": len(mine)}
        for key in SPREAD_METRICS:
            cols: dict[str, list[float | None]] = {s: [] for s in STATS}
            for j, ok in enumerate(est):
                st = _stats([r[name][key][j] for r in mine]) if ok else dict.fromkeys(STATS)
                for s in STATS:
                    cols[s].append(st[s])
            agg[key] = cols
        settle: dict[str, list[float | None]] = {
            s: [] for s in ("settled_fraction", "median", "min", "max")}
        for j, ok in enumerate(est):
            st = (_settling([r[name]["settling_time"][j] for r in mine]) if ok
                  else dict.fromkeys(settle))
            for s in settle:
                settle[s].append(st[s])
        agg["settling_time"] = settle
        agg["update_time"] = float(np.mean([r[name]["update_time"] for r in mine]))
        out[name] = agg
    return out


def monte_carlo(make_run: Callable[[], Mapping[str, Any]], seeds: Iterable[int], *,
                jobs: int = 1, t_transient: float | None = None, band: float = 0.05,
                relative: bool = True) -> MonteCarloResult:
    """Run one scenario once per seed and aggregate the metrics.

    Parameters
    ----------
    make_run : callable ``() -> mapping``
        Builds one run: the keyword arguments of :func:`hgo_mj.simulate.simulate` except
        ``seed`` (``plant``, ``sensor``, ``observers``, ``inputs``, ``duration`` and optionally
        ``sample_period``, ``control_period``, ``x0``, ``metadata``). It is called once per
        seed, so that every run starts from fresh objects (``simulate`` resets the plant, the
        sensor chain, re-seeded, and the observers, but not a stateful input or controller).
        With ``jobs > 1`` it must be picklable: a module-level function, or a
        :func:`functools.partial` of one.
    seeds : iterable of int
        The sensor chain's seeds, one run each (non-negative integers).
    jobs : int, default 1
        Worker processes (``spawn``: safe with MuJoCo and threads). The results do not depend
        on it, apart from the wall times ``update_time``.
    t_transient, band, relative
        As in :func:`hgo_mj.metrics.observer_metrics`.

    Returns
    -------
    MonteCarloResult
        ``runs[i]`` equals ``all_metrics(simulate(**make_run(), seed=seeds[i]))``.

        Runs that diverge are in ``failed`` (seed -> message), not in ``runs``.

    Raises
    ------
    DivergenceError
        If every run diverges; the message names the first (``seed S: ...``).

    Examples
    --------
    >>> from hgo_mj.inputs import Multisine
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.sensors import GaussianNoise, SensorChain
    >>> def make_run():
    ...     plant = make_plant("pendulum", dt=0.001)
    ...     return {"plant": plant, "sensor": SensorChain([GaussianNoise(std=1e-3)]),
    ...             "observers": {"k40": HighGainObserver(plant.system, k=40.0)},
    ...             "inputs": Multisine(amplitudes=[0.3], frequencies=[0.5]),
    ...             "duration": 1.0, "x0": [0.5, 0.0]}
    >>> result = monte_carlo(make_run, seeds=range(4), t_transient=0.5)
    >>> result.seeds, len(result.runs), result.aggregate["k40"]["runs"]
    ([0, 1, 2, 3], 4, 4)
    """
    seeds = check_seeds(seeds)
    done, runs, failed = run_seeds(make_run, seeds, jobs=jobs, t_transient=t_transient,
                                   band=band, relative=relative)
    if not done:
        raise DivergenceError(f"every run diverged ({len(seeds)} of {len(seeds)}); "
                              f"{failed[seeds[0]]}")
    return MonteCarloResult.from_runs(done, runs, failed)


def run_seeds(make_run: Callable[[], Mapping[str, Any]], seeds: Iterable[int], *,
              jobs: int = 1, t_transient: float | None = None, band: float = 0.05,
              relative: bool = True
              ) -> tuple[list[int], list[dict[str, dict[str, Any]]], dict[int, str]]:
    """The runs of :func:`monte_carlo` without the aggregate: ``(seeds that finished, their
    metrics, {seed: message} of those that diverged)``, in the order of ``seeds``.

    Parameters
    ----------
    make_run : callable ``() -> mapping``
        As in :func:`monte_carlo` (picklable for ``jobs > 1``).
    seeds : iterable of int
        The sensor chain's seeds (non-negative integers).
    jobs : int
        Worker processes (default 1: this process).
    t_transient, band, relative
        As in :func:`hgo_mj.metrics.observer_metrics`.

    Returns
    -------
    tuple
        ``(seeds that finished, their all_metrics, {seed: message} of those that
        diverged)``.

    Raises
    ------
    DesignError
        Bad ``seeds`` or ``jobs``, ``make_run`` not callable, or not picklable for
        ``jobs > 1``.

    Examples
    --------
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.sensors import GaussianNoise, SensorChain
    >>> def make_run():
    ...     plant = make_plant("pendulum", dt=0.01)
    ...     return {"plant": plant, "sensor": SensorChain([GaussianNoise(std=1e-3)]),
    ...             "observers": {"hgo": HighGainObserver(plant.system, k=20.0)},
    ...             "inputs": lambda t: [0.0], "duration": 0.2, "x0": [0.5, 0.0]}
    >>> done, runs, failed = run_seeds(make_run, [1, 2])
    >>> done, len(runs), failed
    ([1, 2], 2, {})
    """
    seeds = check_seeds(seeds)
    jobs = positive_int("jobs", jobs, floats=False)
    if not callable(make_run):
        raise DesignError(f"make_run must be a callable returning simulate's arguments; found "
                          f"{type(make_run).__name__}")
    metric_kw = {"t_transient": t_transient, "band": band, "relative": relative}
    jobs = min(jobs, len(seeds))
    if jobs == 1:
        results = [_run_seed_job((make_run, s, metric_kw)) for s in seeds]
    else:
        try:
            pickle.dumps(make_run)
        except Exception as exc:
            raise DesignError(f"make_run must be picklable for jobs > 1 (a module-level function "
                              f"or a functools.partial of one); found {make_run!r}: {exc}"
                              ) from None
        ctx = multiprocessing.get_context("spawn")
        with ctx.Pool(jobs) as pool:
            results = pool.map(_run_seed_job, [(make_run, s, metric_kw) for s in seeds],
                               chunksize=1)
    failed = {s: r for s, r in zip(seeds, results) if isinstance(r, str)}
    done = [(s, r) for s, r in zip(seeds, results) if not isinstance(r, str)]
    return [s for s, _ in done], [r for _, r in done], failed


def format_mc_table(agg: Mapping[str, Mapping[str, Any]], units: Mapping[str, str] | None = None,
                    time_unit: str | None = "s") -> str:
    """A plain-text table, one row per observer and state: RMSE mean, std, median and max,
    the median peak error (in the state's unit), the fraction of runs that settled and their
    median settling time (``-``: not estimated); columns sized to their longest cell
    (:func:`hgo_mj.metrics.text_table`).

    Parameters
    ----------
    agg : mapping
        Per observer, :func:`aggregate`'s statistics.
    units : mapping of str to str, optional
        ``{state: unit}`` (:func:`hgo_mj.units.units_of`); ``?`` where not known.
    time_unit : str or None, default "s"
        The runs' time unit (``""``: dimensionless, ``None``: not known).

    Returns
    -------
    str
        A header line with the number of runs, the column names, one line per observer and
        state, and a note where a state is not estimated.

    Examples
    --------
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.sensors import GaussianNoise, SensorChain
    >>> def make_run():
    ...     plant = make_plant("pendulum", dt=0.01)
    ...     return {"plant": plant, "sensor": SensorChain([GaussianNoise(std=1e-3)]),
    ...             "observers": {"hgo": HighGainObserver(plant.system, k=20.0)},
    ...             "inputs": lambda t: [0.0], "duration": 0.2, "x0": [0.5, 0.0]}
    >>> _, runs, _ = run_seeds(make_run, [1, 2])
    >>> print(format_mc_table(aggregate(runs), {"angle": "rad"}))
    2 run(s) per observer
    observer state            unit  rmse mean  rmse std  rmse med  rmse max  peak med  settled  settle med [s]
    hgo      angle            rad ...
    hgo      angular_velocity ?   ...
    """
    from ..metrics import text_table
    from ..units import bracket

    units = units or {}
    counts = {name: a["runs"] for name, a in agg.items()}
    settle = f"settle med {bracket(time_unit)}"
    rows, missing = [], False
    for name, a in agg.items():
        for i, s in enumerate(a["states"]):
            r, st = a["rmse"], a["settling_time"]
            missing |= r["mean"][i] is None

            rows.append({"observer": name, "state": s, "unit": units.get(s, "?") or "-",
                         "rmse mean": r["mean"][i], "rmse std": r["std"][i],
                         "rmse med": r["median"][i], "rmse max": r["max"][i],
                         "peak med": a["peak"]["median"][i],
                         "settled": ("-" if st["settled_fraction"][i] is None
                                     else f"{st['settled_fraction'][i]:.0%}"),
                         settle: st["median"][i]})
    columns = ["observer", "state", "unit", "rmse mean", "rmse std", "rmse med", "rmse max",
               "peak med", "settled", settle]
    head = (f"{next(iter(counts.values()), 0)} run(s) per observer"
            if len(set(counts.values())) <= 1 else
            "runs per observer: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    lines = [head, text_table(rows, columns, ["observer", "state", "unit"])]
    if missing:
        lines.append("- : not estimated (the observer has no estimate of that plant state)")
    return "\n".join(lines)


__all__ = ["MonteCarloResult", "aggregate", "check_seeds", "format_mc_table", "monte_carlo",
           "run_seed", "run_seeds"]
