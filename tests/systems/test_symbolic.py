"""Any ODE, its normal form derived (hgo_mj.systems.symbolic): the derived forms equal the
hand-written ones, the parser refuses what is not math without evaluating it, and a scenario
file runs an ODE given as text."""

from __future__ import annotations

import builtins

import numpy as np
import pytest
import sympy

from hgo_mj.exceptions import ModelError
from hgo_mj.plants import make_plant
from hgo_mj.systems import CartPendulum, Pendulum
from hgo_mj.systems.symbolic import ode_system

RNG = np.random.default_rng(11)
PENDULUM_F = ["x2", "(gear*u - mass*g*com_distance*sin(x1) - damping*x2)/inertia"]
CART_F = ["x2", "(mass*length*(g*sin(x1) + accel_gain*u*cos(x1)) - damping*x2)/inertia"]


def _hand(name):
    return make_plant(name).system


@pytest.mark.parametrize(("hand_name", "f"), [("pendulum", PENDULUM_F),
                                              ("cart_pendulum", CART_F)])
def test_derived_normal_form_equals_the_hand_written_one(hand_name, f):
    """The pendulum and the cart pendulum (paper 004, eq. 66) from text: Phi, its inverse
    and phi equal the hand-written systems' to 1e-9 at random points."""
    hand = _hand(hand_name)
    assert isinstance(hand, (Pendulum, CartPendulum))
    cls = ode_system(["x1", "x2"], f, "x1", inputs=["u"], params=dict(hand.params),
                     region=[[-3, 3], [-3, 3]])
    derived = cls()
    assert cls.closed_form_inverse and cls.normal_form_order == 2
    assert cls.normal_form_problem is None and cls.rank_problem is None
    rng = np.random.default_rng(7)
    for _ in range(100):
        x, u = rng.uniform(-3, 3, 2), rng.uniform(-2, 2, 1)
        np.testing.assert_allclose(derived.to_normal(x, u), hand.to_normal(x, u), atol=1e-9)
        z = hand.to_normal(x, u)
        np.testing.assert_allclose(derived.from_normal(z, u), hand.from_normal(z, u), atol=1e-9)
        assert derived.phi(z, u) == pytest.approx(hand.phi(z, u), abs=1e-9)
        np.testing.assert_allclose(derived.f(0.0, x, u), hand.f(0.0, x, u), atol=1e-9)
    # the sampled Lipschitz bound of phi in z: max |d phi/d z| over the region
    p = hand.params
    exact = np.hypot(p["mass"] * p["g"] * p.get("com_distance", p.get("length", 0.0)),
                     p["damping"]) / p["inertia"]
    if hand_name == "pendulum":
        assert cls.lipschitz == pytest.approx(exact, rel=0.02)


def test_elastic_joint_with_link_output_n4_round_trips():
    cls = ode_system(["q1", "q2", "w1", "w2"],
                     ["w1", "w2", "-(m*g*l*sin(q1) + k*(q1 - q2))/J1", "(k*(q1 - q2) + u)/J2"],
                     "q1", inputs=["u"], params=dict(m=1.0, g=9.81, l=0.5, k=100.0, J1=0.3,
                                                     J2=0.1), region=[[-1, 1]] * 4)
    s = cls()
    assert cls.normal_form_order == 4 and cls.closed_form_inverse
    rng = np.random.default_rng(1)
    for _ in range(20):
        x, u = rng.uniform(-1, 1, 4), rng.uniform(-1, 1, 1)
        z = s.to_normal(x, u)
        np.testing.assert_allclose(s.from_normal(z, u), x, atol=1e-9)
        # phi = the fourth derivative of the link angle: d/dt of z4 along the dynamics
        J = np.empty((4, 4))
        cls._sym["PhiJ"](x, u, s.param_vector(), J)
        assert s.phi(z, u) == pytest.approx(float(J[3] @ s.f(0.0, x, u)), rel=1e-9, abs=1e-9)


ELASTIC_F = ["ql", "qm", "(-mass*g*com_distance*sin(q) - stiffness*(q - th) - link_damping*ql)"
             "/link_inertia",
             "(stiffness*(q - th) - motor_damping*qm + gear*u)/motor_inertia"]


