"""Gymnasium environments of hgo_mj (installed as ``hgo_mj.envs``), registered on import.

============================================  ==========================================
id                                            class
============================================  ==========================================
``hgo_mj/PendulumSwingUp-v0``                 :class:`PendulumSwingUpEnv`
``hgo_mj/CartPendulumBalance-v0``             :class:`CartPendulumBalanceEnv`
``hgo_mj/ElasticJointReach-v0``               :class:`ElasticJointReachEnv`
``hgo_mj/ElasticJoint2LinkReach-v0``          :class:`ElasticJoint2LinkReachEnv`
``hgo_mj/FurutaSwingUp-v0``                   :class:`FurutaSwingUpEnv`
``hgo_mj/AcrobotSwingUp-v0``                  :class:`AcrobotSwingUpEnv`
``hgo_mj/CartPoleSwingUp-v0``                 :class:`CartPoleSwingUpEnv`
``hgo_mj/FurutaBalance-v0``                   :class:`FurutaBalanceEnv`
``hgo_mj/AcrobotBalance-v0``                  :class:`AcrobotBalanceEnv`
``hgo_mj/AcrobotBalance-v1``                  :class:`AcrobotBalanceEnv`, ``start_noise=0.02``
``hgo_mj/CartPoleBalance-v0``                 :class:`CartPoleBalanceEnv`
============================================  ==========================================

Each is a MuJoCo plant, a sensor chain and an observer in the loop (:class:`HgoEnv`) under a
task; the agent acts on the observer's estimate by default. Use them after
``import hgo_mj.envs``, or without importing anything through Gymnasium's module prefix::

    env = gymnasium.make("hgo_mj.envs:hgo_mj/PendulumSwingUp-v0", observation="true")

(Gymnasium 1.x loads no plugins by entry point; the ``module:id`` form imports the module.)
``gymnasium.make_vec(id, num_envs=N)`` gives the native vector environment
(:class:`~hgo_mj.envs.vector.HgoVectorEnv`: the one loop at B = N, one process);
``vectorization_mode="sync"`` Gymnasium's ``SyncVectorEnv`` of single environments.
The time limit is Gymnasium's ``TimeLimit``, added by ``gymnasium.make`` from
``max_episode_steps``. Wrappers for other environments are in :mod:`hgo_mj.envs.wrappers`.
"""

from __future__ import annotations

from typing import Any

import gymnasium

from .core import INFO_LEVELS, OBSERVATION_MODES, HgoEnv, Task, sensor_chain
from .environments import (
    AcrobotBalanceEnv,
    AcrobotSwingUpEnv,
    CartPendulumBalanceEnv,
    CartPoleBalanceEnv,
    CartPoleSwingUpEnv,
    ElasticJoint2LinkReachEnv,
    ElasticJointReachEnv,
    FurutaBalanceEnv,
    FurutaSwingUpEnv,
    PendulumSwingUpEnv,
)
from .vector import HgoVectorEnv, vector_entry_point

#: registered id -> environment class
ENVIRONMENTS: dict[str, type[HgoEnv]] = {str(cls.env_id): cls for cls in (
    PendulumSwingUpEnv, CartPendulumBalanceEnv, ElasticJointReachEnv, ElasticJoint2LinkReachEnv,
    FurutaSwingUpEnv, AcrobotSwingUpEnv, CartPoleSwingUpEnv, FurutaBalanceEnv, AcrobotBalanceEnv,
    CartPoleBalanceEnv)}

#: registered id of a variant -> (its environment's id in :data:`ENVIRONMENTS`, the
#: registration keywords it differs by)
VARIANTS: dict[str, tuple[str, dict[str, Any]]] = {
    "hgo_mj/AcrobotBalance-v1": ("hgo_mj/AcrobotBalance-v0", {"start_noise": 0.02}),
    "hgo_mj/CartPoleSwingUp-v1": ("hgo_mj/CartPoleSwingUp-v0", {"reward": "dm_control",
                                                                "end_stops": True}),
    "hgo_mj/FurutaSwingUp-v1": ("hgo_mj/FurutaSwingUp-v0", {"reward": "quanser"}),
    "hgo_mj/AcrobotSwingUp-v1": ("hgo_mj/AcrobotSwingUp-v0", {"reward": "dm_control"}),
}

