"""What the wrappers share: the sensor chain's seeding and the environment's time step."""

from __future__ import annotations

from typing import Any

import gymnasium

from hgo_mj._validate import finite_scalar
from hgo_mj.sensors import SensorChain

from ..core import chain_seed


def reset_chain(chain: SensorChain, seed: int | None) -> None:
    """Re-seed the chain on a seeded reset; otherwise reset its stages and let its generator
    continue (Gymnasium's convention for ``reset()`` without a seed)."""
    if seed is not None:
        chain.reset(chain_seed(seed))
    else:
        for s in chain.stages:
            s.reset()


def env_dt(env: gymnasium.Env, dt: Any) -> float:
    """The time between two observations: ``dt`` if given, else ``env.unwrapped.dt`` (MuJoCo
    environments), else 1 (one unit per step)."""
    if dt is not None:
        return finite_scalar("dt", dt, positive=True)
    value = getattr(env.unwrapped, "dt", None)
    return 1.0 if value is None else finite_scalar("env.unwrapped.dt", value, positive=True)
