"""Input signals ``u(t)`` and controllers ``u(t, x_hat)``.

Open-loop signals compute ``u`` at many instants at once (:meth:`Signal.values`, ``(T,)`` times to
``(T, m)`` values); ``signal(t) -> u`` (a 1-D array) is derived from it. A :class:`Controller`
wraps a feedback law that sees only an observer's estimate (or, when asked, the true state, for
comparison). Every signal validates its parameters and reports them with ``params()``.

A plant with several actuators takes one signal per actuator: :class:`Channels` puts signals
side by side (channel ``i`` of ``u`` is the ``i``-th signal's), and a scenario file says the
same with a list of input tables, one per actuator, in the plant's input order
(:func:`signal_from_spec`)::

    [[input]]                   # torque1
    type = "multisine"
    amplitudes = [0.3]
    frequencies = [0.5]
    [[input]]                   # torque2
    type = "prbs"
    amplitude = 0.1
    period = 0.05

(on the command line: ``--input`` once per actuator, in the same order). A single ``[input]``
table is one signal for every channel, as before.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._validate import check_call, finite_scalar, numbers_only, positive_int, reject_unknown, vector
from .exceptions import DesignError, DimensionError

Array = NDArray[np.float64]

__all__ = ["SIGNALS", "Chirp", "Channels", "Constant", "Controller", "FunctionSignal",
           "Multisine", "PRBS", "Schedule", "Signal", "Telegraph", "make_signal",
           "signal_from_spec"]


class Signal(ABC):
    """Base class of open-loop inputs. The one primitive is :meth:`values`, vectorized over
    time; ``signal(t)`` (a fresh 1-D array) is derived from it.

    A subclass sets ``name`` and ``summary`` and implements :meth:`values` (and
    :meth:`params` where it has parameters).

    Examples
    --------
    >>> import numpy as np
    >>> class Ramp(Signal):
    ...     name = "ramp"
    ...     def values(self, t):
    ...         return np.asarray(t, dtype=float)[:, None]
    >>> Ramp()(0.5)
    array([0.5])
    >>> Ramp().values(np.array([0.0, 1.0, 2.0])).shape
    (3, 1)
    """

    name = ""
    summary = ""

    @abstractmethod
    def values(self, t: Array) -> Array:
        """``u`` at the instants ``t`` ``(T,)``, shape ``(T, m)``.

        Parameters
        ----------
        t : (T,) ndarray
            Times, in the plant's time unit (seconds for the MuJoCo plants).

        Returns
        -------
        (T, m) ndarray
            The input at each instant, one column per channel.

        Examples
        --------
        >>> import numpy as np
        >>> Constant([0.1, 0.2]).values(np.array([0.0, 0.5]))
        array([[0.1, 0.2],
               [0.1, 0.2]])
        """

    def __call__(self, t: float) -> Array:
        return self.values(np.array([float(t)]))[0]

    def params(self) -> dict[str, Any]:
        """The signal's parameters, JSON-ready, for a trajectory's metadata.

        Returns
        -------
        dict
            Parameter name -> value (the base: empty).

        Examples
        --------
        >>> Multisine([1.0], [0.5]).params()
        {'amplitudes': [1.0], 'frequencies': [0.5], 'phases': [0.0], 'offset': 0.0}
        """
        return {}


class FunctionSignal(Signal):
    """A plain function ``u(t) -> array`` used as a signal (called once per instant).

    Parameters
    ----------
    fn : callable
        ``fn(t) -> u``: a float time to a number or a 1-D array (the same length every call).

    Examples
    --------
    >>> import numpy as np
    >>> FunctionSignal(lambda t: [t, 2 * t]).values(np.array([0.0, 0.5]))
    array([[0. , 0. ],
           [0.5, 1. ]])
    """

    name = "function"
    summary = "a user function u(t)"

    def __init__(self, fn: Callable[[float], Any]) -> None:
        if not callable(fn):
            raise DesignError(f"a signal function must be callable; found {type(fn).__name__}")
        self.fn = fn

    def values(self, t: Array) -> Array:
        rows = []
        for ti in t:
            u = self.fn(float(ti))
            try:
                rows.append(np.atleast_1d(np.asarray(u, dtype=float)))
            except (TypeError, ValueError):
                raise DimensionError(f"u(t) must return a number or a 1-D array of numbers; "
                                     f"found {type(u).__name__} {u!r:.60} at t={float(ti):g}"
                                     ) from None
        widths = {r.shape for r in rows}
        if len(widths) != 1 or any(r.ndim != 1 for r in rows):
            raise DimensionError(f"u(t) must return 1-D arrays of one length; found shapes "
                                 f"{sorted(widths)}")
        return np.stack(rows)

    def params(self) -> dict[str, Any]:
        return {"function": getattr(self.fn, "__name__", repr(self.fn))}


class TimeShift(Signal):
    """``signal(t + shift)``: e.g. an input held over a sample period taken at the sample's
    midpoint (``shift = dt / 2``), a second-order approximation of a continuous input for a
    plant integrated over the sample with the input held."""

    name = "time_shift"
    summary = "another signal evaluated at t + shift"

    def __init__(self, signal: Signal, shift: float) -> None:
        if not isinstance(signal, Signal):
            raise DesignError(f"TimeShift needs a Signal; found {type(signal).__name__}")
        self.signal = signal
        self.shift = finite_scalar("TimeShift.shift", shift)

    def values(self, t: Array) -> Array:
        return self.signal.values(np.asarray(t, dtype=float) + self.shift)

    def params(self) -> dict[str, Any]:
        return {"shift": self.shift, "signal": {"type": type(self.signal).__name__,
                                                **self.signal.params()}}


def _channels(name: str, value: Any) -> Array:
    if not numbers_only(value):  # a string or a bool is refused, not converted
        raise DesignError(f"{name} must be a number or a list of numbers; found {value!r}")
    return vector(name, np.atleast_1d(np.asarray(value, dtype=float)))


class Constant(Signal):
    """``u(t) = value``.

    Parameters
    ----------
    value : float or sequence of float, default 0.0
        The input, one entry per channel (a number: one channel).

    Examples
    --------
    >>> Constant([0.1, 0.2])(3.0)
    array([0.1, 0.2])
    """

    name = "constant"
    summary = "constant input"

    def __init__(self, value: Any = 0.0) -> None:
        self.value = _channels("Constant.value", value)

    def values(self, t: Array) -> Array:
        return np.tile(self.value, (np.size(t), 1))

    def params(self) -> dict[str, Any]:
        return {"value": self.value.tolist()}


class Schedule(Signal):
    """Piecewise-constant input: ``u = values[i]`` for ``times[i] <= t < times[i+1]``.

    Paper 000's substrate inflow is ``Schedule([0, 30, 50], [0.08, 0.02, 0.08])`` (hours).
    Before ``times[0]`` the first value holds.

    Parameters
    ----------
    times : sequence of float
        Switching times, strictly increasing.
    values : array_like
        One value per time: ``(N,)`` for one channel or ``(N, m)``.

    Examples
    --------
    >>> import numpy as np
    >>> u = Schedule([0, 30, 50], [0.08, 0.02, 0.08])
    >>> u.values(np.array([0.0, 40.0, 60.0])).ravel()
    array([0.08, 0.02, 0.08])
    """

    name = "schedule"
    summary = "piecewise-constant schedule (paper 000's u profile)"

    def __init__(self, times: Sequence[float], values: Any) -> None:
        self.times = vector("Schedule.times", times)
        if not numbers_only(values):
            raise DesignError(f"Schedule.values must be numbers; found {values!r}")
        vals = np.asarray(values, dtype=float)
        self.levels = vals.reshape(len(self.times), -1) if vals.ndim <= 1 else vals
        if self.levels.shape[0] != self.times.size or self.times.size == 0:
            raise DimensionError(f"Schedule needs one value per time; found {self.times.size} "
                                 f"times and {self.levels.shape[0]} values")
        if not np.all(np.isfinite(self.levels)):
            raise DesignError("Schedule.values must be finite")
        if np.any(np.diff(self.times) <= 0):
            raise DesignError(f"Schedule.times must increase strictly; found {self.times.tolist()}")

    def values(self, t: Array) -> Array:
        i = np.maximum(np.searchsorted(self.times, t, side="right") - 1, 0)
        return self.levels[i]

    def params(self) -> dict[str, Any]:
        return {"times": self.times.tolist(), "values": self.levels.tolist()}


class Multisine(Signal):
    """``u(t) = offset + sum_i a_i sin(2 pi f_i t + phase_i)`` (one channel; paper 001's ``u``
    ``sin 2t + 0.1 cos 10t`` is ``Multisine([1, .1], [2/(2pi), 10/(2pi)], [0, pi/2])``).

    Parameters
    ----------
    amplitudes : sequence of float
        ``a_i``, in the input's unit.
    frequencies : sequence of float
        ``f_i`` in Hz (cycles per unit of time), one per amplitude.
    phases : sequence of float, optional
        ``phase_i`` in rad; default zeros.
    offset : float
        Constant added to the sum.

    Raises
    ------
    DesignError
        Lengths that differ, or values that are not finite numbers.

    Examples
    --------
    >>> import numpy as np
    >>> u = Multisine(amplitudes=[1.0, 0.1], frequencies=[2 / (2 * np.pi), 10 / (2 * np.pi)],
    ...               phases=[0.0, np.pi / 2])
    >>> t = 0.3
    >>> bool(np.isclose(u(t)[0], np.sin(2 * t) + 0.1 * np.cos(10 * t)))
    True
    """

    name = "multisine"
    summary = "sum of sinusoids (paper 001's input)"

    def __init__(self, amplitudes: Any, frequencies: Any, phases: Any = None,
                 offset: float = 0.0) -> None:
        self.amplitudes = vector("Multisine.amplitudes", amplitudes)
        self.frequencies = vector("Multisine.frequencies", frequencies, self.amplitudes.size)
        self.phases = (np.zeros(self.amplitudes.size) if phases is None
                       else vector("Multisine.phases", phases, self.amplitudes.size))
        if np.any(self.frequencies < 0):
            raise DesignError(f"Multisine.frequencies must be >= 0; found "
                              f"{self.frequencies.tolist()}")
        self.offset = finite_scalar("Multisine.offset", offset)

    def values(self, t: Array) -> Array:
        s = np.full(np.size(t), self.offset)
        for a, f, ph in zip(self.amplitudes.tolist(), self.frequencies.tolist(),
                            self.phases.tolist()):
            s = s + a * np.sin(2 * math.pi * f * np.asarray(t, dtype=float) + ph)
        return s[:, None]

    def params(self) -> dict[str, Any]:
        return {"amplitudes": self.amplitudes.tolist(), "frequencies": self.frequencies.tolist(),
                "phases": self.phases.tolist(), "offset": self.offset}


class Chirp(Signal):
    """Linear chirp from ``f0`` to ``f1`` Hz over ``duration``: ``a sin(2 pi (f0 t + (f1-f0)
    t^2 / (2 T)))``, then held at ``f1``.

    Parameters
    ----------
    amplitude : float
        ``a``, in the input's unit.
    f0, f1 : float
        Start and end frequencies, Hz, >= 0.
    duration : float
        Sweep time ``T``, > 0.
    offset : float, default 0.0
        Constant added.

    Examples
    --------
    >>> import numpy as np
    >>> Chirp(1.0, f0=0.0, f1=2.0, duration=1.0).values(np.array([0.0, 0.25, 0.5])).round(4)
    array([[0.    ],
           [0.3827],
           [1.    ]])
    """

    name = "chirp"
    summary = "linear frequency sweep"

    def __init__(self, amplitude: float, f0: float, f1: float, duration: float,
                 offset: float = 0.0) -> None:
        self.amplitude = finite_scalar("Chirp.amplitude", amplitude)
        self.f0 = finite_scalar("Chirp.f0", f0, nonnegative=True)
        self.f1 = finite_scalar("Chirp.f1", f1, nonnegative=True)
        self.duration = finite_scalar("Chirp.duration", duration, positive=True)
        self.offset = finite_scalar("Chirp.offset", offset)

    def values(self, t: Array) -> Array:
        t = np.asarray(t, dtype=float)
        T = self.duration
        tt = np.minimum(t, T)
        phase = self.f0 * tt + (self.f1 - self.f0) * tt * tt / (2 * T) + self.f1 * np.maximum(
            t - T, 0.0)
        return (self.offset + self.amplitude * np.sin(2 * math.pi * phase))[:, None]

    def params(self) -> dict[str, Any]:
        return {"amplitude": self.amplitude, "f0": self.f0, "f1": self.f1,
                "duration": self.duration, "offset": self.offset}


#: the longest telegraph sequence (levels held in memory, 8 bytes each)
TELEGRAPH_MAX_LENGTH = 2 ** 22


class _Levels(Signal):
    """A sequence of +-1 ``_levels``, each held ``period`` seconds and repeated:
    ``offset + amplitude * level`` (what :class:`PRBS` and :class:`Telegraph` share)."""

    amplitude: float
    period: float
    offset: float
    _levels: Array

    def values(self, t: Array) -> Array:
        i = (np.floor(np.asarray(t, dtype=float) / self.period + 1e-9).astype(np.int64)
             % self._levels.size)
        return (self.offset + self.amplitude * self._levels[i])[:, None]


class PRBS(_Levels):
    """Maximum-length pseudo-random binary sequence (an m-sequence): ``u = offset +
    amplitude * (2 b_k - 1)`` for ``k period <= t < (k + 1) period``, where ``b`` is the
    output of an ``nbits``-stage linear feedback shift register with primitive taps
    (:func:`scipy.signal.max_len_seq`), started at element ``shift`` and repeated.

    Its properties (tested): the period is ``N = 2**nbits - 1`` clock periods and no shorter;
    one period holds ``2**(nbits-1)`` high and ``2**(nbits-1) - 1`` low levels; the circular
    autocorrelation of the +-1 levels is ``N`` at lag 0 and ``-1`` at every other lag, so its
    spectrum is flat (to within the ``sinc^2`` of the hold) up to about ``0.44 / period`` Hz.
    The random telegraph signal this name used to give is :class:`Telegraph` (``telegraph``).

    Parameters
    ----------
    amplitude : float
        Level ``+-amplitude`` around ``offset``.
    period : float
        Clock period (how long each level holds), > 0.
    nbits : int, default 10
        Shift-register length, 2..20 (sequence period ``2**nbits - 1`` clocks).
    offset : float, default 0.0
        Constant added.
    shift : int, default 0
        Index of the sequence element at ``t = 0``, >= 0.

    Examples
    --------
    >>> import numpy as np
    >>> u = PRBS(0.5, period=0.1, nbits=3)
    >>> u.length
    7
    >>> u.values(np.arange(8) * 0.1).ravel()
    array([ 0.5,  0.5,  0.5, -0.5,  0.5, -0.5, -0.5,  0.5])
    """

    name = "prbs"
    summary = "maximum-length pseudo-random binary sequence (m-sequence, period 2^nbits - 1)"

    def __init__(self, amplitude: float, period: float, nbits: int = 10, offset: float = 0.0,
                 shift: int = 0) -> None:
        from scipy.signal import max_len_seq

        self.amplitude = finite_scalar("PRBS.amplitude", amplitude)
        self.period = finite_scalar("PRBS.period", period, positive=True)
        self.offset = finite_scalar("PRBS.offset", offset)
        self.nbits = positive_int("PRBS.nbits", nbits, floats=False)
        if not 2 <= self.nbits <= 20:  # 2^20 - 1 levels: 8 MB, a period of a million clocks
            raise DesignError(f"PRBS.nbits must be in 2..20 (a period of 3 to 2^20 - 1 clock "
                              f"periods); found {self.nbits}")
        if isinstance(shift, bool) or not isinstance(shift, (int, np.integer)) or shift < 0:
            raise DesignError(f"PRBS.shift must be an integer >= 0; found {shift!r}")
        self.shift = int(shift)
        bits, _ = max_len_seq(self.nbits)
        self._levels = np.roll(2.0 * bits - 1.0, -(self.shift % bits.size))

    @property
    def length(self) -> int:
        """The sequence's period in clock periods, ``2**nbits - 1``."""
        return int(self._levels.size)

    def params(self) -> dict[str, Any]:
        return {"amplitude": self.amplitude, "period": self.period, "nbits": self.nbits,
                "offset": self.offset, "shift": self.shift}


