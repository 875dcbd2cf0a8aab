"""The model-free kinematic Kalman filter: exact on the polynomials it models, its steady-state
gain against the alpha-beta closed form and the discrete Riccati equation, the covariance of a
noise-only run against its own, dropouts, the current estimate, and bad parameters refused."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from hgo_mj.exceptions import DesignError
from hgo_mj.observers import KinematicKalmanFilter, make_observer
from hgo_mj.observers.kinematic_kalman import chain_model
from hgo_mj.systems import Pendulum


def _run(ob, y, dt):
    return ob.run(np.asarray(y, dtype=float)[:, None], np.zeros((len(y), 0)), dt)


@pytest.mark.parametrize("order,coeffs", [(2, [0.2, 3.0]), (3, [0.2, 3.0, -4.0]),
                                          (4, [0.1, -1.0, 2.0, 5.0])])
def test_a_polynomial_of_degree_below_n_is_tracked_exactly(order, coeffs):
    """Noise-free samples of a polynomial of degree n - 1 (a constant acceleration for n = 3):
    after the transient every derivative's error is zero (to rounding)."""
    dt, T = 0.02, 600
    t = np.arange(T) * dt
    poly = np.polynomial.Polynomial(coeffs)
    z = _run(KinematicKalmanFilter(order=order, q=10.0, r=1e-6), poly(t), dt).z_hat[0]
    for i in range(order):  # the row after sample k predicts t_{k+1}
        truth = poly.deriv(i)(t + dt)
        err = np.abs(z[-100:, i] - truth[-100:])
        assert err.max() < 1e-7 * max(1.0, np.abs(truth).max()), (i, err.max())


def test_order_2_lags_a_constant_acceleration_by_its_bias():
    """What n = 2 does not model: a constant acceleration leaves a constant velocity error
    (not zero); n = 3 removes it."""
    dt, T = 0.02, 400
    t = np.arange(T) * dt
    y = 2.0 * t ** 2
    v = 4.0 * (t + dt)
    e2 = _run(KinematicKalmanFilter(order=2, q=1.0, r=1e-6), y, dt).z_hat[0, -50:, 1] - v[-50:]
    e3 = _run(KinematicKalmanFilter(order=3, q=1.0, r=1e-6), y, dt).z_hat[0, -50:, 1] - v[-50:]
    assert np.ptp(e2) < 1e-9 and abs(e2[0]) > 1e-3
    assert np.abs(e3).max() < 1e-7


def _gain(ob, dt, T=3000):
    """The steady-state gain K = P^- H^T / (H P^- H^T + r) of a run on noise."""
    y = np.random.default_rng(0).normal(0.0, 1.0, T)
    ob.reset()
    for k in range(T):
        ob.update([y[k]], np.zeros(0), dt)
    P = ob.state.P[0]
    return P[:, 0] / (P[0, 0] + ob.r)


@pytest.mark.parametrize("lam", [0.05, 1.0, 30.0])
def test_order_2_steady_state_is_the_alpha_beta_filter(lam):
    """The gain tends to (alpha, beta / h) of Kalata's closed form in the tracking index
    lambda = sqrt(q / r) h^2 (Bar-Shalom et al. 2001, sec. 6.5)."""
    dt, r = 0.01, 1e-6
    q = r * (lam / dt ** 2) ** 2
    root = np.sqrt(lam ** 2 + 8 * lam)
    alpha = -(lam ** 2 + 8 * lam - (lam + 4) * root) / 8
    beta = (lam ** 2 + 4 * lam - lam * root) / 4
    K = _gain(KinematicKalmanFilter(order=2, q=q, r=r), dt)
    np.testing.assert_allclose(K, [alpha, beta / dt], rtol=1e-8)


@pytest.mark.parametrize("order", [2, 3])
def test_steady_state_solves_the_discrete_riccati_equation(order):
    dt, q, r = 0.05, 40.0, 1e-4
    Phi, Gamma = chain_model(order, dt)
    H = np.zeros((1, order))
    H[0, 0] = 1.0
    P = solve_discrete_are(Phi.T, H.T, q * np.outer(Gamma, Gamma), np.array([[r]]))
    want = P[:, 0] / (P[0, 0] + r)
    K = _gain(KinematicKalmanFilter(order=order, q=q, r=r), dt)
    np.testing.assert_allclose(K, want, rtol=1e-7)


