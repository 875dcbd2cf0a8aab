"""Any ODE, its observability normal form derived (issue 12).

A control researcher writes the model as on paper::

    cls = ode_system(states=["x1", "x2"], inputs=["u"], params={"a": 9.81, "b": 0.1},
                     f=["x2", "-a*sin(x1) - b*x2 + u"], h="x1")

and gets a :class:`System` whose single-output normal form (paper 000, eq. 1) is derived:

* the Lie derivatives ``L_f^k h`` and the observability map
  ``Phi(x) = (h, L_f h, ..., L_f^(n-1) h)`` with its Jacobian;
* the relative degree: where some ``L_f^k h`` with ``k < n`` depends on ``u``, the normal form
  would need derivatives of ``u``: :attr:`SymbolicSystem.normal_form_problem` says so (the
  EKF/UKF still apply);
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
its position.

**Evaluation.** Each derived expression becomes a tree of numpy closures (:func:`numeric`): no
generated source, no ``exec``; it evaluates on scalars or on arrays of B members alike.
"""

from __future__ import annotations

import ast
from collections.abc import Callable, Mapping, Sequence
from typing import Any, ClassVar

import numpy as np
import sympy

from ..exceptions import ModelError
from .base import Array, System

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


def parse(text: Any, names: Mapping[str, sympy.Symbol], where: str) -> sympy.Expr:
    """The sympy expression of ``text``, built from its Python ``ast`` (never ``eval``).

    Raises
    ------
    ModelError
        Not a string, a syntax error (with its column), or a name, operator or call that is not
        allowed (named, with its column)."""
    if not isinstance(text, str):
        raise ModelError(f"{where} must be an expression as a string; found {text!r} "
                         f"({type(text).__name__})")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        raise ModelError(f"{where} = {text!r}: syntax error at column {exc.offset}: "
                         f"{exc.msg}") from None
    return _node(tree.body, names, where, text)


def _node(node: ast.AST, names: Mapping[str, sympy.Symbol], where: str, text: str) -> Any:
    at = f"{where} = {text!r}, column {getattr(node, 'col_offset', 0) + 1}"
    if isinstance(node, ast.Constant) and type(node.value) in (int, float):
        return sympy.Float(node.value) if isinstance(node.value, float) else sympy.Integer(
            node.value)
    if isinstance(node, ast.Name):
        if node.id in names:
            return names[node.id]
        if node.id in _CONSTANTS:
            return _CONSTANTS[node.id]
        raise ModelError(f"{at}: {node.id!r} is not declared; declared: {sorted(names)} "
                         f"(and the constants {sorted(_CONSTANTS)})")
    if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
        return _BINOPS[type(node.op)](_node(node.left, names, where, text),
                                      _node(node.right, names, where, text))
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        value = _node(node.operand, names, where, text)
        return -value if isinstance(node.op, ast.USub) else value
    if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and not node.keywords
            and node.func.id in FUNCTIONS):
        if len(node.args) != 1:
            raise ModelError(f"{at}: {node.func.id}() takes one argument; found "
                             f"{len(node.args)}")
        return FUNCTIONS[node.func.id][0](_node(node.args[0], names, where, text))
    what = (f"a call of {ast.unparse(node.func)!r} (allowed: {sorted(FUNCTIONS)})"
            if isinstance(node, ast.Call) else f"{type(node).__name__} {ast.unparse(node)!r}")
    allowed = "" if isinstance(node, ast.Call) else f", and calls of {sorted(FUNCTIONS)}"
    raise ModelError(f"{at}: {what} is not allowed in an expression (numbers, declared names, "
                     f"+ - * / **{allowed})")


def numeric(expr: sympy.Expr) -> Callable[[Mapping[sympy.Symbol, Any]], Any]:
    """A closure evaluating ``expr`` with numpy from ``{symbol: value}`` (scalars or arrays)."""
    if expr.is_Symbol:
        return lambda env: env[expr]
    if expr.is_Number or expr in (sympy.pi, sympy.E):
        c = float(expr)
        return lambda env: c
    args = [numeric(a) for a in expr.args]
    if isinstance(expr, sympy.Add):
        return lambda env: sum(a(env) for a in args)
    if isinstance(expr, sympy.Mul):
        def product(env: Mapping[sympy.Symbol, Any]) -> Any:
            out = args[0](env)
            for a in args[1:]:
                out = out * a(env)
            return out
        return product
    if isinstance(expr, sympy.Pow):
        base, power = args
        return lambda env: base(env) ** power(env)
    if expr.func is sympy.DiracDelta:
        first = args[0]
        return lambda env: 0.0 * first(env)
    fn = _NUMPY.get(expr.func)
    if fn is not None and len(args) == 1:
        (arg,) = args
        return lambda env: fn(arg(env))
    raise ModelError(f"the derived expression {expr} uses {expr.func}, which hgo_mj cannot "
                     f"evaluate")


