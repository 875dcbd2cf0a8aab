"""The parameter-affine form of paper 001 (eq. 9, one output; eq. 21, several outputs).

.. math::

    \\dot z = A z + \\varphi(z, u) + \\psi(z, u)\\, \\theta, \\qquad y = C z

with :math:`A = \\mathrm{diag}(A_1, \\dots, A_p)` a block diagonal of integrator chains of
orders :math:`n_1, \\dots, n_p` (eq. 2), :math:`C` picking the first state of each chain,
:math:`\\varphi` triangular in each chain except its last entry (eq. 3, [A1']) and
:math:`\\psi` (:math:`n \\times q`) zero except the last row of each chain (eq. 7).

A system that has this form declares it: ``forms = (..., "affine")`` and
``_form_affine(**options)`` returning an :class:`AffineForm` (the Besançon observer asks for
it with ``system.form("affine", ...)`` and never imports a concrete system). An object with
the members ``A``, ``C``, ``phi0(x, u)`` and ``regressor(x, u)`` (one row at a time) is wrapped
by :meth:`AffineForm.from_protocol`.

**Rows.** The form's functions work on rows: ``terms(Z (N, n), U (N, m))`` returns
``phi (N, n)`` and ``psi (N, p, q)`` (the last row of :math:`\\psi` of each chain), so that
a batch of observers evaluates its model terms in one call. The systems' own forms compute
them with ``numba`` kernels over the rows (one row costs the same alone or in a batch, bit for
bit); ``phi0``, ``regressor`` and ``rhs`` of one point are the validating conveniences.

References
----------
.. [001] G. Besançon, Q. Zhang, H. Hammouri, "High-gain observer based state and parameter
   estimation in nonlinear systems", IFAC NOLCOS 2004 (``shared/papers/001_fa1af3b6b9a222a1.txt``):
   eq. 2-3 (structure), 7 (regressor), 9 (single-output form), 21 (several outputs).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .._validate import vector
from ..exceptions import DesignError, DimensionError
from .base import Array

__all__ = ["AffineForm", "chain_structure"]

#: the members an object needs to be wrapped by :meth:`AffineForm.from_protocol`
PROTOCOL = ("A", "C", "phi0", "regressor")

#: ``terms(Z (N, n), U (N, m)) -> (phi (N, n), psi_last (N, p, q))``
Terms = Callable[[Array, Array], tuple[Array, Array]]


def chain_structure(A: Any, C: Any) -> tuple[int, ...]:
    """Chain orders ``(n_1, ..., n_p)`` of ``A = diag(A_c)``, ``C = diag(C_c)`` (eq. 2, 21).

    Parameters
    ----------
    A : array_like, shape (n, n)
        Block diagonal of integrator chains (ones on the superdiagonal inside each chain).
    C : array_like, shape (p, n)
        Output matrix: row ``c`` a single 1 at the first state of chain ``c``.

    Returns
    -------
    tuple of int
        The chain orders ``(n_1, ..., n_p)``, summing to ``n``.

    Raises
    ------
    DimensionError
        ``A`` is not square or ``C`` not ``(p, n)``.
    DesignError
        ``C`` does not pick the first states of consecutive chains, or ``A`` is not the block
        diagonal of those chains.

    Examples
    --------
    >>> chain_structure([[0, 1, 0], [0, 0, 0], [0, 0, 0]], [[1, 0, 0], [0, 0, 1]])
    (2, 1)
    """
    A = np.asarray(A, dtype=float)
    C = np.asarray(C, dtype=float)
    if A.ndim != 2 or A.shape[0] != A.shape[1]:
        raise DimensionError(f"A must be a square matrix; found shape {A.shape}")
    n = A.shape[0]
    if C.ndim != 2 or C.shape[1] != n:
        raise DimensionError(f"C must have shape (p, {n}); found shape {C.shape}")
    firsts = []
    for r in range(C.shape[0]):
        nz = np.flatnonzero(C[r])
        if nz.size != 1 or C[r, nz[0]] != 1.0:
            raise DesignError(f"row {r} of C must pick one state (a single 1, eq. 2); found "
                              f"{C[r].tolist()}")
        firsts.append(int(nz[0]))
    if firsts != sorted(firsts) or not firsts or firsts[0] != 0:
        raise DesignError(f"C must pick the first state of consecutive chains, in order; "
                          f"found the states {firsts}")
    bounds = firsts + [n]
    orders = tuple(b - a for a, b in zip(bounds[:-1], bounds[1:]))
    if any(o < 1 for o in orders):
        raise DesignError(f"C picks the same state twice; found {firsts}")
    expect = np.zeros((n, n))
    for f, o in zip(firsts, orders):
        for i in range(o - 1):
            expect[f + i, f + i + 1] = 1.0
    if not np.array_equal(A, expect):
        raise DesignError(f"A must be a block diagonal of integrator chains of orders {list(orders)} "
                          f"(eq. 2 / 21); found {A.tolist()}")
    return orders


def _call(factory: Callable[..., Any], args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
    return factory(*args, **kwargs)


class AffineForm:
    """A system in the parameter-affine form of paper 001, eq. 9 (one output) or 21.

    .. math::

        \\dot z = A z + \\varphi(z, u) + \\psi(z, u)\\, \\theta, \\qquad y = C z

    Parameters
    ----------
    orders : sequence of int
        Chain orders :math:`n_1, \\dots, n_p` (one per measured output).
    theta_names : sequence of str
        Names of the :math:`q` parameters of the form.
    terms : callable ``terms(Z, U) -> (phi, psi_last)``
        The model terms of rows: ``Z`` ``(N, n)``, ``U`` ``(N, m)`` (float64, C-contiguous);
        ``phi`` ``(N, n)`` the entries of :math:`\\varphi`, ``psi_last`` ``(N, p, q)`` the last
        row of :math:`\\psi` of each chain. Fast path: not validated per call.
    label : str
        One line for messages and metadata.
    theta : array_like, optional
        True parameter values (reports only).
    state_names : sequence of str, optional
        Names of ``z`` (default ``z1..zn``).
    outputs : sequence of int, optional
        Measured channel of each chain (default ``0..p-1``).
    n_inputs : int, optional
        Width of ``u`` (default: the width of the system, or 1).
    to_physical : callable ``(Z (N, n), Theta (N, q), U (N, m)) -> X (N, n_x)``, optional
        Map of rows to the physical state; a row where it is undefined (e.g. a non-positive
        stiffness estimate) is NaN.
    from_physical : callable ``(x, theta, u) -> z``, optional
        Its inverse at one point (for an initial estimate given physically); may raise
        :class:`DesignError` where undefined.
    physical_state_names : sequence of str, optional
        Names of the physical state (with ``to_physical``).
    physical_params : callable ``Theta (N, q) -> dict of (N,) arrays``, optional
        Physical parameters recovered from the form's parameters (e.g. ``K``, ``MgL``).
    true_physical : dict, optional
        Their true values (reports only).
    param_block : sequence of int, optional
        Chain whose last row carries each parameter (for ``theta_exponents`` with unequal
        orders, see correction 3 of :mod:`hgo_mj.observers.besancon`).

    Raises
    ------
    DesignError
        ``orders`` is empty or has an entry < 1, ``theta_names`` is empty, or ``terms`` is
        not callable.
    DimensionError
        ``state_names`` does not have ``n = sum(orders)`` entries, ``outputs`` not one per
        chain, or ``theta`` not ``q`` entries.

    Examples
    --------
    >>> from hgo_mj.systems import Pendulum
    >>> f = Pendulum().form("affine", unknown=("g_over_l",))
    >>> f.orders, f.theta_names
    ((2,), ('g_over_l',))
    """

    _recipe: tuple[Callable[..., Any], tuple[Any, ...], dict[str, Any]] | None = None

    def __init__(self, *, orders: Sequence[int], theta_names: Sequence[str], terms: Terms,
                 label: str, theta: Any = None, state_names: Sequence[str] | None = None,
                 outputs: Sequence[int] | None = None, n_inputs: int | None = None,
                 to_physical: Callable[[Array, Array, Array], Array] | None = None,
                 from_physical: Callable[[Array, Array, Array], Array] | None = None,
                 physical_state_names: Sequence[str] | None = None,
                 physical_params: Callable[[Array], dict[str, Array]] | None = None,
                 true_physical: dict[str, float] | None = None,
                 param_block: Sequence[int] | None = None) -> None:
        self.orders = tuple(int(o) for o in orders)
        if not self.orders or any(o < 1 for o in self.orders):
            raise DesignError(f"orders must be positive integers; found {list(orders)}")
        self.n = sum(self.orders)
        self.p = len(self.orders)
        self.theta_names = tuple(str(s) for s in theta_names)
        self.q = len(self.theta_names)
        if self.q < 1:
            raise DesignError("the form needs at least one parameter (theta_names is empty)")
        if not callable(terms):
            raise DesignError(f"terms must be a callable; found {type(terms).__name__}")
        self.terms = terms
        self.label = label
        self.theta = None if theta is None else vector("theta", theta, self.q)
        self.firsts = tuple(int(v) for v in np.cumsum((0,) + self.orders[:-1]))
        self.lasts = tuple(f + o - 1 for f, o in zip(self.firsts, self.orders))
        self.state_names = (tuple(state_names) if state_names is not None
                            else tuple(f"z{i + 1}" for i in range(self.n)))
        if len(self.state_names) != self.n:
            raise DimensionError(f"state_names must have n = {self.n} entries; found "
                                 f"{len(self.state_names)}")
        self.outputs = tuple(range(self.p)) if outputs is None else tuple(int(o) for o in outputs)
        if len(self.outputs) != self.p:
            raise DimensionError(f"outputs must name one channel per chain ({self.p}); found "
                                 f"{len(self.outputs)}")
        self.n_inputs = None if n_inputs is None else int(n_inputs)
        self.to_physical = to_physical
        self.from_physical = from_physical
        self.physical_state_names = (tuple(physical_state_names) if physical_state_names
                                     else self.state_names)
        self.physical_params = physical_params
        self.true_physical = dict(true_physical or {})
        self.param_block = None if param_block is None else tuple(int(b) for b in param_block)

    # ------------------------------------------------------------------ pickling
    def _made_by(self, factory: Callable[..., Any], *args: Any, **kwargs: Any) -> AffineForm:
        """Record ``factory(*args, **kwargs)`` as the way to rebuild this form (its functions
        are closures of the factory, which pickle cannot store); returns the form."""
        self._recipe = (factory, args, kwargs)
        return self

    def __reduce_ex__(self, protocol: Any) -> Any:
        if self._recipe is None:
            return super().__reduce_ex__(protocol)
        return (_call, self._recipe)

    # ------------------------------------------------------------------ matrices
    @property
    def A(self) -> Array:
        """Block diagonal of integrator chains (eq. 2, 21)."""
        A = np.zeros((self.n, self.n))
        for f, o in zip(self.firsts, self.orders):
            for i in range(o - 1):
                A[f + i, f + i + 1] = 1.0
        return A

    @property
    def C(self) -> Array:
        """Picks the first state of each chain, shape ``(p, n)``."""
        C = np.zeros((self.p, self.n))
        for c, f in enumerate(self.firsts):
            C[c, f] = 1.0
        return C

    def _point(self, z: Any, u: Any) -> tuple[Array, Array]:
        zr = vector("z", z, self.n)[None]
        ur = np.ascontiguousarray(np.atleast_1d(np.asarray(u, dtype=float)))[None]
        return zr, ur

    def phi0(self, z: Any, u: Any) -> Array:
        """:math:`\\varphi(z, u)` at one point, shape ``(n,)``.

        Parameters
        ----------
        z : array_like, shape (n,)
            Form state.
        u : array_like, shape (m,) or float
            Input.

        Returns
        -------
        ndarray, shape (n,)
            :math:`\\varphi(z, u)`.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> f = Pendulum().form("affine")  # damping known: phi = (0, -d/J z2)
        >>> f.phi0([0.5, 0.0], [0.2])
        array([0., 0.])
        """
        ph, _ = self.terms(*self._point(z, u))
        return np.array(ph[0], dtype=float)

    def regressor(self, z: Any, u: Any) -> Array:
        """:math:`\\psi(z, u)` at one point, shape ``(n, q)``, zero except the last row of each
        chain.

        Parameters
        ----------
        z : array_like, shape (n,)
            Form state.
        u : array_like, shape (m,) or float
            Input.

        Returns
        -------
        ndarray, shape (n, q)
            :math:`\\psi(z, u)`, columns in the order of :attr:`theta_names`.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> f = Pendulum().form("affine")  # theta = (g_over_l, b_over_J)
        >>> f.regressor([0.5, 1.0], [0.2]).round(6)  # last row: (-sin z1, u)
        array([[ 0.      ,  0.      ],
               [-0.479426,  0.2     ]])
        """
        _, ps = self.terms(*self._point(z, u))
        out = np.zeros((self.n, self.q))
        for c, last in enumerate(self.lasts):
            out[last] = ps[0, c]
        return out

    def rhs(self, z: Any, u: Any, theta: Any) -> Array:
        """:math:`A z + \\varphi(z, u) + \\psi(z, u) \\theta` (for checks).

        Parameters
        ----------
        z : array_like, shape (n,)
            Form state.
        u : array_like, shape (m,) or float
            Input.
        theta : array_like, shape (q,)
            Parameter values, in the order of :attr:`theta_names`.

        Returns
        -------
        ndarray, shape (n,)
            :math:`\\dot z`.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> p = Pendulum()
        >>> f = p.form("affine")
        >>> f.rhs([0.5, 0.0], [0.0], f.theta).round(4)  # equals p.f: z is the state
        array([ 0.   , -9.759])
        """
        z = vector("z", z, self.n)
        th = vector("theta", theta, self.q)
        return self.A @ z + self.phi0(z, u) + self.regressor(z, u) @ th

    def __repr__(self) -> str:
        return f"AffineForm({self.label!r}, orders={list(self.orders)}, theta={list(self.theta_names)})"

    # ------------------------------------------------------------------ builders
    @classmethod
    def from_protocol(cls, obj: Any, n_inputs: int | None = None) -> AffineForm:
        """Wrap an object with ``A``, ``C``, ``phi0(x, u)``, ``regressor(x, u)`` (one point at
        a time; the rows are evaluated one by one: the slow, general path), and optionally
        ``theta`` (true values) and ``param_names``.

        Parameters
        ----------
        obj : object
            Has ``A`` ``(n, n)``, ``C`` ``(p, n)``, ``phi0(x, u) -> (n,)`` and
            ``regressor(x, u) -> (n, q)``; ``param_names`` (``q`` names, else
            ``theta1..thetaq``), ``theta``, ``state_names`` and ``input_names`` are used if
            present.
        n_inputs : int, optional
            Width of ``u`` (default: ``len(obj.input_names)``, or 1).

        Returns
        -------
        AffineForm
            The form, its ``terms`` calling ``phi0`` and ``regressor`` row by row; it pickles
            as this call.

        The regressor's shape and the structure of eq. 7 (zero except the last row of each
        chain) are checked at a probe point ``z = 0.1 (1, 2, ..., n)``, ``u = 0.3``.

        Raises
        ------
        DesignError
            A protocol member is missing (all missing ones are named), ``A``/``C`` are not
            chains, or ``psi`` is not zero outside the last rows.
        DimensionError
            ``phi0`` or ``regressor`` return the wrong shape.

        Examples
        --------
        >>> from hgo_mj.systems import BesanconExample1
        >>> f = AffineForm.from_protocol(BesanconExample1())
        >>> f
        AffineForm('BesanconExample1 (paper 001 form)', orders=[2], theta=['theta1', 'theta2'])
        >>> f.rhs([1.0, 1.0], [0.1], [1.0, 2.0]).round(6)
        array([ 1.1     , -0.816939])
        """
        missing = [m for m in PROTOCOL if not hasattr(obj, m)]
        if missing:
            raise DesignError(f"{type(obj).__name__} is not in the form of paper 001 eq. 9/21: "
                              f"missing {missing} (needs A, C, phi0(x, u), regressor(x, u)), "
                              f"and it does not declare the 'affine' form")
        orders = chain_structure(obj.A, obj.C)
        n = sum(orders)
        if n_inputs is None:
            n_inputs = len(getattr(obj, "input_names", ())) or 1
        z0 = 0.1 * np.arange(1, n + 1)
        u0 = np.full(n_inputs, 0.3)
        ps = np.asarray(obj.regressor(z0, u0), dtype=float)
        if ps.ndim != 2 or ps.shape[0] != n:
            raise DimensionError(f"regressor(x, u) of {type(obj).__name__} must have shape "
                                 f"(n, q) = ({n}, q); found shape {ps.shape}")
        q = ps.shape[1]
        ph = np.asarray(obj.phi0(z0, u0), dtype=float)
        if ph.shape != (n,):
            raise DimensionError(f"phi0(x, u) of {type(obj).__name__} must have shape ({n},); "
                                 f"found shape {ph.shape}")
        firsts = np.cumsum((0,) + orders[:-1])
        lasts = [int(f + o - 1) for f, o in zip(firsts, orders)]
        inner = np.setdiff1d(np.arange(n), lasts)
        if inner.size and np.any(ps[inner] != 0.0):
            rows = [int(r) for r in inner if np.any(ps[r] != 0.0)]
            raise DesignError(f"regressor(x, u) of {type(obj).__name__} must be zero except the "
                              f"last row of each chain (eq. 7, rows {lasts}); found non-zero rows "
                              f"{rows}")
        names = tuple(getattr(obj, "param_names", ()))
        if len(names) != q:
            names = tuple(f"theta{j + 1}" for j in range(q))
        theta = getattr(obj, "theta", None)
        phi0, reg = obj.phi0, obj.regressor

        def terms(Z: Array, U: Array) -> tuple[Array, Array]:
            N = Z.shape[0]
            phi = np.empty((N, n))
            psi = np.empty((N, len(lasts), q))
            for r in range(N):
                P = np.asarray(reg(Z[r], U[r]), dtype=float)
                if P.shape != (n, q):
                    raise DimensionError(f"regressor(x, u) must have shape ({n}, {q}); found "
                                         f"shape {P.shape}")
                phi[r] = phi0(Z[r], U[r])
                psi[r] = P[lasts]
            return phi, psi

        return cls(orders=orders, theta_names=names, terms=terms,
                   label=f"{type(obj).__name__} (paper 001 form)", theta=theta,
                   state_names=getattr(obj, "state_names", None) or None, n_inputs=n_inputs,
                   )._made_by(cls.from_protocol, obj, n_inputs)
