"""The lean install (issue 28, item 1): what is optional sits in an extra, and a feature whose
extra is missing fails with one line naming it (``hgo_mj._extras.require``)."""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

import numpy as np
import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

from hgo_mj._extras import EXTRAS, require
from hgo_mj.cli import main
from hgo_mj.exceptions import MissingExtraError

ROOT = Path(__file__).resolve().parents[1]
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]


def _names(reqs: list[str]) -> set[str]:
    return {re.split(r"[\[<>=;! ]", r, maxsplit=1)[0].lower() for r in reqs}


def test_the_extras_are_those_of_pyproject_and_the_runtime_holds_none_of_them():
    extras = PROJECT["optional-dependencies"]
    assert set(EXTRAS) == set(extras)
    runtime = _names(PROJECT["dependencies"])
    assert not runtime & {"cvxpy", "clarabel", "sympy", "ray", "moviepy", "imageio", "pytest"}
    # MuJoCo's bindings alone: its metapackage `mujoco` adds glfw, PyOpenGL and MuJoCo Studio,
    # which only rendering needs (the render extra)
    assert not runtime & {"mujoco", "glfw", "pyopengl"}
    assert {"mujoco-core", "numba", "rerun-sdk", "optuna", "cmaes", "pyarrow"} <= runtime
    assert extras["render"] == ["mujoco-core[rendering]>=4,<5"]
    # make test installs dev: every extra the tests import but docs and rl
    assert "hgo_mj[lmi,symbolic,render,gym,ray]" in extras["dev"]
    readme = (ROOT / "README.md").read_text()
    install = readme[readme.index("## Install"):readme.index("\n## ", readme.index("## Install") + 3)]
    assert re.findall(r"^\| `(\w+)` \|", install, re.M) == list(extras)  # a row per extra


def test_a_missing_package_is_one_line_naming_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "cvxpy", None)  # `import cvxpy` raises ImportError
    with pytest.raises(MissingExtraError) as err:
        require("cvxpy", "lmi", "LMI (62)")
    assert str(err.value) == "LMI (62) needs the optional dependency cvxpy: pip install 'hgo_mj[lmi]'"
    assert isinstance(err.value, ImportError) and err.value.extra == "lmi"
    with pytest.raises(ValueError, match="unknown extra 'lmii'"):
        require("numpy", "lmii", "x")


def test_a_package_whose_own_import_fails_is_not_called_missing(tmp_path, monkeypatch):
    (tmp_path / "half_installed.py").write_text("import no_such_dependency_of_it\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ModuleNotFoundError, match="no_such_dependency_of_it"):
        require("half_installed", "lmi", "x")


def test_the_lmi_design_without_cvxpy_names_the_lmi_extra(monkeypatch):
    from hgo_mj.design import max_sampling_period

    monkeypatch.setitem(sys.modules, "cvxpy", None)
    M = np.array([[0.0], [2.0]])
    with pytest.raises(MissingExtraError, match=r"pip install 'hgo_mj\[lmi\]'$"):
        max_sampling_period([2.0, 1.0], 5.0, M, np.eye(2))


def test_check_without_cvxpy_still_reports_and_names_the_extra(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "cvxpy", None)
    assert main(["check", str(ROOT / "scenarios" / "ode_pendulum.toml")]) == 0
    out = capsys.readouterr().out
    assert "no sampling bound: LMI (63)/(65) of paper 004 needs the optional dependency cvxpy: " \
           "pip install 'hgo_mj[lmi]'" in out


def test_an_ode_plant_without_sympy_is_one_line_naming_the_symbolic_extra(tmp_path, monkeypatch,
                                                                           capsys):
    monkeypatch.setitem(sys.modules, "sympy", None)
    for mod in [m for m in sys.modules if m.startswith("hgo_mj.systems.symbolic")]:
        monkeypatch.delitem(sys.modules, mod)
    out = tmp_path / "o"
    assert main(["run", str(ROOT / "scenarios" / "ode_pendulum.toml"), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err == ("hgo-mj: error: an ODE plant given as text (hgo_mj.systems.symbolic) needs the "
                   "optional dependency sympy: pip install 'hgo_mj[symbolic]'\n")
    assert not out.exists()


def _dry_run(target: str, tmp_path: Path) -> list[str]:
    """The commands ``make -n TARGET`` would run from nothing (a folder with the Makefile and
    what its rules depend on, no .venv)."""
    import shutil
    import subprocess

    for name in ("Makefile", "pyproject.toml", "constraints.txt"):
        shutil.copy(ROOT / name, tmp_path / name)
    # run as its own make, not a sub-make of the `make test` that runs this test (which would
    # print "make[1]: Entering directory" lines): no inherited MAKEFLAGS / MAKELEVEL
    env = {k: v for k, v in os.environ.items() if k not in ("MAKEFLAGS", "MAKELEVEL", "MFLAGS")}
    res = subprocess.run(["make", "--no-print-directory", "-n", target], cwd=tmp_path,
                         capture_output=True, text=True, timeout=60, check=True, env=env)
    return res.stdout.splitlines()


def test_make_demo_installs_the_runtime_only_and_says_each_step(tmp_path):
    lines = _dry_run("demo", tmp_path)
    installs = [ln for ln in lines if "pip install" in ln and not ln.startswith("echo")]
    assert installs == [".venv/bin/python -m pip install --no-compile -e ."]
    steps = [ln for ln in lines if ln.startswith('echo "[')]
    assert [s[6:11] for s in steps] == ["[1/3]", "[2/3]", "[3/3]"]
    assert any("hgo-mj bench --suite quick" in ln for ln in lines)
    assert lines[-1] == f'echo "done: open {tmp_path}/runs/demo/leaderboard.md and ' \
                        f'{tmp_path}/runs/demo/score_matrix.png"'


def test_make_test_installs_dev_within_the_constraints(tmp_path):
    lines = _dry_run("test", tmp_path)
    assert '.venv/bin/python -m pip install -e ".[dev]" -c constraints.txt' in lines
    assert lines[-1] == ".venv/bin/python -m pytest -q -ra"


def test_constraints_pin_every_distribution_of_the_test_environment():
    pins = {}
    for line in (ROOT / "constraints.txt").read_text().splitlines():
        if line and not line.startswith("#"):
            name, _, ver = line.partition("==")
            assert ver and re.fullmatch(r"[0-9][0-9A-Za-z.+!-]*", ver), line
            pins[re.sub(r"[-_.]+", "-", name).lower()] = ver
    assert "hgo-mj" not in pins
    wanted = _names(PROJECT["dependencies"]) | {
        n for extra in ("lmi", "symbolic", "render", "gym", "ray", "docs") for n in
        _names(PROJECT["optional-dependencies"][extra])} | _names(
        [r for r in PROJECT["optional-dependencies"]["dev"] if not r.startswith("hgo_mj")])
    wanted = {re.sub(r"[-_.]+", "-", n) for n in wanted} - {"tomli"}  # tomli: Python 3.10 only
    assert wanted <= set(pins), sorted(wanted - set(pins))


def test_the_lmi_reproduction_without_cvxpy_stops_before_any_work(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "cvxpy", None)
    out = tmp_path / "ibrir"
    assert main(["reproduce", "ibrir2007", "--out", str(out)]) == 2
    assert capsys.readouterr().err == ("hgo-mj: error: the ibrir2007 reproduction needs the optional "
                                       "dependency cvxpy: pip install 'hgo_mj[lmi]'\n")
    assert not out.exists()
