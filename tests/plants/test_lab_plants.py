"""The three lab plants under models/ (issue 12): the rotary inverted (Furuta) pendulum of the
Quanser QUBE-Servo 2, Spong's acrobot and the Barto-Sutton-Anderson cart-pole, run through the
generic MJCF path (hgo_mj.systems.mjcf) with quantized encoders on every joint."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from hgo_mj.observers import make_observer
from hgo_mj.plants import make_plant, model_path
from hgo_mj.sensors import Quantization, SensorChain
from hgo_mj.simulate import simulate

REV = 2 * np.pi
#: file -> (encoder outputs, encoder resolutions, input amplitude, input frequency [rad/s])
LAB = {
    "furuta.xml": (["arm_angle", "pendulum_angle"], [REV / 2048, REV / 2048], 3.0, 8.0),
    "acrobot.xml": (["shoulder_angle", "elbow_angle"], [REV / 4096, REV / 4096], 3.0, 2.0),
    "cart_pole.xml": (["cart_position", "pole_angle"], [REV * 0.01482 / 4096, REV / 4096],
                      3.0, 4.0),
}
#: what tests/systems/test_models.py does not check already
_NAMED = [(mujoco.mjtObj.mjOBJ_LIGHT, "nlight", 0), (mujoco.mjtObj.mjOBJ_CAMERA, "ncam", 0)]


@pytest.mark.parametrize("name", sorted(LAB))
def test_lights_and_cameras_named_no_contacts_rk4(name):
    m = mujoco.MjModel.from_xml_path(str(model_path(name)))
    assert not np.any(m.geom_contype) and not np.any(m.geom_conaffinity)
    assert m.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4 and m.opt.timestep == 0.001
    for kind, count, first in _NAMED:
        unnamed = [i for i in range(first, getattr(m, count)) if not mujoco.mj_id2name(m, kind, i)]
        assert unnamed == [], f"{name}: unnamed {kind.name} {unnamed}"
    assert m.nq == m.nv == 2 and m.nu == 1 and m.na == 0


def test_furuta_carries_the_qube_servo_2_parameters():
    m = mujoco.MjModel.from_xml_path(str(model_path("furuta.xml")))
    arm, pend = m.joint("arm"), m.joint("pendulum")
    assert m.body("arm_body").mass[0] == pytest.approx(0.0106 + 0.095)  # hub + rotary arm
    assert m.body("pendulum_body").mass[0] == pytest.approx(0.024)
    # pendulum: thin rod of 0.129 m about its end, COM 0.0645 m below the hinge
    assert m.body("pendulum_body").ipos[2] == pytest.approx(-0.129 / 2)
    assert m.actuator("voltage").gear[0] == pytest.approx(0.042 / 8.4)
    assert m.dof_damping[arm.dofadr[0]] == pytest.approx(0.0015 + 0.042 * 0.042 / 8.4, rel=1e-2)
    assert m.dof_damping[pend.dofadr[0]] == pytest.approx(0.0005)
    assert m.dof_armature[arm.dofadr[0]] == pytest.approx(4.0e-6)
    # the pendulum's inertia about its hinge: a thin rod about its end, mp Lp^2 / 3
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    M = np.zeros((2, 2))
    mujoco.mj_fullM(m, d, M)  # mujoco 4: (model, data, dst)
    J = M[pend.dofadr[0], pend.dofadr[0]]
    assert J == pytest.approx(0.024 * 0.129 ** 2 / 3, rel=2e-3)

@pytest.mark.parametrize("name", sorted(LAB))
def test_velocities_from_quantized_encoders(name):
    """Every joint read by its encoder only (quantized to the unit's counts): the high-gain
    chains with MuJoCo's model term and the MuJoCo EKF estimate both velocities far better
    than a backward difference of the counts."""
    outputs, res, amp, w = LAB[name]
    dt, duration = 0.002, 2.0
    plant = make_plant(model_path(name), dt, outputs=outputs)
    system = plant.system
    assert system.normal_form_problem is None and system.normal_form_orders == (2, 2)
    observers = {
        "hgo_model": make_observer("high_gain_multi", system, k=40.0, model=True),
        "ekf": make_observer("ekf_mujoco", system, model=plant, R=[r ** 2 / 12 for r in res],
                             Q=1e-3, x_hat0=np.zeros(4)),
    }
    tr = simulate(plant, SensorChain([Quantization(resolution=res)], seed=0), observers,
                  lambda t: [amp * np.sin(w * t)], duration, sample_period=dt,
                  x0=[0.0, 0.1, 0.0, 0.0], seed=0)
    late = tr.t >= duration / 2
    truth = tr.x[:, 2:]
    assert np.all(np.ptp(truth[late], axis=0) > 0.05)  # both joints move
    assert np.all(np.abs(tr.y_meas - tr.y_clean) <= np.array(res) / 2 + 1e-12)
    bd = np.diff(tr.y_meas, axis=0) / dt
    rms_bd = np.sqrt(np.mean((bd - truth[1:])[late[1:]] ** 2, axis=0))
    for k in observers:
        rms = np.sqrt(np.mean(tr.error(k)[late][:, 2:] ** 2, axis=0))
        assert np.all(rms < 0.5 * rms_bd), (k, rms, rms_bd)


@pytest.mark.parametrize("name", ["furuta", "acrobot", "cart_pole"])
def test_lab_plants_are_plant_names(name):
    """``make_plant(name)`` and a scenario's ``[plant] name`` build the lab plant: the MJCF
    file measured by its encoders, as the generic path builds it from the file."""
    from hgo_mj.cli import cmd_list
    from hgo_mj.plants import LAB_PLANTS, plant_names
    from hgo_mj.scenario import build_plant
    from hgo_mj.schema import check_scenario

    file = LAB_PLANTS[name][0]
    outputs, *_ = LAB[file]
    by_file = make_plant(model_path(file), outputs=outputs)
    for plant in (make_plant(name), build_plant({"name": name})):
        assert plant.system.output_names == tuple(outputs)
        assert plant.state_names == by_file.state_names and plant.dt == by_file.dt == 0.001
    check_scenario({"plant": {"name": name}, "run": {"duration": 1.0}}, required=True)
    assert name in plant_names() and f"  {name} " in cmd_list()
    assert make_plant(name, 0.002, outputs=[outputs[1]]).system.output_names == (outputs[1],)
    with pytest.raises(Exception, match=rf"unknown plant 'furuta_x'; valid: \[.*'{name}'"):
        make_plant("furuta_x")
    with pytest.raises(Exception, match=rf"unknown plant 'furuta_x'; valid: \[.*'{name}'"):
        check_scenario({"plant": {"name": "furuta_x"}})
