"""Gain design as pure functions (testable alone), from [000]_ and [004]_.

References
----------
.. [000] E. Bullinger, A. Ilchmann, F. Allgöwer, "A simple adaptive observer for nonlinear
   systems", NOLCOS 1998 (``shared/papers/000_*``), eq. 2, 3, 6.
.. [004] S. Ibrir, "On observer design for nonlinear systems", Int. J. Control, 2007
   (``shared/papers/004_*``): Riccati design (eq. 5-10, 17), LMI sampling bounds (eq. 62-65).
"""

from __future__ import annotations

from math import comb
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._extras import require
from ._validate import finite_scalar, vector
from .exceptions import DesignError, DimensionError

Array = NDArray[np.float64]

__all__ = ["binomial_coefficients", "bullinger_theorem3_bound", "check_hurwitz",
           "check_riccati_alpha", "hgo_gains", "lipschitz_condition", "max_sampling_period",
           "min_gamma", "observer_matrix", "riccati_P", "riccati_Q", "riccati_gains",
           "riccati_weights", "riccati_weights_as_printed", "sampling_lmi_62", "sampling_lmi_63"]


def binomial_coefficients(n: int) -> Array:
    """``p_i = C(n, i)``: the polynomial ``(s + 1)^n``, all observer poles at ``-k`` (paper 000, eq. 3).

    Parameters
    ----------
    n : int
        The order, >= 1.

    Returns
    -------
    (n,) ndarray
        ``p_1 .. p_n``.

    Raises
    ------
    DesignError
        ``n`` not a positive integer.

    Examples
    --------
    >>> binomial_coefficients(3)
    array([3., 3., 1.])
    """
    if int(n) != n or n < 1:
        raise DesignError(f"order n must be a positive integer; found {n!r}")
    return np.array([comb(int(n), i) for i in range(1, int(n) + 1)], dtype=float)


def check_hurwitz(p: Any, name: str = "p") -> Array:
    """Validate that ``s^n + p_1 s^(n-1) + ... + p_n`` is Hurwitz and return ``p`` as an array.

    Parameters
    ----------
    p : array_like, shape (n,)
        The coefficients ``p_1 .. p_n``.
    name : str, default "p"
        The parameter's name, for the messages.

    Returns
    -------
    (n,) ndarray
        ``p`` as floats.

    Raises
    ------
    DesignError
        If a root has a non-negative real part; the message lists the offending roots; or
        ``p`` is empty or not finite.

    Examples
    --------
    >>> check_hurwitz([2.0, 1.0])
    array([2., 1.])
    >>> check_hurwitz([-1.0, 1.0])
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: p must give a Hurwitz polynomial ... have non-negative real part
    """
    p = vector(name, p)
    if p.size == 0:
        raise DesignError(f"{name} must hold at least one coefficient; found none")
    roots = np.roots(np.concatenate(([1.0], p)))
    bad = roots[roots.real >= 0]
    if bad.size:
        shown = ", ".join(f"{r:.4g}" for r in bad)
        raise DesignError(f"{name} must give a Hurwitz polynomial s^n + p_1 s^(n-1) + ... + p_n; "
                          f"roots [{shown}] have non-negative real part")
    return p


def hgo_gains(p: Any, k: float) -> Array:
    """Output-injection gains ``L_i = p_i k^i`` of the high-gain observer (paper 000, eq. 2).

    .. math:: \\dot{\\hat x}_i = \\hat x_{i+1} + p_i k^i (y - \\hat x_1)

    Parameters
    ----------
    p : array_like, shape (n,)
        Coefficients of a Hurwitz polynomial ``s^n + p_1 s^{n-1} + ... + p_n``.
    k : float
        High-gain parameter, ``k > 0``; the observer poles are ``k`` times the roots of ``p``.

    Returns
    -------
    (n,) ndarray
        ``L = (p_1 k, p_2 k^2, ..., p_n k^n)``.

    Raises
    ------
    DesignError
        ``p`` not Hurwitz, ``k`` not positive, or gains that overflow the floats.

    Examples
    --------
    >>> hgo_gains([2.0, 1.0], k=10.0)
    array([ 20., 100.])
    """
    p = check_hurwitz(p)
    k = finite_scalar("k", k, positive=True)
    with np.errstate(over="ignore"):
        L = p * k ** np.arange(1, p.size + 1)
    if not np.all(np.isfinite(L)):
        raise DesignError(f"k = {k:g} is too large: the gains p_i k^i (i = 1..{p.size}) overflow "
                          f"the floats; found {L.tolist()}")
    return L


def observer_matrix(p: Any, k: float) -> Array:
    """The error-dynamics matrix ``A_k = A - L C`` (paper 000, eq. 6: ``A_k = k K Abar K^-1``).

    Parameters
    ----------
    p : array_like, shape (n,)
        Hurwitz coefficients.
    k : float
        High-gain parameter, > 0.

    Returns
    -------
    (n, n) ndarray
        The chain of integrators with ``-L`` (:func:`hgo_gains`) in its first column.

    Examples
    --------
    >>> observer_matrix([2.0, 1.0], k=10.0)
    array([[ -20.,    1.],
           [-100.,    0.]])
    """
    L = hgo_gains(p, k)
    n = L.size
    A = np.diag(np.ones(n - 1), 1)
    A[:, 0] -= L
    return A


# ---------------------------------------------------------------------------------------------
# Paper 004 (Ibrir 2007): Riccati-based high-gain observer, Lipschitz condition, LMI bounds
# ---------------------------------------------------------------------------------------------

def _chain(n: int) -> tuple[Array, Array]:
    """``A`` (the shift, ones on the superdiagonal) and ``C = e_1'`` of eq. 7."""
    A = np.diag(np.ones(n - 1), 1)
    C = np.zeros((1, n))
    C[0, 0] = 1.0
    return A, C


