"""The normalized innovation squared (diagnostic ``nis``) of the Kalman filters
(hgo_mj/observers/kalman.py): chi-square consistency on a linear plant simulated exactly as
the filter models it, its reaction to a wrong ``R``, filterpy's ``y' S^-1 y`` sample by sample,
the sequential (diagonal ``R``) sum against the joint formula, dropouts, and the general-output
paths (EKF by finite differences, UKF by sigma points)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2

from hgo_mj.observers.kalman import (
    ExtendedKalmanFilter,
    MujocoExtendedKalmanFilter,
    UnscentedKalmanFilter,
    _condition_selection,
)
from hgo_mj.systems import Pendulum
from hgo_mj.systems.base import System

# a damped oscillator x' = A x + B u, both states measured (p = 2) or the position only
A = np.array([[0.0, 1.0], [-4.0, -0.4]])
BU = np.array([[0.0], [1.0]])
DT = 0.05
QC = np.diag([1e-3, 4e-2])  # continuous-time intensity: Q h per step


def _linear(C: np.ndarray) -> System:
    """A System ``x' = A x + B u``, ``y = C x`` (no parameters)."""
    p = C.shape[0]

    class Linear(System):
        state_names = ("x0", "x1")
        input_names = ("u0",)
        output_names = tuple(f"y{i}" for i in range(p))
        default_x0 = (0.0, 0.0)

        @staticmethod
        def dynamics(t, x, u, p_):
            return A @ np.asarray(x, dtype=float) + BU @ np.asarray(u, dtype=float)

        @staticmethod
        def output(x, p_):
            return C @ np.asarray(x, dtype=float)

    return Linear()


def _taylor4(M: np.ndarray) -> np.ndarray:
    out, term = np.eye(len(M)), np.eye(len(M))
    for k in range(1, 5):
        term = term @ M / k
        out = out + term
    return out


def _simulate(C: np.ndarray, R_true: np.ndarray, T: int, P0: float, seed: int):
    """The plant as the filter models it (RK4 of a linear ODE is ``T_4(hA)``, process noise of
    covariance ``Q h``, u = 0) and its noisy outputs ``(T, p)``; x0 ~ N(0, P0 I)."""
    rng = np.random.default_rng(seed)
    Phi = _taylor4(DT * A)
    Lq = np.linalg.cholesky(QC * DT)
    Lr = np.linalg.cholesky(R_true)
    x = math.sqrt(P0) * rng.standard_normal(2)
    Y = np.empty((T, C.shape[0]))
    for k in range(T):
        Y[k] = C @ x + Lr @ rng.standard_normal(C.shape[0])
        x = Phi @ x + Lq @ rng.standard_normal(2)
    return Y


def _nis(f, Y: np.ndarray) -> np.ndarray:
    blk = f.run(Y, np.zeros((len(Y), 1)), DT)
    return blk.diagnostics[0, :, f.diagnostic_names.index("nis")]


@pytest.mark.parametrize("p", [1, 2])
def test_consistent_filter_has_chi_square_nis(p):
    """Q and R exactly those of the simulated plant: over T = 5000 samples the mean NIS lies in
    the 95 % band of a mean of T chi2(p), and about 95 % of the samples lie in the single
    sample's 95 % band (Bar-Shalom, Li, Kirubarajan 2001, sec. 5.4.2)."""
    T = 5000
    C = np.eye(2)[:p]
    R_true = np.diag([4e-3, 1e-2][:p])
    Y = _simulate(C, R_true, T, P0=0.5, seed=11 + p)
    f = ExtendedKalmanFilter(_linear(C), Q=QC, R=R_true, P0=0.5, x_hat0=[0.0, 0.0])
    nis = _nis(f, Y)
    assert np.all(np.isfinite(nis)) and np.all(nis >= 0.0)
    lo, hi = chi2.ppf(0.025, T * p) / T, chi2.ppf(0.975, T * p) / T
    assert lo <= nis.mean() <= hi, (nis.mean(), lo, hi)
    inside = np.mean((nis >= chi2.ppf(0.025, p)) & (nis <= chi2.ppf(0.975, p)))
    assert 0.93 <= inside <= 0.97, inside
    # the UKF's innovation covariance of a linear model is the EKF's (to rounding)
    u = UnscentedKalmanFilter(_linear(C), Q=QC, R=R_true, P0=0.5, x_hat0=[0.0, 0.0])
    np.testing.assert_allclose(_nis(u, Y[:500]), nis[:500], rtol=1e-8)


