"""Any ODE, its observability normal form derived (issue 12).

A control researcher writes the model as on paper::

    cls = ode_system(states=["x1", "x2"], inputs=["u"], params={"a": 9.81, "b": 0.1},
                     f=["x2", "-a*sin(x1) - b*x2 + u"], h="x1")

and gets a :class:`System` whose single-output normal form (paper 000, eq. 1) is derived:

* the Lie derivatives ``L_f^k h`` and the observability map
  ``Phi(x) = (h, L_f h, ..., L_f^(n-1) h)`` with its Jacobian;
* the relative degree ``r`` (the first ``k`` with ``u`` in ``L_f^k h``): where ``r < n`` the
  normal form would need derivatives of ``u``: :attr:`SymbolicSystem.normal_form_problem` says
  so (the EKF/UKF still apply); with ``held_input=True``, ``Phi`` depends on ``u`` and ``phi``
  holds for an input held between its steps (``u' = 0``), the construction of paper 000 for its
  bioreactor (eq. 16), and :attr:`SymbolicSystem.normal_form_note` says so;
* ``phi(z, u) = L_f^n h`` at ``x = Phi^-1(z)``, with ``z_n' = phi(z, u)``;
* the inverse map, in closed form where each equation ``Phi_k(x) = z_k`` brings in one new
  unknown with a single solution (``sympy.solve``), else Newton's method on the Jacobian from the
  last inverse (failures counted in :attr:`SymbolicSystem.inverse_failures`);
* over a stated box ``region``, the observability rank checked at sampled points
  (:attr:`SymbolicSystem.rank_problem` names a point where it drops) and a sampled Lipschitz
  bound of ``phi`` in ``z`` (:attr:`SymbolicSystem.lipschitz`, for the Riccati observer's
  ``min_gamma``; paper 004, Theorem 1).

**Parsing without evaluating user text.** sympy's ``sympify``/``parse_expr`` call ``eval`` and
never see the user's strings: :func:`parse` walks Python's ``ast`` of each expression and
builds the sympy expression node by node, allowing numbers, declared names, ``+ - * / **``,
unary signs and calls of :data:`FUNCTIONS`; anything else is a :class:`ModelError` naming it and
its position. Sizes are bounded before sympy sees them (sympy computes with exact numbers:
``9**9**9`` would never end): at most :data:`MAX_CHARS` characters, :data:`MAX_NODES` nodes
nested at most :data:`MAX_DEPTH` deep, constant exponents up to :data:`MAX_EXPONENT` in
magnitude and constants within float64's range; a constant that is not a finite real number
(``sqrt(-1)``, ``1/0``) is refused where it appears.

**Evaluation.** Every derived expression is compiled into a numba row function
(:mod:`hgo_mj.systems._codegen`: sympy's code printer over the checked expression with its
symbols renamed, so no user text reaches the generated source); :meth:`SymbolicSystem.phi_batch`
is one kernel over the observers' rows, and :attr:`SymbolicSystem.compiled` hands ``f`` and its
Jacobians to the Kalman filters' kernels. ``scripts/bench_symbolic.py`` measures a derived system
against the hand-written one (BENCHMARKS.md).
"""

from __future__ import annotations

import ast
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from .._extras import require

# the `symbolic` extra, named in one line before the imports that need it
require("sympy", "symbolic", "an ODE plant given as text (hgo_mj.systems.symbolic)")

import sympy  # noqa: E402
from numba import njit  # noqa: E402

from ..exceptions import ModelError  # noqa: E402
from ._codegen import row_function  # noqa: E402
from .base import Array, CompiledModel, System  # noqa: E402

#: the functions an expression may call: name -> (sympy function, numpy function)
FUNCTIONS: dict[str, tuple[Any, Callable[[Any], Any]]] = {
    "sin": (sympy.sin, np.sin), "cos": (sympy.cos, np.cos), "tan": (sympy.tan, np.tan),
    "exp": (sympy.exp, np.exp), "log": (sympy.log, np.log), "sqrt": (sympy.sqrt, np.sqrt),
    "tanh": (sympy.tanh, np.tanh), "sinh": (sympy.sinh, np.sinh),
    "cosh": (sympy.cosh, np.cosh), "atan": (sympy.atan, np.arctan),
    "asin": (sympy.asin, np.arcsin), "acos": (sympy.acos, np.arccos),
    "abs": (sympy.Abs, np.abs),
}
_NUMPY = {sym: fn for sym, fn in FUNCTIONS.values()}
# what derivatives of abs() bring in: sign, and Dirac deltas (zero away from the kink)
_NUMPY[sympy.sign] = np.sign
_CONSTANTS = {"pi": sympy.pi, "e": sympy.E}
_BINOPS: dict[type, Callable[[Any, Any], Any]] = {
    ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b, ast.Mult: lambda a, b: a * b,
    ast.Div: lambda a, b: a / b, ast.Pow: lambda a, b: a ** b}
#: the longest expression :func:`parse` takes (characters)
MAX_CHARS = 10_000
#: the most nodes (numbers, names, operations, calls) of one expression
MAX_NODES = 2_000
#: the deepest nesting of one expression (a sum or product of k terms nests k deep)
MAX_DEPTH = 200
#: the largest magnitude of a constant exponent (``x**e``, ``2**e``)
MAX_EXPONENT = 100
#: the largest power of ten of a constant: float64's range, where the compiled model computes
_MAX_LOG10 = 308.0
_FLOAT_MAX = int(np.finfo(float).max)
#: values that are not finite real numbers (a constant like ``sqrt(-1)`` or ``1/0``)
_NOT_REAL = (sympy.I, sympy.zoo, sympy.nan, sympy.oo, -sympy.oo)


def parse(text: Any, names: Mapping[str, sympy.Symbol], where: str) -> sympy.Expr:
    """The sympy expression of ``text``, built from its Python ``ast`` (never ``eval``).

    Parameters
    ----------
    text : str
        The expression, e.g. ``"-a*sin(x1) + u"``.
    names : mapping of str to sympy.Symbol
        The declared names (states, inputs, parameters) and their symbols.
    where : str
        What the expression is (``"f[1]"``), for messages.

    Returns
    -------
    sympy.Expr

    Raises
    ------
    ModelError
        Not a string, a syntax error (with its column), or a name, operator or call that is not
        allowed (named, with its column).

    Examples
    --------
    >>> x = sympy.Symbol("x", real=True)
    >>> parse("2*sin(x) + x**2", {"x": x}, "h")
    x**2 + 2*sin(x)
    >>> parse("__import__('os')", {"x": x}, "h")
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.ModelError: h = "__import__('os')", column 1: a call of '__import__' ...
    """
    if not isinstance(text, str):
        raise ModelError(f"{where} must be an expression as a string; found {text!r} "
                         f"({type(text).__name__})")
    if len(text) > MAX_CHARS:
        raise ModelError(f"{where} = {_quote(text)}: {len(text)} characters; an expression "
                         f"has at most {MAX_CHARS}")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        col = exc.offset or len(text.strip()) + 1  # 0: the expression ended too early
        raise ModelError(f"{where} = {_quote(text)}: syntax error at column {col}: "
                         f"{exc.msg}") from None
    except (MemoryError, RecursionError, ValueError) as exc:  # nested too deep, huge literals
        raise ModelError(f"{where} = {_quote(text)}: Python cannot parse it "
                         f"({type(exc).__name__}: {str(exc) or 'too deeply nested'})") from None
    _check_size(tree.body, where, text)
    try:
        return _node(tree.body, names, where, text)
    except (MemoryError, RecursionError, OverflowError) as exc:
        raise ModelError(f"{where} = {_quote(text)}: too large to build "
                         f"({type(exc).__name__})") from None


