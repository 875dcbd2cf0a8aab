"""The pure functions of a recording's blocks (:mod:`hgo_mj.record.rows`), without a file."""

from __future__ import annotations

import numpy as np
import pytest

from hgo_mj.exceptions import DimensionError
from hgo_mj.record import rows
from hgo_mj.record.layout import estimate_layout


def block(T=4, *, est=None, diag=None, extra=None, y_clean=True, episode=None):
    t = np.arange(T) * 0.01
    x = np.c_[np.arange(T, dtype=float), 10.0 + np.arange(T)]
    return rows.Block(t, np.arange(T, dtype=np.int64), episode, x,
                      x[:, :1] if y_clean else None, x[:, :1] + 0.5, -x[:, :1],
                      est or {}, diag or {}, extra or {})


# ----------------------------------------------------------------------------- checks
def test_check_block_shapes_and_messages():
    t = np.zeros(3)
    ok = dict(x=np.zeros((3, 2)), y_clean=None, y_meas=np.zeros((3, 1)), u=np.zeros(3),
              est={}, names={}, diag={}, extra={}, widths=(2, 1, 1), steps=np.arange(3),
              episode=2)
    b = rows.check_block(t, **ok)
    assert b.y_clean is None and b.u.shape == (3, 1) and b.episode == 2
    with pytest.raises(DimensionError, match=r"x must have shape \(3, 2\); found \(3, 3\)"):
        rows.check_block(t, **{**ok, "x": np.zeros((3, 3))})
    with pytest.raises(DimensionError, match=r"estimate of 'o' must have shape \(3, 1\) "
                                             r"\(columns \['a'\]\); found \(3, 2\)"):
        rows.check_block(t, **{**ok, "est": {"o": np.zeros((3, 2))}, "names": {"o": ("a",)}})
    with pytest.raises(DimensionError, match="diagnostic 'k' of 'o' must have 3 rows; found 2"):
        rows.check_block(t, **{**ok, "diag": {"o": {"k": np.zeros(2)}}})
    with pytest.raises(DimensionError, match=r"extra 'r' must have shape \(3,\) or \(3, k\)"):
        rows.check_block(t, **{**ok, "extra": {"r": np.zeros((3, 1, 1))}})


def test_as_steps():
    assert rows.as_steps(None, 2, 7).tolist() == [7, 8]
    assert rows.as_steps(np.int64(3), 2, 7).tolist() == [3, 4]
    assert rows.as_steps([5, 9], 2, 7).tolist() == [5, 9]
    with pytest.raises(DimensionError, match="step must have 2 entries; found 3"):
        rows.as_steps([1, 2, 3], 2, 0)


# ----------------------------------------------------------------------------- series
def test_signal_series_one_entity_per_state_with_its_estimates():
    """A state's truth and its observers' estimates are the columns of one entity (in observer
    order), its errors likewise; an output's clean and measured values share one."""
    lay = estimate_layout(["a", "va"], ["o1", "o2"], {"o1": ["a", "va"], "o2": ["a", "z"]})
    est = {"o1": np.full((4, 2), 1.0), "o2": np.full((4, 2), 2.0)}
    out = rows.signal_series(lay, block(est=est, extra={"r": np.ones(4)}), ["a"], ["tau"],
                             {"r": "/env/r"})
    paths = [p for p, _, _ in out]
    assert paths == ["/state/a", "/error/a", "/state/va", "/error/va", "/observer/o2/estimate/z",
                     "/sensor/a", "/input/tau", "/env/r"]
    got = {p: v for p, v, _ in out}
    x = block().x
    np.testing.assert_array_equal(got["/state/a"], np.c_[x[:, 0], np.ones(4), np.full(4, 2.0)])
    np.testing.assert_array_equal(got["/error/a"], np.c_[x[:, 0] - 1.0, x[:, 0] - 2.0])
    np.testing.assert_array_equal(got["/state/va"], np.c_[x[:, 1], np.ones(4)])
    np.testing.assert_array_equal(got["/error/va"], (10.0 + np.arange(4) - 1.0)[:, None])
    np.testing.assert_array_equal(got["/sensor/a"], np.c_[x[:, 0], x[:, 0] + 0.5])
    np.testing.assert_array_equal(got["/input/tau"], -np.arange(4.0))
    assert [p for p, _, clock in out if clock] == ["/state/a", "/state/va"]


