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


def _state_unit(scenario: dict[str, Any], state: str) -> str:
    from ..systems import SYSTEMS

    cls = SYSTEMS.get(str(scenario.get("plant", {}).get("name")))
    return cls.unit(state) if cls is not None else ""


def _output_unit(scenario: dict[str, Any]) -> str:
    """The unit of the first measured output (where it is a state: a noise std's unit)."""
    from ..systems import SYSTEMS

    cls = SYSTEMS.get(str(scenario.get("plant", {}).get("name")))
    return cls.unit(cls.output_names[0]) if cls is not None and cls.output_names else ""


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


def _tidy(fig: Any, rows: int) -> None:
    """Margins for labels and the title (a fixed layout: matplotlib's constrained layout
    costs seconds on figures of many panels)."""
    h = fig.get_figheight()
    fig.subplots_adjust(left=0.07, right=0.97, bottom=0.55 / h, top=1 - 0.6 / h,
                        wspace=0.32, hspace=0.55 * 2.6 / max(h / max(rows, 1), 1.0))


def axis_figure(summary: Any, axis: str, axes: list[str], scenario: dict[str, Any],
                title: str) -> Any:
    """The metrics against one axis (module docstring)."""
    from matplotlib.figure import Figure

    s = summary[summary["estimated"]]
    states = list(dict.fromkeys(s["state"]))
    others = [a for a in axes if a != axis]
    fig = Figure(figsize=(4.2 * len(PANELS), 2.6 * len(states) + 0.9))
    grid = fig.subplots(len(states), len(PANELS), squeeze=False)
    numeric = s[axis].dtype.kind == "f"
    cats = list(dict.fromkeys(s[axis])) if not numeric else []
    out_unit = _output_unit(scenario)
    groups = list(s.groupby(["observer", *others], sort=False))
    observers = list(dict.fromkeys(s["observer"]))
    combos = list(dict.fromkeys(tuple(k[1:]) for k, _ in groups))
    colors = [f"C{observers.index(k[0]) % 10}" for k, _ in groups]
    styles = [("-", "--", ":", "-.")[combos.index(tuple(k[1:])) % 4] for k, _ in groups]
    for r, state in enumerate(states):
        unit = _state_unit(scenario, state)
        for c, (metric, label) in enumerate(PANELS):
            ax = grid[r, c]
            for (key, g), color, style in zip(groups, colors, styles):
                g = g[g["state"] == state].sort_values(axis)
                x = g[axis].to_numpy(dtype=float) if numeric else np.array(
                    [cats.index(v) for v in g[axis]], dtype=float)
                med = g[f"{metric}_median"].to_numpy(dtype=float)
                lo = g[f"{metric}_q25"].to_numpy(dtype=float)
                hi = g[f"{metric}_q75"].to_numpy(dtype=float)
                name = ", ".join(
                    [str(key[0])] + [f"{o.split('.')[-1]}={v:g}" if isinstance(v, float)
                                     else f"{o.split('.')[-1]}={v}" for o, v in zip(others,
                                                                                    key[1:])])
                ax.plot(x, med, marker="o", ls=style, color=color, lw=1.4, ms=3.5, label=name)
                ax.fill_between(x, lo, hi, color=color, alpha=0.2, lw=0)
            xs = s[axis].to_numpy(dtype=float) if numeric else np.arange(len(cats), dtype=float)
            if numeric and _spans_decades(xs):
                ax.set_xscale("log")
                _plain_ticks(ax.xaxis)
            if not numeric:
                ax.set_xticks(range(len(cats)), [str(v)[:18] for v in cats], rotation=20,
                              fontsize=7)
            ys = s[s["state"] == state][f"{metric}_median"].to_numpy(dtype=float)
            if _spans_decades(ys):
                ax.set_yscale("log")
                _plain_ticks(ax.yaxis)
            yunit = "s" if metric == "settling_time" else (unit or "-")
            ax.set_ylabel(f"{label} [{yunit}]", fontsize=8)
            ax.set_xlabel(_axis_label(axis, out_unit), fontsize=8)
            ax.set_title(state, fontsize=9)
            ax.grid(True, alpha=0.3)
            ax.tick_params(labelsize=7)
    if groups:
        grid[0, 0].legend(fontsize=7, loc="best")
    fig.suptitle(f"{title}: median and interquartile band over the seeds", fontsize=10)
    _tidy(fig, len(states))
    return fig


def heatmap_figure(summary: Any, a: str, b: str, scenario: dict[str, Any], title: str) -> Any:
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
        unit = _state_unit(scenario, state) or "-"
        ax.set_xlabel(_axis_label(a, _output_unit(scenario)), fontsize=8)
        ax.set_ylabel(_axis_label(b, _output_unit(scenario)), fontsize=8)
        ax.set_title(f"{obs}: {state}", fontsize=9)
        fig.colorbar(im, ax=ax, label=f"median RMSE [{unit}]")
    for j in range(len(pairs), rows * cols):
        grid[j // cols, j % cols].set_visible(False)
    fig.suptitle(f"{title}: median RMSE over the seeds", fontsize=10)
    _tidy(fig, rows)
    return fig


def study_figures(result: Any, out: str | Path | None = None) -> list[Any]:
    """Every figure of a study (module docstring); saved as PNG into ``out`` if given."""
    summary = result.summary()
    axes = result.plot_axes
    scenario = result.study.spec.scenario
    title = result.study.name
    figs: list[tuple[str, Any]] = []
    for axis in axes:
        figs.append((f"axis_{_file(axis)}.png", axis_figure(summary, axis, axes, scenario,
                                                             title)))
    if len(axes) == 2:
        figs.append((f"heatmap_{_file(axes[0])}__{_file(axes[1])}.png",
                     heatmap_figure(summary, axes[0], axes[1], scenario, title)))
    if out is not None:
        for name, fig in figs:
            save_figure(fig, Path(out) / name)
    return [f for _, f in figs]


__all__ = ["axis_figure", "heatmap_figure", "study_figures"]
