"""The adaptive observer of Bastin and Gevers (paper 002) on the adaptive observer canonical form.

**Canonical form (AOCF), eq. 2.2-2.3.** A single-output system transformed to

.. math::

    \\dot x = R x + \\Omega(\\omega)\\, \\theta + g, \\qquad y = x_1, \\qquad
    R = \\begin{bmatrix} 0 & k^T \\\\ 0 & F \\end{bmatrix}, \\qquad
    \\Omega_{ij}(\\omega) = \\alpha_{ij}^T \\omega,

with :math:`x \\in \\mathbb R^n`, unknown (possibly slowly time-varying) parameters
:math:`\\theta \\in \\mathbb R^m`, :math:`\\omega \\in \\mathbb R^s` a vector of known functions
of the input and the output, constant vectors :math:`\\alpha_{ij}`, known :math:`k`, a Hurwitz
:math:`F` and known :math:`g`.

**Observer, eq. 3.1.** With :math:`\\tilde y = y - \\hat x_1`, :math:`\\Omega_1` the first row
of :math:`\\Omega` and :math:`\\bar\\Omega` the others (eq. 3.2),

.. math::

    \\dot{\\hat x} &= R \\hat x + \\Omega(\\omega) \\hat\\theta + g
                    + \\begin{bmatrix} c_1 \\tilde y \\\\ V \\dot{\\hat\\theta} \\end{bmatrix}
                    && \\text{(3.1a)} \\\\
    \\dot{\\hat\\theta} &= \\Gamma \\varphi \\tilde y && \\text{(3.1c)} \\\\
    \\dot V &= F V + \\bar\\Omega(\\omega), \\quad V(0) = 0 && \\text{(3.1d)} \\\\
    \\varphi &= V^T k + \\Omega_1^T(\\omega) && \\text{(3.1e)}

**Three misprints of the paper, corrected here** (each follows from the error system 4.2,
which the paper derives from 3.1; the derivation is in ``docs/adaptive_canonical_forms.md``
and the test ``tests/test_bastin_gevers.py::test_error_system_4_2``):

* 3.1a prints the correction of the last rows as :math:`v(t) \\hat\\theta(t)`; it is
  :math:`V(t) \\dot{\\hat\\theta}(t)`.
* 3.1e prints :math:`\\dot\\varphi = V^T k + \\Omega_1^T`; the regressor is the filter's
  *output* :math:`\\varphi = V^T k + \\Omega_1^T` (only then is the top row of 4.2
  :math:`\\varphi^T \\tilde\\theta`).
* 4.1 prints :math:`\\tilde x^* = \\tilde x - (0, \\tilde\\theta)`; dimensions require
  :math:`\\tilde x^* = \\tilde x - (0, V \\tilde\\theta)`, and the forcing of 4.2 is the true
  parameter drift :math:`\\dot\\theta` (printed :math:`\\hat\\theta`).

**Output reachability, Theorem 4.2.** The filter (3.1d, e) with output :math:`\\varphi` is
output reachable from :math:`\\omega` iff :math:`S(\\omega)` of eq. 4.11 has full column rank
over :math:`\\mathbb R`, with rows the Markov parameters
:math:`s_1 = \\Omega_1`, :math:`s_j = k^T F^{j-2} \\bar\\Omega` (the printed
":math:`F_j^{-2}`" is :math:`F^{j-2}`). Rows beyond :math:`j = n` are combinations of the first
:math:`n` (Cayley-Hamilton), so :math:`j = 1..n` is used whatever :math:`m`. Since
:math:`S` is linear in :math:`\\omega`, :math:`S(\\omega) = \\sum_l \\omega_l S_l`, and the
structural check (before a run) is the column rank of :math:`[S_1; \\dots; S_s]`, exact
whenever the components of :math:`\\omega` are linearly independent functions of time. Along
a run, :attr:`BastinGeversObserver.reachability_rank_` is the rank of the stacked
:math:`S(\\omega(t_k))`.

**Excitation, condition 4.5.** The diagnostic ``excitation`` is the smallest eigenvalue of
:math:`\\int_{t-T}^{t} \\varphi \\varphi^T d\\tau` over the last ``excitation_window`` ``T``
(a sum over samples): positive and bounded away from zero where :math:`\\theta` is
identifiable.

References
----------
.. [002] G. Bastin, M. Gevers, "Stable adaptive observers for nonlinear time-varying systems",
   1986 (``shared/papers/002_7adafa82055be9d3.txt``): eq. 2.2-2.3 (AOCF), 3.1-3.2 (observer),
   4.1-4.3 (error system), 4.5 (persistence of excitation), 4.11 and Theorem 4.2 (output
   reachability), section 6 (bioreactor, eq. 6.4-6.6).
.. [LN74] G. Lüders, K.S. Narendra, "A new canonical form for an adaptive observer", IEEE TAC
   19(2), 1974 (the linear observer this one extends).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from typing import Any, TypeVar

import numpy as np

from .._validate import finite_scalar, one_of, positive_int, symmetric_matrix, vector
from ..exceptions import DesignError, DimensionError, DivergenceError
from ..systems.base import System
from .base import Array, Observer

__all__ = ["AOCF", "BastinGeversObserver", "SlidingGram", "check_rk_period",
           "rk_stable_period"]

METHODS = ("rk4", "euler")


# ======================================================================================
# shared helpers (also used by the Jo-Son observer)
# ======================================================================================


def _rk_gain(z: complex, method: str) -> float:
    """|R(z)| of the stability function of ``method`` (Euler, Heun "rk2", classical RK4)."""
    if method == "euler":
        return abs(1 + z)
    if method == "rk2":
        return abs(1 + z + z * z / 2)
    return abs(1 + z + z * z / 2 + z ** 3 / 6 + z ** 4 / 24)


def rk_stable_period(eigenvalues: Any, method: str) -> float:
    """Largest step ``h`` for which ``method`` (``"rk4"``, ``"rk2"`` or ``"euler"``) is stable on the
    linear modes ``eigenvalues`` (all in the open left half-plane): every ``h * lambda`` inside
    the method's region of absolute stability. ``inf`` if there are no modes."""
    lam = np.asarray(eigenvalues, dtype=complex).reshape(-1)
    lam = lam[lam != 0]
    if lam.size == 0:
        return math.inf

    def ok(h: float) -> bool:
        return all(_rk_gain(h * v, method) < 1.0 for v in lam)

    hi = 4.0 / float(np.max(np.abs(lam)))
    lo = 0.0
    if ok(hi):  # cannot happen for rk4/euler on left-half-plane modes; be safe
        return hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo


