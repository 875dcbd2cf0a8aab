"""The environments: a :class:`~hgo_mj.envs.core.Task` each, in the loop of :class:`~hgo_mj.envs.core.HgoEnv`.

The classes below carry only their documentation and their task; the loop, the arguments and
the observation modes are :class:`~hgo_mj.envs.core.HgoEnv`'s. Variants are made with
:func:`functools.partial` or registration keywords, never by copying a class::

    PendulumSwingUpTrue = functools.partial(PendulumSwingUpEnv, observation="true")
"""

from __future__ import annotations

from .core import HgoEnv
from .tasks import (
    AcrobotBalanceTask,
    AcrobotSwingUpTask,
    BalanceTask,
    CartPoleBalanceTask,
    CartPoleSwingUpTask,
    FurutaBalanceTask,
    FurutaSwingUpTask,
    Reach2LinkTask,
    ReachTask,
    SwingUpTask,
)

_ARGUMENTS = """
    Common to every hgo_mj environment (:class:`~hgo_mj.envs.core.HgoEnv`); pass them to
    ``gymnasium.make``:

    | Parameter         | Default      | Description                                          |
    |-------------------|--------------|------------------------------------------------------|
    | `observer`        | `"default"`  | observer name, `{"type": name, ...}`, instance, None |
    | `observer_kwargs` | `None`       | parameters of a named observer, over the defaults    |
    | `sensor`          | `"default"`  | `SensorChain`, `{"stage": name, ...}` spec(s), None  |
    | `observation`     | `"estimate"` | `"estimate"`, `"measurement"`, `"true"`,             |
    |                   |              | `"estimate+diagnostics"`                             |
    | `physics_dt`      | see below    | MuJoCo timestep [s]                                  |
    | `control_period`  | see below    | action hold [s], a multiple of `sample_period`       |
    | `sample_period`   | see below    | sensor and observer period [s], multiple of physics  |
    | `integrator`      | see below    | `"Euler"`, `"RK4"`, `"implicit"`, `"implicitfast"`   |
    | `invalid_action`  | `"clip"`     | outside [-1, 1]: clip, or `"raise"`; NaN raises      |
    | `info_level`      | `"basic"`    | `info`: `state`, `estimate`, `error`; `"full"` adds  |
    |                   |              | time, measurement, diagnostics, goal, reward terms   |

    Recording episodes to rerun is the wrapper `hgo_mj.envs.wrappers.RecordEpisodes`.

    Bad actions and starting states raise, they are never replaced: `step` raises
    `DimensionError` for an action that is not a sequence of numbers of the action space's
    shape (a bool, a string, a nested list) and `DesignError` for a NaN entry (or one outside
    [-1, 1] with `invalid_action="raise"`); `reset(options={"x0": x0})` raises `DesignError`
    naming the entry for a state the plant cannot take (not finite, or, on a MuJoCo plant, an
    entry beyond 1e10 or one `mj_forward` flags as bad, which MuJoCo would silently reset to
    zero) and `DimensionError` for a state of the wrong length.
"""


def _sections(env_id: str, task_params: str, obs_shape: str, reward: str) -> str:
    """The numpydoc Parameters and Examples sections of an environment class."""
    return f"""
    Parameters
    ----------
    task : Task, optional
        A task instance instead of the class's ``task_class(**task_kwargs)``.
    observer : str, mapping, Observer, "default" or None
        The observer in the loop (default ``"default"``: the task's); see
        :class:`~hgo_mj.envs.core.HgoEnv`.
    observer_kwargs : mapping, optional
        Parameters of a named observer, merged over the task's defaults for it.
    sensor : SensorChain, stage spec, sequence of stage specs, "default" or None
        The sensor chain (default ``"default"``: the task's, given above).
    observation : {{"estimate", "measurement", "true", "estimate+diagnostics"}}
        What the agent sees (default ``"estimate"``).
    physics_dt, control_period, sample_period : float, optional
        MuJoCo timestep, action hold and sensor/observer period [s]; defaults above.
    integrator : {{"Euler", "RK4", "implicit", "implicitfast"}}, optional
        MuJoCo integrator (default above).
    invalid_action : {{"clip", "raise"}}
        What an action outside [-1, 1] does (default ``"clip"``).
    info_level : {{"basic", "full"}}
        What ``info`` carries (default ``"basic"``).
    render_mode : {{None, "rgb_array"}}
        ``"rgb_array"``: ``render()`` returns the true pose with the estimate's ghost.
    **task_kwargs
        Parameters of the task (below; the ``## Arguments`` table above).
{task_params}

    Examples
    --------
    >>> import gymnasium
    >>> import numpy as np
    >>> import hgo_mj.envs
    >>> env = gymnasium.make("{env_id}")
    >>> obs, info = env.reset(seed=0)
    >>> obs.shape
    {obs_shape}
    >>> action = np.zeros(env.action_space.shape, dtype=np.float32)
    >>> obs, reward, terminated, truncated, info = env.step(action)
    >>> round(reward, 2), terminated, truncated
    ({reward}, False, False)
    >>> env.close()
"""


