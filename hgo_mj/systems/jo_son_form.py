"""The adaptive observer canonical form of Jo and Son (paper 003, eq. 9-10), as data.

A system that has this form builds it (``forms = ("jo_son",)`` and ``_form_jo_son(**options)``,
see :meth:`hgo_mj.systems.base.System.form`); the Jo-Son observer
(:class:`hgo_mj.observers.jo_son.JoSonObserver`) asks for it by name and never imports a
concrete system. The form lives here, in the systems package, so that systems build it without
importing an observer.

.. math::

    \\dot z_o &= A_o z_o + \\gamma_o(y, u) + b\\, \\beta^T(y, u)\\, \\theta \\\\
    \\dot z_{\\bar o} &= A_{\\bar o o} z_o + f_{\\bar o}(y, z_{\\bar o}) + \\gamma_{\\bar o}(y, u) \\\\
    y &= C_o z_o = z_{o, r}

with :math:`A_o` the lower shift and :math:`C_o = (0, \\dots, 0, 1)`.

**The form's functions work on rows, component first** (the layout of scipy's
``solve_ivp(..., vectorized=True)``): ``y`` is ``(N,)``, one value per member, ``u`` is
``(m, N)`` (``u[0]`` the first input of every member), ``z_obar`` ``(n - r, N)``, ``z`` ``(n, N)``,
``x`` ``(n_x, N)``; each function returns a sequence of components, each a number or an
``(N,)`` array. Written with numpy functions (``np.sin``, not ``math.sin``), the same code
serves one point (``y`` a float, ``u`` of shape ``(m,)``) and N members at once:
``beta = lambda y, u: (y * u[0],)``.

References
----------
.. [003] N.-H. Jo, Y.-I. Son, "Adaptive observer design for nonlinear systems using generalized
   nonlinear observer canonical form", KSME Int. J. 18(7), 2004
   (``shared/papers/003_bd61d49996cbe973.txt``): eq. 9-10 (form), Theorem 3.1.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .._validate import vector
from ..exceptions import DesignError, DimensionError
from .base import Array

__all__ = ["JoSonForm"]

Rows = Callable[..., Sequence[Any]]


def _callable(name: str, f: Any, optional: bool = False) -> Rows | None:
    if f is None and optional:
        return None
    if not callable(f):
        raise DesignError(f"{name} must be a callable; found {type(f).__name__}")
    return f  # type: ignore[no-any-return]


def _names(name: str, value: Sequence[str] | None, count: int,
           default: Sequence[str]) -> tuple[str, ...]:
    if value is None:
        return tuple(default)
    out = tuple(str(v) for v in value)
    if len(out) != count:
        raise DimensionError(f"{name} must have {count} entries; found {len(out)}: {list(out)}")
    if len(set(out)) != len(out):
        raise DesignError(f"{name} must be distinct; found {list(out)}")
    return out


class JoSonForm:
    """Adaptive observer canonical form of paper 003, eq. 10.

    Parameters
    ----------
    b : array_like, shape (r,)
        The direction :math:`b` along which the parameters enter :math:`\\dot z_o`.
    gamma_o : callable ``(y, u) -> r components``
        :math:`\\gamma_o(y, u)` (rows, component first: see the module docstring).
    beta : callable ``(y, u) -> p components``
        :math:`\\beta(y, u)`, the regressor (eq. 10: :math:`b \\beta^T \\theta`).
    n_unobservable : int
        :math:`n - r`, the dimension of :math:`z_{\\bar o}` (0: none).
    f_obar : callable ``(y, z_obar) -> n - r components``, optional
        :math:`f_{\\bar o}(y, z_{\\bar o})` (required when ``n_unobservable > 0``).
    gamma_obar : callable ``(y, u) -> n - r components``, optional
        :math:`\\gamma_{\\bar o}(y, u)` (default zero).
    A_obar_o : array_like, shape (n-r, r), optional
        :math:`A_{\\bar o o}` (default zero).
    theta_names : sequence of str, optional
        ``p`` names (default ``"1".."p"``); the observer reports ``theta_<name>``.
    n_params : int, optional
        ``p``, when ``theta_names`` is not given.
    to_physical : callable ``z -> n_x components``, optional
        :math:`T^{-1}` (eq. 27, first line); default: ``x_hat = z_hat``.
    from_physical : callable ``x -> n components``, optional
        :math:`T` (to start from a physical ``x_hat0``).
    state_names : sequence of str, optional
        Names of ``x`` (default ``z1..zn``).
    aux_outputs : sequence of int
        Indices of further measured channels appended to the input ``u`` that ``gamma_o``,
        ``beta`` and ``gamma_obar`` receive (signals measured but used as known inputs, e.g. a
        second sensor): ``u`` has ``m + len(aux_outputs)`` components.
    label : str
        What the form is of, for messages.

    Raises
    ------
    DimensionError
        ``b`` is empty, ``A_obar_o`` has the wrong shape, ``p < 1``, ``theta_names`` or
        ``state_names`` has the wrong length, or (without ``to_physical``) ``state_names``
        does not have ``n`` entries.
    DesignError
        A function is not callable, ``n_unobservable`` is not a non-negative integer,
        ``f_obar`` is missing for ``n_unobservable > 0`` (or ``f_obar``/``gamma_obar`` given
        for 0), neither ``theta_names`` nor ``n_params`` is given, names repeat, or an
        ``aux_outputs`` index is negative.

    Notes
    -----
    A form pickles when its functions do (module-level functions, bound methods of a system):
    the forms the systems build are written that way. A form of closures or lambdas does not.

    References
    ----------
    Paper 003, eq. 9-10; Theorem 3.1 (conditions for the coordinates to exist).

    Examples
    --------
    A fully observable form with ``r = 2``, ``b = (2, 1)`` and one parameter,
    :math:`\\gamma_o = (0, u)`, :math:`\\beta = y u`:

    >>> form = JoSonForm([2.0, 1.0], lambda y, u: (0.0 * y, u[0]), lambda y, u: (y * u[0],),
    ...                  n_params=1)
    >>> form
    JoSonForm(adaptive observer canonical form: r=2, n=2, b=[2.0, 1.0], theta=['1'])
    >>> form.state_names
    ('z1', 'z2')

    The form of paper 003's example (eq. 31), which the example system builds (a system
    declares its form; the form knows no system):

    >>> from hgo_mj.systems import JoSonExample
    >>> JoSonExample().form("jo_son")
    JoSonForm(Jo-Son example eq. 31: r=2, n=3, b=[2.0, 1.0], theta=['theta'])
    """

    def __init__(self, b: Any, gamma_o: Rows, beta: Rows, *, n_unobservable: int = 0,
                 f_obar: Rows | None = None, gamma_obar: Rows | None = None,
                 A_obar_o: Any = None, theta_names: Sequence[str] | None = None,
                 n_params: int | None = None, to_physical: Rows | None = None,
                 from_physical: Rows | None = None, state_names: Sequence[str] | None = None,
                 aux_outputs: Sequence[int] = (),
                 label: str = "adaptive observer canonical form") -> None:
        self.b = vector("b", b)
        if self.b.size < 1:
            raise DimensionError("b must have r >= 1 entries; found none")
        self.r = int(self.b.size)
        if int(n_unobservable) != n_unobservable or n_unobservable < 0:
            raise DesignError(f"n_unobservable must be a non-negative integer; found "
                              f"{n_unobservable!r}")
        self.n_obar = int(n_unobservable)
        self.n = self.r + self.n_obar
        self.gamma_o: Rows = _callable("gamma_o", gamma_o)  # type: ignore[assignment]
        self.beta: Rows = _callable("beta", beta)  # type: ignore[assignment]
        self.f_obar = _callable("f_obar", f_obar, optional=True)
        self.gamma_obar = _callable("gamma_obar", gamma_obar, optional=True)
        if self.n_obar and self.f_obar is None:
            raise DesignError(f"an unobservable part of dimension {self.n_obar} needs f_obar "
                              f"(eq. 10); found none")
        if not self.n_obar and (f_obar is not None or gamma_obar is not None):
            raise DesignError("f_obar and gamma_obar need n_unobservable > 0")
        if A_obar_o is None:
            self.A_obar_o = np.zeros((self.n_obar, self.r))
        else:
            A = np.array(A_obar_o, dtype=float)
            if A.shape != (self.n_obar, self.r):
                raise DimensionError(f"A_obar_o must have shape (n-r, r) = ({self.n_obar}, "
                                     f"{self.r}); found {A.shape}")
            self.A_obar_o = A
        if theta_names is None and n_params is None:
            raise DesignError("give theta_names or n_params (the number p of parameters)")
        p = len(theta_names) if theta_names is not None else int(n_params)  # type: ignore[arg-type]
        if p < 1:
            raise DimensionError(f"the form needs p >= 1 parameters; found {p}")
        self.p = p
        self.theta_names = _names("theta_names", theta_names, p, [str(i + 1) for i in range(p)])
        self.to_physical = _callable("to_physical", to_physical, optional=True)
        self.from_physical = _callable("from_physical", from_physical, optional=True)
        self.state_names = _names("state_names", state_names, len(state_names or ()) or self.n,
                                  [f"z{i + 1}" for i in range(self.n)])
        if self.to_physical is None and len(self.state_names) != self.n:
            raise DimensionError(f"without to_physical the estimate is z: state_names must have "
                                 f"n = {self.n} entries; found {list(self.state_names)}")
        aux = tuple(int(i) for i in aux_outputs)
        if any(i < 0 for i in aux):
            raise DesignError(f"aux_outputs must be channel indices >= 0; found {list(aux)}")
        self.aux_outputs = aux
        self.label = str(label)

    def __repr__(self) -> str:
        return (f"JoSonForm({self.label}: r={self.r}, n={self.n}, b={self.b.tolist()}, "
                f"theta={list(self.theta_names)})")

    # ------------------------------------------------------------ evaluation on rows
    def rows(self, what: str, f: Rows, count: int, N: int, *args: Any) -> Array:
        """``f(*args)`` (component first) as a C-contiguous ``(N, count)`` float array.

        Parameters
        ----------
        what : str
            How ``f`` is called, for messages (e.g. ``"beta(y, u)"``).
        f : callable
            One of the form's functions (rows, component first).
        count : int
            Number of components ``f`` must return.
        N : int
            Number of members (rows).
        *args
            The arguments of ``f``, component first (``y`` ``(N,)``, ``u`` ``(m, N)``, ...).

        Returns
        -------
        ndarray, shape (N, count)
            Column ``i``: component ``i`` of ``f(*args)`` (a number is broadcast to ``N``
            rows).

        Raises
        ------
        DimensionError
            ``f`` fails on the shapes given (an index past the input's width), returns a number
            of components other than ``count``, or components of another length than ``N``.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems import JoSonExample
        >>> form = JoSonExample().form("jo_son")
        >>> y, u = np.array([0.5, 1.0]), np.array([[0.3, 0.0]])  # u component first: (m, N)
        >>> form.rows("beta(y, u)", form.beta, 1, 2, y, u)
        array([[0.15],
               [0.  ]])
        """
        try:
            comps = f(*args)
            k = len(comps)
        except (IndexError, TypeError) as exc:
            shapes = ", ".join(str(np.shape(a)) for a in args)
            raise DimensionError(f"{what} of {self.label} failed on arguments of shapes "
                                 f"({shapes}): {exc}") from None
        if k != count:
            raise DimensionError(f"{what} of {self.label} must return {count} values; found {k}")
        out = np.empty((N, count))
        try:
            for i, c in enumerate(comps):
                out[:, i] = c
        except ValueError:
            raise DimensionError(f"{what} of {self.label} must return components of {N} "
                                 f"member(s); found shapes {[np.shape(c) for c in comps]}"
                                 ) from None
        return out

    def signals(self, y: Array, u: Array) -> tuple[Array, Array, Array]:
        """:math:`\\gamma_o(y, u)` ``(N, r)``, :math:`\\beta(y, u)` ``(N, p)`` and
        :math:`\\gamma_{\\bar o}(y, u)` ``(N, n - r)`` of the members ``y`` ``(N,)``, ``u``
        ``(N, m)`` (rows; ``u`` includes the ``aux_outputs`` channels).

        Parameters
        ----------
        y : ndarray, shape (N,)
            Measured outputs, one per member.
        u : ndarray, shape (N, m)
            Inputs (with the ``aux_outputs`` channels appended), one row per member.

        Returns
        -------
        gamma_o : ndarray, shape (N, r)
        beta : ndarray, shape (N, p)
        gamma_obar : ndarray, shape (N, n - r)
            Zero when the form has no ``gamma_obar``.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems import JoSonExample
        >>> form = JoSonExample().form("jo_son")  # beta = y u, gamma_obar = -y^2/2 + y^4
        >>> go, be, gb = form.signals(np.array([0.5, 1.0]), np.array([[0.3], [0.0]]))
        >>> be
        array([[0.15],
               [0.  ]])
        >>> gb
        array([[-0.0625],
               [ 0.5   ]])
        """
        N = y.shape[0]
        uc = np.ascontiguousarray(u.T)  # component first, each component contiguous
        go = self.rows("gamma_o(y, u)", self.gamma_o, self.r, N, y, uc)
        be = self.rows("beta(y, u)", self.beta, self.p, N, y, uc)
        if self.gamma_obar is None:
            gb = np.zeros((N, self.n_obar))
        else:
            gb = self.rows("gamma_obar(y, u)", self.gamma_obar, self.n_obar, N, y, uc)
        return go, be, gb

    def f_obar_rows(self, y: Array, z_obar: Array) -> Array:
        """:math:`f_{\\bar o}(y, \\hat z_{\\bar o})` ``(N, n - r)`` of the rows ``z_obar``
        ``(N, n - r)``.

        Parameters
        ----------
        y : ndarray, shape (N,)
            Measured outputs, one per member.
        z_obar : ndarray, shape (N, n - r)
            Unobservable-part estimates, one row per member.

        Returns
        -------
        ndarray, shape (N, n - r)
            :math:`f_{\\bar o}` of each row.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems import JoSonExample
        >>> form = JoSonExample().form("jo_son")  # f_obar = -z3 - (z3 + y^2/2)^3
        >>> form.f_obar_rows(np.array([0.5, 1.0]), np.array([[-1.125], [0.0]]))
        array([[ 2.125],
               [-0.125]])
        """
        return self.rows("f_obar(y, z_obar)", self.f_obar, self.n_obar,  # type: ignore[arg-type]
                         y.shape[0], y, np.ascontiguousarray(z_obar.T))

    def physical_rows(self, Z: Array) -> Array:
        """:math:`T^{-1}` of the rows ``Z`` ``(N, n)``, ``(N, n_x)`` (``Z`` itself without a map);
        non-finite where the map is undefined.

        Parameters
        ----------
        Z : ndarray, shape (N, n)
            Canonical-form rows.

        Returns
        -------
        ndarray, shape (N, n_x)
            Physical states (a copy of ``Z`` when the form has no ``to_physical``).

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems import JoSonExample
        >>> form = JoSonExample().form("jo_son")
        >>> form.physical_rows(np.array([[1.041666666666667, 0.5, -1.125]])).round(6)
        array([[ 0.5,  1. , -1. ]])
        """
        if self.to_physical is None:
            return np.array(Z, dtype=float)
        return self.rows("to_physical(z)", self.to_physical, len(self.state_names),
                         Z.shape[0], np.ascontiguousarray(Z.T))

    def normal_rows(self, X: Array) -> Array:
        """:math:`T` of the physical rows ``X`` ``(N, n_x)``, ``(N, n)``.

        Parameters
        ----------
        X : ndarray, shape (N, n_x)
            Physical states, one row per member.

        Returns
        -------
        ndarray, shape (N, n)
            Canonical-form rows.

        Raises
        ------
        DesignError
            The form has no ``from_physical`` map.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems import JoSonExample
        >>> form = JoSonExample().form("jo_son")  # T(x) = (x1^3/3 + x2, x1, x3 - x1^2/2)
        >>> form.normal_rows(np.array([[0.5, 1.0, -1.0]])).round(6)
        array([[ 1.041667,  0.5     , -1.125   ]])
        """
        if self.from_physical is None:
            raise DesignError(f"x_hat0 in physical coordinates needs the form's from_physical "
                              f"map (T of eq. 27); {self.label} has none: give z_hat0")
        return self.rows("from_physical(x)", self.from_physical, self.n, X.shape[0],
                         np.ascontiguousarray(X.T))
