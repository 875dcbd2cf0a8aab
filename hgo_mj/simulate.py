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
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from importlib import metadata as importlib_metadata
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._io import atomic_path
from ._validate import finite_scalar, positive_int, vector
from .exceptions import DesignError, DimensionError, DivergenceError, TrajectoryFileError
from .loop import Drive, Loop, LoopFailure, Periods, Segment
from .observers.base import Observer
from .plants.base import Plant
from .sensors import SensorChain

Array = NDArray[np.float64]


@dataclass
class ObserverRecord:
    """One observer's columns in a :class:`Trajectory`.

    ``state_names`` names the columns of ``x_hat`` (the observer's ``state_names``); empty
    means "the plant's states", which :class:`Trajectory` fills in when the widths agree
    (``x_hat_1, x_hat_2, ...`` otherwise, as for files written before the names were saved).

    Parameters
    ----------
    x_hat : ndarray, shape (T, n_hat)
        The observer's estimate at each sample instant, in its own state layout.
    z_hat : ndarray, shape (T, n_z)
        The estimate in the observer's own coordinates (e.g. the normal form).
    diagnostics : dict of str to ndarray, shape (T,)
        Per-sample diagnostics named by the observer's ``diagnostic_names`` (default: none).
    update_time : float
        Mean wall time of one ``update`` call, seconds (default NaN: not measured).
    state_names : tuple of str
        Names of the columns of ``x_hat`` (default ``()``: the plant's states).

    Examples
    --------
    >>> import numpy as np
    >>> rec = ObserverRecord(x_hat=np.zeros((3, 2)), z_hat=np.zeros((3, 2)),
    ...                      state_names=("angle", "angular_velocity"))
    >>> rec.x_hat.shape, rec.state_names, rec.diagnostics
    ((3, 2), ('angle', 'angular_velocity'), {})
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
    """Numpy columns of one run; ``save``/``load`` use one ``.npz`` with JSON metadata.

    Made by :func:`simulate` (row ``k`` is the sample instant ``t[k]``); a user rarely builds
    one directly.

    Parameters
    ----------
    t : ndarray, shape (T,)
        Sample instants.
    x : ndarray, shape (T, n)
        True state.
    y_clean, y_meas : ndarray, shape (T, p)
        Clean and measured outputs (NaN: a dropout).
    u : ndarray, shape (T, m)
        Input applied from each instant.
    observers : dict of str to ObserverRecord
        Each observer's ``x_hat``, ``z_hat``, diagnostics and state names.
    state_names, output_names, input_names : tuple of str
        Names of the columns of ``x``, ``y_*`` and ``u``.
    metadata : dict
        Scenario, seed, periods, package versions (strict JSON when saved).

    Raises
    ------
    DimensionError
        Columns whose lengths disagree with ``t``, or observer state names that do not name
        its columns.

    Examples
    --------
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> plant = make_plant("pendulum", dt=0.01)
    >>> traj = simulate(plant, None, {"k10": HighGainObserver(plant.system, k=10.0)},
    ...                 lambda t: [0.0], duration=1.0, x0=[0.2, 0.0])
    >>> len(traj), traj.state_names, traj.error("k10").shape
    (101, ('angle', 'angular_velocity'), (101, 2))
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = traj.save(f"{tmp}/run.npz")
    ...     path.name, len(Trajectory.load(path))
    ('run.npz', 101)
    """

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
        self._check_lengths()
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

    def _check_lengths(self) -> None:
        """Every column has one row per sample instant of ``t`` (a file whose columns disagree
        is refused, not read with rows silently misaligned)."""
        if np.ndim(self.t) != 1:
            raise DimensionError(f"t must be 1-D (one time per row); found shape "
                                 f"{np.shape(self.t)}")
        T = len(self.t)
        cols: dict[str, Any] = {"x": self.x, "y_clean": self.y_clean, "y_meas": self.y_meas,
                                "u": self.u}
        for name, rec in self.observers.items():
            cols[f"observers[{name!r}].x_hat"] = rec.x_hat
            cols[f"observers[{name!r}].z_hat"] = rec.z_hat
            for d, v in rec.diagnostics.items():
                cols[f"observers[{name!r}].diagnostics[{d!r}]"] = v
        for key, v in cols.items():
            if np.ndim(v) == 0 or len(v) != T:
                raise DimensionError(f"trajectory column {key} must have {T} rows (one per "
                                     f"time in t); found shape {np.shape(v)}")

    def __len__(self) -> int:
        return int(self.t.size)

    @property
    def diverged(self) -> dict[str, dict[str, Any]]:
        """The observers stopped alone by a failure (``simulate(..., isolate=True)``): name ->
        ``{"t": the instant of the sample whose update failed, "sample": its index, "row": the
        first stored row that is NaN (rows hold the estimate before each sample's update),
        "error": "Type: message"}``; empty when none did.

        Returns
        -------
        dict of str to dict

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> simulate(plant, None, {"hgo": HighGainObserver(plant.system, k=5.0)},
        ...          lambda t: [0.0], 0.1, isolate=True).diverged
        {}
        """
        return dict(self.metadata.get("diverged", {}))

    def _record(self, observer: str) -> ObserverRecord:
        if observer not in self.observers:
            raise DesignError(f"no observer {observer!r} in the trajectory; found "
                              f"{sorted(self.observers)}")
        return self.observers[observer]

    def estimated(self, observer: str) -> NDArray[np.bool_]:
        """Which plant states (``state_names``) the observer estimates (by name), shape ``(n,)``.

        Parameters
        ----------
        observer : str
            Name of the observer in :attr:`observers`.

        Returns
        -------
        ndarray of bool, shape (n,)
            ``True`` for each plant state that the observer has a column of the same name for.

        Raises
        ------
        DesignError
            No observer of that name in the trajectory.

        Examples
        --------
        >>> from hgo_mj.observers import make_observer
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", 0.01)
        >>> traj = simulate(plant, None, {"hgo": make_observer("high_gain", plant.system,
        ...                 k=20.0)}, lambda t: [0.0], duration=0.1, x0=[0.2, 0.0])
        >>> traj.estimated("hgo")
        array([ True,  True])
        """
        own = set(self._record(observer).state_names)
        return np.array([s in own for s in self.state_names], dtype=bool)

    def estimate(self, observer: str) -> Array:
        """The observer's ``x_hat`` on the plant's state columns, shape ``(T, n)``: matched by
        name, NaN for a plant state it does not estimate. Its columns that are not plant states
        (``extra_states``) are left out.

        Parameters
        ----------
        observer : str
            Name of the observer in :attr:`observers`.

        Returns
        -------
        ndarray, shape (T, n)
            The estimate on the plant's state columns (NaN where not estimated).

        Raises
        ------
        DesignError
            No observer of that name in the trajectory.

        Examples
        --------
        >>> from hgo_mj.observers import make_observer
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", 0.01)
        >>> traj = simulate(plant, None, {"hgo": make_observer("high_gain", plant.system,
        ...                 k=20.0)}, lambda t: [0.0], duration=0.1, x0=[0.2, 0.0])
        >>> est = traj.estimate("hgo")
        >>> est.shape, est[0].tolist() == traj.observers["hgo"].x_hat[0].tolist()
        ((11, 2), True)
        """
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
        output, parameter estimates, ...): they have no true value to compare with.

        Parameters
        ----------
        observer : str
            Name of the observer in :attr:`observers`.

        Returns
        -------
        tuple of str
            The observer's column names that are not in :attr:`state_names`, in its order
            (empty when it estimates the plant's states only).

        Raises
        ------
        DesignError
            No observer of that name in the trajectory.

        Examples
        --------
        >>> from hgo_mj.observers import make_observer
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", 0.01)
        >>> traj = simulate(plant, None, {"hgo": make_observer("high_gain", plant.system,
        ...                 k=20.0)}, lambda t: [0.0], duration=0.1, x0=[0.2, 0.0])
        >>> traj.extra_states("hgo")
        ()
        """
        plant = set(self.state_names)
        return tuple(s for s in self._record(observer).state_names if s not in plant)

    def error(self, observer: str) -> Array:
        """``x - x_hat`` of one observer, shape ``(T, n)`` (the plant's states), columns matched
        by name: NaN for a plant state the observer does not estimate, and where its estimate
        is NaN (inverse map undefined).

        Parameters
        ----------
        observer : str
            Name of the observer in :attr:`observers`.

        Returns
        -------
        ndarray, shape (T, n)
            The estimation error on the plant's state columns.

        Raises
        ------
        DesignError
            No observer of that name in the trajectory.

        Examples
        --------
        >>> from hgo_mj.observers import make_observer
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", 0.01)
        >>> traj = simulate(plant, None, {"hgo": make_observer("high_gain", plant.system,
        ...                 k=20.0)}, lambda t: [0.0], duration=0.1, x0=[0.2, 0.0])
        >>> err = traj.error("hgo")
        >>> err.shape, bool(np.all(np.isfinite(err)))
        ((11, 2), True)
        """
        return self.x - self.estimate(observer)

    def to_pandas(self, form: str = "wide") -> Any:
        """The run as a :class:`pandas.DataFrame`: ``form="wide"`` (one row per sample, the
        columns ``t``, ``true/<state>``, ``<observer>/<state>``,
        ``<observer>/diagnostics/<name>``, ``measured/<output>``, ``clean/<output>``,
        ``input/<input>``; ``attrs["units"]`` their units) or ``form="long"`` (one row per
        sample and column: ``t``, ``source``, ``name``, ``value``, ``unit``). See
        :mod:`hgo_mj.tidy`.

        Parameters
        ----------
        form : {"wide", "long"}
            The layout (default ``"wide"``).

        Returns
        -------
        pandas.DataFrame
            The run's columns in that layout; ``attrs["units"]`` maps each column to its unit
            in the wide form.

        Raises
        ------
        DesignError
            ``form`` is neither ``"wide"`` nor ``"long"``.

        Examples
        --------
        >>> from hgo_mj.inputs import Constant
        >>> from hgo_mj.observers import make_observer
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", 0.01)
        >>> traj = simulate(plant, None, {"hgo": make_observer("high_gain", plant.system,
        ...                 k=20.0)}, Constant(0.0), duration=0.1)
        >>> df = traj.to_pandas()
        >>> df.shape
        (11, 10)
        >>> df.attrs["units"]["hgo/angular_velocity"], df.attrs["units"]["t"]
        ('rad/s', 's')
        >>> long = traj.to_pandas("long")
        >>> sorted(set(long["source"]))
        ['clean', 'hgo', 'hgo/diagnostics', 'input', 'measured', 'true']
        """
        from .tidy import to_pandas

        return to_pandas(self, form)

    def to_arrow(self, form: str = "wide") -> Any:
        """The run as a :class:`pyarrow.Table` (the columns of :meth:`to_pandas`); in the wide
        form each field's metadata holds its unit (``field.metadata[b"unit"]``), and the
        schema metadata ``b"hgo_mj"`` the names, units and run metadata as JSON. Writing it
        with :func:`pyarrow.parquet.write_table` keeps both (:func:`hgo_mj.tidy.write_table`
        does so atomically).

        Parameters
        ----------
        form : {"wide", "long"}
            The layout, as in :meth:`to_pandas` (default ``"wide"``).

        Returns
        -------
        pyarrow.Table
            The run's columns with their units and the run's metadata.

        Raises
        ------
        DesignError
            ``form`` is neither ``"wide"`` nor ``"long"`` (raised by :mod:`hgo_mj.tidy`).

        Examples
        --------
        >>> from hgo_mj.inputs import Constant
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", 0.01)
        >>> table = simulate(plant, None, {}, Constant(0.0), duration=0.1).to_arrow()
        >>> table.schema.field("true/angular_velocity").metadata
        {b'unit': b'rad/s'}
        """
        from .tidy import to_arrow

        return to_arrow(self, form)

    def save(self, path: str | Path) -> Path:
        """Write the run to one ``.npz`` (numpy columns, no pickle) with its names and metadata
        as JSON, atomically; :meth:`load` reads it back.

        Parameters
        ----------
        path : str or Path
            The file to write (conventionally ``*.npz``); missing parent folders are created,
            an existing file is replaced only once the new one is complete.

        Returns
        -------
        Path
            ``path`` as a :class:`~pathlib.Path`.

        Examples
        --------
        >>> import tempfile
        >>> from hgo_mj.observers import make_observer
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", 0.01)
        >>> traj = simulate(plant, None, {"hgo": make_observer("high_gain", plant.system,
        ...                 k=20.0)}, lambda t: [0.0], duration=0.1, x0=[0.2, 0.0])
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     path = traj.save(f"{tmp}/runs/run.npz")
        ...     path.name, path.exists()
        ('run.npz', True)
        """
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
        with atomic_path(path) as tmp, open(tmp, "wb") as fh:  # a kill keeps the old file
            np.savez_compressed(fh, **cols)
        return path

    @classmethod
    def load(cls, path: str | Path) -> Trajectory:
        """Read a trajectory written by :meth:`save`.

        Parameters
        ----------
        path : str or Path
            A ``.npz`` file written by :meth:`save`.

        Returns
        -------
        Trajectory
            The run with its columns, names, observers and metadata as saved.

        Raises
        ------
        TrajectoryFileError
            The file is not one :meth:`save` writes (not an ``.npz``, a pickle, a column
            missing, not numeric or larger than the file or the memory, metadata that is not
            its JSON, names repeated, columns of different lengths), named with what is wrong;
            columns of different lengths also raise it as a ``DimensionError``.
        OSError
            The file cannot be opened.

        Examples
        --------
        >>> import tempfile
        >>> from hgo_mj.observers import make_observer
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", 0.01)
        >>> traj = simulate(plant, None, {"hgo": make_observer("high_gain", plant.system,
        ...                 k=20.0)}, lambda t: [0.0], duration=0.1, x0=[0.2, 0.0])
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     back = Trajectory.load(traj.save(f"{tmp}/run.npz"))
        >>> len(back), back.state_names, np.array_equal(back.x, traj.x)
        (11, ('angle', 'angular_velocity'), True)
        """
        from ._trajfile import read

        z, meta = read(path)  # checked: a TrajectoryFileError naming the file and the problem
        observers = {
            name: ObserverRecord(
                x_hat=z[f"obs/{name}/x_hat"], z_hat=z[f"obs/{name}/z_hat"],
                diagnostics={d: z[f"obs/{name}/diag/{d}"] for d in om["diagnostics"]},
                update_time=float("nan" if om.get("update_time") is None
                                  else om["update_time"]),
                state_names=om["state_names"])
            for name, om in meta["observers"].items()}
        try:
            return cls(t=z["t"], x=z["x"], y_clean=z["y_clean"], y_meas=z["y_meas"], u=z["u"],
                       observers=observers, state_names=meta["state_names"],
                       output_names=meta["output_names"], input_names=meta["input_names"],
                       metadata=meta.get("metadata", {}))
        except DimensionError as exc:
            raise _TrajectoryShapeError(f"{path}: {exc}") from None


class _TrajectoryShapeError(TrajectoryFileError, DimensionError):
    """A loaded file whose columns disagree: both errors (``except DimensionError`` written
    before files were checked still catches it)."""


def package_versions() -> dict[str, str]:
    """Versions of the packages a result depends on, for its metadata (looked up once per
    process: the lookup costs milliseconds; a fresh dict each call).

    Returns
    -------
    dict of str to str
        ``"python"`` and each of hgo_mj, mujoco, numpy, scipy, gymnasium and rerun-sdk mapped
        to its installed version (``"not installed"`` where it is missing).

    Examples
    --------
    >>> versions = package_versions()
    >>> sorted(versions)
    ['gymnasium', 'hgo_mj', 'mujoco', 'numpy', 'python', 'rerun-sdk', 'scipy']
    >>> versions["numpy"] == np.__version__
    True
    """
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
        items = [(f"{ob.name or type(ob).__name__}_{i}", ob) for i, ob in enumerate(observers)]
    for name, ob in items:
        if not isinstance(ob, Observer):
            raise DesignError(f"observer {name!r} must be an Observer; found {type(ob).__name__}")
    return dict(items)


def simulate(plant: Plant, sensor: SensorChain | None,
             observers: Mapping[str, Observer] | Sequence[Observer] | Observer | None,
             inputs: Callable[..., Any], duration: float, *, sample_period: float | None = None,
             control_period: float | None = None, x0: Any = None, seed: int | None = None,
             metadata: Mapping[str, Any] | None = None,
             on_chunk: tuple[float, Callable[[int, Trajectory], None]] | None = None,
             store_every: int = 1, isolate: bool = False, keep: bool = True) -> Trajectory:
    """Run plant, sensor chain and observers together and return the :class:`Trajectory`.

    Parameters
    ----------
    plant : Plant
        The true plant; ``plant.dt`` is its step (a multiple of its physics step).
    sensor : SensorChain or None
        Applied to the clean outputs at every sample (re-seeded with ``seed`` first: the run's
        seed wins over the chain's own, which is used only when ``seed`` is None);
        ``None`` measures exactly.
    observers : mapping name -> Observer, sequence, single Observer, or None
        Every observer is reset to its own initial estimate and fed the same ``y_meas``.
    inputs : Signal, callable ``u(t)`` or Controller
        An open-loop signal (evaluated at the control instants and held) or a
        :class:`~hgo_mj.inputs.Controller` (fed the named observer's estimate, or the true state).
    duration : float
        Simulated time; the run has ``round(duration / sample_period) + 1`` sample rows.
    sample_period, control_period : float, optional
        Defaults: ``plant.dt`` and ``sample_period``; each a multiple of the one before.
    x0 : array_like, optional
        Initial true state (default ``plant.system.default_x0``).
    seed : int, optional
        Seed of the sensor chain's streams: the same seed gives a bit-identical run, whatever
        seed the chain was built with; None: the chain's own seed
        (``SensorChain(..., seed=...)``; fresh entropy if that is None too).
    metadata : mapping, optional
        Extra JSON-ready entries for the trajectory's metadata (e.g. the scenario).
    on_chunk : (seconds, callback), optional
        Hand the stored rows over as they are simulated: ``callback(first_row, chunk)`` with a
        :class:`Trajectory` of the rows ``first_row ...`` each time ``seconds`` of simulated
        time have been stored (at least one row), and once more with the rows left at the end
        (a tail shorter than half a chunk joins the last chunk), also when the run stops on a
        :class:`DivergenceError`. A chunk's metadata holds only ``sample_period`` and
        ``first_row``; its ``update_time`` is NaN. The simulated values do not depend on it.
    store_every : int
        Keep every ``store_every``-th sample row (rows ``0, s, 2s, ...``); the run itself
        advances at every sample.
    isolate : bool
        An observer that fails (its update raises, or its estimate leaves the finite numbers)
        stops alone: its rows are NaN from the failing sample on, the plant and the other
        observers run to the end, and the metadata's ``"diverged"`` names it, the time, the
        sample and the error (:attr:`Trajectory.diverged`). Default False: the run stops and
        raises (below). ``hgo-mj run`` isolates.
    keep : bool
        Default True. False **streams** the run: the rows are handed to ``on_chunk`` (which
        must be given) and not kept, so memory stays flat with the duration (a buffer of
        about 1.5 chunks); the returned trajectory has no rows but its complete metadata.
        With ``isolate``, an estimate that leaves the finite numbers is NaN from there on in
        the chunks handed out; without it, the run raises at the end as it would keeping.
        ``hgo-mj run --stream`` writes the chunks to Parquet this way (:mod:`hgo_mj.stream`).

    Returns
    -------
    Trajectory
        Row ``k`` is the sample instant ``t_k``: the true state, clean and measured outputs,
        the input applied from ``t_k``, and each observer's estimate *before* it consumes
        ``y(t_k)``. The metadata's ``inverse_failures`` counts each observer's failed
        evaluations of its inverse normal-form map.

    Raises
    ------
    DivergenceError
        If an observer's ``z_hat`` leaves the finite numbers (or ``x_hat`` becomes infinite),
        or an observer's update raises ``ValueError`` or an ``ArithmeticError`` (the message
        names the observer, the time and the row; the original error is ``exc.__cause__``),
        or the plant fails (a non-finite or too large input, MuJoCo's bad-state reset). The
        partial trajectory is ``exc.trajectory``. A ``DimensionError`` in an update and every
        error raised before the loop (argument validation, ``check_period``) propagate.
    DesignError
        ``keep=False`` without ``on_chunk`` (or any other argument refused before the run).

    Examples
    --------
    >>> from hgo_mj.inputs import Multisine
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.sensors import GaussianNoise, SensorChain
    >>> plant = make_plant("pendulum", dt=0.001)
    >>> traj = simulate(plant, SensorChain([GaussianNoise(std=1e-3)]),
    ...                 {"k40": HighGainObserver(plant.system, k=40.0)},
    ...                 Multisine(amplitudes=[0.3], frequencies=[0.5]), duration=1.0,
    ...                 x0=[0.5, 0.0], seed=1)
    >>> traj.t.shape, traj.x.shape, traj.observers["k40"].x_hat.shape
    ((1001,), (1001, 2), (1001, 2))
    >>> float(traj.t[1]), traj.metadata["seed"]
    (0.001, 1)

    Streamed (``keep=False``): the chunks hold the rows, the trajectory returned none.

    >>> chunks = []
    >>> streamed = simulate(plant, SensorChain([GaussianNoise(std=1e-3)]),
    ...                     {"k40": HighGainObserver(plant.system, k=40.0)},
    ...                     Multisine(amplitudes=[0.3], frequencies=[0.5]), duration=1.0,
    ...                     x0=[0.5, 0.0], seed=1, keep=False,
    ...                     on_chunk=(0.25, lambda row, chunk: chunks.append(chunk)))
    >>> len(streamed), [len(c) for c in chunks]
    (0, [250, 250, 250, 251])
    >>> import numpy as np
    >>> np.array_equal(np.concatenate([c.observers["k40"].x_hat for c in chunks]),
    ...                traj.observers["k40"].x_hat)
    True
    """
    if x0 is not None and np.ndim(x0) != 1:
        raise DimensionError(f"simulate runs one member: x0 must be a state (n,); found shape "
                             f"{np.shape(x0)} (for B initial states use simulate_batch)")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))):
        raise DesignError(f"seed must be an integer or None; found {seed!r} (for B seeds use "
                          f"simulate_batch)")
    return _run(plant, sensor, observers, inputs, duration, sample_period=sample_period,
                control_period=control_period, x0=x0, seeds=seed, batch=None,
                metadata=metadata, on_chunk=on_chunk, store_every=store_every,
                isolate=isolate, keep=keep)[0]