def test_consistent_filter_has_chi_square_nees():
    """The NEES of the same consistent filter (Q, R, P0 and x0's spread those of the
    simulated plant), from its covariance (:meth:`Observer.covariance`) and the true state of
    B = 2000 independent runs at one instant: the mean over the runs lies in the 95 % band of a
    mean of B chi2(2), and about 95 % of the runs in one sample's band (Bar-Shalom et al.
    2001, sec. 5.4.2: the NEES over Monte Carlo runs; over one run's samples the NEES is
    correlated in time, unlike the NIS). A filter told Q 100x too small is overconfident."""
    from hgo_mj.metrics import chi2_band, nees

    B, T, C, r = 2000, 300, np.eye(2)[:1], 1e-2
    rng = np.random.default_rng(3)
    Phi, Lq = _taylor4(DT * A), np.linalg.cholesky(QC * DT)
    x = math.sqrt(0.5) * rng.standard_normal((B, 2))
    Y = np.empty((B, T, 1))
    for k in range(T):
        Y[:, k] = x @ C.T + math.sqrt(r) * rng.standard_normal((B, 1))
        x = x @ Phi.T + rng.standard_normal((B, 2)) @ Lq.T
    means = {}
    for scale in (1.0, 0.01):
        f = ExtendedKalmanFilter(_linear(C), Q=QC * scale, R=[[r]], P0=0.5, x_hat0=[0.0, 0.0])
        p = f.parameters(B)
        st, blk = f.step(p, f.init(B, params=p), Y, np.zeros((B, T, 1)), DT)
        eps = nees(x - blk.x_hat[:, -1], f.covariance(st))  # x_T and its prediction
        means[scale] = eps.mean()
        if scale == 1.0:
            lo, hi = chi2.ppf(0.025, 2 * B) / B, chi2.ppf(0.975, 2 * B) / B
            assert lo <= eps.mean() <= hi, (eps.mean(), lo, hi)
            blo, bhi = chi2_band(2)
            assert 0.93 <= np.mean((eps >= blo) & (eps <= bhi)) <= 0.97
    assert means[0.01] > 4.0, means


def test_wrong_R_moves_the_mean_nis():
    """A filter told R 4x too small is overconfident (mean NIS well above p = 1), 4x too large
    underconfident (well below)."""
    C, R_true = np.eye(2)[:1], np.array([[1e-2]])
    Y = _simulate(C, R_true, 3000, P0=0.5, seed=5)
    means = {}
    for scale in (0.25, 1.0, 4.0):
        f = ExtendedKalmanFilter(_linear(C), Q=QC, R=R_true * scale, P0=0.5, x_hat0=[0.0, 0.0])
        means[scale] = _nis(f, Y)[100:].mean()
    assert means[0.25] > 2.0 and means[4.0] < 0.5, means
    assert means[4.0] < means[1.0] < means[0.25]
    assert 0.9 < means[1.0] < 1.1


def _filterpy_nis(kf) -> float:
    return float(kf.y @ np.linalg.solve(kf.S, kf.y))


