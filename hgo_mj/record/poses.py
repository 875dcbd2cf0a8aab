"""The 3D view of a MuJoCo plant: its geometry as rerun archetypes, posed by MuJoCo itself.

:class:`Poses` sets the recorded joint positions into an ``MjData`` (every other joint at the
model's ``qpos0``) and runs ``mujoco.mj_kinematics`` for each pose row: the world pose of
every body is MuJoCo's own ``xpos``/``xquat``, for the true state and for each observer's
estimate (its translucent ghost). A row costs about 1 us (pendulum) to 1.3 us (two-link
elastic arm) on this machine; poses are logged at ``pose_rate`` (50 Hz by default), so a
10 s run poses about 500 rows per set.

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


class Poses:
    """World poses of a MuJoCo model's bodies at recorded joint positions, by
    ``mujoco.mj_kinematics``, and the model's geometry as rerun archetypes.

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
        self._adr = names.qpos(self.joints)
        moving = np.zeros(model.nbody, dtype=bool)
        for b in range(1, model.nbody):  # a parent's id is below its children's
            moving[b] = moving[model.body_parentid[b]] or b in bodies
        self.moving = moving
        self.body_names = [model.body(b).name or f"body{b}" for b in range(model.nbody)]
        self.geoms = drawn_geoms(model)
        self.drawn = np.zeros(model.nbody, dtype=bool)
        self.drawn[[g.body for g in self.geoms]] = True
        self._data = mujoco.MjData(model)

    def poses(self, q: Any) -> tuple[Array, Array]:
        """World positions ``(T, nbody, 3)`` and quaternions ``(T, nbody, 4)`` (``w, x, y,
        z``) of every body for the joint positions ``q`` of shape ``(T, len(joints))``: each
        row set into the ``qpos`` of an ``MjData`` and posed by ``mujoco.mj_kinematics``.

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
        import mujoco

        q = np.asarray(q, dtype=float).reshape(-1, self.njoints)
        m, d = self.model, self._data
        d.qpos[:] = m.qpos0
        pos = np.empty((q.shape[0], m.nbody, 3))
        quat = np.empty((q.shape[0], m.nbody, 4))
        qpos, xpos, xquat, adr = d.qpos, d.xpos, d.xquat, self._adr  # views into d
        for k in range(q.shape[0]):
            qpos[adr] = q[k]
            mujoco.mj_kinematics(m, d)
            pos[k] = xpos
            quat[k] = xquat
        return pos, quat

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
            pos0, quat0 = self.poses(np.zeros((1, self.njoints)))
            out += [(body_path(root, self.body_names[b]), [transform(pos0[0, b], quat0[0, b])])
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
