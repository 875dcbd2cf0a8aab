"""`hgo_mj.check` / `hgo-mj check`: which observer applies to a system and why, and `hgo-mj run`
refusing one that does not."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from hgo_mj import check
from hgo_mj.cli import main
from hgo_mj.exceptions import DesignError
from hgo_mj.observers import registered
from hgo_mj.plants import make_plant
from hgo_mj.systems.symbolic import ode_system

ROOT = Path(__file__).resolve().parents[1]


def _rows(system):
    return {r.observer: r for r in check.check(system)}


def test_one_row_per_registered_observer_with_the_papers_reasons():
    rows = _rows(make_plant("elastic_joint_2link").system)
    assert list(rows) == list(registered())
    assert rows["high_gain_multi"].applies and rows["besancon"].applies and rows["ekf"].applies
    assert not rows["high_gain"].applies
    assert rows["high_gain"].reason.startswith("needs a single-output observability normal "
                                               "form (paper 000, eq. 1)")
    assert "paper 002, eq. 2.2" in rows["bastin_gevers"].reason
    assert "paper 003" in rows["jo_son"].reason
    bio = _rows(make_plant("bioreactor_bastin_gevers").system)
    assert bio["bastin_gevers"].applies and not bio["besancon"].applies
    assert "paper 001, eq. 9 / 21" in bio["besancon"].reason
    assert bio["ekf_mujoco"].reason.startswith("needs an MJCF model")


def test_every_row_agrees_with_construction():
    """Where check says an observer does not apply, building it fails; a derived system's
    relative-degree problem is the reason given."""
    rd = ode_system(["x1", "x2"], ["x2 + u", "-x1"], "x1", inputs=["u"])()
    rows = _rows(rd)
    assert not rows["high_gain"].applies and "relative degree 1" in rows["high_gain"].reason
    assert rows["ekf"].applies
    from hgo_mj.observers import make_observer

    with pytest.raises(DesignError):
        make_observer("high_gain", rd, k=10.0)


def test_the_command_prints_the_table_and_run_refuses(tmp_path, capsys):
    assert main(["check", str(ROOT / "scenarios" / "ode_pendulum.toml")]) == 0
    out = capsys.readouterr().out
    assert "lipschitz: 9.81" in out and re.search(r"\nhigh_gain +applies", out)
    assert main(["check", "pendulum"]) == 0
    assert re.search(r"jo_son +no +needs the generalized observer canonical form",
                     capsys.readouterr().out)
    assert main(["check", "nope"]) == 2
    assert "unknown plant 'nope'" in capsys.readouterr().err
    assert main(["run", "--plant", "elastic_joint_2link", "--observer", "high_gain:k=5",
                 "--duration", "1", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["hgo-mj: error: observer 'high_gain_0' (high_gain) does not apply to "
                   "ElasticJoint2Link: needs a single-output observability normal form (paper "
                   "000, eq. 1); ElasticJoint2Link declares none (outputs: ['link1_angle', "
                   "'link2_angle'])"]
    assert not (tmp_path / "o").exists()


def test_sample_period_against_the_lmi_bound_of_paper_004(capsys):
    """The Riccati row notes the sample period against LMI (63)/(65) (Theorem 2) for the
    derived system's Lipschitz bound: within at 1 ms, beyond at 50 ms (a note, not a refusal:
    the bound is sufficient); the command takes the period from the flag or the scenario."""
    system = ode_system(["x1", "x2"], ["x2", "-9.81*sin(x1)"], "x1")()
    fine = {r.observer: r for r in check.check(system, 0.001)}
    assert fine["riccati"].applies and fine["riccati"].note.startswith(
        "sample period 0.001 s is within the bound delta_max = ")
    coarse = {r.observer: r for r in check.check(system, 0.05)}
    assert coarse["riccati"].applies and "exceeds the bound" in coarse["riccati"].note
    assert "not certified" in coarse["riccati"].note
    assert all(not r.note for name, r in coarse.items() if name != "riccati")
    assert check.sampling_note(make_plant("pendulum").system, 0.01) == ""  # no rho stated
    with pytest.raises(DesignError, match="sample_period must be"):
        check.check(system, -1.0)
    assert main(["check", str(ROOT / "scenarios" / "ode_pendulum.toml"), "--sample-period",
                 "0.05"]) == 0
    assert re.search(r"riccati +applies  sample period 0.05 s exceeds", capsys.readouterr().out)


def test_reachability_and_spr_are_checked_on_the_forms():
    """Bastin-Gevers needs the AOCF output reachable (paper 002, Theorem 4.2): two parameters
    entering as a sum cannot be told apart. Jo-Son needs Corollary 3.3's conditions on b
    (paper 003): b = (-3, 1) gives s - 3, not Hurwitz. Both are refused by hgo-mj run too."""
    twins = ode_system(["x1", "x2"], ["x2", "-(a + b)*sin(x1) - 0.1*x2 + u"], "x1",
                       inputs=["u"], params={"a": 4.0, "b": 5.81})()
    rows = _rows(twins)
    assert not rows["bastin_gevers"].applies
    assert rows["bastin_gevers"].reason.startswith(
        "its AOCF is not output reachable (paper 002, Theorem 4.2): rank S = 1 < m = 2")
    unstable = ode_system(["y", "w"], ["w + th*y*u", "-y - 3*th*y*u"], "y", inputs=["u"],
                          params={"th": 1.0})()
    rows = _rows(unstable)
    assert not rows["jo_son"].applies
    assert rows["jo_son"].reason.startswith("the SPR condition of paper 003 fails for its form: "
                                            "Corollary 3.3 needs b_r s^(r-1) + ... + b_1 Hurwitz")
    with pytest.raises(DesignError, match="does not apply to Ode_ode: the SPR condition"):
        check.refuse_inapplicable("jo_son", unstable, "js")


VDP = """
name = "vdp"
[plant]
states = ["x1", "x2"]
f = ["x2", "(1 - x1**2)*x2 - x1"]
h = "x1"
x0 = [2.0, 0.0]
dt = 0.01
{region}
[run]
duration = 10.0
"""


def test_check_over_the_region_the_scenario_visits(tmp_path, capsys):
    """Van der Pol from x0 = (2, 0): over the default box [-1, 1]^2 the Lipschitz bound is
    small and the Riccati observer looks certified; ``hgo-mj check`` takes the box a short
    simulation visits instead (or ``[plant] region``), and warns where x0 or the run leaves a
    given region."""
    from hgo_mj.scenario import build_plant, scenario_plant
    from hgo_mj.schema import check_scenario

    default = build_plant({k: v for k, v in {"states": ["x1", "x2"],
                                              "f": ["x2", "(1 - x1**2)*x2 - x1"],
                                              "h": "x1"}.items()}).system.lipschitz
    visited = tmp_path / "vdp.toml"
    visited.write_text(VDP.format(region=""))
    assert main(["check", str(visited)]) == 0
    out = capsys.readouterr().out
    rho = float(re.search(r"lipschitz: ([\d.]+)", out).group(1))
    assert out.startswith("region: the box visited by a 10 s simulation") and rho > 4 * default
    assert "warning" not in out
    assert re.search(r"riccati +applies +sample period 0.01 s exceeds", out)
    given = tmp_path / "given.toml"
    given.write_text(VDP.format(region="region = [[-1.0, 1.0], [-1.0, 1.0]]"))
    assert main(["check", str(given)]) == 0
    out = capsys.readouterr().out
    assert "warning: x0 = [2.0, 0.0] lies outside the region [[-1.0, 1.0], [-1.0, 1.0]]" in out
    assert "warning: a 10 s simulation of the scenario leaves the region" in out
    assert float(re.search(r"lipschitz: ([\d.]+)", out).group(1)) == pytest.approx(default)
    wide = {"states": ["x1", "x2"], "f": ["x2", "(1 - x1**2)*x2 - x1"], "h": "x1",
            "x0": [2.0, 0.0], "region": [[-3.0, 3.0], [-4.0, 4.0]]}
    plant, notes = scenario_plant({"plant": wide, "run": {"duration": 5.0}})
    assert notes == ["region: [plant] region [[-3.0, 3.0], [-4.0, 4.0]]"]
    with pytest.raises(DesignError, match=r"plant.region must be a list of \[lo, hi\] pairs"):
        check_scenario({"plant": {**wide, "region": [[1.0, -1.0], [0.0, 1.0]]}}, required=False)
    with pytest.raises(DesignError, match="a registered or MJCF plant has none"):
        build_plant({"name": "pendulum", "region": [[-1.0, 1.0], [-1.0, 1.0]]})
