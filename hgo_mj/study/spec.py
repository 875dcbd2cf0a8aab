"""A study: a scenario, the axes swept over it, and the seeds; expanded into cells.

A study file is a scenario file (see :mod:`hgo_mj.scenario`) with a ``[sweep]`` table::

    [sweep]
    seeds = 64                               # the seeds SEED ... SEED+63 of [run] seed; or a list
    mode = "product"                         # or "zip": the axes advance together
    "observers.hgo.k" = [10, 20, 40, 80]     # one axis per dotted path into the scenario
    "sensor.stages.0.std" = [1e-4, 1e-3]

Axes in a ``[[sweep.together]]`` table advance together (their lists have one length), and
the group as a whole is one axis of the product: e.g. a plant with its own initial state and
bounds, ``"plant.name" = ["pendulum", "elastic_joint"]`` beside ``"plant.x0" = [[0.3, 0.0],
[0.3, 0.3, 0.0, 0.0]]``.

A dotted path names a value of the scenario: its first part is a section (``plant``,
``sensor``, ``observers``, ``input``, ``run``); an observer is addressed by its ``name``
(``observers.hgo.k``), a list entry by its index (``sensor.stages.0.std``). A path that ends on
an observer (``observers.hgo``) takes whole observer tables as values, to compare families
under one name. ``observers.NAME.system_params.P`` gives the observer a model whose parameter
``P`` differs from the plant's (model mismatch). A path must exist in the scenario, or end in a
parameter its table accepts: an unknown one is refused with the valid keys at that level.

Each **cell** is the scenario with one value per axis set (the product of the axes, or their
zip); each cell runs once per seed. The expansion is pure data: a cell is a plain dict that
:func:`hgo_mj.scenario.scenario_run` builds, so a cell's run is exactly ``simulate`` of that
scenario at that seed.
"""

from __future__ import annotations

import copy
import inspect
import itertools
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..exceptions import DesignError
from ..scenario import SCENARIO_KEYS

#: keys of ``[sweep]`` that are not axes
SWEEP_KEYS = ("seeds", "mode", "store", "together")
#: the sections a dotted path may start with
SECTIONS = ("plant", "sensor", "observers", "input", "controller", "run")
#: refuse larger studies unless confirmed (``--yes``)
MAX_RUNS = 10_000_000


@dataclass(frozen=True)
class Axis:
    """One swept dotted path and its values; axes of one ``group`` (a ``[[sweep.together]]``
    table) advance together.

    Parameters
    ----------
    path : str
        The dotted path into the scenario (e.g. ``"observers.hgo.k"``).
    values : tuple
        The values the path takes, in order (numbers, strings, lists or tables).
    group : int or None
        Index of the ``[[sweep.together]]`` table the axis belongs to (default None: an axis
        of its own).

    Examples
    --------
    >>> doc = {"plant": {"name": "pendulum", "dt": 0.01},
    ...        "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...        "run": {"duration": 0.2, "seed": 5},
    ...        "sweep": {"seeds": 2, "observers.hgo.k": [10.0, 40.0],
    ...                  "plant.x0": [[0.1, 0.0], [0.2, 0.0]]}}
    >>> parse_study(doc).axes[0]
    Axis(path='observers.hgo.k', values=(10.0, 40.0), group=None)
    """

    path: str
    values: tuple[Any, ...]
    group: int | None = None


