"""The high-gain observer of Tornambè [T92]_ (paper 000 [000]_, eq. 2), optionally with a model
term ([GHO92]_, [K]_), and the multi-output observer of paper 001 [001]_ (eq. 4-5): one chain of
integrators per measured output.

.. math::

    \\dot{\\hat z}_i &= \\hat z_{i+1} + p_i k^i (y - \\hat z_1), \\quad i = 1, \\dots, n-1 \\\\
    \\dot{\\hat z}_n &= p_n k^n (y - \\hat z_1) + [\\hat\\varphi(\\mathrm{sat}(\\hat z), u)]

The bracketed model term is off by default (Tornambè's observer is model-free: a chain of
integrators); ``model=True`` adds the system's ``phi`` as in Gauthier, Hammouri and Othman
(1992). The error ``e = z - z_hat`` of the model-free observer obeys the linear dynamics of
paper 000, eq. 6, ``e' = A_k e + B phi(z, u)`` with ``A_k = A - L C``.

**One kernel.** With the measurement ``y`` and the model term ``w = phi`` held over a sample,
every method's one-step map is affine (:func:`one_step_map`):

.. math:: z^+ = M z + b\\, y + g\\, w, \\qquad z^+ = M_0 z + g_0 w \\ \\text{(a dropout)}

``M, b, g`` (closed loop) and ``M_0, g_0`` (open loop, no correction) are built once per sample
period and cached (at most :data:`MAP_CACHE` periods). :func:`affine_advance` applies them over
B members and T samples in one compiled call (numba), choosing per member and per chain the
open-loop map where that member's measurement is NaN, and saturating the reported estimate.

* Model-free (the default), and every multi-output observer without ``phi``: one kernel call
  per block of T samples.
* With the model term and ``exact``/``euler``: ``w = phi(sat(z_hat), u)`` is evaluated by the
  system (``System.phi_batch`` on the B rows, plain numpy or Python) before each sample, so the
  samples loop in Python and the kernel is called once per sample for all B members.
* With the model term and ``rk4``: RK4 of the continuous observer, ``phi`` evaluated at every
  stage (vectorized numpy over B); a member whose measurement is NaN takes the open-loop map
  with ``phi`` held, as before.

References
----------
.. [000] E. Bullinger, A. Ilchmann, F. Allgöwer, "A simple adaptive observer for nonlinear
   systems", NOLCOS 1998, eq. 2 (observer), eq. 3 (noise/disturbance transfer), eq. 6 (error).
.. [001] G. Besançon, Q. Zhang, H. Hammouri, "High-gain observer based state and parameter
   estimation in nonlinear systems", IFAC NOLCOS 2004, eq. 4 (observer), eq. 5 (block form).
.. [T92] A. Tornambè, "High-gain observers for non-linear systems", Int. J. Systems Science
   23(9), 1992.
.. [GHO92] J.P. Gauthier, H. Hammouri, S. Othman, "A simple observer for nonlinear systems:
   applications to bioreactors", IEEE TAC 37(6), 1992 (the model term).
.. [K] H.K. Khalil, *Nonlinear Systems*, 3rd ed., sec. 14.5: saturating the estimate against
   peaking.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from math import factorial
from typing import Any

import numpy as np
from numba import njit

from .._validate import boolean, finite_scalar, one_of, vector
from ..design import binomial_coefficients, check_hurwitz, hgo_gains
from ..exceptions import DesignError, DimensionError
from ..systems.base import System, derivative_names
from ._integrate import rk4
from .base import Array, Dimension, Observer, Params, State, batch_rows, register

__all__ = ["METHODS", "HighGainObserver", "MultiOutputHighGainObserver", "matched_gain",
           "one_step_map"]

#: the integration methods of a sample: the sampled-data observer, forward Euler, RK4
METHODS = ("exact", "euler", "rk4")
#: at most this many (sample period, parameters) keep their one-step maps (a tuning round of many
#: gains reuses them; jittered periods do not grow memory without bound)
MAP_CACHE = 64


#: ``flags`` bits of :func:`affine_advance`
SATURATE, MODEL_TERM = 1, 2
#: members advanced together by :func:`affine_advance` (its scratch rows hold one tile)
TILE = 64


@njit(inline="always")
def _row_sums(Pi: Array, col: int, z: Array, f: int, m: int, gn: int,
              acc: Array) -> None:  # pragma: no cover
    """``acc[g] = 0 + Pi[col] z[f, g] + ... + Pi[col + m - 1] z[f + m - 1, g]`` for the tile's
    first ``gn`` members, left to right: a row of ``M z`` (``col = 0``) or of ``M0 z``
    (``col = nm``) of :func:`affine_advance`."""
    p = Pi[col]
    for g in range(gn):
        acc[g] = 0.0 + p * z[f, g]
    for j in range(1, m):
        p = Pi[col + j]
        for g in range(gn):
            acc[g] += p * z[f + j, g]


@njit(inline="always")
def _report(z: Array, gn: int, bounds: Array, saturate: bool,
            out: Array) -> None:  # pragma: no cover
    """``out[g] = z[:, g]`` for the tile's first ``gn`` members, clipped to ``[bounds[0],
    bounds[1]]`` when ``saturate``."""
    for g in range(gn):
        for i in range(z.shape[0]):
            v = z[i, g]
            if saturate:
                if v < bounds[0, i]:
                    v = bounds[0, i]
                elif v > bounds[1, i]:
                    v = bounds[1, i]
            out[g, i] = v


@njit(cache=True)
def affine_advance(Z: Array, Y: Array, W: Array, P: Array, lay: Array, bounds: Array,
                   flags: int, t0: int, t1: int, Zout: Array) -> None:  # pragma: no cover
    r"""Apply the affine one-step maps of the chains to ``Z`` ``(B, n)`` in place, for the
    samples ``t0 <= t < t1`` of ``Y`` ``(B, T, nc)`` (chain ``c`` reads ``Y[:, t, c]``).

    Chain ``c`` occupies ``z[f : f + m]`` with ``f, m = lay[c]``. Its maps are packed in
    ``P[c]`` (:func:`packed_maps`, zero-padded to the largest chain ``nm``): ``M = P[c, :, :nm]``,
    ``M0 = P[c, :, nm:2nm]``, ``b, g, g0 = P[c, :, 2nm], P[c, :, 2nm+1], P[c, :, 2nm+2]``:

    .. math:: z_c^+ = M z_c + b\, y_c\, [+ g\, w_c] \quad\text{or, where } y_c
              \text{ is NaN,}\quad z_c^+ = M_0 z_c\, [+ g_0 w_c]

    with ``w = W[b, t, c]`` the held model term when ``flags & MODEL_TERM``. Each row is summed
    left to right from zero (``0 + M_i1 z_1 + ... + M_im z_m``, then ``b y``, then ``g w``).
    ``Zout[b, t]`` receives the new state, clipped to ``[bounds[0], bounds[1]]`` when
    ``flags & SATURATE`` (the reported estimate; the state is not clipped).

    The members go in tiles of :data:`TILE`, every sample of a tile before the next tile; a
    tile's state, measurements and sums are held member-minor (``z[i, member]``), so that each
    term of a row is one loop over the tile's members, which the compiler vectorizes (the
    members are independent; one member at a time, each sample waits on the previous one).
    Every member's arithmetic is the same, in the same order, whatever the tile: a member
    advanced alone gives the same bits.
    """
    B, n = Z.shape
    nb = lay.shape[0]
    nm = P.shape[1]
    saturate = (flags & 1) != 0
    use_w = (flags & 2) != 0
    tl = min(TILE, B)
    rows = np.empty((2 * n + 3, tl))  # the tile's scratch rows, one allocation
    z = rows[:n]  # the tile's state
    zn = rows[n:2 * n]  # its next state
    y = rows[2 * n]
    w = rows[2 * n + 1]
    acc = rows[2 * n + 2]  # a row's running sum of M z (or M0 z)
    for b0 in range(0, B, tl):
        gn = min(tl, B - b0)
        for g in range(gn):
            for i in range(n):
                z[i, g] = Z[b0 + g, i]
        for t in range(t0, t1):
            for c in range(nb):
                f = lay[c, 0]
                m = lay[c, 1]
                lost = False
                for g in range(gn):
                    v = Y[b0 + g, t, c]
                    y[g] = v
                    lost |= v != v
                if use_w:
                    for g in range(gn):
                        w[g] = W[b0 + g, t, c]
                for i in range(m):
                    _row_sums(P[c, i], 0, z, f, m, gn, acc)
                    p = P[c, i, 2 * nm]
                    if use_w:
                        q = P[c, i, 2 * nm + 1]
                        for g in range(gn):
                            zn[f + i, g] = acc[g] + p * y[g] + q * w[g]
                    else:
                        for g in range(gn):
                            zn[f + i, g] = acc[g] + p * y[g]
                    if lost:  # some member's y is NaN: its row of the open-loop map
                        _row_sums(P[c, i], nm, z, f, m, gn, acc)
                        q = P[c, i, 2 * nm + 2]
                        for g in range(gn):
                            if y[g] != y[g]:
                                zn[f + i, g] = acc[g] + q * w[g] if use_w else acc[g]
            z, zn = zn, z
            _report(z, gn, bounds, saturate, Zout[b0:b0 + gn, t])
        for g in range(gn):
            for i in range(n):
                Z[b0 + g, i] = z[i, g]


#: the model-term argument of :func:`affine_advance` when there is none (never read)
_NO_W = np.zeros((1, 1, 1))


def packed_maps(chains: list[tuple[Array, Array, Array, Array, Array]]) -> Array:
    """The per-chain maps ``(M, b, g, M0, g0)`` packed as :func:`affine_advance` reads them:
    ``(len(chains), nm, 2 nm + 3)``, zero-padded to the largest chain ``nm``."""
    nm = max(c[0].shape[0] for c in chains)
    P = np.zeros((len(chains), nm, 2 * nm + 3))
    for c, (M, b, g, M0, g0) in enumerate(chains):
        m = M.shape[0]
        P[c, :m, :m], P[c, :m, nm:nm + m] = M, M0
        P[c, :m, 2 * nm], P[c, :m, 2 * nm + 1], P[c, :m, 2 * nm + 2] = b, g, g0
    return P


def sampled_chain(n: int, dt: float) -> tuple[Array, Array]:
    """``Phi = e^{A dt}`` and ``S = int_0^dt e^{A s} ds`` of the chain of ``n`` integrators."""
    Phi = np.zeros((n, n))
    S = np.zeros((n, n))
    for i in range(n):
        for j in range(i, n):
            Phi[i, j] = dt ** (j - i) / factorial(j - i)
            S[i, j] = dt ** (j - i + 1) / factorial(j - i + 1)
    return Phi, S


def matched_gain(p: Array, k: float, dt: float) -> Array:
    """Gain ``Ld`` placing the eigenvalues of ``Phi - Ld C`` at ``exp(k r_i dt)``, ``r_i`` the
    roots of ``s^n + p_1 s^(n-1) + ... + p_n``: the sampled-data observer whose error at the
    samples decays exactly as the continuous one's modes (pole matching).

    Ackermann's formula in the scaled coordinates ``diag(1, dt, ..., dt^(n-1))``, in which the
    sampled chain does not depend on ``dt``, applied to ``Phi - I`` so that the tiny
    ``(k dt)^n`` terms are not lost to cancellation near ``z = 1``.
    As ``k dt -> 0``, ``Ld / dt -> (p_i k^i)``: the continuous gains of paper 000, eq. 2.

    Parameters
    ----------
    p : (n,) ndarray
        Hurwitz coefficients ``p_1..p_n``.
    k : float
        High-gain parameter, > 0.
    dt : float
        Sample period, > 0.

    Returns
    -------
    (n,) ndarray
        The discrete correction gain ``Ld``.

    Examples
    --------
    >>> import numpy as np
    >>> matched_gain(np.array([2.0, 1.0]), 10.0, 0.01).round(4)
    array([0.1903, 0.9056])
    """
    n = p.size
    # Pole placement for N = Phi - I (nilpotent; scaled: N_ij = 1/(j-i)! for j > i) with the
    # eigenvalues w_i = exp(k r_i dt) - 1 computed by expm1: no cancellation when k dt is small.
    N = sampled_chain(n, 1.0)[0] - np.eye(n)
    w = np.expm1(k * dt * np.roots(np.concatenate(([1.0], p))))
    q = np.zeros((n, n))
    for c in np.real(np.poly(w)):  # Horner: q(N) = N^n + c_1 N^(n-1) + ... + c_n I
        q = q @ N + c * np.eye(n)
    obs = np.array([np.linalg.matrix_power(N, i)[0] for i in range(n)])  # C N^i
    en = np.zeros(n)
    en[-1] = 1.0
    return q @ np.linalg.solve(obs, en) / dt ** np.arange(n)


def one_step_map(p: Array, k: float, dt: float, method: str,
                 closed: bool = True) -> tuple[Array, Array, Array]:
    """One sample of the observer: ``z+ = M z + b y + g w`` with ``y`` and ``w = phi`` held.

    * ``exact``: the sampled-data observer. Between samples the chain is propagated exactly
      (``Phi = e^{A dt}``, ``g = S B``) and the correction ``Ld (y_k - z_1(t_k))`` uses the
      pole-matched gain of :func:`matched_gain`: ``M = Phi - Ld C`` has eigenvalues
      ``exp(k r_i dt)``, stable for every ``dt``, and a polynomial output of degree < n is
      tracked without the lag and sawtooth that a held measurement causes.
    * ``euler``: forward Euler of the continuous observer, ``M = I + dt (A - L C)`` with
      ``L = (p_i k^i)`` (paper 004, eq. 53, for this observer); unstable for long ``dt``.
    * ``rk4``: classical RK4 of the continuous observer with the measurement held, i.e. the
      degree-4 Taylor polynomial of ``e^{(A - L C) dt}``; unstable for long ``dt``.

    ``closed=False`` gives the open-loop prediction (no correction), used over a dropout.

    Parameters
    ----------
    p : (n,) ndarray
        Hurwitz coefficients ``p_1..p_n``.
    k : float
        High-gain parameter, > 0.
    dt : float
        Sample period, > 0.
    method : {"exact", "euler", "rk4"}
        How the sample is advanced (above).
    closed : bool, default True
        With the output correction (False: the open-loop prediction, ``b = 0``).

    Returns
    -------
    M : (n, n) ndarray
        The error (state) transition over one sample.
    b : (n,) ndarray
        The gain on the held measurement ``y``.
    g : (n,) ndarray
        The gain on the held model term ``w``.

    Examples
    --------
    >>> import numpy as np
    >>> M, b, g = one_step_map(np.array([2.0, 1.0]), 10.0, 0.01, "euler")
    >>> M, b, g
    (array([[ 0.8 ,  0.01],
           [-1.  ,  1.  ]]), array([0.2, 1. ]), array([0.  , 0.01]))
    >>> M, b, g = one_step_map(np.array([2.0, 1.0]), 10.0, 0.01, "exact")
    >>> np.abs(np.linalg.eigvals(M)).round(6)       # exp(-k dt), twice
    array([0.904837, 0.904837])
    """
    n = p.size
    Phi, S = sampled_chain(n, dt)
    B = np.zeros(n)
    B[-1] = 1.0
    if method == "exact":
        b = matched_gain(p, k, dt) if closed else np.zeros(n)
        M = Phi.copy()
        M[:, 0] -= b
        return M, b, S @ B
    L = p * k ** np.arange(1, n + 1) if closed else np.zeros(n)
    F = np.diag(np.ones(n - 1), 1)
    F[:, 0] -= L
    M, Sm = taylor_step(F, dt, method)
    return M, Sm @ L, Sm @ B


def taylor_step(F: Array, dt: float, method: str) -> tuple[Array, Array]:
    """Euler (``method="euler"``) or RK4 of ``w' = F w + v`` with ``v`` held over ``dt``:
    ``w+ = M w + Sm v`` with ``M = sum_{j<=order} (F dt)^j / j!`` (the degree-1 or degree-4
    Taylor polynomial of ``e^{F dt}``) and ``Sm = sum_{j<order} dt^{j+1} F^j / (j+1)!``."""
    n = F.shape[0]
    order = 1 if method == "euler" else 4
    M = np.eye(n)
    Sm = np.eye(n) * dt
    term = np.eye(n)
    for j in range(1, order + 1):
        term = term @ F * dt / j
        M = M + term
        if j < order:
            Sm = Sm + term * dt / (j + 1)
    return M, Sm


def spectral_radius(M: Array) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(M))))


def largest_stable_step(step_matrix: Callable[[float], Array], start: float,
                        limit: float) -> float:
    """Largest step ``h`` with ``spectral_radius(step_matrix(h)) < 1``: the first instability
    going up from ``start`` (a step known to be stable) in 5 % increments, then 60 bisections;
    ``inf`` if still stable at ``limit``. (Going up in 5 % steps finds the *first* boundary: a
    stability region need not be star-shaped, and doubling could jump over a band.)"""

    def stable(h: float) -> bool:
        return spectral_radius(step_matrix(h)) < 1.0

    lo, hi = 0.0, start
    while stable(hi):
        lo, hi = hi, hi * 1.05
        if hi > limit:
            return math.inf
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo


def check_step_stable(M: Array, on_unstable: str, what: str, dt: float,
                      max_stable_period: Callable[[], float], digits: int = 4) -> None:
    """React to a one-step error map ``M`` of spectral radius >= 1 at the sample period ``dt``
    as ``on_unstable`` says ("raise": :class:`DesignError`, "warn": a ``RuntimeWarning`` at the
    caller of ``check_period``/``update``, "ignore"), with a message naming ``what`` is updated
    ("euler update of the ...") and the largest stable period (computed only then)."""
    if on_unstable == "ignore":
        return
    rho = spectral_radius(M)
    if rho < 1.0:
        return
    msg = (f"{what} with sample period {dt:g} is unstable: spectral radius of the one-step "
           f"error map {rho:.{digits}g} >= 1; the largest stable period is "
           f"{max_stable_period():.{digits}g}")
    if on_unstable == "raise":
        raise DesignError(msg)
    warnings.warn(msg, RuntimeWarning, stacklevel=4)


def check_options(method: str, on_unstable: str, model: bool = False,
                  system: System | None = None) -> None:
    """The integration method, the reaction to an unstable sample period and the model term
    (which needs a system), validated."""
    boolean("model", model)
    one_of("method", method, METHODS)
    one_of("on_unstable", on_unstable, ("raise", "warn", "ignore"))
    if model and system is None:
        raise DesignError("model=True needs a system providing phi")


def bounds_pair(z_bounds: Any, n: int) -> tuple[Array, Array] | None:
    """``z_bounds = (lower, upper)`` as two length-``n`` arrays with lower < upper, or None."""
    if z_bounds is None:
        return None
    try:
        lower, upper = z_bounds
    except (TypeError, ValueError):
        raise DesignError(f"z_bounds must be a pair (lower, upper) of {n} numbers each; found "
                          f"{z_bounds!r:.60}") from None
    lo, hi = (vector("z_bounds[0]", lower, n), vector("z_bounds[1]", upper, n))
    if np.any(lo >= hi):
        raise DesignError(f"z_bounds need lower < upper; found lower {lo.tolist()}, "
                          f"upper {hi.tolist()}")
    return lo, hi


def bounds_floats(bounds: tuple[Array, Array] | None) -> tuple[list[float], list[float]] | None:
    """:func:`bounds_pair`'s arrays as two lists of Python floats (for :func:`clip_floats`),
    made once per observer rather than at every sample."""
    return None if bounds is None else (bounds[0].tolist(), bounds[1].tolist())


def clip_floats(z: Any, bounds: tuple[list[float], list[float]]) -> tuple[float, ...]:
    """``np.clip(z, lower, upper)`` on a tuple of Python floats, without numpy (``bounds`` from
    :func:`bounds_floats`)."""
    lo, hi = bounds
    return tuple([min(max(v, a), b) for v, a, b in zip(z, lo, hi)])


class _Chains:
    """The chain layout and the bounded per-period map cache shared by the two observers."""

    _lay: Array
    _bounds: Array
    _flags: int
    _maps: dict[tuple[float, bytes], Array]

    def _layout(self, orders: tuple[int, ...], bounds: tuple[Array, Array] | None) -> None:
        first = np.cumsum((0,) + orders[:-1])
        self._lay = np.ascontiguousarray(np.stack([first, orders], axis=1), dtype=np.int64)
        self._bounds = np.zeros((2, 1)) if bounds is None else np.array(bounds, dtype=float)
        self._flags = 0 if bounds is None else SATURATE
        self._maps = {}

    def _chain_maps(self, p: Params, dt: float) -> list[tuple[Array, Array, Array, Array, Array]]:
        raise NotImplementedError

    def _maps_at(self, p: Params, dt: float) -> Array:
        """The packed maps of the parameters ``p`` at the period ``dt`` (built and checked on
        first use; at most :data:`MAP_CACHE` kept)."""
        key = (dt, p.key())
        maps = self._maps.get(key)
        if maps is None:
            maps = packed_maps(self._chain_maps(p, finite_scalar("dt", dt, positive=True)))
            if len(self._maps) >= MAP_CACHE:
                del self._maps[next(iter(self._maps))]
            self._maps[key] = maps
        return maps

    def _check_period(self, p: Params, dt: float) -> None:
        self._maps_at(p, dt)

    def _kernel(self, Z: Array, Y: Array, W: Array | None, maps: Array, t0: int, t1: int,
                Zout: Array) -> None:
        if W is None:
            affine_advance(Z, Y, _NO_W, maps, self._lay, self._bounds, self._flags, t0, t1, Zout)
        else:
            affine_advance(Z, Y, W, maps, self._lay, self._bounds, self._flags | MODEL_TERM,
                           t0, t1, Zout)

    def __getstate__(self) -> dict[str, Any]:
        """Pickle without the map cache (rebuilt on first use)."""
        state = self.__dict__.copy()
        state["_maps"] = {}
        return state


@register
class HighGainObserver(_Chains, Observer):
    """High-gain observer of Tornambè (paper 000, eq. 2) on a chain of ``n`` integrators.

    Parameters
    ----------
    system : System, optional
        Gives the order ``n`` (its normal form), the map back to physical coordinates and, with
        ``model=True``, the model term ``phi`` (``System.phi_batch``). Without a system, give
        ``order``: the estimate is then ``z_hat`` itself.
    k : float
        High-gain parameter (> 0); the observer poles are ``k`` times the roots of ``p``.
    p : array_like, optional
        Hurwitz coefficients ``p_1..p_n``; default binomial, ``(s + 1)^n`` (paper 000, eq. 3).
    order : int, optional
        ``n`` when no system is given (must match the system's if both are).
    outputs : tuple of int
        The measured channel this observer uses, as a 1-tuple (default ``(0,)``).
    model : bool
        Add the model term ``phi(sat(z_hat), u)`` of Gauthier et al. (needs a system).
    method : {"exact", "euler", "rk4"}
        How one sample is advanced (see :func:`one_step_map`): ``exact`` is the sampled-data
        observer (chain propagated exactly, pole-matched correction, stable for every period;
        the model term, if any, held at its start-of-sample value); ``euler`` and ``rk4``
        integrate the continuous observer with the measurement held (``rk4`` with the model
        term evaluates ``phi`` at every stage).
    z_bounds : (array_like, array_like), optional
        Saturation of the estimate against peaking (Khalil, sec. 14.5): the reported
        ``z_hat``/``x_hat`` and the argument of the model term are clipped to these bounds;
        the observer's own state is not.
    x_hat0, z_hat0 : array_like, optional
        Initial estimate in physical or observer coordinates, ``(n_x,)`` / ``(n,)`` (default
        zero): what :meth:`reset` starts from when given nothing.
    on_unstable : {"raise", "warn", "ignore"}
        What to do when the chosen ``method`` and sample period give a one-step error map of
        spectral radius >= 1 (a high gain with a too-long period): the message states the
        largest stable period.

    Attributes
    ----------
    k_ : float
        The gain (constant here; the adaptive observer changes it), the diagnostic ``k``.

    Notes
    -----
    Sensitivity (paper 000, eq. 3, binomial ``p``): ``e_1(s) = w(s)/(s+k)^n +
    s^n/(s+k)^n nu(s)``: a larger ``k`` rejects the unmodelled ``phi`` better and passes the
    measurement noise ``nu`` with gain ``k^(i-1)`` into the ``i``-th estimate.

    Cost: model-free, a block of T samples of B members is one compiled call
    (:func:`affine_advance`); with the model term the samples loop in Python (the system
    evaluates ``phi`` on the B rows before each sample, or at every RK4 stage).

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.observers import HighGainObserver
    >>> ob = HighGainObserver(order=2, k=10.0, z_hat0=[1.0, 2.0])
    >>> ob.update(np.array([np.nan]), np.zeros(0), 0.1)  # a dropout: open-loop prediction
    array([1.2, 2. ])

    References
    ----------
    Paper 000 (Bullinger, Ilchmann, Allgöwer 1998), eq. 2, 3, 6; Tornambè 1992; Gauthier,
    Hammouri, Othman 1992; Khalil, *Nonlinear Systems*, sec. 14.5.
    """

    name = "high_gain"
    summary = "Tornambè high-gain observer, gains p_i k^i, optional model term and saturation"
    reference = "paper 000 (Bullinger et al. 1998), eq. 2, 3, 6"
    family_diagnostics = ("k",)

    def __init__(self, system: System | None = None, *, k: float, p: Any = None,
                 order: int | None = None, outputs: Any = (0,), model: bool = False,
                 method: str = "exact", z_bounds: Any = None, x_hat0: Any = None,
                 z_hat0: Any = None, on_unstable: str = "raise") -> None:
        super().__init__(system, order=order, outputs=outputs, on_unstable=on_unstable)
        if len(self.outputs) != 1:
            raise DesignError(f"{type(self).__name__} reads one output: outputs must be a "
                              f"1-tuple such as (0,); found {list(self.outputs)}")
        n = self.n
        self.p = binomial_coefficients(n) if p is None else check_hurwitz(p)
        if self.p.size != n:
            raise DimensionError(f"p must have n = {n} coefficients; found {self.p.size}")
        self.k_ = finite_scalar("k", k, positive=True)
        check_options(method, on_unstable, model, system)
        self.model = boolean("model", model)
        self.method = method
        self.z_bounds = bounds_pair(z_bounds, n)
        hgo_gains(self.p, self.k_)  # the gains must be finite numbers (a huge k is refused)
        if x_hat0 is not None and z_hat0 is not None:
            raise DesignError("give x_hat0 or z_hat0, not both")
        self._start = (None if x_hat0 is None else vector("x_hat0", x_hat0, len(self.state_names)),
                       None if z_hat0 is None else vector("z_hat0", z_hat0, n))
        #: ``x_hat`` is ``z_hat`` itself (no system, or a system whose normal form is its state)
        self._identity = system is None or _is_identity(system, n)
        # x_hat is the system's state (from_normal), or z_hat: its names must fit it
        self._check_width(n if system is None else len(system.state_names),
                          len(self.state_names))
        self._layout((n,), self.z_bounds)

    def _parameters(self) -> dict[str, Any]:
        """The gain ``k`` and the Hurwitz coefficients ``p`` (paper 000, eq. 2-3)."""
        return {"k": self.k_, "p": self.p}

    def tuning_space(self) -> dict[str, Dimension]:
        """The gain ``k`` over ``[k / 10, 100 k]`` on a log scale: a high gain trades the
        rejection of the unmodelled ``phi`` against noise amplified by ``k^(i-1)`` in the
        ``i``-th estimate (paper 000, eq. 3), so the optimum is often well above a hand-set
        ``k``. (``p`` stays as given: a search over Hurwitz polynomials is not declared.)"""
        k = self.k_
        return {"k": Dimension("k", k / 10.0, k * 100.0, True, k)}

    def _check_parameter(self, name: str, value: Any) -> Array:
        if name == "k":
            k = finite_scalar("k", value, positive=True)
            hgo_gains(self.p, k)  # a huge k is refused as the constructor refuses it
            return np.array(k)
        arr = check_hurwitz(value)
        if arr.size != self.n:
            raise DimensionError(f"p must have n = {self.n} coefficients; found {arr.size}")
        return arr

    # ------------------------------------------------------------------ setup
    def max_stable_period(self) -> float:
        """Largest sample period for which ``method``'s one-step error map is stable.

        Returns
        -------
        float
            Seconds; ``inf`` for ``method="exact"`` (stable for every period).

        Examples
        --------
        >>> round(HighGainObserver(order=2, k=10.0, method="euler").max_stable_period(), 6)
        0.2
        >>> HighGainObserver(order=2, k=10.0).max_stable_period()
        inf
        """
        return self._max_period(self.p, self.k_)

    def _max_period(self, p: Array, k: float) -> float:
        if self.method == "exact":
            return float("inf")
        return largest_stable_step(lambda dt: one_step_map(p, k, dt, self.method)[0],
                                   1e-3 / k, 1e6 / k)

    def _chain_maps(self, p: Params, dt: float) -> list[tuple[Array, Array, Array, Array, Array]]:
        k, pc = float(p.k), np.asarray(p.p)
        M, b, g = one_step_map(pc, k, dt, self.method)
        check_step_stable(M, self.on_unstable,
                          f"{self.method} update of the high-gain observer (n={self.n}, k={k:g})",
                          dt, lambda: self._max_period(pc, k), digits=6)
        M0, _, g0 = one_step_map(pc, k, dt, self.method, closed=False)  # dropout
        return [(M, b, g, M0, g0)]

    # ------------------------------------------------------------- the family
    def _init(self, p: Params, x0: Array | None, z0: Array | None,
              u0: Array) -> dict[str, Any]:
        B = u0.shape[0]
        if x0 is None and z0 is None:
            ix, iz = self._start
            x0 = None if ix is None else batch_rows("x_hat0", ix, ix.size, B)
            z0 = None if iz is None else batch_rows("z_hat0", iz, iz.size, B)
        fields: dict[str, Any] = {"z": np.array(self._initial_z(x0, z0, u0), dtype=float,
                                                order="C")}
        if not self._identity:
            s = State(**self._core(B))
            X = np.empty((B, 1, len(self.state_names)))
            self._to_physical(s, self._sat(fields["z"])[:, None], u0[:, None], X)
            fields.update(s.fields)
        return fields

    def _step(self, p: Params, s: State, Y: Array, U: Array, dt: float, X: Array, Z: Array,
              D: Array) -> None:
        maps = self._maps.get((dt, p.key()))
        if maps is None:
            maps = self._maps_at(p, dt)
        T = Y.shape[1]
        if not self.model:
            self._kernel(s.z, Y, None, maps, 0, T, Z)
        elif self.method != "rk4":
            phi = self.system.phi_batch  # type: ignore[union-attr]
            if T == 1:  # one sample: phi's rows are the held term as they come
                W = np.ascontiguousarray(phi(self._sat(s.z), U[:, 0]),
                                         dtype=np.float64).reshape(Y.shape[0], 1, 1)
                self._kernel(s.z, Y, W, maps, 0, 1, Z)
            else:
                W = np.empty((Y.shape[0], T, 1))
                for j in range(T):  # phi at the start of the sample, held over it
                    W[:, j, 0] = phi(self._sat(s.z), U[:, j])
                    self._kernel(s.z, Y, W, maps, j, j + 1, Z)
        else:
            L = hgo_gains(np.asarray(p.p), float(p.k))
            for j in range(T):
                self._rk4_model(s.z, L, Y, U, dt, maps, j, Z)
        D[...] = float(p.k)
        if self._identity:
            np.copyto(X, Z)
        elif T:
            self._to_physical(s, Z, U, X)

    def _rk4_model(self, Z: Array, L: Array, Y: Array, U: Array, dt: float, maps: Array,
                   j: int, Zout: Array) -> None:
        """Sample ``j`` by RK4 of the continuous observer with ``phi`` at every stage, ``Z``
        in place; members whose measurement is NaN take the open-loop map with ``phi`` held
        (the kernel)."""
        phi = self.system.phi_batch  # type: ignore[union-attr]
        y = Y[:, j, 0]
        lost = np.isnan(y)
        if lost.any():
            rows = np.flatnonzero(lost)
            Zl = Z[rows]
            W = phi(self._sat(Zl), U[rows, j]).reshape(-1, 1, 1)
            Zo = np.empty((rows.size, 1, self.n))
            self._kernel(Zl, np.ascontiguousarray(Y[rows, j:j + 1]), W, maps, 0, 1, Zo)
            Z[rows] = Zl
        ok = np.flatnonzero(~lost)
        if ok.size:
            Uo, yo = U[ok, j], y[ok, None]

            def rhs(z: Array) -> Array:
                dz = np.empty_like(z)
                dz[:, :-1] = z[:, 1:]
                dz[:, -1] = phi(self._sat(z), Uo)
                return dz + L * (yo - z[:, :1])

            Z[ok] = rk4(rhs, Z[ok], dt)
        Zout[:, j] = self._sat(Z)

    def _sat(self, z: Array) -> Array:
        """``z`` clipped to ``z_bounds`` (a new array), or ``z`` itself without bounds."""
        if self.z_bounds is None:
            return z
        return np.clip(z, self.z_bounds[0], self.z_bounds[1])

    def _current(self, p: Params, s: State) -> tuple[Array, Array, Array]:
        z = self._sat(s.z)
        z = z.copy() if z is s.z else z
        k = np.empty((z.shape[0], 1))
        k.fill(float(p.k))  # np.full's values, without its Python-level wrapper
        return (z.copy() if self._identity else s.x_held.copy(), z, k)

    def params(self) -> dict[str, Any]:
        return {"k": self.k_, "p": self.p.tolist(), "order": self.n,
                "outputs": list(self.outputs), "model": self.model, "method": self.method,
                "z_bounds": None if self.z_bounds is None else [b.tolist() for b in self.z_bounds]}


def _is_identity(system: System, n: int) -> bool:
    """Whether ``system.from_normal_unchecked`` hands ``z`` back as it is (the normal form is
    the state, as for the one-joint MuJoCo systems): then ``x_hat = z_hat`` without the map."""
    probe = np.zeros(n)
    try:
        return system.from_normal_unchecked(probe, np.zeros(len(system.input_names))) is probe
    except Exception:  # noqa: BLE001 - a map that cannot take the probe is not the identity
        return False


def _per_chain(name: str, value: Any, m: int) -> list[Any]:
    """A scalar (or None) for every chain, or a sequence with one entry per chain."""
    if value is None or np.ndim(value) == 0:
        return [value] * m
    seq = list(value)
    if len(seq) != m:
        raise DimensionError(f"{name} must be a scalar or have one entry per chain ({m}); "
                             f"found {len(seq)} entries")
    return seq


def _chain_orders(cls: str, system: Any, orders: Any) -> tuple[int, ...]:
    """The chain orders of a multi-output observer: given, or the system's
    ``normal_form_orders``, or its single-output normal form (one chain)."""
    if system is not None and not isinstance(system, System):
        raise DesignError(f"system must be a System instance or None; found "
                          f"{type(system).__name__}")
    if orders is None and system is not None:
        orders = getattr(system, "normal_form_orders", None)
        if orders is None and system.normal_form_order is not None:
            orders = (system.normal_form_order,)
    if orders is None:
        where = "" if system is None else f" for {type(system).__name__}"
        problem = getattr(system, "normal_form_problem", None)
        raise DesignError(f"{cls} needs orders=[n_1, n_2, ...]{where} (one chain order per "
                          f"output)" + (f": {problem}" if problem else ""))
    orders = [orders] if np.ndim(orders) == 0 else list(orders)
    if not orders or any(isinstance(o, bool) or int(o) != o or o < 1 for o in orders):
        raise DesignError(f"orders must be positive integers, one per chain; found {orders!r}")
    return tuple(int(o) for o in orders)


@register
class MultiOutputHighGainObserver(_Chains, Observer):
    """One high-gain chain per measured output (paper 001, eq. 5), model-free by default.

    Chain ``c`` of order ``n_c`` estimates ``z[c] = (y_c, y_c', ..., y_c^(n_c - 1))`` from the
    measured channel ``outputs[c]`` with the gains of paper 000, eq. 2 (its own ``k_c``,
    ``p_c``):

    .. math::

        \\dot{\\hat z}_{c,i} &= \\hat z_{c,i+1} + p_{c,i} k_c^i (y_c - \\hat z_{c,1}),
            \\quad i = 1, \\dots, n_c - 1 \\\\
        \\dot{\\hat z}_{c,n_c} &= p_{c,n_c} k_c^{n_c} (y_c - \\hat z_{c,1})
            + [\\varphi_c(\\hat z, u)]

    This is the block structure of paper 001, eq. 5 (block-diagonal ``A = diag(A_1, A_2, ...)``,
    ``C = diag(C_1, C_2, ...)``), with the observer of eq. 4 designed for each block
    (``lambda Lambda^-1 K_0 = (p_i k^i)``). The coupling between the chains (eq. 5 lets the
    last component of ``phi_c`` depend on the other blocks) enters only through the optional
    model term ``phi(z_hat, u)``, which returns the chains' top derivatives
    ``(phi_1, phi_2, ...)``. Without it the chains are independent: each is exactly a
    :class:`HighGainObserver` on its own channel, and only the orders need to be known
    (paper 000's point).

    **Estimate.** Model-free, what can be had is ``z_hat`` itself: the outputs and their
    derivatives, so ``x_hat = z_hat`` with :attr:`state_names` derived from the output names
    (``link1_angle, link1_velocity, link1_acceleration, link1_jerk, link2_angle, ...`` for the
    two-link elastic arm with ``orders=(4, 4)``). These are *not* the plant's state columns
    (the motor angles and velocities need the model's inverse map); on the two-link arm the
    link angles and velocities coincide with plant states by name. ``Trajectory.error``
    matches columns by name: the plant states this observer does not estimate (the motor
    angles and velocities) are NaN there, "not estimated" in the metrics.

    Parameters
    ----------
    system : System, optional
        Names the outputs (for :attr:`state_names`) and bounds the channel indices. A system
        may declare ``normal_form_orders``; otherwise ``orders`` is needed unless the system has
        a single-output normal form (then one chain of that order).
    k : float or sequence of float
        High-gain parameter of every chain, or one per chain (each > 0).
    orders : sequence of int, optional
        Order ``n_c`` of each chain (the relative degree of output ``c``).
    p : array_like or sequence of array_like, optional
        Hurwitz coefficients: ``None`` (binomial, ``(s + 1)^n_c``), one array used for every
        chain (all of that order), or one array (or ``None``) per chain.
    outputs : tuple of int, optional
        Measured channel of each chain (default: the system's ``normal_form_outputs`` where it
        declares them, else ``(0, 1, ...)``), distinct.
    model : bool
        Use the system's model term ``chain_phi`` as ``phi`` (the MJCF systems of
        :mod:`hgo_mj.systems.mjcf`: MuJoCo's forward dynamics at the estimate).
    phi : callable ``phi(z_hat, u) -> array`` of length ``len(orders)``, optional
        Model term: the chains' top derivatives, evaluated at the full ``z_hat`` (chains
        concatenated in order). With ``exact`` and ``euler`` it is held at its start-of-sample
        value over the sample; ``rk4`` evaluates it at every stage.
    method : {"exact", "euler", "rk4"}
        As in :class:`HighGainObserver` (see :func:`one_step_map`), for every chain.
    z_hat0 : array_like, optional
        Initial estimate, length ``sum(orders)`` (default zero); ``x_hat0`` is the same thing
        (``x_hat = z_hat``); give one of them.
    x_hat0 : array_like, optional
        The same as ``z_hat0`` (the estimate is ``z_hat`` itself); not together with it.
    on_unstable : {"raise", "warn", "ignore"}
        What to do when a chain's one-step map at the sample period is unstable.

    Attributes
    ----------
    dropouts_ : int or (B,) int array
        Samples at which at least one channel was NaN.
    channel_dropouts_ : list of int, or (B, len(orders)) int array when batched
        NaN samples per chain; a chain whose channel is NaN runs open loop over that sample
        while the others correct as usual.

    Notes
    -----
    Without ``phi`` (and with ``phi`` under ``exact``/``euler``, ``phi`` then evaluated in
    Python per member before each sample), the chains advance in :func:`affine_advance`,
    each with its own maps and its own dropout choice. With ``phi`` and ``rk4``, RK4 of the
    coupled observer runs in numpy over the B members (``phi`` called per member and stage).

    References
    ----------
    Paper 001 (Besançon, Zhang, Hammouri 2004), eq. 4 (high-gain observer) and eq. 5
    (two-output block structure, after Besançon and Hammouri 1998); paper 000, eq. 2 (gains
    ``p_i k^i``).

    Examples
    --------
    >>> import numpy as np
    >>> obs = MultiOutputHighGainObserver(k=[10.0, 20.0], orders=(2, 1))
    >>> obs.state_names
    ('y1', 'y1_d1', 'y2')
    >>> obs.update(np.array([1.0, np.nan]), np.zeros(0), 0.01).round(4)  # chain 2: dropout
    array([0.1903, 0.9056, 0.    ])
    >>> obs.channel_dropouts_
    [0, 1]
    """

    name = "high_gain_multi"

    @classmethod
    def applicability(cls, system: System) -> str | None:
        """Applies where the system gives the chain orders: ``normal_form_orders`` (one chain
        per measured output, paper 001, eq. 5) or a single-output normal form."""
        if (getattr(system, "normal_form_orders", None) is None
                and system.normal_form_order is None):
            return getattr(system, "normal_form_problem", None) or (
                f"needs the chain orders (paper 001, eq. 5): {type(system).__name__} declares "
                f"no normal_form_orders and no single-output normal form; give orders=[...]")
        return None
    summary = "one Tornambè chain per output (paper 001 eq. 5), per-chain order/k/p, optional coupling"
    reference = "paper 001 (Besançon et al. 2004), eq. 4-5; paper 000, eq. 2"
    family_diagnostics = ()
    needs_normal_form = False

    def __init__(self, system: System | None = None, *, k: Any, orders: Any = None,
                 p: Any = None, outputs: Any = None,
                 phi: Callable[[Array, Array], Any] | None = None, model: bool = False,
                 method: str = "exact", z_hat0: Any = None, x_hat0: Any = None,
                 on_unstable: str = "raise") -> None:
        self.orders = _chain_orders(type(self).__name__, system, orders)
        m = len(self.orders)
        if outputs is None:  # the system's chain outputs (MJCF systems), else 0, 1, ...
            outputs = getattr(system, "normal_form_outputs", None) or tuple(range(m))
        super().__init__(system, order=sum(self.orders), outputs=outputs,
                         on_unstable=on_unstable)
        if not isinstance(model, bool):
            raise DesignError(f"model must be true or false; found {model!r} "
                              f"({type(model).__name__})")
        if model:
            if phi is not None:
                raise DesignError("give phi= or model=true (the system's chain_phi), not both")
            phi = getattr(system, "chain_phi", None)
            if phi is None:
                raise DesignError(f"model=true needs a system with chain_phi (an MJCF system "
                                  f"whose joints are all measured); found "
                                  f"{type(system).__name__}")
        if len(self.outputs) != m:
            raise DimensionError(f"outputs must name one channel per chain ({m}); found "
                                 f"{len(self.outputs)}")
        ks = _per_chain("k", k, m)
        self.ks = tuple(finite_scalar(f"k[{c}]" if m > 1 else "k", kc, positive=True)
                        for c, kc in enumerate(ks))
        self.ps = self._chain_p(p)
        check_options(method, on_unstable)
        if phi is not None and not callable(phi):
            raise DesignError(f"phi must be a callable phi(z_hat, u) or None; found "
                              f"{type(phi).__name__}")
        self.phi = phi
        self.method = method
        for pc, kc in zip(self.ps, self.ks):
            hgo_gains(pc, kc)  # the gains must be finite numbers (a huge k is refused)
        if x_hat0 is not None and z_hat0 is not None:
            raise DesignError("give x_hat0 or z_hat0 (the same thing here), not both")
        z0 = z_hat0 if z_hat0 is not None else x_hat0
        self._start = None if z0 is None else vector("z_hat0", z0, self.n)
        self._layout(self.orders, None)

    def _parameters(self) -> dict[str, Any]:
        """The gain of each chain, ``k`` ``(len(orders),)`` (paper 001, eq. 5)."""
        return {"k": np.array(self.ks)}

    def tuning_space(self) -> dict[str, Dimension]:
        """Each chain's gain ``k[c]`` over ``[k_c / 10, 100 k_c]``, log scale (as
        :meth:`HighGainObserver.tuning_space`)."""
        return {f"k[{c}]": Dimension(f"k[{c}]", k / 10.0, k * 100.0, True, k)
                for c, k in enumerate(self.ks)}

    def _check_parameter(self, name: str, value: Any) -> Array:
        ks = _per_chain("k", value, len(self.orders))
        return np.array([finite_scalar(f"k[{c}]", kc, positive=True) for c, kc in enumerate(ks)])

    def _chain_p(self, p: Any) -> tuple[Array, ...]:
        m = len(self.orders)
        if p is None:
            per: list[Any] = [None] * m
        elif all(v is not None and np.ndim(v) == 0 for v in p):
            per = [p] * m  # one polynomial for every chain
        else:
            per = list(p)
            if len(per) != m:
                raise DimensionError(f"p must be one array for every chain or one per chain "
                                     f"({m}); found {len(per)} entries")
        out = []
        for c, (n, pc) in enumerate(zip(self.orders, per)):
            arr = binomial_coefficients(n) if pc is None else check_hurwitz(pc, f"p[{c}]")
            if arr.size != n:
                raise DimensionError(f"p[{c}] must have n_{c} = {n} coefficients (chain order); "
                                     f"found {arr.size}")
            out.append(arr)
        return tuple(out)

    # ------------------------------------------------------------------ naming
    @property
    def output_names(self) -> tuple[str, ...]:
        """Names of the measured channels the chains use."""
        if self.system is None:
            return tuple(f"y{o + 1}" for o in self.outputs)
        return tuple(self.system.output_names[o] for o in self.outputs)

    @property
    def state_names(self) -> tuple[str, ...]:
        """Names of ``z_hat`` (= ``x_hat``), chain after chain: each output and its derivatives."""
        return tuple(name for out, n in zip(self.output_names, self.orders)
                     for name in derivative_names(out, n))

    # ------------------------------------------------------------------ setup
    def max_stable_period(self) -> float:
        """Largest sample period at which every chain's one-step map is stable.

        Returns
        -------
        float
            Seconds, the smallest over the chains; ``inf`` for ``method="exact"``.

        Examples
        --------
        >>> obs = MultiOutputHighGainObserver(k=10.0, orders=(2, 2), method="euler")
        >>> round(obs.max_stable_period(), 6)
        0.2
        """
        return self._max_period(self.ks)

    def _max_period(self, ks: Any) -> float:
        return min(HighGainObserver(order=n, k=float(kc), p=pc, method=self.method,
                                    on_unstable="ignore").max_stable_period()
                   for n, kc, pc in zip(self.orders, ks, self.ps))

    def _chain_maps(self, p: Params, dt: float) -> list[tuple[Array, Array, Array, Array, Array]]:
        entries = []
        ks = [float(v) for v in p.k]
        for c, (n, kc, pc) in enumerate(zip(self.orders, ks, self.ps)):
            M, b, g = one_step_map(pc, kc, dt, self.method)
            check_step_stable(M, self.on_unstable,
                              f"{self.method} update of chain {c} ({self.output_names[c]}, n={n}, "
                              f"k={kc:g}) of the multi-output high-gain observer", dt,
                              lambda: self._max_period(ks))
            M0, _, g0 = one_step_map(pc, kc, dt, self.method, closed=False)
            entries.append((M, b, g, M0, g0))
        return entries

    # ------------------------------------------------------------- the family
    @property
    def channel_dropouts_(self) -> Any:
        """NaN samples per chain: a list of ints (unbatched) or a ``(B, len(orders))`` array."""
        drops = self.state.channel_dropouts
        if self._batched:
            return drops.copy()
        return [int(v) for v in drops[0]]

    def predicted_output(self, x_hat: Array, z_hat: Array) -> Array | None:
        """The first entry of each chain: the measured outputs (paper 001, eq. 5)."""
        return z_hat[..., self._lay[:, 0]]

    def _init(self, p: Params, x0: Array | None, z0: Array | None,
              u0: Array) -> dict[str, Any]:
        B = u0.shape[0]
        z = x0 if x0 is not None else z0
        if z is None:
            z = np.zeros((B, self.n)) if self._start is None else np.tile(self._start, (B, 1))
        return {"z": np.array(z, dtype=float, order="C"),
                "channel_dropouts": np.zeros((B, len(self.orders)), dtype=np.int64)}

    def _step(self, p: Params, s: State, Y: Array, U: Array, dt: float, X: Array, Z: Array,
              D: Array) -> None:
        maps = self._maps_at(p, dt)
        B, T = Y.shape[0], Y.shape[1]
        s.channel_dropouts += np.isnan(Y).sum(axis=1)
        if self.phi is None:
            self._kernel(s.z, Y, None, maps, 0, T, Z)
        elif self.method != "rk4":
            W = np.empty((B, T, len(self.orders)))
            for j in range(T):  # phi at the start of the sample, held over it
                W[:, j] = self._phi_rows(s.z, U[:, j])
                self._kernel(s.z, Y, W, maps, j, j + 1, Z)
        else:
            L = [hgo_gains(pc, float(kc)) for pc, kc in zip(self.ps, p.k)]
            for j in range(T):
                s.z = self._rk4_model(s.z, L, Y[:, j], U[:, j], dt)
                Z[:, j] = s.z
        X[...] = Z

    def _phi_rows(self, Z: Array, U: Array) -> Array:
        """``phi(z_hat, u)`` of every member ``(B, len(orders))``: one call of the system's
        ``chain_phi_batch`` for a batch with the model term (MJCF systems), else one Python
        call per row."""
        batch_phi = getattr(self.system, "chain_phi_batch", None)
        if Z.shape[0] > 1 and batch_phi is not None and self.phi == getattr(
                self.system, "chain_phi", None):
            return batch_phi(Z, U)  # type: ignore[no-any-return]
        out = np.empty((Z.shape[0], len(self.orders)))
        for b in range(Z.shape[0]):
            ph = np.asarray(self.phi(Z[b].copy(), U[b]), dtype=float).reshape(-1)  # type: ignore[misc,type-var]
            if ph.shape != (len(self.orders),):
                raise DimensionError(f"phi(z_hat, u) must return one top derivative per chain "
                                     f"({len(self.orders)}); found shape {ph.shape}")
            out[b] = ph
        return out

    def _rk4_model(self, z: Array, L: list[Array], y: Array, u: Array, dt: float) -> Array:
        """One sample by RK4 of the coupled observer from ``z``, ``phi`` at every stage; a
        chain whose channel is NaN runs open loop (no correction) over it."""
        n = self.n
        first, size = self._lay[:, 0], self._lay[:, 1]
        top = first + size - 1
        inner = np.setdiff1d(np.arange(n), top)  # z_i' = z_{i+1} inside a chain
        chain_of = np.repeat(np.arange(len(self.orders)), self.orders)
        lost = np.isnan(y)
        Lfull = np.zeros((y.shape[0], n))
        for c, (f, nc) in enumerate(zip(first, size)):
            Lfull[:, f:f + nc] = np.where(lost[:, c:c + 1], 0.0, L[c])
        yv = np.where(lost, 0.0, y)

        def rhs(z: Array) -> Array:
            dz = np.zeros_like(z)
            dz[:, inner] = z[:, inner + 1]
            dz[:, top] += self._phi_rows(z, u)
            return dz + Lfull * (yv - z[:, first])[:, chain_of]

        return np.ascontiguousarray(rk4(rhs, z, dt))

    def _current(self, p: Params, s: State) -> tuple[Array, Array, Array]:
        """``x_hat = z_hat`` (model-free: outputs and derivatives, see the class docstring)."""
        return s.z.copy(), s.z.copy(), np.zeros((s.z.shape[0], 0))

    def params(self) -> dict[str, Any]:
        return {"k": list(self.ks), "orders": list(self.orders),
                "p": [pc.tolist() for pc in self.ps], "outputs": list(self.outputs),
                "phi": None if self.phi is None else getattr(self.phi, "__name__", repr(self.phi)),
                "method": self.method, "state_names": list(self.state_names)}