def riccati_weights(alpha: Any) -> Array:
    """Diagonal weights ``q_ii(1)`` of ``Q(gamma)`` that make the ARE's gain ``(alpha_i gamma^i)``.

    .. math::

        \\tilde q_i = \\alpha_i^2 + 2 \\sum_{l=1}^{i} (-1)^l \\alpha_{i+l} \\alpha_{i-l},
        \\qquad \\alpha_0 = 1, \\quad \\alpha_k = 0 \\text{ for } k < 0 \\text{ or } k > n,

    i.e. ``q_11 = alpha_1^2 - 2 alpha_2``, ``q_22 = alpha_2^2 - 2 alpha_3 alpha_1 + 2 alpha_4``,
    ..., ``q_nn = alpha_n^2``; ``Q(gamma) = diag(q_i gamma^(2i))``. Equivalently
    ``(-1)^(n-i) q_i`` is the coefficient of ``s^(2(n-i))`` in ``p(s) p(-s)``, ``p`` the
    polynomial (9).

    This is eq. 17 of the paper (the proof of Lemma 4). **Correction:** eq. 8 (and condition
    (10), which repeats its bracket) prints the sum as
    :math:`\\sum_{k=i}^{n-1} (-1)^{k+i-1} \\alpha_{k+1} \\alpha_{k-1}`, whose products are not
    symmetric about ``i``; it agrees with eq. 17 only for ``n <= 3`` and even contradicts eq. 8's
    own line for ``q_11`` when ``n >= 3``. With the printed weights the Riccati gain is not
    ``(alpha_i gamma^i)`` (``alpha = (4, 6, 4, 1)``: printed ``q_22 = 16``, the gain becomes
    ``(4.27, 7.10, 4.27, 1)``). :func:`riccati_weights_as_printed` evaluates the printed form.

    Parameters
    ----------
    alpha : array_like, shape (n,)
        The coefficients ``alpha_1 .. alpha_n`` of (9).

    Returns
    -------
    (n,) ndarray
        ``q_1 .. q_n`` (the weights at ``gamma = 1``).

    References
    ----------
    Paper 004 (Ibrir 2007), eq. 8, 10, 17 (Lemma 4).

    Examples
    --------
    >>> riccati_weights([4, 6, 4, 1])
    array([4., 6., 4., 1.])
    """
    a = vector("alpha", alpha)
    n = a.size
    ext = np.concatenate(([1.0], a, np.zeros(n + 1)))  # ext[k] = alpha_k for 0 <= k <= 2n+1
    return np.array([ext[i] ** 2 + 2.0 * sum((-1) ** l * ext[i + l] * ext[i - l]
                                             for l in range(1, i + 1))
                     for i in range(1, n + 1)])


def riccati_weights_as_printed(alpha: Any) -> Array:
    """``q_ii(1)`` exactly as eq. 8 of paper 004 prints them (for reports; wrong for ``n >= 4``).

    .. math::

        q_{1,1} = \\alpha_1^2 - 2\\alpha_2\\alpha_0, \\quad
        q_{i,i} = \\alpha_i^2 + 2 \\sum_{k=i}^{n-1} (-1)^{k+i-1} \\alpha_{k+1}\\alpha_{k-1}
        \\ (2 \\le i \\le n-1), \\quad q_{n,n} = \\alpha_n^2.

    See :func:`riccati_weights` for the correct weights (eq. 17).

    Parameters
    ----------
    alpha : array_like, shape (n,)
        The coefficients ``alpha_1 .. alpha_n`` of (9).

    Returns
    -------
    (n,) ndarray
        The printed ``q_ii(1)``.

    Examples
    --------
    >>> riccati_weights_as_printed([4, 6, 4, 1])    # q_22 = 16, not 6 (eq. 17)
    array([ 4., 16.,  4.,  1.])
    """
    a = vector("alpha", alpha)
    n = a.size
    ext = np.concatenate(([1.0], a, [0.0]))
    out = []
    for i in range(1, n + 1):
        if i == 1:
            out.append(ext[1] ** 2 - 2.0 * ext[2] * ext[0] if n > 1 else ext[1] ** 2)
        elif i == n:
            out.append(ext[n] ** 2)
        else:
            out.append(ext[i] ** 2 + 2.0 * sum((-1) ** (k + i - 1) * ext[k + 1] * ext[k - 1]
                                               for k in range(i, n)))
    return np.array(out)


def check_riccati_alpha(alpha: Any, name: str = "alpha") -> Array:
    """Validate ``alpha`` for the Riccati design: (9) Hurwitz and condition (10) ``q_i > 0``.

    Condition (10) is checked in its corrected form, the positivity of the weights of eq. 17
    (:func:`riccati_weights`): ``Q(gamma) > 0``, which Lemma 3 needs.

    Parameters
    ----------
    alpha : array_like, shape (n,)
        The coefficients ``alpha_1 .. alpha_n``.
    name : str, default "alpha"
        The parameter's name, for the messages.

    Returns
    -------
    (n,) ndarray
        ``alpha`` as floats.

    Raises
    ------
    DesignError
        Roots of (9) with non-negative real part (listed), or weights ``q_i <= 0`` (listed).

    References
    ----------
    Paper 004 (Ibrir 2007), eq. 9, 10, 17.

    Examples
    --------
    >>> check_riccati_alpha([2.0, 1.0])
    array([2., 1.])
    """
    a = check_hurwitz(alpha, name)
    q = riccati_weights(a)
    bad = [f"q_{i + 1} = {v:.6g}" for i, v in enumerate(q) if not v > 0]
    if bad:
        raise DesignError(f"{name} = {a.tolist()} violates condition (10) of paper 004: the weights "
                          f"q_i = alpha_i^2 + 2 sum_l (-1)^l alpha_(i+l) alpha_(i-l) must be > 0 "
                          f"(Q(gamma) > 0); found {', '.join(bad)}")
    return a