def _quote(text: str, most: int = 60) -> str:
    """``repr(text)``, its middle left out beyond ``most`` characters (messages stay one
    short line)."""
    if len(text) <= most:
        return repr(text)
    return repr(text[:most // 2]) + f" ... ({len(text)} characters) ... " + repr(text[-10:])


def _check_size(tree: ast.AST, where: str, text: str) -> None:
    """Refuse more than :data:`MAX_NODES` nodes or a nesting deeper than :data:`MAX_DEPTH`
    (walked without recursion: the check must not overflow the stack it protects)."""
    stack, count = [(tree, 1)], 0
    while stack:
        node, depth = stack.pop()
        count += 1
        if depth > MAX_DEPTH:
            raise ModelError(f"{where} = {_quote(text)}, column "
                             f"{getattr(node, 'col_offset', 0) + 1}: nested more than "
                             f"{MAX_DEPTH} deep (a sum or product of k terms nests k deep)")
        if count > MAX_NODES:
            raise ModelError(f"{where} = {_quote(text)}: more than {MAX_NODES} numbers, names "
                             f"and operations in one expression")
        stack.extend((child, depth + 1) for child in ast.iter_child_nodes(node)
                     if not isinstance(child, (ast.operator, ast.unaryop, ast.expr_context)))


def _log10(value: Any) -> float:
    """``log10 |value|`` of a nonzero sympy number, however large (no float overflow)."""
    if isinstance(value, sympy.Rational):
        return math.log10(abs(int(value.p))) - math.log10(int(value.q))
    return float(sympy.log(abs(value), 10).evalf(15))


def _power(base: Any, exp: Any, at: str) -> Any:
    """``base ** exp`` with a constant exponent of at most :data:`MAX_EXPONENT` in magnitude
    and, for a constant base, a result within float64's range (sympy's exact powers of exact
    numbers would not end: ``9**9**9``)."""
    if isinstance(exp, sympy.Number) and exp.is_finite:
        if abs(exp) > MAX_EXPONENT:
            raise ModelError(f"{at}: the exponent {_quote(str(exp), 30)} is too large: constant "
                             f"exponents are at most {MAX_EXPONENT} in magnitude")
        if isinstance(base, sympy.Number) and base.is_finite and base != 0:
            size = float(abs(exp)) * abs(_log10(base))
            if size > _MAX_LOG10:
                raise ModelError(f"{at}: the power's magnitude is 10^(+-{size:.0f}), beyond "
                                 f"float64's range (10^{_MAX_LOG10:.0f})")
    return base ** exp


def _real(value: Any, at: str, node: ast.AST) -> Any:
    """``value``, unless it brought in a number that is not a finite real one (``sqrt(-1)``,
    ``log(0)``, ``1/0``): the compiled model computes with real floats."""
    if value.has(*_NOT_REAL) or (value.is_number and value.is_extended_real is False):
        raise ModelError(f"{at}: {ast.unparse(node)} is {value}, not a finite real number")
    return value


def _node(node: ast.AST, names: Mapping[str, sympy.Symbol], where: str, text: str) -> Any:
    at = f"{where} = {_quote(text)}, column {getattr(node, 'col_offset', 0) + 1}"
    if isinstance(node, ast.Constant) and type(node.value) in (int, float):
        number: int | float = node.value  # type: ignore[assignment]
        if (abs(number) > _FLOAT_MAX if isinstance(number, int) else not math.isfinite(number)):
            raise ModelError(f"{at}: the number {_quote(str(number), 30)} is beyond "
                             f"float64's range (10^{_MAX_LOG10:.0f})")
        return sympy.Float(number) if isinstance(number, float) else sympy.Integer(number)
    if isinstance(node, ast.Name):
        if node.id in names:
            return names[node.id]
        if node.id in _CONSTANTS:
            return _CONSTANTS[node.id]
        raise ModelError(f"{at}: {node.id!r} is not declared; declared: {sorted(names)} "
                         f"(and the constants {sorted(_CONSTANTS)})")
    if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
        left = _node(node.left, names, where, text)
        right = _node(node.right, names, where, text)
        if isinstance(node.op, ast.Pow):
            return _real(_power(left, right, at), at, node)
        value = _BINOPS[type(node.op)](left, right)
        # from finite real operands, only a division brings in what is not (1/0)
        return _real(value, at, node) if isinstance(node.op, ast.Div) else value
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        value = _node(node.operand, names, where, text)
        return -value if isinstance(node.op, ast.USub) else value
    if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and not node.keywords
            and node.func.id in FUNCTIONS):
        if len(node.args) != 1:
            raise ModelError(f"{at}: {node.func.id}() takes one argument; found "
                             f"{len(node.args)}")
        arg = _node(node.args[0], names, where, text)
        return _real(FUNCTIONS[node.func.id][0](arg), at, node)
    what = (f"a call of {ast.unparse(node.func)!r} (allowed: {sorted(FUNCTIONS)})"
            if isinstance(node, ast.Call) else f"{type(node).__name__} {ast.unparse(node)!r}")
    allowed = "" if isinstance(node, ast.Call) else f", and calls of {sorted(FUNCTIONS)}"
    raise ModelError(f"{at}: {what} is not allowed in an expression (numbers, declared names, "
                     f"+ - * / **{allowed})")


def _names(what: str, value: Any, allow_empty: bool = False) -> tuple[str, ...]:
    ok = isinstance(value, (list, tuple)) and all(isinstance(v, str) and v.isidentifier()
                                                   for v in value)
    if not ok or (not value and not allow_empty) or len(set(value)) != len(value):
        raise ModelError(f"{what} must be a list of distinct names (identifiers); found "
                         f"{value!r}")
    return tuple(value)


class SymbolicSystem(System):
    """A system derived from expressions by :func:`ode_system` (one subclass per model).

    Every derived expression is compiled (:mod:`hgo_mj.systems._codegen`): ``dynamics``,
    ``output``, the Jacobians the Kalman filters use (also as :attr:`compiled`, so their kernels
    run it without returning to Python), ``Phi`` and its Jacobian, the inverse and ``phi``.
    :meth:`phi_batch`, the high-gain observers' model term, is one kernel over the rows.

    Parameters
    ----------
    **params : float
        Parameter values overriding the defaults given to :func:`ode_system`.

    Examples
    --------
    >>> cls = ode_system(["x1", "x2"], ["x2", "-a*sin(x1) + u"], "x1", inputs=["u"],
    ...                  params={"a": 9.81})
    >>> s = cls(a=4.0)
    >>> s.params, s.to_normal([0.5, 0.1], [0.0])
    ({'a': 4.0}, array([0.5, 0.1]))
    """

    reference = "normal form derived symbolically (paper 000, eq. 1)"
    #: a sampled point of the region where the observability rank drops, else None
    rank_problem: ClassVar[str | None] = None
    #: sampled Lipschitz bound of phi in z over the region
    lipschitz: ClassVar[float] = float("nan")
    #: whether the inverse map is in closed form (else Newton)
    closed_form_inverse: ClassVar[bool] = False
    #: the first k with u in L_f^k h (None: u enters no L_f^k h, k <= n)
    relative_degree: ClassVar[int | None] = None
    #: why the single-output normal form does not hold (relative degree < n without
    #: ``held_input``), else None
    normal_form_problem: ClassVar[str | None] = None
    #: where the normal form holds only for a held input (relative degree < n), why
    normal_form_note: ClassVar[str | None] = None
    #: why the model is not in observer form (y = x_1, f = A w + r(y, u; theta)), so has no
    #: derived AOCF (paper 002); None where it is
    aocf_problem: ClassVar[str | None] = None
    #: why there is no derived Jo-Son form (paper 003, eq. 10) for the default unknowns
    jo_son_problem: ClassVar[str | None] = None
    _sym: ClassVar[dict[str, Any]] = {}

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)
        self.inverse_failures = 0
        self._last = np.array(self.default_x0, dtype=float)
        self._rows_last = np.empty((0, len(self.state_names)))
        self._cvec = np.array([self.params[k] for k in self.param_names], dtype=float)

    def _c(self, p: Mapping[str, float] | None = None) -> Array:
        if p is None or p is self.params:
            return self._cvec
        return np.array([p[k] for k in self.param_names], dtype=float)

    def _u(self, u: Any) -> Array:
        return (np.zeros(len(self.input_names)) if u is None
                else np.asarray(u, dtype=float).reshape(len(self.input_names)))

    def dynamics(self, t: float, x: Array, u: Array, p: Any = None) -> Array:  # type: ignore[override]
        out = np.empty(len(self.state_names))
        self._sym["f"](np.asarray(x, dtype=float), self._u(u), self._c(p), out)
        return out

    def output(self, x: Array, p: Any = None) -> Array:  # type: ignore[override]
        out = np.empty(1)
        self._sym["h"](np.asarray(x, dtype=float), self._c(p), out)
        return out

    def jacobian(self, t: float, x: Array, u: Array, p: Any = None) -> Array:
        """:math:`\\partial f/\\partial x` at ``(x, u)`` (derived, compiled).

        Parameters
        ----------
        t : float
            Time (unused: the model is autonomous).
        x : array_like, shape (n,)
        u : array_like, shape (m,)
        p : mapping, optional
            Parameter values (default the system's).

        Returns
        -------
        ndarray, shape (n, n)

        Examples
        --------
        >>> s = ode_system(["x1", "x2"], ["x2", "-a*sin(x1)"], "x1", params={"a": 2.0})()
        >>> s.jacobian(0.0, [0.0, 0.0], [])
        array([[ 0.,  1.],
               [-2.,  0.]])
        """
        n = len(self.state_names)
        out = np.empty((n, n))
        self._sym["jac"](np.asarray(x, dtype=float), self._u(u), self._c(p), out)
        return out

    def param_jacobian(self, t: float, x: Array, u: Array, p: Any,
                       names: Sequence[str]) -> Array:
        """:math:`\\partial f/\\partial p` for the parameters ``names`` (derived, compiled).

        Parameters
        ----------
        t : float
            Time (unused).
        x : array_like, shape (n,)
        u : array_like, shape (m,)
        p : mapping or None
            Parameter values (None: the system's).
        names : sequence of str
            The parameters, columns in this order.

        Returns
        -------
        ndarray, shape (n, len(names))

        Examples
        --------
        >>> s = ode_system(["x1", "x2"], ["x2", "-a*sin(x1)"], "x1", params={"a": 2.0})()
        >>> s.param_jacobian(0.0, [np.pi / 2, 0.0], [], None, ["a"])
        array([[ 0.],
               [-1.]])
        """
        out = np.empty((len(self.state_names), len(self.param_names)))
        self._sym["pjac"](np.asarray(x, dtype=float), self._u(u), self._c(p), out)
        return out[:, self._param_columns(names)]

    def _form_affine(self, unknown: Sequence[str] | None = None) -> Any:
        """The derived normal form in paper 001's eq. 9: ``z_k' = z_(k+1)`` and
        :math:`\\dot z_n = \\varphi_0(z, u) + \\psi(z, u)\\,\\theta`, with the regressor
        :math:`\\psi_j = \\partial\\varphi/\\partial\\theta_j` (eq. 7) derived, for the parameters
        ``unknown`` (default: the parameters in declaration order, each kept where ``phi``
        stays jointly linear in those kept).

        Parameters
        ----------
        unknown : sequence of str, optional
            The parameters the Besançon observer estimates.

        Returns
        -------
        AffineForm
            Its ``terms`` compiled; the physical state from the estimate through the derived
            inverse at the estimated parameters.

        Raises
        ------
        DesignError
            ``unknown`` names no parameter or an unknown one, or ``phi`` is not linear in it
            (the regressor would depend on the parameters: no linear parametrization).
        """
        from ..exceptions import DesignError
        from .affine_form import AffineForm

        self._require()
        s = self._sym
        P = s["params"]
        phi_z = _phi_z(s)
        if phi_z is None:
            raise DesignError(f"{type(self).__name__}: the affine form needs phi in normal-form "
                              f"coordinates, which needs the inverse map in closed form (this "
                              f"system's is Newton's)")
        linear: list[str] = []
        for k in self.param_names:  # greedily, in declaration order, while jointly linear
            if _linear_in(phi_z, [P[j] for j in [*linear, k]]):
                linear.append(k)
        names = tuple(linear if unknown is None else unknown)
        bad = [k for k in names if k not in P]
        if not names or bad or len(set(names)) != len(names):
            raise DesignError(f"unknown must be distinct parameter names of {list(P)}; found "
                              f"{list(names)}")
        if not _linear_in(phi_z, [P[k] for k in names]):
            raise DesignError(f"phi = {phi_z} is not linear in {list(names)} (paper 001, eq. 9 "
                              f"needs phi_0 + psi theta with psi free of theta); it is linear "
                              f"in {linear}")
        terms = _affine_terms(self, names)
        idx = np.array([self.param_names.index(k) for k in names], dtype=np.int64)
        kernels, c = s["kernels"], self._cvec

        def to_physical(Z: Array, TH: Array, U: Array) -> Array:
            C = np.tile(c, (len(Z), 1))
            C[:, idx] = TH
            return kernels.inverse_rows_p(np.ascontiguousarray(Z, dtype=float),  # type: ignore[no-any-return]
                                          np.ascontiguousarray(U, dtype=float), C)

        n = len(self.state_names)
        return AffineForm(orders=(n,), theta_names=names, terms=terms,
                          label=f"{self.name}: z{n}' = phi0 + psi theta, unknown {list(names)}",
                          theta=[self.params[k] for k in names],
                          state_names=tuple(f"z{i + 1}" for i in range(n)),
                          n_inputs=len(self.input_names),
                          to_physical=None if s["identity"] else to_physical,
                          physical_state_names=self.state_names,
                          true_physical={k: self.params[k] for k in names})

    def _form_aocf(self, unknown: Sequence[str] | None = None, c2: float = 2.0) -> Any:
        """The adaptive observer canonical form of paper 002 (eq. 2.2-2.3) where the model is
        in observer form in its own coordinates: ``y = x_1`` and
        ``f(x, u) = A w + r(y, u; theta)`` with ``w = (x_2, ..., x_n)``, ``A`` constant and
        ``r`` linear in the unknowns (:attr:`aocf_problem` says why not otherwise).

        With the pair ``(F_0, k^T)`` (``F_0 = A[1:]``, ``k^T = A[0]``), ``K`` places the
        eigenvalues of ``F = F_0 - K k^T`` at ``-c2`` (Ackermann) and ``x = (y, w - K y)``:

        .. math::

            \\dot x = \\begin{bmatrix} 0 & k^T \\\\ 0 & F \\end{bmatrix} x
            + \\begin{bmatrix} \\psi_1 \\\\ \\Psi_w - K \\psi_1 \\end{bmatrix} \\theta
            + \\begin{bmatrix} k^T K y + r_{0,1} \\\\
              (F_0 - K k^T) K y + r_{0,w} - K r_{0,1} \\end{bmatrix}

        with ``psi = d r/d theta`` and ``r_0 = r`` at ``theta = 0`` (derived here; for the
        pendulum it is the hand-written form of ``AOCF.second_order``, tested).

        Parameters
        ----------
        unknown : sequence of str, optional
            The parameters to estimate (default: in declaration order, each kept where ``r``
            stays jointly linear in those kept and ``A`` is free of it).
        c2 : float
            The eigenvalues ``-c2`` of ``F`` (> 0).

        Returns
        -------
        AOCF
            On rows; ``theta_true`` the system's values of ``unknown``.

        Raises
        ------
        DesignError
            The model is not in observer form (:attr:`aocf_problem`), ``unknown`` is not a
            set of parameters ``r`` is linear in and ``A`` is free of, or ``c2`` is not > 0.
        """
        from .._validate import finite_scalar
        from ..exceptions import DesignError
        from .aocf import AOCF

        if self.aocf_problem is not None:
            raise DesignError(f"{type(self).__name__} has no AOCF (paper 002, eq. 2.2): "
                              f"{self.aocf_problem}")
        c2 = finite_scalar("c2", c2, positive=True)
        s = self._sym
        P, (Aw, r) = s["params"], s["observer_form"]
        X, U = s["x"], s["u"]
        names, subs = _aocf_unknowns(self, unknown)
        n, m = len(X), len(names)
        A = np.array([[float(e.xreplace(subs)) for e in row] for row in Aw], dtype=float)
        k_row, F0 = A[0], A[1:]
        K = _ackermann(F0, k_row, c2)
        thetas = [P[k] for k in names]
        psi = [[sympy.diff(e, t) for t in thetas] for e in r]
        r0 = [e.xreplace({t: 0 for t in thetas}) for e in r]
        y = X[0]
        Km = [sympy.Float(v) for v in K]
        omega = list(psi[0]) + [psi[1 + i][j] - Km[i] * psi[0][j]
                                for i in range(n - 1) for j in range(m)]
        FK = (F0 - np.outer(K, k_row)) @ K
        g = [sympy.Float(float(k_row @ K)) * y + r0[0]] + [
            sympy.Float(float(FK[i])) * y + r0[1 + i] - Km[i] * r0[0] for i in range(n - 1)]
        args = [("x", [y]), ("u", U), ("c", list(P.values()))]
        signals, alpha = _signals([e.xreplace(subs) for e in omega], n, m)
        omega_row = row_function("aocf_omega", signals, (len(signals),), args)
        g_row = row_function("aocf_g", [e.xreplace(subs) for e in g], (n,), args)
        rows_kernel = _aocf_rows(omega_row, g_row, len(signals), n)
        c = self._cvec
        R = np.zeros((n, n))
        R[0, 1:] = k_row
        R[1:, 1:] = F0 - np.outer(K, k_row)

        def omega_fn(Y: Array, Uq: Array) -> Array:
            return rows_kernel(np.ascontiguousarray(Y, dtype=float).reshape(-1),  # type: ignore[no-any-return]
                               np.ascontiguousarray(Uq, dtype=float), c)[0]

        def g_fn(Y: Array, Uq: Array) -> Array:
            return rows_kernel(np.ascontiguousarray(Y, dtype=float).reshape(-1),  # type: ignore[no-any-return]
                               np.ascontiguousarray(Uq, dtype=float), c)[1]

        def to_physical(Xa: Array, TH: Array, Uq: Array) -> tuple[Array, Array]:
            S = np.array(Xa, dtype=float)
            S[:, 1:] += np.outer(S[:, 0], K)
            return S, np.empty((len(S), 0))

        def from_physical(S: Array, TH: Array, Uq: Array) -> Array:
            Xa = np.array(S, dtype=float)
            Xa[:, 1:] -= np.outer(Xa[:, 0], K)
            return Xa

        return AOCF(R, alpha, omega_fn, g=g_fn, theta_names=names,
                    omega_names=[str(e) for e in signals],
                    to_physical=to_physical, from_physical=from_physical,
                    state_names=self.state_names, rows=True,
                    label=f"{self.name}: AOCF derived, c2={c2:g}, unknown {list(names)}",
                    theta_true=[self.params[k] for k in names])

    def _form_jo_son(self, unknown: Sequence[str] | None = None) -> Any:
        """The canonical form of Jo and Son (paper 003, eq. 10, no unobservable part) where the
        model is in observer form (``y = x_1``, ``f = A w + r(y, u)``, see
        :meth:`_form_aocf`) and, in the observer canonical coordinates, the parameters enter
        along one constant direction ``b``:

        .. math::

            z = T x, \\quad T^{-1} = [v, A v, \\dots, A^{n-1} v], \\quad
            v = O^{-1} e_n, \\qquad
            \\dot z = A_o z + \\gamma_o(y, u) + b\\, \\beta^T(y, u)\\, \\theta, \\quad y = z_n

        with ``A`` the linear part (its first column moved into ``r``: output injection), ``O``
        the observability matrix of ``(A, e_1^T)``, ``A_o`` the lower shift, ``b`` scaled to
        ``b_n = 1`` and ``beta_j = (T psi)_{n j}``.

        Parameters
        ----------
        unknown : sequence of str, optional
            The parameters to estimate (default as :meth:`_form_aocf`).

        Returns
        -------
        JoSonForm

        Raises
        ------
        DesignError
            Not in observer form, the parameters do not enter along one constant direction,
            or ``b_n = 0`` (they do not reach the output's first derivative).
        """
        from ..exceptions import DesignError
        from .jo_son_form import JoSonForm

        if self.aocf_problem is not None:
            raise DesignError(f"{type(self).__name__} has no Jo-Son form (paper 003, eq. 10): "
                              f"{self.aocf_problem}")
        names, T, b, gamma, beta = _jo_son_structure(self, unknown)
        s = self._sym
        n, m = len(self.state_names), len(self.input_names)
        args = [("x", [s["x"][0]]), ("u", s["u"]), ("c", list(s["params"].values()))]
        kernel = _aocf_rows(row_function("jo_son_gamma", gamma, (n,), args),
                            row_function("jo_son_beta", beta, (len(names),), args),
                            n, len(names))
        c, Tinv = self._cvec, np.linalg.inv(T)

        def rows(y: Any, u: Any) -> tuple[Array, Array, bool]:
            one = np.ndim(y) == 0
            Y = np.atleast_1d(np.asarray(y, dtype=float))
            Uq = np.asarray(u, dtype=float).reshape(m, -1).T if m else np.zeros((len(Y), 0))
            G, Bt = kernel(np.ascontiguousarray(Y), np.ascontiguousarray(Uq), c)
            return G, Bt, one

        def gamma_o(y: Any, u: Any) -> Sequence[Any]:
            G, _, one = rows(y, u)
            return [float(G[0, i]) if one else G[:, i] for i in range(n)]

        def beta_fn(y: Any, u: Any) -> Sequence[Any]:
            _, Bt, one = rows(y, u)
            return [float(Bt[0, j]) if one else Bt[:, j] for j in range(len(names))]

        def to_physical(z: Any) -> Sequence[Any]:
            return list(Tinv @ np.asarray(z, dtype=float))

        def from_physical(x: Any) -> Sequence[Any]:
            return list(T @ np.asarray(x, dtype=float))

        return JoSonForm(b, gamma_o, beta_fn, theta_names=names, to_physical=to_physical,
                         from_physical=from_physical, state_names=self.state_names,
                         label=f"{self.name}: Jo-Son form derived, unknown {list(names)}")

    def _require(self) -> None:
        if self.normal_form_problem is not None:
            raise ModelError(self.normal_form_problem)

    def to_normal(self, x: Any, u: Any = None) -> Array:
        self._require()
        out = np.empty(len(self.state_names))
        self._sym["Phi"](np.asarray(x, dtype=float), self._u(u), self._c(), out)
        return out

    def from_normal(self, z: Any, u: Any = None) -> Array:
        self._require()
        return self.from_normal_unchecked(np.asarray(z, dtype=float), self._u(u))

    def from_normal_unchecked(self, z: Array, u: Array) -> Array:
        if self._sym["identity"]:  # the normal form is the state: z back as it is
            return z
        X = self.from_normal_batch(np.asarray(z, dtype=float).reshape(1, -1),
                                   np.asarray(u, dtype=float).reshape(1, -1),
                                   start=self._last.reshape(1, -1))
        self._last = X[0]
        return X[0]

    def from_normal_batch(self, Z: Array, U: Array, start: Array | None = None) -> Array:
        """``Phi^-1`` of the rows ``Z`` at inputs ``U``: the closed form, or Newton's method
        from ``start`` (default: the rows' last inverse, failures counted in
        :attr:`inverse_failures`), compiled.

        Parameters
        ----------
        Z : array_like, shape (N, n)
            Normal-form states.
        U : array_like, shape (N, m)
            Inputs.
        start : array_like, shape (N, n), optional
            Newton's initial guesses.

        Returns
        -------
        ndarray, shape (N, n)
            The states ``x`` with ``Phi(x, u) = z``.

        Examples
        --------
        >>> s = ode_system(["x1", "x2"], ["x2", "-x1"], "x1 + x1**3/3")()
        >>> X = s.from_normal_batch([[0.2 + 0.2**3 / 3, 0.0]], [[]])
        >>> np.round(X, 12)
        array([[0.2, 0. ]])
        """
        Z = np.ascontiguousarray(Z, dtype=float)
        U = np.ascontiguousarray(U, dtype=float)
        k = self._sym["kernels"]
        if self._sym["identity"]:
            return Z
        if self.closed_form_inverse:
            return k.inverse_rows(Z, U, self._cvec)  # type: ignore[no-any-return]
        X = self._newton_start(Z) if start is None else np.array(start, dtype=float)
        self.inverse_failures += int(k.newton_rows(Z, U, self._cvec, X))
        if start is None:
            self._rows_last = X
        return X

    def _newton_start(self, Z: Array) -> Array:
        """Each row's last inverse (the default initial state where the batch is new), with
        non-finite rows restarted at zero."""
        if self._rows_last.shape != Z.shape:
            self._rows_last = np.tile(np.asarray(self.default_x0, dtype=float), (len(Z), 1))
        X = self._rows_last.copy()
        X[~np.isfinite(X).all(axis=1)] = 0.0
        return X

    def phi(self, z: Any, u: Any = None) -> float:
        self._require()
        return self.phi_unchecked(np.asarray(z, dtype=float), self._u(u))

    def phi_unchecked(self, z: Array, u: Array) -> float:
        x = self.from_normal_unchecked(z, u)
        out = np.empty(1)
        self._sym["phi"](x, np.asarray(u, dtype=float), self._c(), out)
        return float(out[0])

    def phi_batch(self, Z: Array, U: Array) -> Array:
        Z = np.ascontiguousarray(Z, dtype=float)
        U = np.ascontiguousarray(U, dtype=float)
        k = self._sym["kernels"]
        if self.closed_form_inverse:
            return k.phi_rows(Z, U, self._cvec)  # type: ignore[no-any-return]
        X = self._newton_start(Z)
        self.inverse_failures += int(k.newton_rows(Z, U, self._cvec, X))
        self._rows_last = X
        return k.phi_x_rows(X, U, self._cvec)  # type: ignore[no-any-return]


