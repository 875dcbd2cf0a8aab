"""The observer contract: one abstract base, a batch axis, one primitive.

An observer is a continuous-time ODE in observer coordinates ``z`` driven by the measurement,
which is held constant between samples. Every observer advances **B independent copies at
once**: its state is data with a leading batch axis (estimate ``(B, n)``, gains, parameter
estimates, covariances), measurements are ``(B, p)``, inputs ``(B, m)``. A single run is
B = 1 on the same code.

**The one primitive** is :meth:`Observer._advance`, which a family implements: consume T
samples ``Y[:, j]`` (the channels in :attr:`Observer.outputs` only) with the inputs
``U[:, j]``, integrate over ``dt`` after each, and write the estimate *after* each sample into
the rows ``X[:, j]``, ``Z[:, j]``, ``D[:, j]``. Everything else is derived here, once:

* :meth:`advance` validates the measurement block, counts dropouts and calls ``_advance``;
* :meth:`step` is one sample (T = 1), :meth:`update` one sample of an unbatched observer
  (1-D ``y`` and ``u``, returns the 1-D estimate), :meth:`run` an offline driver over a whole
  record (in the spirit of filterpy's ``batch_filter``);
* :attr:`x_hat`, :attr:`z_hat` and :meth:`diagnostics` read the current state.

Shapes follow the batch of the last :meth:`reset`: ``reset(batch=B)`` (or an initial estimate
of shape ``(B, n)``) makes the observer *batched* and every public array carries the leading
``B``; a plain ``reset()`` makes it *unbatched* (``B = 1`` inside) and the public arrays drop
the batch axis, so ``x_hat`` is ``(n,)`` and a diagnostic a float.

**Estimate layout.** ``x_hat`` has one entry per name in :attr:`Observer.state_names`. These
are the plant's state names when the observer estimates the physical state, but need not be:
an order-only observer (no system) estimates ``z1, z2, ...``, a model-free multi-output one the
outputs and their derivatives, an adaptive one appends parameter estimates. Trajectories,
metrics, figures and recordings match the estimate to the plant's states *by name*. An initial
estimate ``x_hat0`` always has this layout, ``(n_x,)`` for every member or ``(B, n_x)``.

**Dropouts.** A NaN measurement (a sensor dropout) is never propagated: the observer integrates
its prediction without output injection over that sample; :meth:`advance` counts it in
``dropouts_`` (per member). An infinite measurement raises :class:`DivergenceError`.

**Undefined inverse map.** ``x_hat`` is the image of ``z_hat`` under the inverse normal-form
map, which may be undefined there (the bioreactor's ``Phi^-1`` needs ``m > 0``). Then ``x_hat``
holds its last valid value, and is **NaN before any valid value**; each failed evaluation is
counted in ``inverse_failures_`` (:meth:`Observer._to_physical`). Divergence is judged on
``z_hat``, which is always defined.

**Diagnostics.** :attr:`diagnostic_names` lists exactly what :meth:`diagnostics` returns, in
order, ``"dropouts"`` last (added here); a family lists its own (run-time quantities such as
the gain ``k``) in :attr:`family_diagnostics` and writes them into ``D``.

**Registration.** :func:`register` adds a family to :data:`OBSERVERS` under its ``name``;
observers of other packages register through the entry-point group ``hgo_mj.observers``
(loaded by :func:`registered`), so that scenario files can name them.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, TypeVar

import numpy as np
from numpy.typing import NDArray

from .._validate import one_of
from ..exceptions import DesignError, DimensionError, DivergenceError
from ..systems.base import System

Array = NDArray[np.float64]

_F64 = np.dtype(np.float64)

#: the reactions to a sample period at which the observer's update is unstable
ON_UNSTABLE = ("raise", "warn", "ignore")
#: from this many member-samples on, a new :class:`Block`'s three arrays share one allocation
ONE_BUFFER = 4096


@dataclass
class Block:
    """Rows of an :meth:`Observer.advance`: the estimate after each of the T samples.

    ``x_hat`` ``(B, T, len(state_names))``, ``z_hat`` ``(B, T, n)``, ``diagnostics``
    ``(B, T, len(diagnostic_names))`` in the order of ``diagnostic_names``.

    Parameters
    ----------
    x_hat : (B, T, n_x) ndarray
        Estimate in the layout of :attr:`Observer.state_names` after each sample.
    z_hat : (B, T, n) ndarray
        Estimate in observer coordinates after each sample.
    diagnostics : (B, T, d) ndarray
        The values of :attr:`Observer.diagnostic_names` after each sample.

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.systems import SYSTEMS
    >>> rows = HighGainObserver(SYSTEMS["pendulum"](), k=10.0).run(
    ...     np.full((3, 1), 0.2), np.zeros((3, 1)), 0.01)
    >>> isinstance(rows, Block), rows.x_hat.shape, rows.diagnostics[0, -1].tolist()
    (True, (1, 3, 2), [10.0, 0.0])
    """

    x_hat: Array
    z_hat: Array
    diagnostics: Array


def _one_buffer(B: int, T: int, nx: int, n: int, nd: int) -> Block:
    """A new :class:`Block` ``(B, T, nx)``, ``(B, T, n)``, ``(B, T, nd)`` whose arrays are
    consecutive parts of one allocation. (glibc returns the freed top of its heap to the system
    when it exceeds twice the largest block freed before; three arrays of nearly that size per
    call exceeded it, so every call of a large batch page-faulted its fresh rows in again; one
    allocation of their total stays under it.)"""
    buf = np.empty(B * T * (nx + n + nd))
    a, b = B * T * nx, B * T * (nx + n)
    return Block(buf[:a].reshape(B, T, nx), buf[a:b].reshape(B, T, n), buf[b:].reshape(B, T, nd))


def check_outputs(outputs: Any, where: str = "outputs") -> tuple[int, ...]:
    """``outputs`` as a tuple of distinct non-negative channel indices (a sequence of ints:
    one output is a 1-tuple; an int, a bool or a float is refused, not coerced)."""
    if isinstance(outputs, (str, bytes)) or not isinstance(outputs, Sequence) or not outputs:
        raise DesignError(f"{where} must be a non-empty sequence of channel indices (one output "
                          f"is a 1-tuple such as (0,)); found {outputs!r}")
    for o in outputs:
        if isinstance(o, (bool, np.bool_)) or not isinstance(o, (int, np.integer)) or o < 0:
            raise DesignError(f"{where} must hold non-negative integer channel indices; found "
                              f"{outputs!r}")
    out = tuple(int(o) for o in outputs)
    if len(set(out)) != len(out):
        raise DesignError(f"{where} must be distinct channels; found {list(out)}")
    return out


def batch_rows(name: str, value: Any, width: int, batch: int | None) -> Array:
    """An initial value given for every member ``(width,)`` or per member ``(B, width)``, as a
    fresh C-contiguous ``(B, width)`` float array (``B = batch``, or the value's own ``B``, or
    1). Numbers only: strings and booleans are refused; values must be finite."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "iuf" or arr.dtype == np.bool_:
        raise DimensionError(f"{name} must be an array of real numbers of shape ({width},) or "
                             f"(B, {width}); found {value!r}")
    if arr.ndim == 1 and arr.shape == (width,):
        out = np.tile(arr.astype(float), (1 if batch is None else batch, 1))
    elif arr.ndim == 2 and arr.shape[1] == width and (batch is None or arr.shape[0] == batch):
        out = np.array(arr, dtype=float, order="C")
    else:
        want = f"({width},) or ({'B' if batch is None else batch}, {width})"
        raise DimensionError(f"{name} must have shape {want}; found shape {arr.shape}")
    if not np.all(np.isfinite(out)):
        raise DesignError(f"{name} must be finite; found {out.tolist()}")
    return out