class Telegraph(_Levels):
    """Random telegraph signal: ``offset +- amplitude``, each ``period`` seconds the level drawn
    anew, high or low with probability 1/2, from ``seed`` (a fixed sequence of ``length``
    levels, repeated; independent of the run). What ``prbs`` gave before it became a true
    m-sequence (:class:`PRBS`): the same numbers for the same parameters.

    Parameters
    ----------
    amplitude : float
        Level ``+-amplitude`` around ``offset``.
    period : float
        How long each level holds, > 0.
    seed : int, default 0
        Seed of the level sequence, >= 0.
    offset : float, default 0.0
        Constant added.
    length : int, default 4096
        Levels before the sequence repeats, at most ``2**22``.

    Examples
    --------
    >>> import numpy as np
    >>> Telegraph(0.5, period=0.1).values(np.arange(5) * 0.1).ravel()
    array([ 0.5, -0.5, -0.5, -0.5,  0.5])
    """

    name = "telegraph"
    summary = "random telegraph signal (a level drawn each period)"

    def __init__(self, amplitude: float, period: float, seed: int = 0, offset: float = 0.0,
                 length: int = 4096) -> None:
        self.amplitude = finite_scalar("Telegraph.amplitude", amplitude)
        self.period = finite_scalar("Telegraph.period", period, positive=True)
        self.offset = finite_scalar("Telegraph.offset", offset)
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise DesignError(f"Telegraph.seed must be a non-negative integer; found {seed!r}")
        self.seed = int(seed)
        self.length = positive_int("Telegraph.length", length, floats=False)
        if self.length > TELEGRAPH_MAX_LENGTH:
            raise DesignError(f"Telegraph.length must be at most {TELEGRAPH_MAX_LENGTH} (the "
                              f"sequence repeats cyclically); found {self.length}")
        rng = np.random.default_rng(self.seed)
        self._levels = np.where(rng.random(self.length) < 0.5, -1.0, 1.0)

    def params(self) -> dict[str, Any]:
        return {"amplitude": self.amplitude, "period": self.period, "seed": self.seed,
                "offset": self.offset, "length": self.length}


