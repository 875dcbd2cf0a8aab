"""Record every episode of an hgo_mj environment to a rerun ``.rrd`` file."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import gymnasium
import numpy as np
from gymnasium.utils import RecordConstructorArgs
from numpy.typing import NDArray

from hgo_mj.exceptions import DesignError

if TYPE_CHECKING:
    from hgo_mj.record import Recorder

    from ..core import HgoEnv

Array = NDArray[np.float64]

_COLUMNS = ("t", "x", "y", "y_clean", "u", "x_hat", "diagnostics", "reward")


class RecordEpisodes(gymnasium.Wrapper[Any, Any, Any, Any], RecordConstructorArgs):
    """Write every episode of an hgo_mj environment (:class:`~hgo_mj.envs.HgoEnv`), batched at
    its end (the next ``reset`` or ``close``), to the rerun recording ``path``
    (:class:`hgo_mj.record.Recorder`), as Gymnasium's ``RecordEpisodeStatistics`` records
    statistics: one row at ``reset`` and one per ``step`` (``steps + 1`` rows an episode; the
    reset row's input and reward are 0) on the ``sim_time``, ``step`` and ``episode``
    timelines: true state, the observer's estimate by its own ``state_names`` and errors,
    clean and measured outputs, input, the observer's diagnostics, the reward
    (``/env/reward``), the 3D view; after each episode the ``/metrics`` table (one row per
    episode: seed, steps, return, RMSE per estimated state) and the ``/scenario`` document
    (the environment's ``recording_metadata()``, with every episode's seed).

    Parameters
    ----------
    env : gymnasium.Env
        An hgo_mj environment, possibly wrapped (``TimeLimit`` from ``gymnasium.make``).
    path : str or Path
        The ``.rrd`` file to write.

    Attributes
    ----------
    episodes : list of dict
        Per finished episode: ``episode``, ``seed``, ``steps``, ``return``, ``terminated`` and,
        with an observer, ``rmse`` and ``final_error`` by estimated state name.

    Raises
    ------
    DesignError
        ``env`` is not an hgo_mj environment (its unwrapped environment lacks
        ``current_row`` and ``loop``).

    Examples
    --------
    >>> import gymnasium, hgo_mj.envs  # doctest: +SKIP
    >>> env = RecordEpisodes(gymnasium.make("hgo_mj/PendulumSwingUp-v0"), "episodes.rrd")  # doctest: +SKIP

    Two episodes into a temporary file; the first is written at the second ``reset``:

    >>> import os
    >>> import tempfile
    >>> import gymnasium
    >>> import numpy as np
    >>> import hgo_mj.envs
    >>> from hgo_mj.envs.wrappers import RecordEpisodes
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = os.path.join(tmp, "episodes.rrd")
    ...     env = RecordEpisodes(gymnasium.make("hgo_mj/PendulumSwingUp-v0"), path)
    ...     _ = env.reset(seed=0)
    ...     for _ in range(3):
    ...         _ = env.step(np.zeros(1, dtype=np.float32))
    ...     _ = env.reset(seed=1)
    ...     env.close()
    ...     written = os.path.getsize(path) > 0
    >>> written, env.episodes[0]["steps"], round(env.episodes[0]["return"], 2)
    (True, 3, -29.21)
    """

    def __init__(self, env: gymnasium.Env, path: str | Path) -> None:
        RecordConstructorArgs.__init__(self, path=str(path))
        gymnasium.Wrapper.__init__(self, env)
        if not hasattr(env.unwrapped, "current_row") or not hasattr(env.unwrapped, "loop"):
            raise DesignError(f"RecordEpisodes records an hgo_mj environment (HgoEnv); found "
                              f"{type(env.unwrapped).__name__}")
        from hgo_mj.record import Recorder

        base = self._base
        self.path = Path(path)
        obs = base.observer
        names = [] if obs is None else [obs.name or type(obs).__name__]
        states = {names[0]: base.estimate_names} if names else None
        self.recorder: Recorder | None = Recorder.for_plant(self.path, base.plant, observers=names,
                                           observer_states=states,
                                           recording_name=type(base).__name__,
                                           dropouts=base.sensor.has_dropouts)
        self._rows: dict[str, list[Any]] = {k: [] for k in _COLUMNS}
        self._episode = -1
        self._seed: int | None = None
        #: per finished episode: its seed and metrics (the ``/metrics`` document)
        self.episodes: list[dict[str, Any]] = []

    @property
    def _base(self) -> HgoEnv:
        """The wrapped hgo_mj environment (its methods checked in ``__init__``)."""
        return cast("HgoEnv", self.env.unwrapped)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[Any, dict[str, Any]]:
        self._write_episode()
        out = self.env.reset(seed=seed, options=options)
        self._episode += 1
        self._seed = seed
        self._add(self._base.current_row())
        return out

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        out = self.env.step(action)
        self._add(self._base.current_row())
        return out

    def close(self) -> None:
        """Write the last episode and close the recording."""
        if self.recorder is not None:
            self._write_episode()
            self.recorder.close()
            self.recorder = None
        super().close()

    def _add(self, row: dict[str, Any]) -> None:
        for k in _COLUMNS:
            self._rows[k].append(row[k])

    def metadata_document(self) -> dict[str, Any]:
        """The environment's ``recording_metadata()`` with the seed of every episode.

        Returns
        -------
        dict
            :meth:`~hgo_mj.envs.HgoEnv.recording_metadata` plus ``"seed"`` (the first
            episode's, else the current one's) and ``"seeds"`` (episode number as str -> seed,
            finished episodes only); what the ``/scenario`` document holds.

        Examples
        --------
        >>> import os
        >>> import tempfile
        >>> import gymnasium
        >>> import hgo_mj.envs
        >>> from hgo_mj.envs.wrappers import RecordEpisodes
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     env = RecordEpisodes(gymnasium.make("hgo_mj/PendulumSwingUp-v0"),
        ...                          os.path.join(tmp, "episodes.rrd"))
        ...     _ = env.reset(seed=0)
        ...     _ = env.reset(seed=1)
        ...     meta = env.metadata_document()
        ...     env.close()
        >>> meta["scenario"], meta["seed"], meta["seeds"]
        ('hgo_mj/PendulumSwingUp-v0', 0, {'0': 0})
        """
        meta = self._base.recording_metadata()
        seeds = [e["seed"] for e in self.episodes]
        meta["seed"] = seeds[0] if seeds else self._seed
        meta["seeds"] = {str(e["episode"]): e["seed"] for e in self.episodes}
        return meta

    def _metrics(self, x: Array, xh: Array | None, rewards: list[float]) -> dict[str, Any]:
        base = self._base
        out: dict[str, Any] = {"episode": self._episode, "seed": self._seed,
                               "steps": len(x) - 1, "return": float(np.sum(rewards[1:])),
                               "terminated": bool(base.task.terminated(list(x[-1])))}
        if xh is not None:
            rmse: dict[str, float] = {}
            final: dict[str, float] = {}
            for j, i in base._err_pairs:
                e = x[:, j] - xh[:, i]
                ok = np.isfinite(e)
                name = base.state_names[j]
                rmse[name] = float(np.sqrt(np.mean(e[ok] ** 2))) if ok.any() else math.nan
                final[name] = float(abs(e[-1]))
            out["rmse"] = rmse
            out["final_error"] = final
        return out

    def _write_episode(self) -> None:
        rows = self._rows
        if self.recorder is None or not rows["t"]:
            return
        rec = self.recorder
        x = np.array(rows["x"], dtype=float)
        est = diag = xh = None
        if rows["x_hat"][0] is not None:
            name = rec.observers[0]
            xh = np.array(rows["x_hat"], dtype=float)
            est = {name: xh}
            keys = rows["diagnostics"][0].keys()
            diag = {name: {k: np.array([d.get(k, math.nan) for d in rows["diagnostics"]],
                                       dtype=float) for k in keys}}
        rec.record_episode(self._episode, np.array(rows["t"], dtype=float), x,
                           np.array(rows["y"], dtype=float), np.array(rows["u"], dtype=float),
                           y_clean=np.array(rows["y_clean"], dtype=float), estimates=est,
                           diagnostics=diag, extra={"reward": np.array(rows["reward"])})
        self.episodes.append(self._metrics(x, xh, rows["reward"]))
        rec.log_metadata(self.metadata_document())
        rec.log_episode_metrics(self.episodes)
        for v in rows.values():
            v.clear()


__all__ = ["RecordEpisodes"]
