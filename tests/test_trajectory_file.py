"""``Trajectory.load`` on damaged and crafted files: every one is a ``TrajectoryFileError``
(an ``HgoError`` and a ``ValueError``) naming the file and what is wrong, never a raw
ValueError, KeyError, JSONDecodeError, TypeError, RecursionError or MemoryError; pickles stay
refused; a file that ``save`` wrote loads unchanged."""

from __future__ import annotations

import io
import json
import pickle
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hgo_mj.exceptions import DimensionError, HgoError, TrajectoryFileError
from hgo_mj.observers import make_observer
from hgo_mj.plants import make_plant
from hgo_mj.simulate import Trajectory, simulate


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    """A saved run (one observer with diagnostics) and its columns as ``np.load`` reads them."""
    plant = make_plant("pendulum", 0.01)
    traj = simulate(plant, None, {"hgo": make_observer("high_gain", plant.system, k=20.0)},
                    lambda t: [0.0], duration=0.05, x0=[0.2, 0.0])
    path = traj.save(tmp_path_factory.mktemp("saved") / "run.npz")
    with np.load(path) as z:
        cols = {k: z[k] for k in z.files}
    return path, cols


def _meta(cols):
    return json.loads(str(cols["__meta__"]))


def _with_meta(cols, **changes):
    meta = _meta(cols)
    meta.update(changes)
    return {**cols, "__meta__": np.array(json.dumps(meta))}


def _write(path, cols):
    np.savez(path, **cols)
    return path


def _refused(path, match):
    with pytest.raises(TrajectoryFileError, match=match) as err:
        Trajectory.load(path)
    msg = str(err.value)
    assert msg.startswith(str(path)) and "\n" not in msg, msg
    return err.value


def test_a_saved_file_loads_unchanged(saved):
    path, cols = saved
    back = Trajectory.load(path)
    np.testing.assert_array_equal(back.x, cols["x"])
    assert back.state_names == ("angle", "angular_velocity")
    assert issubclass(TrajectoryFileError, HgoError) and issubclass(TrajectoryFileError,
                                                                      ValueError)


def _crafted(cols):
    """name -> (columns or raw bytes, the message it must give)."""
    meta = _meta(cols)
    obs = meta["observers"]["hgo"]
    return {
        "no __meta__": ({k: v for k, v in cols.items() if k != "__meta__"}, "no __meta__"),
        "__meta__ not JSON": ({**cols, "__meta__": np.array("{'a': 1")}, "__meta__ is not JSON"),
        "__meta__ numbers": ({**cols, "__meta__": np.arange(3)}, "must be one JSON string"),
        "__meta__ a list": ({**cols, "__meta__": np.array("[1, 2]")}, "must be a JSON object"),
        "nested JSON": ({**cols, "__meta__": np.array("[" * 100_000 + "]" * 100_000)},
                        "nested too deeply"),
        "no t": ({k: v for k, v in cols.items() if k != "t"}, "no column 't'"),
        "text column": ({**cols, "x": np.array(["a", "b"])}, "column 'x' must be an array of "
                                                             "numbers"),
        "state names repeated": (_with_meta(cols, state_names=["angle", "angle"]),
                                 r"state_names must be distinct; \['angle'\] appear"),
        "state names not strings": (_with_meta(cols, state_names=[1, 2]),
                                    "state_names must be a list of strings"),
        "observers a list": (_with_meta(cols, observers=[1]), "observers must be an object"),
        "observer without columns": (_with_meta(cols, observers={"ghost": {"diagnostics": []}}),
                                     "no column 'obs/ghost/x_hat'"),
        "diagnostics not a list": (_with_meta(cols, observers={"hgo": {**obs, "diagnostics": 3}}),
                                   "observer 'hgo': diagnostics must be a list of strings"),
        "update time text": (_with_meta(cols, observers={"hgo": {**obs, "update_time": "x"}}),
                             "update_time must be a number"),
        "metadata a string": (_with_meta(cols, metadata="x"), "metadata must be an object"),
        "x too wide": ({**cols, "x": np.zeros((len(cols["t"]), 5))},
                       r"column 'x' must have shape \(rows, 2\)"),
        "rows disagree": ({**cols, "u": cols["u"][:2]}, "column u must have 6 rows"),
    }


CASES = ["no __meta__", "__meta__ not JSON", "__meta__ numbers", "__meta__ a list", "nested JSON",
         "no t", "text column", "state names repeated", "state names not strings",
         "observers a list", "observer without columns", "diagnostics not a list",
         "update time text", "metadata a string", "x too wide", "rows disagree"]


@pytest.mark.parametrize("case", CASES)
def test_a_crafted_file_is_one_trajectory_file_error_naming_it(saved, tmp_path, case):
    _, cols = saved
    crafted, match = _crafted(cols)[case]
    assert sorted(_crafted(cols)) == sorted(CASES)
    _refused(_write(tmp_path / "bad.npz", crafted), match)


