"""The plain high-gain observer (paper 000, eq. 2) against its linear error dynamics (eq. 3, 6)."""

from __future__ import annotations

from math import factorial

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hgo_mj.design import binomial_coefficients, check_hurwitz, hgo_gains, observer_matrix
from hgo_mj.exceptions import DesignError, DimensionError
from hgo_mj.inputs import Multisine
from hgo_mj.observers import HighGainObserver, MultiOutputHighGainObserver, make_observer
from hgo_mj.observers.high_gain import derivative_names, matched_gain
from hgo_mj.plants.ode import OdePlant
from hgo_mj.sensors import SensorChain, Stage
from hgo_mj.simulate import simulate
from hgo_mj.systems.pendulum import Pendulum


def test_gains_are_p_i_k_to_the_i():
    np.testing.assert_allclose(hgo_gains([3, 3, 1], 10.0), [30.0, 300.0, 1000.0])
    np.testing.assert_array_equal(binomial_coefficients(4), [4, 6, 4, 1])
    # eq. 6: A_k = k K Abar K^-1 with K = diag(1, k, ..., k^(n-1))
    p, k = np.array([2.0, 1.5, 0.5]), 7.0
    Abar = np.diag(np.ones(2), 1)
    Abar[:, 0] = -p
    K = np.diag(k ** np.arange(3))
    np.testing.assert_allclose(observer_matrix(p, k), k * K @ Abar @ np.linalg.inv(K), rtol=1e-12)


def test_non_hurwitz_p_names_the_roots():
    with pytest.raises(DesignError, match=r"roots \[.*\] have non-negative real part"):
        check_hurwitz([-0.2, 1.01])
    with pytest.raises(DesignError, match="k must be > 0; found -1"):
        hgo_gains([2, 1], -1)


def _steady_amplitude(t, e, t_from):
    sel = t >= t_from
    return 0.5 * (e[sel].max() - e[sel].min())


def _sampled_chain(n, dt):
    """Phi = e^{A dt} and S = int_0^dt e^{A s} ds of the chain of integrators, in closed form."""
    Phi = np.array([[dt ** (j - i) / factorial(j - i) if j >= i else 0.0 for j in range(n)]
                    for i in range(n)])
    S = np.array([[dt ** (j - i + 1) / factorial(j - i + 1) if j >= i else 0.0
                   for j in range(n)] for i in range(n)])
    return Phi, S


@pytest.mark.parametrize("method", ["exact", "rk4"])
@pytest.mark.parametrize("n", [2, 3, 4])
def test_disturbance_transfer_matches_eq3(chain, n, method):
    """e1(s) = w(s) / (s + k)^n for y^(n) = w (paper 000, eq. 3, binomial p).

    The plant starts on the periodic orbit y = sin(omega t), so y^(n) = w is a pure sinusoid.
    Sampling at dt changes eq. 3 by O(k dt); the test predicts the sampled amplitude exactly:
    for ``exact`` the error obeys e_{k+1} = (Phi - Ld C) e_k + S B w_k; for
    ``rk4`` the observer sees y through a zero-order hold, (1 - e^{-s dt}) / (s dt).
    """
    k, f, dt = 6.0, 0.4, 1e-3
    omega = 2 * np.pi * f
    x0 = [omega**i * np.sin(i * np.pi / 2) for i in range(n)]
    plant = OdePlant(chain(n)(), dt=dt, physics_dt=dt)
    ob = HighGainObserver(plant.system, k=k, method=method)
    w = Multisine([omega**n], [f], [n * np.pi / 2])
    traj = simulate(plant, None, {"hgo": ob}, w, duration=20.0, x0=x0)
    e1 = traj.error("hgo")[:, 0]
    s = 1j * omega
    continuous = abs(s + k) ** -n * omega**n  # eq. 3 with |w| = omega^n
    if method == "exact":
        Phi, S = _sampled_chain(n, dt)
        M = Phi - np.outer(matched_gain(binomial_coefficients(n), k, dt), np.eye(n)[0])
        z = np.exp(s * dt)
        sampled = abs(np.linalg.solve(z * np.eye(n) - M, S[:, -1])[0]) * omega**n
    else:
        T = 1 - (s / (s + k)) ** n
        sampled = abs(1 - T * (1 - np.exp(-s * dt)) / (s * dt))
    assert abs(sampled - continuous) < 0.06 * continuous
    assert _steady_amplitude(traj.t, e1, 12.0) == pytest.approx(sampled, rel=3e-3)


