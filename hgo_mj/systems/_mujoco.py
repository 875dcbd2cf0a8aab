"""The machinery the MuJoCo systems share: :class:`_MujocoSystem` (parameters
read from a compiled ``MjModel``, defaults from the shipped MJCF) and :class:`_MjReader`
(masses, inertias about hinge axes, damping, armature, gears and spring tendons, read at
``q = 0`` in world coordinates).
"""

from __future__ import annotations

from collections.abc import Mapping
from importlib import resources
from typing import Any, ClassVar

import mujoco
import numpy as np

from .._binding import Binding
from .._validate import vector
from ..exceptions import DesignError
from .base import Array, System

_SHIPPED: dict[type, dict[str, float]] = {}
_TOL = 1e-9


class _MjReader:
    """Geometry and parameters of a compiled ``MjModel``, at ``qpos = 0``, in world coordinates.

    Every lookup is by name; a missing element or a geometry the analytic model cannot
    represent raises :class:`DesignError` naming what was expected and what was found.
    """

    def __init__(self, model: Any, where: str) -> None:
        if not isinstance(model, mujoco.MjModel):
            raise DesignError(f"{where}: expected a mujoco.MjModel; found {type(model).__name__}")
        self.m = model
        self.where = where
        self.binding = Binding(model, f"{where}: the MJCF")
        self.d = mujoco.MjData(model)
        self.d.qpos[:] = 0.0
        mujoco.mj_kinematics(model, self.d)
        gvec = np.array(model.opt.gravity, dtype=float)
        self.g = float(np.linalg.norm(gvec))
        if self.g == 0.0:
            raise DesignError(f"{where}: the model needs gravity; found opt.gravity = {gvec}")
        #: unit vector along gravity
        self.down = gvec / self.g

    def body(self, name: str) -> int:
        return self.binding.id("body", name)

    def parent(self, body: str, parent: str | None) -> None:
        """Require ``body``'s parent to be ``parent`` (``None``: the world)."""
        b = self.body(body)
        want = 0 if parent is None else self.body(parent)
        got = int(self.m.body_parentid[b])
        if got != want:
            raise DesignError(
                f"{self.where}: body {body!r} must be a child of {parent or 'the world'!r}; "
                f"found parent {self.m.body(got).name or 'world'!r}")

    def joint(self, name: str, kind: str = "hinge") -> tuple[int, int, Array, Array]:
        """``(joint id, dof address, world anchor, world unit axis)`` of a hinge or slide."""
        j = self.binding.id("joint", name)
        want = {"hinge": mujoco.mjtJoint.mjJNT_HINGE, "slide": mujoco.mjtJoint.mjJNT_SLIDE}[kind]
        if self.m.jnt_type[j] != want:
            raise DesignError(f"{self.where}: joint {name!r} must be a {kind} joint; "
                              f"found type {mujoco.mjtJoint(self.m.jnt_type[j]).name}")
        axis = np.array(self.d.xaxis[j], dtype=float)
        axis /= np.linalg.norm(axis)
        if abs(axis @ self.down) > _TOL:
            raise DesignError(f"{self.where}: joint {name!r} must have a horizontal axis "
                              f"(perpendicular to gravity); found axis {axis.tolist()}")
        return j, int(self.m.jnt_dofadr[j]), np.array(self.d.xanchor[j], dtype=float), axis

    def same_axis_direction(self, names: tuple[str, ...]) -> None:
        """Require the joints' axes to point the same way (planar mechanism, one sign)."""
        axes = [self.joint(n)[3] for n in names]
        for n, a in zip(names[1:], axes[1:]):
            if abs(a @ axes[0] - 1.0) > _TOL:
                raise DesignError(f"{self.where}: joint {n!r} must have the same axis direction "
                                  f"as {names[0]!r} ({axes[0].tolist()}); found {a.tolist()}")

    def about_axis(self, body: str, anchor: Array, axis: Array) -> tuple[float, Array, float]:
        """``(mass, COM offset perpendicular to the axis, inertia about the axis)`` of a body."""
        b = self.body(body)
        mass = float(self.m.body_mass[b])
        r = np.array(self.d.xipos[b], dtype=float) - anchor
        r_perp = r - (r @ axis) * axis
        R = np.array(self.d.ximat[b], dtype=float).reshape(3, 3)
        inertia = float(axis @ R @ np.diag(self.m.body_inertia[b]) @ R.T @ axis)
        return mass, r_perp, inertia + mass * float(r_perp @ r_perp)

    def along(self, what: str, r_perp: Array, direction: Array) -> float:
        """Component of ``r_perp`` along ``direction``, requiring no other in-plane part."""
        s = float(r_perp @ direction)
        off = r_perp - s * direction
        if np.linalg.norm(off) > _TOL * (1.0 + abs(s)):
            raise DesignError(
                f"{self.where}: {what} must lie on the vertical through the hinge at q = 0; "
                f"found a horizontal offset {off.tolist()} m")
        return s

    def on_axis(self, body: str, r_perp: Array) -> None:
        """Require a body's COM on its joint axis (no gravity torque, no coupling)."""
        if np.linalg.norm(r_perp) > _TOL:
            raise DesignError(f"{self.where}: the COM of body {body!r} must lie on its joint "
                              f"axis; found an offset {r_perp.tolist()} m")

    def damping(self, dof: int) -> float:
        return float(self.m.dof_damping[dof])

    def armature(self, dof: int) -> float:
        return float(self.m.dof_armature[dof])

    def gear(self, actuator: str, joint: str) -> float:
        """Generalized force per unit control of a ``<motor>`` on ``joint`` (gear times gain)."""
        a = self.binding.id("actuator", actuator)
        j = self.binding.id("joint", joint)
        m = self.m
        if m.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_JOINT or m.actuator_trnid[a, 0] != j:
            raise DesignError(f"{self.where}: actuator {actuator!r} must drive joint {joint!r}")
        if (m.actuator_gaintype[a] != mujoco.mjtGain.mjGAIN_FIXED
                or m.actuator_biastype[a] != mujoco.mjtBias.mjBIAS_NONE
                or m.actuator_dyntype[a] != mujoco.mjtDyn.mjDYN_NONE):
            raise DesignError(f"{self.where}: actuator {actuator!r} must be a plain <motor> "
                              "(fixed gain, no bias, no activation dynamics)")
        return float(m.actuator_gear[a, 0] * m.actuator_gainprm[a, 0])

    def spring(self, tendon: str, plus: str, minus: str) -> float:
        """Stiffness of a fixed tendon of length ``q_plus - q_minus`` with rest length 0."""
        t = self.binding.id("tendon", tendon)
        m = self.m
        adr, num = int(m.tendon_adr[t]), int(m.tendon_num[t])
        coef = {int(m.wrap_objid[k]): float(m.wrap_prm[k]) for k in range(adr, adr + num)
                if m.wrap_type[k] == mujoco.mjtWrap.mjWRAP_JOINT}
        want = {self.binding.id("joint", plus): 1.0,
                self.binding.id("joint", minus): -1.0}
        if num != 2 or coef != want:
            raise DesignError(f"{self.where}: tendon {tendon!r} must be a fixed tendon "
                              f"{plus} - {minus} (coef +1, -1)")
        rest = np.asarray(m.tendon_lengthspring[t], dtype=float)
        if np.any(rest != 0.0):
            raise DesignError(f"{self.where}: tendon {tendon!r} must have springlength 0; "
                              f"found {rest.tolist()}")
        return float(m.tendon_stiffness[t])


