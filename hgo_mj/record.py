"""Headless rerun recordings (``.rrd``) of true versus estimated signals, for review.

A :class:`Recorder` owns an explicit :class:`rerun.RecordingStream` (never rerun's global one)
that writes to a file; no viewer is spawned and no display is needed. A reviewer opens the file
later with ``rerun file.rrd``. Data goes in columns, batched: the entities sharing a block's rows
are one Arrow record batch handed to rerun in one call (``rerun.chunk.Chunk.from_record_batch``
and ``send_chunks``, which split it into one chunk per entity; ``send_columns`` is the same
columnar path one entity a call), static styles and geometry one batch too. A per-step
``rr.log`` would cost 36 to 120 microseconds a step here. Styles, geometry and the blueprint
are converted to Arrow once per process (per layout) and sent again as they are: rerun's
archetype and blueprint classes cost milliseconds to build and convert for every recording.

Timelines: ``sim_time`` (simulated time, a duration), ``step`` (the sample index) and, for
environments, ``episode``.

Entities (names escaped with :func:`rerun.escape_entity_path_part`)::

    /state/<state>              scalars [true, <observer 1>, <observer 2>, ...], one row a sample
                                (the observers that estimate that plant state, by name)
    /error/<state>              scalars [<observer 1>, ...]: x - x_hat, for those observers
    /observer/<obs>/estimate/<name>   an estimate that is not a plant state (the observer's
                                own state names: an order-only observer's z1, z2, ..., the
                                derivatives of a multi-output observer, ...)
    /sensor/<output>            scalars [clean, measured] (a dropout is NaN)
    /input/<input>              scalar u
    /observer/<obs>/gain        the gain diagnostic (``k``, ``gain``, ``gamma``; ``k_<x>`` -> gain/<x>)
    /observer/<obs>/theta/<p>   parameter estimates (diagnostics ``theta...``), next to
    /plant/param/<p>            the true parameter, when the system has one of that name
    /observer/<obs>/diagnostics/<key>   every other diagnostic (dropouts, ...)
    /env/<name>                 environment extras (reward, ...)
    /world/true/<body>/<geom>   the MuJoCo model's geometry posed from the true state
    /world/estimate/<obs>/<body>/<geom>   translucent ghost posed from that observer's estimate
    /scenario, /metrics         text documents: scenario, seed, observer parameters, package
                                versions; the metrics table (an environment's: one row per
                                episode, :meth:`Recorder.log_episode_metrics`)

Estimates are matched to the plant's states by name: each observer's column names are its
``state_names`` (``observer_states``, or ``ObserverRecord.state_names`` of a trajectory); an
observer given none names the plant's states when its estimate has their number, else
``x_hat_1, x_hat_2, ...``. A plant state no observer estimates has a truth-only ``/state``
entity and no ``/error`` entity.

One entity per state holds the truth and every estimate as instances (rather than one entity
per observer and state): each entity row costs about 20 bytes of row id and time on top of its
values, and this layout keeps a 10 s, 1 kHz pendulum recording with two observers under 3 MB.
Diagnostics are logged where they change (and at the end of the run or episode), drawn as
steps.
Series styles (names, one colour per observer, the truth in a fixed colour) are logged once as
static data, and a default blueprint is embedded: one time-series view per state (truth and
every estimate), one per state's errors, the adaptive quantities, inputs and measurements, the
3D view and the text documents.

The 3D view is posed with a batched forward kinematics of the hinge and slide joints the
system names (MuJoCo's ``mj_kinematics`` equations, vectorised over samples); joints the
system does not name stay at the model's ``qpos0``. Poses are logged at ``pose_rate`` (default
50 Hz, the frame rate a viewer plays back in real time) to keep files small and cheap; every
sample with ``pose_rate=None``.
"""

from __future__ import annotations

import json
import signal
import threading
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from numpy.typing import NDArray

from ._json import strict_json
from .exceptions import DesignError, DimensionError

Array = NDArray[np.float64]

SIM_TIME = "sim_time"
STEP = "step"
EPISODE = "episode"

#: colour of the true signals (the true robot keeps the MJCF's colours)
TRUE_COLOR = (230, 230, 230)
MEASURED_COLOR = (130, 130, 130)
INPUT_COLOR = (255, 196, 0)
EXTRA_COLOR = (120, 200, 255)
#: one colour per observer, in order (tab10 without its grey)
OBSERVER_COLORS = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
                   (140, 86, 75), (227, 119, 194), (188, 189, 34), (23, 190, 207))
#: alpha of the estimate ghosts in the 3D view (0-255)
GHOST_ALPHA = 90

_GAIN_KEYS = ("k", "gain", "gamma")
#: least wall time between two flushes started after blocks, seconds
_FLUSH_INTERVAL = 0.25
#: pose rows queued before they are posed and sent (a 2 s block at 50 Hz has 101)
_POSE_ROWS = 250
#: the chunk batcher of a recorder's own stream (rerun's default holds chunks up to 200 ms or
#: 2 MiB: the file writer would then encode a run's last blocks at close)
_BATCHER = rr.ChunkBatcherConfig(flush_tick=0.01, flush_num_bytes=262144)


_THETA_PREFIXES = ("theta_hat_", "theta_hat", "theta_", "theta")


def _part(name: str) -> str:
    return rr.escape_entity_path_part(str(name))


def observer_color(i: int) -> tuple[int, int, int]:
    """Colour of the ``i``-th observer of a recording (the same in every view)."""
    return OBSERVER_COLORS[i % len(OBSERVER_COLORS)]


def diagnostic_path(observer: str, key: str, param_names: Sequence[str] = ()) -> tuple[str, str]:
    """Entity path and kind (``"gain"``, ``"theta"`` or ``"other"``) of one diagnostic.

    ``k``, ``gain`` and ``gamma`` go to ``/observer/<obs>/gain`` (``k_<x>``, ... below it); a key
    that is a parameter name of the system, or starts with ``theta`` (``theta_hat_<p>``,
    ``theta_<p>``, ``theta<p>``), to ``/observer/<obs>/theta/<p>``; anything else to
    ``/observer/<obs>/diagnostics/<key>``.
    """
    o = _part(observer)
    low = key.lower().rstrip("_")
    if low in _GAIN_KEYS:
        return f"/observer/{o}/gain", "gain"
    for g in _GAIN_KEYS:
        if low.startswith(g + "_"):
            return f"/observer/{o}/gain/{_part(key[len(g) + 1:])}", "gain"
    if key in param_names:
        return f"/observer/{o}/theta/{_part(key)}", "theta"
    for pre in _THETA_PREFIXES:
        if low.startswith(pre) and len(key) > len(pre):
            param = key[len(pre):].strip("_")
            return f"/observer/{o}/theta/{_part(param or key)}", "theta"
    if low == "theta":
        return f"/observer/{o}/theta/theta", "theta"
    return f"/observer/{o}/diagnostics/{_part(key)}", "other"


def _theta_param(path: str) -> str:
    return path.rsplit("/theta/", 1)[1]


