r"""The extended Luenberger observer of Zeitz [Z87]_ on the observability normal form.

A baseline outside the papers (issue "The nonlinear observer benchmark", item 4). On the normal
form ``z' = A z + B phi(z, u)``, ``y = C z = z_1`` (``A`` the chain of integrators):

.. math::

    \dot{\hat z} &= A \hat z + B \varphi(\hat z, u) + L(\hat z, u)\,(y - \hat z_1), \\
    L(\hat z, u) &= q\big(A_\varphi(\hat z, u)\big)\, e_n, \qquad
    A_\varphi = A + B \frac{\partial\varphi}{\partial z}(\hat z, u), \qquad
    q(s) = (s + \omega)^n

The gain is Zeitz's: it places the eigenvalues of the error dynamics *linearized at the
estimate*, ``A_phi - L C``, at ``-omega`` (all ``n``) for every ``z_hat`` ([Z87]_, sec. 3: the
extended Luenberger observer assigns a constant characteristic polynomial to the linearized
error dynamics by a state-dependent gain). In the normal form the observability matrix of
``(A_phi, C)`` is the identity, so Ackermann's formula reduces to ``L = q(A_phi) e_n`` (Horner on
the vector). ``dphi/dz`` is a central difference of the system's ``phi_batch``. Without a
system (or where ``phi`` does not depend on ``z``) the gain is constant, ``L_i = C(n, i)
omega^i``: the Luenberger observer with poles at ``-omega``, i.e. the high-gain observer of
paper 000 with ``k = omega`` and the model term.

**Discretization.** Forward Euler in ``substeps`` steps per sample period ``h``, the measurement
held, ``phi``, its Jacobian and the gain evaluated at the start of each step. The frozen
linearized one-step error map ``I + (h / substeps)(A_phi - L C)`` has all its eigenvalues at
``1 - omega h / substeps``: stable for ``omega h / substeps < 2`` (checked by
:meth:`~hgo_mj.observers.Observer.check_period`). A dropout (NaN) integrates without correction.

**Why not a KKL observer.** The Kazantzis-Kravaris/Luenberger observer [KK98]_ [AP06]_ needs an
injective map ``T`` solving the PDE ``dT/dx f(x, u) = D T(x) + F h(x)`` and its left inverse
``T*``; neither has a closed form for the plants here (a pendulum's ``sin`` already gives an
infinite series), and the numerical solutions (learned or tabulated ``T``, ``T*``) are
approximations with their own tuning, not a baseline. The extended Luenberger observer is the
closed-form member of the same family (a linear error dynamics assigned, here to first order).

References
----------
.. [Z87] M. Zeitz, "The extended Luenberger observer for nonlinear systems", Systems & Control
   Letters 9(2), 149-156, 1987.
.. [KK98] N. Kazantzis, C. Kravaris, "Nonlinear observer design using Lyapunov's auxiliary
   theorem", Systems & Control Letters 34(5), 241-247, 1998.
.. [AP06] V. Andrieu, L. Praly, "On the existence of a Kazantzis-Kravaris/Luenberger observer",
   SIAM J. Control Optim. 45(2), 432-456, 2006.
"""

from __future__ import annotations

import warnings
from math import comb
from typing import Any

import numpy as np
from numba import njit

from .._validate import finite_scalar, positive_int
from ..exceptions import DesignError, DivergenceError
from ..systems.base import System
from .base import Array, Dimension, Observer, Params, State, register
from .finite_difference import _NormalFormEstimate

__all__ = ["ExtendedLuenbergerObserver", "zeitz_gain", "phi_and_jacobian"]


@njit(cache=True)
def _gain_row(a: Array, c: Array, out: Array) -> None:  # pragma: no cover
    """``out = q(A_phi) e_n`` by Horner (``v <- A_phi v + c_i e_n``), ``A_phi`` the chain with
    the last row ``a``; ``c`` the coefficients ``c_1..c_n`` of ``q``."""
    n = a.shape[0]
    v = np.zeros(n)
    w = np.empty(n)
    v[n - 1] = 1.0
    for i in range(n):
        for r in range(n - 1):
            w[r] = v[r + 1]
        acc = 0.0
        for j in range(n):
            acc += a[j] * v[j]
        w[n - 1] = acc + c[i]
        for r in range(n):
            v[r] = w[r]
    for r in range(n):
        out[r] = v[r]