@pytest.mark.parametrize("n", [2, 3, 4, 5])
@pytest.mark.parametrize("kdt", [1e-3, 0.05, 0.5, 3.0])
def test_matched_gain_places_the_sampled_poles(n, kdt):
    """eig(Phi - Ld C) = exp(k dt r_i), and Ld / dt -> (p_i k^i) as k dt -> 0."""
    rng = np.random.default_rng(n)
    roots = -rng.uniform(0.5, 2.0, n)
    p = np.poly(roots)[1:]
    k, dt = 20.0, kdt / 20.0
    Ld = matched_gain(p, k, dt)
    Phi, _ = _sampled_chain(n, dt)
    # compare characteristic polynomials (eigenvalues of near-repeated roots are ill-conditioned)
    charpoly = np.poly(Phi - np.outer(Ld, np.eye(n)[0]))
    np.testing.assert_allclose(charpoly, np.poly(np.exp(k * dt * roots)), rtol=1e-9, atol=1e-11)
    if kdt <= 1e-3:
        np.testing.assert_allclose(Ld / dt, hgo_gains(p, k), rtol=5 * n * kdt)


@pytest.mark.parametrize("n", [2, 3, 4])
def test_exact_update_tracks_polynomials_without_lag(chain, n):
    """y^(n) = 0: the sampled-data observer's error decays to zero; the held measurement of the
    rk4 update leaves a lag of about dt/2 times y' (the sawtooth a hold makes)."""
    plant = OdePlant(chain(n)(), dt=1e-3, physics_dt=1e-3)
    x0 = [1.0, 10.0] + [0.0] * (n - 2)  # a ramp, 10 units per second
    obs = {m: HighGainObserver(plant.system, k=40.0, method=m) for m in ("exact", "rk4")}
    traj = simulate(plant, None, obs, Multisine([0.0], [0.0]), duration=2.0, x0=x0)
    assert np.abs(traj.error("exact")[-1]).max() < 1e-9
    assert abs(traj.error("rk4")[-1, 0]) > 1e-3  # ~ dt/2 * 10


@pytest.mark.parametrize("n", [2, 3])
def test_noise_transfer_matches_eq3(chain, n):
    """(y + nu) - y_hat = s^n / (s + k)^n nu for the plant at rest (paper 000, eq. 3)."""
    k, f = 5.0, 1.5
    plant = OdePlant(chain(n)(), dt=1e-3, physics_dt=1e-3)
    ob = HighGainObserver(plant.system, k=k)

    class SineNoise(Stage):  # a sensor stage of one's own: nu(t) = sin(2 pi f t)
        name = "sine"

        def apply(self, t, Y, draws):
            return Y + np.sin(2 * np.pi * f * np.asarray(t))[None, :, None]

    nu = SensorChain([SineNoise()])
    traj = simulate(plant, nu, {"hgo": ob}, Multisine([0.0], [0.0]), duration=20.0)
    out_err = traj.y_meas[:, 0] - traj.observers["hgo"].x_hat[:, 0]
    omega = 2 * np.pi * f
    expected = omega ** n / abs(1j * omega + k) ** n
    assert _steady_amplitude(traj.t, out_err, 12.0) == pytest.approx(expected, rel=2e-2)


@pytest.mark.parametrize("method", ["exact", "rk4"])
def test_error_follows_linear_error_dynamics_eq6(chain, method):
    """e' = A_k e + B w(t) (eq. 6) integrated by solve_ivp against the sampled observer."""
    n, k, dt = 3, 8.0, 1e-4
    plant = OdePlant(chain(n)(), dt=dt, physics_dt=dt)
    ob = HighGainObserver(plant.system, k=k, p=[3.0, 3.5, 1.2], method=method)
    w = Multisine([1.0, 0.3], [0.3, 1.1], [0.2, 0.0])
    x0 = np.array([0.5, -0.2, 0.1])
    traj = simulate(plant, None, {"hgo": ob}, w, duration=3.0, x0=x0)
    A = observer_matrix([3.0, 3.5, 1.2], k)
    sol = solve_ivp(lambda t, e: A @ e + np.array([0, 0, w(t)[0]]), (0, 3.0), x0,
                    t_eval=traj.t, rtol=1e-10, atol=1e-12, method="DOP853")
    err = traj.error("hgo")
    # sampling with a held y differs from the continuous observer by O(k dt): scale by |e|max
    scale = np.abs(sol.y.T).max(axis=0)
    assert np.all(np.abs(err - sol.y.T).max(axis=0) <= 2e-3 * scale)