class _Kernels:
    """The row loops of one derived system, compiled with its row functions as constants (so
    a call passes arrays only): ``inverse_rows(Z, U, c)`` (closed form), ``phi_rows(Z, U, c)``
    (closed-form inverse, then ``phi``), ``newton_rows(Z, U, c, X)`` (``Phi(x) = z`` by
    Newton's method from ``X``, overwritten with the solutions; returns the number of rows that
    did not converge in 30 steps) and ``phi_x_rows(X, U, c)``."""

    def __init__(self, n: int, Phi: Any, PhiJ: Any, phi: Any, inverse: Any) -> None:
        @njit(error_model="numpy")
        def phi_x_rows(X: Array, U: Array, c: Array) -> Array:
            out = np.empty(X.shape[0])
            v = np.empty(1)
            for b in range(X.shape[0]):
                phi(X[b], U[b], c, v)
                out[b] = v[0]
            return out

        @njit(error_model="numpy")
        def newton_rows(Z: Array, U: Array, c: Array, X: Array) -> int:
            r = np.empty(n)
            J = np.empty((n, n))
            failures = 0
            for b in range(Z.shape[0]):
                x = X[b]
                scale = 1.0 + np.max(np.abs(Z[b]))
                ok = False
                for _ in range(30):
                    Phi(x, U[b], c, r)
                    r -= Z[b]
                    if np.max(np.abs(r)) <= 1e-12 * scale:
                        ok = True
                        break
                    PhiJ(x, U[b], c, J)
                    if not np.isfinite(J).all() or abs(np.linalg.det(J)) < 1e-300:
                        break
                    x -= np.linalg.solve(J, r)
                if not ok:
                    failures += 1
            return failures

        self.phi_x_rows, self.newton_rows = phi_x_rows, newton_rows
        if inverse is None:
            return

        @njit(error_model="numpy")
        def inverse_rows(Z: Array, U: Array, c: Array) -> Array:
            X = np.empty_like(Z)
            for b in range(Z.shape[0]):
                inverse(Z[b], U[b], c, X[b])
            return X

        @njit(error_model="numpy")
        def phi_rows(Z: Array, U: Array, c: Array) -> Array:
            out = np.empty(Z.shape[0])
            x = np.empty(n)
            v = np.empty(1)
            for b in range(Z.shape[0]):
                inverse(Z[b], U[b], c, x)
                phi(x, U[b], c, v)
                out[b] = v[0]
            return out

        @njit(error_model="numpy")
        def inverse_rows_p(Z: Array, U: Array, C: Array) -> Array:
            X = np.empty_like(Z)
            for b in range(Z.shape[0]):
                inverse(Z[b], U[b], C[b], X[b])
            return X

        self.inverse_rows, self.phi_rows = inverse_rows, phi_rows
        self.inverse_rows_p = inverse_rows_p


