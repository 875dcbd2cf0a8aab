"""Small validation helpers shared by the package (errors name what was expected and found)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .exceptions import DesignError, DimensionError


def finite_scalar(name: str, value: Any, *, positive: bool = False,
                  nonnegative: bool = False) -> float:
    """Return ``value`` as a float, raising :class:`DesignError` unless finite (and signed as asked)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise DesignError(f"{name} must be a real number; found {value!r}") from None
    if not math.isfinite(v):
        raise DesignError(f"{name} must be finite; found {v}")
    if positive and not v > 0:
        raise DesignError(f"{name} must be > 0; found {v}")
    if nonnegative and v < 0:
        raise DesignError(f"{name} must be >= 0; found {v}")
    return v


def vector(name: str, value: Any, n: int | None = None, *, finite: bool = True) -> NDArray[np.float64]:
    """Return ``value`` as a fresh 1-D float array of length ``n`` (if given)."""
    try:
        a = np.array(value, dtype=float).reshape(-1) if np.ndim(value) <= 1 else None
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a 1-D array of numbers; found {value!r}") from None
    if a is None:
        raise DimensionError(f"{name} must be 1-D; found shape {np.shape(value)}")
    if n is not None and a.shape != (n,):
        raise DimensionError(f"{name} must have length {n}; found length {a.size}")
    if finite and not np.all(np.isfinite(a)):
        raise DesignError(f"{name} must be finite; found {a.tolist()}")
    return a


def reject_unknown(where: str, given: Iterable[str], known: Iterable[str]) -> None:
    """Raise :class:`DesignError` for keyword names not in ``known``, listing the valid ones."""
    known = list(known)
    bad = [k for k in given if k not in known]
    if bad:
        raise DesignError(f"{where}: unknown parameter(s) {bad}; valid: {sorted(known)}")


def check_params(where: str, params: Mapping[str, Any], required: Iterable[str]) -> dict[str, float]:
    """Validate a parameter mapping: exactly the ``required`` names, each a finite float."""
    required = list(required)
    reject_unknown(where, params, required)
    missing = [k for k in required if k not in params]
    if missing:
        raise DesignError(f"{where}: missing parameter(s) {missing}")
    return {k: finite_scalar(f"{where}.{k}", params[k]) for k in required}
