"""scripts/rl_tuning_scenario.py: the scenario replays an environment episode open loop, and
the committed scenarios (scenarios/rl_balance/) replay the env's episodes to 1e-12."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import gymnasium as gym
import hgo_mj.envs  # noqa: F401
import numpy as np
import pytest

from hgo_mj.study.study import load_toml

ROOT = Path(__file__).resolve().parents[2]


def _load(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # its dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def _episode(env_id, actions, x0=None, seed=10_000):
    """Run ``actions`` (in [-1, 1]) on the true-state env; the Episode and the env."""
    rl = _load("rl_tuning_scenario")
    env = gym.make(env_id, observation="true")
    _, info = env.reset(seed=seed, options=None if x0 is None else {"x0": x0})
    scale = np.asarray(env.unwrapped.task.max_action, dtype=float)
    xs, us = [info["state"]], []
    for a in actions:
        _, _, terminated, _, info = env.step(np.asarray(a, dtype=np.float64))
        xs.append(info["state"])
        us.append(np.asarray(a, dtype=float) * scale)
        if terminated:
            break
    return rl, env, rl.Episode(np.array(xs), np.array(us))


@pytest.mark.parametrize("env_id", ["hgo_mj/CartPoleBalance-v0", "hgo_mj/FurutaBalance-v0",
                                    "hgo_mj/ElasticJointReach-v0",  # an MJCF, a registered plant
                                    "hgo_mj/CartPoleSwingUp-v1"])  # a variant of v0
def test_scenario_replays_the_episode_bit_for_bit(env_id):
    actions = np.random.default_rng(0).uniform(-1, 1, size=(30, 1))
    rl, env, ep = _episode(env_id, actions)
    sc = rl.scenario(env, ep)
    assert sc["name"] == f"{env_id.split('/')[-1]}_balance"  # the variant's id, not its base's
    assert sc["observers"][0]["type"] == env.unwrapped.default_observer_kind()
    assert [o["name"] for o in sc["observers"]] == (
        ["default", "ekf"] if env_id == "hgo_mj/ElasticJointReach-v0" else ["default"])
    assert rl.replay_error(sc, ep) == 0.0
    sc["input"]["values"][10] = (ep.u[10] + 1e-3).tolist()  # another input: another motion
    assert rl.replay_error(sc, ep) > 1e-9


@pytest.mark.parametrize("name", ["CartPoleBalance-v0", "FurutaBalance-v0",
                                  "AcrobotBalance-v1", "ElasticJointReach-v0",
                                  "CartPoleSwingUp-v1"])
def test_committed_scenario_is_a_balancing_episode(name):
    sc = load_toml(ROOT / "scenarios" / "rl_balance" / f"{name}.toml")
    u = np.array(sc["input"]["values"])
    rl = _load("rl_tuning_scenario")
    env = gym.make(f"hgo_mj/{name}", observation="true")
    assert len(u) == env.spec.max_episode_steps  # balanced to the time limit
    _, env, ep = _episode(f"hgo_mj/{name}", u / np.asarray(env.unwrapped.task.max_action),
                          x0=sc["plant"]["x0"])
    assert len(ep.u) == len(u)  # never terminated
    assert rl.replay_error(sc, ep) <= 1e-12
