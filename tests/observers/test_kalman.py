"""Extended and unscented Kalman filters (hgo_mj/observers/kalman.py): against the exact Kalman
filter on linear systems, the one Python model path (nothing probed), the MuJoCo
variants, and every validation. (Batch against single runs: tests/observers/test_kalman_batch.py.)"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from hgo_mj.exceptions import DesignError, DimensionError, DivergenceError
from hgo_mj.inputs import Multisine
from hgo_mj.observers import OBSERVERS, _integrate, make_observer
from hgo_mj.observers.kalman import (
    ExtendedKalmanFilter,
    MujocoExtendedKalmanFilter,
    MujocoModel,
    MujocoUnscentedKalmanFilter,
    SystemModel,
    UnscentedKalmanFilter,
)
from hgo_mj.plants import make_plant
from hgo_mj.sensors import Dropout, GaussianNoise, SensorChain
from hgo_mj.simulate import simulate
from hgo_mj.systems import BioreactorBullinger, ElasticJoint, Pendulum
from hgo_mj.systems.base import System

RNG = np.random.default_rng(7)


def linear_system(A, B, C, name="Linear"):
    """A System ``x' = A x + B u``, ``y = C x`` (no parameters)."""
    A, B, C = (np.array(M, dtype=float) for M in (A, B, C))
    n, m, p = A.shape[0], B.shape[1], C.shape[0]

    class Linear(System):
        state_names = tuple(f"x{i}" for i in range(n))
        input_names = tuple(f"u{i}" for i in range(m))
        output_names = tuple(f"y{i}" for i in range(p))
        default_x0 = (0.0,) * n

        @staticmethod
        def dynamics(t, x, u, p_):
            return A @ np.asarray(x, dtype=float) + B @ np.asarray(u, dtype=float)

        @staticmethod
        def output(x, p_):
            return C @ np.asarray(x, dtype=float)

    Linear.__name__ = name
    return Linear(), A, B, C


OSC = ([[0.0, 1.0], [-4.0, -0.4]], [[0.0], [1.0]], [[1.0, 0.0]])
CHAIN6 = (np.diag(np.ones(5), 1) - 0.3 * np.eye(6) + np.diag([-1.0] * 5, -1) * 0.5,
          np.eye(6)[:, [5]], np.eye(6)[[0]])
CHAIN8 = (np.diag(np.ones(7), 1) - 0.3 * np.eye(8) + np.diag([-1.0] * 7, -1) * 0.5,
          np.eye(8)[:, [7]], np.eye(8)[[0]])
OSC2OUT = (OSC[0], OSC[1], [[1.0, 0.0], [0.0, 1.0]])
OSC_MIX = (OSC[0], OSC[1], [[1.0, 0.5]])


def _taylor(M, order):
    out = np.eye(M.shape[0])
    term = np.eye(M.shape[0])
    for k in range(1, order + 1):
        term = term @ M / k
        out = out + term
    return out


def reference_kf(A, B, C, Q, R, x0, P0, ys, us, dt, substeps, method):
    """Textbook discrete Kalman filter of the RK4 (or Euler) discretization, written out."""
    n = A.shape[0]
    h = dt / substeps
    order = 4 if method == "rk4" else 1
    F = _taylor(h * A, order)
    S = h * sum(np.linalg.matrix_power(h * A, k) / math.factorial(k + 1) for k in range(order))
    x, P = x0.copy(), P0.copy()
    out = []
    for y, u in zip(ys, us):
        ok = ~np.isnan(y)
        if ok.any():
            Cm, Rm = C[ok], R[np.ix_(ok, ok)]
            Sy = Cm @ P @ Cm.T + Rm
            K = P @ Cm.T @ np.linalg.inv(Sy)
            x = x + K @ (y[ok] - Cm @ x)
            P = (np.eye(n) - K @ Cm) @ P
        for _ in range(substeps):
            x = F @ x + S @ B @ u
            P = F @ P @ F.T + Q * h
        out.append(x.copy())
    return np.array(out), P


