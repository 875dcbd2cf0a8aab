"""The shared integrators (hgo_mj.observers._integrate): order of accuracy on z' = -z and on a
harmonic oscillator (the error ratio when the step halves ~ 2, 4, 16), exactness on a constant
derivative, batch shapes, and the numba forms equal to the numpy forms bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from hgo_mj.observers import _integrate as I

NUMPY = {"euler": (I.euler, 1), "heun": (I.heun, 2), "rk4": (I.rk4, 4)}


def decay(z: np.ndarray) -> np.ndarray:
    return -z


def oscillator(z: np.ndarray) -> np.ndarray:
    """``q' = p, p' = -w^2 q`` (w = 2) on rows ``(q, p)``."""
    return np.stack([z[:, 1], -4.0 * z[:, 0]], axis=1)


def error(step, f, z0, exact, t_end: float, n: int) -> float:
    z, dt = z0.copy(), t_end / n
    for _ in range(n):
        z = step(f, z, dt)
    return float(np.max(np.abs(z - exact)))


def osc_exact(z0: np.ndarray, t: float) -> np.ndarray:
    q0, p0 = z0[:, 0], z0[:, 1]
    return np.stack([q0 * np.cos(2 * t) + p0 / 2 * np.sin(2 * t),
                     -2 * q0 * np.sin(2 * t) + p0 * np.cos(2 * t)], axis=1)


@pytest.mark.parametrize("method", NUMPY)
@pytest.mark.parametrize("problem", ["decay", "oscillator"])
def test_order_of_accuracy(method: str, problem: str) -> None:
    step, order = NUMPY[method]
    t_end = 1.0
    if problem == "decay":
        f, z0 = decay, np.array([[1.0, -2.0], [0.5, 3.0]])
        exact = z0 * np.exp(-t_end)
    else:
        f, z0 = oscillator, np.array([[1.0, 0.0], [0.3, -1.2]])
        exact = osc_exact(z0, t_end)
    e1, e2 = (error(step, f, z0, exact, t_end, n) for n in (40, 80))
    assert e2 / e1 == pytest.approx(2.0 ** -order, rel=0.1)


@pytest.mark.parametrize("method", NUMPY)
def test_exact_on_a_constant_derivative(method: str) -> None:
    step, _ = NUMPY[method]
    c = np.array([[1.0, -0.5, 0.25]])
    z0 = np.array([[2.0, 3.0, -1.0]])
    z = z0
    for _ in range(8):
        z = step(lambda v: np.broadcast_to(c, v.shape).copy(), z, 0.125)
    np.testing.assert_allclose(z, z0 + c, rtol=0, atol=1e-15)


@pytest.mark.parametrize("method", NUMPY)
def test_batch_shapes_and_rows_independent(method: str) -> None:
    step, _ = NUMPY[method]
    rng = np.random.default_rng(0)
    Z = rng.standard_normal((7, 2))
    Zc = Z.copy()
    out = step(oscillator, Z, 0.01)
    assert out.shape == (7, 2) and out is not Z
    np.testing.assert_array_equal(Z, Zc)  # the input is not modified
    for b in range(7):  # each row as a batch of one, bit for bit
        np.testing.assert_array_equal(step(oscillator, Z[b:b + 1], 0.01), out[b:b + 1])


@njit(cache=True)
def _osc_rhs(v, args, out):  # pragma: no cover - jit
    out[0] = v[1]
    out[1] = -args[0] * v[0]


@njit(cache=True)
def _run(method, S, h, steps):  # pragma: no cover - jit
    """``steps`` steps of each row of ``S`` in place by the numba forms (0 euler, 1 heun,
    2 rk4), ``out`` the state itself."""
    n = S.shape[1]
    w = np.empty((5, n))
    for b in range(S.shape[0]):
        s = S[b]
        for _ in range(steps):
            if method == 0:
                I.euler_step(_osc_rhs, s, h, (4.0,), w[0], s)
            elif method == 1:
                I.heun_step(_osc_rhs, s, h, (4.0,), w[0], w[1], w[2], s)
            else:
                I.rk4_step(_osc_rhs, s, h, (4.0,), w[0], w[1], w[2], w[3], w[4], s)


@pytest.mark.parametrize("code,method", [(0, "euler"), (1, "heun"), (2, "rk4")])
def test_numba_forms_equal_numpy_bit_for_bit(code: int, method: str) -> None:
    step, _ = NUMPY[method]
    rng = np.random.default_rng(1)
    Z = rng.standard_normal((5, 2))
    S = Z.copy()
    _run(code, S, 0.01, 50)
    for _ in range(50):
        Z = step(oscillator, Z, 0.01)
    np.testing.assert_array_equal(S, Z)


def test_numba_out_into_the_stage_buffer() -> None:
    """``out`` may be ``tmp`` (the adaptive observer's kernel keeps ``s`` until it accepts the
    step); ``s`` is then untouched."""
    s = np.array([1.0, 0.0])
    w = np.empty((5, 2))
    I.rk4_step(_osc_rhs, s, 0.1, (4.0,), w[0], w[1], w[2], w[3], w[4], w[4])
    np.testing.assert_array_equal(s, [1.0, 0.0])
    np.testing.assert_array_equal(w[4], I.rk4(oscillator, s[None], 0.1)[0])


def test_stage_helpers() -> None:
    s, k = np.array([1.0, 2.0]), np.array([4.0, -4.0])
    out = np.empty(2)
    I.axpy(s, 0.25, k, out)
    np.testing.assert_array_equal(out, [2.0, 1.0])
    I.heun_sum(s, 0.5, k, k, out)
    np.testing.assert_array_equal(out, s + 0.5 * (k + k))
    I.rk4_sum(s, 1.0 / 6.0, k, k, k, k, s)  # in place
    np.testing.assert_array_equal(s, [5.0, -2.0])