def _phi_z(s: dict[str, Any]) -> Any:
    """``phi`` in normal-form coordinates, ``phi(Phi^-1(z, u), u)`` (closed-form inverse only;
    else None), simplified once and kept."""
    e = s["exprs"]
    if "phi_z" not in e:
        e["phi_z"] = None if e["inverse"] is None else sympy.simplify(
            e["phi"].xreplace(dict(zip(s["x"], e["inverse"]))))
    return e["phi_z"]


def _linear_in(expr: Any, thetas: Sequence[Any]) -> bool:
    """Whether ``expr`` is affine in the symbols ``thetas`` jointly: every derivative in them
    is free of all of them."""
    return bool(thetas) and all(not sympy.diff(expr, t).has(*thetas) for t in thetas)


def _affine_terms(system: SymbolicSystem, names: tuple[str, ...]) -> Any:
    """``terms(Z, U) -> (phi (N, n), psi (N, 1, q))`` of :meth:`SymbolicSystem._form_affine`:
    ``phi`` zero but its last column ``phi_0`` (the unknowns set to 0), ``psi`` the regressor,
    one compiled row function for both."""
    s = system._sym
    P = s["params"]
    thetas = [P[k] for k in names]
    phi_z = _phi_z(s)
    exprs = [phi_z.xreplace({t: 0 for t in thetas})] + [sympy.diff(phi_z, t) for t in thetas]
    row = row_function("affine", exprs, (1 + len(names),),
                       [("z", s["z"]), ("u", s["u"]), ("c", list(P.values()))])
    n, q = len(system.state_names), len(names)
    kernel = _affine_kernel(row, n, q)
    c = system._cvec

    def terms(Z: Array, U: Array) -> tuple[Array, Array]:
        return kernel(np.ascontiguousarray(Z, dtype=float),  # type: ignore[no-any-return]
                      np.ascontiguousarray(U, dtype=float), c)
    return terms


