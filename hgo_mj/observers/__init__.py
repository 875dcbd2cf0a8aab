"""Observers, one module per family. ``OBSERVERS`` maps registry names to classes."""

from __future__ import annotations

from typing import Any

from ..exceptions import DesignError
from .adaptive_gain import AdaptiveGainObserver
from .bank import ObserverBank
from .base import Observer, register
from .bastin_gevers import AOCF, BastinGeversObserver
from .besancon import AffineForm, BesanconObserver
from .high_gain import HighGainObserver, MultiOutputHighGainObserver
from .jo_son import JoSonForm, JoSonObserver
from .kalman import (
    ExtendedKalmanFilter,
    MujocoExtendedKalmanFilter,
    MujocoUnscentedKalmanFilter,
    UnscentedKalmanFilter,
)
from .q_integral import QIntegralObserver
from .riccati import RiccatiObserver

OBSERVERS: dict[str, type[Observer]] = {
    HighGainObserver.name: HighGainObserver,
    "adaptive_gain": AdaptiveGainObserver,
    "high_gain_multi": MultiOutputHighGainObserver,
    "riccati": RiccatiObserver,
    "q_integral": QIntegralObserver,
    "bastin_gevers": BastinGeversObserver,
    "jo_son": JoSonObserver,
    "besancon": BesanconObserver,
    "ekf": ExtendedKalmanFilter,
    "ukf": UnscentedKalmanFilter,
    "ekf_mujoco": MujocoExtendedKalmanFilter,
    "ukf_mujoco": MujocoUnscentedKalmanFilter,
}


def make_observer(kind: str, system: Any = None, **params: Any) -> Observer:
    """Build a registered observer by name; unknown names list the valid ones."""
    if kind not in OBSERVERS:
        raise DesignError(f"unknown observer {kind!r}; valid: {sorted(OBSERVERS)}")
    try:
        return OBSERVERS[kind](system, **params)
    except TypeError as exc:  # unknown keyword
        raise DesignError(f"observer {kind!r}: {exc}") from None


__all__ = ["AOCF", "AffineForm", "BesanconObserver", "ExtendedKalmanFilter",
           "MujocoExtendedKalmanFilter", "MujocoUnscentedKalmanFilter", "UnscentedKalmanFilter",
           "OBSERVERS", "AdaptiveGainObserver", "BastinGeversObserver", "JoSonForm",
           "JoSonObserver", "HighGainObserver",
           "MultiOutputHighGainObserver", "Observer", "ObserverBank", "QIntegralObserver", "RiccatiObserver",
           "make_observer", "register"]
