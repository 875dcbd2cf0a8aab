"""Error metrics of a :class:`~hgo_mj.simulate.Trajectory`, per observer and state.

All metrics use the error ``e = x - x_hat`` in physical coordinates, per plant state
(:meth:`~hgo_mj.simulate.Trajectory.error`: the estimate's columns matched to the plant's states
by name):

* ``rmse``: root mean square over ``t >= t_transient``;
* ``peak``: the largest ``|e|`` over the whole run (peaking of high-gain observers);
* ``settling_time``: the first time after which ``|e|`` stays inside ``band`` (absolute, or
  relative to the range of the true state when ``relative=True``); ``inf`` if it never does;
* ``final``: ``|e|`` at the last sample;
* ``update_time``: mean wall time of one observer update, seconds, warm: the loop spends the
  kernels' compilation or cache load on a throw-away sample before it starts timing
  (:class:`~hgo_mj.loop.Loop`), so an observer's cost is the same listed first or second.

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

__all__ = ["PER_STATE", "RunningMetrics", "all_metrics", "format_table", "metrics_frame",
           "observer_metrics", "settling_time"]


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
    if t_transient is None:
        t_transient = 0.2 * float(traj.t[-1])
    acc = RunningMetrics(traj, t_transient=t_transient, band=band, relative=relative,
                         observers=[observer])
    acc.add(traj)
    acc.settle(traj.t, {observer: traj.error(observer)})
    return acc.result(traj)[observer]


class RunningMetrics:
    """:func:`observer_metrics` of a run handed over in chunks, in bounded memory (a streamed
    run, ``simulate(keep=False)``): :meth:`add` each chunk in order, then :meth:`settle` with
    the chunks' errors from the last chunk back (the settling band is relative to the whole
    run's range, known only at the end), then :meth:`result`. :func:`observer_metrics` is this
    with one chunk, the whole trajectory: the equations are written here once.

    Parameters
    ----------
    traj : Trajectory
        A trajectory (or a chunk) of the run: its names only.
    t_transient : float
        Start of the ``rmse`` window, >= 0 (the run's time unit).
    band : float, default 0.05
        Settling band, > 0.
    relative : bool, default True
        The band is relative to each true state's range over the run.
    observers : sequence of str, optional
        The observers to measure (default all of ``traj``'s).

    Raises
    ------
    DesignError
        A bad ``t_transient`` or ``band``, or an observer ``traj`` does not have.

    Examples
    --------
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.simulate import simulate
    >>> plant = make_plant("pendulum", dt=0.01)
    >>> run = (plant, None, {"hgo": HighGainObserver(plant.system, k=30.0)}, lambda t: [0.0])
    >>> chunks = []
    >>> traj = simulate(*run, duration=2.0, x0=[0.2, 0.0], keep=False,
    ...                 on_chunk=(0.5, lambda row, chunk: chunks.append(chunk)))
    >>> acc = RunningMetrics(traj, t_transient=0.4)
    >>> for chunk in chunks:
    ...     acc.add(chunk)
    >>> for chunk in reversed(chunks):
    ...     if acc.settle(chunk.t, {"hgo": chunk.error("hgo")}):
    ...         break
    >>> m = acc.result(traj)["hgo"]
    >>> kept = all_metrics(simulate(*run, duration=2.0, x0=[0.2, 0.0]), t_transient=0.4)
    >>> m["settling_time"] == kept["hgo"]["settling_time"], len(chunks)
    (True, 4)
    """

    def __init__(self, traj: Any, *, t_transient: float, band: float = 0.05,
                 relative: bool = True, observers: Any = None) -> None:
        self.t_transient = finite_scalar("t_transient", t_transient, nonnegative=True)
        self.band = finite_scalar("band", band, positive=True)
        if not isinstance(relative, bool):
            raise DesignError(f"relative must be a bool; found {relative!r}")
        self.relative = relative
        names = list(traj.observers) if observers is None else list(observers)
        for name in names:
            if name not in traj.observers:
                raise DesignError(f"no observer {name!r} in the trajectory; found "
                                  f"{sorted(traj.observers)}")
        n = len(traj.state_names)
        self.est = {name: traj.estimated(name) for name in names}
        self.lo, self.hi = np.full(n, np.inf), np.full(n, -np.inf)
        self.sumsq = {name: np.zeros(n) for name in names}
        self.count = {name: np.zeros(n, dtype=np.int64) for name in names}
        self.peak = {name: np.full(n, -np.inf) for name in names}
        self.undefined = {name: np.zeros(n, dtype=np.int64) for name in names}
        self.final = {name: np.full(n, np.nan) for name in names}
        self.t_end = -np.inf
        #: settling: the time found per state (NaN: not yet), and the first time of the chunk
        #: after the one being scanned (inf before the last chunk)
        self.settled = {name: np.full(n, np.nan) for name in names}
        self._after = np.inf

    def add(self, chunk: Any) -> None:
        """Take the next chunk of the run (a :class:`~hgo_mj.simulate.Trajectory` of rows
        following the last one taken).

        Parameters
        ----------
        chunk : Trajectory
            The rows, in order; an empty chunk is ignored.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> from hgo_mj.simulate import simulate
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> traj = simulate(plant, None, {"hgo": HighGainObserver(plant.system, k=30.0)},
        ...                 lambda t: [0.0], duration=0.5, x0=[0.2, 0.0])
        >>> acc = RunningMetrics(traj, t_transient=0.1)
        >>> acc.add(traj)
        >>> int(acc.count["hgo"][0])
        41
        """
        if len(chunk) == 0:
            return
        t = chunk.t
        win = t >= self.t_transient
        self.t_end = float(t[-1])
        with np.errstate(over="ignore", invalid="ignore"):  # inf - inf, huge**2: honest inf/NaN
            self.lo = np.fmin(self.lo, chunk.x.min(axis=0))
            self.hi = np.fmax(self.hi, chunk.x.max(axis=0))
            for name in self.est:
                e = chunk.error(name)
                finite = np.isfinite(e)
                self.sumsq[name] += np.sum(np.where(finite & win[:, None], e, 0.0) ** 2, axis=0)
                self.count[name] += np.count_nonzero(finite & win[:, None], axis=0)
                self.peak[name] = np.fmax(self.peak[name],
                                          np.max(np.where(finite, np.abs(e), -np.inf), axis=0))
                self.undefined[name] += np.count_nonzero(~finite, axis=0)
                self.final[name] = np.abs(e[-1])

    def _scale(self) -> Any:
        if not self.relative:
            return np.ones_like(self.lo)
        with np.errstate(invalid="ignore"):
            scale = self.hi - self.lo
        return np.where(scale > 0, scale, 1.0)

    def settle(self, t: Any, errors: Any) -> bool:
        """Scan a chunk's errors for the settling time, from the last chunk back.

        Parameters
        ----------
        t : (T,) ndarray
            The chunk's times.
        errors : mapping str -> (T, n) ndarray
            Each observer's error ``x - x_hat`` on the plant's states
            (:meth:`~hgo_mj.simulate.Trajectory.error`) over the chunk.

        Returns
        -------
        bool
            True when every settling time is found (the earlier chunks need no scan).

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> from hgo_mj.simulate import simulate
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> traj = simulate(plant, None, {"hgo": HighGainObserver(plant.system, k=30.0)},
        ...                 lambda t: [0.0], duration=0.5, x0=[0.2, 0.0])
        >>> acc = RunningMetrics(traj, t_transient=0.1)
        >>> acc.add(traj)
        >>> acc.settle(traj.t, {"hgo": traj.error("hgo")})
        True
        """
        scale = self._scale()
        for name, e in errors.items():
            done = ~np.isnan(self.settled[name])
            with np.errstate(invalid="ignore"):
                found = settling_time(t, np.where(np.isfinite(e), e, np.inf),
                                      self.band * scale)
            # a state inside over the whole chunk settled at or before its first time; one
            # outside at its last sample settled where the chunk after it starts
            here = np.where(found == t[0], np.nan, np.where(np.isinf(found), self._after, found))
            self.settled[name] = np.where(done, self.settled[name], here)
        self._after = float(t[0])
        return all(not np.isnan(v).any() for v in self.settled.values())

    def result(self, traj: Any) -> dict[str, dict[str, Any]]:
        """The metrics, as :func:`observer_metrics` gives them, per observer.

        Parameters
        ----------
        traj : Trajectory
            The run's trajectory (its names and each observer's ``update_time``; a streamed
            run's has no rows).

        Returns
        -------
        dict of str to dict
            Observer name -> :func:`observer_metrics`'s dictionary.

        Raises
        ------
        DesignError
            ``t_transient`` left no samples.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> from hgo_mj.simulate import simulate
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> traj = simulate(plant, None, {"hgo": HighGainObserver(plant.system, k=30.0)},
        ...                 lambda t: [0.0], duration=0.5, x0=[0.2, 0.0])
        >>> acc = RunningMetrics(traj, t_transient=0.1)
        >>> acc.add(traj)
        >>> _ = acc.settle(traj.t, {"hgo": traj.error("hgo")})
        >>> acc.result(traj)["hgo"]["states"]
        ['angle', 'angular_velocity']
        """
        if self.t_end < self.t_transient:
            raise DesignError(f"t_transient = {self.t_transient:g} leaves no samples (run ends "
                              f"at {self.t_end:g})")
        out = {}
        for name, est in self.est.items():
            with np.errstate(invalid="ignore"):
                rmse = np.sqrt(self.sumsq[name] / self.count[name])
            settle = np.where(np.isnan(self.settled[name]), self._after, self.settled[name])
            per_state = _PerState(est)
            out[name] = {
                "states": list(traj.state_names),
                "estimated": est.tolist(),
                "rmse": per_state(np.where(self.count[name] > 0, rmse, math.nan), float),
                "peak": per_state(np.where(np.isfinite(self.peak[name]), self.peak[name],
                                           math.nan), float),
                "settling_time": per_state(settle, float),
                "final": per_state(self.final[name], float),
                "undefined_samples": per_state(self.undefined[name], int),
                "extra_states": list(traj.extra_states(name)),
                "update_time": traj.observers[name].update_time,
                "t_transient": self.t_transient,
                "band": self.band,
                "band_relative_to_range": self.relative,
            }
        return out


class _PerState:
    """A list over the plant's states of metric values: ``None`` where not estimated."""

    def __init__(self, estimated: Any) -> None:
        self.estimated = estimated

    def __call__(self, values: Any, cast: Any) -> list[Any]:
        return [cast(v) if ok else None for v, ok in zip(values, self.estimated)]


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
