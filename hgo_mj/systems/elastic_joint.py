"""A single link driven through an elastic joint (``models/elastic_joint.xml``)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from functools import cached_property
from typing import Any

import numpy as np
from numba import njit
from numba.extending import register_jitable

from ..exceptions import DesignError, DimensionError
from ._mujoco import _MjReader, _MujocoSystem
from .base import Array, CompiledModel
from .jo_son_form import JoSonForm

__all__ = ["AFFINE_PARAMS", "ElasticJoint", "jo_son_motor_side"]

#: the parameters of the elastic joint's affine form (paper 001, eq. 9)
AFFINE_PARAMS = ("MgL", "stiffness")


@njit(cache=True)
def _affine_terms(Z: Array, U: Array, c: Array, mode: int) -> tuple[Array, Array]:
    """Rows of the elastic joint's form eq. 9 (``ElasticJoint._form_affine``):
    ``y^(4) = phi_4 + psi_1 MgL + psi_2 K + psi_3 K MgL``. ``c = (I, J, d_l/I, d_m/J, d_m,
    b, K, MgL)``; ``mode`` 0: theta = (MgL, K, K MgL); 1: theta = MgL (K known); 2: theta = K
    (MgL known)."""
    I, J, delta, rm, dm, bg, k_true, mgl_true = c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]
    IJ = I * J
    N = Z.shape[0]
    phi = np.zeros((N, 4))
    psi = np.empty((N, 1, 3 if mode == 0 else 1))
    for b in range(N):
        z1, z2, z3, z4 = Z[b, 0], Z[b, 1], Z[b, 2], Z[b, 3]
        s, co = math.sin(z1), math.cos(z1)
        ps1 = (s * z2 * z2 - co * z3 - rm * co * z2) / I
        ps2 = -z3 / I - (z3 + delta * z2) / J - dm * z2 / IJ + bg * U[b, 0] / IJ
        ps3 = -s / IJ
        ph = -delta * z4 - rm * (z4 + delta * z3)
        if mode == 0:
            phi[b, 3] = ph
            psi[b, 0, 0] = ps1
            psi[b, 0, 1] = ps2
            psi[b, 0, 2] = ps3
        elif mode == 1:
            phi[b, 3] = ph + k_true * ps2
            psi[b, 0, 0] = ps1 + k_true * ps3
        else:
            phi[b, 3] = ph + mgl_true * ps1
            psi[b, 0, 0] = ps2 + mgl_true * ps3
    return phi, psi


@njit(cache=True)
def _affine_to_physical(Z: Array, TH: Array, c: Array, mode: int) -> Array:
    """Rows of ``x = (q, theta, q', theta')`` from ``z`` and the parameter estimates (the
    inverse normal-form map with ``K``, ``MgL`` from ``theta``); NaN where undefined (a
    stiffness estimate not > 0, a non-finite load). ``c = (I, d_l, K, m, g, L)``."""
    I, dl, k_true, m_true, g, L = c[0], c[1], c[2], c[3], c[4], c[5]
    N = Z.shape[0]
    X = np.empty((N, 4))
    for b in range(N):
        k, mass = k_true, m_true
        if mode == 0:
            k = TH[b, 1]
            mass = (TH[b, 2] / k if k != 0.0 else np.nan) / (g * L)
        elif mode == 1:
            mass = TH[b, 0] / (g * L)
        else:
            k = TH[b, 0]
        mgl = mass * g * L
        if not (k > 0.0) or not math.isfinite(mgl):
            X[b, :] = np.nan
            continue
        q, w, a, j = Z[b, 0], Z[b, 1], Z[b, 2], Z[b, 3]
        X[b, 0] = q
        X[b, 1] = q + (I * a + mgl * math.sin(q) + dl * w) / k
        X[b, 2] = w
        X[b, 3] = w + (I * j + mgl * math.cos(q) * w + dl * a) / k
    return X


def _from_normal_row(q: float, w: float, a: float, j: float, inertia: float, k: float,
                     dl: float, mass: float, g: float, lc: float) -> tuple[float, float]:
    """The motor side ``(theta, theta')`` of the inverse normal-form map, once: the scalar path
    (:meth:`ElasticJoint._from_normal`, plain Python) and the compiled rows of
    :func:`_from_normal_rows` both run this source, so they agree bit for bit."""
    mgl = mass * g * lc
    th = q + (inertia * a + mgl * math.sin(q) + dl * w) / k
    v = w + (inertia * j + mgl * math.cos(q) * w + dl * a) / k
    return th, v


def _phi_row(q: float, w: float, a: float, j: float, u0: float, inertia: float, k: float,
             dl: float, mass: float, g: float, lc: float, dm: float, gear: float,
             motor_inertia: float) -> float:
    """``y^(4) = phi(z, u)``, once (scalar :meth:`ElasticJoint._phi` and compiled
    :func:`_phi_rows`)."""
    mgl = mass * g * lc
    s, c = math.sin(q), math.cos(q)
    # spring torque K (q - theta) and motor velocity from the inverse map
    tau = -(inertia * a + mgl * s + dl * w)
    v = w + (inertia * j + mgl * c * w + dl * a) / k
    thdd = (tau - dm * v + gear * u0) / motor_inertia
    return (mgl * s * w * w - mgl * c * a - k * (a - thdd) - dl * j) / inertia


_from_normal_nb = njit(cache=True)(_from_normal_row)
_phi_nb = njit(cache=True)(_phi_row)


# the ODE for the compiled model; c in the order of ElasticJoint.param_names: (link_inertia,
# motor_inertia, mass, com_distance, g, stiffness, link_damping, motor_damping, gear)


@register_jitable
def _accelerations(q: float, th: float, w: float, v: float, u0: float, I: float, J: float,
                   mass: float, lc: float, g: float, k: float, dl: float, dm: float,
                   gear: float) -> tuple[float, float]:
    """``(q'', theta'')`` of Spong's model, once (:meth:`ElasticJoint.dynamics` and the
    compiled rows): :math:`I q'' = -m g l_c \\sin q - K (q - \\theta) - d_l q'`,
    :math:`J \\theta'' = K (q - \\theta) - d_m \\theta' + b u`."""
    tau = k * (q - th)
    mgl = mass * g * lc
    qdd = (-mgl * math.sin(q) - tau - dl * w) / I
    thdd = (tau - dm * v + gear * u0) / J
    return qdd, thdd


@register_jitable
def _dynamics_row(x: Array, u: Array, c: Array, out: Array) -> None:
    """``out = f(x, u) = (q', theta', q'', theta'')``: :meth:`ElasticJoint.dynamics`."""
    out[0] = x[2]
    out[1] = x[3]
    out[2], out[3] = _accelerations(x[0], x[1], x[2], x[3], u[0], c[0], c[1], c[2], c[3], c[4],
                                    c[5], c[6], c[7], c[8])


@register_jitable
def _jacobian_row(x: Array, u: Array, c: Array, out: Array) -> None:
    """``out[:4, :4] = df/dx``: :meth:`ElasticJoint.jacobian`."""
    I, J, k = c[0], c[1], c[5]
    mgl = c[2] * c[4] * c[3]
    for i in range(4):
        for j in range(4):
            out[i, j] = 0.0
    out[0, 2] = 1.0
    out[1, 3] = 1.0
    out[2, 0] = (-mgl * math.cos(x[0]) - k) / I
    out[2, 1] = k / I
    out[2, 2] = -c[6] / I
    out[3, 0] = k / J
    out[3, 1] = -k / J
    out[3, 3] = -c[7] / J


@register_jitable
def _param_jacobian_row(x: Array, u: Array, c: Array, out: Array) -> None:
    """``out = df/dc`` (4, 9), columns in the order of ``param_names``:
    :meth:`ElasticJoint.param_jacobian`."""
    q, th, w, v, uu = x[0], x[1], x[2], x[3], u[0]
    I, J, M, L, g = c[0], c[1], c[2], c[3], c[4]
    s = math.sin(q)
    qdd, thdd = _accelerations(q, th, w, v, uu, I, J, M, L, g, c[5], c[6], c[7], c[8])
    for i in range(4):
        for j in range(9):
            out[i, j] = 0.0
    out[2, 0] = -qdd / I  # link_inertia
    out[3, 1] = -thdd / J  # motor_inertia
    out[2, 2] = -g * L * s / I  # mass
    out[2, 3] = -M * g * s / I  # com_distance
    out[2, 4] = -M * L * s / I  # g
    out[2, 5] = -(q - th) / I  # stiffness
    out[3, 5] = (q - th) / J
    out[2, 6] = -w / I  # link_damping
    out[3, 7] = -v / J  # motor_damping
    out[3, 8] = uu / J  # gear


class ElasticJointModel(CompiledModel):
    """The elastic joint's ODE for numba kernels (:class:`~hgo_mj.systems.base.CompiledModel`)."""

    __slots__ = ()
    dynamics = staticmethod(_dynamics_row)
    jacobian = staticmethod(_jacobian_row)
    param_jacobian = staticmethod(_param_jacobian_row)


