"""Any hgo_mj observer in the loop of any Gymnasium environment: the agent sees the estimate."""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping, Sequence
from typing import Any, cast

import gymnasium
import mujoco
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


class MujocoTap:
    """The wrapper's hold on a Gymnasium MuJoCo environment (``joints=``): the measured joints'
    positions, the observation entries that are a joint's position or velocity, and a hook in
    the environment's physics stepping that hands every physics step (or every environment
    step) to the observer.

    The observers design against the environment's own MJCF (``env.unwrapped.fullpath``, read
    by :func:`hgo_mj.systems.mjcf.mjcf_system` with the measured joints as outputs): the MuJoCo
    Kalman filters step that model, checked to have the environment's sizes and time step.

    Parameters
    ----------
    env : gymnasium.Env
        A Gymnasium MuJoCo environment (``env.unwrapped`` has ``model``, ``data``,
        ``fullpath``, ``frame_skip`` and ``_step_mujoco_simulation``).
    joints : sequence of str
        The measured joints (hinge or slide), by MJCF name.

    Raises
    ------
    DesignError
        ``env`` is not a MuJoCo environment; :class:`~hgo_mj.exceptions.ModelError` for a
        joint the model does not have (the valid names listed) or a model with ball or free
        joints.
    """

    def __init__(self, env: gymnasium.Env, joints: Sequence[str]) -> None:
        from hgo_mj.systems.mjcf import mjcf_system

        u: Any = env.unwrapped
        missing = [a for a in ("model", "data", "fullpath", "frame_skip",
                               "_step_mujoco_simulation") if not hasattr(u, a)]
        if missing:
            raise DesignError(f"joints= needs a Gymnasium MuJoCo environment; "
                              f"{type(u).__name__} has no {missing} (use measure= instead)")
        self.env: Any = u
        self.joints = tuple(joints)
        self.system = mjcf_system(u.fullpath, list(joints))()
        m = u.model
        self.qadr = np.array([m.jnt_qposadr[m.joint(j).id] for j in joints], dtype=np.intp)
        self.h = float(m.opt.timestep)
        own = self.system.model
        if (own.nq, own.nv, own.nu, float(own.opt.timestep)) != (m.nq, m.nv, m.nu, self.h):
            raise DesignError(f"the environment's MjModel differs from its MJCF file "
                              f"{u.fullpath!r} (nq, nv, nu, timestep: {(m.nq, m.nv, m.nu, self.h)} "
                              f"against {(own.nq, own.nv, own.nu, float(own.opt.timestep))}): the "
                              f"observers could not model it")
        self.entries = self._probe()
        self.on_frame: Callable[[Array, float], None] | None = None
        self.substeps = True

    def _probe(self) -> dict[int, int]:
        """Observation entry -> index in the system's state (joint positions, then velocities)
        for the entries equal to one: found by setting distinct positions and velocities and
        reading the environment's own ``_get_obs`` (the state restored after)."""
        u, m = self.env, self.env.model
        sys_ = self.system
        d = u.data
        saved = np.empty(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS))
        mujoco.mj_getState(m, d, saved, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        rng = np.random.default_rng(12345)
        state = rng.uniform(0.05, 0.95, len(sys_.state_names))
        nj = len(sys_.joints)
        qadr = [m.jnt_qposadr[m.joint(j).id] for j in sys_.joints]
        vadr = [m.jnt_dofadr[m.joint(j).id] for j in sys_.joints]
        d.qpos[qadr], d.qvel[vadr] = state[:nj], state[nj:]
        mujoco.mj_forward(m, d)
        try:
            obs = np.asarray(u._get_obs(), dtype=float).reshape(-1)
        finally:
            mujoco.mj_setState(m, d, saved, mujoco.mjtState.mjSTATE_FULLPHYSICS)
            mujoco.mj_forward(m, d)
        out = {}
        for i, v in enumerate(obs):
            hits = np.flatnonzero(np.abs(state - v) <= 1e-12)
            if hits.size == 1:
                out[i] = int(hits[0])
        return out

    def attach(self) -> None:
        """Route the environment's physics stepping through :meth:`_step`."""
        self.env._step_mujoco_simulation = self._step

    def measure(self) -> Array:
        """The measured joints' positions now (a fresh array)."""
        return np.array(self.env.data.qpos[self.qadr], dtype=np.float64)

    def _step(self, ctrl: Any, n_frames: int) -> None:
        """Gymnasium's ``_step_mujoco_simulation``, one physics step at a time: before each,
        (or before the first, without substeps) the observer gets the measurement and steps
        over the time to the next one."""
        m, d = self.env.model, self.env.data
        d.ctrl[:] = ctrl
        u = np.array(ctrl, dtype=float).reshape(-1)
        for f in range(n_frames):
            if self.on_frame is not None and (self.substeps or f == 0):
                self.on_frame(u, self.h if self.substeps else self.h * n_frames)
            mujoco.mj_step(m, d)
        mujoco.mj_rnePostConstraint(m, d)


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

    **On Gymnasium's MuJoCo environments** give ``joints=`` instead of ``measure=``: the
    named joints' positions are measured (through the sensor chain) inside the environment's
    physics, at every physics step of its frame skip (``substeps=True``) or once per step; the
    observer (default ``"ekf_mujoco"``; any registered name that applies, e.g.
    ``"high_gain_multi"`` with ``model=True``) designs against the environment's own MJCF
    (``env.unwrapped.fullpath``) and reads the controls; the agent's observation is the
    environment's own, in its own space, with every entry that is a joint's position or
    velocity replaced by the estimate (:attr:`observation_names` from the MJCF joints) and the
    other entries (a target, contact forces, cos/sin of angles) kept.
    ``docs/results/wrappers.md`` compares it with a backward difference.

    Parameters
    ----------
    env : gymnasium.Env
        Any environment whose observation (or state) contains the signals a sensor would read.
    measure : sequence of int or callable, optional
        The measured signals: indices into the environment's observation, or a function
        ``measure(env, observation) -> array`` (e.g. reading ``env.unwrapped.data``).
    joints : sequence of str, optional
        Instead of ``measure``, on a MuJoCo environment: the measured hinge or slide joints.
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
        The sensor chain on the measured signals (see :func:`hgo_mj.envs.core.sensor_chain`);
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
        the unclipped value). With ``joints=`` the environment's own space is kept.
    substeps : bool
        With ``joints=``: sample at every physics step (default) or once per step.

    Notes
    -----
    ``info`` gains ``"estimate"`` (the agent's estimate before ``layout`` and clipping),
    ``"measurement"`` (the sensor's reading of the new observation, which the observer
    consumes at the next step) and ``"true_observation"`` (the environment's own
    observation).

    Examples
    --------
    Gymnasium's inverted pendulum with only the cart position and pole angle measured:

    >>> env = ObserverInTheLoop(
    ...     gymnasium.make("InvertedPendulum-v5"), measure=(0, 1),
    ...     observer="high_gain", observer_kwargs={"order": 2, "k": 30.0},
    ...     sensor=[{"stage": "gaussian", "std": 1e-3}], layout=(0, 2, 1, 3))
    >>> obs, info = env.reset(seed=0)
    >>> obs.shape
    (4,)

    The same environment through its joints, the MuJoCo EKF sampling at every physics step:

    >>> env = ObserverInTheLoop(gymnasium.make("InvertedPendulum-v5"), joints=["slider", "hinge"],
    ...                         sensor=[{"stage": "gaussian", "std": 1e-3}])
    >>> env.observation_names
    ('slider_position', 'hinge_angle', 'slider_velocity', 'hinge_velocity')
    >>> obs, info = env.reset(seed=0)
    >>> obs, reward, terminated, truncated, info = env.step(np.zeros(1, dtype=np.float32))
    >>> bool(abs(obs[2] - info["true_observation"][2]) < 0.1)
    True
    """

    def __init__(self, env: gymnasium.Env,
                 measure: Sequence[int] | Callable[..., Any] | None = None, *,
                 joints: Sequence[str] | None = None,
                 observer: str | Observer | Sequence[Observer] | None = None,
                 observer_kwargs: Mapping[str, Any] | None = None, sensor: Any = None,
                 layout: Sequence[int] | None = None,
                 input: Callable[[Any], Any] | None = None,  # noqa: A002 - the observer's u
                 init: str = "measurement", dt: float | None = None, bound: float = 1e6,
                 substeps: bool = True) -> None:
        gymnasium.utils.RecordConstructorArgs.__init__(
            self, measure=measure, joints=joints, observer=observer,
            observer_kwargs=observer_kwargs, sensor=sensor, layout=layout, input=input,
            init=init, dt=dt, bound=bound, substeps=substeps)
        super().__init__(env)
        if (measure is None) == (joints is None):
            raise DesignError("give measure= (observation entries, or a function of the "
                              "environment) or joints= (MuJoCo joint names), one of them")
        if init not in ("measurement", "zero"):
            raise DesignError(f"init must be 'measurement' or 'zero'; found {init!r}")
        if not isinstance(substeps, bool):
            raise DesignError(f"substeps must be true or false; found {substeps!r}")
        self.sensor = sensor_chain(sensor)
        self._input = input
        self._init = init
        self.loop: Loop | None = None
        self.plant: EnvPlant = None  # type: ignore[assignment]
        self.tap: MujocoTap | None = None
        self._renderer: Any = None
        if joints is not None:
            self._setup_joints(env, joints, observer, observer_kwargs, substeps,
                               layout=layout, input=input, dt=dt)
            return
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
        self.dt = env_dt(env, dt)
        self._built = observer is None or isinstance(observer, str)
        self.observer = self._make("high_gain" if observer is None else observer,
                                   observer_kwargs, probe)
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

    def _setup_joints(self, env: gymnasium.Env, joints: Sequence[str], observer: Any,
                      observer_kwargs: Mapping[str, Any] | None, substeps: bool,
                      **generic: Any) -> None:
        """``joints=``: the MuJoCo tap, the observer designed against the environment's own
        MJCF, and the environment's observation space and layout kept."""
        given = [k for k, v in generic.items() if v is not None]
        if given:
            raise DesignError(f"{given} go with measure=; with joints= the observation keeps "
                              f"the environment's layout, the observer reads the controls and "
                              f"the time step is the physics step")
        if isinstance(joints, str) or not all(isinstance(j, str) for j in joints) or not joints:
            raise DesignError(f"joints must be a non-empty list of MJCF joint names; found "
                              f"{joints!r}")
        tap = self.tap = MujocoTap(env, joints)
        tap.substeps = substeps
        system = tap.system
        name = "ekf_mujoco" if observer is None else observer
        if isinstance(name, str):
            from hgo_mj.check import refuse_inapplicable

            kw = dict(observer_kwargs or {})
            refuse_inapplicable(name, system, name)
            self.observer = make_observer(name, system, **kw)
        elif isinstance(name, Observer):
            if observer_kwargs:
                raise DesignError("observer_kwargs apply to a named observer, not to an instance")
            self.observer = copy.deepcopy(name)
        else:
            raise DesignError(f"with joints= the observer is a registered name or an Observer "
                              f"designed against the environment's MJCF; found {name!r}")
        names = tuple(self.observer.state_names)
        if sorted(names) != sorted(system.state_names):
            raise DimensionError(f"the observer's estimate {list(names)} is not the MJCF's "
                                 f"state {list(system.state_names)}")
        #: the observer's estimate in the MJCF's state order (chains are per joint)
        self._perm = np.array([names.index(n) for n in system.state_names], dtype=np.intp)
        self._built = False
        self.dt = tap.h * tap.env.frame_skip
        self.observer.check_period(tap.h if substeps else self.dt)
        space = env.observation_space
        if not isinstance(space, spaces.Box) or len(space.shape) != 1:
            raise DesignError(f"joints= needs a 1-D Box observation space; found {space}")
        self.observation_space = space
        self.observation_names = tuple(
            system.state_names[tap.entries[i]] if i in tap.entries else f"observation_{i}"
            for i in range(space.shape[0]))
        self._t, self._y = 0.0, np.full(len(joints), np.nan)
        self._ready = False
        tap.on_frame = self._frame
        tap.attach()

    def _frame(self, u: Array, dt: float) -> None:
        """One observer update in the MuJoCo tap: the measured joints now, through the sensor
        chain, then the step over ``dt`` with the controls ``u``."""
        assert self.tap is not None
        self._y = self.sensor.apply(np.array([self._t]), self.tap.measure()[None, None])[0, 0]
        self.observer.update(self._y, u, dt)
        self._t += dt

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
            try:
                members = [make_observer(observer, None, outputs=(i,), **kw) for i in range(m)]
            except DesignError as exc:
                if observer not in OBSERVERS:  # misspelt: make_observer lists the valid ones
                    raise
                raise DesignError(
                    f"observer {observer!r} cannot run model-free, one per measured channel, as "
                    f"measure= needs ({exc}): give a model-free one (e.g. 'high_gain'), joints= "
                    f"on a Gymnasium MuJoCo environment (the observer then models its MJCF), "
                    f"or an Observer instance designed against your system") from None
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
        if self.tap is not None:
            return self._reset_joints(obs, info, seed)
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
        if self.tap is not None:
            return self._step_joints(action)
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

    # ------------------------------------------------------------ joints= (MuJoCo tap)
    def _reset_joints(self, obs: Any, info: dict[str, Any], seed: int | None
                      ) -> tuple[Array, dict[str, Any]]:
        """The observer restarts from the first measurement of the joints' positions (the
        model's ``qpos0`` for the unmeasured ones, zero velocities)."""
        from ..core import reset_chain

        tap = self.tap
        assert tap is not None
        reset_chain(self.sensor, seed)
        self._t = 0.0
        self._y = self.sensor.apply(np.array([0.0]), tap.measure()[None, None])[0, 0]
        m = tap.env.model
        system = tap.system
        nj = len(system.joints)
        x0 = np.zeros(len(system.state_names))
        x0[:nj] = [m.qpos0[m.jnt_qposadr[m.joint(j).id]] for j in system.joints]
        for k, j in enumerate(tap.joints):
            if self._y[k] == self._y[k]:  # a dropout keeps qpos0
                x0[system.joints.index(j)] = self._y[k]
        x0_obs = np.empty_like(x0)
        x0_obs[self._perm] = x0
        self.observer.reset(x_hat0=x0_obs)
        self._ready = True
        return self._joint_result(obs, info)

    def _step_joints(self, action: Any) -> tuple[Array, Any, bool, bool, dict[str, Any]]:
        if not self._ready:
            raise ResetNeeded("ObserverInTheLoop: call reset() before step()")
        obs, reward, terminated, truncated, info = self.env.step(action)
        out, info = self._joint_result(obs, info)
        return out, reward, terminated, truncated, info

    def _joint_result(self, obs: Any, info: dict[str, Any]) -> tuple[Array, dict[str, Any]]:
        """The environment's observation with the entries that are a joint's position or
        velocity replaced by the estimate, inside the observation space."""
        assert self.tap is not None
        x_hat = np.array(self.observer.x_hat, dtype=float)[self._perm]
        if not np.all(np.isfinite(x_hat)):
            raise DivergenceError(f"the observer's estimate left the finite numbers at t = "
                                  f"{self._t:.6g} s: {x_hat.tolist()}")
        out = np.array(obs, dtype=float).reshape(-1)
        for i, j in self.tap.entries.items():
            out[i] = x_hat[j]
        space = cast(spaces.Box, self.observation_space)
        out = np.clip(out, space.low, space.high).astype(space.dtype, copy=False)
        info = dict(info)
        info.update(estimate=x_hat, measurement=np.array(self._y),
                    true_observation=np.array(obs))
        return out, info

    def render(self) -> Any:
        """With ``joints=`` and the environment's ``render_mode="rgb_array"``: the true pose and
        the estimate's translucent ghost in one frame (:class:`hgo_mj.envs.render.
        GhostRenderer`, its camera set from the environment's own ``default_cam_config`` as
        Gymnasium's renderer sets it); otherwise the environment's own ``render()``.

        Returns
        -------
        (480, 480, 3) uint8 array, or what the environment's ``render()`` returns

        Raises
        ------
        gymnasium.error.ResetNeeded
            A ghost frame before the first ``reset``.
        hgo_mj.envs.render.RenderError
            No OpenGL backend could be made.

        Examples
        --------
        Skipped here: it needs an OpenGL backend.

        >>> env = ObserverInTheLoop(gymnasium.make("Hopper-v5", render_mode="rgb_array"),
        ...                         joints=["rootz", "rooty", "thigh_joint"])  # doctest: +SKIP
        >>> _ = env.reset(seed=0)  # doctest: +SKIP
        >>> env.render().shape  # doctest: +SKIP
        (480, 480, 3)
        """
        if self.tap is None or self.env.render_mode != "rgb_array":
            return self.env.render()
        if not self._ready:
            raise ResetNeeded("ObserverInTheLoop: call reset() before render()")
        tap = self.tap
        m = tap.env.model
        adr = [m.jnt_qposadr[m.joint(j).id] for j in tap.system.joints]
        if self._renderer is None:
            from ..render import GhostRenderer

            self._renderer = GhostRenderer(m, adr)
            config = getattr(getattr(tap.env, "mujoco_renderer", None), "default_cam_config",
                             None) or {}
            cam = self._renderer.camera
            for key, value in config.items():  # as Gymnasium's own renderer applies it
                if isinstance(value, np.ndarray):
                    getattr(cam, key)[:] = value
                else:
                    setattr(cam, key, value)
        nj = len(tap.system.joints)
        q = np.array(tap.env.data.qpos[adr], dtype=float)
        ghost = np.array(self.observer.x_hat, dtype=float)[self._perm][:nj]
        return self._renderer.render(q, ghost)

    def close(self) -> None:
        if self.tap is not None:  # the environment steps its own way again
            self.tap.env.__dict__.pop("_step_mujoco_simulation", None)
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        super().close()


__all__ = ["ObserverInTheLoop"]
