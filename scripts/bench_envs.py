"""Speed of the hgo_mj environments against Gymnasium's InvertedPendulum-v5, side by side.

Measured in one process, in interleaved short bursts (each configuration runs a burst in turn,
many rounds; the best burst of each counts), timed with the thread's CPU clock
(``time.thread_time``) so that time the process spends descheduled on a shared machine does
not count; the load still slows every configuration alike through caches:

* ``step``: one ``env.step`` of ``gymnasium.make(id)`` (so with Gymnasium's ``TimeLimit``,
  ``OrderEnforcing`` and ``PassiveEnvChecker`` on both sides), zero action; the resets
  between episodes (InvertedPendulum falls within a few dozen steps) are subtracted at the
  measured reset cost;
* ``reset``: one ``env.reset()``;
* ``vector``: total environment steps per second of a ``SyncVectorEnv`` of 8 copies, zero
  actions, autoreset included.

``--vector`` (also part of a full run, its own block ``bench_envs_vector``): at N = 64, total
environment steps per second of the native vector environment
(``gymnasium.make_vec(id, num_envs=64)``, the one loop at B = 64, MuJoCo's batched step on
its thread pool) against Gymnasium's ``SyncVectorEnv`` of 64 of the same environment and of 64
InvertedPendulum-v5, zero actions, autoresets included; interleaved bursts, the best of each.
Beside them, the physics limit: a bare batched ``mj_step`` loop over 64 ``MjData`` of the
environment's own model (its integrator, contacts off where it has no collidable geom), each
advanced by the environment's physics steps per control period (``mj_step(m, d, nstep)``), and
the native environment's CPU time per step against it (the issue's target: at most 1.3x).
The native environment runs MuJoCo on two threads, so it is timed with the process's CPU
clock (``time.process_time``: every thread's time counts, the second thread's included) and
with the wall clock; the SyncVectorEnvs are single-threaded (the same clocks). The same
native environment with ``nthread=1`` (MuJoCo's batched step on this thread alone) is the
like-for-like comparison with the one-thread bare loop, and the target's.

PendulumSwingUp runs as registered (Gaussian sensor noise, the high-gain observer with the
pendulum's model term, two Euler MuJoCo steps per ``step`` as InvertedPendulum-v5's
``frame_skip=2``), and in variants that show what each part costs.

Usage::

    python scripts/bench_envs.py                      # print the table
    python scripts/bench_envs.py --write BENCHMARKS.md  # also replace its block there
    python scripts/bench_envs.py --vector --write BENCHMARKS.md  # only the N = 64 comparison
"""

from __future__ import annotations

import argparse
import copy
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import hgo_mj.envs  # noqa: F401  (registers the environments)
import mujoco
import numpy as np

from hgo_mj._bench import header, write_section

SECTION = "## Issue 5: Gymnasium environments"

CONFIGS: dict[str, tuple[str, dict[str, Any]]] = {
    "InvertedPendulum-v5 (Gymnasium)": ("InvertedPendulum-v5", {}),
    "PendulumSwingUp-v0 as registered (Gaussian noise, high_gain with model term)": (
        "hgo_mj/PendulumSwingUp-v0", {}),
    "PendulumSwingUp-v0, model-free high_gain (k=20)": (
        "hgo_mj/PendulumSwingUp-v0", {"observer_kwargs": {"k": 20.0, "model": False}}),
    "PendulumSwingUp-v0, info_level='full'": ("hgo_mj/PendulumSwingUp-v0", {"info_level": "full"}),
    "PendulumSwingUp-v0, no observer, no noise, observation='true'": (
        "hgo_mj/PendulumSwingUp-v0", {"observer": None, "sensor": None, "observation": "true"}),
}
REFERENCE = "InvertedPendulum-v5 (Gymnasium)"
BARE = "PendulumSwingUp-v0, no observer, no noise, observation='true'"
TARGET = "PendulumSwingUp-v0 as registered (Gaussian noise, high_gain with model term)"
TARGET_ID = "hgo_mj/PendulumSwingUp-v0"


