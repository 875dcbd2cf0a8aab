"""The study engine: every run equals the cell run alone through ``simulate``; failures are
rows; results, summary, resume, figures and the command line."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import warnings

import numpy as np
import pandas as pd
import pytest
from figure_texts import drawn_texts, text_faults

from hgo_mj.cli import main
from hgo_mj.exceptions import DesignError, DivergenceError
from hgo_mj.metrics import all_metrics
from hgo_mj.scenario import scenario_run
from hgo_mj.simulate import simulate
from hgo_mj.study import Study
from hgo_mj.study.engine import plan

BASE = {
    "name": "mixed",
    "plant": {"name": "pendulum", "dt": 0.001, "x0": [0.5, 0.0]},
    "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3},
                          {"stage": "quantize", "counts_per_rev": 4096}]},
    "observers": [
        {"type": "high_gain", "name": "hgo", "k": 20.0},
        {"type": "adaptive_gain", "name": "ad", "lam": 0.01, "lam_hat": 0.02, "gamma": 100.0,
         "k0": 5.0},
    ],
    "input": {"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]},
    "run": {"duration": 2.1, "seed": 3},  # three segments of the loop (1024 samples each)
}

MIXED = {"observers.hgo.k": [20.0, 80.0], "plant.x0": [[0.5, 0.0], [1.0, 0.0]],
         "sensor.stages.0.std": [1e-4, 1e-2]}

EXACT = ("peak", "settling_time", "final", "undefined_samples")


def _alone(cell_scenario, seed):
    """The metrics of one cell at one seed run alone through simulate, or the error."""
    warnings.simplefilter("ignore", RuntimeWarning)  # metrics of a blown-up estimate
    try:
        return all_metrics(simulate(**scenario_run(cell_scenario), seed=seed)), None
    except DivergenceError as exc:
        return None, str(exc)


@pytest.fixture(scope="module")
def mixed(tmp_path_factory):
    study = Study(BASE, MIXED, seeds=3)
    return study, study.run(tmp_path_factory.mktemp("mixed"), quiet=True)


def test_every_run_of_a_mixed_study_equals_its_cell_run_alone(mixed):
    """Gains x noise x initial states x 3 seeds, two observers: peak, settling time, final
    error and undefined samples bit for bit; the RMSE to 1e-12 (a sum per segment of 1024
    samples against numpy's pairwise mean over the whole window)."""
    study, result = mixed
    df = result.table
    assert len(df) == 8 * 3 * 2 * 2
    assert set(df["seed"]) == {3, 4, 5}
    worst = 0.0
    for cell in study.cells:
        for seed in study.spec.seeds:
            metrics, err = _alone(cell.scenario, seed)
            assert err is None
            for name, m in metrics.items():
                for j, state in enumerate(m["states"]):
                    row = df[(df.cell == cell.index) & (df.seed == seed) & (df.observer == name)
                             & (df.state == state)]
                    assert len(row) == 1
                    row = row.iloc[0]
                    for key in EXACT:
                        assert row[key] == m[key][j], (cell.values, seed, name, state, key)
                    worst = max(worst, abs(row["rmse"] - m["rmse"][j]) / m["rmse"][j])
                    for path, value in cell.values.items():
                        expect = value if isinstance(value, float) else json.dumps(
                            value, separators=(",", ":"))
                        assert row[path] == expect
    assert worst <= 1e-12


def test_a_study_shares_one_plant_run_per_initial_state():
    study = Study(BASE, MIXED, seeds=3)
    p = study.plan(jobs=1)
    assert (p.cells, p.runs, p.trajectories) == (8, 24, 2)
    # one group (one plant run for both initial states), 4 buckets (gain x noise) in it
    assert [c.n_runs for c in p.chunks] == [24]
    # four workers: two chunks each, every chunk within the group
    assert [c.n_runs for c in plan(study.cells, study.spec.seeds, jobs=4)] == [3] * 8


def test_diverging_runs_are_rows_and_the_others_are_kept(tmp_path):
    """Rare huge outliers: the seeds that meet one lose the high-gain estimate (non-finite,
    found by the metrics) and the EKF (its update raises); the other seeds and the
    high-gain observer of an EKF failure are kept, and each row equals the run alone."""
    sc = {**BASE, "sensor": {"stages": [{"stage": "outliers", "p": 0.002, "magnitude": 1e308}]},
          "observers": [{"type": "high_gain", "name": "hgo", "k": 200.0},
                        {"type": "ekf", "name": "ekf", "R": 1e-6}],
          "run": {"duration": 0.5, "seed": 0}}
    study = Study(sc, seeds=8)
    df = study.run(tmp_path / "div", quiet=True).table
    per_seed = df.groupby(["observer", "seed"])["diverged"].first()
    assert per_seed["hgo"].any() and not per_seed["hgo"].all()
    assert per_seed["ekf"].any() and not per_seed["ekf"].all()
    for seed in study.spec.seeds:
        for name in ("hgo", "ekf"):
            one = {**sc, "observers": [o for o in sc["observers"] if o["name"] == name]}
            metrics, err = _alone(one, seed)
            rows = df[(df.seed == seed) & (df.observer == name)]
            if err is not None:
                assert rows["diverged"].all()
                msg = rows["message"].iloc[0]
                assert msg.split(":")[0] in err, (msg, err)  # the same observer and cause
                assert rows["rmse"].isna().all()
            else:
                assert not rows["diverged"].any()
                assert rows["message"].isna().all()
                for j, state in enumerate(metrics[name]["states"]):
                    assert rows[rows.state == state]["peak"].iloc[0] == metrics[name]["peak"][j]


def test_results_are_parquet_that_pandas_reads_without_hgo_mj(mixed, tmp_path):
    _, result = mixed
    code = ("import sys; sys.modules['hgo_mj'] = None\n"  # any import of hgo_mj would fail
            f"import pandas as pd; df = pd.read_parquet({str(result.out / 'results.parquet')!r});"
            f"s = pd.read_parquet({str(result.out / 'summary.parquet')!r});"
            "print(len(df), len(s), sorted(df.columns)[:3])")
    out = subprocess.run([sys.executable, "-I", "-c", code], capture_output=True, text=True,
                         check=True, cwd=tmp_path).stdout
    assert out.startswith("96 32 ")


def test_the_summary_holds_the_statistics_over_seeds(mixed):
    _, result = mixed
    df, s = result.table, result.summary()
    g = df[(df.cell == 5) & (df.observer == "hgo") & (df.state == "angular_velocity")]
    row = s[(s.cell == 5) & (s.observer == "hgo") & (s.state == "angular_velocity")].iloc[0]
    v = g["rmse"].to_numpy()
    assert row["rmse_median"] == pytest.approx(np.median(v), rel=1e-15)
    assert row["rmse_iqr"] == pytest.approx(np.subtract(*np.percentile(v, [75, 25])), rel=1e-12)
    assert row["rmse_std"] == pytest.approx(np.std(v, ddof=1), rel=1e-12)
    assert row["runs"] == 3 and row["diverged_fraction"] == 0.0
    md = (result.out / "summary.md").read_text()
    assert md.startswith("# mixed") and "| observers.hgo.k | plant.x0 |" in md


def test_figures_have_units_and_one_file_per_axis(mixed, tmp_path):
    _, result = mixed
    figs = result.plot(tmp_path)
    assert len(figs) == 4  # three axes: one figure each (a heatmap only for two axes)
    names = sorted(p.name for p in tmp_path.glob("*.png"))
    assert names == ["axis_observers.hgo.k.png", "axis_plant.x0.png",
                     "axis_sensor.stages.0.std.png", "best_gain.png"]
    ax = figs[0].axes[0]
    assert ax.get_xlabel() == "observers.hgo.k [1/s]" and ax.get_xscale() == "linear"
    assert ax.get_ylabel().endswith("[rad]")
    assert figs[2].axes[0].get_xlabel() == "sensor.stages.0.std [rad]"
    assert figs[2].axes[0].get_xscale() == "log"


def test_resume_runs_only_what_is_missing(tmp_path):
    out = tmp_path / "r"
    Study(BASE, {"observers.hgo.k": [20.0, 40.0]}, seeds=2).run(out, quiet=True)
    first = pd.read_parquet(out / "results.parquet")
    lines: list[str] = []
    more = Study(BASE, {"observers.hgo.k": [20.0, 40.0]}, seeds=3)
    res = more.run(out, resume=True, echo=lines.append)
    assert "4 runs done already" in lines[0] or "(4 done already)" in lines[0]
    df = res.table
    assert len(df) == 3 * 2 * 2 * 2 and len(list((out / "results.parquet").glob("*"))) == 2
    again = Study(BASE, {"observers.hgo.k": [20.0, 40.0]}, seeds=3).run(
        tmp_path / "fresh", quiet=True).table
    cols = ["cell", "seed", "observer", "state", "rmse", "peak", "final"]
    pd.testing.assert_frame_equal(df[cols], again[cols])
    assert set(map(tuple, first[["cell", "seed"]].to_numpy())) <= set(
        map(tuple, df[["cell", "seed"]].to_numpy()))


def test_resume_into_another_study_is_refused(tmp_path):
    out = tmp_path / "r"
    Study(BASE, {"observers.hgo.k": [20.0]}, seeds=1).run(out, quiet=True)
    with pytest.raises(DesignError, match="holds another study: axes differ"):
        Study(BASE, {"observers.hgo.k": [30.0]}, seeds=1).run(out, resume=True, quiet=True)
    with pytest.raises(DesignError, match="exists: resume it with --resume"):
        Study(BASE, {"observers.hgo.k": [20.0]}, seeds=1).run(out, quiet=True)


def test_the_local_backend_with_two_processes_gives_the_same_rows(mixed, tmp_path,
                                                                  monkeypatch):
    """This process and a spawned worker share the chunks (workers start even for this short
    study here); the rows are those of one process."""
    from hgo_mj.study import backends

    monkeypatch.setattr(backends, "WORKERS_WORTH_S", 0.0)
    study, result = mixed
    two = Study(BASE, MIXED, seeds=3).run(tmp_path / "two", jobs=2, quiet=True).table
    cols = [c for c in two.columns if c != "update_time"]
    pd.testing.assert_frame_equal(two[cols], result.table[cols])


def test_progress_without_a_terminal_is_a_line_per_tenth(tmp_path):
    lines: list[str] = []
    Study(BASE, {"observers.hgo.k": [10.0, 20.0, 40.0, 80.0, 160.0]}, seeds=2).run(
        tmp_path / "p", echo=lines.append)
    assert lines[0].startswith("study: 5 cells, 10 runs, 1 distinct plant trajectory")
    assert "100% 10/10 runs" in lines[-1]
    assert 2 <= len(lines) <= 11


def test_observer_tables_as_axis_values_compare_families(tmp_path):
    sc = {**BASE, "observers": [{"type": "high_gain", "name": "est", "k": 20.0}]}
    study = Study(sc, {"observers.est": [{"type": "high_gain", "k": 40.0},
                                         {"type": "ekf", "R": 1e-6}]}, seeds=2)
    df = study.run(tmp_path / "fam", quiet=True).table
    assert set(df["observer"]) == {"est"}
    assert df["observers.est"].str.contains('"type":"ekf"').sum() == 4
    metrics, _ = _alone(study.cells[1].scenario, 3)
    row = df[(df.cell == 1) & (df.seed == 3) & (df.state == "angle")].iloc[0]
    assert row["peak"] == metrics["est"]["peak"][0]


def test_model_mismatch_through_the_observers_system_params(tmp_path):
    sc = {**BASE, "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0, "model": True}]}
    study = Study(sc, {"observers.hgo.system_params.mass": [1.0, 2.0]}, seeds=1)
    df = study.run(tmp_path / "mm", quiet=True).table
    a, b = (df[(df.cell == i) & (df.state == "angular_velocity")]["rmse"].iloc[0]
            for i in (0, 1))
    assert a != b
    metrics, _ = _alone(study.cells[1].scenario, 3)
    assert df[(df.cell == 1) & (df.state == "angle")]["peak"].iloc[0] == metrics["hgo"]["peak"][0]


@pytest.mark.parametrize("axes, seeds, mode, match", [
    ({"observers.hgx.k": [1.0]}, 1, "product", r"no observer named 'hgx'; valid: \['hgo', 'ad'\]"),
    ({"observers.hgo.kk": [1.0]}, 1, "product", r"observers.hgo has no key 'kk'; valid: .*'k'"),
    ({"sensor.stages.5.std": [1.0]}, 1, "product", r"valid indices: \[0, 1\]"),
    ({"plant.nope": [1.0]}, 1, "product", r"plant has no key 'nope'; valid: \['dt', "),
    ({"bogus.x": [1.0]}, 1, "product", r"valid first parts"),
    ({"observers.hgo.k": []}, 1, "product", "is empty"),
    ({"observers.hgo.k": 5}, 1, "product", "must be a list of values"),
    ({"observers.hgo.k": [1.0, 2.0], "sensor.stages.0.std": [1.0]}, 1, "zip",
     "zip axes must have the same length; found observers.hgo.k: 2, sensor.stages.0.std: 1"),
    ({}, 0, "product", "sweep.seeds must be between 1 and 10,000,000; found 0"),
    ({}, True, "product", "sweep.seeds must be a positive integer"),
    ({}, 1, "grid", "sweep.mode must be 'product' or 'zip'"),
    ({"observers.hgo.k": list(range(1, 101))}, 200_000, "product", "more than 10,000,000"),
])
def test_bad_studies_are_refused_before_any_work(axes, seeds, mode, match):
    with pytest.raises(DesignError, match=match):
        Study(BASE, axes, seeds, mode=mode)


def test_a_bad_value_names_its_cell(tmp_path):
    study = Study(BASE, {"observers.hgo.k": [20.0, "fast"]}, seeds=1)
    with pytest.raises(DesignError, match=r"cell 1 \(observers.hgo.k = \"fast\"\)"):
        study.run(tmp_path / "bad", quiet=True)
    assert not (tmp_path / "bad").exists()


def test_the_sweep_command(tmp_path, capsys):
    f = tmp_path / "s.toml"
    f.write_text('name = "cli"\n[plant]\nname = "pendulum"\nx0 = [0.5, 0.0]\n'
                 '[sensor]\nstages = [{stage = "gaussian", std = 1e-3}]\n'
                 '[[observers]]\ntype = "high_gain"\nname = "hgo"\nk = 20.0\n'
                 '[run]\nduration = 0.3\n'
                 '[sweep]\nseeds = 2\n"observers.hgo.k" = [10, 40]\n')
    out = tmp_path / "o"
    assert main(["sweep", str(f), "--out", str(out), "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "| observers.hgo.k |" not in text and f"the whole table: {out / 'summary.md'}" in text
    head, row = text.splitlines()[1:3]
    assert head.split()[:5] == ["observer", "state", "unit", "rmse", "median"]
    assert row.split()[:3] == ["hgo", "angle", "rad"] and "observers.hgo.k = " in row
    assert len(text.splitlines()) < 12
    assert (out / "axis_observers.hgo.k.png").stat().st_size > 10_000
    assert main(["sweep", str(f), "--out", str(out), "--quiet"]) == 2
    assert "resume it with --resume" in capsys.readouterr().err
    f.write_text(f.read_text().replace('"observers.hgo.k"', '"observers.hgo.q"'))
    assert main(["sweep", str(f), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "observers.hgo has no key 'q'" in err
    assert main(["sweep", str(tmp_path / "missing.toml")]) == 2


def test_results_hold_nothing_non_finite_that_is_not_documented(mixed):
    _, result = mixed
    df = result.table
    for col in ("rmse", "peak", "final", "update_time"):
        assert np.isfinite(df[col].to_numpy(dtype=float)).all(), col
    st = df["settling_time"].to_numpy(dtype=float)
    assert np.all(np.isfinite(st) | (st == math.inf))


CLOSED = {
    "name": "closed",
    "plant": {"name": "cart_pendulum", "dt": 0.001, "x0": [0.3, 0.0]},
    "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
    "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0},
                  {"type": "high_gain", "name": "passive", "k": 60.0}],
    "controller": {"type": "lqr", "Q": [1.0, 1.0], "R": 1.0, "observer": "hgo"},
    "run": {"duration": 1.2, "seed": 0},
}


def test_a_closed_loop_study_equals_its_runs_alone(tmp_path):
    """LQR on the estimate (or the true state), gains x initial states x seeds: every plant
    its own, stepped as one batch; each run equals simulate alone (the metrics bit for bit,
    the cost to 1e-12), with its closed-loop cost and peak input."""
    from hgo_mj.control import quadratic_cost

    study = Study(CLOSED, {"observers.hgo.k": [10.0, 40.0], "controller.source":
                           ["estimate", "true"], "plant.x0": [[0.3, 0.0], [-0.2, 0.5]]}, seeds=2)
    assert study.plan().trajectories == 16  # a closed loop: every run its own trajectory
    df = study.run(tmp_path / "cl", quiet=True).table
    for cell in study.cells:
        for seed in study.spec.seeds:
            kw = scenario_run(cell.scenario)
            traj = simulate(**kw, seed=seed)
            metrics = all_metrics(traj)
            cost = quadratic_cost(traj.x, traj.u, kw["inputs"].Q, kw["inputs"].R, 0.001)
            for name, m in metrics.items():
                rows = df[(df.cell == cell.index) & (df.seed == seed) & (df.observer == name)]
                for j, state in enumerate(m["states"]):
                    row = rows[rows.state == state].iloc[0]
                    for key in EXACT:
                        assert row[key] == m[key][j], (cell.values, seed, name, key)
                    assert row["rmse"] == pytest.approx(m["rmse"][j], rel=1e-12)
                assert (rows["cost"] == rows["cost"].iloc[0]).all()
                assert rows["cost"].iloc[0] == pytest.approx(cost, rel=1e-12)
                assert rows["peak_input"].iloc[0] == np.abs(traj.u).max()
    s = df.groupby(["observers.hgo.k", "controller.source"])["cost"].median()
    assert s[(10.0, "true")] == s[(40.0, "true")]  # the true-state loop ignores the gain
    assert s[(10.0, "estimate")] > s[(10.0, "true")]


def test_a_closed_loop_run_that_fails_is_a_row_and_the_others_are_kept(tmp_path):
    """Huge outliers blow up the estimate the controller acts on: the plant gets a non-finite
    input and stops. The seeds that meet one are diverged rows with simulate's message; the
    other seeds finish."""
    sc = {**CLOSED, "sensor": {"stages": [{"stage": "outliers", "p": 0.0006,
                                           "magnitude": 1e308}]},
          "observers": [{"type": "high_gain", "name": "hgo", "k": 200.0}]}
    study = Study(sc, seeds=8)
    df = study.run(tmp_path / "clf", quiet=True).table
    per_seed = df.groupby("seed")["diverged"].first()
    assert per_seed.any() and not per_seed.all()
    for seed, diverged in per_seed.items():
        try:
            simulate(**scenario_run(sc), seed=seed)
            alone = None
        except DivergenceError as exc:
            alone = str(exc)
        assert diverged == (alone is not None)
        if diverged:
            msg = df[df.seed == seed]["message"].iloc[0]
            assert msg.split(":")[0] in alone, (msg, alone)
            assert df[df.seed == seed]["cost"].isna().all()


def test_a_controller_and_an_input_are_refused_together():
    with pytest.raises(DesignError, match=r"an \[input\] signal or a \[controller\], not both"):
        scenario_run({**CLOSED, "input": {"type": "constant", "value": [0.0]}})
    with pytest.raises(DesignError, match=r"unknown controller 'pid'; valid: \['lqr'\]"):
        scenario_run({**CLOSED, "controller": {"type": "pid"}})
    with pytest.raises(DesignError, match="controller has no key 'gain'"):
        Study(CLOSED, {"controller.gain": [1.0]})


def test_axes_together_advance_as_one(tmp_path):
    """Two plants, each with its own initial state, as one axis of the product with the gain."""
    sc = {**BASE, "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
          "input": {"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]},
          "run": {"duration": 0.5, "seed": 0}}
    study = Study(sc, {"observers.hgo.k": [10.0, 40.0]}, seeds=1, together=[
        {"plant.name": ["pendulum", "elastic_joint"],
         "plant.x0": [[0.5, 0.0], [0.3, 0.3, 0.0, 0.0]]}])
    assert [c.values for c in study.cells] == [
        {"observers.hgo.k": k, "plant.name": p, "plant.x0": x} for k in (10.0, 40.0)
        for p, x in (("pendulum", [0.5, 0.0]), ("elastic_joint", [0.3, 0.3, 0.0, 0.0]))]
    result = study.run(tmp_path / "tog", quiet=True)
    assert set(result.table["plant.name"]) == {"pendulum", "elastic_joint"}
    assert result.plot_axes == ["observers.hgo.k", "plant.name"]
    metrics, _ = _alone(study.cells[3].scenario, 0)
    row = result.table[(result.table.cell == 3) & (result.table.state == "motor_velocity")]
    assert row["peak"].iloc[0] == metrics["hgo"]["peak"][3]
    with pytest.raises(DesignError, match="must have the same length"):
        Study(sc, together=[{"plant.name": ["pendulum"], "plant.x0": [[0.5, 0.0], [1.0, 0.0]]}])
    with pytest.raises(DesignError, match=r"given twice: \['plant.name'\]"):
        Study(sc, {"plant.name": ["pendulum"]}, together=[{"plant.name": ["pendulum"]}])


def test_an_interrupted_study_keeps_its_finished_chunks_and_resumes(tmp_path, monkeypatch):
    """Ctrl-C after two chunks: their partitions are whole and readable, nothing half-written
    is left, and --resume runs only the rest; the result equals an uninterrupted study."""
    from hgo_mj.study import backends, engine

    real, calls = engine.run_chunk, []

    def flaky(chunk):
        calls.append(chunk.id)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(chunk)

    monkeypatch.setattr(backends, "run_chunk", flaky)
    axes = {"run.duration": [0.3, 0.4, 0.5, 0.6]}  # four plant runs: four chunks
    study = Study(BASE, axes, seeds=2)
    out = tmp_path / "int"
    with pytest.raises(KeyboardInterrupt):
        study.run(out, quiet=True)
    parts = sorted((out / "results.parquet").glob("*"))
    assert len(parts) == 2 and all(p.suffix == ".parquet" for p in parts)
    assert len(pd.read_parquet(out / "results.parquet")) == 2 * 2 * 2 * 2
    monkeypatch.setattr(backends, "run_chunk", real)
    done = study.run(out, resume=True, quiet=True).table
    whole = Study(BASE, axes, seeds=2).run(tmp_path / "whole", quiet=True).table
    cols = ["cell", "seed", "observer", "state", "rmse", "peak", "settling_time", "final"]
    pd.testing.assert_frame_equal(done[cols], whole[cols])


@pytest.mark.parametrize("sweep, extra, message", [
    ('"observers.hgo.kk" = [1.0]', [], "observers.hgo has no key 'kk'"),
    ('"observers.hgo.k" = []', [], "is empty"),
    ('"observers.hgo.k" = ["x"]', [], "cell 0 (observers.hgo.k = \"x\")"),
    ('mode = "zip"\n"observers.hgo.k" = [1.0, 2.0]\n"run.duration" = [0.1]', [],
     "zip axes must have the same length"),
    ('seeds = 100000\n"observers.hgo.k" = ' + str([float(k) for k in range(1, 101)]) +
     '\n"run.duration" = ' + str([0.1 + i for i in range(2)]), [], "confirm with --yes"),
    ('"observers.hgo.k" = [1.0]', ["--backend", "ray", "--address", "nowhere"],
     "--address must be HOST:PORT"),
    # found by the study fuzz (tests/test_fuzz_scenarios.py): a MemoryError, an array of
    # 1.4 PiB, a study.json that could not be written
    ("seeds = 1000000000000", [], "sweep.seeds must be between 1 and 10,000,000; found "
                                  "1,000,000,000,000"),
    ('"run.duration" = [1000000000000.0]', [], "holds 1e+15 rows of the plant, about"),
    ('"observers.hgo.k" = [1979-05-27]', [], "values must be numbers, strings, booleans or "
                                             "lists and tables of them; found datetime.date"),
])
def test_bad_studies_on_the_command_line_are_one_line_and_leave_nothing(
        sweep, extra, message, tmp_path, capsys):
    f = tmp_path / "s.toml"
    f.write_text('[plant]\nname = "pendulum"\n[[observers]]\ntype = "high_gain"\nname = "hgo"\n'
                 f'k = 20.0\n[run]\nduration = 0.2\n[sweep]\n{sweep}\n')
    out = tmp_path / "o"
    assert main(["sweep", str(f), "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hgo-mj: error:") and message in err, err
    assert len(err.strip().splitlines()) == 1 and not out.exists()


def test_ray_not_installed_names_the_extra(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    f = tmp_path / "s.toml"
    f.write_text('[plant]\nname = "pendulum"\n[run]\nduration = 0.1\n')
    assert main(["sweep", str(f), "--out", str(tmp_path / "o"), "--backend", "ray"]) == 2
    err = capsys.readouterr().err
    assert "--backend ray needs the optional dependency ray: pip install 'hgo_mj[ray]'" in err
    assert not (tmp_path / "o").exists()


def test_stored_cells_keep_their_trajectories_as_npz(tmp_path):
    """store = [{path: value}]: the runs of the matching cells are also kept, each the cell run
    alone through simulate; the others are not."""
    from hgo_mj.simulate import Trajectory

    study = Study(BASE, {"observers.hgo.k": [20.0, 80.0]}, seeds=2,
                  store=[{"observers.hgo.k": 80.0}])
    out = tmp_path / "st"
    study.run(out, quiet=True)
    files = sorted(p.name for p in (out / "trajectories").glob("*.npz"))
    assert files == ["cell1_seed3.npz", "cell1_seed4.npz"]
    traj = Trajectory.load(out / "trajectories" / "cell1_seed4.npz")
    alone = simulate(**scenario_run(study.cells[1].scenario), seed=4)
    np.testing.assert_array_equal(traj.observers["hgo"].x_hat, alone.observers["hgo"].x_hat)
    with pytest.raises(DesignError, match="store filter names 'plant.x0', which is not an axis"):
        Study(BASE, {"observers.hgo.k": [20.0]}, store=[{"plant.x0": [0.5, 0.0]}])


def test_many_facets_are_pooled_and_every_plant_gives_its_units(tmp_path, monkeypatch):
    """A facet per observer, value of the other axes and state (the plant group is a facet:
    each plant has its own states), one line per noise level against the gain; beyond
    MAX_FACETS facets the other axes are pooled, said in the title; each state's unit comes
    from the plant that has it."""
    from hgo_mj.study import figures

    sc = {**BASE, "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
          "run": {"duration": 0.3, "seed": 0}}
    study = Study(sc, {"observers.hgo.k": [10.0, 40.0], "sensor.stages.0.std": [1e-4, 1e-3,
                                                                               1e-2]},
                  seeds=1, together=[{"plant.name": ["pendulum", "elastic_joint"],
                                      "plant.x0": [[0.5, 0.0], [0.3, 0.3, 0.0, 0.0]]}])
    result = study.run(tmp_path / "pool", quiet=True)
    k_fig = result.plot()[0]  # against the gain: a line per noise level
    assert [t.get_text() for t in k_fig.legends[0].get_texts()] == [
        "std = 0.0001", "std = 0.001", "std = 0.01"]
    titles = [ax.get_title() for ax in k_fig.axes[::3]]
    assert titles[0] == "hgo, plant = pendulum, angle" and len(titles) == 2 + 4
    assert "pooled" not in k_fig._suptitle.get_text()
    ylabels = {ax.get_title(): ax.get_ylabel() for ax in k_fig.axes[::3]}
    assert ylabels["hgo, plant = elastic_joint, motor_velocity"].endswith("[rad/s]")
    assert ylabels["hgo, plant = pendulum, angle"].endswith("[rad]")
    monkeypatch.setattr(figures, "MAX_FACETS", 4)
    fig = figures.axis_figure(result, "observers.hgo.k")
    assert "pooled over plant.name" in fig._suptitle.get_text()
    assert [ax.get_title() for ax in fig.axes[::3]][:2] == ["hgo, angle", "hgo, angular_velocity"]


def test_a_closed_loops_chunks_are_bounded_by_its_kept_errors():
    """A closed loop keeps every member's errors until the end: its chunks hold at most
    CLOSED_VALUES member-samples; an open loop's are not bounded that way."""
    from hgo_mj.study.engine import CLOSED_VALUES

    study = Study({**CLOSED, "run": {"duration": 10.0, "seed": 0}}, seeds=1024)
    sizes = [c.n_runs for c in study.plan().chunks]
    assert sum(sizes) == 1024 and max(sizes) * 10001 <= CLOSED_VALUES
    assert [c.n_runs for c in Study({**BASE, "run": {"duration": 10.0}}, seeds=1024).plan(
    ).chunks] == [1024]


# ------------------------------------------------ issue 27 item 5: overlapping, useless axes
OVERLAP_BASE = {"plant": {"name": "pendulum", "dt": 0.01},
                "observers": [{"type": "high_gain", "name": "k20", "k": 20.0}],
                "run": {"duration": 0.2, "seed": 3}}


@pytest.mark.parametrize("sweep, message", [
    ({"observers.k20": [{"type": "high_gain", "k": 5.0}], "observers.k20.k": [1.0]},
     r"sweep axes 'observers.k20' and 'observers.k20.k' overlap"),
    ({"observers.k20.k": [1.0], "observers.k20": [{"type": "high_gain", "k": 5.0}]},
     r"sweep axes 'observers.k20' and 'observers.k20.k' overlap"),
    ({"together": [{"run": [{"duration": 0.2}], "run.duration": [0.3]}]},
     r"sweep axes 'run' and 'run.duration' overlap"),
    ({"run.seed": [1, 2]}, r"'run.seed' cannot change a run: .*\[sweep\] seeds = N"),
    ({"run.out": ["a", "b"]}, r"'run.out' cannot change a run: .*--out"),
    ({"run.stream": [True, False]}, r"'run.stream' cannot change a run"),
])
def test_overlapping_or_useless_axes_are_refused(sweep, message):
    from hgo_mj.study.spec import parse_study

    with pytest.raises(DesignError, match=message):
        parse_study({**OVERLAP_BASE, "sweep": sweep})


def test_summary_spread_of_no_finished_run_is_nan_not_zero():
    """Issue 27 item 6: a cell whose runs all diverged has NaN statistics, its std included."""
    import numpy as np
    import pandas as pd

    from hgo_mj.study.results import summarize

    df = pd.DataFrame({"cell": [0, 0, 1], "seed": [0, 1, 0], "observer": "hgo",
                       "state": "angle", "estimated": True, "rmse": [np.nan, np.nan, 0.1],
                       "peak": 0.5, "settling_time": [np.nan, np.nan, 0.2], "final": 0.01,
                       "diverged": [True, True, False]})
    s = summarize(df, [])
    assert np.isnan(s["rmse_mean"].iloc[0]) and np.isnan(s["rmse_std"].iloc[0])
    assert s["rmse_std"].iloc[1] == 0.0


def test_the_time_estimate_counts_each_family_by_its_measured_cost():
    """Issue 27 item 7: an EKF study is planned as slower than the same high-gain study (its
    warm cost per update is measured), so --jobs is not silently one process. The serial
    estimate is the updates (2 x 4 runs of 200 and 300 samples) times the family's measured
    cost, so the ratio of the two plans is the ratio of the EKF's measured cost to the
    high-gain one's (floored at _OBSERVER_STEP_S); one cost for every family would give 1.
    The EKF measured 2.4x (3 runs, the lead's machine) to 3.1-4.6x (loaded 2-core machine):
    the bound is 1.5x, a timing ratio with room for the machine's load."""
    base = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.5, 0.0]},
            "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
            "run": {"duration": 2.0}}
    hgo = Study({**base, "observers": [{"type": "high_gain", "name": "o", "k": 20.0}]},
                {"run.duration": [2.0, 3.0]}, seeds=4)
    ekf = Study({**base, "observers": [{"type": "ekf", "name": "o"}]},
                {"run.duration": [2.0, 3.0]}, seeds=4)
    for s in (hgo, ekf):
        s.validate()
    for s in (hgo, ekf):
        (cost,) = s._family_cost.values()
        assert s.plan().serial_s == pytest.approx(2000 * cost, rel=1e-12)
    assert ekf.plan().serial_s > 1.5 * hgo.plan().serial_s
    assert set(ekf._family_cost) and all(c > 0 for c in ekf._family_cost.values())


def test_a_study_too_large_for_memory_is_refused_even_with_yes(monkeypatch):
    """Issue 27 item 12: the size and memory of a study are estimated before any cell is
    built, and the memory bound holds without max_runs (--yes)."""
    import hgo_mj.simulate
    from hgo_mj.study.spec import parse_study, study_memory

    doc = {**OVERLAP_BASE, "sweep": {"seeds": 100,
                                     "observers.k20.k": [float(i + 1) for i in range(100_000)]}}
    monkeypatch.setattr(hgo_mj.simulate, "available_memory", lambda: 2.0**30)
    with pytest.raises(DesignError, match=r"10,000,000 runs .* would hold about [\d.]+ GiB .* "
                                          r"found 1 GiB .*a bound --yes keeps"):
        parse_study(doc, max_runs=None)
    small = parse_study({**OVERLAP_BASE, "sweep": {"observers.k20.k": [1.0, 2.0]}})
    assert 0 < study_memory(small) < 2**20


def test_validate_keeps_no_plant_per_cell():
    """The check of every cell builds each distinct one and lets it go (100,000 MuJoCo plants
    held at once did not fit)."""
    import gc
    import weakref

    from hgo_mj.plants.mujoco import MujocoPlant as Plant

    seen = []
    original = Plant.__init__

    def tracked(self, *a, **kw):
        original(self, *a, **kw)
        seen.append(weakref.ref(self))

    study = Study(OVERLAP_BASE, {"observers.k20.k": [float(i + 1) for i in range(20)]})
    Plant.__init__ = tracked
    try:
        study.validate()
    finally:
        Plant.__init__ = original
    gc.collect()
    assert len(seen) >= 20 and sum(r() is not None for r in seen) <= 2


def test_study_figures_answer_the_gain_noise_question(tmp_path):
    """Each metric against each axis with one line per value of the next axis and a facet per
    observer, value of the other axes and state; an axis that changes the states
    (plant.name) is a facet, not an x-axis; the best gain per noise level with its fitted
    power law (best_gain.png), drawn on the user's axes on request."""
    from hgo_mj.plotting import subplots
    from hgo_mj.study.figures import axis_figure, best_gain, best_gain_figure, best_gains, varying_axes

    sc = {"name": "gn", "plant": {"name": "pendulum", "dt": 0.002},
          "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
          "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
          "input": {"type": "multisine", "amplitudes": [0.8, 0.3], "frequencies": [0.4, 1.5]},
          "run": {"duration": 3.0, "t_transient": 1.0}}
    axes = {"plant.name": ["pendulum", "elastic_joint"],
            "observers.hgo.k": [5.0, 20.0, 80.0, 320.0, 1280.0],
            "sensor.stages.0.std": [1e-5, 1e-3, 1e-2]}
    result = Study(sc, axes, seeds=2).run(tmp_path / "gn", quiet=True)
    assert varying_axes(result) == ["observers.hgo.k", "sensor.stages.0.std"]
    names = sorted(p.name for p in (tmp_path / "gn").glob("*.png"))
    assert names == []  # Study.run writes no figure; plot does
    figs = result.plot(tmp_path / "figs")
    assert sorted(p.name for p in (tmp_path / "figs").glob("*.png")) == [
        "axis_observers.hgo.k.png", "axis_sensor.stages.0.std.png", "best_gain.png"]
    fig = figs[0]
    panels = [ax for ax in fig.axes if ax.get_visible()]
    assert len(panels) == 3 * 6  # rmse, peak, settling x (2 + 4 states of the two plants)
    assert panels[0].get_title() == "hgo, plant = pendulum, angle"
    assert [ln.get_label() for ln in panels[0].get_lines()] == [
        "std = 1e-05", "std = 0.001", "std = 0.01"]
    assert [t.get_text() for t in fig.legends[0].get_texts()] == [
        "std = 1e-05", "std = 0.001", "std = 0.01"]
    assert [ln.get_label() for ln in figs[1].axes[0].get_lines()][:2] == ["k = 5", "k = 20"]
    bg = best_gains(result)
    s = result.summary()
    for _, r in bg.iterrows():  # k* is best_gain of that noise level's RMSE over the gains
        g = s[(s["observer"] == "hgo") & (s["state"] == r["state"])
              & (s["plant.name"] == r["plant.name"])
              & (s["sensor.stages.0.std"] == r["sigma"])].sort_values("observers.hgo.k")
        assert (r["k_star"], r["interior"]) == best_gain(g["observers.hgo.k"], g["rmse_median"])
    pend = bg[(bg["plant.name"] == "pendulum") & (bg["state"] == "angle")]
    assert pend["order"].iloc[0] == 2 and -0.8 < pend["slope"].iloc[0] < -0.3
    fit = [ln.get_label() for ln in figs[2].axes[0].get_lines()]
    assert any(lb.startswith("fit k* ~ sigma^") for lb in fit) and any(
        lb.startswith("theory sigma^-0.50") for lb in fit)
    mine, grid = subplots(1, 6)
    assert best_gain_figure(result, axes=grid) is mine
    mine, grid = subplots(6, 3)
    assert axis_figure(result, "observers.hgo.k", axes=grid) is mine
    with pytest.raises(DesignError, match="axis must be one of"):
        axis_figure(result, "plant.name")


def test_sweep_of_the_shipped_gain_noise_study_draws_the_best_gain_of_its_table(
        tmp_path, monkeypatch, capsys):
    """`hgo-mj sweep studies/gain_noise.toml --seeds 1` writes best_gain.png, whose points are
    the best gain per noise level of the written summary (the grid minimum of the median RMSE
    refined by the parabola through it and its neighbours in log-log; hollow at the grid's
    edge) and whose fitted line is the least-squares power law of the filled points, as
    printed."""
    from pathlib import Path

    import hgo_mj.study.figures as figures

    saved = {}
    original = figures.save_figure

    def spy(fig, path):
        saved[Path(path).name] = fig
        return original(fig, path)

    monkeypatch.setattr(figures, "save_figure", spy)
    study = Path(__file__).resolve().parents[2] / "studies" / "gain_noise.toml"
    out = tmp_path / "gn"
    assert main(["sweep", str(study), "--seeds", "1", "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert (out / "best_gain.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    fig = saved["best_gain.png"]
    s = pd.read_parquet(out / "summary.parquet")
    s = s[(s["observer"] == "hgo") & s["estimated"]]
    panels = [ax for ax in fig.axes if ax.get_visible()]
    assert len(panels) == 2 + 4  # the states of the pendulum and of the elastic joint
    for ax in panels:
        plant, state = ax.get_title().removeprefix("plant = ").split(", ")
        lines = {ln.get_label(): ln for ln in ax.get_lines()}
        drawn = {}
        for label, interior in (("k* inside the grid", True), ("k* at the grid's edge", False)):
            if label in lines:
                for x, y in zip(*lines[label].get_data()):
                    drawn[float(x)] = (float(y), interior)
        g = s[(s["plant.name"] == plant) & (s["state"] == state)]
        expected = {}
        for sigma, h in g.groupby("sensor.stages.0.std"):
            h = h.sort_values("observers.hgo.k")
            k, e = h["observers.hgo.k"].to_numpy(), h["rmse_median"].to_numpy()
            i = int(np.argmin(e))
            if i in (0, len(k) - 1):
                expected[float(sigma)] = (k[i], False)
                continue
            x, y = np.log(k[i - 1:i + 2]), np.log(e[i - 1:i + 2])
            # the vertex of the parabola through three points (Lagrange form)
            num = (x[0] ** 2 * (y[1] - y[2]) + x[1] ** 2 * (y[2] - y[0])
                   + x[2] ** 2 * (y[0] - y[1]))
            den = x[0] * (y[1] - y[2]) + x[1] * (y[2] - y[0]) + x[2] * (y[0] - y[1])
            expected[float(sigma)] = (np.exp(np.clip(num / (2 * den), x[0], x[2])), True)
        assert sorted(drawn) == sorted(expected) == [1e-5, 1e-4, 1e-3, 1e-2]
        for sigma, (k_star, interior) in expected.items():
            assert drawn[sigma][1] == interior, (plant, state, sigma)
            assert drawn[sigma][0] == pytest.approx(k_star, rel=1e-9), (plant, state, sigma)
        inner = [(sg, k) for sg, (k, ok) in drawn.items() if ok]
        slope = np.polyfit(np.log([a for a, _ in inner]), np.log([b for _, b in inner]), 1)[0]
        fit = next(ln for label, ln in lines.items() if label.startswith("fit k* ~ sigma^"))
        fx, fy = (np.log(np.asarray(v, dtype=float)) for v in fit.get_data())
        assert (fy[-1] - fy[0]) / (fx[-1] - fx[0]) == pytest.approx(slope, rel=1e-9)
        assert f"hgo, plant.name = {plant}, {state}: k* ~ sigma^{slope:.2f}" in printed


@pytest.fixture(scope="module")
def gain_noise_figures(tmp_path_factory):
    """The figures of a two-axis gain x noise study of two observers: the axis figures, the
    heatmap (four panels, three a row, logarithmic colour bars) and the best gain."""
    sc = {"name": "gn2", "plant": {"name": "pendulum", "dt": 0.002},
          "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
          "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0},
                        {"type": "adaptive_gain", "name": "adaptive", "lam": 1e-3,
                         "lam_hat": 5e-3, "gamma": 1e7, "k0": 5.0, "k_max": 5000.0}],
          "input": {"type": "multisine", "amplitudes": [0.8, 0.3], "frequencies": [0.4, 1.5]},
          "run": {"duration": 2.0, "t_transient": 1.0}}
    axes = {"observers.hgo.k": [5.0, 20.0, 80.0, 320.0, 1280.0],
            "sensor.stages.0.std": [1e-5, 1e-3, 1e-2]}
    import hgo_mj.study.figures as figures

    out = tmp_path_factory.mktemp("gn2")
    result = Study(sc, axes).run(out / "run", quiet=True)
    saved = {}
    original = figures.save_figure
    with pytest.MonkeyPatch.context() as mp:  # each figure by the name it is saved under
        mp.setattr(figures, "save_figure", lambda fig, path: (
            saved.__setitem__(path.name, fig), original(fig, path))[1])
        result.plot(out)
    return saved


def test_study_figure_texts_stay_inside_the_figure_and_apart(gain_noise_figures):
    """Titles, axis and colour-bar labels, tick labels and legends: none reaches outside the
    figure (the heatmap's colour-bar label was cut at the right edge), none overlaps another."""
    names = sorted(gain_noise_figures)
    assert names == ["axis_observers.hgo.k.png", "axis_sensor.stages.0.std.png",
                     "best_gain.png", "heatmap_observers.hgo.k__sensor.stages.0.std.png"]
    for name, fig in gain_noise_figures.items():
        assert text_faults(fig) == [], name


def test_best_gain_tick_labels_are_the_size_of_the_other_figures(gain_noise_figures):
    """Every drawn tick label of best_gain.png, the minor ones (200, 500) too, is the size of
    the axis figures' tick labels."""
    def sizes(fig):
        ticks = {id(t) for ax in fig.axes for axis in (ax.xaxis, ax.yaxis)
                 for t in axis.get_ticklabels(which="both")}
        return {t.get_fontsize() for t, _ in drawn_texts(fig) if id(t) in ticks}

    reference = sizes(gain_noise_figures["axis_observers.hgo.k.png"])
    assert reference == {7.0}
    assert sizes(gain_noise_figures["best_gain.png"]) == reference