def test_derived_elastic_joint_with_link_output_equals_the_hand_written_one():
    """n = 4 (Spong's elastic joint, y = link angle): Phi, its inverse, phi and the Jacobians
    the Kalman filters use equal the hand-written ElasticJoint's to 1e-9."""
    hand = _hand("elastic_joint")
    cls = ode_system(["q", "th", "ql", "qm"], ELASTIC_F, "q", inputs=["u"],
                     params=dict(hand.params), region=[[-1, 1]] * 4)
    derived = cls()
    assert cls.normal_form_order == 4 and cls.closed_form_inverse
    rng = np.random.default_rng(3)
    for _ in range(50):
        x, u = rng.uniform(-1, 1, 4), rng.uniform(-1, 1, 1)
        z = hand.to_normal(x, u)
        np.testing.assert_allclose(derived.to_normal(x, u), z, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(derived.from_normal(z, u), hand.from_normal(z, u), atol=1e-9)
        assert derived.phi(z, u) == pytest.approx(hand.phi(z, u), rel=1e-9, abs=1e-9)
        np.testing.assert_allclose(derived.jacobian(0.0, x, u),
                                   hand.jacobian(0.0, x, u, hand.params), atol=1e-9)
    Z = np.array([hand.to_normal(x, [0.2]) for x in rng.uniform(-1, 1, (16, 4))])
    U = np.full((16, 1), 0.2)
    np.testing.assert_allclose(derived.phi_batch(Z, U), hand.phi_batch(Z, U), atol=1e-9)


BULLINGER_F = ["a1*m*s/(a2*m + s) - u*m", "-a3*a1*m*s/(a2*m + s) - u*s + u*a4"]


def test_derived_bullinger_bioreactor_equals_the_hand_written_one():
    """Paper 000's bioreactor (eq. 15, y = m): the input enters m' (relative degree 1 < 2), so
    the derived form is refused by default and, with held_input, is the paper's eq. 16:
    Phi(x, u), its inverse and phi (u' = 0) equal the hand-written ones to 1e-9."""
    hand = _hand("bioreactor_bullinger")
    args = (["m", "s"], BULLINGER_F, "m")
    kw = {"inputs": ["u"], "params": dict(hand.params), "region": [[0.05, 1], [0.0, 1]]}
    refused = ode_system(*args, **kw)
    assert refused.normal_form_problem.startswith("the input enters L_f^1 h (relative degree 1")
    cls = ode_system(*args, **kw, held_input=True)
    assert cls.normal_form_problem is None and "paper 000" in cls.normal_form_note
    assert cls.relative_degree == 1 and cls.closed_form_inverse
    derived = cls()
    rng = np.random.default_rng(5)
    for _ in range(100):
        x = np.array([rng.uniform(0.05, 1.0), rng.uniform(0.0, 1.0)])
        u = rng.uniform(0.0, hand.params["a4"], 1)
        z = hand.to_normal(x, u)
        np.testing.assert_allclose(derived.to_normal(x, u), z, atol=1e-9)
        np.testing.assert_allclose(derived.from_normal(z, u), hand.from_normal(z, u), atol=1e-9)
        assert derived.phi(z, u) == pytest.approx(hand.phi(z, u, 0.0), rel=1e-9, abs=1e-9)
        np.testing.assert_allclose(derived.f(0.0, x, u), hand.f(0.0, x, u), atol=1e-12)


BASTIN_GEVERS_F = ["-(mu_max/(K_m + K_c*z2 + z1)/p2)*z1*z2 - p3*z2 - z1 + u1",
                   "(mu_max/(K_m + K_c*z2 + z1))*z1*z2 - z2 + u2"]


def test_derived_bastin_gevers_bioreactor_agrees_with_its_aocf():
    """Paper 002's bioreactor (eq. 6.1 corrected, y = z1) from text: f equals the hand-written
    model; z2 = y' equals x2 + y theta1 + u1 of the hand-written AOCF (eq. 6.4-6.5); phi = y''
    equals the derivative of y' along the hand-written flow (central difference, 1e-7)."""
    hand = _hand("bioreactor_bastin_gevers")
    cls = ode_system(["z1", "z2"], BASTIN_GEVERS_F, "z1", inputs=["u1", "u2"],
                     params=dict(hand.params), region=[[0.1, 2], [0.1, 2]], held_input=True)
    derived = cls()
    # z1' = z2 is quadratic in z2 for a symbolic K_c (Contois): the inverse is Newton's
    assert cls.relative_degree == 1 and not cls.closed_form_inverse
    rng = np.random.default_rng(9)
    for _ in range(50):
        x, u = rng.uniform(0.1, 2.0, 2), rng.uniform(0.0, 2.0, 2)
        np.testing.assert_allclose(derived.f(0.0, x, u), hand.f(0.0, x, u), atol=1e-12)
        xa, theta = hand.to_aocf(x)
        z = derived.to_normal(x, u)
        assert z[1] == pytest.approx(xa[1] + x[0] * theta[0] + u[0], abs=1e-9)
        np.testing.assert_allclose(derived.from_normal(z, u), x, atol=1e-9)
        h = 1e-5
        fx = hand.f(0.0, x, u)
        ydd = (hand.f(0.0, x + h * fx, u)[0] - hand.f(0.0, x - h * fx, u)[0]) / (2 * h)
        assert derived.phi(z, u) == pytest.approx(ydd, rel=1e-7, abs=1e-7)
    assert derived.inverse_failures == 0


JO_SON_F = ["x2 - x1**3 + u + theta*x1*u",
            "-x1**2*x2 + x1*sin(x1)*u + 2*theta*x1*u - theta*x1**3*u",
            "-x3 - x3**3 + x1*x2 + x1*u + theta*x1**2*u"]


def test_derived_jo_son_example_is_found_not_observable():
    """Paper 003's example (eq. 28) is, as the paper says, not observable from y = x1: the
    derived observability map's Jacobian has rank 2 < 3 everywhere (x3 never reaches y), so
    no high-gain normal form exists; its Jo-Son form (eq. 30-31) stays hand-written."""
    with pytest.raises(ModelError, match="not observable from y = x1: the observability map's "
                                         "Jacobian has rank < 3"):
        ode_system(["x1", "x2", "x3"], JO_SON_F, "x1", inputs=["u"], params={"theta": 1.0})
    # its observable part (x1, x2) alone has the normal form; f matches eq. 28 there
    hand = _hand("jo_son")
    part = ode_system(["x1", "x2"], JO_SON_F[:2], "x1", inputs=["u"], params={"theta": 1.0},
                      held_input=True)()
    rng = np.random.default_rng(2)
    for _ in range(20):
        x, u = rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 1)
        np.testing.assert_allclose(part.f(0.0, x[:2], u), hand.f(0.0, x, u)[:2], atol=1e-12)