# --------------------------------------------------------------------------- kinematics
def _qmul(a: Array, b: Array) -> Array:
    """Quaternion products ``a * b`` (``w, x, y, z`` last axis), broadcasting."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack((aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw),
                    axis=-1)


def _qrot(q: Array, v: Array) -> Array:
    """Rotate vectors ``v`` by unit quaternions ``q`` (``w, x, y, z``), broadcasting."""
    w, u = q[..., :1], q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


class Kinematics:
    """Batched forward kinematics of a MuJoCo model driven by some of its joints.

    Parameters
    ----------
    model : mujoco.MjModel
        The compiled model.
    joints : sequence of str
        Hinge or slide joints whose positions :meth:`poses` takes, in order; every other joint
        stays at ``qpos0``.

    Notes
    -----
    The pose of body ``b`` with parent ``p`` follows ``mj_kinematics``: ``x_b = x_p + R_p
    pos_b``, ``q_b = q_p body_quat_b``, then for each driven joint a hinge rotates about its
    axis through its anchor by ``q - qpos0`` and a slide translates along its axis. Each body is
    a handful of numpy operations on ``(T, 3)`` and ``(T, 4)`` arrays; a test holds it against
    ``mj_kinematics``.
    """

    def __init__(self, model: Any, joints: Sequence[str]) -> None:
        import mujoco

        self.model = model
        m = model
        driven: dict[int, list[tuple[int, int]]] = {}  # body -> [(joint id, column)]
        for col, name in enumerate(joints):
            j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
            if j < 0:
                raise DesignError(f"the model has no joint named {name!r}; joints: "
                                  f"{[m.joint(i).name for i in range(m.njnt)]}")
            jtype = int(m.jnt_type[j])
            if jtype not in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
                raise DesignError(f"joint {name!r} must be a hinge or slide joint to be posed; "
                                  f"found {mujoco.mjtJoint(jtype).name}")
            driven.setdefault(int(m.jnt_bodyid[j]), []).append((j, col))
        for b in driven:
            driven[b].sort()
        self._driven = driven
        self.njoints = len(joints)
        moving = np.zeros(m.nbody, dtype=bool)
        for b in range(1, m.nbody):
            moving[b] = moving[m.body_parentid[b]] or b in driven
        self.moving = moving
        self._hinge = int(mujoco.mjtJoint.mjJNT_HINGE)

    def poses(self, q: Array) -> tuple[list[Array], list[Array]]:
        """World positions and quaternions (``w, x, y, z``) of every body for the joint
        positions ``q`` of shape ``(T, len(joints))``: lists over bodies of arrays of shape
        ``(T, 3)`` and ``(T, 4)`` for bodies the joints move, ``(1, 3)`` and ``(1, 4)`` for the
        others."""
        m = self.model
        q = np.asarray(q, dtype=float)
        pos: list[Array] = [np.zeros((1, 3))]
        quat: list[Array] = [np.array([[1.0, 0.0, 0.0, 0.0]])]
        for b in range(1, m.nbody):
            par = m.body_parentid[b]
            xb, qb = pos[par], quat[par]
            bpos, bquat = np.asarray(m.body_pos[b]), np.asarray(m.body_quat[b])
            if bpos.any():
                xb = xb + _qrot(qb, bpos)
            if bquat[0] != 1.0:
                qb = _qmul(qb, bquat)
            for j, col in self._driven.get(b, ()):
                a = q[:, col] - m.qpos0[m.jnt_qposadr[j]]
                axis = np.asarray(m.jnt_axis[j])
                if m.jnt_type[j] == self._hinge:
                    anchor = np.asarray(m.jnt_pos[j])
                    xanchor = xb + _qrot(qb, anchor) if anchor.any() else xb
                    half = 0.5 * a[:, None]
                    qb = _qmul(qb, np.concatenate((np.cos(half), np.sin(half) * axis), axis=1))
                    xb = xanchor - _qrot(qb, anchor) if anchor.any() else xb
                else:
                    xb = xb + _qrot(qb, axis) * a[:, None]
            if self.moving[b]:
                n = q.shape[0]
                xb = np.broadcast_to(xb, (n, 3))
                qb = np.broadcast_to(qb, (n, 4))
            pos.append(xb)
            quat.append(qb / np.linalg.norm(qb, axis=-1, keepdims=True))
        return pos, quat


def _xyzw(q: Array) -> Array:
    return np.concatenate((q[..., 1:], q[..., :1]), axis=-1)


def _geom_color(m: Any, g: int) -> NDArray[np.float64]:
    rgba = np.array(m.geom_rgba[g], dtype=float)
    if m.geom_matid[g] >= 0 and np.allclose(rgba, (0.5, 0.5, 0.5, 1.0)):
        rgba = np.array(m.mat_rgba[m.geom_matid[g]], dtype=float)
    return rgba


def _geom_shape(m: Any, g: int, rgba: Any, fill: Any) -> Any:
    """The rerun archetype of geom ``g`` in its own frame, or ``None`` for a type not drawn."""
    import mujoco

    t = mujoco.mjtGeom
    kind, size = int(m.geom_type[g]), np.array(m.geom_size[g], dtype=float)
    col = [rgba]
    if kind == t.mjGEOM_BOX:
        return rr.Boxes3D(half_sizes=[size], colors=col, fill_mode=fill)
    if kind == t.mjGEOM_SPHERE:
        return rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], colors=col, fill_mode=fill)
    if kind == t.mjGEOM_ELLIPSOID:
        return rr.Ellipsoids3D(half_sizes=[size], colors=col, fill_mode=fill)
    if kind == t.mjGEOM_CAPSULE:
        return rr.Capsules3D(lengths=[2 * size[1]], radii=[size[0]],
                             translations=[[0.0, 0.0, -size[1]]], colors=col, fill_mode=fill)
    if kind == t.mjGEOM_CYLINDER:
        return rr.Cylinders3D(lengths=[2 * size[1]], radii=[size[0]], colors=col, fill_mode=fill)
    if kind == t.mjGEOM_PLANE:
        half = [size[0] or 2.0, size[1] or 2.0, 1e-3]
        return rr.Boxes3D(half_sizes=[half], colors=col, fill_mode=fill)
    if kind == t.mjGEOM_MESH and m.geom_dataid[g] >= 0:
        k = m.geom_dataid[g]
        v0, nv = m.mesh_vertadr[k], m.mesh_vertnum[k]
        f0, nf = m.mesh_faceadr[k], m.mesh_facenum[k]
        return rr.Mesh3D(vertex_positions=np.array(m.mesh_vert[v0:v0 + nv]),
                         triangle_indices=np.array(m.mesh_face[f0:f0 + nf]), albedo_factor=rgba)
    return None  # height fields, SDFs


def _geom_key(m: Any, g: int, rgba: Any, fill: Any) -> Any:
    """What determines :func:`_geom_shape` of a primitive geom (``None`` for meshes and the
    rest, which are not cached)."""
    import mujoco

    t = mujoco.mjtGeom
    kind = int(m.geom_type[g])
    if kind not in (t.mjGEOM_BOX, t.mjGEOM_SPHERE, t.mjGEOM_ELLIPSOID, t.mjGEOM_CAPSULE,
                    t.mjGEOM_CYLINDER, t.mjGEOM_PLANE):
        return None
    return ("geom", kind, tuple(float(v) for v in m.geom_size[g]), tuple(rgba), fill)


# --------------------------------------------------------------------------- SIGINT
class _DeferSigint:
    """Hold a SIGINT (Ctrl-C) until a block is written, so a chunk is never half-recorded."""

    def __enter__(self) -> _DeferSigint:
        self._old: Any = None
        self._hit = False
        if (threading.current_thread() is threading.main_thread()
                and signal.getsignal(signal.SIGINT) is signal.default_int_handler):
            self._old = signal.signal(signal.SIGINT, self._handler)
        return self

    def _handler(self, signum: int, frame: Any) -> None:
        self._hit = True

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None,
                 tb: TracebackType | None) -> None:
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)
        if self._hit and et is None:
            raise KeyboardInterrupt


# --------------------------------------------------------------------------- recorder
def _columns(name: str, a: Any, rows: int, width: int | None = None) -> Array:
    arr = np.asarray(a, dtype=float)
    if arr.ndim == 1 and width is not None:
        arr = arr.reshape(-1, 1) if width == 1 else arr
    if arr.ndim != 2 or arr.shape[0] != rows or (width is not None and arr.shape[1] != width):
        want = f"({rows}, {width})" if width is not None else f"({rows}, n)"
        raise DimensionError(f"{name} must have shape {want}; found {arr.shape}")
    return arr


def _estimate_names(observer: str, names: Any) -> tuple[str, ...]:
    out = tuple(str(s) for s in names)
    if not out or len(set(out)) != len(out):
        raise DesignError(f"the estimate names of {observer!r} must be distinct and not empty; "
                          f"found {list(out)}")
    return out


_DESCRIPTORS: dict[str, tuple[dict[bytes, bytes], Any]] = {}


def _descriptor(kind: str) -> tuple[dict[bytes, bytes], Any]:
    """Arrow field metadata and datatype of one component, taken from rerun's own columns."""
    if kind not in _DESCRIPTORS:
        if kind == "scalar":
            col = next(iter(rr.Scalars.columns(scalars=np.zeros(1))))
        else:
            cols = rr.Transform3D.columns(translation=np.zeros((1, 3), np.float32),
                                          quaternion=np.zeros((1, 4), np.float32))
            col = next(c for c in cols if c.component_descriptor().component.endswith(kind))
        d = col.component_descriptor()
        meta = {b"rerun:kind": b"data", b"rerun:component": d.component.encode(),
                b"rerun:archetype": (d.archetype or "").encode(),
                b"rerun:component_type": (d.component_type or "").encode()}
        _DESCRIPTORS[kind] = (meta, col.as_arrow_array().type)
    return _DESCRIPTORS[kind]


