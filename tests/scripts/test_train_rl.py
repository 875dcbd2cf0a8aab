"""scripts/train_rl.py's report from raw results (no training: stable-baselines3 is an extra
the test suite does not need): the table, the generated sentences and the learning curves."""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "train_rl.py"


def _load():
    spec = importlib.util.spec_from_file_location("train_rl", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    sys.modules["train_rl"] = mod  # its dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def test_report_and_findings_from_raw_runs(tmp_path):
    rl = _load()
    own = {"true": -300.0, "estimate": -310.0, "measurement": -1800.0,
           "measurement+stack": -1800.0, "measurement+lstm": -1000.0}
    runs = []
    for agent, ret in own.items():
        for seed in range(2):
            r = rl.Run("hgo_mj/PendulumSwingUp-v0", agent, seed, 1000, "ppo", 1.0, 1.0)
            r.returns = {m: (ret if m == rl.base_mode(agent) else None) for m in rl.MODES}
            r.solved = 1.0 if ret > -400 else 0.0
            r.curve = [[500.0, ret - 100.0], [1000.0, ret]]
            runs.append(r)
    text = rl.findings(runs)
    assert "on PendulumSwingUp the agents rank true (-300.0, 100% solved), estimate" in text
    assert "On PendulumSwingUp the share of the gap" in text  # not lowercased
    assert "estimate 99%, measurement+stack 0%, measurement+lstm 53%" in text
    assert "-0%" not in text
    args = argparse.Namespace(full=False, steps=1000, seed_list=[0, 1], eval_episodes=2,
                              workers=2)
    page = rl.report(runs, args, 60.0)
    assert "| measurement+lstm | -1000.0 ± 0.0 | 0% |" in page
    assert rl.figure(runs, tmp_path / "c.png").stat().st_size > 10_000


def test_without_the_rl_extra_one_line_names_it(tmp_path, monkeypatch, capsys):
    rl = _load()
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)
    assert rl.main(["--out", str(tmp_path / "rl_seeds.md")]) == 2
    err = capsys.readouterr().err
    assert err == ("scripts/train_rl.py needs the optional dependency stable_baselines3: "
                   "pip install 'hgo_mj[rl]' (CPU torch first: pip install torch==2.13.0)\n")
    assert not (tmp_path / "rl_seeds.md").exists()
