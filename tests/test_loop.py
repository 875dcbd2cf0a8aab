"""The one loop: a batch of B members equals each member run alone; segments and storage
decimation change nothing but what is kept."""

from __future__ import annotations

import numpy as np
import pytest

import hgo_mj.simulate as sim
from hgo_mj.exceptions import DesignError, DimensionError, DivergenceError
from hgo_mj.inputs import Constant, Controller, Multisine
from hgo_mj.observers import AdaptiveGainObserver, HighGainObserver
from hgo_mj.plants import make_plant
from hgo_mj.sensors import Dropout, GaussianNoise, Quantization, SensorChain
from hgo_mj.simulate import simulate, simulate_batch


def _parts():
    plant = make_plant("pendulum")
    sensor = SensorChain([GaussianNoise(std=1e-3), Quantization(resolution=1e-4)])
    obs = {"hgo": HighGainObserver(plant.system, k=20.0),
           "model": HighGainObserver(plant.system, k=20.0, model=True),
           "adaptive": AdaptiveGainObserver(plant.system, lam=0.01, lam_hat=0.02, gamma=50.0, k0=5.0)}
    return plant, sensor, obs


def _same(a, b):
    for col in ("t", "x", "y_clean", "y_meas", "u"):
        np.testing.assert_array_equal(getattr(a, col), getattr(b, col), err_msg=col)
    assert a.observers.keys() == b.observers.keys()
    for name in a.observers:
        ra, rb = a.observers[name], b.observers[name]
        np.testing.assert_array_equal(ra.x_hat, rb.x_hat, err_msg=name)
        np.testing.assert_array_equal(ra.z_hat, rb.z_hat, err_msg=name)
        assert ra.diagnostics.keys() == rb.diagnostics.keys()
        for d in ra.diagnostics:
            np.testing.assert_array_equal(ra.diagnostics[d], rb.diagnostics[d], err_msg=d)


def test_64_seeds_in_one_batch_equal_their_single_runs():
    """B = 64 sensor streams (and 64 initial states) advance as one batch: the plants, the
    sensor chain and every observer; each member is bit-identical to its run alone."""
    seeds = list(range(100, 164))
    rng = np.random.default_rng(0)
    x0 = np.column_stack([rng.uniform(-1, 1, 64), rng.uniform(-0.5, 0.5, 64)])
    u = Multisine([0.2], [0.5])
    plant, sensor, obs = _parts()
    batch = simulate_batch(plant, sensor, obs, u, 0.5, seeds=seeds, x0=x0)
    assert len(batch) == 64
    for i in (0, 1, 17, 63):
        plant, sensor, obs = _parts()
        alone = simulate(plant, sensor, obs, u, 0.5, seed=seeds[i], x0=x0[i])
        _same(batch[i], alone)
        assert batch[i].metadata["seed"] == seeds[i]
    assert not np.array_equal(batch[0].y_meas, batch[1].y_meas)


def test_segment_length_changes_nothing(monkeypatch):
    plant, sensor, obs = _parts()
    ref = simulate(plant, sensor, obs, Multisine([0.2], [0.5]), 0.3, seed=4)
    monkeypatch.setattr(sim, "SEGMENT", 7)
    plant, sensor, obs = _parts()
    _same(simulate(plant, sensor, obs, Multisine([0.2], [0.5]), 0.3, seed=4), ref)


def test_store_every_keeps_every_kth_row():
    plant, sensor, obs = _parts()
    full = simulate(plant, sensor, obs, Multisine([0.2], [0.5]), 0.301, seed=2)
    plant, sensor, obs = _parts()
    kept = simulate(plant, sensor, obs, Multisine([0.2], [0.5]), 0.301, seed=2, store_every=10)
    assert len(kept) == 31 and kept.metadata["store_every"] == 10
    np.testing.assert_array_equal(kept.t, full.t[::10])
    np.testing.assert_array_equal(kept.x, full.x[::10])
    for name in full.observers:
        np.testing.assert_array_equal(kept.observers[name].x_hat, full.observers[name].x_hat[::10])
    with pytest.raises(DesignError, match="store_every"):
        simulate(plant, sensor, obs, Multisine([0.2], [0.5]), 0.1, store_every=1.5)


def test_closed_loop_batch_equals_single():
    """A feedback law on the estimate: the control instants split the run into segments; a
    batch of members with their own seeds equals each alone."""
    def law(t, x):
        return np.array([-2.0 * x[0] - 0.5 * x[1]])

    def parts():
        plant = make_plant("pendulum")
        return plant, SensorChain([GaussianNoise(std=1e-3)]), {
            "hgo": HighGainObserver(plant.system, k=30.0)}

    seeds = [5, 6, 7]
    plant, sensor, obs = parts()
    batch = simulate_batch(plant, sensor, obs, Controller(law), 0.2, seeds=seeds,
                           control_period=0.005)
    for i, s in enumerate(seeds):
        plant, sensor, obs = parts()
        _same(batch[i], simulate(plant, sensor, obs, Controller(law), 0.2, seed=s,
                                 control_period=0.005))


