"""A long run streamed to disk in bounded memory (``hgo-mj run --stream``, ``run.stream``).

:func:`~hgo_mj.simulate.simulate` with ``keep=False`` hands the rows over in chunks and keeps
none; :func:`stream_run` writes each chunk to the wide Parquet table
(:mod:`hgo_mj.tidy`: the same columns, units and schema metadata as ``--format parquet``),
takes the metrics chunk by chunk (:class:`~hgo_mj.metrics.RunningMetrics`, then a pass over
the file's row groups from the end for the settling times) and keeps every k-th row for the
figure (at most :data:`FIGURE_ROWS`). The memory of the run does not grow with its duration:
``python scripts/reliability.py`` measures it (docs/reliability.md).

Each chunk is a closed Parquet file of its own in ``trajectory.parquet.parts/``, joined into
``trajectory.parquet`` (written to a temporary and renamed into place) when the run has
finished: a killed run (SIGKILL, Ctrl-C) leaves no torn ``trajectory.parquet`` (an earlier one
stays) and its rows up to the last chunk readable in the parts folder, which the next run
reports (:func:`check_no_parts`) rather than overwrites.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ._io import atomic_path
from ._json import strict_json
from .exceptions import DesignError

#: the most rows a streamed run keeps for its figure (every k-th row)
FIGURE_ROWS = 20_000
#: the fewest rows of a row group of the joined table (its last one excepted): a Parquet
#: writer keeps every row group's metadata until it closes, and a reader parses all of it
#: (1,800 row groups of 2,000 rows and 30 columns: +48 MB resident for a 3,600 s, 1 kHz run)
ROW_GROUP_ROWS = 16_384

__all__ = ["FIGURE_ROWS", "ROW_GROUP_ROWS", "ParquetChunks", "check_no_parts", "parts_folder",
           "stream_run"]


def parts_folder(path: str | Path) -> Path:
    """The folder of a streamed table's chunks while it is written: ``PATH.parts``.

    Parameters
    ----------
    path : str or Path
        The streamed table (``trajectory.parquet``).

    Returns
    -------
    Path
        ``path`` with ``.parts`` appended to its name.

    Examples
    --------
    >>> parts_folder("runs/a/trajectory.parquet").name
    'trajectory.parquet.parts'
    """
    path = Path(path)
    return path.with_name(path.name + ".parts")


def check_no_parts(path: str | Path) -> None:
    """Raise :class:`~hgo_mj.exceptions.DesignError` when the chunks of a killed streamed run
    lie in ``PATH.parts``: its rows (readable) are reported, not overwritten.

    Parameters
    ----------
    path : str or Path
        The streamed table a run is about to write.

    Raises
    ------
    DesignError
        The parts folder holds chunks; the message gives their rows and how to read them.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     check_no_parts(Path(tmp) / "trajectory.parquet")  # none: passes
    """
    import pyarrow.parquet as pq

    parts = parts_folder(path)
    files = sorted(parts.glob("*.parquet")) if parts.is_dir() else []
    if files:
        rows = sum(pq.ParquetFile(f).metadata.num_rows for f in files)
        raise DesignError(f"{parts} holds {len(files)} chunk(s), {rows} rows, of a streamed run "
                          f"that was killed: read them with pandas.read_parquet({str(parts)!r}), "
                          f"then remove the folder (or choose another --out)")


class ParquetChunks:
    """The wide table of a run written chunk by chunk (row groups of at least
    :data:`ROW_GROUP_ROWS` rows, the last one excepted).

    Parameters
    ----------
    path : str or Path
        The file to write. Each chunk is first a closed Parquet file of its own in the
        folder ``PATH.parts`` (:func:`parts_folder`), written atomically; :meth:`close`
        joins them into ``path`` (consecutive chunks into row groups of at least
        :data:`ROW_GROUP_ROWS` rows, the floats plainly encoded, atomically) and removes the
        folder. A killed run leaves its chunks there, readable
        (``pandas.read_parquet(PATH.parts)``); a new run refuses to start over them
        (:func:`check_no_parts`).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import pandas as pd
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.simulate import simulate
    >>> plant = make_plant("pendulum", dt=0.01)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     table = ParquetChunks(Path(tmp) / "run.parquet")
    ...     traj = simulate(plant, None, {"hgo": HighGainObserver(plant.system, k=30.0)},
    ...                     lambda t: [0.0], duration=1.0, keep=False,
    ...                     on_chunk=(0.25, lambda row, chunk: table.write(chunk)))
    ...     path = table.close(traj)
    ...     df = pd.read_parquet(path)
    >>> df.shape, table.chunks
    ((101, 10), 4)
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.parts = parts_folder(self.path)
        check_no_parts(self.path)
        self.parts.mkdir(parents=True, exist_ok=True)
        self.schema: Any = None
        self.chunks = 0

    def write(self, chunk: Any) -> None:
        """Append a chunk's rows as one part (the first chunk fixes the schema).

        Parameters
        ----------
        chunk : Trajectory
            The next rows of the run.

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> from hgo_mj.simulate import simulate
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> traj = simulate(plant, None, {"hgo": HighGainObserver(plant.system, k=30.0)},
        ...                 lambda t: [0.0], duration=0.1)
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     table = ParquetChunks(Path(tmp) / "run.parquet")
        ...     table.write(traj)
        ...     table.abort()
        >>> table.chunks
        1
        """
        import pyarrow as pa
        import pyarrow.parquet as pq

        from .tidy import arrow_array, wide_columns

        cols, units = wide_columns(chunk)
        if self.schema is None:
            fields = [pa.field(c, pa.float64(), metadata=None if units.get(c) is None
                               else {"unit": units[c]}) for c in cols]
            self.schema = pa.schema(fields)
            self.units = units
        # a closed file per chunk: a kill leaves every chunk before it readable
        with atomic_path(self.parts / f"part-{self.chunks:06d}.parquet") as tmp:
            # from the columns' buffers: pa.table would import pandas (arrow_array)
            pq.write_table(pa.Table.from_arrays([arrow_array(np.asarray(v, dtype=np.float64))
                                                 for v in cols.values()], schema=self.schema),
                           str(tmp))
        self.chunks += 1

    def close(self, traj: Any) -> Path:
        """Write the run's metadata (the schema's ``hgo_mj`` entry, as
        :func:`hgo_mj.tidy.write_table` writes it) and rename the file into place.

        Parameters
        ----------
        traj : Trajectory
            The run as :func:`~hgo_mj.simulate.simulate` returned it (its names and complete
            metadata; a streamed run's has no rows).

        Returns
        -------
        Path
            The file written.

        Raises
        ------
        DesignError
            No chunk was written.

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> from hgo_mj.observers import HighGainObserver
        >>> from hgo_mj.plants import make_plant
        >>> from hgo_mj.simulate import simulate
        >>> from hgo_mj.tidy import read_units
        >>> plant = make_plant("pendulum", dt=0.01)
        >>> traj = simulate(plant, None, {"hgo": HighGainObserver(plant.system, k=30.0)},
        ...                 lambda t: [0.0], duration=0.1)
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     table = ParquetChunks(Path(tmp) / "run.parquet")
        ...     table.write(traj)
        ...     units = read_units(table.close(traj))
        >>> units["hgo/angular_velocity"]
        'rad/s'
        """
        import pyarrow as pa
        import pyarrow.parquet as pq

        from .tidy import schema_metadata

        if self.schema is None:
            self.abort()
            raise DesignError("no rows were written to the streamed table")
        meta = schema_metadata(traj, "wide", self.units)
        schema = self.schema.with_metadata({"hgo_mj": json.dumps(strict_json(meta),
                                                                 allow_nan=False)})
        with atomic_path(self.path) as tmp, pq.ParquetWriter(str(tmp), schema,
                                                             use_dictionary=False) as writer:
            group: list[Any] = []  # parts joined into row groups of ROW_GROUP_ROWS or more
            for i in range(self.chunks):  # ParquetFile, not read_table: that imports
                # pyarrow.dataset (46 MB of resident memory)
                with pq.ParquetFile(self.parts / f"part-{i:06d}.parquet") as part:
                    group.append(part.read(use_threads=False).replace_schema_metadata(
                        schema.metadata))
                if sum(len(g) for g in group) >= ROW_GROUP_ROWS or i == self.chunks - 1:
                    joined = pa.concat_tables(group)
                    writer.write_table(joined, row_group_size=len(joined))
                    group = []
        shutil.rmtree(self.parts)
        return self.path

    def abort(self) -> None:
        """Remove the parts (the run failed: nothing is written in place).

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     table = ParquetChunks(Path(tmp) / "run.parquet")
        ...     table.abort()
        ...     left = list(Path(tmp).iterdir())
        >>> left
        []
        """
        shutil.rmtree(self.parts, ignore_errors=True)


