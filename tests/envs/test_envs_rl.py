"""scripts/train_rl.py without torch: cross-mode deployment by observation names, the report."""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

import gymnasium as gym
import hgo_mj.envs  # noqa: F401

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


def test_report_table_and_findings():
    runs = []
    for mode, base in (("true", -400.0), ("estimate", -600.0), ("measurement", -1800.0)):
        for seed in range(3):
            r = train_rl.Run("hgo_mj/PendulumSwingUp-v0", mode, seed, 1000, "sac", 10.0 + seed,
                             20.0)
            r.returns = {"true": base + seed, "estimate": base - 50.0 + seed,
                         "measurement": None if mode != "measurement" else base + seed}
            runs.append(r)
    args = argparse.Namespace(algo="sac", full=False, steps=1000, eval_episodes=2,
                              seed_list=[0, 1, 2], workers=2)
    text = train_rl.report(runs, args, 60.0)
    assert "| true | -399.0 ± 0.8 | -449.0 ± 0.8 | n/a | 11 | 20 |" in text
    assert "3.0 CPU minutes" in text
    assert "returns -649.0, against -399.0 on the true state and -1799.0" in text
    assert "the estimate recovers 82% of the return" in text


def test_report_is_rewritten_from_raw_results(tmp_path):
    import json

    runs = [train_rl.Run("hgo_mj/ElasticJointReach-v0", m, 0, 500, "sac", 5.0, 6.0,
                         {"true": -10.0, "estimate": -12.0,
                          "measurement": -30.0 if m == "measurement" else None})
            for m in train_rl.MODES]
    raw = {"args": {"algo": "sac", "full": False, "steps": 500, "eval_episodes": 1,
                    "seed_list": [0], "workers": 1},
           "wall": 20.0, "runs": [vars(r) for r in runs]}
    (tmp_path / "rl.json").write_text(json.dumps(raw))
    out = tmp_path / "rl.md"
    assert train_rl.main(["--report-from", str(tmp_path / "rl.json"), "--out", str(out)]) == 0
    assert "## hgo_mj/ElasticJointReach-v0" in out.read_text()