def test_derived_affine_form_equals_the_pendulums_and_estimates_its_parameters():
    """Paper 001's form derived (the regressor psi = d phi/d theta, eq. 7/9): the pendulum as
    text in the hand-written form's parameters gives the same terms to 1e-12; the Besançon
    observer on the derived ODE plant finds both parameters within 1 % in 20 s, as it does on
    the hand-written MuJoCo pendulum (tests/observers/test_besancon.py)."""
    from hgo_mj.exceptions import DesignError
    from hgo_mj.inputs import Multisine
    from hgo_mj.observers import make_observer
    from hgo_mj.plants import OdePlant
    from hgo_mj.sensors import GaussianNoise, SensorChain
    from hgo_mj.simulate import simulate

    hand = Pendulum()
    hf = hand.form("affine", unknown=("g_over_l", "b_over_J"))
    true = dict(zip(hf.theta_names, hf.theta))
    d_over_J = hand.params["damping"] / hand.params["inertia"]
    cls = ode_system(["x1", "x2"], ["x2", "-g_over_l*sin(x1) - d_over_J*x2 + b_over_J*u"],
                     "x1", inputs=["u"], params={**true, "d_over_J": d_over_J})
    assert "affine" in cls.forms
    derived = cls()
    form = derived.form("affine", unknown=["g_over_l", "b_over_J"])
    Z, U = RNG.uniform(-2, 2, (32, 2)), RNG.uniform(-1, 1, (32, 1))
    for a, b in zip(form.terms(Z, U), hf.terms(Z, U)):
        np.testing.assert_allclose(a, b, atol=1e-12)
    assert derived.form("affine").theta_names == ("g_over_l", "b_over_J", "d_over_J")
    with pytest.raises(DesignError, match=r"is not linear in \['g', 'mass'\]"):
        ode_system(["x1", "x2"], PENDULUM_F, "x1", inputs=["u"],
                   params=dict(hand.params))().form("affine", unknown=["g", "mass"])
    plant = OdePlant(derived, 0.001)
    ob = make_observer("besancon", derived, unknown=["g_over_l", "b_over_J"], lam=20.0,
                       gain=100.0, hold="innovation")
    traj = simulate(plant, SensorChain([GaussianNoise(std=1e-4)], seed=1), {"b": ob},
                    Multisine([0.3, 0.2, 0.1], [0.3, 0.7, 1.9]), 20.0, seed=3)
    d = traj.observers["b"].diagnostics
    np.testing.assert_allclose([d["theta_g_over_l"][-1], d["theta_b_over_J"][-1]],
                               form.theta, rtol=0.01)


