"""The 3D view of a MuJoCo plant: its geometry as rerun archetypes, posed as MuJoCo poses it.

:class:`Poses` poses every body for the recorded joint positions (every other joint at the
model's ``qpos0``) by the steps of ``mujoco.mj_kinematics`` in numpy, all rows at once: the
bodies the joints do not move once, at ``qpos0``, the moving ones per row, for the true
state and for each observer's estimate (its translucent ghost). The poses are MuJoCo's
``xpos``/``xquat`` to rounding (tested against ``mj_kinematics`` on every shipped model). A
row costs about 0.2 us (pendulum; a loop over ``mj_kinematics`` cost 1 us); poses are
logged at ``pose_rate`` (50 Hz by default), so a 10 s run poses about 500 rows per set.

Each drawn geom is one entity below its body: a static ``Transform3D`` (its pose in the body
frame) and its shape; a body the joints move gets a ``Transform3D`` per pose row.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr
from numpy.typing import NDArray

from .._binding import Binding
from ..exceptions import DesignError
from ..models import model_path
from .layout import GHOST_ALPHA, TRUE_ROOT, body_path, geom_path

Array = NDArray[np.float64]


def xyzw(q: Any) -> Array:
    """Quaternions ``w, x, y, z`` (MuJoCo) as ``x, y, z, w`` (rerun), last axis."""
    q = np.asarray(q, dtype=float)
    return np.concatenate((q[..., 1:], q[..., :1]), axis=-1)


@dataclass(frozen=True)
class Geom:
    """A drawn geom: its index, body, entity name, colour (RGBA in 0..1) and pose in the body
    frame (``quat`` as ``w, x, y, z``).

    Parameters
    ----------
    index : int
        The geom's id in the model.
    body : int
        The id of the body it belongs to.
    name : str
        Its entity name (the MJCF name, ``geom<i>`` for an unnamed one).
    rgba : ndarray, shape (4,)
        The colour MuJoCo draws it in, 0..1.
    pos : ndarray, shape (3,)
        Position in the body frame (model units, m).
    quat : ndarray, shape (4,)
        Orientation in the body frame, ``w, x, y, z``.

    Examples
    --------
    >>> from hgo_mj.plants import make_plant
    >>> geom = Poses(make_plant("pendulum", 0.01).model, ["hinge"]).geoms[0]
    >>> geom.index, geom.body, geom.name, geom.quat.tolist()
    (0, 0, 'mount', [1.0, 0.0, 0.0, 0.0])
    """

    index: int
    body: int
    name: str
    rgba: Array
    pos: Array
    quat: Array


def geom_color(model: Any, g: int) -> Array:
    """The RGBA colour (0..1) MuJoCo draws geom ``g`` in: its own, else its material's."""
    rgba = np.array(model.geom_rgba[g], dtype=float)
    if model.geom_matid[g] >= 0 and np.allclose(rgba, (0.5, 0.5, 0.5, 1.0)):
        rgba = np.array(model.mat_rgba[model.geom_matid[g]], dtype=float)
    return rgba


def drawn_geoms(model: Any) -> list[Geom]:
    """The geoms MuJoCo's viewer shows by default (visible, in groups 0 to 2)."""
    out = []
    for g in range(model.ngeom):
        rgba = geom_color(model, g)
        if rgba[3] <= 0 or model.geom_group[g] > 2:
            continue
        out.append(Geom(g, int(model.geom_bodyid[g]), model.geom(g).name or f"geom{g}", rgba,
                        np.array(model.geom_pos[g], dtype=float),
                        np.array(model.geom_quat[g], dtype=float)))
    return out


def geom_shape(model: Any, g: int, rgba: Sequence[int], fill: Any) -> Any:
    """The rerun archetype of geom ``g`` in its own frame (colour ``rgba`` in 0..255), or
    ``None`` for a type not drawn (height fields, SDFs)."""
    import mujoco

    kind = int(model.geom_type[g])
    if kind == mujoco.mjtGeom.mjGEOM_MESH:
        if model.geom_dataid[g] < 0:
            return None
        k = model.geom_dataid[g]
        v0, nv = model.mesh_vertadr[k], model.mesh_vertnum[k]
        f0, nf = model.mesh_faceadr[k], model.mesh_facenum[k]
        return rr.Mesh3D(vertex_positions=np.array(model.mesh_vert[v0:v0 + nv]),
                         triangle_indices=np.array(model.mesh_face[f0:f0 + nf]),
                         albedo_factor=list(rgba))
    return _primitive(kind, tuple(float(v) for v in model.geom_size[g]), tuple(rgba), fill)


