"""The papers' non-mechanical example systems (hgo_mj/systems/papers.py).

Checks the plants against an independent high-accuracy integrator, the coordinate changes the
papers give (and the corrections of their typos), the regressor forms, and statements about
the trajectories.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hgo_mj.exceptions import DesignError, DimensionError
from hgo_mj.plants.ode import OdePlant
from hgo_mj.systems.base import System
from hgo_mj.systems.papers import (
    BASTIN_GEVERS_U_MAX,
    BesanconExample1,
    BesanconExample2,
    BioreactorBastinGevers,
    BioreactorBullinger,
    JoSonExample,
    bastin_gevers_input,
    besancon_ex1_input,
    besancon_ex2_input,
    besancon_ex2_signal,
    bullinger_input,
    jo_son_input,
)

ALL = (BioreactorBullinger, BioreactorBastinGevers, BesanconExample1, BesanconExample2,
       JoSonExample)


def simulate(system: System, inp, dt: float, horizon: float, *, physics_dt=None, offset=0.0):
    """Run OdePlant and a piecewise DOP853 reference with the same held input.

    The input is sampled at ``t_k + offset * dt`` and held over ``[t_k, t_k + dt)``; the
    reference restarts ``solve_ivp`` at every control period so the held input is exact.
    Returns ``(t, x_plant, x_ref, u)`` with ``N + 1`` rows of states.
    """
    plant = OdePlant(system, dt, physics_dt=physics_dt)
    n = round(horizon / dt)
    xs, refs, us = [plant.state], [plant.state], []
    xr = plant.state
    for k in range(n):
        tk = k * dt
        u = np.asarray(inp(tk + offset * dt), dtype=float)
        plant.step(u)
        sol = solve_ivp(lambda t, x, u=u: system.dynamics(t, x, u, system.params),
                        (tk, tk + dt), xr, method="DOP853", rtol=1e-10, atol=1e-12)
        xr = sol.y[:, -1]
        xs.append(plant.state)
        refs.append(xr)
        us.append(u)
    t = dt * np.arange(n + 1)
    return t, np.array(xs), np.array(refs), np.array(us)


# ------------------------------------------------------------------ class attributes
@pytest.mark.parametrize("cls", ALL)
def test_class_attributes_are_consistent(cls: type[System]) -> None:
    assert cls.name and cls.summary and cls.model_file is None
    assert re.search(r"\(paper 00\d\)", cls.reference) and re.search(r"eq\.|section",
                                                                       cls.reference)
    assert len(cls.default_x0) == len(cls.state_names)
    assert tuple(cls.default_params) == cls.param_names
    sys_ = cls()
    x0 = np.array(cls.default_x0)
    u0 = np.zeros(len(cls.input_names))
    assert sys_.f(0.0, x0, u0).shape == x0.shape
    assert sys_.h(x0).shape == (len(cls.output_names),)
    doc = cls.__doc__ or ""
    assert ".. math::" in doc and "References" in doc


def test_paper_values() -> None:
    assert BioreactorBullinger().params == {"a1": 1.0, "a2": 1.0, "a3": 1.0, "a4": 0.1}
    assert BioreactorBullinger.default_x0 == (0.075, 0.03)
    assert BesanconExample1().params == {"theta1": 1.0, "theta2": 2.0}
    assert BesanconExample1.default_x0 == (1.0, 1.0)
    assert BesanconExample2().params == {"theta1": 10.0, "theta2": -5.0}
    # the input generator starts on the paper's input: (u(0), u'(0)) = (0.1, 2)
    np.testing.assert_allclose(BesanconExample2.default_x0[2:], besancon_ex2_signal(0.0)[:2])
    assert JoSonExample().params == {"theta": 1.0}
    assert JoSonExample.default_x0 == (0.5, 1.0, -1.0)
    np.testing.assert_allclose(bullinger_input(0.0), [0.08])
    np.testing.assert_allclose(bullinger_input(29.999), [0.08])
    np.testing.assert_allclose(bullinger_input(30.0), [0.02])
    np.testing.assert_allclose(bullinger_input(49.999), [0.02])
    np.testing.assert_allclose(bullinger_input(50.0), [0.08])
    np.testing.assert_allclose(bullinger_input(200.0), [0.08])
    t = 0.37
    np.testing.assert_allclose(besancon_ex1_input(t), [math.sin(2 * t) + 0.1 * math.cos(10 * t)])
    np.testing.assert_allclose(jo_son_input(t),
                               [math.sin(math.pi * t / 3) * math.sin(math.pi * t / 2)])


# ------------------------------------------------------------------ OdePlant vs DOP853
# (system, input, control period dt, horizon, absolute tolerance on the state):
# RK4 at physics_dt = dt/10 against DOP853 at rtol 1e-10, the input held per period.
PLANT_CASES = [
    pytest.param(BioreactorBullinger, bullinger_input, 0.1, 100.0, 1e-11, id="bullinger-100h"),
    pytest.param(BioreactorBastinGevers, bastin_gevers_input, 0.05, 20.0, 1e-8,
                 id="bastin_gevers-20"),
    pytest.param(BesanconExample1, besancon_ex1_input, 0.05, 20.0, 1e-8, id="besancon_ex1-20s"),
    pytest.param(BesanconExample2, besancon_ex2_input, 0.02, 20.0, 1e-7, id="besancon_ex2-20s"),
    pytest.param(JoSonExample, jo_son_input, 0.05, 20.0, 1e-8, id="jo_son-20s"),
]


@pytest.mark.parametrize(("cls", "inp", "dt", "horizon", "tol"), PLANT_CASES)
def test_ode_plant_matches_dop853(cls, inp, dt, horizon, tol) -> None:
    # u'' of the second Besançon example is sampled mid-period, as its docstring advises
    offset = 0.5 if cls is BesanconExample2 else 0.0
    t, xs, refs, _ = simulate(cls(), inp, dt, horizon, offset=offset)
    assert t[-1] == pytest.approx(horizon)
    err = np.max(np.abs(xs - refs))
    assert err < tol, f"max |RK4 - DOP853| = {err:.3g} over {horizon}"
    assert np.all(np.isfinite(xs))


# ------------------------------------------------------------------ Bullinger (paper 000)
def test_bullinger_trajectory_statements() -> None:
    """Paper 000, sec. 4: states strictly positive, input in (0, a4).

    Also the mass balance of eq. 15 with a3 = 1, (m + s)' = u (a4 - m - s), solved exactly,
    and the equilibria m = a4 (1 - u), s = a4 u it implies for each level of the input.
    """
    sys_ = BioreactorBullinger()
    t, xs, _, us = simulate(sys_, bullinger_input, 0.1, 100.0)
    assert np.all(xs > 0)
    assert np.all((us > 0) & (us < sys_.params["a4"]))
    a4 = sys_.params["a4"]
    integral_u = np.concatenate(([0.0], np.cumsum(us[:, 0]) * 0.1))
    expected = a4 + (sum(sys_.default_x0) - a4) * np.exp(-integral_u)
    np.testing.assert_allclose(xs.sum(axis=1), expected, rtol=1e-9)
    for t_end, u in ((30.0, 0.08), (50.0, 0.02), (100.0, 0.08)):
        k = round(t_end / 0.1)
        np.testing.assert_allclose(xs[k], [a4 * (1 - u), a4 * u], atol=5e-4)


def _bullinger_samples(rng, n=200):
    m = rng.uniform(0.01, 1.0, n)
    s = rng.uniform(0.0, 1.0, n)
    u = rng.uniform(0.0, 0.1, n)
    return m, s, u


def test_bullinger_normal_form_round_trip() -> None:
    sys_ = BioreactorBullinger(a1=1.3, a2=0.7, a3=1.1, a4=0.1)
    rng = np.random.default_rng(1)
    for m, s, u in zip(*_bullinger_samples(rng), strict=True):
        x = np.array([m, s])
        z = sys_.to_normal(x, u)
        assert z[0] == m
        np.testing.assert_allclose(sys_.from_normal(z, [u]), x, rtol=1e-9, atol=1e-12)
    # and z -> x -> z on random points of the domain m > 0, 0 <= m' + u m < a1 m
    for _ in range(200):
        m, u = rng.uniform(0.01, 1.0), rng.uniform(0.0, 0.1)
        w = rng.uniform(0.0, 0.999) * sys_.params["a1"] * m
        z = np.array([m, w - u * m])
        np.testing.assert_allclose(sys_.to_normal(sys_.from_normal(z, u), u), z,
                                   rtol=1e-9, atol=1e-12)


def test_bullinger_substrate_recovered_along_trajectory() -> None:
    sys_ = BioreactorBullinger()
    _, xs, _, us = simulate(sys_, bullinger_input, 0.1, 100.0)
    for x, u in zip(xs[:-1], us, strict=True):
        s_rec = sys_.from_normal(sys_.to_normal(x, u), u)[1]
        assert s_rec == pytest.approx(x[1], rel=1e-9)


def test_bullinger_phi_equals_finite_difference_of_simulated_mdot() -> None:
    """phi(z, u) = m'' against a central difference of m' along the plant (u held at 0.08).

    Five-point stencil with h = 0.01 h (error ~h^4/30 |m^(5)|); tolerance 1e-8 relative to
    max |m''| over 30 h.
    """
    sys_ = BioreactorBullinger()
    plant = OdePlant(sys_, 0.01, physics_dt=0.001)
    u = np.array([0.08])
    xs = [plant.state]
    for _ in range(3000):  # 30 h
        plant.step(u)
        xs.append(plant.state)
    mdot = np.array([sys_.to_normal(x, u)[1] for x in xs])
    fd = (-mdot[4:] + 8 * mdot[3:-1] - 8 * mdot[1:-3] + mdot[:-4]) / (12 * 0.01)
    phi = np.array([sys_.phi(sys_.to_normal(x, u), u) for x in xs[2:-2]])
    scale = np.max(np.abs(phi))
    assert scale > 1e-3
    assert np.max(np.abs(fd - phi)) < 1e-8 * scale


def test_bullinger_phi_u_dot_term() -> None:
    """With a smooth input u = 0.05 + 0.02 sin t, phi(z, u, u') matches d/dt m' (DOP853)."""
    sys_ = BioreactorBullinger()

    def uf(t):
        return np.array([0.05 + 0.02 * math.sin(t)])

    sol = solve_ivp(lambda t, x: sys_.dynamics(t, x, uf(t), sys_.params), (0.0, 20.0),
                    np.array(sys_.default_x0), method="DOP853", rtol=1e-12, atol=1e-14,
                    dense_output=True)
    h = 1e-4
    for t in np.linspace(0.5, 19.5, 25):
        def mdot(tt):
            return sys_.to_normal(sol.sol(tt), uf(tt))[1]
        fd = (mdot(t + h) - mdot(t - h)) / (2 * h)
        ph = sys_.phi(sys_.to_normal(sol.sol(t), uf(t)), uf(t), u_dot=0.02 * math.cos(t))
        assert ph == pytest.approx(fd, abs=1e-8)
        # without the u_dot term it is wrong by u_dot * m
        ph0 = sys_.phi(sys_.to_normal(sol.sol(t), uf(t)), uf(t))
        assert ph0 - ph == pytest.approx(0.02 * math.cos(t) * sol.sol(t)[0], rel=1e-9, abs=1e-15)


@pytest.mark.parametrize(("z", "u", "match"), [
    ((0.0, 0.01), 0.08, "m = z1 > 0"),
    ((-0.1, 0.01), 0.08, "m = z1 > 0"),
    ((0.1, -0.02), 0.08, r"0 <= m' \+ u m < a1 m"),  # w < 0: negative substrate
    ((0.1, 0.095), 0.08, r"0 <= m' \+ u m < a1 m"),  # w >= a1 m: no finite substrate
    ((0.1, 0.092), 0.08, r"0 <= m' \+ u m < a1 m"),  # w == a1 m exactly
    ((0.1, 0.0), None, "depends on the input u"),
])
def test_bullinger_inverse_outside_domain(z, u, match) -> None:
    with pytest.raises(DesignError, match=match):
        BioreactorBullinger().from_normal(z, u)


def test_bullinger_phi_and_to_normal_errors() -> None:
    sys_ = BioreactorBullinger()
    with pytest.raises(DesignError, match="m = z1 > 0"):
        sys_.phi([0.0, 0.0], 0.08)
    with pytest.raises(DesignError, match="depends on the input u"):
        sys_.to_normal([0.1, 0.01])
    with pytest.raises(DimensionError, match="u must have length 1"):
        sys_.to_normal([0.1, 0.01], [0.08, 0.0])
    with pytest.raises(DesignError, match="a1 > 0 and a2 > 0"):
        BioreactorBullinger(a2=0.0).from_normal([0.1, 0.0], 0.08)


# ------------------------------------------------------------------ Bastin-Gevers (paper 002)
def _bg_random(rng):
    z = rng.uniform(0.05, 5.0, 2)
    u = np.array([rng.uniform(0.0, 8.0), rng.uniform(0.0, 2.0)])
    c2 = rng.uniform(0.2, 5.0)
    return z, u, c2


def _bg_systems():
    return [BioreactorBastinGevers(),
            BioreactorBastinGevers(mu_max=1.7, K_m=0.0, K_c=0.4, p2=0.8, p3=0.1),  # Contois
            BioreactorBastinGevers(mu_max=2.5, K_m=0.3, K_c=0.2, p2=0.3, p3=0.02)]


def _jacobian_fd(fun, x, h=1e-6):
    cols = []
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = h
        cols.append((fun(x + e) - fun(x - e)) / (2 * h))
    return np.array(cols).T


def test_bastin_gevers_6_4_maps_6_1_into_6_5() -> None:
    """d/dt x(z) along the (corrected) eq. 6.1 equals the AOCF eq. 6.5 at theta(z)."""
    rng = np.random.default_rng(2)
    for sys_ in _bg_systems():
        for _ in range(50):
            z, u, c2 = _bg_random(rng)
            x, theta = sys_.to_aocf(z, c2)
            J = _jacobian_fd(lambda zz, c2=c2, sys_=sys_: sys_.to_aocf(zz, c2)[0], z)
            lhs = J @ sys_.f(0.0, z, u)
            rhs = sys_.aocf_rhs(x, theta, u, c2)
            np.testing.assert_allclose(lhs, rhs, rtol=1e-8, atol=1e-8)
            R, Omega, g = sys_.aocf_structure(x[0], u, c2)
            np.testing.assert_allclose(R @ x + Omega @ theta + g, rhs, rtol=1e-14, atol=1e-14)


def test_bastin_gevers_printed_6_1_is_not_consistent_with_6_4_6_5() -> None:
    """Evidence for the correction: without the dilution -z1 in the substrate equation, the
    residual of 6.5 is exactly (z1, (1 - c2) z1) -- i.e. the missing term -z1 mapped by 6.4."""
    rng = np.random.default_rng(3)
    sys_ = BioreactorBastinGevers()
    for _ in range(20):
        z, u, c2 = _bg_random(rng)
        x, theta = sys_.to_aocf(z, c2)
        f_printed = sys_.f(0.0, z, u) + np.array([z[0], 0.0])  # eq. 6.1 as printed
        J = np.array([[1.0, 0.0], [1.0 - c2, -sys_.params["p3"]]])
        residual = J @ f_printed - sys_.aocf_rhs(x, theta, u, c2)
        np.testing.assert_allclose(residual, [z[0], (1.0 - c2) * z[0]], rtol=1e-10, atol=1e-12)
        assert abs(residual[0]) > 0.01


def test_bastin_gevers_6_6_inverts_6_4() -> None:
    rng = np.random.default_rng(4)
    for sys_ in _bg_systems():
        p = sys_.params
        for _ in range(50):
            z, _, c2 = _bg_random(rng)
            x, theta = sys_.to_aocf(z, c2)
            z_back, p_back = sys_.from_aocf(x, theta, c2)
            p1 = sys_.specific_growth_rate(z) / z[0]
            np.testing.assert_allclose(z_back, z, rtol=1e-10)
            np.testing.assert_allclose(p_back, [p1, p["p2"], p["p3"]], rtol=1e-10)


def test_bastin_gevers_printed_6_6b_has_wrong_sign() -> None:
    """Evidence for the correction: 6.6b as printed, (-x2 + (1 - c2) y)/theta3, gives -z2."""
    rng = np.random.default_rng(5)
    sys_ = BioreactorBastinGevers()
    for _ in range(20):
        z, _, c2 = _bg_random(rng)
        x, theta = sys_.to_aocf(z, c2)
        z2_printed = (-x[1] + (1.0 - c2) * x[0]) / theta[2]
        assert z2_printed == pytest.approx(-z[1], rel=1e-10)


def test_bastin_gevers_trajectory_statements() -> None:
    """Paper 002, sec. 6: F.1 (0 <= p0 <= mu*), F.2 (p2 p3 << 1), F.4 on the input, and the
    bound z1 + z2/p2 <= u_max behind C.1; concentrations stay positive."""
    sys_ = BioreactorBastinGevers()
    p = sys_.params
    assert p["p2"] > 0 and p["p2"] * p["p3"] < 0.05
    z0 = np.array(sys_.default_x0)
    assert z0[0] <= BASTIN_GEVERS_U_MAX and z0[1] / p["p2"] <= BASTIN_GEVERS_U_MAX
    _, xs, _, us = simulate(sys_, bastin_gevers_input, 0.05, 60.0)
    assert np.all(us > 0)
    feed = us[:, 0] + us[:, 1] / p["p2"]
    assert np.all(feed >= p["p2"] * p["p3"] * BASTIN_GEVERS_U_MAX)
    assert np.all(feed <= BASTIN_GEVERS_U_MAX)
    assert np.all(xs > 0)
    assert np.all(xs[:, 0] + xs[:, 1] / p["p2"] <= BASTIN_GEVERS_U_MAX)
    p0 = np.array([sys_.specific_growth_rate(x) for x in xs])
    assert np.all((p0 >= 0) & (p0 <= p["mu_max"]))
    # the observer's theta is time-varying but bounded along the trajectory (S.3)
    thetas = np.array([sys_.to_aocf(x)[1] for x in xs])
    assert np.all(np.isfinite(thetas)) and np.ptp(thetas[:, 0]) > 0.1


def test_bastin_gevers_errors() -> None:
    sys_ = BioreactorBastinGevers()
    x, theta = sys_.to_aocf([1.0, 1.0])
    with pytest.raises(DesignError, match="theta3 = -p3 != 0"):
        sys_.from_aocf(x, [theta[0], theta[1], 0.0])
    with pytest.raises(DesignError, match="z2 != 0"):
        sys_.from_aocf([1.0, (1.0 - 2.0) * 1.0], theta, 2.0)  # x2 = (1 - c2) y  =>  z2 = 0
    with pytest.raises(DesignError, match="c2 must be > 0"):
        sys_.to_aocf([1.0, 1.0], c2=-1.0)
    with pytest.raises(DimensionError, match="theta must have length 3"):
        sys_.from_aocf(x, theta[:2])
    with pytest.raises(DimensionError, match="u must have length 2"):
        sys_.aocf_rhs(x, theta, [1.0])


# ------------------------------------------------------------------ Besançon (paper 001)
@pytest.mark.parametrize("cls", [BesanconExample1, BesanconExample2])
def test_besancon_regressor_form_reproduces_dynamics(cls) -> None:
    """x' = A x + phi0(x, u) + psi(x, u) theta (eq. 9 / 21), exactly."""
    rng = np.random.default_rng(6)
    for theta in ([1.0, 2.0], [10.0, -5.0], [-0.3, 4.2]):
        sys_ = cls(theta1=theta[0], theta2=theta[1])
        n = len(cls.state_names)
        for _ in range(100):
            x = rng.normal(scale=3.0, size=n)
            u = rng.normal(size=1)
            form = sys_.A @ x + sys_.phi0(x, u) + sys_.regressor(x, u) @ sys_.theta
            np.testing.assert_allclose(form, sys_.f(0.0, x, u), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("cls", [BesanconExample1, BesanconExample2])
def test_besancon_structure(cls) -> None:
    """[A1] / [A1']: A, C integrator chains; psi non-zero only in the last row of each block;
    phi's non-last entries of a block depend only on that block's leading states and u."""
    sys_ = cls()
    rng = np.random.default_rng(7)
    last_rows = [1] if cls is BesanconExample1 else [1, 3]
    for _ in range(20):
        x, u = rng.normal(size=len(cls.state_names)), rng.normal(size=1)
        psi = sys_.regressor(x, u)
        assert psi.shape == (len(cls.state_names), 2)
        other = np.delete(psi, last_rows, axis=0)
        assert np.all(other == 0.0)
        if cls is BesanconExample1:
            x2 = x.copy()
            x2[1] += 1.0  # phi_1 must not depend on x2
            assert sys_.phi0(x2, u)[0] == sys_.phi0(x, u)[0]
    C = sys_.C
    assert C.shape == (len(cls.output_names), len(cls.state_names))
    x = rng.normal(size=len(cls.state_names))
    np.testing.assert_array_equal(C @ x, sys_.h(x))


def test_besancon_ex1_state_bounded() -> None:
    """[A2]: the paper's input generates bounded states (checked over 100 s)."""
    _, xs, _, _ = simulate(BesanconExample1(), besancon_ex1_input, 0.05, 100.0)
    assert np.max(np.abs(xs)) < 5.0
    assert np.max(np.abs(xs[1000:])) < 3.0


def test_besancon_ex2_input_derivatives_are_exact() -> None:
    h = 1e-5
    for t in np.linspace(0.0, 7.0, 30):
        s = besancon_ex2_signal(t)
        assert s[0] == pytest.approx(besancon_ex1_input(t)[0], abs=1e-15)
        d = (besancon_ex2_signal(t + h) - besancon_ex2_signal(t - h)) / (2 * h)
        assert d[0] == pytest.approx(s[1], abs=1e-8)
        assert d[1] == pytest.approx(s[2], abs=1e-7)
        assert besancon_ex2_input(t)[0] == s[2]


def test_besancon_ex2_generator_follows_input_and_y_grows_like_sqrt_t() -> None:
    """With u'' held at mid-period (dt = 0.01), x4 - u'(t) = O(dt^2) (below 1e-3) and x3 - u(t)
    drifts at most like dt^2/24 |u'''(0)| t = 3.3e-5 t (below 5e-3 over 100 s).
    The state is unbounded: y y' averages w* = pi - atan(10), so y^2/2 grows at rate w*
    (observation of this module, not a statement of the paper)."""
    dt = 0.01
    plant = OdePlant(BesanconExample2(), dt)
    xs = [plant.state]
    for k in range(round(100.0 / dt)):
        plant.step(besancon_ex2_input((k + 0.5) * dt))
        xs.append(plant.state)
    xs = np.array(xs)
    t = dt * np.arange(len(xs))
    sig = np.array([besancon_ex2_signal(tk) for tk in t])
    assert np.max(np.abs(xs[:, 2] - sig[:, 0])) < 5e-3
    assert np.max(np.abs(xs[:, 2] - sig[:, 0]) - 3.4e-5 * t) < 1e-3
    assert np.max(np.abs(xs[:, 3] - sig[:, 1])) < 1e-3
    w_star = math.pi - math.atan(10.0)
    k50, k100 = round(50 / dt), round(100 / dt)
    rate = (xs[k100, 0] ** 2 - xs[k50, 0] ** 2) / 2 / 50.0
    assert rate == pytest.approx(w_star, rel=0.05)
    assert 15.0 < xs[k100, 0] < 21.0


# ------------------------------------------------------------------ Jo-Son (paper 003)
def test_jo_son_eq30_maps_eq28_into_eq31() -> None:
    """d/dt T(x) along eq. 28 equals the right-hand side of eq. 31 at z = T(x)."""
    rng = np.random.default_rng(8)
    for theta in (1.0, -0.7, 2.5):
        sys_ = JoSonExample(theta=theta)
        for _ in range(100):
            x = rng.normal(scale=1.5, size=3)
            u = rng.normal(size=1)
            J = _jacobian_fd(sys_.to_canonical, x)
            lhs = J @ sys_.f(0.0, x, u)
            rhs = sys_.canonical_rhs(sys_.to_canonical(x), u)
            np.testing.assert_allclose(lhs, rhs, rtol=1e-7, atol=1e-7)
            # with the exact Jacobian of eq. 30 the identity holds to rounding
            J_exact = np.array([[x[0] ** 2, 1.0, 0.0], [1.0, 0.0, 0.0], [-x[0], 0.0, 1.0]])
            np.testing.assert_allclose(J_exact @ sys_.f(0.0, x, u), rhs, rtol=1e-12, atol=1e-10)


def test_jo_son_canonical_round_trip_and_output() -> None:
    sys_ = JoSonExample()
    rng = np.random.default_rng(9)
    for _ in range(100):
        x = rng.normal(scale=2.0, size=3)
        z = sys_.to_canonical(x)
        assert z[1] == sys_.h(x)[0]  # y = z2
        np.testing.assert_allclose(sys_.from_canonical(z), x, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(sys_.to_canonical(sys_.from_canonical(x)), x,
                                   rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(sys_.to_canonical([0.0, 0.0, 0.0]), 0.0)  # T(0) = 0
    # b and beta of the canonical form: the theta-terms of eq. 31 are b * theta * beta(y, u)
    y, u = 0.7, -0.4
    z = np.array([0.3, y, 0.1])
    d = JoSonExample(theta=1.0).canonical_rhs(z, u) - JoSonExample(theta=0.0).canonical_rhs(z, u)
    np.testing.assert_allclose(d, [*np.array(JoSonExample.b) * JoSonExample.beta(y, u), 0.0])


def test_jo_son_unobservable_part_contracts() -> None:
    """Corollary 3.3 (i) with P2 = 1, k0 = 1: x1, x2 do not see x3, and two solutions that
    differ only in x3(0) approach each other at least as fast as exp(-t)."""
    sys_ = JoSonExample()
    t, xa, _, _ = simulate(sys_, jo_son_input, 0.05, 10.0)
    plant = OdePlant(sys_, 0.05)
    plant.reset([0.5, 1.0, 2.0])
    xb = [plant.state]
    for k in range(len(t) - 1):
        plant.step(jo_son_input(k * 0.05))
        xb.append(plant.state)
    xb = np.array(xb)
    np.testing.assert_array_equal(xa[:, :2], xb[:, :2])
    gap = np.abs(xa[:, 2] - xb[:, 2])
    assert np.all(gap <= 3.0 * np.exp(-t) + 1e-12)
    assert np.all(np.abs(xa) < 3.0)


# ------------------------------------------------------------------ bad input
@pytest.mark.parametrize("cls", ALL)
def test_wrong_length_state_raises(cls) -> None:
    sys_ = cls()
    n = len(cls.state_names)
    bad = np.ones(n + 1)
    u = np.zeros(len(cls.input_names))
    with pytest.raises(DimensionError, match=f"x must have length {n}; found length {n + 1}"):
        sys_.f(0.0, bad, u)
    with pytest.raises(DimensionError, match=f"x must have length {n}"):
        sys_.h(bad)
    with pytest.raises(DimensionError, match=f"x0 must have length {n}"):
        OdePlant(sys_, 0.1).reset(bad)


def test_wrong_length_in_transformations_raises() -> None:
    with pytest.raises(DimensionError, match="x must have length 2"):
        BioreactorBullinger().to_normal([0.1, 0.2, 0.3], 0.08)
    with pytest.raises(DimensionError, match="z must have length 2"):
        BioreactorBullinger().from_normal([0.1], 0.08)
    with pytest.raises(DimensionError, match="z must have length 2"):
        BioreactorBastinGevers().to_aocf([1.0])
    with pytest.raises(DimensionError, match="x must have length 2"):
        BesanconExample1().regressor([1.0, 2.0, 3.0], [0.0])
    with pytest.raises(DimensionError, match="x must have length 4"):
        BesanconExample2().phi0([1.0, 2.0], [0.0])
    with pytest.raises(DimensionError, match="x must have length 3"):
        JoSonExample().to_canonical([1.0, 2.0])
    with pytest.raises(DimensionError, match="z must have length 3"):
        JoSonExample().from_canonical([1.0, 2.0, 3.0, 4.0])


def test_unknown_or_nonfinite_parameter_raises() -> None:
    with pytest.raises(DesignError, match="unknown parameter"):
        BioreactorBullinger(a5=1.0)
    with pytest.raises(DesignError, match="must be finite"):
        JoSonExample(theta=float("nan"))
