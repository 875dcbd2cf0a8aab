"""The adaptive-gain high-gain observer (paper 000, eq. 2, 4-5; Theorems 2 and 3)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hgo_mj.cli import parse_spec
from hgo_mj.design import bullinger_theorem3_bound
from hgo_mj.exceptions import DesignError, DimensionError, DivergenceError
from hgo_mj.inputs import Constant, Multisine
from hgo_mj.observers import AdaptiveGainObserver, make_observer
from hgo_mj.observers.adaptive_gain import dead_zone
from hgo_mj.observers.high_gain import one_step_map
from hgo_mj.plants.ode import OdePlant
from hgo_mj.sensors import GaussianNoise, SensorChain
from hgo_mj.simulate import simulate
from hgo_mj.systems.papers import BioreactorBullinger

U0 = np.zeros(0)


def test_dead_zone_is_eq5():
    e = np.array([0.0, 0.01, -0.02, 0.03, -0.3, 0.5, 0.7, -2.0])
    np.testing.assert_allclose(dead_zone(e, 0.02, 0.5), [0, 0, 0, 0.01, 0.28, 0.48, 0.48, 0.48])


def test_theorem3_bound_values():
    # n = 1: Pbar = 1 / (2 p1), bound mu / (p1 k0): the exact worst case of e' = -p1 k0 e + phi
    np.testing.assert_allclose(bullinger_theorem3_bound([2.0], 3.0, 0.5), [3.0])
    # n = 2, binomial: Pbar = [[1/2, -1/2], [-1/2, 3/2]] (solves eq. 7), ||Pbar|| = 1 + 1/sqrt 2
    b = bullinger_theorem3_bound([2.0, 1.0], 1.0, 2.0)
    np.testing.assert_allclose(b, 2 * (1 + 2**-0.5) / np.array([4.0, 2.0]), rtol=1e-12)
    with pytest.raises(DesignError, match="roots .* have non-negative real part"):
        bullinger_theorem3_bound([1.0, -1.0], 1.0, 1.0)
    with pytest.raises(DesignError, match="k0 must be > 0"):
        bullinger_theorem3_bound([2.0, 1.0], 1.0, 0.0)
    with pytest.raises(DesignError, match="mu must be finite"):
        bullinger_theorem3_bound([2.0, 1.0], np.nan, 1.0)


def _sine_chain(chain, n, mu, omega, dt):
    """Chain of n integrators started on the orbit with y^(n) = mu sin(omega t)."""
    plant = OdePlant(chain(n)(), dt=dt, physics_dt=dt)
    x0 = [mu / omega**n * np.sin((i - n) * np.pi / 2) * omega**i for i in range(n)]
    return plant, Multisine([mu], [omega / (2 * np.pi)]), x0


@pytest.mark.parametrize("method", ["exact", "rk4"])
def test_theorems_2c_and_3_on_a_chain_with_bounded_phi(chain, method):
    """Noise-free, |y''| <= mu: k converges (Thm 2 a), e1 ends in the lambda strip (Thm 2 c)
    and the final errors are below eq. 14 (Thm 3), which is not vacuous (found: 72x and 8x
    above the errors, k from 1 to about 4.5)."""
    mu, lam, k0 = 1.0, 0.05, 1.0
    plant, w, x0 = _sine_chain(chain, 2, mu, 1.0, 1e-3)
    ob = AdaptiveGainObserver(plant.system, lam=lam, lam_hat=0.5, gamma=1000.0, k0=k0,
                              method=method)
    traj = simulate(plant, None, {"a": ob}, w, duration=50.0, x0=x0)
    k = traj.observers["a"].diagnostics["k"]
    e = np.abs(traj.error("a"))
    late = traj.t >= 30.0
    assert np.all(np.diff(k) >= 0.0) and k[0] == k0
    assert k[-1] > 3.0 * k0  # it did adapt ...
    assert k[-1] == k[np.argmax(late)]  # ... and stopped: k constant over the last 20 s
    assert e[late, 0].max() <= lam  # Theorem 2 c
    bound = bullinger_theorem3_bound(ob.p, mu, k0)
    final = e[late].max(axis=0)
    assert np.all(final < bound)  # Theorem 3, eq. 14
    assert np.all(final > 1e-3 * bound)  # and not vacuous


def test_rk4_update_integrates_the_joint_ode_with_y_held():
    """One rk4 sample against solve_ivp of eq. 2 + eq. 4-5 in (z, k), y held, k adapting: the
    error is RK4's local error, O(dt^5) (halving dt divides it by about 32)."""
    lam, lam_hat, gamma, p = 0.05, 0.5, 30.0, np.array([3.0, 3.5, 1.2])
    z0, y = np.array([0.0, 0.4, -0.3]), 0.45

    def rhs(t, s):
        k, z = s[0], s[1:]
        e = y - z[0]
        dz = np.append(z[1:], 0.0) + p * k ** np.arange(1, 4) * e
        return np.concatenate(([gamma * dead_zone(e, lam, lam_hat) ** 2], dz))

    errs = []
    for dt in (0.04, 0.02):
        ob = AdaptiveGainObserver(order=3, p=p, lam=lam, lam_hat=lam_hat, gamma=gamma, k0=2.0,
                                  method="rk4", z_hat0=z0)
        ob.update(np.array([y]), U0, dt)
        assert ob.k_ > 2.0 + 1e-3  # the sample adapted k
        ref = solve_ivp(rhs, (0, dt), np.concatenate(([2.0], z0)), method="DOP853",
                        rtol=1e-13, atol=1e-15).y[:, -1]
        errs.append(np.abs(np.concatenate(([ob.k_], ob.z_hat)) - ref).max())
    assert errs[1] < 1e-6
    assert 20.0 < errs[0] / errs[1] < 45.0


