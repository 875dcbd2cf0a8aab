"""Extended and unscented Kalman filters, continuous-discrete, with parameter augmentation
([J70]_, [JU97]_, [S06]_; MuJoCo finite differences [MJ]_).

The baselines the adaptive observers of papers 001-003 measure themselves against. The state
is the physical state of a :class:`~hgo_mj.systems.base.System` augmented with the
parameters named in ``estimate`` (constant, driven by a small random walk):

.. math::

    \\dot x = f(x, u, \\theta) + w_x, \\qquad \\dot\\theta = w_\\theta, \\qquad
    y_k = h(x(t_k)) + v_k, \\qquad
    E[w w^T] = Q\\,\\delta(t - s), \\quad E[v_k v_k^T] = R.

Each sample first corrects the prediction with ``y(t_k)`` (the measurement update), then
predicts to ``t_k + dt`` with ``u`` held (the time update), so that, as every observer of the
package, the filter reports the estimate of ``x(t_k + dt)`` and row ``k`` of a trajectory is
the prediction made before ``y(t_k)`` was seen.

**State and parameters as data.** ``B`` filters advance together: the state's fields are the
augmented estimate ``x`` ``(B, N)`` and its covariance ``P`` ``(B, N, N)`` (``N = n + q``); the
tunable parameters (:meth:`~hgo_mj.observers.base.Observer.parameters`) are the noise
covariances ``Q`` ``(n, n)``, ``R`` ``(p, p)`` and, with ``estimate``, ``Q_theta`` ``(q, q)``, and
the UKF's ``alpha``, ``beta``, ``kappa``, each for every member or per member. The step is
written once, in the shape of dynamax's ``_predict`` / ``_condition_on``:
:meth:`_KalmanFilter._condition_on` (the measurement update) and ``_predict`` (the time
update) act on the whole batch of one member's parameters; the covariance arithmetic
(transition, :math:`\\Phi P \\Phi^T + Q h`, the updates, Cholesky factors, sigma points and
moments) runs in the module-level numba kernels below, one loop over ``B`` each, so a
member's numbers do not depend on the batch it runs in.

**Time update** over ``substeps`` steps ``h``: the mean by RK4 (or Euler) of :math:`f` with
:math:`u` held; the covariance by :math:`P \\leftarrow \\Phi P \\Phi^T + Q h` with
:math:`\\Phi = T_4(hF)` (RK4: the degree-4 Taylor polynomial of :math:`e^{hF}`, which is
exactly RK4's transition on a linear system) or :math:`I + hF` (Euler),
:math:`F = \\partial f/\\partial x` at the start of the step [J70, sec. 8.3]. On a linear
system the filter *is* the discrete Kalman filter of the RK4 (or Euler) discretization (tested
against a textbook Kalman filter, and against the exact discretization as :math:`h \\to 0`).

**The model** comes from the system (:class:`SystemModel`): ``dynamics`` and, where given,
the analytic ``jacobian(t, x, u, p)`` and ``param_jacobian(t, x, u, p, names)``, else central
finite differences. Two ways to evaluate it over a batch, chosen once at construction by
what the system declares (nothing is probed):

* *compiled* (every system of the package): the system's
  :class:`~hgo_mj.systems.base.CompiledModel`, its ODE and Jacobians written once as rows that
  numba kernels call (:func:`_model_step`, :func:`_model_jacobian`, :func:`_ekf_predict`); the
  EKF then runs a whole block of samples in one call (:func:`_ekf_block`);
* *Python* (a system without a compiled model, e.g. a user's): one ``dynamics`` call per
  member and stage, the RK4 and Euler arithmetic of :mod:`hgo_mj.observers._integrate` over
  the rows.

Both do the same operations in the same order (the RK4 of :func:`_rk4_row` is that of
:func:`hgo_mj.observers._integrate.rk4`), so they give the same numbers bit for bit (tested).

The MuJoCo variants (:class:`MujocoExtendedKalmanFilter`, :class:`MujocoUnscentedKalmanFilter`,
model :class:`MujocoModel`) use the MJCF itself: the mean by stepping an ``MjData`` of a copy of
the ``MjModel``, the EKF's transition matrix from ``mujoco.mjd_transitionFD``; MuJoCo is called
per model and data, so these loop over the members.

**Measurement update**: where the measured outputs are state components (all systems of the
package: ``y = x[j]``), :math:`H` is a selection, the EKF update is exact and the UKF's
unscented update reduces to the same formula (the unscented transform is exact for a linear
map), so both use it (:func:`_condition_selection`: sequential scalar updates for a diagonal
:math:`R`, the joint Joseph-form update otherwise). For a general :math:`h` the EKF linearizes
by finite differences and the UKF uses sigma points (one member at a time).

**Consistency: the NIS.** Every Kalman filter reports, per sample, the diagnostic ``nis``: the
normalized innovation squared of its measurement update,

.. math::

    \\epsilon_k = \\nu_k^T S_k^{-1} \\nu_k, \\qquad \\nu_k = y_k - h(\\hat x_k^-), \\qquad
    S_k = H P_k^- H^T + R

over the present (non-NaN) channels (the UKF's :math:`S_k = P_{yy} + R` from sigma points;
for a selection output both are the formula above), NaN for a sample whose channels are all
lost (and before the first update). For a consistent filter (the model right, ``Q`` and ``R``
the true noise) :math:`\\epsilon_k` is :math:`\\chi^2` with as many degrees of freedom as
present channels, so its **expected value is the number of present channels** [BLK01]_; a mean
well above it says the filter is overconfident (``R`` or ``Q`` too small), well below
underconfident. It needs no ground truth (the tuner's ``nis`` objective reads it). The kernels
form it from the :math:`S` (or the scalar :math:`s`) that the update computes anyway: with a
diagonal :math:`R` the sequential scalar updates give the sum of the squared normalized
sequential innovations :math:`\\sum_c \\nu_c'^2 / s_c`, which equals the joint
:math:`\\nu^T S^{-1} \\nu` (the sequential innovations are :math:`L^{-1} \\nu` for
:math:`S = L D L^T`, their variances :math:`D`).

References
----------
.. [J70] A. H. Jazwinski, *Stochastic Processes and Filtering Theory*, Academic Press 1970,
   sec. 8.3 (continuous-discrete extended Kalman filter).
.. [JU97] S. J. Julier, J. K. Uhlmann, "A new extension of the Kalman filter to nonlinear
   systems", Proc. AeroSense 1997; [WM00] E. A. Wan, R. van der Merwe, "The unscented Kalman
   filter for nonlinear estimation", IEEE AS-SPCC 2000 (scaled sigma points, weights).
.. [S06] D. Simon, *Optimal State Estimation*, Wiley 2006, sec. 13.2 (parameter estimation by
   state augmentation), sec. 10.1 (Joseph form), sec. 14.3 (UKF).
.. [MJ] MuJoCo documentation, ``mjd_transitionFD`` (finite-differenced transition matrices).
.. [BLK01] Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking
   and Navigation*, Wiley 2001, sec. 5.4.2 (the normalized innovation squared and its
   chi-square test).
"""

from __future__ import annotations

import copy
import functools
import math
from collections import namedtuple
from collections.abc import Callable, Mapping, Sequence
from typing import Any, ClassVar

import mujoco
import mujoco.batch
import numpy as np
from numba import njit
from numba.extending import overload
from numpy.typing import NDArray

from .._binding import Binding
from .._validate import (
    finite_scalar,
    one_of,
    positive_definite,
    positive_int,
    positive_semidefinite,
    vector,
)
from ..exceptions import DesignError, DivergenceError
from ..plants.fields import VECTOR, get_field, resolve, set_field, set_fields
from ..systems.base import CompiledModel, System
from . import _integrate
from .base import Array, Observer, Params, State, batch_rows, register

IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


# ------------------------------------------ a system's CompiledModel, called from the kernels
def model_dynamics(model: CompiledModel, x: Array, u: Array, c: Array, out: Array) -> None:
    """``model``'s ``dynamics`` of one row (from Python and from numba kernels)."""
    type(model).dynamics(x, u, c, out)


def model_jacobian(model: CompiledModel, x: Array, u: Array, c: Array, out: Array) -> None:
    """``model``'s ``jacobian`` of one row (from Python and from numba kernels)."""
    type(model).jacobian(x, u, c, out)


def model_param_jacobian(model: CompiledModel, x: Array, u: Array, c: Array,
                         out: Array) -> None:
    """``model``'s ``param_jacobian`` of one row (from Python and from numba kernels)."""
    type(model).param_jacobian(x, u, c, out)


def _model_overload(attr: str) -> Any:
    """The numba implementation of ``model_<attr>``: the function ``attr`` of the model's
    class (a model without it: an implementation that raises, never called by the filters,
    which check :attr:`CompiledModel.jacobian` before asking for it)."""

    # no annotations: numba compares the typer's signature with the implementation's
    def typer(model, x, u, c, out):  # type: ignore[no-untyped-def]
        fn = getattr(getattr(model, "instance_class", None), attr, None)
        if fn is None:
            def missing(model, x, u, c, out):  # type: ignore[no-untyped-def]
                raise NotImplementedError("the compiled model has no such function")
            return missing
        return lambda model, x, u, c, out: fn(x, u, c, out)

    return typer


for _fn, _attr in ((model_dynamics, "dynamics"), (model_jacobian, "jacobian"),
                   (model_param_jacobian, "param_jacobian")):
    overload(_fn, inline="always")(_model_overload(_attr))


# the filters' process models (SystemModel, MujocoModel) are plumbing: a user builds a filter
__all__ = ["ExtendedKalmanFilter", "MujocoExtendedKalmanFilter", "MujocoUnscentedKalmanFilter",
           "UnscentedKalmanFilter"]

METHODS = ("rk4", "euler")
JACOBIANS = ("auto", "analytic", "fd")
#: at most this many per-period matrices (``Q h``) are kept
_CACHE_MAX = 8


# ======================================================================================
# kernels: the covariance arithmetic, one loop over the batch each (float64, C-contiguous)
# ======================================================================================


@njit(cache=True, inline="always")
def _t4(A: Array, rk4: bool, T: Array, W: Array) -> None:  # pragma: no cover - numba
    r"""``T = T_4(A)`` (RK4) or ``I + A`` (Euler) [J70, sec. 8.3], ``W`` scratch.

    :math:`T_4(A) = I + A + A^2/2 + A^3/6 + A^4/24` by Horner:
    :math:`T = I + A/4,\ T \leftarrow I + A T/3,\ T \leftarrow I + A T/2,\ \Phi = I + A T`,
    exactly RK4's one-step map of :math:`\dot x = F x` with ``A = h F``."""
    N = A.shape[0]
    if not rk4:
        for i in range(N):
            for j in range(N):
                T[i, j] = A[i, j] + (1.0 if i == j else 0.0)
        return
    for i in range(N):
        for j in range(N):
            T[i, j] = (1.0 if i == j else 0.0) + 0.25 * A[i, j]
    for div in (3.0, 2.0, 1.0):
        for i in range(N):
            for j in range(N):
                s = 0.0
                for k in range(N):
                    s += A[i, k] * T[k, j]
                W[i, j] = (1.0 if i == j else 0.0) + s / div
        for i in range(N):
            for j in range(N):
                T[i, j] = W[i, j]


@njit(cache=True, inline="always")
def _sandwich(Phi: Array, P: Array, Qh: Array, M: Array) -> None:  # pragma: no cover - numba
    """In place ``P = Phi P Phi^T + Q h`` (the upper triangle, mirrored), ``M`` scratch."""
    N = P.shape[0]
    for i in range(N):
        for j in range(N):
            s = 0.0
            for k in range(N):
                s += Phi[i, k] * P[k, j]
            M[i, j] = s
    for i in range(N):
        for j in range(i, N):
            s = 0.0
            for k in range(N):
                s += M[i, k] * Phi[j, k]
            s += Qh[i, j]
            P[i, j] = s
            P[j, i] = s


@njit(cache=True)
def _transition(F: Array, h: float, rk4: bool, Phi: Array) -> None:  # pragma: no cover - numba
    """``Phi[b] = T_4(h F[b])`` (RK4) or ``I + h F[b]`` (Euler): :func:`_t4` of each member."""
    B, N = F.shape[0], F.shape[1]
    A = np.empty((N, N))
    T = np.empty((N, N))
    W = np.empty((N, N))
    for b in range(B):
        for i in range(N):
            for j in range(N):
                A[i, j] = h * F[b, i, j]
        _t4(A, rk4, T, W)
        Phi[b] = T


@njit(cache=True)
def _propagate(P: Array, Phi: Array, Qh: Array) -> None:  # pragma: no cover - numba
    """In place ``P[b] = Phi[b] P[b] Phi[b]^T + Q h``: :func:`_sandwich` of each member."""
    B, N = P.shape[0], P.shape[1]
    M = np.empty((N, N))
    for b in range(B):
        _sandwich(Phi[b], P[b], Qh, M)


