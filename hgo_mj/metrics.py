"""Error metrics of a :class:`~hgo_mj.simulate.Trajectory`, per observer and state.

All metrics use the error ``e = x - x_hat`` in physical coordinates, per plant state
(:meth:`~hgo_mj.simulate.Trajectory.error`: the estimate's columns matched to the plant's states
by name):

* ``rmse``: root mean square over ``t >= t_transient``;
* ``peak``: the largest ``|e|`` over the whole run (peaking of high-gain observers);
* ``settling_time``: the first time after which ``|e|`` stays inside ``band`` (absolute, or
  relative to the range of the true state when ``relative=True``); ``inf`` if it never does,
  and ``inf`` too when only the last sample is inside (one sample inside is no evidence of
  having settled);
* ``final``: ``|e|`` at the last sample;
* ``update_time``: mean wall time of one observer update, seconds, warm: the loop spends the
  kernels' compilation or cache load on a throw-away sample before it starts timing, and in
  each segment the observers take turns at running first after the plant, whose run leaves
  the caches cold for the next one (:class:`~hgo_mj.loop.Loop`), so an observer's cost is
  the same listed first or second.

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
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from ._validate import DIVERGED_ABOVE, finite_scalar
from .exceptions import DesignError

Array = NDArray[np.float64]

__all__ = ["PER_STATE", "RunningMetrics", "all_metrics", "chi2_band", "format_table",
           "metrics_frame", "metrics_rows", "nees", "observer_metrics", "settling_time", "text_table"]


def nees(err: Array, P: Array) -> Array:
    """The normalized estimation error squared :math:`\\varepsilon = e^T P^{-1} e` of each
    member: ``err`` ``(B, d)`` (truth minus estimate) and the filter's covariance of that
    estimate ``P`` ``(B, d, d)`` (Bar-Shalom, Li and Kirubarajan, *Estimation with
    Applications to Tracking and Navigation*, Wiley 2001, sec. 5.4.2, eq. 5.4.2-1). For a
    consistent filter it is :math:`\\chi^2_d` distributed (mean ``d``). A member whose ``P``
    is singular or not finite gets NaN.

    Parameters
    ----------
    err : ndarray
        ``(B, d)``.
    P : ndarray
        ``(B, d, d)``, symmetric positive definite.

    Returns
    -------
    ndarray
        ``(B,)``.

    Examples
    --------
    >>> import numpy as np
    >>> nees(np.array([[1.0, 2.0]]), np.array([np.diag([1.0, 4.0])])).tolist()
    [2.0]
    """
    e = np.asarray(err, dtype=float)
    out = np.full(e.shape[0], np.nan)
    ok = np.isfinite(e).all(axis=1) & np.isfinite(P).all(axis=(1, 2))
    if ok.any():
        try:
            sol = np.linalg.solve(P[ok], e[ok][:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:  # one singular member: solve them one by one
            sol = np.full(e[ok].shape, np.nan)
            for i, (Pi, ei) in enumerate(zip(P[ok], e[ok])):
                try:
                    sol[i] = np.linalg.solve(Pi, ei)
                except np.linalg.LinAlgError:
                    pass
        out[ok] = np.einsum("bi,bi->b", e[ok], sol)
    return out


def chi2_band(dof: int | Array, confidence: float = 0.95) -> tuple[Array, Array]:
    """The two-sided ``confidence`` band ``(low, high)`` of one :math:`\\chi^2_{dof}`
    sample: where a consistent filter's NEES (``dof`` states) or NIS (``dof`` measured
    channels) lies with that probability (Bar-Shalom et al. 2001, sec. 5.4.2). ``dof`` 0
    gives the empty band ``(inf, -inf)``.

    Parameters
    ----------
    dof : int or ndarray
        Degrees of freedom (an array gives a band per entry).
    confidence : float
        The probability inside the band.

    Returns
    -------
    tuple of ndarray
        ``(low, high)``, shaped as ``dof``.

    Examples
    --------
    >>> lo, hi = chi2_band(1)
    >>> round(float(lo), 5), round(float(hi), 3)
    (0.00098, 5.024)
    """
    from scipy.stats import chi2

    d = np.asarray(dof, dtype=float)
    a = (1.0 - confidence) / 2.0
    with np.errstate(invalid="ignore"):
        lo = np.where(d > 0, chi2.ppf(a, np.maximum(d, 1)), np.inf)
        hi = np.where(d > 0, chi2.ppf(1.0 - a, np.maximum(d, 1)), -np.inf)
    return lo, hi


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
        end: ``t[0]`` if always inside, ``inf`` if the last sample is outside, and ``inf``
        if only the last sample is inside (a run of two samples or more).

    Examples
    --------
    >>> import numpy as np
    >>> err = np.array([[1.0, 0.0, 1.0], [0.5, 0.0, 1.0], [0.01, 0.2, 1.0],
    ...                 [0.02, 0.0, 1.0], [0.0, 0.0, 0.0]])
    >>> settling_time(np.arange(5) * 0.1, err, 0.05)
    array([0.2, 0.3, inf])
    """
    found = _inside_from(t, err, band)
    return np.where((found == t[-1]) & (t.size > 1), np.inf, found)


