"""The native vector environment (envs/vector.py): the one loop at B = num_envs.

Member i is checked against Gymnasium's own SyncVectorEnv of the single environment (its
member i is ``gymnasium.make(id)`` reset with ``seed + i``, autoreset by Gymnasium's
NEXT_STEP rule): bit for bit, across autoresets, in every observation mode.
"""

from __future__ import annotations

import gymnasium as gym
import hgo_mj.envs  # noqa: F401  (registers the environments)
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode
from hgo_mj.envs import ENVIRONMENTS, HgoVectorEnv, PendulumSwingUpEnv

from hgo_mj.exceptions import DesignError, DimensionError, DivergenceError

IDS = list(ENVIRONMENTS)
INFO_KEYS = ("state", "estimate", "error", "measurement", "time", "goal")


def _pair(env_id: str, n: int, limit: int, native_kw=None, **kw):
    native = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                          max_episode_steps=limit, **(native_kw or {}), **kw)
    sync = gym.vector.SyncVectorEnv(
        [lambda: gym.make(env_id, max_episode_steps=limit, **kw)] * n)
    return native, sync


def _same(a, b) -> bool:
    return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)


def _run_equal(env_id: str, n: int, limit: int, steps: int, native_kw=None, **kw) -> int:
    """Step both with the same random actions; assert bit-equal results; return the number
    of autoresets seen. ``native_kw``: arguments of the native vector environment only."""
    native, sync = _pair(env_id, n, limit, native_kw, **kw)
    o1, i1 = native.reset(seed=7)
    o2, i2 = sync.reset(seed=7)
    assert _same(o1, o2)
    for k in INFO_KEYS:
        assert (k in i1) == (k in i2)
        if k in i2:
            assert _same(i1[k], i2[k]), k
    rng = np.random.default_rng(1)
    m = native.single_action_space.shape[0]
    resets = 0
    for step in range(steps):
        a = rng.uniform(-1.2, 1.2, (n, m)).astype(np.float32)
        r1, r2 = native.step(a), sync.step(a)
        for j, what in enumerate(("obs", "reward", "terminated", "truncated")):
            assert _same(r1[j], r2[j]), f"{env_id} {what} at step {step}"
            assert r1[j].dtype == r2[j].dtype, what
        for k in INFO_KEYS:
            if k in r2[4]:
                assert _same(r1[4][k], r2[4][k]), f"{env_id} info[{k!r}] at step {step}"
        resets += int(np.sum(r1[2] | r1[3]))
    native.close()
    sync.close()
    return resets


@pytest.mark.parametrize("nthread", [1, 2])
@pytest.mark.parametrize("env_id", IDS)
def test_members_equal_single_environments_across_autoresets(env_id, nthread):
    """Bit for bit on MuJoCo's batched step on one thread and on two (the members split over
    the threads), the rewards included."""
    resets = _run_equal(env_id, 3, 12, 40, native_kw={"nthread": nthread}, info_level="full")
    assert resets >= 6  # truncated every 12 steps: autoresets were exercised


@pytest.mark.parametrize("mode", ["measurement", "true", "estimate+diagnostics"])
def test_members_equal_in_every_observation_mode(mode):
    # dropouts (NaN held in the observation, counted by the observer) and outliers: counters
    # per stream, restarted per member
    sensor = [{"stage": "gaussian", "std": 0.01}, {"stage": "outliers", "p": 0.05,
                                                   "magnitude": 0.3},
              {"stage": "dropout", "p": 0.2}]
    assert _run_equal("hgo_mj/PendulumSwingUp-v0", 3, 10, 35, observation=mode,
                      sensor=sensor) >= 6


def test_terminations_autoreset_next_step():
    """CartPendulumBalance terminates: NEXT_STEP resets the member at the following step with
    reward 0, both flags False and its first observation (the reference: Gymnasium's own
    SyncVectorEnv); the others go on."""
    native, sync = _pair("hgo_mj/CartPendulumBalance-v0", 4, 400, max_acceleration=0.1)
    native.reset(seed=0)
    sync.reset(seed=0)
    a = np.ones((4, 1), dtype=np.float32)
    done_at = None
    for _ in range(200):
        obs, rew, term, trunc, info = native.step(a)
        ref = sync.step(a)
        assert _same(obs, ref[0]) and _same(rew, ref[1]) and _same(term, ref[2])
        if done_at is not None:
            assert rew[done_at] == 0.0 and not term[done_at] and not trunc[done_at]
            assert abs(info["state"][done_at, 0]) <= 0.2  # the reset distribution
            break
        if term.any():
            done_at = int(np.argmax(term))
            assert abs(info["state"][done_at, 0]) > 0.5  # ended by the angle
    assert done_at is not None, "no member terminated"


def test_spaces_metadata_and_registration():
    for env_id in IDS:
        single = gym.make(env_id)
        venv = gym.make_vec(env_id, num_envs=5)  # the vector entry point is the default
        assert isinstance(venv.unwrapped, HgoVectorEnv)
        assert venv.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
        assert venv.single_observation_space == single.observation_space
        assert venv.single_action_space == single.action_space
        assert venv.observation_space.shape == (5, *single.observation_space.shape)
        assert venv.action_space.shape == (5, *single.action_space.shape)
        assert venv.action_space.dtype == np.float32
        obs, info = venv.reset(seed=0)
        assert obs.dtype == np.float64 and obs in venv.observation_space
        assert info["state"].shape == (5, len(single.unwrapped.state_names))
        assert info["_state"].all()
        obs, rew, term, trunc, info = venv.step(venv.action_space.sample())
        assert obs in venv.observation_space
        assert rew.shape == (5,) and rew.dtype == np.float64
        assert term.dtype == bool and trunc.dtype == bool and term.shape == (5,)
        assert gym.make_vec(env_id, num_envs=2, vectorization_mode="sync").num_envs == 2