class PendulumSwingUpEnv(HgoEnv):
    __doc__ = """Swing a torque-limited pendulum up and balance it, acting on an observer's estimate.

    ## Description
    The MuJoCo pendulum of ``models/pendulum.xml`` (a rod and bob, 0.25 kg, hinge-to-COM
    distance 0.45 m, viscous hinge damping) hangs from a motor whose torque is limited to
    ``max_torque`` = 0.5 N m, less than half the 1.10 N m the gravity load can reach: the
    agent must pump energy in over several swings, then catch and hold the pendulum upright.
    Only the hinge angle is measured, with Gaussian noise (standard deviation 0.01 rad); a
    high-gain observer (paper 000, eq. 2) with the pendulum's model term (Gauthier et al.)
    estimates the angle and angular velocity from it, and the agent sees that estimate by
    default. The model-free observer (`observer_kwargs={"k": 20, "model": False}`, Tornambe's:
    it knows only that the angle's second derivative is bounded) is about 7 microseconds
    cheaper per step (``scripts/bench_envs.py``, 64 against 72 us) but its velocity error is about six times
    larger while the pendulum swings (0.48 against 0.08 rad/s RMS under an energy-pumping
    swing-up), enough that a swing-up controller acting on it fails to catch the pendulum.

    ## Action Space
    `Box(-1, 1, (1,), float32)`: the motor torque over ``max_torque``.

    | Num | Action       | Min | Max | Actuator (MJCF) | Unit                |
    |-----|--------------|-----|-----|-----------------|---------------------|
    | 0   | motor torque | -1  | 1   | `torque`        | N m / `max_torque`  |

    ## Observation Space
    `Box(float64)`; the angle (0 hanging, pi upright) enters as its cosine and sine.

    `observation="estimate"` (default) and `"true"`, shape `(3,)`; `"estimate+diagnostics"`
    appends the observer's run-time quantities (for `high_gain`: the gain `k`):

    | Num | Observation                | Min | Max | Unit  |
    |-----|----------------------------|-----|-----|-------|
    | 0   | cos(angle)                 | -1  | 1   | -     |
    | 1   | sin(angle)                 | -1  | 1   | -     |
    | 2   | angular velocity (clipped) | -50 | 50  | rad/s |

    `observation="measurement"`, shape `(2,)`: cos and sin of the measured angle.

    ## Rewards
    `-(d^2 + 0.1 w^2 + 0.001 a^2)` per step, with `d` the angle from upright wrapped to
    [-pi, pi) [rad], `w` the true angular velocity [rad/s], `a` the action (the torque limit
    and the hinge damping bound `w`); with `info_level="full"`, `info` has the terms as
    `reward_upright`, `reward_velocity`, `reward_control`.

    ## Starting State
    Angle and angular velocity uniform in [-`start_noise`, `start_noise`] (default 0.1 rad
    and rad/s): hanging nearly still. The observer starts from its own initial estimate (zero).

    ## Episode End
    No termination; truncated after 250 steps (10 s) by `TimeLimit` (registration).

    ## Arguments
    | Parameter     | Default | Description                              |
    |---------------|---------|------------------------------------------|
    | `max_torque`  | `0.5`   | torque per unit action [N m]             |
    | `start_noise` | `0.1`   | half width of the initial state draw     |
""" + _ARGUMENTS + """
    Defaults here: `physics_dt=0.02` with the `"Euler"` integrator and `control_period=0.04`
    (two MuJoCo steps per `step`, as Gymnasium's InvertedPendulum-v5), the sample period the
    control period (one measurement per `step`);
    observer `high_gain` with `k=10, model=True`; sensor `[{"stage": "gaussian", "std": 0.01}]`.

    ## Version History
    * v0: initial version.
""" + _sections(
        "hgo_mj/PendulumSwingUp-v0", """\
    max_torque : float, default 0.5
        Torque per unit action [N m].
    start_noise : float, default 0.1
        Half width of the initial state draw [rad, rad/s].""", "(3,)", "-9.71")
    task_class = SwingUpTask
    env_id = "hgo_mj/PendulumSwingUp-v0"


