"""Riccati design, Riccati and q-integral observers of paper 004 (Ibrir 2007)."""

from __future__ import annotations

from math import comb

import numpy as np
import pytest
from scipy.linalg import solve_discrete_lyapunov

from hgo_mj.design import (
    check_riccati_alpha,
    lipschitz_condition,
    max_sampling_period,
    min_gamma,
    riccati_gains,
    riccati_P,
    riccati_Q,
    riccati_weights,
    riccati_weights_as_printed,
    sampling_lmi_62,
    sampling_lmi_63,
)
from hgo_mj.exceptions import DesignError, DimensionError
from hgo_mj.inputs import Constant
from hgo_mj.observers import QIntegralObserver, RiccatiObserver, make_observer
from hgo_mj.observers.high_gain import one_step_map
from hgo_mj.observers.q_integral import q_integral_step_map
from hgo_mj.plants.ode import OdePlant
from hgo_mj.sensors import GaussianNoise, SensorChain
from hgo_mj.simulate import simulate
from hgo_mj.systems import CartPendulum

RHO = 1.5
M_PEND = np.diag([0.0, np.sqrt(RHO)])
N_PEND = np.diag([np.sqrt(RHO), 0.0])


def _alphas(n):
    """Binomial, random real roots, and a well-damped complex pair (all meet condition (10))."""
    rng = np.random.default_rng(100 + n)
    out = [np.array([comb(n, k) for k in range(1, n + 1)], dtype=float),
           np.poly(-rng.uniform(0.3, 4.0, n))[1:]]
    roots = np.concatenate(([-1.0 + 0.5j, -1.0 - 0.5j], -rng.uniform(0.5, 3.0, n - 2)))
    out.append(np.real(np.poly(roots))[1:])
    return out


# ------------------------------------------------------------------------- Riccati design
@pytest.mark.parametrize("n", [2, 3, 4, 5, 6])
@pytest.mark.parametrize("gamma", [0.5, 6.0, 40.0])
def test_riccati_gain_equals_alpha_gamma_powers(n, gamma):
    """Lemma 4: P(gamma) C' = (alpha_i gamma^i), P solving the ARE of eq. 6 with Q of eq. 17.

    Tolerance: rtol 1e-9 (observed <= 1e-13) for the scaled solve, and for the direct solve of
    the ARE at gamma (entries spanning gamma .. gamma^(2n-1)), rtol 1e-8."""
    for alpha in _alphas(n):
        check_riccati_alpha(alpha)
        closed = alpha * gamma ** np.arange(1, n + 1)
        np.testing.assert_allclose(riccati_gains(alpha, gamma), closed, rtol=1e-9)
        np.testing.assert_allclose(riccati_gains(alpha, gamma, scaled=False), closed, rtol=1e-8)
        P, Q = riccati_P(alpha, gamma), riccati_Q(alpha, gamma)
        A = np.diag(np.ones(n - 1), 1)
        C = np.eye(n)[:1]
        res = A @ P + P @ A.T - P @ C.T @ C @ P + Q
        assert np.abs(res).max() <= 1e-9 * np.abs(Q).max()
        assert np.linalg.eigvalsh(P).min() > 0
        # eq. 20: P_ij = P~_ij gamma^(i+j-1)
        i, j = np.indices((n, n))
        np.testing.assert_allclose(P, riccati_P(alpha, 1.0) * gamma ** (i + j + 1.0), rtol=1e-9)


def test_pendulum_example_eq68():
    g = 6.0
    np.testing.assert_allclose(riccati_Q([3, 2], g), np.diag([5 * g**2, 4 * g**4]), rtol=1e-14)
    np.testing.assert_allclose(riccati_P([3, 2], g), [[3 * g, 2 * g**2], [2 * g**2, 6 * g**3]],
                               rtol=1e-12)
    # eq. 68 prints (P^-1)_21 = +1/(7 gamma^2): it is -1/(7 gamma^2) (P^-1 is symmetric)
    Pi = np.linalg.inv(riccati_P([3, 2], g))
    np.testing.assert_allclose(Pi, [[3 / (7 * g), -1 / (7 * g**2)], [-1 / (7 * g**2), 3 / (14 * g**3)]],
                               rtol=1e-12)


