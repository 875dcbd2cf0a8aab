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

import math
import warnings
from collections.abc import Callable
from math import factorial
from typing import Any

import numpy as np

from .._validate import finite_scalar, one_of, vector
from ..design import binomial_coefficients, check_hurwitz, hgo_gains
from ..exceptions import DesignError, DimensionError, DivergenceError
from ..systems.base import System
from .base import Array, Observer

METHODS = ("exact", "euler", "rk4")


def affine_step(M: Array, b: Array, g: Array | None = None) -> Callable[..., tuple[float, ...]]:
    """Compile ``z -> M z + b y`` into a plain-float function ``step(y, *z)``; with ``g``,
    ``z -> M z + b y + g w`` into ``step(y, w, *z)`` (``w`` the model term).

    Observer updates run once per sample; for ``n <= 6`` a generated expression in Python
    floats costs a fraction of a microsecond, against several microseconds for small numpy
    arrays (measured in ``scripts/bench.py``). Each row is summed left to right, ``g w``
    last, as ``affine_step(I, g)`` applied after ``affine_step(M, b)`` would.
    """
    n = len(b)
    zs = [f"z{j}" for j in range(n)]
    rows = []
    for i in range(n):
        terms = [f"{float(M[i, j])!r}*z{j}" for j in range(n) if M[i, j] != 0.0]
        if b[i] != 0.0:
            terms.append(f"{float(b[i])!r}*y")
        if g is not None and g[i] != 0.0:
            terms.append(f"{float(g[i])!r}*w")
        rows.append(" + ".join(terms) if terms else "0.0")
    args = ", ".join((["y"] if g is None else ["y", "w"]) + zs)
    src = f"def step({args}):\n    return ({', '.join(rows)},)\n"
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
    one_of("method", method, METHODS)
    one_of("on_unstable", on_unstable, ("raise", "warn", "ignore"))
    if model and system is None:
        raise DesignError("model=True needs a system providing phi")


