"""LQR state feedback on a system's linearization, batched, with saturation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hgo_mj.control import LinearFeedback, linearize, lqr
from hgo_mj.exceptions import DesignError
from hgo_mj.systems import CartPendulum, ElasticJoint


def test_the_cart_pendulums_lqr_gain_is_the_analytic_one():
    """x1'' = sin x1 + u cos x1 at the upright: A = [[0, 1], [1, 0]], B = [0, 1]; with Q = I,
    R = 1 the Riccati equation gives K = [1 + sqrt 2, sqrt(1 + 2 (1 + sqrt 2))]."""
    A, B = linearize(CartPendulum())
    np.testing.assert_allclose(A, [[0.0, 1.0], [1.0, 0.0]], atol=1e-8)
    np.testing.assert_allclose(B, [[0.0], [1.0]], atol=1e-8)
    K = lqr(CartPendulum(), Q=[1.0, 1.0], R=1.0).K
    k1 = 1 + math.sqrt(2)
    np.testing.assert_allclose(K, [[k1, math.sqrt(1 + 2 * k1)]], rtol=1e-6)


def test_the_elastic_joints_lqr_closed_loop_is_stable():
    sys = ElasticJoint()
    law = lqr(sys, Q=1.0, R=0.1)
    A, B = linearize(sys)
    assert np.max(np.linalg.eigvals(A - B @ law.K).real) < 0
    assert law.K.shape == (1, 4)


def test_a_batch_acts_as_its_members_bit_for_bit_and_saturates():
    law = LinearFeedback([[2.0, 0.7]], u_max=1.5)
    X = np.random.default_rng(0).normal(size=(64, 2))
    U = law.act(0.0, X)
    for b in range(64):
        assert law.act(0.0, X[b:b + 1])[0, 0] == U[b, 0]
        assert law(0.0, X[b])[0] == U[b, 0]
    assert np.abs(U).max() == 1.5
    assert law.act(0.0, np.array([[0.1, 0.0]]))[0, 0] == pytest.approx(-0.2)


@pytest.mark.parametrize("kw, match", [
    ({"Q": [1.0, 1.0, 1.0]}, "Q must have length 2"),
    ({"R": 0.0}, "R must be positive definite"),
    ({"R": "1"}, "R must be a number"),
])
def test_bad_weights_are_refused(kw, match):
    with pytest.raises((DesignError, ValueError), match=match):
        lqr(CartPendulum(), **kw)


def test_the_estimate_is_saturated_only_when_asked():
    law = LinearFeedback([[1.0, 1.0]], x_max=[0.5, 2.0])
    assert law.act(0.0, np.array([[3.0, -9.0]]))[0, 0] == pytest.approx(-(0.5 - 2.0))
    off = LinearFeedback([[1.0, 1.0]], x_max=[0.5, 2.0], saturate=False)
    assert off.act(0.0, np.array([[3.0, -9.0]]))[0, 0] == pytest.approx(6.0)
    with pytest.raises(DesignError, match="saturate must be true or false"):
        LinearFeedback([[1.0, 1.0]], saturate="yes")


def test_u_max_of_the_wrong_length_is_a_dimension_error():
    """One bound per input, or one for all (found by a docs helper: numpy's broadcast error
    came through before)."""
    from hgo_mj.control import LinearFeedback
    from hgo_mj.exceptions import DimensionError

    K = np.zeros((3, 2))
    with pytest.raises(DimensionError, match=r"u_max must be one number or one per input \(3\); "
                                             r"found 2 entries"):
        LinearFeedback(K, u_max=[1.0, 2.0])
    assert LinearFeedback(K, u_max=2.0).u_max.tolist() == [2.0, 2.0, 2.0]
