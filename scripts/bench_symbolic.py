"""Speed of a system derived from text (``hgo_mj.systems.symbolic``) against the hand-written
system of the same model, side by side in one process.

Usage: ``python scripts/bench_symbolic.py [--write BENCHMARKS.md] [--updates N] [--rounds R]``.

The model is the pendulum: the hand-written :class:`~hgo_mj.systems.pendulum.Pendulum`
(``make_plant("pendulum").system``) against ``ode_system`` of its equation
``x2' = (gear u - m g l_c sin x1 - d x2)/J`` with the same parameters. Per update or call, best
of ``R`` interleaved rounds:

* the high-gain observer with its model term (``high_gain``, ``model=True``): ``phi`` through
  the system's ``phi_batch`` at every sample;
* ``phi_batch`` of 64 rows (a batch of observers' model term in one call);
* the EKF (``ekf``) on each system's compiled model (derived: the generated ``f`` and Jacobian
  as a :class:`~hgo_mj.systems.base.CompiledModel`).
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from hgo_mj._bench import header, write_section
from hgo_mj.observers import make_observer
from hgo_mj.plants import make_plant
from hgo_mj.systems.symbolic import ode_system

DT = 1e-3
PENDULUM_F = ["x2", "(gear*u - mass*g*com_distance*sin(x1) - damping*x2)/inertia"]


def _observer_case(obs, n: int):
    y, u = np.array([0.1]), np.array([0.2])

    def run() -> None:
        for _ in range(n):
            obs.update(y, u, DT)
    return run, n


def _phi_case(system, n: int):
    rng = np.random.default_rng(0)
    Z, U = rng.uniform(-1, 1, (64, 2)), rng.uniform(-1, 1, (64, 1))

    def run() -> None:
        for _ in range(n):
            system.phi_batch(Z, U)
    return run, n


def cases(updates: int) -> dict[str, tuple]:
    hand = make_plant("pendulum", DT).system
    derived = ode_system(["x1", "x2"], PENDULUM_F, "x1", inputs=["u"],
                         params=dict(hand.params))()
    out = {}
    for label, system in (("hand-written", hand), ("derived", derived)):
        out[f"HGO + model term, {label}"] = _observer_case(
            make_observer("high_gain", system, k=20.0, model=True), updates)
        out[f"phi_batch of 64 rows, {label}"] = _phi_case(system, updates)
        out[f"EKF, {label}"] = _observer_case(make_observer("ekf", system, R=1e-4), updates)
    return out


def measure(updates: int, rounds: int) -> dict[str, float]:
    """Best time per update or call [us] of each case, rounds interleaved."""
    cs = cases(updates)
    for run, _ in cs.values():  # warm-up: compile and fill caches
        run()
    best = {k: float("inf") for k in cs}
    for _ in range(rounds):
        for k, (run, n) in cs.items():
            t0 = time.perf_counter()
            run()
            best[k] = min(best[k], (time.perf_counter() - t0) / n * 1e6)
    return best


def report(best: dict[str, float], command: str) -> str:
    kinds = ("HGO + model term", "phi_batch of 64 rows", "EKF")
    lines = [*header(command), "", "| case | us per update/call |", "|---|---|"]
    lines += [f"| {k} | {v:.2f} |" for k, v in best.items()]
    lines += ["", "| derived / hand-written | ratio |", "|---|---|"]
    lines += [f"| {k} | {best[f'{k}, derived'] / best[f'{k}, hand-written']:.2f}x |"
              for k in kinds]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--updates", type=int, default=2000)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--write", default=None, help="write the block into this file")
    a = ap.parse_args(argv)
    if a.updates < 1 or a.rounds < 1:
        print(f"--updates and --rounds must be >= 1; found {a.updates}, {a.rounds}",
              file=sys.stderr)
        return 2
    text = report(measure(a.updates, a.rounds),
                  f"python scripts/bench_symbolic.py --updates {a.updates} --rounds {a.rounds}")
    print(text)
    if a.write:
        write_section(a.write, "bench_symbolic", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
