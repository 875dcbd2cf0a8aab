"""Figures of a trajectory and of a Monte Carlo study, as :class:`matplotlib.figure.Figure`.

The functions never import pyplot nor change the user's matplotlib backend. Each takes
``axes=`` (the grid of :class:`~matplotlib.axes.Axes` to draw on, as python-control's and
scikit-learn's ``plot(ax=...)``); without it, it makes its own figure (:func:`new_figure`):
pyplot-managed when the user has imported ``matplotlib.pyplot`` (so ``plt.show()`` shows it),
else a :class:`~matplotlib.figure.Figure` without pyplot (no global state: a notebook shows it
as the cell's value, ``fig.savefig(path)`` saves it, or atomically
:func:`hgo_mj._io.save_figure`, as the command line does).

Estimates are matched to the plant's states by name (:meth:`~hgo_mj.simulate.Trajectory.
estimate`): an observer that does not estimate a plant state draws nothing in its row. The
observers' columns that are not plant states (an order-only observer's ``z1, z2, ...``, the
derivatives of a multi-output observer, parameter estimates) get rows of their own below,
estimates only (there is no true value, so no error). NaN samples (an inverse map undefined,
a dropout) are gaps; axis limits use the finite samples only.

Every axis label carries a unit in brackets, taken from the plant's system
(:attr:`~hgo_mj.systems.base.System.state_units`, :attr:`~hgo_mj.systems.base.System.time_unit`):
``[-]`` is dimensionless; the derivatives of an output get the output's unit per second
(``rad/s^2``); ``[?]`` marks a quantity whose unit no system declares (a parameter estimate).
"""

from __future__ import annotations

import math
import sys
from typing import Any

import numpy as np

from .units import bracket, units_of

TRUE_COLOR = "black"

__all__ = ["axes_grid", "new_figure", "plot_monte_carlo", "plot_trajectory", "subplots"]


def _finite_range(*arrays: Any) -> tuple[float, float] | None:
    """``(min, max)`` over the finite values of the arrays, or ``None`` if there are none."""
    vals = [a[np.isfinite(a)] for a in (np.asarray(v, dtype=float).ravel() for v in arrays)]
    vals = [v for v in vals if v.size]
    if not vals:
        return None
    cat = np.concatenate(vals)
    return float(cat.min()), float(cat.max())


def _colors() -> list[str]:
    import matplotlib

    return list(matplotlib.rcParams["axes.prop_cycle"].by_key()["color"])


def new_figure(figsize: tuple[float, float] | None = None, layout: Any = None) -> Any:
    """A new figure: pyplot-managed when the user has imported ``matplotlib.pyplot`` (so that
    ``plt.show()`` shows it), else a :class:`~matplotlib.figure.Figure` without pyplot (no
    backend, no global state). hgo_mj itself never imports pyplot.

    Parameters
    ----------
    figsize : tuple of float, optional
        ``(width, height)`` in inches; default matplotlib's ``figure.figsize``.
    layout : str or LayoutEngine, optional
        The figure's layout engine (``"constrained"``, ``"tight"``); default none.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import sys
    >>> fig = new_figure((4, 3))
    >>> ("matplotlib.pyplot" in sys.modules) == (fig.canvas.manager is not None)
    True
    """
    if "matplotlib.pyplot" in sys.modules:  # the user's: its figures are shown by plt.show()
        import matplotlib.pyplot as plt

        return plt.figure(figsize=figsize, layout=layout)
    from matplotlib.figure import Figure

    return Figure(figsize=figsize, layout=layout)


def subplots(*args: Any, figsize: tuple[float, float] | None = None, layout: Any = None,
             **kw: Any) -> tuple[Any, Any]:
    """``pyplot.subplots`` on :func:`new_figure`: a figure (pyplot's when the user has
    imported pyplot, else one without it) and its axes (``Figure.subplots(*args, **kw)``).

    Parameters
    ----------
    *args
        ``nrows, ncols`` of the grid (default ``1, 1``), as :meth:`matplotlib.figure.Figure.
        subplots`.
    figsize : tuple of float, optional
        ``(width, height)`` in inches; default matplotlib's ``figure.figsize``.
    layout : str or LayoutEngine, optional
        The figure's layout engine (``"constrained"``, ``"tight"``); default none.
    **kw
        Passed to :meth:`matplotlib.figure.Figure.subplots` (``sharex``, ``squeeze``, ...).

    Returns
    -------
    fig : matplotlib.figure.Figure
        Save it with ``fig.savefig(path)``.
    axes : matplotlib.axes.Axes or numpy.ndarray of Axes
        One axes, or the ``(nrows, ncols)`` array of them (squeezed as by pyplot).

    Examples
    --------
    >>> fig, axes = subplots(2, 1, figsize=(4, 3), sharex=True)
    >>> axes.shape, fig.get_size_inches().tolist()
    ((2,), [4.0, 3.0])
    >>> line, = axes[0].plot([0.0, 1.0], [0.0, 2.0])
    """
    fig = new_figure(figsize, layout)
    return fig, fig.subplots(*args, **kw)