@pytest.mark.parametrize("cls", [ExtendedKalmanFilter, UnscentedKalmanFilter])
@pytest.mark.parametrize("case", ["osc", "chain6", "chain8", "osc2out", "osc_mix"])
@pytest.mark.parametrize("method,substeps", [("rk4", 1), ("rk4", 3), ("euler", 2)])
def test_linear_system_equals_exact_kalman_filter(cls, case, method, substeps):
    """On a linear system both filters *are* the Kalman filter of the RK4 (Euler)
    discretization: diagonal R (osc, chain6, chain8: sequential scalar updates), 2 outputs with
    a full R (the joint Joseph-form update), general output map (osc_mix: finite-difference H
    for the EKF, sigma points for the UKF)."""
    A, B, C = {"osc": OSC, "chain6": CHAIN6, "chain8": CHAIN8, "osc2out": OSC2OUT,
               "osc_mix": OSC_MIX}[case]
    s, A, B, C = linear_system(A, B, C)
    n, p = A.shape[0], C.shape[0]
    Q = np.diag(RNG.uniform(0.01, 0.1, n))
    R = np.diag(RNG.uniform(0.01, 0.05, p))
    if p == 2:
        R[0, 1] = R[1, 0] = 0.005
    P0 = np.eye(n) * 0.5
    x0 = RNG.normal(size=n) * 0.1
    f = cls(s, Q=Q, R=R, P0=P0, x_hat0=x0, method=method, substeps=substeps)
    assert f.model.compiled is None  # a user's system: the one Python model path
    dt = 0.05
    xs = np.zeros(n)
    ys, us, est = [], [], []
    for k in range(80):
        u = np.array([math.sin(0.7 * k * dt)])
        y = C @ xs + RNG.normal(size=p) * 0.1
        if k % 17 == 5:
            y[0] = np.nan
        ys.append(y)
        us.append(u)
        est.append(f.update(y, u, dt))
        xs = xs + dt * (A @ xs + B @ u)
    ref, Pref = reference_kf(A, B, C, Q, R, x0, P0, ys, us, dt, substeps, method)
    tol = 1e-7 if case == "osc_mix" else 1e-10
    np.testing.assert_allclose(np.array(est), ref, rtol=tol, atol=tol)
    np.testing.assert_allclose(f.P_, Pref, rtol=tol, atol=tol)
    assert f.dropouts_ == len([k for k in range(80) if k % 17 == 5])


def test_rk4_substeps_converge_to_the_exact_discretization():
    """With many substeps the time update approaches expm / the continuous Lyapunov integral."""
    from scipy.linalg import expm

    s, A, B, C = linear_system(*OSC)
    Q = np.diag([0.02, 0.05])
    f = ExtendedKalmanFilter(s, Q=Q, R=0.01, P0=0.3, method="rk4", substeps=200)
    dt = 0.2
    f.update(np.array([np.nan]), np.array([0.0]), dt)  # pure prediction
    M = np.block([[-A, Q], [np.zeros((2, 2)), A.T]]) * dt  # Van Loan
    E = expm(M)
    Phi = E[2:, 2:].T
    Qd = Phi @ E[:2, 2:]
    np.testing.assert_allclose(f.P_, Phi @ (0.3 * np.eye(2)) @ Phi.T + Qd, rtol=2e-3)


# ----------------------------------------------------------------------------- validation


