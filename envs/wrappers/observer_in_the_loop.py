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

from hgo_mj._validate import one_of
from hgo_mj.exceptions import DesignError, DimensionError, DivergenceError
from hgo_mj.loop import check_fits
from hgo_mj.observers import OBSERVERS, Observer, make_observer
from hgo_mj.observers.bank import ObserverBank

from ..core import sensor_chain
from ._common import box_indices, env_dt, reset_chain

Array = NDArray[np.float64]

#: what the agent is handed: the estimate that has used the newest measurement, or the
#: prediction made before it
ESTIMATES = ("current", "prediction")


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
        #: hand over each physics step after it (the sample at its end) instead of before it
        self.lead = False

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
        """Gymnasium's ``_step_mujoco_simulation``, one physics step at a time, each handed to
        :attr:`on_frame` (without substeps, the whole frame skip at once): before it (the
        observer takes the sample at its start) or, with :attr:`lead`, after it (the sample
        at its end)."""
        m, d = self.env.model, self.env.data
        d.ctrl[:] = ctrl
        u = np.array(ctrl, dtype=float).reshape(-1)
        dt = self.h if self.substeps else self.h * n_frames
        for f in range(n_frames):
            hand = self.on_frame is not None and (self.substeps or f == (
                n_frames - 1 if self.lead else 0))
            if hand and not self.lead:
                self.on_frame(u, dt)  # type: ignore[misc]
            mujoco.mj_step(m, d)
            if hand and self.lead:
                self.on_frame(u, dt)  # type: ignore[misc]
        mujoco.mj_rnePostConstraint(m, d)


