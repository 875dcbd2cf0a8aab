"""Any hgo_mj observer in the loop of any Gymnasium environment: the agent sees the estimate."""

from __future__ import annotations

import copy
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any, cast

import gymnasium
import mujoco
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded
from numpy.typing import NDArray

from hgo_mj._binding import Binding
from hgo_mj._validate import one_of
from hgo_mj.exceptions import DesignError, DimensionError, DivergenceError
from hgo_mj.loop import check_fits
from hgo_mj.observers import OBSERVERS, Observer, make_observer
from hgo_mj.observers.bank import ObserverBank
from hgo_mj.observers.base import Dimension, Params

from ..core import measurement_start, sensor_chain
from ._common import box_indices, cache_key, cache_path, cache_read, cache_write, env_dt, reset_chain

Array = NDArray[np.float64]

#: what the agent is handed: the estimate that has used the newest measurement, or the
#: prediction made before it
ESTIMATES = ("current", "prediction")


#: what ``observer="auto"`` tunes: model-free kinematic Kalman filters (one per measured
#: signal, :class:`~hgo_mj.observers.KinematicKalmanFilter`) with ``measure=``, the MuJoCo EKF on
#: the environment's MJCF with ``joints=``
AUTO_KINDS = {"measure": "kinematic_kalman", "joints": "ekf_mujoco"}
#: the tuning options (``tuning=``) and their defaults: environment steps of the recorded
#: rollout, trials per study, trials per round (one batch), the seed of the rollout, the
#: sensor noise and the samplers, and the cache file (None: the user cache; False: none)
TUNING = {"steps": 400, "budget": 48, "round": 16, "seed": 0, "cache": None}


def auto_kind(observer: Any, mode: str) -> tuple[bool, str]:
    """``(tuned, kind)`` of an ``observer`` argument: ``"auto"`` is :data:`AUTO_KINDS`'s kind
    for ``mode``, ``"auto:<kind>"`` that kind, tuned; anything else is not tuned."""
    if not isinstance(observer, str) or not (observer == "auto" or observer.startswith("auto:")):
        return False, ""
    kind = observer[5:] or AUTO_KINDS[mode]
    if kind not in OBSERVERS:
        raise DesignError(f"observer {observer!r}: unknown kind {kind!r}; give 'auto' or "
                          f"'auto:<kind>' with a kind of {sorted(OBSERVERS)}")
    return True, kind


def tuning_options(tuning: Mapping[str, Any] | None, auto: bool) -> dict[str, Any] | None:
    """:data:`TUNING` updated by ``tuning`` (None when the observer is not tuned), checked."""
    if not auto:
        if tuning is not None:
            raise DesignError("tuning= goes with observer='auto' or 'auto:<kind>' (a tuned "
                              "observer)")
        return None
    given = dict(tuning or {})
    bad = sorted(set(given) - set(TUNING))
    if bad:
        raise DesignError(f"tuning: unknown option(s) {bad}; valid: {sorted(TUNING)}")
    out = {**TUNING, **given}
    for key, low in (("steps", 10), ("budget", 2), ("round", 1), ("seed", 0)):
        v = out[key]
        if isinstance(v, bool) or not isinstance(v, int) or v < low:
            raise DesignError(f"tuning {key} must be an integer >= {low}; found {v!r}")
    out["cache"] = cache_path(out["cache"])
    return out


def auto_defaults(kind: str, dt: float) -> dict[str, Any]:
    """The constructor parameters a tuning of ``kind`` starts from (its tuning space spans a
    factor of 10 to 10^5 around them): model-free chains of order 2 with ``k = 1 / dt``; the
    model-free kinematic Kalman filters of order 2 at the tracking index
    ``sqrt(q / r) dt^2 = 30`` (``r = 1``: the estimate depends on ``q / r`` alone); the MuJoCo
    Kalman filters with ``Q = 1`` (per environment step); ``high_gain_multi`` with
    ``k = 1 / dt``."""
    return {"high_gain": {"order": 2, "k": 1.0 / dt},
            "kinematic_kalman": {"order": 2, "r": 1.0, "q": (30.0 / dt ** 2) ** 2},
            "ekf_mujoco": {"Q": 1.0}, "ukf_mujoco": {"Q": 1.0},
            "high_gain_multi": {"k": 1.0 / dt}}.get(kind, {})


def default_estimate(observer: Observer) -> str:
    """The estimate handed by default, per observer kind, as ``docs/results/wrappers.md``
    measured it: ``"prediction"`` for a continuous-time observer with a model term (a
    high-gain one with ``model=True`` or a ``phi``: holding the newest sample over the step
    pushes its model-based prediction ahead) and for a bank that mixes Kalman filters with
    continuous-time observers (the one mode that applies to both); ``"current"`` for every
    other (Kalman filters: the measurement update; model-free chains).

    Parameters
    ----------
    observer : Observer
        An observer, or a bank of them.

    Returns
    -------
    str
        ``"current"`` or ``"prediction"``.

    Examples
    --------
    >>> from hgo_mj.observers import HighGainObserver
    >>> default_estimate(HighGainObserver(order=2, k=10.0))
    'current'
    """
    members = getattr(observer, "members", (observer,))
    if len({bool(o.measurement_update) for o in members}) > 1:
        return "prediction"
    modelled = any(not o.measurement_update and (getattr(o, "model", None) is True or callable(
        getattr(o, "phi", None))) for o in members)
    return "prediction" if modelled else "current"


