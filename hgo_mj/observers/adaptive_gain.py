"""The adaptive-gain high-gain observer of Bullinger, Ilchmann and Allgöwer (paper 000).

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
from collections.abc import Callable
from functools import lru_cache
from math import comb
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._validate import finite_scalar
from ..design import binomial_coefficients, check_hurwitz
from ..exceptions import DesignError, DimensionError, DivergenceError
from ..systems.base import System
from .base import Array, Observer
from .high_gain import (
    _is_identity,
    affine_step,
    bounds_floats,
    bounds_pair,
    check_options,
    clip_floats,
    largest_stable_step,
    one_step_map,
    sampled_chain,
)


def dead_zone(e: ArrayLike, lam: float, lam_hat: float) -> Array:
    """The dead zone :math:`d_{\\lambda, \\hat\\lambda}(e)` of paper 000, eq. 5 (vectorized).

    ``0`` inside ``|e| <= lam``, ``|e| - lam`` up to ``lam_hat``, then constant ``lam_hat - lam``:
    the adaptation rate ``gamma d^2`` is bounded by ``gamma (lam_hat - lam)^2``.
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


# ------------------------------------------------------------------ code generation
def _dead_zone_lines(q: str, lam: float, lam_hat: float, gamma: float) -> list[str]:
    """Plain-float lines computing ``q = gamma d(e)^2`` from the local ``e``."""
    return ["    a = e if e >= 0.0 else -e",
            f"    if a > {lam!r}:",
            f"        d = a - {lam!r} if a < {lam_hat!r} else {lam_hat - lam!r}",
            f"        {q} = {gamma!r} * d * d",
            "    else:",
            f"        {q} = 0.0"]


def _flow_source(p: Array, dt: float, method: str, lam: float, lam_hat: float, gamma: float,
                 model: bool, held: bool = False) -> str:
    """``step(y, k, z0, ..., [f | w]) -> (k+, z0+, ...)``: euler or rk4 of the joint ODE in
    ``(k, z)`` with ``y`` held, unrolled into plain-float statements. With ``model`` the last
    derivative adds ``f(z0, ..., z_{n-1})`` at every stage; with ``held`` (euler) the model
    term's value ``w``, held over the sample, is added as ``+ dt w`` to the last state (after
    the rest of its update, so the sums are those of adding ``dt B w`` afterwards)."""
    n = p.size
    zs = [f"z{i}" for i in range(n)]
    args = ", ".join(["y", "k", *zs] + (["f"] if model else []) + (["w"] if held else []))
    lines = [f"def step({args}):"]
    stages = [("s1", None, 0.0)] if method == "euler" else [
        ("s1", None, 0.0), ("s2", "s1", dt / 2), ("s3", "s2", dt / 2), ("s4", "s3", dt)]
    for tag, prev, h in stages:
        if prev is None:
            kk, zz = "k", zs
        else:  # stage input: state + h * previous derivative
            kk = f"k_{tag}"
            lines.append(f"    {kk} = k + {h!r} * q_{prev}")
            zz = [f"{z}_{tag}" for z in zs]
            lines += [f"    {zz[i]} = {zs[i]} + {h!r} * d{i}_{prev}" for i in range(n)]
        lines.append(f"    e = y - {zz[0]}")
        lines += _dead_zone_lines(f"q_{tag}", lam, lam_hat, gamma)
        lines.append(f"    t = {kk} * e")  # t = k^i e, built up
        for i in range(n):
            if i:
                lines.append(f"    t = t * {kk}")
            nxt = f"{zz[i + 1]} + " if i < n - 1 else ""
            extra = f" + f({', '.join(zz)})" if (model and i == n - 1) else ""
            gain = "t" if p[i] == 1.0 else f"{float(p[i])!r} * t"
            lines.append(f"    d{i}_{tag} = {nxt}{gain}{extra}")
    if method == "euler":
        out = [f"k + {dt!r} * q_s1"] + [f"{zs[i]} + {dt!r} * d{i}_s1" for i in range(n)]
        if held:
            out[-1] += f" + {dt!r} * w"
    else:
        h6 = dt / 6.0

        def comb(v: str) -> str:
            return f"{h6!r} * ({v}_s1 + 2.0 * ({v}_s2 + {v}_s3) + {v}_s4)"

        out = [f"k + {comb('q')}"] + [f"{zs[i]} + {comb(f'd{i}')}" for i in range(n)]
    lines.append(f"    return ({', '.join(out)},)")
    return "\n".join(lines) + "\n"


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


