"""Issue 24's environment targets, side by side: PendulumSwingUp-v0 step and reset against
InvertedPendulum-v5's, on the thread CPU clock, for one source tree per process.

Both environments as registered (``gymnasium.make``), reset in bursts and stepped (zero action,
the resets between episodes subtracted at the measured reset cost) in interleaved rounds, the
best burst of each (:func:`bench_envs._reset_burst`, :func:`bench_envs._step_burst`). With
``--tree DIR`` the package is imported from ``DIR`` (a ``git archive`` export laid out as the
wheel installs it: ``DIR/hgo_mj`` with ``envs/`` as ``hgo_mj/envs`` and ``models/`` as
``hgo_mj/models``; the editable install's finder is taken off ``sys.meta_path``), so that two
commits are measured the same way, one after the other::

    git archive fa1704a | tar -x -C /tmp/main && python scripts/bench_env_ratio.py --layout /tmp/main
    python scripts/bench_env_ratio.py --tree /tmp/main/tree --rounds 8   # one process per tree

Prints one JSON line: the microseconds per step and reset of each environment and the ratios;
with ``--parts`` the microseconds of each part of one step and reset of this code, alone.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path
from typing import Any

TARGET, REFERENCE = "hgo_mj/PendulumSwingUp-v0", "InvertedPendulum-v5"


def layout(src: Path) -> Path:
    """``src/tree/hgo_mj``: the export ``src`` laid out as the wheel installs it."""
    tree = src / "tree"
    if tree.exists():
        shutil.rmtree(tree)
    shutil.copytree(src / "hgo_mj", tree / "hgo_mj")
    shutil.copytree(src / "envs", tree / "hgo_mj" / "envs")
    shutil.copytree(src / "models", tree / "hgo_mj" / "models")
    return tree


def _use_tree(tree: Path) -> None:
    """Import ``hgo_mj`` from ``tree``, not from the editable install."""
    sys.meta_path[:] = [f for f in sys.meta_path  # the finder is a class (or an instance)
                        if "editable" not in str(getattr(f, "__module__", "")).lower()
                        and "editable" not in type(f).__module__.lower()]
    sys.path.insert(0, str(tree))


def measure(rounds: int, steps: int, resets: int) -> dict[str, float]:
    import bench_envs as B  # after the tree is on the path: it imports hgo_mj
    import gymnasium as gym
    import numpy as np

    envs = {k: gym.make(k) for k in (TARGET, REFERENCE)}
    for e in envs.values():
        e.reset(seed=0)
        B._step_burst(e, steps)  # warm: compiled kernels, caches
        B._reset_burst(e, resets)
    best: dict[str, float] = {}
    for _ in range(rounds):
        for k, e in envs.items():
            r = B._reset_burst(e, resets)
            e.reset(seed=0)
            t, n = B._step_burst(e, steps)
            s = (t - n * r) / steps
            best[f"{k} reset"] = min(best.get(f"{k} reset", np.inf), r * 1e6)
            best[f"{k} step"] = min(best.get(f"{k} step", np.inf), s * 1e6)
    return {**{k: round(v, 2) for k, v in best.items()},
            "step ratio": round(best[f"{TARGET} step"] / best[f"{REFERENCE} step"], 3),
            "reset ratio": round(best[f"{TARGET} reset"] / best[f"{REFERENCE} reset"], 3)}


def parts(repeat: int = 7, n: int = 4000) -> dict[str, float]:
    """Microseconds of the parts of one PendulumSwingUp-v0 step and reset (this tree's code:
    the bound step, the start from the first measurement) and of InvertedPendulum-v5's, each
    alone on the thread CPU clock, the best of ``repeat`` bursts of ``n`` calls."""
    import timeit

    import gymnasium as gym
    import mujoco
    import numpy as np
    from hgo_mj.envs.core import env_seed

    env = gym.make(TARGET)
    e = env.unwrapped
    env.reset(seed=0)
    a = np.zeros(1, np.float32)
    for _ in range(100):
        env.step(a)
    loop, ob, plant = e.loop, e.observer, e.plant
    ip = gym.make(REFERENCE).unwrapped
    ip.reset(seed=0)
    out: dict[str, float] = {}

    def t(name: str, f: Any, calls: int = n) -> None:
        best = min(timeit.repeat(f, number=calls, repeat=repeat, timer=time.thread_time))
        out[name] = round(best / calls * 1e6, 2)

    def ip_step() -> None:
        ip.set_state(ip.init_qpos, ip.init_qvel)
        ip.step(a)

    t("IP reset (unwrapped)", ip.reset)
    t("IP step from upright, with set_state (unwrapped)", ip_step)
    t("IP set_state", lambda: ip.set_state(ip.init_qpos, ip.init_qvel))
    t("IP mj_step x2 (its model)", lambda: mujoco.mj_step(ip.model, ip.data, 2))
    t("step (wrapped)", lambda: env.step(a))
    t("step (unwrapped)", lambda: e.step(a))
    _, Yc, Ym = loop.sample()
    U = np.zeros((1, 1, 1))
    run = plant.bind_run(np.zeros_like(U), 1, np.empty((1, 1, 2)), np.empty((1, 1, 1)))
    advance = ob._bind_step(loop.params["observer"], 1, 1, loop.periods.sample)
    st = loop.states["observer"]
    blk = advance(st, Ym, U)
    pg = loop.params["observer"].groups()[0][1]

    def bound() -> None:
        loop._pending = (loop.k, Ym)
        e._bound([0.0])

    def observe() -> None:
        loop._pending = None
        e._observe([0.0], None)

    def sample() -> None:
        loop._pending = None
        loop.sample()

    t("  bound step (plant, sensor, observer)", bound)
    t("    plant bound run", run)
    t("      mj_step x2", lambda: mujoco.mj_step(plant.model, plant.data, 2))
    t("    observer bound step", lambda: advance(st, Ym, U))
    t("      family _step (high-gain, model term)", lambda: ob._step(
        pg, st, Ym.copy(), U, 0.01, blk.x_hat, blk.z_hat, blk.diagnostics[..., :1]))
    t("        phi_batch", lambda: ob.system.phi_batch(st.z, U[:, 0]))
    t("  _observe", observe)
    t("    Loop.sample", sample)
    t("      sensor chain draw", lambda: e.sensor._apply(np.array([0.1]), Yc))
    t("    Loop.estimate", lambda: loop.estimate("observer"))
    t("    encoder", lambda: e.encoder([0.1, 0.2], (), ()))
    t("    _info", lambda: e._info(plant.state, [0.1, 0.2], [0.1], [0.1, 0.2], None))
    t("  action", lambda: e._action(a))
    x = plant.state.tolist()
    t("  reward", lambda: e.task.reward(x, [0.0], ()))
    t("reset (unwrapped)", e.reset, n // 2)
    t("  plant.reset", lambda: plant.reset(x), n // 2)
    t("  loop.reset (start from the first measurement)",
      lambda: loop.reset(x, seed=env_seed(None), start=e._start), n // 2)
    t("    Observer._start_from", lambda: ob._start_from(loop.params["observer"],
                                                         np.array([[0.1, 0.0]])), n // 2)
    t("    the start's map (measurement_start)", lambda: e._start(ob, Ym[:, 0]), n // 2)
    t("  _observe (the measurement drawn)", lambda: e._observe([0.0], 0.0), n // 2)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tree", type=Path, help="import hgo_mj from this laid-out tree")
    ap.add_argument("--layout", type=Path, help="lay out a git archive export (DIR/tree) and exit")
    ap.add_argument("--rounds", type=int, default=8)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--resets", type=int, default=50)
    ap.add_argument("--parts", action="store_true",
                    help="the parts of one step and reset instead (this tree's code)")
    args = ap.parse_args(argv)
    if args.layout is not None:
        print(layout(args.layout))
        return 0
    if args.tree is not None:
        _use_tree(args.tree)
    sys.path.insert(0, str(Path(__file__).parent))
    t0 = time.time()
    res: dict[str, Any] = parts() if args.parts else measure(args.rounds, args.steps,
                                                             args.resets)
    import hgo_mj

    res["hgo_mj"] = str(Path(hgo_mj.__file__).parent)
    res["seconds"] = round(time.time() - t0, 1)
    print(json.dumps(res))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