@njit(cache=True)
def _spd_solve(S: Array, Rhs: Array) -> Array:  # pragma: no cover - numba
    """``S^{-1} Rhs`` for a symmetric positive definite ``S`` (Cholesky)."""
    m = S.shape[0]
    L = np.zeros((m, m))
    for j in range(m):
        d = S[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        L[j, j] = math.sqrt(d)
        for i in range(j + 1, m):
            s = S[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / L[j, j]
    X = Rhs.copy()
    for c in range(X.shape[1]):
        for i in range(m):
            s = X[i, c]
            for k in range(i):
                s -= L[i, k] * X[k, c]
            X[i, c] = s / L[i, i]
        for i in range(m - 1, -1, -1):
            s = X[i, c]
            for k in range(i + 1, m):
                s -= L[k, i] * X[k, c]
            X[i, c] = s / L[i, i]
    return X


@njit(cache=True)
def _gain_and_nis(S: Array, PHt: Array, v: Array) -> tuple[Array, float]:  # pragma: no cover
    """The gain :math:`K = P H^T S^{-1}` ``(N, m)`` and the normalized innovation squared
    :math:`v^T S^{-1} v` from one Cholesky factor of ``S`` (:func:`_spd_solve` of the right-hand
    sides :math:`H P` and ``v`` together; it solves the columns one by one, so the gain is
    the same to the bit as solved alone)."""
    N, m = PHt.shape
    rhs = np.empty((m, N + 1))
    for a in range(m):
        for i in range(N):
            rhs[a, i] = PHt[i, a]
        rhs[a, N] = v[a]
    sol = _spd_solve(S, rhs)
    nis = 0.0
    for a in range(m):
        nis += v[a] * sol[a, N]
    return sol[:, :N].T.copy(), nis


@njit(cache=True, inline="always")
def _mat_mul(A: Array, B: Array, out: Array) -> None:  # pragma: no cover - numba
    """``out = A B`` (``(r, k) (k, c)``), each entry one sum in the order of ``k``."""
    for i in range(A.shape[0]):
        for j in range(B.shape[1]):
            s = 0.0
            for k in range(A.shape[1]):
                s += A[i, k] * B[k, j]
            out[i, j] = s


@njit(cache=True, inline="always")
def _mat_mul_bt(A: Array, B: Array, out: Array) -> None:  # pragma: no cover - numba
    """``out = A B^T`` (``(r, k) (c, k)``), each entry one sum in the order of ``k``."""
    for i in range(A.shape[0]):
        for j in range(B.shape[0]):
            s = 0.0
            for k in range(A.shape[1]):
                s += A[i, k] * B[j, k]
            out[i, j] = s


@njit(cache=True, inline="always")
def _mat_mul_bt_add(A: Array, B: Array, out: Array) -> None:  # pragma: no cover - numba
    """In place ``out += A B^T`` (each entry's sum formed first, then added)."""
    for i in range(A.shape[0]):
        for j in range(B.shape[0]):
            s = 0.0
            for k in range(A.shape[1]):
                s += A[i, k] * B[j, k]
            out[i, j] += s


@njit(cache=True, inline="always")
def _mat_vec_add(A: Array, v: Array, x: Array) -> None:  # pragma: no cover - numba
    """In place ``x += A v`` (each ``(A v)_i`` summed first, then added)."""
    for i in range(A.shape[0]):
        s = 0.0
        for k in range(A.shape[1]):
            s += A[i, k] * v[k]
        x[i] += s


@njit(cache=True, inline="always")
def _symmetrize(A: Array, out: Array) -> None:  # pragma: no cover - numba
    """``out = (A + A^T) / 2``."""
    for i in range(A.shape[0]):
        for j in range(A.shape[0]):
            out[i, j] = 0.5 * (A[i, j] + A[j, i])


@njit(cache=True)
def _joint_update(x: Array, P: Array, v: Array, H: Array, R: Array) -> float:  # pragma: no cover
    """In place, the Kalman update of one member with innovation ``v`` [S06, sec. 10.1]:

    .. math::

        S = H P H^T + R, \\quad K = P H^T S^{-1}, \\quad x \\leftarrow x + K v, \\quad
        P \\leftarrow (I - K H) P (I - K H)^T + K R K^T \\ \\text{(Joseph form, symmetrized)};

    returns the normalized innovation squared :math:`v^T S^{-1} v` (:func:`_gain_and_nis`).
    Written with the small-matrix kernels :func:`_mat_mul`, :func:`_mat_mul_bt`,
    :func:`_mat_mul_bt_add`, :func:`_mat_vec_add`, :func:`_symmetrize`."""
    N, m = P.shape[0], H.shape[0]
    PHt = np.empty((N, m))
    _mat_mul_bt(P, H, PHt)
    S = np.empty((m, m))
    _mat_mul(H, PHt, S)
    for a in range(m):
        for c in range(m):
            S[a, c] += R[a, c]
    K, nis = _gain_and_nis(S, PHt, v)
    _mat_vec_add(K, v, x)
    IKH = np.empty((N, N))  # I - K H
    _mat_mul(K, H, IKH)
    for i in range(N):
        for j in range(N):
            IKH[i, j] = (1.0 if i == j else 0.0) - IKH[i, j]
    M = np.empty((N, N))
    _mat_mul(IKH, P, M)
    KR = np.empty((N, m))
    _mat_mul(K, R, KR)
    out = np.empty((N, N))
    _mat_mul_bt(M, IKH, out)  # (I - K H) P (I - K H)^T
    _mat_mul_bt_add(KR, K, out)  # + K R K^T
    _symmetrize(out, P)
    return nis


@njit(cache=True)
def _condition_selection(X: Array, P: Array, Y: Array, sel: IntArray, R: Array,
                         diagonal: bool, nis: Array) -> None:  # pragma: no cover - numba
    """The measurement update of every member with a selection output ``y_c = x[sel[c]]``; a NaN
    channel (a dropout) is left out, so a member with every channel lost only predicts.

    Diagonal :math:`R`: one scalar update per present channel (exact, :math:`R` diagonal),
    :math:`s = P_{jj} + r_c,\\ k = P_{:,j},\\ x \\leftarrow x + k (y_c - x_j)/s,\\
    P \\leftarrow P - k k^T / s`. Otherwise the joint update (:func:`_joint_update`) of the
    present channels.

    ``nis[b]``: the member's normalized innovation squared :math:`v^T S^{-1} v` over the
    present channels, NaN where none is. Sequentially it is the sum of the squared normalized
    scalar innovations :math:`(y_c - x_j)^2 / s`: with :math:`S = L D L^T` (unit lower
    :math:`L`), the scalar innovations are :math:`L^{-1} v` and their variances :math:`D`, so
    :math:`\\sum_c (L^{-1} v)_c^2 / D_c = v^T S^{-1} v` (the joint value)."""
    B, N = X.shape
    p = Y.shape[1]
    idx = np.empty(p, dtype=np.int64)
    k = np.empty(N)
    for b in range(B):
        if diagonal:
            acc = 0.0
            seen = False
            for c in range(p):
                y = Y[b, c]
                if y != y:
                    continue
                seen = True
                j = sel[c]
                s = P[b, j, j] + R[c, c]
                d = y - X[b, j]
                e = d / s
                acc += d * e
                for i in range(N):
                    k[i] = P[b, i, j]
                for i in range(N):
                    X[b, i] += k[i] * e
                w = 1.0 / s
                for i in range(N):
                    for m in range(i, N):
                        q = P[b, i, m] - k[i] * k[m] * w
                        P[b, i, m] = q
                        P[b, m, i] = q
            nis[b] = acc if seen else np.nan
            continue
        m = 0
        for c in range(p):
            if Y[b, c] == Y[b, c]:
                idx[m] = c
                m += 1
        if m == 0:
            nis[b] = np.nan
            continue
        H = np.zeros((m, N))
        v = np.empty(m)
        Rm = np.empty((m, m))
        for a in range(m):
            j = sel[idx[a]]
            H[a, j] = 1.0
            v[a] = Y[b, idx[a]] - X[b, j]
            for c in range(m):
                Rm[a, c] = R[idx[a], idx[c]]
        nis[b] = _joint_update(X[b], P[b], v, H, Rm)


@njit(cache=True)
def _sigma_points(X: Array, P: Array, c: float, S: Array, ok: BoolArray) -> None:  # pragma: no cover
    """The ``2N + 1`` scaled sigma points of every member [WM00]: ``S[b, 0] = x``,
    ``S[b, 1 + i] = x + c L_i``, ``S[b, 1 + N + i] = x - c L_i`` with ``L L^T = P[b]``
    (Cholesky, column ``L_i``). ``ok[b]`` is False (and ``S[b]`` unset) where ``P[b]`` is not
    numerically positive definite."""
    B, N = X.shape
    L = np.empty((N, N))
    for b in range(B):
        good = True
        L[:, :] = 0.0
        for j in range(N):
            d = P[b, j, j]
            for k in range(j):
                d -= L[j, k] * L[j, k]
            if not d > 0.0:
                good = False
                break
            L[j, j] = math.sqrt(d)
            for i in range(j + 1, N):
                s = P[b, i, j]
                for k in range(j):
                    s -= L[i, k] * L[j, k]
                L[i, j] = s / L[j, j]
        ok[b] = good
        if not good:
            continue
        for i in range(N):
            S[b, 0, i] = X[b, i]
        for j in range(N):
            for i in range(N):
                S[b, 1 + j, i] = X[b, i] + c * L[i, j]
                S[b, 1 + N + j, i] = X[b, i] - c * L[i, j]


@njit(cache=True)
def _moments(S: Array, Wm: Array, Wc: Array, Qh: Array, X: Array,
             P: Array) -> None:  # pragma: no cover - numba
    """The unscented moments of the propagated points ``S`` ``(B, 2N + 1, N)`` [WM00]:
    :math:`\\hat x = \\sum_i W^m_i \\chi_i`,
    :math:`P = \\sum_i W^c_i (\\chi_i - \\hat x)(\\chi_i - \\hat x)^T + Q h`."""
    B, M, N = S.shape
    mu = np.empty(N)
    for b in range(B):
        for i in range(N):
            s = 0.0
            for k in range(M):
                s += Wm[k] * S[b, k, i]
            mu[i] = s
            X[b, i] = s
        for i in range(N):
            for j in range(i, N):
                s = 0.0
                for k in range(M):
                    s += Wc[k] * (S[b, k, i] - mu[i]) * (S[b, k, j] - mu[j])
                s += Qh[i, j]
                P[b, i, j] = s
                P[b, j, i] = s


@njit(cache=True)
def _ekf_covariance(P: Array, F: Array, h: float, rk4: bool, Qh: Array) -> None:  # pragma: no cover
    """In place ``P[b] = Phi P[b] Phi^T + Q h`` with ``Phi = T_4(h F[b])`` (RK4) or
    ``I + h F[b]`` (Euler): :func:`_t4` then :func:`_sandwich` of each member, without storing
    the transitions."""
    B, N = F.shape[0], F.shape[1]
    A = np.empty((N, N))
    T = np.empty((N, N))
    W = np.empty((N, N))
    for b in range(B):
        for i in range(N):
            for j in range(N):
                A[i, j] = h * F[b, i, j]
        _t4(A, rk4, T, W)
        _sandwich(T, P[b], Qh, W)


@njit(cache=True)
def _first_nonfinite(X: Array) -> int:  # pragma: no cover - numba
    """The first row of ``X`` with a non-finite entry, or -1."""
    for b in range(X.shape[0]):
        for i in range(X.shape[1]):
            if not math.isfinite(X[b, i]):
                return b
    return -1


# --------------------------------------------------------------------------------------
# the model compiled with the filter: a system's CompiledModel (hgo_mj.systems.base) called
# from the kernels, so that a time update never returns to Python. Rows are augmented states
# (x, theta); ``c0`` holds the system's parameters in the order of its param_names and
# ``pidx[k]`` the index of the k-th estimated one, read from ``xa[n + k]``. error_model
# "numpy": a division by zero gives inf or NaN, as the system's Python dynamics on numpy floats.
# --------------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _row_params(c0: Array, pidx: IntArray, xa: Array, n: int, c: Array) -> None:  # pragma: no cover
    """``c`` = the parameters of the row ``xa``: ``c0`` with the estimated ones from it."""
    for i in range(c0.shape[0]):
        c[i] = c0[i]
    for k in range(pidx.shape[0]):
        c[pidx[k]] = xa[n + k]


@njit(cache=True, error_model="numpy", inline="always")
def _rk4_row(model: Any, xa: Array, u: Array, c: Array, h: float, rk4: bool, out: Array,
             k1: Array, k2: Array, k3: Array, k4: Array, xs: Array) -> None:  # pragma: no cover
    """One RK4 (or Euler) step of ``h`` of the physical part ``x = xa[:n]`` of a row with ``u``
    held, into ``out[:n]`` (``n = len(k1)``; ``k1`` ... ``xs`` scratch):
    :math:`x + \\tfrac{h}{6}(k_1 + 2 (k_2 + k_3) + k_4)`,
    :math:`k_2 = f(x + \\tfrac{h}{2} k_1)`, ... (the arithmetic of :meth:`SystemModel.step`).
    Whole rows, no slices: the model reads ``x[:n]`` only."""
    n = k1.shape[0]
    model_dynamics(model, xa, u, c, k1)
    if not rk4:
        for i in range(n):
            out[i] = xa[i] + h * k1[i]
        return
    hh, h6 = 0.5 * h, h / 6.0
    for i in range(n):
        xs[i] = xa[i] + hh * k1[i]
    model_dynamics(model, xs, u, c, k2)
    for i in range(n):
        xs[i] = xa[i] + hh * k2[i]
    model_dynamics(model, xs, u, c, k3)
    for i in range(n):
        xs[i] = xa[i] + h * k3[i]
    model_dynamics(model, xs, u, c, k4)
    for i in range(n):
        out[i] = xa[i] + h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])