@dataclass
class StudySpec:
    """A validated study: the base scenario, its axes, the mode and the seeds.

    Made by :func:`parse_study` (or :class:`~hgo_mj.study.Study`, whose ``spec`` it is).

    Parameters
    ----------
    scenario : dict
        The base scenario (the study document without ``[sweep]``).
    axes : tuple of Axis
        The swept paths, in the order of the document (the last varies fastest).
    seeds : tuple of int
        The seeds each cell runs at.
    mode : {"product", "zip"}
        Every combination of the axes' values, or the axes advancing together (default
        ``"product"``).
    store : tuple of dict
        Cell filters (``{path: value}``) whose runs keep their trajectories (default none).

    Examples
    --------
    >>> doc = {"plant": {"name": "pendulum", "dt": 0.01},
    ...        "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...        "run": {"duration": 0.2, "seed": 5},
    ...        "sweep": {"seeds": 2, "observers.hgo.k": [10.0, 40.0],
    ...                  "plant.x0": [[0.1, 0.0], [0.2, 0.0]]}}
    >>> spec = parse_study(doc)
    >>> spec.seeds, spec.mode, spec.n_cells, spec.n_runs
    ((5, 6), 'product', 4, 8)
    """

    scenario: dict[str, Any]
    axes: tuple[Axis, ...]
    seeds: tuple[int, ...]
    mode: str = "product"
    #: cell filters whose runs keep their trajectories (``[{"path": value}, ...]``)
    store: tuple[dict[str, Any], ...] = field(default_factory=tuple)

    def units(self) -> list[list[Axis]]:
        """What a product runs over: each axis alone, the axes of a group together.

        Returns
        -------
        list of list of Axis
            One entry per unit of the product: ``[axis]`` for an axis of its own, the axes of
            a ``[[sweep.together]]`` group in one list (at the place of its first axis).

        Examples
        --------
        >>> doc = {"plant": {"name": "pendulum", "dt": 0.01},
        ...        "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
        ...        "run": {"duration": 0.2, "seed": 5},
        ...        "sweep": {"seeds": 2, "observers.hgo.k": [10.0, 40.0],
        ...                  "plant.x0": [[0.1, 0.0], [0.2, 0.0]]}}
        >>> doc["sweep"]["together"] = [{"run.duration": [0.2, 0.3], "run.t_transient":
        ...                              [0.05, 0.1]}]
        >>> [[a.path for a in u] for u in parse_study(doc).units()]
        [['observers.hgo.k'], ['plant.x0'], ['run.duration', 'run.t_transient']]
        """
        out: list[list[Axis]] = []
        groups: dict[int, list[Axis]] = {}
        for a in self.axes:
            if a.group is None:
                out.append([a])
            elif a.group not in groups:
                groups[a.group] = [a]
                out.append(groups[a.group])
            else:
                groups[a.group].append(a)
        return out

    @property
    def n_cells(self) -> int:
        if not self.axes:
            return 1
        if self.mode == "zip":
            return len(self.axes[0].values)
        return int(np.prod([len(u[0].values) for u in self.units()]))

    @property
    def n_runs(self) -> int:
        return self.n_cells * len(self.seeds)

    def cells(self) -> list[Cell]:
        """Every cell, in order (the last axis varies fastest in a product).

        Returns
        -------
        list of Cell
            :attr:`n_cells` cells, each with a deep copy of the scenario with its values set.

        Examples
        --------
        >>> doc = {"plant": {"name": "pendulum", "dt": 0.01},
        ...        "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
        ...        "run": {"duration": 0.2, "seed": 5},
        ...        "sweep": {"seeds": 2, "observers.hgo.k": [10.0, 40.0],
        ...                  "plant.x0": [[0.1, 0.0], [0.2, 0.0]]}}
        >>> cells = parse_study(doc).cells()
        >>> [c.values["observers.hgo.k"] for c in cells]
        [10.0, 10.0, 40.0, 40.0]
        >>> cells[1].scenario["plant"]
        {'name': 'pendulum', 'dt': 0.01, 'x0': [0.2, 0.0]}
        """
        if not self.axes:
            picks: list[dict[str, Any]] = [{}]
        elif self.mode == "zip":
            picks = [{a.path: a.values[i] for a in self.axes}
                     for i in range(len(self.axes[0].values))]
        else:
            units = self.units()
            picks = [{a.path: a.values[i] for u, i in zip(units, idx) for a in u}
                     for idx in itertools.product(*(range(len(u[0].values)) for u in units))]
        out = []
        for i, pick in enumerate(picks):
            sc = copy.deepcopy(self.scenario)
            for axis in self.axes:
                set_path(sc, axis.path, copy.deepcopy(pick[axis.path]))
            out.append(Cell(i, {a.path: pick[a.path] for a in self.axes}, sc))
        return out

    def to_json(self) -> dict[str, Any]:
        """The study as JSON data (what ``--resume`` compares).

        Returns
        -------
        dict
            ``scenario``, ``axes`` (path -> list of values), ``groups`` (path -> group index,
            for grouped axes), ``mode``, ``seeds`` (a list) and ``store``.

        Examples
        --------
        >>> doc = {"plant": {"name": "pendulum", "dt": 0.01},
        ...        "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
        ...        "run": {"duration": 0.2, "seed": 5},
        ...        "sweep": {"seeds": 2, "observers.hgo.k": [10.0, 40.0],
        ...                  "plant.x0": [[0.1, 0.0], [0.2, 0.0]]}}
        >>> js = parse_study(doc).to_json()
        >>> sorted(js), js["seeds"], js["axes"]["observers.hgo.k"]
        (['axes', 'groups', 'mode', 'scenario', 'seeds', 'store'], [5, 6], [10.0, 40.0])
        """
        return {"scenario": self.scenario, "axes": {a.path: list(a.values) for a in self.axes},
                "groups": {a.path: a.group for a in self.axes if a.group is not None},
                "mode": self.mode, "seeds": list(self.seeds), "store": list(self.store)}


