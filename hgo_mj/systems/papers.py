"""The non-mechanical example systems of the papers (ODE plants, no MJCF).

Each class is a :class:`~hgo_mj.systems.base.System` with the paper's parameter values and
initial state as defaults, plus the structure the paper's observer is designed on:

* :class:`BioreactorBullinger` -- paper 000, eq. 15, with the observability normal form
  eq. 16 (``to_normal``, ``from_normal`` = :math:`\\Phi^{-1}`, ``phi`` = :math:`\\ddot m`);
* :class:`BioreactorBastinGevers` -- paper 002, eq. 6.1 (with the dilution term of the substrate
  restored, see the class), with the map 6.4 to the adaptive observer canonical form 6.5 and
  its inverse 6.6 (sign of 6.6b corrected);
* :class:`BesanconExample1`, :class:`BesanconExample2` -- paper 001, section 4, in the forms
  eq. 9 and eq. 21 (``A``, ``phi0``, ``regressor``);
* :class:`JoSonExample` -- paper 003, eq. 28, with the coordinate change eq. 30 to the adaptive
  observer canonical form eq. 31.

The paper's input signals are module functions returning the input vector of shape ``(m,)``,
ready for :meth:`hgo_mj.plants.ode.OdePlant.step`.

References
----------
.. [000] E. Bullinger, A. Ilchmann, F. Allgöwer, "A simple adaptive observer for nonlinear
   systems", NOLCOS 1998 (``shared/papers/000_76f8d44710f783d2.txt``).
.. [001] G. Besançon, Q. Zhang, H. Hammouri, "High-gain observer based state and parameter
   estimation in nonlinear systems", IFAC 2004 (``shared/papers/001_fa1af3b6b9a222a1.txt``).
.. [002] G. Bastin, M. Gevers, "Stable adaptive observers for nonlinear time-varying systems",
   1986/88 (``shared/papers/002_7adafa82055be9d3.txt``).
.. [003] N.-H. Jo, Y.-I. Son, "Adaptive observer design for nonlinear systems using generalized
   nonlinear observer canonical form", KSME Int. J. 2004
   (``shared/papers/003_bd61d49996cbe973.txt``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
from numba import njit
from numba.extending import register_jitable

from .._validate import finite_scalar, vector
from ..exceptions import DesignError
from .aocf import AOCF, system_form
from .base import Array, CompiledModel, System
from .jo_son_form import JoSonForm

__all__ = [
    "BASTIN_GEVERS_U_MAX",
    "BesanconExample1",
    "BesanconExample2",
    "BioreactorBastinGevers",
    "BioreactorBullinger",
    "JoSonExample",
    "bastin_gevers_input",
    "besancon_ex1_input",
    "besancon_ex2_input",
    "besancon_ex2_signal",
    "bullinger_input",
    "jo_son_input",
]


def _time(t: Any) -> float:
    return finite_scalar("t", t)


# =====================================================================================
# Paper 000: Bullinger, Ilchmann, Allgöwer -- bioreactor, eq. 15-16
# =====================================================================================


def bullinger_input(t: float) -> Array:
    """Substrate inflow rate of the simulations of paper 000, section 4 (time in hours).

    .. math::

        u(t) = \\begin{cases} 0.08\\,\\mathrm{h}^{-1} & t \\in [0, 30)\\,\\mathrm{h} \\\\
                              0.02\\,\\mathrm{h}^{-1} & t \\in [30, 50)\\,\\mathrm{h} \\\\
                              0.08\\,\\mathrm{h}^{-1} & t \\ge 50\\,\\mathrm{h} \\end{cases}

    Parameters
    ----------
    t : float
        Time in hours (``t < 0`` is given the first value).

    Returns
    -------
    ndarray, shape (1,)
        ``[u(t)]``. Its derivative is zero except at the jumps ``t = 30`` and ``t = 50``, where
        it is an impulse: there ``m' = a_1 m s/(a_2 m + s) - u m`` jumps and
        :math:`\\varphi = \\ddot m` holds :math:`-\\dot u m`, so the paper's boundedness
        assumption on :math:`\\varphi` (A2; "essentially bounded" in Theorems 2-3) fails at
        the switching instants and holds only between them (the paper does not say so).

    References
    ----------
    Paper 000, section 4 (input profile below eq. 16).

    Examples
    --------
    >>> bullinger_input(10.0), bullinger_input(40.0)
    (array([0.08]), array([0.02]))
    """
    t = _time(t)
    return np.array([0.02 if 30.0 <= t < 50.0 else 0.08])


def _bullinger_s_row(m: float, md: float, uu: float, a1: float, a2: float) -> float:
    """:math:`s = \\Phi^{-1}_2(z, u)` of :class:`BioreactorBullinger`, once (scalar
    :meth:`~BioreactorBullinger.from_normal` and compiled :func:`_bullinger_from_normal_rows`);
    NaN outside the domain ``a1, a2 > 0``, ``m > 0``, ``0 <= m' + u m < a1 m``."""
    w = md + uu * m
    if not (a1 > 0 and a2 > 0 and m > 0 and 0.0 <= w < a1 * m):
        return math.nan
    return a2 * m * w / (a1 * m - w)


def _bullinger_phi_row(m: float, md: float, uu: float, ud: float, a1: float, a2: float,
                       a3: float, a4: float) -> float:
    """:math:`\\varphi(z, u, \\dot u) = \\ddot m` of :class:`BioreactorBullinger`, once (scalar
    :meth:`~BioreactorBullinger.phi` and compiled :func:`_bullinger_phi_rows`); NaN where
    ``m > 0`` fails (the pole at ``m = 0``)."""
    if not m > 0:
        return math.nan
    w = md + uu * m
    r = a1 * m - w
    return (w * w * md / (a1 * m * m) + r * r * (uu * a4 - a3 * w) / (a1 * a2 * m * m)
            - uu * w * r / (a1 * m) - uu * md - ud * m)


# error_model="numpy": a division by an underflowed m*m gives inf (the rows then take the scalar
# path) instead of raising ZeroDivisionError inside the kernel
_bullinger_s_nb = njit(cache=True, error_model="numpy")(_bullinger_s_row)
_bullinger_phi_nb = njit(cache=True, error_model="numpy")(_bullinger_phi_row)


@njit(cache=True, error_model="numpy")
def _bullinger_from_normal_rows(Z: Array, U: Array, a1: float, a2: float) -> Array:
    """Rows ``(m, s)`` of :func:`_bullinger_s_row`; NaN rows outside the domain."""
    N = Z.shape[0]
    X = np.empty((N, 2))
    for i in range(N):
        s = _bullinger_s_nb(Z[i, 0], Z[i, 1], U[i, 0], a1, a2)
        X[i, 0] = Z[i, 0] if s == s else np.nan
        X[i, 1] = s
    return X


@njit(cache=True, error_model="numpy")
def _bullinger_phi_rows(Z: Array, U: Array, c: Array) -> Array:
    """:func:`_bullinger_phi_row` of the rows with ``u' = 0``; ``c = (a1, a2, a3, a4)``."""
    N = Z.shape[0]
    out = np.empty(N)
    for i in range(N):
        out[i] = _bullinger_phi_nb(Z[i, 0], Z[i, 1], U[i, 0], 0.0, c[0], c[1], c[2], c[3])
    return out


@register_jitable
def _bullinger_rates(m: Any, s: Any, uu: Any, a1: float, a2: float, a3: float,
                     a4: float) -> tuple[Any, Any]:
    """Eq. 15: ``(m', s')`` with the growth ``a1 m s / (a2 m + s)``; floats or arrays (the
    columns of a batch), and compiled into kernels (:class:`BullingerModel`)."""
    g = a1 * m * s / (a2 * m + s)
    return g - uu * m, -a3 * g - uu * s + uu * a4


@register_jitable
def _bullinger_dynamics_row(x: Array, u: Array, c: Array, out: Array) -> None:
    """``out = f(x, u)`` of one row, ``c = (a1, a2, a3, a4)``: :meth:`BioreactorBullinger.dynamics`."""
    out[0], out[1] = _bullinger_rates(x[0], x[1], u[0], c[0], c[1], c[2], c[3])


class BullingerModel(CompiledModel):
    """The bioreactor of paper 000 for numba kernels (no analytic Jacobian: the filters
    difference it)."""

    __slots__ = ()
    dynamics = staticmethod(_bullinger_dynamics_row)