def _names(what: str, value: Any, allow_empty: bool = False) -> tuple[str, ...]:
    ok = isinstance(value, (list, tuple)) and all(isinstance(v, str) and v.isidentifier()
                                                   for v in value)
    if not ok or (not value and not allow_empty) or len(set(value)) != len(value):
        raise ModelError(f"{what} must be a list of distinct names (identifiers); found "
                         f"{value!r}")
    return tuple(value)


class SymbolicSystem(System):
    """A system derived from expressions by :func:`ode_system` (one subclass per model)."""

    reference = "normal form derived symbolically (paper 000, eq. 1)"
    #: why the single-output normal form does not hold (relative degree), else None
    normal_form_problem: ClassVar[str | None] = None
    #: a sampled point of the region where the observability rank drops, else None
    rank_problem: ClassVar[str | None] = None
    #: sampled Lipschitz bound of phi in z over the region
    lipschitz: ClassVar[float] = float("nan")
    #: whether the inverse map is in closed form (else Newton)
    closed_form_inverse: ClassVar[bool] = False
    _sym: ClassVar[dict[str, Any]] = {}

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)
        self.inverse_failures = 0
        self._last = np.array(self.default_x0, dtype=float)

    def _env(self, x: Any, u: Any, p: Mapping[str, float] | None = None) -> dict[Any, Any]:
        s = self._sym
        env: dict[Any, Any] = {sym: (self.params if p is None else p)[name]
                               for name, sym in s["params"].items()}
        env.update(zip(s["x"], x))
        env.update(zip(s["u"], u if u is not None else np.zeros(len(s["u"]))))
        return env

    def dynamics(self, t: float, x: Array, u: Array, p: Any = None) -> Array:  # type: ignore[override]
        env = self._env(x, u, p)
        return np.array([np.asarray(fk(env), dtype=float) for fk in self._sym["f"]])

    def output(self, x: Array, p: Any = None) -> Array:  # type: ignore[override]
        env = self._env(x, None, p)
        return np.array([float(self._sym["h"](env))])

    def to_normal(self, x: Any, u: Any = None) -> Array:
        self._require()
        env = self._env(np.asarray(x, dtype=float), u)
        return np.array([float(k(env)) for k in self._sym["Phi"]])

    def from_normal(self, z: Any, u: Any = None) -> Array:
        self._require()
        return self.from_normal_unchecked(np.asarray(z, dtype=float), u)

    def from_normal_unchecked(self, z: Array, u: Array) -> Array:
        s = self._sym
        if s["inverse"] is not None:
            env = {**self._env(self._last, u), **dict(zip(s["z"], z))}
            x = np.array([float(k(env)) for k in s["inverse"]])
        else:
            x = self._newton(z, u)
        self._last = x
        return x

    def _newton(self, z: Array, u: Array) -> Array:
        """``Phi(x) = z`` by Newton's method on the Jacobian, from the last inverse."""
        x = self._last.copy() if np.all(np.isfinite(self._last)) else np.zeros(len(z))
        s = self._sym
        for _ in range(30):
            env = self._env(x, u)
            r = np.array([float(k(env)) for k in s["Phi"]]) - z
            if np.max(np.abs(r)) <= 1e-12 * (1.0 + np.max(np.abs(z))):
                return x
            J = np.array([[float(c(env)) for c in row] for row in s["J"]])
            try:
                x = x - np.linalg.solve(J, r)
            except np.linalg.LinAlgError:
                break
        self.inverse_failures += 1
        return x

    def phi(self, z: Any, u: Any = None) -> float:
        self._require()
        return self.phi_unchecked(np.asarray(z, dtype=float),
                                  np.zeros(len(self.input_names)) if u is None else u)

    def phi_unchecked(self, z: Array, u: Array) -> float:
        x = self.from_normal_unchecked(z, u)
        return float(self._sym["phi"](self._env(x, u)))

    def phi_batch(self, Z: Array, U: Array) -> Array:
        return np.array([self.phi_unchecked(z, u) for z, u in zip(Z, U)], dtype=float)

    def _require(self) -> None:
        if self.normal_form_problem is not None:
            raise ModelError(self.normal_form_problem)


