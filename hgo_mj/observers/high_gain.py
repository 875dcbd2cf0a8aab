"""The high-gain observer of Tornambè (paper 000, eq. 2), optionally with a model term.

.. math::

    \\dot{\\hat z}_i &= \\hat z_{i+1} + p_i k^i (y - \\hat z_1), \\quad i = 1, \\dots, n-1 \\\\
    \\dot{\\hat z}_n &= p_n k^n (y - \\hat z_1) + [\\hat\\varphi(\\mathrm{sat}(\\hat z), u)]

The bracketed model term is off by default (Tornambè's observer is model-free: a chain of
integrators); ``model=True`` adds the system's ``phi`` as in Gauthier, Hammouri and Othman
(1992). The error ``e = z - z_hat`` of the model-free observer obeys the linear dynamics of
paper 000, eq. 6, ``e' = A_k e + B phi(z, u)`` with ``A_k = A - L C``.

References
----------
.. [000] E. Bullinger, A. Ilchmann, F. Allgöwer, "A simple adaptive observer for nonlinear
   systems", NOLCOS 1998, eq. 2 (observer), eq. 3 (noise/disturbance transfer), eq. 6 (error).
.. [T92] A. Tornambè, "High-gain observers for non-linear systems", Int. J. Systems Science
   23(9), 1992.
.. [GHO92] J.P. Gauthier, H. Hammouri, S. Othman, "A simple observer for nonlinear systems:
   applications to bioreactors", IEEE TAC 37(6), 1992 (the model term).
.. [K] H.K. Khalil, *Nonlinear Systems*, 3rd ed., sec. 14.5: saturating the estimate against
   peaking.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from math import factorial
from typing import Any

import numpy as np

from .._validate import finite_scalar, vector
from ..design import binomial_coefficients, check_hurwitz, hgo_gains
from ..exceptions import DesignError, DimensionError, DivergenceError
from ..systems.base import System
from .base import Array, Observer

METHODS = ("exact", "euler", "rk4")


def affine_step(M: Array, b: Array) -> Callable[..., tuple[float, ...]]:
    """Compile ``z -> M z + b y`` into a plain-float function ``step(y, *z)``.

    Observer updates run once per sample; for ``n <= 6`` a generated expression in Python
    floats costs a fraction of a microsecond, against several microseconds for small numpy
    arrays (measured in ``scripts/bench.py``).
    """
    n = len(b)
    zs = [f"z{j}" for j in range(n)]
    rows = []
    for i in range(n):
        terms = [f"{float(M[i, j])!r}*z{j}" for j in range(n) if M[i, j] != 0.0]
        if b[i] != 0.0:
            terms.append(f"{float(b[i])!r}*y")
        rows.append(" + ".join(terms) if terms else "0.0")
    src = f"def step(y, {', '.join(zs)}):\n    return ({', '.join(rows)},)\n"
    scope: dict[str, Any] = {}
    exec(compile(src, "<affine_step>", "exec"), scope)  # noqa: S102 - numbers only
    return scope["step"]


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
    order = 1 if method == "euler" else 4
    M = np.eye(n)
    Sm = np.eye(n) * dt  # sum_{j<order} dt^{j+1} F^j / (j+1)!
    term = np.eye(n)
    for j in range(1, order + 1):
        term = term @ F * dt / j
        M = M + term
        if j < order:
            Sm = Sm + term * dt / (j + 1)
    return M, Sm @ L, Sm @ B


def spectral_radius(M: Array) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(M))))


class HighGainObserver(Observer):
    """High-gain observer of Tornambè (paper 000, eq. 2) on a chain of ``n`` integrators.

    Parameters
    ----------
    system : System, optional
        Gives the order ``n`` (its normal form), the map back to physical coordinates and, with
        ``model=True``, the model term ``phi``. Without a system, give ``order``: the estimate
        is then ``z_hat`` itself.
    k : float
        High-gain parameter (> 0); the observer poles are ``k`` times the roots of ``p``.
    p : array_like, optional
        Hurwitz coefficients ``p_1..p_n``; default binomial, ``(s + 1)^n`` (paper 000, eq. 3).
    order : int, optional
        ``n`` when no system is given (must match the system's if both are).
    output : int
        Index of the measured channel this observer uses.
    model : bool
        Add the model term ``phi(sat(z_hat), u)`` of Gauthier et al. (needs a system).
    method : {"exact", "euler", "rk4"}
        How ``update`` advances one sample (see :func:`one_step_map`): ``exact`` is the
        sampled-data observer (chain propagated exactly, pole-matched correction, stable for
        every period; the model term, if any, held at its start-of-sample value); ``euler`` and
        ``rk4`` integrate the continuous observer with the measurement held.
    z_bounds : (array_like, array_like), optional
        Saturation of the estimate against peaking (Khalil, sec. 14.5): the reported
        ``z_hat``/``x_hat`` and the argument of the model term are clipped to these bounds;
        the observer's own state is not.
    x_hat0, z_hat0 : array_like, optional
        Initial estimate in physical or observer coordinates (default zero).
    on_unstable : {"raise", "warn", "ignore"}
        What to do when the chosen ``method`` and sample period give a one-step error map of
        spectral radius >= 1 (a high gain with a too-long period): the message states the
        largest stable period.

    Attributes
    ----------
    k_ : float
        The gain (constant here; the adaptive observer changes it).
    dropouts_ : int
        Samples that were NaN and over which the observer ran open loop.

    Notes
    -----
    Sensitivity (paper 000, eq. 3, binomial ``p``): ``e_1(s) = w(s)/(s+k)^n +
    s^n/(s+k)^n nu(s)``: a larger ``k`` rejects the unmodelled ``phi`` better and passes the
    measurement noise ``nu`` with gain ``k^(i-1)`` into the ``i``-th estimate.

    References
    ----------
    Paper 000 (Bullinger, Ilchmann, Allgöwer 1998), eq. 2, 3, 6; Tornambè 1992; Gauthier,
    Hammouri, Othman 1992; Khalil, *Nonlinear Systems*, sec. 14.5.
    """

    name = "high_gain"
    summary = "Tornambè high-gain observer, gains p_i k^i, optional model term and saturation"
    reference = "paper 000 (Bullinger et al. 1998), eq. 2, 3, 6"
    diagnostic_names = ("k",)

    def __init__(self, system: System | None = None, *, k: float, p: Any = None,
                 order: int | None = None, output: int = 0, model: bool = False,
                 method: str = "exact", z_bounds: Any = None, x_hat0: Any = None,
                 z_hat0: Any = None, on_unstable: str = "raise") -> None:
        super().__init__(system, order, output)
        n = self.n
        self.p = binomial_coefficients(n) if p is None else check_hurwitz(p)
        if self.p.size != n:
            raise DimensionError(f"p must have n = {n} coefficients; found {self.p.size}")
        self.k_ = finite_scalar("k", k, positive=True)
        if method not in METHODS:
            raise DesignError(f"method must be one of {list(METHODS)}; found {method!r}")
        if on_unstable not in ("raise", "warn", "ignore"):
            raise DesignError(f"on_unstable must be 'raise', 'warn' or 'ignore'; "
                              f"found {on_unstable!r}")
        if model and system is None:
            raise DesignError("model=True needs a system providing phi")
        self.model = bool(model)
        self.method = method
        self.on_unstable = on_unstable
        if z_bounds is None:
            self.z_bounds = None
        else:
            lo, hi = (vector("z_bounds[0]", z_bounds[0], n), vector("z_bounds[1]", z_bounds[1], n))
            if np.any(lo >= hi):
                raise DesignError(f"z_bounds need lower < upper; found lower {lo.tolist()}, "
                                  f"upper {hi.tolist()}")
            self.z_bounds = (lo, hi)
        self.L = hgo_gains(self.p, self.k_)
        self._steps: dict[float, tuple[Callable, Callable, Array, Array]] = {}
        self._init = (x_hat0, z_hat0)
        self.reset(x_hat0, z_hat0=z_hat0)

    # ------------------------------------------------------------------ setup
    def max_stable_period(self) -> float:
        """Largest sample period for which ``method``'s one-step error map is stable."""
        if self.method == "exact":
            return float("inf")

        def stable(dt: float) -> bool:
            return spectral_radius(one_step_map(self.p, self.k_, dt, self.method)[0]) < 1.0

        lo, hi = 0.0, 1.0 / self.k_
        while stable(hi):
            lo, hi = hi, hi * 2.0
            if hi > 1e6 / self.k_:
                return float("inf")
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if stable(mid) else (lo, mid)
        return lo

    def check_period(self, dt: float) -> None:
        if dt not in self._steps:
            self._compile(dt)

    def _compile(self, dt: float) -> tuple[Callable, Callable, Array, Array]:
        dt = finite_scalar("dt", dt, positive=True)
        M, b, g = one_step_map(self.p, self.k_, dt, self.method)
        rho = spectral_radius(M)
        if rho >= 1.0 and self.on_unstable != "ignore":
            msg = (f"{self.method} update of the high-gain observer (n={self.n}, k={self.k_:g}) "
                   f"with sample period {dt:g} is unstable: spectral radius of the one-step error "
                   f"map {rho:.4g} >= 1; the largest stable period is "
                   f"{self.max_stable_period():.4g}")
            if self.on_unstable == "raise":
                raise DesignError(msg)
            warnings.warn(msg, RuntimeWarning, stacklevel=3)
        M0, _, g0 = one_step_map(self.p, self.k_, dt, self.method, closed=False)  # dropout
        entry = (affine_step(M, b), affine_step(M0, np.zeros(self.n)), g, g0)
        self._steps[dt] = entry
        return entry

    # -------------------------------------------------------------- interface
    def reset(self, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None) -> None:
        """Restart from ``x_hat0``/``z_hat0`` (default: those given to the constructor)."""
        if x_hat0 is None and z_hat0 is None:
            x_hat0, z_hat0 = self._init
        self._z = tuple(float(v) for v in self._initial_z(x_hat0, z_hat0, u0))
        self.dropouts_ = 0
        self.inverse_failures_ = 0
        self._x_last = None

    def update(self, y: Any, u: Any, dt: float) -> Array:
        """Consume ``y(t_k)``, ``u(t_k)``; integrate over ``dt``; return ``x_hat(t_k + dt)``."""
        yi = float(y[self.output])
        self._u = u
        entry = self._steps.get(dt)
        if entry is None:
            entry = self._compile(dt)
        closed, open_, gphi, gphi0 = entry
        z = self._z
        if yi != yi:  # NaN: sensor dropout, predict without correction
            self.dropouts_ += 1
            znew, g = open_(0.0, *z), gphi0
        elif yi in (np.inf, -np.inf):
            raise DivergenceError(f"measurement y[{self.output}] is {yi}")
        elif self.model and self.method == "rk4":
            znew, g = self._rk4_model(yi, u, dt), None
        else:
            znew, g = closed(yi, *z), gphi
        if self.model and g is not None:
            ph = float(self.system.phi_unchecked(self._saturate(np.array(z)), u))  # type: ignore[union-attr]
            znew = tuple(a + b * ph for a, b in zip(znew, g))
        self._z = znew
        return self.x_hat

    def _rk4_model(self, y: float, u: Any, dt: float) -> tuple[float, ...]:
        L = self.L

        def rhs(z: Array) -> Array:
            dz = np.empty_like(z)
            dz[:-1] = z[1:]
            dz[-1] = float(self.system.phi_unchecked(self._saturate(z), u))  # type: ignore[union-attr]
            return dz + L * (y - z[0])

        z = np.array(self._z)
        k1 = rhs(z)
        k2 = rhs(z + dt / 2 * k1)
        k3 = rhs(z + dt / 2 * k2)
        k4 = rhs(z + dt * k3)
        return tuple((z + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)).tolist())

    def _saturate(self, z: Array) -> Array:
        if self.z_bounds is None:
            return z
        return np.clip(z, self.z_bounds[0], self.z_bounds[1])

    @property
    def z_hat(self) -> Array:
        z = np.array(self._z)
        return z if self.z_bounds is None else self._saturate(z)

    @property
    def x_hat(self) -> Array:
        z = self.z_hat
        return z if self.system is None else self._physical(z)

    def diagnostics(self) -> dict[str, float]:
        return {"k": self.k_, "dropouts": float(self.dropouts_)}

    def params(self) -> dict[str, Any]:
        return {"k": self.k_, "p": self.p.tolist(), "order": self.n, "output": self.output,
                "model": self.model, "method": self.method,
                "z_bounds": None if self.z_bounds is None else [b.tolist() for b in self.z_bounds]}