def test_model_term_makes_observer_exact_on_known_phi(chain):
    plant = OdePlant(chain(2)(), dt=1e-3, physics_dt=1e-3)
    omega = 2 * np.pi
    w = Multisine([-2.0 * omega**2], [1.0])  # y = 2 sin(omega t) from x0 below
    free = HighGainObserver(plant.system, k=5.0)
    model = HighGainObserver(plant.system, k=5.0, model=True, method="rk4")
    traj = simulate(plant, None, {"free": free, "model": model}, w, duration=5.0,
                    x0=[0.0, 2.0 * omega])
    e_free = np.abs(traj.error("free")[2000:]).max()
    e_model = np.abs(traj.error("model")[2000:]).max()
    # what is left with the model term is the effect of the held measurement alone
    assert e_model < 1e-2 * e_free


def test_euler_with_too_long_period_is_refused_with_the_bound():
    ob = HighGainObserver(order=2, k=50.0, method="euler")
    assert ob.max_stable_period() == pytest.approx(0.04, rel=1e-6)  # |1 - k dt| < 1, double pole
    with pytest.raises(DesignError, match=r"largest stable period is 0\.04"):
        ob.update(np.array([1.0]), np.zeros(0), 0.05)
    warn = HighGainObserver(order=2, k=50.0, method="euler", on_unstable="warn")
    with pytest.warns(RuntimeWarning, match="unstable"):
        warn.update(np.array([1.0]), np.zeros(0), 0.05)
    # the sampled-data update is stable for every period
    assert HighGainObserver(order=2, k=50.0, method="exact").max_stable_period() == np.inf
    ob = HighGainObserver(order=2, k=50.0, method="exact")
    for _ in range(50):
        x = ob.update(np.array([1.0]), np.zeros(0), 1.0)
    np.testing.assert_allclose(x, [1.0, 0.0], atol=1e-12)


def test_dropout_holds_prediction_and_counts():
    ob = HighGainObserver(order=2, k=10.0, z_hat0=[1.0, 2.0])
    x = ob.update(np.array([np.nan]), np.zeros(0), 0.1)
    np.testing.assert_allclose(x, [1.2, 2.0])  # open-loop chain of integrators
    assert ob.dropouts_ == 1 and np.all(np.isfinite(ob.x_hat))
    ob.reset()
    assert ob.dropouts_ == 0
    np.testing.assert_array_equal(ob.z_hat, [1.0, 2.0])


def test_saturation_clips_reported_estimate_only():
    ob = HighGainObserver(order=2, k=100.0, z_bounds=([-1, -5], [1, 5]))
    ob.update(np.array([0.9]), np.zeros(0), 0.01)
    assert ob.z_hat[1] == 5.0 and ob.state.z[0, 1] > 5.0


def test_update_returns_fresh_arrays():
    ob = HighGainObserver(order=2, k=10.0)
    a = ob.update(np.array([1.0]), np.zeros(0), 1e-3)
    b = ob.update(np.array([1.0]), np.zeros(0), 1e-3)
    assert not np.shares_memory(a, b) and not np.array_equal(a, b)


def _pendulum():
    from hgo_mj.systems import Pendulum

    return Pendulum()


