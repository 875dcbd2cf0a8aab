"""Helpers shared by the adaptive observers and the Kalman filters (not public)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from ..exceptions import DivergenceError
from .base import Observer

__all__ = ["measured_channels"]

_INF = (math.inf, -math.inf)


def measured_channels(ob: Observer, y: Any, outputs: Sequence[int]) -> list[float]:
    """The channels ``outputs`` of the measurement ``y`` as plain floats, ``nan`` where a
    channel is lost (a dropout: the sample is counted once in ``ob.dropouts_``).

    Plain-float loop, no numpy per sample (the observers' hot path).

    Raises
    ------
    DimensionError
        ``y`` lacks a channel (``ob._bad_measurement``).
    DivergenceError
        A channel is infinite.
    """
    try:
        vals = [float(y[o]) for o in outputs]
    except (IndexError, TypeError):
        raise ob._bad_measurement(y, list(outputs)) from None
    lost = False
    for o, v in zip(outputs, vals):
        if v != v:
            lost = True
        elif v in _INF:
            raise DivergenceError(f"measurement y[{o}] is {v}")
    if lost:
        ob.dropouts_ += 1
    return vals