def riccati_Q(alpha: Any, gamma: float) -> Array:
    """``Q(gamma) = diag(q_i gamma^(2i))`` of eq. 8 (weights of eq. 17, see :func:`riccati_weights`).

    Parameters
    ----------
    alpha : array_like, shape (n,)
        Hurwitz coefficients meeting condition (10).
    gamma : float
        High-gain parameter, > 0.

    Returns
    -------
    (n, n) ndarray
        The diagonal weight matrix.

    References
    ----------
    Paper 004 (Ibrir 2007), eq. 8, 17.

    Examples
    --------
    >>> riccati_Q([2.0, 1.0], gamma=10.0)
    array([[  200.,     0.],
           [    0., 10000.]])
    """
    a = check_riccati_alpha(alpha)
    g = finite_scalar("gamma", gamma, positive=True)
    return np.diag(riccati_weights(a) * g ** (2.0 * np.arange(1, a.size + 1)))


def riccati_P(alpha: Any, gamma: float, *, scaled: bool = True) -> Array:
    """Solution ``P(gamma) > 0`` of the algebraic Riccati equation of Theorem 1 (eq. 6).

    .. math:: A P + P A' - P C' C P + Q(\\gamma) = 0

    with ``A``, ``C`` of eq. 7 and ``Q`` of :func:`riccati_Q`, solved numerically
    (``scipy.linalg.solve_continuous_are``, the stabilising solution).

    Parameters
    ----------
    alpha : array_like, shape (n,)
        Hurwitz coefficients meeting condition (10).
    gamma : float
        High-gain parameter, ``> 0``.
    scaled : bool
        ``True`` (default): solve the ARE at ``gamma = 1`` and map its solution by the
        congruence ``P(gamma) = D P(1) D / gamma``, ``D = diag(gamma, ..., gamma^n)``: with
        ``A D = gamma D A``, ``C D = gamma C`` and ``Q(gamma) = D Q(1) D`` the ARE at ``gamma``
        is ``D (ARE at 1) D``, exactly (eq. 20, 46). Well conditioned for any ``gamma``.
        ``False``: solve the ARE at ``gamma`` directly (entries spanning ``gamma`` to
        ``gamma^(2n-1)``).

    Returns
    -------
    (n, n) ndarray
        The symmetric positive definite ``P(gamma)``.

    Raises
    ------
    DesignError
        If ``alpha`` fails :func:`check_riccati_alpha` or the solver fails (the solver's message
        and the residual are given).

    References
    ----------
    Paper 004 (Ibrir 2007), Theorem 1 (eq. 6-8), Lemma 4 (eq. 15-21), eq. 46.

    Examples
    --------
    >>> riccati_P([2.0, 1.0], gamma=10.0).round(6)
    array([[  20.,  100.],
           [ 100., 2000.]])
    """
    from scipy.linalg import solve_continuous_are

    a = check_riccati_alpha(alpha)
    g = finite_scalar("gamma", gamma, positive=True)
    n = a.size
    A, C = _chain(n)
    Qs = np.diag(riccati_weights(a)) if scaled else riccati_Q(a, g)
    try:
        P = solve_continuous_are(A.T, C.T, Qs, np.eye(1))
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise DesignError(f"the Riccati equation of paper 004 (eq. 6) has no stabilising solution "
                          f"for alpha = {a.tolist()}, gamma = {g:g}: {exc}") from None
    res = A @ P + P @ A.T - P @ C.T @ C @ P + Qs
    if not np.all(np.isfinite(P)) or np.abs(res).max() > 1e-8 * max(1.0, np.abs(Qs).max()):
        raise DesignError(f"the Riccati solution for alpha = {a.tolist()}, gamma = {g:g} is "
                          f"inaccurate: residual {np.abs(res).max():.3g}")
    if scaled:
        D = g ** np.arange(1, n + 1)
        P = D[:, None] * P * D[None, :] / g
    return 0.5 * (P + P.T)


def riccati_gains(alpha: Any, gamma: float, *, scaled: bool = True) -> Array:
    """Observer gain ``P(gamma) C'`` from the Riccati solution (Lemma 4: equals ``(alpha_i gamma^i)``).

    .. math::

        P(\\gamma) C' = (\\alpha_1 \\gamma, \\alpha_2 \\gamma^2, \\dots, \\alpha_n \\gamma^n)'

    Computed as the first column of :func:`riccati_P`, not from the closed form; the closed
    form is what Lemma 4 proves and what the tests hold it against.

    Parameters
    ----------
    alpha : array_like, shape (n,)
        Hurwitz coefficients meeting condition (10).
    gamma : float
        High-gain parameter, > 0.
    scaled : bool, default True
        As :func:`riccati_P`.

    Returns
    -------
    (n,) ndarray
        The gain ``P(gamma) C'``.

    References
    ----------
    Paper 004 (Ibrir 2007), Theorem 1 (eq. 6), Lemma 4 (eq. 15).

    Examples
    --------
    >>> riccati_gains([2.0, 1.0], gamma=10.0).round(6)     # (alpha_1 gamma, alpha_2 gamma^2)
    array([ 20., 100.])
    """
    return riccati_P(alpha, gamma, scaled=scaled)[:, 0].copy()


def _condition5_parts(alpha: Array) -> tuple[Array, float, float]:
    """The ``gamma``-free parts of condition (5): ``P(1)``, ``lambda_min(P(1)^-1 Q(1))`` and
    ``(P(1)^-1)_nn`` (see :func:`_condition5_sides`)."""
    P1 = riccati_P(alpha, 1.0)  # the ARE once, at gamma = 1 (well conditioned)
    w, V = np.linalg.eigh(P1)
    if not w.min() > 0:
        raise DesignError(f"P(1) is not positive definite (eigenvalues {w.tolist()})")
    P1_inv = (V / w) @ V.T
    sq = np.sqrt(riccati_weights(alpha))
    # P(1)^-1 Q(1) is similar to the symmetric Q(1)^1/2 P(1)^-1 Q(1)^1/2 (Q(1) diagonal, > 0)
    lam1 = float(np.linalg.eigvalsh(sq[:, None] * P1_inv * sq[None, :]).min())
    return P1, lam1, float(P1_inv[-1, -1])


