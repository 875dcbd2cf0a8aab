"""The built wheel works on its own: models and envs are inside it, `hgo-mj demo` runs."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(cmd, cwd, timeout=900):
    res = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout)
    assert res.returncode == 0, f"{cmd} failed:\n{res.stdout[-3000:]}\n{res.stderr[-3000:]}"
    return res


@pytest.mark.slow
def test_wheel_installs_and_runs_demo_outside_the_source_tree(tmp_path):
    dist = tmp_path / "dist"
    _run([sys.executable, "-m", "build", "--wheel", "--outdir", str(dist), str(ROOT)], cwd=tmp_path)
    (wheel,) = dist.glob("hgo_mj-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert "hgo_mj/models/elastic_joint.xml" in names
    assert "hgo_mj/envs/__init__.py" in names
    assert not any(n.startswith("envs/") or n.startswith("models/") for n in names)

    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", str(venv)], cwd=tmp_path)
    py = venv / "bin" / "python"
    _run([str(py), "-m", "pip", "install", "--quiet", str(wheel)], cwd=tmp_path)
    work = tmp_path / "elsewhere"
    work.mkdir()
    res = _run([str(venv / "bin" / "hgo-mj"), "demo", "--out", "demo_out"], cwd=work)
    assert "hgo_k25" in res.stdout
    for f in ("trajectory.npz", "metrics.json", "figure.png", "summary.txt"):
        assert (work / "demo_out" / f).stat().st_size > 0
    probe = ("import hgo_mj, hgo_mj.envs, importlib.util;"
             "from hgo_mj.plants import model_path;"
             "p = model_path('pendulum.xml');"
             "assert 'site-packages' in str(p), p;"
             "assert importlib.util.find_spec('envs') is None;"
             "print('ok')")
    assert _run([str(py), "-c", probe], cwd=work).stdout.strip() == "ok"
