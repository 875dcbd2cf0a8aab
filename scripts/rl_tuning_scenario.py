"""A tuning scenario of a balance task from one episode of its committed true-state policy.

``hgo-mj tune`` tunes an observer on an open-loop scenario, and the open-loop run of a balance
task is a fall: gains tuned on it fit a motion the balancing policy never produces. This script
records a balancing episode instead: a committed policy of the environment
(``docs/results/policies/<Env>_<agent>_seed0.zip``; by default the ``estimate`` agent on the
default observer) runs one episode with deterministic actions from the reset seeded ``--seed``
(default :data:`EVAL_SEED`, the first episode of ``scripts/eval_rl.py``), and the scenario
replays it open loop. The estimate agent's episode, not the true-state agent's: the motion an
observer sees under the estimate agent is what the tuning should fit, and it differs. The
true-state agent holds the Furuta pendulum within an encoder count or so, and on its episode
the tuner raised the pendulum chain's gain to about 2700 (against the default 40), which in the
estimate agent's loop amplified the encoder's steps into the actions and raised the pendulum
velocity's RMS error 59-fold (``docs/results/rl.md``). MuJoCo is deterministic, so
the environment's plant, started from the episode's initial state with the recorded inputs
``u = action * max_action`` held over each control period (a ``schedule`` input switching
half a control period before each control instant, so that no instant sits on a switching
time), reproduces the balancing trajectory; :func:`replay_error` checks it against the
episode's true states. The scenario has the environment's plant (its MJCF, outputs, sample
and physics periods), sensor chain and default observer (label ``default``, the task's
parameters), so ``hgo-mj tune scenarios/rl_balance/<Env>.toml --observer default`` tunes the
environment's observer on the states a balancing policy sees. The same for
``hgo_mj/ElasticJointReach-v0`` (a registered plant, ``[plant] name``): an episode of its
estimate agent bringing the link to its target, and for ``hgo_mj/CartPoleSwingUp-v1`` (the
cart-pole's MJCF, its own integrator): an episode of its estimate agent swinging the pole up
and balancing it. Not ``hgo_mj/PendulumSwingUp-v0``: its
environment steps MuJoCo with the Euler integrator instead of its MJCF's, which a scenario's
``[plant]`` cannot set, so the replay would not be its episode (it differed by 8.5 rad).
Where ``eval_rl.TUNED`` names another observer for the environment (ElasticJointReach's
extended Kalman filter), the scenario carries it too, and ``hgo-mj tune ... --observer ekf``
tunes it.

Usage::

    python scripts/rl_tuning_scenario.py                 # the solved balance tasks
    python scripts/rl_tuning_scenario.py --env hgo_mj/CartPoleBalance-v0 --out /tmp/sc

Install the ``rl`` extra (stable-baselines3 and torch).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hgo_mj._io import write_text

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
from eval_rl import EVAL_SEED, TUNED, load  # noqa: E402

ENVS = ("hgo_mj/CartPoleBalance-v0", "hgo_mj/FurutaBalance-v0",
        "hgo_mj/AcrobotBalance-v1", "hgo_mj/ElasticJointReach-v0",
        "hgo_mj/CartPoleSwingUp-v1")
#: the observer's label in the scenario (``hgo-mj tune --observer default``)
LABEL = "default"


@dataclass
class Episode:
    """One recorded episode: the true states (``(T + 1, n)``, the start first) and the plant
    inputs held over each of the ``T`` control periods (``(T, m)``)."""

    x: np.ndarray
    u: np.ndarray


def record(env_id: str, seed: int, policies: Path, agent: str = "estimate"
           ) -> tuple[Any, Episode]:
    """Run the committed ``agent`` policy (``true`` or ``estimate``, on the default observer)
    of ``env_id`` for one deterministic episode from the reset seeded ``seed``; returns the
    (closed) environment and the episode."""
    import json

    import gymnasium as gym
    import hgo_mj.envs  # noqa: F401  (registers the environments)

    zip_path = policies / f"{env_id.split('/')[-1]}_{agent}_seed0.zip"
    if not zip_path.exists():
        raise SystemExit(f"no committed {agent} policy for {env_id}: {zip_path} is missing")
    model = load(zip_path, json.loads(zip_path.with_suffix(".json").read_text()))
    env = gym.make(env_id, observation=agent)
    obs, info = env.reset(seed=seed)
    xs, us = [info["state"]], []
    terminated = truncated = False
    scale = np.asarray(env.unwrapped.task.max_action, dtype=float)
    while not (terminated or truncated):
        action, _ = model.predict(obs, deterministic=True)
        obs, _, terminated, truncated, info = env.step(action)
        us.append(np.clip(np.asarray(action, dtype=float), -1.0, 1.0) * scale)
        xs.append(info["state"])
    env.close()
    return env, Episode(np.array(xs, dtype=float), np.array(us, dtype=float))


def scenario(env: Any, episode: Episode) -> dict[str, Any]:
    """The tuning scenario replaying ``episode`` on ``env``'s plant, sensor and observer."""
    u, env_id = env.unwrapped, env.spec.id  # the registered id (a variant's, not its base's)
    tc, ts = u.control_period, u.sample_period
    T = len(episode.u)
    times = [0.0] + [(j - 0.5) * tc for j in range(1, T)]
    spec = u._observer_spec
    plant = ({"model": f"models/{u.task.plant}", "outputs": list(u.output_names)}
             if u.task.plant.endswith(".xml") else {"name": u.task.plant})  # a registered one
    return {
        "name": f"{env_id.split('/')[-1]}_balance",
        "plant": {**plant, "dt": ts, "physics_dt": u.physics_dt, "x0": episode.x[0].tolist()},
        "sensor": {"stages": u.sensor.describe()},
        "observers": [{"name": LABEL, **spec}, *([TUNED[env_id]] if env_id in TUNED
                                                 else [])],
        "input": {"type": "schedule", "times": times, "values": episode.u.tolist()},
        "run": {"duration": T * tc, "sample_period": ts, "control_period": tc, "seed": 0},
    }