CLOCK = time.thread_time


def _step_burst(env: gym.Env, n: int) -> tuple[float, int]:
    """CPU seconds of ``n`` steps, and the number of resets among them."""
    a = np.zeros(env.action_space.shape, dtype=env.action_space.dtype)
    resets = 0
    t0 = CLOCK()
    for _ in range(n):
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
            resets += 1
    return CLOCK() - t0, resets


def _reset_burst(env: gym.Env, n: int) -> float:
    t0 = CLOCK()
    for _ in range(n):
        env.reset()
    return (CLOCK() - t0) / n


def _vector_burst(venv: gym.vector.VectorEnv, n: int) -> float:
    """Environment steps per CPU second of a vector env (all copies together)."""
    a = np.zeros(venv.action_space.shape, dtype=venv.action_space.dtype)
    t0 = CLOCK()
    for _ in range(n):
        venv.step(a)
    return n * venv.num_envs / (CLOCK() - t0)


def _interleaved(fns: dict[str, Callable[[], float]], rounds: int, best: Callable[..., float]
                 ) -> dict[str, float]:
    results: dict[str, list[float]] = {k: [] for k in fns}
    for _ in range(rounds):
        for k, f in fns.items():
            results[k].append(f())
    return {k: best(v) for k, v in results.items()}


def _parts(rounds: int, n: int) -> dict[str, float]:
    """CPU seconds of the parts of one step of PendulumSwingUp as registered, each alone and
    as the environment's loop calls it, on an environment of its own (interleaved, best
    burst): the whole unwrapped ``step``; the loop's bound step of the control period
    (``Loop.bind_step``: one sample, the measurement drawn before); in it the plant's bound
    run (``MujocoPlant.bind_run``, and the bare ``mj_step`` of the same physics steps) and the
    observer's bound step (``Observer._bind_step``); the action's check; the observation and
    ``info``
    (``HgoEnv._observe`` with the measurement drawn already: ``Loop.sample``'s reads of the
    state and clean outputs, the estimate, the encoder, ``info``); the sensor chain's draw
    for one sample (``SensorChain._apply``); the task's reward."""
    env = gym.make(TARGET_ID).unwrapped
    env.reset(seed=0)
    loop, plant, ob = env.loop, env.plant, env.observer
    a = np.zeros(env.action_space.shape, dtype=env.action_space.dtype)
    for _ in range(200):
        env.step(a)
    U = np.zeros((1, 1, len(plant.input_names)))
    steps = loop.periods.steps
    nstep = steps * plant.substeps
    _, Yc, Ym = loop.sample()
    t1 = np.zeros(1)
    chain = copy.deepcopy(env.sensor)
    m, d = plant.model, plant.data

    bound = env._bound  # the step bound at the reset (one sample per step, as registered)
    run = plant.bind_run(np.zeros_like(U), steps, np.empty((1, 1, len(plant.state_names))),
                         np.empty((1, 1, len(plant.output_names))))
    advance = ob._bind_step(loop.params["observer"], 1, 1, loop.periods.sample)

    def segment() -> None:
        loop._pending = (loop.k, Ym)
        bound([0.0])

    def observe() -> None:
        loop._pending = (loop.k, Ym)  # the measurement drawn already: no sensor draw
        env._observe([0.0], None)

    x = plant.state.tolist()

    def burst(f: Callable[[], Any]) -> Callable[[], float]:
        def go() -> float:
            t0 = CLOCK()
            for _ in range(n):
                f()
            return (CLOCK() - t0) / n
        return go

    return _interleaved({
        "step": burst(lambda: env.step(a)),
        "segment": burst(segment),
        "plant_run": burst(run),
        "mj_step": burst(lambda: mujoco.mj_step(m, d, nstep)),
        "observer": burst(lambda: advance(loop.states["observer"], Ym, U)),
        "action": burst(lambda: env._action(a)),
        "observe": burst(observe),
        "sensor": burst(lambda: chain._apply(t1, Yc)),
        "reward": burst(lambda: env.task.reward(x, [0.0], ())),
    }, rounds, min)


