"""Conformance of the hgo_mj Gymnasium environments, for every environment and every observer
that applies to it; their behaviour (info, seeding, noise shared across modes) and bad input."""

from __future__ import annotations

import json
import math
import pickle
import re
import warnings

import gymnasium as gym
import hgo_mj.envs as envs
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from hgo_mj.envs.wrappers import RecordEpisodes
from rrd_reader import read_rrd

from hgo_mj.exceptions import DesignError, DimensionError
from hgo_mj.observers import OBSERVERS, make_observer
from hgo_mj.record import read
from hgo_mj.systems import CartPendulum

ENV_IDS = sorted(envs.ENVIRONMENTS)
MODES = list(envs.OBSERVATION_MODES)


#: the observers that cannot run on an environment's plant, with the key phrase of the clear
#: error that constructing the environment with them raises (every other pair must run)
#: the benchmark's baselines on a single-output normal form (paper 000, eq. 1)
SINGLE_OUTPUT_BASELINES = ("finite_difference", "super_twisting", "extended_luenberger", "mhe",
                           "kinematic_kalman")
_INCOMPATIBLE: dict[tuple[str, str], tuple[type[Exception], str]] = {
    ("hgo_mj/CartPendulumBalance-v0", "besancon"): (DesignError, "is not in the form of paper 001"),
    ("hgo_mj/CartPendulumBalance-v0", "ekf_mujoco"): (
        DesignError, "the MuJoCo filter needs a model whose only degrees of freedom"),
    ("hgo_mj/CartPendulumBalance-v0", "ukf_mujoco"): (
        DesignError, "the MuJoCo filter needs a model whose only degrees of freedom"),
    ("hgo_mj/CartPendulumBalance-v0", "jo_son"): (
        DesignError, "the Jo-Son observer needs the adaptive observer canonical form"),
    ("hgo_mj/ElasticJoint2LinkReach-v0", "adaptive_gain"): (
        DesignError, "needs a single-output normal form"),
    ("hgo_mj/ElasticJoint2LinkReach-v0", "bastin_gevers"): (
        DesignError, "the Bastin-Gevers observer needs the adaptive observer canonical form"),
    ("hgo_mj/ElasticJoint2LinkReach-v0", "besancon"): (
        DesignError, "to physical coordinates is undefined"),
    ("hgo_mj/ElasticJoint2LinkReach-v0", "high_gain"): (
        DesignError, "needs a single-output normal form"),
    ("hgo_mj/ElasticJoint2LinkReach-v0", "jo_son"): (
        DesignError, "the Jo-Son observer needs the adaptive observer canonical form"),
    ("hgo_mj/ElasticJoint2LinkReach-v0", "q_integral"): (
        DesignError, "needs a single-output normal form"),
    ("hgo_mj/ElasticJoint2LinkReach-v0", "riccati"): (
        DesignError, "needs a single-output normal form"),
    ("hgo_mj/ElasticJointReach-v0", "bastin_gevers"): (
        DesignError, "the Bastin-Gevers observer needs the adaptive observer canonical form"),
    ("hgo_mj/ElasticJointReach-v0", "besancon"): (
        DesignError, "to physical coordinates is undefined"),
    ("hgo_mj/ElasticJointReach-v0", "jo_son"): (
        DesignError, "provides no Jo-Son form .paper 003, eq. 10. for the sensors 'link_angle'"),
    ("hgo_mj/PendulumSwingUp-v0", "jo_son"): (
        DesignError, "the Jo-Son observer needs the adaptive observer canonical form"),
    # the lab plants: two encoders, one chain per joint (high_gain_multi) and the filters
    **{(f"hgo_mj/{env}-v0", kind): (DesignError, why)
       for env in ("FurutaSwingUp", "AcrobotSwingUp", "CartPoleSwingUp", "FurutaBalance",
                   "AcrobotBalance", "CartPoleBalance")
       for kind, why in (
           ("adaptive_gain", "needs a single-output normal form"),
           ("high_gain", "needs a single-output normal form"),
           ("q_integral", "needs a single-output normal form"),
           ("riccati", "needs a single-output normal form"),
           ("besancon", "is not in the form of paper 001"),
           ("bastin_gevers", "the Bastin-Gevers observer needs the adaptive observer canonical"),
           ("jo_son", "the Jo-Son observer needs the adaptive observer canonical form"),
           *((b, "needs a single-output normal form") for b in SINGLE_OUTPUT_BASELINES))},
    **{("hgo_mj/ElasticJoint2LinkReach-v0", b): (DesignError, "needs a single-output normal form")
       for b in SINGLE_OUTPUT_BASELINES},
    ("hgo_mj/ElasticJointReach-v0", "super_twisting"): (
        DesignError, "needs a second-order normal form"),
}


def _pairs() -> list:
    return [pytest.param(env_id, kind, id=f"{env_id.split('/')[1]}-{kind}")
            for env_id in ENV_IDS for kind in sorted(OBSERVERS)]


def _compatible() -> list:
    """The (environment, observer) pairs that run (every pair not in ``_INCOMPATIBLE``)."""
    return [p for p in _pairs() if tuple(p.values) not in _INCOMPATIBLE]


def _checked(env: gym.Env) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # rendering in every declared mode ("human" needs a display) is checked by
        # tests/envs/test_render.py under xvfb-run; every environment's frame there too
        check_env(env.unwrapped, skip_render_check=True)


def _rollout(env: gym.Env, seed: int, n: int) -> list:
    env.action_space.seed(seed)
    obs, info = env.reset(seed=seed)
    rows = [(obs, 0.0, False, False, info)]
    for _ in range(n):
        rows.append(env.step(env.action_space.sample()))
        if rows[-1][2] or rows[-1][3]:
            break
    return rows


