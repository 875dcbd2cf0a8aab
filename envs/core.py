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
"""

from __future__ import annotations

import copy
import inspect
import math
import pickle
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar

import gymnasium
import mujoco
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from hgo_mj._validate import finite_scalar, integer_multiple, vector
from hgo_mj.exceptions import DesignError, DimensionError, DivergenceError
from hgo_mj.observers import OBSERVERS, Observer, make_observer
from hgo_mj.plants import make_plant
from hgo_mj.sensors import SensorChain, Stage, make_stage

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
    independent of the environment's own ``np_random`` (which the same integer also seeds)."""
    ss = np.random.SeedSequence([int(seed), 0x5E4503])
    return int(ss.generate_state(1, np.uint64)[0] >> np.uint64(1))


def reset_chain(chain: SensorChain, seed: int | None) -> None:
    """Reset a sensor chain at an environment's ``reset(seed=...)``: re-seed it (from
    :func:`chain_seed`) on a seeded reset; otherwise reset its stages and let its generator
    continue (Gymnasium's convention for ``reset()`` without a seed)."""
    if seed is not None:
        chain.reset(chain_seed(seed))
    else:
        for s in chain.stages:
            s.reset()


def sensor_chain(spec: Any, seed: int | None = None) -> SensorChain:
    """Build a :class:`~hgo_mj.sensors.SensorChain` from what an environment accepts.

    Parameters
    ----------
    spec : SensorChain, Stage, mapping, str, sequence of those, or None
        A chain (used as is); one stage, given as an instance, a mapping
        ``{"stage": name, **params}`` or a bare name (a stage without required parameters);
        a sequence of such stages, applied in order; ``None`` or ``[]`` for exact
        measurements.
    seed : int, optional
        Seed of a new chain.

    Raises
    ------
    DesignError
        Unknown stage names (the message lists the valid ones), unknown or missing parameters.
    """
    if isinstance(spec, SensorChain):
        return spec
    if spec is None:
        return SensorChain([], seed=seed)
    if isinstance(spec, (str, Stage, Mapping)):
        spec = [spec]
    stages: list[Stage] = []
    for i, s in enumerate(spec):
        if isinstance(s, Stage):
            stages.append(s)
        elif isinstance(s, str):
            stages.append(make_stage(s))
        elif isinstance(s, Mapping):
            params = dict(s)
            if "stage" not in params:
                raise DesignError(f"sensor stage {i} must name its stage: {{'stage': name, ...}}; "
                                  f"found keys {sorted(params)}")
            stages.append(make_stage(params.pop("stage"), **params))
        else:
            raise DesignError(f"sensor stage {i} must be a Stage, a stage name or a mapping "
                              f"{{'stage': name, ...}}; found {type(s).__name__}")
    return SensorChain(stages, seed=seed)


def _accepted(cls: type, params: Mapping[str, Any]) -> dict[str, Any]:
    """The entries of ``params`` that ``cls``'s constructor accepts (all, with ``**kwargs``)."""
    sig = inspect.signature(cls.__init__)
    if any(p.kind is p.VAR_KEYWORD for p in sig.parameters.values()):
        return dict(params)
    return {k: v for k, v in params.items() if k in sig.parameters}


class Task:
    """Reward, termination and reset distribution of an environment, and its defaults.

    Subclasses set the class attributes and implement :meth:`initial_state` and
    :meth:`reward` (and, where they apply, :meth:`sample_goal` and :meth:`terminated`). A
    task never sees the estimate: reward and termination use the true state.

    Attributes
    ----------
    plant : str
        Registry name of the plant (``hgo_mj.systems.SYSTEMS``).
    max_action : tuple of float
        Input per unit action, one per plant input (``u = action * max_action``).
    """

    plant: ClassVar[str] = ""
    physics_dt: ClassVar[float] = 0.001
    control_period: ClassVar[float] = 0.01
    #: default sample period (``None``: the control period)
    sample_period: ClassVar[float | None] = None
    #: MuJoCo integrator to use instead of the MJCF's (``None``: keep the MJCF's)
    integrator: ClassVar[str | None] = None
    max_episode_steps: ClassVar[int] = 1000
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

    def __init__(self, max_action: Sequence[float]) -> None:
        self.max_action = tuple(finite_scalar(f"max_action[{i}]", v, positive=True)
                                for i, v in enumerate(max_action))

    def bound(self, name: str) -> float:
        """Observation bound of an entry named ``name``."""
        for suffix, b in self.bounds:
            if name.endswith(suffix):
                return b
        return self.default_bound

    def initial_state(self, rng: np.random.Generator) -> list[float]:
        """Draw the true initial state."""
        raise NotImplementedError

    def sample_goal(self, rng: np.random.Generator) -> tuple[float, ...]:
        """Draw the goal shown to the agent (default: none)."""
        return ()

    def reward(self, x: list[float], u: list[float], goal: tuple[float, ...]
               ) -> tuple[float, dict[str, float]]:
        """Reward of the step that ended in the true state ``x`` under input ``u``, and its
        terms, keyed ``reward_<term>`` (they go into ``info`` as they are)."""
        raise NotImplementedError

    def terminated(self, x: list[float]) -> bool:
        """Whether the true state ``x`` ends the episode (default: never)."""
        return False

    def fallback_observer(self, system: Any, sample_period: float) -> Observer | None:
        """The observer to use when ``default_observer`` is not registered (default: none)."""
        return None

    def params(self) -> dict[str, Any]:
        return {"max_action": list(self.max_action)}