def _exact_source(p: Array, dt: float, lam: float, lam_hat: float, gamma: float,
                  g: Array | None = None) -> str:
    """``step(y, k, z0, ..., [w])``: the sampled-data observer at gain ``k`` plus the adaptation
    of ``k`` with the sampled innovation held (see :class:`AdaptiveGainObserver`, ``exact``).
    With ``g``, the held model term ``w`` enters as ``+ g w``, added last to each row.

    The pole-matched gain of :func:`~hgo_mj.observers.high_gain.matched_gain` is linear in the
    coefficients ``c_j`` of ``prod_i (w - w_i)``, ``w_i = expm1(k dt r_i)`` (Ackermann: the
    ``N^n`` term vanishes, ``N = Phi - I`` being nilpotent): ``Ld = W c`` with ``W`` fixed for a
    given ``dt``. Only the ``c_j`` depend on ``k``; they are expanded here into plain floats.
    """
    n = p.size
    N = sampled_chain(n, 1.0)[0] - np.eye(n)
    obs = np.array([np.linalg.matrix_power(N, i)[0] for i in range(n)])
    en = np.zeros(n)
    en[-1] = 1.0
    v = np.linalg.solve(obs, en)
    # W[:, j-1] = N^(n-j) v / dt^i, j = 1..n
    W = np.column_stack([np.linalg.matrix_power(N, n - j) @ v for j in range(1, n + 1)])
    W[np.abs(W) < 1e-12 * np.abs(W).max(axis=1, keepdims=True)] = 0.0  # round-off of exact zeros
    W = W / (dt ** np.arange(n))[:, None]
    Phi = sampled_chain(n, dt)[0]
    zs = [f"z{i}" for i in range(n)]
    extra = "" if g is None else ", w"
    lines = [f"def step(y, k, {', '.join(zs)}{extra}):", "    e = y - z0", f"    tau = k * {dt!r}"]
    r = -p[0] / n
    if np.allclose(p, [comb(n, i) * (-r) ** i for i in range(1, n + 1)], rtol=1e-13, atol=0.0):
        # one root of multiplicity n (the default binomial p): prod (w - w_0)^n, one expm1,
        # and no numerically split roots
        lines += [f"    m = -expm1(tau * {float(r)!r})", "    c1 = m" if n == 1 else
                  f"    c1 = {float(n)!r} * m"]
        coef = ["1.0", "c1"]
        for j in range(2, n + 1):
            lines += [f"    mp{j} = {'m' if j == 2 else f'mp{j - 1}'} * m",
                      f"    c{j} = {float(comb(n, j))!r} * mp{j}"]
            coef.append(f"c{j}")
        return _exact_tail(lines, coef, W, Phi, zs, dt, lam, lam_hat, gamma, g)
    real, pairs = _root_groups(p)
    factors: list[list[str]] = []
    for i, r in enumerate(real):
        lines.append(f"    w{i} = expm1(tau * {r!r})")
        factors.append([f"(-w{i})"])
    for i, (a, b) in enumerate(pairs):
        lines += [f"    ea{i} = expm1(tau * {a!r})",
                  f"    cb{i} = cos(tau * {b!r})",
                  f"    sb{i} = sin(tau * {b!r})",
                  f"    sh{i} = sin(tau * {b / 2!r})",
                  f"    re{i} = ea{i} * cb{i} - 2.0 * sh{i} * sh{i}",  # Re expm1, no cancellation
                  f"    im{i} = (ea{i} + 1.0) * sb{i}"]
        factors.append([f"(-2.0 * re{i})", f"(re{i} * re{i} + im{i} * im{i})"])
    coef = ["1.0"]  # coefficients of prod (w - w_i), leading first; "1.0" is the constant one
    for fi, f in enumerate(factors):
        full = ["1.0", *f]
        new = ["1.0"]
        for j in range(1, len(coef) + len(full) - 1):
            terms = []
            for a_ in range(len(full)):
                if 0 <= j - a_ < len(coef):
                    x, y_ = full[a_], coef[j - a_]
                    terms.append(x if y_ == "1.0" else y_ if x == "1.0" else f"{x} * {y_}")
            if len(terms) == 1 and fi < len(factors) - 1:
                new.append(terms[0])  # a plain copy: no statement needed
                continue
            name = f"c{fi}_{j}"
            lines.append(f"    {name} = {' + '.join(terms)}")
            new.append(name)
        coef = new
    return _exact_tail(lines, coef, W, Phi, zs, dt, lam, lam_hat, gamma, g)


