"""Speed of tuning against the planned study of the same runs (issue 25).

Usage: ``python scripts/bench_tune.py [--trials 200] [--seeds 16] [--write BENCHMARKS.md]``.

A high-gain observer on the 10 s, 1 kHz pendulum (Gaussian noise and quantization, the study
benchmark's scenario) tuned over ``--trials`` trials x ``--seeds`` seeds with ``hgo_mj.tune``
(TPE, rounds of 50 trials, each round one batch: the plant run once and replayed, every trial
x seed a member with its own gain), against the study engine's plan of the same number of
runs (``Study`` with ``--trials`` gains on the axis ``observers.hgo.k`` x ``--seeds`` seeds,
``jobs = 1``: the plant run once per chunk, each gain a bucket of its seeds). Both in this
process, after a small warm-up of each; wall clock and this process's CPU time.
Target: tuning <= 3x the planned study: the evaluation dominates, not the sampler.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from hgo_mj._bench import header, write_section

BASE = {
    "name": "bench",
    "plant": {"name": "pendulum", "dt": 0.001, "x0": [0.5, 0.0]},
    "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3},
                          {"stage": "quantize", "counts_per_rev": 4096}]},
    "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    "input": {"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]},
    "run": {"duration": 10.0, "seed": 0},
}


def _clock(fn):  # type: ignore[no-untyped-def]
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return time.perf_counter() - w0, time.process_time() - c0, out


def run(trials: int, seeds: int) -> dict[str, tuple[float, float]]:
    from hgo_mj.study import Study
    from hgo_mj.tune import tune

    tmp = Path(tempfile.mkdtemp())
    try:
        small = {**BASE, "run": {"duration": 0.5, "seed": 0}}
        tune(small, "hgo", budget=4, seeds=2, progress=False)  # warm: kernels, Optuna
        Study(small, {"observers.hgo.k": [10.0, 20.0]}, seeds=2).run(tmp / "warm", quiet=True)
        gains = np.geomspace(2.0, 2000.0, trials).tolist()
        wt, ct, res = _clock(lambda: tune(BASE, "hgo", budget=trials, seeds=seeds,
                                          round_size=50, progress=False))
        ws, cs, study = _clock(lambda: Study(BASE, {"observers.hgo.k": gains},
                                             seeds=seeds).run(tmp / "study", quiet=True))
        assert len(study.table) == trials * seeds * 2, len(study.table)
        return {"tune": (wt, ct), "study": (ws, cs),
                "best": (res.values["best"][0], res.values["default"][0])}
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def table(res: dict[str, tuple[float, float]], trials: int, seeds: int) -> str:
    (wt, ct), (ws, cs) = res["tune"], res["study"]
    best, default = res["best"]
    lines = header(f"python scripts/bench_tune.py --trials {trials} --seeds {seeds}") + [
        "",
        f"{trials} trials x {seeds} seeds = {trials * seeds} runs of 10 s at 1 kHz (pendulum, "
        f"high-gain observer, Gaussian noise + quantization).",
        "",
        "| what | wall [s] | CPU [s] | ratio (wall) | target |",
        "|---|---:|---:|---:|---|",
        f"| `tune` (TPE, rounds of 50 trials, each one batch) | {wt:.2f} | {ct:.2f} | "
        f"{wt / ws:.2f}x | <= 3x |",
        f"| the planned study of the same runs (`Study`, {trials} gains x {seeds} seeds) | "
        f"{ws:.2f} | {cs:.2f} | 1.00x | |",
        "",
        f"Tuned normalized RMSE {best:.4g} against the default's {default:.4g} "
        f"({default / best:.1f}x lower).",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--seeds", type=int, default=16)
    ap.add_argument("--write", type=Path, help="replace the bench_tune block of this file")
    args = ap.parse_args(argv)
    text = table(run(args.trials, args.seeds), args.trials, args.seeds)
    print(text)
    if args.write:
        write_section(args.write, "bench_tune", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
