"""The Kalman filters' batch axis: B = 64 members (different initial estimates, different
measurement streams with NaN dropouts, different inputs) advanced together equal each member run
alone, bit for bit, for every configuration of the family; a block of T samples equals T single
steps; the per-period cache stays bounded."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from observer_cases import advance

from hgo_mj.exceptions import DesignError, DimensionError, DivergenceError
from hgo_mj.observers import make_observer
from hgo_mj.observers.base import Observer
from hgo_mj.systems import BioreactorBullinger, ElasticJoint, ElasticJoint2Link, Pendulum
from hgo_mj.systems.base import System

B = 64
T = 200


class MixedOutput(System):
    """A damped oscillator measured through ``y = x0 + 0.5 x1`` (no system of the package has
    a non-selection output: this one exercises the general measurement updates)."""

    state_names = ("x0", "x1")
    input_names = ("u",)
    output_names = ("y",)

    @staticmethod
    def dynamics(t, x, u, p):
        return np.array([x[1], -4.0 * x[0] - 0.4 * x[1] + u[0]])

    @staticmethod
    def output(x, p):
        return np.array([x[0] + 0.5 * x[1]])


# (id, constructor, dt, initial state, its spread, initial parameters or None, input level)
CASES: list[tuple[Any, ...]] = [
    ("ekf-pendulum-analytic-estimate",
     lambda: make_observer("ekf", Pendulum(), estimate=("mass", "gear"), theta_hat0=[0.2, 0.8],
                           Q=[1e-6, 1e-3], Q_theta=1e-5, R=1e-4), 0.01, [0.3, 0.0], 0.1,
     [0.2, 0.8], (0.0, 0.5)),
    ("ekf-pendulum-euler-fd-substeps",
     lambda: make_observer("ekf", Pendulum(), method="euler", substeps=2, jacobian="fd",
                           R=1e-4), 0.01, [0.3, 0.0], 0.1, None, (0.0, 0.5)),
    ("ekf-bioreactor-estimate",
     lambda: make_observer("ekf", BioreactorBullinger(), estimate=("a1",), theta_hat0=[0.8],
                           Q=[1e-6, 1e-4], Q_theta=1e-5, R=1e-4, P0=1e-4, P0_theta=1e-2),
     0.5, [0.075, 0.03], 0.005, [0.8], (0.08, 0.02)),
    ("ekf-two-link-full-R",
     lambda: make_observer("ekf", ElasticJoint2Link(), R=[[1e-4, 2e-5], [2e-5, 1e-4]]), 0.01,
     [0.3, -0.2, 0.3, -0.2, 0.0, 0.0, 0.0, 0.0], 0.05, None, (0.0, 0.3)),
    ("ekf-general-output",
     lambda: make_observer("ekf", MixedOutput(), R=1e-3), 0.05, [0.1, 0.0], 0.1, None, (0.0, 1.0)),
    ("ukf-pendulum-estimate",
     lambda: make_observer("ukf", Pendulum(), estimate=("g",), theta_hat0=[9.0], R=1e-4), 0.01,
     [0.3, 0.0], 0.1, [9.0], (0.0, 0.5)),
    ("ukf-bioreactor-substeps",
     lambda: make_observer("ukf", BioreactorBullinger(), R=1e-4, P0=1e-4, substeps=2), 0.5,
     [0.075, 0.03], 0.005, None, (0.08, 0.02)),
    ("ukf-elastic-joint-estimate",
     lambda: make_observer("ukf", ElasticJoint(), estimate=("stiffness",), theta_hat0=[90.0],
                           R=1e-4, method="euler"), 0.01, [0.3, 0.25, 0.0, 0.0], 0.05, [90.0],
     (0.0, 0.5)),
    ("ukf-general-output",
     lambda: make_observer("ukf", MixedOutput(), R=1e-3), 0.05, [0.1, 0.0], 0.1, None, (0.0, 1.0)),
    ("ekf_mujoco-pendulum-estimate-damping",
     lambda: make_observer("ekf_mujoco", Pendulum(), estimate=("damping",), theta_hat0=[0.05],
                           R=1e-4), 0.002, [0.3, 0.0], 0.1, [0.05], (0.0, 0.5)),
    ("ekf_mujoco-elastic-joint-fd",
     lambda: make_observer("ekf_mujoco", ElasticJoint(), jacobian="fd", R=1e-4), 0.001,
     [0.3, 0.25, 0.0, 0.0], 0.05, None, (0.0, 0.5)),
    ("ukf_mujoco-pendulum-estimate-g",
     lambda: make_observer("ukf_mujoco", Pendulum(), estimate=("g",), theta_hat0=[9.0],
                           R=1e-4), 0.001, [0.3, 0.0], 0.1, [9.0], (0.0, 0.5)),
]
PARAMS = [pytest.param(*c[1:], id=c[0]) for c in CASES]
ARGS = "make,dt,x0,spread,th0,u_level"


def _streams(ob: Observer, dt: float, x0: list[float], spread: float, u_level: tuple[float, float],
             seed: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """B different measurement streams (every channel of the system, from B true trajectories
    of the system itself with noise) with NaN dropouts (about 8 % of the samples, some losing
    every channel) and B different inputs around ``u_level = (offset, amplitude)``."""
    rng = np.random.default_rng(seed)
    sys_ = ob.system
    assert sys_ is not None
    p, m = len(sys_.output_names), len(sys_.input_names)
    t = np.arange(T) * dt
    U = u_level[0] + u_level[1] * np.cos(3.0 * t[None, :, None] / (T * dt) * 20
                                         + rng.uniform(0, 2 * np.pi, (B, 1, m)))
    Y = np.empty((B, T, p))
    h = dt / 10
    for b in range(B):
        x = np.array(x0) + spread * rng.standard_normal(len(x0))
        for j in range(T):
            Y[b, j] = sys_.output(x, sys_.params)
            for _ in range(10):
                x = x + h * np.asarray(sys_.dynamics(0.0, x, U[b, j], sys_.params))
    Y += 0.01 * np.abs(Y).mean() * rng.standard_normal((B, T, p))
    Y[rng.random((B, T, p)) < 0.06] = np.nan
    Y[rng.random((B, T)) < 0.03] = np.nan
    return Y, U


def _initial(x0, spread, th0, seed=9):
    rng = np.random.default_rng(seed)
    X0 = np.array(x0) + spread * rng.standard_normal((B, len(x0)))
    TH0 = None if th0 is None else np.array(th0) * rng.uniform(0.8, 1.2, (B, len(th0)))
    return X0, TH0


@pytest.mark.parametrize(ARGS, PARAMS)
def test_batch_equals_each_member_alone(make, dt, x0, spread, th0, u_level):
    ob = make()
    Y, U = _streams(ob, dt, x0, spread, u_level)
    X0, TH0 = _initial(x0, spread, th0)
    ob.reset(X0, theta_hat0=TH0)
    assert ob.batch == B
    blk = advance(ob, Y, U, dt)
    assert np.isnan(Y).any(axis=2).sum() > 0 and np.all(np.isfinite(blk.x_hat))
    P = ob.P_
    assert P.shape == (B, ob.N, ob.N) and ob.theta_hat_.shape == (B, ob.q)
    np.testing.assert_array_equal(ob.dropouts_, np.isnan(Y).any(axis=2).sum(axis=1))
    for b in range(B):
        one = make()
        one.reset(X0[b:b + 1], theta_hat0=None if TH0 is None else TH0[b:b + 1])
        r = advance(one, Y[b:b + 1], U[b:b + 1], dt)
        np.testing.assert_array_equal(r.x_hat[0], blk.x_hat[b])
        np.testing.assert_array_equal(r.z_hat[0], blk.z_hat[b])
        np.testing.assert_array_equal(r.diagnostics[0], blk.diagnostics[b])
        np.testing.assert_array_equal(one.P_[0], P[b])


@pytest.mark.parametrize(ARGS, PARAMS)
def test_block_equals_single_steps(make, dt, x0, spread, th0, u_level):
    a, b = make(), make()
    Y, U = _streams(a, dt, x0, spread, u_level, seed=11)
    Y, U = Y[:4, :60], U[:4, :60]
    X0, TH0 = _initial(x0, spread, th0, seed=3)
    a.reset(X0[:4], theta_hat0=None if TH0 is None else TH0[:4])
    b.reset(X0[:4], theta_hat0=None if TH0 is None else TH0[:4])
    blk = advance(a, Y, U, dt)
    for j in range(Y.shape[1]):
        b.update(Y[:, j], U[:, j], dt)
        np.testing.assert_array_equal(b.x_hat, blk.x_hat[:, j])
        np.testing.assert_array_equal(b.theta_hat_, blk.diagnostics[:, j, :a.q])
    np.testing.assert_array_equal(a.P_, b.P_)
    # unbatched: update() is row 0 of a batch of one
    c = make()
    c.reset(X0[0], theta_hat0=None if TH0 is None else TH0[0])
    for j in range(Y.shape[1]):
        got = c.update(Y[0, j], U[0, j], dt)
        assert got.shape == (len(x0),)
    np.testing.assert_array_equal(got, blk.x_hat[0, -1])
    assert c.P_.shape == (a.N, a.N)


def test_period_cache_is_bounded():
    ob = make_observer("ekf", Pendulum(), R=1e-4)
    rng = np.random.default_rng(0)
    for dt in 0.01 + 1e-4 * rng.random(200):
        ob.update([0.1], [0.0], float(dt))
    assert len(ob._qh) <= 8


# the filters of the system-model cases (not the MuJoCo ones, not the general output, whose
# model is Python) run with the system's compiled model; the same filter on the Python model
# (``model.compiled = None``: one dynamics call per member and stage) gives the same bits
COMPILED = [c for c in CASES if not c[0].startswith(("ekf_mujoco", "ukf_mujoco"))
            and "general" not in c[0]]


@pytest.mark.parametrize(ARGS, [pytest.param(*c[1:], id=c[0]) for c in COMPILED])
def test_compiled_model_equals_python_model(make, dt, x0, spread, th0, u_level):
    fast, slow = make(), make()
    assert fast.model.compiled is not None
    slow.model.compiled = None
    Y, U = _streams(fast, dt, x0, spread, u_level, seed=13)
    Y, U = Y[:6, :80], U[:6, :80]
    X0, TH0 = _initial(x0, spread, th0, seed=4)
    for ob in (fast, slow):
        ob.reset(X0[:6], theta_hat0=None if TH0 is None else TH0[:6])
    a, b = advance(fast, Y, U, dt), advance(slow, Y, U, dt)
    np.testing.assert_array_equal(a.x_hat, b.x_hat)
    np.testing.assert_array_equal(a.diagnostics, b.diagnostics)
    np.testing.assert_array_equal(fast.P_, slow.P_)
    X = np.column_stack([X0[:6], TH0[:6]]) if TH0 is not None else X0[:6]
    for name in ("deriv", "jac"):
        np.testing.assert_array_equal(getattr(fast.model, name)(X, U[:, 0]),
                                      getattr(slow.model, name)(X, U[:, 0]))
    np.testing.assert_array_equal(fast.model.step(X, U[:, 0], dt, fast.method),
                                  slow.model.step(X, U[:, 0], dt, fast.method))


@pytest.mark.parametrize("cls", ["ekf", "ukf"])
def test_compiled_model_divergence_is_reported_alike(cls):
    """An estimate that leaves the finite numbers raises the same error, naming the member and
    the sample, from the compiled and the Python model (the state is left at that sample)."""
    errors, states = [], []
    for compiled in (True, False):
        ob = make_observer(cls, BioreactorBullinger(), R=1e-4, P0=1e-4)
        if not compiled:
            ob.model.compiled = None
        ob.reset(np.array([[0.075, 0.03], [1e200, 1e200], [0.075, 0.03]]))
        Y = np.full((3, 40, 1), 0.075)
        # numpy warns of the overflow on the Python model's floats; the kernels do not
        with pytest.raises(DivergenceError) as e, np.errstate(all="ignore"):
            advance(ob, Y, np.full((3, 40, 1), 0.08), 0.5)
        errors.append(str(e.value))
        states.append(ob.state.x.copy())
    assert errors[0] == errors[1] and "member 1" in errors[0]
    np.testing.assert_array_equal(states[0], states[1])


# ---------------------------------------------------------------- per-member parameters
Q2 = [np.diag([1e-6, 1e-3]), np.diag([1e-5, 1e-2]), np.array([[1e-4, 1e-5], [1e-5, 1e-3]])]
Q8 = [1e-4 * np.eye(8), np.diag(np.linspace(1e-5, 1e-3, 8)), 1e-3 * np.eye(8) + 1e-5]
R1 = [np.array([[1e-4]]), np.array([[1e-3]]), np.array([[1e-5]])]
R2 = [np.diag([1e-4, 2e-4]), np.array([[1e-4, 2e-5], [2e-5, 1e-4]]),
      np.array([[1e-3, -1e-4], [-1e-4, 5e-4]])]
QT = [np.array([[1e-5]]), np.array([[1e-6]]), np.array([[1e-4]])]
SIGMA = {"alpha": [1.0, 0.5, 2.0], "beta": [2.0, 0.0, 3.0], "kappa": [0.0, 1.0, -0.5]}

# (id, constructor taking the tuned keywords, dt, initial state, initial parameters, input
# level, three values of each tunable parameter); member 3 repeats member 0's values
TUNED: list[tuple[Any, ...]] = [
    ("ekf-pendulum-estimate",
     lambda **kw: make_observer("ekf", Pendulum(), estimate=("mass",), theta_hat0=[0.2], **kw),
     0.01, [0.3, 0.0], [0.2], (0.0, 0.5), {"Q": Q2, "R": R1, "Q_theta": QT}),
    ("ekf-two-link-diagonal-and-full-R",
     lambda **kw: make_observer("ekf", ElasticJoint2Link(), **kw), 0.01,
     [0.3, -0.2, 0.3, -0.2, 0.0, 0.0, 0.0, 0.0], None, (0.0, 0.3), {"Q": Q8, "R": R2}),
    ("ekf-general-output", lambda **kw: make_observer("ekf", MixedOutput(), **kw), 0.05,
     [0.1, 0.0], None, (0.0, 1.0), {"Q": Q2, "R": R1}),
    ("ukf-pendulum-estimate",
     lambda **kw: make_observer("ukf", Pendulum(), estimate=("g",), theta_hat0=[9.0], **kw),
     0.01, [0.3, 0.0], [9.0], (0.0, 0.5), {"Q": Q2, "R": R1, "Q_theta": QT, **SIGMA}),
    ("ukf-general-output", lambda **kw: make_observer("ukf", MixedOutput(), **kw), 0.05,
     [0.1, 0.0], None, (0.0, 1.0), {"R": R1, **SIGMA}),
    ("ekf_mujoco-pendulum-estimate",
     lambda **kw: make_observer("ekf_mujoco", Pendulum(), estimate=("damping",),
                                theta_hat0=[0.05], **kw),
     0.002, [0.3, 0.0], [0.05], (0.0, 0.5), {"Q": Q2, "R": R1, "Q_theta": QT}),
    ("ukf_mujoco-pendulum", lambda **kw: make_observer("ukf_mujoco", Pendulum(), **kw), 0.002,
     [0.3, 0.0], None, (0.0, 0.5), {"Q": Q2, "R": R1, **SIGMA}),
]


@pytest.mark.parametrize("make,dt,x0,th0,u_level,values",
                         [pytest.param(*c[1:], id=c[0]) for c in TUNED])
def test_members_with_their_own_parameters_equal_single_runs(make, dt, x0, th0, u_level,
                                                             values):
    """Four members, each with its own Q, R (Q_theta; alpha, beta, kappa) (member 3 with
    member 0's), as one batch through the pure step: each equals the filter constructed with
    its values run alone, bit for bit (estimate, parameters, covariance, dropouts, the
    measurement update ``filtered``); the state passed to ``step`` is left as it was."""
    nb, T_ = 4, 60
    ob = make()
    Y, U = _streams(ob, dt, x0, 0.05, u_level, seed=21)
    Y, U = Y[:nb, :T_].copy(), U[:nb, :T_].copy()
    Y[1, 5] = np.nan  # a dropout for sure, besides the random ones
    X0, TH0 = _initial(x0, 0.05, th0, seed=22)
    X0, TH0 = X0[:nb], None if TH0 is None else TH0[:nb]
    per = {k: [*v, v[0]] for k, v in values.items()}
    params = ob.parameters(nb, **per)
    assert set(params.fields) == set(ob.parameter_names) >= set(values)
    assert len(params.groups()) == 3
    state = ob.init(nb, X0, params=params, theta_hat0=TH0)
    before = state.copy()
    new, blk = ob.step(params, state, Y, U, dt)
    for k, v in before.fields.items():
        np.testing.assert_array_equal(state.fields[k], v)
    assert np.isnan(Y).any() and np.all(np.isfinite(blk.x_hat))
    np.testing.assert_array_equal(new.dropouts, np.isnan(Y).any(axis=2).sum(axis=1))
    ob.reset(X0, params=params, theta_hat0=TH0)
    advance(ob, Y[:, :-1], U[:, :-1], dt)
    current = ob.filtered(Y[:, -1])
    for b in range(nb):
        one = make(**{k: v[b] for k, v in per.items()})
        p1 = one.parameters(1)
        for k in values:
            np.testing.assert_array_equal(p1.fields[k][0], params.fields[k][b])
        s1 = one.init(1, X0[b], params=p1, theta_hat0=None if TH0 is None else TH0[b])
        s1, r = one.step(p1, s1, Y[b:b + 1], U[b:b + 1], dt)
        np.testing.assert_array_equal(r.x_hat[0], blk.x_hat[b])
        np.testing.assert_array_equal(r.z_hat[0], blk.z_hat[b])
        np.testing.assert_array_equal(r.diagnostics[0], blk.diagnostics[b])
        np.testing.assert_array_equal(s1.x[0], new.x[b])
        np.testing.assert_array_equal(s1.P[0], new.P[b])
        one.reset(X0[b], theta_hat0=None if TH0 is None else TH0[b])
        advance(one, Y[b:b + 1, :-1], U[b:b + 1, :-1], dt)
        np.testing.assert_array_equal(one.filtered(Y[b, -1]), current[b])
    # the members do differ: a batch with member 0's parameters throughout gives other rows
    same = ob.parameters(nb, **{k: v[0] for k, v in values.items()})
    _, other = ob.step(same, ob.init(nb, X0, params=same, theta_hat0=TH0), Y, U, dt)
    assert not np.array_equal(other.x_hat[1], blk.x_hat[1])
    np.testing.assert_array_equal(other.x_hat[3], blk.x_hat[3])


def test_parameters_refuse_what_the_constructor_refuses():
    ekf = make_observer("ekf", Pendulum(), estimate=("mass",), theta_hat0=[0.2], R=1e-4)
    ukf = make_observer("ukf", Pendulum(), R=1e-4)
    assert ekf.parameter_names == ("Q", "R", "Q_theta")
    assert ukf.parameter_names == ("Q", "R", "alpha", "beta", "kappa")
    p = ekf.parameters(1)
    assert p.Q.shape == (1, 2, 2) and p.R.shape == (1, 1, 1) and p.Q_theta.shape == (1, 1, 1)
    np.testing.assert_array_equal(p.Q[0], 1e-4 * np.eye(2))  # the constructor's scalar, as used
    good = [[[1e-4]], [[1e-4]], [[1e-4]]]
    with pytest.raises(DesignError, match=r"R must be positive definite; found eigenvalues \[0.0\]"):
        ekf.parameters(3, R=[[[1e-4]], [[0.0]], [[1e-4]]])
    with pytest.raises(DesignError, match=r"Q must be positive semi-definite; found eigenvalues "
                                          r"\[-1.0, 1.0\]"):
        ekf.parameters(3, Q=[np.eye(2), [[0.0, 1.0], [1.0, 0.0]], np.eye(2)], R=good)
    with pytest.raises(DesignError, match="Q must be symmetric"):
        ekf.parameters(2, Q=[[[1.0, 0.5], [0.0, 1.0]], np.eye(2)])
    with pytest.raises(DesignError, match="Q_theta must be positive semi-definite"):
        ekf.parameters(2, Q_theta=[[[1e-5]], [[-1.0]]])
    with pytest.raises(DimensionError, match=r"Q must be a scalar, a length-2 vector or a 2x2 "
                                             r"matrix; found shape \(3, 3\)"):
        ekf.parameters(2, Q=np.eye(3))
    with pytest.raises(DesignError, match=r"alpha\^2 \(N \+ kappa\) must be > 0"):
        ukf.parameters(3, kappa=[0.0, -5.0, 1.0])
    with pytest.raises(DesignError, match="alpha must be"):
        ukf.parameters(2, alpha=[1.0, 0.0])
    with pytest.raises(DesignError, match="beta must be"):
        ukf.parameters(2, beta=[1.0, np.inf])
    with pytest.raises(DesignError, match=r"unknown parameter\(s\) \['Q_theta'\]"):
        ukf.parameters(2, Q_theta=1e-6)


@pytest.mark.parametrize("method", ["rk4", "euler"])
@pytest.mark.parametrize("jacobian", ["analytic", "fd"])
def test_each_switch_pair_compiles_its_own_loop_and_equals_the_python_model(method, jacobian):
    """The EKF's block kernel takes RK4/Euler and analytic/differences as a type (one class
    per pair), so a filter compiles the one loop it runs (issue 28: the four were compiled
    for every system); each pair gives the Python model's bits."""
    from hgo_mj.observers import kalman

    fast, slow = (make_observer("ekf", Pendulum(), R=1e-4, method=method, jacobian=jacobian,
                                estimate=["damping"], theta_hat0=[0.05]) for _ in range(2))
    slow.model.compiled = None
    rng = np.random.default_rng(5)
    Y = 0.2 + 0.01 * rng.standard_normal((3, 30, 1))
    U = 0.1 * rng.standard_normal((3, 30, 1))
    for ob in (fast, slow):
        ob.reset(np.array([[0.2, 0.0], [0.1, 0.1], [0.3, -0.1]]))
    a, b = advance(fast, Y, U, 0.01), advance(slow, Y, U, 0.01)
    np.testing.assert_array_equal(a.x_hat, b.x_hat)
    np.testing.assert_array_equal(fast.P_, slow.P_)
    X = np.array([[0.2, 0.0, 0.05], [0.1, 0.1, 0.04]])
    for m in ("rk4", "euler"):  # the model's kernels: the flag they read, constant
        np.testing.assert_array_equal(fast.model.step(X, U[:2, 0], 0.01, m),
                                      slow.model.step(X, U[:2, 0], 0.01, m))
    np.testing.assert_array_equal(fast.model.jac(X, U[:2, 0]), slow.model.jac(X, U[:2, 0]))
    want = type(kalman._ekf_switches(method == "rk4", jacobian == "analytic"))
    assert want.rk4 == (method == "rk4") and want.analytic == (jacobian == "analytic")
    switches = {getattr(sig[11], "instance_class", None) for sig in kalman._ekf_block.signatures
                if getattr(sig[0], "instance_class", None) is type(Pendulum.compiled)}
    assert want in switches and None not in switches