class ObserverInTheLoop(gymnasium.Wrapper[Array, Any, Any, Any],
                        gymnasium.utils.RecordConstructorArgs):
    """Measure some signals of an environment, estimate its state with hgo_mj observers, and
    hand the agent the estimate instead of the environment's observation.

    The agent steps the environment, so the wrapper feeds its observer sample by sample as
    the environment steps (hgo_mj's loop kernel, :class:`hgo_mj.loop.Loop`, drives hgo_mj's own
    plants). A step with the action ``a_k`` takes the environment from ``t_k`` to ``t_k+1``; its
    new observation is measured (the measured signals through the sensor chain) as
    ``y_k+1``, and the observer integrates over the step with the input ``u_k`` (the action,
    or ``input(action)``) held. What the agent is handed (``estimate=``):

    * ``"current"`` (default): the estimate at ``t_k+1`` that has used ``y_k+1``, the newest
      measurement. A continuous-time observer (every family but the Kalman filters)
      integrates over the step with ``y_k+1`` held (the measurement at the step's end, in
      place of the one at its start: no sample of delay); a Kalman filter predicts with
      ``y_k`` and hands ``x_k+1|k+1``, its measurement update with ``y_k+1``
      (:meth:`~hgo_mj.observers.Observer.filtered`).
    * ``"prediction"``: the observer integrates over the step with ``y_k`` held and hands
      its prediction of ``x(t_k+1)`` made before ``y_k+1`` (every sample a step late, as a
      sampled observer runs in hgo_mj's loop).

    The agent's observation is that estimate, rearranged by ``layout``.

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
    estimate : {"current", "prediction"}
        The estimate that has used the newest measurement (default), or the prediction made
        before it (see above). With ``joints=`` and substeps, the same per physics step.

    Notes
    -----
    ``info`` gains ``"estimate"`` (the agent's estimate before ``layout`` and clipping),
    ``"measurement"`` (the sensor's reading of the new observation) and
    ``"true_observation"`` (the environment's own observation).
    ``docs/results/wrappers.md`` measures ``"current"`` against ``"prediction"`` and a
    backward difference of the same measurements.

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
                 substeps: bool = True, estimate: str = "current") -> None:
        gymnasium.utils.RecordConstructorArgs.__init__(
            self, measure=measure, joints=joints, observer=observer,
            observer_kwargs=observer_kwargs, sensor=sensor, layout=layout, input=input,
            init=init, dt=dt, bound=bound, substeps=substeps, estimate=estimate)
        super().__init__(env)
        if (measure is None) == (joints is None):
            raise DesignError("give measure= (observation entries, or a function of the "
                              "environment) or joints= (MuJoCo joint names), one of them")
        if init not in ("measurement", "zero"):
            raise DesignError(f"init must be 'measurement' or 'zero'; found {init!r}")
        if not isinstance(substeps, bool):
            raise DesignError(f"substeps must be true or false; found {substeps!r}")
        self.estimate = one_of("estimate", estimate, ESTIMATES)
        self.sensor = sensor_chain(sensor)
        self._input = input
        self._init = init
        self.tap: MujocoTap | None = None
        self._renderer: Any = None
        #: the sensor's clock, the newest measurement, whether the observer has yet to consume
        #: it (it was taken at this instant) and whether the environment was reset
        self._t, self._y, self._fresh, self._ready = 0.0, np.empty(0), False, False
        #: how a step feeds the observer (:meth:`_order`)
        self._lead, self._filter = False, False
        if joints is not None:
            self._setup_joints(env, joints, observer, observer_kwargs, substeps,
                               layout=layout, input=input, dt=dt)
            self._order()
            assert self.tap is not None
            self.tap.lead = self._lead
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
        self._order()

    def _order(self) -> None:
        """How a step feeds the observer for :attr:`estimate`: ``_lead`` (a continuous-time
        observer integrates over the step with the sample at its end) or ``_filter`` (a Kalman
        filter hands its measurement update with the newest sample)."""
        members = getattr(self.observer, "members", (self.observer,))
        kinds = {bool(o.measurement_update) for o in members}
        current = self.estimate == "current"
        if current and len(kinds) > 1:
            raise DesignError("estimate='current' needs observers of one kind: Kalman filters "
                              "(a measurement update) or continuous-time observers; this bank "
                              "mixes them (give estimate='prediction', or one kind)")
        self._filter = current and kinds == {True}
        self._lead = current and not self._filter

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
        tap.on_frame = self._frame
        tap.attach()

    def _frame(self, u: Array, dt: float) -> None:
        """One observer update over ``dt`` with the controls ``u`` in the MuJoCo tap: with the
        measurement of the measured joints at its start (taken now unless already taken at
        this instant) or, leading (:attr:`MujocoTap.lead`, called after the physics step), at
        its end."""
        assert self.tap is not None
        if self._lead:
            self._t += dt
            self._sample(self.tap.measure())
        elif not self._fresh:
            self._sample(self.tap.measure())
        self._fresh = False
        self.observer.update(self._y, u, dt)
        if not self._lead:
            self._t += dt

    def _sample(self, signals: Array) -> None:
        """The measurement of ``signals`` at the sensor's clock, through the sensor chain:
        the newest, not yet consumed."""
        self._y = self.sensor.apply(np.array([self._t]), signals[None, None])[0, 0]
        self._fresh = True

    def _current(self) -> Array:
        """What the agent is handed before ``layout``: the observer's estimate, or a Kalman
        filter's measurement update with the newest sample (``estimate="current"``)."""
        if self._filter:
            return np.array(self.observer.filtered(self._y), dtype=float)
        return np.array(self.observer.x_hat, dtype=float)

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
            raise DivergenceError(f"the observer's estimate left the finite numbers at t = "
                                  f"{self._t:.6g} s: {x_hat.tolist()}")
        return np.clip(x_hat[self.layout], -self.bound, self.bound)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[Array, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        reset_chain(self.sensor, seed)
        self._t = 0.0
        if self.tap is not None:
            return self._reset_joints(obs, info)
        self._sample(self._signals(obs))
        y, ob = self._y, self.observer
        if not self._ready:  # the widths are known now: the observer's channels and input
            n_u = self._u(self.env.action_space.sample() * 0).size
            check_fits("observer", ob, [f"y{i + 1}" for i in range(y.size)],
                       [f"u{i + 1}" for i in range(n_u)])
        if self._built and self._init == "measurement" and isinstance(ob, ObserverBank):
            z0: list[float] = []
            for o in ob.members:
                yi = float(y[o.outputs[0]])
                z0 += [yi if yi == yi else 0.0] + [0.0] * (len(o.state_names) - 1)
            ob.reset(z_hat0=z0)
        else:
            ob.reset()
        self._ready = True
        x_hat = self._current()
        info = dict(info)
        info.update(estimate=x_hat.copy(), measurement=y.copy(), true_observation=np.array(obs))
        return self._observation(x_hat), info

    def step(self, action: Any) -> tuple[Array, Any, bool, bool, dict[str, Any]]:
        if not self._ready:
            raise ResetNeeded("ObserverInTheLoop: call reset() before step()")
        if self.tap is not None:
            return self._step_joints(action)
        u = self._u(action)
        if not self._lead:  # the sample at the step's start
            self.observer.update(self._y, u, self.dt)
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._t += self.dt
        self._sample(self._signals(obs))
        if self._lead:  # the sample at its end
            self.observer.update(self._y, u, self.dt)
        x_hat = self._current()
        info = dict(info)
        info.update(estimate=x_hat.copy(), measurement=self._y.copy(),
                    true_observation=np.array(obs))
        return self._observation(x_hat), reward, terminated, truncated, info

    # ------------------------------------------------------------ joints= (MuJoCo tap)
    def _reset_joints(self, obs: Any, info: dict[str, Any]) -> tuple[Array, dict[str, Any]]:
        """The observer restarts from the first measurement of the joints' positions (the
        model's ``qpos0`` for the unmeasured ones, zero velocities)."""
        tap = self.tap
        assert tap is not None
        self._sample(tap.measure())
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
        obs, reward, terminated, truncated, info = self.env.step(action)
        if not self._lead:  # the sample at the step's end, consumed first by the next step
            assert self.tap is not None
            self._sample(self.tap.measure())
        out, info = self._joint_result(obs, info)
        return out, reward, terminated, truncated, info

    def _joint_result(self, obs: Any, info: dict[str, Any]) -> tuple[Array, dict[str, Any]]:
        """The environment's observation with the entries that are a joint's position or
        velocity replaced by the estimate, inside the observation space."""
        assert self.tap is not None
        x_hat = self._current()[self._perm]
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
