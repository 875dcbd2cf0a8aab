"""A :class:`~hgo_mj.simulate.Trajectory` as a table: pandas, Arrow, Parquet and CSV.

Wide form (one row per sample instant), the columns in this order:

==============================  ==========================================================
``t``                           time of the sample
``true/<state>``                the plant's true state
``<observer>/<state>``          the observer's estimate, one column per column of its
                                ``x_hat`` (its own ``state_names``: plant states, output
                                derivatives, parameter estimates)
``<observer>/diagnostics/<d>``  its run-time diagnostics (gain, dropouts, ...)
``measured/<output>``           the measurement the observers saw
``clean/<output>``              the plant's output before the sensor chain
``input/<input>``               the input applied over the next sample
==============================  ==========================================================

Long form (tidy, one row per sample and column of the wide form): ``t``, ``source`` (the
column's name up to its last ``/``: ``true``, an observer, ``<observer>/diagnostics``,
``measured``, ``clean``, ``input``), ``name`` (after the last ``/``), ``value`` and ``unit``.

Units come from the plant's system (:mod:`hgo_mj.units`): in the wide form each Arrow field
carries its unit in the field metadata (key ``unit``; absent when unknown, ``""`` for
dimensionless) and ``DataFrame.attrs["units"]`` maps each column to its unit; the long form
has them in its ``unit`` column. The Arrow schema metadata (key ``hgo_mj``) holds, as strict
JSON, the form, the units, the time unit, the names and the run's metadata; ``z_hat`` (the
observers' own normal-form coordinates) stays in the ``.npz`` only.

Examples
--------
>>> from hgo_mj.inputs import Constant
>>> from hgo_mj.observers import make_observer
>>> from hgo_mj.plants import make_plant
>>> from hgo_mj.simulate import simulate
>>> plant = make_plant("pendulum", 0.01)
>>> traj = simulate(plant, None, {"hgo": make_observer("high_gain", plant.system, k=20.0)},
...                 Constant(0.0), duration=0.05)
>>> df = traj.to_pandas()
>>> list(df.columns[:5])
['t', 'true/angle', 'true/angular_velocity', 'hgo/angle', 'hgo/angular_velocity']
>>> df.attrs["units"]["hgo/angular_velocity"]
'rad/s'
>>> traj.to_pandas("long").columns.tolist()
['t', 'source', 'name', 'value', 'unit']
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ._io import atomic_path, write_text
from ._json import strict_json
from .exceptions import DesignError
from .units import units_of

#: the sources of the wide form's columns that are not observers
RESERVED = ("t", "true", "measured", "clean", "input")
#: the table forms
FORMS = ("wide", "long")
#: the file formats of :func:`write_table` (``npz`` is :meth:`Trajectory.save`)
FILE_FORMATS = ("parquet", "csv")


def _check_form(form: Any) -> str:
    if not isinstance(form, str) or form not in FORMS:
        raise DesignError(f"form must be one of {list(FORMS)}; found {form!r}")
    return form


def _columns(x: Any) -> list[Any]:
    """The columns of a ``(T,)`` or ``(T, k)`` array."""
    a = np.asarray(x, dtype=float)
    return [a] if a.ndim == 1 else [a[:, j] for j in range(a.shape[1])]


def wide_columns(traj: Any) -> tuple[dict[str, Any], dict[str, str | None]]:
    """The wide form's columns ``{name: (T,) array}`` in order, and each column's unit
    (``None``: unknown)."""
    for name in traj.observers:
        if name in RESERVED or "/" in name:
            raise DesignError(f"observer name {name!r} cannot name table columns: expected no "
                              f"'/' and none of {list(RESERVED)}")
    units, t_unit = units_of(traj)
    cols: dict[str, Any] = {"t": np.asarray(traj.t, dtype=float)}
    unit: dict[str, str | None] = {"t": t_unit}

    def put(source: str, names: Any, values: Any, fixed: Any = False) -> None:
        for name, v in zip(names, _columns(values)):
            key = f"{source}/{name}"
            cols[key] = v
            unit[key] = units.get(name) if fixed is False else fixed

    put("true", traj.state_names, traj.x)
    for oname, rec in traj.observers.items():
        put(oname, rec.state_names, rec.x_hat)
        for d, v in rec.diagnostics.items():
            put(f"{oname}/diagnostics", [d], v, "" if d == "dropouts" else None)
    put("measured", traj.output_names, traj.y_meas)
    put("clean", traj.output_names, traj.y_clean)
    put("input", traj.input_names, traj.u)
    return cols, unit


def arrow_array(values: Any) -> Any:
    """A column as a ``pyarrow.Array`` built from its buffers, without pandas: ``pa.array``
    and ``pa.table`` of numpy or Python data import pandas (pyarrow's pandas shim checks
    their types; 69 MB of resident memory), ``Array.from_buffers`` does not.

    Parameters
    ----------
    values : ndarray or sequence
        A numeric array (float64, or int64 where every entry is an integer), or a sequence of
        bools, of ``str``/``None`` (a string column, ``None`` null), or of numbers and ``None``
        (float64, ``None`` as NaN; int64 where every entry is an integer): the types pandas
        gives the same values.

    Returns
    -------
    pyarrow.Array

    Examples
    --------
    >>> from hgo_mj.tidy import arrow_array
    >>> arrow_array(["rad", None]).to_pylist(), arrow_array([1, 2]).type
    (['rad', None], DataType(int64))
    >>> arrow_array([0.5, None]).to_pylist(), arrow_array([True, False]).to_pylist()
    ([0.5, nan], [True, False])
    """
    import pyarrow as pa

    if not isinstance(values, np.ndarray):
        vals = list(values)
        if vals and all(isinstance(v, (bool, np.bool_)) for v in vals):
            bits = np.packbits(np.array(vals, dtype=bool), bitorder="little")
            return pa.Array.from_buffers(pa.bool_(), len(vals), [None, pa.py_buffer(bits)])
        if any(isinstance(v, str) for v in vals) or (vals and all(v is None for v in vals)):
            data = [b"" if v is None else str(v).encode() for v in vals]
            offsets = np.zeros(len(data) + 1, dtype=np.int32)
            offsets[1:] = np.cumsum([len(b) for b in data])
            valid = np.packbits(np.array([v is not None for v in vals], dtype=bool),
                                bitorder="little")
            return pa.Array.from_buffers(
                pa.string(), len(vals), [pa.py_buffer(valid), pa.py_buffer(offsets),
                                         pa.py_buffer(b"".join(data))],
                null_count=sum(v is None for v in vals))
        ints = vals and all(isinstance(v, (int, np.integer)) for v in vals)
        values = np.array([np.nan if v is None else v for v in vals],
                          dtype=np.int64 if ints else np.float64)
    kind = np.int64 if values.dtype.kind in "iu" else np.float64
    arr = np.ascontiguousarray(values, dtype=kind)
    return pa.Array.from_buffers(pa.int64() if kind is np.int64 else pa.float64(), arr.size,
                                 [None, pa.py_buffer(arr)])


def float_column(column: Any) -> Any:
    """A float64 Arrow column (``Array`` or ``ChunkedArray``) as a new numpy array, null as
    NaN, read from its buffers: ``to_numpy`` imports pandas (see :func:`arrow_array`).

    Parameters
    ----------
    column : pyarrow.Array or pyarrow.ChunkedArray
        Of type float64.

    Returns
    -------
    ndarray, shape (len(column),)

    Examples
    --------
    >>> import pyarrow as pa
    >>> from hgo_mj.tidy import arrow_array, float_column
    >>> col = pa.chunked_array([arrow_array([0.5, 1.5]), arrow_array([2.5])])
    >>> float_column(col).tolist(), float_column(col.chunk(0).slice(1)).tolist()
    ([0.5, 1.5, 2.5], [1.5])
    """
    chunks = getattr(column, "chunks", [column])
    out = np.empty(sum(len(a) for a in chunks))
    i = 0
    for a in chunks:
        n = len(a)
        valid, data = a.buffers()
        out[i:i + n] = np.frombuffer(data, dtype=np.float64, count=n, offset=a.offset * 8)
        if a.null_count:
            bits = np.unpackbits(np.frombuffer(valid, dtype=np.uint8), bitorder="little")
            out[i:i + n][~bits[a.offset:a.offset + n].astype(bool)] = np.nan
        i += n
    return out


def write_rows_parquet(rows: list[dict[str, Any]], columns: list[str], path: str | Path) -> None:
    """Write rows (one mapping each) as a Parquet table of ``columns``, atomically, without
    pandas (:func:`arrow_array`): ``metrics.parquet``.

    Parameters
    ----------
    rows : list of dict
        One mapping per row, from column name to value.
    columns : list of str
        The columns, in order.
    path : str or Path
        The file.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import pyarrow.parquet as pq
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     write_rows_parquet([{"state": "angle", "rmse": 0.1}], ["state", "rmse"],
    ...                        Path(tmp) / "m.parquet")
    ...     pq.read_table(Path(tmp) / "m.parquet").to_pylist()
    [{'state': 'angle', 'rmse': 0.1}]
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_arrays([arrow_array([r.get(c) for r in rows]) for c in columns],
                                 names=list(columns))
    with atomic_path(Path(path)) as tmp:
        pq.write_table(table, str(tmp))