def ode_system(states: Sequence[str], f: Sequence[str], h: str, *, inputs: Sequence[str] = (),
               params: Mapping[str, float] | None = None, x0: Sequence[float] | None = None,
               region: Sequence[Sequence[float]] | None = None, name: str = "ode",
               samples: int = 256) -> type[SymbolicSystem]:
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
    >>> round(sys.phi([0.5, 0.2], [1.0]), 6) == round(-9.81 * np.sin(0.5) - 0.02 + 1.0, 6)
    True
    >>> cls.closed_form_inverse, cls.normal_form_problem
    (True, None)
    """
    states = _names("states", states)
    inputs = _names("inputs", inputs, allow_empty=True)
    params = dict(params or {})
    pnames = _names("params", list(params), allow_empty=True)
    n = len(states)
    X, U, P, fx, hx = _parse_model(states, inputs, pnames, f, h)
    lie = [hx]
    for _ in range(n):
        lie.append(sympy.expand(sum(sympy.diff(lie[-1], xi) * fi for xi, fi in zip(X, fx))))
    Phi, phi_x = lie[:n], lie[n]
    problem = None
    dep = next((k for k in range(n) if any(Phi[k].has(u) for u in U)), None)
    if dep is not None:
        problem = (f"the input enters L_f^{dep} h (relative degree {dep} < n = {n}): the normal "
                   f"form would need derivatives of u; the high-gain family does not apply, the "
                   f"EKF/UKF still do")
    Z = sympy.symbols([f"z{i + 1}" for i in range(n)], real=True)
    inverse = None if problem else _closed_inverse(Phi, X, Z)
    J = sympy.Matrix(Phi).jacobian(sympy.Matrix(X))
    sym = {"x": X, "u": U, "z": Z, "params": P, "f": [numeric(e) for e in fx],
           "h": numeric(hx), "Phi": [numeric(e) for e in Phi], "phi": numeric(phi_x),
           "J": [[numeric(J[i, j]) for j in range(n)] for i in range(n)],
           "inverse": None if inverse is None else [numeric(e) for e in inverse],
           "exprs": {"Phi": Phi, "phi": phi_x, "f": fx, "h": hx, "inverse": inverse}}
    x0t = tuple(float(v) for v in (x0 if x0 is not None else [0.0] * n))
    ns = {"name": name, "summary": f"ODE {name}: y = {h}", "state_names": states,
          "state_units": tuple("" for _ in states), "input_names": inputs,
          "input_units": tuple("" for _ in inputs), "output_names": ("y",),
          "param_names": pnames, "default_params": params, "default_x0": x0t,
          "normal_form_order": None if problem else n, "normal_form_problem": problem,
          "closed_form_inverse": inverse is not None, "_sym": sym}
    cls: type[SymbolicSystem] = type(f"Ode_{name}", (SymbolicSystem,), ns)
    if len(x0t) != n:
        raise ModelError(f"x0 must have {n} entries, one per state; found {list(x0t)}")
    _check_region(cls, region, samples)
    return cls


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
    if cls.normal_form_problem is not None:
        return
    system = cls()
    rng = np.random.default_rng(0)
    pts = box[:, 0] + (box[:, 1] - box[:, 0]) * rng.random((samples, n))
    s = cls._sym
    drops, bound = [], 0.0
    u0 = np.zeros(len(cls.input_names))
    dphi = [numeric(sympy.diff(s["exprs"]["phi"], xi)) for xi in s["x"]]
    for x in pts:
        env = system._env(x, u0)
        J = np.array([[float(c(env)) for c in row] for row in s["J"]])
        if np.linalg.matrix_rank(J) < n:
            drops.append(x)
            continue
        # d phi / d z = (d phi / d x) (d Phi / d x)^-1 at x = Phi^-1(z)
        g = np.array([float(d(env)) for d in dphi])
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


__all__ = ["FUNCTIONS", "SymbolicSystem", "numeric", "ode_system", "parse"]
