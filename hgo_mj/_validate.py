"""Small validation helpers shared by the package (errors name what was expected and found)."""

from __future__ import annotations

import inspect
import math
import numbers
from collections.abc import Callable, Iterable, Mapping
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from .exceptions import DesignError, DimensionError

_T = TypeVar("_T")

#: the one rule of divergence: a state or estimate beyond this magnitude (or not finite) has
#: diverged. Below it an error's square (at most 4e200) summed over any run stays a float, so
#: no metric of a run that did not diverge overflows.
DIVERGED_ABOVE = 1e100


def diverged_rows(z: Any, x: Any = None) -> Any:
    """Per row of ``z`` ``(T, k)`` (and of ``x``, its ``x_hat``), whether it has diverged:
    an entry of ``z`` not finite or beyond :data:`DIVERGED_ABOVE` in magnitude, or one of
    ``x`` beyond it (a NaN ``x_hat``, an undefined inverse, is no divergence)."""
    with np.errstate(invalid="ignore"):
        bad = ~np.all(np.abs(z) <= DIVERGED_ABOVE, axis=-1)
        if x is not None:
            bad |= np.any(np.abs(x) > DIVERGED_ABOVE, axis=-1)
    return bad


def sum_is_finite(a: NDArray[np.float64]) -> bool:
    """Whether the sum of the float array ``a`` is finite: False where an entry is NaN or
    infinite (and where the sum overflows, so that a check refuses rather than passes). A few
    entries are summed in Python (a check at every reset: numpy's reduction costs more there).

    Examples
    --------
    >>> sum_is_finite(np.array([[0.5, 1.0]])), sum_is_finite(np.array([0.5, np.nan]))
    (True, False)
    """
    return math.isfinite(sum(a.flat) if a.size <= 16 else a.sum())


def is_real(value: Any) -> bool:
    """Whether ``value`` is a real number: an int, a float, a numpy integer or float, or a 0-d
    array of one. A bool, a string and anything else are not (types are checked, not coerced)."""
    if isinstance(value, (bool, np.bool_)):
        return False
    if isinstance(value, np.ndarray):
        return value.ndim == 0 and value.dtype.kind in "iuf"
    return isinstance(value, numbers.Real)