def _same(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, tuple | list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray):
        return np.array_equal(a, b, equal_nan=True)
    return a == b or (a != a and b != b)


# --------------------------------------------------------------------------- registration
def test_every_environment_is_registered_with_a_time_limit():
    for env_id, cls in envs.ENVIRONMENTS.items():
        spec = gym.spec(env_id)
        assert spec.max_episode_steps == cls.task_class.max_episode_steps
        assert spec.entry_point.startswith("hgo_mj.envs.")
    env = gym.make("hgo_mj.envs:hgo_mj/PendulumSwingUp-v0", max_episode_steps=3)
    env.reset(seed=0)
    ends = [env.step(env.action_space.sample())[3] for _ in range(3)]
    assert ends == [False, False, True]
    assert isinstance(env, gym.wrappers.TimeLimit)


# --------------------------------------------------------------------------- conformance
def test_incompatible_pairs_name_registered_environments_and_observers():
    for env_id, kind in _INCOMPATIBLE:
        assert env_id in envs.ENVIRONMENTS and kind in OBSERVERS


@pytest.mark.parametrize("env_id,kind", _pairs())
def test_check_env_for_every_observer_or_its_clear_error(env_id, kind):
    """Every (environment, observer) pair: it passes Gymnasium's checker and runs, or, where
    the observer cannot apply to the plant, constructing the environment raises its error."""
    if (env_id, kind) in _INCOMPATIBLE:
        exc, phrase = _INCOMPATIBLE[env_id, kind]
        with pytest.raises(exc, match=phrase):
            gym.make(env_id, observer=kind)
        return
    env = gym.make(env_id, observer=kind)
    _checked(env)
    rows = _rollout(env, 3, 25)
    for obs, *_ in rows:
        assert obs in env.observation_space and np.all(np.isfinite(obs))
    info = rows[-1][-1]
    assert set(info) == {"state", "estimate", "error"}
    names = env.unwrapped.error_names
    assert info["error"].shape == (len(names),)


@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("mode", MODES)
def test_check_env_for_every_observation_mode(env_id, mode):
    env = gym.make(env_id, observation=mode, info_level="full")
    _checked(env)
    u = env.unwrapped
    assert env.observation_space.shape == (len(u.observation_names),)


@pytest.mark.parametrize("env_id,kind", _compatible())
def test_same_seed_same_trajectory_fresh_finite_observations(env_id, kind):
    """Every compatible pair: the same seed gives the same episode (observations, rewards,
    full info), another seed another; every array is finite and none shares memory with
    another, within a step or across steps."""
    a = _rollout(gym.make(env_id, observer=kind, info_level="full"), 7, 30)
    b = _rollout(gym.make(env_id, observer=kind, info_level="full"), 7, 30)
    assert len(a) > 10 and _same(a, b)  # (the balance task may end early)
    c = _rollout(gym.make(env_id, observer=kind, info_level="full"), 8, 30)
    assert not _same(a, c)
    arrays = [r[0] for r in a] + [v for r in a for v in r[-1].values() if isinstance(v, np.ndarray)]
    for i, x in enumerate(arrays):
        assert np.all(np.isfinite(x))
        for y in arrays[i + 1:]:
            assert not np.shares_memory(x, y)


@pytest.mark.parametrize("env_id,kind", _compatible())
def test_sync_vector_env_runs_through_autoreset(env_id, kind):
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="sync", max_episode_steps=4,
                        observer=kind)
    obs, info = venv.reset(seed=1)
    assert obs.shape == (3, *venv.single_observation_space.shape)
    venv.action_space.seed(1)
    for _ in range(6):  # through an autoreset (after step 4)
        obs, reward, term, trunc, info = venv.step(venv.action_space.sample())
        assert np.all(np.isfinite(obs)) and reward.shape == (3,)
    assert info["state"].shape[0] == 3 and np.all(np.isfinite(info["estimate"]))
    assert not np.array_equal(obs[0], obs[1])  # each copy its own seed
    venv.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_async_vector_env_with_spawn(env_id):
    """Every environment runs in an ``AsyncVectorEnv`` whose workers are spawned (each
    rebuilds it from its pickled constructor call), through an autoreset."""
    kw = {"vectorization_mode": "async", "vector_kwargs": {"context": "spawn"}}
    venv = gym.make_vec(env_id, num_envs=2, max_episode_steps=3, **kw)
    try:
        shape = venv.single_observation_space.shape
        obs, _ = venv.reset(seed=[1, 2])
        assert obs.shape == (2, *shape)
        for _ in range(4):  # the fourth step resets (autoreset after the third)
            obs, reward, term, trunc, info = venv.step(
                np.zeros(venv.action_space.shape, dtype=np.float32))
            assert obs.shape == (2, *shape) and np.all(np.isfinite(obs)) and reward.shape == (2,)
        assert not np.array_equal(info["state"][0], info["state"][1])  # each copy its own seed
    finally:
        venv.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_environments_pickle(env_id):
    env = gym.make(env_id)
    _rollout(env, 0, 3)
    copy = pickle.loads(pickle.dumps(env))
    assert _same(_rollout(env, 5, 10), _rollout(copy, 5, 10))


@pytest.mark.parametrize("env_id,kind", _compatible())
def test_environment_with_every_observer_pickles(env_id, kind):
    """Named observers and observer instances (with their caches of compiled updates filled
    by a rollout) pickle, and the copy runs the same episode."""
    env = gym.make(env_id, observer=kind)
    _rollout(env, 0, 3)
    copy = pickle.loads(pickle.dumps(env))
    assert _same(_rollout(env, 4, 5), _rollout(copy, 4, 5))
    e2 = envs.ENVIRONMENTS[env_id](observer=env.unwrapped.observer)  # an instance
    _rollout(e2, 1, 3)
    c2 = pickle.loads(pickle.dumps(e2))
    assert _same(_rollout(e2, 2, 5), _rollout(c2, 2, 5))


