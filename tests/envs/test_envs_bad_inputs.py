"""Issue 14: a reset state the plant cannot take raises at reset naming the value (MuJoCo would
reset it to zero silently), and NaN or wrongly shaped actions raise a clear error."""

from __future__ import annotations

import gymnasium as gym
import hgo_mj.envs  # noqa: F401  (registers the environments)
import numpy as np
import pytest

from hgo_mj.exceptions import DesignError, DimensionError

IDS = [i for i in gym.registry if i.startswith("hgo_mj/")]


@pytest.fixture(params=IDS)
def env(request):
    e = gym.make(request.param).unwrapped
    yield e
    e.close()


def test_unreachable_reset_state_raises_naming_the_value(env):
    n = len(env.state_names)
    x0 = [0.0] * n
    x0[-1] = 1e12
    with pytest.raises(DesignError, match=rf"{env.state_names[-1]} = 1e\+12 is a state MuJoCo "
                                          rf"cannot take"):
        env.reset(options={"x0": x0})
    env.reset(seed=0)  # the environment is still usable


@pytest.mark.parametrize("x0, error, message", [
    ("nan", DesignError, "must be finite"),
    ("short", DimensionError, "must have length"),
    ("bool", DimensionError, "1-D array of numbers"),
])
def test_bad_reset_state_raises(env, x0, error, message):
    n = len(env.state_names)
    value = {"nan": [np.nan] * n, "short": [0.0] * (n - 1), "bool": [True] * n}[x0]
    with pytest.raises(error, match=message):
        env.reset(options={"x0": value})


def test_reset_state_within_range_is_taken_as_given():
    env = gym.make("hgo_mj/PendulumSwingUp-v0").unwrapped
    env.reset(options={"x0": [0.3, 1e9]})
    assert env.loop.plant.state.tolist() == [0.3, 1e9]


def test_bad_actions_raise(env):
    env.reset(seed=0)
    nu = env.action_space.shape[0]
    with pytest.raises(DesignError, match=r"action\[0\] is NaN"):
        env.step(np.full(nu, np.nan))
    with pytest.raises(DimensionError, match=rf"action must have {nu} entries; found {nu + 1}"):
        env.step(np.zeros(nu + 1))
    for bad in ([[0.0] * nu], "a", True, [True] * nu, ["0.1"] * nu):
        with pytest.raises(DimensionError, match="action must be a sequence of"):
            env.step(bad)
    env.step(np.zeros(nu))  # a good action still steps after the refusals


def test_documented(env):
    doc = type(env).__doc__
    assert "Bad actions and starting states raise" in doc
    assert "Raises" in type(env).reset.__doc__ and "Raises" in type(env).step.__doc__


def test_reset_options_not_a_dict_is_a_clear_error(env):
    """Issue 27 item 13: reset(options=5) names what it expected, not Python's TypeError."""
    with pytest.raises(DesignError, match=r"reset options must be a dict .*found int 5"):
        env.reset(options=5)


@pytest.mark.parametrize("goal", [1e300, -4.0, float("nan")])
def test_reach_goal_beyond_its_bound_is_refused(goal):
    """Issue 27 item 7: a goal outside the observation space's bound (pi) is refused."""
    env = gym.make("hgo_mj/ElasticJointReach-v0").unwrapped
    with pytest.raises(DesignError, match=r"options\['goal'\] must (lie in \[-3.14159, "
                                          r"3.14159\]|be finite)"):
        env.reset(options={"goal": [goal]})
    obs, _ = env.reset(options={"goal": [1.0]})
    assert obs[-1] == 1.0 or 1.0 in obs.tolist()
    env.close()