def test_validation_messages():
    s = Pendulum()
    with pytest.raises(DesignError,
                       match=r"Q must be positive semi-definite; found eigenvalues \[-1.0, 1.0\]"):
        ExtendedKalmanFilter(s, Q=[[0.0, 1.0], [1.0, 0.0]])
    with pytest.raises(DesignError, match=r"R must be positive definite; found eigenvalues \[0.0\]"):
        ExtendedKalmanFilter(s, R=0.0)
    with pytest.raises(DesignError, match="P0 must be positive definite"):
        UnscentedKalmanFilter(s, P0=[1.0, -1.0])
    with pytest.raises(DesignError, match="P0_theta must be positive definite"):
        ExtendedKalmanFilter(s, estimate=("mass",), theta_hat0=[0.2], P0_theta=0.0)
    with pytest.raises(DesignError, match="Q_theta must be positive semi-definite"):
        ExtendedKalmanFilter(s, estimate=("mass",), theta_hat0=[0.2], Q_theta=-1.0)
    with pytest.raises(DesignError, match="Q must be symmetric"):
        ExtendedKalmanFilter(s, Q=[[1.0, 0.5], [0.0, 1.0]])
    with pytest.raises(DimensionError, match=r"R must be a scalar, a length-1 vector or a 1x1 "
                                              r"matrix; found shape \(2, 2\)"):
        ExtendedKalmanFilter(s, R=np.eye(2))
    with pytest.raises(DesignError,
                       match=r"estimate must name distinct parameters of Pendulum .*found \['length'\]"):
        ExtendedKalmanFilter(s, estimate=("length",), theta_hat0=[1.0])
    with pytest.raises(DesignError, match=r"theta_hat0 is required with estimate=\['mass'\]"):
        ExtendedKalmanFilter(s, estimate=("mass",))
    with pytest.raises(DesignError, match="noise variance, which is 0 for channel"):
        ExtendedKalmanFilter(s, sensor=SensorChain([Dropout(0.1)]))
    with pytest.raises(DesignError, match="method must be one of"):
        UnscentedKalmanFilter(s, method="exact")
    with pytest.raises(DimensionError, match=r"Pendulum has 1 output\(s\) \['angle'\]; found "
                                              r"channel 3"):
        ExtendedKalmanFilter(s, outputs=(3,))
    with pytest.raises(DesignError, match="outputs must be a non-empty sequence"):
        ExtendedKalmanFilter(s, outputs=0)
    with pytest.raises(DesignError, match=r"alpha\^2 \(N \+ kappa\) must be > 0"):
        UnscentedKalmanFilter(s, kappa=-5.0)

    class NoJac(System):
        state_names = ("x",)
        input_names = ("u",)
        output_names = ("y",)

        @staticmethod
        def dynamics(t, x, u, p):
            return np.array([-x[0] + u[0]])

        @staticmethod
        def output(x, p):
            return np.array([x[0]])

    with pytest.raises(DesignError, match=r"jacobian='analytic' needs NoJac.jacobian"):
        ExtendedKalmanFilter(NoJac(), jacobian="analytic")
    with pytest.raises(DesignError, match="model= and model_fields= are for the MuJoCo filters"):
        ExtendedKalmanFilter(s, model=object())
    with pytest.raises(DesignError, match="is not a MuJoCo system"):
        MujocoExtendedKalmanFilter(NoJac())
    with pytest.raises(DesignError, match="cannot estimate 'mass'"):
        MujocoExtendedKalmanFilter(s, estimate=("mass",), theta_hat0=[0.3])
    with pytest.raises(DesignError, match="the model has no tendon named 'nope'"):
        MujocoExtendedKalmanFilter(ElasticJoint(), estimate=("tendon_stiffness[nope]",),
                                   theta_hat0=[1.0])
    with pytest.raises(DesignError, match="unexpected keyword|unknown parameter"):
        make_observer("ekf", s, nope=1)


def test_sensor_chain_gives_the_default_R():
    s = Pendulum()
    sensor = SensorChain([GaussianNoise(std=0.01)])
    f = ExtendedKalmanFilter(s, sensor=sensor)
    assert f.R[0, 0] == pytest.approx(1e-4)
    assert UnscentedKalmanFilter(s, sensor=sensor, R=2e-4).R[0, 0] == 2e-4


@pytest.mark.parametrize("system,names", [(Pendulum(), ("mass", "gear", "inertia", "damping",
                                                        "com_distance", "g")),
                                          (ElasticJoint(), ("stiffness", "mass", "gear",
                                                            "link_inertia", "motor_inertia",
                                                            "link_damping", "motor_damping",
                                                            "com_distance", "g"))])
