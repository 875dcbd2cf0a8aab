"""Animated frames of a solved episode for the environments' doc page, from the committed
policies.

For each committed policy (``docs/results/policies/<name>.zip`` with its ``<name>.json``,
``scripts/train_policy.py``) of the agents asked (default: ``estimate``, the agent on the
observer's estimate), one episode runs with deterministic actions from the first evaluation
seed of ``scripts/eval_rl.py`` (10000) with ``render_mode="rgb_array"``: the true pose, the
estimate's translucent ghost and the task's target over a floor
(:meth:`hgo_mj.envs.core.HgoEnv.render`). Every ``--every``-th frame, scaled to ``--size``
pixels, goes to an animated GIF ``<out>/<name>.gif`` shown at the episode's own speed. A
policy whose episode terminates before the time limit (not solved) writes no GIF: the page
shows solved episodes only, and the script says which it skipped.

Usage::

    python scripts/env_frames.py                       # docs/results/frames/*.gif
    python scripts/env_frames.py --every 50 --out /tmp/frames        # quick look

Install the ``rl`` extra (stable-baselines3 and torch).
"""

from __future__ import annotations

import argparse
import io
import json
import sys
from pathlib import Path

import numpy as np

from hgo_mj._io import write_bytes

ROOT = Path(__file__).resolve().parents[1]
EVAL_SEED = 10_000


def episode_frames(zip_path: Path, every: int, size: int
                   ) -> tuple[list[np.ndarray], int, bool, float]:
    """The frames of one deterministic episode of a committed policy (every ``every``-th,
    ``size`` pixels square), its steps, whether it ran to the time limit and the control
    period (s)."""
    import gymnasium as gym
    import hgo_mj.envs  # noqa: F401  (registers the environments)
    from PIL import Image
    from stable_baselines3 import PPO, SAC

    meta = json.loads(zip_path.with_suffix(".json").read_text())
    model = {"PPO": PPO, "SAC": SAC}[meta["algorithm"]].load(zip_path, device="cpu")
    env = gym.make(meta["env_id"], observation=meta["agent"], render_mode="rgb_array")
    obs, _ = env.reset(seed=EVAL_SEED)
    frames, k, terminated, truncated = [], 0, False, False
    while not (terminated or truncated):
        if k % every == 0:
            frame = Image.fromarray(env.render()).resize((size, size), Image.LANCZOS)
            frames.append(np.asarray(frame))
        action, _ = model.predict(obs, deterministic=True)
        obs, _, terminated, truncated, _ = env.step(action)
        k += 1
    env.close()
    return frames, k, not terminated, float(env.unwrapped.dt)


def gif(frames: list[np.ndarray], seconds_per_frame: float) -> bytes:
    """An animated GIF of ``frames``, looping, ``seconds_per_frame`` each."""
    from PIL import Image

    images = [Image.fromarray(f) for f in frames]
    buf = io.BytesIO()
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:], loop=0,
                   duration=round(1000 * seconds_per_frame), optimize=True)
    return buf.getvalue()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--policies", type=Path, default=ROOT / "docs" / "results" / "policies")
    ap.add_argument("--agents", nargs="+", default=["estimate"])
    ap.add_argument("--every", type=int, default=10, help="keep every N-th control step")
    ap.add_argument("--size", type=int, default=240, help="pixels (square)")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "frames")
    args = ap.parse_args(argv)
    if args.every < 1 or args.size < 16:
        raise SystemExit(f"--every must be >= 1 and --size >= 16; found {args.every} and "
                         f"{args.size}")
    zips = sorted(p for p in args.policies.glob("*.zip")
                  if json.loads(p.with_suffix(".json").read_text())["agent"] in args.agents)
    if not zips:
        raise SystemExit(f"found no policy of the agents {args.agents} in {args.policies}")
    for z in zips:
        frames, steps, solved, dt = episode_frames(z, args.every, args.size)
        if not solved:
            print(f"{z.stem}: not solved (terminated after {steps} steps): no GIF", flush=True)
            continue
        path = write_bytes(args.out / f"{z.stem}.gif", gif(frames, dt * args.every))
        print(f"{z.stem}: {len(frames)} frames -> {path}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
