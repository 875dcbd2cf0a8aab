"""The loop: plant, sensor chain, observers, input; and the :class:`Trajectory` it returns.

Timing (all periods exact integer multiples of each other)::

    physics_dt | plant.dt | sample_period | control_period

Row ``k`` of a trajectory is the sample instant ``t_k = k * sample_period``: the true state
``x(t_k)``, the clean and measured outputs, the input ``u(t_k)`` applied over the next sample,
and for each observer its estimate of ``x(t_k)`` *before* it consumes ``y(t_k)`` (a
continuous-time observer with the measurement held between samples: row 0 is the initial
estimate). Every observer sees the same measurement stream.

An observer's estimate need not have the plant's state layout: an order-only high-gain
observer estimates ``z = (y, y', ...)``, an adaptive one may append parameters. Each
:class:`ObserverRecord` names its columns (``state_names``, the observer's own), and
:meth:`Trajectory.error` matches them to the plant's states by name: a plant state the
observer does not estimate has a NaN error ("not estimated"). A NaN in ``x_hat`` is also
how an observer says that its inverse normal-form map is undefined there (see
:class:`~hgo_mj.observers.base.Observer`); divergence is judged on the observer's own
coordinates ``z_hat``.
"""

from __future__ import annotations

import json
import platform
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from importlib import metadata as importlib_metadata
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._validate import finite_scalar, integer_multiple, vector
from .exceptions import DesignError, DimensionError, DivergenceError
from .inputs import Controller
from .observers.base import Observer
from .plants.base import Plant
from .sensors import SensorChain, Stage

Array = NDArray[np.float64]


@dataclass
class ObserverRecord:
    """One observer's columns in a :class:`Trajectory`.

    ``state_names`` names the columns of ``x_hat`` (the observer's ``state_names``); empty
    means "the plant's states", which :class:`Trajectory` fills in when the widths agree
    (``x_hat_1, x_hat_2, ...`` otherwise, as for files written before the names were saved).
    """

    x_hat: Array
    z_hat: Array
    diagnostics: dict[str, Array] = field(default_factory=dict)
    #: mean wall time of one ``update`` call, seconds
    update_time: float = float("nan")
    #: names of the columns of ``x_hat``
    state_names: tuple[str, ...] = ()