@njit(cache=True, error_model="numpy", inline="always")
def _jacobian_row(model: Any, xa: Array, u: Array, c: Array, pidx: IntArray, analytic: bool,
                  A: Array, fp: Array, fm: Array, xs: Array,
                  Fp: Array) -> None:  # pragma: no cover - numba
    """:math:`F = \\partial (f, 0) / \\partial (x, \\theta)` of the augmented row ``xa``
    (parameters ``c`` read from it) into ``A`` ``(N, N)``, zero below row ``n = len(fp)``: the
    model's ``jacobian`` and ``param_jacobian`` (``analytic``), else central differences with
    the relative step ``1e-6`` (the arithmetic of :func:`_central_differences`); ``fp``,
    ``fm``, ``xs`` ``(n,)`` and ``Fp`` ``(n, len(c))`` scratch."""
    N, n = xa.shape[0], fp.shape[0]
    for i in range(N):
        for j in range(N):
            A[i, j] = 0.0
    # no early return, and the parameter columns in a loop: a branch around a call keeps
    # numba's reference counting of the row views (several times slower)
    if analytic:
        model_jacobian(model, xa, u, c, A)  # writes A[:n, :n]
        for k in range(pidx.shape[0]):
            if k == 0:
                model_param_jacobian(model, xa, u, c, Fp)
            for i in range(n):
                A[i, n + k] = Fp[i, pidx[k]]
    else:
        for j in range(n):
            v = xa[j]
            e = 1e-6 * max(1.0, abs(v))
            for i in range(n):
                xs[i] = xa[i]
            xs[j] = v + e
            model_dynamics(model, xs, u, c, fp)
            xs[j] = v - e
            model_dynamics(model, xs, u, c, fm)
            for i in range(n):
                A[i, j] = (fp[i] - fm[i]) / (2.0 * e)
        for j in range(n, N):
            v = xa[j]
            e = 1e-6 * max(1.0, abs(v))
            ci = pidx[j - n]
            c[ci] = v + e
            model_dynamics(model, xa, u, c, fp)
            c[ci] = v - e
            model_dynamics(model, xa, u, c, fm)
            c[ci] = v
            for i in range(n):
                A[i, j] = (fp[i] - fm[i]) / (2.0 * e)


@njit(cache=True, error_model="numpy")
def _model_step(model: Any, X: Array, U: Array, c0: Array, pidx: IntArray, h: float,
                switches: _EkfSwitches, out: Array) -> None:  # pragma: no cover - numba
    """:meth:`SystemModel.step` of the rows ``X`` ``(K, N)`` with a compiled model (``out``
    holds ``X``: the parameters are kept), RK4 or Euler by the type ``switches``: the loop
    compiled with the flag constant, only the one used (see :func:`_ekf_predict`)."""
    _step_rows(switches, model, X, U, c0, pidx, h, out)


@njit(cache=True, error_model="numpy", inline="always")
def _model_step_rows(model: Any, X: Array, U: Array, c0: Array, pidx: IntArray, h: float,
                     rk4: bool, out: Array) -> None:  # pragma: no cover - numba
    K, N = X.shape
    n = N - pidx.shape[0]
    c = np.empty(c0.shape[0])
    k1, k2, k3, k4, xs = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    for r in range(K):
        _row_params(c0, pidx, X[r], n, c)
        _rk4_row(model, X[r], U[r], c, h, rk4, out[r], k1, k2, k3, k4, xs)


@njit(cache=True, error_model="numpy")
def _model_jacobian(model: Any, X: Array, U: Array, c0: Array, pidx: IntArray,
                    switches: _EkfSwitches, A: Array) -> None:  # pragma: no cover - numba
    """:meth:`SystemModel.jac` of the rows ``X`` ``(K, N)`` with a compiled model, analytic or
    by differences by the type ``switches`` (the loop compiled with the flag constant, only
    the one used, see :func:`_ekf_predict`)."""
    _jacobian_rows(switches, model, X, U, c0, pidx, A)


@njit(cache=True, error_model="numpy", inline="always")
def _model_jacobian_rows(model: Any, X: Array, U: Array, c0: Array, pidx: IntArray,
                         analytic: bool, A: Array) -> None:  # pragma: no cover - numba
    K, N = X.shape
    n = N - pidx.shape[0]
    c = np.empty(c0.shape[0])
    fp, fm, xs = np.empty(n), np.empty(n), np.empty(n)
    Fp = np.empty((n, c0.shape[0]))
    for r in range(K):
        _row_params(c0, pidx, X[r], n, c)
        _jacobian_row(model, X[r], U[r], c, pidx, analytic, A[r], fp, fm, xs, Fp)


@njit(cache=True, error_model="numpy")
def _model_deriv(model: Any, X: Array, U: Array, c0: Array, pidx: IntArray,
                 out: Array) -> None:  # pragma: no cover - numba
    """:meth:`SystemModel.deriv` of the rows ``X`` ``(K, N)`` with a compiled model (``out``
    zero: :math:`\\dot\\theta = 0`)."""
    K, N = X.shape
    n = N - pidx.shape[0]
    c = np.empty(c0.shape[0])
    for r in range(K):
        _row_params(c0, pidx, X[r], n, c)
        model_dynamics(model, X[r], U[r], c, out[r])


@njit(cache=True)
def _ekf_scratch(n: int, N: int, nc: int) -> tuple[Any, Any]:  # pragma: no cover - numba
    """Work arrays of :func:`_ekf_predict`, allocated once per block: the vectors ``(c, k1,
    k2, k3, k4, xs, x1, fm)`` and the matrices ``(Fp, F, A, T, M)``."""
    vs = (np.empty(nc), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n),
          np.empty(n), np.empty(n))
    ms = (np.empty((n, nc)), np.empty((N, N)), np.empty((N, N)), np.empty((N, N)),
          np.empty((N, N)))
    return vs, ms


class _EkfSwitches(namedtuple("EkfSwitches", ())):
    """The EKF time update's two switches as a type (:func:`_ekf_switches`): RK4 or Euler,
    analytic Jacobians or central differences (also of :func:`_model_step`, which reads the
    first, and :func:`_model_jacobian`, the second). A kernel that takes one is compiled for
    that pair only (its numba type names the subclass, as a :class:`CompiledModel`'s does), so a
    filter compiles the one loop it runs, not all four.

    Parameters
    ----------
    *args, **kwargs
        None accepted: made by :func:`_ekf_switches`.

    Examples
    --------
    >>> _ekf_switches(rk4=True, analytic=False).rk4
    True
    """

    __slots__ = ()
    #: the mean and the transition by RK4 (else Euler)
    rk4: ClassVar[bool] = True
    #: the model's Jacobians (else central differences)
    analytic: ClassVar[bool] = True


class _RK4Analytic(_EkfSwitches):
    __slots__ = ()


class _RK4Differences(_EkfSwitches):
    __slots__ = ()
    analytic = False


class _EulerAnalytic(_EkfSwitches):
    __slots__ = ()
    rk4 = False


class _EulerDifferences(_EkfSwitches):
    __slots__ = ()
    rk4, analytic = False, False


_SWITCHES = {(c.rk4, c.analytic): c() for c in (_RK4Analytic, _RK4Differences, _EulerAnalytic,
                                                  _EulerDifferences)}


def _ekf_switches(rk4: bool, analytic: bool) -> _EkfSwitches:
    """The switches of :func:`_ekf_predict` and :func:`_ekf_block` as a type.

    Parameters
    ----------
    rk4 : bool
        RK4 (else Euler) for the mean and the transition.
    analytic : bool
        The model's Jacobians (else central differences).

    Returns
    -------
    _EkfSwitches
        One of four shared instances, one class per pair.

    Examples
    --------
    >>> type(_ekf_switches(False, True)).__name__
    '_EulerAnalytic'
    """
    return _SWITCHES[(bool(rk4), bool(analytic))]


def _predict_rows(switches: _EkfSwitches, model: Any, X: Array, U: Array, P: Array, c0: Array,
                  pidx: IntArray, h: float, Qh: Array, vs: Any, ms: Any) -> None:
    """:func:`_ekf_predict_rows` with the switches' two flags (from numba kernels only)."""
    raise NotImplementedError("called from numba kernels only")  # pragma: no cover


@overload(_predict_rows)
def _predict_rows_overload(switches, model, X, U, P, c0, pidx, h, Qh, vs, ms):  # type: ignore[no-untyped-def]
    """At typing, the loop for the switches' class: the flags become constants of one
    :func:`_ekf_predict_rows` (inlined into this implementation, itself a call: inlining it
    too into the caller costs twice the compile), and the other three pairs are never typed
    nor compiled."""
    cls = getattr(switches, "instance_class", None)
    if cls is None or not issubclass(cls, _EkfSwitches):
        return None
    rk4, analytic = cls.rk4, cls.analytic

    def impl(switches, model, X, U, P, c0, pidx, h, Qh, vs, ms):  # type: ignore[no-untyped-def]
        _ekf_predict_rows(model, X, U, P, c0, pidx, analytic, h, rk4, Qh, vs, ms)

    return impl


def _step_rows(switches: _EkfSwitches, model: Any, X: Array, U: Array, c0: Array,
               pidx: IntArray, h: float, out: Array) -> None:
    """:func:`_model_step_rows` with the switches' ``rk4`` (from numba kernels only)."""
    raise NotImplementedError("called from numba kernels only")  # pragma: no cover


@overload(_step_rows)
def _step_rows_overload(switches, model, X, U, c0, pidx, h, out):  # type: ignore[no-untyped-def]
    """At typing, the loop with the switches' ``rk4`` constant (:func:`_predict_rows_overload`)."""
    cls = getattr(switches, "instance_class", None)
    if cls is None or not issubclass(cls, _EkfSwitches):
        return None
    rk4 = cls.rk4

    def impl(switches, model, X, U, c0, pidx, h, out):  # type: ignore[no-untyped-def]
        _model_step_rows(model, X, U, c0, pidx, h, rk4, out)

    return impl


def _jacobian_rows(switches: _EkfSwitches, model: Any, X: Array, U: Array, c0: Array,
                   pidx: IntArray, A: Array) -> None:
    """:func:`_model_jacobian_rows` with the switches' ``analytic`` (from numba kernels only)."""
    raise NotImplementedError("called from numba kernels only")  # pragma: no cover


@overload(_jacobian_rows)
def _jacobian_rows_overload(switches, model, X, U, c0, pidx, A):  # type: ignore[no-untyped-def]
    """At typing, the loop with the switches' ``analytic`` constant."""
    cls = getattr(switches, "instance_class", None)
    if cls is None or not issubclass(cls, _EkfSwitches):
        return None
    analytic = cls.analytic

    def impl(switches, model, X, U, c0, pidx, A):  # type: ignore[no-untyped-def]
        _model_jacobian_rows(model, X, U, c0, pidx, analytic, A)

    return impl


@njit(cache=True, error_model="numpy")
def _ekf_predict(model: Any, X: Array, U: Array, P: Array, c0: Array, pidx: IntArray,
                 switches: _EkfSwitches, h: float, Qh: Array, vs: Any,
                 ms: Any) -> None:  # pragma: no cover - numba
    """The EKF's time update of every member over one substep ``h`` with a compiled model, in
    place: :math:`F` at the row, the mean by :func:`_rk4_row`, then
    :math:`P \\leftarrow \\Phi P \\Phi^T + Q h`, :math:`\\Phi = T_4(hF)` (:func:`_t4`,
    :func:`_sandwich`): the operations of ``jac``, ``step`` and :func:`_ekf_covariance`
    (``vs``, ``ms``: :func:`_ekf_scratch`).

    The flags come as a type (``switches``, :func:`_ekf_switches`) and the loop
    (:func:`_ekf_predict_rows`) is compiled with them constant: a run-time branch inside
    the loop keeps numba's reference counting of the row views, which made a member 3-4x
    slower; a branch on two booleans here, outside the loop, compiled all four loops (a first
    call cost 18 s of CPU instead of 10 s per system, issue 28), where a filter runs one."""
    _predict_rows(switches, model, X, U, P, c0, pidx, h, Qh, vs, ms)


@njit(cache=True, error_model="numpy", inline="always")
def _ekf_predict_rows(model: Any, X: Array, U: Array, P: Array, c0: Array, pidx: IntArray,
                      analytic: bool, h: float, rk4: bool, Qh: Array, vs: Any,
                      ms: Any) -> None:  # pragma: no cover - numba
    B, N = X.shape
    n = N - pidx.shape[0]
    c, k1, k2, k3, k4, xs, x1, fm = vs
    Fp, F, A, T, M = ms
    for b in range(B):
        xa = X[b]
        _row_params(c0, pidx, xa, n, c)
        _jacobian_row(model, xa, U[b], c, pidx, analytic, F, k1, fm, xs, Fp)
        _rk4_row(model, xa, U[b], c, h, rk4, x1, k1, k2, k3, k4, xs)
        for i in range(n):
            xa[i] = x1[i]
        for i in range(N):
            for j in range(N):
                A[i, j] = h * F[i, j]
        _t4(A, rk4, T, M)
        _sandwich(T, P[b], Qh, M)


