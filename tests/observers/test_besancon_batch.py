"""The Besançon observer (paper 001, eq. 12 / 24) on the batch axis: B members advanced together
equal each member advanced alone, bit for bit, and a block of T samples equals T single steps,
for every configuration of the family (integration methods, held measurement or innovation,
saturations, adaptation frozen at first, substeps, one and two outputs with dropouts, the
systems' compiled forms, the maps to physical coordinates, the protocol form)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from observer_cases import advance

from hgo_mj.observers.besancon import AffineForm, BesanconObserver
from hgo_mj.systems import BesanconExample1, BesanconExample2, ElasticJoint, ElasticJoint2Link, Pendulum

B = 64
T = 200


def _streams(p: int, m: int, dt: float, seed: int, scale: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """B different smooth measurement streams (phases per member and channel) with NaN
    dropouts (5 %, independent per channel), and B different inputs."""
    rng = np.random.default_rng(seed)
    t = np.arange(T) * dt
    ph = rng.uniform(0, 2 * np.pi, size=(B, 1, p))
    Y = scale * np.sin(2.0 * t[None, :, None] + ph) + 0.05 * rng.normal(size=(B, 1, p))
    Y[rng.random(size=Y.shape) < 0.05] = np.nan
    U = 0.2 * np.cos(3.0 * t[None, :, None] + rng.uniform(0, 2 * np.pi, size=(B, 1, m))) + 0.1
    return Y, U


# (id, constructor, dt, initial state rows (B) -> reset keywords)
def _z_theta(n: int, q: int, th: np.ndarray, zs: float = 0.1, ts: float = 0.05):
    def make(rng: np.random.Generator) -> dict[str, np.ndarray]:
        return {"z_hat0": zs * rng.normal(size=(B, n)),
                "theta_hat0": th * (1.0 + ts * rng.normal(size=(B, q)))}
    return make


def _ej_physical(rng: np.random.Generator) -> dict[str, np.ndarray]:
    x0 = np.array([0.3, 0.3, 0.0, 0.0]) + 0.02 * rng.normal(size=(B, 4))
    return {"x_hat0": x0, "theta_hat0": np.array([0.8, 7.0, 5.6]) * (1 + 0.05 * rng.normal(size=(B, 3)))}


CASES = [
    ("ex1-rk2-measurement", lambda: BesanconObserver(BesanconExample1(), lam=10.0), 0.01,
     _z_theta(2, 2, np.array([0.5, 1.0]))),
    ("ex1-rk4-innovation-saturated", lambda: BesanconObserver(
        BesanconExample1(), lam=10.0, X=0.5, Theta=1.2, method="rk4", hold="innovation",
        excitation_window=0.2), 0.01, _z_theta(2, 2, np.array([0.5, 0.9]))),
    ("ex1-euler-substeps-gain", lambda: BesanconObserver(
        BesanconExample1(), lam=10.0, method="euler", substeps=2, K0=(3.0, 2.0),
        gain=[[2.0, 0.3], [0.3, 0.5]], adapt_after=0.5, excitation_window=0.1), 0.01,
     _z_theta(2, 2, np.array([0.5, 1.0]))),
    ("ex1-protocol-form", lambda: BesanconObserver(
        form=AffineForm.from_protocol(BesanconExample1()), lam=5.0, excitation_window=0.3), 0.01,
     _z_theta(2, 2, np.array([0.5, 1.0]))),
    ("ex2-two-outputs-innovation", lambda: BesanconObserver(
        BesanconExample2(), lam=5.0, X=100.0, Theta=20.0, hold="innovation",
        excitation_window=0.5), 0.01, _z_theta(4, 2, np.array([5.0, -2.0]))),
    ("pendulum-gain-frozen", lambda: BesanconObserver(
        Pendulum(), lam=20.0, gain=100.0, adapt_after=0.05, excitation_window=0.05), 0.001,
     _z_theta(2, 2, np.array([30.0, 20.0]))),
    ("pendulum-three-unknowns-rk4", lambda: BesanconObserver(
        Pendulum(), unknown=("d_over_J", "g_over_l", "b_over_J"), lam=20.0, gain=10.0,
        method="rk4"), 0.001, _z_theta(2, 3, np.array([0.1, 30.0, 20.0]))),
    ("elastic-joint-physical", lambda: BesanconObserver(
        ElasticJoint(), lam=20.0, gain=[1e-5, 1e-7, 1e-7], X=2e4, Theta=30.0,
        theta_hat0=[0.8, 7.0, 5.6], hold="innovation", excitation_window=0.05), 0.001, _ej_physical),
    ("elastic-joint-stiffness-only", lambda: BesanconObserver(
        ElasticJoint(), unknown=("stiffness",), lam=20.0, gain=1e-6, theta_hat0=[9.0]), 0.001,
     _z_theta(4, 1, np.array([9.0]), zs=0.01)),
    ("two-link-arm", lambda: BesanconObserver(
        ElasticJoint2Link(), lam=30.0, gain=[1e-6, 1e-7], X=1e5, Theta=100.0, theta_hat0=[14.0, 4.2],
        hold="innovation", adapt_after=0.02, excitation_window=0.05), 0.001,
     _z_theta(8, 2, np.array([14.0, 4.2]), zs=0.01)),
]


def _block(ob: BesanconObserver, Y: np.ndarray, U: np.ndarray, dt: float) -> list[np.ndarray]:
    blk = advance(ob, Y, U, dt)
    return [blk.x_hat, blk.z_hat, blk.diagnostics, ob.state_rows, ob.inverse_failures_]


@pytest.mark.parametrize("make,dt,init", [pytest.param(m, d, i, id=c) for c, m, d, i in CASES])
def test_batch_equals_members_alone(make, dt, init):
    ob = make()
    p, m = ob.form.p, ob.n_inputs
    rng = np.random.default_rng(7)
    kw = init(rng)
    Y, U = _streams(p, m, dt, seed=11, scale=0.3)
    ob.reset(**kw)
    assert ob.batch == B
    together = _block(ob, Y, U, dt)
    assert np.all(np.isfinite(together[1]))
    assert (ob.dropouts_ > 0).any()
    assert ob.theta_hat_.shape == (B, ob.q) and ob.Gamma_.shape == (B, ob.n, ob.q)
    diag = ob.diagnostics()
    assert set(diag) == set(ob.diagnostic_names) and diag["dropouts"].shape == (B,)
    alone = make()
    for b in range(B):
        alone.reset(**{k: v[b] for k, v in kw.items()}, batch=1)
        one = _block(alone, Y[b:b + 1], U[b:b + 1], dt)
        for got, want in zip(one, together):
            np.testing.assert_array_equal(got[0], want[b])


@pytest.mark.parametrize("make,dt,init", [pytest.param(m, d, i, id=c) for c, m, d, i in CASES])
def test_block_equals_single_steps(make, dt, init):
    ob = make()
    p, m = ob.form.p, ob.n_inputs
    kw = {k: v[:8] for k, v in init(np.random.default_rng(3)).items()}
    Y, U = _streams(p, m, dt, seed=5)
    Y, U = Y[:8], U[:8]
    ob.reset(**kw)
    blk = advance(ob, Y, U, dt)
    ob.reset(**kw)
    rows = []
    for j in range(T):
        ob.update(Y[:, j], U[:, j], dt)
        rows.append((ob.x_hat, ob.z_hat, ob.excitation_))
    np.testing.assert_array_equal(np.stack([r[0] for r in rows], axis=1), blk.x_hat)
    np.testing.assert_array_equal(np.stack([r[1] for r in rows], axis=1), blk.z_hat)
    np.testing.assert_array_equal(np.stack([r[2] for r in rows], axis=1), blk.diagnostics[:, :, -2])
    # and a pickled copy continues identically
    copy = pickle.loads(pickle.dumps(ob))
    a = advance(ob, Y[:, :20], U[:, :20], dt)
    c = advance(copy, Y[:, :20], U[:, :20], dt)
    np.testing.assert_array_equal(a.x_hat, c.x_hat)
    np.testing.assert_array_equal(a.diagnostics, c.diagnostics)


def test_unbatched_public_shapes_and_defaults():
    """A plain reset() is one unbatched member from the constructor's initial values; a batch
    reset tiles them; each value not given is the constructor's."""
    ob = BesanconObserver(BesanconExample1(), lam=10.0, z_hat0=[0.2, 0.1], theta_hat0=[0.5, 1.0])
    assert ob.z_hat.shape == (2,) and ob.theta_hat_.tolist() == [0.5, 1.0]
    assert isinstance(ob.excitation_, float) and ob.Gamma_.shape == (2, 2)
    ob.reset(batch=3)
    np.testing.assert_array_equal(ob.z_hat, [[0.2, 0.1]] * 3)
    np.testing.assert_array_equal(ob.theta_hat_, [[0.5, 1.0]] * 3)
    ob.reset(theta_hat0=np.array([[0.1, 0.2], [0.3, 0.4]]))
    assert ob.batch == 2
    np.testing.assert_array_equal(ob.z_hat, [[0.2, 0.1]] * 2)
    ob.reset(z_hat0=[0.0, 0.0])
    np.testing.assert_array_equal(ob.theta_hat_, [0.5, 1.0])