def schema_metadata(traj: Any, form: str, units: dict[str, str | None]) -> dict[str, Any]:
    """What the Arrow schema's ``hgo_mj`` metadata holds (strict JSON data)."""
    return strict_json({
        "form": form, "units": units, "time_unit": units.get("t"),
        "state_names": list(traj.state_names), "output_names": list(traj.output_names),
        "input_names": list(traj.input_names),
        "observers": {name: {"state_names": list(rec.state_names),
                             "diagnostics": list(rec.diagnostics),
                             "update_time": rec.update_time}
                      for name, rec in traj.observers.items()},
        "metadata": traj.metadata})


def to_pandas(traj: Any, form: str = "wide") -> Any:
    """The trajectory as a :class:`pandas.DataFrame` in the wide or long form (see the module
    docstring); ``attrs["units"]`` maps each wide column to its unit, ``attrs["hgo_mj"]`` is
    the schema metadata.

    Parameters
    ----------
    traj : Trajectory
        A run of :func:`hgo_mj.simulate.simulate` (``traj.to_pandas(form)`` calls this).
    form : {"wide", "long"}
        Wide: one row per sample, ``T`` rows; long: one row per sample and wide column
        (``t`` excepted), columns ``t``, ``source``, ``name``, ``value``, ``unit``.

    Returns
    -------
    pandas.DataFrame
        The table; ``attrs["units"]`` is ``{wide column: unit or None}``, ``attrs["hgo_mj"]``
        the strict-JSON schema metadata (form, units, time unit, names, run metadata).

    Raises
    ------
    DesignError
        ``form`` is not ``"wide"`` or ``"long"``; an observer's name would collide with the
        reserved column sources or contains ``/``.

    Examples
    --------
    >>> from hgo_mj.inputs import Constant
    >>> from hgo_mj.observers import make_observer
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.simulate import simulate
    >>> plant = make_plant("pendulum", 0.01)
    >>> traj = simulate(plant, None, {"hgo": make_observer("high_gain", plant.system, k=20.0)},
    ...                 Constant(0.0), duration=0.05)
    >>> df = to_pandas(traj)
    >>> df.shape, list(df.columns[-3:])
    ((6, 10), ['measured/angle', 'clean/angle', 'input/torque'])
    >>> long = to_pandas(traj, "long")
    >>> len(long) == 6 * 9, long.loc[0, ["source", "name", "unit"]].tolist()
    (True, ['true', 'angle', 'rad'])
    """
    import pandas as pd

    form = _check_form(form)
    cols, units = wide_columns(traj)
    if form == "wide":
        df = pd.DataFrame(cols)
    else:
        names = [c for c in cols if c != "t"]
        T = len(cols["t"])
        split = [c.rsplit("/", 1) for c in names]
        df = pd.DataFrame({
            "t": np.tile(cols["t"], len(names)),
            "source": np.repeat([s for s, _ in split], T),
            "name": np.repeat([n for _, n in split], T),
            "value": np.concatenate([cols[c] for c in names]) if names else np.array([]),
            "unit": np.repeat(np.array([units[c] for c in names], dtype=object), T)})
    df.attrs["units"] = units
    df.attrs["hgo_mj"] = schema_metadata(traj, form, units)
    return df


