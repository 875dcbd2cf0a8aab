"""The adaptive high-gain observer of Besançon, Zhang and Hammouri (paper 001 [001]_, after [Z02]_).

**Form (eq. 9 / 21).** The observer is designed on a system

.. math::

    \\dot x = A x + \\varphi(x, u) + \\psi(x, u)\\, \\theta, \\qquad y = C x

with :math:`A = \\mathrm{diag}(A_1, \\dots, A_p)` a block diagonal of integrator chains of
orders :math:`n_1, \\dots, n_p` (eq. 2), :math:`C` picking the first state of each chain,
:math:`\\varphi` triangular in each chain except its last entry (eq. 3, [A1']) and
:math:`\\psi` (:math:`n \\times q`) zero except the last row of each chain (eq. 7): an
:class:`~hgo_mj.systems.affine_form.AffineForm`. A system declares it (``forms = ("affine",
...)``, asked for by ``system.form("affine", unknown=...)``: the pendulum, the elastic joint,
the two-link elastic arm and the paper's examples), or has the members ``A``, ``C``,
``phi0(x, u)``, ``regressor(x, u)`` (wrapped by :meth:`AffineForm.from_protocol`).

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

**Kernels.** The observer state of B members is data: ``(B, N)`` rows
:math:`(\\hat x, \\hat\\theta, \\hat\\Gamma)` (:math:`N = n + q + nq`, :math:`\\hat\\Gamma`
row-major). The right-hand side above is written once, per row, in :func:`_derivative` (numba);
one integration stage of all members is one call of :func:`_stage`, between which the form's
``terms`` evaluates :math:`\\varphi, \\psi` of all members' saturated rows at once. The
state (:meth:`BesanconObserver.init`) holds those rows ``S`` with each member's own clock ``t``
(``adapt_after``) and excitation ring (eq. 11), so a member restarts alone; the tunable
parameters :math:`\\lambda` (``lam``), :math:`K` (``K0``) and :math:`S` (``gain``) may differ per
member (:meth:`~hgo_mj.observers.base.Observer.parameters`).

**Corrections of the paper** (the checks are in ``tests/observers/test_besancon.py`` and
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
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from .._validate import finite_scalar, one_of, positive_int, symmetric_matrix, vector
from ..design import binomial_coefficients, check_hurwitz
from ..exceptions import DesignError, DimensionError, DivergenceError
from ..systems.affine_form import AffineForm
from ..systems.base import System
from .base import Array, Observer, Params, State, _batch_size, batch_rows, check_outputs, register
from .bastin_gevers import check_rk_period

__all__ = ["AffineForm", "BesanconObserver", "affine_form"]

METHODS = ("rk4", "rk2", "euler")
HOLDS = ("measurement", "innovation")
#: the stages ``(a, b)`` of each method: the next stage's state is ``s0 + a h k``, the step
#: ``s0 + h sum_i b_i k_i`` (Euler; Heun; classical RK4)
TABLEAUS: dict[str, tuple[tuple[float, float], ...]] = {
    "euler": ((1.0, 1.0),),
    "rk2": ((1.0, 0.5), (1.0, 0.5)),
    "rk4": ((0.5, 1.0 / 6.0), (0.5, 1.0 / 3.0), (1.0, 1.0 / 3.0), (1.0, 1.0 / 6.0)),
}
#: sub-windows of the excitation integral (eq. 11)
SUBWINDOWS = 20
#: designs (per parameter values) an observer keeps
DESIGN_CACHE = 64


def affine_form(system: Any, unknown: Sequence[str] | None = None) -> AffineForm:
    """The form eq. 9 / 21 of ``system``: the one it declares (``system.form("affine",
    unknown=...)``), or its protocol members wrapped (:meth:`AffineForm.from_protocol`); an
    :class:`AffineForm` is returned as it is.

    Parameters
    ----------
    system : System or AffineForm or object
        A system declaring the ``"affine"`` form, an object with the protocol members of
        :meth:`AffineForm.from_protocol`, or an AffineForm.
    unknown : sequence of str, optional
        The parameters to estimate, for a system whose form lets the caller choose them
        (default: the form's own choice).

    Returns
    -------
    AffineForm

    Raises
    ------
    DesignError
        The system declares no affine form and lacks the protocol (the missing members are
        named), or ``unknown`` is given for a form that fixes its parameters.

    Examples
    --------
    >>> from hgo_mj.systems import BesanconExample1
    >>> form = affine_form(BesanconExample1())
    >>> form
    AffineForm('paper 001 example 1 (eq. 9)', orders=[2], theta=['theta1', 'theta2'])
    >>> affine_form(form) is form
    True
    """
    if isinstance(system, AffineForm):
        if unknown is not None:
            raise DesignError("unknown chooses the parameters of a system's form; an AffineForm "
                              "has fixed its own")
        return system
    if isinstance(system, System) and "affine" in system.forms:
        return system.form("affine", unknown=unknown)  # type: ignore[no-any-return]
    if unknown is not None:
        raise DesignError(f"unknown= chooses parameters of a derived form; {type(system).__name__} "
                          f"gives its own (regressor columns)")
    return AffineForm.from_protocol(system)


# ======================================================================================
# kernels: eq. 12 / 24 on rows (numba)
# ======================================================================================


#: ``flags`` of :func:`_stage`
FIRST, LAST, INNOVATION = 1, 2, 4


@njit(cache=True, inline="always")
def _saturate(S: Array, m: int, X: float, Theta: float, Xt: Array,
              Tt: Array) -> None:
    """:math:`\\tilde x, \\tilde\\theta` of Theorem 3.1 for row ``m``: ``x_hat`` and
    ``theta_hat`` of ``S[m]`` scaled back onto the balls of radius ``X`` and ``Theta`` where
    they leave them (written into ``Xt[m]``, ``Tt[m]``)."""
    n, q = Xt.shape[1], Tt.shape[1]
    nx = 0.0
    for i in range(n):
        nx += S[m, i] * S[m, i]
    c = X / math.sqrt(nx) if nx > X * X else 1.0
    for i in range(n):
        Xt[m, i] = S[m, i] * c
    nt = 0.0
    for j in range(q):
        nt += S[m, n + j] * S[m, n + j]
    ct = Theta / math.sqrt(nt) if nt > Theta * Theta else 1.0
    for j in range(q):
        Tt[m, j] = S[m, n + j] * ct


@njit(cache=True, inline="always")
def _unpack(P: Array, n: int, q: int, p: int) -> tuple[float, float, float, Array, Array, Array,
                                                       Array]:
    """The design vector ``P`` (:meth:`BesanconObserver._design`) as ``(lambda, X, Theta,
    lamK, lampow, lam_e, psicoef)``: per state ``i`` in chain ``c`` at depth ``r``,
    ``lamK[i]`` :math:`= \\lambda K_c[r]` and ``lampow[i]`` :math:`= \\lambda^r`
    (:math:`\\Lambda^{-1}`); ``lam_e[j]`` :math:`= \\lambda^{e_j}` (:math:`I_\\lambda`);
    ``psicoef[c, j]`` :math:`= \\lambda^{e_j - (n_c - 1)}` (the last row of
    :math:`\\Lambda \\psi I_\\lambda`)."""
    o = 3
    lamK = P[o:o + n]
    lampow = P[o + n:o + 2 * n]
    lam_e = P[o + 2 * n:o + 2 * n + q]
    psicoef = P[o + 2 * n + q:o + 2 * n + q + p * q].reshape((p, q))
    return P[0], P[1], P[2], lamK, lampow, lam_e, psicoef


@njit(cache=True, inline="always")
def _derivative(S: Array, Xt: Array, Tt: Array, phi: Array, psi: Array, m: int, e: Array,
                chains: Any, lam: float, lamK: Array, lampow: Array, lam_e: Array,
                psicoef: Array, Sg: Array, v: Array, w: Array,
                out: Array) -> None:
    """Eq. 12 / 24 for row ``m`` of ``S``, the state ``(x_hat, theta_hat, Gamma_hat)``
    (writes ``out`` ``(N,)``).

    ``Xt[m], Tt[m]`` the saturated estimates, ``phi[m]`` ``(n,)`` and ``psi[m]`` ``(p, q)``
    (last row of each chain) the form's terms at ``Xt[m]``, ``e`` ``(p,)`` the innovations
    :math:`\\tilde y`; ``chains[c] = (first, order)``; the design as :func:`_unpack` gives it;
    ``Sg`` the adaptation gain :math:`S`; ``v, w`` scratch ``(q,)``.
    """
    n, q, p = Xt.shape[1], Tt.shape[1], chains.shape[0]
    G = n + q  # Gamma_hat[i, j] is S[m, G + i * q + j]
    # v = Gamma^T C^T y~ ,  w = S v
    for j in range(q):
        acc = 0.0
        for c in range(p):
            acc += S[m, G + chains[c, 0] * q + j] * e[c]
        v[j] = acc
    for j in range(q):
        acc = 0.0
        for k in range(q):
            acc += Sg[j, k] * v[k]
        w[j] = acc
    for c in range(p):
        f, o = chains[c, 0], chains[c, 1]
        for r in range(o):
            i = f + r
            # x_hat' = A x + phi(x~) + psi(x~) theta~ + Lambda^-1 [lambda K + Gamma S Gamma^T C^T] y~
            corr = lamK[i] * e[c]
            for j in range(q):
                corr += S[m, G + i * q + j] * w[j]
            d = phi[m, i]
            if r < o - 1:
                d = S[m, i + 1] + d
            else:
                pt = 0.0
                for j in range(q):
                    pt += psi[m, c, j] * Tt[m, j]
                d = d + pt
            out[i] = d + lampow[i] * corr
            # Gamma' = lambda (A - K C) Gamma + Lambda psi(x~) I_lambda
            for j in range(q):
                g = -lamK[i] * S[m, G + f * q + j]
                if r < o - 1:
                    g = lam * S[m, G + (i + 1) * q + j] + g
                else:
                    g = g + psicoef[c, j] * psi[m, c, j]
                out[G + i * q + j] = g
    # theta_hat' = I_lambda S Gamma^T C^T y~
    for j in range(q):
        out[n + j] = lam_e[j] * w[j]


@njit(cache=True, inline="always")
def _innovations(Sk: Array, m: int, EM: Array, chains: Any, innov: bool,
                 e: Array) -> None:
    """:math:`\\tilde y` of row ``m``: the held innovations ``EM[m, 0]`` (``innov``), else the
    held measurements ``EM[m, 0]`` minus :math:`C \\hat x` of the stage state ``Sk[m]``,
    masked by ``EM[m, 1]`` (0 for a dropped channel)."""
    for c in range(chains.shape[0]):
        e[c] = EM[m, 0, c] if innov else (EM[m, 0, c] - Sk[m, chains[c, 0]]) * EM[m, 1, c]


@njit(cache=True)
def _begin(S: Array, Y: Array, chains: Any, innov: bool, gram_dt: float, EM: Array,
           acc: Array) -> None:
    """At a sample: the held values ``EM[:, 0]`` (innovations ``y - C x_hat``, or the
    measurements) and masks ``EM[:, 1]`` of every member from ``Y`` ``(B, p)`` (NaN: a
    dropout, value 0, mask 0); with ``gram_dt > 0`` add ``gram_dt``
    :math:`\\hat\\Gamma^T C^T C \\hat\\Gamma` to the excitation integral ``acc`` ``(B, q, q)``
    (eq. 11)."""
    B, p = Y.shape
    q = acc.shape[1]
    G = S.shape[1] - q * (S.shape[1] - q) // (q + 1)  # n + q, from N = n + q + n q
    for b in range(B):
        for c in range(p):
            y = Y[b, c]
            if math.isnan(y):
                EM[b, 0, c] = 0.0
                EM[b, 1, c] = 0.0
            else:
                EM[b, 0, c] = y - S[b, chains[c, 0]] if innov else y
                EM[b, 1, c] = 1.0
        if gram_dt > 0.0:
            for j in range(q):
                for k in range(q):
                    t = 0.0
                    for c in range(p):
                        f = chains[c, 0]
                        t += S[b, G + f * q + j] * S[b, G + f * q + k]
                    acc[b, j, k] += gram_dt * t


@njit(cache=True)
def _stage(S0: Array, Sk: Array, Xt: Array, Tt: Array, phi: Array, psi: Array, EM: Array,
           chains: Any, P: Array, Sg: Array, adapt: NDArray[np.int64], h: float, a: float, b: float,
           flags: int, Acc: Array, Snext: Array, Xtn: Array, Ttn: Array) -> int:
    """One Runge-Kutta stage of every member: ``k`` = eq. 12 / 24 at the stage state ``Sk``
    (saturated ``Xt, Tt``, the form's terms ``phi, psi`` there, innovations from ``EM``, the
    adaptation gain ``Sg[adapt[m]]`` of member ``m``: ``Sg`` ``(2, q, q)`` holds the frozen
    gain 0 and :math:`S`); ``Acc`` = (``FIRST`` stage) or += ``b k``; the next stage's state
    ``Snext = S0 + a h k``, or on the ``LAST`` stage the step ``S0 + h Acc``, and its
    saturation ``Xtn, Ttn``. Returns the number of members whose step is not finite (0 but on
    the last stage)."""
    B, N = Sk.shape
    n, q, p = Xt.shape[1], Tt.shape[1], chains.shape[0]
    lam, X, Theta, lamK, lampow, lam_e, psicoef = _unpack(P, n, q, p)
    first, last, innov = (flags & FIRST) != 0, (flags & LAST) != 0, (flags & INNOVATION) != 0
    k = np.empty(N)
    e = np.empty(p)
    v = np.empty(q)
    w = np.empty(q)
    ah = a * h
    bad = 0
    for m in range(B):
        _innovations(Sk, m, EM, chains, innov, e)
        _derivative(Sk, Xt, Tt, phi, psi, m, e, chains, lam, lamK, lampow, lam_e, psicoef,
                    Sg[adapt[m]], v, w, k)
        if first:
            for i in range(N):
                Acc[m, i] = b * k[i]
        else:
            for i in range(N):
                Acc[m, i] += b * k[i]
        if last:
            ok = True
            for i in range(N):
                Snext[m, i] = S0[m, i] + h * Acc[m, i]
                ok = ok and math.isfinite(Snext[m, i])
            bad += 0 if ok else 1
        else:
            for i in range(N):
                Snext[m, i] = S0[m, i] + ah * k[i]
        _saturate(Snext, m, X, Theta, Xtn, Ttn)
    return bad


@njit(cache=True)
def _saturate_rows(S: Array, X: float, Theta: float, Xt: Array,
                   Tt: Array) -> None:
    """:func:`_saturate` of every row of ``S``."""
    for m in range(S.shape[0]):
        _saturate(S, m, X, Theta, Xt, Tt)


@njit(cache=True)
def _derivative_rows(S: Array, Xt: Array, Tt: Array, phi: Array, psi: Array, EM: Array,
                     chains: Any, P: Array, Sg: Array, out: Array) -> None:
    """:func:`_derivative` of every row of ``S`` with the measurements held (for checks and
    the continuous-time reproduction)."""
    n, q, p = Xt.shape[1], Tt.shape[1], chains.shape[0]
    lam, _, _, lamK, lampow, lam_e, psicoef = _unpack(P, n, q, p)
    e = np.empty(p)
    v = np.empty(q)
    w = np.empty(q)
    k = np.empty(S.shape[1])
    for m in range(S.shape[0]):
        _innovations(S, m, EM, chains, False, e)
        _derivative(S, Xt, Tt, phi, psi, m, e, chains, lam, lamK, lampow, lam_e, psicoef, Sg,
                    v, w, k)
        out[m] = k


# ======================================================================================
# the observer
# ======================================================================================


def _c(a: Array) -> Array:
    return np.ascontiguousarray(a, dtype=np.float64)


def _window_sums(s: Any, rows: NDArray[np.intp]) -> Array:
    """The excitation integral of the members ``rows`` of the state ``s`` over their complete
    sub-windows, ``(len(rows), q, q)``: each member's ring ``blocks`` summed oldest first (NaN
    where none is complete yet)."""
    F = s.fields
    blocks, nblocks, next_block = F["blocks"], F["nblocks"], F["next_block"]
    B, q = blocks.shape[0], blocks.shape[2]
    k0, n0 = int(nblocks[rows[0]]), int(next_block[rows[0]])
    if rows.size == B and (nblocks == k0).all() and (next_block == n0).all():
        # every member at one ring position (the usual case): views, no copies
        if k0 == 0:
            return np.full((B, q, q), np.nan)
        order = [(n0 - k0 + i) % SUBWINDOWS for i in range(k0)]
        W = blocks[:, order[0]].copy()
        for i in order[1:]:
            W += blocks[:, i]
        return W
    out = np.full((len(rows), q, q), np.nan)
    k_all, next_all = nblocks[rows], next_block[rows]
    for k, nxt in {(int(k), int(x)) for k, x in zip(k_all, next_all)}:
        if k == 0:
            continue
        at = np.flatnonzero((k_all == k) & (next_all == nxt))
        members = rows[at]
        order = [(nxt - k + i) % SUBWINDOWS for i in range(k)]
        W = blocks[members, order[0]]  # (a copy: fancy indexing)
        for i in order[1:]:
            W += blocks[members, i]
        out[at] = W
    return out


@register
class BesanconObserver(Observer):
    """Adaptive high-gain observer of Besançon, Zhang and Hammouri (paper 001, eq. 12 / 24).

    See the module docstring for the equations (and the corrections of the paper). Between
    samples the measurement and the input are held; each sample integrates the observer state
    :math:`(\\hat x, \\hat\\theta, \\hat\\Gamma)` of every member over one period by Heun's
    method, RK4 or Euler in ``substeps`` steps.

    Parameters
    ----------
    system : System or AffineForm, optional
        The system (its form is :func:`affine_form`: the one it declares, or its protocol) or
        the form itself.
    form : AffineForm, optional
        The form, when ``system`` is only used for names (or not given).
    unknown : sequence of str, optional
        Parameters to estimate, for the systems' forms (pendulum: ``g_over_l``, ``b_over_J``,
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
    outputs : tuple of int, optional
        The measured channel of each chain (default the form's, ``(0, ..., p-1)``).
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
    on_unstable : {"raise", "warn", "ignore"}
        What :meth:`check_period` does at a period where the linear modes are unstable.

    Attributes
    ----------
    theta_hat_ : ndarray (q,) or (B, q)
        Parameter estimate.
    Gamma_ : ndarray (n, q) or (B, n, q)
        The filter :math:`\\hat\\Gamma`.
    excitation_ : float or (B,)
        Smallest eigenvalue of the windowed :math:`\\int \\hat\\Gamma^T C^T C \\hat\\Gamma`
        (NaN until a first window is complete).
    physical_params_ : dict
        Physical parameters recovered from :math:`\\hat\\theta` (elastic joint: ``stiffness``,
        ``MgL``).
    dropouts_, inverse_failures_
        As in :class:`~hgo_mj.observers.base.Observer` (a sample where the map to physical
        coordinates is undefined holds the last value).

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.systems import BesanconExample1
    >>> ob = BesanconObserver(BesanconExample1(), lam=10.0, X=10.0, Theta=10.0)
    >>> ob.reset(batch=4)
    >>> ob.run(np.full((4, 3, 1), 0.5), np.zeros((4, 3, 1)), 0.01).x_hat.shape
    (4, 3, 2)
    >>> ob.theta_hat_.shape
    (4, 2)

    Four high gains and adaptation gains as one batch, each member its own single run:

    >>> params = ob.parameters(4, lam=[5.0, 10.0, 20.0, 40.0],
    ...                        gain=np.eye(2) * np.array([1.0, 1.0, 2.0, 4.0])[:, None, None])
    >>> state = ob.init(4, params=params)
    >>> state, blk = ob.step(params, state, np.full((4, 3, 1), 0.5), np.zeros((4, 3, 1)), 0.01)
    >>> blk.z_hat.shape, state.t.tolist()
    ((4, 3, 2), [0.03, 0.03, 0.03, 0.03])

    References
    ----------
    Paper 001, eq. 12 (Theorem 3.1), eq. 24 (Theorem 3.2), eq. 11 ([A3]).
    """

    name = "besancon"
    required_form = ("affine", "a linear parametrization in the unknown parameters "
                              "(paper 001, eq. 9 / 21)")
    summary = "Besançon-Zhang-Hammouri adaptive high-gain observer (state + parameters), PE figure"
    reference = "paper 001 (Besançon, Zhang, Hammouri 2004), eq. 9-12, 21-24"
    needs_normal_form = False

    def __init__(self, system: Any = None, *, form: AffineForm | None = None,
                 unknown: Sequence[str] | None = None, lam: float, K0: Any = None,
                 gain: Any = 1.0, X: float | None = None, Theta: float | None = None,
                 theta_hat0: Any = None, x_hat0: Any = None, z_hat0: Any = None,
                 Gamma0: Any = None, theta_exponents: Any = None, outputs: Any = None,
                 method: str = "rk2", substeps: int = 1, hold: str = "measurement",
                 adapt_after: float = 0.0, excitation_window: float | None = 10.0,
                 on_unstable: str = "raise") -> None:
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
        outs = form.outputs if outputs is None else check_outputs(outputs)
        if len(outs) != form.p:
            raise DesignError(f"outputs must be {form.p} channel indices (one per chain); found "
                              f"{list(outs)}")
        super().__init__(system if isinstance(system, System) else None, order=form.n,
                         outputs=outs, on_unstable=on_unstable)
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
        if excitation_window is not None:
            excitation_window = finite_scalar("excitation_window", excitation_window,
                                              positive=True)
        self.excitation_window = excitation_window
        self.adapt_after = finite_scalar("adapt_after", adapt_after, nonnegative=True)
        self._design()
        self._extra = tuple(k for k in form.true_physical if k not in form.theta_names)
        self.family_diagnostics = tuple(  # type: ignore[misc]  # per instance: the form's names
            f"theta_{nm}" for nm in form.theta_names) + tuple(
            f"theta_{k}" for k in self._extra) + ("excitation",)
        self._start = (x_hat0, z_hat0, theta_hat0, Gamma0)
        self.init(1)  # checks the initial estimate (Theorem 3.1's balls, the map's domain)

    # ------------------------------------------------------------------ setup
    def _design(self) -> None:
        """The constant arrays of the kernels that do not depend on the tunable parameters:
        ``chains`` ``(p, 2)`` (first state, order), the tableau, the sub-window length; the
        design vectors of the parameters are built by :meth:`_design_at`."""
        f = self.form
        self._chains = np.array([(fi, o) for fi, o in zip(f.firsts, f.orders)], dtype=np.int64)
        self._tableau = tuple((a, b, (FIRST if i == 0 else 0)
                               | (LAST if i == len(TABLEAUS[self.method]) - 1 else 0)
                               | (INNOVATION if self.hold == "innovation" else 0))
                              for i, (a, b) in enumerate(TABLEAUS[self.method]))
        self._sub = (self.excitation_window / SUBWINDOWS * (1.0 - 1e-9)
                     if self.excitation_window else math.inf)
        self._designs: dict[bytes, tuple[Array, Array]] = {}

    def _parameters(self) -> dict[str, Any]:
        """The high gain ``lam`` (:math:`\\lambda`, a float), the Hurwitz gains ``K0`` of the
        chains concatenated (:math:`(K_1, \\dots, K_p)`, ``(n,)``) and the adaptation gain
        ``gain`` (:math:`S`, ``(q, q)``) (paper 001, eq. 12 / 24; Zhang 2002)."""
        return {"lam": self.lam, "K0": np.concatenate(self.K), "gain": self.gain}

    def _check_parameter(self, name: str, value: Any) -> Array:
        if name == "lam":
            return np.array(finite_scalar("lam", value, positive=True))
        if name == "K0":
            a = np.asarray(value, dtype=object)
            if a.ndim == 1 and a.shape != (self.n,) and all(np.ndim(v) == 0 for v in a):
                raise DimensionError(f"K0 must have n = {self.n} gains (the chains' gains "
                                     f"concatenated) or one array per chain; found {a.size}")
            if np.shape(value) == (self.n,):  # the chains' gains concatenated
                return np.concatenate(self._chain_gains(
                    [np.asarray(value)[fi:fi + o] for fi, o in zip(self.form.firsts,
                                                                   self.form.orders)]))
            return np.concatenate(self._gains(value))
        return symmetric_matrix("gain", value, self.q)

    def _design_at(self, p: Params) -> tuple[Array, Array]:
        """The design of the parameters ``p`` (one member's): the vector ``P`` of
        :func:`_unpack` and the adaptation gains ``(2, q, q)`` (0 before ``adapt_after``,
        then :math:`S`), built on first use (at most :data:`DESIGN_CACHE` kept)."""
        key = p.key()
        design = self._designs.get(key)
        if design is None:
            f, lam = self.form, float(p.lam)
            K = np.asarray(p.K0)
            lamK = np.empty(f.n)
            lampow = np.empty(f.n)
            for fi, o in zip(f.firsts, f.orders):
                for r in range(o):
                    lamK[fi + r] = lam * K[fi + r]
                    lampow[fi + r] = lam ** r
            lam_e = np.array([lam ** e for e in self.exps])
            psicoef = np.array([[lam ** (e - (o - 1)) for e in self.exps] for o in f.orders])
            P = np.concatenate(([lam, self.X, self.Theta], lamK, lampow, lam_e,
                                psicoef.reshape(-1)))
            Sg = np.zeros((2, f.q, f.q))  # [0]: no adaptation before adapt_after
            Sg[1] = p.gain
            design = (P, Sg)
            if len(self._designs) >= DESIGN_CACHE:
                del self._designs[next(iter(self._designs))]
            self._designs[key] = design
        return design

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
        return self._chain_gains(per)

    def _chain_gains(self, per: list[Any]) -> tuple[Array, ...]:
        """:math:`K_c` of each chain from ``per`` (one value or None per chain), checked."""
        f = self.form
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

    @property
    def n_inputs(self) -> int | None:
        if self.system is not None:
            return len(self.system.input_names)
        return self.form.n_inputs

    @property
    def state_names(self) -> tuple[str, ...]:
        f = self.form
        return f.physical_state_names if f.to_physical is not None else f.state_names

    def _check_period(self, p: Params, dt: float) -> None:
        """Refuse (``on_unstable``) a sample period for which the integration of the linear
        modes :math:`\\lambda\\,\\mathrm{eig}(A_c - K_c C_c)` is unstable (the parameter modes
        depend on the data and are not checked here)."""
        if self.on_unstable == "ignore":
            return
        lam, K = float(p.lam), np.asarray(p.K0)
        lam_modes = np.concatenate([lam * np.roots(np.concatenate(([1.0], K[fi:fi + o])))
                                    for fi, o in zip(self.form.firsts, self.form.orders)])
        try:
            check_rk_period(f"the Besançon observer (lambda={lam:g}, modes lambda*eig(A - K C))",
                            lam_modes, dt, self.method, self.substeps)
        except DesignError as exc:
            if self.on_unstable == "raise":
                raise
            warnings.warn(str(exc), RuntimeWarning, stacklevel=3)

    # ------------------------------------------------------------------ initial state
    def reset(self, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None,
              batch: int | None = None, params: Params | None = None, theta_hat0: Any = None,
              Gamma0: Any = None) -> None:
        """Restart the observer's own state (see :meth:`Observer.reset`); each initial value
        not given is the constructor's. ``theta_hat0`` is ``(q,)`` or ``(B, q)``, ``Gamma0``
        ``(n, q)`` or ``(B, n, q)``; one given per member makes the observer batched.

        Raises
        ------
        DesignError
            An initial estimate outside the balls of radius ``X``, ``Theta`` (Theorem 3.1), or
            where the form's map to physical coordinates is undefined.
        """
        if batch is None and params is None:  # the batch of any value given per member
            given = x_hat0 if x_hat0 is not None else z_hat0
            for v, nd in ((given, 2), (theta_hat0, 2), (Gamma0, 3)):
                if v is not None and np.ndim(v) == nd:
                    batch = int(np.shape(v)[0])
                    break
        batched = batch is not None or params is not None
        B = batch if batch is not None else (1 if params is None else params.batch)
        p = self.parameters(B) if params is None else params
        s = self.init(B, x_hat0, z_hat0=z_hat0, u0=u0, params=p, theta_hat0=theta_hat0,
                      Gamma0=Gamma0)
        self._hold(p, s, batched)

    def init(self, batch: int = 1, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None,
             params: Params | None = None, theta_hat0: Any = None,
             Gamma0: Any = None) -> State:
        """A new state of ``batch`` members (see :meth:`Observer.init`), with also the initial
        parameter estimate ``theta_hat0`` (``(q,)`` or ``(B, q)``) and filter ``Gamma0``
        (``(n, q)`` or ``(B, n, q)``); each not given is the constructor's. The initial state
        does not depend on the parameters.

        Parameters
        ----------
        batch : int
            The number of members B.
        x_hat0, z_hat0, u0, params
            As in :meth:`Observer.init`.
        theta_hat0 : array_like, optional
            Initial parameter estimate.
        Gamma0 : array_like, optional
            Initial :math:`\\hat\\Gamma`.

        Returns
        -------
        State
            ``S`` ``(B, N)`` (rows :math:`(\\hat x, \\hat\\theta, \\hat\\Gamma)`), the clock
            ``t`` ``(B,)``, the excitation integral (``acc``, ``acc_t``, the ring ``blocks``
            ``(B, 20, q, q)`` with ``nblocks`` and ``next_block``, ``exc``), then the core
            fields of :meth:`Observer.init`.

        Raises
        ------
        DesignError
            As :meth:`reset`.
        DimensionError
            An initial value of the wrong shape.

        Examples
        --------
        >>> from hgo_mj.systems import BesanconExample1
        >>> ob = BesanconObserver(BesanconExample1(), lam=10.0)
        >>> s = ob.init(3, theta_hat0=[[0.5, 1.0], [0.4, 1.0], [0.3, 1.0]])
        >>> s.S.shape, s.S[:, 2].tolist()
        ((3, 8), [0.5, 0.4, 0.3])
        """
        if theta_hat0 is None and Gamma0 is None:
            return super().init(batch, x_hat0, z_hat0=z_hat0, u0=u0, params=params)
        B = _batch_size(batch)
        if x_hat0 is not None and z_hat0 is not None:
            raise DesignError("give x_hat0 or z_hat0, not both")
        if params is not None and (not isinstance(params, Params) or params.batch != B):
            raise DesignError(f"{self.name}: params must be this observer's Params of {B} "
                              f"member(s) (Observer.parameters); found {params!r}")
        x0 = None if x_hat0 is None else batch_rows("x_hat0", x_hat0, len(self.state_names), B)
        z0 = None if z_hat0 is None else batch_rows("z_hat0", z_hat0, self.n, B)
        m = self.n_inputs
        u = np.zeros((B, m or 0)) if u0 is None or m is None else batch_rows("u0", u0, m, B)
        return State(**{**self._core(B), **self._fields(x0, z0, u, theta_hat0, Gamma0)})

    def _init(self, p: Params, x0: Array | None, z0: Array | None,
              u0: Array) -> dict[str, Any]:
        return self._fields(x0, z0, u0, None, None)

    def _fields(self, x0: Array | None, z0: Array | None, u0: Array, th0: Any,
                G0: Any) -> dict[str, Any]:
        """The state fields of ``len(u0)`` members from ``x0`` or ``z0`` (neither: the
        constructor's), ``th0`` and ``G0`` (None: the constructor's)."""
        f, B = self.form, u0.shape[0]
        ix, iz, ith, iG = self._start
        if x0 is None and z0 is None:
            x0 = None if ix is None else batch_rows("x_hat0", ix, len(self.state_names), B)
            z0 = None if iz is None else batch_rows("z_hat0", iz, self.n, B)
        th0 = ith if th0 is None else th0
        G0 = iG if G0 is None else G0
        th = np.zeros((B, f.q)) if th0 is None else batch_rows("theta_hat0", th0, f.q, B)
        if G0 is None:
            G = np.zeros((B, f.n, f.q))
        else:
            G = np.array(G0, dtype=float)
            if G.shape == (f.n, f.q):
                G = np.tile(G, (B, 1, 1))
            if G.shape != (B, f.n, f.q):
                raise DimensionError(f"Gamma0 must have shape (n, q) = ({f.n}, {f.q}) or "
                                     f"({B}, {f.n}, {f.q}); found shape {np.shape(G0)}")
            if not np.all(np.isfinite(G)):
                raise DesignError("Gamma0 must be finite")
        if x0 is not None and f.from_physical is not None:
            z = np.array([vector("from_physical(x_hat0)", f.from_physical(x, t, u), f.n)
                          for x, t, u in zip(x0, th, u0)], dtype=float).reshape(B, f.n)
        else:
            z = x0 if x0 is not None else (z0 if z0 is not None else np.zeros((B, f.n)))
        nz = np.sqrt(np.sum(z * z, axis=1))
        if np.any(nz > self.X):
            raise DesignError(f"the initial estimate must lie in the ball |x_hat| <= X = {self.X:g} "
                              f"(Theorem 3.1); found |x_hat0| = {nz.max():.4g}")
        nt = np.sqrt(np.sum(th * th, axis=1))
        if np.any(nt > self.Theta):
            raise DesignError(f"the initial parameter estimate must lie in |theta_hat| <= Theta = "
                              f"{self.Theta:g} (Theorem 3.1); found {nt.max():.4g}")
        fields: dict[str, Any] = {
            "S": _c(np.concatenate((z, th, G.reshape(B, -1)), axis=1)),
            "t": np.zeros(B),  # each member's time since its start (adapt_after)
            # excitation: SUBWINDOWS sub-windows of the windowed Gram integral (eq. 11)
            "acc": np.zeros((B, f.q, f.q)), "acc_t": np.zeros(B),
            "blocks": np.zeros((B, SUBWINDOWS, f.q, f.q)),
            "nblocks": np.zeros(B, dtype=np.int64), "next_block": np.zeros(B, dtype=np.int64),
            "exc": np.full(B, np.nan)}
        if f.to_physical is not None:
            xp = np.asarray(f.to_physical(z, th, u0), dtype=float).reshape(B, -1)
            if not np.all(np.isfinite(xp)):
                b = int(np.argmin(np.all(np.isfinite(xp), axis=1)))
                raise DesignError(f"the initial estimate (z = {z[b].tolist()}, theta = "
                                  f"{th[b].tolist()}) lies where the map of {f.label} to physical "
                                  f"coordinates is undefined; give theta_hat0 inside its domain "
                                  f"(e.g. a positive stiffness)")
            fields["x_held"] = xp.copy()
        return fields

    # ------------------------------------------------------------------ step
    def _step(self, p: Params, s: State, Y: Array, U: Array, dt: float, X: Array, Z: Array,
              D: Array) -> None:
        f = self.form
        B, T = Y.shape[0], Y.shape[1]
        if T == 0:
            return
        n, q = f.n, f.q
        P, Sg = self._design_at(p)
        F = s.fields  # the state's arrays (read in the sample loop without attribute lookups)
        S = F["S"]
        Yt = np.ascontiguousarray(Y.transpose(1, 0, 2))  # (T, B, p): one sample is contiguous
        Ut = np.ascontiguousarray(U.transpose(1, 0, 2))
        TH = np.empty((B, T, q))
        chains = self._chains
        # work arrays: held values and masks, the stage sum, two stage states
        EM = np.empty((B, 2, f.p))
        Acc = np.empty(S.shape)
        bufs = [(np.empty(S.shape), np.empty((B, n)), np.empty((B, q))) for _ in range(2)]
        cur = (S, np.empty((B, n)), np.empty((B, q)))  # the state, x~, theta~
        _saturate_rows(S, self.X, self.Theta, cur[1], cur[2])
        innov = self.hold == "innovation"
        gram_dt = dt if self.excitation_window is not None else 0.0
        h = dt / self.substeps
        terms = f.terms
        acc, acc_t, t, exc, sub = F["acc"], F["acc_t"], F["t"], F["exc"], self._sub
        # per member: the gain Sg[adapt] (Sg[0] = 0 until adapt_after, then Sg[1] = S)
        frozen_until = self.adapt_after - 1e-12
        frozen = self.adapt_after > 0.0
        adapt = np.empty(B, dtype=np.int64)
        adapt.fill(1)
        for j in range(T):
            Uj = Ut[j]
            _begin(cur[0], Yt[j], chains, innov, gram_dt, EM, acc)
            if gram_dt:
                acc_t += dt
                due = acc_t >= sub
                if due.any():
                    self._close_windows(s, np.flatnonzero(due))
            if frozen:
                np.greater_equal(t, frozen_until, out=adapt, casting="unsafe")
                frozen = not adapt.all()
            t += dt
            for _ in range(self.substeps):
                src = cur
                for st, (a, b, flags) in enumerate(self._tableau):
                    dst = bufs[st % 2]  # stages alternate between two buffers
                    phi, psi = terms(src[1], Uj)
                    bad = _stage(cur[0], src[0], src[1], src[2], phi, psi, EM, chains, P, Sg,
                                 adapt, h, a, b, flags, Acc, dst[0], dst[1], dst[2])
                    src = dst
                if bad:
                    rows = cur[0][~np.all(np.isfinite(src[0]), axis=1), :n]
                    raise DivergenceError(
                        f"the Besançon observer state left the finite numbers: from "
                        f"{rows[0].tolist()} (lambda={float(p.lam):g}, step {dt:g}); bound it "
                        f"with X= and Theta=, lower the gain or raise substeps")
                # the step is the new state; the old state's arrays become a stage buffer
                bufs[0 if src is bufs[0] else 1] = cur
                cur = src
                F["S"] = cur[0]
            Z[:, j] = cur[0][:, :n]
            TH[:, j] = cur[0][:, n:n + q]
            D[:, j, -1] = exc
        self._write_diag(D, TH)
        self._write_physical(s, Z, TH, U, X)

    def _write_diag(self, D: Array, TH: Array) -> None:
        """The parameter columns of the diagnostics ``D`` ``(B, T, d)`` from the estimates
        ``TH`` ``(B, T, q)``: ``theta_<name>``, the physical parameters the form recovers
        (``theta_MgL``); the excitation (last column) is written by the caller."""
        f, q = self.form, self.form.q
        B, T = TH.shape[0], TH.shape[1]
        D[:, :, :q] = TH
        if self._extra:
            phys = f.physical_params(TH.reshape(B * T, q)) if f.physical_params else {}
            for i, k in enumerate(self._extra):
                D[:, :, q + i] = (np.asarray(phys[k]).reshape(B, T) if k in phys else np.nan)

    def _write_physical(self, s: State, Z: Array, TH: Array, U: Array, X: Array) -> None:
        """``X`` ``(B, T, n_x)``: the form's map to physical coordinates of the rows (with the
        parameter estimates after each sample), holding each member's last valid value where it
        is undefined (counted in the state's ``inverse_failures``); ``z_hat`` without a map."""
        f = self.form
        if f.to_physical is None:
            X[...] = Z
            return
        B, T = Z.shape[0], Z.shape[1]
        xp = np.asarray(f.to_physical(_c(Z.reshape(B * T, -1)), _c(TH.reshape(B * T, -1)),
                                      _c(U.reshape(B * T, -1))), dtype=float).reshape(B, T, -1)
        bad = ~np.all(np.isfinite(xp), axis=2)
        if bad.any():
            for b in np.flatnonzero(bad.any(axis=1)):
                held = s.x_held[b]
                for j in range(T):
                    if bad[b, j]:
                        s.inverse_failures[b] += 1
                        xp[b, j] = held
                    else:
                        held = xp[b, j]
        X[...] = xp
        s.x_held = xp[:, -1].copy()

    def _close_windows(self, s: State, rows: NDArray[np.intp]) -> None:
        """A sub-window of the excitation integral is complete for the members ``rows``: store
        it in their rings, refresh their smallest eigenvalue over the last ``SUBWINDOWS``
        (summed oldest first)."""
        F = s.fields
        blocks, nblocks, next_block, acc = F["blocks"], F["nblocks"], F["next_block"], F["acc"]
        i0 = int(next_block[rows[0]])
        if rows.size == blocks.shape[0] and (next_block == i0).all():
            # every member at one ring position (the usual case): views, no copies
            blocks[:, i0] = acc
            next_block.fill((i0 + 1) % SUBWINDOWS)
            np.minimum(nblocks + 1, SUBWINDOWS, out=nblocks)
            acc.fill(0.0)
            F["acc_t"].fill(0.0)
        else:
            nxt = next_block[rows]
            blocks[rows, nxt] = acc[rows]
            next_block[rows] = (nxt + 1) % SUBWINDOWS
            nblocks[rows] = np.minimum(nblocks[rows] + 1, SUBWINDOWS)
            acc[rows] = 0.0
            F["acc_t"][rows] = 0.0
        full = rows[nblocks[rows] == SUBWINDOWS]
        if full.size:
            W = _window_sums(s, full)
            ok = np.all(np.isfinite(W), axis=(1, 2))
            if ok.all():
                F["exc"][full] = np.linalg.eigvalsh(W)[:, 0]
            else:
                exc = np.full(full.size, np.nan)
                if ok.any():
                    exc[ok] = np.linalg.eigvalsh(W[ok])[:, 0]
                F["exc"][full] = exc

    def excitation_matrix_rows(self, state: State | None = None) -> Array:
        """The windowed :math:`\\int \\hat\\Gamma^T C^T C \\hat\\Gamma d\\tau` of every member
        over the complete sub-windows, ``(B, q, q)`` (NaN before the first).

        Parameters
        ----------
        state : State, optional
            The state to read (default: the observer's own).

        Returns
        -------
        (B, q, q) ndarray
            One symmetric matrix per member (all NaN before a first sub-window is complete).

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems import BesanconExample1
        >>> ob = BesanconObserver(BesanconExample1(), lam=10.0, X=10.0, Theta=10.0,
        ...                       excitation_window=0.1)
        >>> ob.reset(batch=3)
        >>> ob.excitation_matrix_rows().shape
        (3, 2, 2)
        """
        s = self.state if state is None else state
        return _window_sums(s, np.arange(s.batch))

    def excitation_matrix(self) -> Array:
        """:meth:`excitation_matrix_rows`, ``(q, q)`` for an unbatched observer (eq. 11).

        Returns
        -------
        ndarray
            ``(q, q)`` unbatched, ``(B, q, q)`` batched.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems import BesanconExample1
        >>> ob = BesanconObserver(BesanconExample1(), lam=10.0, X=10.0, Theta=10.0,
        ...                       excitation_window=0.1)
        >>> ob.reset()
        >>> for t in np.arange(20) * 0.01:
        ...     _ = ob.update(np.array([np.sin(5 * t)]), np.array([np.cos(3 * t)]), 0.01)
        >>> ob.excitation_matrix().round(4)
        array([[0.0036, 0.0078],
               [0.0078, 0.0185]])
        """
        return self._public(self.excitation_matrix_rows())  # type: ignore[no-any-return]

    # ------------------------------------------------------------------ checks
    def _rhs(self, S: Any, Y: Any, U: Any, *, gain: Any = None) -> Array:
        """Eq. 12 / 24 of the rows ``S`` ``(B, N)`` (``(x_hat, theta_hat, Gamma_hat)``,
        ``Gamma_hat`` row-major) with the measurements ``Y`` ``(B, p)`` held (NaN: a dropout)
        and inputs ``U`` ``(B, m)``, with the constructor's parameters: the continuous-time
        observer (tests, the reproduction's continuous-time cross-check)."""
        S, Y, U = _c(np.atleast_2d(S)), _c(np.atleast_2d(Y)), _c(np.atleast_2d(U))
        B = S.shape[0]
        Xt, Tt = np.empty((B, self.n)), np.empty((B, self.q))
        _saturate_rows(S, self.X, self.Theta, Xt, Tt)
        phi, psi = self.form.terms(Xt, U)
        lost = np.isnan(Y)
        EM = _c(np.stack((np.where(lost, 0.0, Y), (~lost).astype(float)), axis=1))
        out = np.empty_like(S)
        P, Sg = self._design_at(self.parameters().member(0))
        _derivative_rows(S, Xt, Tt, phi, psi, EM, self._chains, P,
                         Sg[1] if gain is None else _c(gain), out)
        return out

    # ------------------------------------------------------------------ estimates
    def _current(self, p: Params, s: State) -> tuple[Array, Array, Array]:
        n, q, S = self.n, self.q, s.S
        x = s.x_held.copy() if self.form.to_physical is not None else S[:, :n].copy()
        d = np.empty((S.shape[0], 1, len(self.family_diagnostics)))
        self._write_diag(d, S[:, None, n:n + q])
        d[:, 0, -1] = s.exc
        return x, S[:, :n].copy(), d[:, 0]

    @property
    def state_rows(self) -> Array:
        """The observer state of every member, ``(B, N)`` rows ``(x_hat, theta_hat,
        Gamma_hat)`` (a copy)."""
        return self.state.S.copy()  # type: ignore[no-any-return]

    @property
    def theta_hat_(self) -> Array:
        return self._public(self.state.S[:, self.n:self.n + self.q].copy())  # type: ignore[no-any-return]

    @property
    def Gamma_(self) -> Array:
        n, q = self.n, self.q
        return self._public(self.state.S[:, n + q:].reshape(-1, n, q).copy())  # type: ignore[no-any-return]

    @property
    def excitation_(self) -> Any:
        return self._public(self.state.exc.copy())

    @property
    def physical_params_(self) -> dict[str, Any]:
        f = self.form
        th = self.state.S[:, self.n:self.n + self.q]
        phys = f.physical_params(th.copy()) if f.physical_params else {}
        out: dict[str, Any] = {}
        for k in f.true_physical:
            if k in phys:
                v = np.asarray(phys[k], dtype=float)
            elif k in f.theta_names:
                v = th[:, f.theta_names.index(k)].copy()
            else:
                v = np.full(self.batch, np.nan)
            out[k] = self._public(v)
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
                "excitation_window": self.excitation_window, "on_unstable": self.on_unstable}