@njit(cache=True)
def _ekf_block(model: Any, X: Array, P: Array, nis: Array, Y: Array, U: Array, sel: IntArray,
               R: Array, diagonal: bool, c0: Array, pidx: IntArray, switches: _EkfSwitches,
               h: float, substeps: int, Qh: Array, Xs: Array, Zs: Array,
               Ds: Array) -> int:  # pragma: no cover - numba
    """The EKF over a block of samples ``Y`` ``(B, T, p)``, ``U`` ``(B, T, m)`` with a compiled
    model and a selection output, in place: per sample :func:`_condition_selection` (its NIS
    into ``nis`` ``(B,)``), then ``substeps`` times :func:`_ekf_predict`, the estimate after it
    into ``Xs[:, j]`` and ``Zs[:, j]`` ``(B, T, n)``, the parameters and the NIS into
    ``Ds[:, j]`` ``(B, T, q + 1)``: the sample loop of ``_KalmanFilter._step`` in one call.
    Returns the sample at which an estimate left the finite numbers (the state left there),
    else -1."""
    B, T = Y.shape[0], Y.shape[1]
    N = X.shape[1]
    n = N - pidx.shape[0]
    y = np.empty((B, Y.shape[2]))
    u = np.empty((B, U.shape[2]))
    vs, ms = _ekf_scratch(n, N, c0.shape[0])
    for j in range(T):
        for b in range(B):
            for c in range(Y.shape[2]):
                y[b, c] = Y[b, j, c]
            for c in range(U.shape[2]):
                u[b, c] = U[b, j, c]
        _condition_selection(X, P, y, sel, R, diagonal, nis)
        for _ in range(substeps):
            _ekf_predict(model, X, u, P, c0, pidx, switches, h, Qh, vs, ms)
        if _first_nonfinite(X) >= 0:
            return j
        for b in range(B):
            for i in range(n):
                Xs[b, j, i] = X[b, i]
                Zs[b, j, i] = X[b, i]
            for i in range(n, N):
                Ds[b, j, i - n] = X[b, i]
            Ds[b, j, N - n] = nis[b]
    return -1


def _central_differences(f: Callable[[Array], Array], X: Array, cols: int) -> Array:
    """Central-difference Jacobians ``(K, rows, cols)`` of the row map ``f`` ``(K, N) -> (K,
    rows)`` at the rows ``X`` in their first ``cols`` components (relative step ``1e-6``):
    ``f`` is called once, on the ``2 cols K`` perturbed rows stacked (a row's value does not
    depend on the others)."""
    K = X.shape[0]
    e = 1e-6 * np.maximum(1.0, np.abs(X[:, :cols]))  # (K, cols)
    Xs = np.repeat(X[None], 2 * cols, axis=0)  # (2 cols, K, N): +e_j then -e_j
    for j in range(cols):
        Xs[j, :, j] += e[:, j]
        Xs[cols + j, :, j] -= e[:, j]
    F = f(Xs.reshape(2 * cols * K, -1)).reshape(2 * cols, K, -1)
    return np.stack([(F[j] - F[cols + j]) / (2.0 * e[:, j])[:, None] for j in range(cols)],
                    axis=2)


def _rows_output(out: Callable[[Array], Array], chans: list[int], Z: Array) -> Array:
    """The channels ``chans`` of ``out`` at each row of ``Z``, ``(K, len(chans))``."""
    return np.array([out(z)[chans] for z in Z])


def _probe_selection(output: Callable[[Array, Any], Array], params: Any, n: int,
                     channels: Sequence[int]) -> list[int] | None:
    """State index ``j`` with ``h_c(x) = x_j`` for each channel, or ``None`` if ``h`` is not a
    selection (probed at two random points)."""
    rng = np.random.default_rng(12345)
    xs = [rng.uniform(-2.0, 2.0, n) for _ in range(2)]
    ys = [np.asarray(output(x, params), dtype=float).reshape(-1) for x in xs]
    idx = []
    for c in channels:
        hit = [j for j in range(n) if all(y[c] == x[j] for x, y in zip(xs, ys))]
        if len(hit) != 1:
            return None
        idx.append(hit[0])
    return idx


# ======================================================================================
# models: the system's ODE, or the MJCF stepped by MuJoCo (rows: (K, N) augmented states)
# ======================================================================================


class SystemModel:
    """A :class:`System`'s ODE with the parameters ``estimate`` appended to the state, on rows.

    Every method takes rows ``X`` ``(K, N)`` of augmented states (``N = n + q``) and inputs
    ``U`` ``(K, m)``; the parameters ``X[:, n:]`` are constant (:math:`\\dot\\theta = 0`).

    Parameters
    ----------
    system : System
        Gives ``dynamics``, ``output``, the known parameters and (optionally) the analytic
        ``jacobian`` / ``param_jacobian``.
    estimate : sequence of str
        Names of ``system.param_names`` to estimate by augmentation.
    jacobian : {"auto", "analytic", "fd"}
        ``auto``: analytic where the system provides it, else central finite differences.

    Attributes
    ----------
    compiled : CompiledModel or None
        The system's compiled ODE the kernels call, or None: its Python ``dynamics``, one
        call per row (see the module docstring).
    """

    kind = "system"

    def __init__(self, system: System, estimate: Sequence[str] = (), jacobian: str = "auto") -> None:
        if not isinstance(system, System):
            raise DesignError(f"system must be a System instance; found {type(system).__name__}")
        self.system = system
        self.names = tuple(str(e) for e in estimate)
        unknown = [e for e in self.names if e not in system.param_names]
        if unknown or len(set(self.names)) != len(self.names):
            raise DesignError(f"estimate must name distinct parameters of {type(system).__name__} "
                              f"{list(system.param_names)}; found {list(self.names)}")
        if jacobian not in JACOBIANS:
            raise DesignError(f"jacobian must be one of {list(JACOBIANS)}; found {jacobian!r}")
        has_x = callable(getattr(system, "jacobian", None))
        has_p = callable(getattr(system, "param_jacobian", None))
        if jacobian == "analytic" and (not has_x or (self.names and not has_p)):
            need = ["jacobian"] + (["param_jacobian"] if self.names else [])
            raise DesignError(f"jacobian='analytic' needs {type(system).__name__}.{' and .'.join(need)}"
                              f"(t, x, u, p{', names' if self.names else ''}); it has "
                              f"{[m for m in need if callable(getattr(system, m, None))] or 'none'}")
        self.analytic = jacobian != "fd" and has_x and (has_p or not self.names)
        self.jacobian_kind = "analytic" if self.analytic else "fd"
        self.n = len(system.state_names)
        self.q = len(self.names)
        self.N = self.n + self.q
        self.base = dict(system.params)
        self.state_names = tuple(system.state_names)
        self.output_names = tuple(system.output_names)
        self.n_inputs = len(system.input_names)
        #: the system's ODE compiled for the kernels (:class:`CompiledModel`), where it has
        #: one with the Jacobians this filter asks for; ``None``: its Python ``dynamics``
        self.compiled = self._compiled(system)
        #: the system's ``dynamics_batch(X, U)`` (its own parameters, all rows in one call:
        #: the MJCF systems) where no parameter is estimated, else ``None``
        rows = getattr(system, "dynamics_batch", None)
        self._rows = rows if callable(rows) and not self.q else None
        self._c0 = system.param_vector(self.base)
        self._pidx = np.array([system.param_names.index(nm) for nm in self.names],
                              dtype=np.int64)

    def _compiled(self, system: System) -> CompiledModel | None:
        cm = system.compiled
        if cm is not None and self.analytic and (cm.jacobian is None or (
                self.q and cm.param_jacobian is None)):
            return None
        return cm

    # --------------------------------------------------------------------- parameters
    def params(self, xa: Array) -> dict[str, float]:
        """The system's parameters with the estimated ones read from the row ``xa``."""
        if not self.q:
            return self.base
        p = dict(self.base)
        n = self.n
        for j, nm in enumerate(self.names):
            p[nm] = float(xa[n + j])
        return p

    # --------------------------------------------------------------------- dynamics
    def _f(self, Z: Array, U: Array, ps: Sequence[Mapping[str, float]]) -> Array:
        """The Python ``dynamics`` of the rows ``Z`` ``(K, n)`` (row ``k`` with the input
        ``U[k]`` and the parameters ``ps[k]``), ``(K, n)``: one call per row, or one call of
        the system's ``dynamics_batch`` for all rows where it has one and nothing is
        estimated (then ``ps`` are the system's own parameters)."""
        if self._rows is not None:
            return np.asarray(self._rows(Z, U), dtype=float)
        dyn = self.system.dynamics
        out = np.empty(Z.shape)
        for k in range(Z.shape[0]):
            out[k] = dyn(0.0, Z[k], U[k], ps[k])
        return out

    def deriv(self, X: Array, U: Array) -> Array:
        """:math:`(f(x, u, \\theta), 0)` of the rows, shape (K, N)."""
        out = np.zeros(X.shape)
        n = self.n
        if self.compiled is not None:
            _model_deriv(self.compiled, np.ascontiguousarray(X, dtype=float),
                         np.ascontiguousarray(U, dtype=float), self._c0, self._pidx, out)
            return out
        ps = [] if self._rows is not None else [self.params(x) for x in X]
        out[:, :n] = self._f(X[:, :n], U, ps)
        return out

    def jac(self, X: Array, U: Array) -> Array:
        """:math:`F = \\partial (f, 0) / \\partial (x, \\theta)` of the rows, shape (K, N, N)."""
        n, N, K = self.n, self.N, X.shape[0]
        A = np.zeros((K, N, N))
        if self.compiled is not None:
            _model_jacobian(self.compiled, np.ascontiguousarray(X, dtype=float),
                            np.ascontiguousarray(U, dtype=float), self._c0, self._pidx,
                            _ekf_switches(True, self.analytic), A)
            return A
        if not self.analytic:
            Ucols = np.tile(np.asarray(U, dtype=float), (2 * N, 1))
            A[:, :n] = _central_differences(lambda Z: self.deriv(Z, Ucols)[:, :n], X, N)
            return A
        jx = self.system.jacobian  # type: ignore[attr-defined]
        jp = getattr(self.system, "param_jacobian", None)
        for k in range(K):
            p = self.params(X[k])
            A[k, :n, :n] = jx(0.0, X[k, :n], U[k], p)
            if self.q:
                A[k, :n, n:] = jp(0.0, X[k, :n], U[k], p, self.names)  # type: ignore[misc]
        return A

    def step(self, X: Array, U: Array, h: float, method: str,
             members: Array | None = None) -> Array:
        """One RK4 (or Euler) step of ``h`` of the rows with ``u`` held (``members`` unused):
        :math:`x + \\tfrac{h}{6}(k_1 + 2 (k_2 + k_3) + k_4)`,
        :math:`k_2 = f(x + \\tfrac{h}{2} k_1)`, ... (:func:`hgo_mj.observers._integrate.rk4`;
        the compiled kernel :func:`_rk4_row` does the same operations); the parameters
        ``X[:, n:]`` are kept."""
        n = self.n
        out = np.array(X, dtype=float, order="C")
        if self.compiled is not None:
            _model_step(self.compiled, np.ascontiguousarray(X, dtype=float),
                        np.ascontiguousarray(U, dtype=float), self._c0, self._pidx, h,
                        _ekf_switches(method == "rk4", self.analytic), out)
            return out
        ps = [] if self._rows is not None else [self.params(x) for x in X]
        scheme = _integrate.rk4 if method == "rk4" else _integrate.euler
        out[:, :n] = scheme(lambda Z: self._f(Z, U, ps), out[:, :n], h)
        return out

    def output(self, xa: Array) -> Array:
        """``h`` of one augmented row (the estimated parameters read from it)."""
        return np.asarray(self.system.output(xa[:self.n], self.params(xa)),
                          dtype=float).reshape(-1)

    def selection(self, channels: Sequence[int]) -> list[int] | None:
        return _probe_selection(self.system.output, self.base, self.n, channels)


#: MJCF fields an augmented MuJoCo filter may estimate, by the object kind naming the element
def _check_model_matches(system: System, m: Any, estimate: Sequence[str]) -> None:
    """Refuse a shipped MJCF (with its ``model_fields``) whose parameters, read back by the
    system's ``from_mjmodel``, are not the system's: ``system_params`` change the system, not
    the MJCF the filter steps, so the filter would silently get the plant's true model.
    Parameters being estimated are exempt (the system holds their initial guess)."""
    try:
        read = type(system).from_mjmodel(m).params
    except (DesignError, NotImplementedError):  # a system that reads nothing back
        return
    skip = set(estimate)
    diff = [k for k, v in system.params.items()
            if k in read and k not in skip and not np.allclose(
                np.asarray(v, dtype=float), np.asarray(read[k], dtype=float), rtol=1e-6,
                atol=1e-12)]
    if diff:
        said = ", ".join(f"{k} = {system.params[k]!r}" for k in diff)
        has = ", ".join(f"{k} = {read[k]!r}" for k in diff)
        raise DesignError(
            f"the MuJoCo filter steps the MJCF, whose {has} differ from the system's {said}: "
            f"system_params do not reach the MJCF. Give model_fields= to change the filter's "
            f"copy of it (e.g. {{'body_mass[body]': value, 'dof_damping[joint]': value}}), or "
            f"model= a modified MjModel")


#: MuJoCo's warnings of a reset to the reference pose (an unstable qpos, qvel or qacc)
_RESET_WARNINGS = list(int(w) for w in (mujoco.mjtWarning.mjWARN_BADQPOS,
                                         mujoco.mjtWarning.mjWARN_BADQVEL,
                                         mujoco.mjtWarning.mjWARN_BADQACC))


def _resets(d: Any) -> int:
    """The number of resets MuJoCo has counted in ``d`` (:data:`_RESET_WARNINGS`)."""
    w = d.warning
    return sum(int(w[i].number) for i in _RESET_WARNINGS)


