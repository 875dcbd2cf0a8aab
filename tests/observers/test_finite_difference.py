"""The finite-difference baseline: hand-checked differences (a ramp, a parabola, a sine), the
noise amplification of a backward difference against its analytic variance, the pendulum, NaN
dropouts, and bad parameters refused."""

from __future__ import annotations

import numpy as np
import pytest

from hgo_mj.exceptions import DesignError, DimensionError
from hgo_mj.inputs import Multisine
from hgo_mj.observers import FiniteDifferenceObserver, make_observer
from hgo_mj.observers.finite_difference import filtered_difference_variance
from hgo_mj.plants import make_plant
from hgo_mj.sensors import GaussianNoise, SensorChain
from hgo_mj.simulate import simulate
from hgo_mj.systems import Pendulum


def _run(ob, y, dt):
    return ob.run(np.asarray(y, dtype=float)[:, None], np.zeros((len(y), 0)), dt)


def test_a_ramp_is_differentiated_exactly_and_extrapolated_one_sample():
    dt = 0.01
    t = np.arange(20) * dt
    rows = _run(FiniteDifferenceObserver(order=2, tau=0.0), 0.5 + 3.0 * t, dt)
    # after sample k: z1 = y(t_{k+1}) (y_k + h y'), z2 = y' = 3 from the second sample on
    np.testing.assert_allclose(rows.z_hat[0, 1:, 1], 3.0, rtol=1e-12)
    np.testing.assert_allclose(rows.z_hat[0, 1:, 0], 0.5 + 3.0 * (t[1:] + dt), rtol=1e-12)


def test_repeated_differences_of_a_parabola():
    """y = t^2: d1 = 2 t_k - h (the backward difference), d2 = 2; reported for t_{k+1}:
    z2 = d1 + h d2 = 2 t_{k+1} - h, z3 = 2."""
    dt = 0.01
    t = np.arange(30) * dt
    z = _run(FiniteDifferenceObserver(order=3, tau=0.0), t ** 2, dt).z_hat[0]
    np.testing.assert_allclose(z[2:, 2], 2.0, rtol=1e-9)
    np.testing.assert_allclose(z[2:, 1], 2.0 * (t[2:] + dt) - dt, atol=1e-12)


def test_a_sine_derivative_within_the_filter_lag():
    """y = sin(w t) with tau: the filtered difference lags by about tau + h/2 (a first-order
    filter at w: |d1 - w cos(w (t - lag))| small); tau = 0 within O(h w^2)."""
    dt, w = 1e-3, 2.0
    t = np.arange(4000) * dt
    y = np.sin(w * t)
    z0 = _run(FiniteDifferenceObserver(order=2, tau=0.0), y, dt).z_hat[0]
    truth = w * np.cos(w * (t + dt))
    assert np.max(np.abs(z0[10:, 1] - truth[10:])) < 2 * w * w * dt
    tau = 0.02
    z = _run(FiniteDifferenceObserver(order=2, tau=tau), y, dt).z_hat[0]
    late = t > 10 * tau
    lagged = w * np.cos(w * (t + dt - tau - dt / 2))
    gain = 1.0 / np.sqrt(1.0 + (w * tau) ** 2)  # the filter's amplitude at w
    assert np.max(np.abs(z[late, 1] - gain * lagged[late])) < 5e-3


@pytest.mark.parametrize("tau", [0.0, 0.002, 0.01])
def test_noise_variance_of_the_difference_matches_the_analytic_value(tau):
    """White noise of variance s^2: var(d1) = 2 s^2 (1-a)^2 / ((1+a) h^2), 2 s^2 / h^2 for
    the plain backward difference (tau = 0)."""
    dt, s = 1e-3, 1e-3
    e = np.random.default_rng(0).normal(0.0, s, 200_000)
    z = _run(FiniteDifferenceObserver(order=2, tau=tau), e, dt).z_hat[0, 1000:, 1]
    want = filtered_difference_variance(s * s, tau, dt)
    assert np.var(z) == pytest.approx(want, rel=0.03)
    if tau == 0.0:
        assert want == pytest.approx(2 * s * s / dt ** 2)