def _affine_kernel(row: Any, n: int, q: int) -> Any:
    @njit(error_model="numpy")
    def kernel(Z: Array, U: Array, c: Array) -> tuple[Array, Array]:
        N = Z.shape[0]
        phi = np.zeros((N, n))
        psi = np.empty((N, 1, q))
        v = np.empty(1 + q)
        for b in range(N):
            row(Z[b], U[b], c, v)
            phi[b, n - 1] = v[0]
            psi[b, 0, :] = v[1:]
        return phi, psi
    return kernel


def _jo_son_structure(system: SymbolicSystem, unknown: Sequence[str] | None
                      ) -> tuple[tuple[str, ...], Array, Array, list[Any], list[Any]]:
    """``(unknown, T, b, gamma_o, beta)`` of :meth:`SymbolicSystem._form_jo_son`
    (``gamma_o`` and ``beta`` as expressions in ``y = x_1``, the inputs and the parameters).

    Raises
    ------
    DesignError
        As :meth:`SymbolicSystem._form_jo_son`."""
    from ..exceptions import DesignError

    s = system._sym
    P, (Aw, r) = s["params"], s["observer_form"]
    X = s["x"]
    n = len(X)
    names, subs = _aocf_unknowns(system, unknown)
    A = np.zeros((n, n))
    A[:, 1:] = [[float(e.xreplace(subs)) for e in row] for row in Aw]
    C = np.zeros(n)
    C[0] = 1.0
    O = np.vstack([C @ np.linalg.matrix_power(A, i) for i in range(n)])
    if np.linalg.matrix_rank(O) < n:
        raise DesignError("the linear part (A, e_1) is not observable: no observer canonical form")
    v = np.linalg.solve(O, np.eye(n)[-1])
    Tinv = np.column_stack([np.linalg.matrix_power(A, i) @ v for i in range(n)])
    T = np.linalg.inv(Tinv)
    # z' = T A T^-1 z + T r: the last column of T A T^-1 (beyond the lower shift) is output
    # injection, y = z_n
    Ao = T @ A @ Tinv
    inj = Ao[:, -1].copy()
    thetas = [P[k] for k in names]
    y = X[0]
    Tr = [sum(sympy.Float(T[i, j]) * r[j].xreplace(subs) for j in range(n)) for i in range(n)]
    psi = [[sympy.diff(e, t) for t in thetas] for e in Tr]
    beta = psi[-1]
    if all(sympy.simplify(e) == 0 for e in beta):
        raise DesignError(f"the parameters {list(names)} do not enter the output's first "
                          f"derivative (b_n = 0): paper 003's form needs b_r > 0")
    b = np.zeros(n)
    for i in range(n):
        ratios = {sympy.simplify(psi[i][j] / beta[j]) for j in range(len(names))
                  if sympy.simplify(beta[j]) != 0}
        zero_where_beta_zero = all(sympy.simplify(psi[i][j]) == 0 for j in range(len(names))
                                   if sympy.simplify(beta[j]) == 0)
        if len(ratios) != 1 or not zero_where_beta_zero or not next(iter(ratios)).is_number:
            raise DesignError(f"the parameters do not enter along one constant direction b in "
                              f"the observer canonical coordinates (row {i + 1}: "
                              f"{[str(e) for e in psi[i]]} against beta = "
                              f"{[str(e) for e in beta]}): paper 003's form b beta(y, u)^T "
                              f"theta does not hold")
        b[i] = float(next(iter(ratios)))
    gamma = [sympy.expand(Tr[i].xreplace({t: 0 for t in thetas}) + sympy.Float(inj[i]) * y)
             for i in range(n)]
    return names, T, b, gamma, beta