@lru_cache(maxsize=1024)
def _primitive(kind: int, size_: tuple[float, ...], rgba: tuple[int, ...], fill: Any) -> Any:
    """A primitive geom's archetype (built once per process for each shape, colour and fill:
    the same in every recording of a model)."""
    import mujoco

    t = mujoco.mjtGeom
    size, col = np.array(size_), [list(rgba)]
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
    return None  # height fields, SDFs


def transform(pos: Any, quat: Any) -> rr.Transform3D:
    """A rerun transform from a MuJoCo position and quaternion (``w, x, y, z``)."""
    return _transform(tuple(float(v) for v in pos), tuple(float(v) for v in quat))


@lru_cache(maxsize=1024)
def _transform(pos: tuple[float, ...], quat: tuple[float, ...]) -> rr.Transform3D:
    return rr.Transform3D(translation=np.array(pos), quaternion=rr.Quaternion(xyzw=xyzw(quat)))


#: a joint of :func:`_chain`: type, axis, anchor, column of ``q`` (None: at ``qpos0``), its
#: ``qpos0`` entries (up to 7)
_Joint = tuple[int, Array, Array, "int | None", Array]
#: a body of :func:`_chain`: id, parent, position and quaternion in the parent, joints
_Body = tuple[int, int, Array, Array, list[_Joint]]


def _chain(model: Any, bodies: Any, column: Mapping[int, int]) -> list[_Body]:
    """``bodies`` (ascending ids: a parent before its children) as :func:`_pose` takes them;
    ``column`` maps a joint's ``qpos`` address to its column of ``q``."""
    out = []
    for b in bodies:
        joints: list[_Joint] = []
        for j in range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b]):
            adr = int(model.jnt_qposadr[j])
            joints.append((int(model.jnt_type[j]), np.array(model.jnt_axis[j]),
                           np.array(model.jnt_pos[j]), column.get(adr),
                           np.array(model.qpos0[adr:adr + 7])))
        out.append((int(b), int(model.body_parentid[b]), np.array(model.body_pos[b]),
                    np.array(model.body_quat[b]), joints))
    return out


def _pose(chain: list[_Body], pos: Array, quat: Array, q: Array) -> tuple[Array, Array]:
    """Pose the bodies of ``chain`` in ``pos`` ``(T, nbody, 3)`` and ``quat`` ``(T, nbody,
    4)``, their parents posed already, for the joint positions ``q`` ``(T, columns)``: the
    steps of ``mj_kinematics`` (MuJoCo's ``engine_core_smooth.c``) on all rows at once."""
    import mujoco

    kinds = mujoco.mjtJoint
    for b, parent, body_pos, body_quat, joints in chain:
        if joints and joints[0][0] == kinds.mjJNT_FREE:  # its pose is its qpos0
            xpos = np.broadcast_to(joints[0][4][:3], pos[:, b].shape)
            xquat = np.broadcast_to(joints[0][4][3:7], quat[:, b].shape)
        else:
            xpos = pos[:, parent] + _rotate(quat[:, parent], body_pos)
            xquat = _mul(quat[:, parent], body_quat)
        for kind, axis, anchor, col, qpos0 in joints:
            if kind == kinds.mjJNT_SLIDE and col is not None:
                xpos = xpos + _rotate(xquat, axis) * (q[:, col] - qpos0[0])[:, None]
                continue
            if kind == kinds.mjJNT_BALL:
                local = qpos0[:4] / np.linalg.norm(qpos0[:4])
            elif kind == kinds.mjJNT_HINGE and col is not None:
                half = 0.5 * (q[:, col] - qpos0[0])
                local = np.concatenate((np.cos(half)[:, None], np.sin(half)[:, None] * axis),
                                       axis=1)
            else:  # a slide or hinge at qpos0 moves nothing; a free joint is done
                continue
            xanchor = xpos + _rotate(xquat, anchor)
            xquat = _mul(xquat, local)
            xpos = xanchor - _rotate(xquat, anchor)  # turned about the anchor
        pos[:, b] = xpos
        quat[:, b] = xquat / np.linalg.norm(xquat, axis=-1, keepdims=True)
    return pos, quat