#: the calls one ``HgoEnv.step`` makes, timed inside running steps by :func:`_in_step`
IN_STEP = ("action", "segment", "sample", "observe", "reward")


def _in_step(rounds: int, n: int) -> dict[str, float]:
    """Seconds of each call one step of PendulumSwingUp makes, timed inside running steps
    (``perf_counter_ns`` around the calls: the action, the bound step, ``HgoEnv._observe``
    and, inside it, ``Loop.sample``, the reward), and the same calls alone right after with the
    same clock (``alone_<name>``); best burst of each. On an environment of its own."""
    env = gym.make(TARGET_ID).unwrapped
    env.reset(seed=0)
    loop = env.loop
    a = np.zeros(env.action_space.shape, dtype=env.action_space.dtype)
    clk = time.perf_counter_ns
    acc = dict.fromkeys(IN_STEP, 0)

    def timed(key: str, f: Callable[..., Any]) -> Callable[..., Any]:
        def g(*args: Any) -> Any:
            t0 = clk()
            out = f(*args)
            acc[key] += clk() - t0
            return out
        return g

    calls = {"action": env._action, "segment": env._bound, "sample": loop.sample,
             "observe": env._observe, "reward": env.task.reward}
    env._action, env._bound, loop.sample = (timed(k, calls[k]) for k in IN_STEP[:3])
    env._observe, env.task.reward = timed("observe", calls["observe"]), timed("reward",
                                                                             calls["reward"])
    for _ in range(200):
        env.step(a)
    _, _, Ym = calls["sample"]()
    x = env.plant.state.tolist()

    def segment() -> None:
        loop._pending = (loop.k, Ym)  # as in a step: the measurement drawn by the last sample
        calls["segment"]([0.0])

    def sample() -> None:
        loop._pending = None
        calls["sample"]()

    def observe() -> None:  # as in a step: Loop.sample draws the new instant's measurement
        loop._pending = None
        calls["observe"]([0.0], None)

    alone = {"action": lambda: calls["action"](a), "segment": segment, "sample": sample,
             "observe": observe, "reward": lambda: calls["reward"](x, [0.0], ())}
    best: dict[str, float] = {}
    for _ in range(rounds):
        for k in IN_STEP:
            acc[k] = 0
        for _ in range(n):
            env.step(a)
        inside = {k: v / n * 1e-9 for k, v in acc.items()}
        for k in IN_STEP:
            best[k] = min(best.get(k, np.inf), inside[k])
            t0 = clk()
            for _ in range(n):
                alone[k]()
            best["alone_" + k] = min(best.get("alone_" + k, np.inf), (clk() - t0) / n * 1e-9)
    return best