@dataclass
class Cell:
    """One combination of axis values: ``index``, ``values`` (path -> value), ``scenario``.

    Parameters
    ----------
    index : int
        The cell's position in :meth:`StudySpec.cells` (the ``cell`` column of the results).
    values : dict
        Each axis's dotted path -> the value this cell sets.
    scenario : dict
        The scenario with those values set (what the cell's runs simulate).

    Examples
    --------
    >>> doc = {"plant": {"name": "pendulum", "dt": 0.01},
    ...        "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...        "run": {"duration": 0.2, "seed": 5},
    ...        "sweep": {"seeds": 2, "observers.hgo.k": [10.0, 40.0],
    ...                  "plant.x0": [[0.1, 0.0], [0.2, 0.0]]}}
    >>> cell = parse_study(doc).cells()[2]
    >>> cell.index, cell.values
    (2, {'observers.hgo.k': 40.0, 'plant.x0': [0.1, 0.0]})
    """

    index: int
    values: dict[str, Any]
    scenario: dict[str, Any]

    def label(self) -> str:
        """The cell's values as text, for messages.

        Returns
        -------
        str
            ``"path = value, ..."`` with each value as JSON, or ``"the scenario"`` for a study
            without axes.

        Examples
        --------
        >>> Cell(0, {"observers.hgo.k": 40.0, "plant.x0": [0.1, 0.0]}, {}).label()
        'observers.hgo.k = 40.0, plant.x0 = [0.1, 0.0]'
        >>> Cell(0, {}, {}).label()
        'the scenario'
        """
        return ", ".join(f"{p} = {json.dumps(v)}" for p, v in self.values.items()) or "the scenario"


# ----------------------------------------------------------------- dotted paths
def _observer_label(spec: Any, i: int) -> str:
    if isinstance(spec, Mapping):
        return str(spec.get("name", f"{spec.get('type')}_{i}"))
    return f"#{i}"


def _step(node: Any, part: str, walked: str) -> tuple[Any, Any]:
    """The child of ``node`` named ``part`` and the key/index to set it, or a DesignError
    listing the valid keys at that level."""
    if walked == "observers":
        if not isinstance(node, list):
            raise DesignError(f"scenario observers must be a list of tables; found {node!r}")
        labels = [_observer_label(s, i) for i, s in enumerate(node)]
        if part not in labels:
            raise DesignError(f"unknown dotted path 'observers.{part}': no observer named "
                              f"{part!r}; valid: {labels}")
        j = labels.index(part)
        return node[j], j
    if isinstance(node, list):
        if not part.isdigit() or int(part) >= len(node):
            raise DesignError(f"unknown dotted path '{walked}.{part}': {walked} is a list of "
                              f"{len(node)}; valid indices: {list(range(len(node)))}")
        return node[int(part)], int(part)
    if isinstance(node, Mapping):
        if part not in node:
            raise KeyError(part)
        return node[part], part
    raise DesignError(f"unknown dotted path '{walked}.{part}': {walked} is a value "
                      f"({node!r}), not a table or list")


