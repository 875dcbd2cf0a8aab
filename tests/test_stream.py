"""A long run streamed to disk in bounded memory (issue 14): simulate(keep=False) hands out
the rows in chunks and keeps none; hgo-mj run --stream writes them to Parquet as row groups and
takes the metrics chunk by chunk, with the same table and metrics as the run kept in memory."""

from __future__ import annotations

import json
import shutil
import tracemalloc

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from hgo_mj.cli import main
from hgo_mj.control import LinearFeedback
from hgo_mj.exceptions import DesignError, DivergenceError
from hgo_mj.inputs import Constant, Multisine
from hgo_mj.metrics import RunningMetrics, all_metrics
from hgo_mj.observers import HighGainObserver, make_observer
from hgo_mj.plants import make_plant
from hgo_mj.sensors import GaussianNoise, SensorChain
from hgo_mj.simulate import simulate
from hgo_mj.stream import ROW_GROUP_ROWS, ParquetChunks, stream_run


class Runaway(HighGainObserver):
    """Its estimate becomes infinite after ``after`` samples, without an exception."""

    def __init__(self, *args, after=0, **kw):
        self.after = after
        super().__init__(*args, **kw)

    def _init(self, p, x0, z0, u0):  # the samples seen are state
        return {**super()._init(p, x0, z0, u0), "seen": np.zeros(u0.shape[0], dtype=int)}

    def _step(self, p, s, Y, U, dt, X, Z, D):
        start = int(s.seen[0])
        s.seen += Y.shape[1]
        super()._step(p, s, Y, U, dt, X, Z, D)
        Z[:, max(self.after - start, 0):] = np.inf

    def _current(self, p, s):
        x, z, d = super()._current(p, s)
        return (x, np.full_like(z, np.inf), d) if s.seen[0] > self.after else (x, z, d)


def _run(keep, *, every=1, duration=3.0, chunk=0.37, controller=False, observers=None,
         isolate=False):
    plant = make_plant("pendulum", dt=0.01)
    obs = observers(plant) if observers else {
        "hgo": HighGainObserver(plant.system, k=20.0),
        "ekf": make_observer("ekf", plant.system, Q=1e-4, R=1e-6)}
    inputs = (LinearFeedback([[0.5, 0.1]], observer="hgo") if controller
              else Multisine([0.3], [0.5]))
    chunks = []
    traj = simulate(plant, SensorChain([GaussianNoise(std=1e-3)]), obs, inputs, duration,
                    x0=[0.4, 0.0], seed=3, store_every=every, keep=keep, isolate=isolate,
                    control_period=0.02 if controller else None,
                    on_chunk=(chunk, lambda row, c: chunks.append((row, c))))
    return traj, chunks


def _columns(traj):
    cols = {"t": traj.t, "x": traj.x, "y_clean": traj.y_clean, "y_meas": traj.y_meas,
            "u": traj.u}
    for name, rec in traj.observers.items():
        cols[f"{name}.x_hat"], cols[f"{name}.z_hat"] = rec.x_hat, rec.z_hat
        cols.update({f"{name}.{d}": v for d, v in rec.diagnostics.items()})
    return cols


def _joined(chunks):
    parts = [_columns(c) for _, c in chunks]
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


@pytest.mark.parametrize("every,controller", [(1, False), (3, False), (1, True), (7, True)])
def test_streamed_chunks_are_the_kept_run_bit_for_bit(every, controller):
    kept, _ = _run(True, every=every, controller=controller)
    streamed, chunks = _run(False, every=every, controller=controller)
    assert len(streamed) == 0 and len(chunks) > 3
    assert [row for row, _ in chunks] == list(np.cumsum([0] + [len(c) for _, c in chunks[:-1]]))
    joined, want = _joined(chunks), _columns(kept)
    assert joined.keys() == want.keys()
    for key in want:
        np.testing.assert_array_equal(joined[key], want[key], err_msg=key)
    assert streamed.metadata["store_every"] == every
    assert set(streamed.observers) == {"hgo", "ekf"}