class _Plan:
    """How a vector of named values becomes observation entries (cos/sin or clipped)."""

    def __init__(self, task: Task, names: Sequence[str]) -> None:
        self.items: list[tuple[int, bool, float]] = []
        self.labels: list[str] = []
        low: list[float] = []
        for i, name in enumerate(names):
            if name in task.periodic:
                self.items.append((i, True, 1.0))
                self.labels += [f"cos({name})", f"sin({name})"]
                low += [-1.0, -1.0]
            else:
                b = task.bound(name)
                self.items.append((i, False, b))
                self.labels.append(name)
                low.append(-b)
        self.low = low

    def compile(self, n_goal: int) -> Callable[[list[float], tuple[float, ...]], list[float]]:
        """Straight-line ``encode(vals, goal) -> list`` for this plan (no loop, no branches
        beyond the clips): a few hundred nanoseconds instead of a microsecond."""
        lines, items = [], []
        for i, per, b in self.items:
            if per:
                lines.append(f"    a{i} = v[{i}]")
                items += [f"cos(a{i})", f"sin(a{i})"]
            else:
                lines.append(f"    a{i} = v[{i}]")
                items.append(f"({b!r} if a{i} > {b!r} else ({-b!r} if a{i} < {-b!r} else a{i}))")
        items += [f"g[{j}]" for j in range(n_goal)]
        src = "def encode(v, g):\n" + "\n".join(lines) + f"\n    return [{', '.join(items)}]\n"
        scope: dict[str, Any] = {"cos": math.cos, "sin": math.sin}
        exec(compile(src, "<observation encoder>", "exec"), scope)  # noqa: S102 - numbers only
        return scope["encode"]