@njit(cache=True)
def luenberger_advance(Z: Array, y: Array, W: Array, J: Array, c: Array, h: float,
                       Zout: Array) -> int:  # pragma: no cover
    """One forward-Euler step of ``h`` of every member: ``Z`` ``(B, n)`` in place (and into
    ``Zout`` ``(B, n)``), ``y`` ``(B,)`` (NaN: no correction), ``W`` ``(B,)`` the model term and
    ``J`` ``(B, n)`` its Jacobian at ``Z``. Returns the first member whose new state is not
    finite, or -1."""
    B, n = Z.shape
    L = np.empty(n)
    bad = -1
    for b in range(B):
        e = y[b] - Z[b, 0]
        if e == e:
            _gain_row(J[b], c, L)
        else:
            e = 0.0
            L[:] = 0.0
        for i in range(n - 1):
            Zout[b, i] = Z[b, i] + h * (Z[b, i + 1] + L[i] * e)
        Zout[b, n - 1] = Z[b, n - 1] + h * (W[b] + L[n - 1] * e)
        for i in range(n):
            Z[b, i] = Zout[b, i]
            if bad < 0 and not np.isfinite(Z[b, i]):
                bad = b
    return bad


@njit(cache=True)
def _difference_rows(Z: Array, U: Array, step: Array, rows: Array,
                     Ur: Array) -> None:  # pragma: no cover
    """The rows of :func:`phi_and_jacobian`'s central differences: ``step`` ``(B, n)`` ``=
    1e-6 max(1, |Z|)``; ``rows`` ``((2 n + 1) B, n)`` the blocks ``Z``, ``Z + step_i e_i``
    (``i = 1..n``), ``Z - step_i e_i``; ``Ur`` ``((2 n + 1) B, m)`` the inputs ``U`` ``(B, m)``
    in every block."""
    B, n = Z.shape
    m = U.shape[1]
    for b in range(B):
        for i in range(n):
            a = abs(Z[b, i])
            step[b, i] = 1e-6 * (a if a > 1.0 or a != a else 1.0)  # np.maximum: NaN stays
    for k in range(2 * n + 1):
        for b in range(B):
            for i in range(n):
                rows[k * B + b, i] = Z[b, i]
            for i in range(m):
                Ur[k * B + b, i] = U[b, i]
    for i in range(n):
        for b in range(B):
            rows[(1 + i) * B + b, i] += step[b, i]
            rows[(1 + n + i) * B + b, i] -= step[b, i]


@njit(cache=True)
def _central_gradient(F: Array, step: Array, J: Array) -> None:  # pragma: no cover
    """``J`` ``(B, n)``: the central differences of ``phi`` at the rows of
    :func:`_difference_rows` (``F`` ``((2 n + 1) B,)``)."""
    B, n = J.shape
    for i in range(n):
        for b in range(B):
            J[b, i] = (F[(1 + i) * B + b] - F[(1 + n + i) * B + b]) / (2.0 * step[b, i])


class _Differences:
    """:func:`phi_and_jacobian`'s buffers for ``B`` rows of ``n`` coordinates and ``m``
    inputs, kept over an observer's samples (one compiled call builds the difference rows,
    one takes the gradient: no numpy temporaries per sample)."""

    def __init__(self, B: int, n: int, m: int) -> None:
        self.step = np.empty((B, n))
        self.rows = np.empty(((2 * n + 1) * B, n))
        self.Ur = np.empty(((2 * n + 1) * B, m))
        self.J = np.empty((B, n))

    def __call__(self, system: System, Z: Array, U: Array) -> tuple[Array, Array]:
        """``phi`` at the rows ``Z`` (C-contiguous) with inputs ``U`` and its gradient (views
        of this object's buffers, overwritten by the next call)."""
        _difference_rows(Z, U, self.step, self.rows, self.Ur)
        F = np.asarray(system.phi_batch(self.rows, self.Ur), dtype=np.float64).reshape(-1)
        _central_gradient(F, self.step, self.J)
        return F[:Z.shape[0]], self.J


