"""The README's Python example and scenario file run as written."""

from __future__ import annotations

import re
from pathlib import Path

from hgo_mj.cli import main
from hgo_mj.simulate import Trajectory

README = (Path(__file__).resolve().parents[1] / "README.md").read_text()


def test_python_example_runs(tmp_path, monkeypatch, capsys):
    (code,) = re.findall(r"```python\n(.*?)```", README, re.S)
    assert len(code.strip().splitlines()) <= 22
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "README.md", "exec"), {})
    assert "k=80" in capsys.readouterr().out
    assert len(Trajectory.load(tmp_path / "runs" / "pendulum.npz")) == 10001


def test_scenario_file_runs(tmp_path, monkeypatch):
    (toml,) = re.findall(r"```toml\n(.*?)```", README, re.S)
    (tmp_path / "s.toml").write_text(toml)
    monkeypatch.chdir(tmp_path)
    assert main(["run", "s.toml"]) == 0
    assert (tmp_path / "runs" / "pendulum" / "metrics.json").is_file()