def axes_grid(axes: Any, shape: tuple[int, int], figsize: tuple[float, float],
              what: str, **kw: Any) -> tuple[Any, Any]:
    """The figure and ``(rows, cols)`` array of axes a plotting function draws on: the user's
    ``axes`` (any array-like of that many :class:`~matplotlib.axes.Axes`, in row order), or a
    new figure's (:func:`new_figure`, constrained layout) when ``axes`` is None.

    Parameters
    ----------
    axes : Axes, array_like of Axes, or None
        Where to draw.
    shape : (int, int)
        The grid the function draws.
    figsize : (float, float)
        The size of a new figure, inches.
    what : str
        The function, for the message.
    **kw
        ``sharex``/``sharey`` of a new figure's grid.

    Returns
    -------
    fig : matplotlib.figure.Figure
    grid : numpy.ndarray of Axes, shape ``shape``

    Raises
    ------
    DesignError
        ``axes`` of another count, or not Axes.

    Examples
    --------
    >>> fig, grid = axes_grid(None, (2, 3), (6, 4), "plot")
    >>> grid.shape, len(fig.axes)
    ((2, 3), 6)
    >>> axes_grid(grid[0], (2, 3), (6, 4), "plot")
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: plot: axes= must hold 6 Axes (a grid of 2 x 3); found 3
    """
    from matplotlib.axes import Axes

    from .exceptions import DesignError

    if axes is None:
        fig = new_figure(figsize, "constrained")
        return fig, fig.subplots(*shape, squeeze=False, **kw)
    flat = np.ravel(np.asarray(axes, dtype=object))
    if flat.size != shape[0] * shape[1] or not all(isinstance(a, Axes) for a in flat):
        found = (f"{flat.size}" if all(isinstance(a, Axes) for a in flat)
                 else f"{type(axes).__name__} {axes!r}")
        raise DesignError(f"{what}: axes= must hold {shape[0] * shape[1]} Axes (a grid of "
                          f"{shape[0]} x {shape[1]}); found {found}")
    return flat[0].figure, flat.reshape(shape)


