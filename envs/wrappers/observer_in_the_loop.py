"""Any hgo_mj observer in the loop of any Gymnasium environment: the agent sees the estimate."""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded
from numpy.typing import NDArray

from hgo_mj.exceptions import DesignError, DimensionError, DivergenceError
from hgo_mj.loop import Loop, LoopFailure, Periods
from hgo_mj.observers import OBSERVERS, Observer, make_observer
from hgo_mj.observers.bank import ObserverBank
from hgo_mj.plants.base import Plant

from ..core import env_seed, sensor_chain
from ._common import box_indices, env_dt

Array = NDArray[np.float64]


class EnvPlant(Plant):
    """A Gymnasium environment as the plant of :class:`hgo_mj.loop.Loop`: its state is the
    environment's observation, its outputs the measured signals, and ``run`` steps the
    environment with the action the wrapper set (:attr:`action`), one step per sample.

    The environment itself is reset by the wrapper (with its seed and options) before the
    loop is; :meth:`reset` only reads its first observation.
    """

    batch = 1

    def __init__(self, env: gymnasium.Env, measure: Callable[[Any], Array], dt: float,
                 n_inputs: int) -> None:
        self.env, self._measure, self.dt = env, measure, dt
        self.system = None  # type: ignore[assignment]
        self.obs: Any = None
        self.action: Any = None
        #: what the last environment step returned: (observation, reward, terminated,
        #: truncated, info)
        self.result: tuple[Any, ...] | None = None
        self._n_inputs = n_inputs
        self.t = 0.0

    @property
    def state_names(self) -> tuple[str, ...]:
        return tuple(f"observation_{i}" for i in range(np.size(self.state)))

    @property
    def input_names(self) -> tuple[str, ...]:
        return tuple(f"u{i + 1}" for i in range(self._n_inputs))

    @property
    def output_names(self) -> tuple[str, ...]:
        return tuple(f"y{i + 1}" for i in range(np.size(self.outputs())))

    def start(self, obs: Any) -> None:
        """The environment was reset and observes ``obs``."""
        self.obs, self.result, self.t = obs, None, 0.0

    def reset(self, x0: Any = None, *, batch: int | None = None) -> None:
        if x0 is not None or (batch is not None and batch != 1):
            raise DesignError("an environment plant is reset through its environment (one copy)")

    def run(self, U: Array, steps: int) -> tuple[Array, Array]:
        """Record the observation and the measured signals, then step the environment with
        :attr:`action`, ``steps`` times per sample (the observer's input ``U`` is not the
        environment's action)."""
        T = U.shape[1]
        X = np.empty((1, T, np.size(self.state)))
        Y = np.empty((1, T, np.size(self.outputs())))
        for j in range(T):
            X[0, j], Y[0, j] = self.state, self.outputs()
            for _ in range(steps):
                self.result = self.env.step(self.action)
                self.obs = self.result[0]
                self.t += self.dt
        return X, Y

    @property
    def state(self) -> Array:
        return np.array(self.obs, dtype=float).reshape(-1)  # a copy, as Plant.state promises

    def outputs(self) -> Array:
        return self._measure(self.obs)