class Channels(Signal):
    """Signals side by side, one per actuator: ``u = (signals[0](t), signals[1](t), ...)``
    (a signal of several channels gives several).

    Parameters
    ----------
    signals : sequence of Signal
        One (or more channels) per actuator, in the plant's input order; non-empty.

    Examples
    --------
    >>> Channels([Constant(1.0), Multisine([1.0], [0.25])])(1.0)
    array([1., 1.])
    """

    name = "channels"
    summary = "one signal per actuator"

    def __init__(self, signals: Sequence[Signal]) -> None:
        signals = list(signals)
        if not signals or not all(isinstance(sg, Signal) for sg in signals):
            raise DesignError(f"Channels needs a non-empty list of Signals; found "
                              f"{[type(sg).__name__ for sg in signals]}")
        self.signals = signals

    def values(self, t: Array) -> Array:
        return np.hstack([sg.values(t) for sg in self.signals])

    def params(self) -> dict[str, Any]:
        return {"signals": [{"type": sg.name, **sg.params()} for sg in self.signals]}


class Controller:
    """A feedback law ``law(t, x) -> u`` fed with an observer's estimate.

    Parameters
    ----------
    law : callable
        ``law(t, x) -> u``; ``x`` is the estimate in physical coordinates.
    source : {"estimate", "true"}
        Feed the estimate of ``observer`` (default) or the true state (for comparison).
    observer : str, optional
        Name of the observer whose estimate is used; default the first one.

    Examples
    --------
    >>> import numpy as np
    >>> ctl = Controller(lambda t, x: -2.0 * x[:1])
    >>> ctl(0.0, np.array([0.5, 0.0]))
    array([-1.])
    """

    name = "controller"
    summary = "feedback law on the estimate (or the true state)"

    def __init__(self, law: Callable[[float, Array], Any], source: str = "estimate",
                 observer: str | None = None) -> None:
        if not callable(law):
            raise DesignError(f"Controller.law must be callable; found {type(law).__name__}")
        if source not in ("estimate", "true"):
            raise DesignError(f"Controller.source must be 'estimate' or 'true'; found {source!r}")
        self.law, self.source, self.observer = law, source, observer

    def __call__(self, t: float, x: Array) -> Array:
        return np.atleast_1d(np.asarray(self.law(t, x), dtype=float))

    def act(self, t: float, X: Array) -> Array:
        """The inputs ``(B, m)`` of B members at time ``t`` from their states ``X``
        ``(B, n)`` (what the loop calls; here the law once per member, a batched law
        overrides it).

        Parameters
        ----------
        t : float
            Time.
        X : (B, n) ndarray
            One state (estimate) per member.

        Returns
        -------
        (B, m) ndarray
            One input per member.

        Examples
        --------
        >>> import numpy as np
        >>> Controller(lambda t, x: -2.0 * x[:1]).act(0.0, np.array([[1.0, 0.0], [0.5, 0.0]]))
        array([[-2.],
               [-1.]])
        """
        return np.stack([self(t, x) for x in X])

    def params(self) -> dict[str, Any]:
        """The controller's settings, JSON-ready, for a trajectory's metadata.

        Returns
        -------
        dict
            ``source``, ``observer`` and the law's name.

        Examples
        --------
        >>> def law(t, x):
        ...     return -x[:1]
        >>> Controller(law, source="true").params()
        {'source': 'true', 'observer': None, 'law': 'law'}
        """
        return {"source": self.source, "observer": self.observer,
                "law": getattr(self.law, "__name__", repr(self.law))}