class BioreactorBullinger(System):
    """Generic bioreactor of paper 000 (Bastin and Dochain's model), eq. 15.

    Microorganism concentration :math:`m`, substrate concentration :math:`s`, substrate inflow
    rate :math:`u` (per hour); the microorganism concentration is measured:

    .. math::

        \\dot m &= \\frac{a_1 m s}{a_2 m + s} - u m \\\\
        \\dot s &= -\\frac{a_3 a_1 m s}{a_2 m + s} - u s + u a_4 \\\\
        y &= m

    with :math:`a_1 = a_2 = a_3 = 1`, :math:`a_4 = 0.1`, :math:`m(0) = 0.075`,
    :math:`s(0) = 0.03`, time in hours. The paper states that all states are strictly positive
    and that the high-gain assumptions A1, A2 hold for :math:`u \\in (0, a_4)`; the input
    profile is :func:`bullinger_input`.

    **Normal form (eq. 16).** :math:`z = \\Phi(m, s, u) = (m, \\dot m)`, order :math:`n = 2`,
    :math:`\\dot z_1 = z_2`, :math:`\\dot z_2 = \\varphi(z, u, \\dot u) = \\ddot m`.
    With :math:`w = z_2 + u z_1 = a_1 m s / (a_2 m + s)` (the growth term), the inverse is

    .. math::

        s = \\Phi^{-1}_2(z, u) = \\frac{a_2 z_1 w}{a_1 z_1 - w},

    valid on the domain :math:`z_1 > 0,\\ 0 \\le w < a_1 z_1` (for :math:`a_1, a_2 > 0`),
    which is exactly the image of :math:`m > 0, s \\ge 0`: the growth term lies in
    :math:`[0, a_1 m)`. Outside it :meth:`from_normal` raises :class:`DesignError`. In these
    coordinates :math:`\\partial_m g = w^2/(a_1 m^2)`,
    :math:`\\partial_s g = (a_1 m - w)^2/(a_1 a_2 m^2)` with :math:`g = a_1 m s/(a_2 m + s)`, so

    .. math::

        \\varphi = \\frac{w^2}{a_1 z_1^2} z_2
                 + \\frac{(a_1 z_1 - w)^2}{a_1 a_2 z_1^2} (u a_4 - a_3 w)
                 - \\frac{u w (a_1 z_1 - w)}{a_1 z_1} - u z_2 - \\dot u z_1,

    a rational function defined for every :math:`z_1 > 0` (the analytic continuation of
    :math:`\\ddot m` beyond the physical domain).

    References
    ----------
    Paper 000 (``000_76f8d44710f783d2.txt``), section 4, eq. 15 (model, parameters, initial
    state), eq. 16 (normal form :math:`\\Phi`), input profile below eq. 16.

    Parameters
    ----------
    **params : float
        Values of some of ``param_names`` (``a1`` to ``a4``); the others take
        ``default_params`` (the paper's values).

    Examples
    --------
    >>> bio = BioreactorBullinger()
    >>> bio
    BioreactorBullinger(a1=1, a2=1, a3=1, a4=0.1)
    >>> z = bio.to_normal(bio.default_x0, [0.08])
    >>> z.round(6)
    array([0.075   , 0.015429])
    >>> bio.from_normal(z, [0.08]).round(6)
    array([0.075, 0.03 ])
    >>> round(bio.phi(z, [0.08]), 6)
    -0.008051
    """

    name: ClassVar[str] = "bioreactor_bullinger"
    summary: ClassVar[str] = "Bioreactor m, s with growth a1 m s/(a2 m + s), y = m (paper 000, eq. 15)"
    reference: ClassVar[str] = ("Bullinger, Ilchmann, Allgöwer, NOLCOS 1998 "
                                "(paper 000), eq. 15 (model), eq. 16 (normal form)")
    state_names: ClassVar[tuple[str, ...]] = ("m", "s")
    #: concentrations; the paper states no unit for them ("conc."), time in hours
    state_units: ClassVar[tuple[str, ...]] = ("conc.", "conc.")
    time_unit: ClassVar[str] = "h"
    input_names: ClassVar[tuple[str, ...]] = ("u",)
    output_names: ClassVar[tuple[str, ...]] = ("m",)
    param_names: ClassVar[tuple[str, ...]] = ("a1", "a2", "a3", "a4")
    default_params: ClassVar[Mapping[str, float]] = {"a1": 1.0, "a2": 1.0, "a3": 1.0, "a4": 0.1}
    default_x0: ClassVar[tuple[float, ...]] = (0.075, 0.03)
    normal_form_order: ClassVar[int | None] = 2
    compiled: ClassVar[CompiledModel | None] = BullingerModel()

    @staticmethod
    def dynamics(t: float, x: Array, u: Array, p: Mapping[str, float]) -> Array:
        """Eq. 15: ``[m', s']`` (fast path, no checks)."""
        return np.array(_bullinger_rates(x[0], x[1], u[0], p["a1"], p["a2"], p["a3"], p["a4"]))

    @staticmethod
    def output(x: Array, p: Mapping[str, float]) -> Array:
        """``y = m``."""
        return np.array([x[0]])

    # ----------------------------------------------------------- normal form
    @staticmethod
    def _u(u: Any) -> float:
        if u is None:
            raise DesignError("the bioreactor's normal form depends on the input u; give u "
                              "(the substrate inflow rate, per hour)")
        return float(vector("u", u, 1)[0])

    def _positive_a(self) -> tuple[float, float]:
        a1, a2 = self.params["a1"], self.params["a2"]
        if not (a1 > 0 and a2 > 0):
            raise DesignError(f"the normal form needs a1 > 0 and a2 > 0; found a1={a1}, a2={a2}")
        return a1, a2

    def to_normal(self, x: Any, u: Any = None) -> Array:
        """:math:`\\Phi`: ``(m, s) -> z = (m, m')`` at input ``u`` (eq. 16).

        Parameters
        ----------
        x : array_like, shape (2,)
            Physical state ``(m, s)``.
        u : float or array_like, shape (1,)
            Substrate inflow rate.

        Returns
        -------
        ndarray, shape (2,)
        """
        x = vector("x", x, 2)
        uu = self._u(u)
        return np.array([x[0], self.dynamics(0.0, x, np.array([uu]), self.params)[0]])

    def from_normal(self, z: Any, u: Any = None) -> Array:
        """:math:`\\Phi^{-1}`: ``z = (m, m') -> (m, s)`` at input ``u``.

        Solves :math:`\\dot m = a_1 m s/(a_2 m + s) - u m` for :math:`s`:
        :math:`s = a_2 m w / (a_1 m - w)` with :math:`w = \\dot m + u m`.

        Raises
        ------
        DesignError
            Outside the domain :math:`m > 0,\\ 0 \\le \\dot m + u m < a_1 m` (where no
            non-negative substrate concentration produces ``m'``), or if ``u`` is missing.
        """
        z = vector("z", z, 2)
        uu = self._u(u)
        a1, a2 = self._positive_a()
        m = z[0]
        w = z[1] + uu * m
        if not m > 0:
            raise DesignError(f"Phi^-1 of the bioreactor needs m = z1 > 0; found m = {m:.6g}")
        if not 0.0 <= w < a1 * m:
            raise DesignError(
                f"Phi^-1 of the bioreactor is defined for 0 <= m' + u m < a1 m (growth term of "
                f"a non-negative substrate); found m' + u m = {w:.6g} with a1 m = {a1 * m:.6g} "
                f"(m = {m:.6g}, m' = {z[1]:.6g}, u = {uu:.6g})")
        return np.array([m, _bullinger_s_row(m, z[1], uu, a1, a2)])

    def from_normal_batch(self, Z: Array, U: Array) -> Array:
        """:meth:`from_normal` of the rows ``Z`` ``(N, 2)``, ``U`` ``(N, 1)``, compiled (equal to
        the scalar path bit for bit); NaN rows where it raises (outside the domain, a1 or
        a2 not > 0, or a non-finite entry).

        Parameters
        ----------
        Z : (N, 2) ndarray of float
            Normal-form rows ``(m, m')``.
        U : (N, 1) ndarray of float
            Substrate inflow rates, one per row.

        Returns
        -------
        (N, 2) ndarray of float
            ``(m, s)`` per row; NaN rows where the inverse is not defined.

        Examples
        --------
        >>> import numpy as np
        >>> bio = BioreactorBullinger()
        >>> Z = np.array([bio.to_normal(bio.default_x0, [0.08]), [-1.0, 0.0]])
        >>> bio.from_normal_batch(Z, np.full((2, 1), 0.08)).round(6)
        array([[0.075, 0.03 ],
               [  nan,   nan]])
        """
        return _bullinger_from_normal_rows(  # type: ignore[no-any-return]
            np.ascontiguousarray(Z, dtype=float), np.ascontiguousarray(U, dtype=float),
            self.params["a1"], self.params["a2"])

    def phi(self, z: Any, u: Any = None, u_dot: float = 0.0) -> float:
        """:math:`\\varphi(z, u, \\dot u) = \\ddot m` in normal-form coordinates (see the class).

        Parameters
        ----------
        z : array_like, shape (2,)
            ``(m, m')``, with ``m > 0``.
        u : float or array_like, shape (1,)
            Substrate inflow rate.
        u_dot : float, optional
            Its derivative (zero between the jumps of :func:`bullinger_input`).

        Raises
        ------
        DesignError
            If ``m <= 0`` (``phi`` has a pole at ``m = 0``) or ``u`` is missing.
        """
        z = vector("z", z, 2)
        uu = self._u(u)
        ud = finite_scalar("u_dot", u_dot)
        a1, a2 = self._positive_a()
        m, md = z[0], z[1]
        if not m > 0:
            raise DesignError(f"phi of the bioreactor needs m = z1 > 0; found m = {m:.6g}")
        return float(_bullinger_phi_row(m, md, uu, ud, a1, a2, self.params["a3"],
                                        self.params["a4"]))

    def phi_batch(self, Z: Array, U: Array) -> Array:
        """:meth:`phi_unchecked` (``u' = 0``) of the rows ``Z`` ``(N, 2)``, ``U`` ``(N, 1)``,
        compiled (equal to the scalar path bit for bit). Where a row would raise (``m <= 0``,
        a non-finite entry, ``a1`` or ``a2`` not > 0) or is not finite, the rows go through
        the scalar path, which raises the same :class:`DesignError` as before."""
        Z = np.ascontiguousarray(Z, dtype=float)
        U = np.ascontiguousarray(U, dtype=float)
        p = self.params
        out = _bullinger_phi_rows(Z, U, np.array([p["a1"], p["a2"], p["a3"], p["a4"]]))
        if (p["a1"] > 0 and p["a2"] > 0 and np.isfinite(out).all() and np.isfinite(Z).all()
                and np.isfinite(U).all()):
            return out  # type: ignore[no-any-return]
        return super().phi_batch(Z, U)


# =====================================================================================
# Paper 002: Bastin, Gevers -- biotechnological process, eq. 6.1-6.6
# =====================================================================================

#: bound ``u_max`` of assumption F.4 met by :func:`bastin_gevers_input` with the default ``p2``
BASTIN_GEVERS_U_MAX = 10.0


