"""Any MJCF as a plant and as the model of observers (issue 12).

:func:`mjcf_system` reads an MJCF file hgo_mj did not write and returns a :class:`System`
class for it, so that :class:`~hgo_mj.plants.MujocoPlant` runs it as the true plant and the
observers design against it:

* **State**: ``(qpos, qvel)`` of every joint, in the MJCF's joint order. Hinge and slide joints
  only (a ball or free joint has a quaternion ``qpos`` with ``nq != nv``: refused, named);
  activation states (``act``) are refused too.
* **Outputs**: named MJCF sensors (jointpos, actuatorpos, framepos, ..., each channel of a
  multi-dimensional sensor its own output ``name[i]``), or a joint's name, which adds a
  ``jointpos`` sensor on that joint (named ``<joint>_angle`` for a hinge, ``<joint>_position``
  for a slide) so that files without sensors (Gymnasium's) can be measured.
* **Inputs**: named actuators (default: all, in the MJCF's order). Unnamed joints and actuators
  are named ``joint<i>`` / ``actuator<i>`` by their index.

**Normal form.** Where every joint's position is an output (a ``jointpos`` sensor or the joint
itself), each joint is a chain of order 2, ``z_c = (q_c, q_c')`` with
``q_c'' = phi_c(z, u)`` = MuJoCo's forward dynamics (``mj_forward``'s ``qacc``) at the
estimate: :meth:`MjcfSystem.chain_phi`, the model term of ``high_gain_multi(model=True)``
(paper 001, eq. 5, the block structure). The model-free high-gain observer needs only the chain
orders (paper 000); the MuJoCo EKF/UKF (``ekf_mujoco``, ``ukf_mujoco``) need no normal form.
Where a joint's position is not measured, :attr:`MjcfSystem.normal_form_problem` says which,
and that only the MuJoCo EKF/UKF still apply.

Example
-------
>>> from hgo_mj.systems.mjcf import mjcf_system
>>> from hgo_mj.plants import model_path
>>> cls = mjcf_system(model_path("pendulum.xml"), outputs=["hinge"])
>>> cls.state_names, cls.normal_form_problem
(('hinge_angle', 'hinge_velocity'), None)
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, ClassVar

import mujoco
import mujoco.batch
import numpy as np

from .._binding import Binding
from ..exceptions import ModelError
from .base import Array, System, derivative_names

_WORD = {int(mujoco.mjtJoint.mjJNT_HINGE): ("angle", "rad", "rad/s"),
         int(mujoco.mjtJoint.mjJNT_SLIDE): ("position", "m", "m/s")}
_JOINTPOS = int(mujoco.mjtSensor.mjSENS_JOINTPOS)
_JOINT = int(mujoco.mjtObj.mjOBJ_JOINT)


class MjcfSystem(System):
    """A system read from an MJCF file by :func:`mjcf_system` (one subclass per file, outputs
    and inputs). Instances hold their own ``MjModel``/``MjData`` for :meth:`output` and
    :meth:`chain_phi`.

    Parameters
    ----------
    model : mujoco.MjModel, optional
        The compiled model to evaluate on (default: :meth:`load_model`, the file with the
        sensors and names the class added).

    Examples
    --------
    >>> from hgo_mj.plants import model_path
    >>> cls = mjcf_system(model_path("pendulum.xml"), ["hinge"])
    >>> s = cls()
    >>> s.state_names, s.normal_form_orders
    (('hinge_angle', 'hinge_velocity'), (2,))
    """

    reference = "MuJoCo forward dynamics of the MJCF; chains after paper 001, eq. 5"
    forms: ClassVar[tuple[str, ...]] = ()
    #: ``None`` when every joint's position is measured (the (q, q') normal form holds), else
    #: why not, and which observers still apply
    normal_form_problem: ClassVar[str | None] = None
    #: chain orders (2 per joint) where the normal form holds, else None
    normal_form_orders: ClassVar[tuple[int, ...] | None] = None
    #: the output channel measuring each joint's position (chain c measures joint c)
    normal_form_outputs: ClassVar[tuple[int, ...] | None] = None
    #: what built the class: ``{"model": path, "outputs": [...], "inputs": [...]}`` (kept in a
    #: trajectory's metadata as ``"mjcf"``, so that figures and recordings rebuild it)
    mjcf: ClassVar[dict[str, Any]] = {}
    _spec_path: ClassVar[str] = ""
    _added: ClassVar[tuple[tuple[str, str], ...]] = ()
    _names: ClassVar[tuple[tuple[str, ...], tuple[str, ...]]] = ((), ())
    #: per output: (sensordata address) -- read after mj_forward
    _sensor_adr: ClassVar[tuple[int, ...]] = ()

    def __init__(self, model: Any = None) -> None:
        super().__init__()
        self.model = type(self).load_model() if model is None else model
        self.data = mujoco.MjData(self.model)
        #: the model's names bound to ids and addresses (the one binding)
        self.binding = names = Binding(self.model, f"{type(self).__name__}: the MJCF")
        self._qadr, self._vadr = names.qpos(self.joints), names.dofs(self.joints)
        self._aid = names.ids("actuator", self.actuators)
        self._sadr = np.array(self._sensor_adr, dtype=np.intp)
        #: batch size -> (mujoco.batch.Batch, its qpos, qvel, ctrl, qacc) of :meth:`_qacc_rows`
        self._batches: dict[int, tuple[Any, ...]] = {}

    def __reduce__(self) -> tuple[Any, tuple[dict[str, Any]]]:
        """Pickle as what built the class (the class itself is made per call): unpickling
        rebuilds it with :func:`mjcf_system` from the file, outputs and inputs."""
        return (_rebuilt, (dict(type(self).mjcf),))

    @classmethod
    def load_model(cls) -> Any:
        """The compiled ``MjModel``: the MJCF with the sensors and names this class added."""
        return _compile(_edited_spec(cls._spec_path, cls._names, cls._added), cls._spec_path)

    @classmethod
    def from_mjmodel(cls, model: Any) -> MjcfSystem:
        return cls(model)

    def _set(self, x: Array, u: Array | None) -> None:
        nj = len(self.joints)
        d = self.data
        d.qpos[self._qadr] = x[:nj]
        d.qvel[self._vadr] = x[nj:2 * nj]
        if u is not None and self._aid.size:
            d.ctrl[self._aid] = u
        mujoco.mj_forward(self.model, d)

    def output(self, x: Array, p: Any = None) -> Array:  # type: ignore[override]
        """The sensors' values at state ``x`` (``mj_forward``, controls zero)."""
        self.data.ctrl[:] = 0.0
        self._set(np.asarray(x, dtype=float), None)
        return np.array(self.data.sensordata[self._sadr], dtype=float)

    def dynamics(self, t: float, x: Array, u: Array, p: Any = None) -> Array:  # type: ignore[override]
        """``dx/dt = (q', q'')`` from ``mj_forward`` at ``x`` with controls ``u``."""
        self._set(np.asarray(x, dtype=float), np.asarray(u, dtype=float))
        return np.concatenate((self.data.qvel[self._vadr], self.data.qacc[self._vadr]))

    def chain_phi(self, z: Array, u: Array) -> Array:
        """The chains' top derivatives ``q''`` at ``z = (q_1, q_1', q_2, q_2', ...)`` (chain
        ``c`` is joint ``c``): the model term of ``high_gain_multi(model=True)``.

        Parameters
        ----------
        z : array_like, shape (2 n_joints,)
            Positions and velocities, interleaved per joint.
        u : array_like, shape (m,)
            The actuators' controls.

        Returns
        -------
        ndarray, shape (n_joints,)
            ``qacc`` of ``mj_forward`` at that state and control.

        Raises
        ------
        ModelError
            The normal form does not hold (:attr:`normal_form_problem`).

        Examples
        --------
        >>> from hgo_mj.plants import model_path
        >>> s = mjcf_system(model_path("pendulum.xml"), ["hinge"])()
        >>> s.chain_phi([0.0, 0.0], [0.0])
        array([0.])
        """
        if self.normal_form_problem is not None:
            raise ModelError(self.normal_form_problem)
        z = np.asarray(z, dtype=float)
        x = np.concatenate((z[0::2], z[1::2]))
        self._set(x, np.asarray(u, dtype=float))
        return np.array(self.data.qacc[self._vadr], dtype=float)

    def chain_phi_batch(self, Z: Array, U: Array) -> Array:
        """:meth:`chain_phi` of the rows ``Z`` ``(B, 2 n_joints)``, ``U`` ``(B, m)``, shape
        ``(B, n_joints)``: one ``mj_forward`` per row on MuJoCo's batch
        (``mujoco.batch.Batch``, one thread; the same bits as :meth:`chain_phi`, tested), so
        that a batch of observers takes its model term in one call.

        Parameters
        ----------
        Z : array_like, shape (B, 2 n_joints)
            One state per row, as :meth:`chain_phi`'s ``z``.
        U : array_like, shape (B, m)
            One control per row.

        Returns
        -------
        ndarray, shape (B, n_joints)

        Raises
        ------
        ModelError
            The normal form does not hold (:attr:`normal_form_problem`).

        Examples
        --------
        >>> from hgo_mj.plants import model_path
        >>> s = mjcf_system(model_path("pendulum.xml"), ["hinge"])()
        >>> s.chain_phi_batch(np.zeros((3, 2)), np.zeros((3, 1))).shape
        (3, 1)
        """
        if self.normal_form_problem is not None:
            raise ModelError(self.normal_form_problem)
        Z = np.asarray(Z, dtype=float)
        return self._qacc_rows(Z[:, 0::2], Z[:, 1::2], U)

    def dynamics_batch(self, X: Array, U: Array) -> Array:
        """:meth:`dynamics` of the rows ``X`` ``(B, n)`` with the controls ``U`` ``(B, m)``,
        shape ``(B, n)``: one ``mj_forward`` per row on MuJoCo's batch (one thread), so that a
        Kalman filter over this model (:class:`~hgo_mj.observers.kalman.SystemModel`) takes
        its model in one call per stage instead of one Python call per row. The same bits as
        :meth:`dynamics` row by row on a model without constraints (tested); with constraints
        MuJoCo's solver starts each row from its own warm start rather than from the previous
        row's, which agrees to the solver's tolerance.

        Parameters
        ----------
        X : array_like, shape (B, n)
            One state ``(q, q')`` per row.
        U : array_like, shape (B, m)
            One control per row.

        Returns
        -------
        ndarray, shape (B, n)
            ``(q', q'')`` per row.

        Examples
        --------
        >>> from hgo_mj.plants import model_path
        >>> s = mjcf_system(model_path("pendulum.xml"), ["hinge"])()
        >>> s.dynamics_batch(np.array([[0.0, 1.0]]), np.zeros((1, 1))).round(4)  # damped
        array([[ 1.    , -0.1844]])
        """
        X = np.asarray(X, dtype=float)
        nj = len(self.joints)
        return np.concatenate((X[:, nj:2 * nj], self._qacc_rows(X[:, :nj], X[:, nj:2 * nj], U)),
                              axis=1)

    def _qacc_rows(self, Q: Array, V: Array, U: Array) -> Array:
        """``qacc`` of the joints at the rows of positions ``Q``, velocities ``V`` and controls
        ``U`` (other controls zero), ``(B, n_joints)``, on a ``mujoco.batch.Batch`` kept per
        batch size."""
        B = Q.shape[0]
        if B not in self._batches:
            bt = mujoco.batch.Batch(self.model, B, nthread=1)
            self._batches[B] = (bt, *(bt.bind(f) for f in ("qpos", "qvel", "ctrl", "qacc")))
        bt, qpos, qvel, ctrl, qacc = self._batches[B]
        qpos[:, self._qadr] = Q
        qvel[:, self._vadr] = V
        ctrl[:] = 0.0
        if self._aid.size:
            ctrl[:, self._aid] = U
        bt.forward()
        return np.array(qacc[:, self._vadr], dtype=float)


