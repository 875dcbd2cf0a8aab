"""Named MuJoCo model fields (hgo_mj/plants/fields.py): a plant with Coulomb friction its
system does not model, the MuJoCo filters' ``model_fields`` and their refusal of
``system_params`` that do not reach the MJCF, and one-line errors for bad fields."""

from __future__ import annotations

import numpy as np
import pytest

from hgo_mj.exceptions import DesignError
from hgo_mj.observers.kalman import MujocoExtendedKalmanFilter, MujocoUnscentedKalmanFilter
from hgo_mj.plants import make_plant
from hgo_mj.plants.fields import get_field, resolve, set_fields
from hgo_mj.scenario import scenario_run
from hgo_mj.systems import SYSTEMS, Pendulum


def _swing(plant, T=5000):
    plant.reset([0.5, 0.0])
    X = np.empty((T, 2))
    for k in range(T):
        plant.step([0.0])
        X[k] = plant.state
    return X


def test_plant_friction_is_in_the_physics_and_not_in_the_system():
    """0.05 N m of frictionloss on the hinge stops the free swing within 5 s (the frictionless
    one keeps swinging); the system read back from the model (the observers' equations) has
    the same parameters as the nominal one."""
    free = make_plant("pendulum", 0.001)
    dry = make_plant("pendulum", 0.001, model_fields={"dof_frictionloss[hinge]": 0.05})
    assert dry.model.dof_frictionloss[0] == 0.05 and free.model.dof_frictionloss[0] == 0.0
    assert dry.system.params == free.system.params
    a, b = _swing(free), _swing(dry)
    assert np.ptp(a[-1000:, 0]) > 0.5 and np.ptp(b[-1000:, 0]) < 0.01
    # the same through a scenario's [plant] table
    kw = scenario_run({"plant": {"name": "pendulum", "dt": 0.001, "model_fields": {
        "dof_frictionloss[hinge]": 0.05}}, "observers": [], "run": {"duration": 1.0}})
    assert kw["plant"].model.dof_frictionloss[0] == 0.05


@pytest.mark.parametrize("cls", [MujocoExtendedKalmanFilter, MujocoUnscentedKalmanFilter])
def test_filters_model_fields_give_a_wrong_model_and_system_params_alone_are_refused(cls):
    wrong = {"dof_damping[hinge]": 0.011}
    f = cls(Pendulum(damping=0.011), R=1e-4, model_fields=wrong)
    assert f.model.m.dof_damping[0] == 0.011
    # a heavier bob is a larger inertia about the hinge too: the system must say both
    with pytest.raises(DesignError, match=r"whose mass = 0.275, inertia = 0.0592"):
        cls(Pendulum(), R=1e-4, model_fields={"body_mass[pole]": 0.275})
    with pytest.raises(DesignError, match=r"damping = 0.01 differ from the system's damping = "
                                          r"0.011: system_params do not reach the MJCF"):
        cls(Pendulum(damping=0.011), R=1e-4)
    # a parameter being estimated may differ (the system holds its initial guess) ...
    cls(SYSTEMS["elastic_joint"](stiffness=9.0), R=1e-4, estimate=["stiffness"],
        theta_hat0=[9.0])
    # ... and a model given by the user is the user's
    m = Pendulum.load_model()
    m.dof_damping[0] = 0.02
    assert cls(Pendulum(), R=1e-4, model=m).model.m.dof_damping[0] == 0.02
    with pytest.raises(DesignError, match="model= and model_fields= are for the MuJoCo"):
        from hgo_mj.observers.kalman import ExtendedKalmanFilter

        ExtendedKalmanFilter(Pendulum(), R=1e-4, model_fields=wrong)


def test_aliases_vectors_and_gravity():
    E = SYSTEMS["elastic_joint"]
    f = MujocoExtendedKalmanFilter(E(stiffness=9.0), R=1e-4, model_fields={"stiffness": 9.0})
    assert f.model.m.tendon_stiffness[0] == 9.0
    m = Pendulum.load_model()
    set_fields(m, {"body_inertia[pole]": [1e-3, 2e-3, 3e-3], "opt.gravity": 3.0})
    assert get_field(m, *resolve(m, "body_inertia[pole]")).tolist() == [1e-3, 2e-3, 3e-3]
    assert get_field(m, *resolve(m, "opt.gravity")) == pytest.approx(3.0)
    assert np.allclose(m.opt.gravity, [0, 0, -3.0])


@pytest.mark.parametrize("values,match", [
    ({"dof_friction[hinge]": 0.1}, r"give a model field \[.*\]\[element name\]"),
    ({"dof_frictionloss[elbow]": 0.1}, r"the model has no joint named 'elbow'"),
    ({"dof_frictionloss[hinge]": -0.1}, r"must be a finite number >= 0; found -0.1"),
    ({"dof_frictionloss[hinge]": "a"}, r"must be a finite number >= 0; found 'a'"),
    ({"body_inertia[pole]": 0.1}, r"must be 3 finite numbers >= 0; found 0.1"),
    ({"dof_damping[hinge]": float("nan")}, r"must be a finite number >= 0; found nan"),
    ([1, 2], r"must be a table of 'field\[element\]' = value; found list"),
])
def test_bad_fields_are_one_line_and_change_nothing(values, match):
    m = Pendulum.load_model()
    before = (m.dof_frictionloss.copy(), m.body_inertia.copy(), m.dof_damping.copy())
    with pytest.raises(DesignError, match=match):
        set_fields(m, {"dof_damping[hinge]": 0.5, **values} if isinstance(values, dict)
                   else values)
    assert all(np.array_equal(x, y) for x, y in zip(before, (
        m.dof_frictionloss, m.body_inertia, m.dof_damping)))
