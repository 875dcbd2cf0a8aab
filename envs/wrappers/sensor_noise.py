"""Sensor noise (hgo_mj's sensor stages) on any environment with a ``Box`` observation."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, cast

import gymnasium
import numpy as np
from gymnasium.error import ResetNeeded
from numpy.typing import NDArray

from ..core import sensor_chain
from ._common import box_indices, env_dt, reset_chain

Array = NDArray[np.floating]


class SensorNoise(gymnasium.Wrapper[Array, Any, Array, Any], gymnasium.utils.RecordConstructorArgs):
    """Pass (some entries of) a ``Box`` observation through an hgo_mj sensor chain.

    The stages of :mod:`hgo_mj.sensors` (noise, bias, drift, quantization, sample-and-hold,
    delay, dropout, outliers, saturation) act on the chosen entries in the order given, at the
    time ``step_count * dt``. ``reset(seed=s)`` seeds the chain (a stream independent of the
    environment's own); ``reset()`` resets the stages and lets the chain's generator continue,
    so the same seed gives the same noise.

    Parameters
    ----------
    env : gymnasium.Env
        An environment with a 1-D ``Box`` observation space.
    sensor : SensorChain, stage spec or sequence of stage specs
        As for the hgo_mj environments: ``[{"stage": "gaussian", "std": 0.01}, ...]``, stage
        instances, or a :class:`~hgo_mj.sensors.SensorChain`.
    indices : sequence of int, optional
        The observation entries measured through the chain (default: all); the others pass
        unchanged.
    dt : float, optional
        Time between observations [s] for the time-based stages; default ``env.unwrapped.dt``
        (MuJoCo environments), else 1.

    Notes
    -----
    The observation space is unchanged and the measured entries are clipped to its bounds
    (noise would otherwise take ``cos``/``sin`` entries past 1), so every observation is in the
    space; a dropout stage's NaN stays NaN (put an observer after a lossy sensor,
    :class:`ObserverInTheLoop`). ``info["clean_observation"]`` holds the observation before the
    sensor. The constructor's arguments are recorded (``gymnasium.utils.RecordConstructorArgs``);
    stepping before ``reset`` raises ``gymnasium.error.ResetNeeded``.

    Examples
    --------
    >>> env = SensorNoise(gymnasium.make("InvertedPendulum-v5"),  # doctest: +SKIP
    ...                   [{"stage": "gaussian", "std": 0.01}], indices=[0, 1])

    The same on an hgo_mj environment shown its true state: only the angle is noisy.

    >>> import hgo_mj.envs
    >>> from hgo_mj.envs.wrappers import SensorNoise
    >>> env = SensorNoise(gymnasium.make("hgo_mj/CartPendulumBalance-v0", observation="true"),
    ...                   [{"stage": "gaussian", "std": 0.01}], indices=[0])
    >>> obs, info = env.reset(seed=0)
    >>> obs.round(3), info["clean_observation"].round(3)
    (array([ 0.048, -0.092]), array([ 0.055, -0.092]))
    >>> env.dt
    0.05
    """

    def __init__(self, env: gymnasium.Env, sensor: Any, *, indices: Sequence[int] | None = None,
                 dt: float | None = None) -> None:
        gymnasium.utils.RecordConstructorArgs.__init__(self, sensor=sensor, indices=indices,
                                                       dt=dt)
        super().__init__(env)
        idx = box_indices(env.observation_space, indices, owner="SensorNoise", name="indices")
        self.indices = np.array(idx, dtype=np.intp)
        shape = cast(tuple[int, ...], env.observation_space.shape)  # a 1-D Box (box_indices)
        self._all = idx == list(range(shape[0]))
        self.sensor = sensor_chain(sensor)
        self.dt = env_dt(env, dt)
        self._k = -1  # no reset yet
        space = cast(gymnasium.spaces.Box, env.observation_space)
        self._low, self._high = np.asarray(space.low, float), np.asarray(space.high, float)

    def _measure(self, obs: Array) -> Array:
        t = self._k * self.dt
        clean = np.asarray(obs, dtype=float)
        tt = np.array([t])
        if self._all:
            y = self.sensor.apply(tt, clean[None, None])[0, 0]
        else:
            y = clean.copy()
            y[self.indices] = self.sensor.apply(tt, clean[self.indices][None, None])[0, 0]
        y = np.clip(y, self._low, self._high)  # inside the space; NaN (a dropout) stays NaN
        return y.astype(self.observation_space.dtype, copy=False)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[Array, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        reset_chain(self.sensor, seed)
        self._k = 0
        info = dict(info)
        info["clean_observation"] = np.array(obs)
        return self._measure(obs), info

    def step(self, action: Any) -> tuple[Array, Any, bool, bool, dict[str, Any]]:
        if self._k < 0:
            raise ResetNeeded("SensorNoise: call reset() before step()")
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._k += 1
        info = dict(info)
        info["clean_observation"] = np.array(obs)
        return self._measure(obs), reward, terminated, truncated, info


__all__ = ["SensorNoise"]
