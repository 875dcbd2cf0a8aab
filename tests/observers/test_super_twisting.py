"""The super-twisting observer (Davila, Fridman, Levant 2005): one Euler step by hand, exact
differentiation of a signal with bounded second derivative (to the sampled accuracy O(L h)),
the MuJoCo pendulum with and without the model term, dropouts, bad parameters."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hgo_mj.exceptions import DesignError
from hgo_mj.inputs import Multisine
from hgo_mj.observers import SuperTwistingObserver, make_observer
from hgo_mj.plants import make_plant
from hgo_mj.sensors import GaussianNoise, SensorChain
from hgo_mj.simulate import simulate
from hgo_mj.systems import ElasticJoint, Pendulum


def test_one_euler_step_by_hand():
    """z = (0, 0), y = 0.04, h = 0.01, L = 100: k1 = 15, k2 = 110, e = 0.04:
    z1 = 0.01 * 15 * 0.2 = 0.03, z2 = 0.01 * 110 = 1.1."""
    ob = SuperTwistingObserver(L=100.0)
    assert ob.gains() == pytest.approx((15.0, 110.0))
    np.testing.assert_allclose(ob.update([0.04], np.zeros(0), 0.01), [0.03, 1.1])
    ob2 = SuperTwistingObserver(L=100.0, substeps=2)  # two steps of h/2: e = 0.04, then 0.025
    z1 = 0.005 * 15 * 0.2
    z2 = 0.005 * 110
    z1, z2 = z1 + 0.005 * (z2 + 15 * math.sqrt(0.04 - z1)), z2 + 0.005 * 110
    np.testing.assert_allclose(ob2.update([0.04], np.zeros(0), 0.01), [z1, z2])


def test_differentiates_a_sine_to_the_sampled_accuracy():
    """y = sin(3 t), |y''| <= 9 < L = 20: after the finite-time transient the velocity error
    stays within a few k2 h (the chattering), and the position error within O(L h^2)."""
    dt = 1e-3
    t = np.arange(0.0, 4.0, dt)
    ob = SuperTwistingObserver(L=20.0)
    z = ob.run(np.sin(3 * t)[:, None], np.zeros((t.size, 0)), dt).z_hat[0]
    late = t > 1.5
    tn = t + dt  # the row after sample k estimates z(t_{k+1})
    e2 = np.abs(z[late, 1] - 3 * np.cos(3 * tn[late]))
    k2 = ob.gains()[1]
    assert e2.max() < 3 * k2 * dt
    assert np.abs(z[late, 0] - np.sin(3 * tn[late])).max() < 20 * 20 * dt ** 2


def test_converges_on_the_mujoco_pendulum_model_helps():
    """The pendulum at 1 kHz with 1e-4 rad noise: model-free L must bound |y''| (tens of
    rad/s^2); with the model term a small L suffices and the velocity is better."""
    plant = make_plant("pendulum", dt=0.001)
    obs = {"free": SuperTwistingObserver(plant.system, L=200.0),
           "model": SuperTwistingObserver(plant.system, L=5.0, model=True)}
    traj = simulate(plant, SensorChain([GaussianNoise(std=1e-4)], seed=0), obs,
                    Multisine([0.3, 0.1], [0.4, 1.3]), 4.0, x0=[0.5, 0.0], seed=0)
    win = traj.t >= 1.0
    rms = {k: np.sqrt(np.mean(traj.error(k)[win] ** 2, axis=0)) for k in obs}
    span = np.ptp(traj.x[win, 1])
    assert span > 2.0
    for k in obs:
        assert rms[k][0] < 2e-3 and rms[k][1] < 0.1 * span, (k, rms[k])
    assert rms["model"][1] < rms["free"][1]


def test_a_dropout_integrates_without_correction():
    ob = SuperTwistingObserver(L=100.0, z_hat0=[1.0, 2.0])
    np.testing.assert_allclose(ob.update([np.nan], np.zeros(0), 0.1), [1.2, 2.0])
    assert ob.dropouts_ == 1
    ob = make_observer("super_twisting", Pendulum(), model=True, z_hat0=[0.5, 0.0])
    x = ob.update([np.nan], [0.0], 0.01)
    np.testing.assert_allclose(x, [0.5, 0.01 * Pendulum().phi([0.5, 0.0], [0.0])])


def test_members_with_their_own_L():
    ob = SuperTwistingObserver(L=10.0)
    p = ob.parameters(2, L=[10.0, 1000.0])
    _, rows = ob.step(p, ob.init(2, params=p), np.full((2, 1, 1), 0.04), np.zeros((2, 1, 0)),
                      0.01)
    np.testing.assert_allclose(rows.z_hat[:, 0, 1], [0.11, 11.0])  # h lambda2 L


def test_bad_parameters_and_systems_are_refused():
    with pytest.raises(DesignError, match="L must be > 0"):
        SuperTwistingObserver(L=0.0)
    with pytest.raises(DesignError, match="L must be > 0"):
        SuperTwistingObserver().parameters(2, L=[1.0, -1.0])
    with pytest.raises(DesignError, match="lambda2 must be > 0"):
        SuperTwistingObserver(lambda2=-1.0)
    with pytest.raises(DesignError, match="substeps must be a positive integer"):
        SuperTwistingObserver(substeps=0)
    with pytest.raises(DesignError, match="model=True needs a system"):
        SuperTwistingObserver(model=True)
    with pytest.raises(DesignError, match="second-order normal form"):
        SuperTwistingObserver(order=3)
    with pytest.raises(DesignError, match="second-order normal form"):
        SuperTwistingObserver(ElasticJoint())
    assert "second-order normal form" in SuperTwistingObserver.applicability(ElasticJoint())
    assert SuperTwistingObserver.applicability(Pendulum()) is None
    space = SuperTwistingObserver(L=10.0).tuning_space()
    assert space["L"].low == pytest.approx(0.1) and space["L"].high == 1000.0 and space["L"].log
