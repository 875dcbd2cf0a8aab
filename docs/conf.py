"""Sphinx configuration of the hgo_mj documentation (``make docs``: warnings are errors)."""

from __future__ import annotations

import os
import sys
from importlib.metadata import version as _version

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # tiny matrices: threads only add contention
os.environ.setdefault("MPLBACKEND", "Agg")  # the gallery saves figures; no display
sys.path.insert(0, os.path.dirname(__file__))  # this file's scraper, named "conf.figure_scraper"

project = "hgo_mj"
author = "hgo_mj authors"
copyright = "hgo_mj authors, MIT license"  # noqa: A001 (Sphinx's name)
release = _version("hgo_mj")
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
    "sphinx.ext.intersphinx",
]

#: the projects whose API hgo_mj's pages link to (``:class:`numpy.ndarray```, Gymnasium's
#: ``Env``, MuJoCo's ``MjModel``): each one only when its inventory can be fetched now, so that
#: a build without the network (``-W``) has no inventory warning, only plain names
INTERSPHINX = {"numpy": "https://numpy.org/doc/stable/",
               "gymnasium": "https://gymnasium.farama.org/",
               "mujoco": "https://mujoco.readthedocs.io/en/stable/"}


def reachable(url: str, timeout: float = 3.0) -> bool:
    """Whether ``url`` + ``objects.inv`` (a Sphinx inventory) answers now."""
    import urllib.request

    if os.environ.get("HGO_MJ_DOCS_OFFLINE"):  # said so: no attempt
        return False
    try:
        with urllib.request.urlopen(url + "objects.inv", timeout=timeout) as resp:
            return resp.status == 200
    except (OSError, ValueError):  # no network, no DNS, a timeout, a refusal
        return False


intersphinx_mapping = {name: (url, None) for name, url in INTERSPHINX.items() if reachable(url)}
intersphinx_timeout = 5

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "benchmark/results/*", "gallery/*.py", "gallery/GALLERY_HEADER.rst",
                    "auto_examples/*.ipynb",
                    "auto_examples/*.py", "auto_examples/*.zip", "auto_examples/*.json"]
root_doc = "index"

html_theme = "furo"
html_title = f"hgo_mj {release}"

autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "none"  # numpydoc's Parameters sections carry the types
autosummary_generate = False
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]
suppress_warnings = ["myst.header"]

# hgo_mj.plotting builds its figures without pyplot (it never touches the user's backend), so
# sphinx-gallery's pyplot scraper does not see them: this scraper saves every matplotlib Figure
# an example holds in its globals, once, in the order they were made.
_SHOWN: set[int] = set()


def figure_scraper(block, block_vars, gallery_conf):  # noqa: ARG001 (sphinx-gallery's hook)
    from matplotlib.figure import Figure
    from sphinx_gallery.scrapers import figure_rst

    figures = [v for v in block_vars["example_globals"].values()
               if isinstance(v, Figure) and id(v) not in _SHOWN]
    paths = []
    for fig, path in zip(figures, block_vars["image_path_iterator"]):
        fig.savefig(path, dpi=90)
        _SHOWN.add(id(fig))
        paths.append(path)
    return figure_rst(paths, gallery_conf["src_dir"])


def reset_figures(gallery_conf, fname):  # noqa: ARG001 (sphinx-gallery's hook)
    _SHOWN.clear()


sphinx_gallery_conf = {
    "examples_dirs": "gallery",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "matplotlib_animations": False,
    "image_scrapers": ("matplotlib", "conf.figure_scraper"),
    "reset_modules": ("matplotlib", "conf.reset_figures"),
    "show_memory": False,
    # "examples using this": the examples that call each hgo_mj function or class, listed
    # under it in the API pages (example_backlinks below)
    "backreferences_dir": "gen_modules/backreferences",
    "doc_module": ("hgo_mj",),
    "inspect_global_variables": True,
}

BACKREFERENCES = os.path.join(os.path.dirname(__file__), "gen_modules", "backreferences")


def example_backlinks(app, what, name, obj, options, lines):  # noqa: ARG001 (Sphinx's hook)
    """Append "Examples using this" (sphinx-gallery's minigallery) to the docstring of a
    function or class that some gallery example uses: sphinx-gallery writes
    ``gen_modules/backreferences/NAME.examples`` before autodoc runs, empty where none does,
    under the shortest name it is importable by (``hgo_mj.NAME`` for a re-export)."""
    if what not in ("function", "class"):
        return
    import hgo_mj

    short = f"hgo_mj.{name.rsplit('.', 1)[-1]}"  # sphinx-gallery names a re-export so
    for candidate in (name, short):
        if candidate == short and getattr(hgo_mj, short[7:], None) is not obj:
            continue
        path = os.path.join(BACKREFERENCES, f"{candidate}.examples")
        if os.path.isfile(path) and os.path.getsize(path) > 0:
            lines += ["", ".. rubric:: Examples using this", "", f".. minigallery:: {candidate}",
                      ""]
            return


# The environment classes keep Gymnasium's docstring sections, written in Markdown as
# Gymnasium's own are ("## Description", pipe tables); they become reST here, before numpydoc
# reads the docstring: a heading becomes a rubric, a pipe table a list-table (a row whose first
# cell is empty continues the row above).
def _row(line: str) -> list[str]:
    return [cell.strip() for cell in line.strip().strip("|").split("|")]


def _table(rows: list[list[str]], indent: str) -> list[str]:
    merged: list[list[str]] = []
    for row in rows:
        if merged and not row[0]:
            merged[-1] = [f"{a} {b}".strip() for a, b in zip(merged[-1], row)]
        else:
            merged.append(row)
    out = [f"{indent}.. list-table::", f"{indent}   :header-rows: 1", ""]
    for row in merged:
        out += [f"{indent}   * - {row[0]}"] + [f"{indent}     - {cell}" for cell in row[1:]]
    return out + [""]


def markdown_sections(app, what, name, obj, options, lines):  # noqa: ARG001 (Sphinx's hook)
    if not any(line.startswith("## ") for line in lines):
        return
    out: list[str] = []
    table: list[list[str]] = []
    for line in lines + [""]:
        text = line.strip()
        if text.startswith("|"):
            if not set(text) <= set("|- "):  # skip the |---|---| rule
                table.append(_row(text))
            continue
        if table:
            out += _table(table, "")
            table = []
        if text.startswith("## "):
            out += [f".. rubric:: {text[3:]}", ""]
        else:
            out.append(line)
    lines[:] = out


def setup(app):
    app.connect("autodoc-process-docstring", markdown_sections, priority=100)
    app.connect("autodoc-process-docstring", example_backlinks, priority=900)
