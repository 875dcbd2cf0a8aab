"""The documentation (docs/, built by ``make docs``): the API reference lists every public name,
every module's public names (its ``__all__``) carry numpydoc Parameters/Returns/Raises/Examples
sections whose doctests pass (scripts/check_docstrings.py is the rule), the user guide's
examples run, and the gallery has its eight executed examples.

The Sphinx build itself (warnings as errors, the gallery executed) is ``make docs`` in CI.
"""

from __future__ import annotations

import doctest
import importlib
import importlib.util
import inspect
import re
import runpy
from pathlib import Path

import pytest
from numpydoc.docscrape import ClassDoc, FunctionDoc

import hgo_mj

DOCS = Path(__file__).resolve().parents[1] / "docs"
API = (DOCS / "api.rst").read_text()


def start_here() -> list[str]:
    """The dotted names of the API reference's "Start here" autosummary."""
    block = API.split(".. autosummary::", 1)[1].split("\n\n", 2)[1]
    return [line.strip() for line in block.splitlines() if line.strip()]


def resolve(dotted: str) -> object:
    module, name = dotted.rsplit(".", 1)
    return getattr(importlib.import_module(module), name)


def test_api_reference_lists_every_name_of_all():
    listed = start_here()
    missing = [n for n in hgo_mj.__all__ if f"{hgo_mj._HOME[n]}.{n}" not in listed]
    assert not missing, f"hgo_mj.__all__ names missing from docs/api.rst: {missing}"
    # and each listed name is the object hgo_mj exports under that name
    for name in hgo_mj.__all__:
        assert getattr(hgo_mj, name) is resolve(f"{hgo_mj._HOME[name]}.{name}")


def test_api_reference_documents_each_package_module():
    documented = set(re.findall(r"^\.\. automodule:: (\S+)$", API, re.M))
    for home in set(hgo_mj._HOME.values()):
        assert home in documented, f"{home} has public names but no automodule in docs/api.rst"
    for module in documented:  # and every documented module imports
        importlib.import_module(module)


def test_import_hgo_mj_lists_names_and_rejects_others():
    assert sorted(dir(hgo_mj)) == sorted(set(dir(hgo_mj)))
    assert set(hgo_mj.__all__) <= set(dir(hgo_mj))
    with pytest.raises(AttributeError, match="no attribute 'simulatee'; public: "):
        hgo_mj.simulatee  # noqa: B018


def sections(obj: object) -> dict:
    doc = ClassDoc(obj) if inspect.isclass(obj) else FunctionDoc(obj)
    return {k: doc[k] for k in ("Parameters", "Returns", "Raises", "Examples")}


def takes_parameters(obj: object) -> bool:
    target = obj.__init__ if inspect.isclass(obj) else obj
    params = [p for p in inspect.signature(target).parameters if p not in ("self", "cls")]
    return bool(params)


@pytest.mark.parametrize("dotted", start_here())
def test_entry_point_has_numpydoc_sections(dotted):
    obj = resolve(dotted)
    found = sections(obj)
    assert found["Examples"], f"{dotted}: no Examples section"
    assert ">>>" in "\n".join(found["Examples"]), f"{dotted}: Examples without a doctest"
    if takes_parameters(obj):
        assert found["Parameters"], f"{dotted}: no Parameters section"
        target = obj.__init__ if inspect.isclass(obj) else obj
        named = {n.strip() for p in found["Parameters"] for n in p.name.split(",")}
        named = {n.lstrip("*") for n in named}
        sig = [p for p in inspect.signature(target).parameters if p not in ("self", "cls")]
        undocumented = [p for p in sig if p not in named]
        assert not undocumented, f"{dotted}: parameters without an entry: {undocumented}"
    if not inspect.isclass(obj):
        assert found["Returns"], f"{dotted}: no Returns section"