def test_derived_aocf_equals_the_pendulums_and_bastin_gevers_finds_the_ratios():
    """Paper 002's AOCF derived where the model is in observer form (y = x1, the unmeasured
    states linear with constant coefficients): for the pendulum as text it is the hand-written
    AOCF (R, Omega and g to 1e-12, at c2 = 3); Bastin-Gevers on the derived ODE plant finds
    g/l and b/J to 1 % in 30 s, as on the MuJoCo pendulum (tests/observers/test_bastin_gevers.py).
    A model not in observer form names why."""
    from hgo_mj.exceptions import DesignError
    from hgo_mj.inputs import Multisine
    from hgo_mj.observers import make_observer
    from hgo_mj.plants import OdePlant
    from hgo_mj.simulate import simulate

    hand = Pendulum()
    hf = hand.form("aocf", c2=3.0)
    p = hand.params
    true = dict(zip(hf.theta_names, hf.theta_true))
    cls = ode_system(["x1", "x2"], ["x2", "-g_over_l*sin(x1) - d_over_J*x2 + b_over_J*u"],
                     "x1", inputs=["u"], params={**true, "d_over_J": p["damping"] / p["inertia"]})
    assert cls.forms == ("affine", "aocf") and cls.aocf_problem is None
    derived = cls()
    f = derived.form("aocf", c2=3.0)
    assert f.theta_names == hf.theta_names
    np.testing.assert_array_equal(f.R, hf.R)
    Y, U = RNG.uniform(-2, 2, 16), RNG.uniform(-1, 1, (16, 1))

    def omega(form):
        return np.einsum("ijs,ns->nij", form.alpha, form.omega_rows(Y, U))
    np.testing.assert_allclose(omega(f), omega(hf), atol=1e-12)
    np.testing.assert_allclose(f.g_rows(Y, U), hf.g_rows(Y, U), atol=1e-12)
    ob = make_observer("bastin_gevers", derived, c1=50.0, c2=5.0, gamma=1e5, x_hat0=[0.0, 0.0])
    u = Multisine([0.3, 0.2, 0.25], [0.2, 0.45, 1.3], [0.0, 1.0, 2.0])
    simulate(OdePlant(derived, 0.002), None, {"bg": ob}, u, 30.0, x0=[0.3, 0.0])
    np.testing.assert_allclose(ob.theta_hat_, hf.theta_true, rtol=0.01)
    other = ode_system(["x1", "x2"], PENDULUM_F, "x1", inputs=["u"], params=dict(p))
    assert other.aocf_problem is None  # in observer form too: damping/inertia is a constant
    cubic = ode_system(["x1", "x2"], ["x2", "-x1 - x2**3 + a*u"], "x1", inputs=["u"],
                       params={"a": 1.0})
    assert cubic.forms == ("affine",) and "not linear in x2" in cubic.aocf_problem
    with pytest.raises(DesignError, match="has no AOCF .paper 002, eq. 2.2.: f.1. is not"):
        cubic()._form_aocf()


