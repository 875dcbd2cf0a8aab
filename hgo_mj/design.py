"""Gain design as pure functions (testable alone).

References
----------
.. [000] E. Bullinger, A. Ilchmann, F. Allgöwer, "A simple adaptive observer for nonlinear
   systems", NOLCOS 1998 (``shared/papers/000_*``), eq. 2, 3, 6.
"""

from __future__ import annotations

from math import comb
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._validate import finite_scalar, vector
from .exceptions import DesignError

Array = NDArray[np.float64]


def binomial_coefficients(n: int) -> Array:
    """``p_i = C(n, i)``: the polynomial ``(s + 1)^n``, all observer poles at ``-k`` (paper 000, eq. 3)."""
    if int(n) != n or n < 1:
        raise DesignError(f"order n must be a positive integer; found {n!r}")
    return np.array([comb(int(n), i) for i in range(1, int(n) + 1)], dtype=float)


def check_hurwitz(p: Any, name: str = "p") -> Array:
    """Validate that ``s^n + p_1 s^(n-1) + ... + p_n`` is Hurwitz and return ``p`` as an array.

    Raises
    ------
    DesignError
        If a root has a non-negative real part; the message lists the offending roots.
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
    """
    p = check_hurwitz(p)
    k = finite_scalar("k", k, positive=True)
    return p * k ** np.arange(1, p.size + 1)


def observer_matrix(p: Any, k: float) -> Array:
    """The error-dynamics matrix ``A_k = A - L C`` (paper 000, eq. 6: ``A_k = k K Abar K^-1``)."""
    L = hgo_gains(p, k)
    n = L.size
    A = np.diag(np.ones(n - 1), 1)
    A[:, 0] -= L
    return A
