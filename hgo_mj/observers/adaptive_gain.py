"""The adaptive-gain high-gain observer of Bullinger, Ilchmann and Allgöwer (paper 000 [000]_).

The high-gain observer of eq. 2 whose gain ``k`` grows by the dead-zone law of eq. 4-5:

.. math::

    \\dot{\\hat z}_i &= \\hat z_{i+1} + p_i k^i (y - \\hat z_1), \\quad i = 1, \\dots, n-1 \\\\
    \\dot{\\hat z}_n &= p_n k^n (y - \\hat z_1) + [\\hat\\varphi(\\mathrm{sat}(\\hat z), u)] \\\\
    \\dot k &= \\gamma \\, d_{\\lambda, \\hat\\lambda}^2(y - \\hat z_1), \\qquad k(0) = k_0 \\\\
    d_{\\lambda, \\hat\\lambda}(e) &= \\begin{cases} \\hat\\lambda - \\lambda & |e| \\ge \\hat\\lambda \\\\
        |e| - \\lambda & \\lambda \\le |e| \\le \\hat\\lambda \\\\
        0 & |e| \\le \\lambda \\end{cases}

with ``lam_hat > lam > 0``, ``gamma > 0``, ``k0 > 0``. Theorem 2: noise-free and with
``|phi|`` bounded, ``k(t)`` converges and ``y - y_hat`` tends to the strip ``[-lam, lam]``;
Theorem 3 bounds the final errors (:func:`hgo_mj.design.bullinger_theorem3_bound`).

References
----------
.. [000] E. Bullinger, A. Ilchmann, F. Allgöwer, "A simple adaptive observer for nonlinear
   systems", NOLCOS 1998, eq. 2 (observer), eq. 4-5 (adaptation), eq. 6-7 (error dynamics,
   Lyapunov equation), Theorems 2 and 3.
"""

from __future__ import annotations

import math
import warnings
from functools import lru_cache
from math import comb
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from .._validate import boolean, finite_scalar
from ..design import binomial_coefficients, check_hurwitz
from ..exceptions import DesignError, DimensionError, DivergenceError
from ..systems.base import System
from ._integrate import euler_step, rk4_step
from .base import Array, Observer, Params, State, batch_rows, register
from .high_gain import (
    MAP_CACHE,
    bounds_pair,
    check_options,
    largest_stable_step,
    one_step_map,
    sampled_chain,
)
from .riccati import bounds_rows, is_identity_map, model_rk4, report, saturated

#: method codes of the kernels
EXACT, EULER, RK4 = 0, 1, 2
_CODES = {"exact": EXACT, "euler": EULER, "rk4": RK4}


def dead_zone(e: ArrayLike, lam: float, lam_hat: float) -> Array:
    """The dead zone :math:`d_{\\lambda, \\hat\\lambda}(e)` of paper 000, eq. 5 (vectorized).

    ``0`` inside ``|e| <= lam``, ``|e| - lam`` up to ``lam_hat``, then constant ``lam_hat - lam``:
    the adaptation rate ``gamma d^2`` is bounded by ``gamma (lam_hat - lam)^2``.

    Parameters
    ----------
    e : array_like
        Output error(s) ``e_1 = y - z_hat_1``, any shape.
    lam : float
        Dead-zone half width ``lambda > 0``.
    lam_hat : float
        Saturation level ``lambda_hat > lambda``.

    Returns
    -------
    ndarray
        ``d(e)``, the shape of ``e``, in ``[0, lam_hat - lam]``.

    Examples
    --------
    >>> dead_zone([0.0, 0.15, 0.5, -2.0], lam=0.1, lam_hat=0.3)
    array([0.  , 0.05, 0.2 , 0.2 ])
    """
    return np.clip(np.abs(np.asarray(e, dtype=float)) - lam, 0.0, lam_hat - lam)


@lru_cache(maxsize=64)
def _max_stable_kdt(p: tuple[float, ...], method: str) -> float:
    """Largest ``tau = k dt`` for which ``method``'s one-step map of the linear part is stable.

    ``A_k dt = K (k dt Abar) K^-1`` (eq. 6), so the one-step map of euler/rk4, a polynomial in
    ``A_k dt``, is similar to the same polynomial in ``tau Abar``: stability depends on
    ``tau`` only. ``exact`` is stable for every ``tau``.
    """
    if method == "exact":
        return math.inf
    pa = np.array(p)
    start = 1e-3 / max(1.0, float(np.max(np.abs(np.roots(np.concatenate(([1.0], pa)))))))
    return largest_stable_step(lambda tau: one_step_map(pa, 1.0, tau, method)[0], start, 1e6)


# ------------------------------------------------------------------------- the equations
@njit(cache=True, inline="always")
def adaptation_rate(e, lam, lam_hat, gamma):  # pragma: no cover - compiled
    """:math:`\\dot k = \\gamma\\, d_{\\lambda, \\hat\\lambda}^2(e)` (paper 000, eq. 4-5)."""
    a = e if e >= 0.0 else -e
    if a > lam:
        d = a - lam if a < lam_hat else lam_hat - lam
        return gamma * d * d
    return 0.0


