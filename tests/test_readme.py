"""The README's Python example and scenario file run as written."""

from __future__ import annotations

import re
from pathlib import Path

from hgo_mj.cli import main
from hgo_mj.simulate import Trajectory

README = (Path(__file__).resolve().parents[1] / "README.md").read_text()


def test_python_example_runs(tmp_path, monkeypatch, capsys):
    code, batch = re.findall(r"```python\n(.*?)```", README, re.S)[:2]
    assert len(code.strip().splitlines()) <= 22
    monkeypatch.chdir(tmp_path)
    scope: dict = {}
    exec(compile(code, "README.md", "exec"), scope)
    assert "k80" in capsys.readouterr().out
    alone = Trajectory.load(tmp_path / "runs" / "pendulum.npz")
    assert len(alone) == 10001
    exec(compile(batch, "README.md", "exec"), scope)  # the batch of 64, on the same parts
    runs = scope["runs"]
    assert len(runs) == 64 and [r.metadata["seed"] for r in runs] == list(range(64))
    assert all(len(r) == 10001 for r in runs)
    assert runs[5].x[0].tolist() == scope["x0"][5].tolist()


def test_scenario_file_runs(tmp_path, monkeypatch):
    toml = re.findall(r"```toml\n(.*?)```", README, re.S)[0]
    (tmp_path / "s.toml").write_text(toml)
    monkeypatch.chdir(tmp_path)
    assert main(["run", "s.toml"]) == 0
    assert (tmp_path / "runs" / "pendulum" / "metrics.json").is_file()


def test_the_study_examples_run(tmp_path, monkeypatch, capsys):
    """The scenario file with the [sweep] table appended, through `hgo-mj sweep`; and the
    Python study on the scenario file."""
    blocks = re.findall(r"```toml\n(.*?)```", README, re.S)
    scenario, (sweep,) = blocks[0], [b for b in blocks if "[sweep]" in b]
    (tmp_path / "scenario.toml").write_text(scenario)
    (tmp_path / "study.toml").write_text(scenario + sweep)
    monkeypatch.chdir(tmp_path)
    assert main(["sweep", "study.toml", "--out", "runs/sweep", "--quiet"]) == 0
    import pandas as pd

    df = pd.read_parquet(tmp_path / "runs" / "sweep" / "results.parquet")
    # 32 seeds x 4 gains of k20 x 3 noise levels, two observers (k20, k80), two states
    assert len(df) == 32 * 4 * 3 * 2 * 2 and not df["diverged"].any()
    study = re.findall(r"```python\n(.*?)```", README, re.S)[2]
    scope: dict = {}
    exec(compile(study, "README.md", "exec"), scope)
    assert len(scope["result"].table) == 16 * 3 * 2 * 2
    assert len(scope["figures"]) == 1


def test_every_observer_and_reproduction_is_in_the_readme():
    from hgo_mj.observers import OBSERVERS
    from hgo_mj.reproduce import REPRODUCTIONS

    rows = set(re.findall(r"^\| `([a-z0-9_]+)`(?:, `([a-z0-9_]+)`)? \|", README, re.M))
    listed = {name for row in rows for name in row if name}
    assert set(OBSERVERS) <= listed, sorted(set(OBSERVERS) - listed)
    assert set(REPRODUCTIONS) <= listed, sorted(set(REPRODUCTIONS) - listed)


def test_environment_examples_run():
    """The two ```py blocks of the Gymnasium section, run one after the other as written."""
    section = README[README.index("## Gymnasium environments"):]
    blocks = re.findall(r"```py\n(.*?)```", section, re.S)
    assert len(blocks) == 2
    ns: dict = {}
    exec(compile(blocks[0], "README.md", "exec"), ns)
    assert set(ns["info"]) >= {"state", "estimate", "error"}
    exec(compile(blocks[1], "README.md", "exec"), ns)
    obs, _ = ns["env"].reset(seed=0)
    assert obs.shape == (4,)


def test_adding_an_observer_example_runs(capsys):
    from hgo_mj.observers import OBSERVERS

    (code,) = [b for b in re.findall(r"```py\n(.*?)```", README, re.S) if "@register" in b]
    try:
        exec(compile(code, "README.md", "exec"), {})
        assert "[0.3] {'dropouts': 0.0}" in capsys.readouterr().out
        assert "hold_last_example" in OBSERVERS
    finally:
        OBSERVERS.pop("hold_last_example", None)


