"""The adaptive-gain observer (paper 000, eq. 2, 4-5) batched: B members advanced together
equal each member run alone, bit for bit, and a block of T samples equals T single steps."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from observer_cases import advance

from hgo_mj.exceptions import DesignError
from hgo_mj.observers import AdaptiveGainObserver
from hgo_mj.systems import ElasticJoint, Pendulum

B, T, DT = 64, 240, 0.01


def streams(n_z: int, seed: int = 0, m: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per member: an initial estimate, a measured sine with noise and NaN dropouts, inputs."""
    rng = np.random.default_rng(seed)
    t = np.arange(T) * DT
    amp = rng.uniform(0.1, 0.6, (B, 1))
    phase = rng.uniform(0, 2 * np.pi, (B, 1))
    y = amp * np.sin(2.0 * t + phase) + rng.normal(0.0, 0.05, (B, T))
    y[rng.random((B, T)) < 0.05] = np.nan
    u = 0.3 * np.cos(3.0 * t + phase)[:, :, None] * np.ones((1, 1, m))
    z0 = rng.normal(0.0, 0.3, (B, n_z))
    return z0, y[:, :, None], np.ascontiguousarray(u)


CONFIGS = [
    pytest.param(dict(method=m, model=model, z_bounds=zb), id=f"{m}-{'model' if model else 'free'}"
                 f"{'-sat' if zb else ''}")
    for m in ("exact", "euler", "rk4") for model in (False, True)
    for zb in (None, ([-0.4, -1.0], [0.4, 1.0]))
]


def make(**kw):
    return AdaptiveGainObserver(Pendulum(), lam=0.04, lam_hat=0.08, gamma=400.0, k0=10.0,
                                k_max=30.0, on_unstable="ignore", **kw)


def _check_batch_equals_single(make_ob, z0, Y, U):
    ob = make_ob()
    ob.reset(z_hat0=z0)
    blk = advance(ob, Y, U, DT)
    assert ob.batch == B and blk.x_hat.shape[:2] == (B, T)
    for b in (0, 1, 17, 40, 63):
        one = make_ob()
        one.reset(z_hat0=z0[b:b + 1])
        blk1 = advance(one, Y[b:b + 1], U[b:b + 1], DT)
        np.testing.assert_array_equal(blk1.x_hat[0], blk.x_hat[b])
        np.testing.assert_array_equal(blk1.z_hat[0], blk.z_hat[b])
        np.testing.assert_array_equal(blk1.diagnostics[0], blk.diagnostics[b])
    return ob, blk


