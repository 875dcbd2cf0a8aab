"""Analytic systems, one module per plant family; ``SYSTEMS`` maps registry names to classes."""

from __future__ import annotations

from .base import System
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

SYSTEMS: dict[str, type[System]] = {
    cls.name: cls
    for cls in (Pendulum, CartPendulum, ElasticJoint, ElasticJoint2Link, BioreactorBullinger,
                BioreactorBastinGevers, BesanconExample1, BesanconExample2, JoSonExample)
}

__all__ = ["SYSTEMS", "System", *(c.__name__ for c in SYSTEMS.values())]
