"""Speed of the study engine, side by side with what it replaces (issue 11).

Usage: ``python scripts/bench_study.py [--write BENCHMARKS.md] [--single N] [--no-ray]``.

1. **Seeds x gains, open loop**: 256 seeds x 4 gains of a high-gain observer on the pendulum,
   10 s at 1 kHz, Gaussian noise + quantization, as one study (``jobs = 2``) against the same
   runs through the single-run path (``simulate`` and its metrics once per run,
   ``hgo_mj.study.run_seed``, on a pool of 2 processes: today's ``hgo-mj run --seeds``). The
   single-run path is timed on ``--single`` of the 1024 runs (default all) and its rate scaled
   to 1024; every run it made is compared with the study's row (peak, settling time and final
   error equal; RMSE to 1e-12).
   Target: at least 30x faster.
2. **Initial states**: 256 distinct initial states (256 plant trajectories), one observer,
   no noise, as one study, against bare ``mujoco.rollout.Rollout(nthread=2)`` of the same
   model, initial states and inputs (the controls made once, outside the timing). Target: at
   least 0.7x the rollout's throughput.
3. **Closed loop**: 256 seeds of the LQR on the high-gain estimate of the cart pendulum (paper
   004), 10 s at 1 kHz, as one study (every member its own plant, stepped together) against
   the same runs through the single-run path (``--single-closed`` of them timed, scaled).
   Target: at least 5x faster.
4. **Ray**: study 1 on a local Ray instance (2 CPUs, 127.0.0.1; started before the timing,
   its workers cold) against the local backend. Target: at least 0.7x, rows identical.
5. **Memory**: 10,000 runs by ``hgo-mj sweep`` in a fresh process: its peak resident memory
   (``ru_maxrss`` of the child, the largest of its processes). Target: under 500 MB.

Every study is timed after a small study in the same process has loaded the compiled kernels
(a first study in a fresh process pays about a second more: ``import`` and the kernel cache).
"""

from __future__ import annotations

import argparse
import multiprocessing
import shutil
import sys
import tempfile
import time
from functools import partial
from pathlib import Path

import numpy as np

from hgo_mj._bench import header, write_section
from hgo_mj._extras import require

BASE = {
    "name": "bench",
    "plant": {"name": "pendulum", "dt": 0.001, "x0": [0.5, 0.0]},
    "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3},
                          {"stage": "quantize", "counts_per_rev": 4096}]},
    "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    "input": {"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]},
    "run": {"duration": 10.0, "seed": 0},
}
GAINS = [10.0, 20.0, 40.0, 80.0]


def _timed_study(study, out: Path, **kw):
    shutil.rmtree(out, ignore_errors=True)
    t0 = time.perf_counter()
    result = study.run(out, quiet=True, **kw)
    return time.perf_counter() - t0, result


def warm_up(tmp: Path) -> None:
    from hgo_mj.study import Study

    small = {**BASE, "run": {"duration": 0.2, "seed": 0}}
    Study(small, {"observers.hgo.k": [10.0, 20.0]}, seeds=2).run(tmp / "warm", quiet=True)


def _single_run(job: tuple[dict, int]) -> dict:
    """One run through the single-run path: ``simulate`` and its metrics."""
    from hgo_mj.scenario import scenario_run
    from hgo_mj.study import run_seed

    sc, seed = job
    return run_seed(partial(scenario_run, sc), seed)


