"""Tuning (hgo_mj.tune, ``hgo-mj tune``): a round of trials is one batch equal to the single
runs, a real Optuna study in a real SQLite file, the same seed the same result, resume after a
kill loses no trial and repeats none, and every bad input is one line before any work."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from hgo_mj.cli import main
from hgo_mj.exceptions import DesignError
from hgo_mj.metrics import observer_metrics
from hgo_mj.scenario import scenario_run
from hgo_mj.simulate import simulate
from hgo_mj.tune import Objective, check_space, evaluate, setup, tune

SC = {"name": "pendulum-encoder",
      "plant": {"name": "pendulum", "dt": 0.002, "x0": [0.5, 0.0]},
      "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3},
                            {"stage": "quantize", "counts_per_rev": 4096}]},
      "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
      "input": {"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]},
      "run": {"duration": 3.0}}


def _toml(path: Path, sc: dict) -> Path:
    from hgo_mj.tune.tuner import _toml as to_toml

    path.write_text(to_toml(sc))
    return path


def test_a_round_is_one_batch_each_member_equal_to_its_single_run():
    """Trial r at seed s of one batch equals simulate() of that gain at that seed and its
    metrics (the same kernels on the same numbers)."""
    st = setup(SC, "hgo")
    gains, seeds = [8.0, 40.0, 120.0], [3, 4]
    sc = evaluate(st, [{"k": k} for k in gains], seeds)
    for r, k in enumerate(gains):
        for j, seed in enumerate(seeds):
            kw = scenario_run({**SC, "observers": [{"type": "high_gain", "name": "hgo", "k": k}]})
            kw.pop("metadata")
            traj = simulate(seed=seed, **kw)
            m = observer_metrics(traj, "hgo", t_transient=st.t_transient)
            np.testing.assert_allclose(sc.rmse[r, j], m["rmse"], rtol=1e-12)
            np.testing.assert_array_equal(sc.peak[r, j], m["peak"])
            np.testing.assert_array_equal(sc.settling[r, j], m["settling_time"])
            # the output prediction error: z1 before each sample (a trajectory's row k holds
            # the estimate before y(t_k)) against that sample
            y = traj.y_meas[:, 0]
            zb = traj.observers["hgo"].z_hat[:, 0]
            first = int(np.ceil(st.t_transient / 0.002 - 1e-9))
            e = y[first:st.N] - zb[first:st.N]
            np.testing.assert_allclose(sc.output_error[r, j], np.sqrt(np.mean(e * e)),
                                       rtol=1e-9)


def test_tune_keeps_a_real_optuna_study_in_sqlite_and_beats_the_default(tmp_path):
    out = tmp_path / "t"
    r = tune(SC, "hgo", budget=12, seeds=3, round_size=6, out=out, progress=False)
    assert (out / "study.db").stat().st_size > 0
    import optuna

    study = optuna.load_study(study_name="hgo_mj-tune", storage=f"sqlite:///{out / 'study.db'}")
    assert len(study.trials) == 12
    table = pd.read_parquet(out / "trials.parquet")
    assert list(table["number"]) == list(range(12)) and set(table["state"]) == {"COMPLETE"}
    assert table.loc[0, "k"] == 20.0  # trial 0 is the untuned default
    assert r.values["best"][0] < r.values["default"][0]
    assert table["rmse"].min() == pytest.approx(r.values["best"][0])
    assert json.loads(table.loc[0, "seeds"]) == [1, 2, 3]
    assert (out / "convergence.png").stat().st_size > 0
    assert "angle" in (out / "summary.txt").read_text()
    # best.toml runs with hgo-mj run, the tuned gain in it
    assert main(["run", str(out / "best.toml"), "--out", str(tmp_path / "run"),
                 "--format", "npz"]) == 0
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert metrics["hgo"]["rmse"][0] < 0.5 * r.values["default"][0] * 1e3  # finite, sane
    assert f"k = {r.best['k']!r}" in (out / "best.toml").read_text()


def test_the_same_seed_gives_the_same_best_parameters():
    a = tune(SC, "hgo", budget=10, seeds=2, round_size=5, seed=7, progress=False)
    b = tune(SC, "hgo", budget=10, seeds=2, round_size=5, seed=7, progress=False)
    c = tune(SC, "hgo", budget=10, seeds=2, round_size=5, seed=8, progress=False)
    assert a.best == b.best and a.values == b.values
    pd.testing.assert_frame_equal(a.trials, b.trials)
    assert not a.trials["k"].equals(c.trials["k"])


def test_several_objectives_give_a_pareto_front():
    r = tune(SC, "hgo", objective=["rmse", "peak"], budget=12, seeds=2, round_size=6,
             progress=False)
    assert {"convergence", "pareto"} <= set(r.figures)
    front = r.trials[r.trials["number"].isin(r.pareto)]
    for _, row in front.iterrows():  # no trial dominates a member of the front
        dominated = (r.trials["rmse"] <= row["rmse"]) & (r.trials["peak"] <= row["peak"]) & (
            (r.trials["rmse"] < row["rmse"]) | (r.trials["peak"] < row["peak"]))
        assert not dominated.any()


def test_without_truth_the_output_error_optimum_is_near_the_truth_optimum():
    """Tuned on the output prediction error only (what a rig gives), the gain's truth RMSE is
    within 25 % of the truth-tuned one's."""
    truth = tune(SC, "hgo", objective="rmse", budget=24, seeds=3, progress=False)
    blind = tune(SC, "hgo", objective="output_error", budget=24, seeds=3, progress=False)
    st = setup(SC, "hgo")
    seeds = [11, 12, 13]  # scored on other seeds
    both = evaluate(st, [truth.best_parameters, blind.best_parameters], seeds)
    rmse = np.mean(both.rmse / st.ranges, axis=(1, 2))
    assert rmse[1] <= 1.25 * rmse[0], (truth.best, blind.best, rmse)


