"""The runner checks every observer's sample period before a run (paper 004, section 3: a
high gain with a too-long period is a stiff, diverging update): refused with the bound in the
message, or warned, as the observer is configured; the same from the command line."""

from __future__ import annotations

import re

import pytest

from hgo_mj.cli import main
from hgo_mj.exceptions import DesignError
from hgo_mj.inputs import make_signal
from hgo_mj.observers import make_observer
from hgo_mj.plants import MujocoPlant
from hgo_mj.simulate import simulate
from hgo_mj.systems import Pendulum


def _run(observer, **kw):
    plant = MujocoPlant(Pendulum())
    return simulate(plant, None, {"o": observer}, make_signal("constant", value=[0.0]), 0.1,
                    sample_period=0.01, **kw)


@pytest.mark.parametrize("kind, kw, label", [
    ("high_gain", {"k": 1000.0}, r"high-gain observer \(n=2, k=1000\)"),
    ("riccati", {"gamma": 1000.0}, r"Riccati observer \(n=2, gamma=1000\)"),
])
def test_simulate_refuses_an_unstable_euler_period_with_the_bound(kind, kw, label):
    ob = make_observer(kind, Pendulum(), method="euler", **kw)
    with pytest.raises(DesignError, match=rf"euler update of the {label} with sample period "
                                          r"0\.01 is unstable.*largest stable period is 0\.002"):
        _run(ob)


def test_simulate_warns_when_told_to_and_runs():
    ob = make_observer("high_gain", Pendulum(), k=1000.0, method="euler", on_unstable="warn")
    with pytest.warns(RuntimeWarning, match="largest stable period is 0.002"):
        traj = _run(ob, x0=[0.3, 0.0])
    # as warned: the error grows like the spectral radius, 9, every sample (|1 - k dt| with a
    # double pole of p at -1)
    assert abs(traj.error("o")[-1, 0]) > 1e6


def test_the_stable_method_runs_at_the_same_period():
    ob = make_observer("high_gain", Pendulum(), k=1000.0, method="exact")
    traj = _run(ob)
    assert len(traj) == 11


def test_command_line_refuses_with_the_bound(capsys):
    argv = ["run", "--plant", "pendulum", "--observer", "high_gain:k=1000,method=euler",
            "--sample-period", "0.01", "--duration", "0.1"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("hgo-mj: error:") and "Traceback" not in err
    assert re.search(r"largest stable period is 0\.002", err)
