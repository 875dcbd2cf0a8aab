"""hgo_mj: nonlinear (high-gain) observers on MuJoCo and ODE plants behind a sensor chain.

The names of :data:`__all__` are the entry points a user starts from; each lives in its
module (``hgo_mj.make_plant`` is ``hgo_mj.plants.make_plant``) and is imported from there on
first use, so ``import hgo_mj`` stays cheap. ``simulate`` is not among them: ``hgo_mj.simulate``
is its module, so it is ``from hgo_mj.simulate import simulate``. The documentation's API
reference lists these names and the rest of each module. ``hgo_mj.__version__`` is read from
the installed package's metadata on first use.
"""

from __future__ import annotations

import importlib
import importlib.abc
import sys
from typing import Any


class _MujocoWithoutGL(importlib.abc.MetaPathFinder):
    """``import mujoco`` without its OpenGL renderer: while mujoco's ``__init__`` runs (its
    first import, after ``import hgo_mj``), ``mujoco.rendering`` is refused, which mujoco
    itself tolerates (it then lacks ``Renderer`` and ``GLContext``), so no simulation loads
    GLFW. ``mujoco.Renderer`` and ``mujoco.GLContext`` are imported on first use (a module
    ``__getattr__``), and ``mujoco.rendering`` imports as usual after that ``__init__``."""

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> None:
        if fullname != "mujoco.rendering":
            return None
        mj = sys.modules.get("mujoco")
        if mj is None or not getattr(mj.__spec__, "_initializing", False):
            return None
        if "__getattr__" not in vars(mj):
            setattr(mj, "__getattr__", _mujoco_gl_attr)  # noqa: B010 - PEP 562 on mujoco
        raise ModuleNotFoundError("mujoco.rendering is loaded on first use (hgo_mj)",
                                  name=fullname)


def _mujoco_gl_attr(name: str) -> Any:
    """``mujoco.Renderer`` / ``mujoco.GLContext``, imported on first use."""
    mj = sys.modules["mujoco"]
    if name == "Renderer":
        from mujoco.rendering.classic.renderer import Renderer

        setattr(mj, "Renderer", Renderer)  # noqa: B010
        return Renderer
    if name == "GLContext":
        from mujoco.rendering.classic.gl_context import GLContext

        setattr(mj, "GLContext", GLContext)  # noqa: B010
        return GLContext
    raise AttributeError(f"module 'mujoco' has no attribute {name!r}")


if "mujoco" not in sys.modules and not any(isinstance(f, _MujocoWithoutGL)
                                           for f in sys.meta_path):
    sys.meta_path.insert(0, _MujocoWithoutGL())


#: public name -> the module that defines it
_HOME = {
    "simulate_batch": "hgo_mj.simulate", "Trajectory": "hgo_mj.simulate",
    "make_plant": "hgo_mj.plants", "MujocoPlant": "hgo_mj.plants", "OdePlant": "hgo_mj.plants",
    "make_observer": "hgo_mj.observers", "HighGainObserver": "hgo_mj.observers",
    "SensorChain": "hgo_mj.sensors", "make_stage": "hgo_mj.sensors",
    "GaussianNoise": "hgo_mj.sensors", "Quantization": "hgo_mj.sensors",
    "make_signal": "hgo_mj.inputs", "Multisine": "hgo_mj.inputs",
    "all_metrics": "hgo_mj.metrics", "metrics_frame": "hgo_mj.metrics",
    "format_table": "hgo_mj.metrics",
    "Study": "hgo_mj.study", "monte_carlo": "hgo_mj.study",
    "read": "hgo_mj.record", "record_trajectory": "hgo_mj.record",
    "plot_trajectory": "hgo_mj.plotting", "plot_monte_carlo": "hgo_mj.plotting",
}

__all__ = sorted(_HOME)


def __getattr__(name: str) -> Any:
    """Import a public name from its module on first use (PEP 562); ``__version__`` is the
    installed distribution's version (its one source: ``version`` in pyproject.toml)."""
    if name == "__version__":
        from importlib.metadata import version

        globals()[name] = version("hgo_mj")
        return globals()[name]
    if name not in _HOME:
        raise AttributeError(f"module 'hgo_mj' has no attribute {name!r}; public: {__all__}")
    value = getattr(importlib.import_module(_HOME[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
