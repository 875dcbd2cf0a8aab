"""Batched sensor chains: ``SensorChain.reset(seeds)`` and ``apply(t, Y (B, T, p))``.

Every stream equals the same seed run alone, bit for bit; a block equals the same samples cut
into smaller blocks; the random stage of a chain with one draws exactly ``default_rng(seed)``'s
numbers in sample order (checked against the stage's formula written out sample by sample);
in a chain with more random stages the later ones draw from generators spawned from the seed.
"""

from __future__ import annotations

import numpy as np
import pytest

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
    stream_generators,
)

B, T, P = 64, 200, 2
SEEDS = list(range(100, 100 + B))

CHAINS = {
    "gaussian": lambda: [GaussianNoise(std=[0.1, 0.2])],
    "gaussian_psd": lambda: [GaussianNoise(psd=0.25e-6, sample_time=0.01)],
    "uniform": lambda: [UniformNoise([0.2, 0.05])],
    "bias": lambda: [Bias([0.1, -0.3])],
    "drift": lambda: [RandomWalkDrift(0.3, initial=[0.1, -0.1])],
    "quantize": lambda: [Quantization(resolution=0.05)],
    "encoder": lambda: [Quantization(counts_per_rev=[2048, 512])],
    "sample_hold": lambda: [SampleHold(0.03)],
    "delay": lambda: [Delay(0.05)],
    "delay_fractional": lambda: [Delay(0.017)],
    "dropout": lambda: [Dropout([0.2, 0.5])],
    "outliers": lambda: [Outliers(0.1, [1.0, 2.0])],
    "saturate": lambda: [Saturation(-0.5, [0.4, 0.6])],
    "gaussian+quantize": lambda: [GaussianNoise(std=0.01), Quantization(resolution=0.005)],
    "deterministic": lambda: [Delay(0.02), SampleHold(0.03), Bias(0.1), Quantization(0.01),
                              Saturation(-1.0, 1.0)],
    # two and more random stages: the later ones on spawned generators
    "recommended": lambda: [Delay(0.02), SampleHold(0.02), Bias(0.05), RandomWalkDrift(0.1),
                            GaussianNoise(std=0.02), Outliers(0.05, 0.5), Quantization(0.01),
                            Saturation(-2.0, 2.0), Dropout(0.1)],
    "gaussian+dropout": lambda: [GaussianNoise(std=1.0), Dropout(0.5)],
}
ONE_RANDOM = [k for k, mk in CHAINS.items()
              if sum(s.draws is not None for s in mk()) <= 1]


def _gaussian(std):
    def ref(t, Y, rng):
        return np.array([y + std * rng.standard_normal(P) for y in Y])
    return ref


def _uniform(t, Y, rng):
    return np.array([(rng.random(P) * 2.0 - 1.0) * np.array([0.2, 0.05]) + y for y in Y])


def _drift(t, Y, rng):
    b, out = np.array([0.1, -0.1]), []
    for j, y in enumerate(Y):
        z = rng.standard_normal(P)
        if j:
            b = b + z * 0.3 * np.sqrt(t[j] - t[j - 1])
        out.append(y + b)
    return np.array(out)


def _dropout(t, Y, rng):
    return np.array([np.where(rng.random(P) < [0.2, 0.5], np.nan, y) for y in Y])


def _outliers(t, Y, rng):
    out = []
    for y in Y:
        hit, sign = rng.random(P) < 0.1, rng.random(P) < 0.5
        out.append(np.where(hit, y + np.where(sign, -1.0, 1.0) * np.array([1.0, 2.0]), y))
    return np.array(out)


def _gaussian_quantize(t, Y, rng):
    Z = _gaussian(0.01)(t, Y, rng)
    return np.rint(Z / 0.005) * 0.005


#: the random stages of the one-random-stage chains written out sample by sample
REFERENCE = {
    "gaussian": _gaussian(np.array([0.1, 0.2])),
    "gaussian_psd": _gaussian(np.sqrt(0.25e-6 / 0.01)),
    "uniform": _uniform,
    "drift": _drift,
    "dropout": _dropout,
    "outliers": _outliers,
    "gaussian+quantize": _gaussian_quantize,
}


