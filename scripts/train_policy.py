"""Train one policy (stable-baselines3 PPO) on an hgo_mj task, with checkpoints and resume.

The policies a reviewer loads (``docs/results/policies/``, evaluated by
``scripts/eval_rl.py``) come from here: one task, one agent, one seed. The agents are those of
``scripts/train_rl.py`` (``docs/results/rl_seeds.md``): the observation the policy sees is the
``true`` state, the observer's ``estimate`` or the raw ``measurement``; ``measurement+stack``
sees the last 4 measurements (Gymnasium's ``FrameStackObservation`` over single environments
in stable-baselines3's ``DummyVecEnv``), ``measurement+lstm`` the measurement through a
recurrent policy (sb3-contrib's ``RecurrentPPO``, ``MlpLstmPolicy``, with the PPO settings
below: RL Zoo's ``ppo_lstm.yml`` gives ``CartPoleNoVel-v1`` the same ones, with observation
normalisation, which is not used here). The balance tasks
(``hgo_mj/{Furuta,Acrobot,CartPole}Balance-v0``) train with RL Zoo's tuned PPO settings of
``CartPole-v1`` (``hyperparams/ppo.yml`` of rl-baselines3-zoo: 8 environments, n_steps 32,
batch 256, 20 epochs, gamma 0.98, GAE 0.8, learning rate and clip range decaying linearly
from 1e-3 and 0.2, no entropy bonus), the nearest balance task RL Zoo tunes; the
continuous action gets SB3's Gaussian policy. PPO by default: a balance task is solved
within RL Zoo's 1e5 steps by PPO, and PPO's batched rollouts use the native vector
environment (:func:`hgo_mj.envs.sb3.sb3_vec_env`, one loop at B = 8). ``--ppo-settings
mujoco`` takes the PPO paper's MuJoCo settings instead (:data:`PPO_MUJOCO`), the swing-ups':
with ``CartPole-v1``'s (32 steps per member, GAE 0.8, 20 epochs) the policy's noise
collapsed on ``CartPoleSwingUp-v1`` (log standard deviation -3 at 300k steps) with the cart
running off its track in 0.78 s.

The two tasks of ``docs/results/rl_seeds.md`` (``hgo_mj/PendulumSwingUp-v0`` and
``hgo_mj/ElasticJointReach-v0``) train with that page's PPO settings instead
(``scripts/train_rl.py``'s :data:`PPO_SETTINGS`: n_steps 256 on the 8 members, batch 512,
10 epochs, gamma 0.98, GAE 0.95, learning rate 1e-3, gSDE resampled every 4 steps, two layers
of 64; the LSTM's hidden size 64) and its budget of 409,600 steps by default, so that a
committed policy is one of the runs that page reports, not a differently tuned one.

``--algorithm SAC`` trains stable-baselines3's SAC instead (its defaults: two layers of 256,
automatic entropy coefficient, tau 0.005; with gamma 0.99, learning rate 1e-3, a buffer of
3e5, batch 256, 4000 warm-up steps and two gradient steps per step of the 8 members), on the
same vector environment: the acrobot's balance, which PPO with these settings did not learn
(its policy stays near zero torque and the elbow falls in about 2 s;
``docs/results/rl.md``). A SAC checkpoint keeps its replay buffer
(``<name>.replay.pkl``), so that a resumed run goes on with the samples it had.

Checkpoints: the model is saved every ``--checkpoint-every`` seconds (and at the end) to
``<checkpoints>/<name>.zip`` with ``<name>.json`` (steps done, training seconds so far)
and ``<name>.curve.json`` (the learning curve: steps, seconds and the mean return of the
last 100 training episodes, stable-baselines3's ``VecMonitor``, at each checkpoint); a run
started again with the same arguments loads them and trains the remaining steps, so a
stop loses at most one interval. The finished policy goes to ``<out>/<name>.zip`` with
``<name>.json`` (environment, agent, seed, algorithm and settings, steps, training seconds).
Every file is written atomically.

Usage::

    python scripts/train_policy.py --env hgo_mj/CartPoleBalance-v0 --agent estimate --seed 0
    python scripts/train_policy.py --env hgo_mj/FurutaBalance-v0 --agent true --steps 4096 \\
        --out /tmp/policies --checkpoints /tmp/ckpt                       # smoke run

Install the ``rl`` extra (stable-baselines3 and torch; on a CPU machine the CPU torch wheel).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from hgo_mj._io import atomic_path
from hgo_mj._json import write_json

ROOT = Path(__file__).resolve().parents[1]
AGENTS = ("true", "estimate", "measurement", "measurement+stack", "measurement+lstm")
#: measurements the stacked agent sees
STACK = 4
#: members of the native vector environment a policy trains on (RL Zoo's n_envs)
N_ENVS = 8
#: RL Zoo's tuned PPO for CartPole-v1 (``lin_x``: decaying linearly from x to 0)
PPO_CARTPOLE = {"n_steps": 32, "batch_size": 256, "gae_lambda": 0.8, "gamma": 0.98,
                "n_epochs": 20, "ent_coef": 0.0, "learning_rate": "lin_0.001",
                "clip_range": "lin_0.2"}
#: the PPO paper's MuJoCo settings (Schulman et al. 2017, Table 3: horizon 2048, Adam 3e-4, 10
#: epochs, minibatch 64, gamma 0.99, GAE 0.95; stable-baselines3's PPO defaults), the horizon
#: split over the :data:`N_ENVS` members: ``--ppo-settings mujoco``, the swing-ups
PPO_MUJOCO = {"n_steps": 256, "batch_size": 64, "gae_lambda": 0.95, "gamma": 0.99,
              "n_epochs": 10, "ent_coef": 0.0, "learning_rate": 3e-4, "clip_range": 0.2}
PPO_PRESETS = {"cartpole": (PPO_CARTPOLE, "rl-baselines3-zoo hyperparams/ppo.yml, CartPole-v1"),
               "mujoco": (PPO_MUJOCO, "Schulman et al. 2017 Table 3 (MuJoCo), "
                                      "stable-baselines3's PPO defaults")}
#: SAC for the acrobot's balance: stable-baselines3's defaults but these
SAC_BALANCE = {"gamma": 0.99, "learning_rate": 1e-3, "buffer_size": 300_000, "batch_size": 256,
               "learning_starts": 4000, "train_freq": 1, "gradient_steps": 2}
ALGORITHMS = ("PPO", "SAC")
#: the steps of RL Zoo's CartPole-v1 budget
DEFAULT_STEPS = 100_000
sys.path.insert(0, str(ROOT / "scripts"))
from train_rl import ENVS as RL_MD_ENVS  # noqa: E402
from train_rl import FULL, LSTM_HIDDEN, NET_ARCH, PPO_SETTINGS  # noqa: E402


def policy_name(env_id: str, agent: str, seed: int, tuned: bool = False) -> str:
    """File stem of a policy: ``FurutaBalance-v0_estimate_seed0`` (on the tuned observer
    ``FurutaBalance-v0_tuned-estimate_seed0``)."""
    return f"{env_id.split('/')[-1]}_{'tuned-' if tuned else ''}{agent}_seed{seed}"


def ppo_settings(env_id: str, agent: str,
                 preset: str = "cartpole") -> tuple[dict[str, Any], dict[str, Any], str]:
    """The PPO settings of ``env_id`` (``preset`` of :data:`PPO_PRESETS`, or
    ``docs/results/rl_seeds.md``'s for its tasks), the policy's ``policy_kwargs`` (``agent``'s LSTM
    too) and their source."""
    if env_id not in RL_MD_ENVS:
        settings, source = PPO_PRESETS[preset]
        return settings, {}, source
    kwargs: dict[str, Any] = {"net_arch": NET_ARCH}
    if agent.endswith("+lstm"):
        kwargs["lstm_hidden_size"] = LSTM_HIDDEN
    return PPO_SETTINGS, kwargs, "docs/results/rl_seeds.md (PPO_SETTINGS of scripts/train_rl.py)"


def default_steps(env_id: str) -> int:
    """The training budget of ``env_id``: RL Zoo's 1e5 of ``CartPole-v1``, or the 409,600 of
    ``docs/results/rl_seeds.md`` for its tasks."""
    return int(FULL["steps"]) if env_id in RL_MD_ENVS else DEFAULT_STEPS


def tuned_spec(env_id: str) -> dict[str, Any]:
    """The observer ``hgo-mj tune`` tuned for ``env_id`` on a balancing episode
    (``scenarios/rl_balance/<Env>.best.toml``; ``eval_rl.tuned_observer``)."""
    from eval_rl import tuned_observer

    spec = tuned_observer(env_id, ROOT / "scenarios" / "rl_balance")
    if spec is None:
        raise SystemExit(f"--tuned: no tuned observer for {env_id} (scenarios/rl_balance/"
                         f"{env_id.split('/')[-1]}.best.toml, from hgo-mj tune)")
    return spec


def _schedule(value: Any) -> Any:
    """RL Zoo's ``lin_x`` as a function of SB3's remaining progress; a number as it is."""
    if isinstance(value, str) and value.startswith("lin_"):
        start = float(value[4:])

        def linear(progress_remaining: float) -> float:
            return progress_remaining * start
        return linear
    return value


def check_args(args: argparse.Namespace) -> None:
    """Refuse bad arguments before any work, naming what was expected and found."""
    import gymnasium as gym
    import hgo_mj.envs  # noqa: F401  (registers the environments)

    if args.env not in gym.registry or not args.env.startswith("hgo_mj/"):
        raise SystemExit(f"--env must be a registered hgo_mj id; found {args.env!r}")
    if args.agent not in AGENTS:
        raise SystemExit(f"--agent must be one of {list(AGENTS)}; found {args.agent!r}")
    if args.algorithm not in ALGORITHMS:
        raise SystemExit(f"--algorithm must be one of {list(ALGORITHMS)}; found "
                         f"{args.algorithm!r}")
    if args.agent.endswith("+lstm") and args.algorithm != "PPO":
        raise SystemExit(f"--agent {args.agent} trains RecurrentPPO: --algorithm must be PPO; "
                         f"found {args.algorithm!r}")
    if args.ppo_settings not in PPO_PRESETS:
        raise SystemExit(f"--ppo-settings must be one of {list(PPO_PRESETS)}; found "
                         f"{args.ppo_settings!r}")
    if args.gamma is not None and not 0.0 < args.gamma < 1.0:
        raise SystemExit(f"--gamma must be in (0, 1); found {args.gamma}")
    if args.tuned and args.agent != "estimate":
        raise SystemExit(f"--tuned swaps the estimate's observer: --agent must be estimate; "
                         f"found {args.agent!r}")
    if args.steps < 1 or args.checkpoint_every <= 0:
        raise SystemExit(f"--steps must be >= 1 and --checkpoint-every > 0; found "
                         f"{args.steps} and {args.checkpoint_every}")


def train_env(env_id: str, agent: str, observer: dict[str, Any] | None = None) -> Any:
    """The stable-baselines3 ``VecEnv`` of :data:`N_ENVS` members an agent trains on: the
    native vector environment on the agent's observation, or (``+stack``) a ``DummyVecEnv``
    of single environments in ``FrameStackObservation``; ``observer`` instead of the
    environment's default one."""
    import gymnasium as gym
    from hgo_mj.envs.sb3 import sb3_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv

    mode = agent.split("+")[0]
    kw = {} if observer is None else {"observer": observer}
    if agent.endswith("+stack"):
        return DummyVecEnv([lambda: gym.wrappers.FrameStackObservation(
            gym.make(env_id, observation=mode, **kw), STACK)] * N_ENVS)
    return sb3_vec_env(env_id, num_envs=N_ENVS, observation=mode, nthread=1, **kw)


def _save_model(model: Any, path: Path) -> None:
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:  # SB3 would append ".zip" to a bare temporary name
            model.save(fh)


def save_policy(model: Any, path: Path) -> None:
    """Save ``model`` without its optimisers' state (Adam's two moments per parameter, two
    thirds of a PPO zip): the zip loads with ``<Algorithm>.load`` as any other (each optimiser
    keeps its settings and starts its moments afresh) and acts the same; a resumed training
    reads the checkpoint, which keeps them."""
    from torch.optim import Optimizer

    kept = [(o, o.state) for o in dict.fromkeys(
        o for holder in (model, *model.policy.modules()) for o in vars(holder).values()
        if isinstance(o, Optimizer))]
    try:
        for o, _ in kept:
            o.state = type(o.state)(dict)
        _save_model(model, path)
    finally:
        for o, state in kept:
            o.state = state


def train(args: argparse.Namespace) -> Path:
    """Train (or resume) one policy and write it to ``args.out``; returns the policy path."""
    import torch
    from sb3_contrib import RecurrentPPO
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecMonitor

    torch.set_num_threads(1)
    name = policy_name(args.env, args.agent, args.seed, args.tuned)
    observer = tuned_spec(args.env) if args.tuned else None
    ckpt, ckpt_meta = args.checkpoints / f"{name}.zip", args.checkpoints / f"{name}.json"
    curve_path = args.checkpoints / f"{name}.curve.json"
    curve = json.loads(curve_path.read_text()) if curve_path.exists() else []
    replay = args.checkpoints / f"{name}.replay.pkl"
    venv = VecMonitor(train_env(args.env, args.agent, observer))  # the episodes' returns
    venv.seed(args.seed)
    base, policy_kwargs, source = ppo_settings(args.env, args.agent, args.ppo_settings)
    if args.algorithm == "SAC":
        algo, base, policy_kwargs = SAC, SAC_BALANCE, {}
        source = "stable-baselines3 SAC defaults, SAC_BALANCE of scripts/train_policy.py"
    else:
        algo = PPO
    policy = "MlpPolicy"
    if args.agent.endswith("+lstm"):
        algo, policy = RecurrentPPO, "MlpLstmPolicy"
    done_seconds = 0.0
    if ckpt.exists() and ckpt_meta.exists():
        model = algo.load(ckpt, env=venv, device="cpu")
        if args.algorithm == "SAC" and replay.exists():
            model.load_replay_buffer(replay)
        done_seconds = float(json.loads(ckpt_meta.read_text())["train_seconds"])
        print(f"resuming {name} at {model.num_timesteps} steps", flush=True)
    else:
        settings = {k: _schedule(v) for k, v in base.items()}
        if args.gamma is not None:
            settings["gamma"] = args.gamma
        if policy_kwargs:
            settings["policy_kwargs"] = policy_kwargs
        model = algo(policy, venv, seed=args.seed, device="cpu", verbose=0, **settings)
    start = time.monotonic()

    def checkpoint() -> None:
        _save_model(model, ckpt)
        if args.algorithm == "SAC":
            with atomic_path(replay) as tmp, open(tmp, "wb") as fh:
                model.save_replay_buffer(fh)
        seconds = done_seconds + time.monotonic() - start
        write_json(ckpt_meta, {"steps": int(model.num_timesteps), "train_seconds": seconds})
        if model.ep_info_buffer:  # the learning curve: the last (up to 100) episodes' returns
            curve.append([int(model.num_timesteps), round(seconds, 1),
                          float(np.mean([e["r"] for e in model.ep_info_buffer]))])
            write_json(curve_path, curve)

    class Every(BaseCallback):  # type: ignore[misc]
        last = time.monotonic()

        def _on_step(self) -> bool:
            if time.monotonic() - self.last >= args.checkpoint_every:
                checkpoint()
                Every.last = time.monotonic()
                print(f"{name}: {model.num_timesteps} steps, mean return "
                      f"{curve[-1][2] if curve else float('nan'):.1f}", flush=True)
            return True

    args.checkpoints.mkdir(parents=True, exist_ok=True)
    remaining = args.steps - int(model.num_timesteps)
    if remaining > 0:
        model.learn(remaining, callback=Every(), reset_num_timesteps=False)
        checkpoint()
    seconds = done_seconds + time.monotonic() - start
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / f"{name}.zip"
    save_policy(model, path)
    write_json(args.out / f"{name}.json", {
        "env_id": args.env, "agent": args.agent, "seed": args.seed,
        "algorithm": algo.__name__, "observation": args.agent.split("+")[0],
        "stack": STACK if args.agent.endswith("+stack") else 0,
        **({} if observer is None else {"observer": observer}),
        "settings": {**base, "gamma": float(model.gamma), "n_envs": N_ENVS,
                     **({"policy_kwargs": policy_kwargs} if policy_kwargs else {}),
                     "source": source
                     + ("" if model.gamma == base["gamma"] else
                        f", gamma {model.gamma:g} (--gamma)")},
        "steps": int(model.num_timesteps), "train_seconds": round(seconds, 1),
        "cpu_note": f"one torch thread, nice {os.nice(0)}, on a 2-core machine shared with "
                    "other jobs"})
    venv.close()
    print(f"{name}: {model.num_timesteps} steps in {seconds:.0f} s -> {path}", flush=True)
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--env", required=True, help="registered id, e.g. hgo_mj/FurutaBalance-v0")
    ap.add_argument("--agent", default="estimate", help=f"one of {list(AGENTS)}")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", type=int, default=None,
                    help=f"default {DEFAULT_STEPS:,} (RL Zoo's CartPole-v1), {FULL['steps']:,} "
                         "for the tasks of docs/results/rl_seeds.md")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "policies")
    ap.add_argument("--checkpoints", type=Path, default=ROOT / "runs" / "rl_checkpoints")
    ap.add_argument("--checkpoint-every", type=float, default=120.0, help="seconds")
    ap.add_argument("--algorithm", default="PPO", help=f"one of {list(ALGORITHMS)}")
    ap.add_argument("--ppo-settings", default="cartpole",
                    help=f"PPO's settings, one of {list(PPO_PRESETS)} (a new run only; "
                         "rl_seeds.md's tasks take rl_seeds.md's)")
    ap.add_argument("--gamma", type=float, default=None,
                    help="discount instead of the algorithm's settings' (a new run only; a "
                         "resumed run keeps its own)")
    ap.add_argument("--tuned", action="store_true",
                    help="the estimate of the observer hgo-mj tune tuned on a balancing episode "
                         "(scenarios/rl_balance/<Env>.best.toml) instead of the default one")
    args = ap.parse_args(argv)
    if args.steps is None:
        args.steps = default_steps(args.env)
    check_args(args)
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    train(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
