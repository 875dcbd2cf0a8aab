"""Condition (5) of paper 004 (Theorem 1) for n = 2..6 and gamma up to 1e4, held against an
exact-arithmetic reference.

The reference forms ``P(gamma)`` and ``Q(gamma)`` themselves (the *unscaled* formula of eq. 5)
in rational arithmetic: ``P(gamma)`` from Lemma 4 (first column ``alpha_i gamma^i``, eq. 15;
the rest from the Lyapunov equation (19) by the recursion
``P_(i+1),j + P_i,(j+1) = alpha_i alpha_j gamma^(i+j) - q_ii(gamma) delta_ij``), the
eigenvalues as roots of the exact characteristic polynomials (Newton's method in 60-digit
decimals, started outside the real spectrum: monotone convergence to the extreme root), and
``(P^-1)_nn`` as a ratio of exact determinants. No floating-point matrix is ever formed, so
nothing in it depends on the conditioning of ``P(gamma)``.
"""

from __future__ import annotations

import decimal
from decimal import Decimal
from fractions import Fraction

import numpy as np
import pytest

from hgo_mj.design import (
    binomial_coefficients,
    lipschitz_condition,
    min_gamma,
    riccati_P,
    riccati_Q,
    riccati_weights,
)

DIGITS = 60
GAMMAS = (0.05, 0.3, 1.0, 7.0, 50.0, 400.0, 3000.0, 1e4)


def det(m: list[list[Fraction]]) -> Fraction:
    """Exact determinant by Gaussian elimination over the rationals."""
    a = [row[:] for row in m]
    n = len(a)
    out = Fraction(1)
    for c in range(n):
        piv = next((r for r in range(c, n) if a[r][c] != 0), None)
        if piv is None:
            return Fraction(0)
        if piv != c:
            a[c], a[piv] = a[piv], a[c]
            out = -out
        out *= a[c][c]
        for r in range(c + 1, n):
            f = a[r][c] / a[c][c]
            if f:
                a[r] = [x - f * y for x, y in zip(a[r], a[c])]
    return out


def char_poly(A: list[list[Fraction]], B: list[list[Fraction]]) -> list[Fraction]:
    """Exact coefficients (constant first) of ``det(A - lam B)``, by interpolation at
    ``lam = 0..n``."""
    n = len(A)
    xs = list(range(n + 1))
    ys = [det([[A[i][j] - x * B[i][j] for j in range(n)] for i in range(n)]) for x in xs]
    coef = [Fraction(0)] * (n + 1)
    for k, xk in enumerate(xs):  # Lagrange basis polynomials, expanded
        basis = [Fraction(1)]
        denom = Fraction(1)
        for m, xm in enumerate(xs):
            if m == k:
                continue
            basis = [Fraction(0)] + basis  # times lam
            for i in range(len(basis) - 1):
                basis[i] -= xm * basis[i + 1]
            denom *= xk - xm
        for i in range(n + 1):
            coef[i] += ys[k] * basis[i] / denom
    return coef


def newton_root(coef: list[Fraction], start: Fraction) -> Decimal:
    """Newton's method from ``start`` (outside the spectrum: it converges monotonically to
    the nearest, extreme, root of a polynomial with real roots), in 60-digit decimals."""
    with decimal.localcontext() as ctx:
        ctx.prec = DIGITS
        c = [Decimal(f.numerator) / Decimal(f.denominator) for f in coef]
        x = Decimal(start.numerator) / Decimal(start.denominator)
        for _ in range(2000):
            f = Decimal(0)
            df = Decimal(0)
            for a in reversed(c):  # Horner for f and f'
                df = df * x + f
                f = f * x + a
            step = f / df
            x -= step
            if abs(step) <= abs(x) * Decimal(10) ** (-DIGITS + 8):
                return x
    raise AssertionError("Newton did not converge")