class CartPendulumBalanceEnv(HgoEnv):
    __doc__ = """Balance Ibrir's inverted pendulum through its pivot acceleration, on an estimate.

    ## Description
    The pendulum of paper 004 (Ibrir 2007), eq. 66, in MuJoCo (``models/cart_pendulum.xml``):
    `x1'' = sin x1 + u cos x1` in time-scaled units (`g / l = 1`; one time unit is
    `sqrt(l / g)`, 0.226 s for a 0.5 m pendulum), `x1` the angle from upright and `u` the
    pivot acceleration in units of `g`. The agent keeps the pendulum upright from a perturbed
    start. Only the angle is measured (Gaussian noise, standard deviation 0.005 rad).

    ## Action Space
    `Box(-1, 1, (1,), float32)`: the pivot acceleration over `max_acceleration` (default 2 g).

    | Num | Action             | Min | Max | Actuator (MJCF) | Unit                    |
    |-----|--------------------|-----|-----|-----------------|-------------------------|
    | 0   | pivot acceleration | -1  | 1   | `acceleration`  | g / `max_acceleration`  |

    ## Observation Space
    `Box(float64)`. `"estimate"` (default) and `"true"`, shape `(2,)`
    (`"estimate+diagnostics"` appends the observer's run-time quantities):

    | Num | Observation      | Min   | Max  | Unit              |
    |-----|------------------|-------|------|-------------------|
    | 0   | angle            | -2 pi | 2 pi | rad (0 upright)   |
    | 1   | angular velocity | -50   | 50   | rad / time unit   |

    `"measurement"`, shape `(1,)`: the measured angle [rad].

    ## Rewards
    `1 - x1^2 - 0.01 a^2` per step (with `info_level="full"`, `info` has `reward_alive`,
    `reward_angle`, `reward_control`).

    ## Starting State
    Angle and angular velocity uniform in [-`start_noise`, `start_noise`] (default 0.2).

    ## Episode End
    Terminates when `|x1| > max_angle` (default 0.5 rad); truncated after 400 steps (20 time
    units) by `TimeLimit`.

    ## Arguments
    | Parameter          | Default | Description                                     |
    |--------------------|---------|-------------------------------------------------|
    | `max_acceleration` | `2.0`   | pivot acceleration per unit action [g]          |
    | `max_angle`        | `0.5`   | termination angle [rad]                         |
    | `start_noise`      | `0.2`   | half width of the initial state draw            |
""" + _ARGUMENTS + """
    Defaults here: `physics_dt=0.01` (RK4, the MJCF's), `control_period=0.05`,
    `sample_period=0.01`; observer `high_gain` with `k=10, model=True`; sensor Gaussian, std 0.005 rad.

    ## Version History
    * v0: initial version.
""" + _sections(
        "hgo_mj/CartPendulumBalance-v0", """\
    max_acceleration : float, default 2.0
        Pivot acceleration per unit action [g].
    max_angle : float, default 0.5
        Termination angle [rad].
    start_noise : float, default 0.2
        Half width of the initial state draw.""", "(2,)", "1.0")
    task_class = BalanceTask
    env_id = "hgo_mj/CartPendulumBalance-v0"


class ElasticJointReachEnv(HgoEnv):
    __doc__ = """Bring the link of an elastic joint to a target angle, acting on an estimate.

    ## Description
    The single-link elastic joint of ``models/elastic_joint.xml`` (Spong's model: a motor
    drives the link through a torsional spring of 10 N m/rad, joint resonance 8.6 Hz, gravity
    load 1.18 N m). The agent must bring the *link* to a target angle drawn at reset and hold
    it there with little residual vibration. Only the link angle is measured, by an encoder
    (Gaussian noise of 0.001 rad, then 16384 counts per revolution); a fourth-order high-gain
    observer estimates the link velocity and, through the normal form's inverse map, the motor
    angle and velocity.

    ## Action Space
    `Box(-1, 1, (1,), float32)`: the motor torque over `max_torque` (default 2 N m).

    | Num | Action       | Min | Max | Actuator (MJCF) | Unit               |
    |-----|--------------|-----|-----|-----------------|--------------------|
    | 0   | motor torque | -1  | 1   | `torque`        | N m / `max_torque` |

    ## Observation Space
    `Box(float64)`. `"estimate"` (default) and `"true"`, shape `(5,)`
    (`"estimate+diagnostics"` appends the observer's run-time quantities):

    | Num | Observation       | Min   | Max  | Unit  |
    |-----|-------------------|-------|------|-------|
    | 0   | link angle        | -2 pi | 2 pi | rad   |
    | 1   | motor angle       | -2 pi | 2 pi | rad   |
    | 2   | link velocity     | -50   | 50   | rad/s |
    | 3   | motor velocity    | -50   | 50   | rad/s |
    | 4   | target link angle | -pi   | pi   | rad   |

    `"measurement"`, shape `(2,)`: measured link angle [rad], target link angle [rad].

    ## Rewards
    `-min(e^2 + 0.01 q'^2 + 0.01 (q' - theta')^2 + 0.001 a^2, max_cost)` per step: `e` the link
    angle error [rad], `q'` the link velocity, `q' - theta'` the spring's deflection rate
    [rad/s] (residual vibration), `a` the action; `max_cost` = 10 bounds a runaway (the link
    whirling). With `info_level="full"`, `info` has the unbounded terms `reward_tracking`,
    `reward_velocity`, `reward_vibration`, `reward_control`.

    ## Starting State
    Link and motor at the same angle, uniform in [-`start_noise`, `start_noise`] (0.1 rad),
    at rest; target uniform in [-`target_range`, `target_range`] (1 rad).

    ## Episode End
    No termination; truncated after 300 steps (3 s) by `TimeLimit`.

    ## Arguments
    | Parameter      | Default | Description                              |
    |----------------|---------|------------------------------------------|
    | `max_torque`   | `2.0`   | torque per unit action [N m]             |
    | `target_range` | `1.0`   | half width of the target draw [rad]      |
    | `start_noise`  | `0.1`   | half width of the initial angle draw [rad] |
    | `max_cost`     | `10.0`  | bound of the per-step cost               |
""" + _ARGUMENTS + """
    Defaults here: `physics_dt=0.001` (RK4, the MJCF's), `sample_period=0.002`,
    `control_period=0.01`; observer `high_gain` with `k=80, model=True`; sensor Gaussian
    (0.001 rad) then quantization (16384 counts per revolution).

    ## Version History
    * v0: initial version.
""" + _sections(
        "hgo_mj/ElasticJointReach-v0", """\
    max_torque : float, default 2.0
        Torque per unit action [N m].
    target_range : float, default 1.0
        Half width of the target draw [rad].
    start_noise : float, default 0.1
        Half width of the initial angle draw [rad].
    max_cost : float, default 10.0
        Bound of the per-step cost.""", "(5,)", "-0.24")
    task_class = ReachTask
    env_id = "hgo_mj/ElasticJointReach-v0"