def test_analytic_jacobians_match_finite_differences(system, names):
    a = SystemModel(system, names, "analytic")
    fd = SystemModel(system, names, "fd")
    assert a.analytic and not fd.analytic
    for _ in range(5):
        x = np.concatenate((RNG.normal(size=a.n), [system.params[k] for k in names]))
        u = RNG.normal(size=1)
        np.testing.assert_allclose(a.jac(x[None], u[None])[0], fd.jac(x[None], u[None])[0],
                                   rtol=1e-6, atol=1e-5)


def _run(f, ys, us, dt):
    return np.array([f.update(y, u, dt) for y, u in zip(ys, us)])


@pytest.mark.parametrize("cls", [ExtendedKalmanFilter, UnscentedKalmanFilter])
def test_one_python_model_path_nothing_probed(cls):
    """A system without a compiled model has one model path, chosen by what it declares: the
    filter's construction calls its ``dynamics`` not once (no probing), and the RK4 (Euler)
    step of a batch is :func:`hgo_mj.observers._integrate.rk4` (``euler``) of its rows, bit
    for bit, with the estimated parameter read from each row."""
    s, A, B, _ = linear_system(*OSC)
    calls = []
    dyn = type(s).dynamics

    def counted(t, x, u, p_):
        calls.append(np.shape(x))
        return dyn(t, x, u, p_)

    type(s).dynamics = staticmethod(counted)
    f = cls(s, R=1e-3)
    assert f.model.compiled is None and calls == []
    rng = np.random.default_rng(3)
    X, U = rng.normal(size=(5, 2)), rng.normal(size=(5, 1))
    for method, scheme in (("rk4", _integrate.rk4), ("euler", _integrate.euler)):
        want = scheme(lambda Z: np.array([A @ z + B @ u for z, u in zip(Z, U)]), X, 0.05)
        np.testing.assert_array_equal(f.model.step(X, U, 0.05, method), want)
    assert all(shape == (2,) for shape in calls)  # one row per call
    b = BioreactorBullinger()  # an augmented parameter read from each row
    m = ExtendedKalmanFilter(b, estimate=("a1",), theta_hat0=[0.8]).model
    m.compiled = None
    Xa = np.array([[0.9, 0.4, 0.8], [0.7, 0.3, 1.1]])
    Ua = np.array([[0.1], [0.2]])
    got = m.step(Xa, Ua, 0.5, "rk4")
    for r in range(2):
        p = dict(b.params, a1=Xa[r, 2])
        one = _integrate.rk4(lambda z, u=Ua[r], p=p: np.asarray(b.dynamics(0.0, z[0], u, p))[None],
                             Xa[r:r + 1, :2], 0.5)
        np.testing.assert_array_equal(got[r, :2], one[0])
    np.testing.assert_array_equal(got[:, 2], Xa[:, 2])


@pytest.mark.parametrize("cls", [ExtendedKalmanFilter, UnscentedKalmanFilter,
                                 MujocoExtendedKalmanFilter, MujocoUnscentedKalmanFilter])
def test_nan_is_a_prediction_and_counted(cls):
    s = Pendulum()
    a = cls(s, x_hat0=[0.3, 0.0], P0=1e-8)
    b = cls(s, x_hat0=[0.3, 0.0], P0=1e-8)
    u = np.array([0.1])
    xa = a.update(np.array([np.nan]), u, 0.002)
    assert a.dropouts_ == 1 and a.diagnostics()["dropouts"] == 1.0
    # no correction: the estimate is the model's prediction from x_hat0 (for the UKF the
    # sigma-point mean, equal to it up to the curvature over the spread of P0 = 1e-8)
    np.testing.assert_allclose(xa, a.model.step(np.array([[0.3, 0.0]]), u[None], 0.002, "rk4")[0],
                               rtol=1e-12, atol=1e-12 if "Unscented" not in cls.__name__ else 1e-9)
    b.update(np.array([0.3]), u, 0.002)
    assert b.dropouts_ == 0
    assert a.P_[0, 0] > b.P_[0, 0]  # the measurement was not used
    with pytest.raises(DivergenceError, match=r"measurement y\[0\] is inf"):
        a.update(np.array([np.inf]), u, 0.002)


