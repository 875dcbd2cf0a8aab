"""Reproduction of Ibrir (2007), section 4: the inverted pendulum of eq. 66-71.

``hgo-mj reproduce ibrir2007 --out DIR`` writes ``DIR/summary.json``, ``DIR/report.txt`` and the
figures ``fig1_standard.png``, ``fig2_noisy_output.png``, ``fig3_q_integral.png``,
``fig4_euler_periods.png``, ``fig5_mujoco.png``.

The plant (eq. 66), in time-scaled units,

.. math:: \\dot x_1 = x_2, \\qquad \\dot x_2 = \\sin x_1 + u \\cos x_1, \\qquad y = x_1,

with ``u = 0.5 sin t``, the Riccati observer (eq. 67) with ``alpha = (3, 2)``, ``gamma = 6``,
the Lipschitz constant ``rho = 3/2``, the q-integral observer (eq. 40) with ``q = 2`` and
``alpha_k = C(4, k)``, and the Lipschitz structure ``M = diag(0, sqrt(rho))``,
``N = diag(sqrt(rho), 0)`` of the discrete-time part.

What the paper states and what is computed here (``summary.json``):

* eq. 68: ``Q(6) = diag(5 gamma^2, 4 gamma^4)``, ``P(6)`` (from the Riccati equation) and its
  gain ``(18, 72) = (alpha_i gamma^i)``; eq. 71: ``P^{-1/2}``, ``lambda_min = 3.5620``,
  ``2 sqrt(p_nn lambda_max) = 2.2713`` and ``rho < 1.5683``: all reproduced to the printed
  digits. ``gamma_min_for_rho_1_5``: the smallest ``gamma`` meeting (5) for ``rho = 1.5``
  (the paper only says that ``gamma = 6`` does).
* LMI (63)/(65): the paper's ``delta = 0.0915`` with ``tau = 0.0347`` is feasible; the
  optimum of (65) is ``delta_max = 0.0919`` (the paper's value is 0.4 % conservative, as a
  solver tolerance would make it).
* LMI (62): the paper's ``(X, epsilon)`` at ``delta = 0.01`` and ``0.525`` are feasible;
  bisection gives ``delta_max = 0.5286`` (paper 0.525, 0.7 % conservative).
* Simulation of the Euler observer (53) against the Euler-discretized plant (50) (Theorem 2's
  setting): the largest period at which it still converges, about ``1/6`` (the stability limit
  of its linear part, poles ``-6``, ``-12``), above the LMI (63) bound, which is sufficient.
* Figures 1-3: the standard and q-integral observers under the same white measurement noise;
  the root-mean-square error of ``x_2`` after the transient, next to the value the linear error
  dynamics predict (discrete Lyapunov equation).
* The same observers on the MuJoCo cart pendulum (``models/cart_pendulum.xml``, eq. 66).

Corrections to the paper (each shown by a number in the summary):

1. eq. 8 and condition (10) print ``sum_{k=i}^{n-1} (-1)^{k+i-1} alpha_{k+1} alpha_{k-1}``;
   eq. 17 (the proof) has ``alpha_{i+l} alpha_{i-l}``. They agree for ``n <= 3`` only. For the
   paper's own q-integral example (``N = 4``, ``alpha = C(4, k) = (4, 6, 4, 1)``) the printed
   eq. 8 gives ``q_22 = 16`` instead of 6, and the Riccati gain with that ``Q`` is
   ``(4.27, 7.10, 4.27, 1)``, not ``(4, 6, 4, 1)``. Eq. 17 is implemented.
2. eq. 68 prints ``(P^{-1})_{21} = +1/(7 gamma^2)``; ``P^{-1}`` is symmetric and
   ``(P^{-1})_{12} = -1/(7 gamma^2)`` (the paper's own ``P^{-1/2}`` in eq. 71 has a negative
   off-diagonal).
3. eq. 65 prints the (2,1) block as ``(A + alpha I) P^{-1} - C'C``, not the transpose of the
   (1,2) block; from eq. 63 it is ``P^{-1}(A + alpha I) - C'C``.
4. eq. 51 and 64 use ``phi(x_k, u_k)`` (the unknown true state); the error equation (54) needs
   ``phi(x_hat_k, u_k)`` as in eq. 53; eq. 64 also omits ``C'`` in ``delta P C'``. Eq. 6 and
   40 print ``gamma - C x_hat`` for ``y - C x_hat``; eq. 37 ``ÿ = xi_1`` for
   ``tilde y = xi_1``. Eq. 3 prints the chain as ``x_i' = x_i + 1`` for ``x_i' = x_{i+1}``.
   Eq. 57 prints its second factor with ``A_delta + X^{-1} C'C``; the error map (54), (56)
   and eq. 58 have ``A_delta - X^{-1} C'C`` (the sign LMI (62) is built from).
5. The q-integral observer at ``gamma = 6`` (the paper does not state its ``gamma``; its
   Fig. 3 suggests the same) does not meet condition (44) for ``rho = 1.5``: (44) admits
   ``rho <= 0.22`` there, and needs ``gamma >= 39.6``. It converges nevertheless (the
   condition is sufficient; the true Lipschitz constant of ``phi`` for ``|u| <= 0.5`` is
   ``sqrt(1.25) = 1.118``).
6. eq. 48: from ``Z = D Z~ D / gamma`` (eq. 46),
   ``|Z^{-1/2} B| = sqrt((Z~^{-1})_qq) gamma^(1/2 - q)``, which decays faster than the printed
   ``C_2 / gamma^(q/2)``; the printed bound still holds here (``gamma >= 1`` and
   ``sqrt((Z~^{-1})_22) = 0.41 <= lambda_max(Z~^{-1}) = 0.57`` for ``alpha = C(4, k)``).
   Either way it bounds ``W = |Z^{-1/2} e|``, not ``e``: the attenuation the figures show is
   that of the observer's transfer from ``y`` to ``x_hat``, of relative degree ``q + 1``
   instead of 1 (see :mod:`hgo_mj.observers.q_integral`).

References
----------
S. Ibrir, "On observer design for nonlinear systems", Int. J. Control, 2007
(``shared/papers/004_*``), eq. 5-10, 17, 37-48, 50-65, 66-71, Fig. 1-3.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from .._extras import require
from .._io import save_figure
from ..design import (
    binomial_coefficients,
    lipschitz_condition,
    max_sampling_period,
    min_gamma,
    riccati_gains,
    riccati_P,
    riccati_Q,
    riccati_weights,
    riccati_weights_as_printed,
    sampling_lmi_62,
    sampling_lmi_63,
)
from ..exceptions import DesignError
from ..progress import Progress
from . import finish

ALPHA = (3.0, 2.0)
GAMMA = 6.0
RHO = 1.5
Q_INT = 2
#: paper's numbers (eq. 71 and section 4)
PAPER = {"lambda_min": 3.5620, "two_sqrt_pnn_lmax": 2.2713, "rho_bound": 1.5683,
         "delta_max_lmi63": 0.0915, "tau_lmi63": 0.0347, "delta_max_lmi62": 0.525}
PAPER_P_INV_SQRT = [[0.2669, -0.0134], [-0.0134, 0.0285]]
PAPER_LMI62 = {0.01: (0.5671, [[1.5533, -0.1662], [-0.1662, 0.8352]]),
               0.525: (0.3415, [[1.1685, -0.3414], [-0.3414, 0.3119]])}
#: simulation setup (the paper states only u = 0.5 sin t)
SAMPLE_PERIOD = 0.01
DURATION = 40.0
T_TRANSIENT = 5.0
NOISE_STD = 0.05
SEED = 7
X0 = (0.5, -0.5)
X_HAT0 = (0.0, 0.0)


def lipschitz_structure(rho: float = RHO) -> tuple[np.ndarray, np.ndarray]:
    """``M``, ``N`` of section 4: ``delta B dphi/dx = delta M F N`` with ``|F| <= 1``."""
    s = np.sqrt(rho)
    return np.diag([0.0, s]), np.diag([s, 0.0])


def eq70(gamma: float) -> float:
    """``2 sqrt(p_nn lambda_max(P))`` in the closed form of eq. 70 (``alpha = (3, 2)``)."""
    g2 = gamma * gamma
    return 2.0 * float(np.sqrt(3.0 / 28.0 * (6.0 + 3.0 / g2 + np.sqrt(36.0 - 20.0 / g2 + 9.0 / g2**2))))


def _u(t: Any) -> Any:
    return 0.5 * np.sin(t)


def euler_final_errors(deltas: np.ndarray, gain: Any, steps: int, x0: Any = X0,
                       x_hat0: Any = X_HAT0) -> np.ndarray:
    """``|e_K| / |e_0|`` after ``steps`` steps of the Euler observer (53) (or (51) with a given
    discrete gain ``delta * gain``) against the Euler-discretized plant (50), for each period in
    ``deltas`` (vectorised; NaN/inf count as divergence, returned as ``inf``)."""
    d = np.asarray(deltas, dtype=float)
    L1, L2 = float(gain[0]), float(gain[1])
    x1 = np.full_like(d, x0[0])
    x2 = np.full_like(d, x0[1])
    h1 = np.full_like(d, x_hat0[0])
    h2 = np.full_like(d, x_hat0[1])
    e0 = np.hypot(x0[0] - x_hat0[0], x0[1] - x_hat0[1])
    with np.errstate(all="ignore"):
        for k in range(steps):
            u = _u(k * d)
            cu = u
            phi = np.sin(x1) + cu * np.cos(x1)
            phih = np.sin(h1) + cu * np.cos(h1)
            inn = x1 - h1
            x1, x2 = x1 + d * x2, x2 + d * phi
            h1, h2 = h1 + d * (h2 + L1 * inn), h2 + d * (phih + L2 * inn)
        err = np.hypot(x1 - h1, x2 - h2) / e0
    return np.where(np.isfinite(err), err, np.inf)


def largest_converging_period(gain: Any, lo: float, hi: float, *, steps: int = 20000,
                              points: int = 400, tol: float = 1e-6) -> tuple[float, np.ndarray,
                                                                            np.ndarray]:
    """Largest ``delta`` of a grid on ``[lo, hi]`` such that the Euler observer converges
    (``|e_K| <= tol |e_0|``) at it and at every grid period below it; refined once on a finer
    grid. Returns it, and the coarse grid with its final errors (for the figure)."""
    grid = np.linspace(lo, hi, points)
    err = euler_final_errors(grid, gain, steps)
    ok = err <= tol
    if not ok[0]:
        raise DesignError(f"the Euler observer does not converge even at delta = {lo:g}")
    i = len(ok) if ok.all() else int(np.argmin(ok))  # first failure
    best = grid[i - 1]
    if i < len(grid):
        fine = np.linspace(grid[i - 1], grid[i], 41)
        ok_f = euler_final_errors(fine, gain, steps) <= tol
        j = len(ok_f) if ok_f.all() else int(np.argmin(ok_f))
        best = fine[j - 1]
    return float(best), grid, err


def predicted_noise_rmse(M: np.ndarray, b: np.ndarray, std: float, index: int) -> float:
    """Stationary standard deviation of state ``index`` of ``w+ = M w + b v``, ``v ~ N(0, std^2)``
    (discrete Lyapunov equation; the linear part of the error dynamics, ``phi`` left out)."""
    from scipy.linalg import solve_discrete_lyapunov

    S = solve_discrete_lyapunov(M, std**2 * np.outer(b, b))
    return float(np.sqrt(S[index, index]))


def _rmse(traj: Any, name: str, col: int) -> float:
    sel = traj.t >= T_TRANSIENT
    return float(np.sqrt(np.mean(traj.error(name)[sel, col] ** 2)))


def _tolist(v: Any) -> Any:
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, dict):
        return {str(k): _tolist(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_tolist(x) for x in v]
    if isinstance(v, (np.floating, np.integer, np.bool_)):
        return v.item()
    return v


def design_numbers() -> dict[str, Any]:
    """Eq. 68-71, condition (5), and the corrections to eq. 8 and eq. 68 (no simulation)."""
    a, g = np.array(ALPHA), GAMMA
    P = riccati_P(a, g)
    w, V = np.linalg.eigh(P)
    P_inv = np.linalg.inv(P)
    cond = lipschitz_condition(a, g, RHO)
    aq = binomial_coefficients(2 + Q_INT)
    Qp = riccati_weights_as_printed(aq)
    A4 = np.diag(np.ones(3), 1)
    C4 = np.eye(4)[:1]
    from scipy.linalg import solve_continuous_are

    gain_printed = solve_continuous_are(A4.T, C4.T, np.diag(Qp), np.eye(1))[:, 0]
    cond_q = lipschitz_condition(aq, g, RHO)
    return {
        "Q_gamma6": riccati_Q(a, g),
        "P_gamma6": P,
        "P_gamma6_closed_form_eq68": np.array([[3 * g, 2 * g**2], [2 * g**2, 6 * g**3]]),
        "gain_gamma6": riccati_gains(a, g),
        "P_inv_gamma6": P_inv,
        "P_inv_21_times_gamma2": float(P_inv[1, 0] * g**2),
        "P_inv_21_times_gamma2_printed": 1.0 / 7.0,
        "P_inv_sqrt_gamma6": (V / np.sqrt(w)) @ V.T,
        "P_inv_sqrt_gamma6_paper": PAPER_P_INV_SQRT,
        "lambda_min": cond["lambda_min"],
        "two_sqrt_pnn_lmax": cond["two_sqrt_pnn_lmax"],
        "two_sqrt_pnn_lmax_eq70": eq70(g),
        "rho_bound": cond["rho_bound"],
        "condition5_satisfied_rho_1_5": cond["satisfied"],
        "gamma_min_for_rho_1_5": min_gamma(a, RHO),
        "qintegral_alpha": aq,
        "qintegral_Q_weights_eq17": riccati_weights(aq),
        "qintegral_Q_weights_eq8_as_printed": Qp,
        "qintegral_gain_from_eq8_as_printed_at_gamma1": gain_printed,
        "qintegral_condition44_gamma6": {k: cond_q[k] for k in ("lambda_min", "two_sqrt_pnn_lmax",
                                                                "rho_bound", "satisfied")},
        "gamma_min_qintegral_rho_1_5": min_gamma(aq, RHO),
    }


def lmi_numbers() -> dict[str, Any]:
    """LMI (63)/(65) and (62) for the pendulum; solve times; the paper's points checked."""
    a, g = np.array(ALPHA), GAMMA
    M, N = lipschitz_structure()
    t0 = time.perf_counter()
    r63 = max_sampling_period(a, g, M, N, lmi="63")
    cold = time.perf_counter() - t0
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        max_sampling_period(a, g, M, N, lmi="63")
        times.append(time.perf_counter() - t0)
    paper63 = sampling_lmi_63(a, g, M, N, PAPER["delta_max_lmi63"], tau=PAPER["tau_lmi63"])
    beyond63 = sampling_lmi_63(a, g, M, N, 1.01 * r63["delta_max"])
    r62 = max_sampling_period(a, g, M, N, lmi="62")
    at001 = sampling_lmi_62(M, N, 0.01)
    paper62 = {f"{d:g}": sampling_lmi_62(M, N, d, X=X, epsilon=e)["margin"]
               for d, (e, X) in PAPER_LMI62.items()}
    # LMI (65) for the q-integral observer (Z instead of P, augmented M, N)
    aq = binomial_coefficients(2 + Q_INT)
    Mq = np.zeros((4, 4))
    Nq = np.zeros((4, 4))
    Mq[3, 3] = np.sqrt(RHO)
    Nq[2, 2] = np.sqrt(RHO)
    try:
        q63: Any = max_sampling_period(aq, g, Mq, Nq, lmi="63")["delta_max"]
    except DesignError as exc:
        q63 = f"infeasible: {exc}"
    return {
        "delta_max_lmi63": r63["delta_max"],
        "tau_lmi63": r63["tau"],
        "lmi63_solve_time_s": min(times),
        "lmi63_solve_time_cold_s": cold,
        "paper_point_lmi63": {"delta": PAPER["delta_max_lmi63"], "tau": PAPER["tau_lmi63"],
                              "feasible": paper63["feasible"], "max_eig": paper63["max_eig"]},
        "lmi63_feasible_1pct_beyond": beyond63["feasible"],
        "delta_max_lmi62": r62["delta_max"],
        "lmi62_at_delta_max": {"X": r62["X"], "epsilon": r62["epsilon"], "gain": r62["gain"]},
        "lmi62_at_0_01": {"X": at001["X"], "epsilon": at001["epsilon"], "margin": at001["margin"]},
        "lmi62_solve_time_s": r62["solve_time_s"],
        "paper_X_lmi62_margin": paper62,
        "delta_max_lmi63_qintegral": q63,
    }


