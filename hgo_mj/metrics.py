"""Error metrics of a :class:`~hgo_mj.simulate.Trajectory`, per observer and state.

All metrics use the error ``e = x - x_hat`` in physical coordinates, per state:

* ``rmse``: root mean square over ``t >= t_transient``;
* ``peak``: the largest ``|e|`` over the whole run (peaking of high-gain observers);
* ``settling_time``: the first time after which ``|e|`` stays inside ``band`` (absolute, or
  relative to the range of the true state when ``relative=True``); ``inf`` if it never does;
* ``final``: ``|e|`` at the last sample;
* ``update_time``: mean wall time of one observer update, seconds.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._validate import finite_scalar
from .exceptions import DesignError

Array = NDArray[np.float64]


def settling_time(t: Array, err: Array, band: float | Array) -> Array:
    """First time after which ``|err|`` stays within ``band``, per column (``inf``: never)."""
    inside = np.abs(err) <= np.asarray(band)
    out = np.full(err.shape[1], np.inf)
    for j in range(err.shape[1]):
        outside = np.flatnonzero(~inside[:, j])
        if outside.size == 0:
            out[j] = t[0]
        elif outside[-1] + 1 < t.size:
            out[j] = t[outside[-1] + 1]
    return out


def observer_metrics(traj: Any, observer: str, *, t_transient: float | None = None,
                     band: float = 0.05, relative: bool = True) -> dict[str, Any]:
    """Metrics of one observer (see the module docstring); values are lists over states."""
    if observer not in traj.observers:
        raise DesignError(f"no observer {observer!r} in the trajectory; found "
                          f"{sorted(traj.observers)}")
    t = traj.t
    if t_transient is None:
        t_transient = 0.2 * float(t[-1])
    t_transient = finite_scalar("t_transient", t_transient, nonnegative=True)
    band = finite_scalar("band", band, positive=True)
    e = traj.error(observer)
    win = t >= t_transient
    if not win.any():
        raise DesignError(f"t_transient = {t_transient:g} leaves no samples (run ends at "
                          f"{t[-1]:g})")
    scale = np.ptp(traj.x, axis=0) if relative else np.ones(e.shape[1])
    scale = np.where(scale > 0, scale, 1.0)
    finite = np.isfinite(e)
    return {
        "states": list(traj.state_names),
        "rmse": np.sqrt(np.nanmean(e[win] ** 2, axis=0)).tolist(),
        "peak": np.nanmax(np.abs(e), axis=0).tolist(),
        "settling_time": settling_time(t, np.where(finite, e, np.inf), band * scale).tolist(),
        "final": np.abs(e[-1]).tolist(),
        "update_time": traj.observers[observer].update_time,
        "t_transient": t_transient,
        "band": band,
        "band_relative_to_range": relative,
    }


def all_metrics(traj: Any, **kw: Any) -> dict[str, dict[str, Any]]:
    """:func:`observer_metrics` for every observer of the trajectory."""
    return {name: observer_metrics(traj, name, **kw) for name in traj.observers}


def format_table(metrics: dict[str, dict[str, Any]]) -> str:
    """A plain-text table: one row per observer and state."""
    lines = [f"{'observer':<16} {'state':<18} {'rmse':>11} {'peak':>11} {'settle[s]':>10} "
             f"{'final':>11} {'update[us]':>10}"]
    for name, m in metrics.items():
        for i, s in enumerate(m["states"]):
            lines.append(f"{name:<16} {s:<18} {m['rmse'][i]:>11.4g} {m['peak'][i]:>11.4g} "
                         f"{m['settling_time'][i]:>10.4g} {m['final'][i]:>11.4g} "
                         f"{m['update_time'] * 1e6:>10.3g}")
    return "\n".join(lines)