class _MjIO:
    """Lean per-step access to a :class:`~hgo_mj.plants.MujocoPlant`'s ``MjData``.

    An environment step has a budget of a few microseconds beyond MuJoCo itself, so the loop
    reads and writes ``MjData`` through addresses looked up by name once (the joints, actuators
    and sensors the plant's system names) in Python floats, and runs the substeps of a sample
    in one ``mj_step(m, d, nstep)`` call. It does what ``MujocoPlant.reset``, ``step``,
    ``state`` and ``outputs`` do, with two differences: ``reset`` skips ``mj_forward`` when
    every output is read straight from ``qpos``/``qvel`` (the next ``mj_step`` computes it),
    and MuJoCo's silent reset on a bad state is detected by its effect, the simulation time
    falling back (``mj_resetData`` zeroes it), and then reported with the warning's name.
    A model without collidable geoms runs with contacts disabled (no effect on its dynamics,
    less work per step).
    """

    def __init__(self, plant: Any) -> None:
        m, d = plant.model, plant.data
        system = plant.system
        obj = mujoco.mjtObj

        def _id(kind: Any, name: str) -> int:
            return int(mujoco.mj_name2id(m, kind, name))

        joints = [_id(obj.mjOBJ_JOINT, j) for j in system.joints]
        self.qadr = [int(m.jnt_qposadr[j]) for j in joints]
        self.vadr = [int(m.jnt_dofadr[j]) for j in joints]
        self.aadr = [_id(obj.mjOBJ_ACTUATOR, a) for a in system.actuators]
        self.nq = len(joints)
        self.substeps = int(plant.substeps)
        #: simulated time one ``step`` advances by, less half a physics step (reset detection)
        self.advance = plant.substeps * float(m.opt.timestep) - 0.5 * float(m.opt.timestep)
        self.plant, self.m, self.d = plant, m, d
        direct = []
        for name in plant.output_names:
            sid = _id(obj.mjOBJ_SENSOR, name)
            typ = int(m.sensor_type[sid])
            on_joint = int(m.sensor_objtype[sid]) == int(obj.mjOBJ_JOINT)
            if on_joint and typ == int(mujoco.mjtSensor.mjSENS_JOINTPOS):
                direct.append(("q", int(m.jnt_qposadr[m.sensor_objid[sid]])))
            elif on_joint and typ == int(mujoco.mjtSensor.mjSENS_JOINTVEL):
                direct.append(("v", int(m.jnt_dofadr[m.sensor_objid[sid]])))
            else:
                direct = []
                break
        #: ``(array, address)`` of each output, or ``None``: use ``plant.outputs()``
        self.out = [(d.qpos if k == "q" else d.qvel, a) for k, a in direct] or None
        self._direct = direct
        if not np.any(m.geom_contype) and not np.any(m.geom_conaffinity):
            m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
        self._compile()

    def _compile(self) -> None:
        """Straight-line ``step(u) -> t``, ``read_x() -> list`` and ``read_y() -> list`` for
        this model's addresses (no loop over one-entry lists: a step has a few microseconds)."""
        d = self.d
        self.qpos, self.qvel, self.ctrl = d.qpos, d.qvel, d.ctrl  # views, valid while d lives
        #: the time the next ``step`` must reach at least (MuJoCo's silent reset detection)
        self.next_time = [float("inf")]
        scope: dict[str, Any] = {"qpos": self.qpos, "qvel": self.qvel, "ctrl": self.ctrl,
                                 "d": d, "m": self.m, "mj_step": mujoco.mj_step,
                                 "nxt": self.next_time, "diverged": self._diverged}
        writes = "".join(f"    ctrl[{a}] = u[{i}]\n" for i, a in enumerate(self.aadr))
        xs = [f"qpos.item({a})" for a in self.qadr] + [f"qvel.item({a})" for a in self.vadr]
        src = (f"def step(u):\n{writes}    mj_step(m, d, {self.substeps})\n    t = d.time\n"
               f"    if t < nxt[0]:\n        diverged(u, t)\n"
               f"    nxt[0] = t + {self.advance!r}\n    return t\n"
               f"def read_x():\n    return [{', '.join(xs)}]\n")
        if self.out is not None:
            ys = [f"{'qpos' if k == 'q' else 'qvel'}.item({a})" for k, a in self._direct]
            src += f"def read_y():\n    return [{', '.join(ys)}]\n"
        exec(compile(src, "<environment io>", "exec"), scope)  # noqa: S102 - numbers only
        self.step: Callable[[list[float]], float] = scope["step"]
        self.read_x: Callable[[], list[float]] = scope["read_x"]
        plant = self.plant
        self.read_y: Callable[[], list[float]] = (
            scope["read_y"] if self.out is not None else (lambda: plant.outputs().tolist()))

    def reset(self, x0: list[float]) -> None:
        m, d = self.m, self.d
        mujoco.mj_resetData(m, d)
        qpos, qvel, n = self.qpos, self.qvel, self.nq
        for i, a in enumerate(self.qadr):
            qpos[a] = x0[i]
        for i, a in enumerate(self.vadr):
            qvel[a] = x0[n + i]
        if self.out is None:
            mujoco.mj_forward(m, d)
        self.next_time[0] = d.time + self.advance

    def _diverged(self, u: list[float], t: float) -> None:
        d = self.d
        w = mujoco.mjtWarning
        bad = [n for n in ("QPOS", "QVEL", "QACC")
               if d.warning[int(getattr(w, "mjWARN_BAD" + n))].number]
        raise DivergenceError(f"MuJoCo found a non-finite or huge value (mjWARN_BAD"
                              f"{bad[0] if bad else '?'}) and reset the simulation near "
                              f"t={t:g}; input was {u}")