def test_its_covariance_is_the_error_covariance_on_its_own_model():
    """Samples drawn from the model itself (white piecewise-constant accelerations, sensor
    noise of variance r): the velocity error's variance is the filter's P_22 and the mean NIS
    is 1 (consistency)."""
    dt, q, r, T, B = 0.01, 50.0, 1e-6, 2000, 64
    rng = np.random.default_rng(3)
    Phi, Gamma = chain_model(2, dt)
    z = np.zeros((B, 2))
    Y = np.empty((B, T, 1))
    V = np.empty((B, T))
    for k in range(T):
        Y[:, k, 0] = z[:, 0] + rng.normal(0.0, np.sqrt(r), B)
        z = z @ Phi.T + np.outer(rng.normal(0.0, np.sqrt(q), B), Gamma)
        V[:, k] = z[:, 1]
    ob = KinematicKalmanFilter(order=2, q=q, r=r)
    rows = ob.run(Y, np.zeros((B, T, 0)), dt)
    err = rows.z_hat[:, 200:, 1] - V[:, 200:]
    assert np.var(err) == pytest.approx(ob.covariance(ob.state)[0, 1, 1], rel=0.05)
    assert np.nanmean(rows.diagnostics[:, 200:, 0]) == pytest.approx(1.0, rel=0.05)


def test_the_current_estimate_is_the_measurement_update():
    """filtered(y) is z_k|k: on a ramp, exact at the sample's own instant; the state is left
    as it was."""
    dt = 0.01
    ob = KinematicKalmanFilter(order=2, q=1.0, r=1e-6)
    ob.reset(z_hat0=[0.0, 0.0])
    for k in range(100):
        ob.update([0.5 * k * dt], np.zeros(0), dt)
    before = ob.x_hat.copy()
    np.testing.assert_allclose(ob.filtered([0.5 * 100 * dt]), [0.5, 0.5], rtol=1e-9)
    np.testing.assert_array_equal(ob.x_hat, before)


def test_a_dropout_predicts_without_an_update():
    dt = 0.01
    t = np.arange(60) * dt
    y = 1.0 + 2.0 * t
    y[40] = np.nan
    ob = KinematicKalmanFilter(order=2, q=1.0, r=1e-6)
    rows = _run(ob, y, dt)
    assert np.isnan(rows.diagnostics[0, 40, 0]) and ob.dropouts_ == 1
    np.testing.assert_allclose(rows.z_hat[0, 41:, 1], 2.0, rtol=1e-7)


def test_with_a_system_the_estimate_is_in_its_coordinates():
    ob = make_observer("kinematic_kalman", Pendulum(), q=10.0, r=1e-6)
    assert ob.state_names == ("angle", "angular_velocity") and ob.n == 2


@pytest.mark.parametrize("kw,match", [
    ({"q": 0.0}, r"q must be"), ({"r": -1.0}, r"r must be"), ({"q": np.inf}, r"q must be"),
    ({"outputs": (0, 1)}, r"reads one output"), ({"P0": [[1.0, 2.0], [2.0, 1.0]]}, r"P0"),
])
def test_bad_parameters_are_refused(kw, match):
    with pytest.raises(DesignError, match=match):
        KinematicKalmanFilter(**{"order": 2, **kw})


def test_the_tuning_space_is_q_alone():
    sp = KinematicKalmanFilter(order=2, q=4.0, r=1e-6).tuning_space()
    assert list(sp) == ["q"] and sp["q"].log and (sp["q"].low, sp["q"].high) == (4e-5, 4e5)


def test_the_current_estimate_is_mapped_to_physical_coordinates():
    """With a system whose normal form is not its state (the elastic joint: the link angle's
    derivatives), filtered(y) is from_normal of the updated z with the newest input."""
    from hgo_mj.systems import ElasticJoint

    system = ElasticJoint()
    ob = make_observer("kinematic_kalman", system, q=1e4, r=1e-6)
    assert ob.covariance(ob.init(1)) is None  # P is of z, not of the physical state
    for k in range(20):
        ob.update([0.01 * k], [0.1], 0.01)
    P = ob.state.P[0]
    z = ob.z_hat + P[:, 0] / (P[0, 0] + 1e-6) * (0.2 - ob.z_hat[0])
    np.testing.assert_allclose(ob.filtered([0.2]), system.from_normal(z, np.array([0.1])),
                               rtol=1e-12)
