"""The observer contract: state and parameters as data, one pure step, a batch axis.

An observer is a continuous-time ODE in observer coordinates ``z`` driven by the measurement,
which is held constant between samples. Its **state is data** and its **parameters are data**,
in the shape of dynamax's ``_predict``/``_condition_on``:

* :meth:`Observer.parameters` ``(batch)`` -> :class:`Params`: the tunable quantities (gains,
  noise covariances, adaptation gains), each ``(B, ...)``. A parameter may differ per member
  (``k`` of shape ``()`` for every member or ``(B,)``; ``Q`` of ``(n, n)`` or ``(B, n, n)``),
  so one batch holds many tunings; member ``i`` equals the single run with its own values, bit
  for bit.
* :meth:`Observer.init` ``(batch, x_hat0, ...)`` -> :class:`State`: named ``(B, ...)``
  arrays (the estimate, gains, parameter estimates, covariances, dropout counts).
* :meth:`Observer.step` ``(params, state, Y, U, dt) -> (state, block)``: **pure**: consume T
  samples ``Y`` ``(B, T, p)`` with inputs ``U`` ``(B, T, m)``, return the new state and the
  rows of the estimate after each sample (:class:`Block`); the state given is not touched.
* :meth:`Observer.current` ``(params, state)``: the estimate, ``z_hat`` and diagnostics now.

The object keeps what is not state: the model (``system``), names, checks, diagnostics'
names, the constructor's parameters (the defaults of :meth:`parameters`) and caches derived
from parameters (one-step maps per period). The loop holds the states: a replay after a failure
starts again from the state before the segment, and restarting members is a row assignment
(:meth:`State.put`).

For users with one run at hand the object also holds **one state of its own**: :meth:`reset`
starts it, :meth:`update` consumes one sample (the second public stepping verb, the one the
Gymnasium wrappers and a user's own loop call), :attr:`x_hat`, :attr:`z_hat` and
:meth:`diagnostics` read it, and :meth:`run` is the offline driver over a whole record (in the
spirit of filterpy's ``batch_filter``). All of them go through the same pure step.

**A family implements** (the equations, next to their paper): :meth:`Observer._parameters`
(its tunable parameters with their defaults, one member's shape), :meth:`Observer._init`
(the state fields of a batch), :meth:`Observer._step` (advance a state in place over a block
and write the rows), :meth:`Observer._current`, and where it has a discrete measurement update
:meth:`Observer._filtered`. Each of these sees the parameters of **one member** (a batch whose
members differ is handed to the family group by group of equal parameters, by the base): a
family is written once, for shared parameters, and gets per-member ones for free.

**Validate once, run unchecked.** The public entries check shapes, types and the period; the
loop checks them once per run (:func:`hgo_mj.loop.check_fits`) and calls
:meth:`Observer._step_checked`, which checks nothing per sample.

**Estimate layout.** ``x_hat`` has one entry per name in :attr:`Observer.state_names`. These
are the plant's state names when the observer estimates the physical state, but need not be:
an order-only observer (no system) estimates ``z1, z2, ...``, a model-free multi-output one the
outputs and their derivatives, an adaptive one appends parameter estimates. Trajectories,
metrics, figures and recordings match the estimate to the plant's states *by name*. An initial
estimate ``x_hat0`` always has this layout, ``(n_x,)`` for every member or ``(B, n_x)``.

**Measurements.** A measurement row holds the system's measured channels (never more: a wider
``y`` is a :class:`DimensionError`, at every public entry). Each value is a number of magnitude
at most :data:`MAX_MEASUREMENT` or NaN; the rule is the base's, checked once per call on the
whole block, so every family gets it:

* NaN (a sensor dropout) is never propagated: the observer integrates its prediction without
  output injection over that sample; the step counts it in the state's ``dropouts`` (per
  member);
* an infinite value, or one beyond :data:`MAX_MEASUREMENT`, raises :class:`DivergenceError`
  naming the channel, the member, the sample and the bound, before the family sees the block
  (no sample is ignored silently, and no family overflows on it).

**Undefined inverse map.** ``x_hat`` is the image of ``z_hat`` under the inverse normal-form
map, which may be undefined there (the bioreactor's ``Phi^-1`` needs ``m > 0``). Then ``x_hat``
holds its last valid value, and is **NaN before any valid value**; each failed evaluation is
counted in the state's ``inverse_failures`` (:meth:`Observer._to_physical`). Divergence is
judged on ``z_hat``, which is always defined.

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
from typing import TYPE_CHECKING, Any, ClassVar, TypeVar

import numpy as np
from numpy.typing import NDArray

from .._registry import LazyRegistry
from .._validate import one_of, sum_is_finite
from ..exceptions import DesignError, DimensionError, DivergenceError
from ..systems.base import System

Array = NDArray[np.float64]

_F64 = np.dtype(np.float64)

#: the reactions to a sample period at which the observer's update is unstable
ON_UNSTABLE = ("raise", "warn", "ignore")
#: the largest measurement magnitude an observer accepts (MuJoCo's ``mjMAXVAL``, beyond which
#: MuJoCo calls a value "huge" and resets its simulation): a value beyond it is no measurement
#: of a plant but a fault, and the gains and covariances would carry it to overflow
MAX_MEASUREMENT = 1e10
#: from this many member-samples on, a new :class:`Block`'s three arrays share one allocation
ONE_BUFFER = 4096


@dataclass
class Block:
    """Rows of an :meth:`Observer.step`: the estimate after each of the T samples.

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


@dataclass(frozen=True)
class Dimension:
    """One dimension of an observer's tuning space (:meth:`Observer.tuning_space`): a search
    variable, its bounds, its scale and its default.

    Parameters
    ----------
    name : str
        The search variable: a parameter's name (``"k"``), or an entry of one
        (``"Q[1]"``: the second diagonal entry of ``Q``).
    low, high : float
        The bounds, ``low < high``.
    log : bool
        Search on a log scale (gains, covariances) or a linear one.
    default : float
        The constructor's value.

    Examples
    --------
    >>> Dimension("k", 1.0, 100.0, True, 10.0)
    Dimension(name='k', low=1.0, high=100.0, log=True, default=10.0)
    """

    name: str
    low: float
    high: float
    log: bool
    default: float


def _one_buffer(B: int, T: int, nx: int, n: int, nd: int) -> Block:
    """A new :class:`Block` ``(B, T, nx)``, ``(B, T, n)``, ``(B, T, nd)`` whose arrays are
    consecutive parts of one allocation. (glibc returns the freed top of its heap to the system
    when it exceeds twice the largest block freed before; three arrays of nearly that size per
    call exceeded it, so every call of a large batch page-faulted its fresh rows in again; one
    allocation of their total stays under it.)"""
    buf = np.empty(B * T * (nx + n + nd))
    a, b = B * T * nx, B * T * (nx + n)
    return Block(buf[:a].reshape(B, T, nx), buf[a:b].reshape(B, T, n), buf[b:].reshape(B, T, nd))


def _new_block(B: int, T: int, nx: int, n: int, nd: int) -> Block:
    """A new :class:`Block` of these shapes: three arrays, or from :data:`ONE_BUFFER`
    member-samples on one allocation (:func:`_one_buffer`)."""
    if B * T >= ONE_BUFFER:
        return _one_buffer(B, T, nx, n, nd)
    return Block(np.empty((B, T, nx)), np.empty((B, T, n)), np.empty((B, T, nd)))


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


def _rows_of(value: Any, rows: Any) -> Any:
    """``value[rows]`` of an array, a :class:`State` or a tuple of them (a copy)."""
    if isinstance(value, State):
        return value.take(rows)
    if isinstance(value, tuple):
        return tuple(_rows_of(v, rows) for v in value)
    return value[rows]


def _put_rows(dst: Any, rows: Any, src: Any) -> None:
    """``dst[rows] = src`` for an array, a :class:`State` or a tuple of them."""
    if isinstance(dst, State):
        dst.put(rows, src)
    elif isinstance(dst, tuple):
        for d, s in zip(dst, src):
            _put_rows(d, rows, s)
    else:
        dst[rows] = src


def _copied(value: Any) -> Any:
    if isinstance(value, State):
        return value.copy()
    if isinstance(value, tuple):
        return tuple(_copied(v) for v in value)
    return value.copy()


_StateT = TypeVar("_StateT", bound="State")