def bastin_gevers_input(t: float) -> Array:
    """Feed rates for :class:`BioreactorBastinGevers` (chosen here: the paper gives none).

    .. math::

        u_1(t) = 5 + 2 \\sin(0.5 t) + \\sin(1.7 t), \\qquad
        u_2(t) = 0.5 + 0.3 \\sin(1.1 t)

    (time in units of the residence time, the flow rate being one). Both are positive and,
    with the default yield :math:`p_2 = 0.5` and maintenance :math:`p_3 = 0.05`,
    :math:`u_1 + u_2/p_2 \\in [2.4, 9.6] \\subset [p_2 p_3 u_{max}, u_{max}]` for
    :math:`u_{max} = 10`, so assumption F.4 holds; three incommensurate frequencies make
    :math:`\\omega = (y, u_1, u_2)` rich enough to identify the three :math:`\\theta`.

    Parameters
    ----------
    t : float
        Time in residence times.

    Returns
    -------
    ndarray, shape (2,)
        ``[u1(t), u2(t)]``.

    References
    ----------
    Paper 002, section 6, assumption F.4.

    Examples
    --------
    >>> bastin_gevers_input(0.0)
    array([5. , 0.5])
    """
    t = _time(t)
    return np.array([5.0 + 2.0 * math.sin(0.5 * t) + math.sin(1.7 * t),
                     0.5 + 0.3 * math.sin(1.1 * t)])


@register_jitable
def _bastin_gevers_rates(z1: Any, z2: Any, u1: Any, u2: Any, mu_max: float, K_m: float,
                         K_c: float, p2: float, p3: float) -> tuple[Any, Any]:
    """Eq. 6.1 (with the substrate dilution ``-z1``): ``(z1', z2')``, floats or columns, and
    compiled (:class:`BastinGeversModel`)."""
    p1 = mu_max / (K_m + K_c * z2 + z1)
    return -(p1 / p2) * z1 * z2 - p3 * z2 - z1 + u1, p1 * z1 * z2 - z2 + u2


@register_jitable
def _bastin_gevers_dynamics_row(x: Array, u: Array, c: Array, out: Array) -> None:
    """``out = f(x, u)``, ``c = (mu_max, K_m, K_c, p2, p3)``."""
    out[0], out[1] = _bastin_gevers_rates(x[0], x[1], u[0], u[1], c[0], c[1], c[2], c[3], c[4])


class BastinGeversModel(CompiledModel):
    """The bioreactor of paper 002 for numba kernels."""

    __slots__ = ()
    dynamics = staticmethod(_bastin_gevers_dynamics_row)


