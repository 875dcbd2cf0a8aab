"""The torque-driven pendulum (``models/pendulum.xml``)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from functools import cached_property
from typing import Any

import numpy as np
from numba import njit
from numba.extending import register_jitable

from ..exceptions import DesignError
from ._mujoco import _MjReader, _SecondOrderMujocoSystem
from .aocf import AOCF, joint_aocf
from .base import Array, CompiledModel

__all__ = ["AFFINE_PARAMS", "Pendulum"]

#: the parameters of the pendulum's affine form (paper 001, eq. 9), in the order of
#: :func:`_affine_terms`' basis regressors
AFFINE_PARAMS = ("g_over_l", "b_over_J", "d_over_J")


@njit(cache=True)
def _affine_terms(Z: Array, U: Array, unknown: Any, known: Array) -> tuple[Array, Array]:
    """Rows of the pendulum's form eq. 9: ``z2' = phi_2 + psi theta`` with the basis regressors
    ``r = (-sin z1, u, -z2)`` of ``(g_over_l, b_over_J, d_over_J)``; ``psi`` holds the columns
    ``unknown`` (indices into ``r``), ``phi_2 = sum_k known_k r_k`` the rest (``known_k`` the
    true value of a known parameter, 0 for an unknown one)."""
    N = Z.shape[0]
    phi = np.zeros((N, 2))
    psi = np.empty((N, 1, unknown.shape[0]))
    r = np.empty(3)
    for b in range(N):
        r[0] = -math.sin(Z[b, 0])
        r[1] = U[b, 0]
        r[2] = -Z[b, 1]
        phi[b, 1] = 0.0 + known[0] * r[0] + known[1] * r[1] + known[2] * r[2]
        for j in range(unknown.shape[0]):
            psi[b, 0, j] = r[unknown[j]]
    return phi, psi


def _aocf_features(Y: Array, U: Array) -> Array:
    """The pendulum's :math:`\\psi(y, u) = (-\\sin y, u)` on rows (its AOCF)."""
    F = np.empty((len(Y), 2))
    F[:, 0] = -np.sin(Y)
    F[:, 1] = U[:, 0]
    return F


@register_jitable
def _acceleration_row(q: float, v: float, u0: float, gear: float, mass: float, g: float,
                      lc: float, damping: float, inertia: float) -> float:
    """The pendulum's ``q''``, once: the scalar path (:meth:`Pendulum._acceleration`, plain
    Python) and the compiled rows of :func:`_phi_rows` both run this source, so they agree bit
    for bit."""
    return (gear * u0 - mass * g * lc * math.sin(q) - damping * v) / inertia


_acceleration_nb = njit(cache=True)(_acceleration_row)


# the ODE of one row for the compiled model; c = (mass, com_distance, inertia, damping, gear,
# g), the order of Pendulum.param_names


@register_jitable
def _dynamics_row(x: Array, u: Array, c: Array, out: Array) -> None:
    """``out = f(x, u) = (theta', theta'')``: :meth:`Pendulum.dynamics`."""
    out[0] = x[1]
    out[1] = _acceleration_row(x[0], x[1], u[0], c[4], c[0], c[5], c[1], c[3], c[2])


@register_jitable
def _jacobian_row(x: Array, u: Array, c: Array, out: Array) -> None:
    """``out = df/dx`` (2, 2): :meth:`Pendulum.jacobian`."""
    mass, lc, J, d, g = c[0], c[1], c[2], c[3], c[5]
    out[0, 0] = 0.0
    out[0, 1] = 1.0
    out[1, 0] = -mass * g * lc * math.cos(x[0]) / J
    out[1, 1] = -d / J


@register_jitable
def _param_jacobian_row(x: Array, u: Array, c: Array, out: Array) -> None:
    """``out = df/dc`` (2, 6), columns in the order of ``param_names``:
    :meth:`Pendulum.param_jacobian`."""
    mass, lc, J, d, gear, g = c[0], c[1], c[2], c[3], c[4], c[5]
    th, w, uu = x[0], x[1], u[0]
    s = math.sin(th)
    acc = _acceleration_row(th, w, uu, gear, mass, g, lc, d, J)
    out[0, :] = 0.0
    out[1, 0] = -g * lc * s / J  # mass
    out[1, 1] = -mass * g * s / J  # com_distance
    out[1, 2] = -acc / J  # inertia
    out[1, 3] = -w / J  # damping
    out[1, 4] = uu / J  # gear
    out[1, 5] = -mass * lc * s / J  # g


