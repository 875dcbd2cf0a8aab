"""A planar two-link arm with two elastic joints (``models/elastic_joint_2link.xml``)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ._mujoco import _MjReader, _MujocoSystem
from .base import Array


class ElasticJoint2Link(_MujocoSystem):
    r"""Two-link arm in a vertical plane, each joint elastic (Spong's reduced model).

    Link angles :math:`q = (q_1, q_2)` (``q1`` from hanging down, ``q2`` relative to link 1),
    motor angles :math:`\theta = (\theta_1, \theta_2)` (motor 2 sits on link 1, its angle
    relative to link 1), torques :math:`u = (u_1, u_2)`:

    .. math::

        M(q) \ddot q + c(q, \dot q) + g(q) + D \dot q + K (q - \theta)
            + \begin{pmatrix} J_r \ddot\theta_2 \\ 0 \end{pmatrix} &= 0, \\
        J \ddot\theta + D_m \dot\theta - K (q - \theta)
            + \begin{pmatrix} 0 \\ J_r \ddot q_1 \end{pmatrix} &= B u,

    with, writing :math:`s_2 = m_2 l_{c2}` for link 2's first mass moment about the elbow,
    :math:`s_1` for link 1's about the shoulder, :math:`I_1, I_2` the link inertias about their
    own joints and :math:`l_1` the link-1 length,

    .. math::

        M_{11} &= I_1 + I_2 + m_2 l_1^2 + 2 l_1 s_2 \cos q_2 + J_r, \quad
        M_{12} = I_2 + l_1 s_2 \cos q_2, \quad M_{22} = I_2, \\
        c &= l_1 s_2 \sin q_2 \begin{pmatrix} -2 \dot q_1 \dot q_2 - \dot q_2^2 \\
                                              \dot q_1^2 \end{pmatrix}, \qquad
        g = g_0 \begin{pmatrix} (s_1 + m_2 l_1) \sin q_1 + s_2 \sin(q_1 + q_2) \\
                                 s_2 \sin(q_1 + q_2) \end{pmatrix},

    :math:`D = \mathrm{diag}(d_1, d_2)`, :math:`D_m = \mathrm{diag}(d_{m1}, d_{m2})`,
    :math:`K = \mathrm{diag}(K_1, K_2)`, :math:`J = \mathrm{diag}(J_1, J_2)`,
    :math:`B = \mathrm{diag}(b_1, b_2)`. :math:`J_r` is the axial inertia of the motor-2 rotor
    *body* alone: its spin rate is :math:`\dot q_1 + \dot\theta_2`, so it couples link 1 and
    motor 2. Spong's assumption is :math:`J_r = 0`; MuJoCo needs a positive inertia, so the
    MJCF sets :math:`J_r = 10^{-12}` kg m^2 (the motor inertia itself is joint armature) and
    the model carries the term to stay exact. The rotor body's mass sits on the elbow axis and
    is counted in link 1's :math:`I_1, s_1`.

    State ``x = (q1, q2, theta1, theta2, q1', q2', theta1', theta2')``; outputs the two link
    angles. With two outputs there is no single-output normal form
    (``normal_form_order = None``); the multi-output structure is declared instead:
    ``normal_form_orders = (4, 4)``, each link angle with its first three derivatives, which
    the multi-output high-gain observer (``high_gain_multi``) reads when no orders are given.
    Each link angle has relative degree 4 under Spong's assumption :math:`J_r = 0` (the
    torques reach :math:`q^{(4)}` through the springs); with the MJCF's
    :math:`J_r = 10^{-12}` kg m^2, :math:`u_2` also enters :math:`\ddot q_1`, with a coefficient
    of order :math:`J_r b_2 / (J_2 M_{11})`: a negligible disturbance of the first chain.

    Parameters (``param_names``): ``link1_inertia`` I1, ``link1_moment`` s1,
    ``link1_length`` l1, ``link2_mass`` m2, ``link2_moment`` s2, ``link2_inertia`` I2,
    ``motor1_inertia`` J1, ``motor2_inertia`` J2 (armature plus J_r), ``rotor2_inertia`` J_r,
    ``stiffness1`` K1, ``stiffness2`` K2, ``link1_damping`` d1, ``link2_damping`` d2,
    ``motor1_damping`` dm1, ``motor2_damping`` dm2, ``gear1`` b1, ``gear2`` b2, ``g`` g0
    (SI units); read by :meth:`from_mjmodel`.

    References
    ----------
    .. [1] M. W. Spong, "Modeling and control of elastic joint robots", ASME J. Dynamic
       Systems, Measurement, and Control 109(4) (1987), 310-319: the reduced model.
    .. [2] S. Nicosia and A. Tornambè, "High-gain observers in the state and parameter
       estimation of robots having elastic joints", Systems & Control Letters 13(4) (1989),
       331-337.
    """

    name = "elastic_joint_2link"
    summary = "planar two-link arm with two elastic joints, Spong 1987 (MuJoCo)"
    reference = "Spong (1987); Nicosia and Tornambè (1989)"
    state_names = ("link1_angle", "link2_angle", "motor1_angle", "motor2_angle",
                   "link1_velocity", "link2_velocity", "motor1_velocity", "motor2_velocity")
    input_names = ("torque1", "torque2")
    output_names = ("link1_angle", "link2_angle")
    param_names = ("link1_inertia", "link1_moment", "link1_length", "link2_mass",
                   "link2_moment", "link2_inertia", "motor1_inertia", "motor2_inertia",
                   "rotor2_inertia", "stiffness1", "stiffness2", "link1_damping",
                   "link2_damping", "motor1_damping", "motor2_damping", "gear1", "gear2", "g")
    _positive = ("link1_inertia", "link2_inertia", "motor1_inertia", "motor2_inertia")
    default_x0 = (0.3, -0.2, 0.3, -0.2, 0.0, 0.0, 0.0, 0.0)
    normal_form_order = None
    #: chain orders of the multi-output normal form, one per output (see the class docstring)
    normal_form_orders = (4, 4)
    model_file = "elastic_joint_2link.xml"
    joints = ("link1", "link2", "motor1", "motor2")
    actuators = ("torque1", "torque2")
    forms = ("kalman_fields",)

    def _form_kalman_fields(self) -> dict[str, str]:
        """The ``"kalman_fields"`` form: the MJCF fields an augmented MuJoCo Kalman filter
        may estimate under this system's parameter names (the two springs and g),
        ``{name: "field[element]" or "opt.gravity"}``."""
        return {"stiffness1": "tendon_stiffness[spring1]",
                "stiffness2": "tendon_stiffness[spring2]",
                "g": "opt.gravity"}

    @classmethod
    def params_from_mjmodel(cls, model: Any) -> dict[str, float]:
        r = _MjReader(model, cls.__name__)
        for body, parent in (("link1", None), ("rotor1", None), ("link2", "link1"),
                             ("rotor2", "link1")):
            r.parent(body, parent)
        r.same_axis_direction(("link1", "link2", "motor1", "motor2"))
        _, d1, a1, ax = r.joint("link1")
        _, d2, a2, _ = r.joint("link2")
        _, dm1, am1, _ = r.joint("motor1")
        _, dm2, am2, _ = r.joint("motor2")
        # link 1 with the motor-2 rotor body as a point mass on the elbow axis
        m1, r1, i1 = r.about_axis("link1", a1, ax)
        mr, rr, ir = r.about_axis("rotor2", a1, ax)
        _, rr_own, jr = r.about_axis("rotor2", am2, ax)
        r.on_axis("rotor2", rr_own)
        s1 = (r.along("link 1's COM", r1, r.down) * m1
              + r.along("the motor-2 rotor", rr, r.down) * mr)
        l1 = r.along("the elbow joint", (a2 - a1) - ((a2 - a1) @ ax) * ax, r.down)
        m2, r2, i2 = r.about_axis("link2", a2, ax)
        _, rm1, jm1 = r.about_axis("rotor1", am1, ax)
        r.on_axis("rotor1", rm1)
        return {"link1_inertia": i1 + (ir - jr), "link1_moment": s1, "link1_length": l1,
                "link2_mass": m2, "link2_moment": m2 * r.along("link 2's COM", r2, r.down),
                "link2_inertia": i2, "motor1_inertia": jm1 + r.armature(dm1),
                "motor2_inertia": jr + r.armature(dm2), "rotor2_inertia": jr,
                "stiffness1": r.spring("spring1", "link1", "motor1"),
                "stiffness2": r.spring("spring2", "link2", "motor2"),
                "link1_damping": r.damping(d1), "link2_damping": r.damping(d2),
                "motor1_damping": r.damping(dm1), "motor2_damping": r.damping(dm2),
                "gear1": r.gear("torque1", "motor1"), "gear2": r.gear("torque2", "motor2"),
                "g": r.g}

    @staticmethod
    def dynamics(t: float, x: Array, u: Array, p: Mapping[str, float]) -> Array:
        q1, q2, t1, t2, w1, w2, v1, v2 = (float(v) for v in x)
        l1, s2, i2, jr, j2 = (p["link1_length"], p["link2_moment"], p["link2_inertia"],
                              p["rotor2_inertia"], p["motor2_inertia"])
        c2, sn2, s12 = math.cos(q2), math.sin(q2), math.sin(q1 + q2)
        m11 = p["link1_inertia"] + i2 + p["link2_mass"] * l1 * l1 + 2.0 * l1 * s2 * c2 + jr
        m12 = i2 + l1 * s2 * c2
        h = l1 * s2 * sn2
        g0 = p["g"]
        e1 = p["stiffness1"] * (q1 - t1)
        e2 = p["stiffness2"] * (q2 - t2)
        tau1 = (h * (2.0 * w1 * w2 + w2 * w2)
                - g0 * ((p["link1_moment"] + p["link2_mass"] * l1) * math.sin(q1) + s2 * s12)
                - p["link1_damping"] * w1 - e1)
        tau2 = -h * w1 * w1 - g0 * s2 * s12 - p["link2_damping"] * w2 - e2
        sig1 = e1 - p["motor1_damping"] * v1 + p["gear1"] * float(u[0])
        sig2 = e2 - p["motor2_damping"] * v2 + p["gear2"] * float(u[1])
        # eliminate theta2'' = (sig2 - jr q1'') / j2 from the link-1 row
        a11 = m11 - jr * jr / j2
        r1 = tau1 - jr * sig2 / j2
        det = a11 * i2 - m12 * m12
        q1dd = (i2 * r1 - m12 * tau2) / det
        q2dd = (a11 * tau2 - m12 * r1) / det
        return np.array([w1, w2, v1, v2, q1dd, q2dd, sig1 / p["motor1_inertia"],
                         (sig2 - jr * q1dd) / j2])

    @staticmethod
    def output(x: Array, p: Mapping[str, float]) -> Array:
        return np.array([float(x[0]), float(x[1])])
