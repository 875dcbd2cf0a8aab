"""Issue 14: property-based fuzzing of scenario documents and API arguments.

Malformed scenario documents are generated from the scenario schema (:data:`hgo_mj.schema.SCHEMA`,
plus the high-gain observer's and the Gaussian stage's constructor parameters): values of the
wrong type per key, out-of-range numbers, missing keys and extra keys, one to three at a time,
applied to a small valid scenario. Each document is run through ``hgo-mj run`` (``main``, in
this process): either it is a valid run (exit 0, the four result files), or it is refused with
exit status 2, one line on stderr and no output files. Anything else (a traceback, another exit
status, files left behind by a refused run) fails.

Deterministic in CI: ``derandomize=True`` and no example database; a bounded number of examples
and a per-example deadline that fits two cores.
"""

from __future__ import annotations

import contextlib
import copy
import datetime
import inspect
import io
import json
import math
import tempfile
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hgo_mj.cli import main
from hgo_mj.exceptions import HgoError
from hgo_mj.observers import HighGainObserver
from hgo_mj.schema import OPEN, SCHEMA, _ok

FUZZ = settings(max_examples=150, derandomize=True, database=None,
                deadline=datetime.timedelta(seconds=60),
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

VALID: dict[str, Any] = {
    "name": "fuzz",
    "plant": {"name": "pendulum", "dt": 0.01, "x0": [0.3, 0.0]},
    "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
    "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    "input": {"type": "constant", "value": [0.0]},
    "run": {"duration": 0.2, "seed": 1, "t_transient": 0.05},
}

#: values of every TOML type, and numbers out of range
POOL: list[Any] = [0, -1, 1, 2, 3, 2.5, 0.0, -0.5, 1e300, -1e300, 1e-300, math.nan, math.inf,
                   -math.inf, True, False, "", "no", "1", "pendulum", [], [1, 2], [True],
                   ["a"], [[1.0]], {}, {"a": 1}, [{"a": 1}], 10 ** 12,
                   datetime.datetime(1979, 5, 27, 7, 32), datetime.date(1979, 5, 27)]

#: keys a family's table takes beyond the schema's (its constructor's parameters)
FAMILY = {
    "observers": [p for p in inspect.signature(HighGainObserver.__init__).parameters
                  if p not in ("self", "system")],
    "stages": ["std", "psd", "sample_time"],
    "input": ["value", "amplitudes", "frequencies", "amplitude", "period", "length"],
}


def _toml(v: Any) -> str:
    """One TOML value (inline tables and arrays), enough for the documents generated here."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if v != v else ("inf" if v == math.inf else "-inf" if v == -math.inf
                                     else repr(v))
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (datetime.datetime, datetime.date)):
        return v.isoformat()
    if isinstance(v, list):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {_toml(x)}" for k, x in v.items()) + "}"
    raise TypeError(v)


def to_toml(doc: dict[str, Any]) -> str:
    return "".join(f"{json.dumps(k)} = {_toml(v)}\n" for k, v in doc.items())


def _table(doc: dict[str, Any], section: str) -> dict[str, Any] | None:
    """The table of the document that a schema section describes (None if it is not one)."""
    if section == "":
        return doc
    if section == "observers":
        obs = doc.get("observers")
        return obs[0] if isinstance(obs, list) and obs and isinstance(obs[0], dict) else None
    if section == "stages":
        sensor = doc.get("sensor")
        stages = sensor.get("stages") if isinstance(sensor, dict) else None
        return stages[0] if isinstance(stages, list) and stages and isinstance(
            stages[0], dict) else None
    t = doc.get(section)
    return t if isinstance(t, dict) else None


SECTIONS = sorted(SCHEMA)


@st.composite
def mutation(draw: Any) -> tuple[str, str, str, Any]:
    section = draw(st.sampled_from(SECTIONS))
    op = draw(st.sampled_from(["wrong", "wrong", "range", "drop", "extra"]))
    keys = list(SCHEMA[section]) + FAMILY.get(section, [])
    key = draw(st.sampled_from(keys))
    if op == "wrong" and key in SCHEMA[section]:
        value = draw(st.sampled_from([v for v in POOL if not _ok(SCHEMA[section][key], v)]))
    elif op == "extra":
        key = draw(st.sampled_from([key, "extra", "sed", "Duration"]))
        value = draw(st.sampled_from(POOL))
    else:
        value = draw(st.sampled_from(POOL))
    return op, section, key, value


def apply(doc: dict[str, Any], mutations: list[tuple[str, str, str, Any]]) -> dict[str, Any]:
    doc = copy.deepcopy(doc)
    for op, section, key, value in mutations:
        table = _table(doc, section)
        if table is None:
            continue
        if op == "drop":
            table.pop(key, None)
        else:
            table[key] = copy.deepcopy(value)
    return doc


def cli(doc: dict[str, Any], out: Path) -> tuple[int, str]:
    """``hgo-mj run`` of the document: its exit status and its stderr."""
    path = out.parent / "s.toml"
    path.write_text(to_toml(doc))
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(["run", str(path), "--out", str(out)])
    return code, err.getvalue()


def run_cli(doc: dict[str, Any]) -> None:
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "out"
        code, err = cli(doc, out)
        if code == 0:
            assert {"trajectory.npz", "metrics.json", "figure.png", "summary.txt"} <= {
                p.name for p in out.iterdir()}
            return
        assert code == 2, (code, err)
        assert err.startswith("hgo-mj: error:") and "Traceback" not in err, err
        assert len(err.strip().splitlines()) == 1, err
        assert not out.exists() or not any(out.iterdir()), sorted(out.iterdir())


def test_the_valid_document_runs():
    run_cli(VALID)


@FUZZ
@given(st.lists(mutation(), min_size=1, max_size=3))
def test_malformed_scenarios_are_a_run_or_one_line(mutations):
    run_cli(apply(VALID, mutations))


@FUZZ
@given(section=st.sampled_from([s for s in SECTIONS if s not in OPEN]), value=st.sampled_from(POOL))
def test_unknown_key_in_a_closed_section_is_refused(section, value):
    doc = apply(VALID, [("extra", section, "not_a_key", value)])
    with tempfile.TemporaryDirectory() as d:
        code, err = cli(doc, Path(d) / "o")
        assert code == 2 and "unknown parameter(s) ['not_a_key']" in err, err


# ---------------------------------------------------------------- API arguments
@settings(max_examples=150, derandomize=True, database=None, deadline=None)
@given(k=st.sampled_from(POOL), order=st.sampled_from(POOL + [None]),
       model=st.sampled_from(POOL), outputs=st.sampled_from(POOL + [(0,)]))
def test_high_gain_arguments_build_or_raise_hgo_errors(k, order, model, outputs):
    from hgo_mj.systems import Pendulum

    try:
        ob = HighGainObserver(Pendulum(), k=k, order=order, model=model, outputs=outputs)
    except HgoError:
        return
    # accepted: the values were of their types, not coerced
    assert isinstance(model, bool) and not isinstance(k, (bool, str))
    assert order is None or (isinstance(order, int) and not isinstance(order, bool))
    assert math.isfinite(ob.k_) and ob.k_ > 0


@pytest.mark.parametrize("kind", sorted(k for k in SCHEMA["run"]))
def test_each_run_key_refuses_every_wrong_type(kind):
    """Exhaustive over the pool for the [run] keys: every value not of the key's type is one
    line naming the key."""
    for value in POOL:
        if _ok(SCHEMA["run"][kind], value):
            continue
        doc = apply(VALID, [("wrong", "run", kind, value)])
        with tempfile.TemporaryDirectory() as d:
            code, err = cli(doc, Path(d) / "o")
            assert code == 2, value
            assert f"run.{kind} must be" in err and len(err.strip().splitlines()) == 1, err


# ---------------------------------------------------------------- study documents
#: a small valid study: the scenario above with a [sweep] table
VALID_STUDY: dict[str, Any] = {**VALID, "sweep": {"seeds": 2, "observers.hgo.k": [10.0, 30.0]}}
#: sweep keys: the table's own, axis paths that exist, and ones that do not
SWEEP_KEYS = ["seeds", "mode", "observers.hgo.k", "sensor.stages.0.std", "plant.x0",
              "run.duration", "plant.name", "observers.hgo", "observers.nobody.k",
              "plant.nokey", "sensor.stages.5.std", "run", "",
              # issue 27: axes that cannot change a run, overlapping axes, the rest of [sweep]
              "run.seed", "run.out", "run.stream", "run.store_every", "sensor",
              "sensor.stages", "together", "store"]


@st.composite
def sweep_mutation(draw: Any) -> tuple[str, str, Any]:
    op = draw(st.sampled_from(["set", "set", "list", "drop"]))
    key = draw(st.sampled_from(SWEEP_KEYS))
    value = draw(st.sampled_from(POOL))
    if op == "list":  # an axis whose values are of any kind
        value = draw(st.lists(st.sampled_from(POOL), min_size=0, max_size=3))
    return op, key, value


def run_sweep(doc: dict[str, Any]) -> None:
    with tempfile.TemporaryDirectory() as d:
        path, out = Path(d) / "s.toml", Path(d) / "out"
        text = to_toml({k: v for k, v in doc.items() if k != "sweep"})
        sweep = doc.get("sweep")
        text += ("[sweep]\n" + "".join(f"{json.dumps(k)} = {_toml(v)}\n" for k, v in
                                       sweep.items())) if isinstance(sweep, dict) else ""
        path.write_text(text)
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main(["sweep", str(path), "--out", str(out), "--quiet"])
        err_text = err.getvalue()
        if code == 0:
            assert {"results.parquet", "summary.md", "study.json"} <= {
                p.name for p in out.iterdir()}
            return
        assert code == 2, (code, err_text)
        assert err_text.startswith("hgo-mj: error:") and "Traceback" not in err_text, err_text
        assert len(err_text.strip().splitlines()) == 1, err_text
        assert not out.exists() or not any(out.iterdir()), sorted(out.iterdir())


def test_the_valid_study_runs():
    run_sweep(VALID_STUDY)


@settings(FUZZ, max_examples=80)
@given(st.lists(sweep_mutation(), min_size=1, max_size=3))
def test_malformed_studies_are_a_study_or_one_line(mutations):
    """Malformed [sweep] tables (wrong types, axes into keys that do not exist, empty or
    mixed axes, seeds out of range): ``hgo-mj sweep`` runs the study or refuses in one line
    with no results folder left."""
    doc = copy.deepcopy(VALID_STUDY)
    for op, key, value in mutations:
        if op == "drop":
            doc["sweep"].pop(key, None)
        else:
            doc["sweep"][key] = copy.deepcopy(value)
    run_sweep(doc)


# ------------------------------------------------------------- ODE expressions (issue 27)
#: the pieces of generated right-hand sides: names the system knows and does not, numbers of
#: every size, operators, functions, brackets and text that is not Python
ODE_TOKENS = ["x1", "x2", "u", "p", "nobody", "0", "1", "2.5", "-3", "1e300", "1e-300",
              "9**9", "10**400", "inf", "nan", "I", "pi", "+", "-", "*", "/", "**", "(", ")",
              "sin(", "cos(", "exp(", "log(", "sqrt(", "Abs(", "acos(", "__import__(", "'os'",
              "lambda", ";", ",", "[", "]", "=", "x1.real", "Heaviside(", "Piecewise(",
              " ", "\\", "#", "é", "\x00"]


@settings(FUZZ, max_examples=150, deadline=datetime.timedelta(seconds=30))
@given(st.lists(st.sampled_from(ODE_TOKENS), min_size=1, max_size=25))
def test_ode_expressions_build_or_are_one_model_error_line(tokens):
    """A generated right-hand side either builds a system whose dynamics give finite floats or
    is refused as one :class:`~hgo_mj.exceptions.ModelError` line (within the deadline): no
    other exception, no hang, no multi-line message."""
    import numpy as np

    from hgo_mj.exceptions import ModelError
    from hgo_mj.systems.symbolic import ode_system

    f1 = "".join(tokens)
    try:
        cls = ode_system(["x1", "x2"], ["x2", f1], "x1", inputs=["u"], params={"p": 1.0})
    except ModelError as exc:
        assert "\n" not in str(exc) and len(str(exc)) < 400, str(exc)
        return
    with np.errstate(all="ignore"):
        dx = np.asarray(cls().f(0.0, np.array([0.1, 0.2]), np.array([0.3])), dtype=float)
    assert dx.shape == (2,)
