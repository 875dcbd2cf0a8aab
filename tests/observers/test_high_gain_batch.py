"""The high-gain family on the batch axis: B = 64 members (their own initial estimates and
measurement streams, with NaN dropouts) advanced together equal, bit for bit, each member
advanced alone (B = 1); a block of T samples equals T single steps; the bank of observers
likewise. Every configuration: methods, model term on/off, saturation, the inverse map."""

from __future__ import annotations

import numpy as np
import pytest
from observer_cases import advance

from hgo_mj.observers import HighGainObserver, MultiOutputHighGainObserver, ObserverBank
from hgo_mj.observers.base import ONE_BUFFER
from hgo_mj.observers.high_gain import TILE
from hgo_mj.systems import ElasticJoint, Pendulum

B, T, DT = 64, 200, 2e-3
METHODS = ("exact", "euler", "rk4")


def streams(p: int, m: int, seed: int = 0, n_b: int = B, t: int = T) -> tuple[np.ndarray, ...]:
    """``Y`` ``(B, T, p)``: a sinusoid per member and channel with noise and 5 % NaN dropouts;
    ``U`` ``(B, T, m)``."""
    rng = np.random.default_rng(seed)
    tt = np.arange(t) * DT
    w = rng.uniform(0.5, 3.0, (n_b, 1, p))
    ph = rng.uniform(0, 2 * np.pi, (n_b, 1, p))
    Y = 0.5 * np.sin(w * tt[None, :, None] + ph) + 1e-3 * rng.standard_normal((n_b, t, p))
    Y[rng.random(Y.shape) < 0.05] = np.nan
    U = rng.uniform(-0.5, 0.5, (n_b, t, m))
    return Y, U


def assert_block_equal(a, b):
    np.testing.assert_array_equal(a.x_hat, b.x_hat)
    np.testing.assert_array_equal(a.z_hat, b.z_hat)
    np.testing.assert_array_equal(a.diagnostics, b.diagnostics)


def check_batch_equals_members(make, z0: np.ndarray, Y: np.ndarray, U: np.ndarray) -> None:
    batched = make()
    batched.reset(z_hat0=z0)
    assert batched.batch == B
    blk = advance(batched, Y, U, DT)
    assert np.isnan(Y).any() and np.all(np.isfinite(blk.z_hat))
    for b in range(B):
        alone = make()
        alone.reset(z_hat0=z0[b:b + 1])
        one = advance(alone, Y[b:b + 1], U[b:b + 1], DT)
        np.testing.assert_array_equal(one.x_hat[0], blk.x_hat[b], err_msg=f"member {b}")
        np.testing.assert_array_equal(one.z_hat[0], blk.z_hat[b], err_msg=f"member {b}")
        np.testing.assert_array_equal(one.diagnostics[0], blk.diagnostics[b])
        np.testing.assert_array_equal(alone.z_hat[0], batched.z_hat[b])
        np.testing.assert_array_equal(alone.x_hat[0], batched.x_hat[b])
    np.testing.assert_array_equal(batched.dropouts_, np.isnan(Y).any(axis=2).sum(axis=1))


def check_block_equals_steps(make, z0: np.ndarray, Y: np.ndarray, U: np.ndarray) -> None:
    """One advance over T samples = T calls of step (batched) = T calls of update (one member)."""
    a, s = make(), make()
    a.reset(z_hat0=z0)
    s.reset(z_hat0=z0)
    blk = advance(a, Y, U, DT)
    for j in range(Y.shape[1]):
        s.update(Y[:, j], U[:, j], DT)
        np.testing.assert_array_equal(s.z_hat, blk.z_hat[:, j])
        np.testing.assert_array_equal(s.x_hat, blk.x_hat[:, j])
    u = make()
    u.reset(z_hat0=z0[0])
    for j in range(Y.shape[1]):
        np.testing.assert_array_equal(u.update(Y[0, j], U[0, j], DT), blk.x_hat[0, j])
    assert u.dropouts_ == int(np.isnan(Y[0]).any(axis=1).sum())


SYSTEMS = {"order-only": None, "pendulum": Pendulum, "elastic-joint": ElasticJoint}


def hgo_cases():
    for sname, S in SYSTEMS.items():
        for method in METHODS:
            for model in (False, True):
                if S is None and model:
                    continue
                for bounded in (False, True):
                    yield pytest.param(sname, method, model, bounded,
                                       id=f"{sname}-{method}-{'model' if model else 'free'}"
                                          f"{'-sat' if bounded else ''}")


