"""The `hgo-mj` command: run (flags and TOML), list, demo, and its errors."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from hgo_mj.cli import main, parse_spec
from hgo_mj.simulate import Trajectory

SCENARIO = """
name = "pend"
[plant]
name = "pendulum"
x0 = [0.4, 0.0]
[sensor]
stages = [{stage = "gaussian", std = 1e-3}, {stage = "quantize", counts_per_rev = 4096}]
[[observers]]
type = "high_gain"
name = "slow"
k = 15.0
[[observers]]
type = "high_gain"
name = "fast"
k = 60.0
[input]
type = "multisine"
amplitudes = [0.2]
frequencies = [0.5]
[run]
duration = 2.0
seed = 4
t_transient = 0.5
"""


def test_parse_spec():
    assert parse_spec("high_gain:k=5,p=[2, 1],method=rk4,model=true", "type") == {
        "type": "high_gain", "k": 5, "p": [2, 1], "method": "rk4", "model": True}


def test_run_toml_writes_results(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(SCENARIO)
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "slow" in printed and "fast" in printed and "rmse" in printed
    metrics = json.loads((out / "metrics.json").read_text())
    assert set(metrics) == {"slow", "fast"}
    traj = Trajectory.load(out / "trajectory.npz")
    assert len(traj) == 2001 and traj.metadata["scenario"] == "pend"
    assert traj.metadata["seed"] == 4
    np.testing.assert_allclose(metrics["fast"]["rmse"],
                               np.sqrt(np.mean(traj.error("fast")[traj.t >= 0.5] ** 2, axis=0)))
    assert (out / "figure.png").stat().st_size > 10_000


def test_flags_equal_toml(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SCENARIO)
    main(["run", str(path), "--out", str(tmp_path / "a")])
    main(["run", "--plant", "pendulum", "--sensor", "gaussian:std=1e-3",
          "--sensor", "quantize:counts_per_rev=4096", "--observer", "high_gain:name=slow,k=15",
          "--observer", "high_gain:name=fast,k=60",
          "--input", "multisine:amplitudes=[0.2],frequencies=[0.5]", "--duration", "2",
          "--seed", "4", "--out", str(tmp_path / "b")])
    a = Trajectory.load(tmp_path / "a" / "trajectory.npz")
    b = Trajectory.load(tmp_path / "b" / "trajectory.npz")
    # the TOML starts at x0 = (0.4, 0); the flags at the model's default state
    assert not np.array_equal(a.x, b.x)
    assert a.y_meas.shape == b.y_meas.shape


def test_list_names_everything(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for word in ("elastic_joint", "cart_pendulum", "bioreactor_bullinger", "gaussian", "quantize",
                 "dropout", "high_gain", "paper 000", "multisine"):
        assert word in out


@pytest.mark.parametrize("argv, message", [
    (["run", "--plant", "pendulm", "--duration", "1"],
     "unknown plant 'pendulm'; valid: ['acrobot'"),
    (["run", "--plant", "pendulum", "--observer", "kalman:k=1", "--duration", "1"],
     "unknown observer 'kalman'; valid: ["),
    (["run", "--plant", "pendulum", "--observer", "high_gain:k=1,p=[-1,1]", "--duration", "1"],
     "Hurwitz"),
    (["run", "--plant", "pendulum", "--sample-period", "0.0015", "--duration", "1"],
     "sample_period = 0.0015 must be a positive integer multiple"),
    (["run", "--plant", "pendulum", "--sensor", "gaussian:std=-0.1", "--duration", "1"],
     "std must be >= 0; found -0.1"),
    (["run", "--plant", "pendulum", "--observer", "high_gain:k=nan", "--duration", "1"],
     "k must be finite"),
    (["run", "--plant", "pendulum"], "needs run.duration"),
    (["run", "missing.toml"], "does not exist"),
])
def test_bad_input_exits_2_with_one_line(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("hgo-mj: error:") and message in err and "Traceback" not in err


def test_nan_in_scenario_file(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(SCENARIO.replace("k = 15.0", "k = nan"))
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "k must be finite; found nan" in capsys.readouterr().err


def test_unknown_scenario_key(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(SCENARIO.replace("seed = 4", "seed = 4\nsed = 5"))
    assert main(["run", str(path)]) == 2
    assert "unknown parameter(s) ['sed']" in capsys.readouterr().err


def test_console_script_demo(tmp_path):
    res = subprocess.run([sys.executable, "-m", "hgo_mj.cli", "demo", "--out",
                          str(tmp_path / "demo")], capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    assert "hgo_k25" in res.stdout and "hgo_k200" in res.stdout
    m = json.loads((tmp_path / "demo" / "metrics.json").read_text())
    # the demo's point, state by state: the high gain wins on the link angle and velocity (the
    # unmodelled fourth derivative matters less), the low gain on the motor velocity, which
    # needs the third derivative of the link angle and so carries the encoder noise times k^3
    assert m["hgo_k200"]["rmse"][0] < 0.5 * m["hgo_k25"]["rmse"][0]
    assert m["hgo_k200"]["rmse"][2] < 0.5 * m["hgo_k25"]["rmse"][2]
    assert m["hgo_k25"]["rmse"][3] < 0.8 * m["hgo_k200"]["rmse"][3]


def test_list_sizes_name_columns_to_the_longest_name(capsys):
    """Every section's descriptions start in one column, one space after its longest name
    (``high_gain_multi`` used to run into its summary)."""
    from hgo_mj.inputs import SIGNALS
    from hgo_mj.observers import OBSERVERS
    from hgo_mj.plants import LAB_PLANTS
    from hgo_mj.reproduce import PAPERS, REPRODUCTIONS
    from hgo_mj.sensors import STAGES
    from hgo_mj.systems import SYSTEMS

    assert main(["list"]) == 0
    out = capsys.readouterr().out
    sections = dict(zip(("PLANTS", "SENSOR STAGES", "OBSERVERS", "INPUTS", "REPRODUCTIONS",
                         "PAPERS"),
                        ([*SYSTEMS, *LAB_PLANTS], STAGES, OBSERVERS, SIGNALS, REPRODUCTIONS,
                         PAPERS)))
    blocks = out.split("\n\n")
    assert len(blocks) == len(sections)
    for block, (title, names) in zip(blocks, sections.items()):
        head, *rows = block.splitlines()
        assert head.startswith(title)
        width = max(len(n) for n in names)
        entries = [r for r in rows if r[2:3] != " "]  # name rows (not continuation lines)
        assert [r[2:].split(" ", 1)[0] for r in entries] == list(names), title
        for r in rows:
            assert r[2 + width] == " " and r[3 + width] != " ", (title, r)
    observers = blocks[2].splitlines()
    width = max(len(n) for n in OBSERVERS)
    multi = next(r for r in observers if r.startswith("  high_gain_multi "))
    assert multi[3 + width:].startswith(OBSERVERS["high_gain_multi"].summary)


def test_version_is_the_installed_one(capsys):
    from importlib.metadata import version

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"hgo-mj {version('hgo_mj')}"
    res = subprocess.run([sys.executable, "-m", "hgo_mj.cli", "--version"], capture_output=True,
                         text=True, timeout=120)
    assert res.returncode == 0 and res.stdout.strip() == f"hgo-mj {version('hgo_mj')}"


def _all_parsers(parser):
    """The parser and every subcommand's parser, depth first."""
    import argparse

    yield parser.prog, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                yield from _all_parsers(sub)


