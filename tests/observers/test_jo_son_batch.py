"""Jo-Son observer (paper 003, eq. 27) with a batch axis: B members advanced together equal
each member run alone, bit for bit, and a block of T samples equals T single steps."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from observer_cases import advance

from hgo_mj.exceptions import DesignError, DimensionError
from hgo_mj.observers.jo_son import JoSonForm, JoSonObserver
from hgo_mj.systems import ElasticJoint
from hgo_mj.systems.elastic_joint import jo_son_motor_side
from hgo_mj.systems.papers import JoSonExample

B, T = 64, 240

# (id, constructor, measured channels, inputs, sample period, initial-state scale)
CONFIGS = [
    ("example-rk4", lambda: JoSonObserver(JoSonExample(), lam=2.0, gamma=5.0), 1, 1, 0.01),
    ("example-euler-substeps", lambda: JoSonObserver(JoSonExample(), lam=2.0, gamma=5.0,
                                                     method="euler", substeps=3), 1, 1, 0.01),
    ("example-no-excitation", lambda: JoSonObserver(JoSonExample(), lam=2.0, gamma=5.0,
                                                    excitation_window=None), 1, 1, 0.01),
    ("motor-side", lambda: JoSonObserver(form=ElasticJoint().form("jo_son", sensors="motor_side"),
                                         lam=50.0, gamma=(1e4, 20.0, 1e6),
                                         excitation_window=0.05), 3, 1, 0.001),
    ("motor-side-rk4-substeps", lambda: JoSonObserver(form=jo_son_motor_side(),
                                                      lam=50.0, gamma=(1e4, 20.0, 1e6),
                                                      substeps=2), 3, 1, 0.001),
]
PARAMS = [pytest.param(make, p, m, dt, id=cid) for cid, make, p, m, dt in CONFIGS]


def _streams(p: int, m: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per-member measurement and input streams (some NaN dropouts, of y and of auxiliary
    channels), initial estimates and initial parameter estimates."""
    rng = np.random.default_rng(seed)
    t = np.arange(T) * 0.01
    Y = (0.5 * np.sin(t[None, :, None] * rng.uniform(0.5, 3.0, (B, 1, p)))
         + 0.01 * rng.normal(size=(B, T, p)))
    U = np.sin(t[None, :, None] * rng.uniform(0.5, 2.0, (B, 1, m)) + rng.uniform(0, 3, (B, 1, m)))
    lost = rng.random((B, T, p)) < 0.03
    Y[lost] = np.nan
    Y[3, 10:14, 0] = np.nan  # a run of dropouts
    return Y, U, rng


