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
        J = np.array([[float(c(s._env(x, u))) for c in row] for row in cls._sym["J"]])
        assert s.phi(z, u) == pytest.approx(float(J[3] @ s.f(0.0, x, u)), rel=1e-9, abs=1e-9)


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
    from hgo_mj.cli import main, scenario_run
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