def test_every_flag_of_every_subcommand_has_help():
    import argparse

    from hgo_mj.cli import build_parser

    seen, missing = set(), []
    for prog, parser in _all_parsers(build_parser()):
        seen.add(prog)
        for action in parser._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            if not (action.help or "").strip() or action.help == argparse.SUPPRESS:
                missing.append(f"{prog} {'/'.join(action.option_strings) or action.dest}")
    assert seen == {"hgo-mj", *(f"hgo-mj {c}" for c in ("run", "sweep", "tune", "bench", "check",
                                                       "list", "reproduce", "demo"))}
    assert not missing, missing


def test_t_transient_and_band_flags_set_the_run_keys(tmp_path):
    """``--t-transient`` and ``--band`` give the metrics of the TOML keys ``run.t_transient``
    and ``run.band``, and differ from the defaults."""
    path = tmp_path / "s.toml"
    path.write_text(SCENARIO.replace("t_transient = 0.5", ""))
    with_keys = tmp_path / "k.toml"
    with_keys.write_text(SCENARIO.replace("t_transient = 0.5", "t_transient = 1.2\nband = 0.2"))
    assert main(["run", str(path), "--out", str(tmp_path / "default")]) == 0
    assert main(["run", str(path), "--t-transient", "1.2", "--band", "0.2",
                 "--out", str(tmp_path / "flags")]) == 0
    assert main(["run", str(with_keys), "--out", str(tmp_path / "keys")]) == 0
    default, flags, keys = (json.loads((tmp_path / d / "metrics.json").read_text())
                            for d in ("default", "flags", "keys"))
    def without_timing(m):  # the wall time per update differs from run to run
        return {o: {k: v for k, v in mo.items() if k != "update_time"} for o, mo in m.items()}

    assert without_timing(flags) == without_timing(keys)
    traj = Trajectory.load(tmp_path / "flags" / "trajectory.npz")
    np.testing.assert_allclose(flags["fast"]["rmse"],
                               np.sqrt(np.mean(traj.error("fast")[traj.t >= 1.2] ** 2, axis=0)))
    assert flags["fast"]["rmse"] != default["fast"]["rmse"]
    assert flags["slow"]["settling_time"] != default["slow"]["settling_time"]