@njit(cache=True, inline="always")
def joint_rhs(s, y, phi, vecs, lam, lam_hat, gamma, ds):  # pragma: no cover - compiled
    """The joint ODE of ``s = (k, z_1..z_n)`` with ``y`` held (paper 000, eq. 2 and 4-5):

    .. math::

        \\dot k = \\gamma d^2(y - \\hat z_1), \\quad
        \\dot{\\hat z}_i = \\hat z_{i+1} + p_i k^i (y - \\hat z_1), \\quad
        \\dot{\\hat z}_n = p_n k^n (y - \\hat z_1) + \\varphi

    (``phi`` the model term, 0 without one; ``p = vecs[0]``)."""
    n = s.size - 1
    k = s[0]
    e = y - s[1]
    ds[0] = adaptation_rate(e, lam, lam_hat, gamma)
    t = k * e  # k^i e, built up
    for i in range(n):
        if i:
            t = t * k
        if i < n - 1:
            ds[1 + i] = s[2 + i] + vecs[0, i] * t
        else:
            ds[1 + i] = vecs[0, i] * t + phi


@njit(cache=True, inline="always")
def matched_coefficients(tau, mode, r, nr, npair, vecs, c, work):  # pragma: no cover
    """Coefficients ``c`` (leading 1 first) of :math:`\\prod_i (w - w_i)`,
    :math:`w_i = e^{\\tau r_i} - 1`, ``r_i`` the roots of ``s^n + p_1 s^(n-1) + ... + p_n``:
    the pole-matched gain at ``tau = k dt`` is ``W c[1:]`` (see :func:`exact_matrices`).

    ``mode`` 0: one root ``r`` of multiplicity ``n`` (binomial ``p``), ``c_j = C(n, j) m^j``,
    ``m = -expm1(tau r)`` (``C(n, j)`` in ``vecs[2]``). ``mode`` 1: the ``nr`` real roots
    ``vecs[3]`` (``w = expm1(tau r)``) and the ``npair`` pairs ``a +- i b`` (``vecs[4]``,
    ``vecs[5]``: ``Re w = expm1(tau a) cos(tau b) - 2 sin^2(tau b / 2)``, no cancellation;
    ``Im w = e^(tau a) sin(tau b)``), multiplied out factor by factor."""
    n = c.size - 1
    c[0] = 1.0
    if mode == 0:
        m = -math.expm1(tau * r)
        mp = m
        for j in range(1, n + 1):
            if j > 1:
                mp = mp * m
            c[j] = vecs[2, j] * mp
    deg = 0
    for q in range(nr + npair if mode == 1 else 0):
        f2 = 0.0
        if q < nr:
            f1 = -math.expm1(tau * vecs[3, q])
            nf = 2
        else:
            a, b = vecs[4, q - nr], vecs[5, q - nr]
            ea = math.expm1(tau * a)
            sh = math.sin(tau * (b / 2))
            re = ea * math.cos(tau * b) - 2.0 * sh * sh
            im = (ea + 1.0) * math.sin(tau * b)
            f1, f2 = -2.0 * re, re * re + im * im
            nf = 3
        for j in range(deg + nf):
            acc = 0.0
            for a_ in range(nf):
                if 0 <= j - a_ <= deg:
                    fa = 1.0 if a_ == 0 else (f1 if a_ == 1 else f2)
                    acc += fa * c[j - a_]
            work[j] = acc
        deg += nf - 1
        for j in range(deg + 1):
            c[j] = work[j]


@njit(cache=True, inline="always")
def gain_limits(t, j, par, lim):  # pragma: no cover - compiled
    """``k = t[0]`` after a sample against its bounds ``par[5:8] = (k_limit, k_max, k_stab)``
    (``k_limit`` the smaller of the other two): clipped to ``k_max`` (``lim[0] = 1``), and the
    first sample at which it passes ``k_stab`` (the largest gain at which euler/rk4 are stable
    at this period) recorded as ``lim[1] = j``, ``lim[2] = k``. Returns 1 where ``k`` reached
    ``k_max``, 2 where it crossed ``k_stab`` now (3: both), else 0."""
    if not t[0] > par[5]:
        return 0
    out = 0
    if t[0] >= par[6]:
        lim[0] = 1.0
        t[0] = par[6]
        out = 1
    if t[0] >= par[7] and lim[1] < 0:
        lim[1] = j
        lim[2] = t[0]
        out += 2
    return out


@njit(cache=True, inline="always")
def _plus(acc, g, phi, model):  # pragma: no cover - compiled
    """``acc + g phi`` with the model term (``g`` its input gain), ``acc`` without."""
    return acc + g * phi if model else acc


@njit(cache=True, inline="always")
def _mac(acc, w, c):  # pragma: no cover - compiled
    """``acc + w c``, skipping the structural zeros ``w = 0`` of ``W``."""
    return acc + w * c if w != 0.0 else acc


@njit(cache=True, inline="always")
def _reported(v, lo, hi, sat):  # pragma: no cover - compiled
    """``v`` clipped to ``[lo, hi]`` where the estimate is saturated (``sat``)."""
    if sat:
        if v < lo:
            return lo
        if v > hi:
            return hi
    return v


@njit(cache=True, inline="always")
def _stops(code, stop):  # pragma: no cover - compiled
    """Whether a member stops here: ``k`` crossed ``k_stab`` (:func:`gain_limits`) with ``stop``."""
    return code >= 2 and stop


@njit(cache=True, inline="always")
def joint_rhs_args(s, a, ds):  # pragma: no cover - compiled
    """:func:`joint_rhs` with its other arguments as one tuple ``a = (y, phi, vecs, lam,
    lam_hat, gamma)``: the right-hand side form of :mod:`hgo_mj.observers._integrate`."""
    joint_rhs(s, a[0], a[1], a[2], a[3], a[4], a[5], ds)