def zeitz_gain(a: Any, omega: float) -> Array:
    """The extended Luenberger gain ``L = q(A_phi) e_n``, ``q(s) = (s + omega)^n``, for the
    normal form whose ``phi`` has the gradient ``a = dphi/dz`` at the estimate.

    .. math:: \\det(sI - A_\\varphi + L C) = (s + \\omega)^n

    Parameters
    ----------
    a : (n,) array_like
        ``dphi/dz`` at the estimate (the last row of ``A_phi``).
    omega : float
        The assigned eigenvalue is ``-omega``, > 0.

    Returns
    -------
    (n,) ndarray
        The gain.

    Raises
    ------
    DesignError
        ``omega`` not a positive finite number.

    Examples
    --------
    >>> zeitz_gain([0.0, 0.0], 10.0)            # phi independent of z: (2 w, w^2)
    array([ 20., 100.])
    >>> zeitz_gain([-9.0, -0.5], 10.0)           # the pendulum near rest
    array([19.5 , 81.25])
    """
    omega = finite_scalar("omega", omega, positive=True)
    a = np.ascontiguousarray(a, dtype=np.float64)
    out = np.empty(a.size)
    _gain_row(a, _coefficients(a.size, omega), out)
    return out


def _coefficients(n: int, omega: float) -> Array:
    """``c_i = C(n, i) omega^i``: ``(s + omega)^n = s^n + c_1 s^(n-1) + ... + c_n``."""
    return np.array([comb(n, i) * omega ** i for i in range(1, n + 1)])


def phi_and_jacobian(system: System, Z: Array, U: Array) -> tuple[Array, Array]:
    """``phi(z, u)`` and its central-difference gradient ``dphi/dz`` at the rows ``Z``, in one
    call of ``system.phi_batch`` on ``(2 n + 1) B`` rows (steps ``1e-6 max(1, |z_i|)``).

    Parameters
    ----------
    system : System
        A system with a normal form (its ``phi_batch``).
    Z : (B, n) ndarray
        Normal-form rows.
    U : (B, m) ndarray
        Inputs.

    Returns
    -------
    W : (B,) ndarray
        ``phi`` at the rows.
    J : (B, n) ndarray
        Its gradient.

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.systems import Pendulum
    >>> W, J = phi_and_jacobian(Pendulum(), np.zeros((1, 2)), np.zeros((1, 1)))
    >>> J.round(3)      # (-m g l_c / J, -d / J)
    array([[-20.356,  -0.184]])
    """
    Z = np.ascontiguousarray(Z, dtype=np.float64)
    U = np.ascontiguousarray(U, dtype=np.float64)
    W, J = _Differences(Z.shape[0], Z.shape[1], U.shape[1])(system, Z, U)
    return W.copy(), J


