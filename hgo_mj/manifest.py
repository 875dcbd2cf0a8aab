"""A folder's manifest: which files one run (or study) wrote, so that a folder whose files
come from two runs (a kill between two files) is found, not read as one.

A command that writes a folder first marks it as being written (:func:`begin`: a
``manifest.json`` with ``"complete": false``), writes its files, and writes the manifest last
(:func:`finish`): each file's SHA-256 and row count (the rows of a trajectory or table; null
for a JSON, text or figure). Both writes are atomic (:mod:`hgo_mj._io`). The readers
(:meth:`hgo_mj.simulate.Trajectory.load`, a study's results) call :func:`check` on what they
read: a folder whose manifest is not complete, or whose listed files are missing or differ from
the manifest, is refused with a :class:`~hgo_mj.exceptions.ManifestError` naming the folder, the
file and what differs. A file outside any manifest (``Trajectory.save`` to a folder of one's
own) is read as it is.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from ._io import write_text
from .exceptions import ManifestError

#: the manifest's file name in a folder
MANIFEST = "manifest.json"
#: the manifest's format version
VERSION = 1


def begin(folder: str | Path) -> None:
    """Mark ``folder`` as being written (its earlier manifest replaced by an incomplete one):
    until :func:`finish`, its readers refuse it.

    Parameters
    ----------
    folder : str or Path
        The folder a run is about to write (created if missing).

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     begin(tmp)
    ...     check(Path(tmp) / "metrics.json")
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.ManifestError: ...did not finish...
    """
    folder = Path(folder)
    write_text(folder / MANIFEST, json.dumps({"version": VERSION, "complete": False,
                                              "files": {}}, indent=1) + "\n")


def finish(folder: str | Path, names: Iterable[str]) -> dict[str, Any]:
    """Write the manifest of ``folder`` naming ``names``, the files this run wrote.

    Parameters
    ----------
    folder : str or Path
        The folder written.
    names : iterable of str
        The files, as paths relative to ``folder`` (``results.parquet/part-1.parquet``).

    Returns
    -------
    dict
        The entries written: name -> ``{"sha256", "bytes", "rows"}`` (``rows``: a
        trajectory's or table's rows, None for another file).

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     _ = (Path(tmp) / "t.csv").write_text("t,x\\n0,1\\n1,2\\n")
    ...     entry = finish(tmp, ["t.csv"])["t.csv"]
    ...     names = listed(tmp)
    >>> entry["rows"], entry["bytes"], names
    (2, 12, ['t.csv'])
    """
    folder = Path(folder)
    files = {name: _entry(folder / name) for name in sorted(set(names))}
    write_text(folder / MANIFEST, json.dumps({"version": VERSION, "complete": True,
                                              "files": files}, indent=1) + "\n")
    return files


def listed(folder: str | Path) -> list[str]:
    """The files a complete manifest of ``folder`` names.

    Parameters
    ----------
    folder : str or Path
        A folder, with or without a manifest.

    Returns
    -------
    list of str
        The names (relative paths); empty without a manifest or with an incomplete one.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     listed(tmp)
    []
    """
    data = _read(Path(folder))
    return list(data["files"]) if data and data.get("complete") else []


def check(path: str | Path) -> None:
    """Raise :class:`~hgo_mj.exceptions.ManifestError` when ``path`` (a file or a folder of
    parts) lies in a folder whose manifest is incomplete (the run writing it did not finish),
    or is listed there while a listed file is missing or differs from its entry (the folder
    mixes two runs). Nothing is checked where there is no manifest.

    Parameters
    ----------
    path : str or Path
        The file (or folder of parts) about to be read.

    Raises
    ------
    ManifestError
        The folder's manifest is incomplete or malformed, or a file it lists is missing or
        differs from its entry (size or SHA-256), named with the folder.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     _ = (Path(tmp) / "a.txt").write_text("one")
    ...     _ = finish(tmp, ["a.txt"])
    ...     check(Path(tmp) / "a.txt")  # as written: passes
    ...     _ = (Path(tmp) / "a.txt").write_text("two")
    ...     check(Path(tmp) / "a.txt")
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.ManifestError: ...a.txt differs from the manifest ...
    """
    path = Path(path)
    folder = path.parent
    data = _read(folder)
    if data is None:
        return
    if not data.get("complete"):
        raise ManifestError(f"{folder}: the run that wrote this folder did not finish "
                            f"({MANIFEST} is incomplete): its files may come from two runs; "
                            f"run it again")
    files = data["files"]
    if not any(n == path.name or n.startswith(path.name + "/") for n in files):
        return
    for name, want in files.items():
        f = folder / name
        if not f.is_file():
            raise ManifestError(f"{folder}: {name} is listed in {MANIFEST} but missing: the "
                                f"folder is not the run that wrote it")
        if f.stat().st_size != want["bytes"] or _sha256(f) != want["sha256"]:
            raise ManifestError(f"{folder}: {name} differs from the manifest (it was written "
                                f"by another run, or changed since): the folder mixes two runs; "
                                f"run it again")


def _read(folder: Path) -> dict[str, Any] | None:
    path = folder / MANIFEST
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
        if not (isinstance(data, dict) and isinstance(data.get("files"), dict)
                and all(isinstance(v, dict) and {"sha256", "bytes"} <= set(v)
                        for v in data["files"].values())):
            raise ValueError("expected {'complete', 'files': {name: {'sha256', 'bytes', ...}}}")
    except (ValueError, UnicodeDecodeError) as exc:
        raise ManifestError(f"{path}: not a manifest hgo_mj wrote ({exc})") from None
    return data


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _entry(path: Path) -> dict[str, Any]:
    return {"sha256": _sha256(path), "bytes": path.stat().st_size, "rows": _rows(path)}


def _rows(path: Path) -> int | None:
    """The rows of a trajectory (``.npz``: its times) or a table (Parquet, CSV); None else."""
    if path.suffix == ".npz":
        import numpy as np

        with np.load(path, allow_pickle=False) as z:
            return int(z["t"].shape[0]) if "t" in z else None
    if path.suffix == ".parquet":
        import pyarrow.parquet as pq

        return int(pq.ParquetFile(path).metadata.num_rows)
    if path.suffix == ".csv":
        with open(path, "rb") as fh:
            return max(sum(1 for _ in fh) - 1, 0)
    return None


__all__ = ["MANIFEST", "begin", "check", "finish", "listed"]
