"""The adaptive observer canonical form (AOCF) of paper 002, eq. 2.2-2.3, as data.

A system that has an AOCF declares it (``forms = (..., "aocf")`` and ``_form_aocf(**options)``)
and builds an :class:`AOCF` here; the Bastin-Gevers observer asks ``system.form("aocf", ...)``
and never imports a concrete system.

.. math::

    \\dot x = R x + \\Omega(\\omega)\\, \\theta + g(y, u), \\qquad y = x_1, \\qquad
    R = \\begin{bmatrix} 0 & k^T \\\\ 0 & F \\end{bmatrix}, \\qquad
    \\Omega_{ij}(\\omega) = \\alpha_{ij}^T \\omega(y, u)

**Rows.** The functions of a form (``omega``, ``g``, the inverse map ``to_physical`` and
``from_physical``) evaluate either one point (a hand-made form: ``omega(y, u)`` with ``y`` a
float) or, with ``rows=True``, rows: ``omega(Y (N,), U (N, m)) -> (N, s)``, as the forms the
systems build, so that an observer of B members evaluates them once per sample. Both kinds
offer both evaluations: :meth:`AOCF.omega` (one point) and :meth:`AOCF.omega_rows` (rows),
and likewise for the others.

Also here: :class:`Rebuildable`, the base of the observers' canonical forms (a form pickles as
the call that built it), and two small option checks shared by the forms.

References
----------
.. [002] G. Bastin, M. Gevers, "Stable adaptive observers for nonlinear time-varying systems",
   1986 (``shared/papers/002_7adafa82055be9d3.txt``): eq. 2.1-2.5 (AOCF and its maps), 4.11
   (the matrix S of Theorem 4.2).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, TypeVar

import numpy as np

from .._validate import finite_scalar, vector
from ..exceptions import DesignError, DimensionError
from .base import Array, System

__all__ = ["AOCF", "Rebuildable", "joint_aocf", "system_form"]


# ======================================================================================
# forms that pickle as the call that built them
# ======================================================================================


def _call(factory: Callable[..., Any], args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
    return factory(*args, **kwargs)


def system_form(system: System, kind: str, **options: Any) -> Any:
    """``system.form(kind, **options)``: the recipe a system's form records (:class:`Rebuildable`).

    Parameters
    ----------
    system : System
        The system whose form to build.
    kind : str
        The form's name, one of ``system.forms`` (e.g. ``"aocf"``).
    **options
        The options of the system's ``_form_<kind>``.

    Returns
    -------
    object
        ``system.form(kind, **options)``.

    Examples
    --------
    >>> from hgo_mj.systems import Pendulum
    >>> system_form(Pendulum(), "aocf", c2=3.0)
    AOCF(pendulum: y'' = -d/J y' - a sin y + b u, c2=3: n=2, m=2, theta=['g_over_l', 'b_over_J'],
    omega=['y', '-sin y', 'u'])
    """
    return system.form(kind, **options)


_F = TypeVar("_F", bound="Rebuildable")


class Rebuildable:
    """Base of the canonical forms: a form whose functions pickle cannot store (closures of
    its factory) pickles as the factory call that built it, which its factory records with
    :meth:`_made_by` (its arguments must pickle: a system, numbers, names). A form built by
    hand pickles as usual, where its functions do (module-level ones).

    Parameters
    ----------
    *args, **kwargs
        None accepted by this base; a subclass documents its own (:class:`AOCF`).

    Examples
    --------
    The pendulum's AOCF holds closures; it pickles as the call that built it:

    >>> import pickle
    >>> from hgo_mj.systems import Pendulum
    >>> form = Pendulum().form("aocf")
    >>> isinstance(form, Rebuildable)
    True
    >>> pickle.loads(pickle.dumps(form)).theta_true.round(4)
    array([20.3557, 18.4444])
    """

    _recipe: tuple[Callable[..., Any], tuple[Any, ...], dict[str, Any]] | None = None

    def _made_by(self: _F, factory: Callable[..., Any], *args: Any, **kwargs: Any) -> _F:
        """Record ``factory(*args, **kwargs)`` as the way to rebuild this form; returns it."""
        self._recipe = (factory, args, kwargs)
        return self

    def __reduce_ex__(self, protocol: Any) -> Any:
        if self._recipe is None:
            return super().__reduce_ex__(protocol)
        return (_call, self._recipe)

    @classmethod
    def _system_method(cls: type[_F], system: Any, method: str, kw: dict[str, Any],
                       factory: Callable[..., Any]) -> _F | None:
        """The form ``system.<method>(**kw)`` (checked to be one of ``cls``, recorded as
        ``factory(system, **kw)``), or ``None`` for a system without that method."""
        maker = getattr(system, method, None)
        if not callable(maker):
            return None
        form = maker(**kw)
        if not isinstance(form, cls):
            article = "an" if cls.__name__[0] in "AEIOU" else "a"
            raise DesignError(f"{type(system).__name__}.{method}() must return {article} "
                              f"{cls.__name__}; found {type(form).__name__}")
        return form._made_by(factory, system, **kw)


def _callable(name: str, f: Any, optional: bool = False) -> Callable[..., Any] | None:
    if f is None and optional:
        return None
    if not callable(f):
        raise DesignError(f"{name} must be a callable; found {type(f).__name__}")
    return f


def _names(name: str, value: Sequence[str] | None, count: int, default: Sequence[str]) -> tuple[str, ...]:
    if value is None:
        return tuple(default)
    out = tuple(str(v) for v in value)
    if len(out) != count:
        raise DimensionError(f"{name} must have {count} entries; found {len(out)}: {list(out)}")
    if len(set(out)) != len(out):
        raise DesignError(f"{name} must be distinct; found {list(out)}")
    return out


# ======================================================================================
# the canonical form
# ======================================================================================

#: the errors of a pointwise inverse map that mean "undefined here"
_UNDEFINED = (DesignError, ZeroDivisionError, FloatingPointError)


def _start(start: Any, n: int, m: int) -> tuple[Array, Array] | None:
    """An AOCF's ``start``: None, or the pair ``(x (n,), theta (m,))`` checked."""
    if start is None:
        return None
    if not isinstance(start, tuple) or len(start) != 2:
        raise DesignError(f"start must be a pair (x_hat0 (n,), theta_hat0 (m,)); found {start!r}")
    return vector("start[0] (x_hat0)", start[0], n), vector("start[1] (theta_hat0)", start[1], m)