@pytest.mark.parametrize("dotted", start_here())
def test_entry_point_examples_run(dotted, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # examples that write files write them here
    obj = resolve(dotted)
    module = importlib.import_module(dotted.rsplit(".", 1)[0])
    tests = doctest.DocTestFinder(recurse=False).find(obj, dotted, module=module,
                                                      globs=dict(vars(module)))
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    ran = 0
    for test in tests:
        result = runner.run(test)
        assert result.failed == 0, f"{dotted}: {result.failed} doctest example(s) failed"
        ran += result.attempted
    assert ran > 0, f"{dotted}: no doctest example ran"


GUIDE = sorted((DOCS / "guide").glob("*.rst"))


def test_guide_has_every_page():
    names = {p.stem for p in GUIDE}
    assert {"loop", "plants", "sensors", "observers", "studies", "environments", "recordings",
            "own_plant_observer"} <= names


@pytest.mark.parametrize("page", [p for p in GUIDE if re.search(r"^>>> ", p.read_text(), re.M)],
                         ids=lambda p: p.stem)
def test_guide_examples_run(page, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = doctest.testfile(str(page), module_relative=False,
                              optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0, f"{page.name}: {result}"


def test_own_plant_observer_example_runs(capsys):
    from hgo_mj.observers import OBSERVERS

    try:
        runpy.run_path(str(DOCS / "guide" / "examples" / "own_plant_observer.py"),
                       run_name="__main__")
    finally:  # the example registers its observer: leave the registry as it was
        OBSERVERS.pop("euler_luenberger", None)
    out = capsys.readouterr().out
    assert "luenberger" in out and "hgo" in out


def test_gallery_has_eight_examples_each_ending_in_a_figure():
    examples = sorted((DOCS / "gallery").glob("plot_*.py"))
    assert len(examples) >= 8
    for path in examples:
        text = path.read_text()
        assert text.startswith('"""\n') and "\n====" in text.split('"""')[1], path.name
        # the example makes a Figure (hgo_mj.plotting's, or subplots'), which the build shows
        assert re.search(r"^fig\b[^=\n]* = ", text, re.M), f"{path.name} makes no figure"


@pytest.mark.slow
@pytest.mark.parametrize("example", sorted(p.name for p in (DOCS / "gallery").glob("plot_*.py")))
def test_gallery_figure_texts_stay_inside_the_figure_and_apart(example, tmp_path, monkeypatch):
    """Every figure a gallery example makes, drawn: no title, label, tick label or legend
    text reaches outside the figure (issue 28: an x-axis label was cut off) or overlaps
    another (tests/figure_texts.py)."""
    from figure_texts import text_faults
    from matplotlib.figure import Figure

    made = []
    original = Figure.__init__

    def init(self, *args, **kwargs):
        original(self, *args, **kwargs)
        made.append(self)

    monkeypatch.setattr(Figure, "__init__", init)
    monkeypatch.chdir(tmp_path)
    runpy.run_path(str(DOCS / "gallery" / example), run_name="__main__")
    monkeypatch.undo()
    assert made
    for i, fig in enumerate(made):
        assert text_faults(fig) == [], (example, i)

def test_every_reproduction_has_a_page():
    from hgo_mj.reproduce import REPRODUCTIONS

    for name in REPRODUCTIONS:
        page = DOCS / "reproductions" / f"{name}.rst"
        assert page.exists(), f"no page for {name}: run scripts/docs_reproductions.py {name}"
        text = page.read_text()
        assert f".. automodule:: {REPRODUCTIONS[name][0]}" in text
        assert (DOCS / "reproductions" / name / "report.txt").read_text().strip()
        for fig in re.findall(r"\.\. figure:: (\S+)", text):
            assert (DOCS / "reproductions" / fig).exists(), fig
        assert re.findall(r"\.\. figure:: ", text), f"{name}: no figure"


def _checker():
    path = Path(__file__).resolve().parents[1] / "scripts" / "check_docstrings.py"
    spec = importlib.util.spec_from_file_location("check_docstrings", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


#: every module of the package (scripts/check_docstrings.py): each public name (``__all__``)
#: has its numpydoc sections and its doctests pass
MODULES = [m.__name__ for m in _checker().modules()]


@pytest.mark.parametrize("module", MODULES)
def test_every_module_has_every_section_and_its_doctests_pass(module, tmp_path,
                                                                    monkeypatch):
    checker = _checker()
    assert checker.problems([module]) == []
    monkeypatch.chdir(tmp_path)
    mod = importlib.import_module(module)
    tests = doctest.DocTestFinder().find(mod, module, globs=dict(vars(mod)))
    # pytest's checker, so that NUMBER (pyproject's doctest_optionflags) means what it does
    # under ``pytest --doctest-modules``
    from _pytest.doctest import _get_checker, _get_number_flag

    runner = doctest.DocTestRunner(checker=_get_checker(), optionflags=(
        doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE | _get_number_flag()))
    ran = 0
    for test in tests:
        result = runner.run(test)
        assert result.failed == 0, f"{test.name}: {result.failed} doctest example(s) failed"
        ran += result.attempted
    # constants or re-exports only; a reproduction's run (a minute) is shown, not run
    assert ran > 0 or not list(checker.public_objects(mod)) or module.startswith(
        "hgo_mj.reproduce.")


def test_gallery_examples_are_text_and_code_cells():
    """scikit-learn's layout: every example alternates titled text cells (``# %%``) and code,
    so its figure sits under the text and code that make it, not above all of it."""
    for path in sorted((DOCS / "gallery").glob("plot_*.py")):
        text = path.read_text()
        cells = re.findall(r"^# %%\n# (.+)\n# (-+)\n", text, re.M)
        assert len(cells) >= 1 and text.count("\n# %%\n") >= 1, path.name
        for title, rule in cells:
            assert len(rule) >= len(title), (path.name, title)
        first_cell = text.index("\n# %%\n")
        fig = re.search(r"^fig\b[^=\n]* = ", text, re.M)
        assert fig and fig.start() > first_cell, path.name
        assert "subplots(" not in text or "layout=\"constrained\"" in text, path.name


def _conf(monkeypatch):
    monkeypatch.setenv("HGO_MJ_DOCS_OFFLINE", "1")
    spec = importlib.util.spec_from_file_location("docs_conf", DOCS / "conf.py")
    conf = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(conf)
    return conf


def test_intersphinx_only_to_reachable_inventories(monkeypatch):
    """Offline (no network, or HGO_MJ_DOCS_OFFLINE) no inventory is configured, so a -W build
    has no fetch warning; online numpy, Gymnasium and MuJoCo are linked."""
    import urllib.request

    conf = _conf(monkeypatch)
    assert "sphinx.ext.intersphinx" in conf.extensions and conf.intersphinx_mapping == {}
    assert set(conf.INTERSPHINX) == {"numpy", "gymnasium", "mujoco"}
    monkeypatch.delenv("HGO_MJ_DOCS_OFFLINE")

    def unreachable(url, timeout):
        raise OSError("Temporary failure in name resolution")

    class Answer:
        status = 200

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

    monkeypatch.setattr(urllib.request, "urlopen", unreachable)
    assert not conf.reachable("https://numpy.org/doc/stable/")
    asked = []
    monkeypatch.setattr(urllib.request, "urlopen",
                        lambda url, timeout: asked.append(url) or Answer())
    assert conf.reachable("https://numpy.org/doc/stable/")
    assert asked == ["https://numpy.org/doc/stable/objects.inv"]


def test_api_pages_link_the_examples_that_use_each_name(monkeypatch, tmp_path):
    """sphinx-gallery's back-references (``backreferences_dir``, ``doc_module``): a function
    some example uses gets "Examples using this" (a minigallery) under its docstring."""
    conf = _conf(monkeypatch)
    assert conf.sphinx_gallery_conf["doc_module"] == ("hgo_mj",)
    assert conf.sphinx_gallery_conf["backreferences_dir"] == "gen_modules/backreferences"
    monkeypatch.setattr(conf, "BACKREFERENCES", str(tmp_path))
    (tmp_path / "hgo_mj.plotting.plot_trajectory.examples").write_text(".. thumbnail\n")
    (tmp_path / "hgo_mj.plotting.subplots.examples").write_text("")
    lines = ["Doc."]
    conf.example_backlinks(None, "function", "hgo_mj.plotting.plot_trajectory", None, {}, lines)
    assert ".. minigallery:: hgo_mj.plotting.plot_trajectory" in lines
    for name in ("hgo_mj.plotting.subplots", "hgo_mj.plotting.new_figure"):
        lines = ["Doc."]
        conf.example_backlinks(None, "function", name, None, {}, lines)
        assert lines == ["Doc."]
    import hgo_mj
    from hgo_mj.metrics import format_table

    (tmp_path / "hgo_mj.format_table.examples").write_text(".. thumbnail\n")
    lines = ["Doc."]  # documented under its module, found under its re-export
    conf.example_backlinks(None, "function", "hgo_mj.metrics.format_table", format_table, {},
                           lines)
    assert ".. minigallery:: hgo_mj.format_table" in lines and hgo_mj.format_table is format_table
