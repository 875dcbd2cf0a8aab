"""A failing observer stops alone (issue 14): simulate(..., isolate=True) and `hgo-mj run`
record where it failed, fill its rows with NaN from there, and run the plant and the other
observers to the end, bit for bit as without it; isolate=False keeps raising."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hgo_mj.cli import main
from hgo_mj.exceptions import DesignError, DivergenceError
from hgo_mj.inputs import Constant, Multisine
from hgo_mj.loop import Loop, Periods
from hgo_mj.metrics import all_metrics, format_table
from hgo_mj.observers import HighGainObserver
from hgo_mj.plants import make_plant
from hgo_mj.sensors import GaussianNoise, SensorChain
from hgo_mj.simulate import simulate, simulate_batch

FRAG = '''
import numpy as np

from hgo_mj.exceptions import DivergenceError
from hgo_mj.observers.high_gain import HighGainObserver


class Frag(HighGainObserver):
    """Fails in its update at its 31st sample."""

    name = "frag"

    def _init(self, p, x0, z0, u0):  # its sample count is state
        return {**super()._init(p, x0, z0, u0), "count": np.zeros(u0.shape[0], dtype=int)}

    def _step(self, p, s, Y, U, dt, X, Z, D):
        s.count += Y.shape[1]
        if s.count.max() > 30:
            raise DivergenceError("the observer state left the finite numbers: [inf]")
        super()._step(p, s, Y, U, dt, X, Z, D)
'''


@pytest.fixture
def frag(tmp_path, monkeypatch):
    (tmp_path / "hgo_frag_mod.py").write_text(FRAG)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.chdir(tmp_path)
    import importlib

    yield importlib.import_module("hgo_frag_mod").Frag
    import sys

    sys.modules.pop("hgo_frag_mod", None)


def _parts():
    plant = make_plant("pendulum", dt=0.01)
    sensor = SensorChain([GaussianNoise(std=1e-3)])
    u = Multisine([0.3], [0.5])
    return plant, sensor, u


def test_a_failing_observer_stops_alone_and_the_others_are_untouched(frag):
    plant, sensor, u = _parts()
    good = HighGainObserver(plant.system, k=10.0)
    alone = simulate(plant, sensor, {"good": good}, u, 1.0, seed=4)
    with pytest.raises(DivergenceError, match="observer 'frag' failed in its update"):
        simulate(plant, sensor, {"good": good, "frag": frag(plant.system, k=5.0)}, u, 1.0,
                 seed=4)
    tr = simulate(plant, sensor, {"good": good, "frag": frag(plant.system, k=5.0)}, u, 1.0,
                  seed=4, isolate=True)
    d = tr.diverged["frag"]
    assert d["t"] == pytest.approx(0.30) and d["sample"] == 30
    assert d["error"] == ("DivergenceError: the observer state left the finite numbers: [inf]")
    e = tr.estimate("frag")
    assert np.isfinite(e[:d["row"]]).all() and np.isnan(e[d["row"]:]).all()
    assert len(tr.t) == len(alone.t) == 101
    np.testing.assert_array_equal(tr.estimate("good"), alone.estimate("good"))
    np.testing.assert_array_equal(tr.x, alone.x)
    m = all_metrics(tr, t_transient=0.1)
    assert m["frag"]["diverged_at"] == d["t"] and "diverged_at" not in m["good"]
    assert "frag: diverged at t = 0.3 s" in format_table(m)
    batch = simulate_batch(plant, sensor, {"good": good, "frag": frag(plant.system, k=5.0)}, u,
                           1.0, seeds=[4, 5], isolate=True)
    assert all(t.diverged["frag"]["t"] == pytest.approx(0.30) for t in batch)
    np.testing.assert_array_equal(batch[0].estimate("good"), alone.estimate("good"))


def test_an_estimate_that_leaves_the_finite_numbers_stops_alone():
    """No exception, an infinite estimate: with isolate it is NaN from that row on."""

    class Runaway(HighGainObserver):
        def _current(self, p, s):
            x, z, d = super()._current(p, s)
            return x, np.full_like(z, np.inf), d

    plant, sensor, u = _parts()
    tr = simulate(plant, None, {"ok": HighGainObserver(plant.system, k=10.0),
                                "run": Runaway(plant.system, k=1.0)}, Constant([0.0]), 0.2,
                  isolate=True)
    assert tr.diverged["run"]["row"] == 0 and np.isnan(tr.observers["run"].z_hat).all()
    assert np.isfinite(tr.estimate("ok")).all()


def test_the_command_line_writes_the_healthy_observers_and_says_which_diverged(frag, capsys):
    assert main(["run", "--plant", "pendulum", "--observer", "high_gain:k=10", "--observer",
                 "hgo_frag_mod:Frag:k=5", "--duration", "1", "--out", "o", "--quiet",
                 "--t-transient", "0.01"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["hgo-mj: observer 'Frag_1' diverged at t = 0.03 s (DivergenceError: the "
                   "observer state left the finite numbers: [inf]); its estimate is NaN from "
                   "there on, the other observers ran to the end"]
    metrics = json.loads(open("o/metrics.json").read())
    assert metrics["Frag_1"]["diverged_at"] == pytest.approx(0.03)
    assert all(v is not None for v in metrics["high_gain_0"]["rmse"])


def test_isolate_is_checked():
    plant = make_plant("pendulum", dt=0.01)
    with pytest.raises(DesignError, match="isolate must be true or false"):
        Loop(plant, None, {}, Periods.of(plant), isolate=1)


# ------------------------------------------------ issue 27 item 1: an overflowing estimate
#: an observer whose estimate grows beyond the floats' squares (explicit Euler, k = 3000)
#: beside a healthy one
RUNAWAY = ["--plant", "pendulum", "--sensor", "gaussian:std=1e-3", "--observer",
           "high_gain:name=unstable,k=3000,method=euler,on_unstable=ignore", "--observer",
           "high_gain:name=ok,k=20", "--input", "multisine:amplitudes=[0.3],frequencies=[0.5]",
           "--duration", "1", "--quiet"]


def _runaway_parts():
    plant = make_plant("pendulum", dt=0.01)
    obs = {"unstable": HighGainObserver(plant.system, k=3000.0, method="euler",
                                        on_unstable="ignore"),
           "ok": HighGainObserver(plant.system, k=20.0)}
    return plant, SensorChain([GaussianNoise(std=1e-3)]), obs


def test_an_estimate_that_grows_huge_but_finite_stops_alone():
    plant, sensor, obs = _runaway_parts()
    tr = simulate(plant, sensor, obs, Multisine([0.3], [0.5]), 1.0, seed=1, isolate=True)
    assert set(tr.diverged) == {"unstable"} and "1e+100" in tr.diverged["unstable"]["error"]
    m = all_metrics(tr)
    assert all(np.isfinite(v) for v in m["ok"]["rmse"])
    assert m["unstable"]["diverged_at"] == tr.diverged["unstable"]["t"]
    with pytest.raises(DivergenceError, match="observer 'unstable' estimate left"):
        simulate(plant, sensor, _runaway_parts()[2], Multisine([0.3], [0.5]), 1.0, seed=1)


def test_run_writes_the_healthy_observer_beside_an_overflowing_one(tmp_path, capsys):
    assert main(["run", *RUNAWAY, "--seed", "1", "--out", str(tmp_path / "o")]) == 0
    metrics = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert metrics["unstable"]["diverged_at"] is not None
    assert all(v is not None and np.isfinite(v) for v in metrics["ok"]["rmse"])
    assert "observer 'unstable' diverged" in capsys.readouterr().err


def test_seeds_count_the_overflowing_observer_as_diverged_in_every_seed(tmp_path, capsys):
    """Every seed has a diverged observer (the first one included): it is left out of each
    run's statistics, the healthy observer keeps all three runs; said so, the rows of every
    seed and the first seed's run written."""
    assert main(["run", *RUNAWAY, "--seed", "1", "--seeds", "3",
                 "--out", str(tmp_path / "mc")]) == 0
    data = json.loads((tmp_path / "mc" / "metrics_mc.json").read_text())
    assert list(data["aggregate"]) == ["ok"] and data["aggregate"]["ok"]["runs"] == 3
    assert [f["seed"] for f in data["failed"]] == [1, 2, 3]
    assert all("observer 'unstable'" in f["error"] for f in data["failed"])
    summary = (tmp_path / "mc" / "summary_mc.txt").read_text()
    assert "3 of 3 run(s) had an observer diverge" in summary
    assert "seed 1: observer 'unstable' diverged" in summary
    metrics = json.loads((tmp_path / "mc" / "metrics.json").read_text())
    assert all(np.isfinite(v) for v in metrics["ok"]["rmse"])
    rows = __import__("pandas").read_parquet(tmp_path / "mc" / "seeds" / "results.parquet")
    bad = rows[rows["observer"] == "unstable"]
    good = rows[rows["observer"] == "ok"]
    assert len(bad) and bad["diverged"].all()
    assert not good["diverged"].any() and np.isfinite(good["rmse"]).all()