class _MujocoSystem(System):
    """A :class:`System` whose parameters come from an MJCF model.

    ``from_mjmodel(model)`` reads them from a compiled model; ``cls()`` with some or no
    parameters fills the missing ones from the shipped MJCF (``model_file``), so the analytic
    model can be used alone (e.g. by an observer) without restating numbers.
    """

    #: parameters that must be > 0
    _positive: ClassVar[tuple[str, ...]] = ()

    def __init__(self, **params: Any) -> None:
        if set(params) != set(self.param_names):
            params = {**self.shipped_params(), **params}
        super().__init__(**params)
        bad = {k: self.params[k] for k in self._positive if not self.params[k] > 0}
        if bad:
            raise DesignError(f"{type(self).__name__}: parameters {sorted(self._positive)} "
                              f"must be > 0; found {bad}")

    @classmethod
    def params_from_mjmodel(cls, model: Any) -> dict[str, float]:
        """The parameter dictionary read from a compiled ``mujoco.MjModel``."""
        raise NotImplementedError

    @classmethod
    def from_mjmodel(cls, model: Any) -> _MujocoSystem:
        return cls(**cls.params_from_mjmodel(model))

    @classmethod
    def shipped_params(cls) -> dict[str, float]:
        """Parameters of the MJCF shipped under ``models/`` (read once, then cached)."""
        if cls not in _SHIPPED:
            path = resources.files("hgo_mj.models").joinpath(str(cls.model_file))
            _SHIPPED[cls] = cls.params_from_mjmodel(mujoco.MjModel.from_xml_path(str(path)))
        return dict(_SHIPPED[cls])

    # helpers for the validating public methods
    def _x(self, x: Any) -> Array:
        return vector("x", x, len(self.state_names))

    def _z(self, z: Any) -> Array:
        return vector("z", z, self._require_normal_form())

    def _u(self, u: Any, required: bool) -> Array | None:
        if u is None:
            if required:
                raise DesignError(f"{type(self).__name__}.phi needs the input u "
                                  f"({list(self.input_names)}); found None")
            return None
        return vector("u", u, len(self.input_names))


