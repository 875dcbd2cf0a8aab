"""scripts/bench_quick.py: a cold and a warm run of a part of the quick suite, each in a fresh
process with its own numba and bytecode caches; the report holds both and whether their scores agree (no
timing asserted)."""

from __future__ import annotations

import contextlib
import importlib.util
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "bench_quick.py"


def _load():
    spec = importlib.util.spec_from_file_location("bench_quick", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_cold_and_warm_side_by_side_with_the_same_scores(tmp_path, monkeypatch):
    bench = _load()
    kept = tmp_path / "runs"
    kept.mkdir()
    monkeypatch.setattr(bench.tempfile, "TemporaryDirectory",
                        lambda **kw: contextlib.nullcontext(str(kept)))
    monkeypatch.setenv("PYTHONDONTWRITEBYTECODE", "1")  # as on the test machine
    out = tmp_path / "B.md"
    assert bench.main(["--jobs", "1", "--budget", "2", "--tasks", "pendulum/encoder-v1",
                       "--observers", "finite_difference", "--write", str(out)]) == 0
    text = out.read_text()
    assert "<!-- bench_quick: begin -->" in text
    row = next(ln for ln in text.splitlines() if ln.startswith("| 1 |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    cold_cpu, warm_cpu = float(cells[2]), float(cells[4])
    assert cold_cpu > 0 and warm_cpu > 0 and cells[-1] == "yes"
    # cold started from empty caches of its own, which it filled for the warm run: numba's
    # kernels and the bytecode of the modules it imported (hgo_mj's and its dependencies')
    cache = kept / "cache"
    assert list((cache / "numba").rglob("*.nbi"))
    pycs = [p.relative_to(cache / "pycache").as_posix()
            for p in (cache / "pycache").rglob("*.pyc")]
    assert any("hgo_mj/scenario." in p for p in pycs) and any("/numpy/" in p for p in pycs)
    assert bench.main(["--jobs", "0"]) == 2