@pytest.mark.parametrize("p", [[4.0, 6.0, 4.0, 1.0], [1.0, 0.2], [1.4, 1.0], [2.0],
                               [2.0, 3.0, 1.5, 0.4, 0.1]],
                         ids=["binomial4", "real", "complex", "n1", "mixed5"])
@pytest.mark.parametrize("method", ["exact", "rk4", "euler"])
def test_without_adaptation_it_is_the_plain_observer(method, p):
    """Inside the dead zone k stays k0 and the update is the plain high-gain observer's (for
    ``exact``: the pole-matched gain expanded in closed form, repeated, real and complex roots)."""
    n = len(p)
    ad = AdaptiveGainObserver(order=n, p=p, lam=1e6, lam_hat=2e6, gamma=5.0, k0=7.0,
                              method=method)
    # the plain high-gain observer's one-sample map z+ = M z + b y (one_step_map, which
    # HighGainObserver runs), held against the adaptive observer's own kernel
    M, b, _ = one_step_map(np.array(p), 7.0, 0.01, method)
    z = np.zeros(n)
    rng = np.random.default_rng(0)
    for _ in range(200):
        y = rng.standard_normal(1)
        z = M @ z + b * y[0]
        np.testing.assert_allclose(ad.update(y, U0, 0.01), z, rtol=1e-10, atol=1e-11)
    assert ad.k_ == 7.0


def test_methods_agree_when_k_dt_is_small(chain):
    plant, w, x0 = _sine_chain(chain, 2, 1.0, 1.0, 1e-3)
    obs = {m: AdaptiveGainObserver(plant.system, lam=0.05, lam_hat=0.5, gamma=1000.0, k0=1.0,
                                   method=m) for m in ("exact", "rk4", "euler")}
    traj = simulate(plant, None, obs, w, duration=10.0, x0=x0)
    ks = {m: traj.observers[m].diagnostics["k"][-1] for m in obs}
    assert ks["rk4"] == pytest.approx(ks["exact"], rel=0.02)
    assert ks["euler"] == pytest.approx(ks["rk4"], rel=0.02)