def test_batch_needs_one_seed_per_member():
    plant, sensor, obs = _parts()
    with pytest.raises(DesignError, match="seeds must be a non-empty sequence"):
        simulate_batch(plant, sensor, obs, Multisine([0.2], [0.5]), 0.1, seeds=3)
    with pytest.raises(DimensionError):
        simulate_batch(plant, sensor, obs, Multisine([0.2], [0.5]), 0.1, seeds=[1, 2],
                       x0=np.zeros((3, 2)))


@pytest.mark.parametrize("amplitude", [1e9, 1.0], ids=["first-step", "later"])
def test_plant_divergence_stops_the_run_with_the_partial_trajectory(amplitude):
    """A plant driven to blow up (MuJoCo's bad-acceleration reset) stops the run with a
    DivergenceError at a non-negative time (also when it fails on the very first step)
    carrying the valid rows, which the chunks handed out cover."""
    plant = make_plant("pendulum")
    sensor = SensorChain([GaussianNoise(std=2e-3), Dropout(0.15)], seed=11)
    obs = {"free": HighGainObserver(plant.system, k=40.0)}
    ctrl = Controller(lambda t, x: [amplitude * np.exp(40.0 * t)], source="true")
    chunks = []
    with pytest.raises(DivergenceError, match=r"^simulation stopped at t=") as info:
        simulate(plant, sensor, obs, ctrl, 1.0, seed=1,
                 on_chunk=(0.05, lambda k0, c: chunks.append((k0, c))))
    msg, traj = str(info.value), info.value.trajectory
    assert "t=-" not in msg
    assert len(traj) >= 1 and msg.startswith(f"simulation stopped at t={traj.t[-1]:g}:")
    if amplitude == 1e9:
        assert len(traj) == 1 and traj.t[-1] == 0.0
    else:
        assert len(traj) > 100
    assert np.all(np.isfinite(traj.x)) and np.all(np.isfinite(traj.observers["free"].z_hat))
    assert sum(len(c) for _, c in chunks) == len(traj)
    np.testing.assert_array_equal(np.concatenate([c.x for _, c in chunks]), traj.x)


def test_open_loop_signal_of_wrong_width_names_channels_shape_and_time():
    plant, sensor, obs = _parts()
    with pytest.raises(DimensionError, match=r"input must have 1 channel\(s\) \('torque',\); "
                                             r"found shape \(2,\) at t=0"):
        simulate(plant, sensor, obs, Constant([0.0, 1.0]), 0.1)


def test_initial_states_alone_make_a_batch():
    """``x0`` of shape (B, n) without a sensor: B plants, and as many copies of each observer,
    each member equal to its run alone."""
    rng = np.random.default_rng(3)
    x0 = np.column_stack([rng.uniform(-1, 1, 4), np.zeros(4)])

    def parts():
        plant = make_plant("pendulum")
        return plant, {"hgo": HighGainObserver(plant.system, k=20.0)}

    plant, obs = parts()
    runs = simulate_batch(plant, None, obs, Multisine([0.2], [0.5]), 0.05, seeds=[None] * 4,
                          x0=x0)
    for i in (0, 3):
        plant, obs = parts()
        _same(runs[i], simulate(plant, None, obs, Multisine([0.2], [0.5]), 0.05, x0=x0[i]))
    assert obs["hgo"].batch == 1  # the single runs left it unbatched
    with pytest.raises(DimensionError, match=r"simulate runs one member: x0 must be a state "
                                             r"\(n,\); found shape \(4, 2\)"):
        simulate(plant, None, obs, Multisine([0.2], [0.5]), 0.05, x0=x0)
    with pytest.raises(DesignError, match=r"seed must be an integer or None; found \[1, 2\]"):
        simulate(plant, None, obs, Multisine([0.2], [0.5]), 0.05, seed=[1, 2])


def test_reset_validates_once_and_again_only_when_something_changed():
    """An environment's reset does not rebuild or recheck the parameters: the same read-only
    Params serve while B and the observer's constructor values stay; a new B or a changed
    constructor value builds and checks them again (and the run uses the new value)."""
    from hgo_mj.loop import Loop, Periods

    plant = make_plant("pendulum", dt=0.01)
    ob = HighGainObserver(plant.system, k=10.0)
    loop = Loop(plant, None, {"hgo": ob}, Periods.of(plant))
    loop.reset()
    first = loop.params["hgo"]
    loop.reset()
    assert loop.params["hgo"] is first
    loop.reset(batch=2)
    assert loop.params["hgo"] is not first and loop.params["hgo"].batch == 2
    two = loop.params["hgo"]
    ob.k_ = 30.0  # the constructor's value changed in place
    loop.reset(batch=2)
    assert loop.params["hgo"] is not two and loop.params["hgo"].k.tolist() == [30.0, 30.0]