def check_rk_period(what: str, poles: Any, dt: float, method: str, substeps: int) -> None:
    """Raise :class:`DesignError` if ``substeps`` steps of ``method`` per sample period ``dt``
    are unstable on the linear modes ``poles`` of ``what`` (e.g. "the Jo-Son observer"),
    naming the largest stable step and the substeps it takes (:func:`rk_stable_period`)."""
    dt = finite_scalar("dt", dt, positive=True)
    h = rk_stable_period(poles, method)
    if dt / substeps >= h:
        raise DesignError(
            f"{method} integration of {what} with step {dt / substeps:g} (sample period "
            f"{dt:g} / {substeps} substeps) is unstable on its poles "
            f"{np.round(poles, 6).tolist()}; the largest stable step is {h:.4g}: raise "
            f"substeps to at least {math.ceil(dt / h * 1.0000001)}")


class SlidingGram:
    """Sliding-window Gram matrix ``sum_{last W samples} v v^T dt`` (condition 4.5).

    The last ``W = round(window / dt)`` vectors are kept in a ring buffer (one row write per
    sample); the matrix and its smallest eigenvalue are computed when asked for.
    """

    def __init__(self, m: int, window: float) -> None:
        self.m = m
        self.window = window
        self.reset()

    def reset(self) -> None:
        self._buf: Array | None = None
        self._dt = math.nan
        self._i = 0
        self._full = False
        self._min_eig: float | None = 0.0

    def add(self, v: Array, dt: float) -> None:
        buf = self._buf
        if buf is None or dt != self._dt:
            self._dt = dt
            buf = self._buf = np.zeros((max(1, int(round(self.window / dt))), self.m))
            self._i, self._full = 0, False
        buf[self._i] = v
        self._i += 1
        if self._i == buf.shape[0]:
            self._i, self._full = 0, True
        self._min_eig = None

    @property
    def matrix(self) -> Array:
        if self._buf is None:
            return np.zeros((self.m, self.m))
        b = self._buf if self._full else self._buf[:self._i]
        return (b.T @ b) * self._dt

    @property
    def min_eig(self) -> float:
        if self._min_eig is None:
            G = self.matrix
            self._min_eig = (float(np.linalg.eigvalsh(G)[0]) if np.all(np.isfinite(G))
                             else math.nan)
        return self._min_eig


def initial_estimate(n: int, q: int, x_hat0: Any, z_hat0: Any, theta_hat0: Any,
                     from_physical: Callable[[Any, Array], Array]) -> tuple[Array, Array]:
    """The initial state (in the form's coordinates, length ``n``) and parameter estimate
    (length ``q``, default zero) of an adaptive observer: ``z_hat0``, or the physical
    ``x_hat0`` mapped by ``from_physical(x_hat0, theta_hat0)`` (which raises where the form
    has no such map), or zero."""
    th = np.zeros(q) if theta_hat0 is None else vector("theta_hat0", theta_hat0, q)
    if x_hat0 is not None and z_hat0 is not None:
        raise DesignError("give x_hat0 or z_hat0, not both")
    if x_hat0 is not None:
        return from_physical(x_hat0, th), th
    if z_hat0 is not None:
        return vector("z_hat0", z_hat0, n), th
    return np.zeros(n), th


