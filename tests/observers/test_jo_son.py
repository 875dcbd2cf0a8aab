"""The Jo-Son adaptive observer (paper 003, eq. 27) and its canonical form eq. 10."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hgo_mj.exceptions import DesignError, DimensionError, DivergenceError
from hgo_mj.inputs import Multisine
from hgo_mj.observers import JoSonForm, JoSonObserver, make_observer
from hgo_mj.observers.jo_son import jo_son_gain
from hgo_mj.plants import make_plant
from hgo_mj.plants.ode import OdePlant
from hgo_mj.simulate import simulate
from hgo_mj.systems import ElasticJoint, Pendulum
from hgo_mj.systems.elastic_joint import jo_son_motor_side
from hgo_mj.systems.papers import JoSonExample, jo_son_input


def _observer(**kw):
    kw = {"lam": 2.0, "gamma": 5.0, **kw}
    return JoSonObserver(JoSonExample(), **kw)


# ------------------------------------------------------------------ gain, eq. 25-26
def test_gain_of_the_example_is_2lambda_2_plus_lambda():
    for lam in (0.5, 2.0, 7.0):
        np.testing.assert_allclose(jo_son_gain([2.0, 1.0], lam), [2 * lam, 2 + lam])


@pytest.mark.parametrize("b", [[2.0, 1.0], [6.0, 5.0, 1.0], [1.0, 3.0, 3.0, 2.0], [4.0]])
def test_eq_26_and_the_spr_transfer_function(b):
    """b_r (s^r + k_r s^(r-1) + ... + k_1) = (s + lambda)(b_r s^(r-1) + ... + b_1), and
    C_o (sI - A_o + K C_o)^-1 b = b_r / (s + lambda) (the paper prints (sI - A_o)^-1)."""
    b = np.array(b)
    r, lam = b.size, 1.7
    K = jo_son_gain(b, lam)
    A = np.diag(np.ones(r - 1), -1)  # A_o: lower shift
    C = np.zeros(r)
    C[-1] = 1.0
    Acl = A - np.outer(K, C)
    char = np.poly(Acl)  # s^r + k_r s^(r-1) + ... + k_1
    np.testing.assert_allclose(b[-1] * char, np.polymul([1.0, lam], b[::-1]), rtol=1e-10, atol=1e-10)
    for w in (0.0, 0.3, 2.0, 50.0):
        H = C @ np.linalg.solve(1j * w * np.eye(r) - Acl, b)
        assert H == pytest.approx(b[-1] / (1j * w + lam), rel=1e-10)
        assert H.real > 0


@pytest.mark.parametrize("b, match", [
    ([2.0, 0.0], r"b_r > 0 \(the parameters must reach y = z_r with relative degree one.*found "
                 r"b_r = 0"),
    ([2.0, -1.0], "needs b_r > 0.*found b_r = -1"),
    ([-2.0, 1.0], r"b_r s\^\(r-1\) \+ \.\.\. \+ b_1 Hurwitz.*roots \[2"),
    ([1.0, 0.0, 1.0], r"Hurwitz.*roots \[.*j.*\] with non-negative real part"),
])
def test_corollary_3_3_conditions(b, match):
    with pytest.raises(DesignError, match=match):
        jo_son_gain(b, 2.0)
    form = JoSonForm(b, lambda y, u: np.zeros(len(b)), lambda y, u: (y,), n_params=1)
    with pytest.raises(DesignError, match=match):
        JoSonObserver(form=form)


def test_lambda_must_be_positive():
    with pytest.raises(DesignError, match="Corollary 3.3 needs lambda > 0; found lambda = 0"):
        _observer(lam=0.0)
    with pytest.raises(DesignError, match="lambda must be finite"):
        _observer(lam=float("nan"))


# ------------------------------------------------------------------ the example's form
def test_example_form_is_eq_31():
    """A_o z + gamma_o + b beta theta and f_obar + gamma_obar reproduce eq. 31 (canonical_rhs)."""
    rng = np.random.default_rng(0)
    form = JoSonExample().form("jo_son")
    for theta in (0.0, 1.0, -0.7):
        sys_ = JoSonExample(theta=theta)
        for _ in range(20):
            z, u = rng.uniform(-1.5, 1.5, 3), rng.uniform(-1, 1, 1)
            y = z[1]
            go, be = np.array(form.gamma_o(y, u)), np.array(form.beta(y, u))
            zo = np.array([0.0, z[0]]) + go + form.b * (be @ [theta])
            zb = np.array(form.f_obar(y, z[2:])) + np.array(form.gamma_obar(y, u))
            np.testing.assert_allclose(np.concatenate((zo, zb)), sys_.canonical_rhs(z, u), atol=1e-12)
            x = sys_.from_canonical(z)
            np.testing.assert_allclose(form.to_physical(z), x, atol=1e-14)
            np.testing.assert_allclose(form.from_physical(x), z, atol=1e-14)


def test_form_functions_work_on_rows_component_first():
    """The same functions serve one point and N members (rows, component first)."""
    rng = np.random.default_rng(1)
    form = JoSonExample().form("jo_son")
    Z, U = rng.uniform(-1.5, 1.5, (7, 3)), rng.uniform(-1, 1, (7, 1))
    go, be, gb = form.signals(Z[:, 1], U)
    assert go.shape == (7, 2) and be.shape == (7, 1) and gb.shape == (7, 1)
    for i in range(7):
        np.testing.assert_allclose(go[i], form.gamma_o(Z[i, 1], U[i]), rtol=1e-15)
        np.testing.assert_allclose(be[i], form.beta(Z[i, 1], U[i]), rtol=1e-15)
    np.testing.assert_allclose(form.physical_rows(Z), [form.to_physical(z) for z in Z], rtol=1e-15)
    np.testing.assert_allclose(form.normal_rows(form.physical_rows(Z)), Z, atol=1e-14)
    assert JoSonExample().form("jo_son").label == form.label


def test_forms_are_declared_by_the_systems():
    assert "jo_son" in JoSonExample.forms and "jo_son" in ElasticJoint.forms
    assert JoSonForm is __import__("hgo_mj.systems.jo_son_form", fromlist=["JoSonForm"]).JoSonForm
    form = ElasticJoint().form("jo_son", sensors="motor_side")
    assert form.theta_names == jo_son_motor_side().theta_names


def test_observer_rhs_is_eq_27_with_z_hat1():
    """The second line uses z_hat1 (the paper prints z1): with a wrong z1 the paper's literal
    equation would differ; ours depends on the estimate only."""
    ob = _observer()
    s = [0.3, -0.2, 0.1, 0.5]  # z_hat1, z_hat2, z_hat3, theta_hat
    y, u = 0.4, np.array([0.7])
    d = ob.rhs(np.array([s]), np.array([y]), u[None])[0]
    e = y - s[1]
    K = ob.K_
    assert d[0] == pytest.approx(-y ** 5 + (y * np.sin(y) + y * y) * 0.7 + 2 * s[3] * y * 0.7 + K[0] * e)
    assert d[1] == pytest.approx(s[0] - 4 / 3 * y ** 3 + 0.7 + s[3] * y * 0.7 + K[1] * e)
    c = s[2] + 0.5 * y * y
    assert d[2] == pytest.approx(-s[2] - c ** 3 - 0.5 * y * y + y ** 4)
    assert d[3] == pytest.approx(5.0 * y * 0.7 * e)


def test_true_start_stays_exact_in_continuous_time():
    """Started on the true state and parameter, the observer reproduces the plant (e = 0 is
    an equilibrium of the error dynamics)."""
    sys_ = JoSonExample()
    ob = _observer(x_hat0=sys_.default_x0, theta_hat0=[1.0])

    def f(t, s):
        x = s[:3]
        u = jo_son_input(t)
        return np.concatenate((sys_.dynamics(t, x, u, sys_.params), ob.rhs(s[None, 3:], x[:1], u[None])[0]))

    s0 = np.concatenate((sys_.default_x0, ob.z_hat, ob.theta_hat_))
    sol = solve_ivp(f, (0, 10), s0, method="DOP853", rtol=1e-11, atol=1e-13)
    x_hat = ob.form.to_physical(sol.y[3:6, -1])
    np.testing.assert_allclose(x_hat, sol.y[:3, -1], atol=1e-8)
    assert sol.y[6, -1] == pytest.approx(1.0, abs=1e-8)


def test_sampled_run_converges_and_is_deterministic():
    sys_ = JoSonExample()
    ob = make_observer("jo_son", sys_, lam=2.0, gamma=5.0)
    tr = simulate(OdePlant(sys_, 0.002), None, {"js": ob}, jo_son_input, 30.0)
    e = np.linalg.norm(tr.x - tr.observers["js"].x_hat, axis=1)
    assert e[0] > 1.0 and np.max(e[tr.t > 20]) < 5e-3
    assert tr.observers["js"].diagnostics["theta_theta"][-1] == pytest.approx(1.0, abs=5e-3)
    assert set(tr.observers["js"].diagnostics) == {"theta_theta", "excitation", "dropouts"}
    tr2 = simulate(OdePlant(sys_, 0.002), None, {"js": ob}, jo_son_input, 30.0)
    np.testing.assert_array_equal(tr.observers["js"].x_hat, tr2.observers["js"].x_hat)


def test_dropout_holds_the_prediction_and_counts():
    ob = _observer()
    u = np.array([0.5])
    ob.update(np.array([0.4]), u, 0.01)
    th = ob.theta_hat_
    z = ob.z_hat
    ob.update(np.array([np.nan]), u, 0.01)
    assert ob.dropouts_ == 1 and ob.diagnostics()["dropouts"] == 1.0
    np.testing.assert_array_equal(ob.theta_hat_, th)
    # open loop: the chain driven by the signals at the predicted output z_hat2
    sol = solve_ivp(lambda t, s: ob.rhs(s[None], z[1:2], u[None], c=0.0)[0], (0, 0.01),
                    np.concatenate((z, th)), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(ob.z_hat, sol.y[:3, -1], rtol=1e-8, atol=1e-10)
    with pytest.raises(DivergenceError, match=r"measurement y\[0\] is -inf"):
        ob.update(np.array([-np.inf]), u, 0.01)


def test_lost_auxiliary_output_holds_only_the_auxiliary_channels():
    ob = JoSonObserver(form=jo_son_motor_side(), lam=50.0, gamma=(1e4, 20.0, 1e6))
    seen = []
    signals = ob.signals
    ob.signals = lambda y, u: (seen.append(np.array(u)), signals(y, u))[1]
    ob.update(np.array([0.1, 0.3, 0.2]), np.array([0.5]), 0.001)
    ob.update(np.array([0.1, np.nan, 0.25]), np.array([0.7]), 0.001)
    assert ob.dropouts_ == 1
    # the known torque of this sample, the last link angle, the current motor angle
    np.testing.assert_array_equal(seen[-1], [[0.7, 0.3, 0.25]])
    ob.reset()
    ob.update(np.array([0.1, np.nan, np.nan]), np.array([0.7]), 0.001)
    np.testing.assert_array_equal(seen[-1], [[0.7, 0.0, 0.0]])  # nothing to hold yet
    assert ob.outputs == (0, 1, 2)  # y, then the form's auxiliary channels


def test_reset_where_the_inverse_map_is_undefined_is_refused():
    go = lambda y, u: (0.0,)  # noqa: E731
    be = lambda y, u: (y,)  # noqa: E731
    form = JoSonForm([1.0], go, be, n_params=1, to_physical=lambda z: (1.0 / z[0],))
    ob = JoSonObserver(form=form, lam=1.0, gamma=1.0, z_hat0=[2.0])
    np.testing.assert_allclose(ob.x_hat, [0.5])
    with np.errstate(divide="ignore"):
        with pytest.raises(DesignError, match=r"initial estimate z = \[0.0\] lies where the "
                                              r"inverse map T\^-1 .* is undefined \(it gives "
                                              r"\[inf\]\)"):
            ob.reset(z_hat0=np.zeros(1))
        with pytest.raises(DesignError, match="inverse map"):
            JoSonObserver(form=form, lam=1.0, gamma=1.0, z_hat0=np.zeros(1))
        with pytest.raises(DesignError, match=r"z = \[0.0\] \(member 2\) lies where the inverse"):
            ob.reset(z_hat0=[[1.0], [2.0], [0.0]])
    # later, where the map is undefined, x_hat holds its last value and the failure is counted
    ob.reset(z_hat0=[1.0])
    with np.errstate(all="ignore"):
        blk = ob.run(np.zeros((3, 1)), np.zeros((3, 1)), 0.5, x_hat0=None)
    assert ob.inverse_failures_ == 0 and np.all(np.isfinite(blk.x_hat))


def test_check_period():
    ob = _observer(lam=500.0, method="euler")
    with pytest.raises(DesignError, match=r"euler integration of the Jo-Son observer .* unstable on "
                                          r"its poles \[-500.0, -2.0\].*largest stable step is 0.004"):
        ob.check_period(0.01)
    _observer(lam=2.0).check_period(0.01)
    with pytest.warns(RuntimeWarning, match="unstable"):
        _observer(lam=500.0, method="euler", on_unstable="warn").check_period(0.01)
    _observer(lam=500.0, method="euler", on_unstable="ignore").check_period(0.01)


# ------------------------------------------------------------------ MuJoCo: motor-side sensors
def test_elastic_joint_motor_side_estimates_the_motor_parameters():
    plant = make_plant("elastic_joint", dt=0.001,
                       outputs=("motor_velocity", "link_angle", "motor_angle"))
    p = plant.system.params
    J = p["motor_inertia"]
    truth = np.array([p["gear"] / J, p["motor_damping"] / J, p["stiffness"] / J])
    ob = JoSonObserver(form=jo_son_motor_side(), lam=50.0, gamma=(1e4, 20.0, 1e6))
    u = Multisine([0.3, 0.2, 0.1], [0.5, 2.3, 11.0], [0.0, 1.0, 2.0])
    simulate(plant, None, {"js": ob}, u, 10.0, x0=[0.3, 0.3, 0.0, 0.0])
    rel = (ob.theta_hat_ - truth) / truth
    assert abs(rel[0]) < 0.01 and abs(rel[2]) < 0.02  # b/J and K/J
    assert abs(rel[1]) < 0.5  # the weakly excited damping (O(dt) bias, see the reproduction)


# ------------------------------------------------------------------ bad input
def test_system_without_the_form_is_named():
    with pytest.raises(DesignError, match=r"canonical form of paper 003, eq. 10.*Pendulum provides "
                                          r"none"):
        JoSonObserver(Pendulum.from_mjmodel(make_plant("pendulum").model))
    with pytest.raises(DesignError, match=r"ElasticJoint provides no Jo-Son form.*relative degree "
                                          r">= 2, so b_r = 0.*jo_son_motor_side"):
        make_observer("jo_son", ElasticJoint.from_mjmodel(make_plant("elastic_joint").model))
    with pytest.raises(DesignError, match="needs a system with a derived form or form="):
        JoSonObserver()
    with pytest.raises(DesignError, match="form must be a JoSonForm; found dict"):
        JoSonObserver(form={})


@pytest.mark.parametrize("gamma, exc, match", [
    (0.0, DesignError, r"gamma must be positive definite; found eigenvalues \[0.0\]"),
    (-5.0, DesignError, "positive definite"),
    ([1.0, 2.0], DimensionError, "length m = 1"),
])
def test_gamma_must_be_positive_definite(gamma, exc, match):
    with pytest.raises(exc, match=match):
        _observer(gamma=gamma)


def test_bad_forms_and_shapes():
    go = lambda y, u: (0.0,)  # noqa: E731
    be = lambda y, u: (y,)  # noqa: E731
    with pytest.raises(DimensionError, match="b must have r >= 1 entries; found none"):
        JoSonForm([], go, be, n_params=1)
    with pytest.raises(DesignError, match=r"unobservable part of dimension 1 needs f_obar \(eq. 10\)"):
        JoSonForm([1.0], go, be, n_params=1, n_unobservable=1)
    with pytest.raises(DimensionError, match=r"A_obar_o must have shape \(n-r, r\) = \(1, 1\); found "
                                             r"\(2, 1\)"):
        JoSonForm([1.0], go, be, n_params=1, n_unobservable=1, f_obar=lambda y, z: (-z[0],),
                  A_obar_o=np.zeros((2, 1)))
    with pytest.raises(DesignError, match="give theta_names or n_params"):
        JoSonForm([1.0], go, be)
    with pytest.raises(DesignError, match="beta must be a callable; found float"):
        JoSonForm([1.0], go, 1.0, n_params=1)
    bad = JoSonForm([1.0], go, lambda y, u: (y, u[0]), n_params=1)
    ob = JoSonObserver(form=bad)
    with pytest.raises(DimensionError, match=r"beta\(y, u\) of .* must return 1 values; found 2"):
        ob.update(np.array([1.0]), np.array([0.0]), 0.01)
    ob = JoSonObserver(form=JoSonForm([1.0], go, lambda y, u: (u[1],), n_params=1))
    with pytest.raises(DimensionError, match=r"beta\(y, u\) of adaptive observer canonical form "
                                             r"failed on arguments of shapes \(\(1,\), \(1, 1\)\)"):
        ob.update(np.array([1.0]), np.array([0.0]), 0.01)
    ob = JoSonObserver(form=JoSonForm([1.0], go, lambda y, u: (np.ones(3),), n_params=1))
    with pytest.raises(DimensionError, match=r"components of 1 member\(s\); found shapes \[\(3,\)\]"):
        ob.update(np.array([1.0]), np.array([0.0]), 0.01)
    ob = _observer()
    with pytest.raises(DimensionError, match=r"u must have shape \(1,\); found shape \(0,\)"):
        ob.update(np.array([1.0]), np.array([]), 0.01)
    with pytest.raises(DimensionError, match=r"y must be \(p,\) with channel\(s\) \[0\]"):
        ob.update(np.array([]), np.array([0.0]), 0.01)
    with pytest.raises(DimensionError, match=r"theta_hat0 must have shape \(1,\) or \(1, 1\); "
                                             r"found shape \(2,\)"):
        _observer(theta_hat0=[1.0, 2.0])
    with pytest.raises(DimensionError, match=r"z_hat0 must have shape \(3,\) or \(B, 3\); found "
                                             r"shape \(2,\)"):
        _observer(z_hat0=[1.0, 2.0])
    with pytest.raises(DesignError, match=r"outputs must be a non-empty sequence.*found 0"):
        _observer(outputs=0)
    with pytest.raises(DesignError, match=r"outputs of the Jo-Son observer is the channel of y, a "
                                          r"1-tuple.*found \[0, 1\]"):
        _observer(outputs=(0, 1))
    with pytest.raises(DesignError, match=r"outputs must be distinct channels; found \[1, 1, 2\]"):
        JoSonObserver(form=jo_son_motor_side(), outputs=(1,))
    with pytest.raises(DesignError, match="x_hat0 in physical coordinates needs the form's "
                                          "from_physical"):
        JoSonObserver(form=jo_son_motor_side(), x_hat0=[1.0])
    with pytest.raises(DesignError, match="give x_hat0 or z_hat0, not both"):
        _observer(x_hat0=[0, 0, 0], z_hat0=[0, 0, 0])
    with pytest.raises(DesignError, match=r"jo_son.: unknown parameter\(s\) \[.Lambda.\]; valid:"):
        make_observer("jo_son", JoSonExample(), Lambda=2.0)
    with pytest.raises(DimensionError, match="aux_outputs must name 2 channels"):
        jo_son_motor_side(aux_outputs=(1,))