class ElasticJoint2LinkReachEnv(HgoEnv):
    __doc__ = """Bring both links of an elastic two-link arm to target angles, acting on an estimate.

    ## Description
    The planar two-link arm of ``models/elastic_joint_2link.xml``, each joint elastic (Spong's
    reduced model, resonances 9.4 and 11.3 Hz), in a vertical plane. The agent brings both link
    angles to targets drawn at reset. Both link angles are measured by encoders. With two
    outputs there is no single-output normal form, so the default observer is model-free:
    `high_gain_multi` with one chain of order 4 per link angle (paper 001, eq. 5), which
    estimates each link angle and its first three derivatives; if `high_gain_multi` is not
    registered, two `high_gain` chains of order 4 without a system, run together
    (`ObserverBank`), give the same estimate. The motor angles are not estimated by either.

    ## Action Space
    `Box(-1, 1, (2,), float32)`: the motor torques over `max_torque` (default 6 and 2 N m).

    | Num | Action         | Min | Max | Actuator (MJCF) | Unit                  |
    |-----|----------------|-----|-----|-----------------|-----------------------|
    | 0   | motor 1 torque | -1  | 1   | `torque1`       | N m / `max_torque[0]` |
    | 1   | motor 2 torque | -1  | 1   | `torque2`       | N m / `max_torque[1]` |

    ## Observation Space
    `Box(float64)`. `"estimate"` (default) with the default observer, shape `(10,)`:

    | Num | Observation                          | Min   | Max  | Unit    |
    |-----|--------------------------------------|-------|------|---------|
    | 0   | link 1 angle                         | -2 pi | 2 pi | rad     |
    | 1   | link 1 velocity                      | -50   | 50   | rad/s   |
    | 2   | link 1 acceleration                  | -1e3  | 1e3  | rad/s^2 |
    | 3   | link 1 jerk                          | -1e5  | 1e5  | rad/s^3 |
    | 4-7 | the same for link 2 (relative angle) |       |      |         |
    | 8   | target link 1 angle                  | -pi   | pi   | rad     |
    | 9   | target link 2 angle                  | -pi   | pi   | rad     |

    `"true"`, shape `(10,)`: link 1, link 2, motor 1, motor 2 angles [rad, within +-2 pi],
    then their velocities [rad/s, within +-50], then the two targets. `"measurement"`, shape
    `(4,)`: the two measured link angles, the two targets. `env.unwrapped.observation_names`
    names every entry.

    ## Rewards
    `-min(sum_i (e_i^2 + 0.01 q_i'^2 + 0.01 (q_i' - theta_i')^2 + 0.001 a_i^2), max_cost)` per
    step, as in ElasticJointReach, summed over both joints.

    ## Starting State
    Each link and its motor at the same angle, uniform in [-0.1, 0.1] rad, at rest; targets
    uniform in [-`target_range`, `target_range`] (0.8 rad) each.

    ## Episode End
    No termination; truncated after 300 steps (3 s) by `TimeLimit`.

    ## Arguments
    | Parameter      | Default      | Description                               |
    |----------------|--------------|-------------------------------------------|
    | `max_torque`   | `(6.0, 2.0)` | torques per unit action [N m]             |
    | `target_range` | `0.8`        | half width of each target draw [rad]      |
    | `start_noise`  | `0.1`        | half width of the initial angle draw [rad] |
    | `max_cost`     | `10.0`       | bound of the per-step cost                |
""" + _ARGUMENTS + """
    Defaults here: `physics_dt=0.001` (RK4), `sample_period=0.002`, `control_period=0.01`;
    observer `high_gain_multi` with `k=150, orders=(4, 4)`; sensor as in ElasticJointReach.

    ## Version History
    * v0: initial version.
""" + _sections(
        "hgo_mj/ElasticJoint2LinkReach-v0", """\
    max_torque : tuple of float, default (6.0, 2.0)
        Torques per unit action [N m].
    target_range : float, default 0.8
        Half width of each target draw [rad].
    start_noise : float, default 0.1
        Half width of the initial angle draw [rad].
    max_cost : float, default 10.0
        Bound of the per-step cost.""", "(10,)", "-1.11")
    task_class = Reach2LinkTask
    env_id = "hgo_mj/ElasticJoint2LinkReach-v0"


