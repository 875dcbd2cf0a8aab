"""One MuJoCo model's names bound to ids and addresses, in one place (dm_control's
``physics.named``, MuJoCo's ``model.joint('hinge')``).

Every module that reads ``MjData`` by name (the plant, the MJCF systems, the MuJoCo Kalman
filters, the observer-in-the-loop wrapper, the recorder's poses) resolves its names through a
:class:`Binding`: a joint, actuator, sensor, body, tendon, site or geom name to its id, a joint
to its ``qpos`` and ``qvel`` addresses, an output (a sensor, or ``sensor[k]`` for channel ``k``
of a multi-dimensional one) to its ``sensordata`` address. An unknown name is one error, the
same everywhere: a :class:`~hgo_mj.exceptions.ModelError` naming what was asked and listing the
names the model has. Names are looked up once (each answer is kept); the hot paths read the
arrays of addresses this returns, never a name.

It lives below ``systems`` and ``plants`` (both use it; a system never imports a plant).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from .exceptions import DesignError, ModelError

IntArray = NDArray[np.intp]

#: element kind -> (MuJoCo object type, the model's count attribute)
KINDS: dict[str, tuple[Any, str]] = {
    "joint": (mujoco.mjtObj.mjOBJ_JOINT, "njnt"),
    "actuator": (mujoco.mjtObj.mjOBJ_ACTUATOR, "nu"),
    "sensor": (mujoco.mjtObj.mjOBJ_SENSOR, "nsensor"),
    "body": (mujoco.mjtObj.mjOBJ_BODY, "nbody"),
    "tendon": (mujoco.mjtObj.mjOBJ_TENDON, "ntendon"),
    "site": (mujoco.mjtObj.mjOBJ_SITE, "nsite"),
    "geom": (mujoco.mjtObj.mjOBJ_GEOM, "ngeom"),
}


class Binding:
    """The names of one ``MjModel`` bound to ids and addresses.

    Parameters
    ----------
    model : mujoco.MjModel
        The model (not copied; its names and addresses never change).
    where : str
        How errors name the model (``"pendulum.xml"``, ``"ElasticJoint: the MJCF"``).

    Raises
    ------
    DesignError
        ``model`` is not a ``mujoco.MjModel``.

    Examples
    --------
    >>> import mujoco
    >>> m = mujoco.MjModel.from_xml_string(
    ...     '<mujoco><worldbody><body name="b"><joint name="hinge"/><geom size=".1"/></body>'
    ...     '</worldbody><actuator><motor name="torque" joint="hinge"/></actuator>'
    ...     '<sensor><jointpos name="angle" joint="hinge"/></sensor></mujoco>')
    >>> names = Binding(m)
    >>> names.id("actuator", "torque"), names.qpos(["hinge"]).tolist(), names.sensordata("angle")
    (0, [0], 0)
    >>> names.id("joint", "elbow")
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.ModelError: the model has no joint named 'elbow'; its joint names: ['hinge']
    """

    def __init__(self, model: Any, where: str = "the model") -> None:
        if not isinstance(model, mujoco.MjModel):
            raise DesignError(f"{where}: expected a mujoco.MjModel; found {type(model).__name__}")
        self.model = model
        self.where = where
        self._ids: dict[tuple[str, str], int] = {}

    def names(self, kind: str) -> list[str]:
        """The names of the model's elements of ``kind``, in id order (``""``: unnamed).

        Parameters
        ----------
        kind : str
            One of :data:`KINDS`.

        Returns
        -------
        list of str
        """
        obj, count = self._kind(kind)
        return [mujoco.mj_id2name(self.model, obj, i) or ""
                for i in range(int(getattr(self.model, count)))]

    def id(self, kind: str, name: str) -> int:
        """The id of the element ``name`` of ``kind``.

        Parameters
        ----------
        kind : str
            One of :data:`KINDS` (``"joint"``, ``"actuator"``, ``"sensor"``, ...).
        name : str
            The element's name in the MJCF.

        Returns
        -------
        int

        Raises
        ------
        ModelError
            The model has no such element (the known names listed).
        """
        key = (kind, name)
        found = self._ids.get(key)
        if found is None:
            obj, _ = self._kind(kind)
            i = mujoco.mj_name2id(self.model, obj, name) if isinstance(name, str) else -1
            if i < 0:
                known = [n for n in self.names(kind) if n]
                raise ModelError(f"{self.where} has no {kind} named {name!r}; its {kind} "
                                 f"names: {known}")
            found = self._ids[key] = int(i)
        return found

    def ids(self, kind: str, names: Sequence[str]) -> IntArray:
        """The ids of ``names`` (:meth:`id` of each), an index array."""
        return np.array([self.id(kind, n) for n in names], dtype=np.intp)

    def qpos(self, joints: Sequence[str]) -> IntArray:
        """The ``qpos`` addresses of the joints ``joints`` (``jnt_qposadr``)."""
        return np.array([self.model.jnt_qposadr[self.id("joint", j)] for j in joints],
                        dtype=np.intp)

    def dofs(self, joints: Sequence[str]) -> IntArray:
        """The ``qvel`` (degree-of-freedom) addresses of the joints ``joints``
        (``jnt_dofadr``)."""
        return np.array([self.model.jnt_dofadr[self.id("joint", j)] for j in joints],
                        dtype=np.intp)

    def sensor(self, output: str) -> tuple[int, int]:
        """``(sensor id, channel)`` of an output: a sensor's name (channel 0), or
        ``<name>[k]`` for channel ``k`` of a multi-dimensional sensor (``framepos``: 3); a
        sensor whose own name ends in ``[k]`` is itself.

        Raises
        ------
        ModelError
            No such sensor (or channel).
        """
        m = self.model
        if output.endswith("]") and "[" in output and mujoco.mj_name2id(
                m, mujoco.mjtObj.mjOBJ_SENSOR, output) < 0:
            base, _, k = output[:-1].rpartition("[")
            s = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, base)
            if s >= 0 and k.isdigit() and int(k) < int(m.sensor_dim[s]):
                return int(s), int(k)
        return self.id("sensor", output), 0

    def sensordata(self, output: str) -> int:
        """The ``sensordata`` address of an output (:meth:`sensor`)."""
        s, k = self.sensor(output)
        return int(self.model.sensor_adr[s]) + k

    def _kind(self, kind: str) -> tuple[Any, str]:
        try:
            return KINDS[kind]
        except KeyError:
            raise DesignError(f"unknown element kind {kind!r}; known: {list(KINDS)}") from None
