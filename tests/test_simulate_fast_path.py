"""``simulate``'s plain-float fast path against its array path: bit-identical columns.

The fast path reads the plant through ``state_list``/``outputs_list``, runs the sensor stages'
``apply_list`` and the open-loop signal's ``value_list`` (the observers have one interface:
the same high-gain observers run in both). Subclasses that override only the array methods
(``state``, ``__call__``, ...) by calling the parent keep the same numbers but force the
array path, so the two runs below differ only in the path taken.
"""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest

from hgo_mj.exceptions import DimensionError, DivergenceError
from hgo_mj.inputs import PRBS, SIGNALS, Chirp, Constant, Controller, Multisine, Schedule, Signal
from hgo_mj.observers import HighGainObserver
from hgo_mj.plants import MujocoPlant
from hgo_mj.sensors import Dropout, GaussianNoise, Quantization, SensorChain, _rint
from hgo_mj.simulate import _owns, simulate
from hgo_mj.systems.pendulum import Pendulum


class ArrayPlant(MujocoPlant):
    """The same plant through the array interface only."""

    @property
    def state(self):
        return super().state

    def outputs(self):
        return super().outputs()

    def step(self, u):
        assert type(u) is np.ndarray  # the array interface
        super().step(u)


class ArrayGaussian(GaussianNoise):
    def __call__(self, t, y, rng):
        return super().__call__(t, y, rng)


class ArrayQuantization(Quantization):
    def __call__(self, t, y, rng):
        return super().__call__(t, y, rng)


class ArrayDropout(Dropout):
    def __call__(self, t, y, rng):
        return super().__call__(t, y, rng)


class ArrayChain(SensorChain):
    def __call__(self, t, y):
        return super().__call__(t, y)


def _array_signal(sig: Signal) -> Signal:
    """The same signal (a copy) through ``__call__`` only: a subclass that overrides it."""
    cls = type(sig)
    sub = type(f"Array{cls.__name__}", (cls,), {"__call__": lambda self, t: cls.__call__(self, t)})
    twin = copy.copy(sig)
    twin.__class__ = sub
    return twin


#: one of each signal, with values that exercise their branches over a 1.5 s run
SIGNAL_CASES = {
    "constant": lambda: Constant(0.35),
    "schedule": lambda: Schedule([0.0, 0.4, 0.9, 1.2], [0.1, -0.3, 0.25, 0.0]),
    "multisine": lambda: Multisine([0.4, 0.1], [1.3, 7.0], [0.2, 1.0], offset=0.05),
    "chirp": lambda: Chirp(0.5, 0.2, 6.0, 1.0, offset=-0.1),
    "prbs": lambda: PRBS(0.3, 0.05, seed=4, offset=0.02, length=64),
}


def _setup(fast: bool, *, dt: float = 0.001):
    plant = (MujocoPlant if fast else ArrayPlant)(Pendulum, dt=dt)
    if fast:
        stages = [GaussianNoise(std=2e-3), Quantization(counts_per_rev=2048), Dropout(0.15)]
        chain = SensorChain
    else:
        stages = [ArrayGaussian(std=2e-3), ArrayQuantization(counts_per_rev=2048),
                  ArrayDropout(0.15)]
        chain = ArrayChain
    sensor = chain(stages, seed=11)
    obs = {"free": HighGainObserver(plant.system, k=40.0),
           "model": HighGainObserver(plant.system, k=70.0, model=True,
                                     z_bounds=([-2.0, -5.0], [2.0, 5.0]))}

    def law(t, x):
        return [-3.0 * x[0] - 0.8 * x[1] + 0.2 * np.sin(3.0 * t)]

    return plant, sensor, obs, Controller(law, observer="model")