def test_pendulum_parameters_by_augmentation():
    plant = make_plant("pendulum", 0.001)
    s = plant.system
    sensor = SensorChain([GaussianNoise(std=1e-4)], seed=1)
    kw = dict(sensor=sensor, Q=[1e-8, 1e-2], Q_theta=1e-6, x_hat0=[0.0, 0.0])
    obs = {"ekf": ExtendedKalmanFilter(s, estimate=("mass", "gear"), theta_hat0=[0.0, 0.0],
                                       P0_theta=[1, 100], **kw),
           "ukf": UnscentedKalmanFilter(s, estimate=("mass", "gear"), theta_hat0=[0.0, 0.0],
                                        P0_theta=[1, 100], **kw),
           "ekf_mj": MujocoExtendedKalmanFilter(s, estimate=("g", "gear"), theta_hat0=[5.0, 0.5],
                                                P0_theta=[25, 1], model=plant, **kw)}
    traj = simulate(plant, sensor, obs, Multisine([0.3, 0.2, 0.1], [0.3, 0.7, 1.9]), 10.0, seed=3)
    for name in ("ekf", "ukf"):
        d = traj.observers[name].diagnostics
        assert d["theta_mass"][-1] == pytest.approx(0.25, rel=5e-3)
        assert d["theta_gear"][-1] == pytest.approx(1.0, rel=5e-3)
    d = traj.observers["ekf_mj"].diagnostics
    assert d["theta_g"][-1] == pytest.approx(9.81, rel=5e-3)
    assert d["theta_gear"][-1] == pytest.approx(1.0, rel=5e-3)


def test_mujoco_transition_matches_finite_differences_of_the_step():
    """mjd_transitionFD (on the Euler twin of the RK4 model, converted to RK4's transition)
    against central differences of the RK4 step itself, permuted into the system's state
    order; the twin's raw matrix differs by the O(h^2) terms where semi-implicit Euler and
    RK4 differ (h^2 K / J = 2.6e-3 here)."""
    s = ElasticJoint()
    a = MujocoModel(s, estimate=("stiffness",), jacobian="transition_fd")
    b = MujocoModel(s, estimate=("stiffness",), jacobian="fd")
    x = np.array([0.3, 0.25, 0.5, -0.4, 10.0])
    u = np.array([0.2])
    xa, Pa = (v[0] for v in a.transition(x[None], u[None], 0.001))
    xb, Pb = (v[0] for v in b.transition(x[None], u[None], 0.001))
    np.testing.assert_array_equal(xa, xb)
    np.testing.assert_allclose(Pa, Pb, rtol=0, atol=1e-5)
    a._load(a.dt_, x[:4], u)
    raw = np.zeros((4, 4))
    mujoco.mjd_transitionFD(a.twin, a.dt_, 1e-6, False, raw, None, None, None)
    assert np.abs(raw[a._pix] - Pb[:4, :4]).max() > 1e-3  # why the conversion is needed
    assert Pa[0, 2] == pytest.approx(1e-3, rel=1e-2)  # d link angle / d link velocity
    assert a.get_params()[0] == 10.0
    # the mean is MuJoCo's step: equal to the plant's
    plant = make_plant("elastic_joint", 0.001)
    plant.reset(x[:4])
    plant.step(u)
    np.testing.assert_allclose(xa[:4], plant.state, rtol=0, atol=1e-15)
    with pytest.raises(DesignError, match="must be a multiple of the model timestep"):
        a.step(x[None], u[None], 0.0015)
    f = MujocoExtendedKalmanFilter(s, substeps=2)
    f.check_period(0.002)
    with pytest.raises(DesignError, match=r"step 0.00075 must be a multiple of the model timestep 0.001"):
        f.check_period(0.0015)
    with pytest.raises(mujoco.FatalError, match="RK4 integrator is not supported"):
        m = a.m
        mujoco.mjd_transitionFD(m, a.d, 1e-6, False, np.zeros((4, 4)), None, None, None)


