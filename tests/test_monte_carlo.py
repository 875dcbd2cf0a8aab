"""Monte Carlo over sensor-noise seeds: :func:`hgo_mj.study.monte_carlo` and ``hgo-mj run --seeds``.

Every run of a study must be bit-identical to a single ``simulate`` at its seed, the aggregate
must be the plain statistics of those runs, the worker processes must change nothing, and the
command must write its files and leave the first seed's files as a single run writes them.
"""

from __future__ import annotations

import json
import math
from functools import partial

import numpy as np
import pytest

from hgo_mj.cli import main
from hgo_mj.exceptions import DesignError
from hgo_mj.inputs import Multisine
from hgo_mj.metrics import all_metrics
from hgo_mj.observers import HighGainObserver
from hgo_mj.plants import make_plant
from hgo_mj.scenario import scenario_run
from hgo_mj.sensors import GaussianNoise, Quantization, SensorChain
from hgo_mj.simulate import Trajectory, simulate
from hgo_mj.study import aggregate, monte_carlo

SEEDS = [3, 4, 5, 9]
TIMING = "update_time"  # the wall time: the one value that differs between repetitions


def make_run() -> dict:
    plant = make_plant("pendulum", dt=0.001)
    return {"plant": plant,
            "sensor": SensorChain([GaussianNoise(std=2e-3), Quantization(counts_per_rev=4096)]),
            "observers": {"k15": HighGainObserver(plant.system, k=15.0),
                          "k60": HighGainObserver(plant.system, k=60.0),
                          # no system: its columns y1, y1_d1 are no plant state (None metrics)
                          "free": HighGainObserver(order=2, k=30.0)},
            "inputs": Multisine([0.2], [0.5]), "duration": 0.6, "x0": [0.4, 0.0]}


def _strip(metrics: dict) -> dict:
    return {o: {k: v for k, v in m.items() if k != TIMING} for o, m in metrics.items()}


@pytest.fixture(scope="module")
def study():
    return monte_carlo(make_run, SEEDS, t_transient=0.1)


def test_runs_are_single_runs_and_aggregate_is_their_statistics(study):
    singles = [all_metrics(simulate(**make_run(), seed=s), t_transient=0.1) for s in SEEDS]
    assert study.seeds == SEEDS
    for got, want in zip(study.runs, singles):
        assert _strip(got) == _strip(want)  # bit-identical: exact float equality
    assert study.runs[0]["k60"]["rmse"] != study.runs[1]["k60"]["rmse"]  # the seeds matter
    agg = study.aggregate
    assert list(agg) == ["k15", "k60", "free"]
    for obs in ("k15", "k60"):
        a = agg[obs]
        assert a["runs"] == len(SEEDS) and a["estimated"] == [True, True]
        for key in ("rmse", "peak", "final"):
            for j in range(2):
                v = np.array([m[obs][key][j] for m in singles])
                assert a[key]["mean"][j] == pytest.approx(v.mean(), rel=1e-15)
                assert a[key]["std"][j] == pytest.approx(v.std(ddof=1), rel=1e-12, abs=1e-300)
                assert a[key]["min"][j] == v.min() and a[key]["max"][j] == v.max()
                assert a[key]["median"][j] == pytest.approx(np.median(v), rel=1e-15)
        for j in range(2):
            st = np.array([m[obs]["settling_time"][j] for m in singles])
            ok = st[np.isfinite(st)]
            assert a["settling_time"]["settled_fraction"][j] == ok.size / st.size
            assert a["settling_time"]["median"][j] == (np.median(ok) if ok.size else math.inf)
    # not estimated: every statistic is None, as the metrics are
    free = agg["free"]
    assert free["estimated"] == [False, False]
    for key in ("rmse", "peak", "final"):
        assert all(v == [None, None] for v in free[key].values())
    assert all(v == [None, None] for v in free["settling_time"].values())
    json.loads(json.dumps(study.to_json()))  # JSON-ready
    table = study.table()
    assert "k60" in table and "rmse std" in table and "not estimated" in table