def test_a_streamed_run_holds_a_bounded_buffer():
    """Ten times the duration, about the same peak memory (a kept run's grows tenfold)."""

    plant = make_plant("pendulum", dt=0.01)

    def peak(duration, keep):
        obs = {"hgo": HighGainObserver(plant.system, k=20.0)}
        tracemalloc.start()
        simulate(plant, SensorChain([GaussianNoise(std=1e-3)]), obs, Multisine([0.3], [0.5]),
                 duration, seed=3, keep=keep, on_chunk=(0.5, lambda row, c: None))
        _, top = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        return top

    short, long_ = peak(20.0, False), peak(200.0, False)
    kept_long = peak(200.0, True)
    assert long_ < 1.5 * short, (short, long_)
    assert kept_long > 4 * long_, (kept_long, long_)


def test_streaming_needs_its_chunks_and_a_bool():
    plant = make_plant("pendulum", dt=0.01)
    with pytest.raises(DesignError, match="keep=False streams the rows to on_chunk"):
        simulate(plant, None, {}, Constant([0.0]), 1.0, keep=False)
    with pytest.raises(DesignError, match="keep must be a bool; found 'no'"):
        simulate(plant, None, {}, Constant([0.0]), 1.0, keep="no",
                 on_chunk=(0.5, lambda row, c: None))


def test_an_estimate_leaving_the_finite_numbers_in_a_later_chunk_stops_alone():
    def observers(plant):
        return {"ok": HighGainObserver(plant.system, k=10.0),
                "run": Runaway(plant.system, k=5.0, after=120)}

    kept, _ = _run(True, observers=observers, isolate=True)
    streamed, chunks = _run(False, observers=observers, isolate=True)
    assert streamed.diverged["run"]["row"] == kept.diverged["run"]["row"] == 121
    assert streamed.diverged["run"]["t"] == pytest.approx(1.21)
    joined, want = _joined(chunks), _columns(kept)
    for key in want:
        np.testing.assert_array_equal(joined[key], want[key], err_msg=key)
    assert np.isnan(joined["run.x_hat"][121:]).all() and np.isfinite(joined["run.x_hat"][:121]).all()
    with pytest.raises(DivergenceError, match=r"observer 'run' estimate left the finite numbers "
                                              r"at t=1.21 \(row 121\)"):
        _run(False, observers=observers)


@pytest.mark.parametrize("sizes", [[1, 300], [37, 1, 1, 262], [150, 151], [5] * 60 + [1]])
def test_running_metrics_over_any_chunks_equal_the_metrics_of_the_whole(sizes):
    """Chunks of every size, a settling instant on a chunk's edge, NaN estimates."""
    kept, _ = _run(True)
    rec = kept.observers["hgo"]
    rec.x_hat[40:45, 1] = np.nan  # undefined samples count as outside the band
    want = all_metrics(kept, t_transient=0.5, band=0.02)
    edges = np.cumsum([0, *sizes])
    assert edges[-1] == len(kept)
    chunks = [_slice(kept, a, b) for a, b in zip(edges[:-1], edges[1:])]
    acc = RunningMetrics(kept, t_transient=0.5, band=0.02)
    for c in chunks:
        acc.add(c)
    for c in reversed(chunks):
        if acc.settle(c.t, {n: c.error(n) for n in c.observers}):
            break
    got = acc.result(kept)
    for name in want:
        for key, v in want[name].items():
            if key in ("rmse",):
                np.testing.assert_allclose(got[name][key], v, rtol=1e-12)
            else:
                assert got[name][key] == v, (name, key)
    assert want["hgo"]["undefined_samples"] == [0, 5]


def _slice(traj, a, b):
    from hgo_mj.stream import _rows

    return _rows(traj, np.arange(a, b))