def run(rounds: int = 200, steps: int = 200) -> dict[str, dict[str, float]]:
    envs = {k: gym.make(i, **kw) for k, (i, kw) in CONFIGS.items()}
    for e in envs.values():
        e.reset(seed=0)
        _step_burst(e, 200)  # warm up (first-step checks, compiled observer updates)
    reset = _interleaved({k: (lambda e=e: _reset_burst(e, steps // 2)) for k, e in envs.items()},
                         rounds, min)

    def per_step(e: gym.Env, k: str) -> float:
        cpu, resets = _step_burst(e, steps)
        return (cpu - resets * reset[k]) / steps

    step = _interleaved({k: (lambda e=e, k=k: per_step(e, k)) for k, e in envs.items()},
                        rounds, min)
    venvs = {}
    for k, (i, kw) in CONFIGS.items():
        venvs[k] = gym.vector.SyncVectorEnv([lambda i=i, kw=kw: gym.make(i, **kw)] * 8)
        venvs[k].reset(seed=0)
        _vector_burst(venvs[k], 50)
    vec = _interleaved({k: (lambda v=v: _vector_burst(v, steps // 8)) for k, v in venvs.items()},
                       rounds, max)
    for v in venvs.values():
        v.close()
    out = {k: {"step": step[k], "reset": reset[k], "vector": vec[k]} for k in CONFIGS}
    out["parts"] = {**_parts(rounds, steps), **{"in_" + k: v for k, v in
                                                 _in_step(rounds, steps).items()}}
    return out


VEC_N = 64
VEC_IDS = tuple(hgo_mj.envs.ENVIRONMENTS)
VEC_REFERENCE = "InvertedPendulum-v5"


def _vec_burst(venv: gym.vector.VectorEnv, n: int) -> tuple[float, float]:
    """Environment steps per CPU second (every thread of the process) and per wall second."""
    a = np.zeros(venv.action_space.shape, dtype=venv.action_space.dtype)
    c0, w0 = time.process_time(), time.perf_counter()
    for _ in range(n):
        venv.step(a)
    c1, w1 = time.process_time(), time.perf_counter()
    return n * venv.num_envs / max(c1 - c0, 1e-9), n * venv.num_envs / (w1 - w0)


class BarePhysics:
    """The physics limit of an environment at N members: ``N`` ``MjData`` of its own model,
    each advanced by its physics steps per control period (``mj_step(m, d, nstep)``), one
    after the other in this thread; ``num_envs``, ``step`` as a vector environment's."""

    def __init__(self, env_id: str, num_envs: int) -> None:
        env = gym.make(env_id).unwrapped
        self.model = env.plant.model
        self.nstep = int(round(env.control_period / env.physics_dt))
        self.num_envs = num_envs
        self.datas = [mujoco.MjData(self.model) for _ in range(num_envs)]
        self.action_space = gym.spaces.Box(-1, 1, (num_envs, self.model.nu), np.float64)
        env.close()

    def reset(self, seed: int | None = None) -> None:
        for d in self.datas:
            mujoco.mj_resetData(self.model, d)

    def step(self, actions: Any) -> None:
        m, k = self.model, self.nstep
        for d, a in zip(self.datas, actions):
            d.ctrl[:] = a
            mujoco.mj_step(m, d, k)

    def close(self) -> None:
        self.datas = []


def run_vector(rounds: int, steps: int) -> dict[str, tuple[float, float]]:
    """``{label: (steps per CPU s, steps per wall s)}`` at N = 64, interleaved, best burst."""
    venvs: dict[str, gym.vector.VectorEnv] = {
        f"{VEC_REFERENCE} SyncVectorEnv": gym.make_vec(VEC_REFERENCE, num_envs=VEC_N,
                                                       vectorization_mode="sync")}
    for env_id in VEC_IDS:
        venvs[f"{env_id} native"] = gym.make_vec(env_id, num_envs=VEC_N,
                                                 vectorization_mode="vector_entry_point")
        venvs[f"{env_id} SyncVectorEnv"] = gym.make_vec(env_id, num_envs=VEC_N,
                                                        vectorization_mode="sync")
        venvs[f"{env_id} bare mj_step"] = BarePhysics(env_id, VEC_N)  # type: ignore[assignment]
        venvs[f"{env_id} native, nthread=1"] = gym.make_vec(
            env_id, num_envs=VEC_N, vectorization_mode="vector_entry_point", nthread=1)
    n = max(2, steps // 20)
    for v in venvs.values():
        v.reset(seed=0)
        _vec_burst(v, n)  # warm up
    best: dict[str, tuple[float, float]] = {k: (0.0, 0.0) for k in venvs}
    for _ in range(rounds):
        for k, v in venvs.items():
            cpu, wall = _vec_burst(v, n)
            best[k] = (max(best[k][0], cpu), max(best[k][1], wall))
    for v in venvs.values():
        v.close()
    return best


def vector_table(res: dict[str, tuple[float, float]], rounds: int, steps: int) -> str:
    ref_cpu, ref_wall = res[f"{VEC_REFERENCE} SyncVectorEnv"]
    lines = [
        "## Native vector environment (issue 13), N = 64",
        "",
        *header(f"`python scripts/bench_envs.py --vector --rounds {rounds} --steps {steps}` "
                f"(interleaved bursts of {max(2, steps // 20)} vector steps, best of {rounds}; "
                f"steps = environment steps, all 64 members)"),
        "",
        "| environment | native steps / CPU s | SyncVectorEnv(64) steps / CPU s | native / sync "
        "(CPU) | native / sync (wall) | native / SyncVectorEnv(64) of IPv5 (CPU) | bare "
        "mj_step x64 steps / CPU s | native CPU per step / bare | native, nthread=1, steps / "
        "CPU s | native, nthread=1, CPU per step / bare |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    ok, limit = {}, {}
    for env_id in VEC_IDS:
        nc, nw = res[f"{env_id} native"]
        sc, sw = res[f"{env_id} SyncVectorEnv"]
        bc = res[f"{env_id} bare mj_step"][0]
        one = res[f"{env_id} native, nthread=1"][0]
        ok[env_id], limit[env_id] = nc / sc, bc / one
        lines.append(f"| {env_id} | {nc:,.0f} | {sc:,.0f} | {nc / sc:.1f}x | {nw / sw:.1f}x | "
                     f"{nc / ref_cpu:.2f}x | {bc:,.0f} | {bc / nc:.2f}x | {one:,.0f} | "
                     f"{bc / one:.2f}x |")
    lines += [
        f"| {VEC_REFERENCE} (Gymnasium), SyncVectorEnv(64) | | {ref_cpu:,.0f} | | | 1.00x |",
        "",
        "| target (native at N = 64 against SyncVectorEnv(64) of the same environment) | "
        "status |",
        "|---|---|",
        *(f"| {env_id}: at least 10x | {'met' if r >= 10 else 'NOT met'} ({r:.1f}x CPU) |"
          for env_id, r in ok.items()),
        "",
        "| target (issue 29: native at N = 64 against the bare batched mj_step, CPU time per "
        "step, both on one thread) | status |",
        "|---|---|",
        *(f"| {env_id}: at most 1.3x | {'met' if r <= 1.3 else 'NOT met'} ({r:.2f}x) |"
          for env_id, r in limit.items()),
    ]
    return "\n".join(lines) + "\n"


def plant_steps() -> int:
    """MuJoCo steps per sample of the registered environment (``mj_step``'s ``nstep``)."""
    env = gym.make(TARGET_ID).unwrapped
    return int(env.loop.periods.steps * env.plant.substeps)


def table(res: dict[str, dict[str, float]], rounds: int, steps: int) -> str:
    parts = res.pop("parts")
    ref = res[REFERENCE]
    tgt = res[TARGET]
    lines = [
        SECTION,
        "",
        *header(f"`python scripts/bench_envs.py --rounds {rounds} --steps {steps}` (interleaved "
                f"bursts of thread CPU time, best burst of {rounds} per figure)"),
        "",
        "| environment | step [us] | step / IPv5 | reset [us] | reset / IPv5 | "
        "SyncVectorEnv(8) steps per CPU s | vector / IPv5 |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for k, r in res.items():
        lines.append(f"| {k} | {r['step'] * 1e6:.2f} | {r['step'] / ref['step']:.2f} | "
                     f"{r['reset'] * 1e6:.2f} | {r['reset'] / ref['reset']:.2f} | "
                     f"{r['vector']:,.0f} | {r['vector'] / ref['vector']:.2f} |")
    ok = (tgt["step"] <= 0.5 * ref["step"], tgt["reset"] <= ref["reset"],
          tgt["vector"] >= ref["vector"])
    bare = res[BARE]
    us = {k: v * 1e6 for k, v in parts.items()}
    seg_rest = us["segment"] - us["plant_run"] - us["observer"]
    named = ("action", "segment", "observe", "sensor", "reward")
    rest = us["step"] - sum(us[k] for k in named)
    lines += [
        "",
        f"The loop alone (`{BARE.split(', ', 1)[1]}`) steps in {bare['step'] * 1e6:.1f} us "
        f"({bare['step'] / ref['step']:.2f}x); the sensor stage and the observer add "
        f"{(tgt['step'] - bare['step']) * 1e6:.1f} us. Where one step of the registered "
        f"environment goes (each part alone, as the environment and its loop call it, on an "
        f"environment of its own; best burst):",
        "",
        "| part | us |",
        "|---|---:|",
        f"| `env.step` without Gymnasium's wrappers | {us['step']:.2f} |",
        f"| - the action checked and scaled (`HgoEnv._action`) | {us['action']:.2f} |",
        f"| - the loop's bound step (`Loop.bind_step`: one sample; the measurement drawn "
        f"before) | {us['segment']:.2f} |",
        f"| - - the plant's bound run (`MujocoPlant.bind_run`: one sample of {plant_steps()} "
        f"physics steps) | {us['plant_run']:.2f} |",
        f"| - - - of which the bare `mj_step(m, d, {plant_steps()})` | {us['mj_step']:.2f} |",
        f"| - - the observer's bound step (`Observer._bind_step`: `_advance_block`, "
        f"`HighGainObserver._step` with the model term) | {us['observer']:.2f} |",
        f"| - - the bound step's own bookkeeping (sample time, measurement, timing) | "
        f"{seg_rest:.2f} |",
        f"| - observation and `info` (`HgoEnv._observe`: the state and clean outputs read by "
        f"`Loop.sample`, the estimate, the encoder, `info`) | {us['observe']:.2f} |",
        f"| - the sensor chain's draw for the new instant (`SensorChain._apply`, Gaussian) | "
        f"{us['sensor']:.2f} |",
        f"| - the task's reward | {us['reward']:.2f} |",
        f"| - not accounted for by the parts alone (the calls between "
        f"the parts, caches shared by the whole step) | {rest:.2f} |",
        f"| Gymnasium's wrappers (the registered step in the first table less the unwrapped "
        f"one) | {tgt['step'] * 1e6 - us['step']:.2f} |",
        "",
        "Inside a running step the same calls cost more than alone: timed with "
        "`perf_counter_ns` around each call the step makes (the timing wrapper's own call, "
        "about 0.1 us, included; `HgoEnv._observe` includes the wrapped `Loop.sample`), "
        "against the same calls alone right after with the same clock (best burst of each, "
        "us):",
        "",
        "| call | inside a step | alone | ratio |",
        "|---|---:|---:|---:|",
        *(f"| {label} | {us['in_' + k]:.2f} | {us['in_alone_' + k]:.2f} | "
          f"{us['in_' + k] / us['in_alone_' + k]:.2f} |" for k, label in (
              ("action", "the action (`HgoEnv._action`)"),
              ("segment", "the loop's bound step (`Loop.bind_step`)"),
              ("observe", "`HgoEnv._observe`, observation and `info`"),
              ("sample", "- of which `Loop.sample` (state, outputs, the sensor's draw)"),
              ("reward", "the task's reward"))),
    ]
    lines += [
        "",
        "| target (PendulumSwingUp-v0 as registered against InvertedPendulum-v5) | status |",
        "|---|---|",
        f"| step at most 0.5x | {'met' if ok[0] else 'NOT met'} "
        f"({tgt['step'] / ref['step']:.2f}x) |",
        f"| reset at most 1x | {'met' if ok[1] else 'NOT met'} "
        f"({tgt['reset'] / ref['reset']:.2f}x) |",
        f"| SyncVectorEnv of 8 at least the same steps/s | {'met' if ok[2] else 'NOT met'} "
        f"({tgt['vector'] / ref['vector']:.2f}x) |",
    ]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=200)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--write", type=Path, help="replace the bench_envs block of this markdown file")
    ap.add_argument("--vector", action="store_true",
                    help="only the native vector environment against SyncVectorEnv, N = 64")
    args = ap.parse_args(argv)
    if not args.vector:
        res = run(args.rounds, args.steps)
        text = table(res, args.rounds, args.steps)
        print(text)
        if args.write:
            write_section(args.write, "bench_envs", text)
    vtext = vector_table(run_vector(args.rounds, args.steps), args.rounds, args.steps)
    print(vtext)
    if args.write:
        write_section(args.write, "bench_envs_vector", vtext)
    return 0


if __name__ == "__main__":
    sys.exit(main())
