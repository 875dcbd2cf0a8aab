"""A single link driven through an elastic joint (``models/elastic_joint.xml``)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ._mujoco import _MjReader, _MujocoSystem
from .base import Array


class ElasticJoint(_MujocoSystem):
    r"""One link driven by a motor through a torsional spring: Spong's elastic-joint model.

    .. math::

        I \ddot q &= -M g L \sin q - K (q - \theta) - d_l \dot q, \\
        J \ddot\theta &= K (q - \theta) - d_m \dot\theta + b u, \qquad y = q,

    with :math:`q` the link angle from hanging down, :math:`\theta` the motor angle, :math:`I`
    the link inertia about the joint, :math:`M g L` the gravity load, :math:`J` the motor
    inertia, :math:`K` the joint stiffness, :math:`d_l, d_m` viscous damping and :math:`b` the
    actuator gear. State ``x = (q, theta, q', theta')``.

    Only the link angle is measured. The output has relative degree 4, and the
    observability normal form :math:`z = (y, \dot y, \ddot y, y^{(3)})` follows from
    differentiating the link equation:

    .. math::

        z_3 &= \left(-M g L \sin q - K (q - \theta) - d_l \dot q\right) / I, \\
        z_4 &= \left(-M g L \cos q\, \dot q - K (\dot q - \dot\theta) - d_l z_3\right) / I, \\
        \varphi(z, u) &= \left(M g L \sin z_1\, z_2^2 - M g L \cos z_1\, z_3
                         - K (z_3 - \ddot\theta) - d_l z_4\right) / I,

    with :math:`\ddot\theta = (K (q - \theta) - d_m \dot\theta + b u) / J`. The inverse map
    (:meth:`from_normal`) recovers the motor side:

    .. math::

        \theta = z_1 + \left(I z_3 + M g L \sin z_1 + d_l z_2\right) / K, \qquad
        \dot\theta = z_2 + \left(I z_4 + M g L \cos z_1\, z_2 + d_l z_3\right) / K.

    Parameters (``param_names``): ``link_inertia`` I [kg m^2], ``motor_inertia`` J [kg m^2]
    (rotor axial inertia plus armature), ``mass`` M [kg], ``com_distance`` L [m], ``g``
    [m/s^2], ``stiffness`` K [N m/rad], ``link_damping`` d_l and ``motor_damping`` d_m
    [N m s/rad], ``gear`` b; read by :meth:`from_mjmodel` from bodies ``link`` and ``rotor``,
    joints ``link`` and ``motor``, tendon ``spring``, actuator ``torque``. The fast paths
    ``_to_normal(x, p)``, ``_from_normal(z, p)`` and ``_phi(z, u, p)`` skip validation.

    References
    ----------
    .. [1] M. W. Spong, "Modeling and control of elastic joint robots", ASME J. Dynamic
       Systems, Measurement, and Control 109(4) (1987), 310-319: the reduced model, in which
       the rotor's kinetic energy is due to its own rotation only (equation numbers not
       checked against the original here).
    .. [2] S. Nicosia and A. Tornambè, "High-gain observers in the state and parameter
       estimation of robots having elastic joints", Systems & Control Letters 13(4) (1989),
       331-337.
    """

    name = "elastic_joint"
    summary = "single link with an elastic joint, Spong 1987 (MuJoCo)"
    reference = "Spong (1987); Nicosia and Tornambè (1989)"
    state_names = ("link_angle", "motor_angle", "link_velocity", "motor_velocity")
    input_names = ("torque",)
    output_names = ("link_angle",)
    param_names = ("link_inertia", "motor_inertia", "mass", "com_distance", "g", "stiffness",
                   "link_damping", "motor_damping", "gear")
    _positive = ("link_inertia", "motor_inertia", "stiffness")
    default_x0 = (0.3, 0.3, 0.0, 0.0)
    normal_form_order = 4
    model_file = "elastic_joint.xml"
    joints = ("link", "motor")
    actuators = ("torque",)
    forms = ("kalman_fields",)

    def _form_kalman_fields(self) -> dict[str, str]:
        """The ``"kalman_fields"`` form: the MJCF fields an augmented MuJoCo Kalman filter
        may estimate under this system's parameter names (the spring, gear, the two dampings
        and g, which carries :math:`M g L`), ``{name: "field[element]" or "opt.gravity"}``."""
        return {"stiffness": "tendon_stiffness[spring]",
                "gear": "actuator_gear[torque]",
                "link_damping": "dof_damping[link]",
                "motor_damping": "dof_damping[motor]",
                "g": "opt.gravity"}

    @classmethod
    def params_from_mjmodel(cls, model: Any) -> dict[str, float]:
        r = _MjReader(model, cls.__name__)
        r.parent("link", None)
        r.parent("rotor", None)
        _, ldof, lanchor, laxis = r.joint("link")
        mass, r_perp, link_inertia = r.about_axis("link", lanchor, laxis)
        _, mdof, manchor, maxis = r.joint("motor")
        _, rotor_perp, rotor_inertia = r.about_axis("rotor", manchor, maxis)
        r.on_axis("rotor", rotor_perp)
        return {"link_inertia": link_inertia,
                "motor_inertia": rotor_inertia + r.armature(mdof),
                "mass": mass, "com_distance": r.along("the link's COM", r_perp, r.down),
                "g": r.g, "stiffness": r.spring("spring", "link", "motor"),
                "link_damping": r.damping(ldof), "motor_damping": r.damping(mdof),
                "gear": r.gear("torque", "motor")}

    @staticmethod
    def dynamics(t: float, x: Array, u: Array, p: Mapping[str, float]) -> Array:
        q, th, w, v = float(x[0]), float(x[1]), float(x[2]), float(x[3])
        tau = p["stiffness"] * (q - th)
        mgl = p["mass"] * p["g"] * p["com_distance"]
        qdd = (-mgl * math.sin(q) - tau - p["link_damping"] * w) / p["link_inertia"]
        thdd = (tau - p["motor_damping"] * v + p["gear"] * float(u[0])) / p["motor_inertia"]
        return np.array([w, v, qdd, thdd])

    @staticmethod
    def output(x: Array, p: Mapping[str, float]) -> Array:
        return np.array([float(x[0])])

    @staticmethod
    def jacobian(t: float, x: Array, u: Array, p: Mapping[str, float]) -> Array:
        """:math:`\\partial f / \\partial x` of :meth:`dynamics`, shape (4, 4) (used by the
        Kalman filters of :mod:`hgo_mj.observers.kalman`)."""
        I, J, k = p["link_inertia"], p["motor_inertia"], p["stiffness"]
        mgl = p["mass"] * p["g"] * p["com_distance"]
        return np.array([[0.0, 0.0, 1.0, 0.0],
                         [0.0, 0.0, 0.0, 1.0],
                         [(-mgl * math.cos(float(x[0])) - k) / I, k / I, -p["link_damping"] / I, 0.0],
                         [k / J, -k / J, 0.0, -p["motor_damping"] / J]])

    @staticmethod
    def param_jacobian(t: float, x: Array, u: Array, p: Mapping[str, float],
                       names: tuple[str, ...]) -> Array:
        """:math:`\\partial f / \\partial p` of :meth:`dynamics` for the parameters ``names``,
        shape (4, len(names))."""
        q, th, w, v, uu = (float(x[0]), float(x[1]), float(x[2]), float(x[3]), float(u[0]))
        I, J = p["link_inertia"], p["motor_inertia"]
        M, g, L, s = p["mass"], p["g"], p["com_distance"], math.sin(q)
        qdd, thdd = ElasticJoint.dynamics(t, x, u, p)[2:].tolist()
        d = {"stiffness": (-(q - th) / I, (q - th) / J), "mass": (-g * L * s / I, 0.0),
             "com_distance": (-M * g * s / I, 0.0), "g": (-M * L * s / I, 0.0),
             "link_damping": (-w / I, 0.0), "motor_damping": (0.0, -v / J),
             "gear": (0.0, uu / J), "link_inertia": (-qdd / I, 0.0),
             "motor_inertia": (0.0, -thdd / J)}
        out = np.zeros((4, len(names)))
        for j, nm in enumerate(names):
            out[2, j], out[3, j] = d[nm]
        return out

    # ------------------------------------------------------------- normal form (fast)
    @staticmethod
    def _to_normal(x: Array, p: Mapping[str, float]) -> Array:
        q, th, w, v = float(x[0]), float(x[1]), float(x[2]), float(x[3])
        inertia, k, dl = p["link_inertia"], p["stiffness"], p["link_damping"]
        mgl = p["mass"] * p["g"] * p["com_distance"]
        a = (-mgl * math.sin(q) - k * (q - th) - dl * w) / inertia
        j = (-mgl * math.cos(q) * w - k * (w - v) - dl * a) / inertia
        return np.array([q, w, a, j])

    @staticmethod
    def _from_normal(z: Array, p: Mapping[str, float]) -> Array:
        q, w, a, j = float(z[0]), float(z[1]), float(z[2]), float(z[3])
        inertia, k, dl = p["link_inertia"], p["stiffness"], p["link_damping"]
        mgl = p["mass"] * p["g"] * p["com_distance"]
        th = q + (inertia * a + mgl * math.sin(q) + dl * w) / k
        v = w + (inertia * j + mgl * math.cos(q) * w + dl * a) / k
        return np.array([q, th, w, v])

    @staticmethod
    def _phi(z: Array, u: Array, p: Mapping[str, float]) -> float:
        q, w, a, j = float(z[0]), float(z[1]), float(z[2]), float(z[3])
        inertia, k, dl = p["link_inertia"], p["stiffness"], p["link_damping"]
        mgl = p["mass"] * p["g"] * p["com_distance"]
        s, c = math.sin(q), math.cos(q)
        # spring torque K (q - theta) and motor velocity from the inverse map
        tau = -(inertia * a + mgl * s + dl * w)
        v = w + (inertia * j + mgl * c * w + dl * a) / k
        thdd = (tau - p["motor_damping"] * v + p["gear"] * float(u[0])) / p["motor_inertia"]
        return (mgl * s * w * w - mgl * c * a - k * (a - thdd) - dl * j) / inertia

    # ------------------------------------------------------------- normal form (public)
    def to_normal(self, x: Any, u: Any = None) -> Array:
        """``z = (q, q', q'', q''')`` from ``x = (q, theta, q', theta')``."""
        self._require_normal_form()
        self._u(u, required=False)
        return self._to_normal(self._x(x), self.params)

    def from_normal(self, z: Any, u: Any = None) -> Array:
        """``x = (q, theta, q', theta')`` from ``z`` (inverse of :meth:`to_normal`)."""
        self._u(u, required=False)
        return self._from_normal(self._z(z), self.params)

    def phi(self, z: Any, u: Any = None) -> float:
        """``y'''' = phi(z, u)``, damping included."""
        z = self._z(z)
        u = self._u(u, required=True)
        return self._phi(z, u, self.params)

    def from_normal_unchecked(self, z: Array, u: Array) -> Array:
        return self._from_normal(z, self.params)

    def phi_unchecked(self, z: Array, u: Array) -> float:
        return self._phi(z, u, self.params)