class State:
    """An observer's state as data: named arrays, each with the leading batch axis ``B``
    (a field may also be a :class:`State` or a tuple of them: an observer bank's members).

    Read a field as an attribute (``state.z``); a family's :meth:`Observer._step` writes into
    the arrays or assigns a field anew (``state.z = ...``). :meth:`copy`, :meth:`take` and
    :meth:`put` are the whole of what the loop does with a state: keep it, and restart members.

    Parameters
    ----------
    **fields : ndarray or State or tuple of State
        The named fields; every array's first axis is the batch.

    Attributes
    ----------
    fields : dict
        Field name -> array (or nested state), in the order given.

    Examples
    --------
    >>> import numpy as np
    >>> s = State(z=np.zeros((3, 2)), dropouts=np.zeros(3, dtype=np.int64))
    >>> s.batch, s.z.shape
    (3, (3, 2))
    >>> s.put([1], State(z=np.ones((1, 2)), dropouts=np.zeros(1, dtype=np.int64)))
    >>> s.z[:, 0].tolist()
    [0.0, 1.0, 0.0]
    """

    def __init__(self, **fields: Any) -> None:
        vars(self).update(fields)  # plain attributes: a field is read at attribute speed

    if TYPE_CHECKING:  # the fields are dynamic: any name reads and writes an array
        def __getattr__(self, name: str) -> Any: ...

        def __setattr__(self, name: str, value: Any) -> None: ...

    @property
    def fields(self) -> dict[str, Any]:
        """Field name -> array (or nested state), in the order given (the live mapping)."""
        return vars(self)

    @property
    def batch(self) -> int:
        """The number of members ``B`` (the first axis of the first array field)."""
        for v in self.fields.values():
            if isinstance(v, np.ndarray):
                return int(v.shape[0])
            if isinstance(v, State):
                return v.batch
            if isinstance(v, tuple) and v:
                return int(v[0].batch)
        raise DesignError(f"{type(self).__name__} has no array field to give its batch")

    def copy(self: _StateT) -> _StateT:
        """A deep copy (new arrays).

        Returns
        -------
        State

        Examples
        --------
        >>> import numpy as np
        >>> s = State(z=np.zeros((2, 1)))
        >>> t = s.copy(); t.z[0] = 5.0
        >>> s.z[0].tolist()
        [0.0]
        """
        return type(self)(**{k: _copied(v) for k, v in self.fields.items()})

    def take(self: _StateT, rows: Any) -> _StateT:
        """The members ``rows`` as a new state (copies).

        Parameters
        ----------
        rows : sequence of int or ndarray or slice
            Member indices.

        Returns
        -------
        State
            ``len(rows)`` members.

        Examples
        --------
        >>> import numpy as np
        >>> State(z=np.arange(6.0).reshape(3, 2)).take([2]).z.tolist()
        [[4.0, 5.0]]
        """
        return type(self)(**{k: _rows_of(v, rows) for k, v in self.fields.items()})

    def put(self, rows: Any, src: State) -> None:
        """Write the members of ``src`` into the members ``rows`` of this state, in place.

        Parameters
        ----------
        rows : sequence of int or ndarray or slice
            Member indices, one per member of ``src``.
        src : State
            A state with the same fields and ``len(rows)`` members.

        Raises
        ------
        DesignError
            ``src`` has other fields.

        Examples
        --------
        >>> import numpy as np
        >>> s = State(z=np.zeros((2, 1)))
        >>> s.put([0], State(z=np.ones((1, 1))))
        >>> s.z.ravel().tolist()
        [1.0, 0.0]
        """
        if list(src.fields) != list(self.fields):
            raise DesignError(f"put: the states have different fields {list(self.fields)} and "
                              f"{list(src.fields)}")
        for k, v in self.fields.items():
            _put_rows(v, rows, src.fields[k])

    def __repr__(self) -> str:
        inner = ", ".join(f"{k}={getattr(v, 'shape', type(v).__name__)}"
                          for k, v in self.fields.items())
        return f"{type(self).__name__}({inner})"