def test_environment_with_an_observer_instance_pickles():
    plant_env = envs.PendulumSwingUpEnv(observer=None, observation="true")
    obs = make_observer("high_gain", plant_env.plant.system, k=12.0)
    obs.check_period(0.04)  # fills the cache of one-step maps (dropped when pickled)
    assert obs._maps
    env = envs.PendulumSwingUpEnv(observer=obs)
    assert env.observer is not obs
    first = _rollout(env, 1, 5)
    copy = pickle.loads(pickle.dumps(env))
    assert _same(first, _rollout(copy, 1, 5))


def test_vector_copies_do_not_share_observer_or_sensor_instances():
    from hgo_mj.sensors import GaussianNoise, SensorChain

    plant_env = envs.PendulumSwingUpEnv(observer=None, observation="true")
    obs = make_observer("high_gain", plant_env.plant.system, k=12.0)
    chain = SensorChain([GaussianNoise(std=0.01)])
    venv = gym.make_vec("hgo_mj/PendulumSwingUp-v0", num_envs=2, vectorization_mode="sync",
                        observer=obs, sensor=chain)
    a, b = (e.unwrapped for e in venv.envs)
    assert a.observer is not b.observer and a.sensor is not b.sensor
    seeded = venv.reset(seed=[3, 3])[0]
    np.testing.assert_array_equal(seeded[0], seeded[1])


# --------------------------------------------------------------------------- layout and docs
@pytest.mark.parametrize("env_id,kind", _compatible())
def test_estimate_plus_diagnostics_layout(env_id, kind):
    """``observation="estimate+diagnostics"``: the ``"estimate"`` observation (estimate, then
    goal) followed by the observer's diagnostics less ``dropouts``, in its order, each within
    the task's bound (NaN, not defined yet, as 0), for every compatible pair."""
    env = envs.ENVIRONMENTS[env_id](observer=kind, observation="estimate+diagnostics",
                                    info_level="full")
    plain = envs.ENVIRONMENTS[env_id](observer=kind)
    names = env.diagnostic_names
    assert names == tuple(k for k in env.observer.diagnostics() if k != "dropouts")
    nd = len(names)
    assert env.observation_names == plain.observation_names + tuple(f"diagnostic:{k}"
                                                                    for k in names)
    np.testing.assert_array_equal(env.observation_space.high[len(plain.observation_names):],
                                  [env.task.bound(k) for k in names])
    a, b = _rollout(env, 2, 8), _rollout(plain, 2, 8)
    for (obs, *_, info), (ref, *_) in zip(a, b):
        assert obs in env.observation_space
        np.testing.assert_array_equal(obs[:len(ref)], ref)
        d = info["diagnostics"]
        want = [0.0 if np.isnan(d[k]) else np.clip(d[k], -env.task.bound(k), env.task.bound(k))
                for k in names]
        np.testing.assert_array_equal(obs[len(ref):], want)
        assert len(obs) == len(ref) + nd


@pytest.mark.parametrize("env_id,kind,kwargs,keys", [
    ("hgo_mj/PendulumSwingUp-v0", "adaptive_gain", {}, ("k",)),
    ("hgo_mj/ElasticJointReach-v0", "adaptive_gain", {}, ("k",)),
    ("hgo_mj/PendulumSwingUp-v0", "besancon", {}, ("theta_g_over_l", "theta_b_over_J",
                                                   "excitation")),
    ("hgo_mj/PendulumSwingUp-v0", "ekf", {"estimate": ["damping"], "theta_hat0": [0.02]},
     ("theta_damping", "nis")),
    ("hgo_mj/ElasticJointReach-v0", "ukf", {"estimate": ["stiffness"], "theta_hat0": [8.0]},
     ("theta_stiffness", "nis")),
])
def test_estimate_plus_diagnostics_holds_gain_and_parameter_estimates(env_id, kind, kwargs, keys):
    env = gym.make(env_id, observer=kind, observer_kwargs=kwargs,
                   observation="estimate+diagnostics", info_level="full")
    u = env.unwrapped
    assert u.diagnostic_names == keys
    assert u.observation_names[-len(keys):] == tuple(f"diagnostic:{k}" for k in keys)
    rows = _rollout(env, 0, 20)
    tail = np.array([r[0][-len(keys):] for r in rows])
    d = np.array([[r[-1]["diagnostics"][k] for k in keys] for r in rows])
    np.testing.assert_array_equal(tail, np.nan_to_num(d, nan=0.0))
    if kind in ("ekf", "ukf"):  # the augmented parameter moves from its initial guess
        assert tail[0, 0] == kwargs["theta_hat0"][0] and tail[-1, 0] != tail[0, 0]
    if kind == "adaptive_gain":
        assert np.all(tail[:, 0] > 0)


_GYMNASIUM_SECTIONS = ("Description", "Action Space", "Observation Space", "Rewards",
                       "Starting State", "Episode End", "Arguments", "Version History")


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_environment_docstring_has_gymnasium_sections(env_id):
    """Each class documents itself as Gymnasium's environments do: these ``## `` sections, in
    this order, each with text, the version history naming the registered version."""
    doc = envs.ENVIRONMENTS[env_id].__doc__
    heads = re.findall(r"^\s*## (.+?)\s*$", doc, re.M)
    assert tuple(heads) == _GYMNASIUM_SECTIONS
    parts = re.split(r"^\s*## .+$", doc, flags=re.M)[1:]
    assert all(len(p.strip()) > 20 for p in parts)
    assert f"* {env_id.rsplit('-', 1)[1]}:" in parts[-1]