class _Thinned:
    """Every ``every``-th row of the chunks of a run, as one trajectory at the end."""

    def __init__(self, every: int) -> None:
        self.every = every
        self.parts: list[Any] = []

    def add(self, first_row: int, chunk: Any) -> None:
        sel = np.arange(-first_row % self.every, len(chunk), self.every)
        if sel.size:
            self.parts.append(_rows(chunk, sel))

    def trajectory(self, traj: Any) -> Any:
        from .simulate import ObserverRecord, Trajectory

        parts = self.parts
        observers = {}
        for name, rec in traj.observers.items():
            recs = [p.observers[name] for p in parts]
            observers[name] = ObserverRecord(
                x_hat=np.concatenate([r.x_hat for r in recs]),
                z_hat=np.concatenate([r.z_hat for r in recs]),
                diagnostics={d: np.concatenate([r.diagnostics[d] for r in recs])
                             for d in rec.diagnostics},
                update_time=rec.update_time, state_names=rec.state_names)
        cols = {key: np.concatenate([getattr(p, key) for p in parts])
                for key in ("t", "x", "y_clean", "y_meas", "u")}
        return Trajectory(**cols, observers=observers, state_names=traj.state_names,
                          output_names=traj.output_names, input_names=traj.input_names,
                          metadata={**traj.metadata, "figure_every": self.every})


