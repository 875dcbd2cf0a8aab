"""Any MJCF as plant and model (hgo_mj.systems.mjcf): on the shipped pendulum against its
hand-written system, and on Gymnasium's inverted_double_pendulum.xml and reacher.xml, files
hgo_mj did not write."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import gymnasium
import mujoco
import numpy as np
import pytest

from hgo_mj.exceptions import DesignError, ModelError
from hgo_mj.inputs import signal_from_spec
from hgo_mj.observers import make_observer
from hgo_mj.plants import make_plant, model_path
from hgo_mj.sensors import SensorChain
from hgo_mj.simulate import Trajectory, simulate
from hgo_mj.systems import Pendulum
from hgo_mj.systems.mjcf import mjcf_system

ASSETS = Path(os.path.dirname(gymnasium.__file__)) / "envs" / "mujoco" / "assets"
IDP = ASSETS / "inverted_double_pendulum.xml"
REACHER = ASSETS / "reacher.xml"


def test_state_outputs_inputs_and_units_come_from_the_file():
    cls = mjcf_system(IDP, outputs=["slider", "hinge", "hinge2"])
    assert cls.joints == ("slider", "hinge", "hinge2")
    assert cls.state_names == ("slider_position", "hinge_angle", "hinge2_angle",
                               "slider_velocity", "hinge_velocity", "hinge2_velocity")
    assert cls.state_units == ("m", "rad", "rad", "m/s", "rad/s", "rad/s")
    assert cls.output_names == ("slider_position", "hinge_angle", "hinge2_angle")
    assert cls.input_names == ("slide",)
    assert cls.normal_form_problem is None
    assert cls.normal_form_orders == (2, 2, 2) and cls.normal_form_outputs == (0, 1, 2)
    # unnamed actuators are named by index; the target joints are not measured
    rc = mjcf_system(REACHER, outputs=["joint0", "joint1"])
    assert rc.input_names == ("actuator0", "actuator1")
    assert rc.normal_form_orders is None
    assert "target_x" in rc.normal_form_problem and "ekf_mujoco" in rc.normal_form_problem


def test_outputs_read_the_named_sensors(tmp_path):
    xml = tmp_path / "arm.xml"
    xml.write_text("""<mujoco><option timestep="0.002"/><worldbody>
      <body name="link"><joint name="shoulder" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.02" mass="1"/>
        <site name="tip" pos="0.5 0 0"/></body></worldbody>
      <actuator><motor name="m" joint="shoulder"/></actuator>
      <sensor><jointpos name="enc" joint="shoulder"/><framepos name="tip_pos" objtype="site"
        objname="tip"/></sensor></mujoco>""")
    plant = make_plant(xml, outputs=["enc", "tip_pos"])
    assert plant.output_names == ("enc", "tip_pos[0]", "tip_pos[1]", "tip_pos[2]")
    # the joint's states are named after the encoder that measures it
    assert plant.state_names == ("enc", "enc_d1")
    plant.reset([0.3, 0.0])
    y = plant.outputs()
    np.testing.assert_allclose(y, [0.3, 0.5 * np.cos(0.3), 0.0, -0.5 * np.sin(0.3)], atol=1e-12)
    np.testing.assert_allclose(plant.system.output(np.array([0.3, 0.0])), y, atol=1e-12)


def test_chain_phi_equals_the_hand_written_pendulum_model():
    """The MJCF-derived model term of the shipped pendulum equals the analytic system's phi
    (paper 000's normal form z = (q, q'), q'' = phi(z, u)) to 1e-9 at random points."""
    cls = mjcf_system(model_path("pendulum.xml"), outputs=["hinge"])
    derived = cls()
    hand = Pendulum.from_mjmodel(derived.model)
    rng = np.random.default_rng(3)
    for _ in range(50):
        z, u = rng.uniform(-3, 3, 2), rng.uniform(-1, 1, 1)
        assert derived.chain_phi(z, u)[0] == pytest.approx(hand.phi(z, u), abs=1e-9)
        np.testing.assert_allclose(derived.dynamics(0.0, z, u), hand.f(0.0, z, u), atol=1e-9)


def _run(path, outputs, x0, duration, observers, amp):
    plant = make_plant(path, outputs=outputs, dt=0.01)
    m = len(plant.input_names)
    specs = [{"type": "multisine", "amplitudes": [amp], "frequencies": [0.5 + i]} for i in range(m)]
    inputs = signal_from_spec(specs if m > 1 else specs[0], m)
    obs = {k: make_observer(kind, plant.system, **kw) for k, (kind, kw) in observers.items()}
    sensor = SensorChain.from_spec([{"stage": "gaussian", "std": 1e-3}])
    return plant, simulate(plant, sensor, obs, inputs, duration, x0=x0, seed=1)


def _velocity_rms(tr: Trajectory, nj: int, est: np.ndarray) -> np.ndarray:
    half = len(tr.t) // 2
    return np.sqrt(np.nanmean((est[half:] - tr.x[half:, nj:]) ** 2, axis=0))


def test_velocities_of_gymnasiums_double_pendulum_from_noisy_angles():
    """Gymnasium's inverted_double_pendulum.xml, its three joint positions under 1e-3 Gaussian
    noise at 100 Hz: the MuJoCo EKF and the high-gain observer with MuJoCo's forward dynamics
    as model term estimate every velocity better than a backward difference of the same
    measurements (the EKF by a factor of 10)."""
    x0 = [0.0, 0.05, -0.05, 0.0, 0.0, 0.0]
    plant, tr = _run(IDP, ["slider", "hinge", "hinge2"], x0, 1.0, {
        "ekf": ("ekf_mujoco", {"Q": 1e-2, "R": 1e-6, "x_hat0": x0}),
        "hgo": ("high_gain_multi", {"k": 30.0, "model": True})}, 0.05)
    diff = np.vstack([np.full((1, 3), np.nan), np.diff(tr.y_meas, axis=0) / 0.01])
    base = _velocity_rms(tr, 3, diff)
    ekf = _velocity_rms(tr, 3, tr.estimate("ekf")[:, 3:])
    hgo = _velocity_rms(tr, 3, tr.estimate("hgo")[:, 3:])
    assert np.all(ekf < 0.1 * base), (ekf, base)
    assert np.all(hgo < base), (hgo, base)


def test_reacher_with_its_unmeasured_target_runs_the_mujoco_ekf_and_refuses_the_chains():
    x0 = [0.3, -0.5, 0.1, -0.1, 0.0, 0.0, 0.0, 0.0]
    plant, tr = _run(REACHER, ["joint0", "joint1"], x0, 2.0, {
        "ekf": ("ekf_mujoco", {"Q": 1e-2, "R": 1e-6, "x_hat0": x0})}, 0.5)
    diff = np.vstack([np.full((1, 2), np.nan), np.diff(tr.y_meas, axis=0) / 0.01])
    half = len(tr.t) // 2
    base = np.sqrt(np.nanmean((diff[half:] - tr.x[half:, 4:6]) ** 2, axis=0))
    ekf = np.sqrt(np.mean((tr.estimate("ekf")[half:, 4:6] - tr.x[half:, 4:6]) ** 2, axis=0))
    assert np.all(ekf < 0.1 * base), (ekf, base)
    with pytest.raises(DesignError, match="target_x.*ekf_mujoco"):
        make_observer("high_gain_multi", plant.system, k=30.0)
    with pytest.raises(ModelError, match="not measured"):
        plant.system.chain_phi(np.zeros(8), np.zeros(2))


@pytest.mark.parametrize(("xml", "outputs", "inputs", "match"), [
    (None, ["a"], None, "does not exist"),
    ("<mujoco><worldbody><bodyx/></worldbody></mujoco>", ["a"], None,
     "does not load: .*bodyx"),
    ('<mujoco><worldbody><body><joint name="j" type="ball"/><geom size="0.1"/></body>'
     '</worldbody></mujoco>', ["j"], None, "joint 'j' is a mjJNT_BALL joint"),
    ('<mujoco><worldbody><body><joint name="j"/><geom size="0.1"/></body></worldbody>'
     '<actuator><motor name="m" joint="j"/></actuator></mujoco>', ["k"], None,
     r"output 'k' is neither a sensor nor a joint; sensors: \[\], joints: \['j'\]"),
    ('<mujoco><worldbody><body><joint name="j"/><geom size="0.1"/></body></worldbody>'
     '<actuator><motor name="m" joint="j"/></actuator></mujoco>', ["j"], ["n"],
     r"no actuator named 'n'; actuators: \['m'\]"),
    ('<mujoco><worldbody><body><joint name="j"/><geom size="0.1"/></body></worldbody></mujoco>',
     "j", None, "outputs must be a non-empty list of names"),
])
def test_bad_models_are_one_clear_error(tmp_path, xml, outputs, inputs, match):
    path = tmp_path / "m.xml"
    if xml is not None:
        path.write_text(xml)
    with pytest.raises(ModelError, match=match):
        mjcf_system(path, outputs, inputs)


def test_command_line_runs_any_mjcf_and_refuses_bad_names(tmp_path):
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "hgo_mj.cli", "run", "--model", str(IDP), "--outputs", "slider",
           "hinge", "hinge2", "--observer", "ekf_mujoco:Q=0.01,R=1e-6", "--sensor",
           "gaussian:std=1e-3", "--duration", "0.3", "--x0", "[0,0.05,-0.05,0,0,0]",
           "--out", str(out), "--rrd", str(out / "run.rrd")]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    tr = Trajectory.load(out / "trajectory.npz")
    assert tr.state_names[:3] == ("slider_position", "hinge_angle", "hinge2_angle")
    assert tr.metadata["mjcf"]["outputs"] == ["slider", "hinge", "hinge2"]
    from hgo_mj.record import read

    df = read(out / "run.rrd")
    assert "/state/hinge2_velocity[hinge2_velocity ekf_mujoco_0]" in df.columns
    bad = subprocess.run([sys.executable, "-m", "hgo_mj.cli", "run", "--model", str(REACHER),
                          "--outputs", "joint0", "nope", "--duration", "1", "--out",
                          str(tmp_path / "o2")], capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2
    assert bad.stderr.strip().splitlines() == [
        "hgo-mj: error: reacher.xml: output 'nope' is neither a sensor nor a joint; sensors: "
        "[], joints: ['joint0', 'joint1', 'target_x', 'target_y']"]
    assert not (tmp_path / "o2").exists()


def test_scenario_file_takes_model_outputs_and_inputs(tmp_path):
    from hgo_mj.exceptions import DesignError as DE
    from hgo_mj.scenario import scenario_run

    sc = {"plant": {"model": str(IDP), "outputs": ["slider", "hinge", "hinge2"],
                    "inputs": ["slide"], "x0": [0, 0.05, -0.05, 0, 0, 0]},
          "observers": [{"type": "high_gain_multi", "k": 30.0, "model": True}],
          "run": {"duration": 0.2}}
    kw = scenario_run(sc)
    assert kw["plant"].input_names == ("slide",)
    assert kw["observers"]["high_gain_multi_0"].state_names[:2] == ("slider_position",
                                                                    "slider_velocity")
    with pytest.raises(DE, match="name .* or model .* not both"):
        scenario_run({**sc, "plant": {**sc["plant"], "name": "pendulum"}})
    with pytest.raises(DE, match="needs outputs"):
        scenario_run({**sc, "plant": {"model": str(IDP)}})
    with pytest.raises(DE, match="plant.outputs must be a non-empty list of strings"):
        scenario_run({**sc, "plant": {**sc["plant"], "outputs": "hinge"}})


def test_mjcf_plant_steps_as_mujoco_does():
    plant = make_plant(IDP, outputs=["slider", "hinge", "hinge2"])
    assert plant.dt == pytest.approx(0.01)
    m = mujoco.MjModel.from_xml_path(str(IDP))
    d = mujoco.MjData(m)
    x0 = np.array([0.1, 0.2, -0.1, 0.0, 0.3, 0.0])
    d.qpos[:], d.qvel[:] = x0[:3], x0[3:]
    plant.reset(x0)
    for _ in range(20):
        d.ctrl[:] = 0.3
        mujoco.mj_step(m, d)
        plant.step(np.array([0.3]))
    np.testing.assert_array_equal(plant.state, np.concatenate((d.qpos, d.qvel)))


def test_dynamics_batch_equals_dynamics_row_by_row_and_feeds_the_ekf():
    """dynamics_batch (MuJoCo's batch) gives dynamics' bits row by row on an unconstrained
    model, and the System EKF over an MJCF system, which takes it, gives the same estimates as
    the EKF over the same system with dynamics_batch hidden (one Python call per row)."""
    plant = make_plant(IDP, 0.01, outputs=["slider", "hinge", "hinge2"])
    s = plant.system
    rng = np.random.default_rng(5)
    X, U = rng.uniform(-0.5, 0.5, (7, 6)), rng.uniform(-1, 1, (7, 1))
    rows = np.array([s.dynamics(0.0, x, u) for x, u in zip(X, U)])
    assert np.array_equal(s.dynamics_batch(X, U), rows)
    assert np.array_equal(s.dynamics_batch(X[:3], U[:3]), rows[:3])  # a second batch size

    class PerRow(type(s)):  # the same system without the batched form
        dynamics_batch = None

    Y = rng.normal(0.0, 1e-3, (40, 3))
    Uk = rng.uniform(-1, 1, (40, 1))
    out = []
    for system in (s, PerRow()):
        ekf = make_observer("ekf", system, Q=np.eye(6), R=1e-4 * np.eye(3))
        assert (ekf.model._rows is None) == (system is not s)
        out.append(np.array([ekf.update(y, u, 0.01).copy() for y, u in zip(Y, Uk)]))
    assert np.array_equal(out[0], out[1])


def test_batched_model_term_equals_the_single_members():
    """chain_phi_batch (MuJoCo's batch, one mj_forward per row) gives chain_phi's bits, and a
    batch of high-gain observers with the MJCF model term (simulate_batch) equals the single
    runs bit for bit."""
    plant = make_plant(IDP, 0.01, outputs=["slider", "hinge", "hinge2"])
    s = plant.system
    rng = np.random.default_rng(4)
    Z, U = rng.uniform(-0.5, 0.5, (5, 6)), rng.uniform(-1, 1, (5, 1))
    rows = np.array([s.chain_phi(z, u) for z, u in zip(Z, U)])
    assert np.array_equal(s.chain_phi_batch(Z, U), rows)
    from hgo_mj.sensors import GaussianNoise
    from hgo_mj.simulate import simulate_batch

    sensor = SensorChain([GaussianNoise(std=1e-3)])
    u = signal_from_spec({"type": "multisine", "amplitudes": [0.2], "frequencies": [0.5]}, 1)
    obs = {"hgo": make_observer("high_gain_multi", s, k=30.0, model=True)}
    x0 = [0.0, 0.05, -0.05, 0.0, 0.0, 0.0]
    many = simulate_batch(plant, sensor, obs, u, 0.3, seeds=[1, 2, 3], x0=x0)
    for seed, tr in zip([1, 2, 3], many):
        one = simulate(plant, sensor, obs, u, 0.3, seed=seed, x0=x0)
        assert np.array_equal(one.estimate("hgo"), tr.estimate("hgo"))
