"""Input signals: the m-sequence ``prbs``, the ``telegraph`` signal it used to be, and one
signal per actuator (``Channels``; a list of ``[[input]]`` tables in a scenario file)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hgo_mj.cli import main
from hgo_mj.exceptions import DesignError, DimensionError
from hgo_mj.inputs import (
    PRBS,
    SIGNALS,
    Channels,
    Constant,
    Multisine,
    Telegraph,
    make_signal,
    signal_from_spec,
)
from hgo_mj.scenario import scenario_run
from hgo_mj.simulate import Trajectory


def _levels(sig, n, period):
    """The signal at the middle of each of its first ``n`` clock periods."""
    return sig.values((np.arange(n) + 0.5) * period)[:, 0]


@pytest.mark.parametrize("nbits", [3, 5, 7, 10])
def test_prbs_is_a_maximum_length_sequence(nbits):
    period, N = 0.02, 2**nbits - 1
    sig = PRBS(1.0, period, nbits=nbits)
    assert sig.length == N
    s = _levels(sig, 3 * N, period)
    assert set(s.tolist()) == {-1.0, 1.0}
    one = s[:N]
    # period N: it repeats after N clock periods, and after no proper divisor of N
    np.testing.assert_array_equal(s[N:2 * N], one)
    np.testing.assert_array_equal(s[2 * N:], one)
    for d in range(1, N):
        if N % d == 0:
            assert not np.array_equal(np.roll(one, d), one), d
    # balance: 2^(n-1) high and 2^(n-1) - 1 low levels in one period
    assert (one > 0).sum() == 2 ** (nbits - 1) and (one < 0).sum() == 2 ** (nbits - 1) - 1
    # two-valued circular autocorrelation: N at lag 0, -1 at every other lag
    acf = np.array([one @ np.roll(one, k) for k in range(N)])
    assert acf[0] == N and np.all(acf[1:] == -1)


def test_prbs_amplitude_offset_shift_and_registry():
    base = PRBS(0.5, 0.1, nbits=6)
    sig = PRBS(0.5, 0.1, nbits=6, offset=0.2, shift=5)
    a, b = _levels(base, 63, 0.1), _levels(sig, 63, 0.1)
    assert set(a.tolist()) == {-0.5, 0.5}
    np.testing.assert_allclose(b, np.roll(a, -5) + 0.2, atol=1e-15)
    assert make_signal("prbs", amplitude=0.5, period=0.1, nbits=6).params() == base.params()
    assert SIGNALS["prbs"] is PRBS and SIGNALS["telegraph"] is Telegraph
    with pytest.raises(DesignError, match=r"nbits must be in 2..20 .*; found 40"):
        PRBS(1.0, 0.1, nbits=40)
    with pytest.raises(DesignError, match=r"shift must be an integer >= 0; found -1"):
        PRBS(1.0, 0.1, shift=-1)
    with pytest.raises(DesignError, match=r"unknown parameter\(s\) \['seed'\]"):
        make_signal("prbs", amplitude=1.0, period=0.1, seed=3)


def test_telegraph_gives_the_numbers_prbs_gave():
    """``telegraph`` is the random telegraph signal ``prbs`` was before (the numbers below were
    printed by ``PRBS(0.5, 0.1, seed=2, offset=0.1)`` and ``PRBS(1.0, 0.01, seed=7,
    length=16)`` before the change) and the algorithm it was."""
    sig = make_signal("telegraph", amplitude=0.5, period=0.1, seed=2, offset=0.1)
    assert sig.values(np.arange(0, 2.0, 0.05))[:, 0].tolist() == [
        -0.4, -0.4, -0.4, -0.4, 0.6, 0.6, -0.4, -0.4, 0.6, 0.6, 0.6, 0.6, -0.4, -0.4, -0.4, -0.4,
        -0.4, -0.4, 0.6, 0.6, 0.6, 0.6, -0.4, -0.4, -0.4, -0.4, 0.6, 0.6, -0.4, -0.4, 0.6, 0.6,
        0.6, 0.6, 0.6, 0.6, -0.4, -0.4, -0.4, -0.4]
    short = Telegraph(1.0, 0.01, seed=7, length=16)
    assert short.values(np.arange(40) * 0.01)[:, 0].tolist() == [
        1.0, 1.0, 1.0, -1.0, -1.0, 1.0, -1.0, 1.0, 1.0, -1.0, -1.0, -1.0, -1.0, -1.0, 1.0, 1.0,
        1.0, 1.0, 1.0, -1.0, -1.0, 1.0, -1.0, 1.0, 1.0, -1.0, -1.0, -1.0, -1.0, -1.0, 1.0, 1.0,
        1.0, 1.0, 1.0, -1.0, -1.0, 1.0, -1.0, 1.0]
    rng = np.random.default_rng(11)
    levels = np.where(rng.random(4096) < 0.5, -1.0, 1.0)
    np.testing.assert_array_equal(_levels(Telegraph(1.0, 0.3, seed=11), 4096, 0.3), levels)


def test_channels_put_one_signal_per_actuator():
    ms = Multisine([0.3], [0.5])
    pr = PRBS(0.1, 0.05, nbits=5)
    both = Channels([ms, pr, Constant([1.0, 2.0])])
    t = np.linspace(0, 3, 301)
    U = both.values(t)
    assert U.shape == (301, 4)
    np.testing.assert_array_equal(U[:, 0], ms.values(t)[:, 0])
    np.testing.assert_array_equal(U[:, 1], pr.values(t)[:, 0])
    np.testing.assert_array_equal(U[:, 2:], np.tile([1.0, 2.0], (301, 1)))
    assert both.params()["signals"][1] == {"type": "prbs", **pr.params()}
    with pytest.raises(DesignError, match="non-empty list of Signals"):
        Channels([ms, "prbs"])
    spec = [{"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]}, {"type": "constant"}]
    sig = signal_from_spec(spec, 2)
    np.testing.assert_array_equal(sig.values(t), np.column_stack([ms.values(t)[:, 0],
                                                                  np.zeros(301)]))
    with pytest.raises(DesignError, match=r"input #2 must be a table"):
        signal_from_spec([spec[0], 3.0], 2)
    with pytest.raises(DesignError, match=r"empty list"):
        signal_from_spec([], 2)


TWO_LINK = """
name = "arm"
[plant]
name = "elastic_joint_2link"
[[observers]]
type = "high_gain_multi"
name = "hgo"
k = 40.0
[[input]]
type = "multisine"
amplitudes = [0.3, 0.1]
frequencies = [0.5, 1.3]
[[input]]
type = "prbs"
amplitude = 0.05
period = 0.05
nbits = 6
offset = 0.02
[run]
duration = 1.0
seed = 0
"""


def test_the_two_link_arm_gets_one_signal_per_joint_from_a_scenario_file(tmp_path):
    path = tmp_path / "arm.toml"
    path.write_text(TWO_LINK)
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out)]) == 0
    traj = Trajectory.load(out / "trajectory.npz")
    assert traj.input_names == ("torque1", "torque2")
    u1 = Multisine([0.3, 0.1], [0.5, 1.3]).values(traj.t)[:, 0]
    # the input is held over each plant step: compare at the step starts
    np.testing.assert_allclose(traj.u[:-1, 0], u1[:-1], atol=1e-12)
    assert np.ptp(traj.u[:, 0]) > 0.3 and set(np.round(traj.u[:, 1], 12)) == {-0.03, 0.07}
    assert len(set(np.round(traj.u[:, 1], 12))) == 2
    # the motion follows: both links move, differently
    assert np.ptp(traj.x[:, 0]) > 0 and np.ptp(traj.x[:, 1]) > 0
    metrics = json.loads((out / "metrics.json").read_text())["hgo"]
    assert metrics["states"][:2] == ["link1_angle", "link2_angle"]
    assert all(v is not None and v < 0.01 for v in metrics["rmse"][:2])


def test_one_input_flag_per_actuator_equals_the_scenario_file(tmp_path):
    path = tmp_path / "arm.toml"
    path.write_text(TWO_LINK)
    assert main(["run", str(path), "--out", str(tmp_path / "a")]) == 0
    assert main(["run", "--plant", "elastic_joint_2link", "--observer", "high_gain_multi:name=hgo,k=40",
                 "--input", "multisine:amplitudes=[0.3,0.1],frequencies=[0.5,1.3]",
                 "--input", "prbs:amplitude=0.05,period=0.05,nbits=6,offset=0.02",
                 "--duration", "1", "--out", str(tmp_path / "b")]) == 0
    a, b = (Trajectory.load(tmp_path / d / "trajectory.npz") for d in "ab")
    np.testing.assert_array_equal(a.u, b.u)
    np.testing.assert_array_equal(a.x, b.x)


def test_a_wrong_number_of_input_channels_is_refused(tmp_path, capsys):
    from hgo_mj.cli import tomllib

    sc = tomllib.loads(TWO_LINK)
    sc["input"] = sc["input"][:1]
    from hgo_mj.simulate import simulate

    with pytest.raises(DimensionError, match="2 channel"):
        simulate(**scenario_run(sc), seed=0)
