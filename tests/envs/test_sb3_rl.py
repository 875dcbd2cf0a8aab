"""hgo_mj.envs.sb3 with stable-baselines3 (the ``rl`` extra; skipped without it): the adapter
is a ``VecEnv``, steps as SB3's own ``DummyVecEnv`` of single environments does, and trains."""

from __future__ import annotations

import pytest

sb3 = pytest.importorskip("stable_baselines3")

import gymnasium as gym  # noqa: E402
import hgo_mj.envs  # noqa: E402, F401
import numpy as np  # noqa: E402
from hgo_mj.envs.sb3 import Sb3VecEnvAdapter, sb3_vec_env  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecMonitor  # noqa: E402


def test_the_adapter_steps_as_dummy_vec_env_of_single_environments():
    """The same seeds, the same actions: the same observations, rewards, dones and terminal
    observations, across autoresets (4-step episodes)."""
    ours = sb3_vec_env("hgo_mj/CartPoleBalance-v0", num_envs=3, max_episode_steps=4)
    assert isinstance(ours, VecEnv) and isinstance(ours, Sb3VecEnvAdapter)
    theirs = DummyVecEnv([lambda: gym.make("hgo_mj/CartPoleBalance-v0", max_episode_steps=4)]
                         * 3)
    ours.seed(11)
    theirs.seed(11)
    np.testing.assert_array_equal(ours.reset(), theirs.reset())
    rng = np.random.default_rng(0)
    for _ in range(10):
        a = rng.uniform(-1, 1, (3, 1)).astype(np.float32)
        o1, r1, d1, i1 = ours.step(a)
        o2, r2, d2, i2 = theirs.step(a)
        np.testing.assert_array_equal(o1, o2)
        np.testing.assert_array_equal(r1, r2)
        np.testing.assert_array_equal(d1, d2)
        for a1, a2 in zip(i1, i2):
            if "terminal_observation" in a2:
                np.testing.assert_array_equal(a1["terminal_observation"],
                                              a2["terminal_observation"])
                assert a1["TimeLimit.truncated"] == a2["TimeLimit.truncated"]


def test_ppo_trains_on_it_through_sb3_wrappers():
    from stable_baselines3 import PPO

    venv = VecMonitor(sb3_vec_env("hgo_mj/CartPoleBalance-v0", num_envs=2, observation="true",
                                  max_episode_steps=8))
    model = PPO("MlpPolicy", venv, n_steps=16, batch_size=16, n_epochs=1, seed=0, device="cpu")
    model.learn(64)
    assert model.num_timesteps == 64 and len(model.ep_info_buffer) > 0
    assert venv.getattr_depth_check("num_envs", already_found=True) is not None
