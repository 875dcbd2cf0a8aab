"""Observers, one module per family. ``OBSERVERS`` maps registry names to classes."""

from __future__ import annotations

from typing import Any

from ..exceptions import DesignError
from .base import Observer
from .high_gain import HighGainObserver

OBSERVERS: dict[str, type[Observer]] = {
    HighGainObserver.name: HighGainObserver,
}


def make_observer(kind: str, system: Any = None, **params: Any) -> Observer:
    """Build a registered observer by name; unknown names list the valid ones."""
    if kind not in OBSERVERS:
        raise DesignError(f"unknown observer {kind!r}; valid: {sorted(OBSERVERS)}")
    try:
        return OBSERVERS[kind](system, **params)
    except TypeError as exc:  # unknown keyword
        raise DesignError(f"observer {kind!r}: {exc}") from None


__all__ = ["OBSERVERS", "HighGainObserver", "Observer", "make_observer"]
