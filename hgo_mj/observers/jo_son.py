"""The adaptive observer of Jo and Son (paper 003 [003]_) on the generalized observer canonical form.

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
:math:`A_{\\bar o o} \\hat z_{\\bar o}`; the proof's error equation
:math:`\\dot e_{\\bar o} = A_{\\bar o o} e_o + \\dots` requires :math:`A_{\\bar o o} \\hat z_o`,
and eq. 21 prints :math:`\\dot{\\hat z}_{\\bar o} = A_{\\bar o o} \\hat z_{\\bar o} = f_{\\bar o}
+ \\gamma_{\\bar o}` with "=" where "+" is meant (eq. 27 has the "+"). Eq. 27's parameter line
prints :math:`\\hat\\theta = \\Gamma \\beta (y - \\hat z_r)`, the dot of
:math:`\\dot{\\hat\\theta}` missing (eq. 21 has it).
In the proof of Corollary 3.3 the first line reads :math:`b_r b_1 = \\lambda b_1`
(it is :math:`b_r k_1 = \\lambda b_1`) and the transfer function is printed
:math:`C_o (sI - A_o)^{-1} b` (it is :math:`C_o (sI - A_o + K C_o)^{-1} b`). In the example
(section 4) the observer's :math:`\\dot{\\hat z}_2` reads :math:`z_1` where :math:`\\hat z_1` is
meant (run as printed, that leaves a constant offset in :math:`\\hat x_2`: see
:mod:`hgo_mj.reproduce.jo_son2004`). The proof of Corollary 3.3 also writes
:math:`b \\beta^T e_o`; it is :math:`b \\beta^T e_\\theta`. Eq. 5 writes
:math:`X_i = ad^{i-1} \\tau` without the sign of the drift: the example's
:math:`X_2 = \\partial_{x_1} - x_1^2 \\partial_{x_2} + x_1 \\partial_{x_3}` is
:math:`ad_{-f} \\tau = -[f, \\tau]` (with :math:`[f, g] = (\\partial g/\\partial x) f -
(\\partial f/\\partial x) g`), as the proof of Theorem 3.1 writes it
(:math:`\\langle dh, ad_{-f}^i \\tau \\rangle`). The example cites conditions (v)-(viii) of
Theorem 3.1, which has (i)-(iii) (its (i) is Theorem 2.2's (i)-(vii)); its "(vii)",
:math:`[X_2, q] = u (2 X_1 + X_2)`, is Theorem 3.1 (iii).

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
import warnings
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from .._validate import finite_scalar, one_of, positive_int, symmetric_matrix, vector
from ..exceptions import DesignError, DimensionError, DivergenceError
from ..systems.base import System
from ..systems.jo_son_form import JoSonForm
from ._integrate import euler, rk4
from .base import Array, Observer, Params, State, batch_rows, check_outputs, register
from .bastin_gevers import check_rk_period, sym_eigvals

__all__ = ["JoSonForm", "JoSonObserver", "jo_son_gain"]

METHODS = ("rk4", "euler")
#: the most parameter sets whose gains an observer keeps (:meth:`JoSonObserver._gains`)
GAIN_CACHE = 64


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
    DimensionError
        ``b`` is empty.

    References
    ----------
    Paper 003, Corollary 3.3, eq. 25-26.

    Examples
    --------
    >>> jo_son_gain([1.0, 1.0], lam=2.0)       # k_1 = 2 * 1 / 1, k_2 = (1 + 2 * 1) / 1
    array([2., 3.])
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


# ======================================================================================
# kernels: arrays, floats and ints only; one loop over the B members inside
# ======================================================================================


@njit(cache=True)
def eq27(S: Array, y: Array, c: Array, go: Array, be: Array, fo: Array, gb: Array, K: Array,
         b: Array, A: Array, G: Array, r: int, out: Array) -> None:  # pragma: no cover - jit
    """Right-hand side of eq. 27 (paper 003, Theorem 3.4) for the rows of ``S`` ``(B, n + p)``
    ``= (z_hat_o, z_hat_obar, theta_hat)``, written into ``out``:

    .. math::

        \\dot{\\hat z}_o &= A_o \\hat z_o + \\gamma_o + b\\, \\beta^T \\hat\\theta + K e,
        \\qquad e = c\\, (y - \\hat z_r) \\\\
        \\dot{\\hat z}_{\\bar o} &= A_{\\bar o o} \\hat z_o + f_{\\bar o}(y, \\hat z_{\\bar o})
                                    + \\gamma_{\\bar o} \\\\
        \\dot{\\hat\\theta} &= \\Gamma \\beta\\, e

    with the signals held over the sample: ``go`` :math:`\\gamma_o(y, u)` ``(B, r)``, ``be``
    :math:`\\beta(y, u)` ``(B, p)``, ``gb`` :math:`\\gamma_{\\bar o}(y, u)` ``(B, n - r)``;
    ``fo`` is :math:`f_{\\bar o}(y, \\hat z_{\\bar o})` at this ``S``. ``c`` is 1 (correct) or
    0 (a dropout: prediction without output injection). The second line reads
    :math:`A_{\\bar o o} \\hat z_o` where the paper prints :math:`\\hat z_{\\bar o}` (see the
    module docstring).
    """
    B, w = S.shape
    p = be.shape[1]
    n = w - p
    for i in range(B):
        e = c[i] * (y[i] - S[i, r - 1])  # y - C_o z_hat_o
        bt = 0.0  # beta^T theta_hat
        for m in range(p):
            bt += be[i, m] * S[i, n + m]
        out[i, 0] = go[i, 0] + b[0] * bt + K[0] * e  # (A_o z)_1 = 0
        for k in range(1, r):  # (A_o z)_k = z_(k-1)
            out[i, k] = S[i, k - 1] + go[i, k] + b[k] * bt + K[k] * e
        for j in range(n - r):
            a = 0.0  # (A_obar_o z_hat_o)_j
            for k in range(r):
                a += A[j, k] * S[i, k]
            out[i, r + j] = fo[i, j] + gb[i, j] + a
        for m in range(p):
            g = 0.0  # (Gamma beta)_m
            for k in range(p):
                g += G[m, k] * be[i, k]
            out[i, n + m] = g * e


@njit(cache=True)
def gram_exact(buf: Array, M: Array, b: int) -> None:  # pragma: no cover - jit
    """``M[b]`` = :math:`\\sum v v^T` over every row of member ``b``'s ring ``buf[b]``,
    recomputed exactly (once a window)."""
    _, W, p = buf.shape
    for k in range(p):
        for m in range(p):
            s = 0.0
            for w in range(W):
                s += buf[b, w, k] * buf[b, w, m]
            M[b, k, m] = s


@njit(cache=True)
def gram_push(buf: Array, M: Array, v: Array, i: NDArray[np.int64],
              full: NDArray[np.bool_]) -> None:  # pragma: no cover - jit
    """Slide every member's excitation window by one sample: row ``i[b]`` of the ring ``buf``
    ``(B, W, p)`` leaves (if ``full[b]``) and ``v[b]`` ``(p,)`` enters; ``M`` ``(B, p, p)`` is
    the running :math:`\\sum v v^T` over the window. ``i`` and ``full`` (per member) advance;
    a member whose ring comes round (``i`` back to 0) recomputes its ``M`` exactly
    (:func:`gram_exact`), so that the running sum does not drift."""
    B, W, p = buf.shape
    for b in range(B):
        ib = i[b]
        for k in range(p):
            for m in range(p):
                if full[b]:
                    M[b, k, m] -= buf[b, ib, k] * buf[b, ib, m]
                M[b, k, m] += v[b, k] * v[b, m]
        for k in range(p):
            buf[b, ib, k] = v[b, k]
        ib += 1
        if ib == W:
            ib = 0
            full[b] = True
            gram_exact(buf, M, b)
        i[b] = ib


@njit(cache=True)
def min_eig_sym(M: Array, scale: float, out: Array) -> None:  # pragma: no cover - jit
    """``out[b]`` = the smallest eigenvalue of the symmetric ``scale * M[b]`` (``M``
    ``(B, p, p)``), by the Jacobi rotations of :func:`~hgo_mj.observers.bastin_gevers.sym_eigvals`
    (the excitation measure of paper 002, eq. 4.5, computed the same way); NaN for a
    non-finite matrix. A small ``p`` is a few rotations: no LAPACK call per member."""
    B, p, _ = M.shape
    A = np.empty((p, p))
    work = np.empty((p, p))
    ev = np.empty(p)
    for b in range(B):
        finite = True
        for i in range(p):
            for j in range(p):
                A[i, j] = scale * M[b, i, j]
                if not np.isfinite(A[i, j]):
                    finite = False
        if not finite:
            out[b] = np.nan
            continue
        sym_eigvals(A, work, ev)
        lo = ev[0]
        for i in range(1, p):
            lo = min(lo, ev[i])
        out[b] = lo


@register
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
    ``gamma_obar`` are evaluated once per sample (for a whole block of samples at once, on
    rows), ``f_obar`` at every stage of the RK4 (or Euler) integration; the arithmetic of
    eq. 27 is the kernel :func:`eq27`, one loop over the B members.

    State as data (:meth:`_init`): ``(B, n + p)`` rows ``(z_hat_o, z_hat_obar, theta_hat)``,
    the held auxiliary channels ``(B, a)`` and each member's excitation window. Parameters as
    data (:meth:`~hgo_mj.observers.base.Observer.parameters`): ``lam`` (``()`` per member) and
    ``gamma`` (``(p, p)`` per member), so one batch may hold many tunings.

    Parameters
    ----------
    system : System, optional
        A system that declares the ``"jo_son"`` form (``system.form("jo_son")``); not needed
        when ``form`` is given.
    form : JoSonForm, optional
        The canonical form eq. 10.
    lam : float
        :math:`\\lambda > 0` of eq. 25 (the paper's example: 2).
    gamma : float, array_like (p,) or (p, p)
        :math:`\\Gamma`, symmetric positive definite (the example: 5).
    outputs : tuple of int
        The channel of ``y``, a 1-tuple. The form's ``aux_outputs`` are read too (as known
        inputs appended to ``u``): :attr:`outputs` is ``(y channel, *aux_outputs)``, and a
        NaN in any of them is a dropout (the lost auxiliary channels hold their last value,
        0 before any).
    theta_hat0 : array_like (p,) or (B, p), optional
        Initial parameter estimate (default zero); :meth:`reset` takes one too.
    x_hat0, z_hat0 : array_like, optional
        Initial estimate in physical coordinates (needs ``from_physical``) or in the form's
        coordinates (default zero), used by a :meth:`reset` that is given neither.
    method : {"rk4", "euler"}
    substeps : int
        Integration steps per sample.
    excitation_window : float or None
        Window of the diagnostic ``excitation``: the smallest eigenvalue of
        :math:`\\int \\beta \\beta^T` over it (identifiability of :math:`\\theta`; the state
        estimate converges without it, Theorem 3.2). The window keeps the last
        ``round(window / dt)`` regressors of every member (``B W p`` floats); None drops the
        diagnostic (and its cost).
    on_unstable : {"raise", "warn", "ignore"}
        What :meth:`check_period` does at a period where the integration is unstable.

    Attributes
    ----------
    theta_hat_ : ndarray (p,) or (B, p)
    K_ : ndarray (r,)
        The gain of eq. 25.
    excitation_ : float or ndarray (B,)

    Raises
    ------
    DesignError
        Where the conditions of Corollary 3.3 fail (:func:`jo_son_gain`), Gamma is not
        symmetric positive definite, the system has no form, or the initial estimate lies where
        the inverse map :math:`T^{-1}` is undefined.

    Examples
    --------
    >>> from hgo_mj.systems.papers import JoSonExample
    >>> ob = JoSonObserver(JoSonExample(), lam=2.0, gamma=5.0)
    >>> ob.reset(batch=4)
    >>> ob.z_hat.shape, ob.theta_hat_.shape
    ((4, 3), (4, 1))

    Three values of :math:`\\lambda` as one batch, each member its own single run:

    >>> import numpy as np
    >>> params = ob.parameters(3, lam=[1.0, 2.0, 4.0])
    >>> state = ob.init(3, params=params)
    >>> state, rows = ob.step(params, state, np.full((3, 5, 1), 0.5), np.zeros((3, 5, 1)), 0.01)
    >>> rows.z_hat.shape, rows.diagnostics.shape
    ((3, 5, 3), (3, 5, 3))

    References
    ----------
    Paper 003, eq. 10, 25-27, Theorem 3.2, Corollary 3.3, Theorem 3.4.
    """

    name = "jo_son"
    required_form = ("jo_son", "the generalized observer canonical form with the SPR "
                              "conditions of paper 003 (eq. 10, 25-27)")
    summary = "Jo-Son adaptive observer on the generalized observer canonical form, SPR gain"
    reference = "paper 003 (Jo, Son 2004), eq. 10, 25, 27"
    needs_normal_form = False

    @classmethod
    def applicability(cls, system: System) -> str | None:
        """The base's form check, then Corollary 3.3's conditions on the system's form (with
        its default options): ``b_r > 0`` and ``b_r s^(r-1) + ... + b_1`` Hurwitz, under
        which the gain eq. 25 makes the error system SPR (eq. 26). A form that needs options
        to be built (e.g. the elastic joint's motor-side sensors) is left to construction."""
        reason = super().applicability(system)
        if reason is not None:
            return reason
        try:
            form = system.form("jo_son")
        except DesignError:
            return None
        try:
            jo_son_gain(form.b, 1.0)
        except DesignError as exc:
            return f"the SPR condition of paper 003 fails for its form: {exc}"
        return None

    def __init__(self, system: System | None = None, *, form: JoSonForm | None = None,
                 lam: float = 2.0, gamma: Any = 1.0, outputs: Any = (0,), theta_hat0: Any = None,
                 x_hat0: Any = None, z_hat0: Any = None, method: str = "rk4", substeps: int = 1,
                 excitation_window: float | None = 10.0, on_unstable: str = "raise") -> None:
        if system is not None and not isinstance(system, System):
            raise DesignError(f"system must be a System instance or None; found "
                              f"{type(system).__name__}")
        if form is None:
            if system is None:
                raise DesignError("JoSonObserver needs a system with a derived form or "
                                  "form=JoSonForm(...)")
            form = self._form_of(system)
        elif not isinstance(form, JoSonForm):
            raise DesignError(f"form must be a JoSonForm; found {type(form).__name__}")
        y_channel = check_outputs(outputs)
        if len(y_channel) != 1:
            raise DesignError(f"outputs of the Jo-Son observer is the channel of y, a 1-tuple "
                              f"(the form eq. 10 has one output; its aux_outputs "
                              f"{list(form.aux_outputs)} are read as known inputs); found "
                              f"{list(y_channel)}")
        self.form = form
        super().__init__(system, order=form.n, outputs=(*y_channel, *form.aux_outputs),
                         on_unstable=on_unstable)
        self.lam = finite_scalar("lambda", lam)
        self.K_ = jo_son_gain(form.b, self.lam)
        self.gamma = symmetric_matrix("gamma", gamma, form.p, dim="m")
        self.method = one_of("method", method, METHODS)
        self.substeps = positive_int("substeps", substeps)
        if excitation_window is not None:
            excitation_window = finite_scalar("excitation_window", excitation_window, positive=True)
        self.excitation_window = excitation_window
        # per instance: the names follow the form's parameters
        names = tuple(f"theta_{nm}" for nm in form.theta_names)
        self.family_diagnostics = names + (  # type: ignore[misc]
            ("excitation",) if excitation_window is not None else ())
        if x_hat0 is not None and z_hat0 is not None:
            raise DesignError("give x_hat0 or z_hat0, not both")
        #: the constructor's initial estimate (raw: a reset given none takes its batch from it)
        self._start = (x_hat0, z_hat0, theta_hat0)
        #: ``(K, Gamma)`` per parameters (:meth:`_gains`), at most :data:`GAIN_CACHE` kept
        self._gain_cache: dict[bytes, tuple[Array, Array]] = {}
        # check the initial estimate here, as a reset given none would read it: its shapes,
        # theta_hat0's, and T^-1 defined there (the state made is dropped)
        given = [batch_rows(nm, v, w, None) for nm, v, w in
                 (("x_hat0", x_hat0, len(self.state_names)), ("z_hat0", z_hat0, self.n))
                 if v is not None]
        self.init(given[0].shape[0] if given else 1)

    def _parameters(self) -> dict[str, Any]:
        """The tunable parameters: :math:`\\lambda` ``lam`` (a float; the gain ``K`` of eq. 25
        follows from it) and the adaptation gain :math:`\\Gamma` ``gamma`` ``(p, p)``."""
        return {"lam": self.lam, "gamma": self.gamma}

    def _check_parameter(self, name: str, value: Any) -> Array:
        if name == "lam":  # Corollary 3.3: lambda > 0 (b is the form's, checked already)
            lam = finite_scalar("lambda", value)
            jo_son_gain(self.form.b, lam)
            return np.array(lam)
        return symmetric_matrix("gamma", value, self.form.p, dim="m")

    def _gains(self, p: Params) -> tuple[Array, Array]:
        """``K`` (eq. 25) and :math:`\\Gamma` of the parameters ``p`` (one member's), as the
        kernel reads them."""
        key = p.key()
        gains = self._gain_cache.get(key)
        if gains is None:
            gains = (jo_son_gain(self.form.b, float(p.lam)),
                     np.array(p.gamma, dtype=np.float64, order="C"))
            if len(self._gain_cache) >= GAIN_CACHE:
                del self._gain_cache[next(iter(self._gain_cache))]
            self._gain_cache[key] = gains
        return gains

    @staticmethod
    def _form_of(system: System) -> JoSonForm:
        """``system.form("jo_son")``, or an error naming what is missing."""
        if "jo_son" not in system.forms:
            raise DesignError(
                f"the Jo-Son observer needs the adaptive observer canonical form of paper 003, "
                f"eq. 10 (b, gamma_o, beta, and f_obar for an unobservable part); "
                f"{type(system).__name__} provides none (its forms: {list(system.forms)}; a "
                f"system declares forms = (..., 'jo_son') and _form_jo_son()); see "
                f"docs/adaptive_canonical_forms.md")
        form = system.form("jo_son")
        if not isinstance(form, JoSonForm):
            raise DesignError(f"{type(system).__name__}.form('jo_son') must return a JoSonForm; "
                              f"found {type(form).__name__}")
        return form

    @property
    def state_names(self) -> tuple[str, ...]:
        return self.form.state_names

    # ------------------------------------------------------------------ state
    def reset(self, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None,
              batch: int | None = None, params: Params | None = None,
              theta_hat0: Any = None) -> None:
        """Restart the observer's own state (:meth:`Observer.reset`) from ``x_hat0`` /
        ``z_hat0`` (neither: the constructor's) and ``theta_hat0`` (``(p,)`` or ``(B, p)``;
        default: the constructor's, else zero).

        Raises
        ------
        DesignError
            ``x_hat0`` given for a form without ``from_physical``, or an initial estimate where
            the inverse map :math:`T^{-1}` is undefined (non-finite), naming the member.
        """
        if x_hat0 is None and z_hat0 is None:
            x_hat0, z_hat0 = self._start[0], self._start[1]
        super().reset(x_hat0, z_hat0=z_hat0, u0=u0, batch=batch, params=params)
        if theta_hat0 is not None:
            s = self.state
            s.S[:, self.form.n:] = batch_rows("theta_hat0", theta_hat0, self.form.p, s.batch)

    def _init(self, p: Params, x0: Array | None, z0: Array | None,
              u0: Array) -> dict[str, Any]:
        """The state of ``len(u0)`` members: ``S`` ``(B, n + p)`` the rows
        ``(z_hat, theta_hat)``, ``x_held`` :math:`T^{-1}(\\hat z)`, ``aux_last`` the held
        auxiliary channels ``(B, a)``, and with an excitation window its ring ``gram_buf``
        ``(B, W, p)`` (``W = 1`` until a period gives it its length: :meth:`_step_checked`),
        its running sum ``gram_M`` ``(B, p, p)``, next row ``gram_i``, whether it is full
        ``gram_full``, the period it was kept at ``gram_dt`` (NaN: none yet) and its smallest
        eigenvalue ``excitation``, each ``(B,)``."""
        f, B = self.form, u0.shape[0]
        ix, iz, ith = self._start
        if x0 is None and z0 is None:
            x0 = None if ix is None else batch_rows("x_hat0", ix, len(self.state_names), B)
            z0 = None if iz is None else batch_rows("z_hat0", iz, f.n, B)
        th = np.zeros((B, f.p)) if ith is None else batch_rows("theta_hat0", ith, f.p, B)
        if x0 is not None:
            z = f.normal_rows(x0)
            if not np.all(np.isfinite(z)):
                raise DesignError(f"T(x_hat0) of {f.label} must be finite; found {z.tolist()}")
        else:
            z = z0 if z0 is not None else np.zeros((B, f.n))
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            x = f.physical_rows(z)
        bad = np.flatnonzero(~np.all(np.isfinite(x), axis=1))
        if bad.size:
            b = int(bad[0])
            who = f" (member {b})" if B > 1 else ""
            raise DesignError(f"the initial estimate z = {z[b].tolist()}{who} lies where the "
                              f"inverse map T^-1 of {f.label} is undefined (it gives "
                              f"{x[b].tolist()}); give x_hat0 / z_hat0 inside its domain")
        fields: dict[str, Any] = {
            "S": np.ascontiguousarray(np.concatenate((z, th), axis=1)),
            "x_held": np.array(x, dtype=np.float64),
            "aux_last": np.zeros((B, len(f.aux_outputs)))}
        if self.excitation_window is not None:
            fields.update(gram_buf=np.zeros((B, 1, f.p)), gram_M=np.zeros((B, f.p, f.p)),
                          gram_i=np.zeros(B, dtype=np.int64),
                          gram_full=np.zeros(B, dtype=np.bool_),
                          gram_dt=np.full(B, math.nan), excitation=np.zeros(B))
        return fields

    # ------------------------------------------------------------------ dynamics
    def signals(self, y: Any, u: Any) -> tuple[Array, Array, Array]:
        """:math:`\\gamma_o(y, u)` ``(N, r)``, :math:`\\beta(y, u)` ``(N, p)`` and
        :math:`\\gamma_{\\bar o}(y, u)` ``(N, n - r)`` of the rows ``y`` ``(N,)``, ``u``
        ``(N, m + a)`` (``u`` with the ``aux_outputs`` channels appended).

        Parameters
        ----------
        y : array_like
            Measurements ``(N,)``.
        u : array_like
            Inputs ``(N, m + a)``.

        Returns
        -------
        gamma_o : (N, r) ndarray
        beta : (N, p) ndarray
        gamma_obar : (N, n - r) ndarray

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems.papers import JoSonExample
        >>> ob = JoSonObserver(JoSonExample(), lam=2.0, gamma=5.0)
        >>> [a.shape for a in ob.signals(np.array([0.5, 1.0]), np.zeros((2, 1)))]
        [(2, 2), (2, 1), (2, 1)]
        """
        return self.form.signals(np.asarray(y, dtype=float), np.asarray(u, dtype=float))

    def _eq27(self, S: Array, y: Array, c: Array, go: Array, be: Array, gb: Array, K: Array,
              G: Array, out: Array) -> Array:
        """:func:`eq27` at the rows ``S`` with the held signals and the gains ``K``, ``G``
        (:math:`\\Gamma`) into ``out`` (``f_obar`` evaluated here, at ``S``)."""
        f = self.form
        fo = f.f_obar_rows(y, S[:, f.r:f.n]) if f.n_obar else gb
        eq27(S, y, c, go, be, fo, gb, K, f.b, f.A_obar_o, G, f.r, out)
        return out

    def rhs(self, S: Any, y: Any, u: Any, c: Any = 1.0) -> Array:
        """Right-hand side of eq. 27 at the rows ``S`` ``(N, n + p)`` ``= (z_hat, theta_hat)``
        with ``y`` ``(N,)`` and ``u`` ``(N, m + a)``: the same arithmetic as the sampled
        update (with the constructor's gains), for continuous-time checks. ``c = 0`` drops the
        output injection.

        Parameters
        ----------
        S : array_like
            Rows ``(N, n + p)``: the estimate and the parameter estimate.
        y : array_like
            Measurements ``(N,)``.
        u : array_like
            Inputs ``(N, m + a)``.
        c : float or array_like, default 1.0
            Weight of the output injection, per row (1: corrected, 0: a dropout).

        Returns
        -------
        (N, n + p) ndarray
            The time derivative of the rows.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems.papers import JoSonExample
        >>> ob = JoSonObserver(JoSonExample(), lam=2.0, gamma=5.0)
        >>> ob.rhs(np.zeros((2, 4)), [0.5, 1.0], np.zeros((2, 1))).round(3)
        array([[ 1.969,  1.833, -0.064,  0.   ],
               [ 3.   ,  2.667,  0.375,  0.   ]])
        """
        S = np.ascontiguousarray(S, dtype=float)
        y = np.ascontiguousarray(y, dtype=float)
        go, be, gb = self.signals(y, u)
        cc = np.ascontiguousarray(np.broadcast_to(np.asarray(c, dtype=float), y.shape))
        return self._eq27(S, y, cc, go, be, gb, self.K_, self.gamma, np.empty_like(S))

    def _integrate(self, S: Array, y: Array, c: Array, go: Array, be: Array, gb: Array,
                   K: Array, G: Array, h: float) -> Array:
        """``substeps`` steps of RK4 (or Euler) of eq. 27 over ``h`` each, the signals held
        (:func:`~hgo_mj.observers._integrate.rk4`, :func:`~hgo_mj.observers._integrate.euler`
        over the batch). Returns a new array."""
        step = euler if self.method == "euler" else rk4

        def f(V: Array) -> Array:
            return self._eq27(V, y, c, go, be, gb, K, G, np.empty_like(V))

        for _ in range(self.substeps):
            S = step(f, S, h)
        return S

    def _window(self, s: State, dt: float) -> None:
        """Give the excitation window its length ``round(window / dt)`` at the period ``dt``:
        a member whose window was kept at another period (or at none yet, ``gram_dt`` NaN)
        starts a new, empty one. Before the members are grouped by their parameters
        (:meth:`_step_checked`): the ring's length is one for the whole state."""
        new = s.gram_dt != dt
        if not new.any():
            return
        W = max(1, int(round(self.excitation_window / dt)))  # type: ignore[operator]
        if s.gram_buf.shape[1] != W:
            s.gram_buf = np.zeros((s.batch, W, self.form.p))
            new[:] = True
        else:
            s.gram_buf[new] = 0.0
        s.gram_M[new] = 0.0
        s.gram_i[new] = 0
        s.gram_full[new] = False
        s.gram_dt[new] = dt

    def _excite(self, s: State, be: Array, dt: float) -> None:
        """Add the regressors ``be`` ``(B, p)`` of one sample to each member's excitation
        window and update its smallest eigenvalue."""
        gram_push(s.gram_buf, s.gram_M, be, s.gram_i, s.gram_full)
        if be.shape[1] == 1:
            s.excitation = s.gram_M[:, 0, 0] * dt
            return
        exc = np.empty(be.shape[0])
        min_eig_sym(s.gram_M, dt, exc)
        s.excitation = exc

    # ------------------------------------------------------------------ interface
    def _check_period(self, p: Params, dt: float) -> None:
        """Check the sample period against the integration of the observer's linear modes
        (the roots of :math:`(s + \\lambda)(b_r s^{r-1} + \\dots + b_1)`, eq. 26) and react as
        ``on_unstable`` says."""
        b = self.form.b
        lam_ = np.concatenate(([-float(p.lam)], np.roots(b[::-1]) if b.size > 1 else []))
        try:
            check_rk_period("the Jo-Son observer", lam_, dt, self.method, self.substeps)
        except DesignError as exc:
            if self.on_unstable == "raise":
                raise
            if self.on_unstable == "warn":
                warnings.warn(str(exc), RuntimeWarning, stacklevel=3)

    def _prepare(self, s: State, dt: float) -> None:
        """The excitation window given its length at ``dt`` for the whole state
        (:meth:`_window`)."""
        if self.excitation_window is not None:
            self._window(s, dt)

    def _step(self, p: Params, s: State, Y: Array, U: Array, dt: float, X: Array, Z: Array,
              D: Array) -> None:
        # floating-point warnings are silenced over the block: a blown-up state raises
        # DivergenceError below, an undefined inverse map is counted (inverse_failures_)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            S = self._samples(p, s, Y, U, dt, Z, D)
            if not np.isfinite(S).all():
                self._diverged(Z, D)
            s.S = S
            self._physical(s, Z, X)

    def _samples(self, p: Params, s: State, Y: Array, U: Array, dt: float, Z: Array,
                 D: Array) -> Array:
        """Integrate eq. 27 over the T samples of the block; return the final ``S`` (the
        state's own is left as it was until the block is checked)."""
        f = self.form
        B, T = Y.shape[0], Y.shape[1]
        r, n, np_, a = f.r, f.n, f.p, len(f.aux_outputs)
        K, G = self._gains(p)
        lost = np.asarray(np.isnan(Y).any(axis=2)).T  # (T, B): y or an aux channel lost
        yT = np.ascontiguousarray(Y[:, :, 0].T)  # (T, B): sample-major, each sample contiguous
        UU = np.ascontiguousarray(U.transpose(1, 0, 2))  # (T, B, m)
        if a:  # known inputs: the auxiliary channels, lost ones held (0 before any)
            aux = Y[:, :, 1:].transpose(1, 0, 2).copy()
            last = s.aux_last
            for j in range(T):
                aux[j] = np.where(np.isnan(aux[j]), last, aux[j])
                last = aux[j]
            s.aux_last = last.copy()
            UU = np.concatenate((UU, aux), axis=2)
        # the held signals of eq. 27 at the measured y, the whole block at once
        go, be, gb = (v.reshape(T, B, -1) for v in
                      self.signals(yT.reshape(T * B), UU.reshape(T * B, -1)))
        c = np.where(lost, 0.0, 1.0)
        h = dt / self.substeps
        S = s.S
        window = self.excitation_window is not None
        for j in range(T):
            y = yT[j]
            if lost[j].any():  # a dropout: the signals at the predicted output z_hat_r
                m = lost[j]
                y[m] = S[m, r - 1]
                go[j][m], be[j][m], gb[j][m] = self.signals(y[m], UU[j][m])
            if window:
                self._excite(s, be[j], dt)
            S = self._integrate(S, y, c[j], go[j], be[j], gb[j], K, G, h)
            Z[:, j] = S[:, :n]
            D[:, j, :np_] = S[:, n:]
            if window:
                D[:, j, np_] = s.excitation
        return S

    def _diverged(self, Z: Array, D: Array) -> None:
        """Raise :class:`DivergenceError` naming the first sample and member whose state left
        the finite numbers."""
        n = self.form.n
        bad = ~np.asarray(np.isfinite(Z).all(axis=2) & np.isfinite(D[:, :, :self.form.p]).all(axis=2))
        j = int(np.flatnonzero(bad.any(axis=0))[0])
        m = int(np.flatnonzero(bad[:, j])[0])
        state = np.concatenate((Z[m, j], D[m, j, :self.form.p]))
        raise DivergenceError(f"the Jo-Son observer left the finite numbers: state "
                              f"(z_hat, theta_hat) = {state.tolist()} (member {m}, sample {j}; "
                              f"n = {n})")

    def _physical(self, s: State, Z: Array, X: Array) -> None:
        """``X`` = :math:`T^{-1}(\\hat z)` of the rows ``Z`` ``(B, T, n)``; where the map is
        undefined (non-finite) the member holds its last valid value (``x_held``), counted in
        the state's ``inverse_failures``."""
        B, T, n = Z.shape
        if T == 0:
            return
        Xf = self.form.physical_rows(Z.reshape(B * T, n)).reshape(B, T, -1)
        ok = np.asarray(np.isfinite(Xf).all(axis=2))
        if ok.all():
            X[...] = Xf
            s.x_held = Xf[:, -1].copy()
            return
        for b in range(B):
            held = s.x_held[b]
            for j in range(T):
                if ok[b, j]:
                    held = Xf[b, j]
                else:
                    s.inverse_failures[b] += 1
                X[b, j] = held
            s.x_held[b] = held

    def _current(self, p: Params, s: State) -> tuple[Array, Array, Array]:
        n = self.form.n
        d = s.S[:, n:]
        if self.excitation_window is not None:
            d = np.concatenate((d, s.excitation[:, None]), axis=1)
        return s.x_held.copy(), s.S[:, :n].copy(), d.copy()

    # ------------------------------------------------------------------ estimates
    @property
    def theta_hat_(self) -> Any:
        """:math:`\\hat\\theta` of the observer's own state, ``(p,)`` or ``(B, p)``."""
        return self._public(self.state.S[:, self.form.n:].copy())

    @property
    def excitation_(self) -> Any:
        """The smallest eigenvalue of the excitation window (NaN without one)."""
        if self.excitation_window is None:
            return self._public(np.full(self.batch, math.nan))
        return self._public(self.state.excitation.copy())

    def params(self) -> dict[str, Any]:
        f = self.form
        return {"form": f.label, "r": f.r, "n": f.n, "b": f.b.tolist(), "lambda": self.lam,
                "K": self.K_.tolist(), "gamma": self.gamma.tolist(),
                "theta_names": list(f.theta_names), "outputs": list(self.outputs),
                "aux_outputs": list(f.aux_outputs), "method": self.method,
                "substeps": self.substeps, "excitation_window": self.excitation_window,
                "on_unstable": self.on_unstable}
