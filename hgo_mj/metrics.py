"""Error metrics of a :class:`~hgo_mj.simulate.Trajectory`, per observer and state.

All metrics use the error ``e = x - x_hat`` in physical coordinates, per plant state
(:meth:`~hgo_mj.simulate.Trajectory.error`: the estimate's columns matched to the plant's states
by name):

* ``rmse``: root mean square over ``t >= t_transient``;
* ``peak``: the largest ``|e|`` over the whole run (peaking of high-gain observers);
* ``settling_time``: the first time after which ``|e|`` stays inside ``band`` (absolute, or
  relative to the range of the true state when ``relative=True``); ``inf`` if it never does;
* ``final``: ``|e|`` at the last sample;
* ``update_time``: mean wall time of one observer update, seconds.

A plant state the observer does not estimate (an order-only observer's ``z1, z2, ...``, a
model-free multi-output observer without the motor states, ...) is **not estimated**: its
``rmse``, ``peak``, ``settling_time``, ``final`` and ``undefined_samples`` are ``None`` and
``estimated`` is ``False`` (the table prints ``-``). ``extra_states`` lists the observer's
columns that are not plant states (no true value to compare with).

Samples where an estimated state's estimate is NaN (its inverse map undefined, e.g. before the
first valid value) are counted in ``undefined_samples`` and left out of ``rmse`` and ``peak``;
they count as outside the band for ``settling_time``. A metric with no finite sample to use is
NaN (``final`` when the last estimate is undefined). No metric warns.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._validate import finite_scalar
from .exceptions import DesignError

Array = NDArray[np.float64]

__all__ = ["PER_STATE", "all_metrics", "format_table", "metrics_frame", "observer_metrics",
           "settling_time"]


def settling_time(t: Array, err: Array, band: float | Array) -> Array:
    """First time after which ``|err|`` stays within ``band``, per column (``inf``: never).

    Parameters
    ----------
    t : (T,) ndarray
        Sample times, increasing.
    err : (T, n) ndarray
        Errors, one column per state (NaN or inf count as outside).
    band : float or (n,) ndarray
        Absolute tolerance, one for all columns or one per column.

    Returns
    -------
    (n,) ndarray
        Per column the time of the first sample from which ``|err| <= band`` holds to the
        end: ``t[0]`` if always inside, ``inf`` if the last sample is outside.

    Examples
    --------
    >>> import numpy as np
    >>> err = np.array([[1.0, 0.0], [0.5, 0.0], [0.01, 0.2], [0.02, 0.0], [0.0, 0.0]])
    >>> settling_time(np.arange(5) * 0.1, err, 0.05)
    array([0.2, 0.3])
    """
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
    """Metrics of one observer (see the module docstring); values are lists over states.

    Parameters
    ----------
    traj : Trajectory
        A run of :func:`hgo_mj.simulate.simulate`.
    observer : str
        The observer's name in ``traj.observers``.
    t_transient : float, optional
        Start of the ``rmse`` window, in the run's time unit, >= 0; default the first 20 % of
        the run.
    band : float, default 0.05
        Settling band, > 0.
    relative : bool, default True
        The band is relative to each true state's range (``ptp``); False: absolute.

    Returns
    -------
    dict
        ``states``, ``estimated``, ``rmse``, ``peak``, ``settling_time``, ``final``,
        ``undefined_samples`` (lists over the plant's states, ``None`` where not estimated),
        ``extra_states``, ``update_time`` (s), ``t_transient``, ``band`` and
        ``band_relative_to_range``.

    Raises
    ------
    DesignError
        An observer the trajectory does not have, a bad ``t_transient`` or ``band``, or a
        ``t_transient`` that leaves no samples.

    Examples
    --------
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.simulate import simulate
    >>> plant = make_plant("pendulum", dt=0.01)
    >>> traj = simulate(plant, None, {"hgo": HighGainObserver(plant.system, k=30.0)},
    ...                 lambda t: [0.0], duration=0.5, x0=[0.2, 0.0])
    >>> m = observer_metrics(traj, "hgo", t_transient=0.25)
    >>> m["states"], m["estimated"], m["settling_time"]
    (['angle', 'angular_velocity'], [True, True], [0.15, inf])
    """
    if observer not in traj.observers:
        raise DesignError(f"no observer {observer!r} in the trajectory; found "
                          f"{sorted(traj.observers)}")
    t = traj.t
    if t_transient is None:
        t_transient = 0.2 * float(t[-1])
    t_transient = finite_scalar("t_transient", t_transient, nonnegative=True)
    band = finite_scalar("band", band, positive=True)
    e = traj.error(observer)
    est = traj.estimated(observer)
    win = t >= t_transient
    if not win.any():
        raise DesignError(f"t_transient = {t_transient:g} leaves no samples (run ends at "
                          f"{t[-1]:g})")
    with np.errstate(over="ignore", invalid="ignore"):  # inf - inf, huge**2: honest inf/NaN
        scale = np.ptp(traj.x, axis=0) if relative else np.ones(e.shape[1])
        scale = np.where(scale > 0, scale, 1.0)
        finite = np.isfinite(e)
        ae = np.abs(e)
        settle = settling_time(t, np.where(finite, e, np.inf), band * scale)
        rmse: list[float | None] = []
        peak: list[float | None] = []
        final: list[float | None] = []
        undefined: list[int | None] = []
        for j in range(e.shape[1]):
            if not est[j]:
                for col in (rmse, peak, final, undefined):
                    col.append(None)
                continue
            fw = finite[win, j]
            rmse.append(float(np.sqrt(np.mean(e[win, j][fw] ** 2))) if fw.any() else math.nan)
            peak.append(float(ae[finite[:, j], j].max()) if finite[:, j].any() else math.nan)
            final.append(float(ae[-1, j]))
            undefined.append(int(np.count_nonzero(~finite[:, j])))
    return {
        "states": list(traj.state_names),
        "estimated": est.tolist(),
        "rmse": rmse,
        "peak": peak,
        "settling_time": [float(v) if ok else None for v, ok in zip(settle, est)],
        "final": final,
        "undefined_samples": undefined,
        "extra_states": list(traj.extra_states(observer)),
        "update_time": traj.observers[observer].update_time,
        "t_transient": t_transient,
        "band": band,
        "band_relative_to_range": relative,
    }


def all_metrics(traj: Any, **kw: Any) -> dict[str, dict[str, Any]]:
    """:func:`observer_metrics` for every observer of the trajectory.

    Parameters
    ----------
    traj : Trajectory
        A run of :func:`hgo_mj.simulate.simulate`.
    **kw
        ``t_transient`` (default: the first 20 % of the run), ``band`` (0.05) and ``relative``
        (True: the band is relative to each state's range) of :func:`observer_metrics`.

    Returns
    -------
    dict of str to dict
        Observer name -> its metrics: lists over the plant's states (``rmse`` after
        ``t_transient``, ``peak``, ``settling_time``, ``final``; ``None`` for a state it does
        not estimate) and run-wide entries (``update_time``, ``t_transient``, ``band``).

    Raises
    ------
    DesignError
        A ``t_transient`` that leaves no samples, or a bad ``band``.

    Examples
    --------
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.simulate import simulate
    >>> plant = make_plant("pendulum", dt=0.01)
    >>> traj = simulate(plant, None, {"k10": HighGainObserver(plant.system, k=10.0),
    ...                               "k30": HighGainObserver(plant.system, k=30.0)},
    ...                 lambda t: [0.0], duration=3.0, x0=[0.2, 0.0])
    >>> m = all_metrics(traj, t_transient=1.0)
    >>> sorted(m), m["k30"]["states"]
    (['k10', 'k30'], ['angle', 'angular_velocity'])
    >>> m["k30"]["rmse"][1] < m["k10"]["rmse"][1]      # noise-free: the higher gain wins
    True
    """
    out = {name: observer_metrics(traj, name, **kw) for name in traj.observers}
    for name, d in getattr(traj, "diverged", {}).items():  # stopped alone (isolate)
        out[name]["diverged_at"] = d["t"]
    return out


#: the per-state metrics, the columns of :func:`metrics_frame` after ``observer``, ``state``
PER_STATE = ("estimated", "rmse", "peak", "settling_time", "final", "undefined_samples")


def metrics_frame(metrics: dict[str, dict[str, Any]],
                  units: dict[str, str] | None = None) -> Any:
    """The metrics of :func:`all_metrics` as a tidy :class:`pandas.DataFrame`: one row per
    observer and plant state, the columns ``observer``, ``state``, ``unit`` (from ``units``,
    ``{state: unit}``, e.g. :func:`hgo_mj.units.units_of`; ``None`` where missing), then
    ``estimated``, ``rmse``, ``peak``, ``settling_time``, ``final``, ``undefined_samples``
    (NaN where the state is not estimated), ``update_time``, ``t_transient``, ``band``.

    Parameters
    ----------
    metrics : dict
        What :func:`all_metrics` returns.
    units : dict of str to str, optional
        ``{state: unit}`` for the ``unit`` column.

    Returns
    -------
    pandas.DataFrame

    Examples
    --------
    >>> m = {"hgo": {"states": ["angle"], "estimated": [True], "rmse": [0.1], "peak": [0.5],
    ...              "settling_time": [1.0], "final": [0.01], "undefined_samples": [0],
    ...              "update_time": 1e-6, "t_transient": 2.0, "band": 0.05}}
    >>> metrics_frame(m, {"angle": "rad"})[["observer", "state", "unit", "rmse"]]
      observer  state unit  rmse
    0      hgo  angle  rad   0.1
    """
    import pandas as pd

    units = units or {}
    rows = []
    for name, m in metrics.items():
        for i, state in enumerate(m["states"]):
            row: dict[str, Any] = {"observer": name, "state": state, "unit": units.get(state)}
            for key in PER_STATE:
                v = m[key][i]
                row[key] = bool(v) if key == "estimated" else (math.nan if v is None else v)
            for key in ("update_time", "t_transient", "band"):
                row[key] = m.get(key, math.nan)
            rows.append(row)
    columns = ["observer", "state", "unit", *PER_STATE, "update_time", "t_transient", "band"]
    return pd.DataFrame(rows, columns=columns)


def _cell(v: Any, width: int) -> str:
    return f"{'-':>{width}}" if v is None else f"{v:>{width}.4g}"


def format_table(metrics: dict[str, dict[str, Any]]) -> str:
    """A plain-text table: one row per observer and state (``-``: not estimated).

    Parameters
    ----------
    metrics : dict
        What :func:`all_metrics` returns.

    Returns
    -------
    str
        Columns observer, state, RMSE, peak, settling time [s], final error and the mean wall
        time per update [us].

    Examples
    --------
    >>> m = {"hgo": {"states": ["angle"], "estimated": [True], "rmse": [0.1], "peak": [0.5],
    ...              "settling_time": [1.0], "final": [0.01], "update_time": 2e-6}}
    >>> print(format_table(m))
    observer         state                     rmse        peak  settle[s]       final update[us]
    hgo              angle                      0.1         0.5          1        0.01          2
    """
    lines = [f"{'observer':<16} {'state':<18} {'rmse':>11} {'peak':>11} {'settle[s]':>10} "
             f"{'final':>11} {'update[us]':>10}"]
    missing = False
    for name, m in metrics.items():
        for i, s in enumerate(m["states"]):
            missing |= m["rmse"][i] is None
            lines.append(f"{name:<16} {s:<18} {_cell(m['rmse'][i], 11)} {_cell(m['peak'][i], 11)} "
                         f"{_cell(m['settling_time'][i], 10)} {_cell(m['final'][i], 11)} "
                         f"{m['update_time'] * 1e6:>10.3g}")
    if missing:
        lines.append("- : not estimated (the observer has no estimate of that plant state)")
    for name, m in metrics.items():
        if m.get("diverged_at") is not None:
            lines.append(f"{name}: diverged at t = {m['diverged_at']:g} s, its estimate NaN "
                         f"from there on (its metrics use the rows before it; null where none is past "
                         f"t_transient)")
    return "\n".join(lines)