def plot_trajectory(traj: Any, *, title: str = "", axes: Any = None) -> Any:
    """A figure of one run: one row per plant state, left the truth (black, drawn on top) and
    every estimate, right the estimation error; then one row per estimated quantity that is
    not a plant state (estimates only). Returns a :class:`matplotlib.figure.Figure`.

    Parameters
    ----------
    traj : Trajectory
        A run of :func:`hgo_mj.simulate.simulate`.
    title : str
        The figure's title.
    axes : array_like of Axes, optional
        Where to draw: ``2 * rows`` axes, the grid ``(rows, 2)`` (one row per plant state and
        per estimated quantity that is not one); default a new figure (:func:`new_figure`).

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on: save it with ``fig.savefig(path)``, or leave it as a notebook
        cell's value (``plt.show()`` shows it when pyplot is imported).

    Examples
    --------
    >>> from hgo_mj.inputs import Multisine
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.sensors import GaussianNoise, SensorChain
    >>> from hgo_mj.simulate import simulate
    >>> plant = make_plant("pendulum", dt=0.01)
    >>> traj = simulate(plant, SensorChain([GaussianNoise(std=1e-3)], seed=0),
    ...                 {"k40": HighGainObserver(plant.system, k=40.0)},
    ...                 Multisine(amplitudes=[0.3], frequencies=[0.5]), duration=0.1,
    ...                 x0=[0.5, 0.0], seed=0)
    >>> fig = plot_trajectory(traj, title="pendulum")
    >>> [ax.get_ylabel() for ax in fig.axes[:2]]
    ['angle [rad]', 'error angle [rad]']
    >>> import tempfile
    >>> from pathlib import Path
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     fig.savefig(Path(tmp) / "pendulum.png")
    """
    n = traj.x.shape[1]
    extra: list[str] = []
    for oname in traj.observers:
        extra += [s for s in traj.extra_states(oname) if s not in extra]
    rows = n + len(extra)
    units, t_unit = units_of(traj)
    fig, axes = axes_grid(axes, (rows, 2), (11, 2.0 * rows + 1.0), "plot_trajectory",
                          sharex=True)
    colors = _colors()
    late = len(traj.t) // 5
    est = {oname: traj.estimate(oname) for oname in traj.observers}
    for i, name in enumerate(traj.state_names):
        ax, ae = axes[i]
        errs = []
        for j, oname in enumerate(traj.observers):
            if not traj.estimated(oname)[i]:
                continue  # not estimated: nothing to draw
            c = colors[j % len(colors)]
            e = traj.x[:, i] - est[oname][:, i]
            ax.plot(traj.t, est[oname][:, i], color=c, lw=0.9, ls="--", alpha=0.8, label=oname,
                    zorder=2)
            ae.plot(traj.t, e, color=c, lw=0.7, alpha=0.7, label=oname)
            errs.append(e[late:])
        # the truth last and above every estimate, so that a noisy estimate cannot hide it
        ax.plot(traj.t, traj.x[:, i], color=TRUE_COLOR, lw=1.3, label="true", zorder=3)
        unit = bracket(units.get(name))
        ax.set_ylabel(f"{name} {unit}", fontsize=9)
        rng = _finite_range(traj.x[:, i])
        if rng is not None:
            lo, hi = rng
            pad = 0.5 * (hi - lo) + 1e-9
            ax.set_ylim(lo - pad, hi + pad)  # keep the true signal readable under peaking
        ae.set_ylabel(f"error {name} {unit}", fontsize=9)
        ae.axhline(0.0, color="0.6", lw=0.6)
        rng = _finite_range(*errs) if errs else None
        if rng is not None:
            lim = 1.5 * max(abs(rng[0]), abs(rng[1])) + 1e-12
            ae.set_ylim(-lim, lim)
        elif traj.observers:
            ae.text(0.5, 0.5, "not estimated", transform=ae.transAxes, ha="center",
                    va="center", color="0.4")
    for r, name in enumerate(extra, start=n):
        ax, ae = axes[r]
        vals = []
        for j, (oname, rec) in enumerate(traj.observers.items()):
            if name in rec.state_names:
                v = rec.x_hat[:, rec.state_names.index(name)]
                ax.plot(traj.t, v, color=colors[j % len(colors)], lw=0.9, ls="--", alpha=0.85,
                        label=oname)
                vals.append(v[late:])
        ax.set_ylabel(f"{name} {bracket(units.get(name))}\n(estimate only)", fontsize=9)
        rng = _finite_range(*vals)
        if rng is not None:
            lo, hi = rng
            pad = 0.25 * (hi - lo) + 1e-9
            ax.set_ylim(lo - pad, hi + pad)  # fits t > 20% of the run, as the errors do
        ae.axis("off")
        ae.text(0.5, 0.5, f"{name}: not a plant state (no true value)", transform=ae.transAxes,
                ha="center", va="center", color="0.4")
    axes[0, 0].legend(loc="upper right", fontsize=8)
    axes[0, 0].set_title("true vs estimate", fontsize=10)
    axes[0, 1].set_title("estimation error (axis fits t > 20% of the run)", fontsize=10)
    for ax in axes[-1]:
        ax.set_xlabel(f"t {bracket(t_unit)}")
    if extra:  # the error column ends at the last plant state: its time axis is labelled there
        axes[n - 1, 1].tick_params(labelbottom=True)
        axes[n - 1, 1].set_xlabel(f"t {bracket(t_unit)}")
    if title:
        fig.suptitle(title)
    return fig