@njit(cache=True)
def adaptive_run(S, Y, PHI, j0, model, method, mode, nr, npair, stop, sat, par, mats, vecs,
                 bounds, Z, D, lim):  # pragma: no cover - compiled
    """Samples ``j0 .. j0 + T'`` (``T' = PHI.shape[1]``, ``PHI`` the model term held over each
    sample, read when ``model``) for each member, ``s = (k, z)`` (``S`` ``(B, n + 1)``, ``k``
    first, updated in place):

    * ``y`` NaN (a dropout): ``z+ = M0 z + g0 phi`` (the prediction without correction), ``k``
      held (nothing to adapt to);
    * ``exact`` (``method`` 0): ``z+ = Phi z + Ld(k) e + g0 phi`` with the pole-matched gain at
      the start-of-sample ``k`` (``Ld = W c(k dt)``, :func:`matched_coefficients`; reused
      while ``k`` does not change) and ``k+ = k + dt gamma d^2(e)``, ``e = y - z_1``;
    * ``euler`` (1): ``s+ = s + dt f(s)`` (:func:`joint_rhs`, by
      :func:`~hgo_mj.observers._integrate.euler_step`), plus ``dt phi`` in the last row;
    * ``rk4`` (2): classical RK4 of :func:`joint_rhs`
      (:func:`~hgo_mj.observers._integrate.rk4_step`; without the model term: with it, the
      stages are driven from Python, :meth:`AdaptiveGainObserver._step`);

    then :func:`gain_limits` (``lim`` ``(B, 3)``); ``sat(z)`` into ``Z[:, j]``, ``k`` into
    ``D[:, j, 0]``. With ``stop`` a member stops before the sample at which ``k`` crosses
    ``k_stab`` (the caller raises). Returns the or of :func:`gain_limits`' codes.

    The constants come packed (few arguments make the call cheap):
    ``par = (dt, lam, lam_hat, gamma, r, k_limit, k_max, k_stab)``, ``mats = (Phi, W, M0)``,
    ``vecs = (p, g0, C(n, j), real roots, Re and Im of the pairs)`` (rows padded to ``n + 1``).
    The loop is written flat: views and calls with many arrays inside it cost more than the
    arithmetic (the helpers it calls take and return scalars only, inlined by numba).
    """
    B = S.shape[0]
    n = mats.shape[1]
    Tc = PHI.shape[1]
    lo, hi = bounds[0], bounds[1]
    dt, lam, lam_hat, gamma = par[0], par[1], par[2], par[3]
    s = np.empty(n + 1)
    t = np.empty(n + 1)
    d1, d2, d3, d4 = np.empty(n + 1), np.empty(n + 1), np.empty(n + 1), np.empty(n + 1)
    c, work, gain = np.empty(n + 1), np.empty(n + 1), np.empty(n)
    status = 0
    for i in range(B):
        for q in range(n + 1):
            s[q] = S[i, q]
        k_gain = np.nan  # the k at which ``gain`` was computed
        for jj in range(Tc):
            j = j0 + jj
            y = Y[i, j, 0]
            phi = PHI[i, jj] if model else 0.0
            if y != y:
                t[0] = s[0]
                for r in range(n):
                    acc = 0.0
                    for q in range(n):
                        acc += mats[2, r, q] * s[1 + q]
                    t[1 + r] = _plus(acc, vecs[1, r], phi, model)
            elif method == 0:
                k = s[0]
                e = y - s[1]
                if k != k_gain:
                    matched_coefficients(k * dt, mode, par[4], nr, npair, vecs, c, work)
                    for r in range(n):
                        gi = 0.0
                        for q in range(n):
                            gi = _mac(gi, mats[1, r, q], c[q + 1])
                        gain[r] = gi
                    k_gain = k
                for r in range(n):
                    acc = 0.0
                    for q in range(r, n):
                        acc += mats[0, r, q] * s[1 + q]
                    v = acc + gain[r] * e
                    t[1 + r] = _plus(v, vecs[1, r], phi, model)
                t[0] = k + dt * adaptation_rate(e, lam, lam_hat, gamma)
            elif method == 1:
                euler_step(joint_rhs_args, s, dt, (y, 0.0, vecs, lam, lam_hat, gamma), d1, t)
                if model:
                    t[n] = t[n] + dt * phi
            else:
                rk4_step(joint_rhs_args, s, dt, (y, 0.0, vecs, lam, lam_hat, gamma), d1, d2, d3, d4,
                         t, t)
            if y == y:
                code = gain_limits(t, j, par, lim[i])
                status |= code
                if _stops(code, stop):
                    break
            s[0] = t[0]
            D[i, j, 0] = s[0]
            for q in range(n):
                s[1 + q] = t[1 + q]
                Z[i, j, q] = _reported(s[1 + q], lo[q], hi[q], sat)
        for q in range(n + 1):
            S[i, q] = s[q]
    return status


@njit(cache=True)
def adaptive_limits(S, Sprev, Y, j, par, stop, lim):  # pragma: no cover - compiled
    """:func:`gain_limits` over the members after an RK4 sample driven from Python (the model
    term at every stage); a member that crosses with ``stop`` gets its state back."""
    B, N = S.shape
    status = 0
    for i in range(B):
        y = Y[i, j, 0]
        if y == y:
            code = gain_limits(S[i], j, par, lim[i])
            status |= code
            if code >= 2 and stop:
                for q in range(N):
                    S[i, q] = Sprev[i, q]
    return status


