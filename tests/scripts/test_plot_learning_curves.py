"""scripts/plot_learning_curves.py: one panel per environment from train_policy's curves."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"


def _load():
    spec = importlib.util.spec_from_file_location("plot_learning_curves",
                                                  SCRIPTS / "plot_learning_curves.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["plot_learning_curves"] = mod
    spec.loader.exec_module(mod)
    return mod


def test_curves_plot_per_environment_and_bad_files_are_refused(tmp_path):
    pl = _load()
    a = tmp_path / "CartPoleSwingUp-v1_true_seed0.curve.json"
    b = tmp_path / "FurutaSwingUp-v1_true_seed0.curve.json"
    a.write_text(json.dumps([[1000, 1.0, 10.0], [2000, 2.0, 300.0]]))
    b.write_text(json.dumps([[1000, 1.0, 100.0]]))
    assert pl.env_of(a) == "hgo_mj/CartPoleSwingUp-v1"
    out = tmp_path / "c.png"
    assert pl.main([str(a), str(b), "--out", str(out)]) == 0
    assert out.read_bytes()[:4] == b"\x89PNG"
    b.write_text(json.dumps([[1000, 1.0]]))
    with pytest.raises(SystemExit, match=r"must hold a list of \[steps, seconds, mean return\]"):
        pl.main([str(b), "--out", str(out)])
    with pytest.raises(SystemExit, match="curve files not found"):
        pl.main([str(tmp_path / "none.curve.json"), "--out", str(out)])