def reference_rho_bound(alpha: np.ndarray, gamma: float) -> tuple[float, float, float]:
    """``(lambda_min, 2 sqrt(pnn lambda_max), ratio)`` of eq. 5 in exact arithmetic."""
    n = alpha.size
    a = [Fraction(float(v)) for v in alpha]
    g = Fraction(gamma)
    q1 = [Fraction(float(v)) for v in riccati_weights(alpha)]
    ag = [a[i] * g ** (i + 1) for i in range(n)]  # P C' = (alpha_i gamma^i), eq. 15
    qg = [q1[i] * g ** (2 * (i + 1)) for i in range(n)]
    P = [[Fraction(0)] * (n + 1) for _ in range(n + 1)]
    P[0][:n] = ag
    for i in range(n - 1):  # A P + P A' = G'G - Q (eq. 19), row by row
        for j in range(n):
            P[i + 1][j] = ag[i] * ag[j] - (qg[i] if i == j else 0) - P[i][j + 1]
    P = [row[:n] for row in P[:n]]
    assert all(P[i][j] == P[j][i] for i in range(n) for j in range(n))
    Q = [[qg[i] if i == j else Fraction(0) for j in range(n)] for i in range(n)]
    eye = [[Fraction(int(i == j)) for j in range(n)] for i in range(n)]
    # lambda_min(P^-1/2 Q P^-1/2): smallest root of det(Q - lam P), from lam = 0 (below it)
    lam_min = newton_root(char_poly(Q, P), Fraction(0))
    # lambda_max(P): largest root of det(P - lam I), from trace(P) (above it)
    lam_max = newton_root(char_poly(P, eye), sum(P[i][i] for i in range(n)))
    pnn = det([row[:-1] for row in P[:-1]]) / det(P)
    with decimal.localcontext() as ctx:
        ctx.prec = DIGITS
        den = 2 * (Decimal(pnn.numerator) / Decimal(pnn.denominator) * lam_max).sqrt()
        return float(lam_min), float(den), float(lam_min / den)


CASES = [(n, binomial_coefficients(n)) for n in range(2, 7)] + [
    (3, np.array([6.0, 11.0, 6.0])),  # roots -1, -2, -3
    (4, np.array([10.0, 35.0, 50.0, 24.0])),  # roots -1..-4
]


@pytest.mark.parametrize("n, alpha", CASES, ids=[f"n{n}-{a.tolist()}" for n, a in CASES])
def test_condition5_matches_exact_reference(n, alpha):
    for gamma in GAMMAS:
        lam_ref, den_ref, ratio_ref = reference_rho_bound(alpha, gamma)
        c = lipschitz_condition(alpha, gamma)
        assert c["lambda_min"] == pytest.approx(lam_ref, rel=1e-12), (n, gamma)
        assert c["two_sqrt_pnn_lmax"] == pytest.approx(den_ref, rel=1e-12), (n, gamma)
        assert c["rho_bound"] == pytest.approx(ratio_ref, rel=1e-12), (n, gamma)


@pytest.mark.parametrize("n", range(2, 7))
def test_min_gamma_meets_condition5_exactly_for_large_rho(n):
    alpha = binomial_coefficients(n)
    for rho in (1.5, 300.0, 1e3):
        g = min_gamma(alpha, rho)
        assert np.isfinite(g) and g > 0
        assert reference_rho_bound(alpha, g)[2] >= rho * (1 - 1e-12), (n, rho)
        assert reference_rho_bound(alpha, g * (1 - 1e-8))[2] < rho, (n, rho)


def unscaled_rho_bound(alpha: np.ndarray, gamma: float) -> float:
    """Condition (5) straight from ``P(gamma)`` and ``Q(gamma)`` in floating point (the
    former implementation): accurate only where ``P(gamma)`` is well conditioned."""
    P, Q = riccati_P(alpha, gamma), riccati_Q(alpha, gamma)
    w, V = np.linalg.eigh(P)
    P_mh = (V / np.sqrt(w)) @ V.T
    lam_min = np.linalg.eigvalsh(P_mh @ Q @ P_mh).min()
    return lam_min / (2.0 * np.sqrt(np.linalg.inv(P)[-1, -1] * w.max()))


@pytest.mark.parametrize("n", (2, 3, 4))
def test_condition5_matches_unscaled_formula_where_well_conditioned(n):
    alpha = binomial_coefficients(n)
    for gamma in (0.5, 1.0, 3.0, 10.0):
        assert lipschitz_condition(alpha, gamma)["rho_bound"] == pytest.approx(
            unscaled_rho_bound(alpha, gamma), rel=1e-8)


def test_min_gamma_large_rho_n4_no_longer_fails():
    """``min_gamma(C(4, i), rho)`` raised "P(gamma) is not positive definite" from rho ~ 300
    on; the elastic-joint study needs rho ~ 1e4."""
    a = binomial_coefficients(4)
    g = min_gamma(a, 1e4)
    assert lipschitz_condition(a, g)["rho_bound"] == pytest.approx(1e4, rel=1e-9)
    # the bound is about linear in gamma (eq. 25-31)
    assert min_gamma(a, 1e4) / min_gamma(a, 1e3) == pytest.approx(10.0, rel=1e-3)