@dataclass
class Trajectory:
    """Numpy columns of one run; ``save``/``load`` use one ``.npz`` with JSON metadata."""

    t: Array
    x: Array
    y_clean: Array
    y_meas: Array
    u: Array
    observers: dict[str, ObserverRecord]
    state_names: tuple[str, ...]
    output_names: tuple[str, ...]
    input_names: tuple[str, ...]
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = len(self.state_names)
        for name, rec in self.observers.items():
            width = rec.x_hat.shape[1] if rec.x_hat.ndim == 2 else 1
            if not rec.state_names:
                rec.state_names = (tuple(self.state_names) if width == n
                                   else tuple(f"x_hat_{i + 1}" for i in range(width)))
            rec.state_names = tuple(str(s) for s in rec.state_names)
            if len(rec.state_names) != width:
                raise DimensionError(f"observer {name!r}: state_names must name the {width} "
                                     f"column(s) of x_hat; found {len(rec.state_names)} "
                                     f"{list(rec.state_names)}")
            if len(set(rec.state_names)) != width:
                raise DimensionError(f"observer {name!r}: state_names must be distinct; found "
                                     f"{list(rec.state_names)}")

    def __len__(self) -> int:
        return int(self.t.size)

    def _record(self, observer: str) -> ObserverRecord:
        if observer not in self.observers:
            raise DesignError(f"no observer {observer!r} in the trajectory; found "
                              f"{sorted(self.observers)}")
        return self.observers[observer]

    def estimated(self, observer: str) -> NDArray[np.bool_]:
        """Which plant states (``state_names``) the observer estimates (by name), shape ``(n,)``."""
        own = set(self._record(observer).state_names)
        return np.array([s in own for s in self.state_names], dtype=bool)

    def estimate(self, observer: str) -> Array:
        """The observer's ``x_hat`` on the plant's state columns, shape ``(T, n)``: matched by
        name, NaN for a plant state it does not estimate. Its columns that are not plant states
        (``extra_states``) are left out."""
        rec = self._record(observer)
        cols = {s: j for j, s in enumerate(rec.state_names)}
        out = np.full(self.x.shape, np.nan)
        for i, s in enumerate(self.state_names):
            j = cols.get(s)
            if j is not None:
                out[:, i] = rec.x_hat[:, j]
        return out

    def extra_states(self, observer: str) -> tuple[str, ...]:
        """Names of the observer's columns that are not plant states (derivatives of an
        output, parameter estimates, ...): they have no true value to compare with."""
        plant = set(self.state_names)
        return tuple(s for s in self._record(observer).state_names if s not in plant)

    def error(self, observer: str) -> Array:
        """``x - x_hat`` of one observer, shape ``(T, n)`` (the plant's states), columns matched
        by name: NaN for a plant state the observer does not estimate, and where its estimate
        is NaN (inverse map undefined)."""
        return self.x - self.estimate(observer)

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        cols: dict[str, Any] = {"t": self.t, "x": self.x, "y_clean": self.y_clean,
                                "y_meas": self.y_meas, "u": self.u}
        obs_meta = {}
        for name, rec in self.observers.items():
            cols[f"obs/{name}/x_hat"] = rec.x_hat
            cols[f"obs/{name}/z_hat"] = rec.z_hat
            for d, v in rec.diagnostics.items():
                cols[f"obs/{name}/diag/{d}"] = v
            obs_meta[name] = {"diagnostics": list(rec.diagnostics), "update_time": rec.update_time,
                              "state_names": list(rec.state_names)}
        meta = {"state_names": self.state_names, "output_names": self.output_names,
                "input_names": self.input_names, "observers": obs_meta,
                "metadata": self.metadata}
        cols["__meta__"] = np.array(json.dumps(meta))
        with open(path, "wb") as fh:
            np.savez_compressed(fh, **cols)
        return path

    @classmethod
    def load(cls, path: str | Path) -> Trajectory:
        with np.load(Path(path), allow_pickle=False) as z:
            meta = json.loads(str(z["__meta__"]))
            observers = {
                name: ObserverRecord(
                    x_hat=z[f"obs/{name}/x_hat"], z_hat=z[f"obs/{name}/z_hat"],
                    diagnostics={d: z[f"obs/{name}/diag/{d}"] for d in om["diagnostics"]},
                    update_time=float(om["update_time"]),
                    state_names=tuple(om.get("state_names") or ()))
                for name, om in meta["observers"].items()}
            return cls(t=z["t"], x=z["x"], y_clean=z["y_clean"], y_meas=z["y_meas"], u=z["u"],
                       observers=observers, state_names=tuple(meta["state_names"]),
                       output_names=tuple(meta["output_names"]),
                       input_names=tuple(meta["input_names"]), metadata=meta["metadata"])


def package_versions() -> dict[str, str]:
    """Versions of the packages a result depends on, for its metadata (looked up once per
    process: the lookup costs milliseconds; a fresh dict each call)."""
    if not _VERSIONS:
        out = {"python": platform.python_version()}
        for pkg in ("hgo_mj", "mujoco", "numpy", "scipy", "gymnasium", "rerun-sdk"):
            try:
                out[pkg] = importlib_metadata.version(pkg)
            except importlib_metadata.PackageNotFoundError:
                out[pkg] = "not installed"
        _VERSIONS.update(out)
    return dict(_VERSIONS)


_VERSIONS: dict[str, str] = {}


def _named_observers(observers: Any) -> dict[str, Observer]:
    if observers is None:
        return {}
    if isinstance(observers, Observer):
        observers = [observers]
    if isinstance(observers, Mapping):
        items = list(observers.items())
    else:
        items = []
        for i, ob in enumerate(observers):
            items.append((f"{ob.name or type(ob).__name__}_{i}", ob))
    for name, ob in items:
        if not isinstance(ob, Observer):
            raise DesignError(f"observer {name!r} must be an Observer; found {type(ob).__name__}")
    return dict(items)


