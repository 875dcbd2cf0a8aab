"""Import time of ``hgo_mj.simulate`` against ``import mujoco, numpy`` (issue 28, item 1:
target at most 1.5x), each in a fresh interpreter.

Usage: ``python scripts/bench_import.py [--write BENCHMARKS.md] [--rounds R]``.

Each round starts one interpreter per statement, the two interleaved (so load on a shared
machine falls on both alike), and times the statement inside it with ``time.perf_counter``
(the interpreter's own start is left out: it is the same for both). The median of ``R`` rounds
is reported, the ratio of the medians, the modules each statement loads, and the load average
while it ran.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys

from hgo_mj._bench import header, write_section

#: label -> the statement timed
STATEMENTS = {"import mujoco, numpy": "import mujoco, numpy",
              "import hgo_mj.simulate": "import hgo_mj.simulate"}
TARGET = 1.5

_PROBE = ("import sys, time, json\nt0 = time.perf_counter()\n{stmt}\n"
          "t = time.perf_counter() - t0\n"
          "print(json.dumps({{'s': t, 'modules': len(sys.modules), "
          "'numba': 'numba' in sys.modules}}))")


def _once(stmt: str) -> dict:
    out = subprocess.run([sys.executable, "-c", _PROBE.format(stmt=stmt)], capture_output=True,
                         text=True, check=True, timeout=300).stdout
    return json.loads(out.strip().splitlines()[-1])


def measure(rounds: int) -> dict[str, dict]:
    """Per statement: ``times`` (one per round, s), ``median`` (s), ``modules`` (how many
    modules it leaves loaded), ``numba`` (whether numba is among them)."""
    runs: dict[str, list[dict]] = {label: [] for label in STATEMENTS}
    for _ in range(rounds):
        for label, stmt in STATEMENTS.items():
            runs[label].append(_once(stmt))
    return {label: {"times": [r["s"] for r in rs], "median": statistics.median(r["s"] for r in rs),
                    "modules": rs[-1]["modules"], "numba": rs[-1]["numba"]}
            for label, rs in runs.items()}


def report(res: dict[str, dict], command: str, load: tuple[float, float]) -> str:
    base, ours = res["import mujoco, numpy"], res["import hgo_mj.simulate"]
    ratio = ours["median"] / base["median"]
    lines = ["## Issue 28: import time (`scripts/bench_import.py`)", "", *header(command),
             f"Load average (1 min) before / after: {load[0]:.2f} / {load[1]:.2f}", "",
             "| statement, in a fresh interpreter | median [ms] | min-max [ms] | modules loaded |",
             "|---|---|---|---|"]
    for label, r in res.items():
        lines.append(f"| `{label}` | {1e3 * r['median']:.0f} | {1e3 * min(r['times']):.0f}-"
                     f"{1e3 * max(r['times']):.0f} | {r['modules']} |")
    verdict = "meets" if ratio <= TARGET else "misses"
    lines += ["", f"`import hgo_mj.simulate` / `import mujoco, numpy` = **{ratio:.2f}x** (median of "
              f"{len(base['times'])} interleaved rounds; target <= {TARGET}x: {verdict} it). "
              f"numba loaded by `import hgo_mj.simulate`: {'yes' if ours['numba'] else 'no'} "
              "(the observer and system registries import a family, and with it numba, on first "
              "use)."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--write", metavar="FILE", help="replace this script's block in FILE")
    args = ap.parse_args(argv)
    if args.rounds < 1:
        print(f"bench_import: --rounds must be >= 1; found {args.rounds}", file=sys.stderr)
        return 2
    before = os.getloadavg()[0]
    res = measure(args.rounds)
    text = report(res, "python scripts/bench_import.py " + " ".join(argv or sys.argv[1:]),
                  (before, os.getloadavg()[0]))
    print(text)
    if args.write:
        write_section(args.write, "bench_import", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