class HgoEnv(gymnasium.Env[NDArray[np.float64], NDArray[np.float32]]):
    """A MuJoCo plant, a sensor chain and an observer in the loop, under a :class:`Task`.

    See the module docstring for the loop and the observation modes, and the environment
    classes (``PendulumSwingUpEnv``, ...) for each task.

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
        Every ``info`` entry costs a ``SyncVectorEnv`` about a microsecond per copy and step.
    record_path : str or Path, optional
        Write every episode, batched at its end (the next ``reset`` or ``close``), to this
        rerun ``.rrd`` file (:class:`hgo_mj.record.Recorder`, issue 6): one row at ``reset``
        and one per ``step`` (``steps + 1`` rows an episode; the reset row's input and reward
        are 0) on the ``sim_time``, ``step`` and ``episode`` timelines: true state, the
        observer's estimate by its own ``state_names`` (:attr:`estimate_names`) and errors,
        clean and measured outputs, input, the observer's diagnostics, the reward
        (``/env/reward``), the 3D view; after each episode the ``/metrics`` table (one row per
        episode: seed, steps, return, RMSE per estimated state) and the ``/scenario`` document
        (:meth:`recording_metadata`, with every episode's seed).
    render_mode : None
        No rendering (headless testbed); any other value raises.
    **task_kwargs
        Parameters of the task (see the environment class).

    Attributes
    ----------
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
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": [], "render_fps": 50}
    task_class: ClassVar[type[Task] | None] = None

    def __init__(self, *, task: Task | None = None, observer: Any = "default",
                 observer_kwargs: Mapping[str, Any] | None = None, sensor: Any = "default",
                 observation: str = "estimate", physics_dt: float | None = None,
                 control_period: float | None = None, sample_period: float | None = None,
                 integrator: str | None = None, invalid_action: str = "clip",
                 info_level: str = "basic", record_path: str | Path | None = None,
                 render_mode: str | None = None, **task_kwargs: Any) -> None:
        self._init_kwargs = dict(task=task, observer=observer, observer_kwargs=observer_kwargs,
                                 sensor=sensor, observation=observation, physics_dt=physics_dt,
                                 control_period=control_period, sample_period=sample_period,
                                 integrator=integrator, invalid_action=invalid_action,
                                 info_level=info_level, record_path=record_path,
                                 render_mode=render_mode, **task_kwargs)
        self.task = self._make_task(task, task_kwargs)
        task = self.task
        if observation not in OBSERVATION_MODES:
            raise DesignError(f"unknown observation mode {observation!r}; valid: "
                              f"{list(OBSERVATION_MODES)}")
        if info_level not in INFO_LEVELS:
            raise DesignError(f"info_level must be one of {list(INFO_LEVELS)}; found {info_level!r}")
        self._full_info = info_level == "full"
        if invalid_action not in INVALID_ACTION_MODES:
            raise DesignError(f"invalid_action must be one of {list(INVALID_ACTION_MODES)}; found "
                              f"{invalid_action!r}")
        if render_mode is not None:
            raise DesignError(f"{type(self).__name__} does not render (headless); render_mode must "
                              f"be None; found {render_mode!r}")
        self.render_mode = None
        self.observation_mode = observation
        self._clip = invalid_action == "clip"

        # ---- time
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
        self._n_samples = integer_multiple("control_period", tc, ts, "sample_period")
        self.physics_dt, self.control_period, self.sample_period = pdt, tc, ts
        self.dt = tc
        self.metadata = {**type(self).metadata, "render_fps": max(1, int(round(1.0 / tc)))}

        # ---- plant
        self.plant = make_plant(task.plant, dt=ts, physics_dt=pdt)
        integ = task.integrator if integrator is None else integrator
        if integ is not None:
            if integ not in _INTEGRATORS:
                raise DesignError(f"unknown integrator {integ!r}; valid: {sorted(_INTEGRATORS)}")
            self.plant.model.opt.integrator = _INTEGRATORS[integ]
        used = int(self.plant.model.opt.integrator)
        #: the MuJoCo integrator in use, by the name ``integrator=`` takes
        self.integrator = next(k for k, v in _INTEGRATORS.items() if int(v) == used)
        self._io = _MjIO(self.plant)
        system = self.plant.system
        self.state_names = tuple(self.plant.state_names)
        self.output_names = tuple(self.plant.output_names)
        nu = len(self.plant.input_names)
        if len(task.max_action) != nu:
            raise DimensionError(f"max_action must have one entry per input "
                                 f"{list(self.plant.input_names)}; found {len(task.max_action)}")

        # ---- sensor and observer
        self.sensor = sensor_chain(task.default_sensor if _is_default(sensor) else
                                   copy.deepcopy(sensor))
        self.observer = self._make_observer(observer, observer_kwargs, system)
        if self.observer is None and observation in ("estimate", "estimate+diagnostics"):
            raise DesignError(f"observation {observation!r} needs an observer; found observer=None")
        if self.observer is not None:
            self.observer.check_period(ts)
            self.observer.reset()
            self.estimate_names = tuple(str(s) for s in self.observer.state_names)
            est = {name: i for i, name in enumerate(self.estimate_names)}
            pairs = [(j, est[name]) for j, name in enumerate(self.state_names) if name in est]
            #: ``(state index, estimate index)`` of each state the observer estimates
            self._err_pairs = pairs
            self._err = _error_function(pairs)
            self.error_names = tuple(self.state_names[j] for j, _ in pairs)
            diag = self.observer.diagnostics()
            self.diagnostic_names = tuple(k for k in diag if k != "dropouts")
        else:
            self.estimate_names = self.error_names = self.diagnostic_names = ()

        # ---- spaces
        source = {"true": self.state_names, "measurement": self.output_names}.get(
            observation, self.estimate_names)
        self._plan = _Plan(task, source)
        self._encode = self._plan.compile(len(task.goal_names))
        low = list(self._plan.low)
        labels = list(self._plan.labels)
        low += [-task.goal_bound] * len(task.goal_names)
        labels += list(task.goal_names)
        if observation == "estimate+diagnostics":
            self._diag_bounds = [task.bound(k) for k in self.diagnostic_names]
            low += [-b for b in self._diag_bounds]
            labels += [f"diagnostic:{k}" for k in self.diagnostic_names]
        self.observation_names = tuple(labels)
        lo = np.array(low, dtype=np.float64)
        self.observation_space = spaces.Box(lo, -lo, dtype=np.float64)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(nu,), dtype=np.float32)
        self._nu = nu
        self._scale = task.max_action
        self._mode = {"estimate": 0, "estimate+diagnostics": 0, "true": 1, "measurement": 2}[
            observation]
        self._diag_on = observation == "estimate+diagnostics"

        # ---- run-time state (Python floats: a step builds arrays only for what it returns)
        self._goal: tuple[float, ...] = ()
        #: the last measurement and the observer's estimate, lists of floats
        self._y: list[float] = [0.0] * len(self.output_names)
        self._y_held: list[float] = [0.0] * len(self.output_names)
        self._x_hat: list[float] | None = None
        self._apply = [s.apply_list for s in self.sensor.stages]
        self._rng = self.sensor.rng
        self._update = None if self.observer is None else _list_update(self.observer)
        lean = (self._mode == 0 and not self._diag_on and not self._full_info
                and record_path is None)
        #: what a step needs, in one attribute (unpacked at once: a step has microseconds)
        self._hot = (nu, self._scale, self._io.step, self._io.read_y, self._io.read_x,
                     self._update, self._apply, ts, self._n_samples, task, lean,
                     getattr(self, "_err", None), self._encode)
        self._episode = -1
        self._recorder: Any = None
        self.record_path = None if record_path is None else Path(record_path)
        self._rec_rows: dict[str, list[Any]] | None = None
        if self.record_path is not None:
            self._open_recorder()

    # ------------------------------------------------------------------ construction
    def _make_task(self, task: Task | None, task_kwargs: Mapping[str, Any]) -> Task:
        if task is not None:
            if not isinstance(task, Task):
                raise DesignError(f"task must be a Task; found {type(task).__name__}")
            if task_kwargs:
                raise DesignError(f"give task parameters {sorted(task_kwargs)} to the Task, not "
                                  f"beside an explicit task=")
            return task
        cls = self.task_class
        if cls is None:
            raise DesignError(f"{type(self).__name__} needs task= (it has no default task)")
        sig = inspect.signature(cls.__init__)
        known = [p for p in sig.parameters if p != "self"]
        bad = [k for k in task_kwargs if k not in known]
        if bad:
            loop = [p for p in inspect.signature(HgoEnv.__init__).parameters
                    if p not in ("self", "task_kwargs")]
            raise DesignError(f"{type(self).__name__}: unknown argument(s) {bad}; valid: "
                              f"{sorted(loop + known)}")
        return cls(**task_kwargs)

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
        return self.build_observer(kind, system, params)

    def default_observer_kind(self) -> str:
        """The observer used by ``observer="default"`` (the task's, if registered)."""
        return self.task.default_observer

    def observer_params(self, kind: str) -> dict[str, Any]:
        """The task's default parameters for a registered observer ``kind``, restricted to the
        ones its constructor accepts (empty if the task has none for it)."""
        if kind not in OBSERVERS:
            raise DesignError(f"unknown observer {kind!r}; valid: {sorted(OBSERVERS)}")
        return _accepted(OBSERVERS[kind], self.task.observer_defaults.get(kind, {}))

    def build_observer(self, kind: str, system: Any, params: Mapping[str, Any]) -> Observer:
        """``make_observer(kind, system, **params)`` over the task's defaults for ``kind``."""
        if not isinstance(kind, str) or kind not in OBSERVERS:
            raise DesignError(f"unknown observer {kind!r}; valid: {sorted(OBSERVERS)}")
        return make_observer(kind, system, **{**self.observer_params(kind), **params})

    def _check_instance(self, obs: Observer, system: Any) -> None:
        if obs.system is not None and type(obs.system) is not type(system):
            raise DesignError(f"the observer was designed for {type(obs.system).__name__}; this "
                              f"environment's plant is {type(system).__name__}")
        m = len(self.output_names)
        outs = getattr(obs, "outputs", None)
        if not isinstance(outs, tuple | list) or not outs:
            outs = (getattr(obs, "output", 0),)
        if max(outs) >= m:
            raise DimensionError(f"the observer reads output channel {max(outs)}; the plant has "
                                 f"{m} output(s) {list(self.output_names)}")

    # ------------------------------------------------------------------ the loop
    def _measure(self) -> list[float]:
        y = self._io.read_y()
        if self._apply:
            t = self._io.d.time
            rng = self._rng
            for f in self._apply:
                y = f(t, y, rng)
        return y

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

        Returns
        -------
        observation : ndarray
        info : dict
            ``time``, ``state``, ``measurement`` and, with an observer, ``estimate``, ``error``
            and ``diagnostics`` (see :attr:`error_names`); ``goal`` for the reach tasks.
        """
        super().reset(seed=seed)
        if self._rec_rows is not None:
            if self._rec_rows["t"]:
                self._write_episode()
            self._rec_seed = seed
        reset_chain(self.sensor, seed)
        self._rng = self.sensor.rng  # a new generator after a seeded reset
        task, rng = self.task, self.np_random
        x0 = task.initial_state(rng)
        goal = task.sample_goal(rng)
        if options:
            x0, goal = self._options(options, x0, goal)
        self._goal = goal
        self._io.reset(x0)
        obs = self.observer
        if obs is not None:
            obs.reset()
            xh = getattr(obs, "x_hat_list", None)
            self._x_hat = xh() if xh is not None else np.asarray(obs.x_hat, dtype=float).tolist()
        y = self._measure()
        self._y = y
        if self._mode == 2:
            self._y_held = [v if v == v else 0.0 for v in y]
        self._episode += 1
        xl = self._io.read_x()
        info = self._info(xl, y, self._x_hat, 0.0)
        if self._rec_rows is not None:
            self._record_row(0.0, np.array(xl), np.array(y), None, 0.0)
        return self._observe(xl, y, self._x_hat), info

    def _options(self, options: Mapping[str, Any], x0: list[float], goal: tuple[float, ...]
                 ) -> tuple[list[float], tuple[float, ...]]:
        unknown = [k for k in options if k not in ("x0", "goal")]
        if unknown:
            raise DesignError(f"unknown reset option(s) {unknown}; valid: ['goal', 'x0']")
        if options.get("x0") is not None:
            x0 = vector("options['x0']", options["x0"], len(self.state_names)).tolist()
        if options.get("goal") is not None:
            names = self.task.goal_names
            g = vector("options['goal']", options["goal"], len(names))
            goal = tuple(g.tolist())
        return x0, goal

    def step(self, action: Any) -> tuple[Array, float, bool, bool, dict[str, Any]]:
        """Hold ``u = action * max_action`` over one control period (see the module docstring).

        Returns
        -------
        observation, reward, terminated, truncated, info
            ``truncated`` is always False here: the time limit is ``TimeLimit``'s. ``info`` as
            at :meth:`reset`, plus the task's reward terms ``reward_<term>``.
        """
        try:
            na = len(action)
        except TypeError:
            raise DimensionError(f"action must be a sequence of {self._nu} number(s); found "
                                 f"{action!r}") from None
        (nu, scale, io_step, read_y, read_x, update, apply, ts, n_samples, task, lean,
         err, encode) = self._hot
        if na == 1 == nu:
            v = float(action[0])
            if not -1.0 <= v <= 1.0:
                v = self._invalid(0, v)
            u = [v * scale[0]]
        else:
            if na != nu:
                raise DimensionError(f"action must have {nu} entries; found {na}")
            u = []
            for i, sc in enumerate(scale):
                v = float(action[i])
                if not -1.0 <= v <= 1.0:
                    v = self._invalid(i, v)
                u.append(v * sc)
        y, x_hat, rng = self._y, self._x_hat, self._rng
        t = 0.0
        for _ in range(n_samples):
            if update is not None:
                x_hat = update(y, u, ts)
            t = io_step(u)
            y = read_y()
            for f in apply:
                y = f(t, y, rng)
        self._y, self._x_hat = y, x_hat
        xl = read_x()
        goal = self._goal
        reward, terms = task.reward(xl, u, goal)
        if lean:  # estimate observation, basic info, no recording: the common case, inline
            if not math.isfinite(sum(x_hat)):  # type: ignore[arg-type]
                self._observe(xl, y, x_hat)  # raises DivergenceError
            return (np.array(encode(x_hat, goal)), reward, task.terminated(xl), False,
                    {"state": np.array(xl), "estimate": np.array(x_hat),
                     "error": np.array(err(xl, x_hat))})
        info = self._info(xl, y, x_hat, t)
        if self._full_info:
            info.update(terms)
        if self._rec_rows is not None:
            self._record_row(t, np.array(xl), np.array(y), np.array(u), reward)
        return self._observe(xl, y, x_hat), reward, task.terminated(xl), False, info

    def _invalid(self, i: int, v: float) -> float:
        """An action entry outside [-1, 1]: NaN raises; clip or raise as configured."""
        if v != v:
            raise DesignError(f"action[{i}] is NaN")
        if not self._clip:
            raise DesignError(f"action[{i}] = {v:g} is outside the action space [-1, 1] "
                              f"(invalid_action='raise')")
        return 1.0 if v > 1.0 else -1.0

    def _observe(self, xl: list[float], y: list[float], x_hat: list[float] | None) -> Array:
        mode = self._mode
        if mode == 0:
            vals = x_hat
            if not math.isfinite(sum(vals)):  # type: ignore[arg-type]
                raise DivergenceError(f"the observer's estimate left the finite numbers at "
                                      f"t={self._io.d.time:g}: {vals}")
        elif mode == 1:
            vals = xl
        else:
            vals = self._y_held
            for i, v in enumerate(y):
                if v == v:
                    vals[i] = v
        out = self._encode(vals, self._goal)
        if self._diag_on:
            d = self.observer.diagnostics()  # type: ignore[union-attr]
            for k, b in zip(self.diagnostic_names, self._diag_bounds):
                v = float(d.get(k, 0.0))
                if v != v:  # not defined yet (an excitation measure before its window fills)
                    v = 0.0
                out.append(b if v > b else -b if v < -b else v)
        return np.array(out)

    def _info(self, xl: list[float], y: list[float], x_hat: list[float] | None, t: float
              ) -> dict[str, Any]:
        if x_hat is None:
            info: dict[str, Any] = {"state": np.array(xl)}
        else:
            info = {"state": np.array(xl), "estimate": np.array(x_hat),
                    "error": np.array(self._err(xl, x_hat))}
        if self._full_info:
            info["time"] = t
            info["measurement"] = np.array(y)
            if x_hat is not None:
                info["diagnostics"] = dict(self.observer.diagnostics())  # type: ignore[union-attr]
            if self._goal:
                info["goal"] = np.array(self._goal)
        return info

    # ------------------------------------------------------------------ recording (issue 6)
    def _open_recorder(self) -> None:
        """Open the rerun recording of ``record_path`` (:mod:`hgo_mj.record`, issue 6).

        The observer's estimate columns are named by its own ``state_names``
        (:attr:`estimate_names`): the states it estimates go next to the truth under
        ``/state`` and ``/error``, the others (derivatives of a model-free observer, ...) under
        ``/observer/<obs>/estimate``, and its ghost poses the joints it estimates."""
        try:
            from hgo_mj.record import Recorder
        except ImportError as exc:  # pragma: no cover - record.py is issue 6's
            raise DesignError(f"record_path needs hgo_mj.record (rerun recordings); {exc}") from None
        obs = self.observer
        names = [] if obs is None else [obs.name or type(obs).__name__]
        states = {names[0]: self.estimate_names} if names else None
        self._recorder = Recorder.for_plant(self.record_path, self.plant, observers=names,
                                            observer_states=states,
                                            recording_name=type(self).__name__)
        self._rec_rows = {k: [] for k in ("t", "x", "y", "y_clean", "u", "x_hat", "diag",
                                          "reward")}
        self._rec_seed: int | None = None
        #: per finished episode: its seed and metrics (the ``/metrics`` document)
        self._rec_episodes: list[dict[str, Any]] = []

    def _record_row(self, t: float, x: Array, y: Array, u: Array | None, reward: float) -> None:
        rows = self._rec_rows
        assert rows is not None
        rows["t"].append(t)
        rows["x"].append(x)
        rows["y"].append(y)
        # the plant has not moved since ``y`` was measured: the same read, before the sensor
        rows["y_clean"].append(np.array(self._io.read_y(), dtype=float))
        rows["u"].append(np.zeros(self._nu) if u is None else u)
        rows["reward"].append(reward)
        if self.observer is not None:
            rows["x_hat"].append(np.array(self._x_hat, dtype=float))
            rows["diag"].append(dict(self.observer.diagnostics()))

    def recording_metadata(self) -> dict[str, Any]:
        """What a recording's ``/scenario`` document holds: the environment (registered id,
        class), task, observation, periods, integrator, plant, sensor chain, observer (name,
        type, parameters), the seed of every episode recorded so far, package versions."""
        from hgo_mj.simulate import package_versions

        from . import ENVIRONMENTS

        spec = getattr(self, "spec", None)
        env_id = spec.id if spec is not None else next(
            (k for k, c in ENVIRONMENTS.items() if c is type(self)), None)
        obs = self.observer
        observers = {}
        if obs is not None:
            observers[obs.name or type(obs).__name__] = {
                "type": type(obs).__name__, "state_names": list(self.estimate_names),
                **obs.params()}
        episodes = getattr(self, "_rec_episodes", [])
        seeds = [e["seed"] for e in episodes]
        return {
            "scenario": env_id or type(self).__name__,
            "environment": {"id": env_id, "class": f"{type(self).__module__}."
                                                    f"{type(self).__qualname__}"},
            "task": {"class": type(self.task).__name__, **self.task.params()},
            "plant": type(self.plant.system).__name__,
            "system_params": self.plant.system.params,
            "seed": seeds[0] if seeds else getattr(self, "_rec_seed", None),
            "seeds": {str(e["episode"]): e["seed"] for e in episodes},
            "observation": self.observation_mode,
            "physics_dt": self.physics_dt, "sample_period": self.sample_period,
            "control_period": self.control_period, "integrator": self.integrator,
            "sensor": self.sensor.describe(),
            "observers": observers,
            "versions": package_versions(),
        }

    def _episode_metrics(self, rows: Mapping[str, list[Any]]) -> dict[str, Any]:
        """Seed, length, return and estimation error of the finished episode."""
        steps = len(rows["t"]) - 1
        out: dict[str, Any] = {"episode": self._episode, "seed": self._rec_seed, "steps": steps,
                               "return": float(np.sum(rows["reward"][1:])),
                               "terminated": bool(self.task.terminated(list(rows["x"][-1])))}
        if self.observer is not None:
            x, xh = np.array(rows["x"]), np.array(rows["x_hat"])
            rmse: dict[str, float] = {}
            final: dict[str, float] = {}
            for j, i in self._err_pairs:
                e = x[:, j] - xh[:, i]
                ok = np.isfinite(e)
                rmse[self.state_names[j]] = (float(np.sqrt(np.mean(e[ok] ** 2))) if ok.any()
                                             else math.nan)
                final[self.state_names[j]] = float(abs(e[-1]))
            out["rmse"] = rmse
            out["final_error"] = final
        return out

    def _write_episode(self) -> None:
        """Hand the finished episode to the recorder in one batch, then its metrics (the
        ``/metrics`` table, one row per episode so far) and the scenario with every episode's
        seed (``/scenario``); clear the buffer."""
        rows = self._rec_rows
        if rows is None or not rows["t"]:
            return
        rec = self._recorder
        est = diag = None
        if self.observer is not None:
            name = rec.observers[0]
            est = {name: np.array(rows["x_hat"])}
            keys = rows["diag"][0].keys()
            diag = {name: {k: np.array([d.get(k, math.nan) for d in rows["diag"]], dtype=float)
                           for k in keys}}
        rec.record_episode(self._episode, np.array(rows["t"]), np.array(rows["x"]),
                           np.array(rows["y"]), np.array(rows["u"]),
                           y_clean=np.array(rows["y_clean"]), estimates=est, diagnostics=diag,
                           extra={"reward": np.array(rows["reward"])})
        self._rec_episodes.append(self._episode_metrics(rows))
        rec.log_metadata(self.recording_metadata())
        rec.log_episode_metrics(self._rec_episodes)
        for v in rows.values():
            v.clear()

    def close(self) -> None:
        """Write the last episode of a recording and close it."""
        if self._recorder is not None:
            self._write_episode()
            self._recorder.close()
            self._recorder = None
            self._rec_rows = None
        super().close()

    # ------------------------------------------------------------------ pickling
    def __reduce__(self) -> tuple[Callable[..., HgoEnv], tuple[Any, ...]]:
        """Pickle as the constructor call (like Gymnasium's MuJoCo environments): the copy is a
        fresh environment to be ``reset``; an observer instance travels in its current state.

        Raises
        ------
        DesignError
            The environment was given an observer instance that does not pickle (one holding
            functions compiled at run time or local closures); an environment given the
            observer by name (``observer="ekf", observer_kwargs=...``) always pickles."""
        kwargs = dict(self._init_kwargs)
        if isinstance(kwargs.get("observer"), Observer):
            obs = kwargs["observer"]  # observers drop their compiled caches when pickled
            try:
                pickle.dumps(obs)
            except (pickle.PicklingError, AttributeError, TypeError) as exc:
                raise DesignError(f"this environment's observer instance "
                                  f"({type(obs).__name__}) does not pickle ({exc}); give the "
                                  f"observer by name (observer={obs.name!r}, observer_kwargs="
                                  f"...) for a picklable environment") from None
        return (_rebuild, (type(self), kwargs))


def _error_function(pairs: Sequence[tuple[int, int]]
                    ) -> Callable[[list[float], list[float]], list[float]]:
    """Straight-line ``error(x, x_hat) -> [x[j] - x_hat[i], ...]`` over the ``(j, i)`` pairs
    of a state and its estimate."""
    items = ", ".join(f"x[{j}] - h[{i}]" for j, i in pairs)
    scope: dict[str, Any] = {}
    exec(compile(f"def error(x, h):\n    return [{items}]\n", "<estimation error>", "exec"),
         scope)  # noqa: S102 - numbers only
    return scope["error"]


def _list_update(obs: Observer) -> Callable[[list[float], list[float], float], list[float]]:
    """``update(y, u, dt) -> estimate`` in lists of floats: the observer's ``update_list`` when
    it has one (the high-gain family, no arrays per sample) and it belongs to the class that
    defines the ``update`` in use; otherwise ``update`` on arrays, its estimate as a list."""
    mro = type(obs).__mro__
    own_list = next((c for c in mro if "update_list" in vars(c)), None)
    own_update = next((c for c in mro if "update" in vars(c)), None)
    if own_list is not None and own_update is not None and issubclass(own_list, own_update):
        return obs.update_list  # type: ignore[attr-defined,no-any-return]
    update = obs.update

    def via_arrays(y: list[float], u: list[float], dt: float) -> list[float]:
        return np.asarray(update(np.array(y), np.array(u), dt), dtype=float).tolist()

    return via_arrays


def _rebuild(cls: type[HgoEnv], kwargs: dict[str, Any]) -> HgoEnv:
    return cls(**kwargs)


def _is_default(value: Any) -> bool:
    return isinstance(value, str) and value == "default"


__all__ = ["HgoEnv", "INFO_LEVELS", "OBSERVATION_MODES", "Task", "chain_seed", "sensor_chain"]