def test_derived_jo_son_form_equals_the_papers_and_the_observer_finds_theta():
    """Paper 003's form derived (observer canonical coordinates z = T x, the parameters along
    one constant b): the observable part of the paper's eq. 31 written as text in (y, z1) gives
    the paper's b = (2, 1), gamma_o and beta = y u (the hand-written form's, 1e-12); the
    Jo-Son observer on the derived plant with the paper's lambda = 2, Gamma = 5 and input finds
    theta = 1 within 1 % over the last 10 s of 60. The pendulum has no such form (b_n = 0),
    as its hand-written system has none."""
    from hgo_mj.exceptions import DesignError
    from hgo_mj.observers import make_observer
    from hgo_mj.plants import OdePlant
    from hgo_mj.simulate import simulate
    from hgo_mj.systems.papers import JoSonExample, jo_son_input

    hand = JoSonExample().form("jo_son")
    cls = ode_system(["y", "z1"], ["z1 - 4/3*y**3 + u + theta*y*u",
                                   "-y**5 + (y*sin(y) + y**2)*u + 2*theta*y*u"], "y",
                     inputs=["u"], params={"theta": 1.0}, x0=[1.0, 7.0 / 6.0])
    assert "jo_son" in cls.forms and cls.jo_son_problem is None
    derived = cls()
    form = derived.form("jo_son")
    np.testing.assert_allclose(form.b, hand.b, atol=1e-12)
    Y, U = RNG.uniform(-1, 1, 8), RNG.uniform(-1, 1, (1, 8))
    np.testing.assert_allclose(form.gamma_o(Y, U), hand.gamma_o(Y, U), atol=1e-12)
    np.testing.assert_allclose(form.beta(Y, U), hand.beta(Y, U), atol=1e-12)
    ob = make_observer("jo_son", derived, lam=2.0, gamma=5.0)
    tr = simulate(OdePlant(derived, 0.01), None, {"js": ob}, jo_son_input, 60.0)
    theta = tr.observers["js"].diagnostics["theta_theta"]
    assert np.max(np.abs(theta[tr.t > 50.0] - 1.0)) < 0.01
    pend = ode_system(["x1", "x2"], ["x2", "-a*sin(x1) - 0.1*x2 + u"], "x1", inputs=["u"],
                      params={"a": 9.81})
    assert "jo_son" not in pend.forms and "b_n = 0" in pend.jo_son_problem
    with pytest.raises(DesignError, match="b_r > 0"):
        pend()._form_jo_son()


def test_newton_inverse_where_no_closed_form():
    """y = x1 + x1^3/3: the cubic has three roots in sympy's eyes, so the inverse is Newton's
    from the last estimate; it round-trips and counts no failure."""
    cls = ode_system(["x1", "x2"], ["x2", "-x1"], "x1 + x1**3/3")
    s = cls()
    assert not cls.closed_form_inverse
    for x in ([0.2, -0.1], [0.5, 0.3], [-0.7, 0.9]):
        np.testing.assert_allclose(s.from_normal(s.to_normal(x)), x, atol=1e-9)
    assert s.inverse_failures == 0


def test_parsing_never_evaluates_user_text(monkeypatch):
    def forbidden(*args, **kwargs):
        raise AssertionError("user text reached eval/sympify")

    monkeypatch.setattr(sympy, "sympify", forbidden)
    monkeypatch.setattr(builtins, "eval", forbidden)
    cls = ode_system(["x1", "x2"], ["x2", "-sin(x1) + u"], "x1", inputs=["u"])
    assert cls().phi([0.1, 0.0], [0.0]) == pytest.approx(-np.sin(0.1))


