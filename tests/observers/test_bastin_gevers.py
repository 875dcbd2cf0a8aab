"""The Bastin-Gevers adaptive observer (paper 002, eq. 3.1) and its canonical forms."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hgo_mj._validate import symmetric_matrix
from hgo_mj.exceptions import DesignError, DimensionError, DivergenceError
from hgo_mj.inputs import Multisine
from hgo_mj.observers import AOCF, BastinGeversObserver, make_observer
from hgo_mj.observers.bastin_gevers import (
    SlidingGram,
    rk_stable_period,
    sym_eigvals,
)
from hgo_mj.plants import make_plant
from hgo_mj.plants.ode import OdePlant
from hgo_mj.simulate import simulate
from hgo_mj.systems import CartPendulum, ElasticJoint, Pendulum
from hgo_mj.systems.papers import BioreactorBastinGevers, bastin_gevers_input


def _bio_observer(**kw):
    sys_ = BioreactorBastinGevers()
    guess = BioreactorBastinGevers(mu_max=2.0, p2=1.0, p3=0.1)
    x, th = guess.to_aocf([1.0, 2.0], kw.get("c2", 1.0))
    kw = {"c1": 5.0, "gamma": 2.0, "c2": 1.0, "theta_hat0": th, "z_hat0": x, **kw}
    return sys_, BastinGeversObserver(sys_, **kw)


# ------------------------------------------------------------------ the canonical form
def test_bioreactor_aocf_is_the_papers_6_5():
    sys_ = BioreactorBastinGevers()
    rng = np.random.default_rng(0)
    for c2 in (0.5, 1.0, 2.0, 3.7):
        form = AOCF.bioreactor(sys_, c2)
        np.testing.assert_array_equal(form.k, [1.0])
        np.testing.assert_array_equal(form.F, [[-c2]])
        for _ in range(20):
            y, u = rng.uniform(0.1, 3), rng.uniform(0, 5, 2)
            R, Om, g = sys_.aocf_structure(y, u, c2)
            w = form.omega(y, u)
            np.testing.assert_allclose(form.Omega(w), Om, atol=1e-14)
            np.testing.assert_allclose(form.g(y, u), g, atol=1e-13)
            z = rng.uniform([0.1, 0.2], [3.0, 5.0])
            x, th = sys_.to_aocf(z, c2)
            zz, params = form.to_physical(x, th, u)
            z_ref, p_ref = sys_.from_aocf(x, th, c2)
            np.testing.assert_allclose(zz, z_ref, rtol=1e-12)
            np.testing.assert_allclose([params["p1"], params["p2"], params["p3"]], p_ref, rtol=1e-12)
            np.testing.assert_allclose(form.from_physical(z, th, u), x, rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("cls, unknown, damping_known", [
    (Pendulum, None, "ratio"), (Pendulum, None, "coefficient"),
    (Pendulum, ("d_over_J", "g_over_l", "b_over_J"), "ratio"),
    (CartPendulum, None, "ratio"), (CartPendulum, ("d_over_J", "g_over_l", "b_over_J"), "ratio")])
def test_second_order_aocf_is_the_pendulum(cls, unknown, damping_known):
    """d/dt x(z) along the MuJoCo systems' analytic ODE equals R x + Omega theta + g at the
    true theta (the derivation of docs/adaptive_canonical_forms.md): damping ratio d/J known,
    damping coefficient d known with J unknown, or damping estimated."""
    sys_ = cls.from_mjmodel(make_plant(cls.name).model)
    if cls is CartPendulum:  # the shipped model has no damping: give it some
        sys_ = cls(**{**sys_.params, "damping": 0.3})
    rng = np.random.default_rng(1)
    for c2 in (1.0, 5.0):
        form = AOCF.pendulum(sys_, c2=c2, unknown=unknown, damping_known=damping_known)
        theta = AOCF.pendulum_theta(sys_, unknown)
        for _ in range(20):
            z, u = rng.uniform(-2, 2, 2), rng.uniform(-1, 1, 1)
            x = form.from_physical(z, theta, u)
            # x = (y, y' + (delta - c2) y): dx/dt = (y', y'' + (delta - c2) y')
            zd = sys_.f(0.0, z, u)
            delta = sys_.params["damping"] / sys_.params["inertia"]
            xd = np.array([zd[0], zd[1] + (delta - c2) * zd[0]])
            w = form.omega(z[0], u)
            np.testing.assert_allclose(form.R @ x + form.Omega(w) @ theta + form.g(z[0], u), xd,
                                       rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(form.to_physical(x, theta, u)[0], z, atol=1e-13)
        assert form.reachability()["reachable"]


def test_S_blocks_are_the_markov_parameters_of_the_filter():
    """Eq. 4.11: s_1 = Omega_1, s_j = k^T F^(j-2) Omega_bar (the printed F_j^-2 is F^(j-2))."""
    rng = np.random.default_rng(2)
    n, m, s = 4, 3, 5
    R = np.zeros((n, n))
    R[0, 1:] = rng.normal(size=n - 1)
    R[1:, 1:] = -np.diag([1.0, 2.0, 3.0]) + 0.3 * np.triu(rng.normal(size=(3, 3)), 1)
    alpha = rng.normal(size=(n, m, s))
    form = AOCF(R, alpha, lambda y, u: np.ones(5))
    w = rng.normal(size=s)
    Om = form.Omega(w)
    k, F = R[0, 1:], R[1:, 1:]
    S = np.vstack([Om[0]] + [k @ np.linalg.matrix_power(F, j - 2) @ Om[1:] for j in range(2, n + 1)])
    np.testing.assert_allclose(form.S(w), S, rtol=1e-12, atol=1e-12)
    # phi of the filter driven by a constant omega: its Taylor coefficients at t = 0 are S's rows
    ob = BastinGeversObserver(aocf=form, excitation_window=None)
    V = np.zeros((n - 1, m))
    h = 1e-3
    phis = []
    for _ in range(4):
        phis.append(V.T @ k + Om[0])
        V = V + h * (F @ V + Om[1:])
    d1 = (phis[1] - phis[0]) / h
    np.testing.assert_allclose(d1, S[1], rtol=1e-12)
    assert ob.structure["rank"] == 3


def test_reachability_finds_the_unexcitable_direction():
    sys_ = BioreactorBastinGevers()
    full = AOCF.bioreactor(sys_, 1.0)
    assert full.reachability() == {"rank": 3, "m": 3, "reachable": True, "unreachable": []}
    no_u2 = AOCF(full.R, full.alpha[:, :, :2], lambda y, u: np.array([y, u[0]]),
                 theta_names=("1", "2", "3"), label="6.5 without u2")
    r = no_u2.reachability()
    assert r["rank"] == 2 and not r["reachable"]
    np.testing.assert_allclose(np.abs(r["unreachable"][0]), [0, 0, 1], atol=1e-12)
    with pytest.raises(DesignError, match=r"not output reachable \(Theorem 4.2\).*column rank 2 "
                                          r"over R, expected m = 3.*1\*3"):
        BastinGeversObserver(aocf=no_u2)
    with pytest.warns(RuntimeWarning, match="not output reachable"):
        BastinGeversObserver(aocf=no_u2, on_unreachable="warn")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        BastinGeversObserver(aocf=no_u2, on_unreachable="ignore")


# ------------------------------------------------------------------ the observer equations
def _rhs_numpy(ob, s, y, w, g, correct=True):
    """Eq. 3.1 (3.1a and 3.1e corrected) transcribed in numpy matrices: the reference of the
    kernel rhs_3_1."""
    f = ob.form
    n, m = f.n, f.m
    x, th, V = s[:n], s[n:n + m], s[n + m:].reshape(n - 1, m)
    Om = f.Omega(w)
    phi = V.T @ f.k + Om[0]
    e = (y - x[0]) if correct else 0.0
    thd = ob.gamma @ phi * e
    xd = f.R @ x + Om @ th + g
    xd[0] += ob.c1 * e
    xd[1:] += V @ thd
    Vd = f.F @ V + Om[1:]
    return np.concatenate((xd, thd, Vd.reshape(-1)))


def test_kernel_rhs_equals_the_matrix_form_of_3_1():
    rng = np.random.default_rng(3)
    for c2 in (1.0, 2.0):
        _, ob = _bio_observer(c2=c2, gamma=[[2.0, 0.3, 0.0], [0.3, 1.0, 0.1], [0.0, 0.1, 4.0]])
        for correct in (True, False):
            s = rng.normal(size=8)
            y, u = rng.uniform(0.1, 2), rng.uniform(0, 5, 2)
            w, g = ob.omega_g(y, u)
            np.testing.assert_allclose(ob.rhs(s, y, w, g, correct), _rhs_numpy(ob, s, y, w, g, correct),
                                       rtol=1e-13, atol=1e-13)
    # a general form (n = 4, full F) too
    R = np.zeros((4, 4))
    R[0, 1:] = [1.0, -0.5, 2.0]
    R[1:, 1:] = [[-1.0, 0.2, 0.0], [0.0, -2.0, 0.7], [0.1, 0.0, -3.0]]
    alpha = rng.normal(size=(4, 2, 3))
    alpha[2, 1] = 0.0
    form = AOCF(R, alpha, lambda y, u: np.array([y, u[0], math.sin(y)]))
    ob = BastinGeversObserver(aocf=form, c1=3.0, gamma=[1.0, 2.0], excitation_window=None)
    s = rng.normal(size=4 + 2 + 6)
    w, g = ob.omega_g(0.3, np.array([1.5]))
    np.testing.assert_allclose(ob.rhs(s, 0.3, w, g), _rhs_numpy(ob, s, 0.3, w, g),
                               rtol=1e-13, atol=1e-13)
    # the regressor phi = V^T k + Omega_1^T (eq. 3.1e) after a sample is the one recorded
    ob.reset(z_hat0=s[:4], theta_hat0=s[4:6])
    ob.update(np.array([0.3]), np.array([1.5]), 0.01)
    np.testing.assert_array_equal(ob.phi_, (alpha @ w)[0])  # V(0) = 0: phi = Omega_1^T


def test_symmetric_eigenvalues_by_jacobi():
    rng = np.random.default_rng(7)
    for m in (1, 2, 3, 5):
        for _ in range(20):
            A = rng.normal(size=(m, m))
            A = A @ A.T if m > 1 else A * A
            ev = np.empty(m)
            sym_eigvals(A, np.empty((m, m)), ev)
            np.testing.assert_allclose(np.sort(ev), np.linalg.eigvalsh(A), rtol=1e-12,
                                       atol=1e-14 * np.abs(A).max())
    # a rank-deficient Gram: the null eigenvalue within a few ulps of the largest
    v = rng.normal(size=(10, 2)) @ rng.normal(size=(2, 3))
    ev = np.empty(3)
    sym_eigvals(v.T @ v, np.empty((3, 3)), ev)
    assert np.sort(ev)[0] < 1e-13 * ev.max()


def test_error_system_4_2():
    """With x~* = x~ - (0, V theta~) (eq. 4.1 corrected) the errors obey eq. 4.2:
    x~*' = R* x~* + (phi^T theta~, -V theta'), theta~' = -Gamma phi x~1 + theta' -- the evidence
    for the corrections of 3.1a (V theta_hat') and 3.1e (phi, not phi')."""
    rng = np.random.default_rng(4)
    sys_, ob = _bio_observer(c1=3.0, gamma=[1.0, 2.0, 3.0])
    f = ob.form
    for _ in range(10):
        x = rng.normal(size=2)
        theta, theta_dot = rng.normal(size=3), rng.normal(size=3)
        s = rng.normal(size=8)
        u = rng.uniform(0, 5, 2)
        y = x[0]
        w, g = ob.omega_g(y, u)
        Om = f.Omega(w)
        xd = f.R @ x + Om @ theta + g
        sd = ob.rhs(s, y, w, g)
        xh, th_h, V = s[:2], s[2:5], s[5:].reshape(1, 3)
        Vd = sd[5:].reshape(1, 3)
        xt, tht = x - xh, theta - th_h
        xs = xt - np.concatenate(([0.0], V @ tht))
        tht_d = theta_dot - sd[2:5]
        xs_d = (xd - sd[:2]) - np.concatenate(([0.0], Vd @ tht + V @ tht_d))
        phi = V.T @ f.k + Om[0]
        Rstar = f.R.copy()
        Rstar[0, 0] = -ob.c1
        expect = Rstar @ xs + np.concatenate(([phi @ tht], -V @ theta_dot))
        np.testing.assert_allclose(xs_d, expect, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(tht_d, -ob.gamma @ phi * xt[0] + theta_dot, rtol=1e-12, atol=1e-12)


def test_frozen_theta_converges_in_continuous_time():
    """AOCF 6.5 with constant theta, a zero-mean exciting input: theta_hat -> theta (the full
    check to 1e-6 is the reproduction's part (a))."""
    sys_ = BioreactorBastinGevers()
    form = AOCF.bioreactor(sys_, 1.0)
    x0, theta = sys_.to_aocf(sys_.default_x0, 1.0)
    ob = BastinGeversObserver(aocf=form, c1=5.0, gamma=20.0, theta_hat0=theta + [1.0, -1.0, -0.05],
                              z_hat0=1.2 * x0)

    def u(t):
        return np.array([2 * math.sin(0.5 * t) + 2 * math.sin(1.7 * t) + 1.5 * math.sin(3.1 * t),
                         math.sin(1.1 * t) + 0.7 * math.sin(2.3 * t)])

    def rhs(t, s):
        w, g = ob.omega_g(s[0], u(t))
        return np.concatenate((form.R @ s[:2] + form.Omega(w) @ theta + g, ob.rhs(s[2:], s[0], w, g)))

    sol = solve_ivp(rhs, (0, 60), np.concatenate((x0, ob.state_vector_)), method="DOP853",
                    rtol=1e-10, atol=1e-12)
    assert np.max(np.abs(sol.y[4:7, -1] - theta)) < 2e-3
    assert np.max(np.abs(sol.y[4:7, -1] - theta)) < 1e-3 * np.max(np.abs(sol.y[4:7, 0] - theta))


def test_dropout_holds_the_prediction_and_counts():
    sys_, ob = _bio_observer()
    u = np.array([5.0, 0.5])
    ob.update(np.array([0.8]), u, 0.01)
    th0, s0 = ob.theta_hat_, ob.state_vector_
    x_pred = ob.update(np.array([np.nan]), u, 0.01)
    assert ob.dropouts_ == 1 and ob.diagnostics()["dropouts"] == 1.0
    np.testing.assert_array_equal(ob.theta_hat_, th0)  # no adaptation without a measurement
    assert np.all(np.isfinite(x_pred))
    # the prediction is the open-loop model with omega at the predicted output
    w, g = ob.omega_g(s0[0], u)
    sol = solve_ivp(lambda t, s: ob.rhs(s, s0[0], w, g, correct=False), (0, 0.01), s0,
                    rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(ob.state_vector_, sol.y[:, -1], rtol=1e-8, atol=1e-10)
    with pytest.raises(DivergenceError, match=r"measurement y\[0\] is inf"):
        ob.update(np.array([np.inf]), u, 0.01)


def test_sensor_dropouts_in_a_run_are_counted():
    from hgo_mj.sensors import Dropout, SensorChain

    sys_, ob = _bio_observer()
    tr = simulate(OdePlant(sys_, 0.05), SensorChain([Dropout(0.2)], seed=3), {"bg": ob},
                  bastin_gevers_input, 10.0, seed=3)
    n_nan = int(np.sum(np.isnan(tr.y_meas[:-1, 0])))
    assert n_nan > 10 and ob.dropouts_ == n_nan
    assert np.all(np.isfinite(tr.observers["bg"].x_hat))


def test_run_diagnostics_and_determinism():
    sys_, ob = _bio_observer()
    tr = simulate(OdePlant(sys_, 0.05), None, {"bg": ob}, bastin_gevers_input, 20.0)
    d = tr.observers["bg"].diagnostics
    assert set(d) == {"theta_1", "theta_2", "theta_3", "theta_p1", "theta_p2", "theta_p3",
                      "theta_p0", "excitation", "reachability_rank", "dropouts"}
    assert d["reachability_rank"][0] == 0 and d["reachability_rank"][-1] == 3
    assert d["excitation"][-1] > 0
    tr2 = simulate(OdePlant(sys_, 0.05), None, {"bg": ob}, bastin_gevers_input, 20.0)
    np.testing.assert_array_equal(tr.observers["bg"].x_hat, tr2.observers["bg"].x_hat)
    # the windowed Gram is the sum of phi phi^T dt over the last window
    assert ob.excitation_matrix_.shape == (3, 3)
    assert ob.params()["structural_rank"] == 3


def test_sliding_gram_window():
    g = SlidingGram(2, window=1.0)
    for k in range(30):
        g.add(np.array([1.0, k]), 0.1)
    vs = np.array([[1.0, k] for k in range(20, 30)])
    np.testing.assert_allclose(g.matrix, vs.T @ vs * 0.1)
    assert g.min_eig == pytest.approx(np.linalg.eigvalsh(vs.T @ vs * 0.1)[0])


def test_pendulum_mujoco_recovers_the_ratios():
    """Bastin-Gevers on the MuJoCo pendulum, damping known: g/l and b/J to 1 % in 30 s."""
    plant = make_plant("pendulum", dt=0.002)
    ob = make_observer("bastin_gevers", plant.system, c1=50.0, c2=5.0, gamma=1e5,
                       x_hat0=[0.0, 0.0])
    u = Multisine([0.3, 0.2, 0.25], [0.2, 0.45, 1.3], [0.0, 1.0, 2.0])
    tr = simulate(plant, None, {"bg": ob}, u, 30.0, x0=[0.3, 0.0])
    truth = AOCF.pendulum_theta(plant.system)
    np.testing.assert_allclose(ob.theta_hat_, truth, rtol=0.01)
    assert tr.observers["bg"].diagnostics["reachability_rank"][-1] == 2
    e = tr.x[-2500:] - tr.observers["bg"].x_hat[-2500:]
    # the O(dt) lag of a measurement held over 2 ms: |y_dot| dt / 2 ~ 1e-3
    assert np.max(np.abs(e[:, 0])) < 5e-3 and np.max(np.abs(e[:, 1])) < 0.05


def test_registry_and_physical_start():
    sys_ = BioreactorBastinGevers()
    ob = make_observer("bastin_gevers", sys_, c2=1.0, theta_hat0=[-3.0, -0.1, -0.1],
                       x_hat0=[1.0, 2.0])
    np.testing.assert_allclose(ob.x_hat, [1.0, 2.0])
    np.testing.assert_allclose(ob.z_hat, [1.0, -0.2])  # x2 = (1 - c2) z1 + theta3 z2
    with pytest.raises(DesignError, match=r"bastin_gevers.: unknown parameter\(s\) \[.kk.\]; valid:"):
        make_observer("bastin_gevers", sys_, c2=1.0, kk=1)


def test_defaults_start_inside_the_inverse_domain_on_its_own_plant(tmp_path):
    """With no initial estimate the observer starts at its form's ``start``: the bioreactor's
    nominal model at its default state (eq. 6.4), inside the domain of the inverse 6.6
    (theta3 != 0, z2 != 0), so that the defaults run on the registered plant, the command line
    included; an estimate given in part takes the rest from the start."""
    from hgo_mj.cli import main

    sys_ = BioreactorBastinGevers()
    x0, th0 = sys_.to_aocf(sys_.default_x0, sys_.default_c2)
    ob = BastinGeversObserver(sys_)
    np.testing.assert_allclose(ob.z_hat, x0)
    np.testing.assert_allclose(ob.theta_hat_, th0)
    np.testing.assert_allclose(ob.x_hat, sys_.default_x0)
    s = ob.init(2, z_hat0=[1.0, -0.2])
    np.testing.assert_allclose(s.S[:, 2:5], [th0, th0])
    assert make_observer("bastin_gevers", sys_, c2=1.0).form.start[1][0] == pytest.approx(
        sys_.to_aocf(sys_.default_x0, 1.0)[1][0])
    assert main(["run", "--plant", "bioreactor_bastin_gevers", "--observer", "bastin_gevers",
                 "--duration", "2", "--out", str(tmp_path)]) == 0
    with pytest.raises(DesignError, match=r"start must be a pair"):
        AOCF([[0.0]], np.ones((1, 1, 1)), lambda y, u: np.array([y]), start=[0.0])


# ------------------------------------------------------------------ bad input
def test_system_without_a_canonical_form_is_named():
    sys_ = ElasticJoint.from_mjmodel(make_plant("elastic_joint").model)
    with pytest.raises(DesignError, match=r"canonical form of paper 002, eq. 2.2.*ElasticJoint "
                                          r"provides none \(it declares the forms \[.*\], no 'aocf'\)"):
        BastinGeversObserver(sys_)
    with pytest.raises(DesignError, match="needs a system with a derived AOCF or aocf="):
        BastinGeversObserver()
    with pytest.raises(DesignError, match="aocf must be an AOCF; found str"):
        BastinGeversObserver(aocf="6.5")
    with pytest.raises(DesignError, match="c2, unknown and damping_known choose a derived AOCF"):
        BastinGeversObserver(aocf=AOCF.bioreactor(BioreactorBastinGevers()), c2=1.0)
    with pytest.raises(DesignError, match="the AOCF of BioreactorBastinGevers takes other options"):
        BastinGeversObserver(BioreactorBastinGevers(), unknown=("p2",))


@pytest.mark.parametrize("gamma, exc, match", [
    (-1.0, DesignError, r"gamma must be positive definite; found eigenvalues \[-1.0, -1.0, -1.0\]"),
    ([1.0, 0.0, 2.0], DesignError, r"positive definite; found eigenvalues \[0.0, 1.0, 2.0\]"),
    ([[1, 2, 0], [2, 1, 0], [0, 0, 1]], DesignError, r"positive definite; found eigenvalues \[-1.0"),
    ([[1, 0.5, 0], [0, 1, 0], [0, 0, 1]], DesignError, "gamma must be symmetric"),
    ([1.0, 2.0], DimensionError, "gamma as a vector must have length m = 3.*found length 2"),
    (np.eye(2), DimensionError, r"3x3 matrix; found shape \(2, 2\)"),
    ([np.nan, 1, 1], DesignError, "gamma must be finite"),
    ("big", DesignError, "gamma must be a number"),
])
def test_gamma_must_be_symmetric_positive_definite(gamma, exc, match):
    with pytest.raises(exc, match=match):
        _bio_observer(gamma=gamma)


def test_bad_forms_and_settings():
    omega = lambda y, u: np.array([y])  # noqa: E731
    with pytest.raises(DimensionError, match=r"R must be a square n x n matrix \(eq. 2.3\); found "
                                             r"shape \(2, 3\)"):
        AOCF(np.zeros((2, 3)), np.zeros((2, 1, 1)), omega)
    with pytest.raises(DesignError, match=r"zero first column \(eq. 2.3.*found \[0.0, 1.0\]"):
        AOCF([[0.0, 1.0], [1.0, -1.0]], np.ones((2, 1, 1)), omega)
    with pytest.raises(DesignError, match=r"F = R\[1:, 1:\] must be Hurwitz.*\[0.5"):
        AOCF([[0.0, 1.0], [0.0, 0.5]], np.ones((2, 1, 1)), omega)
    with pytest.raises(DimensionError, match=r"alpha must have shape \(n, m, s\) = \(2, m, s\).*"
                                             r"found shape \(3, 1, 1\)"):
        AOCF([[0.0, 1.0], [0.0, -1.0]], np.ones((3, 1, 1)), omega)
    with pytest.raises(DesignError, match="omega must be a callable; found int"):
        AOCF([[0.0, 1.0], [0.0, -1.0]], np.ones((2, 1, 1)), 3)
    with pytest.raises(DimensionError, match="theta_names must have 1 entries; found 2"):
        AOCF([[0.0, 1.0], [0.0, -1.0]], np.ones((2, 1, 1)), omega, theta_names=("a", "b"))
    form = AOCF([[0.0, 1.0], [0.0, -1.0]], np.ones((2, 1, 2)), omega)  # omega returns 1 of 2
    ob = BastinGeversObserver(aocf=form)
    with pytest.raises(DimensionError, match=r"omega\(y, u\) of AOCF must return 2 values; found "
                                             r"shape \(1,\)"):
        ob.update(np.array([1.0]), np.array([0.0]), 0.01)
    _, ob = _bio_observer()
    with pytest.raises(DimensionError, match=r"u must have shape \(2,\); found shape \(1,\)"):
        ob.update(np.array([1.0]), np.array([1.0]), 0.01)
    ob = BastinGeversObserver(aocf=AOCF.bioreactor(BioreactorBastinGevers(), 1.0),
                              theta_hat0=[-3.0, -0.1, -0.1], z_hat0=[1.0, 1.0])  # u of any width
    with pytest.raises(DimensionError, match=r"omega\(y, u\) or g\(y, u\) of .* failed on "
                                             r"y = 1.0, u of shape \(1,\)"):
        ob.update(np.array([1.0]), np.array([1.0]), 0.01)
    with pytest.raises(DimensionError, match=r"y must be \(p,\) with channel\(s\) \[0\]"):
        ob.update(1.0, np.array([1.0, 1.0]), 0.01)
    for kw, match in [({"c1": 0.0}, "c1 must be > 0; found 0"),
                      ({"method": "rk45"}, r"method must be one of \['rk4', 'euler'\]"),
                      ({"substeps": 0}, "substeps must be a positive integer"),
                      ({"on_unreachable": "maybe"}, "on_unreachable must be"),
                      ({"excitation_window": -1.0}, "excitation_window must be > 0"),
                      ({"theta_hat0": [1.0, 2.0]},
                       r"theta_hat0 must have shape \(3,\) or \(B, 3\); found shape \(2,\)"),
                      ({"z_hat0": [1.0]}, r"z_hat0 must have shape \(2,\) or \(B, 2\); found shape \(1,\)"),
                      ({"outputs": 0}, "outputs must be a non-empty sequence"),
                      ({"outputs": (1,)}, r"BioreactorBastinGevers has 1 output\(s\) \['z1'\]; "
                                          r"found channel 1")]:
        exc = DimensionError if "shape" in match or "channel" in match else DesignError
        with pytest.raises(exc, match=match):
            _bio_observer(**kw)
    with pytest.raises(DesignError, match=r"initial estimate .* lies where the inverse map is "
                                          r"undefined: .*it needs theta3 = -p3 != 0"):
        BastinGeversObserver(BioreactorBastinGevers(), c2=1.0, theta_hat0=[0.0, 0.0, 0.0])
    with pytest.raises(DesignError, match="x_hat0 in physical coordinates needs the form's "
                                          "from_physical map"):
        BastinGeversObserver(aocf=form, x_hat0=[1.0, 2.0])
    with pytest.raises(DesignError, match=r"reads one output \(y = x1\); found outputs \[0, 1\]"):
        BastinGeversObserver(aocf=form, outputs=(0, 1))
    sys_ = Pendulum.from_mjmodel(make_plant("pendulum").model)
    with pytest.raises(DesignError, match=r"unknown must be \['g_over_l', 'b_over_J'\]"):
        BastinGeversObserver(sys_, unknown=("g_over_l",))
    with pytest.raises(DesignError, match="damping_known must be 'ratio' or 'coefficient'"):
        BastinGeversObserver(sys_, damping_known="both")


def test_check_period_refuses_an_unstable_step():
    _, ob = _bio_observer(c1=400.0, method="euler")
    h = rk_stable_period([-400.0, -1.0], "euler")
    assert h == pytest.approx(2.0 / 400.0, rel=1e-9)
    with pytest.raises(DesignError, match=r"euler integration .* unstable on its poles \[-400.0, "
                                          r"-1.0\]; the largest stable step is 0.005: raise "
                                          r"substeps to at least 3"):
        ob.check_period(0.01)
    ob2 = BastinGeversObserver(ob.system, aocf=None, c1=400.0, c2=1.0, method="euler", substeps=3,
                               theta_hat0=ob.theta_hat_, z_hat0=ob.z_hat)
    ob2.check_period(0.01)
    assert rk_stable_period([-1.0], "rk4") == pytest.approx(2.785293563, rel=1e-6)


def test_symmetric_positive_definite_helper():
    np.testing.assert_array_equal(symmetric_matrix("G", 2.0, 2, dim="m"), 2 * np.eye(2))
    np.testing.assert_array_equal(symmetric_matrix("G", [1.0, 3.0], 2, dim="m"), np.diag([1, 3]))


def test_first_order_form_has_no_filter():
    """n = 1: R = [[0]], no V; phi = Omega_1^T. x' = theta u is identified."""
    form = AOCF([[0.0]], np.ones((1, 1, 1)), lambda y, u: np.array([u[0]]))
    ob = BastinGeversObserver(aocf=form, c1=5.0, gamma=10.0)
    assert ob.V_.shape == (0, 1)
    x, theta, dt = 0.0, 2.0, 0.001
    for k in range(20000):
        u = np.array([math.sin(k * dt)])
        ob.update(np.array([x]), u, dt)
        x += dt * theta * u[0]
    assert ob.theta_hat_[0] == pytest.approx(theta, abs=2e-3)
