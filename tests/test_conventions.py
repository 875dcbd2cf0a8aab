"""What users expect of a Python research package (issue 28, item 4): ``__version__`` from the
one version in pyproject.toml, ``python -m hgo_mj``, ``py.typed`` in the wheel, a
``CITATION.cff`` and a CHANGELOG that agree with that version."""

from __future__ import annotations

import re
import subprocess
import sys
import unicodedata
from importlib.metadata import version
from pathlib import Path

import hgo_mj

ROOT = Path(__file__).resolve().parents[1]
VERSION = re.search(r'^version = "(.+)"$', (ROOT / "pyproject.toml").read_text(), re.M).group(1)


def test_version_is_the_installed_pyproject_version():
    assert hgo_mj.__version__ == version("hgo_mj") == VERSION


def test_python_m_hgo_mj_is_the_command_line(tmp_path):
    res = subprocess.run([sys.executable, "-m", "hgo_mj", "list"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith("PLANTS (hgo-mj run --plant NAME)")
    bad = subprocess.run([sys.executable, "-m", "hgo_mj", "run", "--plant", "pendulum"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2 and bad.stderr.startswith("hgo-mj: error:")


def test_py_typed_is_package_data():
    assert (ROOT / "hgo_mj" / "py.typed").is_file()
    text = (ROOT / "pyproject.toml").read_text()
    assert '"hgo_mj" = ["py.typed"]' in text  # the wheel test (test_install) checks the wheel


def test_citation_cff_names_this_version_and_every_reproduced_paper():
    from hgo_mj.reproduce import REPRODUCTIONS

    cff = (ROOT / "CITATION.cff").read_text()
    assert cff.startswith("# ") and "\ncff-version: 1.2.0\n" in cff
    assert f'\nversion: "{VERSION}"\n' in cff
    plain = unicodedata.normalize("NFKD", cff).encode("ascii", "ignore").decode()
    papers = plain.split("\n  - type: ")[1:]
    for name in REPRODUCTIONS:  # bastin_gevers1986: a reference by Bastin of 1986
        first, year = re.match(r"([a-z]+)\D*?(\d{4})$", name).groups()
        assert any(re.search(rf"family-names: \"?{first}\"?\n", p, re.I)
                   and f"\n    year: {year}\n" in p + "\n" for p in papers), name


def test_the_changelog_starts_at_this_version():
    text = (ROOT / "CHANGELOG.md").read_text()
    first = re.search(r"^## \[(.+?)\]", text, re.M).group(1)
    assert first == VERSION
