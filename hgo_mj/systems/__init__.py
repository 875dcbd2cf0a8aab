"""Analytic systems, one module per plant family; ``SYSTEMS`` maps registry names to classes.

A family's module is imported on first use (its name looked up in ``SYSTEMS``, its class
imported from here), so ``import hgo_mj.systems`` loads no family."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._registry import LazyRegistry, lazy_module
from .base import System

if TYPE_CHECKING:  # imported on first use (module __getattr__)
    from .cart_pendulum import CartPendulum
    from .elastic_joint import ElasticJoint
    from .elastic_joint_2link import ElasticJoint2Link
    from .papers import (
        BesanconExample1,
        BesanconExample2,
        BioreactorBastinGevers,
        BioreactorBullinger,
        JoSonExample,
    )
    from .pendulum import Pendulum

#: registry name -> ``"module:Class"`` of the package's systems
FAMILIES = {
    "pendulum": "hgo_mj.systems.pendulum:Pendulum",
    "cart_pendulum": "hgo_mj.systems.cart_pendulum:CartPendulum",
    "elastic_joint": "hgo_mj.systems.elastic_joint:ElasticJoint",
    "elastic_joint_2link": "hgo_mj.systems.elastic_joint_2link:ElasticJoint2Link",
    "bioreactor_bullinger": "hgo_mj.systems.papers:BioreactorBullinger",
    "bioreactor_bastin_gevers": "hgo_mj.systems.papers:BioreactorBastinGevers",
    "besancon_ex1": "hgo_mj.systems.papers:BesanconExample1",
    "besancon_ex2": "hgo_mj.systems.papers:BesanconExample2",
    "jo_son": "hgo_mj.systems.papers:JoSonExample",
}

#: registry name -> System subclass, each module imported on first lookup
SYSTEMS: LazyRegistry[type[System]] = LazyRegistry("system", FAMILIES)


#: a class (``Pendulum``, ...) imported from its module on first use (PEP 562)
__getattr__, __dir__ = lazy_module(__name__, FAMILIES.values())


__all__ = ["FAMILIES", "SYSTEMS", "System", "Pendulum", "CartPendulum", "ElasticJoint",
           "ElasticJoint2Link", "BioreactorBullinger", "BioreactorBastinGevers", "BesanconExample1",
           "BesanconExample2", "JoSonExample"]
