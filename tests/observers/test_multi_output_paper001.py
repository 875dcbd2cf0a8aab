"""The multi-output high-gain observer against its equations (paper 001, eq. 4-5).

Eq. 5 of Besançon, Zhang, Hammouri (2004) gives the multi-output normal form a block structure:
``A = diag(A_1, A_2, ...)``, ``C = diag(C_1, C_2, ...)``, each block a chain of integrators
measured at its first state, and the observer of eq. 4 is designed block by block. Without a
model term the chains are therefore independent: one chain is exactly the single-output
observer (paper 000, eq. 2), and two chains are two single-output observers on their own
channels. Both are checked bit for bit on a stream with dropouts, for every method.
"""

import numpy as np
import pytest

from hgo_mj.design import hgo_gains
from hgo_mj.observers.high_gain import HighGainObserver, MultiOutputHighGainObserver

DT = 0.01


def _stream(m: int, steps: int = 300, seed: int = 0) -> list[np.ndarray]:
    """Measurements of ``m`` channels: smooth signals with noise and some NaN dropouts."""
    rng = np.random.default_rng(seed)
    t = np.arange(steps) * DT
    ys = np.stack([np.sin((c + 1) * t) + 0.3 * c + 1e-3 * rng.standard_normal(steps)
                   for c in range(m)], axis=1)
    ys[rng.random(ys.shape) < 0.05] = np.nan
    return list(ys)


@pytest.mark.parametrize("method", ["exact", "euler", "rk4"])
def test_one_chain_is_the_single_output_observer(method):
    multi = MultiOutputHighGainObserver(k=6.0, orders=[3], p=[3.0, 3.0, 1.0], method=method,
                                        z_hat0=[0.1, -0.2, 0.3])
    single = HighGainObserver(order=3, k=6.0, p=[3.0, 3.0, 1.0], method=method,
                              z_hat0=[0.1, -0.2, 0.3])
    u = np.zeros(0)
    for y in _stream(1):
        np.testing.assert_array_equal(multi.update(y, u, DT), single.update(y, u, DT))
    assert multi.dropouts_ == single.dropouts_ > 0
    assert multi.channel_dropouts_ == [single.dropouts_]


@pytest.mark.parametrize("method", ["exact", "euler", "rk4"])
def test_two_chains_are_two_observers_on_their_channels(method):
    """Block-diagonal ``A``, ``C`` (eq. 5): chain ``c`` sees only channel ``outputs[c]``, with
    its own order, gain and polynomial; the estimate is the chains' estimates concatenated."""
    multi = MultiOutputHighGainObserver(k=[5.0, 8.0], orders=[2, 3], outputs=[2, 0],
                                        p=[None, [2.0, 2.5, 1.0]], method=method,
                                        z_hat0=[0.5, 0.0, -0.1, 0.2, 0.0])
    first = HighGainObserver(order=2, k=5.0, outputs=(2,), method=method, z_hat0=[0.5, 0.0])
    second = HighGainObserver(order=3, k=8.0, p=[2.0, 2.5, 1.0], outputs=(0,), method=method,
                              z_hat0=[-0.1, 0.2, 0.0])
    u = np.zeros(0)
    for y in _stream(3, seed=1):
        ref = np.concatenate([first.update(y, u, DT), second.update(y, u, DT)])
        np.testing.assert_array_equal(multi.update(y, u, DT), ref)
    assert multi.channel_dropouts_ == [first.dropouts_, second.dropouts_]


def test_euler_step_is_the_block_diagonal_observer_of_eq_4():
    """One Euler step of ``z' = A z + L (y - C z)`` with ``A = diag(A_1, A_2)``,
    ``C = diag(C_1, C_2)`` and ``L = diag(L_1, L_2)``, ``L_c = (p_{c,i} k_c^i)``."""
    orders, ks = (2, 3), (4.0, 7.0)
    multi = MultiOutputHighGainObserver(k=list(ks), orders=list(orders), method="euler",
                                        z_hat0=[0.3, -0.1, 0.2, 0.4, -0.5])
    n = sum(orders)
    A, C, L = np.zeros((n, n)), np.zeros((2, n)), np.zeros((n, 2))
    f = 0
    for c, (nc, kc) in enumerate(zip(orders, ks)):
        A[f:f + nc, f:f + nc] = np.diag(np.ones(nc - 1), 1)
        C[c, f] = 1.0
        L[f:f + nc, c] = hgo_gains(multi.ps[c], kc)
        f += nc
    z = multi.z_hat
    y = np.array([0.7, -0.4])
    expected = z + DT * (A @ z + L @ (y - C @ z))
    np.testing.assert_allclose(multi.update(y, np.zeros(0), DT), expected, rtol=0, atol=1e-14)
