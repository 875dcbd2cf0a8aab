"""Issue 27 item 4: a run's (or study's) set of files is one, marked by a manifest written last
(each file's SHA-256 and row count); a folder that mixes two runs is refused by the readers."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import textwrap

import pytest

from hgo_mj import manifest
from hgo_mj.cli import main
from hgo_mj.exceptions import ManifestError
from hgo_mj.simulate import Trajectory

RUN = ["run", "--plant", "pendulum", "--observer", "high_gain:k=20", "--quiet"]


def test_a_run_writes_its_manifest_last_with_hashes_and_rows(tmp_path):
    out = tmp_path / "o"
    assert main([*RUN, "--duration", "2", "--out", str(out)]) == 0
    data = json.loads((out / manifest.MANIFEST).read_text())
    assert data["complete"] is True
    files = data["files"]
    assert set(files) == {"trajectory.npz", "trajectory.parquet", "metrics.parquet",
                          "metrics.json", "figure.png", "summary.txt"}
    traj = Trajectory.load(out / "trajectory.npz")
    assert files["trajectory.npz"]["rows"] == files["trajectory.parquet"]["rows"] == len(traj)
    assert files["metrics.json"]["rows"] is None and len(files["figure.png"]["sha256"]) == 64


def test_a_kill_between_two_files_leaves_a_folder_the_readers_refuse(tmp_path):
    """A 2 s run, then a 20 s run into the same folder SIGKILLed after its trajectory.npz and
    before its metrics.json: the folder mixes the two runs, and Trajectory.load says so."""
    out = tmp_path / "o"
    assert main([*RUN, "--duration", "2", "--out", str(out)]) == 0
    script = tmp_path / "killed.py"
    script.write_text(textwrap.dedent(f"""
        import os, signal
        import hgo_mj.cli as cli
        def killed(path, data):
            os.kill(os.getpid(), signal.SIGKILL)  # between trajectory.npz and metrics.json
        cli.write_json = killed
        cli.main({[*RUN, "--duration", "20", "--out", str(out)]!r})
    """))
    res = subprocess.run([sys.executable, str(script)], capture_output=True, timeout=300)
    assert res.returncode == -9, res.stderr
    assert json.loads((out / "metrics.json").read_text())  # the 2 s run's, beside the 20 s rows
    with pytest.raises(ManifestError, match=r"did not finish .*two runs"):
        Trajectory.load(out / "trajectory.npz")


def test_a_file_of_another_run_is_named(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    assert main([*RUN, "--duration", "2", "--out", str(a)]) == 0
    assert main([*RUN, "--duration", "1", "--out", str(b)]) == 0
    Trajectory.load(a / "trajectory.npz")  # as written
    shutil.copy(b / "metrics.json", a / "metrics.json")
    with pytest.raises(ManifestError, match=r"metrics.json differs from the manifest"):
        Trajectory.load(a / "trajectory.npz")
    (a / "metrics.json").unlink()
    with pytest.raises(ManifestError, match=r"metrics.json is listed .* but missing"):
        Trajectory.load(a / "trajectory.npz")


def test_a_study_folder_with_a_replaced_partition_is_refused(tmp_path):
    from hgo_mj.study import Study
    from hgo_mj.study.results import ResultsDir

    base = {"plant": {"name": "pendulum", "x0": [0.5, 0.0]},
            "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
            "run": {"duration": 0.3}}
    one = Study(base, {"observers.hgo.k": [10.0, 20.0]}).run(tmp_path / "one", quiet=True)
    two = Study(base, {"observers.hgo.k": [30.0, 40.0]}).run(tmp_path / "two", quiet=True)
    assert "results.parquet/" + sorted(one.out.glob("results.parquet/*"))[0].name in \
        manifest.listed(one.out)
    part = sorted((one.out / "results.parquet").glob("*.parquet"))[0]
    shutil.copy(sorted((two.out / "results.parquet").glob("*.parquet"))[0], part)
    with pytest.raises(ManifestError, match=r"results.parquet/part-.* differs"):
        ResultsDir(one.out).table()


def test_a_malformed_manifest_is_named(tmp_path):
    (tmp_path / "manifest.json").write_text("[1, 2]")
    with pytest.raises(ManifestError, match=r"manifest.json: not a manifest hgo_mj wrote"):
        manifest.check(tmp_path / "trajectory.npz")