def record_rollout(env: gymnasium.Env, steps: int, seed: int,
                   read: Callable[[Any, Any], dict[str, Array]],
                   control: Callable[[Any, Any], Array]) -> list[dict[str, Array]]:
    """A rollout of ``env`` with seeded uniformly random actions for ``steps`` steps in all,
    reset (``seed + episode``) when an episode ends: per episode, each of ``read(env, obs)``'s
    arrays at the reset and after every step ``(T + 1, ...)``, and ``"u"``:
    ``control(env, action)`` of every step ``(T, ...)``. Episodes of fewer than 2 steps are
    dropped."""
    env.action_space.seed(seed)
    episodes: list[dict[str, Array]] = []
    cur: dict[str, list[Any]] = {}
    done, k, e = True, 0, 0
    while k < steps:
        if done:
            if len(cur.get("u", ())) >= 2:
                episodes.append({key: np.array(v, dtype=float) for key, v in cur.items()})
            obs, _ = env.reset(seed=seed + e)
            e += 1
            cur = {key: [v] for key, v in read(env, obs).items()}
            cur["u"] = []
        action = env.action_space.sample()
        obs, _, terminated, truncated, _ = env.step(action)
        for key, v in read(env, obs).items():
            cur[key].append(v)
        cur["u"].append(control(env, action))
        done, k = bool(terminated or truncated), k + 1
    if len(cur.get("u", ())) >= 2:
        episodes.append({key: np.array(v, dtype=float) for key, v in cur.items()})
    if not episodes:
        raise DesignError(f"the tuning rollout of {steps} steps had no episode of 2 steps or "
                          f"more: give tuning={{'steps': ...}} more")
    return episodes


def signal_velocities(episodes: list[dict[str, Array]], model: Any, dt: float) -> None:
    """Add ``"v"``, the true velocity of each measured signal ``"y"``, to every episode: the
    ``qvel`` of the hinge or slide joint whose ``qpos`` the signal equals at every recorded
    instant (``"q"``, ``"qd"`` recorded on a MuJoCo environment), else the central difference
    of the clean signal (``numpy.gradient``)."""
    p = episodes[0]["y"].shape[1]
    # ints: ``numpy.int32(3) in (mujoco.mjtJoint.mjJNT_HINGE,)`` is False (the enum's __eq__)
    kinds = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    joints = [] if model is None else [
        (int(model.jnt_qposadr[i]), int(model.jnt_dofadr[i])) for i in range(model.njnt)
        if int(model.jnt_type[i]) in kinds]
    match: list[int | None] = []
    for c in range(p):
        same = [dof for adr, dof in joints
                if all(np.array_equal(ep["y"][:, c], ep["q"][:, adr]) for ep in episodes)]
        match.append(same[0] if len(same) == 1 else None)
    for ep in episodes:
        v = np.empty_like(ep["y"])
        for c, dof in enumerate(match):
            v[:, c] = ep["qd"][:, dof] if dof is not None else np.gradient(ep["y"][:, c], dt)
        ep["v"] = v


def tied_space(ob: Observer, n_pos: int) -> tuple[dict[str, Dimension], dict[str, list[str]]]:
    """The observer's tuning space with the entries of a parameter tied (one search variable
    each): a covariance's position entries (the first ``n_pos``), its velocity entries, a gain
    vector's entries. A MuJoCo filter of Walker2d has 27 entries in its space; TPE finds little
    in 27 dimensions with a few dozen trials, and the tied three (``Q[positions]``,
    ``Q[velocities]``, ``R[*]``) carry most of what a tuning gains."""
    base = ob.tuning_space()
    groups: dict[str, list[str]] = {}
    for key in base:
        name, _, index = key.partition("[")
        if index and name == "Q" and int(index.rstrip("]")) < 2 * n_pos:
            group = f"Q[{'positions' if int(index.rstrip(']')) < n_pos else 'velocities'}]"
        else:
            group = f"{name}[*]" if index else key
        groups.setdefault(group, []).append(key)
    space = {g: Dimension(g, base[k[0]].low, base[k[0]].high, base[k[0]].log, base[k[0]].default)
             for g, k in groups.items()}
    return space, groups


def estimates(ob: Observer, params: Any, start: dict[str, Any], Y: Array, U: Array,
              dt: float, mode: str) -> Array:
    """The estimates ``(B, T, n_x)`` at ``t_1 .. t_T`` of the members ``params`` started at
    ``start`` (``x_hat0`` or ``z_hat0``) over the samples ``Y`` ``(T + 1, p)`` and inputs ``U``
    ``(T, m)``, handed as the wrapper hands them (``mode``): ``"lead"`` (integrating over each
    step with the sample at its end), ``"prediction"`` (with the sample at its start), or
    ``"filter"`` (a Kalman filter's measurement update with the sample at the step's end)."""
    B, T = params_batch(params), U.shape[0]
    if mode == "filter":
        ob.reset(**start, params=params)
        out = np.empty((B, T, len(ob.state_names)))
        for k in range(T):
            ob.update(np.tile(Y[k], (B, 1)), np.tile(U[k], (B, 1)), dt)
            out[:, k] = ob.filtered(np.tile(Y[k + 1], (B, 1)))
        return out
    rows = Y[1:] if mode == "lead" else Y[:-1]
    state = ob.init(B, params=params, **start)
    _, block = ob.step(params, state, np.tile(rows, (B, 1, 1)), np.tile(U, (B, 1, 1)), dt)
    return block.x_hat


