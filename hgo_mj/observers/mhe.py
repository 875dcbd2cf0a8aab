r"""A moving-horizon estimator on the normal form: least squares over the last ``N`` samples,
one (or a few) Gauss-Newton iterations per sample, warm-started, with a fixed-weight arrival
cost.

A baseline outside the papers (issue "The nonlinear observer benchmark", item 4). The model is
the normal-form chain sampled with ``phi`` held over a sample (exact for the chain, as the
high-gain observer's ``exact`` method), with process noise ``w_i`` on the top derivative and
measurement noise ``v_i``:

.. math::

    z_{i+1} = F(z_i, u_i) + w_i, \quad F(z, u) = e^{A h} z + \Big(\int_0^h e^{A s} ds\Big)
    B\, \varphi(z, u), \qquad y_i = z_{i,1} + v_i

At sample ``k`` the estimator solves, over the window ``i = k-N+1 .. k`` (``N = horizon``),

.. math::

    \min_{z_{k-N+1}, \dots, z_k}\ \|z_{k-N+1} - \bar z_{k-N+1}\|^2_{P_0^{-1}}
    + \sum_{i} \frac{(y_i - z_{i,1})^2}{r}
    + \sum_{i} \|z_{i+1} - F(z_i, u_i)\|^2_{Q_d^{-1}}

the problem of Rao, Rawlings and Mayne [RRM03]_ (eq. 6-8; Rawlings, Mayne and Diehl [RMD]_,
sec. 4.3), without constraints. ``Q_d = q \int_0^h e^{As} B B^T e^{A^T s} ds`` is the sampled
white noise of intensity ``q`` on ``z_n'`` (the model error of ``phi``), ``P_0 = p_0 I``.

**The approximations made (honestly).**

* *Gauss-Newton, not a converged solve*: each sample runs ``iterations`` (default 1)
  Gauss-Newton steps, warm-started from the previous window's solution shifted by one sample
  and extended by the prediction. A Gauss-Newton step of this least-squares problem linearizes
  ``F`` along the current trajectory and solves the linear problem exactly; that solution is the
  Kalman smoother (forward Kalman filter, backward Rauch-Tung-Striebel pass) on the linearized
  model (Bell [B94]_). ``dphi/dz`` is a central difference of the system's ``phi_batch``.
* *Fixed-weight arrival cost*: the prior ``z_bar`` of the window's first state is the
  estimator's own prediction of that state made before its measurement (the filtering prior of
  [RRM03]_), weighted by the fixed ``P_0`` rather than a propagated covariance.
* *No constraints*: bounds on the state (the reason MHE is used in practice) are not imposed;
  unconstrained and linear, MHE with the exact arrival cost would equal the Kalman filter.

The reported estimate after sample ``k`` is the prediction ``F(z_hat_{k|k}, u_k)`` of
``z(t_{k+1})`` (the convention of every observer here). A dropout (NaN) is a window sample
without a measurement term. Without a system (``order`` only), ``phi = 0``: a linear window
smoother on a chain of integrators. Cost per sample: ``(2n + 1) N`` rows of ``phi_batch`` per
member and iteration, and a compiled smoother of ``O(N n^3)`` per member.

References
----------
.. [RRM03] C. V. Rao, J. B. Rawlings, D. Q. Mayne, "Constrained state estimation for nonlinear
   discrete-time systems: stability and moving horizon approximations", IEEE Trans. Automatic
   Control 48(2), 246-258, 2003 (the moving-horizon problem and its arrival cost).
.. [RMD] J. B. Rawlings, D. Q. Mayne, M. M. Diehl, *Model Predictive Control: Theory,
   Computation, and Design*, 2nd ed., Nob Hill, 2017, ch. 4, sec. 4.3 (moving horizon
   estimation).
.. [B94] B. M. Bell, "The iterated Kalman smoother as a Gauss-Newton method", SIAM J.
   Optimization 4(3), 626-636, 1994.
"""

from __future__ import annotations

from math import factorial
from typing import Any

import numpy as np
from numba import njit

