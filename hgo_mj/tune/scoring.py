"""Evaluating many tunings of one observer as one batch.

A tuning holds the scenario fixed: the plant, its initial state, the input and the periods. In
an open loop the plant's trajectory then depends neither on the noise seed nor on the
observer, so it is simulated **once** (:func:`hgo_mj.study.engine.plant_rows`) and replayed to
every member (:class:`hgo_mj.study.engine.ReplayPlant`), as the study engine does. A round of
``R`` trials over ``S`` seeds is one batch of ``R x S`` members on the one loop
(:class:`hgo_mj.loop.Loop`): the sensor chain draws one seeded stream per member (member
``r S + s`` uses seed ``s``: trial-major, so each trial's members are consecutive and the base
steps them as views), and the observer advances every member with its own trial's parameters
(``Loop(params=...)``, :meth:`hgo_mj.observers.Observer.parameters`). Member ``(r, s)`` equals
``simulate`` of trial ``r`` at seed ``s`` alone.

What each member gives (:class:`Scores`):

* with ground truth, the study engine's streamed metrics (:class:`hgo_mj.study.engine.Metrics`,
  as :func:`hgo_mj.metrics.observer_metrics`): per scored state its RMSE after the transient,
  its peak and its settling time into a band of 5 % of the state's range;
* without ground truth, what a user has on a rig: the output prediction error, the RMS over
  the samples after the transient of ``y_k - y_hat_k`` where ``y_hat_k`` is the output the
  estimate *before* ``y_k`` predicts (:meth:`hgo_mj.observers.Observer.predicted_output`); the
  **whiteness** of those errors (the innovations of a filter), the Box-Pierce statistic
  :math:`Q = n \\sum_{l=1}^{L} \\hat\\rho_l^2` over :data:`WHITENESS_LAGS` lags divided by
  :math:`L`, the mean over the channels (about 1 for white errors, :math:`Q \\sim \\chi^2_L`;
  Box and Pierce, *J. Amer. Statist. Assoc.* 65, 1970; a correlated sequence, as an observer
  too slow or too fast leaves, scores higher: the innovations of an optimal filter are white,
  Mehra, *IEEE TAC* 15, 1970); and,
  for a filter that reports it (a diagnostic ``nis``), the mean normalized innovation squared
  and the fraction of samples inside its chi-square 95 % band.

A filter that keeps a covariance of its estimate (:meth:`hgo_mj.observers.Observer.covariance`)
also gets, with ground truth and ``consistency=True`` (the benchmark), its NEES
(:func:`hgo_mj.metrics.nees`, every estimated plant state): the covariance is read between
segments, so such an observer's run is cut into about
:data:`NEES_POINTS` segments and the NEES is the mean over those instants after the transient
(instants far apart, so nearly independent), with the fraction inside the chi-square 95 % band.

A member whose observer fails (an exception in its update) or whose estimate leaves the finite
numbers scores ``inf``; the trials of a round that fails are split in halves until each failing
trial is alone, so one diverging trial does not cost the others their scores.
"""

from __future__ import annotations

import copy
import json
import math
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..exceptions import DesignError
from ..loop import Drive, Loop, LoopFailure, Periods
from ..metrics import chi2_band, nees
from ..observers.base import Observer
from ..study.engine import Metrics, ReplayPlant, plant_rows, segment_length

Array = NDArray[np.float64]

__all__ = ["NEES_POINTS", "WHITENESS_LAGS", "Scores", "Setup", "evaluate", "setup"]

#: instants per run at which a filter's NEES is read (its run cut into as many segments)
NEES_POINTS = 200
#: lags of the whiteness score (Box-Pierce)
WHITENESS_LAGS = 10