def _aocf_unknowns(system: SymbolicSystem, unknown: Sequence[str] | None
                   ) -> tuple[tuple[str, ...], dict[Any, float]]:
    """The unknowns of the observer-form families (default: in declaration order, each kept
    where ``r`` stays jointly linear in those kept and ``A`` is free of it) and the
    substitution of the other parameters' values.

    Raises
    ------
    DesignError
        ``unknown`` is not such a set."""
    from ..exceptions import DesignError

    s = system._sym
    P, (Aw, r) = s["params"], s["observer_form"]
    in_A = {k for k in system.param_names if any(e.has(P[k]) for row in Aw for e in row)}
    linear: list[str] = []
    for k in system.param_names:
        if k not in in_A and all(_linear_in(e, [P[j] for j in [*linear, k]]) for e in r):
            linear.append(k)
    names = tuple(linear if unknown is None else unknown)
    if (not names or len(set(names)) != len(names) or not set(names) <= set(linear)
            or not all(_linear_in(e, [P[k] for k in names]) for e in r)):
        raise DesignError(f"unknown must be distinct parameters that r(y, u) is jointly "
                          f"linear in and the linear part A is free of: from {linear}; "
                          f"found {list(names)}")
    subs = {P[k]: system.params[k] for k in system.param_names if k not in names}
    return names, subs


def _signals(entries: list[Any], n: int, m: int) -> tuple[list[Any], Array]:
    """The distinct signals ``omega`` of the entries of ``Omega`` (``n * m``, row-major) and
    ``alpha`` ``(n, m, s)`` with ``Omega_ij = alpha_ij^T omega`` (paper 002, eq. 2.2): zero
    entries get a zero ``alpha_ij``, an entry proportional to a signal found before reuses it,
    so that Theorem 4.2's rank (which takes the signals as independent) is not overstated.

    Raises
    ------
    DesignError
        Every entry is zero (no parameter enters)."""
    from ..exceptions import DesignError

    signals: list[Any] = []
    coeff: list[tuple[int, float] | None] = []
    for e in entries:
        if sympy.simplify(e) == 0:
            coeff.append(None)
            continue
        for k, sig in enumerate(signals):
            ratio = sympy.simplify(e / sig)
            if ratio.is_number:
                coeff.append((k, float(ratio)))
                break
        else:
            signals.append(e)
            coeff.append((len(signals) - 1, 1.0))
    if not signals:
        raise DesignError("no parameter enters the model (Omega is zero)")
    alpha = np.zeros((n * m, len(signals)))
    for idx, cf in enumerate(coeff):
        if cf is not None:
            alpha[idx, cf[0]] = cf[1]
    return signals, alpha.reshape(n, m, len(signals))