from .._validate import finite_scalar, positive_int
from ..exceptions import DesignError
from ..systems.base import System
from .base import Array, Dimension, Observer, Params, State, register
from .extended_luenberger import phi_and_jacobian
from .finite_difference import _NormalFormEstimate

__all__ = ["MovingHorizonEstimator", "sampled_noise"]


def sampled_noise(n: int, q: float, dt: float) -> Array:
    """``Q_d = q int_0^h e^{As} B B^T e^{A^T s} ds`` for the chain of ``n`` integrators: white
    noise of intensity ``q`` on ``z_n'`` over one sample.

    .. math:: (Q_d)_{ij} = q\\,\\frac{h^{p_i + p_j + 1}}{p_i!\\, p_j!\\, (p_i + p_j + 1)},
              \\quad p_i = n - i

    Parameters
    ----------
    n : int
        Order of the chain.
    q : float
        Noise intensity, > 0.
    dt : float
        Sample period ``h``, > 0.

    Returns
    -------
    (n, n) ndarray

    Examples
    --------
    >>> sampled_noise(2, 3.0, 0.1).round(6)          # q (h^3/3, h^2/2; h^2/2, h)
    array([[0.001, 0.015],
           [0.015, 0.3  ]])
    """
    p = np.arange(n - 1, -1, -1)
    Q = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            k = p[i] + p[j] + 1
            Q[i, j] = q * dt ** k / (factorial(p[i]) * factorial(p[j]) * k)
    return Q


def _chain(n: int, dt: float) -> tuple[Array, Array]:
    """``Phi = e^{A h}`` and ``g = (int_0^h e^{As} ds) B`` of the chain."""
    Phi = np.zeros((n, n))
    for i in range(n):
        for j in range(i, n):
            Phi[i, j] = dt ** (j - i) / factorial(j - i)
    g = np.array([dt ** (n - i) / factorial(n - i) for i in range(n)])
    return Phi, g


@njit(cache=True)
def window_smooth(traj: Array, ywin: Array, W: Array, J: Array, prior: Array, count: Array,
                  Phi: Array, g: Array, P0: Array, Qd: Array, r: float) -> None:  # pragma: no cover
    """One Gauss-Newton step of every member's window problem, ``traj`` ``(B, N, n)`` in place:
    the Kalman filter and Rauch-Tung-Striebel smoother on the model linearized along ``traj``
    (``W``, ``J`` ``(B, N - 1)``, ``(B, N - 1, n)``: ``phi`` and ``dphi/dz`` there), from the
    prior ``prior[b, s]`` with covariance ``P0`` at the window's first sample
    ``s = N - min(count[b], N)``; NaN in ``ywin`` ``(B, N)``: no measurement term."""
    B, N, n = traj.shape
    xp = np.empty((N, n))
    xf = np.empty((N, n))
    Pp = np.empty((N, n, n))
    Pf = np.empty((N, n, n))
    Ai = np.empty((n, n))
    for b in range(B):
        s = N - min(count[b], N)
        x = prior[b, s].copy()
        P = P0.copy()
        for i in range(s, N):
            if i > s:
                k = i - 1
                Ai[:, :] = Phi
                lin = W[b, k]
                for c in range(n):
                    lin += J[b, k, c] * (x[c] - traj[b, k, c])
                    for r_ in range(n):
                        Ai[r_, c] += g[r_] * J[b, k, c]
                x = Phi @ x + g * lin
                P = Ai @ P @ Ai.T + Qd
            xp[i] = x
            Pp[i] = P
            y = ywin[b, i]
            if y == y:
                S = P[0, 0] + r
                K = P[:, 0] / S
                x = x + K * (y - x[0])
                P = P - np.outer(K, P[0, :])
                P = 0.5 * (P + P.T)
            xf[i] = x
            Pf[i] = P
        xs = xf[N - 1].copy()
        traj[b, N - 1] = xs
        for i in range(N - 2, s - 1, -1):
            Ai[:, :] = Phi
            for c in range(n):
                for r_ in range(n):
                    Ai[r_, c] += g[r_] * J[b, i, c]
            Gt = np.linalg.solve(Pp[i + 1], Ai @ Pf[i])  # G^T = Pp^-1 A Pf (symmetric P)
            xs = xf[i] + Gt.T @ (xs - xp[i + 1])
            traj[b, i] = xs