def _initial(ob: JoSonObserver, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    z0 = rng.uniform(-0.5, 0.5, (B, ob.n))
    th0 = rng.uniform(0.0, 2.0, (B, ob.form.p))
    return z0, th0


@pytest.mark.parametrize("make,p,m,dt", PARAMS)
def test_batch_equals_each_member_alone(make, p, m, dt):
    Y, U, rng = _streams(p, m)
    ob = make()
    z0, th0 = _initial(ob, rng)
    ob.reset(z_hat0=z0, theta_hat0=th0)
    assert ob.batch == B and ob.z_hat.shape == (B, ob.n) and ob.theta_hat_.shape == (B, ob.form.p)
    blk = advance(ob, Y, U, dt)
    assert np.all(np.isfinite(blk.x_hat)) and np.all(np.isfinite(blk.z_hat))
    np.testing.assert_array_equal(ob.dropouts_, np.isnan(Y).any(axis=2).sum(axis=1))
    for b in range(B):
        one = make()
        one.reset(z_hat0=z0[b:b + 1], theta_hat0=th0[b:b + 1])
        ref = advance(one, Y[b:b + 1], U[b:b + 1], dt)
        np.testing.assert_array_equal(blk.x_hat[b], ref.x_hat[0])
        np.testing.assert_array_equal(blk.z_hat[b], ref.z_hat[0])
        np.testing.assert_array_equal(blk.diagnostics[b], ref.diagnostics[0])


@pytest.mark.parametrize("make,p,m,dt", PARAMS)
def test_a_block_equals_single_steps_and_unbatched_updates(make, p, m, dt):
    Y, U, rng = _streams(p, m, seed=1)
    Y, U = Y[:4], U[:4]
    z0, th0 = _initial(make(), rng)
    whole, steps = make(), make()
    for ob in (whole, steps):
        ob.reset(z_hat0=z0[:4], theta_hat0=th0[:4])
    blk = advance(whole, Y, U, dt)
    for j in range(T):
        steps.update(Y[:, j], U[:, j], dt)
        np.testing.assert_array_equal(steps.x_hat, blk.x_hat[:, j])
        np.testing.assert_array_equal(steps.z_hat, blk.z_hat[:, j])
    np.testing.assert_array_equal(steps.theta_hat_, whole.theta_hat_)
    # blocks of uneven length in a row, and the unbatched update of member 0
    parts, j0 = make(), 0
    parts.reset(z_hat0=z0[:4], theta_hat0=th0[:4])
    for n in (1, 7, 50, T - 58):
        b = advance(parts, Y[:, j0:j0 + n], U[:, j0:j0 + n], dt)
        np.testing.assert_array_equal(b.x_hat, blk.x_hat[:, j0:j0 + n])
        np.testing.assert_array_equal(b.diagnostics, blk.diagnostics[:, j0:j0 + n])
        j0 += n
    single = make()
    single.reset(z_hat0=z0[0], theta_hat0=th0[0])
    for j in range(T):
        x = single.update(Y[0, j], U[0, j], dt)
        np.testing.assert_array_equal(x, blk.x_hat[0, j])
    assert single.diagnostics()["dropouts"] == float(np.isnan(Y[0]).any(axis=1).sum())


def test_batched_state_pickles_and_continues_alike():
    Y, U, rng = _streams(1, 1, seed=2)
    ob = JoSonObserver(JoSonExample(), lam=2.0, gamma=5.0)
    ob.reset(batch=5)
    advance(ob, Y[:5, :100], U[:5, :100], 0.01)
    twin = pickle.loads(pickle.dumps(ob))
    a = advance(ob, Y[:5, 100:], U[:5, 100:], 0.01)
    b = advance(twin, Y[:5, 100:], U[:5, 100:], 0.01)
    np.testing.assert_array_equal(a.x_hat, b.x_hat)
    np.testing.assert_array_equal(a.diagnostics, b.diagnostics)


def test_excitation_window_is_the_smallest_eigenvalue_of_the_gram_matrix():
    """The running window equals sum beta beta^T dt over the last round(window / dt) samples
    (recomputed exactly once a window), its smallest eigenvalue within rounding."""
    rng = np.random.default_rng(3)
    ob = JoSonObserver(form=jo_son_motor_side(), lam=50.0, gamma=(1e4, 20.0, 1e6),
                       excitation_window=0.013)
    dt, W = 0.001, 13
    Y = rng.normal(size=(2, 40, 3))
    U = rng.normal(size=(2, 40, 1))
    ob.reset(batch=2)
    blk = advance(ob, Y, U, dt)
    beta = np.stack([U[:, :, 0], -Y[:, :, 0], Y[:, :, 1] - Y[:, :, 2]], axis=2)  # eq. 10 regressor
    for j in (0, 5, 12, 13, 25, 39):
        win = beta[:, max(0, j - W + 1):j + 1]
        G = np.einsum("bwi,bwk->bik", win, win) * dt
        ref = np.linalg.eigvalsh(G)[:, 0]
        np.testing.assert_allclose(blk.diagnostics[:, j, 3], ref,
                                   atol=1e-14 * float(np.abs(G).max()))


def test_a_member_where_the_inverse_map_is_undefined_holds_alone():
    form = JoSonForm([1.0], lambda y, u: (0.0,), lambda y, u: (0.0 * y,), n_params=1,
                     to_physical=lambda z: (np.sqrt(z[0]),), state_names=("sqrt_z",))
    ob = JoSonObserver(form=form, lam=1.0, gamma=1.0)
    ob.reset(z_hat0=[[4.0], [1.0]])
    # z' = K (y - z) with K = lambda = 1: member 1 is driven below zero, member 0 stays positive
    blk = advance(ob, np.array([[[4.0]] * 3, [[-5.0]] * 3]), np.zeros((2, 3, 1)), 1.0)
    assert blk.z_hat[1, -1, 0] < 0 and np.all(blk.x_hat[1] == 1.0)
    np.testing.assert_allclose(blk.x_hat[0, :, 0], np.sqrt(blk.z_hat[0, :, 0]))
    np.testing.assert_array_equal(ob.inverse_failures_, [0, 3])


# ------------------------------------------------------------------ per-member parameters
def _example(lam, gamma):
    return JoSonObserver(JoSonExample(), lam=lam, gamma=gamma)


def _motor_side(lam, gamma):
    return JoSonObserver(form=jo_son_motor_side(), lam=lam, gamma=gamma,
                         excitation_window=0.05)


# members 0 and 2 share their parameters (one group of two), 1 and 3 have their own
MEMBER_CASES = [
    pytest.param(_example, [2.0, 3.5, 2.0, 1.0],
                 [[[5.0]], [[2.0]], [[5.0]], [[9.0]]], 1, 1, 0.01, id="example"),
    pytest.param(_motor_side, [50.0, 30.0, 50.0, 70.0],
                 [np.diag([1e4, 20.0, 1e6]), np.diag([2e4, 10.0, 5e5]), np.diag([1e4, 20.0, 1e6]),
                  np.array([[1e4, 50.0, 0.0], [50.0, 20.0, 0.0], [0.0, 0.0, 1e6]])],
                 3, 1, 0.001, id="motor-side"),
]


@pytest.mark.parametrize("make,lams,gammas,p,m,dt", MEMBER_CASES)
def test_members_with_their_own_gains_equal_their_single_runs(make, lams, gammas, p, m, dt):
    """A batch whose members differ in lambda and Gamma: member b equals, bit for bit, the
    observer constructed with its own values run alone (dropouts of y included); the pure
    step leaves the state it is given as it was."""
    nb = len(lams)
    Y, U, rng = _streams(p, m, seed=4)
    Y, U = Y[:nb, :120].copy(), U[:nb, :120]
    Y[1, 5:8, 0] = np.nan
    Y[2, 40, 0] = np.nan
    ob = make(lams[0], gammas[0])
    params = ob.parameters(nb, lam=lams, gamma=np.array(gammas))
    z0 = rng.uniform(-0.5, 0.5, (nb, ob.n))
    s0 = ob.init(nb, z_hat0=z0, params=params)
    before = s0.copy()
    s1, blk = ob.step(params, s0, Y[:, :70], U[:, :70], dt)
    s2, blk2 = ob.step(params, s1, Y[:, 70:], U[:, 70:], dt)
    for name, v in before.fields.items():
        np.testing.assert_array_equal(s0.fields[name], v)
    assert s0.S is not s1.S and s1.S is not s2.S
    np.testing.assert_array_equal(s2.dropouts, np.isnan(Y).any(axis=2).sum(axis=1))
    x, z, d = ob.current(params, s2)
    for b in range(nb):
        one = make(lams[b], gammas[b])
        one.reset(z_hat0=z0[b:b + 1])
        ref = advance(one, Y[b:b + 1], U[b:b + 1], dt)
        for got, want in ((blk, ref.x_hat[0, :70]), (blk2, ref.x_hat[0, 70:])):
            np.testing.assert_array_equal(got.x_hat[b], want)
        np.testing.assert_array_equal(np.concatenate((blk.z_hat[b], blk2.z_hat[b])), ref.z_hat[0])
        np.testing.assert_array_equal(np.concatenate((blk.diagnostics[b], blk2.diagnostics[b])),
                                      ref.diagnostics[0])
        np.testing.assert_array_equal(s2.S[b], one.state.S[0])
        np.testing.assert_array_equal(x[b], one.x_hat[0])
        np.testing.assert_array_equal(d[b], ob.current(*one._own())[2][0])
        np.testing.assert_array_equal(z[b], one.z_hat[0])


@pytest.mark.parametrize("values,exc,match", [
    ({"lam": [2.0, -1.0, 1.0]}, DesignError, r"Corollary 3.3 needs lambda > 0; found lambda = -1"),
    ({"lam": [2.0, np.nan, 1.0]}, DesignError, r"lambda must be finite"),
    ({"gamma": [[[5.0]], [[0.0]], [[1.0]]]}, DesignError,
     r"gamma must be positive definite; found eigenvalues \[0.0\]"),
    ({"gamma": [[[5.0]], [[-2.0]], [[1.0]]]}, DesignError, "positive definite"),
    ({"gamma": [5.0, 2.0, 1.0]}, DimensionError, r"gamma as a vector must have length m = 1"),
])
def test_per_member_parameters_are_checked_as_the_constructor_checks_them(values, exc, match):
    ob = JoSonObserver(JoSonExample(), lam=2.0, gamma=5.0)
    assert ob.parameter_names == ("lam", "gamma")
    with pytest.raises(exc, match=match):
        ob.parameters(3, **values)
    with pytest.raises(DesignError, match="gamma must be symmetric"):
        _motor_side(50.0, np.eye(3)).parameters(2, gamma=np.array([np.eye(3), np.triu(np.ones((3, 3)))]))


def test_a_restarted_member_equals_a_fresh_run_and_the_others_go_on():
    """reset_members restarts one member's estimate and its excitation window (per-member
    window rows and counters); the others go on as if nothing happened."""
    Y, U, _ = _streams(3, 1, seed=5)
    make = lambda: _motor_side(50.0, (1e4, 20.0, 1e6))  # noqa: E731
    ob, ref = make(), make()
    for o in (ob, ref):
        o.reset(batch=3)
        advance(o, Y[:3, :80], U[:3, :80], 0.001)
    ob.reset_members([1])
    blk = advance(ob, Y[:3, 80:], U[:3, 80:], 0.001)
    rest = advance(ref, Y[:3, 80:], U[:3, 80:], 0.001)
    fresh = make()
    fresh.reset(batch=1)
    one = advance(fresh, Y[1:2, 80:], U[1:2, 80:], 0.001)
    for b in (0, 2):
        np.testing.assert_array_equal(blk.diagnostics[b], rest.diagnostics[b])
    np.testing.assert_array_equal(blk.x_hat[1], one.x_hat[0])
    np.testing.assert_array_equal(blk.diagnostics[1], one.diagnostics[0])
