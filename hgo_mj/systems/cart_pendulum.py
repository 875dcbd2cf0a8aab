"""Ibrir's inverted pendulum with the pivot acceleration as input (``models/cart_pendulum.xml``)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from functools import cached_property
from typing import Any

import numpy as np
from numba import njit
from numba.extending import register_jitable

from ..exceptions import DesignError
from ._mujoco import _TOL, _MjReader, _SecondOrderMujocoSystem
from .aocf import AOCF, joint_aocf
from .base import Array, CompiledModel

__all__ = ["CartPendulum"]


@register_jitable
def _acceleration_row(q: float, v: float, u0: float, mass: float, length: float, g: float,
                      accel_gain: float, damping: float, inertia: float) -> float:
    """The cart pendulum's ``x1''``, once: the scalar path (:meth:`CartPendulum._acceleration`,
    plain Python) and the compiled rows of :func:`_phi_rows` both run this source, so they
    agree bit for bit."""
    return (mass * length * (g * math.sin(q) + accel_gain * u0 * math.cos(q))
            - damping * v) / inertia


_acceleration_nb = njit(cache=True)(_acceleration_row)


@register_jitable
def _dynamics_row(x: Array, u: Array, c: Array, out: Array) -> None:
    """``out = f(x, u) = (x1', x1'')``: :meth:`CartPendulum.dynamics`; ``c`` in the order of
    ``param_names`` ``(g, length, mass, inertia, damping, accel_gain)``."""
    out[0] = x[1]
    out[1] = _acceleration_row(x[0], x[1], u[0], c[2], c[1], c[0], c[5], c[4], c[3])


class CartPendulumModel(CompiledModel):
    """The cart pendulum's ODE for numba kernels (no analytic Jacobian: the filters
    difference it)."""

    __slots__ = ()
    dynamics = staticmethod(_dynamics_row)


@njit(cache=True)
def _phi_rows(Z: Array, U: Array, c: Array) -> Array:
    """:func:`_acceleration_row` of the rows ``Z`` ``(N, 2)``, ``U`` ``(N, 1)``; ``c = (mass,
    length, g, accel_gain, damping, inertia)``."""
    N = Z.shape[0]
    out = np.empty(N)
    for i in range(N):
        out[i] = _acceleration_nb(Z[i, 0], Z[i, 1], U[i, 0], c[0], c[1], c[2], c[3], c[4], c[5])
    return out


def _aocf_features(Y: Array, U: Array) -> Array:
    """The cart pendulum's :math:`\\psi(y, u) = (\\sin y, u \\cos y)` on rows (its AOCF)."""
    F = np.empty((len(Y), 2))
    F[:, 0] = np.sin(Y)
    F[:, 1] = U[:, 0] * np.cos(Y)
    return F


