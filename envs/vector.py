"""The native vector environment: the one loop at B = ``num_envs``.

``gymnasium.make_vec("hgo_mj/<Env>-v0", num_envs=N, vectorization_mode="vector_entry_point")``
(the default mode for these ids) gives an :class:`HgoVectorEnv`: one process, one
:class:`~hgo_mj.loop.Loop` of N members. A step is one ``Loop.segment`` of the control period
for every member at once (the N plants through ``mujoco.rollout`` in MuJoCo's thread pool, N
seeded sensor streams, each observer's N copies in one kernel call), then the observations
(:meth:`hgo_mj.envs.core.Encoder.batch`), the rewards and terminations (:meth:`hgo_mj.envs.core.Task.rewards`,
:meth:`hgo_mj.envs.core.Task.terminations`) as arrays.

Member ``i`` is the single environment (``gymnasium.make(id, **kwargs)``) reset with the seed
``seed + i`` (or the ``i``-th of a list of seeds), step for step and bit for bit (the
observation, reward, flags and ``info``), on any number of MuJoCo threads (``nthread``; 1 and 2
tested for every environment), across autoresets too: a member's reset draws its state and
goal from its own ``np_random``, reseeds
its sensor stream from the same derived seed (:func:`hgo_mj.envs.core.chain_seed`) or lets it go on
(a reset without a seed, as an autoreset), and restarts its observer copy from its first
measurement (:func:`hgo_mj.envs.core.measurement_start`); the plant member keeps the batch's
MuJoCo clock (no shipped model reads it).

Autoreset is Gymnasium 1.x's ``AutoresetMode.NEXT_STEP`` (``metadata["autoreset_mode"]``): the
step after a member terminated or was truncated resets it, ignores its action and returns its
first observation with reward 0 and neither flag set. In that step the member's plant and
observer run with the others and are then restarted, and its sensor stream is held (it does
not advance), so that its numbers are those of the single environment's reset.
``reset(options={"reset_mask": mask})`` resets the masked members only.

``info`` holds, as arrays with a leading member axis (and Gymnasium's ``_key`` masks), what the
single environment's ``info`` holds: ``state``, ``estimate``, ``error`` and with
``info_level="full"`` ``time``, ``measurement``, ``diagnostics`` (a dict of arrays), ``goal``
and the reward terms.

Sensor stages that keep time across samples (``delay``, ``sample_hold``, ``drift``) share one
clock over the streams, which a member's own reset would break: the vector environment refuses
them (use ``vectorization_mode="sync"``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium
import numpy as np
from gymnasium.error import ResetNeeded
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from hgo_mj._validate import numbers_only, sum_is_finite
from hgo_mj.exceptions import DesignError, DimensionError, DivergenceError
from hgo_mj.loop import CONTINUE, LoopFailure

from .core import Array, HgoEnv, chain_seed


def check_num_envs(num_envs: Any) -> int:
    """``num_envs`` as an int >= 1 (a bool, a float or a string is refused, not converted)."""
    if isinstance(num_envs, (bool, np.bool_)) or not isinstance(num_envs, (int, np.integer)):
        raise DesignError(f"num_envs must be an integer >= 1; found {num_envs!r} "
                          f"({type(num_envs).__name__})")
    if num_envs < 1:
        raise DesignError(f"num_envs must be an integer >= 1; found {num_envs}")
    return int(num_envs)


def _columns(idx: list[int]) -> Any:
    """Column indices as a slice where they are consecutive (a view, cheaper at every step),
    else an index array."""
    if idx and idx == list(range(idx[0], idx[0] + len(idx))):
        return slice(idx[0], idx[0] + len(idx))
    return np.array(idx, dtype=np.intp)


class HgoVectorEnv(VectorEnv):  # type: ignore[type-arg]
    """N members of an hgo_mj environment stepped as one batch (see the module docstring).

    Parameters
    ----------
    env_class : type of HgoEnv
        The environment class (``PendulumSwingUpEnv``, ...).
    num_envs : int
        Number of members N, at least 1.
    max_episode_steps : int, optional
        Steps after which a member is truncated (``gymnasium.make_vec`` passes the
        registered one); default the task's.
    nthread : int, optional
        Threads of MuJoCo's batched step (default: the plant's, ``min(2, cpu count)``).
    **kwargs
        The environment's arguments (:class:`~hgo_mj.envs.core.HgoEnv`), the same for every member.

    Raises
    ------
    DesignError
        ``num_envs`` not an integer >= 1, ``max_episode_steps`` or ``nthread`` not a positive
        integer, a sensor stage that keeps time, or any argument the environment refuses.

    Examples
    --------
    >>> import gymnasium
    >>> import numpy as np
    >>> import hgo_mj.envs
    >>> envs = gymnasium.make_vec("hgo_mj/PendulumSwingUp-v0", num_envs=4)
    >>> envs
    HgoVectorEnv(PendulumSwingUpEnv, num_envs=4)
    >>> obs, info = envs.reset(seed=0)
    >>> obs.shape, info["state"].shape
    ((4, 3), (4, 2))
    >>> obs, rewards, terminated, truncated, info = envs.step(np.zeros((4, 1), np.float32))
    >>> rewards.round(2)
    array([-9.71, -9.83, -9.57, -9.36])
    >>> envs.close()
    """

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(self, env_class: type[HgoEnv], num_envs: int = 1, *,
                 max_episode_steps: int | None = None, nthread: int | None = None,
                 **kwargs: Any) -> None:
        N = check_num_envs(num_envs)
        if nthread is not None and (isinstance(nthread, bool)
                                    or not isinstance(nthread, (int, np.integer)) or nthread < 1):
            raise DesignError(f"nthread must be a positive integer; found {nthread!r}")
        if not (isinstance(env_class, type) and issubclass(env_class, HgoEnv)):
            raise DesignError(f"env_class must be an HgoEnv subclass; found {env_class!r}")
        if kwargs.get("render_mode") not in (None, "rgb_array"):
            raise DesignError(f"the native vector environment renders each member's frame as an "
                              f"array: render_mode must be None or 'rgb_array'; found "
                              f"{kwargs['render_mode']!r} (show one member with "
                              f"gymnasium.make(..., render_mode='human'))")
        env = env_class(**kwargs)
        limit = (env.task.max_episode_steps if max_episode_steps is None else max_episode_steps)
        if isinstance(limit, bool) or not isinstance(limit, (int, np.integer)) or limit < 1:
            raise DesignError(f"max_episode_steps must be a positive integer; found {limit!r}")
        timed = [s.name for s in env.sensor.stages if s.keeps_time]
        if timed:
            raise DesignError(f"the native vector environment restarts members on their own; "
                              f"sensor stage(s) {timed} keep one clock over the streams: use "
                              f"vectorization_mode='sync' for them")
        if nthread is not None:
            env.plant.nthread = int(nthread)
        self.env, self.task, self.loop = env, env.task, env.loop
        self.num_envs, self.max_episode_steps = N, int(limit)
        self.single_observation_space = env.observation_space
        self.single_action_space = env.action_space
        self.observation_space = batch_space(env.observation_space, N)
        self.action_space = batch_space(env.action_space, N)
        self.metadata = {**type(self).metadata, "render_fps": env.metadata["render_fps"],
                         "render_modes": ["rgb_array"]}
        #: each member's frame (:meth:`render`), with ``render_mode="rgb_array"``
        self.render_mode = env.render_mode
        self._frame_state: tuple[Array, Array | None] | None = None
        self.observation_names = env.observation_names
        self._nu = len(env.plant.input_names)
        self._scale = np.array(env.task.max_action, dtype=np.float64)
        self._every = env.loop.periods.every
        self._rngs: list[np.random.Generator | None] = [None] * N
        self._goals = np.zeros((N, len(env.task.goal_names)))
        self._y_held = np.zeros((N, len(env.output_names)))
        self._steps = np.zeros(N, dtype=np.int64)
        self._autoreset = np.zeros(N, dtype=bool)
        self._started = False
        self._ones = np.ones(N, dtype=bool)
        err = env._err_pairs
        self._err_state = _columns([j for j, _ in err])
        self._err_est = _columns([i for _, i in err])

    # ------------------------------------------------------------------ reset
    def _seeds(self, seed: Any) -> list[int | None]:
        N = self.num_envs
        if seed is None:
            return [None] * N
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, (bool, np.bool_)):
            return [int(seed) + i for i in range(N)]
        if isinstance(seed, Sequence) and len(seed) == N and all(
                s is None or (isinstance(s, (int, np.integer)) and not isinstance(s, bool))
                for s in seed):
            return [None if s is None else int(s) for s in seed]
        raise DesignError(f"seed must be None, an int or a list of {N} ints (or None); found "
                          f"{seed!r}")

    def _mask(self, options: Mapping[str, Any] | None) -> NDArray[np.intp]:
        if not options:
            return np.arange(self.num_envs)
        unknown = [k for k in options if k != "reset_mask"]
        if unknown:
            raise DesignError(f"unknown reset option(s) {unknown}; valid: ['reset_mask']")
        mask = options["reset_mask"]
        if not (isinstance(mask, np.ndarray) and mask.dtype == bool
                and mask.shape == (self.num_envs,)):
            raise DesignError(f"reset_mask must be a bool array of shape ({self.num_envs},); "
                              f"found {mask!r}")
        if not self._started and not mask.all():
            raise DesignError("the first reset must reset every member (reset_mask all True)")
        return np.flatnonzero(mask)

    def _draw(self, idx: NDArray[np.intp], seeds: list[int | None]) -> Array:
        """Each member's initial state and goal from its own ``np_random`` (seeded as the single
        environment's ``reset(seed=...)`` seeds it)."""
        X0 = []
        for i in idx.tolist():
            sd = seeds[i]
            if sd is not None or self._rngs[i] is None:
                self._rngs[i] = seeding.np_random(sd)[0]
            rng = self._rngs[i]
            X0.append(self.task.initial_state(rng))
            self._goals[i] = self.task.sample_goal(rng)
        self._y_held[idx] = 0.0
        self._steps[idx] = 0
        self._autoreset[idx] = False
        return np.array(X0, dtype=np.float64)

    def reset(self, *, seed: Any = None, options: dict[str, Any] | None = None
              ) -> tuple[Array, dict[str, Any]]:
        """Reset every member (or those of ``options["reset_mask"]``).

        Parameters
        ----------
        seed : int, list of int or None, optional
            An int seeds member ``i`` with ``seed + i``; a list gives each member's seed (None:
            that member's generators go on).
        options : dict, optional
            ``{"reset_mask": bool array (N,)}``: reset only those members.
        """
        seeds = self._seeds(seed)
        idx = self._mask(options)
        X0 = self._draw(idx, seeds)
        if not self._started:
            self.loop.reset(X0, seed=[None if s is None else chain_seed(s) for s in seeds],
                            batch=self.num_envs)
            self._started = True
        else:
            self.loop.reset_members(idx, X0, [CONTINUE if seeds[i] is None else
                                              chain_seed(seeds[i]) for i in idx.tolist()],
                                    restart_observers=False)
        self._start_observer(idx)
        obs, info, _ = self._observe(np.zeros((self.num_envs, self._nu)), None)
        return obs, info

    def _start_observer(self, idx: NDArray[np.intp]) -> None:
        """Restart the members ``idx`` of the observer from their first measurement
        (:func:`hgo_mj.envs.core.measurement_start`), as the single environment's reset does."""
        ob = self.env.observer
        if ob is not None:
            Y = self.loop.sample()[2][idx, 0]
            self.loop.start_observers(idx, {"observer": self.env._start(ob, Y)})

    # ------------------------------------------------------------------ step
    def _actions(self, actions: Any) -> Array:
        """``U = actions * max_action`` ``(N, m)``, the actions checked (NaN raises; outside
        [-1, 1]: clip or raise as configured)."""
        shape = (self.num_envs, self._nu)
        if not numbers_only(actions):
            raise DimensionError(f"actions must be an array of numbers of shape {shape}; found "
                                 f"{actions!r}")
        a = np.array(actions, dtype=np.float64)
        if a.shape != shape:
            raise DimensionError(f"actions must have shape {shape} (num_envs, action entries); "
                                 f"found {a.shape}")
        if not (-1.0 <= a.min() and a.max() <= 1.0):  # False for NaN
            nan = np.argwhere(np.isnan(a))
            if nan.size:
                raise DesignError(f"action[{nan[0, 0]}][{nan[0, 1]}] is NaN")
            if not self.env._clip:
                b, i = np.argwhere(np.abs(a) > 1.0)[0]
                raise DesignError(f"action[{b}][{i}] = {a[b, i]:g} is outside the action space "
                                  f"[-1, 1] (invalid_action='raise')")
            np.clip(a, -1.0, 1.0, out=a)
        return a * self._scale

    def step(self, actions: Any) -> tuple[Array, Array, NDArray[np.bool_], NDArray[np.bool_],
                                          dict[str, Any]]:
        """One control period of every member (members due for an autoreset are reset
        instead; see the module docstring).

        Raises
        ------
        DimensionError
            ``actions`` not numbers of shape ``(num_envs, m)``.
        DesignError
            A NaN action, one outside [-1, 1] with ``invalid_action="raise"``, or a step before
            the first reset.
        DivergenceError
            A plant or an observer left the finite numbers (the member is named).
        """
        if not self._started:
            raise DesignError("call reset() before step() (the members have no state yet)")
        U = self._actions(actions)
        idle = np.flatnonzero(self._autoreset)
        sensor = self.loop.sensor
        if idle.size and sensor is not None:
            sensor.hold(idle.tolist())
        try:
            self.loop.segment(np.repeat(U[:, None], self._every, axis=1))
        except LoopFailure as exc:
            raise DivergenceError(f"{exc}") from exc.cause
        finally:
            if idle.size and sensor is not None:
                sensor.hold(())
        self._steps += 1
        if idle.size:
            X0 = self._draw(idle, [None] * self.num_envs)
            # the observer restarts from the measurement next (_start_observer), not twice
            self.loop.reset_members(idle, X0, [CONTINUE] * idle.size,
                                    restart_observers=False)
            self._start_observer(idle)
        obs, info, X = self._observe(U, idle)
        rewards, terms = self.task.rewards(X, U, self._goals)
        terminated = self.task.terminations(X)
        truncated = self._steps >= self.max_episode_steps
        if idle.size:
            rewards[idle] = 0.0
            terminated[idle] = False
            truncated[idle] = False
            for v in terms.values():
                v[idle] = 0.0
        if self.env._full_info:
            for k, v in terms.items():
                info[k], info["_" + k] = v, self._ones.copy()
        self._autoreset = terminated | truncated
        return obs, rewards, terminated, truncated, info

    def _observe(self, U: Array, idle: NDArray[np.intp] | None
                 ) -> tuple[Array, dict[str, Any], Array]:
        """The observations, ``info`` and the true states of every member at the current
        instant (as the single environment's ``_observe``, row by row)."""
        Xs, _, Ym = self.loop.sample()
        X, Y = Xs[:, 0], Ym[:, 0]
        env, mode = self.env, self.env.observation_mode
        ob = env.observer
        x_hat = D = None
        if ob is not None:
            x_hat = self.loop.estimate("observer")
        extra = None
        if mode in ("estimate", "estimate+diagnostics"):
            x_hat = np.asarray(x_hat)
            if not sum_is_finite(x_hat):
                b = int(np.argmax(~np.isfinite(x_hat.sum(axis=1))))
                raise DivergenceError(f"member {b}: the observer's estimate left the finite "
                                      f"numbers at step {int(self._steps[b])}: "
                                      f"{x_hat[b].tolist()}")
            vals = x_hat
            if mode == "estimate+diagnostics" and env.diagnostic_names:
                diag = ob.diagnostics()  # type: ignore[union-attr]
                extra = np.column_stack([np.asarray(diag[k], dtype=np.float64)
                                         for k in env.diagnostic_names])
        elif mode == "true":
            vals = X
        else:  # a dropout (NaN) is held at the last valid value
            np.copyto(self._y_held, Y, where=~np.isnan(Y))
            vals = self._y_held
        obs = env.encoder.batch(vals, self._goals, extra)
        if self.render_mode is not None:  # what render() draws: copies, the rows move on
            self._frame_state = (X.copy(), None if x_hat is None else np.array(x_hat))
        info: dict[str, Any] = {"state": X}  # (the loop's sample and estimate are fresh)
        if x_hat is not None:
            info["estimate"] = x_hat
            info["error"] = X[:, self._err_state] - x_hat[:, self._err_est]
        if env._full_info:
            info["time"] = self._steps * self._every * self.loop.periods.sample
            info["measurement"] = Y.copy()
            if ob is not None:
                D = ob.diagnostics()
                info["diagnostics"] = {k: np.asarray(v, dtype=np.float64) for k, v in D.items()}
            if self._goals.shape[1]:
                info["goal"] = self._goals.copy()
        for k in list(info):
            info["_" + k] = self._ones.copy()
        return obs, info, X

    def render(self) -> tuple[NDArray[np.uint8], ...] | None:
        """Every member's current frame (``render_mode="rgb_array"``), as the single
        environment draws it (:meth:`hgo_mj.envs.core.HgoEnv.render`: the true pose and the
        estimate's ghost), a tuple of ``num_envs`` arrays ``(480, 480, 3)``; ``None`` (with
        Gymnasium's warning) without a render mode.

        Returns
        -------
        tuple of ndarray or None

        Raises
        ------
        gymnasium.error.ResetNeeded
            Before the first ``reset``.
        hgo_mj.envs.render.RenderError
            No OpenGL backend could be made.

        Examples
        --------
        >>> import gymnasium as gym
        >>> import hgo_mj.envs
        >>> venv = gym.make_vec("hgo_mj/PendulumSwingUp-v0", num_envs=2,
        ...                     vectorization_mode="vector_entry_point", render_mode="rgb_array")
        >>> _ = venv.reset(seed=0)
        >>> [f.shape for f in venv.render()]  # doctest: +SKIP
        [(480, 480, 3), (480, 480, 3)]
        """
        env = self.env
        if self.render_mode is None:
            gymnasium.logger.warn("HgoVectorEnv.render() without a render_mode; make the vector "
                                  "environment with render_mode=\"rgb_array\"")
            return None
        if self._frame_state is None:
            raise ResetNeeded("HgoVectorEnv: call reset() before render()")
        if env._renderer is None:
            from .render import GhostRenderer

            env._renderer = GhostRenderer(env.plant.model, env.plant._qadr)
        X, x_hat = self._frame_state
        return tuple(env._renderer.render(*env._poses(X[b], None if x_hat is None else x_hat[b],
                                                      self._goals[b]))
                     for b in range(self.num_envs))

    def close_extras(self, **kwargs: Any) -> None:
        self.env.close()

    def __repr__(self) -> str:
        return f"HgoVectorEnv({type(self.env).__name__}, num_envs={self.num_envs})"


def vector_entry_point(env_class: type[HgoEnv]) -> Any:
    """The ``vector_entry_point`` registered for ``env_class`` (``make_vec`` calls it with
    ``num_envs``, ``max_episode_steps`` and the environment's arguments).

    Parameters
    ----------
    env_class : type of HgoEnv
        The environment class.

    Returns
    -------
    callable
        ``make(num_envs=1, **kwargs)`` returning ``HgoVectorEnv(env_class, num_envs,
        **kwargs)``, named ``make_<EnvClass>_vector``.

    Examples
    --------
    >>> from hgo_mj.envs import PendulumSwingUpEnv, vector_entry_point
    >>> make = vector_entry_point(PendulumSwingUpEnv)
    >>> make.__name__
    'make_PendulumSwingUpEnv_vector'
    >>> make(num_envs=2, observation="true")
    HgoVectorEnv(PendulumSwingUpEnv, num_envs=2)
    """
    def make(num_envs: int = 1, **kwargs: Any) -> HgoVectorEnv:
        return HgoVectorEnv(env_class, num_envs, **kwargs)
    make.__qualname__ = make.__name__ = f"make_{env_class.__name__}_vector"
    return make


__all__ = ["HgoVectorEnv", "vector_entry_point"]

