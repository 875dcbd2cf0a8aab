"""The scenario schema: the sections of a scenario, their keys and the type of each value.

:func:`check_scenario` checks a scenario document (a parsed TOML file, the command line's
flags, a study's cell) against :data:`SCHEMA` before anything is built: every value of the
wrong type, every unknown key and every missing required key is a :class:`DesignError` that
names the key, what was expected and what was found. Types are checked, not coerced: a
string is not a number (``duration = "1"``), a bool is not a number (``duration = true``), a
float is not an integer (``seed = 1.7``), a TOML date is not a name. The values' ranges and
the parameters of each plant, sensor stage, observer, input and controller are checked by the
objects themselves (their constructors), also before the simulation starts.

The fuzz suite (``tests/test_fuzz_scenarios.py``) generates its malformed documents from
:data:`SCHEMA`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ._validate import is_real, numbers_only, reject_unknown
from .exceptions import DesignError

#: the value types of the schema: a name and a test
KINDS: dict[str, str] = {
    "string": "a string",
    "number": "a real number",
    "positive": "a real number > 0",
    "nonneg": "a real number >= 0",
    "seed": "an integer >= 0",
    "count": "a positive integer",
    "table": "a table",
    "tables": "a list of tables",
    "table_or_tables": "a table, or a list of tables (one per actuator)",
    "numbers": "a list of numbers",
    "names": "a non-empty list of strings",
    "bool": "true or false",
    "box": "a list of [lo, hi] pairs of numbers, lo <= hi",
}

#: section -> key -> kind; ``None`` for a section means "a list of tables" (``observers``)
SCHEMA: dict[str, dict[str, str]] = {
    "": {"name": "string", "plant": "table", "sensor": "table", "observers": "tables",
         "input": "table_or_tables", "controller": "table", "run": "table"},
    # name = a registered plant, model = an MJCF file with its outputs (and inputs), or an ODE
    # given by states, f and h (with inputs and params)
    "plant": {"name": "string", "model": "string", "outputs": "names", "inputs": "names",
              "states": "names", "f": "names", "h": "string", "held_input": "bool",
              "dt": "positive", "physics_dt": "positive", "params": "table", "x0": "numbers",
              "model_fields": "table",
              # an ODE's box for the observability rank and the Lipschitz bound (hgo-mj check)
              "region": "box"},
    "sensor": {"stages": "tables"},
    "run": {"duration": "positive", "sample_period": "positive", "control_period": "positive",
            "seed": "seed", "seeds": "count", "out": "string", "t_transient": "nonneg",
            "band": "positive", "store_every": "count", "stream": "bool"},
    # the tables below take their family's own parameters beside these keys
    "observers": {"type": "string", "name": "string", "system_params": "table"},
    "input": {"type": "string"},
    "controller": {"type": "string"},
    "stages": {"stage": "string"},
}

#: keys a scenario must have (``section.key``)
REQUIRED = ("plant.name", "run.duration")
#: sections whose tables take more keys than the schema lists (the family's parameters)
OPEN = ("observers", "input", "controller", "stages")


#: the kinds whose test is one isinstance
_TYPES: dict[str, type | tuple[type, ...]] = {"bool": bool, "string": str, "table": Mapping}


def _is_box(value: Any) -> bool:
    """A non-empty list of ``[lo, hi]`` pairs of numbers with ``lo <= hi``."""
    if not isinstance(value, list) or not value:
        return False
    return all(isinstance(p, list) and len(p) == 2 and numbers_only(p) and p[0] <= p[1]
               for p in value)


def _ok(kind: str, value: Any) -> bool:
    if kind in _TYPES:
        return isinstance(value, _TYPES[kind])
    if kind == "table_or_tables":
        return _ok("table", value) or (_ok("tables", value) and bool(value))
    if kind == "tables":
        return isinstance(value, list) and all(isinstance(v, Mapping) for v in value)
    if kind == "numbers":
        return isinstance(value, list) and numbers_only(value)
    if kind == "box":
        return _is_box(value)
    if kind == "names":
        return isinstance(value, list) and bool(value) and all(isinstance(v, str) for v in value)
    if kind in ("seed", "count"):
        return (is_real(value) and not isinstance(value, float) and int(value) == value
                and value >= (1 if kind == "count" else 0))
    if not is_real(value) or value != value or abs(value) == float("inf"):
        return False
    return kind == "number" or (value > 0 if kind == "positive" else value >= 0)


def check_value(where: str, kind: str, value: Any) -> None:
    """Raise :class:`DesignError` unless ``value`` is of the schema's ``kind``."""
    if not _ok(kind, value):
        raise DesignError(f"{where} must be {KINDS[kind]}; found {value!r} "
                          f"({type(value).__name__})")


def _check_table(where: str, section: str, table: Mapping[str, Any]) -> None:
    keys = SCHEMA[section]
    if section not in OPEN:
        reject_unknown(f"scenario [{where}]" if where else "scenario", table, keys)
    for key, value in table.items():
        if key in keys:
            check_value(f"{where}.{key}" if where else key, keys[key], value)