def test_settling_statistics_over_the_runs_that_settled():
    base = {"states": ["a"], "estimated": [True], "rmse": [1.0], "peak": [2.0], "final": [0.5],
            "update_time": 1e-6}
    runs = [{"o": {**base, "settling_time": [t]}} for t in (0.3, math.inf, 0.1, 0.2)]
    st = aggregate(runs)["o"]["settling_time"]
    assert st == {"settled_fraction": [0.75], "median": [0.2], "min": [0.1], "max": [0.3]}
    never = aggregate([{"o": {**base, "settling_time": [math.inf]}}])["o"]
    assert never["settling_time"]["settled_fraction"] == [0.0]
    assert never["settling_time"]["median"] == [math.inf] and never["rmse"]["std"] == [0.0]


SCENARIO = {
    "name": "mc", "plant": {"name": "pendulum", "x0": [0.4, 0.0]},
    "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
    "observers": [{"type": "high_gain", "name": "fast", "k": 60.0}],
    "input": {"type": "multisine", "amplitudes": [0.2], "frequencies": [0.5]},
    "run": {"duration": 0.4, "seed": 0},
}


def test_jobs_do_not_change_the_results():
    mk = partial(scenario_run, SCENARIO)  # picklable: the workers are spawned
    one = monte_carlo(mk, [0, 1, 2], jobs=1)
    two = monte_carlo(mk, [0, 1, 2], jobs=2)
    assert [_strip(r) for r in one.runs] == [_strip(r) for r in two.runs]
    drop = {k: v for k, v in one.aggregate["fast"].items() if k != TIMING}
    assert drop == {k: v for k, v in two.aggregate["fast"].items() if k != TIMING}


@pytest.mark.parametrize("kw, message", [
    ({"seeds": []}, "at least one seed"),
    ({"seeds": [1, -2]}, "non-negative integers; found -2"),
    ({"seeds": [1.5]}, "non-negative integers; found 1.5"),
    ({"seeds": [0], "jobs": 0}, "jobs must be a positive integer; found 0"),
    ({"seeds": [0, 1], "jobs": 2, "make_run": lambda: {}}, "must be picklable"),
])
def test_api_bad_input(kw, message):
    kw = {"make_run": make_run, **kw}
    with pytest.raises(DesignError, match=message):
        monte_carlo(kw.pop("make_run"), kw.pop("seeds"), **kw)


FLAGS = ["run", "--plant", "pendulum", "--sensor", "gaussian:std=1e-3",
         "--observer", "high_gain:name=slow,k=15", "--observer", "high_gain:name=fast,k=60",
         "--input", "multisine:amplitudes=[0.2],frequencies=[0.5]", "--duration", "0.5"]