@dataclass
class Setup:
    """What a tuning holds fixed, built once: the scenario's plant run, periods and windows.

    Parameters
    ----------
    scenario : dict
        The scenario (validated).
    observer : str
        The label of the observer tuned (one of the scenario's ``[[observers]]``).
    plant : Plant
        The scenario's plant (its system names the states).
    periods : Periods
        The sample and control periods.
    N : int
        Samples of the run.
    X, Yc : ndarray
        The plant's true states and clean outputs ``(1, N + 1, .)``.
    states : tuple of str
        The scored states (default: every plant state the observer estimates).
    ranges : ndarray
        Each scored state's range over the run (``ptp``; 1 where it is 0): what the scores
        are normalized by.
    t_transient : float
        The window of the steady-state scores starts here (seconds).
    n_outputs : int
        The measured outputs the observer reads (the expected mean NIS).

    Examples
    --------
    Built by :func:`setup`:

    >>> sc = {"plant": {"name": "pendulum", "dt": 0.01}, "run": {"duration": 1.0},
    ...       "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}]}
    >>> s = setup(sc, "hgo")
    >>> isinstance(s, Setup), s.observer, s.n_outputs
    (True, 'hgo', 1)
    """

    scenario: dict[str, Any]
    observer: str
    plant: Any
    periods: Periods
    N: int
    X: Array
    Yc: Array
    states: tuple[str, ...]
    ranges: Array
    t_transient: float
    n_outputs: int


@dataclass
class Scores:
    """Per member of a round ``(R, S)`` (trials x seeds).

    Parameters
    ----------
    rmse : ndarray
        ``(R, S, k)``: RMSE of each scored state after the transient (state units; inf: the
        member diverged).
    peak : ndarray
        ``(R, S, k)``: the largest error of each scored state.
    settling : ndarray
        ``(R, S, k)``: seconds into the 5 % band (inf: never).
    output_error : ndarray
        ``(R, S)``: RMS output prediction error after the transient (NaN: the observer
        predicts no output).
    whiteness : ndarray
        ``(R, S)``: the Box-Pierce statistic of those errors over its lags, divided by the
        number of lags (about 1: white; NaN: no output predicted).
    nis : ndarray
        ``(R, S)``: mean normalized innovation squared (NaN: the observer reports none).
    nis_band : ndarray
        ``(R, S)``: the fraction of its samples inside the chi-square 95 % band of their
        number of measured channels (NaN: no NIS).
    nees : ndarray
        ``(R, S)``: the mean NEES over the estimated plant states (NaN: the observer keeps no
        covariance).
    nees_band : ndarray
        ``(R, S)``: the fraction of the NEES instants inside the chi-square 95 % band.
    iae : ndarray
        ``(R, S)``: the integral over the first second of the norm of the error normalized by
        each scored state's range (seconds; the transient score of the benchmark).
    peaking : ndarray
        ``(R, S)``: the largest normalized error norm over the normalized initial error norm.
    update_time : ndarray
        ``(R,)``: seconds per observer update and member, warm (the loop's wall clock).
    message : list of list of str or None
        Why a member diverged (None: it did not).

    Examples
    --------
    Made by :func:`evaluate`:

    >>> sc = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.2, 0.0]},
    ...       "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...       "run": {"duration": 1.0}}
    >>> scores = evaluate(setup(sc, "hgo"), [{"k": 10.0}], seeds=[0])
    >>> scores.rmse.shape, scores.message
    ((1, 1, 2), [[None]])
    """

    rmse: Array
    peak: Array
    settling: Array
    output_error: Array
    whiteness: Array
    nis: Array
    nis_band: Array
    nees: Array
    nees_band: Array
    iae: Array
    peaking: Array
    update_time: Array
    message: list[list[str | None]]

    @classmethod
    def concat(cls, parts: Sequence[Scores]) -> Scores:
        """The scores of several batches of trials as one, in order (the same seeds): what
        the Ray backend gathers.

        Parameters
        ----------
        parts : sequence of Scores

        Returns
        -------
        Scores

        Examples
        --------
        >>> sc = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.3, 0.0]},
        ...       "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
        ...       "input": {"type": "constant", "value": 0.0}, "run": {"duration": 1.0}}
        >>> st = setup(sc, "hgo")
        >>> both = Scores.concat([evaluate(st, [{"k": k}], [0]) for k in (5.0, 40.0)])
        >>> both.rmse.shape, len(both.message)
        ((2, 1, 2), 2)
        """
        arrays = {f.name: np.concatenate([getattr(p, f.name) for p in parts])
                  for f in fields(cls) if f.name != "message"}
        return cls(**arrays, message=[m for p in parts for m in p.message])