def bounds_pair(z_bounds: Any, n: int) -> tuple[Array, Array] | None:
    """``z_bounds = (lower, upper)`` as two length-``n`` arrays with lower < upper, or None."""
    if z_bounds is None:
        return None
    lo, hi = (vector("z_bounds[0]", z_bounds[0], n), vector("z_bounds[1]", z_bounds[1], n))
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
        check_options(method, on_unstable, model, system)
        self.model = bool(model)
        self.method = method
        self.on_unstable = on_unstable
        self.z_bounds = bounds_pair(z_bounds, n)
        self._bounds_floats = bounds_floats(self.z_bounds)
        self.L = hgo_gains(self.p, self.k_)
        self._steps: dict[float, tuple[Callable, ...]] = {}
        self._init = (x_hat0, z_hat0)
        #: the model term in one compiled call per sample (``exact``/``euler``): see update
        self._fused = self.model and method != "rk4"
        #: ``x_hat`` is ``z_hat`` itself (no system, or a system whose normal form is its state)
        self._identity = system is None or _is_identity(system, n)
        self.reset(x_hat0, z_hat0=z_hat0)

    # ------------------------------------------------------------------ setup
    def max_stable_period(self) -> float:
        """Largest sample period for which ``method``'s one-step error map is stable."""
        if self.method == "exact":
            return float("inf")
        return largest_stable_step(lambda dt: one_step_map(self.p, self.k_, dt, self.method)[0],
                                   1e-3 / self.k_, 1e6 / self.k_)

    def check_period(self, dt: float) -> None:
        if dt not in self._steps:
            self._compile(dt)

    def _compile(self, dt: float) -> tuple[Callable, ...]:
        dt = finite_scalar("dt", dt, positive=True)
        M, b, g = one_step_map(self.p, self.k_, dt, self.method)
        check_step_stable(M, self.on_unstable, f"{self.method} update of the {self._label()}",
                          dt, self.max_stable_period, digits=6)
        M0, _, g0 = one_step_map(self.p, self.k_, dt, self.method, closed=False)  # dropout
        # (closed step, open-loop step, open-loop model term z + g0 phi, closed step fused with
        # the model term z+ = M z + b y + g phi), all compiled in plain floats
        entry = (affine_step(M, b), affine_step(M0, np.zeros(self.n)),
                 affine_step(np.eye(self.n), g0), affine_step(M, b, g))
        self._steps[dt] = entry
        return entry

    def _label(self) -> str:
        """The observer and its gain, as error messages name it."""
        return f"high-gain observer (n={self.n}, k={self.k_:g})"

    # -------------------------------------------------------------- interface
    def reset(self, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None) -> None:
        """Restart from ``x_hat0``/``z_hat0`` (default: those given to the constructor)."""
        if x_hat0 is None and z_hat0 is None:
            x_hat0, z_hat0 = self._init
        self._z = tuple(float(v) for v in self._initial_z(x_hat0, z_hat0, u0))
        self._restart_counters()

    def update(self, y: Any, u: Any, dt: float) -> Array:
        """Consume ``y(t_k)``, ``u(t_k)``; integrate over ``dt``; return ``x_hat(t_k + dt)``."""
        try:
            yi = float(y[self.output])
        except (IndexError, TypeError):
            raise self._bad_measurement(y, self.output) from None
        self._advance(yi, u, dt)
        return self.x_hat

    def update_list(self, y: Any, u: Any, dt: float) -> list[float]:
        """:meth:`update` for per-sample loops: ``y`` and ``u`` sequences of Python floats
        (lists), the estimate returned as a list of floats (the same values as ``update``'s
        array). ``u`` becomes an array where the model term or the inverse map reads it; an
        observer without either keeps the list (it reads ``u`` nowhere)."""
        if self.model or not self._identity:
            u = np.array(u, dtype=float)
        self._advance(y[self.output], u, dt)
        return self.x_hat_list()

    def x_hat_list(self) -> list[float]:
        """:attr:`x_hat` as a list of Python floats."""
        if self._identity:
            z = self._z
            return list(z) if self.z_bounds is None else list(self._saturate_floats(z))
        return self.x_hat.tolist()

    def z_hat_list(self) -> list[float]:
        """:attr:`z_hat` as a list of Python floats (the same values)."""
        z = self._z
        return list(z) if self.z_bounds is None else list(self._saturate_floats(z))

    def diagnostic_values(self) -> tuple[float, ...]:
        """The values of :meth:`diagnostics`, in its key order, without building the dict: for
        per-sample loops that record them as columns."""
        return (self.k_, float(self.dropouts_))

    def _advance(self, yi: float, u: Any, dt: float) -> None:
        """One sample: the new observer state from the measurement ``yi`` (a float)."""
        self._u = u
        entry = self._steps.get(dt)
        if entry is None:
            entry = self._compile(dt)
        z = self._z
        if yi - yi == 0.0:  # finite (NaN and +-inf give NaN): the common case, one call
            if self._fused:  # correction and model term together
                zs = z if self._bounds_floats is None else self._saturate_floats(z)
                self._z = entry[3](yi, float(self.system.phi_unchecked(zs, u)), *z)  # type: ignore[union-attr]
            elif not self.model:
                self._z = entry[0](yi, *z)
            else:  # rk4 with the model term at every stage
                self._z = self._rk4_model(yi, u, dt)
            return
        if yi != yi:  # NaN: sensor dropout, predict without correction
            self.dropouts_ += 1
            znew = entry[1](0.0, *z)
            if self.model:
                # plain floats throughout: the system's unchecked phi takes the tuple z itself
                # (saturated when z_bounds is set); entry[2](phi, *z) = z + g0 phi
                zs = z if self._bounds_floats is None else self._saturate_floats(z)
                znew = entry[2](float(self.system.phi_unchecked(zs, u)), *znew)  # type: ignore[union-attr]
            self._z = znew
            return
        raise DivergenceError(f"measurement y[{self.output}] is {yi}")

    def _saturate_floats(self, z: tuple[float, ...]) -> tuple[float, ...]:
        """:meth:`_saturate` on a tuple of floats (the model term's argument), without numpy."""
        return clip_floats(z, self._bounds_floats)  # type: ignore[arg-type]

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
        return z if self._identity else self._physical(z)

    def diagnostics(self) -> dict[str, float]:
        return {"k": self.k_, "dropouts": float(self.dropouts_)}

    def params(self) -> dict[str, Any]:
        return {"k": self.k_, "p": self.p.tolist(), "order": self.n, "output": self.output,
                "model": self.model, "method": self.method,
                "z_bounds": None if self.z_bounds is None else [b.tolist() for b in self.z_bounds]}


