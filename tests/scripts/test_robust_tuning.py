"""Smoke test of ``scripts/robust_tuning.py`` (docs/results/robust_tuning.md) on a tiny
configuration: the arm MJCF as a user's plant, the filter's wrong model written through
``model_fields``, a finite difference tuned per joint, both tunings and the table."""

from __future__ import annotations

import importlib.util
import math
import re
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "robust_tuning.py"


def _module():
    spec = importlib.util.spec_from_file_location("robust_tuning", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_wrong_model_and_the_table(tmp_path):
    rt = _module()
    wrong = rt.model_fields(1.1, 0.03)
    assert wrong["body_mass[upper]"] == 1.1 and wrong["dof_damping[wrist]"] == 0.03
    assert len(wrong["body_inertia[hand]"]) == 3
    out = tmp_path / "rt.md"
    assert rt.main(["--budget", "2", "--seeds", "1", "--duration", "1", "--out",
                    str(out)]) == 0
    rows = [ln for ln in out.read_text().splitlines() if ln.startswith("| ") and "x |" in ln]
    assert [r.split(" | ")[0][2:] for r in rows] == [
        "finite difference (tau per joint tuned)", "EKF, hand-set Q = 1e-6 I",
        "EKF, tuned on the nominal model", "EKF, tuned robustly (worst of 5 models)"]
    for r in rows:
        vals = [float(v) for v in r.split(" | ")[1:4]]
        assert all(math.isfinite(v) and v > 0 for v in vals), r
    assert re.search(r"\| 1\.00x \| tau = ", rows[0])