@pytest.mark.parametrize(("f0", "match"), [
    ('__import__("os").system("true")', r"column 1: a call of .__import__\(.os.\).system."),
    ("x1.real", "Attribute 'x1.real' is not allowed"),
    ("lambda: 1", "Lambda 'lambda: 1' is not allowed"),
    ("y * 2", r"'y' is not declared; declared: \['x1', 'x2'\]"),
    ("x1 +", "syntax error at column"),
    ("sin(x1, x2)", r"sin\(\) takes one argument; found 2"),
    ("x1 if x2 else 0", "IfExp .* is not allowed"),
    ("[x1][0]", "Subscript .* is not allowed"),
    (3, r"must be an expression as a string; found 3 \(int\)"),
])
def test_bad_expressions_are_one_clear_error(f0, match):
    with pytest.raises(ModelError, match=match):
        ode_system(["x1", "x2"], [f0, "x1"], "x1")


def test_structural_problems_are_named():
    rd = ode_system(["x1", "x2"], ["x2 + u", "-x1"], "x1", inputs=["u"])
    assert rd.normal_form_order is None
    assert rd.normal_form_problem.startswith("the input enters L_f^1 h (relative degree 1 < n = 2)")
    with pytest.raises(ModelError, match="relative degree"):
        rd().phi([0.0, 0.0], [0.0])
    with pytest.raises(ModelError, match="not observable from y = x2"):
        ode_system(["x1", "x2"], ["x2", "0"], "x2")
    half = ode_system(["x1", "x2"], ["x2", "-x1"], "x1 + abs(x1)")
    assert half.rank_problem is not None and "rank drops below 2" in half.rank_problem
    with pytest.raises(ModelError, match="f must be a list of 2 expressions"):
        ode_system(["x1", "x2"], ["x2"], "x1")
    with pytest.raises(ModelError, match="declared twice"):
        ode_system(["x1", "u"], ["u", "x1"], "x1", inputs=["u"])


def test_scenario_runs_an_ode_given_as_text(tmp_path):
    from hgo_mj.cli import main
    from hgo_mj.scenario import scenario_run
    from hgo_mj.simulate import Trajectory, simulate

    sc = {"name": "ode_pendulum",
          "plant": {"states": ["x1", "x2"], "inputs": ["u"], "params": {"a": 9.81, "b": 0.1},
                    "f": ["x2", "-a*sin(x1) - b*x2 + u"], "h": "x1", "x0": [1.0, 0.0]},
          "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
          "observers": [{"type": "high_gain", "k": 20.0, "model": True}, {"type": "ekf"}],
          "input": {"type": "multisine", "amplitudes": [0.5], "frequencies": [0.3]},
          "run": {"duration": 5.0}}
    kw = scenario_run(sc)
    tr = simulate(**kw, seed=0)
    assert isinstance(tr, Trajectory)
    late = tr.t > 2.0
    for name in kw["observers"]:
        assert np.sqrt(np.mean(tr.error(name)[late, 1] ** 2)) < 0.05
    bad = {**sc, "plant": {**sc["plant"], "f": ["x2", "-a*sin(x1) - c*x2"]}}
    (tmp_path / "bad.toml").write_text(
        'name = "b"\n[plant]\nstates = ["x1", "x2"]\nf = ["x2", "-c*x1"]\nh = "x1"\n'
        '[run]\nduration = 1.0\n')
    assert main(["run", str(tmp_path / "bad.toml"), "--out", str(tmp_path / "o")]) == 2
    assert not (tmp_path / "o").exists()
    with pytest.raises(ModelError, match="'c' is not declared"):
        scenario_run(bad)


def test_the_shipped_ode_scenario_runs(tmp_path):
    from pathlib import Path

    from hgo_mj.cli import main
    from hgo_mj.simulate import Trajectory

    path = Path(__file__).resolve().parents[2] / "scenarios" / "ode_pendulum.toml"
    assert main(["run", str(path), "--duration", "3", "--out", str(tmp_path / "o"),
                 "--quiet"]) == 0
    tr = Trajectory.load(tmp_path / "o" / "trajectory.npz")
    assert tr.state_names == ("x1", "x2") and set(tr.observers) == {"high_gain_0", "ekf_1"}


