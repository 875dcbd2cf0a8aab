"""The built wheel works on its own: models and envs are inside it, `hgo-mj demo` runs; with only
the runtime installed (no extra), the README's code blocks run but those marked as needing an
extra, which fail (issue 28, item 1)."""

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
    assert "hgo_mj/envs/__init__.py" in names and "hgo_mj/py.typed" in names
    assert not any(n.startswith("envs/") or n.startswith("models/") for n in names)
    # PEP 639: an SPDX license expression and the license file in the wheel's metadata
    (meta,) = [n for n in names if n.endswith(".dist-info/METADATA")]
    text = zipfile.ZipFile(wheel).read(meta).decode()
    assert "License-Expression: MIT" in text and "License-File: LICENSE" in text
    (lic,) = [n for n in names if n.endswith("/LICENSE")]
    assert "Copyright (c) 2026 the hgo_mj authors" in zipfile.ZipFile(wheel).read(lic).decode()

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
    _readme_blocks_run_after_the_runtime_install(py, wheel, tmp_path / "readme")
    _kernels_cache_outside_a_read_only_install(venv, py, tmp_path)


def _readme_blocks_run_after_the_runtime_install(py: Path, wheel: Path, work: Path) -> None:
    """The README's Python blocks in order, in the venv with only the runtime: each one that
    needs no extra runs; each one marked ``<!-- needs: EXTRA -->`` fails there (else its mark
    is wrong), and no extra is installed. Then, extra by extra, that extra is installed and the
    blocks that need it run."""
    from readme_blocks import blocks, extra_script, runtime_script

    work.mkdir()
    (work / "readme.py").write_text(runtime_script())
    out = _run([str(py), "readme.py"], cwd=work).stdout
    assert "k80" in out and "[0.3] {'dropouts': 0.0}" in out
    marked = [b for b in blocks() if b.needs and b.lang in ("python", "py")]
    assert marked, "no README block is marked as needing an extra"
    for b in marked:
        assert f"NEEDS {','.join(b.needs)} {b.line}: " in out, (b.line, out[-2000:])
    assert "RAN " not in out
    probe = ("import importlib.util as u; print([m for m in ('cvxpy', 'clarabel', 'sympy', 'ray', "
             "'imageio', 'moviepy') if u.find_spec(m)])")
    assert _run([str(py), "-c", probe], cwd=work).stdout.strip() == "[]"
    # then each extra a block needs, alone: the block runs
    for extra in sorted({e for b in marked for e in b.needs}):
        _run([str(py), "-m", "pip", "install", "--quiet", f"{wheel}[{extra}]"], cwd=work)
        (work / f"{extra}.py").write_text(extra_script(extra))
        out = _run([str(py), f"{extra}.py"], cwd=work).stdout
        ran = [ln for ln in out.splitlines() if ln.startswith("RAN ")]
        assert ran == [f"RAN {b.line}" for b in marked if b.needs == (extra,)], out


def _kernels_cache_outside_a_read_only_install(venv: Path, py: Path, tmp_path: Path) -> None:
    """Where the installed package cannot hold numba's cache (here every ``__pycache__`` of
    the installed hgo_mj is a plain file, so no cache folder can be made there, even as root),
    the kernels compile, run and are cached in the user's cache folder instead; a second
    process loads them from there."""
    import os
    import shutil

    (site,) = (venv / "lib").glob("python*/site-packages")
    for d in (site / "hgo_mj").rglob("__pycache__"):
        shutil.rmtree(d)
    for pkg in [p for p in (site / "hgo_mj").rglob("*") if p.is_dir()] + [site / "hgo_mj"]:
        (pkg / "__pycache__").write_text("not a folder")
    home = tmp_path / "home"
    home.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env.update(HOME=str(home), XDG_CACHE_HOME=str(home / ".cache"))
    code = ("import numpy as np; from hgo_mj.observers import HighGainObserver;"
            "ob = HighGainObserver(order=2, k=5.0);"
            "print(ob.update(np.zeros(1) + 1.0, np.zeros(1), 1e-3).tolist())")
    for _ in range(2):
        res = subprocess.run([str(py), "-c", code], cwd=tmp_path, env=env, capture_output=True,
                             text=True, timeout=600)
        assert res.returncode == 0, res.stderr[-3000:]
    cached = list((home / ".cache").rglob("*.nbi"))
    assert cached, "numba cached nothing in the user's cache folder"
