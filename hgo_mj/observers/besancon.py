"""The adaptive high-gain observer of Besançon, Zhang and Hammouri (paper 001).

**Form (eq. 9 / 21).** The observer is designed on a system

.. math::

    \\dot x = A x + \\varphi(x, u) + \\psi(x, u)\\, \\theta, \\qquad y = C x

with :math:`A = \\mathrm{diag}(A_1, \\dots, A_p)` a block diagonal of integrator chains of
orders :math:`n_1, \\dots, n_p` (eq. 2), :math:`C` picking the first state of each chain,
:math:`\\varphi` triangular in each chain except its last entry (eq. 3, [A1']) and
:math:`\\psi` (:math:`n \\times q`) zero except the last row of each chain (eq. 7). A system
provides it through the protocol of :class:`AffineForm` (``A``, ``C``, ``phi0(x, u)``,
``regressor(x, u)``, optionally ``theta``); :func:`affine_form` also derives it for the
MuJoCo pendulum, elastic joint and two-link elastic arm (the parameters to estimate chosen by
name).

**Observer (eq. 12, single output; eq. 24, two outputs).** With
:math:`\\Lambda(\\lambda)^{-1} = \\mathrm{diag}(1, \\lambda, \\dots, \\lambda^{n_c - 1})` per
chain, :math:`K = \\mathrm{diag}(K_1, \\dots, K_p)` making each :math:`A_c - K_c C_c` Hurwitz,
:math:`\\tilde y = y - C\\hat x` and :math:`\\tilde x, \\tilde\\theta` the saturations of
:math:`\\hat x, \\hat\\theta` by the balls of radius :math:`X, \\Theta`,

.. math::

    \\dot{\\hat\\Gamma} &= \\lambda (A - K C) \\hat\\Gamma
        + \\Lambda(\\lambda)\\, \\psi(\\tilde x, u)\\, I_\\lambda \\\\
    \\dot{\\hat x} &= A \\hat x + \\varphi(\\tilde x, u) + \\psi(\\tilde x, u) \\tilde\\theta
        + \\Lambda(\\lambda)^{-1} [\\lambda K + \\hat\\Gamma S \\hat\\Gamma^T C^T] \\tilde y \\\\
    \\dot{\\hat\\theta} &= I_\\lambda S \\hat\\Gamma^T C^T \\tilde y

with :math:`I_\\lambda = \\mathrm{diag}(\\lambda^{e_j})`. For one output :math:`e_j = n` and
:math:`\\Lambda \\psi I_\\lambda = \\lambda \\psi` (the last row of :math:`\\Lambda` is
:math:`\\lambda^{-(n-1)}`): this is eq. 12 exactly when :math:`S = I`. For two chains of equal
order it is eq. 24. :math:`S` (``gain``, symmetric positive definite, default :math:`I`) is the
adaptation gain of Zhang (2002) that eq. 12 fixes to the identity; the error equations 20 hold
for any :math:`S` (the proof of Lemma 3.3 goes through with :math:`V = \\varepsilon^T P_0
\\varepsilon + \\varepsilon_\\theta^T S^{-1}\\varepsilon_\\theta`-type weights). It is needed
where the regressor is large (the elastic joint: :math:`|\\psi| \\sim 10^4`) and the
parameter dynamics :math:`\\dot\\varepsilon_\\theta = -S \\hat\\Gamma^T C^T C \\hat\\Gamma
\\varepsilon_\\theta` would otherwise be far stiffer than the sample period allows.

**Corrections of the paper** (the checks are in ``tests/test_besancon.py`` and
``docs/results/adaptive.md``):

1. Proof of Lemma 3.1: the error equation prints :math:`+\\hat\\Gamma^T C_0^T C_0
   \\varepsilon_0`, which is a :math:`q`-vector in an :math:`n`-vector equation; from eq. 12
   the term is :math:`-\\hat\\Gamma \\hat\\Gamma^T C_0^T C_0 \\varepsilon_0` (that sign and
   factor are what make :math:`\\dot\\varepsilon` of eq. 20 free of :math:`\\varepsilon_0`).
2. Eq. 24 evaluates :math:`\\varphi, \\psi` at :math:`\\hat x` and defines :math:`\\tilde x`
   without using it; as in eq. 12 they are evaluated at :math:`\\tilde x` here.
3. Eq. 24's :math:`I_\\lambda = \\mathrm{diag}(\\lambda^{n_1} I, \\lambda^{n_2} I)` is
   :math:`q \\times q` only if the parameters split into those of block 1 and those of block 2,
   and the cancellation behind eq. 20 needs :math:`\\Lambda \\psi I_\\lambda` (not
   :math:`\\lambda \\psi`) in the :math:`\\hat\\Gamma` filter; the two agree when
   :math:`n_1 = n_2` (both examples of the paper, and the two-link arm). With unequal orders
   give ``theta_exponents`` (or a form's ``param_block``).
4. Lemma 3.3 defines :math:`\\varepsilon_\\theta` with :math:`\\hat\\theta` in its statement and
   :math:`\\tilde\\theta` in its proof; its last inequality prints :math:`-d\\|\\varepsilon_\\theta\\|`
   for :math:`-d\\|\\varepsilon_\\theta\\|^2`; Lemma 3.1's comment says "tuning
   :math:`\\theta`" for tuning :math:`\\lambda`.

**Excitation (eq. 11).** The diagnostic ``excitation`` is the smallest eigenvalue of
:math:`\\int_{t-T}^{t} \\hat\\Gamma^T C^T C \\hat\\Gamma\\, d\\tau` over the last window
:math:`T` (``excitation_window``): with it bounded away from zero the parameter error obeys
:math:`\\dot\\varepsilon_\\theta = -S \\hat\\Gamma^T C^T C \\hat\\Gamma \\varepsilon_\\theta`
(eq. 20) and decays at a rate of about ``gain * excitation / T``, *independently of*
:math:`\\lambda` (as :math:`\\lambda \\to \\infty`, :math:`C\\hat\\Gamma \\to C(-(A-KC)^{-1})\\psi
= \\psi_{last}/k_{n}`, Remark 3.1). A larger :math:`\\lambda` makes the states converge
faster, not the parameters: that rate is set by the excitation and ``gain``.

References
----------
.. [001] G. Besançon, Q. Zhang, H. Hammouri, "High-gain observer based state and parameter
   estimation in nonlinear systems", IFAC NOLCOS 2004 (``shared/papers/001_fa1af3b6b9a222a1.txt``):
   eq. 2-3 (structure), 4 (high-gain observer), 7 (regressor), 9 (single-output form),
   10-11 (excitation [A3]), 12 (observer), 20 (error equations), 21-24 (two outputs).
.. [Z02] Q. Zhang, "Adaptive observer for MIMO linear time-varying systems", IEEE TAC 47(3),
   2002 (the adaptation gain).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .._validate import finite_scalar, one_of, positive_int, symmetric_matrix, vector
from ..design import binomial_coefficients, check_hurwitz
from ..exceptions import DesignError, DimensionError, DivergenceError
from ..systems.base import System
from ._adaptive import measured_channels
from .base import Array, Observer
from .bastin_gevers import Rebuildable, check_rk_period, initial_estimate

__all__ = ["AffineForm", "BesanconObserver", "affine_form", "elastic_joint_form",
           "besancon_example_form", "elastic_joint_2link_form", "pendulum_form"]

METHODS = ("rk4", "rk2", "euler")
_ONE = [1.0]
_ZERO = [0.0]
HOLDS = ("measurement", "innovation")
PROTOCOL = ("A", "C", "phi0", "regressor")


# ======================================================================================
# helpers
# ======================================================================================


def _chain_structure(A: Any, C: Any) -> tuple[int, ...]:
    """Chain orders ``(n_1, ..., n_p)`` of ``A = diag(A_c)``, ``C = diag(C_c)`` (eq. 2, 21)."""
    A = np.asarray(A, dtype=float)
    C = np.asarray(C, dtype=float)
    if A.ndim != 2 or A.shape[0] != A.shape[1]:
        raise DimensionError(f"A must be a square matrix; found shape {A.shape}")
    n = A.shape[0]
    if C.ndim != 2 or C.shape[1] != n:
        raise DimensionError(f"C must have shape (p, {n}); found shape {C.shape}")
    firsts = []
    for r in range(C.shape[0]):
        nz = np.flatnonzero(C[r])
        if nz.size != 1 or C[r, nz[0]] != 1.0:
            raise DesignError(f"row {r} of C must pick one state (a single 1, eq. 2); found "
                              f"{C[r].tolist()}")
        firsts.append(int(nz[0]))
    if firsts != sorted(firsts) or not firsts or firsts[0] != 0:
        raise DesignError(f"C must pick the first state of consecutive chains, in order; "
                          f"found the states {firsts}")
    bounds = firsts + [n]
    orders = tuple(b - a for a, b in zip(bounds[:-1], bounds[1:]))
    if any(o < 1 for o in orders):
        raise DesignError(f"C picks the same state twice; found {firsts}")
    expect = np.zeros((n, n))
    for f, o in zip(firsts, orders):
        for i in range(o - 1):
            expect[f + i, f + i + 1] = 1.0
    if not np.array_equal(A, expect):
        raise DesignError(f"A must be a block diagonal of integrator chains of orders {list(orders)} "
                          f"(eq. 2 / 21); found {A.tolist()}")
    return orders


# ======================================================================================
# the form eq. 9 / 21
# ======================================================================================

Terms = Callable[[Sequence[float], Array], tuple[Sequence[float], Sequence[Sequence[float]]]]


class AffineForm(Rebuildable):
    """A system in the parameter-affine form of paper 001, eq. 9 (one output) or 21.

    .. math::

        \\dot z = A z + \\varphi(z, u) + \\psi(z, u)\\, \\theta, \\qquad y = C z

    **Protocol.** An object (e.g. a :class:`~hgo_mj.systems.base.System`) with ``A``
    (:math:`n \\times n`), ``C`` (:math:`p \\times n`), ``phi0(x, u) -> (n,)`` and
    ``regressor(x, u) -> (n, q)``, and optionally ``theta`` (the true values, for reports)
    and ``param_names``, is in this form; :meth:`from_protocol` wraps it
    (:class:`~hgo_mj.systems.papers.BesanconExample1` and ``BesanconExample2`` are).
    :func:`affine_form` builds one for the MuJoCo systems.

    Parameters
    ----------
    orders : sequence of int
        Chain orders :math:`n_1, \\dots, n_p` (one per measured output).
    theta_names : sequence of str
        Names of the :math:`q` parameters of the form.
    terms : callable ``terms(z, u) -> (phi, psi_last)``
        Fast path: ``phi`` the :math:`n` entries of :math:`\\varphi` and ``psi_last`` the
        :math:`p` last rows of :math:`\\psi` (each of length :math:`q`), as Python floats;
        ``z`` a sequence of floats, ``u`` the input array. Not validated per call.
    label : str
        One line for messages and metadata.
    theta : array_like, optional
        True parameter values (reports only).
    state_names : sequence of str, optional
        Names of ``z`` (default ``z1..zn``).
    outputs : sequence of int, optional
        Measured channel of each chain (default ``0..p-1``).
    to_physical : callable ``(z, theta_hat, u) -> x``, optional
        Map to the physical state (may raise :class:`DesignError` where undefined).
    from_physical : callable ``(x, theta, u) -> z``, optional
        Its inverse (for an initial estimate given physically).
    physical_state_names : sequence of str, optional
        Names of the physical state (with ``to_physical``).
    physical_params : callable ``theta_hat -> dict``, optional
        Physical parameters recovered from the form's parameters (e.g. ``K``, ``MgL``).
    true_physical : dict, optional
        Their true values (reports only).
    param_block : sequence of int, optional
        Chain whose last row carries each parameter (for ``theta_exponents`` with unequal
        orders, see correction 3 of the module docstring).
    """

    def __init__(self, *, orders: Sequence[int], theta_names: Sequence[str], terms: Terms,
                 label: str, theta: Any = None, state_names: Sequence[str] | None = None,
                 outputs: Sequence[int] | None = None,
                 to_physical: Callable[[Array, Array, Array], Array] | None = None,
                 from_physical: Callable[[Array, Array, Array], Array] | None = None,
                 physical_state_names: Sequence[str] | None = None,
                 physical_params: Callable[[Array], dict[str, float]] | None = None,
                 true_physical: dict[str, float] | None = None,
                 param_block: Sequence[int] | None = None) -> None:
        self.orders = tuple(int(o) for o in orders)
        if not self.orders or any(o < 1 for o in self.orders):
            raise DesignError(f"orders must be positive integers; found {list(orders)}")
        self.n = sum(self.orders)
        self.p = len(self.orders)
        self.theta_names = tuple(str(s) for s in theta_names)
        self.q = len(self.theta_names)
        if self.q < 1:
            raise DesignError("the form needs at least one parameter (theta_names is empty)")
        self.terms = terms
        self.label = label
        self.theta = None if theta is None else vector("theta", theta, self.q)
        self.firsts = tuple(int(v) for v in np.cumsum((0,) + self.orders[:-1]))
        self.lasts = tuple(f + o - 1 for f, o in zip(self.firsts, self.orders))
        self.state_names = (tuple(state_names) if state_names is not None
                            else tuple(f"z{i + 1}" for i in range(self.n)))
        if len(self.state_names) != self.n:
            raise DimensionError(f"state_names must have n = {self.n} entries; found "
                                 f"{len(self.state_names)}")
        self.outputs = tuple(range(self.p)) if outputs is None else tuple(int(o) for o in outputs)
        if len(self.outputs) != self.p:
            raise DimensionError(f"outputs must name one channel per chain ({self.p}); found "
                                 f"{len(self.outputs)}")
        self.to_physical = to_physical
        self.from_physical = from_physical
        self.physical_state_names = (tuple(physical_state_names) if physical_state_names
                                     else self.state_names)
        self.physical_params = physical_params
        self.true_physical = dict(true_physical or {})
        self.param_block = None if param_block is None else tuple(int(b) for b in param_block)

    # ------------------------------------------------------------------ matrices
    @property
    def A(self) -> Array:
        """Block diagonal of integrator chains (eq. 2, 21)."""
        A = np.zeros((self.n, self.n))
        for f, o in zip(self.firsts, self.orders):
            for i in range(o - 1):
                A[f + i, f + i + 1] = 1.0
        return A

    @property
    def C(self) -> Array:
        """Picks the first state of each chain, shape ``(p, n)``."""
        C = np.zeros((self.p, self.n))
        for c, f in enumerate(self.firsts):
            C[c, f] = 1.0
        return C

    def phi0(self, z: Any, u: Any) -> Array:
        """:math:`\\varphi(z, u)`, shape ``(n,)``."""
        ph, _ = self.terms(vector("z", z, self.n).tolist(), np.atleast_1d(np.asarray(u, float)))
        return np.array(ph, dtype=float)

    def regressor(self, z: Any, u: Any) -> Array:
        """:math:`\\psi(z, u)`, shape ``(n, q)``, zero except the last row of each chain."""
        _, ps = self.terms(vector("z", z, self.n).tolist(), np.atleast_1d(np.asarray(u, float)))
        out = np.zeros((self.n, self.q))
        for c, last in enumerate(self.lasts):
            out[last] = ps[c]
        return out

    def rhs(self, z: Any, u: Any, theta: Any) -> Array:
        """:math:`A z + \\varphi(z, u) + \\psi(z, u) \\theta` (for checks)."""
        z = vector("z", z, self.n)
        th = vector("theta", theta, self.q)
        return self.A @ z + self.phi0(z, u) + self.regressor(z, u) @ th

    def __repr__(self) -> str:
        return f"AffineForm({self.label!r}, orders={list(self.orders)}, theta={list(self.theta_names)})"

    # ------------------------------------------------------------------ builders
    @classmethod
    def from_protocol(cls, obj: Any, n_inputs: int | None = None) -> AffineForm:
        """Wrap an object with ``A``, ``C``, ``phi0``, ``regressor`` (see the class docstring).

        The regressor's shape and the structure of eq. 7 (zero except the last row of each
        chain) are checked at a probe point ``z = 0.1 (1, 2, ..., n)``, ``u = 0.3``.

        Raises
        ------
        DesignError
            A protocol member is missing (all missing ones are named), ``A``/``C`` are not
            chains, or ``psi`` is not zero outside the last rows.
        DimensionError
            ``phi0`` or ``regressor`` return the wrong shape.
        """
        missing = [m for m in PROTOCOL if not hasattr(obj, m)]
        if missing:
            raise DesignError(f"{type(obj).__name__} is not in the form of paper 001 eq. 9/21: "
                              f"missing {missing} (needs A, C, phi0(x, u), regressor(x, u)); "
                              f"MuJoCo systems get theirs from affine_form(system, unknown=...)")
        orders = _chain_structure(obj.A, obj.C)
        n = sum(orders)
        if n_inputs is None:
            n_inputs = len(getattr(obj, "input_names", ())) or 1
        z0 = 0.1 * np.arange(1, n + 1)
        u0 = np.full(n_inputs, 0.3)
        ps = np.asarray(obj.regressor(z0, u0), dtype=float)
        if ps.ndim != 2 or ps.shape[0] != n:
            raise DimensionError(f"regressor(x, u) of {type(obj).__name__} must have shape "
                                 f"(n, q) = ({n}, q); found shape {ps.shape}")
        q = ps.shape[1]
        ph = np.asarray(obj.phi0(z0, u0), dtype=float)
        if ph.shape != (n,):
            raise DimensionError(f"phi0(x, u) of {type(obj).__name__} must have shape ({n},); "
                                 f"found shape {ph.shape}")
        firsts = np.cumsum((0,) + orders[:-1])
        lasts = [int(f + o - 1) for f, o in zip(firsts, orders)]
        inner = np.setdiff1d(np.arange(n), lasts)
        if inner.size and np.any(ps[inner] != 0.0):
            rows = [int(r) for r in inner if np.any(ps[r] != 0.0)]
            raise DesignError(f"regressor(x, u) of {type(obj).__name__} must be zero except the "
                              f"last row of each chain (eq. 7, rows {lasts}); found non-zero rows "
                              f"{rows}")
        names = tuple(getattr(obj, "param_names", ()))
        if len(names) != q:
            names = tuple(f"theta{j + 1}" for j in range(q))
        theta = getattr(obj, "theta", None)
        phi0, reg = obj.phi0, obj.regressor

        def terms(z: Sequence[float], u: Array) -> tuple[list[float], list[list[float]]]:
            za = np.array(z, dtype=float)
            psi = np.asarray(reg(za, u), dtype=float)
            if psi.shape != (n, q):
                raise DimensionError(f"regressor(x, u) must have shape ({n}, {q}); found "
                                     f"shape {psi.shape}")
            return (np.asarray(phi0(za, u), dtype=float).tolist(), [psi[r].tolist() for r in lasts])

        return cls(orders=orders, theta_names=names, terms=terms,
                   label=f"{type(obj).__name__} (paper 001 form)", theta=theta,
                   state_names=getattr(obj, "state_names", None) or None
                   )._made_by(cls.from_protocol, obj, n_inputs)


def pendulum_form(system: Any, unknown: Sequence[str] | None = None) -> AffineForm:
    """The pendulum :math:`J\\ddot y = -m g l_c \\sin y - d \\dot y + b u` in the form eq. 9.

    With :math:`a = m g l_c / J` (``g_over_l``), :math:`\\beta = b/J` (``b_over_J``) and
    :math:`\\delta = d/J` (``d_over_J``), :math:`z = (y, \\dot y)`:

    .. math::

        \\dot z_1 = z_2, \\qquad
        \\dot z_2 = \\underbrace{-\\delta z_2}_{\\varphi_2}
                  + \\begin{pmatrix} -\\sin z_1 & u \\end{pmatrix}
                    \\begin{pmatrix} a \\\\ \\beta \\end{pmatrix}

    for the default ``unknown = ("g_over_l", "b_over_J")`` (damping known, read from the
    system); a known parameter moves into :math:`\\varphi`, ``d_over_J`` may be estimated too
    (regressor :math:`-z_2`). The names match the Bastin-Gevers form of the same plant.

    References
    ----------
    Paper 001, eq. 9 (form), eq. 7 (regressor structure).
    """
    p = system.params
    J = p["inertia"]
    true = {"g_over_l": p["mass"] * p["g"] * p["com_distance"] / J, "b_over_J": p["gear"] / J,
            "d_over_J": p["damping"] / J}
    allowed = ("g_over_l", "b_over_J", "d_over_J")
    unknown = ("g_over_l", "b_over_J") if unknown is None else tuple(unknown)
    bad = [u for u in unknown if u not in allowed]
    if bad or not unknown or len(set(unknown)) != len(unknown):
        raise DesignError(f"pendulum parameters to estimate must be distinct names from "
                          f"{list(allowed)}; found {list(unknown)}")
    order = tuple(unknown)
    # generated: no per-call dictionaries (terms runs four times per RK4 step)
    reg = {"g_over_l": "-s", "b_over_J": "uu", "d_over_J": "-z2"}
    known = {"g_over_l": f"- {true['g_over_l']!r}*s", "b_over_J": f"+ {true['b_over_J']!r}*uu",
             "d_over_J": f"- {true['d_over_J']!r}*z2"}
    phi = " ".join(known[k] for k in allowed if k not in order) or "+ 0.0"
    src = ("def terms(z, u):\n    z2 = z[1]\n    s = sin(z[0])\n    uu = float(u[0])\n"
           f"    return (0.0, 0.0 {phi}), (({', '.join(reg[k] for k in order)},),)\n")
    scope: dict[str, Any] = {"sin": math.sin}
    exec(compile(src, "<pendulum_form>", "exec"), scope)  # noqa: S102 - numbers only
    terms = scope["terms"]

    return AffineForm(orders=(2,), theta_names=order, terms=terms,
                      label=f"pendulum y'' = -d/J y' - a sin y + b/J u, unknown {list(order)}",
                      theta=[true[k] for k in order], state_names=system.state_names,
                      true_physical={k: true[k] for k in order}
                      )._made_by(pendulum_form, system, unknown)


def elastic_joint_form(system: Any, unknown: Sequence[str] | None = None) -> AffineForm:
    """The elastic joint seen from the link angle, in the form eq. 9, affine in its parameters.

    In the normal form :math:`z = (y, \\dot y, \\ddot y, y^{(3)})` of
    :class:`~hgo_mj.systems.elastic_joint.ElasticJoint` (link inertia :math:`I`, motor inertia
    :math:`J`, damping :math:`d_l, d_m` and gear :math:`b` known, :math:`\\delta = d_l / I`),
    differentiating the link equation twice and eliminating the motor angle gives (checked
    symbolically and in ``tests/test_besancon.py``)

    .. math::

        y^{(4)} = \\underbrace{-\\delta z_4 - \\tfrac{d_m}{J}(z_4 + \\delta z_3)}_{\\varphi_4}
            + \\psi_1\\, MgL + \\psi_2\\, K + \\psi_3\\, K\\, MgL,

    .. math::

        \\psi_1 &= \\left(\\sin z_1\\, z_2^2 - \\cos z_1\\, z_3
                   - \\tfrac{d_m}{J} \\cos z_1\\, z_2\\right) / I, \\\\
        \\psi_2 &= -\\frac{z_3}{I} - \\frac{z_3 + \\delta z_2}{J} - \\frac{d_m z_2}{I J}
                   + \\frac{b\\, u}{I J}, \\qquad
        \\psi_3 = -\\frac{\\sin z_1}{I J}.

    :math:`y^{(4)}` is *not* affine in :math:`(K, MgL)` (the product :math:`K\\,MgL` appears),
    but it is affine in :math:`\\theta = (MgL, K, K\\,MgL)` (``unknown`` both, the default):
    the observer estimates three numbers and the physical ones are mapped back as
    :math:`\\hat K = \\hat\\theta_2` and :math:`\\widehat{MgL} = \\hat\\theta_3 / \\hat\\theta_2`
    (the regressor :math:`\\psi_3` is the best excited: it does not need :math:`z_3`, the
    noisiest estimate). With one of them known, :math:`\\theta` is that one parameter and the
    product term joins its regressor (:math:`\\psi_1 + K \\psi_3` or
    :math:`\\psi_2 + MgL\\, \\psi_3`). The physical state (motor angle and velocity) comes from
    the system's inverse map with the current estimates.

    References
    ----------
    Paper 001, eq. 9; Nicosia and Tornambè (1989) for the problem.
    """
    from ..systems.elastic_joint import ElasticJoint

    p = dict(system.params)
    I, J = p["link_inertia"], p["motor_inertia"]
    dl, dm, b = p["link_damping"], p["motor_damping"], p["gear"]
    mgl_true = p["mass"] * p["g"] * p["com_distance"]
    k_true = p["stiffness"]
    allowed = ("MgL", "stiffness")
    unknown = allowed if unknown is None else tuple(unknown)
    if (not unknown or any(u not in allowed for u in unknown)
            or len(set(unknown)) != len(unknown)):
        raise DesignError(f"elastic-joint parameters to estimate must be distinct names from "
                          f"{list(allowed)}; found {list(unknown)}")
    delta = dl / I
    rm = dm / J
    IJ = I * J
    both = len(unknown) == 2
    if both:
        names: tuple[str, ...] = ("MgL_direct", "stiffness", "stiffness_MgL")
        theta = [mgl_true, k_true, k_true * mgl_true]
    else:
        names = (unknown[0],)
        theta = [mgl_true if unknown[0] == "MgL" else k_true]
    est_mgl = "MgL" in unknown

    def terms(z: Sequence[float], u: Array) -> tuple[tuple[float, ...], tuple[tuple[float, ...]]]:
        z1, z2, z3, z4 = z[0], z[1], z[2], z[3]
        s, c = math.sin(z1), math.cos(z1)
        ps1 = (s * z2 * z2 - c * z3 - rm * c * z2) / I
        ps2 = -z3 / I - (z3 + delta * z2) / J - dm * z2 / IJ + b * float(u[0]) / IJ
        ps3 = -s / IJ
        ph = -delta * z4 - rm * (z4 + delta * z3)
        if both:
            return (0.0, 0.0, 0.0, ph), ((ps1, ps2, ps3),)
        if est_mgl:
            return (0.0, 0.0, 0.0, ph + k_true * ps2), ((ps1 + k_true * ps3,),)
        return (0.0, 0.0, 0.0, ph + mgl_true * ps1), ((ps2 + mgl_true * ps3,),)

    g, L = p["g"], p["com_distance"]

    def physical(th: Array) -> dict[str, float]:
        if both:
            k = float(th[1])
            return {"stiffness": k, "MgL": float(th[2]) / k if k != 0.0 else math.nan}
        if est_mgl:
            return {"MgL": float(th[0])}
        return {"stiffness": float(th[0])}

    def params_for(th: Array) -> dict[str, float]:
        q = dict(p)
        phys = physical(th)
        if "stiffness" in phys:
            if not phys["stiffness"] > 0:
                raise DesignError(f"stiffness estimate {phys['stiffness']:.4g} is not > 0")
            q["stiffness"] = phys["stiffness"]
        if "MgL" in phys:
            if not math.isfinite(phys["MgL"]):
                raise DesignError("MgL estimate is not finite")
            q["mass"] = phys["MgL"] / (g * L)
        return q

    def to_physical(z: Array, th: Array, u: Array) -> Array:
        return ElasticJoint._from_normal(z, params_for(th))

    def from_physical(x: Array, th: Array, u: Array) -> Array:
        return ElasticJoint._to_normal(x, params_for(th))

    return AffineForm(orders=(4,), theta_names=names, terms=terms,
                      label=f"elastic joint, link angle, unknown {list(unknown)}", theta=theta,
                      state_names=("link_angle", "link_velocity", "link_acceleration",
                                   "link_jerk"),
                      to_physical=to_physical, from_physical=from_physical,
                      physical_state_names=system.state_names, physical_params=physical,
                      true_physical={"stiffness": k_true, "MgL": mgl_true}
                      )._made_by(elastic_joint_form, system, unknown)


def elastic_joint_2link_form(system: Any) -> AffineForm:
    """The two-link elastic arm seen from both link angles: the two-output form eq. 21.

    With :math:`z[c] = (q_c, \\dot q_c, \\ddot q_c, q_c^{(3)})` for :math:`c = 1, 2` (orders
    4 and 4) and the link equation written as :math:`L := M(q)\\ddot q + c(q, \\dot q) + g(q)
    + D \\dot q = -K (q - \\theta)`, the motor equation
    :math:`J \\ddot\\theta + D_m \\dot\\theta - K(q - \\theta) = B u` with
    :math:`\\theta = q + K^{-1} L` gives, for diagonal :math:`K, J, D_m`,

    .. math::

        \\ddot L = K w - J^{-1} D_m \\dot L, \\qquad
        w = J^{-1}(B u - D_m \\dot q - L) - \\ddot q,

    and :math:`\\ddot L = M q^{(4)} + 2 \\dot M q^{(3)} + \\ddot M \\ddot q + \\ddot c + \\ddot g
    + D q^{(3)}`, so

    .. math::

        q^{(4)} = \\underbrace{M^{-1}\\left[-J^{-1} D_m \\dot L - 2 \\dot M q^{(3)}
                  - \\ddot M \\ddot q - \\ddot c - \\ddot g - D q^{(3)}\\right]}_{\\varphi}
                  + \\underbrace{M^{-1} \\mathrm{diag}(w)}_{\\psi}
                    \\begin{pmatrix} K_1 \\\\ K_2 \\end{pmatrix}.

    Both stiffnesses enter both chains' last rows (through :math:`M^{-1}`), the orders are
    equal, so eq. 24 applies with :math:`I_\\lambda = \\lambda^4 I`. The structure [A1'] holds:
    each chain's last entry depends on the other chain. The motor-2 rotor body's axial inertia
    :math:`J_r = 10^{-12}` kg m^2 of the MJCF is neglected (Spong's assumption); the time
    derivatives of :math:`M, c, g` along the trajectory are analytic. The estimate ``x_hat``
    is ``z_hat`` (link angles and their derivatives, chain after chain); the motor angles are
    in :meth:`AffineForm.to_physical`.

    References
    ----------
    Paper 001, eq. 21 ([A1']), eq. 24; Spong (1987) for the model.
    """
    p = dict(system.params)
    l1, s2, i2, m2 = p["link1_length"], p["link2_moment"], p["link2_inertia"], p["link2_mass"]
    alpha = p["link1_inertia"] + i2 + m2 * l1 * l1
    beta = l1 * s2
    g0 = p["g"]
    gs1 = g0 * (p["link1_moment"] + m2 * l1)
    gs2 = g0 * s2
    d1, d2 = p["link1_damping"], p["link2_damping"]
    J1, J2 = p["motor1_inertia"], p["motor2_inertia"]
    dm1, dm2 = p["motor1_damping"], p["motor2_damping"]
    b1, b2 = p["gear1"], p["gear2"]

    def parts(z: Sequence[float], u: Array) -> tuple[float, ...]:
        q1, w1, a1, j1, q2, w2, a2, j2 = z
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
        wv1 = (b1 * float(u[0]) - dm1 * w1 - L1) / J1 - a1
        wv2 = (b2 * float(u[1]) - dm2 * w2 - L2) / J2 - a2
        det = m11 * m22 - m12 * m12
        i11, i12, i22 = m22 / det, -m12 / det, m11 / det
        return i11, i12, i22, r1, r2, wv1, wv2, L1, L2, Ld1, Ld2

    def terms(z: Sequence[float], u: Array) -> tuple[tuple[float, ...], tuple[tuple[float, ...], ...]]:
        i11, i12, i22, r1, r2, wv1, wv2 = parts(z, u)[:7]
        ph = (0.0, 0.0, 0.0, i11 * r1 + i12 * r2, 0.0, 0.0, 0.0, i12 * r1 + i22 * r2)
        return ph, ((i11 * wv1, i12 * wv2), (i12 * wv1, i22 * wv2))

    def to_physical(z: Array, th: Array, u: Array) -> Array:
        k1, k2 = float(th[0]), float(th[1])
        if not (k1 > 0 and k2 > 0):
            raise DesignError(f"stiffness estimates {k1:.4g}, {k2:.4g} must be > 0")
        uu = np.zeros(2) if u is None or np.size(u) < 2 else u
        L1, L2, Ld1, Ld2 = parts(list(map(float, z)), uu)[7:]
        q1, w1, _, _, q2, w2, _, _ = (float(v) for v in z)
        return np.array([q1, q2, q1 + L1 / k1, q2 + L2 / k2, w1, w2, w1 + Ld1 / k1, w2 + Ld2 / k2])

    names = ("link1_angle", "link1_velocity", "link1_acceleration", "link1_jerk",
             "link2_angle", "link2_velocity", "link2_acceleration", "link2_jerk")
    return AffineForm(orders=(4, 4), theta_names=("stiffness1", "stiffness2"), terms=terms,
                      label="two-link elastic arm, both link angles, unknown K1, K2",
                      theta=[p["stiffness1"], p["stiffness2"]], state_names=names,
                      to_physical=to_physical, physical_state_names=system.state_names,
                      true_physical={"stiffness1": p["stiffness1"], "stiffness2": p["stiffness2"]}
                      )._made_by(elastic_joint_2link_form, system)


def besancon_example_form(system: Any) -> AffineForm:
    """Paper 001's examples (:class:`~hgo_mj.systems.papers.BesanconExample1`, ``...2``) with
    a fast float ``terms``; equal to :meth:`AffineForm.from_protocol` of the system (their
    ``phi0``/``regressor``, checked in ``tests/test_besancon.py``), which validates its
    arguments at every call and costs about 20 times more.

    Example 1 (eq. 9): :math:`\\varphi = (u, -x_1 - 2 \\sin x_2)`,
    :math:`\\psi_{2\\cdot} = (\\arctan x_2, \\cos(x_1 x_2))`. Example 2 (eq. 21, chains
    :math:`(y, \\dot y)` and :math:`(u, \\dot u)`, input :math:`v = \\ddot u`):
    :math:`\\varphi = (0, \\sin(x_1 x_2), 0, v)`, :math:`\\psi_{2\\cdot} = (\\cos(x_1 x_2),
    x_4 x_3^2)`, :math:`\\psi_{4\\cdot} = 0`.
    """
    from ..systems.papers import BesanconExample1, BesanconExample2

    if isinstance(system, BesanconExample1):
        def terms1(z: Sequence[float], u: Array) -> tuple[tuple[float, ...], tuple[tuple[float, ...]]]:
            x1, x2 = z[0], z[1]
            return (float(u[0]), -x1 - 2.0 * math.sin(x2)), ((math.atan(x2), math.cos(x1 * x2)),)

        return AffineForm(orders=(2,), theta_names=system.param_names, terms=terms1,
                          label="paper 001 example 1 (eq. 9)", theta=system.theta,
                          state_names=system.state_names)._made_by(besancon_example_form, system)
    if isinstance(system, BesanconExample2):
        def terms2(z: Sequence[float], u: Array) -> tuple[tuple[float, ...], tuple[tuple[float, ...], ...]]:
            x1, x2, x3, x4 = z[0], z[1], z[2], z[3]
            w = x1 * x2
            return ((0.0, math.sin(w), 0.0, float(u[0])),
                    ((math.cos(w), x4 * x3 * x3), (0.0, 0.0)))

        return AffineForm(orders=(2, 2), theta_names=system.param_names, terms=terms2,
                          label="paper 001 example 2 (eq. 21)", theta=system.theta,
                          state_names=system.state_names)._made_by(besancon_example_form, system)
    raise DesignError(f"besancon_example_form takes BesanconExample1 or BesanconExample2; found "
                      f"{type(system).__name__}")


def affine_form(system: Any, unknown: Sequence[str] | None = None) -> AffineForm:
    """The form eq. 9 / 21 of a system: derived for the MuJoCo pendulum
    (:func:`pendulum_form`), elastic joint (:func:`elastic_joint_form`) and two-link arm
    (:func:`elastic_joint_2link_form`), or wrapped from the protocol (:meth:`AffineForm.from_protocol`).

    Raises
    ------
    DesignError
        The system has neither a derived form nor the protocol (the missing members are named),
        or ``unknown`` is given for a form that fixes its parameters.
    """
    from ..systems.elastic_joint import ElasticJoint
    from ..systems.elastic_joint_2link import ElasticJoint2Link
    from ..systems.papers import BesanconExample1, BesanconExample2
    from ..systems.pendulum import Pendulum

    if isinstance(system, AffineForm):
        return system
    if type(system) in (BesanconExample1, BesanconExample2) and unknown is None:
        return besancon_example_form(system)
    if isinstance(system, Pendulum):
        return pendulum_form(system, unknown)
    if isinstance(system, ElasticJoint):
        return elastic_joint_form(system, unknown)
    if isinstance(system, ElasticJoint2Link):
        if unknown is not None and tuple(unknown) != ("stiffness1", "stiffness2"):
            raise DesignError(f"the two-link form estimates ['stiffness1', 'stiffness2']; found "
                              f"unknown={list(unknown)}")
        return elastic_joint_2link_form(system)
    if unknown is not None:
        raise DesignError(f"unknown= chooses parameters of a derived form; {type(system).__name__} "
                          f"gives its own (regressor columns)")
    return AffineForm.from_protocol(system)


# ======================================================================================
# code generation of the observer's right-hand side (plain floats)
# ======================================================================================


def _lit(v: float) -> str:
    return repr(float(v))


def _compile(form: AffineForm, lam: float, K: Sequence[Array], S: Array, exps: Array,
             X: float, Theta: float, hold: str = "measurement") -> dict[str, Callable[..., Any]]:
    """Generate ``rhs``, ``rk4`` and ``euler`` for the observer state
    ``s = (x_hat (n), theta_hat (q), Gamma (n*q, row-major))`` in straight-line float code.

    The stages of RK4 are inlined (no call but the form's ``terms`` per stage): one update
    of a 2-state, 2-parameter observer costs a few microseconds this way, against tens for
    the same arithmetic in small numpy arrays (``scripts/bench_kalman.py``). ``y`` holds the
    measurements (``hold="measurement"``) or the innovations at the sample instant
    (``hold="innovation"``), ``m`` the masks (0 for a dropped channel).
    """
    n, q = form.n, form.q
    eye = bool(np.allclose(S, np.eye(q)))
    N = n + q + n * q

    def names(sfx: str) -> list[str]:
        return ([f"x{i}{sfx}" for i in range(n)] + [f"t{j}{sfx}" for j in range(q)]
                + [f"G{i}_{j}{sfx}" for i in range(n) for j in range(q)])

    def stage(sfx: str, ind: str) -> list[str]:
        """Lines computing the derivatives ``d<k><sfx>`` of the state named with suffix ``sfx``."""
        xs = [f"x{i}{sfx}" for i in range(n)]
        ts = [f"t{j}{sfx}" for j in range(q)]
        gs = [[f"G{i}_{j}{sfx}" for j in range(q)] for i in range(n)]
        L = []
        if math.isfinite(X):
            L.append(f"nx = {' + '.join(f'{v}*{v}' for v in xs)}")
            L.append(f"if nx > {_lit(X * X)}:")
            L.append(f"    c = {_lit(X)} / sqrt(nx)")
            L.append(f"    xt = ({', '.join(f'{v}*c' for v in xs)},)")
            L.append("else:")
            L.append(f"    xt = ({', '.join(xs)},)")
        else:
            L.append(f"xt = ({', '.join(xs)},)")
        if math.isfinite(Theta):
            L.append(f"nt = {' + '.join(f'{v}*{v}' for v in ts)}")
            L.append(f"ct = {_lit(Theta)} / sqrt(nt) if nt > {_lit(Theta * Theta)} else 1.0")
            tt = [f"{v}*ct" for v in ts]
        else:
            tt = ts
        L.append("ph, ps = terms(xt, u)")
        for c, f in enumerate(form.firsts):
            if hold == "measurement":
                L.append(f"e{c} = (y{c} - {xs[f]}) * m{c}")
            else:
                L.append(f"e{c} = y{c}")
        for j in range(q):
            L.append(f"v{j} = {' + '.join(f'{gs[f][j]}*e{c}' for c, f in enumerate(form.firsts))}")
        for j in range(q):
            if eye:
                L.append(f"w{j} = v{j}")
            else:
                tj = [f"{_lit(S[j, k])}*v{k}" for k in range(q) if S[j, k] != 0.0]
                L.append(f"w{j} = {' + '.join(tj) if tj else '0.0'}")
        d = [f"d{k}{ind}" for k in range(N)]
        for c, (f, o) in enumerate(zip(form.firsts, form.orders)):
            Kc = K[c]
            L.append(f"pc = ps[{c}]")
            for r in range(o):
                i = f + r
                parts = []
                if r < o - 1:
                    parts.append(xs[i + 1])
                parts.append(f"ph[{i}]")
                if r == o - 1:
                    parts.append("(" + " + ".join(f"pc[{j}]*{tt[j]}" for j in range(q)) + ")")
                corr = f"{_lit(lam * Kc[r])}*e{c} + " + " + ".join(f"{gs[i][j]}*w{j}" for j in range(q))
                parts.append(f"{_lit(lam ** r)}*({corr})" if r else f"{corr}")
                L.append(f"{d[i]} = {' + '.join(parts)}")
            for r in range(o):
                i = f + r
                for j in range(q):
                    expr = f"{_lit(-lam * Kc[r])}*{gs[f][j]}"
                    if r < o - 1:
                        expr = f"{_lit(lam)}*{gs[i + 1][j]} + " + expr
                    else:
                        expr += f" + {_lit(lam ** (exps[j] - (o - 1)))}*pc[{j}]"
                    L.append(f"{d[n + q + i * q + j]} = {expr}")
        for j in range(q):
            L.append(f"{d[n + j]} = {_lit(lam ** exps[j])}*w{j}")
        return L

    p = form.p
    head = [f"    y{c} = y[{c}]" for c in range(p)]
    if hold == "measurement":
        head += [f"    m{c} = m[{c}]" for c in range(p)]
    s0 = names("")
    src = ["def rhs(s, y, m, u):", *head, f"    ({', '.join(s0)},) = s"]
    src += ["    " + ln for ln in stage("", "")]
    src.append(f"    return ({', '.join(f'd{k}' for k in range(N))},)")
    src += ["", "def euler(s, y, m, u, h):", *head, f"    ({', '.join(s0)},) = s"]
    src += ["    " + ln for ln in stage("", "")]
    src.append(f"    return ({', '.join(f'{v} + h*d{k}' for k, v in enumerate(s0))},)")
    src += ["", "def rk2(s, y, m, u, h):", *head, f"    ({', '.join(s0)},) = s"]
    src += ["    " + ln for ln in stage("", "a")]
    for k, (v, w) in enumerate(zip(s0, names("b"))):
        src.append(f"    {w} = {v} + h*d{k}a")
    src += ["    " + ln for ln in stage("b", "b")]
    src.append("    h2 = 0.5*h")
    final2 = ", ".join(f"{v} + h2*(d{k}a + d{k}b)" for k, v in enumerate(s0))
    src.append(f"    return ({final2},)")
    src += ["", "def rk4(s, y, m, u, h):", *head, "    hh = 0.5*h", f"    ({', '.join(s0)},) = s"]
    src += ["    " + ln for ln in stage("", "a")]
    for sfx, prev, coef in (("b", "a", "hh"), ("c", "b", "hh"), ("e", "c", "h")):
        nm = names(sfx)
        for k, (v, w) in enumerate(zip(s0, nm)):  # plain assignments: no tuple per stage
            src.append(f"    {w} = {v} + {coef}*d{k}{prev}")
        src += ["    " + ln for ln in stage(sfx, sfx)]
    src.append("    h6 = h/6.0")
    final = ", ".join(f"{v} + h6*(d{k}a + 2.0*(d{k}b + d{k}c) + d{k}e)" for k, v in enumerate(s0))
    src.append(f"    return ({final},)")
    scope: dict[str, Any] = {"sqrt": math.sqrt, "terms": form.terms}
    exec(compile("\n".join(src) + "\n", "<besancon>", "exec"), scope)  # noqa: S102 - numbers only
    return {"rhs": scope["rhs"], "rk4": scope["rk4"], "rk2": scope["rk2"], "euler": scope["euler"]}


def _gram_adder(form: AffineForm) -> Callable[[tuple[float, ...], float, list[float]], None]:
    """Generated ``add(s, dt, acc)``: ``acc += dt * Gamma^T C^T C Gamma`` (upper triangle,
    row-major ``q x q``) for the state ``s`` of :func:`_compile`."""
    n, q = form.n, form.q
    base = n + q
    src = ["def add(s, dt, acc):"]
    for j in range(q):
        for k in range(j, q):
            terms = " + ".join(f"s[{base + f * q + j}]*s[{base + f * q + k}]" for f in form.firsts)
            src.append(f"    acc[{j * q + k}] += dt*({terms})")
    scope: dict[str, Any] = {}
    exec(compile("\n".join(src) + "\n", "<gram>", "exec"), scope)  # noqa: S102 - numbers only
    return scope["add"]


# ======================================================================================
# the observer
# ======================================================================================


class BesanconObserver(Observer):
    """Adaptive high-gain observer of Besançon, Zhang and Hammouri (paper 001, eq. 12 / 24).

    See the module docstring for the equations (and the corrections of the paper). Between
    samples the measurement and the input are held; ``update`` integrates the observer state
    :math:`(\\hat x, \\hat\\theta, \\hat\\Gamma)` over one sample by Heun's method, RK4 or
    Euler in ``substeps`` steps, in generated straight-line float code.

    Parameters
    ----------
    system : System or AffineForm, optional
        The system (its form is :func:`affine_form`) or the form itself.
    form : AffineForm, optional
        The form, when ``system`` is only used for names (or not given).
    unknown : sequence of str, optional
        Parameters to estimate, for the derived forms (pendulum: ``g_over_l``, ``b_over_J``,
        ``d_over_J``; elastic joint: ``MgL``, ``stiffness``).
    lam : float
        The high gain :math:`\\lambda > 0`.
    K0 : array_like or sequence of array_like, optional
        :math:`K_c = (k_1, \\dots, k_{n_c})` per chain with :math:`A_c - K_c C_c` Hurwitz
        (the polynomial :math:`s^{n_c} + k_1 s^{n_c - 1} + \\dots + k_{n_c}`); one array for
        every chain or one per chain; default binomial :math:`(s+1)^{n_c}` (``(2, 1)`` for
        :math:`n = 2`, the choice of the paper's first example).
    gain : float, array_like (q,) or (q, q)
        Adaptation gain :math:`S`, symmetric positive definite; ``1`` is the paper's observer.
    X, Theta : float or None
        Radii of the saturations :math:`\\tilde x, \\tilde\\theta` (Theorem 3.1); ``None``
        disables one. Must be > 0, and the initial estimates must lie inside (Theorem 3.1).
    theta_hat0 : array_like (q,), optional
        Initial parameter estimate (default zero).
    x_hat0, z_hat0 : array_like, optional
        Initial state estimate in physical coordinates (needs the form's ``from_physical``)
        or in the form's coordinates (default zero).
    Gamma0 : array_like (n, q), optional
        Initial :math:`\\hat\\Gamma` (default zero).
    theta_exponents : sequence of int, optional
        Exponents :math:`e_j` of :math:`I_\\lambda`; default the common chain order (required
        when orders differ and the form has no ``param_block``).
    method : {"rk2", "rk4", "euler"}
        Integration of one sample: Heun's second-order method (default: at the usual 1 kHz
        the estimates agree with RK4's to 0.1 % and it costs 2/3 as much, see
        ``BENCHMARKS.md``), classical RK4 (the paper reproduction), or forward Euler.
    substeps : int
        Integration steps per sample.
    hold : {"measurement", "innovation"}
        What is held between samples. ``"measurement"`` (the contract of
        :mod:`hgo_mj.observers.base`): :math:`y(t_k)`, so the innovation
        :math:`y(t_k) - C\\hat x(t)` lags the true one by about :math:`\\dot y\\, dt / 2`, a
        bias of order :math:`\\lambda\\, dt` on the estimates. ``"innovation"``: the innovation
        :math:`y(t_k) - C\\hat x(t_k)` at the sample instant is held while the model term
        propagates :math:`\\hat x`; its error is of the order of the *estimation error's*
        change over a sample, so a converged observer has no sampling bias (the
        continuous-discrete discretization; it converges to eq. 12 as :math:`dt \\to 0`).
    adapt_after : float
        Time [s] before which :math:`\\hat\\theta` is held (the observer runs with
        :math:`S = 0`: no parameter update and no :math:`\\hat\\Gamma S \\hat\\Gamma^T`
        injection; :math:`\\hat\\Gamma` runs). Not in the paper: its proof first waits for
        :math:`\\|\\hat x - x\\| \\le \\mu` (Lemma 3.1, time :math:`t_1`) before the
        excitation argument (Lemmas 3.2-3.3), and in practice the peaking of the initial
        transient otherwise kicks :math:`\\hat\\theta` far off. Default 0 (the paper's observer).
    excitation_window : float or None
        Window :math:`T` of the excitation diagnostic (eq. 11); ``None`` switches it off. The
        integral is accumulated in 20 sub-windows; the smallest eigenvalue is refreshed each
        time one completes (every :math:`T/20`).

    Attributes
    ----------
    theta_hat_ : ndarray (q,)
        Parameter estimate.
    Gamma_ : ndarray (n, q)
        The filter :math:`\\hat\\Gamma`.
    excitation_ : float
        Smallest eigenvalue of the windowed :math:`\\int \\hat\\Gamma^T C^T C \\hat\\Gamma`
        (NaN until a first window is complete).
    physical_params_ : dict
        Physical parameters recovered from :math:`\\hat\\theta` (elastic joint: ``stiffness``,
        ``MgL``).
    dropouts_ : int
        Samples with at least one NaN channel (that channel is not corrected over the sample).
    inverse_failures_ : int
        Samples where the map to physical coordinates was undefined (the last value is held).

    References
    ----------
    Paper 001, eq. 12 (Theorem 3.1), eq. 24 (Theorem 3.2), eq. 11 ([A3]).
    """

    name = "besancon"
    summary = "Besançon-Zhang-Hammouri adaptive high-gain observer (state + parameters), PE figure"
    reference = "paper 001 (Besançon, Zhang, Hammouri 2004), eq. 9-12, 21-24"

    def __init__(self, system: Any = None, *, form: AffineForm | None = None,
                 unknown: Sequence[str] | None = None, lam: float, K0: Any = None,
                 gain: Any = 1.0, X: float | None = None, Theta: float | None = None,
                 theta_hat0: Any = None, x_hat0: Any = None, z_hat0: Any = None,
                 Gamma0: Any = None, theta_exponents: Any = None, outputs: Any = None,
                 method: str = "rk2", substeps: int = 1, hold: str = "measurement",
                 adapt_after: float = 0.0, excitation_window: float | None = 10.0) -> None:
        if form is None:
            if system is None:
                raise DesignError("BesanconObserver needs a system in the form of paper 001 "
                                  "(eq. 9/21) or form=AffineForm(...)")
            form = affine_form(system, unknown)
        elif not isinstance(form, AffineForm):
            raise DesignError(f"form must be an AffineForm; found {type(form).__name__}")
        elif unknown is not None:
            raise DesignError("unknown chooses a derived form; with form= given leave it out")
        if system is not None and not isinstance(system, (System, AffineForm)):
            raise DesignError(f"system must be a System or an AffineForm; found "
                              f"{type(system).__name__}")
        self.form = form
        self.system = system if isinstance(system, System) else None
        self.n = form.n
        self.q = form.q
        self.lam = finite_scalar("lam", lam, positive=True)
        self.K = self._gains(K0)
        self.gain = symmetric_matrix("gain", gain, form.q)
        self.X = math.inf if X is None else finite_scalar("X", X, positive=True)
        self.Theta = math.inf if Theta is None else finite_scalar("Theta", Theta, positive=True)
        self.exps = self._exponents(theta_exponents)
        self.method = one_of("method", method, METHODS)
        self.substeps = positive_int("substeps", substeps)
        self.hold = one_of("hold", hold, HOLDS)
        outs = form.outputs if outputs is None else (
            (outputs,) if np.ndim(outputs) == 0 else tuple(outputs))
        if len(outs) != form.p or any(isinstance(o, bool) or int(o) != o or o < 0 for o in outs):
            raise DesignError(f"outputs must be {form.p} non-negative channel indices (one per "
                              f"chain); found {outs!r}")
        self.outputs = tuple(int(o) for o in outs)
        self.output = self.outputs[0]
        if excitation_window is not None:
            excitation_window = finite_scalar("excitation_window", excitation_window,
                                              positive=True)
        self.excitation_window = excitation_window
        self.adapt_after = finite_scalar("adapt_after", adapt_after, nonnegative=True)
        self._generate()
        self._single = form.p == 1
        self._innov = hold == "innovation"
        self._excite_on = excitation_window is not None
        self._sub = (excitation_window / 20.0 * (1.0 - 1e-9)) if excitation_window else math.inf
        self._physical_map = form.to_physical is not None
        self.diagnostic_names = tuple(f"theta_{nm}" for nm in form.theta_names) + tuple(
            f"theta_{nm}" for nm in form.true_physical if nm not in form.theta_names) + (
            "excitation",)
        self._u = np.zeros(0)
        self._init = (x_hat0, z_hat0, theta_hat0, Gamma0)
        self.reset(x_hat0, z_hat0=z_hat0, theta_hat0=theta_hat0, Gamma0=Gamma0)

    # ------------------------------------------------------------------ setup
    #: the generated functions (made with ``exec``: pickle cannot store them)
    _GENERATED = ("_rhs", "_step", "_step_frozen", "_gram_add")

    def _generate(self) -> None:
        """Generate the observer's code from the design (at construction and on unpickling)."""
        form, hold = self.form, self.hold
        fns = _compile(form, self.lam, self.K, self.gain, self.exps, self.X, self.Theta, hold)
        self._rhs = fns["rhs"]
        self._step = fns[self.method]
        self._step_frozen = None
        if self.adapt_after > 0:  # S = 0: no parameter update, no Gamma S Gamma^T injection
            self._step_frozen = _compile(form, self.lam, self.K, np.zeros((form.q, form.q)),
                                         self.exps, self.X, self.Theta, hold)[self.method]
        self._gram_add = _gram_adder(form)

    def __getstate__(self) -> dict[str, Any]:
        """Pickle without the generated code (regenerated by :meth:`__setstate__`, the same
        code from the same design: the copy continues identically). The form pickles as the
        call that built it (see :class:`AffineForm`)."""
        return {k: v for k, v in self.__dict__.items() if k not in self._GENERATED}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._generate()

    def _gains(self, K0: Any) -> tuple[Array, ...]:
        f = self.form
        if K0 is None:
            per: list[Any] = [None] * f.p
        elif np.ndim(K0) == 1 and all(np.ndim(v) == 0 for v in K0):
            per = [K0] * f.p
        else:
            per = list(K0)
            if len(per) != f.p:
                raise DimensionError(f"K0 must be one array for every chain or one per chain "
                                     f"({f.p}); found {len(per)} entries")
        out = []
        for c, (o, k) in enumerate(zip(f.orders, per)):
            name = "K0" if f.p == 1 else f"K0[{c}]"
            arr = binomial_coefficients(o) if k is None else check_hurwitz(k, name)
            if arr.size != o:
                raise DimensionError(f"{name} must have n_{c} = {o} entries (chain order); found "
                                     f"{arr.size}")
            out.append(arr)
        return tuple(out)

    def _exponents(self, theta_exponents: Any) -> Array:
        f = self.form
        if theta_exponents is not None:
            e = vector("theta_exponents", theta_exponents, f.q)
            if np.any(e < 0):
                raise DesignError(f"theta_exponents must be >= 0; found {e.tolist()}")
            return e
        if len(set(f.orders)) == 1:
            return np.full(f.q, float(f.orders[0]))
        if f.param_block is not None:
            return np.array([float(f.orders[b]) for b in f.param_block])
        raise DesignError(f"chains of unequal orders {list(f.orders)}: I_lambda of eq. 24 needs the "
                          f"block of each parameter; give theta_exponents=(e_1, ..., e_q) or a "
                          f"form with param_block")

    def check_period(self, dt: float) -> None:
        """Refuse a sample period for which the integration of the linear modes
        :math:`\\lambda\\,\\mathrm{eig}(A_c - K_c C_c)` is unstable (the parameter modes depend
        on the data and are not checked here)."""
        lam_modes = np.concatenate([self.lam * np.roots(np.concatenate(([1.0], k)))
                                    for k in self.K])
        check_rk_period(f"the Besançon observer (lambda={self.lam:g}, modes lambda*eig(A - K C))",
                        lam_modes, dt, self.method, self.substeps)

    # ------------------------------------------------------------------ reset
    def reset(self, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None,
              theta_hat0: Any = None, Gamma0: Any = None) -> None:
        """Restart (default: the constructor's initial values)."""
        f = self.form
        if x_hat0 is None and z_hat0 is None and theta_hat0 is None and Gamma0 is None:
            x_hat0, z_hat0, theta_hat0, Gamma0 = self._init
        u = np.zeros(len(self.system.input_names) if self.system is not None else 1) \
            if u0 is None else np.atleast_1d(np.asarray(u0, dtype=float))

        def physical(x_hat0: Any, th: Array) -> Array:
            if f.from_physical is None:
                return vector("x_hat0", x_hat0, f.n)
            xp = vector("x_hat0", x_hat0, len(f.physical_state_names))
            return vector("from_physical(x_hat0)", f.from_physical(xp, th, u), f.n)

        z, th = initial_estimate(f.n, f.q, x_hat0, z_hat0, theta_hat0, physical)
        if Gamma0 is None:
            G = np.zeros((f.n, f.q))
        else:
            G = np.array(Gamma0, dtype=float)
            if G.shape != (f.n, f.q):
                raise DimensionError(f"Gamma0 must have shape (n, q) = ({f.n}, {f.q}); found "
                                     f"shape {G.shape}")
            if not np.all(np.isfinite(G)):
                raise DesignError("Gamma0 must be finite")
        if float(np.linalg.norm(z)) > self.X:
            raise DesignError(f"the initial estimate must lie in the ball |x_hat| <= X = {self.X:g} "
                              f"(Theorem 3.1); found |x_hat0| = {np.linalg.norm(z):.4g}")
        if float(np.linalg.norm(th)) > self.Theta:
            raise DesignError(f"the initial parameter estimate must lie in |theta_hat| <= Theta = "
                              f"{self.Theta:g} (Theorem 3.1); found {np.linalg.norm(th):.4g}")
        self._s = tuple(float(v) for v in np.concatenate((z, th, G.reshape(-1))))
        self._u = u
        self._restart_counters()
        self._t = 0.0
        self._xp: Array | None = None
        self._phys_last = {k: math.nan for k in f.true_physical}
        self._refresh_physical()
        if self._xp is not None and not np.all(np.isfinite(self._xp)):
            raise DesignError(f"the initial estimate (z = {z.tolist()}, theta = {th.tolist()}) lies "
                              f"where the map of {f.label} to physical coordinates is undefined; "
                              f"give theta_hat0 inside its domain (e.g. a positive stiffness)")
        # excitation: 20 sub-windows of the windowed Gram integral (eq. 11)
        self._acc = [0.0] * (f.q * f.q)
        self._acc_t = 0.0
        self._blocks: list[Array] = []
        self.excitation_ = math.nan

    # ------------------------------------------------------------------ update
    def update(self, y: Any, u: Any, dt: float) -> Array:
        """Consume ``y(t_k)``, ``u(t_k)``; integrate eq. 12/24 over ``dt``; return
        ``x_hat(t_k + dt)``."""
        if type(u) is not np.ndarray:
            u = np.atleast_1d(np.asarray(u, dtype=float))
        self._u = u
        s = self._s
        if self._single:
            try:
                v = float(y[self.output])
            except (IndexError, TypeError):
                raise self._bad_measurement(y, self.output) from None
            if v - v == 0.0:
                ys, ms = [v - s[0] if self._innov else v], _ONE
            elif v != v:
                self.dropouts_ += 1
                ys, ms = [0.0], _ZERO
            else:
                raise DivergenceError(f"measurement y[{self.output}] is {v}")
        else:
            ys, ms = self._measure(y)
            if self._innov:
                ys = [(v - s[f]) * w for v, w, f in zip(ys, ms, self.form.firsts)]
        if self._excite_on:
            self._gram_add(s, dt, self._acc)
            self._acc_t += dt
            if self._acc_t >= self._sub:
                self._close_window()
        step = self._step
        if self._step_frozen is not None and self._t < self.adapt_after - 1e-12:
            step = self._step_frozen
        self._t += dt
        try:
            if self.substeps == 1:
                s = step(s, ys, ms, u, dt)
            else:
                h = dt / self.substeps
                for _ in range(self.substeps):
                    s = step(s, ys, ms, u, h)
        except (ValueError, OverflowError, ZeroDivisionError) as exc:  # math.sin(inf), ...
            raise DivergenceError(f"the Besançon observer state left the finite numbers ({exc}): "
                                  f"{list(self._s[:self.n])} (lambda={self.lam:g}, step {dt:g}); "
                                  f"bound it with X= and Theta=, lower the gain or raise substeps"
                                  ) from None
        if not math.isfinite(sum(s)):
            raise DivergenceError(f"the Besançon observer state left the finite numbers: "
                                  f"{list(s[:self.n])} (lambda={self.lam:g}, step {dt:g}); "
                                  f"lower gain, or raise substeps")
        self._s = s
        if self._physical_map:
            self._refresh_physical()
            return self._xp.copy()  # type: ignore[union-attr]
        return np.array(s[:self.n])

    def _measure(self, y: Any) -> tuple[list[float], list[float]]:
        """Values (0 where lost) and masks (1 present, 0 lost) of the measured channels."""
        vals = measured_channels(self, y, self.outputs)
        return [v if v == v else 0.0 for v in vals], [1.0 if v == v else 0.0 for v in vals]

    def _close_window(self) -> None:
        """A sub-window of the excitation integral is complete: store it, refresh the
        smallest eigenvalue over the last 20."""
        q = self.q
        M = np.array(self._acc).reshape(q, q)
        M = np.triu(M) + np.triu(M, 1).T
        self._blocks.append(M)
        if len(self._blocks) > 20:
            self._blocks.pop(0)
        self._acc = [0.0] * (q * q)
        self._acc_t = 0.0
        if len(self._blocks) == 20:
            W = np.sum(self._blocks, axis=0)
            self.excitation_ = float(np.linalg.eigvalsh(W)[0]) if np.all(np.isfinite(W)) \
                else math.nan

    # ------------------------------------------------------------------ estimates
    def _refresh_physical(self) -> None:
        f = self.form
        th = np.array(self._s[self.n:self.n + self.q])
        if f.physical_params is not None:
            try:
                self._phys_last.update(f.physical_params(th))
            except (DesignError, ZeroDivisionError):
                pass
        if f.to_physical is None:
            return
        z = np.array(self._s[:self.n])
        try:
            x = np.asarray(f.to_physical(z, th, self._u), dtype=float)
            if not np.all(np.isfinite(x)):
                raise DesignError("non-finite physical state")
            self._xp = x
        except (DesignError, ZeroDivisionError):
            self.inverse_failures_ += 1
            if self._xp is None:
                self._xp = np.full(len(f.physical_state_names), np.nan)

    @property
    def state_names(self) -> tuple[str, ...]:
        f = self.form
        return f.physical_state_names if f.to_physical is not None else f.state_names

    @property
    def z_hat(self) -> Array:
        """State estimate in the form's coordinates."""
        return np.array(self._s[:self.n])

    @property
    def x_hat(self) -> Array:
        """Estimate in physical coordinates (the form's ``to_physical`` with the current
        parameter estimates; held where undefined), else ``z_hat``."""
        if self.form.to_physical is not None:
            return self._xp.copy()  # type: ignore[union-attr]
        return self.z_hat

    @property
    def theta_hat_(self) -> Array:
        return np.array(self._s[self.n:self.n + self.q])

    @property
    def Gamma_(self) -> Array:
        return np.array(self._s[self.n + self.q:]).reshape(self.n, self.q)

    @property
    def physical_params_(self) -> dict[str, float]:
        return dict(self._phys_last)

    def excitation_matrix(self) -> Array:
        """The windowed :math:`\\int \\hat\\Gamma^T C^T C \\hat\\Gamma d\\tau` over the last
        complete sub-windows (eq. 11)."""
        if not self._blocks:
            return np.full((self.q, self.q), np.nan)
        return np.sum(self._blocks, axis=0)

    def diagnostics(self) -> dict[str, float]:
        s = self._s
        n = self.n
        out = {f"theta_{nm}": s[n + j] for j, nm in enumerate(self.form.theta_names)}
        for k, v in self._phys_last.items():
            out.setdefault(f"theta_{k}", v)
        out["excitation"] = self.excitation_
        out["dropouts"] = float(self.dropouts_)
        return out

    def params(self) -> dict[str, Any]:
        return {"form": self.form.label, "orders": list(self.form.orders),
                "theta_names": list(self.form.theta_names), "lam": self.lam,
                "K0": [k.tolist() for k in self.K], "gain": self.gain.tolist(),
                "X": None if math.isinf(self.X) else self.X,
                "Theta": None if math.isinf(self.Theta) else self.Theta,
                "theta_exponents": self.exps.tolist(), "outputs": list(self.outputs),
                "method": self.method, "substeps": self.substeps, "hold": self.hold,
                "adapt_after": self.adapt_after,
                "excitation_window": self.excitation_window}