def params_batch(params: Any) -> int:
    """The batch of a :class:`~hgo_mj.observers.base.Params` (a bank's: its first member's)."""
    members = getattr(params, "members", None)
    return params_batch(members[0]) if members is not None else int(
        next(iter(params.fields.values())).shape[0])


class MujocoTap:
    """The wrapper's hold on a Gymnasium MuJoCo environment (``joints=``), through public
    attributes only: the measured joints' positions read from ``env.unwrapped.data`` after each
    ``env.step``, and the observation entries that are a joint's position or velocity.

    The observers design against the environment's own MJCF (``env.unwrapped.fullpath``, read
    by :func:`hgo_mj.systems.mjcf.mjcf_system` with the measured joints as outputs): the MuJoCo
    Kalman filters step that model, checked to have the environment's sizes and time step.

    **Once per environment step.** The observer takes one sample per ``env.step`` (at the
    environment's ``dt``); sampling at every physics step inside the frame skip is not offered.
    It needs a hook inside the environment's own stepping: Gymnasium has no public one (its
    ``_step_mujoco_simulation`` is private), stepping the physics here with ``mj_step`` would
    bypass the environment's own ``step`` (its rewards, terminations and wrappers), and MuJoCo's
    documented hook ``mujoco.set_mjcb_control`` is one process-global slot, called for every
    model in the process (the MuJoCo filters' own models included, several times per sample for
    their Jacobians), from every ``mj_forward`` (resets, renders) and, with RK4, four times a
    step, and raced by threads (``mj_step`` releases the GIL). At the environment's rate the
    MuJoCo EKF beats a backward difference on all six environments of
    ``docs/results/wrappers.md``.

    The observation entries are found on a fresh copy of the environment
    (``gymnasium.make(env.spec)``): an entry is a joint's position or velocity when it equals
    it, and no other, after a seeded reset and two random steps (the environment given is not
    touched).

    Parameters
    ----------
    env : gymnasium.Env
        A Gymnasium MuJoCo environment made by ``gymnasium.make`` (``env.unwrapped`` has
        ``model``, ``data``, ``fullpath`` and ``frame_skip``; ``env.spec`` is set).
    joints : sequence of str
        The measured joints (hinge or slide), by MJCF name.

    Raises
    ------
    DesignError
        ``env`` is not a Gymnasium MuJoCo environment made by ``gymnasium.make``;
        :class:`~hgo_mj.exceptions.ModelError` for a joint the model does not have (the valid
        names listed) or a model with ball or free joints.
    """

    def __init__(self, env: gymnasium.Env, joints: Sequence[str]) -> None:
        from hgo_mj.systems.mjcf import mjcf_system

        u: Any = env.unwrapped
        missing = [a for a in ("model", "data", "fullpath", "frame_skip") if not hasattr(u, a)]
        if missing or not isinstance(getattr(u, "model", None), mujoco.MjModel):
            raise DesignError(f"joints= needs a Gymnasium MuJoCo environment; "
                              f"{type(u).__name__} has no {missing or ['MjModel']} (use "
                              f"measure= instead)")
        if env.spec is None:
            raise DesignError(f"joints= needs an environment made by gymnasium.make ("
                              f"{type(u).__name__} has no spec to make a probe copy from)")
        self.env: Any = u
        self.spec = env.spec
        self.joints = tuple(joints)
        self.system = mjcf_system(u.fullpath, list(joints))()
        m = u.model
        #: the environment's model names bound to ids and addresses (the one binding)
        self.binding = Binding(m, f"the model of {u.fullpath!r}")
        self.qadr = self.binding.qpos(self.joints)
        self.h = float(m.opt.timestep)
        own = self.system.model
        if (own.nq, own.nv, own.nu, float(own.opt.timestep)) != (m.nq, m.nv, m.nu, self.h):
            raise DesignError(f"the environment's MjModel differs from its MJCF file "
                              f"{u.fullpath!r} (nq, nv, nu, timestep: {(m.nq, m.nv, m.nu, self.h)} "
                              f"against {(own.nq, own.nv, own.nu, float(own.opt.timestep))}): the "
                              f"observers could not model it")
        #: qpos and qvel addresses of the system's joints (its state: positions, velocities)
        self.state_qpos = self.binding.qpos(self.system.joints).tolist()
        self.state_qvel = self.binding.dofs(self.system.joints).tolist()
        self.entries = self._probe()

    def fresh(self) -> Any:
        """A new instance of the environment (``gymnasium.make(env.spec)``)."""
        return gymnasium.make(self.spec)

    def state(self, data: Any) -> Array:
        """The system's state (joint positions, then velocities) in ``data``."""
        return np.concatenate([data.qpos[self.state_qpos], data.qvel[self.state_qvel]])

    def _probe(self) -> dict[int, int]:
        """Observation entry -> index in the system's state, for the entries equal to one and
        no other after a seeded reset and two random steps of a fresh copy."""
        env = self.fresh()
        try:
            env.action_space.seed(12345)
            obs, _ = env.reset(seed=12345)
            hits: dict[int, set[int]] | None = None
            for k in range(3):
                state = self.state(env.unwrapped.data)
                now = {i: set(np.flatnonzero(np.abs(state - v) <= 1e-12).tolist())
                       for i, v in enumerate(np.asarray(obs, dtype=float).reshape(-1))}
                hits = now if hits is None else {i: hits[i] & now[i] for i in hits}
                if k < 2:
                    obs = env.step(env.action_space.sample())[0]
        finally:
            env.close()
        assert hits is not None
        return {i: next(iter(s)) for i, s in hits.items() if len(s) == 1}

    def measure(self) -> Array:
        """The measured joints' positions now (a fresh array)."""
        return np.array(self.env.data.qpos[self.qadr], dtype=np.float64)

    def controls(self) -> Array:
        """The controls the environment applied over its last step (``data.ctrl``)."""
        return np.array(self.env.data.ctrl, dtype=np.float64)


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

    * ``"current"``: the estimate at ``t_k+1`` that has used ``y_k+1``, the newest
      measurement. A continuous-time observer (every family but the Kalman filters)
      integrates over the step with ``y_k+1`` held (the measurement at the step's end, in
      place of the one at its start: no sample of delay); a Kalman filter predicts with
      ``y_k`` and hands ``x_k+1|k+1``, its measurement update with ``y_k+1``
      (:meth:`~hgo_mj.observers.Observer.filtered`).
    * ``"prediction"``: the observer integrates over the step with ``y_k`` held and hands
      its prediction of ``x(t_k+1)`` made before ``y_k+1`` (every sample a step late, as a
      sampled observer runs in hgo_mj's loop).

    The default is the one measured better per observer kind (:func:`default_estimate`,
    ``docs/results/wrappers.md``): the current estimate for the Kalman filters and model-free
    chains, the prediction for a continuous-time observer with a model term (``high_gain_multi``
    with ``model=True``). The agent's observation is that estimate, rearranged by ``layout``.

    **Tuned observers.** ``observer="auto"`` tunes the observer for this environment and
    sensor: model-free kinematic Kalman filters of order 2
    (:class:`~hgo_mj.observers.KinematicKalmanFilter`, the alpha-beta filter in steady state),
    one per measured signal, with ``measure=``;
    the MuJoCo EKF on the environment's MJCF with ``joints=`` (:data:`AUTO_KINDS`).
    ``observer="auto:<kind>"`` tunes a named kind instead (e.g. ``"auto:high_gain_multi"``),
    ``observer_kwargs`` fixing what is not searched and the point the search starts from
    (default :func:`auto_defaults`). The wrapper rolls out a fresh copy of the environment
    (``gymnasium.make(env.spec)``: the one given is not touched) with seeded random actions,
    records the measured signals, their true velocities (a joint's ``qvel``; for a signal that
    is no joint position, the central difference of the clean signal) and the inputs, draws
    the sensor's noise on the recording, and searches the kind's tuning space
    (:meth:`~hgo_mj.observers.Observer.tuning_space`) with Optuna's TPE (seeded), each round
    of candidates one batch of the observer's pure step over the recording, scored by the RMS
    velocity error of the estimate handed: each chain is a study of its own (its error
    depends on its gain alone), a MuJoCo observer one study with its covariance entries tied
    (:func:`tied_space`). The result is cached in a JSON file (``tuning={"cache": path}``;
    default ``$XDG_CACHE_HOME/hgo_mj/tuned.json``, else ``~/.cache/hgo_mj/tuned.json``;
    ``False``: no cache), keyed by the environment's id and arguments, what is measured (a
    ``measure`` function by its qualified name), the sensor spec, the kind and its parameters,
    the estimate handed and the tuning options: a second wrapper of the same reads it and
    rolls nothing out. :attr:`tuned` holds the result.

    **On Gymnasium's MuJoCo environments** give ``joints=`` instead of ``measure=``: the
    named joints' positions are read from ``env.unwrapped.data`` after each environment step
    (public attributes only, :class:`MujocoTap`; once per step: the physics-rate sampling
    inside the frame skip is not offered) and measured through the sensor chain; the
    observer (default ``"ekf_mujoco"``; any registered name that applies, e.g.
    ``"high_gain_multi"`` with ``model=True``) designs against the environment's own MJCF
    (``env.unwrapped.fullpath``) and reads the controls; the agent's observation is the
    environment's own, in its own space, with every entry that is a joint's position or
    velocity replaced by the estimate (:attr:`observation_names` from the MJCF joints) and the
    other entries (a target, contact forces, cos/sin of angles) kept.
    ``docs/results/wrappers.md`` compares it with a backward difference. The environment must
    come from ``gymnasium.make`` (its ``spec`` makes the probe copy, :class:`MujocoTap`).

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
        signal estimates it and its velocity; ``"kinematic_kalman"`` with
        ``{"order": 2, "q": ..., "r": ...}``: a discrete Kalman filter per signal, which beats
        the backward difference where the high-gain chains only reach it
        (``docs/results/wrappers.md``). Or an observer instance (e.g. one designed
        against an hgo_mj system), or several, each reading its own channel; their estimates
        are concatenated. Instances are deep-copied: the wrapper (and each copy of it in a
        vector environment) runs an observer of its own; read it as ``wrapper.observer``.
        Or ``"auto"`` / ``"auto:<kind>"``: tuned for this environment and sensor (above).
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
        Initial estimate at ``reset``: from the first measurement (default;
        :func:`hgo_mj.envs.core.measurement_start`: each estimated coordinate a channel
        measures at its value, the derivatives and the others at zero), or the observer's own
        initial estimate (zero for the chains built from a name; an instance's constructor
        ``x_hat0``). With ``joints=`` the observer always starts from the first measurement
        of the joints (the model's ``qpos0`` for the others).
    dt : float, optional
        Time between observations; default ``env.unwrapped.dt`` (MuJoCo environments).
    bound : float
        Half width of the observation space (the estimate is clipped to it; ``info`` keeps
        the unclipped value). With ``joints=`` the environment's own space is kept.
    substeps : bool
        Only ``False``: ``True`` (sampling at every physics step inside the frame skip) is
        refused, with the reason (:class:`MujocoTap`).
    estimate : {"current", "prediction"}, optional
        The estimate that has used the newest measurement, or the prediction made before it
        (see above); default per observer kind (:func:`default_estimate`).
    tuning : mapping, optional
        With ``observer="auto"``: options of the tuning (:data:`TUNING`): ``steps`` of the
        rollout, ``budget`` (trials per study), ``round`` (trials per batch), ``seed`` and
        ``cache`` (a path, None for the user cache, False for none).

    Raises
    ------
    DesignError
        A bad argument (one line naming it and what is expected): neither or both of
        ``measure`` and ``joints``, ``substeps=True``, an unknown ``auto:<kind>``, ``tuning``
        without ``"auto"`` or with an unknown option, an environment not made by
        ``gymnasium.make`` for ``joints=`` or ``"auto"``, an observer that does not apply.

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

    The same environment through its joints, the MuJoCo EKF sampling once per step:

    >>> env = ObserverInTheLoop(gymnasium.make("InvertedPendulum-v5"), joints=["slider", "hinge"],
    ...                         sensor=[{"stage": "gaussian", "std": 1e-3}])
    >>> env.observation_names
    ('slider_position', 'hinge_angle', 'slider_velocity', 'hinge_velocity')
    >>> obs, info = env.reset(seed=0)
    >>> obs, reward, terminated, truncated, info = env.step(np.zeros(1, dtype=np.float32))
    >>> bool(abs(obs[2] - info["true_observation"][2]) < 0.1)
    True

    Tuned for this environment and sensor (a short search here; cached unless ``cache`` is
    ``False``):

    >>> env = ObserverInTheLoop(gymnasium.make("InvertedPendulum-v5"), measure=(0, 1),
    ...                         observer="auto", sensor=[{"stage": "gaussian", "std": 1e-3}],
    ...                         tuning={"steps": 60, "budget": 4, "cache": False})
    >>> env.tuned["kind"], len(env.tuned["values"]), env.estimate
    ('kinematic_kalman', 2, 'current')
    """

    def __init__(self, env: gymnasium.Env,
                 measure: Sequence[int] | Callable[..., Any] | None = None, *,
                 joints: Sequence[str] | None = None,
                 observer: str | Observer | Sequence[Observer] | None = None,
                 observer_kwargs: Mapping[str, Any] | None = None, sensor: Any = None,
                 layout: Sequence[int] | None = None,
                 input: Callable[[Any], Any] | None = None,  # noqa: A002 - the observer's u
                 init: str = "measurement", dt: float | None = None, bound: float = 1e6,
                 substeps: bool = False, estimate: str | None = None,
                 tuning: Mapping[str, Any] | None = None) -> None:
        gymnasium.utils.RecordConstructorArgs.__init__(
            self, measure=measure, joints=joints, observer=observer,
            observer_kwargs=observer_kwargs, sensor=sensor, layout=layout, input=input,
            init=init, dt=dt, bound=bound, substeps=substeps, estimate=estimate, tuning=tuning)
        super().__init__(env)
        if (measure is None) == (joints is None):
            raise DesignError("give measure= (observation entries, or a function of the "
                              "environment) or joints= (MuJoCo joint names), one of them")
        if init not in ("measurement", "zero"):
            raise DesignError(f"init must be 'measurement' or 'zero'; found {init!r}")
        if not isinstance(substeps, bool):
            raise DesignError(f"substeps must be true or false; found {substeps!r}")
        if substeps:
            raise DesignError("substeps=True (sampling inside the frame skip) is not supported: "
                              "it needs a hook inside the environment's own stepping, which "
                              "Gymnasium does not offer publicly; joints= samples once per "
                              "environment step (substeps=False)")
        self._estimate = None if estimate is None else one_of("estimate", estimate, ESTIMATES)
        self.estimate = "current"
        auto, kind = auto_kind(observer, "joints" if joints is not None else "measure")
        self._tuning = tuning_options(tuning, auto)
        #: the tuning of an ``observer="auto"`` (None: not tuned): kind, search values,
        #: scores, whether read from the cache (see :meth:`_autotune`)
        self.tuned: dict[str, Any] | None = None
        self._sensor_spec = sensor
        self.sensor = sensor_chain(sensor)
        self._input = input
        self._init = init
        self.tap: MujocoTap | None = None
        self._renderer: Any = None
        #: the sensor's clock, the newest measurement and whether the environment was reset
        self._t, self._y, self._ready = 0.0, np.empty(0), False
        #: how a step feeds the observer (:meth:`_order`)
        self._lead, self._filter = False, False
        if joints is not None:
            self._setup_joints(env, joints, kind if auto else observer, observer_kwargs,
                               layout=layout, input=input, dt=dt)
            self._order()
            if auto:
                self._autotune(kind, observer_kwargs, joints=list(joints))
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
        if auto:
            fn: Any = measure if hasattr(measure, "__qualname__") else type(measure)
            key = (f"{fn.__module__}.{fn.__qualname__}" if callable(measure)
                   else list(self._idx))  # type: ignore[arg-type]
            self._autotune(kind, observer_kwargs, measure=key, channels=probe)
        else:
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
        """:attr:`estimate` (the argument, else :func:`default_estimate` of the observer) and
        how a step feeds the observer for it: ``_lead`` (a continuous-time observer integrates
        over the step with the sample at its end) or ``_filter`` (a Kalman filter hands its
        measurement update with the newest sample)."""
        members = getattr(self.observer, "members", (self.observer,))
        kinds = {bool(o.measurement_update) for o in members}
        self.estimate = self._estimate or default_estimate(self.observer)
        current = self.estimate == "current"
        if current and len(kinds) > 1:
            raise DesignError("estimate='current' needs observers of one kind: Kalman filters "
                              "(a measurement update) or continuous-time observers; this bank "
                              "mixes them (give estimate='prediction', or one kind)")
        self._filter = current and kinds == {True}
        self._lead = current and not self._filter

    def _setup_joints(self, env: gymnasium.Env, joints: Sequence[str], observer: Any,
                      observer_kwargs: Mapping[str, Any] | None, **generic: Any) -> None:
        """``joints=``: the MuJoCo tap, the observer designed against the environment's own
        MJCF, and the environment's observation space and layout kept."""
        given = [k for k, v in generic.items() if v is not None]
        if given:
            raise DesignError(f"{given} go with measure=; with joints= the observation keeps "
                              f"the environment's layout, the observer reads the controls and "
                              f"the time step is the environment's")
        if isinstance(joints, str) or not all(isinstance(j, str) for j in joints) or not joints:
            raise DesignError(f"joints must be a non-empty list of MJCF joint names; found "
                              f"{joints!r}")
        tap = self.tap = MujocoTap(env, joints)
        system = tap.system
        self.dt = tap.h * tap.env.frame_skip
        name = "ekf_mujoco" if observer is None else observer
        if isinstance(name, str):
            from hgo_mj.check import refuse_inapplicable

            kw = dict(observer_kwargs or {})
            refuse_inapplicable(name, system, name)
            self.observer = make_observer(name, system, **{**auto_defaults(name, self.dt), **kw}
                                          if self._tuning is not None else kw)
        elif isinstance(name, Observer):
            if observer_kwargs:
                raise DesignError("observer_kwargs apply to a named observer, not to an instance")
            self.observer = copy.deepcopy(name)
        else:
            raise DesignError(f"with joints= the observer is a registered name or an Observer "
                              f"designed against the environment's MJCF; found {name!r}")
        self._joint_observer()
        space = env.observation_space
        if not isinstance(space, spaces.Box) or len(space.shape) != 1:
            raise DesignError(f"joints= needs a 1-D Box observation space; found {space}")
        self.observation_space = space
        self.observation_names = tuple(
            system.state_names[tap.entries[i]] if i in tap.entries else f"observation_{i}"
            for i in range(space.shape[0]))

    def _joint_observer(self) -> None:
        """Check the observer's estimate is the MJCF's state and its period the step's."""
        assert self.tap is not None
        system = self.tap.system
        names = tuple(self.observer.state_names)
        if sorted(names) != sorted(system.state_names):
            raise DimensionError(f"the observer's estimate {list(names)} is not the MJCF's "
                                 f"state {list(system.state_names)}")
        #: the observer's estimate in the MJCF's state order (chains are per joint)
        self._perm = np.array([names.index(n) for n in system.state_names], dtype=np.intp)
        self.observer.check_period(self.dt)

    # ------------------------------------------------------------ observer="auto"
    def _autotune(self, kind: str, kwargs: Mapping[str, Any] | None, **where: Any) -> None:
        """Tune ``kind`` for this environment and sensor (``observer="auto"``), or read the
        tuning from the cache: keyed by the environment's id and arguments, what is measured,
        the sensor spec, the kind, its parameters, the estimate handed, the step and the
        tuning options. Tuning records a rollout of a fresh copy of the environment
        (:func:`record_rollout`), draws the sensor's noise on it, and searches the kind's
        tuning space (:func:`hgo_mj.tune.recorded.search_rounds`), each round's candidates one
        batch of the observer's pure step over the recording, scored by the RMS error of the
        estimated velocities against the recorded ones."""
        opts = self._tuning
        assert opts is not None
        spec = self.env.spec
        if spec is None:
            raise DesignError("observer='auto' needs an environment made by gymnasium.make "
                              "(env.spec names it in the cache and makes the copy it rolls out)")
        kw = {**auto_defaults(kind, self.dt), **dict(kwargs or {})}
        if self.tap is None:  # the estimate per kind, from one chain
            self.observer = self._make(kind, kw, where.get("channels") or 1)
            self._order()
        key = cache_key(env=spec.id, env_kwargs=spec.kwargs, kind=kind, observer_kwargs=kw,
                        sensor=self._sensor_spec, estimate=self.estimate, dt=self.dt,
                        **{k: opts[k] for k in ("steps", "budget", "round", "seed")}, **where)
        entry = cache_read(opts["cache"], key)
        hit = entry is not None
        if entry is None:
            t0 = time.perf_counter()
            episodes = self._record(opts)
            if self.tap is None:
                self.observer = self._make(kind, kw, episodes[0]["y"].shape[1])
            entry = self._search(episodes, opts)
            entry["seconds"] = round(time.perf_counter() - t0, 3)
            cache_write(opts["cache"], key, entry)
        self._apply_tuned(kind, kw, entry["values"])
        self.tuned = {**entry, "kind": kind, "from_cache": hit,
                      "cache": None if opts["cache"] is None else str(opts["cache"])}

    def _record(self, opts: Mapping[str, Any]) -> list[dict[str, Array]]:
        """The tuning's rollout on a fresh copy: per episode the clean measured signals ``y``,
        their true velocities ``v`` and the observer's inputs ``u``."""
        tap = self.tap
        env = tap.fresh() if tap is not None else gymnasium.make(self.env.spec)  # type: ignore[arg-type]
        try:
            if tap is not None:
                def read(e: Any, obs: Any) -> dict[str, Array]:
                    d = e.unwrapped.data
                    return {"y": np.array(d.qpos[tap.qadr]), "v": np.array(d.qvel[tap.state_qvel])}
                return record_rollout(env, opts["steps"], opts["seed"], read,
                                      lambda e, a: np.array(e.unwrapped.data.ctrl, dtype=float))
            model = getattr(env.unwrapped, "model", None)
            model = model if isinstance(model, mujoco.MjModel) else None

            def read_m(e: Any, obs: Any) -> dict[str, Array]:
                y = (np.array(self._measure_fn(e, obs), dtype=float).reshape(-1)
                     if self._measure_fn is not None else np.asarray(obs, dtype=float)[self._idx])
                if model is None:
                    return {"y": y}
                d = e.unwrapped.data
                return {"y": y, "q": np.array(d.qpos), "qd": np.array(d.qvel)}
            episodes = record_rollout(env, opts["steps"], opts["seed"], read_m,
                                      lambda e, a: self._u(a))
            signal_velocities(episodes, model, self.dt)
            return episodes
        finally:
            env.close()

    def _search(self, episodes: list[dict[str, Array]], opts: Mapping[str, Any]
                ) -> dict[str, Any]:
        """Search the tuning space over the recording (:meth:`_autotune`): a chain per measured
        signal is a study of its own (its error depends on its own gain), a MuJoCo observer one
        study over its tied space (:func:`tied_space`)."""
        from hgo_mj.tune.recorded import search_rounds

        ob = self.observer
        chain = sensor_chain(copy.deepcopy(self._sensor_spec))
        for e, ep in enumerate(episodes):  # one noise draw, shared by every candidate
            reset_chain(chain, opts["seed"] + e)
            t = np.arange(ep["y"].shape[0]) * self.dt
            ep["ym"] = chain.apply(t, ep["y"][None])[0]
        mode = "filter" if self._filter else "lead" if self._lead else "prediction"
        if isinstance(ob, ObserverBank) and self.tap is None:
            members = ob.members
            spaces = [dict(o.tuning_space()) for o in members]
            offsets = np.cumsum([0] + [len(o.state_names) for o in members])[:-1]
            cols = [int(i) + 1 for i in offsets]
            groups: list[dict[str, list[str]]] = [{k: [k] for k in sp} for sp in spaces]
        else:
            assert self.tap is not None
            nj = len(self.tap.system.joints)
            space, group = tied_space(ob, nj)
            members, spaces, groups = (ob,), [space], [group]
            cols = [int(i) for i in self._perm[nj:]]
        if any(not sp for sp in spaces):
            raise DesignError(f"observer {ob.name!r} declares no tunable parameter")

        def score(cands: list[list[dict[str, float]]]) -> Array:
            return self._score(cands, members, groups, episodes, cols, mode)
        res = search_rounds(spaces, score, budget=opts["budget"], round_size=opts["round"],
                            seed=opts["seed"])
        values = [{k: v for g, v in best.items() for k in grp[g]}
                  for best, grp in zip(res.best, groups)]
        return {"values": values, "score": res.best_score, "default_score": res.default_score,
                "trials": res.trials}

    def _score(self, cands: list[list[dict[str, float]]], members: Sequence[Observer],
               groups: list[dict[str, list[str]]], episodes: list[dict[str, Array]],
               cols: list[int], mode: str) -> Array:
        """``(R, studies)`` scores of a round: the RMS velocity error per chain (per study),
        or over every velocity (one study); a candidate the observer refuses, or whose run
        fails, scores inf."""
        R, S = len(cands), len(members)
        tuned: list[list[dict[str, Any]]] = []
        bad = np.zeros((R, S), dtype=bool)
        for r, cand in enumerate(cands):
            row = []
            for i, (o, grp) in enumerate(zip(members, groups)):
                t = o.tuned_parameters({k: v for g, v in cand[i].items() for k in grp[g]})
                try:
                    o.check_period(self.dt, o.parameters(1, **t))
                except (DesignError, DivergenceError):
                    bad[r, i], t = True, {}
                row.append(t)
            tuned.append(row)
        ok = [r for r in range(R) if not bad[r].all()]
        out = np.full((R, S), np.inf)
        if ok:
            out[ok] = self._run_rows([tuned[r] for r in ok], episodes, cols, mode, S)
        return np.where(bad, np.inf, out)

    def _run_rows(self, rows: list[list[dict[str, Any]]], episodes: list[dict[str, Array]],
                  cols: list[int], mode: str, S: int) -> Array:
        """The scores of the candidates ``rows`` as one batch; on a failure, one by one."""
        ob = copy.deepcopy(self.observer)
        try:
            return self._errors(ob, self._params(ob, rows), episodes, cols, mode, S)
        except (DivergenceError, FloatingPointError, np.linalg.LinAlgError, ValueError):
            if len(rows) == 1:
                return np.full((1, S), np.inf)
            return np.concatenate([self._run_rows([r], episodes, cols, mode, S) for r in rows])

    def _params(self, ob: Observer, rows: list[list[dict[str, Any]]]) -> Params:
        """Per-member parameters of the candidates ``rows`` (a member's refused values: the
        constructor's, its score set to inf by the caller)."""
        def stacked(o: Observer, vals: list[dict[str, Any]]) -> dict[str, Array]:
            defaults = o._parameters()
            names = sorted({n for v in vals for n in v})
            return {n: np.stack([np.asarray(v.get(n, defaults[n]), dtype=float) for v in vals])
                    for n in names}
        if isinstance(ob, ObserverBank) and self.tap is None:
            return ob.parameters(len(rows), members=[
                stacked(o, [r[i] for r in rows]) for i, o in enumerate(ob.members)])
        return ob.parameters(len(rows), **stacked(ob, [r[0] for r in rows]))

    def _errors(self, ob: Observer, params: Params, episodes: list[dict[str, Array]],
                cols: list[int], mode: str, S: int) -> Array:
        """``(B, S)``: the RMS velocity error over every recorded step, per chain (S > 1) or
        over all velocities (S = 1)."""
        B = params_batch(params)
        sq, n = np.zeros((B, len(cols))), 0
        for ep in episodes:
            Y = ep["ym"]
            start = {"x_hat0": self._joint_start(Y[0]) if self.tap is not None else
                     measurement_start(ob, Y[0])[0]}
            X = estimates(ob, params, start, Y, ep["u"], self.dt, mode)
            err = X[:, :, cols] - ep["v"][None, 1:]
            sq += np.sum(np.square(err), axis=1)
            n += err.shape[1]
        rmse = np.sqrt(sq / max(n, 1))
        rmse = rmse if S > 1 else np.sqrt(np.mean(np.square(rmse), axis=1, keepdims=True))
        return np.where(np.isfinite(rmse), rmse, np.inf)

    def _apply_tuned(self, kind: str, kw: Mapping[str, Any], values: list[dict[str, float]]
                     ) -> None:
        """Rebuild the observer with the tuned values (per chain, or the one observer's)."""
        ob = self.observer
        if self.tap is None:
            assert isinstance(ob, ObserverBank)
            members = [make_observer(kind, None, outputs=(c,), **{
                **kw, **{k: np.asarray(v).tolist() for k, v in o.tuned_parameters(vals).items()}})
                for c, (o, vals) in enumerate(zip(ob.members, values))]
            self.observer = ObserverBank(members, output_names=[f"y{i + 1}" for i in
                                                                range(len(members))])
            return
        tuned = {k: np.asarray(v) for k, v in ob.tuned_parameters(values[0]).items()}
        self.observer = make_observer(kind, self.tap.system, **{**kw, **tuned})
        self._joint_observer()

    def _sample(self, signals: Array) -> None:
        """The measurement of ``signals`` at the sensor's clock, through the sensor chain:
        the newest, not yet consumed."""
        self._y = self.sensor.apply(np.array([self._t]), signals[None, None])[0, 0]

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
        if self._init == "measurement":
            ob.reset(x_hat0=measurement_start(ob, y)[0])
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
        assert self.tap is not None
        self._sample(self.tap.measure())
        self.observer.reset(x_hat0=self._joint_start(self._y))
        self._ready = True
        return self._joint_result(obs, info)

    def _joint_start(self, y: Array) -> Array:
        """The initial estimate in the observer's layout: the model's ``qpos0`` with the
        measured joints at ``y`` (a dropout keeps ``qpos0``), zero velocities."""
        tap = self.tap
        assert tap is not None
        m, system = tap.env.model, tap.system
        nj = len(system.joints)
        x0 = np.zeros(len(system.state_names))
        x0[:nj] = m.qpos0[tap.state_qpos]
        for k, j in enumerate(tap.joints):
            if y[k] == y[k]:
                x0[system.joints.index(j)] = y[k]
        x0_obs = np.empty_like(x0)
        x0_obs[self._perm] = x0
        return x0_obs

    def _step_joints(self, action: Any) -> tuple[Array, Any, bool, bool, dict[str, Any]]:
        """One environment step, then one observer update over it with the controls the
        environment applied (``data.ctrl``) and the sample at its start (prediction, a Kalman
        filter) or at its end (a continuous-time observer's current estimate)."""
        assert self.tap is not None
        obs, reward, terminated, truncated, info = self.env.step(action)
        u, before = self.tap.controls(), self._y
        self._t += self.dt
        self._sample(self.tap.measure())
        self.observer.update(self._y if self._lead else before, u, self.dt)
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
        adr = tap.binding.qpos(tap.system.joints).tolist()
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
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        super().close()


__all__ = ["ObserverInTheLoop"]
