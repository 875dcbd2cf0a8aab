"""Conformance of every registered observer (one working construction each, from
``observer_cases``): the interface contract that the runner, the environments and the recorder
rely on.

* ``update`` returns a finite float vector of ``len(state_names)`` entries that shares no
  memory with the observer or with earlier results;
* a NaN measurement (a dropout) is not propagated: the estimate stays finite and the dropout is
  counted in ``diagnostics()["dropouts"]``;
* the same inputs give the same estimates (two instances), and ``reset()`` starts over exactly;
* ``diagnostics()`` are plain floats with the same keys at every sample; ``params()`` is JSON;
* unknown keyword arguments and wrongly sized measurements are refused with clear errors;
* a measurement beyond ``MAX_MEASUREMENT`` or infinite is refused before any work, and a row
  MuJoCo resets is a divergence (the base's one rule for every family).
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from observer_cases import CASES, DT, advance, signals

from hgo_mj.exceptions import DesignError, DimensionError, DivergenceError
from hgo_mj.observers import OBSERVERS, make_observer
from hgo_mj.observers.base import MAX_MEASUREMENT
from hgo_mj.systems import Pendulum

PARAMS = [pytest.param(kind, make, p, m, id=f"{kind}-{cid}") for kind, cid, make, p, m in CASES]
STEPS = 12  # the dropout of ``signals`` is at sample 7


def _run(ob, p: int, m: int) -> list[np.ndarray]:
    return [ob.update(*signals(k, p, m), DT) for k in range(STEPS)]


def _arrays(state) -> list[np.ndarray]:
    """Every array of a state (its fields, nested states and tuples of them)."""
    out: list[np.ndarray] = []
    for v in state.fields.values():
        for item in (v if isinstance(v, tuple) else (v,)):
            out += [item] if isinstance(item, np.ndarray) else _arrays(item)
    return out


@pytest.mark.parametrize("kind,make,p,m", PARAMS)
def test_update_contract(kind, make, p, m):
    ob = make()
    ob.check_period(DT)
    names = tuple(ob.state_names)
    assert len(names) == len(set(names)) > 0
    keys = None
    out = _run(ob, p, m)
    for k, x in enumerate(out):
        assert isinstance(x, np.ndarray) and x.dtype == np.float64 and x.shape == (len(names),), k
        assert np.all(np.isfinite(x)), (k, x)
        diag = ob.diagnostics()
        assert all(isinstance(v, float) for v in diag.values()), diag
        keys = keys or set(diag)
        assert set(diag) == keys
    assert np.all(np.isfinite(ob.z_hat))
    # results are fresh arrays: neither aliased to each other nor to the observer's state
    assert not any(np.shares_memory(a, b) for a, b in zip(out, out[1:]))
    assert not np.shares_memory(out[-1], ob.x_hat)
    before = out[-1].copy()
    ob.x_hat[...] = 123.0
    np.testing.assert_array_equal(ob.x_hat, before)
    # current() hands the family's arrays out without another copy: none is a view of the state
    params, state = ob._own()
    for arr in ob.current(params, state):
        assert not any(np.shares_memory(arr, v) for v in _arrays(state)), kind
    # the dropout at sample 7 is counted once, not propagated
    assert ob.diagnostics()["dropouts"] == 1.0
    json.dumps(ob.params())


@pytest.mark.parametrize("kind,make,p,m", PARAMS)
def test_deterministic_and_reset_starts_over(kind, make, p, m):
    a, b = make(), make()
    ra, rb = _run(a, p, m), _run(b, p, m)
    for xa, xb in zip(ra, rb):
        np.testing.assert_array_equal(xa, xb)
    a.reset()
    assert a.diagnostics()["dropouts"] == 0.0
    for xa, xb in zip(_run(a, p, m), ra):
        np.testing.assert_array_equal(xa, xb)


@pytest.mark.parametrize("kind,make,p,m", PARAMS)
def test_wrong_measurement_size_is_refused(kind, make, p, m):
    ob = make()
    _, u = signals(0, p, m)
    with pytest.raises(DimensionError, match="y"):
        ob.update(np.zeros(0), u, DT)


@pytest.mark.parametrize("kind,make,p,m", PARAMS)
def test_a_measurement_wider_than_the_systems_outputs_is_refused(kind, make, p, m):
    """Every public entry (``update``, ``step``, ``run``, ``filtered``) refuses a row with
    more channels than the system measures; without a system (a form), any row holding the
    observer's channels is one."""
    ob = make()
    y, u = signals(0, p, m)
    wide = np.r_[y, 0.0]
    if ob.system is None:
        assert ob.update(wide, u, DT).shape == (len(ob.state_names),)
        return
    assert len(ob.system.output_names) == p
    match = rf"{ob.name}: y .*and p <= {p}, the outputs"
    with pytest.raises(DimensionError, match=match):
        ob.update(wide, u, DT)
    with pytest.raises(DimensionError, match=match):
        ob.filtered(wide)
    params, state = ob._own()
    with pytest.raises(DimensionError, match=match):
        ob.step(params, state, wide[None, None], u[None, None], DT)
    with pytest.raises(DimensionError, match=match):
        ob.run(wide[None], u[None], DT)
    ob.update(y, u, DT)  # a row of the system's width goes on