def test_signal_series_missing_estimate_and_clean_output_are_nan():
    lay = estimate_layout(["a", "va"], ["o"], {"o": ["a", "va"]})
    got = {p: v for p, v, _ in rows.signal_series(lay, block(y_clean=False), ["a"], [], {})}
    assert got["/state/a"].shape == (4, 2) and not np.isnan(got["/state/a"][:, 0]).any()
    assert np.isnan(got["/state/a"][:, 1]).all() and np.isnan(got["/error/a"]).all()
    assert np.isnan(got["/sensor/a"][:, 0]).all() and not np.isnan(got["/sensor/a"][:, 1]).any()
    assert "/observer/o/estimate/a" not in got


def test_signal_series_a_state_no_observer_estimates_has_the_truth_alone():
    lay = estimate_layout(["a", "va"], ["o"], {"o": ["a"]})
    got = {p: v for p, v, _ in rows.signal_series(lay, block(est={"o": np.ones((4, 1))}), [],
                                                   [], {})}
    assert got["/state/va"].shape == (4, 1) and "/error/va" not in got
    assert got["/error/a"].shape == (4, 1)


def test_diagnostic_series_adds_the_true_parameter_once():
    paths = {("o1", "theta_m"): ("/observer/o1/theta/m", "theta"),
             ("o2", "theta_m"): ("/observer/o2/theta/m", "theta"),
             ("o1", "k"): ("/observer/o1/gain", "gain")}
    b = block(diag={"o1": {"theta_m": np.ones(4), "k": np.full(4, 3.0)},
                    "o2": {"theta_m": np.zeros(4)}})
    got = rows.diagnostic_series(b, paths, {"m": 2.0, "c": 1.0})
    assert sorted(got) == ["/observer/o1/gain", "/observer/o1/theta/m", "/observer/o2/theta/m",
                           "/plant/param/m"]
    np.testing.assert_array_equal(got["/plant/param/m"], np.full(4, 2.0))


# ----------------------------------------------------------------------------- changes
def test_changes_over_blocks_rebuild_the_series():
    """Compressed block by block and filled forward, the kept rows give the series back."""
    rng = np.random.default_rng(0)
    v = np.repeat(rng.integers(0, 3, 40).astype(float), rng.integers(1, 6, 40))
    v[5:9] = np.nan
    last, kept = None, np.zeros(v.size, bool)
    edges = [0, 7, 8, 30, 31, v.size]
    for k0, k1 in zip(edges[:-1], edges[1:]):
        keep, last, pending = rows.changes(v[k0:k1], last, mark_end=k1 == v.size)
        if keep is not None:
            kept[k0:k1] = keep
        assert pending == (k1 != v.size and (keep is None or not keep[-1]))
    assert kept[0] and kept[-1]
    idx = np.maximum.accumulate(np.where(kept, np.arange(v.size), 0))
    np.testing.assert_array_equal(v[idx], v)
    assert kept.sum() < v.size / 2


def test_changes_of_a_constant_and_a_nan_block():
    assert rows.changes(np.full(3, 4.0), 4.0, False) == (None, 4.0, True)
    keep, last, _ = rows.changes(np.full(3, np.nan), np.nan, False)
    assert keep is None and np.isnan(last)
    keep, _, pending = rows.changes(np.full(3, 4.0), None, False)
    assert keep.tolist() == [True, False, False] and pending


# ----------------------------------------------------------------------------- poses
def test_pose_rows_on_the_grid_and_the_last_row():
    t = np.arange(5, 26) * 0.001
    sel = rows.pose_rows(t, np.arange(5, 26), 100.0)
    assert (np.arange(5, 26)[sel]).tolist() == [10, 20, 25]
    assert rows.pose_rows(t[:1], np.arange(1), 100.0).tolist() == [True]
    assert rows.pose_rows(t, np.arange(21), None).all()


def test_pose_sets_take_the_truth_where_an_estimate_has_no_joint():
    lay = estimate_layout(["a", "b", "va", "vb"], ["o"], {"o": ["b", "vb"]})
    b = rows.Block(np.zeros(2), np.arange(2), None, np.array([[1.0, 2, 0, 0], [3, 4, 0, 0]]),
                   None, np.zeros((2, 1)), np.zeros((2, 1)),
                   {"o": np.array([[9.0, 0.0], [np.nan, 0.0]])}, {}, {})
    sets = rows.pose_sets(lay, b, ["o"], 2, np.array([True, True]))
    np.testing.assert_array_equal(sets["/world/true"], [[1, 2], [3, 4]])
    np.testing.assert_array_equal(sets["/world/estimate/o"], [[1, 9], [3, 4]])
