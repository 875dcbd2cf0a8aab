"""A planar two-link arm with two elastic joints (``models/elastic_joint_2link.xml``)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numba import njit
from numba.extending import register_jitable

from ..exceptions import DesignError
from ._mujoco import _MjReader, _MujocoSystem
from .base import Array, CompiledModel

__all__ = ["ElasticJoint2Link"]


@njit(cache=True)
def _affine_parts(z: Array, u0: float, u1: float, c: Array) -> tuple[float, ...]:
    """The pieces of the two-link form eq. 21 at one point ``z = (q1, q1', q1'', q1''', q2,
    ...)`` (``ElasticJoint2Link._form_affine``): ``M^-1`` (``i11, i12, i22``), the right-hand
    side ``r`` of ``M q'''' = r + diag(w) K``, ``w``, and ``L = M q'' + c + g + D q'``, ``L'``.
    ``c = (alpha, beta, I2, g s1', g s2, d1, d2, J1, J2, dm1, dm2, b1, b2)``."""
    alpha, beta, i2, gs1, gs2 = c[0], c[1], c[2], c[3], c[4]
    d1, d2, J1, J2, dm1, dm2, b1, b2 = c[5], c[6], c[7], c[8], c[9], c[10], c[11], c[12]
    q1, w1, a1, j1, q2, w2, a2, j2 = z[0], z[1], z[2], z[3], z[4], z[5], z[6], z[7]
    c2, sn2 = math.cos(q2), math.sin(q2)
    # inertia matrix and its time derivatives (M' = dM/dq2 * w2, ...)
    m11 = alpha + 2.0 * beta * c2
    m12 = i2 + beta * c2
    m22 = i2
    dfac = -beta * sn2 * w2                     # d/dt (beta cos q2)
    ddfac = -beta * (c2 * w2 * w2 + sn2 * a2)   # d2/dt2 (beta cos q2)
    # Coriolis c = h (v1, v2), h = beta sin q2
    h = beta * sn2
    hd = beta * c2 * w2
    hdd = beta * (c2 * a2 - sn2 * w2 * w2)
    v1 = -2.0 * w1 * w2 - w2 * w2
    v2 = w1 * w1
    v1d = -2.0 * (a1 * w2 + w1 * a2) - 2.0 * w2 * a2
    v2d = 2.0 * w1 * a1
    v1dd = -2.0 * (j1 * w2 + 2.0 * a1 * a2 + w1 * j2) - 2.0 * (a2 * a2 + w2 * j2)
    v2dd = 2.0 * (a1 * a1 + w1 * j1)
    cc1, cc2 = h * v1, h * v2
    cd1, cd2 = hd * v1 + h * v1d, hd * v2 + h * v2d
    cdd1 = hdd * v1 + 2.0 * hd * v1d + h * v1dd
    cdd2 = hdd * v2 + 2.0 * hd * v2d + h * v2dd
    # gravity and its derivatives
    sq1, cq1 = math.sin(q1), math.cos(q1)
    s12, c12 = math.sin(q1 + q2), math.cos(q1 + q2)
    ws, as_ = w1 + w2, a1 + a2
    gg1 = gs1 * sq1 + gs2 * s12
    gg2 = gs2 * s12
    gd1 = gs1 * cq1 * w1 + gs2 * c12 * ws
    gd2 = gs2 * c12 * ws
    gdd1 = gs1 * (cq1 * a1 - sq1 * w1 * w1) + gs2 * (c12 * as_ - s12 * ws * ws)
    gdd2 = gs2 * (c12 * as_ - s12 * ws * ws)
    # L = M q'' + c + g + D q' and L'
    L1 = m11 * a1 + m12 * a2 + cc1 + gg1 + d1 * w1
    L2 = m12 * a1 + m22 * a2 + cc2 + gg2 + d2 * w2
    Ld1 = (2.0 * dfac * a1 + dfac * a2 + m11 * j1 + m12 * j2) + cd1 + gd1 + d1 * a1
    Ld2 = (dfac * a1 + m12 * j1 + m22 * j2) + cd2 + gd2 + d2 * a2
    # rhs of M q'''' = ...
    r1 = (-dm1 / J1 * Ld1 - 2.0 * (2.0 * dfac * j1 + dfac * j2)
          - (2.0 * ddfac * a1 + ddfac * a2) - cdd1 - gdd1 - d1 * j1)
    r2 = (-dm2 / J2 * Ld2 - 2.0 * (dfac * j1) - (ddfac * a1) - cdd2 - gdd2 - d2 * j2)
    wv1 = (b1 * u0 - dm1 * w1 - L1) / J1 - a1
    wv2 = (b2 * u1 - dm2 * w2 - L2) / J2 - a2
    det = m11 * m22 - m12 * m12
    i11, i12, i22 = m22 / det, -m12 / det, m11 / det
    return i11, i12, i22, r1, r2, wv1, wv2, L1, L2, Ld1, Ld2


