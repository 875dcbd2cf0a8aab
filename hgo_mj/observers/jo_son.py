"""The adaptive observer of Jo and Son (paper 003) on the generalized observer canonical form.

**Canonical form, eq. 9-10.** A single-output system with unknown constant parameters
:math:`\\theta \\in \\mathbb R^p`, in coordinates :math:`z = (z_o, z_{\\bar o})`,
:math:`z_o \\in \\mathbb R^r`:

.. math::

    \\dot z_o &= A_o z_o + \\gamma_o(y, u) + b\\, \\beta^T(y, u)\\, \\theta \\\\
    \\dot z_{\\bar o} &= A_{\\bar o o} z_o + f_{\\bar o}(y, z_{\\bar o}) + \\gamma_{\\bar o}(y, u) \\\\
    y &= C_o z_o = z_{o, r}

with :math:`A_o` the lower shift (:math:`(A_o z)_1 = 0`, :math:`(A_o z)_i = z_{i-1}`) and
:math:`C_o = (0, \\dots, 0, 1)`: the output is the *last* observable coordinate.

**Observer, eq. 27 (Theorem 3.4, Corollary 3.3).**

.. math::

    \\dot{\\hat z}_o &= A_o \\hat z_o + \\gamma_o(y, u) + b \\beta^T(y, u) \\hat\\theta
                       + K (y - \\hat z_r) \\\\
    \\dot{\\hat z}_{\\bar o} &= A_{\\bar o o} \\hat z_o + f_{\\bar o}(y, \\hat z_{\\bar o})
                       + \\gamma_{\\bar o}(y, u) \\\\
    \\dot{\\hat\\theta} &= \\Gamma \\beta(y, u) (y - \\hat z_r), \\qquad
    K = \\frac{1}{b_r} (A_o b + \\lambda b), \\qquad \\hat x = T^{-1}(\\hat z)

valid when :math:`b_r > 0` and :math:`b_r s^{r-1} + \\dots + b_1` is Hurwitz: then
:math:`b_r (s^r + k_r s^{r-1} + \\dots + k_1) = (s + \\lambda)(b_r s^{r-1} + \\dots + b_1)`
(eq. 26), so :math:`C_o (sI - A_o + K C_o)^{-1} b = b_r / (s + \\lambda)` is strictly positive
real and the Meyer-Kalman-Yakubovich lemma gives the Lyapunov function of Theorem 3.2.
The unobservable part must be contracting (Theorem 3.2 (i)); that is a property of the
system the caller asserts, not checked here.

**Misprints of the paper, corrected here.** In eq. 21 and 27 the second line reads
:math:`A_{\\bar o o} \\hat z_{\\bar o}` ("= f"); the proof's error equation
:math:`\\dot e_{\\bar o} = A_{\\bar o o} e_o + \\dots` requires :math:`A_{\\bar o o} \\hat z_o`.
In the proof of Corollary 3.3 the first line reads :math:`b_r b_1 = \\lambda b_1`
(it is :math:`b_r k_1 = \\lambda b_1`) and the transfer function is printed
:math:`C_o (sI - A_o)^{-1} b` (it is :math:`C_o (sI - A_o + K C_o)^{-1} b`). In the example
(section 4) the observer's :math:`\\dot{\\hat z}_2` reads :math:`z_1` where :math:`\\hat z_1` is
meant. The proof of Corollary 3.3 also writes :math:`b \\beta^T e_o`; it is
:math:`b \\beta^T e_\\theta`.

References
----------
.. [003] N.-H. Jo, Y.-I. Son, "Adaptive observer design for nonlinear systems using generalized
   nonlinear observer canonical form", KSME Int. J. 18(7), 2004
   (``shared/papers/003_bd61d49996cbe973.txt``): eq. 9-10 (form), 21 (observer),
   Theorem 3.2 (SPR condition), Corollary 3.3 and eq. 25-26 (gain), Theorem 3.4 and eq. 27,
   section 4 (example, eq. 28-31).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .._validate import finite_scalar, one_of, positive_int, symmetric_matrix, vector
from ..exceptions import DesignError, DimensionError, DivergenceError
from ..systems.base import System
from .base import Array, Observer
from .bastin_gevers import (
    Rebuildable,
    SlidingGram,
    _callable,
    _names,
    check_rk_period,
    initial_estimate,
    rk_step,
)

__all__ = ["JoSonForm", "JoSonObserver", "jo_son_gain"]

METHODS = ("rk4", "euler")


def jo_son_gain(b: Any, lam: float) -> Array:
    """Observer gain of Corollary 3.3, eq. 25: :math:`K = (A_o b + \\lambda b) / b_r`.

    .. math::

        k_1 = \\lambda b_1 / b_r, \\qquad k_i = (b_{i-1} + \\lambda b_i) / b_r, \\quad
        i = 2, \\dots, r

    Parameters
    ----------
    b : array_like, shape (r,)
        The vector :math:`b` of the canonical form eq. 10.
    lam : float
        :math:`\\lambda > 0`.

    Returns
    -------
    ndarray, shape (r,)

    Raises
    ------
    DesignError
        If :math:`b_r \\le 0`, :math:`b_r s^{r-1} + \\dots + b_1` is not Hurwitz (roots listed)
        or :math:`\\lambda \\le 0`: the conditions of Corollary 3.3.

    References
    ----------
    Paper 003, Corollary 3.3, eq. 25-26.
    """
    b = vector("b", b)
    if b.size < 1:
        raise DimensionError("b must have r >= 1 entries; found none")
    lam = finite_scalar("lambda", lam)
    if not lam > 0:
        raise DesignError(f"Corollary 3.3 needs lambda > 0; found lambda = {lam:g}")
    br = float(b[-1])
    if not br > 0:
        raise DesignError(
            f"Corollary 3.3 needs b_r > 0 (the parameters must reach y = z_r with relative degree "
            f"one, and with a positive sign); found b_r = {br:g} in b = {b.tolist()}")
    if b.size > 1:
        roots = np.roots(b[::-1])
        bad = roots[roots.real >= 0]
        if bad.size:
            shown = ", ".join(f"{z:.4g}" for z in bad)
            raise DesignError(
                f"Corollary 3.3 needs b_r s^(r-1) + ... + b_1 Hurwitz (minimum phase from the "
                f"parameters to y); b = {b.tolist()} gives roots [{shown}] with non-negative "
                f"real part")
    Ab = np.concatenate(([0.0], b[:-1]))  # A_o b: lower shift
    return (Ab + lam * b) / br


class JoSonForm(Rebuildable):
    """Adaptive observer canonical form of paper 003, eq. 10.

    Parameters
    ----------
    b : array_like, shape (r,)
        The direction :math:`b` along which the parameters enter :math:`\\dot z_o`.
    gamma_o : callable ``(y, u) -> (r,)``
        :math:`\\gamma_o(y, u)`.
    beta : callable ``(y, u) -> (p,)``
        :math:`\\beta(y, u)`, the regressor (eq. 10: :math:`b \\beta^T \\theta`).
    n_unobservable : int
        :math:`n - r`, the dimension of :math:`z_{\\bar o}` (0: none).
    f_obar : callable ``(y, z_obar) -> (n-r,)``, optional
        :math:`f_{\\bar o}(y, z_{\\bar o})` (required when ``n_unobservable > 0``).
    gamma_obar : callable ``(y, u) -> (n-r,)``, optional
        :math:`\\gamma_{\\bar o}(y, u)` (default zero).
    A_obar_o : array_like, shape (n-r, r), optional
        :math:`A_{\\bar o o}` (default zero).
    theta_names : sequence of str, optional
        ``p`` names (default ``"1".."p"``); the observer reports ``theta_<name>``.
    to_physical : callable ``z -> x``, optional
        :math:`T^{-1}` (eq. 27, first line); default: ``x_hat = z_hat``.
    from_physical : callable ``x -> z``, optional
        :math:`T` (to start from a physical ``x_hat0``).
    state_names : sequence of str, optional
        Names of ``x`` (default ``z1..zn``).
    aux_outputs : sequence of int
        Indices of further measured channels appended to the input vector ``u`` that
        ``gamma_o``, ``beta`` and ``gamma_obar`` receive (signals measured but used as known
        inputs, e.g. a second sensor).
    label : str
        What the form is of, for messages.

    References
    ----------
    Paper 003, eq. 9-10; Theorem 3.1 (conditions for the coordinates to exist).
    """

    def __init__(self, b: Any, gamma_o: Callable[[float, Array], Any],
                 beta: Callable[[float, Array], Any], *, n_unobservable: int = 0,
                 f_obar: Callable[[float, Array], Any] | None = None,
                 gamma_obar: Callable[[float, Array], Any] | None = None,
                 A_obar_o: Any = None, theta_names: Sequence[str] | None = None,
                 n_params: int | None = None,
                 to_physical: Callable[[Array], Any] | None = None,
                 from_physical: Callable[[Array], Any] | None = None,
                 state_names: Sequence[str] | None = None, aux_outputs: Sequence[int] = (),
                 label: str = "adaptive observer canonical form") -> None:
        self.b = vector("b", b)
        if self.b.size < 1:
            raise DimensionError("b must have r >= 1 entries; found none")
        self.r = int(self.b.size)
        if int(n_unobservable) != n_unobservable or n_unobservable < 0:
            raise DesignError(f"n_unobservable must be a non-negative integer; found "
                              f"{n_unobservable!r}")
        self.n_obar = int(n_unobservable)
        self.n = self.r + self.n_obar
        self.gamma_o = _callable("gamma_o", gamma_o)
        self.beta = _callable("beta", beta)
        self.f_obar = _callable("f_obar", f_obar, optional=True)
        self.gamma_obar = _callable("gamma_obar", gamma_obar, optional=True)
        if self.n_obar and self.f_obar is None:
            raise DesignError(f"an unobservable part of dimension {self.n_obar} needs f_obar "
                              f"(eq. 10); found none")
        if not self.n_obar and (f_obar is not None or gamma_obar is not None):
            raise DesignError("f_obar and gamma_obar need n_unobservable > 0")
        if A_obar_o is None:
            self.A_obar_o = np.zeros((self.n_obar, self.r))
        else:
            A = np.array(A_obar_o, dtype=float)
            if A.shape != (self.n_obar, self.r):
                raise DimensionError(f"A_obar_o must have shape (n-r, r) = ({self.n_obar}, "
                                     f"{self.r}); found {A.shape}")
            self.A_obar_o = A
        if theta_names is None and n_params is None:
            raise DesignError("give theta_names or n_params (the number p of parameters)")
        p = len(theta_names) if theta_names is not None else int(n_params)  # type: ignore[arg-type]
        if p < 1:
            raise DimensionError(f"the form needs p >= 1 parameters; found {p}")
        self.p = p
        self.theta_names = _names("theta_names", theta_names, p, [str(i + 1) for i in range(p)])
        self.to_physical = _callable("to_physical", to_physical, optional=True)
        self.from_physical = _callable("from_physical", from_physical, optional=True)
        self.state_names = _names("state_names", state_names, len(state_names or ()) or self.n,
                                  [f"z{i + 1}" for i in range(self.n)])
        aux = tuple(int(i) for i in aux_outputs)
        if any(i < 0 for i in aux):
            raise DesignError(f"aux_outputs must be channel indices >= 0; found {list(aux)}")
        self.aux_outputs = aux
        self.label = str(label)

    def __repr__(self) -> str:
        return (f"JoSonForm({self.label}: r={self.r}, n={self.n}, b={self.b.tolist()}, "
                f"theta={list(self.theta_names)})")

    # ------------------------------------------------------------------ factories
    @classmethod
    def from_system(cls, system: System, **kw: Any) -> JoSonForm:
        """The form eq. 10 of a system where one is derived.

        * :class:`~hgo_mj.systems.papers.JoSonExample`: eq. 31;
        * any system with a method ``jo_son_form(**kw)`` returning a :class:`JoSonForm`.

        For the MuJoCo elastic joint see :meth:`elastic_joint_motor_side` (it needs a sensor
        choice other than the plant's default output).

        Raises
        ------
        DesignError
            For a system without the form, naming what is missing.
        """
        from ..systems.elastic_joint import ElasticJoint
        from ..systems.papers import JoSonExample

        if isinstance(system, JoSonExample):
            return cls.example(system, **kw)
        form = cls._system_method(system, "jo_son_form", kw, cls.from_system)
        if form is not None:
            return form
        hint = ""
        if isinstance(system, ElasticJoint):
            hint = (" (with its default link-angle sensor every parameter reaches y with relative "
                    "degree >= 2, so b_r = 0; measure the motor velocity and the spring deflection "
                    "and use JoSonForm.elastic_joint_motor_side())")
        raise DesignError(
            f"the Jo-Son observer needs the adaptive observer canonical form of paper 003, eq. 10 "
            f"(b, gamma_o, beta, and f_obar for an unobservable part); {type(system).__name__} "
            f"provides none (no method jo_son_form() and no derivation in "
            f"hgo_mj.observers.jo_son){hint}; see docs/adaptive_canonical_forms.md")

    @classmethod
    def example(cls, system: Any = None) -> JoSonForm:
        """The form eq. 31 of the example eq. 28 (:class:`~hgo_mj.systems.papers.JoSonExample`).

        :math:`r = 2`, :math:`b = (2, 1)`, :math:`\\beta = y u`,
        :math:`\\gamma_o = (-y^5 + (y \\sin y + y^2) u,\\ -\\tfrac43 y^3 + u)`,
        :math:`f_{\\bar o}(y, z_3) = -z_3 - (z_3 + y^2/2)^3`,
        :math:`\\gamma_{\\bar o} = -y^2/2 + y^4`, :math:`A_{\\bar o o} = 0`, and
        :math:`T^{-1}(z) = (z_2, z_1 - z_2^3/3, z_3 + z_2^2/2)` (eq. 30).

        References
        ----------
        Paper 003, eq. 28, 30, 31.
        """
        from ..systems.papers import JoSonExample

        sys_ = JoSonExample() if system is None else system
        b = np.array(JoSonExample.b, dtype=float)

        def gamma_o(y: float, u: Array) -> tuple[float, float]:
            uu = u[0]
            return (-y ** 5 + (y * math.sin(y) + y * y) * uu, -4.0 / 3.0 * y ** 3 + uu)

        def beta(y: float, u: Array) -> tuple[float]:
            return (y * u[0],)

        def f_obar(y: float, zb: Array) -> tuple[float]:
            c = zb[0] + 0.5 * y * y
            return (-zb[0] - c * c * c,)

        def gamma_obar(y: float, u: Array) -> tuple[float]:
            return (-0.5 * y * y + y ** 4,)

        def to_physical(z: Array) -> Array:
            return np.array([z[1], z[0] - z[1] ** 3 / 3.0, z[2] + 0.5 * z[1] ** 2])

        return cls(b, gamma_o, beta, n_unobservable=1, f_obar=f_obar, gamma_obar=gamma_obar,
                   theta_names=("theta",), to_physical=to_physical,
                   from_physical=sys_.to_canonical, state_names=sys_.state_names,
                   label="Jo-Son example eq. 31")._made_by(cls.example, system)

    @classmethod
    def elastic_joint_motor_side(cls, aux_outputs: Sequence[int] = (1, 2),
                                 unknown: Sequence[str] = ("b_over_J", "dm_over_J", "K_over_J")
                                 ) -> JoSonForm:
        """The motor side of the elastic joint in the form eq. 10, measured by a motor
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
        A parameter may be declared known by leaving it out of ``unknown`` only if it is
        moved into :math:`\\gamma_o`; this factory estimates all three.

        Parameters
        ----------
        aux_outputs : (int, int)
            Channels of ``link_angle`` and ``motor_angle`` in the measurement vector (the plant
            built with ``outputs=("motor_velocity", "link_angle", "motor_angle")`` has them at
            1 and 2).

        References
        ----------
        Paper 003, eq. 10, Corollary 3.3; docs/adaptive_canonical_forms.md (why the link-angle
        sensor does not qualify).
        """
        aux = tuple(int(i) for i in aux_outputs)
        if len(aux) != 2:
            raise DimensionError(f"aux_outputs must name 2 channels (link_angle, motor_angle); "
                                 f"found {list(aux)}")
        if tuple(unknown) != ("b_over_J", "dm_over_J", "K_over_J"):
            raise DesignError(f"the motor-side form estimates ('b_over_J', 'dm_over_J', "
                              f"'K_over_J'); found {list(unknown)}")

        def gamma_o(y: float, u: Array) -> tuple[float]:
            return (0.0,)

        def beta(y: float, u: Array) -> tuple[float, float, float]:
            # u = (torque, link_angle, motor_angle)
            return (u[0], -y, u[1] - u[2])

        return cls([1.0], gamma_o, beta, theta_names=tuple(unknown),
                   state_names=("motor_velocity",), aux_outputs=aux,
                   label="elastic joint motor side: y = motor velocity, deflection measured"
                   )._made_by(cls.elastic_joint_motor_side, aux_outputs, unknown)


class JoSonObserver(Observer):
    """Adaptive observer of Jo and Son (paper 003, eq. 27) on a :class:`JoSonForm`.

    .. math::

        \\dot{\\hat z}_o &= A_o \\hat z_o + \\gamma_o(y, u) + b \\beta^T(y, u) \\hat\\theta
                           + K (y - \\hat z_r), \\quad
        K = (A_o b + \\lambda b)/b_r \\\\
        \\dot{\\hat z}_{\\bar o} &= A_{\\bar o o} \\hat z_o + f_{\\bar o}(y, \\hat z_{\\bar o})
                           + \\gamma_{\\bar o}(y, u), \\qquad
        \\dot{\\hat\\theta} = \\Gamma \\beta(y, u) (y - \\hat z_r)

    The measurement and the input are held over a sample; ``gamma_o``, ``beta`` and
    ``gamma_obar`` are evaluated once per sample, ``f_obar`` at every stage of the RK4 (or
    Euler) integration.

    Parameters
    ----------
    system : System, optional
        A system with a derived form (:meth:`JoSonForm.from_system`); not needed when ``form``
        is given.
    form : JoSonForm, optional
        The canonical form eq. 10.
    lam : float
        :math:`\\lambda > 0` of eq. 25 (the paper's example: 2).
    gamma : float, array_like (p,) or (p, p)
        :math:`\\Gamma`, symmetric positive definite (the example: 5).
    output : int
        Index of the measured channel that is ``y``.
    theta_hat0 : array_like (p,), optional
        Initial parameter estimate (default zero).
    x_hat0, z_hat0 : array_like, optional
        Initial estimate in physical coordinates (needs ``from_physical``) or in the form's
        coordinates (default zero).
    method : {"rk4", "euler"}
    substeps : int
        Integration steps per sample.
    excitation_window : float or None
        Window of the diagnostic ``excitation``: the smallest eigenvalue of
        :math:`\\int \\beta \\beta^T` over it (identifiability of :math:`\\theta`; the state
        estimate converges without it, Theorem 3.2).

    Attributes
    ----------
    theta_hat_ : ndarray (p,)
    K_ : ndarray (r,)
        The gain of eq. 25.
    dropouts_ : int

    Raises
    ------
    DesignError
        Where the conditions of Corollary 3.3 fail (:func:`jo_son_gain`), Gamma is not
        symmetric positive definite, or the system has no form.

    References
    ----------
    Paper 003, eq. 10, 25-27, Theorem 3.2, Corollary 3.3, Theorem 3.4.
    """

    name = "jo_son"
    summary = "Jo-Son adaptive observer on the generalized observer canonical form, SPR gain"
    reference = "paper 003 (Jo, Son 2004), eq. 10, 25, 27"

    def __init__(self, system: System | None = None, *, form: JoSonForm | None = None,
                 lam: float = 2.0, gamma: Any = 1.0, output: int = 0, theta_hat0: Any = None,
                 x_hat0: Any = None, z_hat0: Any = None, method: str = "rk4", substeps: int = 1,
                 excitation_window: float | None = 10.0) -> None:
        if system is not None and not isinstance(system, System):
            raise DesignError(f"system must be a System instance or None; found "
                              f"{type(system).__name__}")
        if form is None:
            if system is None:
                raise DesignError("JoSonObserver needs a system with a derived form or "
                                  "form=JoSonForm(...)")
            form = JoSonForm.from_system(system)
        elif not isinstance(form, JoSonForm):
            raise DesignError(f"form must be a JoSonForm; found {type(form).__name__}")
        super().__init__(None, form.n, output)
        self.system = system
        self.form = form
        self.lam = finite_scalar("lambda", lam)
        self.K_ = jo_son_gain(form.b, self.lam)
        self.gamma = symmetric_matrix("gamma", gamma, form.p, dim="m")
        # plain-float copies for the per-sample path (numpy scalar indexing is slow)
        self._Kl, self._bl = self.K_.tolist(), form.b.tolist()
        self._Gl = self.gamma.tolist()
        self._Al = form.A_obar_o.tolist() if np.any(form.A_obar_o) else None
        self.method = one_of("method", method, METHODS)
        self.substeps = positive_int("substeps", substeps)
        if excitation_window is not None:
            excitation_window = finite_scalar("excitation_window", excitation_window, positive=True)
        self.excitation_window = excitation_window
        self._gram = SlidingGram(form.p, excitation_window) if excitation_window is not None else None
        self.diagnostic_names = tuple(f"theta_{nm}" for nm in form.theta_names) + (
            ("excitation",) if self._gram is not None else ())
        self._init = (x_hat0, z_hat0, theta_hat0)
        self.reset(x_hat0, z_hat0=z_hat0, theta_hat0=theta_hat0)

    # ------------------------------------------------------------------ reset
    def reset(self, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None,
              theta_hat0: Any = None) -> None:
        """Restart from ``x_hat0``/``z_hat0`` and ``theta_hat0`` (default: the constructor's)."""
        f = self.form
        if x_hat0 is None and z_hat0 is None and theta_hat0 is None:
            x_hat0, z_hat0, theta_hat0 = self._init

        def physical(x_hat0: Any, th: Array) -> Array:
            if f.from_physical is None:
                raise DesignError(f"x_hat0 in physical coordinates needs the form's from_physical "
                                  f"map (T of eq. 27); {f.label} has none: give z_hat0")
            return vector("T(x_hat0)", f.from_physical(vector("x_hat0", x_hat0, len(f.state_names))),
                          f.n)

        z, th = initial_estimate(f.n, f.p, x_hat0, z_hat0, theta_hat0, physical)
        self._s: list[float] = np.concatenate((z, th)).tolist()
        self._aux_last: list[float] | None = None
        self._restart_counters()
        if self._gram is not None:
            self._gram.reset()
        self._xp = np.array(z)
        if f.to_physical is not None:
            x = np.asarray(f.to_physical(z), dtype=float).reshape(-1)
            if not all(map(math.isfinite, x)):
                raise DesignError(f"the initial estimate z = {z.tolist()} lies where the inverse "
                                  f"map T^-1 of {f.label} is undefined (it gives {x.tolist()}); "
                                  f"give x_hat0 / z_hat0 inside its domain")
            self._xp = x

    # ------------------------------------------------------------------ dynamics
    def signals(self, y: float, u: Array) -> tuple[list[float], list[float], list[float]]:
        """:math:`\\gamma_o(y, u)`, :math:`\\beta(y, u)`, :math:`\\gamma_{\\bar o}(y, u)`
        (shape-checked lists); ``u`` here includes the ``aux_outputs`` channels."""
        f = self.form
        try:
            return self._signals(y, u)
        except (IndexError, TypeError) as exc:
            raise DimensionError(f"the signals of {f.label} failed on y = {y!r}, u of shape "
                                 f"{np.shape(u)}: {exc}") from None

    def _signals(self, y: float, u: Array) -> tuple[list[float], list[float], list[float]]:
        f = self.form
        go = [float(v) for v in f.gamma_o(y, u)]
        if len(go) != f.r:
            raise DimensionError(f"gamma_o(y, u) of {f.label} must return r = {f.r} values; "
                                 f"found {len(go)}")
        be = [float(v) for v in f.beta(y, u)]
        if len(be) != f.p:
            raise DimensionError(f"beta(y, u) of {f.label} must return p = {f.p} values; found "
                                 f"{len(be)}")
        if f.n_obar:
            gb = [0.0] * f.n_obar if f.gamma_obar is None else [float(v) for v in f.gamma_obar(y, u)]
            if len(gb) != f.n_obar:
                raise DimensionError(f"gamma_obar(y, u) of {f.label} must return n - r = "
                                     f"{f.n_obar} values; found {len(gb)}")
        else:
            gb = []
        return go, be, gb

    def rhs(self, s: Any, y: float, go: Sequence[float], be: Sequence[float],
            gb: Sequence[float], c: float = 1.0) -> list[float]:
        """Right-hand side of eq. 27 for the flat state ``s = (z_o, z_obar, theta_hat)`` with
        the signals held (public for continuous-time checks); ``c = 0`` drops the output
        injection (a dropout)."""
        f = self.form
        r, n = f.r, f.n
        zo, th = s[:r], s[n:]
        e = c * (y - zo[r - 1])
        bt = 0.0
        for bi, ti in zip(be, th):
            bt += bi * ti
        out = [go[0] + self._bl[0] * bt + self._Kl[0] * e]
        for i in range(1, r):
            out.append(zo[i - 1] + go[i] + self._bl[i] * bt + self._Kl[i] * e)
        if f.n_obar:
            fo = f.f_obar(y, s[r:n])  # type: ignore[misc]
            A = self._Al
            for j in range(f.n_obar):
                v = float(fo[j]) + gb[j]
                if A is not None:
                    v += sum(a * z for a, z in zip(A[j], zo))
                out.append(v)
        for row in self._Gl:
            g = 0.0
            for gl, bl in zip(row, be):
                g += gl * bl
            out.append(g * e)
        return out

    # ------------------------------------------------------------------ interface
    def check_period(self, dt: float) -> None:
        """Refuse a sample period for which the integration of the observer's linear modes
        (the roots of :math:`(s + \\lambda)(b_r s^{r-1} + \\dots + b_1)`, eq. 26) is unstable."""
        b = self.form.b
        lam_ = np.concatenate(([-self.lam], np.roots(b[::-1]) if b.size > 1 else []))
        check_rk_period("the Jo-Son observer", lam_, dt, self.method, self.substeps)

    def update(self, y: Any, u: Any, dt: float) -> Array:
        """Consume ``y(t_k)``, ``u(t_k)``; integrate eq. 27 over ``dt``; return
        ``x_hat(t_k + dt)``."""
        f = self.form
        yv = y
        try:
            yi = float(yv[self.output])
            aux = [float(yv[i]) for i in f.aux_outputs]
        except (IndexError, TypeError):
            raise DimensionError(f"y must be a vector with channels {self.output} (output) and "
                                 f"{list(f.aux_outputs)} (aux_outputs); found {y!r}") from None
        u = np.asarray(u, dtype=float).reshape(-1)
        aux_lost = any(a != a for a in aux)
        if aux_lost:  # hold the lost auxiliary channels (0 before any), keep the known control
            last = self._aux_last if self._aux_last is not None else [0.0] * len(aux)
            aux = [b if a != a else a for a, b in zip(aux, last)]
        if aux:
            self._aux_last = aux
            u = np.concatenate((u, aux))
        s = self._s
        if yi != yi or aux_lost:  # dropout: predict without correction
            self.dropouts_ += 1
            c = 0.0
            yi = s[f.r - 1]
        elif yi in (math.inf, -math.inf):
            raise DivergenceError(f"measurement y[{self.output}] is {yi}")
        else:
            c = 1.0
        go, be, gb = self.signals(yi, u)
        if self._gram is not None:
            self._gram.add(np.array(be), dt)
        s = rk_step(self.rhs, s, dt / self.substeps, self.method, self.substeps, yi, go, be, gb, c)
        if not all(map(math.isfinite, s)):
            raise DivergenceError(f"the Jo-Son observer left the finite numbers: state "
                                  f"(z_hat, theta_hat) = {s}")
        self._s = s
        self._refresh_physical()
        return self._xp.copy()

    # ------------------------------------------------------------------ estimates
    def _refresh_physical(self) -> None:
        f = self.form
        if f.to_physical is None:
            self._xp = np.array(self._s[:f.n])
            return
        x = f.to_physical(self._s[:f.n])
        if all(map(math.isfinite, x)):
            self._xp = np.asarray(x, dtype=float).reshape(-1)
        else:
            self.inverse_failures_ += 1

    @property
    def state_names(self) -> tuple[str, ...]:
        return self.form.state_names

    @property
    def z_hat(self) -> Array:
        """Estimate in the form's coordinates :math:`(\\hat z_o, \\hat z_{\\bar o})`."""
        return np.array(self._s[:self.form.n])

    @property
    def x_hat(self) -> Array:
        """:math:`T^{-1}(\\hat z)` (eq. 27), or ``z_hat`` without a physical map."""
        return self._xp.copy()

    @property
    def theta_hat_(self) -> Array:
        return np.array(self._s[self.form.n:])

    @property
    def excitation_(self) -> float:
        return self._gram.min_eig if self._gram is not None else math.nan

    def diagnostics(self) -> dict[str, float]:
        f = self.form
        out = {f"theta_{nm}": v for nm, v in zip(f.theta_names, self._s[f.n:])}
        if self._gram is not None:
            out["excitation"] = self._gram.min_eig
        out["dropouts"] = float(self.dropouts_)
        return out

    def params(self) -> dict[str, Any]:
        f = self.form
        return {"form": f.label, "r": f.r, "n": f.n, "b": f.b.tolist(), "lambda": self.lam,
                "K": self.K_.tolist(), "gamma": self.gamma.tolist(),
                "theta_names": list(f.theta_names), "output": self.output,
                "method": self.method, "substeps": self.substeps,
                "excitation_window": self.excitation_window}
