"""scripts/eval_rl.py without stable-baselines3: the solved criterion, the table and the
refusals; with it (skipped otherwise), scripts/train_policy.py trains, stops, resumes and
eval_rl.py evaluates what it wrote."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import gymnasium as gym
import hgo_mj.envs  # noqa: F401
import pytest

SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"


def _load(name: str):
    spec = importlib.util.spec_from_file_location(name, SCRIPTS / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # its dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def test_solved_is_balanced_to_the_time_limit():
    ev = _load("eval_rl")
    env = gym.make("hgo_mj/CartPoleBalance-v0")
    assert ev.episode_solved(env, False, 500)
    assert not ev.episode_solved(env, True, 500)
    assert not ev.episode_solved(env, False, 499)
    with pytest.raises(SystemExit, match="found Reach2LinkTask"):
        ev.episode_solved(gym.make("hgo_mj/ElasticJoint2LinkReach-v0"), False, 250)


def test_solved_reach_holds_the_link_near_its_target_over_the_last_half():
    """rl_seeds.md's criterion on ElasticJointReach: the link within 0.05 rad of the target at
    every step of the episode's last half, whatever the first half did."""
    ev = _load("eval_rl")
    env = gym.make("hgo_mj/ElasticJointReach-v0")
    env.reset(seed=0)
    goal = env.unwrapped._goal[0]
    near, far = [[goal - 0.049, 0.0, 0.0, 0.0]], [[goal + 0.051, 0.0, 0.0, 0.0]]
    assert ev.episode_solved(env, False, 9, states=far * 5 + near * 5)
    assert not ev.episode_solved(env, False, 9, states=far * 4 + near + far + near * 4)


def test_a_lab_swing_up_is_solved_when_its_last_second_is_upright():
    ev = _load("eval_rl")
    env = gym.make("hgo_mj/CartPoleSwingUp-v1")
    assert ev.episode_solved(env, False, 500, 100)
    assert not ev.episode_solved(env, False, 500, 99)
    assert not ev.episode_solved(env, True, 500, 100)
    assert not ev.episode_solved(env, False, 499, 100)


def test_table_and_refusals(tmp_path):
    ev = _load("eval_rl")
    rows = [ev.Row("x", "hgo_mj/CartPoleBalance-v0", "estimate", 0, 100_000, 80.4,
                   [500.0, 300.0], [True, False])]
    assert ("| hgo_mj/CartPoleBalance-v0 | estimate | PPO | 0 | 0.98 | 100,000 | 80 | "
            "400.0 ± 100.0 | 50% | - |" in ev.table(rows))
    rows[0].error_rms = {"pole_angle": 1e-3, "pole_velocity": 2e-2}
    rows[0].on_tuned = ev.Run([500.0] * 2, [True, True], {"pole_angle": 5e-4,
                                                         "pole_velocity": 0.2})
    assert "400.0 ± 100.0 | 50% | 100% |" in ev.table(rows)
    assert ("| hgo_mj/CartPoleBalance-v0 | estimate | tuned | pole_angle 5.00e-04, "
            "pole_velocity 2.00e-01 |") in ev.error_table(rows)
    assert "tuned / default RMS error pole_angle 0.5x, pole_velocity 10x." in \
        ev.tuned_findings(rows)
    assert "Machine:" in ev.report(rows, 2, 3.0)
    rows.append(ev.Row("y", "hgo_mj/CartPoleBalance-v0", "true", 0, 100_000, 50.0,
                       [500.0, 500.0], [True, True]))
    assert ("- hgo_mj/CartPoleBalance-v0: estimate 50%, true 100%; the estimate agent solves "
            "50% as many episodes as the true-state agent (target 90%: not met).") in \
        ev.findings(rows)
    rows.append(ev.Row("z", "hgo_mj/CartPoleBalance-v0", "tuned estimate", 0, 100_000, 50.0,
                       [500.0, 500.0], [True, True]))
    assert ("the tuned estimate agent solves 100% as many episodes as the true-state agent "
            "(target 90%: met).") in ev.findings(rows)
    rows[1].solved = [False, False]
    assert "the true-state agent solves none" in ev.findings(rows)
    assert "tuned estimate agent solves" not in ev.findings(rows)
    with pytest.raises(SystemExit, match="found 0 zip"):
        ev.main(["--policies", str(tmp_path)])
    (tmp_path / "a.zip").write_bytes(b"")
    with pytest.raises(SystemExit, match=r"without json: \['a.zip'\]"):
        ev.main(["--policies", str(tmp_path)])
    with pytest.raises(SystemExit, match="--episodes must be >= 1; found 0"):
        ev.main(["--episodes", "0"])