def test_stream_run_writes_the_table_and_the_metrics_of_the_kept_run(tmp_path):
    plant = make_plant("pendulum", dt=0.001)
    kw = {"plant": plant, "sensor": SensorChain([GaussianNoise(std=1e-3)]),
          "observers": {"hgo": HighGainObserver(plant.system, k=20.0)},
          "inputs": Multisine([0.3], [0.5]), "duration": 30.0, "x0": [0.4, 0.0]}
    thin, metrics = stream_run(kw, tmp_path / "t.parquet", seed=2, chunk_seconds=2.0)
    kept = simulate(**kw, seed=2)
    df = pd.read_parquet(tmp_path / "t.parquet")
    pd.testing.assert_frame_equal(df, kept.to_pandas(), check_exact=True)
    want = all_metrics(kept)
    assert metrics["hgo"]["settling_time"] == want["hgo"]["settling_time"]
    np.testing.assert_allclose(metrics["hgo"]["rmse"], want["hgo"]["rmse"], rtol=1e-12)
    assert len(thin) == 15_001 and thin.metadata["figure_every"] == 2
    np.testing.assert_array_equal(thin.x, kept.x[::2])
    assert [p.name for p in tmp_path.iterdir()] == ["t.parquet"]
    # 15 chunks of 2,000 rows joined into row groups of at least ROW_GROUP_ROWS (the last
    # excepted: its metadata is what a writer keeps), the floats plainly encoded
    meta = pq.ParquetFile(tmp_path / "t.parquet").metadata
    assert [meta.row_group(i).num_rows for i in range(meta.num_row_groups)] == [18_000, 12_001]
    assert ROW_GROUP_ROWS == 16_384
    encodings = {e for i in range(meta.num_row_groups) for j in range(meta.num_columns)
                 for e in meta.row_group(i).column(j).encodings}
    assert not any("DICTIONARY" in e for e in encodings), encodings


def test_stream_run_releases_the_freed_memory_after_the_join(tmp_path, monkeypatch):
    """The memory the join and the settling pass freed is handed back (glibc's
    ``malloc_trim``) once, after the table is joined and read, before the figure is drawn."""
    import hgo_mj.stream as stream

    seen = []
    monkeypatch.setattr(stream, "_release_freed_memory", lambda: seen.append(
        sorted(p.name for p in tmp_path.iterdir())) or True)
    plant = make_plant("pendulum", dt=0.01)
    kw = {"plant": plant, "sensor": None, "inputs": Constant([0.0]), "duration": 3.0,
          "observers": {"hgo": HighGainObserver(plant.system, k=20.0)}}
    stream_run(kw, tmp_path / "t.parquet", seed=0, chunk_seconds=1.0)
    assert seen == [["t.parquet"]]  # once, the parts joined


def test_a_stopped_stream_leaves_the_earlier_file_and_its_chunks(tmp_path):
    path = tmp_path / "t.parquet"
    path.write_bytes(b"the earlier result")
    plant = make_plant("pendulum", dt=0.01)
    kw = {"plant": plant, "sensor": None, "inputs": Constant([0.0]), "duration": 5.0,
          "observers": {"hgo": HighGainObserver(plant.system, k=20.0)}}

    def interrupt(row, chunk):
        if row > 0:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        stream_run(kw, path, seed=0, chunk_seconds=1.0, also=interrupt)
    assert path.read_bytes() == b"the earlier result"
    # Ctrl-C keeps the chunks written (closed files), and the next run reports them
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.parquet", "t.parquet.parts"]
    assert len(pd.read_parquet(tmp_path / "t.parquet.parts")) == 200
    with pytest.raises(DesignError, match=r"t.parquet.parts holds 2 chunk\(s\), 200 rows"):
        stream_run(kw, path, seed=0, chunk_seconds=1.0)
    shutil.rmtree(tmp_path / "t.parquet.parts")
    with pytest.raises(DesignError, match="t_transient = 9 leaves no samples"):
        stream_run(kw, path, seed=0, chunk_seconds=1.0, t_transient=9.0)
    table = ParquetChunks(tmp_path / "u.parquet")
    with pytest.raises(DesignError, match="no rows were written"):
        table.close(None)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.parquet"]


