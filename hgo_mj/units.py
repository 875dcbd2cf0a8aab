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
    """The registered system class of a trajectory's plant (by its metadata), or ``None``."""
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
    """``"[rad]"``; ``"[-]"`` for a dimensionless quantity, ``"[?]"`` for an unknown unit."""
    return "[?]" if unit is None else f"[{unit or '-'}]"


def per_time(unit: str, order: int, time_unit: str = "s") -> str:
    """The unit of the ``order``-th time derivative of a quantity in ``unit``
    (``per_time("rad", 2)`` is ``"rad/s^2"``; a dimensionless time gives ``unit`` back)."""
    if order == 0 or not time_unit:
        return unit
    tail = time_unit if order == 1 else f"{time_unit}^{order}"
    return f"{unit}/{tail}" if unit else f"1/{tail}"


def system_units(cls: Any, output_names: tuple[str, ...] | list[str] = ()) -> dict[str, str]:
    """``{name: unit}`` for a system class: its states, its inputs, and the derivatives of its
    outputs named as an observer names them (``link1_acceleration``: ``rad/s^2``; an observer
    without a system calls output ``i``'s derivatives ``y<i>_d<j>``). ``output_names``
    defaults to the system's. Names whose unit is not declared are missing."""
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
    system is not known (a trajectory without the ``plant`` metadata)."""
    cls = system_of(traj)
    if cls is None:
        return {}, None
    return system_units(cls, tuple(traj.output_names)), cls.time_unit


__all__ = ["bracket", "per_time", "system_of", "system_units", "units_of"]