SIGNALS: dict[str, type[Signal]] = {
    c.name: c for c in (Constant, Schedule, Multisine, Chirp, PRBS, Telegraph)}


def make_signal(kind: str, **params: Any) -> Signal:
    """Build an open-loop signal by registry name; unknown names and keywords are listed.

    Parameters
    ----------
    kind : str
        ``"constant"``, ``"schedule"``, ``"multisine"``, ``"chirp"``, ``"prbs"`` or
        ``"telegraph"`` (``hgo-mj list`` shows their parameters).
    **params
        The signal's constructor parameters.

    Returns
    -------
    Signal
        A callable ``u(t)`` returning the input at time ``t``.

    Raises
    ------
    DesignError
        An unknown kind or keyword (the valid ones are listed), or a bad value.

    Examples
    --------
    >>> u = make_signal("constant", value=0.2)
    >>> u(1.0)
    array([0.2])
    >>> make_signal("sine", amplitude=1.0)
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: unknown input 'sine'; valid: [...]
    """
    if not isinstance(kind, str) or kind not in SIGNALS:
        raise DesignError(f"unknown input {kind!r}; valid: {sorted(SIGNALS)}")
    import inspect

    sig = inspect.signature(SIGNALS[kind].__init__)
    reject_unknown(f"input {kind!r}", params, [p for p in sig.parameters if p != "self"])
    check_call(f"input {kind!r}", SIGNALS[kind].__init__, params)
    return SIGNALS[kind](**params)


