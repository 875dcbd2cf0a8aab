"""The one loop: plant -> sensor chain -> observers, B members at once.

Timing (all periods exact integer multiples of each other)::

    physics_dt | plant.dt | sample_period | control_period

:class:`Loop` owns the periods and the parts. Its one kernel is :meth:`Loop.segment`: over T
consecutive samples with the inputs ``U`` (B, T, m) it records the true state and the clean
outputs at each sample instant while the plant holds ``U[:, j]`` for one sample period
(``plant.run``), passes the clean outputs through the sensor chain (``sensor.apply``, B seeded
streams) and advances every observer over the T measurements (``Observer.step``). The
callers choose T: :func:`hgo_mj.simulate.simulate` runs an open-loop input in long segments and
a feedback law one control period at a time, an environment one control period per ``step``
(one member: the same pieces, bound once at its reset, :meth:`Loop.bind_step`).

The loop holds each observer's state and parameters as data (:attr:`Loop.states`,
:attr:`Loop.params`; :meth:`Observer.init`, :meth:`Observer.parameters`): one batch may hold
members with different parameters (``params=``), each member its own single run. An observer
that fails inside a segment (a math error on a blown-up estimate, its own divergence check) is
found to the sample: the step is pure, so the state before a segment of more than one sample
is still there and, on a failure, the loop replays that observer sample by sample from it.
The :class:`LoopFailure` it raises names the observer, the sample and
the cause, and carries the rows that are valid.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._validate import finite_scalar, integer_multiple
from .exceptions import DesignError, DimensionError, DivergenceError
from .inputs import Controller, FunctionSignal, Signal
from .observers.base import Block, Observer, Params, State
from .plants.base import Plant
from .sensors import SensorChain

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Periods:
    """The loop's periods: ``sample`` and ``control`` (seconds), ``steps`` plant steps per
    sample and ``every`` samples per control period.

    Parameters
    ----------
    sample : float
        Sample period, seconds (a multiple of ``plant.dt``).
    control : float
        Control period, seconds (a multiple of ``sample``).
    steps : int
        Plant steps per sample (``sample / plant.dt``).
    every : int
        Samples per control period (``control / sample``).

    Examples
    --------
    >>> from hgo_mj.plants import make_plant
    >>> Periods.of(make_plant("pendulum", dt=0.01), 0.02, 0.1)
    Periods(sample=0.02, control=0.1, steps=2, every=5)
    """

    sample: float
    control: float
    steps: int
    every: int

    @classmethod
    def of(cls, plant: Plant, sample_period: Any = None, control_period: Any = None) -> Periods:
        """Validated periods: defaults ``plant.dt`` and ``sample_period``, each a positive
        integer multiple of the one before.

        Parameters
        ----------
        plant : Plant
            The plant whose ``dt`` the sample period is a multiple of.
        sample_period : float, optional
            Seconds between samples (default ``plant.dt``).
        control_period : float, optional
            Seconds between control instants (default ``sample_period``).

        Returns
        -------
        Periods
            The periods with ``steps = sample_period / plant.dt`` and
            ``every = control_period / sample_period``.

        Raises
        ------
        DesignError
            A period that is not a finite positive number, or not an integer multiple of
            the one before it.

        Examples
        --------
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> Periods.of(plant)
        Periods(sample=0.01, control=0.01, steps=1, every=1)
        >>> Periods.of(plant, sample_period=0.05, control_period=0.2).every
        4
        """
        Ts = plant.dt if sample_period is None else finite_scalar(
            "sample_period", sample_period, positive=True)
        steps = integer_multiple("sample_period", Ts, plant.dt, "plant.dt")
        Tc = Ts if control_period is None else finite_scalar(
            "control_period", control_period, positive=True)
        every = integer_multiple("control_period", Tc, Ts, "sample_period")
        return cls(Ts, Tc, steps, every)


@dataclass
class Segment:
    """What :meth:`Loop.segment` produced over T samples of B members.

    ``x``, ``y_clean``, ``y_meas``, ``u`` are the rows at the sample instants ``t`` (the state
    before the plant moved on); ``blocks[name]`` holds each observer's estimate *after* each
    sample (:class:`~hgo_mj.observers.base.Block`), ``before[name]`` its estimate before
    sample 0 (``(B, n_x)``, ``(B, n)``, ``(B, d)``).

    Parameters
    ----------
    t : ndarray, shape (T,)
        Sample instants, seconds.
    x : ndarray, shape (B, T, n)
        True state at each instant.
    y_clean, y_meas : ndarray, shape (B, T, p)
        Clean outputs and the sensor chain's measurements of them.
    u : ndarray, shape (B, T, m)
        Input held from each instant over one sample period.
    blocks : dict of str to Block
        Each observer's ``x_hat`` ``(B, T, n_x)``, ``z_hat`` ``(B, T, n)`` and
        ``diagnostics`` ``(B, T, d)`` after each sample.
    before : dict of str to tuple of ndarray
        Each observer's ``(x_hat, z_hat, diagnostics)`` before sample 0, ``(B, ...)`` each
        (empty for a loop built with ``exact=False``).

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> plant = make_plant("pendulum", dt=0.01)
    >>> loop = Loop(plant, None, {"hgo": HighGainObserver(plant.system, k=10.0)},
    ...             Periods.of(plant))
    >>> loop.reset([0.2, 0.0])
    >>> seg = loop.segment(np.zeros((1, 5, 1)))
    >>> len(seg), seg.x.shape, seg.blocks["hgo"].x_hat.shape, seg.before["hgo"][0].shape
    (5, (1, 5, 2), (1, 5, 2), (1, 2))
    """

    t: Array
    x: Array
    y_clean: Array
    y_meas: Array
    u: Array
    blocks: dict[str, Block]
    before: dict[str, tuple[Array, Array, Array]]

    def __len__(self) -> int:
        return int(self.t.size)


class LoopFailure(Exception):
    """An observer's update or the plant failed inside a segment at sample ``row`` (the run's
    sample index). ``segment`` holds the rows ``..row`` that are valid (the plant's and sensor's
    through ``row``; each observer's estimate before each of them), ``observer`` names the
    observer (None: the plant).

    Parameters
    ----------
    observer : str or None
        Name of the observer that failed; ``None`` when the plant failed.
    row : int
        The run's sample index of the failure.
    t : float
        The sample instant of the failure, seconds.
    cause : BaseException
        The original error (also the exception's ``__cause__`` when raised by the loop).
    segment : Segment
        The valid rows of the segment up to ``row``.

    Examples
    --------
    >>> import numpy as np
    >>> seg = Segment(np.zeros(0), *(np.zeros((1, 0, 1)),) * 4, {}, {})
    >>> exc = LoopFailure("hgo", 3, 0.03, ValueError("math domain error"), seg)
    >>> str(exc), exc.observer, exc.row
    ('hgo at t=0.03 (row 3): math domain error', 'hgo', 3)
    """

    def __init__(self, observer: str | None, row: int, t: float, cause: BaseException,
                 segment: Segment) -> None:
        super().__init__(f"{observer or 'plant'} at t={t:g} (row {row}): {cause}")
        self.observer, self.row, self.t, self.cause, self.segment = (observer, row, t, cause,
                                                                      segment)


class _Continue:
    """The type of :data:`CONTINUE`."""

    def __repr__(self) -> str:
        return "CONTINUE"


#: ``Loop.reset(seed=CONTINUE)``: restart the sensor stages, let their generators continue
#: (an environment's ``reset()`` without a seed)
CONTINUE = _Continue()

#: what an observer's failure inside an update may be (a shape mistake, DimensionError, is not)
_FAILURES = (DivergenceError, ValueError, ArithmeticError)


def check_fits(name: str, ob: Observer, output_names: Sequence[str],
               input_names: Sequence[str]) -> None:
    """Raise :class:`DimensionError` unless the observer's output channels and input width are
    those of the plant with these outputs and inputs (checked before a run, not found deep in
    an update)."""
    p, m = len(output_names), len(input_names)
    bad = [o for o in ob.outputs if o >= p]
    if bad:
        raise DimensionError(f"observer {name!r} reads output channel(s) {bad}; the plant has "
                             f"{p} output(s) {list(output_names)} (channels 0..{p - 1})")
    if ob.n_inputs is not None and ob.n_inputs != m:
        raise DimensionError(f"observer {name!r} takes {ob.n_inputs} input(s); the plant has {m} "
                             f"{list(input_names)}")


class Loop:
    """Plant, sensor chain and observers stepped together at their periods, B members.

    Parameters
    ----------
    plant : Plant
        The true plant (batched through ``reset(x0, batch=B)`` and ``run``).
    sensor : SensorChain or None
        Applied to the clean outputs; ``None`` measures exactly.
    observers : mapping name -> Observer
        Every observer sees the same measurement stream and the same input.
    periods : Periods
        The sample and control periods (:meth:`Periods.of`).
    exact : bool
        Keep what a stored run needs (default): each observer's estimate before a segment,
        and a copy of its state before a segment of several samples, so that a failure is
        found to the sample (see the module docstring). An environment, which keeps no rows,
        turns it off: a failure then stops at the segment, and the observers' rows of a
        :class:`Segment` are written again by the next segment of the same length (keep a
        copy to keep them).
    isolate : bool
        An observer whose update fails stops alone (:attr:`failed` records the sample, the
        time and the error; its rows are NaN from then on) and the others run the segment to
        its end; default False: :meth:`segment` raises :class:`LoopFailure`.
    params : mapping name -> dict, optional
        Per observer, parameter values for :meth:`Observer.parameters` (one value for every
        member, or one per member with a leading B: many tunings in one batch); default each
        observer's own.

    Attributes
    ----------
    states : dict of str to State
        Each observer's state (the loop holds it; the observer's own :attr:`Observer.state`
        follows it, so ``observer.x_hat`` reads the last estimate of a run).
    params : dict of str to Params
        Each observer's parameters of the current batch.

    Raises
    ------
    DesignError
        ``plant`` is not a Plant, ``sensor`` not a SensorChain or None, an observer not an
        Observer, or ``params`` naming an observer the loop does not have.

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.sensors import GaussianNoise, SensorChain
    >>> plant = make_plant("pendulum", dt=0.01)
    >>> loop = Loop(plant, SensorChain([GaussianNoise(std=1e-3)]),
    ...             {"hgo": HighGainObserver(plant.system, k=10.0)}, Periods.of(plant))
    >>> loop.reset([0.2, 0.0], seed=1)
    >>> seg = loop.segment(np.zeros((1, 10, 1)))  # 10 samples, zero input
    >>> loop.k, round(loop.t, 6), seg.y_meas.shape
    (10, 0.1, (1, 10, 1))
    """

    def __init__(self, plant: Plant, sensor: SensorChain | None,
                 observers: Mapping[str, Observer], periods: Periods, *,
                 exact: bool = True, isolate: bool = False,
                 params: Mapping[str, Mapping[str, Any]] | None = None) -> None:
        if not isinstance(plant, Plant):
            raise DesignError(f"plant must be a Plant; found {type(plant).__name__}")
        if sensor is not None and not isinstance(sensor, SensorChain):
            raise DesignError(f"sensor must be a SensorChain or None; found "
                              f"{type(sensor).__name__}")
        for name, ob in observers.items():
            if not isinstance(ob, Observer):
                raise DesignError(f"observer {name!r} must be an Observer; found "
                                  f"{type(ob).__name__}")
        self.plant, self.sensor, self.periods = plant, sensor, periods
        self.observers = dict(observers)
        values = dict(params or {})
        unknown = sorted(set(values) - set(self.observers))
        if unknown:
            raise DesignError(f"params names observer(s) {unknown} the loop does not have; it "
                              f"has {list(self.observers)}")
        #: per observer, the parameter values given (``Observer.parameters(B, **values)``)
        self._values = {name: dict(v) for name, v in values.items()}
        self.states: dict[str, State] = {}
        self.params: dict[str, Params] = {}
        #: the observers whose kernels a throw-away sample has warmed (:meth:`_warm_up`)
        self._warm: set[str] = set()
        #: per observer, the last reset's (B, constructor values, checked Params, initial
        #: State: a template, copied at each reset)
        self._checked: dict[str, tuple[int, Any, Params, State]] = {}
        self.exact = bool(exact)
        if not isinstance(isolate, bool):
            raise DesignError(f"isolate must be true or false; found {isolate!r}")
        #: an observer that fails stops alone (its rows NaN from then on), the others go on
        self.isolate = isolate
        #: the observers stopped by a failure: name -> (sample index, time, the error)
        self.failed: dict[str, tuple[int, float, BaseException]] = {}
        self.batch = 1
        self.k = 0
        #: seconds spent in each observer's updates since the reset, warm (the kernels'
        #: compilation or cache load is spent before, on a throw-away sample: :meth:`_warm_up`;
        #: the observers take turns at running first in a segment: :meth:`_rotated`)
        self.wall: dict[str, float] = {}
        #: (sample index, measurement) drawn by :meth:`sample` and not yet consumed
        self._pending: tuple[int, Array] | None = None
        #: each observer's last block, written again by the next segment (exact=False only)
        self._blocks: dict[str, Block] = {}
        #: the segments since the reset whose observers took turns (:meth:`_rotated`)
        self._turn = 0
        #: the last :meth:`bind_step`: (T, the observer's Params, the step)
        self._binding: tuple[int, Params | None, Callable[[Sequence[float]], None]] | None = None

    @property
    def t(self) -> float:
        """The current sample instant."""
        return self.k * self.periods.sample

    def reset(self, x0: Any = None, *, seed: Any = None, batch: int | None = None,
              start: Callable[[Observer, Array], Array] | None = None
              ) -> tuple[Array, Array, Array] | None:
        """Restart every part: the plant from ``x0`` (``(n,)`` or ``(B, n)``; default the
        system's), the sensor streams from ``seed`` (an int or None for one stream, a sequence
        of B seeds for B), each observer from its own initial estimate; check each observer's
        output channels and inputs against the plant and its sample period (a too-long period
        for a high gain is refused here, before any work).

        Parameters
        ----------
        x0 : array_like, optional
            Initial true state ``(n,)``, or ``(B, n)`` for B members (default
            ``plant.system.default_x0``).
        seed : int, sequence of int, CONTINUE or None
            Seed(s) of the sensor chain's streams: one (or None) for one stream, B for B
            members; :data:`CONTINUE` restarts the stages and lets their generators go on.
        batch : int, optional
            Number of members B (default: one unbatched member, or as many as ``x0`` rows).
        start : callable, optional
            ``start(observer, Y)``: each observer's initial estimate ``(B, n_x)`` made from the
            first measurement ``Y`` ``(B, p)`` (drawn here, as :meth:`sample` draws it, and
            consumed by the first segment): an environment's start from its first measurement.
            The state is made from it directly (:meth:`start_observers` after a reset does the
            same, the state made twice). Default: each observer's own initial estimate.

        Returns
        -------
        tuple of ndarray or None
            With ``start`` and at least one observer: the first sample, ``(X, Yc, Ym)`` as
            :meth:`sample` gives it (the caller's own arrays: an environment's first
            observation is made from them, not from a second :meth:`sample`); else None.

        Raises
        ------
        DimensionError
            The sensor chain has a different number of streams than the plant has members,
            or an observer's output channels or input width do not fit the plant.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> loop = Loop(plant, None, {"hgo": HighGainObserver(plant.system, k=10.0)},
        ...             Periods.of(plant))
        >>> loop.reset([[0.2, 0.0], [0.1, 0.0]], batch=2)
        >>> loop.batch, loop.k
        (2, 0)
        """
        self.plant.reset(x0, batch=batch)
        B = self.plant.batch
        if self.sensor is not None:
            if seed is CONTINUE:
                self.sensor.restart()
            else:
                self.sensor.reset(seed)
            if self.sensor.batch != B:
                raise DimensionError(f"the sensor chain has {self.sensor.batch} stream(s) for "
                                     f"{B} plant(s): give one seed per member")
        batched = batch is not None or bool(getattr(self.plant, "batched", False))
        self.batch, self.k, self._turn = B, 0, 0
        self._pending = None
        first = None if start is None or not self.observers else self.sample()
        for name, ob in self.observers.items():  # as many members as plants
            p, self.states[name] = self._checked_start(
                name, ob, B, None if first is None else start(ob, first[2][:, 0]))  # type: ignore[misc]
            self.params[name] = p
            ob._hold(p, self.states[name], batched)
            if name not in self._warm:
                self._warm_up(ob, p, self.states[name])
                self._warm.add(name)
        self.wall = dict.fromkeys(self.observers, 0.0)
        self.failed = {}
        return first

    def _checked_start(self, name: str, ob: Observer, B: int,
                       x_hat0: Array | None = None) -> tuple[Params, State]:
        """The parameters of ``B`` members of the observer ``name``, checked against the plant
        (:func:`check_fits`) and the sample period (:meth:`Observer.check_period`), and a new
        initial state: from ``x_hat0`` ``(B, n_x)`` where given (:meth:`Observer._start_from`, the
        rows' checks only), else the constructor's initial estimate (:meth:`Observer.init`).
        Validate once: the parameters are made and checked again only where ``B`` or the
        observer's constructor values (:meth:`Observer.params`, JSON: compared as they are)
        differ from the last reset's; else the last reset's read-only :class:`Params` serve
        again and the state is a copy of the last reset's initial one (an environment's reset
        then pays no parameter construction, grouping, period check or ``init``: the initial
        state depends on ``B``, the parameters and the constructor's initial estimate only)."""
        mark = ob.params()
        found = self._checked.get(name)
        if found is not None and found[0] == B and found[1] == mark:
            return found[2], (found[3].copy() if x_hat0 is None else ob._start_from(found[2], x_hat0))
        check_fits(name, ob, self.plant.output_names, self.plant.input_names)
        p = ob.parameters(B, **self._values.get(name, {}))
        ob.check_period(self.periods.sample, p)
        s0 = ob.init(B, params=p)
        self._checked[name] = (B, mark, p, s0.copy())
        return p, (s0 if x_hat0 is None else ob._start_from(p, x_hat0))

    def _warm_up(self, ob: Observer, p: Params, state: State) -> None:
        """Two throw-away samples of copies of member 0 (the plant's clean output, zero
        input): it compiles or loads the family's kernels (numba's dispatch and cache), so
        that the wall time the loop reports per update (:attr:`wall`) is the warm cost, the
        same whichever observer runs first. Its outcome is discarded; a failure here is not
        the run's (the run meets it again where it is real).

        As many members as the run, up to two, and two samples: the views a family hands its
        kernels (a sample's column ``Z[:, j]``, the family's diagnostics ``D[..., :nd]``) then
        have the layout of a segment's (numba compiles a kernel once per layout; one member
        and one sample made them C-contiguous where a segment's are strided, and every such
        kernel compiled twice, issue 28)."""
        y = np.asarray(self.plant.outputs(), dtype=np.float64).reshape(self.plant.batch, 1, -1)
        rows = [0] * min(self.plant.batch, 2)
        Y = np.repeat(y[rows], 2, axis=1)
        U = np.zeros((len(rows), 2, len(self.plant.input_names)))
        try:
            ob._step_checked(p.take(rows), state.take(rows), Y, U, self.periods.sample)
        except Exception:  # noqa: BLE001, S110 - a warm-up only; its result is discarded
            pass

    def reset_members(self, idx: Any, X0: Any, seeds: Any, *,
                      restart_observers: bool = True) -> None:
        """Restart the members ``idx`` of a batch only (a vector environment's autoreset): the
        plant's members from the states ``X0`` ``(len(idx), n)``, their sensor streams
        (``seeds``: per member an int to reseed it, or :data:`CONTINUE` to let its generators
        go on, the stages' state cleared either way), each observer's members from its initial
        estimate (``restart_observers=False``: not here, for a caller that restarts them from
        its own estimates by :meth:`start_observers` next). The loop's clock goes on; the
        others are untouched. A measurement already
        drawn for the current instant (:meth:`sample`) is drawn again for these members only,
        from their streams (the others' streams do not advance).

        Parameters
        ----------
        idx : sequence of int
            The members to restart (rows of the batch).
        X0 : array_like, shape (len(idx), n)
            Their new initial states.
        seeds : sequence
            Per member in ``idx``: an int to reseed its sensor streams, ``None``, or
            :data:`CONTINUE` (ignored without a sensor chain).
        restart_observers : bool, default True
            Restart the observers' members from their initial estimates.

        Raises
        ------
        DesignError
            A plant, sensor stage or observer that cannot restart one member (see their
            ``reset_members``).

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> loop = Loop(plant, None, {"hgo": HighGainObserver(plant.system, k=10.0)},
        ...             Periods.of(plant))
        >>> loop.reset([[0.2, 0.0], [0.1, 0.0]], batch=2)
        >>> _ = loop.segment(np.zeros((2, 3, 1)))
        >>> loop.reset_members([1], [[0.3, 0.0]], [None])
        >>> loop.k, loop.plant.state[1].tolist()
        (3, [0.3, 0.0])
        """
        rows = [int(b) for b in idx]
        reset_members = getattr(self.plant, "reset_members", None)
        if reset_members is None:
            raise DesignError(f"{type(self.plant).__name__} cannot restart single members")
        reset_members(rows, X0)
        if self.sensor is not None:
            self.sensor.reset_members(rows, [None if sd is CONTINUE else sd for sd in seeds])
        for name, ob in self.observers.items() if restart_observers else ():
            ob._restart(self.params[name], self.states[name], rows)
        pending, self._pending = self._pending, None
        if pending is not None and pending[0] == self.k and rows:
            Yc = np.asarray(self.plant.outputs(), dtype=np.float64).reshape(self.batch, 1, -1)
            if self.sensor is None:
                Ym = Yc.copy()
            else:
                others = sorted(set(range(self.batch)) - set(rows))
                self.sensor.hold(others)
                try:
                    Ym = self.sensor._apply(np.array([self.t]), Yc)
                finally:
                    self.sensor.hold(())
            fresh = pending[1].copy()
            fresh[rows] = Ym[rows]
            self._pending = (self.k, fresh)

    def start_observers(self, idx: Any, x_hat0: Mapping[str, Any]) -> None:
        """Restart the members ``idx`` of the named observers from the initial estimates
        ``x_hat0[name]`` (:meth:`Observer.init`'s ``x_hat0``, ``(len(idx), n_x)``): an
        environment's start from its first measurement, after :meth:`reset` or
        :meth:`reset_members` and :meth:`sample`. The plant, the sensor streams, the clock and
        the other observers and members are untouched.

        Parameters
        ----------
        idx : sequence of int
            The members to restart (rows of the batch).
        x_hat0 : mapping of str to array_like
            Per observer name, the members' initial estimates in the layout of its
            ``state_names``, ``(len(idx), n_x)`` or ``(n_x,)`` for every one.

        Raises
        ------
        DesignError
            An observer name the loop does not hold, a member outside the batch or a
            non-finite initial estimate.
        DimensionError
            An initial estimate of the wrong shape.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> loop = Loop(plant, None, {"hgo": HighGainObserver(plant.system, k=10.0)},
        ...             Periods.of(plant))
        >>> loop.reset([[0.2, 0.0], [0.1, 0.0]], batch=2)
        >>> loop.start_observers([1], {"hgo": [[0.1, 0.0]]})
        >>> loop.current("hgo")[0].tolist()
        [[0.0, 0.0], [0.1, 0.0]]
        """
        unknown = sorted(set(x_hat0) - set(self.observers))
        if unknown:
            raise DesignError(f"start_observers: unknown observer(s) {unknown}; the loop holds "
                              f"{sorted(self.observers)}")
        rows = [int(b) for b in idx]
        for name, x0 in x_hat0.items():
            self.observers[name]._restart(self.params[name], self.states[name], rows,
                                          np.asarray(x0, dtype=np.float64))

    def estimates(self) -> dict[str, tuple[Array, Array, Array]]:
        """Each observer's current ``(x_hat, z_hat, diagnostics)``, ``(B, ...)`` arrays.

        Returns
        -------
        dict of str to tuple of ndarray
            Per observer name: copies of ``x_hat`` ``(B, n_x)``, ``z_hat`` ``(B, n)`` and the
            diagnostics ``(B, d)`` (the observer's family diagnostics, then its dropout count).

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> loop = Loop(plant, None, {"hgo": HighGainObserver(plant.system, k=10.0)},
        ...             Periods.of(plant))
        >>> loop.reset([0.2, 0.0])
        >>> [v.shape for v in loop.estimates()["hgo"]]
        [(1, 2), (1, 2), (1, 2)]
        """
        return {name: self.current(name) for name in self.observers}

    def current(self, name: str) -> tuple[Array, Array, Array]:
        """The observer ``name``'s current ``(x_hat, z_hat, diagnostics)``, ``(B, ...)``
        arrays (:meth:`estimates` of one observer).

        Parameters
        ----------
        name : str
            One of the loop's observers.

        Returns
        -------
        tuple of ndarray
            Copies of ``x_hat`` ``(B, n_x)``, ``z_hat`` ``(B, n)`` and the diagnostics.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> loop = Loop(plant, None, {"hgo": HighGainObserver(plant.system, k=10.0)},
        ...             Periods.of(plant))
        >>> loop.reset([0.2, 0.0])
        >>> loop.current("hgo")[2].tolist()
        [[10.0, 0.0]]
        """
        if name in self.failed:
            return _nan_current(self.observers[name], self.batch)
        return self.observers[name].current(self.params[name], self.states[name])

    def estimate(self, name: str) -> Array:
        """The observer ``name``'s current estimate ``x_hat`` ``(B, n_x)``: :meth:`current`'s
        first array (:meth:`Observer.current_estimate`), NaN for a stopped observer.

        Parameters
        ----------
        name : str
            One of the loop's observers.

        Returns
        -------
        ndarray
            A copy of ``x_hat`` ``(B, n_x)``.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> loop = Loop(plant, None, {"hgo": HighGainObserver(plant.system, k=10.0)},
        ...             Periods.of(plant))
        >>> loop.reset([0.2, 0.0])
        >>> loop.estimate("hgo").tolist()  # the observer's own initial estimate
        [[0.0, 0.0]]
        """
        if name in self.failed:
            return _nan_current(self.observers[name], self.batch)[0]
        return self.observers[name].current_estimate(self.params[name], self.states[name])

    def segment(self, U: Array) -> Segment:
        """Advance T samples with the inputs ``U`` ``(B, T, m)`` (the kernel; see the module
        docstring). Raises :class:`LoopFailure` on a failure inside it.

        Parameters
        ----------
        U : ndarray, shape (B, T, m)
            The input held over each of the T samples.

        Returns
        -------
        Segment
            The T rows (true state, clean and measured outputs, inputs) and each observer's
            estimates; the loop's clock ``k`` has moved on by T.

        Raises
        ------
        LoopFailure
            An observer's update (``ValueError``, ``ArithmeticError``, its divergence check)
            or the plant failed; it carries the valid rows, and the loop's clock stays put.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> loop = Loop(plant, None, {"hgo": HighGainObserver(plant.system, k=10.0)},
        ...             Periods.of(plant))
        >>> loop.reset([0.2, 0.0])
        >>> seg = loop.segment(np.zeros((1, 4, 1)))
        >>> seg.t.tolist(), loop.k
        ([0.0, 0.01, 0.02, 0.03], 4)
        """
        T = U.shape[1]
        t = self._times(T)
        before = self.estimates() if self.exact else {}
        try:
            X, Yc = self.plant.run(U, self.periods.steps)
        except DivergenceError as exc:
            raise self._plant_failure(exc, t, U, before) from exc
        Ym = self._measure(t, Yc)
        blocks = self._rotated(Ym, U) if self._rotates(T) else None
        if blocks is not None:
            self.k += T
            return Segment(t, X, Yc, Ym, U, blocks, before)
        blocks = {}
        for i, (name, ob) in enumerate(self.observers.items()):
            if name in self.failed:  # stopped by an earlier failure (isolate)
                blocks[name] = _pad(_empty(ob, Ym.shape[0]), T)
                continue
            try:
                blocks[name] = self._advance(name, ob, Ym, U)
            except _Found as found:
                if self.isolate:  # this observer stops here; the others run the segment
                    self.failed[name] = (self.k + found.row, float(t[found.row]), found.cause)
                    blocks[name] = _pad(found.head, T)
                    continue
                items = list(self.observers.items())
                j = found.row
                blocks = {n: _head(b, j) for n, b in blocks.items()}
                blocks[name] = found.head
                for later, ob2 in items[i + 1:]:  # the others consume the samples before j
                    blocks[later] = self._advance(later, ob2, Ym[:, :j], U[:, :j])
                raise self._observer_failure(name, found, t, X, Yc, Ym, U, blocks,
                                             before) from found.cause
        self.k += T
        return Segment(t, X, Yc, Ym, U, blocks, before)

    def bind_step(self, T: int) -> Callable[[Sequence[float]], None] | None:
        """A step of one member (B = 1) bound once: ``step(u)`` advances ``T`` samples with
        the input ``u`` (``m`` floats) held, as :meth:`segment` of ``[[u] * T]`` does, bit
        for bit, and returns nothing (the caller reads :meth:`sample` and :meth:`current`
        next). Validate once, run unchecked: the input, state and output buffers, the
        plant's run of one member (:meth:`Plant.bind_run`) and the observer's step
        (:meth:`Observer._bind_step`: its groups, channels and rows) are bound here; each
        call runs the same pieces as :meth:`segment` (the plant's run, :meth:`_measure`, the
        observer's :meth:`Observer._advance_block`, their failures as :class:`LoopFailure`)
        without its per-call arrays, checks and :class:`Segment`; the observer's state is the
        loop's at each call (a reset or a member's restart makes a new one). An input the
        bound run cannot take goes through :meth:`segment`, which raises its error. The
        binding holds while the loop has one member and the observer's parameters are the
        same :class:`Params` (a reset keeps them while B and the observer's values stay:
        :meth:`reset`); else a call goes through :meth:`segment`. An environment asks for
        it at each reset: the same T and parameters give the last binding again.

        Parameters
        ----------
        T : int
            Samples per call (an environment's samples per control period), at least 1.

        Returns
        -------
        callable or None
            ``step(u)``; None where the binding does not apply (use :meth:`segment`):
            several members, a loop that keeps the states before a segment (``exact``),
            ``isolate``, more than one observer, or a plant without a bound run.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> loop = Loop(plant, None, {"hgo": HighGainObserver(plant.system, k=10.0)},
        ...             Periods.of(plant), exact=False)
        >>> loop.reset([0.2, 0.0])
        >>> step = loop.bind_step(2)
        >>> step([0.5]); loop.k, round(loop.t, 6)
        (2, 0.02)
        """
        if (self.batch != 1 or self.exact or self.isolate or len(self.observers) > 1
                or T < 1):
            return None
        name, ob = next(iter(self.observers.items()), ("", None))
        p = self.params.get(name)
        if self._binding is not None and self._binding[:2] == (T, p):
            return self._binding[2]  # the last binding: the same T and parameters
        U = np.zeros((1, T, len(self.plant.input_names)))
        X = np.empty((1, T, len(self.plant.state_names)))
        Yc = np.empty((1, T, len(self.plant.output_names)))
        run = self.plant.bind_run(U, self.periods.steps, X, Yc)
        if run is None:
            return None
        advance = None if ob is None else ob._bind_step(p, 1, T,  # type: ignore[arg-type]
                                                        self.periods.sample)
        rows, states, params = U[0], self.states, self.params

        def step(u: Sequence[float]) -> None:
            rows[:] = u
            if self.batch != 1 or params.get(name) is not p:  # a reset to other members or
                self.segment(U.copy())                        # parameters: the loop's path
                return
            t = self._times(T)
            try:
                if not run():  # an input the bound run cannot take: the checked path
                    self.segment(U.copy())
                    return
            except DivergenceError as exc:
                raise self._plant_failure(exc, t, U, {}) from exc
            Ym = self._measure(t, Yc)
            if advance is not None:
                t0 = time.perf_counter()
                try:
                    advance(states[name], Ym, U)
                except DimensionError:
                    raise
                except _FAILURES as exc:
                    found = _Found(0, exc, _head(_empty(ob, 1), 0))  # type: ignore[arg-type]
                    raise self._observer_failure(name, found, t, X, Yc, Ym, U, {name: found.head},
                                                 {}) from exc
                self.wall[name] = self.wall.get(name, 0.0) + time.perf_counter() - t0
            self.k += T

        self._binding = (T, p, step)
        return step

    def _times(self, T: int) -> Array:
        """The instants of the next ``T`` samples."""
        k, Ts = self.k, self.periods.sample
        if T <= 8:  # the same products as Python floats (exact int to float): cheaper for a few
            return np.array([(k + j) * Ts for j in range(T)])
        return np.asarray((k + np.arange(T)) * Ts, dtype=np.float64)

    def _plant_failure(self, exc: DivergenceError, t: Array, U: Array,
                       before: dict[str, tuple[Array, Array, Array]]) -> LoopFailure:
        """The :class:`LoopFailure` of the plant's ``exc`` inside a segment: its rows valid for
        every member, each observer over them (:meth:`_partial`)."""
        j = int(getattr(exc, "rows", 0))
        X, Yc = exc.X[:, :j], exc.Yc[:, :j]  # type: ignore[attr-defined]
        Ym = self._measure(t[:j], Yc) if j else Yc.copy()
        seg = Segment(t[:j], X, Yc, Ym, U[:, :j], self._partial(Ym, U, j), before)
        return LoopFailure(None, self.k + j - 1, float(t[max(j - 1, 0)]), exc, seg)

    def _observer_failure(self, name: str, found: _Found, t: Array, X: Array, Yc: Array,
                          Ym: Array, U: Array, blocks: dict[str, Block],
                          before: dict[str, tuple[Array, Array, Array]]) -> LoopFailure:
        """The :class:`LoopFailure` of the observer ``name`` at the segment's row ``found.row``:
        the rows up to it (copies: a bound step's buffers are written again)."""
        j = found.row + 1
        seg = Segment(t[:j], X[:, :j].copy(), Yc[:, :j].copy(), Ym[:, :j].copy(),
                      U[:, :j].copy(), blocks, before)
        return LoopFailure(name, self.k + found.row, float(t[found.row]), found.cause, seg)

    def _rotates(self, T: int) -> bool:
        """Whether the observers take turns at running first (:meth:`_rotated`): a segment
        of several samples of a loop that keeps the states before it (``exact``), several
        observers, none stopped."""
        return self.exact and T > 1 and len(self.observers) > 1 and not self.failed

    def _rotated(self, Ym: Array, U: Array) -> dict[str, Block] | None:
        """Every observer over the segment, a different one first in each segment (the
        segment's turn modulo their number), the blocks in the listed order. The observer that
        runs right after the plant meets caches the plant's run has filled with its own code and
        data, and its wall time (:attr:`wall`) was up to 2x the same observer's listed second
        (issue 24); taking turns shares that cost equally. Each observer's states and results
        do not depend on the order. Where one fails, None, with every observer's state and
        wall time as before the segment: the listed order then decides which failure the
        segment reports (:meth:`segment`)."""
        items = list(self.observers.items())
        r = self._turn % len(items)
        self._turn += 1
        states, wall = dict(self.states), dict(self.wall)
        blocks: dict[str, Block] = {}
        try:
            for name, ob in items[r:] + items[:r]:
                blocks[name] = self._advance(name, ob, Ym, U)
        except _Found:
            self.states, self.wall = states, wall
            for name, ob in items:
                ob._hold(self.params[name], states[name])
            return None
        return {name: blocks[name] for name, _ in items}

    def _partial(self, Ym: Array, U: Array, j: int) -> dict[str, Block]:
        """Every observer over the first ``j - 1`` of ``j`` valid samples (their estimates
        before the last valid one), after the plant failed."""
        return {name: self._advance(name, ob, Ym[:, :max(j - 1, 0)], U[:, :max(j - 1, 0)])
                for name, ob in self.observers.items()}

    def _advance(self, name: str, ob: Observer, Ym: Array, U: Array) -> Block:
        """One observer over the segment, timed; on a failure, the failing sample found by a
        replay from the state before the segment (:class:`_Found`). The step is pure where a
        replay may be needed (a stored run, several samples): the state before is kept as it
        is; an environment (``exact=False``) steps the state in place."""
        T = Ym.shape[1]
        p, before = self.params[name], self.states[name]
        keep = T > 1 and self.exact
        state = before.copy() if keep else before
        t0 = time.perf_counter()
        try:
            # a loop that keeps no rows (exact=False) reuses each observer's block
            blk = ob._step_checked(p, state, Ym, U, self.periods.sample,
                                   None if self.exact else self._blocks.get(name))
        except DimensionError:
            raise  # a shape mistake, not a divergence
        except _FAILURES as exc:
            if not keep:
                raise _Found(0, exc, _head(_empty(ob, Ym.shape[0]), 0)) from exc
            raise _replay(ob, p, before.copy(), Ym, U, self.periods.sample) from exc
        self.wall[name] = self.wall.get(name, 0.0) + time.perf_counter() - t0
        if keep:
            self.states[name] = state
            ob._hold(p, state)
        if not self.exact:
            self._blocks[name] = blk
        return blk

    def sample(self) -> tuple[Array, Array, Array]:
        """The true state, clean and measured outputs at the current instant, ``(B, 1, ...)``
        each, without moving on (the last row of a run; an environment's newest measurement).
        The sensor draws for this instant once: the next :meth:`segment` consumes this
        measurement as its first.

        Returns
        -------
        tuple of ndarray
            ``(X, Yc, Ym)``: the true state ``(B, 1, n)``, the clean outputs ``(B, 1, p)`` and
            the measured outputs ``(B, 1, p)`` (a copy) at the current instant.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> loop = Loop(plant, None, {"hgo": HighGainObserver(plant.system, k=10.0)},
        ...             Periods.of(plant))
        >>> loop.reset([0.2, 0.0])
        >>> X, Yc, Ym = loop.sample()
        >>> X.tolist(), Yc.tolist(), loop.k
        ([[[0.2, 0.0]]], [[[0.2]]], 0)
        """
        B = self.batch  # the plant's state and outputs are fresh arrays: no copies
        X = np.asarray(self.plant.state, dtype=np.float64).reshape(B, 1, -1)
        Yc = np.asarray(self.plant.outputs(), dtype=np.float64).reshape(B, 1, -1)
        if self._pending is None or self._pending[0] != self.k:
            self._pending = (self.k, self._measure(np.array([self.t]), Yc, fresh=True))
        return X, Yc, self._pending[1].copy()

    def _measure(self, t: Array, Yc: Array, fresh: bool = False) -> Array:
        """The sensor chain over the rows ``Yc`` at ``t``; a measurement already drawn for the
        first instant by :meth:`sample` is used, not drawn again."""
        pending, self._pending = (None if fresh else self._pending), None
        if pending is not None and pending[0] == self.k:
            if Yc.shape[1] == 1:
                return pending[1]  # the loop's own array (sample() hands out copies)
            Ym = np.empty_like(Yc)
            Ym[:, :1] = pending[1]
            Ym[:, 1:] = self._measure(t[1:], Yc[:, 1:])
            return Ym
        if self.sensor is None or Yc.shape[1] == 0:
            return Yc.copy()
        return self.sensor._apply(t, Yc)


class Drive:
    """How a run makes the loop's inputs ``U`` ``(B, T, m)``: an open-loop signal evaluated at
    the control instants and held over each control period, or a
    :class:`~hgo_mj.inputs.Controller` called at each control instant on the named observer's
    current estimate (before it consumes that instant's measurement) or on the true state."""

    def __init__(self, signal: Signal | None, controller: Controller | None,
                 observer: str | None, m: int, input_names: tuple[str, ...],
                 periods: Periods) -> None:
        self.signal, self.controller, self.observer = signal, controller, observer
        self.m, self.input_names, self.periods = m, input_names, periods
        self._held: Array | None = None

    @classmethod
    def of(cls, inputs: Any, observers: Mapping[str, Observer], plant: Plant,
           periods: Periods) -> Drive:
        m, names = len(plant.input_names), tuple(plant.input_names)
        if isinstance(inputs, Controller):
            observer = None
            if inputs.source == "estimate":
                if not observers:
                    raise DesignError("a Controller on the estimate needs at least one observer")
                observer = inputs.observer if inputs.observer is not None else next(iter(observers))
                if observer not in observers:
                    raise DesignError(f"Controller.observer {observer!r} is not one of the "
                                      f"observers {list(observers)}")
            return cls(None, inputs, observer, m, names, periods)
        if isinstance(inputs, Signal):
            return cls(inputs, None, None, m, names, periods)
        if callable(inputs):
            return cls(FunctionSignal(inputs), None, None, m, names, periods)
        raise DesignError(f"inputs must be a signal u(t) or a Controller; found "
                          f"{type(inputs).__name__}")

    def length(self, k: int, N: int, segment: int) -> int:
        """Samples in the next segment from sample ``k`` of ``N``: up to ``segment`` for an
        open-loop signal, up to the next control instant for a feedback law."""
        if self.controller is None:
            return min(segment, N - k)
        return min(self.periods.every - k % self.periods.every, N - k)

    def inputs(self, loop: Loop, T: int) -> Array:
        """``U`` ``(B, T, m)`` for the samples ``loop.k ... loop.k + T - 1``."""
        every, Ts, k = self.periods.every, self.periods.sample, loop.k
        if self.controller is None:
            idx = k + np.arange(T)
            first = (idx - idx % every)  # the control instant each sample's input is held from
            inst, where = np.unique(first, return_inverse=True)
            vals = self._check(self.signal.values(inst * Ts), inst.size, inst[0] * Ts)  # type: ignore[union-attr]
            return np.broadcast_to(vals[where], (loop.batch, T, self.m)).copy()
        if k % every == 0 or self._held is None:
            law = self.controller
            x = (np.reshape(loop.plant.state, (loop.batch, -1)) if self.observer is None
                 else loop.current(self.observer)[0])
            self._held = self._check(law.act(k * Ts, x), loop.batch, k * Ts)
        return np.broadcast_to(self._held[:, None], (loop.batch, T, self.m)).copy()

    def _check(self, vals: Any, rows: int, t: float) -> Array:
        try:
            vals = np.asarray(vals, dtype=float)
        except (TypeError, ValueError) as exc:
            raise DimensionError(f"input must be numbers, {self.m} channel(s) "
                                 f"{self.input_names}; found {_short_repr(vals)} at t={t:g} "
                                 f"({exc})") from None
        if vals.shape != (rows, self.m):
            found = vals.shape[1:] if vals.ndim == 2 else vals.shape
            raise DimensionError(f"input must have {self.m} channel(s) {self.input_names}; "
                                 f"found shape {tuple(found)} at t={t:g}")
        return vals

    def describe(self) -> dict[str, Any]:
        src = self.controller if self.controller is not None else self.signal
        params = src.params() if src is not None and hasattr(src, "params") else {}
        return {"type": type(src).__name__, **params}


def _short_repr(value: Any, n: int = 60) -> str:
    """``repr(value)``, cut to ``n`` characters."""
    text = repr(value)
    return text if len(text) <= n else text[:n] + "..."


class _Found(Exception):
    """An observer failed at sample ``row`` of a segment; ``head`` its rows before that."""

    def __init__(self, row: int, cause: BaseException, head: Block) -> None:
        super().__init__(f"row {row}: {cause}")
        self.row, self.cause, self.head = row, cause, head


def _empty(ob: Observer, B: int) -> Block:
    return Block(np.empty((B, 0, len(ob.state_names))), np.empty((B, 0, ob.n)),
                 np.empty((B, 0, len(ob.diagnostic_names))))


def _replay(ob: Observer, p: Params, state: State, Ym: Array, U: Array, Ts: float) -> _Found:
    """Advance ``state`` sample by sample over the segment until it fails again: the failing
    sample, its error and the rows before it."""
    rows: list[Block] = []
    for j in range(Ym.shape[1]):
        try:
            rows.append(ob._step_checked(p, state, Ym[:, j:j + 1], U[:, j:j + 1], Ts))
        except _FAILURES as exc:
            head = _empty(ob, Ym.shape[0]) if not rows else Block(
                *(np.concatenate([getattr(r, f) for r in rows], axis=1)
                  for f in ("x_hat", "z_hat", "diagnostics")))
            return _Found(j, exc, head)
    raise DesignError(f"{type(ob).__name__} failed on a segment but not sample by sample: its "
                      f"update depends on more than its state")  # pragma: no cover


def _pad(b: Block, T: int) -> Block:
    """``b`` with NaN rows after its own up to ``T`` rows (an observer stopped by a failure)."""
    def grow(a: Array) -> Array:
        out = np.full((a.shape[0], T, a.shape[2]), np.nan)
        out[:, :a.shape[1]] = a
        return out
    return Block(grow(b.x_hat), grow(b.z_hat), grow(b.diagnostics))


def _nan_current(ob: Observer, B: int) -> tuple[Array, Array, Array]:
    """:func:`_current`'s shapes, all NaN: the current estimate of a stopped observer."""
    return (np.full((B, len(ob.state_names)), np.nan), np.full((B, ob.n), np.nan),
            np.full((B, len(ob.diagnostic_names)), np.nan))


def _head(b: Block, j: int) -> Block:
    return Block(b.x_hat[:, :j], b.z_hat[:, :j], b.diagnostics[:, :j])


__all__ = ["CONTINUE", "Loop", "LoopFailure", "Periods", "Segment"]
