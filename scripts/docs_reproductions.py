"""Write the documentation's paper-reproduction pages from the reproductions' own output.

Usage::

    python scripts/docs_reproductions.py                 # every reproduction (a few minutes)
    python scripts/docs_reproductions.py jo_son2004      # only the ones named

For each reproduction of :data:`hgo_mj.reproduce.REPRODUCTIONS` it runs
``hgo_mj.reproduce.run_reproduction(name, tmp, quiet=True)``, copies its ``report.txt`` and
figures (``*.png``) to ``docs/reproductions/<name>/`` and writes ``docs/reproductions/<name>.rst``:
the module's docstring (what the paper claims, the setup, the corrections and misprints,
through ``automodule``), the report (what hgo_mj finds, as printed by ``hgo-mj reproduce``)
and every figure. ``make docs`` builds the pages from these committed files and runs no
reproduction; rerun this script when a reproduction changes.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # tiny matrices: threads only add contention

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

from hgo_mj._io import write_bytes, write_text
from hgo_mj.reproduce import REPRODUCTIONS, run_reproduction

DOCS = Path(__file__).resolve().parent.parent / "docs" / "reproductions"


def page(name: str, figures: list[str], seconds: float) -> str:
    """The reST page of reproduction ``name`` with its ``figures`` (file names)."""
    module, line = REPRODUCTIONS[name]
    title = f"{name}: {line}"
    parts = [
        f".. _reproduction-{name}:", "", title, "=" * len(title), "",
        f"Run it with ``hgo-mj reproduce {name} --out DIR`` (here {seconds:.0f} s on 2 cores); "
        f"the test ``tests/reproduce/`` asserts its numbers against the paper. This page is "
        f"written by ``scripts/docs_reproductions.py``.", "",
        "What the paper claims, the setup and the corrections", "-" * 52, "",
        f".. automodule:: {module}", "   :no-members:", "   :no-index:", "",
        "What hgo_mj finds", "-" * 17, "",
        f"The report ``hgo-mj reproduce {name}`` prints (``report.txt``):", "",
        f".. literalinclude:: {name}/report.txt", "   :language: text", "",
        "Figures", "-------", "",
    ]
    for fig in figures:
        parts += [f".. figure:: {name}/{fig}", "   :width: 100%", "", f"   ``{fig}``", ""]
    return "\n".join(parts)


def build(name: str) -> None:
    """Run reproduction ``name`` and write its page and files under :data:`DOCS`."""
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        run_reproduction(name, tmp, quiet=True)
        seconds = time.perf_counter() - start
        target = DOCS / name
        if target.exists():
            shutil.rmtree(target)
        target.mkdir(parents=True)
        figures = sorted(p.name for p in Path(tmp).glob("*.png"))
        for fig in figures:
            write_bytes(target / fig, Path(tmp, fig).read_bytes())
        write_text(target / "report.txt", Path(tmp, "report.txt").read_text())
    write_text(DOCS / f"{name}.rst", page(name, figures, seconds))
    print(f"{name}: {len(figures)} figures, {seconds:.0f} s", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("names", nargs="*", help=f"reproductions (default: all of {sorted(REPRODUCTIONS)})")
    args = parser.parse_args(argv)
    unknown = [n for n in args.names if n not in REPRODUCTIONS]
    if unknown:
        parser.error(f"unknown reproduction(s) {unknown}; valid: {sorted(REPRODUCTIONS)}")
    for name in args.names or sorted(REPRODUCTIONS):
        build(name)
    return 0


if __name__ == "__main__":
    sys.exit(main())