def test_a_trial_the_observer_refuses_scores_inf_and_the_tuning_goes_on():
    sc = {**SC, "observers": [{"type": "adaptive_gain", "name": "ag", "lam": 0.04,
                               "lam_hat": 0.08, "gamma": 200.0, "k0": 20.0, "k_max": 400.0}]}
    r = tune(sc, "ag", budget=10, seeds=1, round_size=10, progress=False)
    bad = r.trials["lam_hat"] <= r.trials["lam"]
    assert bad.any()  # the sampler proposes lam_hat <= lam (paper 000, eq. 5 refuses it)
    assert np.isinf(r.trials.loc[bad, "rmse"]).all() and r.trials.loc[bad, "diverged"].all()
    assert np.isfinite(r.values["best"][0])


RESUME = """
import sys
from hgo_mj.tune import tune
sc = {sc!r}
tune(sc, "hgo", budget={budget}, seeds=2, round_size=4, out=sys.argv[1], resume=len(sys.argv) > 2,
     progress=False)
"""


def test_resume_after_a_kill_loses_no_trial_and_repeats_none(tmp_path):
    out = tmp_path / "t"
    sc = {**SC, "run": {"duration": 20.0}}
    script = tmp_path / "tune_it.py"
    script.write_text(RESUME.format(sc=sc, budget=24))
    proc = subprocess.Popen([sys.executable, str(script), str(out)])
    table = out / "trials.parquet"
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and proc.poll() is None:
        if table.exists() and len(pd.read_parquet(table)) >= 8:
            break
        time.sleep(0.05)
    if proc.poll() is not None:
        pytest.fail("the tuning finished before it could be killed: make it longer")
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    import optuna

    storage = f"sqlite:///{out / 'study.db'}"
    before = {t.number: t.values for t in optuna.load_study(
        study_name="hgo_mj-tune", storage=storage).trials if t.values is not None}
    assert 4 <= len(before) < 24
    assert subprocess.run([sys.executable, str(script), str(out), "resume"],
                          timeout=600).returncode == 0
    trials = optuna.load_study(study_name="hgo_mj-tune", storage=storage).trials
    assert len(trials) == 24 and sorted(t.number for t in trials) == list(range(24))
    assert all(t.state.name == "COMPLETE" for t in trials)
    for t in trials:  # the finished trials are kept as they were, none run again
        if t.number in before:
            assert t.values == before[t.number]
    # and the resumed tuning refuses another scenario
    with pytest.raises(DesignError, match="tuned another scenario"):
        tune({**sc, "run": {"duration": 5.0}}, "hgo", budget=24, seeds=2, out=out, resume=True,
             progress=False)