class _SecondOrderMujocoSystem(_MujocoSystem):
    """A one-joint MuJoCo system whose state ``(q, q')`` already is its normal form
    ``z = (y, y')``: ``to_normal``/``from_normal`` are the identity and
    ``phi(z, u) = q''`` is the second row of :meth:`dynamics`.

    Subclasses give the acceleration once, in plain floats, as :meth:`_acceleration`; their
    :meth:`dynamics` and :meth:`phi_unchecked` (an observer's model term, once per sample) both
    use it, so the model term builds no array.
    """

    @staticmethod
    def _acceleration(q: float, v: float, u0: float, p: Mapping[str, float]) -> float:
        """``q''`` at angle ``q``, velocity ``v`` and input ``u0``, in plain floats (the second
        row of :meth:`dynamics`). Subclasses implement it."""
        raise NotImplementedError

    def to_normal(self, x: Any, u: Any = None) -> Array:
        """``z = (q, q')``: the state itself."""
        self._require_normal_form()
        self._u(u, required=False)
        return self._x(x)

    def from_normal(self, z: Any, u: Any = None) -> Array:
        """Inverse of :meth:`to_normal` (the identity)."""
        self._u(u, required=False)
        return self._z(z)

    def phi(self, z: Any, u: Any = None) -> float:
        """``y'' = phi(z, u)``: the acceleration of :meth:`dynamics`."""
        z = self._z(z)
        u = self._u(u, required=True)
        return float(self.dynamics(0.0, z, u, self.params)[1])

    def to_normal_rows(self, X: Array, U: Array) -> Array:
        """:meth:`to_normal` of the rows ``X`` without validation: a copy of ``X``."""
        return np.array(X, dtype=float)

    def from_normal_unchecked(self, z: Array, u: Array) -> Array:
        return z

    def from_normal_batch(self, Z: Array, U: Array) -> Array:
        """:meth:`from_normal_unchecked` of the rows ``Z`` ``(N, 2)``: a copy of ``Z``."""
        return np.array(Z, dtype=float)

    def phi_unchecked(self, z: Any, u: Array) -> float:
        """:meth:`phi` without validation, in plain floats: ``z`` is any sequence of two
        numbers (an observer passes its tuple of floats), ``u`` has one entry."""
        return self._acceleration(z[0], z[1], float(u[0]), self.params)
