"""Heavy optional packages are imported only where their feature is used (issue: state as data,
part 4): a simulation loads no table, figure, recording, optimisation or symbolic package, and
no OpenGL (MuJoCo's renderer and GLFW load on first use of ``mujoco.Renderer``). The observer
and system registries import a family on first use (issue 28, item 1): ``import
hgo_mj.simulate`` loads none, nor numba; a run loads the families it uses."""

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
             "from hgo_mj.observers.base import FAMILIES as OF\nfrom hgo_mj.systems import FAMILIES as SF\n"
             "tops = {m.split('.')[0] for m in sys.modules}\n"
             f"print(json.dumps({{'heavy': sorted(tops & set({list(HEAVY)!r})), "
             "'numba': 'numba' in sys.modules, "
             "'families': sorted(set(sys.modules) & {h.split(':')[0] for h in [*OF.values(), "
             "*SF.values()]}), "
             "'rendering': sorted(m for m in sys.modules if m.startswith('mujoco.rendering'))}))")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run([sys.executable, "-c", probe], cwd=cwd, env=env, capture_output=True,
                         text=True, timeout=300, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def test_import_simulate_loads_no_heavy_package(tmp_path):
    got = _loaded("import hgo_mj.simulate", tmp_path)
    assert got == {"heavy": [], "rendering": [], "numba": False, "families": []}


def test_a_run_loads_only_the_families_it_uses(tmp_path):
    code = ("import numpy as np\n"
            "from hgo_mj.plants import make_plant\n"
            "from hgo_mj.observers import make_observer\n"
            "from hgo_mj.simulate import simulate\n"
            "plant = make_plant('pendulum')\n"
            "simulate(plant, None, {'hgo': make_observer('high_gain', plant.system, k=10.0)}, "
            "lambda t: [0.0], duration=0.05, x0=np.array([0.1, 0.0]))")
    got = _loaded(code, tmp_path)
    assert got["families"] == ["hgo_mj.observers.high_gain", "hgo_mj.systems.pendulum"]
    assert got["heavy"] == [] and got["numba"]


def test_npz_run_loads_only_the_figure_package(tmp_path):
    # `hgo-mj run` always writes figure.png (there is no flag to turn it off), so matplotlib
    # is what the run truly needs; its metrics table (summary.txt, hgo_mj.metrics.text_table)
    # is plain Python, not pandas (69 MB of the peak RSS: issue 24); no table, recording,
    # optimisation or symbolic package
    code = ("from hgo_mj.cli import main\n"
            "assert main(['run', '--plant', 'pendulum', '--duration', '1', '--out', 'x', "
            "'--format', 'npz']) == 0")
    got = _loaded(code, tmp_path)
    assert got["heavy"] == ["matplotlib"]
    assert (tmp_path / "x" / "trajectory.npz").exists() and (tmp_path / "x" / "figure.png").exists()


def test_mujoco_renderer_still_loads_on_first_use(tmp_path):
    got = _loaded("import hgo_mj.simulate, mujoco\nassert mujoco.Renderer.__name__ == 'Renderer'"
                  "\nassert mujoco.GLContext.__name__ == 'GLContext'", tmp_path)
    assert "mujoco.rendering.classic.renderer" in got["rendering"]


def test_the_registries_name_each_family_where_it_lives():
    """``FAMILIES`` of observers and of systems name each class by the module that defines it,
    and every class a module of the package registers is among them (none forgotten)."""
    import importlib
    import pkgutil

    import hgo_mj.observers as observers
    import hgo_mj.systems as systems
    from hgo_mj.observers.base import FAMILIES, OBSERVERS

    for registry, families in ((OBSERVERS, FAMILIES), (systems.SYSTEMS, systems.FAMILIES)):
        for name, home in families.items():
            cls = registry[name]
            assert f"{cls.__module__}:{cls.__qualname__}" == home, name
    for mod in pkgutil.iter_modules(observers.__path__):
        importlib.import_module(f"hgo_mj.observers.{mod.name}")
    ours = {n: c for n, c in OBSERVERS.items() if c.__module__.startswith("hgo_mj.")}
    assert set(ours) == set(FAMILIES)
    named = {h.split(":")[1] for h in systems.FAMILIES.values()}
    assert named | {"FAMILIES", "SYSTEMS", "System"} == set(systems.__all__)
    assert {getattr(observers, n).__name__ for n in observers.__all__
            if n[0].isupper() and n != "OBSERVERS"} <= set(observers.__all__)



def test_dir_lists_the_lazy_names_before_their_import(tmp_path):
    """Sphinx's autodoc documents only the names ``dir(module)`` shows."""
    got = _loaded("import hgo_mj.observers as o, hgo_mj.systems as s\n"
                  "assert set(o.__all__) <= set(dir(o)), set(o.__all__) - set(dir(o))\n"
                  "assert set(s.__all__) <= set(dir(s)), set(s.__all__) - set(dir(s))", tmp_path)
    assert got["families"] == []


def test_streamed_run_loads_neither_pandas_nor_pyarrow_dataset(tmp_path):
    # the parts are read back by ParquetFile: pq.read_table would import pyarrow.dataset
    # (46 MB of the streamed run's peak RSS, issue 24); the chunks and metrics.parquet are
    # written from buffers (hgo_mj.tidy.arrow_array): pa.table would import pandas
    code = ("import sys\nfrom hgo_mj.cli import main\n"
            "assert main(['run', '--plant', 'pendulum', '--duration', '0.5', '--out', 'x', "
            "'--stream']) == 0\n"
            "print('DATASET', 'pyarrow.dataset' in sys.modules, 'pandas' in sys.modules)")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True,
                         text=True, timeout=300, check=True).stdout
    assert "DATASET False False" in out
    assert (tmp_path / "x" / "trajectory.parquet").exists()