def test_reset_mask_and_seed_list():
    """A partial reset reseeds the masked members only: each equals a single environment
    reset with its seed, the others go on as if nothing happened."""
    env_id = "hgo_mj/ElasticJointReach-v0"
    venv = gym.make_vec(env_id, num_envs=3, max_episode_steps=1000)
    singles = [gym.make(env_id, max_episode_steps=1000) for _ in range(3)]
    obs, _ = venv.reset(seed=[4, 5, 6])
    for i, s in enumerate(singles):
        assert _same(obs[i], s.reset(seed=4 + i)[0])
    rng = np.random.default_rng(0)
    prev = obs
    for step in range(14):
        a = rng.uniform(-1, 1, (3, 1)).astype(np.float32)
        if step == 6:
            mask = np.array([False, True, False])
            obs, info = venv.reset(seed=[None, 99, None], options={"reset_mask": mask})
            assert _same(obs[1], singles[1].reset(seed=99)[0])
            assert _same(obs[0], prev[0]) and _same(obs[2], prev[2])
            continue
        obs = venv.step(a)[0]
        for i, s in enumerate(singles):
            assert _same(obs[i], s.step(a[i])[0]), (step, i)
        prev = obs


@pytest.mark.parametrize("bad", [0, -3, 2.0, "4", True, None])
def test_num_envs_refused(bad):
    with pytest.raises(DesignError, match="num_envs must be an integer >= 1; found"):
        gym.make_vec("hgo_mj/PendulumSwingUp-v0", num_envs=bad,
                     vectorization_mode="vector_entry_point")


def test_bad_inputs():
    venv = HgoVectorEnv(PendulumSwingUpEnv, 2)
    with pytest.raises(DesignError, match="call reset"):
        venv.step(np.zeros((2, 1), dtype=np.float32))
    with pytest.raises(DesignError, match="reset_mask all True"):
        venv.reset(options={"reset_mask": np.array([True, False])})
    venv.reset(seed=0)
    with pytest.raises(DimensionError, match=r"shape \(2, 1\).*found \(3, 1\)"):
        venv.step(np.zeros((3, 1)))
    with pytest.raises(DimensionError, match="array of numbers"):
        venv.step([["a"], ["b"]])
    with pytest.raises(DesignError, match=r"action\[1\]\[0\] is NaN"):
        venv.step(np.array([[0.0], [np.nan]]))
    with pytest.raises(DesignError, match="unknown reset option"):
        venv.reset(options={"x0": [0, 0]})
    with pytest.raises(DesignError, match="bool array of shape"):
        venv.reset(options={"reset_mask": [True, False]})
    with pytest.raises(DesignError, match="seed must be"):
        venv.reset(seed=[1, 2, 3])
    strict = HgoVectorEnv(PendulumSwingUpEnv, 2, invalid_action="raise")
    strict.reset(seed=0)
    with pytest.raises(DesignError, match=r"action\[0\]\[0\] = 2 is outside"):
        strict.step(np.array([[2.0], [0.0]]))
    with pytest.raises(DesignError, match="keep one clock"):
        HgoVectorEnv(PendulumSwingUpEnv, 2, sensor=[{"stage": "delay", "delay": 0.04}])
    with pytest.raises(DesignError, match="max_episode_steps must be a positive integer"):
        HgoVectorEnv(PendulumSwingUpEnv, 2, max_episode_steps=0)
    with pytest.raises(DesignError, match="HgoEnv subclass"):
        HgoVectorEnv(dict, 2)  # type: ignore[arg-type]


def test_an_estimate_that_leaves_the_finite_numbers_names_its_member():
    venv = HgoVectorEnv(PendulumSwingUpEnv, 4)
    venv.reset(seed=0)
    venv.loop.states["observer"].z[2, 1] = np.inf  # member 2's observer state breaks
    with pytest.raises(DivergenceError, match=r"member 2: the observer's estimate left the "
                                              r"finite numbers at step 1"):
        venv.step(np.zeros((4, 1)))
    venv.close()


@pytest.mark.parametrize("env_id", IDS)
def test_batched_rewards_equal_the_task_reward(env_id):
    env = gym.make(env_id).unwrapped
    task, rng = env.task, np.random.default_rng(3)
    n, m, g = len(env.state_names), len(env.plant.input_names), len(task.goal_names)
    X = rng.normal(0, 3, (50, n))
    X[0] = 0.0
    U = rng.uniform(-1, 1, (50, m)) * np.array(task.max_action)
    G = rng.uniform(-1, 1, (50, g))
    r, terms = task.rewards(X, U, G)
    term = task.terminations(X)
    for b in range(50):
        rb, tb = task.reward(X[b].tolist(), U[b].tolist(), tuple(G[b].tolist()))
        assert r[b] == rb
        assert {k: v[b] for k, v in terms.items()} == tb
        assert term[b] == task.terminated(X[b].tolist())