# --------------------------------------------------------------------------- specs
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_spec_has_threshold_observer_and_sensor_and_goes_to_json(env_id):
    """Every registered spec has a reward threshold; a made environment's spec holds the
    observer and sensor chain it runs, ``to_json`` works and ``make(spec)`` rebuilds it."""
    assert isinstance(gym.spec(env_id).reward_threshold, float)
    env = gym.make(env_id)
    kwargs = env.spec.kwargs
    u = env.unwrapped
    assert kwargs["observer"]["type"] == u.observer.name
    assert kwargs["sensor"] == u.sensor.describe() and kwargs["sensor"]
    raw = json.loads(env.spec.to_json())
    assert raw["kwargs"]["observer"]["type"] == u.observer.name
    assert raw["vector_entry_point"].startswith("hgo_mj.envs:make_")
    again = gym.make(env.spec)
    assert again.unwrapped.observer.params() == u.observer.params()
    assert again.unwrapped.sensor.describe() == kwargs["sensor"]


def test_spec_of_an_instance_no_observer_and_a_custom_sensor():
    sensor = [{"stage": "gaussian", "std": 0.02}, {"stage": "quantize", "counts_per_rev": 4096}]
    env = gym.make("hgo_mj/PendulumSwingUp-v0", observer="riccati",
                   observer_kwargs={"gamma": 9.0}, sensor=sensor)
    assert env.spec.kwargs["observer"] == {"type": "riccati", "gamma": 9.0}
    assert "observer_kwargs" not in env.spec.kwargs
    assert env.spec.kwargs["sensor"] == sensor
    inst = envs.PendulumSwingUpEnv(observer="besancon").observer
    env = gym.make("hgo_mj/PendulumSwingUp-v0", observer=inst)
    assert env.spec.kwargs["observer"] == {"type": "besancon", **inst.params()}
    json.loads(env.spec.to_json())
    env = gym.make("hgo_mj/PendulumSwingUp-v0", observer=None, observation="true", sensor=None)
    assert env.spec.kwargs["observer"] is None and env.spec.kwargs["sensor"] == []
    assert envs.PendulumSwingUpEnv().spec is None  # made directly: no spec


# --------------------------------------------------------------------------- behaviour
#: the balance tasks: (id, index and target of the bounded coordinate, its band [rad],
#: a limit (index, bound) or None)
_BALANCE = [("hgo_mj/CartPoleBalance-v0", 1, np.pi, np.radians(12.0), (0, 2.4)),
            ("hgo_mj/FurutaBalance-v0", 1, np.pi, np.radians(20.0), (0, np.pi / 2)),
            ("hgo_mj/AcrobotBalance-v0", 0, np.pi, np.radians(20.0), None)]


@pytest.mark.parametrize("env_id,i,target,band,limit", _BALANCE)
def test_balance_tasks_start_upright_pay_alive_and_end_outside_the_band(env_id, i, target,
                                                                         band, limit):
    """Gymnasium's CartPole-v1 rules (start within 0.05 of upright, +1 per step, the episode
    ends outside the band or the track), the registered threshold 475 of 500 steps."""
    env = gym.make(env_id, observation="true", info_level="full")
    assert env.spec.max_episode_steps == 500 and env.spec.reward_threshold == 475.0
    for seed in range(5):
        _, info = env.reset(seed=seed)
        up = np.zeros(4)
        for j, value, _ in env.unwrapped.task.targets:
            up[j] = value
        assert np.all(np.abs(info["state"] - up) <= 0.05)
    _, r, term, _, info = env.step(np.zeros(1, np.float32))
    assert (r, term, info["reward_alive"]) == (1.0, False, 1.0)
    task = env.unwrapped.task
    x = up.copy()
    x[i] = target + 0.99 * band
    assert not task.terminated(list(x))
    x[i] = target - 1.01 * band
    assert task.terminated(list(x))
    if limit is not None:
        x = up.copy()
        x[limit[0]] = 1.01 * limit[1]
        assert task.terminated(list(x))
    np.testing.assert_array_equal(task.termination(np.array([up, x]).T), [False, True])


def test_the_cart_is_bounded_by_its_track_only():
    """CartPole-v1: the cart may go anywhere on its 2.4 m track (its centring target is not
    held to the pole's 12-degree band)."""
    task = gym.make("hgo_mj/CartPoleBalance-v0").unwrapped.task
    assert not task.terminated([1.0, np.pi, 0.0, 0.0])
    assert task.terminated([2.5, np.pi, 0.0, 0.0])


def test_the_acrobot_balance_bounds_the_elbow_too():
    task = gym.make("hgo_mj/AcrobotBalance-v0").unwrapped.task
    assert not task.terminated([np.pi, 0.3, 0.0, 0.0])
    assert task.terminated([np.pi, -0.4, 0.0, 0.0])


def test_acrobot_balance_v1_starts_within_0_02_in_the_single_and_the_vector_env():
    """v1 is v0 with the start spread 0.02 (registration keywords), v0 unchanged: the vector
    env's members draw the same starts as the single env."""
    up = np.array([np.pi, 0.0, 0.0, 0.0])
    v0, v1 = (gym.make(f"hgo_mj/AcrobotBalance-v{k}", observation="true", info_level="full")
              for k in (0, 1))
    spread = {0: [], 1: []}
    for seed in range(20):
        for k, env in ((0, v0), (1, v1)):
            spread[k].append(np.max(np.abs(env.reset(seed=seed)[1]["state"] - up)))
    assert max(spread[1]) <= 0.02 < max(spread[0]) <= 0.05
    assert gym.spec("hgo_mj/AcrobotBalance-v1").kwargs == {"start_noise": 0.02}
    assert v1.spec.kwargs["start_noise"] == 0.02 and v1.spec.to_json()
    venv = gym.make_vec("hgo_mj/AcrobotBalance-v1", num_envs=2, observation="true",
                        info_level="full")
    _, info = venv.reset(seed=3)
    for i in range(2):
        np.testing.assert_array_equal(info["state"][i], v1.reset(seed=3 + i)[1]["state"])