def test_reset_restarts_each_observer_from_a_fresh_initial_state():
    """While nothing changed, a reset's initial state is a copy of the last reset's: the
    observer's ``init`` bit for bit, new arrays each time (a run does not write into the next
    reset's start), and a new one where B or a constructor value changed."""
    from hgo_mj.loop import Loop, Periods

    plant = make_plant("pendulum", dt=0.01)
    ob = HighGainObserver(plant.system, k=10.0, x_hat0=[0.4, -0.2])
    # exact=False: an environment's loop, each observer's state stepped in place
    loop = Loop(plant, None, {"hgo": ob}, Periods.of(plant), exact=False)
    for batch in (None, None, None, 3, 3, 3):
        loop.reset([0.1, 0.0], batch=batch)
        s = loop.states["hgo"]
        fresh = ob.init(loop.batch, params=loop.params["hgo"])
        assert s.fields.keys() == fresh.fields.keys()
        for k, v in fresh.fields.items():
            np.testing.assert_array_equal(s.fields[k], v)
        for _ in range(3):
            loop.segment(np.full((loop.batch, 1, 1), 0.3))
        assert not np.array_equal(loop.states["hgo"].z, fresh.z)


class _FailsAt(HighGainObserver):
    """Fails in its update once it has consumed more than ``limit`` samples in all."""

    limit = 7

    def _init(self, p, x0, z0, u0):
        return {**super()._init(p, x0, z0, u0), "count": np.zeros(u0.shape[0], dtype=int)}

    def _step(self, p, s, Y, U, dt, X, Z, D):
        s.count += Y.shape[1]
        if s.count.max() > self.limit:
            raise DivergenceError("the observer state left the finite numbers: [inf]")
        super()._step(p, s, Y, U, dt, X, Z, D)


def _three(exact: bool = True):
    from hgo_mj.loop import Loop, Periods

    plant = make_plant("pendulum", dt=0.01)
    obs = {n: HighGainObserver(plant.system, k=k) for n, k in (("a", 10.0), ("b", 20.0),
                                                                ("c", 40.0))}
    return Loop(plant, None, obs, Periods.of(plant), exact=exact), obs


def test_observers_take_turns_at_running_first_after_the_plant(monkeypatch):
    """Issue 24: the observer that runs right after the plant's run meets cold caches (its
    wall time was 2x the same observer's listed second). In a segment of several samples the
    observers take turns at running first, so each pays that equally, whatever the listed
    order; the blocks keep the listed order, and each observer's rows equal its run alone,
    bit for bit. One-sample segments (an environment's step) keep the listed order."""
    from hgo_mj.loop import Loop, Periods

    loop, obs = _three()
    calls: list[str] = []
    for name, ob in obs.items():
        step = ob._step_checked
        monkeypatch.setattr(ob, "_step_checked", lambda *a, _s=step, _n=name, **k:
                            (calls.append(_n), _s(*a, **k))[1])
    loop.reset([0.3, 0.0])
    U = np.full((1, 5, 1), 0.2)
    segs = []
    for _ in range(4):
        calls.clear()
        segs.append(loop.segment(U))
        assert list(segs[-1].blocks) == ["a", "b", "c"]
        assert sorted(calls) == ["a", "b", "c"]
        segs[-1] = (segs[-1], calls[0])
    assert [first for _, first in segs] == ["a", "b", "c", "a"]
    calls.clear()
    loop.segment(U[:, :1])
    assert calls == ["a", "b", "c"]
    for name in obs:  # the same rows as the observer alone
        plant = make_plant("pendulum", dt=0.01)
        alone = Loop(plant, None, {name: HighGainObserver(plant.system, k=obs[name].k_)},
                     Periods.of(plant))
        alone.reset([0.3, 0.0])
        for seg, _ in segs:
            np.testing.assert_array_equal(alone.segment(U).blocks[name].x_hat,
                                          seg.blocks[name].x_hat)


