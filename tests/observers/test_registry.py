"""Registration: the families register themselves; an observer of another package is found
through the entry-point group ``hgo_mj.observers`` and used by name."""

from __future__ import annotations

import sys
import textwrap

import numpy as np
import pytest

import hgo_mj.observers.base as base
from hgo_mj.exceptions import DesignError
from hgo_mj.observers import OBSERVERS, HighGainObserver, Observer, make_observer, register

_EXT = '''
import numpy as np
from hgo_mj.observers import Observer


class HoldObserver(Observer):
    """Holds the last measurement (an observer another package ships)."""

    name = "hold_last"
    needs_normal_form = False

    def __init__(self, system=None, *, outputs=(0,)):
        super().__init__(system, order=1, outputs=outputs)

    def _init(self, p, x0, z0, u0):
        return {"z": np.zeros((u0.shape[0], 1)) if z0 is None else z0.copy()}

    def _step(self, p, s, Y, U, dt, X, Z, D):
        for j in range(Y.shape[1]):
            ok = ~np.isnan(Y[:, j, 0])
            s.z[ok, 0] = Y[ok, j, 0]
            Z[:, j] = s.z
            X[:, j] = s.z

    def _current(self, p, s):
        return s.z.copy(), s.z.copy(), np.zeros((s.z.shape[0], 0))
'''


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    """A package ``extobs`` with an entry point ``hold_last = extobs:HoldObserver``."""
    (tmp_path / "extobs.py").write_text(textwrap.dedent(_EXT))
    info = tmp_path / "extobs-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: extobs\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[hgo_mj.observers]\nhold_last = extobs:HoldObserver\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(base, "_ENTRY_POINTS_LOADED", False)
    yield tmp_path
    OBSERVERS.pop("hold_last", None)
    sys.modules.pop("extobs", None)


def test_every_family_is_registered_by_its_decorator():
    assert {"high_gain", "high_gain_multi", "adaptive_gain", "riccati", "q_integral",
            "besancon", "jo_son", "ekf", "ukf", "ekf_mujoco", "ukf_mujoco"} <= set(OBSERVERS)
    assert OBSERVERS["high_gain"] is HighGainObserver
    for name, cls in OBSERVERS.items():
        assert issubclass(cls, Observer) and cls.name == name


def test_an_observer_of_another_package_is_used_by_name(plugin):
    ob = make_observer("hold_last", None)
    assert type(ob).__name__ == "HoldObserver" and "hold_last" in OBSERVERS
    ob.reset()
    np.testing.assert_array_equal(ob.update(np.array([0.3]), np.zeros(1), 0.01), [0.3])
    np.testing.assert_array_equal(ob.update(np.array([np.nan]), np.zeros(1), 0.01), [0.3])
    assert ob.dropouts_ == 1 and ob.diagnostic_names == ("dropouts",)


def test_a_broken_entry_point_names_itself(tmp_path, monkeypatch):
    info = tmp_path / "broken-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: broken\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[hgo_mj.observers]\nnope = no_such_module:Nope\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(base, "_ENTRY_POINTS_LOADED", False)
    with pytest.raises(DesignError, match="entry point 'nope' = 'no_such_module:Nope' of group "
                                          "hgo_mj.observers does not import"):
        make_observer("high_gain", None, order=2, k=1.0)
    monkeypatch.setattr(base, "_ENTRY_POINTS_LOADED", True)


def test_register_refuses_what_is_not_an_observer_or_a_second_name():
    with pytest.raises(DesignError, match="register takes an Observer subclass"):
        register(int)  # type: ignore[type-var]

    class Twin(HighGainObserver):
        name = "high_gain"

    with pytest.raises(DesignError, match="an observer named 'high_gain' is registered already"):
        register(Twin)


def test_unknown_names_and_keywords_list_the_valid_ones():
    with pytest.raises(DesignError, match=r"unknown observer 'nope'; valid: \['adaptive_gain'"):
        make_observer("nope")
    with pytest.raises(DesignError, match=r"observer 'high_gain': unknown parameter\(s\) \['kk'\]; "
                                          r"valid: \['k', "):
        make_observer("high_gain", None, kk=3.0)