class BioreactorBastinGevers(System):
    """Biomass growth in a continuous stirred tank reactor, paper 002, eq. 6.1 (corrected).

    Substrate :math:`z_1` (measured), biomass :math:`z_2`, substrate feed rate :math:`u_1`,
    biomass feed rate :math:`u_2`, unit flow rate (time in residence times), yield
    :math:`p_2`, maintenance :math:`p_3`, specific growth rate :math:`p_0 = p_1 z_1`:

    .. math::

        \\dot z_1 &= -\\frac{p_1}{p_2} z_1 z_2 - p_3 z_2 - z_1 + u_1 \\\\
        \\dot z_2 &= p_1 z_1 z_2 - z_2 + u_2 \\\\
        y &= z_1, \\qquad
        p_0 = p_1 z_1 = \\frac{\\mu^* z_1}{K_m + K_c z_2 + z_1}

    **Correction of eq. 6.1.** The paper prints the substrate equation without the dilution
    term :math:`-z_1`. The term is restored here because (i) with a unit flow rate both
    concentrations are diluted (the biomass equation has its :math:`-z_2`); (ii) the paper's
    transformation 6.4 takes the model into its AOCF 6.5 only with it: along the printed 6.1,
    :math:`\\dot x_1 - (x_2 + y\\theta_1 + u_1) = z_1` and
    :math:`\\dot x_2 - (\\text{6.5, row 2}) = (1 - c_2) z_1`, both zero with :math:`-z_1`
    restored (verified in ``tests/systems/test_paper_systems.py`` for random states, inputs and
    :math:`c_2`); (iii) assumption F.4 and condition C.1 are the bound
    :math:`z_1 + z_2/p_2 \\le u_{max}`, which is invariant because
    :math:`\\frac{d}{dt}(z_1 + z_2/p_2) = -(z_1 + z_2/p_2) - p_3 z_2 + u_1 + u_2/p_2`, again only
    with the dilution of :math:`z_1`. Keeping the printed 6.1 would instead need three
    changes (checked numerically): :math:`c_2 - 1` for :math:`c_2 - 2` in 6.4c,
    :math:`+c_2(1 - c_2) y` for :math:`-(1 - c_2)^2 y` in :math:`g` of 6.5, and the same
    :math:`c_2 - 1` in 6.6c-d; one change is enough here.

    **Growth law (chosen).** The paper leaves :math:`p_0(z_1, z_2, t)` free (its observer does
    not use it) and cites Monod 6.2 and Contois 6.3; both are covered by
    :math:`\\mu^* z_1/(K_m + K_c z_2 + z_1)` (Monod: :math:`K_c = 0`, Contois:
    :math:`K_m = 0`). The paper gives no numbers; the defaults, chosen here, are Monod with
    :math:`\\mu^* = 3`, :math:`K_m = 1`, :math:`p_2 = 0.5`, :math:`p_3 = 0.05`
    (so :math:`p_2 p_3 = 0.025 \\ll 1`, F.2), :math:`z(0) = (1, 1)` (C.1 with
    :math:`u_{max} = 10`), and the input :func:`bastin_gevers_input` (F.4). The positive
    orthant and :math:`z_1 + z_2/p_2 \\le u_{max}` are then invariant.

    **AOCF (eq. 6.4, 6.5).** For a design constant :math:`c_2 > 0`,

    .. math::

        x_1 &= z_1, \\quad x_2 = (1 - c_2) z_1 - p_3 z_2, \\\\
        \\theta_1 &= -\\frac{p_1}{p_2} z_2 + (c_2 - 2), \\quad
        \\theta_2 = -\\Big[(1 - c_2)\\frac{p_1}{p_2} + p_1 p_3\\Big] z_2, \\quad
        \\theta_3 = -p_3,

    .. math::

        \\dot x = \\begin{bmatrix} 0 & 1 \\\\ 0 & -c_2 \\end{bmatrix} x
                + \\begin{bmatrix} y & 0 & 0 \\\\ 0 & y & u_2 \\end{bmatrix} \\theta
                + \\begin{bmatrix} u_1 \\\\ (1 - c_2) u_1 - (1 - c_2)^2 y \\end{bmatrix}

    with time-varying :math:`\\theta` (through :math:`p_1 z_2`). The inverse 6.6 is

    .. math::

        p_3 = -\\theta_3, \\quad z_2 = \\frac{x_2 - (1 - c_2) y}{\\theta_3}, \\quad
        p_1 = \\frac{(c_2 - 2 - \\theta_1)(1 - c_2) + \\theta_2}{\\theta_3 z_2}, \\quad
        p_2 = \\frac{p_1 z_2}{(c_2 - 2) - \\theta_1}.

    **Correction of eq. 6.6b.** The paper prints
    :math:`z_2 = (-x_2 + (1 - c_2) y)/\\theta_3`, which returns :math:`-z_2` (from 6.4b,
    :math:`p_3 z_2 = (1 - c_2) z_1 - x_2` and :math:`\\theta_3 = -p_3`), and then 6.6c returns
    :math:`-p_1`; the sign is corrected here. 6.6a, c, d are right as printed (with the
    corrected :math:`z_2`). The inverse exists where :math:`\\theta_3 \\ne 0` (maintenance
    :math:`p_3 \\ne 0`), :math:`z_2 \\ne 0` and :math:`p_1 z_2 \\ne 0`.

    References
    ----------
    Paper 002 (``002_7adafa82055be9d3.txt``), section 6: eq. 6.1 (model), 6.2-6.3 (growth
    laws), F.1-F.4 (assumptions), 6.4 (map to AOCF), 6.5 (AOCF), 6.6 (inverse), C.1.

    Parameters
    ----------
    **params : float
        Values of some of ``param_names`` (``mu_max``, ``K_m``, ``K_c``, ``p2``, ``p3``); the others take
        ``default_params`` (Monod, ``mu_max = 3``, ``K_m = 1``,
        ``K_c = 0``, ``p2 = 0.5``, ``p3 = 0.05``).

    Examples
    --------
    >>> bg = BioreactorBastinGevers()
    >>> bg
    BioreactorBastinGevers(mu_max=3, K_m=1, K_c=0, p2=0.5, p3=0.05)
    >>> bg.f(0.0, [1.0, 1.0], [5.0, 0.5])
    array([0.95, 1.  ])
    >>> x, theta = bg.to_aocf([1.0, 1.0])
    >>> bg.aocf_rhs(x, theta, [5.0, 0.5])  # eq. 6.5 along 6.4: (z1', (1 - c2) z1' - p3 z2')
    array([ 0.95, -1.  ])
    """

    name: ClassVar[str] = "bioreactor_bastin_gevers"
    summary: ClassVar[str] = ("CSTR substrate/biomass with yield and maintenance, y = substrate "
                              "(paper 002, eq. 6.1)")
    reference: ClassVar[str] = ("Bastin, Gevers 1986/88 (paper 002), eq. 6.1 "
                                "(dilution -z1 restored), 6.2-6.3, AOCF 6.4-6.5, inverse 6.6 "
                                "(sign of 6.6b corrected)")
    state_names: ClassVar[tuple[str, ...]] = ("z1", "z2")
    #: substrate and biomass concentrations, no unit stated in the paper ("conc."); time in
    #: residence times (unit flow rate), dimensionless
    state_units: ClassVar[tuple[str, ...]] = ("conc.", "conc.")
    time_unit: ClassVar[str] = ""
    input_names: ClassVar[tuple[str, ...]] = ("u1", "u2")
    output_names: ClassVar[tuple[str, ...]] = ("z1",)
    param_names: ClassVar[tuple[str, ...]] = ("mu_max", "K_m", "K_c", "p2", "p3")
    compiled: ClassVar[CompiledModel | None] = BastinGeversModel()
    default_params: ClassVar[Mapping[str, float]] = {
        "mu_max": 3.0, "K_m": 1.0, "K_c": 0.0, "p2": 0.5, "p3": 0.05}
    default_x0: ClassVar[tuple[float, ...]] = (1.0, 1.0)
    #: default design constant ``c2 > 0`` of the AOCF (the pole ``-c2`` of ``F``)
    default_c2: ClassVar[float] = 2.0
    forms: ClassVar[tuple[str, ...]] = ("aocf",)

    @staticmethod
    def _p1(z1: float, z2: float, p: Mapping[str, float]) -> float:
        return p["mu_max"] / (p["K_m"] + p["K_c"] * z2 + z1)

    @staticmethod
    def dynamics(t: float, x: Array, u: Array, p: Mapping[str, float]) -> Array:
        """Eq. 6.1 with the substrate dilution ``-z1``: ``[z1', z2']`` (fast path)."""
        return np.array(_bastin_gevers_rates(x[0], x[1], u[0], u[1], p["mu_max"], p["K_m"],
                                             p["K_c"], p["p2"], p["p3"]))

    @staticmethod
    def output(x: Array, p: Mapping[str, float]) -> Array:
        """``y = z1`` (substrate)."""
        return np.array([x[0]])

    def specific_growth_rate(self, z: Any) -> float:
        """:math:`p_0 = p_1 z_1 = \\mu^* z_1/(K_m + K_c z_2 + z_1)` (eq. 6.2 / 6.3).

        Parameters
        ----------
        z : array_like, shape (2,)
            ``(z1, z2)``: substrate and biomass concentrations.

        Returns
        -------
        float
            The specific growth rate :math:`p_0` (per residence time).

        Examples
        --------
        >>> BioreactorBastinGevers().specific_growth_rate([1.0, 1.0])  # 3 * 1 / (1 + 0 + 1)
        1.5
        """
        z = vector("z", z, 2)
        return float(self._p1(z[0], z[1], self.params) * z[0])

    def _c2(self, c2: Any) -> float:
        c2 = self.default_c2 if c2 is None else finite_scalar("c2", c2)
        if not c2 > 0:
            raise DesignError(f"the AOCF design constant c2 must be > 0; found {c2}")
        return c2

    def to_aocf(self, z: Any, c2: float | None = None) -> tuple[Array, Array]:
        """Eq. 6.4: physical state ``z`` to AOCF state ``x`` and parameters ``theta``.

        Parameters
        ----------
        z : array_like, shape (2,)
            ``(z1, z2)``.
        c2 : float, optional
            Design constant ``> 0`` (default :attr:`default_c2`).

        Returns
        -------
        x : ndarray, shape (2,)
        theta : ndarray, shape (3,)
            Time-varying through :math:`p_1(z) z_2`.

        Examples
        --------
        >>> x, theta = BioreactorBastinGevers().to_aocf([1.0, 1.0])
        >>> x, theta
        (array([ 1.  , -1.05]), array([-3.   ,  2.925, -0.05 ]))
        """
        z = vector("z", z, 2)
        c2 = self._c2(c2)
        p = self.params
        p1, p2, p3 = self._p1(z[0], z[1], p), p["p2"], p["p3"]
        x = np.array([z[0], (1.0 - c2) * z[0] - p3 * z[1]])
        theta = np.array([-(p1 / p2) * z[1] + (c2 - 2.0),
                          (-(1.0 - c2) * p1 / p2 - p1 * p3) * z[1],
                          -p3])
        return x, theta

    def from_aocf(self, x: Any, theta: Any, c2: float | None = None) -> tuple[Array, Array]:
        """Eq. 6.6 (with the sign of 6.6b corrected): ``(x, theta) -> (z, (p1, p2, p3))``.

        Parameters
        ----------
        x : array_like, shape (2,)
            AOCF state ``(x1, x2)``, ``x1 = y = z1``.
        theta : array_like, shape (3,)
            AOCF parameters ``(theta1, theta2, theta3)``.
        c2 : float, optional
            Design constant ``> 0`` (default :attr:`default_c2`); the one used by
            :meth:`to_aocf`.

        Returns
        -------
        z : ndarray, shape (2,)
            ``(z1, z2)``.
        params : ndarray, shape (3,)
            ``(p1, p2, p3)``; ``p1 = p0/z1`` is the (time-varying) growth coefficient.

        Raises
        ------
        DesignError
            Where the inverse does not exist: ``theta3 == 0`` (no maintenance, ``z2`` not
            observable from ``x2``), ``z2 == 0`` or ``(c2 - 2) - theta1 == 0`` (``p1 z2 = 0``).

        Examples
        --------
        >>> bg = BioreactorBastinGevers()
        >>> bg.from_aocf(*bg.to_aocf([1.0, 1.0]))
        (array([1., 1.]), array([1.5 , 0.5 , 0.05]))
        """
        x = vector("x", x, 2)
        th = vector("theta", theta, 3)
        c2 = self._c2(c2)
        y = x[0]
        if th[2] == 0.0:
            raise DesignError("the AOCF inverse (eq. 6.6) needs theta3 = -p3 != 0; found 0 "
                              "(without maintenance z2 cannot be recovered from x2)")
        z2 = (x[1] - (1.0 - c2) * y) / th[2]
        d = (c2 - 2.0) - th[0]
        if z2 == 0.0 or d == 0.0:
            raise DesignError(f"the AOCF inverse (eq. 6.6c-d) needs z2 != 0 and "
                              f"(c2 - 2) - theta1 != 0; found z2 = {z2:.6g}, "
                              f"(c2 - 2) - theta1 = {d:.6g}")
        p1 = (d * (1.0 - c2) + th[1]) / (th[2] * z2)
        p2 = p1 * z2 / d
        return np.array([y, z2]), np.array([p1, p2, -th[2]])

    def aocf_structure(self, y: float, u: Any, c2: float | None = None
                       ) -> tuple[Array, Array, Array]:
        """``R``, ``Omega(omega)`` and ``g`` of the AOCF eq. 6.5 at output ``y`` and input ``u``.

        Parameters
        ----------
        y : float
            Output ``y = z1`` (substrate).
        u : array_like, shape (2,)
            Feed rates ``(u1, u2)``.
        c2 : float, optional
            Design constant ``> 0`` (default :attr:`default_c2`).

        Returns
        -------
        R : ndarray, shape (2, 2)
            ``[[0, 1], [0, -c2]]`` (``k = 1``, ``F = -c2`` in eq. 2.3).
        Omega : ndarray, shape (2, 3)
            ``[[y, 0, 0], [0, y, u2]]``.
        g : ndarray, shape (2,)
            ``[u1, (1 - c2) u1 - (1 - c2)^2 y]``.

        Examples
        --------
        >>> R, Omega, g = BioreactorBastinGevers().aocf_structure(1.0, [5.0, 0.5])
        >>> R
        array([[ 0.,  1.],
               [ 0., -2.]])
        >>> Omega
        array([[1. , 0. , 0. ],
               [0. , 1. , 0.5]])
        >>> g
        array([ 5., -6.])
        """
        y = finite_scalar("y", y)
        u = vector("u", u, 2)
        c2 = self._c2(c2)
        R = np.array([[0.0, 1.0], [0.0, -c2]])
        Omega = np.array([[y, 0.0, 0.0], [0.0, y, u[1]]])
        g = np.array([u[0], (1.0 - c2) * u[0] - (1.0 - c2) ** 2 * y])
        return R, Omega, g

    def aocf_rhs(self, x: Any, theta: Any, u: Any, c2: float | None = None) -> Array:
        """Right-hand side of the AOCF eq. 6.5, ``R x + Omega(y, u) theta + g``, ``y = x1``.

        Parameters
        ----------
        x : array_like, shape (2,)
            AOCF state.
        theta : array_like, shape (3,)
            AOCF parameters.
        u : array_like, shape (2,)
            Feed rates ``(u1, u2)``.
        c2 : float, optional
            Design constant ``> 0`` (default :attr:`default_c2`).

        Returns
        -------
        ndarray, shape (2,)
            ``dx/dt``.

        Examples
        --------
        >>> bg = BioreactorBastinGevers()
        >>> x, theta = bg.to_aocf([1.0, 1.0])
        >>> bg.aocf_rhs(x, theta, [5.0, 0.5])
        array([ 0.95, -1.  ])
        """
        x = vector("x", x, 2)
        th = vector("theta", theta, 3)
        R, Omega, g = self.aocf_structure(x[0], u, c2)
        return R @ x + Omega @ th + g

    def _form_aocf(self, c2: float | None = None) -> AOCF:
        """The AOCF eq. 6.5 (paper 002) as an :class:`~hgo_mj.systems.aocf.AOCF` on rows,
        built on :meth:`aocf_structure`.

        :math:`\\omega = (y, u_1, u_2)`, :math:`k = 1`, :math:`F = -c_2`,
        :math:`\\Omega = [[y, 0, 0], [0, y, u_2]]`,
        :math:`g = (u_1, (1 - c_2) u_1 - (1 - c_2)^2 y)`. The inverse 6.6 (sign of 6.6b
        corrected, as :meth:`from_aocf`) gives the physical state ``(z1, z2)`` and the
        parameters ``p1``, ``p2``, ``p3`` and the specific growth rate ``p0 = p1 z1``; it is NaN
        where it does not exist. The forward map is 6.4b with :math:`p_3 = -\\theta_3`.

        The form's ``start`` (an observer's default initial estimate) is the nominal model at
        the default state, eq. 6.4 at ``default_x0`` with this system's parameters: the zero
        estimate lies outside the domain of 6.6 (:math:`\\theta_3 = -p_3 \\ne 0` and
        :math:`z_2 \\ne 0` are needed), a nominal one inside it.

        References
        ----------
        Paper 002, eq. 6.4 (map), 6.5 (AOCF), 6.6 (inverse).
        """
        c2v = self._c2(c2)
        # alpha and the matrix of g by probing the paper's structure at unit omega
        basis = [(1.0, (0.0, 0.0)), (0.0, (1.0, 0.0)), (0.0, (0.0, 1.0))]
        alpha = np.zeros((2, 3, 3))
        G = np.zeros((2, 3))
        for l, (y, u) in enumerate(basis):
            R, Om, g = self.aocf_structure(y, u, c2v)
            alpha[:, :, l] = Om
            G[:, l] = g
        w = np.array([0.7, 1.3, -0.4])
        R, Om, g = self.aocf_structure(w[0], w[1:], c2v)
        if not (np.allclose(alpha @ w, Om, atol=1e-12) and np.allclose(G @ w, g, atol=1e-12)):
            raise DesignError("the bioreactor AOCF is expected linear in omega = (y, u1, u2); "
                              "aocf_structure is not")
        ga, gb = tuple(float(v) for v in G[0]), tuple(float(v) for v in G[1])

        def omega(Y: Array, U: Array) -> Array:  # omega = (y, u1, u2)
            W = np.empty((len(Y), 3))
            W[:, 0] = Y
            W[:, 1] = U[:, 0]
            W[:, 2] = U[:, 1]
            return W

        def g_fun(Y: Array, U: Array) -> Array:
            G = np.empty((len(Y), 2))
            G[:, 0] = ga[0] * Y + ga[1] * U[:, 0] + ga[2] * U[:, 1]
            G[:, 1] = gb[0] * Y + gb[1] * U[:, 0] + gb[2] * U[:, 1]
            return G

        def to_physical(X: Array, TH: Array, U: Array) -> tuple[Array, Array]:
            # eq. 6.6 (6.6b sign corrected) as from_aocf, NaN where it does not exist
            y, th1, th2, th3 = X[:, 0], TH[:, 0], TH[:, 1], TH[:, 2]
            d = (c2v - 2.0) - th1
            states, params = np.empty((len(X), 2)), np.empty((len(X), 4))
            states[:, 0] = y
            with np.errstate(divide="ignore", invalid="ignore"):
                z2 = states[:, 1] = (X[:, 1] - (1.0 - c2v) * y) / th3
                p1 = params[:, 0] = (d * (1.0 - c2v) + th2) / (th3 * z2)
                params[:, 1] = p1 * z2 / d
                params[:, 2] = -th3
                params[:, 3] = p1 * y
            bad = (th3 == 0.0) | (z2 == 0.0) | (d == 0.0)
            if np.count_nonzero(bad):
                states[bad] = params[bad] = np.nan
            return states, params

        def from_physical(Z: Array, TH: Array, U: Array) -> Array:
            # eq. 6.4b with p3 = -theta3
            X = np.empty((len(Z), 2))
            X[:, 0] = Z[:, 0]
            X[:, 1] = (1.0 - c2v) * Z[:, 0] + TH[:, 2] * Z[:, 1]
            return X

        return AOCF(R, alpha, omega, g=g_fun, theta_names=("1", "2", "3"),
                    omega_names=("y", "u1", "u2"), to_physical=to_physical,
                    from_physical=from_physical, state_names=self.state_names,
                    physical_param_names=("p1", "p2", "p3", "p0"), rows=True,
                    label=f"{type(self).__name__} eq. 6.5, c2={c2v:g}",
                    inverse_domain="theta3 = -p3 != 0, z2 != 0 and (c2 - 2) - theta1 != 0, "
                                   "eq. 6.6",
                    start=self.to_aocf(self.default_x0, c2v)
                    )._made_by(system_form, self, "aocf", c2=c2)


