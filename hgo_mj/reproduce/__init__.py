"""Paper reproductions: ``hgo-mj reproduce NAME --out DIR``.

Each reproduction is a module ``hgo_mj.reproduce.<name>`` with a function
``run(out: pathlib.Path, *, rrd: pathlib.Path | None = None) -> dict`` that writes
``out/summary.json``, PNG figures and ``out/report.txt`` and returns the summary. Its test
asserts the summary's numbers against the paper within stated tolerances.

Recording (``hgo-mj reproduce NAME --rrd [FILE]``): the command passes ``rrd=Path`` (default
``OUT/NAME.rrd``) only when asked, and refuses a reproduction whose ``run`` has no ``rrd``
parameter. With ``rrd`` given, ``run`` writes its main simulation(s) to that one file and
leaves it closed, e.g. ``hgo_mj.record.record_trajectory(traj, rrd)`` for one trajectory, or
for several runs ``with Recorder.for_trajectory(rrd, traj_a) as rec:
rec.record_trajectory(traj_a)`` (runs with the same names can share a recorder; otherwise use
one file per run, ``rrd.with_name(f"{rrd.stem}_{case}.rrd")``, and list them in the report).
With ``rrd=None`` it writes no recording.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

from ..exceptions import DesignError

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


def run_reproduction(name: str, out: str | Path, **kw: Any) -> dict[str, Any]:
    """Run a registered reproduction; unknown names list the valid ones."""
    if name not in REPRODUCTIONS:
        raise DesignError(f"unknown reproduction {name!r}; valid: {sorted(REPRODUCTIONS)}")
    module = importlib.import_module(REPRODUCTIONS[name][0])
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    return module.run(out, **kw)
