"""``scripts/tuning_table.py`` (docs/results/tuning.md): the committed page lists every family
the script tunes on each plant, and the script writes a row per tuned pair."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "tuning_table.py"
PAGE = ROOT / "docs" / "results" / "tuning.md"


def _module():
    spec = importlib.util.spec_from_file_location("tuning_table", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _rows(text: str) -> list[list[str]]:
    """The table's data rows, split into cells."""
    return [[c.strip() for c in ln.strip("|").split("|")] for ln in text.splitlines()
            if ln.startswith("| ") and not ln.startswith("| plant |")]


def test_the_page_lists_every_family_the_script_tunes():
    """Each (plant, family) the script tunes (every registered family that applies to the plant
    and builds at its hand-set parameters, kinematic_kalman included) has its row on the
    committed page, and the page has no other."""
    tt = _module()
    tuned = {(plant, kind) for plant, kind, _ in tt.cases()}
    assert {("pendulum", "kinematic_kalman"), ("elastic_joint", "kinematic_kalman")} <= tuned
    listed = [(r[0], r[1]) for r in _rows(PAGE.read_text())]
    assert len(listed) == len(set(listed))
    assert set(listed) == tuned


def test_the_script_writes_a_row_per_tuned_pair(tmp_path):
    tt = _module()
    out = tmp_path / "tuning.md"
    assert tt.main(["--budget", "2", "--seeds", "1", "--only", "pendulum/kinematic_kalman",
                    "--out", str(out)]) == 0
    (row,) = _rows(out.read_text())
    assert row[:2] == ["pendulum", "kinematic_kalman"]
    assert all(math.isfinite(float(v)) and float(v) > 0 for v in row[2:4])
