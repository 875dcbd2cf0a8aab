"""The q-integral observer of Ibrir (paper 004 [004]_, section 2.2, eq. 37-48).

The plant is augmented with ``q`` integrators of the measured output ``y = x_1 + w``,

.. math::

    \\dot\\xi_1 = \\xi_2, \\ \\dots, \\ \\dot\\xi_q = y, \\quad \\dot x_1 = x_2, \\ \\dots, \\
    \\dot x_n = \\varphi(x, u), \\qquad \\tilde y = \\xi_1,

a chain of ``N = n + q`` integrators whose output ``tilde y`` is the ``q``-th integral of the
measurement (eq. 37-39; the paper prints ``ÿ = xi_1`` for ``tilde y = xi_1``). The Riccati
observer (eq. 6) of that chain is the q-integral observer (eq. 40):

.. math::

    \\dot{\\hat\\eta} = \\tilde A \\hat\\eta + \\tilde B \\varphi(\\hat x, u)
        + Z(\\gamma) \\tilde C' (\\tilde y - \\hat\\eta_1), \\qquad
    Z(\\gamma) \\tilde C' = (\\alpha_i \\gamma^i)_{i=1..N}.

The measurement noise ``w`` enters ``q`` integrators upstream of the observer's output: from
``y`` to ``x_hat_j`` the observer is the filter

.. math::

    \\frac{\\hat x_j}{y}(s) = \\frac{s^{j-1} \\sum_{i=q+j}^{N} \\alpha_i \\gamma^i s^{N-i}}
                                  {s^N + \\alpha_1 \\gamma s^{N-1} + \\dots + \\alpha_N \\gamma^N}

(linear part, ``N = n + q``), of relative degree ``q + 1`` for every ``j`` (1 for the
standard observer, ``q = 0``): high-frequency noise is attenuated by ``q`` more orders, while
the DC gain of ``x_hat_1`` stays 1 (no bias).

Implementation: ``tilde y`` grows without bound (``t^q``), so the state kept is
``w = (tilde y_1 - xi_hat_1, ..., tilde y_q - xi_hat_q, x_hat)``, where ``tilde y_i`` are the
integrators of ``y`` (``tilde y_1 = tilde y``). Its dynamics are closed and bounded:

.. math::

    \\dot\\varepsilon_i = \\varepsilon_{i+1} - l_i \\varepsilon_1 \\ (i < q), \\quad
    \\dot\\varepsilon_q = y - \\hat x_1 - l_q \\varepsilon_1, \\quad
    \\dot{\\hat x}_j = \\hat x_{j+1} + l_{q+j} \\varepsilon_1, \\quad
    \\dot{\\hat x}_n = \\varphi(\\hat x, u) + l_N \\varepsilon_1,

``l = Z(gamma) C'``; its matrix is ``S (A - l C) S`` with ``S = diag(I_q, -I_n)``, so it has the
eigenvalues of the observer, ``gamma`` times the roots of (9).

References
----------
.. [004] S. Ibrir, "On observer design for nonlinear systems", Int. J. Control, 2007,
   section 2.2, eq. 37-48 (Corollary 2), and section 3 for the discrete-time form.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
from numba import njit

from .._validate import positive_int
from ..design import (
    binomial_coefficients,
    check_riccati_alpha,
    lipschitz_condition,
    min_gamma,
    riccati_gains,
    riccati_P,
    riccati_Q,
)
from ..exceptions import DimensionError
from ..systems.base import System
from .base import Array, Params, register
from .high_gain import (
    check_step_stable,
    largest_stable_step,
    matched_gain,
    sampled_chain,
    taylor_step,
)
from .riccati import AffineObserver, design_gamma


def q_integral_matrices(gain: Array, q: int, closed: bool = True) -> tuple[Array, Array, Array]:
    """``(F, b, g)`` of the continuous observer in the state ``w``: ``w' = F w + b y + g phi``.

    ``closed=False``: the prediction without correction (over a dropout): ``l = 0`` and the
    missing ``y`` replaced by the prediction ``x_hat_1``, so that ``eps' = (shift) eps``.

    Parameters
    ----------
    gain : (N,) ndarray
        The gains ``l_i = alpha_i gamma^i`` of the augmented chain, ``N = n + q``.
    q : int
        Number of integrals of the output, >= 1.
    closed : bool, default True
        With the output correction (False: the prediction over a dropout).

    Returns
    -------
    F : (N, N) ndarray
        The state matrix.
    b : (N,) ndarray
        The input vector of the measurement ``y``.
    g : (N,) ndarray
        The input vector of the model term ``phi`` (the last entry 1).

    Examples
    --------
    >>> import numpy as np
    >>> F, b, g = q_integral_matrices(np.array([3.0, 3.0, 1.0]), q=1)
    >>> F
    array([[-3., -1.,  0.],
           [ 3.,  0.,  1.],
           [ 1.,  0.,  0.]])
    >>> b, g
    (array([1., 0., 0.]), array([0., 0., 1.]))
    """
    N = gain.size
    F = np.diag(np.ones(N - 1), 1)
    b = np.zeros(N)
    g = np.zeros(N)
    g[-1] = 1.0
    if closed:
        F[q - 1, q] = -1.0  # eps_q' = y - x_hat_1 - l_q eps_1
        b[q - 1] = 1.0
        F[:q, 0] -= gain[:q]
        F[q:, 0] += gain[q:]
    else:
        F[q - 1, q] = 0.0  # eps_q' = x_hat_1 - x_hat_1 = 0
    return F, b, g


def q_integral_step_map(alpha: Array, gamma: float, q: int, dt: float, method: str,
                        closed: bool = True) -> tuple[Array, Array, Array]:
    """One sample of the q-integral observer in ``w``: ``w+ = M w + b y_k + g phi_k``.

    * ``euler``: ``M = I + dt F`` (eq. 53 for the augmented chain, the integrals of ``y``
      taken by the same Euler rule), ``b = dt b``, ``g = dt g``.
    * ``rk4``: degree-4 Taylor polynomial of ``e^{F dt}`` (RK4 of a linear ODE), ``y`` held.
    * ``exact``: the sampled-data observer of :func:`~hgo_mj.observers.high_gain.one_step_map`
      on the augmented chain: the chain propagated exactly, the correction with the
      pole-matched gain ``Ld`` (:func:`~hgo_mj.observers.high_gain.matched_gain`), and the
      integrals of the held ``y`` exact; the error map has eigenvalues ``exp(gamma r_i dt)``,
      stable for every period.

    Parameters
    ----------
    alpha : (N,) ndarray
        Hurwitz coefficients of the augmented chain, ``N = n + q``.
    gamma : float
        High-gain parameter, > 0.
    q : int
        Number of integrals of the output, >= 1.
    dt : float
        Sample period, > 0.
    method : {"exact", "euler", "rk4"}
        How the sample is advanced (above).
    closed : bool, default True
        With the output correction (False: the prediction over a dropout).

    Returns
    -------
    M : (N, N) ndarray
        The transition of ``w`` over one sample.
    b : (N,) ndarray
        The gain on the held measurement ``y_k``.
    g : (N,) ndarray
        The gain on the held model term ``phi_k``.

    Examples
    --------
    >>> import numpy as np
    >>> M, b, g = q_integral_step_map(np.array([3.0, 3.0, 1.0]), 10.0, 1, 0.01, "exact")
    >>> np.abs(np.linalg.eigvals(M)).round(5)      # exp(-gamma dt) = 0.90484
    array([0.90484, 0.90484, 0.90483])
    """
    N = alpha.size
    if method == "exact":
        Phi, S = sampled_chain(N, dt)
        Ld = matched_gain(alpha, gamma, dt) if closed else np.zeros(N)
        M = np.zeros((N, N))
        # eps+ = Phi_q eps - Phi[:q, q:] x_hat + s_q y - Ld[:q] eps_1 (s_q: last column of S_q)
        M[:q, :q] = Phi[:q, :q]
        M[:q, 0] -= Ld[:q]
        M[q:, q:] = Phi[q:, q:]
        M[q:, 0] += Ld[q:]
        b = np.zeros(N)
        if closed:
            M[:q, q:] = -Phi[:q, q:]
            b[:q] = S[:q, q - 1]
        else:  # the integrators of y fed with the prediction: eps evolves by Phi_q alone
            M[:q, q:] = 0.0
        g = np.zeros(N)
        g[q:] = S[q:, -1]
        return M, b, g
    F, bc, gc = q_integral_matrices(alpha * gamma ** np.arange(1, N + 1), q, closed)
    M, Sm = taylor_step(F, dt, method)
    return M, Sm @ bc, Sm @ gc


@njit(cache=True)
def q_integral_rhs(V, Y, j, PHI, l, q, D):  # pragma: no cover - compiled
    """The continuous q-integral observer (eq. 40) in the bounded state
    ``w = (eps_1..eps_q, x_hat)`` (module docstring), ``y`` held, for each member:

    .. math::

        \\dot\\varepsilon_i = \\varepsilon_{i+1} - l_i \\varepsilon_1 \\ (i < q), \\quad
        \\dot\\varepsilon_q = y - \\hat x_1 - l_q \\varepsilon_1, \\quad
        \\dot{\\hat x}_j = \\hat x_{j+1} + l_{q+j} \\varepsilon_1, \\quad
        \\dot{\\hat x}_n = \\varphi(\\hat x, u) + l_N \\varepsilon_1

    with ``l = Z(gamma) C'``. Over a dropout (``y`` NaN) no correction, and the integrators
    of ``y`` fed with the prediction ``x_hat_1`` (``eps`` only shifts)."""
    B, N = V.shape
    for i in range(B):
        y = Y[i, j, 0]
        closed = y == y
        e1 = V[i, 0] if closed else 0.0
        for r in range(q - 1):
            D[i, r] = V[i, r + 1] - l[r] * e1
        D[i, q - 1] = (y - V[i, q] - l[q - 1] * e1) if closed else 0.0
        for r in range(q, N - 1):
            D[i, r] = V[i, r + 1] + l[r] * e1
        D[i, N - 1] = PHI[i] + l[N - 1] * e1


@register
class QIntegralObserver(AffineObserver):
    """q-integral observer of Ibrir (paper 004, eq. 37-48): the Riccati observer of the plant
    augmented with ``q`` integrators of the measured output.

    Corollary 2 (eq. 48): with ``W = sqrt(e' Z^{-1} e)``,
    ``W' <= -(C_1/2) W + (C_2 / gamma^(q/2)) |w|``: the measurement noise ``w`` is injected
    ``q`` integrators upstream of the output, and the estimates are filtered by ``q`` more orders
    than with the standard observer (see the module docstring for the transfer functions).

    Parameters
    ----------
    system : System, optional
        Gives ``n``, the map back to physical coordinates and ``phi`` (model term, from
        ``system.phi_batch``). Without a system give ``order`` (``n``) and ``model=False``.
    gamma : float or "min"
        High-gain parameter (> 0); ``"min"``: the smallest meeting condition (44) for ``rho``.
    q : int
        Number of integrators (>= 1).
    alpha : array_like, optional
        ``n + q`` coefficients, (9) Hurwitz and meeting (10); default binomial ``C(n+q, k)``
        (the paper's example: ``q = 2``, ``alpha_k = C_4^k``).
    rho : float, optional
        Lipschitz constant of ``phi``: needed for ``gamma="min"``; with a numeric ``gamma`` a
        warning says when condition (44) does not hold.
    order : int, optional
        ``n`` (the plant's order) when no system is given.
    outputs : tuple of int
        The measured channel, a 1-tuple (default ``(0,)``).
    model : bool
        Use ``phi(x_hat, u)`` (default ``True``, as eq. 40).
    method : {"exact", "euler", "rk4"}
        See :func:`q_integral_step_map`. ``euler`` is eq. 53 applied to the augmented system;
        ``rk4`` with the model term evaluates it at every stage (:func:`q_integral_rhs`).
    x_hat0, z_hat0 : array_like, optional
        Initial estimate of the plant's state, ``(n,)`` or ``(B, n)`` (the integrator states
        start at zero error), used by a plain ``reset()``.
    on_unstable : {"raise", "warn", "ignore"}
        What to do when the one-step error map at the sample period is unstable.

    Attributes
    ----------
    gamma_ : float
        The high-gain parameter (constant over a run), reported by :meth:`diagnostics` as
        ``"gamma"``. With ``alpha`` it is a tunable parameter: this value is the default of
        :meth:`parameters`, which gives each member of a batch its own ``gamma`` and ``alpha``.
    Z, Q : ndarray
        ``Z(gamma)`` (the Riccati solution of the augmented chain, eq. 40) and ``Q(gamma)``.
    L : ndarray
        The gain ``Z(gamma) C'`` (length ``n + q``).
    condition : dict or None
        The two sides of (44) when ``rho`` is given.
    w_ : ndarray
        The internal state ``(tilde y_i - xi_hat_i)_{i<=q}`` then ``x_hat``, ``(n + q,)`` or
        ``(B, n + q)``.

    References
    ----------
    Paper 004 (Ibrir 2007), section 2.2, eq. 37-48 (Corollary 2); section 3.

    Examples
    --------
    >>> from hgo_mj.systems import CartPendulum
    >>> ob = QIntegralObserver(CartPendulum(), q=2, gamma=6.0)
    >>> ob.L.round(6).tolist()
    [24.0, 216.0, 864.0, 1296.0]
    """

    name = "q_integral"
    summary = "Ibrir's q-integral observer: Riccati observer on y augmented with q integrators"
    reference = "paper 004 (Ibrir 2007), eq. 37-48"

    def __init__(self, system: System | None = None, *, gamma: Any, q: int = 1, alpha: Any = None,
                 rho: float | None = None, order: int | None = None, outputs: Any = (0,),
                 model: bool = True, method: str = "exact", x_hat0: Any = None,
                 z_hat0: Any = None, on_unstable: str = "raise") -> None:
        super().__init__(system, order=order, outputs=outputs, on_unstable=on_unstable)
        n = self.n
        q = positive_int("q (the number of output integrators)", q)
        N = n + q
        self.q = q
        self._off = q
        self.N = N
        a = binomial_coefficients(N) if alpha is None else self._check_alpha(
            check_riccati_alpha(alpha))
        g, r = design_gamma(gamma, a, rho, type(self).__name__)
        self._setup(model, method, None, x_hat0, z_hat0)
        self.alpha = a
        self.gamma_ = g
        self.rho = r
        self.gamma_spec = gamma if isinstance(gamma, str) else g
        self.Q = riccati_Q(a, g)
        self.Z = riccati_P(a, g)
        self.L = riccati_gains(a, g)  # Z(gamma) C' from the ARE of the augmented chain
        self.condition = None if r is None else lipschitz_condition(a, g, r)
        if r is not None and self.condition is not None and not self.condition["satisfied"]:
            warnings.warn(f"QIntegralObserver: gamma = {g:g} does not meet condition (44) for "
                          f"rho = {r:g} (it admits rho <= {self.condition['rho_bound']:.4g}); "
                          f"convergence is not guaranteed; min_gamma gives {min_gamma(a, r):.4g}",
                          RuntimeWarning, stacklevel=2)

    def _check_alpha(self, a: Array) -> Array:
        if a.size != self.N:
            raise DimensionError(f"alpha must have n + q = {self.n} + {self.q} = {self.N} "
                                 f"coefficients; found {a.size}")
        return a

    # ------------------------------------------------------------------ setup
    def max_stable_period(self) -> float:
        """Largest sample period for which ``method``'s one-step error map is stable.

        Returns
        -------
        float
            Seconds; ``inf`` for ``method="exact"`` (stable for every period).

        Examples
        --------
        >>> obs = QIntegralObserver(order=2, q=1, gamma=10.0, model=False, method="euler")
        >>> round(obs.max_stable_period(), 4)
        0.2
        """
        return self._max_period(self.alpha, self.gamma_)

    def _max_period(self, alpha: Array, gamma: float) -> float:
        if self.method == "exact":
            return float("inf")
        return largest_stable_step(
            lambda dt: q_integral_step_map(alpha, gamma, self.q, dt, self.method)[0],
            1e-3 / gamma, 1e6 / gamma)

    def _maps(self, p: Params, dt: float) -> tuple[Array, ...]:
        alpha, gamma = np.asarray(p.alpha), float(p.gamma)
        M, b, g = q_integral_step_map(alpha, gamma, self.q, dt, self.method)
        check_step_stable(M, self.on_unstable,
                          f"{self.method} update of the q-integral observer (n={self.n}, "
                          f"q={self.q}, gamma={gamma:g})", dt,
                          lambda: self._max_period(alpha, gamma))
        M0, _, g0 = q_integral_step_map(alpha, gamma, self.q, dt, self.method, closed=False)
        return np.array([M, M0]), np.array([b, g, g0])

    def _stage(self, V: Array, Y: Array, j: int, phi: Array, L: Array) -> Array:
        Dv = np.empty_like(V)
        q_integral_rhs(V, Y, j, phi, L, self.q, Dv)
        return Dv

    # ------------------------------------------------------------------ state
    def _initial_state(self, z0: Array) -> Array:
        """The integrals of ``y`` restart from zero, with zero error."""
        return np.ascontiguousarray(np.hstack([np.zeros((z0.shape[0], self.q)), z0]))

    @property
    def w_(self) -> Array:
        return self._public(self.state.S.copy())  # type: ignore[no-any-return]

    def params(self) -> dict[str, Any]:
        return {"gamma": self.gamma_, "gamma_spec": self.gamma_spec, "q": self.q,
                "alpha": self.alpha.tolist(), "rho": self.rho, "order": self.n,
                "outputs": list(self.outputs), "model": self.model, "method": self.method}


__all__ = ["QIntegralObserver", "q_integral_matrices", "q_integral_rhs", "q_integral_step_map"]