#: largest number of entries of each per-process cache (cleared when full)
_CACHE_MAX = 4096
#: (path, key) -> Arrow fields and one-row list arrays of a static archetype
_STATIC_CACHE: dict[tuple[str, Any], tuple[list[Any], list[Any]]] = {}
#: the (path, key) of every queued static archetype -> the chunks of their batch (sent again
#: as they are: the same styles and geometry in every recording of a scenario)
_STATIC_CHUNKS: dict[tuple[tuple[str, Any], ...], list[Any]] = {}


def _static_columns(path: str, archetype: Any) -> tuple[list[Any], list[Any]]:
    """Arrow fields and one-row list arrays of a static archetype logged at ``path``."""
    import pyarrow as pa

    fields, arrays = [], []
    for b in archetype.as_component_batches():
        d, a = b.component_descriptor(), b.as_arrow_array()
        lst = pa.ListArray.from_arrays(pa.array([0, len(a)], pa.int32()), a)
        fields.append(pa.field(f"{path}:{d.component}", lst.type, metadata={
            b"rerun:kind": b"data", b"rerun:entity_path": path.encode(),
            b"rerun:component": d.component.encode(),
            b"rerun:archetype": (d.archetype or "").encode(),
            b"rerun:component_type": (d.component_type or "").encode()}))
        arrays.append(lst)
    return fields, arrays


#: Arrow fields of timelines and temporal components (never evicted: _SCHEMAS keys on their ids)
_FIELDS: dict[tuple[str, str, Any], Any] = {}
#: ids of a batch's (cached) fields -> their Arrow schema
_SCHEMAS: dict[tuple[int, ...], Any] = {}


def _index_field(name: str, kind: str) -> Any:
    """The Arrow field of a timeline column (cached)."""
    key = (name, kind, None)
    if key not in _FIELDS:
        import pyarrow as pa

        _FIELDS[key] = pa.field(name, pa.duration("ns") if kind == "duration" else pa.int64(),
                                nullable=False, metadata={b"rerun:kind": b"index",
                                                          b"rerun:index_name": name.encode()})
    return _FIELDS[key]


