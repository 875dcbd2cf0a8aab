"""scripts/bench_symbolic.py: every case runs and the report holds its ratios (no timing
asserted)."""

from __future__ import annotations

import importlib.util
import math
import re
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "bench_symbolic.py"


def _load():
    spec = importlib.util.spec_from_file_location("bench_symbolic", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_report_has_every_case_and_ratio(tmp_path):
    bench = _load()
    best = bench.measure(updates=20, rounds=1)
    assert len(best) == 6 and all(math.isfinite(v) and v > 0 for v in best.values())
    ratios = [float(r) for r in re.findall(r"\| ([0-9.]+)x \|", bench.report(best, "test"))]
    assert len(ratios) == 3 and all(r > 0 for r in ratios)
    out = tmp_path / "B.md"
    assert bench.main(["--updates", "20", "--rounds", "1", "--write", str(out)]) == 0
    assert "<!-- bench_symbolic: begin -->" in out.read_text()
    assert bench.main(["--rounds", "0"]) == 2