def test_tuned_observer_is_the_tunings_best(tmp_path):
    ev = _load("eval_rl")
    assert ev.tuned_observer("hgo_mj/CartPoleBalance-v0", tmp_path) is None
    path = tmp_path / "CartPoleBalance-v0.best.toml"
    path.write_text('[[observers]]\nname = "default"\ntype = "high_gain_multi"\n'
                    'k = [12.5, 40.0]\nmodel = true\n')
    spec = ev.tuned_observer("hgo_mj/CartPoleBalance-v0", tmp_path)
    assert spec == {"type": "high_gain_multi", "k": [12.5, 40.0], "model": True}
    env = gym.make("hgo_mj/CartPoleBalance-v0", observer=spec)
    assert env.unwrapped.observer.params()["k"] == [12.5, 40.0]
    path.write_text('[[observers]]\nname = "other"\ntype = "high_gain_multi"\n')
    with pytest.raises(SystemExit, match="one observer named 'default'"):
        ev.tuned_observer("hgo_mj/CartPoleBalance-v0", tmp_path)
    # ElasticJointReach: the extended Kalman filter beside the default is the tuned one
    (tmp_path / "ElasticJointReach-v0.best.toml").write_text(
        '[[observers]]\nname = "default"\ntype = "high_gain"\nk = 80.0\n\n'
        '[[observers]]\nname = "ekf"\ntype = "ekf"\nQ = 1e-5\n')
    spec = ev.tuned_observer("hgo_mj/ElasticJointReach-v0", tmp_path)
    assert spec == {"type": "ekf", "Q": 1e-5}
    env = gym.make("hgo_mj/ElasticJointReach-v0", observer=spec)
    assert type(env.unwrapped.observer).__name__ == "ExtendedKalmanFilter"


def test_train_policy_refuses_bad_arguments():
    tp = _load("train_policy")
    with pytest.raises(SystemExit, match="--agent must be one of"):
        tp.main(["--env", "hgo_mj/CartPoleBalance-v0", "--agent", "lstm"])
    with pytest.raises(SystemExit, match="registered hgo_mj id; found 'CartPole-v1'"):
        tp.main(["--env", "CartPole-v1"])
    with pytest.raises(SystemExit, match=r"--gamma must be in \(0, 1\); found 1.5"):
        tp.main(["--env", "hgo_mj/CartPoleBalance-v0", "--gamma", "1.5"])
    with pytest.raises(SystemExit, match="--tuned swaps the estimate's observer"):
        tp.main(["--env", "hgo_mj/CartPoleBalance-v0", "--agent", "true", "--tuned"])
    with pytest.raises(SystemExit, match="--steps must be >= 1"):
        tp.main(["--env", "hgo_mj/CartPoleBalance-v0", "--steps", "0"])
    with pytest.raises(SystemExit, match=r"--algorithm must be one of \['PPO', 'SAC'\]; found "
                                         r"'TD3'"):
        tp.main(["--env", "hgo_mj/CartPoleBalance-v0", "--algorithm", "TD3"])
    with pytest.raises(SystemExit, match=r"--ppo-settings must be one of \['cartpole', "
                                         r"'mujoco'\]; found 'atari'"):
        tp.main(["--env", "hgo_mj/CartPoleBalance-v0", "--ppo-settings", "atari"])
    with pytest.raises(SystemExit, match="trains RecurrentPPO: --algorithm must be PPO"):
        tp.main(["--env", "hgo_mj/CartPoleBalance-v0", "--agent", "measurement+lstm",
                 "--algorithm", "SAC"])


