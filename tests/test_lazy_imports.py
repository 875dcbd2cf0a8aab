"""Heavy optional packages are imported only where their feature is used (issue: state as data,
part 4): a simulation loads no table, figure, recording, optimisation or symbolic package, and
no OpenGL (MuJoCo's renderer and GLFW load on first use of ``mujoco.Renderer``)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("rerun", "pandas", "pyarrow", "matplotlib", "cvxpy", "sympy", "glfw")


def _loaded(code: str, cwd: Path) -> dict[str, list[str]]:
    """Run ``code`` in a fresh interpreter; the heavy top-level packages it loaded, and the
    ``mujoco.rendering`` modules."""
    probe = (f"{code}\nimport json, sys\n"
             "tops = {m.split('.')[0] for m in sys.modules}\n"
             f"print(json.dumps({{'heavy': sorted(tops & set({list(HEAVY)!r})), "
             "'rendering': sorted(m for m in sys.modules if m.startswith('mujoco.rendering'))}))")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run([sys.executable, "-c", probe], cwd=cwd, env=env, capture_output=True,
                         text=True, timeout=300, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def test_import_simulate_loads_no_heavy_package(tmp_path):
    got = _loaded("import hgo_mj.simulate", tmp_path)
    assert got == {"heavy": [], "rendering": []}


def test_npz_run_loads_only_the_figure_package(tmp_path):
    # `hgo-mj run` always writes figure.png (there is no flag to turn it off), so matplotlib
    # is what the run truly needs, and pandas (with its pyarrow strings) sizes the printed
    # table's columns; no recording, optimisation or symbolic package
    code = ("from hgo_mj.cli import main\n"
            "assert main(['run', '--plant', 'pendulum', '--duration', '1', '--out', 'x', "
            "'--format', 'npz']) == 0")
    got = _loaded(code, tmp_path)
    assert set(got["heavy"]) <= {"matplotlib", "pandas", "pyarrow"} and "matplotlib" in got[
        "heavy"]
    assert (tmp_path / "x" / "trajectory.npz").exists() and (tmp_path / "x" / "figure.png").exists()


def test_mujoco_renderer_still_loads_on_first_use(tmp_path):
    got = _loaded("import hgo_mj.simulate, mujoco\nassert mujoco.Renderer.__name__ == 'Renderer'"
                  "\nassert mujoco.GLContext.__name__ == 'GLContext'", tmp_path)
    assert "mujoco.rendering.classic.renderer" in got["rendering"]
