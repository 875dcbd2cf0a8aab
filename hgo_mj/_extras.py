"""Optional dependencies: the extras of ``pyproject.toml`` and the one-line error a feature
raises when its extra is not installed."""

from __future__ import annotations

import importlib
from types import ModuleType

from .exceptions import MissingExtraError

#: extra -> what it enables (README.md, "Install", has a row per extra)
EXTRAS = {
    "lmi": "the LMI designs (cvxpy, Clarabel): hgo_mj.design's LMI gain bounds, paper 004's reproduction",
    "symbolic": "ODE plants given as text (sympy): [plant] f = [...], hgo_mj.systems.symbolic",
    "render": "rendering (render_mode \"rgb_array\" / \"human\", GhostRenderer, RecordVideo): "
              "MuJoCo's Python OpenGL bindings (PyOpenGL, glfw)",
    "gym": "Gymnasium's own MuJoCo environments and RecordVideo (gymnasium[mujoco], imageio, moviepy)",
    "ray": "the Ray backend of studies and tuning (--backend ray)",
    "rl": "scripts/train_rl.py (stable-baselines3, sb3-contrib)",
    "docs": "make docs (Sphinx, numpydoc, sphinx-gallery, furo, myst-parser)",
    "dev": "make test: every extra above but rl and docs, plus the test and lint tools",
}


def require(module: str, extra: str, feature: str) -> ModuleType:
    """Import ``module``, an optional dependency of the extra ``extra``, for ``feature``.

    Parameters
    ----------
    module : str
        The module to import (``"cvxpy"``, ``"sympy.printing.pycode"``, ...).
    extra : str
        The extra of ``pyproject.toml`` that installs it (a key of :data:`EXTRAS`).
    feature : str
        What needs it, as the user named it (``"lmi_delta_max"``, ``"an ODE plant given as
        text"``): the error's first words.

    Returns
    -------
    module
        The imported module.

    Raises
    ------
    MissingExtraError
        ``module`` is not installed (an :class:`ImportError`; one line naming the package and
        the extra to install).

    Examples
    --------
    >>> require("numpy", "lmi", "lmi_delta_max").__name__
    'numpy'
    >>> require("nopkg", "lmi", "x")
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.MissingExtraError: x needs the optional dependency nopkg: pip install 'hgo_mj[lmi]'
    """
    if extra not in EXTRAS:
        raise ValueError(f"unknown extra {extra!r}; expected one of {sorted(EXTRAS)}")
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        if exc.name is not None and module.split(".")[0] != exc.name.split(".")[0]:
            raise  # the package is there but one of its own imports failed
        raise MissingExtraError(module.split(".")[0], extra, feature) from None
