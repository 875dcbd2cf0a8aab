"""Reading a trajectory file (``Trajectory.save``'s ``.npz``) that may be damaged or crafted.

:func:`read` returns its columns and its checked JSON metadata, or raises
:class:`~hgo_mj.exceptions.TrajectoryFileError` naming the file and what is wrong: not a zip
of ``.npy`` columns, a pickle (refused), a column that declares more data than the file holds
or more than this machine's memory, a column that is not numeric, metadata that is not the
JSON ``save`` writes (names that are not distinct strings, an observer without its columns).
Nothing of the file is evaluated.
"""

from __future__ import annotations

import json
import math
import os
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from .exceptions import TrajectoryFileError

#: the plant's columns every file has
COLUMNS = ("t", "x", "y_clean", "y_meas", "u")
#: the longest metadata read (characters): far beyond any run's (names, scenario, versions)
MAX_META_CHARS = 50_000_000


def _memory() -> int | None:
    """This machine's physical memory in bytes, None where unknown."""
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, OSError, ValueError):
        return None


def _check_members(zf: zipfile.ZipFile) -> None:
    """Every member is an ``.npy`` array of plain numbers or text whose header declares no more
    data than the member holds, and all of them together fit in memory (before any is read:
    a crafted header or a zip bomb asks for more than exists)."""
    total = 0
    for info in zf.infolist():
        with zf.open(info) as fh:
            version = np.lib.format.read_magic(fh)
            if version == (1, 0):
                shape, _, dtype = np.lib.format.read_array_header_1_0(fh)
            elif version == (2, 0):
                shape, _, dtype = np.lib.format.read_array_header_2_0(fh)
            else:
                raise TrajectoryFileError(f"column {info.filename!r} is in .npy format "
                                          f"{version}, which Trajectory.save does not write")
        if dtype.hasobject or dtype.kind not in "biufU":
            raise TrajectoryFileError(f"column {info.filename!r} holds {dtype} values (pickled "
                                      f"objects are refused; a trajectory holds numbers)")
        need = math.prod(shape) * dtype.itemsize
        if need > info.file_size:
            raise TrajectoryFileError(f"column {info.filename!r} declares shape {shape} of "
                                      f"{dtype} ({need} bytes) but holds {info.file_size}")
        total += info.file_size
    memory = _memory()
    if memory is not None and total > memory:
        raise TrajectoryFileError(f"its columns take {total / 2**30:.3g} GiB, more than this "
                                  f"machine's memory ({memory / 2**30:.3g} GiB)")


def _names(meta: dict[str, Any], key: str, where: str = "") -> tuple[str, ...]:
    """``meta[key]``: distinct strings."""
    names = meta.get(key)
    if not isinstance(names, list) or not all(isinstance(s, str) for s in names):
        raise TrajectoryFileError(f"{where}{key} must be a list of strings; found "
                                  f"{_short(names)}")
    if len(set(names)) != len(names):
        dup = sorted({s for s in names if names.count(s) > 1})
        raise TrajectoryFileError(f"{where}{key} must be distinct; {dup} appear more than once")
    return tuple(names)


def _short(value: Any, most: int = 80) -> str:
    text = repr(value)
    return text if len(text) <= most else text[:most] + f"... ({len(text)} characters)"


def _meta(z: Any) -> dict[str, Any]:
    """The file's ``__meta__``: one JSON object with the names, the observers and the
    metadata, each of the type ``save`` writes."""
    if "__meta__" not in z.files:
        raise TrajectoryFileError("no __meta__ column: not written by Trajectory.save")
    raw = z["__meta__"]
    if raw.dtype.kind != "U" or raw.ndim != 0 or raw.dtype.itemsize // 4 > MAX_META_CHARS:
        raise TrajectoryFileError(f"__meta__ must be one JSON string; found a {raw.dtype} "
                                  f"array of shape {raw.shape}")
    try:
        meta = json.loads(str(raw))
    except json.JSONDecodeError as exc:
        raise TrajectoryFileError(f"__meta__ is not JSON: {exc}") from None
    except RecursionError:
        raise TrajectoryFileError("__meta__ is JSON nested too deeply to read") from None
    if not isinstance(meta, dict):
        raise TrajectoryFileError(f"__meta__ must be a JSON object; found {_short(meta)}")
    for key in ("state_names", "output_names", "input_names"):
        meta[key] = _names(meta, key)
    if not isinstance(meta.get("observers"), dict):
        raise TrajectoryFileError(f"__meta__: observers must be an object (name -> columns); "
                                  f"found {_short(meta.get('observers'))}")
    if not isinstance(meta.get("metadata", {}), dict):
        raise TrajectoryFileError(f"__meta__: metadata must be an object; found "
                                  f"{_short(meta.get('metadata'))}")
    for name, om in meta["observers"].items():
        _observer_meta(name, om)
    return meta