def test_parameter_jacobians_name_an_unknown_parameter():
    """param_jacobian of the hand-written and derived systems: an unknown parameter is a
    DesignError listing the valid names (was a bare ValueError from list.index); a syntax
    error at the end of an expression names a column inside it."""
    from hgo_mj.exceptions import DesignError

    x2, u1 = np.zeros(2), np.zeros(1)
    with pytest.raises(DesignError, match=r"Pendulum has no parameter\(s\) \['mas'\]; valid: "):
        Pendulum().param_jacobian(0.0, x2, u1, Pendulum().params, ["mas"])
    ej = _hand("elastic_joint")
    with pytest.raises(DesignError, match="ElasticJoint has no parameter"):
        ej.param_jacobian(0.0, np.zeros(4), u1, ej.params, ["k"])
    s = ode_system(["x1", "x2"], ["x2", "-a*x1"], "x1", params={"a": 1.0})()
    with pytest.raises(DesignError, match=r"has no parameter\(s\) \['b'\]"):
        s.param_jacobian(0.0, x2, [], None, ["b"])
    with pytest.raises(ModelError, match=r"syntax error at column 6"):
        ode_system(["x1", "x2"], ["x2", "-x1 +"], "x1")


@pytest.fixture
def deadline():
    """A hang fails: faulthandler ends the process after 60 s, even inside sympy's C code."""
    import faulthandler

    faulthandler.dump_traceback_later(60, exit=True)
    yield
    faulthandler.cancel_dump_traceback_later()


@pytest.mark.parametrize(("f1", "match"), [
    ("9**9**9 + x1", r"f\[1\] = '9\*\*9\*\*9 \+ x1', column 1: the exponent '387420489' is too "
                     r"large: constant exponents are at most 100 in magnitude"),
    ("2**2**2**2**2", r"column 1: the exponent '65536' is too large"),
    ("x1**(10**5)", r"column 1: the exponent '100000' is too large"),
    ("(9**99)**99 * x1", r"the power's magnitude is 10\^\(\+-9353\), beyond float64's range"),
    ("-" * 100000 + "x1", r"f\[1\] = '-----.* \.\.\. \(100002 characters\) \.\.\. '-+x1': 100002 "
                          r"characters; an expression has at most 10000"),
    ("+".join(["x1"] * 200000), r"599999 characters; an expression has at most 10000"),
    ("+".join(["x1"] * 1500), r"column \d+: nested more than 200 deep \(a sum or product"),
    ("-" * 5000 + "x1", r"Python cannot parse it \(RecursionError"),
    ("sqrt(-1)", r"f\[1\] = 'sqrt\(-1\)', column 1: sqrt\(-1\) is I, not a finite real number"),
    ("x1 + log(0)", r"column 6: log\(0\) is zoo, not a finite real number"),
    ("x2/0", r"column 1: x2 / 0 is zoo\*x2, not a finite real number"),
    ("(-8)**(1/3)", r"is 2\*\(-1\)\*\*\(1/3\), not a finite real number"),
    ("acos(2) * x1", r"acos\(2\) is acos\(2\), not a finite real number"),
    ("1e999 * x1", r"the number 'inf' is beyond float64's range"),
    ("9" * 400, r"is beyond float64's range"),
])
def test_oversized_or_non_real_expressions_are_one_line_in_seconds(deadline, f1, match):
    """Sizes are bounded before sympy sees them (its exact numbers made 9**9**9 hang, 100,000
    minus signs a MemoryError, a 200,000-term sum a RecursionError) and a constant that is not
    a finite real number is refused where it is (sqrt(-1) was a numba typing error)."""
    import time

    t = time.perf_counter()
    with pytest.raises(ModelError, match=match) as err:
        ode_system(["x1", "x2"], ["x2", f1], "x1")
    assert "\n" not in str(err.value) and len(str(err.value)) < 300
    assert time.perf_counter() - t < 10.0


def test_the_limits_leave_ordinary_models_alone():
    """Constant powers within float64's range, exponents up to 100, a 150-term sum."""
    cls = ode_system(["x1", "x2"], ["x2", "-2**0.5*x1 + 10**-3*x2**3 - x1**100*1e-300 + "
                                    + "+".join(["0*x1"] * 150)], "x1")
    assert cls().phi([0.1, 0.0]) == pytest.approx(-2 ** 0.5 * 0.1, rel=1e-9)