def _positive_dt(dt: Any) -> float:
    """``dt`` as a float: a positive finite real number (a bool or a string is refused)."""
    if not (isinstance(dt, (float, int, np.floating, np.integer)) and not isinstance(dt, bool)
            and math.isfinite(dt) and dt > 0):
        raise DesignError(f"dt must be a positive finite number; found {dt!r}")
    return float(dt)


class Observer(ABC):
    """Abstract base of every observer family (see the module docstring for the contract).

    Parameters
    ----------
    system : System or None
        The model the observer designs against (its normal form, inverse map and model term),
        or None for an order-only observer (then ``order`` is needed).
    order : int, optional
        The dimension ``n`` of ``z``; must equal the system's normal-form order if both given.
    outputs : tuple of int
        The measured channels this observer reads (one output: a 1-tuple).
    on_unstable : {"raise", "warn", "ignore"}
        What :meth:`check_period` does when the update is unstable at the sample period.

    Attributes
    ----------
    n : int
        Dimension of ``z``.
    outputs : tuple of int
    batch : int
        The number of copies advanced together (1 for an unbatched observer).
    dropouts_ : int or (B,) int array
        NaN samples consumed (per member).
    inverse_failures_ : int or (B,) int array
        Failed evaluations of the inverse normal-form map (per member).

    Raises
    ------
    DesignError
        ``system`` is neither a System nor None, ``outputs`` is not a sequence of distinct
        non-negative channel indices, ``on_unstable`` is not one of its values, or neither a
        system with a normal form nor ``order`` gives ``n``.
    DimensionError
        A channel of ``outputs`` the system does not have, or an ``order`` that differs from
        the system's normal-form order.

    Examples
    --------
    A family subclasses Observer; a user builds one through its class or
    :func:`~hgo_mj.observers.make_observer`:

    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.systems import SYSTEMS
    >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
    >>> isinstance(obs, Observer), obs.n, obs.outputs, obs.state_names
    (True, 2, (0,), ('angle', 'angular_velocity'))
    """

    #: registry name, e.g. ``"high_gain"``
    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    reference: ClassVar[str] = ""
    #: the family's own run-time quantities, in the order ``_advance`` writes them into ``D``
    #: (a class attribute; an instance may set its own where they depend on its form)
    family_diagnostics: tuple[str, ...] = ()
    #: whether ``system`` needs a single-output normal form (``normal_form_order``)
    needs_normal_form: ClassVar[bool] = True
    #: whether a sample moves the estimate at its own instant (a discrete measurement update:
    #: the Kalman filters; see :meth:`filtered`)
    measurement_update: ClassVar[bool] = False

    def __init__(self, system: System | None, *, order: int | None = None,
                 outputs: Any = (0,), on_unstable: str = "raise") -> None:
        if system is not None and not isinstance(system, System):
            raise DesignError(f"system must be a System instance or None; found "
                              f"{type(system).__name__}")
        self.system = system
        self.outputs = check_outputs(outputs)
        if system is not None and max(self.outputs) >= len(system.output_names):
            raise DimensionError(f"{type(self).__name__}: {type(system).__name__} has "
                                 f"{len(system.output_names)} output(s) "
                                 f"{list(system.output_names)}; found channel "
                                 f"{max(self.outputs)} in outputs {list(self.outputs)}")
        self.on_unstable = one_of("on_unstable", on_unstable, ON_UNSTABLE)
        self.n = self._order(system, order)
        self._cols = np.array(self.outputs, dtype=np.intp)
        self._max_col = max(self.outputs)
        #: the channels as a slice where they are consecutive (no fancy-index copy)
        lo, hi = self.outputs[0], self.outputs[-1] + 1
        self._cols_index: slice | NDArray[np.intp] = (slice(lo, hi) if self.outputs == tuple(range(lo, hi))
                                           else self._cols)
        self.batch = 1
        self._batched = False

    #: the observer form a system must declare (:meth:`System.form`), and the paper's words
    #: for it; ``None``: none
    required_form: ClassVar[tuple[str, str] | None] = None

    @classmethod
    def applicability(cls, system: System) -> str | None:
        """``None`` where this family can design against ``system``, else why not, in the
        paper's terms (one sentence). The base checks the single-output normal form
        (paper 000, eq. 1) and :attr:`required_form`; families add their own conditions.

        Parameters
        ----------
        system : System
            The model to design against.

        Returns
        -------
        str or None
            None where the family applies, else one sentence saying why it does not.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> HighGainObserver.applicability(SYSTEMS["pendulum"]()) is None
        True
        """
        if cls.needs_normal_form and system.normal_form_order is None:
            problem = getattr(system, "normal_form_problem", None)
            return problem or (f"needs a single-output observability normal form (paper 000, "
                               f"eq. 1); {type(system).__name__} declares none (outputs: "
                               f"{list(system.output_names)})")
        if cls.required_form is not None and cls.required_form[0] not in system.forms:
            kind, words = cls.required_form
            return (f"needs {words}: the {kind!r} form, which {type(system).__name__} does not "
                    f"declare (it declares {list(system.forms)})")
        return None

    # ----------------------------------------------------------- construction
    def _order(self, system: System | None, order: int | None) -> int:
        """``n`` from the system's normal form or the explicit ``order`` (checked to agree)."""
        if order is not None and (isinstance(order, (bool, np.bool_))
                                  or not isinstance(order, (int, np.integer)) or order < 1):
            raise DesignError(f"order must be a positive integer; found {order!r}")
        if not self.needs_normal_form:
            if order is None:
                raise DesignError(f"{type(self).__name__} needs an explicit order")
            return int(order)
        n_sys = None if system is None else system.normal_form_order
        if system is not None and n_sys is None:
            raise DesignError(f"{type(self).__name__} needs a single-output normal form; "
                              f"{type(system).__name__} has none")
        if order is None and n_sys is None:
            raise DesignError(f"{type(self).__name__} needs a system or an explicit order")
        if order is not None and n_sys is not None and order != n_sys:
            raise DimensionError(f"{type(self).__name__}: order {order} does not match "
                                 f"{type(system).__name__}'s normal form order {n_sys}")
        return int(order if order is not None else n_sys)  # type: ignore[arg-type]

    @property
    def n_inputs(self) -> int | None:
        """Width ``m`` of the input the observer reads: the system's inputs, or None (any
        width, unread) for an observer without a system."""
        return len(self.system.input_names) if self.system is not None else None

    @property
    def state_names(self) -> tuple[str, ...]:
        """Names of the entries of ``x_hat``: the system's state names, or ``z1 ... zn`` for an
        order-only observer (no system), whose estimate is the normal-form state itself."""
        if self.system is None:
            return tuple(f"z{i + 1}" for i in range(self.n))
        return tuple(self.system.state_names)

    @property
    def diagnostic_names(self) -> tuple[str, ...]:
        """Exactly the keys of :meth:`diagnostics`, in order: the family's, then dropouts."""
        return (*self.family_diagnostics, "dropouts")

    # --------------------------------------------------------- the family's part
    @abstractmethod
    def _reset(self, x0: Array | None, z0: Array | None, u0: Array) -> None:
        """Set the state of ``self.batch`` copies from ``x0`` ``(B, len(state_names))`` or ``z0``
        ``(B, n)`` (at most one given; neither: the family's default) and ``u0`` ``(B, m)``."""

    @abstractmethod
    def _advance(self, Y: Array, U: Array, dt: float, X: Array, Z: Array, D: Array) -> None:
        """Consume ``Y[:, j]`` ``(B, T, len(outputs))`` (NaN: a dropout of that member and
        channel) with ``U[:, j]`` ``(B, T, m)``, integrate over ``dt`` after each sample, and
        write the estimate after sample ``j`` into ``X[:, j]``, ``Z[:, j]`` and ``D[:, j]``
        (``family_diagnostics``). Raise :class:`DivergenceError` where the state blows up."""

    @abstractmethod
    def _current(self) -> tuple[Array, Array, Array]:
        """The current ``(x_hat (B, n_x), z_hat (B, n), family diagnostics (B, d))``."""

    def _filtered(self, Y: Array) -> Array:
        """The estimate ``(B, n_x)`` given also ``Y`` ``(B, p)`` (every measured channel) at
        the present instant, the state unchanged (:meth:`filtered`); a family with a discrete
        measurement update (:attr:`measurement_update`) overrides it."""
        return self._current()[0]

    def check_period(self, dt: float) -> None:  # noqa: B027 - optional, default: no check
        """Check that the update is stable at the sample period ``dt`` (the loop calls this
        before a run) and react as ``on_unstable`` says, naming the largest stable period.
        Default: nothing to check (an update stable for every period).

        Parameters
        ----------
        dt : float
            The sample period, in seconds.

        Raises
        ------
        DesignError
            (In a family that checks, with ``on_unstable="raise"``) the update is unstable at
            ``dt``; ``on_unstable="warn"`` warns instead, ``"ignore"`` does nothing.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> HighGainObserver(SYSTEMS["pendulum"](), k=10.0).check_period(0.01)  # stable: silent
        """

    def params(self) -> dict[str, Any]:
        """Constructor parameters, JSON-ready, for a trajectory's metadata.

        Returns
        -------
        dict
            Parameter name -> JSON-ready value (lists, floats, strings, None).

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> HighGainObserver(SYSTEMS["pendulum"](), k=10.0).params()
        {'k': 10.0, 'p': [2.0, 1.0], 'order': 2, 'outputs': [0], 'model': False,
         'method': 'exact', 'z_bounds': None}
        """
        return {"outputs": list(self.outputs)}

    # --------------------------------------------------------------- derived
    def reset(self, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None,
              batch: int | None = None) -> None:
        """Restart ``batch`` copies (default: the batch of the initial estimate, else one
        unbatched copy) from ``x_hat0`` (the layout of :attr:`state_names`) or ``z_hat0``
        (``(n,)`` for every member, or ``(B, n)``); neither: the constructor's initial
        estimate. ``u0`` (``(m,)`` or ``(B, m)``) is the input the maps ``to_normal`` and
        ``from_normal`` read at the start (default zero).

        Parameters
        ----------
        x_hat0 : array_like, optional
            Initial estimate in the layout of :attr:`state_names`: ``(n_x,)`` for every member
            or ``(B, n_x)`` (which makes the observer batched).
        z_hat0 : array_like, optional
            Initial estimate in observer coordinates, ``(n,)`` or ``(B, n)``; not together
            with ``x_hat0``.
        u0 : array_like, optional
            Input at the start, ``(m,)`` or ``(B, m)``; default zero.
        batch : int, optional
            Number of members B; given, the observer is batched (public arrays keep the
            leading B axis).

        Raises
        ------
        DesignError
            Both ``x_hat0`` and ``z_hat0`` given, ``batch`` not a positive integer, or a
            non-finite initial value.
        DimensionError
            An initial value or ``u0`` of the wrong shape.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> obs.reset([0.1, 0.0])
        >>> obs.x_hat
        array([0.1, 0. ])
        >>> obs.reset(batch=3)
        >>> obs.x_hat.shape
        (3, 2)
        """
        if x_hat0 is not None and z_hat0 is not None:
            raise DesignError("give x_hat0 or z_hat0, not both")
        if batch is not None and (isinstance(batch, (bool, np.bool_))
                                  or not isinstance(batch, (int, np.integer)) or batch < 1):
            raise DesignError(f"batch must be a positive integer; found {batch!r}")
        given = x_hat0 if x_hat0 is not None else z_hat0
        batched = batch is not None or (given is not None and np.ndim(given) == 2)
        x0 = None if x_hat0 is None else batch_rows("x_hat0", x_hat0, len(self.state_names), batch)
        z0 = None if z_hat0 is None else batch_rows("z_hat0", z_hat0, self.n, batch)
        B = batch if batch is not None else (
            (x0 if x0 is not None else z0).shape[0] if given is not None else 1)  # type: ignore[union-attr]
        m = self.n_inputs
        if u0 is None or m is None:
            u = np.zeros((B, m or 0))
        else:
            u = batch_rows("u0", u0, m, B)
        self.batch, self._batched = int(B), batched
        self._dropouts = np.zeros(B, dtype=np.int64)
        self._inverse_failures = np.zeros(B, dtype=np.int64)
        #: the width of ``x_hat`` (``len(state_names)``, looked up once per reset)
        self._nx = len(self.state_names)
        self._x_held = np.empty((B, self._nx))
        self._x_held.fill(np.nan)  # np.full's values, without its Python-level wrapper
        self._reset(x0, z0, u)

    def reset_members(self, idx: Sequence[int]) -> None:
        """Restart the members ``idx`` of a batch from the constructor's initial estimate, as
        :meth:`reset` starts every member (zero input); the others go on untouched.

        Derived once for every family: a copy of this observer (kept for the next call) is
        reset to ``len(idx)`` members, and each per-member array of the state (leading axis
        B here, ``len(idx)`` in the copy, the rest of the shape the same; observers held by
        this one, as a bank's, likewise) takes its rows from it. The member is then what a
        fresh reset gives, bit for bit.

        Parameters
        ----------
        idx : sequence of int
            The members to restart, each in ``0 .. batch - 1``.

        Raises
        ------
        DesignError
            An unbatched observer, or a member index outside the batch, or members that share
            a clock or counter (one member cannot be restarted alone).

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> obs.reset(batch=3)
        >>> obs.step(np.full((3, 1), 0.2), np.zeros((3, 1)), 0.01)
        >>> obs.reset_members([1])
        >>> obs.x_hat.round(3)
        array([[0.038, 0.181],
               [0.   , 0.   ],
               [0.038, 0.181]])
        """
        rows = [int(b) for b in idx]
        if not self._batched:
            raise DesignError(f"{self.name}: reset_members needs a batched observer (reset with "
                              f"batch=B); this one is unbatched")
        bad = [b for b in rows if not 0 <= b < self.batch]
        if bad:
            raise DesignError(f"{self.name}: member(s) {bad} outside the batch of {self.batch}")
        if not rows:
            return
        if len(rows) == self.batch:
            self.reset(batch=self.batch)
            return
        fresh = self.__dict__.get("_fresh_copy")
        if fresh is None:
            import copy

            state = {k: v for k, v in self.__dict__.items() if k != "_fresh_copy"}
            fresh = copy.copy(self)
            fresh.__dict__ = copy.deepcopy(state)
            self._fresh_copy = fresh
        fresh.reset(batch=len(rows))
        shared = _shared_clock(self, fresh)
        if shared:
            raise DesignError(f"{self.name}: its members share a clock or counter "
                              f"({', '.join(shared)}): one member cannot be restarted alone")
        _transplant(self, fresh, rows, self.batch, len(rows))

    def advance(self, Y: Any, U: Any, dt: float) -> Block:
        """Consume T samples of B members: ``Y`` ``(B, T, p)`` (every measured channel; the
        observer reads :attr:`outputs`), ``U`` ``(B, T, m)``; return the rows of the estimate
        after each sample (:class:`Block`). The validating entry; the loop calls
        :meth:`_advance_checked` on arrays it has already checked.

        Parameters
        ----------
        Y : array_like
            Measurements ``(B, T, p)``, every measured channel; NaN is a dropout.
        U : array_like
            Inputs ``(B, T, m)``, finite.
        dt : float
            Sample period in seconds, positive.

        Returns
        -------
        Block
            ``x_hat`` ``(B, T, n_x)``, ``z_hat`` ``(B, T, n)`` and ``diagnostics``
            ``(B, T, len(diagnostic_names))`` after each sample.

        Raises
        ------
        DimensionError
            ``Y`` or ``U`` of the wrong shape for this batch, or not real numbers.
        DesignError
            ``dt`` not a positive finite number, or a non-finite input.
        DivergenceError
            An infinite measurement, or (from the family) a state that blows up.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> obs.reset(batch=3)
        >>> rows = obs.advance(np.full((3, 4, 1), 0.2), np.zeros((3, 4, 1)), 0.01)
        >>> rows.x_hat.shape, rows.z_hat.shape, rows.diagnostics.shape
        ((3, 4, 2), (3, 4, 2), (3, 4, 2))
        """
        Y, U = self._floats("y", Y), self._inputs(U)
        if Y.ndim != 3 or Y.shape[0] != self.batch or Y.shape[2] <= self._max_col:
            raise DimensionError(f"{self.name}: y must have shape (B={self.batch}, T, p) with "
                                 f"channel(s) {list(self.outputs)}; found shape {Y.shape}")
        m = self.n_inputs
        if U.ndim != 3 or U.shape[:2] != (self.batch, Y.shape[1]) or (
                m is not None and U.shape[2] != m):
            raise DimensionError(f"{self.name}: u must have shape ({self.batch}, {Y.shape[1]}, "
                                 f"{'m' if m is None else m}); found shape {U.shape}")
        return self._advance_checked(Y, U, _positive_dt(dt))

    def _advance_checked(self, Y: Array, U: Array, dt: float, out: Block | None = None) -> Block:
        """:meth:`advance` without the shape checks (``Y`` ``(B, T, p)`` float); the rows are
        written into ``out`` where it is given with these B and T (a caller that keeps no
        rows reuses its block), else into a new :class:`Block`."""
        # a C-contiguous float64 copy of the observer's channels: a family may write into its
        # measurement block
        Yo = Y[..., self._cols_index]
        Yo = Yo.copy() if Yo.dtype is _F64 else np.array(Yo, dtype=np.float64, order="C")
        B, T = Yo.shape[0], Yo.shape[1]
        nd = len(self.family_diagnostics)
        if out is not None and out.z_hat.shape[:2] == (B, T):
            X, Z, D = out.x_hat, out.z_hat, out.diagnostics
        elif B * T < ONE_BUFFER:
            X = np.empty((B, T, self._nx))
            Z = np.empty((B, T, self.n))
            D = np.empty((B, T, nd + 1))
            out = Block(X, Z, D)
        else:
            out = _one_buffer(B, T, self._nx, self.n, nd + 1)
            X, Z, D = out.x_hat, out.z_hat, out.diagnostics
        finite = (math.isfinite(Yo.item()) if Yo.size == 1  # one sample of one channel: cheap
                  else bool(np.isfinite(Yo).all()))
        if not finite:  # dropouts (NaN) counted; an infinite value refused
            if np.isinf(Yo).any():
                b, j, c = (int(v[0]) for v in np.nonzero(np.isinf(Yo)))
                raise DivergenceError(f"{self.name}: measurement y[{self.outputs[c]}] is "
                                      f"{Yo[b, j, c]} (member {b}, sample {j})")
            lost = np.cumsum(np.isnan(Yo).any(axis=2), axis=1)
        else:
            lost = None
        if not U.flags.c_contiguous:
            U = np.ascontiguousarray(U)
        self._advance(Yo, U, dt, X, Z, D[..., :nd])
        if lost is None:  # (D[..., nd] and a Python number: the cheapest indexing for one row)
            D[..., nd] = self._dropouts.item(0) if B == 1 else self._dropouts[:, None]
        else:
            D[:, :, nd] = self._dropouts[:, None] + lost
            self._dropouts = self._dropouts + lost[:, -1]
        return out

    def step(self, y: Any, u: Any, dt: float) -> None:
        """One sample of every member: ``y`` ``(B, p)``, ``u`` ``(B, m)``.

        Parameters
        ----------
        y : array_like
            Measurements ``(B, p)``; NaN is a dropout.
        u : array_like
            Inputs ``(B, m)``.
        dt : float
            Sample period in seconds.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> obs.reset(batch=2)
        >>> obs.step(np.full((2, 1), 0.2), np.zeros((2, 1)), 0.01)
        >>> obs.x_hat.round(3)
        array([[0.038, 0.181],
               [0.038, 0.181]])
        """
        self.advance(np.asarray(y, dtype=float)[:, None], np.asarray(u, dtype=float)[:, None], dt)

    def update(self, y: Any, u: Any, dt: float) -> Array:
        """One sample of an unbatched observer: ``y`` ``(p,)``, ``u`` ``(m,)``; returns
        ``x_hat`` after it, ``(n_x,)``.

        Parameters
        ----------
        y : array_like
            Measurement ``(p,)``; NaN is a dropout.
        u : array_like
            Input ``(m,)``.
        dt : float
            Sample period in seconds.

        Returns
        -------
        (n_x,) ndarray
            The estimate after the sample, in the layout of :attr:`state_names`.

        Raises
        ------
        DimensionError
            A batched observer, or ``y``/``u`` not vectors of the needed widths.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> obs.reset([0.1, 0.0])
        >>> obs.update([0.2], [0.0], 0.01).round(4)
        array([0.119 , 0.0906])
        """
        if self._batched:
            raise DimensionError(f"{self.name}: update() is for an unbatched observer; this one "
                                 f"holds a batch of {self.batch} (use step or advance)")
        ya, ua = self._floats("y", y), self._inputs(u)
        if ya.ndim != 1 or ya.shape[0] <= self._max_col:
            raise DimensionError(f"{self.name}: y must be a vector with channel(s) "
                                 f"{list(self.outputs)} (the measured outputs this observer "
                                 f"reads); found {y!r}")
        m = self.n_inputs
        if ua.ndim != 1 or (m is not None and ua.shape[0] != m):
            raise DimensionError(f"{self.name}: u must have shape ({'m' if m is None else m},); "
                                 f"found shape {ua.shape}")
        if not (type(dt) is float and dt > 0 and dt < math.inf):
            dt = _positive_dt(dt)
        return self._advance_checked(ya.reshape(1, 1, -1), ua.reshape(1, 1, -1),
                                     dt).x_hat[0, 0]

    def filtered(self, y: Any) -> Array:
        """The estimate at the present instant given also ``y``, measured at this instant,
        without consuming it: the observer's state is unchanged and the next :meth:`advance`
        consumes that sample as usual (the *current* estimate, where :attr:`x_hat` is the
        prediction made before the sample: the current and prediction estimators of G. F.
        Franklin, J. D. Powell, M. L. Workman, *Digital Control of Dynamic Systems*, 3rd ed.,
        sec. 8.2).

        Only an observer with a discrete measurement update (:attr:`measurement_update`: the
        Kalman filters, :math:`\\hat x_{k|k}` against :math:`\\hat x_{k|k-1}`) has one that
        differs from :attr:`x_hat`. The continuous-time observers (every other family) take a
        sample through their output injection over the sample period after it: a sample moves
        nothing at its own instant, and their current estimate is :attr:`x_hat`.

        Parameters
        ----------
        y : array_like
            The measurement at this instant, ``(p,)`` (unbatched) or ``(B, p)``, every
            measured channel; NaN is a lost channel.

        Returns
        -------
        (n_x,) or (B, n_x) ndarray
            The estimate in the layout of :attr:`state_names`.

        Raises
        ------
        DimensionError
            ``y`` of the wrong shape or not real numbers.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> obs.reset([0.1, 0.0])
        >>> obs.filtered([0.3]).tolist() == obs.x_hat.tolist()  # continuous-time: the same
        True
        """
        Y = self._floats("y", y)
        if Y.ndim == 1 and not self._batched:
            Y = Y.reshape(1, -1)
        if Y.ndim != 2 or Y.shape[0] != self.batch or Y.shape[1] <= self._max_col:
            want = f"({self.batch}, p)" if self._batched else "(p,)"
            raise DimensionError(f"{self.name}: y must have shape {want} with channel(s) "
                                 f"{list(self.outputs)}; found shape {Y.shape}")
        return self._public(np.array(self._filtered(Y), dtype=np.float64))  # type: ignore[no-any-return]

    def run(self, ys: Any, us: Any, dt: float, *, x_hat0: Any = None) -> Block:
        """Offline driver over recorded data (filterpy's ``batch_filter``): reset (unbatched,
        or batched when ``ys`` is ``(B, T, p)``), then advance over ``ys`` ``(T, p)`` with
        ``us`` ``(T, m)``. The returned rows are the estimate *after* each sample.

        Parameters
        ----------
        ys : array_like
            Measurements ``(T, p)``, or ``(B, T, p)`` for a batch.
        us : array_like
            Inputs ``(T, m)``, or ``(B, T, m)``.
        dt : float
            Sample period in seconds.
        x_hat0 : array_like, optional
            Initial estimate (as in :meth:`reset`); default: the constructor's.

        Returns
        -------
        Block
            The rows after each sample, with a leading batch axis (1 for ``(T, p)`` data).

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> rows = obs.run(np.full((5, 1), 0.2), np.zeros((5, 1)), 0.01)
        >>> rows.x_hat.shape
        (1, 5, 2)
        """
        ya, ua = self._floats("ys", ys), self._inputs(us, "us")
        if ya.ndim == 2:
            self.reset(x_hat0)
            return self.advance(ya[None], ua[None], dt)
        self.reset(x_hat0, batch=ya.shape[0] if ya.ndim == 3 else None)
        return self.advance(ya, ua, dt)

    def _public(self, a: NDArray[Any]) -> Any:
        """Drop the batch axis of an unbatched observer (``a[0]``; a float for a scalar)."""
        if self._batched:
            return a
        v = a[0]
        return v.item() if np.ndim(v) == 0 else v

    @property
    def z_hat(self) -> Array:
        """The current estimate in observer coordinates, ``(n,)`` or ``(B, n)``."""
        return self._public(self._current()[1])  # type: ignore[no-any-return]

    @property
    def x_hat(self) -> Array:
        """The current estimate in the layout of :attr:`state_names`, ``(n_x,)`` or ``(B, n_x)``."""
        return self._public(self._current()[0])  # type: ignore[no-any-return]

    @property
    def dropouts_(self) -> Any:
        return self._public(self._dropouts)

    @property
    def inverse_failures_(self) -> Any:
        return self._public(self._inverse_failures)

    def diagnostics(self) -> dict[str, Any]:
        """The current run-time quantities named in :attr:`diagnostic_names` (floats, or
        ``(B,)`` arrays for a batched observer).

        Returns
        -------
        dict
            :attr:`diagnostic_names` -> float, or ``(B,)`` array when batched.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> obs.reset()
        >>> obs.diagnostics()
        {'k': 10.0, 'dropouts': 0.0}
        """
        d = self._current()[2]
        out = {name: self._public(d[:, j].astype(float)) for j, name in
               enumerate(self.family_diagnostics)}
        out["dropouts"] = self._public(self._dropouts.astype(float))
        return out

    # --------------------------------------------------------------- helpers
    def _floats(self, what: str, value: Any) -> Array:
        """``value`` as a float array: real numbers only (a bool or a string is refused, not
        converted); NaN is allowed (a measurement's dropout)."""
        a = np.asarray(value)
        if a.dtype.kind not in "iuf":
            raise DimensionError(f"{self.name}: {what} must be an array of real numbers; found "
                                 f"{value!r}")
        return a.astype(np.float64, copy=False)

    def _inputs(self, value: Any, what: str = "u") -> Array:
        """The input as a float array: real numbers, finite (an input is never a dropout)."""
        a = self._floats(what, value)
        if not np.isfinite(a).all():
            at = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
            raise DesignError(f"{self.name}: {what} must be finite; found {what}{list(at)} = "
                              f"{a[at]}")
        return a

    def _initial_z(self, x0: Array | None, z0: Array | None, u0: Array) -> Array:
        """``(B, n)`` observer coordinates from a physical ``x0`` (through ``to_normal``) or
        ``z0``; zero if neither is given."""
        if z0 is not None:
            return z0
        if x0 is None:
            return np.zeros((self.batch, self.n))
        if self.system is None:
            return x0
        return np.array([self.system.to_normal(x, u) for x, u in zip(x0, u0)], dtype=float)

    def _to_physical(self, Z: Array, U: Array, X: Array) -> None:
        """Write ``system.from_normal`` of the rows ``Z`` ``(B, T, n)`` (inputs ``U``) into ``X``.
        Where the inverse is undefined (the system raises :class:`DesignError`) count it in
        ``inverse_failures_`` and hold the member's last valid value (NaN before any). Other
        errors (a math domain error on a blown-up ``z``) propagate as a divergence. Systems
        offering a vectorized ``from_normal_batch(Z, U)`` (rows ``(N, n)``) are used whole."""
        sys = self.system
        if sys is None:
            X[...] = Z
            return
        batch_map: Callable[[Array, Array], Array] | None = getattr(sys, "from_normal_batch", None)
        B, T = Z.shape[0], Z.shape[1]
        if batch_map is not None:
            flat = batch_map(Z.reshape(B * T, -1), U.reshape(B * T, -1)).reshape(B, T, -1)
            self._check_width(flat.shape[2], X.shape[2])
            ok = np.all(np.isfinite(flat), axis=2) | ~np.all(np.isfinite(Z), axis=2)
            if ok.all():
                X[...] = flat
                if T:  # as the per-row path: the last row is the member's held value
                    self._x_held[...] = flat[:, -1]
                return
        for b in range(B):
            held = self._x_held[b]
            for j in range(T):
                try:
                    x = sys.from_normal_unchecked(Z[b, j], U[b, j])
                except DesignError:
                    self._inverse_failures[b] += 1
                    X[b, j] = held
                    continue
                held = np.asarray(x, dtype=float)
                self._check_width(held.size, X.shape[2])
                X[b, j] = held
            self._x_held[b] = held

    def _check_width(self, width: int, named: int) -> None:
        if width != named:
            raise DimensionError(f"{type(self).__name__}: state_names must name the {width} "
                                 f"entries of x_hat; found {named} {list(self.state_names)}")

    def __repr__(self) -> str:
        return f"{type(self).__name__}(outputs={list(self.outputs)}, batch={self.batch})"