def simulate_batch(plant: Plant, sensor: SensorChain | None,
                   observers: Mapping[str, Observer] | Sequence[Observer] | Observer | None,
                   inputs: Callable[..., Any], duration: float, *, seeds: Sequence[int | None],
                   x0: Any = None, sample_period: float | None = None,
                   control_period: float | None = None,
                   metadata: Mapping[str, Any] | None = None,
                   store_every: int = 1, isolate: bool = False) -> list[Trajectory]:
    """:func:`simulate` of B members at once, one per seed in ``seeds`` (and, if ``x0`` is
    ``(B, n)``, per initial state): the plants, the sensor streams and every observer advance
    as one batch. Member ``i`` equals ``simulate(..., x0=x0[i], seed=seeds[i])`` alone, bit
    for bit.

    Parameters
    ----------
    plant, sensor, observers, inputs, duration
        As in :func:`simulate`.
    seeds : sequence of int or None
        One sensor seed per member; its length is the batch size B.
    x0 : array_like, optional
        One initial state ``(n,)`` for every member, or one per member ``(B, n)``.
    sample_period, control_period, metadata, store_every, isolate
        As in :func:`simulate` (an isolated failure stops that observer for every member).

    Returns
    -------
    list of Trajectory
        One per member, in the order of ``seeds``.

    Raises
    ------
    DesignError
        ``seeds`` is not a non-empty sequence (or any argument :func:`simulate` refuses).
    DivergenceError
        A failure (divergence) of any member stops the batch.

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.inputs import Multisine
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.sensors import GaussianNoise, SensorChain
    >>> plant = make_plant("pendulum", dt=0.001)
    >>> parts = (plant, SensorChain([GaussianNoise(std=1e-3)]),
    ...          {"k40": HighGainObserver(plant.system, k=40.0)},
    ...          Multisine(amplitudes=[0.3], frequencies=[0.5]), 0.5)
    >>> runs = simulate_batch(*parts, seeds=[3, 4], x0=[[0.5, 0.0], [-0.5, 0.0]])
    >>> alone = simulate(*parts, x0=[-0.5, 0.0], seed=4)
    >>> len(runs), np.array_equal(runs[1].observers["k40"].x_hat, alone.observers["k40"].x_hat)
    (2, True)
    """
    if isinstance(seeds, (str, bytes)) or not isinstance(seeds, Sequence) or not seeds:
        raise DesignError(f"seeds must be a non-empty sequence of seeds; found {seeds!r}")
    return _run(plant, sensor, observers, inputs, duration, sample_period=sample_period,
                control_period=control_period, x0=x0, seeds=list(seeds), batch=len(seeds),
                metadata=metadata, on_chunk=None, store_every=store_every, isolate=isolate)