def simulate(plant: Plant, sensor: Callable[[float, Array], Array] | None,
             observers: Mapping[str, Observer] | Sequence[Observer] | Observer | None,
             inputs: Callable[..., Any], duration: float, *, sample_period: float | None = None,
             control_period: float | None = None, x0: Any = None, seed: int | None = None,
             metadata: Mapping[str, Any] | None = None,
             on_chunk: tuple[float, Callable[[int, Trajectory], None]] | None = None) -> Trajectory:
    """Run plant, sensor chain and observers together and return the :class:`Trajectory`.

    Parameters
    ----------
    plant : Plant
        The true plant; ``plant.dt`` is its step (a multiple of its physics step).
    sensor : SensorChain or callable ``(t, y) -> y_meas`` or None
        Applied to the clean outputs at every sample; ``None`` measures exactly. A chain with a
        ``reset`` method is reset (and re-seeded with ``seed``) first.
    observers : mapping name -> Observer, sequence, single Observer, or None
        Every observer is reset to its own initial estimate and fed the same ``y_meas``.
    inputs : callable
        An open-loop signal ``u(t)`` (read with its ``value_list(t)`` where its class defines
        it, see :class:`~hgo_mj.inputs.Signal`) or a :class:`~hgo_mj.inputs.Controller` (fed the
        named observer's estimate, or the true state).
    duration : float
        Simulated time; the trajectory has ``round(duration / sample_period) + 1`` rows.
    sample_period, control_period : float, optional
        Defaults: ``plant.dt`` and ``sample_period``; each a multiple of the one before.
    x0 : array_like, optional
        Initial true state (default ``plant.system.default_x0``).
    seed : int, optional
        Seed of the sensor chain's generator: the same seed gives a bit-identical run.
    on_chunk : (seconds, callback), optional
        Hand the rows over as they are simulated: ``callback(first_row, chunk)`` is called with
        a :class:`Trajectory` of the rows ``first_row ...`` each time ``seconds`` of simulated
        time have been collected (at least one row), and once more with the rows left at the
        end (a tail shorter than half a chunk joins the last chunk), also when the run stops
        on a :class:`DivergenceError`. A chunk's metadata holds
        only ``sample_period`` and ``first_row``; its ``update_time`` is NaN. Used by
        :class:`hgo_mj.record.Recorder` so that a run killed part-way leaves a recording of
        everything up to its last chunk. The simulated values do not depend on it.

    Returns
    -------
    Trajectory
        Each observer's record names its columns (``state_names``). The metadata's
        ``inverse_failures`` maps each observer to the number of failed evaluations of its
        inverse normal-form map over the run (``Observer.inverse_failures_``: while the
        inverse is undefined ``x_hat`` holds its last valid value, NaN before any).

    Raises
    ------
    DivergenceError
        If an observer's own state ``z_hat`` leaves the finite numbers (or ``x_hat`` becomes
        infinite; a NaN ``x_hat`` with a finite ``z_hat`` only means that the inverse map is
        undefined there), or if an observer's update raises ``FloatingPointError``,
        ``ValueError`` or another ``ArithmeticError`` (a math domain error or an overflow on a
        blown-up estimate, a ``DesignError`` of a map evaluated outside its domain; the
        message names the observer and the time; the original error is ``exc.__cause__``).
        The partial trajectory is attached to the exception as ``exc.trajectory``. A
        ``DimensionError`` in an update (a shape mistake) and every error raised before the
        loop (argument validation, ``check_period``) propagate unchanged.
    """
    Ts = plant.dt if sample_period is None else finite_scalar("sample_period", sample_period,
                                                               positive=True)
    steps = integer_multiple("sample_period", Ts, plant.dt, "plant.dt")
    Tc = Ts if control_period is None else finite_scalar("control_period", control_period,
                                                         positive=True)
    every = integer_multiple("control_period", Tc, Ts, "sample_period")
    duration = finite_scalar("duration", duration, positive=True)
    N = int(round(duration / Ts))
    obs = _named_observers(observers)
    chunk_rows, chunk_cb = -1, None
    if on_chunk is not None:
        if not (isinstance(on_chunk, tuple) and len(on_chunk) == 2 and callable(on_chunk[1])):
            raise DesignError(f"on_chunk must be a tuple (seconds, callback); found {on_chunk!r}")
        chunk_s = finite_scalar("on_chunk seconds", on_chunk[0], positive=True)
        chunk_rows, chunk_cb = max(int(round(chunk_s / Ts)), 1), on_chunk[1]
    value_list: Callable[[float], list[float]] | None = None
    if isinstance(inputs, Controller):
        if inputs.source == "estimate":
            if not obs:
                raise DesignError("a Controller on the estimate needs at least one observer")
            ctrl_obs = obs[inputs.observer] if inputs.observer is not None else next(
                iter(obs.values()))
        controller = True
    elif callable(inputs):
        controller = False
        if _owns(inputs, "value_list", "__call__"):  # a signal's plain-float path
            value_list = inputs.value_list
    else:
        raise DesignError(f"inputs must be a signal u(t) or a Controller; found "
                          f"{type(inputs).__name__}")

    plant.reset(x0)
    if sensor is not None and hasattr(sensor, "reset"):
        sensor.reset(seed)
    for ob in obs.values():
        ob.reset()
        ob.check_period(Ts)  # a too-long period for a high gain is refused before the run
    n, m, p = len(plant.state_names), len(plant.output_names), len(plant.input_names)
    obs_list = list(obs.values())
    names = list(obs)
    x_hat: list[Any] = [ob.x_hat for ob in obs_list]  # update() returns the next one
    est_names: list[tuple[str, ...]] = []
    for (name, ob), xh in zip(obs.items(), x_hat):
        names_i = tuple(str(s) for s in ob.state_names)
        width = np.asarray(xh).size
        if len(names_i) != width:
            raise DimensionError(f"observer {name!r} ({type(ob).__name__}): state_names must "
                                 f"name the {width} entries of x_hat; found {len(names_i)} "
                                 f"{list(names_i)}")
        est_names.append(names_i)

    # The fast paths: plain Python floats per sample, no small arrays, where the plant, the
    # sensor stages, the open-loop signal and the observers offer them (``state_list``,
    # ``apply_list``, ``value_list``, ``update_list``, ...: the same values, see the
    # differential test); the array interface
    # otherwise. Rows are collected in flat lists (arrays: lists of rows) and stacked per chunk.
    state_list = plant.state_list if _owns(plant, "state_list", "state") else (
        lambda: Plant.state_list(plant))
    outputs_list = plant.outputs_list if _owns(plant, "outputs_list", "outputs") else (
        lambda: Plant.outputs_list(plant))
    step_list = _owns(plant, "step_list", "step")  # step() takes a list of floats
    plant_step = plant.step_list if step_list else plant.step
    stages: list[Callable[..., list[float]]] | None = None
    if isinstance(sensor, SensorChain) and type(sensor).__call__ is SensorChain.__call__:
        stages = [s.apply_list if _owns(s, "apply_list", "__call__")
                  else partial(Stage.apply_list, s) for s in sensor.stages]
        rng = sensor.rng
    fast = [_fast_observer(ob) for ob in obs_list]
    diag_keys: list[tuple[str, ...]] = []
    for i, ob in enumerate(obs_list):
        keys = tuple(ob.diagnostics()) if fast[i] is not None and fast[i][2] is not None else ()
        if keys and len(fast[i][2]()) != len(keys):  # type: ignore[index,misc]
            fast[i] = (fast[i][0], fast[i][1], None)  # type: ignore[index]
        diag_keys.append(keys if fast[i] is not None and fast[i][2] is not None else ())
    for i, f in enumerate(fast):
        if f is not None:
            x_hat[i] = np.asarray(x_hat[i], dtype=float).reshape(-1).tolist()
    need_array = any(f is None for f in fast)  # an observer on the array interface
    # the input as an array only for those on the array interface (observers, plant step)
    u_array = need_array or not step_list

    X: list[float] = []
    Yc: list[float] = []
    Ym: list[float] = []
    U: list[float] = []
    # per observer: flat lists of floats (fast path) or lists of arrays / dicts (array path)
    xh_rows: list[list[Any]] = [[] for _ in names]
    zh_rows: list[list[Any]] = [[] for _ in names]
    dg_rows: list[list[Any]] = [[] for _ in names]
    wall = [0.0] * len(names)
    # per observer, what the loop calls and fills: (index, observer, update_list or None,
    # z_hat_list, diagnostic_values or None, its x_hat, z_hat and diagnostics rows)
    ops = [(i, ob, None if f is None else f[0], None if f is None else f[1],
            None if f is None else f[2], xh_rows[i], zh_rows[i], dg_rows[i])
           for i, (ob, f) in enumerate(zip(obs_list, fast))]
    updates = [(i, ob, upd) for i, ob, upd, *_ in ops]
    perf = time.perf_counter
    u = np.zeros(p)
    ul: list[float] = u.tolist()
    uarg: Any = ul if step_list else u
    failure: Exception | None = None
    f64 = np.dtype(np.float64)

    def build(k0: int, rows: int, meta: dict[str, Any],
              update_time: list[float] | None = None) -> Trajectory:
        """The rows collected in the lists (run rows ``k0 ...``) as a :class:`Trajectory`."""
        records = {}
        for i, name in enumerate(names):
            dg = dg_rows[i]
            if diag_keys[i]:
                keys = diag_keys[i]
                vals = np.array(dg, dtype=float).reshape(rows, len(keys))
                diag = {d: vals[:, j].copy() for j, d in enumerate(keys)} if rows else {}
            else:
                diag = {d: np.array([r[d] for r in dg], dtype=float)
                        for d in (dg[0] if dg else ())}
            records[name] = ObserverRecord(
                x_hat=_stack(xh_rows[i], rows, len(est_names[i])),
                z_hat=_stack(zh_rows[i], rows, 0), diagnostics=diag,
                update_time=float("nan") if update_time is None else update_time[i],
                state_names=est_names[i])
        return Trajectory(
            t=np.arange(k0, k0 + rows) * Ts, x=np.array(X, dtype=float).reshape(rows, n),
            y_clean=np.array(Yc, dtype=float).reshape(rows, m),
            y_meas=np.array(Ym, dtype=float).reshape(rows, m),
            u=np.array(U, dtype=float).reshape(rows, p), observers=records,
            state_names=tuple(plant.state_names), output_names=tuple(plant.output_names),
            input_names=tuple(plant.input_names), metadata=meta)

    parts: list[Trajectory] = []  # chunks handed to on_chunk; their rows leave the lists

    def emit(k0: int, rows: int) -> None:
        chunk = build(k0, rows, {"sample_period": Ts, "first_row": k0})
        for lst in (X, Yc, Ym, U, *xh_rows, *zh_rows, *dg_rows):
            lst.clear()
        parts.append(chunk)
        chunk_cb(k0, chunk)

    sent = 0  # rows already handed to on_chunk
    done = 0  # rows collected so far
    next_chunk = chunk_rows
    ym_arr: Any = None
    try:
        for k in range(N + 1):
            t = k * Ts
            xl = state_list()
            ycl = outputs_list()
            if stages is not None:
                yml = ycl
                for apply in stages:
                    yml = apply(t, yml, rng)
                if need_array:
                    ym_arr = np.array(yml)
            elif sensor is not None:
                ym_arr = sensor(t, np.array(ycl))
                yml = np.asarray(ym_arr, dtype=float).reshape(-1).tolist()
            else:
                yml = ycl
                if need_array:
                    ym_arr = np.array(ycl)
            if k % every == 0:
                if value_list is not None:
                    ul = value_list(t)
                    if len(ul) != p:
                        raise DimensionError(f"input must have {p} channel(s) "
                                             f"{plant.input_names}; found shape ({len(ul)},) "
                                             f"at t={t:g}")
                    if u_array:
                        u = np.array(ul, dtype=float)
                        uarg = ul if step_list else u
                    else:
                        uarg = ul
                else:
                    if controller:
                        u = inputs(t, np.array(xl) if inputs.source == "true"
                                   else ctrl_obs.x_hat)
                    else:
                        u = inputs(t)
                    if type(u) is not np.ndarray or u.dtype is not f64 or u.ndim != 1:
                        u = np.asarray(u, dtype=float).reshape(-1)
                    if u.shape != (p,):
                        raise DimensionError(f"input must have {p} channel(s) "
                                             f"{plant.input_names}; found shape {u.shape} at "
                                             f"t={t:g}")
                    ul = u.tolist()
                    uarg = ul if step_list else u
            X += xl
            Yc += ycl
            Ym += yml
            U += ul
            for i, ob, upd, zl, dv, xr, zr, dr in ops:
                if upd is None:
                    xr.append(x_hat[i])
                    zr.append(ob.z_hat)
                    dr.append(ob.diagnostics())
                else:
                    xr += x_hat[i]
                    zr += zl()
                    if dv is None:
                        dr.append(ob.diagnostics())
                    else:
                        dr += dv()
            done = k + 1
            if done == next_chunk:
                if N - k >= chunk_rows // 2:  # a short tail is folded into the last chunk
                    emit(sent, done - sent)
                    sent = done
                next_chunk = done + chunk_rows
            if k == N:
                break
            for i, ob, upd in updates:
                t0 = perf()
                try:
                    x_hat[i] = ob.update(ym_arr, u, Ts) if upd is None else upd(yml, ul, Ts)
                except DimensionError:
                    raise  # a shape mistake, not a divergence
                except (DivergenceError, ValueError, ArithmeticError) as exc:
                    # the observer's own check, or math on a blown-up estimate (a domain error,
                    # an overflow, a DesignError of a map outside its domain): a divergence
                    raise _UpdateFailure(names[i], t, k, exc) from exc
                wall[i] += perf() - t0
            if steps == 1:
                plant_step(uarg)
            else:
                for _ in range(steps):
                    plant_step(uarg)
    except _UpdateFailure as exc:
        failure = exc
    except (DivergenceError, FloatingPointError) as exc:
        failure = exc  # keep what was simulated: the partial trajectory goes with the error

    if chunk_cb is not None and done > sent:
        emit(sent, done - sent)
    rows = done
    meta = {"plant": type(plant.system).__name__, "system_params": plant.system.params,
            "plant_dt": plant.dt, "physics_dt": getattr(plant, "physics_dt", plant.dt),
            "sample_period": Ts, "control_period": Tc, "duration": duration, "seed": seed,
            "x0": plant_x0(plant, x0),
            "sensor": sensor.describe() if hasattr(sensor, "describe") else repr(sensor),
            "observers": {name: {"type": type(ob).__name__, **ob.params()}
                          for name, ob in obs.items()},
            "input": {"type": type(inputs).__name__,
                      **(inputs.params() if hasattr(inputs, "params") else {})},
            "inverse_failures": {name: int(getattr(ob, "inverse_failures_", 0))
                                 for name, ob in obs.items()},
            "versions": package_versions(), **(dict(metadata) if metadata else {})}
    update_time = [w / max(rows - 1, 1) for w in wall]
    traj = (build(0, rows - sent, meta, update_time) if not parts
            else _concatenate(parts, meta, update_time))
    records, t_col = traj.observers, traj.t
    if isinstance(failure, _UpdateFailure):
        cause = failure.cause
        exc = DivergenceError(f"observer {failure.observer!r} failed in its update at "
                              f"t={failure.t:g} (row {failure.row}): {type(cause).__name__}: "
                              f"{cause}")
        exc.trajectory = traj  # type: ignore[attr-defined]
        raise exc from cause
    if failure is not None:
        exc = DivergenceError(f"simulation stopped at t={(rows - 1) * Ts:g}: {failure}")
        exc.trajectory = traj  # type: ignore[attr-defined]
        raise exc from failure
    for name, r in records.items():
        # the observer's own coordinates decide; a NaN x_hat (inverse undefined) is allowed
        bad = ~np.all(np.isfinite(r.z_hat), axis=1) | np.any(np.isinf(r.x_hat), axis=1)
        if bad.any():
            k = int(np.argmax(bad))
            exc = DivergenceError(f"observer {name!r} estimate left the finite numbers at "
                                  f"t={t_col[k]:g} (row {k}): z_hat = {r.z_hat[k].tolist()}, "
                                  f"x_hat = {r.x_hat[k].tolist()}")
            exc.trajectory = traj  # type: ignore[attr-defined]
            raise exc
    return traj