@njit(cache=True)
def _from_normal_rows(Z: Array, c: Array) -> Array:
    """:func:`_from_normal_row` of the rows ``Z`` ``(N, 4)``: ``x = (q, theta, q', theta')``;
    ``c = (link_inertia, stiffness, link_damping, mass, g, com_distance)``."""
    N = Z.shape[0]
    X = np.empty((N, 4))
    for i in range(N):
        q, w, a, j = Z[i, 0], Z[i, 1], Z[i, 2], Z[i, 3]
        th, v = _from_normal_nb(q, w, a, j, c[0], c[1], c[2], c[3], c[4], c[5])
        X[i, 0] = q
        X[i, 1] = th
        X[i, 2] = w
        X[i, 3] = v
    return X


@njit(cache=True)
def _phi_rows(Z: Array, U: Array, c: Array) -> Array:
    """:func:`_phi_row` of the rows ``Z`` ``(N, 4)``, ``U`` ``(N, 1)``; ``c = (link_inertia,
    stiffness, link_damping, mass, g, com_distance, motor_damping, gear, motor_inertia)``."""
    N = Z.shape[0]
    out = np.empty(N)
    for i in range(N):
        out[i] = _phi_nb(Z[i, 0], Z[i, 1], Z[i, 2], Z[i, 3], U[i, 0], c[0], c[1], c[2], c[3],
                         c[4], c[5], c[6], c[7], c[8])
    return out


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

    Forms (:meth:`~hgo_mj.systems.base.System.form`): ``"affine"`` (paper 001, eq. 9; unknowns
    from :data:`AFFINE_PARAMS`), ``"jo_son"`` (paper 003, eq. 10, only with
    ``sensors="motor_side"``: :func:`jo_son_motor_side`) and ``"kalman_fields"``.

    Parameters
    ----------
    **params : float
        Values of some of ``param_names`` (e.g. ``stiffness=20.0``); the others are read from
        the shipped ``models/elastic_joint.xml``.

    Raises
    ------
    DesignError
        An unknown or non-finite parameter, or ``link_inertia``, ``motor_inertia`` or
        ``stiffness`` not positive.

    References
    ----------
    .. [1] M. W. Spong, "Modeling and control of elastic joint robots", ASME J. Dynamic
       Systems, Measurement, and Control 109(4) (1987), 310-319: the reduced model, in which
       the rotor's kinetic energy is due to its own rotation only (equation numbers not
       checked against the original here).
    .. [2] S. Nicosia and A. Tornambè, "High-gain observers in the state and parameter
       estimation of robots having elastic joints", Systems & Control Letters 13(4) (1989),
       331-337.

    Examples
    --------
    >>> ej = ElasticJoint()
    >>> ej.params["stiffness"], ej.state_names
    (10.0, ('link_angle', 'motor_angle', 'link_velocity', 'motor_velocity'))
    >>> z = ej.to_normal([0.1, 0.2, 0.0, 0.0])
    >>> z.round(3)
    array([ 0.1  ,  0.   , 29.336, -1.95 ])
    >>> ej.from_normal(z).round(6)
    array([0.1, 0.2, 0. , 0. ])
    >>> ej.form("affine").theta_names
    ('MgL_direct', 'stiffness', 'stiffness_MgL')
    """

    name = "elastic_joint"
    summary = "single link with an elastic joint, Spong 1987 (MuJoCo)"
    reference = "Spong (1987); Nicosia and Tornambè (1989)"
    state_names = ("link_angle", "motor_angle", "link_velocity", "motor_velocity")
    state_units = ("rad", "rad", "rad/s", "rad/s")
    input_names = ("torque",)
    input_units = ("N m",)
    output_names = ("link_angle",)
    param_names = ("link_inertia", "motor_inertia", "mass", "com_distance", "g", "stiffness",
                   "link_damping", "motor_damping", "gear")
    _positive = ("link_inertia", "motor_inertia", "stiffness")
    default_x0 = (0.3, 0.3, 0.0, 0.0)
    compiled = ElasticJointModel()
    normal_form_order = 4
    model_file = "elastic_joint.xml"
    joints = ("link", "motor")
    actuators = ("torque",)
    #: the Jo-Son form of the motor side (:meth:`_form_jo_son`, ``sensors="motor_side"``)
    forms = ("affine", "jo_son", "kalman_fields")

    def _form_jo_son(self, sensors: str = "link_angle", aux_outputs: Sequence[int] = (1, 2),
                     unknown: Sequence[str] = ("b_over_J", "dm_over_J", "K_over_J")) -> Any:
        """The Jo-Son form (paper 003, eq. 10) for the motor-side sensors
        (:func:`jo_son_motor_side`); the default link-angle sensor has none, and the error says
        why and what to measure instead.

        Raises
        ------
        DesignError
            ``sensors`` is not ``"motor_side"``.
        """
        if sensors != "motor_side":
            raise DesignError(
                f"{type(self).__name__} provides no Jo-Son form (paper 003, eq. 10) for the "
                f"sensors {sensors!r}: with its default link-angle sensor every parameter "
                f"reaches y with relative degree >= 2, so b_r = 0; measure the motor velocity "
                f"and the spring deflection and use form('jo_son', sensors='motor_side') "
                f"(jo_son_motor_side()); see docs/adaptive_canonical_forms.md")
        return jo_son_motor_side(aux_outputs, unknown)

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
        qdd, thdd = _accelerations(q, th, w, v, float(u[0]), p["link_inertia"],
                                   p["motor_inertia"], p["mass"], p["com_distance"], p["g"],
                                   p["stiffness"], p["link_damping"], p["motor_damping"],
                                   p["gear"])
        return np.array([w, v, qdd, thdd])

    @staticmethod
    def output(x: Array, p: Mapping[str, float]) -> Array:
        return np.array([float(x[0])])

    @staticmethod
    def jacobian(t: float, x: Array, u: Array, p: Mapping[str, float]) -> Array:
        """:math:`\\partial f / \\partial x` of :meth:`dynamics`, shape (4, 4) (used by the
        Kalman filters of :mod:`hgo_mj.observers.kalman`).

        Parameters
        ----------
        t : float
            Time [s] (unused: the system is autonomous).
        x : (4,) ndarray of float
            State ``(link_angle, motor_angle, link_velocity, motor_velocity)`` [rad, rad/s].
        u : (1,) ndarray of float
            Motor torque [N m] (the Jacobian does not depend on it).
        p : mapping of str to float
            Parameters by name (all of ``param_names``).

        Returns
        -------
        (4, 4) ndarray of float
            ``df/dx``; the first two rows are ``[0, 0, 1, 0]`` and ``[0, 0, 0, 1]``.

        Examples
        --------
        >>> import numpy as np
        >>> ej = ElasticJoint()
        >>> J = ej.jacobian(0.0, np.array([0.1, 0.2, 0.0, 0.0]), np.array([0.0]), ej.params)
        >>> J[2:].round(2).tolist()
        [[-371.36, 332.42, -0.07, 0.0], [2604.17, -2604.17, 0.0, -2.6]]
        """
        out = np.empty((4, 4))
        _jacobian_row(x, u, _params(p), out)
        return out

    @staticmethod
    def param_jacobian(t: float, x: Array, u: Array, p: Mapping[str, float],
                       names: tuple[str, ...]) -> Array:
        """:math:`\\partial f / \\partial p` of :meth:`dynamics` for the parameters ``names``,
        shape (4, len(names)).

        Parameters
        ----------
        t : float
            Time [s] (unused).
        x : (4,) ndarray of float
            State ``(link_angle, motor_angle, link_velocity, motor_velocity)``.
        u : (1,) ndarray of float
            Motor torque [N m].
        p : mapping of str to float
            Parameters by name (all of ``param_names``).
        names : tuple of str
            The parameters to differentiate by, names of ``param_names``, in the column order
            wanted.

        Returns
        -------
        (4, len(names)) ndarray of float
            Column ``k``: ``df/d names[k]`` (first two rows zero).

        Raises
        ------
        DesignError
            A name of ``names`` is not in ``param_names`` (the valid ones listed).

        Examples
        --------
        >>> import numpy as np
        >>> ej = ElasticJoint()
        >>> ej.param_jacobian(0.0, np.array([0.1, 0.2, 0.0, 0.0]), np.array([0.0]), ej.params,
        ...                   ("stiffness",)).round(3)
        array([[  0.   ],
               [  0.   ],
               [  3.324],
               [-26.042]])
        """
        out = np.empty((4, len(ElasticJoint.param_names)))
        _param_jacobian_row(x, u, _params(p), out)
        return out[:, ElasticJoint._param_columns(names)]

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
        th, v = _from_normal_row(q, w, a, j, p["link_inertia"], p["stiffness"],
                                 p["link_damping"], p["mass"], p["g"], p["com_distance"])
        return np.array([q, th, w, v])

    @staticmethod
    def _phi(z: Array, u: Array, p: Mapping[str, float]) -> float:
        return _phi_row(float(z[0]), float(z[1]), float(z[2]), float(z[3]), float(u[0]),
                        p["link_inertia"], p["stiffness"], p["link_damping"], p["mass"], p["g"],
                        p["com_distance"], p["motor_damping"], p["gear"], p["motor_inertia"])

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

    # ------------------------------------------------------------------ forms
    def _form_affine(self, unknown: Any = None) -> Any:
        """The elastic joint seen from the link angle, in the form eq. 9 of paper 001, affine
        in its parameters (:class:`~hgo_mj.systems.affine_form.AffineForm`).

        In the normal form :math:`z = (y, \\dot y, \\ddot y, y^{(3)})` (link inertia
        :math:`I`, motor inertia :math:`J`, damping :math:`d_l, d_m` and gear :math:`b` known,
        :math:`\\delta = d_l / I`), differentiating the link equation twice and eliminating
        the motor angle gives (checked in ``tests/observers/test_besancon.py``)

        .. math::

            y^{(4)} = \\underbrace{-\\delta z_4 - \\tfrac{d_m}{J}(z_4 + \\delta z_3)}_{\\varphi_4}
                + \\psi_1\\, MgL + \\psi_2\\, K + \\psi_3\\, K\\, MgL,

        .. math::

            \\psi_1 &= \\left(\\sin z_1\\, z_2^2 - \\cos z_1\\, z_3
                       - \\tfrac{d_m}{J} \\cos z_1\\, z_2\\right) / I, \\\\
            \\psi_2 &= -\\frac{z_3}{I} - \\frac{z_3 + \\delta z_2}{J} - \\frac{d_m z_2}{I J}
                       + \\frac{b\\, u}{I J}, \\qquad
            \\psi_3 = -\\frac{\\sin z_1}{I J}.

        :math:`y^{(4)}` is *not* affine in :math:`(K, MgL)` (the product :math:`K\\,MgL`
        appears), but it is affine in :math:`\\theta = (MgL, K, K\\,MgL)` (``unknown`` both,
        the default): the observer estimates three numbers and the physical ones are mapped
        back as :math:`\\hat K = \\hat\\theta_2` and :math:`\\widehat{MgL} = \\hat\\theta_3 /
        \\hat\\theta_2` (the regressor :math:`\\psi_3` is the best excited: it does not need
        :math:`z_3`, the noisiest estimate). With one of them known, :math:`\\theta` is that
        one parameter and the product term joins its regressor (:math:`\\psi_1 + K \\psi_3` or
        :math:`\\psi_2 + MgL\\, \\psi_3`). The physical state (motor angle and velocity) comes
        from the inverse map with the current estimates (NaN rows where a stiffness estimate
        is not positive).

        Raises
        ------
        DesignError
            ``unknown`` is not a non-empty sequence of distinct names of ``AFFINE_PARAMS``.

        References
        ----------
        Paper 001, eq. 9; Nicosia and Tornambè (1989) for the problem.
        """
        from .affine_form import AffineForm

        p = dict(self.params)
        I, J = p["link_inertia"], p["motor_inertia"]
        dl, dm, b = p["link_damping"], p["motor_damping"], p["gear"]
        g, L = p["g"], p["com_distance"]
        mgl_true = p["mass"] * g * L
        k_true = p["stiffness"]
        order = AFFINE_PARAMS if unknown is None else tuple(unknown)
        if (not order or any(u not in AFFINE_PARAMS for u in order)
                or len(set(order)) != len(order)):
            raise DesignError(f"elastic-joint parameters to estimate must be distinct names from "
                              f"{list(AFFINE_PARAMS)}; found {list(order)}")
        both = len(order) == 2
        mode = 0 if both else (1 if order[0] == "MgL" else 2)
        if both:
            names: tuple[str, ...] = ("MgL_direct", "stiffness", "stiffness_MgL")
            theta = [mgl_true, k_true, k_true * mgl_true]
        else:
            names = (order[0],)
            theta = [mgl_true if mode == 1 else k_true]
        c_terms = np.array([I, J, dl / I, dm / J, dm, b, k_true, mgl_true])
        c_phys = np.array([I, dl, k_true, p["mass"], g, L])

        def terms(Z: Array, U: Array) -> tuple[Array, Array]:
            return _affine_terms(Z, U, c_terms, mode)  # type: ignore[no-any-return]

        def to_physical(Z: Array, TH: Array, U: Array) -> Array:
            return _affine_to_physical(Z, TH, c_phys, mode)  # type: ignore[no-any-return]

        def physical(TH: Array) -> dict[str, Array]:
            if mode == 0:
                k = TH[:, 1].copy()
                safe = np.where(k != 0.0, k, 1.0)
                return {"stiffness": k, "MgL": np.where(k != 0.0, TH[:, 2] / safe, np.nan)}
            return {"MgL" if mode == 1 else "stiffness": TH[:, 0].copy()}

        def params_for(th: Array) -> dict[str, float]:
            q = dict(p)
            phys = {k: float(v[0]) for k, v in physical(np.asarray(th, dtype=float)[None]).items()}
            if "stiffness" in phys:
                if not phys["stiffness"] > 0:
                    raise DesignError(f"stiffness estimate {phys['stiffness']:.4g} is not > 0")
                q["stiffness"] = phys["stiffness"]
            if "MgL" in phys:
                if not math.isfinite(phys["MgL"]):
                    raise DesignError("MgL estimate is not finite")
                q["mass"] = phys["MgL"] / (g * L)
            return q

        def from_physical(x: Array, th: Array, u: Array) -> Array:
            return ElasticJoint._to_normal(x, params_for(th))

        return AffineForm(orders=(4,), theta_names=names, terms=terms,
                          label=f"elastic joint, link angle, unknown {list(order)}", theta=theta,
                          state_names=("link_angle", "link_velocity", "link_acceleration",
                                       "link_jerk"), n_inputs=1,
                          to_physical=to_physical, from_physical=from_physical,
                          physical_state_names=self.state_names, physical_params=physical,
                          true_physical={"stiffness": k_true, "MgL": mgl_true}
                          )._made_by(ElasticJoint._form_affine, self, unknown)

    @cached_property
    def _row_constants(self) -> Array:
        """The parameters of :func:`_phi_rows` (the first six: of :func:`_from_normal_rows`),
        made once (a system's parameters are fixed at construction)."""
        p = self.params
        return np.array([p["link_inertia"], p["stiffness"], p["link_damping"], p["mass"], p["g"],
                         p["com_distance"], p["motor_damping"], p["gear"], p["motor_inertia"]])

    def from_normal_batch(self, Z: Array, U: Array) -> Array:
        """:meth:`from_normal_unchecked` of the rows ``Z`` ``(N, 4)``, compiled (equal to the
        scalar path bit for bit; defined everywhere, the stiffness being > 0).

        Parameters
        ----------
        Z : (N, 4) ndarray of float
            Normal-form rows ``z = (y, y', y'', y^(3))``.
        U : (N, 1) ndarray of float
            Inputs (unused: the inverse map does not depend on the torque).

        Returns
        -------
        (N, 4) ndarray of float
            Physical states ``(q, theta, q', theta')``, one per row of ``Z``.

        Examples
        --------
        >>> import numpy as np
        >>> ej = ElasticJoint()
        >>> Z = np.array([ej.to_normal([0.1, 0.2, 0.0, 0.0]), np.zeros(4)])
        >>> ej.from_normal_batch(Z, np.zeros((2, 1))).round(6)
        array([[0.1, 0.2, 0. , 0. ],
               [0. , 0. , 0. , 0. ]])
        """
        return _from_normal_rows(np.ascontiguousarray(Z, dtype=float),  # type: ignore[no-any-return]
                                 self._row_constants[:6])

    def phi_batch(self, Z: Array, U: Array) -> Array:
        """:meth:`phi_unchecked` of the rows ``Z`` ``(N, 4)``, ``U`` ``(N, 1)``, compiled (equal
        to the scalar path bit for bit)."""
        return _phi_rows(np.ascontiguousarray(Z, dtype=float),  # type: ignore[no-any-return]
                         np.ascontiguousarray(U, dtype=float), self._row_constants)


# ----------------------------------------------------------------------------------------
# Jo-Son form of the motor side (paper 003, eq. 10), rows component first: y (N,), u (3, N)
# ----------------------------------------------------------------------------------------


def _motor_gamma_o(y: Any, u: Any) -> tuple[float]:
    """:math:`\\gamma_o = 0`."""
    return (0.0,)


def _motor_beta(y: Any, u: Any) -> tuple[Any, Any, Any]:
    """:math:`\\beta = (u, -y, \\delta)` with ``u = (torque, link_angle, motor_angle)`` and
    the deflection :math:`\\delta = q - \\theta_m`."""
    return (u[0], -y, u[1] - u[2])


def jo_son_motor_side(aux_outputs: Sequence[int] = (1, 2),
                      unknown: Sequence[str] = ("b_over_J", "dm_over_J", "K_over_J")) -> JoSonForm:
    """The motor side of the elastic joint in the form eq. 10 of paper 003, measured by a motor
    tachometer, with the spring deflection measured as a known signal.

    With :math:`y = \\dot\\theta_m` (MJCF sensor ``motor_velocity``) and the deflection
    :math:`\\delta = q - \\theta_m` from the link and motor encoders
    (``link_angle - motor_angle``, channels ``aux_outputs``), the motor equation is

    .. math::

        \\dot y = \\frac{b}{J} u - \\frac{d_m}{J} y + \\frac{K}{J} \\delta,

    i.e. eq. 10 with :math:`r = 1`, :math:`b = (1)`, :math:`\\gamma_o = 0`,
    :math:`\\beta = (u, -y, \\delta)` and :math:`\\theta = (b/J, d_m/J, K/J)`: every
    parameter reaches the output with relative degree one, :math:`b_r = 1 > 0`, and
    :math:`W(s) = 1/(s + \\lambda)` is SPR. The link side is not part of the observer's
    model (it enters only through the measured :math:`\\delta`), so :math:`n = r = 1`.
    This form estimates all three parameters.

    Parameters
    ----------
    aux_outputs : (int, int)
        Channels of ``link_angle`` and ``motor_angle`` in the measurement vector (the plant
        built with ``outputs=("motor_velocity", "link_angle", "motor_angle")`` has them at
        1 and 2).
    unknown : sequence of str
        Must be ``("b_over_J", "dm_over_J", "K_over_J")``.

    Returns
    -------
    JoSonForm
        The :class:`~hgo_mj.systems.jo_son_form.JoSonForm` with ``r = n = 1``, ``b = (1,)``,
        ``theta_names = unknown`` and state ``("motor_velocity",)``.

    Raises
    ------
    DimensionError
        ``aux_outputs`` does not have exactly two entries.
    DesignError
        ``unknown`` is not ``("b_over_J", "dm_over_J", "K_over_J")``.

    References
    ----------
    Paper 003, eq. 10, Corollary 3.3; docs/adaptive_canonical_forms.md (why the link-angle
    sensor does not qualify).

    Examples
    --------
    >>> form = jo_son_motor_side()
    >>> form
    JoSonForm(elastic joint motor side: y = motor velocity, deflection measured: r=1, n=1,
    b=[1.0], theta=['b_over_J', 'dm_over_J', 'K_over_J'])
    >>> form.aux_outputs
    (1, 2)

    The same form through the system (the default link-angle sensor has none):

    >>> ElasticJoint().form("jo_son", sensors="motor_side").theta_names
    ('b_over_J', 'dm_over_J', 'K_over_J')
    """
    aux = tuple(int(i) for i in aux_outputs)
    if len(aux) != 2:
        raise DimensionError(f"aux_outputs must name 2 channels (link_angle, motor_angle); "
                             f"found {list(aux)}")
    if tuple(unknown) != ("b_over_J", "dm_over_J", "K_over_J"):
        raise DesignError(f"the motor-side form estimates ('b_over_J', 'dm_over_J', "
                          f"'K_over_J'); found {list(unknown)}")
    return JoSonForm([1.0], _motor_gamma_o, _motor_beta, theta_names=tuple(unknown),
                     state_names=("motor_velocity",), aux_outputs=aux,
                     label="elastic joint motor side: y = motor velocity, deflection measured")


def _params(p: Mapping[str, float]) -> Array:
    """The parameters in the order of ``ElasticJoint.param_names``."""
    return np.array([p[k] for k in ElasticJoint.param_names], dtype=float)
