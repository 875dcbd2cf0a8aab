"""scripts/wrapper_velocity.py: runs on one environment and writes its page (no figure of merit
asserted here: tests/envs/test_envs_wrappers.py checks the wrapper beats the difference)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "wrapper_velocity.py"


def test_writes_the_table(tmp_path):
    spec = importlib.util.spec_from_file_location("wrapper_velocity", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    out = tmp_path / "w.md"
    assert module.main(["--steps", "5", "--envs", "InvertedPendulum-v5", "--out",
                        str(out)]) == 0
    text = out.read_text()
    # a ratio cell per configuration: joints= five (two observers, current and prediction,
    # and the tuned EKF); measure= four (the chains, both, tuned; the tuned Kalman filters)
    assert text.count("| InvertedPendulum-v5 | 2 |") == 2 and text.count("x, ") == 5 + 4
    assert "auto (tuned kinematic_kalman, current)" in text
    assert module.main(["--steps", "1"]) == 2