class AOCF(Rebuildable):
    """Adaptive observer canonical form of paper 002, eq. 2.2-2.3.

    .. math::

        \\dot x = R x + \\Omega(\\omega) \\theta + g(y, u), \\quad y = x_1, \\quad
        R = \\begin{bmatrix} 0 & k^T \\\\ 0 & F \\end{bmatrix}, \\quad
        \\Omega_{ij} = \\alpha_{ij}^T \\omega(y, u)

    Parameters
    ----------
    R : array_like, shape (n, n)
        With a zero first column (eq. 2.3); ``k = R[0, 1:]``, ``F = R[1:, 1:]`` (Hurwitz).
    alpha : array_like, shape (n, m, s)
        ``alpha[i, j]`` is the constant vector :math:`\\alpha_{ij}`:
        ``Omega(omega) = alpha @ omega``.
    omega : callable
        The known signals :math:`\\omega` as functions of the measured output and the input:
        ``(y: float, u (mu,)) -> (s,)``, or with ``rows`` ``(Y (N,), U (N, mu)) -> (N, s)``.
    g : callable, optional
        The known term :math:`g` (the paper's "known functions of time": through ``y`` and
        ``u``, the only signals an observer has), ``(y, u) -> (n,)`` or on rows
        ``-> (N, n)``. Default zero.
    theta_names : sequence of str, optional
        Names of the ``m`` parameters (default ``"1".."m"``); the observer reports
        ``theta_<name>``.
    omega_names : sequence of str, optional
        Names of the ``s`` signals, for messages.
    to_physical : callable, optional
        The inverse maps 2.4-2.5: ``(x, theta, u) -> (state, params)`` with ``params`` a
        mapping of the named physical parameters (raising :class:`DesignError` where the
        inverse does not exist); on rows ``(X (N, n), TH (N, m), U) -> (states (N, n_x),
        params (N, len(physical_param_names)))`` with NaN rows where it does not exist.
    from_physical : callable, optional
        The state part of the transformation 2.1 at the parameter value ``theta``,
        ``(state, theta, u) -> x`` (on rows ``-> (N, n)``), to start an observer from a
        physical ``x_hat0``.
    state_names : sequence of str, optional
        Names of the physical state (default ``x1..xn``, the AOCF state).
    physical_param_names : sequence of str
        Keys of the ``params`` of ``to_physical``.
    label : str
        What the form is of, for messages.
    rows : bool
        The functions evaluate rows (see the module docstring).
    theta_true : array_like (m,), optional
        The value of :math:`\\theta` at the parameters of the system the form was built for,
        where :math:`\\theta` is constant (a reference for tests and reproductions).
    inverse_domain : str
        Where the inverse map exists, for the message of a start outside it.
    start : (array_like (n,), array_like (m,)), optional
        The default initial estimate ``(x_hat0, theta_hat0)`` in AOCF coordinates of an
        observer given none, inside the inverse map's domain (default: zero, which a form
        whose inverse needs a non-zero parameter, such as the bioreactor's eq. 6.6, cannot use).

    Raises
    ------
    DimensionError
        ``R`` is not square, ``alpha`` not ``(n, m, s)`` with ``m, s >= 1``, or a name list
        has the wrong length.
    DesignError
        ``R`` or ``alpha`` is not finite, ``R`` has a non-zero first column, ``F`` is not
        Hurwitz, a function is not callable, names repeat, or ``physical_param_names`` are
        given without ``to_physical``.

    References
    ----------
    Paper 002, eq. 2.1-2.5.

    Examples
    --------
    A hand-made form (one point at a time) with ``n = 2``, one parameter, ``F = -2`` and
    :math:`\\Omega = (y, u)^T`:

    >>> import numpy as np
    >>> alpha = np.array([[[1.0, 0.0]], [[0.0, 1.0]]])  # (n, m, s) = (2, 1, 2)
    >>> form = AOCF([[0.0, 1.0], [0.0, -2.0]], alpha, lambda y, u: np.array([y, u[0]]),
    ...             theta_names=("a",))
    >>> form
    AOCF(AOCF: n=2, m=1, theta=['a'], omega=['w1', 'w2'])
    >>> form.Omega(form.omega(0.5, [0.2]))
    array([[0.5],
           [0.2]])
    """

    def __init__(self, R: Any, alpha: Any, omega: Callable[..., Any], *,
                 g: Callable[..., Any] | None = None,
                 theta_names: Sequence[str] | None = None,
                 omega_names: Sequence[str] | None = None,
                 to_physical: Callable[..., Any] | None = None,
                 from_physical: Callable[..., Any] | None = None,
                 state_names: Sequence[str] | None = None,
                 physical_param_names: Sequence[str] = (), label: str = "AOCF",
                 rows: bool = False, theta_true: Any = None, inverse_domain: str = "",
                 start: Any = None) -> None:
        R = np.array(R, dtype=float)
        if R.ndim != 2 or R.shape[0] != R.shape[1] or R.shape[0] < 1:
            raise DimensionError(f"R must be a square n x n matrix (eq. 2.3); found shape {R.shape}")
        n = R.shape[0]
        if not np.all(np.isfinite(R)):
            raise DesignError(f"R must be finite; found {R.tolist()}")
        if np.any(R[:, 0] != 0.0):
            raise DesignError(f"R must have a zero first column (eq. 2.3: y = x1 enters only "
                              f"through Omega and g); found {R[:, 0].tolist()}")
        alpha = np.array(alpha, dtype=float)
        if alpha.ndim != 3 or alpha.shape[0] != n:
            raise DimensionError(f"alpha must have shape (n, m, s) = ({n}, m, s), one constant "
                                 f"vector alpha_ij per entry of Omega; found shape {alpha.shape}")
        if not np.all(np.isfinite(alpha)):
            raise DesignError("alpha must be finite")
        _, m, s = alpha.shape
        if m < 1 or s < 1:
            raise DimensionError(f"alpha needs m >= 1 parameters and s >= 1 signals; found "
                                 f"shape {alpha.shape}")
        self.n, self.m, self.s = n, m, s
        self.R = R
        self.k = R[0, 1:].copy()
        self.F = R[1:, 1:].copy()
        if n > 1:
            eig = np.linalg.eigvals(self.F)
            if np.any(eig.real >= 0):
                bad = ", ".join(f"{e:.4g}" for e in eig[eig.real >= 0])
                raise DesignError(f"F = R[1:, 1:] must be Hurwitz (Theorem 4.1 i: its eigenvalues "
                                  f"are set by c2..cn); eigenvalues [{bad}] have non-negative real "
                                  f"part")
        self.alpha = alpha
        self.rows = bool(rows)
        if not callable(omega):
            raise DesignError(f"omega must be a callable; found {type(omega).__name__}")
        self._omega: Callable[..., Any] = omega
        self._g = _callable("g", g, optional=True)
        self.theta_names = _names("theta_names", theta_names, m, [str(i + 1) for i in range(m)])
        self.omega_names = _names("omega_names", omega_names, s, [f"w{i + 1}" for i in range(s)])
        self._to_physical = _callable("to_physical", to_physical, optional=True)
        self._from_physical = _callable("from_physical", from_physical, optional=True)
        self.physical_param_names = tuple(physical_param_names)
        if to_physical is None and self.physical_param_names:
            raise DesignError("physical_param_names need a to_physical map")
        self.state_names = _names("state_names", state_names, len(state_names or ()) or n,
                                  [f"x{i + 1}" for i in range(n)])
        self.label = str(label)
        self.theta_true = None if theta_true is None else vector("theta_true", theta_true, m)
        self.inverse_domain = str(inverse_domain)
        #: the default initial estimate (x, theta), or None (zero)
        self.start = _start(start, n, m)

    @property
    def has_inverse(self) -> bool:
        """Whether the form maps back to physical coordinates (``to_physical``)."""
        return self._to_physical is not None

    @property
    def has_forward(self) -> bool:
        """Whether the form maps a physical state into its coordinates (``from_physical``)."""
        return self._from_physical is not None

    # ------------------------------------------------------------ one point
    def omega(self, y: float, u: Any) -> Array:
        """:math:`\\omega(y, u)` at one point, shape ``(s,)``.

        Parameters
        ----------
        y : float
            Measured output.
        u : array_like, shape (mu,)
            Input.

        Returns
        -------
        ndarray, shape (s,)
            The signals, in the order of :attr:`omega_names`.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> Pendulum().form("aocf").omega(0.5, [0.2]).round(6)  # (y, -sin y, u)
        array([ 0.5     , -0.479426,  0.2     ])
        """
        if self.rows:
            return np.asarray(self._omega(np.array([float(y)]), _row(u)), dtype=float)[0]
        return np.asarray(self._omega(y, u), dtype=float).reshape(-1)

    def g(self, y: float, u: Any) -> Array:
        """:math:`g(y, u)` at one point, shape ``(n,)`` (zero if the form has none).

        Parameters
        ----------
        y : float
            Measured output.
        u : array_like, shape (mu,)
            Input.

        Returns
        -------
        ndarray, shape (n,)
            The known term :math:`g(y, u)`.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> Pendulum().form("aocf").g(0.5, [0.2]).round(6)  # ((c2 - delta) y, c2 (delta - c2) y)
        array([ 0.907778, -1.815556])
        """
        if self._g is None:
            return np.zeros(self.n)
        if self.rows:
            return np.asarray(self._g(np.array([float(y)]), _row(u)), dtype=float)[0]
        return np.asarray(self._g(y, u), dtype=float).reshape(-1)

    def to_physical(self, x: Any, theta: Any, u: Any) -> tuple[Array, dict[str, float]]:
        """The inverse map 2.4-2.5 at one point: ``(state, {name: value})``.

        Parameters
        ----------
        x : array_like, shape (n,)
            AOCF state.
        theta : array_like, shape (m,)
            AOCF parameters.
        u : array_like, shape (mu,)
            Input.

        Returns
        -------
        state : ndarray, shape (n_x,)
            The physical state.
        params : dict of str to float
            The physical parameters named by :attr:`physical_param_names` (empty when the form
            recovers none).

        Raises
        ------
        DesignError
            Where the inverse does not exist (or the form has none).

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> form = Pendulum().form("aocf")
        >>> x = form.from_physical([0.5, 1.0], form.theta_true, [0.0])
        >>> form.to_physical(x, form.theta_true, [0.0])
        (array([0.5, 1. ]), {})
        """
        if self._to_physical is None:
            raise DesignError(f"{self.label} has no map to physical coordinates (to_physical)")
        if not self.rows:
            state, params = self._to_physical(x, theta, u)
            return np.asarray(state, dtype=float), dict(params)
        S, P = self._to_physical(_row(x), _row(theta), _row(u))
        state = np.asarray(S, dtype=float)[0]
        if not np.all(np.isfinite(state)):
            where = f" (it needs {self.inverse_domain})" if self.inverse_domain else ""
            raise DesignError(f"to_physical of {self.label} gives a non-finite state "
                              f"{state.tolist()}{where}")
        return state, {nm: float(v) for nm, v in zip(self.physical_param_names, P[0])}

    def from_physical(self, state: Any, theta: Any, u: Any) -> Array:
        """The state part of the map 2.1 at ``theta``, one point, shape ``(n,)``.

        Parameters
        ----------
        state : array_like, shape (n_x,)
            Physical state.
        theta : array_like, shape (m,)
            AOCF parameters at which to map.
        u : array_like, shape (mu,)
            Input.

        Returns
        -------
        ndarray, shape (n,)
            AOCF state ``x``.

        Raises
        ------
        DesignError
            The form has no ``from_physical`` map.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> form = Pendulum().form("aocf")  # x2 = y_dot + (delta - c2) y
        >>> form.from_physical([0.5, 1.0], form.theta_true, [0.0]).round(6)
        array([0.5     , 0.092222])
        """
        if self._from_physical is None:
            raise DesignError(f"{self.label} has no map from physical coordinates (from_physical)")
        if self.rows:
            return np.asarray(self._from_physical(_row(state), _row(theta), _row(u)),
                              dtype=float)[0]
        return np.asarray(self._from_physical(state, theta, u), dtype=float).reshape(-1)

    # ------------------------------------------------------------ rows
    def omega_rows(self, Y: Array, U: Array) -> Array:
        """:math:`\\omega` of the rows ``Y`` ``(N,)``, ``U`` ``(N, mu)``: ``(N, s)``.

        Parameters
        ----------
        Y : ndarray, shape (N,)
            Measured outputs, one per row.
        U : ndarray, shape (N, mu)
            Inputs, one row each.

        Returns
        -------
        ndarray, shape (N, s)

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems import Pendulum
        >>> form = Pendulum().form("aocf")
        >>> form.omega_rows(np.array([0.5, 1.0]), np.array([[0.2], [0.0]])).round(6)
        array([[ 0.5     , -0.479426,  0.2     ],
               [ 1.      , -0.841471,  0.      ]])
        """
        if self.rows:
            return np.asarray(self._omega(Y, U), dtype=float)
        return np.array([np.asarray(self._omega(float(y), u), dtype=float).reshape(-1)
                         for y, u in zip(Y, U)], dtype=float).reshape(len(Y), -1)

    def g_rows(self, Y: Array, U: Array) -> Array:
        """:math:`g` of the rows, ``(N, n)``.

        Parameters
        ----------
        Y : ndarray, shape (N,)
            Measured outputs, one per row.
        U : ndarray, shape (N, mu)
            Inputs, one row each.

        Returns
        -------
        ndarray, shape (N, n)
            Zero when the form has no ``g``.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems import Pendulum
        >>> form = Pendulum().form("aocf")
        >>> form.g_rows(np.array([0.5, 1.0]), np.array([[0.2], [0.0]])).round(6)
        array([[ 0.907778, -1.815556],
               [ 1.815556, -3.631112]])
        """
        if self._g is None:
            return np.zeros((len(Y), self.n))
        if self.rows:
            return np.asarray(self._g(Y, U), dtype=float)
        return np.array([np.asarray(self._g(float(y), u), dtype=float).reshape(-1)
                         for y, u in zip(Y, U)], dtype=float).reshape(len(Y), -1)

    def to_physical_rows(self, X: Array, TH: Array, U: Array) -> tuple[Array, Array]:
        """The inverse map of the rows: physical states ``(N, n_x)`` and parameters
        ``(N, len(physical_param_names))``, NaN rows where the inverse does not exist.

        Parameters
        ----------
        X : ndarray, shape (N, n)
            AOCF states.
        TH : ndarray, shape (N, m)
            AOCF parameters, one row per state.
        U : ndarray, shape (N, mu)
            Inputs.

        Returns
        -------
        states : ndarray, shape (N, n_x)
        params : ndarray, shape (N, len(physical_param_names))

        Raises
        ------
        DesignError
            The form has no ``to_physical`` map.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems import Pendulum
        >>> form = Pendulum().form("aocf")
        >>> TH = np.tile(form.theta_true, (1, 1))
        >>> X = form.from_physical_rows(np.array([[0.5, 1.0]]), TH, np.zeros((1, 1)))
        >>> states, params = form.to_physical_rows(X, TH, np.zeros((1, 1)))
        >>> states, params.shape
        (array([[0.5, 1. ]]), (1, 0))
        """
        if self._to_physical is None:
            raise DesignError(f"{self.label} has no map to physical coordinates (to_physical)")
        if self.rows:
            S, P = self._to_physical(X, TH, U)
            return np.asarray(S, dtype=float), np.asarray(P, dtype=float).reshape(len(X), -1)
        states = np.full((len(X), len(self.state_names)), np.nan)
        params = np.full((len(X), len(self.physical_param_names)), np.nan)
        for i in range(len(X)):
            try:
                s, p = self._to_physical(X[i], TH[i], U[i])
            except _UNDEFINED:
                continue
            states[i] = np.asarray(s, dtype=float)
            params[i] = [p[nm] for nm in self.physical_param_names]
        return states, params

    def from_physical_rows(self, S: Array, TH: Array, U: Array) -> Array:
        """The map 2.1 of the rows, ``(N, n)``.

        Parameters
        ----------
        S : ndarray, shape (N, n_x)
            Physical states.
        TH : ndarray, shape (N, m)
            AOCF parameters at which to map, one row per state.
        U : ndarray, shape (N, mu)
            Inputs.

        Returns
        -------
        ndarray, shape (N, n)
            AOCF states.

        Raises
        ------
        DesignError
            The form has no ``from_physical`` map.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems import Pendulum
        >>> form = Pendulum().form("aocf")
        >>> form.from_physical_rows(np.array([[0.5, 1.0]]), form.theta_true[None],
        ...                         np.zeros((1, 1))).round(6)
        array([[0.5     , 0.092222]])
        """
        if self._from_physical is None:
            raise DesignError(f"{self.label} has no map from physical coordinates (from_physical)")
        if self.rows:
            return np.asarray(self._from_physical(S, TH, U), dtype=float)
        return np.array([self.from_physical(s, th, u) for s, th, u in zip(S, TH, U)],
                        dtype=float).reshape(len(S), self.n)

    # ------------------------------------------------------------------ structure
    def Omega(self, omega: Any) -> Array:
        """:math:`\\Omega(\\omega)`, shape ``(n, m)``.

        Parameters
        ----------
        omega : array_like, shape (s,)
            A value of the signals :math:`\\omega` (e.g. from :meth:`omega`).

        Returns
        -------
        ndarray, shape (n, m)
            ``alpha @ omega``.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> form = Pendulum().form("aocf")
        >>> form.Omega([0.5, -0.5, 0.2])  # second row: psi(y, u)^T
        array([[ 0. ,  0. ],
               [-0.5,  0.2]])
        """
        w = vector("omega", omega, self.s)
        return self.alpha @ w

    def S_blocks(self) -> Array:
        """The constant blocks :math:`S_l` of :math:`S(\\omega) = \\sum_l \\omega_l S_l`
        (eq. 4.11), shape ``(s, n, m)``: row 1 is :math:`\\alpha_{1\\cdot l}`, row ``j`` is
        :math:`k^T F^{j-2} \\bar\\alpha_{\\cdot\\cdot l}`, ``j = 2..n``.

        Returns
        -------
        ndarray, shape (s, n, m)
            ``S_blocks()[l]`` is :math:`S_l`.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> Pendulum().form("aocf").S_blocks()[2]  # the block of omega_3 = u
        array([[0., 0.],
               [0., 1.]])
        """
        n = self.n
        out = np.zeros((self.s, n, self.m))
        for l in range(self.s):
            A = self.alpha[:, :, l]
            out[l, 0] = A[0]
            row = self.k.copy()
            for j in range(1, n):
                out[l, j] = row @ A[1:]
                row = row @ self.F
        return out

    def S(self, omega: Any) -> Array:
        """:math:`S(\\omega)` of eq. 4.11 at one value of :math:`\\omega`, shape ``(n, m)``.

        Parameters
        ----------
        omega : array_like, shape (s,)
            A value of the signals :math:`\\omega`.

        Returns
        -------
        ndarray, shape (n, m)
            :math:`\\sum_l \\omega_l S_l`.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> Pendulum().form("aocf").S([0.5, -0.5, 0.2])
        array([[ 0. ,  0. ],
               [-0.5,  0.2]])
        """
        w = vector("omega", omega, self.s)
        return np.tensordot(w, self.S_blocks(), axes=1)

    def reachability(self, tol: float = 1e-9) -> dict[str, Any]:
        """Structural output reachability of the auxiliary filter (Theorem 4.2).

        The column rank over :math:`\\mathbb R` of :math:`S(\\omega)` is the rank of the
        stacked blocks :math:`[S_1; \\dots; S_s]` (exact when the components of
        :math:`\\omega` are linearly independent functions of time).

        Parameters
        ----------
        tol : float, optional
            Relative tolerance: singular values below ``tol`` times the largest count as
            zero (default ``1e-9``).

        Returns
        -------
        dict
            ``rank``, ``m``, ``reachable`` (``rank == m``) and ``unreachable``: an orthonormal
            basis (list of vectors) of the constant :math:`\\beta` with
            :math:`S(\\omega)\\beta \\equiv 0` -- the parameter combinations the filter
            cannot excite.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> Pendulum().form("aocf").reachability()
        {'rank': 2, 'm': 2, 'reachable': True, 'unreachable': []}
        """
        M = self.S_blocks().reshape(-1, self.m)
        sv_full = np.linalg.svd(M, compute_uv=True)
        sv, Vt = sv_full[1], sv_full[2]
        scale = max(float(sv[0]) if sv.size else 0.0, 1e-300)
        rank = int(np.sum(sv > tol * scale)) if sv.size else 0
        null = Vt[rank:] if rank < self.m else np.zeros((0, self.m))
        return {"rank": rank, "m": self.m, "reachable": rank == self.m,
                "unreachable": [v.tolist() for v in null]}

    def __repr__(self) -> str:
        return (f"AOCF({self.label}: n={self.n}, m={self.m}, theta={list(self.theta_names)}, "
                f"omega={list(self.omega_names)})")

    # ------------------------------------------------------------------ by protocol
    @classmethod
    def from_system(cls, system: Any, **options: Any) -> AOCF:
        """``system.form("aocf", **options)``: the AOCF a system declares.

        Parameters
        ----------
        system : System
            A system that lists ``"aocf"`` in its ``forms``.
        **options
            The options of its ``_form_aocf`` (e.g. ``c2``, ``unknown``).

        Returns
        -------
        AOCF

        Raises
        ------
        DesignError
            For a system that declares none, or options it does not take.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> AOCF.from_system(Pendulum(), c2=3.0).F
        array([[-3.]])
        """
        if not isinstance(system, System) or "aocf" not in system.forms:
            declared = list(getattr(system, "forms", ()))
            raise DesignError(
                f"the Bastin-Gevers observer needs the adaptive observer canonical form of paper "
                f"002, eq. 2.2 (R with k and F, Omega(omega) = alpha omega, g); "
                f"{type(system).__name__} provides none (it declares the forms {declared}, no "
                f"'aocf'); give aocf=AOCF(...) explicitly (see docs/adaptive_canonical_forms.md)")
        try:
            form = system.form("aocf", **options)
        except TypeError as exc:
            raise DesignError(f"the AOCF of {type(system).__name__} takes other options: "
                              f"{exc}") from None
        if not isinstance(form, cls):
            raise DesignError(f"{type(system).__name__}.form('aocf') must return an AOCF; found "
                              f"{type(form).__name__}")
        return form

    # the names of the first port, kept as calls of the protocol (no plant knowledge here)
    @classmethod
    def bioreactor(cls, system: Any, c2: float | None = None) -> AOCF:
        """``system.form("aocf", c2=c2)`` (the bioreactor's AOCF eq. 6.5).

        Parameters
        ----------
        system : BioreactorBastinGevers
            The bioreactor (or another system whose ``_form_aocf`` takes ``c2``).
        c2 : float, optional
            Design constant ``> 0`` (default: the system's ``default_c2``).

        Returns
        -------
        AOCF

        Examples
        --------
        >>> from hgo_mj.systems import BioreactorBastinGevers
        >>> AOCF.bioreactor(BioreactorBastinGevers(), c2=1.5).omega_names
        ('y', 'u1', 'u2')
        """
        return cls.from_system(system, c2=c2)

    @classmethod
    def pendulum(cls, system: Any, **options: Any) -> AOCF:
        """``system.form("aocf", **options)`` (the pendulum's AOCF, :func:`joint_aocf`).

        Parameters
        ----------
        system : Pendulum
            The pendulum (or another system that declares ``"aocf"``).
        **options
            ``c2``, ``unknown``, ``damping_known`` (see :func:`joint_aocf`).

        Returns
        -------
        AOCF

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> AOCF.pendulum(Pendulum(), unknown=("d_over_J", "g_over_l", "b_over_J")).theta_names
        ('d_over_J', 'g_over_l', 'b_over_J')
        """
        return cls.from_system(system, **options)

    @staticmethod
    def pendulum_theta(system: Any, unknown: Sequence[str] | None = None) -> Array:
        """The true :math:`\\theta` of a pendulum's AOCF (:attr:`theta_true`).

        Parameters
        ----------
        system : Pendulum
            The pendulum (or another system whose AOCF carries ``theta_true``).
        unknown : sequence of str, optional
            The parameters of the form (see :func:`joint_aocf`; default
            ``("g_over_l", "b_over_J")``).

        Returns
        -------
        ndarray, shape (m,)
            :math:`\\theta` at the system's parameters, in the order of ``unknown``.

        Raises
        ------
        DesignError
            The system's AOCF carries no true :math:`\\theta`.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> AOCF.pendulum_theta(Pendulum()).round(4)  # (m g l_c / J, b / J)
        array([20.3557, 18.4444])
        """
        th = AOCF.from_system(system, unknown=unknown).theta_true
        if th is None:
            raise DesignError(f"the AOCF of {type(system).__name__} carries no true theta")
        return th

    @classmethod
    def second_order(cls, features: Callable[[Array, Array], Any], feature_names: Sequence[str],
                     theta_names: Sequence[str], *, damping: float, c2: float = 2.0,
                     estimate_damping: bool = False, damping_name: str = "d_over_J",
                     damping_from: int | None = None,
                     state_names: Sequence[str] = ("y", "y_dot"), label: str = "",
                     theta_true: Any = None) -> AOCF:
        """AOCF of :math:`\\ddot y = -\\delta \\dot y + \\psi(y, u)^T \\theta` (a mechanical
        joint with viscous damping, measured position), derived in
        ``docs/adaptive_canonical_forms.md``.

        With :math:`\\delta` known, :math:`x_1 = y`, :math:`x_2 = \\dot y + (\\delta - c_2) y`:

        .. math::

            \\dot x_1 = x_2 + (c_2 - \\delta) y, \\qquad
            \\dot x_2 = -c_2 x_2 + \\psi(y, u)^T \\theta + c_2 (\\delta - c_2) y,

        i.e. :math:`k = 1`, :math:`F = -c_2`, :math:`\\Omega_1 = 0`,
        :math:`\\bar\\Omega = \\psi^T`. With :math:`\\delta = \\kappa \\theta_j`
        proportional to a parameter (``damping_from = j``, ``damping`` = :math:`\\kappa`: the
        damping coefficient known but the inertia not, :math:`d/J = (d/b)(b/J)`), the same
        ``x`` gives :math:`\\Omega_{1j} = -\\kappa y`, :math:`\\bar\\Omega_j = \\psi_j +
        c_2 \\kappa y` and :math:`g = (c_2 y, -c_2^2 y)`. With :math:`\\delta` unknown too
        (``estimate_damping``), :math:`\\theta = (\\delta, \\theta)`, the same ``x`` and

        .. math::

            \\dot x_1 = x_2 - y \\delta + c_2 y, \\qquad
            \\dot x_2 = -c_2 x_2 + c_2 y \\delta + \\psi^T \\theta - c_2^2 y.

        Parameters
        ----------
        features : callable ``(Y (N,), U (N, mu)) -> (N, q)``
            :math:`\\psi(y, u)` on rows.
        feature_names, theta_names : sequence of str
            ``q`` names each.
        damping : float
            :math:`\\delta` (the known value, or the value the physical map uses when
            estimated: then ignored).
        c2 : float
            Design pole ``-c2`` of ``F`` (> 0).
        estimate_damping : bool
            Put :math:`\\delta` into :math:`\\theta` (first entry, named ``damping_name``).
        damping_from : int, optional
            :math:`\\delta = \\kappa \\theta_j` with ``j = damping_from`` and
            :math:`\\kappa` = ``damping`` (exclusive with ``estimate_damping``).
        damping_name : str
            Name of :math:`\\delta` in :attr:`theta_names` when estimated (default
            ``"d_over_J"``).
        state_names : sequence of str
            Names of the physical state (default ``("y", "y_dot")``).
        label : str
            What the form is of, for messages (default: ``"second-order joint, c2=..."``).
        theta_true : array_like, optional
            :attr:`AOCF.theta_true`.

        Returns
        -------
        AOCF
            ``n = 2``, ``R = [[0, 1], [0, -c2]]``, on rows, pickling as this call.

        Raises
        ------
        DimensionError
            ``feature_names`` and ``theta_names`` differ in length or are empty.
        DesignError
            ``damping_from`` is out of range or given with ``estimate_damping`` (also: ``c2``
            not positive, or ``c2``/``damping`` not finite).

        References
        ----------
        Paper 002, eq. 2.2, 2.6-2.8 (the observer form this is an instance of).

        Examples
        --------
        >>> import numpy as np
        >>> def psi(Y, U):
        ...     return np.stack([-np.sin(Y), U[:, 0]], axis=1)
        >>> form = AOCF.second_order(psi, ("-sin y", "u"), ("a", "b"), damping=0.1)
        >>> form
        AOCF(second-order joint, c2=2: n=2, m=2, theta=['a', 'b'], omega=['y', '-sin y', 'u'])
        >>> form.g(0.5, [0.2])  # ((c2 - delta) y, c2 (delta - c2) y)
        array([ 0.95, -1.9 ])
        """
        c2 = finite_scalar("c2", c2, positive=True)
        delta = finite_scalar("damping", damping)
        fn, tn = tuple(feature_names), tuple(theta_names)
        if len(fn) != len(tn) or not fn:
            raise DimensionError(f"feature_names and theta_names must have the same non-zero "
                                 f"length; found {len(fn)} and {len(tn)}")
        q = len(fn)
        ed = bool(estimate_damping)
        if damping_from is not None and (ed or not 0 <= int(damping_from) < q):
            raise DesignError(f"damping_from must index one of the {q} parameters and exclude "
                              f"estimate_damping; found {damping_from!r}")
        m = q + ed
        alpha = np.zeros((2, m, q + 1))
        if ed:
            alpha[0, 0, 0] = -1.0
            alpha[1, 0, 0] = c2
        for j in range(q):
            alpha[1, ed + j, 1 + j] = 1.0
        if damping_from is not None:
            jd = int(damping_from)
            alpha[0, jd, 0] = -delta
            alpha[1, jd, 0] = c2 * delta
        gy0, gy1 = (c2, -c2 * c2) if ed or damping_from is not None else (c2 - delta,
                                                                          c2 * (delta - c2))
        feats = features

        def omega(Y: Array, U: Array) -> Array:  # omega = (y, psi(y, u))
            W = np.empty((len(Y), q + 1))
            W[:, 0] = Y
            W[:, 1:] = feats(Y, U)
            return W

        def g_fun(Y: Array, U: Array) -> Array:
            G = np.empty((len(Y), 2))
            G[:, 0] = gy0 * Y
            G[:, 1] = gy1 * Y
            return G

        def dlt(TH: Array) -> Any:  # delta on rows
            if damping_from is not None:
                return delta * TH[:, damping_from]
            return TH[:, 0] if ed else delta

        def to_physical(X: Array, TH: Array, U: Array) -> tuple[Array, Array]:
            S = np.empty((len(X), 2))
            S[:, 0] = X[:, 0]
            S[:, 1] = X[:, 1] - (dlt(TH) - c2) * X[:, 0]  # y_dot = x2 - (delta - c2) y
            return S, np.empty((len(X), 0))

        def from_physical(S: Array, TH: Array, U: Array) -> Array:
            X = np.empty((len(S), 2))
            X[:, 0] = S[:, 0]
            X[:, 1] = S[:, 1] + (dlt(TH) - c2) * S[:, 0]  # x2 = y_dot + (delta - c2) y
            return X

        R = np.array([[0.0, 1.0], [0.0, -c2]])
        names = ((damping_name,) if ed else ()) + tn
        return cls(R, alpha, omega, g=g_fun, theta_names=names, omega_names=("y",) + fn,
                   to_physical=to_physical, from_physical=from_physical,
                   state_names=state_names, label=label or f"second-order joint, c2={c2:g}",
                   rows=True, theta_true=theta_true
                   )._made_by(cls.second_order, features, fn, tn, damping=damping, c2=c2,
                              estimate_damping=ed, damping_name=damping_name,
                              damping_from=damping_from, state_names=state_names, label=label,
                              theta_true=theta_true)