def _accepted_keys(walked: str, node: Mapping[str, Any]) -> list[str]:
    """The keys a table at ``walked`` may take beyond those it has."""
    parts = walked.split(".")
    known = set(node)
    if walked in ("plant", "run"):
        known |= set(SCENARIO_KEYS[walked])
    elif walked == "plant.params":
        known |= set(node)  # a plant's own parameters: those it has
    elif parts[0] == "observers" and len(parts) == 2:
        from ..observers import registered

        cls = registered().get(str(node.get("type")))
        if cls is not None:
            known |= {p for p in inspect.signature(cls.__init__).parameters
                      if p not in ("self", "system")}
        known |= {"type", "name", "system_params"}
    elif parts[0] == "observers" and len(parts) == 3 and parts[2] == "system_params":
        return sorted(known)  # checked against the system when the cell is built
    elif parts[:2] == ["sensor", "stages"] and len(parts) == 3:
        from ..sensors import STAGES

        stage = STAGES.get(str(node.get("stage")))
        if stage is not None:
            known |= {p for p in inspect.signature(stage.__init__).parameters if p != "self"}
        known.add("stage")
    elif walked == "controller":
        known |= {"type", "Q", "R", "x_eq", "u_eq", "u_max", "x_max", "saturate", "source",
                  "observer"}
    elif parts[0] == "input" and len(parts) <= 2:  # the input, or one actuator's (a list)
        from ..inputs import SIGNALS

        sig = SIGNALS.get(str(node.get("type", "constant")))
        if sig is not None:
            known |= {p for p in inspect.signature(sig.__init__).parameters if p != "self"}
        known.add("type")
    return sorted(known)


def check_path(scenario: Mapping[str, Any], path: str) -> None:
    """Refuse a dotted path that does not name a value of ``scenario`` (or a parameter its
    table accepts), listing the valid keys at the level where it goes wrong."""
    if not isinstance(path, str) or not path or any(not p for p in path.split(".")):
        raise DesignError(f"a sweep axis must be a dotted path such as 'observers.hgo.k'; found "
                          f"{path!r}")
    parts = path.split(".")
    if parts[0] not in SECTIONS:
        raise DesignError(f"unknown dotted path {path!r}: valid first parts: {list(SECTIONS)}")
    node: Any = scenario.get(parts[0], [] if parts[0] == "observers" else {})
    walked = parts[0]
    for i, part in enumerate(parts[1:], start=1):
        last = i == len(parts) - 1
        try:
            node, _ = _step(node, part, walked)
        except KeyError:
            valid = _accepted_keys(walked, node)
            new_table = walked.endswith(".system_params") or walked == "plant.params"
            if last and (part in valid or new_table):
                return
            if not last and part in ("system_params", "params") and part in valid:
                return  # a new sub-table: its keys are checked when the cell is built
            raise DesignError(f"unknown dotted path {path!r}: {walked} has no key {part!r}; "
                              f"valid: {valid}") from None
        walked = f"{walked}.{part}"


def set_path(scenario: dict[str, Any], path: str, value: Any) -> None:
    """Set the value at ``path`` (checked by :func:`check_path`), creating a missing last
    table (``system_params``, ``params``)."""
    parts = path.split(".")
    if parts[0] not in scenario:
        scenario[parts[0]] = [] if parts[0] == "observers" else {}
    node: Any = scenario[parts[0]]
    walked = parts[0]
    for i, part in enumerate(parts[1:], start=1):
        last = i == len(parts) - 1
        try:
            child, key = _step(node, part, walked)
        except KeyError:
            if last:
                node[part] = value
                return
            node[part] = {}
            child, key = node[part], part
        if last:
            if walked == "observers" and isinstance(value, Mapping):
                value = {**value, "name": part}  # a whole observer table keeps its name
            node[key] = value
            return
        node = child
        walked = f"{walked}.{part}"


