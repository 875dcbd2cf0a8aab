"""MujocoPlant and OdePlant: timing, outputs, state, validation, divergence."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from hgo_mj.exceptions import DesignError, DimensionError, DivergenceError
from hgo_mj.inputs import Constant
from hgo_mj.observers import HighGainObserver
from hgo_mj.plants import MujocoPlant, OdePlant, Plant, make_plant, model_path
from hgo_mj.simulate import simulate
from hgo_mj.systems import ElasticJoint, Pendulum


def test_control_period_runs_substeps_with_u_held():
    a = MujocoPlant(Pendulum, dt=0.005)
    b = MujocoPlant(Pendulum, dt=0.001)
    assert a.substeps == 5
    a.step([0.2])
    for _ in range(5):
        b.step([0.2])
    np.testing.assert_array_equal(a.state, b.state)
    assert a.t == pytest.approx(0.005)


def test_outputs_are_the_named_sensors_after_the_step():
    plant = MujocoPlant(ElasticJoint, dt=0.001,
                        outputs=("link_angle", "motor_angle", "motor_velocity"))
    plant.reset([0.1, 0.2, 0.3, -0.4])
    for _ in range(7):
        plant.step([0.5])
    # reference: MuJoCo's own sensors, evaluated at the current state
    m, d = plant.model, plant.data
    mujoco.mj_forward(m, d)
    ref = [d.sensor(name).data[0] for name in plant.output_names]
    np.testing.assert_array_equal(plant.outputs(), ref)
    np.testing.assert_array_equal(plant.state[[0, 1, 3]], ref)


def test_state_is_a_copy():
    plant = make_plant("pendulum")
    x = plant.state
    x[0] = 99.0
    assert plant.state[0] != 99.0


@pytest.mark.parametrize("kwargs, exc, match", [
    ({"dt": 0.0015}, DesignError, r"dt = 0.0015 must be a positive integer multiple of "
                                  r"physics_dt = 0.001"),
    ({"dt": -1.0}, DesignError, "dt must be > 0"),
    ({"outputs": ("angle", "speed")}, DesignError, "pendulum.xml has no sensor named 'speed'"),
])
def test_bad_construction(kwargs, exc, match):
    with pytest.raises(exc, match=match):
        MujocoPlant(Pendulum, **kwargs)


def test_bad_reset_and_input():
    plant = make_plant("pendulum")
    with pytest.raises(DimensionError, match="x0 must have length 2; found length 3"):
        plant.reset([0.0, 0.0, 0.0])
    with pytest.raises(DivergenceError, match=r"input u\[0\] must be finite .*; found nan"):
        plant.step([np.nan])
    with pytest.raises(DesignError, match="parameters come from pendulum.xml"):
        make_plant("pendulum", mass=2.0)
    with pytest.raises(DesignError, match="no MJCF model named 'nope.xml'"):
        model_path("nope.xml")


def test_reset_from_a_list_of_floats_is_the_checked_reset():
    """An environment's reset hands a list of Python floats: written into MjData entry by
    entry, it gives the full physics state of the checked reset from an array, bit for bit;
    a list the short path cannot take gives the checked path's error."""
    a, b = make_plant("pendulum"), make_plant("pendulum")
    full = mujoco.mjtState.mjSTATE_FULLPHYSICS
    for x0 in ([0.3, -1.25], [-3.0, 1e9], [0.0, 0.0]):
        a.step([0.4])  # a reset from a running state
        a.reset(x0)
        b.reset(np.array(x0))
        sa, sb = (np.empty(mujoco.mj_stateSize(p.model, full)) for p in (a, b))
        mujoco.mj_getState(a.model, a.data, sa, full)
        mujoco.mj_getState(b.model, b.data, sb, full)
        np.testing.assert_array_equal(sa, sb)
        for field in ("qacc", "xpos", "xquat", "sensordata"):  # mj_forward's results
            np.testing.assert_array_equal(getattr(a.data, field), getattr(b.data, field))
        assert (a.batch, a.batched, a.state.tolist()) == (1, False, x0)
    for bad, exc, match in (([0.1, np.nan], DesignError, "x0 must be finite"),
                            ([0.1, np.inf], DesignError, "x0 must be finite"),
                            ([0.1, 1e12], DesignError, "angular_velocity = 1e\\+12 is a state"),
                            ([True, 0.0], DimensionError, "1-D array of numbers"),
                            ([0.1], DimensionError, "must have length 2")):
        with pytest.raises(exc, match=match):
            a.reset(bad)
    a.reset([1, 0])  # integers: the checked path takes them
    assert a.state.tolist() == [1.0, 0.0]


def test_huge_input_is_an_error_with_the_partial_run():
    """MuJoCo would silently zero a huge control; hgo_mj refuses it, keeping the run so far."""
    plant = make_plant("pendulum")
    ob = HighGainObserver(plant.system, k=10.0)
    u = lambda t: np.array([0.0 if t < 0.0095 else 1e12])  # noqa: E731
    with pytest.raises(DivergenceError, match="MuJoCo would zero it") as info:
        simulate(plant, None, {"hgo": ob}, u, 0.05)
    traj = info.value.trajectory
    assert len(traj) == 11 and np.all(np.isfinite(traj.x))


def test_mujoco_state_reset_is_an_error():
    plant = make_plant("pendulum")
    plant.data.qvel[0] = np.inf  # what an unstable simulation produces
    with pytest.raises(DivergenceError, match="reset the simulation .mjWARN_BADQ"):
        plant.step([0.0])


def test_ode_plant_divergence_names_the_time(chain):
    from hgo_mj.plants.ode import OdePlant

    plant = OdePlant(chain(2)(), dt=0.1)
    plant.reset([1e308, 1e308])
    with pytest.raises(DivergenceError, match="left the finite numbers at t=0.1"):
        with np.errstate(over="ignore", invalid="ignore"):
            plant.step([1e308])
    with pytest.raises(DesignError, match="must be a System instance"):
        OdePlant(Constant, dt=0.1)


def test_plant_interface_is_reset_run_state_outputs():
    """One interface: the abstract surface is the batched primitive and its readers; step is
    derived once in the base from run (no per-plant twins, no list forms)."""
    assert Plant.__abstractmethods__ == {"reset", "run", "state", "outputs"}
    for cls in (MujocoPlant, OdePlant):
        assert "step" not in vars(cls)
        for name in ("state_list", "outputs_list", "step_list"):
            assert not hasattr(cls, name)
    plant = make_plant("pendulum")
    ref = make_plant("pendulum")
    plant.step([0.3])
    X, Yc = ref.run(np.full((1, 1, 1), 0.3), 1)
    np.testing.assert_array_equal(plant.state, ref.state)
    assert plant.t == ref.t
    with pytest.raises(DimensionError, match=r"u must have shape \(1,\); found shape \(2,\)"):
        plant.step([0.3, 0.1])
    plant.reset(batch=2)
    with pytest.raises(DimensionError, match=r"u must have shape \(2, 1\); found shape \(1,\)"):
        plant.step([0.3])