def test_eq8_as_printed_differs_from_eq17_from_n_4():
    for n in (2, 3):
        for a in _alphas(n):
            np.testing.assert_allclose(riccati_weights_as_printed(a), riccati_weights(a), rtol=1e-12)
    np.testing.assert_allclose(riccati_weights([4, 6, 4, 1]), [4, 6, 4, 1], rtol=1e-14)
    np.testing.assert_allclose(riccati_weights_as_printed([4, 6, 4, 1]), [4, 16, 4, 1], rtol=1e-14)
    # (-1)^(n-i) q_i are the coefficients of p(s) p(-s)
    a = _alphas(5)[1]
    p = np.concatenate(([1.0], a))
    pm = p * (-1.0) ** np.arange(len(p))[::-1]
    prod = np.polymul(p, pm)[::2]  # even powers s^(2n), ..., s^0
    np.testing.assert_allclose(prod[1:] * (-1.0) ** (5 - np.arange(1, 6)), riccati_weights(a),
                               rtol=1e-10)


@pytest.mark.parametrize("alpha,rho", [([3, 2], 1.5), ([3, 2], 10.0), ([4, 6, 4, 1], 1.5),
                                       ([2.5, 2.0, 0.7], 0.3)])
def test_min_gamma_meets_condition5_and_slightly_less_does_not(alpha, rho):
    g = min_gamma(alpha, rho)
    assert lipschitz_condition(alpha, g, rho)["satisfied"]
    assert not lipschitz_condition(alpha, g * (1 - 1e-6), rho)["satisfied"]


def test_lipschitz_condition_numerator_is_linear_in_gamma():
    a = [4.0, 6.0, 4.0, 1.0]
    l1 = lipschitz_condition(a, 1.0)["lambda_min"]
    assert lipschitz_condition(a, 7.5)["lambda_min"] == pytest.approx(7.5 * l1, rel=1e-9)


# ------------------------------------------------------------------------------ LMIs
def test_lmi63_bound_is_the_edge_of_feasibility():
    r = max_sampling_period([3, 2], 6.0, M_PEND, N_PEND)
    d = r["delta_max"]
    assert 0.0915 <= d < 0.093  # paper: 0.0915
    assert sampling_lmi_63([3, 2], 6.0, M_PEND, N_PEND, 0.999 * d)["feasible"]
    assert sampling_lmi_63([3, 2], 6.0, M_PEND, N_PEND, 0.5 * d)["feasible"]
    assert not sampling_lmi_63([3, 2], 6.0, M_PEND, N_PEND, 1.01 * d)["feasible"]


def test_lmi62_bound_and_paper_points():
    r = max_sampling_period([3, 2], 6.0, M_PEND, N_PEND, lmi="62")
    assert r["delta_max"] == pytest.approx(0.5286, abs=2e-3)  # paper: 0.525
    assert sampling_lmi_62(M_PEND, N_PEND, 0.525, X=[[1.1685, -0.3414], [-0.3414, 0.3119]],
                           epsilon=0.3415)["feasible"]
    assert not sampling_lmi_62(M_PEND, N_PEND, 1.02 * r["delta_max"])["feasible"]


def test_infeasible_lmi_names_the_solver_status():
    with pytest.raises(DesignError, match=r"LMI \(63\)/\(65\).*infeasible.*solver status 'infeasible'"):
        max_sampling_period([3, 2], 6.0, 30 * M_PEND, 30 * N_PEND)
    with pytest.raises(DesignError, match="lmi must be '63' or '62'; found '64'"):
        max_sampling_period([3, 2], 6.0, M_PEND, N_PEND, lmi="64")


def test_lmi_dimension_mismatch():
    with pytest.raises(DimensionError, match=r"M must have shape \(2, m\) for n = 2; found shape \(3, 3\)"):
        max_sampling_period([3, 2], 6.0, np.eye(3), N_PEND)
    with pytest.raises(DimensionError, match=r"N must have shape \(m, 2\) for n = 2; found shape \(2, 3\)"):
        max_sampling_period([3, 2], 6.0, M_PEND, np.ones((2, 3)))


# ------------------------------------------------------------------------- observers
def _euler_run(delta, steps, on_unstable="raise"):
    """Riccati observer (eq. 53, method euler) against the Euler-discretized pendulum (eq. 50)."""
    system = CartPendulum()
    ob = RiccatiObserver(system, alpha=[3, 2], gamma=6.0, method="euler", on_unstable=on_unstable)
    x = np.array([0.5, -0.5])
    with np.errstate(all="ignore"):
        for k in range(steps):
            u = np.array([0.5 * np.sin(k * delta)])
            xh = ob.update(x[:1], u, delta)
            x = x + delta * np.array([x[1], np.sin(x[0]) + u[0] * np.cos(x[0])])
    return np.abs(x - xh).max()


