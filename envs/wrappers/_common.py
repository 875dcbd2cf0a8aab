"""What the wrappers share: the sensor chain's seeding, the measured entries of a ``Box``
observation, the environment's time step and the cache of tuned observers."""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium
from gymnasium import spaces

from hgo_mj._validate import finite_scalar
from hgo_mj.exceptions import DesignError, DimensionError

from ..core import reset_chain

__all__ = ["box_indices", "cache_key", "cache_path", "cache_read", "cache_write", "env_dt",
           "reset_chain"]


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


# ------------------------------------------------------------------ the tuning cache
#: the cache file's format; an entry of another format is ignored (tuned again)
CACHE_VERSION = 1


def cache_path(cache: Any) -> Path | None:
    """The tuning cache file: ``cache`` if a path, none if ``False``, else
    ``$XDG_CACHE_HOME/hgo_mj/tuned.json`` (``~/.cache/hgo_mj/tuned.json`` without it)."""
    if cache is False:
        return None
    if cache is None or cache is True:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        return Path(base) / "hgo_mj" / "tuned.json"
    if not isinstance(cache, (str, os.PathLike)):
        raise DesignError(f"tuning cache must be a path, None (the user cache) or False (no "
                          f"cache); found {cache!r}")
    return Path(cache)


def cache_key(**parts: Any) -> str:
    """One entry's key: ``parts`` as sorted JSON (anything not JSON by its ``repr``)."""
    return json.dumps(parts, sort_keys=True, default=repr)


def cache_read(path: Path | None, key: str) -> dict[str, Any] | None:
    """The entry ``key`` of the cache file (None: no file, no entry, or an unreadable file)."""
    if path is None or not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(doc, dict) or doc.get("version") != CACHE_VERSION:
        return None
    entry = doc.get("entries", {}).get(key)
    return entry if isinstance(entry, dict) else None


def cache_write(path: Path | None, key: str, entry: dict[str, Any]) -> None:
    """Add ``entry`` under ``key`` to the cache file, written atomically (a reader never sees
    a half-written file; of two processes writing at once, the last one's file stands)."""
    if path is None:
        return
    from hgo_mj._io import write_text

    doc: dict[str, Any] = {"version": CACHE_VERSION, "entries": {}}
    if path.is_file():
        try:
            old = json.loads(path.read_text(encoding="utf-8"))
            if isinstance(old, dict) and old.get("version") == CACHE_VERSION:
                doc["entries"] = dict(old.get("entries", {}))
        except (OSError, ValueError):
            pass
    doc["entries"][key] = entry
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text(path, json.dumps(doc, indent=1, sort_keys=True) + "\n")