def setup(scenario: Mapping[str, Any], observer: str, *, states: Sequence[str] | None = None,
          t_transient: float | None = None,
          mismatches: Sequence[Mapping[str, Any] | None] = ()) -> Setup:
    """Build a tuning's fixed part from a scenario: check it, simulate its plant once.

    Parameters
    ----------
    scenario : mapping
        A scenario (``hgo-mj run``'s format) with an open-loop ``[input]`` and the observer.
    observer : str
        The label of the observer to tune.
    states : sequence of str, optional
        The states scored (default: every plant state the observer estimates).
    t_transient : float, optional
        Start of the steady-state window, seconds (default 0.2 times the duration, as
        :func:`hgo_mj.metrics.observer_metrics`).
    mismatches : sequence of mapping or None
        Models of the observer (``system_params``) the tuning will use: each is built here,
        so that a wrong one is refused before the plant runs.

    Returns
    -------
    Setup

    Raises
    ------
    DesignError
        A closed-loop scenario (a ``[controller]``: the plant's run would depend on the
        estimate), an observer the scenario does not have, states the plant does not have
        or the observer does not estimate, or a model mismatch the observer's system refuses.

    Examples
    --------
    >>> sc = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.3, 0.0]},
    ...       "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...       "input": {"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]},
    ...       "run": {"duration": 2.0}}
    >>> s = setup(sc, "hgo")
    >>> s.N, s.states, s.X.shape
    (200, ('angle', 'angular_velocity'), (1, 201, 2))
    """
    from ..scenario import scenario_run

    sc = copy.deepcopy(dict(scenario))
    if "controller" in sc:
        raise DesignError("tuning replays one plant run to every trial: it needs an open-loop "
                          "[input], not a [controller]")
    kw = scenario_run(sc)
    if observer not in kw["observers"]:
        raise DesignError(f"observer {observer!r} is not in the scenario; it has "
                          f"{list(kw['observers'])}")
    ob: Observer = kw["observers"][observer]
    plant = kw["plant"]
    periods = Periods.of(plant, kw["sample_period"], kw["control_period"])
    N = int(round(float(kw["duration"]) / periods.sample))
    estimated = [s for s in plant.state_names if s in ob.state_names]
    if states is None:
        chosen = tuple(estimated)
    else:
        chosen = tuple(states)
        bad = [s for s in chosen if s not in estimated]
        if bad or not chosen:
            raise DesignError(f"states to score must be plant states the observer {observer!r} "
                              f"estimates, {estimated}; found {list(chosen)}")
    if not chosen:
        raise DesignError(f"observer {observer!r} estimates none of the plant's states "
                          f"{list(plant.state_names)}: nothing to score")
    tt = 0.2 * (N * periods.sample) if t_transient is None else float(t_transient)
    if not (math.isfinite(tt) and 0 <= tt < N * periods.sample):
        raise DesignError(f"t_transient must lie in [0, duration); found {t_transient!r}")
    for m in mismatches:
        if m:
            scenario_run(_with_model(sc, observer, m))
    x0 = kw.get("x0")
    x0s = np.reshape(np.asarray(plant.system.default_x0 if x0 is None else x0, dtype=float),
                     (1, -1))
    X, Yc = _plant_run(sc, plant, kw["inputs"], periods, N, x0s)  # the work: checks are done
    idx = [list(plant.state_names).index(s) for s in chosen]
    with np.errstate(invalid="ignore"):
        ptp = np.ptp(X[0, :, idx], axis=1)
    ranges = np.where(np.isfinite(ptp) & (ptp > 0), ptp, 1.0)
    return Setup(sc, observer, plant, periods, N, X, Yc, chosen, ranges, tt, len(ob.outputs))


#: the plant runs of the last few setups (:func:`_plant_run`), newest last
_PLANT_RUNS: OrderedDict[str, tuple[Array, Array]] = OrderedDict()
_PLANT_RUNS_KEPT = 4


