"""The Riccati (paper 004, Th. 1, eq. 6, 53) and q-integral (eq. 37-48) observers batched: B
members advanced together equal each member run alone, bit for bit, and a block of T samples
equals T single steps."""

from __future__ import annotations

import numpy as np
import pytest
from observer_cases import advance

from hgo_mj.exceptions import DesignError, DimensionError
from hgo_mj.observers import QIntegralObserver, RiccatiObserver
from hgo_mj.systems import CartPendulum, ElasticJoint

B, T, DT = 64, 240, 0.01


def streams(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per member: an initial estimate, a measured sine with noise and NaN dropouts, inputs."""
    rng = np.random.default_rng(seed)
    t = np.arange(T) * DT
    amp = rng.uniform(0.1, 0.6, (B, 1))
    phase = rng.uniform(0, 2 * np.pi, (B, 1))
    y = amp * np.sin(1.5 * t + phase) + rng.normal(0.0, 0.02, (B, T))
    y[rng.random((B, T)) < 0.05] = np.nan
    u = np.ascontiguousarray((0.3 * np.cos(2.0 * t + phase))[:, :, None])
    return rng.normal(0.0, 0.2, (B, n)), y[:, :, None], u


SAT = ([-0.5, -1.5], [0.5, 1.5])
CONFIGS = (
    [pytest.param(RiccatiObserver, dict(method=m, model=model, z_bounds=zb),
                  id=f"riccati-{m}-{'model' if model else 'free'}{'-sat' if zb else ''}")
     for m in ("exact", "euler", "rk4") for model in (False, True) for zb in (None, SAT)]
    + [pytest.param(QIntegralObserver, dict(method=m, model=model, q=q),
                    id=f"q{q}-{m}-{'model' if model else 'free'}")
       for m in ("exact", "euler", "rk4") for model in (False, True) for q in (1, 2)])


def _batch_and_single(make, z0, Y, U):
    ob = make()
    ob.reset(z_hat0=z0)
    blk = advance(ob, Y, U, DT)
    assert blk.x_hat.shape[:2] == (B, T) and np.isfinite(blk.x_hat).all()
    for b in (0, 3, 31, 50, 63):
        one = make()
        one.reset(z_hat0=z0[b:b + 1])
        blk1 = advance(one, Y[b:b + 1], U[b:b + 1], DT)
        np.testing.assert_array_equal(blk1.x_hat[0], blk.x_hat[b])
        np.testing.assert_array_equal(blk1.z_hat[0], blk.z_hat[b])
        np.testing.assert_array_equal(blk1.diagnostics[0], blk.diagnostics[b])
    np.testing.assert_array_equal(ob.diagnostics()["dropouts"], np.isnan(Y[:, :, 0]).sum(axis=1))
    return ob, blk


@pytest.mark.parametrize("cls,kw", CONFIGS)
def test_batch_equals_each_member_alone(cls, kw):
    z0, Y, U = streams(2)
    _batch_and_single(lambda: cls(CartPendulum(), gamma=6.0, **kw), z0, Y, U)


@pytest.mark.parametrize("cls,kw", CONFIGS)
def test_block_equals_single_steps(cls, kw):
    z0, Y, U = streams(2, seed=1)
    a, b = cls(CartPendulum(), gamma=6.0, **kw), cls(CartPendulum(), gamma=6.0, **kw)
    a.reset(z_hat0=z0)
    b.reset(z_hat0=z0)
    blk = advance(a, Y, U, DT)
    for j in range(T):
        b.update(Y[:, j], U[:, j], DT)
        np.testing.assert_array_equal(b.x_hat, blk.x_hat[:, j])
        np.testing.assert_array_equal(b.z_hat, blk.z_hat[:, j])
    np.testing.assert_array_equal(a.z_hat, b.z_hat)
    if cls is QIntegralObserver:
        np.testing.assert_array_equal(a.w_, b.w_)


@pytest.mark.parametrize("cls", [RiccatiObserver, QIntegralObserver])
def test_batch_equals_single_elastic_joint(cls):
    """n = 4 and the inverse normal-form map (not the identity); model-free (the test signal
    is no elastic joint's)."""
    z0, Y, U = streams(4, seed=2)
    _batch_and_single(lambda: cls(ElasticJoint(), gamma=30.0, model=False), z0, Y, U)


def test_unbatched_is_one_member():
    z0, Y, U = streams(2, seed=3)
    ob = QIntegralObserver(CartPendulum(), gamma=6.0, q=2)
    ob.reset(z_hat0=z0)
    blk = advance(ob, Y, U, DT)
    one = QIntegralObserver(CartPendulum(), gamma=6.0, q=2)
    one.reset(z_hat0=z0[9])
    xs = np.array([one.update(Y[9, j], U[9, j], DT) for j in range(T)])
    np.testing.assert_array_equal(xs, blk.x_hat[9])
    assert one.w_.shape == (4,) and ob.w_.shape == (B, 4)
    assert one.diagnostics() == {"gamma": 6.0, "dropouts": float(np.isnan(Y[9]).sum())}


def test_period_cache_is_bounded():
    ob = RiccatiObserver(CartPendulum(), gamma=6.0)
    for j in range(50):
        ob.update(np.array([0.1]), np.array([0.0]), 0.01 * (1 + 1e-3 * j))
    assert len(ob._maps_cache) <= 8


# ------------------------------------------------------------------ per-member parameters
#: per member (B = 4): gamma and alpha differ, members 1 and 3 share theirs (one group of two)
GAMMAS = [4.0, 6.0, 9.0, 6.0]
ALPHAS = {2: [[2.0, 1.0], [3.0, 2.0], [2.5, 1.5], [3.0, 2.0]],  # Riccati, n = 2
          3: [[3.0, 3.0, 1.0], [4.0, 5.0, 2.0], [3.5, 4.0, 1.5], [4.0, 5.0, 2.0]]}  # q = 1
PARAM_CONFIGS = (
    [pytest.param(RiccatiObserver, dict(method=m, model=True, z_bounds=zb),
                  id=f"riccati-{m}{'-sat' if zb else ''}")
     for m in ("exact", "euler", "rk4") for zb in (None, SAT)]
    + [pytest.param(QIntegralObserver, dict(method=m, model=model, q=1),
                    id=f"q1-{m}-{'model' if model else 'free'}")
       for m in ("exact", "euler", "rk4") for model in (False, True)])


@pytest.mark.parametrize("cls,kw", PARAM_CONFIGS)
def test_members_with_their_own_parameters_equal_their_single_runs(cls, kw):
    """A batch whose members differ in gamma and alpha (paper 004, eq. 6-10) equals, member by
    member, the observer constructed with that member's values, bit for bit, with NaN
    dropouts in Y; the state passed to the pure step is unchanged."""
    nb, N = len(GAMMAS), 2 + kw.get("q", 0)
    z0, Y, U = streams(2, seed=4)
    z0, Y, U = z0[:nb], Y[:nb].copy(), U[:nb]
    Y[:, 7, 0] = np.nan  # a dropout for every member, besides the random ones
    assert np.isnan(Y).any(axis=(1, 2)).all()
    ob = cls(CartPendulum(), gamma=6.0, **kw)
    params = ob.parameters(nb, gamma=GAMMAS, alpha=ALPHAS[N])
    assert params.gamma.shape == (nb,) and params.alpha.shape == (nb, N)
    state = ob.init(nb, z_hat0=z0, params=params)
    before = state.copy()
    new, blk = ob.step(params, state, Y, U, DT)
    assert list(state.fields) == list(before.fields)
    for name, value in before.fields.items():
        np.testing.assert_array_equal(getattr(state, name), value)
    np.testing.assert_array_equal(blk.diagnostics[:, :, 0], np.repeat(
        np.array(GAMMAS)[:, None], T, axis=1))
    x, z, d = ob.current(params, new)
    np.testing.assert_array_equal(x, blk.x_hat[:, -1])
    np.testing.assert_array_equal(z, blk.z_hat[:, -1])
    for b in range(nb):
        one = cls(CartPendulum(), gamma=GAMMAS[b], alpha=ALPHAS[N][b], **kw)
        one.reset(z_hat0=z0[b:b + 1])
        blk1 = advance(one, Y[b:b + 1], U[b:b + 1], DT)
        np.testing.assert_array_equal(blk1.x_hat[0], blk.x_hat[b])
        np.testing.assert_array_equal(blk1.z_hat[0], blk.z_hat[b])
        np.testing.assert_array_equal(blk1.diagnostics[0], blk.diagnostics[b])
        np.testing.assert_array_equal(one.state.S[0], new.S[b])
        assert one.state.dropouts[0] == new.dropouts[b] == np.isnan(Y[b]).sum()


@pytest.mark.parametrize("cls", [RiccatiObserver, QIntegralObserver])
def test_members_with_their_own_gamma_through_the_inverse_map(cls):
    """n = 4 with the elastic joint's inverse normal-form map (not the identity)."""
    gammas = [20.0, 30.0, 45.0]
    z0, Y, U = streams(4, seed=5)
    z0, Y, U = z0[:3], Y[:3].copy(), U[:3]
    Y[:, 3, 0] = np.nan
    ob = cls(ElasticJoint(), gamma=30.0, model=False)
    params = ob.parameters(3, gamma=gammas)
    state = ob.init(3, z_hat0=z0, params=params)
    new, blk = ob.step(params, state, Y, U, DT)
    for b, g in enumerate(gammas):
        one = cls(ElasticJoint(), gamma=g, model=False)
        one.reset(z_hat0=z0[b:b + 1])
        blk1 = advance(one, Y[b:b + 1], U[b:b + 1], DT)
        np.testing.assert_array_equal(blk1.x_hat[0], blk.x_hat[b])
        np.testing.assert_array_equal(blk1.z_hat[0], blk.z_hat[b])
        np.testing.assert_array_equal(one.state.x_held[0], new.x_held[b])


@pytest.mark.parametrize("cls,kw", [(RiccatiObserver, {}), (QIntegralObserver, {"q": 1})])
def test_bad_parameters_are_refused_with_the_constructors_message(cls, kw):
    ob = cls(CartPendulum(), gamma=6.0, **kw)
    assert ob.parameter_names == ("gamma", "alpha")
    N = 2 + kw.get("q", 0)
    with pytest.raises(DesignError, match=r"gamma must be > 0; found -2\.0"):
        ob.parameters(3, gamma=[4.0, -2.0, 6.0])
    with pytest.raises(DesignError, match=r"gamma must be > 0"):
        cls(CartPendulum(), gamma=-2.0, **kw)
    with pytest.raises(DesignError, match="gamma must be finite"):
        ob.parameters(3, gamma=[4.0, np.inf, 6.0])
    with pytest.raises(DesignError, match="gamma='min' needs the Lipschitz constant rho"):
        ob.parameters(3, gamma="min")
    bad = [1.0, -1.0] + [1.0] * (N - 2)
    with pytest.raises(DesignError, match="Hurwitz"):
        ob.parameters(2, alpha=[ALPHAS[N][0], bad])
    with pytest.raises(DesignError, match="Hurwitz"):
        cls(CartPendulum(), gamma=6.0, alpha=bad, **kw)
    weights = [1.0, 5.0, 1.0][:N]  # Hurwitz, but q_1 = -9 (condition (10), eq. 17)
    with pytest.raises(DesignError, match=r"violates condition \(10\).*q_1 = -9"):
        ob.parameters(2, alpha=weights)
    with pytest.raises(DesignError, match=r"violates condition \(10\).*q_1 = -9"):
        cls(CartPendulum(), gamma=6.0, alpha=weights, **kw)
    with pytest.raises(DimensionError, match=rf"alpha must have n.* = {N} coefficients; found {N + 1}"):
        ob.parameters(2, alpha=[1.0] * (N + 1))


def test_gamma_min_per_member_is_the_constructors():
    """``gamma="min"`` (paper 004, eq. 5) resolves with the constructor's alpha and rho."""
    ob = RiccatiObserver(CartPendulum(), gamma="min", rho=2.0)
    assert ob.parameters(1, gamma="min").gamma.tolist() == [ob.gamma_]
    assert ob.parameters(2).gamma.tolist() == [ob.gamma_, ob.gamma_]