def _is_identity(system: System, n: int) -> bool:
    """Whether ``system.from_normal_unchecked`` hands ``z`` back as it is (the normal form is
    the state, as for the one-joint MuJoCo systems): then ``x_hat = z_hat`` without the map."""
    probe = np.zeros(n)
    try:
        return system.from_normal_unchecked(probe, np.zeros(len(system.input_names))) is probe
    except Exception:  # noqa: BLE001 - a map that cannot take the probe is not the identity
        return False


_DERIVATIVE_WORDS = {"_angle": ("_angle", "_velocity", "_acceleration", "_jerk"),
                     "_position": ("_position", "_velocity", "_acceleration", "_jerk")}
#: outputs named by the bare word: the plants' own names (pendulum: angle, angular_velocity)
_BARE_DERIVATIVE_WORDS = {"angle": ("angle", "angular_velocity", "angular_acceleration", "angular_jerk"),
                          "position": ("position", "velocity", "acceleration", "jerk")}


def derivative_names(output: str, order: int) -> tuple[str, ...]:
    """Names of ``(y, y', ..., y^(order-1))`` for an output named ``output``.

    ``link1_angle`` gives ``link1_angle, link1_velocity, link1_acceleration, link1_jerk``
    (``_position`` likewise), a bare ``angle`` gives ``angle, angular_velocity, ...`` (the
    pendulums' state names); higher derivatives and other names get ``<name>_d<j>``.
    """
    if output in _BARE_DERIVATIVE_WORDS:
        words = _BARE_DERIVATIVE_WORDS[output]
        return tuple(words[j] if j < len(words) else f"{output}_d{j}" for j in range(order))
    for suffix, words in _DERIVATIVE_WORDS.items():
        if output.endswith(suffix):
            base = output[: -len(suffix)]
            return tuple(base + words[j] if j < len(words) else f"{base}_d{j}" for j in range(order))
    return tuple(output if j == 0 else f"{output}_d{j}" for j in range(order))


def _per_chain(name: str, value: Any, m: int) -> list[Any]:
    """A scalar (or None) for every chain, or a sequence with one entry per chain."""
    if value is None or np.ndim(value) == 0:
        return [value] * m
    seq = list(value)
    if len(seq) != m:
        raise DimensionError(f"{name} must be a scalar or have one entry per chain ({m}); "
                             f"found {len(seq)} entries")
    return seq