def _condition5_sides(parts: tuple[Array, float, float], gamma: float) -> tuple[float, float]:
    """``lambda_min(P^-1/2 Q P^-1/2)`` and ``2 sqrt((P^-1)_nn lambda_max(P))`` of eq. 5 at
    ``gamma``, evaluated in rescaled coordinates (no matrix with ``gamma``-graded entries).

    With eq. 20, ``P(gamma)_ij = P(1)_ij gamma^(i+j-1)``, i.e. ``P(gamma) = gamma S P(1) S``
    with ``S = diag(1, gamma, ..., gamma^(n-1))`` (``S = Delta_gamma^-1``), and
    ``Q(gamma) = gamma^2 S Q(1) S``:

    * ``P(gamma)^-1 Q(gamma) = gamma S^-1 P(1)^-1 Q(1) S`` is similar to
      ``gamma P(1)^-1 Q(1)``: ``lambda_min = gamma lambda_min(P(1)^-1 Q(1))``, exactly;
    * ``(P(gamma)^-1)_nn = gamma^(1-2n) (P(1)^-1)_nn`` (eq. 25);
    * ``lambda_max(P(gamma)) = gamma lambda_max(S P(1) S)``, taken as
      ``gamma^(2n-1) lambda_max(E P(1) E)``, ``E = diag(gamma^(i-n))``, for ``gamma >= 1``
      (entries of ``E P(1) E`` at most those of ``P(1)``), so the denominator is
      ``2 sqrt((P(1)^-1)_nn lambda_max(E P(1) E))``, free of ``gamma`` powers; for
      ``gamma < 1`` the same with ``S`` (entries at most those of ``P(1)``) and the factor
      ``gamma^(1-n)`` outside the root.

    The largest eigenvalue of a symmetric matrix is computed to a small relative error
    whatever its grading; the other two quantities involve only ``P(1)``, whose condition
    number is small (205 for ``n = 6``, binomial ``alpha``).
    """
    P1, lam1, pnn1 = parts
    n = P1.shape[0]
    i = np.arange(1, n + 1, dtype=float)
    if gamma >= 1.0:
        E = gamma ** (i - n)
        factor = 1.0
    else:
        E = gamma ** (i - 1.0)
        factor = gamma ** (1.0 - n)
    lam_max = float(np.linalg.eigvalsh(E[:, None] * P1 * E[None, :]).max())
    return gamma * lam1, 2.0 * factor * float(np.sqrt(pnn1 * lam_max))


def lipschitz_condition(alpha: Any, gamma: float, rho: float | None = None) -> dict[str, Any]:
    """The two sides of the Lipschitz condition (5) of Theorem 1.

    .. math::

        \\rho \\le \\frac{\\lambda_{\\min}\\big(P^{-1/2} Q P^{-1/2}\\big)}
                         {2 \\sqrt{\\bar p_{n,n}\\, \\lambda_{\\max}(P)}},
        \\qquad \\bar p_{n,n} = (P^{-1})_{n,n}.

    Evaluated in rescaled coordinates from ``P(1)`` (eq. 20, 25; see
    :func:`_condition5_sides`), never from ``P(gamma)`` itself, whose entries span ``gamma``
    to ``gamma^(2n-1)``: accurate to about ``1e-13`` relative for ``n <= 6`` and any ``gamma``
    (tested against an exact-arithmetic reference up to ``gamma = 1e4``), where the direct
    evaluation loses ``P(gamma) > 0`` from ``gamma ~ 10^3`` (n = 4) or ``gamma ~ 1`` (n = 6).

    Parameters
    ----------
    alpha : array_like, shape (n,)
        Hurwitz coefficients meeting condition (10).
    gamma : float
        High-gain parameter, > 0.
    rho : float, optional
        A Lipschitz constant to test against the bound, > 0.

    Returns
    -------
    dict
        ``lambda_min`` (the numerator), ``two_sqrt_pnn_lmax`` (the denominator), ``rho_bound``
        (their ratio: the largest Lipschitz constant (5) admits at this ``gamma``), ``gamma``,
        and with ``rho`` given, ``rho`` and ``satisfied`` (``rho <= rho_bound``).

    Notes
    -----
    ``lambda_min`` is exactly linear in ``gamma`` (``P^{-1} Q`` is similar to
    ``gamma P(1)^{-1} Q(1)``) while the denominator tends to a constant (eq. 25-26), so the
    ratio grows about linearly: :func:`min_gamma` bisects it.

    References
    ----------
    Paper 004 (Ibrir 2007), Theorem 1, eq. 5, 20, 24, 25.

    Examples
    --------
    >>> c = lipschitz_condition([2.0, 1.0], gamma=10.0, rho=1.0)
    >>> round(c["rho_bound"], 4), c["satisfied"]
    (1.8278, True)
    """
    a = check_riccati_alpha(alpha)
    g = finite_scalar("gamma", gamma, positive=True)
    lam_min, denom = _condition5_sides(_condition5_parts(a), g)
    out: dict[str, Any] = {"gamma": g, "lambda_min": lam_min, "two_sqrt_pnn_lmax": denom,
                           "rho_bound": lam_min / denom}
    if rho is not None:
        r = finite_scalar("rho", rho, positive=True)
        out.update(rho=r, satisfied=bool(r <= out["rho_bound"]))
    return out