@pytest.mark.parametrize("bad", [1e300, -1e300, 2e10, np.inf, -np.inf])
@pytest.mark.parametrize("kind,make,p,m", PARAMS)
def test_a_measurement_beyond_the_bound_is_refused_before_any_work(kind, make, p, m, bad):
    """One rule in the base for every family: an infinite measurement, or one beyond
    ``MAX_MEASUREMENT``, is a ``DivergenceError`` naming channel, member and sample, raised
    before the family sees the block (the state is unchanged: the next samples give what a
    fresh observer gives); the bound itself is a measurement; ``filtered`` applies the same
    rule."""
    ob, ref = make(), make()
    y0, u0 = signals(0, p, m)
    np.testing.assert_array_equal(ob.update(y0, u0, DT), ref.update(y0, u0, DT))
    y, u = signals(1, p, m)
    y[0] = bad
    with pytest.raises(DivergenceError, match=rf"{ob.name}: measurement y\[{ob.outputs[0]}\] is "
                                              rf".*\(member 0, sample 0\)"):
        ob.update(y, u, DT)
    with pytest.raises(DivergenceError, match="measurement"):
        ob.filtered(y)
    for k in range(1, 4):  # nothing was consumed
        y, u = signals(k, p, m)
        np.testing.assert_array_equal(ob.update(y, u, DT), ref.update(y, u, DT))
    assert ob.diagnostics()["dropouts"] == 0.0
    # a block: member 1's sample 2 is refused by name; the others are not stepped either
    ob.reset(batch=3)
    Y = np.empty((3, 4, p))
    U = np.empty((3, 4, m))
    for k in range(4):
        Y[:, k], U[:, k] = signals(k, p, m)
    Y[1, 2, 0] = bad
    params, state = ob._own()
    with pytest.raises(DivergenceError, match=r"member 1, sample 2"):
        ob.step(params, state, Y, U, DT)


def test_the_bound_itself_is_a_measurement():
    ob = make_observer("high_gain", Pendulum(), k=10.0)
    assert np.all(np.isfinite(ob.update([MAX_MEASUREMENT], [0.0], DT)))
    ob.reset(batch=2)
    assert np.all(np.isfinite(ob.update([[-MAX_MEASUREMENT], [np.nan]], [[0.0], [0.0]], DT)))
    assert ob.diagnostics()["dropouts"].tolist() == [0.0, 1.0]


@pytest.mark.parametrize("kind", ["ekf_mujoco", "ukf_mujoco"])
def test_a_row_mujoco_resets_is_a_divergence_not_a_silent_zero(kind):
    """MuJoCo resets ``MjData`` to the reference pose on a row beyond ``mjMAXVAL``; the
    filters' model step reports it instead of returning zeros."""
    ob = make_observer(kind, Pendulum(), R=1e-4)
    ob.reset([0.1, 2e10])  # a velocity the measured angle does not pull back
    with pytest.raises(DivergenceError, match="MuJoCo reset the filter's model"):
        ob.update([0.1], [0.0], DT)


@pytest.mark.parametrize("kind", sorted(OBSERVERS))
def test_unknown_keyword_is_refused(kind):
    with pytest.raises(DesignError, match=rf"observer '{kind}'.*no_such_option"):
        make_observer(kind, Pendulum(), no_such_option=1.0)


@pytest.mark.parametrize("kind,make,p,m", PARAMS)
def test_diagnostic_names_are_exactly_what_diagnostics_returns(kind, make, p, m):
    ob = make()
    assert tuple(ob.diagnostics()) == ob.diagnostic_names
    assert ob.diagnostic_names[-1] == "dropouts"
    _run(ob, p, m)
    assert tuple(ob.diagnostics()) == ob.diagnostic_names
    ob.reset(batch=3)
    d = ob.diagnostics()
    assert tuple(d) == ob.diagnostic_names and all(np.shape(v) == (3,) for v in d.values())


