"""Wrappers that attach hgo_mj's sensor chain and observers to any Gymnasium environment.

* :class:`SensorNoise`: the stages of :mod:`hgo_mj.sensors` on a ``Box`` observation,
  seeded by ``reset(seed=...)``.
* :class:`ObserverInTheLoop`: measure some signals of an environment through a sensor chain,
  run any hgo_mj observer on them and the action, and hand the agent the estimate; for
  example Gymnasium's ``InvertedPendulum-v5`` with only the cart position and pole angle
  measured, their velocities estimated by high-gain observers.
* :class:`RecordEpisodes`: every episode of an hgo_mj environment to a rerun recording.
"""

from __future__ import annotations

from .observer_in_the_loop import ObserverInTheLoop
from .record_episodes import RecordEpisodes
from .sensor_noise import SensorNoise

__all__ = ["ObserverInTheLoop", "RecordEpisodes", "SensorNoise"]