# =====================================================================================
# Paper 001: Besançon, Zhang, Hammouri -- section 4 examples
# =====================================================================================


def besancon_ex1_input(t: float) -> Array:
    """Input of both examples of paper 001, section 4: ``[sin 2t + 0.1 cos 10t]``.

    Parameters
    ----------
    t : float
        Time (dimensionless, as in the paper).

    Returns
    -------
    ndarray, shape (1,)

    References
    ----------
    Paper 001, section 4, first example.

    Examples
    --------
    >>> besancon_ex1_input(0.0)
    array([0.1])
    """
    t = _time(t)
    return np.array([math.sin(2.0 * t) + 0.1 * math.cos(10.0 * t)])


def besancon_ex2_signal(t: float) -> Array:
    """The input of paper 001's second example and its exact derivatives.

    .. math::

        u &= \\sin 2t + 0.1 \\cos 10t, \\qquad \\dot u = 2 \\cos 2t - \\sin 10t, \\\\
        \\ddot u &= -4 \\sin 2t - 10 \\cos 10t

    Parameters
    ----------
    t : float
        Time (dimensionless).

    Returns
    -------
    ndarray, shape (3,)
        ``[u(t), u'(t), u''(t)]``.

    Examples
    --------
    >>> besancon_ex2_signal(0.0)
    array([  0.1,   2. , -10. ])
    """
    t = _time(t)
    s2, c2, s10, c10 = math.sin(2 * t), math.cos(2 * t), math.sin(10 * t), math.cos(10 * t)
    return np.array([s2 + 0.1 * c10, 2.0 * c2 - s10, -4.0 * s2 - 10.0 * c10])


def besancon_ex2_input(t: float) -> Array:
    """Plant input of :class:`BesanconExample2`: ``[u''(t)]``, the exact second derivative.

    It drives the input generator :math:`x[2] = (u, \\dot u)` so that ``x3`` follows
    :math:`u(t) = \\sin 2t + 0.1 \\cos 10t`. Held over a control period ``dt``, sample it at
    the middle, ``besancon_ex2_input(t_k + dt/2)``: then ``x4 - u'(t)`` is ``O(dt**2)`` and
    ``x3 - u(t)`` drifts only by about ``dt**2/24 |u'''(0)| t`` (``3.3e-5 t`` for
    ``dt = 0.01``). Sampled at ``t_k`` instead, ``u'`` is biased by ``dt/2 u''(0) = -5 dt``
    and ``x3`` drifts by ``5 dt t`` (about 0.9 at ``t = 9`` for ``dt = 0.02``), which changes
    the trajectory completely (``|y'|`` reaches 8 instead of 1.4).

    Parameters
    ----------
    t : float
        Time (dimensionless); mid-period when the input is held.

    Returns
    -------
    ndarray, shape (1,)
        ``[u''(t)] = [-4 sin 2t - 10 cos 10t]``.

    Examples
    --------
    >>> besancon_ex2_input(0.0)
    array([-10.])
    """
    return besancon_ex2_signal(t)[2:]


@njit(cache=True)
def _besancon_ex1_terms(Z: Array, U: Array) -> tuple[Array, Array]:
    """Rows of :class:`BesanconExample1` in the form eq. 9: :math:`\\varphi = (u, -x_1 - 2
    \\sin x_2)`, :math:`\\psi_{2\\cdot} = (\\arctan x_2, \\cos(x_1 x_2))`."""
    N = Z.shape[0]
    phi = np.empty((N, 2))
    psi = np.empty((N, 1, 2))
    for b in range(N):
        x1, x2 = Z[b, 0], Z[b, 1]
        phi[b, 0] = U[b, 0]
        phi[b, 1] = -x1 - 2.0 * math.sin(x2)
        psi[b, 0, 0] = math.atan(x2)
        psi[b, 0, 1] = math.cos(x1 * x2)
    return phi, psi


@njit(cache=True)
def _besancon_ex2_terms(Z: Array, U: Array) -> tuple[Array, Array]:
    """Rows of :class:`BesanconExample2` in the form eq. 21: :math:`\\varphi = (0, \\sin(x_1
    x_2), 0, v)`, :math:`\\psi_{2\\cdot} = (\\cos(x_1 x_2), x_4 x_3^2)`, :math:`\\psi_{4\\cdot} = 0`."""
    N = Z.shape[0]
    phi = np.zeros((N, 4))
    psi = np.zeros((N, 2, 2))
    for b in range(N):
        x1, x2, x3, x4 = Z[b, 0], Z[b, 1], Z[b, 2], Z[b, 3]
        w = x1 * x2
        phi[b, 1] = math.sin(w)
        phi[b, 3] = U[b, 0]
        psi[b, 0, 0] = math.cos(w)
        psi[b, 0, 1] = x4 * x3 * x3
    return phi, psi


def _paper001_form(system: System, unknown: Any, terms: Any, label: str) -> Any:
    """The form of one of paper 001's examples: the compiled ``terms`` for the class itself,
    the protocol (its ``phi0``, ``regressor``, evaluated row by row) for a subclass that may
    have changed them."""
    from .affine_form import AffineForm

    if unknown is not None:
        raise DesignError(f"unknown= chooses parameters of a derived form; "
                          f"{type(system).__name__} gives its own (regressor columns)")
    if type(system) not in (BesanconExample1, BesanconExample2):
        return AffineForm.from_protocol(system)
    orders = (2,) if type(system) is BesanconExample1 else (2, 2)
    return AffineForm(orders=orders, theta_names=system.param_names, terms=terms, label=label,
                      theta=system.theta,  # type: ignore[attr-defined]
                      state_names=system.state_names, n_inputs=1
                      )._made_by(type(system)._form_affine, system, unknown)  # type: ignore[attr-defined]