def _ackermann(F0: Array, k: Array, c: float) -> Array:
    """``K`` with the eigenvalues of ``F0 - K k^T`` all at ``-c`` (Ackermann's formula for the
    observable pair ``(F0, k^T)``); empty for ``n = 1``.

    Raises
    ------
    DesignError
        ``(F0, k^T)`` is not observable (the poles cannot be placed)."""
    from ..exceptions import DesignError

    q = F0.shape[0]
    if q == 0:
        return np.zeros(0)
    O = np.vstack([k @ np.linalg.matrix_power(F0, i) for i in range(q)])
    if np.linalg.matrix_rank(O) < q:
        raise DesignError(f"the AOCF's pair (F, k) = ({F0.tolist()}, {k.tolist()}) is not "
                          f"observable: its poles cannot be placed")
    coeffs = np.poly(np.full(q, -c))  # s^q + a_1 s^(q-1) + ... + a_q
    pF = sum(a * np.linalg.matrix_power(F0, q - i) for i, a in enumerate(coeffs))
    e = np.zeros(q)
    e[-1] = 1.0
    return np.asarray(pF @ np.linalg.solve(O, e), dtype=float)


def _aocf_rows(omega_row: Any, g_row: Any, s: int, n: int) -> Any:
    @njit(error_model="numpy")
    def kernel(Y: Array, U: Array, c: Array) -> tuple[Array, Array]:
        N = Y.shape[0]
        W = np.empty((N, s))
        G = np.empty((N, n))
        y = np.empty(1)
        for b in range(N):
            y[0] = Y[b]
            omega_row(y, U[b], c, W[b])
            g_row(y, U[b], c, G[b])
        return W, G
    return kernel


def _observer_form(X: Sequence[Any], fx: list[Any], hx: Any,
                   U: Sequence[Any]) -> tuple[tuple[list[list[Any]], list[Any]] | None, str | None]:
    """``(A, r)`` with ``f = A w + r(y, u)`` (``y = x_1``, ``w = x_2..x_n``, ``A`` free of the
    state and the input), or ``(None, why not)``."""
    if hx != X[0]:
        return None, f"the output is h = {hx}, not the first state {X[0]}"
    w = list(X[1:])
    A = [[sympy.diff(fi, wj) for wj in w] for fi in fx]
    for i, row in enumerate(A):
        for j, e in enumerate(row):
            if e.has(*X) or (U and e.has(*U)):
                return None, (f"f[{i}] is not linear in {w[j]} with a constant coefficient "
                              f"(d f[{i}]/d {w[j]} = {e}): the unmeasured states must enter "
                              f"linearly (f = A w + r(y, u))")
    r = [sympy.expand(fi - sum(a * wj for a, wj in zip(row, w))) for fi, row in zip(fx, A)]
    return (A, r), None


def ode_system(states: Sequence[str], f: Sequence[str], h: str, *, inputs: Sequence[str] = (),
               params: Mapping[str, float] | None = None, x0: Sequence[float] | None = None,
               region: Sequence[Sequence[float]] | None = None, name: str = "ode",
               samples: int = 256, held_input: bool = False) -> type[SymbolicSystem]:
    """A :class:`SymbolicSystem` class for ``x' = f(x, u; params)``, ``y = h(x)``.

    Parameters
    ----------
    states, inputs : list of str
        The names of the state and input entries (identifiers).
    f : list of str
        One expression per state.
    h : str
        The measured output.
    params : mapping name -> float, optional
        The parameters and their default values.
    x0 : list of float, optional
        Default initial state (zeros).
    region : ``[[lo_1, hi_1], ...]``, optional
        Box over which the observability rank and the Lipschitz bound are sampled (default
        ``[-1, 1]`` for every state).
    name : str
        Registry-style name of the model.
    samples : int
        Points sampled in the region.
    held_input : bool
        Where the relative degree ``r`` is below ``n``: derive the input-dependent normal form
        ``z = Phi(x, u)``, ``z_n' = phi(z, u)`` that holds while the input is held (``u' = 0``
        between its steps, paper 000 eq. 16) instead of refusing the high-gain family.

    Returns
    -------
    type[SymbolicSystem]

    Raises
    ------
    ModelError
        Bad names, an expression that does not parse or uses an undeclared name, a wrong number
        of expressions, an unobservable system (the rank is short everywhere sampled).

    Examples
    --------
    >>> from hgo_mj.systems.symbolic import ode_system
    >>> cls = ode_system(["x1", "x2"], ["x2", "-a*sin(x1) - b*x2 + u"], "x1", inputs=["u"],
    ...                  params={"a": 9.81, "b": 0.1})
    >>> sys = cls()
    >>> bool(round(sys.phi([0.5, 0.2], [1.0]), 6) == round(-9.81 * np.sin(0.5) - 0.02 + 1.0, 6))
    True
    >>> cls.closed_form_inverse, cls.relative_degree, cls.normal_form_note
    (True, 2, None)
    """
    states = _names("states", states)
    if not isinstance(held_input, bool):
        raise ModelError(f"held_input must be true or false; found {held_input!r} "
                         f"({type(held_input).__name__})")
    inputs = _names("inputs", inputs, allow_empty=True)
    params = dict(params or {})
    pnames = _names("params", list(params), allow_empty=True)
    n = len(states)
    X, U, P, fx, hx = _parse_model(states, inputs, pnames, f, h)
    x0t = tuple(float(v) for v in (x0 if x0 is not None else [0.0] * n))
    if len(x0t) != n:
        raise ModelError(f"x0 must have {n} entries, one per state; found {list(x0t)}")
    # Lie derivatives along f with the input held (u' = 0): L_f^k h, k = 0..n
    lie = [hx]
    for _ in range(n):
        lie.append(sympy.expand(sum(sympy.diff(lie[-1], xi) * fi for xi, fi in zip(X, fx))))
    rdeg, note, problem = _relative_degree(lie, U, held_input)
    sym = _compile_model(X, U, P, fx, hx, lie)
    inverse = sym["exprs"]["inverse"]
    sym["observer_form"], aocf_problem = _observer_form(X, fx, hx, U)
    ns = {"name": name, "summary": f"ODE {name}: y = {h}", "state_names": states,
          "state_units": tuple("" for _ in states), "input_names": inputs,
          "input_units": tuple("" for _ in inputs), "output_names": ("y",),
          "param_names": pnames, "default_params": params, "default_x0": x0t,
          "normal_form_order": None if problem else n, "relative_degree": rdeg,
          "normal_form_problem": problem, "normal_form_note": note,
          "closed_form_inverse": inverse is not None, "_sym": sym,
          "forms": (("affine",) if P and inverse is not None and problem is None else ())
          + (("aocf",) if P and aocf_problem is None else ()),
          "aocf_problem": aocf_problem,
          "compiled": type(f"Ode_{name}Model", (CompiledModel,), {
              "__slots__": (), "dynamics": sym["f"], "jacobian": sym["jac"],
              "param_jacobian": sym["pjac"]})()}
    cls: type[SymbolicSystem] = type(f"Ode_{name}", (SymbolicSystem,), ns)
    _check_region(cls, region, samples)
    if aocf_problem is None and P:
        _declare_jo_son(cls)
    return cls


