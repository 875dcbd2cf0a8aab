"""The small-matrix kernels of hgo_mj/observers/kalman.py, each against numpy (random shapes
of the filters' sizes), and the joint update they compose against its formula."""

from __future__ import annotations

import numpy as np
import pytest

from hgo_mj.observers import kalman as K

RNG = np.random.default_rng(2024)
SHAPES = [(1, 1, 1), (2, 3, 1), (5, 2, 4), (8, 8, 3)]


@pytest.mark.parametrize("r,k,c", SHAPES)
def test_mat_mul_and_mat_mul_bt(r, k, c):
    A, B, Bt = RNG.standard_normal((r, k)), RNG.standard_normal((k, c)), RNG.standard_normal((c, k))
    out = np.empty((r, c))
    K._mat_mul(A, B, out)
    np.testing.assert_allclose(out, A @ B, rtol=1e-13, atol=1e-14)
    K._mat_mul_bt(A, Bt, out)
    np.testing.assert_allclose(out, A @ Bt.T, rtol=1e-13, atol=1e-14)
    acc = RNG.standard_normal((r, c))
    want = acc + A @ Bt.T
    K._mat_mul_bt_add(A, Bt, acc)
    np.testing.assert_allclose(acc, want, rtol=1e-13, atol=1e-14)


@pytest.mark.parametrize("r,k,c", SHAPES)
def test_mat_vec_add_and_symmetrize(r, k, c):
    A, v, x = RNG.standard_normal((r, k)), RNG.standard_normal(k), RNG.standard_normal(r)
    want = x + A @ v
    K._mat_vec_add(A, v, x)
    np.testing.assert_allclose(x, want, rtol=1e-13, atol=1e-14)
    M = RNG.standard_normal((r, r))
    out = np.empty((r, r))
    K._symmetrize(M, out)
    np.testing.assert_array_equal(out, 0.5 * (M + M.T))


def _spd(n: int) -> np.ndarray:
    M = RNG.standard_normal((n, n))
    return M @ M.T + 0.1 * np.eye(n)


@pytest.mark.parametrize("n", [1, 2, 5, 8])
def test_sandwich_t4_and_solves(n):
    Phi, P, Q = RNG.standard_normal((n, n)), _spd(n), _spd(n)
    want = Phi @ P @ Phi.T + Q
    K._sandwich(Phi, P, Q, np.empty((n, n)))
    np.testing.assert_allclose(P, want, rtol=1e-12, atol=1e-13)
    np.testing.assert_array_equal(P, P.T)
    A = 0.1 * RNG.standard_normal((n, n))
    T, W = np.empty((n, n)), np.empty((n, n))
    K._t4(A, True, T, W)
    taylor = sum(np.linalg.matrix_power(A, j) / [1, 1, 2, 6, 24][j] for j in range(5))
    np.testing.assert_allclose(T, taylor, rtol=1e-13, atol=1e-14)
    K._t4(A, False, T, W)
    np.testing.assert_array_equal(T, np.eye(n) + A)
    S, rhs = _spd(n), RNG.standard_normal((n, 3))
    np.testing.assert_allclose(K._spd_solve(S, rhs), np.linalg.solve(S, rhs), rtol=1e-9)
    PHt, v = RNG.standard_normal((4, n)), RNG.standard_normal(n)
    gain, nis = K._gain_and_nis(S, PHt, v)
    np.testing.assert_allclose(gain, PHt @ np.linalg.inv(S), rtol=1e-9, atol=1e-12)
    assert nis == pytest.approx(v @ np.linalg.solve(S, v), rel=1e-10)
    # the gain's columns are solved one by one: alone or with v, the same bits
    np.testing.assert_array_equal(gain, K._spd_solve(S, PHt.T.copy()).T)


@pytest.mark.parametrize("N,m", [(2, 1), (3, 2), (8, 3)])
def test_joint_update_is_the_joseph_form(N, m):
    x, P, R = RNG.standard_normal(N), _spd(N), _spd(m)
    H, v = RNG.standard_normal((m, N)), RNG.standard_normal(m)
    S = H @ P @ H.T + R
    G = P @ H.T @ np.linalg.inv(S)
    IKH = np.eye(N) - G @ H
    Pw = IKH @ P @ IKH.T + G @ R @ G.T
    xw = x + G @ v
    nis = K._joint_update(x, P, v, H, R)
    np.testing.assert_allclose(x, xw, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(P, 0.5 * (Pw + Pw.T), rtol=1e-8, atol=1e-12)
    np.testing.assert_array_equal(P, P.T)
    assert nis == pytest.approx(v @ np.linalg.solve(S, v), rel=1e-10)
