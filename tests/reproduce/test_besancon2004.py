"""Reproduction of paper 001, section 4 (``hgo-mj reproduce besancon2004``).

The paper gives figures only. Where its claim holds (example 1: state and parameters
converge) the test asserts it (to 1e-6 by 200 s); where it does not (example 2 does not
identify theta in 300 s) the test pins the numbers found and the explanation's evidence (the
collinear regressors). The sampled observer is cross-checked against the continuous-time
observer integrated by LSODA.
"""

from __future__ import annotations

import numpy as np
import pytest

from hgo_mj.reproduce import REPRODUCTIONS, read_summary, run_reproduction


@pytest.fixture(scope="module")
def summary(tmp_path_factory):
    out = tmp_path_factory.mktemp("besancon2004")
    s = run_reproduction("besancon2004", out, rrd=None)
    s["_out"] = out
    return s


def test_files(summary):
    out = summary["_out"]
    assert "besancon2004" in REPRODUCTIONS
    on_disk = read_summary(out)  # strict JSON: no Infinity / NaN
    assert on_disk == {k: v for k, v in summary.items() if k != "_out"}
    # example 2 never comes within 5 % (inf): null in the file, "never" in the report
    assert on_disk["ex2"]["time_to_5pct"] is None
    assert "time to 5 %           never" in (out / "report.txt").read_text()
    assert "ex2.time_to_5pct = never" in (out / "report.txt").read_text()
    for f in ("fig1_state_errors.png", "fig2_parameters.png", "fig3_parameters.png",
              "excitation.png", "report.txt"):
        assert (out / f).stat().st_size > 1000
    assert "What limits the convergence speed" in (out / "report.txt").read_text()


def test_example1(summary):
    e1, c1 = summary["ex1"], summary["continuous"]["ex1"]
    assert {"theta_at_30s", "time_to_5pct", "state_error_at_30s"} <= set(e1)
    # the numbers found (tolerance 2 %) and the continuous-time observer (sampling effect)
    np.testing.assert_allclose(e1["theta_at_30s"], [0.671, 1.987], rtol=0.02)
    np.testing.assert_allclose(e1["theta_at_30s"], c1["theta_at_30s"], atol=0.01)
    # ... but not to the digits: the gap is first order in the sample period (halves with it)
    gap = np.abs(np.subtract(e1["theta_at_30s"], c1["theta_at_30s"]))
    half = np.abs(np.subtract(c1["theta_at_30s_half_period"], c1["theta_at_30s"]))
    assert gap[0] > 3e-3
    np.testing.assert_allclose(gap / half, 2.0, rtol=0.05)
    assert "halves to" in (summary["_out"] / "report.txt").read_text()
    assert 44.0 < e1["time_to_5pct"] < 50.0
    assert abs(e1["time_to_5pct"] - c1["time_to_5pct"]) < 1.0
    assert max(e1["state_error_at_30s"]) < 0.01
    # the paper's claim (Fig. 1-2): state and parameters converge
    np.testing.assert_allclose(e1["theta_at_200s"], [1.0, 2.0], atol=1e-6)
    assert max(e1["state_error_at_200s"]) < 1e-9


def test_example2(summary):
    e2, c2 = summary["ex2"], summary["continuous"]["ex2"]
    assert {"theta_at_30s", "theta_at_300s", "excitation_min_eig"} <= set(e2)
    np.testing.assert_allclose(e2["theta_at_30s"], [4.10, -1.95], rtol=0.03)
    np.testing.assert_allclose(e2["theta_at_300s"], [6.43, -3.19], rtol=0.02)
    np.testing.assert_allclose(e2["theta_at_300s"], c2["theta_at_300s"], atol=0.03)
    # not identified in 300 s (against the paper's Fig. 3): more than 30 % off
    assert all(abs(t - th) > 0.3 * abs(th) for t, th in zip(e2["theta_at_300s"], (10.0, -5.0)))
    # why: a weak direction of the excitation matrix (eq. 11) ...
    assert 0.12 < e2["excitation_min_eig"] < 0.2
    ev = e2["excitation_eigenvalues"]
    assert ev[1] / ev[0] > 20
    # ... because the true regressors become collinear along the run
    last = e2["true_regressor"]["windows"][-1]
    assert last["correlation"] > 0.999
    assert last["eig"][1] / last["eig"][0] > 50
    # and the parameter error lies along that weak direction
    err = np.array(e2["theta_at_300s"]) - [10.0, -5.0]
    assert abs(np.dot(err / np.linalg.norm(err), last["weak_direction"])) > 0.99
    assert e2["y_at_300s"] == pytest.approx(np.sqrt(2 * e2["true_regressor"]["w_star"] * 300), rel=0.05)