def euler_numbers(lmi: dict[str, Any]) -> dict[str, Any]:
    """Largest converging Euler period (simulation) against the LMI and linear-part bounds."""
    from ..observers import RiccatiObserver

    gain = riccati_gains(ALPHA, GAMMA)
    d_sim, grid, err = largest_converging_period(gain, 0.005, 0.25)
    lin = RiccatiObserver(None, order=2, alpha=ALPHA, gamma=GAMMA, model=False,
                          method="euler").max_stable_period()
    # the observer (51) with the gain re-designed by LMI (62) at its largest period
    d62 = lmi["delta_max_lmi62"]
    g62 = np.asarray(lmi["lmi62_at_delta_max"]["gain"]) / d62  # X^-1 C' = delta * gain
    e62 = float(euler_final_errors(np.array([d62]), g62, 4000)[0])
    return {"delta_max_sim_euler": d_sim, "delta_max_linear_euler": lin,
            "lmi62_gain_error_ratio_after_4000_steps": e62,
            "_grid": grid, "_err": err}


def noise_numbers() -> dict[str, Any]:
    """Fig. 1-3: standard and q-integral observers on the analytic plant under the same noise."""
    from ..inputs import Multisine
    from ..observers import QIntegralObserver, RiccatiObserver
    from ..observers.high_gain import one_step_map
    from ..observers.q_integral import q_integral_step_map
    from ..plants import OdePlant
    from ..sensors import GaussianNoise, SensorChain
    from ..simulate import simulate
    from ..systems import CartPendulum

    system = CartPendulum()
    plant = OdePlant(system, dt=SAMPLE_PERIOD, physics_dt=SAMPLE_PERIOD / 10)
    u = Multisine([0.5], [1.0 / (2.0 * np.pi)])

    def observers() -> dict[str, Any]:
        return {"standard": RiccatiObserver(system, alpha=ALPHA, gamma=GAMMA, x_hat0=X_HAT0),
                "q_integral": QIntegralObserver(system, q=Q_INT, gamma=GAMMA, x_hat0=X_HAT0),
                "q_integral_q1": QIntegralObserver(system, q=1, gamma=GAMMA, x_hat0=X_HAT0)}

    noisy = simulate(plant, SensorChain([GaussianNoise(NOISE_STD)]), observers(), u, DURATION,
                     x0=X0, seed=SEED)
    clean = simulate(plant, None, observers(), u, DURATION, x0=X0)
    # the same noise-free run at half the sample period: the noise-free error is that of the
    # measurement held over a sample (first order in the period), not of the observers
    half = SAMPLE_PERIOD / 2
    clean_half = simulate(OdePlant(system, dt=half, physics_dt=half / 10), None, observers(), u,
                          DURATION, x0=X0)
    M, b, _ = one_step_map(np.array(ALPHA), GAMMA, SAMPLE_PERIOD, "exact")
    Mq, bq, _ = q_integral_step_map(binomial_coefficients(2 + Q_INT), GAMMA, Q_INT,
                                    SAMPLE_PERIOD, "exact")
    out: dict[str, Any] = {
        "rmse_x2_standard": _rmse(noisy, "standard", 1),
        "rmse_x2_qintegral": _rmse(noisy, "q_integral", 1),
        "rmse_x2_qintegral_q1": _rmse(noisy, "q_integral_q1", 1),
        "rmse_x1_standard": _rmse(noisy, "standard", 0),
        "rmse_x1_qintegral": _rmse(noisy, "q_integral", 0),
        "rmse_x2_standard_predicted": predicted_noise_rmse(M, b, NOISE_STD, 1),
        "rmse_x2_qintegral_predicted": predicted_noise_rmse(Mq, bq, NOISE_STD, Q_INT + 1),
        "rmse_x2_standard_noise_free": _rmse(clean, "standard", 1),
        "rmse_x2_qintegral_noise_free": _rmse(clean, "q_integral", 1),
        "rmse_x2_standard_noise_free_half_period": _rmse(clean_half, "standard", 1),
        "rmse_x2_qintegral_noise_free_half_period": _rmse(clean_half, "q_integral", 1),
        "_noisy": noisy, "_clean": clean,
    }
    out["rmse_ratio_standard_over_qintegral"] = out["rmse_x2_standard"] / out["rmse_x2_qintegral"]
    return out


