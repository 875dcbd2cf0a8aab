"""The figures of a study, drawn from its summary (medians and quartiles over the seeds).

* For each swept axis, ``axis_<path>.png``: one row of panels per estimated plant state, one
  column per metric (RMSE after the transient, peak error, settling time), the metric against
  the axis value, one line per observer (and per value of the other axes), the median with
  its interquartile band over the seeds. Axes are logarithmic where the values span a decade
  or more; every axis names its unit.
* For two axes, ``heatmap_<a>__<b>.png``: the median RMSE over both, one panel per observer
  and state (a logarithmic colour scale where it spans decades).

Figures are :class:`matplotlib.figure.Figure` objects made without pyplot: the user's backend
is left alone and nothing opens a window.
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


def _axis_label(path: str, output_unit: str) -> str:
    last = path.split(".")[-1]
    unit = _PARAM_UNITS.get(last)
    if unit is None and last in ("std", "resolution", "bias", "amplitude"):
        unit = output_unit
    return f"{path} [{unit}]" if unit else f"{path} [-]"


def _spans_decades(v: np.ndarray) -> bool:
    v = v[np.isfinite(v)]
    return bool(v.size and np.all(v > 0) and v.max() / v.min() >= 10)


def _file(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)


def _tidy(fig: Any, rows: int, top: float = 0.6) -> None:
    """Margins for labels, the legend and the title (``top`` inches; a fixed layout:
    matplotlib's constrained layout costs seconds on figures of many panels)."""
    h = fig.get_figheight()
    fig.subplots_adjust(left=0.07, right=0.97, bottom=0.55 / h, top=1 - top / h,
                        wspace=0.32, hspace=0.55 * 2.6 / max(h / max(rows, 1), 1.0))


#: at most this many curves (observer x values of the other axes) a panel; beyond, one curve
#: per observer pooled over the other axes' values
MAX_CURVES = 8


def _curves(summary: Any, table: Any, axis: str, others: list[str]
            ) -> tuple[list[tuple[str, Any]], bool]:
    """``[(label, rows)]`` to draw against ``axis`` and whether they are pooled: per observer
    and combination of the other axes (the summary's statistics over seeds), or, for more than
    :data:`MAX_CURVES` of them, per observer over every seed and other cell (from the rows)."""
    s = summary[summary["estimated"]]
    groups = list(s.groupby(["observer", *others], sort=False))
    if len(groups) <= MAX_CURVES:
        out = []
        for key, g in groups:
            parts = [str(key[0])] + [f"{o.split('.')[-1]}={v:g}" if isinstance(v, float)
                                     else f"{o.split('.')[-1]}={v}" for o, v in zip(others, key[1:])]
            out.append((", ".join(parts), g))
        return out, False
    t = table[table["estimated"] & ~table["diverged"]]
    pooled = []
    for obs, g in t.groupby("observer", sort=False):
        by = g.groupby([axis, "state"], sort=True)
        rows = {}
        for m, _ in PANELS:
            rows[f"{m}_median"] = by[m].median()
            rows[f"{m}_q25"] = by[m].quantile(0.25)
            rows[f"{m}_q75"] = by[m].quantile(0.75)
        import pandas as pd

        pooled.append((f"{obs} (pooled)", pd.DataFrame(rows).reset_index()))
    return pooled, True


def axis_figure(summary: Any, table: Any, axis: str, axes: list[str],
                unit_of: Callable[[str], str], out_unit: str, title: str) -> Any:
    """The metrics against one axis (module docstring)."""
    from matplotlib.figure import Figure

    s = summary[summary["estimated"]]
    states = list(dict.fromkeys(s["state"]))
    curves, pooled = _curves(summary, table, axis, [a for a in axes if a != axis])
    fig = Figure(figsize=(4.2 * len(PANELS), 2.6 * len(states) + 1.4))
    grid = fig.subplots(len(states), len(PANELS), squeeze=False)
    numeric = s[axis].dtype.kind == "f"
    cats = list(dict.fromkeys(s[axis])) if not numeric else []
    observers = list(dict.fromkeys(s["observer"]))
    for r, state in enumerate(states):
        for c, (metric, label) in enumerate(PANELS):
            ax = grid[r, c]
            for i, (name, g) in enumerate(curves):
                g = g[g["state"] == state].sort_values(axis)
                x = g[axis].to_numpy(dtype=float) if numeric else np.array(
                    [cats.index(v) for v in g[axis]], dtype=float)
                color = f"C{observers.index(name.split(',')[0].split(' ')[0]) % 10}"
                style = ("-", "--", ":", "-.")[i % 4] if not pooled else "-"
                ax.plot(x, g[f"{metric}_median"].to_numpy(dtype=float), marker="o", ls=style,
                        color=color, lw=1.4, ms=3.5, label=name)
                ax.fill_between(x, g[f"{metric}_q25"].to_numpy(dtype=float),
                                g[f"{metric}_q75"].to_numpy(dtype=float), color=color,
                                alpha=0.15, lw=0)
            _scales(ax, s, axis, state, metric, numeric, cats)
            yunit = "s" if metric == "settling_time" else (unit_of(state) or "-")
            ax.set_ylabel(f"{label} [{yunit}]", fontsize=8)
            ax.set_xlabel(_axis_label(axis, out_unit), fontsize=8)
            ax.set_title(state, fontsize=9)
            ax.grid(True, alpha=0.3)
            ax.tick_params(labelsize=7)
    handles, labels = grid[0, 0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="upper center", ncol=min(4, len(handles)), fontsize=7,
                   bbox_to_anchor=(0.5, 1 - 0.45 / fig.get_figheight()), frameon=False)
    how = ("pooled over the seeds and the other axes' values" if pooled
           else "over the seeds")
    fig.suptitle(f"{title}: median and interquartile band {how}", fontsize=10)
    _tidy(fig, len(states), top=0.75 + 0.2 * int(np.ceil(len(handles) / 4)))
    return fig


def _scales(ax: Any, s: Any, axis: str, state: str, metric: str, numeric: bool,
            cats: list[Any]) -> None:
    """Log scales where the values span a decade or more; category ticks for text axes."""
    if numeric and _spans_decades(s[axis].to_numpy(dtype=float)):
        ax.set_xscale("log")
        _plain_ticks(ax.xaxis)
    if not numeric:
        ax.set_xticks(range(len(cats)), [str(v)[:18] for v in cats], rotation=20, fontsize=7)
    if _spans_decades(s[s["state"] == state][f"{metric}_median"].to_numpy(dtype=float)):
        ax.set_yscale("log")
        _plain_ticks(ax.yaxis)


def heatmap_figure(summary: Any, a: str, b: str, unit_of: Callable[[str], str], out_unit: str,
                   title: str) -> Any:
    """The median RMSE over two axes, one panel per observer and state."""
    from matplotlib.colors import LogNorm
    from matplotlib.figure import Figure

    s = summary[summary["estimated"]]
    pairs = list(dict.fromkeys(zip(s["observer"], s["state"])))
    cols = min(len(pairs), 3)
    rows = int(np.ceil(len(pairs) / cols))
    fig = Figure(figsize=(4.6 * cols, 3.6 * rows + 0.6))
    grid = fig.subplots(rows, cols, squeeze=False)
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
        ax.set_xticks(range(len(xa)), [f"{v:g}" if isinstance(v, float) else str(v)
                                       for v in xa], fontsize=7)
        ax.set_yticks(range(len(xb)), [f"{v:g}" if isinstance(v, float) else str(v)
                                       for v in xb], fontsize=7)
        unit = unit_of(state) or "-"
        ax.set_xlabel(_axis_label(a, out_unit), fontsize=8)
        ax.set_ylabel(_axis_label(b, out_unit), fontsize=8)
        ax.set_title(f"{obs}: {state}", fontsize=9)
        fig.colorbar(im, ax=ax, label=f"median RMSE [{unit}]")
    for j in range(len(pairs), rows * cols):
        grid[j // cols, j % cols].set_visible(False)
    fig.suptitle(f"{title}: median RMSE over the seeds", fontsize=10)
    _tidy(fig, rows)
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
        product) and, for two axes, ``heatmap_<a>__<b>.png``; default: not saved.

    Returns
    -------
    list of matplotlib.figure.Figure
        One figure per swept axis (a ``[[sweep.together]]`` group drawn against its first
        path), and the heatmap for two axes.

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
    summary, table = result.summary(), result.table
    axes = result.plot_axes
    cells = result.study.cells
    unit_of, out_unit = _units([c.scenario for c in cells])
    title = result.study.name
    figs: list[tuple[str, Any]] = []
    for axis in axes:
        figs.append((f"axis_{_file(axis)}.png",
                     axis_figure(summary, table, axis, axes, unit_of, out_unit, title)))
    if len(axes) == 2:
        figs.append((f"heatmap_{_file(axes[0])}__{_file(axes[1])}.png",
                     heatmap_figure(summary, axes[0], axes[1], unit_of, out_unit, title)))
    if out is not None:
        for name, fig in figs:
            save_figure(fig, Path(out) / name)
    return [f for _, f in figs]


#: :func:`axis_figure` and :func:`heatmap_figure` take the study's unit lookup and are
#: internal: the public entry is :func:`study_figures` (``StudyResult.plot``)
__all__ = ["PANELS", "study_figures"]