def signal_from_spec(spec: Any, n_inputs: int) -> Signal:
    """The open-loop signal of a scenario's ``input``: ``None`` (zero on every channel), one
    table ``{"type": KIND, ...}`` (:func:`make_signal`; ``constant`` without ``value`` is zero
    on all ``n_inputs`` channels), or a list of tables, one per actuator in the plant's input
    order (:class:`Channels`; there a ``constant`` without ``value`` is one zero channel).

    Parameters
    ----------
    spec : None, dict or list of dict
        The scenario's ``input`` (tables with a ``"type"`` key, default ``"constant"``, and
        the signal's parameters).
    n_inputs : int
        The plant's number of inputs ``m`` (the width of a zero input).

    Returns
    -------
    Signal

    Raises
    ------
    DesignError
        An empty list, an entry that is not a table, or an invalid signal (see
        :func:`make_signal`).

    Examples
    --------
    >>> signal_from_spec(None, 2)(0.0)
    array([0., 0.])
    >>> u = signal_from_spec([{"type": "constant", "value": 1.0},
    ...                       {"type": "prbs", "amplitude": 0.1, "period": 0.05}], 2)
    >>> type(u).__name__, u(0.0)
    ('Channels', array([1. , 0.1]))
    """
    if spec is None:
        return Constant([0.0] * n_inputs)
    if isinstance(spec, (list, tuple)):
        if not spec:
            raise DesignError("scenario [[input]] is an empty list; expected one table per "
                              "actuator")
        return Channels([signal_from_spec(_input_table(item, i), 1) for i, item in enumerate(spec)])
    inp = dict(_input_table(spec, None))
    kind = inp.pop("type", "constant")
    if kind == "constant" and "value" not in inp:
        return Constant([0.0] * n_inputs)
    return make_signal(kind, **inp)


def _input_table(spec: Any, index: int | None) -> dict[str, Any]:
    if not isinstance(spec, dict):
        where = "scenario [input]" if index is None else f"scenario input #{index + 1}"
        raise DesignError(f"{where} must be a table (type = ..., and its parameters), or a list "
                          f"of tables one per actuator; found {spec!r}")
    return spec
