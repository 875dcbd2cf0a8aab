"""Atomic file writes: every file hgo_mj writes goes to a temporary file in the same folder
and is renamed into place, so a kill at any moment leaves either the old file or the new
one, never a torn one (``os.replace`` is atomic on POSIX and Windows within one folder)."""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary path beside ``path`` to write to; renamed onto ``path`` when the block
    ends without an error, removed otherwise. The folder is created if missing."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temporary_beside(path)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def temporary_beside(path: Path) -> str:
    """A new empty file beside ``path`` (same folder, hidden name), with the permissions a
    plain ``open`` would give (``mkstemp``'s 0600 would follow it onto ``path``)."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.fchmod(fd, 0o666 & ~umask)
    finally:
        os.close(fd)
    return tmp


def stale_temporaries(path: str | Path) -> list[Path]:
    """The temporaries of ``path`` (:func:`temporary_beside`'s ``.NAME.XXXX.tmp``) that a
    killed write left beside it."""
    import glob

    path = Path(path)
    return sorted(path.parent.glob(f".{glob.escape(path.name)}.*.tmp"))


def check_writable(name: str, path: str | Path, *, folder: bool) -> Path:
    """Raise :class:`~hgo_mj.exceptions.DesignError` unless ``path`` can be written: a folder
    (``folder=True``) that exists or can be created, or a file that is not a folder and whose
    folder exists or can be created. Probed by creating (and removing) a temporary file in the
    nearest existing folder, so a read-only folder or file system is found before any work;
    nothing is left behind. ``name`` names the option (``--out``) in the message."""
    from .exceptions import DesignError

    path = Path(path)
    if folder and path.exists() and not path.is_dir():
        raise DesignError(f"{name} must be a folder; found the existing file {str(path)!r}")
    if not folder and path.is_dir():
        raise DesignError(f"{name} must be a file; found the existing folder {str(path)!r}")
    base = path if folder else path.parent
    probe = base.absolute()
    while not probe.exists():
        probe = probe.parent
    if not probe.is_dir():
        raise DesignError(f"{name} {str(path)!r} cannot be created: {str(probe)!r} is a file, "
                          f"not a folder")
    try:
        fd, tmp = tempfile.mkstemp(prefix=".hgo_mj_probe.", dir=probe)
    except OSError as exc:
        raise DesignError(f"{name} {str(path)!r} is not writable: cannot create a file in "
                          f"{str(probe)!r} ({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(tmp)
    return path


def _size(nbytes: float) -> str:
    """A size in MiB below one GiB, else in GiB."""
    return (f"{nbytes / 2**20:,.0f} MiB" if nbytes < 2**30 else f"{nbytes / 2**30:,.3g} GiB")


def check_disk(name: str, path: str | Path, nbytes: float) -> None:
    """Raise :class:`~hgo_mj.exceptions.DesignError` before a run whose files (an estimate of
    ``nbytes``) would not fit on the disk of ``path`` (its nearest existing folder); ``name``
    names the option in the message."""
    import shutil

    from .exceptions import DesignError

    probe = Path(path).absolute()
    while not probe.exists():
        probe = probe.parent
    free = shutil.disk_usage(probe).free
    if nbytes > free:
        raise DesignError(f"the run's files would take about {_size(nbytes)}; "
                          f"{name} {str(path)!r} has {_size(free)} free: free space, "
                          f"write elsewhere, shorten the run or keep every k-th row "
                          f"(--store-every k)")


def write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; returns ``path``."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; returns ``path``."""
    return write_bytes(path, text.encode("utf-8"))


#: points per piece in which Agg draws a long line (matplotlib's ``agg.path.chunksize``): a
#: streamed run's figure of 20,000 rows peaked 17 MB above its drawing in one piece, 6 MB in
#: pieces of 1,000 points. The price: a line drawn with alpha shows a one-pixel gap at a few
#: joins of pieces (3 % of a 120 s run's figure's pixels differ, none by a visible shape)
FIGURE_PATH_CHUNK = 1_000


def save_figure(fig: Any, path: str | Path, dpi: int = 110) -> Path:
    """Save a matplotlib figure atomically, in the format of ``path``'s suffix (PNG when it
    has none), its lines drawn in pieces of :data:`FIGURE_PATH_CHUNK` points, and close it if
    pyplot manages it; returns ``path``."""
    import matplotlib

    fmt = Path(path).suffix.lstrip(".") or "png"
    with atomic_path(path) as tmp, matplotlib.rc_context({"agg.path.chunksize":
                                                          FIGURE_PATH_CHUNK}):
        fig.savefig(tmp, format=fmt, dpi=dpi)
    if getattr(fig.canvas, "manager", None) is not None:  # pyplot's (plotting.new_figure):
        import matplotlib.pyplot as plt  # written, so released (no pile of open figures)

        plt.close(fig)
    return Path(path)
