"""RL on estimated state: what does acting on an observer's estimate cost an agent?

Trains Soft Actor-Critic (stable-baselines3's ``SAC``; ``--algo ppo`` for PPO) on
``hgo_mj/PendulumSwingUp-v0`` and ``hgo_mj/ElasticJointReach-v0`` with the observation
``"true"`` (true state), ``"estimate"`` (the high-gain observer's estimate from the noisy
sensor) and ``"measurement"`` (the raw sensor values), all under the same sensor noise (each
environment's default sensor chain), three seeds each. Every policy is then evaluated on every
observation mode whose entries it can be given, picked by name from the deployed mode's
observation (``env.unwrapped.observation_names``):

* a policy trained on the true state runs on the estimate, and the other way round (same
  entries);
* a policy trained on measurements runs on the true state and on the estimate by reading only
  the measured entries (the clean angle, or the observer's filtered angle);
* a policy that needs velocities cannot run on raw measurements: those cells are "n/a".

Evaluation uses the same environment seeds for every cell. The results go to
``docs/results/rl.md`` (and the raw numbers to ``docs/results/rl.json``).

Install with the ``rl`` extra (``pip install -e ".[rl]"``, which brings stable-baselines3 and
torch; on a CPU machine install ``torch`` first from the CPU wheel). The test suite does not
need it.

Usage::

    python scripts/train_rl.py                 # small default: 25k steps per run, ~12 min on 2 free cores
    python scripts/train_rl.py --full          # full: 100k steps per run, 20 evaluation episodes (~2 h)
    python scripts/train_rl.py --steps 2000 --seeds 1 --out /tmp/rl.md   # smoke run
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hgo_mj._bench import machine_line, versions_line
from hgo_mj._json import write_json
from hgo_mj.progress import track

ENVS = ("hgo_mj/PendulumSwingUp-v0", "hgo_mj/ElasticJointReach-v0")
MODES = ("true", "estimate", "measurement")
SMALL = {"steps": 25_000, "eval_episodes": 5}
FULL = {"steps": 100_000, "eval_episodes": 20}
EVAL_SEED = 10_000
ROOT = Path(__file__).resolve().parents[1]


@dataclass
class Run:
    """One training run and its evaluations."""

    env_id: str
    mode: str
    seed: int
    steps: int
    algo: str
    train_seconds: float = float("nan")
    #: CPU seconds of the worker for training and evaluation (the time on a free core)
    cpu_seconds: float = float("nan")
    #: deployed mode -> mean return over the evaluation episodes (None: n/a)
    returns: dict[str, float | None] = field(default_factory=dict)


# --------------------------------------------------------------------------- environments
def make_env(env_id: str, mode: str, seed: int | None = None) -> Any:
    """The environment of ``env_id`` with observation ``mode`` (default sensor, observer)."""
    import gymnasium as gym
    import hgo_mj.envs  # noqa: F401  (registers the environments)

    env = gym.make(env_id, observation=mode)
    if seed is not None:
        env.reset(seed=seed)
        env.action_space.seed(seed)
    return env


def selector(trained_names: Sequence[str], deployed_names: Sequence[str]) -> list[int] | None:
    """Indices of the deployed observation that give the trained policy its entries, by name;
    ``None`` if one is missing (the policy cannot run on that mode)."""
    where = {n: i for i, n in enumerate(deployed_names)}
    if not all(n in where for n in trained_names):
        return None
    return [where[n] for n in trained_names]


def evaluate(model: Any, env_id: str, trained: str, deployed: str, episodes: int
             ) -> float | None:
    """Mean return of ``model`` (trained on ``trained``) deployed on ``deployed``."""
    names = make_env(env_id, trained).unwrapped.observation_names
    env = make_env(env_id, deployed)
    idx = selector(names, env.unwrapped.observation_names)
    if idx is None:
        return None
    total = 0.0
    for ep in range(episodes):
        obs, _ = env.reset(seed=EVAL_SEED + ep)
        done = False
        while not done:
            action, _ = model.predict(obs[idx], deterministic=True)
            obs, reward, terminated, truncated, _ = env.step(action)
            total += float(reward)
            done = terminated or truncated
    return total / episodes


def train_one(run: Run, eval_episodes: int) -> Run:
    """Train one policy and evaluate it on every mode (runs in a worker process)."""
    import torch

    torch.set_num_threads(1)
    from stable_baselines3 import PPO, SAC

    cpu0 = time.process_time()
    env = make_env(run.env_id, run.mode, run.seed)
    if run.algo == "sac":
        model = SAC("MlpPolicy", env, seed=run.seed, device="cpu", verbose=0,
                    learning_starts=1000, batch_size=128, learning_rate=1e-3,
                    policy_kwargs={"net_arch": [64, 64]})
    else:
        model = PPO("MlpPolicy", env, seed=run.seed, device="cpu", verbose=0, n_steps=1024,
                    batch_size=64, policy_kwargs={"net_arch": [64, 64]})
    t0 = time.perf_counter()
    model.learn(total_timesteps=run.steps)
    run.train_seconds = time.perf_counter() - t0
    run.returns = {m: evaluate(model, run.env_id, run.mode, m, eval_episodes) for m in MODES}
    run.cpu_seconds = time.process_time() - cpu0
    return run


# --------------------------------------------------------------------------- report
def _cell(values: list[float | None]) -> str:
    vals = [v for v in values if v is not None]
    if not vals:
        return "n/a"
    return f"{np.mean(vals):.1f} ± {np.std(vals):.1f}"


def summary(runs: list[Run]) -> dict[str, dict[str, dict[str, float | None]]]:
    """``{env: {trained: {deployed: mean over seeds}}}``."""
    out: dict[str, dict[str, dict[str, float | None]]] = {}
    for env_id in dict.fromkeys(r.env_id for r in runs):
        out[env_id] = {}
        for tm in MODES:
            rs = [r for r in runs if r.env_id == env_id and r.mode == tm]
            out[env_id][tm] = {}
            for dm in MODES:
                vals = [r.returns.get(dm) for r in rs if r.returns.get(dm) is not None]
                out[env_id][tm][dm] = float(np.mean(vals)) if vals else None
    return out


def findings(runs: list[Run]) -> str:
    """Two sentences stating what the table shows, worded from the numbers."""
    s = summary(runs)
    parts, verdicts = [], []
    for env_id, tab in s.items():
        name = env_id.split("/")[1].removesuffix("-v0")
        t, e, m = (tab[k][k] for k in MODES)
        te = tab["true"]["estimate"]
        if None in (t, e, m):
            continue
        parts.append(f"on {name} the policy trained and run on the estimate returns {e:.1f}, "
                     f"against {t:.1f} on the true state and {m:.1f} on raw measurements "
                     f"(the true-state policy run on the estimate: "
                     f"{'n/a' if te is None else f'{te:.1f}'})")
        def sd(k: str, env_id: str = env_id) -> float:
            return float(np.std([r.returns[k] for r in runs if r.env_id == env_id and r.mode == k]))

        spread = max(sd("estimate"), sd("measurement"))
        if abs(t - e) <= max(sd("true"), sd("estimate")) and e > m + spread:
            verdicts.append(f"on {name} acting on the estimate costs no more than the spread "
                            f"across seeds, while raw measurements cost clearly more")
        elif e > m + spread:
            verdicts.append(f"on {name} the estimate recovers {(e - m) / (t - m):.0%} of the "
                            f"return that raw measurements lose against the true state"
                            if t > m else f"on {name} the estimate beats raw measurements")
            if te is not None and t > m and (te - e) > 0.1 * (t - m):
                verdicts[-1] += (f", and the true-state policy keeps {(te - m) / (t - m):.0%} "
                                 f"of it when run on the estimate: at this budget the estimate "
                                 f"costs more in learning than in acting")
        elif abs(e - m) <= spread:
            verdicts.append(f"on {name} the estimate and raw measurements are within the spread "
                            f"across seeds ({spread:.1f}) of each other at this budget")
        else:
            verdicts.append(f"on {name} raw measurements did better than the estimate at this "
                            f"budget")
    if not parts:
        return ""
    return ("Under the same sensor noise, " + "; ".join(parts) + ". In short, "
            + "; ".join(verdicts) + ".")


def report(runs: list[Run], args: argparse.Namespace, wall: float) -> str:
    algo = "SAC" if args.algo == "sac" else "PPO"
    cpu = float(np.nansum([r.cpu_seconds for r in runs]))
    lines = [
        "# RL on estimated state",
        "",
        f"Generated by `python scripts/train_rl.py{' --full' if args.full else ''}"
        f"{'' if args.steps is None else f' --steps {args.steps}'}` "
        f"({algo}, stable-baselines3). Do not edit by hand.",
        "",
        f"{algo} (`MlpPolicy`, two hidden layers of 64, "
        + ("learning rate 1e-3, learning starts after 1000 steps, batch 128, one gradient step "
           "per environment step" if args.algo == "sac" else "n_steps 1024, batch 64")
        + f") trained for {runs[0].steps:,} environment steps per run, {len(args.seed_list)} "
        f"seeds per cell, on each environment with `observation` = `true`, `estimate` and "
        f"`measurement`, under the environment's default sensor noise and observer. Each policy "
        f"is evaluated (deterministic actions) for {args.eval_episodes} episodes, the same "
        f"environment seeds in every cell, on every mode it can run on: a cell is the mean ± "
        f"standard deviation over seeds of the mean episode return. `n/a`: the deployed mode "
        f"lacks an entry the policy was trained on (raw measurements carry no velocity).",
        "",
    ]
    for env_id in dict.fromkeys(r.env_id for r in runs):
        rs = [r for r in runs if r.env_id == env_id]
        lines += [f"## {env_id}", "",
                  "| trained on \\ deployed on | " + " | ".join(MODES)
                  + " | train time [s] | CPU time [s] |",
                  "|---|" + "---:|" * (len(MODES) + 2)]
        for tm in MODES:
            sel = [r for r in rs if r.mode == tm]
            if not sel:
                continue
            cells = [_cell([r.returns.get(dm) for r in sel]) for dm in MODES]
            lines.append(f"| {tm} | " + " | ".join(cells)
                         + f" | {np.mean([r.train_seconds for r in sel]):.0f} | "
                         + f"{np.mean([r.cpu_seconds for r in sel]):.0f} |")
        lines.append("")
    lines += [
        "## What it shows",
        "",
        findings(runs) or "(too few cells to compare)",
        "",
        "## Settings and machine",
        "",
        f"- Small default: {SMALL['steps']:,} steps per run, {SMALL['eval_episodes']} evaluation "
        f"episodes (this run: {runs[0].steps:,} and {args.eval_episodes}); full run "
        f"(`--full`): {FULL['steps']:,} steps per run, {FULL['eval_episodes']} evaluation "
        f"episodes, same three seeds.",
        f"- {len(runs)} runs in {args.workers} worker processes (one torch thread each), "
        f"{wall / 60:.1f} min wall time in all; {cpu / 60:.1f} CPU minutes (training and "
        f"evaluation), i.e. about {cpu / 60 / max(args.workers, 1):.0f} min on "
        f"{args.workers} free cores. Train time per run is wall time (training only), CPU time "
        f"includes the evaluations.",
        f"- {machine_line()} (a shared machine: other jobs' load makes the times pessimistic, "
        "never optimistic).",
        f"- {versions_line(extra=('stable-baselines3', 'torch'))}.",
        "",
    ]
    return "\n".join(lines)


# --------------------------------------------------------------------------- main
def _run_from_json(raw: dict[str, Any]) -> Run:
    """A :class:`Run` back from ``rl.json``, which is strict JSON: a time that was ``nan``
    (not measured) is written as ``null`` and read back as ``nan``; a return of ``None``
    stays ``None`` (n/a)."""
    raw = dict(raw)
    for k in ("train_seconds", "cpu_seconds"):
        if raw.get(k) is None:
            raw[k] = float("nan")
    return Run(**raw)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--algo", choices=("sac", "ppo"), default="sac")
    ap.add_argument("--full", action="store_true", help=f"full settings: {FULL}")
    ap.add_argument("--steps", type=int, help="environment steps per run (overrides the preset)")
    ap.add_argument("--eval-episodes", type=int)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--envs", nargs="+", default=list(ENVS))
    ap.add_argument("--modes", nargs="+", default=list(MODES), choices=MODES)
    ap.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "rl.md")
    ap.add_argument("--report-from", type=Path, metavar="JSON",
                    help="rewrite the report from the raw results of an earlier run (no training)")
    ap.add_argument("--quiet", action="store_true", help="no progress on stderr")
    args = ap.parse_args(argv)
    if args.report_from is not None:
        raw = json.loads(args.report_from.read_text())
        runs = [_run_from_json(r) for r in raw["runs"]]
        for k, v in raw["args"].items():
            setattr(args, k, v)
        args.out.write_text(report(runs, args, raw["wall"]))
        print(f"wrote {args.out}")
        return 0
    try:
        import stable_baselines3  # noqa: F401
    except ImportError:
        print("stable-baselines3 is missing: pip install -e '.[rl]' (CPU torch first: "
              "pip install torch==2.13.0)", file=sys.stderr)
        return 2
    preset = FULL if args.full else SMALL
    steps = args.steps or preset["steps"]
    args.eval_episodes = args.eval_episodes or preset["eval_episodes"]
    args.seed_list = list(range(args.seeds))
    runs = [Run(e, m, s, steps, args.algo) for e in args.envs for m in args.modes
            for s in args.seed_list]
    t0 = time.perf_counter()
    done: list[Run] = []
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        futures = [pool.submit(train_one, r, args.eval_episodes) for r in runs]
        for f in track(futures, desc="train_rl", quiet=args.quiet):
            r = f.result()
            done.append(r)
            print(f"{r.env_id} {r.mode:12s} seed {r.seed}: {r.train_seconds:6.1f} s, returns "
                  + ", ".join(f"{k}={'n/a' if v is None else f'{v:.1f}'}"
                              for k, v in r.returns.items()), flush=True)
    wall = time.perf_counter() - t0
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(report(done, args, wall))
    keep = {k: getattr(args, k) for k in ("algo", "full", "steps", "eval_episodes", "seed_list",
                                           "workers")}
    write_json(args.out.with_suffix(".json"),
               {"args": keep, "wall": wall, "runs": [asdict(r) for r in done]})
    print(f"wrote {args.out} ({wall / 60:.1f} min)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
