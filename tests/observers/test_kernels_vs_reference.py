"""Differential tests: the compiled kernels of the q-integral observer and of the adaptive-gain
observer with its model term against straightforward numpy references written here.

The references integrate the same equations with numpy arrays and the system's validated
``phi`` (an array argument): the q-integral observer by its one-step matrices
(:func:`~hgo_mj.observers.q_integral.q_integral_step_map`) or, for ``rk4``, by RK4 of
``w' = F w + e_q y + e_N phi``; the adaptive observer by RK4/Euler of the joint ODE in
``(k, z)`` (paper 000, eq. 2, 4-5) or, for ``exact``, by the model-free sampled-data step at the
start-of-sample gain (:func:`~hgo_mj.observers.high_gain.one_step_map`, i.e. the pole-matched
gain of :func:`~hgo_mj.observers.high_gain.matched_gain`), ``k`` advanced by
``dt gamma d(e)^2``, plus the held model term ``S B phi``. They must agree to 1e-12 (relative
to the largest value of each column) over a run on samples recorded from the MuJoCo plants,
dropouts included.

Only the public API of the observers is read: ``update``, ``w_`` (the q-integral observer's
state ``(eps_1..eps_q, x_hat)``), ``z_hat``, ``k_`` and ``diagnostics()``. The adaptive observer
exposes no unsaturated state: with ``z_bounds`` its ``z_hat`` is ``sat(z)``, so the reference's
``z`` is clipped to the bounds before the comparison (its unclipped ``z`` still drives the
reference, so a difference in the internal state shows up in the following samples), and the
tolerance stays relative to the unclipped reference, as when the internal state was compared
(clipping never increases a difference).
"""

from __future__ import annotations

import numpy as np
import pytest

from hgo_mj.inputs import Multisine
from hgo_mj.observers import AdaptiveGainObserver, QIntegralObserver
from hgo_mj.observers.adaptive_gain import dead_zone
from hgo_mj.observers.high_gain import one_step_map
from hgo_mj.observers.q_integral import q_integral_matrices, q_integral_step_map
from hgo_mj.plants import make_plant
from hgo_mj.sensors import SensorChain, encoder
from hgo_mj.simulate import simulate

DT = 1e-3
RTOL = 1e-12


@pytest.fixture(scope="module")
def recorded():
    """1.5 s of ``y`` and ``u`` from each plant (1 kHz, encoder with noise), with dropouts."""
    out = {}
    for name in ("pendulum", "elastic_joint"):
        plant = make_plant(name)
        traj = simulate(plant, SensorChain(encoder(65536, 1e-4), seed=0), None,
                        Multisine([0.4, 0.15], [0.5, 1.7]), 1.5, seed=0)
        ys = np.array(traj.y_meas, dtype=float)
        ys[200:204] = np.nan  # a dropout
        ys[900] = np.nan
        out[name] = (plant.system, ys, np.array(traj.u, dtype=float))
    return out


def rk4(f, x, dt):
    k1 = f(x)
    k2 = f(x + dt / 2 * k1)
    k3 = f(x + dt / 2 * k2)
    k4 = f(x + dt * k3)
    return x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def assert_close_runs(got, ref, scale_of=None):
    """``got`` within ``RTOL`` of ``ref``, relative to the largest value of each column of
    ``scale_of`` (default ``ref``)."""
    got, ref = np.asarray(got), np.asarray(ref)
    assert got.shape == ref.shape and np.all(np.isfinite(ref))
    scale = np.abs(ref if scale_of is None else scale_of).max(axis=0)
    np.testing.assert_array_less(np.abs(got - ref).max(axis=0), RTOL * scale + 1e-300)


# ------------------------------------------------------------------------------ q-integral
def q_integral_reference(ob: QIntegralObserver, system, ys, us) -> np.ndarray:
    """``w`` after each sample, with numpy arrays throughout."""
    q, N = ob.q, ob.N
    w = np.array(ob.w_)
    M, b, g = q_integral_step_map(ob.alpha, ob.gamma_, q, DT, ob.method)
    M0, _, g0 = q_integral_step_map(ob.alpha, ob.gamma_, q, DT, ob.method, closed=False)
    F = q_integral_matrices(ob.L, q)[0]
    (col,) = ob.outputs
    out = []
    for y, u in zip(ys, us):
        yi = y[col]
        if np.isnan(yi):
            w = M0 @ w + g0 * system.phi(w[q:], u)
        elif ob.method == "rk4":
            by = np.zeros(N)
            by[q - 1] = yi
            eN = np.eye(N)[-1]
            w = rk4(lambda v, by=by, eN=eN, u=u: F @ v + by + eN * system.phi(v[q:], u), w, DT)
        else:
            w = M @ w + b * yi + g * system.phi(w[q:], u)
        out.append(w.copy())
    return np.array(out)