def test_noise_larger_than_lambda_makes_k_grow_without_end(chain):
    """The theorems assume no noise: with sigma = 2 lambda k keeps growing, faster and faster."""
    plant = OdePlant(chain(2)(), dt=1e-2, physics_dt=1e-2)
    ob = AdaptiveGainObserver(plant.system, lam=0.01, lam_hat=0.1, gamma=100.0, k0=1.0)
    traj = simulate(plant, SensorChain([GaussianNoise(std=0.02)], seed=0), {"a": ob},
                    Constant([0.0]), duration=200.0)
    k = traj.observers["a"].diagnostics["k"]
    q = len(k) // 4
    assert k[-1] > 3.0 and k[-1] - k[2 * q] > k[2 * q] - k[q] > 0.5
    # k_max stops it, with one warning
    capped = AdaptiveGainObserver(plant.system, lam=0.01, lam_hat=0.1, gamma=100.0, k0=1.0,
                                  k_max=2.0)
    with pytest.warns(RuntimeWarning, match="k reached k_max = 2") as rec:
        traj = simulate(plant, SensorChain([GaussianNoise(std=0.02)], seed=0), {"a": capped},
                        Constant([0.0]), duration=200.0)
    assert len([r for r in rec if "k_max" in str(r.message)]) == 1
    assert traj.observers["a"].diagnostics["k"][-1] == 2.0 and capped.k_max_reached_
    capped.reset()
    assert capped.k_ == 1.0 and not capped.k_max_reached_


def test_dropout_holds_prediction_and_does_not_adapt():
    ob = AdaptiveGainObserver(order=2, lam=0.01, lam_hat=0.5, gamma=100.0, k0=1.0,
                              z_hat0=[1.0, 2.0])
    x = ob.update(np.array([np.nan]), U0, 0.1)
    np.testing.assert_allclose(x, [1.2, 2.0])  # the open-loop chain
    assert ob.k_ == 1.0 and ob.dropouts_ == 1
    ob.update(np.array([5.0]), U0, 0.1)
    assert ob.k_ > 1.0  # a real sample far outside the strip adapts
    with pytest.raises(DivergenceError, match=r"measurement y\[0\] is inf"):
        ob.update(np.array([np.inf]), U0, 0.1)


def test_k_is_reported_at_every_sample(chain):
    plant, w, x0 = _sine_chain(chain, 2, 1.0, 1.0, 1e-2)
    ob = make_observer("adaptive_gain", plant.system, lam=0.05, lam_hat=0.5, gamma=100.0, k0=1.0)
    traj = simulate(plant, None, {"a": ob}, w, duration=5.0, x0=x0)
    k = traj.observers["a"].diagnostics["k"]
    assert k.shape == traj.t.shape and k[0] == 1.0 and k[-1] > 1.0
    assert traj.metadata["observers"]["a"]["gamma"] == 100.0


def test_check_period_at_current_k_and_at_k_max():
    # rk4 is stable for k dt < 2.785 with binomial p (n = 2)
    ob = AdaptiveGainObserver(order=2, lam=0.1, lam_hat=1.0, gamma=1.0, k0=100.0, method="rk4")
    assert ob.max_stable_gain(0.01) == pytest.approx(278.53, rel=1e-4)
    ob.check_period(0.01)
    with pytest.raises(DesignError, match=r"at the current gain k=100.*largest stable period "
                                          r"at k=100 is 0\.02785"):
        ob.check_period(0.05)
    capped = AdaptiveGainObserver(order=2, lam=0.1, lam_hat=1.0, gamma=1.0, k0=100.0,
                                  k_max=1000.0, method="rk4")
    with pytest.raises(DesignError, match=r"at k_max k=1000.*k < 278\.5"):
        capped.check_period(0.01)
    warn = AdaptiveGainObserver(order=2, lam=0.1, lam_hat=1.0, gamma=1.0, k0=100.0,
                                k_max=1000.0, method="rk4", on_unstable="warn")
    with pytest.warns(RuntimeWarning, match="unstable at k_max"):
        warn.check_period(0.01)
    # the sampled-data update is stable at every k
    AdaptiveGainObserver(order=2, lam=0.1, lam_hat=1.0, gamma=1.0, k0=1e4, k_max=1e6).check_period(1.0)


def test_k_growing_past_the_stable_limit_during_a_run():
    ob = AdaptiveGainObserver(order=2, lam=0.01, lam_hat=1.0, gamma=1e6, k0=100.0, method="rk4")
    ob.check_period(0.01)
    with pytest.raises(DivergenceError, match=r"k grew to .* past the largest gain 278\.5"):
        for _ in range(10):
            ob.update(np.array([1.0]), U0, 0.01)
    ob = AdaptiveGainObserver(order=2, lam=0.01, lam_hat=1.0, gamma=1e6, k0=100.0, method="rk4",
                              on_unstable="warn")
    with pytest.warns(RuntimeWarning, match="k grew to"):
        ob.update(np.array([1.0]), U0, 0.01)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # warned once only
        ob.update(np.array([1.0]), U0, 0.01)


