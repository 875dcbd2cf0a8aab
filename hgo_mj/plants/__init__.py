"""Plants: MuJoCo models and ODE systems, built by name with :func:`make_plant`."""

from __future__ import annotations

import os
from typing import Any

from .._validate import check_call, import_class, reject_unknown
from ..exceptions import DesignError
from ..models import model_path
from .base import Plant
from .mujoco import MujocoPlant
from .ode import OdePlant

#: The lab plants shipped as MJCF files and run by the generic MJCF path
#: (:func:`hgo_mj.systems.mjcf.mjcf_system`): name -> (file under ``models/``, the encoder
#: sensors measured by default, summary, reference). :func:`make_plant` builds them by name.
LAB_PLANTS: dict[str, tuple[str, tuple[str, ...], str, str]] = {
    "furuta": ("furuta.xml", ("arm_angle", "pendulum_angle"),
               "rotary inverted (Furuta) pendulum driven by motor voltage",
               "Quanser, QUBE-Servo 2 User Manual and Rotary Pendulum Workbook"),
    "acrobot": ("acrobot.xml", ("shoulder_angle", "elbow_angle"),
                "two-link arm actuated at the elbow only",
                "Spong (1995), The swing up control problem for the acrobot, IEEE CSM 15(1)"),
    "cart_pole": ("cart_pole.xml", ("cart_position", "pole_angle"),
                  "pole hinged on a cart pushed by a horizontal force",
                  "Barto, Sutton, Anderson (1983), Neuronlike adaptive elements ..., "
                  "IEEE Trans. SMC 13(5)"),
}


def plant_names() -> list[str]:
    """Every registered plant name: :data:`hgo_mj.systems.SYSTEMS`' and :data:`LAB_PLANTS`'.

    Returns
    -------
    list of str
        Sorted.

    Examples
    --------
    >>> {"pendulum", "furuta", "cart_pole"} <= set(plant_names())
    True
    """
    from ..systems import SYSTEMS

    return sorted([*SYSTEMS, *LAB_PLANTS])


def unknown_plant(name: Any) -> DesignError:
    """The error for a plant name that is not registered (the valid ones listed).

    Parameters
    ----------
    name : object
        The name given.

    Returns
    -------
    DesignError
        To raise.

    Examples
    --------
    >>> str(unknown_plant("pendulm"))[:46]
    "unknown plant 'pendulm'; valid: ['acrobot', 'b"
    """
    return DesignError(f"unknown plant {name!r}; valid: {plant_names()}, an MJCF file, "
                       f"or 'module:Class' (a System subclass)")


def make_plant(name: str | os.PathLike[str], dt: float | None = None, *,
               physics_dt: float | None = None, **params: Any) -> Plant:
    """Build the plant of a registered system, or of any MJCF file.

    MuJoCo systems take their parameters from their MJCF (edit the file, or pass
    ``model_file=``; ``outputs=`` and the rollout's ``nthread=`` as :class:`MujocoPlant`);
    ODE systems take parameter overrides as keywords. The lab plants of :data:`LAB_PLANTS`
    (``furuta``, ``acrobot``, ``cart_pole``) are MJCF files measured by their encoders
    (``outputs=`` and ``inputs=`` as for an MJCF file, default the encoders and all
    actuators). A path to an MJCF file (an
    ``os.PathLike``, or a string ending in ``.xml``) builds the system of
    :func:`hgo_mj.systems.mjcf.mjcf_system` with ``outputs=`` (sensor or joint names) and
    ``inputs=`` (actuator names, default all); ``dt`` defaults to the MJCF's timestep.

    Parameters
    ----------
    name : str or os.PathLike
        A key of :data:`hgo_mj.systems.SYSTEMS` or :data:`LAB_PLANTS` (``hgo-mj list`` names
        them), or an MJCF file.
    dt : float, optional
        Control period; default 0.001 s for registered MuJoCo plants, the MJCF's timestep for
        an MJCF file or a lab plant, the system's ``default_dt`` (else 0.01) for ODE plants.
    physics_dt : float, optional
        Integration step (MuJoCo timestep, or the RK4 step); ``dt`` is a multiple of it.
    **params
        MuJoCo: ``model_file``, ``outputs``, ``nthread``, ``model_fields``; an MJCF file or a
        lab plant: ``outputs``, ``inputs``, ``nthread``, ``model_fields``; ODE: the system's
        parameters.

    Returns
    -------
    Plant
        A :class:`MujocoPlant` or an :class:`OdePlant`.

    Raises
    ------
    DesignError
        An unknown plant or keyword (the valid ones are listed), or a bad value;
        :class:`~hgo_mj.exceptions.ModelError` for an MJCF file that cannot be used.

    Examples
    --------
    >>> plant = make_plant("pendulum", dt=0.002)
    >>> type(plant).__name__, plant.dt, plant.system.output_names
    ('MujocoPlant', 0.002, ('angle',))
    >>> make_plant("pendulum", mass=2.0)
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: plant 'pendulum' (MuJoCo: parameters come from ...
    >>> make_plant(model_path("pendulum.xml"), outputs=["hinge"]).state_names
    ('hinge_angle', 'hinge_velocity')
    >>> furuta = make_plant("furuta")
    >>> furuta.dt, furuta.system.output_names
    (0.001, ('arm_angle', 'pendulum_angle'))
    """
    from ..systems import SYSTEMS

    if isinstance(name, os.PathLike) or (isinstance(name, str) and name.endswith(".xml")):
        return _mjcf_plant(name, dt, physics_dt, params)
    if isinstance(name, str) and name in LAB_PLANTS:
        file, outputs = LAB_PLANTS[name][:2]
        return _mjcf_plant(model_path(file), dt, physics_dt, {"outputs": list(outputs), **params})
    if isinstance(name, str) and ":" in name:  # the user's own System subclass
        from ..systems.base import System

        cls = import_class("plant", name, System)
    elif not isinstance(name, str) or name not in SYSTEMS:
        raise unknown_plant(name)
    else:
        cls = SYSTEMS[name]
    if cls.model_file is not None:
        reject_unknown(f"plant {name!r} (MuJoCo: parameters come from {cls.model_file})",
                       params, ["model_file", "outputs", "nthread", "model_fields"])
        return MujocoPlant(cls, 0.001 if dt is None else dt, physics_dt=physics_dt, **params)
    check_call(f"plant {name!r}", cls.__init__, params)
    system = cls(**params)
    return OdePlant(system, getattr(cls, "default_dt", 0.01) if dt is None else dt,
                    physics_dt=physics_dt)


def _mjcf_plant(path: Any, dt: float | None, physics_dt: float | None,
                params: dict[str, Any]) -> Plant:
    from ..systems.mjcf import mjcf_system

    reject_unknown(f"MJCF plant {str(path)!r}", params, ["outputs", "inputs", "nthread",
                                                         "model_fields"])
    if "outputs" not in params:
        raise DesignError(f"MJCF plant {str(path)!r} needs outputs= (MJCF sensor or joint names)")
    cls = mjcf_system(path, params["outputs"], params.get("inputs"))
    if dt is None:
        dt = physics_dt if physics_dt is not None else float(cls.load_model().opt.timestep)
    return MujocoPlant(cls, dt, physics_dt=physics_dt, nthread=params.get("nthread"),
                       model_fields=params.get("model_fields"))


__all__ = ["LAB_PLANTS", "MujocoPlant", "OdePlant", "Plant", "make_plant", "model_path",
           "plant_names", "unknown_plant"]