def test_columns_of_different_lengths_stay_a_dimension_error(saved, tmp_path):
    _, cols = saved
    err = _refused(_write(tmp_path / "bad.npz", {**cols, "x": cols["x"][:3]}),
                   r"column x must have 6 rows .*found shape \(3, 2\)")
    assert isinstance(err, DimensionError)


def test_pickles_and_other_formats_are_refused(tmp_path):
    pkl = tmp_path / "run.npz"
    pkl.write_bytes(pickle.dumps({"t": [0.0]}))
    _refused(pkl, "not an .npz archive .* pickles and other formats are refused")
    npy = tmp_path / "x.npz"
    np.save(npy.with_suffix(".npy"), np.zeros(3))
    npy.write_bytes(npy.with_suffix(".npy").read_bytes())
    _refused(npy, "not an .npz archive")
    obj = tmp_path / "obj.npz"
    np.savez(obj, t=np.array([{"a": 1}], dtype=object))
    _refused(obj, r"column 't.npy' holds object values \(pickled objects are refused")
    (tmp_path / "torn.npz").write_bytes(b"PK\x03\x04" + b"\0" * 40)
    _refused(tmp_path / "torn.npz", r"not a trajectory written by Trajectory.save \(BadZipFile")
    with pytest.raises(FileNotFoundError):
        Trajectory.load(tmp_path / "missing.npz")


def test_a_header_asking_for_more_than_the_file_holds_is_refused_before_reading(saved,
                                                                               tmp_path):
    """A column whose .npy header declares 10^12 rows (8 TB) in a few bytes: refused from the
    header, nothing allocated (it was a MemoryError)."""
    _, cols = saved
    path = _write(tmp_path / "bomb.npz", cols)
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False,
                                                  "shape": (10**12,)})
    with zipfile.ZipFile(path, "a") as zf:
        zf.writestr("big.npy", header.getvalue() + b"\0" * 64)
    _refused(path, r"column 'big.npy' declares shape \(1000000000000,\) of float64 "
                   r"\(8000000000000 bytes\) but holds \d+")


def _mutations():
    """One change to one column of a saved file: its values, dtype, shape, or the JSON
    metadata's entries (types, names, nesting)."""
    json_values = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() |
                               st.text(max_size=5),
                               lambda c: st.lists(c, max_size=3) |
                               st.dictionaries(st.text(max_size=5), c, max_size=3),
                               max_leaves=8)
    meta_keys = st.sampled_from(["state_names", "output_names", "input_names", "observers",
                                 "metadata", "extra"])
    arrays = st.one_of(
        st.builds(np.zeros, st.tuples(st.integers(0, 8))),
        st.builds(np.zeros, st.tuples(st.integers(0, 8), st.integers(0, 4))),
        st.builds(np.zeros, st.tuples(st.integers(0, 3), st.integers(0, 3), st.integers(0, 3))),
        st.builds(np.array, st.text(max_size=20)),
        st.builds(np.array, st.lists(st.booleans(), max_size=6)),
        st.builds(lambda v: np.array(v, dtype=np.complex128), st.lists(st.floats(), max_size=6)),
        st.just(np.array(3.0)))
    return st.one_of(
        st.tuples(st.just("meta"), meta_keys, json_values),
        st.tuples(st.just("column"), st.sampled_from(["t", "x", "y_clean", "y_meas", "u",
                                                      "obs/hgo/x_hat", "obs/hgo/z_hat",
                                                      "__meta__"]), arrays),
        st.tuples(st.just("drop"), st.sampled_from(["t", "x", "u", "obs/hgo/z_hat", "__meta__"]),
                  st.none()),
        st.tuples(st.just("bytes"), st.integers(0, 10_000), st.binary(min_size=1, max_size=8)))


@settings(max_examples=120, derandomize=True, database=None, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(change=_mutations())
def test_fuzz_a_mutated_file_loads_or_is_one_trajectory_file_error(saved, tmp_path, change):
    path, cols = saved
    kind, key, value = change
    bad = tmp_path / "fuzz.npz"
    if kind == "meta":
        _write(bad, _with_meta(cols, **{key: value}))
    elif kind == "column":
        _write(bad, {**cols, key: value})
    elif kind == "drop":
        _write(bad, {k: v for k, v in cols.items() if k != key})
    else:  # bytes overwritten somewhere in the compressed file
        data = bytearray(path.read_bytes())
        at = key % len(data)
        data[at:at + len(value)] = value
        bad.write_bytes(bytes(data))
    try:
        back = Trajectory.load(bad)
    except TrajectoryFileError as exc:
        assert str(exc).startswith(str(bad)) and "\n" not in str(exc)
        return
    assert len(back) == len(back.t) and back.x.shape[1] == len(back.state_names)
    assert len(set(back.state_names)) == len(back.state_names)
