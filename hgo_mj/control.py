"""State feedback for output-feedback studies: a linear law designed by LQR on the system's
linearization, applied to an observer's estimate (or the true state), batched.

Output feedback through a high-gain observer recovers the performance of the state feedback as
the gain grows (the separation principle of Esfandiari and Khalil, 1992; Khalil, *Nonlinear
Systems*, 3rd ed., sec. 14.5), provided the estimate is saturated outside the region of
interest: without it the observer's peaking reaches the plant through the control.

>>> from hgo_mj.systems import CartPendulum
>>> law = lqr(CartPendulum(), Q=[1.0, 1.0], R=1.0)
>>> law.K.round(3).tolist()
[[2.414, 2.414]]
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._validate import finite_scalar, symmetric_matrix, vector
from .exceptions import DesignError, DimensionError
from .inputs import Controller
from .systems.base import System

Array = NDArray[np.float64]


def linearize(system: System, x_eq: Any = None, u_eq: Any = None, eps: float = 1e-6
              ) -> tuple[Array, Array]:
    """``(A, B)``: the Jacobians of ``system.f(0, x, u)`` at ``(x_eq, u_eq)`` by central
    differences of step ``eps`` (default point: the origin).

    Parameters
    ----------
    system : System
        The plant; its ``f(t, x, u)`` is differentiated at ``t = 0``.
    x_eq : array_like, shape (n,), optional
        The state of the operating point (default: zeros).
    u_eq : array_like, shape (m,), optional
        The input of the operating point (default: zeros).
    eps : float
        Step of the central differences (default ``1e-6``).

    Returns
    -------
    A : (n, n) ndarray
        ``df/dx`` at the operating point.
    B : (n, m) ndarray
        ``df/du`` at the operating point.

    Raises
    ------
    DimensionError
        ``x_eq`` or ``u_eq`` not a vector of length ``n`` or ``m``.
    DesignError
        ``x_eq`` or ``u_eq`` with a non-finite entry.

    Examples
    --------
    The pendulum on a cart, linearized at the upright position:

    >>> from hgo_mj.systems import CartPendulum
    >>> A, B = linearize(CartPendulum())
    >>> A.round(3).tolist(), B.round(3).tolist()
    ([[0.0, 1.0], [1.0, 0.0]], [[0.0], [1.0]])
    """
    n, m = len(system.state_names), len(system.input_names)
    x0 = np.zeros(n) if x_eq is None else vector("x_eq", x_eq, n)
    u0 = np.zeros(m) if u_eq is None else vector("u_eq", u_eq, m)
    A, B = np.empty((n, n)), np.empty((n, m))
    for j in range(n):
        d = np.zeros(n)
        d[j] = eps
        A[:, j] = (system.f(0.0, x0 + d, u0) - system.f(0.0, x0 - d, u0)) / (2 * eps)
    for j in range(m):
        d = np.zeros(m)
        d[j] = eps
        B[:, j] = (system.f(0.0, x0, u0 + d) - system.f(0.0, x0, u0 - d)) / (2 * eps)
    return A, B


def _weight(name: str, value: Any, size: int) -> Array:
    """A weight as a matrix: a number (times the identity), a diagonal list, or a matrix."""
    a = np.asarray(value, dtype=float) if not isinstance(value, (str, bool)) else None
    if a is None or a.ndim > 2:
        raise DesignError(f"{name} must be a number, a list of {size} diagonal entries or a "
                          f"{size}x{size} matrix; found {value!r}")
    if a.ndim == 0:
        a = np.full(size, float(a))
    if a.ndim == 1:
        a = np.diag(vector(name, a, size))
    return symmetric_matrix(name, a, size, semidefinite=True)


class LinearFeedback(Controller):
    """``u = u_eq - K (sat(x) - x_eq)``, clipped to ``[-u_max, u_max]`` when ``u_max`` is
    given; ``x`` the named observer's estimate (``source="estimate"``) or the true state, and
    ``sat`` the saturation of each entry to ``x_eq +- x_max`` when ``x_max`` is given and
    ``saturate`` is true (Khalil's globally bounded output feedback: saturating the estimate
    outside the region of interest keeps the observer's peaking from the plant). Batched:
    :meth:`act` maps ``(B, n)`` states to ``(B, m)`` inputs at once.

    Parameters
    ----------
    K : array_like, shape (m, n)
    x_eq, u_eq : array_like, optional
        The operating point (default: the origin).
    u_max : float or array_like, optional
        Saturation of every input (a limit per input, or one for all).
    x_max : array_like, optional
        Saturation of the state fed to the law, per entry (around ``x_eq``).
    saturate : bool
        Whether ``x_max`` applies (default true; false: the same law unsaturated, to compare).
    source, observer
        As :class:`~hgo_mj.inputs.Controller`.

    Attributes
    ----------
    K : (m, n) ndarray
        The gain.
    Q, R : ndarray
        The weights of the cost ``x'Qx + u'Ru`` (identity unless designed by :func:`lqr`).

    Raises
    ------
    DesignError
        ``K`` not a finite matrix, ``saturate`` not a bool, or (from
        :class:`~hgo_mj.inputs.Controller`) a ``source`` other than ``"estimate"`` or
        ``"true"``.
    DimensionError
        ``x_eq``, ``u_eq``, ``x_max`` not of length ``n`` or ``m``, or ``u_max`` neither one
        number nor one per input.

    Examples
    --------
    >>> import numpy as np
    >>> law = LinearFeedback([[2.0, 1.0]], u_max=1.0)
    >>> law.act(0.0, np.array([[0.1, 0.2], [1.0, 1.0]]))
    array([[-0.4],
           [-1. ]])
    >>> law(0.0, np.array([0.1, 0.2]))
    array([-0.4])
    """

    def __init__(self, K: Any, *, x_eq: Any = None, u_eq: Any = None, u_max: Any = None,
                 x_max: Any = None, saturate: bool = True, source: str = "estimate",
                 observer: str | None = None) -> None:
        Km = np.atleast_2d(np.asarray(K, dtype=float))
        if Km.ndim != 2 or not np.all(np.isfinite(Km)):
            raise DesignError(f"K must be a finite (m, n) matrix; found {K!r}")
        m, n = Km.shape
        self.K = Km
        self.x_eq = np.zeros(n) if x_eq is None else vector("x_eq", x_eq, n)
        self.u_eq = np.zeros(m) if u_eq is None else vector("u_eq", u_eq, m)
        if u_max is not None:
            um = np.abs(vector("u_max", np.atleast_1d(u_max)))
            if um.size not in (1, m):
                raise DimensionError(f"u_max must be one number or one per input ({m}); found "
                                     f"{um.size} entries")
            u_max = np.broadcast_to(um, (m,)).copy()
        self.u_max = u_max
        if not isinstance(saturate, bool):
            raise DesignError(f"saturate must be true or false; found {saturate!r}")
        self.x_max = None if x_max is None else np.abs(vector("x_max", x_max, n))
        self.saturate = saturate
        #: the weights of the cost ``x'Qx + u'Ru`` (identity unless designed by :func:`lqr`)
        self.Q, self.R = np.eye(n), np.eye(m)
        super().__init__(self._law, source=source, observer=observer)

    def _law(self, t: float, x: Array) -> Array:
        return self.act(t, np.asarray(x, dtype=float)[None])[0]

    def act(self, t: float, X: Array) -> Array:
        """The inputs ``(B, m)`` for the states ``X`` ``(B, n)``."""
        D = X - self.x_eq
        if self.x_max is not None and self.saturate:
            D = np.clip(D, -self.x_max, self.x_max)
        KD = np.zeros((D.shape[0], self.K.shape[0]))
        for j in range(D.shape[1]):  # elementwise, in a fixed order: a member's input does not
            KD += D[:, j:j + 1] * self.K[:, j]  # depend on the batch (BLAS kernels would)
        U = self.u_eq - KD
        if self.u_max is not None:
            U = np.clip(U, -self.u_max, self.u_max)
        return U

    def params(self) -> dict[str, Any]:
        return {"K": self.K.tolist(), "x_eq": self.x_eq.tolist(), "u_eq": self.u_eq.tolist(),
                "u_max": None if self.u_max is None else self.u_max.tolist(),
                "x_max": None if self.x_max is None else self.x_max.tolist(),
                "saturate": self.saturate,
                "source": self.source, "observer": self.observer}


def lqr(system: System, Q: Any = 1.0, R: Any = 1.0, *, x_eq: Any = None, u_eq: Any = None,
        u_max: Any = None, x_max: Any = None, saturate: bool = True, source: str = "estimate",
        observer: str | None = None) -> LinearFeedback:
    """The LQR state feedback of ``system`` linearized at ``(x_eq, u_eq)``: ``K = R^-1 B' P``
    with ``P`` the stabilizing solution of ``A'P + PA - P B R^-1 B' P + Q = 0``
    (``scipy.linalg.solve_continuous_are``).

    Parameters
    ----------
    system : System
        The plant, linearized by :func:`linearize`.
    Q : float or array_like
        State weight: a number (times the identity), ``n`` diagonal entries or an ``(n, n)``
        symmetric positive semidefinite matrix (default 1).
    R : float or array_like
        Input weight, likewise of size ``m``; positive definite (default 1).
    x_eq, u_eq : array_like, optional
        The operating point (default: the origin).
    u_max, x_max, saturate, source, observer
        As :class:`LinearFeedback`.

    Returns
    -------
    LinearFeedback
        The law, with the weights ``Q``, ``R`` as matrices in its ``Q`` and ``R`` attributes.

    Raises
    ------
    DesignError
        Weights of the wrong shape, or a linearization that LQR cannot stabilize (not
        stabilizable, or ``R`` not positive definite).

    Examples
    --------
    >>> from hgo_mj.systems import CartPendulum
    >>> law = lqr(CartPendulum(), Q=[1.0, 1.0], R=1.0, u_max=1.0)
    >>> law.K.round(3).tolist()
    [[2.414, 2.414]]
    >>> law.R.tolist()
    [[1.0]]
    """
    from scipy.linalg import solve_continuous_are

    A, B = linearize(system, x_eq, u_eq)
    n, m = B.shape
    Qm, Rm = _weight("Q", Q, n), _weight("R", R, m)
    if np.min(np.linalg.eigvalsh(Rm)) <= 0:
        raise DesignError(f"R must be positive definite; found {Rm.tolist()}")
    try:
        P = solve_continuous_are(A, B, Qm, Rm)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise DesignError(f"LQR of {type(system).__name__} at x_eq = "
                          f"{[] if x_eq is None else list(x_eq)}: no stabilizing solution "
                          f"({exc})") from None
    K = np.linalg.solve(Rm, B.T @ P)
    if np.max(np.linalg.eigvals(A - B @ K).real) >= 0:  # pragma: no cover - the CARE ensures it
        raise DesignError(f"LQR of {type(system).__name__}: the closed loop is not stable")
    law = LinearFeedback(K, x_eq=x_eq, u_eq=u_eq, u_max=u_max, x_max=x_max, saturate=saturate,
                         source=source, observer=observer)
    law.Q, law.R = Qm, Rm  # the weights, for the closed loop's cost
    return law


def quadratic_cost(x: Array, u: Array, Q: Array, R: Array, dt: float) -> float:
    """``dt * sum_k (x_k' Q x_k + u_k' R u_k)`` over the rows of ``x`` ``(T, n)`` and ``u``
    ``(T, m)``: the closed loop's cost by the rectangle rule on the samples.

    Parameters
    ----------
    x : (T, n) ndarray
        The states, one row per sample.
    u : (T, m) ndarray
        The inputs, one row per sample.
    Q : (n, n) ndarray
        State weight.
    R : (m, m) ndarray
        Input weight.
    dt : float
        Sampling period, s.

    Returns
    -------
    float
        The cost.

    Examples
    --------
    >>> import numpy as np
    >>> quadratic_cost(np.ones((10, 2)), np.zeros((10, 1)), np.eye(2), np.eye(1), dt=0.01)
    0.2
    """
    return float(dt * (np.einsum("ti,ij,tj->", x, Q, x) + np.einsum("ti,ij,tj->", u, R, u)))


def make_controller(spec: dict[str, Any], system: System) -> LinearFeedback:
    """A controller from a scenario's ``[controller]`` table: ``type = "lqr"`` with ``Q``,
    ``R``, ``x_eq``, ``u_eq``, ``u_max``, ``x_max``, ``saturate``, ``source``, ``observer``.

    Parameters
    ----------
    spec : dict
        The table's entries (as read from TOML); ``type`` defaults to ``"lqr"``, the other
        keys are :func:`lqr`'s arguments. The mapping itself is not modified.
    system : System
        The plant the law is designed for.

    Returns
    -------
    LinearFeedback
        The law designed by :func:`lqr`.

    Raises
    ------
    DesignError
        A ``type`` other than ``"lqr"``, an unknown key, a ``u_max`` that is not positive
        and finite, or (from :func:`lqr`) weights it cannot use.

    Examples
    --------
    >>> from hgo_mj.systems import CartPendulum
    >>> law = make_controller({"type": "lqr", "Q": [1.0, 1.0], "R": 1.0, "u_max": 5.0},
    ...                       CartPendulum())
    >>> law.K.round(3).tolist(), law.u_max.tolist()
    ([[2.414, 2.414]], [5.0])
    """
    from ._validate import reject_unknown

    spec = dict(spec)
    kind = spec.pop("type", "lqr")
    if kind != "lqr":
        raise DesignError(f"unknown controller {kind!r}; valid: ['lqr']")
    reject_unknown("controller 'lqr'", spec,
                   ["Q", "R", "x_eq", "u_eq", "u_max", "x_max", "saturate", "source", "observer"])
    if "u_max" in spec:
        finite_scalar("controller u_max", np.max(np.abs(np.atleast_1d(spec["u_max"]))),
                      positive=True)
    return lqr(system, spec.pop("Q", 1.0), spec.pop("R", 1.0), **spec)


__all__ = ["LinearFeedback", "linearize", "lqr", "make_controller", "quadratic_cost"]