class CartPendulum(_SecondOrderMujocoSystem):
    r"""Inverted pendulum whose pivot acceleration is the input (Ibrir 2007, eq. 66).

    In time-scaled units (:math:`g/l = 1`) the paper's model is

    .. math::

        \dot x_1 = x_2, \qquad \dot x_2 = \sin x_1 + u \cos x_1, \qquad y = x_1,

    with :math:`x_1` the angle from the upright position and :math:`u` the normalised
    acceleration of the pivot. The analytic model keeps the parameters the MJCF sets,

    .. math::

        J \ddot x_1 = m l \left(g \sin x_1 + a\, u \cos x_1\right) - d \dot x_1,

    with :math:`m` the bob mass, :math:`l` the pivot-to-bob distance, :math:`J` the inertia
    about the pivot, :math:`d` the hinge damping and :math:`a` the pivot acceleration per unit
    input (gear over the translating mass, signed). The shipped model has :math:`g = l = m =
    a = 1`, :math:`d = 0` and :math:`J = 1 + 10^{-12}`: eq. 66. The state is already the
    normal form :math:`z = (y, \dot y)` and :math:`\varphi(z, u) = \ddot x_1`.

    The pivot rides a carriage 1e9 times heavier than the bob, driven by a force equal to the
    translating mass times ``u``: the carriage acceleration equals ``a u`` up to the bob's
    reaction, a relative :math:`m / M_t \approx 10^{-9}` that the analytic model leaves out.

    Parameters (``param_names``): ``g``, ``length``, ``mass``, ``inertia`` (about the pivot),
    ``damping``, ``accel_gain``; read by :meth:`from_mjmodel` from body ``pole``, joints
    ``hinge`` and ``slider``, actuator ``acceleration``.

    Forms (:meth:`~hgo_mj.systems.base.System.form`): ``"aocf"`` (paper 002, eq. 2.2) and
    ``"kalman_fields"``.

    Parameters
    ----------
    **params : float
        Values of some of ``param_names`` (e.g. ``damping=0.1``); the others are read from
        the shipped ``models/cart_pendulum.xml``.

    Raises
    ------
    DesignError
        An unknown or non-finite parameter, or ``length``, ``mass`` or ``inertia`` not
        positive.

    References
    ----------
    .. [1] S. Ibrir, "On observer design for nonlinear systems", Int. J. Control (2007),
       Section 4.1, eq. (66).

    Examples
    --------
    >>> cp = CartPendulum()
    >>> cp
    CartPendulum(g=1, length=1, mass=1, inertia=1, damping=0, accel_gain=1)
    >>> round(cp.phi([0.1, 0.0], [0.5]), 6)  # sin(0.1) + 0.5 cos(0.1)
    0.597335
    >>> cp.form("aocf").theta_names
    ('g_over_l', 'b_over_J')
    """

    name = "cart_pendulum"
    summary = "inverted pendulum driven by pivot acceleration, Ibrir 2007 eq. 66 (MuJoCo)"
    reference = "Ibrir (2007), On observer design for nonlinear systems, eq. 66"
    state_names = ("angle", "angular_velocity")
    state_units = ("rad", "rad/s")
    input_names = ("acceleration",)
    input_units = ("m/s^2",)
    output_names = ("angle",)
    param_names = ("g", "length", "mass", "inertia", "damping", "accel_gain")
    compiled = CartPendulumModel()
    _positive = ("length", "mass", "inertia")
    default_x0 = (0.1, 0.0)
    normal_form_order = 2
    model_file = "cart_pendulum.xml"
    joints = ("hinge",)
    actuators = ("acceleration",)
    forms = ("kalman_fields", "aocf")

    def _form_kalman_fields(self) -> dict[str, str]:
        """The ``"kalman_fields"`` form: the MJCF fields an augmented MuJoCo Kalman filter
        may estimate under this system's parameter names (g),
        ``{name: "field[element]" or "opt.gravity"}``."""
        return {"g": "opt.gravity"}

    def _form_aocf(self, c2: float = 2.0, unknown: Any = None,
                   damping_known: str = "ratio") -> AOCF:
        """The AOCF (paper 002, eq. 2.2) of :math:`\\ddot y = -\\delta \\dot y + a \\sin y
        + \\beta u \\cos y` with :math:`a = m l g / J` (``g_over_l``), :math:`\\beta = m l a_u / J`
        (``b_over_J``), :math:`\\delta = d/J` (``d_over_J``): :func:`~hgo_mj.systems.aocf.joint_aocf`
        (``damping_known="coefficient"`` is derived for the pendulum only)."""
        p = self.params
        J, ml = p["inertia"], p["mass"] * p["length"]
        return joint_aocf(self, _aocf_features, ("sin y", "u cos y"),
                          "cart pendulum: y'' = -d/J y' + a sin y + b u cos y",
                          (ml * p["g"] / J, ml * p["accel_gain"] / J),
                          c2=c2, unknown=unknown, damping_known=damping_known, coefficient=False)

    @classmethod
    def params_from_mjmodel(cls, model: Any) -> dict[str, float]:
        r = _MjReader(model, cls.__name__)
        r.parent("pole", "carriage")
        r.parent("carriage", None)
        _, dof, anchor, axis = r.joint("hinge")
        mass, r_perp, inertia = r.about_axis("pole", anchor, axis)
        length = r.along("the bob", r_perp, -r.down)  # upright at q = 0: COM above the pivot
        if not length > 0:
            raise DesignError(f"{cls.__name__}: the bob must be above the pivot at angle 0; "
                              f"found it {-length:g} below")
        js, sdof, _, e = r.joint("slider", kind="slide")
        if int(model.jnt_bodyid[js]) != r.body("carriage"):
            raise DesignError(f"{cls.__name__}: joint 'slider' must move body 'carriage'")
        # Bob displacement per radian at angle 0 is axis x r; its component along the slider
        # gives the sign with which the pivot acceleration enters: J x1'' = -m (e . axis x r) ...
        coupling = -float(e @ np.cross(axis, r_perp / length))
        if abs(abs(coupling) - 1.0) > _TOL:
            raise DesignError(f"{cls.__name__}: the slider axis must lie in the pendulum's "
                              f"swing plane; found |e . (axis x r)| = {abs(coupling):.6g}")
        translating = float(model.body_subtreemass[r.body("carriage")]) + r.armature(sdof)
        gain = coupling * r.gear("acceleration", "slider") / translating
        return {"g": r.g, "length": length, "mass": mass, "inertia": inertia,
                "damping": r.damping(dof), "accel_gain": gain}

    @staticmethod
    def _acceleration(q: float, v: float, u0: float, p: Mapping[str, float]) -> float:
        return _acceleration_row(q, v, u0, p["mass"], p["length"], p["g"], p["accel_gain"],
                                 p["damping"], p["inertia"])

    def phi_batch(self, Z: Array, U: Array) -> Array:
        """:meth:`phi_unchecked` of the rows ``Z`` ``(N, 2)``, ``U`` ``(N, 1)``, compiled (equal
        to the scalar path bit for bit)."""
        return _phi_rows(np.ascontiguousarray(Z, dtype=float),  # type: ignore[no-any-return]
                         np.ascontiguousarray(U, dtype=float), self._phi_constants)

    @cached_property
    def _phi_constants(self) -> Array:
        """The parameters of :func:`_phi_rows`, made once (a system's parameters are fixed at
        construction)."""
        p = self.params
        return np.array([p["mass"], p["length"], p["g"], p["accel_gain"], p["damping"],
                         p["inertia"]])

    @staticmethod
    def dynamics(t: float, x: Array, u: Array, p: Mapping[str, float]) -> Array:
        th, w = float(x[0]), float(x[1])
        return np.array([w, CartPendulum._acceleration(th, w, float(u[0]), p)])

    @staticmethod
    def output(x: Array, p: Mapping[str, float]) -> Array:
        return np.array([float(x[0])])

