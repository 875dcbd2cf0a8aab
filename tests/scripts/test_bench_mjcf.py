"""scripts/bench_mjcf.py: every case runs and the report holds its ratios (no timing asserted)."""

from __future__ import annotations

import importlib.util
import math
import re
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "bench_mjcf.py"


def _load():
    spec = importlib.util.spec_from_file_location("bench_mjcf", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_report_has_every_case_and_ratio(tmp_path):
    bench = _load()
    best = bench.measure(steps=20, rounds=1)
    assert len(best) == 9 and all(math.isfinite(v) and v > 0 for v in best.values())
    text = bench.report(best, "test")
    ratios = [float(r) for r in re.findall(r"\| ([0-9.]+)x \|", text)]
    assert len(ratios) == 5 and all(r > 0 for r in ratios)
    out = tmp_path / "B.md"
    assert bench.main(["--steps", "20", "--rounds", "1", "--write", str(out)]) == 0
    assert "<!-- bench_mjcf: begin -->" in out.read_text()
    assert bench.main(["--steps", "0"]) == 2