def test_bad_t_transient_flag_exits_2(tmp_path, capsys):
    assert main(["run", "--plant", "pendulum", "--observer", "high_gain:k=10", "--duration", "1",
                 "--t-transient", "-1", "--out", str(tmp_path / "o")]) == 2
    assert "t_transient" in capsys.readouterr().err


def test_list_cites_papers_by_authors_year_title_venue(capsys):
    """``hgo-mj list`` names no paper file (the hash names exist nowhere in the repository):
    every ``paper NNN`` it mentions is cited in its PAPERS section by authors, year, title and
    venue."""
    import re

    from hgo_mj.reproduce import PAPERS

    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert not re.search(r"\d{3}_[0-9a-f]{16}", out)
    body, papers = out.split("\nPAPERS")
    cited = set(re.findall(r"paper (\d{3})", body))
    assert cited and cited <= set(PAPERS)
    for number in cited:
        line = next(r for r in papers.splitlines() if r.startswith(f"  {number} "))
        authors, rest = line[6:].split(" (", 1)
        year, title_venue = rest.split("), ", 1)
        assert "." in authors and year.isdigit() and len(title_venue.split(", ")) >= 2, line


def _help(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 0
    return capsys.readouterr().out


def test_help_is_plain_text_and_lists_every_command(capsys):
    """``hgo-mj --help``: no reStructuredText or Markdown markup, and every command both in
    the description and in the list of commands; ``reproduce --help`` names every
    reproduction."""
    import argparse

    from hgo_mj.cli import build_parser
    from hgo_mj.reproduce import REPRODUCTIONS

    text = _help(["--help"], capsys)
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    assert {"run", "sweep", "tune", "bench", "check", "list", "reproduce", "demo"} <= set(
        sub.choices)
    description = text.split("positional arguments")[0]
    for command in sub.choices:
        assert f"{command} (" in description, command
        assert f"\n    {command}" in text, command
        assert "`" not in _help([command, "--help"], capsys), command
    assert "`" not in text
    reproduce = " ".join(_help(["reproduce", "--help"], capsys).split())
    for name in REPRODUCTIONS:
        assert name in reproduce


@pytest.mark.parametrize("argv", [["run", "--rrd", "scenario.toml"],
                                  ["run", "scenario.toml", "--rrd"],
                                  ["reproduce", "ibrir2007", "--rrd", "out"],
                                  ["demo", "--rrd", "runs/demo"]])
def test_rrd_takes_a_file_ending_in_rrd_only(argv, capsys):
    """``--rrd FILE.rrd``: a flag without a value, or a value not ending in ``.rrd`` (a
    scenario file, a folder), is refused before any work; it never takes the positional."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "--rrd" in err
    from hgo_mj.cli import build_parser

    args = build_parser().parse_args(["run", "s.toml", "--rrd", "r.rrd"])
    assert args.scenario == "s.toml" and str(args.rrd) == "r.rrd"


def test_bare_words_inside_lists():
    """A bare word is a string alone or inside a list or table, as the message says; numbers,
    inf and true stay what they are."""
    from hgo_mj.cli import parse_value
    from hgo_mj.exceptions import DesignError

    assert parse_spec("ekf:estimate=[stiffness],Q=1e-3", "type") == {
        "type": "ekf", "estimate": ["stiffness"], "Q": 1e-3}
    assert parse_value("[stiffness, damping_ratio, 1e-3, inf, true]") == [
        "stiffness", "damping_ratio", 1e-3, float("inf"), True]
    assert parse_value("{a = b, c = [d, 2]}") == {"a": "b", "c": ["d", 2]}
    with pytest.raises(DesignError, match=r"cannot parse value '\[1,,2\]'; .* a word \(alone "
                                          r"or in a list\)"):
        parse_value("[1,,2]")


def test_text_table_aligns_without_pandas():
    """The one table writer (summary.txt, the Monte Carlo and sweep tables): text columns
    left-aligned, the others right-aligned, each as wide as its longest cell or name, None and
    missing keys as '-', no trailing blanks; no rows gives the header alone."""
    from hgo_mj.metrics import text_table

    rows = [{"observer": "hgo", "rmse": 0.0123456, "cell": "k = 20"},
            {"observer": "high_gain_long", "rmse": None}]
    assert text_table(rows, ["observer", "rmse", "cell"], ["observer", "cell"]).splitlines() == [
        "observer           rmse  cell",
        "hgo             0.01235  k = 20",
        "high_gain_long        -  -"]
    assert text_table([], ["a", "bb"], ["a"]) == "a  bb"


def test_printed_tables_have_units_and_columns_sized_to_their_longest_cell():
    """format_table and the Monte Carlo table: a unit column and the settling time's unit;
    a name longer than 16 characters keeps every column aligned."""
    from hgo_mj.metrics import format_table
    from hgo_mj.study.montecarlo import aggregate, format_mc_table

    m = {name: {"states": ["angle", "angular_velocity"], "estimated": [True, False],
                "rmse": [0.125, None], "peak": [1.5, None], "settling_time": [0.25, None],
                "final": [1e-3, None], "undefined_samples": [0, None], "update_time": 3e-6}
         for name in ("high_gain_multi_1", "a")}
    units = {"angle": "rad", "angular_velocity": "rad/s"}
    for text, unit_col in ((format_table(m, units, "h"), "settle [h]"),
                           (format_mc_table(aggregate([m, m]), units), "settle med [s]")):
        lines = [r for r in text.splitlines() if r.startswith(("observer", "high_gain", "a "))]
        head, rows = lines[0], lines[1:]
        assert unit_col in head and len(rows) == 4
        for col in ("state", "unit"):
            assert {r[head.index(col) - 1] for r in rows} == {" "}  # the column starts there
        assert {r.split()[2] for r in rows} == {"rad", "rad/s"}
        ends = {len(r) for r in lines}
        assert len(ends) == 1, text  # every row as wide as the header
