"""The user's own plant and observer classes, named ``module:Class`` in Python, on the command
line and in scenario files (issue 12): they run like registered ones, and every way the name
can fail is one clear line (exit 2 from the command line)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from hgo_mj.cli import main
from hgo_mj.exceptions import DesignError
from hgo_mj.observers import make_observer
from hgo_mj.plants import make_plant
from hgo_mj.simulate import Trajectory

USER_MODULE = '''
from hgo_mj.observers.high_gain import HighGainObserver
from hgo_mj.systems.pendulum import Pendulum


class FarOut(Pendulum):
    """The pendulum, started further out."""

    name = "far_out"
    default_x0 = (1.0, 0.0)


class MyHGO(HighGainObserver):
    name = "my_hgo"
'''


@pytest.fixture
def user_module(tmp_path, monkeypatch):
    """``hgo_user_mod`` (a System and an Observer subclass) and ``hgo_user_broken`` (raises on
    import) in a folder that is the current one, as a user's project would be."""
    (tmp_path / "hgo_user_mod.py").write_text(USER_MODULE)
    (tmp_path / "hgo_user_broken.py").write_text('raise RuntimeError("boom\\nsecond line")\n')
    (tmp_path / "hgo_user_exits.py").write_text("import sys\nsys.exit(0)\n")
    monkeypatch.chdir(tmp_path)
    yield tmp_path
    for name in ("hgo_user_mod", "hgo_user_broken", "hgo_user_exits"):
        sys.modules.pop(name, None)


def test_python_api_builds_the_users_classes(user_module):
    plant = make_plant("hgo_user_mod:FarOut", 0.01)
    assert type(plant.system).__name__ == "FarOut"
    obs = make_observer("hgo_user_mod:MyHGO", plant.system, k=10.0)
    assert type(obs).__name__ == "MyHGO" and obs.state_names == plant.system.state_names


def test_command_line_and_scenario_run_the_users_classes(user_module, capsys):
    assert main(["run", "--plant", "hgo_user_mod:FarOut", "--observer",
                 "hgo_user_mod:MyHGO:k=10", "--duration", "0.5", "--out", "a", "--quiet"]) == 0
    tr = Trajectory.load(user_module / "a" / "trajectory.npz")
    assert set(tr.observers) == {"MyHGO_0"} and np.isfinite(tr.error("MyHGO_0")).all()
    (user_module / "s.toml").write_text(
        'name = "mine"\n[plant]\nname = "hgo_user_mod:FarOut"\n'
        '[[observers]]\ntype = "hgo_user_mod:MyHGO"\nk = 12.0\n[run]\nduration = 0.5\n')
    assert main(["run", "s.toml", "--out", "b", "--quiet"]) == 0
    assert set(Trajectory.load(user_module / "b" / "trajectory.npz").observers) == {"MyHGO_0"}


@pytest.mark.parametrize(("flag", "spec", "message"), [
    ("--plant", "hgo_user_nomod:X",
     "plant 'hgo_user_nomod:X': module 'hgo_user_nomod' does not import (ModuleNotFoundError: "
     "No module named 'hgo_user_nomod')"),
    ("--plant", "hgo_user_broken:X",
     "plant 'hgo_user_broken:X': module 'hgo_user_broken' does not import (RuntimeError: boom)"),
    ("--plant", "hgo_user_exits:X",  # issue 27 item 10: not a silent exit 0
     "plant 'hgo_user_exits:X': module 'hgo_user_exits' called sys.exit(0) while it was "
     "imported"),
    ("--plant", "hgo_user_mod:Nope", "plant 'hgo_user_mod:Nope': module 'hgo_user_mod' has no "
                                     "'Nope'"),
    ("--plant", "hgo_user_mod:MyHGO", "plant 'hgo_user_mod:MyHGO' must name a subclass of "
                                      "System; found <class 'hgo_user_mod.MyHGO'>"),
    ("--plant", "1x:Y", "plant '1x:Y' must be 'module:Class' (dotted Python names)"),
    ("--observer", "hgo_user_mod:FarOut", "observer 'hgo_user_mod:FarOut' must name a "
                                           "subclass of Observer; found <class "
                                           "'hgo_user_mod.FarOut'>"),
    ("--observer", "hgo_user_nomod:Obs:k=3", "observer 'hgo_user_nomod:Obs': module "
                                             "'hgo_user_nomod' does not import"),
])
def test_a_class_that_does_not_load_is_one_line(user_module, capsys, flag, spec, message):
    argv = ["run", "--duration", "0.2", "--out", "o", "--quiet", flag, spec]
    if flag == "--observer":
        argv += ["--plant", "pendulum"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"hgo-mj: error: {message}"), err
    assert not (user_module / "o").exists()


def test_python_errors_are_design_errors(user_module):
    with pytest.raises(DesignError, match="does not import"):
        make_plant("hgo_user_broken:X")
    with pytest.raises(DesignError, match="must name a subclass of Observer"):
        make_observer("hgo_user_mod:FarOut", None)
    with pytest.raises(DesignError, match="unknown plant 'nope'; valid: .*'module:Class'"):
        make_plant("nope")