def _path(path: Any) -> Path:
    if not isinstance(path, (str, os.PathLike)):
        raise ModelError(f"an MJCF model must be given as a path (str or os.PathLike); found "
                         f"{type(path).__name__}")
    p = Path(path).expanduser()
    if not p.is_file():
        raise ModelError(f"MJCF file {str(p)!r} does not exist")
    return p.resolve()


def _spec(path: Path) -> Any:
    try:
        return mujoco.MjSpec.from_file(str(path))
    except Exception as exc:  # MuJoCo's own parse error, one line
        raise ModelError(f"MJCF file {str(path)!r} does not load: "
                         f"{' '.join(str(exc).split())}") from None


def _compile(spec: Any, path: str) -> Any:
    try:
        return spec.compile()
    except Exception as exc:
        raise ModelError(f"MJCF file {path!r} does not compile: {' '.join(str(exc).split())}"
                         ) from None


def _edited_spec(path: str, names: tuple[tuple[str, ...], tuple[str, ...]],
                 added: tuple[tuple[str, str], ...]) -> Any:
    """The file's spec with unnamed joints and actuators named and the joint sensors added."""
    spec = _spec(Path(path))
    for j, name in zip(spec.joints, names[0]):
        j.name = name
    for a, name in zip(spec.actuators, names[1]):
        a.name = name
    for sensor, joint in added:
        s = spec.add_sensor()
        s.name, s.type, s.objtype, s.objname = sensor, _JOINTPOS, _JOINT, joint
    return spec


