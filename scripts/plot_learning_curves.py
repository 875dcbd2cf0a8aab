"""Plot the learning curves ``scripts/train_policy.py`` writes beside its checkpoints.

Each ``<name>.curve.json`` holds, at every checkpoint, ``[steps, training seconds, mean
return of the last 100 training episodes]`` (stable-baselines3's ``VecMonitor``). One panel per
environment, one line per file (its name in the legend), the environment's registered
``reward_threshold`` as a dashed line.

Usage::

    python scripts/plot_learning_curves.py docs/results/curves/*.curve.json \\
        --out docs/results/swingup_curves.png
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from hgo_mj._io import atomic_path


def read_curve(path: Path) -> list[list[float]]:
    """The ``[steps, seconds, mean return]`` rows of one curve file.

    Raises
    ------
    SystemExit
        The file is not a list of three numbers per row.
    """
    rows = json.loads(path.read_text())
    if not isinstance(rows, list) or not rows or any(
            not isinstance(r, list) or len(r) != 3 for r in rows):
        raise SystemExit(f"{path} must hold a list of [steps, seconds, mean return] rows; "
                         f"found {str(rows)[:80]!r}")
    return rows


def env_of(path: Path) -> str:
    """The registered id of a curve's policy: ``CartPoleSwingUp-v1_true_seed0.curve.json``
    is ``hgo_mj/CartPoleSwingUp-v1``."""
    return "hgo_mj/" + path.name.split("_")[0]


def plot(paths: list[Path], out: Path) -> None:
    """One panel per environment, one line per curve file, written to ``out`` (PNG)."""
    import gymnasium as gym
    import hgo_mj.envs  # noqa: F401  (registers the environments)
    from matplotlib.figure import Figure

    envs = sorted({env_of(p) for p in paths})
    fig = Figure(figsize=(4.2 * len(envs), 3.4), layout="constrained")
    axes = fig.subplots(1, len(envs), squeeze=False)[0]
    for ax, env_id in zip(axes, envs):
        for p in paths:
            if env_of(p) == env_id:
                rows = read_curve(p)
                ax.plot([r[0] for r in rows], [r[2] for r in rows], marker=".",
                        label=p.name.removesuffix(".curve.json").split("_", 1)[1])
        ax.axhline(gym.spec(env_id).reward_threshold, color="k", ls="--", lw=0.8,
                   label="reward_threshold")
        ax.set_title(env_id, fontsize=9)
        ax.set_xlabel("environment steps")
        ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 0))
        ax.set_ylabel("mean training return (last 100 episodes)")
        ax.legend(fontsize=7)
    with atomic_path(out) as tmp:
        fig.savefig(tmp, format="png", dpi=110)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("curves", type=Path, nargs="+", help="<name>.curve.json files")
    ap.add_argument("--out", type=Path, required=True, help="the PNG to write")
    args = ap.parse_args(argv)
    missing = [str(p) for p in args.curves if not p.exists()]
    if missing:
        raise SystemExit(f"curve files not found: {missing}")
    plot(args.curves, args.out)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