@njit(cache=True)
def _predict(Z: Array, W: Array, Phi: Array, g: Array, out: Array) -> None:  # pragma: no cover
    """``out[b] = Phi Z[b] + g W[b]`` row by row."""
    for b in range(Z.shape[0]):
        out[b] = Phi @ Z[b] + g * W[b]


@register
class MovingHorizonEstimator(_NormalFormEstimate, Observer):
    """Moving-horizon estimator on the normal form: a window of ``horizon`` samples, Gauss-Newton
    (an iterated Kalman smoother) warm-started each sample, fixed-weight arrival cost.

    .. math:: \\min\\ \\|z_{k-N+1} - \\bar z\\|^2_{P_0^{-1}} + \\sum_i \\frac{(y_i - z_{i,1})^2}{r}
              + \\sum_i \\|z_{i+1} - F(z_i, u_i)\\|^2_{Q_d^{-1}}

    (see the module docstring for the model and every approximation made).

    Parameters
    ----------
    system : System, optional
        Gives the order, ``phi`` (``System.phi_batch``) and the map back to physical
        coordinates. Without one, give ``order`` (then ``phi = 0``).
    q : float
        Intensity of the white process noise on ``z_n'`` (the model error), > 0. Tunable.
    r : float
        Variance of the measurement noise, > 0 (the estimate depends on ``q / r`` and
        ``p0 / r`` only, so ``r`` is not searched).
    p0 : float
        Arrival-cost covariance ``P_0 = p0 I``, > 0. Tunable.
    horizon : int
        Samples in the window ``N`` (default 10); configuration, not tuned.
    iterations : int
        Gauss-Newton steps per sample (default 1).
    order : int, optional
        ``n`` when no system is given.
    outputs : tuple of int
        The measured channel, a 1-tuple (default ``(0,)``).
    x_hat0, z_hat0 : array_like, optional
        Initial estimate (default zero): the prior of the first window.

    Raises
    ------
    DesignError
        ``q``, ``r`` or ``p0`` not a positive finite number, ``horizon`` or ``iterations`` not a
        positive integer, or more than one output.

    References
    ----------
    C. V. Rao, J. B. Rawlings, D. Q. Mayne, IEEE TAC 48(2), 2003; J. B. Rawlings, D. Q. Mayne,
    M. M. Diehl, *Model Predictive Control*, 2nd ed., 2017, ch. 4; B. M. Bell, SIAM J. Optim.
    4(3), 1994.

    Examples
    --------
    >>> import numpy as np
    >>> ob = MovingHorizonEstimator(order=2, q=1.0, r=1e-6, horizon=5)
    >>> t = np.arange(0.0, 0.5, 0.01)
    >>> rows = ob.run((2.0 * t)[:, None], np.zeros((t.size, 0)), 0.01)   # a ramp, y' = 2
    >>> rows.z_hat[0, -1].round(3)
    array([1., 2.])
    """

    name = "mhe"
    summary = "moving-horizon estimator: Gauss-Newton window least squares, fixed arrival cost"
    reference = "Rao, Rawlings & Mayne, IEEE TAC 48(2), 2003; Rawlings et al., MPC, ch. 4"
    family_diagnostics = ()

    def __init__(self, system: System | None = None, *, q: float = 10.0, r: float = 1e-4,
                 p0: float = 1.0, horizon: int = 10, iterations: int = 1,
                 order: int | None = None, outputs: Any = (0,), x_hat0: Any = None,
                 z_hat0: Any = None) -> None:
        super().__init__(system, order=order, outputs=outputs)
        if len(self.outputs) != 1:
            raise DesignError(f"{type(self).__name__} reads one output: outputs must be a "
                              f"1-tuple such as (0,); found {list(self.outputs)}")
        self.q = finite_scalar("q", q, positive=True)
        self.r = finite_scalar("r", r, positive=True)
        self.p0 = finite_scalar("p0", p0, positive=True)
        self.horizon = positive_int("horizon", horizon, floats=False)
        self.iterations = positive_int("iterations", iterations, floats=False)
        self._start_values(x_hat0, z_hat0)

    def _parameters(self) -> dict[str, Any]:
        """The weights: ``q`` (process), ``r`` (measurement), ``p0`` (arrival cost)."""
        return {"q": self.q, "r": self.r, "p0": self.p0}

    def _check_parameter(self, name: str, value: Any) -> Array:
        return np.array(finite_scalar(f"{self.name}: {name}", value, positive=True))

    def tuning_space(self) -> dict[str, Dimension]:
        """``q`` over ``[q / 1000, 1000 q]`` and ``p0`` over ``[p0 / 100, 100 p0]``, log scale;
        ``r`` fixed (only the ratios to ``r`` change the estimate)."""
        return {"q": Dimension("q", self.q / 1e3, self.q * 1e3, True, self.q),
                "p0": Dimension("p0", self.p0 / 1e2, self.p0 * 1e2, True, self.p0)}

    def _init(self, p: Params, x0: Array | None, z0: Array | None,
              u0: Array) -> dict[str, Any]:
        z = self._start_z(x0, z0, u0)
        B, N = z.shape[0], self.horizon
        window = np.repeat(z[:, None, :], N, axis=1)
        return {"z": z, "ywin": np.full((B, N), np.nan),
                "uwin": np.zeros((B, N, u0.shape[1])), "traj": window,
                "prior": window.copy(), "count": np.zeros(B, dtype=np.int64),
                **self._held_fields(z, u0)}

    def _phi(self, Z: Array, U: Array, jacobian: bool) -> tuple[Array, Array]:
        """``phi`` (and ``dphi/dz``) at the rows; zero without a system."""
        if self.system is None:
            return np.zeros(Z.shape[0]), np.zeros(Z.shape)
        if jacobian:
            return phi_and_jacobian(self.system, Z, U)
        W = np.asarray(self.system.phi_batch(Z, U), dtype=np.float64).reshape(-1)
        return W, np.zeros(Z.shape)

    def _step(self, p: Params, s: State, Y: Array, U: Array, dt: float, X: Array, Z: Array,
              D: Array) -> None:
        B, N, n = s.traj.shape
        Phi, g = _chain(n, dt)
        Qd = sampled_noise(n, float(p.q), dt)
        P0 = float(p.p0) * np.eye(n)
        r = float(p.r)
        m = s.uwin.shape[2]
        for j in range(Y.shape[1]):
            for name in ("ywin", "uwin", "traj", "prior"):  # the window moves on one sample
                a = getattr(s, name)
                a[:, :-1] = a[:, 1:].copy()
            s.ywin[:, -1] = Y[:, j, 0]
            s.uwin[:, -1] = U[:, j, :m]
            s.traj[:, -1] = s.z
            s.prior[:, -1] = s.z
            np.minimum(s.count + 1, N, out=s.count)
            for _ in range(self.iterations):
                W, J = self._phi(s.traj[:, :-1].reshape(-1, n),
                                 s.uwin[:, :-1].reshape(B * (N - 1), m), True)
                window_smooth(s.traj, s.ywin, W.reshape(B, N - 1),
                              J.reshape(B, N - 1, n), s.prior, s.count, Phi, g, P0, Qd, r)
            now = np.ascontiguousarray(s.traj[:, -1])
            w, _ = self._phi(now, np.ascontiguousarray(U[:, j, :m]), False)
            _predict(now, w, Phi, g, s.z)
            Z[:, j] = s.z
        self._write_x(s, Z, U, X)

    def _current(self, p: Params, s: State) -> tuple[Array, Array, Array]:
        return self._x_of(s), s.z.copy(), np.zeros((s.z.shape[0], 0))

    def params(self) -> dict[str, Any]:
        return {"q": self.q, "r": self.r, "p0": self.p0, "horizon": self.horizon,
                "iterations": self.iterations, "order": self.n, "outputs": list(self.outputs)}