@njit(cache=True)
def _affine_terms(Z: Array, U: Array, c: Array) -> tuple[Array, Array]:
    """Rows of the two-link form eq. 21: ``phi = (0, 0, 0, [M^-1 r]_1, 0, 0, 0, [M^-1 r]_2)``,
    ``psi_last[c] = [M^-1 diag(w)]_c``."""
    N = Z.shape[0]
    phi = np.zeros((N, 8))
    psi = np.empty((N, 2, 2))
    for b in range(N):
        i11, i12, i22, r1, r2, wv1, wv2, _, _, _, _ = _affine_parts(Z[b], U[b, 0], U[b, 1], c)
        phi[b, 3] = i11 * r1 + i12 * r2
        phi[b, 7] = i12 * r1 + i22 * r2
        psi[b, 0, 0] = i11 * wv1
        psi[b, 0, 1] = i12 * wv2
        psi[b, 1, 0] = i12 * wv1
        psi[b, 1, 1] = i22 * wv2
    return phi, psi


@njit(cache=True)
def _affine_to_physical(Z: Array, TH: Array, U: Array, c: Array) -> Array:
    """Rows of ``x = (q1, q2, theta1, theta2, q1', q2', theta1', theta2')`` from ``z`` and the
    stiffness estimates: ``theta = q + K^-1 L``, ``theta' = q' + K^-1 L'``; NaN where an
    estimate is not > 0."""
    N = Z.shape[0]
    X = np.empty((N, 8))
    for b in range(N):
        k1, k2 = TH[b, 0], TH[b, 1]
        if not (k1 > 0.0 and k2 > 0.0):
            X[b, :] = np.nan
            continue
        _, _, _, _, _, _, _, L1, L2, Ld1, Ld2 = _affine_parts(Z[b], U[b, 0], U[b, 1], c)
        q1, w1, q2, w2 = Z[b, 0], Z[b, 1], Z[b, 4], Z[b, 5]
        X[b, 0] = q1
        X[b, 1] = q2
        X[b, 2] = q1 + L1 / k1
        X[b, 3] = q2 + L2 / k2
        X[b, 4] = w1
        X[b, 5] = w2
        X[b, 6] = w1 + Ld1 / k1
        X[b, 7] = w2 + Ld2 / k2
    return X