def test_a_balance_start_noise_beyond_the_band_is_refused():
    with pytest.raises(DesignError, match="start_noise must be at most 0.2"):
        gym.make("hgo_mj/CartPoleBalance-v0", start_noise=0.3, max_angle=0.2)


def test_info_error_is_state_minus_estimate():
    env = gym.make("hgo_mj/ElasticJointReach-v0")
    _, info = env.reset(seed=0)
    for _ in range(20):
        _, _, _, _, info = env.step(np.array([0.3], dtype=np.float32))
    np.testing.assert_array_equal(info["error"], info["state"] - info["estimate"])
    assert env.unwrapped.error_names == env.unwrapped.state_names


def test_two_link_error_covers_the_estimated_states_only():
    env = envs.ElasticJoint2LinkReachEnv()
    _, info = env.reset(seed=0)
    assert set(env.error_names) == {"link1_angle", "link2_angle", "link1_velocity",
                                    "link2_velocity"}
    est = dict(zip(env.estimate_names, info["estimate"]))
    state = dict(zip(env.state_names, info["state"]))
    for name, e in zip(env.error_names, info["error"]):
        assert e == state[name] - est[name]


def test_two_link_falls_back_to_per_link_chains(monkeypatch):
    monkeypatch.delitem(OBSERVERS, "high_gain_multi", raising=False)
    env = gym.make("hgo_mj/ElasticJoint2LinkReach-v0")
    assert type(env.unwrapped.observer).__name__ == "ObserverBank"
    assert env.unwrapped.estimate_names[:2] == ("link1_angle", "link1_velocity")
    _checked(env)


def test_every_mode_sees_the_same_sensor_noise():
    runs = {}
    for mode in ("estimate", "measurement", "true"):
        env = gym.make("hgo_mj/PendulumSwingUp-v0", observation=mode, info_level="full")
        runs[mode] = _rollout(env, 11, 20)
    meas = [r[-1]["measurement"] for r in runs["measurement"]]
    for mode in ("estimate", "true"):
        assert _same(meas, [r[-1]["measurement"] for r in runs[mode]])
    for (obs, *_rest), y in zip(runs["measurement"], meas):
        np.testing.assert_allclose(obs, [math.cos(y[0]), math.sin(y[0])])


def test_estimate_converges_on_the_pendulum():
    env = gym.make("hgo_mj/PendulumSwingUp-v0")
    env.reset(seed=0)
    errs = [env.step(np.array([0.5], dtype=np.float32))[-1]["error"] for _ in range(100)]
    rms = np.sqrt(np.mean(np.square(errs[25:]), axis=0))
    assert rms[0] < 0.02 and rms[1] < 0.5  # rad, rad/s (sensor noise 0.01 rad)


def test_reset_options_and_reward_from_true_state():
    env = envs.ElasticJointReachEnv(info_level="full")
    obs, info = env.reset(seed=0, options={"x0": [0.5, 0.5, 0.0, 0.0], "goal": [0.5]})
    assert obs[-1] == 0.5 and info["state"][0] == 0.5
    _, reward, _, _, info = env.step(np.zeros(1, dtype=np.float32))
    terms = {k: v for k, v in info.items() if k.startswith("reward_")}
    assert set(terms) == {"reward_tracking", "reward_velocity", "reward_vibration",
                          "reward_control"}
    assert reward == pytest.approx(sum(terms.values()))
    env.reset(seed=0, options={"x0": [0.0, 0.0, 100.0, 0.0]})  # the link whirling
    assert env.step(np.zeros(1, dtype=np.float32))[1] == -10.0  # bounded by max_cost


def test_balance_terminates_when_the_pendulum_falls():
    env = envs.CartPendulumBalanceEnv(max_angle=0.3)
    env.reset(seed=0, options={"x0": [0.2, 0.3]})
    done = [env.step(np.zeros(1, dtype=np.float32))[2] for _ in range(10)]
    assert done[-1] and not done[0]


def test_actions_outside_the_space_are_clipped_by_default():
    a = envs.PendulumSwingUpEnv(sensor=None)
    b = envs.PendulumSwingUpEnv(sensor=None)
    a.reset(seed=0)
    b.reset(seed=0)
    assert _same(a.step(np.array([7.0]))[:4], b.step(np.array([1.0]))[:4])


# --------------------------------------------------------------------------- bad input
def test_unknown_observer_lists_the_valid_ones():
    with pytest.raises(DesignError, match=r"unknown observer 'kalman'; valid: \[.*'high_gain'"):
        gym.make("hgo_mj/PendulumSwingUp-v0", observer="kalman")
    with pytest.raises(DesignError, match=r"needs a 'type'"):
        envs.PendulumSwingUpEnv(observer={"k": 3.0})


def test_a_task_default_the_observer_does_not_take_is_refused():
    """The task's observer defaults go to make_observer as they are: none is dropped silently."""
    from hgo_mj.envs.tasks import SwingUpTask

    class Typo(SwingUpTask):
        observer_defaults = {"high_gain": {"k": 10.0, "kk": 3.0}}

    with pytest.raises(DesignError, match=r"^observer 'high_gain': unknown parameter\(s\) "
                                          r"\['kk'\]; valid: \[.*'k'.*\]$"):
        envs.HgoEnv(task=Typo())
    with pytest.raises(DesignError, match=r"unknown parameter\(s\) \['gain'\]; valid: \["):
        envs.PendulumSwingUpEnv(observer="high_gain", observer_kwargs={"gain": 3.0})
    env = envs.HgoEnv(task=Typo(), observer={"type": "riccati", "gamma": 5.0})  # another kind
    assert type(env.observer).__name__ == "RiccatiObserver"