def _kalman_fields(system: System) -> dict[str, str]:
    """The system's aliases ``{parameter name: "field[element]" or "opt.gravity"}`` (its
    ``"kalman_fields"`` form), or none if it declares no such form."""
    if "kalman_fields" not in system.forms:
        return {}
    fields = system.form("kalman_fields")
    if not isinstance(fields, Mapping) or not all(
            isinstance(k, str) and isinstance(v, str) for k, v in fields.items()):
        raise DesignError(f"{type(system).__name__}'s kalman_fields form must map parameter "
                          f"names to model fields (str -> str); found {fields!r}")
    return dict(fields)


class MujocoModel:
    """The MJCF as the filter's model: ``MjData`` stepping for the mean,
    ``mujoco.mjd_transitionFD`` for the transition matrix.

    MuJoCo is called per model and data, so the rows are stepped one after another through one
    ``MjData`` (and one of the Jacobian twin): each call loads ``qpos``, ``qvel``, ``ctrl``, the
    time and clears the solver's warm start, so a step is a function of the row alone and a
    member's numbers do not depend on its batch. (One ``MjData`` per member is not kept: the
    pendulum's arena alone is 13 MB.) The estimated parameters are written into the model
    copy before a row whose values differ from the last written.

    Parameters
    ----------
    system : System
        Names the state (``joints``: ``qpos`` then ``qvel``), inputs (``actuators``) and
        outputs (``output`` must be a selection of the state).
    model : mujoco.MjModel, MujocoPlant or None
        The model (copied: the filter never touches the plant's); default the system's shipped
        MJCF. A deliberately wrong copy models a parameter error.
    model_fields : mapping, optional
        Values written into the filter's copy of the model, ``"field[element]"`` (the fields of
        :data:`hgo_mj.plants.fields.FIELDS`, ``"body_inertia[body]"`` three moments) or the
        system's aliases -> value: a wrong model without writing an MJCF (the benchmark's
        mismatch tier). With the shipped MJCF, the model (after these) must hold the system's
        parameters, or the filter is refused: ``system_params`` alone do not reach the MJCF.
    estimate : sequence of str
        Parameters to estimate, each a model field ``"tendon_stiffness[spring]"``,
        ``"actuator_gear[torque]"``, ``"dof_damping[joint]"``, ``"dof_armature[joint]"``,
        ``"body_mass[body]"`` or ``"opt.gravity"`` (the magnitude :math:`g`; all gravity
        torques scale with it, so on the pendulum and the elastic joint it carries
        :math:`m g l` and :math:`MgL`), or a parameter name the system aliases to one in its
        ``"kalman_fields"`` form (elastic joint: ``stiffness``, ``gear``, ``link_damping``,
        ``motor_damping``, ``g``).
    jacobian : {"transition_fd", "fd"}
        ``transition_fd``: ``mujoco.mjd_transitionFD`` (forward differences of one physics
        step). It refuses the RK4 integrator (``mjd_transitionFD: RK4 integrator is not
        supported`` in MuJoCo 4.0), so for an RK4 model it is evaluated on a twin model with
        the Euler integrator at the same timestep (the mean is still the RK4 step), and the
        continuous Jacobian recovered from its velocity rows gives RK4's transition
        :math:`T_4(hF)` (:meth:`_rk4_transitions`; using the Euler twin's matrix as is was
        :math:`O(h^2 K/J)` off, enough to wreck the two-link arm's stiffness estimates).
        ``fd``: central differences of the model's own step (:math:`2N` steps). Parameter
        columns are always finite differences of the step.
    """

    kind = "mujoco"

    def __init__(self, system: System, model: Any = None, estimate: Sequence[str] = (),
                 jacobian: str = "transition_fd",
                 model_fields: Mapping[str, Any] | None = None) -> None:
        from ..plants.mujoco import MujocoPlant

        if not isinstance(system, System):
            raise DesignError(f"system must be a System instance; found {type(system).__name__}")
        if system.model_file is None:
            raise DesignError(f"{type(system).__name__} is not a MuJoCo system (model_file is None); "
                              f"use the System-based filter")
        shipped = model is None
        if model is None:
            model = type(system).load_model()
        elif isinstance(model, MujocoPlant):
            model = model.model
        if not isinstance(model, mujoco.MjModel):
            raise DesignError(f"model must be a mujoco.MjModel or a MujocoPlant; found "
                              f"{type(model).__name__}")
        if jacobian not in ("transition_fd", "fd"):
            raise DesignError(f"jacobian must be 'transition_fd' or 'fd'; found {jacobian!r}")
        self.jacobian_kind = jacobian
        self.system = system
        m = copy.deepcopy(model)
        if model_fields:
            set_fields(m, model_fields, _kalman_fields(system))
        if shipped:
            _check_model_matches(system, m, estimate)
        self.m = m
        self.d = mujoco.MjData(m)
        self.ts = float(m.opt.timestep)
        joints = system.joints
        #: the model's names bound to ids and addresses (the one binding)
        self.binding = names = Binding(m, "the model")
        self.qadr, self.vadr = names.qpos(joints), names.dofs(joints)
        if m.nq != m.nv or m.nv != len(joints) or m.na != 0:
            raise DesignError(f"the MuJoCo filter needs a model whose only degrees of freedom are "
                              f"the hinge/slide joints {list(joints)} and no activations; found "
                              f"nq={m.nq}, nv={m.nv}, na={m.na}")
        nv = m.nv
        #: our state index -> index in MuJoCo's tangent state (dq, dv)
        self.perm = np.concatenate((self.vadr, nv + self.vadr))
        self.aid = names.ids("actuator", system.actuators).tolist()
        self.n = 2 * len(joints)
        self.state_names = tuple(system.state_names)
        self.output_names = tuple(system.output_names)
        self.n_inputs = len(system.actuators)
        # parameters: model fields, or the system's aliases of them
        aliases = _kalman_fields(system)
        self.names = tuple(str(e) for e in estimate)
        if len(set(self.names)) != len(self.names):
            raise DesignError(f"estimate must be distinct; found {list(self.names)}")
        self._specs = [self._resolve(aliases.get(e, e), e, aliases) for e in self.names]
        self.q = len(self.names)
        self.N = self.n + self.q
        self.twin = None
        if jacobian == "transition_fd":
            tw = copy.deepcopy(m)
            self._rk4 = tw.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
            if self._rk4:
                tw.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
            self.twin = tw
            self.dt_ = mujoco.MjData(tw)
            self._A = np.zeros((2 * nv, 2 * nv))
            self._M = np.zeros((nv, nv))
        self._last: list[tuple[float, ...] | None] = [None, None]  # stepping model, twin
        #: row count -> (mujoco.batch.Batch of the model, its bound fields): :meth:`_step_batch`
        self._batches: dict[int, tuple[Any, ...]] = {}
        # our joint order -> MuJoCo's (the model has exactly these joints, checked above)
        self._sorted = bool(np.all(self.qadr == np.arange(nv)) and np.all(self.vadr == np.arange(nv)))
        self._inv_q = np.argsort(self.qadr)
        self._inv_v = np.argsort(self.vadr) + len(joints)
        self._pix = np.ix_(self.perm, self.perm)
        self._eyeN = np.eye(self.N)
        self._down = None
        g = np.array(m.opt.gravity, dtype=float)
        if np.linalg.norm(g) > 0:
            self._down = g / np.linalg.norm(g)

    def __getstate__(self) -> dict[str, Any]:
        """Pickle and copy without the batches (MuJoCo's ``Batch`` does not pickle; they are
        made again on the next :meth:`step`)."""
        return {**self.__dict__, "_batches": {}}

    def _resolve(self, spec: str, name: str, aliases: dict[str, str]) -> tuple[str, int]:
        field, i = resolve(self.m, spec, f"cannot estimate {name!r} (or one of the aliases "
                                         f"{sorted(aliases)})")
        if field in VECTOR:
            raise DesignError(f"cannot estimate {name!r}: {field} holds a vector per element; "
                              f"estimate a scalar field")
        return field, i

    # --------------------------------------------------------------------- parameters
    def get_params(self) -> Array:
        return np.array([get_field(self.m, field, i) for field, i in self._specs], dtype=float)

    def _set_params(self, th: Array, twin: bool = False) -> None:
        """Write the parameter values into the stepping model (and the Jacobian twin); each
        model remembers what it holds, so an unchanged value costs a tuple comparison."""
        key = tuple(th.tolist())
        targets = ((self.m, 0), (self.twin, 1)) if twin and self.twin is not None else ((self.m, 0),)
        for mm, slot in targets:
            if self._last[slot] == key:
                continue
            self._last[slot] = key
            for (field, i), v in zip(self._specs, key):
                if field == "gravity":  # along the model's own direction, even through g = 0
                    g = self._down * v  # type: ignore[operator]
                    mm.opt.gravity[0], mm.opt.gravity[1], mm.opt.gravity[2] = g[0], g[1], g[2]
                else:
                    set_field(mm, field, i, v)

    def _load(self, d: Any, x: Array, u: Array) -> None:
        """Put the row ``x`` and input ``u`` into ``d`` (time 0, no warm start)."""
        nj = self.n // 2
        d.time = 0.0
        if self._sorted:
            d.qpos[:] = x[:nj]
            d.qvel[:] = x[nj:self.n]
        else:
            d.qpos[:] = x[self._inv_q]
            d.qvel[:] = x[self._inv_v]
        d.qacc_warmstart[:] = 0.0
        ctrl = d.ctrl
        for k, a in enumerate(self.aid):
            ctrl[a] = u[k]

    def _steps(self, h: float) -> int:
        k = round(h / self.ts)
        if k < 1 or abs(h / self.ts - k) > 1e-9 * max(1.0, h / self.ts):
            raise DesignError(f"the MuJoCo filter's step {h:g} must be a multiple of the model "
                              f"timestep {self.ts:g}")
        return int(k)

    def _step_row(self, xa: Array, u: Array, h: float) -> Array:
        """MuJoCo's own step(s) over ``h`` from one augmented row with ``u`` held.

        MuJoCo answers a row it calls unstable (NaN, or beyond ``mjMAXVAL`` in ``qpos``,
        ``qvel`` or ``qacc``) by resetting ``MjData`` to the model's reference pose and
        counting a warning; stepping on from there would give a silent estimate of zeros, so a
        warning counted during the step is a :class:`DivergenceError`."""
        if self.q:
            self._set_params(xa[self.n:])
        d = self.d
        self._load(d, xa, u)
        warned = _resets(d)
        for _ in range(self._steps(h)):
            mujoco.mj_step(self.m, d)
        if _resets(d) != warned:
            raise DivergenceError(f"MuJoCo reset the filter's model: the row {xa.tolist()} is "
                                  f"unstable (NaN or beyond mjMAXVAL in qpos, qvel or qacc)")
        out = xa.copy()
        nj = self.n // 2
        out[:nj] = d.qpos[self.qadr]
        out[nj:self.n] = d.qvel[self.vadr]
        return out

    def step(self, X: Array, U: Array, h: float, method: str = "",
             members: Array | None = None) -> Array:
        """MuJoCo's own step(s) over ``h`` of every row ``X`` ``(K, N)`` with ``U`` held (the
        model's integrator; ``method`` is not used): all rows in one call of MuJoCo's batch
        where no parameter is estimated (one model for every row; the same bits as
        :meth:`_step_row`, tested), else row by row."""
        if not self.q:
            return self._step_batch(np.asarray(X, dtype=float), np.asarray(U, dtype=float), h)
        out = np.empty_like(X)
        for k in range(X.shape[0]):
            out[k] = self._step_row(X[k], U[k], h)
        return out

    def _step_batch(self, X: Array, U: Array, h: float) -> Array:
        """:meth:`_step_row` of every row on a ``mujoco.batch.Batch`` of the model (one thread,
        kept per row count): each row loaded as :meth:`_load` does (time 0, no warm start),
        a reset warning counted in a row's step is the same :class:`DivergenceError`."""
        K, nj = X.shape[0], self.n // 2
        if K not in self._batches:
            bt = mujoco.batch.Batch(self.m, K, nthread=1)
            self._batches[K] = (bt, *(bt.bind(f) for f in (
                "qpos", "qvel", "ctrl", "qacc_warmstart", "time")))
        bt, qpos, qvel, ctrl, warm, time = self._batches[K]
        qpos[:, self.qadr] = X[:, :nj]
        qvel[:, self.vadr] = X[:, nj:self.n]
        ctrl[:] = 0.0
        if self.aid:
            ctrl[:, self.aid] = U
        warm[:] = 0.0
        time[:] = 0.0
        before = bt.warning[:, _RESET_WARNINGS, 1].sum(axis=1)
        bt.step(nstep=self._steps(h))
        bad = np.flatnonzero(bt.warning[:, _RESET_WARNINGS, 1].sum(axis=1) != before)
        if bad.size:
            raise DivergenceError(f"MuJoCo reset the filter's model: the row "
                                  f"{X[bad[0]].tolist()} is unstable (NaN or beyond mjMAXVAL in "
                                  f"qpos, qvel or qacc)")
        out = X.copy()
        out[:, :nj] = qpos[:, self.qadr]
        out[:, nj:self.n] = qvel[:, self.vadr]
        return out

    def transition(self, X: Array, U: Array, h: float) -> tuple[Array, Array]:
        """``(x(t + h), Phi)`` of every row: ``(K, N)`` and ``(K, N, N)``; without estimated
        parameters and with ``mjd_transitionFD``, the steps in one batch call and the RK4
        conversion over all rows at once (:meth:`_transition_rows`), else row by row."""
        if not self.q and self.twin is not None:
            return self._transition_rows(np.asarray(X, dtype=float), np.asarray(U, dtype=float), h)
        Xn = np.empty_like(X)
        Phi = np.empty((X.shape[0], self.N, self.N))
        for k in range(X.shape[0]):
            Xn[k], Phi[k] = self._transition_row(X[k], U[k], h)
        return Xn, Phi

    def _transition_row(self, xa: Array, u: Array, h: float) -> tuple[Array, Array]:
        n = self.n
        k = self._steps(h)
        Phi = self._eyeN
        x = xa
        ts = self.ts
        for _ in range(k):
            if self.q:
                self._set_params(x[n:], twin=True)
            if self.twin is not None:
                self._load(self.dt_, x, u)
                if self._rk4:
                    mujoco.mj_forward(self.twin, self.dt_)  # the mass matrix at x
                mujoco.mjd_transitionFD(self.twin, self.dt_, 1e-6, False, self._A, None, None, None)
                Ax = self._A if self._rk4 else self._A[self._pix]
                if self._rk4:
                    mujoco.mj_fullM(self.twin, self.dt_, self._M)  # after mj_forward
                    Ax = self._rk4_transitions(Ax[None], self._M[None], ts)[0][self._pix]
            else:
                Ax = _central_differences(lambda Z: np.array([self._step_row(z, u, ts)[:n]
                                                              for z in Z]), x[None], n)[0]
            x1 = self._step_row(x, u, ts)
            A = self._eyeN.copy()
            A[:n, :n] = Ax
            for j in range(self.q):
                e = 1e-6 * max(1.0, abs(float(x[n + j])))
                xp = x.copy()
                xp[n + j] += e
                A[:n, n + j] = (self._step_row(xp, u, ts)[:n] - x1[:n]) / e
            if self.q:
                self._set_params(x[n:])  # undo the perturbation
            Phi = A @ Phi
            x = x1
        return x, Phi

    def _transition_rows(self, X: Array, U: Array, h: float) -> tuple[Array, Array]:
        """:meth:`_transition_row` of every row (no estimated parameters, the twin's
        ``mjd_transitionFD``): per substep, ``mjd_transitionFD`` (and the mass matrix) row by
        row, the RK4 conversion (:meth:`_rk4_transitions`) over all rows in array operations,
        the mean by :meth:`_step_batch`; the same arithmetic per row (tested bit for bit)."""
        K, n, nv = X.shape[0], self.n, self.n // 2
        ts, d, tw = self.ts, self.dt_, self.twin
        AE = np.empty((K, n, n))
        M = np.empty((K, nv, nv))
        Phi: Array = np.broadcast_to(self._eyeN, (K, n, n))
        x = X
        for _ in range(self._steps(h)):
            for r in range(K):
                self._load(d, x[r], U[r])
                if self._rk4:
                    mujoco.mj_forward(tw, d)  # the mass matrix at x
                mujoco.mjd_transitionFD(tw, d, 1e-6, False, AE[r], None, None, None)
                if self._rk4:
                    mujoco.mj_fullM(tw, d, M[r])
            Ax = self._rk4_transitions(AE, M, ts) if self._rk4 else AE
            Phi = Ax[:, self.perm][:, :, self.perm] @ Phi
            x = self._step_batch(x, U, ts)
        return x, np.ascontiguousarray(Phi)

    def _rk4_transitions(self, AE: Array, M: Array, h: float) -> Array:
        """RK4's transitions from the Euler twin's ``AE`` ``(K, 2 nv, 2 nv)`` (MuJoCo's order,
        tangent space) with the mass matrices ``M`` ``(K, nv, nv)`` at the rows.

        MuJoCo's Euler step is semi-implicit and implicit in the joint damping :math:`D`:
        :math:`v^+ = v + h (M + hD)^{-1} f`, :math:`q^+ = q + h v^+`. Its velocity rows are
        :math:`G = h (M + hD)^{-1} \\partial f/\\partial x`, so the acceleration Jacobian is
        :math:`a_x = (I + h M^{-1} D)\\, G / h`, the continuous Jacobian
        :math:`F = [[0, I], [a_q, a_v]]` and :math:`\\Phi = T_4(hF)`, RK4's linearization (the
        twin's own position rows differ from RK4's by :math:`h^2 a_q / 2`, which matters for
        stiff springs)."""
        K, k = AE.shape[0], AE.shape[1] // 2
        G = AE[:, k:].copy()
        G[:, :, k:] -= np.eye(k)
        D = np.broadcast_to(np.diag(self.twin.dof_damping), (K, k, k))  # type: ignore[union-attr]
        ax = (np.eye(k) + h * np.linalg.solve(M, D)) @ G / h
        F = np.zeros_like(AE)
        F[:, :k, k:] = np.eye(k)
        F[:, k:] = ax
        Phi = np.empty_like(AE)
        _transition(np.ascontiguousarray(h * F), 1.0, True, Phi)
        return Phi

    def output(self, xa: Array) -> Array:
        return np.asarray(self.system.output(xa[:self.n], self.system.params), dtype=float).reshape(-1)

    def selection(self, channels: Sequence[int]) -> list[int] | None:
        return _probe_selection(self.system.output, self.system.params, self.n, channels)


