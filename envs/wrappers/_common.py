"""What the wrappers share: the sensor chain's seeding, the measured entries of a ``Box``
observation and the environment's time step."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium
from gymnasium import spaces

from hgo_mj._validate import finite_scalar
from hgo_mj.exceptions import DesignError, DimensionError

from ..core import reset_chain

__all__ = ["box_indices", "env_dt", "reset_chain"]


def box_indices(space: Any, indices: Sequence[int] | None, *, owner: str, name: str,
                hint: str = "") -> list[int]:
    """Entries ``indices`` of a 1-D ``Box`` observation space (``None``: all), checked to be
    distinct and in range.

    Parameters
    ----------
    space : gymnasium.Space
        The environment's observation space.
    indices : sequence of int or None
        The entries.
    owner, name : str
        What needs the space and the name of ``indices``, for the error messages.
    hint : str
        Appended to the message of a space that is not a 1-D ``Box``.

    Raises
    ------
    DesignError
        ``space`` is not a 1-D ``Box``.
    DimensionError
        ``indices`` is empty, out of range or repeats an entry.
    """
    if not isinstance(space, spaces.Box) or len(space.shape) != 1:
        raise DesignError(f"{owner} needs a 1-D Box observation space; found {space}{hint}")
    n = space.shape[0]
    if indices is None:
        return list(range(n))
    idx = [int(i) for i in indices]
    if not idx or any(i < 0 or i >= n for i in idx) or len(set(idx)) != len(idx):
        raise DimensionError(f"{name} must be distinct entries of the {n}-entry observation; "
                             f"found {list(indices)}")
    return idx


def env_dt(env: gymnasium.Env, dt: Any) -> float:
    """The time between two observations: ``dt`` if given, else ``env.unwrapped.dt`` (MuJoCo
    environments), else 1 (one unit per step)."""
    if dt is not None:
        return finite_scalar("dt", dt, positive=True)
    value = getattr(env.unwrapped, "dt", None)
    return 1.0 if value is None else finite_scalar("env.unwrapped.dt", value, positive=True)