def mujoco_numbers(rrd: Path | None = None, reference: Any = None) -> dict[str, Any]:
    """The paper's observer (gamma = 6) and the q-integral one on the MuJoCo cart pendulum
    (same input, noise and seed as :func:`noise_numbers`, whose trajectory ``reference`` the
    MuJoCo states are compared with)."""
    from ..inputs import Multisine
    from ..observers import QIntegralObserver, RiccatiObserver
    from ..plants import make_plant
    from ..sensors import GaussianNoise, SensorChain
    from ..simulate import simulate

    plant = make_plant("cart_pendulum", dt=SAMPLE_PERIOD)
    system = plant.system
    u = Multisine([0.5], [1.0 / (2.0 * np.pi)])

    def observers() -> dict[str, Any]:
        return {"riccati": RiccatiObserver(system, alpha=ALPHA, gamma=GAMMA, x_hat0=X_HAT0),
                "q_integral": QIntegralObserver(system, q=Q_INT, gamma=GAMMA, x_hat0=X_HAT0)}

    noisy = simulate(plant, SensorChain([GaussianNoise(NOISE_STD)]), observers(), u, DURATION,
                     x0=X0, seed=SEED)
    clean = simulate(plant, None, observers(), u, DURATION, x0=X0)
    if rrd is not None:
        from ..record import record_trajectory

        record_trajectory(noisy, rrd)
    return {"plant": "MuJoCo models/cart_pendulum.xml (make_plant('cart_pendulum'))",
            "rmse_x2_riccati": _rmse(noisy, "riccati", 1),
            "rmse_x2_qintegral": _rmse(noisy, "q_integral", 1),
            "rmse_x2_riccati_noise_free": _rmse(clean, "riccati", 1),
            "rmse_x2_qintegral_noise_free": _rmse(clean, "q_integral", 1),
            "update_time_us": {k: 1e6 * r.update_time for k, r in noisy.observers.items()},
            "max_state_difference_vs_ode": (None if reference is None else
                                            float(np.abs(noisy.x - reference.x).max())),
            "_noisy": noisy}


