"""Issue 14: every bad input is one clear line (exit 2, no traceback, no files) on the command
line and a documented ``hgo_mj.exceptions`` error in Python. One regression test per class of
bad input the issue found; the property-based suite is tests/test_fuzz_scenarios.py."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from hgo_mj.cli import main
from hgo_mj.exceptions import DesignError, DimensionError, HgoError
from hgo_mj.simulate import Trajectory

BASE = """
[plant]
name = "pendulum"
dt = 0.01
[[observers]]
type = "high_gain"
k = 20.0
[run]
duration = 0.3
"""


def _run(tmp_path, doc, capsys, *extra):
    path = tmp_path / "s.toml"
    path.write_text(doc)
    out = tmp_path / "o"
    code = main(["run", str(path), "--out", str(out), *extra])
    err = capsys.readouterr().err
    return code, err, out


def assert_one_line(code, err, out, *needles):
    assert code == 2, err
    assert err.startswith("hgo-mj: error:") and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    for n in needles:
        assert n in err, err
    assert not out.exists() or not any(out.iterdir())


def with_run(key_value):
    return BASE.replace("duration = 0.3", f"duration = 0.3\n{key_value}")


def with_observer(key_value):
    return BASE.replace("k = 20.0", key_value if key_value.startswith("k =")
                        else f"k = 20.0\n{key_value}")


# ---------------------------------------------------------------- wrong TOML types
@pytest.mark.parametrize("doc, needles", [
    ("observers = 5\n" + BASE.split("[[observers]]")[0] + "[run]\nduration = 0.3\n",
     ["observers must be a list of tables", "found 5"]),
    (BASE.replace('dt = 0.01', 'dt = 0.01\nparams = 5'), ["plant.params must be a table"]),
    (with_run("out = 5"), ["run.out must be a string", "found 5"]),
    ("name = 1979-05-27T07:32:00Z\n" + BASE, ["name must be a string", "datetime"]),
    (BASE.replace('name = "pendulum"', "name = 1979-05-27"), ["plant.name must be a string"]),
    (BASE.replace("[plant]", 'input = "x"\n[plant]'), ["input must be a table", "'x'"]),
    (BASE + "[sensor]\nstages = 5\n", ["sensor.stages must be a list of tables"]),
    (BASE + "[sensor]\nstages = [5]\n", ["sensor.stages must be a list of tables"]),
    ("observers = [5]\n" + BASE.replace('[[observers]]\ntype = "high_gain"\nk = 20.0\n', ""),
     ["observers must be a list of tables"]),
    (with_observer("system_params = 5"), ["system_params must be a table"]),
])
def test_wrong_toml_type_is_one_line(doc, needles, tmp_path, capsys):
    assert_one_line(*_run(tmp_path, doc, capsys), *needles)


# ---------------------------------------------------------------- types checked, not coerced
@pytest.mark.parametrize("doc, needles", [
    (with_run("seed = 1.7"), ["run.seed must be an integer >= 0", "1.7"]),
    (BASE.replace("duration = 0.3", 'duration = "1"'), ["run.duration must be a real number",
                                                         "'1'"]),
    (BASE.replace("duration = 0.3", "duration = true"), ["run.duration", "True"]),
    (BASE.replace("dt = 0.01", 'dt = "0.01"'), ["plant.dt must be a real number"]),
    (BASE.replace("dt = 0.01", "dt = 0.01\nx0 = [0.1, true]"), ["plant.x0 must be a list of "
                                                                 "numbers"]),
    (with_observer('model = "no"'), ["model must be true or false", "'no'"]),
    (with_observer('k = "20"'), ["k must be a real number", "'20'"]),
    (with_observer("k = true"), ["k must be a real number", "True"]),
    (with_observer("order = 2.5"), ["order must be a positive integer", "2.5"]),
    (BASE + '[sensor]\nstages = [{stage = "gaussian", std = true}]\n',
     ["GaussianNoise.std must be a real number", "True"]),
    (BASE + '[sensor]\nstages = [{stage = "gaussian", std = "0.1"}]\n',
     ["GaussianNoise.std must be a real number"]),
    (with_run('t_transient = "a"'), ["run.t_transient must be a real number"]),
])
def test_type_not_coerced_is_one_line(doc, needles, tmp_path, capsys):
    assert_one_line(*_run(tmp_path, doc, capsys), *needles)


# ---------------------------------------------------------------- checked against the plant
def test_observer_output_the_plant_does_not_have(tmp_path, capsys):
    assert_one_line(*_run(tmp_path, with_observer("outputs = [7]"), capsys),
                    "found channel 7")


def test_observer_output_checked_by_the_loop_before_running():
    from hgo_mj.observers import HighGainObserver
    from hgo_mj.plants import make_plant
    from hgo_mj.simulate import simulate

    plant = make_plant("pendulum", 0.01)
    ob = HighGainObserver(None, k=10.0, order=2, outputs=(3,))  # no system: not checked there
    with pytest.raises(DimensionError, match=r"reads output channel\(s\) \[3\]; the plant has 1"):
        simulate(plant, None, {"h": ob}, lambda t: [0.0], 0.1)


# ---------------------------------------------------------------- inputs
@pytest.mark.parametrize("doc, needles", [
    (BASE + '[input]\ntype = "multisine"\namplitudes = [0.3]\n',
     ["input 'multisine': missing required parameter(s) ['frequencies']"]),
    (BASE + '[input]\ntype = "telegraph"\namplitude = 0.1\nperiod = 0.05\nlength = 0\n',
     ["Telegraph.length must be a positive integer; found 0"]),
    (BASE + '[input]\ntype = "telegraph"\namplitude = 0.1\nperiod = 0.05\nlength = 2000000000\n',
     ["Telegraph.length must be at most", "found 2000000000"]),
    (BASE + '[input]\ntype = "telegraph"\namplitude = 0.1\nperiod = 0.05\nlength = 10.5\n',
     ["Telegraph.length must be a positive integer; found 10.5"]),
    (BASE + '[input]\ntype = "prbs"\namplitude = 0.1\nperiod = 0.05\nnbits = 40\n',
     ["PRBS.nbits must be in 2..20", "found 40"]),
])
def test_bad_input_signal_is_one_line(doc, needles, tmp_path, capsys):
    assert_one_line(*_run(tmp_path, doc, capsys), *needles)


def test_input_missing_parameter_on_the_command_line(tmp_path, capsys):
    code = main(["run", "--plant", "pendulum", "--duration", "0.2", "--out", str(tmp_path / "o"),
                 "--input", "multisine:amplitudes=[0.3]"])
    assert_one_line(code, capsys.readouterr().err, tmp_path / "o", "['frequencies']")


# ---------------------------------------------------------------- structure and size
def test_deeply_nested_toml_is_one_line(tmp_path, capsys):
    doc = BASE + "deep = " + "[" * 5000 + "]" * 5000 + "\n"
    assert_one_line(*_run(tmp_path, doc, capsys), "nested too deeply")


def test_deeply_nested_flag_value_is_one_line(tmp_path, capsys):
    code = main(["run", "--plant", "pendulum", "--duration", "0.2", "--out", str(tmp_path / "o"),
                 "--observer", "high_gain:k=" + "[" * 5000 + "]" * 5000])
    assert_one_line(code, capsys.readouterr().err, tmp_path / "o", "nested too deeply")


def test_too_many_seeds_refused_before_any_work(tmp_path, capsys):
    code, err, out = _run(tmp_path, BASE, capsys, "--seeds", "1000000000")
    assert_one_line(code, err, out, "found 1000000000", "hgo-mj sweep", "--yes")


def test_sample_period_longer_than_duration(tmp_path, capsys):
    assert_one_line(*_run(tmp_path, with_run("sample_period = 1.0"), capsys),
                    "duration = 0.3 s must be at least one sample_period = 1 s")


def test_run_too_long_for_memory_refused_before_running(tmp_path, capsys):
    assert_one_line(*_run(tmp_path, BASE.replace("duration = 0.3", "duration = 1e12"), capsys),
                    "GiB", "store_every")


# ---------------------------------------------------------------- magnitudes
def test_huge_noise_is_reported_not_written_as_null(tmp_path, capsys):
    doc = BASE + '[sensor]\nstages = [{stage = "gaussian", std = 1e300}]\n'
    code, err, out = _run(tmp_path, doc, capsys)
    assert_one_line(code, err, out, "overflowed to inf")


def test_huge_gain_is_refused(tmp_path, capsys):
    assert_one_line(*_run(tmp_path, with_observer("k = 1e300"), capsys),
                    "k = 1e+300 is too large")


# ---------------------------------------------------------------- output paths, before running
def test_out_is_an_existing_file(tmp_path, capsys):
    (tmp_path / "f").write_text("keep")
    code = main(["run", "--plant", "pendulum", "--duration", "0.2", "--out", str(tmp_path / "f")])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "must be a folder; found the existing file" in err
    assert (tmp_path / "f").read_text() == "keep"


def test_out_below_a_file(tmp_path, capsys):
    (tmp_path / "f").write_text("keep")
    code = main(["run", "--plant", "pendulum", "--duration", "0.2", "--out",
                 str(tmp_path / "f" / "sub")])
    err = capsys.readouterr().err
    assert code == 2 and "is a file, not a folder" in err


def test_rrd_is_an_existing_folder_checked_before_the_run(tmp_path, capsys, monkeypatch):
    import hgo_mj.simulate as sim

    def boom(*a, **k):
        raise AssertionError("the simulation must not start")

    monkeypatch.setattr(sim, "simulate", boom)
    (tmp_path / "d.rrd").mkdir()
    code = main(["run", "--plant", "pendulum", "--duration", "0.2", "--out",
                 str(tmp_path / "o"), "--rrd", str(tmp_path / "d.rrd")])
    err = capsys.readouterr().err
    assert code == 2 and "--rrd must be a file; found the existing folder" in err
    assert not (tmp_path / "o").exists()


def test_read_only_out(tmp_path, capsys, monkeypatch):
    """A folder where no file can be created (read-only: the probe's file creation fails, as
    it does for a non-root user; mocked so that it holds when the tests run as root)."""
    import tempfile

    def refuse(*a, **k):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    code = main(["run", "--plant", "pendulum", "--duration", "0.2", "--out",
                 str(tmp_path / "ro" / "o")])
    assert code == 2 and "is not writable" in capsys.readouterr().err
    assert not (tmp_path / "ro").exists()


def test_check_writable_probes_and_leaves_nothing(tmp_path, monkeypatch):
    import tempfile

    from hgo_mj._io import check_writable

    assert check_writable("--out", tmp_path / "a" / "b", folder=True) == tmp_path / "a" / "b"
    assert list(tmp_path.iterdir()) == []  # nothing created

    def refuse(*a, **k):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    with pytest.raises(DesignError, match="is not writable: cannot create a file in"):
        check_writable("--out", tmp_path / "a", folder=True)


# ---------------------------------------------------------------- Python API
@pytest.mark.parametrize("kwargs, message", [
    ({"k": "20"}, "k must be a real number; found '20'"),
    ({"k": True}, "k must be a real number; found True"),
    ({"k": 10.0, "order": 2.5}, "order must be a positive integer; found 2.5"),
    ({"k": 10.0, "model": "no"}, "model must be true or false; found 'no'"),
    ({"k": 10.0, "model": 1}, "model must be true or false; found 1"),
    ({"k": 1e300}, "too large"),
])
def test_observer_types_checked_not_coerced(kwargs, message):
    from hgo_mj.observers import HighGainObserver
    from hgo_mj.systems import Pendulum

    with pytest.raises(DesignError, match=message.replace("(", r"\(")):
        HighGainObserver(Pendulum(), **kwargs)


@pytest.mark.parametrize("std", [True, "0.1", [0.1, False]])
def test_sensor_noise_types_checked(std):
    from hgo_mj.sensors import GaussianNoise

    with pytest.raises(HgoError, match="GaussianNoise.std must be a real number"):
        GaussianNoise(std=std)


@pytest.mark.parametrize("dt", [0.0, -0.01, float("nan"), True, "0.01"])
def test_observer_dt_must_be_positive(dt):
    from hgo_mj.observers import HighGainObserver

    ob = HighGainObserver(None, k=10.0, order=2)
    ob.reset()
    with pytest.raises(DesignError, match="dt must be a positive finite number"):
        ob.update([0.0], [], dt)


def test_observer_inputs_checked():
    from hgo_mj.observers import make_observer
    from hgo_mj.systems import Pendulum

    ob = make_observer("ekf", Pendulum())
    ob.reset()
    with pytest.raises(DimensionError, match=r"u must have shape \(1,\); found shape \(2,\)"):
        ob.update([0.1], [0.0, 1.0], 0.01)
    with pytest.raises(DesignError, match=r"u must be finite; found u\[0\] = nan"):
        ob.update([0.1], [np.nan], 0.01)
    with pytest.raises(DesignError, match=r"us must be finite; found us\[2, 0\] = nan"):
        ob.run(np.zeros((5, 1)), np.array([[0.0], [0.0], [np.nan], [0.0], [0.0]]), 0.01)
    with pytest.raises(DimensionError, match="y must be an array of real numbers"):
        ob.update([True], [0.0], 0.01)
    with pytest.raises(DimensionError, match="u must be an array of real numbers"):
        ob.update([0.1], ["a"], 0.01)
    ob.update([np.nan], [0.0], 0.01)  # a dropout stays allowed


def test_make_signal_missing_parameter():
    from hgo_mj.inputs import make_signal

    with pytest.raises(DesignError, match=r"missing required parameter\(s\) \['frequencies'\]"):
        make_signal("multisine", amplitudes=[0.3])


def test_trajectory_columns_of_different_lengths(tmp_path):
    traj = Trajectory(t=np.arange(3.0), x=np.zeros((3, 2)), y_clean=np.zeros((3, 1)),
                      y_meas=np.zeros((3, 1)), u=np.zeros((3, 1)), observers={},
                      state_names=("a", "b"), output_names=("y",), input_names=("u",))
    path = traj.save(tmp_path / "t.npz")
    assert len(Trajectory.load(path)) == 3
    with np.load(path) as z:
        cols = dict(z)
    cols["x"] = np.zeros((2, 2))
    np.savez(tmp_path / "bad.npz", **cols)
    with pytest.raises(DimensionError, match=r"column x must have 3 rows .*found shape \(2, 2\)"):
        Trajectory.load(tmp_path / "bad.npz")


def test_vector_refuses_bools_and_strings():
    from hgo_mj._validate import finite_scalar, vector

    with pytest.raises(DimensionError, match="1-D array of numbers"):
        vector("x0", [0.1, True])
    with pytest.raises(DimensionError, match="1-D array of numbers"):
        vector("x0", ["0.1", 0.2])
    with pytest.raises(DesignError, match="real number; found '1'"):
        finite_scalar("duration", "1")
    assert finite_scalar("duration", np.float32(0.5)) == 0.5


# ---------------------------------------------------------------- bounded memory
@pytest.mark.parametrize("kind, kwargs", [
    ("high_gain", {"k": 10.0}),
    ("high_gain_multi", {"k": 10.0}),
    ("riccati", {"gamma": 2.0}),
    ("adaptive_gain", {"lam": 0.1, "lam_hat": 0.5, "gamma": 1.0, "k0": 5.0}),
    ("q_integral", {"gamma": 2.0}),
])
def test_20000_jittered_periods_keep_the_caches_bounded(kind, kwargs):
    from hgo_mj.observers import make_observer, registered
    from hgo_mj.systems import Pendulum

    assert kind in registered()
    ob = make_observer(kind, Pendulum(), **kwargs)
    ob.reset()
    dts = (1e-3 * (1 + 0.01 * np.random.default_rng(0).standard_normal(20000))).tolist()
    for dt in dts[:200]:  # warm up: the caches fill
        ob.update([0.1], [0.0], dt)
    tracemalloc.start()
    before = tracemalloc.get_traced_memory()[0]
    for dt in dts[200:]:
        ob.update([0.1], [0.0], dt)
    grown = tracemalloc.get_traced_memory()[0] - before
    tracemalloc.stop()
    caches = [v for k, v in vars(ob).items() if "cache" in k or k == "_maps"]
    assert caches, "no per-period cache found"
    assert all(len(c) <= 64 for c in caches)
    assert grown < 1 << 20, f"{grown} bytes kept by 19,800 distinct periods"


def test_a_misspelt_plant_is_named_before_a_missing_duration(capsys):
    """`hgo-mj run --plant pendulumm` (no --duration): the unknown plant is the error, with
    the valid names, not the missing run.duration."""
    from hgo_mj.cli import main

    assert main(["run", "--plant", "pendulumm"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(
        "hgo-mj: error: unknown plant 'pendulumm'; valid: ['acrobot'"), err
