"""The environment loop: plant, sensor chain and observer under a task (reward, end, start).

:class:`HgoEnv` is the only environment class with behaviour; an environment such as
``PendulumSwingUpEnv`` is a :class:`Task` (reward, termination, reset distribution and
defaults) plus a docstring. One ``step(action)`` holds the input ``u = action * max_action``
over the control period, which holds ``control_period / sample_period`` samples; at each sample
the observer consumes the measurement ``y(t_k)`` and the input (``update(y, u, Ts)``, which
returns its estimate of ``x(t_k + Ts)``), the plant advances ``sample_period / physics_dt``
MuJoCo steps, and the sensor chain measures ``y(t_k + Ts)``. The agent then sees, by
``observation``:

* ``"estimate"``: the observer's estimate of the current state (made from the measurements up
  to the previous sample, as a real-time observer would have it);
* ``"measurement"``: the current measurement, the raw sensor values (a dropout, NaN, is held
  at the last valid value in the observation; with ``info_level="full"``,
  ``info["measurement"]`` keeps the NaN);
* ``"true"``: the true state of the plant;
* ``"estimate+diagnostics"``: the estimate, the goal (below), then the observer's run-time
  quantities (gain, parameter estimates: ``observer.diagnostics()`` less the dropout counter,
  in its order, named ``diagnostic:<key>`` in ``observation_names``; one not defined yet,
  NaN, enters as 0).

Reward and termination always use the *true* state. Every mode appends the task's goal (the
target angles of the reach tasks) after the estimate, measurement or state. Angles the task
declares periodic enter as ``(cos, sin)``; every other entry is clipped to a finite bound of
the task (``info`` holds the unclipped values).

The same measurement stream feeds the observer and the ``"measurement"`` observation, so that
with the same seed every mode sees the same sensor noise.

At ``reset`` the observer starts from the first measurement (:func:`measurement_start`): the
measured coordinates at the measured values, the others (velocities, higher derivatives,
unmeasured positions) at zero, so that an episode that starts away from zero (a balance task,
upright) has no start-up transient of the estimate (a zero start gave a 34-43 rad/s velocity
spike for about 0.2 s on the lab plants' balance tasks).
"""

from __future__ import annotations

import copy
import dataclasses
import inspect
import math
import pickle
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, cast

import gymnasium
import mujoco
import numpy as np
from gymnasium import spaces
from gymnasium.envs.registration import EnvSpec
from gymnasium.error import ResetNeeded
from gymnasium.utils import EzPickle
from numpy.typing import NDArray

from hgo_mj._validate import finite_scalar, integer_multiple, numbers_only, sum_is_finite, vector
from hgo_mj.exceptions import DesignError, DimensionError, DivergenceError
from hgo_mj.loop import CONTINUE, Loop, LoopFailure, Periods
from hgo_mj.observers import OBSERVERS, Observer, make_observer
from hgo_mj.observers.bank import ObserverBank
from hgo_mj.plants import MujocoPlant, make_plant, model_path
from hgo_mj.sensors import SensorChain

Array = NDArray[np.float64]