def seeds_by_gains(tmp: Path, single: int) -> dict[str, float]:
    from hgo_mj.study import Study

    study = Study(BASE, {"observers.hgo.k": GAINS}, seeds=256)
    t_study, result = _timed_study(study, tmp / "s1", jobs=2)
    df = result.table
    per_gain = max(1, single // len(GAINS))
    jobs = [(cell.scenario, seed) for cell in study.cells for seed in study.spec.seeds[:per_gain]]
    t0 = time.perf_counter()
    with multiprocessing.get_context("spawn").Pool(2) as pool:
        runs = pool.map(_single_run, jobs, chunksize=1)
    worst, compared = 0.0, 0
    for cell in study.cells:
        for seed in study.spec.seeds[:per_gain]:
            m = runs[compared]
            for j, state in enumerate(m["hgo"]["states"]):
                row = df[(df.cell == cell.index) & (df.seed == seed) & (df.state == state)].iloc[0]
                for key in ("peak", "settling_time", "final"):
                    assert row[key] == m["hgo"][key][j], (cell.values, seed, state, key)
                worst = max(worst, abs(row["rmse"] - m["hgo"]["rmse"][j]) / m["hgo"]["rmse"][j])
            compared += 1
    t_single = (time.perf_counter() - t0) * (1024 / compared)
    assert worst <= 1e-12, worst
    return {"study_s": t_study, "single_s": t_single, "compared": compared, "worst_rmse": worst}


def initial_states(tmp: Path) -> dict[str, float]:
    import mujoco
    import mujoco.rollout

    from hgo_mj.inputs import make_signal
    from hgo_mj.plants import make_plant
    from hgo_mj.study import Study

    rng = np.random.default_rng(0)
    x0s = np.column_stack([rng.uniform(-1.0, 1.0, 256), rng.uniform(-1.0, 1.0, 256)])
    sc = {**BASE, "sensor": {"stages": []}}
    study = Study(sc, {"plant.x0": [list(map(float, x)) for x in x0s]}, seeds=1)
    t_study, result = _timed_study(study, tmp / "s2", jobs=2)
    assert len(result.table) == 256 * 2
    # bare rollout: the same model, initial states and controls
    plant = make_plant("pendulum", 0.001)
    m = plant.model
    N = 10_000
    u = make_signal("multisine", amplitudes=[0.3], frequencies=[0.5]).values(
        np.arange(N) * 0.001)
    d = mujoco.MjData(m)
    nstate = mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    S0 = np.empty((256, nstate))
    for b, x in enumerate(x0s):
        mujoco.mj_resetData(m, d)
        d.qpos[:], d.qvel[:] = x[:1], x[1:]
        mujoco.mj_forward(m, d)
        mujoco.mj_getState(m, d, S0[b], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    steps = int(round(plant.dt / m.opt.timestep))
    ctrl = np.repeat(np.repeat(u, steps, axis=0)[None], 256, axis=0)
    best = np.inf
    with mujoco.rollout.Rollout(nthread=2) as r:
        datas = [mujoco.MjData(m) for _ in range(2)]
        for _ in range(3):
            t0 = time.perf_counter()
            r.rollout([m] * 256, datas, S0, ctrl, nstep=N * steps)
            best = min(best, time.perf_counter() - t0)
    return {"study_s": t_study, "rollout_s": best, "plant_steps": 256 * N * steps}


CLOSED = {
    "name": "closed",
    "plant": {"name": "cart_pendulum", "dt": 0.001, "x0": [0.3, 0.0]},
    "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
    "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    "controller": {"type": "lqr", "Q": [1.0, 1.0], "R": 1.0, "observer": "hgo"},
    "run": {"duration": 10.0, "seed": 0},
}


def closed_loop(tmp: Path, single: int) -> dict[str, float]:
    from hgo_mj.study import Study

    study = Study(CLOSED, seeds=256)
    t_study, result = _timed_study(study, tmp / "s3", jobs=2)
    df = result.table
    jobs = [(CLOSED, seed) for seed in study.spec.seeds[:single]]
    t0 = time.perf_counter()
    with multiprocessing.get_context("spawn").Pool(2) as pool:
        runs = pool.map(_single_run, jobs, chunksize=1)
    t_single = (time.perf_counter() - t0) * (256 / len(jobs))
    for (_, seed), m in zip(jobs, runs):
        for j, state in enumerate(m["hgo"]["states"]):
            row = df[(df.seed == seed) & (df.state == state)].iloc[0]
            assert row["peak"] == m["hgo"]["peak"][j] and row["final"] == m["hgo"]["final"][j]
    return {"study_s": t_study, "single_s": t_single, "compared": len(jobs)}


MEMORY_TOML = """
name = "memory"
[plant]
name = "pendulum"
x0 = [0.5, 0.0]
[sensor]
stages = [{stage = "gaussian", std = 1e-3}, {stage = "quantize", counts_per_rev = 4096}]
[[observers]]
type = "high_gain"
name = "hgo"
k = 20.0
[input]
type = "multisine"
amplitudes = [0.3]
frequencies = [0.5]
[run]
duration = 10.0
[sweep]
seeds = 2500
"observers.hgo.k" = [10.0, 20.0, 40.0, 80.0]
"""


def memory(tmp: Path) -> dict[str, float]:
    """10,000 runs (2500 seeds x 4 gains, 10 s each) by `hgo-mj sweep` in a fresh process:
    the peak resident memory of that process and of its own workers, and the wall time."""
    import subprocess

    f = tmp / "memory.toml"
    f.write_text(MEMORY_TOML)
    code = ("import resource, sys\n"
            "from hgo_mj.cli import main\n"
            f"rc = main(['sweep', {str(f)!r}, '--out', {str(tmp / 'mem')!r}, '--jobs', '2', "
            "'--quiet'])\n"
            "peak = max(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,\n"
            "           resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n"
            "print('PEAK', peak, file=sys.stderr)\n"
            "sys.exit(rc)\n")
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                          text=True)
    wall = time.perf_counter() - t0
    peak_kib = int(done.stderr.split("PEAK")[-1].split()[0])
    return {"runs": 10_000, "rss_mb": peak_kib / 1024, "wall_s": wall}


def on_ray(tmp: Path, t_local: float, local_df) -> dict[str, float]:
    ray = require("ray", "ray", "scripts/bench_study.py's Ray run")

    from hgo_mj.study import Study

    ray.init(num_cpus=2, include_dashboard=False, _node_ip_address="127.0.0.1",
             log_to_driver=False, configure_logging=False)
    try:
        study = Study(BASE, {"observers.hgo.k": GAINS}, seeds=256)
        t_cold, res = _timed_study(study, tmp / "r1", jobs=2, backend="ray")
        t_warm, _ = _timed_study(study, tmp / "r2", jobs=2, backend="ray")
    finally:
        ray.shutdown()
    cols = [c for c in local_df.columns if c != "update_time"]
    same = bool(res.table[cols].equals(local_df[cols]))
    return {"cold_s": t_cold, "warm_s": t_warm, "local_s": t_local, "identical": same}


def report(s1: dict, s2: dict, s3: dict, mem: dict, r: dict | None,
           args: argparse.Namespace) -> str:
    lines = [
        "## Issue 11: the study engine (`scripts/bench_study.py`)", "",
        *header(f"`python scripts/bench_study.py --write BENCHMARKS.md --single {args.single} "
                f"--single-closed {args.single_closed}`",
                extra=("pandas", "pyarrow", "ray")), "",
        "| what | time [s] | ratio | target |", "|---|---:|---|---|",
        f"| 1. study: 256 seeds x 4 gains, HGO, pendulum 10 s at 1 kHz, Gaussian + "
        f"quantization, `jobs=2` | {s1['study_s']:.2f} | | |",
        f"| 1. the same 1024 runs through the single-run path (`simulate` + metrics per run, "
        f"a pool of 2 processes; {s1['compared']} runs timed, scaled to 1024) | {s1['single_s']:.1f} | "
        f"study {s1['single_s'] / s1['study_s']:.0f}x faster | >= 30x |",
        f"| 2. study: 256 initial states, one HGO, no noise, `jobs=2` | {s2['study_s']:.2f} | "
        f"| |",
        f"| 2. bare `mujoco.rollout.Rollout(nthread=2)`, the same 256 x 10,000 steps | "
        f"{s2['rollout_s']:.2f} | study at {s2['rollout_s'] / s2['study_s']:.2f}x the "
        f"rollout's throughput | >= 0.7x |",
        f"| 3. study: closed loop, LQR on the HGO estimate, cart pendulum 10 s at 1 kHz, 256 "
        f"seeds, `jobs=2` | {s3['study_s']:.2f} | | |",
        f"| 3. the same 256 runs through the single-run path (a pool of 2 processes; "
        f"{s3['compared']} runs timed, scaled to 256) | {s3['single_s']:.1f} | study "
        f"{s3['single_s'] / s3['study_s']:.1f}x faster | >= 5x |",
        f"| memory: 10,000 runs (2500 seeds x 4 gains, 10 s each) by `hgo-mj sweep --jobs 2`, "
        f"peak RSS of the largest process | {mem['wall_s']:.1f} | {mem['rss_mb']:.0f} MB | "
        f"<= 500 MB |",
    ]
    if r is not None:
        lines += [
            f"| 4. study 1 on a local Ray instance (2 CPUs), workers cold | {r['cold_s']:.2f} | "
            f"{r['local_s'] / r['cold_s']:.2f}x the local backend | >= 0.7x |",
            f"| 4. the same again, Ray workers warm | {r['warm_s']:.2f} | "
            f"{r['local_s'] / r['warm_s']:.2f}x the local backend | |",
        ]
    lines += ["", f"Study 1's rows equal the single runs ({s1['compared']} compared: peak, "
              f"settling time and final error bit for bit, RMSE within "
              f"{s1['worst_rmse']:.1e} relative)"
              + (f"; Ray's rows {'equal' if r['identical'] else 'DIFFER FROM'} the local "
                 f"backend's." if r is not None else ".")]
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", help="replace the bench_study block of this markdown file")
    ap.add_argument("--single", type=int, default=1024,
                    help="runs of the single-run path to time (default all 1024)")
    ap.add_argument("--single-closed", type=int, default=64,
                    help="closed-loop runs of the single-run path to time (default 64 of 256)")
    ap.add_argument("--no-ray", action="store_true", help="skip the Ray figure")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench_study_"))
    try:
        warm_up(tmp)
        s1 = seeds_by_gains(tmp, args.single)
        print(f"1: study {s1['study_s']:.2f} s, single path {s1['single_s']:.1f} s",
              file=sys.stderr)
        s2 = initial_states(tmp)
        print(f"2: study {s2['study_s']:.2f} s, rollout {s2['rollout_s']:.2f} s", file=sys.stderr)
        s3 = closed_loop(tmp, args.single_closed)
        print(f"3: study {s3['study_s']:.2f} s, single path {s3['single_s']:.1f} s",
              file=sys.stderr)
        mem = memory(tmp)
        print(f"memory: {mem['rss_mb']:.0f} MB for 10,000 runs", file=sys.stderr)
        r = None
        if not args.no_ray:
            from hgo_mj.study import Study

            t_local, res = _timed_study(Study(BASE, {"observers.hgo.k": GAINS}, seeds=256),
                                        tmp / "l1", jobs=2)
            r = on_ray(tmp, t_local, res.table)
        text = report(s1, s2, s3, mem, r, args)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(text)
    if args.write:
        write_section(args.write, "bench_study", text)
        print(f"written to {args.write}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