def _owns(obj: Any, fast: str, slow: str) -> bool:
    """Whether ``obj``'s method ``fast`` (a plain-float variant) belongs to the class that
    defines the ``slow`` one it stands for, or to a subclass of it: a subclass that overrides
    ``slow`` but not ``fast`` keeps the general path."""
    mro = type(obj).__mro__
    f = next((c for c in mro if fast in vars(c)), None)
    s = next((c for c in mro if slow in vars(c)), None)
    return f is not None and s is not None and issubclass(f, s)


def _fast_observer(ob: Observer) -> tuple[Callable[..., list[float]],
                                          Callable[[], list[float]],
                                          Callable[[], tuple[float, ...]] | None] | None:
    """``(update_list, z_hat_list, diagnostic_values or None)`` of an observer with the
    plain-float path (the high-gain family), or None: the array interface."""
    if not (_owns(ob, "update_list", "update") and _owns(ob, "x_hat_list", "x_hat")
            and _owns(ob, "z_hat_list", "z_hat")):
        return None
    dv = ob.diagnostic_values if _owns(ob, "diagnostic_values", "diagnostics") else None  # type: ignore[attr-defined]
    return ob.update_list, ob.z_hat_list, dv  # type: ignore[attr-defined]


def _stack(rows_list: list[Any], rows: int, width: int) -> Array:
    """``rows`` rows collected as a flat list of floats or as a list of arrays, shape
    ``(rows, width)`` (``width`` 0: inferred)."""
    if not rows:
        return np.empty((0, width))
    return np.array(rows_list, dtype=float).reshape(rows, -1)