def to_arrow(traj: Any, form: str = "wide") -> Any:
    """The trajectory as a :class:`pyarrow.Table` in the wide or long form; in the wide form
    every field with a known unit carries it in its metadata (``field.metadata[b"unit"]``),
    and the schema metadata ``b"hgo_mj"`` holds ``schema_metadata`` as JSON.

    Parameters
    ----------
    traj : Trajectory
        A run of :func:`hgo_mj.simulate.simulate` (``traj.to_arrow(form)`` calls this).
    form : {"wide", "long"}
        The table's form (see :func:`to_pandas`).

    Returns
    -------
    pyarrow.Table
        float64 columns (``source``, ``name`` and ``unit`` of the long form are strings).

    Raises
    ------
    DesignError
        As :func:`to_pandas`: an unknown ``form`` or an observer name unfit for a column.

    Examples
    --------
    >>> from hgo_mj.inputs import Constant
    >>> from hgo_mj.observers import make_observer
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.simulate import simulate
    >>> plant = make_plant("pendulum", 0.01)
    >>> traj = simulate(plant, None, {"hgo": make_observer("high_gain", plant.system, k=20.0)},
    ...                 Constant(0.0), duration=0.05)
    >>> table = to_arrow(traj)
    >>> table.num_rows, table.schema.field("true/angular_velocity").metadata
    (6, {b'unit': b'rad/s'})
    >>> import json
    >>> json.loads(table.schema.metadata[b"hgo_mj"])["time_unit"]
    's'
    """
    import pyarrow as pa
    from pandas.api.types import is_numeric_dtype

    df = to_pandas(traj, form)
    units = df.attrs["units"]
    fields = []
    for c in df.columns:
        typ = pa.float64() if is_numeric_dtype(df[c]) else pa.string()
        meta = ({"unit": units[c]} if form == "wide" and units.get(c) is not None else None)
        fields.append(pa.field(c, typ, metadata=meta))
    meta = {"hgo_mj": json.dumps(df.attrs["hgo_mj"], allow_nan=False)}
    return pa.Table.from_pandas(df, schema=pa.schema(fields, metadata=meta), preserve_index=False)


