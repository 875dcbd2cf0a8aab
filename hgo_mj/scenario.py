"""A run built from a scenario: the plant, sensor chain, observers and input that a scenario
document names (:data:`hgo_mj.schema.SCHEMA`), as fresh objects.

A scenario is plain data (a TOML file's tables, or the same dict in Python)::

    {"plant": {"name": "pendulum", "dt": 0.01},
     "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
     "observers": [{"type": "high_gain", "k": 20.0}],
     "input": {"type": "multisine", "amplitudes": [0.5], "frequencies": [0.5]},
     "run": {"duration": 2.0, "seed": 0}}

:func:`scenario_run` turns it into the keyword arguments of :func:`hgo_mj.simulate.simulate`.
It is the one builder: ``hgo-mj run`` (:mod:`hgo_mj.cli`) and the studies
(:mod:`hgo_mj.study`, each cell a scenario) both call it, so a cell's run is exactly the run
of that scenario.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .check import refuse_inapplicable
from .control import make_controller
from .exceptions import DesignError
from .inputs import Controller, Signal, signal_from_spec
from .observers import Observer, make_observer
from .plants import OdePlant, Plant, make_plant
from .schema import SCHEMA, check_scenario
from .sensors import SensorChain

#: the keys of each section (:data:`hgo_mj.schema.SCHEMA`; ``[input]`` also takes its signal's)
SCENARIO_KEYS = {section: list(SCHEMA[section]) for section in ("plant", "sensor", "input", "run")}


def scenario_run(sc: dict[str, Any], name: str = "run") -> dict[str, Any]:
    """Validate a scenario and build one run of it from fresh objects.

    ``functools.partial(scenario_run, sc)`` is the ``make_run`` of
    :func:`hgo_mj.study.monte_carlo`.

    Parameters
    ----------
    sc : dict
        The scenario (module docstring; :data:`hgo_mj.schema.SCHEMA`): ``plant``, ``sensor``,
        ``observers``, ``input`` or ``controller``, and ``run`` with ``duration``.
    name : str, default "run"
        The scenario's name when it has no ``name`` key (error messages, metadata).

    Returns
    -------
    dict
        The keyword arguments of :func:`hgo_mj.simulate.simulate`: ``plant``, ``sensor``,
        ``observers`` (label -> observer), ``inputs``, ``duration``, ``sample_period``,
        ``control_period``, ``x0`` and ``metadata``; not ``seed`` (``run.seed``, default 0,
        is the sensor chain's seed until ``simulate`` re-seeds it).

    Raises
    ------
    DesignError
        The scenario does not fit :data:`hgo_mj.schema.SCHEMA`, or a part refuses its
        parameters; a ``TypeError`` of a part's constructor (one registered by another package)
        is reported as a DesignError naming the scenario.

    Examples
    --------
    >>> kw = scenario_run({"plant": {"name": "pendulum", "dt": 0.01},
    ...                    "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...                    "run": {"duration": 1.0}})
    >>> type(kw["plant"]).__name__, list(kw["observers"]), kw["duration"]
    ('MujocoPlant', ['hgo'], 1.0)
    >>> scenario_run({"plant": {"name": "pendulum"}, "run": {}})
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: scenario needs run.duration: [run] duration = SECONDS or --duration SECONDS
    """
    try:
        return _scenario_run(sc, name)
    except TypeError as exc:
        raise DesignError(f"scenario {str(sc.get('name', name))!r}: {exc}") from exc


def _scenario_run(sc: dict[str, Any], name: str) -> dict[str, Any]:
    check_scenario(sc)
    pl = sc["plant"]
    plant = build_plant(pl, str(sc.get("name", name)))
    run = sc["run"]
    sensor = SensorChain.from_spec(sc.get("sensor", {}).get("stages", []), seed=run.get("seed", 0))
    observers = build_observers(sc.get("observers", []), plant.system)
    inputs: Signal | Controller
    if "controller" in sc:
        if "input" in sc:
            raise DesignError("a scenario has an [input] signal or a [controller], not both")
        inputs = make_controller(sc["controller"], plant.system)
    else:  # one table, or one table per actuator
        inputs = signal_from_spec(sc.get("input"), len(plant.input_names))
    if "duration" not in run:
        raise DesignError("scenario needs run.duration (seconds), e.g. --duration 10")
    return {"plant": plant, "sensor": sensor, "observers": observers, "inputs": inputs,
            "duration": run["duration"], "sample_period": run.get("sample_period"),
            "control_period": run.get("control_period"), "x0": pl.get("x0"),
            "metadata": {"scenario": sc.get("name", name), "scenario_spec": sc}}


def build_observers(specs: list[dict[str, Any]], system: Any) -> dict[str, Observer]:
    """The observers of a scenario's ``[[observers]]`` tables, by label, each designed for
    ``system`` (or, with ``system_params``, for a model of the same class that differs).

    Parameters
    ----------
    specs : list of dict
        One table per observer: ``type`` (a registered name or ``"module:Class"``), an
        optional ``name`` (default ``TYPE_i``), an optional ``system_params`` table and the
        observer's parameters.
    system : System
        The plant's system.

    Returns
    -------
    dict
        Label -> a new observer, in the order given.

    Raises
    ------
    DesignError
        A table without ``type``, two observers of one name, an observer that does not apply
        to the system (:func:`hgo_mj.check.refuse_inapplicable`), or one that refuses its
        parameters (:func:`hgo_mj.observers.make_observer`).

    Examples
    --------
    >>> from hgo_mj.systems import Pendulum
    >>> obs = build_observers([{"type": "high_gain", "k": 20.0},
    ...                        {"type": "riccati", "name": "ric", "gamma": 5.0}], Pendulum())
    >>> {label: type(ob).__name__ for label, ob in obs.items()}
    {'high_gain_0': 'HighGainObserver', 'ric': 'RiccatiObserver'}
    >>> build_observers([{"k": 20.0}], Pendulum())
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: observer #1 needs type = ...
    """
    observers: dict[str, Observer] = {}
    for i, spec in enumerate(specs):
        spec = dict(spec)
        kind = spec.pop("type", None)
        if kind is None:
            raise DesignError(f"observer #{i + 1} needs type = ...")
        short = kind.rsplit(":", 1)[-1].rsplit(".", 1)[-1] if isinstance(kind, str) else kind
        label = spec.pop("name", f"{short}_{i}")
        if label in observers:
            raise DesignError(f"two observers are named {label!r}; give each a distinct name")
        refuse_inapplicable(kind, system, label)
        observers[label] = make_observer(kind, observer_system(system, spec.pop(
            "system_params", None), label), **spec)
    return observers


def build_plant(pl: dict[str, Any], name: str = "run") -> Plant:
    """The plant of a scenario's ``[plant]`` table.

    Parameters
    ----------
    pl : dict
        The table: a registered plant (``name``), any MJCF file (``model`` with ``outputs``,
        :mod:`hgo_mj.systems.mjcf`) or an ODE given as text (``states``, ``f``, ``h``,
        :mod:`hgo_mj.systems.symbolic`); ``dt``, ``physics_dt`` and ``params`` where they
        apply.
    name : str, default "run"
        The name of an ODE's system.

    Returns
    -------
    Plant
        A new plant.

    Raises
    ------
    DesignError
        An unknown plant, or a parameter it refuses (:func:`hgo_mj.plants.make_plant`).

    Examples
    --------
    >>> build_plant({"name": "pendulum", "dt": 0.01}).state_names
    ('angle', 'angular_velocity')
    >>> build_plant({"states": ["x"], "f": ["-x + u"], "h": "x", "inputs": ["u"]}).state_names
    ('x',)
    """
    if "f" in pl:  # an ODE, its normal form derived (sympy: imported for ODE plants only)
        from .systems.symbolic import ode_system

        system = ode_system(pl["states"], pl["f"], pl["h"], inputs=pl.get("inputs", ()),
                            params=pl.get("params"), x0=pl.get("x0"), name=name,
                            held_input=pl.get("held_input", False), region=pl.get("region"))()
        return OdePlant(system, pl.get("dt", 0.01), physics_dt=pl.get("physics_dt"))
    if "region" in pl:
        raise DesignError("[plant] region is the box of an ODE plant's observability rank and "
                          "Lipschitz bound (states, f, h); a registered or MJCF plant has none")
    extra = {"model_fields": pl["model_fields"]} if "model_fields" in pl else {}
    if "model" in pl:  # any MJCF file (hgo_mj.systems.mjcf)
        return make_plant(Path(pl["model"]), pl.get("dt"), physics_dt=pl.get("physics_dt"),
                          outputs=pl["outputs"], inputs=pl.get("inputs"), **extra,
                          **pl.get("params", {}))
    return make_plant(pl["name"], pl.get("dt"), physics_dt=pl.get("physics_dt"), **extra,
                      **pl.get("params", {}))


def observer_system(system: Any, params: Any, label: str) -> Any:
    """The system an observer designs against: the plant's, or (model mismatch) one of the
    same class whose parameters ``params`` differ from the plant's."""
    if params is None:
        return system
    if not isinstance(params, dict):
        raise DesignError(f"observer {label!r}: system_params must be a table of parameter "
                          f"values; found {params!r}")
    return type(system)(**{**system.params, **params})


__all__ = ["REGION_SECONDS", "SCENARIO_KEYS", "build_observers", "build_plant", "scenario_plant",
           "scenario_run"]


#: the longest simulation :func:`scenario_plant` runs to find the region a scenario visits
REGION_SECONDS = 10.0


def scenario_plant(sc: dict[str, Any], name: str = "run") -> tuple[Any, list[str]]:
    """The plant of a scenario for ``hgo-mj check``, and notes on the region its Lipschitz
    bound and observability rank are taken over (an ODE plant's; others have none).

    An ODE plant uses ``[plant] region`` when given, and warns when ``x0`` or a short
    simulation of the scenario (its input, no noise, no observer, at most
    :data:`REGION_SECONDS`) leaves it; without a region, the box that simulation visits
    (widened by 5 % of its span) replaces the default ``[-1, 1]`` box.

    Parameters
    ----------
    sc : dict
        The scenario (its ``plant``, ``input`` and ``run.duration``).
    name : str
        Its name when it has none.

    Returns
    -------
    plant : Plant
    notes : list of str
        Lines to print above the table (``warning: ...`` where the run leaves the region).

    Examples
    --------
    >>> sc = {"plant": {"states": ["x1", "x2"], "f": ["x2", "(1 - x1**2)*x2 - x1"],
    ...                 "h": "x1", "x0": [2.0, 0.0]}, "run": {"duration": 10.0}}
    >>> plant, notes = scenario_plant(sc)
    >>> notes[0][:60]
    'region: the box visited by a 10 s simulation of the scenario'
    >>> plant.system.lipschitz > 10
    True
    """
    import numpy as np

    from .inputs import signal_from_spec
    from .simulate import simulate

    label = str(sc.get("name", name))
    pl = sc.get("plant", {})
    plant = build_plant(pl, label)
    if "f" not in pl:
        return plant, []
    system = plant.system
    x0 = np.asarray(pl.get("x0", system.default_x0), dtype=float)
    seconds = min(float(sc.get("run", {}).get("duration", REGION_SECONDS)), REGION_SECONDS)
    u = signal_from_spec(sc.get("input"), len(system.input_names))
    x = simulate(plant, None, {}, u, seconds, x0=x0).x
    lo, hi = np.nanmin(x, axis=0), np.nanmax(x, axis=0)
    if "region" not in pl:
        pad = 0.05 * (hi - lo) + 1e-6
        box = np.round(np.column_stack((lo - pad, hi + pad)), 4).tolist()
        return build_plant({**pl, "region": box}, label), [
            f"region: the box visited by a {seconds:g} s simulation of the scenario from x0 = "
            f"{x0.tolist()}, {box} (set [plant] region to choose another)"]
    box = np.asarray(pl["region"], dtype=float)
    notes = [f"region: [plant] region {box.tolist()}"]
    if np.any(x0 < box[:, 0]) or np.any(x0 > box[:, 1]):
        notes.append(f"warning: x0 = {x0.tolist()} lies outside the region {box.tolist()}: "
                     f"the Lipschitz bound and the observability rank hold over the region only")
    if np.any(lo < box[:, 0]) or np.any(hi > box[:, 1]):
        visited = np.round(np.column_stack((lo, hi)), 4).tolist()
        notes.append(f"warning: a {seconds:g} s simulation of the scenario leaves the region "
                     f"(it visits {visited}): the Lipschitz bound and the observability rank "
                     f"hold over the region only")
    return plant, notes