def _rows(chunk: Any, sel: Any) -> Any:
    """The rows ``sel`` of a chunk, as a trajectory."""
    from .simulate import ObserverRecord, Trajectory

    observers = {name: ObserverRecord(
        x_hat=rec.x_hat[sel], z_hat=rec.z_hat[sel],
        diagnostics={d: v[sel] for d, v in rec.diagnostics.items()},
        update_time=rec.update_time, state_names=rec.state_names)
        for name, rec in chunk.observers.items()}
    return Trajectory(t=chunk.t[sel], x=chunk.x[sel], y_clean=chunk.y_clean[sel],
                      y_meas=chunk.y_meas[sel], u=chunk.u[sel], observers=observers,
                      state_names=chunk.state_names, output_names=chunk.output_names,
                      input_names=chunk.input_names, metadata={})


def _settle_from_file(path: Path, acc: Any, traj: Any) -> None:
    """The settling pass of :class:`~hgo_mj.metrics.RunningMetrics` over the file's row
    groups from the last one back (only the columns it needs are read)."""
    import pyarrow.parquet as pq

    from .tidy import float_column

    pf = pq.ParquetFile(str(path))
    need = ["t"] + [f"{who}/{s}" for name in acc.est for j, s in enumerate(traj.state_names)
                    if acc.est[name][j] for who in ("true", name)]
    for i in reversed(range(pf.num_row_groups)):
        group = pf.read_row_group(i, columns=list(dict.fromkeys(need)),  # these only, and
                                 use_threads=False)  # no thread arenas kept (glibc malloc)
        t = float_column(group.column("t"))  # from the buffers: to_numpy imports pandas
        errors = {}
        for name in acc.est:
            e = np.full((len(t), len(traj.state_names)), np.nan)
            for j, s in enumerate(traj.state_names):
                if acc.est[name][j]:
                    e[:, j] = (float_column(group.column(f"true/{s}"))
                               - float_column(group.column(f"{name}/{s}")))
            errors[name] = e
        if acc.settle(t, errors):
            return