class FurutaSwingUpEnv(HgoEnv):
    __doc__ = """Swing the QUBE-Servo 2 rotary (Furuta) pendulum up by the motor voltage, on an estimate.

    ## Description
    The rotary inverted pendulum of ``models/furuta.xml``, with the published parameters of
    the Quanser QUBE-Servo 2 and its pendulum module (QUBE-Servo 2 User Manual): a 0.085 m
    arm turned by a DC motor (voltage input, +-10 V, back-emf as damping) carries a 0.129 m,
    24 g pendulum. The agent swings the pendulum from hanging to upright and holds it there.
    Both joints are read by 2048-count encoders.
    The plant is the MJCF itself, read by the generic MJCF path
    (:func:`hgo_mj.systems.mjcf.mjcf_system`): state `(qpos, qvel)`, outputs the encoder
    sensors, quantized to the unit's counts (the default sensor chain); the default observer
    is `high_gain_multi` with MuJoCo's forward dynamics as its model term (one chain of order 2
    per joint, paper 001, eq. 5).

    ## Action Space
    `Box(-1, 1, (1,), float32)`: the input over `max_input`.

    | Num | Action | Min | Max | Actuator (MJCF) | Unit |
    |-----|--------|-----|-----|-----------------|------|
    | 0   | motor voltage | -1 | 1 | `voltage` | V / `max_input` |

    ## Observation Space
    `Box(float64)`, shape `(6,)` for `observation="estimate"` (default) and `"true"`:
    every angle enters as its cosine and sine, every position and velocity as it is (clipped
    to +-50 m/s, rad/s), in the order of the estimate (chain after chain: each encoder's
    coordinate, then its velocity) or of the true state (the coordinates, then the
    velocities); `observation_names` lists them.

    `observation="measurement"`: cos and sin of the two measured (quantized) angles, shape `(4,)`.
    `"estimate+diagnostics"` appends the observer's run-time quantities.

    ## Rewards
    `-(d^2 + 0.01 (w_arm^2 + w_pend^2) + 0.001 a^2)`, `d` the pendulum angle from upright
    wrapped to [-pi, pi) [rad], `w` the true velocities [rad/s], `a` the action; terms
    `reward_target`, `reward_velocity`, `reward_control` in `info` with `info_level="full"`.

    v1 (`reward="quanser"`): Quanser's Qube swing-up reward (quanser-openai-driver,
    `QubeSwingupEnv`), `max(1 - (0.8 |d| + 0.2 |arm|) / pi, 0)` [rad], in [0, 1]: 0.2 per step
    hanging, 1 upright with the arm centred; term `reward_upright`.

    ## Starting State
    Every state uniform in [-`start_noise`, `start_noise`]: hanging nearly still.

    ## Episode End
    No termination; truncated after 500 steps (5 s) by `TimeLimit` (registration). v1: also
    terminated when the arm is beyond 90 degrees (`QubeSwingupEnv`'s end).

    An episode is *solved* (`scripts/eval_rl.py`) when it runs to the time limit without
    termination and the pendulum is within 20 degrees of upright at each of its last 100
    steps (1 s).

    ## Arguments
    | Parameter     | Default | Description                              |
    |---------------|---------|------------------------------------------|
    | `max_input`   | `10.0`  | motor voltage per unit action [V]        |
    | `start_noise` | `0.05`  | half width of the initial state draw     |
    | `reward`      | `"quadratic"` | `"quanser"`: v1's reward and end   |
""" + _ARGUMENTS + """
    Defaults here: `physics_dt=0.001` (the MJCF's RK4), `sample_period=0.002`,
    `control_period=0.01`; observer `high_gain_multi` with `k=40, model=True`; sensor
    `[{"stage": "quantize", "counts_per_rev": [2048, 2048]}]`.

    ## Version History
    * v0: initial version.
    * v1 (`hgo_mj/FurutaSwingUp-v1`, registered with `reward="quanser"`): Quanser's reward and
      arm limit (Rewards, Episode End), `reward_threshold` 250. v0's reward pays nothing for
      the way up (`-d^2` is -9.87 per step hanging and still -2.5 at a quarter turn) and
      charges 0.01 (w_arm^2 + w_pend^2) for the speed a swing needs, 2-4 per step
      (`docs/results/rl.md`). v0 is kept as it was. Not solved here: with the
      MJCF's pendulum damping (0.0005 N m s/rad) a bang-bang energy pump at 10 V lifts the
      pendulum to at most 1.78 rad, and PPO's policy to 1.75 rad (`rl.md`).
""" + _sections(
        "hgo_mj/FurutaSwingUp-v0", """\
    max_input : float, default 10.0
        Motor voltage per unit action [V].
    start_noise : float, default 0.05
        Half width of the initial state draw.
    reward : {"quadratic", "quanser"}, default "quadratic"
        v0's reward, or Quanser's Qube swing-up reward and arm limit (v1).""", "(6,)", "-9.72")
    task_class = FurutaSwingUpTask
    env_id = "hgo_mj/FurutaSwingUp-v0"