@register_jitable
def _besancon1_rates(x1: float, x2: float, u0: float, th1: float,
                     th2: float) -> tuple[float, float]:
    """Paper 001, example 1: ``(x1', x2')`` (and compiled, :class:`Besancon1Model`)."""
    return (x2 + u0,
            -x1 - 2.0 * math.sin(x2) + math.atan(x2) * th1 + math.cos(x1 * x2) * th2)


@register_jitable
def _besancon1_dynamics_row(x: Array, u: Array, c: Array, out: Array) -> None:
    """``out = f(x, u)``, ``c = (theta1, theta2)``."""
    out[0], out[1] = _besancon1_rates(x[0], x[1], u[0], c[0], c[1])


class Besancon1Model(CompiledModel):
    """Paper 001's example 1 for numba kernels."""

    __slots__ = ()
    dynamics = staticmethod(_besancon1_dynamics_row)


class BesanconExample1(System):
    """First example of paper 001, section 4: single output, two unknown parameters.

    .. math::

        \\dot x_1 &= x_2 + u \\\\
        \\dot x_2 &= -x_1 - 2 \\sin x_2 + \\arctan(x_2)\\, \\theta_1
                    + \\cos(x_1 x_2)\\, \\theta_2 \\\\
        y &= x_1

    with :math:`\\theta = (1, 2)`, :math:`x(0) = (1, 1)`,
    :math:`u(t) = \\sin 2t + 0.1 \\cos 10t` (:func:`besancon_ex1_input`). In the form eq. 9,

    .. math::

        \\dot x = A_0 x + \\varphi(x, u) + \\psi(x, u) \\theta, \\quad
        A_0 = \\begin{bmatrix} 0 & 1 \\\\ 0 & 0 \\end{bmatrix}, \\quad
        \\varphi = \\begin{bmatrix} u \\\\ -x_1 - 2 \\sin x_2 \\end{bmatrix}, \\quad
        \\psi = \\begin{bmatrix} 0 & 0 \\\\ \\arctan x_2 & \\cos(x_1 x_2) \\end{bmatrix},

    which has the triangular structure eq. 3 and the last-row-only :math:`\\psi` of eq. 7
    ([A1]). ``theta1``, ``theta2`` are parameters like any other here; the observer decides
    what it treats as unknown.

    References
    ----------
    Paper 001 (``001_fa1af3b6b9a222a1.txt``), section 4 (first example), eq. 9 (form),
    eq. 2-3, 7 (structure), eq. 12 (observer).

    Parameters
    ----------
    **params : float
        Values of some of ``param_names`` (``theta1``, ``theta2``); the others take
        ``default_params`` (the paper's ``(1, 2)``).

    Examples
    --------
    >>> ex = BesanconExample1()
    >>> ex.theta
    array([1., 2.])
    >>> ex.f(0.0, [1.0, 1.0], [0.1]).round(6)
    array([ 1.1     , -0.816939])
    >>> ex.form("affine").theta_names
    ('theta1', 'theta2')
    """

    name: ClassVar[str] = "besancon_ex1"
    summary: ClassVar[str] = ("x1' = x2 + u, x2' = -x1 - 2 sin x2 + atan(x2) th1 + cos(x1 x2) th2 "
                              "(paper 001, sec. 4)")
    reference: ClassVar[str] = ("Besançon, Zhang, Hammouri, NOLCOS 2004 (paper 001), "
                                "section 4 first example, form eq. 9")
    state_names: ClassVar[tuple[str, ...]] = ("x1", "x2")
    #: a mathematical example: dimensionless states and time (the paper states no units)
    state_units: ClassVar[tuple[str, ...]] = ("", "")
    time_unit: ClassVar[str] = ""
    input_names: ClassVar[tuple[str, ...]] = ("u",)
    output_names: ClassVar[tuple[str, ...]] = ("y",)
    param_names: ClassVar[tuple[str, ...]] = ("theta1", "theta2")
    compiled: ClassVar[CompiledModel | None] = Besancon1Model()
    default_params: ClassVar[Mapping[str, float]] = {"theta1": 1.0, "theta2": 2.0}
    default_x0: ClassVar[tuple[float, ...]] = (1.0, 1.0)
    forms: ClassVar[tuple[str, ...]] = ("affine",)

    @staticmethod
    def dynamics(t: float, x: Array, u: Array, p: Mapping[str, float]) -> Array:
        """``[x1', x2']`` (fast path)."""
        return np.array(_besancon1_rates(x[0], x[1], u[0], p["theta1"], p["theta2"]))

    @staticmethod
    def output(x: Array, p: Mapping[str, float]) -> Array:
        """``y = x1``."""
        return np.array([x[0]])

    @property
    def theta(self) -> Array:
        """``(theta1, theta2)`` of this instance."""
        return np.array([self.params["theta1"], self.params["theta2"]])

    @property
    def A(self) -> Array:
        """:math:`A_0` of eq. 2 (a fresh array)."""
        return np.array([[0.0, 1.0], [0.0, 0.0]])

    @property
    def C(self) -> Array:
        """:math:`C_0 = (1, 0)` of eq. 2, shape (1, 2)."""
        return np.array([[1.0, 0.0]])

    def phi0(self, x: Any, u: Any) -> Array:
        """:math:`\\varphi(x, u) = (u, -x_1 - 2 \\sin x_2)` of eq. 9.

        Parameters
        ----------
        x : array_like, shape (2,)
            State ``(x1, x2)``.
        u : array_like, shape (1,)
            Input ``u``.

        Returns
        -------
        ndarray, shape (2,)
            :math:`\\varphi`.

        Examples
        --------
        >>> BesanconExample1().phi0([1.0, 1.0], [0.1]).round(6)
        array([ 0.1     , -2.682942])
        """
        x = vector("x", x, 2)
        u = vector("u", u, 1)
        return np.array([u[0], -x[0] - 2.0 * math.sin(x[1])])

    def regressor(self, x: Any, u: Any) -> Array:
        """:math:`\\psi(x, u)`, shape (2, 2), of eq. 9: ``[[0, 0], [atan x2, cos(x1 x2)]]``.

        Parameters
        ----------
        x : array_like, shape (2,)
            State ``(x1, x2)``.
        u : array_like, shape (1,)
            Input ``u`` (checked, not used).

        Returns
        -------
        ndarray, shape (2, 2)
            :math:`\\psi`, columns in the order of ``(theta1, theta2)``.

        Examples
        --------
        >>> BesanconExample1().regressor([1.0, 1.0], [0.1]).round(6)
        array([[0.      , 0.      ],
               [0.785398, 0.540302]])
        """
        x = vector("x", x, 2)
        vector("u", u, 1)
        return np.array([[0.0, 0.0], [math.atan(x[1]), math.cos(x[0] * x[1])]])

    def _form_affine(self, unknown: Any = None) -> Any:
        """This system in the form eq. 9 (an :class:`~hgo_mj.systems.affine_form.AffineForm`
        with compiled rows, equal to :meth:`AffineForm.from_protocol` of :meth:`phi0` and
        :meth:`regressor`, checked in ``tests/observers/test_besancon.py``)."""
        return _paper001_form(self, unknown, _besancon_ex1_terms, "paper 001 example 1 (eq. 9)")


@register_jitable
def _besancon2_rates(x1: float, x2: float, x3: float, x4: float, u0: float, th1: float,
                     th2: float) -> tuple[float, float, float, float]:
    """Paper 001, example 2: ``(y', y'', u', u'')`` (and compiled, :class:`Besancon2Model`)."""
    w = x1 * x2
    return x2, math.sin(w) + math.cos(w) * th1 + x4 * x3 * x3 * th2, x4, u0


@register_jitable
def _besancon2_dynamics_row(x: Array, u: Array, c: Array, out: Array) -> None:
    """``out = f(x, u)``, ``c = (theta1, theta2)``."""
    out[0], out[1], out[2], out[3] = _besancon2_rates(x[0], x[1], x[2], x[3], u[0], c[0], c[1])


class Besancon2Model(CompiledModel):
    """Paper 001's example 2 for numba kernels."""

    __slots__ = ()
    dynamics = staticmethod(_besancon2_dynamics_row)


