"""MJCF models of the hgo_mj plants (installed as ``hgo_mj.models``), and where to find them.

:func:`model_path` is the one place that knows where the shipped files lie: the systems
(:meth:`hgo_mj.systems.base.System.load_model`), the plants and the recorder ask it, so none of
them imports another only to find a file.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from hgo_mj.exceptions import DesignError

__all__ = ["model_path"]


def model_path(name: str) -> Path:
    """Absolute path of an MJCF file shipped under ``models/`` (works from a wheel install).

    Parameters
    ----------
    name : str
        File name of a shipped model, e.g. ``"pendulum.xml"``.

    Returns
    -------
    Path
        The absolute path of the file.

    Raises
    ------
    DesignError
        No shipped model of that name (the shipped ones are listed).

    Examples
    --------
    >>> path = model_path("pendulum.xml")
    >>> path.name, path.is_absolute()
    ('pendulum.xml', True)
    >>> model_path("nope.xml")
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: no MJCF model named 'nope.xml'; shipped models: [...]
    """
    path = Path(str(resources.files(__name__).joinpath(name)))
    if not path.is_file():
        shipped = sorted(p.name for p in Path(str(resources.files(__name__))).glob("*.xml"))
        raise DesignError(f"no MJCF model named {name!r}; shipped models: {shipped}")
    return path
