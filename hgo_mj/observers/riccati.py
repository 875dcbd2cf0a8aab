"""The Riccati-based high-gain observer of Ibrir (paper 004, Theorem 1), with the model term.

.. math::

    \\dot{\\hat x} = A \\hat x + B \\varphi(\\hat x, u) + P(\\gamma) C' (y - C \\hat x),
    \\qquad A P(\\gamma) + P(\\gamma) A' - P(\\gamma) C' C P(\\gamma) + Q(\\gamma) = 0

(eq. 6; the paper prints the innovation as ``gamma - C x_hat``, a typo for ``y - C x_hat``).
By Lemma 4 the gain ``P(gamma) C'`` equals ``(alpha_i gamma^i)``: the observer is the
high-gain observer with ``p = alpha``, ``k = gamma`` and the model term of Gauthier et al.,
and it is implemented as such (:class:`~hgo_mj.observers.high_gain.HighGainObserver`), with
the gain designed from the Riccati equation (:func:`hgo_mj.design.riccati_gains`).

References
----------
.. [004] S. Ibrir, "On observer design for nonlinear systems", Int. J. Control, 2007
   (``shared/papers/004_*``): Theorem 1 (eq. 4-10), Lemma 4 (eq. 15-21), eq. 52-53 (Euler
   discretization), Theorem 2 (eq. 63).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from .._validate import finite_scalar
from ..design import (
    binomial_coefficients,
    check_riccati_alpha,
    lipschitz_condition,
    min_gamma,
    riccati_gains,
    riccati_P,
    riccati_Q,
)
from ..exceptions import DesignError, DimensionError
from ..systems.base import System
from .high_gain import HighGainObserver


def chain_order(cls: str, system: System | None, order: int | None) -> int:
    """The order ``n`` an observer of class ``cls`` will have (checks as :class:`Observer` does)."""
    if order is not None:
        if isinstance(order, bool) or int(order) != order or order < 1:
            raise DesignError(f"order must be a positive integer; found {order!r}")
        return int(order)
    if system is not None and isinstance(system, System) and system.normal_form_order is not None:
        return int(system.normal_form_order)
    raise DesignError(f"{cls} needs a system with a single-output normal form or an explicit order")


def design_gamma(gamma: Any, alpha: np.ndarray, rho: Any, where: str) -> tuple[float, float | None]:
    """Resolve ``gamma`` (a number > 0, or ``"min"`` with ``rho``) and validate ``rho``."""
    r = None if rho is None else finite_scalar("rho", rho, positive=True)
    if isinstance(gamma, str):
        if gamma != "min":
            raise DesignError(f"gamma must be a number > 0 or 'min'; found {gamma!r}")
        if r is None:
            raise DesignError(f"{where}: gamma='min' needs the Lipschitz constant rho")
        return min_gamma(alpha, r), r
    return finite_scalar("gamma", gamma, positive=True), r


class RiccatiObserver(HighGainObserver):
    """Riccati-based high-gain observer of Ibrir (paper 004, Theorem 1).

    .. math::

        \\dot{\\hat x} = A \\hat x + B \\varphi(\\hat x, u) + P(\\gamma) C' (y - \\hat x_1),
        \\qquad P(\\gamma) C' = (\\alpha_1 \\gamma, \\dots, \\alpha_n \\gamma^n)'

    with ``P(gamma)`` the solution of the Riccati equation of eq. 6 for ``Q(gamma)`` of eq. 8
    (weights corrected to eq. 17, see :func:`hgo_mj.design.riccati_weights`). If the Lipschitz
    condition (5) holds for the Lipschitz constant ``rho`` of ``phi``, the error decays
    exponentially; :func:`hgo_mj.design.min_gamma` gives the smallest such ``gamma``.

    Parameters
    ----------
    system : System, optional
        Gives the order ``n``, the map back to physical coordinates and ``phi`` (the model term
        the paper's observer uses, ``f(x_hat, u) = B phi``). Without a system give ``order`` and
        ``model=False``.
    gamma : float or "min"
        High-gain parameter (> 0); ``"min"`` takes :func:`~hgo_mj.design.min_gamma` for ``rho``.
    alpha : array_like, optional
        ``alpha_1..alpha_n``: (9) Hurwitz and meeting condition (10); default binomial
        ``C(n, k)`` (then the observer is that of Gauthier et al. 1992, as the paper notes).
    rho : float, optional
        Lipschitz constant of ``phi`` (eq. 4). Needed for ``gamma="min"``; with a numeric
        ``gamma``, a :class:`RuntimeWarning` says when condition (5) does not hold.
    order, output, z_bounds, x_hat0, z_hat0, on_unstable
        As in :class:`HighGainObserver`.
    model : bool
        Use the model term ``phi(x_hat, u)`` (default ``True``, as in the paper).
    method : {"exact", "euler", "rk4"}
        ``euler`` is the discrete-time observer of eq. 53,
        ``x_{k+1} = A_delta x_k + delta B phi(x_k, u_k) + delta P C' (y_k - x_{k,1})``,
        ``A_delta = I + delta A``; it is stable only for short periods (Theorem 2 and
        :func:`hgo_mj.design.max_sampling_period` give a sufficient bound with the
        nonlinearity; :meth:`check_period` checks the linear part). ``exact`` and ``rk4`` as
        in :class:`HighGainObserver` (exact for the linear part, model term held over the
        sample for ``exact``).

    Attributes
    ----------
    gamma_ : float
        The high-gain parameter (constant).
    P, Q : ndarray
        ``P(gamma)`` and ``Q(gamma)`` of the design.
    L : ndarray
        The gain ``P(gamma) C'`` (from the Riccati solution).
    condition : dict or None
        The two sides of (5) when ``rho`` is given (:func:`hgo_mj.design.lipschitz_condition`).
    dropouts_ : int
        NaN samples, over which the observer predicted without correction.

    Notes
    -----
    Corrections to the paper, all checked numerically (``hgo-mj reproduce ibrir2007``):
    eq. 6 ``gamma - C x_hat`` is ``y - C x_hat``; eq. 8/10's sum is eq. 17's; eq. 51/64 print
    ``phi(x_k, u_k)`` (the true state) where the error equation (54) needs ``phi(x_hat_k,
    u_k)``, as in eq. 53; eq. 64 omits the ``C'`` of ``delta P C'``.

    References
    ----------
    Paper 004 (Ibrir 2007): Theorem 1 (eq. 4-10), Lemma 4 (eq. 15-21), eq. 53, Theorem 2.
    Gauthier, Hammouri, Othman 1992 (``alpha_k = C(n, k)``).
    """

    name = "riccati"
    summary = "Ibrir's Riccati-based high-gain observer, gain P(gamma)C' = (alpha_i gamma^i), model term"
    reference = "paper 004 (Ibrir 2007), Theorem 1, Lemma 4, eq. 6-8, 53"
    diagnostic_names = ("gamma",)

    def __init__(self, system: System | None = None, *, gamma: Any, alpha: Any = None,
                 rho: float | None = None, order: int | None = None, output: int = 0,
                 model: bool = True, method: str = "exact", z_bounds: Any = None,
                 x_hat0: Any = None, z_hat0: Any = None, on_unstable: str = "raise") -> None:
        n = chain_order(type(self).__name__, system, order)
        a = binomial_coefficients(n) if alpha is None else check_riccati_alpha(alpha)
        if a.size != n:
            raise DimensionError(f"alpha must have n = {n} coefficients; found {a.size}")
        g, r = design_gamma(gamma, a, rho, type(self).__name__)
        super().__init__(system, k=g, p=a, order=order, output=output, model=model, method=method,
                         z_bounds=z_bounds, x_hat0=x_hat0, z_hat0=z_hat0, on_unstable=on_unstable)
        self.alpha = a
        self.gamma_ = g
        self.rho = r
        self.gamma_spec = gamma if isinstance(gamma, str) else g
        self.Q = riccati_Q(a, g)
        self.P = riccati_P(a, g)
        self.L = riccati_gains(a, g)  # P(gamma) C' from the ARE; equals (alpha_i gamma^i)
        self.condition = None if r is None else lipschitz_condition(a, g, r)
        if self.condition is not None and not self.condition["satisfied"]:
            warnings.warn(f"RiccatiObserver: gamma = {g:g} does not meet the Lipschitz condition (5) "
                          f"for rho = {r:g} (it admits rho <= {self.condition['rho_bound']:.4g}); "
                          f"convergence is not guaranteed; min_gamma gives "
                          f"{min_gamma(a, r):.4g}", RuntimeWarning, stacklevel=2)

    def _label(self) -> str:
        return f"Riccati observer (n={self.n}, gamma={self.gamma_:g})"

    def diagnostics(self) -> dict[str, float]:
        return {"gamma": self.gamma_, "dropouts": float(self.dropouts_)}

    def params(self) -> dict[str, Any]:
        return {"gamma": self.gamma_, "gamma_spec": self.gamma_spec, "alpha": self.alpha.tolist(),
                "rho": self.rho, "order": self.n, "output": self.output, "model": self.model,
                "method": self.method,
                "z_bounds": None if self.z_bounds is None else [b.tolist() for b in self.z_bounds]}
