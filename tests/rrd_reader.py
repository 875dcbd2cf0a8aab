"""Reading a rerun recording (``.rrd``) back in tests, with rerun's own reader.

The reader is ``rerun.chunk.RrdReader`` (rerun-sdk 0.41's Python reader of ``.rrd`` files: it
streams the file's chunks as Arrow record batches). Used by ``test_record.py`` (recordings of
trajectories) and ``test_envs.py`` (recordings of environment episodes).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
from rerun.chunk import RrdReader


class Entity:
    """What a recording holds for one entity: static components, and its temporal rows
    (concatenated over chunks, sorted by ``step``)."""

    def __init__(self) -> None:
        self.static: dict[str, list] = {}
        self._batches: list = []

    def _rows(self) -> dict[str, np.ndarray | list]:
        if not hasattr(self, "_cache"):
            cols: dict[str, list] = {}
            for rb in self._batches:
                for name in rb.schema.names:
                    if not name.startswith("rerun.controls"):
                        cols.setdefault(name, []).extend(rb.column(name).to_pylist())
            order = np.argsort(np.array(cols["step"]), kind="stable") if "step" in cols else None
            out: dict[str, np.ndarray | list] = {}
            for name, v in cols.items():
                if name == "sim_time":
                    arr = np.array([d.total_seconds() for d in v])
                elif name in ("step", "episode"):
                    arr = np.array(v, dtype=np.int64)
                else:
                    arr = np.array([np.array(r, dtype=float).reshape(-1) for r in v])
                out[name] = arr[order] if order is not None else arr
            self._cache = out
        return self._cache

    def __getitem__(self, name: str) -> np.ndarray:
        return self._rows()[name]

    @property
    def rows(self) -> int:
        return sum(rb.num_rows for rb in self._batches)

    @property
    def series(self) -> list[str]:
        """The names of the entity's series (its ``SeriesLines`` style), without their units."""
        return [re.sub(r" \[[^\]]*\]$", "", n) for n in self.static.get("SeriesLines:names", [])]

    def scalars(self, name: str) -> np.ndarray:
        """The values of the series ``name`` (:attr:`series`), one a row."""
        return self["Scalars:scalars"][:, self.series.index(name)]


def read_rrd(path: Path) -> tuple[dict[str, Entity], int]:
    """Entities of the file's recording, and the number of blueprint stores in it."""
    reader = RrdReader(path)
    entities: dict[str, Entity] = {}
    for chunk in reader.stream():
        e = entities.setdefault(chunk.entity_path, Entity())
        rb = chunk.to_record_batch()
        if chunk.is_static:
            for name in rb.schema.names:
                if not name.startswith("rerun.controls"):
                    e.static[name] = rb.column(name).to_pylist()[-1]
        else:
            e._batches.append(rb)
    return entities, len(reader.blueprints())


def blueprint_views(path: Path) -> list[tuple[str, str]]:
    """(view class, space origin) of every view of the file's blueprint."""
    reader = RrdReader(path)
    views = []
    for chunk in reader.stream(store=reader.blueprints()[-1]):
        rb = chunk.to_record_batch()
        if "ViewBlueprint:class_identifier" in rb.schema.names:
            views.append((rb.column("ViewBlueprint:class_identifier").to_pylist()[0][0],
                          rb.column("ViewBlueprint:space_origin").to_pylist()[0][0]))
    return views


def blueprint_view_names(path: Path) -> list[str]:
    """The display name of every view of the file's blueprint."""
    reader = RrdReader(path)
    names = []
    for chunk in reader.stream(store=reader.blueprints()[-1]):
        rb = chunk.to_record_batch()
        if "ViewBlueprint:display_name" in rb.schema.names:
            names += [v[0] for v in rb.column("ViewBlueprint:display_name").to_pylist() if v]
    return names


def chunk_ids(path: Path) -> list[str]:
    """The id of every chunk of the file, its recording's and its blueprints' (in file order)."""
    reader = RrdReader(path)
    stores = [None, *reader.blueprints()]
    return [chunk.id for store in stores for chunk in reader.stream(store=store)]


__all__ = ["Entity", "blueprint_view_names", "blueprint_views", "chunk_ids", "read_rrd"]
