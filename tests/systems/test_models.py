"""Every shipped MJCF loads, names every element, and simulates without contacts."""

from __future__ import annotations

from pathlib import Path

import mujoco
import pytest

MODELS = sorted((Path(__file__).resolve().parents[2] / "models").glob("*.xml"))
MECHANICAL = [p for p in MODELS if p.stem in
              ("pendulum", "cart_pendulum", "elastic_joint", "elastic_joint_2link")]

# (element kind, count attribute, accessor, first index checked: the world body has no name)
_KINDS = [
    ("body", "nbody", "body", 1),
    ("joint", "njnt", "jnt", 0),
    ("geom", "ngeom", "geom", 0),
    ("actuator", "nu", "actuator", 0),
    ("sensor", "nsensor", "sensor", 0),
    ("tendon", "ntendon", "tendon", 0),
]


def test_the_mechanical_models_are_shipped():
    assert len(MECHANICAL) == 4


@pytest.mark.parametrize("path", MODELS, ids=[p.stem for p in MODELS])
def test_model_loads_and_names_every_element(path):
    m = mujoco.MjModel.from_xml_path(str(path))
    unnamed = [f"{kind} {i}" for kind, count, acc, first in _KINDS
               for i in range(first, getattr(m, count)) if not getattr(m, acc)(i).name]
    assert unnamed == [], f"{path.name}: unnamed elements {unnamed}"
    assert m.nu >= 1 and m.nsensor >= 1


@pytest.mark.parametrize("path", MECHANICAL, ids=[p.stem for p in MECHANICAL])
def test_model_has_no_contacts_and_uses_rk4(path):
    m = mujoco.MjModel.from_xml_path(str(path))
    colliding = [m.geom(i).name for i in range(m.ngeom)
                 if m.geom_contype[i] != 0 or m.geom_conaffinity[i] != 0]
    assert colliding == []
    assert m.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    assert m.opt.timestep == pytest.approx(0.001)
    d = mujoco.MjData(m)
    for _ in range(10):
        mujoco.mj_step(m, d)
    assert d.ncon == 0


def test_gravity_is_realistic_except_for_the_time_scaled_cart_pendulum():
    for path in MECHANICAL:
        m = mujoco.MjModel.from_xml_path(str(path))
        want = -1.0 if path.stem == "cart_pendulum" else -9.81
        assert tuple(m.opt.gravity) == (0.0, 0.0, want), path.name
