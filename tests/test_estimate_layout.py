"""Estimates that do not have the plant's state layout: matched to the plant's states by name.

The model-free multi-output high-gain observer on the two-link elastic arm estimates the link
angles and their derivatives (``link1_angle, link1_velocity, link1_acceleration, link1_jerk,
...``): four of its eight columns are plant states (in another order), four are not, and the
motor states are not estimated. Without a system it names its columns ``y1, y1_d1, ...``: no
plant state is estimated. Errors, metrics, figures, files and recordings must follow the names,
with no RuntimeWarning (the pytest configuration makes hgo_mj's RuntimeWarnings errors; the
tests below also turn every warning into an error).
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from hgo_mj._io import save_figure
from hgo_mj.exceptions import DimensionError
from hgo_mj.inputs import Multisine
from hgo_mj.metrics import all_metrics, format_table
from hgo_mj.observers import HighGainObserver, MultiOutputHighGainObserver
from hgo_mj.plants import make_plant
from hgo_mj.plants.ode import OdePlant
from hgo_mj.plotting import plot_trajectory
from hgo_mj.sensors import GaussianNoise, SensorChain
from hgo_mj.simulate import ObserverRecord, Trajectory, simulate

LINK = ("link1_angle", "link2_angle", "link1_velocity", "link2_velocity")
MOTOR = ("motor1_angle", "motor2_angle", "motor1_velocity", "motor2_velocity")


@pytest.fixture(scope="module")
def arm_run() -> Trajectory:
    plant = make_plant("elastic_joint_2link")
    obs = {"multi": MultiOutputHighGainObserver(plant.system, orders=(4, 4), k=120.0),
           "free": MultiOutputHighGainObserver(orders=(4, 4), k=120.0)}  # no system: y1, y2
    s1, s2 = Multisine([0.5, 0.2], [0.5, 1.3], [0.0, 1.0]), Multisine([0.15, 0.05], [0.8, 2.1])
    return simulate(plant, SensorChain([GaussianNoise(std=1e-5)], seed=0), obs,
                    lambda t: np.concatenate([s1(t), s2(t)]), 1.0, seed=0)


def test_error_matches_columns_by_name(arm_run):
    traj = arm_run
    rec = traj.observers["multi"]
    assert rec.state_names == ("link1_angle", "link1_velocity", "link1_acceleration", "link1_jerk",
                               "link2_angle", "link2_velocity", "link2_acceleration", "link2_jerk")
    assert rec.x_hat.shape == (len(traj), 8)
    e = traj.error("multi")
    assert e.shape == traj.x.shape == (len(traj), 8)
    for i, s in enumerate(traj.state_names):
        if s in LINK:
            j = rec.state_names.index(s)
            np.testing.assert_array_equal(e[:, i], traj.x[:, i] - rec.x_hat[:, j])
            assert np.isfinite(e[:, i]).all()
        else:
            assert s in MOTOR and np.isnan(e[:, i]).all()  # not estimated
    # the subtraction column by column would compare link1_velocity with link2_angle
    assert traj.state_names.index("link2_angle") == 1 and rec.state_names[1] == "link1_velocity"
    np.testing.assert_array_equal(traj.estimated("multi"), [s in LINK for s in traj.state_names])
    assert traj.extra_states("multi") == ("link1_acceleration", "link1_jerk",
                                          "link2_acceleration", "link2_jerk")
    # the late error is small: the names put the right columns together
    late = traj.t >= 0.5
    assert np.abs(e[late][:, list(traj.estimated("multi"))]).max() < 0.1
    # without a system, nothing is a plant state
    assert traj.observers["free"].state_names[:2] == ("y1", "y1_d1")
    assert not traj.estimated("free").any() and np.isnan(traj.error("free")).all()


def test_metrics_of_unestimated_states_are_none(arm_run):
    traj = arm_run
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = all_metrics(traj)
        table = format_table(m)
    mm = m["multi"]
    assert mm["states"] == list(traj.state_names)
    for i, s in enumerate(traj.state_names):
        vals = [mm[k][i] for k in ("rmse", "peak", "settling_time", "final", "undefined_samples")]
        if s in LINK:
            assert mm["estimated"][i] and all(v is not None and np.isfinite(v) for v in vals)
            assert mm["undefined_samples"][i] == 0
        else:
            assert not mm["estimated"][i] and vals == [None] * 5
    assert mm["extra_states"] == ["link1_acceleration", "link1_jerk", "link2_acceleration",
                                  "link2_jerk"]
    assert m["free"]["rmse"] == [None] * 8 and m["free"]["estimated"] == [False] * 8
    # JSON-ready (None, not NaN, for "not estimated") and a readable table
    json.loads(json.dumps(m))
    rows = [r for r in table.splitlines() if r.startswith("multi ") and "motor1_angle" in r]
    assert rows and rows[0].split()[3:7] == ["-", "-", "-", "-"]  # after the unit column
    assert "not estimated" in table


def test_figure_of_a_partial_estimate(arm_run, tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        path = save_figure(plot_trajectory(arm_run, title="multi"), tmp_path / "f.png")
    assert path.stat().st_size > 10_000


def test_state_names_saved_and_loaded(arm_run, tmp_path):
    path = arm_run.save(tmp_path / "t.npz")
    back = Trajectory.load(path)
    for name, rec in arm_run.observers.items():
        assert back.observers[name].state_names == rec.state_names
    np.testing.assert_array_equal(back.error("multi"), arm_run.error("multi"))


def test_old_file_without_state_names(tmp_path, chain):
    """Files written before the names were saved: the plant's names when the widths agree."""
    plant = OdePlant(chain(2)(), dt=1e-3, physics_dt=1e-3)
    traj = simulate(plant, None, {"a": HighGainObserver(plant.system, k=5.0)},
                    Multisine([1.0], [1.0]), 0.05, x0=[1.0, 0.0])
    path = traj.save(tmp_path / "old.npz")
    with np.load(path) as z:
        cols = {k: z[k] for k in z.files}
    meta = json.loads(str(cols["__meta__"]))
    for om in meta["observers"].values():
        del om["state_names"]
    # and an observer of another width (an estimate in its own coordinates)
    cols["obs/b/x_hat"], cols["obs/b/z_hat"] = np.zeros((len(traj), 3)), np.zeros((len(traj), 3))
    meta["observers"]["b"] = {"diagnostics": [], "update_time": 0.0}
    cols["__meta__"] = np.array(json.dumps(meta))
    np.savez(tmp_path / "old2.npz", **cols)
    back = Trajectory.load(tmp_path / "old2.npz")
    assert back.observers["a"].state_names == ("x1", "x2")
    np.testing.assert_array_equal(back.error("a"), traj.error("a"))
    assert back.observers["b"].state_names == ("x_hat_1", "x_hat_2", "x_hat_3")
    assert np.isnan(back.error("b")).all()