@pytest.mark.parametrize("kw,match", [
    ({"space": {"gain": (1.0, 2.0)}}, r"space names 'gain', not a search variable of "
                                      r"'high_gain'; valid: \['k'\]"),
    ({"space": {"k": (5.0, 5.0)}}, r"space k: empty bounds, low must be < high"),
    ({"space": {"k": (-1.0, 5.0, "linear")}}, r"space k: the observer refuses the bound -1: "
                                              r"k must be > 0"),
    ({"space": {"k": (0.0, 5.0)}}, r"space k: a log scale needs low > 0"),
    ({"space": {"k": "wide"}}, r"space k: expected \(low, high\)"),
    ({"objective": "rms"}, r"objective 'rms' is not a score"),
    ({"objective": {"rmse": -1.0}}, r"the weight of 'rmse' must be a positive number"),
    ({"budget": 1}, r"budget must be an integer >= 2"),
    ({"budget": 2.5}, r"budget must be an integer >= 2"),
    ({"seeds": 0}, r"seeds must be between 1 and 10000"),
    ({"seeds": [1, 1]}, r"seeds must be distinct"),
    ({"aggregate": "median"}, r"aggregate must be one of \['mean', 'worst'\]"),
    ({"sampler": "grid"}, r"sampler must be one of"),
    ({"backend": "dask"}, r"backend must be 'local' or 'ray'"),
    ({"mismatch": "heavy"}, r"mismatch must be a table"),
    ({"mismatch": {"nonsense": 1.0}}, r"nonsense"),
    ({"objective": "nis"}, r"objective nis: observer 'high_gain' reports no NIS"),
    ({"resume": True}, r"resume needs out"),
    ({"states": ["cart"]}, r"states to score must be plant states the observer 'hgo' estimates"),
])
def test_bad_input_is_one_line_before_any_work(kw, match, monkeypatch):
    ev = sys.modules["hgo_mj.tune.scoring"]

    def no_work(*a, **k):
        raise AssertionError("evaluated before the input was checked")

    monkeypatch.setattr(ev, "plant_rows", no_work)
    with pytest.raises(DesignError, match=match):
        tune(SC, "hgo", progress=False, **kw)


def test_bad_scenarios_are_refused_before_any_work(tmp_path):
    with pytest.raises(DesignError, match=r"observer 'nope' is not in the scenario; it has "
                                          r"\['hgo'\]"):
        tune(SC, "nope", progress=False)
    closed = {k: v for k, v in SC.items() if k != "input"}
    closed["controller"] = {"type": "linear", "gain": [[1.0, 0.5]], "source": "estimate"}
    with pytest.raises(DesignError, match="needs an open-loop \\[input\\]"):
        tune(closed, "hgo", progress=False)
    out = tmp_path / "t"
    tune(SC, "hgo", budget=2, seeds=1, out=out, progress=False)
    with pytest.raises(DesignError, match=r"study.db exists: resume=True"):
        tune(SC, "hgo", budget=2, seeds=1, out=out, progress=False)


def test_check_space_keeps_only_the_variables_named():
    from hgo_mj.observers import make_observer
    from hgo_mj.systems import SYSTEMS

    ob = make_observer("ukf", SYSTEMS["pendulum"]())
    full = ob.tuning_space()
    assert {"Q[0]", "Q[1]", "R[0]", "alpha", "beta"} <= set(full)
    got = check_space(ob, {"R[0]": (1e-8, 1e-2)})
    assert list(got) == ["R[0]"] and got["R[0]"].log
    assert Objective({"rmse": 1.0, "peak": 0.5}).names == ["1*rmse+0.5*peak"]


