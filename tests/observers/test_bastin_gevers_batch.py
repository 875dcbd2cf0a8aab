"""Bastin-Gevers observer (paper 002, eq. 3.1) with a batch axis: B members advanced together
equal each member advanced alone, to the bit; a block of T samples equals T single steps."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
from observer_cases import advance

from hgo_mj.exceptions import DesignError, DimensionError, DivergenceError
from hgo_mj.observers import AOCF, BastinGeversObserver
from hgo_mj.systems import CartPendulum, Pendulum
from hgo_mj.systems.papers import BioreactorBastinGevers

B, T, DT = 64, 240, 0.01


def _hand_made_form() -> AOCF:
    """A pointwise form (rows=False) of n = 3 with a full F and a nonlinear omega."""
    R = np.zeros((3, 3))
    R[0, 1:] = [1.0, -0.5]
    R[1:, 1:] = [[-1.0, 0.2], [0.1, -2.0]]
    alpha = np.zeros((3, 2, 3))
    alpha[0, 0, 2] = 1.0
    alpha[1, 0, 0] = 0.5
    alpha[1, 1, 1] = 1.0
    alpha[2, 1, 0] = -1.0
    return AOCF(R, alpha, lambda y, u: np.array([y, u[0], math.sin(y)]),
                g=lambda y, u: np.array([0.0, u[0], -y]), label="hand-made n = 3")


# (id, observer factory, input width, output around, parameter width, z width)
CONFIGS = [
    ("bioreactor", lambda: BastinGeversObserver(BioreactorBastinGevers(), c1=5.0, gamma=2.0,
                                                c2=1.0, excitation_window=0.5,
                                                theta_hat0=[-3.0, -0.1, -0.1], z_hat0=[1.0, 1.0]), 2, 1.0),
    ("bioreactor-euler-substeps", lambda: BastinGeversObserver(
        BioreactorBastinGevers(), c1=5.0, gamma=[2.0, 1.0, 3.0], c2=2.0, method="euler",
        substeps=3, excitation_window=None, theta_hat0=[-3.0, -0.1, -0.1], z_hat0=[1.0, 1.0]), 2, 1.0),
    ("pendulum", lambda: BastinGeversObserver(Pendulum(), c1=20.0, c2=5.0, gamma=50.0,
                                              excitation_window=0.3), 1, 0.3),
    ("pendulum-coefficient", lambda: BastinGeversObserver(
        Pendulum(), c1=20.0, gamma=[5.0, 20.0], damping_known="coefficient"), 1, 0.3),
    ("cart-pendulum-damping", lambda: BastinGeversObserver(
        CartPendulum(), c1=10.0, gamma=[1.0, 5.0, 5.0],
        unknown=("d_over_J", "g_over_l", "b_over_J"), excitation_window=1.0), 1, 0.3),
    ("hand-made-pointwise", lambda: BastinGeversObserver(aocf=_hand_made_form(), c1=4.0,
                                                         gamma=[1.0, 2.0],
                                                         excitation_window=0.4), 1, 0.5),
]


def _streams(rng: np.random.Generator, mu: int, level: float) -> tuple[np.ndarray, np.ndarray]:
    """B different measurement streams (some members with dropouts) and inputs."""
    t = DT * np.arange(T)
    phase = rng.uniform(0, 2 * np.pi, (B, 1))
    Y = level + 0.3 * level * np.sin(1.3 * t + phase) + 0.01 * rng.normal(size=(B, T))
    Y[rng.random((B, T)) < np.where(np.arange(B) % 3 == 0, 0.15, 0.0)[:, None]] = np.nan
    Y[5, :20] = np.nan  # a long gap at the start
    U = 0.5 + 0.4 * np.sin(0.7 * t[None, :, None] * (1 + np.arange(mu)) + phase[:, :, None])
    return Y[:, :, None], np.ascontiguousarray(np.broadcast_to(U, (B, T, mu)))


def _start(ob: BastinGeversObserver, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    f = ob.form
    truth = f.theta_true if f.theta_true is not None else np.ones(f.m)
    th = rng.uniform(0.5, 1.5, (B, f.m)) * truth
    if "Bioreactor" in f.label:
        th = np.array([-3.0, -0.1, -0.1]) * rng.uniform(0.8, 1.2, (B, 3))
    z = rng.uniform(0.5, 1.5, (B, f.n))
    return th, z


@pytest.mark.parametrize("make, mu, level", [c[1:] for c in CONFIGS], ids=[c[0] for c in CONFIGS])
def test_batch_equals_each_member_alone(make, mu, level):
    rng = np.random.default_rng(11)
    ob = make()
    Y, U = _streams(rng, mu, level)
    th, z = _start(ob, rng)
    ob.reset(z_hat0=z, theta_hat0=th)
    assert ob.batch == B
    blk = advance(ob, Y, U, DT)
    assert np.isnan(Y).any() and np.all(np.isfinite(blk.z_hat))
    np.testing.assert_array_equal(ob.dropouts_, np.isnan(Y[:, :, 0]).sum(axis=1))
    final = (ob.x_hat, ob.z_hat, ob.theta_hat_, ob.V_, ob.inverse_failures_,
             ob.reachability_rank_)
    for b in range(B):
        one = make()
        one.reset(z_hat0=z[b], theta_hat0=th[b])  # unbatched: B = 1 on the same code
        alone = advance(one, Y[b:b + 1], U[b:b + 1], DT)
        np.testing.assert_array_equal(alone.x_hat[0], blk.x_hat[b], err_msg=f"member {b}")
        np.testing.assert_array_equal(alone.z_hat[0], blk.z_hat[b], err_msg=f"member {b}")
        np.testing.assert_array_equal(alone.diagnostics[0], blk.diagnostics[b],
                                      err_msg=f"member {b}")
        np.testing.assert_array_equal(one.theta_hat_, final[2][b])
        np.testing.assert_array_equal(one.V_, final[3][b])
        assert one.inverse_failures_ == final[4][b]
        assert one.reachability_rank_ == final[5][b]


@pytest.mark.parametrize("make, mu, level", [c[1:] for c in CONFIGS], ids=[c[0] for c in CONFIGS])
def test_a_block_equals_single_steps(make, mu, level):
    rng = np.random.default_rng(12)
    ob, ref = make(), make()
    Y, U = _streams(rng, mu, level)
    Y, U = Y[:8], U[:8]
    th, z = _start(ob, rng)
    ob.reset(z_hat0=z[:8], theta_hat0=th[:8])
    ref.reset(z_hat0=z[:8], theta_hat0=th[:8])
    blk = advance(ob, Y, U, DT)
    for j in range(T):
        ref.update(Y[:, j], U[:, j], DT)
        np.testing.assert_array_equal(ref.x_hat, blk.x_hat[:, j], err_msg=f"sample {j}")
        np.testing.assert_array_equal(ref.z_hat, blk.z_hat[:, j], err_msg=f"sample {j}")
        d = ref.diagnostics()
        np.testing.assert_array_equal(np.column_stack([d[k] for k in ref.diagnostic_names]),
                                      blk.diagnostics[:, j], err_msg=f"sample {j}")
    np.testing.assert_array_equal(ref.excitation_, ob.excitation_)


def test_diagnostics_layout_and_pickle_of_a_batch():
    ob = CONFIGS[0][1]()
    rng = np.random.default_rng(3)
    Y, U = _streams(rng, 2, 1.0)
    th, z = _start(ob, rng)
    ob.reset(z_hat0=z, theta_hat0=th)
    blk = advance(ob, Y[:, :100], U[:, :100], DT)
    assert ob.diagnostic_names == ("theta_1", "theta_2", "theta_3", "theta_p1", "theta_p2",
                                   "theta_p3", "theta_p0", "excitation", "reachability_rank",
                                   "dropouts")
    assert blk.diagnostics.shape == (B, 100, 10)
    d = ob.diagnostics()
    assert list(d) == list(ob.diagnostic_names) and all(v.shape == (B,) for v in d.values())
    np.testing.assert_array_equal(d["theta_1"], ob.theta_hat_[:, 0])
    assert ob.excitation_matrix_.shape == (B, 3, 3)
    assert set(ob.physical_params_) == {"p1", "p2", "p3", "p0"}
    twin = pickle.loads(pickle.dumps(ob))
    a, b = advance(ob, Y[:, 100:], U[:, 100:], DT), advance(twin, Y[:, 100:], U[:, 100:], DT)
    np.testing.assert_array_equal(a.x_hat, b.x_hat)
    np.testing.assert_array_equal(a.diagnostics, b.diagnostics)


def test_a_changed_period_restarts_the_window_and_divergence_names_the_member():
    ob = CONFIGS[2][1]()
    ob.reset(batch=2)
    Y = np.full((2, 50, 1), 0.3)
    U = np.full((2, 50, 1), 0.2)
    advance(ob, Y, U, 0.01)
    advance(ob, Y, U, 0.02)  # a new period: a window of round(0.3 / 0.02) = 15 samples
    assert ob.state.ring.shape == (2, 15, 2)
    Y[1, 10] = 1e308  # (g(y) would overflow) refused before the family sees the block
    with pytest.raises(DivergenceError, match=r"measurement y\[0\] is 1e\+308 \(member 1, "
                                              r"sample 10\), beyond"):
        advance(ob, Y, U, 0.02)
    assert ob.state.ring.shape == (2, 15, 2) and ob.dropouts_.tolist() == [0, 0]


# (id, constructor keywords but the gains, input width, output around, three gains c1, gamma)
_GAINS = [
    ("bioreactor", dict(system=BioreactorBastinGevers(), c2=1.0, excitation_window=0.3,
                        theta_hat0=[-3.0, -0.1, -0.1], z_hat0=[1.0, 1.0]), 2, 1.0,
     [5.0, 3.0, 8.0],
     [2.0 * np.eye(3), np.diag([1.0, 2.0, 3.0]),
      np.array([[2.0, 0.3, 0.0], [0.3, 1.0, 0.1], [0.0, 0.1, 4.0]])]),
    ("pendulum-euler", dict(system=Pendulum(), c2=5.0, excitation_window=0.2, method="euler",
                            substeps=2, theta_hat0=[1.0, 1.0]), 1, 0.3,
     [20.0, 10.0, 30.0], [50.0 * np.eye(2), np.diag([5.0, 20.0]), np.array([[3.0, 1.0], [1.0, 2.0]])]),
]


@pytest.mark.parametrize("kw, mu, level, c1s, gammas", [g[1:] for g in _GAINS],
                         ids=[g[0] for g in _GAINS])
def test_members_with_different_gains_equal_their_single_runs(kw, mu, level, c1s, gammas):
    """State and parameters as data: a batch whose members have different gains ``c1`` and
    ``gamma`` (``parameters(B, c1=..., gamma=...)``) equals, member by member and bit for bit,
    the observer constructed with that member's gains run alone, over samples with dropouts
    and a change of period (the excitation window starts over at its new length); ``step``
    leaves the state it is given as it was."""
    rng = np.random.default_rng(21)
    nb = len(c1s)
    ob = BastinGeversObserver(**kw)
    Y, U = _streams(rng, mu, level)
    Y, U = Y[:nb, :90], U[:nb, :90]
    Y[0, 7] = Y[2, 30:33] = np.nan
    params = ob.parameters(nb, c1=c1s, gamma=np.stack(gammas))
    state = ob.init(nb, params=params)
    before = state.copy()
    mid, first = ob.step(params, state, Y[:, :60], U[:, :60], DT)
    for field, value in before.fields.items():  # the state given is untouched
        np.testing.assert_array_equal(getattr(state, field), value, err_msg=field)
    after, second = ob.step(params, mid, Y[:, 60:], U[:, 60:], 2 * DT)
    assert np.isnan(Y).any() and after.ring.shape == (nb, 15 if kw["excitation_window"] == 0.3
                                                       else 10, ob.form.m)
    for b in range(nb):
        one = BastinGeversObserver(**kw, c1=c1s[b], gamma=gammas[b])
        one.reset()
        alone = (advance(one, Y[b:b + 1, :60], U[b:b + 1, :60], DT),
                 advance(one, Y[b:b + 1, 60:], U[b:b + 1, 60:], 2 * DT))
        for got, want in zip((first, second), alone):
            np.testing.assert_array_equal(got.x_hat[b], want.x_hat[0], err_msg=f"member {b}")
            np.testing.assert_array_equal(got.z_hat[b], want.z_hat[0], err_msg=f"member {b}")
            np.testing.assert_array_equal(got.diagnostics[b], want.diagnostics[0],
                                          err_msg=f"member {b}")
        for field, value in after.fields.items():
            np.testing.assert_array_equal(value[b], getattr(one.state, field)[0],
                                          err_msg=f"member {b}, {field}")
    np.testing.assert_array_equal(after.dropouts, np.isnan(Y[:, :, 0]).sum(axis=1))
    assert after.dropouts[2] == 3


def test_member_gains_are_checked_as_the_constructor_checks_them():
    ob = CONFIGS[0][1]()
    assert ob.parameter_names == ("c1", "gamma")
    p = ob.parameters(3, c1=[5.0, 6.0, 7.0])
    assert p.c1.tolist() == [5.0, 6.0, 7.0] and p.gamma.shape == (3, 3, 3)
    np.testing.assert_array_equal(p.gamma[1], 2.0 * np.eye(3))
    with pytest.raises(DesignError, match="c1 must be > 0; found -1"):
        ob.parameters(3, c1=[5.0, -1.0, 2.0])
    with pytest.raises(DesignError, match=r"gamma must be positive definite; found eigenvalues "
                                          r"\[-1.0"):
        ob.parameters(3, gamma=[[1, 2, 0], [2, 1, 0], [0, 0, 1]])
    with pytest.raises(DesignError, match="gamma must be symmetric"):
        ob.parameters(2, gamma=np.stack([np.eye(3), [[1, 0.5, 0], [0, 1, 0], [0, 0, 1]]]))
    with pytest.raises(DimensionError, match=r"gamma must be a scalar, a length-3 vector or a "
                                             r"3x3 matrix; found shape \(2, 2\)"):
        ob.parameters(3, gamma=np.eye(2))
    with pytest.raises(DesignError, match="c1 must be finite; found nan"):
        ob.parameters(1, c1=np.nan)


def test_a_restarted_member_runs_as_a_fresh_one():
    """``reset_members`` writes a fresh member into a running batch: its excitation window
    (the ring of the running period) starts over, the others go on; it then equals a fresh
    single run."""
    ob = CONFIGS[0][1]()
    rng = np.random.default_rng(5)
    Y, U = _streams(rng, 2, 1.0)
    Y, U = Y[:3], U[:3]
    ob.reset(batch=3)
    advance(ob, Y[:, :40], U[:, :40], DT)
    ob.reset_members([1])
    assert np.isnan(ob.state.ring_dt[1]) and not ob.state.ring[1].any()
    rows = advance(ob, Y[:, 40:], U[:, 40:], DT)
    one = CONFIGS[0][1]()
    alone = advance(one, Y[1:2, 40:], U[1:2, 40:], DT)
    np.testing.assert_array_equal(rows.x_hat[1], alone.x_hat[0])
    np.testing.assert_array_equal(rows.diagnostics[1], alone.diagnostics[0])
