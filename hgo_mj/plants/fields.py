"""Named fields of a compiled MuJoCo model: ``"field[element]"`` to a place in an ``MjModel``.

One syntax serves every place that changes a model's numbers by name: the MuJoCo Kalman
filters' estimated parameters (``estimate=``) and their deliberately wrong models
(``model_fields=``), and a plant's own changes (``MujocoPlant(model_fields=...)``: the
benchmark's unmodelled Coulomb friction). A field is one of :data:`FIELDS` with the name of
its element, or ``"opt.gravity"`` (the magnitude :math:`g`, along the model's gravity
direction). Scalar fields take a number; ``body_inertia`` (the three principal moments about
the body's centre of mass) takes three.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

import mujoco
import numpy as np

from ..exceptions import DesignError

__all__ = ["FIELDS", "get_field", "resolve", "set_field", "set_fields"]

#: field -> the kind of element it is indexed by (a dof field by its joint's name)
FIELDS = {"tendon_stiffness": mujoco.mjtObj.mjOBJ_TENDON,
          "actuator_gear": mujoco.mjtObj.mjOBJ_ACTUATOR,
          "dof_damping": mujoco.mjtObj.mjOBJ_JOINT,
          "dof_armature": mujoco.mjtObj.mjOBJ_JOINT,
          "dof_frictionloss": mujoco.mjtObj.mjOBJ_JOINT,
          "body_mass": mujoco.mjtObj.mjOBJ_BODY,
          "body_inertia": mujoco.mjtObj.mjOBJ_BODY}

#: fields holding a vector per element
VECTOR = {"body_inertia": 3}


def resolve(model: Any, spec: str, what: str = "field") -> tuple[str, int]:
    """``(field, row)`` of ``spec`` (``"dof_damping[hinge]"``, ``"opt.gravity"``) in
    ``model``.

    Parameters
    ----------
    model : mujoco.MjModel
    spec : str
    what : str
        How an error names the request (``"cannot estimate 'stiffness'"``).

    Returns
    -------
    tuple of (str, int)
        ``("gravity", 0)`` for ``opt.gravity``.

    Raises
    ------
    DesignError
        Not a known field, or no element of that name.

    Examples
    --------
    >>> from hgo_mj.systems import Pendulum
    >>> resolve(Pendulum.load_model(), "dof_damping[hinge]")
    ('dof_damping', 0)
    """
    if spec == "opt.gravity":
        if not np.linalg.norm(model.opt.gravity) > 0:
            raise DesignError(f"{what}: 'opt.gravity' needs a model with gravity")
        return ("gravity", 0)
    mt = re.fullmatch(r"(\w+)\[(\w+)\]", spec) if isinstance(spec, str) else None
    if mt is None or mt.group(1) not in FIELDS:
        raise DesignError(f"{what}: give a model field {sorted(FIELDS)}[element name] or "
                          f"'opt.gravity'; found {spec!r}")
    field, elem = mt.group(1), mt.group(2)
    i = mujoco.mj_name2id(model, FIELDS[field], elem)
    if i < 0:
        raise DesignError(f"{what}: the model has no {FIELDS[field].name[6:].lower()} named "
                          f"{elem!r}")
    if field.startswith("dof_"):
        i = int(model.jnt_dofadr[i])
    return (field, int(i))


def get_field(model: Any, field: str, i: int) -> Any:
    """The value at a resolved place.

    Parameters
    ----------
    model : mujoco.MjModel
    field, i
        As :func:`resolve` returns them.

    Returns
    -------
    float or ndarray
        An array for a vector field (``body_inertia``).

    Examples
    --------
    >>> from hgo_mj.systems import Pendulum
    >>> m = Pendulum.load_model()
    >>> get_field(m, *resolve(m, "body_mass[pole]"))
    0.25
    """
    if field == "gravity":
        return float(np.linalg.norm(model.opt.gravity))
    if field == "actuator_gear":
        return float(model.actuator_gear[i, 0])
    v = getattr(model, field)[i]
    return np.array(v, dtype=float) if field in VECTOR else float(v)


def set_field(model: Any, field: str, i: int, value: Any) -> None:
    """Write ``value`` at a resolved place, unchecked (the filters' hot path; :func:`set_fields`
    checks).

    Parameters
    ----------
    model : mujoco.MjModel
    field, i
        As :func:`resolve` returns them.
    value : float or array_like

    Examples
    --------
    >>> from hgo_mj.systems import Pendulum
    >>> m = Pendulum.load_model()
    >>> set_field(m, *resolve(m, "dof_damping[hinge]"), 0.05)
    >>> float(m.dof_damping[0])
    0.05
    """
    if field == "gravity":
        g = np.asarray(model.opt.gravity, dtype=float)
        g = g / np.linalg.norm(g) * value
        model.opt.gravity[0], model.opt.gravity[1], model.opt.gravity[2] = g[0], g[1], g[2]
    elif field == "actuator_gear":
        model.actuator_gear[i, 0] = value
    else:
        getattr(model, field)[i] = value


def set_fields(model: Any, values: Mapping[str, Any], aliases: Mapping[str, str] | None = None,
               what: str = "model_fields") -> None:
    """Write named values into ``model`` (in place), each checked before any is written: a
    finite number (non-negative, except for ``actuator_gear``), or three for ``body_inertia``.

    Parameters
    ----------
    model : mujoco.MjModel
    values : mapping
        ``"field[element]"`` (or an alias of one) -> value.
    aliases : mapping, optional
        Names that stand for a field (a system's ``kalman_fields`` form: ``stiffness`` ->
        ``tendon_stiffness[spring]``).
    what : str
        The argument's name in errors.

    Raises
    ------
    DesignError
        Not a mapping, an unknown field or element, a value of the wrong kind.

    Examples
    --------
    >>> from hgo_mj.systems import Pendulum
    >>> m = Pendulum.load_model()
    >>> set_fields(m, {"dof_frictionloss[hinge]": 0.02})
    >>> float(m.dof_frictionloss[0])
    0.02
    """
    if not isinstance(values, Mapping):
        raise DesignError(f"{what} must be a table of 'field[element]' = value; found "
                          f"{type(values).__name__}")
    al = dict(aliases or {})
    writes = []
    for key, v in values.items():
        field, i = resolve(model, al.get(key, key), f"{what} {key!r}")
        size = VECTOR.get(field)
        a = np.asarray(v) if not isinstance(v, (str, bytes)) else np.asarray([])
        ok = a.dtype.kind in "iuf" and a.shape == (() if size is None else (size,))
        if not ok or not np.all(np.isfinite(a)) or (field != "actuator_gear" and np.any(a < 0)):
            want = "a finite number >= 0" if size is None else f"{size} finite numbers >= 0"
            if field == "actuator_gear":
                want = "a finite number"
            raise DesignError(f"{what} {key!r} must be {want}; found {v!r}")
        writes.append((field, i, float(a) if size is None else a.astype(float)))
    for field, i, val in writes:
        if field == "gravity" and not (isinstance(val, float) and math.isfinite(val) and val > 0):
            raise DesignError(f"{what} 'opt.gravity' must be > 0; found {val!r}")
        set_field(model, field, i, val)