@register
class ExtendedLuenbergerObserver(_NormalFormEstimate, Observer):
    """Extended Luenberger observer (Zeitz 1987): the model term and a gain that assigns
    ``(s + omega)^n`` to the error dynamics linearized at the estimate.

    .. math:: \\dot{\\hat z} = A \\hat z + B \\varphi(\\hat z, u) + q(A_\\varphi(\\hat z, u))
              e_n (y - \\hat z_1)

    (see the module docstring, also for why a KKL observer is not given in closed form).

    Parameters
    ----------
    system : System, optional
        Gives the order, ``phi`` (``System.phi_batch``) and the map back to physical
        coordinates. Without one, give ``order``: then ``phi = 0`` and the gain is constant.
    omega : float
        The assigned eigenvalue ``-omega`` of the linearized error dynamics, > 0. Tunable.
    substeps : int
        Forward-Euler steps per sample (default 1).
    order : int, optional
        ``n`` when no system is given.
    outputs : tuple of int
        The measured channel, a 1-tuple (default ``(0,)``).
    x_hat0, z_hat0 : array_like, optional
        Initial estimate (default zero).
    on_unstable : {"raise", "warn", "ignore"}
        What :meth:`check_period` does when ``omega h / substeps >= 2``.

    Raises
    ------
    DesignError
        ``omega`` not a positive finite number, ``substeps`` not a positive integer, or more
        than one output.

    References
    ----------
    M. Zeitz, "The extended Luenberger observer for nonlinear systems", Systems & Control
    Letters 9(2), 1987.

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.systems import Pendulum
    >>> ob = ExtendedLuenbergerObserver(Pendulum(), omega=20.0, x_hat0=[0.2, 1.0])
    >>> t = np.arange(0.0, 1.0, 1e-3)       # the pendulum at rest, y = 0
    >>> rows = ob.run(np.zeros((t.size, 1)), np.zeros((t.size, 1)), 1e-3)
    >>> bool(np.abs(rows.x_hat[0, -1]).max() < 1e-4)
    True
    """

    name = "extended_luenberger"
    summary = "extended Luenberger observer: model term, gain assigning (s+omega)^n at the estimate"
    reference = "Zeitz, Systems & Control Letters 9(2), 1987"
    family_diagnostics = ()

    def __init__(self, system: System | None = None, *, omega: float = 10.0,
                 substeps: int = 1, order: int | None = None, outputs: Any = (0,),
                 x_hat0: Any = None, z_hat0: Any = None, on_unstable: str = "raise") -> None:
        super().__init__(system, order=order, outputs=outputs, on_unstable=on_unstable)
        if len(self.outputs) != 1:
            raise DesignError(f"{type(self).__name__} reads one output: outputs must be a "
                              f"1-tuple such as (0,); found {list(self.outputs)}")
        self.omega = finite_scalar("omega", omega, positive=True)
        self.substeps = positive_int("substeps", substeps, floats=False)
        self._start_values(x_hat0, z_hat0)

    def _parameters(self) -> dict[str, Any]:
        """The assigned eigenvalue ``-omega`` (Zeitz 1987)."""
        return {"omega": self.omega}

    def _check_parameter(self, name: str, value: Any) -> Array:
        return np.array(finite_scalar(f"{self.name}: omega", value, positive=True))

    def tuning_space(self) -> dict[str, Dimension]:
        """``omega`` over ``[omega / 10, 100 omega]`` on a log scale (as the high-gain
        observer's ``k``, which it equals where ``phi`` does not depend on ``z``)."""
        w = self.omega
        return {"omega": Dimension("omega", w / 10.0, w * 100.0, True, w)}

    def max_stable_period(self, omega: float | None = None) -> float:
        """The largest sample period of a stable frozen linearized Euler step,
        ``2 substeps / omega``.

        Parameters
        ----------
        omega : float, optional
            Default: the constructor's.

        Returns
        -------
        float
            Seconds.

        Examples
        --------
        >>> ExtendedLuenbergerObserver(order=2, omega=10.0).max_stable_period()
        0.2
        """
        return 2.0 * self.substeps / (self.omega if omega is None else float(omega))

    def _check_period(self, p: Params, dt: float) -> None:
        w = float(p.omega)
        if self.on_unstable == "ignore" or w * dt / self.substeps < 2.0:
            return
        msg = (f"forward-Euler update of the extended Luenberger observer (omega={w:g}, "
               f"substeps={self.substeps}) with sample period {dt:g} is unstable: "
               f"omega dt / substeps = {w * dt / self.substeps:.4g} >= 2; the largest stable "
               f"period is {self.max_stable_period(w):.4g}")
        if self.on_unstable == "raise":
            raise DesignError(msg)
        warnings.warn(msg, RuntimeWarning, stacklevel=4)

    def _init(self, p: Params, x0: Array | None, z0: Array | None,
              u0: Array) -> dict[str, Any]:
        z = self._start_z(x0, z0, u0)
        return {"z": z, **self._held_fields(z, u0)}

    def _step(self, p: Params, s: State, Y: Array, U: Array, dt: float, X: Array, Z: Array,
              D: Array) -> None:
        c = _coefficients(self.n, float(p.omega))
        B, T = Y.shape[0], Y.shape[1]
        h = dt / self.substeps
        zero_w, zero_j = np.zeros(B), np.zeros((B, self.n))
        differences = _Differences(B, self.n, U.shape[2])
        with np.errstate(over="ignore", invalid="ignore"):  # phi far out: caught below
            for j in range(T):
                y = np.ascontiguousarray(Y[:, j, 0])
                u = np.ascontiguousarray(U[:, j])
                for _ in range(self.substeps):
                    W, J = (zero_w, zero_j) if self.system is None else \
                        differences(self.system, s.z, u)
                    bad = luenberger_advance(s.z, y, W, J, c, h, Z[:, j])
                if bad >= 0:  # a gain too high for the period: blown up
                    raise DivergenceError(f"the observer state left the finite numbers at "
                                          f"sample {j} (member {bad}): {s.z[bad].tolist()}")
        self._write_x(s, Z, U, X)

    def _current(self, p: Params, s: State) -> tuple[Array, Array, Array]:
        return self._x_of(s), s.z.copy(), np.zeros((s.z.shape[0], 0))

    def params(self) -> dict[str, Any]:
        return {"omega": self.omega, "substeps": self.substeps, "order": self.n,
                "outputs": list(self.outputs)}
