"""The systems' vectorized normal-form maps equal their scalar paths bit for bit, row by row:
``phi_batch(Z, U)[i] == phi_unchecked(Z[i], U[i])`` and ``from_normal_batch(Z, U)[i] ==
from_normal_unchecked(Z[i], U[i])`` exactly, at random points (wide angles, so sin/cos are
exercised far from 0) and, for the bioreactor, at points where the inverse is undefined (NaN
rows where the scalar path raises DesignError)."""

from __future__ import annotations

import numpy as np
import pytest

from hgo_mj.exceptions import DesignError
from hgo_mj.observers import HighGainObserver
from hgo_mj.systems import CartPendulum, ElasticJoint, Pendulum
from hgo_mj.systems.papers import BioreactorBullinger

N = 2000


def same_bits(a, b) -> bool:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and bool(np.all((a.view(np.int64) == b.view(np.int64))
                                              | (np.isnan(a) & np.isnan(b))))


def points(n: int, m: int, seed: int, scale: float = 60.0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    Z = rng.uniform(-scale, scale, (N, n)) * rng.choice([1e-6, 1e-2, 1.0], (N, n))
    U = rng.uniform(-5.0, 5.0, (N, m))
    # a non-contiguous view, as an observer's slices may be
    return np.repeat(Z, 2, axis=1)[:, ::2], U


MECHANICAL = [Pendulum, CartPendulum, ElasticJoint]


@pytest.mark.parametrize("cls", MECHANICAL)
@pytest.mark.parametrize("perturb", [False, True])
def test_mechanical_phi_and_inverse_batch_equal_single(cls, perturb):
    system = cls()
    if perturb:  # other parameter values than the shipped ones (all still positive)
        rng = np.random.default_rng(1)
        system = cls(**{k: v * rng.uniform(0.5, 2.0) if v != 0 else rng.uniform(0.1, 1.0)
                        for k, v in system.params.items()})
    n = system.normal_form_order
    Z, U = points(n, len(system.input_names), seed=2 + perturb)
    phi = system.phi_batch(Z, U)
    assert phi.shape == (N,)
    single = np.array([system.phi_unchecked(Z[i], U[i]) for i in range(N)])
    assert same_bits(phi, single)
    # the observers' own argument types: a tuple of floats for z
    assert same_bits(phi[:50], [system.phi_unchecked(tuple(Z[i].tolist()), U[i])
                                for i in range(50)])
    X = system.from_normal_batch(Z, U)
    assert X.shape == (N, len(system.state_names)) and np.isfinite(X).all()
    assert same_bits(X, np.array([system.from_normal_unchecked(Z[i], U[i]) for i in range(N)]))
    assert X is not Z and not np.shares_memory(X, Z)


@pytest.mark.parametrize("cls", MECHANICAL + [BioreactorBullinger])
def test_empty_batch(cls):
    system = cls()
    n, m = system.normal_form_order, len(system.input_names)
    assert system.phi_batch(np.empty((0, n)), np.empty((0, m))).shape == (0,)
    assert system.from_normal_batch(np.empty((0, n)), np.empty((0, m))).shape == (
        0, len(system.state_names))


def bioreactor_points(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows inside Phi^-1's domain, and outside it (m <= 0, growth term < 0 or >= a1 m)."""
    rng = np.random.default_rng(seed)
    m = rng.uniform(1e-3, 2.0, N)
    m[rng.random(N) < 0.1] *= -1.0
    m[rng.random(N) < 0.02] = 0.0
    u = rng.uniform(0.0, 0.1, N)
    w = m * rng.uniform(-0.3, 1.3, N)  # growth term: [0, a1 m) is the domain
    return np.column_stack([m, w - u * m]), u[:, None]


@pytest.mark.parametrize("params", [{}, {"a1": 1.7, "a2": 0.6, "a3": 1.3, "a4": 0.2}])
def test_bioreactor_inverse_batch_equals_single_nan_where_undefined(params):
    system = BioreactorBullinger(**params)
    Z, U = bioreactor_points(3)
    X = system.from_normal_batch(Z, U)
    undefined = 0
    for i in range(N):
        try:
            x = system.from_normal_unchecked(Z[i], U[i])
        except DesignError:
            undefined += 1
            assert np.isnan(X[i]).all()
            continue
        assert same_bits(X[i], x)
    assert 0.2 * N < undefined < 0.8 * N  # both kinds of rows are exercised


def test_bioreactor_inverse_needs_positive_a():
    system = BioreactorBullinger(a2=-1.0)
    Z, U = bioreactor_points(4)
    assert np.isnan(system.from_normal_batch(Z, U)).all()
    with pytest.raises(DesignError, match="a1 > 0 and a2 > 0"):
        system.from_normal_unchecked(np.array([0.1, 0.0]), np.array([0.05]))


def test_bioreactor_phi_batch_equals_single():
    system = BioreactorBullinger()
    Z, U = bioreactor_points(5)
    Z[:, 0] = np.abs(Z[:, 0]) + 1e-3  # phi is defined for every m > 0
    phi = system.phi_batch(Z, U)
    assert same_bits(phi, [system.phi_unchecked(Z[i], U[i]) for i in range(N)])


def test_bioreactor_phi_batch_raises_like_the_row_loop():
    """m <= 0 (phi's pole) or a non-finite entry in any row: the same DesignError as the
    per-row default."""
    system = BioreactorBullinger()
    Z, U = bioreactor_points(6)
    Z[:, 0] = np.abs(Z[:, 0]) + 1e-3
    for i, j, v, match in ((7, 0, -0.5, "needs m = z1 > 0"), (7, 0, 0.0, "needs m = z1 > 0"),
                           (7, 1, np.nan, "must be finite")):
        Zb = Z.copy()
        Zb[i, j] = v
        with pytest.raises(DesignError, match=match):
            system.phi_batch(Zb, U)
    Ub = U.copy()
    Ub[2, 0] = np.inf
    with pytest.raises(DesignError, match="must be finite"):
        system.phi_batch(Z, Ub)


def test_to_physical_batch_path_holds_and_counts():
    """Observer._to_physical with the bioreactor's from_normal_batch: a block with undefined
    rows equals the per-row hold-and-count path, and a block whose rows are all defined
    updates the held value."""
    system = BioreactorBullinger()
    Z, U = bioreactor_points(7)
    B, T = 8, N // 8
    Zb, Ub = Z.reshape(B, T, 2), U.reshape(B, T, 1)

    class RowsOnly(BioreactorBullinger):
        from_normal_batch = None  # type: ignore[assignment]

    fast, slow = HighGainObserver(system, k=5.0), HighGainObserver(RowsOnly(), k=5.0)
    for ob in (fast, slow):
        ob.reset(z_hat0=np.tile([0.5, 0.0], (B, 1)))
    Xf, Xs = np.empty((B, T, 2)), np.empty((B, T, 2))
    fast._to_physical(fast.state, Zb, Ub, Xf)
    slow._to_physical(slow.state, Zb, Ub, Xs)
    assert same_bits(Xf, Xs)
    np.testing.assert_array_equal(fast.inverse_failures_, slow.inverse_failures_)
    good = np.tile([[[0.08, 0.001]]], (B, 1, 1))
    fast._to_physical(fast.state, good, np.full((B, 1, 1), 0.05), Xf[:, :1])  # all defined: batch path
    bad = np.tile([[[-1.0, 0.0]]], (B, 1, 1))
    fast._to_physical(fast.state, bad, np.full((B, 1, 1), 0.05), Xs[:, :1])  # held: the last valid value
    assert same_bits(Xs[:, 0], Xf[:, 0])


COMPILED_SYSTEMS = ["Pendulum", "CartPendulum", "ElasticJoint", "ElasticJoint2Link",
                    "BioreactorBullinger", "BioreactorBastinGevers", "BesanconExample1",
                    "BesanconExample2", "JoSonExample"]


@pytest.mark.parametrize("name", COMPILED_SYSTEMS)
def test_compiled_model_equals_python_dynamics(name):
    """A system's CompiledModel, called from the kernels, gives its Python ``dynamics`` (and
    ``jacobian``, ``param_jacobian`` where written) bit for bit, row by row, with an estimated
    parameter read from the augmented row; ``param_vector`` is in ``param_names`` order."""
    from hgo_mj import systems
    from hgo_mj.observers.kalman import SystemModel
    from hgo_mj.systems import papers

    system = (getattr(systems, name, None) or getattr(papers, name))()
    assert system.compiled is not None
    assert system.param_vector().tolist() == [system.params[k] for k in system.param_names]
    n, m = len(system.state_names), len(system.input_names)
    Z, U = points(n, m, seed=7, scale=3.0)
    est = system.param_names[:1]
    fast = SystemModel(system, est)
    slow = SystemModel(system, est)
    slow.compiled = None
    theta = system.params[est[0]] * np.random.default_rng(8).uniform(0.5, 1.5, (N, 1))
    X = np.column_stack([np.abs(Z) if "Bioreactor" in name else Z, theta])
    with np.errstate(all="ignore"):
        assert same_bits(fast.deriv(X, U), slow.deriv(X, U))
        assert same_bits(fast.jac(X, U), slow.jac(X, U))
        assert same_bits(fast.step(X, U, 0.01, "rk4"), slow.step(X, U, 0.01, "rk4"))
        assert same_bits(fast.step(X, U, 0.01, "euler"), slow.step(X, U, 0.01, "euler"))
    if callable(getattr(system, "jacobian", None)):
        fd = SystemModel(system, est, jacobian="fd")
        assert fd.compiled is not None and fd.analytic is False and fast.analytic is True
        np.testing.assert_allclose(fast.jac(X[:50], U[:50]), fd.jac(X[:50], U[:50]),
                                   rtol=1e-5, atol=1e-5)
