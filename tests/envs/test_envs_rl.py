"""scripts/train_rl.py without torch: cross-mode deployment by observation names, the solved
criterion, the report and its learning-curve figure (the stable-baselines3 step over the
native vector environment is tests/envs/test_sb3.py's)."""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

import gymnasium as gym
import hgo_mj.envs  # noqa: F401
import numpy as np

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "train_rl.py"
spec = importlib.util.spec_from_file_location("train_rl", SCRIPT)
train_rl = importlib.util.module_from_spec(spec)
sys.modules["train_rl"] = train_rl  # dataclasses look their module up
spec.loader.exec_module(train_rl)


def _names(env_id: str, mode: str) -> tuple[str, ...]:
    return gym.make(env_id, observation=mode).unwrapped.observation_names


def test_policies_are_deployed_where_their_entries_exist():
    for env_id in train_rl.ENVS:
        true, est, meas = (_names(env_id, m) for m in train_rl.MODES)
        assert train_rl.selector(true, est) == list(range(len(true)))
        assert train_rl.selector(est, meas) is None  # no velocity in a raw measurement
        idx = train_rl.selector(meas, true)
        assert [true[i] for i in idx] == list(meas)


def _runs(env_id: str = "hgo_mj/PendulumSwingUp-v0") -> list:
    base = {"true": -400.0, "estimate": -600.0, "measurement": -1800.0,
            "measurement+stack": -1000.0, "measurement+lstm": -1200.0}
    runs = []
    for agent, b in base.items():
        for seed in range(3):
            r = train_rl.Run(env_id, agent, seed, 1000, "ppo", 10.0 + seed, 20.0)
            r.returns = {m: None for m in train_rl.MODES}
            r.returns[train_rl.base_mode(agent)] = b + seed
            if agent in ("true", "estimate"):
                r.returns["true" if agent == "estimate" else "estimate"] = b - 50.0 + seed
            r.solved = 1.0 if agent == "true" else 0.0
            r.curve = [[500.0, b - 300.0 + seed], [1000.0, b + seed]]
            runs.append(r)
    return runs


def test_report_table_and_findings(tmp_path):
    runs = _runs()
    args = argparse.Namespace(full=False, steps=1000, eval_episodes=2, seed_list=[0, 1, 2],
                              workers=2)
    text = train_rl.report(runs, args, 60.0)
    assert "**Budget: small** (1,000 environment steps per run; the small default" in text
    assert "| true | -399.0 ± 0.8 | 100% | -399.0 ± 0.8 | -449.0 ± 0.8 | n/a | 11 | 20 |" in text
    assert "| measurement+lstm | -1199.0 ± 0.8 | 0% | - | - | -1199.0 ± 0.8 | 11 | 20 |" in text
    assert "5.0 CPU minutes" in text
    # full run estimated from the CPU time per step: 15 runs x 20 s x (409600 / 1000) / 2 cores
    assert f"about {15 * 20 * 409.6 / 60 / 2:.0f} min on 2 free cores (not run here)" in text
    assert ("on PendulumSwingUp the agents rank true (-399.0, 100% solved), estimate (-599.0, "
            "0% solved), measurement+stack (-999.0, 0% solved)") in text
    # gap closed: (agent - measurement) / (true - measurement)
    assert "estimate 86%, measurement+stack 57%, measurement+lstm 43%" in text
    png = train_rl.figure(runs, tmp_path / "curves.png")
    assert png.stat().st_size > 10_000


def test_solved_criterion():
    up = [[np.pi + 0.1, 0.0]] * 10
    assert train_rl.solved("hgo_mj/PendulumSwingUp-v0", [[0.0, 0.0]] * 10 + up, ())
    assert not train_rl.solved("hgo_mj/PendulumSwingUp-v0", up + [[0.0, 0.0]] * 10, ())
    assert train_rl.solved("hgo_mj/ElasticJointReach-v0", [[0.5, 0, 0, 0]] * 4, (0.49,))
    assert not train_rl.solved("hgo_mj/ElasticJointReach-v0", [[0.5, 0, 0, 0]] * 4, (0.4,))
    # the Furuta pendulum: its task's target coordinate (the pendulum, x[1]) at pi, wrapped;
    # the arm's angle is free
    up = [[5.0, -np.pi + 0.2, 0.0, 0.0]] * 4
    assert train_rl.solved("hgo_mj/FurutaSwingUp-v0", [[0.0] * 4] * 4 + up, ())
    assert not train_rl.solved("hgo_mj/FurutaSwingUp-v0", [[np.pi, 0.0, 0.0, 0.0]] * 8, ())


def test_report_is_rewritten_from_raw_results(tmp_path):
    import json

    runs = _runs("hgo_mj/ElasticJointReach-v0")
    raw = {"args": {"full": False, "steps": 1000, "eval_episodes": 1, "seed_list": [0, 1, 2],
                    "workers": 1},
           "wall": 20.0, "runs": [vars(r) for r in runs]}
    (tmp_path / "rl.json").write_text(json.dumps(raw))
    out = tmp_path / "rl_seeds.md"
    assert train_rl.main(["--report-from", str(tmp_path / "rl.json"), "--out", str(out)]) == 0
    assert "## hgo_mj/ElasticJointReach-v0" in out.read_text()
    assert (tmp_path / "rl_seeds_curves.png").stat().st_size > 10_000