def test_the_command_line_streams_the_same_results(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    args = ["run", "--plant", "pendulum", "--dt", "0.001", "--observer", "high_gain:k=20",
            "--sensor", "gaussian:std=1e-3", "--duration", "12", "--quiet"]
    assert main([*args, "--out", "kept"]) == 0
    assert main([*args, "--out", "streamed", "--stream"]) == 0
    out = capsys.readouterr().out
    assert "wrote streamed/trajectory.parquet, metrics.parquet, metrics.json, figure.png" in out
    pd.testing.assert_frame_equal(pd.read_parquet("streamed/trajectory.parquet"),
                                  pd.read_parquet("kept/trajectory.parquet"), check_exact=True)
    a = json.loads((tmp_path / "kept/metrics.json").read_text())
    b = json.loads((tmp_path / "streamed/metrics.json").read_text())
    for key in ("states", "peak", "settling_time", "final", "undefined_samples"):
        assert a["high_gain_0"][key] == b["high_gain_0"][key], key
    np.testing.assert_allclose(a["high_gain_0"]["rmse"], b["high_gain_0"]["rmse"], rtol=1e-12)
    assert sorted(p.name for p in (tmp_path / "streamed").iterdir()) == [
        "figure.png", "manifest.json", "metrics.json", "metrics.parquet", "summary.txt",
        "trajectory.parquet"]


@pytest.mark.parametrize("extra,message", [
    (["--format", "npz"], "--stream (run.stream) writes the trajectory as Parquet only; found "
                          "--format npz"),
    (["--format", "parquet", "--format", "csv"], "found --format parquet csv"),
])
def test_streaming_refuses_other_formats_in_one_line(tmp_path, monkeypatch, capsys, extra,
                                                     message):
    monkeypatch.chdir(tmp_path)
    assert main(["run", "--plant", "pendulum", "--duration", "1", "--stream", "--quiet",
                 *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]
    assert not (tmp_path / "runs").exists()


def test_run_stream_in_a_scenario_is_a_bool(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "s.toml").write_text('[plant]\nname = "pendulum"\n[run]\nduration = 1.0\n'
                                     'stream = "yes"\n')
    assert main(["run", "s.toml", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "run.stream" in err[0] and "'yes'" in err[0]


# ------------------------------------------- issue 27 item 3: a killed stream keeps its rows
def test_a_killed_stream_leaves_readable_chunks_the_next_run_reports(tmp_path):
    """SIGKILL of `hgo-mj run --stream` part-way: its chunks are closed Parquet files in
    trajectory.parquet.parts (rows from t = 0 on, whole chunks), the next run into the folder
    refuses to overwrite them, naming them; stale temporaries of killed saves are removed and
    said so."""
    import signal
    import subprocess
    import sys
    import time

    from hgo_mj.stream import parts_folder

    out = tmp_path / "o"
    parts = parts_folder(out / "trajectory.parquet")
    argv = ["run", "--plant", "pendulum", "--dt", "0.001", "--observer", "high_gain:k=20",
            "--quiet", "--stream", "--out", str(out)]
    proc = subprocess.Popen([sys.executable, "-m", "hgo_mj.cli", *argv, "--duration", "3000"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while len(list(parts.glob("part-*.parquet"))) < 3:
            assert proc.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert not (out / "trajectory.parquet").exists()
    df = pd.read_parquet(parts)
    assert len(df) >= 3 and df["t"].iloc[0] == 0.0 and (np.diff(df["t"]) > 0).all()
    stale = out / ".metrics.json.abc123.tmp"  # what a kill inside a save leaves
    stale.write_text("{")
    res = subprocess.run([sys.executable, "-m", "hgo_mj.cli", *argv, "--duration", "1"],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 2
    assert "trajectory.parquet.parts holds" in res.stderr and f"{len(df)} rows" in res.stderr
    parts.rename(tmp_path / "kept.parts")
    res = subprocess.run([sys.executable, "-m", "hgo_mj.cli", *argv, "--duration", "1"],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert "removed 1 temporary file(s)" in res.stderr and not stale.exists()
    assert len(pd.read_parquet(out / "trajectory.parquet")) == 1001 and not parts.exists()
