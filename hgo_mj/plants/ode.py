"""An analytic system integrated by fixed-step RK4 as the true plant (the papers' examples).

Runs (:meth:`OdePlant.run`, one member or B; :meth:`Plant.step` is one sample of it)
integrate every member with the classical RK4 below. A system that offers a vectorized
``dynamics_batch(t, X, U, p)`` (rows ``X`` ``(B, n)``, ``U`` ``(B, m)``, returning ``(B, n)``) and optionally
``output_batch(X, p)`` ``(B, p)`` is integrated over the rows at once with numpy; otherwise
(every shipped system today) the members are integrated one after the other in a Python loop.
Either way a member gives the bits it gives alone: the loop calls the very same
``dynamics``; ``dynamics_batch`` must evaluate, row by row, the same floating-point operations
as ``dynamics`` (tested with a system written both ways).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from .._validate import DIVERGED_ABOVE, finite_scalar, integer_multiple, vector
from ..exceptions import DesignError
from ..systems.base import System
from .base import Array, Plant, check_block, divergence, initial_states

__all__ = ["OdePlant"]


def _rk4(f: Callable[..., Any], p: Mapping[str, float], x: Any, u: Any, t: float, h: float,
         substeps: int) -> tuple[Any, float]:
    """``substeps`` classical RK4 steps of ``h`` from ``(t, x)`` with ``u`` held: the new state
    and time. ``x`` is ``(n,)`` with ``f = dynamics`` or ``(B, n)`` with ``f = dynamics_batch``
    (the same operations row by row)."""
    for _ in range(substeps):
        k1 = f(t, x, u, p)
        k2 = f(t + h / 2, x + h / 2 * k1, u, p)
        k3 = f(t + h / 2, x + h / 2 * k2, u, p)
        k4 = f(t + h, x + h * k3, u, p)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        t += h
    return x, t


class OdePlant(Plant):
    """A :class:`System` integrated with classical fixed-step RK4.

    Parameters
    ----------
    system : System
        The system instance (its ``params`` are the true parameters).
    dt : float
        Control period; ``u`` is held over it.
    physics_dt : float, optional
        RK4 step; default ``dt / 10``. ``dt`` must be a multiple of it.

    Examples
    --------
    >>> from hgo_mj.systems import SYSTEMS
    >>> plant = OdePlant(SYSTEMS["jo_son"](), dt=0.01)
    >>> plant.reset(plant.system.default_x0)
    >>> plant.step([0.0])
    >>> plant.state.shape, plant.system.output_names
    ((3,), ('y',))
    """

    def __init__(self, system: System, dt: float, *, physics_dt: float | None = None) -> None:
        if not isinstance(system, System):
            raise DesignError(f"system must be a System instance; found {type(system).__name__}")
        self.system = system
        self.dt = finite_scalar("dt", dt, positive=True)
        self.physics_dt = (self.dt / 10 if physics_dt is None
                           else finite_scalar("physics_dt", physics_dt, positive=True))
        self.substeps = integer_multiple("dt", self.dt, self.physics_dt, "physics_dt")
        self.physics_dt = self.dt / self.substeps
        self._n = len(system.state_names)
        self._x0 = vector("system.default_x0", system.default_x0, self._n)
        self.reset()

    def reset(self, x0: Any = None, *, batch: int | None = None) -> None:
        X0, self.batched = initial_states(x0, batch, self._x0, self._n)
        self.batch = X0.shape[0]
        #: the members' states (B, n); ``_x`` is row 0 (the unbatched plant's state)
        self._X = X0
        self._x = X0[0].copy()
        self.t = 0.0
        self._k = 0

    def _advance_time(self) -> None:
        """One plant step of the clock: ``substeps`` additions of ``physics_dt``, then the
        time snapped to ``k * dt`` when it is that to rounding (the clock of every run)."""
        t = self.t
        for _ in range(self.substeps):
            t += self.physics_dt
        self._k += 1
        self.t = self._k * self.dt if math.isclose(t, self._k * self.dt) else t

    def run(self, U: Any, steps: int) -> tuple[Array, Array]:
        """Advance ``T`` samples of ``steps`` plant steps for every member (see
        :meth:`Plant.run`): rows integrated together through ``system.dynamics_batch`` where
        the system has it, else member by member (module docstring)."""
        U, steps = check_block(U, steps, self.batch, len(self.system.input_names))
        B, T, _ = U.shape
        X = np.full((B, T, self._n), np.nan)
        Yc = np.full((B, T, len(self.output_names)), np.nan)
        # the clock is the same for every member: the start time of each plant step
        starts = np.empty(T * steps)
        for i in range(T * steps):
            starts[i] = self.t
            self._advance_time()
        bad_u = ~np.all(np.isfinite(U), axis=2)          # (B, T)
        batch_f = getattr(self.system, "dynamics_batch", None)
        fails: list[tuple[int, int, str]] = []            # (sample, member, message)
        if batch_f is not None:
            self._run_rows(batch_f, U, steps, starts, bad_u, X, Yc, fails)
        else:
            self._run_members(U, steps, starts, bad_u, X, Yc, fails)
        if fails:
            j, b, msg = min(fails)
            raise divergence(f"member {b}: {msg}", b, float(starts[j * steps]), j + 1, X, Yc)
        self._x = self._X[0].copy()
        return X, Yc

    def _fail_message(self, x: Any, t: float) -> str:
        return (f"{type(self.system).__name__} state left the finite numbers at t={t:g}: "
                f"{np.asarray(x).tolist()}")

    def _run_members(self, U: Array, steps: int, starts: Array, bad_u: Array, X: Array,
                     Yc: Array, fails: list[tuple[int, int, str]]) -> None:
        """Member after member, each through ``system.dynamics`` on 1-D states."""
        f, out, p = self.system.dynamics, self.system.output, self.system.params
        h, sub, T = self.physics_dt, self.substeps, U.shape[1]
        st = starts.tolist()
        for b in range(U.shape[0]):
            x = self._X[b].copy()
            for j in range(T):
                X[b, j] = x
                Yc[b, j] = np.asarray(out(x, p), dtype=float)
                if bad_u[b, j]:
                    fails.append((j, b, f"input u must be finite; found {U[b, j].tolist()} at "
                                        f"t={st[j * steps]:g}"))
                    break
                u = U[b, j]
                for s in range(steps):
                    x, t = _rk4(f, p, x, u, st[j * steps + s], h, sub)
                    if not np.all(np.abs(x) <= DIVERGED_ABOVE):
                        fails.append((j, b, self._fail_message(x, t)))
                        break
                else:
                    continue
                break
            self._X[b] = x

    def _run_rows(self, f: Callable[..., Any], U: Array, steps: int, starts: Array,
                  bad_u: Array, X: Array, Yc: Array, fails: list[tuple[int, int, str]]) -> None:
        """All rows at once with ``dynamics_batch`` (and ``output_batch`` where given); a row
        that fails is recorded and carried along (rows do not interact), the others go on."""
        sysm, p = self.system, self.system.params
        out_b = getattr(sysm, "output_batch", None)
        h, sub, (B, T, _) = self.physics_dt, self.substeps, U.shape
        x = self._X.copy()
        alive = np.ones(B, dtype=bool)
        st = starts.tolist()
        with np.errstate(all="ignore"):
            for j in range(T):
                X[alive, j] = x[alive]
                if out_b is not None:
                    Yc[alive, j] = np.asarray(out_b(x[alive], p), dtype=float)
                else:
                    for b in np.flatnonzero(alive).tolist():
                        Yc[b, j] = np.asarray(sysm.output(x[b], p), dtype=float)
                for b in np.flatnonzero(alive & bad_u[:, j]).tolist():
                    fails.append((j, b, f"input u must be finite; found {U[b, j].tolist()} at "
                                        f"t={st[j * steps]:g}"))
                    alive[b] = False
                u = U[:, j]
                for s in range(steps):
                    xn, t = _rk4(f, p, x, u, st[j * steps + s], h, sub)
                    broke = alive & ~np.all(np.abs(xn) <= DIVERGED_ABOVE, axis=1)
                    for b in np.flatnonzero(broke).tolist():
                        fails.append((j, b, self._fail_message(xn[b], t)))
                    alive &= ~broke
                    x = np.where(alive[:, None], xn, x)
        self._X[:] = x

    @property
    def state(self) -> Array:
        if self.batched:
            return self._X.copy()
        return self._x.copy()

    def outputs(self) -> Array:
        if self.batched:
            out, p = self.system.output, self.system.params
            return np.array([np.asarray(out(x, p), dtype=float) for x in self._X])
        # a fresh array even where a system's output hands back a view of the state
        return np.array(self.system.output(self._x, self.system.params), dtype=float)