def test_nis_equals_filterpy_ekf():
    """The compiled EKF (one kernel call per block) on the pendulum, Euler, against filterpy's
    ExtendedKalmanFilter: ``y' S^-1 y`` from its ``y`` and ``S`` after each update."""
    fp = pytest.importorskip("filterpy.kalman")
    s, dt = Pendulum(), 1e-3
    prm = s.params
    ours = ExtendedKalmanFilter(s, Q=1e-4, R=1e-6, P0=0.1, x_hat0=[0.2, 0.0], method="euler")
    assert ours.model.compiled is not None

    class EKF(fp.ExtendedKalmanFilter):
        def predict_x(self, u=0):
            self.x = self.x + dt * s.dynamics(0, self.x, u, prm)

    ref = EKF(2, 1)
    ref.x, ref.P = np.array([0.2, 0.0]), np.eye(2) * 0.1
    ref.R, ref.Q = np.array([[1e-6]]), np.eye(2) * 1e-4 * dt
    H = np.array([[1.0, 0.0]])
    T = 300
    Us = np.array([[0.2 * math.sin(k * dt * 4)] for k in range(T)])
    Ys = np.array([[0.2 + 0.05 * math.sin(k * dt * 7)] for k in range(T)])
    want = np.empty(T)
    for k in range(T):
        ref.update(Ys[k], lambda x: H, lambda x: x[:1])
        want[k] = _filterpy_nis(ref)
        ref.F = np.eye(2) + dt * s.jacobian(0, ref.x, Us[k], prm)
        ref.predict(Us[k])
    got = ours.run(Ys, Us, dt).diagnostics[0, :, 0]
    assert ours.diagnostic_names == ("nis", "dropouts")
    np.testing.assert_allclose(got, want, rtol=1e-10)
    assert want.max() > 0.1 and np.all(want[1:] > 0.0)  # not a comparison of zeros


@pytest.mark.parametrize("R", [np.diag([2e-3, 5e-3]), np.array([[2e-3, 1e-3], [1e-3, 5e-3]])])
def test_nis_equals_filterpy_kalman_filter(R):
    """Two outputs, diagonal R (sequential scalar updates) and full R (the joint update):
    the EKF of a linear system with the Euler method is the discrete Kalman filter of
    ``I + hA``; its NIS equals filterpy's KalmanFilter's ``y' S^-1 y`` at every sample."""
    fp = pytest.importorskip("filterpy.kalman")
    C = np.eye(2)
    Y = _simulate(C, R, 200, P0=0.5, seed=3)
    ours = ExtendedKalmanFilter(_linear(C), Q=QC, R=R, P0=0.5, x_hat0=[0.0, 0.0], method="euler")
    kf = fp.KalmanFilter(2, 2)
    kf.x, kf.P, kf.R, kf.H = np.zeros(2), 0.5 * np.eye(2), R, C
    kf.F, kf.Q = np.eye(2) + DT * A, QC * DT
    want = np.empty(len(Y))
    for k, y in enumerate(Y):
        kf.update(y)
        want[k] = _filterpy_nis(kf)
        kf.predict()
    np.testing.assert_allclose(_nis(ours, Y), want, rtol=1e-10)


def _joint_nis(x, P, y, sel, R):
    """``v' S^-1 v`` over the present channels, written out (NaN if none)."""
    keep = [c for c in range(len(y)) if y[c] == y[c]]
    if not keep:
        return np.nan
    H = np.eye(len(x))[[sel[c] for c in keep]]
    v = y[keep] - H @ x
    S = H @ P @ H.T + R[np.ix_(keep, keep)]
    return float(v @ np.linalg.solve(S, v))