def test_the_command_line_and_the_scenario_file_are_the_same_study(tmp_path, monkeypatch, capsys):
    """The README calls its command line and its scenario file "the same study" as the Python
    example: all three print the same RMSE of every observer and state."""
    import json
    import shlex

    from hgo_mj.metrics import all_metrics

    monkeypatch.chdir(tmp_path)
    code = re.findall(r"```python\n(.*?)```", README, re.S)[0]
    scope: dict = {}
    exec(compile(code, "README.md", "exec"), scope)
    python = all_metrics(scope["traj"], t_transient=1.0)
    assert list(python) == ["k20", "k80"]
    sh = re.findall(r"```sh\n(hgo-mj run --plant.*?)```", README, re.S)[0]
    command = sh.split("\nhgo-mj run scenario.toml")[0].replace("\\\n", " ")
    argv = shlex.split(command)
    assert argv[:2] == ["hgo-mj", "run"] and "--t-transient" in argv
    capsys.readouterr()
    assert main(argv[1:]) == 0
    printed = capsys.readouterr().out
    cli = json.loads((tmp_path / "runs" / "pend" / "metrics.json").read_text())
    toml = re.findall(r"```toml\n(.*?)```", README, re.S)[0]
    assert 'name = "pendulum-two-gains"' in toml and toml.count("[[observers]]") == 2
    (tmp_path / "scenario.toml").write_text(toml)
    assert main(["run", "scenario.toml"]) == 0
    scenario = json.loads((tmp_path / "runs" / "pendulum" / "metrics.json").read_text())
    assert list(cli) == list(scenario) == ["k20", "k80"]
    for name in python:
        assert cli[name]["rmse"] == python[name]["rmse"] == scenario[name]["rmse"], name
        for value in python[name]["rmse"]:
            assert f"{value:.4g}" in printed  # the printed table


def test_the_input_per_actuator_example_drives_the_two_link_arm(tmp_path):
    import numpy as np

    (block,) = [b for b in re.findall(r"```toml\n(.*?)```", README, re.S) if "[[input]]" in b]
    (tmp_path / "arm.toml").write_text('[plant]\nname = "elastic_joint_2link"\n' + block
                                       + "[run]\nduration = 1.0\n")
    assert main(["run", str(tmp_path / "arm.toml"), "--out", str(tmp_path / "o")]) == 0
    traj = Trajectory.load(tmp_path / "o" / "trajectory.npz")
    assert traj.u.shape[1] == 2
    assert np.ptp(traj.u[:, 0]) > 0.3 and np.ptp(traj.u[:, 1]) == 0.1


def test_every_block_marked_as_needing_an_extra_names_one_that_exists():
    """``<!-- needs: EXTRA -->`` before a block names extras of pyproject.toml; Gymnasium's own
    MuJoCo environment needs ``gym`` (the wheel test runs the unmarked blocks with only the
    runtime and checks that each marked one fails there)."""
    from readme_blocks import blocks

    from hgo_mj._extras import EXTRAS

    marked = [b for b in blocks() if b.needs]
    assert all(set(b.needs) <= set(EXTRAS) for b in marked), [b.needs for b in marked]
    (gym,) = [b for b in marked if "InvertedPendulum-v5" in b.code]
    assert gym.needs == ("gym",) and gym.lang == "py"
    assert not [b for b in blocks() if "InvertedPendulum-v5" in b.code and not b.needs]


def test_the_runtime_script_runs_the_unmarked_blocks_and_tries_the_marked(tmp_path, monkeypatch,
                                                                          capsys):
    from readme_blocks import blocks, runtime_script

    text = ("intro\n```toml\nname = 's'\n```\n```python\nx = 1\n```\n"
            "<!-- needs: lmi,gym -->\n```py\nimport no_such_module_here\n```\n"
            "```py\nprint('x =', x)\n```\n")
    assert [(b.lang, b.needs, b.line) for b in blocks(text)] == [
        ("toml", (), 2), ("python", (), 5), ("py", ("lmi", "gym"), 9), ("py", (), 12)]
    monkeypatch.chdir(tmp_path)
    exec(compile(runtime_script(text), "script", "exec"), {})
    assert capsys.readouterr().out == ("NEEDS lmi,gym 9: ModuleNotFoundError: No module named "
                                       "'no_such_module_here'\nx = 1\n")
    assert (tmp_path / "scenario.toml").read_text() == "name = 's'\n"


def test_the_extra_script_runs_a_marked_block_after_its_section(tmp_path, capsys):
    from readme_blocks import extra_script

    text = ("## One\n```py\nraise SystemExit('another section: not run')\n```\n"
            "## Two\n```py\nx = 2\n```\n<!-- needs: gym -->\n```py\nprint('x =', x)\n```\n"
            "<!-- needs: lmi -->\n```py\nraise SystemExit('another extra: not run')\n```\n")
    exec(compile(extra_script("gym", text), "script", "exec"), {})
    assert capsys.readouterr().out == "x = 2\nRAN 10\n"  # the line of its fence