def test_euler_observer_converges_below_and_diverges_above_the_period_limit():
    assert _euler_run(0.15, 3000) < 1e-9
    assert _euler_run(0.09, 3000) < 1e-9  # below the LMI (63) bound 0.0919 (roundoff floor)
    err = _euler_run(0.18, 400, on_unstable="ignore")
    assert not err < 1e3  # diverged (or overflowed to inf/nan)
    with pytest.raises(DesignError, match=r"unstable.*largest stable period is 0\.16666"):
        _euler_run(0.18, 1)


def test_q_integral_observer_equals_the_augmented_riccati_observer():
    """The bounded internal state w reproduces eq. 40 written with the absolute integrals of y:
    brute-force RK4 of (eta, tilde y) against method rk4 (same held measurement)."""
    n, q, g, dt = 2, 2, 6.0, 0.01
    alpha = np.array([4.0, 6.0, 4.0, 1.0])
    L = alpha * g ** np.arange(1, 5)
    t = np.arange(300) * dt
    ys = np.sin(1.3 * t) + 0.3 * np.cos(5 * t)
    s = np.zeros(6)  # eta (4), then tilde y_1, tilde y_2
    ref = []
    h = dt / 20
    for y in ys:
        def f(s, y=y):
            return np.r_[np.r_[s[1:4], 0.0] + L * (s[4] - s[0]), s[5], y]
        for _ in range(20):
            k1 = f(s)
            k2 = f(s + h / 2 * k1)
            k3 = f(s + h / 2 * k2)
            k4 = f(s + h * k3)
            s = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        ref.append(s[2:4].copy())
    ob = QIntegralObserver(None, order=n, q=q, gamma=g, model=False, method="rk4")
    est = np.array([ob.update([y], [0.0], dt) for y in ys])
    np.testing.assert_allclose(est, np.array(ref), atol=1e-5)
    np.testing.assert_allclose(ob.L, L, rtol=1e-10)  # Z(gamma) C' from the ARE


@pytest.mark.parametrize("q", [1, 2, 3])
def test_q_integral_exact_map_has_the_matched_poles(q):
    n, g, dt = 2, 6.0, 0.05
    alpha = np.array([comb(n + q, k) for k in range(1, n + q + 1)], dtype=float)
    M, _, _ = q_integral_step_map(alpha, g, q, dt, "exact")
    np.testing.assert_allclose(np.poly(M), np.poly(np.full(n + q, np.exp(-g * dt))), atol=1e-10)


def test_q_integral_attenuates_noise():
    """Stated setup: the pendulum's analytic plant at rest (x = 0, u = 0), white Gaussian
    noise std 0.05 on y sampled every 0.01, gamma = 6, 40 s, seed 3; the standard observer
    with alpha = (3, 2) against the q-integral with alpha = C(n+q, k).

    The RMSE of x2_hat (after 5 s) must drop by a factor > 3.5 from the standard observer to
    q = 2 (the linear error dynamics predict 4.6), with q = 1 in between, and each RMSE must
    be within 15 % of the discrete Lyapunov prediction of its linear error map."""
    system = CartPendulum()
    dt, std = 0.01, 0.05
    plant = OdePlant(system, dt=dt, physics_dt=dt / 10)
    obs = {"std": RiccatiObserver(system, alpha=[3, 2], gamma=6.0),
           "q1": QIntegralObserver(system, q=1, gamma=6.0),
           "q2": QIntegralObserver(system, q=2, gamma=6.0)}
    traj = simulate(plant, SensorChain([GaussianNoise(std)]), obs, Constant(0.0), 40.0,
                    x0=[0.0, 0.0], seed=3)
    sel = traj.t >= 5.0
    rmse = {k: float(np.sqrt(np.mean(traj.error(k)[sel, 1] ** 2))) for k in obs}
    assert rmse["std"] / rmse["q2"] > 3.5
    assert rmse["std"] > rmse["q1"] > rmse["q2"]

    def predicted(M, b, i):
        return float(np.sqrt(solve_discrete_lyapunov(M, std**2 * np.outer(b, b))[i, i]))

    M, b, _ = one_step_map(np.array([3.0, 2.0]), 6.0, dt, "exact")
    assert rmse["std"] == pytest.approx(predicted(M, b, 1), rel=0.15)
    for q in (1, 2):
        Mq, bq, _ = q_integral_step_map(np.array([comb(2 + q, k) for k in range(1, q + 3)], float),
                                        6.0, q, dt, "exact")
        assert rmse[f"q{q}"] == pytest.approx(predicted(Mq, bq, q + 1), rel=0.15)