def test_every_stage_is_covered():
    covered = {type(s) for mk in CHAINS.values() for s in mk()}
    assert covered == set(STAGES.values())
    assert set(ONE_RANDOM) == set(CHAINS) - {"recommended", "gaussian+dropout"}
    assert {k for k in ONE_RANDOM if any(s.draws for s in CHAINS[k]())} == set(REFERENCE)


def times(irregular: bool) -> np.ndarray:
    t = np.arange(T) * 0.01
    if irregular:
        t = t + np.random.default_rng(0).uniform(0, 0.004, T)
        t[::17] = t[np.maximum(np.arange(0, T, 17) - 1, 0)]   # repeated times too
    return np.maximum.accumulate(t)


def clean(seed=7) -> np.ndarray:
    Y = np.random.default_rng(seed).standard_normal((B, T, P)).cumsum(axis=1) * 0.05
    Y[3, 10:20] = np.nan      # NaN inputs (an earlier dropout) pass through
    return Y


@pytest.mark.parametrize("irregular", [False, True])
@pytest.mark.parametrize("name", list(CHAINS))
def test_batch_equals_each_seed_alone(name, irregular):
    t, Y = times(irregular), clean()
    Y0 = Y.copy()
    chain = SensorChain(CHAINS[name]())
    chain.reset(SEEDS)
    assert chain.batch == B and chain.batched and chain.seeds == tuple(SEEDS)
    out = chain.apply(t, Y)
    np.testing.assert_array_equal(Y, Y0)          # input not modified
    assert out.shape == (B, T, P)
    alone = SensorChain(CHAINS[name]())
    for b, sd in enumerate(SEEDS):
        alone.reset(sd)                            # one seed: B = 1, unbatched
        assert alone.batch == 1 and not alone.batched
        np.testing.assert_array_equal(alone.apply(t, Y[b:b + 1])[0], out[b])
    if name in REFERENCE:
        # the formula sample by sample with default_rng(seed), as the per-sample path drew
        for b in (0, 1, B - 1):
            ref = REFERENCE[name](t, Y[b], np.random.default_rng(SEEDS[b]))
            np.testing.assert_array_equal(ref, out[b])


@pytest.mark.parametrize("cuts", [(1,) * T, (7,) * 28 + (4,), (3, 50, 1, 146), (T,)])
@pytest.mark.parametrize("name", list(CHAINS))
def test_blocks_cut_anywhere(name, cuts):
    t, Y = times(True), clean()[:8]
    chain = SensorChain(CHAINS[name]())
    chain.reset(SEEDS[:8])
    whole = chain.apply(t, Y)
    chain.reset(SEEDS[:8])
    parts, j = [], 0
    for c in cuts:
        parts.append(chain.apply(t[j:j + c], Y[:, j:j + c]))
        j += c
    assert j == T
    np.testing.assert_array_equal(np.concatenate(parts, axis=1), whole)


def test_reset_restarts_the_streams_and_none_reuses_the_constructor_seed():
    t, Y = times(False), clean()[:4]
    chain = SensorChain(CHAINS["recommended"](), seed=5)
    chain.reset(SEEDS[:4])
    a = chain.apply(t, Y)
    chain.reset(SEEDS[:4])
    np.testing.assert_array_equal(chain.apply(t, Y), a)
    chain.reset()                                  # the constructor's seed, one stream
    assert chain.seeds == (5,) and not chain.batched
    b = chain.apply(t, Y[:1])
    chain.reset([5])
    np.testing.assert_array_equal(chain.apply(t, Y[:1]), b)
    fresh = SensorChain(CHAINS["recommended"](), seed=5)   # the constructor starts a stream
    np.testing.assert_array_equal(fresh.apply(t, Y[:1]), b)


def test_later_random_stages_draw_from_spawned_generators():
    """Gaussian noise then dropout on zeros: the values are default_rng(seed)'s normals, the
    lost samples those where the first child of SeedSequence(seed) draws below p."""
    seed, n = 42, 300
    chain = SensorChain([GaussianNoise(std=1.0), Dropout(0.5)])
    chain.reset([seed])
    out = chain.apply(np.arange(n) * 0.1, np.zeros((1, n, 1)))[0, :, 0]
    z = np.random.default_rng(seed).standard_normal(n)
    u = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0]).random(n)
    np.testing.assert_array_equal(np.isnan(out), u < 0.5)
    np.testing.assert_array_equal(out[u >= 0.5], z[u >= 0.5])
    gens = stream_generators(seed, 3)
    assert gens[1].random() == np.random.default_rng(
        np.random.SeedSequence(seed).spawn(2)[0]).random()
    assert gens[2].random() == np.random.default_rng(
        np.random.SeedSequence(seed).spawn(2)[1]).random()


