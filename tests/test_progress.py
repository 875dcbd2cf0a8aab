"""Progress on stderr (hgo_mj.progress): a tqdm bar on a terminal, a line per tenth otherwise,
nothing with quiet; ``hgo-mj run --seeds`` and ``hgo-mj reproduce`` use it, and a reproduction
prints its report, not its JSON."""

from __future__ import annotations

import sys
import types

import pytest

from hgo_mj.cli import main
from hgo_mj.progress import Progress, seconds, track


def test_lines_at_every_tenth_without_a_terminal():
    lines: list[str] = []
    with Progress(25, unit="case", desc="job", echo=lines.append) as p:
        for _ in range(25):
            p.add()
    assert len(lines) == 10
    assert lines[0].startswith("job:  12% 3/25 cases")
    assert lines[-1].startswith("job: 100% 25/25 cases") and "ETA 1 s" in lines[-1]


def test_quiet_and_empty_jobs_say_nothing(capsys):
    with Progress(5, quiet=True) as p:
        p.add(5)
    with Progress(0) as p:
        p.add(0)
    assert list(track(["a", "b"], quiet=True)) == ["a", "b"]
    assert capsys.readouterr().err == ""


def test_a_terminal_gets_a_tqdm_bar(capsys, monkeypatch):
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    assert list(track(range(3), desc="bar test", unit="run")) == [0, 1, 2]
    err = capsys.readouterr().err
    assert "bar test" in err and "3/3" in err and "run/s" in err  # tqdm's rate and counts


def test_a_generator_with_a_total_is_not_consumed_ahead(capsys):
    seen = []

    def gen():
        for i in range(4):
            seen.append(i)
            yield i

    for i in track(gen(), total=4):
        assert seen == list(range(i + 1))  # each item made when it is asked for
    assert "100% 4/4 runs" in capsys.readouterr().err


def test_seconds_for_people():
    assert [seconds(v) for v in (0.2, 12.4, 90.0, 7200.0)] == ["1 s", "12 s", "1.5 min", "2.0 h"]


RUN = ["run", "--plant", "pendulum", "--observer", "high_gain:k=20", "--duration", "0.3",
       "--seeds", "3"]


def test_run_seeds_shows_progress_unless_quiet(tmp_path, capsys):
    assert main([*RUN, "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert "100% 2/2 runs" in err  # the seeds after the first, as a study
    assert main([*RUN, "--out", str(tmp_path / "b"), "--quiet"]) == 0
    assert capsys.readouterr().err == ""


@pytest.fixture
def fake_reproduction(monkeypatch):
    from hgo_mj import reproduce

    seen = {}

    def run(out, *, rrd=None, quiet=False):
        seen["quiet"] = quiet
        with Progress(2, unit="part", desc="fake", quiet=quiet) as p:
            p.add(2)
        return reproduce.finish(out, {"x": 1.5}, "Fake (2026) -- reproduction\nx = 1.5: HOLDS\n")

    monkeypatch.setitem(sys.modules, "hgo_mj.reproduce.fake", types.SimpleNamespace(run=run))
    monkeypatch.setitem(reproduce.REPRODUCTIONS, "fake", ("hgo_mj.reproduce.fake", "fake"))
    return seen


def test_reproduce_prints_its_report_not_its_json(tmp_path, capsys, fake_reproduction):
    assert main(["reproduce", "fake", "--out", str(tmp_path)]) == 0
    cap = capsys.readouterr()
    assert cap.out.startswith("Fake (2026) -- reproduction\nx = 1.5: HOLDS\n")
    assert '"x"' not in cap.out and "versions" not in cap.out
    assert "fake: 100% 2/2 parts" in cap.err and fake_reproduction["quiet"] is False
    assert main(["reproduce", "fake", "--out", str(tmp_path), "--quiet"]) == 0
    assert capsys.readouterr().err == "" and fake_reproduction["quiet"] is True


def test_every_reproduction_takes_quiet():
    import inspect

    from hgo_mj.cli import run_of
    from hgo_mj.reproduce import REPRODUCTIONS

    for name in REPRODUCTIONS:
        p = inspect.signature(run_of(name)).parameters["quiet"]
        assert p.kind is p.KEYWORD_ONLY and p.default is False, name