@pytest.mark.parametrize("kind", ["riccati", "q_integral"])
@pytest.mark.parametrize("method", ["exact", "euler", "rk4"])
def test_nan_measurement_is_held_and_counted(kind, method):
    system = CartPendulum()
    ob = make_observer(kind, system, gamma=6.0, method=method, x_hat0=[0.2, 0.1])
    ob.update([0.3], [0.1], 0.01)
    z0 = ob.z_hat.copy()
    x = ob.update([float("nan")], [0.1], 0.01)
    assert ob.dropouts_ == 1 and ob.diagnostics()["dropouts"] == 1.0
    assert np.all(np.isfinite(x))
    # the prediction without correction: the plant model over one sample, to O(dt^2)
    phi = np.sin(z0[0]) + 0.1 * np.cos(z0[0])
    np.testing.assert_allclose(x, z0 + 0.01 * np.array([z0[1], phi]), atol=2e-4)
    ob.update([0.3], [0.1], 0.01)
    assert ob.dropouts_ == 1


def test_registry_and_cli_style_parameters():
    from hgo_mj.cli import parse_spec

    system = CartPendulum()
    spec = parse_spec("riccati:alpha=[3,2],gamma=6,method=euler", "type")
    ob = make_observer(spec.pop("type"), system, **spec)
    assert isinstance(ob, RiccatiObserver)
    np.testing.assert_allclose(ob.L, [18.0, 72.0], rtol=1e-12)
    spec = parse_spec("q_integral:q=2,gamma=min,rho=1.5", "type")
    ob = make_observer(spec.pop("type"), system, **spec)
    assert ob.gamma_ == pytest.approx(39.63, abs=0.01) and ob.params()["gamma_spec"] == "min"
    with pytest.raises(DesignError, match=r"observer 'riccati': unknown parameter\(s\) \['k'\]; valid:"):
        make_observer("riccati", system, k=6.0, gamma=6.0)


def test_bad_input():
    system = CartPendulum()
    with pytest.raises(DesignError, match=r"roots \[.*\] have non-negative real part"):
        RiccatiObserver(system, alpha=[-1.0, 2.0], gamma=6.0)
    with pytest.raises(DesignError, match=r"violates condition \(10\).*found q_1 = -1"):
        RiccatiObserver(system, alpha=[1.0, 1.0], gamma=6.0)
    with pytest.raises(DesignError, match=r"violates condition \(10\)"):
        riccati_gains([1.0, 1.0], 6.0)
    with pytest.raises(DesignError, match="gamma must be > 0; found -2"):
        RiccatiObserver(system, gamma=-2.0)
    with pytest.raises(DesignError, match="gamma must be > 0; found 0"):
        riccati_gains([3, 2], 0.0)
    with pytest.raises(DesignError, match="gamma='min' needs the Lipschitz constant rho"):
        RiccatiObserver(system, gamma="min")
    with pytest.raises(DesignError, match="gamma must be a number > 0 or 'min'; found 'max'"):
        QIntegralObserver(system, gamma="max")
    with pytest.raises(DesignError, match="rho must be > 0; found -1"):
        min_gamma([3, 2], -1.0)
    for q in (0, -1, 1.5):
        with pytest.raises(DesignError, match=rf"q \(the number of output integrators\) must be a "
                                              rf"positive integer; found {q}"):
            QIntegralObserver(system, gamma=6.0, q=q)
    with pytest.raises(DimensionError, match="alpha must have n = 2 coefficients; found 3"):
        RiccatiObserver(system, alpha=[3, 3, 1], gamma=6.0)
    with pytest.raises(DimensionError, match=r"alpha must have n \+ q = 2 \+ 2 = 4 coefficients; found 3"):
        QIntegralObserver(system, q=2, alpha=[3, 3, 1], gamma=6.0)
    with pytest.raises(DimensionError, match="order 3 does not match CartPendulum's normal form order 2"):
        RiccatiObserver(system, order=3, gamma=6.0, alpha=[3, 3, 1])
    with pytest.raises(DesignError, match="model=True needs a system providing phi"):
        QIntegralObserver(None, order=2, gamma=6.0)
    with pytest.warns(RuntimeWarning, match=r"does not meet the Lipschitz condition \(5\) for rho = 3"):
        RiccatiObserver(system, alpha=[3, 2], gamma=6.0, rho=3.0)
    with pytest.warns(RuntimeWarning, match=r"does not meet condition \(44\) for rho = 1.5"):
        QIntegralObserver(system, q=2, gamma=6.0, rho=1.5)
    # Euler, poles 4 x -6: stable for delta < 2/6
    with pytest.raises(DesignError, match=r"unstable.*largest stable period is 0\.3333"):
        QIntegralObserver(system, q=2, gamma=6.0, method="euler").check_period(0.4)
