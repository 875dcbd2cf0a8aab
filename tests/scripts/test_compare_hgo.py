"""``scripts/compare_hgo.py`` at a tiny size (one noise level, one seed, 2 s): the report has
every row and column with finite numbers, and the script's design helpers agree with
:mod:`hgo_mj.design` where that is accurate."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from hgo_mj.systems import ElasticJoint

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "compare_hgo.py"


@pytest.fixture(scope="module")
def compare():
    spec = importlib.util.spec_from_file_location("compare_hgo", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules["compare_hgo"] = module  # dataclasses resolve annotations through it
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop("compare_hgo", None)


@pytest.fixture(scope="module")
def report(compare, tmp_path_factory):
    out = tmp_path_factory.mktemp("hgo") / "hgo.md"
    assert compare.main(["--quick", "--out", str(out)]) == 0
    return out


def result_table(text: str) -> list[list[str]]:
    """Cells of the first results table (the one under ``## sigma = ...``)."""
    lines = text.split("## sigma = ", 1)[1].splitlines()
    rows = [ln for ln in lines if ln.startswith("|")]
    return [[c.strip() for c in ln.strip().strip("|").split("|")] for ln in rows]


def number(cell: str) -> float:
    """The mean of a ``mean ± spread`` or ``mean (ratio)`` cell."""
    return float(cell.split("±")[0].split("(")[0])


def test_report_has_every_row_and_column_with_finite_numbers(report):
    text = report.read_text()
    assert "## What the table shows" in text and "python scripts/compare_hgo.py" in text
    assert "mujoco" in text and "numpy" in text  # versions
    assert (report.parent / "hgo_elastic_joint.png").stat().st_size > 10_000
    table = result_table(text)
    head, body = table[0], table[2:]
    for col in ("final k or gamma", "RMSE link angle", "RMSE motor angle", "RMSE link vel.",
                "RMSE motor vel.", "peak abs. error", "time to 5% band", "cost per update"):
        assert any(h.startswith(col) for h in head), col
    names = [r[0] for r in body]
    for row in ("HGO, low k", "HGO, tuned k", "HGO, high k", "adaptive k", "Riccati, min_gamma",
                "Riccati, tuned gamma", "q-integral q = 1", "q-integral q = 2"):
        assert sum(n.startswith(row) for n in names) == 1, row
    for r in body:
        assert len(r) == len(head), r
        values = [number(c) for c in r[1:6]] + [number(r[8])]
        values += [float(v) for v in r[6].split(" / ")]
        assert all(math.isfinite(v) and v >= 0 for v in values), r
        assert r[7] == "never" or math.isfinite(number(r[7])), r


def test_phi_gradient_matches_finite_differences(compare):
    s = ElasticJoint()
    rng = np.random.default_rng(0)
    for _ in range(5):
        z = rng.uniform([-3, -10, -200, -500], [3, 10, 200, 500])
        grad = compare.phi_gradient(s.params, z[0], z[1], z[2])
        h = 1e-6 * np.maximum(1.0, np.abs(z))
        fd = [(s.phi(z + h[i] * np.eye(4)[i], [0.2]) - s.phi(z - h[i] * np.eye(4)[i], [0.2]))
              / (2 * h[i]) for i in range(4)]
        np.testing.assert_allclose(grad, fd, rtol=1e-6)
    rho, _ = compare.lipschitz_rho(s.params)
    k, mgl = s.params["stiffness"], s.params["mass"] * s.params["g"] * s.params["com_distance"]
    assert rho > k * mgl / (s.params["link_inertia"] * s.params["motor_inertia"])
