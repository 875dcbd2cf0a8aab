"""Paper reproductions: ``hgo-mj reproduce NAME --out DIR``.

Each reproduction is a module ``hgo_mj.reproduce.<name>`` with a function
``run(out: pathlib.Path, *, rrd: pathlib.Path | None = None, quiet: bool = False) -> dict``
that writes ``out/summary.json``, PNG figures and ``out/report.txt`` and returns the summary,
showing its progress on stderr unless ``quiet`` (:class:`hgo_mj.progress.Progress`, a step per
part or run); ``hgo-mj reproduce`` prints ``report.txt``. Its test asserts the summary's
numbers against the paper within stated tolerances.

Recording (``hgo-mj reproduce NAME --rrd FILE.rrd``): the command passes ``rrd=Path`` only
when asked, and refuses a reproduction whose ``run`` has no ``rrd``
parameter. With ``rrd`` given, ``run`` writes its main simulation(s) to that one file and
leaves it closed, e.g. ``hgo_mj.record.record_trajectory(traj, rrd)`` for one trajectory, or
for several runs ``with Recorder.for_trajectory(rrd, traj_a) as rec:
rec.record_trajectory(traj_a)`` (runs with the same names can share a recorder; otherwise use
one file per run, ``rrd.with_name(f"{rrd.stem}_{case}.rrd")``, and list them in the report).
With ``rrd=None`` it writes no recording.

``summary.json`` is strict JSON (RFC 8259: ``jq`` and every parser read it): each reproduction
ends its ``run`` with :func:`finish` (the package versions into the summary, then
``summary.json`` and ``report.txt``; :func:`record_runs` writes the recordings), which writes
the file with :func:`write_summary`, which maps a non-finite float to ``null`` -- ``inf`` is
a time that never came (a level never reached and held to the end of the run, or a divergent
run) and ``nan`` a number that is undefined -- and ``run`` returns that same JSON-ready
summary. The report prints such a number as "never" / "undefined" (:func:`fmt_num`) and lists
the keys written as ``null`` (:func:`null_note`).
"""

from __future__ import annotations

import importlib
import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .._io import write_text
from .._json import write_json
from ..exceptions import DesignError

#: the papers hgo_mj implements, cited as "paper NNN" by the plants, observers and
#: reproductions (``hgo-mj list`` prints them): number -> authors (year), title, venue
PAPERS: dict[str, str] = {
    "000": "E. Bullinger, A. Ilchmann, F. Allgöwer (1998), A simple adaptive observer for "
           "nonlinear systems, 4th IFAC Symposium on Nonlinear Control Systems Design "
           "(NOLCOS '98), Enschede, vol. 2, pp. 781-786",
    "001": "G. Besançon, Q. Zhang, H. Hammouri (2004), High-gain observer based state and "
           "parameter estimation in nonlinear systems, IFAC Symposium on Nonlinear Control "
           "Systems (NOLCOS 2004)",
    "002": "G. Bastin, M. Gevers (1988), Stable adaptive observers for nonlinear time-varying "
           "systems, IEEE Transactions on Automatic Control 33(7) (presented at Lund, 1986)",
    "003": "N.-H. Jo, Y.-I. Son (2004), Adaptive observer design for nonlinear systems using "
           "generalized nonlinear observer canonical form, KSME International Journal 18(7)",
    "004": "S. Ibrir (2007), On observer design for nonlinear systems, International Journal "
           "of Control",
}

#: name -> (module, one line)
REPRODUCTIONS: dict[str, tuple[str, str]] = {
    "bullinger1998": ("hgo_mj.reproduce.bullinger1998",
                      "paper 000 sec. 4: adaptive-gain HGO on the bioreactor, 80 h, noisy"),
    "ibrir2007": ("hgo_mj.reproduce.ibrir2007",
                  "paper 004 sec. 4: Riccati and q-integral observers, LMI sampling bounds"),
    "besancon2004": ("hgo_mj.reproduce.besancon2004",
                     "paper 001 sec. 4: adaptive high-gain observer, examples 1 and 2"),
    "bastin_gevers1986": ("hgo_mj.reproduce.bastin_gevers1986",
                          "paper 002 sec. 6: adaptive observer on the bioreactor"),
    "jo_son2004": ("hgo_mj.reproduce.jo_son2004",
                   "paper 003 eq. 28-31: adaptive observer in generalized canonical form"),
}


def nonfinite_keys(value: Any, prefix: str = "") -> list[tuple[str, str]]:
    """``(key path, "never" | "undefined")`` for each non-finite float in ``value`` (``inf``:
    never, ``nan``: undefined); list items as ``key[i]``."""
    found: list[tuple[str, str]] = []
    if isinstance(value, dict):
        for k, v in value.items():
            found += nonfinite_keys(v, f"{prefix}.{k}" if prefix else str(k))
    elif isinstance(value, (list, tuple, np.ndarray)):
        for i, v in enumerate(value):
            found += nonfinite_keys(v, f"{prefix}[{i}]")
    elif isinstance(value, (float, np.floating)) and not math.isfinite(value):
        found.append((prefix, "undefined" if math.isnan(value) else "never"))
    return found