# ------------------------------------------------------------------------------ figures
def _figures(out: Path, noise: dict[str, Any], euler: dict[str, Any], lmi: dict[str, Any],
             mj: dict[str, Any]) -> list[str]:
    from ..plotting import subplots

    tr = noise["_noisy"]
    files = []

    def estimate_figure(name: str, label: str, fname: str, title: str) -> None:
        fig, (ax, ae) = subplots(2, 1, figsize=(8, 5.2), sharex=True,
                                     gridspec_kw={"height_ratios": [2, 1]})
        ax.plot(tr.t, tr.x[:, 1], color="black", lw=1.4, label="$x_2$ (true)", zorder=3)
        ax.plot(tr.t, tr.observers[name].x_hat[:, 1], color="C3" if name == "standard" else "C0",
                lw=0.8, label=f"$\\hat x_2$ ({label})")
        ax.set_ylim(-3.5, 3.5)
        ax.set_ylabel("angular velocity $x_2$ [rad/time unit]")
        ax.legend(loc="upper right", fontsize=8)
        ax.set_title(title, fontsize=10)
        ae.plot(tr.t, tr.error(name)[:, 1], color="C3" if name == "standard" else "C0", lw=0.6)
        ae.axhline(0.0, color="0.6", lw=0.6)
        ae.set_ylim(-0.4, 0.4)
        ae.set_ylabel("$x_2 - \\hat x_2$ [rad/time unit]")
        ae.set_xlabel("t [-] (time-scaled units)")
        key = "rmse_x2_standard" if name == "standard" else "rmse_x2_qintegral"
        ae.text(0.99, 0.92, f"RMSE (t >= {T_TRANSIENT:g}) = {noise[key]:.4f}", ha="right",
                va="top", transform=ae.transAxes, fontsize=8)
        fig.tight_layout()
        save_figure(fig, out / fname)
        files.append(fname)

    estimate_figure("standard", "Riccati observer (67), $\\gamma=6$", "fig1_standard.png",
                    f"Fig. 1 analogue: standard high-gain observer, noise std {NOISE_STD:g}")
    estimate_figure("q_integral", "q-integral observer (40), q=2, $\\gamma=6$",
                    "fig3_q_integral.png",
                    "Fig. 3 analogue: q-integral observer (q=2), the same noise")

    fig, (ax, az) = subplots(1, 2, figsize=(10, 3.4), gridspec_kw={"width_ratios": [2, 1]})
    zoom = (tr.t >= 20.0) & (tr.t <= 22.0)
    for a_, sel in ((ax, slice(None)), (az, zoom)):
        a_.plot(tr.t[sel], tr.y_meas[sel, 0], color="0.55", lw=0.5, label="measured y")
        a_.plot(tr.t[sel], tr.x[sel, 0], color="black", lw=1.2, label="$x_1$")
        a_.set_xlabel("t [-] (time-scaled units)")
    ax.set_ylabel("angle $x_1$ [rad] (from upright)")
    ax.set_title(f"Fig. 2 analogue: noisy output (white Gaussian, std {NOISE_STD:g}, "
                 f"sampled every {SAMPLE_PERIOD:g})", fontsize=10)
    az.set_title("zoom, 20 <= t <= 22", fontsize=10)
    az.set_ylabel("$x_1$ [rad]")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    save_figure(fig, out / "fig2_noisy_output.png")
    files.append("fig2_noisy_output.png")

    fig, ax = subplots(figsize=(8, 4))
    err = np.clip(euler["_err"], 1e-18, 1e6)
    ax.semilogy(euler["_grid"], err, color="C0", lw=1.0, label="$|e_K| / |e_0|$, K = 20000")
    for d, c, ls, lab in ((lmi["delta_max_lmi63"], "C2", "--", "LMI (63) bound (sufficient)"),
                          (euler["delta_max_sim_euler"], "C3", "-", "largest converging (simulation)"),
                          (euler["delta_max_linear_euler"], "C1", ":",
                           "linear part stable up to")):
        ax.axvline(d, color=c, ls=ls, lw=1.2, label=f"{lab}: {d:.4f}")
    ax.axhline(1e-6, color="0.6", lw=0.6, label="convergence threshold 1e-6 (drawn clipped to [1e-18, 1e6])")
    ax.set_xlabel("sampling period $\\delta$ [-] (time-scaled units)")
    ax.set_ylabel("final error ratio $|e_K| / |e_0|$ [-]")
    ax.set_title("Euler observer (53) on the Euler-discretized pendulum (50), $\\gamma = 6$",
                 fontsize=10)
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    save_figure(fig, out / "fig4_euler_periods.png")
    files.append("fig4_euler_periods.png")

    tm = mj["_noisy"]
    fig, axes = subplots(2, 1, figsize=(8, 5.2), sharex=True)
    axes[0].plot(tm.t, tm.x[:, 1], color="black", lw=1.4, label="$x_2$ (MuJoCo)", zorder=3)
    for name, c in (("riccati", "C3"), ("q_integral", "C0")):
        axes[0].plot(tm.t, tm.observers[name].x_hat[:, 1], color=c, lw=0.7, label=name)
        axes[1].plot(tm.t, tm.error(name)[:, 1], color=c, lw=0.6, label=name)
    axes[0].set_ylim(-3.5, 3.5)
    axes[0].legend(fontsize=8, loc="upper right")
    axes[0].set_title("MuJoCo cart pendulum (eq. 66), u = 0.5 sin t, the same noise", fontsize=10)
    axes[1].set_ylim(-0.4, 0.4)
    axes[0].set_ylabel("angular velocity $x_2$ [rad/s]")
    axes[1].set_ylabel("$x_2 - \\hat x_2$ [rad/s]")
    axes[1].set_xlabel("t [s]")
    fig.tight_layout()
    save_figure(fig, out / "fig5_mujoco.png")
    files.append("fig5_mujoco.png")
    return files