class AcrobotSwingUpEnv(HgoEnv):
    __doc__ = """Swing Spong's acrobot up by the elbow torque alone, on an estimate.

    ## Description
    The acrobot of ``models/acrobot.xml`` (Spong 1995: two 1 kg links of 1 m and 2 m in the
    vertical plane, no friction), actuated at the elbow only (+-20 N m). The agent brings
    the first link from hanging to upright with the second link straight, and holds it.
    Both joints are read by 4096-count encoders.
    The plant is the MJCF itself, read by the generic MJCF path
    (:func:`hgo_mj.systems.mjcf.mjcf_system`): state `(qpos, qvel)`, outputs the encoder
    sensors, quantized to the unit's counts (the default sensor chain); the default observer
    is `high_gain_multi` with MuJoCo's forward dynamics as its model term (one chain of order 2
    per joint, paper 001, eq. 5).

    ## Action Space
    `Box(-1, 1, (1,), float32)`: the input over `max_input`.

    | Num | Action | Min | Max | Actuator (MJCF) | Unit |
    |-----|--------|-----|-----|-----------------|------|
    | 0   | elbow torque | -1 | 1 | `elbow_torque` | N m / `max_input` |

    ## Observation Space
    `Box(float64)`, shape `(6,)` for `observation="estimate"` (default) and `"true"`:
    every angle enters as its cosine and sine, every position and velocity as it is (clipped
    to +-50 m/s, rad/s), in the order of the estimate (chain after chain: each encoder's
    coordinate, then its velocity) or of the true state (the coordinates, then the
    velocities); `observation_names` lists them.

    `observation="measurement"`: cos and sin of the two measured (quantized) angles, shape `(4,)`.
    `"estimate+diagnostics"` appends the observer's run-time quantities.

    ## Rewards
    `-(d1^2 + d2^2 + 0.01 (w1^2 + w2^2) + 0.001 a^2)`, `d1` the shoulder angle from upright
    and `d2` the elbow angle, both wrapped to [-pi, pi) [rad], `w` the true velocities
    [rad/s], `a` the action; terms `reward_target`, `reward_velocity`, `reward_control`.

    v1 (`reward="dm_control"`): dm_control's `acrobot.swingup` reward, `tolerance(|tip -
    target|, bounds=(0, r), margin=m)`, the target the tip's upright position, its radius
    0.2 m and margin 1 m for dm_control's 2 m arm scaled to this 3 m arm (r = 0.3, m = 1.5):
    1 within r, a Gaussian falling to 0.1 at m beyond it, in [0, 1]; term `reward_reach`.

    ## Starting State
    Every state uniform in [-`start_noise`, `start_noise`]: hanging nearly still.

    ## Episode End
    No termination; truncated after 500 steps (5 s) by `TimeLimit` (registration).

    An episode is *solved* (`scripts/eval_rl.py`) when the shoulder is within 20 degrees of
    upright and the elbow within 20 degrees of straight at each of its last 100 steps (1 s).

    ## Arguments
    | Parameter     | Default | Description                              |
    |---------------|---------|------------------------------------------|
    | `max_input`   | `20.0`  | elbow torque per unit action [N m]       |
    | `start_noise` | `0.05`  | half width of the initial state draw     |
    | `reward`      | `"quadratic"` | `"dm_control"`: v1's reward        |
""" + _ARGUMENTS + """
    Defaults here: `physics_dt=0.001` (the MJCF's RK4), `sample_period=0.002`,
    `control_period=0.01`; observer `high_gain_multi` with `k=30, model=True`; sensor
    `[{"stage": "quantize", "counts_per_rev": [4096, 4096]}]`.

    ## Version History
    * v0: initial version.
    * v1 (`hgo_mj/AcrobotSwingUp-v1`, registered with `reward="dm_control"`): dm_control's
      reward (Rewards), `reward_threshold` 250. v0's quadratic reward charges the velocity
      of a swing as v0 of :class:`FurutaSwingUpEnv` does. v0 is kept as it was.
""" + _sections(
        "hgo_mj/AcrobotSwingUp-v0", """\
    max_input : float, default 20.0
        Elbow torque per unit action [N m].
    start_noise : float, default 0.05
        Half width of the initial state draw.
    reward : {"quadratic", "dm_control"}, default "quadratic"
        v0's reward, or dm_control's ``acrobot.swingup`` reward (v1).""", "(6,)", "-9.79")
    task_class = AcrobotSwingUpTask
    env_id = "hgo_mj/AcrobotSwingUp-v0"


