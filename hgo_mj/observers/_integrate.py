"""Euler, Heun and classical RK4, written once for every observer family.

Two forms of the same three schemes, with the same arithmetic (so that a family may move from
one to the other without changing a bit):

* over the batch in numpy, :func:`euler`, :func:`heun`, :func:`rk4`: ``f(z) -> dz`` takes and
  returns ``(B, n)`` arrays (any shape, in fact: the schemes are elementwise);
* inside numba kernels, :func:`euler_step`, :func:`heun_step`, :func:`rk4_step` on one state
  (a 1-D array), ``f`` a jitted right-hand side ``f(v, args, out)`` that writes ``dv/dt`` into
  ``out``, ``args`` a tuple of its other arguments (numba's first-class dispatcher argument).
  These are ``inline="always"``: inlined into the calling kernel, ``f`` is a plain call of a
  global function there, so that the kernel keeps ``cache=True`` (not inlined, a function
  argument makes numba refuse to cache the caller: "uses dynamic globals"); ``f`` is called
  with ``args`` as one tuple, not ``*args``, because numba cannot inline a call with ``*args``
  into an ``inline="always"`` right-hand side. They are built on the stage helpers
  :func:`axpy` (a stage state, ``s + a k``) and :func:`rk4_sum` / :func:`heun_sum` (the step).

The arithmetic, identical in both forms (``h`` the step):

* Euler: ``s + h k1``;
* Heun: ``k2 = f(s + h k1)``, ``s + h/2 (k1 + k2)``;
* RK4: ``k2 = f(s + (h/2) k1)``, ``k3 = f(s + (h/2) k2)``, ``k4 = f(s + h k3)``, then
  ``s + (h/6) (k1 + 2 (k2 + k3) + k4)``, summed in that grouping.

The families that integrate with a Butcher table (Besançon's fused stage kernel) or through
the exact Taylor polynomial of a linear map (:func:`~hgo_mj.observers.high_gain.taylor_step`)
keep their own form: see the module docstrings there.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit

Array = np.ndarray

__all__ = ["axpy", "euler", "euler_step", "heun", "heun_step", "heun_sum", "rk4", "rk4_step",
           "rk4_sum"]


# ------------------------------------------------------------------ numpy, over the batch
def euler(f: Callable[[Array], Array], z: Array, dt: float) -> Array:
    """One forward-Euler step ``z + dt f(z)`` of ``z' = f(z)`` over a batch.

    Parameters
    ----------
    f : callable
        ``f(z) -> dz/dt``, an array of ``z``'s shape (``(B, n)``: one row per member).
    z : ndarray
        The state at the start of the step (not modified).
    dt : float
        The step.

    Returns
    -------
    ndarray
        The state after the step (a new array).

    Examples
    --------
    >>> import numpy as np
    >>> euler(lambda z: -z, np.array([[1.0, 2.0]]), 0.1)
    array([[0.9, 1.8]])
    """
    return z + dt * f(z)


def heun(f: Callable[[Array], Array], z: Array, dt: float) -> Array:
    """One step of Heun's method (explicit trapezoid, RK2) of ``z' = f(z)`` over a batch:
    ``k1 = f(z)``, ``k2 = f(z + dt k1)``, ``z + dt/2 (k1 + k2)``.

    Parameters
    ----------
    f : callable
        ``f(z) -> dz/dt``, an array of ``z``'s shape.
    z : ndarray
        The state at the start of the step (not modified).
    dt : float
        The step.

    Returns
    -------
    ndarray
        The state after the step (a new array).

    Examples
    --------
    >>> import numpy as np
    >>> heun(lambda z: -z, np.array([[1.0]]), 0.1)  # 1 - h + h^2/2
    array([[0.905]])
    """
    k1 = f(z)
    k2 = f(z + dt * k1)
    return z + dt / 2 * (k1 + k2)


def rk4(f: Callable[[Array], Array], z: Array, dt: float) -> Array:
    """One step of classical RK4 of ``z' = f(z)`` over a batch:
    ``z + (dt/6) (k1 + 2 (k2 + k3) + k4)`` (stage states ``z + (dt/2) k1``, ``z + (dt/2) k2``,
    ``z + dt k3``), the arithmetic of :func:`rk4_step` and :func:`rk4_sum`.

    ``f`` is called on ``z`` itself first (a right-hand side may recognise the start of the
    step by identity, ``v is z``, to reuse what it computed there).

    Parameters
    ----------
    f : callable
        ``f(z) -> dz/dt``, an array of ``z``'s shape.
    z : ndarray
        The state at the start of the step (not modified).
    dt : float
        The step.

    Returns
    -------
    ndarray
        The state after the step (a new array).

    Examples
    --------
    >>> import numpy as np
    >>> rk4(lambda z: -z, np.array([[1.0]]), 0.1).round(7)  # 1 - h + h^2/2 - h^3/6 + h^4/24
    array([[0.9048375]])
    """
    k1 = f(z)
    k2 = f(z + dt / 2 * k1)
    k3 = f(z + dt / 2 * k2)
    k4 = f(z + dt * k3)
    return z + dt / 6 * (k1 + 2.0 * (k2 + k3) + k4)


# ------------------------------------------------------------ numba, one state in a kernel
@njit(cache=True, inline="always")
def axpy(s: Array, a: float, k: Array, out: Array) -> None:  # pragma: no cover - jit
    """``out = s + a k`` elementwise (1-D): a stage state of a Runge-Kutta step, or the Euler
    step itself. ``out`` may be ``s``.

    Parameters
    ----------
    s, k : ndarray
        The state and a stage derivative, 1-D.
    a : float
        The stage's step (``h/2`` or ``h``).
    out : ndarray
        Written.

    Examples
    --------
    >>> import numpy as np
    >>> out = np.empty(2)
    >>> axpy(np.array([1.0, 2.0]), 0.5, np.array([2.0, -2.0]), out)
    >>> out
    array([2., 1.])
    """
    for i in range(s.shape[0]):
        out[i] = s[i] + a * k[i]


@njit(cache=True, inline="always")
def rk4_sum(s: Array, h6: float, k1: Array, k2: Array, k3: Array, k4: Array,
            out: Array) -> None:  # pragma: no cover - jit
    """``out = s + h6 (k1 + 2 (k2 + k3) + k4)`` elementwise (1-D), ``h6 = h / 6``: the step of
    classical RK4. ``out`` may be ``s``.

    Parameters
    ----------
    s : ndarray
        The state at the start of the step, 1-D.
    h6 : float
        The step over six.
    k1, k2, k3, k4 : ndarray
        The four stage derivatives.
    out : ndarray
        Written.

    Examples
    --------
    >>> import numpy as np
    >>> one, out = np.ones(1), np.empty(1)
    >>> rk4_sum(np.zeros(1), 0.5, one, one, one, one, out)  # the step of a constant: 6 h6
    >>> out
    array([3.])
    """
    for i in range(s.shape[0]):
        out[i] = s[i] + h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])


@njit(cache=True, inline="always")
def heun_sum(s: Array, h2: float, k1: Array, k2: Array, out: Array) -> None:  # pragma: no cover
    """``out = s + h2 (k1 + k2)`` elementwise (1-D), ``h2 = h / 2``: the step of Heun's
    method. ``out`` may be ``s``.

    Parameters
    ----------
    s : ndarray
        The state at the start of the step, 1-D.
    h2 : float
        The step over two.
    k1, k2 : ndarray
        The two stage derivatives.
    out : ndarray
        Written.

    Examples
    --------
    >>> import numpy as np
    >>> out = np.empty(1)
    >>> heun_sum(np.zeros(1), 0.5, np.ones(1), np.ones(1), out)
    >>> out
    array([1.])
    """
    for i in range(s.shape[0]):
        out[i] = s[i] + h2 * (k1[i] + k2[i])


@njit(cache=True, inline="always")
def euler_step(f: Any, s: Array, h: float, args: Any, k1: Array,
               out: Array) -> None:  # pragma: no cover - jit
    """One forward-Euler step of ``s' = f(s)``: ``f(s, args, k1)``, ``out = s + h k1``.

    Parameters
    ----------
    f : numba dispatcher
        The right-hand side ``f(v, args, out)``, writing ``dv/dt`` into ``out``.
    s : ndarray
        The state at the start of the step, 1-D (not modified unless ``out`` is ``s``).
    h : float
        The step.
    args : tuple
        The right-hand side's other arguments.
    k1 : ndarray
        Work array of ``s``'s length (the derivative at ``s`` on return).
    out : ndarray
        The state after the step; may be ``s``.

    Examples
    --------
    >>> import numpy as np
    >>> from numba import njit
    >>> @njit
    ... def decay(v, args, out):
    ...     out[:] = -args[0] * v
    >>> s, k, out = np.ones(1), np.empty(1), np.empty(1)
    >>> euler_step(decay, s, 0.1, (1.0,), k, out)
    >>> out
    array([0.9])
    """
    f(s, args, k1)
    axpy(s, h, k1, out)


@njit(cache=True, inline="always")
def heun_step(f: Any, s: Array, h: float, args: Any, k1: Array, k2: Array, tmp: Array,
              out: Array) -> None:  # pragma: no cover - jit
    """One step of Heun's method of ``s' = f(s)`` (the arithmetic of :func:`heun`).

    Parameters
    ----------
    f : numba dispatcher
        The right-hand side ``f(v, args, out)``, writing ``dv/dt`` into ``out``.
    s : ndarray
        The state at the start of the step, 1-D (not modified unless ``out`` is ``s``).
    h : float
        The step.
    args : tuple
        The right-hand side's other arguments.
    k1, k2, tmp : ndarray
        Work arrays of ``s``'s length (the stage derivatives and the stage state).
    out : ndarray
        The state after the step; may be ``s`` or ``tmp``.

    Examples
    --------
    >>> import numpy as np
    >>> from numba import njit
    >>> @njit
    ... def decay(v, args, out):
    ...     out[:] = -args[0] * v
    >>> s, w = np.ones(1), np.empty((3, 1))
    >>> heun_step(decay, s, 0.1, (1.0,), w[0], w[1], w[2], s)
    >>> s
    array([0.905])
    """
    f(s, args, k1)
    axpy(s, h, k1, tmp)
    f(tmp, args, k2)
    heun_sum(s, h / 2, k1, k2, out)


@njit(cache=True, inline="always")
def rk4_step(f: Any, s: Array, h: float, args: Any, k1: Array, k2: Array, k3: Array,
             k4: Array, tmp: Array, out: Array) -> None:  # pragma: no cover - jit
    """One step of classical RK4 of ``s' = f(s)`` (the arithmetic of :func:`rk4`): stage
    states ``s + (h/2) k1``, ``s + (h/2) k2``, ``s + h k3`` in ``tmp``, then
    ``out = s + (h/6) (k1 + 2 (k2 + k3) + k4)``.

    Parameters
    ----------
    f : numba dispatcher
        The right-hand side ``f(v, args, out)``, writing ``dv/dt`` into ``out``.
    s : ndarray
        The state at the start of the step, 1-D (not modified unless ``out`` is ``s``).
    h : float
        The step.
    args : tuple
        The right-hand side's other arguments.
    k1, k2, k3, k4, tmp : ndarray
        Work arrays of ``s``'s length (the stage derivatives and the stage state).
    out : ndarray
        The state after the step; may be ``s`` or ``tmp``.

    Examples
    --------
    >>> import numpy as np
    >>> from numba import njit
    >>> @njit
    ... def decay(v, args, out):
    ...     out[:] = -args[0] * v
    >>> s, w = np.ones(1), np.empty((5, 1))
    >>> rk4_step(decay, s, 0.1, (1.0,), w[0], w[1], w[2], w[3], w[4], s)
    >>> s.round(7)
    array([0.9048375])
    """
    h2 = h / 2
    f(s, args, k1)
    axpy(s, h2, k1, tmp)
    f(tmp, args, k2)
    axpy(s, h2, k2, tmp)
    f(tmp, args, k3)
    axpy(s, h, k3, tmp)
    f(tmp, args, k4)
    rk4_sum(s, h / 6.0, k1, k2, k3, k4, out)