def hgo_maker(sname: str, method: str, model: bool, bounded: bool):
    S = SYSTEMS[sname]
    n = 3 if S is None else S.normal_form_order
    bounds = (np.full(n, -2.0), np.full(n, 2.0)) if bounded else None  # clips in the transient
    k = 10.0 if method == "euler" else 40.0
    if S is None:
        return n, lambda: HighGainObserver(order=n, k=k, method=method, z_bounds=bounds)
    system = S()
    return n, lambda: HighGainObserver(system, k=k, model=model, method=method, z_bounds=bounds)


@pytest.mark.parametrize("sname,method,model,bounded", list(hgo_cases()))
def test_high_gain_batch_equals_each_member_alone(sname, method, model, bounded):
    n, make = hgo_maker(sname, method, model, bounded)
    Y, U = streams(1, 1, seed=n)
    z0 = np.random.default_rng(7).uniform(-1.0, 1.0, (B, n))
    check_batch_equals_members(make, z0, Y, U)


@pytest.mark.parametrize("sname,method,model,bounded", list(hgo_cases()))
def test_high_gain_block_equals_single_steps(sname, method, model, bounded):
    n, make = hgo_maker(sname, method, model, bounded)
    Y, U = streams(1, 1, seed=n + 1, n_b=4, t=60)
    z0 = np.random.default_rng(8).uniform(-1.0, 1.0, (4, n))
    check_block_equals_steps(make, z0, Y, U)


def test_high_gain_batch_from_physical_initial_states():
    """``reset(x_hat0 (B, n_x))`` maps each member through ``to_normal``, as alone."""
    system = ElasticJoint()
    x0 = np.random.default_rng(3).uniform(-0.3, 0.3, (B, 4))
    Y, U = streams(1, 1, seed=5)
    ob = HighGainObserver(system, k=40.0, model=True)
    ob.reset(x0)
    blk = advance(ob, Y, U, DT)
    for b in (0, 17, 63):
        alone = HighGainObserver(system, k=40.0, model=True)
        alone.reset(x0[b])
        np.testing.assert_allclose(alone.x_hat, x0[b], rtol=1e-12, atol=1e-12)
        for j in range(T):
            x = alone.update(Y[b, j], U[b, j], DT)
        np.testing.assert_array_equal(x, blk.x_hat[b, -1])


@pytest.mark.parametrize("orders", [(4,), (2, 4, 1)], ids=["one-chain", "three-chains"])
def test_members_across_kernel_tiles_equal_each_member_alone(orders):
    """Two whole tiles of the kernel and a partial one (``B = 2 TILE + 3``), with dropouts
    and saturation: each member as alone, bit for bit."""
    nb, t, n = 2 * TILE + 3, 40, sum(orders)
    Y, U = streams(len(orders), 1, seed=21, n_b=nb, t=t)
    z0 = np.random.default_rng(21).uniform(-1.0, 1.0, (nb, n))
    if len(orders) == 1:
        def make():
            return HighGainObserver(order=4, k=40.0, z_bounds=(np.full(4, -2.0), np.full(4, 2.0)))
    else:
        def make():
            return MultiOutputHighGainObserver(orders=orders, k=(20.0, 15.0, 30.0))
    batched = make()
    batched.reset(z_hat0=z0)
    blk = advance(batched, Y, U, DT)
    assert np.isnan(Y).any()
    for b in range(nb):
        alone = make()
        alone.reset(z_hat0=z0[b])
        np.testing.assert_array_equal(advance(alone, Y[b:b + 1], U[b:b + 1], DT).z_hat[0],
                                      blk.z_hat[b], err_msg=f"member {b}")
        np.testing.assert_array_equal(alone.z_hat, batched.z_hat[b])