def test_registry():
    for name, cls in (("ekf", ExtendedKalmanFilter), ("ukf", UnscentedKalmanFilter),
                      ("ekf_mujoco", MujocoExtendedKalmanFilter),
                      ("ukf_mujoco", MujocoUnscentedKalmanFilter)):
        assert OBSERVERS[name] is cls
        f = make_observer(name, Pendulum())
        d = f.diagnostics()
        assert f.x_hat.shape == (2,) and list(d) == ["nis", "dropouts"]
        assert math.isnan(d["nis"]) and d["dropouts"] == 0.0  # no update yet


def _filterpy_pendulum_ekf(R: float, dt: float):
    """filterpy's ExtendedKalmanFilter on the pendulum as our Euler EKF runs it (x0 = (0.2, 0),
    P0 = 0.1 I, Q = 1e-4 per second, measurement H = [1, 0]); ``F`` is set before each
    ``predict``. Returns the filter and H."""
    fp = pytest.importorskip("filterpy.kalman")
    s = Pendulum()
    p = s.params

    class EKF(fp.ExtendedKalmanFilter):
        def predict_x(self, u=0):
            self.x = self.x + dt * s.dynamics(0, self.x, u, p)

    ref = EKF(2, 1)
    ref.x = np.array([0.2, 0.0])
    ref.P = np.eye(2) * 0.1
    ref.R = np.array([[R]])
    ref.Q = np.eye(2) * 1e-4 * dt
    return ref, np.array([[1.0, 0.0]])


def test_filterpy_side_by_side():
    """The same Euler EKF as filterpy's ExtendedKalmanFilter (predict with F = I + h J,
    update with H = [1, 0]) gives the same estimates."""
    s, p, dt = Pendulum(), Pendulum().params, 1e-3
    ours = ExtendedKalmanFilter(s, Q=1e-4, R=1e-6, P0=0.1, x_hat0=[0.2, 0.0], method="euler")
    ref, H = _filterpy_pendulum_ekf(R=1e-6, dt=dt)
    for k in range(300):
        u = np.array([0.2 * math.sin(k * dt * 4)])
        y = np.array([0.2 + 0.05 * math.sin(k * dt * 7)])
        got = ours.update(y, u, dt)
        ref.update(y, lambda x: H, lambda x: x[:1])
        ref.F = np.eye(2) + dt * s.jacobian(0, ref.x, u, p)
        ref.predict(u)
        np.testing.assert_allclose(got, ref.x, rtol=1e-10, atol=1e-13)