def _mul(a: Any, b: Any) -> Array:
    """Quaternion products ``a b`` (``w, x, y, z``, last axis; either may be one quaternion)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack((aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw),
                    axis=-1)


def _rotate(quat: Array, v: Any) -> Array:
    """The vector ``v`` (3,) rotated by each unit quaternion of ``quat`` (T, 4)."""
    u, w = quat[:, 1:], quat[:, :1]
    t = 2.0 * np.cross(u, np.asarray(v, dtype=float))
    return np.asarray(v, dtype=float) + w * t + np.cross(u, t)


class Poses:
    """World poses of a MuJoCo model's bodies at recorded joint positions (the steps of
    ``mujoco.mj_kinematics``, for many rows at once), and the model's geometry as rerun
    archetypes.

    Parameters
    ----------
    model : mujoco.MjModel
        The compiled model (only read).
    joints : sequence of str
        Hinge or slide joints whose positions :meth:`poses` takes, in order
        (``System.joints``); every other joint stays at ``qpos0``.

    Attributes
    ----------
    moving : ndarray of bool, shape (nbody,)
        The bodies the joints move (a body of a joint, and every body below it).
    geoms : list of Geom
        The drawn geoms (:func:`drawn_geoms`).
    body_names : list of str
        Entity names of the bodies (``body<i>`` for an unnamed one).

    Raises
    ------
    DesignError
        ``model`` has no joint of one of the names (a :class:`~hgo_mj.exceptions.ModelError`
        listing its joints), or one of them is neither a hinge nor a slide joint.

    Examples
    --------
    >>> from hgo_mj.plants import make_plant
    >>> scene = Poses(make_plant("pendulum", 0.01).model, ["hinge"])
    >>> scene.body_names, scene.moving.tolist(), [g.name for g in scene.geoms]
    (['world', 'pole'], [False, True], ['mount', 'rod', 'bob'])
    >>> Poses(make_plant("pendulum", 0.01).model, ["elbow"])
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.ModelError: the model has no joint named 'elbow'; its joint names: ['hinge']
    """

    def __init__(self, model: Any, joints: Sequence[str]) -> None:
        import mujoco

        self.model = model
        self.joints = tuple(joints)
        self.njoints = len(self.joints)
        hinge, slide = int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)
        names = Binding(model)
        bodies = set()
        for name in self.joints:
            j = names.id("joint", name)
            jtype = int(model.jnt_type[j])
            if jtype not in (hinge, slide):
                raise DesignError(f"joint {name!r} must be a hinge or slide joint to be posed; "
                                  f"found {mujoco.mjtJoint(jtype).name}")
            bodies.add(int(model.jnt_bodyid[j]))
        moving = np.zeros(model.nbody, dtype=bool)
        for b in range(1, model.nbody):  # a parent's id is below its children's
            moving[b] = moving[model.body_parentid[b]] or b in bodies
        self.moving = moving
        self.body_names = [model.body(b).name or f"body{b}" for b in range(model.nbody)]
        self.geoms = drawn_geoms(model)
        self.drawn = np.zeros(model.nbody, dtype=bool)
        self.drawn[[g.body for g in self.geoms]] = True
        column = {int(model.jnt_qposadr[names.id("joint", j)]): c
                  for c, j in enumerate(self.joints)}
        #: every body at ``qpos0`` (its joints' columns not used), then the moving ones
        self._chain0 = _chain(model, range(1, model.nbody), {})
        self._chain = _chain(model, np.flatnonzero(moving), column)
        pos0, quat0 = np.zeros((1, model.nbody, 3)), np.zeros((1, model.nbody, 4))
        quat0[:, 0, 0] = 1.0
        self._pos0, self._quat0 = _pose(self._chain0, pos0, quat0, np.zeros((1, 0)))

    def poses(self, q: Any) -> tuple[Array, Array]:
        """World positions ``(T, nbody, 3)`` and quaternions ``(T, nbody, 4)`` (``w, x, y,
        z``) of every body for the joint positions ``q`` of shape ``(T, len(joints))``.

        The bodies are posed for all rows at once by the steps of ``mujoco.mj_kinematics``
        in numpy: a body's frame in its parent's, then each of its joints about its anchor
        (a hinge turns by ``q - qpos0`` about its axis, a slide moves along it; a joint not
        in ``joints``, a ball or free joint stays at ``qpos0``); the bodies the joints do not
        move are posed once, when the scene is made. About 0.2 us a row (pendulum) where a
        loop over ``mj_kinematics`` took 1 us; the result equals MuJoCo's to rounding (tested
        to 1e-14 against ``mj_kinematics``).

        Parameters
        ----------
        q : array_like, shape (T, len(joints))
            Joint positions (rad for a hinge, m for a slide), one row per pose; any shape
            that reshapes to it.

        Returns
        -------
        pos : ndarray, shape (T, nbody, 3)
            World positions of the bodies' frames (``xpos``).
        quat : ndarray, shape (T, nbody, 4)
            World orientations (``xquat``, ``w, x, y, z``).

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", 0.01)
        >>> scene = Poses(plant.model, plant.system.joints)
        >>> pos, quat = scene.poses([[0.0], [np.pi / 2]])
        >>> pos.shape, quat.shape
        ((2, 2, 3), (2, 2, 4))
        >>> np.round(quat[1, 1], 3).tolist()  # the pole turned a quarter about y
        [0.707, 0.0, 0.707, 0.0]
        """
        q = np.asarray(q, dtype=float).reshape(-1, self.njoints)
        return _pose(self._chain, np.repeat(self._pos0, q.shape[0], axis=0),
                     np.repeat(self._quat0, q.shape[0], axis=0), q)

    def posed_bodies(self) -> NDArray[np.intp]:
        """The bodies logged per pose row: drawn and moved by the joints.

        Returns
        -------
        ndarray of intp
            Their body ids, ascending.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", 0.01)
        >>> scene = Poses(plant.model, plant.system.joints)
        >>> scene.posed_bodies().tolist()
        [1]
        """
        return np.flatnonzero(self.moving & self.drawn)

    def geometry(self, root: str = TRUE_ROOT, color: Sequence[int] | None = None
                 ) -> list[tuple[str, list[Any]]]:
        """Static entities of the geometry under ``root``: ``(path, archetypes)``.

        ``color=None``: the true robot, solid in the model's colours, with the bodies the
        joints do not move posed once. Else a translucent ghost in ``color`` (RGB) of the
        bodies the joints move only (a ghost of what does not move would sit on the truth).

        Parameters
        ----------
        root : str
            The entity path the geometry goes under (default ``/world/true``; a ghost's is
            ``/world/estimate/<obs>``).
        color : sequence of int, optional
            ``(r, g, b)`` in 0..255 of a ghost (drawn with alpha ``GHOST_ALPHA``); ``None``:
            the true robot.

        Returns
        -------
        list of (str, list)
            ``(entity path, [rr.Transform3D, shape archetype])`` per drawn geom (a geom whose
            type is not drawn is left out), after ``(body path, [rr.Transform3D])`` of each
            drawn body the joints do not move (true robot only).

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", 0.01)
        >>> scene = Poses(plant.model, plant.system.joints)
        >>> [path for path, _ in scene.geometry()]
        ['/world/true/world', '/world/true/world/mount', '/world/true/pole/rod', '/world/true/pole/bob']
        >>> [path for path, _ in scene.geometry("/world/estimate/k40", (31, 119, 180))]
        ['/world/estimate/k40/pole/rod', '/world/estimate/k40/pole/bob']
        """
        out: list[tuple[str, list[Any]]] = []
        m = self.model
        ghost = color is not None
        fill = (rr.components.FillMode.TransparentFillMajorWireframe if ghost
                else rr.components.FillMode.Solid)
        if not ghost:
            pos0, quat0 = self._pos0[0], self._quat0[0]  # at qpos0: where they stay
            out += [(body_path(root, self.body_names[b]), [transform(pos0[b], quat0[b])])
                    for b in np.flatnonzero(self.drawn & ~self.moving)]
        for geom in self.geoms:
            if ghost and not self.moving[geom.body]:
                continue
            col = ([*color, GHOST_ALPHA] if color is not None
                   else np.round(geom.rgba * 255).astype(int).tolist())
            shape = geom_shape(m, geom.index, col, fill)
            if shape is not None:
                out.append((geom_path(root, self.body_names[geom.body], geom.name),
                            [transform(geom.pos, geom.quat), shape]))
        return out


#: (MJCF path, mtime, size) -> the compiled model, for :func:`model_for`
_MODELS: dict[tuple[str, int, int], Any] = {}


def model_for(meta: Mapping[str, Any]) -> tuple[Any, tuple[str, ...]]:
    """The MJCF model and joints of the system a trajectory's metadata names (the scenario's
    ``model_file`` if it gives one), or ``(None, ())`` for an ODE system.

    Parameters
    ----------
    meta : mapping
        A trajectory's metadata (``Trajectory.metadata``): ``plant`` names the system's
        class; ``scenario_spec`` may give ``[plant.params] model_file``; an MJCF plant's
        metadata names its file.

    Returns
    -------
    model : mujoco.MjModel or None
        The compiled model (cached per file, modification time and size); ``None`` for an
        ODE system or an unknown plant.
    joints : tuple of str
        The system's ``joints`` (empty with ``None``).

    Examples
    --------
    >>> model, joints = model_for({"plant": "Pendulum"})
    >>> model.nbody, joints
    (2, ('hinge',))
    >>> model_for({"plant": "BioreactorBullinger"})
    (None, ())
    """
    from ..systems import SYSTEMS
    from ..systems.mjcf import system_from_metadata

    mcls = system_from_metadata(meta)
    if mcls is not None:  # any MJCF (hgo_mj.systems.mjcf): its edited, compiled model
        return mcls.load_model(), tuple(mcls.joints)
    spec = meta.get("scenario_spec") or {}
    cls = next((c for c in SYSTEMS.values() if c.__name__ == meta.get("plant")), None)
    if cls is None or cls.model_file is None:
        return None, ()
    import mujoco

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


__all__ = ["Geom", "Poses", "model_for"]
