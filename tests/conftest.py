"""Shared test fixtures: a chain-of-integrators system whose y^(n) is the input itself."""

from __future__ import annotations

import numpy as np
import pytest

from hgo_mj.systems.base import System


def integrator_chain(n: int) -> type[System]:
    """System ``y^(n) = u``: the normal form is the state itself and ``phi(z, u) = u``."""

    class IntegratorChain(System):
        name = f"chain{n}"
        state_names = tuple(f"x{i + 1}" for i in range(n))
        input_names = ("w",)
        output_names = ("y",)
        default_x0 = (0.0,) * n
        normal_form_order = n

        @staticmethod
        def dynamics(t, x, u, p):
            dx = np.empty(n)
            dx[:-1] = x[1:]
            dx[-1] = u[0]
            return dx

        @staticmethod
        def output(x, p):
            return x[:1].copy()

        def to_normal(self, x, u=None):
            return np.array(x, dtype=float)

        def from_normal(self, z, u=None):
            return np.array(z, dtype=float)

        def phi(self, z, u=None):
            return float(u[0])

    return IntegratorChain


@pytest.fixture
def chain():
    return integrator_chain


@pytest.fixture(autouse=True)
def _close_pyplot_figures():
    """Close what a test left open where pyplot is loaded: hgo_mj's figures are pyplot's when
    the user has imported pyplot (so that ``plt.show()`` works), and pyplot keeps them."""
    yield
    import sys

    plt = sys.modules.get("matplotlib.pyplot")
    if plt is not None:
        plt.close("all")
