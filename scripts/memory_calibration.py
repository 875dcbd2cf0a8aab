"""The peak memory of ``hgo-mj run`` against the up-front estimate it checks (issue 27 item 14).

Usage: ``python scripts/memory_calibration.py [--durations 50 200 800] [--formats npz parquet]``.

Each duration is one ``hgo-mj run`` of the pendulum at 1 kHz with two high-gain observers and
a Gaussian sensor, the rows kept in memory (no ``--stream``), in a fresh process; its peak
resident memory is the child's ``ru_maxrss``. Beside it: the rows x columns of the run
(:func:`hgo_mj.cli.output_shape`), their bytes ``8 x rows x columns`` (the raw estimate) and
what the check asks for: the process before the run (this script's own resident memory after
the same imports) plus :func:`hgo_mj.cli.run_memory`. The peak grows linearly with the rows:
the script fits ``peak = base + slope x 8 x rows x columns`` over the runs and prints the factor
a run needs (the slope, rounded up to a half), from which ``hgo_mj.cli.RUN_MEMORY_FACTOR`` is
set; the check is right when what it asks for is at least the measured peak (``fits``).
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SCENARIO = ["--plant", "pendulum", "--dt", "0.001", "--sensor", "gaussian:std=1e-3",
            "--observer", "high_gain:name=a,k=20", "--observer", "high_gain:name=b,k=60",
            "--input", "multisine:amplitudes=[0.3],frequencies=[0.5]", "--quiet"]


def peak_of(duration: float, formats: list[str], out: Path) -> tuple[float, float]:
    """The peak resident memory (bytes) and wall time of one run in a fresh process."""
    fmt = [a for f in formats for a in ("--format", f)]
    code = ("import resource, sys\nfrom hgo_mj.cli import main\n"
            f"rc = main(['run', *{SCENARIO!r}, '--duration', '{duration}', *{fmt!r}, "
            f"'--out', {str(out)!r}])\n"
            "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\nsys.exit(rc)\n")
    t0 = time.perf_counter()
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if res.returncode != 0:
        raise SystemExit(f"the run of {duration} s failed: {res.stderr}")
    return float(res.stdout.split()[-1]) * 1024, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--durations", type=float, nargs="+", default=[50.0, 200.0, 800.0])
    ap.add_argument("--formats", nargs="+", default=["npz", "parquet"])
    args = ap.parse_args()
    from hgo_mj.cli import RUN_MEMORY_FACTOR, build_parser, output_shape, run_memory, scenario_from_args
    from hgo_mj.scenario import scenario_run

    rows_cols, peaks = [], []
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024.0  # after the imports
    print(f"RUN_MEMORY_FACTOR = {RUN_MEMORY_FACTOR:g}; formats {' '.join(args.formats)}; "
          f"the process before a run: {base / 2**20:.0f} MiB")
    print("| duration [s] | rows | columns | 8 x rows x columns [MiB] | peak RSS [MiB] "
          "| peak / raw | asked [MiB] | fits |")
    print("|---:|---:|---:|---:|---:|---:|---:|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for i, d in enumerate(args.durations):
            sc = scenario_from_args(build_parser().parse_args(
                ["run", *SCENARIO, "--duration", str(d)]))
            rows, width = output_shape(scenario_run(sc, "cal"), 1)
            raw = 8 * rows * width
            peak, wall = peak_of(d, args.formats, Path(tmp) / f"o{i}")
            asked = base + run_memory(rows, width)
            rows_cols.append(raw)
            peaks.append(peak)
            print(f"| {d:g} | {rows:,.0f} | {width} | {raw / 2**20:,.0f} | {peak / 2**20:,.0f} "
                  f"| {peak / raw:.2f} | {asked / 2**20:,.0f} | {'yes' if asked >= peak else 'NO'} "
                  f"| ({wall:.0f} s)")
    slope, base = np.polyfit(rows_cols, peaks, 1)
    print(f"\nfit: peak = {base / 2**20:.0f} MiB + {slope:.2f} x 8 x rows x columns "
          f"(the factor a run needs: {np.ceil(slope * 2) / 2:g}, rounded up to a half)")


if __name__ == "__main__":
    main()
