"""The adaptive observer of Bastin and Gevers (paper 002 [002]_, after [LN74]_) on the adaptive
observer canonical form.

**Canonical form (AOCF), eq. 2.2-2.3.** A single-output system transformed to

.. math::

    \\dot x = R x + \\Omega(\\omega)\\, \\theta + g, \\qquad y = x_1, \\qquad
    R = \\begin{bmatrix} 0 & k^T \\\\ 0 & F \\end{bmatrix}, \\qquad
    \\Omega_{ij}(\\omega) = \\alpha_{ij}^T \\omega,

with :math:`x \\in \\mathbb R^n`, unknown (possibly slowly time-varying) parameters
:math:`\\theta \\in \\mathbb R^m`, :math:`\\omega \\in \\mathbb R^s` a vector of known functions
of the input and the output, constant vectors :math:`\\alpha_{ij}`, known :math:`k`, a Hurwitz
:math:`F` and known :math:`g`. The form is data (:class:`~hgo_mj.systems.aocf.AOCF`); a system
that has one declares it (``system.form("aocf", ...)``).

**Observer, eq. 3.1.** With :math:`\\tilde y = y - \\hat x_1`, :math:`\\Omega_1` the first row
of :math:`\\Omega` and :math:`\\bar\\Omega` the others (eq. 3.2),

.. math::

    \\dot{\\hat x} &= R \\hat x + \\Omega(\\omega) \\hat\\theta + g
                    + \\begin{bmatrix} c_1 \\tilde y \\\\ V \\dot{\\hat\\theta} \\end{bmatrix}
                    && \\text{(3.1a)} \\\\
    \\dot{\\hat\\theta} &= \\Gamma \\varphi \\tilde y && \\text{(3.1c)} \\\\
    \\dot V &= F V + \\bar\\Omega(\\omega), \\quad V(0) = 0 && \\text{(3.1d)} \\\\
    \\varphi &= V^T k + \\Omega_1^T(\\omega) && \\text{(3.1e)}

written once, in :func:`rhs_3_1`, and integrated over one sample period (measurement and
input held) for B members at once by :func:`advance_3_1` (numba; a loop over the members and
the samples inside the kernel).

**Four misprints of the paper, corrected here** (each follows from the error system 4.2,
which the paper derives from 3.1; the derivation is in ``docs/adaptive_canonical_forms.md``
and the test ``tests/observers/test_bastin_gevers.py::test_error_system_4_2``):

* 3.1a prints the correction of the last rows as :math:`v(t) \\hat\\theta(t)`; it is
  :math:`V(t) \\dot{\\hat\\theta}(t)`.
* 3.1e prints :math:`\\dot\\varphi = V^T k + \\Omega_1^T`; the regressor is the filter's
  *output* :math:`\\varphi = V^T k + \\Omega_1^T` (only then is the top row of 4.2
  :math:`\\varphi^T \\tilde\\theta`).
* 4.1 prints :math:`\\tilde x^* = \\tilde x - (0, \\tilde\\theta)`; dimensions require
  :math:`\\tilde x^* = \\tilde x - (0, V \\tilde\\theta)`, and the forcing of 4.2 is the true
  parameter drift :math:`\\dot\\theta` (printed :math:`\\hat\\theta`).
* Theorem 4.1 v), eq. 4.6, prints the bound on
  :math:`|[-V(t);\\ I_m]\\, \\dot{\\hat\\theta}(t)|`; it is the true parameter's drift
  :math:`|[-V(t);\\ I_m]\\, \\dot\\theta(t)| \\le M_1`, the forcing of 4.2 (Comment 4.1 v)
  discusses the boundedness of :math:`|\\dot\\theta|`, and only so does 4.7b,
  :math:`\\limsup |\\varepsilon| \\le K_3 M_1`, give convergence for a constant
  :math:`\\theta`).

**Output reachability, Theorem 4.2.** The filter (3.1d, e) with output :math:`\\varphi` is
output reachable from :math:`\\omega` iff :math:`S(\\omega)` of eq. 4.11 has full column rank
over :math:`\\mathbb R`, with rows the Markov parameters
:math:`s_1 = \\Omega_1`, :math:`s_j = k^T F^{j-2} \\bar\\Omega` (the printed
":math:`F_j^{-2}`" is :math:`F^{j-2}`). Rows beyond :math:`j = n` are combinations of the first
:math:`n` (Cayley-Hamilton), so :math:`j = 1..n` is used whatever :math:`m`. Since
:math:`S` is linear in :math:`\\omega`, :math:`S(\\omega) = \\sum_l \\omega_l S_l`, and the
structural check (before a run) is the column rank of :math:`[S_1; \\dots; S_s]`, exact
whenever the components of :math:`\\omega` are linearly independent functions of time. Along
a run, the diagnostic ``reachability_rank`` is the rank of the stacked
:math:`S(\\omega(t_k))` (:func:`reachability_rank_4_11`).

**Excitation, condition 4.5.** The diagnostic ``excitation`` is the smallest eigenvalue of
:math:`\\int_{t-T}^{t} \\varphi \\varphi^T d\\tau` over the last ``excitation_window`` ``T``
(a sum over samples, :func:`excitation_4_5`): positive and bounded away from zero where
:math:`\\theta` is identifiable.

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
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from .._validate import finite_scalar, one_of, positive_int, symmetric_matrix, vector
from ..exceptions import DesignError, DimensionError, DivergenceError
from ..systems.aocf import AOCF, Rebuildable, _callable, _names
from ..systems.base import System
from ._integrate import euler_step, rk4_step
from .base import Array, Observer, Params, State, _batch_of, _batch_size, batch_rows, register

__all__ = ["AOCF", "BastinGeversObserver", "Rebuildable", "SlidingGram", "advance_3_1",
           "check_rk_period", "diagnostics_4_5_4_11", "excitation_4_5", "reachability_rank_4_11",
           "rhs_3_1", "rk_stable_period", "sym_eigvals"]

# re-exported for the other adaptive families (Jo-Son, Besancon): the form base and checks
_REEXPORTED = (Rebuildable, _callable, _names)

METHODS = ("rk4", "euler")
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


# ======================================================================================
# shared helpers (also used by the Jo-Son and Besancon observers)
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
    the method's region of absolute stability. ``inf`` if there are no modes.

    Parameters
    ----------
    eigenvalues : array_like of complex
        The linear modes (zeros are ignored).
    method : {"rk4", "rk2", "euler"}
        The explicit Runge-Kutta method.

    Returns
    -------
    float
        The step limit (found by bisection to about 1e-16 relative), ``inf`` without modes.

    Examples
    --------
    >>> round(rk_stable_period([-1.0], "euler"), 6), round(rk_stable_period([-1.0], "rk4"), 4)
    (2.0, 2.7853)
    >>> rk_stable_period([], "rk4")
    inf
    """
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
    naming the largest stable step and the substeps it takes (:func:`rk_stable_period`).

    Parameters
    ----------
    what : str
        The integrated system, for the message (e.g. "the Jo-Son observer").
    poles : array_like of complex
        Its linear modes.
    dt : float
        Sample period, > 0.
    method : {"rk4", "rk2", "euler"}
        The integration method.
    substeps : int
        Steps per sample period.

    Raises
    ------
    DesignError
        ``dt`` not a positive finite number, or ``dt / substeps`` not below the stable step.

    Examples
    --------
    >>> check_rk_period("the test observer", [-1.0], 0.1, "euler", 1)  # stable: silent
    >>> check_rk_period("the test observer", [-100.0], 0.1, "euler", 1)
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: euler integration of the test observer with step 0.1 ...
    the largest stable step is 0.02: raise substeps to at least 6
    """
    dt = finite_scalar("dt", dt, positive=True)
    h = rk_stable_period(poles, method)
    if dt / substeps >= h:
        raise DesignError(
            f"{method} integration of {what} with step {dt / substeps:g} (sample period "
            f"{dt:g} / {substeps} substeps) is unstable on its poles "
            f"{np.round(poles, 6).tolist()}; the largest stable step is {h:.4g}: raise "
            f"substeps to at least {math.ceil(dt / h * 1.0000001)}")


class SlidingGram:
    """Sliding-window Gram matrix ``sum_{last W samples} v v^T dt`` (condition 4.5), one
    vector at a time (the Jo-Son observer's; the Bastin-Gevers observer keeps the same window
    for B members in arrays, :func:`excitation_4_5`).

    The last ``W = round(window / dt)`` vectors are kept in a ring buffer (one row write per
    sample); the matrix and its smallest eigenvalue are computed when asked for.

    Parameters
    ----------
    m : int
        Length of the vectors ``v``.
    window : float
        Window length, in the time unit of ``dt``.

    Examples
    --------
    >>> import numpy as np
    >>> gram = SlidingGram(2, window=0.05)
    >>> for i in range(10):
    ...     gram.add(np.array([1.0, float(i % 2)]), 0.01)
    >>> gram.matrix                          # the last 5 samples
    array([[0.05, 0.03],
           [0.03, 0.03]])
    >>> round(gram.min_eig, 6)
    0.008377
    """

    def __init__(self, m: int, window: float) -> None:
        self.m = m
        self.window = window
        self.reset()

    def reset(self) -> None:
        """Empty the window (the matrix is zero until the next :meth:`add`).

        Examples
        --------
        >>> import numpy as np
        >>> gram = SlidingGram(2, window=0.05)
        >>> gram.add(np.ones(2), 0.01)
        >>> gram.reset()
        >>> gram.matrix
        array([[0., 0.],
               [0., 0.]])
        """
        self._buf: Array | None = None
        self._dt = math.nan
        self._i = 0
        self._full = False
        self._min_eig: float | None = 0.0

    def add(self, v: Array, dt: float) -> None:
        """Push one sample ``v`` taken over ``dt`` into the window (the oldest drops out once
        ``round(window / dt)`` are held; a new ``dt`` starts the window over).

        Parameters
        ----------
        v : (m,) ndarray
            The sample.
        dt : float
            Its sample period.

        Examples
        --------
        >>> import numpy as np
        >>> gram = SlidingGram(1, window=1.0)
        >>> gram.add(np.array([2.0]), 0.5)
        >>> gram.matrix
        array([[2.]])
        """
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


# ======================================================================================
# the kernels: eq. 2.2, 3.1, 4.5, 4.11, on the flat state s = (x_hat, theta_hat, vec V)
# ======================================================================================
# Every kernel takes float64 C-contiguous arrays and ints/floats only (one compiled signature
# for every form); the members are independent, so a member computes the same bits alone or
# in a batch. Sums run left to right in the order of the equations as printed.


@njit(cache=True)
def omega_matrix_2_2(alpha: Array, w: Array, Om: Array) -> None:
    """Eq. 2.2: :math:`\\Omega_{ij}(\\omega) = \\alpha_{ij}^T \\omega`, into ``Om`` ``(n, m)``."""
    n, m, s = alpha.shape
    for i in range(n):
        for j in range(m):
            acc = 0.0
            for l in range(s):
                acc += alpha[i, j, l] * w[l]
            Om[i, j] = acc


@njit(cache=True)
def regressor_3_1e(s: Array, Om: Array, R: Array, phi: Array) -> None:
    """Eq. 3.1e: :math:`\\varphi = V^T k + \\Omega_1^T` (``k = R[0, 1:]``), into ``phi`` ``(m,)``."""
    n, m = Om.shape
    v0 = n + m  # V[i, j] = s[v0 + i m + j]
    for j in range(m):
        acc = 0.0
        for i in range(n - 1):
            acc += R[0, 1 + i] * s[v0 + i * m + j]
        phi[j] = acc + Om[0, j]


@njit(cache=True)
def rhs_3_1(s: Array, y: float, c: float, Om: Array, g: Array, R: Array, gamma: Array,
            c1: float, phi: Array, out: Array) -> None:
    """The right-hand side of eq. 3.1 (misprints of 3.1a and 3.1e corrected) at the flat
    state ``s = (x_hat (n), theta_hat (m), vec V ((n-1) m, row-major))`` with
    :math:`\\Omega(\\omega)` ``Om`` and ``g`` held, into ``out``; ``c`` is 1.0, or 0.0 for a
    dropout (no output injection). ``phi`` is work space ``(m,)``.

    .. math::

        \\tilde y &= c\\,(y - \\hat x_1) \\\\
        \\varphi &= V^T k + \\Omega_1^T && \\text{(3.1e)} \\\\
        \\dot{\\hat\\theta} &= \\Gamma \\varphi \\tilde y && \\text{(3.1c)} \\\\
        \\dot{\\hat x} &= R \\hat x + \\Omega \\hat\\theta + g
            + (c_1 \\tilde y,\\ V \\dot{\\hat\\theta}) && \\text{(3.1a)} \\\\
        \\dot V &= F V + \\bar\\Omega && \\text{(3.1d)}
    """
    n, m = Om.shape
    v0 = n + m
    e = c * (y - s[0])
    regressor_3_1e(s, Om, R, phi)
    for j in range(m):  # (3.1c)
        acc = 0.0
        for l in range(m):
            acc += gamma[j, l] * phi[l]
        out[n + j] = acc * e
    for i in range(n):  # (3.1a)
        acc = 0.0
        for a in range(n):
            acc += R[i, a] * s[a]
        for j in range(m):
            acc += Om[i, j] * s[n + j]
        acc += g[i]
        if i == 0:
            acc += c1 * e
        else:
            for j in range(m):
                acc += s[v0 + (i - 1) * m + j] * out[n + j]
        out[i] = acc
    for i in range(n - 1):  # (3.1d), F = R[1:, 1:]
        for j in range(m):
            acc = 0.0
            for a in range(n - 1):
                acc += R[1 + i, 1 + a] * s[v0 + a * m + j]
            out[v0 + i * m + j] = acc + Om[1 + i, j]


@njit(cache=True, inline="always")
def rhs_3_1_args(s: Array, a: Any, out: Array) -> None:  # pragma: no cover - jit
    """:func:`rhs_3_1` with its other arguments as one tuple ``a = (y, c, Om, g, R, gamma, c1,
    phi)``: the right-hand side form of :mod:`hgo_mj.observers._integrate`."""
    rhs_3_1(s, a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], out)


@njit(cache=True)
def _step(s: Array, y: float, c: float, Om: Array, g: Array, R: Array, gamma: Array,
          c1: float, h: float, substeps: int, euler: bool, phi: Array, k1: Array, k2: Array,
          k3: Array, k4: Array, tmp: Array) -> None:
    """``substeps`` steps of classical RK4 (or Euler) of :func:`rhs_3_1`, ``s`` in place
    (:func:`~hgo_mj.observers._integrate.rk4_step`, :func:`~hgo_mj.observers._integrate.euler_step`)."""
    args = (y, c, Om, g, R, gamma, c1, phi)
    for _ in range(substeps):
        if euler:
            euler_step(rhs_3_1_args, s, h, args, k1, s)
        else:
            rk4_step(rhs_3_1_args, s, h, args, k1, k2, k3, k4, tmp, s)


@njit(cache=True)
def advance_3_1(S: Array, j0: int, j1: int, Y: Array, W: Array, G: Array,
                alpha: Array, R: Array, gamma: Array, c1: float, h: float, substeps: int,
                euler: bool, Sout: Array, PHI: Array) -> int:
    """Samples ``j0 <= j < j1`` of every member ``b``: with the measurement ``Y[b, j]``,
    :math:`\\omega` ``W[b, j]`` and ``g`` ``G[b, j]`` held, record the regressor
    :math:`\\varphi` (3.1e) at the sample in ``PHI[b, j]``, integrate eq. 3.1 over the period
    (``substeps`` steps of ``h``) and write the state after it into ``S[b]`` and
    ``Sout[b, j]``. A NaN measurement is a dropout: no output injection (``c = 0``, the
    output taken at the prediction :math:`\\hat x_1`).

    Returns ``-1``, or ``b * T + j`` of the first member and sample whose state left the
    finite numbers (that member's ``S[b]`` keeps its last finite state; ``Sout[b, j]`` holds
    the non-finite one).
    """
    B, ns = S.shape
    T = Y.shape[1]
    n, m, _ = alpha.shape
    Om = np.empty((n, m))
    phi, sv = np.empty(m), np.empty(ns)
    k1, k2, k3, k4, tmp = (np.empty(ns), np.empty(ns), np.empty(ns), np.empty(ns),
                           np.empty(ns))
    for b in range(B):
        for j in range(j0, j1):
            omega_matrix_2_2(alpha, W[b, j], Om)
            for i in range(ns):
                sv[i] = S[b, i]
            regressor_3_1e(sv, Om, R, phi)
            for i in range(m):
                PHI[b, j, i] = phi[i]
            y, c = Y[b, j], 1.0
            if np.isnan(y):  # a dropout: predict without correction
                y, c = sv[0], 0.0
            _step(sv, y, c, Om, G[b, j], R, gamma, c1, h, substeps, euler, phi,
                  k1, k2, k3, k4, tmp)
            finite = True
            for i in range(ns):
                Sout[b, j, i] = sv[i]
                if not np.isfinite(sv[i]):
                    finite = False
            if not finite:
                return b * T + j
            for i in range(ns):
                S[b, i] = sv[i]
    return -1


@njit(cache=True)
def rhs_one(s: Array, y: float, c: float, w: Array, g: Array, alpha: Array, R: Array,
            gamma: Array, c1: float) -> Array:
    """:func:`rhs_3_1` of one state with :math:`\\Omega = \\alpha \\omega` (for
    continuous-time checks)."""
    n, m, _ = alpha.shape
    Om = np.empty((n, m))
    omega_matrix_2_2(alpha, w, Om)
    out = np.empty(s.shape[0])
    rhs_3_1(s, y, c, Om, g, R, gamma, c1, np.empty(m), out)
    return out


@njit(cache=True)
def sym_eigvals(A: Array, a: Array, out: Array) -> None:
    """Eigenvalues of the symmetric ``A`` ``(m, m)`` into ``out`` (unsorted), by cyclic
    Jacobi rotations on the work matrix ``a`` until every off-diagonal entry is below
    ``1e-17`` of its diagonal (accurate to a few ulps of ``|A|``; the same operations for the
    same matrix, alone or in a batch)."""
    m = A.shape[0]
    for p in range(m):
        for q in range(m):
            a[p, q] = A[p, q]
    for _ in range(64):
        rotated = False
        for p in range(m - 1):
            for q in range(p + 1, m):
                apq = a[p, q]
                # an entry below 1e-17 of its diagonal moves no eigenvalue by an ulp: drop it
                if abs(apq) <= 1e-17 * (abs(a[p, p]) + abs(a[q, q])):
                    a[p, q] = 0.0
                    a[q, p] = 0.0
                    continue
                rotated = True
                theta = (a[q, q] - a[p, p]) / (2.0 * apq)
                t = 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
                if theta < 0.0:
                    t = -t
                cs = 1.0 / math.sqrt(t * t + 1.0)
                sn = t * cs
                for r in range(m):  # columns p, q of a J
                    arp, arq = a[r, p], a[r, q]
                    a[r, p] = cs * arp - sn * arq
                    a[r, q] = sn * arp + cs * arq
                for r in range(m):  # rows p, q of J^T (a J)
                    apr, aqr = a[p, r], a[q, r]
                    a[p, r] = cs * apr - sn * aqr
                    a[q, r] = sn * apr + cs * aqr
                a[p, q] = 0.0
                a[q, p] = 0.0
        if not rotated:
            break
    for p in range(m):
        out[p] = a[p, p]


@njit(cache=True)
def excitation_4_5(phi: Array, dt: float, ring: Array, i: int, full: bool, gram: Array,
                   a: Array, ev: Array, G: Array) -> float:
    """Condition 4.5 after one sample: put the regressor ``phi`` into the ring ``(L, m)`` of
    the last ``L`` at position ``i`` (``full``: it has wrapped), update the running
    :math:`\\sum \\varphi \\varphi^T` ``gram`` ``(m, m)`` (rebuilt from the ring at each wrap so
    that rounding cannot accumulate) and return the smallest eigenvalue of ``gram * dt``
    (NaN where it is not finite). ``a``, ``ev``, ``G`` are work space."""
    m = phi.shape[0]
    L = ring.shape[0]
    if full:
        for p in range(m):
            for q in range(m):
                gram[p, q] -= ring[i, p] * ring[i, q]
    for p in range(m):
        ring[i, p] = phi[p]
    for p in range(m):
        for q in range(m):
            gram[p, q] += ring[i, p] * ring[i, q]
    if i == L - 1:
        for p in range(m):
            for q in range(m):
                acc = 0.0
                for r in range(L):
                    acc += ring[r, p] * ring[r, q]
                gram[p, q] = acc
    for p in range(m):
        for q in range(m):
            G[p, q] = gram[p, q] * dt
            if not np.isfinite(G[p, q]):
                return np.nan
    sym_eigvals(G, a, ev)
    return ev.min()


@njit(cache=True)
def reachability_rank_4_11(w: Array, P: Array, Wsum: Array, a: Array, ev: Array,
                           G: Array) -> int:
    """Theorem 4.2 along a run, after one sample with signals ``w`` ``(s,)``: the column rank
    of the stacked :math:`S(\\omega_k)` of eq. 4.11 over every sample so far, as the number of
    eigenvalues of :math:`\\sum_k S(\\omega_k)^T S(\\omega_k) = \\sum_{l,l'} (\\sum_k
    \\omega_{k,l} \\omega_{k,l'}) S_l^T S_{l'}` above ``1e-12`` of the largest. ``P[l, l']``
    ``(s, s, m, m)`` holds :math:`S_l^T S_{l'}`, ``Wsum`` ``(s, s)`` the running
    :math:`\\sum_k \\omega_k \\omega_k^T` (updated here). ``a``, ``ev``, ``G`` are work space."""
    s = w.shape[0]
    m = P.shape[2]
    for l in range(s):
        for k in range(s):
            Wsum[l, k] += w[l] * w[k]
    for p in range(m):
        for q in range(m):
            acc = 0.0
            for l in range(s):
                for k in range(s):
                    acc += Wsum[l, k] * P[l, k, p, q]
            G[p, q] = acc
    for p in range(m):
        for q in range(p + 1, m):
            G[p, q] = G[q, p] = 0.5 * (G[p, q] + G[q, p])
    sym_eigvals(G, a, ev)
    top = ev.max()
    rank = 0
    if top > 0.0:
        for p in range(m):
            if ev[p] > 1e-12 * top:
                rank += 1
    return rank


@njit(cache=True)
def diagnostics_4_5_4_11(PHI: Array, W: Array, dt: float, ring: Array, pos: IntArray,
                         full: BoolArray, gram: Array, P: Array, Wsum: Array,
                         out: Array) -> None:
    """After each sample ``j`` of every member ``b``: ``out[b, j, 0]`` the excitation of
    condition 4.5 (:func:`excitation_4_5`; skipped for a ring ``(B, 0, m)``: the diagnostic
    off) and ``out[b, j, 1]`` the rank of Theorem 4.2 (:func:`reachability_rank_4_11`), from
    the regressors ``PHI`` ``(B, T, m)`` and the signals ``W`` ``(B, T, s)``. ``ring``,
    ``pos``, ``full``, ``gram`` and ``Wsum`` are the members' running state."""
    B, T, m = PHI.shape
    L = ring.shape[1]
    a, ev, G = np.empty((m, m)), np.empty(m), np.empty((m, m))
    for b in range(B):
        for j in range(T):
            if L > 0:
                i = pos[b]
                out[b, j, 0] = excitation_4_5(PHI[b, j], dt, ring[b], i, full[b], gram[b],
                                              a, ev, G)
                i += 1
                if i == L:
                    i = 0
                    full[b] = True
                pos[b] = i
            out[b, j, 1] = reachability_rank_4_11(W[b, j], P, Wsum[b], a, ev, G)


@njit(cache=True)
def hold_valid(states: Array, params: Array, x_held: Array, p_held: Array,
               failures: IntArray, X: Array, Dp: Array) -> None:
    """The physical estimate after each sample: ``states[b, j]`` ``(B, T, n_x)`` (and its
    ``params``) where it is finite, else the member's last valid value (``x_held[b]``,
    ``p_held[b]`` before the block, updated here), counted in ``failures[b]``."""
    B, T, nx = states.shape
    npar = params.shape[2]
    for b in range(B):
        for j in range(T):
            valid = True
            for i in range(nx):
                if not np.isfinite(states[b, j, i]):
                    valid = False
            if valid:
                for i in range(nx):
                    x_held[b, i] = states[b, j, i]
                for i in range(npar):
                    p_held[b, i] = params[b, j, i]
            else:
                failures[b] += 1
            for i in range(nx):
                X[b, j, i] = x_held[b, i]
            for i in range(npar):
                Dp[b, j, i] = p_held[b, i]


# ======================================================================================
# the observer
# ======================================================================================


@register
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
    one sample; the state :math:`(\\hat x, \\hat\\theta, V)` is integrated by RK4 (or Euler) in
    ``substeps`` steps. At a dropout (NaN) the member predicts without output injection, with
    :math:`\\omega` and :math:`g` at its predicted output :math:`\\hat x_1`.

    Parameters
    ----------
    system : System, optional
        A system declaring the ``"aocf"`` form (``system.form("aocf", c2=..., ...)``); gives
        the physical coordinates of ``x_hat``. Not needed when ``aocf`` is given.
    aocf : AOCF, optional
        The canonical form; default the system's.
    c1 : float
        Output-injection gain, > 0 (Theorem 4.1 i).
    gamma : float, array_like (m,) or (m, m)
        Adaptation gain :math:`\\Gamma`, symmetric positive definite (eq. 3.1c).
    c2 : float, optional
        Design constant of the system's AOCF (an option of its form).
    unknown : sequence of str, optional
        Which parameters the system's AOCF estimates (pendulum; an option of its form).
    damping_known : {"ratio", "coefficient"}, optional
        Pendulum: what is known of the damping (an option of its form).
    outputs : tuple of int
        The measured channel that is ``y = x1``, a 1-tuple.
    theta_hat0 : array_like (m,) or (B, m), optional
        Initial parameter estimate (default: the form's ``start``, else zero).
    x_hat0, z_hat0 : array_like, optional
        Initial estimate in physical coordinates (needs the form's ``from_physical``) or in
        AOCF coordinates (default: the form's ``start``, else zero). A form whose inverse map
        is undefined at zero declares a start inside its domain: the bioreactor's is its
        nominal model at its default state (eq. 6.4; 6.6 needs :math:`\\theta_3 \\ne 0`,
        :math:`z_2 \\ne 0`), so ``BastinGeversObserver(BioreactorBastinGevers())`` runs.
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
    on_unstable : {"raise", "warn", "ignore"}
        What :meth:`check_period` does at a period where the integration is unstable.

    Attributes
    ----------
    theta_hat_ : ndarray (m,) or (B, m)
        Parameter estimate (AOCF parameters).
    phi_ : ndarray (m,) or (B, m)
        Regressor :math:`\\varphi` at the last sample.
    V_ : ndarray (n-1, m) or (B, n-1, m)
        State of the auxiliary filter.
    physical_params_ : dict
        Physical parameters from the form's inverse map (held where it is undefined).
    excitation_ : float or (B,)
        Smallest eigenvalue of the windowed :math:`\\int \\varphi \\varphi^T` (4.5).
    reachability_rank_ : int or (B,)
        Column rank of :math:`S(\\omega(t_k))` stacked over the samples seen so far.
    dropouts_, inverse_failures_ : int or (B,)
        NaN samples run open loop; samples where the inverse map was undefined.

    References
    ----------
    Paper 002, eq. 2.2, 3.1-3.2, 4.1-4.5, 4.11, Theorems 4.1-4.4.

    Examples
    --------
    Paper 002's bioreactor (eq. 6.1), started from the canonical coordinates of a wrong guess
    of its parameters:

    >>> import numpy as np
    >>> from hgo_mj.systems.papers import BioreactorBastinGevers
    >>> guess = BioreactorBastinGevers(mu_max=2.0, p2=1.0, p3=0.1)
    >>> x0, th0 = guess.to_aocf([1.0, 2.0], 1.0)
    >>> ob = BastinGeversObserver(BioreactorBastinGevers(), c1=5.0, gamma=2.0, c2=1.0,
    ...                           theta_hat0=th0, z_hat0=x0)
    >>> ob.state_names, ob.theta_hat_.shape
    (('z1', 'z2'), (3,))
    >>> ob.update([1.1], [0.1, 0.5], 0.01).round(4)
    array([0.9717, 2.0071])
    """

    name = "bastin_gevers"
    required_form = ("aocf", "the adaptive observer canonical form (paper 002, eq. 2.2), "
                              "whose output reachability Theorem 4.2 then checks")
    summary = "Bastin-Gevers adaptive observer on the AOCF, auxiliary filter, PE diagnostic"
    reference = "paper 002 (Bastin, Gevers 1986), eq. 2.2, 3.1, 4.5, 4.11"
    needs_normal_form = False

    @classmethod
    def applicability(cls, system: System) -> str | None:
        """The base's form check, then Theorem 4.2's structural output reachability of the
        system's AOCF (with its default options): where ``S(omega)`` has rank below ``m``,
        some parameter combination can never be excited. A form that needs options to be built
        is left to construction."""
        reason = super().applicability(system)
        if reason is not None:
            return reason
        try:
            form = system.form("aocf")
        except DesignError:
            return None
        r = form.reachability()
        if not r["reachable"]:
            return (f"its AOCF is not output reachable (paper 002, Theorem 4.2): rank S = "
                    f"{r['rank']} < m = {r['m']}; the parameter combinations {r['unreachable']} "
                    f"are never excited")
        return None

    def __init__(self, system: System | None = None, *, aocf: AOCF | None = None,
                 c1: float = 1.0, gamma: Any = 1.0, c2: float | None = None,
                 unknown: Sequence[str] | None = None, damping_known: str | None = None,
                 outputs: Any = (0,), theta_hat0: Any = None,
                 x_hat0: Any = None, z_hat0: Any = None, method: str = "rk4", substeps: int = 1,
                 excitation_window: float | None = 10.0, on_unreachable: str = "raise",
                 on_unstable: str = "raise") -> None:
        if system is not None and not isinstance(system, System):
            raise DesignError(f"system must be a System instance or None; found "
                              f"{type(system).__name__}")
        if aocf is None:
            if system is None:
                raise DesignError("BastinGeversObserver needs a system with a derived AOCF or "
                                  "aocf=AOCF(...)")
            kw = {k: v for k, v in (("c2", c2), ("unknown", unknown),
                                    ("damping_known", damping_known)) if v is not None}
            aocf = AOCF.from_system(system, **kw)
        elif not isinstance(aocf, AOCF):
            raise DesignError(f"aocf must be an AOCF; found {type(aocf).__name__}")
        elif c2 is not None or unknown is not None or damping_known is not None:
            raise DesignError("c2, unknown and damping_known choose a derived AOCF; with aocf= "
                              "given they must be left out")
        super().__init__(system, order=aocf.n, outputs=outputs, on_unstable=on_unstable)
        if len(self.outputs) != 1:
            raise DesignError(f"the Bastin-Gevers observer reads one output (y = x1); found "
                              f"outputs {list(self.outputs)}")
        self.form = aocf
        m = aocf.m
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
        # constants of the kernels, float64 C-contiguous
        self._alpha = np.ascontiguousarray(aocf.alpha)
        self._R = np.ascontiguousarray(aocf.R)
        Sb = aocf.S_blocks()  # (s, n, m): P[l, l'] = S_l^T S_l' (eq. 4.11)
        self._P = np.ascontiguousarray(np.einsum("lij,kip->lkjp", Sb, Sb))
        self.family_diagnostics = tuple(  # type: ignore[misc]
            f"theta_{nm}" for nm in aocf.theta_names) + tuple(
            f"theta_{nm}" for nm in aocf.physical_param_names) + (
            ("excitation",) if excitation_window is not None else ()) + ("reachability_rank",)
        #: the constructor's initial estimate (x_hat0, z_hat0, theta_hat0), as given
        self._start = (x_hat0, z_hat0, theta_hat0)
        # checked now (shapes, the form's maps and the inverse map's domain at the start), so
        # that a bad initial estimate is refused at construction; the state is made by init
        self._start_fields(None)

    @property
    def state_names(self) -> tuple[str, ...]:
        return self.form.state_names

    # ------------------------------------------------------------------ parameters
    def _parameters(self) -> dict[str, Any]:
        """The output-injection gain ``c1`` (Theorem 4.1 i) and the adaptation gain
        :math:`\\Gamma` ``gamma`` ``(m, m)`` (eq. 3.1c)."""
        return {"c1": self.c1, "gamma": self.gamma}

    def _check_parameter(self, name: str, value: Any) -> Array:
        if name == "c1":
            return np.array(finite_scalar("c1", value, positive=True))
        return symmetric_matrix("gamma", value, self.form.m, dim="m")

    # ------------------------------------------------------------------ the state
    def _theta_rows(self, theta_hat0: Any, B: int) -> Array:
        """``theta_hat0`` (``(m,)`` for every member or ``(B, m)``; None: the form's start, else
        zero) as ``(B, m)``."""
        m = self.form.m
        if theta_hat0 is None:
            start = self.form.start
            return np.zeros((B, m)) if start is None else np.tile(start[1], (B, 1))
        if np.ndim(theta_hat0) == 1:  # one estimate for every member
            return np.tile(batch_rows("theta_hat0", theta_hat0, m, None), (B, 1))
        return batch_rows("theta_hat0", theta_hat0, m, B)

    def _start_fields(self, B: int | None) -> dict[str, Any]:
        """The state fields of ``B`` members (None: the constructor's own rows, else one) from
        the constructor's initial estimate, input zero."""
        x, z, th = self._start
        if x is not None and z is not None:
            raise DesignError("give x_hat0 or z_hat0, not both")
        x0 = None if x is None else batch_rows("x_hat0", x, len(self.state_names), B)
        z0 = None if z is None else batch_rows("z_hat0", z, self.n, B)
        if B is None:
            rows = [v.shape[0] for v in (x0, z0) if v is not None]
            B = rows[0] if rows else (int(np.shape(th)[0]) if np.ndim(th) == 2 else 1)
        u0 = np.zeros((B, self.n_inputs or 0))
        return self._fields(x0, z0, u0, self._theta_rows(th, B))

    def _fields(self, x0: Array | None, z0: Array | None, u0: Array,
                th: Array) -> dict[str, Any]:
        """The state of ``B = len(u0)`` members from ``x0`` (physical) or ``z0`` (AOCF
        coordinates; neither: the form's ``start``, else zero) and the parameter estimate
        ``th`` ``(B, m)``; the filter starts at ``V(0) = 0``. (The initial state does not
        depend on the gains.)"""
        f = self.form
        B, n, m = u0.shape[0], f.n, f.m
        if x0 is not None:
            if not f.has_forward:
                raise DesignError(f"x_hat0 in physical coordinates needs the form's from_physical "
                                  f"map; {f.label} has none: give z_hat0 (AOCF coordinates)")
            z = np.array([vector("from_physical(x_hat0)", f.from_physical(x, t, u), n)
                          for x, t, u in zip(x0, th, u0)]).reshape(B, n)
        elif z0 is not None:
            z = z0
        else:  # the form's start (inside the inverse map's domain), else zero
            z = np.zeros((B, n)) if f.start is None else np.tile(f.start[0], (B, 1))
        p_held = np.full((B, len(f.physical_param_names)), np.nan)
        xp = z.copy()
        if f.has_inverse:
            xp = np.empty((B, len(f.state_names)))
            for b in range(B):
                try:
                    state, params = f.to_physical(z[b], th[b], u0[b])
                    if not np.all(np.isfinite(state)):
                        raise DesignError(f"the inverse map gave a non-finite state "
                                          f"{list(state)}")
                except (DesignError, ZeroDivisionError, FloatingPointError) as exc:
                    raise DesignError(f"the initial estimate (x = {z[b].tolist()}, theta = "
                                      f"{th[b].tolist()}) lies where the inverse map is "
                                      f"undefined: {exc}; give theta_hat0 / z_hat0 inside its "
                                      f"domain") from None
                xp[b] = state
                if params:
                    p_held[b] = [params[nm] for nm in f.physical_param_names]
        return {
            # (x_hat, theta_hat, vec V), the argument of the kernels
            "S": np.ascontiguousarray(np.concatenate((z, th, np.zeros((B, (n - 1) * m))),
                                                     axis=1)),
            "phi": np.zeros((B, m)),  # the regressor (3.1e) at the last sample
            "p_held": p_held,  # the physical parameters (held where the inverse is undefined)
            "x_held": xp,  # the physical estimate (the same)
            # condition 4.5: the regressors of the last window, per member with the period it
            # was filled at (NaN: none yet); the ring's length is set at the first period
            # (:meth:`_step_checked`); a restarted member's row broadcasts into it
            "ring": np.zeros((B, 0 if self.excitation_window is None else 1, m)),
            "ring_dt": np.full(B, np.nan),
            "ring_pos": np.zeros(B, dtype=np.int64),
            "ring_full": np.zeros(B, dtype=np.bool_),
            "gram": np.zeros((B, m, m)),
            "excitation": np.zeros(B),
            # Theorem 4.2 along the run: sum of omega omega^T, and the rank
            "Wsum": np.zeros((B, f.s, f.s)),
            "rank": np.zeros(B),
        }

    def _init(self, p: Params, x0: Array | None, z0: Array | None,
              u0: Array) -> dict[str, Any]:
        """From ``x0`` or ``z0`` with a zero parameter estimate; neither: the constructor's
        initial estimate (with its ``theta_hat0``)."""
        if x0 is None and z0 is None:
            return self._start_fields(u0.shape[0])
        return self._fields(x0, z0, u0, self._theta_rows(None, u0.shape[0]))

    def init(self, batch: int = 1, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None,
             params: Params | None = None, theta_hat0: Any = None) -> State:
        """A new state of ``batch`` members (:meth:`Observer.init`), with the parameter
        estimate ``theta_hat0`` (``(m,)`` for every member or ``(B, m)``) where given: then
        from ``x_hat0`` or ``z_hat0`` (default: the form's ``start``, else zero). All three
        left out: the constructor's initial estimate. The filter starts at ``V(0) = 0``.

        Parameters
        ----------
        batch : int
            The number of members B.
        x_hat0, z_hat0 : array_like, optional
            Initial estimate in physical coordinates (needs the form's ``from_physical``) or
            in AOCF coordinates, ``(d,)`` or ``(B, d)``.
        u0 : array_like, optional
            Input at the start, ``(m_u,)`` or ``(B, m_u)``; default zero.
        params : Params, optional
            The members' parameters (the initial state does not depend on them).
        theta_hat0 : array_like, optional
            Initial parameter estimate, ``(m,)`` or ``(B, m)``; default the form's ``start``
            (zero without one), or the constructor's, with neither initial estimate given.

        Returns
        -------
        State

        Raises
        ------
        DesignError
            Both ``x_hat0`` and ``z_hat0``, a non-finite value, an initial estimate where the
            inverse map is undefined, or ``params`` of another batch.
        DimensionError
            An initial value of the wrong shape.

        Examples
        --------
        >>> from hgo_mj.systems.papers import BioreactorBastinGevers
        >>> ob = BastinGeversObserver(BioreactorBastinGevers(), c2=1.0,
        ...                           theta_hat0=[-3.0, -0.1, -0.1], z_hat0=[1.0, 1.0])
        >>> s = ob.init(2, z_hat0=[1.0, 1.0], theta_hat0=[[-3.0, -0.1, -0.1], [-2.0, -0.2, -0.1]])
        >>> s.S[:, 2].tolist(), s.ring.shape
        ([-3.0, -2.0], (2, 1, 3))
        """
        if theta_hat0 is None:
            return super().init(batch, x_hat0, z_hat0=z_hat0, u0=u0, params=params)
        B = _batch_size(batch)
        if x_hat0 is not None and z_hat0 is not None:
            raise DesignError("give x_hat0 or z_hat0, not both")
        x0 = None if x_hat0 is None else batch_rows("x_hat0", x_hat0, len(self.state_names), B)
        z0 = None if z_hat0 is None else batch_rows("z_hat0", z_hat0, self.n, B)
        m = self.n_inputs
        u = np.zeros((B, m or 0)) if u0 is None or m is None else batch_rows("u0", u0, m, B)
        if params is not None and (not isinstance(params, Params)
                                   or _batch_of(params) not in (None, B)):
            raise DesignError(f"{self.name}: params must be this observer's Params of {B} "
                              f"member(s) (Observer.parameters); found {params!r}")
        return State(**{**self._core(B), **self._fields(x0, z0, u, self._theta_rows(theta_hat0, B))})

    def reset(self, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None,
              batch: int | None = None, params: Params | None = None,
              theta_hat0: Any = None) -> None:
        """Restart the observer's own state (:meth:`Observer.reset`) from ``x_hat0``
        (physical, needs the form's ``from_physical``) or ``z_hat0`` (AOCF coordinates) and
        ``theta_hat0`` (each ``(d,)`` for every member or ``(B, d)``); all three left out: the
        constructor's. The filter restarts at ``V(0) = 0``."""
        if x_hat0 is None and z_hat0 is None and theta_hat0 is None:
            x_hat0, z_hat0, theta_hat0 = self._start
        if theta_hat0 is None:
            super().reset(x_hat0, z_hat0=z_hat0, u0=u0, batch=batch, params=params)
            return
        given = x_hat0 if x_hat0 is not None else z_hat0
        if batch is not None:
            B = _batch_size(batch)
        elif params is not None and _batch_of(params) is not None:
            B = _batch_of(params)  # type: ignore[assignment]
        elif given is not None and np.ndim(given) == 2:
            B = int(np.shape(given)[0])
        elif np.ndim(theta_hat0) == 2:
            B = int(np.shape(theta_hat0)[0])
        else:
            B = 1
        batched = (batch is not None or params is not None or np.ndim(theta_hat0) == 2
                   or (given is not None and np.ndim(given) == 2))
        p = self.parameters(B) if params is None else params
        s = self.init(B, x_hat0, z_hat0=z_hat0, u0=u0, params=p, theta_hat0=theta_hat0)
        self._hold(p, s, batched)

    # ------------------------------------------------------------------ dynamics
    def _signals(self, Y: Array, U: Array) -> tuple[Array, Array]:
        """:math:`\\omega` ``(N, s)`` and ``g`` ``(N, n)`` of the rows ``Y`` ``(N,)``,
        ``U`` ``(N, mu)``, shape-checked."""
        f = self.form
        try:
            W = f.omega_rows(Y, U)
            G = f.g_rows(Y, U)
        except (IndexError, TypeError, ValueError) as exc:
            raise DimensionError(f"omega(y, u) or g(y, u) of {f.label} failed on y = "
                                 f"{float(Y[0])!r}, u of shape {U.shape[1:]}: {exc}") from None
        if W.shape != (len(Y), f.s):
            raise DimensionError(f"omega(y, u) of {f.label} must return {f.s} values; found "
                                 f"shape {W.shape[1:]}")
        if G.shape != (len(Y), f.n):
            raise DimensionError(f"g(y, u) of {f.label} must return n = {f.n} values; found "
                                 f"shape {G.shape[1:]}")
        return W, G

    def _size_ring(self, s: State, dt: float) -> None:
        """Give the ring of condition 4.5 the ``round(T / dt)`` samples of the window at the
        period ``dt`` (a ring of another length: every member's window starts over). Done on
        the whole state before it is handed to :meth:`_step` group by group."""
        if self.excitation_window is None:
            return
        L = max(1, int(round(self.excitation_window / dt)))
        if s.ring.shape[1] != L:
            s.ring = np.zeros((s.ring.shape[0], L, self.form.m))
            s.ring_dt[:] = np.nan

    def _prepare(self, s: State, dt: float) -> None:
        """The excitation ring given its length at ``dt`` for the whole state."""
        self._size_ring(s, dt)

    def _step(self, p: Params, s: State, Y: Array, U: Array, dt: float, X: Array, Z: Array,
              D: Array) -> None:
        f = self.form
        n, m = f.n, f.m
        B, T = Y.shape[0], Y.shape[1]
        y = Y[:, :, 0]
        lost = np.isnan(y)
        n_lost = np.count_nonzero(lost)
        if n_lost:
            ok = ~lost
            W = np.empty((B, T, f.s))
            G = np.empty((B, T, n))
            if n_lost < B * T:
                W[ok], G[ok] = self._signals(y[ok], U[ok])
        else:
            Wf, Gf = self._signals(y.reshape(-1), U.reshape(B * T, -1))
            W = np.ascontiguousarray(Wf).reshape(B, T, f.s)
            G = np.ascontiguousarray(Gf).reshape(B, T, n)
        Sout = np.empty((B, T, s.S.shape[1]))
        PHI = np.empty((B, T, m))
        y = np.ascontiguousarray(y)
        args = (y, W, G, self._alpha, self._R, np.array(p.gamma), float(p.c1),
                dt / self.substeps, self.substeps, self.method == "euler", Sout, PHI)
        # runs of samples without a dropout go to the kernel whole; at a sample with one,
        # omega and g of the members that lost it are taken at their prediction x_hat_1
        j = 0
        for jl in [*np.flatnonzero(lost.any(axis=0)).tolist(), T] if n_lost else [T]:
            if jl > j:
                self._integrate(s.S, j, jl, args)
            if jl == T:
                break
            bs = np.flatnonzero(lost[:, jl])
            W[bs, jl], G[bs, jl] = self._signals(s.S[bs, 0], U[bs, jl])
            self._integrate(s.S, jl, jl + 1, args)
            j = jl + 1
        Z[...] = Sout[:, :, :n]
        D[:, :, :m] = Sout[:, :, n:n + m]
        col = m + len(f.physical_param_names)
        self._physical(s, Sout, U, X, D[:, :, m:col])
        if self.excitation_window is not None:
            # a member's first period, or a new one: its window of round(T / dt) samples
            self._size_ring(s, dt)
            new = s.ring_dt != dt
            if new.any():
                s.ring[new] = 0.0
                s.ring_pos[new] = 0
                s.ring_full[new] = False
                s.gram[new] = 0.0
                s.ring_dt[new] = dt
        out = np.empty((B, T, 2))
        diagnostics_4_5_4_11(PHI, W, dt, s.ring, s.ring_pos, s.ring_full, s.gram, self._P,
                             s.Wsum, out)
        if self.excitation_window is not None:
            D[:, :, col] = out[:, :, 0]
            col += 1
            if T:
                s.excitation[:] = out[:, -1, 0]
        D[:, :, col] = out[:, :, 1]
        if T:
            s.rank[:] = out[:, -1, 1]
            s.phi[...] = PHI[:, -1]

    def _integrate(self, S: Array, j0: int, j1: int, args: tuple[Any, ...]) -> None:
        """:func:`advance_3_1` of the members' states ``S`` over the samples
        ``j0 <= j < j1``; a divergence is raised."""
        code = advance_3_1(S, j0, j1, *args)
        if code >= 0:
            Sout = args[-2]
            b, j = divmod(code, Sout.shape[1])
            raise DivergenceError(f"the Bastin-Gevers observer left the finite numbers: state "
                                  f"(x_hat, theta_hat, V) = {Sout[b, j].tolist()} (member {b}, "
                                  f"sample {j})")

    def _physical(self, s: State, Sout: Array, U: Array, X: Array, Dp: Array) -> None:
        """The physical estimate (the inverse map 2.4-2.5) after each sample into ``X`` and
        ``Dp``; where the inverse is undefined the member's last value is held and counted in
        the state's ``inverse_failures`` (:func:`hold_valid`)."""
        f = self.form
        n, m = f.n, f.m
        B, T = Sout.shape[0], Sout.shape[1]
        if not f.has_inverse:
            X[...] = Sout[:, :, :n]
            if T:
                s.x_held[...] = X[:, -1]
            return
        states, params = f.to_physical_rows(Sout[:, :, :n].reshape(B * T, n),
                                            Sout[:, :, n:n + m].reshape(B * T, m),
                                            U.reshape(B * T, -1))
        P = np.empty((B, T, Dp.shape[2]))
        hold_valid(np.ascontiguousarray(states).reshape(B, T, -1),
                   np.ascontiguousarray(params).reshape(B, T, -1), s.x_held, s.p_held,
                   s.inverse_failures, X, P)
        Dp[...] = P

    def _current(self, p: Params, s: State) -> tuple[Array, Array, Array]:
        f = self.form
        n, m = f.n, f.m
        cols = [s.S[:, n:n + m], s.p_held]
        if self.excitation_window is not None:
            cols.append(s.excitation[:, None])
        cols.append(s.rank[:, None])
        return s.x_held.copy(), s.S[:, :n].copy(), np.concatenate(cols, axis=1)

    # ------------------------------------------------------------------ one point
    def rhs(self, s: Array, y: float, omega: Array, g: Array, correct: bool = True) -> Array:
        """Right-hand side of eq. 3.1 (:func:`rhs_3_1`) for the flat state
        ``s = (x_hat, theta_hat, vec V)`` with ``omega`` and ``g`` given (public for
        continuous-time checks). ``correct=False`` drops the output injection (a dropout).

        Parameters
        ----------
        s : (n + m + (n - 1) m,) ndarray
            The flat state ``(x_hat, theta_hat, vec V)`` of one member.
        y : float
            The measurement.
        omega : (s,) ndarray
            :math:`\\omega(y, u)` (:meth:`omega_g`).
        g : (n,) ndarray
            :math:`g(y, u)` (:meth:`omega_g`).
        correct : bool, default True
            With the output injection.

        Returns
        -------
        ndarray
            ``ds/dt``, the shape of ``s``.

        Raises
        ------
        DimensionError
            ``s``, ``omega`` or ``g`` of the wrong shape.

        Examples
        --------
        >>> from hgo_mj.systems.papers import BioreactorBastinGevers
        >>> guess = BioreactorBastinGevers(mu_max=2.0, p2=1.0, p3=0.1)
        >>> x0, th0 = guess.to_aocf([1.0, 2.0], 1.0)
        >>> ob = BastinGeversObserver(BioreactorBastinGevers(), c1=5.0, gamma=2.0, c2=1.0,
        ...                           theta_hat0=th0, z_hat0=x0)
        >>> w, g = ob.omega_g(1.0, [0.1, 0.5])
        >>> s = np.concatenate([x0, th0, np.zeros(3)])
        >>> ob.rhs(s, 1.0, w, g).shape
        (8,)
        """
        f = self.form
        sa, w, ga = (np.ascontiguousarray(v, dtype=float) for v in (s, omega, g))
        for name, v, k in (("s", sa, f.n + f.m + (f.n - 1) * f.m), ("omega", w, f.s), ("g", ga, f.n)):
            if v.shape != (k,):
                raise DimensionError(f"{name} must have shape ({k},); found shape {v.shape}")
        return rhs_one(sa, float(y), 1.0 if correct else 0.0, w, ga, self._alpha, self._R,
                       self.gamma, self.c1)

    def omega_g(self, y: float, u: Any) -> tuple[Array, Array]:
        """:math:`\\omega(y, u)` and :math:`g(y, u)` at one point, shape-checked.

        Parameters
        ----------
        y : float
            The measurement.
        u : array_like
            The input, ``(m_u,)``.

        Returns
        -------
        omega : (s,) ndarray
            The regressor signals of the AOCF.
        g : (n,) ndarray
            The known input term.

        Examples
        --------
        >>> from hgo_mj.systems.papers import BioreactorBastinGevers
        >>> guess = BioreactorBastinGevers(mu_max=2.0, p2=1.0, p3=0.1)
        >>> x0, th0 = guess.to_aocf([1.0, 2.0], 1.0)
        >>> ob = BastinGeversObserver(BioreactorBastinGevers(), c1=5.0, gamma=2.0, c2=1.0,
        ...                           theta_hat0=th0, z_hat0=x0)
        >>> w, g = ob.omega_g(1.0, [0.1, 0.5])
        >>> w, g
        (array([1. , 0.1, 0.5]), array([0.1, 0. ]))
        """
        W, G = self._signals(np.array([float(y)]), np.asarray(u, dtype=float).reshape(1, -1))
        return W[0], G[0]

    # ------------------------------------------------------------------ interface
    def _check_period(self, p: Params, dt: float) -> None:
        """Check the integration of the linear modes :math:`-c_1` and :math:`\\lambda(F)` (the
        poles of :math:`R^*`, eq. 4.3) at the period ``dt``; react as ``on_unstable`` says."""
        lam = np.concatenate(([-float(p.c1)], np.linalg.eigvals(self.form.F) if self.form.n > 1
                              else []))
        try:
            check_rk_period("the Bastin-Gevers observer", lam, dt, self.method, self.substeps)
        except DesignError as exc:
            if self.on_unstable == "raise":
                raise
            if self.on_unstable == "warn":
                warnings.warn(str(exc), RuntimeWarning, stacklevel=3)

    @property
    def theta_hat_(self) -> Array:
        f = self.form
        return self._public(self.state.S[:, f.n:f.n + f.m].copy())  # type: ignore[no-any-return]

    @property
    def V_(self) -> Array:
        f = self.form
        S = self.state.S
        return self._public(  # type: ignore[no-any-return]
            S[:, f.n + f.m:].reshape(S.shape[0], f.n - 1, f.m).copy())

    @property
    def phi_(self) -> Array:
        return self._public(self.state.phi.copy())  # type: ignore[no-any-return]

    @property
    def state_vector_(self) -> Array:
        """The flat observer state ``(x_hat, theta_hat, vec V)`` (the argument of :meth:`rhs`)."""
        return self._public(self.state.S.copy())  # type: ignore[no-any-return]

    @property
    def physical_params_(self) -> dict[str, Any]:
        p_held = self.state.p_held
        return {nm: self._public(p_held[:, i].copy())
                for i, nm in enumerate(self.form.physical_param_names)}

    @property
    def excitation_(self) -> Any:
        if self.excitation_window is None:
            return math.nan
        return self._public(self.state.excitation.copy())

    @property
    def excitation_matrix_(self) -> Array:
        """The windowed :math:`\\int \\varphi \\varphi^T d\\tau` of condition 4.5."""
        if self.excitation_window is None:
            raise DesignError("the excitation diagnostic is off (excitation_window=None)")
        s = self.state
        dt = np.where(np.isfinite(s.ring_dt), s.ring_dt, 0.0)
        return self._public(s.gram * dt[:, None, None])  # type: ignore[no-any-return]

    @property
    def reachability_rank_(self) -> Any:
        r = self._public(self.state.rank.astype(np.int64))
        return int(r) if np.ndim(r) == 0 else r

    def params(self) -> dict[str, Any]:
        f = self.form
        return {"aocf": f.label, "n": f.n, "m": f.m, "theta_names": list(f.theta_names),
                "c1": self.c1, "gamma": self.gamma.tolist(), "outputs": list(self.outputs),
                "method": self.method, "substeps": self.substeps,
                "excitation_window": self.excitation_window,
                "structural_rank": self.structure["rank"]}
