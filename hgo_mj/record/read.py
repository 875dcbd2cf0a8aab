"""Reading a recording back: :func:`read` returns its series as a pandas DataFrame.

Read with rerun's own reader (``rerun.chunk.RrdReader``, rerun-sdk >= 0.39), so a recording is
checked against what rerun itself decodes, not against a second parser.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from ..exceptions import DesignError
from .layout import EPISODE, SERIES_ROOTS, SIM_TIME, STEP

__all__ = ["read"]

#: the component holding a scalar series' values
SCALARS = "Scalars:scalars"
#: static components that name the series of an entity, in order
_NAMES = ("SeriesLines:names", "SeriesPoints:names")


def read(path: str | Path) -> Any:
    """The scalar series of a recording (``.rrd``) as a :class:`pandas.DataFrame`.

    One row per ``step`` (the index, the recording's ``step`` timeline; a series logged on
    ``sim_time`` alone takes the step of the true state's row at its time), the ``sim_time``
    timeline in seconds as a column (and ``episode`` where episodes were recorded), and one
    column per series: ``<entity>[<name>]`` with the series' name from its style without its
    unit for the entities of a state, an error or an output, which hold one series per source
    whatever their number (``/state/angle[angle true]``, ``/state/angle[angle fast]``,
    ``/error/angle[angle error fast]``, ``/sensor/angle[angle measured]``), and for any other
    entity of several series; the entity path where it holds one (``/input/torque``,
    ``/observer/fast/gain``); ``<entity>[<i>]`` where its series have no distinct names. A
    series not logged at a step is NaN there (a diagnostic logged only when it changes,
    decimated poses).
    ``df.attrs["static"]`` holds every entity's static components
    (``df.attrs["static"]["/scenario"]["TextDocument:text"][0]`` is the scenario document);
    ``df.attrs["units"]`` maps each series to the unit in its name (``angle true [rad]``:
    ``"rad"``; ``""`` dimensionless), for the series named with one.
    Poses (``Transform3D``) and other non-scalar components are not series and are left out.

    Parameters
    ----------
    path : str or Path
        A recording written by :class:`~hgo_mj.record.Recorder` (``.rrd``).

    Returns
    -------
    pandas.DataFrame
        Indexed by ``step``; columns ``sim_time`` (s), ``episode`` (environment recordings
        only) and one float column per series, NaN where a series was not logged; its
        ``attrs`` hold ``"static"`` (entity path -> component -> value) and ``"units"``
        (column -> unit string).

    Raises
    ------
    DesignError
        The file does not exist or holds no recording.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from hgo_mj.record import record_trajectory
    >>> from hgo_mj.inputs import Multisine
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.sensors import GaussianNoise, SensorChain
    >>> from hgo_mj.simulate import simulate
    >>> plant = make_plant("pendulum", dt=0.01)
    >>> traj = simulate(plant, SensorChain([GaussianNoise(std=1e-3)], seed=0),
    ...                 {"k40": HighGainObserver(plant.system, k=40.0)},
    ...                 Multisine(amplitudes=[0.3], frequencies=[0.5]), duration=0.1,
    ...                 x0=[0.5, 0.0], seed=0)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     df = read(record_trajectory(traj, Path(tmp) / "pendulum.rrd"))
    >>> df[["sim_time", "/state/angle[angle true]", "/state/angle[angle k40]"]].shape
    (11, 3)
    >>> float(df["sim_time"].iloc[-1])
    0.1
    >>> df.attrs["units"]["/state/angle[angle k40]"]
    'rad'
    >>> "/scenario" in df.attrs["static"]
    True
    """
    import pandas as pd
    from rerun.chunk import RrdReader

    path = Path(path)
    if not path.is_file():
        raise DesignError(f"recording {str(path)!r} does not exist")
    try:
        reader = RrdReader(path)
        chunks = list(reader.stream())
    except Exception as exc:  # rerun's own errors: not a readable recording
        raise DesignError(f"cannot read {str(path)!r} as a rerun recording: {exc}") from None
    static: dict[str, dict[str, Any]] = {}
    parts: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
    clocks: list[Any] = []
    loose: list[tuple[str, np.ndarray, np.ndarray]] = []  # series on sim_time alone
    for chunk in chunks:
        rb = chunk.to_record_batch()
        names = [n for n in rb.schema.names if not n.startswith("rerun.controls")]
        if chunk.is_static:
            comps = static.setdefault(chunk.entity_path, {})
            for name in names:
                comps[name] = rb.column(name).to_pylist()[-1]
            continue
        if STEP not in names:
            if SIM_TIME in names and SCALARS in names:
                loose.append((chunk.entity_path, _nanoseconds(rb), _scalars(rb.column(SCALARS))))
            continue
        steps = rb.column(STEP).to_numpy()
        clocks.append(_clock_frame(rb, names, steps))
        if SCALARS in names:
            parts.setdefault(chunk.entity_path, []).append((steps, _scalars(rb.column(SCALARS))))
    clock = (pd.concat(clocks) if clocks else pd.DataFrame(columns=[SIM_TIME, "ns"]))
    clock = clock[~clock.index.duplicated(keep="last")]
    _place(loose, clock, parts)
    clock = clock.drop(columns="ns")
    columns, units = {}, {}
    for entity, got in parts.items():
        steps = np.concatenate([s for s, _ in got])
        values = _stack([v for _, v in got])
        labels = _labels(entity, values.shape[1], static.get(entity, {}))
        frame = pd.DataFrame(values, index=pd.Index(steps, name=STEP),
                             columns=[c for c, _ in labels])
        frame = frame[~frame.index.duplicated(keep="last")]
        for column, unit in labels:
            columns[column] = frame[column]
            if unit is not None:
                units[column] = unit
    df = pd.concat([clock, pd.DataFrame(columns)], axis=1).sort_index()
    df.index.name = STEP
    df.attrs["static"] = static
    df.attrs["units"] = units
    return df


def _named(name: object) -> tuple[str, str | None]:
    """A series' name without its unit, and the unit (``"angle true [rad]"``:
    ``("angle true", "rad")``; ``[-]``: ``""``; no bracket: ``None``)."""
    m = re.fullmatch(r"(.*) \[([^\]]*)\]", str(name))
    if m is None:
        return str(name), None
    return m.group(1), "" if m.group(2) == "-" else m.group(2)


def _nanoseconds(rb: Any) -> np.ndarray:
    """The ``sim_time`` column of a record batch in integer nanoseconds."""
    import pyarrow as pa

    return rb.column(SIM_TIME).cast(pa.int64()).to_numpy(zero_copy_only=False)


def _place(loose: list[tuple[str, np.ndarray, np.ndarray]], clock: Any,
           parts: dict[str, list[tuple[np.ndarray, np.ndarray]]]) -> None:
    """Give the rows of series logged on ``sim_time`` alone the step of the true state's row
    at the same ``sim_time`` (``clock``: step -> ``ns``); a time no step has is dropped."""
    if not loose:
        return
    ns = clock["ns"].to_numpy(dtype=np.int64)
    order = np.argsort(ns, kind="stable")
    ns, steps = ns[order], clock.index.to_numpy()[order]
    for entity, t, values in loose:
        at = np.clip(np.searchsorted(ns, t), 0, max(ns.size - 1, 0))
        found = (ns[at] == t) if ns.size else np.zeros(t.size, dtype=bool)
        parts.setdefault(entity, []).append((steps[at[found]], values[found]))


def _clock_frame(rb: Any, names: list[str], steps: np.ndarray) -> Any:
    import pandas as pd

    out: dict[str, Any] = {}
    if SIM_TIME in names:
        out["ns"] = _nanoseconds(rb)
        out[SIM_TIME] = out["ns"] / 1e9
    if EPISODE in names:
        out[EPISODE] = rb.column(EPISODE).to_numpy(zero_copy_only=False)
    return pd.DataFrame(out, index=pd.Index(steps, name=STEP))


def _scalars(col: Any) -> np.ndarray:
    """A column of scalar lists as ``(rows, width)`` floats; ragged or missing rows padded
    with NaN."""
    import pyarrow.compute as pc

    lens = pc.list_value_length(col).to_numpy(zero_copy_only=False)
    if col.null_count == 0 and len(lens) and np.all(lens == lens[0]):
        flat = col.flatten().to_numpy(zero_copy_only=False).astype(float)
        return flat.reshape(len(lens), int(lens[0]))
    rows = col.to_pylist()
    width = max((len(r) for r in rows if r is not None), default=1)
    out = np.full((len(rows), width), np.nan)
    for i, r in enumerate(rows):
        if r:
            out[i, : len(r)] = r
    return out


def _stack(blocks: list[np.ndarray]) -> np.ndarray:
    width = max(b.shape[1] for b in blocks)
    return np.concatenate([np.pad(b, ((0, 0), (0, width - b.shape[1])), constant_values=np.nan)
                           for b in blocks])


def _labels(entity: str, width: int, static: dict[str, Any]) -> list[tuple[str, str | None]]:
    """The column and unit of each of an entity's ``width`` series: from the names of its
    style (``SeriesLines`` or ``SeriesPoints``) when they are ``width`` distinct names."""
    names = next((static[k] for k in _NAMES if static.get(k)), None)
    named = [_named(n) for n in names] if names is not None and len(names) == width else None
    if named is not None and len({n for n, _ in named}) != width:
        named = None
    if width == 1 and not (named and entity.startswith(SERIES_ROOTS)):
        return [(entity, named[0][1] if named else None)]
    if named is None:
        return [(f"{entity}[{i}]", None) for i in range(width)]
    return [(f"{entity}[{n}]", u) for n, u in named]