def _plant_run(sc: Mapping[str, Any], plant: Any, inputs: Any, periods: Periods, N: int,
               x0s: Array) -> tuple[Array, Array]:
    """:func:`~hgo_mj.study.engine.plant_rows` of the scenario, kept (read-only) for the next
    setup of the same plant run: everything of the scenario but its observers and sensor
    (which the plant's run does not see), the initial state, the periods and the plant
    system's parameters (an MJCF edited between two setups gives other ones). The benchmark
    sets a task up twice per observer (its scoring and its tuning), so a task's plant ran 20
    times for the quick suite's ten observers (issue 28); now once per process."""
    try:
        key = json.dumps([{k: v for k, v in sc.items() if k not in ("observers", "sensor")},
                          x0s.tolist(), N, periods.sample, periods.control,
                          getattr(plant.system, "params", None)], sort_keys=True)
    except (TypeError, ValueError):  # a scenario with values JSON cannot hold: not kept
        return plant_rows(plant, inputs, periods, N, x0s)
    if key in _PLANT_RUNS:
        _PLANT_RUNS.move_to_end(key)
        return _PLANT_RUNS[key]
    X, Yc = plant_rows(plant, inputs, periods, N, x0s)
    X.setflags(write=False)
    Yc.setflags(write=False)
    _PLANT_RUNS[key] = (X, Yc)
    while len(_PLANT_RUNS) > _PLANT_RUNS_KEPT:
        _PLANT_RUNS.popitem(last=False)
    return X, Yc


def _with_model(scenario: Mapping[str, Any], observer: str,
                mismatch: Mapping[str, Any] | None) -> dict[str, Any]:
    """The scenario with the tuned observer alone, its model overridden by ``mismatch``: a
    parameter name goes to its spec's ``system_params``, a MuJoCo model field
    (``"body_mass[link1]"``, ``"opt.gravity"``: :mod:`hgo_mj.plants.fields`) to its
    ``model_fields`` (the MuJoCo filters' copy of the MJCF)."""
    sc = copy.deepcopy(dict(scenario))
    specs = [o for o in sc.get("observers", []) if o.get("name", o.get("type")) == observer]
    if mismatch:
        spec = specs[0]
        fields = {k: v for k, v in mismatch.items() if "[" in k or k.startswith("opt.")}
        params = {k: v for k, v in mismatch.items() if k not in fields}
        if params:
            spec["system_params"] = {**(spec.get("system_params") or {}), **params}
        if fields:
            spec["model_fields"] = {**(spec.get("model_fields") or {}), **fields}
    sc["observers"] = specs
    return sc


def _observer(s: Setup, mismatch: Mapping[str, Any] | None) -> Any:
    """The scenario's run with the tuned observer alone (:func:`_with_model`)."""
    from ..scenario import scenario_run

    return scenario_run(_with_model(s.scenario, s.observer, mismatch))


def evaluate(s: Setup, trials: Sequence[Mapping[str, Any]], seeds: Sequence[int],
             mismatch: Mapping[str, Any] | None = None, *, consistency: bool = False) -> Scores:
    """Score ``R`` trials (each: parameter values for :meth:`Observer.parameters`, one
    member's values) over ``S`` seeds as one batch of ``R x S`` members (module docstring).

    Parameters
    ----------
    s : Setup
        The tuning's fixed part (:func:`setup`).
    trials : sequence of mapping
        Per trial, parameter name -> value (a parameter not named keeps the constructor's).
    seeds : sequence of int
        The sensor chain's seeds.
    mismatch : mapping, optional
        Parameters of the observer's model that differ from the plant's (``system_params``).
    consistency : bool
        Also score the NEES of an observer that keeps a covariance (its run then cut into
        :data:`NEES_POINTS` segments: slower; the tuner's objectives do not need it, the
        benchmark's scores do). Otherwise ``nees`` and ``nees_band`` are NaN.

    Returns
    -------
    Scores

    Raises
    ------
    DesignError
        A trial's value the observer refuses (as :meth:`Observer.parameters` does).

    Examples
    --------
    >>> sc = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.3, 0.0]},
    ...       "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
    ...       "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    ...       "input": {"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]},
    ...       "run": {"duration": 2.0}}
    >>> sc_ = evaluate(setup(sc, "hgo"), [{"k": 5.0}, {"k": 40.0}], seeds=[1, 2])
    >>> sc_.rmse.shape, bool((sc_.rmse[1] < sc_.rmse[0]).all())
    ((2, 2, 2), True)
    """
    R, S = len(trials), len(seeds)
    k = len(s.states)
    per, nan = (lambda: np.full((R, S, k), np.inf)), (lambda: np.full((R, S), np.nan))
    out = Scores(per(), per(), per(), np.full((R, S), np.inf), np.full((R, S), np.inf),
                 np.full((R, S), np.inf), nan(), nan(), nan(), np.full((R, S), np.inf),
                 np.full((R, S), np.inf),
                 np.full(R, np.nan), [[None] * S for _ in range(R)])
    if R == 0 or S == 0:
        return out
    _evaluate(s, list(trials), list(seeds), mismatch, list(range(R)), out, consistency)
    return out


