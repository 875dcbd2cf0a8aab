"""The step bound at reset (``Loop.bind_step``) against the loop's segment path: the same
episodes bit for bit, for every registered environment and the sensor stages that change what
a step holds (delay, dropout, sample-and-hold, several samples per control period), and the
same errors where the plant or the observer fails."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import hgo_mj.envs as E  # noqa: N812
import numpy as np
import pytest

from hgo_mj.exceptions import DivergenceError
from hgo_mj.loop import Loop, Periods
from hgo_mj.observers import HighGainObserver
from hgo_mj.plants import make_plant

SENSOR = [{"stage": "gaussian", "std": 0.01}, {"stage": "delay", "delay": 0.04},
          {"stage": "dropout", "p": 0.2}]


def _episodes(env_id: str, bound: bool, **kw: Any) -> list[Any]:
    """Every observation, reward, flag and ``info`` entry of seeded episodes of up to 40
    random-action steps (out of range included: clipped), autoreset by hand."""
    env = gym.make(env_id, max_episode_steps=25, info_level="full", **kw)
    env.unwrapped.bound_step = bound
    rng = np.random.default_rng(3)
    rows: list[Any] = []
    obs, _ = env.reset(seed=4)
    rows.append(obs.tobytes())
    for _ in range(40):
        obs, r, te, tr, info = env.step(rng.uniform(-1.2, 1.2, env.action_space.shape)
                                        .astype(np.float32))
        rows += [obs.tobytes(), r, te, tr, info["state"].tobytes(), info["time"],
                 info["measurement"].tobytes(),
                 info["estimate"].tobytes() if "estimate" in info else None]
        if te or tr:
            rows.append(env.reset()[0].tobytes())
    assert (env.unwrapped._bound is not None) is bound  # each path was the one asked
    return rows


@pytest.mark.parametrize("env_id", list(E.ENVIRONMENTS))
def test_bound_step_equals_segment_path(env_id: str) -> None:
    assert _episodes(env_id, True, sensor=SENSOR) == _episodes(env_id, False, sensor=SENSOR)


def test_bound_step_several_samples_and_sample_hold() -> None:
    kw = {"physics_dt": 0.005, "sample_period": 0.01,
          "sensor": [{"stage": "sample_hold", "period": 0.02}, {"stage": "dropout", "p": 0.3}]}
    assert (_episodes("hgo_mj/PendulumSwingUp-v0", True, **kw)
            == _episodes("hgo_mj/PendulumSwingUp-v0", False, **kw))


def test_bound_step_plant_divergence_same_error() -> None:
    """A state MuJoCo resets raises the same error on both paths."""
    msgs = []
    for bound in (True, False):
        env = gym.make("hgo_mj/PendulumSwingUp-v0")
        env.unwrapped.bound_step = bound
        env.reset(seed=0)
        env.unwrapped.plant.data.qvel[:] = 1e300  # MuJoCo's mjWARN_BADQVEL at the next step
        with pytest.raises(DivergenceError) as exc:
            env.step(np.zeros(1, dtype=np.float32))
        msgs.append(str(exc.value))
    assert msgs[0] == msgs[1] and "mjWARN_BAD" in msgs[0]


def test_bound_step_observer_failure_same_error() -> None:
    """An observer whose update fails (a math error on its state): the same LoopFailure
    (observer, row, time, cause) on both paths, the loop's clock put."""
    fails = []
    for bound in (True, False):
        plant = make_plant("pendulum", dt=0.01)
        ob = HighGainObserver(plant.system, k=10.0)
        loop = Loop(plant, None, {"hgo": ob}, Periods.of(plant), exact=False)
        loop.reset([0.2, 0.0])
        step = loop.bind_step(1) if bound else (
            lambda u, loop=loop: loop.segment(np.array([[u]])))
        assert step is not None
        step([0.1])
        family_step = ob._step

        def failing(*args: Any) -> None:
            raise ValueError("math domain error")

        ob._step = failing  # type: ignore[method-assign]
        with pytest.raises(Exception) as exc:
            step([0.1])
        ob._step = family_step  # type: ignore[method-assign]
        fails.append((type(exc.value).__name__, str(exc.value), loop.k,
                      type(exc.value.__cause__).__name__, len(exc.value.segment)))
    assert fails[0] == fails[1], fails
    assert fails[0] == ("LoopFailure", "hgo at t=0.01 (row 1): math domain error", 1,
                        "ValueError", 1)


@pytest.mark.parametrize("new_gain", [False, True])
def test_a_binding_after_a_reset(new_gain: bool) -> None:
    """After a reset an old binding steps the new state (the same parameters) or goes through
    the segment path (new parameters: the observer's gain changed): the same rows as a fresh
    binding and as the segment path, never the state or parameters the reset replaced."""
    rows = []
    for how in ("old binding", "new binding", "segment"):
        plant = make_plant("pendulum", dt=0.01)
        ob = HighGainObserver(plant.system, k=10.0)
        loop = Loop(plant, None, {"hgo": ob}, Periods.of(plant), exact=False)
        loop.reset([0.2, 0.0])
        step = loop.bind_step(2)
        assert step is not None
        step([0.3])
        if new_gain:
            ob.k_ = 20.0
        loop.reset([0.1, 0.0])
        if how == "new binding":
            step = loop.bind_step(2)
        elif how == "segment":
            step = lambda u: loop.segment(np.array([[u] * 2]))  # noqa: E731, B023
        assert step is not None
        step([0.3])
        rows.append((plant.state.tolist(), loop.current("hgo")[0].tolist(), loop.k))
    assert rows[0] == rows[1] == rows[2]
    assert rows[0][1][0][0] != 0.1  # the observer moved


def test_no_binding_where_it_does_not_apply() -> None:
    plant = make_plant("pendulum", dt=0.01)
    obs = {"a": HighGainObserver(plant.system, k=10.0), "b": HighGainObserver(plant.system, k=5.0)}
    loop = Loop(plant, None, obs, Periods.of(plant), exact=False)
    loop.reset([0.2, 0.0])
    assert loop.bind_step(1) is None  # two observers
    loop = Loop(plant, None, {"a": obs["a"]}, Periods.of(plant))
    loop.reset([0.2, 0.0])
    assert loop.bind_step(1) is None  # exact
    loop = Loop(plant, None, {"a": obs["a"]}, Periods.of(plant), exact=False)
    loop.reset([[0.2, 0.0], [0.1, 0.0]], batch=2)
    assert loop.bind_step(1) is None  # two members