class MultiOutputHighGainObserver(Observer):
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
    outputs : sequence of int, optional
        Measured channel of each chain (default ``0, 1, ...``), distinct.
    phi : callable ``phi(z_hat, u) -> array`` of length ``len(orders)``, optional
        Model term: the chains' top derivatives, evaluated at the full ``z_hat`` (chains
        concatenated in order). With ``exact`` and ``euler`` it is held at its start-of-sample
        value over the sample; ``rk4`` evaluates it at every stage.
    method : {"exact", "euler", "rk4"}
        As in :class:`HighGainObserver` (see :func:`one_step_map`), for every chain.
    z_hat0 : array_like, optional
        Initial estimate, length ``sum(orders)`` (default zero); ``x_hat0`` is the same thing
        (``x_hat = z_hat``); give one of them.
    on_unstable : {"raise", "warn", "ignore"}
        What to do when a chain's one-step map at the sample period is unstable.

    Attributes
    ----------
    dropouts_ : int
        Samples at which at least one channel was NaN.
    channel_dropouts_ : list of int
        NaN samples per chain; a chain whose channel is NaN runs open loop over that sample
        while the others correct as usual.

    References
    ----------
    Paper 001 (Besançon, Zhang, Hammouri 2004), eq. 4 (high-gain observer) and eq. 5
    (two-output block structure, after Besançon and Hammouri 1998); paper 000, eq. 2 (gains
    ``p_i k^i``).
    """

    name = "high_gain_multi"
    summary = "one Tornambè chain per output (paper 001 eq. 5), per-chain order/k/p, optional coupling"
    reference = "paper 001 (Besançon et al. 2004), eq. 4-5; paper 000, eq. 2"
    diagnostic_names = ()

    def __init__(self, system: System | None = None, *, k: Any, orders: Any = None,
                 p: Any = None, outputs: Any = None,
                 phi: Callable[[Array, Array], Any] | None = None, method: str = "exact",
                 z_hat0: Any = None, x_hat0: Any = None, on_unstable: str = "raise") -> None:
        if system is not None and not isinstance(system, System):
            raise DesignError(f"system must be a System instance or None; found "
                              f"{type(system).__name__}")
        if orders is None:
            orders = getattr(system, "normal_form_orders", None)
            if orders is None and system is not None and system.normal_form_order is not None:
                orders = (system.normal_form_order,)
            if orders is None:
                where = "" if system is None else f" for {type(system).__name__}"
                raise DesignError(f"{type(self).__name__} needs orders=[n_1, n_2, ...]{where} "
                                  f"(one chain order per output)")
        orders = [orders] if np.ndim(orders) == 0 else list(orders)
        if not orders or any(isinstance(o, bool) or int(o) != o or o < 1 for o in orders):
            raise DesignError(f"orders must be positive integers, one per chain; found {orders!r}")
        self.orders = tuple(int(o) for o in orders)
        m = len(self.orders)
        outputs = list(range(m)) if outputs is None else (
            [outputs] if np.ndim(outputs) == 0 else list(outputs))
        if len(outputs) != m:
            raise DimensionError(f"outputs must name one channel per chain ({m}); found "
                                 f"{len(outputs)}")
        if any(isinstance(o, bool) or int(o) != o or o < 0 for o in outputs) or \
                len(set(outputs)) != m:
            raise DesignError(f"outputs must be distinct non-negative channel indices; found "
                              f"{outputs!r}")
        self.outputs = tuple(int(o) for o in outputs)
        if system is not None and max(self.outputs) >= len(system.output_names):
            raise DimensionError(f"{type(system).__name__} has {len(system.output_names)} "
                                 f"output(s) {list(system.output_names)}; found channel "
                                 f"{max(self.outputs)}")
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
        self.on_unstable = on_unstable
        self.system = system
        self.n = sum(self.orders)
        self.output = self.outputs[0]
        self._first = tuple(int(v) for v in np.cumsum((0,) + self.orders[:-1]))
        self.L = [hgo_gains(pc, kc) for pc, kc in zip(self.ps, self.ks)]
        self._u: Array = np.zeros(len(system.input_names)) if system is not None else np.zeros(0)
        self._steps: dict[float, list[tuple[Callable, Callable, Array, Array]]] = {}
        if x_hat0 is not None and z_hat0 is not None:
            raise DesignError("give x_hat0 or z_hat0 (the same thing here), not both")
        self._init = z_hat0 if z_hat0 is not None else x_hat0
        self.reset()

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
        """Largest sample period at which every chain's one-step map is stable."""
        return min(HighGainObserver(order=n, k=kc, p=pc, method=self.method,
                                    on_unstable="ignore").max_stable_period()
                   for n, kc, pc in zip(self.orders, self.ks, self.ps))

    def check_period(self, dt: float) -> None:
        if dt not in self._steps:
            self._compile(dt)

    def _compile(self, dt: float) -> list[tuple[Callable, Callable, Array, Array]]:
        dt = finite_scalar("dt", dt, positive=True)
        entries = []
        for c, (n, kc, pc) in enumerate(zip(self.orders, self.ks, self.ps)):
            M, b, g = one_step_map(pc, kc, dt, self.method)
            check_step_stable(M, self.on_unstable,
                              f"{self.method} update of chain {c} ({self.output_names[c]}, n={n}, "
                              f"k={kc:g}) of the multi-output high-gain observer", dt,
                              self.max_stable_period)
            M0, _, g0 = one_step_map(pc, kc, dt, self.method, closed=False)
            entries.append((affine_step(M, b), affine_step(M0, np.zeros(n)), g, g0))
        self._steps[dt] = entries
        return entries

    # -------------------------------------------------------------- interface
    def reset(self, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None) -> None:
        """Restart from ``z_hat0`` (or ``x_hat0``, the same here; default: the constructor's)."""
        if x_hat0 is not None and z_hat0 is not None:
            raise DesignError("give x_hat0 or z_hat0 (the same thing here), not both")
        z0 = z_hat0 if z_hat0 is not None else x_hat0
        if z0 is None:
            z0 = self._init
        z = np.zeros(self.n) if z0 is None else vector("z_hat0", z0, self.n)
        self._z = [tuple(float(v) for v in z[f:f + n]) for f, n in zip(self._first, self.orders)]
        self._restart_counters()
        self.channel_dropouts_ = [0] * len(self.orders)

    def update(self, y: Any, u: Any, dt: float) -> Array:
        """Consume ``y(t_k)``, ``u(t_k)``; integrate over ``dt``; return ``x_hat(t_k + dt)``."""
        self._u = u
        entries = self._steps.get(dt)
        if entries is None:
            entries = self._compile(dt)
        try:
            ys = [float(y[o]) for o in self.outputs]
        except (IndexError, TypeError):
            raise self._bad_measurement(y, list(self.outputs)) from None
        lost = False
        for c, yc in enumerate(ys):
            if yc != yc:
                lost = True
                self.channel_dropouts_[c] += 1
            elif yc in (np.inf, -np.inf):
                raise DivergenceError(f"measurement y[{self.outputs[c]}] is {yc}")
        self.dropouts_ += lost
        if self.phi is not None and self.method == "rk4":
            self._rk4_model(ys, u, dt)
            return self.x_hat
        ph = None if self.phi is None else self._phi(self.z_hat, u)
        new = []
        for c, (yc, z, (closed, open_, g, g0)) in enumerate(zip(ys, self._z, entries)):
            if yc != yc:
                zc, gc = open_(0.0, *z), g0
            else:
                zc, gc = closed(yc, *z), g
            if ph is not None:
                zc = tuple(a + b * ph[c] for a, b in zip(zc, gc))
            new.append(zc)
        self._z = new
        return self.x_hat

    def _phi(self, z: Array, u: Any) -> Array:
        ph = np.asarray(self.phi(z, u), dtype=float).reshape(-1)  # type: ignore[misc]
        if ph.shape != (len(self.orders),):
            raise DimensionError(f"phi(z_hat, u) must return one top derivative per chain "
                                 f"({len(self.orders)}); found shape {ph.shape}")
        return ph

    def _rk4_model(self, ys: list[float], u: Any, dt: float) -> None:
        n = self.n
        top = [f + nc - 1 for f, nc in zip(self._first, self.orders)]
        inner = np.setdiff1d(np.arange(n), top)  # z_i' = z_{i+1} inside a chain
        Lfull = np.zeros(n)
        first = np.array(self._first)
        yv = np.zeros(len(self.orders))
        for c, (f, nc) in enumerate(zip(self._first, self.orders)):
            if ys[c] == ys[c]:  # a dropped channel runs open loop
                Lfull[f:f + nc] = self.L[c]
                yv[c] = ys[c]
        chain_of = np.repeat(np.arange(len(self.orders)), self.orders)

        def rhs(z: Array) -> Array:
            dz = np.zeros(n)
            dz[inner] = z[inner + 1]
            dz[top] += self._phi(z, u)
            return dz + Lfull * (yv - z[first])[chain_of]

        z = np.concatenate([np.array(zc) for zc in self._z])
        k1 = rhs(z)
        k2 = rhs(z + dt / 2 * k1)
        k3 = rhs(z + dt / 2 * k2)
        k4 = rhs(z + dt * k3)
        z = z + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        self._z = [tuple(z[f:f + nc].tolist()) for f, nc in zip(self._first, self.orders)]

    @property
    def z_hat(self) -> Array:
        return np.array([v for zc in self._z for v in zc])

    @property
    def x_hat(self) -> Array:
        """``z_hat`` itself (model-free: outputs and derivatives, see the class docstring)."""
        return self.z_hat

    def params(self) -> dict[str, Any]:
        return {"k": list(self.ks), "orders": list(self.orders),
                "p": [pc.tolist() for pc in self.ps], "outputs": list(self.outputs),
                "phi": None if self.phi is None else getattr(self.phi, "__name__", repr(self.phi)),
                "method": self.method, "state_names": list(self.state_names)}