def test_a_sweep_marks_the_overflowing_observer_diverged(tmp_path, capsys):
    from hgo_mj.study import Study

    base = {"plant": {"name": "pendulum"},
            "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
            "observers": [{"type": "high_gain", "name": "unstable", "k": 3000.0,
                           "method": "euler", "on_unstable": "ignore"},
                          {"type": "high_gain", "name": "ok", "k": 20.0}],
            "input": {"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]},
            "run": {"duration": 1.0}}
    table = Study(base, {"observers.ok.k": [10.0, 20.0]}, seeds=2).run(
        tmp_path / "s", quiet=True).table
    bad, good = table[table["observer"] == "unstable"], table[table["observer"] == "ok"]
    assert len(bad) == 8 and bad["diverged"].all() and bad["rmse"].isna().all()
    assert not good["diverged"].any() and np.isfinite(good["rmse"]).all()


PICKY = '''
import numpy as np

from hgo_mj.exceptions import DivergenceError
from hgo_mj.observers.high_gain import HighGainObserver


class Picky(HighGainObserver):
    """Fails when its first measurement is above 0.5005 (x0 = 0.5 plus noise > 5e-4: of the
    seeds 6, 7, 8 at std 1e-3, only seed 6)."""

    name = "picky"

    def _init(self, p, x0, z0, u0):
        return {**super()._init(p, x0, z0, u0), "count": np.zeros(u0.shape[0], dtype=int)}

    def _step(self, p, s, Y, U, dt, X, Z, D):
        if s.count.max() == 0 and (Y[:, 0, 0] > 0.5005).any():
            raise DivergenceError("the first measurement is too high")
        s.count += Y.shape[1]
        super()._step(p, s, Y, U, dt, X, Z, D)
'''


def test_a_diverging_first_seed_is_counted_and_nan_has_no_spread(tmp_path, monkeypatch,
                                                                 capsys):
    """Issue 27 item 6: the first seed diverges (isolated in its own run) and is counted with
    the others; a statistic of a NaN mean has a NaN spread, not 0."""
    import importlib
    import sys

    from hgo_mj.study.montecarlo import _stats

    (tmp_path / "hgo_picky_mod.py").write_text(PICKY)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.chdir(tmp_path)
    importlib.import_module("hgo_picky_mod")
    try:
        assert main(["run", "--plant", "pendulum", "--sensor", "gaussian:std=1e-3",
                     "--observer", "hgo_picky_mod:Picky:name=picky,k=20", "--observer",
                     "high_gain:name=ok,k=20", "--duration", "0.5", "--quiet", "--seed", "6",
                     "--seeds", "3", "--out", "mc"]) == 0
    finally:
        sys.modules.pop("hgo_picky_mod", None)
    data = json.loads((tmp_path / "mc" / "metrics_mc.json").read_text())
    assert data["seeds"] == [6, 7, 8] and [f["seed"] for f in data["failed"]] == [6]
    assert data["aggregate"]["picky"]["runs"] == 2 and data["aggregate"]["ok"]["runs"] == 3
    summary = (tmp_path / "mc" / "summary_mc.txt").read_text()
    assert "1 of 3 run(s) had an observer diverge" in summary and "seeds [6]" in summary
    assert "runs per observer: picky 2, ok 3" in summary
    assert "± 0 " not in summary and "nan" not in summary
    assert _stats([float("nan")])["std"] != _stats([float("nan")])["std"]  # NaN
    assert _stats([0.5])["std"] == 0.0