class _Batch:
    """Columns of several entities on the same rows, sent as one Arrow record batch (rerun
    splits it into one chunk per entity): one call instead of one ``send_columns`` each."""

    def __init__(self, t: Array, steps: NDArray[np.int64], episode: int | None) -> None:
        import pyarrow as pa

        self.pa = pa
        self.rows = t.size
        self._offsets: dict[int, Any] = {}
        ns = np.rint(t * 1e9).astype(np.int64)
        self.fields = [_index_field(SIM_TIME, "duration"), _index_field(STEP, "sequence")]
        self.arrays = [pa.Array.from_buffers(pa.duration("ns"), ns.size, [None, pa.py_buffer(ns)]),
                       pa.array(np.ascontiguousarray(steps, dtype=np.int64))]
        if episode is not None:
            self.fields.append(_index_field(EPISODE, "sequence"))
            self.arrays.append(pa.array(np.full(t.size, int(episode), dtype=np.int64)))
        self._n_index = len(self.fields)

    def add(self, path: str, kind: str, values: Any) -> None:
        """Add ``values`` of shape ``(rows,)`` or ``(rows, k)`` (scalars) or ``(rows, 3|4)``
        (``translation``/``quaternion``) to the entity ``path``."""
        pa = self.pa
        meta, typ = _descriptor(kind)
        v = np.asarray(values)
        if kind == "scalar":
            k = 1 if v.ndim == 1 else v.shape[1]
            flat = pa.array(np.ascontiguousarray(v, dtype=np.float64).reshape(-1))
        else:
            k = 1
            inner = typ.value_type
            flat = pa.FixedSizeListArray.from_arrays(
                pa.array(np.ascontiguousarray(v, dtype=np.float32).reshape(-1),
                         type=inner.value_type), type=inner)
        offsets = self._offsets.get(k)
        if offsets is None:
            offsets = self._offsets[k] = pa.array(np.arange(0, self.rows * k + 1, k, dtype=np.int32))
        self.arrays.append(pa.ListArray.from_arrays(offsets, flat, type=typ))
        key = (path, kind, typ)
        field = _FIELDS.get(key)
        if field is None:
            field = _FIELDS[key] = pa.field(f"{path}:{meta[b'rerun:component'].decode()}", typ,
                                            metadata={**meta, b"rerun:entity_path": path.encode()})
        self.fields.append(field)

    def send(self, stream: rr.RecordingStream) -> None:
        if len(self.arrays) > self._n_index:
            from rerun.chunk import Chunk

            key = tuple(map(id, self.fields))  # the fields are cached: their ids are stable
            schema = _SCHEMAS.get(key)
            if schema is None:
                if len(_SCHEMAS) >= _CACHE_MAX:
                    _SCHEMAS.clear()
                schema = _SCHEMAS[key] = self.pa.schema(self.fields)
            batch = self.pa.RecordBatch.from_arrays(self.arrays, schema=schema)
            rr.send_chunks(Chunk.from_record_batch(batch), recording=stream)


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
        rows are queued and sent 250 at a time (and by :meth:`flush` and :meth:`close`): a
        batch costs about the same whatever its length.
    footer : bool
        End the file with rerun's footer (a manifest of its chunks, for random access and
        ``rerun.chunk.RrdReader(...).store()``; about 0.1 MB and 1.3 ms at :meth:`close` for a
        10 s, 1 kHz pendulum run). ``False`` leaves a file that reads as a stream (the
        viewer, ``RrdReader(...).stream()``) but that ``rerun rrd verify`` rejects ("Missing
        RRD footer") and rerun warns about; ``rerun rrd optimize`` adds the footer later.

    Examples
    --------
    >>> with Recorder.for_trajectory("run.rrd", traj) as rec:   # doctest: +SKIP
    ...     rec.record_trajectory(traj)
    """

    def __init__(self, path: str | Path | None, *, state_names: Sequence[str],
                 output_names: Sequence[str], input_names: Sequence[str],
                 observers: Sequence[str] = (),
                 observer_states: Mapping[str, Sequence[str]] | None = None,
                 model: Any = None, joints: Sequence[str] = (),
                 params: Mapping[str, float] | None = None,
                 stream: rr.RecordingStream | None = None, application_id: str = "hgo_mj",
                 recording_name: str | None = None, pose_rate: float | None = 50.0,
                 footer: bool = True) -> None:
        self.state_names = tuple(str(s) for s in state_names)
        self.output_names = tuple(str(s) for s in output_names)
        self.input_names = tuple(str(s) for s in input_names)
        self.observers = tuple(str(o) for o in observers)
        if len(set(self.observers)) != len(self.observers):
            raise DesignError(f"observer names must be distinct; found {list(self.observers)}")
        self._names: dict[str, tuple[str, ...]] = {}  # observer -> names of its columns
        for o, names in (observer_states or {}).items():
            if str(o) not in self.observers:
                raise DesignError(f"observer_states names an unknown observer {o!r}; observers: "
                                  f"{list(self.observers)}")
            self._names[str(o)] = _estimate_names(str(o), names)
        self.params = {str(k): float(v) for k, v in (params or {}).items()
                       if isinstance(v, (int, float))}
        if pose_rate is not None and not (np.isfinite(pose_rate) and pose_rate > 0):
            raise DesignError(f"pose_rate must be a positive number or None; found {pose_rate!r}")
        self.pose_rate = pose_rate
        self.kinematics: Kinematics | None = None
        if model is not None:
            if not joints:
                raise DesignError("a model needs the joints whose positions lead x; found none")
            if 2 * len(joints) > len(self.state_names):
                raise DimensionError(f"x must hold the positions and velocities of the joints "
                                     f"{list(joints)}; found {len(self.state_names)} states")
            self.kinematics = Kinematics(model, joints)
        if stream is None:
            if path is None:
                raise DesignError("give a path for the .rrd file, or a stream with its sinks set")
            stream = rr.RecordingStream(application_id, make_default=False,
                                        make_thread_default=False, batcher_config=_BATCHER)
        elif not isinstance(stream, rr.RecordingStream):
            raise DesignError(f"stream must be a rerun.RecordingStream; found "
                              f"{type(stream).__name__}")
        self.stream = stream
        self.path = None if path is None else Path(path)
        self._own_sink = self.path is not None
        if self.path is not None:
            if self.path.suffix != ".rrd":
                raise DesignError(f"a recording path must end in .rrd; found {str(self.path)!r}")
            self.path.parent.mkdir(parents=True, exist_ok=True)
            stream.save(self.path, write_footer=bool(footer))
        if recording_name:
            stream.send_recording_name(recording_name)
        # fixed at the first block: per plant state the observers estimating it (and column),
        # per observer its columns that are not plant states
        self._est_of: list[tuple[tuple[str, int], ...]] | None = None
        self._own: dict[str, tuple[tuple[str, int], ...]] = {}
        self._diag: dict[tuple[str, str], tuple[str, str]] = {}
        self._diag_last: dict[str, float] = {}
        self._diag_pending: dict[str, float] = {}
        self._last_row: tuple[float, int, int | None] | None = None
        self._extra: dict[str, str] = {}
        self._layout: tuple[Any, ...] | None = None
        self._t_next = 0.0
        self._step_next = 0
        self._closed = False
        self._static: list[tuple[str, Any, tuple[list[Any], list[Any]]]] = []
        self._poses: list[tuple[Array, NDArray[np.int64], int | None, dict[str, Array]]] = []
        self._pose_rows = 0
        self._flushed = time.monotonic()  # the first flush 0.25 s after the start

    # ------------------------------------------------------------------ constructors
    @classmethod
    def for_plant(cls, path: str | Path | None, plant: Any, observers: Sequence[str] = (),
                  **kw: Any) -> Recorder:
        """A recorder for runs of ``plant`` (a :class:`~hgo_mj.plants.base.Plant`); MuJoCo
        plants get the 3D view from their model and ``system.joints``."""
        model = getattr(plant, "model", None)
        kw.setdefault("params", getattr(plant.system, "params", None))
        kw.setdefault("joints", plant.system.joints if model is not None else ())
        return cls(path, state_names=plant.state_names, output_names=plant.output_names,
                   input_names=plant.input_names, observers=observers, model=model, **kw)

    @classmethod
    def for_trajectory(cls, path: str | Path | None, traj: Any, *, model: Any = None,
                       joints: Sequence[str] | None = None, **kw: Any) -> Recorder:
        """A recorder for ``traj``. Without ``model``, the MJCF of the system named in
        ``traj.metadata["plant"]`` is loaded (the scenario's ``model_file`` if it names one);
        ODE systems get no 3D view."""
        meta = traj.metadata or {}
        if model is None:
            model, sys_joints = _model_for(meta)
            joints = sys_joints if joints is None else joints
        kw.setdefault("params", meta.get("system_params"))
        kw.setdefault("recording_name", meta.get("scenario"))
        kw.setdefault("observer_states", {o: tuple(getattr(r, "state_names", ()) or ())
                                          for o, r in traj.observers.items()
                                          if getattr(r, "state_names", ())})
        return cls(path, state_names=traj.state_names, output_names=traj.output_names,
                   input_names=traj.input_names, observers=list(traj.observers), model=model,
                   joints=joints or (), **kw)

    # ------------------------------------------------------------------ metadata
    def log_metadata(self, metadata: Mapping[str, Any]) -> None:
        """Log a run's metadata (scenario, seed, observer parameters, versions, ...) as the
        text document ``/scenario`` and as recording properties."""
        md = dict(metadata)
        lines = [f"# {md.get('scenario', 'run')}", ""]
        for key in ("plant", "seed", "duration", "sample_period", "control_period", "x0",
                    "sensor", "system_params"):
            if key in md:
                lines.append(f"- **{key}**: `{json.dumps(md[key], default=str)}`")
        if md.get("observers"):
            lines += ["", "## Observers", ""]
            lines += [f"- **{k}**: `{json.dumps(v, default=str)}`" for k, v in md["observers"].items()]
        if md.get("input"):
            lines += ["", f"**input**: `{json.dumps(md['input'], default=str)}`"]
        if md.get("versions"):
            lines += ["", "## Versions", ""]
            lines += [f"- {k} {v}" for k, v in md["versions"].items()]
        # strict JSON: a non-finite value is written as null (NaN is not JSON)
        lines += ["", "## All metadata", "", "```json",
                  json.dumps(strict_json(md), indent=2, default=str), "```"]
        self.stream.log("/scenario", rr.TextDocument("\n".join(lines), media_type="text/markdown"),
                        static=True, strict=True)
        props = {k: json.dumps(md[k], default=str) if not isinstance(md[k], str) else md[k]
                 for k in ("scenario", "plant", "seed", "observers", "versions") if k in md}
        if props:
            self.stream.send_property("hgo_mj", rr.AnyValues(**props))
        self._flush()

    def log_metrics(self, metrics: Mapping[str, Mapping[str, Any]]) -> None:
        """Log the metrics table (:func:`hgo_mj.metrics.format_table`) as ``/metrics``."""
        from .metrics import format_table

        text = ("# Metrics\n\nerror e = x - x_hat per observer and state\n\n```\n"
                + format_table(dict(metrics)) + "\n```\n\n```json\n"
                + json.dumps(strict_json(dict(metrics)), indent=2, default=float) + "\n```\n")
        self.stream.log("/metrics", rr.TextDocument(text, media_type="text/markdown"),
                        static=True, strict=True)
        self._flush()

    def log_episode_metrics(self, episodes: Sequence[Mapping[str, Any]]) -> None:
        """Log the metrics of an environment's episodes as ``/metrics``: a table with one row
        per episode (``episode``, ``seed``, ``steps``, ``return``, ``terminated`` and, per
        state, ``rmse``: each a key of the episode's mapping, ``rmse`` a mapping state ->
        value), then the mappings as JSON. Called at the end of every episode with all the
        episodes so far (the document is static: the last one logged is the file's)."""
        states: list[str] = []
        for ep in episodes:
            states += [s for s in ep.get("rmse", {}) if s not in states]

        def cell(v: Any) -> str:
            if isinstance(v, float):
                return f"{v:.4g}"
            return "-" if v is None else str(v)

        head = ["episode", "seed", "steps", "return", "terminated"]
        lines = ["# Metrics", "", f"{len(episodes)} episode(s); return: sum of the step rewards; "
                 "rmse: root mean square of e = x - x_hat over the episode's rows (its reset "
                 "and every step)", "",
                 "| " + " | ".join(head + [f"rmse {s}" for s in states]) + " |",
                 "|" + "---|" * (len(head) + len(states))]
        for ep in episodes:
            rmse = ep.get("rmse", {})
            lines.append("| " + " | ".join([cell(ep.get(k)) for k in head]
                                           + [cell(rmse.get(s)) for s in states]) + " |")
        lines += ["", "```json", json.dumps(strict_json([dict(ep) for ep in episodes]), indent=2,
                                               default=float), "```", ""]
        self.stream.log("/metrics", rr.TextDocument("\n".join(lines), media_type="text/markdown"),
                        static=True, strict=True)
        self._flush()

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
            :meth:`close` (blocks of one run: one Arrow batch less each).
        """
        t = np.asarray(t, dtype=float).reshape(-1)
        T = t.size
        if T == 0:
            return
        n, m, p = len(self.state_names), len(self.output_names), len(self.input_names)
        x = _columns("x", x, T, n)
        ym = _columns("y_meas", y_meas, T, m)
        yc = None if y_clean is None else _columns("y_clean", y_clean, T, m)
        u = _columns("u", u, T, p)
        given = dict(estimates or {})
        unknown = set(given) - set(self.observers)
        if unknown:
            raise DesignError(f"estimates of unknown observer(s) {sorted(unknown)}; observers: "
                              f"{list(self.observers)}")
        est = {o: _columns(f"estimate of {o!r}", given[o], T) for o in self.observers if o in given}
        names = dict(self._names)
        for o, nm in (estimate_names or {}).items():
            if str(o) not in self.observers:
                raise DesignError(f"estimate_names of unknown observer {o!r}; observers: "
                                  f"{list(self.observers)}")
            nm = _estimate_names(str(o), nm)
            if str(o) in names and self._est_of is not None and names[str(o)] != nm:
                raise DesignError(f"estimate_names of {o!r} changed from "
                                  f"{list(names[str(o)])} to {list(nm)}")
            names.setdefault(str(o), nm)
        for o in self.observers:
            if o not in names:
                w = est[o].shape[1] if o in est else n
                names[o] = (self.state_names if w == n
                            else tuple(f"x_hat_{j + 1}" for j in range(w)))
        for o, a in est.items():
            if a.shape[1] != len(names[o]):
                raise DimensionError(f"estimate of {o!r} must have shape ({T}, {len(names[o])}) "
                                     f"(columns {list(names[o])}); found {a.shape}")
        if self._est_of is None:
            self._names = names
            cols = {o: {s: j for j, s in enumerate(names[o])} for o in self.observers}
            self._est_of = [tuple((o, cols[o][s]) for o in self.observers if s in cols[o])
                            for s in self.state_names]
            plant = set(self.state_names)
            self._own = {o: tuple((s, j) for j, s in enumerate(names[o]) if s not in plant)
                         for o in self.observers}
            self._log_styles()
        diag = {o: dict(v) for o, v in (diagnostics or {}).items()}
        unknown = set(diag) - set(self.observers)
        if unknown:
            raise DesignError(f"diagnostics of unknown observer(s) {sorted(unknown)}; observers: "
                              f"{list(self.observers)}")
        for o, d in diag.items():  # checked before anything of the block is sent
            for key, v in d.items():
                d[key] = np.asarray(v, dtype=float).reshape(-1)
                if d[key].size != T:
                    raise DimensionError(f"diagnostic {key!r} of {o!r} must have {T} rows; found "
                                         f"{d[key].size}")
        extra = {name: np.asarray(v, dtype=float) for name, v in (extra or {}).items()}
        for name, v in extra.items():
            if v.ndim not in (1, 2) or v.shape[0] != T:
                raise DimensionError(f"extra {name!r} must have shape ({T},) or ({T}, k); found "
                                     f"{v.shape}")
        if step is None:
            steps = self._step_next + np.arange(T, dtype=np.int64)
        elif np.ndim(step) == 0:
            steps = int(step) + np.arange(T, dtype=np.int64)
        else:
            steps = np.asarray(step, dtype=np.int64).reshape(-1)
            if steps.size != T:
                raise DimensionError(f"step must have {T} entries; found {steps.size}")
        nj = self.kinematics.njoints if self.kinematics is not None else 0
        joint_obs = {o for i in range(nj) for o, _ in self._est_of[i]}
        posed = [o for o in self.observers if o in est and o in joint_obs]
        with _DeferSigint():
            self._register(diag, extra, posed)
            # the block's rows first (rerun's file writer, the slowest part, starts on them),
            # then styles, geometry and layout, diagnostics and poses
            self._send_rows(t, steps, episode, x, yc, ym, u, est, extra)
            self._send_static()
            self._send_blueprint()
            self._record(t, steps, episode, x, est, diag, posed, mark_end)
            self._last_row = (float(t[-1]), int(steps[-1]), episode)
            self._step_next = int(steps[-1]) + 1
            self._t_next = float(t[-1]) + (float(t[-1] - t[-2]) if T > 1 else 0.0)
            self._flush()

    def _register(self, diag: dict[str, dict[str, Any]], extra: dict[str, Any],
                  posed: list[str]) -> None:
        """Queue the styles of diagnostics and extras seen for the first time, and the ghosts
        of observers posed for the first time."""
        for o, d in diag.items():
            for key in d:
                self._register_diagnostic(o, str(key))
        for name in extra:
            if name not in self._extra:
                path = self._extra[name] = f"/env/{_part(name)}"
                self._lines(path, [name], [EXTRA_COLOR])
        if self.kinematics is not None:
            for o in posed:
                if o not in self._ghosts:  # drawn from its first pose on (never at the origin)
                    self._ghosts.add(o)
                    self._log_shapes(f"/world/estimate/{_part(o)}",
                                     observer_color(self.observers.index(o)))

    def _register_diagnostic(self, o: str, key: str) -> tuple[str, str]:
        """Path and kind of a diagnostic, its style queued the first time."""
        ident = (o, key)
        if ident not in self._diag:
            path, kind = diagnostic_path(o, key, tuple(self.params))
            self._diag[ident] = (path, kind)
            i = self.observers.index(o)
            self._lines(path, [f"{o} {key}"], [observer_color(i)], interpolation_mode="StepAfter")
            if kind == "theta" and _theta_param(path) in self.params:
                param = _theta_param(path)
                self._lines(f"/plant/param/{param}", [f"{param} true"], [TRUE_COLOR],
                            interpolation_mode="StepAfter")
        return self._diag[ident]

    def _send_rows(self, t: Array, steps: NDArray[np.int64], episode: int | None, x: Array,
                   yc: Array | None, ym: Array, u: Array, est: dict[str, Array],
                   extra: dict[str, Any]) -> None:
        """Send the block's states, estimates, errors, outputs, inputs and extras (one row a
        sample) as one batch."""
        batch = _Batch(t, steps, episode)
        est_of = self._est_of or []
        nan = np.full(t.size, np.nan)
        for i, s in enumerate(self.state_names):
            # an observer without an estimate in this block: NaN, and no ghost pose
            ests = [est[o][:, j] if o in est else nan for o, j in est_of[i]]
            batch.add(f"/state/{_part(s)}", "scalar", np.column_stack([x[:, i]] + ests))
            if ests:
                batch.add(f"/error/{_part(s)}", "scalar",
                          np.column_stack([x[:, i] - e for e in ests]))
        for o, own in self._own.items():
            if o in est:  # estimates that are not plant states: under the observer's names
                for name, j in own:
                    batch.add(f"/observer/{_part(o)}/estimate/{_part(name)}", "scalar",
                              est[o][:, j])
        for j, name in enumerate(self.output_names):
            clean = yc[:, j] if yc is not None else np.full(t.size, np.nan)
            batch.add(f"/sensor/{_part(name)}", "scalar", np.column_stack((clean, ym[:, j])))
        for j, name in enumerate(self.input_names):
            batch.add(f"/input/{_part(name)}", "scalar", u[:, j])
        for name, v in extra.items():
            batch.add(self._extra[name], "scalar", v)  # registered by _register
        batch.send(self.stream)

    def _record(self, t: Array, steps: NDArray[np.int64], episode: int | None, x: Array,
                est: dict[str, Array], diag: dict[str, dict[str, Any]], posed: list[str],
                mark_end: bool) -> None:
        """Queue and send the block's diagnostics (where they change) and poses."""
        est_of = self._est_of or []
        sparse: dict[bytes, tuple[NDArray[np.bool_], list[tuple[str, Array]]]] = {}
        for o, d in diag.items():
            for key, v in d.items():
                self._record_diagnostic(o, str(key), t.size, v, mark_end, sparse)
        for mask, series in sparse.values():
            b = _Batch(t[mask], steps[mask], episode)
            for path, values in series:
                b.add(path, "scalar", values)
            b.send(self.stream)
        if self.kinematics is not None:
            nj = self.kinematics.njoints
            q: dict[str, Array] = {}
            for o in posed:  # the joint positions on the plant's columns, NaN where not named
                q[o] = np.full((t.size, nj), np.nan)
                for i in range(nj):
                    for oi, j in est_of[i]:
                        if oi == o:
                            q[o][:, i] = est[o][:, j]
            self._record_poses(t, steps, episode, x, q)

    def _record_diagnostic(self, o: str, key: str, rows: int, v: Any, mark_end: bool,
                           sparse: dict[bytes, tuple[NDArray[np.bool_], list[tuple[str, Array]]]]
                           ) -> None:
        """Queue a diagnostic (and the true parameter next to a parameter estimate)."""
        path, kind = self._register_diagnostic(o, key)
        self._sparse(path, v, mark_end, sparse)
        if kind == "theta" and _theta_param(path) in self.params:
            param = _theta_param(path)
            self._sparse(f"/plant/param/{param}", np.full(rows, self.params[param]), mark_end,
                         sparse)

    def _sparse(self, path: str, v: Array, mark_end: bool,
                sparse: dict[bytes, tuple[NDArray[np.bool_], list[tuple[str, Array]]]]) -> None:
        """Queue the rows of a piecewise-constant series where it changes (drawn as steps),
        and its last row when ``mark_end`` (else that row waits for :meth:`close`); rows are
        grouped by mask, one batch each. A series queued twice in a block is kept once."""
        if any(p == path for group in sparse.values() for p, _ in group[1]):
            return
        last = self._diag_last.get(path)
        if last is not None and not mark_end:  # fast path: unchanged through the block
            same = np.isnan(v).all() if np.isnan(last) else bool((v == last).all())
            if same:
                self._diag_pending[path] = last
                return
        prev = np.empty_like(v)
        prev[0] = self._diag_last.get(path, np.nan)
        prev[1:] = v[:-1]
        keep = ~((v == prev) | (np.isnan(v) & np.isnan(prev)))
        if path not in self._diag_last:
            keep[0] = True
        keep[-1] |= mark_end
        self._diag_last[path] = float(v[-1])
        if keep[-1]:
            self._diag_pending.pop(path, None)
        else:
            self._diag_pending[path] = float(v[-1])
        if keep.any():
            sparse.setdefault(keep.tobytes(), (keep, []))[1].append((path, v[keep]))

    def _send_pending(self) -> None:
        """Log the last row of every piecewise-constant series whose end is still pending."""
        if self._diag_pending and self._last_row is not None:
            t, step, episode = self._last_row
            batch = _Batch(np.array([t]), np.array([step], dtype=np.int64), episode)
            for path, value in self._diag_pending.items():
                batch.add(path, "scalar", np.array([value]))
            self._diag_pending.clear()
            batch.send(self.stream)

    def _record_poses(self, t: Array, steps: NDArray[np.int64], episode: int | None, x: Array,
                      est: dict[str, Array]) -> None:
        """Queue the joint positions of the block's pose rows (``pose_rate``); they are posed
        and sent :data:`_POSE_ROWS` rows at a time (a batch costs about 0.5 ms whatever its
        length), and the rest by :meth:`flush` or :meth:`close`."""
        kin = self.kinematics
        assert kin is not None
        if self.pose_rate is None or t.size < 2:
            sel = np.ones(t.size, dtype=bool)
        else:
            dt = float(np.median(np.diff(t)))
            stride = max(int(round(1.0 / (self.pose_rate * dt))), 1) if dt > 0 else 1
            sel = steps % stride == 0
            sel[-1] = True  # the block's last sample, so the 3D view ends where the run does
        nj = kin.njoints
        q_true = x[sel, :nj]
        sets = {"/world/true": q_true}
        for o in est:
            q = est[o][sel, :nj].copy()
            bad = ~np.isfinite(q)
            q[bad] = q_true[bad]  # an undefined estimate puts the ghost's joint on the truth
            sets[f"/world/estimate/{_part(o)}"] = q  # its ghost: queued by _register
        buf = self._poses
        if buf and (buf[0][2] != episode or set(buf[0][3]) != set(sets)):
            self._send_poses()
        self._poses.append((t[sel], steps[sel], episode, sets))
        self._pose_rows += int(sel.sum())
        if self._pose_rows >= _POSE_ROWS:
            self._send_poses()

    def _send_poses(self) -> None:
        """Pose the queued rows (all sets of joint positions in one pass) and send them."""
        if not self._poses:
            return
        kin = self.kinematics
        assert kin is not None
        queued, self._poses, self._pose_rows = self._poses, [], 0
        roots = list(queued[0][3])
        t = np.concatenate([b[0] for b in queued])
        steps = np.concatenate([b[1] for b in queued])
        rows = t.size
        qs = [np.concatenate([b[3][r] for b in queued]) for r in roots]
        bodies = np.flatnonzero(kin.moving & self._drawn)
        batch = _Batch(t, steps, queued[0][2])
        pos, quat = kin.poses(np.concatenate(qs))  # all sets in one pass
        for i, root in enumerate(roots):
            part = slice(i * rows, (i + 1) * rows)
            for b in bodies:
                path = f"{root}/{self._body_names[b]}"
                batch.add(path, "translation", pos[b][part])
                batch.add(path, "quaternion", _xyzw(quat[b][part]))
        batch.send(self.stream)

    # ------------------------------------------------------------------ styles and layout
    def _static_log(self, path: str, archetype: Any, key: Any = None) -> None:
        """Queue static data (styles, geometry); :meth:`_send_static` sends the queue at once.

        ``archetype`` is an archetype or a function making one; with a ``key`` (hashable,
        determining the archetype) its Arrow columns are converted once per process and reused
        (rerun's archetype classes cost tens of microseconds each to build and convert)."""
        cols = _STATIC_CACHE.get((path, key)) if key is not None else None
        if cols is None:
            cols = _static_columns(path, archetype() if callable(archetype) else archetype)
            if key is not None:
                if len(_STATIC_CACHE) >= _CACHE_MAX:
                    _STATIC_CACHE.clear()
                _STATIC_CACHE[(path, key)] = cols
        self._static.append((path, key, cols))

    def _lines(self, path: str, names: Sequence[str], colors: Sequence[Any],
               widths: Sequence[float] | None = None, interpolation_mode: str | None = None) -> None:
        """Queue the static series style of ``path`` (cached, see :meth:`_static_log`)."""
        names, colors = tuple(names), tuple(tuple(c) for c in colors)
        widths = None if widths is None else tuple(widths)
        kw: dict[str, Any] = {} if widths is None else {"widths": list(widths)}
        if interpolation_mode is not None:
            kw["interpolation_mode"] = interpolation_mode
        self._static_log(path, lambda: rr.SeriesLines(names=list(names), colors=list(colors), **kw),
                         key=("SeriesLines", names, colors, widths, interpolation_mode))

    def _send_static(self) -> None:
        """Send the queued static data as one Arrow record batch (one call, not one a log)."""
        if not self._static:
            return
        import pyarrow as pa
        from rerun.chunk import Chunk

        queued, self._static = self._static, []
        key = tuple((path, k) for path, k, _ in queued)
        chunks = _STATIC_CHUNKS.get(key) if all(k is not None for _, k in key) else None
        if chunks is None:
            fields, arrays = [], []
            for _, _, (f, a) in queued:
                fields += f
                arrays += a
            batch = pa.RecordBatch.from_arrays(arrays, schema=pa.schema(fields))
            chunks = Chunk.from_record_batch(batch, index=None)
            if all(k is not None for _, k in key):
                if len(_STATIC_CHUNKS) >= 64:
                    _STATIC_CHUNKS.clear()
                _STATIC_CHUNKS[key] = chunks
        rr.send_chunks(chunks, recording=self.stream)

    def _log_styles(self) -> None:
        for s, ests in zip(self.state_names, self._est_of or []):
            obs = [o for o, _ in ests]
            colors = [observer_color(self.observers.index(o)) for o in obs]
            self._lines(f"/state/{_part(s)}", [f"{s} true"] + [f"{s} {o}" for o in obs],
                        [TRUE_COLOR] + colors, widths=[2.0] + [1.0] * len(obs))
            if obs:
                self._lines(f"/error/{_part(s)}", [f"{s} error {o}" for o in obs], colors)
        for o, own in self._own.items():
            for name, _ in own:
                self._lines(f"/observer/{_part(o)}/estimate/{_part(name)}", [f"{name} {o}"],
                            [observer_color(self.observers.index(o))])
        for name in self.output_names:
            self._lines(f"/sensor/{_part(name)}", [f"{name} clean", f"{name} measured"],
                        [TRUE_COLOR, MEASURED_COLOR], widths=[1.5, 1.0])
        for name in self.input_names:
            self._lines(f"/input/{_part(name)}", [name], [INPUT_COLOR])
        if self.kinematics is not None:
            self._log_geometry()

    def _log_geometry(self) -> None:
        kin = self.kinematics
        assert kin is not None
        m = kin.model
        self._body_names = [_part(m.body(b).name or f"body{b}") for b in range(m.nbody)]
        drawn = np.zeros(m.nbody, dtype=bool)
        geoms: list[tuple[int, int, NDArray[np.float64]]] = []
        for g in range(m.ngeom):
            rgba = _geom_color(m, g)
            if rgba[3] <= 0 or m.geom_group[g] > 2:  # what MuJoCo's viewer hides by default
                continue
            b = int(m.geom_bodyid[g])
            geoms.append((g, b, rgba))
            drawn[b] = True
        self._drawn = drawn
        self._static_log("/world", lambda: rr.ViewCoordinates.RIGHT_HAND_Z_UP, key="RIGHT_HAND_Z_UP")
        pos0, quat0 = kin.poses(np.zeros((1, kin.njoints)))  # static bodies ignore the joints
        for b in np.flatnonzero(drawn & ~kin.moving):  # static bodies: posed once
            self._transform(f"/world/true/{self._body_names[b]}", pos0[b][0], quat0[b][0])
        self._geoms = geoms
        self._ghosts: set[str] = set()
        self._log_shapes("/world/true", None)

    def _log_shapes(self, root: str, color: tuple[int, int, int] | None) -> None:
        """Log the geometry under ``root``: solid in the model's colours (``color=None``), or a
        translucent ghost of the moving bodies in ``color``."""
        kin = self.kinematics
        assert kin is not None
        m = kin.model
        fill = (rr.components.FillMode.Solid if color is None
                else rr.components.FillMode.TransparentFillMajorWireframe)
        for g, b, rgba in self._geoms:
            if color is not None and not kin.moving[b]:
                continue  # a ghost of what does not move would sit on the truth
            col = (np.round(rgba * 255).astype(int).tolist() if color is None
                   else [*color, GHOST_ALPHA])
            path = f"{root}/{self._body_names[b]}/{_part(m.geom(g).name or f'geom{g}')}"
            key = _geom_key(m, g, col, fill)  # primitives: cached, always drawn
            shape: Any = (lambda g=g, col=col: _geom_shape(m, g, col, fill)) if key else None
            if key is None:
                shape = _geom_shape(m, g, col, fill)
                if shape is None:
                    continue  # height fields, SDFs
            self._transform(path, m.geom_pos[g], m.geom_quat[g])
            self._static_log(path, shape, key=key)

    def _transform(self, path: str, pos: Any, quat: Any) -> None:
        """Queue the static pose ``pos``, ``quat`` (``w, x, y, z``) of ``path`` (cached)."""
        pos, quat = np.array(pos, dtype=float), np.array(quat, dtype=float)
        self._static_log(path, lambda: rr.Transform3D(
            translation=pos, quaternion=rr.Quaternion(xyzw=_xyzw(quat))),
            key=("Transform3D", tuple(pos.tolist()), tuple(quat.tolist())))

    def blueprint(self) -> rrb.Blueprint:
        """The default layout: 3D view and text documents, one view per state (truth and
        estimates), one per state's errors, adaptive quantities, inputs and measurements."""
        est_of = self._est_of or [()] * len(self.state_names)
        states = [rrb.TimeSeriesView(origin=f"/state/{_part(s)}", name=f"{s}: true vs estimated")
                  for s in self.state_names]
        states += [rrb.TimeSeriesView(origin=f"/observer/{_part(o)}/estimate",
                                      name=f"{o}: estimates that are not plant states")
                   for o, own in self._own.items() if own]
        errors = [rrb.TimeSeriesView(origin=f"/error/{_part(s)}", name=f"{s}: error x - x_hat")
                  for s, ests in zip(self.state_names, est_of) if ests]
        gains = [p for p, k in self._diag.values() if k == "gain"]
        thetas: dict[str, list[str]] = {}
        other = [p for p, k in self._diag.values() if k == "other"]
        for p, k in self._diag.values():
            if k == "theta":
                thetas.setdefault(_theta_param(p), []).append(p)
        side: list[Any] = []
        if gains:
            side.append(rrb.TimeSeriesView(origin="/observer", contents=gains, name="gains"))
        for param, paths in thetas.items():
            true = [f"/plant/param/{param}"] if param in self.params else []
            side.append(rrb.TimeSeriesView(origin="/observer", contents=true + paths,
                                           name=f"{param}: true vs estimated"))
        if other:
            side.append(rrb.TimeSeriesView(origin="/observer", contents=other,
                                           name="other diagnostics"))
        side.append(rrb.TimeSeriesView(origin="/input", name="inputs"))
        side.append(rrb.TimeSeriesView(origin="/sensor", name="outputs: clean and measured"))
        if self._extra:
            side.append(rrb.TimeSeriesView(origin="/env", name="environment"))
        docs = rrb.Tabs(rrb.TextDocumentView(origin="/metrics", name="metrics"),
                        rrb.TextDocumentView(origin="/scenario", name="scenario"))
        if self.kinematics is not None:
            left: Any = rrb.Vertical(
                rrb.Spatial3DView(origin="/world", name="robot: true (solid), estimates (ghosts)"),
                docs, row_shares=[3, 2])
        else:
            left = docs
        columns: list[Any] = [left, rrb.Vertical(*states, name="states")]
        if errors:
            columns.append(rrb.Vertical(*errors, name="errors"))
        columns.append(rrb.Vertical(*side, name="adaptive, inputs, outputs"))
        return rrb.Blueprint(rrb.Horizontal(*columns), rrb.TimePanel(timeline=SIM_TIME))

    def _send_blueprint(self) -> None:
        """Send :meth:`blueprint` as the recording's default layout, once per layout (a new
        diagnostic or extra estimate changes it)."""
        layout = (tuple(self._diag.values()), tuple(self._extra))
        if layout == self._layout:
            return
        self._layout = layout
        self.stream.send_blueprint(self.blueprint(), make_active=True, make_default=True)

    # ------------------------------------------------------------------ whole runs
    def record_trajectory(self, traj: Any, *, metrics: bool | Mapping[str, Any] = True,
                          chunk_seconds: float | None = None) -> None:
        """Record a whole :class:`~hgo_mj.simulate.Trajectory`: its metadata, its rows (in
        blocks of ``chunk_seconds`` of simulated time, default one block) and its metrics
        (computed with :func:`hgo_mj.metrics.all_metrics` when ``metrics=True``)."""
        rows = len(traj)
        block = rows
        if chunk_seconds is not None and rows > 1:
            block = max(int(round(chunk_seconds / float(traj.t[1] - traj.t[0]))), 1)
        for k0 in range(0, rows, block):
            self.write_chunk(0, traj, slice(k0, min(k0 + block, rows)), mark_end=k0 + block >= rows)
        if traj.metadata:  # after the rows: built while rerun's threads encode them
            self.log_metadata(traj.metadata)
        if metrics is True and traj.observers:
            from .metrics import all_metrics

            metrics = all_metrics(traj)
        if metrics:
            self.log_metrics(metrics)  # type: ignore[arg-type]

    def write_chunk(self, first_row: int, chunk: Any, rows: slice = slice(None), *,
                    mark_end: bool = False) -> None:
        """Record rows of a :class:`~hgo_mj.simulate.Trajectory` whose first row is the run's
        row ``first_row`` (the ``step`` timeline). This is the ``simulate(on_chunk=...)``
        callback: ``simulate(..., on_chunk=(1.0, recorder.write_chunk))``; the diagnostics'
        last row waits for the next chunk or :meth:`close` (see :meth:`record`)."""
        obs = chunk.observers
        missing = [o for o in self.observers if o not in obs]
        if missing:
            raise DesignError(f"the trajectory lacks the observer(s) {missing}; found {list(obs)}")
        self.record(chunk.t[rows], chunk.x[rows], chunk.y_clean[rows], chunk.y_meas[rows],
                    chunk.u[rows], {o: obs[o].x_hat[rows] for o in self.observers},
                    {o: {k: v[rows] for k, v in obs[o].diagnostics.items()} for o in self.observers},
                    step=first_row + (rows.start or 0), mark_end=mark_end,
                    estimate_names={o: obs[o].state_names for o in self.observers
                                    if getattr(obs[o], "state_names", ())})

    def record_episode(self, episode: int, t: Any, x: Any, y_meas: Any, u: Any, *,
                       y_clean: Any = None, estimates: Mapping[str, Any] | None = None,
                       diagnostics: Mapping[str, Mapping[str, Any]] | None = None,
                       extra: Mapping[str, Any] | None = None) -> None:
        """Record one environment episode from numpy arrays, batched, at its end.

        Episodes follow each other on ``sim_time`` and ``step`` (each placed after the last,
        whatever its own ``t`` starts at); the ``episode`` timeline holds ``episode``. Arrays
        as in :meth:`record`; ``extra`` (reward, ...) goes under ``/env/<name>``.
        """
        t = np.asarray(t, dtype=float).reshape(-1)
        if t.size == 0:
            return
        self.record(t - t[0] + self._t_next, x, y_clean, y_meas, u, estimates, diagnostics,
                    step=self._step_next, episode=int(episode), extra=extra)

    # ------------------------------------------------------------------ lifetime
    def _flush(self) -> None:
        """After a block: start a flush to the file without waiting for it, at most every
        0.25 s of wall time (rerun's own thread writes each block within a few milliseconds
        anyway; a flush costs about 0.5 ms). A run killed part-way leaves every block before
        the last in the file (the 3D poses are sent every few blocks, see ``pose_rate``);
        :meth:`close` always waits."""
        now = time.monotonic()
        if now - self._flushed >= _FLUSH_INTERVAL:
            self._flushed = now
            self.stream.flush(timeout_sec=0.0)

    def flush(self) -> None:
        """Send the queued poses and wait until everything recorded so far is written."""
        with _DeferSigint():
            self._send_poses()
        self.stream.flush()

    def close(self) -> None:
        """Log what is pending, flush and close the file (idempotent). A stream handed in
        without a path is flushed, not disconnected."""
        if not self._closed:
            self._closed = True
            self._send_poses()
            self._send_pending()
            if self._own_sink:  # flushes the batcher, then the file sink writes the rest,
                self.stream.disconnect()  # its footer, and closes the file before returning
            else:
                self.stream.flush()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


def _model_for(meta: Mapping[str, Any]) -> tuple[Any, tuple[str, ...]]:
    """The MJCF model and joints of the system a trajectory's metadata names, or ``None``."""
    from .systems import SYSTEMS

    cls = next((c for c in SYSTEMS.values() if c.__name__ == meta.get("plant")), None)
    if cls is None or cls.model_file is None:
        return None, ()
    import mujoco

    from .plants.mujoco import model_path

    spec = meta.get("scenario_spec") or {}
    model_file = (spec.get("plant", {}).get("params", {}) or {}).get("model_file")
    path = Path(model_file) if model_file else model_path(cls.model_file)
    try:
        st = path.stat()
    except OSError:
        return mujoco.MjModel.from_xml_path(str(path)), tuple(cls.joints)  # mujoco's own error
    key = (str(path.resolve()), st.st_mtime_ns, st.st_size)
    model = _MODELS.get(key)
    if model is None:  # compiled once per process (about 1 ms); the recorder only reads it
        if len(_MODELS) >= 64:
            _MODELS.clear()
        model = _MODELS[key] = mujoco.MjModel.from_xml_path(str(path))
    return model, tuple(cls.joints)


#: (MJCF path, mtime, size) -> the compiled model, for :func:`_model_for`
_MODELS: dict[tuple[str, int, int], Any] = {}


def record_trajectory(traj: Any, path: str | Path, *, model: Any = None,
                      metrics: bool | Mapping[str, Any] = True, **kw: Any) -> Path:
    """Write ``traj`` to the recording ``path`` (see :class:`Recorder`); returns the path."""
    with Recorder.for_trajectory(path, traj, model=model, **kw) as rec:
        rec.record_trajectory(traj, metrics=metrics)
    return Path(path)


__all__ = ["Recorder", "Kinematics", "record_trajectory", "diagnostic_path", "observer_color",
           "SIM_TIME", "STEP", "EPISODE"]
