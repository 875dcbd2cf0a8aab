"""The true plant: owns time and the true state, for one member or a batch of B members.

The batched contract (what the loop drives):

* ``reset(x0=None, *, batch=None)``: ``x0`` of shape ``(n,)`` (every member) or ``(B, n)``;
  ``batch`` the number of members B. Plain ``reset()`` / ``reset(x0 (n,))`` is the unbatched
  plant (B = 1, public arrays 1-D as before); ``batch=`` or a 2-D ``x0`` makes it batched
  (``state`` ``(B, n)``, ``outputs()`` ``(B, p)``), also for B = 1.
* ``run(U, steps) -> (X, Yc)``: ``U`` ``(B, T, m)``; for each sample ``j`` the true state
  ``X[:, j]`` ``(B, T, n)`` and clean outputs ``Yc[:, j]`` ``(B, T, p)`` are recorded at the
  current instant, then ``U[:, j]`` is held for ``steps`` plant steps of ``dt`` each. After
  ``run`` the plant is at the instant after the last sample. Every member is independent and
  gives exactly (bit for bit) what it gives when run alone.
* a failure (a non-finite or out-of-range input, a state leaving the finite numbers) raises
  :class:`~hgo_mj.exceptions.DivergenceError` naming the member and the time, with the
  attributes ``member``, ``t``, ``rows`` (the samples of the block recorded for every member:
  ``X[:, :rows]``, ``Yc[:, :rows]`` are valid) and ``X``, ``Yc`` (the block's arrays, NaN where
  nothing was recorded). After a failure the plant must be reset.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..exceptions import DesignError, DimensionError, DivergenceError
from ..systems.base import System

Array = NDArray[np.float64]
_F64 = np.dtype(np.float64)


__all__ = ["Plant"]


def initial_states(x0: Any, batch: Any, default: Array, n: int) -> tuple[Array, bool]:
    """The members' initial states ``(B, n)`` (a fresh float array) and whether the plant is
    batched, from :meth:`Plant.reset`'s ``x0`` (None: ``default``; ``(n,)``: every member;
    ``(B, n)``) and ``batch`` (None or a positive integer).

    Raises
    ------
    DimensionError
        ``x0`` is neither ``(n,)`` nor ``(B, n)``, or its B differs from ``batch``.
    DesignError
        ``batch`` is not a positive integer, or ``x0`` is not finite.
    """
    if batch is not None and (isinstance(batch, bool) or not isinstance(batch, (int, np.integer))
                              or batch < 1):
        raise DesignError(f"batch must be a positive integer or None; found {batch!r}")
    if x0 is None:
        x = np.array(default, dtype=float).reshape(1, n)
    else:
        try:
            x = np.array(x0, dtype=float)
        except (TypeError, ValueError):
            raise DimensionError(f"x0 must be an array of numbers, (n,) or (B, n); found "
                                 f"{x0!r}") from None
        if x.ndim == 1:
            if x.shape != (n,):
                raise DimensionError(f"x0 must have length {n}; found length {x.size}")
            x = x.reshape(1, n)
        elif x.ndim == 2:
            if x.shape[1] != n or x.shape[0] < 1:
                raise DimensionError(f"x0 must have shape (B, {n}); found shape {x.shape}")
            if batch is not None and x.shape[0] != batch:
                raise DimensionError(f"x0 has {x.shape[0]} rows but batch is {batch}")
        else:
            raise DimensionError(f"x0 must be (n,) or (B, n) with n = {n}; found shape "
                                 f"{x.shape}")
        if not np.isfinite(x).all():
            raise DesignError(f"x0 must be finite; found {x.tolist()}")
    batched = batch is not None or (x0 is not None and np.ndim(x0) == 2)
    B = x.shape[0] if batch is None else int(batch)
    if x.shape[0] != B:
        x = np.repeat(x, B, axis=0)
    return np.ascontiguousarray(x), batched


def check_block(U: Any, steps: Any, batch: int, m: int) -> tuple[Array, int]:
    """``U`` as a C-contiguous float64 ``(B, T, m)`` array and ``steps`` as a positive int.

    Raises
    ------
    DimensionError
        ``U`` is not 3-D ``(batch, T, m)``.
    DesignError
        ``steps`` is not a positive integer.
    """
    if (type(U) is np.ndarray and U.dtype is _F64 and U.ndim == 3 and U.flags.c_contiguous
            and U.shape[0] == batch and U.shape[2] == m and type(steps) is int and steps >= 1):
        return U, steps  # already what is asked (the loop's blocks): nothing to convert
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise DesignError(f"steps must be a positive integer (plant steps per sample); found "
                          f"{steps!r}")
    try:
        u = np.ascontiguousarray(U, dtype=np.float64)
    except (TypeError, ValueError):
        raise DimensionError(f"U must be an array of numbers (B, T, m); found {U!r}") from None
    if u.ndim != 3 or u.shape[0] != batch or u.shape[2] != m:
        raise DimensionError(f"U must have shape (B, T, m) = ({batch}, T, {m}); found shape "
                             f"{u.shape}")
    return u, int(steps)


def divergence(message: str, member: int, t: float, rows: int, X: Array,
               Yc: Array) -> DivergenceError:
    """A :class:`DivergenceError` carrying ``member``, ``t``, ``rows`` and the block's
    ``X``, ``Yc`` (see the module docstring)."""
    exc = DivergenceError(message)
    exc.member, exc.t, exc.rows = member, t, rows  # type: ignore[attr-defined]
    exc.X, exc.Yc = X, Yc  # type: ignore[attr-defined]
    return exc


class Plant(ABC):
    """A simulated plant (module docstring). The one primitive is :meth:`run` (a block of
    samples for B members); with :meth:`reset`, :attr:`state` and :meth:`outputs` it is the
    whole abstract surface. :meth:`step` (one control period) is derived from :meth:`run`.

    Attributes
    ----------
    system : System
        The analytic model the plant is described by (names, parameters, default state).
    dt : float
        Control period, seconds (or the plant's own time unit).
    t : float
        Current time.

    Examples
    --------
    A plant of a registered system (an :class:`~hgo_mj.plants.ode.OdePlant` here) driven
    through the batched primitive:

    >>> import numpy as np
    >>> from hgo_mj.plants import make_plant
    >>> plant = make_plant("jo_son", dt=0.01)
    >>> isinstance(plant, Plant), plant.state_names, plant.batch, plant.batched
    (True, ('x1', 'x2', 'x3'), 1, False)
    >>> X, Yc = plant.run(np.zeros((1, 3, 1)), 2)  # 3 samples of 2 plant steps
    >>> X.shape, Yc.shape, round(plant.t, 6)
    ((1, 3, 3), (1, 3, 1), 0.06)
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

    #: number of members (set by :meth:`reset`)
    batch: int = 1
    #: whether the plant was reset batched (public arrays with a leading axis B)
    batched: bool = False

    @abstractmethod
    def reset(self, x0: Any = None, *, batch: int | None = None) -> None:
        """Set time to zero and the state to ``x0`` (default: ``system.default_x0``):
        ``(n,)`` for every member or ``(B, n)``; ``batch`` the number of members.

        Parameters
        ----------
        x0 : array_like, optional
            Initial state ``(n,)`` (every member) or ``(B, n)`` (one per member); default
            ``system.default_x0``. A 2-D ``x0`` makes the plant batched.
        batch : int, optional
            Number of members B; given, the plant is batched (also for B = 1) and a 2-D
            ``x0`` must have B rows. Default: one member, or as many as ``x0`` rows.

        Raises
        ------
        DimensionError
            ``x0`` is neither ``(n,)`` nor ``(B, n)``, or its B differs from ``batch``
            (raised by the implementations).
        DesignError
            ``batch`` is not a positive integer, or ``x0`` is not finite.

        Examples
        --------
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("jo_son", dt=0.01)
        >>> plant.reset([0.5, 1.0, -1.0], batch=2)
        >>> plant.batch, plant.batched, plant.state.shape, plant.t
        (2, True, (2, 3), 0.0)
        """

    @abstractmethod
    def run(self, U: Any, steps: int) -> tuple[Array, Array]:
        """Advance ``U.shape[1]`` samples of ``steps`` plant steps each (module docstring).

        Parameters
        ----------
        U : array_like, shape (B, T, m)
            The input of every member at every sample, held over the sample.
        steps : int
            Plant steps (each :attr:`dt`) per sample.

        Returns
        -------
        X : ndarray, shape (B, T, n)
            The true state at each sample instant, before its input is applied.
        Yc : ndarray, shape (B, T, p)
            The clean outputs at the same instants.

        Raises
        ------
        DimensionError
            ``U`` is not ``(B, T, m)``.
        DivergenceError
            A member's input or state left the allowed numbers (message names the member and
            the time; attributes ``member``, ``t``, ``rows``, ``X``, ``Yc``).

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("jo_son", dt=0.01)
        >>> plant.reset([[0.5, 1.0, -1.0], [0.0, 0.0, 0.0]])  # two members
        >>> X, Yc = plant.run(np.zeros((2, 4, 1)), 1)
        >>> X.shape, X[:, 0].tolist(), round(plant.t, 6)
        ((2, 4, 3), [[0.5, 1.0, -1.0], [0.0, 0.0, 0.0]], 0.04)
        """

    def bind_run(self, U: Array, steps: int, X: Array, Yc: Array) -> Any:
        """A bound run of one member (B = 1) over its own buffers, for a caller that steps
        the same block shapes many times (:meth:`hgo_mj.loop.Loop.bind_step`): ``run()``
        advances the samples of ``U`` ``(1, T, m)`` as :meth:`run` does, writes the rows
        into ``X`` ``(1, T, n)`` and ``Yc`` ``(1, T, p)``, and returns True; False, with
        nothing changed, where an input is one :meth:`run` refuses (the caller then calls
        :meth:`run`, which raises its error). It raises :meth:`run`'s
        :class:`DivergenceError` for a state that leaves the allowed numbers.

        Parameters
        ----------
        U, X, Yc : ndarray
            The caller's buffers, float64, C-contiguous, of one member; ``U`` is read at
            every call.
        steps : int
            Plant steps per sample.

        Returns
        -------
        callable or None
            ``run()``; None here (a plant without a bound run: the caller uses :meth:`run`).

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.plants import make_plant
        >>> a, b = make_plant("pendulum", dt=0.01), make_plant("pendulum", dt=0.01)
        >>> a.reset([0.2, 0.0]); b.reset([0.2, 0.0])
        >>> U, X, Yc = np.full((1, 3, 1), 0.5), np.empty((1, 3, 2)), np.empty((1, 3, 1))
        >>> run = a.bind_run(U, 1, X, Yc)  # a MuJoCo plant's (this base class gives None)
        >>> run(), X.tolist() == b.run(U, 1)[0].tolist(), a.state.tolist() == b.state.tolist()
        (True, True, True)
        """
        return None

    @property
    @abstractmethod
    def state(self) -> Array:
        """A copy of the true physical state: ``(n,)`` unbatched, ``(B, n)`` batched."""

    @abstractmethod
    def outputs(self) -> Array:
        """The clean measured outputs at the current time (a fresh array): ``(p,)``
        unbatched, ``(B, p)`` batched.

        Returns
        -------
        ndarray
            ``(p,)`` for an unbatched plant, ``(B, p)`` for a batched one, in the order of
            :attr:`output_names`.

        Examples
        --------
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("jo_son", dt=0.01)
        >>> plant.output_names, plant.outputs().tolist()
        (('y',), [0.5])
        """

    def step(self, u: Any) -> None:
        """Advance one control period ``dt`` with the input ``u`` held: ``(m,)`` (a scalar
        for one input), or ``(B, m)`` for a batched plant: :meth:`run` of one sample of one
        plant step (what it records is dropped).

        Parameters
        ----------
        u : array_like
            The input held over ``dt``: ``(m,)`` (or a scalar for one input) for an unbatched
            plant, ``(B, m)`` for a batched one.

        Raises
        ------
        DimensionError
            ``u`` is not ``(m,)`` (unbatched) or ``(B, m)`` (batched).
        DivergenceError
            As :meth:`run`.

        Examples
        --------
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("jo_son", dt=0.01)
        >>> plant.step([0.0])
        >>> round(plant.t, 6), plant.state.shape
        (0.01, (3,))
        """
        m = len(self.input_names)
        try:
            a = np.asarray(u, dtype=np.float64)
        except (TypeError, ValueError):
            raise DimensionError(f"u must be an array of numbers; found {u!r}") from None
        want = (self.batch, m) if self.batched else (m,)
        if a.shape != want and (self.batched or a.ndim > 1 or a.size != m):
            raise DimensionError(f"u must have shape {want}; found shape {a.shape}")
        self.run(a.reshape(self.batch, 1, m), 1)