@pytest.mark.parametrize("z_bounds", [None, ([-1.0, -3.0], [1.0, 3.0])])
@pytest.mark.parametrize("method", ["exact", "euler"])
def test_model_update_is_correction_then_held_model_term(method, z_bounds):
    """With the model term, one sample is ``M z + b y + g phi(sat(z), u)`` with ``phi`` held at
    its start-of-sample value (rows summed left to right, ``g phi`` last): bit for bit, the
    correction followed by ``z + g phi``; a dropout takes the open-loop map plus ``g0 phi``."""
    from hgo_mj.observers.high_gain import one_step_map

    sys_ = _pendulum()
    a = HighGainObserver(sys_, k=10.0, model=True, method=method, z_bounds=z_bounds)
    rng = np.random.default_rng(3)
    dt = 0.04
    M, b, g = one_step_map(a.p, a.k_, dt, method)
    M0, _, g0 = one_step_map(a.p, a.k_, dt, method, closed=False)

    def row_sum(A, z, *extra):
        out = []
        for i in range(A.shape[0]):
            acc = 0.0
            for j in range(A.shape[1]):
                acc += A[i, j] * z[j]
            for c, v in extra:
                acc += c[i] * v
            out.append(acc)
        return np.array(out)

    ys = rng.uniform(-2, 2, 200).tolist() + [np.nan]
    for y, u in zip(ys, rng.uniform(-0.5, 0.5, 201).tolist()):
        z = a.state.z[0].copy()
        zs = z if z_bounds is None else np.clip(z, *z_bounds)
        ph = float(sys_.phi(zs, [u]))
        if y == y:
            expected = row_sum(M, z, (b, y), (g, ph))
        else:
            expected = row_sum(M0, z, (g0, ph))
        x = a.update(np.array([y]), np.array([u]), dt)
        np.testing.assert_array_equal(a.state.z[0], expected)
        np.testing.assert_array_equal(x, expected if z_bounds is None else np.clip(expected,
                                                                                    *z_bounds))
    assert a.dropouts_ == 1 and np.all(np.isfinite(x))


def test_model_free_measurement_checks():
    a = HighGainObserver(order=3, k=20.0)
    with pytest.raises(Exception, match="is inf"):
        a.update(np.array([np.inf]), np.zeros(0), 0.01)
    with pytest.raises(DesignError, match=r"outputs must be a 1-tuple such as \(0,\)"):
        HighGainObserver(order=2, k=1.0, outputs=(0, 1))
    with pytest.raises(DesignError, match="a 1-tuple"):
        HighGainObserver(order=2, k=1.0, outputs=1)


@pytest.mark.parametrize("model", [False, True])
def test_pickles_without_the_map_cache(model):
    import pickle

    ob = HighGainObserver(_pendulum(), k=10.0, model=model)
    ob.update(np.array([0.3]), np.array([0.1]), 0.04)
    assert ob._maps
    copy = pickle.loads(pickle.dumps(ob))
    assert copy._maps == {} and ob._maps  # the original keeps its cache
    np.testing.assert_array_equal(copy.update(np.array([0.2]), np.array([0.0]), 0.04),
                                  ob.update(np.array([0.2]), np.array([0.0]), 0.04))


def test_the_map_cache_is_bounded():
    """20,000 jittered periods keep at most MAP_CACHE sets of one-step maps."""
    from hgo_mj.observers.high_gain import MAP_CACHE

    ob = HighGainObserver(order=2, k=10.0)
    rng = np.random.default_rng(0)
    for dt in (1e-3 * (1 + 0.01 * rng.standard_normal(20000))).tolist():
        ob.update(np.array([0.1]), np.zeros(0), dt)
    assert len(ob._maps) <= MAP_CACHE


@pytest.mark.parametrize("kwargs, exc, match", [
    ({"order": 2, "k": 0.0}, DesignError, "k must be > 0"),
    ({"order": 2, "k": float("nan")}, DesignError, "k must be finite"),
    ({"order": 2, "k": 1.0, "p": [1, 2, 1]}, DimensionError, "p must have n = 2"),
    ({"order": 2, "k": 1.0, "p": [1, -1]}, DesignError, "Hurwitz"),
    ({"order": 2, "k": 1.0, "method": "rk45"}, DesignError, "method must be one of"),
    ({"order": 2, "k": 1.0, "z_bounds": ([1, 1], [0, 2])}, DesignError, "lower < upper"),
    ({"k": 1.0}, DesignError, "needs a system or an explicit order"),
    ({"order": 2, "k": 1.0, "model": True}, DesignError, "model=True needs a system"),
])
def test_bad_input(kwargs, exc, match):
    with pytest.raises(exc, match=match):
        HighGainObserver(**kwargs)


def test_order_mismatch_and_unknown_names(chain):
    with pytest.raises(DimensionError, match="order 3 does not match"):
        HighGainObserver(chain(2)(), k=1.0, order=3)
    with pytest.raises(DesignError, match=r"unknown observer 'hgo'; valid: \[.*'high_gain'"):
        make_observer("hgo", None, k=1.0)
    with pytest.raises(DesignError, match=r"unknown parameter\(s\) \['gain'\]; valid: \['k', "):
        make_observer("high_gain", None, order=2, gain=1.0)


