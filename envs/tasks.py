"""The tasks of the environments: reward, termination, reset distribution and defaults.

Each task is small: it never sees the observer, and its reward and termination use the true
state only. The numbers (episode lengths, torque limits, observer gains, sensor noise) are the
defaults of the environment classes in :mod:`hgo_mj.envs.environments`, where they are documented.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from hgo_mj._validate import finite_scalar
from hgo_mj.exceptions import DesignError
from hgo_mj.observers import HighGainObserver, Observer
from hgo_mj.observers.bank import ObserverBank

from .core import Task

_TWO_PI = 2.0 * math.pi


def _wrap(a: Any) -> Any:
    """Angle (a float or an array) wrapped to ``[-pi, pi)``: ``%`` is Python's on a float and
    ``numpy.remainder`` on an array, the same numbers."""
    return (a + math.pi) % _TWO_PI - math.pi


def _total(terms: dict[str, Any]) -> Any:
    """The terms summed in order from 0 (floats or arrays alike)."""
    total: Any = 0.0
    for v in terms.values():
        total = total + v
    return total


def _outside(v: Any, limit: float) -> Any:
    """``not |v| <= limit`` on a float or an array: NaN is outside."""
    return (abs(v) > limit) | (v != v)


def _range(name: str, value: float, upper: float | None = None) -> float:
    v = finite_scalar(name, value, nonnegative=True)
    if upper is not None and v > upper:
        raise DesignError(f"{name} must be at most {upper:g}; found {v:g}")
    return v


class SwingUpTask(Task):
    """Swing the torque-limited pendulum up from hanging and balance it upright.

    Reward per step ``-(d^2 + 0.1 w^2 + 0.001 a^2)`` with ``d`` the angle from upright wrapped
    to ``[-pi, pi)``, ``w`` the angular velocity [rad/s] and ``a`` the action (torque over
    ``max_torque``); range about ``[-16, 0]``.

    Parameters
    ----------
    max_torque : float, default 0.5
        Torque per unit action [N m], positive.
    start_noise : float, default 0.1
        Half width of the uniform draw of the initial angle [rad] and velocity [rad/s].

    Raises
    ------
    DesignError
        A limit that is not positive and finite, or a ``start_noise`` that is negative or not
        finite.

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.envs.tasks import SwingUpTask
    >>> task = SwingUpTask(max_torque=0.5)
    >>> x0 = task.initial_state(np.random.default_rng(0))
    >>> reward, terms = task.reward(x0, [0.0], ())
    >>> round(reward, 3), sorted(terms)
    (-9.698, ['reward_control', 'reward_upright', 'reward_velocity'])
    """

    plant = "pendulum"
    physics_dt = 0.02
    control_period = 0.04
    sample_period = None
    integrator = "Euler"
    max_episode_steps = 250
    #: the 100 %-solved agents of docs/results/rl_seeds.md return -318 +- 25; hanging still -2467
    reward_threshold = -400.0
    default_observer = "high_gain"
    observer_defaults: ClassVar[dict[str, dict[str, Any]]] = {
        "high_gain": {"k": 10.0, "model": True},
        "high_gain_multi": {"k": 20.0, "orders": (2,)},
        "adaptive_gain": {"lam": 0.04, "lam_hat": 0.08, "gamma": 200.0, "k0": 20.0,
                          "k_max": 60.0, "method": "exact"},
        "riccati": {"gamma": 20.0},
        "q_integral": {"gamma": 20.0, "q": 1},
        "besancon": {"lam": 10.0},
    }
    default_sensor = ({"stage": "gaussian", "std": 0.01},)
    periodic = frozenset({"angle"})

    def __init__(self, max_torque: float = 0.5, start_noise: float = 0.1) -> None:
        super().__init__((max_torque,))
        self.max_torque = self.max_action[0]
        self.start_noise = _range("start_noise", start_noise)

    def initial_state(self, rng: np.random.Generator) -> list[float]:
        s = self.start_noise
        r0, r1 = rng.random(2).tolist()
        return [s * (2.0 * r0 - 1.0), s * (2.0 * r1 - 1.0)]

    def reward_terms(self, x: Any, u: Any, goal: Any) -> tuple[Any, dict[str, Any]]:
        d = _wrap(x[0] - math.pi)
        a = u[0] / self.max_torque
        upright, velocity, control = -d * d, -0.1 * x[1] * x[1], -0.001 * a * a
        return upright + velocity + control, {"reward_upright": upright,
                                              "reward_velocity": velocity,
                                              "reward_control": control}

    def target_state(self, x: Any, goal: Any) -> list[float]:
        """Upright, still."""
        return [math.pi, 0.0]

    def params(self) -> dict[str, Any]:
        return {"max_torque": self.max_torque, "start_noise": self.start_noise}


class BalanceTask(Task):
    """Keep Ibrir's inverted pendulum upright through the pivot acceleration.

    Reward per step ``1 - x1^2 - 0.01 a^2`` while ``|x1| <= max_angle``; the episode ends when
    ``|x1| > max_angle``.

    Parameters
    ----------
    max_acceleration : float, default 2.0
        Pivot acceleration per unit action [g], positive.
    max_angle : float, default 0.5
        Termination angle [rad], positive.
    start_noise : float, default 0.2
        Half width of the uniform draw of the initial angle and angular velocity; at most
        ``max_angle``.

    Raises
    ------
    DesignError
        A limit that is not positive and finite, or a ``start_noise`` that is negative or not
        finite, or larger than ``max_angle``.

    Examples
    --------
    >>> from hgo_mj.envs.tasks import BalanceTask
    >>> task = BalanceTask(max_angle=0.5)
    >>> round(task.reward([0.1, 0.0], [0.0], ())[0], 3), task.terminated([0.6, 0.0])
    (0.99, True)
    """

    plant = "cart_pendulum"
    physics_dt = 0.01
    control_period = 0.05
    sample_period = 0.01
    integrator = None
    max_episode_steps = 400
    #: 95 % of the 400 steps' alive bonus, as CartPole-v1's 475 of 500
    reward_threshold = 380.0
    default_observer = "high_gain"
    observer_defaults: ClassVar[dict[str, dict[str, Any]]] = {
        "high_gain": {"k": 10.0, "model": True},
        "high_gain_multi": {"k": 10.0, "orders": (2,)},
        "adaptive_gain": {"lam": 0.02, "lam_hat": 0.04, "gamma": 200.0, "k0": 10.0,
                          "k_max": 40.0, "model": True, "method": "exact"},
        "riccati": {"gamma": 6.0},
        "q_integral": {"gamma": 6.0, "q": 1},
        "besancon": {"lam": 10.0},
    }
    default_sensor = ({"stage": "gaussian", "std": 0.005},)

    def __init__(self, max_acceleration: float = 2.0, max_angle: float = 0.5,
                 start_noise: float = 0.2) -> None:
        super().__init__((max_acceleration,))
        self.max_acceleration = self.max_action[0]
        self.max_angle = finite_scalar("max_angle", max_angle, positive=True)
        self.start_noise = _range("start_noise", start_noise, self.max_angle)

    def initial_state(self, rng: np.random.Generator) -> list[float]:
        s = self.start_noise
        return rng.uniform(-s, s, 2).tolist()

    def reward_terms(self, x: Any, u: Any, goal: Any) -> tuple[Any, dict[str, Any]]:
        a = u[0] / self.max_acceleration
        angle, control = -x[0] * x[0], -0.01 * a * a
        return 1.0 + angle + control, {"reward_alive": 1.0, "reward_angle": angle,
                                       "reward_control": control}

    def termination(self, x: Any) -> Any:
        return _outside(x[0], self.max_angle)

    def target_state(self, x: Any, goal: Any) -> list[float]:
        """Upright (``x1 = 0``), still."""
        return [0.0, 0.0]

    def params(self) -> dict[str, Any]:
        return {"max_acceleration": self.max_acceleration, "max_angle": self.max_angle,
                "start_noise": self.start_noise}


class ReachTask(Task):
    """Bring the link of the elastic joint to a target angle drawn at reset, without vibration.

    Reward per step ``-min(e^2 + 0.01 q'^2 + 0.01 (q' - theta')^2 + 0.001 a^2, max_cost)``
    with ``e`` the link angle error [rad], ``q'`` the link velocity and ``q' - theta'`` the
    deflection rate of the spring [rad/s] (residual vibration), ``a`` the action; the bound
    keeps a runaway (the link whirling) from dominating returns.

    Parameters
    ----------
    max_torque : float, default 2.0
        Motor torque per unit action [N m], positive.
    target_range : float, default 1.0
        Half width of the uniform target draw [rad], at most pi.
    start_noise : float, default 0.1
        Half width of the uniform draw of the initial link (and motor) angle [rad].
    max_cost : float, default 10.0
        Bound of the per-step cost, positive.

    Raises
    ------
    DesignError
        A limit that is not positive and finite, or a ``start_noise`` that is negative or not
        finite, or a ``target_range`` above pi.

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.envs.tasks import ReachTask
    >>> task = ReachTask()
    >>> goal = task.sample_goal(np.random.default_rng(0))
    >>> [round(g, 3) for g in goal], task.goal_names
    ([0.274], ('target_link_angle',))
    >>> round(task.reward([0.0, 0.0, 0.0, 0.0], [0.0], goal)[0], 3)
    -0.075
    """

    plant = "elastic_joint"
    physics_dt = 0.001
    control_period = 0.01
    sample_period = 0.002
    integrator = None
    max_episode_steps = 300
    #: the true-state agent of docs/results/rl_seeds.md returns -6.8 and solves 80 %
    reward_threshold = -10.0
    default_observer = "high_gain"
    observer_defaults: ClassVar[dict[str, dict[str, Any]]] = {
        "high_gain": {"k": 80.0, "model": True},
        "high_gain_multi": {"k": 80.0, "orders": (4,)},
        "adaptive_gain": {"lam": 0.004, "lam_hat": 0.008, "gamma": 1000.0, "k0": 80.0,
                          "k_max": 200.0, "model": True, "method": "exact"},
        "riccati": {"gamma": 80.0},
        "q_integral": {"gamma": 80.0, "q": 1},
        "besancon": {"lam": 40.0},
    }
    default_sensor = ({"stage": "gaussian", "std": 0.001},
                      {"stage": "quantize", "counts_per_rev": 16384})
    goal_names = ("target_link_angle",)
    #: the start is at rest with the spring relaxed: the motor at the link's angle
    start_ties = (("motor_angle", "link_angle"),)

    def __init__(self, max_torque: float = 2.0, target_range: float = 1.0,
                 start_noise: float = 0.1, max_cost: float = 10.0) -> None:
        super().__init__((max_torque,))
        self.max_torque = self.max_action[0]
        self.target_range = _range("target_range", target_range, math.pi)
        self.start_noise = _range("start_noise", start_noise)
        self.max_cost = finite_scalar("max_cost", max_cost, positive=True)

    def initial_state(self, rng: np.random.Generator) -> list[float]:
        q = float(rng.uniform(-self.start_noise, self.start_noise))
        return [q, q, 0.0, 0.0]

    def sample_goal(self, rng: np.random.Generator) -> tuple[float, ...]:
        return (float(rng.uniform(-self.target_range, self.target_range)),)

    def reward_terms(self, x: Any, u: Any, goal: Any) -> tuple[Any, dict[str, Any]]:
        e = x[0] - goal[0]
        a = u[0] / self.max_torque
        defl = x[2] - x[3]
        terms = {"reward_tracking": -e * e, "reward_velocity": -0.01 * x[2] * x[2],
                 "reward_vibration": -0.01 * defl * defl, "reward_control": -0.001 * a * a}
        return np.maximum(_total(terms), -self.max_cost), terms

    def target_state(self, x: Any, goal: Any) -> list[float]:
        """Link and motor at the target angle, still."""
        return [goal[0], goal[0], 0.0, 0.0]

    def params(self) -> dict[str, Any]:
        return {"max_torque": self.max_torque, "target_range": self.target_range,
                "start_noise": self.start_noise, "max_cost": self.max_cost}


class Reach2LinkTask(Task):
    """Bring both links of the elastic two-link arm to target angles drawn at reset.

    Reward per step ``-min(sum_i (e_i^2 + 0.01 q_i'^2 + 0.01 (q_i' - theta_i')^2
    + 0.001 a_i^2), max_cost)``.

    Parameters
    ----------
    max_torque : tuple of float, default (6.0, 2.0)
        Torques of motors 1 and 2 per unit action [N m], positive.
    target_range : float, default 0.8
        Half width of each uniform target draw [rad], at most pi.
    start_noise : float, default 0.1
        Half width of the uniform draw of each initial link (and motor) angle [rad].
    max_cost : float, default 10.0
        Bound of the per-step cost, positive.

    Raises
    ------
    DesignError
        A limit that is not positive and finite, or a ``start_noise`` that is negative or not
        finite, a ``target_range`` above pi, or a ``max_torque`` that is not two numbers.

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.envs.tasks import Reach2LinkTask
    >>> task = Reach2LinkTask()
    >>> task.max_action, task.goal_names
    ((6.0, 2.0), ('target_link1_angle', 'target_link2_angle'))
    >>> [round(g, 3) for g in task.sample_goal(np.random.default_rng(0))]
    [0.219, -0.368]
    """

    plant = "elastic_joint_2link"
    physics_dt = 0.001
    control_period = 0.01
    sample_period = 0.002
    integrator = None
    max_episode_steps = 300
    #: the single link's threshold for each of the two links
    reward_threshold = -20.0
    default_observer = "high_gain_multi"
    observer_defaults: ClassVar[dict[str, dict[str, Any]]] = {
        "high_gain_multi": {"k": 150.0, "orders": (4, 4)},
        # single-output observers, so that their own error says why they do not apply
        "high_gain": {"k": 150.0},
        "adaptive_gain": {"lam": 0.004, "lam_hat": 0.008, "gamma": 1000.0, "k0": 150.0},
        "riccati": {"gamma": 150.0},
        "q_integral": {"gamma": 150.0, "q": 1},
        "besancon": {"lam": 40.0},
    }
    default_sensor = ({"stage": "gaussian", "std": 0.001},
                      {"stage": "quantize", "counts_per_rev": 16384})
    goal_names = ("target_link1_angle", "target_link2_angle")
    #: the start is at rest with the springs relaxed: each motor at its link's angle
    start_ties = (("motor1_angle", "link1_angle"), ("motor2_angle", "link2_angle"))
    #: gain of the fallback per-link observers
    fallback_k: ClassVar[float] = 150.0

    def __init__(self, max_torque: tuple[float, float] = (6.0, 2.0), target_range: float = 0.8,
                 start_noise: float = 0.1, max_cost: float = 10.0) -> None:
        mt = tuple(max_torque)
        if len(mt) != 2:
            raise DesignError(f"max_torque must give two torques (N m); found {max_torque!r}")
        super().__init__(mt)
        self.max_torque = self.max_action
        self.target_range = _range("target_range", target_range, math.pi)
        self.start_noise = _range("start_noise", start_noise)
        self.max_cost = finite_scalar("max_cost", max_cost, positive=True)

    def fallback_observer(self, system: Any, sample_period: float) -> Observer | None:
        """Model-free high-gain chains of order 4, one per link angle (paper 000's point: only
        the relative degree is known), when ``high_gain_multi`` is not registered."""
        chains = [HighGainObserver(order=4, k=self.fallback_k, outputs=(i,)) for i in range(2)]
        return ObserverBank(chains, output_names=system.output_names)

    def initial_state(self, rng: np.random.Generator) -> list[float]:
        q1, q2 = rng.uniform(-self.start_noise, self.start_noise, 2).tolist()
        return [q1, q2, q1, q2, 0.0, 0.0, 0.0, 0.0]

    def sample_goal(self, rng: np.random.Generator) -> tuple[float, ...]:
        return tuple(rng.uniform(-self.target_range, self.target_range, 2).tolist())

    def reward_terms(self, x: Any, u: Any, goal: Any) -> tuple[Any, dict[str, Any]]:
        e1, e2 = x[0] - goal[0], x[1] - goal[1]
        d1, d2 = x[4] - x[6], x[5] - x[7]
        a1, a2 = u[0] / self.max_torque[0], u[1] / self.max_torque[1]
        terms = {"reward_tracking": -(e1 * e1 + e2 * e2),
                 "reward_velocity": -0.01 * (x[4] * x[4] + x[5] * x[5]),
                 "reward_vibration": -0.01 * (d1 * d1 + d2 * d2),
                 "reward_control": -0.001 * (a1 * a1 + a2 * a2)}
        return np.maximum(_total(terms), -self.max_cost), terms

    def target_state(self, x: Any, goal: Any) -> list[float]:
        """Both links and motors at their targets, still."""
        return [goal[0], goal[1], goal[0], goal[1], 0.0, 0.0, 0.0, 0.0]

    def params(self) -> dict[str, Any]:
        return {"max_torque": list(self.max_torque), "target_range": self.target_range,
                "start_noise": self.start_noise, "max_cost": self.max_cost}


class LabSwingUpTask(Task):
    """Swing a lab plant (an MJCF under ``models/``, run through the generic MJCF path) up
    from hanging and balance it; subclasses name the plant, its encoders and the targets.

    Reward per step ``-(sum_i e_i^2 + 0.01 sum_j v_j^2 + 0.001 sum a^2)``: ``e_i`` the error of
    each target coordinate (angles wrapped to ``[-pi, pi)``), ``v_j`` the joint velocities,
    ``a`` the action. The episode ends when a coordinate leaves its limit (the cart's track).

    Parameters
    ----------
    max_input : float
        Input per unit action (plant units: V, N m or N), positive.
    start_noise : float, default 0.05
        Half width of the uniform draw of every initial state entry.
    reward : str, default "quadratic"
        The reward above (v0), or one of the plant's literature's (:attr:`reward_names`,
        :meth:`literature_reward`; v1).

    Raises
    ------
    DesignError
        A limit that is not positive and finite, a ``start_noise`` that is negative or not
        finite, or a ``reward`` that is not one of :attr:`reward_names`.

    Examples
    --------
    A subclass names the plant, its encoders and the targets (here the cart-pole's):

    >>> from hgo_mj.envs.tasks import CartPoleSwingUpTask, LabSwingUpTask
    >>> issubclass(CartPoleSwingUpTask, LabSwingUpTask)
    True
    >>> CartPoleSwingUpTask.plant_outputs, CartPoleSwingUpTask.limits
    (('cart_position', 'pole_angle'), ((0, 2.4),))
    """

    #: MJCF sensors read by the encoders (the plant's outputs)
    plant_outputs: ClassVar[tuple[str, ...]] = ()
    #: (state index, target value, wrapped angle?) of each target coordinate
    targets: ClassVar[tuple[tuple[int, float, bool], ...]] = ()
    #: (state index, limit): ``|x[index]| > limit`` ends the episode
    limits: ClassVar[tuple[tuple[int, float], ...]] = ()
    physics_dt = 0.001
    control_period = 0.01
    sample_period = 0.002
    integrator = None
    max_episode_steps = 500
    #: a fifth of hanging still (-4935 over 500 steps): the swing within 1 s, then upright
    reward_threshold = -1000.0
    default_observer = "high_gain_multi"
    #: single-output observers get parameters, so that their own error says why they do not
    #: apply (two outputs: no single-output normal form)
    single_output_defaults: ClassVar[dict[str, dict[str, Any]]] = {
        "high_gain": {"k": 30.0},
        "adaptive_gain": {"lam": 0.004, "lam_hat": 0.008, "gamma": 1000.0, "k0": 30.0},
        "riccati": {"gamma": 30.0},
        "q_integral": {"gamma": 30.0, "q": 1},
        "besancon": {"lam": 30.0},
    }

    #: the rewards a plant offers: ``"quadratic"`` (v0's, above) and its literature's (v1)
    reward_names: ClassVar[tuple[str, ...]] = ("quadratic",)
    #: band around each wrapped target angle [rad] that counts as upright (:meth:`at_target`)
    upright_band: ClassVar[float] = math.radians(12.0)
    #: the last steps of an episode that must all be upright for it to be *solved* (1 s)
    hold_steps: ClassVar[int] = 100

    def __init__(self, max_input: float, start_noise: float = 0.05,
                 reward: str = "quadratic") -> None:
        super().__init__((max_input,))
        self.max_input = self.max_action[0]
        self.start_noise = _range("start_noise", start_noise)
        if reward not in self.reward_names:
            raise DesignError(f"reward must be one of {list(self.reward_names)}; found {reward!r}")
        self.reward_name = reward

    def initial_state(self, rng: np.random.Generator) -> list[float]:
        n = 2 * len(self.plant_outputs)
        return rng.uniform(-self.start_noise, self.start_noise, n).tolist()

    def at_target(self, x: Any) -> Any:
        """Every target angle within :attr:`upright_band` of its target (wrapped): the state
        of a *solved* episode's last :attr:`hold_steps` steps (``scripts/eval_rl.py``), the
        episode not terminated.

        Parameters
        ----------
        x : sequence of float or (n, B) array
            A true state, or a batch's columns.

        Returns
        -------
        bool or (B,) bool array

        Examples
        --------
        >>> import math
        >>> from hgo_mj.envs.tasks import CartPoleSwingUpTask
        >>> task = CartPoleSwingUpTask()
        >>> bool(task.at_target([1.0, math.pi + 0.2, 0.0, 0.0]))
        True
        >>> bool(task.at_target([0.0, math.pi + 0.3, 0.0, 0.0]))
        False
        """
        out: Any = True
        for i, value, wrapped in self.targets:
            if wrapped:
                out = out & ~_outside(_wrap(x[i] - value), self.upright_band)
        return out

    def literature_reward(self, x: Any, a: Any) -> tuple[Any, dict[str, Any]]:
        """The reward of the plant's literature (``reward != "quadratic"``); the subclass
        gives it.

        Parameters
        ----------
        x : sequence of float or (n, B) array
            The true state at the end of the step, or a batch's columns.
        a : float or (B,) array
            The action: the input over ``max_input``.

        Returns
        -------
        reward : float or (B,) array
        terms : dict of str to float or (B,) array
            Its terms (or factors), keyed ``reward_<term>``.

        Examples
        --------
        >>> import math
        >>> from hgo_mj.envs.tasks import FurutaSwingUpTask
        >>> task = FurutaSwingUpTask(reward="quanser")
        >>> [round(float(task.literature_reward([0.0, q, 0.0, 0.0], 0.0)[0]), 2)
        ...  for q in (0.0, math.pi / 2, math.pi)]
        [0.2, 0.6, 1.0]

        Raises
        ------
        NotImplementedError
            The plant has none (only ``"quadratic"`` in :attr:`reward_names`).
        """
        raise NotImplementedError(f"{type(self).__name__} has no literature reward")

    def reward_terms(self, x: Any, u: Any, goal: Any) -> tuple[Any, dict[str, Any]]:
        if self.reward_name != "quadratic":
            return self.literature_reward(x, u[0] / self.max_input)
        target: Any = 0.0
        for i, value, wrapped in self.targets:
            e = x[i] - value
            if wrapped:
                e = _wrap(e)
            target = target - e * e
        velocity: Any = 0.0
        for j in range(len(x) // 2, len(x)):
            velocity = velocity + x[j] * x[j]
        velocity = -0.01 * velocity
        a = u[0] / self.max_input
        control = -0.001 * a * a
        return target + velocity + control, {"reward_target": target,
                                             "reward_velocity": velocity,
                                             "reward_control": control}

    def termination(self, x: Any) -> Any:
        out: Any = False
        for i, limit in self.limits:
            out = out | _outside(x[i], limit)
        return out

    def target_state(self, x: Any, goal: Any) -> list[float]:
        """Each target coordinate at its target (the others where they are), still."""
        n = len(x) // 2
        t = [float(v) for v in x[:n]] + [0.0] * n
        for i, value, _ in self.targets:
            t[i] = value
        return t

    def params(self) -> dict[str, Any]:
        extra = {} if self.reward_name == "quadratic" else {"reward": self.reward_name}
        return {"max_input": self.max_input, "start_noise": self.start_noise, **extra}


def _tolerance_gaussian(d: Any, margin: float) -> Any:
    """dm_control's ``rewards.tolerance(d, bounds=(0, 0), margin, sigmoid="gaussian",
    value_at_margin=0.1)`` of a distance ``d`` outside the bounds: 1 at 0, 0.1 at ``margin``."""
    z = d / margin
    return np.exp(-0.5 * z * z * (-2.0 * math.log(0.1)))


class FurutaSwingUpTask(LabSwingUpTask):
    """The QUBE-Servo 2 rotary pendulum (``models/furuta.xml``): pendulum to pi, by voltage.

    Parameters
    ----------
    max_input : float, default 10.0
        Motor voltage per unit action [V], positive.
    start_noise : float, default 0.05
        Half width of the uniform draw of every initial state entry.
    reward : {"quadratic", "quanser"}, default "quadratic"
        :class:`LabSwingUpTask`'s quadratic reward (v0), or Quanser's Qube swing-up reward and arm limit (v1).

    Raises
    ------
    DesignError
        A limit that is not positive and finite, or a ``start_noise`` that is negative or not
        finite.

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.envs.tasks import FurutaSwingUpTask
    >>> task = FurutaSwingUpTask()
    >>> task.plant_outputs, task.max_action
    (('arm_angle', 'pendulum_angle'), (10.0,))
    >>> x0 = task.initial_state(np.random.default_rng(0))
    >>> round(task.reward(x0, [0.0], ())[0], 2)
    -9.73
    """

    plant = "furuta.xml"
    plant_outputs = ("arm_angle", "pendulum_angle")
    targets = ((1, math.pi, True),)
    observer_defaults: ClassVar[dict[str, dict[str, Any]]] = {
        **LabSwingUpTask.single_output_defaults, "high_gain_multi": {"k": 40.0, "model": True}}
    default_sensor = ({"stage": "quantize", "counts_per_rev": [2048, 2048]},)
    periodic = frozenset({"arm_angle", "pendulum_angle"})
    reward_names = ("quadratic", "quanser")
    #: the Qube balance band (:class:`FurutaBalanceTask`)
    upright_band = math.radians(20.0)

    def __init__(self, max_input: float = 10.0, start_noise: float = 0.05,
                 reward: str = "quadratic") -> None:
        super().__init__(max_input, start_noise, reward)

    def literature_reward(self, x: Any, a: Any) -> tuple[Any, dict[str, Any]]:
        """Quanser's Qube swing-up reward (quanser-openai-driver, ``QubeSwingupEnv``):
        ``max(1 - (0.8 |alpha| + 0.2 |theta|) / pi, 0)``, ``alpha`` the pendulum's angle from
        upright (wrapped), ``theta`` the arm's angle; no control term."""
        alpha = _wrap(x[1] - math.pi)
        r = np.maximum(1.0 - (0.8 * abs(alpha) + 0.2 * abs(x[0])) / math.pi, 0.0)
        return r, {"reward_upright": r}

    def termination(self, x: Any) -> Any:
        """With ``reward="quanser"`` the Qube swing-up's end: the arm beyond 90 degrees."""
        out: Any = super().termination(x)
        if self.reward_name == "quanser":
            out = out | _outside(x[0], math.pi / 2)
        return out


class AcrobotSwingUpTask(LabSwingUpTask):
    """Spong's acrobot (``models/acrobot.xml``): shoulder to pi, elbow straight, by elbow torque.

    Parameters
    ----------
    max_input : float, default 20.0
        Elbow torque per unit action [N m], positive.
    start_noise : float, default 0.05
        Half width of the uniform draw of every initial state entry.
    reward : {"quadratic", "dm_control"}, default "quadratic"
        :class:`LabSwingUpTask`'s quadratic reward (v0), or dm_control's ``acrobot.swingup`` reward (v1).

    Raises
    ------
    DesignError
        A limit that is not positive and finite, or a ``start_noise`` that is negative or not
        finite.

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.envs.tasks import AcrobotSwingUpTask
    >>> task = AcrobotSwingUpTask()
    >>> task.plant_outputs, task.max_action
    (('shoulder_angle', 'elbow_angle'), (20.0,))
    >>> x0 = task.initial_state(np.random.default_rng(0))
    >>> round(task.reward(x0, [0.0], ())[0], 2)
    -9.78
    """

    plant = "acrobot.xml"
    plant_outputs = ("shoulder_angle", "elbow_angle")
    targets = ((0, math.pi, True), (1, 0.0, True))
    observer_defaults: ClassVar[dict[str, dict[str, Any]]] = {
        **LabSwingUpTask.single_output_defaults, "high_gain_multi": {"k": 30.0, "model": True}}
    default_sensor = ({"stage": "quantize", "counts_per_rev": [4096, 4096]},)
    periodic = frozenset({"shoulder_angle", "elbow_angle"})
    reward_names = ("quadratic", "dm_control")
    #: the balance band (:class:`AcrobotBalanceTask`), on both joints
    upright_band = math.radians(20.0)
    #: link lengths [m] (``models/acrobot.xml``)
    links = (1.0, 2.0)

    def __init__(self, max_input: float = 20.0, start_noise: float = 0.05,
                 reward: str = "quadratic") -> None:
        super().__init__(max_input, start_noise, reward)

    def literature_reward(self, x: Any, a: Any) -> tuple[Any, dict[str, Any]]:
        """dm_control's ``acrobot.swingup`` reward: ``tolerance(|tip - target|, bounds=(0,
        0.2), margin=1)`` for its two 1 m links, the target the tip's upright position; here
        radius and margin scaled by the arm's length (3 m against 2 m): 0.3 and 1.5 [m]. 1
        within the radius, 0.1 at the margin beyond it (Gaussian), in ``[0, 1]``."""
        l1, l2 = self.links
        q12 = x[0] + x[1]
        tip_x = -l1 * np.sin(x[0]) - l2 * np.sin(q12)
        tip_z = -l1 * np.cos(x[0]) - l2 * np.cos(q12)
        dist = np.sqrt(tip_x * tip_x + (tip_z - l1 - l2) ** 2)
        r = _tolerance_gaussian(np.maximum(dist - 0.3, 0.0), 1.5)
        return r, {"reward_reach": r}


class CartPoleSwingUpTask(LabSwingUpTask):
    """The cart-pole (``models/cart_pole.xml``): pole to pi, cart centred and on its track
    (``|cart| <= 2.4 m``), by the force on the cart.

    Parameters
    ----------
    max_input : float, default 10.0
        Force on the cart per unit action [N], positive.
    start_noise : float, default 0.05
        Half width of the uniform draw of every initial state entry.
    reward : {"quadratic", "dm_control"}, default "quadratic"
        :class:`LabSwingUpTask`'s quadratic reward (v0), or dm_control's smooth
        ``cartpole.swingup`` reward (v1).
    end_stops : bool, default False
        The track's ends stop the cart (``models/cart_pole_track.xml``, a soft joint limit at
        +-2.4 m, as dm_control's) and the episode does not end there (v1); else the episode
        ends when the cart leaves its track (v0).

    Raises
    ------
    DesignError
        A limit that is not positive and finite, a ``start_noise`` that is negative or not
        finite, or an ``end_stops`` that is not a bool.

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.envs.tasks import CartPoleSwingUpTask
    >>> task = CartPoleSwingUpTask()
    >>> task.plant_outputs, task.max_action
    (('cart_position', 'pole_angle'), (10.0,))
    >>> x0 = task.initial_state(np.random.default_rng(0))
    >>> round(task.reward(x0, [0.0], ())[0], 2)
    -9.73
    """

    plant = "cart_pole.xml"
    plant_outputs = ("cart_position", "pole_angle")
    targets = ((1, math.pi, True), (0, 0.0, False))
    limits = ((0, 2.4),)
    observer_defaults: ClassVar[dict[str, dict[str, Any]]] = {
        **LabSwingUpTask.single_output_defaults, "high_gain_multi": {"k": 30.0, "model": True}}
    #: cart: 4096 counts/rev on a pinion of radius 0.01482 m; pole: 4096 counts/rev
    default_sensor = ({"stage": "quantize",
                       "resolution": [_TWO_PI * 0.01482 / 4096, _TWO_PI / 4096]},)
    periodic = frozenset({"pole_angle"})
    reward_names = ("quadratic", "dm_control")

    def __init__(self, max_input: float = 10.0, start_noise: float = 0.05,
                 reward: str = "quadratic", end_stops: bool = False) -> None:
        super().__init__(max_input, start_noise, reward)
        if not isinstance(end_stops, bool):
            raise DesignError(f"end_stops must be True or False; found {end_stops!r}")
        self.end_stops = end_stops
        if end_stops:  # this instance's plant: the one with the track's end stops
            self.plant = "cart_pole_track.xml"  # type: ignore[misc]

    def literature_reward(self, x: Any, a: Any) -> tuple[Any, dict[str, Any]]:
        """dm_control's smooth ``cartpole.swingup`` reward (Tassa et al. 2018, ``cartpole.py``
        ``_get_reward``), in ``[0, 1]``: ``upright * centered * small_control *
        small_velocity`` with ``upright = (1 + cos(pole from upright)) / 2``, ``centered = (1 +
        tolerance(x, margin=2)) / 2``, ``small_control = (4 + max(1 - a^2, 0)) / 5`` and
        ``small_velocity = (1 + tolerance(w, margin=5)) / 2`` (Gaussian tolerances, 0.1 at
        the margin)."""
        upright = (1.0 - np.cos(x[1])) / 2.0  # the pole angle is 0 hanging, pi upright
        centered = (1.0 + _tolerance_gaussian(x[0], 2.0)) / 2.0
        small_control = (4.0 + np.maximum(1.0 - a * a, 0.0)) / 5.0
        small_velocity = (1.0 + _tolerance_gaussian(x[3], 5.0)) / 2.0
        r = upright * centered * small_control * small_velocity
        return r, {"reward_upright": upright, "reward_centered": centered,
                   "reward_small_control": small_control, "reward_small_velocity": small_velocity}

    def termination(self, x: Any) -> Any:
        """v0: the cart off its track (``|x| > 2.4`` m). With ``end_stops`` none: the stops
        hold the cart, as dm_control's slider range (+-1.8 m) does. With a reward in [0, 1]
        and 0 hanging, ending the episode at the track's end paid the cart to run off it (PPO
        and SAC both learned that, returns of about 8 in 0.8 s)."""
        if self.end_stops:
            return np.zeros(np.shape(x[0]), dtype=bool)
        return super().termination(x)

    def params(self) -> dict[str, Any]:
        return {**super().params(), **({"end_stops": True} if self.end_stops else {})}

    def at_target(self, x: Any) -> Any:
        """The pole within :attr:`upright_band` of upright and the cart on its track."""
        return super().at_target(x) & ~_outside(x[0], self.limits[0][1])


class LabBalanceTask(LabSwingUpTask):
    """Keep a lab plant upright from a start near upright (the balance variant of a
    :class:`LabSwingUpTask`; subclasses also derive from the plant's swing-up task, which
    names the plant, its encoders, its targets and its track limits).

    Reward ``+1`` per step while upright, the alive bonus of Gymnasium's ``CartPole-v1`` and
    ``InvertedPendulum`` (Barto, Sutton and Anderson 1983); the episode ends when a target
    angle leaves ``max_angle`` of its target (wrapped) or a coordinate its limit (a position
    target, the cart's, is bounded by its limit only).
    A return of ``max_episode_steps`` (500) is an episode balanced to the end: that is the
    *solved* criterion, and ``reward_threshold`` is 95 % of it (``CartPole-v1``: 475 of 500).

    Parameters
    ----------
    max_input : float
        Input per unit action (plant units), positive.
    start_noise : float
        Half width of the uniform draw of every initial state entry around upright; at most
        ``max_angle``.
    max_angle : float
        Termination band around each target coordinate [rad], positive.

    Raises
    ------
    DesignError
        A limit that is not positive and finite, or a ``start_noise`` that is negative, not
        finite or larger than ``max_angle``.

    Examples
    --------
    >>> import math
    >>> import numpy as np
    >>> from hgo_mj.envs.tasks import CartPoleBalanceTask
    >>> task = CartPoleBalanceTask()
    >>> x0 = task.initial_state(np.random.default_rng(0))
    >>> round(x0[1], 3), task.reward(x0, [0.0], ())[0], bool(task.terminated(x0))
    (3.119, 1.0, False)
    >>> bool(task.terminated([0.0, math.pi + 0.3, 0.0, 0.0]))
    True
    """

    max_episode_steps = 500
    reward_threshold = 475.0

    def __init__(self, max_input: float, start_noise: float, max_angle: float) -> None:
        super().__init__(max_input, start_noise)
        self.max_angle = finite_scalar("max_angle", max_angle, positive=True)
        self.start_noise = _range("start_noise", start_noise, self.max_angle)

    def initial_state(self, rng: np.random.Generator) -> list[float]:
        x = super().initial_state(rng)
        for i, value, _ in self.targets:
            x[i] += value
        return x

    def reward_terms(self, x: Any, u: Any, goal: Any) -> tuple[Any, dict[str, Any]]:
        shape = np.shape(x[0])  # () for one member, (B,) for a batch's columns
        return np.ones(shape), {"reward_alive": np.ones(shape)}

    def termination(self, x: Any) -> Any:
        out: Any = super().termination(x)
        for i, value, wrapped in self.targets:
            if wrapped:  # an angle; a position target (the cart's) is bounded by its limit
                out = out | _outside(_wrap(x[i] - value), self.max_angle)
        return out

    def params(self) -> dict[str, Any]:
        return {**super().params(), "max_angle": self.max_angle}


class FurutaBalanceTask(LabBalanceTask, FurutaSwingUpTask):
    """Balance the QUBE-Servo 2 pendulum upright, the arm within a quarter turn.

    Termination as Quanser's balance controller's and the Qube balance environment's
    (quanser-openai-driver, ``QubeBalanceEnv``): the pendulum beyond 20 degrees of upright
    or the arm beyond 90 degrees.

    Parameters
    ----------
    max_input : float, default 10.0
        Motor voltage per unit action [V].
    start_noise : float, default 0.05
        Half width of the initial state draw around upright.
    max_angle : float, default 20 degrees (0.349 rad)
        Band of the pendulum around upright [rad].

    Examples
    --------
    >>> from hgo_mj.envs.tasks import FurutaBalanceTask
    >>> FurutaBalanceTask().limits, FurutaBalanceTask.reward_threshold
    (((0, 1.5707963267948966),), 475.0)
    """

    limits = ((0, math.pi / 2),)

    def __init__(self, max_input: float = 10.0, start_noise: float = 0.05,
                 max_angle: float = math.radians(20.0)) -> None:
        LabBalanceTask.__init__(self, max_input, start_noise, max_angle)


class AcrobotBalanceTask(LabBalanceTask, AcrobotSwingUpTask):
    """Balance Spong's acrobot upright (shoulder at pi, elbow straight) by the elbow torque.

    No standard acrobot balance task exists (Gymnasium's and dm_control's acrobots are
    swing-ups); Spong (1995) switches to his balancing controller near upright, and the band
    here is the Qube's 20 degrees on both joints.

    Parameters
    ----------
    max_input : float, default 20.0
        Elbow torque per unit action [N m].
    start_noise : float, default 0.05
        Half width of the initial state draw around upright.
    max_angle : float, default 20 degrees (0.349 rad)
        Band of the shoulder (from pi) and the elbow (from 0) [rad].

    Examples
    --------
    >>> from hgo_mj.envs.tasks import AcrobotBalanceTask
    >>> AcrobotBalanceTask().targets
    ((0, 3.141592653589793, True), (1, 0.0, True))
    """

    def __init__(self, max_input: float = 20.0, start_noise: float = 0.05,
                 max_angle: float = math.radians(20.0)) -> None:
        LabBalanceTask.__init__(self, max_input, start_noise, max_angle)


class CartPoleBalanceTask(LabBalanceTask, CartPoleSwingUpTask):
    """Balance the cart-pole: Gymnasium's ``CartPole-v1`` (after Barto, Sutton and Anderson
    1983) with a continuous force.

    As ``CartPole-v1``: start uniform within 0.05 of upright and centred, the episode ends
    when the pole is beyond 12 degrees of upright or the cart beyond 2.4 m, +1 per step, 500
    steps. dm_control's ``cartpole.balance`` starts the same way and rewards upright,
    centred and still instead.

    Parameters
    ----------
    max_input : float, default 10.0
        Force on the cart per unit action [N] (``CartPole-v1``'s force magnitude).
    start_noise : float, default 0.05
        Half width of the initial state draw around upright.
    max_angle : float, default 12 degrees (0.209 rad)
        Band of the pole around upright [rad].

    Examples
    --------
    >>> from hgo_mj.envs.tasks import CartPoleBalanceTask
    >>> round(CartPoleBalanceTask().max_angle, 4)
    0.2094
    """

    def __init__(self, max_input: float = 10.0, start_noise: float = 0.05,
                 max_angle: float = math.radians(12.0)) -> None:
        LabBalanceTask.__init__(self, max_input, start_noise, max_angle)


__all__ = ["AcrobotBalanceTask", "CartPoleBalanceTask", "FurutaBalanceTask", "LabBalanceTask",
           "AcrobotSwingUpTask", "BalanceTask", "CartPoleSwingUpTask", "FurutaSwingUpTask",
           "LabSwingUpTask", "Reach2LinkTask", "ReachTask", "SwingUpTask"]
