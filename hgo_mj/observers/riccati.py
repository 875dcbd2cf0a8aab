"""The Riccati-based high-gain observer of Ibrir (paper 004 [004]_, Theorem 1), with the model term.

.. math::

    \\dot{\\hat x} = A \\hat x + B \\varphi(\\hat x, u) + P(\\gamma) C' (y - C \\hat x),
    \\qquad A P(\\gamma) + P(\\gamma) A' - P(\\gamma) C' C P(\\gamma) + Q(\\gamma) = 0

(eq. 6; the paper prints the innovation as ``gamma - C x_hat``, a typo for ``y - C x_hat``).
The plant is the chain of eq. 3, ``x_i' = x_{i+1}``, ``x_n' = phi(x, u)``, ``y = x_1`` (the
paper prints ``x_i' = x_i + 1``).
By Lemma 4 the gain ``P(gamma) C'`` equals ``(alpha_i gamma^i)``: the observer is the
high-gain observer with ``p = alpha``, ``k = gamma`` and the model term of Gauthier et al.;
its one-sample map is that of :func:`~hgo_mj.observers.high_gain.one_step_map`, with the gain
designed from the Riccati equation (:func:`hgo_mj.design.riccati_gains`).

This module also holds the kernels shared with the q-integral observer (paper 004, eq. 40,
:mod:`hgo_mj.observers.q_integral`), whose update is an affine map of the same kind:
``s+ = M s + b y + g phi`` (:func:`affine_run`), or RK4 of the continuous observer with the
model term at every stage (:func:`model_rk4`).

References
----------
.. [004] S. Ibrir, "On observer design for nonlinear systems", Int. J. Control, 2007
   (``shared/papers/004_*``): Theorem 1 (eq. 4-10), Lemma 4 (eq. 15-21), eq. 52-53 (Euler
   discretization), Theorem 2 (eq. 63).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit

from .._validate import boolean, finite_scalar
from ..design import (
    binomial_coefficients,
    check_riccati_alpha,
    lipschitz_condition,
    min_gamma,
    riccati_gains,
    riccati_P,
    riccati_Q,
)
from ..exceptions import DesignError, DimensionError
from ..systems.base import System
from ._integrate import rk4
from .base import Array, Observer, Params, State, batch_rows, register
from .high_gain import (
    bounds_pair,
    check_options,
    check_step_stable,
    largest_stable_step,
    one_step_map,
)

#: per-(dt, parameters) entries kept by an observer (jittered periods and many tunings must
#: not grow memory)
CACHE_SIZE = 8


def design_gamma(gamma: Any, alpha: np.ndarray, rho: Any, where: str) -> tuple[float, float | None]:
    """Resolve ``gamma`` (a number > 0, or ``"min"`` with ``rho``) and validate ``rho``."""
    r = None if rho is None else finite_scalar("rho", rho, positive=True)
    if isinstance(gamma, str):
        if gamma != "min":
            raise DesignError(f"gamma must be a number > 0 or 'min'; found {gamma!r}")
        if r is None:
            raise DesignError(f"{where}: gamma='min' needs the Lipschitz constant rho")
        return min_gamma(alpha, r), r
    return finite_scalar("gamma", gamma, positive=True), r


def cached(cache: dict[Any, Any], key: Any, build: Callable[[Any], Any]) -> Any:
    """``cache[key]``, built by ``build(key)`` when missing; at most :data:`CACHE_SIZE` entries
    (the oldest goes first). The key is what the entry derives from (the period, the
    parameters' :meth:`~hgo_mj.observers.base.Params.key`)."""
    entry = cache.get(key)
    if entry is None:
        entry = build(key)
        if len(cache) >= CACHE_SIZE:
            del cache[next(iter(cache))]
        cache[key] = entry
    return entry


def is_identity_map(system: System | None, n: int) -> bool:
    """Whether ``x_hat = z_hat`` (no system, or ``from_normal_unchecked`` hands ``z`` back as
    it is, as for the one-joint MuJoCo systems): then the inverse map is skipped."""
    if system is None:
        return True
    probe = np.zeros(n)
    try:
        return system.from_normal_unchecked(probe, np.zeros(len(system.input_names))) is probe
    except Exception:  # noqa: BLE001 - a map that cannot take the probe is not the identity
        return False


def bounds_rows(z_bounds: tuple[Array, Array] | None, n: int) -> tuple[Array, bool]:
    """``((lower, upper) as a (2, n) array, saturate)`` for the kernels (infinite bounds when
    there are none)."""
    if z_bounds is None:
        return np.array([np.full(n, -np.inf), np.full(n, np.inf)]), False
    return np.ascontiguousarray(np.vstack(z_bounds), dtype=float), True


# ---------------------------------------------------------------------------------- kernels
@njit(cache=True)
def _clip_row(s, off, lo, hi, sat, a):  # pragma: no cover - compiled
    """``a = sat(s[off:])`` for one member's rows (C-contiguous 1-D views, so that
    :func:`saturated` and :func:`report` share one specialisation)."""
    for r in range(a.shape[0]):
        v = s[off + r]
        if sat:
            if v < lo[r]:
                v = lo[r]
            elif v > hi[r]:
                v = hi[r]
        a[r] = v


@njit(cache=True)
def saturated(S, off, bounds, sat, A):  # pragma: no cover - compiled
    """``A = sat(S[:, off:])``: the reported estimate and the model term's argument, clipped
    to ``bounds = (lower, upper)`` when ``sat`` (Khalil, sec. 14.5); NaN stays NaN as in
    ``np.clip``."""
    for i in range(A.shape[0]):
        _clip_row(S[i], off, bounds[0], bounds[1], sat, A[i])


@njit(cache=True)
def report(S, off, bounds, sat, j, Z):  # pragma: no cover - compiled
    """Write ``sat(S[:, off:])`` into the rows ``Z[:, j]`` (:func:`saturated`)."""
    for i in range(Z.shape[0]):
        _clip_row(S[i], off, bounds[0], bounds[1], sat, Z[i, j])


@njit(cache=True)
def affine_run(S, Y, PHI, j0, model, mats, vecs, bounds, off, sat, Z):  # pragma: no cover - compiled
    """Samples ``j0 .. j0 + T'`` (``T' = PHI.shape[1]``) of the affine one-sample map

    .. math:: s^+ = M s + b\\, y_j + g\\, \\varphi_j \\quad (y_j \\text{ finite}), \\qquad
              s^+ = M_0 s + g_0 \\varphi_j \\quad (y_j = \\text{NaN: no correction})

    for each member (``S`` ``(B, N)`` updated in place, ``Y`` ``(B, T, 1)``, ``PHI``
    ``(B, T')`` the model term held over each sample, read when ``model``), and the estimate
    ``sat(s[off:])`` after each sample into ``Z[:, j]``. ``mats = (M, M0)``,
    ``vecs = (b, g, g0)``, ``bounds = (lower, upper)`` (used when ``sat``): few arguments make
    the call cheap. Each row is summed left to right, ``b y`` then ``g phi`` last.
    """
    B, N = S.shape
    n = Z.shape[2]
    Tc = PHI.shape[1]
    M, M0 = mats[0], mats[1]
    b, g, g0 = vecs[0], vecs[1], vecs[2]
    lo, hi = bounds[0], bounds[1]
    s = np.empty(N)
    t = np.empty(N)
    for i in range(B):
        for r in range(N):
            s[r] = S[i, r]
        for jj in range(Tc):
            j = j0 + jj
            y = Y[i, j, 0]
            ph = PHI[i, jj] if model else 0.0
            if y == y:
                for r in range(N):
                    acc = 0.0
                    for c in range(N):
                        acc += M[r, c] * s[c]
                    t[r] = acc + b[r] * y + g[r] * ph
            else:
                for r in range(N):
                    acc = 0.0
                    for c in range(N):
                        acc += M0[r, c] * s[c]
                    t[r] = acc + g0[r] * ph
            for r in range(N):
                s[r] = t[r]
            for r in range(n):  # _clip_row written out: the call cost 11 % here (88 vs 79 ns)
                v = s[off + r]
                if sat:
                    if v < lo[r]:
                        v = lo[r]
                    elif v > hi[r]:
                        v = hi[r]
                Z[i, j, r] = v
        for r in range(N):
            S[i, r] = s[r]


@njit(cache=True)
def chain_rhs(V, Y, j, PHI, L, D):  # pragma: no cover - compiled
    """The continuous observer of eq. 6 (paper 004) / eq. 2 (paper 000) with the model term,
    ``y`` held, for each member:

    .. math:: \\dot{\\hat z}_i = \\hat z_{i+1} + L_i (y - \\hat z_1), \\qquad
              \\dot{\\hat z}_n = \\varphi(\\hat z, u) + L_n (y - \\hat z_1),

    ``L = P(gamma) C' = (alpha_i gamma^i)``. Over a dropout (``y`` NaN) no correction."""
    B, n = V.shape
    for i in range(B):
        y = Y[i, j, 0]
        e = y - V[i, 0] if y == y else 0.0
        for r in range(n - 1):
            D[i, r] = V[i, r + 1] + L[r] * e
        D[i, n - 1] = PHI[i] + L[n - 1] * e


@njit(cache=True)
def accept_step(S, New, Y, j, lead, M0, g0, PHI1):  # pragma: no cover - compiled
    """``S = New`` (a step of the continuous observer, :func:`model_rk4`) for the members whose
    ``y_j`` is finite; the others take the prediction without correction ``s[lead:]+ = M0
    s[lead:] + g0 phi(s)`` (the model term held at its start-of-sample value ``PHI1``; columns
    before ``lead`` held). ``S`` is updated in place."""
    B, N = S.shape
    m = N - lead
    t = np.empty(m)
    for i in range(B):
        y = Y[i, j, 0]
        if y == y:
            for r in range(N):
                S[i, r] = New[i, r]
        else:
            for r in range(m):
                acc = 0.0
                for c in range(m):
                    acc += M0[r, c] * S[i, lead + c]
                t[r] = acc + g0[r] * PHI1[i]
            for r in range(m):
                S[i, lead + r] = t[r]


def model_rk4(S: Array, Y: Array, j: int, dt: float, lead: int, M0: Array, g0: Array,
              phi: Callable[[Array], Array],
              stage: Callable[[Array, Array], Array]) -> None:
    """One RK4 sample (``S`` updated in place) of an observer whose model term is evaluated at
    every stage: ``phi(V)`` is the model term at the stage state ``V`` (from
    ``system.phi_batch``, hence the stages are driven from here), ``stage(V, phi_V)`` the
    derivative (a kernel such as :func:`chain_rhs`); the step is
    :func:`hgo_mj.observers._integrate.rk4`. Members without a measurement take the
    prediction without correction (:func:`accept_step`)."""
    p1 = phi(S)

    def f(V: Array) -> Array:
        return stage(V, p1 if V is S else phi(V))  # rk4 calls f on S itself first

    accept_step(S, rk4(f, S, dt), Y, j, lead, M0, g0, p1)


class AffineObserver(Observer):
    """What the Riccati and q-integral observers share: a state ``S`` ``(B, N)`` whose
    one-sample map is affine (:func:`affine_run`) with the model term held over the sample, or
    RK4 with the model term at every stage (:func:`model_rk4`); the estimate ``z_hat`` is
    ``sat(S[:, off:])``.

    The tunable parameters are the high-gain parameter ``gamma`` and the coefficients
    ``alpha`` (:meth:`parameters`); the state is ``S`` with the base's fields. A family sets
    ``_off``, ``gamma_``, ``alpha`` and ``rho`` and implements
    ``_maps(p, dt) -> ((M, M0), (b, g, g0))`` (the arrays of :func:`affine_run` for the
    parameters ``p``), the stage derivative ``_stage(V, Y, j, phi, L) -> dV/dt`` (RK4 with the
    model term, ``L`` the gain of ``p``), ``_check_alpha(alpha)`` and ``_initial_state(z0)``.
    """

    family_diagnostics = ("gamma",)
    _off = 0
    gamma_: float
    alpha: Array
    rho: float | None

    def _setup(self, model: bool, method: str, z_bounds: Any, x_hat0: Any, z_hat0: Any) -> None:
        check_options(method, self.on_unstable, model, self.system)
        self.model = boolean("model", model)
        self.method = method
        self.z_bounds = bounds_pair(z_bounds, self.n)
        self._bounds, self._sat = bounds_rows(self.z_bounds, self.n)
        self._identity = is_identity_map(self.system, self.n)
        self._maps_cache: dict[tuple[float, bytes], tuple[Array, ...]] = {}
        self._gains_cache: dict[bytes, Array] = {}
        self._start = (x_hat0, z_hat0)

    # ------------------------------------------------------------- parameters
    def _parameters(self) -> dict[str, Any]:
        """The high-gain parameter ``gamma`` (a float) and the coefficients ``alpha`` of (9)
        (one per integrator of the chain) (paper 004, Theorem 1, eq. 6-10)."""
        return {"gamma": self.gamma_, "alpha": self.alpha}

    def _check_parameter(self, name: str, value: Any) -> Array:
        """``gamma`` > 0, or ``"min"`` (:func:`~hgo_mj.design.min_gamma` of the constructor's
        ``alpha`` and ``rho``); ``alpha`` (9) Hurwitz, meeting (10), of the chain's length. (The
        constructor's warning on the Lipschitz condition is not repeated per member: it needs
        the pair ``gamma``, ``alpha``.)"""
        if name == "gamma":
            return np.array(design_gamma(value, self.alpha, self.rho, type(self).__name__)[0])
        a = np.asarray(value)
        if a.dtype.kind in "iuf" and a.ndim == 1:  # the length first: a wrong one is named so
            self._check_alpha(a.astype(float))
        return self._check_alpha(check_riccati_alpha(value))

    def _check_alpha(self, a: Array) -> Array:
        raise NotImplementedError

    def _gains(self, p: Params) -> Array:
        """The gain ``L = P(gamma) C'`` of the parameters ``p`` (from the Riccati equation,
        :func:`~hgo_mj.design.riccati_gains`), contiguous for the kernels."""
        return cached(self._gains_cache, p.key(),  # type: ignore[no-any-return]
                      lambda _: np.ascontiguousarray(
                          riccati_gains(np.asarray(p.alpha), float(p.gamma)), dtype=float))

    # ------------------------------------------------------------------ setup
    def _maps(self, p: Params, dt: float) -> tuple[Array, ...]:
        raise NotImplementedError

    def _stage(self, V: Array, Y: Array, j: int, phi: Array, L: Array) -> Array:
        raise NotImplementedError

    def _entry(self, p: Params, dt: float) -> tuple[Array, ...]:
        return cached(self._maps_cache, (dt, p.key()),  # type: ignore[no-any-return]
                      lambda _: self._maps(p, dt))

    def _check_period(self, p: Params, dt: float) -> None:
        """Check the one-step error map of the parameters ``p`` at the sample period ``dt``
        (once per period: the first update at a new period does it too) and react as
        ``on_unstable`` says."""
        self._entry(p, finite_scalar("dt", dt, positive=True))

    # ------------------------------------------------------------------ state
    def _initial_state(self, z0: Array) -> Array:
        return np.array(z0, dtype=float, order="C")

    def _init(self, p: Params, x0: Array | None, z0: Array | None,
              u0: Array) -> dict[str, Any]:
        B = u0.shape[0]
        S = self._initial_state(self._initial_z(*initial_rows(self, x0, z0, B), u0))
        s = State(**self._core(B))
        physical_rows(self, s, S, self._off, u0)
        return {"S": S, **s.fields}

    def _phi(self, V: Array, u: Array) -> Array:
        """The model term ``phi(sat(V[:, off:]), u)`` of every member, ``(B,)``."""
        A = np.empty((V.shape[0], self.n))
        saturated(V, self._off, self._bounds, self._sat, A)
        return np.ascontiguousarray(self.system.phi_batch(A, u), dtype=float)  # type: ignore[union-attr]

    def _step(self, p: Params, s: State, Y: Array, U: Array, dt: float, X: Array, Z: Array,
              D: Array) -> None:
        mats, vecs = self._entry(p, dt)
        M0, g0 = mats[1], vecs[2]
        S, off, bounds, sat = s.S, self._off, self._bounds, self._sat
        B, T = Y.shape[0], Y.shape[1]
        if not self.model:  # the whole block in one call
            affine_run(S, Y, np.zeros((1, T)), 0, False, mats, vecs, bounds, off, sat, Z)
        elif self.method == "rk4":  # the model term at every stage
            L = self._gains(p)
            for j in range(T):
                u = U[:, j]

                def phi(V: Array, u: Array = u) -> Array:
                    return self._phi(V, u)

                def stage(V: Array, ph: Array, j: int = j) -> Array:
                    return self._stage(V, Y, j, ph, L)

                model_rk4(S, Y, j, dt, 0, M0, g0, phi, stage)
                report(S, off, bounds, sat, j, Z)
        else:  # the model term held at its start-of-sample value (eq. 53 for euler)
            for j in range(T):
                ph = self._phi(S, U[:, j])
                affine_run(S, Y, ph.reshape(B, 1), j, True, mats, vecs, bounds, off, sat, Z)
        D[:, :, 0] = float(p.gamma)
        to_physical(self, s, Z, U, X)

    def _current(self, p: Params, s: State) -> tuple[Array, Array, Array]:
        B = s.S.shape[0]
        Zc = np.empty((B, 1, self.n))
        report(s.S, self._off, self._bounds, self._sat, 0, Zc)
        return s.x_held.copy(), Zc[:, 0], np.full((B, 1), float(p.gamma))


def initial_rows(ob: Observer, x0: Array | None, z0: Array | None, B: int) -> tuple[Any, Any]:
    """The initial estimate of ``B`` members: the one given, else the constructor's
    (``ob._start = (x_hat0, z_hat0)``) for every member."""
    if x0 is not None or z0 is not None:
        return x0, z0
    ix, iz = ob._start  # type: ignore[attr-defined]
    return (None if ix is None else batch_rows("x_hat0", ix, len(ob.state_names), B),
            None if iz is None else batch_rows("z_hat0", iz, ob.n, B))


def to_physical(ob: Any, s: State, Z: Array, U: Array, X: Array) -> None:
    """``X`` from the rows ``Z`` (the identity, or the inverse normal-form map) and keep the
    last row as the current ``x_hat`` (the state's ``x_held``)."""
    if ob._identity:
        X[...] = Z
        if Z.shape[1]:
            s.x_held[...] = X[:, -1]
    else:
        ob._to_physical(s, Z, U, X)  # keeps the last (valid) row in s.x_held


def physical_rows(ob: Any, s: State, S: Array, off: int, u0: Array) -> None:
    """``x_hat`` of the state ``S`` at the start into ``s.x_held`` (failures of the inverse map
    not counted: the run has not started)."""
    Zc = np.empty((S.shape[0], 1, ob.n))
    report(S, off, ob._bounds, ob._sat, 0, Zc)
    if ob._identity:
        s.x_held[...] = Zc[:, 0]
        return
    X = np.empty((S.shape[0], 1, len(ob.state_names)))
    ob._to_physical(s, Zc, u0[:, None], X)  # keeps the row (or NaN) in s.x_held
    s.inverse_failures[:] = 0


@register
class RiccatiObserver(AffineObserver):
    """Riccati-based high-gain observer of Ibrir (paper 004, Theorem 1).

    .. math::

        \\dot{\\hat x} = A \\hat x + B \\varphi(\\hat x, u) + P(\\gamma) C' (y - \\hat x_1),
        \\qquad P(\\gamma) C' = (\\alpha_1 \\gamma, \\dots, \\alpha_n \\gamma^n)'

    with ``P(gamma)`` the solution of the Riccati equation of eq. 6 for ``Q(gamma)`` of eq. 8
    (weights corrected to eq. 17, see :func:`hgo_mj.design.riccati_weights`). If the Lipschitz
    condition (5) holds for the Lipschitz constant ``rho`` of ``phi``, the error decays
    exponentially; :func:`hgo_mj.design.min_gamma` gives the smallest such ``gamma``.

    Parameters
    ----------
    system : System, optional
        Gives the order ``n``, the map back to physical coordinates and ``phi`` (the model term
        the paper's observer uses, ``f(x_hat, u) = B phi``, from ``system.phi_batch``). Without
        a system give ``order`` and ``model=False``.
    gamma : float or "min"
        High-gain parameter (> 0); ``"min"`` takes :func:`~hgo_mj.design.min_gamma` for ``rho``.
    alpha : array_like, optional
        ``alpha_1..alpha_n``: (9) Hurwitz and meeting condition (10); default binomial
        ``C(n, k)`` (then the observer is that of Gauthier et al. 1992, as the paper notes).
    rho : float, optional
        Lipschitz constant of ``phi`` (eq. 4). Needed for ``gamma="min"``; with a numeric
        ``gamma``, a :class:`RuntimeWarning` says when condition (5) does not hold.
    order : int, optional
        ``n`` when no system is given.
    outputs : tuple of int
        The measured channel, a 1-tuple (default ``(0,)``).
    model : bool
        Use the model term ``phi(x_hat, u)`` (default ``True``, as in the paper).
    method : {"exact", "euler", "rk4"}
        ``euler`` is the discrete-time observer of eq. 53,
        ``x_{k+1} = A_delta x_k + delta B phi(x_k, u_k) + delta P C' (y_k - x_{k,1})``,
        ``A_delta = I + delta A``; it is stable only for short periods (Theorem 2 and
        :func:`hgo_mj.design.max_sampling_period` give a sufficient bound with the
        nonlinearity; :meth:`check_period` checks the linear part). ``exact`` is the
        sampled-data observer of :func:`~hgo_mj.observers.high_gain.one_step_map` (exact for
        the linear part, model term held over the sample); ``rk4`` integrates the continuous
        observer with ``y`` held and the model term at every stage.
    z_bounds : (array_like, array_like), optional
        Saturation of the reported estimate and of the model term's argument.
    x_hat0, z_hat0 : array_like, optional
        Initial estimate ``(n,)`` or ``(B, n)`` (default zero), used by a plain ``reset()``.
    on_unstable : {"raise", "warn", "ignore"}
        What :meth:`check_period` (and the first update at a new period) does when the
        one-step error map at the period has spectral radius >= 1.

    Attributes
    ----------
    gamma_ : float
        The high-gain parameter (constant over a run), reported by :meth:`diagnostics` as
        ``"gamma"``. With ``alpha`` it is a tunable parameter: this value is the default of
        :meth:`parameters`, which gives each member of a batch its own ``gamma`` and ``alpha``.
    P, Q : ndarray
        ``P(gamma)`` and ``Q(gamma)`` of the design.
    L : ndarray
        The gain ``P(gamma) C'`` (from the Riccati solution).
    condition : dict or None
        The two sides of (5) when ``rho`` is given (:func:`hgo_mj.design.lipschitz_condition`).

    Notes
    -----
    Corrections to the paper, all checked numerically (``hgo-mj reproduce ibrir2007``):
    eq. 6 ``gamma - C x_hat`` is ``y - C x_hat``; eq. 8/10's sum is eq. 17's; eq. 51/64 print
    ``phi(x_k, u_k)`` (the true state) where the error equation (54) needs ``phi(x_hat_k,
    u_k)``, as in eq. 53; eq. 64 omits the ``C'`` of ``delta P C'``.

    The update is one compiled kernel (:func:`affine_run`) over the batch and the samples;
    with the model term, ``system.phi_batch`` is called once per sample (four times for
    ``rk4``) for the whole batch.

    References
    ----------
    Paper 004 (Ibrir 2007): Theorem 1 (eq. 4-10), Lemma 4 (eq. 15-21), eq. 53, Theorem 2.
    Gauthier, Hammouri, Othman 1992 (``alpha_k = C(n, k)``).

    Examples
    --------
    >>> from hgo_mj.systems import CartPendulum
    >>> ob = RiccatiObserver(CartPendulum(), alpha=[3, 2], gamma=6.0)
    >>> ob.L.tolist()
    [18.0, 72.0]
    """

    name = "riccati"
    summary = "Ibrir's Riccati-based high-gain observer, gain P(gamma)C' = (alpha_i gamma^i), model term"
    reference = "paper 004 (Ibrir 2007), Theorem 1, Lemma 4, eq. 6-8, 53"

    def __init__(self, system: System | None = None, *, gamma: Any, alpha: Any = None,
                 rho: float | None = None, order: int | None = None, outputs: Any = (0,),
                 model: bool = True, method: str = "exact", z_bounds: Any = None,
                 x_hat0: Any = None, z_hat0: Any = None, on_unstable: str = "raise") -> None:
        super().__init__(system, order=order, outputs=outputs, on_unstable=on_unstable)
        n = self.n
        a = binomial_coefficients(n) if alpha is None else self._check_alpha(
            check_riccati_alpha(alpha))
        g, r = design_gamma(gamma, a, rho, type(self).__name__)
        self._setup(model, method, z_bounds, x_hat0, z_hat0)
        self.alpha = a
        self.p = a
        self.gamma_ = g
        self.rho = r
        self.gamma_spec = gamma if isinstance(gamma, str) else g
        self.Q = riccati_Q(a, g)
        self.P = riccati_P(a, g)
        self.L = riccati_gains(a, g)  # P(gamma) C' from the ARE; equals (alpha_i gamma^i)
        self.condition = None if r is None else lipschitz_condition(a, g, r)
        if r is not None and self.condition is not None and not self.condition["satisfied"]:
            warnings.warn(f"RiccatiObserver: gamma = {g:g} does not meet the Lipschitz condition (5) "
                          f"for rho = {r:g} (it admits rho <= {self.condition['rho_bound']:.4g}); "
                          f"convergence is not guaranteed; min_gamma gives "
                          f"{min_gamma(a, r):.4g}", RuntimeWarning, stacklevel=2)

    def _check_alpha(self, a: Array) -> Array:
        if a.size != self.n:
            raise DimensionError(f"alpha must have n = {self.n} coefficients; found {a.size}")
        return a

    def max_stable_period(self) -> float:
        """Largest sample period for which ``method``'s one-step error map is stable.

        Returns
        -------
        float
            Seconds; ``inf`` for ``method="exact"`` (stable for every period).

        Examples
        --------
        >>> obs = RiccatiObserver(order=2, gamma=10.0, model=False, method="euler")
        >>> round(obs.max_stable_period(), 6)
        0.2
        >>> RiccatiObserver(order=2, gamma=10.0, model=False).max_stable_period()
        inf
        """
        return self._max_period(self.alpha, self.gamma_)

    def _max_period(self, alpha: Array, gamma: float) -> float:
        if self.method == "exact":
            return float("inf")
        return largest_stable_step(
            lambda dt: one_step_map(alpha, gamma, dt, self.method)[0],
            1e-3 / gamma, 1e6 / gamma)

    def _maps(self, p: Params, dt: float) -> tuple[Array, ...]:
        alpha, gamma = np.asarray(p.alpha), float(p.gamma)
        M, b, g = one_step_map(alpha, gamma, dt, self.method)
        check_step_stable(M, self.on_unstable, f"{self.method} update of the Riccati observer "
                          f"(n={self.n}, gamma={gamma:g})", dt,
                          lambda: self._max_period(alpha, gamma), digits=6)
        M0, _, g0 = one_step_map(alpha, gamma, dt, self.method, closed=False)
        return np.array([M, M0]), np.array([b, g, g0])

    def _stage(self, V: Array, Y: Array, j: int, phi: Array, L: Array) -> Array:
        Dv = np.empty_like(V)
        chain_rhs(V, Y, j, phi, L, Dv)
        return Dv

    def params(self) -> dict[str, Any]:
        return {"gamma": self.gamma_, "gamma_spec": self.gamma_spec, "alpha": self.alpha.tolist(),
                "rho": self.rho, "order": self.n, "outputs": list(self.outputs),
                "model": self.model, "method": self.method,
                "z_bounds": None if self.z_bounds is None else [b.tolist() for b in self.z_bounds]}


__all__ = ["RiccatiObserver", "accept_step", "affine_run", "chain_rhs"]
