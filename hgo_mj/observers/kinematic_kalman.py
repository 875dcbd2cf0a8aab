r"""A discrete Kalman filter on a chain of integrators: the model-free tracking filter of
Bar-Shalom, Li and Kirubarajan [BLK01]_, one per measured signal.

A baseline outside the papers, and the model-free estimator of ``ObserverInTheLoop``'s
``measure=`` (``docs/results/wrappers.md``). The signal and its derivatives
``z = (y, y', ..., y^(n-1))`` follow a chain of ``n`` integrators whose ``n``-th derivative is
a constant ``a_k`` over each sample period ``h`` and white from period to period (the
*discrete white noise acceleration* model of [BLK01]_, sec. 6.3.2, for ``n = 2``, written for
any ``n``):

.. math::

    z_{k+1} = \Phi z_k + \Gamma a_k, \qquad y_k = z_{1,k} + v_k, \qquad
    a_k \sim N(0, q), \quad v_k \sim N(0, r),

    \Phi_{ij} = \frac{h^{j-i}}{(j-i)!}\ (j \ge i), \qquad
    \Gamma_i = \frac{h^{n-i+1}}{(n-i+1)!}, \qquad Q = q\, \Gamma \Gamma^T

(``n = 2``: :math:`\Gamma = (h^2/2, h)^T`, [BLK01]_ eq. 6.3.2-4). Each sample is the Kalman
filter's measurement update, then its time update (the order of every filter of the package:
the row after sample ``k`` is the prediction of ``z(t_{k+1})``):

.. math::

    s = P_{11} + r, \quad K = P_{:,1} / s, \quad \hat z \leftarrow \hat z + K (y_k - \hat z_1),
    \quad P \leftarrow P - K K^T s; \qquad
    \hat z \leftarrow \Phi \hat z, \quad P \leftarrow \Phi P \Phi^T + Q.

The covariance arithmetic is that of :mod:`hgo_mj.observers.kalman` (its kernels
``_condition_selection`` and ``_sandwich``, called from one numba loop over the block); a NaN
sample (a dropout) skips the measurement update.

**What it models, exactly.** Without noise, a polynomial of degree below ``n`` is a
trajectory of the model with ``a_k = 0``: the estimation error then decays geometrically to
zero (tested). The random actions of a Gymnasium MuJoCo environment hold the controls over
each environment step, so the joint accelerations are nearly constant within a step and jump
between steps: the model of ``n = 2``.

**Steady state.** For ``n = 2`` the gain tends to that of the alpha-beta filter,
:math:`K = (\alpha, \beta / h)`, which depends on the *tracking index*
:math:`\lambda = \sqrt{q / r}\, h^2` alone [K84]_ ([BLK01]_, sec. 6.5):

.. math::

    \alpha = -\frac{\lambda^2 + 8\lambda - (\lambda + 4)\sqrt{\lambda^2 + 8\lambda}}{8},
    \qquad \beta = \frac{\lambda^2 + 4\lambda - \lambda\sqrt{\lambda^2 + 8\lambda}}{4}

(tested, and for ``n = 3`` against the discrete algebraic Riccati equation). The estimate
depends on ``q / r`` alone; ``r`` sets the covariance's scale (the NIS). The tuning space is
``q`` (log scale, ``Q_SPAN`` each way), ``r`` kept.

**Consistency.** The diagnostic ``nis`` is the normalized innovation squared of each update
(:mod:`hgo_mj.observers.kalman`), chi-square with one degree of freedom when ``q`` and ``r``
are right.

References
----------
.. [BLK01] Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking
   and Navigation*, Wiley 2001, sec. 6.3.2 (the discrete white noise acceleration model),
   sec. 6.5 (steady-state filters: alpha-beta).
.. [K84] P. R. Kalata, "The tracking index: a generalized parameter for alpha-beta and
   alpha-beta-gamma target trackers", IEEE Trans. Aerospace and Electronic Systems 20(2),
   174-182, 1984.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from .._validate import finite_scalar, positive_definite
from ..exceptions import DesignError, DivergenceError
from ..systems.base import System
from .base import Array, Dimension, Observer, Params, State, register
from .finite_difference import _NormalFormEstimate
from .kalman import _condition_selection, _first_nonfinite, _sandwich

__all__ = ["KinematicKalmanFilter"]

#: the tuning space of ``q``: this factor below and above the constructor's value (log scale;
#: 10^5 in ``q`` is a factor of about 316 in the tracking index)
Q_SPAN = 1e5
#: the measured state: ``z_1`` (a selection output)
_SEL = np.zeros(1, dtype=np.int64)


@njit(cache=True)
def kinematic_block(X: Array, P: Array, nis: Array, Y: Array, R: Array, Phi: Array, Qd: Array,
                    Zs: Array, Ds: Array) -> int:  # pragma: no cover - numba
    """The filter over a block ``Y`` ``(B, T, 1)``, in place on ``X`` ``(B, n)``, ``P``
    ``(B, n, n)``, ``nis`` ``(B,)``: per sample the measurement update
    (:func:`hgo_mj.observers.kalman._condition_selection`), the mean ``Phi X`` and the
    covariance ``Phi P Phi^T + Qd`` (:func:`~hgo_mj.observers.kalman._sandwich`); the
    prediction into ``Zs[:, j]``, the NIS into ``Ds[:, j, 0]``. Returns the sample at which an
    estimate left the finite numbers (the state left there), else -1."""
    B, T = Y.shape[0], Y.shape[1]
    n = X.shape[1]
    y = np.empty((B, 1))
    tmp = np.empty(n)
    M = np.empty((n, n))
    sel = np.zeros(1, dtype=np.int64)
    for j in range(T):
        for b in range(B):
            y[b, 0] = Y[b, j, 0]
        _condition_selection(X, P, y, sel, R, True, nis)
        for b in range(B):
            for i in range(n):
                s = 0.0
                for k in range(i, n):
                    s += Phi[i, k] * X[b, k]
                tmp[i] = s
            for i in range(n):
                X[b, i] = tmp[i]
                Zs[b, j, i] = tmp[i]
            _sandwich(Phi, P[b], Qd, M)
            Ds[b, j, 0] = nis[b]
        if _first_nonfinite(X) >= 0:
            return j
    return -1


def chain_model(n: int, h: float) -> tuple[Array, Array]:
    """The transition ``Phi`` ``(n, n)`` and noise gain ``Gamma`` ``(n,)`` of the chain of
    ``n`` integrators over one period ``h`` with its ``n``-th derivative constant over it.

    Parameters
    ----------
    n : int
        The chain's order (1 or more).
    h : float
        The sample period [s].

    Returns
    -------
    Phi : ndarray
        ``Phi[i, j] = h^(j-i) / (j-i)!`` for ``j >= i``, else 0.
    Gamma : ndarray
        ``Gamma[i] = h^(n-i) / (n-i)!`` (0-based ``i``).

    Examples
    --------
    >>> Phi, Gamma = chain_model(2, 0.1)
    >>> Phi.tolist(), Gamma.round(6).tolist()
    ([[1.0, 0.1], [0.0, 1.0]], [0.005, 0.1])
    """
    Phi = np.zeros((n, n))
    for i in range(n):
        for j in range(i, n):
            Phi[i, j] = h ** (j - i) / math.factorial(j - i)
    Gamma = np.array([h ** (n - i) / math.factorial(n - i) for i in range(n)])
    return Phi, Gamma


@register
class KinematicKalmanFilter(_NormalFormEstimate, Observer):
    """A discrete Kalman filter on the chain of integrators ``z = (y, y', ..., y^(n-1))``
    whose ``n``-th derivative is piecewise-constant white noise (see the module docstring):
    model-free, one measured signal; for ``n = 2`` its steady state is the alpha-beta filter.

    .. math:: z_{k+1} = \\Phi z_k + \\Gamma a_k, \\quad a_k \\sim N(0, q), \\qquad
              y_k = z_{1,k} + v_k, \\quad v_k \\sim N(0, r)

    Parameters
    ----------
    system : System, optional
        Gives the order ``n`` (its single-output normal form) and the map back to physical
        coordinates (``from_normal``); without one, give ``order``: the estimate is
        ``z_hat = (y, y', ...)`` itself. Its model is not used.
    q : float
        Variance of the ``n``-th derivative, constant over each sample period (for ``n = 2``
        the acceleration, in (units / s^2)^2), > 0. Tunable.
    r : float
        Variance of the measurement noise, > 0. The estimate depends on ``q / r`` alone.
    order : int, optional
        ``n`` when no system is given.
    P0 : float or (n, n) array_like, optional
        Initial covariance (a scalar: times the identity); default ``1e6 r I``, a diffuse
        start that the first samples override.
    outputs : tuple of int
        The measured channel, a 1-tuple (default ``(0,)``).
    x_hat0, z_hat0 : array_like, optional
        Initial estimate (default zero).

    Raises
    ------
    DesignError
        ``q`` or ``r`` not positive and finite, ``P0`` not positive definite, more than one
        output, or both initial estimates given.

    References
    ----------
    Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
    Navigation*, 2001, sec. 6.3.2, 6.5; P. R. Kalata, IEEE TAES 20(2), 1984.

    Examples
    --------
    A ramp, noise-free: the velocity is exact once the diffuse start is forgotten.

    >>> import numpy as np
    >>> ob = KinematicKalmanFilter(order=2, q=1.0, r=1e-6)
    >>> t = np.arange(50) * 0.01
    >>> rows = ob.run((0.2 + 3.0 * t)[:, None], np.zeros((50, 0)), 0.01)
    >>> round(float(rows.z_hat[0, -1, 1]), 6)
    3.0
    """

    name = "kinematic_kalman"
    summary = ("discrete Kalman filter on a chain of integrators with piecewise-constant "
               "white n-th derivative (model-free; alpha-beta in steady state)")
    reference = "Bar-Shalom, Li & Kirubarajan (2001), sec. 6.3.2, 6.5; Kalata (1984)"
    family_diagnostics = ("nis",)
    measurement_update = True

    def __init__(self, system: System | None = None, *, q: float = 1.0, r: float = 1e-6,
                 order: int | None = None, P0: Any = None, outputs: Any = (0,),
                 x_hat0: Any = None, z_hat0: Any = None) -> None:
        super().__init__(system, order=order, outputs=outputs)
        if len(self.outputs) != 1:
            raise DesignError(f"{type(self).__name__} reads one output: outputs must be a "
                              f"1-tuple such as (0,); found {list(self.outputs)}")
        self.q = finite_scalar("q", q, positive=True)
        self.r = finite_scalar("r", r, positive=True)
        self.P0 = None if P0 is None else positive_definite("P0", P0, self.n)
        self._start_values(x_hat0, z_hat0)
        #: ``(Phi, Gamma Gamma^T)`` by sample period (the last few)
        self._chains: dict[float, tuple[Array, Array]] = {}

    def _parameters(self) -> dict[str, Any]:
        """The noise variances ``q`` (the ``n``-th derivative's) and ``r`` (the sensor's)."""
        return {"q": self.q, "r": self.r}

    def _check_parameter(self, name: str, value: Any) -> Array:
        return np.array(finite_scalar(f"{self.name}: {name}", value, positive=True))

    def tuning_space(self) -> dict[str, Dimension]:
        """``q`` over ``[q / Q_SPAN, Q_SPAN q]`` on a log scale, ``r`` kept: the estimate
        depends on ``q / r`` alone (the tracking index ``sqrt(q / r) h^2``), so one variable
        spans every filter; a larger ``q`` follows faster changes of the ``n``-th derivative
        and passes more noise."""
        return {"q": Dimension("q", self.q / Q_SPAN, self.q * Q_SPAN, True, self.q)}

    def _chain(self, h: float) -> tuple[Array, Array]:
        got = self._chains.get(h)
        if got is None:
            if len(self._chains) >= 8:
                self._chains.clear()
            Phi, Gamma = chain_model(self.n, h)
            got = self._chains[h] = (Phi, np.outer(Gamma, Gamma))
        return got

    def _init(self, p: Params, x0: Array | None, z0: Array | None,
              u0: Array) -> dict[str, Any]:
        z = self._start_z(x0, z0, u0)
        B = z.shape[0]
        P0 = self.P0 if self.P0 is not None else 1e6 * float(p.r) * np.eye(self.n)
        mapped = {} if self._identity else {"u": np.array(u0, dtype=np.float64)}
        return {"z": z, "P": np.ascontiguousarray(np.tile(P0, (B, 1, 1))),
                "nis": np.full(B, np.nan), **mapped, **self._held_fields(z, u0)}

    def _step(self, p: Params, s: State, Y: Array, U: Array, dt: float, X: Array, Z: Array,
              D: Array) -> None:
        Phi, GG = self._chain(dt)
        R = np.array([[float(p.r)]])
        j = kinematic_block(s.z, s.P, s.nis, np.ascontiguousarray(Y[:, :, :1]), R, Phi,
                            float(p.q) * GG, Z, D)
        if j >= 0:
            b = _first_nonfinite(s.z)
            raise DivergenceError(f"{type(self).__name__} estimate left the finite numbers: "
                                  f"{s.z[b].tolist()} (member {b}, sample {j})")
        if not self._identity and U.shape[1]:  # the newest input, for _filtered's map
            s.u = np.array(U[:, -1], dtype=np.float64)
        self._write_x(s, Z, U, X)

    def _filtered(self, p: Params, s: State, Y: Array) -> Array:
        """``z_{k|k}``: the measurement update of a copy with the channel of ``Y``, mapped to
        physical coordinates (with the newest input) where the normal form is not the state."""
        z, P = s.z.copy(), s.P.copy()
        y = np.ascontiguousarray(Y[:, self._cols_index][:, :1])
        _condition_selection(z, P, y, _SEL, np.array([[float(p.r)]]), True,
                             np.empty(z.shape[0]))
        if self._identity:
            return z
        X = np.empty((z.shape[0], 1, len(self.state_names)))
        self._to_physical(s.copy(), z[:, None], s.u[:, None], X)
        return X[:, 0]

    def _current(self, p: Params, s: State) -> tuple[Array, Array, Array]:
        return self._x_of(s), s.z.copy(), s.nis[:, None].copy()

    def covariance(self, state: State) -> Array | None:
        """The covariance ``P`` ``(B, n, n)`` of ``z_hat`` where it is the estimate (no system,
        or a normal form that is the state); None otherwise."""
        return state.P.copy() if self._identity else None

    def params(self) -> dict[str, Any]:
        return {"q": self.q, "r": self.r, "order": self.n,
                "P0": None if self.P0 is None else self.P0.tolist(),
                "outputs": list(self.outputs)}
