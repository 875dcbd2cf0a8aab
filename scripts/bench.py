"""Speed of the parts, measured side by side in one run, as ratios to a bare ``mj_step`` loop.

Usage: ``python scripts/bench.py [--write BENCHMARKS.md]``. Each figure is the best of several
repeats (the machine is shared; the minimum is the least disturbed). Targets (issues 2, 10):

* a plant step adds at most 30% to a bare ``mj_step`` loop on the same model;
* a high-gain observer update for n <= 4 costs at most one bare pendulum ``mj_step``;
* ``simulate`` of the pendulum with the sensor chain and one high-gain observer at 1 kHz runs
  at least 100k loop steps per second, i.e. within 4.5x of a bare ``mj_step`` loop;
* batched over B = 1024 members: a high-gain update at most 20 ns per observer-step, an EKF
  at most 200 ns, the sensor chain (Gaussian + quantization) at most 30 ns per sample;
* the import time of ``hgo_mj`` and the first-call compile time of the kernels are reported
  (each in a fresh process; the compile time with an empty numba cache).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import mujoco
import numpy as np

from hgo_mj._bench import header, write_section
from hgo_mj.inputs import Multisine
from hgo_mj.observers import ExtendedKalmanFilter, HighGainObserver
from hgo_mj.plants import MujocoPlant, model_path
from hgo_mj.sensors import GaussianNoise, Quantization, SensorChain
from hgo_mj.simulate import simulate
from hgo_mj.systems.papers import BioreactorBullinger
from hgo_mj.systems.pendulum import Pendulum

B_BATCH = 1024
T_BATCH = 100


def advance(ob, Y, U, dt):
    """Consume a block on the observer's own state in place: the loop's path
    (``Observer._step_checked``, the block checked once by the caller)."""
    params, state = ob._own()
    return ob._step_checked(params, state, Y, U, dt)


def best_per_call(fn, number: int, repeat: int = 7) -> float:
    """Best over ``repeat`` runs of the mean seconds per call of ``fn`` called ``number`` times."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn(number)
        best = min(best, (time.perf_counter() - t0) / number)
    return best


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", help="replace the bench block of this markdown file")
    ap.add_argument("--steps", type=int, default=20000)
    args = ap.parse_args()
    N = args.steps

    m = mujoco.MjModel.from_xml_path(str(model_path("pendulum.xml")))
    d = mujoco.MjData(m)

    def bare(n):
        for _ in range(n):
            mujoco.mj_step(m, d)

    plant = MujocoPlant(Pendulum, dt=m.opt.timestep)
    u = np.array([0.1])

    def plant_steps(n):
        for _ in range(n):
            plant.step(u)

    me = mujoco.MjModel.from_xml_path(str(model_path("pendulum.xml")))
    me.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    de = mujoco.MjData(me)

    def bare_euler(n):
        for _ in range(n):
            mujoco.mj_step(me, de)

    rows = []
    t_bare = best_per_call(bare, N)
    rows.append(("bare mj_step (pendulum.xml, RK4 as shipped)", t_bare, 1.0, ""))
    t_euler = best_per_call(bare_euler, N)
    rows.append(("bare mj_step, same model with the Euler integrator (reference only)", t_euler,
                 t_euler / t_bare, ""))
    t_plant = best_per_call(plant_steps, N)
    rows.append(("MujocoPlant.step (1 substep; the one-sample convenience, not the loop's path)",
                 t_plant, t_plant / t_bare, ""))
    U = np.full((1, N, 1), 0.1)

    def plant_block(n):
        for _ in range(n // N or 1):
            plant.run(U, 1)

    t_block = best_per_call(lambda n: plant_block(N), 1) / N
    rows.append((f"MujocoPlant.run, a block of {N} samples, per sample", t_block,
                 t_block / t_bare, "<= 1.3"))

    y = np.array([0.1])
    for n in (2, 4):
        ob = HighGainObserver(order=n, k=50.0)
        ob.update(y, u, 1e-3)

        def upd(k, ob=ob):
            for _ in range(k):
                ob.update(y, u, 1e-3)

        t_ob = best_per_call(upd, N)
        rows.append((f"HighGainObserver.update, n={n}", t_ob, t_ob / t_bare, "<= 1.0"))

    def sim(k, euler=False):
        p = MujocoPlant(Pendulum, dt=0.001)
        if euler:
            p.model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
        s = SensorChain([GaussianNoise(std=1e-3), Quantization(counts_per_rev=4096)], seed=0)
        ob = {"hgo": HighGainObserver(p.system, k=50.0)}
        simulate(p, s, ob, Multisine([0.2], [0.5]), duration=k * 0.001)

    t_sim = best_per_call(sim, N, repeat=3)
    rows.append(("simulate loop step (pendulum, 2-stage sensor, 1 HGO, 1 kHz)", t_sim,
                 t_sim / t_bare, "<= 4.5"))
    t_sim_e = best_per_call(lambda k: sim(k, euler=True), N, repeat=3)
    rows.append(("simulate loop step, same with the Euler integrator (reference only)", t_sim_e,
                 t_sim_e / t_bare, ""))

    batched = batched_rows()
    startup = startup_rows()
    lines = [
        *header(f"`python scripts/bench.py` ({N} steps per figure, best of repeats)"),
        f"Physics step of pendulum.xml: {m.opt.timestep} s, integrator "
        f"{mujoco.mjtIntegrator(m.opt.integrator).name}",
        "",
        "| what | time per call [us] | ratio to bare mj_step | target |",
        "|---|---:|---:|---|",
    ]
    for name, t, r, target in rows:
        lines.append(f"| {name} | {t * 1e6:.2f} | {r:.2f} | {target} |")
    lines.append(f"\nsimulate: {1.0 / t_sim:,.0f} loop steps per second (target >= 100,000); "
                 f"the loop's own cost (loop step minus bare mj_step) {(t_sim - t_bare) * 1e6:.2f} "
                 f"us; with the Euler integrator {1.0 / t_sim_e:,.0f} loop steps per second")
    lines += ["", f"Batched over B = {B_BATCH} members, blocks of T = {T_BATCH} samples "
              f"(`advance` / `apply`, checks included):", "",
              "| what | ns per member-sample | target |", "|---|---:|---|"]
    lines += [f"| {name} | {ns:.1f} | {target} |" for name, ns, target in batched]
    lines += ["", "Start-up, each in a fresh process:", "", "| what | seconds |", "|---|---:|"]
    lines += [f"| {name} | {sec:.2f} |" for name, sec in startup]
    text = "\n".join(lines)
    print(text)
    if args.write:
        write_section(args.write, "bench", text)
    return 0


def batched_rows() -> list[tuple[str, float, str]]:
    """ns per member-sample of the batched paths (best of 5)."""
    rng = np.random.default_rng(0)
    B, T, dt = B_BATCH, T_BATCH, 1e-3
    out = []

    def per(fn, repeats: int = 5) -> float:
        fn()  # compile / warm
        return min(_timed(fn) for _ in range(repeats)) / (B * T) * 1e9

    for n in (2, 4):
        ob = HighGainObserver(order=n, k=50.0)
        ob.reset(batch=B)
        Y = rng.normal(size=(B, T, 1))
        Uz = np.zeros((B, T, 1))
        out.append((f"HighGainObserver.advance, n={n}",
                    per(lambda ob=ob, Y=Y, Uz=Uz: advance(ob, Y, Uz, dt)), "<= 20"))
    sysb = BioreactorBullinger()
    ekf = ExtendedKalmanFilter(sysb, x_hat0=[0.08, 0.0], R=1e-6)
    ekf.reset(batch=B)
    Yb = 0.08 + 1e-3 * rng.normal(size=(B, T, 1))
    Ub = np.full((B, T, 1), 0.08)
    out.append(("ExtendedKalmanFilter.advance, bioreactor (n=2, compiled model)",
                per(lambda: advance(ekf, Yb, Ub, 0.01)), "<= 200"))
    chain = SensorChain([GaussianNoise(std=1e-3), Quantization(counts_per_rev=4096)])
    chain.reset(list(range(B)))
    Yc = np.zeros((B, T, 1))
    k = [0]

    def measure():
        t = (k[0] + np.arange(T)) * dt
        k[0] += T
        chain.apply(t, Yc)

    out.append(("SensorChain.apply, Gaussian + quantization", per(measure), "<= 30"))
    return out


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def startup_rows() -> list[tuple[str, float]]:
    """Import time of hgo_mj and first-call compile time (cold and warm numba cache)."""
    code_import = ("import time; t = time.perf_counter(); import hgo_mj.simulate; "
                   "print(time.perf_counter() - t)")
    code_first = ("import numpy as np; from hgo_mj.observers import HighGainObserver; import time; "
                  "ob = HighGainObserver(order=2, k=5.0); t = time.perf_counter(); "
                  "ob.update(np.zeros(1), np.zeros(1), 1e-3); print(time.perf_counter() - t)")

    def run(code: str, env: dict[str, str] | None = None) -> float:
        res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             env={**os.environ, **(env or {})}, check=True)
        return float(res.stdout.strip().splitlines()[-1])

    rows = [("import hgo_mj.simulate (numba, mujoco, numpy included)",
             min(run(code_import) for _ in range(3)))]
    with tempfile.TemporaryDirectory() as cache:
        cold = run(code_first, {"NUMBA_CACHE_DIR": cache})
        warm = min(run(code_first, {"NUMBA_CACHE_DIR": cache}) for _ in range(3))
    rows.append(("first HighGainObserver.update, empty numba cache (compile)", cold))
    rows.append(("first HighGainObserver.update, kernels loaded from the cache", warm))
    return rows


if __name__ == "__main__":
    sys.exit(main())