def replay(sc: dict[str, Any]) -> Any:
    """``simulate`` of the scenario (the plant replaying the recorded inputs)."""
    from hgo_mj.scenario import scenario_run
    from hgo_mj.simulate import simulate

    kw = scenario_run(sc)
    return simulate(kw.pop("plant"), kw.pop("sensor"), kw.pop("observers"), kw.pop("inputs"),
                    kw.pop("duration"), **{k: v for k, v in kw.items() if k != "metadata"})


def replay_error(sc: dict[str, Any], episode: Episode) -> float:
    """The largest difference between the replayed states at the control instants and the
    episode's true states."""
    tr = replay(sc)
    step = round(sc["run"]["control_period"] / sc["run"]["sample_period"])
    x = tr.x[::step]
    if x.shape != episode.x.shape:
        raise RuntimeError(f"the replay has {x.shape} states at the control instants; the "
                           f"episode {episode.x.shape}")
    return float(np.max(np.abs(x - episode.x)))


def main(argv: list[str] | None = None) -> int:
    from hgo_mj.tune.tuner import best_toml

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--env", action="append", choices=ENVS, help="default: all of ENVS")
    ap.add_argument("--seed", type=int, default=EVAL_SEED, help="the episode's reset seed")
    ap.add_argument("--agent", choices=("true", "estimate"), default="estimate",
                    help="the committed policy that balances (default: the estimate agent on "
                         "the default observer)")
    ap.add_argument("--policies", type=Path, default=ROOT / "docs" / "results" / "policies")
    ap.add_argument("--out", type=Path, default=ROOT / "scenarios" / "rl_balance")
    args = ap.parse_args(argv)
    for env_id in args.env or ENVS:
        env, episode = record(env_id, args.seed, args.policies, args.agent)
        sc = scenario(env, episode)
        err = replay_error(sc, episode)
        if err > 1e-12:
            raise SystemExit(f"{env_id}: the replay differs from the episode by {err:.3g}")
        path = args.out / f"{env_id.split('/')[-1]}.toml"
        head = (f"# {env_id}: one episode of its committed {args.agent} policy (reset seed "
                f"{args.seed}, {len(episode.u)} steps),\n# replayed open loop; written by "
                f"scripts/rl_tuning_scenario.py (the replay's largest state error {err:.3g}).\n"
                f"#   hgo-mj tune {path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}"
                f" --observer {TUNED.get(env_id, {'name': LABEL})['name']}\n")
        write_text(path, head + best_toml(sc, LABEL, {}))
        print(f"{path}: {len(episode.u)} steps, replay error {err:.3g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
