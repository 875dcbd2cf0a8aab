"""Every file hgo_mj writes is written atomically: a failure (or a kill) during the write keeps
the old file, and no temporary file is left behind."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hgo_mj._io import atomic_path, save_figure, write_text
from hgo_mj._json import write_json
from hgo_mj.plants import make_plant
from hgo_mj.simulate import Trajectory, simulate


def test_a_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path):
    f = tmp_path / "a.txt"
    write_text(f, "old\n")
    with pytest.raises(RuntimeError), atomic_path(f) as tmp:
        tmp.write_text("half of the ne")
        raise RuntimeError("killed")
    assert f.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]


def test_a_trajectory_save_that_fails_keeps_the_earlier_result(tmp_path, monkeypatch):
    plant = make_plant("pendulum")
    traj = simulate(plant, None, None, lambda t: [0.0], 0.05)
    path = traj.save(tmp_path / "trajectory.npz")
    before = path.read_bytes()

    def broken(fh, **cols):
        fh.write(b"PK\x03\x04 torn")
        raise OSError("No space left on device")

    monkeypatch.setattr(np, "savez_compressed", broken)
    with pytest.raises(OSError, match="No space left"):
        traj.save(path)
    assert path.read_bytes() == before
    assert len(Trajectory.load(path)) == len(traj)
    assert [p.name for p in tmp_path.iterdir()] == ["trajectory.npz"]


def test_json_and_figures_are_written_whole(tmp_path):
    from matplotlib.figure import Figure

    data = write_json(tmp_path / "m.json", {"x": float("inf"), "y": [1.0, 2.0]})
    assert json.loads((tmp_path / "m.json").read_text()) == data == {"x": None, "y": [1.0, 2.0]}
    fig = Figure()
    fig.subplots().plot([0, 1], [1, 0])
    save_figure(fig, tmp_path / "f.png")
    assert (tmp_path / "f.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.png", "m.json"]
