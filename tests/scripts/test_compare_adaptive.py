"""Smoke test of ``scripts/compare_adaptive.py`` (docs/results/adaptive.md): its whole machinery
(every plant, both noise levels and the mismatch, both halves of each run, the report and the
figures, the cache and ``--render-only``) on a tiny configuration: one seed, 1-s runs."""

from __future__ import annotations

import importlib.util
import math
import re
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "compare_adaptive.py"


@pytest.fixture(scope="module")
def ca():
    spec = importlib.util.spec_from_file_location("compare_adaptive", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def report(ca, tmp_path_factory):
    out = tmp_path_factory.mktemp("compare_adaptive")
    assert ca.main(["--quick", "--duration", "1", "--jobs", "1", "--out", str(out),
                    "--cache", str(out / "runs.pkl")]) == 0
    return out, (out / "adaptive.md").read_text()


def _sections(text: str) -> dict[str, str]:
    parts = re.split(r"^## ", text, flags=re.M)
    return {p.split("\n", 1)[0]: p.split("\n", 1)[1] for p in parts[1:]}


def _number(cell: str) -> float:
    v = float(cell)
    assert math.isfinite(v), cell
    return v


def test_every_method_row_and_column(ca, report):
    out, text = report
    sections = _sections(text)
    expected = {"pendulum": {"besancon", "bastin_gevers", "ekf", "ukf", "ekf_mujoco", "ukf_mujoco"},
                "elastic_joint": {"besancon", "ekf", "ukf", "ekf_mujoco", "ukf_mujoco"},
                "elastic_joint_2link": {"besancon", "ekf", "ekf_mujoco"}}
    from hgo_mj.systems import SYSTEMS

    seen = 0
    for plant, cfg in ca.PLANTS.items():
        for noise, mismatch in [(n, False) for n in ca.NOISES] + [(ca.NOISES[0], True)]:
            title = f"{plant}, noise std {noise:g} rad" + (
                f", observers' {cfg['mismatch']} +10 % (model mismatch)" if mismatch else "")
            body = sections[title]
            rows = [line.split("|")[1:-1] for line in body.splitlines()
                    if line.startswith("| ") and not line.startswith("| method")]
            names = {r[0].strip() for r in rows}
            assert names == expected[plant], (title, names)
            # the others are named, with the reason, under the table
            for m in set(ca.METHODS) - names:
                assert f"- `{m}` does not apply: " in body, (title, m)
            for r in rows:
                assert len(r) == 6, r
                name, run, t5, final, rmse, cost = (c.strip() for c in r)
                assert _number(run) == 1.0
                if t5 != "never":
                    assert 0.0 <= _number(t5) <= 1.0
                elif name in ca.KALMAN and not mismatch and noise == ca.NOISES[0]:
                    pytest.fail(f"{title}: {name} never within 5 %")  # they settle in 0.3 s
                assert len([_number(v) for v in final.split(",")]) == len(cfg["params"])
                assert len([_number(v) for v in rmse.split(",")]) == len(SYSTEMS[plant].state_names)
                assert _number(cost) > 0
            fig = f"adaptive_{plant}_{noise:g}{'_mismatch' if mismatch else ''}.png"
            assert f"]({fig})" in body and (out / fig).stat().st_size > 10_000
            seen += 1
    assert seen == 9


def test_what_it_shows_is_two_sentences_with_the_runs_numbers(ca, report):
    _, text = report
    shows = _sections(text)["What it shows"].strip().split("\n\n")[0]
    sentences = re.split(r"(?<=[.!?])\s+(?=[A-Z])", shows)
    assert len(sentences) == 2, sentences
    # the Kalman filters' time to 5 % (model right, low noise) is the range of the tables'
    t5 = []
    for title, body in _sections(text).items():
        if title.endswith(f"noise std {ca.NOISES[0]:g} rad"):
            t5 += [float(line.split("|")[3]) for line in body.splitlines()
                   if line.split("|")[1:2] and line.split("|")[1].strip() in ca.KALMAN]
    assert ca._range(t5, ca._sec) in sentences[0]
    assert "### Details" in text


def test_render_only_rewrites_the_same_report(ca, report, tmp_path):
    out, text = report
    assert ca.main(["--quick", "--duration", "1", "--render-only", "--cache", str(out / "runs.pkl"),
                    "--out", str(tmp_path)]) == 0
    assert (tmp_path / "adaptive.md").read_text() == text
