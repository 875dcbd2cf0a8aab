"""The benchmark (hgo_mj.bench, ``hgo-mj bench``): frozen task versions, scores checked
against hand computations, a user's observer and task on the leaderboard, resume, bad input."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from hgo_mj.bench import SUITES, TASKS, bench, bootstrap_ci, load_task, preset, task_hash, tasks_of
from hgo_mj.bench.scores import leaderboard, score_rows
from hgo_mj.bench.tasks import SUPERSEDED
from hgo_mj.cli import main
from hgo_mj.exceptions import DesignError, DimensionError

#: every task version's hash: a change of a task's definition must be a new version
FROZEN = {
    "pendulum/encoder-v1":
        "1025bf0105e72d027ec4644a1375ea54b6af82679049d9982ce85d6aac4a442d",
    "pendulum/mems-v1":
        "162f3efe264a23f05ef52e7b2f628468a13112ff5181ea329714ac519dfd8597",
    "pendulum/vision-v1":
        "61d2c951e7426eddb1769b3ffb93df8e5f562fdc3efd286bb55d39ee22b5977e",
    "pendulum/analog-v1":
        "4cdf4967e532890be5cc6717159dacb777e416b3f3ef2cb477d2557394d33a49",
    "pendulum/encoder-mismatch-v1":
        "e8d2d6afae3c68ca76497440d76ee03d91fd3850685f64a81716beeed192fa5d",
    "pendulum/encoder-sampled-v1":
        "d5354f96df0e50c9fb817480214f366ad1e3be21825d4954d044bf176b8e5114",
    "cart_pendulum/encoder-v1":
        "bd2b2e5ffbbb92c6891ac1b9c9551313927e2da16d53c7b2a64a9a0b829591c3",
    "elastic_joint/encoder-v1":
        "ec75b60dd36df67d1c44d13e50c4589b02bcf794b2d44759bd8e3379979fd20a",
    "elastic_joint/mems-v1":
        "ba1641743fba3414b3d8f235598aa1fe74a32035f3cb6378208538efcdaf1299",
    "elastic_joint/encoder-mismatch-v1":
        "48eae929ad1b061f895aaa51602d3e95cbc0f3e7fed9236ea6230642a0b498e0",
    "elastic_joint_2link/encoder-v1":
        "5081b8313c9a7ff891f55d7302bb758652b5e61fb3cf4922874b28dfa2746813",
    "bioreactor_bullinger/analog-v1":
        "01fb95b6b4b5b6b055c2d428cf35b7e4373dfefca0407048fb3f89994160947f",
    "bioreactor_bastin_gevers/analog-v1":
        "da7f03a86eb3285ba806bc837744343e64bc2ccd396a5ba628195c4c04abbd8a",
    "besancon_ex1/analog-v1":
        "be0b101c2fd3da422294bb01d6d46b2a7dbc00801c6b6898113d74d8c5cdb2e6",
    "jo_son/analog-v1":
        "458a9cbc46d8734ca10ed7a529c08524b404babbbffef9005017f707847702e8",
    "cart_pendulum/vision-v1":
        "4cb7dc7529e69c004ab0be168314355c0f5d143b35d5a341c9afa635d126f6ea",
    "pendulum/encoder-mismatch-v2":
        "1d3c423607d0b149d29c66428c91dda5e0a8cf4807ee4c01c40a7848c6e2cd19",
    "elastic_joint/encoder-mismatch-v2":
        "56e3e8b9b37efd4ba4daa63301bc608be5bf4fcd51c3a4214ef4b8e613493453",
    "elastic_joint_2link/encoder-v2":
        "03ef3ae9aae45b04e03c90268ef1d7f08e59ed7fc60853cd74b3c1c196bbc264",
    "pendulum/encoder-friction-v1":
        "af9ac561f061bc840c816c24ac0f25468f87bac2a439cbe62a3aca0063e48848",
    "furuta/encoder-v1":
        "1a0266b879bb3bfd69040eab179ee368cfa5ef552402c4660c3727cdd8ad80fd",
    "acrobot/encoder-v1":
        "1947702885a1cc73d9a686b17a92f886436f29f4f0f79f01e45773d4a77cc5b6",
    "cart_pole/encoder-v1":
        "fcfb04733fde4f044ed1961c1d2a7f6f2bf5296bc22241c0a2143415f46d18e3",
}


def test_task_versions_are_frozen():
    assert {n: task_hash(t) for n, t in TASKS.items()} == FROZEN
    assert len(TASKS) >= 16 and len(tasks_of("quick")) in range(4, 7)
    for t in TASKS.values():
        assert not set(t.tuning_seeds) & set(t.scoring_seeds)
        assert t.name.rsplit("-v", 1)[1].isdigit() and t.description


def test_the_full_suite_spans_the_plants_sensors_and_tiers():
    plants = {t.plant["name"] for t in TASKS.values()}
    assert {"pendulum", "cart_pendulum", "elastic_joint", "elastic_joint_2link",
            "bioreactor_bullinger", "bioreactor_bastin_gevers", "besancon_ex1",
            "jo_son", "furuta", "acrobot", "cart_pole"} <= plants
    assert {t.sensor for t in TASKS.values()} == {"encoder", "mems", "vision", "analog"}
    assert any(t.mismatch for t in TASKS.values())
    assert any(t.sample_period for t in TASKS.values())
    full = [TASKS[n] for n in SUITES["full"]]
    assert len(full) >= 16 and not set(SUPERSEDED) & set(SUITES["full"])
    assert all(SUPERSEDED[n] in SUITES["full"] for n in SUPERSEDED)
    # the mismatch tier reaches the MJCF filters, the friction tier is in the plant
    assert all(t.model_fields for t in full if t.mismatch)
    assert any("dof_frictionloss" in str(t.plant.get("model_fields")) for t in full)


def test_every_task_of_the_full_suite_runs_its_plant():
    """Each task's plant, input and sensor run together (elastic_joint_2link/encoder-v1 gave
    the two-input arm a one-channel input, so every observer of it failed: superseded)."""
    from hgo_mj.scenario import scenario_run
    from hgo_mj.simulate import simulate

    for name in SUITES["full"]:
        r = scenario_run({**TASKS[name].scenario(), "observers": []})
        res = simulate(r["plant"], r["sensor"], {}, r["inputs"], duration=0.01)
        assert np.isfinite(res.x).all(), name
    r = scenario_run({**TASKS["elastic_joint_2link/encoder-v1"].scenario(), "observers": []})
    with pytest.raises(DimensionError, match="2 channel"):
        simulate(r["plant"], r["sensor"], {}, r["inputs"], duration=0.01)


def test_a_field_added_later_leaves_the_old_hashes_alone():
    import dataclasses

    t = TASKS["pendulum/encoder-v1"]
    assert task_hash(dataclasses.replace(t, model_fields={})) == FROZEN[t.name]
    assert task_hash(dataclasses.replace(t, model_fields={"dof_damping[hinge]": 0.02})) != (
        FROZEN[t.name])


def test_the_mjcf_filters_get_the_tasks_wrong_model_and_are_refused_without_it():
    """On the v2 mismatch task the MuJoCo EKF's copy of the MJCF holds the task's wrong
    values; on v1 (system_params only, which do not reach an MJCF) it is not applicable,
    with the reason, instead of silently stepping the true model."""
    from hgo_mj.bench.runner import observer_spec, run_task_observer
    from hgo_mj.scenario import scenario_run

    t = TASKS["pendulum/encoder-mismatch-v2"]
    spec = {**observer_spec("ekf_mujoco", "pendulum", "ekf_mujoco"),
            "system_params": t.mismatch, "model_fields": t.model_fields}
    ob = scenario_run({**t.scenario(), "observers": [spec]})["observers"]["ekf_mujoco"]
    m = ob.model.m
    assert m.body_mass[1] == 0.275 and m.dof_damping[0] == 0.011
    assert np.allclose(m.body_inertia[1], t.model_fields["body_inertia[pole]"])
    old = run_task_observer(TASKS["pendulum/encoder-mismatch-v1"], "ekf_mujoco", 2)
    assert old["status"] == "not applicable" and "do not reach the MJCF" in old["reason"]


def test_the_encoder_presets_noise_is_its_quantization_and_noise():
    stages, std = preset("encoder", {"counts_per_rev": 2048, "noise": 0.0})
    assert std == pytest.approx(2 * math.pi / 2048 / math.sqrt(12))
    stages, std = preset("mems", {"noise_density": 1e-3, "sample_rate": 200.0})
    assert std == pytest.approx(1e-3 * math.sqrt(100.0))
    assert [s["stage"] for s in stages] == ["gaussian", "drift", "delay"]


def test_a_bootstrap_interval_covers_the_mean_about_95_percent_of_the_time():
    rng = np.random.default_rng(0)
    covered = 0
    for i in range(200):
        x = rng.normal(3.0, 1.0, 20)
        m, lo, hi = bootstrap_ci(x, seed=i)
        assert lo <= m <= hi and m == pytest.approx(x.mean())
        covered += lo <= 3.0 <= hi
    assert 0.88 <= covered / 200 <= 0.99
    assert bootstrap_ci([1.0, math.inf]) [0] == math.inf
    assert bootstrap_ci([2.0]) == (2.0, 2.0, 2.0)


def _part(task, observer, rmse, iae=0.1):
    S = len(rmse)
    return {"task": task, "hash": "h", "observer": observer, "status": "scored",
            "states": ["angle", "angular_velocity"], "units": ["rad", "rad/s"],
            "output_unit": "rad", "ranges": [1.0, 4.0], "sensor_std": 0.01,
            "parameters": {"k": 1.0}, "tune_seconds": 0.1, "certified_period": None,
            "default": None,
            "tuned": {"rmse": [[r, 4 * r] for r in rmse], "peak": [[1.0, 4.0]] * S,
                      "settling": [[0.1, None]] * S, "iae": [iae] * S, "peaking": [1.0] * S,
                      "nis": [None] * S, "diverged": [not math.isfinite(r) for r in rmse],
                      "message": [None] * S, "update_time": 1e-7, "n_states": 2}}


def test_scores_and_ranks_by_hand():
    """Normalized RMSE = RMSE / range; noise amplification = RMSE / sensor std; the rank by
    normalized RMSE, ties by the transient; the overall rank the mean normalized rank."""
    parts = [_part("a-v1", "x", [0.02, 0.04]), _part("a-v1", "y", [0.01, 0.01]),
             _part("a-v1", "z", [0.01, 0.01], iae=0.05),
             _part("b-v1", "x", [0.01, 0.01]), _part("b-v1", "y", [math.inf, 0.01]),
             {"task": "b-v1", "hash": "h", "observer": "z", "status": "not applicable",
              "reason": "needs a form"}]
    rows = score_rows(parts, {"a-v1": [1, 2], "b-v1": [1, 2]})
    r0 = next(r for r in rows if r["task"] == "a-v1" and r["observer"] == "x"
              and r["state"] == "angular_velocity" and r["seed"] == 1)
    assert r0["rmse_norm"] == pytest.approx(0.08 / 4.0)
    assert r0["noise_amplification"] == pytest.approx(0.08 / 0.01)
    assert r0["noise_amplification_unit"] == "rad/s / rad" and r0["settling"] == math.inf
    board = leaderboard(rows, parts)
    a = board[board["task"] == "a-v1"].set_index("observer")
    assert a.loc["x", "rmse_norm"] == pytest.approx(np.mean([0.02, 0.04]))
    assert list(a.sort_values("rank").index) == ["z", "y", "x"]  # y and z tie, z's transient
    b = board[board["task"] == "b-v1"].set_index("observer")
    assert b.loc["y", "divergence_rate"] == 0.5 and b.loc["y", "rank"] == 2
    assert b.loc["z", "status"] == "not applicable"
    ov = board[board["task"] == "overall"].set_index("observer")
    assert ov.loc["z", "normalized_rank"] == 0.0 and ov.loc["x", "normalized_rank"] == 0.5


USER_OBSERVER = '''
import numpy as np
from hgo_mj.observers.base import Dimension, Observer


class Hold(Observer):
    """The last valid measurement with its backward difference (a user's observer)."""

    name = "user_hold"

    def __init__(self, system=None, *, gain=1.0, outputs=(0,)):
        super().__init__(system, outputs=outputs)
        self.gain = float(gain)

    def _parameters(self):
        return {"gain": self.gain}

    def _init(self, p, x0, z0, u0):
        return {"z": np.zeros((u0.shape[0], self.n))}

    def _step(self, p, s, Y, U, dt, X, Z, D):
        g = float(p.gain)
        for j in range(Y.shape[1]):
            y = Y[:, j, 0]
            ok = ~np.isnan(y)
            v = (y - s.z[:, 0]) / dt
            s.z[ok, 1] = s.z[ok, 1] + g * (v[ok] - s.z[ok, 1])
            s.z[ok, 0] = y[ok]
            Z[:, j] = s.z
            self._to_physical(s, Z[:, j:j + 1], U[:, j:j + 1], X[:, j:j + 1])

    def _current(self, p, s):
        return s.x_held.copy(), s.z.copy(), np.zeros((s.z.shape[0], 0))

    def tuning_space(self):
        return {"gain": Dimension("gain", 0.01, 1.0, True, self.gain)}
'''


def test_a_users_observer_and_task_enter_the_leaderboard(tmp_path, monkeypatch, capsys):
    (tmp_path / "user_obs_mod.py").write_text(USER_OBSERVER)
    monkeypatch.syspath_prepend(str(tmp_path))
    task = tmp_path / "mine.toml"
    task.write_text('name = "mine/encoder-v1"\nsensor = "encoder"\nduration = 3.0\n'
                    't_transient = 1.0\ntuning_seeds = [1, 2]\nscoring_seeds = [11, 12, 13]\n'
                    '[plant]\nname = "pendulum"\ndt = 0.002\nx0 = [0.4, 0.0]\n'
                    '[input]\ntype = "multisine"\namplitudes = [0.3]\nfrequencies = [0.5]\n')
    out = tmp_path / "out"
    assert main(["bench", "--suite", "none", "--task-file", str(task), "--observers",
                 "high_gain", "--observer", "user_obs_mod:Hold", "--budget", "6", "--out",
                 str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "user_obs_mod:Hold" in printed and "mine/encoder-v1" in printed
    board = pd.read_parquet(out / "leaderboard.parquet")
    assert str(board["rank"].dtype) == "Int64" and board["rmse_norm"].dtype == float
    assert board["certified_period"].dtype == float and pd.api.types.is_string_dtype(board["task"])
    mine = board[(board["task"] == "mine/encoder-v1") & (board["observer"] == "user_obs_mod:Hold")]
    assert len(mine) == 1 and mine["status"].iloc[0] == "scored"
    scores = pd.read_parquet(out / "scores.parquet")
    assert set(scores["seed"]) == {11, 12, 13}
    assert {"rmse_norm", "noise_amplification", "settling", "iae", "peaking", "unit"} <= set(
        scores.columns)
    for name in ("leaderboard.md", "score_matrix.png", "task_mine__encoder-v1.png",
                 "traj_mine__encoder-v1.png", "mine__encoder-v1.rrd"):
        assert (out / name).stat().st_size > 0
    # resume: every part reused, nothing run again
    before = {p.name: p.stat().st_mtime_ns for p in (out / "parts").iterdir()}
    import hgo_mj.bench.runner as runner

    monkeypatch.setattr(runner, "_variant", lambda *a: pytest.fail("ran again on resume"))
    assert main(["bench", "--suite", "none", "--task-file", str(task), "--observers",
                 "high_gain", "--observer", "user_obs_mod:Hold", "--budget", "6", "--out",
                 str(out), "--resume", "--quiet", "--no-rrd"]) == 0
    assert {p.name: p.stat().st_mtime_ns for p in (out / "parts").iterdir()} == before


def test_the_quick_suite_scores_tuned_observers_better_than_their_defaults():
    r = bench("quick", observers=["high_gain", "ekf"], budget=6, record=False, progress=False)
    sel = r.leaderboard[(r.leaderboard["task"] == "pendulum/encoder-v1")].set_index("observer")
    assert sel.loc["high_gain", "rmse_norm"] < sel.loc["high_gain", "default_rmse_norm"]
    assert (r.leaderboard["task"] == "overall").sum() == 2
    # consistency: the filter's NIS and NEES with their band shares; none for the HGO
    kf, hgo = sel.loc["ekf"], sel.loc["high_gain"]
    assert all(np.isfinite(kf[c]) and kf[c] > 0 for c in ("nis", "nees"))
    assert all(0.0 <= kf[c] <= 1.0 for c in ("nis_band", "nees_band"))
    assert all(np.isnan(hgo[c]) for c in ("nis", "nis_band", "nees", "nees_band"))
    assert r.scores.loc[r.scores["observer"] == "ekf", "nees"].notna().all()


def test_parts_in_worker_processes_give_the_same_scores(tmp_path):
    """``jobs=2`` (local): the (task, observer) parts run in this process and a spawned
    worker, in completion order; the leaderboard and scores are those of one process."""
    kw = {"tasks": ["pendulum/encoder-v1"], "observers": ["finite_difference", "high_gain"],
          "budget": 2, "record": False, "progress": False}
    one = bench(None, **kw)
    two = bench(None, jobs=2, out=tmp_path, **kw)
    timing = ["update_time", "tune_seconds"]
    for a, b in ((one.scores, two.scores), (one.leaderboard, two.leaderboard)):
        keep = [c for c in a.columns if c not in timing]
        pd.testing.assert_frame_equal(a[keep], b[keep])
    assert len(list((tmp_path / "parts").iterdir())) == 2



def test_parts_are_handed_out_observer_by_observer_and_returned_task_by_task(monkeypatch):
    """A local process takes its parts from one end of the list: one observer's tasks after
    another (its kernels compiled once); the parts come back in task order whatever the order
    they finished in."""
    from hgo_mj.bench.runner import parts_of
    from hgo_mj.study import backends

    handed: list[tuple[str, str]] = []

    def fake_local(specs, jobs, run):
        handed.extend((s.task.name, s.kind) for s in specs)
        for s in reversed(specs):  # finished in another order
            yield s, [{"task": s.task.name, "observer": s.kind, "status": "scored"}]

    monkeypatch.setattr(backends, "_local", fake_local)
    tasks = [TASKS["pendulum/encoder-v1"], TASKS["elastic_joint/encoder-v1"]]
    parts = parts_of(tasks, ["high_gain", "ekf", "riccati"], 2, out=None, resume=False,
                     jobs=2, progress=False)
    names = [t.name for t in tasks]
    assert handed == [(t, o) for o in ("high_gain", "ekf", "riccati") for t in names]
    assert [(p["task"], p["observer"]) for p in parts] == \
        [(t, o) for t in names for o in ("high_gain", "ekf", "riccati")]


@pytest.mark.parametrize("text,match", [
    ('name = "x"\nsensor = "encoder"\n[plant]\nname = "pendulum"\n[input]\n',
     r"name must end in -v<N>"),
    ('name = "x-v1"\nsensor = "laser"\n[plant]\nname = "pendulum"\n[input]\n',
     r"unknown sensor preset 'laser'"),
    ('name = "x-v1"\nsensor = "encoder"\ncolour = 3\n[plant]\nname = "pendulum"\n[input]\n',
     r"unknown field\(s\) \['colour'\]"),
    ('name = "x-v1"\nsensor = "encoder"\n[plant]\nname = "pendulum"\n',
     r"missing field\(s\) \['input'\]"),
    ('name = "x-v1"\nsensor = "encoder"\ntuning_seeds = [1, 2]\nscoring_seeds = [2, 3]\n'
     '[plant]\nname = "pendulum"\n[input]\n', r"must be disjoint; both have \[2\]"),
    ('name = "x-v1"\nsensor = "encoder"\nduration = 1.0\nt_transient = 2.0\n'
     '[plant]\nname = "pendulum"\n[input]\n', r"t_transient must be < duration"),
    ('not toml [', r"is not TOML"),
])
def test_bad_task_files_are_one_line(tmp_path, text, match):
    f = tmp_path / "t.toml"
    f.write_text(text)
    with pytest.raises(DesignError, match=match):
        load_task(f)


@pytest.mark.parametrize("kw,match", [
    ({"observers": ["high_gian"]}, r"unknown observer 'high_gian'"),
    ({"observers": ["no_such_module:Cls"]}, r"no_such_module"),
    ({"tasks": ["pendulum/encoder-v9"]}, r"unknown task 'pendulum/encoder-v9'"),
    ({"budget": 1}, r"budget must be an integer >= 2"),
    ({"backend": "dask"}, r"backend must be 'local' or 'ray'"),
    ({"jobs": 0}, r"jobs must be an integer >= 1; found 0"),
    ({"jobs": 2.0}, r"jobs must be an integer >= 1; found 2.0"),
])
def test_bad_benchmark_arguments_are_one_line_before_any_work(kw, match, monkeypatch):
    import hgo_mj.bench.report as report

    monkeypatch.setattr(report, "parts_of", lambda *a, **k: pytest.fail("work began"))
    with pytest.raises(DesignError, match=match):
        bench(None if "tasks" in kw else "quick", progress=False, **kw)
    assert main(["bench", "--tasks", "pendulum/encoder-v9", "--quiet"]) == 2