class CartPoleSwingUpEnv(HgoEnv):
    __doc__ = """Swing the cart-pole up by the force on the cart, on an estimate.

    ## Description
    The cart-pole of ``models/cart_pole.xml`` (Barto, Sutton and Anderson 1983: a 1 kg cart
    on a slider, a 1 m, 0.1 kg pole), pushed by a force of up to 10 N. The agent swings the
    pole from hanging to upright and balances it with the cart near the centre of its
    track. The pole is read by a 4096-count encoder, the cart by a 4096-count encoder on a
    pinion of radius 0.01482 m (2.27e-5 m per count).
    The plant is the MJCF itself, read by the generic MJCF path
    (:func:`hgo_mj.systems.mjcf.mjcf_system`): state `(qpos, qvel)`, outputs the encoder
    sensors, quantized to the unit's counts (the default sensor chain); the default observer
    is `high_gain_multi` with MuJoCo's forward dynamics as its model term (one chain of order 2
    per joint, paper 001, eq. 5).

    ## Action Space
    `Box(-1, 1, (1,), float32)`: the input over `max_input`.

    | Num | Action | Min | Max | Actuator (MJCF) | Unit |
    |-----|--------|-----|-----|-----------------|------|
    | 0   | force on the cart | -1 | 1 | `force` | N / `max_input` |

    ## Observation Space
    `Box(float64)`, shape `(5,)` for `observation="estimate"` (default) and `"true"`:
    every angle enters as its cosine and sine, every position and velocity as it is (clipped
    to +-50 m/s, rad/s), in the order of the estimate (chain after chain: each encoder's
    coordinate, then its velocity) or of the true state (the coordinates, then the
    velocities); `observation_names` lists them.

    `observation="measurement"`: the measured cart position and cos, sin of the pole angle, shape `(3,)`.
    `"estimate+diagnostics"` appends the observer's run-time quantities.

    ## Rewards
    `-(d^2 + x^2 + 0.01 (v^2 + w^2) + 0.001 a^2)`, `d` the pole angle from upright wrapped
    to [-pi, pi) [rad], `x` the cart position [m], `v`, `w` the true velocities, `a` the
    action; terms `reward_target`, `reward_velocity`, `reward_control`.

    v1 (`reward="dm_control"`): dm_control's smooth `cartpole.swingup` reward (Tassa et al.
    2018), in [0, 1]: `upright * centered * small_control * small_velocity`, `upright = (1 +
    cos d) / 2`, `centered = (1 + tol(x, 2)) / 2`, `small_control = (4 + 1 - a^2) / 5`,
    `small_velocity = (1 + tol(w, 5)) / 2`, `tol(z, m)` a Gaussian of 1 at 0 and 0.1 at `m`;
    the four factors are the terms `reward_upright`, `reward_centered`,
    `reward_small_control`, `reward_small_velocity`.

    ## Starting State
    Every state uniform in [-`start_noise`, `start_noise`]: centred, hanging nearly still.

    ## Episode End
    Terminated when the cart leaves its track (`|x| > 2.4` m); truncated after 500 steps
    (5 s) by `TimeLimit` (registration). v1 (`end_stops=True`): never terminated; end stops
    hold the cart on its track (`models/cart_pole_track.xml`: a soft joint limit at +-2.4 m,
    as dm_control's cart-pole has at +-1.8 m).

    An episode is *solved* (`scripts/eval_rl.py`) when it runs to the time limit without
    termination and at each of its last 100 steps (1 s) the pole is within 12 degrees of
    upright (`CartPole-v1`'s band) and the cart on its track (`|x| <= 2.4` m).

    ## Arguments
    | Parameter     | Default | Description                              |
    |---------------|---------|------------------------------------------|
    | `max_input`   | `10.0`  | force per unit action [N]                |
    | `start_noise` | `0.05`  | half width of the initial state draw     |
    | `reward`      | `"quadratic"` | `"dm_control"`: v1's reward        |
    | `end_stops`   | `False` | v1: end stops, no episode end at the track's end |
""" + _ARGUMENTS + """
    Defaults here: `physics_dt=0.001` (the MJCF's RK4), `sample_period=0.002`,
    `control_period=0.01`; observer `high_gain_multi` with `k=30, model=True`; sensor
    `[{"stage": "quantize", "resolution": [2.27e-5, 2 pi / 4096]}]`.

    ## Version History
    * v0: initial version.
    * v1 (`hgo_mj/CartPoleSwingUp-v1`, registered with `reward="dm_control"` and
      `end_stops=True`): dm_control's reward (Rewards) and end stops instead of the
      episode's end (Episode End), `reward_threshold` 250. v0's reward is negative at every
      step and the track's end terminates: leaving the track pays. Running off it at full
      force returns about -550 in 0.76 s, an energy-based swing-up that balances from 3.7 s
      on about -1950 (`docs/results/rl.md`). dm_control's reward with the track's
      end kept still paid it (0 hanging, about 8 for the pole's rise while the cart runs
      off): PPO and SAC both learned to run off; without an end, PPO swung the pole up with
      the cart out to 2.6 m. v0 is kept as it was.
""" + _sections(
        "hgo_mj/CartPoleSwingUp-v0", """\
    max_input : float, default 10.0
        Force per unit action [N].
    start_noise : float, default 0.05
        Half width of the initial state draw.
    reward : {"quadratic", "dm_control"}, default "quadratic"
        v0's reward, or dm_control's smooth ``cartpole.swingup`` reward (v1).
    end_stops : bool, default False
        End stops at the track's ends instead of the episode's end there (v1).""", "(5,)",
        "-9.72")
    task_class = CartPoleSwingUpTask
    env_id = "hgo_mj/CartPoleSwingUp-v0"