def _report(s: dict[str, Any]) -> str:
    lm = s["paper_point_lmi63"]
    lines = [
        "Ibrir (2007), section 4: inverted pendulum (eq. 66), alpha = (3, 2), gamma = 6, rho = 1.5",
        "",
        "quantity                        this run        paper",
        f"lambda_min(P^-1/2 Q P^-1/2)     {s['lambda_min']:<15.6f} 3.5620",
        f"2 sqrt(p_nn lambda_max(P))      {s['two_sqrt_pnn_lmax']:<15.6f} 2.2713"
        f"   (eq. 70 closed form {s['two_sqrt_pnn_lmax_eq70']:.6f})",
        f"rho bound of (5)                {s['rho_bound']:<15.6f} 1.5683",
        f"gamma_min for rho = 1.5         {s['gamma_min_for_rho_1_5']:<15.6f} (not stated; 6 used)",
        f"delta_max, LMI (63)/(65)        {s['delta_max_lmi63']:<15.6f} 0.0915"
        f"   (tau {s['tau_lmi63']:.4f}; paper's point delta 0.0915, tau 0.0347 feasible: "
        f"{lm['feasible']}, max eig {lm['max_eig']:.2e})",
        f"delta_max, LMI (62)             {s['delta_max_lmi62']:<15.6f} 0.525"
        f"    (paper's X, epsilon feasible, margins {s['paper_X_lmi62_margin']})",
        f"largest converging Euler period {s['delta_max_sim_euler']:<15.6f} (simulation, "
        f"Euler plant; linear part stable up to {s['delta_max_linear_euler']:.6f})",
        f"LMI (63) solve time             {s['lmi63_solve_time_s']:.4f} s warm, "
        f"{s['lmi63_solve_time_cold_s']:.3f} s cold (cvxpy import + compile); "
        f"LMI (62) bisection {s['lmi62_solve_time_s']:.3f} s",
        "",
        f"Noise: white Gaussian, std {NOISE_STD:g}, sample period {SAMPLE_PERIOD:g}, seed {SEED}, "
        f"x(0) = {X0}, x_hat(0) = {X_HAT0}, RMSE over t >= {T_TRANSIENT:g}:",
        f"  x2 RMSE standard (67)       {s['rmse_x2_standard']:.5f}  "
        f"(linear prediction {s['rmse_x2_standard_predicted']:.5f}; noise-free "
        f"{s['rmse_x2_standard_noise_free']:.2e})",
        f"  x2 RMSE q-integral, q = 2   {s['rmse_x2_qintegral']:.5f}  "
        f"(linear prediction {s['rmse_x2_qintegral_predicted']:.5f}; noise-free "
        f"{s['rmse_x2_qintegral_noise_free']:.2e})",
        f"  x2 RMSE q-integral, q = 1   {s['rmse_x2_qintegral_q1']:.5f}",
        f"  ratio standard / q-integral {s['rmse_ratio_standard_over_qintegral']:.2f}",
        f"  The noise-free errors are not the observers': they are those of the measurement held "
        f"over each {SAMPLE_PERIOD:g} sample (the observers are integrated exactly with y(t_k) "
        f"held while the true y moves). At half the period they halve: "
        f"{s['rmse_x2_standard_noise_free_half_period']:.2e} (standard) and "
        f"{s['rmse_x2_qintegral_noise_free_half_period']:.2e} (q-integral) at "
        f"{SAMPLE_PERIOD / 2:g} (first order in the period).",
        "",
        f"MuJoCo cart pendulum, gamma = 6: x2 RMSE Riccati {s['mujoco']['rmse_x2_riccati']:.5f}, "
        f"q-integral {s['mujoco']['rmse_x2_qintegral']:.5f} (noise-free "
        f"{s['mujoco']['rmse_x2_riccati_noise_free']:.2e}, "
        f"{s['mujoco']['rmse_x2_qintegral_noise_free']:.2e})",
        "",
        "Corrections to the paper:",
    ]
    lines += [f"  {i + 1}. {c}" for i, c in enumerate(s["corrections"])]
    lines += ["", f"run time {s['run_time_s']:.1f} s"]
    return "\n".join(lines) + "\n"


