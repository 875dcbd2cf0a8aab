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

from hgo_mj.exceptions import DesignError, DimensionError
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
    S = ob.state.S
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


# ----------------------------------------------------------------- parameters as data
# (id, constructor taking the tunable parameters, dt, per-member lam, K0 (n,), gain (q, q))
TUNED = [
    ("ex1-adapt-after-excitation", lambda **kw: BesanconObserver(
        BesanconExample1(), X=10.0, Theta=10.0, theta_hat0=[0.5, 1.0], adapt_after=0.05,
        excitation_window=0.1, **kw), 0.01,
     [10.0, 5.0, 20.0, 10.0], [[2.0, 1.0], [3.0, 2.0], [2.0, 1.0], [2.0, 1.0]],
     [np.eye(2), np.diag([2.0, 0.5]), [[1.0, 0.3], [0.3, 0.5]], np.eye(2)]),
    ("ex2-two-chains-innovation", lambda **kw: BesanconObserver(
        BesanconExample2(), X=100.0, Theta=20.0, hold="innovation", excitation_window=0.5,
        method="rk4", **kw), 0.01,
     [5.0, 3.0, 8.0], [[2.0, 1.0, 2.0, 1.0], [3.0, 2.0, 2.0, 1.0], [2.0, 1.0, 4.0, 4.0]],
     [np.eye(2), 0.5 * np.eye(2), [[2.0, 0.1], [0.1, 1.0]]]),
    ("elastic-joint-physical", lambda **kw: BesanconObserver(
        ElasticJoint(), X=2e4, Theta=30.0, theta_hat0=[0.8, 7.0, 5.6], excitation_window=0.05,
        **kw), 0.001,
     [20.0, 15.0, 25.0], [[4.0, 6.0, 4.0, 1.0], [4.0, 6.0, 4.0, 1.0], [5.0, 9.0, 7.0, 2.0]],
     [np.diag([1e-5, 1e-7, 1e-7]), np.diag([2e-5, 1e-7, 1e-7]), np.diag([1e-5, 3e-7, 1e-7])]),
]


@pytest.mark.parametrize("make,dt,lams,Ks,gains", [pytest.param(*c[1:], id=c[0]) for c in TUNED])
def test_members_with_their_own_parameters_equal_their_single_runs(make, dt, lams, Ks, gains):
    """One batch whose members have different high gains, Hurwitz gains and adaptation gains
    (some shared, some not) equals, member by member, the single run of an observer built with
    that member's values, bit for bit, through a NaN dropout; step leaves its state alone."""
    ob = make(lam=10.0)
    nb, p, m, n = len(lams), ob.form.p, ob.n_inputs, ob.n
    params = ob.parameters(nb, lam=lams, K0=Ks, gain=np.array(gains, dtype=float))
    assert params.lam.shape == (nb,) and params.K0.shape == (nb, n)
    assert params.gain.shape == (nb, ob.q, ob.q)
    state = ob.init(nb, params=params)
    Y, U = _streams(p, m, dt, seed=23, scale=0.2)
    Y, U = Y[:nb, :120], U[:nb, :120]
    Y[:, 3, 0] = np.nan  # a dropout in every member
    before = state.copy()
    s1, first = ob.step(params, state, Y[:, :50], U[:, :50], dt)
    for k, v in before.fields.items():  # the state passed in is unchanged
        np.testing.assert_array_equal(state.fields[k], v)
    s2, second = ob.step(params, s1, Y[:, 50:], U[:, 50:], dt)
    assert not np.array_equal(s2.S, s1.S)
    x = np.concatenate((first.x_hat, second.x_hat), axis=1)
    z = np.concatenate((first.z_hat, second.z_hat), axis=1)
    d = np.concatenate((first.diagnostics, second.diagnostics), axis=1)
    assert (d[:, -1, -1] >= 1).all()  # the dropout counted
    assert np.isfinite(d[:, -1, ob.diagnostic_names.index("excitation")]).all()
    for b in range(nb):
        alone = make(lam=lams[b], K0=Ks[b] if p == 1 else [Ks[b][:2], Ks[b][2:]], gain=gains[b])
        rows = alone.run(Y[b], U[b], dt)
        np.testing.assert_array_equal(rows.x_hat[0], x[b])
        np.testing.assert_array_equal(rows.z_hat[0], z[b])
        np.testing.assert_array_equal(rows.diagnostics[0], d[b])
        for k, v in alone.state.fields.items():
            np.testing.assert_array_equal(v[0], s2.fields[k][b], err_msg=k)
    # current() of the batch reads each member's own parameters
    xc, zc, dc = ob.current(params, s2)
    np.testing.assert_array_equal(zc, z[:, -1])
    np.testing.assert_array_equal(dc, d[:, -1])


def test_parameters_refuse_what_the_constructor_refuses():
    ob = BesanconObserver(BesanconExample1(), lam=10.0)
    with pytest.raises(DesignError, match="lam must be > 0"):
        ob.parameters(3, lam=[10.0, -1.0, 5.0])
    with pytest.raises(DesignError, match="K0 must give a Hurwitz polynomial"):
        ob.parameters(3, K0=[[2.0, 1.0], [-1.0, 1.0], [2.0, 1.0]])
    with pytest.raises(DesignError, match=r"gain must be positive definite; found eigenvalues \[-1.0, 1.0\]"):
        ob.parameters(3, gain=np.array([np.eye(2), [[0.0, 1.0], [1.0, 0.0]], np.eye(2)]))
    with pytest.raises(DesignError, match="gain must be symmetric"):
        ob.parameters(2, gain=[[1.0, 0.5], [0.0, 1.0]])
    with pytest.raises(DimensionError, match=r"K0 must have n = 2 gains .*; found 4"):
        ob.parameters(3, K0=[1.0, 2.0, 3.0, 4.0])
    two = BesanconObserver(BesanconExample2(), lam=5.0)
    with pytest.raises(DesignError, match=r"K0\[1\] must give a Hurwitz polynomial"):
        two.parameters(1, K0=[2.0, 1.0, 1.0, -1.0])
    assert two.parameters(1).K0.tolist() == [[2.0, 1.0, 2.0, 1.0]]  # the chains concatenated


def test_restarting_a_member_restarts_its_clock_and_excitation():
    """Each member has its own clock (adapt_after) and excitation ring: a member restarted
    mid-run equals a fresh single run from then on; the others go on untouched."""
    make = TUNED[0][1]
    dt = 0.01
    ob, ref = make(lam=10.0), make(lam=10.0)
    Y, U = _streams(1, 1, dt, seed=31, scale=0.2)
    Y, U = Y[:3, :150], U[:3, :150]
    for o in (ob, ref):
        o.reset(batch=3)
        advance(o, Y[:, :40], U[:, :40], dt)
    ob.reset_members([1])
    assert ob.state.t.tolist()[1] == 0.0 and ob.state.nblocks.tolist()[1] == 0
    out, want = advance(ob, Y[:, 40:], U[:, 40:], dt), advance(ref, Y[:, 40:], U[:, 40:], dt)
    alone = make(lam=10.0).run(Y[1, 40:], U[1, 40:], dt)
    for b in (0, 2):
        np.testing.assert_array_equal(out.x_hat[b], want.x_hat[b])
        np.testing.assert_array_equal(out.diagnostics[b], want.diagnostics[b])
    np.testing.assert_array_equal(out.x_hat[1], alone.x_hat[0])
    np.testing.assert_array_equal(out.diagnostics[1], alone.diagnostics[0])