def _inside_from(t: Array, err: Array, band: float | Array) -> Array:
    """Per column the time of the first sample from which ``|err| <= band`` holds to the end
    (``t[0]``: always inside, ``inf``: the last sample outside), the last sample alone
    counting: the scan of one block of a run (:meth:`MetricsBatch.settle`)."""
    with np.errstate(invalid="ignore"):
        outside = ~(np.abs(err) <= np.asarray(band))
    T = t.size
    last = T - 1 - np.argmax(outside[::-1], axis=0)  # the last row outside (where any)
    after = np.where(last + 1 < T, t[np.minimum(last + 1, T - 1)], np.inf)
    return np.where(outside.any(axis=0), after, t[0]).astype(np.float64)


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
        # one member; the estimate's columns are the plant's (Trajectory.estimate)
        self.acc = {name: MetricsBatch(np.flatnonzero(est), np.flatnonzero(est), 1,
                                       self.t_transient)
                    for name, est in self.est.items()}
        self.t_end = -np.inf

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
        >>> int(acc.acc["hgo"].count[0, 0])
        41
        """
        if len(chunk) == 0:
            return
        self.t_end = float(chunk.t[-1])
        with np.errstate(invalid="ignore"):  # inf - inf: an honest NaN
            self.lo = np.fmin(self.lo, chunk.x.min(axis=0))
            self.hi = np.fmax(self.hi, chunk.x.max(axis=0))
        X = np.ascontiguousarray(chunk.x)[None]
        for name, acc in self.acc.items():
            est = np.ascontiguousarray(chunk.estimate(name))[None]
            acc.add(chunk.t, X, (est[:, 0], _NO_Z), est[:, 1:], _NO_Z_ROWS)

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
        band = (self.band * self._scale())[None]
        done = True
        for name, e in errors.items():
            acc = self.acc[name]
            done &= acc.settle(t, np.asarray(e)[None][:, :, acc.idx], band[:, acc.idx])
        return done

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
        n = len(traj.state_names)
        for name, est in self.est.items():
            m = self.acc[name].arrays(n)
            per_state = _PerState(est)
            out[name] = {
                "states": list(traj.state_names),
                "estimated": est.tolist(),
                "rmse": per_state(m["rmse"][0], float),
                "peak": per_state(m["peak"][0], float),
                "settling_time": per_state(m["settling_time"][0], float),
                "final": per_state(m["final"][0], float),
                "undefined_samples": per_state(m["undefined_samples"][0], int),
                "extra_states": list(traj.extra_states(name)),
                "update_time": traj.observers[name].update_time,
                "t_transient": self.t_transient,
                "band": self.band,
                "band_relative_to_range": self.relative,
            }
        return out


_NO_Z = np.empty((1, 0))
_NO_Z_ROWS = np.empty((1, 0, 0))


@njit(cache=True)
def _accumulate(t: Array, X: Array, px: Array, pz: Array, BX: Array, BZ: Array, idx: Any,
                cols: Any, t_tr: float, band: Array, sumsq: Array, comp: Array, count: Any,
                peak: Array, undefined: Any, settle: Array, final: Array, bad: Any,
                E: Array, r0: int, above: float) -> None:  # pragma: no cover - compiled
    """One pass over the rows ``0 ... T - 1`` of a block of B members (:class:`MetricsBatch`):
    the estimate of row ``j`` is ``px``/``pz`` for ``j = 0``, else ``BX``/``BZ``'s row
    ``j - 1``. The squares are summed with Neumaier's compensation. ``settle`` holds the time
    of the row after the last one outside the band (NaN: the next row's, still to come).
    The block's first row is row ``r0`` of the run: ``bad`` holds rows, and where ``E`` has
    rows, each error is also written there (``E[b, r0 + j, s]``). ``above``: the magnitude
    past which an estimate has diverged (:data:`hgo_mj._validate.DIVERGED_ABOVE`, an argument:
    a compiled global would outlive a change in the cache)."""
    keep = E.shape[1] > 0
    B, T, nz, nx = X.shape[0], X.shape[1], pz.shape[1], px.shape[1]
    for b in range(B):
        for j in range(T):
            if bad[b] < 0:
                for q in range(nz):
                    v = pz[b, q] if j == 0 else BZ[b, j - 1, q]
                    if not abs(v) <= above:
                        bad[b] = r0 + j
                for q in range(nx):
                    v = px[b, q] if j == 0 else BX[b, j - 1, q]
                    if abs(v) > above:  # a NaN x_hat (undefined inverse) is no fault
                        bad[b] = r0 + j
            inwin = t[j] >= t_tr
            for s in range(idx.size):
                e = X[b, j, idx[s]] - (px[b, cols[s]] if j == 0 else BX[b, j - 1, cols[s]])
                if keep:
                    E[b, r0 + j, s] = e
                ae = abs(e)
                if j == T - 1:
                    final[b, s] = ae
                if np.isnan(settle[b, s]):
                    settle[b, s] = t[j]
                if not np.isfinite(e):
                    undefined[b, s] += 1
                    settle[b, s] = np.nan
                    continue
                if inwin:
                    v, tot = e * e, sumsq[b, s]
                    new = tot + v
                    comp[b, s] += (tot - new) + v if abs(tot) >= abs(v) else (v - new) + tot
                    sumsq[b, s] = new
                    count[b, s] += 1
                if ae > peak[b, s]:
                    peak[b, s] = ae
                if not ae <= band[b, s]:
                    settle[b, s] = np.nan


class MetricsBatch:
    """The one accumulator of the metrics (module docstring) of B runs of one observer, over
    the rows as they come, without keeping them: one compiled pass per block.
    :class:`RunningMetrics` (one run, chunk by chunk, so :func:`observer_metrics` too) and the
    study engine (B members, block by block) take their metrics from it.

    The plant states ``idx`` are compared with the estimate's columns ``cols``. ``band``
    ``(B, k)`` is the absolute band of each member and compared state, or None when it is
    known only at the end (a relative band): then :meth:`settle` scans the errors from the
    last block back (kept here when ``rows`` > 0, or handed over again). RMSE: the squares in
    the window ``t >= t_transient`` summed with Neumaier's compensation (equal to
    ``numpy.mean``'s pairwise sum to rounding). ``bad`` per member: the first row whose
    estimate has diverged (:func:`hgo_mj._validate.diverged_rows`; -1: none).
    """

    def __init__(self, idx: Any, cols: Any, B: int, t_transient: float,
                 band: Array | None = None, rows: int = 0) -> None:
        self.idx = np.asarray(idx, dtype=np.intp)
        self.cols = np.asarray(cols, dtype=np.intp)
        self.t_transient = float(t_transient)
        k = self.idx.size
        self.known_band = band is not None
        # a band not known yet: only non-finite errors count as outside for now
        self.band = (np.full((B, k), np.inf) if band is None
                     else np.ascontiguousarray(band, dtype=np.float64))
        self.E = np.empty((B, rows, k))
        self.sumsq, self.comp = np.zeros((B, k)), np.zeros((B, k))
        self.count = np.zeros((B, k), dtype=np.int64)
        self.peak = np.full((B, k), -np.inf)
        self.undefined = np.zeros((B, k), dtype=np.int64)
        self.final = np.full((B, k), np.nan)
        self.settle_t = np.full((B, k), np.nan)
        self.bad = np.full(B, -1, dtype=np.int64)
        self.rows = 0
        #: the backward scan (:meth:`settle`): the time found per state (NaN: not yet), and
        #: the first time of the block after the one being scanned (inf before the last)
        self.settled = np.full((B, k), np.nan)
        self._after = np.inf
        #: the run's first and last times (:meth:`add`)
        self.t_first, self.t_last = np.nan, np.nan

    @classmethod
    def of(cls, observer_states: Sequence[str], state_names: Sequence[str], B: int,
           t_transient: float, band: Array | None = None, rows: int = 0) -> MetricsBatch:
        """The accumulator of an observer whose estimate has the columns ``observer_states``,
        on the plant's ``state_names`` (compared where the names agree; ``band`` ``(B, n)``
        over the plant's states)."""
        own = {s: j for j, s in enumerate(observer_states)}
        cols = [own[s] for s in state_names if s in own]
        idx = np.flatnonzero([s in own for s in state_names])
        return cls(idx, cols, B, t_transient, None if band is None else band[:, idx], rows)

    def add(self, t: Any, X: Array, prev: tuple[Array, Array], BX: Array, BZ: Array) -> None:
        """Rows at times ``t`` ``(T,)``: true states ``X`` ``(B, T, n)``; the estimate of the
        first row ``prev`` (``x_hat``, ``z_hat``, ``(B, .)``) and of the others ``BX``, ``BZ``
        ``(B, T - 1 or more, .)`` (row ``j`` is the block's row ``j - 1``)."""
        # one layout of X whatever its source (a replay's read-only broadcast, a segment's
        # rows, a state reshaped): numba compiles the kernel once per layout (issue 28)
        X = np.require(X, np.float64, ["C", "W"])
        _accumulate(np.ascontiguousarray(t, dtype=np.float64), X, prev[0], prev[1], BX, BZ,
                    self.idx, self.cols, self.t_transient, self.band, self.sumsq, self.comp,
                    self.count, self.peak, self.undefined, self.settle_t, self.final, self.bad,
                    self.E, self.rows, DIVERGED_ABOVE)
        if self.rows == 0:
            self.t_first = float(t[0])
        self.t_last = float(t[-1])
        self.rows += X.shape[1]

    def settle(self, t: Array, E: Array, band: Array) -> bool:
        """Scan a block's errors ``E`` ``(B, T, k)`` at times ``t`` against the band ``(B, k)``
        for the settling time, from the last block back; True when every one is found."""
        B, T, k = E.shape
        with np.errstate(invalid="ignore"):
            found = _inside_from(t, np.where(np.isfinite(E), E, np.inf)
                                  .transpose(1, 0, 2).reshape(T, B * k),
                                  np.asarray(band).reshape(B * k)).reshape(B, k)
        # a state inside over the whole block settled at or before its first time; one
        # outside at its last sample settled where the block after it starts
        here = np.where(found == t[0], np.nan, np.where(np.isinf(found), self._after, found))
        self.settled = np.where(np.isnan(self.settled), here, self.settled)
        self._after = float(t[0])
        self.known_band = False
        return not np.isnan(self.settled).any()

    def settle_kept(self, t: Any, band: Array) -> None:
        """:meth:`settle` over the kept errors (``rows`` > 0) at times ``t``, once the band
        ``(B, n)`` over the plant's states is known (a closed loop)."""
        self.settle(t, self.E, band[:, self.idx])

    def arrays(self, n: int) -> dict[str, Array]:
        """Per metric a ``(B, n)`` array over the plant's ``n`` states (NaN: not estimated):
        ``rmse``, ``peak``, ``settling_time``, ``final``, ``undefined_samples``."""
        B = self.sumsq.shape[0]
        # a sum of squares that overflowed is inf (its compensation is then inf - inf = NaN)
        total = np.where(np.isinf(self.sumsq), self.sumsq, self.sumsq + self.comp)
        with np.errstate(invalid="ignore", divide="ignore"):
            rmse = np.where(self.count > 0, np.sqrt(total / np.maximum(self.count, 1)), np.nan)
        peak = np.where(np.isfinite(self.peak), self.peak, np.nan)
        if self.known_band:  # found on the way (NaN: outside at the last row)
            settle = np.where(np.isnan(self.settle_t), np.inf, self.settle_t)
        else:
            settle = np.where(np.isnan(self.settled), self._after, self.settled)
        # inside at the last sample only: not settled (settling_time)
        settle = np.where((settle == self.t_last) & (self.t_last > self.t_first), np.inf, settle)
        out = {}
        for key, val in (("rmse", rmse), ("peak", peak), ("settling_time", settle),
                         ("final", self.final), ("undefined_samples", self.undefined)):
            full = np.full((B, n), np.nan)
            full[:, self.idx] = val
            out[key] = full
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

    rows, columns = metrics_rows(metrics, units)
    return pd.DataFrame(rows, columns=columns)


def metrics_rows(metrics: dict[str, dict[str, Any]], units: dict[str, str] | None = None
                 ) -> tuple[list[dict[str, Any]], list[str]]:
    """The rows of :func:`metrics_frame` (one mapping each) and its columns, without pandas
    (``metrics.parquet`` is written from them: :func:`hgo_mj.tidy.write_rows_parquet`).

    Parameters
    ----------
    metrics : dict
        What :func:`all_metrics` returns.
    units : dict of str to str, optional
        ``{state: unit}`` for the ``unit`` column.

    Returns
    -------
    rows : list of dict
    columns : list of str

    Examples
    --------
    >>> m = {"hgo": {"states": ["angle"], "estimated": [True], "rmse": [None], "peak": [0.5],
    ...              "settling_time": [1.0], "final": [0.01], "undefined_samples": [0],
    ...              "update_time": 1e-6, "t_transient": 2.0, "band": 0.05}}
    >>> rows, columns = metrics_rows(m, {"angle": "rad"})
    >>> rows[0]["unit"], rows[0]["rmse"], columns[:4]
    ('rad', nan, ['observer', 'state', 'unit', 'estimated'])
    """
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
    return rows, ["observer", "state", "unit", *PER_STATE, "update_time", "t_transient", "band"]


def text_table(rows: Sequence[Mapping[str, Any]], columns: Sequence[str],
               left: Sequence[str]) -> str:
    """Rows as a plain-text table, without pandas: each column sized to its longest cell
    (or its name), two spaces between columns, the ``left`` (text) columns left-aligned, the
    others right-aligned, numbers to 4 significant digits, ``None`` (or a missing key) as
    ``-``; no trailing blanks.

    Parameters
    ----------
    rows : sequence of mapping
        One mapping per row, from column name to value.
    columns : sequence of str
        The columns, in order.
    left : sequence of str
        The text columns, left-aligned under a left-aligned name.

    Returns
    -------
    str

    Examples
    --------
    >>> print(text_table([{"observer": "high_gain_multi_1", "rmse": 0.012345},
    ...                   {"observer": "a", "rmse": None}], ["observer", "rmse"], ["observer"]))
    observer              rmse
    high_gain_multi_1  0.01235
    a                        -
    """
    def cell(v: Any) -> str:
        if v is None:
            return "-"
        if isinstance(v, (float, int, np.floating, np.integer)) and not isinstance(v, bool):
            return f"{v:.4g}"
        return str(v)

    cols = []
    for c in columns:
        text = [str(c)] + [cell(r.get(c)) for r in rows]
        w = max(map(len, text))
        cols.append([t.ljust(w) if c in left else t.rjust(w) for t in text])
    return "\n".join("  ".join(line).rstrip() for line in zip(*cols))


def format_table(metrics: dict[str, dict[str, Any]], units: dict[str, str] | None = None,
                 time_unit: str | None = "s") -> str:
    """A plain-text table: one row per observer and state (``-``: not estimated), with the
    units of each state's errors and of the settling time, columns sized to their longest cell
    (:func:`text_table`).

    Parameters
    ----------
    metrics : dict
        What :func:`all_metrics` returns.
    units : dict of str to str, optional
        ``{state: unit}`` (:func:`hgo_mj.units.units_of`): the unit of the state's ``rmse``,
        ``peak`` and ``final``; ``?`` where not known.
    time_unit : str or None, default "s"
        The run's time unit (``""``: dimensionless, ``None``: not known).

    Returns
    -------
    str
        Columns observer, state, unit (of rmse, peak and final), rmse, peak, final, the
        settling time and the mean wall time per update [us].

    Examples
    --------
    >>> m = {"hgo": {"states": ["angle"], "estimated": [True], "rmse": [0.1], "peak": [0.5],
    ...              "settling_time": [1.0], "final": [0.01], "update_time": 2e-6}}
    >>> print(format_table(m, {"angle": "rad"}))
    observer  state  unit  rmse  peak  final  settle [s]  update [us]
    hgo       angle  rad    0.1   0.5   0.01           1            2
    """
    from .units import bracket

    units = units or {}
    settle = f"settle {bracket(time_unit)}"
    rows, missing = [], False
    for name, m in metrics.items():
        for i, s in enumerate(m["states"]):
            missing |= m["rmse"][i] is None
            rows.append({"observer": name, "state": s, "unit": units.get(s, "?") or "-",
                         **{k: m[k][i] for k in ("rmse", "peak", "final")},
                         settle: m["settling_time"][i],
                         "update [us]": m["update_time"] * 1e6})
    lines = [text_table(rows, ["observer", "state", "unit", "rmse", "peak", "final", settle,
                               "update [us]"], ["observer", "state", "unit"])]
    if missing:
        lines.append("- : not estimated (the observer has no estimate of that plant state)")
    for name, m in metrics.items():
        if m.get("diverged_at") is not None:
            lines.append(f"{name}: diverged at t = {m['diverged_at']:g} s, its estimate NaN "
                         f"from there on (its metrics use the rows before it; null where none is past "
                         f"t_transient)")
    return "\n".join(lines)