def test_unknown_sensor_stage_lists_the_valid_ones():
    with pytest.raises(DesignError, match=r"unknown sensor stage 'laser'; valid: \[.*'gaussian'"):
        gym.make("hgo_mj/PendulumSwingUp-v0", sensor=[{"stage": "laser", "std": 1.0}])
    with pytest.raises(DesignError, match=r"unknown parameter\(s\) \['sigma'\]"):
        envs.PendulumSwingUpEnv(sensor={"stage": "gaussian", "sigma": 1.0})


def test_unknown_observation_mode():
    with pytest.raises(DesignError, match=r"unknown observation mode 'pixels'; valid: "
                                          r"\['estimate', 'measurement', 'true', "
                                          r"'estimate\+diagnostics'\]"):
        envs.PendulumSwingUpEnv(observation="pixels")
    with pytest.raises(DesignError, match="needs an observer; found observer=None"):
        envs.PendulumSwingUpEnv(observer=None)


def test_periods_must_be_multiples():
    with pytest.raises(DesignError, match=r"control_period = 0.03 must be a positive integer "
                                          r"multiple of physics_dt = 0.02; found ratio 1.5"):
        envs.PendulumSwingUpEnv(control_period=0.03)
    with pytest.raises(DesignError, match=r"control_period = 0.04 must be a positive integer "
                                          r"multiple of sample_period = 0.06"):
        envs.PendulumSwingUpEnv(physics_dt=0.02, sample_period=0.06)


def test_actions_outside_the_space_raise_when_asked():
    env = envs.PendulumSwingUpEnv(invalid_action="raise")
    env.reset(seed=0)
    with pytest.raises(DesignError, match=r"action\[0\] = 1.5 is outside the action space"):
        env.step(np.array([1.5]))
    with pytest.raises(DesignError, match=r"action\[0\] is NaN"):
        env.step(np.array([np.nan]))
    with pytest.raises(DimensionError, match="action must have 1 entries; found 2"):
        env.step(np.zeros(2))
    with pytest.raises(DesignError, match="invalid_action must be one of"):
        envs.PendulumSwingUpEnv(invalid_action="wrap")


def test_observer_order_must_match_the_plant():
    with pytest.raises(DimensionError, match="order 3 does not match Pendulum's normal form "
                                             "order 2"):
        gym.make("hgo_mj/PendulumSwingUp-v0", observer="high_gain", observer_kwargs={"order": 3})
    with pytest.raises(DesignError, match="needs a single-output normal form; ElasticJoint2Link"):
        envs.ElasticJoint2LinkReachEnv(observer="high_gain", observer_kwargs={"k": 5.0})
    wrong = make_observer("high_gain", CartPendulum.from_mjmodel(
        envs.CartPendulumBalanceEnv(observer=None, observation="true").plant.model), k=5.0)
    with pytest.raises(DesignError, match="designed for CartPendulum; this environment's plant "
                                          "is Pendulum"):
        envs.PendulumSwingUpEnv(observer=wrong)


def test_other_bad_arguments():
    with pytest.raises(DesignError, match=r"unknown argument\(s\) \['torque'\]; valid: .*"
                                          r"'max_torque'"):
        envs.PendulumSwingUpEnv(torque=1.0)
    with pytest.raises(DesignError, match=r"unknown render mode 'sketch' for PendulumSwingUpEnv; "
                                          r"valid: \[None, 'rgb_array', 'human'\]"):
        envs.PendulumSwingUpEnv(render_mode="sketch")
    with pytest.raises(DesignError, match="info_level must be one of"):
        envs.PendulumSwingUpEnv(info_level="all")
    with pytest.raises(DesignError, match="unknown integrator 'Verlet'"):
        envs.PendulumSwingUpEnv(integrator="Verlet")
    with pytest.raises(DesignError, match=r"unknown reset option\(s\) \['state'\]"):
        envs.PendulumSwingUpEnv().reset(options={"state": [0.0, 0.0]})
    with pytest.raises(DimensionError, match="options\\['x0'\\] must have length 2"):
        envs.PendulumSwingUpEnv().reset(options={"x0": [0.0]})
    with pytest.raises(DesignError, match="max_action\\[0\\] must be > 0"):
        envs.PendulumSwingUpEnv(max_torque=-1.0)


# --------------------------------------------------------------------------- recording
def _json_blocks(text: str) -> list:
    return [json.loads(b) for b in re.findall(r"```json\n(.*?)\n```", text, re.S)]


