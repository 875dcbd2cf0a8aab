"""Observers, one module per family. ``OBSERVERS`` maps registry names to classes; a family's
module is imported on first use (its name looked up in ``OBSERVERS``, its class imported from
here), so ``import hgo_mj.observers`` loads no family."""

from __future__ import annotations

import inspect
from typing import TYPE_CHECKING, Any

from .._registry import lazy_module
from .._validate import check_call, import_class
from ..exceptions import DesignError
from .base import FAMILIES, OBSERVERS, Observer, register, registered

if TYPE_CHECKING:  # imported on first use (module __getattr__), so a run loads its family only
    from .adaptive_gain import AdaptiveGainObserver
    from .bank import ObserverBank
    from .bastin_gevers import AOCF, BastinGeversObserver
    from .besancon import AffineForm, BesanconObserver
    from .extended_luenberger import ExtendedLuenbergerObserver
    from .finite_difference import FiniteDifferenceObserver
    from .high_gain import HighGainObserver, MultiOutputHighGainObserver
    from .jo_son import JoSonForm, JoSonObserver
    from .kalman import (
        ExtendedKalmanFilter,
        MujocoExtendedKalmanFilter,
        MujocoUnscentedKalmanFilter,
        UnscentedKalmanFilter,
    )
    from .kinematic_kalman import KinematicKalmanFilter
    from .mhe import MovingHorizonEstimator
    from .q_integral import QIntegralObserver
    from .riccati import RiccatiObserver
    from .super_twisting import SuperTwistingObserver

#: the classes this package exports that are not observer families
_OTHERS = ("hgo_mj.observers.bastin_gevers:AOCF", "hgo_mj.observers.besancon:AffineForm",
           "hgo_mj.observers.jo_son:JoSonForm", "hgo_mj.observers.bank:ObserverBank")


#: a class (``HighGainObserver``, ...) imported from its module on first use (PEP 562)
__getattr__, __dir__ = lazy_module(__name__, [*FAMILIES.values(), *_OTHERS])


def make_observer(kind: str, system: Any = None, **params: Any) -> Observer:
    """Build a registered observer by name (a family of this package, or one registered by
    another package through the entry-point group ``hgo_mj.observers``).

    Parameters
    ----------
    kind : str
        A key of :data:`OBSERVERS` (``"high_gain"``, ``"ekf"``, ...).
    system : System, optional
        The model the observer designs against (None for an order-only observer).
    **params
        The observer's constructor parameters.

    Returns
    -------
    Observer

    Raises
    ------
    DesignError
        An unknown name (the valid ones are listed), or a keyword the observer's constructor
        does not take (its valid keywords are listed).

    Examples
    --------
    >>> from hgo_mj.systems import SYSTEMS
    >>> obs = make_observer("riccati", SYSTEMS["pendulum"](), gamma=20.0)
    >>> type(obs).__name__, obs.state_names
    ('RiccatiObserver', ('angle', 'angular_velocity'))
    >>> make_observer("high_gian", None)
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: unknown observer 'high_gian'; valid: [...], or 'module:Class' ...)
    """
    known = registered()
    if isinstance(kind, str) and ":" in kind:  # the user's own Observer subclass
        cls = import_class("observer", kind, Observer)  # type: ignore[type-abstract]
    elif not isinstance(kind, str) or kind not in known:
        raise DesignError(f"unknown observer {kind!r}; valid: {sorted(known)}, or "
                          f"'module:Class' (an Observer subclass)")
    else:
        cls = known[kind]
    sig = inspect.signature(cls.__init__)
    if not any(p.kind is p.VAR_KEYWORD for p in sig.parameters.values()):
        valid = [p for p in sig.parameters if p not in ("self", "system")]
        bad = [k for k in params if k not in valid]
        if bad:
            raise DesignError(f"observer {kind!r}: unknown parameter(s) {bad}; valid: "
                              f"{sorted(valid)}")
    check_call(f"observer {kind!r}", cls.__init__, params, skip=1)
    return cls(system, **params)


__all__ = ["AOCF", "AffineForm", "BesanconObserver", "ExtendedKalmanFilter",
           "MujocoExtendedKalmanFilter", "MujocoUnscentedKalmanFilter", "UnscentedKalmanFilter",
           "OBSERVERS", "AdaptiveGainObserver", "BastinGeversObserver", "JoSonForm",
           "JoSonObserver", "HighGainObserver",
           "MultiOutputHighGainObserver", "Observer", "ObserverBank", "QIntegralObserver", "RiccatiObserver",
           "make_observer", "register", "registered",
           # baselines outside the papers (the benchmark issue, item 4)
           "ExtendedLuenbergerObserver", "FiniteDifferenceObserver", "KinematicKalmanFilter",
           "MovingHorizonEstimator", "SuperTwistingObserver"]