def run(out: Path, *, rrd: Path | None = None, quiet: bool = False) -> dict[str, Any]:
    """Run the reproduction; write ``out/summary.json``, ``out/report.txt`` and the figures.

    Parameters
    ----------
    out : Path
        Output folder (created).
    rrd : Path, optional
        Also write a rerun recording of the noisy MuJoCo run there.
    quiet : bool
        No progress on stderr (:class:`hgo_mj.progress.Progress`, one step a part).

    Returns
    -------
    dict
        The summary, also written to ``out/summary.json`` (strict JSON); ``report.txt`` says
        what it means against the paper.

    Examples
    --------
    The reproduction (the design numbers, the LMI bounds and the runs) takes about half a minute on two cores;
    ``hgo-mj reproduce ibrir2007`` runs it from the command line:

    >>> from pathlib import Path
    >>> from hgo_mj.reproduce.ibrir2007 import run
    >>> summary = run(Path("runs/reproduce/ibrir2007"), quiet=True)  # doctest: +SKIP
    """
    for module in ("cvxpy", "clarabel"):  # its LMIs (the `lmi` extra), checked before any work
        require(module, "lmi", "the ibrir2007 reproduction")
    t0 = time.perf_counter()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with Progress(5, unit="part", desc="ibrir2007", quiet=quiet) as progress:
        design = design_numbers()
        progress.add()
        lmi = lmi_numbers()
        progress.add()
        euler = euler_numbers(lmi)
        progress.add()
        noise = noise_numbers()
        progress.add()
        mj = mujoco_numbers(rrd, reference=noise["_noisy"])
        progress.add()
    corrections = [
        "eq. 8 / condition (10): the sum must be sum_l (-1)^l alpha_(i+l) alpha_(i-l) (eq. 17); "
        f"for alpha = C(4,k) the printed form gives Q~ = {design['qintegral_Q_weights_eq8_as_printed']}"
        f" instead of {design['qintegral_Q_weights_eq17']}, and Riccati gain "
        f"{np.round(design['qintegral_gain_from_eq8_as_printed_at_gamma1'], 4).tolist()} instead of "
        f"{design['qintegral_alpha'].tolist()}",
        f"eq. 68: (P^-1)_21 gamma^2 = {design['P_inv_21_times_gamma2']:.6f} = -1/7, printed +1/7",
        "eq. 65: (2,1) block is P^-1 (A + alpha I) - C'C (the transpose of the (1,2) block), "
        "printed (A + alpha I) P^-1 - C'C (not symmetric)",
        "eq. 51/64: phi(x_hat_k, u_k), not phi(x_k, u_k); eq. 64: delta P C'; eq. 6/40: y - C x_hat",
        "eq. 3: the chain is x_i' = x_(i+1), printed x_i' = x_i + 1; eq. 57: the second factor is "
        "A_delta - X^-1 C'C (as in (54), (56), (58)), printed A_delta + X^-1 C'C",
        "q-integral observer at gamma = 6 does not meet condition (44) for rho = 1.5 (admits rho <= "
        f"{design['qintegral_condition44_gamma6']['rho_bound']:.4f}; needs gamma >= "
        f"{design['gamma_min_qintegral_rho_1_5']:.2f}); it converges in simulation anyway",
        f"delta_max of LMI (63) is {lmi['delta_max_lmi63']:.4f} (paper 0.0915, feasible but 0.4% "
        f"short of the optimum); of LMI (62) {lmi['delta_max_lmi62']:.4f} (paper 0.525)",
        "eq. 48: |Z^-1/2 B| = sqrt((Z~^-1)_qq) gamma^(1/2-q), not C2 / gamma^(q/2) (the printed "
        "bound holds here, loosely); it bounds |Z^-1/2 e|, not e",
    ]
    summary: dict[str, Any] = {
        "paper": "Ibrir 2007, On observer design for nonlinear systems, section 4",
        "alpha": list(ALPHA), "gamma": GAMMA, "rho": RHO, "q": Q_INT,
        "paper_values": PAPER,
        **design, **lmi,
        **{k: v for k, v in euler.items() if not k.startswith("_")},
        **{k: v for k, v in noise.items() if not k.startswith("_")},
        "mujoco": {k: v for k, v in mj.items() if not k.startswith("_")},
        "setup": {"sample_period": SAMPLE_PERIOD, "duration": DURATION,
                  "t_transient": T_TRANSIENT, "noise_std": NOISE_STD, "seed": SEED,
                  "x0": list(X0), "x_hat0": list(X_HAT0), "input": "u = 0.5 sin t",
                  "method": "exact (sampled-data) for Fig. 1-3 and MuJoCo; euler for the scan"},
        "corrections": corrections,
    }
    summary["figures"] = _figures(out, noise, euler, lmi, mj)
    summary["run_time_s"] = time.perf_counter() - t0
    summary = _tolist(summary)
    return finish(out, summary, _report(summary))


__all__ = ["run"]