@njit(cache=True)
def adaptive_rhs(V, Y, j, PHI, vecs, lam, lam_hat, gamma, Dv):  # pragma: no cover - compiled
    """:func:`joint_rhs` of every member (an RK4 stage with the model term ``PHI``); over a
    dropout, the prediction without correction (``k`` held)."""
    B, N = V.shape
    for i in range(B):
        y = Y[i, j, 0]
        if y == y:
            joint_rhs(V[i], y, PHI[i], vecs, lam, lam_hat, gamma, Dv[i])
        else:
            Dv[i, 0] = 0.0
            for q in range(1, N - 1):
                Dv[i, q] = V[i, q + 1]
            Dv[i, N - 1] = PHI[i]


# --------------------------------------------------------------------- per-period design
def _check_dead_zone(lam: float, lam_hat: float) -> None:
    """``lam_hat > lam`` (paper 000, eq. 5), as the constructor and :meth:`parameters` check it."""
    if not lam_hat > lam:
        raise DesignError(f"lam_hat must be > lam (paper 000, eq. 5: lambda_hat > lambda > 0); "
                          f"found lam_hat={lam_hat:g} <= lam={lam:g}")


def _root_groups(p: Array) -> tuple[list[float], list[tuple[float, float]]]:
    """Roots of ``s^n + p_1 s^(n-1) + ... + p_n``: the real ones and the ``(re, im > 0)`` pairs."""
    roots = np.roots(np.concatenate(([1.0], p)))
    real, pairs = [], []
    scale = max(1.0, float(np.max(np.abs(roots))))
    for r in roots:
        if abs(r.imag) <= 1e-9 * scale:
            real.append(float(r.real))
        elif r.imag > 0:
            pairs.append((float(r.real), float(r.imag)))
    if len(real) + 2 * len(pairs) != p.size:  # pragma: no cover - conjugate pairs always match
        raise DesignError(f"cannot pair the roots {roots.tolist()} into conjugates")
    return real, pairs


def root_data(p: Array) -> tuple[int, float, int, int, Array]:
    """``(mode, r, n_real, n_pairs, rows)`` of :func:`matched_coefficients` for ``p``:
    ``rows`` = ``(C(n, j))_j``, the real roots, ``Re`` and ``Im > 0`` of the complex pairs
    (padded to ``n + 1``)."""
    n = p.size
    r = -p[0] / n
    rows = np.zeros((4, n + 1))
    rows[0] = [float(comb(n, j)) for j in range(n + 1)]
    if np.allclose(p, [comb(n, i) * (-r) ** i for i in range(1, n + 1)], rtol=1e-13, atol=0.0):
        # one root of multiplicity n (the default binomial p): one expm1, no split roots
        return 0, float(r), 0, 0, rows
    real, pairs = _root_groups(p)
    rows[1, :len(real)] = real
    rows[2, :len(pairs)] = [a for a, _ in pairs]
    rows[3, :len(pairs)] = [b for _, b in pairs]
    return 1, 0.0, len(real), len(pairs), rows


def exact_matrices(n: int, dt: float) -> tuple[Array, Array]:
    """``(Phi, W)`` at the period ``dt``: ``Phi = e^{A dt}`` and the fixed matrix ``W`` with
    which the pole-matched gain of :func:`~hgo_mj.observers.high_gain.matched_gain` is linear
    in the coefficients ``c_j`` of ``prod_i (w - w_i)`` (Ackermann: the ``N^n`` term vanishes,
    ``N = Phi - I`` being nilpotent): ``Ld = W c``. Only the ``c_j`` depend on ``k``."""
    N = sampled_chain(n, 1.0)[0] - np.eye(n)
    obs = np.array([np.linalg.matrix_power(N, i)[0] for i in range(n)])
    en = np.zeros(n)
    en[-1] = 1.0
    v = np.linalg.solve(obs, en)
    # W[:, j-1] = N^(n-j) v / dt^i, j = 1..n
    W = np.column_stack([np.linalg.matrix_power(N, n - j) @ v for j in range(1, n + 1)])
    W[np.abs(W) < 1e-12 * np.abs(W).max(axis=1, keepdims=True)] = 0.0  # round-off of exact zeros
    W = W / (dt ** np.arange(n))[:, None]
    return np.ascontiguousarray(sampled_chain(n, dt)[0]), np.ascontiguousarray(W)