# ----------------------------------------------------------------- the [sweep] table
def _seeds(value: Any, base: int) -> tuple[int, ...]:
    if isinstance(value, bool):
        raise DesignError(f"sweep.seeds must be a positive integer or a list of seeds; found "
                          f"{value!r}")
    if isinstance(value, int):
        if not 1 <= value <= MAX_RUNS:
            raise DesignError(f"sweep.seeds must be between 1 and {MAX_RUNS:,}; found {value:,}")
        return tuple(range(base, base + value))
    if isinstance(value, list) and value:
        for s in value:
            if isinstance(s, bool) or not isinstance(s, int) or s < 0:
                raise DesignError(f"sweep.seeds must hold non-negative integers; found {s!r}")
        if len(set(value)) != len(value):
            raise DesignError(f"sweep.seeds must be distinct; found {value}")
        return tuple(value)
    raise DesignError(f"sweep.seeds must be a positive integer or a non-empty list of seeds; "
                      f"found {value!r}")


def _base_seed(scenario: Mapping[str, Any]) -> int:
    """``[run] seed`` (default 0), the first of ``seeds = N``."""
    run = scenario.get("run", {})
    if not isinstance(run, Mapping):
        raise DesignError(f"scenario [run] must be a table; found {run!r}")
    base = run.get("seed", 0)
    if isinstance(base, bool) or not isinstance(base, int) or base < 0:
        raise DesignError(f"run.seed must be a non-negative integer; found {base!r}")
    if "seeds" in run:
        raise DesignError("a study sets its seeds in [sweep] seeds = N (found run.seeds)")
    return base


def _value_key(v: Any) -> str:
    return json.dumps(v, sort_keys=True)


def _axes(scenario: Mapping[str, Any], sweep: Mapping[str, Any]) -> list[Axis]:
    """The axes of a ``[sweep]`` table: each path checked, each value list non-empty and
    without repeats."""
    axes = [_axis(scenario, path, values) for path, values in sweep.items()
            if path not in SWEEP_KEYS]
    together = sweep.get("together", [])
    if not isinstance(together, list) or not all(isinstance(t, Mapping) and t for t in together):
        raise DesignError(f"sweep.together must be a list of tables of axes ([[sweep.together]]"
                          f"); found {together!r}")
    for g, table in enumerate(together):
        group = [_axis(scenario, path, values, g) for path, values in table.items()]
        if len({len(a.values) for a in group}) > 1:
            raise DesignError("the axes of a [[sweep.together]] table must have the same "
                              "length; found " + ", ".join(f"{a.path}: {len(a.values)}"
                                                           for a in group))
        axes += group
    paths = [a.path for a in axes]
    if len(set(paths)) != len(paths):
        twice = sorted(p for p in set(paths) if paths.count(p) > 1)
        raise DesignError(f"a sweep axis is given twice: {twice}")
    for a in paths:
        for b in paths:
            if b.startswith(a + "."):
                raise DesignError(f"sweep axes {a!r} and {b!r} overlap ({b!r} sets a part of "
                                  f"{a!r}): which value runs would depend on their order; "
                                  f"sweep one of them")
    return axes


#: paths a sweep axis may not take, and why (their cells would be duplicate runs)
NOT_AN_AXIS = {
    "run.seed": "the runs' seeds are the study's own, [sweep] seeds = N (or a list of seeds); "
                "run.seed is only the first of N",
    "run.seeds": "a study sets its seeds in [sweep] seeds = N (or a list of seeds)",
    "run.out": "a study writes one folder, its --out",
    "run.stream": "a study keeps each run's metrics, not its trajectory (nothing to stream)",
}


def _plain(v: Any) -> bool:
    """Whether ``v`` is a value a scenario holds (no TOML date or time)."""
    if isinstance(v, (bool, int, float, str)):
        return True
    if isinstance(v, list):
        return all(_plain(x) for x in v)
    if isinstance(v, Mapping):
        return all(isinstance(k, str) and _plain(x) for k, x in v.items())
    return False