def test_record_validates_names():
    T = 3
    z = np.zeros((T, 2))
    common = dict(t=np.arange(T) * 0.1, x=z, y_clean=z[:, :1], y_meas=z[:, :1], u=z[:, :1],
                  state_names=("a", "b"), output_names=("y",), input_names=("u",))
    # no names: the plant's when the widths agree
    tr = Trajectory(observers={"o": ObserverRecord(x_hat=z, z_hat=z)}, **common)
    assert tr.observers["o"].state_names == ("a", "b")
    with pytest.raises(DimensionError, match=r"observer 'o': state_names must name the 2 "
                                             r"column\(s\) of x_hat; found 3"):
        Trajectory(observers={"o": ObserverRecord(x_hat=z, z_hat=z, state_names=("a", "b", "c"))},
                   **common)
    with pytest.raises(DimensionError, match="must be distinct"):
        Trajectory(observers={"o": ObserverRecord(x_hat=z, z_hat=z, state_names=("a", "a"))},
                   **common)
    # a subset, in another order
    tr = Trajectory(observers={"o": ObserverRecord(x_hat=np.ones((T, 2)), z_hat=z,
                                                   state_names=("b", "extra"))}, **common)
    e = tr.error("o")
    assert np.isnan(e[:, 0]).all() and np.all(e[:, 1] == -1.0)


def test_an_observer_whose_names_do_not_fit_is_refused(chain):
    class Misnamed(HighGainObserver):
        @property
        def state_names(self):
            return ("only_one",)

    plant = OdePlant(chain(2)(), dt=1e-3, physics_dt=1e-3)
    # refused as soon as the observer is made (its reset maps an estimate), before any run
    with pytest.raises(DimensionError, match=r"Misnamed: state_names must name the 2 entries of "
                                             r"x_hat; found 1 \['only_one'\]"):
        Misnamed(plant.system, k=5.0)


def test_an_estimate_that_is_never_defined(tmp_path):
    """An estimated state whose estimate is NaN throughout (its inverse map never defined):
    metrics NaN with every sample counted as undefined, a figure, and no warning."""
    T = 50
    t = np.arange(T) * 0.1
    x = np.column_stack([np.sin(t), np.cos(t)])
    xh = np.column_stack([np.sin(t) + 0.01, np.full(T, np.nan)])
    tr = Trajectory(t=t, x=x, y_clean=x[:, :1], y_meas=x[:, :1], u=np.zeros((T, 1)),
                    observers={"o": ObserverRecord(x_hat=xh, z_hat=xh)},
                    state_names=("a", "b"), output_names=("y",), input_names=("u",))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = all_metrics(tr)["o"]
        format_table({"o": m})
        save_figure(plot_trajectory(tr), tmp_path / "f.png")
    assert m["estimated"] == [True, True] and m["undefined_samples"] == [0, T]
    assert m["rmse"][0] == pytest.approx(0.01) and np.isnan(m["rmse"][1])
    assert np.isnan(m["peak"][1]) and np.isnan(m["final"][1])
    assert m["settling_time"][1] == np.inf