def _exact_tail(lines: list[str], coef: list[str], W: Array, Phi: Array, zs: list[str],
                dt: float, lam: float, lam_hat: float, gamma: float,
                g: Array | None = None) -> str:
    """The adaptation and ``z+ = Phi z + (W c) e [+ g w]`` of :func:`_exact_source`."""
    n = len(zs)
    lines += _dead_zone_lines("q", lam, lam_hat, gamma)
    out = [f"k + {dt!r} * q"]
    for i in range(n):
        gain = " + ".join(coef[j + 1] if W[i, j] == 1.0 else f"{float(W[i, j])!r} * {coef[j + 1]}"
                          for j in range(n) if W[i, j] != 0.0)
        chain = " + ".join(f"{float(Phi[i, j])!r} * {zs[j]}" if j != i else zs[j]
                           for j in range(i, n))
        held = "" if g is None or g[i] == 0.0 else f" + {float(g[i])!r} * w"
        out.append(f"{chain} + ({gain or '0.0'}) * e{held}")
    lines.append(f"    return ({', '.join(out)},)")
    return "\n".join(lines) + "\n"


def _compile_source(src: str, name: str) -> Callable[..., tuple[float, ...]]:
    scope: dict[str, Any] = {"expm1": math.expm1, "cos": math.cos, "sin": math.sin}
    exec(compile(src, f"<{name}>", "exec"), scope)  # noqa: S102 - numbers only
    return scope["step"]


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
    output : int
        Measured channel used.
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
        current ``k`` or at ``k_max``, and what ``update`` does when ``k`` grows past the
        stable limit during a run (``raise``: :class:`~hgo_mj.exceptions.DivergenceError`;
        ``warn``: once per reset).

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

    **Per-sample cost.** ``update`` runs generated straight-line code in Python floats (no
    numpy in the step); for ``exact`` the pole-matched gain at the current ``k`` is expanded
    in closed form (one ``expm1`` per real root, or one in all for the default binomial ``p``).
    Measured against the plain observer's ``exact`` update (same order, no system, best of
    40 rounds): ``exact`` 1.00-1.09x for n = 2 and 4, ``euler`` 0.9x, ``rk4`` 1.4-1.7x (four
    evaluations of the dead zone and of the powers of ``k``).

    References
    ----------
    Paper 000 (Bullinger, Ilchmann, Allgöwer 1998): eq. 2, eq. 4-5, Theorems 2 and 3 (eq. 14),
    section 4 (bioreactor example, reproduced by ``hgo-mj reproduce bullinger1998``).
    """

    name = "adaptive_gain"
    summary = "high-gain observer whose k adapts by the dead-zone law dk/dt = gamma d(e1)^2"
    reference = "paper 000 (Bullinger et al. 1998), eq. 2, 4-5, Theorems 2-3"
    diagnostic_names = ("k",)

    def __init__(self, system: System | None = None, *, lam: float, lam_hat: float,
                 gamma: float, k0: float, p: Any = None, order: int | None = None,
                 output: int = 0, k_max: float | None = None, model: bool = False,
                 method: str = "exact", z_bounds: Any = None, x_hat0: Any = None,
                 z_hat0: Any = None, on_unstable: str = "raise") -> None:
        super().__init__(system, order, output)
        n = self.n
        self.p = binomial_coefficients(n) if p is None else check_hurwitz(p)
        if self.p.size != n:
            raise DimensionError(f"p must have n = {n} coefficients; found {self.p.size}")
        self.lam = finite_scalar("lam", lam, positive=True)
        self.lam_hat = finite_scalar("lam_hat", lam_hat, positive=True)
        if not self.lam_hat > self.lam:
            raise DesignError(f"lam_hat must be > lam (paper 000, eq. 5: lambda_hat > lambda > 0); "
                              f"found lam_hat={self.lam_hat:g} <= lam={self.lam:g}")
        self.gamma = finite_scalar("gamma", gamma, positive=True)
        self.k0 = finite_scalar("k0", k0, positive=True)
        if k_max is None:
            self.k_max = None
        else:
            self.k_max = finite_scalar("k_max", k_max, positive=True)
            if self.k_max < self.k0:
                raise DesignError(f"k_max must be >= k0; found k_max={self.k_max:g} < "
                                  f"k0={self.k0:g}")
        check_options(method, on_unstable, model, system)
        self.model = bool(model)
        self.method = method
        self.on_unstable = on_unstable
        self.z_bounds = bounds_pair(z_bounds, n)
        self._bounds_floats = bounds_floats(self.z_bounds)
        self._tau_max = _max_stable_kdt(tuple(self.p.tolist()), method)
        #: ``x_hat`` is ``z_hat`` itself (no system, or a normal form that is the state)
        self._identity = system is None or _is_identity(system, n)
        self._plain = self.z_bounds is None and self._identity
        self._steps: dict[float, tuple[Callable, Callable, Callable, float]] = {}
        self._init = (x_hat0, z_hat0)
        self.reset(x_hat0, z_hat0=z_hat0)

    # ------------------------------------------------------------------ state
    @property
    def k_(self) -> float:
        """The current gain ``k(t)``."""
        return self._s[0]

    @property
    def L(self) -> Array:
        """The current output-injection gains ``p_i k^i`` (eq. 2)."""
        return self.p * self.k_ ** np.arange(1, self.n + 1)

    # ------------------------------------------------------------------ setup
    def max_stable_gain(self, dt: float) -> float:
        """Largest ``k`` at which the linear part's one-step map (``method``) at period ``dt``
        is stable: ``tau_max / dt``, ``tau_max`` depending on ``p`` and ``method`` only."""
        return self._tau_max / finite_scalar("dt", dt, positive=True)

    def max_stable_period(self, k: float | None = None) -> float:
        """Largest stable sample period at gain ``k`` (default: the current ``k_``)."""
        k = self.k_ if k is None else finite_scalar("k", k, positive=True)
        return self._tau_max / k

    def check_period(self, dt: float) -> None:
        """Check the linear part's one-step map at the current ``k`` and at ``k_max`` (if given).

        ``k`` only grows, so a period stable now may not stay so: without ``k_max``, ``update``
        checks ``k dt`` against the limit at every sample where ``k`` changed.
        """
        dt = finite_scalar("dt", dt, positive=True)
        self._entry(dt)
        if self.on_unstable == "ignore" or self.method == "exact":
            return
        limit = self.max_stable_gain(dt)
        for what, k in (("the current gain", self.k_), ("k_max", self.k_max)):
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

    def _entry(self, dt: float) -> tuple[Callable, Callable, Callable, float]:
        entry = self._steps.get(dt)
        if entry is not None:
            return entry
        dt = finite_scalar("dt", dt, positive=True)
        M0, _, g0 = one_step_map(self.p, 1.0, dt, self.method, closed=False)  # dropout
        # with the model term held over the sample (exact, euler), the step takes its value
        # as a last argument and adds g0 phi (g0 = S B or dt B) in the same call
        held = self.model and self.method != "rk4"
        if self.method == "exact":
            src = _exact_source(self.p, dt, self.lam, self.lam_hat, self.gamma,
                                g0 if held else None)
        else:
            src = _flow_source(self.p, dt, self.method, self.lam, self.lam_hat, self.gamma,
                               self.model and self.method == "rk4", held)
        step = _compile_source(src, f"adaptive_gain_{self.method}")
        # held model term: s + (0, g) phi with g = S B (exact) or dt B (euler), open or closed
        # loop alike; compiled in plain floats over the whole state s = (k, z)
        g = affine_step(np.eye(self.n + 1), np.concatenate(([0.0], g0)))
        limit = math.inf
        if self.method != "exact" and self.on_unstable != "ignore":
            limit = self._tau_max / dt
        if self.k_max is not None:
            limit = min(limit, self.k_max)
        entry = (step, affine_step(M0, np.zeros(self.n)), g, limit)
        self._steps[dt] = entry
        return entry

    # -------------------------------------------------------------- interface
    def reset(self, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None) -> None:
        """Restart from ``x_hat0``/``z_hat0`` (default: those given to the constructor) and
        ``k = k0``."""
        if x_hat0 is None and z_hat0 is None:
            x_hat0, z_hat0 = self._init
        z = self._initial_z(x_hat0, z_hat0, u0)
        self._s = (self.k0, *(float(v) for v in z))
        self._restart_counters()
        self.k_max_reached_ = False
        self._warned_unstable = False

    def update(self, y: Any, u: Any, dt: float) -> Array:
        """Consume ``y(t_k)``, ``u(t_k)``; integrate ``(z, k)`` over ``dt``; return
        ``x_hat(t_k + dt)``."""
        try:
            yi = float(y[self.output])
        except (IndexError, TypeError):
            raise self._bad_measurement(y, self.output) from None
        self._u = u
        entry = self._steps.get(dt)
        if entry is None:
            self.check_period(dt)
            entry = self._steps[dt]
        step, open_, g, limit = entry
        s = self._s
        if yi - yi != 0.0:  # NaN or inf
            if yi != yi:  # dropout: predict without correction, k held
                self.dropouts_ += 1
                s1 = (s[0], *open_(0.0, *s[1:]))
                self._s = g(self._phi(s[1:], u), *s1) if self.model else s1
                return self.x_hat
            raise DivergenceError(f"measurement y[{self.output}] is {yi}")
        if not self.model:
            s = step(yi, *s)
        elif self.method == "rk4":
            ph_u = self._phi_u(u)
            s = step(yi, *s, ph_u)
        else:  # model term held at its start-of-sample value, added by the step itself
            s = step(yi, *s, self._phi(s[1:], u))
        if s[0] > limit:
            s = self._at_limit(s, dt)
        self._s = s
        if self._plain:  # no saturation, no physical map: x_hat is z_hat
            return np.array(s[1:])
        return self.x_hat

    def _at_limit(self, s: tuple[float, ...], dt: float) -> tuple[float, ...]:
        if self.k_max is not None and s[0] >= self.k_max:
            if not self.k_max_reached_:
                self.k_max_reached_ = True
                warnings.warn(f"adaptive high-gain observer: k reached k_max = {self.k_max:g}; "
                              f"k is held there (the output error is still outside the "
                              f"lam = {self.lam:g} strip: noise larger than lam, or lam too "
                              f"small for this plant)", RuntimeWarning, stacklevel=3)
            s = (self.k_max, *s[1:])
        if (self.method != "exact" and self.on_unstable != "ignore"
                and s[0] >= self._tau_max / dt and not self._warned_unstable):
            self._warned_unstable = True
            self._unstable(
                f"adaptive high-gain observer: k grew to {s[0]:g}, past the largest gain "
                f"{self._tau_max / dt:.4g} at which the {self.method} update with sample period "
                f"{dt:g} is stable (k dt < {self._tau_max:.4g}); use method='exact', a shorter "
                f"period, or k_max below the limit", DivergenceError)
        return s

    def _phi(self, z: tuple[float, ...], u: Any) -> float:
        """The model term in plain floats: the system's unchecked ``phi`` takes the tuple ``z``
        itself (clipped with min/max when ``z_bounds`` is set)."""
        if self.z_bounds is not None:
            z = self._saturate_floats(z)
        return float(self.system.phi_unchecked(z, u))  # type: ignore[union-attr]

    def _phi_u(self, u: Any) -> Callable[..., float]:
        phi = self.system.phi_unchecked  # type: ignore[union-attr]
        if self.z_bounds is None:
            return lambda *z: float(phi(z, u))
        return lambda *z: self._phi(z, u)

    def _saturate_floats(self, z: tuple[float, ...]) -> tuple[float, ...]:
        """:meth:`_saturate` on a tuple of floats, without numpy."""
        return clip_floats(z, self._bounds_floats)  # type: ignore[arg-type]

    def _saturate(self, z: Array) -> Array:
        if self.z_bounds is None:
            return z
        return np.clip(z, self.z_bounds[0], self.z_bounds[1])

    @property
    def z_hat(self) -> Array:
        z = np.array(self._s[1:])
        return z if self.z_bounds is None else self._saturate(z)

    @property
    def x_hat(self) -> Array:
        z = self.z_hat
        return z if self._identity else self._physical(z)

    def diagnostics(self) -> dict[str, float]:
        return {"k": self._s[0], "dropouts": float(self.dropouts_)}

    def params(self) -> dict[str, Any]:
        return {"lam": self.lam, "lam_hat": self.lam_hat, "gamma": self.gamma, "k0": self.k0,
                "k_max": self.k_max, "p": self.p.tolist(), "order": self.n,
                "output": self.output, "model": self.model, "method": self.method,
                "z_bounds": None if self.z_bounds is None else [b.tolist() for b in self.z_bounds]}


__all__ = ["AdaptiveGainObserver", "dead_zone"]