@pytest.mark.parametrize("env_id", ["hgo_mj/PendulumSwingUp-v0", "hgo_mj/ElasticJoint2LinkReach-v0"])
def test_record_episodes_holds_every_episode(tmp_path, env_id):
    """Two episodes (6 and 4 steps) recorded through ``RecordEpisodes`` and read back with rerun's
    reader: one row at reset and one per step, on the episode timeline; the true state, the
    observer's estimate of the states it estimates (the two-link arm's model-free observer:
    link angles and velocities, not the motors; its derivatives under its own names), the
    errors, inputs, rewards and diagnostics equal what ``step`` returned; the ghost, the
    scenario (with each episode's seed) and the per-episode metrics are there."""
    path = tmp_path / "episodes.rrd"
    env = RecordEpisodes(gym.make(env_id, max_episode_steps=10), path)
    u = env.unwrapped
    obs_name = u.observer.name
    lengths, seeds = (6, 4), (0, 1)
    infos, rewards, actions = [], [], []
    for seed, n in zip(seeds, lengths):
        env.action_space.seed(seed)
        _, info = env.reset(seed=seed)
        infos.append(info)
        rewards.append(0.0)
        actions.append(np.zeros(env.action_space.shape))
        for _ in range(n):
            a = env.action_space.sample()
            _, r, _, _, info = env.step(a)
            infos.append(info)
            rewards.append(r)
            actions.append(a.astype(float) * np.array(u.task.max_action))
    env.close()
    ents, blueprints = read_rrd(path)
    assert blueprints >= 1
    rows = sum(n + 1 for n in lengths)
    X = np.array([i["state"] for i in infos])
    XH = np.array([i["estimate"] for i in infos])
    E = np.array([i["error"] for i in infos])
    assert X.shape[0] == rows
    est = {name: k for k, name in enumerate(u.estimate_names)}
    df = read(path)
    for j, s in enumerate(u.state_names):
        e = ents[f"/state/{s}"]
        assert e.rows == rows, s
        np.testing.assert_array_equal(e["episode"], np.repeat([0, 1], [n + 1 for n in lengths]))
        np.testing.assert_array_equal(e["step"], np.arange(rows))
        assert np.all(np.diff(e["sim_time"]) > 0)  # the second episode follows the first
        np.testing.assert_array_equal(df[f"/state/{s}[{s} true]"], X[:, j])
        if s in est:  # one entity per state: the truth and the estimate, named
            assert e.series == [f"{s} true", f"{s} {obs_name}"]
            np.testing.assert_array_equal(df[f"/state/{s}[{s} {obs_name}]"], XH[:, est[s]])
            np.testing.assert_array_equal(df[f"/error/{s}[{s} error {obs_name}]"],
                                          E[:, u.error_names.index(s)])
        else:  # a state the observer does not estimate: the truth only, no error
            assert e.series == [f"{s} true"] and f"/error/{s}" not in ents
    assert set(u.error_names) == {s for s in u.state_names if s in est}
    for name, k in est.items():  # estimates that are not plant states: the observer's names
        if name not in u.state_names:
            e = ents[f"/observer/{obs_name}/estimate/{name}"]
            np.testing.assert_array_equal(e["Scalars:scalars"][:, 0], XH[:, k])
    np.testing.assert_allclose(df["/env/reward"], rewards)
    inputs = np.array(actions)
    for j, name in enumerate(u.plant.input_names):
        np.testing.assert_allclose(df[f"/input/{name}"], inputs[:, j], rtol=1e-6)
        assert df.attrs["units"][f"/input/{name}"] == "N m"
    for name in u.output_names:  # the clean output is the true state's
        clean, measured = df[f"/sensor/{name}[{name} clean]"], df[f"/sensor/{name}[{name} measured]"]
        if name in u.state_names:
            np.testing.assert_allclose(clean, X[:, u.state_names.index(name)], atol=1e-12)
        assert np.all(np.abs(measured - clean) < 0.05)  # noise, quantization
    # diagnostics: where they change and at each episode's end
    diag = u.observer.diagnostics()
    if "k" in diag:
        gain = ents[f"/observer/{obs_name}/gain"]
        assert np.all(gain["Scalars:scalars"] == diag["k"]) and gain["step"][-1] == rows - 1
    # no dropout stage in the sensor chain: no dropout series
    assert not u.sensor.has_dropouts
    assert f"/observer/{obs_name}/diagnostics/dropouts" not in ents
    # the ghost poses the estimated joints
    body = {"hgo_mj/PendulumSwingUp-v0": "pole", "hgo_mj/ElasticJoint2LinkReach-v0": "link2"}[env_id]
    ghost = ents[f"/world/estimate/{obs_name}/{body}"]
    assert 0 < ghost.rows <= rows and ghost.rows == ents[f"/world/true/{body}"].rows
    # the scenario: environment, task, periods, sensor, observer, seeds, versions
    scenario = ents["/scenario"].static["TextDocument:text"][0]
    meta = _json_blocks(scenario)[-1]
    assert meta["environment"]["id"] == env_id
    assert meta["environment"]["class"].endswith(type(u).__name__)
    assert meta["task"] == {"class": type(u.task).__name__, **json.loads(json.dumps(u.task.params()))}
    assert meta["seeds"] == {"0": 0, "1": 1}
    assert (meta["sample_period"], meta["control_period"], meta["physics_dt"]) == (
        u.sample_period, u.control_period, u.physics_dt)
    assert meta["integrator"] == u.integrator
    assert meta["sensor"] == json.loads(json.dumps(u.sensor.describe()))
    observer = meta["observers"][obs_name]
    assert observer["type"] == type(u.observer).__name__
    assert observer["state_names"] == list(u.estimate_names)
    assert observer["k"] == json.loads(json.dumps(u.observer.params()["k"]))
    assert meta["versions"]["mujoco"] == mujoco.__version__
    # the metrics: one row per episode
    metrics = ents["/metrics"].static["TextDocument:text"][0]
    assert "| episode | seed | steps | return |" in metrics
    table = _json_blocks(metrics)[0]
    assert [m["episode"] for m in table] == [0, 1] and [m["seed"] for m in table] == list(seeds)
    assert [m["steps"] for m in table] == list(lengths)
    first = 0
    for m, n in zip(table, lengths):
        part = slice(first, first + n + 1)
        assert m["return"] == pytest.approx(sum(rewards[part]))
        for k, s in enumerate(u.error_names):
            assert m["rmse"][s] == pytest.approx(np.sqrt(np.mean(E[part, k] ** 2)))
            assert m["final_error"][s] == pytest.approx(abs(E[part][-1, k]))
        first += n + 1


