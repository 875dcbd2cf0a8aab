"""``hgo_mj.record.read``: a recording's series as a pandas DataFrame, read with rerun's own
reader, equal to the trajectory it was made from."""

from __future__ import annotations

import numpy as np
import pytest

from hgo_mj.exceptions import DesignError
from hgo_mj.inputs import make_signal
from hgo_mj.observers import make_observer
from hgo_mj.plants import make_plant
from hgo_mj.record import Recorder, read, record_trajectory
from hgo_mj.sensors import SensorChain
from hgo_mj.simulate import simulate


@pytest.fixture(scope="module")
def run_and_file(tmp_path_factory):
    plant = make_plant("pendulum", 0.001)
    obs = {"slow": make_observer("high_gain", plant.system, k=10.0),
           "fast": make_observer("adaptive_gain", plant.system, k0=20.0, gamma=50.0,
                                 lam=0.01, lam_hat=0.02)}
    sensor = SensorChain.from_spec([{"stage": "gaussian", "std": 1e-3},
                                    {"stage": "dropout", "p": 0.05}], seed=3)
    traj = simulate(plant, sensor, obs, make_signal("multisine", amplitudes=[0.3],
                                                    frequencies=[0.5]), 1.0, x0=[0.4, 0.0],
                    seed=3)
    path = record_trajectory(traj, tmp_path_factory.mktemp("rrd") / "r.rrd")
    return traj, path


def test_read_gives_every_series_of_the_trajectory(run_and_file):
    import pandas as pd

    traj, path = run_and_file
    df = read(path)
    assert isinstance(df, pd.DataFrame) and df.index.name == "step"
    np.testing.assert_array_equal(df.index, np.arange(len(traj)))
    np.testing.assert_allclose(df["sim_time"], traj.t, atol=1e-9)
    for i, s in enumerate(traj.state_names):  # one column per series: truth, each observer
        np.testing.assert_array_equal(df[f"/state/{s}[{s} true]"], traj.x[:, i])
        for name in traj.observers:
            np.testing.assert_array_equal(df[f"/state/{s}[{s} {name}]"],
                                          traj.estimate(name)[:, i])
            np.testing.assert_array_equal(df[f"/error/{s}[{s} error {name}]"],
                                          traj.error(name)[:, i])
    np.testing.assert_array_equal(df["/sensor/angle[angle clean]"], traj.y_clean[:, 0])
    np.testing.assert_array_equal(df["/sensor/angle[angle measured]"], traj.y_meas[:, 0])
    assert df["/sensor/angle[angle measured]"].isna().sum() == np.isnan(traj.y_meas).sum() > 0
    np.testing.assert_array_equal(df["/input/torque"], traj.u[:, 0])
    # the units, from the series' names: every series of the states, errors and outputs
    units = df.attrs["units"]
    assert units["/state/angular_velocity[angular_velocity fast]"] == "rad/s"
    assert units["/error/angle[angle error slow]"] == "rad" and units["/input/torque"] == "N m"
    assert units["/sensor/angle[angle clean]"] == units["/sensor/angle[angle measured]"] == "rad"
    assert {c for c in df.columns if c.startswith(("/state", "/error", "/sensor"))} <= set(units)
    assert units["/observer/slow/diagnostics/dropouts"] == ""  # a dropout stage: recorded
    assert "/observer/fast/gain" not in units  # the gain's unit is not declared
    # the adaptive gain, a series of its own
    gain = df["/observer/fast/gain"].to_numpy()
    np.testing.assert_array_equal(gain[np.isfinite(gain)][-1],
                                  traj.observers["fast"].diagnostics["k"][-1])
    # static components: the documents
    assert df.attrs["static"]["/scenario"]["TextDocument:text"][0].strip()


def test_read_of_episodes_and_of_chunked_recordings(tmp_path, run_and_file):
    traj, path = run_and_file
    with Recorder.for_trajectory(tmp_path / "blocks.rrd", traj) as rec:
        rec.record_trajectory(traj, chunk_seconds=0.3)
    whole, blocks = read(path), read(tmp_path / "blocks.rrd")
    assert list(blocks.columns) == list(whole.columns)
    np.testing.assert_array_equal(blocks.to_numpy(), whole.to_numpy())

    plant = make_plant("pendulum", 0.001)
    ep = tmp_path / "ep.rrd"
    with Recorder.for_plant(ep, plant, ["hgo"]) as rec:
        x = np.ones((4, 2))
        for k in range(2):
            rec.record_episode(k, np.arange(4) * 1e-3, (k + 1) * x, x[:, :1], np.zeros((4, 1)),
                               estimates={"hgo": 2 * x})
    df = read(ep)
    assert len(df) == 8 and df["episode"].tolist() == [0] * 4 + [1] * 4
    assert df["/state/angle[angle true]"].tolist() == [1.0] * 4 + [2.0] * 4
    # one observer: its error is named as with several (one entity per state, whatever the
    # number of observers)
    assert df["/error/angle[angle error hgo]"].tolist() == [-1.0] * 4 + [0.0] * 4


def test_read_refuses_what_is_no_recording(tmp_path):
    with pytest.raises(DesignError, match="does not exist"):
        read(tmp_path / "missing.rrd")
    (tmp_path / "bad.rrd").write_bytes(b"not a recording")
    with pytest.raises(DesignError, match="cannot read .* as a rerun recording"):
        read(tmp_path / "bad.rrd")