#: registered id of a variant -> its ``reward_threshold`` where it differs from its
#: environment's: the swing-ups' literature rewards lie in [0, 1] per step, and half the
#: 500 steps' maximum, 250, is the threshold
VARIANT_THRESHOLDS: dict[str, float] = {
    "hgo_mj/CartPoleSwingUp-v1": 250.0,
    "hgo_mj/FurutaSwingUp-v1": 250.0,
    "hgo_mj/AcrobotSwingUp-v1": 250.0,
}


def register_all() -> None:
    """Register every environment with Gymnasium (done on import; idempotent).

    Each id of :data:`ENVIRONMENTS` gets its class as entry point, the task's
    ``max_episode_steps`` (Gymnasium's ``TimeLimit``) and :func:`vector_entry_point` by name
    (``"hgo_mj.envs:make_<EnvClass>_vector"``: the native :class:`HgoVectorEnv` of
    ``gymnasium.make_vec``) and the task's
    ``reward_threshold``; each id of :data:`VARIANTS` the same as its environment's with its
    keywords as the spec's ``kwargs`` (and its :data:`VARIANT_THRESHOLDS` entry, if any).
    An id already registered is left as it is.

    Examples
    --------
    >>> import gymnasium
    >>> import hgo_mj.envs
    >>> hgo_mj.envs.register_all()
    >>> "hgo_mj/PendulumSwingUp-v0" in gymnasium.registry
    True
    >>> gymnasium.spec("hgo_mj/PendulumSwingUp-v0").max_episode_steps
    250
    >>> gymnasium.spec("hgo_mj/AcrobotBalance-v1").kwargs
    {'start_noise': 0.02}
    """
    ids: dict[str, tuple[str, dict[str, Any]]] = {
        env_id: (env_id, {}) for env_id in ENVIRONMENTS} | VARIANTS
    for env_id, (base, kwargs) in ids.items():
        if env_id in gymnasium.registry:
            continue
        cls = ENVIRONMENTS[base]
        gymnasium.register(id=env_id, entry_point=f"{__name__}.environments:{cls.__name__}",
                           max_episode_steps=cls.task_class.max_episode_steps,  # type: ignore[union-attr]
                           reward_threshold=VARIANT_THRESHOLDS.get(
                               env_id, cls.task_class.reward_threshold),  # type: ignore[union-attr]
                           vector_entry_point=f"{__name__}:make_{cls.__name__}_vector",
                           kwargs=dict(kwargs))


def __getattr__(name: str) -> Any:
    """``make_<EnvClass>_vector``: the registered vector entry points by name (a string in
    the spec, so that ``spec.to_json()`` works), made by :func:`vector_entry_point`."""
    for cls in ENVIRONMENTS.values():
        if name == f"make_{cls.__name__}_vector":
            return vector_entry_point(cls)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


register_all()

__all__ = ["ENVIRONMENTS", "INFO_LEVELS", "OBSERVATION_MODES", "VARIANTS", "VARIANT_THRESHOLDS",
           "AcrobotBalanceEnv",
           "AcrobotSwingUpEnv", "CartPendulumBalanceEnv", "CartPoleBalanceEnv",
           "CartPoleSwingUpEnv", "FurutaBalanceEnv", "FurutaSwingUpEnv",
           "ElasticJoint2LinkReachEnv", "ElasticJointReachEnv", "HgoEnv", "HgoVectorEnv",
           "PendulumSwingUpEnv",
           "Task", "register_all", "sensor_chain"]
