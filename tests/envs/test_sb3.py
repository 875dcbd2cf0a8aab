"""hgo_mj.envs.sb3 without stable-baselines3: the same-step autoreset over the native vector
environment and the duck-typed ``VecEnv`` interface (tests/envs/test_sb3_rl.py checks it with
stable-baselines3 itself, where installed)."""

from __future__ import annotations

import subprocess
import sys

import gymnasium as gym
import hgo_mj.envs  # noqa: F401
import numpy as np
import pytest
from hgo_mj.envs.sb3 import Sb3VecEnvAdapter, same_step, sb3_vec_env

from hgo_mj.exceptions import DesignError


def test_same_step_resets_ended_members_at_once():
    """stable-baselines3's semantics over the NEXT_STEP vector environment: the observation
    after an episode's end is the next episode's first, the last one is in the info."""
    venv = gym.make_vec("hgo_mj/PendulumSwingUp-v0", num_envs=3, max_episode_steps=4)
    singles = [gym.make("hgo_mj/PendulumSwingUp-v0", max_episode_steps=4) for _ in range(3)]
    obs, _ = venv.reset(seed=[1, 2, 3])
    for i, env in enumerate(singles):
        env.reset(seed=i + 1)
    a = np.full((3, 1), 0.3, dtype=np.float32)
    for step in range(10):
        obs, rew, dones, infos = same_step(venv, a)
        assert rew.dtype == np.float32 and dones.dtype == bool
        for i, env in enumerate(singles):
            o, r, term, trunc, _ = env.step(a[i])
            assert np.float32(r) == rew[i]
            if term or trunc:
                assert dones[i] and infos[i]["TimeLimit.truncated"]
                assert np.array_equal(infos[i]["terminal_observation"], o)
                o, _ = env.reset()  # the generators go on, as the member's
            else:
                assert not dones[i] and infos[i] == {}
            assert np.array_equal(obs[i], o), (step, i)


def test_a_termination_is_not_a_time_limit():
    """A member the task ended (the cart-pole's pole beyond 12 degrees) is done, and its info
    says the time limit did not end it."""
    venv = Sb3VecEnvAdapter(gym.make_vec("hgo_mj/CartPoleBalance-v0", num_envs=2,
                                         observation="true"))
    venv.seed(5)
    venv.reset()
    for _ in range(200):
        obs, rew, dones, infos = venv.step(np.ones((2, 1), np.float32))
        if dones.any():
            break
    i = int(np.flatnonzero(dones)[0])
    assert infos[i]["TimeLimit.truncated"] is False
    last = infos[i]["terminal_observation"]  # cart, cos and sin of the pole, velocities
    assert abs(np.arctan2(last[2], last[1]) % (2 * np.pi) - np.pi) > np.radians(12.0)
    assert rew.tolist() == [1.0, 1.0]


def test_the_adapter_has_the_vecenv_interface_without_sb3():
    venv = Sb3VecEnvAdapter(gym.make_vec("hgo_mj/FurutaBalance-v0", num_envs=3,
                                         observation="true"))
    assert venv.num_envs == 3 and venv.observation_space.shape == (6,)
    assert venv.action_space.shape == (1,) and venv.unwrapped is venv
    assert venv.seed(7) == [7, 8, 9]
    obs = venv.reset()
    for i in range(3):  # member i is the single environment reset with seed 7 + i
        single, _ = gym.make("hgo_mj/FurutaBalance-v0", observation="true").reset(seed=7 + i)
        np.testing.assert_array_equal(obs[i], single)
    assert venv.get_attr("observation_mode") == ["true"] * 3
    assert venv.get_attr("observation_mode", indices=[0]) == ["true"]
    assert venv.env_is_wrapped(gym.Wrapper) == [False] * 3
    assert venv.get_images() == [None] * 3 and venv.render() is None
    with pytest.raises(DesignError, match="share one configuration: cannot set 'x'"):
        venv.set_attr("x", 1)
    with pytest.raises(DesignError, match="no per-member methods; found a call of 'reset'"):
        venv.env_method("reset")
    with pytest.raises(DesignError, match="takes no reset options"):
        venv.set_options({"x0": [0.0]})
    venv.set_options(None)
    venv.close()


def test_bad_arguments_are_refused():
    with pytest.raises(DesignError, match="venv must be an HgoVectorEnv.*found SyncVectorEnv"):
        Sb3VecEnvAdapter(gym.make_vec("hgo_mj/CartPoleBalance-v0", num_envs=2,
                                      vectorization_mode="sync"))
    with pytest.raises(DesignError, match="needs num_envs"):
        sb3_vec_env("hgo_mj/CartPoleBalance-v0")
    with pytest.raises(DesignError, match="go with an id"):
        sb3_vec_env(gym.make_vec("hgo_mj/CartPoleBalance-v0", num_envs=2), num_envs=2)


def test_importing_the_module_does_not_import_sb3():
    code = ("import sys, hgo_mj.envs.sb3; "
            "assert 'stable_baselines3' not in sys.modules, 'imported'")
    subprocess.run([sys.executable, "-c", code], check=True)