def test_converges_on_the_mujoco_pendulum():
    """Encoder noise 1e-4 rad at 1 kHz: the filtered difference tracks the velocity to a few
    percent of its range (the angle to the noise level plus one sample)."""
    plant = make_plant("pendulum", dt=0.001)
    obs = {"fd": FiniteDifferenceObserver(plant.system, tau=0.005),
           "raw": FiniteDifferenceObserver(plant.system, tau=0.0)}
    traj = simulate(plant, SensorChain([GaussianNoise(std=1e-4)], seed=0), obs,
                    Multisine([0.3, 0.1], [0.4, 1.3]), 4.0, seed=0)
    win = traj.t >= 0.5
    err = {k: traj.error(k)[win] for k in obs}
    rms = {k: np.sqrt(np.mean(err[k] ** 2, axis=0)) for k in obs}
    span = np.ptp(traj.x[win, 1])
    assert span > 2.0
    assert rms["fd"][0] < 5e-3 and rms["fd"][1] < 0.05 * span
    assert rms["fd"][1] < rms["raw"][1] / 2  # the filter earns its keep against the noise


def test_a_dropout_predicts_by_the_chain_and_is_counted():
    dt = 0.1
    ob = FiniteDifferenceObserver(order=2, tau=0.0)
    rows = _run(ob, [0.0, 0.1, np.nan, 0.3, 0.4], dt)
    z = rows.z_hat[0]
    np.testing.assert_allclose(z[2], [0.3, 1.0])  # open loop over the dropout
    np.testing.assert_allclose(z[3:, 1], 1.0)  # differenced against the prediction: exact
    assert ob.dropouts_ == 1 and np.all(np.isfinite(z))


def test_physical_estimate_and_parameters_per_member():
    ob = make_observer("finite_difference", Pendulum(), tau=0.01)
    assert ob.state_names == ("angle", "angular_velocity")
    p = ob.parameters(2, tau=[0.0, 0.05])
    s = ob.init(2, [0.1, 0.0], params=p)
    Y = np.linspace(0.1, 0.2, 10)[None, :, None].repeat(2, axis=0)
    _, rows = ob.step(p, s, Y, np.zeros((2, 10, 1)), 0.01)
    assert rows.x_hat[0, -1, 1] > rows.x_hat[1, -1, 1] > 0  # the filter is slower


def test_bad_parameters_are_refused_with_messages():
    with pytest.raises(DesignError, match="tau must be >= 0"):
        FiniteDifferenceObserver(order=2, tau=-1.0)
    with pytest.raises(DesignError, match="tau must be a real number"):
        FiniteDifferenceObserver(order=2, tau="fast")  # type: ignore[arg-type]
    with pytest.raises(DesignError, match="tau must be >= 0"):
        FiniteDifferenceObserver(order=2).parameters(2, tau=[0.1, -0.1])
    with pytest.raises(DesignError, match="one output"):
        FiniteDifferenceObserver(order=2, outputs=(0, 1))
    with pytest.raises(DesignError, match="needs a system or an explicit order"):
        FiniteDifferenceObserver()
    with pytest.raises(DimensionError, match="z_hat0"):
        FiniteDifferenceObserver(order=2, z_hat0=[1.0, 2.0, 3.0])
    space = FiniteDifferenceObserver(order=2).tuning_space()
    assert list(space) == ["tau"] and space["tau"].log and space["tau"].low > 0


def test_applicability_needs_a_single_output_normal_form():
    from hgo_mj.systems import ElasticJoint2Link

    assert FiniteDifferenceObserver.applicability(Pendulum()) is None
    assert "normal form" in FiniteDifferenceObserver.applicability(ElasticJoint2Link())