ObserverT = TypeVar("ObserverT", bound=type[Observer])

__all__ = ["ON_UNSTABLE", "OBSERVERS", "Block", "Observer", "register", "registered"]

def _shared_clock(dst: Any, src: Any) -> list[str]:
    """The numbers (ints, floats) of ``dst``'s state, and of the observers it holds, that are
    not what a fresh reset (``src``) gives: a clock or a counter shared by the members."""
    out = []
    for key, d in vars(dst).items():
        s = vars(src).get(key)
        if isinstance(d, (int, float)) and not isinstance(d, bool) and key != "batch":
            if not (d == s or (d != d and s != s)):
                out.append(key)
        elif isinstance(d, Observer) and isinstance(s, Observer):
            out += _shared_clock(d, s)
        elif isinstance(d, (list, tuple)) and isinstance(s, (list, tuple)) and len(d) == len(s):
            for di, si in zip(d, s):
                if isinstance(di, Observer) and isinstance(si, Observer):
                    out += _shared_clock(di, si)
    return out


def _transplant(dst: Any, src: Any, rows: list[int], B: int, k: int) -> None:
    """Copy the ``k`` members of ``src`` into the members ``rows`` of ``dst`` (B members):
    every array attribute whose leading axis is B in ``dst`` and k in ``src`` (the rest of the
    shape equal), in the observers they hold (attributes, lists and tuples) likewise."""
    for key, d in vars(dst).items():
        if key == "_fresh_copy":
            continue
        s = vars(src).get(key)
        if isinstance(d, np.ndarray) and isinstance(s, np.ndarray):
            if d.ndim and s.ndim == d.ndim and d.shape[0] == B and s.shape[0] == k \
                    and d.shape[1:] == s.shape[1:]:
                d[rows] = s
        elif isinstance(d, Observer) and isinstance(s, Observer):
            _transplant(d, s, rows, B, k)
        elif isinstance(d, (list, tuple)) and isinstance(s, (list, tuple)) and len(d) == len(s):
            for di, si in zip(d, s):
                if isinstance(di, Observer) and isinstance(si, Observer):
                    _transplant(di, si, rows, B, k)