def test_dropout_counts_per_stream():
    t, Y = times(False), np.zeros((B, T, P))
    chain = SensorChain([Dropout(0.3), Dropout([0.0, 0.1])])
    chain.reset(SEEDS)
    out = chain.apply(t[:50], Y[:, :50])
    out2 = chain.apply(t[50:], Y[:, 50:])
    lost = np.isnan(np.concatenate((out, out2), axis=1)).sum(axis=(1, 2))
    # a sample lost twice counts twice: the counts are at least the NaNs
    counts = chain.dropout_counts()
    assert counts.shape == (B,) and np.all(counts >= lost) and counts.sum() > 0
    one = SensorChain([Dropout(0.3)])
    one.reset(SEEDS)
    o = one.apply(t, Y)
    np.testing.assert_array_equal(one.dropout_counts(), np.isnan(o).sum(axis=(1, 2)))
    np.testing.assert_array_equal(one.stages[0].counts, one.dropout_counts())
    one.reset(SEEDS)
    assert one.stages[0].counts is None and one.dropout_counts().sum() == 0


def test_outlier_counts_per_stream():
    t, Y = times(False), np.zeros((8, T, 1))
    chain = SensorChain([Outliers(0.2, 1.0)])
    chain.reset(SEEDS[:8])
    out = chain.apply(t, Y)
    np.testing.assert_array_equal(chain.stages[0].counts, (out != 0).sum(axis=(1, 2)))


def test_empty_chain_and_empty_block():
    chain = SensorChain([])
    chain.reset([1, 2])
    Y = np.ones((2, 3, 1))
    out = chain.apply([0.0, 0.1, 0.2], Y)
    np.testing.assert_array_equal(out, Y)
    assert out is not Y
    full = SensorChain(CHAINS["recommended"]())
    full.reset([1, 2])
    assert full.apply(np.empty(0), np.empty((2, 0, 1))).shape == (2, 0, 1)


def test_apply_errors():
    chain = SensorChain([Delay(0.1), RandomWalkDrift(0.1), GaussianNoise(std=[0.1, 0.2])])
    chain.reset([1, 2, 3])
    with pytest.raises(DimensionError, match=r"Y must have shape \(B, T, p\) = \(3, 2, p\); "
                                             r"found shape \(2, 2, 2\)"):
        chain.apply([0.0, 0.1], np.zeros((2, 2, 2)))
    with pytest.raises(DimensionError, match=r"Y must have shape .* found shape \(2, 2\)"):
        chain.apply([0.0, 0.1], np.zeros((2, 2)))
    with pytest.raises(DimensionError, match=r"t must be 1-D \(T,\); found shape \(\)"):
        chain.apply(0.0, np.zeros((3, 1, 2)))
    with pytest.raises(DesignError, match=r"t must be finite; found \[0.0, nan\]"):
        chain.apply([0.0, np.nan], np.zeros((3, 2, 2)))
    with pytest.raises(DimensionError, match=r"GaussianNoise.std has 2 entries .* but y has 3"):
        chain.apply([0.0], np.zeros((3, 1, 3)))
    chain.reset([1, 2, 3])
    chain.apply([0.0, 0.1], np.zeros((3, 2, 2)))
    with pytest.raises(DesignError, match=r"Delay: time must not decrease; found t=0.05 after "
                                          r"t=0.1"):
        chain.apply([0.05], np.zeros((3, 1, 2)))
    drift = SensorChain([RandomWalkDrift(0.1)])
    drift.reset([1])
    with pytest.raises(DesignError, match=r"RandomWalkDrift: time must not decrease; found "
                                          r"t=0.1 after t=0.2"):
        drift.apply([0.0, 0.2, 0.1], np.zeros((1, 3, 1)))
    hold = SampleHold(0.1)
    hold.apply(np.array([0.0]), np.zeros((2, 1, 1)), None)
    with pytest.raises(DimensionError, match=r"SampleHold: the batch changed from 2 to 3 "
                                             r"streams without reset\(\)"):
        hold.apply(np.array([0.1]), np.zeros((3, 1, 1)), None)
    with pytest.raises(DimensionError, match=r"SampleHold: y changed length from 1 to 2"):
        hold.apply(np.array([0.1]), np.zeros((2, 1, 2)), None)
    hold.reset()
    hold.apply(np.array([0.1]), np.zeros((3, 1, 2)), None)


