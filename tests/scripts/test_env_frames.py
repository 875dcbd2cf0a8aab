"""scripts/env_frames.py: the animated frames of a solved episode of a committed policy, and
its refusals."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"
POLICIES = SCRIPTS.parent / "docs" / "results" / "policies"


def _load():
    spec = importlib.util.spec_from_file_location("env_frames", SCRIPTS / "env_frames.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["env_frames"] = mod
    spec.loader.exec_module(mod)
    return mod


def test_refusals(tmp_path):
    ef = _load()
    with pytest.raises(SystemExit, match="--every must be >= 1 and --size >= 16; found 0 and 240"):
        ef.main(["--every", "0"])
    with pytest.raises(SystemExit, match=r"found no policy of the agents \['true'\]"):
        ef.main(["--policies", str(tmp_path), "--agents", "true"])


def test_a_solved_episode_becomes_a_gif_an_unsolved_one_does_not(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    from PIL import Image

    ef = _load()
    assert ef.main(["--every", "100", "--size", "32", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    for z in POLICIES.glob("*_estimate_seed0.zip"):  # each one: a GIF or the reason for none
        made = (tmp_path / f"{z.stem}.gif").exists()
        assert made != (f"{z.stem}: not solved" in out)
    im = Image.open(tmp_path / "CartPoleBalance-v0_estimate_seed0.gif")  # solved: 500 steps
    total = 0
    for i in range(im.n_frames):  # 5 frames of 100 x 0.01 s (identical ones merged by PIL)
        im.seek(i)
        total += im.info["duration"]
    assert im.size == (32, 32) and 2 <= im.n_frames <= 5 and total == 5000