def test_sequential_nis_equals_the_joint_formula():
    """With a diagonal R the sequential scalar updates' sum of squared normalized innovations
    equals the joint ``v' (H P H' + R)^-1 v`` (two outputs of a 3-state member, correlated
    prior); the joint kernel gives the same NIS, the same x and P (to rounding); a lost
    channel leaves the other's NIS, every channel lost gives NaN."""
    rng = np.random.default_rng(1)
    B, N = 6, 3
    M = rng.standard_normal((B, N, N))
    P = np.ascontiguousarray(M @ M.transpose(0, 2, 1) + 0.1 * np.eye(N))
    X = rng.standard_normal((B, N))
    Y = rng.standard_normal((B, 2))
    Y[3, 1] = np.nan
    Y[4, 0] = np.nan
    Y[5] = np.nan
    sel = np.array([0, 2], dtype=np.int64)
    R = np.diag([0.3, 0.05])
    want = np.array([_joint_nis(X[b], P[b], Y[b], sel, R) for b in range(B)])
    out = {}
    for diagonal in (True, False):
        x, Pm, nis = X.copy(), P.copy(), np.empty(B)
        _condition_selection(x, Pm, Y, sel, R, diagonal, nis)
        np.testing.assert_allclose(nis, want, rtol=1e-10)
        out[diagonal] = (x, Pm)
    assert np.isnan(want[5]) and np.all(np.isfinite(want[:5]))
    np.testing.assert_allclose(out[True][0], out[False][0], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(out[True][1], out[False][1], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(out[True][0][5], X[5])  # nothing to update


def test_nis_in_rows_current_filtered_and_dropouts():
    """The rows carry the NIS of each sample's update, NaN for a sample with every channel lost;
    ``diagnostics()`` reports the last one (NaN before any update); ``filtered`` leaves it."""
    C = np.eye(2)
    f = ExtendedKalmanFilter(_linear(C), Q=QC, R=np.diag([1e-2, 1e-2]), P0=0.5,
                             x_hat0=[0.0, 0.0])
    assert f.diagnostic_names == ("nis", "dropouts") and math.isnan(f.diagnostics()["nis"])
    Y = _simulate(C, np.diag([1e-2, 1e-2]), 8, P0=0.5, seed=2)
    Y[3] = np.nan
    Y[5, 0] = np.nan
    nis = _nis(f, Y)
    assert np.isnan(nis[3]) and np.all(np.isfinite(np.delete(nis, 3)))
    assert f.diagnostics()["nis"] == nis[-1]
    before = f.diagnostics()["nis"]
    f.filtered(Y[0])
    assert f.diagnostics()["nis"] == before
    # the NIS of the update is that of the prediction before it
    g = ExtendedKalmanFilter(_linear(C), Q=QC, R=np.diag([1e-2, 1e-2]), P0=0.5,
                             x_hat0=[0.0, 0.0])
    for k in range(len(Y)):
        x, P = g.x_hat.copy(), g.P_.copy()
        g.update(Y[k], [0.0], DT)
        want = _joint_nis(x, P, Y[k], [0, 1], np.diag([1e-2, 1e-2]))
        np.testing.assert_allclose(g.diagnostics()["nis"], want, rtol=1e-10)


@pytest.mark.parametrize("cls", [ExtendedKalmanFilter, UnscentedKalmanFilter])
def test_nis_of_a_general_output(cls):
    """``y = x0 + 0.5 x1`` is no selection: the EKF linearizes it by finite differences, the UKF
    by sigma points (exact for a linear map); both NIS equal the joint formula with H = C."""
    C = np.array([[1.0, 0.5]])
    R = np.array([[1e-2]])
    Y = _simulate(C, R, 40, P0=0.5, seed=9)
    f = cls(_linear(C), Q=QC, R=R, P0=0.5, x_hat0=[0.0, 0.0])
    assert f.sel is None
    for k in range(len(Y)):
        x, P = f.x_hat.copy(), f.P_.copy()
        f.update(Y[k], [0.0], DT)
        v = Y[k] - C @ x
        want = float(v @ np.linalg.solve(C @ P @ C.T + R, v))
        np.testing.assert_allclose(f.diagnostics()["nis"], want, rtol=1e-6)
    f.update([np.nan], [0.0], DT)
    assert math.isnan(f.diagnostics()["nis"])


def test_mujoco_and_augmented_filters_report_nis_after_the_parameters():
    """The MuJoCo EKF and an augmented EKF list ``nis`` after their ``theta_*`` columns and
    write a finite value into the rows."""
    s = Pendulum()
    for f in (MujocoExtendedKalmanFilter(s, estimate=["dof_damping[hinge]"], theta_hat0=[0.05],
                                         R=1e-4, x_hat0=[0.1, 0.0]),
              ExtendedKalmanFilter(s, estimate=["damping"], theta_hat0=[0.05], R=1e-4,
                                   x_hat0=[0.1, 0.0])):
        assert f.diagnostic_names[-2:] == ("nis", "dropouts")
        assert f.diagnostic_names[0].startswith("theta_")
        blk = f.run(np.full((5, 1), 0.12), np.zeros((5, 1)), 0.01)
        col = blk.diagnostics[0, :, 1]
        assert np.all(np.isfinite(col)) and col[0] == pytest.approx(0.02 ** 2 / (1.0 + 1e-4))