@pytest.mark.parametrize("plant", ["pendulum", "elastic_joint"])
@pytest.mark.parametrize("method", ["exact", "euler", "rk4"])
@pytest.mark.parametrize("q", [1, 2])
def test_q_integral_kernel_matches_numpy_reference(recorded, plant, method, q):
    system, ys, us = recorded[plant]
    gamma = 20.0 if plant == "pendulum" else 100.0
    ob = QIntegralObserver(system, gamma=gamma, q=q, method=method)
    assert ob.outputs == (0,)
    ref = q_integral_reference(ob, system, ys, us)
    got = []
    for y, u in zip(ys, us):
        ob.update(y, u, DT)
        w = ob.w_
        assert w.shape == (ob.N,)
        np.testing.assert_array_equal(ob.z_hat, w[q:])  # no bounds: z_hat is x_hat's part
        got.append(w)
    assert ob.dropouts_ == 5
    assert ob.diagnostics() == {"gamma": gamma, "dropouts": 5.0}
    assert_close_runs(got, ref)


# ---------------------------------------------------------------------------- adaptive gain
def adaptive_reference(ob: AdaptiveGainObserver, system, ys, us) -> np.ndarray:
    """``(k, z)`` after each sample, with numpy arrays throughout (``z`` unsaturated)."""
    n, p = ob.n, ob.p
    lo, hi = ob.z_bounds if ob.z_bounds is not None else (np.full(n, -np.inf), np.full(n, np.inf))
    M0, _, g0 = one_step_map(p, 1.0, DT, ob.method, closed=False)
    s = np.concatenate(([ob.k0], ob.z_hat))
    A = np.diag(np.ones(n - 1), 1)
    en = np.eye(n)[-1]
    (col,) = ob.outputs

    def phi(z, u):
        return system.phi(np.clip(z, lo, hi), u)

    out = []
    for y, u in zip(ys, us):
        yi = y[col]
        k, z = s[0], s[1:]
        if np.isnan(yi):
            s = np.concatenate(([k], M0 @ z + g0 * phi(z, u)))
        elif ob.method == "exact":
            # the model-free sampled-data step at the start-of-sample gain (M = Phi - Ld C with
            # the pole-matched Ld), k by the held innovation, then the held model term S B phi
            M, b, _ = one_step_map(p, k, DT, "exact")
            e = yi - z[0]
            k_next = k + DT * ob.gamma * float(dead_zone(e, ob.lam, ob.lam_hat)) ** 2
            s = np.concatenate(([k_next], M @ z + b * yi + g0 * phi(z, u)))
        else:
            ph = phi(z, u) if ob.method == "euler" else None

            def f(v, yi=yi, u=u, ph=ph):
                kk, zz = v[0], v[1:]
                e = yi - zz[0]
                dk = ob.gamma * float(dead_zone(e, ob.lam, ob.lam_hat)) ** 2
                m = ph if ph is not None else phi(zz, u)
                dz = A @ zz + p * kk ** np.arange(1, n + 1) * e + en * m
                return np.concatenate(([dk], dz))

            s = s + DT * f(s) if ob.method == "euler" else rk4(f, s, DT)
        out.append(s.copy())
    return np.array(out)


@pytest.mark.parametrize("plant", ["pendulum", "elastic_joint"])
@pytest.mark.parametrize("method", ["exact", "euler", "rk4"])
@pytest.mark.parametrize("bounded", [False, True])
def test_adaptive_model_kernel_matches_numpy_reference(recorded, plant, method, bounded):
    system, ys, us = recorded[plant]
    n = system.normal_form_order
    k0 = 20.0 if plant == "pendulum" else 100.0
    zb = (np.full(n, -1.0), np.full(n, 1.0)) if bounded else None  # clips during the transient
    ob = AdaptiveGainObserver(system, lam=1e-4, lam_hat=1e-3, gamma=1e5, k0=k0, model=True,
                              method=method, z_bounds=zb)
    raw = adaptive_reference(ob, system, ys, us)
    ref = raw.copy()
    if bounded:  # the observer reports sat(z) (module docstring)
        ref[:, 1:] = np.clip(raw[:, 1:], zb[0], zb[1])
        assert (np.abs(raw[:, 1:]) > 1.0).any()  # the saturation is exercised
    got = []
    for y, u in zip(ys, us):
        ob.update(y, u, DT)
        k = ob.diagnostics()["k"]
        assert k == ob.k_
        got.append((k, *ob.z_hat))
    assert ob.dropouts_ == 5
    assert ob.diagnostics()["dropouts"] == 5.0
    assert ob.k_ > k0  # the gain adapted: the k-equation is exercised
    assert_close_runs(got, ref, scale_of=raw)