class PendulumModel(CompiledModel):
    """The pendulum's ODE for numba kernels (:class:`~hgo_mj.systems.base.CompiledModel`)."""

    __slots__ = ()
    dynamics = staticmethod(_dynamics_row)
    jacobian = staticmethod(_jacobian_row)
    param_jacobian = staticmethod(_param_jacobian_row)


@njit(cache=True)
def _phi_rows(Z: Array, U: Array, c: Array) -> Array:
    """:func:`_acceleration_row` of the rows ``Z`` ``(N, 2)``, ``U`` ``(N, 1)``; ``c = (gear,
    mass, g, com_distance, damping, inertia)``."""
    N = Z.shape[0]
    out = np.empty(N)
    for i in range(N):
        out[i] = _acceleration_nb(Z[i, 0], Z[i, 1], U[i, 0], c[0], c[1], c[2], c[3], c[4], c[5])
    return out


class Pendulum(_SecondOrderMujocoSystem):
    r"""Rigid pendulum on a horizontal hinge with a torque motor and viscous damping.

    .. math::

        J \ddot\theta = -m g l_c \sin\theta - d \dot\theta + b u, \qquad y = \theta

    with :math:`\theta` the angle from hanging down, :math:`J` the inertia about the hinge,
    :math:`m` the mass, :math:`l_c` the hinge-to-COM distance, :math:`d` the damping and
    :math:`b` the actuator gear. The state is already the observability normal form
    :math:`z = (y, \dot y)`, with

    .. math:: \varphi(z, u) = \frac{b u - m g l_c \sin z_1 - d z_2}{J}.

    Parameters (``param_names``): ``mass`` [kg], ``com_distance`` [m], ``inertia``
    [kg m^2], ``damping`` [N m s/rad], ``gear`` [-], ``g`` [m/s^2]; read from
    ``models/pendulum.xml`` by :meth:`from_mjmodel` (body ``pole``, joint ``hinge``,
    actuator ``torque``).

    Forms (:meth:`~hgo_mj.systems.base.System.form`): ``"affine"`` (paper 001, eq. 9; unknowns
    from :data:`AFFINE_PARAMS`), ``"aocf"`` (paper 002, eq. 2.2) and ``"kalman_fields"``.

    Parameters
    ----------
    **params : float
        Values of some of ``param_names`` (e.g. ``damping=0.02``); the others are read from
        the shipped ``models/pendulum.xml``.

    Raises
    ------
    DesignError
        An unknown or non-finite parameter, or ``mass``, ``com_distance`` or ``inertia`` not
        positive.

    References
    ----------
    .. [1] H. K. Khalil, *Nonlinear Systems*, 3rd ed., Prentice Hall, 2002, Example 1.2.1
       (pendulum equation).
    .. [2] E. Bullinger, A. Ilchmann, F. Allgöwer, "A simple adaptive observer for nonlinear
       systems", NOLCOS 1998, eq. (1): the observability normal form.

    Examples
    --------
    >>> p = Pendulum(damping=0.02)
    >>> p
    Pendulum(mass=0.25, com_distance=0.45, inertia=0.054217, damping=0.02, gear=1, g=9.81)
    >>> round(p.phi([0.5, 0.0], [0.0]), 4)
    -9.759
    >>> p.form("affine", unknown=["g_over_l"]).theta_names
    ('g_over_l',)
    """

    name = "pendulum"
    summary = "torque-driven pendulum with damping (MuJoCo)"
    reference = "Khalil, Nonlinear Systems (2002), Example 1.2.1"
    state_names = ("angle", "angular_velocity")
    state_units = ("rad", "rad/s")
    input_names = ("torque",)
    input_units = ("N m",)
    output_names = ("angle",)
    param_names = ("mass", "com_distance", "inertia", "damping", "gear", "g")
    _positive = ("mass", "com_distance", "inertia")
    default_x0 = (0.5, 0.0)
    normal_form_order = 2
    model_file = "pendulum.xml"
    joints = ("hinge",)
    actuators = ("torque",)
    forms = ("affine", "kalman_fields", "aocf")
    compiled = PendulumModel()

    def _form_kalman_fields(self) -> dict[str, str]:
        """The ``"kalman_fields"`` form: the MJCF fields an augmented MuJoCo Kalman filter
        may estimate under this system's parameter names (the gear, damping and g, which
        carries :math:`m g l_c`), ``{name: "field[element]" or "opt.gravity"}``."""
        return {"gear": "actuator_gear[torque]",
                "damping": "dof_damping[hinge]",
                "g": "opt.gravity"}

    def _form_aocf(self, c2: float = 2.0, unknown: Any = None,
                   damping_known: str = "ratio") -> AOCF:
        """The AOCF (paper 002, eq. 2.2) of :math:`\\ddot y = -\\delta \\dot y - a \\sin y
        + \\beta u` with :math:`a = m g l_c / J` (``g_over_l``), :math:`\\beta = b/J`
        (``b_over_J``), :math:`\\delta = d/J` (``d_over_J``): :func:`~hgo_mj.systems.aocf.joint_aocf`
        (``unknown``, ``damping_known``, derived in ``docs/adaptive_canonical_forms.md``)."""
        p = self.params
        J = p["inertia"]
        return joint_aocf(self, _aocf_features, ("-sin y", "u"),
                          "pendulum: y'' = -d/J y' - a sin y + b u",
                          (p["mass"] * p["g"] * p["com_distance"] / J, p["gear"] / J),
                          c2=c2, unknown=unknown, damping_known=damping_known)

    @classmethod
    def params_from_mjmodel(cls, model: Any) -> dict[str, float]:
        r = _MjReader(model, cls.__name__)
        _, dof, anchor, axis = r.joint("hinge")
        mass, r_perp, inertia = r.about_axis("pole", anchor, axis)
        return {"mass": mass, "com_distance": r.along("the pole's COM", r_perp, r.down),
                "inertia": inertia, "damping": r.damping(dof),
                "gear": r.gear("torque", "hinge"), "g": r.g}

    @staticmethod
    def _acceleration(q: float, v: float, u0: float, p: Mapping[str, float]) -> float:
        return _acceleration_row(q, v, u0, p["gear"], p["mass"], p["g"], p["com_distance"],
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
        return np.array([p["gear"], p["mass"], p["g"], p["com_distance"], p["damping"],
                         p["inertia"]])

    @staticmethod
    def dynamics(t: float, x: Array, u: Array, p: Mapping[str, float]) -> Array:
        th, w = float(x[0]), float(x[1])
        return np.array([w, Pendulum._acceleration(th, w, float(u[0]), p)])

    @staticmethod
    def output(x: Array, p: Mapping[str, float]) -> Array:
        return np.array([float(x[0])])

    @staticmethod
    def jacobian(t: float, x: Array, u: Array, p: Mapping[str, float]) -> Array:
        """:math:`\\partial f / \\partial x` of :meth:`dynamics`, shape (2, 2) (used by the
        Kalman filters of :mod:`hgo_mj.observers.kalman`).

        Parameters
        ----------
        t : float
            Time [s] (unused: the pendulum is autonomous).
        x : (2,) ndarray of float
            State ``(angle [rad], angular_velocity [rad/s])``.
        u : (1,) ndarray of float
            Input torque [N m] (the Jacobian does not depend on it).
        p : mapping of str to float
            Parameters by name (all of ``param_names``).

        Returns
        -------
        (2, 2) ndarray of float
            ``[[0, 1], [-m g l_c cos(theta) / J, -d / J]]``.

        Examples
        --------
        >>> import numpy as np
        >>> p = Pendulum(damping=0.02)
        >>> p.jacobian(0.0, np.array([0.0, 0.0]), np.array([0.0]), p.params).round(3)
        array([[  0.   ,   1.   ],
               [-20.356,  -0.369]])
        """
        out = np.empty((2, 2))
        _jacobian_row(x, u, _params(p), out)
        return out

    @staticmethod
    def param_jacobian(t: float, x: Array, u: Array, p: Mapping[str, float],
                       names: tuple[str, ...]) -> Array:
        """:math:`\\partial f / \\partial p` of :meth:`dynamics` for the parameters ``names``,
        shape (2, len(names)).

        Parameters
        ----------
        t : float
            Time [s] (unused).
        x : (2,) ndarray of float
            State ``(angle [rad], angular_velocity [rad/s])``.
        u : (1,) ndarray of float
            Input torque [N m].
        p : mapping of str to float
            Parameters by name (all of ``param_names``).
        names : tuple of str
            The parameters to differentiate by, names of ``param_names``, in the column order
            wanted.

        Returns
        -------
        (2, len(names)) ndarray of float
            Column ``k``: ``df/d names[k]`` (first row zero).

        Raises
        ------
        DesignError
            A name of ``names`` is not in ``param_names`` (the valid ones listed).

        Examples
        --------
        >>> import numpy as np
        >>> p = Pendulum(damping=0.02)
        >>> p.param_jacobian(0.0, np.array([0.5, 1.0]), np.array([0.2]), p.params,
        ...                  ("damping", "gear")).round(3)
        array([[  0.   ,   0.   ],
               [-18.444,   3.689]])
        """
        out = np.empty((2, len(Pendulum.param_names)))
        _param_jacobian_row(x, u, _params(p), out)
        return out[:, Pendulum._param_columns(names)]

    # ------------------------------------------------------------------ forms
    def _form_affine(self, unknown: Any = None) -> Any:
        """The pendulum :math:`J\\ddot y = -m g l_c \\sin y - d \\dot y + b u` in the form
        eq. 9 of paper 001 (:class:`~hgo_mj.systems.affine_form.AffineForm`).

        With :math:`a = m g l_c / J` (``g_over_l``), :math:`\\beta = b/J` (``b_over_J``) and
        :math:`\\delta = d/J` (``d_over_J``), :math:`z = (y, \\dot y)`:

        .. math::

            \\dot z_1 = z_2, \\qquad
            \\dot z_2 = \\underbrace{-\\delta z_2}_{\\varphi_2}
                      + \\begin{pmatrix} -\\sin z_1 & u \\end{pmatrix}
                        \\begin{pmatrix} a \\\\ \\beta \\end{pmatrix}

        for the default ``unknown = ("g_over_l", "b_over_J")`` (damping known, read from the
        system); a known parameter moves into :math:`\\varphi`, ``d_over_J`` may be estimated
        too (regressor :math:`-z_2`). The names match the Bastin-Gevers form of the same plant.

        Raises
        ------
        DesignError
            ``unknown`` is not a non-empty sequence of distinct names of ``AFFINE_PARAMS``.

        References
        ----------
        Paper 001, eq. 9 (form), eq. 7 (regressor structure).
        """
        from .affine_form import AffineForm

        p = self.params
        J = p["inertia"]
        true = {"g_over_l": p["mass"] * p["g"] * p["com_distance"] / J, "b_over_J": p["gear"] / J,
                "d_over_J": p["damping"] / J}
        order = ("g_over_l", "b_over_J") if unknown is None else tuple(unknown)
        bad = [u for u in order if u not in AFFINE_PARAMS]
        if bad or not order or len(set(order)) != len(order):
            raise DesignError(f"pendulum parameters to estimate must be distinct names from "
                              f"{list(AFFINE_PARAMS)}; found {list(order)}")
        idx = np.array([AFFINE_PARAMS.index(k) for k in order], dtype=np.int64)
        known = np.array([0.0 if k in order else true[k] for k in AFFINE_PARAMS])

        def terms(Z: Array, U: Array) -> tuple[Array, Array]:
            return _affine_terms(Z, U, idx, known)  # type: ignore[no-any-return]

        return AffineForm(orders=(2,), theta_names=order, terms=terms,
                          label=f"pendulum y'' = -d/J y' - a sin y + b/J u, unknown {list(order)}",
                          theta=[true[k] for k in order], state_names=self.state_names,
                          n_inputs=1, true_physical={k: true[k] for k in order}
                          )._made_by(Pendulum._form_affine, self, unknown)


def _params(p: Mapping[str, float]) -> Array:
    """The parameters in the order of ``Pendulum.param_names``."""
    return np.array([p[k] for k in Pendulum.param_names], dtype=float)