def test_record_episodes_without_observer(tmp_path):
    """No observer: the truth, measurements and rewards only, no error, no metrics RMSE."""
    path = tmp_path / "true.rrd"
    env = RecordEpisodes(envs.PendulumSwingUpEnv(observer=None, observation="true"), path)
    env.reset(seed=4)
    for _ in range(3):
        env.step(np.zeros(1, dtype=np.float32))
    env.close()
    ents, _ = read_rrd(path)
    assert ents["/state/angle"].rows == 4 and ents["/state/angle"].series == ["angle true"]
    assert not any(e.startswith(("/error", "/observer", "/world/estimate")) for e in ents)
    table = _json_blocks(ents["/metrics"].static["TextDocument:text"][0])[0]
    assert table == [{"episode": 0, "seed": 4, "steps": 3, "return": table[0]["return"],
                      "terminated": False}]
    meta = _json_blocks(ents["/scenario"].static["TextDocument:text"][0])[-1]
    assert meta["observers"] == {} and meta["environment"]["id"] == "hgo_mj/PendulumSwingUp-v0"


def test_readme_environment_examples_run():
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    section = text[text.index("## Gymnasium environments"):]
    blocks = re.findall(r"```py\n(.*?)```", section, re.S)
    assert len(blocks) == 2
    scope: dict = {}
    for code in blocks:
        exec(compile(code, "README.md", "exec"), scope)
    assert scope["env"].observation_space.shape == (4,)


def test_a_task_in_the_loop_and_a_variant_by_partial():
    from functools import partial

    from hgo_mj.envs.tasks import SwingUpTask

    env = envs.HgoEnv(task=SwingUpTask(max_torque=0.3))
    assert env.task.max_action == (0.3,) and env.spec is None
    gym.register(id="hgo_mj_test/PendulumSwingUpTrue-v0", max_episode_steps=10,
                 entry_point=partial(envs.PendulumSwingUpEnv, observation="true"))
    try:
        variant = gym.make("hgo_mj_test/PendulumSwingUpTrue-v0")
        _checked(variant)
        assert variant.unwrapped.observation_mode == "true"
    finally:
        del gym.registry["hgo_mj_test/PendulumSwingUpTrue-v0"]
    with pytest.raises(DesignError, match="give task parameters"):
        envs.PendulumSwingUpEnv(task=SwingUpTask(), max_torque=0.2)


def test_lab_swing_up_v1_rewards_are_their_literatures_and_v0_is_kept():
    """v1 = v0 with the literature's reward (registration keywords): dm_control's cart-pole
    and acrobot, Quanser's Qube; 1 upright and still, about 0 (0.2 for the Qube) hanging, in
    [0, 1]; the Qube's episode ends with the arm beyond 90 degrees; the vector env gives the
    single env's rewards; v0 keeps its quadratic reward."""
    cases = {"CartPoleSwingUp": ([0.0, np.pi, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], 0.0),
             "FurutaSwingUp": ([0.0, np.pi, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], 0.2),
             "AcrobotSwingUp": ([np.pi, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], 0.0)}
    for name, (up, down, hanging) in cases.items():
        v0, v1 = (gym.make(f"hgo_mj/{name}-v{k}").unwrapped.task for k in (0, 1))
        assert gym.spec(f"hgo_mj/{name}-v1").reward_threshold == 250.0
        assert v1.reward(up, [0.0], ())[0] == pytest.approx(1.0)
        assert v1.reward(down, [0.0], ())[0] == pytest.approx(hanging, abs=1e-3)
        assert v0.reward(up, [0.0], ())[0] == pytest.approx(0.0)
        assert v0.reward(down, [0.0], ())[0] < -9.0
        assert v1.at_target(up) and not v1.at_target(down)
        assert "reward" not in v0.params() and v1.params()["reward"] != "quadratic"
    cart_pole = gym.make("hgo_mj/CartPoleSwingUp-v1").unwrapped.task
    assert not cart_pole.terminated([3.0, 0.0, 0.0, 0.0])  # end stops, no episode end
    stops = gym.make("hgo_mj/CartPoleSwingUp-v1", observation="true")
    stops.reset(seed=0)
    for _ in range(300):  # pushed at full force, the cart rests against the stop at 2.4 m
        _, _, terminated, _, info = stops.step(np.array([1.0], dtype=np.float32))
    assert not terminated and 2.4 < info["state"][0] < 2.41
    assert gym.make("hgo_mj/CartPoleSwingUp-v0").unwrapped.task.terminated([3.0, 0, 0, 0])
    assert not cart_pole.at_target([3.0, np.pi, 0.0, 0.0])  # upright off the track
    furuta = gym.make("hgo_mj/FurutaSwingUp-v1").unwrapped.task
    assert furuta.terminated([1.6, np.pi, 0.0, 0.0])
    assert not gym.make("hgo_mj/FurutaSwingUp-v0").unwrapped.task.terminated([1.6, 0, 0, 0])
    for name in cases:
        env = gym.make(f"hgo_mj/{name}-v1", observation="true")
        venv = gym.make_vec(f"hgo_mj/{name}-v1", num_envs=2, observation="true")
        venv.reset(seed=5)
        env.reset(seed=6)
        a = np.array([[0.7], [0.7]], dtype=np.float32)
        for _ in range(20):
            r_vec = venv.step(a)[1]
            r = env.step(a[1])[1]
        assert r_vec[1] == pytest.approx(r, rel=1e-12, abs=1e-15)
        assert env.spec.to_json()
    with pytest.raises(DesignError, match=r"reward must be one of \['quadratic', 'dm_control'\]"):
        gym.make("hgo_mj/CartPoleSwingUp-v0", reward="quanser")
