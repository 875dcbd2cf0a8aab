"""Every registered observer pickles (Gymnasium's AsyncVectorEnv with spawn, users copying an
observer) and the copy continues exactly as the original: the same estimates, to the bit."""

from __future__ import annotations

import copy
import pickle
from typing import Any

import numpy as np
import pytest
from observer_cases import CASES, DT, signals

from hgo_mj.observers import OBSERVERS
from hgo_mj.observers.base import Observer
from hgo_mj.observers.bastin_gevers import AOCF
from hgo_mj.observers.jo_son import JoSonForm, JoSonObserver
from hgo_mj.systems import (
    JoSonExample,
    Pendulum,
)


def _params() -> list[Any]:
    out = []
    for kind, cid, make, p, m in CASES:
        out.append(pytest.param(kind, make, p, m, id=f"{kind}-{cid}"))
    return out


def test_every_registered_observer_has_a_case():
    assert {c[0] for c in CASES} == set(OBSERVERS)


def _snapshot(ob: Observer) -> list[Any]:
    out: list[Any] = [ob.x_hat, ob.diagnostics()]
    for name in ("theta_hat_", "P_", "Gamma_", "z_hat"):
        if hasattr(ob, name):
            out.append(getattr(ob, name))
    return out


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and np.array_equal(a.view(np.int64), b.view(np.int64))


@pytest.mark.parametrize("kind,make,p,m", _params())
def test_observer_pickles_and_continues_identically(kind, make, p, m):
    ob = make()
    assert ob.name == kind
    ob.check_period(DT)
    for k in range(5):
        ob.update(*signals(k, p, m), DT)
    blob = pickle.dumps(ob)
    twin = pickle.loads(blob)
    assert type(twin) is type(ob) and _same(_snapshot(twin), _snapshot(ob))
    for k in range(5, 12):  # through the dropout at k = 7
        y, u = signals(k, p, m)
        assert _same(twin.update(y, u, DT), ob.update(y, u, DT)), k
        assert _same(_snapshot(twin), _snapshot(ob)), k
    # the copy pickles again, and a deep copy continues alike
    again = pickle.loads(pickle.dumps(twin))
    deep = copy.deepcopy(twin)
    y, u = signals(12, p, m)
    ref = ob.update(y, u, DT)
    for c in (twin, again, deep):
        assert _same(c.update(y, u, DT), ref)


def test_forms_pickle_as_the_factory_call_that_built_them():
    s = Pendulum()
    form = AOCF.pendulum(s, c2=3.0, unknown=("d_over_J", "g_over_l", "b_over_J"))
    twin = pickle.loads(pickle.dumps(form))
    assert twin.label == form.label and twin.theta_names == form.theta_names
    np.testing.assert_array_equal(twin.alpha, form.alpha)
    np.testing.assert_array_equal(twin.omega(0.3, np.array([0.2])), form.omega(0.3, np.array([0.2])))
    jf = pickle.loads(pickle.dumps(JoSonExample().form("jo_son")))
    assert jf.label == "Jo-Son example eq. 31" and jf.beta(2.0, np.array([3.0])) == (6.0,)


def test_a_form_of_local_functions_does_not_pickle():
    """A form built by hand from closures has no recipe: pickle says what it cannot store."""
    form = JoSonForm([1.0], lambda y, u: (0.0,), lambda y, u: (u[0],), theta_names=("b",))
    with pytest.raises((pickle.PicklingError, AttributeError, TypeError)):
        pickle.dumps(JoSonObserver(form=form))
