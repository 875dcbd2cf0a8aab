r"""The engineer's first estimate: low-pass filtered backward differences of the measurement.

A baseline outside the papers (issue "The nonlinear observer benchmark", item 4): what one does
before designing an observer. The output is differentiated ``n - 1`` times by cascaded backward
differences, each through the first-order derivative filter of Åström and Hägglund [AH95]_
(``s / (1 + tau s)``, sec. 3.3, discretized by the backward difference of their sec. 3.6):

.. math::

    d_0[k] &= y_k, \qquad
    d_i[k] = a\, d_i[k-1] + (1 - a)\,\frac{d_{i-1}[k] - d_{i-1}[k-1]}{h},
    \quad a = \frac{\tau}{\tau + h}, \quad i = 1, \dots, n-1 \\
    \hat z_i(t_{k+1}) &= \sum_{j=0}^{n-i} \frac{h^j}{j!}\, d_{i-1+j}[k]

with ``h`` the sample period. ``tau = 0`` is the plain backward difference
``(y_k - y_{k-1}) / h`` (Franklin, Powell and Workman [FPW]_, sec. 4.3.1, the backward
rectangular rule). The reported estimate is that of the next sample instant (the convention of
every observer here: the row after sample ``k`` estimates ``z(t_{k+1})``), extrapolated by the
Taylor polynomial of the chain of integrators (``e^{A h}``) from the differences at ``t_k``.

**Noise.** Of white measurement noise of variance ``s^2``, the backward difference has variance
``2 s^2 / h^2``; filtered, the first difference has variance
``2 s^2 (1 - a)^2 / ((1 + a) h^2)`` (the squared impulse response of
``(1 - q^{-1}) / (1 - a q^{-1})`` sums to ``2 / (1 + a)``). Each further difference multiplies by
about ``2 / h^2`` again: beyond the first derivative this baseline is mostly noise, which is the
point of comparing it.

**Lag.** The filtered difference lags the true derivative by about ``tau + h / 2``; a polynomial of
degree below ``n`` is differentiated exactly only without the filter (``tau = 0``), up to the
``O(h)`` offset of a backward difference (the difference of ``t^2`` is ``2 t - h``).

**Dropouts.** A NaN sample advances the differences open loop by the chain of integrators
(``d <- e^{A h} d``): the next valid sample is differenced against that prediction.

References
----------
.. [AH95] K. J. Åström, T. Hägglund, *PID Controllers: Theory, Design, and Tuning*, 2nd ed., ISA,
   1995, sec. 3.3 (the derivative filter ``s T_d / (1 + s T_d / N)``) and sec. 3.6 (its
   backward-difference discretization).
.. [FPW] G. F. Franklin, J. D. Powell, M. L. Workman, *Digital Control of Dynamic Systems*, 3rd
   ed., Addison-Wesley, 1998, sec. 4.3.1 (the backward rectangular rule ``s = (z - 1) / (T z)``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from .._validate import finite_scalar, vector
from ..exceptions import DesignError
from ..systems.base import System
from .base import Array, Dimension, Observer, Params, State, batch_rows, register
from .high_gain import _is_identity

__all__ = ["FiniteDifferenceObserver", "filtered_difference_variance"]

#: the bounds of ``tau`` searched (seconds, log scale)
TAU_RANGE = (1e-4, 1.0)


@njit(cache=True)
def _taylor(d: Array, h: float, out: Array) -> None:  # pragma: no cover
    """``out = e^{A h} d`` for the chain of integrators: ``out_i = sum_j h^j / j! d_{i+j}``."""
    n = d.shape[0]
    for i in range(n):
        acc = 0.0
        c = 1.0
        for j in range(n - i):
            if j > 0:
                c = c * h / j
            acc += c * d[i + j]
        out[i] = acc


@njit(cache=True)
def difference_advance(D: Array, Z: Array, started: Array, Y: Array, a: float, h: float,
                       Zout: Array) -> None:  # pragma: no cover
    """Consume ``Y`` ``(B, T, 1)``: the cascaded filtered differences ``D`` ``(B, n)`` (at the
    last sample instant) and the reported estimates ``Z`` ``(B, n)`` in place, rows into
    ``Zout`` ``(B, T, n)``. ``started[b]``: member ``b`` has had a valid sample (the first one
    sets ``d_0`` and leaves the derivatives at their initial values)."""
    B, n = D.shape
    tmp = np.empty(n)
    for b in range(B):
        for t in range(Y.shape[1]):
            y = Y[b, t, 0]
            if y == y:
                prev = D[b, 0]
                D[b, 0] = y
                if started[b]:
                    for i in range(1, n):
                        old = D[b, i]
                        D[b, i] = a * old + (1.0 - a) * ((D[b, i - 1] - prev) / h)
                        prev = old
                started[b] = 1
            else:  # a dropout: the chain open loop
                _taylor(D[b], h, tmp)
                for i in range(n):
                    D[b, i] = tmp[i]
            _taylor(D[b], h, tmp)
            for i in range(n):
                Z[b, i] = tmp[i]
                Zout[b, t, i] = tmp[i]


def filtered_difference_variance(s2: float, tau: float, dt: float) -> float:
    """The stationary variance of the first filtered backward difference of white noise.

    .. math:: \\operatorname{var} d_1 = \\frac{2 s^2 (1 - a)^2}{(1 + a) h^2},
              \\quad a = \\frac{\\tau}{\\tau + h}

    (``2 s^2 / h^2`` for the plain difference, ``tau = 0``; see the module docstring).

    Parameters
    ----------
    s2 : float
        Variance of the white measurement noise.
    tau : float
        Filter time constant [s], >= 0.
    dt : float
        Sample period ``h`` [s], > 0.

    Returns
    -------
    float
        The variance of ``d_1``.

    Raises
    ------
    DesignError
        A negative ``s2`` or ``tau``, or ``dt`` not positive.

    Examples
    --------
    >>> filtered_difference_variance(1e-6, 0.0, 1e-3)   # 2 s^2 / h^2
    2.0
    >>> round(filtered_difference_variance(1e-6, 9e-3, 1e-3), 6)  # a = 0.9
    0.010526
    """
    s2 = finite_scalar("s2", s2, nonnegative=True)
    tau = finite_scalar("tau", tau, nonnegative=True)
    h = finite_scalar("dt", dt, positive=True)
    a = tau / (tau + h)
    return 2.0 * s2 * (1.0 - a) ** 2 / ((1.0 + a) * h * h)


class _NormalFormEstimate:
    """``x_hat`` from ``z_hat`` as :class:`~hgo_mj.observers.HighGainObserver` does: ``z_hat``
    itself without a system or where the normal form is the state, else ``from_normal``
    (:meth:`Observer._to_physical`); shared by the baselines of this issue."""

    system: System | None
    n: int
    _identity: bool
    _start: tuple[Array | None, Array | None]

    def _start_values(self, x_hat0: Any, z_hat0: Any) -> None:
        if x_hat0 is not None and z_hat0 is not None:
            raise DesignError("give x_hat0 or z_hat0, not both")
        names = self.state_names  # type: ignore[attr-defined]
        self._start = (None if x_hat0 is None else vector("x_hat0", x_hat0, len(names)),
                       None if z_hat0 is None else vector("z_hat0", z_hat0, self.n))
        self._identity = self.system is None or _is_identity(self.system, self.n)

    def _start_z(self, x0: Array | None, z0: Array | None, u0: Array) -> Array:
        """The initial ``(B, n)`` observer coordinates (given, or the constructor's, or 0)."""
        B = u0.shape[0]
        if x0 is None and z0 is None:
            ix, iz = self._start
            x0 = None if ix is None else batch_rows("x_hat0", ix, ix.size, B)
            z0 = None if iz is None else batch_rows("z_hat0", iz, iz.size, B)
        z: Array = self._initial_z(x0, z0, u0)  # type: ignore[attr-defined]
        return np.array(z, dtype=np.float64, order="C")

    def _held_fields(self, z: Array, u0: Array) -> dict[str, Any]:
        """The mapped start (``x_held``, ``inverse_failures``) where ``x_hat`` is not ``z``."""
        if self._identity:
            return {}
        s = State(**self._core(z.shape[0]))  # type: ignore[attr-defined]
        X = np.empty((z.shape[0], 1, len(self.state_names)))  # type: ignore[attr-defined]
        self._to_physical(s, z[:, None], u0[:, None], X)  # type: ignore[attr-defined]
        return dict(s.fields)

    def _write_x(self, s: State, Z: Array, U: Array, X: Array) -> None:
        if self._identity:
            np.copyto(X, Z)
        elif Z.shape[1]:
            self._to_physical(s, Z, U, X)  # type: ignore[attr-defined]

    def _x_of(self, s: State) -> Array:
        return s.z.copy() if self._identity else s.x_held.copy()  # type: ignore[no-any-return]


@register
class FiniteDifferenceObserver(_NormalFormEstimate, Observer):
    """Low-pass filtered backward differences of the output: ``z = (y, y', ...)``.

    The baseline every observer should beat: no model, one tuning knob (the derivative filter's
    time constant ``tau``). See the module docstring for the equations.

    .. math:: d_i[k] = a\\, d_i[k-1] + (1 - a)\\,\\frac{d_{i-1}[k] - d_{i-1}[k-1]}{h},
              \\qquad a = \\frac{\\tau}{\\tau + h}

    Parameters
    ----------
    system : System, optional
        Gives the order ``n`` (its single-output normal form) and the map back to physical
        coordinates (``from_normal``, as the high-gain observer uses it); without one, give
        ``order``: the estimate is ``z_hat = (y, y', ...)`` itself.
    tau : float
        Time constant [s] of the first-order low-pass filter of every difference, >= 0
        (0: plain backward differences). Tunable.
    order : int, optional
        ``n`` when no system is given.
    outputs : tuple of int
        The measured channel, a 1-tuple (default ``(0,)``).
    x_hat0, z_hat0 : array_like, optional
        Initial estimate (default zero); the first valid sample replaces ``z_1`` by the
        measurement, the derivatives start from these values.

    Raises
    ------
    DesignError
        ``tau`` negative or not a finite number, more than one output, or both initial
        estimates given.

    Notes
    -----
    Variance of the first difference of white noise of variance ``s^2``:
    :func:`filtered_difference_variance` (``2 s^2 / h^2`` unfiltered).

    References
    ----------
    K. J. Åström, T. Hägglund, *PID Controllers*, 2nd ed., 1995, sec. 3.3 and 3.6 (the filtered
    derivative and its backward-difference form); G. F. Franklin, J. D. Powell, M. L. Workman,
    *Digital Control of Dynamic Systems*, 3rd ed., 1998, sec. 4.3.1.

    Examples
    --------
    >>> import numpy as np
    >>> ob = FiniteDifferenceObserver(order=2, tau=0.0)
    >>> rows = ob.run(np.array([[0.0], [0.1], [0.2]]), np.zeros((3, 0)), 0.1)
    >>> rows.z_hat[0, -1].round(6)   # y(t_3) = 0.3 and y' = 1, a ramp differentiated exactly
    array([0.3, 1. ])
    """

    name = "finite_difference"
    summary = "low-pass filtered backward differences of the output (the engineer's baseline)"
    reference = "Åström & Hägglund, PID Controllers (1995), sec. 3.3, 3.6; Franklin et al., sec. 4.3.1"
    family_diagnostics = ()

    def __init__(self, system: System | None = None, *, tau: float = 0.005,
                 order: int | None = None, outputs: Any = (0,), x_hat0: Any = None,
                 z_hat0: Any = None) -> None:
        super().__init__(system, order=order, outputs=outputs)
        if len(self.outputs) != 1:
            raise DesignError(f"{type(self).__name__} reads one output: outputs must be a "
                              f"1-tuple such as (0,); found {list(self.outputs)}")
        self.tau = finite_scalar("tau", tau, nonnegative=True)
        self._start_values(x_hat0, z_hat0)

    def _parameters(self) -> dict[str, Any]:
        """The filter time constant ``tau`` [s] (Åström and Hägglund, sec. 3.3)."""
        return {"tau": self.tau}

    def _check_parameter(self, name: str, value: Any) -> Array:
        return np.array(finite_scalar(f"{self.name}: tau", value, nonnegative=True))

    def tuning_space(self) -> dict[str, Dimension]:
        """``tau`` over ``[1e-4, 1]`` s on a log scale: from about no filter at a kilohertz
        sample rate to a filter slower than the plants' motions."""
        lo, hi = TAU_RANGE
        return {"tau": Dimension("tau", lo, hi, True, min(max(self.tau, lo), hi))}

    def _init(self, p: Params, x0: Array | None, z0: Array | None,
              u0: Array) -> dict[str, Any]:
        z = self._start_z(x0, z0, u0)
        return {"z": z, "d": z.copy(), "started": np.zeros(z.shape[0], dtype=np.int64),
                **self._held_fields(z, u0)}

    def _step(self, p: Params, s: State, Y: Array, U: Array, dt: float, X: Array, Z: Array,
              D: Array) -> None:
        tau = float(p.tau)
        difference_advance(s.d, s.z, s.started, Y, tau / (tau + dt), dt, Z)
        self._write_x(s, Z, U, X)

    def _current(self, p: Params, s: State) -> tuple[Array, Array, Array]:
        return self._x_of(s), s.z.copy(), np.zeros((s.z.shape[0], 0))

    def params(self) -> dict[str, Any]:
        return {"tau": self.tau, "order": self.n, "outputs": list(self.outputs)}

