"""The :class:`Recorder`: trajectories and environment episodes to a rerun file, headless.

A recorder checks each block of rows and keeps what a recording needs across blocks (the
layout fixed at the first block, the styles not yet sent, the diagnostics' last values, the
queued poses); what a block becomes is computed by pure functions
(:mod:`hgo_mj.record.rows`: the entities and values of a block, the rows kept of a
piecewise-constant diagnostic, the rows posed in 3D; :mod:`hgo_mj.record.layout`: entity
paths, styles, blueprint; :mod:`hgo_mj.record.documents`; :mod:`hgo_mj.record.poses`), and
sent by a thin row sink (:class:`hgo_mj.record.sink.RowSink`), the one place that talks to
rerun. No viewer is spawned and no display is needed; a reviewer opens the file later with
``rerun file.rrd``. It uses rerun's public API only: each entity's block of rows is one
``rr.send_columns`` call (``rr.TimeColumn`` indexes and the archetypes' ``.columns(...)``; a
per-step ``rr.log`` would cost 36 to 120 microseconds a step), static styles and geometry one
``rr.log(..., static=True)`` each, the blueprint one ``send_blueprint``. Every call makes new
chunks, so two recordings written in one process share no chunk id.

Timelines: ``sim_time`` (simulated time, a duration), ``step`` (the sample index) and, for
environments, ``episode``. ``step`` is carried by the states (``/state/<s>``: the truth and
the estimates), the diagnostics and the 3D poses; the other per-sample series (errors,
outputs, inputs, extras) carry ``sim_time`` (and ``episode``) only: their step is the
states' at the same ``sim_time``, and :func:`hgo_mj.record.read` indexes them so (one index
column less per row and entity); the viewer's time panel shows ``sim_time`` (the blueprint's
timeline), where every series is drawn, while the ``step`` timeline draws the states,
diagnostics and poses only. Where each signal goes and how it is styled:
:mod:`hgo_mj.record.layout`; the documents: :mod:`hgo_mj.record.documents`; the 3D view:
:mod:`hgo_mj.record.poses`.

Diagnostics are logged where they change (and at the end of the run or episode), drawn as
steps. Poses are logged at ``pose_rate`` (default 50 Hz, the frame rate a viewer plays back in
real time) to keep files small and cheap; every sample with ``pose_rate=None``.

A block is written whole: a SIGINT (Ctrl-C) during a block is held until the block is sent,
so a run interrupted part-way leaves a readable file holding every block before the signal.

A file that cannot be written is an error, not a log line: a sink that fails when it opens
(an unwritable path, a full disk) raises :class:`~hgo_mj.exceptions.RecordingError` at once,
and :meth:`Recorder.close` raises it when the file sink cannot write everything within
:data:`CLOSE_TIMEOUT_S` or the closed file is not a finalized recording (no footer: the file
``rerun rrd verify`` would reject). rerun itself only logs a failed write, and a flush that
waits on a failed file sink never returns (rerun-sdk 0.41): after such a failure the stream is
left open for the rest of the process (its shutdown would wait for ever).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any, TypeVar

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from ..exceptions import DesignError, DimensionError, RecordingError
from . import documents, layout
from . import rows as row_fns
from .layout import EstimateLayout
from .poses import Poses, model_for, xyzw
from .rows import Array, Block, Mask
from .sink import DeferSigint as _DeferSigint
from .sink import RowSink, time_columns

_T = TypeVar("_T")

#: pose rows queued before they are posed and sent (a 2 s block at 50 Hz has 101; a 10 s
#: run's poses are sent at close, in one call per body and set)
_POSE_ROWS = 1000
#: seconds :meth:`Recorder.close` waits for the file sink to write what is queued (a healthy
#: sink writes a block within milliseconds; one that failed never finishes)
CLOSE_TIMEOUT_S = 20.0


class Recorder:
    """Write trajectories or environment episodes to a rerun recording (``.rrd``), headless.

    Parameters
    ----------
    path : str or Path or None
        The ``.rrd`` file to write (its folder is created). ``None`` only with ``stream``,
        whose sinks the caller has set.
    state_names, output_names, input_names : sequence of str
        Names of the columns of ``x``, ``y`` and ``u``.
    observers : sequence of str
        Names of the observers, in order (their colours follow it).
    observer_states : mapping observer -> sequence of str, optional
        Names of each observer's estimate columns (``Observer.state_names``); default: fixed
        at the first block (``estimate_names`` of :meth:`record`, else the plant's state
        names when the widths agree). A ghost is drawn for an observer that estimates at least
        one joint position; a joint it does not estimate is posed on the truth.
    model : mujoco.MjModel, optional
        The plant's model: draws the 3D view. ``None`` (ODE plants): no 3D view.
    joints : sequence of str
        The joints whose positions are the first ``len(joints)`` columns of ``x`` and
        ``x_hat`` (``System.joints``); required with ``model``.
    params : mapping, optional
        True parameter values of the system, drawn next to parameter estimates.
    stream : rerun.RecordingStream, optional
        The stream to write through; default a new one with ``application_id`` that is never
        made the global or thread default.
    application_id : str
        Application id of a new stream (the viewer keys blueprints on it).
    recording_name : str, optional
        Name of the recording shown in the viewer.
    pose_rate : float or None
        Samples per unit of simulated time of the 3D poses (``None``: every sample). Pose
        rows are queued and sent 1,000 at a time (and by :meth:`flush` and :meth:`close`).
    units : mapping, optional
        ``{name: unit}`` of the states, outputs, inputs and output derivatives
        (:func:`hgo_mj.units.system_units`): each series and view is named with its unit.
    dropouts : bool or None
        Whether the sensor chain has a dropout stage: ``False`` leaves the observers'
        ``dropouts`` diagnostic out (a count that is zero by construction); ``None`` (not
        known) records it.
    footer : bool
        End the file with rerun's footer (a manifest of its chunks, for random access and
        ``rerun.chunk.RrdReader(...).store()``). ``False`` leaves a file that reads as a
        stream (the viewer, ``RrdReader(...).stream()``) but that ``rerun rrd verify``
        rejects ("Missing RRD footer"); ``rerun rrd optimize`` adds the footer later.

    Raises
    ------
    DesignError
        Repeated observer names, an observer named ``true``, ``observer_states`` naming an
        unknown observer, ``pose_rate`` not positive, ``model`` without ``joints``, neither
        ``path`` nor ``stream``, a ``stream`` that is not a :class:`rerun.RecordingStream`, or
        a ``path`` not ending in ``.rrd``.
    DimensionError
        ``state_names`` too short to hold the positions and velocities of ``joints``.
    RecordingError
        The file cannot be opened for writing.

    Examples
    --------
    A block of rows from numpy arrays (an environment or a custom loop), read back:

    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from hgo_mj.record import read
    >>> t = np.linspace(0.0, 0.1, 11)
    >>> x = np.c_[np.cos(t), -np.sin(t)]
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     with Recorder(Path(tmp) / "run.rrd", state_names=["angle", "angular_velocity"],
    ...                   output_names=["angle"], input_names=["torque"], observers=["hgo"],
    ...                   units={"angle": "rad", "angular_velocity": "rad/s"}) as rec:
    ...         rec.record(t, x, x[:, :1], x[:, :1], np.zeros((11, 1)), {"hgo": x + 0.01},
    ...                    {"hgo": {"gain": np.full(11, 40.0)}})
    ...     df = read(Path(tmp) / "run.rrd")
    >>> df.shape
    (11, 11)
    >>> round(float(df["/error/angle[angle error hgo]"].iloc[-1]), 3)
    -0.01
    >>> df.attrs["units"]["/state/angular_velocity[angular_velocity hgo]"]
    'rad/s'
    """

    def __init__(self, path: str | Path | None, *, state_names: Sequence[str],
                 output_names: Sequence[str], input_names: Sequence[str],
                 observers: Sequence[str] = (),
                 observer_states: Mapping[str, Sequence[str]] | None = None,
                 model: Any = None, joints: Sequence[str] = (),
                 params: Mapping[str, float] | None = None,
                 stream: rr.RecordingStream | None = None, application_id: str = "hgo_mj",
                 recording_name: str | None = None, pose_rate: float | None = 50.0,
                 units: Mapping[str, str] | None = None, dropouts: bool | None = None,
                 footer: bool = True) -> None:
        self.state_names = tuple(str(s) for s in state_names)
        self.output_names = tuple(str(s) for s in output_names)
        self.input_names = tuple(str(s) for s in input_names)
        self.observers = tuple(str(o) for o in observers)
        if len(set(self.observers)) != len(self.observers):
            raise DesignError(f"observer names must be distinct; found {list(self.observers)}")
        if layout.TRUE in self.observers:
            raise DesignError(f"an observer cannot be named {layout.TRUE!r} in a recording "
                              f"(the series '<state> true' is the true state); found "
                              f"{list(self.observers)}")
        self.units = {str(k): str(v) for k, v in (units or {}).items()}
        self.dropouts = dropouts
        self._names = {str(o): layout.check_names(str(o), names)
                       for o, names in (observer_states or {}).items()}
        unknown = [o for o in self._names if o not in self.observers]
        if unknown:
            raise DesignError(f"observer_states names an unknown observer {unknown[0]!r}; "
                              f"observers: {list(self.observers)}")
        self.params = {str(k): float(v) for k, v in (params or {}).items()
                       if isinstance(v, (int, float))}
        if pose_rate is not None and not (np.isfinite(pose_rate) and pose_rate > 0):
            raise DesignError(f"pose_rate must be a positive number or None; found {pose_rate!r}")
        self.pose_rate = pose_rate
        self.scene = self._scene(model, joints)
        self.path = None if path is None else Path(path)
        self._sink = RowSink(self.path, stream, application_id, footer, recording_name)
        self.stream = self._sink.stream
        self.layout: EstimateLayout | None = None  # fixed at the first block
        self._diag: dict[tuple[str, str], tuple[str, str]] = {}  # (obs, key) -> (path, kind)
        self._diag_last: dict[str, float] = {}
        self._diag_pending: dict[str, float] = {}
        self._extra: dict[str, str] = {}
        self._ghosts: set[str] = set()
        self._static: list[tuple[str, list[Any]]] = []
        self._sent_layout: tuple[Any, ...] | None = None
        self._last_row: tuple[float, int, int | None] | None = None
        self._t_next = 0.0
        self._step_next = 0
        self._closed = False
        self._poses: list[tuple[Array, row_fns.Steps, int | None, dict[str, Array]]] = []
        self._pose_rows = 0

    def _scene(self, model: Any, joints: Sequence[str]) -> Poses | None:
        if model is None:
            return None
        if not joints:
            raise DesignError("a model needs the joints whose positions lead x; found none")
        if 2 * len(joints) > len(self.state_names):
            raise DimensionError(f"x must hold the positions and velocities of the joints "
                                 f"{list(joints)}; found {len(self.state_names)} states")
        return Poses(model, joints)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def for_plant(cls, path: str | Path | None, plant: Any, observers: Sequence[str] = (),
                  **kw: Any) -> Recorder:
        """A recorder for runs of ``plant`` (a :class:`~hgo_mj.plants.base.Plant`); MuJoCo
        plants get the 3D view from their model and ``system.joints``.

        Parameters
        ----------
        path : str or Path or None
            The ``.rrd`` file to write (``None`` only with ``stream=`` in ``kw``).
        plant : Plant
            Gives the state, output and input names, the model (MuJoCo plants), the joints,
            the system's parameters and units.
        observers : sequence of str
            Names of the observers whose estimates will be recorded, in order.
        **kw
            Further :class:`Recorder` arguments; ``params``, ``units`` and ``joints`` override
            the plant's.

        Returns
        -------
        Recorder
            A new recorder with its file open.

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> from hgo_mj.plants import make_plant
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     with Recorder.for_plant(Path(tmp) / "run.rrd", make_plant("pendulum"),
        ...                             ["k40"]) as rec:
        ...         names = rec.state_names, rec.observers, rec.scene is not None
        >>> names
        (('angle', 'angular_velocity'), ('k40',), True)
        """
        from ..units import system_units

        model = getattr(plant, "model", None)
        kw.setdefault("params", getattr(plant.system, "params", None))
        kw.setdefault("units", system_units(type(plant.system), tuple(plant.output_names)))
        kw.setdefault("joints", plant.system.joints if model is not None else ())
        return cls(path, state_names=plant.state_names, output_names=plant.output_names,
                   input_names=plant.input_names, observers=observers, model=model, **kw)

    @classmethod
    def for_trajectory(cls, path: str | Path | None, traj: Any, *, model: Any = None,
                       joints: Sequence[str] | None = None, **kw: Any) -> Recorder:
        """A recorder for ``traj``. Without ``model``, the MJCF of the system named in
        ``traj.metadata["plant"]`` is loaded (the scenario's ``model_file`` if it names one);
        ODE systems get no 3D view. The units are the system's (:func:`hgo_mj.units.units_of`);
        the observers' ``dropouts`` are left out when ``traj.metadata["sensor"]`` (the chain's
        stages) has no dropout stage.

        Parameters
        ----------
        path : str or Path or None
            The ``.rrd`` file to write (``None`` only with ``stream=`` in ``kw``).
        traj : Trajectory
            A run of :func:`hgo_mj.simulate.simulate`: its names, observers (with their
            ``state_names``) and metadata set up the recorder; no rows are written.
        model : mujoco.MjModel, optional
            The model drawn in the 3D view; default the MJCF of the trajectory's plant.
        joints : sequence of str, optional
            The joints of ``model`` leading ``x``; default the system's ``joints`` (with the
            default model).
        **kw
            Further :class:`Recorder` arguments; they override ``units``, ``dropouts``,
            ``params``, ``recording_name`` and ``observer_states`` taken from ``traj``.

        Returns
        -------
        Recorder
            A new recorder with its file open; write the rows with
            :meth:`record_trajectory` or :meth:`write_chunk`.

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> from hgo_mj.inputs import Multisine
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> from hgo_mj.sensors import GaussianNoise, SensorChain
        >>> from hgo_mj.simulate import simulate
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> traj = simulate(plant, SensorChain([GaussianNoise(std=1e-3)], seed=0),
        ...                 {"k40": HighGainObserver(plant.system, k=40.0)},
        ...                 Multisine(amplitudes=[0.3], frequencies=[0.5]), duration=0.1,
        ...                 x0=[0.5, 0.0], seed=0)
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     with Recorder.for_trajectory(Path(tmp) / "run.rrd", traj) as rec:
        ...         rec.record_trajectory(traj)
        ...     size = (Path(tmp) / "run.rrd").stat().st_size
        >>> rec.observers, rec.units["angle"], size > 0
        (('k40',), 'rad', True)
        """
        from ..units import units_of

        meta = traj.metadata or {}
        kw.setdefault("units", units_of(traj)[0])
        if "sensor" in meta:
            kw.setdefault("dropouts", layout.has_dropout_stage(meta["sensor"]))
        if model is None:
            model, sys_joints = model_for(meta)
            joints = sys_joints if joints is None else joints
        kw.setdefault("params", meta.get("system_params"))
        kw.setdefault("recording_name", meta.get("scenario"))
        kw.setdefault("observer_states", {o: tuple(r.state_names) for o, r in
                                          traj.observers.items() if r.state_names})
        return cls(path, state_names=traj.state_names, output_names=traj.output_names,
                   input_names=traj.input_names, observers=list(traj.observers), model=model,
                   joints=joints or (), **kw)

    # ------------------------------------------------------------------ documents
    def log_metadata(self, metadata: Mapping[str, Any]) -> None:
        """Log a run's metadata (scenario, seed, observer parameters, versions, ...) as the
        text document ``/scenario`` (:func:`~hgo_mj.record.documents.scenario_document`) and
        as recording properties.

        Parameters
        ----------
        metadata : mapping
            A run's metadata (``Trajectory.metadata``); its ``scenario``, ``plant``, ``seed``,
            ``observers`` and ``versions`` also become the ``hgo_mj`` recording properties.

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> from hgo_mj.record import read
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     with Recorder(Path(tmp) / "run.rrd", state_names=["angle", "angular_velocity"],
        ...                   output_names=["angle"], input_names=["torque"]) as rec:
        ...         rec.log_metadata({"scenario": "demo", "plant": "Pendulum", "seed": 3})
        ...     doc = read(Path(tmp) / "run.rrd").attrs["static"]["/scenario"]
        >>> doc["TextDocument:text"][0].splitlines()[:3]
        ['# demo', '', '- **plant**: `"Pendulum"`']
        """
        props: dict[str, Any] = dict(documents.scenario_properties(metadata))
        if props:
            self._sink.properties("hgo_mj", props)
        self._sink.document("/scenario", documents.scenario_document(metadata))

    def log_metrics(self, metrics: Mapping[str, Mapping[str, Any]]) -> None:
        """Log the metrics table (:func:`hgo_mj.metrics.format_table`) as ``/metrics``.

        Parameters
        ----------
        metrics : mapping observer -> mapping metric -> value
            As :func:`hgo_mj.metrics.all_metrics` returns them.

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> from hgo_mj.record import read
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     with Recorder(Path(tmp) / "run.rrd", state_names=["angle", "angular_velocity"],
        ...                   output_names=["angle"], input_names=["torque"]) as rec:
        ...         rec.log_metrics({"k40": {"states": ["angle"], "estimated": [True],
        ...                                  "rmse": [0.1], "peak": [0.5],
        ...                                  "settling_time": [1.0], "final": [0.01],
        ...                                  "update_time": 2e-6}})
        ...     doc = read(Path(tmp) / "run.rrd").attrs["static"]["/metrics"]
        >>> print(doc["TextDocument:text"][0].splitlines()[6])
        k40      angle ?      0.1   0.5   0.01           1            2
        """
        self._sink.document("/metrics", documents.metrics_document(metrics, self.units))

    def log_episode_metrics(self, episodes: Sequence[Mapping[str, Any]]) -> None:
        """Log the metrics of an environment's episodes as ``/metrics``
        (:func:`~hgo_mj.record.documents.episode_metrics_document`). Called at the end of
        every episode with all the episodes so far (the document is static: the last one
        logged is the file's).

        Parameters
        ----------
        episodes : sequence of mapping
            One mapping per episode with the keys ``episode``, ``seed``, ``steps``,
            ``return``, ``terminated`` (each optional) and ``rmse`` (state -> value).

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> from hgo_mj.record import read
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     with Recorder(Path(tmp) / "run.rrd", state_names=["angle", "angular_velocity"],
        ...                   output_names=["angle"], input_names=["torque"]) as rec:
        ...         rec.log_episode_metrics([{"episode": 0, "seed": 1, "steps": 200,
        ...                                   "return": -3.5, "terminated": False,
        ...                                   "rmse": {"angle": 0.01}}])
        ...     doc = read(Path(tmp) / "run.rrd").attrs["static"]["/metrics"]
        >>> doc["TextDocument:text"][0].splitlines()[6]
        '| 0 | 1 | 200 | -3.5 | False | 0.01 |'
        """
        self._sink.document("/metrics", documents.episode_metrics_document(episodes))

    # ------------------------------------------------------------------ data
    def record(self, t: Any, x: Any, y_clean: Any, y_meas: Any, u: Any,
               estimates: Mapping[str, Any] | None = None,
               diagnostics: Mapping[str, Mapping[str, Any]] | None = None, *,
               step: Any = None, episode: int | None = None,
               extra: Mapping[str, Any] | None = None, mark_end: bool = True,
               estimate_names: Mapping[str, Sequence[str]] | None = None) -> None:
        """Record one block of rows (``T`` samples).

        Parameters
        ----------
        t : array_like, shape (T,)
            Simulated time of each row (the ``sim_time`` timeline).
        x, y_clean, y_meas, u : array_like, shapes (T, n), (T, m), (T, m), (T, p)
            True state, clean and measured outputs, input. ``y_clean`` may be ``None``.
        estimates : mapping observer -> array (T, k), optional
            The observers' ``x_hat``, columns named by ``estimate_names`` (or
            ``observer_states``; default the plant's states when ``k == n``): columns named
            after plant states go to ``/state`` and ``/error``, the others to
            ``/observer/<obs>/estimate/<name>``. An observer left out is NaN in this block
            (and its ghost is not moved).
        diagnostics : mapping observer -> mapping key -> array (T,), optional
            Run-time quantities (gain, parameter estimates, ...).
        step : array_like of int or int, optional
            The ``step`` timeline: an array, or the step of the first row (default: where the
            last block ended).
        episode : int, optional
            Adds the ``episode`` timeline.
        extra : mapping name -> array (T,) or (T, k), optional
            More series, under ``/env/<name>``.
        estimate_names : mapping observer -> sequence of str, optional
            Names of the estimate columns (``ObserverRecord.state_names``), used where the
            constructor's ``observer_states`` gave none; the layout is fixed at the first
            block, and a later block must agree with it.
        mark_end : bool
            Log the diagnostics (which are logged where they change) at the block's last row
            too, so their lines reach it; ``False`` leaves that row to the next block or to
            :meth:`close`.

        Raises
        ------
        DimensionError
            An array whose shape does not match ``(T, width)`` of its names (an estimate,
            an extra, a diagnostic), or a ``step`` array without ``T`` entries.
        DesignError
            Estimates, diagnostics or ``estimate_names`` of an unknown observer, or
            ``estimate_names`` that change an observer's names given before.

        Examples
        --------
        Two blocks of a run; the second continues the ``step`` timeline:

        >>> import tempfile
        >>> from pathlib import Path
        >>> import numpy as np
        >>> from hgo_mj.record import read
        >>> t = np.linspace(0.0, 0.2, 21)
        >>> x = np.c_[np.cos(t), -np.sin(t)]
        >>> u = np.zeros((21, 1))
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     with Recorder(Path(tmp) / "run.rrd", state_names=["angle", "angular_velocity"],
        ...                   output_names=["angle"], input_names=["torque"],
        ...                   observers=["hgo"]) as rec:
        ...         for rows in (slice(0, 10), slice(10, 21)):
        ...             rec.record(t[rows], x[rows], None, x[rows, :1], u[rows],
        ...                        {"hgo": x[rows]})
        ...     df = read(Path(tmp) / "run.rrd")
        >>> df.index[[0, -1]].tolist(), float(df["/error/angle[angle error hgo]"].abs().max())
        ([0, 20], 0.0)
        """
        t = np.asarray(t, dtype=float).reshape(-1)
        if t.size == 0:
            return
        block = self._block(t, x, y_clean, y_meas, u, estimates, diagnostics, step, episode,
                            extra, estimate_names)
        with _DeferSigint():
            self._write(block, mark_end)

    def _block(self, t: Array, x: Any, y_clean: Any, y_meas: Any, u: Any,
               estimates: Mapping[str, Any] | None,
               diagnostics: Mapping[str, Mapping[str, Any]] | None, step: Any,
               episode: int | None, extra: Mapping[str, Any] | None,
               estimate_names: Mapping[str, Sequence[str]] | None) -> Block:
        """Check a block before anything of it is sent (:func:`~hgo_mj.record.rows.check_block`),
        and fix the layout at the first."""
        self._check_observers("estimates of", estimates)
        est = {o: estimates[o] for o in self.observers if o in (estimates or {})}  # type: ignore[index]
        est = {o: row_fns.as_columns(f"estimate of {o!r}", a, t.size) for o, a in est.items()}
        names = self._estimate_names(est, estimate_names)
        self._check_observers("diagnostics of", diagnostics)
        diag = {o: {k: v for k, v in d.items() if self.dropouts is not False or k != "dropouts"}
                for o, d in (diagnostics or {}).items()}
        block = row_fns.check_block(t, x, y_clean, y_meas, u, est, names, diag, extra or {},
                                 (len(self.state_names), len(self.output_names),
                                  len(self.input_names)),
                                 row_fns.as_steps(step, t.size, self._step_next), episode)
        if self.layout is None:
            self._names = names
            self.layout = layout.estimate_layout(self.state_names, self.observers, names)
            self._static += [(path, [style]) for path, style in layout.signal_styles(
                self.layout, self.output_names, self.input_names, self.units)]
            if self.scene is not None:
                self._static += [("/world", [rr.ViewCoordinates.RIGHT_HAND_Z_UP])]
                self._static += self.scene.geometry()
        return block

    def _check_observers(self, what: str, given: Mapping[str, Any] | None) -> None:
        unknown = sorted(set(given or {}) - set(self.observers))
        if unknown:
            raise DesignError(f"{what} unknown observer(s) {unknown}; observers: "
                              f"{list(self.observers)}")

    def _estimate_names(self, est: Mapping[str, Array],
                        given: Mapping[str, Sequence[str]] | None) -> dict[str, tuple[str, ...]]:
        """The column names of every observer's estimate: the constructor's, else
        ``given``, else the plant's states (or ``x_hat_<j>``); fixed at the first block."""
        names = dict(self._names)
        for o, nm in (given or {}).items():
            if str(o) not in self.observers:
                raise DesignError(f"estimate_names of unknown observer {o!r}; observers: "
                                  f"{list(self.observers)}")
            nm = layout.check_names(str(o), nm)
            if str(o) in names and self.layout is not None and names[str(o)] != nm:
                raise DesignError(f"estimate_names of {o!r} changed from "
                                  f"{list(names[str(o)])} to {list(nm)}")
            names.setdefault(str(o), nm)
        for o in self.observers:
            if o not in names:
                width = est[o].shape[1] if o in est else len(self.state_names)
                names[o] = layout.default_names(self.state_names, width)
        return names

    def _write(self, b: Block, mark_end: bool) -> None:
        """Send a checked block: its rows first (rerun's file writer, the slowest part,
        starts on them), then new styles and geometry, the layout, diagnostics and poses."""
        posed = self._posed(b)
        self._register(b, posed)
        self._send_rows(b)
        self._sink.static(self._take_static())
        self._send_blueprint()
        self._send_diagnostics(b, mark_end)
        if self.scene is not None:
            self._queue_poses(b, posed)
        self._last_row = (float(b.t[-1]), int(b.steps[-1]), b.episode)
        self._step_next = int(b.steps[-1]) + 1
        self._t_next = float(b.t[-1]) + (float(b.t[-1] - b.t[-2]) if b.t.size > 1 else 0.0)
        self._sink.tick()

    def _posed(self, b: Block) -> list[str]:
        """The observers of the block whose estimate poses a ghost (one joint at least)."""
        if self.scene is None or self.layout is None:
            return []
        joint_obs = self.layout.joint_observers(self.scene.njoints)
        return [o for o in self.observers if o in b.est and o in joint_obs]

    def _register(self, b: Block, posed: list[str]) -> None:
        """Queue the styles of diagnostics and extras seen for the first time, and the
        geometry of ghosts posed for the first time (drawn from their first pose on)."""
        for o, d in b.diag.items():
            for key in d:
                self._diagnostic(o, key)
        for name in b.extra:
            if name not in self._extra:
                path, style = layout.extra_style(name)
                self._extra[name] = path
                self._static.append((path, [style]))
        for o in posed:
            if o not in self._ghosts and self.scene is not None:
                self._ghosts.add(o)
                color = layout.observer_color(self.observers.index(o))
                self._static += self.scene.geometry(layout.ghost_root(o), color)

    def _diagnostic(self, o: str, key: str) -> tuple[str, str]:
        """Path and kind of a diagnostic, its style queued the first time."""
        if (o, key) not in self._diag:
            self._diag[(o, key)] = layout.diagnostic_path(o, key, tuple(self.params))
            styles = layout.diagnostic_styles(o, self.observers.index(o), key, self.params)
            self._static += [(path, [style]) for path, style in styles]
        return self._diag[(o, key)]

    def _take_static(self) -> list[tuple[str, list[Any]]]:
        """The queued static styles and geometry, the queue emptied."""
        queued, self._static = self._static, []
        return queued

    @staticmethod
    def _require(value: _T | None, what: str) -> _T:
        """``value``, which the recorder made at its start (a missing one is a bug here)."""
        if value is None:
            raise DesignError(f"the recorder has no {what}: it was closed or never started")
        return value

    def _send_rows(self, b: Block) -> None:
        """Send the block's per-sample series (:func:`~hgo_mj.record.rows.signal_series`),
        one ``send_columns`` per entity; only the true states carry the ``step`` timeline
        (see the module docstring)."""
        lay = self._require(self.layout, "layout")
        clock = time_columns(b.t, b.steps, b.episode)  # the truth: sim_time and step
        index = [c for c in clock if c.timeline_name() != layout.STEP]  # the rest: sim_time
        for path, values, on_clock in row_fns.signal_series(lay, b, self.output_names,
                                                            self.input_names, self._extra):
            self._sink.scalars(path, clock if on_clock else index, values)

    # ------------------------------------------------------------------ diagnostics
    def _send_diagnostics(self, b: Block, mark_end: bool) -> None:
        """Send the block's diagnostics where they change
        (:func:`~hgo_mj.record.rows.changes`), and the true parameter next to a parameter
        estimate; a series' last row waits for the next block or :meth:`close` unless
        ``mark_end``."""
        for path, v in row_fns.diagnostic_series(b, self._diag, self.params).items():
            keep, last, pending = row_fns.changes(v, self._diag_last.get(path), mark_end)
            self._diag_last[path] = last
            if pending:
                self._diag_pending[path] = last
            else:
                self._diag_pending.pop(path, None)
            if keep is not None:
                self._sink.scalars(path, time_columns(b.t[keep], b.steps[keep], b.episode),
                                   v[keep])

    def _send_pending(self) -> None:
        """Log the last row of every piecewise-constant series whose end is still pending."""
        if self._diag_pending and self._last_row is not None:
            t, step, episode = self._last_row
            index = time_columns(np.array([t]), np.array([step], dtype=np.int64), episode)
            for path, value in self._diag_pending.items():
                self._sink.scalars(path, index, np.array([value]))
            self._diag_pending.clear()

    # ------------------------------------------------------------------ poses
    def _queue_poses(self, b: Block, posed: list[str]) -> None:
        """Queue the joint positions of the block's pose rows
        (:func:`~hgo_mj.record.rows.pose_rows`, :func:`~hgo_mj.record.rows.pose_sets`); they
        are posed and sent :data:`_POSE_ROWS` rows at a time (a batch costs about the same
        whatever its length), the rest by :meth:`flush` or :meth:`close`."""
        lay = self._require(self.layout, "layout")
        scene = self._require(self.scene, "scene")
        sel: Mask = row_fns.pose_rows(b.t, b.steps, self.pose_rate)
        sets = row_fns.pose_sets(lay, b, posed, scene.njoints, sel)
        queued = self._poses
        if queued and (queued[0][2] != b.episode or set(queued[0][3]) != set(sets)):
            self._send_poses()
        self._poses.append((b.t[sel], b.steps[sel], b.episode, sets))
        self._pose_rows += int(sel.sum())
        if self._pose_rows >= _POSE_ROWS:
            self._send_poses()

    def _send_poses(self) -> None:
        """Pose the queued rows (every set of joint positions in one call of
        :meth:`~hgo_mj.record.poses.Poses.poses`) and send the moving bodies' transforms."""
        if not self._poses or self.scene is None:
            return
        queued, self._poses, self._pose_rows = self._poses, [], 0
        roots = list(queued[0][3])
        t = np.concatenate([q[0] for q in queued])
        steps = np.concatenate([q[1] for q in queued])
        index = time_columns(t, steps, queued[0][2])
        pos, quat = self.scene.poses(np.concatenate([np.concatenate([q[3][r] for q in queued])
                                                     for r in roots]))
        for i, root in enumerate(roots):
            rows = slice(i * t.size, (i + 1) * t.size)
            for body in self.scene.posed_bodies():
                self._sink.transforms(layout.body_path(root, self.scene.body_names[body]), index,
                                      pos[rows, body], xyzw(quat[rows, body]))

    # ------------------------------------------------------------------ layout
    def blueprint(self) -> rrb.Blueprint:
        """The default layout (:func:`hgo_mj.record.layout.blueprint`) of what has been
        recorded so far.

        Returns
        -------
        rerun.blueprint.Blueprint
            The views of the states, errors, sensor, input, diagnostics, extras and (with a
            model) the 3D scene; sent to the file as its default blueprint.

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     with Recorder(Path(tmp) / "run.rrd", state_names=["angle", "angular_velocity"],
        ...                   output_names=["angle"], input_names=["torque"],
        ...                   observers=["hgo"]) as rec:
        ...         bp = rec.blueprint()
        >>> type(bp).__name__
        'Blueprint'
        """
        lay = self.layout or layout.estimate_layout(  # before the first block: the names given
            self.state_names, self.observers, {o: self._names.get(o, ()) for o in self.observers})
        return layout.blueprint(lay, list(self._diag.values()), self.params,
                                extras=bool(self._extra), world=self.scene is not None,
                                units=self.units, output_names=self.output_names,
                                input_names=self.input_names)

    def _send_blueprint(self) -> None:
        """Send :meth:`blueprint` as the recording's default layout, once per layout (a new
        diagnostic or extra changes it)."""
        key = (tuple(self._diag.values()), tuple(self._extra))
        if key != self._sent_layout:
            self._sent_layout = key
            self._sink.blueprint(self.blueprint())

    # ------------------------------------------------------------------ whole runs
    def record_trajectory(self, traj: Any, *, metrics: bool | Mapping[str, Any] = True,
                          chunk_seconds: float | None = None) -> None:
        """Record a whole :class:`~hgo_mj.simulate.Trajectory`: its rows (in blocks of
        ``chunk_seconds`` of simulated time, default one block), its metadata and its metrics
        (computed with :func:`hgo_mj.metrics.all_metrics` when ``metrics=True``).

        Parameters
        ----------
        traj : Trajectory
            A run of :func:`hgo_mj.simulate.simulate` with every observer of the recorder.
        metrics : bool or mapping
            True: the ``/metrics`` document from :func:`hgo_mj.metrics.all_metrics` (when the
            run has observers); a mapping: those metrics; False: none.
        chunk_seconds : float, optional
            Simulated seconds per block (a long run in several ``send_columns`` calls);
            default the whole run in one block.

        Raises
        ------
        DesignError
            (from :meth:`write_chunk`) ``traj`` lacks one of the recorder's observers.

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> from hgo_mj.record import read
        >>> from hgo_mj.inputs import Multisine
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> from hgo_mj.sensors import GaussianNoise, SensorChain
        >>> from hgo_mj.simulate import simulate
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> traj = simulate(plant, SensorChain([GaussianNoise(std=1e-3)], seed=0),
        ...                 {"k40": HighGainObserver(plant.system, k=40.0)},
        ...                 Multisine(amplitudes=[0.3], frequencies=[0.5]), duration=0.1,
        ...                 x0=[0.5, 0.0], seed=0)
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     with Recorder.for_trajectory(Path(tmp) / "run.rrd", traj) as rec:
        ...         rec.record_trajectory(traj, chunk_seconds=0.05)
        ...     df = read(Path(tmp) / "run.rrd")
        >>> len(df), "/scenario" in df.attrs["static"], "/metrics" in df.attrs["static"]
        (11, True, True)
        """
        rows = len(traj)
        block = rows
        if chunk_seconds is not None and rows > 1:
            block = max(int(round(chunk_seconds / float(traj.t[1] - traj.t[0]))), 1)
        for k0 in range(0, rows, block):
            self.write_chunk(0, traj, slice(k0, min(k0 + block, rows)), mark_end=k0 + block >= rows)
        if traj.metadata:  # after the rows: built while rerun's threads encode them
            self.log_metadata(traj.metadata)
        if metrics is True and traj.observers:
            from ..metrics import all_metrics

            metrics = all_metrics(traj)
        if metrics:
            self.log_metrics(metrics)  # type: ignore[arg-type]

    def write_chunk(self, first_row: int, chunk: Any, rows: slice = slice(None), *,
                    mark_end: bool = False) -> None:
        """Record rows of a :class:`~hgo_mj.simulate.Trajectory` whose first row is the run's
        row ``first_row`` (the ``step`` timeline). This is the ``simulate(on_chunk=...)``
        callback: ``simulate(..., on_chunk=(1.0, recorder.write_chunk))``; the diagnostics'
        last row waits for the next chunk or :meth:`close` (see :meth:`record`).

        Parameters
        ----------
        first_row : int
            The run's row index (``step``) of ``chunk``'s first row.
        chunk : Trajectory
            Rows of a run, holding every observer of the recorder.
        rows : slice
            The rows of ``chunk`` to record (default all).
        mark_end : bool
            Log the diagnostics at the last row too (see :meth:`record`); True for a run's
            last chunk.

        Raises
        ------
        DesignError
            ``chunk`` lacks one of the recorder's observers.

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> from hgo_mj.record import read
        >>> from hgo_mj.inputs import Multisine
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> from hgo_mj.sensors import GaussianNoise, SensorChain
        >>> from hgo_mj.simulate import simulate
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> traj = simulate(plant, SensorChain([GaussianNoise(std=1e-3)], seed=0),
        ...                 {"k40": HighGainObserver(plant.system, k=40.0)},
        ...                 Multisine(amplitudes=[0.3], frequencies=[0.5]), duration=0.1,
        ...                 x0=[0.5, 0.0], seed=0)
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     with Recorder.for_trajectory(Path(tmp) / "run.rrd", traj) as rec:
        ...         rec.write_chunk(0, traj, slice(0, 6))
        ...         rec.write_chunk(0, traj, slice(6, 11), mark_end=True)
        ...     df = read(Path(tmp) / "run.rrd")
        >>> df.index[[0, -1]].tolist()
        [0, 10]
        """
        obs = chunk.observers
        missing = [o for o in self.observers if o not in obs]
        if missing:
            raise DesignError(f"the trajectory lacks the observer(s) {missing}; found {list(obs)}")
        self.record(chunk.t[rows], chunk.x[rows], chunk.y_clean[rows], chunk.y_meas[rows],
                    chunk.u[rows], {o: obs[o].x_hat[rows] for o in self.observers},
                    {o: {k: v[rows] for k, v in obs[o].diagnostics.items()} for o in self.observers},
                    step=first_row + (rows.start or 0), mark_end=mark_end,
                    estimate_names={o: obs[o].state_names for o in self.observers
                                    if obs[o].state_names})

    def record_episode(self, episode: int, t: Any, x: Any, y_meas: Any, u: Any, *,
                       y_clean: Any = None, estimates: Mapping[str, Any] | None = None,
                       diagnostics: Mapping[str, Mapping[str, Any]] | None = None,
                       extra: Mapping[str, Any] | None = None) -> None:
        """Record one environment episode from numpy arrays, at its end.

        Episodes follow each other on ``sim_time`` and ``step`` (each placed after the last,
        whatever its own ``t`` starts at); the ``episode`` timeline holds ``episode``. Arrays
        as in :meth:`record`; ``extra`` (reward, ...) goes under ``/env/<name>``.

        Parameters
        ----------
        episode : int
            The episode's number (the ``episode`` timeline).
        t : array_like, shape (T,)
            The episode's times, s; only their differences matter.
        x, y_meas, u : array_like, shapes (T, n), (T, m), (T, p)
            True state, measured output and input.
        y_clean : array_like, shape (T, m), optional
            Clean output.
        estimates : mapping observer -> array (T, k), optional
            The observers' estimates.
        diagnostics : mapping observer -> mapping key -> array (T,), optional
            Run-time quantities of the observers.
        extra : mapping name -> array (T,) or (T, k), optional
            More series (reward, ...), under ``/env/<name>``.

        Raises
        ------
        DimensionError, DesignError
            As :meth:`record`.

        Examples
        --------
        Two episodes of 5 rows each, the second placed after the first:

        >>> import tempfile
        >>> from pathlib import Path
        >>> import numpy as np
        >>> from hgo_mj.record import read
        >>> t = np.linspace(0.0, 0.04, 5)
        >>> x = np.zeros((5, 2))
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     with Recorder(Path(tmp) / "env.rrd", state_names=["angle", "angular_velocity"],
        ...                   output_names=["angle"], input_names=["torque"]) as rec:
        ...         for ep in range(2):
        ...             rec.record_episode(ep, t, x, x[:, :1], np.zeros((5, 1)),
        ...                                extra={"reward": -np.ones(5)})
        ...     df = read(Path(tmp) / "env.rrd")
        >>> df["episode"].tolist()
        [0, 0, 0, 0, 0, 1, 1, 1, 1, 1]
        >>> float(df["/env/reward"].sum())
        -10.0
        """
        t = np.asarray(t, dtype=float).reshape(-1)
        if t.size == 0:
            return
        self.record(t - t[0] + self._t_next, x, y_clean, y_meas, u, estimates, diagnostics,
                    step=self._step_next, episode=int(episode), extra=extra)

    # ------------------------------------------------------------------ lifetime
    @property
    def writing(self) -> Path | None:
        """The file being written: a temporary beside :attr:`path` until :meth:`close`
        checks it and renames it onto :attr:`path` (an earlier recording there is kept until
        then); None for a recorder without a path."""
        return self._sink.file

    def flush(self) -> None:
        """Send the queued poses and wait until everything recorded so far is written (to
        :attr:`writing` until the recorder is closed).

        Examples
        --------
        The file readable while the recorder is still open:

        >>> import tempfile
        >>> import warnings
        >>> from pathlib import Path
        >>> import numpy as np
        >>> from hgo_mj.record import read
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     rec = Recorder(Path(tmp) / "run.rrd", state_names=["angle", "angular_velocity"],
        ...                    output_names=["angle"], input_names=["torque"], footer=False)
        ...     rec.record(np.arange(3) * 0.01, np.zeros((3, 2)), None, np.zeros((3, 1)),
        ...                np.zeros((3, 1)))
        ...     rec.flush()
        ...     with warnings.catch_warnings():  # no footer yet: rerun warns
        ...         warnings.simplefilter("ignore")
        ...         rows = len(read(rec.writing))
        ...     rec.close()
        >>> rows
        3
        """
        with _DeferSigint():
            self._send_poses()
        self._sink.flush()

    def close(self) -> None:
        """Log what is pending, flush and close the file (idempotent). A stream handed in
        without a path is flushed, not disconnected.

        Raises
        ------
        RecordingError
            The file sink did not write everything within :data:`CLOSE_TIMEOUT_S` seconds (a
            failed write: full disk, file too large), or the closed file is not a finalized
            recording (no footer; ``rerun rrd verify`` rejects it).

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> import numpy as np
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     rec = Recorder(Path(tmp) / "run.rrd", state_names=["angle", "angular_velocity"],
        ...                    output_names=["angle"], input_names=["torque"])
        ...     rec.record(np.arange(3) * 0.01, np.zeros((3, 2)), None, np.zeros((3, 1)),
        ...                np.zeros((3, 1)))
        ...     rec.close()
        ...     rec.close()  # a second close does nothing
        ...     check_finalized(rec.path)
        """
        if not self._closed:
            self._closed = True
            self._send_poses()
            self._send_pending()
            self._sink.close(CLOSE_TIMEOUT_S)
            if self._sink.file is not None and self._sink.footer:
                try:
                    check_finalized(self._sink.file, name=self.path)
                except RecordingError:
                    self._sink.discard()
                    raise
            self._sink.publish()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


def check_finalized(path: Any, name: Any = None) -> None:
    """Raise :class:`RecordingError` unless ``path`` is a recording that ends in rerun's
    footer (what ``rerun rrd verify`` checks first); the footer alone is read.

    Parameters
    ----------
    path : str or Path
        The ``.rrd`` file to check.
    name : str or Path, optional
        The file named in the message (default ``path``; the recorder checks its temporary
        and names the recording).

    Raises
    ------
    RecordingError
        ``path`` is not a readable rerun recording, or it has no footer (a write failed, the
        file was changed while it was written, or it was written with ``footer=False``).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     with Recorder(Path(tmp) / "run.rrd", state_names=["angle", "angular_velocity"],
    ...                   output_names=["angle"], input_names=["torque"]) as rec:
    ...         rec.record([0.0], np.zeros((1, 2)), None, np.zeros((1, 1)), np.zeros((1, 1)))
    ...     check_finalized(rec.path)  # passes: returns None
    ...     (Path(tmp) / "torn.rrd").write_bytes(rec.path.read_bytes()[:-8])
    ...     check_finalized(Path(tmp) / "torn.rrd")
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.RecordingError: the recording ... was not finalized ...
    """
    import warnings

    from rerun.chunk import RrdReader

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            RrdReader(path)
        except Exception as exc:  # rerun's own errors: not a readable recording
            raise RecordingError(f"the recording {str(name or path)!r} is not readable: "
                                 f"{exc}") from None
    if any("footer" in str(w.message) for w in caught):
        raise RecordingError(f"the recording {str(name or path)!r} was not finalized (no rerun footer: "
                             f"a write failed or the file was changed while it was written)")


def record_trajectory(traj: Any, path: str | Path, *, model: Any = None,
                      metrics: bool | Mapping[str, Any] = True, **kw: Any) -> Path:
    """Write ``traj`` to the recording ``path`` (see :class:`Recorder`); returns the path.

    Parameters
    ----------
    traj : Trajectory
        A run of :func:`hgo_mj.simulate.simulate`.
    path : str or Path
        The ``.rrd`` file to write (``rerun FILE`` opens it).
    model : mujoco.MjModel, optional
        The model drawn in the 3D view; default the MJCF of the trajectory's plant (none for
        ODE plants).
    metrics : bool or mapping
        True: the ``/metrics`` document from :func:`hgo_mj.metrics.all_metrics`; a mapping:
        those metrics; False: none.
    **kw
        Passed to :meth:`Recorder.for_trajectory` (e.g. ``recording_name``).

    Returns
    -------
    Path
        ``path``.

    Examples
    --------
    >>> from hgo_mj.inputs import Multisine
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.sensors import GaussianNoise, SensorChain
    >>> from hgo_mj.simulate import simulate
    >>> plant = make_plant("pendulum", dt=0.01)
    >>> traj = simulate(plant, SensorChain([GaussianNoise(std=1e-3)], seed=0),
    ...                 {"k40": HighGainObserver(plant.system, k=40.0)},
    ...                 Multisine(amplitudes=[0.3], frequencies=[0.5]), duration=0.1,
    ...                 x0=[0.5, 0.0], seed=0)
    >>> import tempfile
    >>> from pathlib import Path
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = record_trajectory(traj, Path(tmp) / "pendulum.rrd")
    ...     size = path.stat().st_size
    >>> path.name, size > 0
    ('pendulum.rrd', True)
    """
    with Recorder.for_trajectory(path, traj, model=model, **kw) as rec:
        rec.record_trajectory(traj, metrics=metrics)
    return Path(path)


__all__ = ["CLOSE_TIMEOUT_S", "Recorder", "check_finalized", "record_trajectory"]