def _relative_degree(lie: list[Any], U: Sequence[Any], held_input: bool
                     ) -> tuple[int | None, str | None, str | None]:
    """``(r, note, problem)`` from the Lie derivatives ``L_f^k h``, k = 0..n: ``r`` the first
    k with u in ``L_f^k h``; below n, a note (``held_input``) or the problem."""
    n = len(lie) - 1
    rdeg = next((k for k in range(1, n + 1) if any(lie[k].has(u) for u in U)), None)
    if rdeg is None or rdeg >= n:
        return rdeg, None, None
    if held_input:
        return rdeg, (f"the input enters L_f^{rdeg} h (relative degree {rdeg} < n = {n}): Phi "
                      f"depends on u, and phi is exact for an input held between its steps "
                      f"(u' = 0; the derivatives of u are left out), as paper 000 does for its "
                      f"bioreactor (eq. 16); the EKF/UKF need no such assumption"), None
    return rdeg, None, (f"the input enters L_f^{rdeg} h (relative degree {rdeg} < n = {n}): "
                        f"the normal form would need derivatives of u; the high-gain family "
                        f"does not apply (unless the input is held between steps: held_input "
                        f"= true, as paper 000 eq. 16), the EKF/UKF still do")


def _compile_model(X: Sequence[Any], U: Sequence[Any], P: dict[str, Any], fx: list[Any],
                   hx: Any, lie: list[Any]) -> dict[str, Any]:
    """The derived expressions (``Phi``, ``phi``, the inverse, the Jacobians) and their
    compiled row functions and kernels: the class's ``_sym``."""
    n = len(X)
    Phi, phi_x = lie[:n], lie[n]
    Z = sympy.symbols([f"z{i + 1}" for i in range(n)], real=True)
    inverse = _closed_inverse(Phi, X, Z)
    J = sympy.Matrix(Phi).jacobian(sympy.Matrix(X))
    Pl = list(P.values())
    xuc = [("x", X), ("u", U), ("c", Pl)]
    fm = sympy.Matrix(fx)
    sym = {"x": X, "u": U, "z": Z, "params": P,
           "f": row_function("f", fx, (n,), xuc),
           "h": row_function("h", [hx], (1,), [("x", X), ("c", Pl)]),
           "jac": row_function("jac", list(fm.jacobian(sympy.Matrix(X))), (n, n), xuc),
           "pjac": row_function("pjac", list(fm.jacobian(sympy.Matrix(Pl))) if Pl else [],
                                (n, len(Pl)), xuc),
           "Phi": row_function("Phi", Phi, (n,), xuc),
           "PhiJ": row_function("PhiJ", list(J), (n, n), xuc),
           "phi": row_function("phi", [phi_x], (1,), xuc),
           "inverse": None if inverse is None else row_function(
               "inverse", inverse, (n,), [("z", Z), ("u", U), ("c", Pl)]),
           "exprs": {"Phi": Phi, "phi": phi_x, "f": fx, "h": hx, "inverse": inverse, "J": J}}
    sym["identity"] = inverse is not None and all(sympy.simplify(xi - zi) == 0
                                                  for xi, zi in zip(inverse, Z))
    sym["kernels"] = _Kernels(n, sym["Phi"], sym["PhiJ"], sym["phi"], sym["inverse"])
    return sym


def _declare_jo_son(cls: type[SymbolicSystem]) -> None:
    """Add ``"jo_son"`` to the class's forms where its default unknowns admit the form, else
    say why in :attr:`SymbolicSystem.jo_son_problem`."""
    from ..exceptions import DesignError

    try:
        _jo_son_structure(cls(), None)
        cls.forms = (*cls.forms, "jo_son")
    except DesignError as exc:
        cls.jo_son_problem = str(exc)


def _parse_model(states: tuple[str, ...], inputs: tuple[str, ...], pnames: tuple[str, ...],
                 f: Any, h: Any) -> tuple[Any, Any, dict[str, Any], list[Any], Any]:
    """The symbols of the states, inputs and parameters, and the parsed ``f`` and ``h``."""
    clash = (set(states) & set(inputs)) | (set(pnames) & (set(states) | set(inputs)))
    if clash:
        raise ModelError(f"a name is declared twice (states, inputs, params): {sorted(clash)}")
    n = len(states)
    if isinstance(f, str) or not isinstance(f, (list, tuple)) or len(f) != n:
        raise ModelError(f"f must be a list of {n} expressions, one per state {list(states)}; "
                         f"found {f!r}")
    X = sympy.symbols(states, real=True)
    U = sympy.symbols(inputs, real=True) if inputs else ()
    P = {k: sympy.Symbol(k, real=True) for k in pnames}
    names = {**dict(zip(states, X)), **dict(zip(inputs, U)), **P}
    fx = [parse(fk, names, f"f[{i}]") for i, fk in enumerate(f)]
    hx = parse(h, {**dict(zip(states, X)), **P}, "h")  # the output may not depend on u
    return X, U, P, fx, hx


def _closed_inverse(Phi: list[Any], X: Sequence[Any], Z: Sequence[Any]) -> list[Any] | None:
    """``x = Phi^-1(z)`` where the equations ``Phi_k(x) = z_k`` can be solved one after the
    other, each for one new unknown with one solution; else None (Newton then)."""
    known: dict[Any, Any] = {}
    for pk, zk in zip(Phi, Z):
        eq = sympy.simplify(pk.subs(known) - zk)
        new = [x for x in X if x not in known and eq.has(x)]
        if not new:
            continue
        if len(new) != 1:
            return None
        try:
            sols = sympy.solve(eq, new[0], dict=False)
        except (NotImplementedError, ValueError):
            return None
        if len(sols) != 1:
            return None
        known[new[0]] = sols[0]
    if len(known) != len(X):
        return None
    return [sympy.simplify(known[x]) for x in X]


def _check_region(cls: type[SymbolicSystem], region: Any, samples: int) -> None:
    """Observability rank at sampled points of the box, and a sampled Lipschitz bound."""
    n = len(cls.state_names)
    box = np.array(region if region is not None else [[-1.0, 1.0]] * n, dtype=float)
    if box.shape != (n, 2) or not np.all(box[:, 0] <= box[:, 1]):
        raise ModelError(f"region must be [[lo, hi], ...] with lo <= hi, one per state; "
                         f"found {region!r}")
    rng = np.random.default_rng(0)
    pts = box[:, 0] + (box[:, 1] - box[:, 0]) * rng.random((samples, n))
    s = cls._sym
    dphi = row_function("dphi", [sympy.diff(s["exprs"]["phi"], xi) for xi in s["x"]], (n,),
                        [("x", s["x"]), ("u", s["u"]), ("c", list(s["params"].values()))])
    c = cls().param_vector()
    u0 = np.zeros(len(cls.input_names))
    J, g = np.empty((n, n)), np.empty(n)
    drops, bound = [], 0.0
    for x in pts:
        s["PhiJ"](x, u0, c, J)
        if np.linalg.matrix_rank(J) < n:
            drops.append(x)
            continue
        # d phi / d z = (d phi / d x) (d Phi / d x)^-1 at x = Phi^-1(z)
        dphi(x, u0, c, g)
        bound = max(bound, float(np.linalg.norm(np.linalg.solve(J.T, g))))
    if len(drops) == len(pts):
        raise ModelError(f"{cls.name}: not observable from y = {s['exprs']['h']}: the "
                         f"observability map's Jacobian has rank < {n} at every sampled point "
                         f"of the region")
    if drops:
        cls.rank_problem = (f"the observability rank drops below {n} at x = "
                            f"{np.round(drops[0], 4).tolist()} ({len(drops)} of {len(pts)} "
                            f"sampled points of the region)")
    cls.lipschitz = bound


__all__ = ["FUNCTIONS", "MAX_CHARS", "MAX_DEPTH", "MAX_EXPONENT", "MAX_NODES",
           "SymbolicSystem", "ode_system", "parse"]
