"""The benchmark's quick suite, cold and warm, side by side (issues 26 and 28: at most 60 s
on 2 cores, tuning included, on its first run after install).

Usage: ``python scripts/bench_quick.py [--jobs J ...] [--budget N] [--write BENCHMARKS.md]
[--tasks T ...] [--observers O ...]``.

For each ``J`` (default 2, what ``make demo`` uses), ``hgo-mj bench --suite quick --budget N
--jobs J`` runs twice in a fresh process, with numba's cache in a new empty folder
(``NUMBA_CACHE_DIR``) and Python's bytecode in another (``PYTHONPYCACHEPREFIX``; written, also
where the environment sets ``PYTHONDONTWRITEBYTECODE``):

* **cold**: both caches empty, as after ``make demo``'s ``pip install --no-compile -e .`` in a
  fresh clone: every module the suite imports is compiled to bytecode and every kernel it runs
  by numba (both written to their cache);
* **warm**: the same command again: the bytecode and every kernel loaded from the caches.

Reported per run: the wall time, the CPU time of the command and its workers (user + sys),
the load average before and after (other work on the machine lengthens the wall time, not
the CPU time), and whether the cold and the warm run gave the same scores (every column of
``scores.parquet`` but the timings). ``--tasks``/``--observers`` run a part of the suite
instead (a smoke test).
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from hgo_mj._bench import header, write_section

#: the issue's target for the quick suite, tuning included, on 2 cores [s]
TARGET_S = 60.0
#: columns of scores.parquet that are timings (they differ between any two runs)
TIMING_COLUMNS = ("update_time", "tune_seconds")


def _hgo_mj() -> list[str]:
    exe = Path(sys.executable).with_name("hgo-mj")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "hgo_mj"]


def run_once(out: Path, cache: Path, jobs: int, budget: int, tasks: list[str],
             observers: list[str]) -> dict[str, float]:
    """One ``hgo-mj bench`` into ``out`` with numba's cache in ``cache/numba`` and the
    bytecode in ``cache/pycache``: ``wall``, ``cpu`` (user + sys of the command and its
    workers) [s], ``load_before``, ``load_after``."""
    cmd = [*_hgo_mj(), "bench", "--budget", str(budget), "--jobs", str(jobs), "--out", str(out),
           "--no-rrd", "--quiet"]
    cmd += ["--suite", "quick"] if not tasks else ["--suite", "none", "--tasks", *tasks]
    cmd += ["--observers", *observers] if observers else []
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env.update(NUMBA_CACHE_DIR=str(cache / "numba"), PYTHONPYCACHEPREFIX=str(cache / "pycache"),
               OPENBLAS_NUM_THREADS="1")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, check=True, timeout=3600, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall": wall, "cpu": cpu, "load_before": load0, "load_after": os.getloadavg()[0]}


def same_scores(a: Path, b: Path) -> bool:
    """Whether two runs' ``scores.parquet`` agree in every column but the timings."""
    import pandas as pd

    fa, fb = (pd.read_parquet(p / "scores.parquet") for p in (a, b))
    keep = [c for c in fa.columns if c not in TIMING_COLUMNS]
    return list(fa.columns) == list(fb.columns) and fa[keep].equals(fb[keep])


def measure(jobs: list[int], budget: int, tasks: list[str] = (),  # type: ignore[assignment]
            observers: list[str] = ()) -> list[dict]:  # type: ignore[assignment]
    """Per ``J`` in ``jobs``: ``jobs``, ``cold`` and ``warm`` (:func:`run_once`), ``same``
    (:func:`same_scores`)."""
    rows = []
    for j in jobs:
        with tempfile.TemporaryDirectory(prefix="bench_quick_") as tmp:
            root = Path(tmp)
            cold = run_once(root / "cold", root / "cache", j, budget, list(tasks), list(observers))
            warm = run_once(root / "warm", root / "cache", j, budget, list(tasks), list(observers))
            rows.append({"jobs": j, "cold": cold, "warm": warm,
                         "same": same_scores(root / "cold", root / "warm")})
    return rows


def report(rows: list[dict], command: str, budget: int) -> str:
    lines = ["## Issues 26 and 28: the quick suite, cold and warm (`scripts/bench_quick.py`)", "",
             *header(command),
             f"`hgo-mj bench --suite quick --budget {budget} --jobs J --no-rrd --quiet`, each "
             "run in a fresh process; cold: numba's cache and the bytecode cache empty (a fresh "
             "clone after `pip install --no-compile -e .`, as `make demo` installs), warm: the "
             "same command again (the bytecode and every kernel from the caches). CPU: user + "
             "sys of the command and its workers.", "",
             "| J (processes) | cold wall [s] | cold CPU [s] | warm wall [s] | warm CPU [s] | "
             "compile (cold - warm CPU) [s] | load before / after | scores cold = warm |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        c, w = r["cold"], r["warm"]
        lines.append(f"| {r['jobs']} | {c['wall']:.1f} | {c['cpu']:.1f} | {w['wall']:.1f} | "
                     f"{w['cpu']:.1f} | {c['cpu'] - w['cpu']:.1f} | {c['load_before']:.2f} / "
                     f"{w['load_after']:.2f} | {'yes' if r['same'] else 'NO'} |")
    best = min(r["cold"]["wall"] for r in rows)
    lines += ["", f"Cold, the demo's case: **{best:.1f} s** wall at best (target <= {TARGET_S:.0f} "
              f"s on 2 cores: {'meets' if best <= TARGET_S else 'misses'} it on this machine, at "
              "the load shown)."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, nargs="+", default=[2])
    ap.add_argument("--budget", type=int, default=8)
    ap.add_argument("--tasks", nargs="*", default=[])
    ap.add_argument("--observers", nargs="*", default=[])
    ap.add_argument("--write", metavar="FILE", help="replace this script's block in FILE")
    args = ap.parse_args(argv)
    if min(args.jobs) < 1 or args.budget < 2:
        print(f"bench_quick: --jobs must be >= 1 and --budget >= 2; found {args.jobs} and "
              f"{args.budget}", file=sys.stderr)
        return 2
    rows = measure(args.jobs, args.budget, args.tasks, args.observers)
    text = report(rows, "python scripts/bench_quick.py " + " ".join(argv or sys.argv[1:]),
                  args.budget)
    print(text)
    if args.write:
        write_section(args.write, "bench_quick", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