def test_a_failure_among_turns_is_the_listed_order_one(monkeypatch):
    """Where an observer fails in a segment whose turn started with another, the segment is
    run again in the listed order from the states before it: the same failure, rows, states
    and wall times as a loop that never takes turns."""
    from hgo_mj.loop import Loop, LoopFailure, Periods

    def run(turns: bool):
        plant = make_plant("pendulum", dt=0.01)
        obs = {"bad": _FailsAt(plant.system, k=20.0),
               "ok": HighGainObserver(plant.system, k=10.0)}
        loop = Loop(plant, None, obs, Periods.of(plant), isolate=False)
        if not turns:
            monkeypatch.setattr(loop, "_rotates", lambda T: False)
        loop.reset([0.3, 0.0])
        loop.segment(np.full((1, 5, 1), 0.2))  # turn 0: "bad" first
        with pytest.raises(LoopFailure) as info:  # turn 1: "ok" first, then "bad" fails
            loop.segment(np.full((1, 5, 1), 0.2))
        return loop, info.value

    (a, fa), (b, fb) = run(True), run(False)
    assert (fa.observer, fa.row, fa.t) == (fb.observer, fb.row, fb.t) == ("bad", 7, 0.07)
    for name in ("ok", "bad"):
        np.testing.assert_array_equal(fa.segment.blocks[name].x_hat,
                                      fb.segment.blocks[name].x_hat)
        for k, v in b.states[name].fields.items():
            np.testing.assert_array_equal(a.states[name].fields[k], v)
        assert a.observers[name].x_hat.tolist() == b.observers[name].x_hat.tolist()
    assert a.k == b.k


def test_reset_members_restarts_the_observers_unless_told_not_to():
    """A vector environment's autoreset restarts its observer from the measurement itself
    (``start_observers``): ``restart_observers=False`` leaves the observer's members as
    they were, the plant's restarted."""
    from hgo_mj.loop import Loop, Periods

    plant = make_plant("pendulum", dt=0.01)
    loop = Loop(plant, None, {"hgo": HighGainObserver(plant.system, k=10.0)}, Periods.of(plant))
    loop.reset([[0.2, 0.0], [0.1, 0.0]], batch=2)
    loop.segment(np.zeros((2, 3, 1)))
    before = np.array(loop.current("hgo")[0])
    loop.reset_members([1], [[0.3, 0.0]], [None], restart_observers=False)
    np.testing.assert_array_equal(loop.current("hgo")[0], before)
    assert plant.state[1].tolist() == [0.3, 0.0]
    loop.reset_members([1], [[0.3, 0.0]], [None])
    after = np.array(loop.current("hgo")[0])
    np.testing.assert_array_equal(after[0], before[0])
    assert not np.array_equal(after[1], before[1])


def test_reset_with_start_equals_reset_then_start_observers():
    """``Loop.reset(start=...)`` makes each observer's state from the first measurement
    directly; the same states, measurement and segment as a reset, ``sample`` and
    ``start_observers`` (the two-step start it replaces in an environment)."""
    from hgo_mj.loop import Loop, Periods

    def start(ob, Y):
        return np.column_stack([Y[:, 0], np.full(len(Y), 0.5)])

    runs = []
    for direct in (True, False):
        plant, sensor, obs = _parts()
        loop = Loop(plant, sensor, obs, Periods.of(plant), exact=False)
        if direct:
            loop.reset([0.3, 0.1], seed=5, start=start)
        else:
            loop.reset([0.3, 0.1], seed=5)
            Y = loop.sample()[2][:, 0]
            loop.start_observers([0], {name: start(ob, Y) for name, ob in obs.items()})
        first = {name: [a.copy() for a in loop.current(name)] for name in obs}
        seg = loop.segment(np.full((1, 3, 1), 0.2))
        runs.append((first, seg.y_meas.copy(),
                     {name: b.x_hat.copy() for name, b in seg.blocks.items()}))
    (fa, ya, ba), (fb, yb, bb) = runs
    np.testing.assert_array_equal(ya, yb)
    for name in fa:
        for u, v in zip(fa[name], fb[name]):
            np.testing.assert_array_equal(u, v)
        np.testing.assert_array_equal(ba[name], bb[name])
    assert fa["hgo"][0][0, 1] == 0.5


@pytest.mark.parametrize("Ts", [0.01, 0.001, 0.003, 0.007])
def test_sample_times_of_a_few_samples_are_numpys_products(Ts):
    """The instants of a few samples (Python products, the bound step's) are the bits of
    the numpy products of many, at large sample indices too."""
    from hgo_mj.loop import Loop, Periods

    plant = make_plant("pendulum", dt=Ts)
    loop = Loop(plant, None, {}, Periods.of(plant))
    for k in (0, 7, 123_457, 2**40 + 3):
        loop.k = k
        for T in (1, 2, 3, 8, 9, 20):
            got = loop._times(T)
            want = np.asarray((k + np.arange(T)) * Ts, dtype=np.float64)
            assert got.dtype == np.float64 and got.tobytes() == want.tobytes(), (k, T)
