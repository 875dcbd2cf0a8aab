r"""The super-twisting second-order sliding-mode observer of Davila, Fridman and Levant [DFL05]_
for a second-order system in normal form (a mechanical system ``x1' = x2, x2' = f + xi``).

A baseline outside the papers (issue "The nonlinear observer benchmark", item 4). With
``e = y - \hat z_1``:

.. math::

    \dot{\hat z}_1 &= \hat z_2 + k_1 |e|^{1/2} \operatorname{sign}(e) \\
    \dot{\hat z}_2 &= [\hat\varphi(y, \hat z_2, u)] + k_2 \operatorname{sign}(e)

(the observer of [DFL05]_, sec. II, with ``lambda = k_1`` and ``alpha = k_2``; their nominal
model ``f(t, x_1, \hat x_2, u)`` is evaluated at the *measured* position and the estimated
velocity, as here when ``model=True``; without it, this is Levant's robust exact
differentiator [L98]_). If the unknown part of ``z_2'`` is bounded by ``f^+``, [DFL05]_ (sec. III)
proves finite-time convergence for ``k_2 > f^+`` and
``k_1 > \sqrt{2 / (k_2 - f^+)}\,(k_2 + f^+)(1 + p)/(1 - p)`` with some ``0 < p < 1``.

**Tuning.** The gains follow Levant's scaling [L03]_: ``k_1 = lambda_1 L^{1/2}``,
``k_2 = lambda_2 L`` with ``L`` the bound of the unknown acceleration (the second derivative of
the output without the model term, the model error with it) and Levant's recommended
``lambda_1 = 1.5``, ``lambda_2 = 1.1`` [L03]_. ``L`` is the one tunable parameter.

**Discretization and chattering.** Each sample period ``h`` is integrated by forward Euler in
``substeps`` equal steps with the measurement held (and the model term held at its value at the
start of the sample). The discontinuous ``sign`` terms make the discrete estimate chatter: in the
ideal sampled case (no noise) Levant [L98]_ bounds the accuracy by ``|e_1| = O(L h^2)`` and
``|e_2| = O(L h)`` (``e_2`` chatters with amplitude about ``k_2 h``); with measurement noise of
amplitude ``eps``, ``|e_2| = O(L^{1/2} eps^{1/2})``. A dropout (NaN) integrates the estimate
without correction.

References
----------
.. [DFL05] J. Davila, L. Fridman, A. Levant, "Second-order sliding-mode observer for mechanical
   systems", IEEE Trans. Automatic Control 50(11), 1785-1789, 2005: sec. II (the observer),
   sec. III (the gain conditions, finite-time convergence).
.. [L98] A. Levant, "Robust exact differentiation via sliding mode technique", Automatica 34(3),
   379-384, 1998 (the differentiator and its sampled accuracy).
.. [L03] A. Levant, "Higher-order sliding modes, differentiation and output-feedback control",
   Int. J. Control 76(9-10), 924-941, 2003 (the recommended ``lambda_1 = 1.5``,
   ``lambda_2 = 1.1``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from .._validate import boolean, finite_scalar, positive_int
from ..exceptions import DesignError
from ..systems.base import System
from .base import Array, Dimension, Observer, Params, State, register
from .finite_difference import _NormalFormEstimate

__all__ = ["SuperTwistingObserver"]

#: the tuning space of ``L``: this factor below and above the constructor's value (log scale)
L_SPAN = 100.0


@njit(cache=True)
def twisting_advance(Z: Array, Y: Array, W: Array, use_w: bool, k1: float, k2: float,
                     h: float, substeps: int, t0: int, t1: int,
                     Zout: Array) -> None:  # pragma: no cover
    """Forward Euler of the super-twisting observer over the samples ``t0 <= t < t1`` of ``Y``
    ``(B, T, 1)``, ``Z`` ``(B, 2)`` in place, ``substeps`` steps of ``h / substeps`` per
    sample with the measurement held; ``W[b, t]`` the held model term when ``use_w``; a NaN
    measurement: no correction."""
    hs = h / substeps
    for b in range(Z.shape[0]):
        z1 = Z[b, 0]
        z2 = Z[b, 1]
        for t in range(t0, t1):
            y = Y[b, t, 0]
            w = W[b, t] if use_w else 0.0
            for _ in range(substeps):
                if y == y:
                    e = y - z1
                    sg = 1.0 if e > 0.0 else (-1.0 if e < 0.0 else 0.0)
                    d1 = z2 + k1 * math.sqrt(abs(e)) * sg
                    d2 = w + k2 * sg
                else:
                    d1 = z2
                    d2 = w
                z1 = z1 + hs * d1
                z2 = z2 + hs * d2
            Zout[b, t, 0] = z1
            Zout[b, t, 1] = z2
        Z[b, 0] = z1
        Z[b, 1] = z2


_NO_W = np.zeros((1, 1))


@register
class SuperTwistingObserver(_NormalFormEstimate, Observer):
    """Super-twisting sliding-mode observer (Davila, Fridman, Levant 2005) for ``n = 2``.

    .. math::

        \\dot{\\hat z}_1 = \\hat z_2 + \\lambda_1 L^{1/2} |e|^{1/2} \\operatorname{sign}(e),
        \\qquad
        \\dot{\\hat z}_2 = [\\hat\\varphi(y, \\hat z_2, u)] + \\lambda_2 L \\operatorname{sign}(e)

    with ``e = y - z_hat_1`` (see the module docstring for the gain conditions and the
    discretization's chattering).

    Parameters
    ----------
    system : System, optional
        A system whose single-output normal form has order 2 (``z = (y, y')``); it gives the
        map back to physical coordinates and, with ``model=True``, the model term
        ``phi`` (``System.phi_batch``). Without a system, ``order=2`` (the default then).
    L : float
        Bound of the unknown acceleration, > 0: the gains are ``k1 = lambda1 sqrt(L)`` and
        ``k2 = lambda2 L`` (Levant's scaling). Tunable.
    lambda1, lambda2 : float
        Levant's coefficients (default 1.5 and 1.1), > 0; not tuned.
    model : bool
        Add the model term ``phi(y, z_hat_2, u)`` (needs a system); ``L`` then bounds the model
        error only.
    substeps : int
        Forward-Euler steps per sample (default 1).
    order : int, optional
        Must be 2 (given or not) without a system.
    outputs : tuple of int
        The measured channel, a 1-tuple (default ``(0,)``).
    x_hat0, z_hat0 : array_like, optional
        Initial estimate (default zero).

    Raises
    ------
    DesignError
        A normal form of another order than 2, ``L``, ``lambda1`` or ``lambda2`` not a
        positive finite number, ``substeps`` not a positive integer, ``model=True`` without a
        system, or more than one output.

    References
    ----------
    J. Davila, L. Fridman, A. Levant, IEEE TAC 50(11), 2005, sec. II (observer) and III (gain
    conditions); A. Levant, Automatica 34(3), 1998; A. Levant, Int. J. Control 76, 2003.

    Examples
    --------
    >>> import numpy as np
    >>> ob = SuperTwistingObserver(L=40.0)
    >>> t = np.arange(0.0, 2.0, 1e-3)
    >>> rows = ob.run(np.sin(t)[:, None], np.zeros((t.size, 0)), 1e-3)
    >>> bool(abs(rows.z_hat[0, -1, 1] - np.cos(t[-1] + 1e-3)) < 0.1)   # y' = cos t
    True
    """

    name = "super_twisting"
    summary = "super-twisting sliding-mode observer/differentiator, gains from Levant's L"
    reference = "Davila, Fridman & Levant, IEEE TAC 50(11), 2005, sec. II-III"
    family_diagnostics = ()

    @classmethod
    def applicability(cls, system: System) -> str | None:
        """Applies to a single-output normal form of order 2 (a mechanical system,
        Davila et al. 2005, sec. II)."""
        why = super().applicability(system)
        if why is None and system.normal_form_order != 2:
            why = (f"the super-twisting observer needs a second-order normal form "
                   f"(z = (y, y'), Davila et al. 2005); {type(system).__name__}'s has order "
                   f"{system.normal_form_order}")
        return why

    def __init__(self, system: System | None = None, *, L: float = 100.0,
                 lambda1: float = 1.5, lambda2: float = 1.1, model: bool = False,
                 substeps: int = 1, order: int | None = None, outputs: Any = (0,),
                 x_hat0: Any = None, z_hat0: Any = None) -> None:
        if system is None and order is None:
            order = 2
        super().__init__(system, order=order, outputs=outputs)
        if self.n != 2:
            raise DesignError(f"the super-twisting observer needs a second-order normal form "
                              f"(z = (y, y'), Davila et al. 2005); found order {self.n}")
        if len(self.outputs) != 1:
            raise DesignError(f"{type(self).__name__} reads one output: outputs must be a "
                              f"1-tuple such as (0,); found {list(self.outputs)}")
        self.L = finite_scalar("L", L, positive=True)
        self.lambda1 = finite_scalar("lambda1", lambda1, positive=True)
        self.lambda2 = finite_scalar("lambda2", lambda2, positive=True)
        self.model = boolean("model", model)
        if self.model and system is None:
            raise DesignError("model=True needs a system providing phi")
        self.substeps = positive_int("substeps", substeps, floats=False)
        self._start_values(x_hat0, z_hat0)

    def _parameters(self) -> dict[str, Any]:
        """Levant's ``L``: ``k1 = lambda1 sqrt(L)``, ``k2 = lambda2 L`` (Levant 2003)."""
        return {"L": self.L}

    def _check_parameter(self, name: str, value: Any) -> Array:
        return np.array(finite_scalar(f"{self.name}: L", value, positive=True))

    def tuning_space(self) -> dict[str, Dimension]:
        """``L`` over ``[L / 100, 100 L]`` on a log scale: a larger ``L`` converges faster and
        rejects larger unknown accelerations, and chatters (``k2 h``) and passes noise
        (``(L eps)^{1/2}``) more."""
        return {"L": Dimension("L", self.L / L_SPAN, self.L * L_SPAN, True, self.L)}

    def gains(self, L: float | None = None) -> tuple[float, float]:
        """The gains ``(k1, k2) = (lambda1 sqrt(L), lambda2 L)``.

        Parameters
        ----------
        L : float, optional
            The scaling (default: the constructor's).

        Returns
        -------
        tuple of float
            ``(k1, k2)``.

        Examples
        --------
        >>> SuperTwistingObserver(L=100.0).gains()
        (15.0, 110.00000000000001)
        """
        L = self.L if L is None else float(L)
        return self.lambda1 * math.sqrt(L), self.lambda2 * L

    def _init(self, p: Params, x0: Array | None, z0: Array | None,
              u0: Array) -> dict[str, Any]:
        z = self._start_z(x0, z0, u0)
        return {"z": z, **self._held_fields(z, u0)}

    def _step(self, p: Params, s: State, Y: Array, U: Array, dt: float, X: Array, Z: Array,
              D: Array) -> None:
        k1, k2 = self.gains(float(p.L))
        T = Y.shape[1]
        if not self.model:
            twisting_advance(s.z, Y, _NO_W, False, k1, k2, dt, self.substeps, 0, T, Z)
        else:
            phi = self.system.phi_batch  # type: ignore[union-attr]
            W = np.empty((Y.shape[0], T))
            for j in range(T):  # phi(y, z2, u) at the start of the sample, held over it
                y = Y[:, j, 0]
                at = s.z.copy()
                at[:, 0] = np.where(np.isnan(y), at[:, 0], y)
                W[:, j] = phi(at, U[:, j])
                twisting_advance(s.z, Y, W, True, k1, k2, dt, self.substeps, j, j + 1, Z)
        self._write_x(s, Z, U, X)

    def _current(self, p: Params, s: State) -> tuple[Array, Array, Array]:
        return self._x_of(s), s.z.copy(), np.zeros((s.z.shape[0], 0))

    def params(self) -> dict[str, Any]:
        return {"L": self.L, "lambda1": self.lambda1, "lambda2": self.lambda2,
                "model": self.model, "substeps": self.substeps, "order": self.n,
                "outputs": list(self.outputs)}