def test_the_command_line_tunes_and_writes_its_files(tmp_path, capsys):
    scenario = _toml(tmp_path / "sc.toml", SC)
    out = tmp_path / "out"
    assert main(["tune", str(scenario), "--observer", "hgo", "--budget", "6", "--seeds", "2",
                 "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "default RMSE" in printed and "rad/s" in printed and "trials.parquet (6 trials)" in printed
    for name in ("trials.parquet", "best.toml", "summary.txt", "convergence.png", "study.db"):
        assert (out / name).stat().st_size > 0
    assert main(["tune", str(scenario), "--observer", "hgo", "--budget", "8", "--seeds", "2",
                 "--out", str(out), "--resume", "--quiet"]) == 0
    assert len(pd.read_parquet(out / "trials.parquet")) == 8
    assert main(["tune", str(scenario), "--observer", "hgo", "--budget", "1"]) == 2
    assert "budget must be an integer >= 2" in capsys.readouterr().err


def test_a_kalman_filter_tuned_without_truth_finds_the_sensor_variance():
    """A known optimum: a linear plant (a damped oscillator) with Gaussian noise of known
    variance; the Kalman filter (the EKF of a linear model) tuned on its NIS alone, Q held,
    recovers R within 20 % of the true variance, and its RMSE is within 5 % of the filter given
    the true variance (the Riccati-optimal one for this Q)."""
    std = 2e-3
    sc = {"plant": {"states": ["x1", "x2"], "inputs": ["u"], "f": ["x2", "-4*x1 - 0.4*x2 + u"],
                    "h": "x1", "x0": [0.5, 0.0], "dt": 0.01},
          "sensor": {"stages": [{"stage": "gaussian", "std": std}]},
          "observers": [{"type": "ekf", "name": "kf", "R": 1e-2, "Q": [1e-6, 1e-6]}],
          "input": {"type": "multisine", "amplitudes": [1.0, 0.5], "frequencies": [0.3, 0.7]},
          "run": {"duration": 60.0}}
    r = tune(sc, "kf", objective="nis", budget=40, seeds=4, space={"R[0]": (1e-7, 1e-2)},
             progress=False)
    R = r.best_parameters["R"][0, 0]
    assert abs(R / std ** 2 - 1) < 0.2, R
    st = setup(sc, "kf")
    both = evaluate(st, [r.best_parameters, {"R": np.array([[std ** 2]])}], [21, 22, 23, 24])
    rmse = np.mean(both.rmse / st.ranges, axis=(1, 2))
    assert rmse[0] <= 1.05 * rmse[1], rmse
    # and the mean NIS of the tuned filter is its expected value, one per output
    assert abs(np.mean(both.nis[0]) - 1.0) < 0.1


def test_a_plant_run_is_set_up_once_for_every_observer_and_sensor(monkeypatch):
    """setup keeps the plant's run (read-only) for the next setup of the same plant, input,
    run and initial state, whatever its observers and sensor (the benchmark sets up each task
    twice per observer, issue 28); another initial state or input runs again."""
    import hgo_mj.tune.scoring as scoring

    calls = []
    real = scoring.plant_rows
    monkeypatch.setattr(scoring, "_PLANT_RUNS", type(scoring._PLANT_RUNS)())
    monkeypatch.setattr(scoring, "plant_rows", lambda *a: calls.append(1) or real(*a))
    other = {**SC, "observers": [{"type": "finite_difference", "name": "fd"}],
             "sensor": {"stages": [{"stage": "gaussian", "std": 1e-2}]}}
    a, b = setup(SC, "hgo"), setup(other, "fd")
    assert len(calls) == 1 and a.X is b.X and not a.X.flags.writeable
    fresh = real(*[a.plant, scenario_run(dict(SC))["inputs"], a.periods, a.N,
                   np.array([[0.5, 0.0]])])
    np.testing.assert_array_equal(a.X, fresh[0])
    np.testing.assert_array_equal(a.Yc, fresh[1])
    assert evaluate(a, [{}], [1]).rmse.tolist() == evaluate(setup(SC, "hgo"), [{}], [1]).rmse.tolist()
    setup({**SC, "plant": {**SC["plant"], "x0": [0.4, 0.0]}}, "hgo")
    setup({**SC, "input": {**SC["input"], "amplitudes": [0.2]}}, "hgo")
    assert len(calls) == 3
