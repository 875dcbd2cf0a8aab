"""Every reproduction writes ``summary.json`` as strict JSON (``jq`` reads it): non-finite
numbers become ``null``, which the report prints as "never" (``inf``) / "undefined" (``nan``)."""

from __future__ import annotations

import importlib
import inspect
import json
import math
from pathlib import Path

import numpy as np
import pytest

from hgo_mj._json import strict_json
from hgo_mj.reproduce import (
    REPRODUCTIONS,
    finish,
    fmt_num,
    nonfinite_keys,
    null_note,
    read_summary,
    write_summary,
)


def test_write_summary_maps_non_finite_to_null(tmp_path):
    summary = {"t": math.inf, "neg": -math.inf, "u": float("nan"), "ok": 1.5,
               "arr": np.array([1.0, np.inf, np.nan]), "tup": (np.float64(np.inf), np.int64(3)),
               "nested": {"x": [np.float32(2.0), {"y": float("nan")}]}, "flag": np.bool_(True),
               "path": Path("a/b.rrd"), 7: "int key", "none": None}
    data = write_summary(tmp_path, summary)
    text = (tmp_path / "summary.json").read_text()
    assert "Infinity" not in text and "NaN" not in text
    assert read_summary(tmp_path) == data == json.loads(text)
    assert data["t"] is None and data["neg"] is None and data["u"] is None and data["ok"] == 1.5
    assert data["arr"] == [1.0, None, None] and data["tup"] == [None, 3]
    assert data["nested"] == {"x": [2.0, {"y": None}]}
    assert data["flag"] is True and data["path"] == "a/b.rrd" and data["7"] == "int key"
    assert strict_json(summary) == data
    # what the report says about them
    assert nonfinite_keys(summary) == [("t", "never"), ("neg", "never"), ("u", "undefined"),
                                       ("arr[1]", "never"), ("arr[2]", "undefined"),
                                       ("tup[0]", "never"), ("nested.x[1].y", "undefined")]
    note = null_note(summary, limit=2)
    assert "t = never, neg = never and 5 more" in note
    assert null_note({"a": 1.0}) == ""


def test_read_summary_rejects_python_json_extensions(tmp_path):
    (tmp_path / "summary.json").write_text(json.dumps({"t": math.inf}))  # 'Infinity'
    with pytest.raises(ValueError, match="Infinity"):
        read_summary(tmp_path)
    (tmp_path / "summary.json").write_text(json.dumps({"t": [math.nan]}))
    with pytest.raises(ValueError, match="NaN"):
        read_summary(tmp_path)


def test_fmt_num():
    assert fmt_num(math.inf) == fmt_num(None) == "never"
    assert fmt_num(float("nan")) == "undefined"
    assert fmt_num(np.float64(1.23456), ".2f") == "1.23" and fmt_num(3, "5.1f") == "  3.0"


@pytest.mark.parametrize("name", sorted(REPRODUCTIONS))
def test_every_reproduction_writes_through_write_summary(name):
    """Each ``run`` writes ``summary.json`` with :func:`write_summary`, through :func:`finish`
    (no other ``json.dumps`` in the module). The numbers themselves are read back strictly by
    each reproduction's test (``read_summary``); ``besancon2004``
    (``tests/reproduce/test_besancon2004.py``) has a non-finite one."""
    module = importlib.import_module(REPRODUCTIONS[name][0])
    src = inspect.getsource(module)
    assert "write_summary(out, summary)" in inspect.getsource(finish)
    assert "finish(out, summary, " in inspect.getsource(module.run)
    assert "json.dumps" not in src and '"summary.json").write_text' not in src
