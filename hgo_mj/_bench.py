"""Shared pieces of the benchmark and study scripts in ``scripts/``: the lines that say where
and with what a figure was measured, and the one way they write into ``BENCHMARKS.md``.

Each script owns one block of that file, between ``<!-- {name}: begin -->`` and
``<!-- {name}: end -->``; :func:`write_section` replaces what lies between the two markers (or
appends the block, markers included, when they are missing), so a rerun never touches the
hand-written notes outside the markers nor another script's block. (Here, inside the package,
because the tests load the scripts by file path, where ``scripts/`` is not importable.)"""

from __future__ import annotations

import os
import platform
from collections.abc import Iterable
from importlib import metadata as importlib_metadata
from pathlib import Path

from hgo_mj._io import write_text
from hgo_mj.simulate import package_versions


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return os.cpu_count() or 0


def machine_line() -> str:
    """``Machine: x86_64, 2 cores, Linux-...`` (the cores this process may run on)."""
    return f"Machine: {platform.machine()}, {_cores()} cores, {platform.platform()}"


def versions(extra: Iterable[str] = ()) -> dict[str, str]:
    """:func:`~hgo_mj.simulate.package_versions` and the named ``extra`` distributions
    (``"not installed"`` where missing)."""
    out = package_versions()
    for pkg in extra:
        try:
            out[pkg] = importlib_metadata.version(pkg)
        except importlib_metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


def versions_line(extra: Iterable[str] = ()) -> str:
    """``Versions: python 3.11.7, hgo_mj 0.1.0, ...`` (with the named ``extra`` packages)."""
    return "Versions: " + ", ".join(f"{k} {v}" for k, v in versions(extra).items())


def header(command: str, extra: Iterable[str] = ()) -> list[str]:
    """The three lines that open a result: ``Command: {command}``, :func:`machine_line` and
    :func:`versions_line` (``extra`` as there)."""
    return [f"Command: {command}", machine_line(), versions_line(extra)]


def markers(name: str) -> tuple[str, str]:
    """The begin and end markers of block ``name``."""
    return f"<!-- {name}: begin -->", f"<!-- {name}: end -->"


def write_section(path: str | Path, name: str, text: str) -> None:
    """Put ``text`` between the markers of block ``name`` in ``path``, replacing what was
    there; where the markers are missing (or the file is), append the block with them."""
    path = Path(path)
    begin, end = markers(name)
    old = path.read_text() if path.exists() else ""
    body = text.strip("\n")
    i = old.find(begin)
    j = old.find(end, i + len(begin)) if i >= 0 else -1
    if i >= 0 and j >= 0:
        new = old[:i] + begin + "\n" + body + "\n" + old[j:]
    else:
        new = (old.rstrip("\n") + "\n\n" if old.strip() else "") + f"{begin}\n{body}\n{end}\n"
    write_text(path, new)