def min_gamma(alpha: Any, rho: float, *, rtol: float = 1e-10) -> float:
    """Smallest ``gamma`` meeting the Lipschitz condition (5) for the Lipschitz constant ``rho``.

    The right side of (5) grows with ``gamma`` (see :func:`lipschitz_condition`); the bracket
    is found by doubling and refined by bisection to ``rtol``. The returned value is the upper
    end of the final bracket, so it meets (5). Condition (5) is evaluated in rescaled
    coordinates (:func:`_condition5_sides`, ``P(1)`` computed once), accurate for any ``gamma``.

    Parameters
    ----------
    alpha : array_like, shape (n,)
        Hurwitz coefficients meeting condition (10).
    rho : float
        The Lipschitz constant of ``phi``, > 0.
    rtol : float, default 1e-10
        Relative width of the final bisection bracket.

    Returns
    -------
    float
        The smallest ``gamma`` (to ``rtol``) with ``rho <= rho_bound(gamma)``.

    Raises
    ------
    DesignError
        ``alpha`` fails :func:`check_riccati_alpha`, or no ``gamma <= 1e12`` meets (5).

    References
    ----------
    Paper 004 (Ibrir 2007), Theorem 1, eq. 5 and its proof (eq. 20, 25-31).

    Examples
    --------
    >>> g = min_gamma([2.0, 1.0], rho=1.0)
    >>> round(g, 4), lipschitz_condition([2.0, 1.0], g, rho=1.0)["satisfied"]
    (5.4873, True)
    """
    a = check_riccati_alpha(alpha)
    r = finite_scalar("rho", rho, positive=True)
    rtol = finite_scalar("rtol", rtol, positive=True)
    parts = _condition5_parts(a)

    def ok(g: float) -> bool:
        lam_min, denom = _condition5_sides(parts, g)
        return lam_min / denom >= r

    lo, hi = 0.0, 1.0
    while not ok(hi):
        lo, hi = hi, 2.0 * hi
        if hi > 1e12:
            raise DesignError(f"no gamma <= 1e12 meets condition (5) for rho = {r:g}")
    while hi - lo > rtol * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if ok(mid) else (mid, hi)
    return hi


def _lipschitz_structure(M: Any, N: Any, n: int) -> tuple[Array, Array]:
    try:
        Mm = np.array(M, dtype=float)
        Nm = np.array(N, dtype=float)
    except (TypeError, ValueError):
        raise DimensionError(f"M and N must be 2-D arrays of numbers; found {M!r}, {N!r}") from None
    if Mm.ndim != 2 or Mm.shape[0] != n:
        raise DimensionError(f"M must have shape ({n}, m) for n = {n}; found shape {Mm.shape}")
    if Nm.ndim != 2 or Nm.shape[1] != n:
        raise DimensionError(f"N must have shape (m, {n}) for n = {n}; found shape {Nm.shape}")
    if not (np.all(np.isfinite(Mm)) and np.all(np.isfinite(Nm))):
        raise DesignError("M and N must be finite")
    return Mm, Nm


def _compress(Mm: Array, Nm: Array) -> tuple[Array, Array]:
    """Drop the zero columns of ``M`` and zero rows of ``N``: ``M F N`` only sees the rest of
    ``F``, a sub-matrix, whose norm is at most ``|F|``; (62)/(63) are unchanged but better posed."""
    keep_m = np.any(Mm != 0.0, axis=0)
    keep_n = np.any(Nm != 0.0, axis=1)
    if not keep_m.any() or not keep_n.any():
        return np.zeros((Mm.shape[0], 1)), np.zeros((1, Nm.shape[1]))
    return Mm[:, keep_m], Nm[keep_n, :]


def _cvxpy(feature: str) -> Any:
    """cvxpy with the Clarabel solver the LMIs are solved by (the ``lmi`` extra)."""
    require("clarabel", "lmi", feature)
    return require("cvxpy", "lmi", feature)


def _lmi63_problem(alpha: Any, gamma: float, M: Any, N: Any) -> tuple[Any, Any, Any, Any, float]:
    """cvxpy variables and the scaled matrix of LMI (65) (see :func:`max_sampling_period`).

    The matrix is the congruence ``T L T``, ``T = diag(S, S, s3 I)`` with
    ``S = diag((P^-1)_ii^-1/2)`` (unit diagonal of ``P^-1``) and ``s3`` making the ``P^-1 M``
    block of unit norm: same sign as ``L``, better conditioned. The variable ``tau`` returned
    is ``tau s3^2``; multiply its value by the returned factor ``1 / s3^2`` to get ``tau``.
    """
    cp = _cvxpy("LMI (63)/(65) of paper 004")

    P = riccati_P(alpha, gamma)
    n = P.shape[0]
    Mm, Nm = _compress(*_lipschitz_structure(M, N, n))
    A, C = _chain(n)
    Pi = np.linalg.inv(P)
    Pi = 0.5 * (Pi + Pi.T)
    S = np.diag(1.0 / np.sqrt(np.diag(Pi)))
    Pis = S @ Pi @ S
    CC = S @ C.T @ C @ S
    APi = S @ A.T @ Pi @ S  # S A' P^-1 S
    PiM = S @ Pi @ Mm
    norm = float(np.linalg.norm(PiM, 2))
    s3 = 1.0 / norm if norm > 0 else 1.0
    PiM = PiM * s3
    NN = S @ Nm.T @ Nm @ S / s3**2
    m1 = Mm.shape[1]
    al = cp.Variable(name="alpha")
    tau = cp.Variable(name="tau_scaled")
    Z = np.zeros((n, m1))
    L = cp.bmat([[-al * Pis + tau * NN, APi + al * Pis - CC, Z],
                 [APi.T + al * Pis - CC, -al * Pis, PiM],
                 [Z.T, PiM.T, -tau * np.eye(m1)]])
    return cp, al, tau, 0.5 * (L + L.T), 1.0 / s3**2


def _status_ok(status: str) -> bool:
    return status in ("optimal", "optimal_inaccurate")