class _UpdateFailure(Exception):
    """An observer's update raised a math error (carried out of the loop, then re-raised as a
    :class:`DivergenceError` with the partial trajectory)."""

    def __init__(self, observer: str, t: float, row: int, cause: BaseException) -> None:
        super().__init__(f"observer {observer!r} at t={t:g}: {cause}")
        self.observer, self.t, self.row, self.cause = observer, t, row, cause


def _concatenate(parts: list[Trajectory], meta: dict[str, Any],
                 update_time: list[float]) -> Trajectory:
    """One trajectory of consecutive chunks."""
    first = parts[0]
    records = {}
    for i, name in enumerate(first.observers):
        recs = [c.observers[name] for c in parts]
        records[name] = ObserverRecord(
            x_hat=np.concatenate([r.x_hat for r in recs]),
            z_hat=np.concatenate([r.z_hat for r in recs]),
            diagnostics={d: np.concatenate([r.diagnostics[d] for r in recs])
                         for d in recs[0].diagnostics}, update_time=update_time[i],
            state_names=recs[0].state_names)
    return Trajectory(t=np.concatenate([c.t for c in parts]),
                      x=np.concatenate([c.x for c in parts]),
                      y_clean=np.concatenate([c.y_clean for c in parts]),
                      y_meas=np.concatenate([c.y_meas for c in parts]),
                      u=np.concatenate([c.u for c in parts]), observers=records,
                      state_names=first.state_names, output_names=first.output_names,
                      input_names=first.input_names, metadata=meta)


def plant_x0(plant: Plant, x0: Any) -> list[float]:
    if x0 is not None:
        return vector("x0", x0).tolist()
    return [float(v) for v in plant.system.default_x0]


__all__ = ["ObserverRecord", "Trajectory", "simulate", "package_versions"]
