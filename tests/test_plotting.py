"""Figures: matplotlib Figures built without pyplot (the user's backend untouched), units on
every axis, the truth drawn on top, the Monte Carlo observers on shared axes, no title over a
panel title."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from hgo_mj.cli import main
from hgo_mj.simulate import Trajectory
from hgo_mj.systems import SYSTEMS


def _canvas(fig):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    fig.canvas.draw()
    return fig.canvas.get_renderer()


def _labels(fig):
    return [(ax, ax.get_xlabel(), ax.get_ylabel()) for ax in fig.axes if ax.axison]


def test_importing_and_plotting_never_switch_the_backend():
    code = """
import sys, matplotlib
matplotlib.use("svg")
import hgo_mj.plotting, hgo_mj.cli, hgo_mj.study
import hgo_mj.reproduce.bastin_gevers1986, hgo_mj.reproduce.besancon2004
import hgo_mj.reproduce.bullinger1998, hgo_mj.reproduce.ibrir2007, hgo_mj.reproduce.jo_son2004
from hgo_mj.cli import main
assert main(["run", "--plant", "pendulum", "--observer", "high_gain:k=20", "--duration", "0.5",
             "--seeds", "3", "--out", sys.argv[1]]) == 0
assert matplotlib.get_backend() == "svg", matplotlib.get_backend()
assert "matplotlib.pyplot" not in sys.modules
print("ok")
"""
    import tempfile

    with tempfile.TemporaryDirectory() as out:
        res = subprocess.run([sys.executable, "-c", code, out], capture_output=True, text=True,
                             timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    assert res.stdout.strip().endswith("ok")


def test_every_system_declares_its_units():
    for name, cls in SYSTEMS.items():
        assert len(cls.state_units) == len(cls.state_names), name
        assert isinstance(cls.time_unit, str), name
        if cls.model_file:  # the MuJoCo plants' actuators have SI units
            assert len(cls.input_units) == len(cls.input_names), name
    assert SYSTEMS["bioreactor_bullinger"].time_unit == "h"
    assert SYSTEMS["bioreactor_bullinger"].unit("m") == "conc."
    assert SYSTEMS["pendulum"].unit("angular_velocity") == "rad/s"


@pytest.fixture(scope="module")
def pend_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("pend")
    assert main(["run", "--plant", "pendulum", "--sensor", "gaussian:std=0.02",
                 "--observer", "high_gain:name=slow,k=10", "--observer", "high_gain:name=fast,k=200",
                 "--observer", "high_gain_multi:name=multi,k=30,orders=[3]",
                 "--input", "multisine:amplitudes=[0.3],frequencies=[0.5]", "--duration", "3",
                 "--seeds", "6", "--out", str(out)]) == 0
    return out


def test_the_trajectory_figure(pend_run):
    from matplotlib.figure import Figure

    from hgo_mj.plotting import plot_trajectory

    traj = Trajectory.load(pend_run / "trajectory.npz")
    fig = plot_trajectory(traj, title="a title")
    assert isinstance(fig, Figure)
    labels = _labels(fig)
    ys = [y for _, _, y in labels]
    assert "angle [rad]" in ys and "error angular_velocity [rad/s]" in ys
    # the third-order chain's extra column: the angle's second derivative
    assert "angular_acceleration [rad/s^2]\n(estimate only)" in ys
    assert all(y.split("\n")[0].endswith("]") for y in ys), ys
    assert {x for _, x, _ in labels if x} == {"t [s]"}
    # both columns show their time axis: the error column ends above the extra row
    err_last = fig.axes[3]
    assert err_last.get_xlabel() == "t [s]"
    assert any(t.get_visible() and t.get_text() for t in err_last.get_xticklabels())
    for ax in fig.axes[::2][:2]:  # the left column: truth and estimates
        lines = ax.get_lines()
        true = [ln for ln in lines if ln.get_label() == "true"]
        assert len(true) == 1 and true[0].get_zorder() > max(
            ln.get_zorder() for ln in lines if ln.get_label() != "true")
    renderer = _canvas(fig)
    sup = fig._suptitle.get_window_extent(renderer)
    for ax in fig.axes:
        assert not sup.overlaps(ax.title.get_window_extent(renderer)) or not ax.get_title()
        assert not sup.overlaps(ax.get_window_extent(renderer))
    assert (pend_run / "figure.png").stat().st_size > 10_000


def test_units_of_a_bioreactor_in_hours(tmp_path):
    from hgo_mj.plotting import plot_trajectory

    assert main(["run", "--plant", "bioreactor_bullinger", "--observer", "high_gain:k=2",
                 "--input", "constant:value=0.05", "--duration", "4", "--out",
                 str(tmp_path)]) == 0
    fig = plot_trajectory(Trajectory.load(tmp_path / "trajectory.npz"))
    labels = _labels(fig)
    assert {x for _, x, _ in labels if x} == {"t [h]"}
    assert "s [conc.]" in [y for _, _, y in labels]


def test_the_monte_carlo_figure_shares_one_axis_per_state(pend_run):
    import json

    from hgo_mj.plotting import plot_monte_carlo
    from hgo_mj.study import MonteCarloResult

    mcj = json.loads((pend_run / "metrics_mc.json").read_text())
    mc = MonteCarloResult.from_runs(mcj["seeds"], [r["metrics"] for r in mcj["runs"]], {})
    fig = plot_monte_carlo(mc, title="t", units={"angle": "rad", "angular_velocity": "rad/s"})
    panels = [ax for ax in fig.axes if ax.axison]
    assert [ax.get_title() for ax in panels] == ["angle", "angular_velocity"]
    assert [ax.get_ylabel() for ax in panels] == ["RMSE angle [rad]",
                                                 "RMSE angular_velocity [rad/s]"]
    for ax in panels:  # every observer on the one axis of its state
        assert [t.get_text() for t in ax.get_xticklabels()] == ["slow", "fast", "multi"]
    for i, ax in enumerate(panels):  # log exactly where the values span a decade
        v = [r[o]["rmse"][i] for r in mc.runs for o in ("slow", "fast", "multi")]
        assert (ax.get_yscale() == "log") == (max(v) / min(v) >= 10)
    renderer = _canvas(fig)
    sup = fig._suptitle.get_window_extent(renderer)
    assert not any(sup.overlaps(ax.get_window_extent(renderer)) for ax in panels)
    assert (pend_run / "mc.png").stat().st_size > 10_000


def test_saved_figures_are_the_returned_ones(pend_run, tmp_path):
    """The command line saves the Figures the plotting functions return (hgo_mj._io)."""
    from hgo_mj._io import save_figure
    from hgo_mj.plotting import plot_trajectory

    traj = Trajectory.load(pend_run / "trajectory.npz")
    path = save_figure(plot_trajectory(traj), tmp_path / "f.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(tmp_path.glob(".*.tmp"))
    assert np.isfinite(traj.x).all()


def test_the_monte_carlo_axis_is_logarithmic_where_values_span_decades():
    from hgo_mj.plotting import plot_monte_carlo
    from hgo_mj.study import MonteCarloResult

    def metrics(a, b):
        return {"states": ["p", "v"], "estimated": [True, True], "rmse": [a, b],
                "peak": [a, b], "final": [a, b], "settling_time": [0.1, 0.1],
                "undefined_samples": [0, 0], "update_time": 1e-6, "extra_states": []}

    runs = [{"lo": metrics(1e-3 * (1 + s), 0.5 + 0.1 * s), "hi": metrics(0.2 + 0.1 * s,
                                                                         0.6 + 0.1 * s)}
            for s in range(5)]
    fig = plot_monte_carlo(MonteCarloResult.from_runs(list(range(5)), runs, {}))
    p, v = [ax for ax in fig.axes if ax.axison]
    assert p.get_yscale() == "log" and v.get_yscale() == "linear"
    assert p.get_ylabel() == "RMSE p [?]"  # no units given
    lo, hi = p.get_ylim()
    assert lo <= 1e-3 and hi >= 0.6  # both observers on the one axis


def test_every_plotting_function_draws_on_given_axes(pend_run):
    """``axes=`` / ``ax=`` (python-control's and scikit-learn's ``plot(ax=...)``): each public
    plotting function draws on the user's axes and returns their figure; axes of another
    count are refused, naming the grid expected."""
    import json

    import pandas as pd

    from hgo_mj.bench.figures import interval_chart, score_matrix
    from hgo_mj.exceptions import DesignError
    from hgo_mj.plotting import plot_monte_carlo, plot_trajectory, subplots
    from hgo_mj.study import MonteCarloResult

    traj = Trajectory.load(pend_run / "trajectory.npz")
    fig, grid = subplots(3, 2)  # 2 plant states + the multi-output chain's extra row
    assert plot_trajectory(traj, axes=grid) is fig and len(fig.axes) == 6
    assert grid[0, 0].get_ylabel() == "angle [rad]" and grid[0, 0].get_lines()
    with pytest.raises(DesignError, match=r"plot_trajectory: axes= must hold 6 Axes \(a grid "
                                          r"of 3 x 2\); found 4"):
        plot_trajectory(traj, axes=subplots(2, 2)[1])
    mcj = json.loads((pend_run / "metrics_mc.json").read_text())
    mc = MonteCarloResult.from_runs(mcj["seeds"], [r["metrics"] for r in mcj["runs"]], {})
    fig, (a, b) = subplots(1, 2)
    assert plot_monte_carlo(mc, axes=[a, b]) is fig and a.get_title() == "angle"
    board = pd.DataFrame([{"task": "a-v1", "observer": "x", "status": "scored", "rank": 1,
                           "normalized_rank": 0.0, "rmse_norm": 0.01, "rmse_norm_low": 0.009,
                           "rmse_norm_high": 0.011, "default_rmse_norm": 0.05}])
    fig, (a, b) = subplots(1, 2)
    assert score_matrix(board, ax=a) is fig and interval_chart(board, "a-v1", ax=b) is fig
    assert a.get_images() and b.get_title() == "a-v1"
    with pytest.raises(DesignError, match="score_matrix: axes= must hold 1 Axes"):
        score_matrix(board, ax="left")


def test_figures_are_pyplots_when_the_user_imported_pyplot(tmp_path):
    """Without ``axes=``: a figure pyplot manages (``plt.show()`` shows it) once the user has
    imported pyplot, and a Figure without pyplot otherwise; the command line never imports
    pyplot, and closes a pyplot figure it saved."""
    code = """
import sys
import matplotlib
matplotlib.use("Agg")
from hgo_mj.inputs import Constant
from hgo_mj.plants import make_plant
from hgo_mj.plotting import plot_trajectory
from hgo_mj.simulate import simulate
traj = simulate(make_plant("pendulum", 0.01), None, {}, Constant(0.0), duration=0.05)
fig = plot_trajectory(traj)
assert fig.canvas.manager is None and "matplotlib.pyplot" not in sys.modules
import matplotlib.pyplot as plt
fig = plot_trajectory(traj)
assert plt.get_fignums() == [fig.number] and plt.gcf() is fig
from hgo_mj._io import save_figure
save_figure(fig, sys.argv[1])
assert plt.get_fignums() == []
print("ok")
"""
    res = subprocess.run([sys.executable, "-c", code, str(tmp_path / "f.png")],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0 and res.stdout.strip() == "ok", res.stderr[-3000:]
