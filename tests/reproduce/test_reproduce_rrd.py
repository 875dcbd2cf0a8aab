"""Every reproduction records on request: ``hgo-mj reproduce NAME --out DIR --rrd``."""

from __future__ import annotations

import importlib
import inspect

import pytest

from hgo_mj.cli import main
from hgo_mj.reproduce import REPRODUCTIONS, read_summary


@pytest.mark.parametrize("name", sorted(REPRODUCTIONS))
def test_run_takes_rrd(name):
    """``run(out, *, rrd=None, ...)``: what ``--rrd`` passes (the command refuses a ``run``
    without it)."""
    run = importlib.import_module(REPRODUCTIONS[name][0]).run
    params = inspect.signature(run).parameters
    assert "rrd" in params, f"{name}.run{inspect.signature(run)} has no rrd parameter"
    assert params["rrd"].kind is inspect.Parameter.KEYWORD_ONLY
    assert params["rrd"].default is None


@pytest.mark.slow
def test_reproduce_cli_rrd(tmp_path, capsys):
    """``--rrd FILE`` writes that file (and, for a second example with other states, a file
    next to it), listed in the summary and the report."""
    out = tmp_path / "out"
    assert main(["reproduce", "besancon2004", "--out", str(out), "--rrd",
                 str(out / "besancon2004.rrd")]) == 0
    rrd = out / "besancon2004.rrd"
    assert str(rrd) in capsys.readouterr().out
    summary = read_summary(out)
    assert summary["recordings"] == [str(rrd), str(out / "besancon2004_ex2.rrd")]
    for path in summary["recordings"]:
        with open(path, "rb") as fh:
            assert fh.read(4) == b"RRF2"  # a rerun file, closed (non-empty)
        assert path in (out / "report.txt").read_text()


def test_reproduce_cli_without_rrd_writes_none(tmp_path):
    """Without ``--rrd`` no reproduction gets ``rrd`` (the default ``None``): no recording."""
    from hgo_mj.cli import _reproduction_kwargs

    assert _reproduction_kwargs("besancon2004", None) == {}
    assert _reproduction_kwargs("bullinger1998", tmp_path / "b.rrd") == {"rrd": tmp_path / "b.rrd"}


def test_bullinger1998_records_both_runs(tmp_path):
    """The noisy run of Fig. 2 and the noise-free one, in two files, listed in the report."""
    from hgo_mj.reproduce.bullinger1998 import run

    rrd = tmp_path / "b.rrd"
    s = run(tmp_path / "out", rrd=rrd, seeds=1)
    assert s["recordings"] == [str(rrd), str(tmp_path / "b_noise_free.rrd")]
    report = (tmp_path / "out" / "report.txt").read_text()
    for path in s["recordings"]:
        with open(path, "rb") as fh:
            assert fh.read(4) == b"RRF2"
        assert path in report
    assert not run(tmp_path / "none", seeds=1).get("recordings")
