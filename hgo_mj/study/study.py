"""The study as a user holds it: :class:`Study` (built from a file or in Python), its plan,
its run on a backend, and the :class:`StudyResult`.

>>> study = Study.from_toml("studies/gain_noise.toml")        # doctest: +SKIP
>>> result = study.run("runs/gain_noise", jobs=2)              # doctest: +SKIP
>>> result.table.groupby(["observers.hgo.k", "state"]).rmse.median()  # doctest: +SKIP
"""

from __future__ import annotations

import copy
import json
import sys
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .._validate import vector
from ..exceptions import DesignError, HgoError
from ..progress import Progress, seconds
from ..scenario import scenario_run
from .engine import Chunk, plan
from .results import ResultsDir, schema, write_summary
from .spec import MAX_RUNS, Cell, parse_study

#: rough costs for the plan's time estimate (seconds per plant step, on MuJoCo's rollout with
#: 2 threads, and per observer-step of a high-gain observer with its sensor and metrics, on one
#: core; scripts/bench_study.py on a 2-core machine)
_PLANT_STEP_S = 5e-6
_OBSERVER_STEP_S = 6.5e-8
#: cells from which a study says its size and memory before checking and planning them
LARGE_CELLS = 10_000
#: members and samples of the short batched run that measures a family's warm cost per update
_COST_BATCH, _COST_SAMPLES = 32, 64


def update_cost(kw: Mapping[str, Any], name: str) -> float:
    """The warm cost of observer ``name`` of a built scenario ``kw``, seconds per update of one
    member: measured on a short batched loop (:data:`_COST_BATCH` members, the second of two
    segments of :data:`_COST_SAMPLES` samples; the first compiles and fills the caches). A
    family whose update fails there (a short run it cannot take) costs as a high-gain one."""
    import numpy as np

    from ..loop import Loop, LoopFailure, Periods

    plant = kw["plant"]
    loop = Loop(plant, None, {name: kw["observers"][name]},
                Periods.of(plant, kw.get("sample_period"), None))
    m = len(plant.input_names)
    try:
        loop.reset(kw.get("x0"), batch=_COST_BATCH)
        loop.segment(np.zeros((_COST_BATCH, _COST_SAMPLES, m)))
        loop.wall[name] = 0.0
        loop.segment(np.zeros((_COST_BATCH, _COST_SAMPLES, m)))
    except (LoopFailure, HgoError, ArithmeticError, ValueError):
        return _OBSERVER_STEP_S
    return max(loop.wall[name] / (_COST_BATCH * _COST_SAMPLES), _OBSERVER_STEP_S)
#: a closed loop's plant step (one control period a segment: MuJoCo's rollout called per step)
#: and the cost of one segment of the loop (plant, sensor, observers, controller calls)
_CLOSED_STEP_S = 4e-6
_SEGMENT_S = 1.5e-4


