"""Cost of the batch axis on the plant and sensor sides (issue 10).

Measured in one process, each figure the best of several repeats (wall clock, since the
MuJoCo rollout runs in its own threads):

* ``sensor``: ``SensorChain.apply`` of Gaussian noise then quantization over B streams, in
  blocks of T samples, nanoseconds per stream-sample (the issue's target: at most 30 ns at
  B = 1024); B = 1, T = 1 is one sample of one stream (the per-sample cost);
* ``mujoco``: ``MujocoPlant.run`` of the pendulum, B members, open-loop inputs, physics steps
  per second, against bare ``mj_step`` on one ``MjData`` (the loop of one member, a short
  block: the Python loop; long or batched blocks: ``mujoco.rollout``), and the one-member
  block length where the rollout starts to pay (``_ROLLOUT_MIN_STEPS``);
* ``ode``: ``OdePlant.run`` of a paper system, B members (a loop over the members of the
  same RK4 as a one-member run), microseconds per member-plant-step.

Usage::

    python scripts/bench_batch.py                         # print the table
    python scripts/bench_batch.py --write BENCHMARKS.md   # also replace its block there
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np

from hgo_mj._bench import header, write_section
from hgo_mj.plants import OdePlant, make_plant
from hgo_mj.sensors import GaussianNoise, Quantization, SensorChain
from hgo_mj.systems import BioreactorBullinger

SECTION = "Issue 10: batch axis, plants and sensors"
CLOCK = time.perf_counter


def best(fn: Callable[[], float], repeats: int) -> float:
    """The least of ``repeats`` calls of ``fn`` (each returns a cost)."""
    return min(fn() for _ in range(repeats))


def sensor_cost(B: int, T: int, samples: int) -> float:
    """ns per stream-sample of Gaussian + quantization over B streams in blocks of T."""
    chain = SensorChain([GaussianNoise(std=1e-3), Quantization(counts_per_rev=4096)])
    chain.reset(list(range(B)))
    Y = np.zeros((B, T, 1))
    blocks = max(1, samples // T)
    ts = [np.arange(k * T, (k + 1) * T) * 1e-3 for k in range(blocks + 8)]
    for k in range(8):                  # warm: the draw blocks grow to their size
        chain.apply(ts[k], Y)
    t0 = CLOCK()
    for k in range(8, 8 + blocks):
        chain.apply(ts[k], Y)
    return (CLOCK() - t0) / (blocks * T * B) * 1e9


def mujoco_rate(B: int, T: int, steps: int, nthread: int) -> float:
    """Physics steps per second of ``MujocoPlant.run`` (pendulum, zero-mean random input)."""
    plant = make_plant("pendulum", 0.001, nthread=nthread)
    U = np.random.default_rng(0).standard_normal((B, T, 1)) * 0.1
    plant.reset(batch=B) if B > 1 else plant.reset()
    plant.run(U[:, :2], steps)          # the rollout's thread pool and data are made once
    plant.reset(batch=B) if B > 1 else plant.reset()
    t0 = CLOCK()
    plant.run(U, steps)
    return B * T * steps * plant.substeps / (CLOCK() - t0)


def bare_rate(n: int) -> float:
    plant = make_plant("pendulum", 0.001)
    m, d = plant.model, mujoco.MjData(plant.model)
    t0 = CLOCK()
    mujoco.mj_step(m, d, n)
    return n / (CLOCK() - t0)


def single_block_cost(T: int, path: str) -> float:
    """us per sample of one member's block of T one-step samples through the loop or the
    rollout (the choice ``_ROLLOUT_MIN_STEPS`` makes)."""
    from hgo_mj.plants import mujoco as mjp

    plant = make_plant("pendulum", 0.001, nthread=1)
    U = np.zeros((1, T, 1))
    keep = mjp._ROLLOUT_MIN_STEPS
    mjp._ROLLOUT_MIN_STEPS = 2 if path == "rollout" else 1 << 60
    try:
        plant.reset()
        plant.run(U, 1)     # the rollout's pool is made once
        t0 = CLOCK()
        plant.run(U, 1)
        return (CLOCK() - t0) / T * 1e6
    finally:
        mjp._ROLLOUT_MIN_STEPS = keep


def ode_cost(B: int, T: int) -> float:
    """us per member-plant-step of ``OdePlant.run`` (paper 000's bioreactor, 10 RK4 steps)."""
    plant = OdePlant(BioreactorBullinger(), dt=0.01)
    plant.reset(batch=B)
    U = np.full((B, T, 1), 0.1)
    t0 = CLOCK()
    plant.run(U, 1)
    return (CLOCK() - t0) / (B * T) * 1e6


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--write", type=Path, help="replace this script's block in that file")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    r = args.repeats
    lines = [f"### {SECTION}", "", *header("python scripts/bench_batch.py"), ""]
    lines += ["| sensor chain: Gaussian + quantization | ns per stream-sample |", "|---|---|"]
    for B, T in ((1, 1), (1, 100), (64, 1), (1024, 1), (1024, 10), (1024, 100)):
        cost = best(lambda B=B, T=T: sensor_cost(B, T, 2_000 if B == 1024 else 20_000), r)
        lines.append(f"| `apply`, B = {B}, blocks of T = {T} | {cost:.1f} |")
    lines += ["", "| MuJoCo pendulum, open loop | physics steps/s |", "|---|---|"]
    lines.append(f"| bare `mj_step` (one MjData) | {best(lambda: bare_rate(100_000), r):,.0f} |")
    for B, T, nth in ((1, 100, 1), (1, 1000, 1), (256, 1000, 1), (256, 1000, 2),
                      (1024, 200, 2)):
        rate = best(lambda B=B, T=T, nth=nth: mujoco_rate(B, T, 1, nth), r)
        lines.append(f"| `run`, B = {B}, T = {T}, nthread = {nth} | {rate:,.0f} |")
    lines += ["", "| one member, a block of T one-step samples | loop us/sample | "
                  "rollout us/sample |", "|---|---|---|"]
    for T in (4, 16, 64, 256):
        lines.append(f"| T = {T} | {best(lambda T=T: single_block_cost(T, 'loop'), r):.2f} | "
                     f"{best(lambda T=T: single_block_cost(T, 'rollout'), r):.2f} |")
    lines += ["", "| ODE plant (bioreactor, 10 RK4 steps per plant step) | us per "
                  "member-step |", "|---|---|"]
    for B in (1, 64):
        lines.append(f"| `run`, B = {B}, T = 100 (member loop) | "
                     f"{best(lambda B=B: ode_cost(B, 100), r):.0f} |")
    text = "\n".join(lines)
    print(text)
    if args.write is not None:
        write_section(args.write, "bench_batch", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
