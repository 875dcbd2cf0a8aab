"""scripts/bench_import.py: both statements are timed in fresh interpreters and the report
holds the ratio (no timing asserted); ``import hgo_mj.simulate`` loads no numba."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "bench_import.py"


def _load():
    spec = importlib.util.spec_from_file_location("bench_import", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_report_has_both_statements_and_the_ratio(tmp_path):
    bench = _load()
    res = bench.measure(rounds=1)
    assert set(res) == set(bench.STATEMENTS)
    assert all(r["median"] > 0 and r["modules"] > 0 for r in res.values())
    assert res["import hgo_mj.simulate"]["numba"] is False
    text = bench.report(res, "test", (0.5, 0.6))
    assert re.search(r"= \*\*[0-9.]+x\*\*", text)
    out = tmp_path / "B.md"
    assert bench.main(["--rounds", "1", "--write", str(out)]) == 0
    assert "<!-- bench_import: begin -->" in out.read_text()
    assert bench.main(["--rounds", "0"]) == 2