def write_table(traj: Any, path: str | Path, fmt: str = "parquet", form: str = "wide") -> Path:
    """Write the trajectory's table to ``path`` atomically: ``fmt`` ``"parquet"`` (units and
    metadata in the schema) or ``"csv"`` (the columns only; the units in a ``# units:`` line
    would break plain readers, so a CSV carries none: read them from the Parquet file or
    :attr:`~hgo_mj.systems.base.System.state_units`).

    Parameters
    ----------
    traj : Trajectory
        A run of :func:`hgo_mj.simulate.simulate`.
    path : str or Path
        The file to write (its folder is created; replaced whole, never left half-written).
    fmt : {"parquet", "csv"}
        The file format (:data:`FILE_FORMATS`).
    form : {"wide", "long"}
        The table's form (see :func:`to_pandas`).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    DesignError
        ``fmt`` is not ``"parquet"`` or ``"csv"``; or, from :func:`to_pandas`, an unknown
        ``form`` or an observer name unfit for a column.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import pandas as pd
    >>> from hgo_mj.inputs import Constant
    >>> from hgo_mj.observers import make_observer
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.simulate import simulate
    >>> plant = make_plant("pendulum", 0.01)
    >>> traj = simulate(plant, None, {"hgo": make_observer("high_gain", plant.system, k=20.0)},
    ...                 Constant(0.0), duration=0.05)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = write_table(traj, Path(tmp) / "run.parquet")
    ...     df = pd.read_parquet(path)
    ...     units = read_units(path)
    ...     csv = write_table(traj, Path(tmp) / "run.csv", fmt="csv").read_text()
    >>> path.name, df.shape, units["hgo/angle"]
    ('run.parquet', (6, 10), 'rad')
    >>> csv.splitlines()[0].split(",")[:3]
    ['t', 'true/angle', 'true/angular_velocity']
    """
    if fmt not in FILE_FORMATS:
        raise DesignError(f"table format must be one of {list(FILE_FORMATS)}; found {fmt!r}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if fmt == "csv":
        return write_text(path, to_pandas(traj, form).to_csv(index=False))
    import pyarrow.parquet as pq

    table = to_arrow(traj, form)
    with atomic_path(path) as tmp:
        pq.write_table(table, str(tmp))
    return path


def read_units(path: str | Path) -> dict[str, str | None]:
    """The units a Parquet file written by :func:`write_table` declares, ``{column: unit}``.

    Parameters
    ----------
    path : str or Path
        A Parquet file written by :func:`write_table` (or :meth:`Trajectory.to_arrow` with
        :func:`pyarrow.parquet.write_table`).

    Returns
    -------
    dict of str to (str or None)
        Each wide column's unit (``""`` dimensionless, ``None`` unknown; the wide columns'
        units for a long-form file too).

    Raises
    ------
    DesignError
        The file's key-value metadata has no ``hgo_mj`` entry (not written by this package).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from hgo_mj.inputs import Constant
    >>> from hgo_mj.observers import make_observer
    >>> from hgo_mj.plants import make_plant
    >>> from hgo_mj.simulate import simulate
    >>> plant = make_plant("pendulum", 0.01)
    >>> traj = simulate(plant, None, {"hgo": make_observer("high_gain", plant.system, k=20.0)},
    ...                 Constant(0.0), duration=0.05)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     units = read_units(write_table(traj, Path(tmp) / "run.parquet"))
    >>> units["t"], units["true/angle"], units["input/torque"]
    ('s', 'rad', 'N m')
    """
    import pyarrow.parquet as pq

    # the file's key-value metadata: a streamed file (hgo_mj.stream) has it there only, one
    # written whole also in the Arrow schema
    meta = pq.read_metadata(str(path)).metadata or {}
    if b"hgo_mj" not in meta:
        raise DesignError(f"{str(path)!r} is no hgo_mj table: its metadata has no 'hgo_mj' "
                          f"entry")
    return dict(json.loads(meta[b"hgo_mj"])["units"])


__all__ = ["FILE_FORMATS", "FORMS", "RESERVED", "arrow_array", "float_column", "read_units",
           "to_arrow", "to_pandas", "write_rows_parquet", "write_table"]