def test_large_block_arrays_share_one_allocation_and_nothing_else():
    """From ``ONE_BUFFER`` member-samples on, a new block's three arrays are parts of one
    allocation: C-contiguous, disjoint, each its own shape, the values of the small path's
    separate arrays, and the next call's block is new memory."""
    nb, t = 2 * TILE + 3, 40
    assert nb * t >= ONE_BUFFER > t
    Y, U = streams(1, 1, seed=22, n_b=nb, t=t)
    ob = HighGainObserver(order=3, k=40.0)
    ob.reset(batch=nb)
    blk = advance(ob, Y, U, DT)
    arrays = (blk.x_hat, blk.z_hat, blk.diagnostics)
    assert [a.shape for a in arrays] == [(nb, t, 3), (nb, t, 3), (nb, t, 2)]
    assert all(a.flags.c_contiguous and a.flags.writeable for a in arrays)
    assert not any(np.shares_memory(a, b) for i, a in enumerate(arrays) for b in arrays[i + 1:])
    nxt = advance(ob, Y, U, DT)
    assert not any(np.shares_memory(a, b) for a in arrays
                   for b in (nxt.x_hat, nxt.z_hat, nxt.diagnostics))
    alone = HighGainObserver(order=3, k=40.0)
    for b in (0, nb - 1):
        alone.reset()
        one = advance(alone, Y[b:b + 1], U[b:b + 1], DT)
        np.testing.assert_array_equal(one.x_hat[0], blk.x_hat[b])
        np.testing.assert_array_equal(one.diagnostics[0], blk.diagnostics[b])


def multi_maker(method: str, coupled: bool):
    def phi(z, u):
        return np.array([-z[0] + u[0], np.sin(z[2]) - z[3]])

    return lambda: MultiOutputHighGainObserver(orders=(2, 3), k=(20.0, 15.0), outputs=(1, 0),
                                               method=method, phi=phi if coupled else None)


@pytest.mark.parametrize("coupled", [False, True], ids=["model-free", "phi"])
@pytest.mark.parametrize("method", METHODS)
def test_multi_output_batch_equals_each_member_alone(method, coupled):
    Y, U = streams(2, 1, seed=11)
    z0 = np.random.default_rng(9).uniform(-1.0, 1.0, (B, 5))
    make = multi_maker(method, coupled)
    check_batch_equals_members(make, z0, Y, U)
    ob = make()
    ob.reset(z_hat0=z0)
    advance(ob, Y, U, DT)
    # chain c reads channel outputs[c]: its dropouts are that channel's NaN samples
    np.testing.assert_array_equal(ob.channel_dropouts_, np.isnan(Y[:, :, [1, 0]]).sum(axis=1))


@pytest.mark.parametrize("coupled", [False, True], ids=["model-free", "phi"])
@pytest.mark.parametrize("method", METHODS)
def test_multi_output_block_equals_single_steps(method, coupled):
    Y, U = streams(2, 1, seed=12, n_b=4, t=60)
    z0 = np.random.default_rng(10).uniform(-1.0, 1.0, (4, 5))
    check_block_equals_steps(multi_maker(method, coupled), z0, Y, U)


def bank_maker():
    system = Pendulum()
    return lambda: ObserverBank([HighGainObserver(order=3, k=30.0, outputs=(2,)),
                                 HighGainObserver(system, k=20.0, model=True, method="rk4",
                                                  z_bounds=([-2.0, -4.0], [2.0, 4.0])),
                                 MultiOutputHighGainObserver(orders=(2,), k=25.0, outputs=(1,))])


def test_bank_batch_equals_each_member_alone():
    Y, U = streams(3, 1, seed=13)
    z0 = np.random.default_rng(11).uniform(-1.0, 1.0, (B, 7))
    make = bank_maker()
    assert make().outputs == (2, 0, 1)
    check_batch_equals_members(make, z0, Y, U)


def test_bank_block_equals_single_steps_and_its_members():
    Y, U = streams(3, 1, seed=14, n_b=4, t=60)
    z0 = np.random.default_rng(12).uniform(-1.0, 1.0, (4, 7))
    make = bank_maker()
    check_block_equals_steps(make, z0, Y, U)
    bank = make()
    bank.reset(z_hat0=z0)
    blk = advance(bank, Y, U, DT)
    i = 0
    for o in make().members:  # the bank is its members run on their own channels
        o.reset(z_hat0=z0[:, i:i + o.n])
        # a member with a system takes no wider y than its outputs (the bank hands it the
        # channels it reads); an order-only member reads its channel of any width
        Yo = Y if o.system is None else Y[:, :, :len(o.system.output_names)]
        np.testing.assert_array_equal(advance(o, Yo, U, DT).z_hat, blk.z_hat[:, :, i:i + o.n])
        i += o.n
    assert bank.diagnostic_names == ("k_0", "k_1", "dropouts")