def _strings(what: str, value: Any, default: tuple[str, ...] | None = None) -> tuple[str, ...]:
    if value is None and default is not None:
        return default
    if isinstance(value, str) or not isinstance(value, (list, tuple)) or not value or not all(
            isinstance(v, str) for v in value):
        raise ModelError(f"{what} must be a non-empty list of names; found {value!r}")
    if len(set(value)) != len(value):
        raise ModelError(f"{what} must be distinct; found {list(value)}")
    return tuple(value)


def mjcf_system(path: Any, outputs: Any, inputs: Any = None) -> type[MjcfSystem]:
    """A :class:`MjcfSystem` class for the MJCF file ``path``.

    Parameters
    ----------
    path : str or os.PathLike
        The MJCF file.
    outputs : list of str
        Measured outputs: MJCF sensor names, or joint names (their position).
    inputs : list of str, optional
        Actuators driven by ``u``, in order; default every actuator.

    Returns
    -------
    type[MjcfSystem]
        The system class (``MujocoPlant(cls, dt)`` runs it; ``cls()`` is the observers' model).

    Raises
    ------
    ModelError
        The file does not exist, load or compile (MuJoCo's message and the file); a ball or
        free joint, or activation states; an output that is neither a sensor nor a joint, an
        input that is not an actuator (the valid names listed).

    Examples
    --------
    >>> from hgo_mj.systems.mjcf import mjcf_system
    >>> from hgo_mj.plants import model_path
    >>> cls = mjcf_system(model_path("pendulum.xml"), outputs=["hinge"])
    >>> cls.output_names, cls.input_names
    (('hinge_angle',), ('torque',))
    """
    p = _path(path)
    outputs = _strings("outputs", outputs)
    spec = _spec(p)
    jnames = tuple(j.name or f"joint{i}" for i, j in enumerate(spec.joints))
    anames = tuple(a.name or f"actuator{i}" for i, a in enumerate(spec.actuators))
    inputs = _strings("inputs", inputs, anames)
    m = _compile(_edited_spec(str(p), (jnames, anames), ()), str(p))
    for i, name in enumerate(jnames):
        if int(m.jnt_type[i]) not in _WORD:
            kind = mujoco.mjtJoint(m.jnt_type[i]).name
            raise ModelError(f"{p.name}: joint {name!r} is a {kind} joint; hgo_mj's MJCF plants "
                             f"take hinge and slide joints only")
    if m.na:
        raise ModelError(f"{p.name}: the model has {m.na} activation states (act); hgo_mj's "
                         f"MJCF plants do not take them yet")
    bad = [a for a in inputs if a not in anames]
    if bad:
        raise ModelError(f"{p.name}: no actuator named {bad[0]!r}; actuators: {list(anames)}")
    bound = Binding(m, p.name)
    sensors = set(bound.names("sensor"))
    added: list[tuple[str, str]] = []
    measured: dict[str, int] = {}
    out_names: list[str] = []
    adrs: list[int] = []
    for name in outputs:
        if name in sensors:
            s = bound.id("sensor", name)
            dim, adr = int(m.sensor_dim[s]), int(m.sensor_adr[s])
            chans = [name] if dim == 1 else [f"{name}[{k}]" for k in range(dim)]
            if int(m.sensor_type[s]) == _JOINTPOS and int(m.sensor_objtype[s]) == _JOINT:
                measured.setdefault(jnames[int(m.sensor_objid[s])], len(out_names))
        elif name in jnames:
            word = _WORD[int(m.jnt_type[jnames.index(name)])][0]
            chans = [f"{name}_{word}"]
            if chans[0] in sensors:
                raise ModelError(f"{p.name}: output {name!r} would add a sensor "
                                 f"{chans[0]!r}, which the model has already; list that sensor")
            added.append((chans[0], name))
            measured.setdefault(name, len(out_names))
            adr = -1
        else:
            raise ModelError(f"{p.name}: output {name!r} is neither a sensor nor a joint; "
                             f"sensors: {sorted(sensors)}, joints: {list(jnames)}")
        out_names += chans
        adrs += [adr + k for k in range(len(chans))] if adr >= 0 else [-1]
    m = _compile(_edited_spec(str(p), (jnames, anames), tuple(added)), str(p))
    bound = Binding(m, p.name)  # the model compiled with the added sensors
    adrs = [a if a >= 0 else bound.sensordata(c) for a, c in zip(adrs, out_names)]
    cls = _make_class(p, m, jnames, anames, inputs, tuple(out_names), tuple(adrs),
                      tuple(added), measured)
    cls.mjcf = {"model": str(p), "outputs": list(outputs), "inputs": list(inputs)}
    return cls