class Params(State):
    """An observer's parameters as data: one ``(B, ...)`` array per tunable parameter (see
    :meth:`Observer.parameters`). The same container as :class:`State`; the arrays are
    read-only, so a family cannot change a parameter by accident.

    Parameters
    ----------
    **fields : ndarray
        Parameter name -> ``(B, ...)`` array.

    Examples
    --------
    >>> import numpy as np
    >>> p = Params(k=np.array([10.0, 20.0]))
    >>> p.batch, p.k.flags.writeable
    (2, False)
    """

    def __init__(self, **fields: Any) -> None:
        for v in fields.values():
            if isinstance(v, np.ndarray):
                v.flags.writeable = False
        super().__init__(**fields)

    def __setattr__(self, name: str, value: Any) -> None:
        raise DesignError(f"Params are read-only; make new ones (Observer.parameters) to "
                          f"change {name!r}")

    def __getstate__(self) -> dict[str, Any]:
        return {k: v for k, v in vars(self).items() if not k.startswith("_")}

    def __setstate__(self, fields: dict[str, Any]) -> None:
        vars(self).update(fields)

    @property
    def fields(self) -> dict[str, Any]:
        """Parameter name -> ``(B, ...)`` array (the caches :meth:`groups` and :meth:`key`
        keep are not fields)."""
        return {k: v for k, v in vars(self).items() if not k.startswith("_")}

    def take(self, rows: Any) -> Params:
        """The members ``rows`` as new parameters (:meth:`State.take`); where :meth:`groups`
        found one group, the new parameters' single group is known without a search (an
        environment's autoreset takes the members it restarts at nearly every step).

        Parameters
        ----------
        rows : sequence of int or ndarray or slice
            Member indices.

        Returns
        -------
        Params
            ``len(rows)`` members.

        Examples
        --------
        >>> import numpy as np
        >>> p = Params(k=np.array([1.0, 1.0, 1.0]))
        >>> _ = p.groups()
        >>> [(r.tolist(), q.k.item()) for r, q in p.take([0, 2]).groups()]
        [([0, 1], 1.0)]
        """
        out = super().take(rows)
        found = vars(self).get("_groups")
        if found is not None and len(found) == 1 and isinstance(found[0][0], np.ndarray):
            vars(out)["_groups"] = [(np.arange(out.batch), found[0][1])]
        return out

    def copy(self) -> Params:  # read-only arrays are shared, not copied
        """The same parameters (their arrays are read-only, so shared).

        Returns
        -------
        Params

        Examples
        --------
        >>> import numpy as np
        >>> p = Params(k=np.array([1.0]))
        >>> p.copy().k is p.k
        True
        """
        return type(self)(**self.fields)

    def member(self, b: int) -> Params:
        """Member ``b``'s parameters, without the batch axis (what a family's hooks see).

        Parameters
        ----------
        b : int
            The member.

        Returns
        -------
        Params
            Each field of one member's shape.

        Examples
        --------
        >>> import numpy as np
        >>> Params(k=np.array([10.0, 20.0])).member(1).k.item()
        20.0
        """
        return Params(**{k: (v.member(b) if isinstance(v, Params) else
                             tuple(x.member(b) for x in v) if isinstance(v, tuple) else v[b])
                         for k, v in self.fields.items()})

    def key(self) -> bytes:
        """The values as bytes: equal parameters give equal keys (a cache key for what a
        family derives from them).

        Returns
        -------
        bytes

        Examples
        --------
        >>> import numpy as np
        >>> Params(k=np.array(2.0)).key() == Params(k=np.array(2.0)).key()
        True
        """
        found = vars(self).get("_key")
        if found is None:
            found = vars(self)["_key"] = self._find_key()
        return found  # type: ignore[no-any-return]

    def _find_key(self) -> bytes:
        parts = []
        for v in self.fields.values():
            if isinstance(v, Params):
                parts.append(v.key())
            elif isinstance(v, tuple):
                parts.extend(x.key() for x in v)
            else:
                parts.append(np.ascontiguousarray(v, dtype=np.float64).tobytes())
        return b"|".join(parts)

    def groups(self) -> list[tuple[NDArray[np.intp], Params]]:
        """The members grouped by equal parameters: ``(rows, one member's parameters)`` per
        group, in order of first appearance (one group when every member shares them);
        ``rows`` is an index array, or a slice where the group's members are consecutive.

        Returns
        -------
        list of (ndarray, Params)

        Examples
        --------
        >>> import numpy as np
        >>> [(r, p.k.item()) for r, p in Params(k=np.array([1.0, 2.0, 1.0])).groups()]
        [(array([0, 2]), 1.0), (slice(1, 2, None), 2.0)]

        Consecutive members of a group are a slice (the base then steps views of the state,
        without copies): a tuning round's trials x seeds, seeds innermost, are.
        """
        found = vars(self).get("_groups")
        if found is None:  # computed once: the arrays are read-only
            found = vars(self)["_groups"] = self._find_groups()
        return found  # type: ignore[no-any-return]

    def _find_groups(self) -> list[tuple[Any, Params]]:
        arrays = [v for v in self.fields.values() if isinstance(v, np.ndarray)]
        if not arrays:  # no parameters: one group of every member
            return [(slice(None), self)]
        B = self.batch
        flat = [np.ascontiguousarray(v, dtype=np.float64).reshape(B, -1) for v in arrays]
        table = np.concatenate(flat, axis=1)
        if table.shape[0] == 1 or (table == table[:1]).all():
            return [(np.arange(B), self.member(0))]
        _, first, inverse = np.unique(table, axis=0, return_index=True, return_inverse=True)
        out: list[tuple[Any, Params]] = []
        for g in np.argsort(first):
            rows: Any = np.flatnonzero(inverse.ravel() == g)
            if rows[-1] - rows[0] + 1 == rows.size:  # consecutive members: a slice (views)
                rows = slice(int(rows[0]), int(rows[-1]) + 1)
            out.append((rows, self.member(int(first[g]))))
        return out


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
        The number of members of the observer's own state (1 for an unbatched observer).
    state : State
        The observer's own state (:meth:`reset`, :meth:`update`).
    dropouts_ : int or (B,) int array
        NaN samples consumed (per member) by the observer's own state.
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

    >>> import numpy as np
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.systems import SYSTEMS
    >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
    >>> isinstance(obs, Observer), obs.n, obs.outputs, obs.state_names
    (True, 2, (0,), ('angle', 'angular_velocity'))

    Three gains as one batch, each member its own single run:

    >>> params = obs.parameters(3, k=[5.0, 10.0, 20.0])
    >>> state = obs.init(3, params=params)
    >>> state, rows = obs.step(params, state, np.full((3, 4, 1), 0.2), np.zeros((3, 4, 1)), 0.01)
    >>> rows.diagnostics[:, -1, 0].tolist()
    [5.0, 10.0, 20.0]
    """

    #: registry name, e.g. ``"high_gain"``
    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    reference: ClassVar[str] = ""
    #: the family's own run-time quantities, in the order ``_step`` writes them into ``D``
    #: (a class attribute; an instance may set its own where they depend on its form)
    family_diagnostics: tuple[str, ...] = ()
    #: whether ``system`` needs a single-output normal form (``normal_form_order``)
    needs_normal_form: ClassVar[bool] = True
    #: whether a sample moves the estimate at its own instant (a discrete measurement update:
    #: the Kalman filters; see :meth:`filtered`)
    measurement_update: ClassVar[bool] = False
    #: whether the base hands the family's hooks one group of equal parameters at a time (see
    #: the module docstring); an observer that holds others (a bank) takes the whole batch
    grouped: ClassVar[bool] = True

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
        #: the widest measurement row: the system's outputs (None: no system, any width)
        self._max_width = None if system is None else len(system.output_names)
        #: the channels as a slice where they are consecutive (no fancy-index copy)
        lo, hi = self.outputs[0], self.outputs[-1] + 1
        self._cols_index: slice | NDArray[np.intp] = (slice(lo, hi) if self.outputs == tuple(range(lo, hi))
                                           else self._cols)
        self._held: tuple[Params, State] | None = None
        #: the rows :meth:`update` writes, reused while B stays (it returns a copy of x_hat)
        self._rows: Block | None = None
        #: whether the family shapes a state before a block (:meth:`_prepare`): else not called
        self._prepares = type(self)._prepare is not Observer._prepare
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
    def _parameters(self) -> dict[str, Any]:
        """The family's tunable parameters: name -> the constructor's value, in one member's
        shape (a float, or an array). Default: none."""
        return {}

    def _check_parameter(self, name: str, value: Any) -> Array:
        """One member's value of the parameter ``name``, checked (as the constructor checks
        it) and as a float array of the default's shape. Default: real and finite; a family
        adds its own conditions (positive, Hurwitz, ...)."""
        default = np.asarray(self._parameters()[name], dtype=np.float64)
        a = np.asarray(value)
        if a.dtype.kind not in "iuf" or a.dtype == np.bool_:
            raise DesignError(f"{self.name}: parameter {name} must be real numbers; found "
                              f"{value!r}")
        if a.shape != default.shape:
            raise DimensionError(f"{self.name}: parameter {name} must have shape "
                                 f"{default.shape} per member; found shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise DesignError(f"{self.name}: parameter {name} must be finite; found {value!r}")
        return a.astype(np.float64)

    @abstractmethod
    def _init(self, p: Params, x0: Array | None, z0: Array | None,
              u0: Array) -> dict[str, Any]:
        """The family's state fields for ``len(u0)`` members with the parameters ``p`` (one
        member's) from ``x0`` ``(B, len(state_names))`` or ``z0`` ``(B, n)`` (at most one
        given; neither: the family's default) and ``u0`` ``(B, m)``."""

    @abstractmethod
    def _step(self, p: Params, s: State, Y: Array, U: Array, dt: float, X: Array, Z: Array,
              D: Array) -> None:
        """Advance the state ``s`` in place: consume ``Y[:, j]`` ``(B, T, len(outputs))``
        (NaN: a dropout of that member and channel) with ``U[:, j]`` ``(B, T, m)``, integrate
        over ``dt`` after each sample, and write the estimate after sample ``j`` into
        ``X[:, j]``, ``Z[:, j]`` and ``D[:, j]`` (``family_diagnostics``). Raise
        :class:`DivergenceError` where the state blows up."""

    @abstractmethod
    def _current(self, p: Params, s: State) -> tuple[Array, Array, Array]:
        """The current ``(x_hat (B, n_x), z_hat (B, n), family diagnostics (B, d))`` of the
        state ``s``: new arrays, none a view of ``s`` (:meth:`current` hands float64 ones out
        as they are, without another copy)."""

    def _filtered(self, p: Params, s: State, Y: Array) -> Array:
        """The estimate ``(B, n_x)`` given also ``Y`` ``(B, p)`` (every measured channel) at
        the present instant, the state unchanged (:meth:`filtered`); a family with a discrete
        measurement update (:attr:`measurement_update`) overrides it."""
        return self._current(p, s)[0]

    def _prepare(self, s: State, dt: float) -> None:  # noqa: B027 - optional hook
        """Shape the whole state ``s`` for the period ``dt`` before a block is split into
        groups of equal parameters (a window whose length is ``round(window / dt)``: every
        member's buffer one size); default: nothing."""

    def _check_period(self, p: Params, dt: float) -> None:  # noqa: B027 - optional hook
        """:meth:`check_period` for one member's parameters; default: nothing to check."""

    def check_period(self, dt: float, params: Params | None = None) -> None:
        """Check that the update is stable at the sample period ``dt`` for every member's
        parameters (the loop calls this before a run) and react as ``on_unstable`` says,
        naming the largest stable period. Default: nothing to check (an update stable for
        every period).

        Parameters
        ----------
        dt : float
            The sample period, in seconds.
        params : Params, optional
            The parameters to check (default: the constructor's).

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
        params = self.parameters(1) if params is None else params
        for _, p in self._groups(params):
            self._check_period(p, dt)

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

    def covariance(self, state: State) -> Array | None:
        """The covariance the observer keeps of its estimate ``x_hat`` of ``state``, ``(B,
        n_x, n_x)`` in the layout of :attr:`state_names` (a new array), for a family that
        keeps one (the Kalman filters); None for one that does not. With the true state it
        gives the NEES (:func:`hgo_mj.metrics.nees`), the benchmark's consistency score.

        Parameters
        ----------
        state : State
            The state to read.

        Returns
        -------
        ndarray or None

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> ob = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> ob.covariance(ob.init(1, [0.3, 0.0])) is None
        True
        """
        return None

    def predicted_output(self, x_hat: Array, z_hat: Array) -> Array | None:
        """The measured outputs an estimate predicts, ``(..., len(outputs))`` from rows
        ``x_hat`` ``(..., n_x)`` and ``z_hat`` ``(..., n)``: what tuning without ground truth
        compares with the next measurement (the output prediction error). Default: ``z_1``, the
        output in the observability normal form (paper 000, eq. 1), for a single-output
        observer; None where the family gives none.

        Parameters
        ----------
        x_hat : ndarray
            Estimates in the layout of :attr:`state_names`.
        z_hat : ndarray
            The same estimates in observer coordinates.

        Returns
        -------
        ndarray or None

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> ob = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> ob.predicted_output(np.zeros((1, 2)), np.array([[0.3, 1.0]])).tolist()
        [[0.3]]
        """
        if len(self.outputs) == 1 and self.needs_normal_form:
            return z_hat[..., :1]
        return None

    # --------------------------------------------------------- tuning space
    #: the factor around a positive default that the default tuning space spans (log scale)
    TUNING_SPAN: ClassVar[float] = 10.0

    def tuning_space(self) -> dict[str, Dimension]:
        """The search variables of this observer's tunable parameters (what ``hgo-mj tune``
        searches), by name: a positive scalar parameter on a log scale over
        ``[default / 10, 10 default]``; a square matrix (a covariance) by its positive
        diagonal entries ``"Q[i]"``, log scale over ``[default / 100, 100 default]``. Other
        parameters (polynomials, vectors) are not searched unless a family declares them
        (families override this with their papers' ranges).

        Returns
        -------
        dict of str to Dimension

        Examples
        --------
        >>> from hgo_mj.observers import make_observer
        >>> from hgo_mj.systems import SYSTEMS
        >>> make_observer("riccati", SYSTEMS["pendulum"](), gamma=20.0).tuning_space()["gamma"]
        Dimension(name='gamma', low=2.0, high=200.0, log=True, default=20.0)
        """
        out: dict[str, Dimension] = {}
        span = self.TUNING_SPAN
        for name, value in self._parameters().items():
            a = np.asarray(value, dtype=np.float64)
            if a.ndim == 0 and np.isfinite(a) and a > 0:
                v = float(a)
                out[name] = Dimension(name, v / span, v * span, True, v)
            elif a.ndim == 2 and a.shape[0] == a.shape[1]:
                for i, v in enumerate(np.diag(a).tolist()):
                    if np.isfinite(v) and v > 0:
                        key = f"{name}[{i}]"
                        out[key] = Dimension(key, v / span ** 2, v * span ** 2, True, v)
        return out

    def tuned_parameters(self, values: dict[str, float]) -> dict[str, Any]:
        """The parameter values (for :meth:`parameters`) of search values over
        :meth:`tuning_space`: a scalar as it is, an entry ``"Q[i]"`` into a copy of the
        constructor's value (a diagonal entry of a matrix, an entry of a vector); a parameter
        not searched keeps its value.

        Parameters
        ----------
        values : dict of str to float
            Search variable -> value (a subset of :meth:`tuning_space`).

        Returns
        -------
        dict
            Parameter name -> one member's value.

        Raises
        ------
        DesignError
            A name that is not a search variable of this observer (the valid ones listed).

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> HighGainObserver(SYSTEMS["pendulum"](), k=10.0).tuned_parameters({"k": 25.0})
        {'k': 25.0}
        """
        space = self.tuning_space()
        bad = [k for k in values if k not in space]
        if bad:
            raise DesignError(f"{self.name}: unknown search variable(s) {bad}; valid: "
                              f"{list(space)}")
        defaults = self._parameters()
        out: dict[str, Any] = {}
        for key, v in values.items():
            name, _, index = key.partition("[")
            if not index:
                out[name] = float(v)
                continue
            m = out.get(name)
            if m is None:
                m = out[name] = np.array(defaults[name], dtype=np.float64)
            i = int(index.rstrip("]"))
            if m.ndim == 1:  # an entry of a vector (a gain per chain)
                m[i] = float(v)
            else:  # a diagonal entry of a matrix (a covariance)
                m[i, i] = float(v)
        return out

    # --------------------------------------------------------- data: the pure API
    @property
    def parameter_names(self) -> tuple[str, ...]:
        """The names of the family's tunable parameters (the fields of :meth:`parameters`)."""
        return tuple(self._parameters())

    def parameters(self, batch: int = 1, **values: Any) -> Params:
        """The parameters of ``batch`` members as data: every tunable parameter ``(B, ...)``,
        the constructor's value unless given here, for every member (one member's shape) or
        per member (``(B, ...)``).

        Parameters
        ----------
        batch : int
            The number of members B.
        **values : array_like
            Parameter name -> one value for every member, or one per member (leading B).

        Returns
        -------
        Params
            One read-only ``(B, ...)`` array per name of :attr:`parameter_names`.

        Raises
        ------
        DesignError
            An unknown name (the valid ones listed), ``batch`` not a positive integer, or a
            value the family refuses (each member is checked as the constructor checks it).
        DimensionError
            A value that is neither one member's shape nor ``(B, ...)`` of it.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> obs.parameters(2, k=[10.0, 30.0]).k.tolist()
        [10.0, 30.0]
        >>> obs.parameters(2, gain=[1.0, 2.0])
        Traceback (most recent call last):
        ...
        hgo_mj.exceptions.DesignError: high_gain: unknown parameter(s) ['gain']; valid: ['k', 'p']
        """
        B = _batch_size(batch)
        defaults = self._parameters()
        bad = [k for k in values if k not in defaults]
        if bad:
            raise DesignError(f"{self.name}: unknown parameter(s) {bad}; valid: "
                              f"{list(defaults)}")
        out: dict[str, Array] = {}
        for name, default in defaults.items():
            shape = np.shape(default)
            if name not in values:
                out[name] = np.broadcast_to(np.asarray(default, dtype=np.float64),
                                            (B, *shape)).copy()
                continue
            a = np.asarray(values[name])
            if a.shape == (B, *shape) and a.dtype != object:  # one value per member
                out[name] = np.stack([self._check_parameter(name, a[b]) for b in range(B)])
            elif a.ndim <= len(shape) or a.dtype == object:  # one value (a family's shorthand
                one = self._check_parameter(name, values[name])  # as its constructor takes)
                out[name] = np.broadcast_to(one, (B, *shape)).copy()
            else:
                raise DimensionError(f"{self.name}: parameter {name} must have shape {shape} "
                                     f"(every member) or {(B, *shape)} (per member); found "
                                     f"shape {a.shape}")
        return Params(**out)

    def _groups(self, params: Params) -> list[tuple[Any, Params]]:
        """``(rows, parameters)`` for each group of members the family's hooks see: one group
        of every member with the whole ``params`` for an ungrouped observer (a bank), else
        :meth:`Params.groups`."""
        if not self.grouped:
            return [(slice(None), params)]
        return params.groups()

    def init(self, batch: int = 1, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None,
             params: Params | None = None) -> State:
        """A new state of ``batch`` members, from ``x_hat0`` (the layout of
        :attr:`state_names`) or ``z_hat0`` (``(n,)`` for every member or ``(B, n)``);
        neither: the constructor's initial estimate. ``u0`` (``(m,)`` or ``(B, m)``) is the
        input the maps ``to_normal`` and ``from_normal`` read at the start (default zero).

        Parameters
        ----------
        batch : int
            The number of members B.
        x_hat0 : array_like, optional
            Initial estimate in the layout of :attr:`state_names`, ``(n_x,)`` or ``(B, n_x)``.
        z_hat0 : array_like, optional
            Initial estimate in observer coordinates, ``(n,)`` or ``(B, n)``; not together
            with ``x_hat0``.
        u0 : array_like, optional
            Input at the start, ``(m,)`` or ``(B, m)``; default zero.
        params : Params, optional
            The members' parameters (default: :meth:`parameters` ``(batch)``); where a family's
            initial state depends on them (an initial gain), each member starts from its own.

        Returns
        -------
        State
            Named ``(B, ...)`` arrays: the family's fields, then ``dropouts``,
            ``inverse_failures`` and ``x_held`` (the last valid estimate, NaN before any).

        Raises
        ------
        DesignError
            Both ``x_hat0`` and ``z_hat0`` given, ``batch`` not a positive integer, a
            non-finite initial value, or ``params`` of another batch.
        DimensionError
            An initial value or ``u0`` of the wrong shape.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> s = obs.init(2, [0.1, 0.0])
        >>> obs.current(obs.parameters(2), s)[0].tolist()
        [[0.1, 0.0], [0.1, 0.0]]
        """
        B = _batch_size(batch)
        if x_hat0 is not None and z_hat0 is not None:
            raise DesignError("give x_hat0 or z_hat0, not both")
        x0 = None if x_hat0 is None else batch_rows("x_hat0", x_hat0, len(self.state_names), B)
        z0 = None if z_hat0 is None else batch_rows("z_hat0", z_hat0, self.n, B)
        m = self.n_inputs
        u = np.zeros((B, m or 0)) if u0 is None or m is None else batch_rows("u0", u0, m, B)
        params = self.parameters(B) if params is None else params
        if not isinstance(params, Params) or _batch_of(params) not in (None, B):
            raise DesignError(f"{self.name}: params must be this observer's Params of {B} "
                              f"member(s) (Observer.parameters); found {params!r}")
        return self._fresh(B, params, x0, z0, u)

    def _start_from(self, params: Params, x_hat0: Array) -> State:
        """A new state of every member of ``params`` from ``x_hat0`` ``(B, n_x)``, float64, at
        zero input: :meth:`init` without its checks, for the loop, whose caller built the rows
        (an environment's start from its first measurement) and whose ``params`` are checked
        (validate once). A family that extends :meth:`init` (an initial parameter estimate
        written after the base's), or rows that are not finite, take :meth:`init`, which
        refuses what it must."""
        B = x_hat0.shape[0]
        if (type(self).init is not Observer.init or x_hat0.shape[1:] != (len(self.state_names),)
                or not sum_is_finite(x_hat0)):
            return self.init(B, x_hat0, params=params)
        return self._fresh(B, params, x_hat0, None, np.zeros((B, self.n_inputs or 0)))

    def _fresh(self, B: int, params: Params, x0: Array | None, z0: Array | None,
               u: Array) -> State:
        """The state of :meth:`init` from checked rows (``x0``/``z0`` ``(B, ...)`` or None,
        ``u`` ``(B, m)``): the family's :meth:`_init`, group by group of equal parameters."""
        groups = self._groups(params)
        if len(groups) == 1:
            return State(**{**self._core(B), **self._init(groups[0][1], x0, z0, u)})
        state: State | None = None
        for rows, p in groups:
            part = State(**{**self._core(len(range(B)[rows]) if isinstance(rows, slice)
                                         else len(rows)),
                            **self._init(p, None if x0 is None else x0[rows],
                                         None if z0 is None else z0[rows], u[rows])})
            if state is None:  # the fields' shapes from the first group, B rows
                state = State(**{k: _empty_rows(v, B) for k, v in part.fields.items()})
            state.put(rows, part)
        assert state is not None
        return state

    def _core(self, B: int) -> dict[str, Array]:
        """The fields every state has, fresh for ``B`` members: ``dropouts``,
        ``inverse_failures`` and ``x_held`` (the last valid estimate, NaN before any). A
        family's :meth:`_init` may return its own ``x_held`` (an estimate mapped at the start)."""
        held = np.empty((B, len(self.state_names)))
        held.fill(np.nan)  # np.full's values, without its Python-level wrapper
        return {"dropouts": np.zeros(B, dtype=np.int64),
                "inverse_failures": np.zeros(B, dtype=np.int64), "x_held": held}

    def step(self, params: Params, state: State, Y: Any, U: Any,
             dt: float) -> tuple[State, Block]:
        """Consume T samples of B members, **purely**: ``Y`` ``(B, T, p)`` (every measured
        channel; the observer reads :attr:`outputs`), ``U`` ``(B, T, m)``; return the new
        state and the rows of the estimate after each sample. ``state`` is not changed.

        Parameters
        ----------
        params : Params
            The members' parameters (:meth:`parameters`).
        state : State
            The state before the samples (:meth:`init`, or a previous step's).
        Y : array_like
            Measurements ``(B, T, p)``, every measured channel; NaN is a dropout.
        U : array_like
            Inputs ``(B, T, m)``, finite.
        dt : float
            Sample period in seconds, positive.

        Returns
        -------
        state : State
            The state after the T samples (new arrays).
        block : Block
            ``x_hat`` ``(B, T, n_x)``, ``z_hat`` ``(B, T, n)`` and ``diagnostics``
            ``(B, T, len(diagnostic_names))`` after each sample.

        Raises
        ------
        DimensionError
            ``Y`` or ``U`` of the wrong shape for this batch, or not real numbers.
        DesignError
            ``dt`` not a positive finite number, a non-finite input, or ``params`` and
            ``state`` of different batches.
        DivergenceError
            An infinite measurement or one beyond :data:`MAX_MEASUREMENT`, or (from the
            family) a state that blows up.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> p = obs.parameters(3)
        >>> s0 = obs.init(3, params=p)
        >>> s1, rows = obs.step(p, s0, np.full((3, 4, 1), 0.2), np.zeros((3, 4, 1)), 0.01)
        >>> rows.x_hat.shape, rows.z_hat.shape, rows.diagnostics.shape
        ((3, 4, 2), (3, 4, 2), (3, 4, 2))
        >>> float(s0.z[0, 0]), round(float(s1.z[0, 0]), 4)   # s0 untouched
        (0.0, 0.1223)
        """
        Y, U = self._check_block(params, state, Y, U)
        new = state.copy()
        return new, self._step_checked(params, new, Y, U, _positive_dt(dt))

    def _check_block(self, params: Params, state: State, Y: Any, U: Any) -> tuple[Array, Array]:
        """``Y`` and ``U`` as float arrays of this batch's shapes (the checks of :meth:`step`)."""
        if not isinstance(state, State) or not isinstance(params, Params):
            raise DesignError(f"{self.name}: step takes (params, state, Y, U, dt) with Params "
                              f"and State (Observer.parameters, Observer.init); found "
                              f"{type(params).__name__}, {type(state).__name__}")
        B = state.batch
        if _batch_of(params) not in (None, B):
            raise DesignError(f"{self.name}: params of {_batch_of(params)} member(s) for a state "
                              f"of {B}")
        Y, U = self._floats("y", Y), self._inputs(U)
        if Y.ndim != 3 or Y.shape[0] != B or not self._width_ok(Y.shape[2]):
            raise DimensionError(f"{self.name}: y must have shape (B={B}, T, p) with "
                                 f"{self._width_words()}; found shape {Y.shape}")
        m = self.n_inputs
        if U.ndim != 3 or U.shape[:2] != (B, Y.shape[1]) or (m is not None and U.shape[2] != m):
            raise DimensionError(f"{self.name}: u must have shape ({B}, {Y.shape[1]}, "
                                 f"{'m' if m is None else m}); found shape {U.shape}")
        return Y, U

    def _step_checked(self, params: Params, s: State, Y: Array, U: Array, dt: float,
                      out: Block | None = None) -> Block:
        """Advance ``s`` **in place** over ``Y`` ``(B, T, p)``, ``U`` ``(B, T, m)`` (checked by
        the caller: the loop checks once per run) and return the rows; they are written into
        ``out`` where it is given with these B and T (a caller that keeps no rows reuses its
        block), else into a new :class:`Block`."""
        # a C-contiguous float64 copy of the observer's channels: a family may write into its
        # measurement block
        Yo = Y[..., self._cols_index]
        Yo = Yo.copy() if Yo.dtype is _F64 else np.array(Yo, dtype=np.float64, order="C")
        B, T = Yo.shape[0], Yo.shape[1]
        nd = len(self.family_diagnostics)
        nx = s.x_held.shape[1]
        if out is None or out.z_hat.shape[:2] != (B, T):
            out = _new_block(B, T, nx, self.n, nd + 1)
        X, Z, D = out.x_hat, out.z_hat, out.diagnostics
        if not U.flags.c_contiguous:
            U = np.ascontiguousarray(U)
        groups = params.groups() if self.grouped else [(slice(None), params)]  # (_groups)
        self._advance_block(groups, s, Yo, U, dt, X, Z, D)
        return out

    def _bind_step(self, params: Params, B: int, T: int,
                   dt: float) -> Callable[[State, Array, Array], Block]:
        """:meth:`_step_checked` of ``B`` members over blocks of ``T`` samples, bound once:
        ``step(s, Y, U)`` advances the state ``s`` in place over ``Y`` ``(B, T, p)`` and ``U``
        ``(B, T, m)`` (C-contiguous float64, the shapes of the binding: the caller's,
        unchecked) and returns the rows, written into the one :class:`Block` of the binding
        at every call. What :meth:`_step_checked` finds per call (the groups, the buffers,
        the observer's channels' index) is found here; the measurement rule, the family's
        :meth:`_step` and the dropout count run as they do there (:meth:`_advance_block`), bit
        for bit.

        Parameters
        ----------
        params : Params
            The members' parameters (checked: :meth:`check_period`).
        B, T : int
            Members and samples per block.
        dt : float
            Sample period, seconds (positive).

        Returns
        -------
        callable
            ``step(s, Y, U) -> Block``.
        """
        dt = _positive_dt(dt)
        cols = self._cols_index
        width = (cols.stop - cols.start) if isinstance(cols, slice) else len(cols)
        Yo = np.empty((B, T, width))
        out = _new_block(B, T, len(self.state_names), self.n, len(self.family_diagnostics) + 1)
        X, Z, D = out.x_hat, out.z_hat, out.diagnostics
        groups = self._groups(params)
        advance = self._advance_block

        def step(s: State, Y: Array, U: Array) -> Block:
            Yo[...] = Y[..., cols]
            advance(groups, s, Yo, U, dt, X, Z, D)
            return out

        return step

    def _advance_block(self, groups: list[tuple[Any, Params]], s: State, Yo: Array, U: Array,
                       dt: float, X: Array, Z: Array, D: Array) -> None:
        """The measurement rule on the observer's channels ``Yo`` (:meth:`_lost`), the family's
        :meth:`_step` group by group of equal parameters, the dropout count: the work of
        :meth:`_step_checked` and of a bound step (:meth:`_bind_step`) on their buffers."""
        nd = len(self.family_diagnostics)
        B = Yo.shape[0]
        lost = self._lost(Yo)
        if self._prepares:
            self._prepare(s, dt)
        if len(groups) == 1:
            self._step(groups[0][1], s, Yo, U, dt, X, Z, D[..., :nd])
        else:
            for rows, p in groups:
                if isinstance(rows, slice):  # consecutive members: views, written in place
                    sub = _view(s, rows)
                    self._step(p, sub, Yo[rows], U[rows], dt, X[rows], Z[rows], D[rows, :, :nd])
                    _put_back(s, rows, sub)
                    continue
                sub = s.take(rows)
                Xg, Zg, Dg = X[rows], Z[rows], D[rows, :, :nd]
                self._step(p, sub, np.ascontiguousarray(Yo[rows]), U[rows], dt, Xg, Zg, Dg)
                s.put(rows, sub)
                X[rows], Z[rows], D[rows, :, :nd] = Xg, Zg, Dg
        dropouts = s.dropouts
        if lost is None:  # (D[..., nd] and a Python number: the cheapest indexing for one row)
            D[..., nd] = dropouts.item(0) if B == 1 else dropouts[:, None]
        else:
            D[:, :, nd] = dropouts[:, None] + lost
            dropouts += lost[:, -1]

    def _lost(self, Yo: Array) -> NDArray[np.int64] | None:
        """The measurement rule (module docstring) on the observer's channels ``Yo``
        ``(B, T, c)``, one pass over the block: None where every value is a number within
        :data:`MAX_MEASUREMENT`; else the running count of dropped samples ``(B, T)`` (NaN);
        an infinite value or one beyond the bound raises :class:`DivergenceError`."""
        if Yo.size == 1:  # one sample of one channel: a Python comparison (False for NaN)
            if -MAX_MEASUREMENT <= Yo.item() <= MAX_MEASUREMENT:
                return None
        elif bool((np.abs(Yo) <= MAX_MEASUREMENT).all()):
            return None
        bad = np.abs(Yo) > MAX_MEASUREMENT  # (NaN compares False: a dropout)
        if bad.any():
            b, j, c = (int(v[0]) for v in np.nonzero(bad))
            beyond = "" if np.isinf(Yo[b, j, c]) else f", beyond +-{MAX_MEASUREMENT:g}"
            raise DivergenceError(f"{self.name}: measurement y[{self.outputs[c]}] is "
                                  f"{Yo[b, j, c]} (member {b}, sample {j}){beyond}")
        return np.cumsum(np.isnan(Yo).any(axis=2), axis=1)

    def _width_ok(self, width: int) -> bool:
        """Whether a measurement row of ``width`` channels holds the observer's channels and
        no more than the system's outputs."""
        return self._max_col < width and (self._max_width is None or width <= self._max_width)

    def _width_words(self) -> str:
        words = f"channel(s) {list(self.outputs)} (the measured outputs this observer reads)"
        if self._max_width is None:
            return words
        names = list(self.system.output_names)  # type: ignore[union-attr]
        return (f"{words} and p <= {self._max_width}, the outputs {names} of "
                f"{type(self.system).__name__}")

    def current(self, params: Params, state: State) -> tuple[Array, Array, Array]:
        """The estimate of ``state`` now: ``x_hat`` ``(B, n_x)``, ``z_hat`` ``(B, n)`` and the
        diagnostics ``(B, len(diagnostic_names))`` (new arrays).

        Parameters
        ----------
        params : Params
            The members' parameters.
        state : State
            The state to read.

        Returns
        -------
        tuple of ndarray
            ``(x_hat, z_hat, diagnostics)``.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> p = obs.parameters(1)
        >>> x, z, d = obs.current(p, obs.init(1, [0.3, 0.0], params=p))
        >>> x.tolist(), d.tolist()
        ([[0.3, 0.0]], [[10.0, 0.0]])
        """
        nd = len(self.family_diagnostics)
        dropouts = state.dropouts  # every state's (_core): its length is the batch
        B = dropouts.shape[0]
        groups = self._groups(params)
        if len(groups) == 1:
            x, z, d = self._current(groups[0][1], state)
        else:
            x, z, d = (np.empty((B, len(self.state_names))), np.empty((B, self.n)),
                       np.empty((B, nd)))
            for rows, p in groups:
                x[rows], z[rows], d[rows] = self._current(p, state.take(rows))
        D = np.empty((B, nd + 1))
        D[:, :nd] = d
        D[:, nd] = dropouts
        # the family's new arrays (_current) as they are where float64: no second copy
        return (x if x.dtype is _F64 else np.array(x, dtype=np.float64),
                z if z.dtype is _F64 else np.array(z, dtype=np.float64), D)

    def current_estimate(self, params: Params, state: State) -> Array:
        """The estimate ``x_hat`` ``(B, n_x)`` of ``state`` now, float64: :meth:`current`'s
        first array, the family's :meth:`_current` alone (an environment's observation reads
        no ``z_hat`` or diagnostics).

        Parameters
        ----------
        params : Params
            The members' parameters.
        state : State
            The state to read.

        Returns
        -------
        ndarray
            ``x_hat`` ``(B, n_x)``, a new array.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> p = obs.parameters(1)
        >>> obs.current_estimate(p, obs.init(1, [0.3, 0.0], params=p)).tolist()
        [[0.3, 0.0]]
        """
        groups = self._groups(params)
        if len(groups) > 1:
            return self.current(params, state)[0]
        x = self._current(groups[0][1], state)[0]
        return x if x.dtype is _F64 else np.array(x, dtype=np.float64)

    # ------------------------------------------- the observer's own state (convenience)
    @property
    def batch(self) -> int:
        """The number of members of the observer's own state (:meth:`reset`)."""
        return 1 if self._held is None else self._held[1].batch

    @property
    def state(self) -> State:
        """The observer's own state (:meth:`reset`, :meth:`update`)."""
        return self._own()[1]

    def _hold(self, params: Params, state: State, batched: bool | None = None) -> None:
        """Make ``(params, state)`` the observer's own (the loop hands its states over, so
        that :attr:`x_hat` reads a run's last estimate); ``batched`` sets the public shapes."""
        self._held = (params, state)
        if batched is not None:
            self._batched = batched

    def _own(self) -> tuple[Params, State]:
        if self._held is None:
            self.reset()
        return self._held  # type: ignore[return-value]

    def reset(self, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None,
              batch: int | None = None, params: Params | None = None) -> None:
        """Restart the observer's own state: ``batch`` members (default: the batch of the
        initial estimate or of ``params``, else one unbatched member) from ``x_hat0`` or
        ``z_hat0``; neither: the constructor's initial estimate (see :meth:`init`).

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
        params : Params, optional
            Per-member parameters (:meth:`parameters`); given, the observer is batched.

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
        given = x_hat0 if x_hat0 is not None else z_hat0
        if batch is not None:
            B = _batch_size(batch)
        elif params is not None and _batch_of(params) is not None:
            B = _batch_of(params)  # type: ignore[assignment]
        elif given is not None and np.ndim(given) == 2:
            B = int(np.shape(given)[0])
        else:
            B = 1
        batched = batch is not None or params is not None or (given is not None
                                                               and np.ndim(given) == 2)
        p = self.parameters(B) if params is None else params
        s = self.init(B, x_hat0, z_hat0=z_hat0, u0=u0, params=p)
        self._held, self._batched = (p, s), batched

    def reset_members(self, idx: Sequence[int]) -> None:
        """Restart the members ``idx`` of the observer's own batched state from the
        constructor's initial estimate, as :meth:`reset` starts every member (zero input); the
        others go on untouched. A row assignment (:meth:`State.put`) of a fresh
        :meth:`init` of those members with their own parameters.

        Parameters
        ----------
        idx : sequence of int
            The members to restart, each in ``0 .. batch - 1``.

        Raises
        ------
        DesignError
            An unbatched observer, or a member index outside the batch.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> obs.reset(batch=3)
        >>> obs.update(np.full((3, 1), 0.2), np.zeros((3, 1)), 0.01).round(3)
        array([[0.038, 0.181],
               [0.038, 0.181],
               [0.038, 0.181]])
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
        params, state = self._own()
        self._restart(params, state, rows)

    def _restart(self, params: Params, state: State, rows: list[int],
                 x_hat0: Array | None = None) -> None:
        """Write a fresh :meth:`init` of the members ``rows`` (with their own parameters; from
        ``x_hat0`` ``(len(rows), n_x)`` where given, else the constructor's initial estimate)
        into ``state``: the loop's and :meth:`reset_members`' restart."""
        B = state.batch
        bad = [b for b in rows if not 0 <= b < B]
        if bad:
            raise DesignError(f"{self.name}: member(s) {bad} outside the batch of {B}")
        if not rows:
            return
        where: Any = rows
        if rows == list(range(B)):  # every member: the parameters as they are (their
            sub, where = params, slice(None)  # groups found once), the rows as a slice
        else:
            sub = params.take(rows) if params.fields else self.parameters(len(rows))
        if x_hat0 is not None and x_hat0.ndim == 2 and x_hat0.shape[0] == len(rows):
            # the loop's parameters are checked: the rows' checks only (else init refuses)
            state.put(where, self._start_from(sub, x_hat0))  # type: ignore[arg-type]
        else:
            state.put(where, self.init(len(rows), x_hat0, params=sub))  # type: ignore[arg-type]

    def update(self, y: Any, u: Any, dt: float) -> Array:
        """One sample of the observer's own state: ``y`` ``(p,)`` and ``u`` ``(m,)`` when
        unbatched, ``(B, p)`` and ``(B, m)`` when batched; returns ``x_hat`` after it.

        Parameters
        ----------
        y : array_like
            Measurement (every measured channel; the observer reads :attr:`outputs`); NaN is
            a dropout.
        u : array_like
            Input.
        dt : float
            Sample period in seconds.

        Returns
        -------
        ndarray
            ``x_hat`` after the sample, ``(n_x,)`` or ``(B, n_x)``.

        Raises
        ------
        DimensionError
            ``y`` without the observer's channels or wider than the system's outputs, or ``u``
            of the wrong width.
        DesignError
            ``dt`` not a positive finite number.
        DivergenceError
            A measurement that is infinite or beyond :data:`MAX_MEASUREMENT` (NaN is a
            dropout), or (from the family) a state that blows up.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> obs.update([0.2], [0.0], 0.01).round(3)
        array([0.038, 0.181])
        """
        params, state = self._held if self._held is not None else self._own()
        ya, ua = self._floats("y", y), self._inputs(u)
        B = state.batch if self._batched else 1
        if self._batched:
            ya, ua = ya[:, None] if ya.ndim == 2 else ya, ua[:, None] if ua.ndim == 2 else ua
        else:
            ya, ua = ya.reshape(1, 1, -1) if ya.ndim == 1 else ya, (
                ua.reshape(1, 1, -1) if ua.ndim == 1 else ua)
        if ya.ndim != 3 or ya.shape[:2] != (B, 1) or not self._width_ok(ya.shape[2]):
            want = f"({B}, p)" if self._batched else "(p,)"
            raise DimensionError(f"{self.name}: y must be {want} with {self._width_words()}; "
                                 f"found {y!r}")
        m = self.n_inputs
        if ua.ndim != 3 or ua.shape[:2] != (B, 1) or (m is not None and ua.shape[2] != m):
            want = f"({B}, {'m' if m is None else m})" if self._batched else \
                f"({'m' if m is None else m},)"
            raise DimensionError(f"{self.name}: u must have shape {want}; found shape "
                                 f"{np.shape(u)}")
        if not (type(dt) is float and dt > 0 and dt < math.inf):
            dt = _positive_dt(dt)
        rows = self._rows = self._step_checked(params, state, ya, ua, dt, self._rows)
        return self._public(rows.x_hat[:, 0].copy())  # type: ignore[no-any-return]

    def filtered(self, y: Any) -> Array:
        """The estimate at the present instant given also ``y``, measured at this instant,
        without consuming it: the observer's state is unchanged and the next :meth:`update`
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
            ``y`` of the wrong shape (without the observer's channels, or wider than the
            system's outputs) or not real numbers.
        DivergenceError
            A measurement that is infinite or beyond :data:`MAX_MEASUREMENT`.

        Examples
        --------
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.systems import SYSTEMS
        >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
        >>> obs.reset([0.1, 0.0])
        >>> obs.filtered([0.3]).tolist() == obs.x_hat.tolist()  # continuous-time: the same
        True
        """
        params, state = self._own()
        Y = self._floats("y", y)
        if Y.ndim == 1 and not self._batched:
            Y = Y.reshape(1, -1)
        if Y.ndim != 2 or Y.shape[0] != state.batch or not self._width_ok(Y.shape[1]):
            want = f"({state.batch}, p)" if self._batched else "(p,)"
            raise DimensionError(f"{self.name}: y must have shape {want} with "
                                 f"{self._width_words()}; found shape {Y.shape}")
        self._lost(Y[:, None, self._cols_index])  # the measurement rule of a step
        return self._public(self._filtered_of(params, state, Y))  # type: ignore[no-any-return]

    def _filtered_of(self, params: Params, state: State, Y: Array) -> Array:
        """:meth:`_filtered` over the groups of ``params`` (new ``(B, n_x)`` array)."""
        groups = self._groups(params)
        if len(groups) == 1:
            return np.array(self._filtered(groups[0][1], state, Y), dtype=np.float64)
        out = np.empty((state.batch, len(self.state_names)))
        for rows, p in groups:
            out[rows] = self._filtered(p, state.take(rows), Y[rows])
        return out

    def run(self, ys: Any, us: Any, dt: float, *, x_hat0: Any = None) -> Block:
        """Offline driver over recorded data (filterpy's ``batch_filter``): restart the
        observer's own state (unbatched, or batched when ``ys`` is ``(B, T, p)``), then
        consume ``ys`` ``(T, p)`` with ``us`` ``(T, m)``. The returned rows are the estimate
        *after* each sample.

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

        Raises
        ------
        DimensionError
            ``ys`` or ``us`` of the wrong shape.

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
            ya, ua = ya[None], ua[None]
            self.reset(x_hat0)
        else:
            self.reset(x_hat0, batch=ya.shape[0] if ya.ndim == 3 else None)
        params, state = self._own()
        Y, U = self._check_block(params, state, ya, ua)
        return self._step_checked(params, state, Y, U, _positive_dt(dt))

    def _public(self, a: NDArray[Any]) -> Any:
        """Drop the batch axis of an unbatched observer (``a[0]``; a float for a scalar)."""
        if self._batched:
            return a
        v = a[0]
        return v.item() if v.ndim == 0 else v

    @property
    def z_hat(self) -> Array:
        """The current estimate in observer coordinates, ``(n,)`` or ``(B, n)``."""
        return self._public(self.current(*self._own())[1])  # type: ignore[no-any-return]

    @property
    def x_hat(self) -> Array:
        """The current estimate in the layout of :attr:`state_names`, ``(n_x,)`` or ``(B, n_x)``."""
        return self._public(self.current(*self._own())[0])  # type: ignore[no-any-return]

    @property
    def dropouts_(self) -> Any:
        return self._public(self._own()[1].dropouts.copy())

    @property
    def inverse_failures_(self) -> Any:
        return self._public(self._own()[1].inverse_failures.copy())

    def diagnostics(self) -> dict[str, Any]:
        """The current run-time quantities of the observer's own state, named in
        :attr:`diagnostic_names` (floats, or ``(B,)`` arrays for a batched observer).

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
        d = self.current(*self._own())[2]
        return {name: self._public(d[:, j]) for j, name in enumerate(self.diagnostic_names)}

    # --------------------------------------------------------------- helpers
    def _floats(self, what: str, value: Any) -> Array:
        """``value`` as a float array: real numbers only (a bool or a string is refused, not
        converted); NaN is allowed (a measurement's dropout)."""
        a = value if type(value) is np.ndarray else np.asarray(value)
        if a.dtype is _F64:
            return a  # type: ignore[no-any-return]
        if a.dtype.kind not in "iuf":
            raise DimensionError(f"{self.name}: {what} must be an array of real numbers; found "
                                 f"{value!r}")
        return a.astype(np.float64, copy=False)

    def _inputs(self, value: Any, what: str = "u") -> Array:
        """The input as a float array: real numbers, finite (an input is never a dropout)."""
        a = self._floats(what, value)
        size = a.size
        if size == 0:  # no inputs (a model-free observer): nothing to check
            return a
        if not (math.isfinite(a.item()) if size == 1 else np.isfinite(a).all()):
            at = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
            raise DesignError(f"{self.name}: {what} must be finite; found {what}{list(at)} = "
                              f"{a[at]}")
        return a

    def _initial_z(self, x0: Array | None, z0: Array | None, u0: Array) -> Array:
        """``(B, n)`` observer coordinates from a physical ``x0`` (through ``to_normal``) or
        ``z0``; zero if neither is given (``B = len(u0)``)."""
        if z0 is not None:
            return z0
        if x0 is None:
            return np.zeros((u0.shape[0], self.n))
        if self.system is None:
            return x0
        # the rows are checked (init's batch_rows): the map without its checks
        return self.system.to_normal_rows(x0, u0)

    def _to_physical(self, s: State, Z: Array, U: Array, X: Array) -> None:
        """Write ``system.from_normal`` of the rows ``Z`` ``(B, T, n)`` (inputs ``U``) into ``X``.
        Where the inverse is undefined (the system raises :class:`DesignError`) count it in
        the state's ``inverse_failures`` and hold the member's last valid value (``x_held``,
        NaN before any). Other errors (a math domain error on a blown-up ``z``) propagate as
        a divergence. Systems offering a vectorized ``from_normal_batch(Z, U)`` (rows
        ``(N, n)``) are used whole."""
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
                    s.x_held[...] = flat[:, -1]
                return
        for b in range(B):
            held = s.x_held[b]
            for j in range(T):
                try:
                    x = sys.from_normal_unchecked(Z[b, j], U[b, j])
                except DesignError:
                    s.inverse_failures[b] += 1
                    X[b, j] = held
                    continue
                held = np.asarray(x, dtype=float)
                self._check_width(held.size, X.shape[2])
                X[b, j] = held
            s.x_held[b] = held

    def _check_width(self, width: int, named: int) -> None:
        if width != named:
            raise DimensionError(f"{type(self).__name__}: state_names must name the {width} "
                                 f"entries of x_hat; found {named} {list(self.state_names)}")

    def __repr__(self) -> str:
        return f"{type(self).__name__}(outputs={list(self.outputs)}, batch={self.batch})"


def _batch_size(batch: Any) -> int:
    if isinstance(batch, (bool, np.bool_)) or not isinstance(batch, (int, np.integer)) or batch < 1:
        raise DesignError(f"batch must be a positive integer; found {batch!r}")
    return int(batch)


def _view(s: State, rows: slice) -> State:
    """The members ``rows`` of ``s`` as views (a field that is a nested state: its views)."""
    def one(v: Any) -> Any:
        if isinstance(v, State):
            return _view(v, rows)
        if isinstance(v, tuple):
            return tuple(one(x) for x in v)
        return v[rows]
    return State(**{k: one(v) for k, v in s.fields.items()})


def _put_back(s: State, rows: slice, sub: State) -> None:
    """Write the fields of ``sub`` that a family assigned anew (no longer views of ``s``)
    into the members ``rows`` of ``s``."""
    for k, v in s.fields.items():
        w = sub.fields[k]
        if isinstance(v, State):
            _put_back(v, rows, w)
        elif isinstance(v, tuple):
            for a, b in zip(v, w):
                _put_back(a, rows, b)
        elif not (isinstance(w, np.ndarray) and w.base is v):
            v[rows] = w


def _batch_of(params: Params) -> int | None:
    """The batch of ``params``, or None where it has no array to tell (no parameters)."""
    try:
        return params.batch
    except DesignError:
        return None


def _empty_rows(value: Any, B: int) -> Any:
    """An uninitialised field of ``B`` rows shaped like ``value``'s rows (arrays, nested)."""
    if isinstance(value, State):
        return State(**{k: _empty_rows(v, B) for k, v in value.fields.items()})
    if isinstance(value, tuple):
        return tuple(_empty_rows(v, B) for v in value)
    return np.empty((B, *value.shape[1:]), dtype=value.dtype)


ObserverT = TypeVar("ObserverT", bound=type[Observer])

__all__ = ["FAMILIES", "MAX_MEASUREMENT", "ON_UNSTABLE", "OBSERVERS", "Block", "Dimension",
           "Observer", "Params", "State", "register", "registered"]

#: the package's families: registry name -> ``"module:Class"`` (each module registers its
#: classes with :func:`register` when it is imported: on first lookup in :data:`OBSERVERS`)
FAMILIES = {
    "high_gain": "hgo_mj.observers.high_gain:HighGainObserver",
    "high_gain_multi": "hgo_mj.observers.high_gain:MultiOutputHighGainObserver",
    "riccati": "hgo_mj.observers.riccati:RiccatiObserver",
    "adaptive_gain": "hgo_mj.observers.adaptive_gain:AdaptiveGainObserver",
    "bastin_gevers": "hgo_mj.observers.bastin_gevers:BastinGeversObserver",
    "besancon": "hgo_mj.observers.besancon:BesanconObserver",
    "finite_difference": "hgo_mj.observers.finite_difference:FiniteDifferenceObserver",
    "extended_luenberger": "hgo_mj.observers.extended_luenberger:ExtendedLuenbergerObserver",
    "jo_son": "hgo_mj.observers.jo_son:JoSonObserver",
    "kinematic_kalman": "hgo_mj.observers.kinematic_kalman:KinematicKalmanFilter",
    "ekf": "hgo_mj.observers.kalman:ExtendedKalmanFilter",
    "ukf": "hgo_mj.observers.kalman:UnscentedKalmanFilter",
    "ekf_mujoco": "hgo_mj.observers.kalman:MujocoExtendedKalmanFilter",
    "ukf_mujoco": "hgo_mj.observers.kalman:MujocoUnscentedKalmanFilter",
    "mhe": "hgo_mj.observers.mhe:MovingHorizonEstimator",
    "q_integral": "hgo_mj.observers.q_integral:QIntegralObserver",
    "super_twisting": "hgo_mj.observers.super_twisting:SuperTwistingObserver",
}

#: registry name -> observer class: the package's :data:`FAMILIES`, each imported on first
#: lookup, then the classes of other packages (the entry points :func:`registered` loads,
#: before a name outside the families is looked up) and those given to :func:`register`
OBSERVERS: LazyRegistry[type[Observer]] = LazyRegistry("observer", FAMILIES,
                                                       discover=lambda: registered())


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
    home = FAMILIES.get(cls.name)
    there = OBSERVERS.loaded(cls.name)
    if (home is not None and home != f"{cls.__module__}:{cls.__qualname__}") or (
            there is not None and there is not cls):
        held = home or f"{there.__module__}:{there.__qualname__}"  # type: ignore[union-attr]
        raise DesignError(f"an observer named {cls.name!r} is registered already ({held})")
    OBSERVERS[cls.name] = cls
    return cls


_ENTRY_POINTS_LOADED = False


def registered() -> LazyRegistry[type[Observer]]:
    """:data:`OBSERVERS`, after loading the entry-point group ``hgo_mj.observers`` once (each
    entry point names an :class:`Observer` subclass; one that fails to import is an error
    naming it).

    Returns
    -------
    LazyRegistry
        Registry name -> Observer subclass (the same object as :data:`OBSERVERS`; a family's
        module is imported on first lookup).

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