def _axis(scenario: Mapping[str, Any], path: str, values: Any, group: int | None = None) -> Axis:
    """One axis, checked: its path names a value of the scenario, its values are a non-empty
    list (without repeats, unless it advances with others in a group)."""
    key = next((k for k in NOT_AN_AXIS if path == k or path.startswith(f"{k}.")), None)
    if key is not None:
        raise DesignError(f"sweep axis {path!r} cannot change a run: {NOT_AN_AXIS[key]}")
    check_path(scenario, path)
    if not isinstance(values, list):
        raise DesignError(f"sweep axis {path!r} must be a list of values; found {values!r}")
    if not values:
        raise DesignError(f"sweep axis {path!r} is empty: give at least one value")
    for v in values:
        if not _plain(v):
            raise DesignError(f"sweep axis {path!r}: values must be numbers, strings, booleans "
                              f"or lists and tables of them; found {v!r}")
    keys = [_value_key(v) for v in values]
    if len(set(keys)) != len(keys) and group is None:
        raise DesignError(f"sweep axis {path!r} repeats a value: {values}")
    return Axis(path, tuple(values), group)


def parse_study(doc: Mapping[str, Any], *, max_runs: int | None = MAX_RUNS) -> StudySpec:
    """A :class:`StudySpec` from a study document (a scenario with a ``[sweep]`` table),
    validated: every axis path, the values (non-empty lists, distinct), zip lengths, the seeds
    and the study's size (at most ``max_runs`` runs; None: no limit).

    Parameters
    ----------
    doc : mapping
        A study document: the scenario's sections (``plant``, ``sensor``, ``observers``,
        ``input``, ``controller``, ``run``) and an optional ``sweep`` table (module
        docstring). It is not modified.
    max_runs : int or None
        Refuse a study of more runs (cells x seeds) than this (default :data:`MAX_RUNS`,
        10 million; None: no limit).

    Returns
    -------
    StudySpec
        The scenario (a deep copy, without ``sweep``), the axes, seeds, mode and store.

    Raises
    ------
    DesignError
        ``doc`` or ``sweep`` is not a table; an unknown dotted path (the valid keys at that
        level are listed); an axis that is not a non-empty list, repeats a value or is given
        twice; bad ``seeds`` (or ``run.seed``, or a ``run.seeds``), ``mode``, ``store`` or
        ``together``; zip axes (or a group's) of different lengths; more than ``max_runs``
        runs.

    Examples
    --------
    >>> doc = {"plant": {"name": "pendulum", "dt": 0.01},
    ...        "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...        "run": {"duration": 0.2, "seed": 5},
    ...        "sweep": {"seeds": 2, "observers.hgo.k": [10.0, 40.0],
    ...                  "plant.x0": [[0.1, 0.0], [0.2, 0.0]]}}
    >>> spec = parse_study(doc)
    >>> [a.path for a in spec.axes], spec.seeds, spec.n_runs
    (['observers.hgo.k', 'plant.x0'], (5, 6), 8)
    >>> parse_study(doc, max_runs=4)
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: the study has 8 runs (4 cells x 2 seeds), more than 4; ...
    >>> parse_study({**doc, "sweep": {"observers.luenberger.k": [1.0]}})
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: unknown dotted path 'observers.luenberger': no observer ...
    """
    if not isinstance(doc, Mapping):
        raise DesignError(f"a study must be a table; found {type(doc).__name__}")
    scenario = {k: copy.deepcopy(v) for k, v in doc.items() if k != "sweep"}
    run = scenario.get("run")
    if isinstance(run, Mapping) and "store_every" in run:
        raise DesignError("run.store_every thins the trajectory of `hgo-mj run`; a study keeps "
                          "metrics computed at every sample (and sweep.store's trajectories "
                          "whole): leave it out")
    sweep = doc.get("sweep", {})
    if not isinstance(sweep, Mapping):
        raise DesignError(f"[sweep] must be a table; found {sweep!r}")
    seeds = _seeds(sweep.get("seeds", 1), _base_seed(scenario))
    mode = sweep.get("mode", "product")
    if mode not in ("product", "zip"):
        raise DesignError(f"sweep.mode must be 'product' or 'zip'; found {mode!r}")
    store = sweep.get("store", [])
    if not isinstance(store, list) or not all(isinstance(s, Mapping) for s in store):
        raise DesignError(f"sweep.store must be a list of tables (cell filters, e.g. "
                          f"[{{\"observers.hgo.k\" = 20}}]); found {store!r}")
    axes = _axes(scenario, sweep)
    for f in store:
        for p in f:
            if p not in {a.path for a in axes}:
                raise DesignError(f"sweep.store filter names {p!r}, which is not an axis; "
                                  f"axes: {[a.path for a in axes]}")
    if mode == "zip" and len({len(a.values) for a in axes}) > 1:
        raise DesignError("zip axes must have the same length; found " + ", ".join(
            f"{a.path}: {len(a.values)}" for a in axes))
    spec = StudySpec(scenario, tuple(axes), seeds, mode, tuple(dict(s) for s in store))
    if max_runs is not None and spec.n_runs > max_runs:
        raise DesignError(f"the study has {spec.n_runs:,} runs ({spec.n_cells:,} cells x "
                          f"{len(seeds):,} seeds), more than {max_runs:,}; confirm with --yes")
    check_study_memory(spec)
    return spec