def sampling_lmi_63(alpha: Any, gamma: float, M: Any, N: Any, delta: float,
                    tau: float | None = None) -> dict[str, Any]:
    """Test LMI (63) of Theorem 2 at the sampling period ``delta`` (Euler observer (53)).

    .. math::

        \\begin{bmatrix}
        -\\tfrac{1}{\\delta}P^{-1} + \\tau N'N & \\tfrac{1}{\\delta}A_\\delta' P^{-1} - C'C & 0 \\\\
        \\tfrac{1}{\\delta}P^{-1}A_\\delta - C'C & -\\tfrac{1}{\\delta}P^{-1} & P^{-1}M \\\\
        0 & M'P^{-1} & -\\tau I
        \\end{bmatrix} < 0, \\qquad A_\\delta = I + \\delta A.

    With ``tau`` given, the matrix is evaluated and its largest eigenvalue reported (e.g. to
    check a published pair ``(delta, tau)``); otherwise ``tau`` is chosen by cvxpy/Clarabel to
    make the largest eigenvalue of the (Jacobi-scaled) matrix as negative as possible.

    Parameters
    ----------
    alpha : array_like, shape (n,)
        Hurwitz coefficients meeting condition (10).
    gamma : float
        High-gain parameter, > 0.
    M : array_like, shape (n, m1)
        Left factor of the Lipschitz structure (55).
    N : array_like, shape (m2, n)
        Right factor of the Lipschitz structure (55).
    delta : float
        Sampling period, > 0.
    tau : float, optional
        The multiplier, >= 0; default chosen by the solver.

    Returns
    -------
    dict
        ``feasible``, ``tau``, ``max_eig`` (of the unscaled matrix at that ``tau``), ``status``.

    References
    ----------
    Paper 004 (Ibrir 2007), Theorem 2, eq. 63.

    Examples
    --------
    >>> import numpy as np
    >>> M, N = np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]])  # phi with |dphi/dx_1| < 1
    >>> sampling_lmi_63([3, 2], 6.0, M, N, delta=0.05, tau=0.014)["feasible"]
    True
    """
    d = finite_scalar("delta", delta, positive=True)
    P = riccati_P(alpha, gamma)
    n = P.shape[0]
    Mm, Nm = _lipschitz_structure(M, N, n)
    A, C = _chain(n)
    Pi = np.linalg.inv(P)
    Ad = np.eye(n) + d * A

    def matrix(t: float) -> Array:
        m1 = Mm.shape[1]
        Z = np.zeros((n, m1))
        L = np.block([[-Pi / d + t * Nm.T @ Nm, Ad.T @ Pi / d - C.T @ C, Z],
                      [Pi @ Ad / d - C.T @ C, -Pi / d, Pi @ Mm],
                      [Z.T, Mm.T @ Pi, -t * np.eye(m1)]])
        return 0.5 * (L + L.T)

    status = "given"
    if tau is None:
        cp, al, tv, L, factor = _lmi63_problem(alpha, gamma, Mm, Nm)
        t = cp.Variable()
        prob = cp.Problem(cp.Maximize(t), [L << -t * np.eye(L.shape[0]), al == 1.0 / d,
                                           tv >= 0, t <= 1.0])
        prob.solve(solver="CLARABEL")
        status = str(prob.status)
        if not _status_ok(status):
            return {"feasible": False, "tau": float("nan"), "max_eig": float("nan"),
                    "status": status}
        tau = max(float(tv.value) * factor, 0.0)
    tau = finite_scalar("tau", tau, nonnegative=True)
    max_eig = float(np.linalg.eigvalsh(matrix(tau)).max())
    return {"feasible": bool(max_eig < 0), "tau": tau, "max_eig": max_eig, "status": status}


def sampling_lmi_62(M: Any, N: Any, delta: float, *, order: int | None = None,
                    X: Any = None, epsilon: float | None = None,
                    x_bound: float = 1e4) -> dict[str, Any]:
    """Solve (or check) LMI (62) for ``X = X' > 0`` and ``epsilon > 0`` at the period ``delta``.

    .. math::

        \\begin{bmatrix}
        -X + \\epsilon N'N & A_\\delta' X - C'C & 0 \\\\
        X A_\\delta - C'C & -X & \\delta X M \\\\
        0 & \\delta M' X & -\\epsilon I
        \\end{bmatrix} < 0

    Feasible: the Euler observer (51) with the gain ``X^{-1} C'`` converges to the states of the
    Euler discretization (50) of the plant. (The derivation's eq. 57 prints its second factor
    with ``A_delta + X^{-1} C'C``; the error map (54), (56) and eq. 58 have
    ``A_delta - X^{-1} C'C``, which (62) is built from.) Solved with cvxpy/Clarabel by maximising a margin
    ``t`` (matrix ``<= -t I``, ``X >= t I``, ``epsilon >= t``, ``trace X <= x_bound``):
    feasible when ``t > 0``. With ``X`` and ``epsilon`` given, they are only checked.

    Parameters
    ----------
    M : array_like, shape (n, m1)
        Left factor of the Lipschitz structure (55).
    N : array_like, shape (m2, n)
        Right factor of the Lipschitz structure (55).
    delta : float
        Sampling period, > 0.
    order : int, optional
        ``n``; default the number of rows of ``M``.
    X : array_like, shape (n, n), optional
        A candidate ``X`` to check (with ``epsilon``) instead of solving.
    epsilon : float, optional
        The candidate ``epsilon > 0`` that goes with ``X``.
    x_bound : float, default 1e4
        Bound on ``trace X`` when solving.

    Returns
    -------
    dict
        ``feasible``, ``margin`` (``t``, or minus the largest eigenvalue when checking),
        ``X``, ``epsilon``, ``gain`` (``X^{-1} C'``), ``status``.

    Raises
    ------
    DimensionError
        ``M``, ``N`` or ``X`` of the wrong shape.
    DesignError
        A non-finite ``M`` or ``N``, or a bad ``delta`` or ``epsilon``.

    References
    ----------
    Paper 004 (Ibrir 2007), section 3, eq. 51, 54-62.

    Examples
    --------
    >>> import numpy as np
    >>> M, N = np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]])  # phi with |dphi/dx_1| < 1
    >>> r = sampling_lmi_62(M, N, delta=0.01)
    >>> r["feasible"], r["gain"].shape
    (True, (2,))
    >>> sampling_lmi_62(M, N, 0.01, X=r["X"], epsilon=r["epsilon"])["status"]
    'given'
    """
    d = finite_scalar("delta", delta, positive=True)
    Marr = np.asarray(M, dtype=float)
    n = int(order) if order is not None else (Marr.shape[0] if Marr.ndim == 2 else -1)
    Mm, Nm = _lipschitz_structure(M, N, n)
    A, C = _chain(n)
    Ad = np.eye(n) + d * A
    m1 = Mm.shape[1]
    CC = C.T @ C

    def blocks(Xv: Any, e: Any, Z: Array) -> list[list[Any]]:
        return [[-Xv + e * (Nm.T @ Nm), Ad.T @ Xv - CC, Z],
                [Xv @ Ad - CC, -Xv, d * Xv @ Mm],
                [Z.T, d * Mm.T @ Xv, -e * np.eye(m1)]]

    Z = np.zeros((n, m1))
    if X is not None:
        Xn = np.array(X, dtype=float)
        if Xn.shape != (n, n):
            raise DimensionError(f"X must have shape ({n}, {n}); found {Xn.shape}")
        e = finite_scalar("epsilon", epsilon, positive=True)
        L = np.block(blocks(Xn, e, Z))
        margin = -float(np.linalg.eigvalsh(0.5 * (L + L.T)).max())
        margin = min(margin, float(np.linalg.eigvalsh(0.5 * (Xn + Xn.T)).min()))
        return {"feasible": margin > 0, "margin": margin, "X": Xn, "epsilon": e,
                "gain": np.linalg.solve(Xn, C.T).ravel(), "status": "given"}
    cp = _cvxpy("LMI (62) of paper 004")

    Xv = cp.Variable((n, n), symmetric=True)
    ev = cp.Variable()
    tv = cp.Variable()
    L = cp.bmat(blocks(Xv, ev, Z))
    cons = [0.5 * (L + L.T) << -tv * np.eye(2 * n + m1), Xv >> tv * np.eye(n), ev >= tv,
            cp.trace(Xv) <= x_bound, tv <= 1.0]
    prob = cp.Problem(cp.Maximize(tv), cons)
    prob.solve(solver="CLARABEL")
    status = str(prob.status)
    X_val, t_val, e_val = Xv.value, tv.value, ev.value
    if not _status_ok(status) or X_val is None or t_val is None or e_val is None:
        return {"feasible": False, "margin": float("nan"), "X": None, "epsilon": float("nan"),
                "gain": None, "status": status}
    Xn = 0.5 * (X_val + X_val.T)
    return {"feasible": bool(t_val > 1e-7), "margin": float(t_val), "X": Xn,
            "epsilon": float(e_val), "gain": np.linalg.solve(Xn, C.T).ravel(), "status": status}