def _row(v: Any) -> Array:
    """One point as a row ``(1, k)``."""
    return np.asarray(v, dtype=float).reshape(1, -1)


def joint_aocf(system: System, features: Callable[[Array, Array], Any],
               feature_names: Sequence[str], model: str, ratios: tuple[float, float], *,
               c2: float = 2.0, unknown: Sequence[str] | str | None = None,
               damping_known: str = "ratio", coefficient: bool = True) -> AOCF:
    """The AOCF of a pendulum-like joint :math:`\\ddot y = -\\delta \\dot y + a\\,\\psi_1(y)
    + \\beta\\,\\psi_2(y, u)` with unknown ``g_over_l`` (:math:`a`) and ``b_over_J``
    (:math:`\\beta`), through :meth:`AOCF.second_order`; the system gives its features, its
    model (for the label) and its true ratios ``(a, beta)``.

    Parameters
    ----------
    system : System
        The joint's system; its ``params`` must hold ``inertia``, ``damping`` and ``gear``.
    features : callable ``(Y (N,), U (N, mu)) -> (N, 2)``
        :math:`(\\psi_1(y), \\psi_2(y, u))` on rows.
    feature_names : sequence of str
        Two names, for messages (e.g. ``("-sin y", "u")``).
    model : str
        The model's equation, for the label.
    ratios : (float, float)
        The true :math:`(a, \\beta)` (``g_over_l``, ``b_over_J``).
    c2 : float
        Design pole ``-c2`` of ``F`` (> 0, default 2).
    unknown : sequence of str, optional
        ``("g_over_l", "b_over_J")`` (default; damping known, read from the system) or
        ``("d_over_J", "g_over_l", "b_over_J")`` (damping estimated too).
    damping_known : {"ratio", "coefficient"}
        With two unknowns, what is known of the damping: ``"ratio"`` (default),
        :math:`\\delta = d/J` itself; ``"coefficient"``, the coefficient :math:`d` and the
        gear :math:`b` but not the inertia, so :math:`\\delta = (d/b)\\,(b/J)` moves with
        the input-gain parameter (where ``coefficient``: systems whose input gain is
        ``gear / inertia``).
    coefficient : bool
        Whether ``damping_known="coefficient"`` is derived for this system (its input gain
        is ``gear / inertia``; default True).

    Returns
    -------
    AOCF
        The form (:meth:`AOCF.second_order`), with :attr:`AOCF.theta_true` set; it pickles
        as ``system.form("aocf", ...)``.

    Raises
    ------
    DesignError
        ``unknown`` is not one of the two allowed sets, ``damping_known`` is not
        ``"ratio"`` or ``"coefficient"``, or ``"coefficient"`` is asked of a system with
        ``coefficient=False``.

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.systems import Pendulum
    >>> def psi(Y, U):
    ...     return np.stack([-np.sin(Y), U[:, 0]], axis=1)
    >>> form = joint_aocf(Pendulum(), psi, ("-sin y", "u"), "my pendulum", (10.0, 18.0))
    >>> form
    AOCF(my pendulum, c2=2: n=2, m=2, theta=['g_over_l', 'b_over_J'], omega=['y', '-sin y', 'u'])
    >>> form.theta_true
    array([10., 18.])
    """
    p = system.params
    base = ("g_over_l", "b_over_J")
    allowed = (base, ("d_over_J",) + base)
    if isinstance(unknown, str):
        unknown = (unknown,)
    unknown = base if unknown is None else tuple(unknown)
    if set(unknown) not in ({*a} for a in allowed) or len(unknown) not in (2, 3):
        raise DesignError(f"unknown must be {list(allowed[0])} (damping known) or "
                          f"{list(allowed[1])}; found {list(unknown)}: the AOCF "
                          f"{'needs both g_over_l and b_over_J' if 'd_over_J' not in unknown else ''}"
                          f" (a known ratio moves into g; see docs/adaptive_canonical_forms.md)")
    if damping_known not in ("ratio", "coefficient"):
        raise DesignError(f"damping_known must be 'ratio' or 'coefficient'; found "
                          f"{damping_known!r}")
    coef = damping_known == "coefficient" and "d_over_J" not in unknown
    if coef and not coefficient:
        raise DesignError(f"damping_known='coefficient' is derived for the pendulum only "
                          f"({type(system).__name__}: its input gain is not gear / inertia)")
    J = p["inertia"]
    estimated = "d_over_J" in unknown
    truth = ([p["damping"] / J] if estimated else []) + list(ratios)
    options = {"c2": c2, "unknown": unknown, "damping_known": damping_known}
    if coef:
        form = AOCF.second_order(features, feature_names, base, damping=p["damping"] / p["gear"],
                                 c2=c2, damping_from=1, state_names=system.state_names,
                                 label=f"{model}, d known (d/J = (d/b) b/J), c2={c2:g}",
                                 theta_true=truth)
    else:
        form = AOCF.second_order(features, feature_names, base, damping=p["damping"] / J,
                                 c2=c2, estimate_damping=estimated,
                                 state_names=system.state_names, label=f"{model}, c2={c2:g}",
                                 theta_true=truth)
    return form._made_by(system_form, system, "aocf", **options)