class BesanconExample2(System):
    """Second example of paper 001, section 4: an input-output model with two outputs.

    The model :math:`\\ddot y = \\sin(y \\dot y) + \\cos(y \\dot y)\\, \\theta_1
    + \\dot u u^2 \\theta_2` with :math:`\\theta = (10, -5)` and
    :math:`u(t) = \\sin 2t + 0.1 \\cos 10t`, written as eq. 6 / 21 with
    :math:`x[1] = (y, \\dot y)`, :math:`x[2] = (u, \\dot u)` and both :math:`y` and :math:`u`
    measured. The second block is an input generator driven by the plant input
    :math:`v = \\ddot u` (:func:`besancon_ex2_input`, exact):

    .. math::

        \\dot x_1 = x_2, \\quad
        \\dot x_2 = \\sin(x_1 x_2) + \\cos(x_1 x_2)\\, \\theta_1 + x_4 x_3^2\\, \\theta_2, \\quad
        \\dot x_3 = x_4, \\quad \\dot x_4 = v, \\quad y = (x_1, x_3).

    In the form eq. 21, :math:`A = \\mathrm{diag}(A_1, A_2)` (two 2x2 integrator chains),
    :math:`C = \\mathrm{diag}(C_1, C_2)`,

    .. math::

        \\varphi(x, v) = (0, \\sin(x_1 x_2), 0, v), \\qquad
        \\psi(x, v) = \\begin{bmatrix} 0 & 0 \\\\ \\cos(x_1 x_2) & x_4 x_3^2 \\\\
                                      0 & 0 \\\\ 0 & 0 \\end{bmatrix},

    with the structure [A1'] (the last entry of :math:`\\psi_1` may depend on :math:`x[2]`).
    The paper instead takes a piecewise-linear approximation of :math:`u` (so
    :math:`\\ddot u = 0` almost everywhere and the second block of :math:`\\varphi` vanishes);
    feeding ``v = 0`` between breakpoints reproduces that convention. When ``v`` is held
    over a control period, sample it mid-period (see :func:`besancon_ex2_input`): sampling at
    the period's start makes ``x3`` drift away from :math:`u(t)` linearly in time.

    The paper gives no initial state; :math:`(y, \\dot y)(0) = (1, 1)` is chosen here (as in
    the first example) and :math:`x[2](0) = (u(0), \\dot u(0)) = (0.1, 2)` is fixed by the
    input. Note (found here, not in the paper): the state is not bounded. The averaged
    dynamics drive :math:`y \\dot y` to the root :math:`w^* = \\pi - \\arctan 10 \\approx
    1.6705` of :math:`\\sin w + 10 \\cos w` (the forcing :math:`\\dot u u^2 =
    \\frac{d}{dt} u^3/3` has zero mean), so :math:`y^2/2 \\approx w^* t` and :math:`y`
    grows like :math:`\\sqrt{2 w^* t}` (about 18 at :math:`t = 100`); bounds ``X`` in the
    observer's saturation must allow for this horizon.

    References
    ----------
    Paper 001 (``001_fa1af3b6b9a222a1.txt``), section 4 (second example), eq. 6, 8 (input-output
    model), eq. 21 (form), eq. 24 (observer).

    Parameters
    ----------
    **params : float
        Values of some of ``param_names`` (``theta1``, ``theta2``); the others take
        ``default_params`` (the paper's ``(10, -5)``).

    Examples
    --------
    >>> ex = BesanconExample2()
    >>> ex.h(ex.default_x0)
    array([1. , 0.1])
    >>> ex.form("affine")
    AffineForm('paper 001 example 2 (eq. 21)', orders=[2, 2], theta=['theta1', 'theta2'])
    """

    name: ClassVar[str] = "besancon_ex2"
    summary: ClassVar[str] = ("y'' = sin(y y') + cos(y y') th1 + u' u^2 th2 with outputs (y, u) "
                              "(paper 001, sec. 4)")
    reference: ClassVar[str] = ("Besançon, Zhang, Hammouri, NOLCOS 2004 (paper 001), "
                                "section 4 second example, form eq. 6 / 21")
    state_names: ClassVar[tuple[str, ...]] = ("y", "y_dot", "u", "u_dot")
    #: a mathematical example: dimensionless states and time (the paper states no units)
    state_units: ClassVar[tuple[str, ...]] = ("", "", "", "")
    time_unit: ClassVar[str] = ""
    input_names: ClassVar[tuple[str, ...]] = ("u_ddot",)
    output_names: ClassVar[tuple[str, ...]] = ("y", "u")
    param_names: ClassVar[tuple[str, ...]] = ("theta1", "theta2")
    compiled: ClassVar[CompiledModel | None] = Besancon2Model()
    default_params: ClassVar[Mapping[str, float]] = {"theta1": 10.0, "theta2": -5.0}
    default_x0: ClassVar[tuple[float, ...]] = (1.0, 1.0, 0.1, 2.0)
    forms: ClassVar[tuple[str, ...]] = ("affine",)

    @staticmethod
    def dynamics(t: float, x: Array, u: Array, p: Mapping[str, float]) -> Array:
        """``[y', y'', u', u'']`` (fast path); ``u[0]`` is the generator input ``u''``."""
        return np.array(_besancon2_rates(x[0], x[1], x[2], x[3], u[0], p["theta1"],
                                         p["theta2"]))

    @staticmethod
    def output(x: Array, p: Mapping[str, float]) -> Array:
        """``y = (x1, x3)``: the model output and the input."""
        return np.array([x[0], x[2]])

    @property
    def theta(self) -> Array:
        """``(theta1, theta2)`` of this instance."""
        return np.array([self.params["theta1"], self.params["theta2"]])

    @property
    def A(self) -> Array:
        """``diag(A1, A2)`` of eq. 21, shape (4, 4)."""
        A = np.zeros((4, 4))
        A[0, 1] = A[2, 3] = 1.0
        return A

    @property
    def C(self) -> Array:
        """``diag(C1, C2)`` of eq. 21, shape (2, 4)."""
        C = np.zeros((2, 4))
        C[0, 0] = C[1, 2] = 1.0
        return C

    def phi0(self, x: Any, u: Any) -> Array:
        """:math:`\\varphi(x, v) = (0, \\sin(x_1 x_2), 0, v)` of eq. 21, ``v = u''``.

        Parameters
        ----------
        x : array_like, shape (4,)
            State ``(y, y', u, u')``.
        u : array_like, shape (1,)
            Input ``v = u''`` of the input generator.

        Returns
        -------
        ndarray, shape (4,)
            :math:`\\varphi`.

        Examples
        --------
        >>> BesanconExample2().phi0([1.0, 1.0, 0.1, 2.0], [0.5]).round(6)
        array([0.      , 0.841471, 0.      , 0.5     ])
        """
        x = vector("x", x, 4)
        u = vector("u", u, 1)
        return np.array([0.0, math.sin(x[0] * x[1]), 0.0, u[0]])

    def regressor(self, x: Any, u: Any) -> Array:
        """:math:`\\psi(x, v)`, shape (4, 2), of eq. 21 (only row 2 is non-zero).

        Parameters
        ----------
        x : array_like, shape (4,)
            State ``(y, y', u, u')``.
        u : array_like, shape (1,)
            Input ``v = u''`` (checked, not used).

        Returns
        -------
        ndarray, shape (4, 2)
            :math:`\\psi`; row 2 is ``(cos(x1 x2), x4 x3^2)``.

        Examples
        --------
        >>> BesanconExample2().regressor([1.0, 1.0, 0.1, 2.0], [0.5])[1].round(6)
        array([0.540302, 0.02    ])
        """
        x = vector("x", x, 4)
        vector("u", u, 1)
        psi = np.zeros((4, 2))
        psi[1] = (math.cos(x[0] * x[1]), x[3] * x[2] * x[2])
        return psi

    def _form_affine(self, unknown: Any = None) -> Any:
        """This system in the form eq. 21 (chains ``(y, y')`` and ``(u, u')``; compiled rows,
        equal to :meth:`AffineForm.from_protocol` of :meth:`phi0` and :meth:`regressor`)."""
        return _paper001_form(self, unknown, _besancon_ex2_terms, "paper 001 example 2 (eq. 21)")


# =====================================================================================
# Paper 003: Jo, Son -- example eq. 28-31
# =====================================================================================


def jo_son_input(t: float) -> Array:
    """Input of paper 003, section 4: ``[sin(pi t/3) sin(pi t/2)]``.

    Parameters
    ----------
    t : float
        Time [s].

    Returns
    -------
    ndarray, shape (1,)

    Examples
    --------
    >>> jo_son_input(1.0).round(6)
    array([0.866025])
    """
    t = _time(t)
    return np.array([math.sin(math.pi * t / 3.0) * math.sin(math.pi * t / 2.0)])


# The form eq. 30-31 on rows, component first (``y`` (N,), ``u`` (1, N), ``z`` (3, N)): see
# hgo_mj.systems.jo_son_form. Module level, so that the form pickles.


def jo_son_T(x: Any) -> tuple[Any, Any, Any]:
    """Eq. 30, :math:`z = T(x) = (x_1^3/3 + x_2,\\ x_1,\\ x_3 - x_1^2/2)`, component first."""
    return (x[0] ** 3 / 3.0 + x[1], x[0], x[2] - 0.5 * x[0] ** 2)


def jo_son_T_inverse(z: Any) -> tuple[Any, Any, Any]:
    """Inverse of eq. 30, :math:`x = (z_2,\\ z_1 - z_2^3/3,\\ z_3 + z_2^2/2)`, component
    first."""
    z2 = z[1]
    return (z2, z[0] - z2 * z2 * z2 / 3.0, z[2] + 0.5 * (z2 * z2))


# powers as products: pow() of a negative base takes a slow path in libm (60 ns an element)


def _jo_son_gamma_o(y: Any, u: Any) -> tuple[Any, Any]:
    """Eq. 31: :math:`\\gamma_o = (-y^5 + (y \\sin y + y^2) u,\\ -\\tfrac43 y^3 + u)`."""
    uu = u[0]
    y2 = y * y
    return (-(y2 * y2 * y) + (y * np.sin(y) + y2) * uu, -4.0 / 3.0 * (y2 * y) + uu)


def _jo_son_beta(y: Any, u: Any) -> tuple[Any]:
    """Eq. 31: :math:`\\beta = y u`."""
    return (y * u[0],)


def _jo_son_f_obar(y: Any, zb: Any) -> tuple[Any]:
    """Eq. 31: :math:`f_{\\bar o}(y, z_3) = -z_3 - (z_3 + y^2/2)^3`."""
    c = zb[0] + 0.5 * y * y
    return (-zb[0] - c * c * c,)


def _jo_son_gamma_obar(y: Any, u: Any) -> tuple[Any]:
    """Eq. 31: :math:`\\gamma_{\\bar o} = -y^2/2 + y^4`."""
    y2 = y * y
    return (-0.5 * y2 + y2 * y2,)


@register_jitable
def _jo_son_rates(x1: float, x2: float, x3: float, uu: float,
                  th: float) -> tuple[float, float, float]:
    """Paper 003, eq. 28: ``(x1', x2', x3')`` (and compiled, :class:`JoSonModel`)."""
    x1sq = x1 * x1
    return (x2 - x1sq * x1 + uu + th * x1 * uu,
            -x1sq * x2 + x1 * math.sin(x1) * uu + 2.0 * th * x1 * uu - th * x1sq * x1 * uu,
            -x3 - x3 * x3 * x3 + x1 * x2 + x1 * uu + th * x1sq * uu)


