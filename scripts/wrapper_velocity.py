"""Velocity estimates of ObserverInTheLoop on Gymnasium's MuJoCo environments against the
backward difference of noisy joint positions (issue 13), written to docs/results/wrappers.md.

Usage: ``python scripts/wrapper_velocity.py [--steps N] [--std S] [--out docs/results/wrappers.md]``.

For each environment, every hinge and slide joint's position is measured with Gaussian noise of
standard deviation ``S`` (rad or m); the environment steps with uniformly random actions (seeded),
reset when an episode ends, for ``N`` environment steps in all. Compared, as the RMS error of
the joint velocities at the end of each environment step against the environment's own qvel:

* ``backward difference``: ``(y_k - y_(k-1)) / dt`` of the positions measured at each
  environment step (the same noise, drawn by a sensor chain of its own);
* ``ObserverInTheLoop(joints=..., observer="ekf_mujoco")``: the MuJoCo EKF on the environment's
  own MJCF, sampling at every physics step inside the frame skip (``substeps=True``, ``Q =
  0.01``);
* the same at the environment step only (``substeps=False``, ``Q = 1``);
* ``observer="high_gain_multi"`` with the MuJoCo model term (``model=True``, ``k = 60``) at
  every physics step.
"""

from __future__ import annotations

import argparse
import sys
import time

import gymnasium as gym
import numpy as np
from hgo_mj.envs.wrappers import ObserverInTheLoop

from hgo_mj._bench import header
from hgo_mj._io import write_text
from hgo_mj.sensors import GaussianNoise, SensorChain

ENVS = ("InvertedDoublePendulum-v5", "Reacher-v5", "Hopper-v5", "Walker2d-v5", "HalfCheetah-v5")


def joints_of(name: str) -> list[str]:
    m = gym.make(name).unwrapped.model
    return [m.joint(i).name for i in range(m.njnt) if m.jnt_type[i] in (2, 3)]


def run(name: str, config: dict, steps: int, std: float, seed: int = 0
        ) -> tuple[float, float, float]:
    """(RMS velocity error of the wrapper, of the backward difference, us per env step)."""
    joints = joints_of(name)
    env = ObserverInTheLoop(gym.make(name), joints=joints,
                            sensor=[{"stage": "gaussian", "std": std}], **config)
    u = env.unwrapped
    m = u.model
    vadr = [m.jnt_dofadr[m.joint(j).id] for j in joints]
    qadr = [m.jnt_qposadr[m.joint(j).id] for j in joints]
    nj = len(joints)
    bd_sensor = SensorChain([GaussianNoise(std=std)], seed=seed + 1)
    env.action_space.seed(seed)
    err_w, err_bd = [], []
    done, k, episode, prev = True, 0, 0, None
    t0 = time.perf_counter()
    while k < steps:
        if done:
            env.reset(seed=seed + episode)
            episode += 1
            prev = bd_sensor.apply(np.array([0.0]), u.data.qpos[qadr][None, None])[0, 0]
        _, _, term, trunc, info = env.step(env.action_space.sample())
        done = term or trunc
        k += 1
        v = np.array(u.data.qvel[vadr])
        err_w.append(info["estimate"][nj:] - v)
        y = bd_sensor.apply(np.array([k * env.dt]), u.data.qpos[qadr][None, None])[0, 0]
        err_bd.append((y - prev) / env.dt - v)
        prev = y
    elapsed = (time.perf_counter() - t0) / steps * 1e6
    env.close()
    rms = lambda e: float(np.sqrt(np.mean(np.square(e))))  # noqa: E731
    return rms(err_w), rms(err_bd), elapsed


CONFIGS = {
    "ekf_mujoco, every physics step": {"observer": "ekf_mujoco",
                                       "observer_kwargs": {"Q": 0.01}},
    "ekf_mujoco, every env step": {"observer": "ekf_mujoco", "observer_kwargs": {"Q": 1.0},
                                   "substeps": False},
    "high_gain_multi + MuJoCo model term, every physics step": {
        "observer": "high_gain_multi", "observer_kwargs": {"k": 60.0, "model": True}},
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=1000, help="environment steps per environment")
    ap.add_argument("--std", type=float, default=1e-3, help="position noise (rad or m)")
    ap.add_argument("--envs", nargs="*", default=list(ENVS), help="Gymnasium environment ids")
    ap.add_argument("--out", default=None, help="write the markdown here")
    a = ap.parse_args(argv)
    if a.steps < 2 or not a.std > 0:
        print(f"--steps must be >= 2 and --std > 0; found {a.steps}, {a.std}", file=sys.stderr)
        return 2
    cmd = f"python scripts/wrapper_velocity.py --steps {a.steps} --std {a.std:g}"
    rows = []
    for name in a.envs:
        bd = None
        cells = []
        for label, cfg in CONFIGS.items():
            w, b, us = run(name, cfg, a.steps, a.std)
            bd = b if bd is None else bd
            cells.append((label, w, us))
        rows.append((name, len(joints_of(name)), bd, cells))
    lines = [*header(cmd), "",
             "| environment | joints | backward difference | " + " | ".join(CONFIGS) + " |",
             "|---|---|---|" + "---|" * len(CONFIGS)]
    for name, nj, bd, cells in rows:
        lines.append(f"| {name} | {nj} | {bd:.4g} | " + " | ".join(
            f"{w:.4g} ({w / bd:.2f}x, {us:.0f} us/step)" for _, w, us in cells) + " |")
    text = "\n".join(lines)
    print(text)
    if a.out:
        write_text(a.out, PAGE.format(table=text, std=a.std, steps=a.steps))
    return 0


PAGE = """# Velocity from noisy joint positions: ObserverInTheLoop on Gymnasium's MuJoCo environments

Generated by `scripts/wrapper_velocity.py` (issue 13). Every hinge and slide joint's position of
the environment is measured with Gaussian noise of standard deviation {std:g} (rad or m); the
environment steps with seeded uniformly random actions for {steps} environment steps (reset
when an episode ends). Each cell is the RMS error of all joint velocities at the end of each
environment step against the environment's own `qvel`, then, in parentheses, its ratio to the
backward difference `(y_k - y_(k-1)) / dt` of positions measured with the same noise at each
environment step, and the wall time per environment step (one run on the shared 2-core
machine).

{table}

The wrapper is `ObserverInTheLoop(env, joints=[...], observer=..., sensor=[{{"stage":
"gaussian", "std": ...}}])`: the observer designs against the environment's own MJCF
(`env.unwrapped.fullpath`), reads the controls, and with `substeps=True` (the default) takes a
measurement at every physics step inside the frame skip; the agent's observation is the
environment's own with every entry that is a joint position or velocity replaced by the
estimate (names from the MJCF joints, bounds from the environment's space). With substeps the
estimate at the end of a step has used every measurement up to one physics step before it (the
observer's prediction over that physics step); without, up to one environment step before it.
The EKF's process noise `Q` is per sample, hence smaller at the physics rate.
"""


if __name__ == "__main__":
    sys.exit(main())