#: what the agent can be shown
OBSERVATION_MODES = ("estimate", "measurement", "true", "estimate+diagnostics")
#: what ``step`` does with an action outside ``[-1, 1]``
INVALID_ACTION_MODES = ("clip", "raise")
_INTEGRATORS = {"Euler": mujoco.mjtIntegrator.mjINT_EULER, "RK4": mujoco.mjtIntegrator.mjINT_RK4,
                "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
                "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST}
#: what ``info`` carries: ``"basic"`` the true state, the estimate and the estimation error
#: (``"state"``, ``"estimate"``, ``"error"``); ``"full"`` adds ``"time"``, ``"measurement"``,
#: ``"diagnostics"``, ``"goal"`` (reach tasks) and, at a step, the task's ``"reward_<term>"``
INFO_LEVELS = ("basic", "full")


def chain_seed(seed: int) -> int:
    """The sensor chain's seed derived from an environment's ``reset(seed=...)``: a stream
    independent of the environment's own ``np_random`` (which the same integer also seeds).

    Parameters
    ----------
    seed : int
        The seed given to ``reset(seed=...)``.

    Returns
    -------
    int
        A non-negative 63-bit seed for :meth:`hgo_mj.sensors.SensorChain.reset`; the same
        ``seed`` always gives the same value.

    Examples
    --------
    >>> from hgo_mj.envs.core import chain_seed
    >>> chain_seed(0)
    4246322151728509
    >>> chain_seed(0) == chain_seed(0) != chain_seed(1)
    True
    """
    ss = np.random.SeedSequence([int(seed), 0x5E4503])
    return int(ss.generate_state(1, np.uint64)[0] >> np.uint64(1))


def env_seed(seed: int | None) -> Any:
    """What an environment's ``reset(seed=...)`` gives its sensor chain: a stream seeded from
    :func:`chain_seed` on a seeded reset; otherwise :data:`~hgo_mj.loop.CONTINUE` (the stages
    restart, the generators continue: Gymnasium's convention for ``reset()`` without a seed).

    Parameters
    ----------
    seed : int or None
        The seed given to ``reset(seed=...)``.

    Returns
    -------
    int or CONTINUE
        ``chain_seed(seed)``, or :data:`~hgo_mj.loop.CONTINUE` for ``seed=None``: what
        :meth:`hgo_mj.loop.Loop.reset` takes as ``seed``.

    Examples
    --------
    >>> from hgo_mj.envs.core import env_seed
    >>> from hgo_mj.loop import CONTINUE
    >>> env_seed(None) is CONTINUE
    True
    >>> env_seed(0)
    4246322151728509
    """
    return CONTINUE if seed is None else chain_seed(seed)


def reset_chain(chain: SensorChain, seed: int | None) -> None:
    """Reset a sensor chain as an environment's ``reset(seed=...)`` does (:func:`env_seed`)."""
    if seed is None:
        chain.restart()
    else:
        chain.reset(chain_seed(seed))


def sensor_chain(spec: Any, seed: int | None = None) -> SensorChain:
    """Build a :class:`~hgo_mj.sensors.SensorChain` from what an environment accepts: a chain
    as is, anything else read by :meth:`~hgo_mj.sensors.SensorChain.from_spec` (the one reader
    of a sensor spec).

    Parameters
    ----------
    spec : SensorChain, Stage, mapping, str, sequence of those, or None
        A chain (used as is); one stage, given as an instance, a mapping
        ``{"stage": name, **params}`` or a bare name (a stage without required parameters);
        a sequence of such stages, applied in order; ``None`` or ``[]`` for exact
        measurements.
    seed : int, optional
        Seed of a new chain (ignored when ``spec`` is a chain, which is returned as is).

    Returns
    -------
    SensorChain
        The chain, its stages in the order given.

    Raises
    ------
    DesignError
        Unknown stage names (the message lists the valid ones), unknown or missing parameters,
        a mapping without a ``"stage"`` key, or an entry of another type.

    Examples
    --------
    >>> from hgo_mj.envs import sensor_chain
    >>> sensor_chain([{"stage": "gaussian", "std": 0.01}], seed=0)
    SensorChain([GaussianNoise(std=0.01)], seed=0)
    >>> sensor_chain(None).describe()
    []
    """
    return spec if isinstance(spec, SensorChain) else SensorChain.from_spec(spec, seed=seed)


def measurement_start(observer: Observer, Y: Any,
                      ties: Sequence[tuple[str, str]] = ()) -> Array:
    """An observer's initial estimate made from the first measurement: every estimated
    coordinate that a channel the observer reads measures is that channel's value (a dropout,
    NaN, gives 0); an unmeasured coordinate named first in a pair of ``ties`` takes the value
    of the coordinate named second (a task's nominal start, :attr:`Task.start_ties`: the
    elastic joint's motor at its link's angle); every other coordinate is 0 (the velocities
    and derivatives of a start at rest). What an environment's ``reset`` starts its observer
    from (:meth:`Observer.init`'s ``x_hat0``), so that the estimate begins at the measured pose
    rather than at zero.

    A coordinate is measured when its name is the name of a channel the observer reads
    (``system.output_names[c]`` for ``c`` in ``observer.outputs``); an observer without a
    system that reads one channel estimates that channel and its derivatives, and its first
    coordinate is measured; a bank's members are matched one by one.

    Parameters
    ----------
    observer : Observer
        The observer (or :class:`~hgo_mj.observers.ObserverBank`) to start.
    Y : array_like, shape (p,) or (B, p)
        The first measurement: every channel, as the observer reads it (``y[outputs]``).
    ties : sequence of (str, str)
        ``(coordinate, source)`` names of the estimate: an unmeasured ``coordinate`` starts at
        ``source``'s start (pairs naming a coordinate the estimate lacks are skipped).

    Returns
    -------
    ndarray, shape (B, len(observer.state_names))
        The initial estimate of each of the B members (one row for a ``(p,)`` measurement).

    Examples
    --------
    >>> from hgo_mj.envs.core import measurement_start
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.systems import SYSTEMS
    >>> ob = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
    >>> ob.state_names, measurement_start(ob, [3.1]).tolist()
    (('angle', 'angular_velocity'), [[3.1, 0.0]])
    >>> measurement_start(HighGainObserver(order=3, k=10.0), [[0.5], [float("nan")]]).tolist()
    [[0.5, 0.0, 0.0], [0.0, 0.0, 0.0]]
    >>> ej = HighGainObserver(SYSTEMS["elastic_joint"](), k=80.0, model=True)
    >>> measurement_start(ej, [0.2], ties=[("motor_angle", "link_angle")]).tolist()
    [[0.2, 0.2, 0.0, 0.0]]
    """
    return _start_map(observer, ties)(Y)


class _StartMap:
    """:func:`measurement_start` of one observer and ties, its indices found once (an
    environment builds it with its observer and calls it at every reset)."""

    def __init__(self, n: int, measured: list[tuple[int, int]],
                 tied: list[tuple[int, int]]) -> None:
        self.n, self.measured, self.tied = n, measured, tied

    def __call__(self, Y: Any) -> Array:
        Ya = np.asarray(Y, dtype=np.float64)
        Ya = Ya.reshape(1, -1) if Ya.ndim == 1 else Ya
        out = np.zeros((Ya.shape[0], self.n))
        for col, ch in self.measured:
            out[:, col] = Ya[:, ch]
        if not sum_is_finite(out):  # a dropout gives 0 (the rare case: checked once;
            np.nan_to_num(out, copy=False, nan=0.0)  # a sum that overflows changes nothing)
        for col, source in self.tied:
            out[:, col] = out[:, source]
        return out


def _start_map(observer: Observer, ties: Sequence[tuple[str, str]]) -> _StartMap:
    """The :class:`_StartMap` of ``observer`` and ``ties`` (see :func:`measurement_start`)."""
    measured = _measured_coordinates(observer)
    names, done = list(observer.state_names), {col for col, _ in measured}
    tied = [(names.index(name), names.index(source)) for name, source in ties
            if name in names and source in names and names.index(name) not in done]
    return _StartMap(len(names), measured, tied)


def _measured_coordinates(observer: Observer, offset: int = 0) -> list[tuple[int, int]]:
    """``(estimate index, channel)`` of each estimated coordinate a channel measures (see
    :func:`measurement_start`)."""
    if isinstance(observer, ObserverBank):  # the members' estimates, concatenated
        pairs: list[tuple[int, int]] = []
        for member in observer.members:
            pairs += _measured_coordinates(member, offset)
            offset += len(member.state_names)
        return pairs
    system = observer.system
    if system is None:  # an order-only observer: its first coordinate is the channel
        return [(offset, observer.outputs[0])] if len(observer.outputs) == 1 else []
    names = list(observer.state_names)
    return [(offset + names.index(system.output_names[c]), c) for c in observer.outputs
            if system.output_names[c] in names]


def _system_key(system: Any) -> Any:
    """What makes two systems the same plant: the class, or for a system read from an MJCF
    (a class built per call by :func:`hgo_mj.systems.mjcf.mjcf_system`) the file and the
    names of its state, outputs and inputs."""
    cls = type(system)
    if getattr(cls, "model_file", None) is None or not hasattr(cls, "normal_form_problem"):
        return cls
    return (cls.__name__, cls.model_file, cls.state_names, cls.output_names, cls.input_names)


def _column(v: Any, B: int, dtype: Any) -> Any:
    """``v`` as a fresh ``(B,)`` array of ``dtype`` (a float broadcast; an array that is a view,
    e.g. a column of the states, copied so that the caller may write into it)."""
    if type(v) is np.ndarray and v.base is None and v.shape == (B,) and v.dtype == dtype:
        return v
    return np.full(B, v, dtype=dtype)


class Task:
    """Reward, termination and reset distribution of an environment, and its defaults.

    Subclasses set the class attributes and implement :meth:`initial_state` and
    :meth:`reward` (and, where they apply, :meth:`sample_goal` and :meth:`terminated`). A
    task never sees the estimate: reward and termination use the true state.

    Attributes
    ----------
    plant : str
        Registry name of the plant (``hgo_mj.systems.SYSTEMS``), or an MJCF file under
        ``models/`` (``"furuta.xml"``) read by the generic MJCF path with the task's
        ``plant_outputs`` as outputs.
    max_action : tuple of float
        Input per unit action, one per plant input (``u = action * max_action``).

    Parameters
    ----------
    max_action : sequence of float
        Input per unit action, one positive finite value per plant input.

    Examples
    --------
    A task of the pendulum: reward and reset distribution use only the true state.

    >>> import numpy as np
    >>> from hgo_mj.envs.tasks import SwingUpTask
    >>> task = SwingUpTask()
    >>> task.max_action, task.params()
    ((0.5,), {'max_torque': 0.5, 'start_noise': 0.1})
    >>> x0 = task.initial_state(np.random.default_rng(0))
    >>> [round(v, 3) for v in x0]
    [0.027, -0.046]
    """

    plant: ClassVar[str] = ""
    physics_dt: ClassVar[float] = 0.001
    control_period: ClassVar[float] = 0.01
    #: default sample period (``None``: the control period)
    sample_period: ClassVar[float | None] = None
    #: MuJoCo integrator to use instead of the MJCF's (``None``: keep the MJCF's)
    integrator: ClassVar[str | None] = None
    max_episode_steps: ClassVar[int] = 1000
    #: return from which an episode counts as solved (the registered spec's
    #: ``reward_threshold``, as Gymnasium's ``CartPole-v1`` has 475); each task documents its own
    reward_threshold: ClassVar[float] = 0.0
    #: observer used when none is given, and per-kind parameters used unless overridden
    default_observer: ClassVar[str] = "high_gain"
    observer_defaults: ClassVar[Mapping[str, Mapping[str, Any]]] = {}
    default_sensor: ClassVar[tuple[Mapping[str, Any], ...]] = ()
    #: state and output names that enter the observation as (cos, sin)
    periodic: ClassVar[frozenset[str]] = frozenset()
    #: observation bound by name suffix (first match); other names get ``default_bound``
    bounds: ClassVar[tuple[tuple[str, float], ...]] = (
        ("angle", 2 * math.pi), ("velocity", 50.0), ("acceleration", 1e3), ("jerk", 1e5))
    default_bound: ClassVar[float] = 1e6
    goal_names: ClassVar[tuple[str, ...]] = ()
    goal_bound: ClassVar[float] = math.pi
    #: the nominal start of unmeasured estimated coordinates: ``(name, source)``, the
    #: coordinate ``name`` starts at ``source``'s first measurement (:func:`measurement_start`);
    #: every other unmeasured one starts at 0
    start_ties: ClassVar[tuple[tuple[str, str], ...]] = ()

    def __init__(self, max_action: Sequence[float]) -> None:
        self.max_action = tuple(finite_scalar(f"max_action[{i}]", v, positive=True)
                                for i, v in enumerate(max_action))

    def bound(self, name: str) -> float:
        """Observation bound of an entry named ``name``.

        Parameters
        ----------
        name : str
            A state, output or diagnostic name.

        Returns
        -------
        float
            The bound of the first suffix of :attr:`bounds` that ``name`` ends with, else
            :attr:`default_bound`; the entry is clipped to ``[-bound, bound]``.

        Examples
        --------
        >>> from hgo_mj.envs.tasks import SwingUpTask
        >>> task = SwingUpTask()
        >>> task.bound("angular_velocity"), task.bound("gain")
        (50.0, 1000000.0)
        """
        for suffix, b in self.bounds:
            if name.endswith(suffix):
                return b
        return self.default_bound

    def initial_state(self, rng: np.random.Generator) -> list[float]:
        """Draw the true initial state.

        Parameters
        ----------
        rng : numpy.random.Generator
            The environment's ``np_random`` (seeded by ``reset(seed=...)``).

        Returns
        -------
        list of float
            The true state, one entry per plant state.

        Raises
        ------
        NotImplementedError
            Always, here: a subclass implements it.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.envs.tasks import SwingUpTask
        >>> len(SwingUpTask().initial_state(np.random.default_rng(0)))
        2
        """
        raise NotImplementedError

    def sample_goal(self, rng: np.random.Generator) -> tuple[float, ...]:
        """Draw the goal shown to the agent (default: none).

        Parameters
        ----------
        rng : numpy.random.Generator
            The environment's ``np_random``, drawn after :meth:`initial_state`.

        Returns
        -------
        tuple of float
            One entry per name of :attr:`goal_names` (empty here).

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.envs.tasks import SwingUpTask
        >>> SwingUpTask().sample_goal(np.random.default_rng(0))
        ()
        """
        return ()

    def target_state(self, x: Sequence[float], goal: Sequence[float]) -> list[float] | None:
        """The pose the task drives the plant to, for the frames (:meth:`HgoEnv.render`).

        Parameters
        ----------
        x : sequence of float
            The true state (coordinates the task leaves free keep their value).
        goal : sequence of float
            The episode's goal.

        Returns
        -------
        list of float or None
            A state at the target, velocities zero; None (here): no target pose to draw.

        Examples
        --------
        >>> from hgo_mj.envs.tasks import ReachTask, SwingUpTask
        >>> SwingUpTask().target_state([0.1, 0.2], ())
        [3.141592653589793, 0.0]
        >>> ReachTask().target_state([0.0, 0.0, 0.0, 0.0], (0.5,))
        [0.5, 0.5, 0.0, 0.0]
        """
        return None

    def reward_terms(self, x: Any, u: Any, goal: Any) -> tuple[Any, dict[str, Any]]:
        """The reward and its terms, written once for one member and for B members at once.

        ``x``, ``u`` and ``goal`` are indexed by state, input and goal entry: each entry is a
        float (one member, :meth:`reward`) or a ``(B,)`` column (B members, :meth:`rewards`),
        so the body is arithmetic that works on both (operators, ``abs``, ``%``, numpy ufuncs
        such as ``np.maximum``); the same numbers come out either way, bit for bit. A term that
        does not depend on the state may be a float (broadcast to the members).

        Parameters
        ----------
        x : sequence
            True state at the end of the step, one entry (float or column) per plant state.
        u : sequence
            Input held over the step (``action * max_action``, plant units).
        goal : sequence
            The episode's goal (empty for a task without one).

        Returns
        -------
        reward : float or (B,) array
        terms : dict of str to float or (B,) array
            The reward's terms, keyed ``reward_<term>``.

        Raises
        ------
        NotImplementedError
            Always, here: a subclass implements it (or :meth:`reward` alone, which the vector
            environment then calls row by row).

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.envs.tasks import SwingUpTask
        >>> r, terms = SwingUpTask().reward_terms([3.0, 0.0], [0.1], ())
        >>> round(r, 4)
        -0.0201
        >>> X = np.array([[3.0, 0.0], [0.0, 0.0]])
        >>> SwingUpTask().reward_terms(X.T, np.zeros((1, 2)), ())[0].round(2)
        array([-0.02, -9.87])
        """
        raise NotImplementedError

    def termination(self, x: Any) -> Any:
        """Whether the true state ends the episode, written once for one member and for B
        members (``x`` as in :meth:`reward_terms`; default: never).

        Parameters
        ----------
        x : sequence
            True state, one entry (float or ``(B,)`` column) per plant state.

        Returns
        -------
        bool or (B,) bool array
            True where the episode ends.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.envs.tasks import BalanceTask
        >>> BalanceTask().termination([0.6, 0.0])
        True
        >>> BalanceTask().termination(np.array([[0.1, 0.0], [np.nan, 0.0]]).T)
        array([False,  True])
        """
        return False

    def reward(self, x: list[float], u: list[float], goal: tuple[float, ...]
               ) -> tuple[float, dict[str, float]]:
        """Reward of the step that ended in the true state ``x`` under input ``u``, and its
        terms, keyed ``reward_<term>`` (they go into ``info`` as they are): :meth:`reward_terms`
        of one member, as floats.

        Parameters
        ----------
        x : list of float
            True state at the end of the step.
        u : list of float
            Input held over the step (``action * max_action``, plant units).
        goal : tuple of float
            The episode's goal (empty for a task without one).

        Returns
        -------
        reward : float
        terms : dict of str to float
            The reward's terms, keyed ``reward_<term>``.

        Examples
        --------
        >>> from hgo_mj.envs.tasks import SwingUpTask
        >>> reward, terms = SwingUpTask().reward([3.0, 0.0], [0.1], ())
        >>> round(reward, 4), sorted(terms)
        (-0.0201, ['reward_control', 'reward_upright', 'reward_velocity'])
        """
        r, terms = self.reward_terms(x, u, goal)
        return float(r), {k: float(v) for k, v in terms.items()}

    def terminated(self, x: list[float]) -> bool:
        """Whether the true state ``x`` ends the episode: :meth:`termination` of one member.

        Parameters
        ----------
        x : list of float
            True state at the end of a step.

        Returns
        -------
        bool
            True if the episode ends (``terminated`` of ``step``).

        Examples
        --------
        >>> from hgo_mj.envs.tasks import BalanceTask
        >>> BalanceTask().terminated([0.1, 0.0]), BalanceTask().terminated([0.6, 0.0])
        (False, True)
        """
        return bool(self.termination(x))

    def rewards(self, X: Array, U: Array, G: Array) -> tuple[Array, dict[str, Array]]:
        """:meth:`reward` of B members at once (a vector environment): true states ``X``
        ``(B, n)``, inputs ``U`` ``(B, m)``, goals ``G`` ``(B, g)``; the rewards ``(B,)`` and
        the terms as ``(B,)`` arrays (fresh, writable). :meth:`reward_terms` on the columns;
        a task that gives only :meth:`reward` is called row by row.

        Parameters
        ----------
        X : (B, n) array
            True states at the end of the step.
        U : (B, m) array
            Inputs held over the step.
        G : (B, g) array
            Goals (``g = 0`` for a task without one).

        Returns
        -------
        rewards : (B,) array
        terms : dict of str to (B,) array
            The reward terms, keyed ``reward_<term>``.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.envs.tasks import SwingUpTask
        >>> r, terms = SwingUpTask().rewards(np.array([[3.0, 0.0], [0.0, 0.0]]),
        ...                                  np.zeros((2, 1)), np.zeros((2, 0)))
        >>> r.round(2)
        array([-0.02, -9.87])
        """
        B = X.shape[0]
        if type(self).reward_terms is Task.reward_terms:  # a task written row by row
            out = [self.reward(x, u, tuple(g)) for x, u, g in zip(X.tolist(), U.tolist(),
                                                                   G.tolist())]
            terms = {k: np.array([t[k] for _, t in out]) for k in (out[0][1] if out else {})}
            return np.array([r for r, _ in out], dtype=np.float64), terms
        r, terms = self.reward_terms(X.T, U.T, G.T)
        return _column(r, B, np.float64), {k: _column(v, B, np.float64)
                                           for k, v in terms.items()}

    def terminations(self, X: Array) -> NDArray[np.bool_]:
        """:meth:`terminated` of B members at once, ``(B,)``: :meth:`termination` on the
        columns (a task that gives only :meth:`terminated` is called row by row).

        Parameters
        ----------
        X : (B, n) array
            True states.

        Returns
        -------
        (B,) bool array
            :meth:`terminated` of each row.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.envs.tasks import BalanceTask
        >>> BalanceTask().terminations(np.array([[0.1, 0.0], [0.6, 0.0]]))
        array([False,  True])
        """
        if type(self).terminated is not Task.terminated:  # a task written row by row
            return np.array([self.terminated(x) for x in X.tolist()], dtype=bool)
        return _column(self.termination(X.T), X.shape[0], np.bool_)

    def fallback_observer(self, system: Any, sample_period: float) -> Observer | None:
        """The observer to use when ``default_observer`` is not registered (default: none).

        Parameters
        ----------
        system : System
            The environment's plant system.
        sample_period : float
            The environment's sample period [s].

        Returns
        -------
        Observer or None
            An observer for ``system``; ``None`` (here) makes ``observer="default"`` raise
            :class:`~hgo_mj.exceptions.DesignError` as an unknown observer.

        Examples
        --------
        >>> from hgo_mj.envs.tasks import SwingUpTask
        >>> SwingUpTask().fallback_observer(None, 0.04) is None
        True
        """
        return None

    def params(self) -> dict[str, Any]:
        """The task's constructor arguments, as a recording's ``/scenario`` stores them.

        Returns
        -------
        dict
            Here ``{"max_action": [...]}``; a task overrides it with its own arguments.

        Examples
        --------
        >>> from hgo_mj.envs.core import Task
        >>> Task([0.5, 2.0]).params()
        {'max_action': [0.5, 2.0]}
        """
        return {"max_action": list(self.max_action)}


class Encoder:
    """Observation entries from named values: a name the task declares periodic enters as
    ``(cos, sin)``, every other one clipped to the task's bound for it; then the goal; then,
    with ``diagnostics``, the observer's run-time quantities clipped to their bounds (one not
    defined yet, NaN, enters as 0).

    Attributes
    ----------
    labels : tuple of str
        Name of every entry.
    low : ndarray
        Lower bound of every entry (the upper is ``-low``).

    Parameters
    ----------
    task : Task
        Gives the periodic names, the bounds and the goal names.
    names : sequence of str
        Names of the values encoded (state, output or estimate names), in their order.
    diagnostics : sequence of str
        Names of the observer's run-time quantities appended after the goal (default none).

    Examples
    --------
    >>> import math
    >>> from hgo_mj.envs.core import Encoder
    >>> from hgo_mj.envs.tasks import SwingUpTask
    >>> enc = Encoder(SwingUpTask(), ("angle", "angular_velocity"))
    >>> enc.labels
    ('cos(angle)', 'sin(angle)', 'angular_velocity')
    >>> enc([math.pi, 60.0], ()).round(3)
    array([-1.,  0., 50.])
    """

    def __init__(self, task: Task, names: Sequence[str], diagnostics: Sequence[str] = ()) -> None:
        self.items: list[tuple[int, bool, float]] = []
        labels: list[str] = []
        low: list[float] = []
        for i, name in enumerate(names):
            if name in task.periodic:
                self.items.append((i, True, 1.0))
                labels += [f"cos({name})", f"sin({name})"]
                low += [-1.0, -1.0]
            else:
                b = task.bound(name)
                self.items.append((i, False, b))
                labels.append(name)
                low.append(-b)
        labels += list(task.goal_names)
        low += [-task.goal_bound] * len(task.goal_names)
        self.diag_bounds = [task.bound(k) for k in diagnostics]
        labels += [f"diagnostic:{k}" for k in diagnostics]
        low += [-b for b in self.diag_bounds]
        self.labels, self.low = tuple(labels), np.array(low, dtype=np.float64)

    def batch(self, vals: Array, goal: Array, diag: Array | None = None) -> Array:
        """The observations of B members at once, ``(B, len(labels))``: ``vals`` ``(B, k)``,
        ``goal`` ``(B, g)``, ``diag`` ``(B, d)`` (what :meth:`__call__` gives row by row).

        Parameters
        ----------
        vals : (B, k) array
            The named values, one row per member.
        goal : (B, g) array
            The goals (``g = 0`` for a task without one).
        diag : (B, d) array, optional
            The diagnostics (NaN enters as 0); ignored without diagnostic names.

        Returns
        -------
        (B, len(labels)) array
            The observations.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.envs.core import Encoder
        >>> from hgo_mj.envs.tasks import SwingUpTask
        >>> enc = Encoder(SwingUpTask(), ("angle", "angular_velocity"))
        >>> enc.batch(np.array([[0.0, 1.0], [np.pi, -60.0]]), np.zeros((2, 0))).round(3)
        array([[  1.,   0.,   1.],
               [ -1.,   0., -50.]])
        """
        B = vals.shape[0]
        out = np.empty((B, len(self.labels)))
        c = 0
        for i, periodic, b in self.items:
            if periodic:
                out[:, c] = np.cos(vals[:, i])
                out[:, c + 1] = np.sin(vals[:, i])
                c += 2
            else:
                np.clip(vals[:, i], -b, b, out=out[:, c])
                c += 1
        g = goal.shape[1]
        out[:, c:c + g] = goal
        c += g
        if diag is not None and self.diag_bounds:
            d = np.nan_to_num(diag, nan=0.0, posinf=np.inf, neginf=-np.inf)
            bd = np.array(self.diag_bounds)
            np.clip(d, -bd, bd, out=out[:, c:])
        return out

    def __call__(self, vals: Sequence[float], goal: Sequence[float],
                 diag: Sequence[float] = ()) -> Array:
        out: list[float] = []
        for i, periodic, b in self.items:
            v = vals[i]
            if periodic:
                out += [math.cos(v), math.sin(v)]
            else:
                out.append(b if v > b else -b if v < -b else v)
        out += goal
        for v, b in zip(diag, self.diag_bounds):
            v = 0.0 if v != v else v
            out.append(b if v > b else -b if v < -b else v)
        return np.array(out)


@dataclass(frozen=True)
class EnvConfig:
    """An environment's validated arguments (see :class:`HgoEnv`): built by :meth:`of`, which
    checks every argument before anything is made.

    Parameters
    ----------
    task : Task
        The task (made from the environment class's ``task_class`` unless given).
    observer : str, mapping, Observer, "default" or None
        As given to the environment.
    observer_kwargs : mapping or None
        As given to the environment.
    sensor : SensorChain, stage spec(s), "default" or None
        As given to the environment.
    observation : str
        One of :data:`OBSERVATION_MODES`.
    physics_dt, control_period, sample_period : float
        The periods in use [s] (the task's defaults filled in).
    integrator : str or None
        The integrator to set (``None``: keep the MJCF's).
    invalid_action : {"clip", "raise"}
    info_level : {"basic", "full"}

    Examples
    --------
    >>> from hgo_mj.envs import PendulumSwingUpEnv
    >>> cfg = PendulumSwingUpEnv().config
    >>> cfg.physics_dt, cfg.control_period, cfg.sample_period, cfg.integrator
    (0.02, 0.04, 0.04, 'Euler')
    """

    task: Task
    observer: Any
    observer_kwargs: Mapping[str, Any] | None
    sensor: Any
    observation: str
    physics_dt: float
    control_period: float
    sample_period: float
    integrator: str | None
    invalid_action: str
    info_level: str

    @classmethod
    def of(cls, env_cls: type[HgoEnv], *, task: Task | None, observer: Any,
           observer_kwargs: Mapping[str, Any] | None, sensor: Any, observation: str,
           physics_dt: float | None, control_period: float | None,
           sample_period: float | None, integrator: str | None, invalid_action: str,
           info_level: str, render_mode: str | None,
           task_kwargs: Mapping[str, Any]) -> EnvConfig:
        """Check an environment's arguments and fill in the task's defaults.

        Parameters
        ----------
        env_cls : type of HgoEnv
            The environment class (its ``task_class`` and ``metadata["render_modes"]``).
        task, observer, observer_kwargs, sensor, observation
            The arguments of :class:`HgoEnv` (``task=None``: made from ``task_kwargs``).
        physics_dt, control_period, sample_period : float or None
            The periods [s]; ``None``: the task's (``sample_period``: the task's, else the
            control period).
        integrator : str or None
            ``None``: the task's (``None`` there too keeps the MJCF's).
        invalid_action, info_level : str
            As for :class:`HgoEnv`.
        render_mode : str or None
            ``None`` or one of ``env_cls.metadata["render_modes"]``.
        task_kwargs : mapping
            Arguments of ``env_cls.task_class`` (none with an explicit ``task``).

        Returns
        -------
        EnvConfig
            The validated arguments.

        Raises
        ------
        DesignError
            An unknown observation mode, info level, ``invalid_action``, render mode or
            integrator; a period that is not a positive finite number or not an integer
            multiple as required (``control_period`` of ``sample_period`` and of
            ``physics_dt``, ``sample_period`` of ``physics_dt``); a ``task`` that is not a
            Task, task arguments beside it, unknown task arguments, or no task at all.
        hgo_mj.exceptions.MissingExtraError
            A render mode without the ``render`` extra
            (:func:`hgo_mj.envs.render.require_render`).

        Examples
        --------
        >>> from hgo_mj.envs.core import EnvConfig
        >>> from hgo_mj.envs import PendulumSwingUpEnv
        >>> cfg = EnvConfig.of(PendulumSwingUpEnv, task=None, observer="default",
        ...                    observer_kwargs=None, sensor="default", observation="true",
        ...                    physics_dt=None, control_period=0.08, sample_period=None,
        ...                    integrator=None, invalid_action="clip", info_level="basic",
        ...                    render_mode=None, task_kwargs={"max_torque": 1.0})
        >>> cfg.control_period, cfg.sample_period, cfg.task.max_action
        (0.08, 0.08, (1.0,))
        """
        task = _make_task(env_cls, task, task_kwargs)
        if observation not in OBSERVATION_MODES:
            raise DesignError(f"unknown observation mode {observation!r}; valid: "
                              f"{list(OBSERVATION_MODES)}")
        if info_level not in INFO_LEVELS:
            raise DesignError(f"info_level must be one of {list(INFO_LEVELS)}; found {info_level!r}")
        if invalid_action not in INVALID_ACTION_MODES:
            raise DesignError(f"invalid_action must be one of {list(INVALID_ACTION_MODES)}; found "
                              f"{invalid_action!r}")
        if render_mode is not None and render_mode not in env_cls.metadata["render_modes"]:
            raise DesignError(f"unknown render mode {render_mode!r} for {env_cls.__name__}; "
                              f"valid: {[None, *env_cls.metadata['render_modes']]}")
        if render_mode is not None:
            from .render import check_display, require_render

            require_render(render_mode)
            if render_mode == "human":
                check_display()
        integ = task.integrator if integrator is None else integrator
        if integ is not None and integ not in _INTEGRATORS:
            raise DesignError(f"unknown integrator {integ!r}; valid: {sorted(_INTEGRATORS)}")
        pdt = finite_scalar("physics_dt", task.physics_dt if physics_dt is None else physics_dt,
                            positive=True)
        tc = finite_scalar("control_period",
                           task.control_period if control_period is None else control_period,
                           positive=True)
        ts_default = task.sample_period if task.sample_period is not None else tc
        ts = finite_scalar("sample_period", ts_default if sample_period is None else sample_period,
                           positive=True)
        integer_multiple("control_period", tc, pdt, "physics_dt")
        integer_multiple("sample_period", ts, pdt, "physics_dt")
        integer_multiple("control_period", tc, ts, "sample_period")
        return cls(task, observer, observer_kwargs, sensor, observation, pdt, tc, ts, integ,
                   invalid_action, info_level)


def _make_task(env_cls: type[HgoEnv], task: Task | None, task_kwargs: Mapping[str, Any]) -> Task:
    if task is not None:
        if not isinstance(task, Task):
            raise DesignError(f"task must be a Task; found {type(task).__name__}")
        if task_kwargs:
            raise DesignError(f"give task parameters {sorted(task_kwargs)} to the Task, not "
                              f"beside an explicit task=")
        return task
    cls = env_cls.task_class
    if cls is None:
        raise DesignError(f"{env_cls.__name__} needs task= (it has no default task)")
    known = [p for p in inspect.signature(cls.__init__).parameters if p != "self"]
    bad = [k for k in task_kwargs if k not in known]
    if bad:
        loop = [p for p in inspect.signature(HgoEnv.__init__).parameters
                if p not in ("self", "task_kwargs")]
        raise DesignError(f"{env_cls.__name__}: unknown argument(s) {bad}; valid: "
                          f"{sorted(loop + known)}")
    return cls(**task_kwargs)


#: the loop's name for the environment's observer
_OB = "observer"


class HgoEnv(gymnasium.Env[NDArray[np.float64], NDArray[np.float32]], EzPickle):
    """A MuJoCo plant, a sensor chain and an observer in the loop, under a :class:`Task`.

    The environment is :class:`hgo_mj.loop.Loop` (plant -> sensor chain -> observer) plus a
    task: ``step`` runs one control period of the loop with the action held, then reads the
    newest measurement; the task gives reward, termination and the reset distribution. See
    the module docstring for the observation modes, and the environment classes
    (``PendulumSwingUpEnv``, ...) for each task. Recording episodes is a wrapper,
    :class:`hgo_mj.envs.wrappers.RecordEpisodes`.

    Parameters
    ----------
    task : Task, optional
        Default: ``task_class(**task_kwargs)`` of the environment class.
    observer : str, mapping, Observer, "default" or None
        A registered observer name (parameters in ``observer_kwargs``, merged over the task's
        defaults for that observer), a mapping ``{"type": name, **params}``, an
        :class:`~hgo_mj.observers.Observer` instance designed for this plant (the environment
        runs its own deep copy, so that the copies of a vector environment made from the same
        arguments do not share it; the running one is :attr:`observer`), ``"default"`` (the
        task's default observer) or ``None`` (no observer: only the ``"true"`` and
        ``"measurement"`` observations).
    observer_kwargs : mapping, optional
        Parameters of a named observer.
    sensor : SensorChain, stage spec, sequence of stage specs, "default" or None
        The sensor chain (see :func:`sensor_chain`; a chain or stage instances are deep-copied
        like an observer instance); ``"default"``: the task's; ``None`` or ``[]``: exact
        measurements. Seeded by ``reset(seed=...)``.
    observation : {"estimate", "measurement", "true", "estimate+diagnostics"}
        What the agent sees.
    physics_dt, control_period, sample_period : float, optional
        MuJoCo timestep, period over which an action is held, and period of the sensor and
        the observer update; defaults from the task. ``control_period`` must be a multiple of
        ``sample_period``, which must be a multiple of ``physics_dt``.
    integrator : {"Euler", "RK4", "implicit", "implicitfast"}, optional
        MuJoCo integrator (default: the task's, else the MJCF's).
    invalid_action : {"clip", "raise"}
        An action outside ``[-1, 1]`` is clipped to it (default) or raises
        :class:`~hgo_mj.exceptions.DesignError`. A NaN action always raises.
    info_level : {"basic", "full"}
        ``"basic"`` (default): ``info`` holds ``"state"`` (true state), ``"estimate"`` (the
        observer's estimate, named by :attr:`estimate_names`) and ``"error"`` (state minus
        estimate, for the states the observer estimates: :attr:`error_names`). ``"full"``
        adds ``"time"``, ``"measurement"`` (NaN for a dropout), ``"diagnostics"`` (the
        observer's run-time quantities), ``"goal"`` and the reward terms ``"reward_<term>"``.
    render_mode : {None, "rgb_array", "human"}
        ``None`` (default): no rendering (headless testbed); ``"rgb_array"``: :meth:`render`
        returns the true pose with a ghost posed from the estimate; ``"human"``: the same
        scene in MuJoCo's interactive viewer, drawn at every reset and step at ``render_fps``
        (needs a display: :class:`~hgo_mj.envs.render.RenderError` otherwise). Any other value
        raises :class:`~hgo_mj.exceptions.DesignError`.
    **task_kwargs
        Parameters of the task (see the environment class).

    Attributes
    ----------
    config : EnvConfig
        The validated arguments.
    loop : hgo_mj.loop.Loop
    plant : MujocoPlant
    sensor : SensorChain
    observer : Observer or None
    task : Task
    integrator : str
        The MuJoCo integrator in use (``"Euler"``, ``"RK4"``, ...).
    observation_names : tuple of str
        Name of every observation entry.
    estimate_names : tuple of str
        Names of the observer's estimate (``info["estimate"]``).
    error_names : tuple of str
        Names of ``info["error"]``: the states the observer estimates, in plant order.

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.envs import PendulumSwingUpEnv
    >>> env = PendulumSwingUpEnv(observation="measurement", info_level="full")
    >>> obs, info = env.reset(seed=0)
    >>> env.observation_names, env.estimate_names
    (('cos(angle)', 'sin(angle)'), ('angle', 'angular_velocity'))
    >>> obs, reward, terminated, truncated, info = env.step(np.array([1.0], dtype=np.float32))
    >>> info["time"], sorted(info)[:4]
    (0.04, ['diagnostics', 'error', 'estimate', 'measurement'])
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array", "human"], "render_fps": 50}
    _spec: EnvSpec | None = None
    #: the observer as built by name, ``{"type": kind, **parameters}`` (None: an instance)
    _observer_spec: dict[str, Any] | None = None
    task_class: ClassVar[type[Task] | None] = None
    #: the id the class is registered under (:data:`hgo_mj.envs.ENVIRONMENTS`); None: none
    env_id: ClassVar[str | None] = None
    #: step through the loop's step bound at each reset (:meth:`Loop.bind_step`: the same
    #: results as :meth:`Loop.segment` bit for bit); False: every step through
    #: :meth:`Loop.segment` (set before a reset)
    bound_step: bool = True

    def __init__(self, *, task: Task | None = None, observer: Any = "default",
                 observer_kwargs: Mapping[str, Any] | None = None, sensor: Any = "default",
                 observation: str = "estimate", physics_dt: float | None = None,
                 control_period: float | None = None, sample_period: float | None = None,
                 integrator: str | None = None, invalid_action: str = "clip",
                 info_level: str = "basic", render_mode: str | None = None,
                 **task_kwargs: Any) -> None:
        EzPickle.__init__(self, task=task, observer=observer, observer_kwargs=observer_kwargs,
                          sensor=sensor, observation=observation, physics_dt=physics_dt,
                          control_period=control_period, sample_period=sample_period,
                          integrator=integrator, invalid_action=invalid_action,
                          info_level=info_level, render_mode=render_mode, **task_kwargs)
        cfg = EnvConfig.of(type(self), task=task, observer=observer,
                           observer_kwargs=observer_kwargs, sensor=sensor,
                           observation=observation, physics_dt=physics_dt,
                           control_period=control_period, sample_period=sample_period,
                           integrator=integrator, invalid_action=invalid_action,
                           info_level=info_level, render_mode=render_mode,
                           task_kwargs=task_kwargs)
        self.config, self.task = cfg, cfg.task
        self.render_mode = render_mode
        self._renderer: Any = None
        self.observation_mode = cfg.observation
        self.physics_dt, self.control_period, self.sample_period = (
            cfg.physics_dt, cfg.control_period, cfg.sample_period)
        self.dt = cfg.control_period
        self.metadata = {**type(self).metadata,
                         "render_fps": max(1, int(round(1.0 / cfg.control_period)))}
        self.plant = self._make_plant(cfg)
        self.state_names = tuple(self.plant.state_names)
        self.output_names = tuple(self.plant.output_names)
        self.sensor = sensor_chain(cfg.task.default_sensor if _is_default(cfg.sensor) else
                                   copy.deepcopy(cfg.sensor))
        self.observer = self._make_observer(cfg.observer, cfg.observer_kwargs,
                                            self.plant.system)
        if self.observer is None and cfg.observation in ("estimate", "estimate+diagnostics"):
            raise DesignError(f"observation {cfg.observation!r} needs an observer; found "
                              f"observer=None")
        periods = Periods.of(self.plant, cfg.sample_period, cfg.control_period)
        self._n_samples = periods.every
        self.loop = Loop(self.plant, self.sensor,
                         {} if self.observer is None else {_OB: self.observer}, periods,
                         exact=False)
        self._names()
        #: the observer's start from the first measurement (:func:`measurement_start`)
        self._start_map = (None if self.observer is None else
                           _start_map(self.observer, cfg.task.start_ties))
        source = {"true": self.state_names, "measurement": self.output_names}.get(
            cfg.observation, self.estimate_names)
        self.encoder = Encoder(cfg.task, source, self.diagnostic_names
                               if cfg.observation == "estimate+diagnostics" else ())
        self.observation_names = self.encoder.labels
        lo = self.encoder.low
        self.observation_space = spaces.Box(lo, -lo, dtype=np.float64)
        nu = len(self.plant.input_names)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(nu,), dtype=np.float32)
        self._nu, self._scale = nu, cfg.task.max_action
        self._clip = cfg.invalid_action == "clip"
        self._full_info = cfg.info_level == "full"
        self._goal: tuple[float, ...] = ()
        self._y_held = [0.0] * len(self.output_names)
        self._ashape = (nu,)
        self._last: tuple[Any, ...] = ()
        self._reward = 0.0
        #: the loop's step bound at the last reset (:meth:`Loop.bind_step`), or None
        self._bound: Any = None

    # ------------------------------------------------------------------ construction
    def _make_plant(self, cfg: EnvConfig) -> MujocoPlant:
        if cfg.task.plant.endswith(".xml"):  # a lab plant: its MJCF through the generic path
            plant = make_plant(model_path(cfg.task.plant), dt=cfg.sample_period,
                               physics_dt=cfg.physics_dt,
                               outputs=list(getattr(cfg.task, "plant_outputs", ())))
        else:
            plant = make_plant(cfg.task.plant, dt=cfg.sample_period, physics_dt=cfg.physics_dt)
        if not isinstance(plant, MujocoPlant):
            raise DesignError(f"an hgo_mj environment needs a MuJoCo plant; task plant "
                              f"{cfg.task.plant!r} is {type(plant).__name__}")
        if len(cfg.task.max_action) != len(plant.input_names):
            raise DimensionError(f"max_action must have one entry per input "
                                 f"{list(plant.input_names)}; found {len(cfg.task.max_action)}")
        m = plant.model
        if cfg.integrator is not None:
            m.opt.integrator = _INTEGRATORS[cfg.integrator]
        used = int(m.opt.integrator)
        #: the MuJoCo integrator in use, by the name ``integrator=`` takes
        self.integrator = next(k for k, v in _INTEGRATORS.items() if int(v) == used)
        if not np.any(m.geom_contype) and not np.any(m.geom_conaffinity):
            # no collidable geoms: contacts off changes nothing in the dynamics, saves work
            m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
        return plant

    def _names(self) -> None:
        """Names of the estimate, of the estimated states (``info["error"]``) and of the
        observer's run-time quantities."""
        obs = self.observer
        if obs is None:
            self.estimate_names: tuple[str, ...] = ()
            self.error_names: tuple[str, ...] = ()
            self.diagnostic_names: tuple[str, ...] = ()
            self._err_pairs: list[tuple[int, int]] = []
            return
        self.estimate_names = tuple(str(s) for s in obs.state_names)
        est = {name: i for i, name in enumerate(self.estimate_names)}
        #: ``(state index, estimate index)`` of each state the observer estimates
        self._err_pairs = [(j, est[name]) for j, name in enumerate(self.state_names)
                           if name in est]
        self.error_names = tuple(self.state_names[j] for j, _ in self._err_pairs)
        self.diagnostic_names = tuple(k for k in obs.diagnostic_names if k != "dropouts")

    def _make_observer(self, observer: Any, kwargs: Mapping[str, Any] | None,
                       system: Any) -> Observer | None:
        if observer is None:
            if kwargs:
                raise DesignError("observer_kwargs given without an observer")
            return None
        if isinstance(observer, Observer):
            if kwargs:
                raise DesignError("observer_kwargs apply to a named observer, not to an instance")
            self._check_instance(observer, system)
            return copy.deepcopy(observer)
        if _is_default(observer):
            observer = self.default_observer_kind()
            if observer not in OBSERVERS:
                fallback = self.task.fallback_observer(system, self.sample_period)
                if fallback is not None:
                    if kwargs:
                        raise DesignError(f"observer_kwargs need a named observer; the default "
                                          f"{observer!r} is not registered (valid: "
                                          f"{sorted(OBSERVERS)})")
                    return fallback
        if isinstance(observer, Mapping):
            spec = dict(observer)
            kind = spec.pop("type", None)
            if kind is None:
                raise DesignError(f"an observer mapping needs a 'type' (one of {sorted(OBSERVERS)}); "
                                  f"found keys {sorted(spec)}")
            params = {**spec, **dict(kwargs or {})}
        elif isinstance(observer, str):
            kind, params = observer, dict(kwargs or {})
        else:
            raise DesignError(f"observer must be a registered name (one of {sorted(OBSERVERS)}), a "
                              f"mapping {{'type': name, ...}}, an Observer or None; found "
                              f"{type(observer).__name__}")
        built = self.build_observer(kind, system, params)
        self._observer_spec = {"type": kind, **self.observer_params(kind), **params}
        return built

    def default_observer_kind(self) -> str:
        """The observer used by ``observer="default"`` (the task's, if registered).

        Returns
        -------
        str
            The task's ``default_observer`` (when it is not registered, the environment uses
            the task's :meth:`Task.fallback_observer`).

        Examples
        --------
        >>> from hgo_mj.envs import PendulumSwingUpEnv
        >>> PendulumSwingUpEnv().default_observer_kind()
        'high_gain'
        """
        return self.task.default_observer

    def observer_params(self, kind: str) -> dict[str, Any]:
        """The task's default parameters for the observer ``kind``, as the task gives them
        (empty if it has none for that kind); :meth:`build_observer` passes every one to the
        observer, which refuses one it does not take.

        Parameters
        ----------
        kind : str
            An observer name (``hgo_mj.observers.OBSERVERS``).

        Returns
        -------
        dict
            Parameter name -> default value.

        Examples
        --------
        >>> from hgo_mj.envs import PendulumSwingUpEnv
        >>> PendulumSwingUpEnv().observer_params("high_gain")
        {'k': 10.0, 'model': True}
        """
        return dict(self.task.observer_defaults.get(kind, {}))

    def build_observer(self, kind: str, system: Any, params: Mapping[str, Any]) -> Observer:
        """``make_observer(kind, system, **params)`` over the task's defaults for ``kind``
        (:meth:`observer_params`): the builder a scenario's observers go through too.

        Parameters
        ----------
        kind : str
            A registered observer name.
        system : System
            The plant's system (``env.plant.system``).
        params : mapping
            Parameters of the observer; they override :meth:`observer_params`.

        Returns
        -------
        Observer
            A new observer (not the environment's running one).

        Raises
        ------
        DesignError
            ``kind`` is not a registered name, or a parameter (the task's default or
            ``params``) is not one the observer takes: one line naming the valid ones; the
            observer's own constructor raises for bad values.

        Examples
        --------
        >>> from hgo_mj.envs import PendulumSwingUpEnv
        >>> env = PendulumSwingUpEnv()
        >>> obs = env.build_observer("high_gain", env.plant.system, {"k": 5.0})
        >>> type(obs).__name__, obs.params()["k"]
        ('HighGainObserver', 5.0)
        """
        return make_observer(kind, system, **{**self.observer_params(kind), **params})

    def _check_instance(self, obs: Observer, system: Any) -> None:
        if obs.system is not None and _system_key(obs.system) != _system_key(system):
            raise DesignError(f"the observer was designed for {type(obs.system).__name__}; this "
                              f"environment's plant is {type(system).__name__}")
        m = len(self.output_names)
        if max(obs.outputs) >= m:
            raise DimensionError(f"the observer reads output channel {max(obs.outputs)}; the "
                                 f"plant has {m} output(s) {list(self.output_names)}")

    # ------------------------------------------------------------------ the loop
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[Array, dict[str, Any]]:
        """Start an episode.

        Parameters
        ----------
        seed : int, optional
            Seeds the reset distribution (``np_random``) and the sensor chain (whose generator
            otherwise continues from episode to episode; its stages are reset every episode).
        options : dict, optional
            ``{"x0": state}`` and/or ``{"goal": goal}`` instead of drawing them.

        The observer restarts from the first measurement (:func:`measurement_start`).

        Returns
        -------
        observation : ndarray
        info : dict
            ``state`` and, with an observer, ``estimate`` and ``error`` (see
            :attr:`error_names`); with ``info_level="full"`` also ``time``, ``measurement``,
            ``diagnostics`` and, for the reach tasks, ``goal``.

        Raises
        ------
        DesignError
            An unknown option, or an ``x0`` the plant cannot take: not finite, or on a MuJoCo
            plant an entry beyond its ``mjMAXVAL`` (1e10) or a state its ``mj_forward`` flags
            as bad (MuJoCo would reset it to zero and the episode would go on from there); the
            message names the entry and its value.
        DimensionError
            An ``x0`` or ``goal`` of the wrong length.
        """
        super().reset(seed=seed)
        task, rng = self.task, self.np_random
        x0 = task.initial_state(rng)
        goal = task.sample_goal(rng)
        if options:
            x0, goal = self._options(options, x0, goal)
        self._goal = goal
        # the estimate starts from the first measurement
        first = self.loop.reset(x0, seed=env_seed(seed), start=self._start)
        self._bound = self.loop.bind_step(self._n_samples) if self.bound_step else None
        self._y_held = [0.0] * len(self.output_names)
        obs, info, _ = self._observe([0.0] * self._nu, 0.0, first)
        if self.render_mode == "human":
            self.render()
        return obs, info

    def _start(self, observer: Observer, Y: Array) -> Array:
        """The observer's initial estimate from the first measurement ``Y`` ``(1, p)``
        (:func:`measurement_start`, the task's ties: their indices found at construction)."""
        return cast(_StartMap, self._start_map)(Y)

    def _options(self, options: Mapping[str, Any], x0: list[float], goal: tuple[float, ...]
                 ) -> tuple[list[float], tuple[float, ...]]:
        if not isinstance(options, Mapping):
            raise DesignError(f"reset options must be a dict (keys 'goal', 'x0'); found "
                              f"{type(options).__name__} {options!r}")
        unknown = [k for k in options if k not in ("x0", "goal")]
        if unknown:
            raise DesignError(f"unknown reset option(s) {unknown}; valid: ['goal', 'x0']")
        if options.get("x0") is not None:
            x0 = vector("options['x0']", options["x0"], len(self.state_names)).tolist()
        if options.get("goal") is not None:
            names = self.task.goal_names
            g = vector("options['goal']", options["goal"], len(names))
            b = self.task.goal_bound
            if np.any(np.abs(g) > b):  # the observation space's bound on the goal
                raise DesignError(f"options['goal'] must lie in [-{b:g}, {b:g}] (the goal's "
                                  f"bound in the observation space) for {list(names)}; found "
                                  f"{g.tolist()}")
            goal = tuple(g.tolist())
        return x0, goal

    def step(self, action: Any) -> tuple[Array, float, bool, bool, dict[str, Any]]:
        """Hold ``u = action * max_action`` over one control period (see the module docstring).

        Returns
        -------
        observation, reward, terminated, truncated, info
            ``truncated`` is always False here: the time limit is ``TimeLimit``'s. ``info`` as
            at :meth:`reset`, plus (``info_level="full"``) the task's reward terms.

        Raises
        ------
        DimensionError
            An action that is not a sequence of real numbers of the action space's shape (a
            bool, a string, a nested list, the wrong length).
        DesignError
            A NaN entry, or one outside [-1, 1] with ``invalid_action="raise"``.
        DivergenceError
            The plant or the observer left the finite numbers.
        """
        if not self._last:
            raise ResetNeeded(f"{type(self).__name__}: call reset() before step()")
        u = self._action(action)
        try:  # u held over the control period's samples, (1, T, m)
            if self._bound is not None:
                self._bound(u)
            else:
                self.loop.segment(np.array([[u] * self._n_samples]))
        except LoopFailure as exc:
            raise DivergenceError(f"{exc}") from exc.cause
        obs, info, x = self._observe(u, None)
        reward, terms = self.task.reward(x, u, self._goal)
        if self._full_info:
            info.update(terms)
        self._reward = reward
        if self.render_mode == "human":
            self.render()
        return obs, reward, self.task.terminated(x), False, info

    def _action(self, action: Any) -> list[float]:
        """``u = action * max_action`` as floats, the action checked (NaN raises; outside
        [-1, 1]: clip or raise as configured)."""
        if (type(action) is np.ndarray and action.shape == self._ashape
                and action.dtype.kind == "f"):  # the usual action: float32 or float64
            a = action.tolist()
        else:
            if not numbers_only(action) or np.ndim(action) != 1:
                raise DimensionError(f"action must be a sequence of {self._nu} number(s) (shape "
                                     f"{self._ashape}); found {action!r}")
            arr = np.asarray(action, dtype=float)
            if arr.size != self._nu:
                raise DimensionError(f"action must have {self._nu} entries; found {arr.size} "
                                     f"(expected shape {self._ashape})")
            a = arr.tolist()
        for i, v in enumerate(a):
            if not -1.0 <= v <= 1.0:
                if v != v:
                    raise DesignError(f"action[{i}] is NaN")
                if not self._clip:
                    raise DesignError(f"action[{i}] = {v:g} is outside the action space [-1, 1] "
                                      f"(invalid_action='raise')")
                a[i] = -1.0 if v < -1.0 else 1.0
        return [v * s for v, s in zip(a, self._scale)]

    def _observe(self, u: list[float], reward: float | None,
                 sampled: tuple[Array, Array, Array] | None = None
                 ) -> tuple[Array, dict[str, Any], list[float]]:
        """The observation, ``info`` and the true state at the current instant: the true
        state, the newest measurement and the observer's estimate (from the measurements
        before it); ``sampled``: this instant's :meth:`Loop.sample` already made (a reset's)."""
        X, Yc, Ym = self.loop.sample() if sampled is None else sampled
        x, y = X[0, 0].tolist(), Ym[0, 0].tolist()
        obs = self.observer
        x_hat = diag = None
        mode = self.observation_mode
        if obs is not None:
            x_hat = self.loop.estimate(_OB)[0].tolist()
            if self._full_info or mode == "estimate+diagnostics":  # else read when asked
                diag = obs.diagnostics()
        # the row a recording reads (current_row), kept as it is and built when asked
        self._last = (self.loop.t, x, y, Yc, u, x_hat, diag)
        self._reward = 0.0 if reward is None else reward
        extra: Sequence[float] = ()
        if mode in ("estimate", "estimate+diagnostics"):
            # these modes need an observer (refused at construction without one)
            x_hat = cast(list[float], x_hat)
            if not math.isfinite(sum(x_hat)):
                raise DivergenceError(f"the observer's estimate left the finite numbers at "
                                      f"t={self.loop.t:g}: {x_hat}")
            vals = x_hat
            if mode == "estimate+diagnostics":
                extra = [cast(dict[str, float], diag)[k] for k in self.diagnostic_names]
        elif mode == "true":
            vals = x
        else:  # a dropout (NaN) is held at the last valid value
            held = self._y_held
            for i, v in enumerate(y):
                if v == v:
                    held[i] = v
            vals = held
        return self.encoder(vals, self._goal, extra), self._info(X[0, 0], x, y, x_hat, diag), x

    def _info(self, xa: Array, x: list[float], y: list[float], x_hat: list[float] | None,
              diag: dict[str, Any] | None) -> dict[str, Any]:
        """``info``; ``xa`` is the true state as a fresh array of its own (it is handed out)."""
        if x_hat is None:
            info: dict[str, Any] = {"state": xa}
        else:
            info = {"state": xa, "estimate": np.array(x_hat),
                    "error": np.array([x[j] - x_hat[i] for j, i in self._err_pairs],
                                      dtype=np.float64)}
        if self._full_info:
            info["time"] = self.loop.t
            info["measurement"] = np.array(y)
            if diag is not None:
                info["diagnostics"] = dict(diag)
            if self._goal:
                info["goal"] = np.array(self._goal)
        return info

    def render(self) -> NDArray[np.uint8] | None:
        """The current frame (``render_mode="rgb_array"``): the true pose, a translucent
        ghost posed from the observer's estimate (:class:`hgo_mj.envs.render.GhostRenderer`;
        a joint position the observer does not estimate is drawn at its true value) and the
        task's target pose in translucent yellow (:meth:`Task.target_state`), over a floor,
        shape ``(480, 480, 3)`` uint8. ``None`` (with Gymnasium's warning) without a render mode.
        With ``render_mode="human"`` the scene goes to MuJoCo's viewer
        (:class:`hgo_mj.envs.render.HumanViewer`; ``reset`` and ``step`` call this) and
        ``None`` is returned.

        Raises
        ------
        gymnasium.error.ResetNeeded
            Before the first ``reset``.
        hgo_mj.envs.render.RenderError
            No OpenGL backend could be made (the message says which were tried)."""
        if self.render_mode is None:
            gymnasium.logger.warn(f"{type(self).__name__}.render() without a render_mode; "
                                  f"make the environment with render_mode=\"rgb_array\"")
            return None
        if not self._last:
            raise ResetNeeded(f"{type(self).__name__}: call reset() before render()")
        if self._renderer is None:
            from .render import GhostRenderer, HumanViewer

            self._renderer = (GhostRenderer(self.plant.model, self.plant._qadr)
                              if self.render_mode == "rgb_array" else
                              HumanViewer(self.plant.model, self.plant._qadr,
                                          fps=self.metadata["render_fps"]))
        q, ghost, target = self._poses(self._last[1], self._last[5], self._goal)
        if self.render_mode == "human":
            self._renderer.show(q, ghost)
            return None
        return self._renderer.render(q, ghost, target)

    def _poses(self, x: Any, x_hat: Any, goal: Any
               ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64] | None]:
        """The joint positions of a frame: the true ones, the ghost's (the estimated joint
        positions, the states matched by name; the others at their true value) and the
        task's target (:meth:`Task.target_state`; None: none)."""
        nq = len(self.plant._qadr)
        q = np.array(x[:nq], dtype=float)
        ghost = q.copy()
        if x_hat is not None:
            for j, e in self._err_pairs:
                if j < nq:
                    ghost[j] = x_hat[e]
        t = self.task.target_state([float(v) for v in x], tuple(float(g) for g in goal))
        return q, ghost, None if t is None else np.array(t[:nq], dtype=float)

    def close(self) -> None:
        """Free the renderer's buffers, if one was made."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        super().close()

    def current_row(self) -> dict[str, Any]:
        """The last reset's or step's row: time ``t``, true state ``x``, measurement ``y``,
        clean outputs ``y_clean``, input ``u``, estimate ``x_hat`` and ``diagnostics`` (None
        without an observer), ``reward`` (0 at a reset); what a recording wrapper writes.

        Returns
        -------
        dict
            Keys ``"t"`` (float, s), ``"x"``, ``"y"``, ``"y_clean"``, ``"u"`` (lists of
            float), ``"x_hat"`` (list or None), ``"diagnostics"`` (dict or None),
            ``"reward"`` (float).

        Examples
        --------
        >>> from hgo_mj.envs import PendulumSwingUpEnv
        >>> env = PendulumSwingUpEnv()
        >>> _ = env.reset(seed=0)
        >>> row = env.current_row()
        >>> row["t"], row["x_hat"] == [row["y"][0], 0.0], row["reward"], sorted(row)
        (0.0, True, 0.0, ['diagnostics', 'reward', 't', 'u', 'x', 'x_hat', 'y', 'y_clean'])
        """
        t, x, y, Yc, u, x_hat, diag = self._last
        if diag is None and self.observer is not None:
            diag = self.observer.diagnostics()  # the state has not moved since
        return {"t": t, "x": list(x), "y": list(y), "y_clean": Yc[0, 0].tolist(), "u": list(u),
                "x_hat": None if x_hat is None else list(x_hat), "diagnostics": diag,
                "reward": self._reward}

    def recording_metadata(self) -> dict[str, Any]:
        """What a recording's ``/scenario`` document holds: the environment (registered id,
        class), task, observation, periods, integrator, plant, sensor chain, observer (name,
        type, parameters) and package versions.

        Returns
        -------
        dict
            JSON-serializable; keys ``"scenario"`` (the registered id, else the class name),
            ``"environment"``, ``"task"``, ``"plant"``, ``"system_params"``,
            ``"observation"``, ``"physics_dt"``, ``"sample_period"``, ``"control_period"``,
            ``"integrator"``, ``"sensor"``, ``"observers"``, ``"versions"``.

        Examples
        --------
        >>> from hgo_mj.envs import PendulumSwingUpEnv
        >>> meta = PendulumSwingUpEnv().recording_metadata()
        >>> meta["scenario"], meta["task"]
        ('hgo_mj/PendulumSwingUp-v0', {'class': 'SwingUpTask', 'max_torque': 0.5, 'start_noise': 0.1})
        """
        from hgo_mj.simulate import package_versions

        spec = getattr(self, "spec", None)  # else the class's own id (a subclass has none)
        env_id = spec.id if spec is not None else vars(type(self)).get("env_id")
        obs = self.observer
        observers = {}
        if obs is not None:
            observers[obs.name or type(obs).__name__] = {
                "type": type(obs).__name__, "state_names": list(self.estimate_names),
                **obs.params()}
        return {
            "scenario": env_id or type(self).__name__,
            "environment": {"id": env_id, "class": f"{type(self).__module__}."
                                                    f"{type(self).__qualname__}"},
            "task": {"class": type(self.task).__name__, **self.task.params()},
            "plant": type(self.plant.system).__name__,
            "system_params": self.plant.system.params,
            "observation": self.observation_mode,
            "physics_dt": self.physics_dt, "sample_period": self.sample_period,
            "control_period": self.control_period, "integrator": self.integrator,
            "sensor": self.sensor.describe(),
            "observers": observers,
            "versions": package_versions(),
        }

    @property  # type: ignore[override]
    def spec(self) -> EnvSpec | None:
        """Gymnasium's ``EnvSpec`` of the environment (set by ``gymnasium.make``), with the
        observer and the sensor chain this environment runs in ``spec.kwargs``.

        ``kwargs["observer"]`` is ``{"type": name, **parameters}`` (the task's defaults for
        that observer merged with the ones given; ``observer_kwargs`` is folded in), or, for
        an observer instance, its name and :meth:`~hgo_mj.observers.Observer.params`, or
        None; ``kwargs["sensor"]`` is the chain's stages
        (:meth:`~hgo_mj.sensors.SensorChain.describe`). ``spec.to_json()`` works, and
        ``gymnasium.make(env.spec)`` makes the same environment for an observer given by name.

        Returns
        -------
        gymnasium.envs.registration.EnvSpec or None
            None before ``gymnasium.make`` set one (a class made directly).

        Examples
        --------
        >>> import gymnasium
        >>> import hgo_mj.envs
        >>> env = gymnasium.make("hgo_mj/PendulumSwingUp-v0", observer_kwargs={"k": 12.0})
        >>> env.spec.kwargs["observer"]
        {'type': 'high_gain', 'k': 12.0, 'model': True}
        >>> env.spec.kwargs["sensor"]
        [{'stage': 'gaussian', 'std': 0.01}]
        >>> '"observer": {"type": "high_gain"' in env.spec.to_json()
        True
        """
        return self._spec

    @spec.setter
    def spec(self, spec: EnvSpec | None) -> None:
        if spec is not None:
            kwargs = {k: v for k, v in spec.kwargs.items() if k != "observer_kwargs"}
            obs = self.observer
            if obs is None:
                kwargs["observer"] = None
            elif self._observer_spec is not None:
                kwargs["observer"] = self._observer_spec
            elif obs.name in OBSERVERS or not isinstance(spec.kwargs.get("observer", "default"),
                                                         str):
                kwargs["observer"] = {"type": obs.name or type(obs).__name__, **obs.params()}
            else:  # the task's fallback for a default that is not registered (a bank of
                # chains): the name asked for, which makes the same environment again
                kwargs["observer"] = spec.kwargs.get("observer", "default")
            kwargs["sensor"] = self.sensor.describe()
            spec = dataclasses.replace(spec, kwargs=kwargs)
        self._spec = spec

    # ------------------------------------------------------------------ pickling
    def __getstate__(self) -> dict[str, Any]:
        """Pickle as the constructor call (Gymnasium's ``EzPickle``): the copy is a fresh
        environment to be ``reset``; an observer instance travels in its current state.

        Raises
        ------
        DesignError
            The environment was given an observer instance that does not pickle; an
            environment given the observer by name always pickles."""
        obs = self._ezpickle_kwargs.get("observer")
        if isinstance(obs, Observer):
            try:
                pickle.dumps(obs)
            except (pickle.PicklingError, AttributeError, TypeError) as exc:
                raise DesignError(f"this environment's observer instance "
                                  f"({type(obs).__name__}) does not pickle ({exc}); give the "
                                  f"observer by name (observer={obs.name!r}, observer_kwargs="
                                  f"...) for a picklable environment") from None
        return EzPickle.__getstate__(self)


def _is_default(value: Any) -> bool:
    return isinstance(value, str) and value == "default"


__all__ = ["HgoEnv", "INFO_LEVELS", "OBSERVATION_MODES", "EnvConfig", "Encoder", "Task",
           "chain_seed", "env_seed", "measurement_start", "sensor_chain"]