@register_jitable
def _dynamics_row(x: Array, u: Array, c: Array, out: Array) -> None:
    """``out = f(x, u)`` of the two-link arm (:meth:`ElasticJoint2Link.dynamics`, and compiled
    for the Kalman filters); ``c`` in the order of ``param_names``."""
    q1, q2, t1, t2, w1, w2, v1, v2 = x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7]
    (i1, s1, l1, m2, s2, i2, j1, j2, jr, k1, k2, dl1, dl2, dm1, dm2, b1, b2,
     g0) = (c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8], c[9], c[10], c[11], c[12],
            c[13], c[14], c[15], c[16], c[17])
    c2, sn2, s12 = math.cos(q2), math.sin(q2), math.sin(q1 + q2)
    m11 = i1 + i2 + m2 * l1 * l1 + 2.0 * l1 * s2 * c2 + jr
    m12 = i2 + l1 * s2 * c2
    h = l1 * s2 * sn2
    e1 = k1 * (q1 - t1)
    e2 = k2 * (q2 - t2)
    tau1 = (h * (2.0 * w1 * w2 + w2 * w2)
            - g0 * ((s1 + m2 * l1) * math.sin(q1) + s2 * s12)
            - dl1 * w1 - e1)
    tau2 = -h * w1 * w1 - g0 * s2 * s12 - dl2 * w2 - e2
    sig1 = e1 - dm1 * v1 + b1 * u[0]
    sig2 = e2 - dm2 * v2 + b2 * u[1]
    # eliminate theta2'' = (sig2 - jr q1'') / j2 from the link-1 row
    a11 = m11 - jr * jr / j2
    r1 = tau1 - jr * sig2 / j2
    det = a11 * i2 - m12 * m12
    q1dd = (i2 * r1 - m12 * tau2) / det
    q2dd = (a11 * tau2 - m12 * r1) / det
    out[0], out[1], out[2], out[3] = w1, w2, v1, v2
    out[4], out[5] = q1dd, q2dd
    out[6] = sig1 / j1
    out[7] = (sig2 - jr * q1dd) / j2