# ------------------------------------------------------------ multi-output observer
@pytest.mark.parametrize("method", ["exact", "euler", "rk4"])
def test_multi_on_independent_chains_equals_two_single_observers(method):
    """Model-free, the chains of paper 001 eq. 5 are independent: bit for bit two HGOs,
    including a dropout on one channel only (that chain predicts, the other corrects)."""
    dt = 2e-3
    multi = MultiOutputHighGainObserver(orders=(2, 3), k=(5.0, 8.0), p=[None, [3.0, 3.5, 1.2]],
                                        method=method, z_hat0=[0.1, -0.2, 0.3, 0.0, 1.0])
    one = HighGainObserver(order=2, k=5.0, method=method, z_hat0=[0.1, -0.2], outputs=(0,))
    two = HighGainObserver(order=3, k=8.0, p=[3.0, 3.5, 1.2], method=method,
                           z_hat0=[0.3, 0.0, 1.0], outputs=(1,))
    rng = np.random.default_rng(1)
    for j in range(400):
        y = np.array([np.sin(0.01 * j), np.cos(0.02 * j)]) + 0.01 * rng.standard_normal(2)
        if j % 37 == 5:
            y[1] = np.nan
        x = multi.update(y, np.zeros(0), dt)
        np.testing.assert_array_equal(x, np.concatenate([one.update(y, np.zeros(0), dt),
                                                         two.update(y, np.zeros(0), dt)]))
    assert multi.channel_dropouts_ == [0, two.dropouts_] and two.dropouts_ == 11
    assert multi.dropouts_ == 11 and one.dropouts_ == 0


@pytest.mark.parametrize("method", ["exact", "rk4"])
def test_multi_model_term_matches_single_observers_with_model(chain, method):
    """phi(z_hat, u) -> the chains' top derivatives, as the single observers' model term."""
    dt = 1e-3
    multi = MultiOutputHighGainObserver(orders=(2, 3), k=(5.0, 8.0), method=method,
                                        phi=lambda z, u: u[:2])
    one = HighGainObserver(chain(2)(), k=5.0, model=True, method=method)
    two = HighGainObserver(chain(3)(), k=8.0, model=True, method=method)  # reads y[1:]
    for j in range(300):
        t = j * dt
        y = np.array([np.sin(3 * t), t * t])
        u = np.array([-9 * np.sin(3 * t), 0.0 if t < 0.1 else 1.0])
        x = multi.update(y, u, dt)
        ref = np.concatenate([one.update(y[:1], u[:1], dt), two.update(y[1:], u[1:], dt)])
        if method == "exact":
            np.testing.assert_array_equal(x, ref)
        else:  # the same RK4, summed in another order
            np.testing.assert_allclose(x, ref, rtol=1e-12, atol=1e-12)


def test_multi_on_the_mujoco_two_link_arm():
    """Two chains of order 4 on the link angles of the MuJoCo two-link elastic arm, model-free,
    k = 200, encoder-like noise 1e-5 rad: link velocities to 0.01 and 0.02 rad/s RMSE after 1 s
    (found 2.5e-3 and 4.0e-3; ranges 5.2 and 15.6 rad/s)."""
    from hgo_mj.plants import make_plant
    from hgo_mj.sensors import GaussianNoise, SensorChain

    plant = make_plant("elastic_joint_2link")
    ob = make_observer("high_gain_multi", plant.system, orders=[4, 4], k=200.0,
                       z_hat0=[0.3, 0, 0, 0, -0.2, 0, 0, 0])
    assert ob.state_names == ("link1_angle", "link1_velocity", "link1_acceleration", "link1_jerk",
                              "link2_angle", "link2_velocity", "link2_acceleration", "link2_jerk")
    plant_cols = plant.system.state_names  # estimates that are plant states, by name
    state_map = {i: plant_cols.index(name) for i, name in enumerate(ob.state_names)
                 if name in plant_cols}
    assert state_map == {0: 0, 1: 4, 4: 1, 5: 5}
    s1, s2 = Multisine([0.5, 0.2], [0.5, 1.3], [0.0, 1.0]), Multisine([0.15, 0.05], [0.8, 2.1])
    traj = simulate(plant, SensorChain([GaussianNoise(std=1e-5)], seed=0), {"multi": ob},
                    lambda t: np.concatenate([s1(t), s2(t)]), duration=3.0)
    xh, win = traj.observers["multi"].x_hat, traj.t >= 1.0
    rmse = {ob.state_names[i]: np.sqrt(np.mean((traj.x[win, j] - xh[win, i]) ** 2))
            for i, j in state_map.items()}
    assert rmse["link1_velocity"] < 0.01 and rmse["link2_velocity"] < 0.02
    assert rmse["link1_angle"] < 1e-4 and rmse["link2_angle"] < 1e-4
    assert np.ptp(traj.x[:, 4]) > 3.0 and np.ptp(traj.x[:, 5]) > 10.0  # the arm does move