@pytest.mark.parametrize("kw", CONFIGS)
def test_batch_equals_each_member_alone(kw):
    z0, Y, U = streams(2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # k_max reached
        ob, blk = _check_batch_equals_single(lambda: make(**kw), z0, Y, U)
    k = blk.diagnostics[:, :, 0]
    assert np.all(np.diff(k, axis=1) >= 0) and k.max() > 10.0  # it adapted ...
    assert np.all(k <= 30.0)  # ... up to k_max at most
    assert np.isfinite(blk.x_hat).all()
    np.testing.assert_array_equal(ob.diagnostics()["dropouts"], np.isnan(Y[:, :, 0]).sum(axis=1))


@pytest.mark.parametrize("kw", CONFIGS)
def test_block_equals_single_steps(kw):
    z0, Y, U = streams(2, seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        a, b = make(**kw), make(**kw)
        a.reset(z_hat0=z0)
        b.reset(z_hat0=z0)
        blk = advance(a, Y, U, DT)
        for j in range(T):
            b.update(Y[:, j], U[:, j], DT)
            np.testing.assert_array_equal(b.x_hat, blk.x_hat[:, j])
            np.testing.assert_array_equal(b.z_hat, blk.z_hat[:, j])
            np.testing.assert_array_equal(b.k_, blk.diagnostics[:, j, 0])


@pytest.mark.parametrize("p", [None, [1.4, 1.0, 0.3, 0.05], [3.0, 3.5, 1.5, 0.25]],
                         ids=["binomial", "complex", "real"])
def test_batch_equals_single_elastic_joint(p):
    """n = 4, the inverse normal-form map (not the identity), the pole-matched gain from
    repeated, complex and real roots (model-free: the test signal is no elastic joint's)."""
    z0, Y, U = streams(4, seed=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        _, blk = _check_batch_equals_single(
            lambda: AdaptiveGainObserver(ElasticJoint(), lam=0.02, lam_hat=0.1, gamma=500.0,
                                         k0=5.0, k_max=20.0, p=p), z0, Y, U)
    assert np.isfinite(blk.x_hat).all() and blk.diagnostics[:, -1, 0].max() > 5.0


def test_unbatched_is_one_member():
    z0, Y, U = streams(2, seed=3)
    ob = make(method="exact")
    ob.reset(z_hat0=z0)
    blk = advance(ob, Y, U, DT)
    one = make(method="exact")
    one.reset(z_hat0=z0[5])
    xs = np.array([one.update(Y[5, j], U[5, j], DT) for j in range(T)])
    np.testing.assert_array_equal(xs, blk.x_hat[5])
    assert isinstance(one.k_, float) and one.k_ == blk.diagnostics[5, -1, 0]
    assert one.L.shape == (2,) and ob.L.shape == (B, 2)


#: per member: the adaptation law's constants (paper 000, eq. 4-5), every one different
MEMBER_VALUES = {"lam": [0.04, 0.02, 0.03], "lam_hat": [0.08, 0.1, 0.05],
                 "gamma": [400.0, 900.0, 150.0], "k0": [10.0, 4.0, 25.0]}


@pytest.mark.parametrize("kw", CONFIGS)
def test_members_with_different_parameters_equal_their_single_runs(kw):
    """State and parameters as data: one batch whose members have different ``lam``,
    ``lam_hat``, ``gamma`` and ``k0`` equals, member by member and bit for bit, the single run
    of an observer constructed with that member's values (NaN dropouts included); ``step``
    leaves the state it is given as it was."""
    n_b, n_t = 3, 120
    z0, Y, U = streams(2, seed=4)
    z0, Y, U = z0[:n_b], Y[:n_b, :n_t].copy(), U[:n_b, :n_t]
    Y[:, 7] = np.nan  # a dropout of every member
    Y[1, 30:33] = np.nan  # and of one member
    ob = make(**kw)
    assert ob.parameter_names == ("lam", "lam_hat", "gamma", "k0")
    params = ob.parameters(n_b, **MEMBER_VALUES)
    assert len(params.groups()) == n_b
    state = ob.init(n_b, z_hat0=z0, params=params)
    np.testing.assert_array_equal(ob.current(params, state)[2][:, 0], MEMBER_VALUES["k0"])
    before = state.copy()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # k_max reached
        after, blk = ob.step(params, state, Y, U, DT)
        for field, value in before.fields.items():  # the state given is untouched
            np.testing.assert_array_equal(getattr(state, field), value)
        assert after is not state
        k = blk.diagnostics[:, :, 0]
        assert np.all(k[:, -1] > MEMBER_VALUES["k0"])  # every member adapted, at its own rate
        assert len(set(k[:, -1].tolist())) == n_b
        np.testing.assert_array_equal(blk.diagnostics[:, -1, 1], np.isnan(Y[:, :, 0]).sum(axis=1))
        for b in range(n_b):
            one = AdaptiveGainObserver(Pendulum(), k_max=30.0, on_unstable="ignore",
                                       **{name: v[b] for name, v in MEMBER_VALUES.items()}, **kw)
            one.reset(z_hat0=z0[b:b + 1])
            alone = advance(one, Y[b:b + 1], U[b:b + 1], DT)
            np.testing.assert_array_equal(blk.x_hat[b], alone.x_hat[0])
            np.testing.assert_array_equal(blk.z_hat[b], alone.z_hat[0])
            np.testing.assert_array_equal(blk.diagnostics[b], alone.diagnostics[0])
            for field, value in one.state.fields.items():
                np.testing.assert_array_equal(getattr(after, field)[b], value[0])
    # the current estimate after the block is the last row, member by member
    x, z, d = ob.current(params, after)
    np.testing.assert_array_equal(x, blk.x_hat[:, -1])
    np.testing.assert_array_equal(z, blk.z_hat[:, -1])
    np.testing.assert_array_equal(d, blk.diagnostics[:, -1])


@pytest.mark.parametrize("values, match", [
    ({"gamma": [100.0, -1.0, 200.0]}, "gamma must be > 0; found -1"),
    ({"lam": [0.04, 0.0, 0.02]}, "lam must be > 0; found 0"),
    ({"lam_hat": [0.08, float("nan"), 0.1]}, "lam_hat must be finite; found nan"),
    ({"k0": [10.0, 0.0, 5.0]}, "k0 must be > 0; found 0"),
    ({"k0": [10.0, 40.0, 5.0]}, r"k_max must be >= k0; found k_max=30 < k0=40"),
    ({"lam": [0.04, 0.09, 0.02]}, r"lam_hat must be > lam .*found lam_hat=0.08 <= lam=0.09"),
    ({"lam": [0.04, 0.05, 0.02], "lam_hat": [0.08, 0.05, 0.1]},
     r"lam_hat must be > lam .*found lam_hat=0.05 <= lam=0.05"),
    ({"lam_hat": 0.03}, "lam_hat must be > lam"),
])
def test_parameters_refuse_what_the_constructor_refuses(values, match):
    with pytest.raises(DesignError, match=match):
        make().parameters(3, **values)
    if np.ndim(next(iter(values.values()))):  # the constructor refuses it with the same message
        bad = {k: v[1] for k, v in values.items()}
        with pytest.raises(DesignError, match=match):
            AdaptiveGainObserver(Pendulum(), **{**dict(lam=0.04, lam_hat=0.08, gamma=400.0,
                                                       k0=10.0, k_max=30.0), **bad})
