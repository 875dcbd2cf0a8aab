"""The figures of a study, drawn from its rows (medians and quartiles over the seeds).

* For each swept axis, ``axis_<path>.png``, in the manner of seaborn's ``relplot``: one
  column per metric (RMSE after the transient, peak error, settling time) against the axis,
  one line per value of the next swept axis (the hue; the observers when nothing else is
  swept) with its interquartile band over the seeds, and one row of panels (a facet) per
  observer, value of the remaining axes and estimated state. Beyond :data:`MAX_FACETS`
  facets the remaining axes are pooled (said in the title). Axes are logarithmic where the
  values span a decade or more; every axis names its unit.
* For two axes, ``heatmap_<a>__<b>.png``: the median RMSE over both, one panel per observer
  and state.
* For a study of an observer's gain ``k`` and a noise level (``observers.NAME.k`` and
  ``sensor.stages.I.std``), ``best_gain.png``: per state (and value of the other axes) the
  best gain ``k*`` at each noise level (the minimum of the median RMSE over the gain grid,
  refined by a parabola in log-log coordinates, :func:`best_gain`) with its fitted power law
  ``k* ~ sigma^slope``, beside the slope ``-1/n`` of the bound ``a/k + b sigma k^(n-1)``.

Each figure function takes ``axes=`` (the grid to draw on); without it the figure is
:func:`hgo_mj.plotting.new_figure`'s (pyplot's when the user has imported pyplot, else one
without it: the user's backend is left alone and nothing opens a window).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .._io import save_figure

#: the metrics drawn against each axis, with their labels
PANELS = (("rmse", "RMSE after the transient"), ("peak", "peak error"),
          ("settling_time", "settling time"))

#: units of common swept parameters, by the last part of their path
_PARAM_UNITS = {"k": "1/s", "sample_period": "s", "control_period": "s", "duration": "s",
                "dt": "s", "t_transient": "s", "delay": "s", "k0": "1/s"}


def _units(scenarios: list[dict[str, Any]]) -> tuple[Callable[[str], str], str]:
    """``(unit of a state, unit of the first measured output)`` over the plants a study's
    cells name (a state's unit from the first plant that has it; ``""`` when undeclared)."""
    from ..systems import SYSTEMS

    names = list(dict.fromkeys(str(sc.get("plant", {}).get("name")) for sc in scenarios))
    systems = [SYSTEMS[n] for n in names if n in SYSTEMS]
    units: dict[str, str] = {}
    for cls in systems:
        for st in cls.state_names:
            units.setdefault(st, cls.unit(st))
    first = systems[0] if systems else None
    out = first.unit(first.output_names[0]) if first is not None and first.output_names else ""
    return (lambda state: units.get(state, "")), out


def _plain_ticks(axis: Any) -> None:
    """Tick labels as plain numbers (``20``, ``0.001``) on a log axis, no minor labels."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(NullFormatter())


def _log_labels(axis: Any) -> None:
    """Plain labels on a log axis at the powers of ten and at 2 and 5 times them (a range
    under a decade still gets labels)."""
    from matplotlib.ticker import FuncFormatter

    from ..plotting import _minor_log_label

    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(FuncFormatter(_minor_log_label))


def _axis_label(path: str, output_unit: str) -> str:
    last = path.split(".")[-1]
    unit = _PARAM_UNITS.get(last)
    if unit is None and last in ("std", "resolution", "bias", "amplitude"):
        unit = output_unit
    return f"{path} [{unit}]" if unit else f"{path} [-]"


def _spans_decades(v: np.ndarray) -> bool:
    v = np.ravel(v)
    v = v[np.isfinite(v)]
    return bool(v.size and np.all(v > 0) and v.max() / v.min() >= 10)


def _file(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)


def _tidy(fig: Any, rows: int, top: float = 0.6) -> None:
    """Margins for labels, the legend and the title (``top`` inches; a fixed layout:
    matplotlib's constrained layout costs seconds on figures of many panels). A figure with
    a layout engine (the user's, or pyplot's default) is left to it."""
    if fig.get_layout_engine() is not None:
        return
    h = fig.get_figheight()
    fig.subplots_adjust(left=0.08, right=0.97, bottom=0.6 / h, top=1 - top / h,
                        wspace=0.34, hspace=0.62 * 2.6 / max(h / max(rows, 1), 1.0))


def _grid(axes: Any, shape: tuple[int, int], figsize: tuple[float, float],
          what: str) -> tuple[Any, Any, bool]:
    """The user's axes or a new figure's without a layout engine (:func:`_tidy` lays it
    out); and whether the figure is this function's own."""
    from ..plotting import axes_grid, new_figure

    if axes is not None:
        fig, grid = axes_grid(axes, shape, figsize, what)
        return fig, grid, False
    fig = new_figure(figsize)
    fig.set_layout_engine("none")
    return fig, fig.subplots(*shape, squeeze=False), True


#: at most this many facets (rows of panels) an axis figure draws; beyond, the axes after the
#: hue are pooled
MAX_FACETS = 12


def _value(v: Any) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _short(path: str) -> str:
    """A swept path's last word for labels (``plant.name``: ``plant``)."""
    return "plant" if path == "plant.name" else path.split(".")[-1]


def _stats(table: Any, keys: list[str]) -> Any:
    """The statistics over the seeds (and any axis left out of ``keys``) per combination of
    ``keys`` (:func:`hgo_mj.study.results.summarize`'s definitions)."""
    from .results import summarize

    swept = [k for k in keys if k not in ("observer", "state")]
    t = table[table["estimated"]].copy()
    t["cell"] = (t[swept].astype(str).agg("\x1f".join, axis=1).factorize()[0] if swept
                 else 0)
    return summarize(t, swept)


def _units_of(result: Any) -> tuple[Callable[[str], str], str]:
    return _units([c.scenario for c in result.study.cells])


def varying_axes(result: Any) -> list[str]:
    """The plotted axes along which some observer's estimate of some state varies: an axis
    that changes the states (``plant.name``: each plant its own) is a facet, not a line.

    Parameters
    ----------
    result : StudyResult

    Returns
    -------
    list of str
        In the order of :attr:`~hgo_mj.study.StudyResult.plot_axes`.

    Examples
    --------
    >>> import tempfile
    >>> from hgo_mj.study import Study
    >>> scenario = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.5, 0.0]},
    ...             "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
    ...             "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...             "run": {"duration": 0.5, "t_transient": 0.1}}
    >>> axes = {"observers.hgo.k": [10.0, 20.0, 40.0], "sensor.stages.0.std": [1e-4, 1e-2]}
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     result = Study(scenario, axes).run(tmp, quiet=True)
    ...     varying = varying_axes(result)
    >>> varying
    ['observers.hgo.k', 'sensor.stages.0.std']
    """
    t = result.table[result.table["estimated"]]
    g = t.groupby(["observer", "state"])
    return [a for a in result.plot_axes if int(g[a].nunique().max()) > 1]


def axis_figure(result: Any, axis: str, *, axes: Any = None) -> Any:
    """Each metric against one swept axis (module docstring): columns the metrics, one line
    per value of the next axis, a row per observer, value of the remaining axes and state.

    Parameters
    ----------
    result : StudyResult
        A finished study.
    axis : str
        One of its :func:`varying_axes`.
    axes : array_like of Axes, optional
        Where to draw: ``3 * facets`` axes, a grid ``(facets, 3)``; default a new figure.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import tempfile
    >>> from hgo_mj.study import Study
    >>> scenario = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.5, 0.0]},
    ...             "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
    ...             "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...             "run": {"duration": 0.5, "t_transient": 0.1}}
    >>> axes = {"observers.hgo.k": [10.0, 20.0, 40.0], "sensor.stages.0.std": [1e-4, 1e-2]}
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     result = Study(scenario, axes).run(tmp, quiet=True)
    ...     fig = axis_figure(result, "observers.hgo.k")
    >>> [ln.get_label() for ln in fig.axes[0].get_lines()]
    ['std = 0.0001', 'std = 0.01']
    """
    from .._validate import one_of

    every = list(result.plot_axes)
    varying = varying_axes(result)
    one_of("axis", axis, varying)
    unit_of, out_unit = _units_of(result)
    i = varying.index(axis)
    hue = varying[(i + 1) % len(varying)] if len(varying) > 1 else None
    rest = [a for a in every if a not in (axis, hue)]
    table = result.table[~result.table["diverged"]]
    by = ["observer", *rest, "state"]
    facets = list(dict.fromkeys(map(tuple, table[table["estimated"]][by].astype(str).values)))
    pooled = len(facets) > MAX_FACETS and bool(rest)
    if pooled:
        rest, by = [], ["observer", "state"]
    keys = list(dict.fromkeys([axis, *([hue] if hue else []), *by]))
    s = _stats(table, keys)
    facets = list(dict.fromkeys(map(tuple, s[by].values.tolist())))
    numeric = s[axis].dtype.kind in "fi"
    cats = [] if numeric else list(dict.fromkeys(s[axis]))
    hues = list(dict.fromkeys(s[hue])) if hue else ["all"]
    if hue and s[hue].dtype.kind in "fi":
        hues = sorted(hues)
    colors = _hue_colors(len(hues))
    fig, grid, own = _grid(axes, (len(facets), len(PANELS)),
                           (4.0 * len(PANELS), 2.5 * len(facets) + 1.6), "axis_figure")
    for r, facet in enumerate(facets):
        f = s[np.logical_and.reduce([s[k] == v for k, v in zip(by, facet)])]
        state = facet[-1]
        for c, (metric, label) in enumerate(PANELS):
            ax = grid[r, c]
            _lines(ax, f, axis, hue, hues, metric, colors, cats)
            _scales(ax, s, f, axis, metric, numeric, cats)
            yunit = "s" if metric == "settling_time" else (unit_of(state) or "-")
            ax.set_ylabel(f"{label} [{yunit}]", fontsize=8)
            ax.set_xlabel(_axis_label(axis, out_unit), fontsize=8)
            ax.set_title(", ".join([facet[0], *(f"{_short(k)} = {v}" for k, v in
                                                zip(rest, facet[1:-1])), state]), fontsize=8)
            ax.grid(True, alpha=0.3)
            ax.tick_params(labelsize=7)
    handles, labels = grid[0, 0].get_legend_handles_labels()
    ncol = min(6, max(len(handles), 1))
    h = fig.get_figheight()
    if own:
        how = (f"over the seeds, pooled over "
               f"{', '.join(a for a in every if a not in (axis, hue))}" if pooled
               else "over the seeds")
        fig.suptitle(f"{result.study.name}: median and interquartile band {how}", fontsize=10,
                     y=1 - 0.1 / h, va="top")
    if handles and hue:
        fig.legend(handles, labels, loc="upper center", ncol=ncol, fontsize=7, frameon=False,
                   bbox_to_anchor=(0.5, 1 - 0.38 / h),
                   title=f"one line per {_axis_label(hue, out_unit)}", title_fontsize=7)
    legend_rows = int(np.ceil(len(handles) / ncol)) if hue else 0
    _tidy(fig, len(facets), top=0.75 + 0.2 * (legend_rows + 1) + 0.25)
    return fig


def _lines(ax: Any, f: Any, axis: str, hue: str | None, hues: list[Any], metric: str,
           colors: list[Any], cats: list[Any]) -> None:
    """One panel of :func:`axis_figure`: the facet ``f``'s median of ``metric`` against
    ``axis`` (category positions where ``cats``), a line and its interquartile band per value
    of ``hue``."""
    for j, hv in enumerate(hues):
        g = (f[f[hue] == hv] if hue else f).sort_values(axis)
        if not len(g):
            continue
        x = np.array([cats.index(v) for v in g[axis]], dtype=float) if cats else g[
            axis].to_numpy(dtype=float)
        ax.plot(x, g[f"{metric}_median"].to_numpy(dtype=float), marker="o", color=colors[j],
                lw=1.4, ms=3.5, label=f"{_short(hue)} = {_value(hv)}" if hue else "median")
        ax.fill_between(x, g[f"{metric}_q25"].to_numpy(dtype=float),
                        g[f"{metric}_q75"].to_numpy(dtype=float), color=colors[j], alpha=0.15,
                        lw=0)


def _hue_colors(n: int) -> list[Any]:
    """The default colour cycle for up to 10 lines, else a sequential colormap."""
    if n <= 10:
        return [f"C{i}" for i in range(n)]
    from matplotlib import colormaps

    return [colormaps["viridis"](v) for v in np.linspace(0.0, 0.9, n)]


def _scales(ax: Any, s: Any, facet: Any, axis: str, metric: str, numeric: bool,
            cats: list[Any]) -> None:
    """Log scales where the values span a decade or more (the axis over the study, a metric
    over the panel's facet); category ticks for text axes."""
    if numeric and _spans_decades(s[axis].to_numpy(dtype=float)):
        x = s[axis].to_numpy(dtype=float)
        ax.set_xscale("log")
        ax.set_xlim(x.min() / 1.3, x.max() * 1.3)  # also where the panel has no finite value
        _plain_ticks(ax.xaxis)
    if not numeric:
        ax.set_xticks(range(len(cats)), [str(v)[:18] for v in cats], rotation=20, ha="right",
                      fontsize=7)
    if _spans_decades(facet[[f"{metric}_median", f"{metric}_q25"]].to_numpy(dtype=float)):
        ax.set_yscale("log")
        _plain_ticks(ax.yaxis)


def heatmap_figure(result: Any, a: str, b: str, *, axes: Any = None) -> Any:
    """The median RMSE over two axes, one panel per observer and state.

    Parameters
    ----------
    result : StudyResult
        A finished study.
    a, b : str
        Two of its axes: ``a`` across, ``b`` up.
    axes : array_like of Axes, optional
        Where to draw: one axes per observer and state; default a new figure (3 a row).

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import tempfile
    >>> from hgo_mj.study import Study
    >>> scenario = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.5, 0.0]},
    ...             "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
    ...             "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...             "run": {"duration": 0.5, "t_transient": 0.1}}
    >>> axes = {"observers.hgo.k": [10.0, 20.0, 40.0], "sensor.stages.0.std": [1e-4, 1e-2]}
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     result = Study(scenario, axes).run(tmp, quiet=True)
    ...     fig = heatmap_figure(result, "observers.hgo.k", "sensor.stages.0.std")
    >>> [ax.get_title() for ax in fig.axes if ax.get_title()]
    ['hgo: angle', 'hgo: angular_velocity']
    """
    from matplotlib.colors import LogNorm

    unit_of, out_unit = _units_of(result)
    s = result.summary()
    s = s[s["estimated"]]
    pairs = list(dict.fromkeys(zip(s["observer"], s["state"])))
    cols = min(len(pairs), 3) if axes is None else len(pairs)
    rows = int(np.ceil(len(pairs) / cols))
    fig, grid, own = _grid(axes, (rows, cols), (5.0 * cols, 3.9 * rows + 0.8),
                           "heatmap_figure")
    for i, (obs, state) in enumerate(pairs):
        ax = grid[i // cols, i % cols]
        g = s[(s["observer"] == obs) & (s["state"] == state)]
        xa = sorted(dict.fromkeys(g[a]), key=lambda v: (isinstance(v, str), v))
        xb = sorted(dict.fromkeys(g[b]), key=lambda v: (isinstance(v, str), v))
        M = np.full((len(xb), len(xa)), np.nan)
        for _, r in g.iterrows():
            M[xb.index(r[b]), xa.index(r[a])] = r["rmse_median"]
        norm = LogNorm() if _spans_decades(M.ravel()) else None
        im = ax.imshow(M, origin="lower", aspect="auto", norm=norm, cmap="viridis")
        ax.set_xticks(range(len(xa)), [_value(v) for v in xa], fontsize=7, rotation=45,
                      ha="right")
        ax.set_yticks(range(len(xb)), [_value(v) for v in xb], fontsize=7)
        ax.set_xlabel(_axis_label(a, out_unit), fontsize=8)
        ax.set_ylabel(_axis_label(b, out_unit), fontsize=8)
        ax.set_title(f"{obs}: {state}", fontsize=9)
        cb = fig.colorbar(im, ax=ax, fraction=0.08, pad=0.03)
        cb.set_label(f"median RMSE [{unit_of(state) or '-'}]", fontsize=8)
        cb.ax.tick_params(labelsize=7)
        if norm is not None:  # plain numbers, no crowded minor labels
            _plain_ticks(cb.ax.yaxis)
    for j in range(len(pairs), rows * cols):
        grid[j // cols, j % cols].set_visible(False)
    if own:
        fig.suptitle(f"{result.study.name}: median RMSE over the seeds", fontsize=10)
    if fig.get_layout_engine() is None:
        h, w = fig.get_figheight(), fig.get_figwidth()
        fig.subplots_adjust(left=0.9 / w, right=1 - 0.9 / w, bottom=0.85 / h,
                            top=1 - 0.65 / h, wspace=0.55, hspace=0.6 * 3.9 / max(h / rows, 1))
    return fig


#: a swept observer gain and a swept noise level (:func:`best_gain_figure`)
_GAIN = re.compile(r"^observers\.[^.]+\.k$")
_NOISE = re.compile(r"^sensor\.stages\.\d+\.std$")


def gain_noise_axes(axes: list[str]) -> tuple[str, str] | None:
    """``(gain axis, noise axis)`` of a study that sweeps an observer's ``k`` and a noise
    ``std``, or None.

    Parameters
    ----------
    axes : list of str
        The swept paths.

    Returns
    -------
    (str, str) or None

    Examples
    --------
    >>> gain_noise_axes(["plant.name", "observers.hgo.k", "sensor.stages.0.std"])
    ('observers.hgo.k', 'sensor.stages.0.std')
    >>> gain_noise_axes(["observers.hgo.k"]) is None
    True
    """
    gain = next((a for a in axes if _GAIN.match(a)), None)
    noise = next((a for a in axes if _NOISE.match(a)), None)
    return None if gain is None or noise is None else (gain, noise)


def best_gain(k: Any, rmse: Any) -> tuple[float, bool]:
    """``(k*, interior)``: the gain of least RMSE, refined by a parabola in (log k, log RMSE)
    through the grid minimum and its neighbours; ``interior`` is False at the grid's edge.

    Parameters
    ----------
    k : array_like
        The gains, increasing, > 0.
    rmse : array_like
        The median RMSE at each gain, > 0 (NaN: left out).

    Returns
    -------
    (float, bool)

    Examples
    --------
    >>> k = np.array([1.0, 10.0, 100.0])
    >>> k_star, interior = best_gain(k, 1 / k + 0.01 * k)  # a/k + b k: least at k = 10
    >>> round(k_star, 6), interior
    (10.0, True)
    """
    k, rmse = np.asarray(k, dtype=float), np.asarray(rmse, dtype=float)
    i = int(np.nanargmin(rmse))
    if i == 0 or i == len(k) - 1:
        return float(k[i]), False
    x, y = np.log(k[i - 1:i + 2]), np.log(rmse[i - 1:i + 2])
    a, b, _ = np.polyfit(x, y, 2)
    if a <= 0:
        return float(k[i]), True
    return float(np.exp(np.clip(-b / (2 * a), x[0], x[2]))), True


def best_gains(result: Any) -> Any:
    """The best gain per noise level (:func:`best_gain`) of a gain x noise study, per state
    and value of its other axes, with the power law fitted to the interior minima.

    Parameters
    ----------
    result : StudyResult
        A study that sweeps ``observers.NAME.k`` and ``sensor.stages.I.std``
        (:func:`gain_noise_axes`).

    Returns
    -------
    pandas.DataFrame
        One row per group (``observer``, the other axes, ``state``) and noise level: the noise
        level ``sigma``, ``k_star``, ``interior``, ``rmse_min``, and per group the fitted
        ``slope`` of ``log k*`` against ``log sigma`` (NaN with fewer than two interior
        minima) and ``order`` (the plant's normal-form order n, NaN where unknown).

    Raises
    ------
    DesignError
        The study sweeps no observer gain or no noise level.

    Examples
    --------
    >>> import tempfile
    >>> from hgo_mj.study import Study
    >>> scenario = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.5, 0.0]},
    ...             "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
    ...             "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...             "run": {"duration": 0.5, "t_transient": 0.1}}
    >>> axes = {"observers.hgo.k": [10.0, 20.0, 40.0], "sensor.stages.0.std": [1e-4, 1e-2]}
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     result = Study(scenario, axes).run(tmp, quiet=True)
    ...     bg = best_gains(result)
    >>> bg[["state", "sigma"]].values.tolist()[:2]
    [['angle', 0.0001], ['angle', 0.01]]
    """
    import pandas as pd

    from ..exceptions import DesignError
    from ..systems import SYSTEMS

    found = gain_noise_axes(list(result.axes))
    if found is None:
        raise DesignError(f"best_gains needs a swept observers.NAME.k and sensor.stages.I.std; "
                          f"found the axes {list(result.axes)}")
    gain, noise = found
    name = gain.split(".")[1]
    others = [a for a in result.axes if a not in found]
    s = result.summary()
    s = s[(s["observer"] == name) & s["estimated"]]
    rows = []
    for key, g in s.groupby([*others, "state"], sort=False):
        key = key if isinstance(key, tuple) else (key,)
        group = dict(zip([*others, "state"], key))
        plant = group.get("plant.name") or result.study.cells[0].scenario["plant"].get("name")
        cls = SYSTEMS.get(str(plant))
        order = getattr(cls, "normal_form_order", None) if cls is not None else None
        found_rows = []
        for sigma, h in g.groupby(noise, sort=True):
            h = h.sort_values(gain)
            k_star, interior = best_gain(h[gain], h["rmse_median"])
            found_rows.append({"observer": name, **group, "sigma": float(sigma),
                               "k_star": k_star, "interior": interior,
                               "rmse_min": float(h["rmse_median"].min())})
        inner = [r for r in found_rows if r["interior"]]
        slope = (float(np.polyfit(np.log([r["sigma"] for r in inner]),
                                  np.log([r["k_star"] for r in inner]), 1)[0])
                 if len(inner) >= 2 else np.nan)
        rows += [{**r, "slope": slope, "order": float(order) if order else np.nan}
                 for r in found_rows]
    return pd.DataFrame(rows)


def best_gain_figure(result: Any, *, axes: Any = None) -> Any:
    """The best gain against the noise level of a gain x noise study (:func:`best_gains`),
    log-log: one panel per state (a row per value of the other axes), the minima found inside
    the gain grid filled (those at its edge hollow, left out of the fit), the fitted power
    law and the slope ``-1/n`` of the bound ``a/k + b sigma k^(n-1)``.

    Parameters
    ----------
    result : StudyResult
        A study that sweeps ``observers.NAME.k`` and ``sensor.stages.I.std``.
    axes : array_like of Axes, optional
        Where to draw: one per group (other axes' values and state); default a new figure.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import tempfile
    >>> from hgo_mj.study import Study
    >>> scenario = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.5, 0.0]},
    ...             "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
    ...             "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...             "run": {"duration": 0.5, "t_transient": 0.1}}
    >>> axes = {"observers.hgo.k": [10.0, 20.0, 40.0], "sensor.stages.0.std": [1e-4, 1e-2]}
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     result = Study(scenario, axes).run(tmp, quiet=True)
    ...     fig = best_gain_figure(result)
    >>> fig.axes[0].get_ylabel()
    'best gain k* [1/s]'
    """
    bg = best_gains(result)
    gain, noise = gain_noise_axes(list(result.axes))  # type: ignore[misc]
    others = [a for a in result.axes if a not in (gain, noise)]
    _, out_unit = _units_of(result)
    outer = list(dict.fromkeys(map(tuple, bg[others].values.tolist()))) if others else [()]
    per = [list(dict.fromkeys(bg[np.logical_and.reduce(
        [bg[k] == v for k, v in zip(others, o)] or [np.ones(len(bg), bool)])]["state"]))
        for o in outer]
    cols = max(len(p) for p in per)
    shape = (len(outer), cols) if axes is None else (1, sum(len(p) for p in per))
    fig, grid, own = _grid(axes, shape, (3.6 * cols, 3.2 * len(outer) + 1.0),
                           "best_gain_figure")
    slot = 0
    for r, (o, states) in enumerate(zip(outer, per)):
        for c in range(len(states), cols if axes is None else 0):
            grid[r, c].set_visible(False)
        for c, state in enumerate(states):
            ax = grid[r, c] if axes is None else grid[0, slot]
            slot += 1
            sel = bg[np.logical_and.reduce([bg[k] == v for k, v in zip(others, o)]
                                           + [bg["state"] == state])]
            inner = sel[sel["interior"]]
            ax.plot(inner["sigma"], inner["k_star"], "o", color="C0", label="k* inside the grid")
            edge = sel[~sel["interior"]]
            if len(edge):
                ax.plot(edge["sigma"], edge["k_star"], "o", mfc="none", color="C0",
                        label="k* at the grid's edge")
            slope, n = float(sel["slope"].iloc[0]), float(sel["order"].iloc[0])
            if np.isfinite(slope):
                x = np.geomspace(inner["sigma"].min(), inner["sigma"].max(), 20)
                c0 = np.exp(np.mean(np.log(inner["k_star"]) - slope * np.log(inner["sigma"])))
                ax.plot(x, c0 * x ** slope, "-", color="C1",
                        label=f"fit k* ~ sigma^{slope:.2f}")
                if np.isfinite(n):
                    ax.plot(x, c0 * x[0] ** (slope + 1 / n) * x ** (-1 / n), "--", color="0.5",
                            label=f"theory sigma^{-1 / n:.2f} (n = {n:g})")
            ax.set_xscale("log")
            ax.set_yscale("log")
            _log_labels(ax.yaxis)
            ax.set_xlabel(_axis_label(noise, out_unit), fontsize=8)
            ax.set_ylabel(f"best gain k* [{_PARAM_UNITS['k']}]", fontsize=8)
            ax.set_title(", ".join([*(f"{_short(k)} = {_value(v)}" for k, v in zip(others, o)),
                                    state]), fontsize=8)
            ax.grid(True, which="both", alpha=0.3)
            ax.tick_params(which="both", labelsize=7)  # the minor labels too (2, 5 x 10^i)
            ax.legend(fontsize=6, loc="best")
    if own:
        fig.suptitle(f"{result.study.name}: the best gain of {gain.split('.')[1]} per noise "
                     f"level (minimum of the median RMSE over the seeds)", fontsize=10)
    _tidy(fig, len(outer), top=0.75)
    return fig


def study_figures(result: Any, out: str | Path | None = None) -> list[Any]:
    """Every figure of a study (module docstring); saved as PNG into ``out`` if given.

    :meth:`hgo_mj.study.StudyResult.plot` calls it.

    Parameters
    ----------
    result : StudyResult
        A finished study (its summary, table, axes and cells' scenarios are read).
    out : str or Path, optional
        A folder to save the figures in, as ``axis_<path>.png`` (one per unit of the
        product), for two axes ``heatmap_<a>__<b>.png``, and for a gain x noise study
        ``best_gain.png``; default: not saved.

    Returns
    -------
    list of matplotlib.figure.Figure
        One figure per swept axis along which a state's metrics vary (:func:`varying_axes`;
        a ``[[sweep.together]]`` group drawn against its first path), the heatmap for two
        axes, the best gain for a gain x noise study.

    Examples
    --------
    >>> import os, tempfile
    >>> from hgo_mj.study import Study
    >>> scenario = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.5, 0.0]},
    ...             "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...             "input": {"type": "constant", "value": 0.0},
    ...             "run": {"duration": 0.2, "t_transient": 0.1}}
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     result = Study(scenario, {"observers.hgo.k": [20.0, 40.0]}).run(tmp, quiet=True)
    ...     figs = study_figures(result, out=tmp)
    ...     pngs = sorted(f for f in os.listdir(tmp) if f.endswith(".png"))
    >>> len(figs), pngs
    (1, ['axis_observers.hgo.k.png'])
    """
    axes = result.plot_axes
    figs: list[tuple[str, Any]] = [(f"axis_{_file(axis)}.png", axis_figure(result, axis))
                                   for axis in varying_axes(result)]
    if len(axes) == 2:
        figs.append((f"heatmap_{_file(axes[0])}__{_file(axes[1])}.png",
                     heatmap_figure(result, axes[0], axes[1])))
    if gain_noise_axes(list(result.axes)) is not None:
        figs.append(("best_gain.png", best_gain_figure(result)))
    if out is not None:
        for name, fig in figs:
            save_figure(fig, Path(out) / name)
    return [f for _, f in figs]


__all__ = ["MAX_FACETS", "PANELS", "axis_figure", "best_gain", "best_gain_figure", "best_gains",
           "gain_noise_axes", "heatmap_figure", "study_figures", "varying_axes"]