def test_cli_seeds_writes_the_study_and_the_first_seed(tmp_path, capsys):
    assert main([*FLAGS, "--seed", "7", "--seeds", "3", "--out", str(tmp_path / "mc")]) == 0
    printed = capsys.readouterr().out
    assert "Monte Carlo over the seeds 7..9" in printed and "rmse std" in printed
    assert main([*FLAGS, "--seed", "7", "--out", str(tmp_path / "one")]) == 0
    mc, one = tmp_path / "mc", tmp_path / "one"
    for f in ("metrics_mc.json", "summary_mc.txt", "mc.png", "trajectory.npz", "metrics.json",
              "figure.png", "summary.txt"):
        assert (mc / f).is_file(), f
    assert not (one / "metrics_mc.json").exists()
    data = json.loads((mc / "metrics_mc.json").read_text())
    assert set(data) == {"seeds", "runs", "aggregate", "failed"} and data["seeds"] == [7, 8, 9]
    assert data["failed"] == []
    assert [r["seed"] for r in data["runs"]] == [7, 8, 9]
    agg = data["aggregate"]
    assert set(agg) == {"slow", "fast"}
    assert set(agg["fast"]) == {"states", "estimated", "runs", "rmse", "peak", "final",
                                "settling_time", "update_time"}
    assert set(agg["fast"]["rmse"]) == {"mean", "std", "min", "median", "max"}
    assert set(agg["fast"]["settling_time"]) == {"settled_fraction", "median", "min", "max"}
    # the first seed's files are those of a single run at that seed
    a, b = Trajectory.load(mc / "trajectory.npz"), Trajectory.load(one / "trajectory.npz")
    for col in ("t", "x", "y_clean", "y_meas", "u"):
        np.testing.assert_array_equal(getattr(a, col), getattr(b, col))
    for name in ("slow", "fast"):
        np.testing.assert_array_equal(a.observers[name].x_hat, b.observers[name].x_hat)
    spec_a, spec_b = a.metadata["scenario_spec"], b.metadata["scenario_spec"]
    assert spec_a["run"].pop("out") != spec_b["run"].pop("out")
    assert spec_a == spec_b  # no run.seeds in the first seed's files
    single = json.loads((one / "metrics.json").read_text())
    assert _strip(data["runs"][0]["metrics"]) == _strip(single)
    assert "fast" in (mc / "summary_mc.txt").read_text()
    assert (mc / "mc.png").stat().st_size > 10_000