def _check_plant_kind(plant: Mapping[str, Any], required: bool) -> bool:
    """Which kind of plant a ``[plant]`` table is: a registered plant (``name``), an MJCF file
    (``model`` with ``outputs``) or an ODE (``states``, ``f``, ``h``); True for an ODE."""
    ode = any(k in plant for k in ("states", "f", "h"))
    if ode:
        if "name" in plant or "model" in plant:
            raise DesignError("[plant] is a registered plant (name), an MJCF file (model) or an "
                              "ODE (states, f, h), one of them")
        missing = [k for k in ("states", "f", "h") if k not in plant]
        if missing:
            raise DesignError(f"an ODE [plant] needs states, f and h; missing {missing}")
    elif "model" in plant:
        if "name" in plant:
            raise DesignError("[plant] has name (a registered plant) or model (an MJCF file), "
                              f"not both; found name = {plant['name']!r}, model = "
                              f"{plant['model']!r}")
        if "outputs" not in plant:
            raise DesignError("[plant] model = ... needs outputs = [MJCF sensor or joint names]")
    elif required and ("outputs" in plant or "inputs" in plant):
        raise DesignError("[plant] outputs and inputs go with model = \"robot.xml\" (an MJCF "
                          "file); a registered plant's outputs are its own")
    return ode


def check_scenario(sc: Any, *, required: bool = True) -> None:
    """Check a scenario document against :data:`SCHEMA` (types, unknown and missing keys;
    ``required=False``: a file whose missing keys the command line may still give).

    Parameters
    ----------
    sc : mapping
        The scenario document: top-level keys ``name``, ``plant``, ``sensor``, ``observers``,
        ``input``, ``controller``, ``run`` (a parsed TOML file, ``tomllib.loads(text)``).
    required : bool
        Require the keys of :data:`REQUIRED` (``plant.name`` unless the plant is an MJCF
        file or an ODE, and ``run.duration``) and reject ``outputs``/``inputs`` beside a
        registered plant's ``name``; ``False`` for a file the command line completes.

    Raises
    ------
    DesignError
        The first key whose value is not of its type, an unknown key (the valid ones
        listed) or a missing required key; the message names the key (``run.duration``,
        ``observers[1].type``), what was expected and what was found. Also: ``sc`` is not a
        table; an observer without ``type``; a ``[plant]`` that mixes a registered name, an
        MJCF ``model`` and an ODE (``states``, ``f``, ``h``) or lacks part of one; an unknown
        plant name (the valid ones listed).

    Examples
    --------
    >>> import tomllib
    >>> sc = tomllib.loads('''
    ... [plant]
    ... name = "pendulum"
    ... [[observers]]
    ... type = "high_gain"
    ... k = 40.0
    ... [run]
    ... duration = 2.0
    ... ''')
    >>> check_scenario(sc)  # valid: returns None
    >>> check_scenario({"plant": {"name": "pendulum"}, "run": {"duration": "1"}})
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: run.duration must be a real number > 0; found '1' (str)
    >>> check_scenario({"plant": {"name": "pendulum"}})
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: scenario needs run.duration: [run] duration = SECONDS or --duration SECONDS
    >>> check_scenario({"plant": {"name": "pendulum"}}, required=False)
    """
    if not isinstance(sc, Mapping):
        raise DesignError(f"a scenario must be a table; found {sc!r}")
    _check_table("", "", sc)
    for section in ("plant", "sensor", "input", "controller", "run"):
        if section in sc:
            if isinstance(sc[section], list):  # [[input]]: one table per actuator
                for i, table in enumerate(sc[section]):
                    _check_table(f"{section}[{i}]", section, table)
            else:
                _check_table(section, section, sc[section])
    for i, ob in enumerate(sc.get("observers", [])):
        _check_table(f"observers[{i}]", "observers", ob)
        if "type" not in ob:
            raise DesignError(f"observers[{i}] needs type = ... (see `hgo-mj list`); found keys "
                              f"{sorted(map(str, ob))}")
    for i, st in enumerate(sc.get("sensor", {}).get("stages", [])):
        _check_table(f"sensor.stages[{i}]", "stages", st)
    plant = sc.get("plant", {})
    ode = _check_plant_kind(plant, required)
    name = plant.get("name")
    if isinstance(name, str) and ":" not in name:  # a misspelt name before a missing key
        from .plants import plant_names, unknown_plant

        if name not in plant_names():
            raise unknown_plant(name)
    for path in REQUIRED if required else ():
        section, key = path.split(".")
        if path == "plant.name" and ("model" in plant or ode):
            continue
        if key not in sc.get(section, {}):
            hint = {"plant.name": "[plant] name = ... or --plant NAME (see `hgo-mj list`), or "
                                      "[plant] model = \"robot.xml\" or --model FILE",
                    "run.duration": "[run] duration = SECONDS or --duration SECONDS"}[path]
            raise DesignError(f"scenario needs {path}: {hint}")


__all__ = ["KINDS", "OPEN", "REQUIRED", "SCHEMA", "check_scenario"]