def _observer_meta(name: str, om: Any) -> None:
    """One observer's entry: its diagnostics' names, its update time, its state names."""
    where = f"__meta__: observer {name!r}: "
    if not isinstance(om, dict):
        raise TrajectoryFileError(f"{where}must be an object; found {_short(om)}")
    om["diagnostics"] = _names(om, "diagnostics", where)
    om.setdefault("state_names", [])
    om["state_names"] = _names(om, "state_names", where)
    ut = om.get("update_time")
    if ut is not None and (isinstance(ut, bool) or not isinstance(ut, (int, float))):
        raise TrajectoryFileError(f"{where}update_time must be a number; found {_short(ut)}")


def _column(z: Any, key: str) -> Any:
    """The numeric column ``key`` (at least 1-D: one entry per row)."""
    if key not in z.files:
        raise TrajectoryFileError(f"no column {key!r}")
    value = z[key]
    if value.dtype.kind not in "biuf" or value.ndim == 0:
        raise TrajectoryFileError(f"column {key!r} must be an array of numbers with one row "
                                  f"per time; found {value.dtype} of shape {value.shape}")
    return value


def _widths(cols: dict[str, Any], meta: dict[str, Any]) -> None:
    """``x``, ``y_*`` and ``u`` have one column per name."""
    for key, names in (("x", "state_names"), ("y_clean", "output_names"),
                       ("y_meas", "output_names"), ("u", "input_names")):
        v = cols[key]
        width = v.shape[1] if v.ndim == 2 else None
        if width != len(meta[names]):
            raise TrajectoryFileError(f"column {key!r} must have shape (rows, "
                                      f"{len(meta[names])}), one column per name in {names}; "
                                      f"found {v.shape}")


def read(path: str | Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """The plant's columns, each observer's columns and the checked metadata of the file.

    Parameters
    ----------
    path : str or Path
        A ``.npz`` written by ``Trajectory.save``.

    Returns
    -------
    tuple of dict
        ``cols`` (``"t"``, ``"x"``, ... and ``"obs/<name>/..."`` arrays) and ``meta`` (the
        names, ``"observers"`` and ``"metadata"``).

    Raises
    ------
    TrajectoryFileError
        The file is not one ``save`` writes (named, with what is wrong).
    OSError
        The file cannot be opened (missing, not readable).
    """
    path = Path(path)
    with open(path, "rb") as fh:  # a missing or unreadable file stays an OSError
        try:
            return _read(fh)
        except TrajectoryFileError as exc:
            raise TrajectoryFileError(f"{path}: {exc}") from None
        except (ValueError, KeyError, TypeError, EOFError, OSError, RecursionError,
                MemoryError, zipfile.BadZipFile, zlib.error, NotImplementedError) as exc:
            raise TrajectoryFileError(f"{path}: not a trajectory written by Trajectory.save "
                                      f"({type(exc).__name__}: {_short(str(exc), 200)})"
                                      ) from None


def _read(fh: Any) -> tuple[dict[str, Any], dict[str, Any]]:
    if fh.read(4) != b"PK\x03\x04":
        raise TrajectoryFileError("not an .npz archive (a zip of .npy columns); pickles and "
                                  "other formats are refused")
    fh.seek(0)
    with np.load(fh, allow_pickle=False) as z:
        _check_members(z.zip)
        meta = _meta(z)
        cols = {key: _column(z, key) for key in COLUMNS}
        _widths(cols, meta)
        for name, om in meta["observers"].items():
            for part in ("x_hat", "z_hat", *(f"diag/{d}" for d in om["diagnostics"])):
                cols[f"obs/{name}/{part}"] = _column(z, f"obs/{name}/{part}")
    return cols, meta


__all__: list[str] = []