def test_cli_seeds_in_the_scenario_file(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text('[plant]\nname = "pendulum"\n[sensor]\nstages = [{stage = "gaussian", '
                    'std = 1e-3}]\n[[observers]]\ntype = "high_gain"\nk = 30.0\n'
                    f'[run]\nduration = 0.3\nseed = 2\nseeds = 2\nout = "{tmp_path / "o"}"\n')
    assert main(["run", str(path)]) == 0
    data = json.loads((tmp_path / "o" / "metrics_mc.json").read_text())
    assert data["seeds"] == [2, 3]
    # the flag overrides the file
    assert main(["run", str(path), "--seeds", "1", "--out", str(tmp_path / "p")]) == 0
    assert not (tmp_path / "p" / "metrics_mc.json").exists()


@pytest.mark.parametrize("extra, message", [
    (["--seeds", "0"], "--seeds must be a positive integer; found 0"),
    (["--seeds", "-3"], "--seeds must be a positive integer; found '-3'"),
    (["--seeds", "2.5"], "--seeds must be a positive integer; found '2.5'"),
    (["--seeds", "many"], "--seeds must be a positive integer; found 'many'"),
    (["--seeds", "2", "--jobs", "0"], "--jobs must be a positive integer; found 0"),
    (["--jobs", "x"], "--jobs must be a positive integer; found 'x'"),
])
def test_cli_bad_input_exits_2_with_one_line(extra, message, tmp_path, capsys):
    assert main([*FLAGS, "--out", str(tmp_path / "o"), *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hgo-mj: error:") and message in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()  # refused before anything runs


@pytest.mark.parametrize("value, shown", [("0", "0"), ("2.5", "2.5"), ("true", "True"),
                                          ('"3"', "'3'")])
def test_cli_bad_seeds_in_the_scenario_file(value, shown, tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(f'[plant]\nname = "pendulum"\n[run]\nduration = 0.3\nseeds = {value}\n')
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"run.seeds must be a positive integer; found {shown}" in err
    assert not (tmp_path / "o").exists()


class _Fragile(HighGainObserver):
    """A high-gain observer that gives up (DivergenceError) on a measurement jump larger than
    ``jump``: with Gaussian noise it diverges on some seeds and not on others."""

    def __init__(self, system, *, jump: float, **kw):
        super().__init__(system, **kw)
        self.jump = jump

    def _init(self, p, x0, z0, u0):  # the last measurement is state (NaN: none yet)
        return {**super()._init(p, x0, z0, u0), "last": np.full(u0.shape[0], np.nan)}

    def _step(self, p, s, Y, U, dt, X, Z, D):
        from hgo_mj.exceptions import DivergenceError

        for j in range(Y.shape[1]):
            y = float(Y[0, j, 0])
            last = float(s.last[0])
            if last == last and abs(y - last) > self.jump:
                raise DivergenceError(f"jump of {abs(y - last):.3g}")
            s.last[0] = y
            one = slice(j, j + 1)
            super()._step(p, s, Y[:, one], U[:, one], dt, X[:, one], Z[:, one], D[:, one])


def make_fragile_run() -> dict:
    plant = make_plant("pendulum", dt=0.001)
    return {"plant": plant, "sensor": SensorChain([GaussianNoise(std=1e-2)]),
            "observers": {"fragile": _Fragile(plant.system, k=15.0, jump=0.035)},
            "inputs": Multisine([0.2], [0.5]), "duration": 0.05, "x0": [0.4, 0.0]}


def test_a_diverging_seed_is_listed_and_left_out_not_fatal():
    from hgo_mj.exceptions import DivergenceError

    seeds = list(range(12))
    expected_failed = set()
    for s in seeds:  # each seed alone: which ones diverge
        try:
            simulate(**make_fragile_run(), seed=s)
        except DivergenceError:
            expected_failed.add(s)
    assert 0 < len(expected_failed) < len(seeds)  # the study has both kinds
    res = monte_carlo(make_fragile_run, seeds, t_transient=0.0)
    assert set(res.failed) == expected_failed
    assert res.seeds == [s for s in seeds if s not in expected_failed]
    assert res.aggregate["fragile"]["runs"] == len(res.seeds)
    assert all("jump of" in msg for msg in res.failed.values())
    assert f"{len(expected_failed)} of {len(seeds)} run(s) had an observer diverge" in res.table()
    assert json.loads(json.dumps(res.to_json(), allow_nan=False))["failed"][0]["seed"] == min(
        expected_failed)
    with pytest.raises(DivergenceError, match=r"every run diverged \(2 of 2\); seed"):
        monte_carlo(make_fragile_run, sorted(expected_failed)[:2])


def test_cli_seeds_resume_keeps_what_finished(tmp_path, capsys, monkeypatch):
    """An interrupted --seeds run keeps its finished chunks (OUT/seeds); --resume runs only
    the rest and gives the result of an uninterrupted run; --resume of a finished run runs
    no seed again; without --resume the seeds' folder is replaced."""
    from hgo_mj.study import backends, engine

    real, calls = engine.run_chunk, []
    out = str(tmp_path / "mc")
    args = [*FLAGS, "--seed", "7", "--seeds", "4", "--out", out, "--quiet"]

    def interrupted(chunk):
        calls.append(chunk.id)
        raise KeyboardInterrupt

    monkeypatch.setattr(backends, "run_chunk", interrupted)
    assert main(args) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["hgo-mj: interrupted; the finished runs are kept: rerun with --resume to go "
                   "on"]
    monkeypatch.setattr(backends, "run_chunk", real)
    assert main([*args, "--resume"]) == 0
    resumed = json.loads((tmp_path / "mc" / "metrics_mc.json").read_text())

    def never(chunk):
        raise AssertionError("a finished seed ran again")

    monkeypatch.setattr(backends, "run_chunk", never)
    assert main([*args, "--resume"]) == 0
    again = json.loads((tmp_path / "mc" / "metrics_mc.json").read_text())
    monkeypatch.setattr(backends, "run_chunk", real)
    assert main([*FLAGS, "--seed", "7", "--seeds", "4", "--out", str(tmp_path / "whole"),
                 "--quiet"]) == 0
    whole = json.loads((tmp_path / "whole" / "metrics_mc.json").read_text())
    assert _strip(resumed["aggregate"]) == _strip(whole["aggregate"]) == _strip(again["aggregate"])
    assert [r["seed"] for r in resumed["runs"]] == [7, 8, 9, 10]
    capsys.readouterr()
    assert main([*FLAGS, "--out", str(tmp_path / "one"), "--resume", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--resume goes on with the seeds of an interrupted --seeds N run" in err[0]