def test_reset_seed_errors():
    chain = SensorChain([GaussianNoise(std=0.1)])
    with pytest.raises(DesignError, match="a sequence of seeds needs at least one"):
        chain.reset([])
    with pytest.raises(DesignError, match=r"seed must be a non-negative integer or None; "
                                          r"found -1"):
        chain.reset([1, -1])
    with pytest.raises(DesignError, match=r"seed must be a non-negative integer or None; "
                                          r"found 1.5"):
        chain.reset([1.5])
    chain.reset(np.arange(3))                       # an array of seeds
    assert chain.seeds == (0, 1, 2)
    chain.reset([None, None])                       # fresh entropy per stream
    out = chain.apply([0.0], np.zeros((2, 1, 1)))
    assert out[0, 0, 0] != out[1, 0, 0]


def test_a_stage_without_apply_is_refused():
    class Custom(Stage):
        name = "custom"

    chain = SensorChain([Custom()])
    with pytest.raises(DesignError, match=r"Custom has no batched apply\(t, Y, draws\)"):
        chain.apply([0.0], np.ones((1, 1, 1)))


def test_long_blocks_beyond_the_draw_block():
    """Blocks longer than the kept draw block (1024 per stream) draw what they need: the
    same stream as default_rng(seed) call after call."""
    n = 3000
    chain = SensorChain([GaussianNoise(std=1.0)])
    chain.reset([5, 6])
    t = np.arange(n) * 1e-3
    out = np.concatenate([chain.apply(t[:10], np.zeros((2, 10, 1))),
                          chain.apply(t[10:2500], np.zeros((2, 2490, 1))),
                          chain.apply(t[2500:], np.zeros((2, 500, 1)))], axis=1)
    for b, sd in enumerate((5, 6)):
        np.testing.assert_array_equal(out[b, :, 0], np.random.default_rng(sd).standard_normal(n))


def test_held_and_restarted_streams_equal_the_stream_alone():
    """``hold`` (a stream does not advance) and ``reset_members`` (one stream reseeded or
    continued): the stream's measurements are those of the chain alone skipping the held
    blocks, bit for bit, its counters restarted; the other streams are not touched."""
    def chain():
        return SensorChain([GaussianNoise(std=1.0), Outliers(p=0.2, magnitude=5.0),
                            Dropout(0.1), Quantization(resolution=0.01)])

    c, alone, other = chain(), chain(), chain()
    c.reset([5, 6, 7])
    alone.reset(6)
    other.reset(7)
    rng = np.random.default_rng(0)
    held_blocks = 0
    for k in range(300):
        T = int(rng.integers(1, 40))  # across the buffer's refills
        t = k + 0.001 * np.arange(T)
        held = rng.random() < 0.3
        c.hold([1] if held else [])
        out = c._apply(t, np.zeros((3, T, 2)))
        c.hold([])
        np.testing.assert_array_equal(out[2], other._apply(t, np.zeros((1, T, 2)))[0])
        if held:
            held_blocks += 1
        else:
            np.testing.assert_array_equal(out[1], alone._apply(t, np.zeros((1, T, 2)))[0])
        if k == 100:
            c.reset_members([1], [99])
            alone.reset(99)
        if k == 200:
            c.reset_members([1], [None])   # continue: the stages restart, the numbers go on
            alone.restart()
    assert held_blocks > 50
    assert c.dropout_counts()[1] == alone.dropout_counts()[0]
    assert c.dropout_counts()[2] == other.dropout_counts()[0]
    assert c.seeds == (5, 99, 7)
    with pytest.raises(DesignError, match="one seed"):
        c.reset_members([0, 1], [1])
    timed = SensorChain([Delay(0.01)])
    timed.reset([1, 2])
    with pytest.raises(DesignError, match="keeps time"):
        timed.reset_members([0], [None])
    with pytest.raises(DesignError, match="keeps time"):
        timed.hold([0])
