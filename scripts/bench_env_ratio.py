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

Prints one JSON line: the microseconds per step and reset of each environment and the ratios.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tree", type=Path, help="import hgo_mj from this laid-out tree")
    ap.add_argument("--layout", type=Path, help="lay out a git archive export (DIR/tree) and exit")
    ap.add_argument("--rounds", type=int, default=8)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--resets", type=int, default=50)
    args = ap.parse_args(argv)
    if args.layout is not None:
        print(layout(args.layout))
        return 0
    if args.tree is not None:
        _use_tree(args.tree)
    sys.path.insert(0, str(Path(__file__).parent))
    t0 = time.time()
    res = measure(args.rounds, args.steps, args.resets)
    import hgo_mj

    res["hgo_mj"] = str(Path(hgo_mj.__file__).parent)
    res["seconds"] = round(time.time() - t0, 1)
    print(json.dumps(res))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