def finite_scalar(name: str, value: Any, *, positive: bool = False,
                  nonnegative: bool = False) -> float:
    """Return ``value`` as a float, raising :class:`DesignError` unless a finite real number
    (signed as asked); a bool or a string such as ``"1"`` is refused, not converted."""
    if not is_real(value):
        raise DesignError(f"{name} must be a real number; found {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise DesignError(f"{name} must be a real number; found {value!r}") from None
    if not math.isfinite(v):
        raise DesignError(f"{name} must be finite; found {v}")
    if positive and not v > 0:
        raise DesignError(f"{name} must be > 0; found {v}")
    if nonnegative and v < 0:
        raise DesignError(f"{name} must be >= 0; found {v}")
    return v


def numbers_only(value: Any) -> bool:
    """Whether an array-like holds only real numbers (no bool, string or other object)."""
    if isinstance(value, np.ndarray):
        return value.dtype.kind in "iuf"
    if isinstance(value, (list, tuple)):
        return all(numbers_only(v) for v in value)
    return is_real(value)


def vector(name: str, value: Any, n: int | None = None, *, finite: bool = True) -> NDArray[np.float64]:
    """Return ``value`` as a fresh 1-D float array of length ``n`` (if given); its entries must
    be real numbers (a bool or a string is refused, not converted)."""
    if not numbers_only(value):
        raise DimensionError(f"{name} must be a 1-D array of numbers; found {value!r}")
    try:
        a = np.array(value, dtype=float).reshape(-1) if np.ndim(value) <= 1 else None
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a 1-D array of numbers; found {value!r}") from None
    if a is None:
        raise DimensionError(f"{name} must be 1-D; found shape {np.shape(value)}")
    if n is not None and a.shape != (n,):
        raise DimensionError(f"{name} must have length {n}; found length {a.size}")
    if finite and not np.isfinite(a).all():
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


def symmetric_matrix(name: str, value: Any, m: int, *, semidefinite: bool = False,
                     dim: str | None = None) -> NDArray[np.float64]:
    """``value`` as a fresh ``m x m`` symmetric positive definite (or, with ``semidefinite``,
    semi-definite) matrix: a scalar ``g`` gives ``g I``, a vector of length ``m`` its diagonal.

    ``dim`` names ``m`` in the length message (``"length m = 3"``).

    Raises
    ------
    DimensionError
        Neither a scalar, an ``(m,)`` vector nor an ``(m, m)`` matrix.
    DesignError
        Not numbers (a string included), not finite, not symmetric, or an eigenvalue not
        positive (not negative, for ``semidefinite``); the eigenvalues are listed.
    """
    try:
        if isinstance(value, str):
            raise ValueError(value)
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise DesignError(f"{name} must be a number, a vector or a matrix; found {value!r}") from None
    if a.ndim == 0:
        a = a * np.eye(m)
    elif a.ndim == 1:
        if a.shape != (m,):
            raise DimensionError(f"{name} as a vector must have length "
                                 f"{f'{dim} = ' if dim else ''}{m} (its diagonal); found length "
                                 f"{a.size}")
        a = np.diag(a)
    elif a.shape != (m, m):
        raise DimensionError(f"{name} must be a scalar, a length-{m} vector or a {m}x{m} "
                             f"matrix; found shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise DesignError(f"{name} must be finite; found {a.tolist()}")
    if not m:
        return a
    asym = float(np.max(np.abs(a - a.T)))
    if asym > 1e-12 * max(1.0, float(np.max(np.abs(a)))):
        raise DesignError(f"{name} must be symmetric; found max |{name} - {name}^T| = {asym:.3g}")
    eig = np.linalg.eigvalsh(a)
    shown = [float(f"{e:.6g}") for e in eig]
    if semidefinite:
        if eig[0] < -1e-12 * max(1.0, float(eig[-1])):
            raise DesignError(f"{name} must be positive semi-definite; found eigenvalues {shown} "
                              f"(some < 0)")
    elif not eig[0] > 0:
        raise DesignError(f"{name} must be positive definite; found eigenvalues {shown} "
                          f"(not all > 0)")
    return a


def positive_definite(name: str, value: Any, m: int) -> NDArray[np.float64]:
    """:func:`symmetric_matrix`, positive definite."""
    return symmetric_matrix(name, value, m)


def positive_semidefinite(name: str, value: Any, m: int) -> NDArray[np.float64]:
    """:func:`symmetric_matrix`, positive semi-definite."""
    return symmetric_matrix(name, value, m, semidefinite=True)


def one_of(name: str, value: Any, options: Iterable[Any]) -> Any:
    """Return ``value``, raising :class:`DesignError` unless it is one of ``options``."""
    options = list(options)
    if value not in options:
        raise DesignError(f"{name} must be one of {options}; found {value!r}")
    return value


def positive_int(name: str, value: Any, *, floats: bool = True) -> int:
    """Return ``value`` as an int, raising :class:`DesignError` unless a positive whole number
    (``True`` is not one). ``floats=False`` also refuses a whole float such as ``2.0`` (a count
    read from a file or given to the API, which must be written as an integer)."""
    try:
        ok = (not isinstance(value, bool) and int(value) == value and value >= 1
              and (floats or isinstance(value, (int, np.integer))))
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok:
        raise DesignError(f"{name} must be a positive integer; found {value!r}")
    return int(value)


def integer_multiple(name: str, period: float, base: float, base_name: str) -> int:
    """``period / base`` as a positive integer, or a :class:`DesignError` naming both periods
    (a sample or control period must be a whole number of physics steps)."""
    ratio = period / base
    n = round(ratio)
    if n < 1 or abs(ratio - n) > 1e-9 * max(1.0, ratio):
        raise DesignError(f"{name} = {period:g} must be a positive integer multiple of {base_name} "
                          f"= {base:g}; found ratio {ratio:.9g}")
    return n


def boolean(name: str, value: Any) -> bool:
    """Return ``value``, raising :class:`DesignError` unless it is ``True`` or ``False`` (a
    string such as ``"no"`` or a number is refused, not converted)."""
    if not isinstance(value, (bool, np.bool_)):
        raise DesignError(f"{name} must be true or false; found {value!r}")
    return bool(value)


def text(name: str, value: Any) -> str:
    """Return ``value``, raising :class:`DesignError` unless it is a string."""
    if not isinstance(value, str):
        raise DesignError(f"{name} must be a string; found {value!r}")
    return value


def check_call(where: str, fn: Callable[..., Any], params: Mapping[str, Any],
               skip: int = 0) -> None:
    """Raise :class:`DesignError` unless ``fn(<skip positional>, **params)`` binds: an unknown
    keyword (the valid ones listed) or a missing required parameter is named, before ``fn``
    runs (so that no ``TypeError`` escapes a constructor called with a user's table)."""
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):  # a builtin without a signature: let the call decide
        return
    ps = list(sig.parameters.values())
    if ps and ps[0].name == "self":
        ps = ps[1:]
    ps = ps[skip:]
    if not any(p.kind is p.VAR_KEYWORD for p in ps):
        reject_unknown(where, params, [p.name for p in ps if p.kind is not p.VAR_POSITIONAL])
    missing = [p.name for p in ps if p.default is p.empty and p.name not in params
               and p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD)]
    if missing:
        raise DesignError(f"{where}: missing required parameter(s) {missing}")


def import_class(what: str, spec: Any, base: type[_T]) -> type[_T]:
    """The class named by ``spec`` = ``"module:Class"`` (``module`` importable from
    ``sys.path`` or the current folder), checked to subclass ``base``; every failure is one
    :class:`DesignError` line naming ``what``, the spec and the cause (a module that does not
    import gives its exception's first line)."""
    import importlib
    import os
    import sys

    if not isinstance(spec, str) or spec.count(":") != 1:
        raise DesignError(f"{what} must be a registered name or 'module:Class'; found {spec!r}")
    module, attr = spec.split(":")
    if not all(p.isidentifier() for p in module.split(".")) or not all(
            p.isidentifier() for p in attr.split(".")):
        raise DesignError(f"{what} {spec!r} must be 'module:Class' (dotted Python names)")
    here = os.getcwd()
    added = here not in sys.path
    if added:
        sys.path.append(here)
    try:
        mod = importlib.import_module(module)
    except SystemExit as exc:  # sys.exit() at import would end the run silently
        sys.modules.pop(module, None)
        raise DesignError(f"{what} {spec!r}: module {module!r} called sys.exit({exc.code!r}) "
                          f"while it was imported; a module a scenario names must define the "
                          f"class, not end the program") from None
    except Exception as exc:  # noqa: BLE001 - any failure of user code is reported, one line
        first = (str(exc).strip().splitlines() or [""])[0]
        raise DesignError(f"{what} {spec!r}: module {module!r} does not import "
                          f"({type(exc).__name__}: {first})") from None
    finally:
        if added:
            sys.path.remove(here)
    obj: Any = mod
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise DesignError(f"{what} {spec!r}: module {module!r} has no {attr!r}")
        obj = getattr(obj, part)
    if not (isinstance(obj, type) and issubclass(obj, base)):
        raise DesignError(f"{what} {spec!r} must name a subclass of {base.__name__}; found "
                          f"{obj!r}")
    return obj