def _rebuilt(spec: dict[str, Any]) -> MjcfSystem:
    """The system :meth:`MjcfSystem.__reduce__` pickled (its class rebuilt from the file)."""
    return mjcf_system(spec["model"], spec["outputs"], spec.get("inputs"))()


def system_from_metadata(meta: Any) -> type[MjcfSystem] | None:
    """The MJCF system a trajectory's metadata names (its ``"mjcf"`` entry), or ``None``.

    Parameters
    ----------
    meta : mapping
        A trajectory's metadata.

    Returns
    -------
    type[MjcfSystem] or None
        The class rebuilt with :func:`mjcf_system` from the file, outputs and inputs stored.

    Examples
    --------
    >>> from hgo_mj.plants import model_path
    >>> meta = {"mjcf": {"model": str(model_path("pendulum.xml")), "outputs": ["hinge"]}}
    >>> system_from_metadata(meta).output_names
    ('hinge_angle',)
    >>> system_from_metadata({}) is None
    True
    """
    spec = meta.get("mjcf") if hasattr(meta, "get") else None
    if not spec:
        return None
    return mjcf_system(spec["model"], spec["outputs"], spec.get("inputs"))


def _make_class(p: Path, m: Any, jnames: tuple[str, ...], anames: tuple[str, ...],
                inputs: tuple[str, ...], out_names: tuple[str, ...], adrs: tuple[int, ...],
                added: tuple[tuple[str, str], ...], measured: dict[str, int]) -> type[MjcfSystem]:
    states, units = [], []
    for i, j in enumerate(jnames):
        word, pu, vu = _WORD[int(m.jnt_type[i])]
        names = (derivative_names(out_names[measured[j]], 2) if j in measured
                 else (f"{j}_{word}", f"{j}_velocity"))
        states.append(names)
        units.append((pu, vu))
    missing = [j for j in jnames if j not in measured]
    problem = None if not missing else (
        f"the positions of joint(s) {missing} are not measured, so the (q, q') normal form "
        f"with q'' from MuJoCo does not hold: the high-gain family does not apply; the MuJoCo "
        f"EKF/UKF (ekf_mujoco, ukf_mujoco) still do")
    qpos0 = [float(m.qpos0[m.jnt_qposadr[i]]) for i in range(len(jnames))]
    ns = {
        "name": f"mjcf:{p.name}", "summary": f"MJCF {p.name}", "model_file": str(p),
        "joints": jnames, "actuators": inputs, "input_names": inputs,
        "input_units": tuple("" for _ in inputs), "output_names": out_names,
        "state_names": tuple(s[0] for s in states) + tuple(s[1] for s in states),
        "state_units": tuple(u[0] for u in units) + tuple(u[1] for u in units),
        "default_x0": tuple(qpos0) + (0.0,) * len(jnames),
        "normal_form_problem": problem,
        "normal_form_orders": None if missing else (2,) * len(jnames),
        "normal_form_outputs": None if missing else tuple(measured[j] for j in jnames),
        "_spec_path": str(p), "_added": added, "_names": (jnames, anames),
        "_sensor_adr": adrs,
    }
    return type(f"Mjcf_{p.stem}", (MjcfSystem,), ns)


__all__ = ["MjcfSystem", "mjcf_system", "system_from_metadata"]