def _evaluate(s: Setup, trials: list[Mapping[str, Any]], seeds: list[int],
              mismatch: Mapping[str, Any] | None, which: list[int], out: Scores,
              consistency: bool) -> None:
    """Score the trials ``which`` as one batch; on a failure, halves (module docstring)."""
    try:
        _batch(s, [trials[r] for r in which], seeds, mismatch, which, out, consistency)
    except LoopFailure as failure:
        if len(which) == 1:
            msg = (f"observer {s.observer!r} failed in its update at t={failure.t:g} (row "
                   f"{failure.row}): {type(failure.cause).__name__}: {failure.cause}")
            for j in range(len(seeds)):
                out.message[which[0]][j] = msg
            return
        half = len(which) // 2
        _evaluate(s, trials, seeds, mismatch, which[:half], out, consistency)
        _evaluate(s, trials, seeds, mismatch, which[half:], out, consistency)


def _member_values(ob: Observer, trials: list[Mapping[str, Any]], S: int) -> dict[str, Array]:
    """The per-member parameter values ``(R S, ...)`` of the trials (trial-major)."""
    defaults = ob._parameters()
    names = sorted({name for t in trials for name in t})
    bad = [n for n in names if n not in defaults]
    if bad:
        raise DesignError(f"{ob.name}: unknown parameter(s) {bad}; valid: {list(defaults)}")
    values: dict[str, Array] = {}
    for name in names:
        rows = [ob._check_parameter(name, t.get(name, defaults[name])) for t in trials]
        values[name] = np.repeat(np.stack(rows), S, axis=0)
    return values