def load_toml(path: str | Path) -> dict[str, Any]:
    """A TOML file as a dict, or a DesignError naming the file and the problem.

    Parameters
    ----------
    path : str or Path
        The file to read (a scenario or study file).

    Returns
    -------
    dict
        The document's tables and values.

    Raises
    ------
    DesignError
        The file does not exist, is not valid TOML, or is nested too deeply to read.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> text = '''
    ... [plant]
    ... name = "pendulum"
    ... x0 = [0.5, 0.0]
    ...
    ... [[observers]]
    ... type = "high_gain"
    ... name = "hgo"
    ... k = 20.0
    ...
    ... [run]
    ... duration = 0.2
    ...
    ... [sweep]
    ... seeds = 2
    ... "observers.hgo.k" = [20.0, 40.0]
    ... '''
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = Path(tmp, "gains.toml")
    ...     _ = path.write_text(text)
    ...     doc = load_toml(path)
    >>> doc["sweep"], doc["plant"]["name"]
    ({'seeds': 2, 'observers.hgo.k': [20.0, 40.0]}, 'pendulum')
    >>> load_toml("no_such_study.toml")
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: study file 'no_such_study.toml' does not exist
    """
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib  # type: ignore[no-redef]
    p = Path(path)
    if not p.is_file():
        raise DesignError(f"study file {str(p)!r} does not exist")
    try:
        with open(p, "rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise DesignError(f"study file {str(p)!r} is not valid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise DesignError(f"study file {str(p)!r} is not UTF-8 text (a binary file?): "
                          f"{exc}") from None
    except RecursionError:
        raise DesignError(f"study file {str(p)!r} is nested too deeply (arrays or tables "
                          f"inside each other beyond Python's recursion limit)") from None


@dataclass
class Plan:
    """What a study will do: its chunks, and the figures printed before it runs.

    Made by :meth:`Study.plan`.

    Parameters
    ----------
    chunks : list of Chunk
        The pieces of work handed to the backend (:mod:`hgo_mj.study.engine`).
    cells : int
        Cells of the study.
    runs : int
        Runs of the study (cells x seeds).
    todo : int
        Runs left to do (fewer than ``runs`` when resuming).
    trajectories : int
        Distinct plant trajectories the runs left need (simulated once each).
    estimate_s : float
        Rough estimate of the wall time, seconds.
    serial_s : float
        The part of the estimate that runs on one core per process (sensors, observers,
        metrics), seconds.
    out : Path or None
        The study's folder, if known.

    Examples
    --------
    >>> from hgo_mj.study import Study
    >>> scenario = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.5, 0.0]},
    ...             "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...             "run": {"duration": 0.2}}
    >>> study = Study(scenario, {"observers.hgo.k": [20.0, 40.0]})
    >>> plan = study.plan()
    >>> plan.cells, plan.runs, plan.todo, plan.trajectories, len(plan.chunks)
    (2, 2, 2, 1, 1)
    """

    chunks: list[Chunk]
    cells: int
    runs: int
    todo: int
    trajectories: int
    estimate_s: float
    #: the part of the estimate that runs on one core per process (sensors, observers,
    #: metrics; the batched plant already runs on threads)
    serial_s: float
    out: Path | None

    def describe(self) -> str:
        """The plan line a study prints before it runs.

        Returns
        -------
        str
            Cells, runs (and those done already), distinct plant trajectories, chunks, the
            time estimate and the folder.

        Examples
        --------
        >>> from hgo_mj.study import Study
        >>> scenario = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.5, 0.0]},
        ...             "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
        ...             "run": {"duration": 0.2}}
        >>> study = Study(scenario, {"observers.hgo.k": [20.0, 40.0]})
        >>> study.plan(done={(0, 0)}).describe()
        'study: 2 cells, 2 runs (1 done already), 1 distinct plant trajectory, 1 chunk, about ...'
        """
        where = f" -> {self.out}" if self.out is not None else ""
        done = f" ({self.runs - self.todo} done already)" if self.todo != self.runs else ""
        return (f"study: {_n(self.cells, 'cell')}, {_n(self.runs, 'run')}{done}, "
                f"{_n(self.trajectories, 'distinct plant trajectory', 'distinct plant trajectories')}"
                f", {_n(len(self.chunks), 'chunk')}, about {seconds(self.estimate_s)}{where}")


def _n(k: int, one: str, many: str | None = None) -> str:
    return f"{k} {one if k == 1 else (many or one + 's')}"


class Study:
    """A scenario swept over axes and seeds (see :mod:`hgo_mj.study.spec`).

    Parameters
    ----------
    scenario : mapping
        A scenario as in a scenario file (``plant``, ``sensor``, ``observers``, ``input``,
        ``run``).
    axes : mapping dotted path -> list of values, optional
        One axis per dotted path into the scenario (:mod:`hgo_mj.study.spec`); default none.
    seeds : int or list of int
        ``N``: the seeds ``run.seed ... run.seed + N - 1``; or the seeds themselves.
    mode : {"product", "zip"}
        Every combination of the axes' values (default), or the axes advancing together.
    together : list of mappings, optional
        Groups of axes that advance together (each a mapping path -> list, one length).
    store : list of cell filters, optional
        Cells (``{path: value}``) whose runs also keep their trajectory (``.npz`` per run).
    max_runs : int or None
        Refuse a study with more runs (default 10 million; None: no limit).

    Raises
    ------
    DesignError
        A scenario or axis the schema refuses (the message names the path, what was expected
        and what was found), or more runs than ``max_runs``.

    Examples
    --------
    >>> import tempfile
    >>> scenario = {
    ...     "plant": {"name": "pendulum", "dt": 0.01, "x0": [0.5, 0.0]},
    ...     "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
    ...     "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...     "input": {"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]},
    ...     "run": {"duration": 0.2, "t_transient": 0.1, "seed": 0},
    ... }
    >>> study = Study(scenario, axes={"observers.hgo.k": [20.0, 80.0]}, seeds=1)
    >>> study.spec.n_cells, study.spec.n_runs
    (2, 2)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     result = study.run(tmp, quiet=True)
    ...     s = result.summary()
    >>> s[s["state"] == "angle"][["observers.hgo.k", "runs"]].values.tolist()
    [[20.0, 1.0], [80.0, 1.0]]
    """

    def __init__(self, scenario: Mapping[str, Any], axes: Mapping[str, Any] | None = None,
                 seeds: Any = 1, *, mode: str = "product", store: Iterable[Any] = (),
                 together: Iterable[Mapping[str, Any]] = (),
                 max_runs: int | None = MAX_RUNS) -> None:
        if not isinstance(scenario, Mapping):
            raise DesignError(f"scenario must be a table; found {type(scenario).__name__}")
        if axes is not None and not isinstance(axes, Mapping):
            raise DesignError(f"axes must map dotted paths to lists of values; found {axes!r}")
        # parse_study checks the kinds (a list of tables each) and names what it found
        sweep = {"seeds": seeds, "mode": mode, "store": list(store),
                 "together": [dict(t) if isinstance(t, Mapping) else t for t in together],
                 **dict(axes or {})}
        self.spec = parse_study({**copy.deepcopy(dict(scenario)), "sweep": sweep},
                                max_runs=max_runs)
        self.name = str(scenario.get("name", "study"))
        self._validated = False
        #: measured warm cost per update of each observer family, and per cell the sum over
        #: its observers (seconds per sample of one run; :meth:`validate` fills them)
        self._family_cost: dict[str, float] = {}
        self._cell_cost: dict[int, float] = {}

    @classmethod
    def from_toml(cls, path: str | Path, *, max_runs: int | None = MAX_RUNS,
                  seeds: int | None = None) -> Study:
        """A study from a file: a scenario with a ``[sweep]`` table.

        Parameters
        ----------
        path : str or Path
            The study file (TOML); its stem names the study unless it sets ``name``.
        max_runs : int or None
            Refuse a study with more runs (default 10 million; None: no limit).
        seeds : int, optional
            In place of the file's ``[sweep] seeds`` (``hgo-mj sweep --seeds N``: a quick
            look at a study with fewer seeds).

        Returns
        -------
        Study
            The study of the file's scenario, axes, seeds, mode, store and groups.

        Raises
        ------
        DesignError
            The file cannot be read (:func:`load_toml`), ``[sweep]`` is not a table or its
            ``store``/``together`` not a list, or anything :class:`Study` refuses.

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> text = '''
        ... [plant]
        ... name = "pendulum"
        ... x0 = [0.5, 0.0]
        ...
        ... [[observers]]
        ... type = "high_gain"
        ... name = "hgo"
        ... k = 20.0
        ...
        ... [run]
        ... duration = 0.2
        ...
        ... [sweep]
        ... seeds = 2
        ... "observers.hgo.k" = [20.0, 40.0]
        ... '''
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     path = Path(tmp, "gains.toml")
        ...     _ = path.write_text(text)
        ...     study = Study.from_toml(path)
        >>> study.name, study.spec.n_cells, study.spec.seeds
        ('gains', 2, (0, 1))
        """
        doc = load_toml(path)
        sweep = doc.pop("sweep", {})
        if not isinstance(sweep, Mapping):
            raise DesignError(f"[sweep] must be a table; found {sweep!r}")
        sweep = dict(sweep)
        in_file = sweep.pop("seeds", 1)
        seeds = in_file if seeds is None else seeds
        mode = sweep.pop("mode", "product")
        store = sweep.pop("store", [])
        together = sweep.pop("together", [])
        for key, value in (("store", store), ("together", together)):
            if not isinstance(value, list):
                raise DesignError(f"sweep.{key} must be a list of tables; found {value!r}")
        doc.setdefault("name", Path(path).stem)
        return cls(doc, sweep, seeds, mode=mode, store=store, together=together,
                   max_runs=max_runs)

    @property
    def cells(self) -> list[Cell]:
        return self.spec.cells()

    def validate(self) -> list[str]:
        """Build every distinct cell once (plant, sensor, observers, input), so that a bad
        value is refused before any run, naming the cell. Returns every diagnostic name of
        the study's observers (the result columns ``diag.<name>``).

        Returns
        -------
        list of str
            The diagnostic names, in the order first met.

        Raises
        ------
        DesignError
            A cell that cannot be built (a bad plant, sensor, observer or input value, an
            ``x0`` of the wrong length, a ``run.t_transient`` outside ``[0, duration]``); the
            message names the cell's index and values.

        Examples
        --------
        >>> scenario = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.5, 0.0]},
        ...             "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
        ...             "run": {"duration": 0.2}}
        >>> study = Study(scenario, {"observers.hgo.k": [20.0, 40.0]})
        >>> study.validate()
        ['k', 'dropouts']
        >>> Study(scenario, {"observers.hgo.k": [20.0, -1.0]}).validate()
        Traceback (most recent call last):
        ...
        hgo_mj.exceptions.DesignError: cell 1 (observers.hgo.k = -1.0): ...
        """
        names: list[str] = []
        built: dict[str, tuple[int, int]] = {}
        for cell in self.cells:
            # cells that differ only in x0 are built once; each x0 is checked on its own
            rest = {**cell.scenario, "plant": {k: v for k, v in cell.scenario["plant"].items()
                                               if k != "x0"}}
            key = json.dumps(rest, sort_keys=True)
            try:
                if key in built:
                    n, first = built[key]
                    self._check_x0(cell.scenario["plant"].get("x0"), n)
                    self._cell_cost[cell.index] = self._cell_cost[first]
                    continue
                kw = scenario_run(cell.scenario, self.name)
                # only the state count is kept: a plant per distinct cell would not fit
                built[key] = (len(kw["plant"].state_names), cell.index)
                self._check_x0(cell.scenario["plant"].get("x0"), built[key][0])
                self._check_memory(kw)
                if "t_transient" in cell.scenario.get("run", {}):
                    t_tr = cell.scenario["run"]["t_transient"]
                    if isinstance(t_tr, bool) or not isinstance(t_tr, (int, float)) or not (
                            0 <= t_tr <= kw["duration"]):
                        raise DesignError(f"run.t_transient must be a number in [0, duration = "
                                          f"{kw['duration']}]; found {t_tr!r}")
            except HgoError as exc:
                raise DesignError(f"cell {cell.index} ({cell.label()}): {exc}") from None
            except (TypeError, ValueError) as exc:
                raise DesignError(f"cell {cell.index} ({cell.label()}): {exc}") from None
            cost = 0.0
            for name, ob in kw["observers"].items():
                for d in ob.diagnostic_names:
                    if d not in names:
                        names.append(d)
                family = type(ob).__qualname__
                if family not in self._family_cost:  # each family measured once
                    self._family_cost[family] = update_cost(kw, name)
                cost += self._family_cost[family]
            self._cell_cost[cell.index] = cost
        self._validated = True
        return names

    @staticmethod
    def _check_memory(kw: dict[str, Any]) -> None:
        """Refuse a cell whose one plant trajectory (the rows every run of it shares) would
        not fit in the memory available."""
        from ..simulate import available_memory

        plant = kw["plant"]
        ts = float(kw.get("sample_period") or plant.dt)
        rows = kw["duration"] / ts + 1
        nbytes = 8 * rows * (len(plant.state_names) + len(plant.output_names))
        avail = available_memory()
        if nbytes > avail:
            raise DesignError(f"a run of run.duration = {kw['duration']:g} s sampled every "
                              f"{ts:g} s holds {rows:.3g} rows of the plant, about "
                              f"{nbytes / 2**30:.3g} GiB; found {avail / 2**30:.3g} GiB of memory "
                              f"available: shorten run.duration or sample less often")

    @staticmethod
    def _check_x0(x0: Any, n: int) -> None:
        if x0 is not None:
            vector("plant.x0", x0, n)

    def _metric_kw(self) -> dict[str, Any]:
        run = self.spec.scenario.get("run", {})
        return {k: run[k] for k in ("t_transient", "band") if k in run}

    def plan(self, *, jobs: int = 1, done: set[tuple[int, int]] | None = None,
             out: str | Path | None = None) -> Plan:
        """The chunks of the runs left, grouped by what they share, and the plan's figures.

        Parameters
        ----------
        jobs : int
            Processes the estimate assumes (default 1).
        done : set of (int, int), optional
            ``(cell, seed)`` pairs already done, left out of the plan (a resumed study).
        out : str or Path, optional
            The study's folder, named by :meth:`Plan.describe`.

        Returns
        -------
        Plan
            The chunks and the figures (cells, runs, runs left, distinct plant trajectories,
            time estimate).

        Examples
        --------
        >>> scenario = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.5, 0.0]},
        ...             "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
        ...             "run": {"duration": 0.2}}
        >>> study = Study(scenario, {"observers.hgo.k": [20.0, 40.0]})
        >>> plan = study.plan(done={(1, 0)})
        >>> plan.runs, plan.todo
        (2, 1)
        """
        cells = self.cells
        chunks = plan(cells, self.spec.seeds, done=done, jobs=jobs, metric_kw=self._metric_kw())
        trajectories, plant_steps, obs_s, closed_steps = set(), 0.0, 0.0, 0.0
        closed_cells: set[int] = set()
        segments = 0.0
        for c in chunks:
            for cell, seed in c.members:
                sc = c.scenarios[cell]
                dur = float(sc["run"]["duration"])
                dt = float(sc["plant"].get("dt") or 0.001)
                steps = dur / float(sc["run"].get("sample_period") or dt)
                # each family's measured warm cost (validate), else a high-gain one's
                obs_s += steps * self._cell_cost.get(
                    cell, _OBSERVER_STEP_S * max(len(sc.get("observers", [])), 1))
                if "controller" in sc:  # a closed loop: every run its own plant trajectory
                    trajectories.add(json.dumps([cell, seed]))
                    closed_steps += dur / dt
                    if cell not in closed_cells:  # one loop segment per control period
                        closed_cells.add(cell)
                        segments += steps
                    continue
                key = json.dumps([{k: v for k, v in sc["plant"].items()}, sc.get("input"),
                                  {k: sc["run"].get(k) for k in ("duration", "sample_period")}],
                                 sort_keys=True)
                if key not in trajectories:
                    trajectories.add(key)
                    plant_steps += dur / dt
        serial = (obs_s + closed_steps * _CLOSED_STEP_S
                  + segments * _SEGMENT_S)
        est = plant_steps * _PLANT_STEP_S + serial / max(jobs, 1)
        todo = sum(c.n_runs for c in chunks)
        return Plan(chunks, self.spec.n_cells, self.spec.n_runs, todo, len(trajectories), est,
                    serial, None if out is None else Path(out))

    def run(self, out: str | Path, *, jobs: int = 1, backend: str = "local",
            address: str | None = None, resume: bool = False, quiet: bool = False,
            echo: Callable[[str], None] | None = None) -> StudyResult:
        """Run the study into the folder ``out`` (see :mod:`hgo_mj.study.results`).

        Parameters
        ----------
        out : path
            The study's folder.
        jobs : int
            Worker processes (local) or CPUs (a local Ray instance).
        backend : {"local", "ray"}
        address : str, optional
            A Ray cluster's address (``ray start --head`` prints it); default: a local
            instance on 127.0.0.1.
        resume : bool
            Skip the ``(cell, seed)`` pairs already in ``out``'s results (the same study only).
        quiet : bool
            No plan line and no progress on stderr.
        echo : callable ``(str) -> None``, optional
            Where the plan line and the progress go instead of stderr.

        Returns
        -------
        StudyResult
            The finished study's folder; ``summary.parquet`` and ``summary.md`` are written.

        Raises
        ------
        DesignError
            A bad ``jobs``, backend or address (Ray missing, the address unreachable), a
            cell that cannot be built (:meth:`validate`), or an ``out`` that holds results of
            another study (or any, without ``resume``).

        Examples
        --------
        >>> import tempfile
        >>> scenario = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.5, 0.0]},
        ...             "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
        ...             "run": {"duration": 0.2}}
        >>> study = Study(scenario, {"observers.hgo.k": [20.0, 40.0]})
        >>> lines = []
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     result = study.run(tmp, echo=lines.append)
        ...     rows = len(result.table)
        >>> rows, lines[0]
        (4, 'study: 2 cells, 2 runs, 1 distinct plant trajectory, 1 chunk, about ...')
        """
        from .._validate import positive_int
        from .backends import backend_for, local_jobs

        jobs = positive_int("jobs", jobs, floats=False)
        backend_for(backend, address=address, jobs=jobs)  # Ray importable, address reachable
        say = echo or (lambda s: print(s, file=sys.stderr))
        if not quiet and self.spec.n_cells >= LARGE_CELLS:  # its checks and plan take a while
            from .spec import study_memory

            say(f"study: {self.spec.n_runs:,} runs ({self.spec.n_cells:,} cells x "
                f"{len(self.spec.seeds):,} seeds), up to {study_memory(self.spec) / 2**30:.2g} "
                f"GiB of memory; checking every cell and planning ...")
        diagnostics = self.validate()
        res = ResultsDir(out)
        done = res.start(self.spec, resume)
        if backend == "local":  # workers only for work that outlasts their start
            jobs = local_jobs(jobs, self.plan(jobs=1, done=done).serial_s)
        the_plan = self.plan(jobs=jobs, done=done, out=out)
        run_backend = backend_for(backend, address=address, jobs=jobs)
        if not quiet:
            say(the_plan.describe())
        sch = schema(self.spec, diagnostics)
        values = {c.index: c.values for c in self.cells}
        progress = Progress(the_plan.todo, desc=self.name, quiet=quiet, echo=echo)
        t0 = time.perf_counter()
        for chunk, rows in run_backend(the_plan.chunks):
            res.write(rows, self.spec, values, sch)
            progress.add(chunk.n_runs)
        progress.close()
        res.seal()  # the rows are complete: readable from here on
        result = StudyResult(self, Path(out), time.perf_counter() - t0)
        result.write_summary()
        self._store_trajectories(Path(out))
        res.seal()
        return result

    def _store_trajectories(self, out: Path) -> None:
        """The runs of the cells in ``store``: ``trajectories/cell<i>_seed<s>.npz``, each the
        cell run alone through :func:`hgo_mj.simulate.simulate`."""
        if not self.spec.store:
            return
        from ..simulate import simulate

        for cell in self.cells:
            if not any(all(cell.values.get(p) == v for p, v in f.items())
                       for f in self.spec.store):
                continue
            for seed in self.spec.seeds:
                try:
                    traj = simulate(**scenario_run(cell.scenario, self.name), seed=seed)
                except HgoError as exc:  # a diverged run: what it has, up to the divergence
                    if getattr(exc, "trajectory", None) is None:
                        continue
                    traj = exc.trajectory  # type: ignore[attr-defined]
                traj.save(out / "trajectories" / f"cell{cell.index}_seed{seed}.npz")


class StudyResult:
    """A finished study's folder: ``table`` (every row), :meth:`summary`, :meth:`plot`.

    Returned by :meth:`Study.run`; the results are read from the folder when first asked for.

    Parameters
    ----------
    study : Study
        The study that wrote the folder.
    out : Path
        The study's folder.
    seconds : float
        Wall time of the run, seconds (default NaN: not measured).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> scenario = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.5, 0.0]},
    ...             "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...             "run": {"duration": 0.2}}
    >>> study = Study(scenario, {"observers.hgo.k": [20.0, 40.0]})
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     _ = study.run(tmp, quiet=True)
    ...     result = StudyResult(study, Path(tmp))  # the same folder, opened again
    ...     table = result.table
    >>> result.axes, table.shape
    (['observers.hgo.k'], (4, 18))
    """

    def __init__(self, study: Study, out: Path, seconds: float = float("nan")) -> None:
        self.study, self.out, self.seconds = study, Path(out), seconds
        self._table: Any = None

    @property
    def axes(self) -> list[str]:
        """Every swept path (a column each)."""
        return [a.path for a in self.study.spec.axes]

    @property
    def plot_axes(self) -> list[str]:
        """One path per unit of the product (a group is drawn against its first path)."""
        return [u[0].path for u in self.study.spec.units()]

    @property
    def table(self) -> Any:
        """Every result row as a pandas DataFrame (see :mod:`hgo_mj.study.results`)."""
        if self._table is None:
            self._table = ResultsDir(self.out).table()
        return self._table

    def summary(self) -> Any:
        """Per cell, observer and state: the statistics over the seeds (a DataFrame).

        Returns
        -------
        pandas.DataFrame
            :func:`hgo_mj.study.results.summarize` of :attr:`table`.

        Examples
        --------
        >>> import tempfile
        >>> scenario = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.5, 0.0]},
        ...             "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
        ...             "run": {"duration": 0.2}}
        >>> study = Study(scenario, {"observers.hgo.k": [20.0, 40.0]})
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     s = study.run(tmp, quiet=True).summary()
        >>> s["state"].tolist()
        ['angle', 'angular_velocity', 'angle', 'angular_velocity']
        >>> s[["observers.hgo.k", "runs"]].values.tolist()
        [[20.0, 1.0], [20.0, 1.0], [40.0, 1.0], [40.0, 1.0]]
        """
        from .results import summarize

        return summarize(self.table, self.axes)

    def write_summary(self) -> Any:
        """Write ``summary.parquet`` and ``summary.md`` into the folder (:meth:`Study.run`
        does so).

        Returns
        -------
        pandas.DataFrame
            The summary written (:meth:`summary`).

        Examples
        --------
        >>> import os, tempfile
        >>> scenario = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.5, 0.0]},
        ...             "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
        ...             "run": {"duration": 0.2}}
        >>> study = Study(scenario, {"observers.hgo.k": [20.0, 40.0]})
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     result = study.run(tmp, quiet=True)
        ...     os.remove(f"{tmp}/summary.md")
        ...     n = len(result.write_summary())
        ...     again = os.path.exists(f"{tmp}/summary.md")
        >>> n, again
        (4, True)
        """
        return write_summary(self.out, self.table, self.axes, self.study.name)

    def plot(self, out: str | Path | None = None) -> list[Any]:
        """The study's figures (:mod:`hgo_mj.study.figures`); with ``out``, also saved there
        as PNG files.

        Parameters
        ----------
        out : str or Path, optional
            A folder to save the figures in (default: not saved).

        Returns
        -------
        list of matplotlib.figure.Figure
            One figure per swept axis, and a heatmap for two axes.

        Examples
        --------
        >>> import tempfile
        >>> scenario = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.5, 0.0]},
        ...             "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
        ...             "run": {"duration": 0.2}}
        >>> study = Study(scenario, {"observers.hgo.k": [20.0, 40.0]})
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     figs = study.run(tmp, quiet=True).plot()
        >>> [type(f).__name__ for f in figs]
        ['Figure']
        """
        from .figures import study_figures

        figs = study_figures(self, out)
        if out is not None and Path(out) == self.out:
            ResultsDir(self.out).seal()  # the figures join the folder's manifest
        return figs


__all__ = ["Plan", "Study", "StudyResult", "load_toml"]