@register_jitable
def _jo_son_dynamics_row(x: Array, u: Array, c: Array, out: Array) -> None:
    """``out = f(x, u)``, ``c = (theta,)``."""
    out[0], out[1], out[2] = _jo_son_rates(x[0], x[1], x[2], u[0], c[0])


class JoSonModel(CompiledModel):
    """Paper 003's example for numba kernels."""

    __slots__ = ()
    dynamics = staticmethod(_jo_son_dynamics_row)


class JoSonExample(System):
    """Example of paper 003, eq. 28: a not-observable system with one unknown parameter.

    .. math::

        \\dot x_1 &= x_2 - x_1^3 + u + \\theta x_1 u \\\\
        \\dot x_2 &= -x_1^2 x_2 + x_1 \\sin(x_1) u + 2 \\theta x_1 u - \\theta x_1^3 u \\\\
        \\dot x_3 &= -x_3 - x_3^3 + x_1 x_2 + x_1 u + \\theta x_1^2 u \\\\
        y &= x_1

    with :math:`\\theta = 1`, :math:`x(0) = (0.5, 1, -1)`,
    :math:`u = \\sin(\\pi t/3) \\sin(\\pi t/2)` (:func:`jo_son_input`). The coordinate change
    eq. 30 and its inverse are

    .. math::

        z = T(x) = \\begin{bmatrix} x_1^3/3 + x_2 \\\\ x_1 \\\\ x_3 - x_1^2/2 \\end{bmatrix},
        \\qquad
        x = T^{-1}(z) = \\begin{bmatrix} z_2 \\\\ z_1 - z_2^3/3 \\\\ z_3 + z_2^2/2
        \\end{bmatrix},

    giving the adaptive observer canonical form eq. 31 (``y = z_2``, :math:`b = (2, 1)`,
    :math:`\\beta(y, u) = y u`):

    .. math::

        \\dot z_1 &= -y^5 + (y \\sin y + y^2) u + 2 \\theta y u \\\\
        \\dot z_2 &= z_1 - \\tfrac43 y^3 + u + \\theta y u \\\\
        \\dot z_3 &= -z_3 - (z_3 + \\tfrac12 y^2)^3 - \\tfrac12 y^2 + y^4

    Verified: the derivative of :math:`T(x)` along eq. 28 equals eq. 31 at :math:`z = T(x)`
    (symbolically by hand and numerically in ``tests/systems/test_paper_systems.py``), and
    :math:`T^{-1}` is the map the paper uses in its observer. Eq. 28, 30 and 31 are mutually
    consistent; no correction is needed. (In the paper's observer equations, printed after
    eq. 31, the line for :math:`\\dot{\\hat z}_2` reads :math:`z_1` where
    :math:`\\hat z_1` is meant; this does not concern the plant.) Since
    :math:`\\partial \\dot z_3/\\partial z_3 = -1 - 3(z_3 + y^2/2)^2 \\le -1`, the unobservable
    part contracts at rate at least 1 (Corollary 3.3 (i) with :math:`P_2 = 1`, :math:`k_0 = 1`).

    References
    ----------
    Paper 003 (``003_bd61d49996cbe973.txt``), section 4: eq. 28 (system), eq. 29 (condition
    of Theorem 3.1), eq. 30 (transformation), eq. 31 (canonical form); eq. 10 (form), eq. 25,
    27 (observer).

    Parameters
    ----------
    **params : float
        Values of some of ``param_names`` (``theta``); the others take
        ``default_params`` (the paper's ``theta = 1``).

    Examples
    --------
    >>> ex = JoSonExample()
    >>> ex.f(0.0, ex.default_x0, [0.3]).round(6)
    array([1.325   , 0.084414, 2.725   ])
    >>> ex.form("jo_son")
    JoSonForm(Jo-Son example eq. 31: r=2, n=3, b=[2.0, 1.0], theta=['theta'])
    """

    name: ClassVar[str] = "jo_son"
    summary: ClassVar[str] = "Not-observable 3-state system with unknown theta (paper 003, eq. 28)"
    reference: ClassVar[str] = ("Jo, Son, KSME Int. J. 2004 (paper 003), eq. 28 "
                                "(system), eq. 30 (transformation), eq. 31 (canonical form)")
    state_names: ClassVar[tuple[str, ...]] = ("x1", "x2", "x3")
    #: a mathematical example: dimensionless states; time in seconds ("after approximately
    #: 2 seconds", section 4)
    state_units: ClassVar[tuple[str, ...]] = ("", "", "")
    input_names: ClassVar[tuple[str, ...]] = ("u",)
    output_names: ClassVar[tuple[str, ...]] = ("y",)
    param_names: ClassVar[tuple[str, ...]] = ("theta",)
    compiled: ClassVar[CompiledModel | None] = JoSonModel()
    default_params: ClassVar[Mapping[str, float]] = {"theta": 1.0}
    default_x0: ClassVar[tuple[float, ...]] = (0.5, 1.0, -1.0)
    #: ``b`` of the canonical form eq. 10 / 31 (``b_r = 1 > 0``, ``s + 2`` Hurwitz)
    b: ClassVar[tuple[float, float]] = (2.0, 1.0)
    #: the adaptive observer canonical form eq. 31 (:meth:`_form_jo_son`)
    forms: ClassVar[tuple[str, ...]] = ("jo_son",)

    @staticmethod
    def dynamics(t: float, x: Array, u: Array, p: Mapping[str, float]) -> Array:
        """Eq. 28: ``[x1', x2', x3']`` (fast path)."""
        return np.array(_jo_son_rates(x[0], x[1], x[2], u[0], p["theta"]))

    @staticmethod
    def output(x: Array, p: Mapping[str, float]) -> Array:
        """``y = x1``."""
        return np.array([x[0]])

    def to_canonical(self, x: Any) -> Array:
        """Eq. 30: :math:`z = T(x) = (x_1^3/3 + x_2,\\ x_1,\\ x_3 - x_1^2/2)`.

        Parameters
        ----------
        x : array_like, shape (3,)
            Physical state ``(x1, x2, x3)``.

        Returns
        -------
        ndarray, shape (3,)
            Canonical state ``z``.

        Examples
        --------
        >>> JoSonExample().to_canonical([0.5, 1.0, -1.0]).round(6)
        array([ 1.041667,  0.5     , -1.125   ])
        """
        return np.array(jo_son_T(vector("x", x, 3)))

    def from_canonical(self, z: Any) -> Array:
        """Inverse of eq. 30: :math:`x = (z_2,\\ z_1 - z_2^3/3,\\ z_3 + z_2^2/2)`.

        Parameters
        ----------
        z : array_like, shape (3,)
            Canonical state ``(z1, z2, z3)``.

        Returns
        -------
        ndarray, shape (3,)
            Physical state ``x``.

        Examples
        --------
        >>> ex = JoSonExample()
        >>> ex.from_canonical(ex.to_canonical([0.5, 1.0, -1.0])).round(12)
        array([ 0.5,  1. , -1. ])
        """
        return np.array(jo_son_T_inverse(vector("z", z, 3)))

    def _form_jo_son(self) -> Any:
        """The adaptive observer canonical form eq. 31 (paper 003, eq. 10).

        :math:`r = 2`, :math:`b = (2, 1)`, :math:`\\beta = y u`,
        :math:`\\gamma_o = (-y^5 + (y \\sin y + y^2) u,\\ -\\tfrac43 y^3 + u)`,
        :math:`f_{\\bar o}(y, z_3) = -z_3 - (z_3 + y^2/2)^3`,
        :math:`\\gamma_{\\bar o} = -y^2/2 + y^4`, :math:`A_{\\bar o o} = 0`, and
        :math:`T^{-1}(z) = (z_2, z_1 - z_2^3/3, z_3 + z_2^2/2)` (eq. 30). Its functions are
        module level (rows, component first), so the form pickles.

        References
        ----------
        Paper 003, eq. 28, 30, 31.
        """
        return JoSonForm(self.b, _jo_son_gamma_o, _jo_son_beta, n_unobservable=1,
                         f_obar=_jo_son_f_obar, gamma_obar=_jo_son_gamma_obar,
                         theta_names=("theta",), to_physical=jo_son_T_inverse,
                         from_physical=jo_son_T, state_names=self.state_names,
                         label="Jo-Son example eq. 31")

    @staticmethod
    def beta(y: float, u: float) -> float:
        """:math:`\\beta(y, u) = y u` of eq. 10 / 31.

        Parameters
        ----------
        y : float
            Output.
        u : float
            Input.

        Returns
        -------
        float
            ``y * u``.

        Examples
        --------
        >>> JoSonExample.beta(0.5, 2.0)
        1.0
        """
        return float(y) * float(u)

    def canonical_rhs(self, z: Any, u: Any) -> Array:
        """Right-hand side of eq. 31 at canonical state ``z`` (``y = z2``) and input ``u``.

        Parameters
        ----------
        z : array_like, shape (3,)
            Canonical state.
        u : array_like, shape (1,)
            Input.

        Returns
        -------
        ndarray, shape (3,)
            ``dz/dt``; equals ``dT/dx f(x, u)`` at ``z = T(x)``.

        Examples
        --------
        >>> ex = JoSonExample()
        >>> ex.canonical_rhs(ex.to_canonical(ex.default_x0), [0.3]).round(6)
        array([0.415664, 1.325   , 2.0625  ])
        """
        z = vector("z", z, 3)
        uu = float(vector("u", u, 1)[0])
        th = self.params["theta"]
        y = z[1]
        c = z[2] + 0.5 * y * y
        return np.array([
            -y ** 5 + (y * math.sin(y) + y * y) * uu + self.b[0] * th * y * uu,
            z[0] - 4.0 / 3.0 * y ** 3 + uu + self.b[1] * th * y * uu,
            -z[2] - c ** 3 - 0.5 * y * y + y ** 4,
        ])