#: registry name -> observer class (filled by :func:`register`)
OBSERVERS: dict[str, type[Observer]] = {}


def register(cls: ObserverT) -> ObserverT:
    """Class decorator: add an observer family to :data:`OBSERVERS` under its ``name``.

    Parameters
    ----------
    cls : type
        An :class:`Observer` subclass with a non-empty class attribute ``name``.

    Returns
    -------
    type
        ``cls`` itself (so it works as a decorator).

    Raises
    ------
    DesignError
        ``cls`` is not an Observer subclass, has no ``name``, or another class is registered
        under that name already.

    Examples
    --------
    >>> from hgo_mj.observers import HighGainObserver
    >>> register(HighGainObserver) is HighGainObserver  # registering again is a no-op
    True
    >>> register(int)
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: register takes an Observer subclass; found <class 'int'>
    """
    if not (isinstance(cls, type) and issubclass(cls, Observer)):
        raise DesignError(f"register takes an Observer subclass; found {cls!r}")
    if not cls.name:
        raise DesignError(f"{cls.__name__} needs a registry name (class attribute 'name')")
    if cls.name in OBSERVERS and OBSERVERS[cls.name] is not cls:
        raise DesignError(f"an observer named {cls.name!r} is registered already "
                          f"({OBSERVERS[cls.name].__module__}.{OBSERVERS[cls.name].__name__})")
    OBSERVERS[cls.name] = cls
    return cls