def _batch(s: Setup, trials: list[Mapping[str, Any]], seeds: list[int],
           mismatch: Mapping[str, Any] | None, which: list[int], out: Scores,
           consistency: bool) -> None:
    kw = _observer(s, mismatch)
    name = s.observer
    ob: Observer = kw["observers"][name]
    R, S = len(trials), len(seeds)
    B = R * S
    plant = ReplayPlant(s.plant, s.X, s.Yc, np.zeros(B, dtype=np.intp))
    loop = Loop(plant, kw["sensor"], {name: ob}, s.periods, exact=False,
                params={name: _member_values(ob, trials, S)})
    drive = Drive.of(kw["inputs"], {name: ob}, plant, s.periods)
    loop.reset(None, seed=[sd for _ in range(R) for sd in seeds], batch=B)
    Ts = s.periods.sample
    band = 0.05 * np.broadcast_to(_full_ranges(s), (B, len(s.plant.state_names)))
    acc = Metrics(ob, s.plant.state_names, B, Ts, s.t_transient, np.ascontiguousarray(band))
    x, z, _ = loop.current(name)
    prev = (x, z)
    cols = list(ob.outputs)
    first = int(math.ceil(s.t_transient / Ts - 1e-9))
    sq, n_sq = np.zeros(B), 0
    white = _Whiteness(B, len(cols))
    con = _Consistency(s, ob, B, consistency and ob.covariance(loop.states[name]) is not None)
    cap = min(segment_length(B), max(1, -(-s.N // NEES_POINTS))) if con.nees_on else (
        segment_length(B))
    pidx = [list(s.plant.state_names).index(st) for st in s.states]
    oidx = [list(ob.state_names).index(st) for st in s.states]
    n_first = int(round(1.0 / Ts))  # the samples of the first second
    iae, peak_e = np.zeros(B), np.zeros(B)
    e0 = None
    while loop.k < s.N:
        k0, T = loop.k, drive.length(loop.k, s.N, cap)
        seg = loop.segment(drive.inputs(loop, T))
        blk = seg.blocks[name]
        acc.add(k0, seg.x, prev, blk.x_hat, blk.z_hat)
        # the estimate before each sample: prev for the first, then the block's rows
        xb = np.concatenate([prev[0][:, None], blk.x_hat[:, :-1]], axis=1)
        zb = np.concatenate([prev[1][:, None], blk.z_hat[:, :-1]], axis=1)
        en = np.linalg.norm((seg.x[:, :, pidx] - xb[:, :, oidx]) / s.ranges, axis=2)
        if e0 is None:
            e0 = en[:, 0].copy()
        with np.errstate(invalid="ignore"):
            peak_e = np.fmax(peak_e, np.max(np.where(np.isfinite(en), en, np.inf), axis=1))
        if k0 < n_first:
            iae += np.sum(en[:, :n_first - k0], axis=1) * Ts
        yh = ob.predicted_output(xb, zb)
        lo = max(first - k0, 0)
        if yh is not None and lo < T:
            e = seg.y_meas[:, lo:, cols] - yh[:, lo:]
            e = np.where(np.isfinite(seg.y_meas[:, lo:, cols]), e, 0.0)
            sq += np.sum(e * e, axis=(1, 2))
            n_sq += (T - lo) * len(cols)
            white.add(e)
        if lo < T:
            con.add_nis(blk.diagnostics[:, lo:], seg.y_meas[:, lo:, cols])
        if loop.k >= first:  # the estimate of the state at sample loop.k
            con.add_nees(plant.state, blk.x_hat[:, -1], loop.states[name])
        prev = (blk.x_hat[:, -1].copy(), blk.z_hat[:, -1].copy())
    Xl = np.reshape(plant.state, (B, 1, -1))
    acc.add(s.N, Xl, prev, prev[0][:, None], prev[1][:, None])
    res = acc.result(len(s.plant.state_names), 0.0)
    idx = [list(s.plant.state_names).index(st) for st in s.states]
    oe = np.sqrt(sq / max(n_sq, 1)) if n_sq else np.full(B, np.nan)
    wh = white.result()
    with np.errstate(divide="ignore", invalid="ignore"):
        peaking = np.where(e0 > 0, peak_e / e0, np.nan) if e0 is not None else np.full(B, np.nan)
    wall = loop.wall[name] / (max(s.N, 1) * B)
    nis, nis_band, nees_m, nees_band = con.result()
    for i, r in enumerate(which):
        rows = slice(i * S, (i + 1) * S)
        bad = acc.bad_row[rows] >= 0
        for key, arr in (("rmse", out.rmse), ("peak", out.peak), ("settling", out.settling)):
            vals = res["settling_time" if key == "settling" else key][rows][:, idx]
            arr[r] = np.where(bad[:, None], np.inf, vals)
        out.output_error[r] = np.where(bad, np.inf, oe[rows])
        out.whiteness[r] = np.where(bad, np.inf, wh[rows])
        out.nis[r] = np.where(bad, np.inf, nis[rows])
        out.nis_band[r] = np.where(bad, 0.0, nis_band[rows])
        out.nees[r] = np.where(bad, np.inf, nees_m[rows])
        out.nees_band[r] = np.where(bad, 0.0, nees_band[rows])
        out.iae[r] = np.where(bad, np.inf, iae[rows])
        out.peaking[r] = np.where(bad, np.inf, peaking[rows])
        out.update_time[r] = wall
        for j in range(S):
            if bad[j]:
                out.message[r][j] = (f"observer {name!r} estimate left the finite numbers at "
                                     f"t={acc.bad_row[rows][j] * Ts:g}")


class _Whiteness:
    """The Box-Pierce statistic of each member's output errors over :data:`WHITENESS_LAGS`
    lags, accumulated over segments (the last ``L`` errors of one carried into the next)."""

    def __init__(self, B: int, p: int) -> None:
        L = WHITENESS_LAGS
        self.tail = np.zeros((B, L, p))  # zeros before the first error: no product
        self.lag = np.zeros((B, L, p))  # sum_k e_k e_{k-l}, l = 1..L
        self.s0 = np.zeros((B, p))
        self.n = 0

    def add(self, e: Array) -> None:
        """The errors ``e`` ``(B, T, p)`` of the next samples (in order)."""
        L, T = WHITENESS_LAGS, e.shape[1]
        ext = np.concatenate([self.tail, e], axis=1)
        for lag in range(1, L + 1):
            self.lag[:, lag - 1] += np.einsum("btp,btp->bp", ext[:, L:], ext[:, L - lag:L - lag + T])
        self.s0 += np.einsum("btp,btp->bp", e, e)
        self.n += T
        self.tail = ext[:, -L:]

    def result(self) -> Array:
        """``(B,)``: ``Q / L``, the mean over the channels (NaN: no error seen)."""
        if self.n == 0:
            return np.full(self.s0.shape[0], np.nan)
        with np.errstate(invalid="ignore", divide="ignore"):
            rho = self.lag / self.s0[:, None, :]
        q = self.n * np.sum(rho * rho, axis=1) / WHITENESS_LAGS  # (B, p)
        return np.asarray(np.mean(q, axis=1))


class _Consistency:
    """A filter's NIS over the samples after the transient and its NEES at the instants after
    it, per member, with the shares inside one sample's chi-square 95 % band (module
    docstring); NaN for an observer without a ``nis`` diagnostic or covariance."""

    def __init__(self, s: Setup, ob: Observer, B: int, nees_on: bool) -> None:
        self.ob, self.B, self.nees_on = ob, B, nees_on
        names = ob.diagnostic_names
        self.nis_col = names.index("nis") if "nis" in names else None
        self.nis_lo, self.nis_hi = chi2_band(np.arange(len(ob.outputs) + 1.0))  # by channels
        plant = list(s.plant.state_names)
        both = [(plant.index(st), j) for j, st in enumerate(ob.state_names) if st in plant]
        self.pidx, self.oidx = [a for a, _ in both], [b for _, b in both]
        self.nees_lo, self.nees_hi = chi2_band(len(both))
        self.sums = np.zeros((4, B))  # nis, nis in band, nees, nees in band
        self.nis_n, self.nees_n = np.zeros(B), 0

    def add_nis(self, D: Array, Y: Array) -> None:
        """The diagnostics ``D`` ``(B, T, d)`` of samples ``Y`` ``(B, T, channels)`` (a sample
        with every channel lost has no NIS; the band is that of the channels present)."""
        if self.nis_col is None:
            return
        v = D[:, :, self.nis_col]
        dof = np.sum(np.isfinite(Y), axis=2)
        self.sums[0] += np.nansum(v, axis=1)
        self.sums[1] += np.sum((v >= self.nis_lo[dof]) & (v <= self.nis_hi[dof]), axis=1)
        self.nis_n += np.sum(~np.isnan(v), axis=1)

    def add_nees(self, x: Array, x_hat: Array, state: Any) -> None:
        """The true state ``x`` ``(B, n)`` and the estimate of it ``x_hat`` ``(B, n_x)``,
        with the covariance of ``state``."""
        P = self.ob.covariance(state) if self.nees_on else None
        if P is None:
            return
        o = self.oidx
        v = nees(x[:, self.pidx] - x_hat[:, o], P[:, o][:, :, o])
        self.sums[2] += v
        self.sums[3] += (v >= self.nees_lo) & (v <= self.nees_hi)
        self.nees_n += 1

    def result(self) -> tuple[Array, Array, Array, Array]:
        """``(nis, nis_band, nees, nees_band)``, each ``(B,)``."""
        nan = np.full(self.B, np.nan)
        with np.errstate(invalid="ignore", divide="ignore"):
            nis = (self.sums[0] / self.nis_n, self.sums[1] / self.nis_n) if (
                self.nis_col is not None) else (nan, nan)
            ne = (self.sums[2] / self.nees_n, self.sums[3] / self.nees_n) if (
                self.nees_on and self.nees_n) else (nan, nan)
        return nis[0], nis[1], ne[0], ne[1]


def _full_ranges(s: Setup) -> Array:
    """Every plant state's range over the run (``ptp``; 1 where 0): the settling band's
    scale, as :func:`hgo_mj.metrics.observer_metrics` with ``relative=True``."""
    with np.errstate(invalid="ignore"):
        ptp = np.ptp(s.X[0], axis=0)
    return np.where(np.isfinite(ptp) & (ptp > 0), ptp, 1.0)