# ======================================================================================
# the filters
# ======================================================================================


class _Tuning:
    """What a filter derives from one member's parameters: the augmented process noise
    intensity ``Qc`` ``(N, N)``, the measurement covariance ``R`` ``(p, p)`` and whether it is
    diagonal (the sequential scalar updates), and for the UKF the sigma-point scale ``c`` and
    weights ``Wm``, ``Wc`` (:func:`_sigma_weights`)."""

    __slots__ = ("Qc", "R", "diag_R", "c", "Wm", "Wc")

    def __init__(self, Qc: Array, R: Array, diag_R: bool) -> None:
        self.Qc, self.R, self.diag_R = Qc, R, diag_R
        self.c = 0.0
        self.Wm = self.Wc = np.zeros(0)


def _sigma_weights(N: int, alpha: float, beta: float, kappa: float) -> tuple[float, Array, Array]:
    """The scaled sigma points' spread ``c = sqrt(N + lambda)`` and the weights ``Wm``, ``Wc``
    ``(2N + 1,)`` [WM00], :math:`\\lambda = \\alpha^2 (N + \\kappa) - N`; refused where
    :math:`N + \\lambda \\le 0`."""
    lam = alpha ** 2 * (N + kappa) - N
    if not N + lam > 0:
        raise DesignError(f"alpha^2 (N + kappa) must be > 0 (sigma-point spread); found "
                          f"{N + lam:g} with N = {N}, alpha = {alpha:g}, kappa = {kappa:g}")
    Wm = np.full(2 * N + 1, 0.5 / (N + lam))
    Wc = Wm.copy()
    Wm[0] = lam / (N + lam)
    Wc[0] = lam / (N + lam) + 1.0 - alpha ** 2 + beta
    return math.sqrt(N + lam), Wm, Wc