class ObserverInTheLoop(gymnasium.Wrapper[Array, Any, Any, Any],
                        gymnasium.utils.RecordConstructorArgs):
    """Measure some signals of an environment, estimate its state with hgo_mj observers, and
    hand the agent the estimate instead of the environment's observation.

    The environment is the plant of hgo_mj's loop (:class:`hgo_mj.loop.Loop`, through
    :class:`EnvPlant`): at every step the observer consumes the current measurement ``y_k``
    (the measured signals through the sensor chain) and the input ``u_k`` (the action, or
    ``input(action)``) and predicts the estimate at the next step; the environment steps, and
    its new observation is measured for the next step. The agent's observation is that
    estimate, rearranged by ``layout``.

    Parameters
    ----------
    env : gymnasium.Env
        Any environment whose observation (or state) contains the signals a sensor would read.
    measure : sequence of int or callable
        The measured signals: indices into the environment's observation, or a function
        ``measure(env, observation) -> array`` (e.g. reading ``env.unwrapped.data``).
    observer : str, Observer or sequence of Observer
        A registered observer name: one observer per measured channel, built without a system
        (model-free) as ``make_observer(name, None, outputs=(i,), **observer_kwargs)``, e.g.
        ``"high_gain"`` with ``observer_kwargs={"order": 2, "k": 30}``: a chain of order 2 per
        signal estimates it and its velocity. Or an observer instance (e.g. one designed
        against an hgo_mj system), or several, each reading its own channel; their estimates
        are concatenated. Instances are deep-copied: the wrapper (and each copy of it in a
        vector environment) runs an observer of its own; read it as ``wrapper.observer``.
    observer_kwargs : mapping, optional
        Parameters of a named observer.
    sensor : sensor spec, optional
        The sensor chain on the measured signals (see :func:`envs.core.sensor_chain`);
        default exact measurement. Seeded by ``reset(seed=...)``.
    layout : sequence of int, optional
        The agent's observation as indices into the concatenated estimate (default: the
        estimate as it is). For InvertedPendulum-v5 measured at ``(0, 1)`` with two chains of
        order 2 (estimate ``x, x', theta, theta'``), ``layout=(0, 2, 1, 3)`` restores the
        environment's own order ``x, theta, x', theta'``.
    input : callable, optional
        ``input(action) -> u`` fed to the observer (default: the action as a float array).
    init : {"measurement", "zero"}
        Initial estimate of the per-channel chains built from a name: the first measurement
        with zero derivatives (default), or zero. Observer instances start from their own
        initial estimate.
    dt : float, optional
        Time between observations; default ``env.unwrapped.dt`` (MuJoCo environments).
    bound : float
        Half width of the observation space (the estimate is clipped to it; ``info`` keeps
        the unclipped value).

    Notes
    -----
    ``info`` gains ``"estimate"`` (the agent's estimate before ``layout`` and clipping),
    ``"measurement"`` (the sensor's reading of the new observation, which the observer
    consumes at the next step) and ``"true_observation"`` (the environment's own
    observation).

    Examples
    --------
    Gymnasium's inverted pendulum with only the cart position and pole angle measured:

    >>> env = ObserverInTheLoop(  # doctest: +SKIP
    ...     gymnasium.make("InvertedPendulum-v5"), measure=(0, 1),
    ...     observer="high_gain", observer_kwargs={"order": 2, "k": 30.0},
    ...     sensor=[{"stage": "gaussian", "std": 1e-3}], layout=(0, 2, 1, 3))
    """

    def __init__(self, env: gymnasium.Env, measure: Sequence[int] | Callable[..., Any], *,
                 observer: str | Observer | Sequence[Observer] = "high_gain",
                 observer_kwargs: Mapping[str, Any] | None = None, sensor: Any = None,
                 layout: Sequence[int] | None = None,
                 input: Callable[[Any], Any] | None = None,  # noqa: A002 - the observer's u
                 init: str = "measurement", dt: float | None = None, bound: float = 1e6) -> None:
        gymnasium.utils.RecordConstructorArgs.__init__(
            self, measure=measure, observer=observer, observer_kwargs=observer_kwargs,
            sensor=sensor, layout=layout, input=input, init=init, dt=dt, bound=bound)
        super().__init__(env)
        if callable(measure):
            self._measure_fn: Callable[..., Any] | None = measure
            self._idx = None
            probe = None
        else:
            idx = box_indices(env.observation_space, measure, owner="measure= as indices",
                              name="measure",
                              hint=" (give a function measure(env, obs) instead)")
            self._measure_fn = None
            self._idx = np.array(idx, dtype=np.intp)
            probe = len(idx)
        if init not in ("measurement", "zero"):
            raise DesignError(f"init must be 'measurement' or 'zero'; found {init!r}")
        self.sensor = sensor_chain(sensor)
        self.dt = env_dt(env, dt)
        self._input = input
        self._built = isinstance(observer, str)
        self.observer = self._make(observer, observer_kwargs, probe)
        self._init = init
        self.observer.check_period(self.dt)
        n_est = len(self.observer.state_names)
        if layout is None:
            lay = list(range(n_est))
        else:
            lay = [int(i) for i in layout]
            if not lay or any(i < 0 or i >= n_est for i in lay):
                raise DimensionError(f"layout must index the {n_est}-entry estimate "
                                     f"{list(self.observer.state_names)}; found {list(layout)}")
        self.layout = np.array(lay, dtype=np.intp)
        self.observation_names = tuple(self.observer.state_names[i] for i in lay)
        self.bound = float(bound)
        self.observation_space = spaces.Box(-self.bound, self.bound, shape=(len(lay),),
                                            dtype=np.float64)
        self.loop: Loop | None = None
        self.plant: EnvPlant = None  # type: ignore[assignment]

    def _make(self, observer: Any, kwargs: Mapping[str, Any] | None, m: int | None) -> Observer:
        if isinstance(observer, Observer):
            if kwargs:
                raise DesignError("observer_kwargs apply to a named observer, not to an instance")
            # a copy of its own: vector copies of the wrapper must not share one state
            return copy.deepcopy(observer)
        if isinstance(observer, str):
            if m is None:
                raise DesignError("a named observer needs measure= as indices (to know how many "
                                  "channels); with measure(env, obs) give observer instances")
            kw = dict(kwargs or {})
            if "outputs" in kw:
                raise DesignError("outputs are set per channel by the wrapper; do not give them")
            members = [make_observer(observer, None, outputs=(i,), **kw) for i in range(m)]
            names = [f"y{i + 1}" for i in range(m)]
            return ObserverBank(members, output_names=names)
        members = list(observer)
        if not members or not all(isinstance(o, Observer) for o in members):
            raise DesignError(f"observer must be a registered name (one of {sorted(OBSERVERS)}), an "
                              f"Observer or a sequence of them; found {observer!r}")
        members = [copy.deepcopy(o) for o in members]
        return members[0] if len(members) == 1 else ObserverBank(members)

    # ------------------------------------------------------------------ loop
    def _signals(self, obs: Any) -> Array:
        if self._measure_fn is not None:  # a fresh array (Plant.outputs), never the caller's
            return np.array(self._measure_fn(self.env, obs), dtype=float).reshape(-1)
        return np.asarray(obs, dtype=float)[self._idx]

    def _u(self, action: Any) -> Array:
        if self._input is not None:
            return np.asarray(self._input(action), dtype=float).reshape(-1)
        return np.asarray(action, dtype=float).reshape(-1)

    def _observation(self, x_hat: Array) -> Array:
        if not np.all(np.isfinite(x_hat)):
            k = self.loop.k if self.loop is not None else 0
            raise DivergenceError(f"the observer's estimate left the finite numbers at step "
                                  f"{k}: {x_hat.tolist()}")
        return np.clip(x_hat[self.layout], -self.bound, self.bound)

    def _build_loop(self, action: Any) -> Loop:
        """The loop around the environment, made at the first reset (when the width of the
        observer's input is known from the action space)."""
        m = self._u(action).size
        self.plant = EnvPlant(self.env, self._signals, self.dt, m)
        self.loop = Loop(self.plant, self.sensor, {"observer": self.observer},
                         Periods(self.dt, self.dt, 1, 1), exact=False)
        return self.loop

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[Array, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        loop = self.loop
        if loop is None:
            loop = self._build_loop(self.env.action_space.sample() * 0)
        self.plant.start(obs)
        loop.reset(seed=env_seed(seed))
        _, _, Ym = loop.sample()
        y = Ym[0, 0]
        ob = self.observer
        if self._built and self._init == "measurement" and isinstance(ob, ObserverBank):
            z0: list[float] = []
            for o in ob.members:
                yi = float(y[o.outputs[0]])
                z0 += [yi if yi == yi else 0.0] + [0.0] * (len(o.state_names) - 1)
            ob.reset(z_hat0=z0)
        x_hat = np.array(ob.x_hat, dtype=float)
        info = dict(info)
        info.update(estimate=x_hat.copy(), measurement=y.copy(), true_observation=np.array(obs))
        return self._observation(x_hat), info

    def step(self, action: Any) -> tuple[Array, Any, bool, bool, dict[str, Any]]:
        if self.loop is None or self.plant.obs is None:
            raise ResetNeeded("ObserverInTheLoop: call reset() before step()")
        self.plant.action = action
        try:
            self.loop.segment(self._u(action)[None, None])
        except LoopFailure as exc:
            raise DivergenceError(str(exc)) from exc.cause
        obs, reward, terminated, truncated, info = self.plant.result  # type: ignore[misc]
        x_hat = np.array(self.observer.x_hat, dtype=float)
        _, _, Ym = self.loop.sample()
        info = dict(info)
        info.update(estimate=x_hat.copy(), measurement=Ym[0, 0].copy(),
                    true_observation=np.array(obs))
        return self._observation(x_hat), reward, terminated, truncated, info