def plot_monte_carlo(result: Any, *, title: str = "", units: dict[str, str] | None = None,
                     axes: Any = None) -> Any:
    """A figure of a Monte Carlo study (:class:`hgo_mj.study.MonteCarloResult`): one panel per
    plant state that some observer estimates, the observers side by side on the panel's one
    y-axis (logarithmic where the RMSEs span a decade or more), the RMSE of every seed as a dot
    over the observer's box plot (quartiles, whiskers to 1.5 IQR, the mean as a triangle); runs
    with a NaN RMSE are left out (their count is noted). ``units``: ``{state: unit}`` for the
    axis labels (``[?]`` where missing). Returns a :class:`matplotlib.figure.Figure`.

    Parameters
    ----------
    result : MonteCarloResult
        What :func:`hgo_mj.study.monte_carlo` returns.
    title : str
        The figure's title.
    units : dict of str to str, optional
        ``{state: unit}``, e.g. :func:`hgo_mj.units.system_units` of the plant's system.
    axes : Axes or array_like of Axes, optional
        Where to draw: one axes per estimated state (in the plant's order); default a new
        figure (:func:`new_figure`) of at most 4 panels a row.

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.

    Examples
    --------
    >>> from hgo_mj.study import MonteCarloResult
    >>> def run(rmse):
    ...     return {"hgo": {"states": ["angle"], "estimated": [True], "rmse": [rmse],
    ...                     "peak": [0.5], "settling_time": [1.0], "final": [0.01],
    ...                     "update_time": 1e-6}}
    >>> result = MonteCarloResult.from_runs([0, 1, 2], [run(0.1), run(0.2), run(0.15)], {})
    >>> fig = plot_monte_carlo(result, units={"angle": "rad"})
    >>> fig.axes[0].get_ylabel()
    'RMSE angle [rad]'
    """
    runs, agg = result.runs, result.aggregate
    observers = list(agg)
    states = list(next(iter(agg.values()))["states"]) if agg else []
    units = units or {}
    shown = [i for i in range(len(states)) if any(agg[o]["estimated"][i] for o in observers)]
    cols = min(max(len(shown), 1), 4)
    rows = max(math.ceil(len(shown) / cols), 1)
    if axes is not None:  # the user's: one per shown state
        rows, cols = 1, max(len(shown), 1)
    width = max(1.0 + 0.9 * len(observers), 3.2)
    fig, grid = axes_grid(axes, (rows, cols), (width * cols + 0.6, 3.0 * rows + 0.9),
                          "plot_monte_carlo")
    colors = _colors()
    jitter = np.random.default_rng(0).uniform(-0.12, 0.12, len(runs))  # same figure every time
    for k, ax in enumerate(grid.ravel()):
        if k >= len(shown):
            ax.axis("off")
            if not shown:
                ax.text(0.5, 0.5, "no plant state is estimated", ha="center", va="center",
                        color="0.4", transform=ax.transAxes)
            continue
        i = shown[k]
        _mc_panel(ax, runs, agg, observers, i, colors, jitter)
        ax.set_title(states[i], fontsize=9)
        ax.set_ylabel(f"RMSE {states[i]} {bracket(units.get(states[i]))}", fontsize=8)
    hidden = [states[i] for i in range(len(states)) if i not in shown]
    head = f"{title}\n" if title else ""
    if axes is not None and not title:  # the user's figure keeps its own title
        return fig
    fig.suptitle(head + f"RMSE after the transient over {len(runs)} seeds"
                 + (f" (not estimated by any observer: {', '.join(hidden)})" if hidden else ""),
                 fontsize=10)
    return fig


def _mc_panel(ax: Any, runs: list[Any], agg: dict[str, Any], observers: list[str], i: int,
              colors: list[str], jitter: Any) -> None:
    """One state's panel of :func:`plot_monte_carlo`: every observer on the same y-axis."""
    from matplotlib.ticker import FuncFormatter, LogLocator

    finite: list[Any] = []
    for j, oname in enumerate(observers):
        pos = j + 1
        if not agg[oname]["estimated"][i]:
            ax.text(pos, 0.5, "not\nestimated", transform=ax.get_xaxis_transform(), ha="center",
                    va="center", color="0.4", fontsize=7)
            continue
        # the runs this observer finished (one that diverged in a run is not in it)
        v = np.array([r[oname]["rmse"][i] for r in runs if oname in r], dtype=float)
        ok = np.isfinite(v)
        if ok.any():
            ax.boxplot(v[ok], positions=[pos], showmeans=True, widths=0.5, showfliers=False,
                       medianprops={"color": "black"},
                       meanprops={"marker": "^", "markerfacecolor": "white",
                                  "markeredgecolor": "black", "markersize": 5})
            ax.plot(pos + jitter[:v.size][ok], v[ok], "o", ms=3, color=colors[j % len(colors)], alpha=0.6,
                    zorder=3)
            finite.append(v[ok])
        if not ok.all():
            ax.text(pos, 0.97, f"{int((~ok).sum())} NaN", transform=ax.get_xaxis_transform(),
                    ha="center", va="top", fontsize=7, color="0.4")
    ax.set_xticks(range(1, len(observers) + 1), [o[:14] for o in observers], rotation=20,
                  fontsize=7)
    ax.set_xlim(0.4, len(observers) + 0.6)
    ax.tick_params(labelsize=7)
    ax.grid(True, axis="y", alpha=0.3)
    vals = np.concatenate(finite) if finite else np.array([])
    if vals.size and np.all(vals > 0) and vals.max() / vals.min() >= 10:
        ax.set_yscale("log")
        ax.yaxis.set_major_locator(LogLocator(base=10))
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.yaxis.set_minor_formatter(FuncFormatter(_minor_log_label))
        ax.tick_params(which="both", labelsize=7)


def _minor_log_label(v: float, _: Any) -> str:
    """Plain labels at 2 and 5 times a power of ten on a log axis, none elsewhere."""
    if v <= 0:
        return ""
    lead = round(v / 10 ** math.floor(math.log10(v)))
    return f"{v:g}" if lead in (2, 5) else ""
