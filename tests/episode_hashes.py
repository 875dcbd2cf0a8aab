"""SHA-256 of seeded episodes of every registered environment, in the variants whose step or
reset paths differ (observation modes, sensor stages, several samples per control period):
every observation, reward, flag, ``info``'s state, estimate, error and measurement, in order.

``python tests/episode_hashes.py --write tests/envs/episode_hashes.json`` records them
(with the versions they depend on); ``test_envs_seeded.py`` compares the current code against
that record, so a change meant to keep seeded episodes bit-identical is checked against the
code the record was made with (issue 24: "bit-identical seeds")."""

from __future__ import annotations

import argparse
import hashlib
import json
import platform
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import hgo_mj.envs as E  # noqa: N812
import mujoco
import numba
import numpy as np

SENSOR = [{"stage": "gaussian", "std": 0.01}, {"stage": "delay", "delay": 0.04},
          {"stage": "dropout", "p": 0.2}]
PENDULUM = "hgo_mj/PendulumSwingUp-v0"

#: name -> (env id, keyword arguments)
VARIANTS: dict[str, tuple[str, dict[str, Any]]] = {
    **{env_id: (env_id, {}) for env_id in E.ENVIRONMENTS},
    **{f"{env_id} sensor": (env_id, {"sensor": SENSOR}) for env_id in E.ENVIRONMENTS},
    **{f"{PENDULUM} {mode}": (PENDULUM, {"observation": mode})
       for mode in ("measurement", "true", "estimate+diagnostics")},
    f"{PENDULUM} no observer": (PENDULUM, {"observer": None, "observation": "true"}),
    f"{PENDULUM} model-free": (PENDULUM, {"observer_kwargs": {"k": 20.0, "model": False}}),
    f"{PENDULUM} samples": (PENDULUM, {
        "physics_dt": 0.005, "sample_period": 0.01,
        "sensor": [{"stage": "sample_hold", "period": 0.02}, {"stage": "dropout", "p": 0.3}]}),
}


def versions() -> dict[str, str]:
    """What the hashes depend on besides the code."""
    return {"numpy": np.__version__, "mujoco": mujoco.__version__, "numba": numba.__version__,
            "machine": platform.machine(), "simd": _simd()}


def _simd() -> str:
    """The widest x86 vector extension the CPU has: numpy's and numba's kernels pick their
    code paths by it, and their float results may differ in the last bit between paths."""
    try:
        flags = Path("/proc/cpuinfo").read_text().split()
    except OSError:
        return "unknown"
    return next((f for f in ("avx512f", "avx2", "sse4_2") if f in flags), "other")


def episode_hash(env_id: str, episodes: int = 3, steps: int = 60, **kw: Any) -> str:
    """SHA-256 of ``episodes`` seeded episodes of up to ``steps`` random actions (some outside
    [-1, 1]: clipped), at ``info_level="full"`` and as registered (``"basic"``)."""
    h = hashlib.sha256()
    for level in ("full", "basic"):
        env = gym.make(env_id, max_episode_steps=40, info_level=level, **kw)
        rng = np.random.default_rng(3)
        for ep in range(episodes):
            obs, info = env.reset(seed=ep if ep < 2 else None)
            h.update(obs.tobytes())
            _info(h, info)
            for _ in range(steps):
                a = rng.uniform(-1.2, 1.2, env.action_space.shape).astype(np.float32)
                obs, r, te, tr, info = env.step(a)
                h.update(obs.tobytes())
                h.update(repr((float(r), bool(te), bool(tr))).encode())
                _info(h, info)
                if te or tr:
                    break
        env.close()
    return h.hexdigest()


def _info(h: Any, info: dict[str, Any]) -> None:
    for k in sorted(info):
        v = info[k]
        h.update(k.encode())
        h.update(v.tobytes() if isinstance(v, np.ndarray) else repr(v).encode())


def hashes() -> dict[str, str]:
    return {name: episode_hash(env_id, **kw) for name, (env_id, kw) in VARIANTS.items()}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", type=Path, help="write the record (JSON) here")
    args = ap.parse_args(argv)
    record = {"versions": versions(), "hashes": hashes()}
    text = json.dumps(record, indent=1, sort_keys=True) + "\n"
    if args.write is None:
        sys.stdout.write(text)
    else:
        tmp = args.write.with_suffix(".tmp")
        tmp.write_text(text)
        tmp.replace(args.write)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
