"""The extended Luenberger observer (Zeitz 1987): the gain assigns (s + omega)^n to the
linearized error dynamics (checked on eigenvalues, n = 2 and 4), the constant-gain special case,
one Euler step by hand, the MuJoCo pendulum, dropouts, the period check, bad parameters."""

from __future__ import annotations

import numpy as np
import pytest

from hgo_mj.exceptions import DesignError
from hgo_mj.inputs import Multisine
from hgo_mj.observers import ExtendedLuenbergerObserver, make_observer
from hgo_mj.observers.extended_luenberger import phi_and_jacobian, zeitz_gain
from hgo_mj.plants import make_plant
from hgo_mj.sensors import GaussianNoise, SensorChain
from hgo_mj.simulate import simulate
from hgo_mj.systems import ElasticJoint, Pendulum


@pytest.mark.parametrize("n", [2, 3, 4])
def test_the_gain_assigns_the_eigenvalues_of_the_linearized_error(n):
    rng = np.random.default_rng(n)
    a = rng.normal(0.0, 5.0, n)
    w = 7.0
    L = zeitz_gain(a, w)
    A = np.diag(np.ones(n - 1), 1)
    A[-1] += a
    C = np.zeros((1, n))
    C[0, 0] = 1.0
    want = np.poly(np.full(n, -w))
    np.testing.assert_allclose(np.poly(A - np.outer(L, C)), want, rtol=1e-9, atol=1e-6)


def test_without_dependence_on_z_it_is_the_binomial_luenberger_gain():
    np.testing.assert_allclose(zeitz_gain(np.zeros(3), 2.0), [6.0, 12.0, 8.0])


def test_jacobian_of_the_pendulum_phi():
    sys = Pendulum()
    Z = np.array([[0.4, 1.0], [-1.0, 0.0]])
    _, J = phi_and_jacobian(sys, Z, np.zeros((2, 1)))
    p = sys.params
    want0 = -p["mass"] * p["g"] * p["com_distance"] * np.cos(Z[:, 0]) / p["inertia"]
    np.testing.assert_allclose(J[:, 0], want0, rtol=1e-6)
    np.testing.assert_allclose(J[:, 1], -p["damping"] / p["inertia"], rtol=1e-6)



def test_the_compiled_differences_are_numpys_bit_for_bit():
    """The steps ``1e-6 max(1, |z|)``, the rows and the quotient, built by compiled kernels
    into buffers kept over the samples, equal the plain numpy computation exactly (a NaN row
    and a huge one included): the benchmark's scores do not move."""
    sys = ElasticJoint()
    rng = np.random.default_rng(3)
    Z = rng.normal(0.0, 3.0, (6, 4))
    Z[1, 2], Z[4, 0] = np.nan, 1e200
    U = rng.normal(0.0, 1.0, (6, 1))
    step = 1e-6 * np.maximum(1.0, np.abs(Z))
    with np.errstate(all="ignore"):
        W, J = phi_and_jacobian(sys, Z, U)
        want_J = np.empty_like(Z)
        for i in range(4):
            e = np.zeros(4)
            e[i] = 1.0
            plus, minus = sys.phi_batch(Z + step * e, U), sys.phi_batch(Z - step * e, U)
            want_J[:, i] = (plus - minus) / (2.0 * step[:, i])
    np.testing.assert_array_equal(W, sys.phi_batch(Z, U))
    np.testing.assert_array_equal(J, want_J)


def test_one_euler_step_by_hand():
    """Order 2 without a system (phi = 0): L = (2 w, w^2); z = 0, y = 1, h = 0.01, w = 10:
    z+ = h (0 + 20, 100) = (0.2, 1.0)."""
    ob = ExtendedLuenbergerObserver(order=2, omega=10.0)
    np.testing.assert_allclose(ob.update([1.0], np.zeros(0), 0.01), [0.2, 1.0])


def test_converges_on_the_mujoco_pendulum():
    plant = make_plant("pendulum", dt=0.001)
    obs = {"elo": ExtendedLuenbergerObserver(plant.system, omega=30.0)}
    traj = simulate(plant, SensorChain([GaussianNoise(std=1e-4)], seed=0), obs,
                    Multisine([0.3, 0.1], [0.4, 1.3]), 4.0, x0=[1.0, 0.0], seed=0)
    win = traj.t >= 1.0
    rms = np.sqrt(np.mean(traj.error("elo")[win] ** 2, axis=0))
    assert np.ptp(traj.x[win, 1]) > 2.0
    assert rms[0] < 5e-4 and rms[1] < 0.02, rms  # the model is exact here


def test_a_dropout_integrates_the_model_without_correction():
    sys = Pendulum()
    ob = make_observer("extended_luenberger", sys, omega=10.0, x_hat0=[0.5, 0.0])
    x = ob.update([np.nan], [0.0], 0.01)
    np.testing.assert_allclose(x, [0.5, 0.01 * sys.phi([0.5, 0.0], [0.0])])
    assert ob.dropouts_ == 1


def test_the_period_check_names_the_largest_stable_period():
    ob = ExtendedLuenbergerObserver(order=2, omega=100.0)
    ob.check_period(0.019)
    with pytest.raises(DesignError, match="largest stable period is 0.02"):
        ob.check_period(0.03)
    ob2 = ExtendedLuenbergerObserver(order=2, omega=100.0, substeps=4)
    ob2.check_period(0.03)
    with pytest.warns(RuntimeWarning, match="unstable"):
        ExtendedLuenbergerObserver(order=2, omega=100.0, on_unstable="warn").check_period(0.03)
    with pytest.raises(DesignError, match="omega=300"):
        ob.check_period(0.01, ob.parameters(2, omega=[10.0, 300.0]))


def test_bad_parameters_are_refused():
    with pytest.raises(DesignError, match="omega must be > 0"):
        ExtendedLuenbergerObserver(order=2, omega=-1.0)
    with pytest.raises(DesignError, match="omega must be > 0"):
        ExtendedLuenbergerObserver(order=2).parameters(2, omega=[1.0, 0.0])
    with pytest.raises(DesignError, match="substeps must be a positive integer"):
        ExtendedLuenbergerObserver(order=2, substeps=1.5)  # type: ignore[arg-type]
    with pytest.raises(DesignError, match="one output"):
        ExtendedLuenbergerObserver(order=2, outputs=(0, 1))
    assert ExtendedLuenbergerObserver.applicability(ElasticJoint()) is None
    space = ExtendedLuenbergerObserver(order=2, omega=10.0).tuning_space()
    assert (space["omega"].low, space["omega"].high, space["omega"].log) == (1.0, 1000.0, True)