def max_sampling_period(alpha: Any, gamma: float, M: Any, N: Any, *, lmi: str = "63",
                        rtol: float = 1e-5) -> dict[str, Any]:
    """Largest Euler sampling period certified by LMI (63)/(65) or by LMI (62) of paper 004.

    The Lipschitz structure (55): ``delta B dphi/dx = delta M F N`` with ``F'F < I`` on the
    region of interest, ``M`` of shape ``(n, m1)`` and ``N`` of shape ``(m2, n)``.

    * ``lmi="63"``: the Euler observer (53) with the Riccati gain ``delta P(gamma) C'``
      (Theorem 2). With ``a = 1/delta`` LMI (63) is linear in ``(a, tau)``; the linear
      program (65) minimises ``a``:

      .. math::

          \\min a \\ \\text{s.t.}\\
          \\begin{bmatrix}
          -a P^{-1} + \\tau N'N & (A' + a I) P^{-1} - C'C & 0 \\\\
          P^{-1}(A + a I) - C'C & -a P^{-1} & P^{-1} M \\\\
          0 & M' P^{-1} & -\\tau I
          \\end{bmatrix} < 0,

      and ``delta_max = 1 / a_min``. **Correction:** the paper prints the (2,1) block as
      ``(A + a I) P^{-1} - C'C``, which is not the transpose of the (1,2) block (the matrix
      would not be symmetric); replacing ``1/delta`` by ``a`` in (63) gives
      ``P^{-1}(A + a I) - C'C``, used here.
    * ``lmi="62"``: the observer (51) whose gain ``X^{-1} C'`` is re-designed at each period
      (``alpha`` and ``gamma`` only fix ``n``): (62) is an LMI in ``(X, epsilon)`` for fixed
      ``delta``, and ``delta_max`` is found by bisection on its feasibility
      (:func:`sampling_lmi_62`).

    Solved with cvxpy and the Clarabel solver; (65) with a small margin (``<= -1e-9 I`` on the
    Jacobi-scaled matrix), so the bound is strict.

    Parameters
    ----------
    alpha : array_like, shape (n,)
        Hurwitz coefficients meeting condition (10).
    gamma : float
        High-gain parameter, > 0.
    M : array_like, shape (n, m1)
        Left factor of the Lipschitz structure (55).
    N : array_like, shape (m2, n)
        Right factor of the Lipschitz structure (55).
    lmi : {"63", "62"}, default "63"
        Which certificate (above).
    rtol : float, default 1e-5
        Relative tolerance of the bisection (``lmi="62"``).

    Returns
    -------
    dict
        ``delta_max``, ``lmi``, ``status``, ``solve_time_s``, and ``tau`` (63) or ``X``,
        ``epsilon``, ``gain`` at ``delta_max`` (62).

    Raises
    ------
    DesignError
        If the LMI is infeasible (the message gives the solver status), or ``lmi`` is unknown.

    References
    ----------
    Paper 004 (Ibrir 2007), section 3: eq. 53, 55, 62, 63 (Theorem 2), 65.

    Examples
    --------
    >>> import numpy as np
    >>> M, N = np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]])  # phi with |dphi/dx_1| < 1
    >>> r = max_sampling_period([3, 2], 6.0, M, N)
    >>> round(r["delta_max"], 3), r["status"]
    (0.092, 'optimal')
    """
    import time

    if lmi not in ("63", "62"):
        raise DesignError(f"lmi must be '63' or '62'; found {lmi!r}")
    rtol = finite_scalar("rtol", rtol, positive=True)
    a = check_riccati_alpha(alpha)
    t0 = time.perf_counter()
    if lmi == "63":
        cp, al, tau, L, factor = _lmi63_problem(a, gamma, M, N)
        prob = cp.Problem(cp.Minimize(al), [L << -1e-9 * np.eye(L.shape[0]), tau >= 1e-9])
        prob.solve(solver="CLARABEL")
        status = str(prob.status)
        if not _status_ok(status) or al.value is None or not al.value > 0:
            raise DesignError(f"LMI (63)/(65) of paper 004 is infeasible for alpha = {a.tolist()}, "
                              f"gamma = {float(gamma):g} with the given M, N: no sampling period "
                              f"is certified (solver status {status!r})")
        return {"lmi": "63", "delta_max": 1.0 / float(al.value), "tau": float(tau.value) * factor,
                "status": status, "solve_time_s": time.perf_counter() - t0}
    n = a.size
    Mm, Nm = _lipschitz_structure(M, N, n)

    def feasible(d: float) -> dict[str, Any]:
        return sampling_lmi_62(Mm, Nm, d, order=n)

    lo, res_lo = 1e-3, feasible(1e-3)
    while not res_lo["feasible"]:
        lo /= 10.0
        if lo < 1e-7:
            raise DesignError(f"LMI (62) of paper 004 is infeasible for every sampling period "
                              f"tried down to 1e-6 with the given M, N (solver status "
                              f"{res_lo['status']!r}, margin {res_lo['margin']:.3g})")
        res_lo = feasible(lo)
    hi = 2.0 * lo
    while feasible(hi)["feasible"]:
        lo, hi = hi, 2.0 * hi
        if hi > 1e6:
            raise DesignError("LMI (62) stays feasible beyond delta = 1e6; check M and N")
    res_lo = feasible(lo)
    while hi - lo > rtol * lo:
        mid = 0.5 * (lo + hi)
        r = feasible(mid)
        if r["feasible"]:
            lo, res_lo = mid, r
        else:
            hi = mid
    return {"lmi": "62", "delta_max": lo, "X": res_lo["X"], "epsilon": res_lo["epsilon"],
            "gain": res_lo["gain"], "margin": res_lo["margin"], "status": res_lo["status"],
            "solve_time_s": time.perf_counter() - t0}