def test_train_stop_resume_and_evaluate(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    tp, ev = _load("train_policy"), _load("eval_rl")
    args = ["--env", "hgo_mj/CartPoleBalance-v0", "--agent", "true", "--out",
            str(tmp_path / "pol"), "--checkpoints", str(tmp_path / "ck")]
    assert tp.main([*args, "--steps", "256"]) == 0
    ck = json.loads((tmp_path / "ck" / "CartPoleBalance-v0_true_seed0.json").read_text())
    assert ck["steps"] == 256
    assert tp.main([*args, "--steps", "512"]) == 0  # resumes from the checkpoint
    assert "resuming CartPoleBalance-v0_true_seed0 at 256 steps" in capsys.readouterr().out
    meta = json.loads((tmp_path / "pol" / "CartPoleBalance-v0_true_seed0.json").read_text())
    assert meta["steps"] == 512 and meta["algorithm"] == "PPO"
    assert meta["settings"]["gamma"] == 0.98
    assert tp.main(["--env", "hgo_mj/CartPoleBalance-v0", "--agent", "estimate", "--steps", "256",
                    "--gamma", "0.99", "--out", str(tmp_path / "g"), "--checkpoints",
                    str(tmp_path / "ckg")]) == 0
    meta = json.loads((tmp_path / "g" / "CartPoleBalance-v0_estimate_seed0.json").read_text())
    assert meta["settings"]["gamma"] == 0.99 and "gamma 0.99 (--gamma)" in \
        meta["settings"]["source"]
    out = tmp_path / "rl.md"
    assert ev.main(["--policies", str(tmp_path / "pol"), "--episodes", "1", "--write",
                    str(out)]) == 0
    assert "| hgo_mj/CartPoleBalance-v0 | true | PPO | 0 | 0.98 | 512 |" in out.read_text()


def test_sac_keeps_its_replay_buffer_across_a_resume(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    tp, ev = _load("train_policy"), _load("eval_rl")
    args = ["--env", "hgo_mj/AcrobotBalance-v0", "--agent", "estimate", "--algorithm", "SAC",
            "--out", str(tmp_path / "pol"), "--checkpoints", str(tmp_path / "ck")]
    assert tp.main([*args, "--steps", "64"]) == 0
    assert (tmp_path / "ck" / "AcrobotBalance-v0_estimate_seed0.replay.pkl").exists()
    assert tp.main([*args, "--steps", "128"]) == 0
    out = capsys.readouterr().out
    assert "resuming AcrobotBalance-v0_estimate_seed0 at 64 steps" in out
    from stable_baselines3 import SAC

    model = SAC.load(tmp_path / "ck" / "AcrobotBalance-v0_estimate_seed0.zip")
    model.load_replay_buffer(tmp_path / "ck" / "AcrobotBalance-v0_estimate_seed0.replay.pkl")
    assert model.replay_buffer.size() == 128 // 8  # every step's 8 members, both sessions
    meta = json.loads((tmp_path / "pol" / "AcrobotBalance-v0_estimate_seed0.json").read_text())
    assert meta["algorithm"] == "SAC" and meta["settings"]["gradient_steps"] == 2
    row = ev.evaluate(tmp_path / "pol" / "AcrobotBalance-v0_estimate_seed0.zip", 1)
    assert row.algorithm == "SAC" and len(row.returns) == 1


@pytest.mark.parametrize("agent,algorithm,stack,shape", [
    ("measurement", "PPO", 0, (3,)), ("measurement+stack", "PPO", 4, (4, 3)),
    ("measurement+lstm", "RecurrentPPO", 0, (3,))])
def test_measurement_agents_train_and_evaluate_on_their_own_observation(
        tmp_path, agent, algorithm, stack, shape):
    """The raw-measurement agents of rl_seeds.md: the cart-pole's two encoders (the position, the
    angle as cosine and sine), stacked 4 deep, or through an LSTM (its state carried through
    the evaluation episode)."""
    pytest.importorskip("sb3_contrib")
    tp, ev = _load("train_policy"), _load("eval_rl")
    assert tp.main(["--env", "hgo_mj/CartPoleBalance-v0", "--agent", agent, "--steps", "256",
                    "--out", str(tmp_path), "--checkpoints", str(tmp_path / "ck")]) == 0
    name = f"CartPoleBalance-v0_{agent}_seed0"
    meta = json.loads((tmp_path / f"{name}.json").read_text())
    assert (meta["algorithm"], meta["observation"], meta["stack"]) == (
        algorithm, "measurement", stack)
    model = ev.load(tmp_path / f"{name}.zip", meta)
    assert model.observation_space.shape == shape
    row = ev.evaluate(tmp_path / f"{name}.zip", 1)
    assert (row.agent, row.algorithm, len(row.returns)) == (agent, algorithm, 1)


def test_train_and_evaluate_on_the_tuned_observer(tmp_path):
    pytest.importorskip("stable_baselines3")
    tp, ev = _load("train_policy"), _load("eval_rl")
    assert tp.main(["--env", "hgo_mj/CartPoleBalance-v0", "--tuned", "--steps", "256", "--out",
                    str(tmp_path / "pol"), "--checkpoints", str(tmp_path / "ck")]) == 0
    zip_path = tmp_path / "pol" / "CartPoleBalance-v0_tuned-estimate_seed0.zip"
    meta = json.loads(zip_path.with_suffix(".json").read_text())
    tuned = ev.tuned_observer("hgo_mj/CartPoleBalance-v0", ev.ROOT / "scenarios" / "rl_balance")
    assert meta["observer"] == tuned and meta["agent"] == "estimate"
    row = ev.evaluate(zip_path, 1)
    assert row.agent == "tuned estimate" and row.on_tuned is None
    assert set(row.error_rms) == {"cart_position", "cart_velocity", "pole_angle",
                                  "pole_velocity"}


def test_rl_md_tasks_train_with_its_settings_and_save_small_policies(tmp_path):
    """ElasticJointReach trains with rl_seeds.md's PPO (gSDE, two layers of 64, the LSTM's 64) and
    budget; the committed zip drops the optimiser's moments, loads and acts as the
    checkpoint."""
    pytest.importorskip("sb3_contrib")
    import numpy as np

    tp, ev = _load("train_policy"), _load("eval_rl")
    env_id = "hgo_mj/ElasticJointReach-v0"
    assert (tp.default_steps(env_id), tp.default_steps("hgo_mj/CartPoleBalance-v0")) == (
        409_600, 100_000)
    for agent in ("true", "measurement+lstm"):
        assert tp.main(["--env", env_id, "--agent", agent, "--steps", "256", "--out",
                        str(tmp_path), "--checkpoints", str(tmp_path / "ck")]) == 0
    zip_path = tmp_path / "ElasticJointReach-v0_true_seed0.zip"
    meta = json.loads(zip_path.with_suffix(".json").read_text())
    assert meta["settings"]["use_sde"] and meta["settings"]["n_steps"] == 256
    assert meta["settings"]["policy_kwargs"] == {"net_arch": [64, 64]}
    assert meta["settings"]["source"].startswith("docs/results/rl_seeds.md")
    small, full = ev.load(zip_path, meta), ev.load(tmp_path / "ck" / zip_path.name, meta)
    assert zip_path.stat().st_size < 0.6 * (tmp_path / "ck" / zip_path.name).stat().st_size
    assert not small.policy.optimizer.state and full.policy.optimizer.state
    obs = np.random.default_rng(0).normal(size=(16, 5))
    assert np.array_equal(small.predict(obs, deterministic=True)[0],
                          full.predict(obs, deterministic=True)[0])
    lstm_path = tmp_path / "ElasticJointReach-v0_measurement+lstm_seed0.zip"
    lstm = ev.load(lstm_path, json.loads(lstm_path.with_suffix(".json").read_text()))
    assert lstm.policy.lstm_actor.hidden_size == 64
    row = ev.evaluate(lstm_path, 1)
    assert (row.algorithm, len(row.solved)) == ("RecurrentPPO", 1)