def _assert_same(a, b):
    for col in ("t", "x", "y_clean", "y_meas", "u"):
        A, B = getattr(a, col), getattr(b, col)
        assert A.shape == B.shape and A.dtype == B.dtype, col
        np.testing.assert_array_equal(A, B, err_msg=col)
    assert list(a.observers) == list(b.observers)
    for name, ra in a.observers.items():
        rb = b.observers[name]
        np.testing.assert_array_equal(ra.x_hat, rb.x_hat, err_msg=f"{name} x_hat")
        np.testing.assert_array_equal(ra.z_hat, rb.z_hat, err_msg=f"{name} z_hat")
        assert list(ra.diagnostics) == list(rb.diagnostics) == ["k", "dropouts"]
        for d in ra.diagnostics:
            np.testing.assert_array_equal(ra.diagnostics[d], rb.diagnostics[d], err_msg=d)
        assert ra.state_names == rb.state_names
    # the observers' and the input's types differ by name (the Array... subclasses)
    ma = {k: v for k, v in a.metadata.items() if k not in ("observers", "input")}
    mb = {k: v for k, v in b.metadata.items() if k not in ("observers", "input")}
    assert ma == mb
    if "input" in a.metadata:
        ia, ib = dict(a.metadata["input"]), dict(b.metadata["input"])
        assert ia.pop("type").removeprefix("Array") == ib.pop("type").removeprefix("Array")
        assert ia == ib


@pytest.mark.parametrize("periods", [{}, {"sample_period": 0.002, "control_period": 0.006}])
def test_fast_path_bit_identical_to_array_path(periods):
    runs = []
    for fast in (True, False):
        plant, sensor, obs, ctrl = _setup(fast)
        runs.append(simulate(plant, sensor, obs, ctrl, 1.5, seed=5, **periods))
    fast_run, array_run = runs
    _assert_same(fast_run, array_run)
    # the run exercised the dropouts (NaN measurements) and the saturation
    assert np.isnan(fast_run.y_meas).any()
    assert fast_run.observers["free"].diagnostics["dropouts"][-1] > 0
    assert fast_run.metadata["inverse_failures"] == {"free": 0, "model": 0}


def test_fast_path_identical_with_chunks_and_substeps():
    runs, chunks = [], []
    for fast in (True, False):
        got = []
        plant, sensor, obs, ctrl = _setup(fast, dt=0.002)
        runs.append(simulate(plant, sensor, obs, ctrl, 1.0, seed=2,
                             on_chunk=(0.3, lambda k0, c, got=got: got.append((k0, c)))))
        chunks.append(got)
    _assert_same(*runs)
    assert [k for k, _ in chunks[0]] == [k for k, _ in chunks[1]] == [0, 150, 300]
    for (_, a), (_, b) in zip(*chunks):
        _assert_same(a, b)


def test_fast_path_identical_on_divergence():
    """A plant that blows up: the same DivergenceError and partial trajectory on both paths."""
    out = []
    for fast in (True, False):
        plant, sensor, obs, _ = _setup(fast)
        ctrl = Controller(lambda t, x: [1e9 * np.exp(40.0 * t)], source="true")
        with pytest.raises(DivergenceError) as info:
            simulate(plant, sensor, obs, ctrl, 1.0, seed=1, on_chunk=(0.05, lambda k0, c: None))
        out.append(info.value)
    assert str(out[0]) == str(out[1]) and "t=-" not in str(out[0])
    _assert_same(out[0].trajectory, out[1].trajectory)


def test_plant_list_readers_take_their_own_path():
    assert _owns(MujocoPlant(Pendulum), "state_list", "state")
    assert not _owns(ArrayPlant(Pendulum), "state_list", "state")


def test_list_readers_and_quantization_match_the_arrays():
    plant = MujocoPlant(Pendulum, dt=0.001)
    for _ in range(50):
        plant.step([0.4])
    assert plant.state_list() == plant.state.tolist()
    assert plant.outputs_list() == plant.outputs().tolist()
    # a copy (or pickle) rebuilds its cached views: it steps its own MjData
    for twin in (copy.deepcopy(plant), pickle.loads(pickle.dumps(plant))):
        twin.step([0.1])
        plant_copy = copy.deepcopy(plant)
        plant_copy.step([0.1])
        assert twin.state_list() == plant_copy.state_list() != plant.state_list()
    vals = np.array([-2.5, -1.5, -0.5, -0.3, -0.0, 0.0, 0.5, 1.5, 2.5, 3.7, 2.0**52 + 1.0,
                     np.nan, np.inf, -np.inf])
    ref = np.rint(vals)
    got = np.array([_rint(v) for v in vals.tolist()])
    np.testing.assert_array_equal(got, ref)
    np.testing.assert_array_equal(np.signbit(got), np.signbit(ref))
    q = Quantization(resolution=[0.1, 0.25])
    rng = np.random.default_rng(0)
    for _ in range(200):
        y = rng.normal(0.0, 2.0, 2)
        np.testing.assert_array_equal(q.apply_list(0.0, y.tolist(), rng), q(0.0, y, rng))