def test_inverse_failures_hold_the_last_physical_value():
    """The elastic joint's map to physical coordinates needs a positive stiffness estimate:
    where a member's estimate is not, x_hat holds its last value and the failure is counted,
    for that member only."""
    ob = BesanconObserver(ElasticJoint(), unknown=("stiffness",), lam=20.0, gain=1e-6,
                          theta_hat0=[9.0])
    ob.reset(theta_hat0=np.array([[9.0], [9.0]]))
    advance(ob, np.full((2, 1, 1), 0.1), np.zeros((2, 1, 1)), 0.001)
    held = ob.x_hat.copy()
    S = ob._S
    S[1, ob.n] = -1.0  # member 1's stiffness estimate leaves the domain
    blk = advance(ob, np.full((2, 3, 1), 0.1), np.zeros((2, 3, 1)), 0.001)
    np.testing.assert_array_equal(ob.inverse_failures_, [0, 3])
    np.testing.assert_array_equal(blk.x_hat[1], np.tile(held[1], (3, 1)))
    assert np.all(np.isfinite(blk.x_hat[0])) and not np.array_equal(blk.x_hat[0, -1], held[0])


def test_dt_changes_between_blocks():
    """A jittered period: one design for every dt (no per-dt state)."""
    ob = BesanconObserver(Pendulum(), lam=20.0, gain=10.0)
    rng = np.random.default_rng(0)
    for _ in range(200):
        ob.update(np.array([0.3]), np.array([0.1]), 0.001 * (1 + 0.1 * rng.random()))
    assert np.all(np.isfinite(ob.x_hat))