def bullinger_theorem3_bound(p: Any, mu: float, k0: float) -> Array:
    """Ultimate bound on the errors of the adaptive high-gain observer (paper 000, Theorem 3).

    .. math::

        \\limsup_{t \\to \\infty} |e_i(t)| \\le \\frac{2 \\mu \\|\\bar P\\|}{k_0^{\\,n+1-i}},
        \\qquad i = 1, \\dots, n, \\qquad
        \\bar A^T \\bar P + \\bar P \\bar A = -I,

    where :math:`\\bar A` is the companion matrix with first column :math:`-p` (eq. 6),
    :math:`\\bar P` solves the Lyapunov equation (7) and :math:`\\|\\cdot\\|` is the spectral norm.

    Parameters
    ----------
    p : array_like, shape (n,)
        Coefficients of the Hurwitz polynomial ``s^n + p_1 s^(n-1) + ... + p_n``.
    mu : float
        Bound ``|phi(x, u)| = |y^(n)| <= mu`` (assumption of Theorem 3), ``mu > 0``.
    k0 : float
        Initial gain ``k(0) > 0`` of the adaptation law (eq. 4).

    Returns
    -------
    ndarray, shape (n,)
        The bound on ``limsup |e_i|`` for ``i = 1..n``.

    Notes
    -----
    The sketch of the proof in the paper is loose: it writes
    :math:`\\|\\eta\\|_{\\bar P} \\ge \\|\\eta\\| \\sqrt{\\|\\bar P^{-1}\\|}` where (11) gives
    :math:`\\|\\eta\\|_{\\bar P} \\ge \\|\\eta\\| / \\sqrt{\\|\\bar P^{-1}\\|}`, and it mixes
    :math:`k(0)` and :math:`k(t)` in :math:`e_i = k^{i-1} \\eta_i`; a Lyapunov argument done
    carefully carries an extra factor :math:`\\sqrt{\\mathrm{cond}(\\bar P)}`. The bound (14)
    itself holds nevertheless for the cases checked: as :math:`k(t) \\to k_\\infty \\ge k_0`,
    the worst case of :math:`\\limsup |e_i|` over :math:`|\\varphi| \\le \\mu` is
    :math:`\\mu \\|h_i\\|_{L_1} / k_\\infty^{n+1-i}`, :math:`h = e^{\\bar A t} B`, and
    :math:`\\|h_i\\|_{L_1} \\le 2 \\|\\bar P\\|` held in a random search over 3000 Hurwitz
    polynomials of orders 2 to 4 (largest ratio 0.95; it is equality for ``n = 1``). This is
    a numerical finding, not a proof. Since it uses :math:`k_0`, not :math:`k_\\infty`, the
    bound is loose by :math:`(k_\\infty / k_0)^{n+1-i}` when the gain adapts far.

    References
    ----------
    Paper 000 (Bullinger, Ilchmann, Allgöwer 1998), Theorem 3, eq. 14; eq. 6 and 7.

    Examples
    --------
    >>> bullinger_theorem3_bound([2.0, 1.0], mu=1.0, k0=10.0).round(5)
    array([0.03414, 0.34142])
    """
    from scipy.linalg import solve_continuous_lyapunov

    p = check_hurwitz(p)
    mu = finite_scalar("mu", mu, positive=True)
    k0 = finite_scalar("k0", k0, positive=True)
    n = p.size
    Abar = np.diag(np.ones(n - 1), 1)
    Abar[:, 0] = -p
    Pbar = solve_continuous_lyapunov(Abar.T, -np.eye(n))  # Abar^T P + P Abar = -I (eq. 7)
    norm_p = float(np.linalg.norm(Pbar, 2))
    return 2.0 * mu * norm_p / k0 ** (n + 1 - np.arange(1, n + 1, dtype=float))