class _KalmanFilter(Observer):
    """Shared construction, validation, measurement update and bookkeeping (see module)."""

    backend = "system"
    needs_normal_form = False
    measurement_update = True

    @classmethod
    def applicability(cls, system: System) -> str | None:
        """Any system with dynamics; the MuJoCo filters need an MJCF model whose only degrees
        of freedom are hinge/slide joints."""
        if cls.backend == "mujoco" and system.model_file is None:
            return (f"needs an MJCF model (its mean steps MuJoCo); {type(system).__name__} is "
                    f"an ODE system: use ekf / ukf")
        return None

    def __init__(self, system: System | None = None, *, estimate: Sequence[str] = (),
                 Q: Any = 1e-4, Q_theta: Any = 1e-6, R: Any = None, sensor: Any = None,
                 P0: Any = 1.0, P0_theta: Any = 1.0, x_hat0: Any = None, theta_hat0: Any = None,
                 outputs: Any = None, method: str = "rk4", substeps: int = 1,
                 jacobian: str = "auto", model: Any = None,
                 model_fields: Mapping[str, Any] | None = None,
                 on_unstable: str = "raise") -> None:
        if system is None or not isinstance(system, System):
            raise DesignError(f"{type(self).__name__} needs a System; found "
                              f"{type(system).__name__}")
        if isinstance(estimate, str):
            estimate = (estimate,)
        self.model: SystemModel | MujocoModel
        if self.backend == "mujoco":
            jac = "transition_fd" if jacobian == "auto" else jacobian
            self.model = MujocoModel(system, model, estimate, jac, model_fields)
        else:
            if model is not None or model_fields is not None:
                raise DesignError("model= and model_fields= are for the MuJoCo filters "
                                  "(ekf_mujoco, ukf_mujoco); give system_params= instead")
            self.model = SystemModel(system, estimate, jacobian)
        mdl = self.model
        n_out = len(system.output_names)
        super().__init__(system, order=mdl.n,
                         outputs=tuple(range(n_out)) if outputs is None else outputs,
                         on_unstable=on_unstable)
        self.q = mdl.q
        self.N = mdl.N
        self.estimate = mdl.names
        self.method = one_of("method", method, METHODS)
        self.substeps = positive_int("substeps", substeps)
        p = len(self.outputs)
        # covariances
        none = np.zeros((0, 0))
        self.Qc = self._augmented(positive_semidefinite("Q", Q, self.n), positive_semidefinite(
            "Q_theta", Q_theta, self.q) if self.q else none)
        if R is None:
            if sensor is not None:
                var = np.asarray(sensor.noise_variance(n_out), dtype=float)[list(self.outputs)]
                if not np.all(var > 0):
                    zero = [system.output_names[c] for c, v in zip(self.outputs, var) if not v > 0]
                    raise DesignError(f"R defaults to the sensor chain's noise variance, which is 0 "
                                      f"for channel(s) {zero}: R must be positive definite; give R=")
                R = var
            else:
                R = 1e-6
        self.R = positive_definite("R", R, p)
        self.P0 = self._augmented(positive_definite("P0", P0, self.n), positive_definite(
            "P0_theta", P0_theta, self.q) if self.q else none)
        if self.q and theta_hat0 is None:
            raise DesignError(f"theta_hat0 is required with estimate={list(self.estimate)} (the "
                              f"initial guess of the estimated parameters)")
        self.sel = mdl.selection(self.outputs)
        self._sel = np.array(self.sel if self.sel is not None else [], dtype=np.int64)
        self.family_diagnostics = (  # type: ignore[misc]
            *(f"theta_{nm}" for nm in self.estimate), "nis")
        self._x_hat0 = None if x_hat0 is None else (
            vector("x_hat0", x_hat0, self.n) if np.ndim(x_hat0) <= 1
            else batch_rows("x_hat0", x_hat0, self.n, None))
        self._theta_hat0 = None if not self.q else (
            vector("theta_hat0", theta_hat0, self.q) if np.ndim(theta_hat0) <= 1
            else batch_rows("theta_hat0", theta_hat0, self.q, None))
        #: what the filter derives from one member's parameters (:class:`_Tuning`), by
        #: :meth:`Params.key`, and ``Q h`` by substep and key (at most ``_CACHE_MAX`` each)
        self._tunings: dict[bytes, _Tuning] = {}
        self._qh: dict[tuple[float, bytes], Array] = {}

    def _augmented(self, state: Array, params: Array) -> Array:
        """The block-diagonal ``N x N`` matrix of a state block and a parameter block."""
        out = np.zeros((self.N, self.N))
        out[:self.n, :self.n] = state
        out[self.n:, self.n:] = params
        return out

    # ------------------------------------------------------------------ parameters
    def _parameters(self) -> dict[str, Any]:
        """The noise covariances as the filter uses them: ``Q`` ``(n, n)``, ``R`` ``(p, p)``
        and, with ``estimate``, ``Q_theta`` ``(q, q)`` (full matrices, whatever form the
        constructor was given)."""
        n = self.n
        out: dict[str, Any] = {"Q": self.Qc[:n, :n].copy(), "R": self.R.copy()}
        if self.q:
            out["Q_theta"] = self.Qc[n:, n:].copy()
        return out

    def _check_parameter(self, name: str, value: Any) -> Array:
        if name == "Q":
            return positive_semidefinite("Q", value, self.n)
        if name == "Q_theta":
            return positive_semidefinite("Q_theta", value, self.q)
        if name == "R":
            return positive_definite("R", value, len(self.outputs))
        return super()._check_parameter(name, value)

    def _tuning(self, p: Params, key: bytes) -> _Tuning:
        """What the filter derives from the parameters ``p`` (``key = p.key()``), built on
        first use."""
        t = self._tunings.get(key)
        if t is None:
            if len(self._tunings) >= _CACHE_MAX:
                self._tunings.clear()
            t = self._tune(p)
            self._tunings[key] = t
        return t

    def _tune(self, p: Params) -> _Tuning:
        R = np.array(p.R, dtype=np.float64, order="C")  # writable: the kernels' type
        Qc = self._augmented(np.asarray(p.Q), np.asarray(p.Q_theta) if self.q
                             else np.zeros((0, 0)))
        return _Tuning(Qc, R, bool(np.all(R == np.diag(np.diag(R)))))

    # ------------------------------------------------------------------ state
    def init(self, batch: int = 1, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None,
             params: Params | None = None, theta_hat0: Any = None) -> State:
        """:meth:`Observer.init`, and ``theta_hat0`` (``(q,)`` for every member or ``(B, q)``;
        default the constructor's): the state ``x`` ``(B, N)`` (the estimate, then the
        parameter estimates) and ``P`` ``(B, N, N)`` (``P0``).

        Parameters
        ----------
        batch, x_hat0, z_hat0, u0, params
            As :meth:`Observer.init` (``z_hat0`` is the same thing as ``x_hat0`` here).
        theta_hat0 : array_like, optional
            Initial parameter estimates.

        Returns
        -------
        State
            The fields ``x``, ``P``, then the base's.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> f = ExtendedKalmanFilter(Pendulum(), estimate=["damping"], theta_hat0=[0.05])
        >>> s = f.init(2, [0.1, 0.0], theta_hat0=[[0.04], [0.06]])
        >>> s.x.tolist(), s.P.shape
        ([[0.1, 0.0, 0.04], [0.1, 0.0, 0.06]], (2, 3, 3))
        """
        if x_hat0 is None and z_hat0 is None and self._x_hat0 is not None \
                and self._x_hat0.ndim == 2:
            x_hat0 = self._x_hat0
        s = super().init(batch, x_hat0, z_hat0=z_hat0, u0=u0, params=params)
        if self.q:
            th = theta_hat0 if theta_hat0 is not None else self._theta_hat0
            s.x[:, self.n:] = batch_rows("theta_hat0", th, self.q, s.batch)
        return s

    def reset(self, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None,
              batch: int | None = None, params: Params | None = None,
              theta_hat0: Any = None) -> None:
        """Restart ``batch`` filters from ``x_hat0`` (physical state; ``z_hat0`` is the same
        thing here) and ``theta_hat0`` (``(q,)`` for every member or ``(B, q)``) with the
        covariance ``P0``; what is not given is the constructor's (``x_hat0`` default zero)."""
        if (batch is None and params is None and x_hat0 is None and z_hat0 is None
                and theta_hat0 is not None and np.ndim(theta_hat0) == 2):
            batch = int(np.shape(theta_hat0)[0])
        if batch is None and x_hat0 is None and z_hat0 is None and self._x_hat0 is not None \
                and self._x_hat0.ndim == 2:
            x_hat0 = self._x_hat0
        super().reset(x_hat0, z_hat0=z_hat0, u0=u0, batch=batch, params=params)
        if self.q and theta_hat0 is not None:
            s = self.state
            s.x[:, self.n:] = batch_rows("theta_hat0", theta_hat0, self.q, s.batch)

    def predicted_output(self, x_hat: Array, z_hat: Array) -> Array | None:
        """The measured outputs ``h(x_hat)`` where the output selects states (``y_c =
        x[sel[c]]``: joint positions, a measured concentration), else None."""
        if self.sel is None:
            return None
        return x_hat[..., self._sel]

    def _init(self, p: Params, x0: Array | None, z0: Array | None,
              u0: Array) -> dict[str, Any]:
        """``x`` from ``x0`` (the parameter columns zero: :meth:`init` writes them), ``P = P0``
        and ``nis`` NaN (no measurement update yet)."""
        B = u0.shape[0]
        x = x0 if x0 is not None else z0
        if x is None:
            x = (np.zeros((B, self.n)) if self._x_hat0 is None
                 else batch_rows("x_hat0", self._x_hat0, self.n, B))
        rows = [x]
        if self.q:
            rows.append(np.zeros((B, self.q)))
        return {"x": np.ascontiguousarray(np.concatenate(rows, axis=1), dtype=float),
                "P": np.ascontiguousarray(np.tile(self.P0, (B, 1, 1))),
                "nis": np.full(B, np.nan)}

    # ------------------------------------------------------------------ the step
    def _Qh(self, t: _Tuning, key: bytes, h: float) -> Array:
        """``Q h`` for the substep ``h`` (at most ``_CACHE_MAX`` kept)."""
        Qh = self._qh.get((h, key))
        if Qh is None:
            if len(self._qh) >= _CACHE_MAX:
                self._qh.clear()
            Qh = np.ascontiguousarray(t.Qc * h)
            self._qh[(h, key)] = Qh
        return Qh

    def _step(self, p: Params, s: State, Y: Array, U: Array, dt: float, X: Array, Z: Array,
              D: Array) -> None:
        n = self.n
        h = dt / self.substeps
        key = p.key()
        t = self._tuning(p, key)
        Qh = self._Qh(t, key, h)
        T = Y.shape[1]
        j = self._block(t, s, Y, U, h, Qh, X, Z, D)
        if j is None:  # sample by sample, from Python (the same arithmetic)
            hist = np.empty((T, s.x.shape[0], self.N + 1))  # the estimates and NIS, sample-major
            for j in range(T):
                self._condition_on(t, s.x, s.P, np.ascontiguousarray(Y[:, j]), s.nis)
                u = np.ascontiguousarray(U[:, j])
                for _ in range(self.substeps):
                    self._predict(t, s, u, h, Qh)
                if _first_nonfinite(s.x) >= 0:
                    break
                hist[j, :, :-1] = s.x
                hist[j, :, -1] = s.nis
            else:
                j = -1
                X[...] = hist[:, :, :n].transpose(1, 0, 2)
                Z[...] = X
                D[...] = hist[:, :, n:].transpose(1, 0, 2)
        if j >= 0:
            b = _first_nonfinite(s.x)
            raise DivergenceError(f"{type(self).__name__} estimate left the finite numbers: "
                                  f"{s.x[b].tolist()} (member {b}, sample {j})")

    def _block(self, t: _Tuning, s: State, Y: Array, U: Array, h: float, Qh: Array, X: Array,
               Z: Array, D: Array) -> int | None:
        """The whole block in one kernel call where the filter has one (the EKF with a compiled
        model and a selection output): the rows after each sample into ``X``, ``Z``, ``D`` (as
        :meth:`_step`); returns the sample at which an estimate left the finite numbers (the
        state is left there), else -1. ``None``: no such kernel, the samples go one by one
        from Python."""
        return None

    def _condition_on(self, t: _Tuning, x: Array, P: Array, Y: Array, nis: Array) -> None:
        """The measurement update of every member of ``x`` ``(B, N)``, ``P`` ``(B, N, N)``
        (in place) with ``Y`` ``(B, p)`` (NaN: lost channel); each member's normalized
        innovation squared into ``nis`` ``(B,)`` (NaN: every channel lost)."""
        if self.sel is not None:
            _condition_selection(x, P, Y, self._sel, t.R, t.diag_R, nis)
        else:
            self._condition_general(t, x, P, Y, nis)

    def _condition_general(self, t: _Tuning, x: Array, P: Array, Y: Array, nis: Array) -> None:
        """The measurement update for a general output map ``h`` (filter-specific), the NIS
        into ``nis`` as :meth:`_condition_on`."""
        raise NotImplementedError

    def _filtered(self, p: Params, s: State, Y: Array) -> Array:
        """``x_{k|k}``: the measurement update of a copy of the state with ``Y`` (every
        channel; the filter's own read), the state left as it was."""
        x, P = s.x.copy(), s.P.copy()
        self._condition_on(self._tuning(p, p.key()), x, P,
                           np.ascontiguousarray(Y[:, self._cols_index]), np.empty(x.shape[0]))
        return x[:, :self.n].copy()

    def _present(self, y: Array) -> list[int]:
        return [c for c in range(y.shape[0]) if y[c] == y[c]]

    def _predict(self, t: _Tuning, s: State, U: Array, h: float, Qh: Array) -> None:
        """The time update of every member of ``s`` over one substep ``h`` (filter-specific)."""
        raise NotImplementedError

    def covariance(self, state: State) -> Array:
        """The covariance ``P`` of the estimate of the plant's states, ``(B, n, n)`` (the
        block of ``P`` without the estimated parameters' rows and columns)."""
        return state.P[:, :self.n, :self.n].copy()

    def _current(self, p: Params, s: State) -> tuple[Array, Array, Array]:
        x = s.x
        return (x[:, :self.n].copy(), x[:, :self.n].copy(),
                np.concatenate((x[:, self.n:], s.nis[:, None]), axis=1))

    # ------------------------------------------------------------------ interface
    def _check_period(self, p: Params, dt: float) -> None:
        """Refuse a sample period the MuJoCo model cannot step (not a multiple of its
        timestep times ``substeps``); the system-model filters take any period (the filter
        is a discrete recursion: no period makes it unstable)."""
        dt = finite_scalar("dt", dt, positive=True)
        if isinstance(self.model, MujocoModel):
            self.model._steps(dt / self.substeps)

    @property
    def theta_hat_(self) -> Any:
        """Parameter estimates, ``(q,)`` or ``(B, q)`` (also the diagnostics ``theta_<name>``)."""
        return self._public(self.state.x[:, self.n:].copy())

    @property
    def P_(self) -> Any:
        """Covariance of the augmented estimate, ``(N, N)`` or ``(B, N, N)``."""
        return self._public(self.state.P.copy())

    def params(self) -> dict[str, Any]:
        return {"model": self.model.kind, "estimate": list(self.estimate),
                "Q": self.Qc.tolist(), "R": self.R.tolist(), "P0": self.P0.tolist(),
                "outputs": list(self.outputs), "method": self.method, "substeps": self.substeps,
                "jacobian": self.model.jacobian_kind, "on_unstable": self.on_unstable}


@register
class ExtendedKalmanFilter(_KalmanFilter):
    """Continuous-discrete extended Kalman filter with parameter augmentation.

    .. math::

        K_k &= P^- H^T (H P^- H^T + R)^{-1}, \\quad
        \\hat x^+ = \\hat x^- + K_k (y_k - h(\\hat x^-)), \\quad
        P^+ = (I - K_k H) P^- (I - K_k H)^T + K_k R K_k^T, \\\\
        \\hat x^-_{k+1} &= \\mathrm{RK4}_h(\\hat x^+_k), \\quad
        P^-_{k+1} = \\Phi P^+_k \\Phi^T + Q h, \\quad \\Phi = T_4(h F(\\hat x^+_k))

    (per substep ``h``; see the module docstring; Jazwinski 1970, sec. 8.3).

    Parameters
    ----------
    system : System
        The model (physical coordinates), with its known parameter values.
    estimate : sequence of str
        Parameters of the system to estimate by augmentation (``theta_hat0`` then needed).
    Q, Q_theta : float, array_like
        Continuous-time process noise intensity of the state (``n x n``, or scalar / diagonal)
        and of the parameters' random walk (``q x q``); symmetric positive semi-definite.
    R : float, array_like, optional
        Measurement noise covariance of the used channels (positive definite); default the
        ``sensor`` chain's :meth:`~hgo_mj.sensors.SensorChain.noise_variance`, else ``1e-6``.
    sensor : SensorChain, optional
        Only read for the default ``R``.
    P0, P0_theta : float, array_like
        Initial covariance of the state and of the parameters (positive definite).
    x_hat0, theta_hat0 : array_like, optional
        Initial estimates (physical state, default zero; parameters, required with
        ``estimate``), ``(n,)`` / ``(q,)`` for every member, or ``(B, n)`` / ``(B, q)``.
    outputs : tuple of int, optional
        Measured channels used (default all of the system's outputs).
    method : {"rk4", "euler"}
        Mean propagation and the matching :math:`\\Phi`.
    substeps : int
        Time-update steps per sample.
    jacobian : {"auto", "analytic", "fd"}
        How :math:`F` is obtained (see :class:`SystemModel`).
    model, model_fields : None
        Only for the MuJoCo filters (:class:`MujocoExtendedKalmanFilter`); must be None here.
    on_unstable : {"raise", "warn", "ignore"}
        Kept for the contract: the filter is stable at every period.

    Attributes
    ----------
    theta_hat_ : ndarray (q,) or (B, q)
        Parameter estimates (also the diagnostics ``theta_<name>``).
    P_ : ndarray (N, N) or (B, N, N)
        Covariance of the augmented estimate.
    dropouts_ : int or (B,) int array
        Samples with at least one NaN channel (only the present ones correct).

    Notes
    -----
    The diagnostics are ``theta_<name>`` (the parameter estimates), ``nis`` (the normalized
    innovation squared of the last measurement update, :math:`\\nu^T S^{-1} \\nu`; expected
    value the number of present channels for a consistent filter, Bar-Shalom, Li,
    Kirubarajan 2001, sec. 5.4.2; NaN when every channel was lost) and ``dropouts``.

    Examples
    --------
    >>> from hgo_mj.systems import Pendulum
    >>> f = ExtendedKalmanFilter(Pendulum(), R=1e-4, x_hat0=[0.1, 0.0])
    >>> f.update([0.1], [0.0], 0.01).shape
    (2,)
    >>> round(f.diagnostics()["nis"], 6)   # (0.1 - 0.1)^2 / (P + R): nothing surprising
    0.0

    Estimating the pendulum's damping by augmentation:

    >>> f = ExtendedKalmanFilter(Pendulum(), estimate=["damping"], theta_hat0=[0.05], R=1e-4)
    >>> f.diagnostic_names, f.theta_hat_, f.P_.shape
    (('theta_damping', 'nis', 'dropouts'), array([0.05]), (3, 3))

    References
    ----------
    Jazwinski (1970), sec. 8.3; Simon (2006), sec. 13.2 (augmentation).
    """

    name = "ekf"
    summary = "continuous-discrete extended Kalman filter, parameters by state augmentation"
    reference = "Jazwinski 1970 sec. 8.3; Simon 2006 sec. 13.2"

    def _predict(self, t: _Tuning, s: State, U: Array, h: float, Qh: Array) -> None:
        mdl = self.model
        if isinstance(mdl, MujocoModel):
            s.x, Phi = mdl.transition(s.x, U, h)
        elif mdl.compiled is not None:
            vs, ms = _ekf_scratch(self.n, self.N, mdl._c0.shape[0])
            _ekf_predict(mdl.compiled, s.x, U, s.P, mdl._c0, mdl._pidx,
                         _ekf_switches(self.method == "rk4", mdl.analytic), h, Qh, vs, ms)
            return
        else:
            F = mdl.jac(s.x, U)
            s.x = mdl.step(s.x, U, h, self.method)
            _ekf_covariance(s.P, F, h, self.method == "rk4", Qh)
            return
        _propagate(s.P, Phi, Qh)

    def _block(self, t: _Tuning, s: State, Y: Array, U: Array, h: float, Qh: Array, X: Array,
               Z: Array, D: Array) -> int | None:
        mdl = self.model
        if not isinstance(mdl, SystemModel) or mdl.compiled is None or self.sel is None:
            return None
        return _ekf_block(mdl.compiled, s.x, s.P, s.nis, Y, U, self._sel, t.R,  # type: ignore[no-any-return]
                          t.diag_R, mdl._c0, mdl._pidx,
                          _ekf_switches(self.method == "rk4", mdl.analytic), h, self.substeps,
                          Qh, X, Z, D)

    def _condition_general(self, t: _Tuning, x: Array, P: Array, Y: Array, nis: Array) -> None:
        """Linearize ``h`` by central differences at each member's prediction, then update
        (:func:`_joint_update`, which gives the NIS)."""
        out = self.model.output
        for b in range(x.shape[0]):
            idx = self._present(Y[b])
            if not idx:
                nis[b] = np.nan
                continue
            chans = [self.outputs[c] for c in idx]
            xb = x[b]
            H = _central_differences(functools.partial(_rows_output, out, chans), xb[None],
                                     self.N)[0]
            v = np.ascontiguousarray(Y[b, idx] - out(xb)[chans])
            nis[b] = _joint_update(xb, P[b], v, np.ascontiguousarray(H),
                                   np.ascontiguousarray(t.R[np.ix_(idx, idx)]))