def _balance_doc(title: str, plant: str, swing_up: str, band: str, source: str,
                 max_input: str, obs_shape: str, history: str = "") -> str:
    """The docstring of a lab plant's balance environment: the swing-up environment's plant,
    sensors and observer, the balance task (:class:`~hgo_mj.envs.tasks.LabBalanceTask`);
    ``history``: the Version History's lines after v0's."""
    env_id = f"hgo_mj/{title}-v0"
    return f"""Balance the {plant} upright from a start near upright, on an estimate.

    ## Description
    The plant, its encoders, the default sensor chain and observer of :class:`{swing_up}`
    (read its Description); the agent starts near upright and keeps it there. {source}

    ## Action Space
    `Box(-1, 1, (1,), float32)`: the input over `max_input`, as in :class:`{swing_up}`.

    ## Observation Space
    `Box(float64)`, shape `{obs_shape}` for `observation="estimate"` (default) and `"true"`,
    as in :class:`{swing_up}` (angles as cosine and sine; `observation_names` lists them).

    ## Rewards
    `+1` per step (the alive bonus of Gymnasium's `CartPole-v1` and `InvertedPendulum`),
    term `reward_alive` in `info` with `info_level="full"`. The registered
    `reward_threshold` is 475: an episode balanced to the end returns 500, and that is the
    *solved* criterion of `scripts/eval_rl.py`.

    ## Starting State
    Every state uniform in [-`start_noise`, `start_noise`] around upright (the targets of
    :class:`{swing_up}`).

    ## Episode End
    Terminated when {band}; truncated after 500 steps (5 s) by `TimeLimit` (registration).

    ## Arguments
    | Parameter     | Default | Description                              |
    |---------------|---------|------------------------------------------|
    | `max_input`   | `{max_input}` | input per unit action (plant units) |
    | `start_noise` | `0.05`  | half width of the initial state draw     |
    | `max_angle`   | see Episode End | termination band [rad]           |
""" + _ARGUMENTS + """
    Defaults here: those of the swing-up environment.

    ## Version History
    * v0: initial version.
""" + history + _sections(env_id, f"""\
    max_input : float, default {max_input}
        Input per unit action (plant units).
    start_noise : float, default 0.05
        Half width of the initial state draw around upright.
    max_angle : float
        Termination band around upright [rad] (see Episode End).""", obs_shape, "1.0")


class FurutaBalanceEnv(HgoEnv):
    __doc__ = _balance_doc(
        "FurutaBalance", "QUBE-Servo 2 rotary pendulum", "FurutaSwingUpEnv",
        "the pendulum is beyond `max_angle` = 20 degrees of upright or the arm beyond 90 "
        "degrees", "Termination as Quanser's balance controller's and the Qube balance "
        "environment's (quanser-openai-driver, `QubeBalanceEnv`).", "10.0", "(6,)")
    task_class = FurutaBalanceTask
    env_id = "hgo_mj/FurutaBalance-v0"


class AcrobotBalanceEnv(HgoEnv):
    __doc__ = _balance_doc(
        "AcrobotBalance", "acrobot", "AcrobotSwingUpEnv",
        "the shoulder is beyond `max_angle` = 20 degrees of upright or the elbow beyond 20 "
        "degrees of straight", "Gymnasium's and dm_control's acrobots are swing-ups; Spong "
        "(1995) hands over to a balancing controller near upright, which this task trains.",
        "20.0", "(6,)", """\
    * v1 (`hgo_mj/AcrobotBalance-v1`, registered with `start_noise=0.02`): the start within
      0.02 of upright instead of 0.05. From v0's start a saturated LQR of the linearisation
      about upright (Q = diag(10, 10, 1, 1), R = 0.1, clipped at the 20 N m of the elbow) on
      the true state keeps 14 of 30 episodes upright for 5 s, and 29 of 30 from v1's
      (`docs/results/rl.md`): with the elbow's 20 N m, half of v0's starts are
      beyond what a linear controller recovers. v0 is kept as it was.
""")
    task_class = AcrobotBalanceTask
    env_id = "hgo_mj/AcrobotBalance-v0"


class CartPoleBalanceEnv(HgoEnv):
    __doc__ = _balance_doc(
        "CartPoleBalance", "cart-pole", "CartPoleSwingUpEnv",
        "the pole is beyond `max_angle` = 12 degrees of upright or the cart beyond 2.4 m "
        "(`CartPole-v1`'s limits)", "Gymnasium's `CartPole-v1` (Barto, Sutton and Anderson "
        "1983) with a continuous force of up to 10 N; dm_control's `cartpole.balance` starts "
        "the same way.", "10.0", "(5,)")
    task_class = CartPoleBalanceTask
    env_id = "hgo_mj/CartPoleBalance-v0"


__all__ = ["AcrobotBalanceEnv", "AcrobotSwingUpEnv", "CartPendulumBalanceEnv",
           "CartPoleBalanceEnv", "CartPoleSwingUpEnv",
           "ElasticJoint2LinkReachEnv", "ElasticJointReachEnv", "FurutaBalanceEnv",
           "FurutaSwingUpEnv",
           "PendulumSwingUpEnv"]
