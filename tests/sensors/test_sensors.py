"""Tests of hgo_mj.sensors: each stage's promised statistics, the chain, and the validation.

Everything goes through the one primitive, :meth:`SensorChain.apply` on blocks ``(B, T, p)``:
:func:`one` is one sample of an unbatched chain (B = 1, T = 1), :func:`block` a series of
samples of it (B = 1); the batched streams themselves are tested in tests/sensors/.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hgo_mj.exceptions import DesignError, DimensionError
from hgo_mj.sensors import (
    STAGES,
    Bias,
    Delay,
    Dropout,
    GaussianNoise,
    Outliers,
    Quantization,
    RandomWalkDrift,
    SampleHold,
    Saturation,
    SensorChain,
    Stage,
    UniformNoise,
    encoder,
    make_stage,
)

N_STAT = 100_000


def one(chain: SensorChain, t: float, y) -> np.ndarray:
    """One sample ``y`` ``(p,)`` at time ``t`` through an unbatched chain, ``(p,)``."""
    return chain.apply([t], np.asarray(y, dtype=float)[None, None])[0, 0]


def block(chain: SensorChain, t, Y) -> np.ndarray:
    """Samples ``Y`` ``(T, p)`` at times ``t`` ``(T,)`` through an unbatched chain, ``(T, p)``."""
    return chain.apply(np.asarray(t, dtype=float), np.asarray(Y, dtype=float)[None])[0]


def _binomial_ok(k: int, n: int, p: float) -> bool:
    return abs(k / n - p) < 4 * math.sqrt(p * (1 - p) / n)


# --------------------------------------------------------------------------- additive noise
def test_gaussian_std_statistics():
    chain = SensorChain([GaussianNoise(std=0.3)], seed=1)
    e = one(chain, 0.0, np.zeros(N_STAT))
    assert abs(e.std() / 0.3 - 1) < 0.02
    assert abs(e.mean()) < 4 * 0.3 / math.sqrt(N_STAT)


def test_gaussian_std_per_channel_over_time():
    chain = SensorChain([GaussianNoise(std=[0.1, 2.0])], seed=2)
    y = np.array([1.0, -5.0])
    e = block(chain, np.arange(50_000) * 1e-3, np.tile(y, (50_000, 1))) - y
    assert np.all(np.abs(e.std(axis=0) / [0.1, 2.0] - 1) < 0.02)
    assert np.all(np.abs(e.mean(axis=0)) < 4 * np.array([0.1, 2.0]) / math.sqrt(50_000))


def test_gaussian_psd_form():
    g = GaussianNoise(psd=0.25e-6, sample_time=0.01)
    var = 0.25e-6 / 0.01
    assert g.variance == pytest.approx(var, rel=1e-15)
    assert g.std == pytest.approx(math.sqrt(var))
    e = one(SensorChain([g], seed=3), 0.0, np.zeros(N_STAT))
    assert abs(e.var() / var - 1) < 0.02
    assert abs(e.mean()) < 4 * math.sqrt(var / N_STAT)
    assert g.params() == {"psd": 0.25e-6, "sample_time": 0.01}


def test_gaussian_std_variance_property():
    assert GaussianNoise(std=0.2).variance == pytest.approx(0.04)
    np.testing.assert_allclose(GaussianNoise(std=[0.1, 0.3]).variance, [0.01, 0.09])


def test_uniform_statistics_and_bounds():
    hw = 0.5
    u = UniformNoise(hw)
    e = one(SensorChain([u], seed=4), 0.0, np.zeros(N_STAT))
    assert abs(e.std() / (hw / math.sqrt(3)) - 1) < 0.02
    assert np.all(np.abs(e) <= hw)
    assert e.min() < -0.99 * hw and e.max() > 0.99 * hw
    assert u.variance == pytest.approx(hw**2 / 3)
    assert abs(e.mean()) < 4 * (hw / math.sqrt(3)) / math.sqrt(N_STAT)


def test_bias_exact():
    y = np.array([0.1, -2.0, 3.5])
    out = one(SensorChain([Bias(0.25)]), 0.0, y)
    np.testing.assert_array_equal(out, y + 0.25)
    out = one(SensorChain([Bias([1.0, 2.0, -3.0])]), 0.0, y)
    np.testing.assert_array_equal(out, y + np.array([1.0, 2.0, -3.0]))


# --------------------------------------------------------------------------- drift
def test_drift_increment_variance():
    sigma, dt, n, steps = 0.5, 0.01, 20_000, 10
    chain = SensorChain([RandomWalkDrift(sigma)], seed=5)
    y = np.zeros(n)
    b = block(chain, np.arange(steps) * dt, np.tile(y, (steps, 1)))
    np.testing.assert_array_equal(b[0], 0.0)  # first call: dt = 0, b = initial
    inc = np.diff(b, axis=0).ravel()
    assert abs(inc.var() / (sigma**2 * dt) - 1) < 0.05
    assert abs(inc.mean()) < 4 * sigma * math.sqrt(dt / inc.size)


def test_drift_irregular_dt_and_initial():
    sigma, n = 2.0, 50_000
    d = RandomWalkDrift(sigma, initial=1.5)
    chain = SensorChain([d], seed=6)
    y = np.zeros(n)
    b0 = one(chain, 0.0, y)
    np.testing.assert_array_equal(b0, 1.5)
    b0b = one(chain, 0.0, y)  # dt = 0: no change
    np.testing.assert_array_equal(b0b, b0)
    b1 = one(chain, 0.04, y)
    assert abs((b1 - b0).var() / (sigma**2 * 0.04) - 1) < 0.05
    assert d.bias.shape == (1, n)                      # per stream and channel
    np.testing.assert_array_equal(d.bias[0], b1)
    chain.reset()
    assert d.bias is None
    np.testing.assert_array_equal(one(chain, 0.0, y), 1.5)
    # a block with repeated and irregular times gives the same as those samples one by one
    t = [0.0, 0.0, 0.04, 0.05, 0.05, 0.2]
    chain.reset()
    whole = block(chain, t, np.zeros((6, 3)))
    chain.reset()
    np.testing.assert_array_equal(np.array([one(chain, tk, np.zeros(3)) for tk in t]), whole)


def test_drift_time_backwards_raises():
    chain = SensorChain([RandomWalkDrift(0.1)], seed=0)
    one(chain, 1.0, np.zeros(2))
    with pytest.raises(DesignError, match="time must not decrease"):
        one(chain, 0.5, np.zeros(2))
    chain.reset()
    with pytest.raises(DesignError, match="time must not decrease"):   # within a block
        block(chain, [0.0, 1.0, 0.5], np.zeros((3, 2)))


# --------------------------------------------------------------------------- quantization
def _assert_quantized(out: np.ndarray, y: np.ndarray, res: float) -> None:
    k = out / res
    assert np.all(np.abs(k - np.rint(k)) <= 1e-12 * np.maximum(1.0, np.abs(k)))
    assert np.max(np.abs(out - y)) <= res / 2 * (1 + 1e-9)


def test_quantization_exact_step():
    rng = np.random.default_rng(0)
    y = rng.uniform(-10, 10, 10_000)
    for res in (0.01, 1e-3, 0.37, 2 * math.pi / 1024):
        out = one(SensorChain([Quantization(res)]), 0.0, y)
        _assert_quantized(out, y, res)
        # the error spreads over the whole step (not a constant offset)
        assert np.max(np.abs(out - y)) > 0.49 * res


def test_quantization_counts_per_rev():
    q = Quantization(counts_per_rev=4096)
    assert q.resolution == 2 * math.pi / 4096
    assert q.params() == {"counts_per_rev": 4096}
    assert q.variance == pytest.approx(q.resolution**2 / 12)
    y = np.linspace(-7, 7, 1001)
    _assert_quantized(one(SensorChain([q]), 0.0, y), y, 2 * math.pi / 4096)
    enc = encoder(1024, std=0.001)
    assert [s.name for s in enc] == ["gaussian", "quantize"]
    assert [s.name for s in encoder(1024)] == ["quantize"]


@settings(max_examples=200, deadline=None)
@given(
    y=st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=1, max_size=20),
    res=st.floats(1e-6, 1e3),
)
def test_quantization_error_bounded_property(y, res):
    y = np.array(y)
    out = one(SensorChain([Quantization(res)]), 0.0, y)
    k = out / res
    assert np.all(np.abs(k - np.rint(k)) <= 1e-12 * np.maximum(1.0, np.abs(k)))
    tol = res / 2 + 4 * np.finfo(float).eps * np.maximum(np.abs(y), res)
    assert np.all(np.abs(out - y) <= tol)


# --------------------------------------------------------------------------- sample & hold
@pytest.mark.parametrize("accumulate", [False, True])
def test_sample_hold_changes_every_10_calls(accumulate):
    ts, n = 1e-3, 2000
    chain = SensorChain([SampleHold(0.01)])
    t = 0.0
    outs, ins = [], []
    for k in range(n):
        if not accumulate:
            t = k * ts
        y = np.array([k + 1.0, -3.0 * k])
        ins.append(y)
        outs.append(one(chain, t, y))
        if accumulate:
            t += ts
    outs, ins = np.array(outs), np.array(ins)
    changed = np.flatnonzero(np.any(np.diff(outs, axis=0) != 0, axis=1)) + 1
    np.testing.assert_array_equal(changed, np.arange(10, n, 10))
    for k in range(n):
        np.testing.assert_array_equal(outs[k], ins[10 * (k // 10)])


def test_sample_hold_floating_point_accumulation():
    sh = SensorChain([SampleHold(0.1)])
    t = 0.0
    assert one(sh, t, [1.0])[0] == 1.0
    t += 0.1
    t += 0.1
    assert one(sh, t, [2.0])[0] == 2.0   # 0.2: new sample
    t += 0.1                              # 0.30000000000000004
    assert one(sh, t, [3.0])[0] == 3.0
    assert one(sh, 0.35, [4.0])[0] == 3.0
    sh.restart()
    assert one(sh, 0.35, [5.0])[0] == 5.0  # first sample after a restart samples
    sh.stages[0].reset()
    assert one(sh, 0.36, [6.0])[0] == 6.0  # ... and after the stage's own reset


# --------------------------------------------------------------------------- delay
@pytest.mark.parametrize("accumulate", [False, True])
def test_delay_exact_in_samples(accumulate):
    ts, m, n = 1e-3, 5, 500
    d = Delay(m * ts)
    chain = SensorChain([d])
    ins, outs = [], []
    t = 0.0
    for k in range(n):
        if not accumulate:
            t = k * ts
        y = np.array([10.0 + k, -float(k) ** 2])
        ins.append(y)
        outs.append(one(chain, t, y))
        if accumulate:
            t += ts
        assert len(d._bstate[1]["t"]) <= m + 2   # bounded buffer (the entries still needed)
    for k in range(n):
        np.testing.assert_array_equal(outs[k], ins[k - m] if k >= m else ins[0])


def test_delay_fractional_and_zero():
    ts = 0.01
    chain = SensorChain([Delay(2.5 * ts)])
    ins = [np.array([float(k)]) for k in range(20)]
    outs = [one(chain, k * ts, y) for k, y in enumerate(ins)]
    for k in range(20):
        assert outs[k][0] == max(k - 3, 0)
    chain0 = SensorChain([Delay(0.0)])
    for k in range(5):
        y = np.array([k * 1.5])
        out = one(chain0, k * ts, y)
        np.testing.assert_array_equal(out, y)
        assert out is not y


def test_delay_reset_and_errors():
    chain = SensorChain([Delay(0.02)])
    one(chain, 0.0, np.array([1.0]))
    one(chain, 0.01, np.array([2.0]))
    with pytest.raises(DesignError, match="time must not decrease"):
        one(chain, 0.005, np.array([3.0]))
    with pytest.raises(DimensionError, match="changed length from 1 to 2"):
        one(chain, 0.02, np.array([3.0, 4.0]))
    chain.reset()
    assert one(chain, 5.0, np.array([7.0]))[0] == 7.0
    assert one(chain, 5.01, np.array([8.0]))[0] == 7.0


@settings(max_examples=50, deadline=None)
@given(m=st.integers(0, 12), ts=st.sampled_from([1e-3, 0.01, 0.1, 1 / 3]),
       n=st.integers(1, 60))
def test_delay_property(m, ts, n):
    chain = SensorChain([Delay(m * ts)])
    for k in range(n):
        out = one(chain, k * ts, np.array([float(k)]))
        assert out[0] == max(k - m, 0)


# --------------------------------------------------------------------------- dropout, outliers
def test_dropout_rate_and_count():
    p, n_ch, calls = 0.1, 1000, 100
    drop = Dropout(p)
    chain = SensorChain([drop], seed=8)
    y = np.arange(n_ch, dtype=float)
    nan_total = 0
    assert drop.counts is None and chain.dropouts == 0
    for k in range(calls):
        before = chain.dropouts
        out = one(chain, k * 1e-3, y)
        nan = np.isnan(out)
        assert chain.dropouts - before == nan.sum()       # NaN exactly where counted
        np.testing.assert_array_equal(out[~nan], y[~nan])  # never a silent zero
        nan_total += int(nan.sum())
    assert drop.counts.tolist() == [nan_total] and chain.dropouts == nan_total
    assert _binomial_ok(nan_total, n_ch * calls, p)
    chain.reset()
    assert drop.counts is None and chain.dropouts == 0


def test_dropout_extremes():
    y = np.ones(1000)
    assert not np.any(np.isnan(one(SensorChain([Dropout(0.0)], seed=0), 0.0, y)))
    assert np.all(np.isnan(one(SensorChain([Dropout(1.0)], seed=0), 0.0, y)))
    out = one(SensorChain([Dropout([0.0, 1.0])], seed=0), 0.0, np.array([1.0, 2.0]))
    assert out[0] == 1.0 and np.isnan(out[1])


def test_chain_dropouts_sums_stages():
    chain = SensorChain([Dropout(0.2), Bias(1.0), Dropout(0.3)], seed=9)
    for k in range(100):
        one(chain, k * 0.01, np.zeros(10))
    (a,), (b,) = chain.stages[0].counts, chain.stages[2].counts
    assert a > 0 and b > 0 and chain.dropouts == a + b
    np.testing.assert_array_equal(chain.dropout_counts(), [a + b])


def test_outliers_rate_and_magnitude():
    p, mag, n_ch, calls = 0.05, 3.0, 1000, 100
    o = Outliers(p, mag)
    chain = SensorChain([o], seed=10)
    y = np.zeros(n_ch)
    out = np.array([one(chain, k * 1e-3, y) for k in range(calls)])
    assert set(np.unique(out)) <= {-mag, 0.0, mag}    # magnitude exact
    hits = int(np.count_nonzero(out))
    assert o.counts.tolist() == [hits]
    assert _binomial_ok(hits, n_ch * calls, p)
    assert _binomial_ok(int(np.count_nonzero(out > 0)), hits, 0.5)   # random sign
    chain.reset()
    assert o.counts is None


def test_outliers_on_signal():
    y = np.linspace(-1, 1, 5000)
    o = Outliers(0.5, [2.0] * 5000)
    out = one(SensorChain([o], seed=11), 0.0, y)
    d = out - y
    hit = d != 0
    np.testing.assert_allclose(np.abs(d[hit]), 2.0, rtol=1e-14)
    assert o.counts.tolist() == [hit.sum()]


# --------------------------------------------------------------------------- saturation
def test_saturation():
    y = np.array([-5.0, -1.0, 0.0, 0.5, 7.0, np.nan])
    out = one(SensorChain([Saturation(-1.0, 1.0)]), 0.0, y)
    np.testing.assert_array_equal(out, [-1.0, -1.0, 0.0, 0.5, 1.0, np.nan])
    out = one(SensorChain([Saturation(-np.inf, 0.2)]), 0.0, y[:5])
    np.testing.assert_array_equal(out, [-5.0, -1.0, 0.0, 0.2, 0.2])
    out = one(SensorChain([Saturation([0.0, -10.0], [1.0, 10.0])]), 0.0, np.array([5.0, 5.0]))
    np.testing.assert_array_equal(out, [1.0, 5.0])


@settings(max_examples=100, deadline=None)
@given(y=st.lists(st.floats(-1e9, 1e9), min_size=1, max_size=10),
       lo=st.floats(-100, 100), width=st.floats(1e-6, 100))
def test_saturation_property(y, lo, width):
    y = np.array(y)
    hi = lo + width
    out = one(SensorChain([Saturation(lo, hi)]), 0.0, y)
    assert np.all((out >= lo) & (out <= hi))
    inside = (y >= lo) & (y <= hi)
    np.testing.assert_array_equal(out[inside], y[inside])


# --------------------------------------------------------------------------- the chain
def _full_chain(seed: int | None) -> SensorChain:
    return SensorChain([Delay(0.003), SampleHold(0.002), Bias(0.1), RandomWalkDrift(0.2),
                        GaussianNoise(std=0.05), UniformNoise(0.01), Outliers(0.05, 1.0),
                        Quantization(1e-3), Saturation(-2.0, 2.0), Dropout(0.05)], seed=seed)


def _run(chain: SensorChain, n: int = 300) -> np.ndarray:
    k = np.arange(n)
    Y = np.stack([np.sin(k * 0.01), np.cos(k * 0.01), np.full(n, 0.5)], axis=1)
    return np.concatenate([block(chain, k[:100] * 1e-3, Y[:100]),   # blocks of any length
                           np.array([one(chain, j * 1e-3, Y[j]) for j in range(100, 150)]),
                           block(chain, k[150:] * 1e-3, Y[150:])])


def test_order_matters():
    y = np.array([0.0, 0.04])
    a = one(SensorChain([Quantization(0.1), Bias(0.03)]), 0.0, y)
    b = one(SensorChain([Bias(0.03), Quantization(0.1)]), 0.0, y)
    np.testing.assert_allclose(a, [0.03, 0.03])
    np.testing.assert_allclose(b, [0.0, 0.1])


def test_same_seed_bit_identical_and_reset():
    a = _run(_full_chain(7))
    b = _run(_full_chain(7))
    assert np.array_equal(a, b, equal_nan=True)
    assert np.isnan(a).any()
    c = _full_chain(7)
    first = _run(c)
    c.reset()
    assert np.array_equal(_run(c), first, equal_nan=True)
    c.reset(seed=11)
    assert c.seed == 11
    assert np.array_equal(_run(c), _run(_full_chain(11)), equal_nan=True)
    c.reset()                      # back to the constructor's seed
    assert c.seed == 7
    assert np.array_equal(_run(c), first, equal_nan=True)


def test_different_seeds_differ():
    a = _run(_full_chain(1))
    b = _run(_full_chain(2))
    assert not np.array_equal(a, b, equal_nan=True)


def test_input_not_modified():
    y = np.array([0.3, -0.7, 1.2])
    y0 = y.copy()
    Y = np.tile(y, (50, 1))[None]
    Y0 = Y.copy()
    chain = _full_chain(0)
    out = chain.apply(np.arange(50) * 1e-3, Y)
    assert not np.shares_memory(out, Y)
    np.testing.assert_array_equal(Y, Y0)
    for s in _full_chain(0).stages:
        alone = SensorChain([s], seed=0)
        out = alone.apply([0.0], Y[:, :1])
        assert not np.shares_memory(out, Y)
        out[:] = 99.0                           # mutating an output leaves the input...
        np.testing.assert_array_equal(Y, Y0)
    sh = SensorChain([SampleHold(1.0)])
    out = sh.apply([0.0], Y[:, :1])
    out[:] = 99.0                               # ...and the held sample intact
    np.testing.assert_array_equal(one(sh, 0.1, y * 2), y0)


def test_empty_chain_returns_copy():
    y = np.array([1.0, 2.0])
    out = one(SensorChain(), 0.0, y)
    np.testing.assert_array_equal(out, y)
    Y = y[None, None]
    assert not np.shares_memory(SensorChain().apply([0.0], Y), Y)
    np.testing.assert_array_equal(one(SensorChain(), 0.0, [1, 2]), [1.0, 2.0])


def test_describe_from_spec_round_trip():
    spec = [
        {"stage": "delay", "delay": 0.002},
        {"stage": "sample_hold", "period": 0.001},
        {"stage": "bias", "offset": [0.1, -0.1]},
        {"stage": "drift", "sigma": 0.01, "initial": 0.0},
        {"stage": "gaussian", "psd": 0.25e-6, "sample_time": 0.01},
        {"stage": "uniform", "half_width": 0.002},
        {"stage": "outliers", "p": 0.01, "magnitude": 0.5},
        {"stage": "quantize", "counts_per_rev": 2048},
        {"stage": "saturate", "low": -3.0, "high": 3.0},
        {"stage": "dropout", "p": 0.01},
    ]
    chain = SensorChain.from_spec(spec, seed=3)
    desc = chain.describe()
    assert desc == spec
    assert json.loads(json.dumps(desc)) == desc
    again = SensorChain.from_spec(desc, seed=3)
    assert again.describe() == desc
    y = np.array([0.4, -0.2])
    a = [one(chain, k * 1e-3, y) for k in range(100)]
    b = block(again, np.arange(100) * 1e-3, np.tile(y, (100, 1)))
    assert np.array_equal(np.array(a), np.array(b), equal_nan=True)
    assert GaussianNoise(std=[0.1, 0.2]).params() == {"std": [0.1, 0.2]}


def test_noise_variance():
    chain = SensorChain([Bias(1.0), GaussianNoise(std=0.1), UniformNoise(0.3),
                         Quantization(0.01), RandomWalkDrift(1.0), Outliers(0.1, 5.0)])
    expected = 0.01 + 0.09 / 3 + 1e-4 / 12
    np.testing.assert_allclose(chain.noise_variance(3), [expected] * 3, rtol=1e-14)
    chain = SensorChain([GaussianNoise(std=[0.1, 0.2]),
                         GaussianNoise(psd=1e-6, sample_time=1e-3)])
    np.testing.assert_allclose(chain.noise_variance(2), [0.01 + 1e-3, 0.04 + 1e-3])
    with pytest.raises(DimensionError, match="2 entries.*n_outputs is 3"):
        chain.noise_variance(3)
    np.testing.assert_array_equal(SensorChain().noise_variance(2), [0.0, 0.0])
    with pytest.raises(DesignError, match="n_outputs must be a positive integer"):
        chain.noise_variance(0)


def test_noise_variance_matches_empirical():
    chain = SensorChain([GaussianNoise(std=0.02), UniformNoise(0.05), Quantization(0.01)],
                        seed=12)
    rng = np.random.default_rng(1)
    y = rng.uniform(-1, 1, N_STAT)
    e = one(chain, 0.0, y) - y
    assert abs(e.var() / chain.noise_variance(1)[0] - 1) < 0.03


# --------------------------------------------------------------------------- registry
def test_registry():
    assert set(STAGES) == {"gaussian", "uniform", "bias", "drift", "quantize", "sample_hold",
                           "delay", "dropout", "outliers", "saturate"}
    for name, cls in STAGES.items():
        assert issubclass(cls, Stage) and cls.name == name
        assert cls.summary and "\n" not in cls.summary


@pytest.mark.parametrize("name,params", [
    ("gaussian", {"std": 0.1}), ("uniform", {"half_width": 0.2}), ("bias", {"offset": 1.0}),
    ("drift", {"sigma": 0.1}), ("quantize", {"resolution": 0.01}),
    ("sample_hold", {"period": 0.01}), ("delay", {"delay": 0.0}), ("dropout", {"p": 0.5}),
    ("outliers", {"p": 0.1, "magnitude": 2.0}), ("saturate", {"low": -1, "high": 1}),
])
def test_make_stage_round_trip(name, params):
    s = make_stage(name, **params)
    assert isinstance(s, STAGES[name])
    assert make_stage(name, **s.params()).params() == s.params()
    assert type(s).__name__ in repr(s)


# --------------------------------------------------------------------------- validation
@pytest.mark.parametrize("build,match", [
    (lambda: GaussianNoise(std=-0.1), r"GaussianNoise\.std must be >= 0; found -0\.1"),
    (lambda: GaussianNoise(std=0.1, psd=1e-6, sample_time=0.01), "exactly one.*found both"),
    (lambda: GaussianNoise(), "exactly one.*found neither"),
    (lambda: GaussianNoise(psd=1e-6), r"sample_time must be given with psd"),
    (lambda: GaussianNoise(std=0.1, sample_time=0.01), "sample_time goes with psd"),
    (lambda: GaussianNoise(psd=1e-6, sample_time=0.0), r"sample_time must be > 0; found 0"),
    (lambda: GaussianNoise(psd=-1e-6, sample_time=0.1), r"psd must be >= 0"),
    (lambda: GaussianNoise(std=float("nan")), r"GaussianNoise\.std must be finite; found nan"),
    (lambda: GaussianNoise(std=[0.1, float("inf")]), r"std must be finite"),
    (lambda: UniformNoise(-1.0), r"UniformNoise\.half_width must be >= 0; found -1"),
    (lambda: Bias(float("nan")), r"Bias\.offset must be finite; found nan"),
    (lambda: Bias("abc"), r"Bias\.offset must be a real number"),
    (lambda: Bias(None), r"Bias\.offset must be a real number"),
    (lambda: RandomWalkDrift(-0.5), r"RandomWalkDrift\.sigma must be >= 0"),
    (lambda: RandomWalkDrift(0.5, initial=float("nan")), r"initial must be finite"),
    (lambda: Quantization(0.0), r"Quantization\.resolution must be > 0; found 0"),
    (lambda: Quantization(-0.1), r"Quantization\.resolution must be > 0; found -0\.1"),
    (lambda: Quantization(float("nan")), r"resolution must be finite; found nan"),
    (lambda: Quantization(), "exactly one.*found neither"),
    (lambda: Quantization(0.1, counts_per_rev=100), "exactly one.*found both"),
    (lambda: Quantization(counts_per_rev=0), r"counts_per_rev must be > 0"),
    (lambda: Quantization(counts_per_rev=10.5), r"counts_per_rev must be a positive integer"),
    (lambda: SampleHold(0.0), r"SampleHold\.period must be > 0; found 0"),
    (lambda: SampleHold(float("nan")), r"SampleHold\.period must be finite"),
    (lambda: Delay(-0.01), r"Delay\.delay must be >= 0; found -0\.01"),
    (lambda: Delay(float("inf")), r"Delay\.delay must be finite"),
    (lambda: Dropout(1.5), r"Dropout\.p must be in \[0, 1\]; found 1\.5"),
    (lambda: Dropout(-0.1), r"Dropout\.p must be in \[0, 1\]; found -0\.1"),
    (lambda: Dropout([0.1, 2.0]), r"Dropout\.p must be in \[0, 1\]; found \[0\.1, 2\.0\]"),
    (lambda: Dropout(float("nan")), r"Dropout\.p must be finite; found nan"),
    (lambda: Outliers(2.0, 1.0), r"Outliers\.p must be in \[0, 1\]"),
    (lambda: Outliers(0.1, -1.0), r"Outliers\.magnitude must be >= 0"),
    (lambda: Saturation(1.0, 1.0), r"low < high; found low=1\.0, high=1\.0"),
    (lambda: Saturation(2.0, 1.0), r"low < high; found low=2\.0, high=1\.0"),
    (lambda: Saturation([0.0, 0.0], [1.0, -1.0]), r"low < high"),
    (lambda: Saturation(float("nan"), 1.0), r"Saturation\.low must be not NaN; found nan"),
    (lambda: encoder(1024, std=-1.0), r"encoder\.std must be >= 0"),
    (lambda: SensorChain(seed=-1), "seed must be a non-negative integer"),
    (lambda: SensorChain(seed=1.5), "seed must be a non-negative integer"),
    (lambda: SensorChain([object()]), "stage 0 must be a Stage"),
])
def test_design_errors(build, match):
    with pytest.raises(DesignError, match=match):
        build()


def test_make_stage_errors():
    with pytest.raises(DesignError, match=r"unknown sensor stage 'gausian'.*'gaussian'.*"
                                          r"'sample_hold'"):
        make_stage("gausian", std=0.1)
    with pytest.raises(DesignError,
                       match=r"unknown parameter\(s\) \['sd'\]; valid: \['psd', "
                             r"'sample_time', 'std'\]"):
        make_stage("gaussian", sd=0.1)
    with pytest.raises(DesignError, match=r"missing parameter\(s\) \['offset'\]"):
        make_stage("bias")
    with pytest.raises(DesignError, match=r"Dropout\.p must be in \[0, 1\]"):
        make_stage("dropout", p=3)


def test_from_spec_reads_every_form_of_a_stage():
    """The one reader of a sensor spec: dicts, bare names, Stage instances, one stage alone."""
    bias = Bias(0.5)
    chain = SensorChain.from_spec([{"stage": "gaussian", "std": 0.1}, bias], seed=3)
    assert [s.name for s in chain.stages] == ["gaussian", "bias"]
    assert chain.stages[1] is bias and chain.seed == 3
    with pytest.raises(DesignError, match=r"Bias \('bias'\): missing parameter\(s\) \['offset'\]"):
        SensorChain.from_spec(["bias"])  # a bare name: the stage without parameters
    assert SensorChain.from_spec({"stage": "gaussian", "std": 0.1}).describe() == [
        {"stage": "gaussian", "std": 0.1}]
    assert len(SensorChain.from_spec(None)) == 0 == len(SensorChain.from_spec([]))


def test_from_spec_errors():
    with pytest.raises(DesignError, match=r"spec\[1\] has no 'stage' key.*found keys \['std'\]"):
        SensorChain.from_spec([{"stage": "bias", "offset": 1.0}, {"std": 0.1}])
    with pytest.raises(DesignError, match=r"spec\[0\] must be a dict.*a stage name or a Stage; "
                                          r"found 5"):
        SensorChain.from_spec([5])
    with pytest.raises(DesignError, match="must be a list of stages"):
        SensorChain.from_spec(5)
    with pytest.raises(DesignError, match="unknown sensor stage 'nope'"):
        SensorChain.from_spec([{"stage": "nope"}])


@pytest.mark.parametrize("stage", [
    GaussianNoise(std=[0.1, 0.2, 0.3]), GaussianNoise(psd=[1e-6] * 3, sample_time=0.01),
    UniformNoise([0.1, 0.2, 0.3]), Bias([1.0, 2.0, 3.0]), RandomWalkDrift([0.1, 0.2, 0.3]),
    Quantization([0.1, 0.2, 0.3]), Quantization(counts_per_rev=[100, 200, 300]),
    Dropout([0.1, 0.2, 0.3]), Outliers(0.1, [1.0, 2.0, 3.0]),
    Saturation([-1.0, -1.0, -1.0], 1.0),
])
def test_per_channel_length_mismatch(stage):
    chain = SensorChain([stage], seed=0)
    assert one(chain, 0.0, np.zeros(3)).shape == (3,)   # right length works
    with pytest.raises(DimensionError, match=r"has 3 entries \(one per channel\) but y has "
                                             r"2 channels"):
        one(chain, 0.0, np.zeros(2))


def test_per_channel_params_disagree():
    with pytest.raises(DimensionError, match=r"Saturation\.high has 3 entries but "
                                             r"Saturation\.low has 2"):
        Saturation([0.0, 0.0], [1.0, 1.0, 1.0])
    with pytest.raises(DimensionError, match=r"Bias\.offset must be a scalar or 1-D.*"
                                             r"found shape \(1, 2\)"):
        Bias([[1.0, 2.0]])
    with pytest.raises(DimensionError, match="empty"):
        Bias([])


@pytest.mark.parametrize("Y", [np.zeros((2, 2)), np.float64(1.0), 3.0, np.zeros((1, 3)),
                               np.zeros(3), np.zeros((1, 1, 1, 3))])
def test_y_not_a_block(Y):
    for chain in (SensorChain(), SensorChain([Bias(1.0)])):
        with pytest.raises(DimensionError, match=r"Y must have shape \(B, T, p\) = \(1, 1, p\); "
                                                 r"found shape"):
            chain.apply([0.0], Y)


def test_call_errors():
    with pytest.raises(DimensionError, match=r"t \(T,\) and Y \(B, T, p\) must be arrays of "
                                             "numbers"):
        SensorChain([Bias(1.0)]).apply([0.0], [[["a", "b"]]])
    with pytest.raises(DesignError, match="t must be finite"):
        one(SensorChain([Bias(1.0)]), float("nan"), np.zeros(2))
    chain = SensorChain([RandomWalkDrift(0.1)], seed=0)
    one(chain, 0.0, np.zeros(2))
    with pytest.raises(DimensionError, match="changed length from 2 to 3"):
        one(chain, 0.1, np.zeros(3))
    chain = SensorChain([SampleHold(0.1)])
    one(chain, 0.0, np.zeros(2))
    with pytest.raises(DimensionError, match="changed length from 2 to 3"):
        one(chain, 0.2, np.zeros(3))
