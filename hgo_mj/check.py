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

from .exceptions import DesignError, MissingExtraError


class Applicability(NamedTuple):
    """One row of :func:`check`: the observer, whether it applies, why not, and a note on a
    guarantee that does not hold although the observer runs (the sample period against
    paper 004's LMI bound).

    Parameters
    ----------
    observer : str
        The registered observer family.
    applies : bool
        Whether it can be designed against the system.
    reason : str
        Why not, in the paper's terms (empty where it applies).
    note : str
        Where it applies: a condition of its paper checked against the run (empty if none).

    Examples
    --------
    >>> Applicability("ekf", True, "")
    Applicability(observer='ekf', applies=True, reason='', note='')
    """

    observer: str
    applies: bool
    reason: str
    note: str = ""


def check(system: Any, sample_period: float | None = None) -> list[Applicability]:
    """One row per registered observer, in registry order.

    Parameters
    ----------
    system : System
        The system the observers would design against.
    sample_period : float, optional
        The run's sample period [s]: checked against the LMI bound of paper 004 (Theorem 2,
        LMI (63)/(65)) for the Riccati observer where the system states a Lipschitz bound of
        ``phi`` (a derived system does, :attr:`SymbolicSystem.lipschitz`).

    Returns
    -------
    list of Applicability

    Raises
    ------
    DesignError
        ``system`` is not a :class:`~hgo_mj.systems.base.System` instance, or
        ``sample_period`` is not a positive number.

    Examples
    --------
    >>> from hgo_mj.plants import make_plant
    >>> rows = check(make_plant("pendulum").system)
    >>> [r.observer for r in rows if not r.applies]
    ['jo_son']
    """
    from ._validate import finite_scalar
    from .observers import registered
    from .systems.base import System

    if not isinstance(system, System):
        raise DesignError(f"check takes a System instance; found {type(system).__name__}")
    if sample_period is not None:
        sample_period = finite_scalar("sample_period", sample_period, positive=True)
    rows = []
    for name, cls in registered().items():
        reason = cls.applicability(system)
        note = "" if reason or name != "riccati" else sampling_note(system, sample_period)
        rows.append(Applicability(name, reason is None, reason or "", note))
    return rows


def sampling_note(system: Any, sample_period: float | None) -> str:
    """The sample period against the largest period LMI (63)/(65) of paper 004 certifies for
    the Euler-sampled Riccati observer (Theorem 2) with ``alpha`` the binomial coefficients,
    ``gamma = min_gamma(alpha, rho)`` and the Lipschitz structure of a scalar ``phi``:
    ``B dphi/dz = M F N`` with ``M = rho e_n``, ``N = I``, ``|F| < 1`` (eq. 55).

    Parameters
    ----------
    system : System
        A system with a normal form; its ``lipschitz`` attribute is ``rho``.
    sample_period : float or None
        The run's sample period [s] (None: no note).

    Returns
    -------
    str
        One sentence (empty without a period or a finite Lipschitz bound).

    Examples
    --------
    >>> from hgo_mj.systems.symbolic import ode_system
    >>> cls = ode_system(["x1", "x2"], ["x2", "-9.81*sin(x1)"], "x1")
    >>> print(sampling_note(cls(), 0.001))
    sample period 0.001 s is within the bound delta_max = 0.0133 s of paper 004 ...
    """
    import numpy as np

    from .design import binomial_coefficients, max_sampling_period, min_gamma

    rho = getattr(system, "lipschitz", float("nan"))
    n = system.normal_form_order
    if sample_period is None or n is None or not np.isfinite(rho) or rho <= 0:
        return ""
    alpha = binomial_coefficients(n)
    gamma = min_gamma(alpha, rho)
    M = np.zeros((n, 1))
    M[-1, 0] = rho
    try:
        bound = max_sampling_period(alpha, gamma, M, np.eye(n))["delta_max"]
    except DesignError as exc:
        return f"the LMI (63) of paper 004 has no solution here ({exc})"
    except MissingExtraError as exc:
        return f"no sampling bound: {exc}"
    where = (f"the bound delta_max = {bound:.3g} s of paper 004 (Theorem 2, LMI (63)/(65)) "
             f"for gamma = min_gamma = {gamma:.3g}, Lipschitz rho = {rho:.3g}")
    if sample_period <= bound:
        return f"sample period {sample_period:g} s is within {where}"
    return (f"sample period {sample_period:g} s exceeds {where}: convergence of the sampled "
            f"observer is not certified (the bound is sufficient, not necessary)")


def table(system: Any, sample_period: float | None = None) -> str:
    """:func:`check` as a text table, with the system's structural notes (the observability
    rank over the region, the Lipschitz bound and the held-input note of a derived system).

    Parameters
    ----------
    system : System
        As for :func:`check`.
    sample_period : float, optional
        As for :func:`check`.

    Returns
    -------
    str
        A header line, the notes, then one line per observer.

    Examples
    --------
    >>> from hgo_mj.plants import make_plant
    >>> print(table(make_plant("pendulum").system).splitlines()[0])
    Pendulum: 2 states ['angle', 'angular_velocity'], outputs ['angle'], inputs ['torque']
    """
    rows = check(system, sample_period)
    width = max(len(r.observer) for r in rows)
    lines = [f"{type(system).__name__}: {len(system.state_names)} states "
             f"{list(system.state_names)}, outputs {list(system.output_names)}, inputs "
             f"{list(system.input_names)}"]
    for note in ("rank_problem", "lipschitz", "normal_form_note"):
        value = getattr(system, note, None)
        if isinstance(value, str) or (isinstance(value, float) and value == value):
            lines.append(f"  {note}: {value}")
    lines.append("")
    for r in rows:
        lines.append(f"{r.observer:<{width}}  {'applies' if r.applies else 'no':<7}  "
                     f"{r.reason or r.note}".rstrip())
    return "\n".join(lines)


def refuse_inapplicable(kind: str, system: Any, label: str) -> None:
    """Raise :class:`DesignError` if the registered observer ``kind`` does not apply to
    ``system`` (unknown kinds are left to :func:`hgo_mj.observers.make_observer`).

    Parameters
    ----------
    kind : str
        A registered observer family.
    system : System
        The system it would design against.
    label : str
        The observer's name in the run, for the message.

    Returns
    -------
    None

    Raises
    ------
    DesignError
        The family does not apply; the message is its reason.

    Examples
    --------
    >>> from hgo_mj.plants import make_plant
    >>> refuse_inapplicable("ekf", make_plant("pendulum").system, "ekf_0")
    """
    from ._validate import import_class
    from .observers import Observer, registered

    cls = (import_class("observer", kind, Observer) if isinstance(kind, str) and ":" in kind  # type: ignore[type-abstract]
           else registered().get(kind))
    reason = None if cls is None else cls.applicability(system)
    if reason:
        raise DesignError(f"observer {label!r} ({kind}) does not apply to "
                          f"{type(system).__name__}: {reason}")


__all__ = ["Applicability", "check", "refuse_inapplicable", "sampling_note", "table"]
