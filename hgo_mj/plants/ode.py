"""An analytic system integrated by fixed-step RK4 as the true plant (the papers' examples)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .._validate import finite_scalar, integer_multiple, vector
from ..exceptions import DesignError, DivergenceError
from ..systems.base import System
from .base import Array, Plant


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

    def reset(self, x0: Any = None) -> None:
        self._x = self._x0.copy() if x0 is None else vector("x0", x0, self._n)
        self.t = 0.0
        self._k = 0

    def step(self, u: Any) -> None:
        u = np.asarray(u, dtype=float)
        if not np.all(np.isfinite(u)):
            raise DivergenceError(f"input u must be finite; found {u.tolist()}")
        f, p, h = self.system.dynamics, self.system.params, self.physics_dt
        x, t = self._x, self.t
        for _ in range(self.substeps):
            k1 = f(t, x, u, p)
            k2 = f(t + h / 2, x + h / 2 * k1, u, p)
            k3 = f(t + h / 2, x + h / 2 * k2, u, p)
            k4 = f(t + h, x + h * k3, u, p)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            t += h
        if not np.all(np.isfinite(x)):
            raise DivergenceError(f"{type(self.system).__name__} state left the finite numbers "
                                  f"at t={t:g}: {x.tolist()}")
        self._k += 1
        self._x = x
        self.t = self._k * self.dt if math.isclose(t, (self._k) * self.dt) else t

    @property
    def state(self) -> Array:
        return self._x.copy()

    def outputs(self) -> Array:
        return np.asarray(self.system.output(self._x, self.system.params), dtype=float)