@pytest.mark.parametrize("kind,make,p,m", PARAMS)
def test_a_batch_equals_its_members_run_alone(kind, make, p, m):
    """Every family: B = 5 members fed different measurement streams (a dropout each at its
    own sample) advance as one batch, bit-identical to each member run alone; the rows of a
    block are the estimates after each sample."""
    B, T = 5, STEPS
    rng = np.random.default_rng(7)
    Y = np.empty((B, T, p))
    U = np.empty((B, T, m))
    for k in range(T):
        y, u = signals(k, p, m)
        Y[:, k], U[:, k] = y, u
    Y += 1e-3 * rng.standard_normal(Y.shape) * np.isfinite(Y)
    for b in range(B):
        Y[b, 2 + b, 0] = np.nan
    batch = make()
    batch.reset(batch=B)
    blk = advance(batch, Y, U, DT)
    assert blk.x_hat.shape == (B, T, len(batch.state_names))
    assert blk.z_hat.shape == (B, T, batch.n)
    assert blk.diagnostics.shape == (B, T, len(batch.diagnostic_names))
    for b in range(B):
        alone = make()
        for k in range(T):
            np.testing.assert_array_equal(alone.update(Y[b, k], U[b, k], DT), blk.x_hat[b, k])
        np.testing.assert_array_equal(alone.z_hat, blk.z_hat[b, -1])
        assert list(alone.diagnostics().values()) == pytest.approx(
            blk.diagnostics[b, -1].tolist(), nan_ok=True, rel=0, abs=0)
    np.testing.assert_array_equal(batch.x_hat, blk.x_hat[:, -1])


def test_the_contract_is_an_abstract_base():
    from hgo_mj.observers.base import Observer

    with pytest.raises(TypeError, match="abstract"):
        Observer(None, order=2)  # type: ignore[abstract]
    for cls in OBSERVERS.values():
        assert issubclass(cls, Observer) and not getattr(cls, "__abstractmethods__", None)


@pytest.mark.parametrize("kind,make,p,m", PARAMS)
def test_reset_members_restarts_only_those_members(kind, make, p, m):
    """``reset_members([1])`` of a batch of 3: member 1 then runs as a fresh observer on its
    samples (bit for bit), members 0 and 2 as if nothing happened."""
    def block(k0: int, k1: int, shift: float) -> tuple[np.ndarray, np.ndarray]:
        ys, us = zip(*(signals(k, p, m) for k in range(k0, k1)))
        return np.array(ys)[None] + shift, np.array(us)[None]

    def batch(k0: int, k1: int) -> tuple[np.ndarray, np.ndarray]:
        parts = [block(k0, k1, 0.01 * b) for b in range(3)]
        return np.concatenate([y for y, _ in parts]), np.concatenate([u for _, u in parts])

    ob, ref, fresh = make(), make(), make()
    ob.reset(batch=3)
    ref.reset(batch=3)
    for o in (ob, ref):
        advance(o, *batch(0, 5), DT)
    ob.reset_members([1])  # state is data, every clock per member: any member restarts alone
    out, want = advance(ob, *batch(5, STEPS), DT), advance(ref, *batch(5, STEPS), DT)
    fresh.reset(batch=1)
    alone = advance(fresh, *block(5, STEPS, 0.01), DT)
    for b in (0, 2):
        np.testing.assert_array_equal(out.x_hat[b], want.x_hat[b])
        np.testing.assert_array_equal(out.diagnostics[b], want.diagnostics[b])
    np.testing.assert_array_equal(out.x_hat[1], alone.x_hat[0])
    np.testing.assert_array_equal(out.diagnostics[1], alone.diagnostics[0])
    with pytest.raises(DesignError, match="outside the batch of 3"):
        ob.reset_members([3])
    single = make()
    with pytest.raises(DesignError, match="needs a batched observer"):
        single.reset_members([0])


def _member_values(ob, name: str) -> list:
    """Three values of the parameter ``name`` the observer accepts: its own and two scaled
    ones (the first factors its check accepts)."""
    default = np.asarray(ob._parameters()[name], dtype=float)
    out = [default]
    for f in (1.25, 1.5, 0.9, 1.1, 0.95):
        try:
            ob.parameters(1, **{name: default * f})
        except (DesignError, DimensionError):
            continue
        out.append(default * f)
        if len(out) == 3:
            return out
    raise AssertionError(f"{name}: no scaled value accepted")


