"""Units of a run's quantities, as its plant's system declares them.

Every system declares the unit of each state (:attr:`~hgo_mj.systems.base.System.state_units`),
of each input (:attr:`~hgo_mj.systems.base.System.input_units`) and of time
(:attr:`~hgo_mj.systems.base.System.time_unit`). An empty string is a dimensionless quantity
(or one whose unit the paper does not give); the derivatives of an output get the output's
unit per time unit (``rad/s^2``). The figures (:mod:`hgo_mj.plotting`), the tidy tables
(:meth:`hgo_mj.simulate.Trajectory.to_arrow`) and the recordings (:mod:`hgo_mj.record`) read
their units here.
"""

from __future__ import annotations

from typing import Any


def system_of(traj: Any) -> Any:
    """The registered system class of a trajectory's plant (by its metadata), or ``None``.

    Parameters
    ----------
    traj : Trajectory
        A run whose ``metadata["plant"]`` names the plant's system (its class name or its
        :data:`~hgo_mj.systems.SYSTEMS` key), or whose metadata describes an MJCF system.

    Returns
    -------
    type or None
        The :class:`~hgo_mj.systems.base.System` subclass (for an MJCF plant, the class built
        from its model file); ``None`` when no system matches.

    Examples
    --------
    >>> from hgo_mj.inputs import Constant
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.simulate import simulate
    >>> traj = simulate(make_plant("pendulum", 0.01), None, {}, Constant(0.0), duration=0.02)
    >>> system_of(traj).__name__
    'Pendulum'
    >>> traj.metadata.pop("plant")
    'Pendulum'
    >>> system_of(traj) is None
    True
    """
    from .systems import SYSTEMS
    from .systems.mjcf import system_from_metadata

    mjcf = system_from_metadata(traj.metadata)
    if mjcf is not None:
        return mjcf
    plant = str(traj.metadata.get("plant", ""))
    for cls in SYSTEMS.values():
        if plant in (cls.__name__, cls.name):
            return cls
    return None


def bracket(unit: str | None) -> str:
    """``"[rad]"``; ``"[-]"`` for a dimensionless quantity, ``"[?]"`` for an unknown unit.

    Parameters
    ----------
    unit : str or None
        A unit (``""``: dimensionless; ``None``: not known).

    Returns
    -------
    str
        The unit in brackets, for an axis label.

    Examples
    --------
    >>> bracket("rad"), bracket(""), bracket(None)
    ('[rad]', '[-]', '[?]')
    """
    return "[?]" if unit is None else f"[{unit or '-'}]"


def per_time(unit: str, order: int, time_unit: str = "s") -> str:
    """The unit of the ``order``-th time derivative of a quantity in ``unit``
    (``per_time("rad", 2)`` is ``"rad/s^2"``; a dimensionless time gives ``unit`` back).

    Parameters
    ----------
    unit : str
        The quantity's unit (``""``: dimensionless).
    order : int
        The order of the derivative (0: the quantity itself).
    time_unit : str
        The unit of time (``System.time_unit``; ``""``: dimensionless time).

    Returns
    -------
    str
        ``unit/time_unit^order`` (``1/...`` for a dimensionless quantity).

    Examples
    --------
    >>> per_time("rad", 2), per_time("m", 1), per_time("", 1, "h"), per_time("rad", 3, "")
    ('rad/s^2', 'm/s', '1/h', 'rad')
    """
    if order == 0 or not time_unit:
        return unit
    tail = time_unit if order == 1 else f"{time_unit}^{order}"
    return f"{unit}/{tail}" if unit else f"1/{tail}"


def system_units(cls: Any, output_names: tuple[str, ...] | list[str] = ()) -> dict[str, str]:
    """``{name: unit}`` for a system class: its states, its inputs, and the derivatives of its
    outputs named as an observer names them (``link1_acceleration``: ``rad/s^2``; an observer
    without a system calls output ``i``'s derivatives ``y<i>_d<j>``). ``output_names``
    defaults to the system's. Names whose unit is not declared are missing.

    Parameters
    ----------
    cls : type
        A :class:`~hgo_mj.systems.base.System` subclass (``type(plant.system)``).
    output_names : sequence of str
        The plant's output names (``plant.output_names``); default the system's.

    Returns
    -------
    dict of str to str
        ``{name: unit}`` of the states, the inputs and the output derivatives up to order 5
        (under their own names and ``y<i>_d<j>``).

    Examples
    --------
    >>> from hgo_mj.systems import SYSTEMS
    >>> units = system_units(SYSTEMS["pendulum"])
    >>> units["angle"], units["torque"], units["angular_acceleration"], units["y1_d2"]
    ('rad', 'N m', 'rad/s^2', 'rad/s^2')
    """
    from .observers.high_gain import derivative_names

    units: dict[str, str] = {}
    if len(cls.state_units) == len(cls.state_names):
        units.update(zip(cls.state_names, cls.state_units))
    if len(cls.input_units) == len(cls.input_names):
        for name, unit in zip(cls.input_names, cls.input_units):
            units.setdefault(name, unit)
    for i, out in enumerate(output_names or cls.output_names):
        if out not in units:
            continue
        for alias in (out, f"y{i + 1}"):
            for j, name in enumerate(derivative_names(alias, 6)):
                units.setdefault(name, per_time(units[out], j, cls.time_unit))
    return units


def units_of(traj: Any) -> tuple[dict[str, str], str | None]:
    """The units the plant's system declares for a trajectory: ``({name: unit}, time unit)``
    (:func:`system_units` with the trajectory's output names). ``({}, None)`` when the plant's
    system is not known (a trajectory without the ``plant`` metadata).

    Parameters
    ----------
    traj : Trajectory
        A run of :func:`hgo_mj.simulate.simulate` (its metadata names the plant).

    Returns
    -------
    units : dict of str to str
        ``{name: unit}`` as :func:`system_units`.
    time_unit : str or None
        The system's time unit (``"s"``, ``"h"``); ``None`` when the system is not known.

    Examples
    --------
    >>> from hgo_mj.inputs import Constant
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.simulate import simulate
    >>> traj = simulate(make_plant("pendulum", 0.01), None, {}, Constant(0.0), duration=0.02)
    >>> units, t_unit = units_of(traj)
    >>> units["angular_velocity"], t_unit
    ('rad/s', 's')
    """
    cls = system_of(traj)
    if cls is None:
        return {}, None
    return system_units(cls, tuple(traj.output_names)), cls.time_unit


__all__ = ["bracket", "per_time", "system_of", "system_units", "units_of"]