def test_derivative_names():
    assert derivative_names("cart_position", 3) == ("cart_position", "cart_velocity",
                                                    "cart_acceleration")
    assert derivative_names("m", 3) == ("m", "m_d1", "m_d2")
    assert derivative_names("angle", 2) == Pendulum.state_names  # the pendulum's own names
    assert derivative_names("angle", 5)[4] == "angle_d4"
    assert derivative_names("q_angle", 6)[4:] == ("q_d4", "q_d5")


def test_multi_unstable_period_and_params():
    with pytest.raises(DesignError, match=r"chain 1 .* largest stable period is 0\.04"):
        MultiOutputHighGainObserver(orders=(2, 2), k=(10.0, 50.0), method="euler").update(
            np.zeros(2), np.zeros(0), 0.05)
    ob = MultiOutputHighGainObserver(orders=(2, 2), k=(10.0, 50.0), method="euler")
    assert ob.max_stable_period() == pytest.approx(0.04, rel=1e-6)
    assert ob.params()["orders"] == [2, 2] and ob.x_hat.shape == (4,)


@pytest.mark.parametrize("kwargs, exc, match", [
    ({"k": 1.0}, DesignError, r"needs orders=\[n_1, n_2, \.\.\.\]"),
    ({"k": 1.0, "orders": (2, 0)}, DesignError, "orders must be positive integers"),
    ({"k": [1.0, 2.0, 3.0], "orders": (2, 2)}, DimensionError, "one entry per chain"),
    ({"k": [1.0, -2.0], "orders": (2, 2)}, DesignError, r"k\[1\] must be > 0"),
    ({"k": 1.0, "orders": (2, 3), "p": [2, 1]}, DimensionError, r"p\[1\] must have n_1 = 3"),
    ({"k": 1.0, "orders": (2, 2), "p": [[2, 1], [1, -1]]}, DesignError, r"p\[1\] must give a Hurwitz"),
    ({"k": 1.0, "orders": (2, 2), "outputs": (1, 1)}, DesignError, "distinct"),
    ({"k": 1.0, "orders": (2, 2), "outputs": (0,)}, DimensionError, "one channel per chain"),
    ({"k": 1.0, "orders": 2, "phi": 3.0}, DesignError, "phi must be a callable"),
    ({"k": 1.0, "orders": (2, 2), "z_hat0": [0, 0, 0]}, DimensionError, "z_hat0 must have length 4"),
])
def test_multi_bad_input(kwargs, exc, match):
    with pytest.raises(exc, match=match):
        MultiOutputHighGainObserver(**kwargs)


def test_multi_bad_phi_and_channels():
    from hgo_mj.plants import make_plant

    ob = MultiOutputHighGainObserver(orders=(2, 2), k=1.0, phi=lambda z, u: [0.0])
    with pytest.raises(DimensionError, match=r"one top derivative per chain \(2\); found shape"):
        ob.update(np.zeros(2), np.zeros(0), 0.01)
    system = make_plant("elastic_joint_2link").system
    with pytest.raises(DimensionError, match=r"has 2 output\(s\).*found channel 2"):
        MultiOutputHighGainObserver(system, orders=(4, 4), k=1.0, outputs=(0, 2))
    # the two-link arm declares its chain orders (normal_form_orders); without a system or
    # orders, the observer asks for them
    assert make_observer("high_gain_multi", system, k=1.0).orders == (4, 4)
    with pytest.raises(DesignError, match=r"needs orders=\[n_1, n_2, \.\.\.\] \(one chain"):
        MultiOutputHighGainObserver(k=1.0)
