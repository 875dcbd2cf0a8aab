"""hgo_mj: nonlinear (high-gain) observers on MuJoCo and ODE plants behind a sensor chain.

The names of :data:`__all__` are the entry points a user starts from; each lives in its
module (``hgo_mj.make_plant`` is ``hgo_mj.plants.make_plant``) and is imported from there on
first use, so ``import hgo_mj`` stays cheap. ``simulate`` is not among them: ``hgo_mj.simulate``
is its module, so it is ``from hgo_mj.simulate import simulate``. The documentation's API
reference lists these names and the rest of each module.
"""

from __future__ import annotations

import importlib
from typing import Any

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
    """Import a public name from its module on first use (PEP 562)."""
    if name not in _HOME:
        raise AttributeError(f"module 'hgo_mj' has no attribute {name!r}; public: {__all__}")
    value = getattr(importlib.import_module(_HOME[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