_ENTRY_POINTS_LOADED = False


def registered() -> dict[str, type[Observer]]:
    """:data:`OBSERVERS`, after loading the entry-point group ``hgo_mj.observers`` once (each
    entry point names an :class:`Observer` subclass; one that fails to import is an error
    naming it).

    Returns
    -------
    dict
        Registry name -> Observer subclass (the same object as :data:`OBSERVERS`).

    Raises
    ------
    DesignError
        An entry point of the group that fails to import, or names no Observer subclass.

    Examples
    --------
    >>> import hgo_mj.observers
    >>> reg = registered()
    >>> reg["high_gain"].__name__, reg is OBSERVERS
    ('HighGainObserver', True)
    """
    global _ENTRY_POINTS_LOADED
    if not _ENTRY_POINTS_LOADED:
        from importlib.metadata import entry_points

        for ep in entry_points(group="hgo_mj.observers"):
            try:
                cls = ep.load()
            except Exception as exc:  # noqa: BLE001 - any import failure, reported by name
                raise DesignError(f"entry point {ep.name!r} = {ep.value!r} of group "
                                  f"hgo_mj.observers does not import: {type(exc).__name__}: "
                                  f"{exc}") from exc
            register(cls)
        _ENTRY_POINTS_LOADED = True
    return OBSERVERS
