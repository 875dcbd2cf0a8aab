"""Tidy data: a trajectory as a pandas / Arrow table (wide and long), the metrics as a
DataFrame, and ``hgo-mj run --format parquet|csv|npz`` read back with pandas."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from hgo_mj.cli import check_formats, main
from hgo_mj.exceptions import DesignError
from hgo_mj.inputs import Multisine
from hgo_mj.metrics import all_metrics, metrics_frame
from hgo_mj.observers import make_observer
from hgo_mj.plants import make_plant
from hgo_mj.sensors import GaussianNoise, SensorChain
from hgo_mj.simulate import Trajectory, simulate
from hgo_mj.tidy import read_units, write_table


@pytest.fixture(scope="module")
def traj():
    """The elastic joint with a model-free HGO (the link states and acceleration) and an
    adaptive-gain one."""
    plant = make_plant("elastic_joint", 0.001)
    obs = {"hgo": make_observer("high_gain_multi", plant.system, k=30.0, orders=[3]),
           "ada": make_observer("adaptive_gain", plant.system, k0=20.0, lam=0.01,
                                  lam_hat=0.02, gamma=100.0)}
    return simulate(plant, SensorChain([GaussianNoise(1e-4)], seed=3), obs,
                    Multisine([0.5], [0.7]), duration=0.3)


def test_the_wide_form_holds_every_column_under_its_name(traj):
    df = traj.to_pandas()
    T = len(traj)
    assert len(df) == T and df.columns[0] == "t"
    np.testing.assert_array_equal(df["t"], traj.t)
    for i, s in enumerate(traj.state_names):
        np.testing.assert_array_equal(df[f"true/{s}"], traj.x[:, i])
    for name, rec in traj.observers.items():
        for j, s in enumerate(rec.state_names):
            np.testing.assert_array_equal(df[f"{name}/{s}"], rec.x_hat[:, j])
        for d, v in rec.diagnostics.items():
            np.testing.assert_array_equal(df[f"{name}/diagnostics/{d}"], v)
    np.testing.assert_array_equal(df["measured/link_angle"], traj.y_meas[:, 0])
    np.testing.assert_array_equal(df["clean/link_angle"], traj.y_clean[:, 0])
    np.testing.assert_array_equal(df["input/torque"], traj.u[:, 0])
    units = df.attrs["units"]
    assert units["t"] == "s"
    assert units["true/motor_velocity"] == "rad/s"
    assert units["hgo/link_acceleration"] == "rad/s^2"  # an output's derivative
    assert units["input/torque"] == "N m"
    assert units["hgo/diagnostics/dropouts"] == "" and units["ada/diagnostics/k"] is None


def test_the_long_form_is_the_wide_form_melted(traj):
    wide, long = traj.to_pandas(), traj.to_pandas("long")
    assert list(long.columns) == ["t", "source", "name", "value", "unit"]
    assert len(long) == len(traj) * (wide.shape[1] - 1)
    back = long.assign(col=long["source"] + "/" + long["name"]).pivot(
        index="t", columns="col", values="value")
    for col in wide.columns[1:]:
        np.testing.assert_array_equal(back[col].to_numpy(), wide[col].to_numpy())
    row = long[(long.source == "true") & (long.name == "link_velocity")].iloc[0]
    assert row["unit"] == "rad/s"
    assert set(long.source) == {"true", "hgo", "hgo/diagnostics", "ada", "ada/diagnostics",
                                "measured", "clean", "input"}


def test_arrow_fields_carry_their_units_and_the_schema_the_names(traj):
    table = traj.to_arrow()
    assert table.schema.field("true/link_angle").metadata == {b"unit": b"rad"}
    assert table.schema.field("ada/diagnostics/k").metadata is None  # unit unknown
    meta = json.loads(table.schema.metadata[b"hgo_mj"])  # strict JSON (NaN update times: null)
    assert meta["state_names"] == list(traj.state_names)
    assert meta["observers"]["hgo"]["state_names"] == list(traj.observers["hgo"].state_names)
    assert meta["metadata"]["plant"] == "ElasticJoint"
    assert traj.to_arrow("long").num_rows == len(traj) * (table.num_columns - 1)


def test_parquet_and_csv_files_read_back_with_pandas(traj, tmp_path):
    write_table(traj, tmp_path / "t.parquet")
    df = pd.read_parquet(tmp_path / "t.parquet")
    pd.testing.assert_frame_equal(df, traj.to_pandas(), check_like=False)
    assert read_units(tmp_path / "t.parquet")["true/motor_angle"] == "rad"
    write_table(traj, tmp_path / "t.csv", "csv")
    csv = pd.read_csv(tmp_path / "t.csv")
    assert list(csv.columns) == list(df.columns)
    np.testing.assert_allclose(csv.to_numpy(), df.to_numpy(), rtol=1e-15)
    write_table(traj, tmp_path / "long.parquet", form="long")
    assert pd.read_parquet(tmp_path / "long.parquet").shape == traj.to_pandas("long").shape


def test_bad_forms_and_names_are_refused(traj, tmp_path):
    with pytest.raises(DesignError, match=r"form must be one of \['wide', 'long'\]; found 'tall'"):
        traj.to_pandas("tall")
    with pytest.raises(DesignError, match=r"table format must be one of .*; found 'xlsx'"):
        write_table(traj, tmp_path / "t.xlsx", "xlsx")
    clash = Trajectory(traj.t, traj.x, traj.y_clean, traj.y_meas, traj.u,
                       {"true": traj.observers["hgo"]}, traj.state_names, traj.output_names,
                       traj.input_names, traj.metadata)
    with pytest.raises(DesignError, match="observer name 'true' cannot name table columns"):
        clash.to_pandas()
    with pytest.raises(DesignError, match=r"--format must be one of \['npz', 'parquet', 'csv'\]"):
        check_formats(["npz", "hdf5"])
    with pytest.raises(DesignError, match="formats must be a non-empty list"):
        check_formats("parquet")
    with pytest.raises(DesignError, match="is no hgo_mj table"):
        pd.DataFrame({"a": [1.0]}).to_parquet(tmp_path / "plain.parquet")
        read_units(tmp_path / "plain.parquet")


def test_metrics_as_a_data_frame(traj):
    metrics = all_metrics(traj, t_transient=0.1)
    df = metrics_frame(metrics, {"link_angle": "rad", "motor_angle": "rad"})
    assert len(df) == 2 * len(traj.state_names)
    row = df[(df.observer == "ada") & (df.state == "link_velocity")].iloc[0]
    assert row["rmse"] == metrics["ada"]["rmse"][2] and bool(row["estimated"])
    missing = df[(df.observer == "hgo") & (df.state == "motor_angle")].iloc[0]
    assert not missing["estimated"] and np.isnan(missing["rmse"])  # not estimated
    assert missing["unit"] == "rad" and pd.isna(row["unit"])  # not in the units given
    assert (df["t_transient"] == 0.1).all()


RUN = ["run", "--plant", "pendulum", "--observer", "high_gain:name=hgo,k=30",
       "--sensor", "gaussian:std=1e-3", "--duration", "0.5"]


def test_cli_writes_parquet_beside_the_npz_by_default(tmp_path, capsys):
    assert main([*RUN, "--out", str(tmp_path)]) == 0
    assert "trajectory.npz, trajectory.parquet, metrics.parquet" in capsys.readouterr().out
    df = pd.read_parquet(tmp_path / "trajectory.parquet")
    traj = Trajectory.load(tmp_path / "trajectory.npz")
    np.testing.assert_array_equal(df["hgo/angular_velocity"], traj.observers["hgo"].x_hat[:, 1])
    assert pq.read_schema(tmp_path / "trajectory.parquet").field("true/angle").metadata == {
        b"unit": b"rad"}
    m = pd.read_parquet(tmp_path / "metrics.parquet")
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert m.loc[m.state == "angle", "rmse"].item() == metrics["hgo"]["rmse"][0]
    assert list(m.unit) == ["rad", "rad/s"]


def test_cli_format_chooses_the_files(tmp_path):
    assert main([*RUN, "--out", str(tmp_path / "c"), "--format", "csv"]) == 0
    names = {p.name for p in (tmp_path / "c").iterdir()}
    assert {"trajectory.csv", "metrics.csv", "metrics.json", "figure.png"} <= names
    assert not {"trajectory.npz", "trajectory.parquet"} & names
    df = pd.read_csv(tmp_path / "c" / "trajectory.csv")
    assert list(df.columns[:3]) == ["t", "true/angle", "true/angular_velocity"]
    assert main([*RUN, "--out", str(tmp_path / "n"), "--format", "npz"]) == 0
    names = {p.name for p in (tmp_path / "n").iterdir()}
    assert "trajectory.npz" in names and not any(n.endswith((".parquet", ".csv")) for n in names)
    with pytest.raises(SystemExit) as exc:  # argparse: one line, exit status 2
        main([*RUN, "--out", str(tmp_path / "x"), "--format", "xlsx"])
    assert exc.value.code == 2


def test_metrics_parquet_without_pandas_reads_back_as_pandas_writes_it(tmp_path):
    """metrics.parquet is written from buffers (no pandas import): read with pandas it is the
    frame pandas' own to_parquet writes, column types included (an integer column stays
    int64, None is NaN in a number column and null in the unit column)."""
    from hgo_mj.metrics import metrics_frame, metrics_rows
    from hgo_mj.tidy import write_rows_parquet

    one = {"states": ["angle", "v"], "estimated": [True, False], "rmse": [0.1, None],
           "peak": [0.5, None], "settling_time": [1.0, None], "final": [0.01, None],
           "undefined_samples": [0, None], "update_time": 1e-6, "t_transient": 2.0,
           "band": 0.05}
    two = {**one, "estimated": [True, True], "rmse": [0.1, 0.2], "peak": [0.5, 1.0],
           "settling_time": [1.0, 2.0], "final": [0.01, 3.0], "undefined_samples": [0, 2]}
    for metrics in ({"hgo": one, "b": two}, {"b": two}):
        metrics_frame(metrics, {"angle": "rad"}).to_parquet(tmp_path / "a.parquet", index=False)
        write_rows_parquet(*metrics_rows(metrics, {"angle": "rad"}), tmp_path / "b.parquet")
        pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "a.parquet"),
                                      pd.read_parquet(tmp_path / "b.parquet"))