#: bytes a cell's scenario takes in memory per character of its JSON (dicts, lists, floats;
#: measured: about 1.9 KB for a 242-character scenario), plus a cell's fixed share
CELL_BYTES_PER_CHAR, CELL_BYTES = 10, 512
#: bytes a result row (a run's observer and state) takes in the results table and the plan
ROW_BYTES, RUN_BYTES = 400, 200


def study_memory(spec: StudySpec) -> float:
    """An upper estimate of the memory a study holds, bytes: its cells' scenarios, the plan's
    runs and the result rows (one per run, observer and plant state; the states counted from
    ``plant.x0`` where given, else 8)."""
    scenario = spec.scenario
    n_obs = max(len(scenario.get("observers", []) or []), 1)
    x0 = scenario.get("plant", {}).get("x0") if isinstance(scenario.get("plant"), Mapping) \
        else None
    n_states = len(x0) if isinstance(x0, list) and x0 else 8
    per_cell = CELL_BYTES + CELL_BYTES_PER_CHAR * len(json.dumps(scenario, default=str))
    return (spec.n_cells * per_cell + spec.n_runs * RUN_BYTES
            + spec.n_runs * n_obs * n_states * (ROW_BYTES + 8 * len(spec.axes)))


def check_study_memory(spec: StudySpec) -> None:
    """Refuse, before any cell is built, a study whose estimate (:func:`study_memory`) exceeds
    the memory available; a bound that ``--yes`` (``max_runs=None``) keeps."""
    from ..simulate import available_memory

    need, avail = study_memory(spec), available_memory()
    if need > avail:
        raise DesignError(f"the study has {spec.n_runs:,} runs ({spec.n_cells:,} cells x "
                          f"{len(spec.seeds):,} seeds) and would hold about "
                          f"{need / 2**30:.3g} GiB (cells, plan and result rows); found "
                          f"{avail / 2**30:.3g} GiB of memory available (a bound --yes keeps): "
                          f"fewer cells or seeds, or split the study")


def axis_kind(values: Sequence[Any]) -> str:
    """The type of an axis's column: ``"number"`` (floats) when every value is a number,
    ``"bool"`` when every value is true or false, else ``"text"``."""
    if all(isinstance(v, bool) for v in values):
        return "bool"
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        return "number"
    return "text"


def column_value(v: Any, kind: str) -> Any:
    """An axis value as a cell of its column (:func:`axis_kind`): a float, a bool, or text
    (a string as is, anything else, lists and tables, as compact JSON)."""
    if kind == "number":
        return float(v)
    if kind == "bool" or isinstance(v, str):
        return v
    return json.dumps(v, sort_keys=True, separators=(",", ":"))


__all__ = ["Axis", "Cell", "MAX_RUNS", "StudySpec", "parse_study"]
