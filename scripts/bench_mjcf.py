"""Speed of a system read from an MJCF file (``hgo_mj.systems.mjcf``) against the hand-written
system of the same model, side by side in one process.

Usage: ``python scripts/bench_mjcf.py [--write BENCHMARKS.md] [--steps N] [--rounds R]``.

The model is the shipped pendulum (``models/pendulum.xml``): the hand-written
:class:`~hgo_mj.systems.pendulum.Pendulum` (``make_plant("pendulum")``) against the same file
through the generic MJCF path (``make_plant(model_path("pendulum.xml"), outputs=["hinge"])``).
Per step or update, best of ``R`` interleaved rounds:

* the plant: ``MujocoPlant.run`` over a block of ``N`` physics steps of 1 ms;
* the high-gain observer with its model term: ``high_gain`` (``model=True``, ``Pendulum.phi``)
  against ``high_gain_multi`` (``model=True``, the MJCF's ``mj_forward`` at the estimate), one
  observer, and a batch of 64 per member (the MJCF's model term through ``mujoco.batch``);
* the EKF: ``ekf`` on the hand-written compiled model, and ``ekf_mujoco`` (stepping the MJCF
  and ``mjd_transitionFD``) on each system.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from hgo_mj._bench import header, write_section
from hgo_mj.observers import make_observer
from hgo_mj.plants import make_plant, model_path

DT = 1e-3


def _plant_case(plant, steps: int):
    U = np.full((1, steps, 1), 0.1)

    def run() -> None:
        plant.reset()
        plant.run(U, 1)  # T = steps samples of one plant step each
    return run, steps


def _observer_case(obs, steps: int):
    y, u = np.array([0.1]), np.array([0.2])

    def run() -> None:
        for _ in range(steps):
            obs.update(y, u, DT)
    return run, steps


def _batch_case(obs, steps: int, B: int = 64):
    """Per member and sample of a batch of ``B`` observers (``Observer.update``, batched)."""
    y, u = np.full((B, len(obs.outputs)), 0.1), np.full((B, 1), 0.2)
    obs.reset(batch=B)

    def run() -> None:
        for _ in range(steps):
            obs.update(y, u, DT)
    return run, steps * B


def cases(steps: int) -> dict[str, tuple]:
    hand = make_plant("pendulum", DT)
    mjcf = make_plant(model_path("pendulum.xml"), DT, outputs=["hinge"])
    hs, ms = hand.system, mjcf.system
    n_obs = max(steps // 10, 50)
    return {
        "plant run, hand-written": _plant_case(hand, steps),
        "plant run, MJCF": _plant_case(mjcf, steps),
        "HGO + model term, hand-written (high_gain)": _observer_case(
            make_observer("high_gain", hs, k=20.0, model=True), n_obs),
        "HGO + model term, MJCF (high_gain_multi)": _observer_case(
            make_observer("high_gain_multi", ms, k=20.0, model=True), n_obs),
        "HGO + model term, hand-written, batch of 64, per member": _batch_case(
            make_observer("high_gain", hs, k=20.0, model=True), max(n_obs // 10, 10)),
        "HGO + model term, MJCF, batch of 64 (mujoco.batch), per member": _batch_case(
            make_observer("high_gain_multi", ms, k=20.0, model=True), max(n_obs // 10, 10)),
        "EKF, hand-written compiled model (ekf)": _observer_case(
            make_observer("ekf", hs, R=1e-4), n_obs),
        "EKF, MuJoCo on the hand-written system (ekf_mujoco)": _observer_case(
            make_observer("ekf_mujoco", hs, R=1e-4), n_obs),
        "EKF, MuJoCo on the MJCF system (ekf_mujoco)": _observer_case(
            make_observer("ekf_mujoco", ms, R=1e-4), n_obs),
    }


def measure(steps: int, rounds: int) -> dict[str, float]:
    """Best time per step or update [us] of each case, rounds interleaved."""
    cs = cases(steps)
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
    pairs = [("plant run, MJCF", "plant run, hand-written"),
             ("HGO + model term, MJCF (high_gain_multi)",
              "HGO + model term, hand-written (high_gain)"),
             ("HGO + model term, MJCF, batch of 64 (mujoco.batch), per member",
              "HGO + model term, hand-written, batch of 64, per member"),
             ("EKF, MuJoCo on the MJCF system (ekf_mujoco)",
              "EKF, hand-written compiled model (ekf)"),
             ("EKF, MuJoCo on the MJCF system (ekf_mujoco)",
              "EKF, MuJoCo on the hand-written system (ekf_mujoco)")]
    lines = [*header(command), "", "| case | us per step/update |", "|---|---|"]
    lines += [f"| {k} | {v:.2f} |" for k, v in best.items()]
    lines += ["", "| MJCF-derived / hand-written | ratio |", "|---|---|"]
    lines += [f"| {a} / {b} | {best[a] / best[b]:.2f}x |" for a, b in pairs]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--write", default=None, help="write the block into this file")
    a = ap.parse_args(argv)
    if a.steps < 1 or a.rounds < 1:
        print(f"--steps and --rounds must be >= 1; found {a.steps}, {a.rounds}", file=sys.stderr)
        return 2
    text = report(measure(a.steps, a.rounds),
                  f"python scripts/bench_mjcf.py --steps {a.steps} --rounds {a.rounds}")
    print(text)
    if a.write:
        write_section(a.write, "bench_mjcf", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