def stream_run(kw: dict[str, Any], path: str | Path, *, seed: Any, chunk_seconds: float,
               t_transient: float | None = None, band: float = 0.05,
               also: Callable[[int, Any], None] | None = None) -> tuple[Any, dict[str, Any]]:
    """Simulate with ``keep=False``, the table to ``path`` (Parquet, chunk by chunk),
    the metrics taken chunk by chunk.

    Parameters
    ----------
    kw : dict
        :func:`~hgo_mj.simulate.simulate`'s arguments (plant, sensor, observers, inputs,
        duration, and optionally sample_period, control_period, x0, metadata, store_every).
    path : str or Path
        The Parquet file.
    seed : int or None
        The sensor seed.
    chunk_seconds : float
        Simulated seconds a chunk.
    t_transient : float, optional
        As in :func:`~hgo_mj.metrics.all_metrics` (default the first 20 % of the run).
    band : float
        As in :func:`~hgo_mj.metrics.all_metrics`.
    also : callable, optional
        Also called with every chunk, ``also(first_row, chunk)`` (a recording).

    Returns
    -------
    (Trajectory, dict)
        Every k-th row of the run (at most :data:`FIGURE_ROWS` rows; the metadata's
        ``figure_every`` is k) for the figure, and the metrics of the whole run, equal to
        :func:`~hgo_mj.metrics.all_metrics` of the run kept in memory.

    Raises
    ------
    DesignError
        A ``t_transient`` that leaves no samples (before the run), or what
        :func:`~hgo_mj.simulate.simulate` refuses.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> plant = make_plant("pendulum", dt=0.01)
    >>> kw = {"plant": plant, "sensor": None, "inputs": lambda t: [0.0], "duration": 2.0,
    ...       "observers": {"hgo": HighGainObserver(plant.system, k=30.0)}}
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     thin, metrics = stream_run(kw, Path(tmp) / "run.parquet", seed=0,
    ...                                chunk_seconds=0.5)
    >>> len(thin), metrics["hgo"]["states"]
    (201, ['angle', 'angular_velocity'])
    """
    from .metrics import RunningMetrics
    from .simulate import simulate

    plant = kw["plant"]
    ts = float(kw.get("sample_period") or plant.dt)
    every = int(kw.get("store_every", 1))
    N = int(round(float(kw["duration"]) / ts))
    rows = N // every + 1
    t_end = (N // every) * every * ts
    t_transient = 0.2 * t_end if t_transient is None else t_transient
    if t_transient > t_end:
        raise DesignError(f"t_transient = {t_transient:g} leaves no samples (run ends at "
                          f"{t_end:g})")
    table = ParquetChunks(path)
    thin = _Thinned(max(1, -(-rows // FIGURE_ROWS)))
    acc: Any = None

    def take(first_row: int, chunk: Any) -> None:
        nonlocal acc
        if acc is None:
            acc = RunningMetrics(chunk, t_transient=t_transient, band=band)
        table.write(chunk)
        acc.add(chunk)
        thin.add(first_row, chunk)
        if also is not None:
            also(first_row, chunk)

    try:
        traj = simulate(**kw, seed=seed, on_chunk=(chunk_seconds, take), keep=False,
                        isolate=True)
        table.close(traj)
    except KeyboardInterrupt:
        raise  # the chunks written stay readable in the parts folder (check_no_parts)
    except BaseException:
        table.abort()
        raise
    _settle_from_file(Path(path), acc, traj)
    metrics = acc.result(traj)
    for name, d in traj.diverged.items():
        metrics[name]["diverged_at"] = d["t"]
    _release_freed_memory()  # the join's and the settling pass's, before the figure is drawn
    return thin.trajectory(traj), metrics


def _release_freed_memory() -> bool:
    """Hand the memory the process has freed back to the system where the C library keeps it
    (glibc's ``malloc_trim(0)``; elsewhere nothing). After a streamed run's join and
    settling pass (Arrow's buffers come from the C library's allocator, see
    :func:`hgo_mj.cli.main`) it lowers the resident set the figure then adds to: a 3,600 s,
    1 kHz run 259 -> 238 MB before the figure, peak 292 -> 284 MB (BENCHMARKS.md).

    Returns
    -------
    bool
        Whether ``malloc_trim`` was called.

    Examples
    --------
    >>> import sys
    >>> _release_freed_memory() == (sys.platform == "linux" and _malloc_trim() is not None)
    True
    """
    trim = _malloc_trim()
    if trim is None:
        return False
    trim(0)
    return True


def _malloc_trim() -> Any:
    """glibc's ``malloc_trim``, or None (another C library or system)."""
    import sys

    if sys.platform != "linux":
        return None
    import ctypes

    try:
        return ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError):  # musl and others: no malloc_trim
        return None