class ElasticJoint2LinkModel(CompiledModel):
    """The two-link arm's ODE for numba kernels (no analytic Jacobian: the filters
    difference it)."""

    __slots__ = ()
    dynamics = staticmethod(_dynamics_row)


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

    Forms (:meth:`~hgo_mj.systems.base.System.form`): ``"affine"`` (paper 001, eq. 21,
    unknown ``stiffness1``, ``stiffness2``) and ``"kalman_fields"``.

    Parameters
    ----------
    **params : float
        Values of some of ``param_names`` (e.g. ``stiffness2=8.0``); the others are read from
        the shipped ``models/elastic_joint_2link.xml``.

    Raises
    ------
    DesignError
        An unknown or non-finite parameter, or a link or motor inertia (``link1_inertia``,
        ``link2_inertia``, ``motor1_inertia``, ``motor2_inertia``) not positive.

    References
    ----------
    .. [1] M. W. Spong, "Modeling and control of elastic joint robots", ASME J. Dynamic
       Systems, Measurement, and Control 109(4) (1987), 310-319: the reduced model.
    .. [2] S. Nicosia and A. Tornambè, "High-gain observers in the state and parameter
       estimation of robots having elastic joints", Systems & Control Letters 13(4) (1989),
       331-337.

    Examples
    --------
    >>> arm = ElasticJoint2Link()
    >>> arm.params["stiffness1"], arm.params["stiffness2"], arm.normal_form_orders
    (20.0, 6.0, (4, 4))
    >>> arm.h(arm.default_x0)
    array([ 0.3, -0.2])
    >>> arm.f(0.0, arm.default_x0, [0.0, 0.0])[4:6].round(3)
    array([-14.383,  30.573])
    >>> arm.form("affine").theta_names
    ('stiffness1', 'stiffness2')
    """

    name = "elastic_joint_2link"
    summary = "planar two-link arm with two elastic joints, Spong 1987 (MuJoCo)"
    reference = "Spong (1987); Nicosia and Tornambè (1989)"
    state_names = ("link1_angle", "link2_angle", "motor1_angle", "motor2_angle",
                   "link1_velocity", "link2_velocity", "motor1_velocity", "motor2_velocity")
    state_units = ("rad",) * 4 + ("rad/s",) * 4
    input_names = ("torque1", "torque2")
    input_units = ("N m", "N m")
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
    forms = ("affine", "kalman_fields")
    compiled = ElasticJoint2LinkModel()

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
        out = np.empty(8)
        _dynamics_row(x, u, np.array([p[k] for k in ElasticJoint2Link.param_names]), out)
        return out

    @staticmethod
    def output(x: Array, p: Mapping[str, float]) -> Array:
        return np.array([float(x[0]), float(x[1])])

    # ------------------------------------------------------------------ forms
    def _form_affine(self, unknown: Any = None) -> Any:
        """The two-link elastic arm seen from both link angles: the two-output form eq. 21 of
        paper 001 (:class:`~hgo_mj.systems.affine_form.AffineForm`), unknown ``stiffness1``,
        ``stiffness2``.

        With :math:`z[c] = (q_c, \\dot q_c, \\ddot q_c, q_c^{(3)})` for :math:`c = 1, 2`
        (orders 4 and 4) and the link equation written as :math:`L := M(q)\\ddot q + c(q,
        \\dot q) + g(q) + D \\dot q = -K (q - \\theta)`, the motor equation
        :math:`J \\ddot\\theta + D_m \\dot\\theta - K(q - \\theta) = B u` with
        :math:`\\theta = q + K^{-1} L` gives, for diagonal :math:`K, J, D_m`,

        .. math::

            \\ddot L = K w - J^{-1} D_m \\dot L, \\qquad
            w = J^{-1}(B u - D_m \\dot q - L) - \\ddot q,

        and :math:`\\ddot L = M q^{(4)} + 2 \\dot M q^{(3)} + \\ddot M \\ddot q + \\ddot c
        + \\ddot g + D q^{(3)}`, so

        .. math::

            q^{(4)} = \\underbrace{M^{-1}\\left[-J^{-1} D_m \\dot L - 2 \\dot M q^{(3)}
                      - \\ddot M \\ddot q - \\ddot c - \\ddot g - D q^{(3)}\\right]}_{\\varphi}
                      + \\underbrace{M^{-1} \\mathrm{diag}(w)}_{\\psi}
                        \\begin{pmatrix} K_1 \\\\ K_2 \\end{pmatrix}.

        Both stiffnesses enter both chains' last rows (through :math:`M^{-1}`), the orders are
        equal, so eq. 24 applies with :math:`I_\\lambda = \\lambda^4 I`. The structure [A1']
        holds: each chain's last entry depends on the other chain. The motor-2 rotor body's
        axial inertia :math:`J_r = 10^{-12}` kg m^2 of the MJCF is neglected (Spong's
        assumption); the time derivatives of :math:`M, c, g` along the trajectory are
        analytic. The map to the physical state (motor angles) is ``to_physical``.

        Raises
        ------
        DesignError
            ``unknown`` is given and is not ``("stiffness1", "stiffness2")``.

        References
        ----------
        Paper 001, eq. 21 ([A1']), eq. 24; Spong (1987) for the model.
        """
        from .affine_form import AffineForm

        if unknown is not None and tuple(unknown) != ("stiffness1", "stiffness2"):
            raise DesignError(f"the two-link form estimates ['stiffness1', 'stiffness2']; found "
                              f"unknown={list(unknown)}")
        p = dict(self.params)
        l1, s2, i2, m2 = p["link1_length"], p["link2_moment"], p["link2_inertia"], p["link2_mass"]
        g0 = p["g"]
        c = np.array([p["link1_inertia"] + i2 + m2 * l1 * l1, l1 * s2, i2,
                      g0 * (p["link1_moment"] + m2 * l1), g0 * s2,
                      p["link1_damping"], p["link2_damping"],
                      p["motor1_inertia"], p["motor2_inertia"],
                      p["motor1_damping"], p["motor2_damping"], p["gear1"], p["gear2"]])

        def terms(Z: Array, U: Array) -> tuple[Array, Array]:
            return _affine_terms(Z, U, c)  # type: ignore[no-any-return]

        def to_physical(Z: Array, TH: Array, U: Array) -> Array:
            return _affine_to_physical(Z, TH, U, c)  # type: ignore[no-any-return]

        names = ("link1_angle", "link1_velocity", "link1_acceleration", "link1_jerk",
                 "link2_angle", "link2_velocity", "link2_acceleration", "link2_jerk")
        return AffineForm(orders=(4, 4), theta_names=("stiffness1", "stiffness2"), terms=terms,
                          label="two-link elastic arm, both link angles, unknown K1, K2",
                          theta=[p["stiffness1"], p["stiffness2"]], state_names=names,
                          n_inputs=2, to_physical=to_physical,
                          physical_state_names=self.state_names,
                          true_physical={"stiffness1": p["stiffness1"],
                                         "stiffness2": p["stiffness2"]}
                          )._made_by(ElasticJoint2Link._form_affine, self, unknown)