@register
class UnscentedKalmanFilter(_KalmanFilter):
    """Continuous-discrete unscented Kalman filter with parameter augmentation.

    Time update: the :math:`2N + 1` scaled sigma points of Wan and van der Merwe,
    :math:`\\chi_0 = \\hat x`, :math:`\\chi_{\\pm i} = \\hat x \\pm \\sqrt{N + \\kappa'}\\,
    L_i` (:math:`L L^T = P`, :math:`\\kappa' = \\alpha^2 (N + \\kappa) - N`), each propagated by
    the model over the substep (RK4 or Euler; MuJoCo steps for the MuJoCo variant),

    .. math::

        \\hat x^- = \\sum_i W^m_i \\chi_i^+, \\qquad
        P^- = \\sum_i W^c_i (\\chi_i^+ - \\hat x^-)(\\chi_i^+ - \\hat x^-)^T + Q\\, h,

    :math:`W^m_0 = \\kappa'/(N+\\kappa')`, :math:`W^c_0 = W^m_0 + 1 - \\alpha^2 + \\beta`,
    :math:`W_i = 1/(2(N+\\kappa'))`. Measurement update: for a selection output the exact
    linear update (the unscented transform of a linear map is exact), else the unscented one
    with :math:`P_{yy}, P_{xy}` from sigma points.

    Parameters
    ----------
    alpha, beta, kappa : float
        Sigma-point spread and weights (defaults 1, 2, 0: the points at
        :math:`\\pm\\sqrt{N} L_i`, zero mean weight on the centre).
    **kw
        As :class:`ExtendedKalmanFilter` (``jacobian`` is not used).
    system, estimate, Q, Q_theta, R, sensor, P0, P0_theta, x_hat0, theta_hat0, outputs, \
method, substeps, jacobian, model, model_fields, on_unstable
        The keywords of :class:`ExtendedKalmanFilter`, the same meaning.

    References
    ----------
    Julier and Uhlmann (1997); Wan and van der Merwe (2000); Simon (2006), sec. 14.3.

    Examples
    --------
    >>> from hgo_mj.systems import Pendulum
    >>> f = UnscentedKalmanFilter(Pendulum(), R=1e-4, x_hat0=[0.1, 0.0])
    >>> f.update([0.1], [0.0], 0.01).round(4)
    array([ 0.0999, -0.0203])
    """

    name = "ukf"
    summary = "continuous-discrete unscented Kalman filter, parameters by state augmentation"
    reference = "Julier, Uhlmann 1997; Wan, van der Merwe 2000"

    def __init__(self, system: System | None = None, *, alpha: float = 1.0, beta: float = 2.0,
                 kappa: float = 0.0, **kw: Any) -> None:
        self.alpha = finite_scalar("alpha", alpha, positive=True)
        self.beta = finite_scalar("beta", beta)
        self.kappa = finite_scalar("kappa", kappa)
        super().__init__(system, **kw)
        _sigma_weights(self.N, self.alpha, self.beta, self.kappa)  # refuse a bad spread now

    def _parameters(self) -> dict[str, Any]:
        """:meth:`_KalmanFilter._parameters` and the sigma points' ``alpha``, ``beta``,
        ``kappa`` (floats)."""
        return {**super()._parameters(), "alpha": self.alpha, "beta": self.beta,
                "kappa": self.kappa}

    def _check_parameter(self, name: str, value: Any) -> Array:
        if name == "alpha":
            alpha = finite_scalar("alpha", value, positive=True)
            _sigma_weights(self.N, alpha, self.beta, self.kappa)
            return np.array(alpha)
        if name == "beta":
            return np.array(finite_scalar("beta", value))
        if name == "kappa":
            kappa = finite_scalar("kappa", value)
            _sigma_weights(self.N, self.alpha, self.beta, kappa)
            return np.array(kappa)
        return super()._check_parameter(name, value)

    def _tune(self, p: Params) -> _Tuning:
        t = super()._tune(p)
        t.c, t.Wm, t.Wc = _sigma_weights(self.N, float(p.alpha), float(p.beta), float(p.kappa))
        return t

    def _sigma(self, t: _Tuning, x: Array, P: Array) -> Array:
        """The sigma points of every member, ``(B, 2N + 1, N)``; where ``P`` is not numerically
        positive definite, from its eigen-decomposition (refused if indefinite)."""
        B, N = x.shape
        S = np.empty((B, 2 * N + 1, N))
        ok = np.empty(B, dtype=np.bool_)
        _sigma_points(x, P, t.c, S, ok)
        for b in np.nonzero(~ok)[0]:
            Pb = P[b]
            w, V = np.linalg.eigh(0.5 * (Pb + Pb.T))
            if w[0] < -1e-9 * max(1.0, w[-1]):
                raise DivergenceError(f"UKF covariance is not positive semi-definite (eigenvalues "
                                      f"{w.tolist()}, member {int(b)})")
            cL = t.c * (V * np.sqrt(np.clip(w, 0.0, None)))
            xb = x[b]
            S[b] = np.vstack((xb, xb + cL.T, xb - cL.T))
        return S

    def _predict(self, t: _Tuning, s: State, U: Array, h: float, Qh: Array) -> None:
        # sigma points redrawn and Q h added per substep
        S = self._sigma(t, s.x, s.P)
        B, M, N = S.shape
        rows = self.model.step(S.reshape(B * M, N), np.repeat(U, M, axis=0), h, self.method,
                               members=np.repeat(np.arange(B), M))
        _moments(np.ascontiguousarray(rows.reshape(B, M, N)), t.Wm, t.Wc, Qh, s.x, s.P)

    def _condition_general(self, t: _Tuning, x: Array, P: Array, Y: Array, nis: Array) -> None:
        """The unscented measurement update, one member at a time; the NIS
        :math:`v^T (P_{yy} + R)^{-1} v` with :math:`v = y - \\hat y` (the innovation
        covariance ``Pyy`` below includes ``R``)."""
        S = self._sigma(t, x, P)
        out = self.model.output
        for b in range(x.shape[0]):
            idx = self._present(Y[b])
            if not idx:
                nis[b] = np.nan
                continue
            chans = [self.outputs[c] for c in idx]
            xb, Pb = x[b], P[b]
            Xs = S[b]
            Ys = np.array([out(s)[chans] for s in Xs])
            yhat = t.Wm @ Ys
            dY = Ys - yhat
            dX = Xs - xb
            Pyy = (dY.T * t.Wc) @ dY + t.R[np.ix_(idx, idx)]
            Pxy = (dX.T * t.Wc) @ dY
            K = np.linalg.solve(Pyy, Pxy.T).T
            v = Y[b, idx] - yhat
            nis[b] = float(v @ np.linalg.solve(Pyy, v))
            x[b] = xb + K @ v
            Pb = Pb - K @ Pyy @ K.T
            P[b] = 0.5 * (Pb + Pb.T)


@register
class MujocoExtendedKalmanFilter(ExtendedKalmanFilter):
    """:class:`ExtendedKalmanFilter` whose model is the MJCF (see :class:`MujocoModel`).

    The mean is predicted by stepping an ``MjData`` of a copy of the ``MjModel``
    (``model=``: the plant's, a modified copy, or default the system's shipped MJCF), the
    transition matrix comes from ``mujoco.mjd_transitionFD`` (``jacobian="transition_fd"``,
    default) or central differences of the step (``"fd"``); ``estimate`` names model fields or
    the system's aliases (its ``"kalman_fields"`` form). The update period must be a multiple
    of the model timestep. MuJoCo is called once per member (a loop over the batch).

    Parameters
    ----------
    system : System
        An MJCF system (``model_file`` set) whose degrees of freedom are hinge/slide joints;
        it names the state (``qpos`` then ``qvel``), the inputs and the outputs (a selection
        of the state).
    model : mujoco.MjModel, MujocoPlant or None
        The model (copied: the filter never touches the plant's); default the system's
        shipped MJCF. A deliberately wrong copy models a parameter error.
    model_fields : mapping, optional
        Values written into the filter's copy of the model (:class:`MujocoModel`), e.g.
        ``{"body_mass[pole]": 0.275, "dof_damping[hinge]": 0.011}``.
    estimate : sequence of str
        Parameters to estimate, each a model field ``"tendon_stiffness[spring]"``,
        ``"actuator_gear[torque]"``, ``"dof_damping[joint]"``, ``"dof_armature[joint]"``,
        ``"body_mass[body]"`` or ``"opt.gravity"`` (the magnitude :math:`g`), or a name the
        system aliases to one in its ``"kalman_fields"`` form (elastic joint: ``stiffness``,
        ``gear``, ``link_damping``, ``motor_damping``, ``g``).
    jacobian : {"auto", "transition_fd", "fd"}
        ``auto`` (default) is ``transition_fd``: ``mujoco.mjd_transitionFD``; ``fd``: central
        differences of the model's own step.
    Q, Q_theta, R, sensor, P0, P0_theta, x_hat0, theta_hat0, outputs, method, substeps, \
on_unstable
        As :class:`ExtendedKalmanFilter`.

    Examples
    --------
    >>> from hgo_mj.systems import Pendulum
    >>> f = MujocoExtendedKalmanFilter(Pendulum(), estimate=["dof_damping[hinge]"],
    ...                                theta_hat0=[0.05], R=1e-4, x_hat0=[0.1, 0.0])
    >>> f.diagnostic_names
    ('theta_dof_damping[hinge]', 'nis', 'dropouts')
    >>> f.update([0.1], [0.0], 0.01).round(4)
    array([ 0.0999, -0.0203])
    """

    name = "ekf_mujoco"
    summary = "EKF whose model is the MuJoCo plant (MjData stepping, mjd_transitionFD)"
    reference = "Jazwinski 1970 sec. 8.3; MuJoCo mjd_transitionFD"
    backend = "mujoco"


@register
class MujocoUnscentedKalmanFilter(UnscentedKalmanFilter):
    """:class:`UnscentedKalmanFilter` whose sigma points are stepped by MuJoCo (see
    :class:`MujocoModel`; one call per sigma point and member).

    Parameters
    ----------
    system, model, model_fields, estimate, jacobian
        As :class:`MujocoExtendedKalmanFilter` (``jacobian`` is not used).
    alpha, beta, kappa
        As :class:`UnscentedKalmanFilter`.
    Q, Q_theta, R, sensor, P0, P0_theta, x_hat0, theta_hat0, outputs, method, substeps, \
on_unstable
        As :class:`ExtendedKalmanFilter`.

    Examples
    --------
    >>> from hgo_mj.systems import Pendulum
    >>> f = MujocoUnscentedKalmanFilter(Pendulum(), R=1e-4, x_hat0=[0.1, 0.0])
    >>> f.update([0.1], [0.0], 0.01).round(4)
    array([ 0.0999, -0.0203])
    """

    name = "ukf_mujoco"
    summary = "UKF whose sigma points are stepped by the MuJoCo plant"
    reference = "Julier, Uhlmann 1997; Wan, van der Merwe 2000"
    backend = "mujoco"


def _full_signature(cls: type) -> None:
    """Show the shared keyword arguments in ``cls.__init__``'s signature (``hgo-mj list``)."""
    import inspect

    own = inspect.signature(cls.__init__)  # type: ignore[misc]
    base = inspect.signature(_KalmanFilter.__init__)
    params = [p for p in own.parameters.values() if p.kind is not p.VAR_KEYWORD]
    params += [p for n, p in base.parameters.items() if n not in own.parameters]
    cls.__init__.__signature__ = own.replace(parameters=params)  # type: ignore[attr-defined,misc]


_full_signature(UnscentedKalmanFilter)