@register
class AdaptiveGainObserver(Observer):
    """High-gain observer with the dead-zone gain adaptation of paper 000, eq. 2, 4-5.

    Parameters
    ----------
    system : System, optional
        Gives the order ``n``, the map back to physical coordinates and, with ``model=True``,
        the model term. Without one, give ``order``: the estimate is ``z_hat`` itself.
    lam, lam_hat : float
        Width ``lambda`` of the dead zone (the strip the output error is driven into) and the
        saturation level ``lambda_hat`` of eq. 5, ``lam_hat > lam > 0``. (``lambda`` is a
        Python keyword, and names ending in ``_`` are run-time quantities here, hence ``lam``.)
    gamma : float
        Adaptation rate, ``> 0``: ``k`` grows at most ``gamma (lam_hat - lam)^2`` per unit time.
    k0 : float
        Initial gain ``k(0) > 0``.
    p : array_like, optional
        Hurwitz coefficients ``p_1..p_n`` (default binomial, ``(s + 1)^n``).
    order : int, optional
        ``n`` when no system is given.
    outputs : tuple of int
        The measured channel, a 1-tuple (default ``(0,)``).
    k_max : float, optional
        Upper bound on ``k`` (``>= k0``). ``k`` is clipped to it after each sample and a
        :class:`RuntimeWarning` is issued the first time (per reset) it is reached. Not in the
        paper; a safeguard for measurements noisier than ``lam`` (see Notes).
    model : bool
        Add the model term ``phi(sat(z_hat), u)`` of the system to the last equation.
    method : {"exact", "rk4", "euler"}
        How ``update`` advances the observer state ``(z, k)`` over one sample, ``y`` held:

        * ``rk4``: classical RK4 of the joint ODE in ``(z, k)``, i.e. eq. 2 with eq. 4-5
          integrated together (``k`` varies inside the sample);
        * ``euler``: forward Euler of the same joint ODE;
        * ``exact`` (default, as for the plain observer): the sampled-data observer of
          :class:`~hgo_mj.observers.high_gain.HighGainObserver` at the start-of-sample gain
          ``k(t_j)`` (chain propagated exactly, correction with the pole-matched gain, stable
          for every ``k dt``), and ``k(t_{j+1}) = k(t_j) + dt gamma d(y_j - z_1(t_j))^2``, the
          adaptation law integrated exactly with the sampled innovation held. "Exact" is exact
          for the linear part at frozen ``k``; with ``k`` varying inside a sample no closed form
          exists. As ``k dt -> 0`` all three agree with the continuous observer.

        ``rk4`` and ``euler`` become unstable when ``k dt`` exceeds a limit fixed by ``p``
        (:meth:`max_stable_gain`); ``exact`` never does, which matters when ``k`` keeps growing.
    z_bounds : (array_like, array_like), optional
        Saturation of the reported estimate and of the model term's argument (Khalil, sec. 14.5).
    x_hat0, z_hat0 : array_like, optional
        Initial estimate in physical or observer coordinates (default zero).
    on_unstable : {"raise", "warn", "ignore"}
        What :meth:`check_period` does when the linear part's one-step map is unstable at the
        gain a run starts from (``k0``) or at ``k_max``, and what a step does when ``k`` grows
        past the stable limit during a run (``raise``: :class:`~hgo_mj.exceptions.DivergenceError`;
        ``warn``: once per member and reset).

    Attributes
    ----------
    k_ : float
        The current gain ``k(t)``, reported by :meth:`diagnostics` as ``"k"`` at every sample.
    dropouts_ : int
        NaN samples, over which the observer ran open loop (prediction held, ``k`` not adapted).
    k_max_reached_ : bool
        Whether ``k`` reached ``k_max`` since the last reset.

    Notes
    -----
    **Choosing lambda against the noise.** The theorems assume a noise-free measurement. With
    additive noise ``nu`` the adapted quantity is ``y + nu - y_hat``: even a perfect estimate
    leaves ``|e_1| = |nu|``, and every sample with ``|nu| > lam`` increases ``k``. With
    Gaussian noise of standard deviation ``sigma`` the fraction of such samples is
    ``P(|nu| > lam) = erfc(lam / (sigma sqrt 2))``: 32 % at ``lam = sigma``, 4.6 % at
    ``2 sigma``, 0.27 % at ``3 sigma``, 6e-5 at ``4 sigma``. So ``lam`` must be several
    ``sigma`` (paper 000's example: ``lam = 0.02 = 4 sigma``) or ``k`` grows without end; and a
    larger ``k`` passes more noise into ``y_hat`` (eq. 3), which makes ``|e_1|`` exceed ``lam``
    more often still. With noise larger than ``lam`` no ``k`` stops the adaptation: bound it
    with ``k_max`` (and prefer ``method="exact"``, stable at every ``k``). Measured on a
    chain of two integrators at rest (``lam = 0.01``, ``gamma = 100``, ``dt = 0.01``, 200 s):
    ``sigma = 2 lam`` drives ``k`` from 1 to 4.5, faster and faster; ``sigma = lam / 2`` still
    lets it creep up (by 0.6 %); ``sigma = lam / 5`` leaves it at ``k0``.

    **Per-sample cost.** One compiled kernel (:func:`adaptive_run`) advances every member over
    a block of samples; for ``exact`` the pole-matched gain at the current ``k`` is expanded
    from the roots of ``p`` (one ``expm1`` per real root, or one in all for the default
    binomial ``p``) and reused while ``k`` does not change. With the model term,
    ``system.phi_batch`` is called once per sample for the whole batch (four times for
    ``rk4``). Measured (2 shared cores, heavily loaded): an unbatched ``update`` costs
    0.8-1.0x the plain observer's (``RiccatiObserver(model=False)``, the same one-sample map as
    :class:`~hgo_mj.observers.high_gain.HighGainObserver`); the kernel alone 20 ns (euler),
    70 ns (exact, ``k`` changing every sample), 90 ns (rk4) per observer-step at B = 1024.

    References
    ----------
    Paper 000 (Bullinger, Ilchmann, Allgöwer 1998): eq. 2, eq. 4-5, Theorems 2 and 3 (eq. 14),
    section 4 (bioreactor example, reproduced by ``hgo-mj reproduce bullinger1998``).

    Examples
    --------
    A sample with ``|e_1| = 1 > lam_hat`` raises ``k`` by ``dt gamma (lam_hat - lam)^2``:

    >>> import numpy as np
    >>> obs = AdaptiveGainObserver(order=2, lam=0.1, lam_hat=0.3, gamma=100.0, k0=5.0,
    ...                            method="euler")
    >>> obs.update([1.0], np.zeros(0), 0.01).round(4)
    array([0.1 , 0.25])
    >>> obs.diagnostics()
    {'k': 5.04, 'dropouts': 0.0}
    """

    name = "adaptive_gain"
    summary = "high-gain observer whose k adapts by the dead-zone law dk/dt = gamma d(e1)^2"
    reference = "paper 000 (Bullinger et al. 1998), eq. 2, 4-5, Theorems 2-3"
    family_diagnostics = ("k",)

    def __init__(self, system: System | None = None, *, lam: float, lam_hat: float,
                 gamma: float, k0: float, p: Any = None, order: int | None = None,
                 outputs: Any = (0,), k_max: float | None = None, model: bool = False,
                 method: str = "exact", z_bounds: Any = None, x_hat0: Any = None,
                 z_hat0: Any = None, on_unstable: str = "raise") -> None:
        super().__init__(system, order=order, outputs=outputs, on_unstable=on_unstable)
        n = self.n
        self.p = binomial_coefficients(n) if p is None else check_hurwitz(p)
        if self.p.size != n:
            raise DimensionError(f"p must have n = {n} coefficients; found {self.p.size}")
        self.lam = finite_scalar("lam", lam, positive=True)
        self.lam_hat = finite_scalar("lam_hat", lam_hat, positive=True)
        _check_dead_zone(self.lam, self.lam_hat)
        self.gamma = finite_scalar("gamma", gamma, positive=True)
        self.k0 = finite_scalar("k0", k0, positive=True)
        if k_max is None:
            self.k_max = None
        else:
            self.k_max = finite_scalar("k_max", k_max, positive=True)
            self._check_parameter("k0", self.k0)
        check_options(method, self.on_unstable, model, system)
        self.model = boolean("model", model)
        self.method = method
        self.z_bounds = bounds_pair(z_bounds, n)
        self._bounds, self._sat = bounds_rows(self.z_bounds, n)
        self._tau_max = _max_stable_kdt(tuple(self.p.tolist()), method)
        self._roots = root_data(self.p)
        self._identity = is_identity_map(system, n)
        #: the packed constants of :func:`adaptive_run` per (period, parameters)
        self._maps_cache: dict[tuple[float, bytes], tuple[Array, Array, Array]] = {}
        # the constructor's initial estimate, checked now (any number of members)
        for name, value, width in (("x_hat0", x_hat0, len(self.state_names)),
                                   ("z_hat0", z_hat0, n)):
            if value is not None:
                batch_rows(name, value, width, None)
        self._start = (x_hat0, z_hat0)

    # ------------------------------------------------------------------ parameters
    def _parameters(self) -> dict[str, Any]:
        """The constants of the adaptation law (paper 000, eq. 4-5): the dead-zone width
        ``lam``, its saturation level ``lam_hat``, the rate ``gamma`` and the initial gain
        ``k0``, each a float per member."""
        return {"lam": self.lam, "lam_hat": self.lam_hat, "gamma": self.gamma, "k0": self.k0}

    def _check_parameter(self, name: str, value: Any) -> Array:
        """Each a positive finite number (``k0 <= k_max``), as the constructor checks it;
        ``lam_hat > lam`` is a condition on two parameters, checked by :meth:`parameters`."""
        v = finite_scalar(name, value, positive=True)
        if name == "k0" and self.k_max is not None and self.k_max < v:
            raise DesignError(f"k_max must be >= k0; found k_max={self.k_max:g} < k0={v:g}")
        return np.array(v)

    def parameters(self, batch: int = 1, **values: Any) -> Params:
        """The parameters of ``batch`` members (:meth:`Observer.parameters`), each member's
        ``lam_hat > lam`` checked as the constructor checks it (paper 000, eq. 5).

        Examples
        --------
        >>> obs = AdaptiveGainObserver(order=2, lam=0.1, lam_hat=0.3, gamma=100.0, k0=5.0)
        >>> obs.parameters(2, gamma=[100.0, 400.0]).gamma.tolist()
        [100.0, 400.0]
        >>> obs.parameters(2, lam=[0.1, 0.3])  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        hgo_mj.exceptions.DesignError: lam_hat must be > lam ...; found lam_hat=0.3 <= lam=0.3
        """
        params = super().parameters(batch, **values)
        for lam, lam_hat in zip(params.lam, params.lam_hat):
            _check_dead_zone(float(lam), float(lam_hat))
        return params

    # ------------------------------------------------------------------ state
    @property
    def k_(self) -> Any:
        """The current gain ``k(t)`` (a float, or ``(B,)`` for a batched observer)."""
        return self._public(self.state.S[:, 0].copy())

    @property
    def k_max_reached_(self) -> Any:
        """Whether ``k`` reached ``k_max`` since the last reset (per member)."""
        return self._public(self.state.lim[:, 0] > 0)

    @property
    def L(self) -> Array:
        """The current output-injection gains ``p_i k^i`` (eq. 2), ``(n,)`` or ``(B, n)``."""
        return self._public(self.p * self.state.S[:, :1] ** np.arange(1, self.n + 1))  # type: ignore[no-any-return]

    def _init(self, p: Params, x0: Array | None, z0: Array | None,
              u0: Array) -> dict[str, Any]:
        """``S = (k, z)`` ``(B, n + 1)`` with ``k = k0``; ``lim`` per member: reached
        ``k_max`` (0/1), sample at which ``k`` crossed the stable limit (-1: not yet), ``k``
        there; ``warned``: whether the warnings of ``k_max`` and of the stable limit were
        issued (once per member and reset); ``x_held``: the estimate at the start (failures
        of the inverse map not counted: the run has not started)."""
        B = u0.shape[0]
        if x0 is None and z0 is None:
            ix, iz = self._start
            x0 = None if ix is None else batch_rows("x_hat0", ix, len(self.state_names), B)
            z0 = None if iz is None else batch_rows("z_hat0", iz, self.n, B)
        z = self._initial_z(x0, z0, u0)
        S = np.ascontiguousarray(np.hstack([np.full((B, 1), float(p.k0)), z]))
        lim = np.zeros((B, 3))
        lim[:, 1] = -1.0
        fields: dict[str, Any] = {"S": S, "lim": lim, "warned": np.zeros((B, 2), dtype=bool)}
        if not self._identity:
            s = State(**self._core(B))
            Zc = np.empty((B, 1, self.n))
            report(S, 1, self._bounds, self._sat, 0, Zc)
            self._to_physical(s, Zc, u0[:, None], np.empty((B, 1, len(self.state_names))))
            s.inverse_failures[:] = 0
            fields.update(s.fields)
        return fields

    def _current(self, p: Params, s: State) -> tuple[Array, Array, Array]:
        S = s.S
        Zc = np.empty((S.shape[0], 1, self.n))
        report(S, 1, self._bounds, self._sat, 0, Zc)
        x = Zc[:, 0].copy() if self._identity else s.x_held.copy()
        return x, Zc[:, 0], S[:, :1].copy()

    # ------------------------------------------------------------------ setup
    def max_stable_gain(self, dt: float) -> float:
        """Largest ``k`` at which the linear part's one-step map (``method``) at period ``dt``
        is stable: ``tau_max / dt``, ``tau_max`` depending on ``p`` and ``method`` only.

        Parameters
        ----------
        dt : float
            Sample period, seconds, > 0.

        Returns
        -------
        float
            The gain limit (``inf`` for ``method="exact"``).

        Raises
        ------
        DesignError
            ``dt`` not a positive finite number.

        Examples
        --------
        >>> obs = AdaptiveGainObserver(order=2, lam=0.1, lam_hat=0.3, gamma=100.0, k0=5.0,
        ...                            method="euler")
        >>> round(obs.max_stable_gain(0.01), 3)
        200.0
        """
        return self._tau_max / finite_scalar("dt", dt, positive=True)

    def max_stable_period(self, k: float | None = None) -> float:
        """Largest stable sample period at gain ``k`` (default: the current ``k`` of the
        observer's own state, the largest over the members).

        Parameters
        ----------
        k : float, optional
            The gain, > 0; default the current one.

        Returns
        -------
        float
            Seconds (``inf`` for ``method="exact"``).

        Raises
        ------
        DesignError
            ``k`` not a positive finite number.

        Examples
        --------
        >>> obs = AdaptiveGainObserver(order=2, lam=0.1, lam_hat=0.3, gamma=100.0, k0=5.0,
        ...                            method="euler")
        >>> round(obs.max_stable_period(), 6), round(obs.max_stable_period(10.0), 6)
        (0.4, 0.2)
        """
        k = float(self.state.S[:, 0].max()) if k is None else finite_scalar("k", k, positive=True)
        return self._tau_max / k

    def _check_period(self, p: Params, dt: float) -> None:
        """Check the linear part's one-step map at the current gain of a run that starts
        (``k0`` of the parameters ``p``) and at ``k_max`` (if given).

        ``k`` only grows, so a period stable now may not stay so: without ``k_max``, the update
        checks ``k dt`` against the limit at every sample where ``k`` changed.
        """
        dt = finite_scalar("dt", dt, positive=True)
        self._entry(p, dt)
        if self.on_unstable == "ignore" or self.method == "exact":
            return
        limit = self.max_stable_gain(dt)
        for what, k in (("the current gain", float(p.k0)), ("k_max", self.k_max)):
            if k is not None and k >= limit:
                self._unstable(
                    f"{self.method} update of the adaptive high-gain observer (n={self.n}) with "
                    f"sample period {dt:g} is unstable at {what} k={k:g}: the linear part is "
                    f"stable for k dt < {self._tau_max:.4g}, i.e. k < {limit:.4g} at this period; "
                    f"the largest stable period at k={k:g} is {self._tau_max / k:.4g} "
                    f"(method='exact' is stable for every k)", DesignError)

    def _unstable(self, msg: str, exc: type[Exception]) -> None:
        if self.on_unstable == "raise":
            raise exc(msg)
        warnings.warn(msg, RuntimeWarning, stacklevel=4)

    def _entry(self, p: Params, dt: float) -> tuple[Array, Array, Array]:
        """:meth:`_maps` of the parameters ``p`` at the period ``dt``, cached (at most
        :data:`~hgo_mj.observers.high_gain.MAP_CACHE` kept, the oldest goes first)."""
        key = (dt, p.key())
        entry = self._maps_cache.get(key)
        if entry is None:
            entry = self._maps(p, dt)
            if len(self._maps_cache) >= MAP_CACHE:
                del self._maps_cache[next(iter(self._maps_cache))]
            self._maps_cache[key] = entry
        return entry

    def _maps(self, p: Params, dt: float) -> tuple[Array, Array, Array]:
        """The packed constants of :func:`adaptive_run` at the period ``dt`` for the
        parameters ``p``:
        ``par = (dt, lam, lam_hat, gamma, r, k_limit, k_max, k_stab)``, ``mats = (Phi, W, M0)``
        (``Phi``, ``W`` of the exact map, zero otherwise; ``M0`` the dropout map) and
        ``vecs = (p, g0, C(n, j), real roots, pairs)``; ``g0`` is also the held model term's
        input matrix (``S B`` for exact, ``dt B`` for euler)."""
        n = self.n
        M0, _, g0 = one_step_map(self.p, 1.0, dt, self.method, closed=False)
        if self.method == "exact":
            Phi, W = exact_matrices(n, dt)
        else:
            Phi = W = np.zeros((n, n))
        k_stab = math.inf
        if self.method != "exact" and self.on_unstable != "ignore":
            k_stab = self._tau_max / dt
        k_max = math.inf if self.k_max is None else self.k_max
        mode, r, _, _, rows = self._roots
        par = np.array([dt, float(p.lam), float(p.lam_hat), float(p.gamma), r,
                        min(k_stab, k_max), k_max, k_stab])
        vecs = np.zeros((6, n + 1))
        vecs[0, :n], vecs[1, :n], vecs[2:] = self.p, g0, rows
        return par, np.array([Phi, W, M0]), vecs

    # ------------------------------------------------------------------ update
    def _step(self, p: Params, s: State, Y: Array, U: Array, dt: float, X: Array, Z: Array,
              D: Array) -> None:
        par, mats, vecs = self._entry(p, dt)
        S, B, T = s.S, Y.shape[0], Y.shape[1]
        stop = self.on_unstable == "raise"
        bounds, sat, lim = self._bounds, self._sat, s.lim
        mode, _, nr, npair, _ = self._roots
        code = _CODES[self.method]
        if not self.model:  # the whole block in one call
            status = adaptive_run(S, Y, np.zeros((1, T)), 0, False, code, mode, nr, npair, stop,
                                  sat, par, mats, vecs, bounds, Z, D, lim)
            if status:
                self._limits(p, s, dt)
        elif self.method == "rk4":  # the model term at every stage
            M0, g0 = mats[2], vecs[1, :self.n]
            lam, lam_hat, gamma = float(par[1]), float(par[2]), float(par[3])
            for j in range(T):
                u = U[:, j]
                prev = S.copy()

                def phi(V: Array, u: Array = u) -> Array:
                    return self._phi(V, u)

                def stage(V: Array, ph: Array, j: int = j) -> Array:
                    Dv = np.empty_like(V)
                    adaptive_rhs(V, Y, j, ph, vecs, lam, lam_hat, gamma, Dv)
                    return Dv

                model_rk4(S, Y, j, dt, 1, M0, g0, phi, stage)
                if adaptive_limits(S, prev, Y, j, par, stop, lim):
                    self._limits(p, s, dt)
                D[:, j, 0] = S[:, 0]
                report(S, 1, bounds, sat, j, Z)
        else:  # the model term held at its start-of-sample value
            for j in range(T):
                ph = self._phi(S, U[:, j])
                if adaptive_run(S, Y, ph.reshape(B, 1), j, True, code, mode, nr, npair, stop,
                                sat, par, mats, vecs, bounds, Z, D, lim):
                    self._limits(p, s, dt)
        if self._identity:
            X[...] = Z
        else:
            self._to_physical(s, Z, U, X)

    def _phi(self, V: Array, u: Array) -> Array:
        """The model term ``phi(sat(z), u)`` of every member, ``(B,)``."""
        A = np.empty((V.shape[0], self.n))
        saturated(V, 1, self._bounds, self._sat, A)
        return np.ascontiguousarray(self.system.phi_batch(A, u), dtype=float)  # type: ignore[union-attr]

    def _limits(self, p: Params, s: State, dt: float) -> None:
        """Warn (once per member and reset) that ``k`` reached ``k_max``; raise or warn (once)
        when it grew past the largest gain at which euler/rk4 are stable at this period."""
        lim, warned = s.lim, s.warned
        reached = lim[:, 0] > 0
        if (reached & ~warned[:, 0]).any():
            warned[:, 0] |= reached
            warnings.warn(f"adaptive high-gain observer: k reached k_max = {self.k_max:g}; "
                          f"k is held there (the output error is still outside the "
                          f"lam = {float(p.lam):g} strip: noise larger than "
                          f"lam, or lam too small for this plant)", RuntimeWarning, stacklevel=5)
        crossed = lim[:, 1] >= 0
        new = crossed & ~warned[:, 1]
        if not new.any():
            return
        warned[:, 1] |= crossed
        b = int(np.argmax(new))
        B = lim.shape[0]
        who = f" (member {b} of {B} with these parameters)" if B > 1 else ""
        self._unstable(
            f"adaptive high-gain observer: k grew to {lim[b, 2]:g}{who}, past the largest "
            f"gain {self._tau_max / dt:.4g} at which the {self.method} update with sample period "
            f"{dt:g} is stable (k dt < {self._tau_max:.4g}); use method='exact', a shorter "
            f"period, or k_max below the limit", DivergenceError)

    def params(self) -> dict[str, Any]:
        return {"lam": self.lam, "lam_hat": self.lam_hat, "gamma": self.gamma, "k0": self.k0,
                "k_max": self.k_max, "p": self.p.tolist(), "order": self.n,
                "outputs": list(self.outputs), "model": self.model, "method": self.method,
                "z_bounds": None if self.z_bounds is None else [b.tolist() for b in self.z_bounds]}


__all__ = ["AdaptiveGainObserver", "adaptation_rate", "adaptive_run", "dead_zone",
           "joint_rhs", "matched_coefficients"]
