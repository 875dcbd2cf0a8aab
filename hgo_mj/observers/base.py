"""What every observer shares: construction checks, the physical/normal-form maps, dropouts.

An observer is a continuous-time ODE in observer coordinates ``z`` driven by the measurement,
which is held constant between samples. ``update(y, u, dt)`` consumes the sample ``y(t_k)``
and the input ``u(t_k)``, integrates over one sample period and returns the estimate of
``x(t_k + dt)``. Run-time quantities (gain ``k_``, parameter estimates ``theta_hat_``, ...)
are attributes ending in ``_`` and are listed by :meth:`Observer.diagnostics`.

A NaN measurement (a sensor dropout) is never propagated: the observer integrates its
prediction without output injection over that sample and counts it in ``dropouts_``.

**Estimate layout.** ``x_hat`` has one entry per name in :attr:`Observer.state_names`. These
are the plant's state names when the observer estimates the physical state, but need not be:
an order-only observer (no system) estimates ``z1, z2, ...``, a model-free multi-output one the
outputs and their derivatives, an adaptive one may append parameter estimates. Trajectories,
metrics, figures and recordings match the estimate to the plant's states *by name*; a plant
state the observer does not name is "not estimated".

**Undefined inverse map.** ``x_hat`` is the image of the observer's own state ``z_hat`` under
the inverse normal-form map, which may be undefined there (the bioreactor's ``Phi^-1`` needs
``m > 0``; an observer started from ``z_hat = 0`` is outside it). Then ``x_hat`` holds its last
valid value, and is **NaN before any valid value**: a NaN in ``x_hat`` means "inverse map
undefined here", not divergence. Each failed evaluation is counted in ``inverse_failures_``.
Divergence is judged on ``z_hat`` (see :func:`hgo_mj.simulate.simulate`), which is always
defined.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from .._validate import vector
from ..exceptions import DesignError, DimensionError
from ..systems.base import System

Array = NDArray[np.float64]


class Observer:
    """Base class of the observers (see the module docstring for the contract)."""

    #: registry name, e.g. ``"high_gain"``
    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    reference: ClassVar[str] = ""
    #: names of the run-time quantities returned by :meth:`diagnostics`
    diagnostic_names: ClassVar[tuple[str, ...]] = ()

    def __init__(self, system: System | None, order: int | None, output: int = 0) -> None:
        if system is not None and not isinstance(system, System):
            raise DesignError(f"system must be a System instance or None; found "
                              f"{type(system).__name__}")
        if system is not None and system.normal_form_order is None:
            raise DesignError(f"{type(self).__name__} needs a single-output normal form; "
                              f"{type(system).__name__} has none")
        n_sys = None if system is None else system.normal_form_order
        if order is None and n_sys is None:
            raise DesignError(f"{type(self).__name__} needs a system or an explicit order")
        if order is not None and n_sys is not None and order != n_sys:
            raise DimensionError(f"{type(self).__name__}: order {order} does not match "
                                 f"{type(system).__name__}'s normal form order {n_sys}")
        n = int(order if order is not None else n_sys)  # type: ignore[arg-type]
        if n < 1:
            raise DesignError(f"order must be >= 1; found {n}")
        if int(output) != output or output < 0:
            raise DesignError(f"output must be a non-negative channel index; found {output!r}")
        self.system = system
        self.n = n
        self.output = int(output)
        self._u: Array = np.zeros(len(system.input_names)) if system is not None else np.zeros(0)
        self._x_last: Array | None = None
        self._restart_counters()

    # ----------------------------------------------------------- coordinates
    @property
    def state_names(self) -> tuple[str, ...]:
        """Names of the entries of ``x_hat``: the system's state names, or ``z1 ... zn`` for an
        order-only observer (no system), whose estimate is the normal-form state itself."""
        if self.system is None:
            return tuple(f"z{i + 1}" for i in range(self.n))
        return self.system.state_names

    def _initial_z(self, x_hat0: Any, z_hat0: Any, u0: Any) -> Array:
        if x_hat0 is not None and z_hat0 is not None:
            raise DesignError("give x_hat0 or z_hat0, not both")
        if z_hat0 is not None:
            return vector("z_hat0", z_hat0, self.n)
        if x_hat0 is not None:
            if self.system is None:
                return vector("x_hat0", x_hat0, self.n)
            return self.system.to_normal(vector("x_hat0", x_hat0, len(self.system.state_names)), u0)
        return np.zeros(self.n)

    def _physical(self, z: Array) -> Array:
        """Map ``z`` to physical coordinates. Where the inverse is undefined (the system raises
        :class:`DesignError`) count it in ``inverse_failures_`` and hold the last valid value
        (NaN before any). Other errors (a math domain error on a blown-up ``z``) propagate: the
        runner reports a divergence. A system's fast path that returns NaN instead of raising
        gives a NaN ``x_hat`` (also read as "undefined"), neither held nor counted: the check
        would cost a fifth of this map on the hot path."""
        if self.system is None:
            return z.copy()
        try:
            x = self.system.from_normal_unchecked(z, self._u)
        except DesignError:
            self.inverse_failures_ += 1
            if self._x_last is None:
                return np.full(len(self.system.state_names), np.nan)
            return np.array(self._x_last, dtype=float)
        self._x_last = x
        return np.array(x, dtype=float)

    def __getstate__(self) -> dict[str, Any]:
        """Pickle without a cache of compiled updates (``_steps``: functions made with
        ``exec``, which pickle cannot store); ``update`` rebuilds it on first use."""
        state = self.__dict__.copy()
        if "_steps" in state:
            state["_steps"] = {}
        return state

    def _restart_counters(self) -> None:
        """At ``reset``: no dropouts or inverse-map failures counted, no last valid estimate
        held (:meth:`_physical`)."""
        self.dropouts_ = 0
        self.inverse_failures_ = 0
        self._x_last = None

    def _bad_measurement(self, y: Any, channels: Any) -> DimensionError:
        """The error for a measurement ``y`` that lacks the channels this observer reads
        (raised from ``update``'s fast path only after indexing failed: no cost otherwise)."""
        return DimensionError(f"{self.name}: y must be a vector with channel(s) {channels} (the "
                              f"measured outputs this observer reads); found {y!r}")

    # ----------------------------------------------------------- interface
    def check_period(self, dt: float) -> None:
        """Check that ``update`` is stable at the sample period ``dt`` (the runner calls this
        before a run). Raises :class:`~hgo_mj.exceptions.DesignError` or warns, as the observer
        is configured, naming the largest stable period. Default: nothing to check."""

    def reset(self, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None) -> None:
        raise NotImplementedError

    def update(self, y: Any, u: Any, dt: float) -> Array:
        raise NotImplementedError

    @property
    def z_hat(self) -> Array:
        raise NotImplementedError

    @property
    def x_hat(self) -> Array:
        """Estimate in physical coordinates (``system.from_normal(z_hat)``)."""
        return self._physical(self.z_hat)

    def diagnostics(self) -> dict[str, float]:
        """The run-time quantities named in ``diagnostic_names`` (plus the dropout count)."""
        return {"dropouts": float(self.dropouts_)}

    def params(self) -> dict[str, Any]:
        """Constructor parameters, JSON-ready, for a trajectory's metadata."""
        return {}