def fmt_num(value: Any, spec: str = ".3g") -> str:
    """``format(value, spec)``, but ``inf`` (or ``None``, as read back from ``summary.json``)
    as "never" and ``nan`` as "undefined"."""
    if value is None:
        return "never"
    v = float(value)
    if math.isnan(v):
        return "undefined"
    if math.isinf(v):
        return "never"
    return format(v, spec)


def null_note(summary: dict[str, Any], limit: int = 12) -> str:
    """One line for the report naming the keys ``summary.json`` writes as ``null``; empty if
    none."""
    keys = nonfinite_keys(summary)
    if not keys:
        return ""
    shown = ", ".join(f"{k} = {what}" for k, what in keys[:limit])
    more = f" and {len(keys) - limit} more" if len(keys) > limit else ""
    return (f"summary.json writes non-finite numbers as null (never: a time not reached by the end "
            f"of the run, or a divergent run; undefined: no value): {shown}{more}.")


def write_summary(out: str | Path, summary: dict[str, Any]) -> dict[str, Any]:
    """Write ``out/summary.json`` as strict JSON (:func:`hgo_mj._json.write_json`) and return
    what was written (the parsed form of the file)."""
    return write_json(Path(out, "summary.json"), summary)


def finish(out: str | Path, summary: dict[str, Any], report: str) -> dict[str, Any]:
    """The common end of a reproduction's ``run``: add the package versions to ``summary``
    (``summary["versions"]``), write ``out/summary.json`` (:func:`write_summary`) and
    ``out/report.txt`` (``report`` and, after a blank line, :func:`null_note`'s line when there
    are non-finite numbers), and return the JSON-ready summary."""
    from ..simulate import package_versions

    summary["versions"] = package_versions()
    note = null_note(summary)
    data = write_summary(out, summary)
    text = report.rstrip("\n") + "\n"
    write_text(Path(out, "report.txt"), text + (f"\n{note}\n" if note else ""))
    return data


def record_runs(rrd: str | Path, runs: Mapping[str, Any],
                names: Mapping[str, str] | None = None) -> list[str]:
    """Record each trajectory of ``runs`` (``suffix -> trajectory``) with
    :func:`hgo_mj.record.record_trajectory`: suffix ``""`` to ``rrd`` itself, any other to
    ``<stem>_<suffix>.rrd`` next to it (``names``: an optional recording name per suffix).
    Returns the paths written, in order, as strings (for ``summary["recordings"]``)."""
    from ..record import record_trajectory

    rrd = Path(rrd)
    paths = []
    for suffix, traj in runs.items():
        path = rrd if not suffix else rrd.with_name(f"{rrd.stem}_{suffix}.rrd")
        if names and suffix in names:
            record_trajectory(traj, path, recording_name=names[suffix])
        else:
            record_trajectory(traj, path)
        paths.append(str(path))
    return paths


def _reject_constant(name: str) -> Any:
    raise ValueError(f"summary.json is not strict JSON: it holds {name}")


def read_summary(out: str | Path) -> dict[str, Any]:
    """Read ``out/summary.json`` as strict JSON: ``NaN``/``Infinity`` (which Python's ``json``
    accepts by default, ``jq`` does not) raise ``ValueError``.

    Parameters
    ----------
    out : str or Path
        A reproduction's output folder.

    Returns
    -------
    dict

    Examples
    --------
    >>> import json, tempfile
    >>> with tempfile.TemporaryDirectory() as d:
    ...     _ = Path(d, "summary.json").write_text(json.dumps({"k_final": 0.27}))
    ...     read_summary(d)
    {'k_final': 0.27}
    """
    return json.loads(Path(out, "summary.json").read_text(), parse_constant=_reject_constant)


def run_reproduction(name: str, out: str | Path, **kw: Any) -> dict[str, Any]:
    """Run a registered reproduction; unknown names list the valid ones.

    Parameters
    ----------
    name : str
        A key of :data:`REPRODUCTIONS`.
    out : str or Path
        Output folder (created).
    **kw
        The reproduction's own options (``rrd``, ``quiet``, ...; see its ``run``).

    Returns
    -------
    dict
        Its summary (also ``out/summary.json``).

    Raises
    ------
    DesignError
        ``name`` is not a registered reproduction.

    Examples
    --------
    >>> sorted(REPRODUCTIONS)[:2]
    ['bastin_gevers1986', 'besancon2004']
    >>> run_reproduction("nope", "runs/x")
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: unknown reproduction 'nope'; valid: [...]
    """
    if name not in REPRODUCTIONS:
        raise DesignError(f"unknown reproduction {name!r}; valid: {sorted(REPRODUCTIONS)}")
    module = importlib.import_module(REPRODUCTIONS[name][0])
    return module.run(Path(out), **kw)  # each run creates out, after checking what it needs


__all__ = ["PAPERS", "REPRODUCTIONS", "read_summary", "run_reproduction"]