#: samples per segment of an open-loop run (a feedback law runs one control period at a time)
SEGMENT = 1024


def _run(plant: Plant, sensor: SensorChain | None, observers: Any, inputs: Any,
         duration: float, *, sample_period: Any, control_period: Any, x0: Any, seeds: Any,
         batch: int | None, metadata: Mapping[str, Any] | None, on_chunk: Any,
         store_every: Any, isolate: bool = False, keep: bool = True) -> list[Trajectory]:
    periods = Periods.of(plant, sample_period, control_period)
    duration = finite_scalar("duration", duration, positive=True)
    if duration < periods.sample:
        raise DesignError(f"duration = {duration:g} s must be at least one sample_period = "
                          f"{periods.sample:g} s; a shorter run has a single row")
    every = positive_int("store_every", store_every, floats=False)
    N = int(round(duration / periods.sample))
    obs = _named_observers(observers)
    drive = Drive.of(inputs, obs, plant, periods)
    loop = Loop(plant, sensor, obs, periods, isolate=isolate)
    store = Store(loop, N, every, on_chunk, keep=keep, isolate=isolate)
    loop.reset(x0, seed=seeds, batch=batch)
    store.start()
    failure: LoopFailure | None = None
    try:
        while loop.k < N:
            T = drive.length(loop.k, N, SEGMENT)
            store.add(loop.segment(drive.inputs(loop, T)))
        store.add_last(*loop.sample(), drive.inputs(loop, 1))
    except LoopFailure as exc:
        store.add(exc.segment, last=True)
        failure = exc
    meta = {"plant": type(plant.system).__name__, "system_params": plant.system.params,
            "plant_dt": plant.dt, "physics_dt": getattr(plant, "physics_dt", plant.dt),
            "sample_period": periods.sample, "control_period": periods.control,
            "duration": duration, "store_every": every,
            "sensor": sensor.describe() if sensor is not None else None,
            "observers": {name: {"type": type(ob).__name__, **ob.params()}
                          for name, ob in obs.items()},
            "input": drive.describe(), "versions": package_versions(),
            **({"diverged": {**{name: {"t": t, "row": -(-(row + 1) // every), "sample": row,
                                       "error": f"{type(cause).__name__}: {cause}"}
                                for name, (row, t, cause) in loop.failed.items()},
                             **store.nonfinite}}
               if loop.failed or store.nonfinite else {}),
            **({"mjcf": mjcf} if (mjcf := getattr(type(plant.system), "mjcf", None)) else {}),
            **(dict(metadata) if metadata else {})}
    trajs = store.trajectories(meta, seeds, x0)
    for traj in trajs:
        if isolate and keep and (found := _isolate_nonfinite(traj, skip=loop.failed)):
            traj.metadata["diverged"] = {**traj.metadata.get("diverged", {}), **found}
        if not keep and not isolate and store.nonfinite:  # found in a chunk handed out
            name, d = next(iter(store.nonfinite.items()))
            err = DivergenceError(f"observer {name!r} estimate left the finite numbers at "
                                  f"t={d['t']:g} (row {d['row']})")
            err.trajectory = traj  # type: ignore[attr-defined]
            raise err
        _raise_on_divergence(traj, failure, skip={**loop.failed, **traj.diverged})
    return trajs


def _raise_on_divergence(traj: Trajectory, failure: LoopFailure | None,
                         skip: Mapping[str, Any] = {}) -> None:  # noqa: B006 - read only
    """Raise the run's failure, or the first non-finite ``z_hat`` (an infinite ``x_hat``), as
    a :class:`DivergenceError` carrying the trajectory; observers in ``skip`` (stopped alone
    by ``isolate``) are not scanned."""
    if failure is not None:
        cause = failure.cause
        if failure.observer is None:
            exc = DivergenceError(f"simulation stopped at t={failure.t:g}: {cause}")
        else:
            exc = DivergenceError(f"observer {failure.observer!r} failed in its update at "
                                  f"t={failure.t:g} (row {failure.row}): "
                                  f"{type(cause).__name__}: {cause}")
        exc.trajectory = traj  # type: ignore[attr-defined]
        raise exc from cause
    for name, r in traj.observers.items():
        if name in skip:
            continue
        # the observer's own coordinates decide; a NaN x_hat (inverse undefined) is allowed
        bad = ~np.all(np.isfinite(r.z_hat), axis=1) | np.any(np.isinf(r.x_hat), axis=1)
        if bad.any():
            k = int(np.argmax(bad))
            exc = DivergenceError(f"observer {name!r} estimate left the finite numbers at "
                                  f"t={traj.t[k]:g} (row {k}): z_hat = {r.z_hat[k].tolist()}, "
                                  f"x_hat = {r.x_hat[k].tolist()}")
            exc.trajectory = traj  # type: ignore[attr-defined]
            raise exc


def _isolate_nonfinite(traj: Trajectory, skip: Mapping[str, Any], first_row: int = 0,
                       stopped: Sequence[str] = (), nan: bool = True) -> dict[str, Any]:
    """With ``isolate``: an observer whose estimate left the finite numbers without its update
    failing stops alone at that row (NaN from there on, as one whose update failed), and the
    ``"diverged"`` records of those found are returned. ``traj`` may be a chunk whose first
    row is the run's ``first_row``; observers in ``stopped`` (found in an earlier chunk) are
    NaN throughout it. ``nan=False`` only finds them."""
    found = {}
    for name, r in traj.observers.items():
        if name in skip:
            continue
        bad = ~np.all(np.isfinite(r.z_hat), axis=1) | np.any(np.isinf(r.x_hat), axis=1)
        if name not in stopped and not bad.any():
            continue
        k = 0 if name in stopped else int(np.argmax(bad))
        if nan:
            r.x_hat[k:] = np.nan
            r.z_hat[k:] = np.nan
            for v in r.diagnostics.values():
                v[k:] = np.nan
        if name not in stopped:
            found[name] = {"t": float(traj.t[k]), "row": first_row + k, "sample": None,
                           "error": "DivergenceError: the estimate left the finite numbers"}
    return found


class Store:
    """The stored rows of a run (every ``every``-th sample), filled segment by segment, handed
    out in chunks (``on_chunk``) and returned as one :class:`Trajectory` per member; with
    ``keep=False`` only the rows not yet handed out are held (a buffer of about 1.5 chunks and
    a segment: a streamed run's memory does not grow with its duration)."""

    def __init__(self, loop: Loop, N: int, every: int, on_chunk: Any, keep: bool = True,
                 isolate: bool = False) -> None:
        if not isinstance(keep, bool):
            raise DesignError(f"keep must be a bool; found {keep!r}")
        if not keep and on_chunk is None:
            raise DesignError("keep=False streams the rows to on_chunk, which is missing: give "
                              "on_chunk=(seconds, callback)")
        self.loop, self.N, self.every, self.keep, self.isolate = loop, N, every, keep, isolate
        self.rows = N // every + 1
        self.base = 0  # the run's row held in row 0 of the columns
        #: observers whose estimate left the finite numbers in a chunk handed out (streaming)
        self.nonfinite: dict[str, Any] = {}
        self.chunk_rows, self.chunk_cb = -1, None
        if on_chunk is not None:
            if not (isinstance(on_chunk, tuple) and len(on_chunk) == 2 and callable(on_chunk[1])):
                raise DesignError(f"on_chunk must be a tuple (seconds, callback); found "
                                  f"{on_chunk!r}")
            chunk_s = finite_scalar("on_chunk seconds", on_chunk[0], positive=True)
            self.chunk_rows = max(int(round(chunk_s / (loop.periods.sample * every))), 1)
            self.chunk_cb = on_chunk[1]

    def start(self) -> None:
        """Allocate the columns (after the loop's reset: the batch and widths are known)."""
        lp, B, R = self.loop, self.loop.batch, self.rows
        if not self.keep:  # unsent rows: < 1.5 chunks held back, plus one segment
            R = min(R, self.chunk_rows + self.chunk_rows // 2 + SEGMENT // self.every + 2)
        n, p, m = (len(lp.plant.state_names), len(lp.plant.output_names),
                   len(lp.plant.input_names))
        width = n + 2 * p + m + sum(x.shape[1] + z.shape[1] + d.shape[1]
                                    for x, z, d in lp.estimates().values())
        check_memory(8 * B * R * width, R)
        self.cols = {"x": np.empty((B, R, n)), "y_clean": np.empty((B, R, p)),
                     "y_meas": np.empty((B, R, p)), "u": np.empty((B, R, m))}
        self.est = {}
        for name, (x, z, d) in lp.estimates().items():
            self.est[name] = (np.empty((B, R, x.shape[1])), np.empty((B, R, z.shape[1])),
                              np.empty((B, R, d.shape[1])))
        self.done = 0  # rows stored
        self.sent = 0  # rows handed to on_chunk

    def _put(self, k0: int, cols: dict[str, Array], est: dict[str, tuple[Array, ...]]) -> None:
        """Store the sample rows ``k0 ...`` that fall on ``every``."""
        T = next(iter(cols.values())).shape[1]
        first = -k0 % self.every
        sel = slice(first, T, self.every)
        count = len(range(first, T, self.every))
        if count == 0:
            return
        dst = slice(self.done - self.base, self.done - self.base + count)
        for key, v in cols.items():
            self.cols[key][:, dst] = v[:, sel]
        for name, parts in est.items():
            for out, v in zip(self.est[name], parts):
                out[:, dst] = v[:, sel]
        self.done += count
        self._emit(final=False)

    def add(self, seg: Segment, last: bool = False) -> None:
        """Store a segment's rows; each observer's estimate before sample ``j`` is its row
        ``j - 1`` (the one before the segment for ``j = 0``)."""
        if len(seg) == 0:
            self._emit(final=True)
            return
        est = {}
        for name in self.est:
            b = seg.blocks.get(name)
            before = seg.before[name]
            rows = len(seg) if b is None else b.x_hat.shape[1]
            parts = []
            for i, now in enumerate(before):
                after = None if b is None else (b.x_hat, b.z_hat, b.diagnostics)[i]
                col = np.empty((now.shape[0], len(seg), now.shape[1]))
                col[:, 0] = now
                if after is not None and rows:
                    col[:, 1:rows + 1] = after[:, :len(seg) - 1]
                parts.append(col)
            est[name] = tuple(parts)
        self._put(int(round(seg.t[0] / self.loop.periods.sample)),
                  {"x": seg.x, "y_clean": seg.y_clean, "y_meas": seg.y_meas, "u": seg.u}, est)
        if last:
            self._emit(final=True)

    def add_last(self, X: Array, Yc: Array, Ym: Array, U: Array) -> None:
        """The last row (sample ``N``: measured, not consumed)."""
        est = {name: tuple(v[:, None] for v in now) for name, now in self.loop.estimates().items()}
        self._put(self.N, {"x": X, "y_clean": Yc, "y_meas": Ym, "u": U}, est)
        self._emit(final=True)

    def _emit(self, final: bool) -> None:
        if self.chunk_cb is None:
            return
        c = self.chunk_rows
        while self.sent + c <= self.done and self.rows - (self.sent + c) >= c // 2 \
                and self.sent + c < self.rows:
            self._send(self.sent, self.sent + c)
        if final and self.done > self.sent:
            self._send(self.sent, self.done)

    def _send(self, a: int, b: int) -> None:
        chunk = self._trajectory(0, a, b, {"sample_period": self.loop.periods.sample *
                                           self.every, "first_row": a}, None)
        self.sent = b
        if not self.keep:  # the rows handed out leave the buffer; in-place views are gone
            self.nonfinite.update(_isolate_nonfinite(
                chunk, skip=self.loop.failed, first_row=a, stopped=list(self.nonfinite),
                nan=self.isolate))
            held = slice(b - self.base, self.done - self.base)
            for v in (*self.cols.values(), *(c for parts in self.est.values() for c in parts)):
                v[:, :held.stop - held.start] = v[:, held]
            self.base = b
        self.chunk_cb(a, chunk)  # type: ignore[misc]

    def _trajectory(self, member: int, a: int, b: int, meta: dict[str, Any],
                    update_time: dict[str, float] | None) -> Trajectory:
        lp = self.loop
        records = {}
        a0, b0 = a - self.base, b - self.base
        for name, ob in lp.observers.items():
            xh, zh, dg = (v[member, a0:b0] for v in self.est[name])
            records[name] = ObserverRecord(
                x_hat=xh.copy(), z_hat=zh.copy(),
                diagnostics={d: dg[:, j].copy() for j, d in enumerate(ob.diagnostic_names)},
                update_time=float("nan") if update_time is None else update_time[name],
                state_names=tuple(str(s) for s in ob.state_names))
        t = np.asarray(np.arange(a, b) * (lp.periods.sample * self.every), dtype=np.float64)
        return Trajectory(t=t, **{k: v[member, a0:b0].copy() for k, v in self.cols.items()},
                          observers=records, state_names=tuple(lp.plant.state_names),
                          output_names=tuple(lp.plant.output_names),
                          input_names=tuple(lp.plant.input_names), metadata=meta)

    def trajectories(self, meta: dict[str, Any], seeds: Any, x0: Any) -> list[Trajectory]:
        """One :class:`Trajectory` per member of the rows stored."""
        lp = self.loop
        steps = max(self.done * self.every - self.every, 1)
        update_time = {name: lp.wall[name] / (steps * lp.batch) for name in lp.observers}
        out = []
        n = len(lp.plant.state_names)
        x0s = np.broadcast_to(np.reshape(plant_x0_rows(lp.plant, x0), (-1, n)), (lp.batch, n))
        for b in range(lp.batch):
            seed = seeds[b] if isinstance(seeds, list) else seeds
            inv = {name: int(lp.states[name].inverse_failures[b]) for name in lp.observers}
            m = {**meta, "seed": seed, "x0": x0s[b].tolist(), "inverse_failures": inv}
            out.append(self._trajectory(b, self.base, self.done, m, update_time))
        return out


def available_memory() -> float:
    """Bytes of physical memory available now (``inf`` where the system does not say)."""
    import os

    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_AVPHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return float("inf")


def check_memory(nbytes: float, rows: int) -> None:
    """Raise :class:`DesignError` before a run whose stored rows (``nbytes``) would not fit in
    the memory available, naming the estimate and ``store_every`` (keep every k-th row)."""
    avail = available_memory()
    if nbytes > avail:
        raise DesignError(f"the run would store {rows} rows, about {nbytes / 2**30:.3g} GiB; "
                          f"found {avail / 2**30:.3g} GiB of memory available: shorten the "
                          f"duration or keep every k-th row (store_every=k; hgo-mj run "
                          f"--store-every k, run.store_every)")


def plant_x0_rows(plant: Plant, x0: Any) -> Array:
    """The initial true state(s) of a run, as given or the system's default."""
    if x0 is not None:
        return np.asarray(x0, dtype=float)
    return np.asarray(plant.system.default_x0, dtype=float)


def plant_x0(plant: Plant, x0: Any) -> list[float]:
    if x0 is not None:
        return vector("x0", x0).tolist()
    return [float(v) for v in plant.system.default_x0]


__all__ = ["ObserverRecord", "Trajectory", "simulate", "simulate_batch", "package_versions"]