def _call(factory: Callable[..., Any], args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
    return factory(*args, **kwargs)


_F = TypeVar("_F", bound="Rebuildable")


class Rebuildable:
    """Base of the canonical forms: a form whose functions pickle cannot store (closures of
    its factory, generated code) pickles as the factory call that built it, which its factory
    records with :meth:`_made_by` (its arguments must pickle: a system, numbers, names). A
    form built by hand pickles as usual, where its functions do (module-level ones)."""

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


def _lin(terms: list[tuple[float, str]]) -> str:
    """``c1*a + c2*b + ...`` with zero coefficients dropped (``0.0`` if none are left)."""
    out = []
    for c, v in terms:
        if c == 0.0:
            continue
        out.append(v if c == 1.0 else f"{c!r}*{v}")
    return " + ".join(out) if out else "0.0"


def compile_rhs(R: Array, omega_mask: Array, gamma: Array, c1: float) -> Callable[..., list[float]]:
    """Generate eq. 3.1 in plain floats: ``rhs(s, y, c, O, g) -> ds`` for the flat state
    ``s = (x_hat, theta_hat, vec V)``, ``O`` = ``Omega(omega)`` flattened row-major, ``g`` the
    known term and ``c`` 1.0 (correct) or 0.0 (dropout). Constants and the zero pattern of
    ``Omega`` (``omega_mask``, shape (n, m)) are inlined: for the small forms of the papers this
    costs a few microseconds, against tens for the same arithmetic in small numpy arrays.

    The returned function carries ``rhs.phi(s, O) -> [phi_1, ..., phi_m]``, the regressor
    :math:`\\varphi = V^T k + \\Omega_1^T` of eq. 3.1e, from the same generated lines."""
    n, m = omega_mask.shape
    xs = [f"x{i}" for i in range(n)]
    ts = [f"t{j}" for j in range(m)]
    vs = [[f"v{i}_{j}" for j in range(m)] for i in range(n - 1)]
    os_ = [[f"o{i}_{j}" if omega_mask[i, j] else "" for j in range(m)] for i in range(n)]
    k, F = R[0, 1:], R[1:, 1:]
    body = []
    flat = xs + ts + [v for row in vs for v in row]
    body.append(f"    ({', '.join(flat)},) = s")
    used_o = [(i, j) for i in range(n) for j in range(m) if omega_mask[i, j]]
    if used_o:
        body.append(f"    ({', '.join(os_[i][j] for i, j in used_o)},) = "
                    f"({', '.join(f'O[{i * m + j}]' for i, j in used_o)},)")
    body.append(f"    ({', '.join(f'g{i}' for i in range(n))},) = g")
    body.append("    e = c * (y - x0)")
    p_lines = []
    for j in range(m):
        terms = [(float(k[i]), vs[i][j]) for i in range(n - 1)]
        if os_[0][j]:
            terms.append((1.0, os_[0][j]))
        p_lines.append(f"    p{j} = {_lin(terms)}")
    body += p_lines
    for j in range(m):
        body.append(f"    d{j} = ({_lin([(float(gamma[j, l]), f'p{l}') for l in range(m)])}) * e")
    for i in range(n):
        terms = [(float(R[i, a]), xs[a]) for a in range(n)]
        terms += [(1.0, f"{os_[i][j]}*{ts[j]}") for j in range(m) if os_[i][j]]
        terms.append((1.0, f"g{i}"))
        if i == 0:
            terms.append((float(c1), "e"))
        else:
            terms += [(1.0, f"{vs[i - 1][j]}*d{j}") for j in range(m)]
        body.append(f"    xd{i} = {_lin(terms)}")
    vd = []
    for i in range(n - 1):
        for j in range(m):
            terms = [(float(F[i, a]), vs[a][j]) for a in range(n - 1)]
            if os_[i + 1][j]:
                terms.append((1.0, os_[i + 1][j]))
            vd.append(_lin(terms))
    out = [f"xd{i}" for i in range(n)] + [f"d{j}" for j in range(m)] + vd
    src = "def rhs(s, y, c, O, g):\n" + "\n".join(body) + f"\n    return [{', '.join(out)}]\n"
    phi = ["def phi(s, O):"]
    if n > 1:
        phi.append(f"    ({', '.join(v for row in vs for v in row)},) = s[{n + m}:]")
    used_o0 = [j for j in range(m) if omega_mask[0, j]]
    if used_o0:
        phi.append(f"    ({', '.join(os_[0][j] for j in used_o0)},) = "
                   f"({', '.join(f'O[{j}]' for j in used_o0)},)")
    src += "\n".join(phi + p_lines) + f"\n    return [{', '.join(f'p{j}' for j in range(m))}]\n"
    scope: dict[str, Any] = {}
    exec(compile(src, "<bastin_gevers_rhs>", "exec"), scope)  # noqa: S102 - numbers only
    rhs = scope["rhs"]
    rhs.phi = scope["phi"]
    return rhs


def rk_step(rhs: Callable[..., list[float]], s: list[float], h: float, method: str,
            substeps: int, *args: Any) -> list[float]:
    """``substeps`` steps of RK4 (or Euler) of ``ds/dt = rhs(s, *args)`` in plain floats."""
    h2, h6 = 0.5 * h, h / 6.0
    for _ in range(substeps):
        k1 = rhs(s, *args)
        if method == "euler":
            s = [a + h * b for a, b in zip(s, k1)]
            continue
        k2 = rhs([a + h2 * b for a, b in zip(s, k1)], *args)
        k3 = rhs([a + h2 * b for a, b in zip(s, k2)], *args)
        k4 = rhs([a + h * b for a, b in zip(s, k3)], *args)
        s = [a + h6 * (b + 2.0 * (c + d) + f) for a, b, c, d, f in zip(s, k1, k2, k3, k4)]
    return s


# ======================================================================================
# the canonical form
# ======================================================================================

PhysicalMap = Callable[[Array, Array, Array], tuple[Array, Mapping[str, float]]]


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
    omega : callable ``(y, u) -> (s,)``
        The known signals :math:`\\omega` as functions of the measured output (a float) and the
        input vector.
    g : callable ``(y, u) -> (n,)``, optional
        The known term :math:`g` (the paper's "known functions of time": through ``y`` and
        ``u``, the only signals an observer has). Default zero.
    theta_names : sequence of str, optional
        Names of the ``m`` parameters (default ``"1".."m"``); the observer reports
        ``theta_<name>``.
    omega_names : sequence of str, optional
        Names of the ``s`` signals, for messages.
    to_physical : callable ``(x, theta, u) -> (state, params)``, optional
        The inverse maps 2.4-2.5: physical state and a mapping of named physical parameters.
        May raise :class:`DesignError` where the inverse does not exist.
    from_physical : callable ``(state, theta, u) -> x``, optional
        The state part of the transformation 2.1 at the parameter value ``theta`` (to start an
        observer from a physical ``x_hat0``).
    state_names : sequence of str, optional
        Names of the physical state (default ``x1..xn``, the AOCF state).
    physical_param_names : sequence of str
        Keys of the ``params`` mapping returned by ``to_physical``.
    label : str
        What the form is of, for messages.

    References
    ----------
    Paper 002, eq. 2.1-2.5.
    """

    def __init__(self, R: Any, alpha: Any, omega: Callable[[float, Array], Any], *,
                 g: Callable[[float, Array], Any] | None = None,
                 theta_names: Sequence[str] | None = None,
                 omega_names: Sequence[str] | None = None,
                 to_physical: PhysicalMap | None = None,
                 from_physical: Callable[[Array, Array, Array], Array] | None = None,
                 state_names: Sequence[str] | None = None,
                 physical_param_names: Sequence[str] = (), label: str = "AOCF") -> None:
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
        self.omega = _callable("omega", omega)
        self.g = _callable("g", g, optional=True)
        self.theta_names = _names("theta_names", theta_names, m, [str(i + 1) for i in range(m)])
        self.omega_names = _names("omega_names", omega_names, s, [f"w{i + 1}" for i in range(s)])
        self.to_physical = _callable("to_physical", to_physical, optional=True)
        self.from_physical = _callable("from_physical", from_physical, optional=True)
        self.physical_param_names = tuple(physical_param_names)
        if to_physical is None and self.physical_param_names:
            raise DesignError("physical_param_names need a to_physical map")
        self.state_names = _names("state_names", state_names, len(state_names or ()) or n,
                                  [f"x{i + 1}" for i in range(n)])
        self.label = str(label)

    # ------------------------------------------------------------------ structure
    def Omega(self, omega: Any) -> Array:
        """:math:`\\Omega(\\omega)`, shape ``(n, m)``."""
        w = vector("omega", omega, self.s)
        return self.alpha @ w

    def S_blocks(self) -> Array:
        """The constant blocks :math:`S_l` of :math:`S(\\omega) = \\sum_l \\omega_l S_l`
        (eq. 4.11), shape ``(s, n, m)``: row 1 is :math:`\\alpha_{1\\cdot l}`, row ``j`` is
        :math:`k^T F^{j-2} \\bar\\alpha_{\\cdot\\cdot l}`, ``j = 2..n``."""
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
        """:math:`S(\\omega)` of eq. 4.11 at one value of :math:`\\omega`, shape ``(n, m)``."""
        w = vector("omega", omega, self.s)
        return np.tensordot(w, self.S_blocks(), axes=1)

    def reachability(self, tol: float = 1e-9) -> dict[str, Any]:
        """Structural output reachability of the auxiliary filter (Theorem 4.2).

        The column rank over :math:`\\mathbb R` of :math:`S(\\omega)` is the rank of the
        stacked blocks :math:`[S_1; \\dots; S_s]` (exact when the components of
        :math:`\\omega` are linearly independent functions of time).

        Returns
        -------
        dict
            ``rank``, ``m``, ``reachable`` (``rank == m``) and ``unreachable``: an orthonormal
            basis (list of vectors) of the constant :math:`\\beta` with
            :math:`S(\\omega)\\beta \\equiv 0` -- the parameter combinations the filter
            cannot excite.
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

    # ------------------------------------------------------------------ factories
    @classmethod
    def from_system(cls, system: System, **kw: Any) -> AOCF:
        """The AOCF of a registered system, where one is derived.

        * :class:`~hgo_mj.systems.papers.BioreactorBastinGevers`: eq. 6.4-6.6 (``c2``);
        * :class:`~hgo_mj.systems.pendulum.Pendulum`,
          :class:`~hgo_mj.systems.cart_pendulum.CartPendulum`: :meth:`second_order`
          (``c2``, ``unknown``);
        * any system with a method ``aocf(**kw)`` returning an :class:`AOCF`.

        Raises
        ------
        DesignError
            For a system without a derived AOCF, naming what is missing.
        """
        from ..systems.cart_pendulum import CartPendulum
        from ..systems.papers import BioreactorBastinGevers
        from ..systems.pendulum import Pendulum

        if isinstance(system, BioreactorBastinGevers):
            return cls.bioreactor(system, **kw)
        if isinstance(system, (Pendulum, CartPendulum)):
            return cls.pendulum(system, **kw)
        form = cls._system_method(system, "aocf", kw, cls.from_system)
        if form is not None:
            return form
        raise DesignError(
            f"the Bastin-Gevers observer needs the adaptive observer canonical form of paper 002, "
            f"eq. 2.2 (R with k and F, Omega(omega) = alpha omega, g); {type(system).__name__} "
            f"provides none (no method aocf() and no derivation in hgo_mj.observers.bastin_gevers)"
            f"; give aocf=AOCF(...) explicitly (see docs/adaptive_canonical_forms.md)")

    @classmethod
    def bioreactor(cls, system: Any, c2: float | None = None) -> AOCF:
        """The AOCF eq. 6.5 of the bioreactor eq. 6.1, built on
        :meth:`~hgo_mj.systems.papers.BioreactorBastinGevers.aocf_structure`.

        :math:`\\omega = (y, u_1, u_2)`, :math:`k = 1`, :math:`F = -c_2`,
        :math:`\\Omega = [[y, 0, 0], [0, y, u_2]]`,
        :math:`g = (u_1, (1 - c_2) u_1 - (1 - c_2)^2 y)`. The inverse 6.6 (sign of 6.6b
        corrected) gives the physical state ``(z1, z2)`` and the parameters ``p1``, ``p2``,
        ``p3`` and the specific growth rate ``p0 = p1 z1``.

        References
        ----------
        Paper 002, eq. 6.4 (map), 6.5 (AOCF), 6.6 (inverse).
        """
        c2v = system._c2(c2)
        # alpha and the matrix of g by probing the paper's structure at unit omega
        basis = [(1.0, (0.0, 0.0)), (0.0, (1.0, 0.0)), (0.0, (0.0, 1.0))]
        alpha = np.zeros((2, 3, 3))
        G = np.zeros((2, 3))
        for l, (y, u) in enumerate(basis):
            R, Om, g = system.aocf_structure(y, u, c2v)
            alpha[:, :, l] = Om
            G[:, l] = g
        w = np.array([0.7, 1.3, -0.4])
        R, Om, g = system.aocf_structure(w[0], w[1:], c2v)
        if not (np.allclose(alpha @ w, Om, atol=1e-12) and np.allclose(G @ w, g, atol=1e-12)):
            raise DesignError("the bioreactor AOCF is expected linear in omega = (y, u1, u2); "
                              "aocf_structure is not")
        ga, gb = tuple(float(v) for v in G[0]), tuple(float(v) for v in G[1])

        def omega(y: float, u: Array) -> Array:
            return np.array([y, u[0], u[1]])

        def g_fun(y: float, u: Array) -> Array:
            return np.array([ga[0] * y + ga[1] * u[0] + ga[2] * u[1],
                             gb[0] * y + gb[1] * u[0] + gb[2] * u[1]])

        def to_physical(x: Array, theta: Array, u: Array) -> tuple[Array, dict[str, float]]:
            # eq. 6.6 (6.6b sign corrected) as in BioreactorBastinGevers.from_aocf, unchecked
            y, th1, th2, th3 = float(x[0]), float(theta[0]), float(theta[1]), float(theta[2])
            d = (c2v - 2.0) - th1
            z2 = (float(x[1]) - (1.0 - c2v) * y) / th3 if th3 != 0.0 else 0.0
            if th3 == 0.0 or z2 == 0.0 or d == 0.0:
                return system.from_aocf(x, theta, c2v)  # raises DesignError naming the cause
            p1 = (d * (1.0 - c2v) + th2) / (th3 * z2)
            return np.array([y, z2]), {"p1": p1, "p2": p1 * z2 / d, "p3": -th3, "p0": p1 * y}

        def from_physical(z: Array, theta: Array, u: Array) -> Array:
            # eq. 6.4b with p3 = -theta3
            return np.array([z[0], (1.0 - c2v) * z[0] + theta[2] * z[1]])

        return cls(R, alpha, omega, g=g_fun, theta_names=("1", "2", "3"),
                   omega_names=("y", "u1", "u2"), to_physical=to_physical,
                   from_physical=from_physical, state_names=system.state_names,
                   physical_param_names=("p1", "p2", "p3", "p0"),
                   label=f"{type(system).__name__} eq. 6.5, c2={c2v:g}"
                   )._made_by(cls.bioreactor, system, c2)

    @classmethod
    def second_order(cls, features: Callable[[float, Array], Any], feature_names: Sequence[str],
                     theta_names: Sequence[str], *, damping: float, c2: float = 2.0,
                     estimate_damping: bool = False, damping_name: str = "d_over_J",
                     damping_from: int | None = None,
                     state_names: Sequence[str] = ("y", "y_dot"), label: str = "") -> AOCF:
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
        features : callable ``(y, u) -> (q,)``
            :math:`\\psi(y, u)`.
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

        References
        ----------
        Paper 002, eq. 2.2, 2.6-2.8 (the observer form this is an instance of).
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

        def omega(y: float, u: Array) -> Array:
            w = np.empty(q + 1)
            w[0] = y
            w[1:] = feats(y, u)
            return w

        def g_fun(y: float, u: Array) -> Array:
            return np.array([gy0 * y, gy1 * y])

        def dlt(theta: Array) -> float:
            if damping_from is not None:
                return delta * float(theta[damping_from])
            return float(theta[0]) if ed else delta

        def to_physical(x: Array, theta: Array, u: Array) -> tuple[Array, dict[str, float]]:
            return np.array([x[0], x[1] - (dlt(theta) - c2) * x[0]]), {}

        def from_physical(xp: Array, theta: Array, u: Array) -> Array:
            return np.array([xp[0], xp[1] + (dlt(theta) - c2) * xp[0]])

        R = np.array([[0.0, 1.0], [0.0, -c2]])
        names = ((damping_name,) if ed else ()) + tn
        return cls(R, alpha, omega, g=g_fun, theta_names=names, omega_names=("y",) + fn,
                   to_physical=to_physical, from_physical=from_physical,
                   state_names=state_names, label=label or f"second-order joint, c2={c2:g}"
                   )._made_by(cls.second_order, features, fn, tn, damping=damping, c2=c2,
                              estimate_damping=ed, damping_name=damping_name,
                              damping_from=damping_from, state_names=state_names, label=label)

    @classmethod
    def pendulum(cls, system: Any, c2: float = 2.0, unknown: Sequence[str] | str | None = None,
                 damping_known: str = "ratio") -> AOCF:
        """AOCF of the MuJoCo pendulum (or Ibrir's cart pendulum) with unknown
        gravity-to-length ratio and input gain (:meth:`second_order`).

        Pendulum: :math:`\\ddot y = -\\delta \\dot y - a \\sin y + \\beta u` with
        :math:`a = m g l_c / J` (``g_over_l``: gravity over the equivalent length
        :math:`J/(m l_c)`), :math:`\\beta = b/J` (``b_over_J``), :math:`\\delta = d/J`
        (``d_over_J``). Cart pendulum: :math:`\\ddot y = -\\delta \\dot y + a \\sin y +
        \\beta u \\cos y` with :math:`a = m l g / J`, :math:`\\beta = m l a_u / J`.

        Parameters
        ----------
        unknown : sequence of str, optional
            ``("g_over_l", "b_over_J")`` (default; damping known, read from the system) or
            ``("d_over_J", "g_over_l", "b_over_J")`` (damping estimated too).
        damping_known : {"ratio", "coefficient"}
            With two unknowns, what is known of the damping: ``"ratio"`` (default),
            :math:`\\delta = d/J` itself; ``"coefficient"``, the coefficient :math:`d` and the
            gear :math:`b` but not the inertia, so :math:`\\delta = (d/b)\\,(b/J)` moves with
            the input-gain parameter (pendulum only).
        """
        from ..systems.cart_pendulum import CartPendulum

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
        if coef and isinstance(system, CartPendulum):
            raise DesignError("damping_known='coefficient' is derived for the pendulum only")
        if isinstance(system, CartPendulum):
            feats = lambda y, u: (math.sin(y), u[0] * math.cos(y))  # noqa: E731
            fnames = ("sin y", "u cos y")
            label = "cart pendulum: y'' = -d/J y' + a sin y + b u cos y"
        else:
            feats = lambda y, u: (-math.sin(y), u[0])  # noqa: E731
            fnames = ("-sin y", "u")
            label = "pendulum: y'' = -d/J y' - a sin y + b u"
        if coef:
            form = cls.second_order(feats, fnames, base, damping=p["damping"] / p["gear"], c2=c2,
                                    damping_from=1, state_names=system.state_names,
                                    label=f"{label}, d known (d/J = (d/b) b/J), c2={c2:g}")
        else:
            form = cls.second_order(feats, fnames, base, damping=p["damping"] / p["inertia"],
                                    c2=c2, estimate_damping="d_over_J" in unknown,
                                    state_names=system.state_names, label=f"{label}, c2={c2:g}")
        return form._made_by(cls.pendulum, system, c2=c2, unknown=unknown,
                             damping_known=damping_known)

    @staticmethod
    def pendulum_theta(system: Any, unknown: Sequence[str] | None = None) -> Array:
        """The true :math:`\\theta` of :meth:`pendulum` for a system's parameters."""
        from ..systems.cart_pendulum import CartPendulum

        p = system.params
        J = p["inertia"]
        if isinstance(system, CartPendulum):
            a = p["mass"] * p["length"] * p["g"] / J
            b = p["mass"] * p["length"] * p["accel_gain"] / J
        else:
            a = p["mass"] * p["g"] * p["com_distance"] / J
            b = p["gear"] / J
        th = [a, b]
        if unknown is not None and "d_over_J" in unknown:
            th = [p["damping"] / J, *th]
        return np.array(th)


# ======================================================================================
# the observer
# ======================================================================================


class BastinGeversObserver(Observer):
    """Adaptive observer of Bastin and Gevers (paper 002, eq. 3.1) on an :class:`AOCF`.

    .. math::

        \\dot{\\hat x} &= R \\hat x + \\Omega(\\omega) \\hat\\theta + g
            + \\begin{bmatrix} c_1 \\tilde y \\\\ V \\dot{\\hat\\theta} \\end{bmatrix}, \\quad
        \\dot{\\hat\\theta} = \\Gamma \\varphi \\tilde y, \\\\
        \\dot V &= F V + \\bar\\Omega(\\omega), \\quad
        \\varphi = V^T k + \\Omega_1^T(\\omega), \\quad \\tilde y = y - \\hat x_1

    (misprints of 3.1a and 3.1e corrected; see the module docstring). Between samples the
    measurement ``y`` and the input are held, so :math:`\\omega` and :math:`g` are constant over
    one ``update``; the state :math:`(\\hat x, \\hat\\theta, V)` is integrated by RK4 (or
    Euler) in ``substeps`` steps.

    Parameters
    ----------
    system : System, optional
        A system whose AOCF is derived (see :meth:`AOCF.from_system`); gives the physical
        coordinates of ``x_hat``. Not needed when ``aocf`` is given.
    aocf : AOCF, optional
        The canonical form; default ``AOCF.from_system(system, c2=..., unknown=...)``.
    c1 : float
        Output-injection gain, > 0 (Theorem 4.1 i).
    gamma : float, array_like (m,) or (m, m)
        Adaptation gain :math:`\\Gamma`, symmetric positive definite (eq. 3.1c).
    c2 : float, optional
        Design constant of the derived AOCF (forwarded to :meth:`AOCF.from_system`).
    unknown : sequence of str, optional
        Which parameters the derived AOCF estimates (pendulum; forwarded).
    damping_known : {"ratio", "coefficient"}, optional
        Pendulum: what is known of the damping (forwarded to :meth:`AOCF.pendulum`).
    output : int
        Index of the measured channel that is ``y = x1``.
    theta_hat0 : array_like (m,), optional
        Initial parameter estimate (default zero).
    x_hat0, z_hat0 : array_like, optional
        Initial estimate in physical coordinates (needs the form's ``from_physical``) or in
        AOCF coordinates (default zero).
    method : {"rk4", "euler"}
        Integration of one sample.
    substeps : int
        Integration steps per sample.
    excitation_window : float or None
        Window ``T`` of the excitation diagnostic (condition 4.5), in time units; ``None``
        switches the diagnostic off.
    on_unreachable : {"raise", "warn", "ignore"}
        What to do when the structural check of Theorem 4.2 finds the filter not output
        reachable (the parameters can then never be persistently excited).

    Attributes
    ----------
    theta_hat_ : ndarray (m,)
        Parameter estimate (AOCF parameters).
    phi_ : ndarray (m,)
        Regressor :math:`\\varphi` at the last sample.
    V_ : ndarray (n-1, m)
        State of the auxiliary filter.
    physical_params_ : dict
        Physical parameters from the form's inverse map (held where it is undefined).
    excitation_ : float
        Smallest eigenvalue of the windowed :math:`\\int \\varphi \\varphi^T` (4.5).
    reachability_rank_ : int
        Column rank of :math:`S(\\omega(t_k))` stacked over the samples seen so far.
    dropouts_, inverse_failures_ : int
        NaN samples run open loop; samples where the inverse map was undefined.

    References
    ----------
    Paper 002, eq. 2.2, 3.1-3.2, 4.1-4.5, 4.11, Theorems 4.1-4.4.
    """

    name = "bastin_gevers"
    summary = "Bastin-Gevers adaptive observer on the AOCF, auxiliary filter, PE diagnostic"
    reference = "paper 002 (Bastin, Gevers 1986), eq. 2.2, 3.1, 4.5, 4.11"

    def __init__(self, system: System | None = None, *, aocf: AOCF | None = None,
                 c1: float = 1.0, gamma: Any = 1.0, c2: float | None = None,
                 unknown: Sequence[str] | None = None, damping_known: str | None = None,
                 output: int = 0, theta_hat0: Any = None,
                 x_hat0: Any = None, z_hat0: Any = None, method: str = "rk4", substeps: int = 1,
                 excitation_window: float | None = 10.0, on_unreachable: str = "raise") -> None:
        if system is not None and not isinstance(system, System):
            raise DesignError(f"system must be a System instance or None; found "
                              f"{type(system).__name__}")
        if aocf is None:
            if system is None:
                raise DesignError("BastinGeversObserver needs a system with a derived AOCF or "
                                  "aocf=AOCF(...)")
            kw: dict[str, Any] = {}
            if c2 is not None:
                kw["c2"] = c2
            if unknown is not None:
                kw["unknown"] = unknown
            if damping_known is not None:
                kw["damping_known"] = damping_known
            try:
                aocf = AOCF.from_system(system, **kw)
            except TypeError as exc:
                raise DesignError(f"the AOCF of {type(system).__name__} takes other options: "
                                  f"{exc}") from None
        elif not isinstance(aocf, AOCF):
            raise DesignError(f"aocf must be an AOCF; found {type(aocf).__name__}")
        elif c2 is not None or unknown is not None or damping_known is not None:
            raise DesignError("c2, unknown and damping_known choose a derived AOCF; with aocf= "
                              "given they must be left out")
        super().__init__(None, aocf.n, output)
        self.system = system
        self.form = aocf
        n, m = aocf.n, aocf.m
        self.c1 = finite_scalar("c1", c1, positive=True)
        self.gamma = symmetric_matrix("gamma", gamma, m, dim="m")
        self.method = one_of("method", method, METHODS)
        self.substeps = positive_int("substeps", substeps)
        self.on_unreachable = one_of("on_unreachable", on_unreachable, ("raise", "warn", "ignore"))
        self.structure = aocf.reachability()
        if not self.structure["reachable"] and on_unreachable != "ignore":
            combos = "; ".join(
                " + ".join(f"{c:.3g}*{nm}" for c, nm in zip(v, aocf.theta_names) if abs(c) > 1e-9)
                for v in self.structure["unreachable"])
            msg = (f"the auxiliary filter (3.1d, e) of {aocf.label} is not output reachable "
                   f"(Theorem 4.2): S(omega) of eq. 4.11 has column rank {self.structure['rank']} "
                   f"over R, expected m = {m}; phi can never be persistently excited along "
                   f"[{combos}] of theta = {list(aocf.theta_names)}")
            if on_unreachable == "raise":
                raise DesignError(msg + " (on_unreachable='warn' runs anyway)")
            warnings.warn(msg, RuntimeWarning, stacklevel=2)
        if excitation_window is not None:
            excitation_window = finite_scalar("excitation_window", excitation_window, positive=True)
        self.excitation_window = excitation_window
        self._gram = SlidingGram(m, excitation_window) if excitation_window is not None else None
        # per-sample constants
        self._alpha2 = aocf.alpha.reshape(n * m, aocf.s)
        self._S_blocks = aocf.S_blocks()
        self._R, self._k, self._F = aocf.R, aocf.k, aocf.F
        self._generate()
        self.diagnostic_names = tuple(f"theta_{nm}" for nm in aocf.theta_names) + tuple(
            f"theta_{nm}" for nm in aocf.physical_param_names) + (
            ("excitation",) if self._gram is not None else ()) + ("reachability_rank",)
        self._init = (x_hat0, z_hat0, theta_hat0)
        self.reset(x_hat0, z_hat0=z_hat0, theta_hat0=theta_hat0)

    def _generate(self) -> None:
        """Generate eq. 3.1 in plain floats (at construction and on unpickling)."""
        f = self.form
        self._rhs_fast = compile_rhs(f.R, np.any(f.alpha != 0.0, axis=2), self.gamma, self.c1)

    def __getstate__(self) -> dict[str, Any]:
        """Pickle without the generated right-hand side (made with ``exec``); unpickling
        generates it again from the same design, so the copy continues identically. The
        form pickles as the call that built it (:class:`Rebuildable`)."""
        return {k: v for k, v in self.__dict__.items() if k != "_rhs_fast"}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._generate()

    # ------------------------------------------------------------------ reset
    def reset(self, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None,
              theta_hat0: Any = None) -> None:
        """Restart from ``x_hat0``/``z_hat0`` and ``theta_hat0`` (default: the constructor's);
        the filter restarts at ``V(0) = 0``."""
        f = self.form
        if x_hat0 is None and z_hat0 is None and theta_hat0 is None:
            x_hat0, z_hat0, theta_hat0 = self._init

        def physical(x_hat0: Any, th: Array) -> Array:
            if f.from_physical is None:
                raise DesignError(f"x_hat0 in physical coordinates needs the form's from_physical "
                                  f"map; {f.label} has none: give z_hat0 (AOCF coordinates)")
            xp = vector("x_hat0", x_hat0, len(f.state_names))
            u = np.zeros(0) if u0 is None else np.asarray(u0, dtype=float).reshape(-1)
            return vector("from_physical(x_hat0)", f.from_physical(xp, th, u), f.n)

        x, th = initial_estimate(f.n, f.m, x_hat0, z_hat0, theta_hat0, physical)
        self._s: list[float] = np.concatenate((x, th, np.zeros((f.n - 1) * f.m))).tolist()
        self.phi_ = np.zeros(f.m)
        self._restart_counters()
        self._params_last: Mapping[str, float] = {nm: math.nan for nm in f.physical_param_names}
        self._W = np.zeros((f.s, f.s))  # sum of omega omega^T: rank of S along the run
        self._wbuf: list[Array] = []  # the omegas not yet summed into _W
        self._rank: int | None = 0
        if self._gram is not None:
            self._gram.reset()
        self._u = np.zeros(0) if u0 is None else np.asarray(u0, dtype=float).reshape(-1)
        self._xp = x.copy()
        if f.to_physical is not None:
            try:
                self._xp = self._to_physical(x, th, self._u)
            except (DesignError, ZeroDivisionError, FloatingPointError) as exc:
                raise DesignError(f"the initial estimate (x = {x.tolist()}, theta = {th.tolist()}) "
                                  f"lies where the inverse map of {f.label} is undefined: {exc}; "
                                  f"give theta_hat0 / z_hat0 inside its domain") from None

    # ------------------------------------------------------------------ dynamics
    def rhs(self, s: Array, y: float, omega: Array, g: Array, correct: bool = True) -> Array:
        """Right-hand side of eq. 3.1 for the flat state ``s = (x_hat, theta_hat, vec V)``
        with ``omega`` and ``g`` given (public for continuous-time checks). ``correct=False``
        drops the output injection (a dropout)."""
        f = self.form
        n, m = f.n, f.m
        x, th = s[:n], s[n:n + m]
        V = s[n + m:].reshape(n - 1, m)
        Om = (self._alpha2 @ omega).reshape(n, m)
        phi = V.T @ self._k + Om[0]
        e = (y - x[0]) if correct else 0.0
        thd = self.gamma @ phi * e
        xd = self._R @ x + Om @ th
        xd += g
        xd[0] += self.c1 * e
        xd[1:] += V @ thd
        Vd = self._F @ V + Om[1:]
        return np.concatenate((xd, thd, Vd.reshape(-1)))

    def omega_g(self, y: float, u: Array) -> tuple[Array, Array]:
        """:math:`\\omega(y, u)` and :math:`g(y, u)`, shape-checked."""
        f = self.form
        try:
            w = np.asarray(f.omega(y, u), dtype=float).reshape(-1)
        except (IndexError, TypeError, ValueError) as exc:
            raise DimensionError(f"omega(y, u) of {f.label} failed on y = {y!r}, u of shape "
                                 f"{np.shape(u)}: {exc}") from None
        if w.shape != (f.s,):
            raise DimensionError(f"omega(y, u) of {f.label} must return {f.s} values; found "
                                 f"shape {w.shape}")
        if f.g is None:
            g = np.zeros(f.n)
        else:
            g = np.asarray(f.g(y, u), dtype=float).reshape(-1)
            if g.shape != (f.n,):
                raise DimensionError(f"g(y, u) of {f.label} must return n = {f.n} values; found "
                                     f"shape {g.shape}")
        return w, g

    # ------------------------------------------------------------------ interface
    def check_period(self, dt: float) -> None:
        """Refuse a sample period for which the integration of the linear modes
        :math:`-c_1` and :math:`\\lambda(F)` (the poles of :math:`R^*`, eq. 4.3) is unstable."""
        lam = np.concatenate(([-self.c1], np.linalg.eigvals(self._F) if self.form.n > 1 else []))
        check_rk_period("the Bastin-Gevers observer", lam, dt, self.method, self.substeps)

    def update(self, y: Any, u: Any, dt: float) -> Array:
        """Consume ``y(t_k)``, ``u(t_k)``; integrate eq. 3.1 over ``dt``; return
        ``x_hat(t_k + dt)``."""
        try:
            yi = float(y[self.output])
        except (IndexError, TypeError):
            raise DimensionError(f"y must be a vector with channel {self.output} (output); found "
                                 f"{y!r}") from None
        u = np.asarray(u, dtype=float).reshape(-1)
        self._u = u
        s = self._s
        if yi != yi:  # NaN: dropout -- predict without correction, omega at the prediction
            self.dropouts_ += 1
            c = 0.0
            yw = s[0]
        elif yi in (math.inf, -math.inf):
            raise DivergenceError(f"measurement y[{self.output}] is {yi}")
        else:
            c = 1.0
            yw = yi
        w, g = self.omega_g(yw, u)
        O = (self._alpha2 @ w).tolist()
        self.phi_ = phi = np.array(self._rhs_fast.phi(s, O))
        if self._gram is not None:
            self._gram.add(phi, dt)
        self._wbuf.append(w)  # folded into _W when the rank is asked for
        self._rank = None
        s = rk_step(self._rhs_fast, s, dt / self.substeps, self.method, self.substeps,
                    yw, c, O, g.tolist())
        if not all(map(math.isfinite, s)):
            raise DivergenceError(f"the Bastin-Gevers observer left the finite numbers: state "
                                  f"(x_hat, theta_hat, V) = {s}")
        self._s = s
        self._refresh_physical()
        return self._xp.copy()

    # ------------------------------------------------------------------ estimates
    def _to_physical(self, x: Array, th: Array, u: Array) -> Array:
        state, params = self.form.to_physical(x, th, u)  # type: ignore[misc]
        if not all(map(math.isfinite, state)):
            raise DesignError(f"the inverse map gave a non-finite state {list(state)}")
        if params:
            self._params_last = params
        return state

    @property
    def z_hat(self) -> Array:
        """AOCF state estimate :math:`\\hat x`."""
        return np.array(self._s[:self.form.n])

    @property
    def theta_hat_(self) -> Array:
        f = self.form
        return np.array(self._s[f.n:f.n + f.m])

    @property
    def V_(self) -> Array:
        f = self.form
        return np.array(self._s[f.n + f.m:]).reshape(f.n - 1, f.m)

    @property
    def state_vector_(self) -> Array:
        """The flat observer state ``(x_hat, theta_hat, vec V)`` (the argument of :meth:`rhs`)."""
        return np.array(self._s)

    def _refresh_physical(self) -> None:
        f = self.form
        x = np.array(self._s[:f.n])
        if f.to_physical is None:
            self._xp = x
            return
        try:
            self._xp = self._to_physical(x, np.array(self._s[f.n:f.n + f.m]), self._u)
        except (DesignError, ZeroDivisionError, FloatingPointError):
            self.inverse_failures_ += 1  # hold the last physical estimate

    @property
    def state_names(self) -> tuple[str, ...]:
        return self.form.state_names

    @property
    def x_hat(self) -> Array:
        """Estimate in physical coordinates (the form's inverse map 2.4, computed once per
        sample; where it is undefined the last value is held and ``inverse_failures_`` counts
        it)."""
        return self._xp.copy()

    @property
    def physical_params_(self) -> dict[str, float]:
        return {nm: float(self._params_last[nm]) for nm in self.form.physical_param_names}

    @property
    def excitation_(self) -> float:
        return self._gram.min_eig if self._gram is not None else math.nan

    @property
    def excitation_matrix_(self) -> Array:
        """The windowed :math:`\\int \\varphi \\varphi^T d\\tau` of condition 4.5."""
        if self._gram is None:
            raise DesignError("the excitation diagnostic is off (excitation_window=None)")
        return self._gram.matrix

    @property
    def reachability_rank_(self) -> int:
        if self._rank is None:
            if self._wbuf:
                B = np.array(self._wbuf)
                self._W += B.T @ B
                self._wbuf.clear()
            Sb = self._S_blocks  # (s, n, m)
            G = np.einsum("lij,lk,kip->jp", Sb, self._W, Sb)
            ev = np.linalg.eigvalsh(0.5 * (G + G.T))
            top = float(ev[-1]) if ev.size else 0.0
            self._rank = int(np.sum(ev > 1e-12 * top)) if top > 0 else 0
        return self._rank

    def diagnostics(self) -> dict[str, float]:
        f = self.form
        th = self._s[f.n:f.n + f.m]
        out = {f"theta_{nm}": v for nm, v in zip(f.theta_names, th)}
        if f.physical_param_names:
            p = self._params_last
            out.update({f"theta_{nm}": float(p[nm]) for nm in f.physical_param_names})
        if self._gram is not None:
            out["excitation"] = self._gram.min_eig
        out["reachability_rank"] = float(self.reachability_rank_)
        out["dropouts"] = float(self.dropouts_)
        return out

    def params(self) -> dict[str, Any]:
        f = self.form
        return {"aocf": f.label, "n": f.n, "m": f.m, "theta_names": list(f.theta_names),
                "c1": self.c1, "gamma": self.gamma.tolist(), "output": self.output,
                "method": self.method, "substeps": self.substeps,
                "excitation_window": self.excitation_window,
                "structural_rank": self.structure["rank"]}
