"""One working construction of every registered observer, shared by the observer-wide
tests (pickling, conformance), and a smooth test signal with a dropout."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from hgo_mj.observers import make_observer
from hgo_mj.observers.base import Observer
from hgo_mj.observers.bastin_gevers import AOCF, BastinGeversObserver
from hgo_mj.observers.besancon import AffineForm, BesanconObserver
from hgo_mj.observers.jo_son import JoSonObserver
from hgo_mj.systems import (
    BesanconExample1,
    BesanconExample2,
    BioreactorBastinGevers,
    CartPendulum,
    ElasticJoint,
    ElasticJoint2Link,
    JoSonExample,
    Pendulum,
)
from hgo_mj.systems.elastic_joint import jo_son_motor_side

DT = 0.01

# (registered name, case id, constructor, number of measured channels, number of inputs)
Case = tuple[str, str, Callable[[], Observer], int, int]

CASES: list[Case] = [
    # the high-gain family (settings of the environments' tasks)
    ("high_gain", "pendulum", lambda: make_observer("high_gain", Pendulum(), k=10.0, model=True), 1, 1),
    ("high_gain_multi", "pendulum",
     lambda: make_observer("high_gain_multi", Pendulum(), k=20.0, orders=(2,)), 1, 1),
    ("adaptive_gain", "pendulum",
     lambda: make_observer("adaptive_gain", Pendulum(), lam=0.04, lam_hat=0.08, gamma=200.0,
                           k0=20.0, k_max=60.0, method="exact"), 1, 1),
    ("riccati", "pendulum", lambda: make_observer("riccati", Pendulum(), gamma=20.0), 1, 1),
    ("q_integral", "pendulum", lambda: make_observer("q_integral", Pendulum(), gamma=20.0, q=1), 1, 1),
    # Bastin-Gevers: AOCFs built from closures (pendulum, cart pendulum) and the bioreactor's
    ("bastin_gevers", "pendulum",
     lambda: BastinGeversObserver(Pendulum(), c1=5.0, gamma=[2.0, 3.0], theta_hat0=[1.0, 1.0]), 1, 1),
    ("bastin_gevers", "pendulum-coefficient",
     lambda: BastinGeversObserver(Pendulum(), damping_known="coefficient", theta_hat0=[1.0, 1.0]),
     1, 1),
    ("bastin_gevers", "cart-pendulum-damping",
     lambda: BastinGeversObserver(CartPendulum(), unknown=("d_over_J", "g_over_l", "b_over_J")), 1, 1),
    ("bastin_gevers", "bioreactor-aocf",
     lambda: BastinGeversObserver(aocf=AOCF.bioreactor(BioreactorBastinGevers(), 1.0), c1=5.0,
                                  gamma=20.0, theta_hat0=[-3.0, -0.1, -0.1], z_hat0=[1.0, 1.0]),
     1, 2),
    # Jo-Son: forms of closures
    ("jo_son", "example", lambda: JoSonObserver(JoSonExample(), lam=2.0, gamma=5.0), 1, 1),
    ("jo_son", "motor-side",
     lambda: JoSonObserver(form=jo_son_motor_side(), lam=50.0,
                           gamma=(1e4, 20.0, 1e6)), 3, 1),
    # Besancon: generated code (pendulum, the adaptation frozen at first), closures (elastic
    # joint, with the map to physical coordinates), the papers' examples and the protocol
    ("besancon", "pendulum",
     lambda: BesanconObserver(Pendulum(), lam=10.0, theta_hat0=[5.0, 1.0], adapt_after=0.03,
                              excitation_window=0.05), 1, 1),
    ("besancon", "elastic-joint",
     lambda: BesanconObserver(ElasticJoint(), lam=20.0, theta_hat0=[1.0, 9.0, 9.0],
                              gain=[1e-5, 1e-7, 1e-7], method="rk4"), 1, 1),
    ("besancon", "example-2",
     lambda: BesanconObserver(BesanconExample2(), lam=5.0, hold="innovation"), 2, 1),
    ("besancon", "protocol-form",
     lambda: BesanconObserver(form=AffineForm.from_protocol(BesanconExample1()), lam=5.0,
                              gain=[[2.0, 0.3], [0.3, 0.5]]), 1, 1),
    # Kalman filters: the float path (small), numpy (the two-link arm), augmentation
    ("ekf", "pendulum", lambda: make_observer("ekf", Pendulum()), 1, 1),
    ("ekf", "pendulum-estimate-g",
     lambda: make_observer("ekf", Pendulum(), estimate=("g",), theta_hat0=[9.0], R=1e-4), 1, 1),
    ("ekf", "two-link", lambda: make_observer("ekf", ElasticJoint2Link(), R=1e-4), 2, 2),
    ("ukf", "pendulum", lambda: make_observer("ukf", Pendulum()), 1, 1),
    ("ukf", "elastic-joint-estimate",
     lambda: make_observer("ukf", ElasticJoint(), estimate=("stiffness",), theta_hat0=[90.0],
                           R=1e-4), 1, 1),
    ("ukf", "two-link", lambda: make_observer("ukf", ElasticJoint2Link(), R=1e-4), 2, 2),
    ("ekf_mujoco", "pendulum-estimate-damping",
     lambda: make_observer("ekf_mujoco", Pendulum(), estimate=("damping",), theta_hat0=[0.05],
                           R=1e-4), 1, 1),
    ("ukf_mujoco", "pendulum", lambda: make_observer("ukf_mujoco", Pendulum(), R=1e-4), 1, 1),
    # baselines outside the papers (the benchmark issue, item 4)
    ("finite_difference", "pendulum",
     lambda: make_observer("finite_difference", Pendulum(), tau=0.02), 1, 1),
    ("super_twisting", "pendulum-model",
     lambda: make_observer("super_twisting", Pendulum(), L=20.0, model=True, substeps=2), 1, 1),
    ("extended_luenberger", "pendulum",
     lambda: make_observer("extended_luenberger", Pendulum(), omega=15.0), 1, 1),
    ("kinematic_kalman", "pendulum",
     lambda: make_observer("kinematic_kalman", Pendulum(), q=100.0, r=1e-6), 1, 1),
    ("kinematic_kalman", "model-free-order-3",
     lambda: make_observer("kinematic_kalman", None, order=3, q=10.0, r=1e-6), 1, 1),
    ("mhe", "pendulum",
     lambda: make_observer("mhe", Pendulum(), q=5.0, r=1e-4, p0=0.5, horizon=6), 1, 1),
]

def signals(k: int, p: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Measurements and inputs of sample ``k``: smooth, with a dropout at k = 7."""
    t = k * DT
    y = np.array([0.3 * math.sin(2.0 * t + c) + 0.01 * c for c in range(p)])
    if k == 7:
        y[0] = math.nan
    u = np.array([0.2 * math.cos(3.0 * t + j) + 0.5 for j in range(m)])
    return y, u


def advance(ob: Observer, Y: np.ndarray, U: np.ndarray, dt: float):
    """Consume the block ``Y`` ``(B, T, p)``, ``U`` ``(B, T, m)`` on the observer's own state
    through the pure step (``Observer.step``), keep the new state, return the rows."""
    params, state = ob._own()
    new, rows = ob.step(params, state, Y, U, dt)
    ob._hold(params, new)
    return rows