def test_filtered_is_the_measurement_update_and_leaves_the_filter_alone():
    """``filtered(y)`` is x_k|k: filterpy's estimate right after its ``update(y)``, from the
    same Euler EKF; the filter's own state (estimate, covariance) is not moved, so the next
    ``update`` consumes the sample as if ``filtered`` had not been called. The UKF's update
    with a selection output is the same formula; a batch gives its rows; the continuous-time
    observers' current estimate is their ``x_hat``."""
    s, p, dt = Pendulum(), Pendulum().params, 1e-3
    ours = ExtendedKalmanFilter(s, Q=1e-4, R=1e-4, P0=0.1, x_hat0=[0.2, 0.0], method="euler")
    ukf = UnscentedKalmanFilter(s, Q=1e-4, R=1e-4, P0=0.1, x_hat0=[0.2, 0.0], method="euler")
    ref, H = _filterpy_pendulum_ekf(R=1e-4, dt=dt)
    moved = 0.0
    for k in range(100):
        u = np.array([0.2 * math.sin(k * dt * 4)])
        y = np.array([0.25 + 0.05 * math.sin(k * dt * 7)])
        before, P = ours.x_hat.copy(), ours.P_.copy()
        current = ours.filtered(y)
        np.testing.assert_array_equal(ours.x_hat, before)
        np.testing.assert_array_equal(ours.P_, P)
        ref.update(y, lambda x: H, lambda x: x[:1])
        np.testing.assert_allclose(current, ref.x, rtol=1e-10, atol=1e-13)
        Pu, xu = ukf.P_, ukf.x_hat  # the UKF's update with y = x[0]: the Kalman formula
        gain = Pu[:, 0] / (Pu[0, 0] + 1e-4)
        np.testing.assert_allclose(ukf.filtered(y), xu + gain * (y[0] - xu[0]), rtol=1e-9,
                                   atol=1e-12)
        moved = max(moved, float(np.abs(current - before).max()))
        ours.update(y, u, dt)
        ukf.update(y, u, dt)
        ref.F = np.eye(2) + dt * s.jacobian(0, ref.x, u, p)
        ref.predict(u)
    assert moved > 1e-3  # the update did move the estimate
    ours.reset([[0.1, 0.0], [0.3, 0.0]])
    rows = ours.filtered([[0.2], [0.2]])
    assert rows.shape == (2, 2) and rows[0, 0] > 0.1 and rows[1, 0] < 0.3  # toward y
    with pytest.raises(DimensionError, match=r"y must have shape \(2, p\)"):
        ours.filtered([0.2])
    hgo = make_observer("high_gain", s, k=10.0)
    hgo.reset([0.1, 0.0])
    assert not hgo.measurement_update and ours.measurement_update
    np.testing.assert_array_equal(hgo.filtered([0.5]), hgo.x_hat)


def test_mujoco_batch_step_equals_the_row_steps_and_reports_an_unstable_row():
    """Without estimated parameters, the MuJoCo model steps all rows in one MuJoCo batch call:
    the same bits as row by row (the furuta pendulum; the elastic joint, RK4), an
    unstable row (MuJoCo resets it) is the same DivergenceError naming the row, and the model
    still pickles after the batch was made."""
    import pickle

    rng = np.random.default_rng(3)
    for system in (make_plant("furuta", 0.001).system, ElasticJoint()):
        mm = MujocoModel(system)
        X = rng.uniform(-0.5, 0.5, (6, mm.n))
        U = rng.uniform(-1.0, 1.0, (6, mm.n_inputs))
        rows = np.array([mm._step_row(x, u, 0.002) for x, u in zip(X, U)])
        np.testing.assert_array_equal(mm.step(X, U, 0.002), rows)
        np.testing.assert_array_equal(mm.step(X[:2], U[:2], 0.002), rows[:2])
        X[4, 0] = 1e300
        with pytest.raises(DivergenceError, match=r"MuJoCo reset the filter's model: the row "
                                                  r"\[1e\+300"):
            mm.step(X, U, 0.002)
        again = pickle.loads(pickle.dumps(mm))
        np.testing.assert_array_equal(again.step(X[:2], U[:2], 0.002), rows[:2])


@pytest.mark.parametrize("h", [0.001, 0.002])
def test_mujoco_transition_of_all_rows_equals_the_row_by_row_one(h):
    """The transition without estimated parameters (one batch call for the steps, the RK4
    conversion over all rows) equals the row-by-row computation bit for bit, over one and
    two substeps, on the RK4 models (elastic joint, furuta pendulum) and a semi-implicit
    Euler copy of the elastic joint."""
    rng = np.random.default_rng(8)
    euler = ElasticJoint.load_model()
    euler.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    for system, model in ((ElasticJoint(), None), (make_plant("furuta", 0.001).system, None),
                          (ElasticJoint(), euler)):
        mm = MujocoModel(system, model=model)
        assert mm._rk4 == (model is None)
        X = rng.uniform(-0.5, 0.5, (5, mm.n))
        U = rng.uniform(-1.0, 1.0, (5, mm.n_inputs))
        Xn, Phi = mm.transition(X, U, h)
        rows = [mm._transition_row(x, u, h) for x, u in zip(X, U)]
        np.testing.assert_array_equal(Xn, np.array([r[0] for r in rows]))
        np.testing.assert_array_equal(Phi, np.array([r[1] for r in rows]))
