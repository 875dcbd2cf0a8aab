"""The true plant: owns time and the true state."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..systems.base import System

Array = NDArray[np.float64]


class Plant(ABC):
    """A simulated plant. ``step(u)`` advances one control period with ``u`` held.

    Attributes
    ----------
    system : System
        The analytic model the plant is described by (names, parameters, default state).
    dt : float
        Control period, seconds (or the plant's own time unit).
    t : float
        Current time.
    """

    system: System
    dt: float
    t: float

    @property
    def state_names(self) -> tuple[str, ...]:
        return self.system.state_names

    @property
    def input_names(self) -> tuple[str, ...]:
        return self.system.input_names

    @property
    def output_names(self) -> tuple[str, ...]:
        return self.system.output_names

    @abstractmethod
    def reset(self, x0: Any = None) -> None:
        """Set time to zero and the state to ``x0`` (default: ``system.default_x0``)."""

    @abstractmethod
    def step(self, u: Any) -> None:
        """Advance one control period ``dt`` with the input ``u`` held."""

    @property
    @abstractmethod
    def state(self) -> Array:
        """A copy of the true physical state."""

    @abstractmethod
    def outputs(self) -> Array:
        """The clean measured outputs at the current time (a fresh array)."""

    def state_list(self) -> list[float]:
        """:attr:`state` as a list of Python floats (the same values), for per-sample loops;
        plants override it with a path that builds no array."""
        return np.asarray(self.state, dtype=float).tolist()  # type: ignore[no-any-return]

    def outputs_list(self) -> list[float]:
        """:meth:`outputs` as a list of Python floats (the same values), for per-sample loops."""
        return np.asarray(self.outputs(), dtype=float).tolist()  # type: ignore[no-any-return]

    def step_list(self, u: list[float]) -> None:
        """:meth:`step` with ``u`` a list of Python floats, for per-sample loops (plants whose
        ``step`` takes any sequence alias it to ``step``)."""
        self.step(np.array(u, dtype=float))