def test_signal_subclass_without_value_list_takes_the_call():
    sig = Multisine([0.3], [1.0])
    assert _owns(sig, "value_list", "__call__")
    assert not _owns(_array_signal(sig), "value_list", "__call__")
    assert set(SIGNAL_CASES) == set(SIGNALS)  # every registered signal is covered below


@pytest.mark.parametrize("kind", sorted(SIGNAL_CASES))
@pytest.mark.parametrize("fast_parts", [(True, True, True), (True, False, True),
                                        (False, True, True)],
                         ids=["all-fast", "array-plant", "array-sensor"])
def test_open_loop_signal_fast_path_bit_identical(kind, fast_parts):
    """The signal's ``value_list`` against its ``__call__`` (a subclass without value_list),
    column by column, with the plant, the sensor chain or the observers on the fast path or
    not (the input array is then built from the list, or not at all)."""
    fast_sensor, fast_plant, fast_obs = fast_parts  # the observers have one interface
    runs = []
    for fast_signal in (True, False):
        plant = _setup(fast_plant)[0]
        sensor = _setup(fast_sensor)[1]
        obs = _setup(fast_obs)[2]  # a model-based observer too: it reads u in its update
        sig = SIGNAL_CASES[kind]()
        runs.append(simulate(plant, sensor, obs, sig if fast_signal else _array_signal(sig),
                             1.5, seed=7, sample_period=0.002, control_period=0.004))
    _assert_same(*runs)
    # the reference: everything on the array interface
    plant, sensor, obs, _ = _setup(False)
    ref = simulate(plant, sensor, obs, _array_signal(SIGNAL_CASES[kind]()), 1.5, seed=7,
                   sample_period=0.002, control_period=0.004)
    _assert_same(runs[0], ref)
    assert np.unique(ref.u).size > 1 or kind == "constant"


@pytest.mark.parametrize("fast", [True, False])
def test_open_loop_signal_channel_mismatch(fast):
    plant, sensor, obs, _ = _setup(True)
    sig = Constant([0.0, 1.0])
    with pytest.raises(DimensionError, match=r"input must have 1 channel\(s\) \('torque',\); "
                                             r"found shape \(2,\) at t=0"):
        simulate(plant, sensor, obs, sig if fast else _array_signal(sig), 0.1)


@pytest.mark.parametrize("kind", sorted(SIGNAL_CASES))
def test_value_list_equals_call(kind):
    sig = SIGNAL_CASES[kind]()
    ts = [0.0, 1e-9, 0.001, 0.05, 0.0499999999, 0.4, 0.39999999999, 0.9, 1.0, 1.2, 1.25,
          2.5, 7.3, 1e3, *np.linspace(0.0, 3.0, 301).tolist()]
    for t in ts:
        got, ref = sig.value_list(t), sig(t)
        assert type(got) is list and all(type(v) is float for v in got), t
        assert got == ref.tolist(), (t, got, ref)
        np.testing.assert_array_equal(np.signbit(got), np.signbit(ref))
        got.append(99.0)  # a fresh list each call: changing it changes nothing
        assert sig.value_list(t) == ref.tolist()
    # two channels
    for sig in (Constant([0.5, -1.5]), Schedule([0.0, 1.0], [[1.0, 2.0], [3.0, 4.0]])):
        for t in ts:
            assert sig.value_list(t) == sig(t).tolist()
    # the base class's default goes through __call__
    assert Signal.value_list(SIGNAL_CASES[kind](), 0.3) == SIGNAL_CASES[kind]()(0.3).tolist()
