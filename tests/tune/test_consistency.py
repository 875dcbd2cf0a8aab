"""The consistency scores of :func:`hgo_mj.tune.scoring.evaluate` (``consistency=True``): the
NIS band share and the NEES of a filter read from its covariance between segments, checked
against a run of the same member read by hand; an observer without a covariance gets NaN."""

from __future__ import annotations

import numpy as np
import pytest

from hgo_mj.loop import Drive, Loop
from hgo_mj.metrics import chi2_band, nees
from hgo_mj.study.engine import ReplayPlant
from hgo_mj.tune import scoring
from hgo_mj.tune.scoring import _observer, evaluate, setup

SC = {"plant": {"name": "pendulum", "dt": 0.01, "x0": [0.3, 0.0]},
      "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
      "observers": [{"type": "ekf", "name": "kf", "R": 1e-6},
                    {"type": "high_gain", "name": "hgo", "k": 20.0}],
      "input": {"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]},
      "run": {"duration": 4.0}}


def test_nees_equals_a_hand_reading_at_the_same_instants(monkeypatch):
    """NEES_POINTS = 8: the run of 400 samples is cut into segments of 50; after each segment
    from the transient (0.8 s) on, the NEES of the estimate of the state at that instant with
    the filter's covariance, read here from a loop of the same member stepped alike."""
    monkeypatch.setattr(scoring, "NEES_POINTS", 8)
    st = setup(SC, "kf")
    sc = evaluate(st, [{}], [5], consistency=True)
    kw = _observer(st, None)
    ob = kw["observers"]["kf"]
    plant = ReplayPlant(st.plant, st.X, st.Yc, np.zeros(1, dtype=np.intp))
    loop = Loop(plant, kw["sensor"], {"kf": ob}, st.periods, exact=False)
    drive = Drive.of(kw["inputs"], {"kf": ob}, plant, st.periods)
    loop.reset(None, seed=[5], batch=1)
    got = []
    while loop.k < st.N:
        seg = loop.segment(drive.inputs(loop, 50))
        if loop.k >= 80:
            e = st.X[0, loop.k][None] - seg.blocks["kf"].x_hat[:, -1]
            got.append(nees(e, ob.covariance(loop.states["kf"]))[0])
    lo, hi = chi2_band(2)
    assert len(got) == 7
    assert sc.nees[0, 0] == pytest.approx(np.mean(got), rel=1e-9)
    assert sc.nees_band[0, 0] == pytest.approx(np.mean((np.array(got) >= lo) &
                                                       (np.array(got) <= hi)), rel=1e-12)
    assert 0.0 <= sc.nis_band[0, 0] <= 1.0 and np.isfinite(sc.nis[0, 0])


def test_an_overconfident_filter_scores_a_larger_nees_and_a_smaller_band_share():
    st = setup(SC, "kf")
    sc = evaluate(st, [{"Q": np.diag([1e-3, 1e-3])}, {"Q": np.diag([1e-12, 1e-12]),
                                                        "R": np.array([[1e-9]])}],
                  [1, 2], consistency=True)
    assert np.all(sc.nees[1] > 10 * sc.nees[0]), sc.nees
    assert np.all(sc.nis[1] > 10 * sc.nis[0]), sc.nis
    assert np.all(sc.nis_band[1] < sc.nis_band[0]), sc.nis_band


def test_without_a_covariance_or_without_asking_the_nees_is_nan():
    hgo = evaluate(setup(SC, "hgo"), [{}], [1], consistency=True)
    assert np.isnan(hgo.nees).all() and np.isnan(hgo.nis_band).all()
    kf = evaluate(setup(SC, "kf"), [{}], [1])
    assert np.isnan(kf.nees).all() and np.isfinite(kf.nis_band).all()


def test_whiteness_is_box_pierce_of_the_output_errors():
    """The accumulator over segments of any lengths equals Box-Pierce computed at once: about 1
    for white noise, far above it for an AR(1) sequence."""
    from hgo_mj.tune.scoring import WHITENESS_LAGS, _Whiteness

    rng = np.random.default_rng(0)
    white = rng.standard_normal((1, 4000, 1))
    ar = np.empty_like(white)
    ar[:, 0] = white[:, 0]
    for k in range(1, 4000):
        ar[:, k] = 0.8 * ar[:, k - 1] + white[:, k]
    L = WHITENESS_LAGS
    for e, expect in ((white, (0.5, 1.6)), (ar, (50.0, np.inf))):
        acc = _Whiteness(1, 1)
        for a, b in ((0, 3), (3, 1000), (1000, 1001), (1001, 4000)):  # segments of any length
            acc.add(e[:, a:b])
        x = e[0, :, 0]
        rho = [x[lag:] @ x[:-lag] / (x @ x) for lag in range(1, L + 1)]
        assert acc.result()[0] == pytest.approx(len(x) * np.sum(np.square(rho)) / L, rel=1e-9)
        assert expect[0] < acc.result()[0] < expect[1]


def test_a_slow_observer_leaves_correlated_errors():
    """A high-gain observer far too slow (k = 1: its estimate lags the swing) leaves output
    errors far less white than a fast one (k = 200)."""
    sc = {**SC, "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}]}
    r = evaluate(setup(sc, "hgo"), [{"k": 1.0}, {"k": 200.0}], [1, 2])
    w = r.whiteness.mean(axis=1)
    assert w[0] > 10 * w[1], w


def test_a_model_mismatch_goes_to_system_params_or_to_the_mjcf_fields():
    """``mismatch`` tables: parameter names change the observer's system, MuJoCo model fields
    its copy of the MJCF (model_fields); the MuJoCo EKF then steps the wrong MJCF."""
    from hgo_mj.tune.scoring import _with_model

    sc = {**SC, "observers": [{"type": "ekf_mujoco", "name": "m", "model_fields": {
        "dof_damping[hinge]": 0.02}}]}
    out = _with_model(sc, "m", {"damping": 0.02, "body_mass[pole]": 0.3, "opt.gravity": 9.0})
    spec = out["observers"][0]
    assert spec["system_params"] == {"damping": 0.02}
    assert spec["model_fields"] == {"dof_damping[hinge]": 0.02, "body_mass[pole]": 0.3,
                                    "opt.gravity": 9.0}
    assert sc["observers"][0]["model_fields"] == {"dof_damping[hinge]": 0.02}  # not changed
    st = setup({**SC, "observers": [{"type": "ekf_mujoco", "name": "m", "R": 1e-6}]}, "m")
    right = evaluate(st, [{}], [1])
    wrong = evaluate(st, [{}], [1], mismatch={"damping": 0.05, "dof_damping[hinge]": 0.05})
    assert wrong.rmse[0, 0, 1] > 2 * right.rmse[0, 0, 1]
