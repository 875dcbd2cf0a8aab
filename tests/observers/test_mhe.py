"""The moving-horizon estimator: one window of one sample by hand, the full-information case
equal to the Kalman filter (a linear chain, while the window still holds every sample), the
sampled process noise, the MuJoCo pendulum, dropouts, bad parameters."""

from __future__ import annotations

import numpy as np
import pytest

from hgo_mj.exceptions import DesignError
from hgo_mj.inputs import Multisine
from hgo_mj.observers import MovingHorizonEstimator, make_observer
from hgo_mj.observers.mhe import sampled_noise
from hgo_mj.plants import make_plant
from hgo_mj.sensors import GaussianNoise, SensorChain
from hgo_mj.simulate import simulate
from hgo_mj.systems import Pendulum


def test_a_window_of_one_sample_by_hand():
    """N = 1, prior 0 with P0 = I, r = 1, y = 1: z_k|k = (0.5, 0); prediction with phi = 0
    over h = 0.1: (0.5, 0). Then y = NaN: no measurement term, the prior is predicted."""
    ob = MovingHorizonEstimator(order=2, q=1.0, r=1.0, p0=1.0, horizon=1)
    np.testing.assert_allclose(ob.update([1.0], np.zeros(0), 0.1), [0.5, 0.0])
    np.testing.assert_allclose(ob.update([np.nan], np.zeros(0), 0.1), [0.5, 0.0])
    assert ob.dropouts_ == 1


def test_sampled_noise_of_a_third_order_chain():
    h, q = 0.2, 2.0
    s = np.linspace(0.0, h, 20001)
    v = np.stack([s ** 2 / 2, s, np.ones_like(s)])  # e^{As} B
    want = q * np.trapezoid(v[:, None] * v[None], s, axis=2)
    np.testing.assert_allclose(sampled_noise(3, q, h), want, rtol=1e-6)


def _kalman(ys, dt, n, q, r, p0, z0):
    """The Kalman filter of the sampled chain (phi = 0), its prediction after each sample."""
    Phi = np.array([[dt ** (j - i) / np.prod(range(1, j - i + 1)) if j >= i else 0.0
                     for j in range(n)] for i in range(n)])
    Q = sampled_noise(n, q, dt)
    x, P = np.array(z0, dtype=float), p0 * np.eye(n)
    out = []
    for y in ys:
        if not np.isnan(y):
            K = P[:, 0] / (P[0, 0] + r)
            x = x + K * (y - x[0])
            P = P - np.outer(K, P[0])
        x, P = Phi @ x, Phi @ P @ Phi.T + Q
        out.append(x)
    return np.array(out)


@pytest.mark.parametrize("iterations", [1, 2])
def test_full_information_equals_the_kalman_filter_on_a_linear_chain(iterations):
    """While the window holds every sample since the start, the (linear, unconstrained)
    window problem with the prior z0, P0 is the full-information problem: its last state is
    the Kalman filter's, and Gauss-Newton is exact in one step."""
    dt, N = 0.01, 15
    rng = np.random.default_rng(1)
    ys = np.sin(np.arange(N) * dt * 5) + 1e-3 * rng.standard_normal(N)
    ys[4] = np.nan
    ob = MovingHorizonEstimator(order=3, q=50.0, r=1e-6, p0=2.0, horizon=N,
                                iterations=iterations, z_hat0=[0.1, 0.5, 0.0])
    z = ob.run(ys[:, None], np.zeros((N, 0)), dt).z_hat[0]
    np.testing.assert_allclose(z, _kalman(ys, dt, 3, 50.0, 1e-6, 2.0, [0.1, 0.5, 0.0]),
                               rtol=1e-7, atol=1e-9)


def test_converges_on_the_mujoco_pendulum():
    """1e-4 rad noise at 1 kHz, N = 10. Found: angle 4.1e-5 rad, velocity 5.0e-3 rad/s with
    q = 0.01, p0 = 1e-6; with an uninformative arrival cost (p0 = 1) the velocity is what 10
    samples give, about 1.1e-2 (the fixed-weight arrival cost is the tuning that matters)."""
    plant = make_plant("pendulum", dt=0.001)
    obs = {"mhe": MovingHorizonEstimator(plant.system, q=0.01, r=1e-8, p0=1e-6, horizon=10)}
    traj = simulate(plant, SensorChain([GaussianNoise(std=1e-4)], seed=0), obs,
                    Multisine([0.3, 0.1], [0.4, 1.3]), 3.0, x0=[1.0, 0.0], seed=0)
    win = traj.t >= 0.5
    rms = np.sqrt(np.mean(traj.error("mhe")[win] ** 2, axis=0))
    assert np.ptp(traj.x[win, 1]) > 2.0
    assert rms[0] < 1e-4 and rms[1] < 1e-2, rms


def test_dropouts_in_the_window_and_per_member_weights():
    ob = make_observer("mhe", Pendulum(), horizon=4)
    p = ob.parameters(2, q=[1.0, 100.0])
    Y = np.full((2, 8, 1), 0.2)
    Y[:, 2:5] = np.nan
    _, rows = ob.step(p, ob.init(2, [0.2, 0.0], params=p), Y, np.zeros((2, 8, 1)), 0.01)
    assert np.all(np.isfinite(rows.x_hat))
    assert rows.diagnostics[0, -1, -1] == 3.0
    assert not np.array_equal(rows.x_hat[0], rows.x_hat[1])


def test_bad_parameters_are_refused():
    with pytest.raises(DesignError, match="q must be > 0"):
        MovingHorizonEstimator(order=2, q=0.0)
    with pytest.raises(DesignError, match="r must be > 0"):
        MovingHorizonEstimator(order=2).parameters(2, r=[1.0, -1.0])
    with pytest.raises(DesignError, match="horizon must be a positive integer"):
        MovingHorizonEstimator(order=2, horizon=0)
    with pytest.raises(DesignError, match="iterations must be a positive integer"):
        MovingHorizonEstimator(order=2, iterations=2.0)  # type: ignore[arg-type]
    with pytest.raises(DesignError, match="one output"):
        MovingHorizonEstimator(order=2, outputs=(0, 1))
    space = MovingHorizonEstimator(order=2, q=10.0, p0=1.0).tuning_space()
    assert set(space) == {"q", "p0"} and all(d.log for d in space.values())
    assert space["q"].low == pytest.approx(0.01) and space["q"].high == pytest.approx(1e4)
