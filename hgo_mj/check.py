"""Which observer applies to a system, and why (issue 12).

:func:`check` asks every registered observer family (:data:`hgo_mj.observers.OBSERVERS`) its
:meth:`~hgo_mj.observers.base.Observer.applicability` for a system: each family states its own
conditions next to its equations (the single-output normal form of paper 000, the chain
orders of paper 001's eq. 5, the linear parametrization of paper 001, the AOCF of paper 002, the
generalized observer canonical form of paper 003, an MJCF model for the MuJoCo filters).
``hgo-mj check PLANT-OR-SCENARIO`` prints the table; ``hgo-mj run`` refuses an observer that
does not apply with the same sentence.

Example
-------
>>> from hgo_mj import check
>>> from hgo_mj.plants import make_plant
>>> rows = {r.observer: r for r in check.check(make_plant("elastic_joint_2link").system)}
>>> rows["ekf"].applies, rows["high_gain"].applies
(True, False)
"""

from __future__ import annotations

from typing import Any, NamedTuple

from .exceptions import DesignError


class Applicability(NamedTuple):
    """One row of :func:`check`: the observer, whether it applies, and why not."""

    observer: str
    applies: bool
    reason: str


def check(system: Any) -> list[Applicability]:
    """One row per registered observer, in registry order.

    Raises
    ------
    DesignError
        ``system`` is not a :class:`~hgo_mj.systems.base.System` instance."""
    from .observers import registered
    from .systems.base import System

    if not isinstance(system, System):
        raise DesignError(f"check takes a System instance; found {type(system).__name__}")
    rows = []
    for name, cls in registered().items():
        reason = cls.applicability(system)
        rows.append(Applicability(name, reason is None, reason or ""))
    return rows


def table(system: Any) -> str:
    """:func:`check` as a text table, with the system's structural notes (the observability
    rank over the region and the Lipschitz bound of a derived system)."""
    rows = check(system)
    width = max(len(r.observer) for r in rows)
    lines = [f"{type(system).__name__}: {len(system.state_names)} states "
             f"{list(system.state_names)}, outputs {list(system.output_names)}, inputs "
             f"{list(system.input_names)}"]
    for note in ("rank_problem", "lipschitz"):
        value = getattr(system, note, None)
        if isinstance(value, str) or (isinstance(value, float) and value == value):
            lines.append(f"  {note}: {value}")
    lines.append("")
    for r in rows:
        lines.append(f"{r.observer:<{width}}  {'applies' if r.applies else 'no':<7}  {r.reason}")
    return "\n".join(lines)


def refuse_inapplicable(kind: str, system: Any, label: str) -> None:
    """Raise :class:`DesignError` if the registered observer ``kind`` does not apply to
    ``system`` (unknown kinds are left to :func:`hgo_mj.observers.make_observer`)."""
    from .observers import registered

    cls = registered().get(kind)
    reason = None if cls is None else cls.applicability(system)
    if reason:
        raise DesignError(f"observer {label!r} ({kind}) does not apply to "
                          f"{type(system).__name__}: {reason}")


__all__ = ["Applicability", "check", "refuse_inapplicable", "table"]