@pytest.mark.parametrize("method", ["exact", "rk4", "euler"])
def test_model_term(chain, method):
    """With the model term (phi = y'' known) the estimate is nearly exact and k adapts less."""
    plant, w, x0 = _sine_chain(chain, 2, 4.0, 2.0, 1e-3)
    kw = dict(lam=0.01, lam_hat=0.5, gamma=100.0, k0=2.0, method=method)
    obs = {"free": AdaptiveGainObserver(plant.system, **kw),
           "model": AdaptiveGainObserver(plant.system, model=True, **kw)}
    traj = simulate(plant, None, obs, w, duration=10.0, x0=x0)
    late = traj.t >= 5.0
    e_free = np.abs(traj.error("free")[late]).max()
    e_model = np.abs(traj.error("model")[late]).max()
    assert e_model < 0.05 * e_free
    assert traj.observers["model"].diagnostics["k"][-1] < traj.observers["free"].diagnostics["k"][-1]


def test_cli_parameters_build_the_observer():
    spec = parse_spec("adaptive_gain:lam=0.02,lam_hat=0.5,gamma=100,k0=0.1,p=[1,0.2],"
                      "method=rk4", "type")
    kind = spec.pop("type")
    ob = make_observer(kind, BioreactorBullinger(), **spec)
    assert isinstance(ob, AdaptiveGainObserver) and ob.gamma == 100.0 and ob.n == 2
    assert ob.params()["p"] == [1.0, 0.2] and ob.diagnostics()["k"] == 0.1
    with pytest.raises(DesignError, match=r"unknown parameter\(s\) \[.lambda_hat.\]; valid: \[.gamma., .k0."):
        make_observer("adaptive_gain", None, order=2, lam=0.1, lambda_hat=1.0, gamma=1.0, k0=1.0)


GOOD = dict(order=2, lam=0.02, lam_hat=0.5, gamma=100.0, k0=0.1)


@pytest.mark.parametrize("change, exc, match", [
    ({"lam_hat": 0.02}, DesignError, r"lam_hat must be > lam .*found lam_hat=0.02 <= lam=0.02"),
    ({"lam_hat": 0.01}, DesignError, "lam_hat must be > lam"),
    ({"lam": 0.0}, DesignError, "lam must be > 0; found 0"),
    ({"gamma": 0.0}, DesignError, "gamma must be > 0; found 0"),
    ({"gamma": -1.0}, DesignError, "gamma must be > 0; found -1"),
    ({"k0": 0.0}, DesignError, "k0 must be > 0; found 0"),
    ({"k0": -0.1}, DesignError, "k0 must be > 0"),
    ({"k_max": 0.05}, DesignError, r"k_max must be >= k0; found k_max=0.05 < k0=0.1"),
    ({"p": [0.2, -1.0]}, DesignError, r"roots \[.*\] have non-negative real part"),
    ({"p": [1.0, 0.2, 0.1]}, DimensionError, "p must have n = 2 coefficients; found 3"),
    ({"lam": float("nan")}, DesignError, "lam must be finite; found nan"),
    ({"lam_hat": float("nan")}, DesignError, "lam_hat must be finite; found nan"),
    ({"gamma": float("nan")}, DesignError, "gamma must be finite; found nan"),
    ({"k0": float("nan")}, DesignError, "k0 must be finite; found nan"),
    ({"k_max": float("nan")}, DesignError, "k_max must be finite; found nan"),
    ({"p": [1.0, float("nan")]}, DesignError, "p must be finite"),
    ({"method": "rk45"}, DesignError, r"method must be one of \['exact', 'euler', 'rk4'\]"),
    ({"on_unstable": "maybe"}, DesignError, "on_unstable must be"),
    ({"model": True}, DesignError, "model=True needs a system"),
    ({"order": None}, DesignError, "needs a system or an explicit order"),
])
def test_bad_input(change, exc, match):
    with pytest.raises(exc, match=match):
        AdaptiveGainObserver(**{**GOOD, **change})