@pytest.mark.parametrize("kind,make,p,m", PARAMS)
def test_members_with_different_parameters_equal_their_single_runs(kind, make, p, m):
    """State and parameters as data: one batch whose members have different values of every
    tunable parameter (``parameters(B, name=[...])``) equals, member by member and bit for bit,
    the single run with that member's values; ``step`` leaves the state it is given as it
    was (it is pure)."""
    ob = make()
    names = ob.parameter_names
    if ob.name == "bank":
        pytest.skip("a bank holds its members' parameters")
    assert names, f"{kind} declares no tunable parameter"
    values = {name: _member_values(ob, name) for name in names}
    B, T = 3, STEPS
    Y = np.empty((B, T, p))
    U = np.empty((B, T, m))
    for k in range(T):
        Y[:, k], U[:, k] = signals(k, p, m)
    params = ob.parameters(B, **{name: np.stack(v) for name, v in values.items()})
    state = ob.init(B, params=params)
    before = state.copy()
    after, rows = ob.step(params, state, Y, U, DT)
    for field, value in before.fields.items():  # the state given is untouched
        if isinstance(value, np.ndarray):
            np.testing.assert_array_equal(getattr(state, field), value)
    assert after is not state
    for b in range(B):
        one = ob.parameters(1, **{name: v[b] for name, v in values.items()})
        _, alone = ob.step(one, ob.init(1, params=one), Y[b:b + 1], U[b:b + 1], DT)
        np.testing.assert_array_equal(rows.x_hat[b], alone.x_hat[0])
        np.testing.assert_array_equal(rows.z_hat[b], alone.z_hat[0])
        np.testing.assert_array_equal(rows.diagnostics[b], alone.diagnostics[0])
    with pytest.raises(DesignError, match="unknown parameter"):
        ob.parameters(B, not_a_parameter=1.0)
    with pytest.raises(DimensionError, match="per member"):
        ob.parameters(B, **{names[0]: np.stack([values[names[0]][0]] * (B + 1))})


@pytest.mark.parametrize("kind,make,p,m", PARAMS)
def test_start_from_checked_rows_equals_init(kind, make, p, m):
    """The loop's start from rows it checked (``_start_from``, an environment's start from its
    first measurement) is ``init`` from them, bit for bit, for every family (those that extend
    ``init`` go through it); a row that is not finite is refused as ``init`` refuses it."""
    ob = make()
    params = ob.parameters(2)
    x0 = np.linspace(0.1, 0.4, 2 * len(ob.state_names)).reshape(2, -1)
    try:
        b = ob.init(2, x0, params=params)
    except DesignError as exc:  # a family that starts only in its own coordinates
        with pytest.raises(DesignError, match="^" + re.escape(str(exc)) + "$"):
            ob._start_from(params, x0)
        return
    a = ob._start_from(params, x0)
    assert list(a.fields) == list(b.fields)
    for u, v in zip(_arrays(a), _arrays(b)):
        assert u.dtype == v.dtype and u.shape == v.shape
        np.testing.assert_array_equal(u, v)
    assert not any(np.shares_memory(u, x0) for u in _arrays(a))
    x0[1, 0] = np.nan
    with pytest.raises(DesignError, match="finite"):
        ob._start_from(params, x0)


@pytest.mark.parametrize("kind,make,p,m", PARAMS)
def test_bound_step_equals_the_checked_step(kind, make, p, m):
    """A step bound once (``_bind_step``: the environments' step) gives the rows and states
    of ``_step_checked`` bit for bit over blocks with a dropout, for every family, members
    with different parameters included where the family has a tunable one."""
    ob = make()
    B, T = 2, 3
    names = () if ob.name == "bank" else ob.parameter_names
    params = ob.parameters(B, **{name: np.stack(_member_values(ob, name)[:B]) for name in names})
    a, b = ob.init(B, params=params), ob.init(B, params=params)
    step = ob._bind_step(params, B, T, DT)
    for block in range(4):
        rows = [signals(block * T + j, p, m) for j in range(T)]
        Y = np.ascontiguousarray(np.broadcast_to(np.array([r[0] for r in rows]), (B, T, p)))
        U = np.ascontiguousarray(np.broadcast_to(np.array([r[1] for r in rows]).reshape(T, m),
                                                 (B, T, m)))
        got, want = step(a, Y, U), ob._step_checked(params, b, Y, U, DT)
        for f in ("x_hat", "z_hat", "diagnostics"):
            np.testing.assert_array_equal(getattr(got, f), getattr(want, f), err_msg=f)
        for u, v in zip(_arrays(a), _arrays(b)):
            np.testing.assert_array_equal(u, v)


@pytest.mark.parametrize("kind,make,p,m", PARAMS)
def test_current_estimate_is_the_current_x_hat(kind, make, p, m):
    """``current_estimate`` (an environment's observation) is ``current``'s ``x_hat``, float64,
    for every family, one group of parameters and members with different ones."""
    ob = make()
    names = () if ob.name == "bank" else ob.parameter_names
    for params in (ob.parameters(2),
                   ob.parameters(2, **{n: np.stack(_member_values(ob, n)[:2]) for n in names})):
        s = ob.init(2, params=params)
        ob._step_checked(params, s, np.full((2, 3, p), 0.3), np.full((2, 3, m), 0.1), DT)
        got = ob.current_estimate(params, s)
        assert got.dtype == np.float64
        np.testing.assert_array_equal(got, ob.current(params, s)[0])
