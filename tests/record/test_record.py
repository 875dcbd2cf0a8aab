"""Rerun recordings: written headless, read back with rerun's own reader and command line.

The reader is ``rerun.chunk.RrdReader`` (rerun-sdk 0.41's Python reader of ``.rrd`` files: it
streams the file's chunks as Arrow record batches), and ``rerun rrd verify`` / ``rerun rrd
stats`` from the same package's command line.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import mujoco
import numpy as np
import pytest
import rerun as rr
from rrd_reader import blueprint_view_names, blueprint_views, chunk_ids, read_rrd

from hgo_mj.cli import RRD_CHUNK_SECONDS, main
from hgo_mj.exceptions import DesignError, DimensionError
from hgo_mj.inputs import make_signal
from hgo_mj.observers import make_observer
from hgo_mj.plants import make_plant, model_path
from hgo_mj.record import Poses, Recorder, diagnostic_path, read, record_trajectory
from hgo_mj.sensors import SensorChain
from hgo_mj.simulate import Trajectory, simulate

RERUN = Path(sys.executable).parent / "rerun"


def rerun_cli(*args: str) -> subprocess.CompletedProcess:
    """The ``rerun`` command beside this interpreter, else ``python -m rerun`` (the same)."""
    cmd = [str(RERUN)] if RERUN.is_file() else [sys.executable, "-m", "rerun"]
    return subprocess.run([*cmd, *args], capture_output=True, text=True, timeout=60)


# ----------------------------------------------------------------------------- fixtures
def pendulum_run(duration: float = 2.0, *, on_chunk=None, seed: int = 3) -> Trajectory:
    plant = make_plant("pendulum", 0.001)
    sensor = SensorChain.from_spec([{"stage": "gaussian", "std": 1e-3},
                                    {"stage": "dropout", "p": 0.01}], seed=seed)
    obs = {"slow": make_observer("high_gain", plant.system, k=15.0),
           "fast": make_observer("high_gain", plant.system, k=60.0)}
    inputs = make_signal("multisine", amplitudes=[0.3], frequencies=[0.5])
    return simulate(plant, sensor, obs, inputs, duration, x0=[0.5, 0.0], seed=seed,
                    on_chunk=on_chunk, metadata={"scenario": "test_pendulum"})


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A pendulum run recorded chunk by chunk during the run, and its trajectory."""
    path = tmp_path_factory.mktemp("rec") / "pend.rrd"
    plant_names = make_plant("pendulum", 0.001)
    rec = Recorder.for_plant(path, plant_names, ["slow", "fast"], recording_name="test_pendulum")
    traj = pendulum_run(on_chunk=(0.5, rec.write_chunk))
    rec.log_metadata(traj.metadata)
    from hgo_mj.metrics import all_metrics

    rec.log_metrics(all_metrics(traj))
    rec.close()
    entities, blueprints = read_rrd(path)
    return path, traj, entities, blueprints


# ----------------------------------------------------------------------------- contents
def test_entities_and_blueprint(recorded):
    path, traj, ents, blueprints = recorded
    for name in ("/state/angle", "/state/angular_velocity", "/error/angle",
                 "/error/angular_velocity", "/sensor/angle", "/input/torque", "/observer/slow/gain",
                 "/observer/fast/gain",
                 "/observer/slow/diagnostics/dropouts", "/world/true/pole",
                 "/world/true/pole/rod", "/world/true/pole/bob", "/world/true/world/mount",
                 "/world/estimate/slow/pole", "/world/estimate/fast/pole/bob", "/scenario",
                 "/metrics"):
        assert name in ents, f"{name} missing; found {sorted(ents)}"
    assert blueprints == 1
    views = blueprint_views(path)
    for view in [("3D", "/world"), ("TimeSeries", "/input"), ("TimeSeries", "/sensor"),
                 ("TextDocument", "/metrics"), ("TextDocument", "/scenario")] + [
            (kind, f"/{root}/{s}") for s in traj.state_names for kind, root in
            (("TimeSeries", "state"), ("TimeSeries", "error"))]:
        assert view in views, f"{view} missing; found {views}"
    names = set(blueprint_view_names(path))
    assert {"angle [rad]: true vs estimated", "angular_velocity [rad/s]: error x - x_hat",
            "inputs: torque [N m]", "outputs, clean and measured: angle [rad]"} <= names
    # styles logged once as static: one entity per state, each series named with its unit,
    # one colour per observer, the truth in a fixed colour; the errors in the observers' colours
    style = ents["/state/angle"].static
    assert style["SeriesLines:names"] == ["angle true [rad]", "angle slow [rad]",
                                          "angle fast [rad]"]
    assert len(set(style["SeriesLines:colors"])) == 3
    assert (ents["/error/angle"].static["SeriesLines:colors"]
            == style["SeriesLines:colors"][1:])
    assert ents["/error/angular_velocity"].static["SeriesLines:names"] == [
        "angular_velocity error slow [rad/s]", "angular_velocity error fast [rad/s]"]
    assert ents["/sensor/angle"].static["SeriesLines:names"] == ["angle clean [rad]",
                                                                 "angle measured [rad]"]
    # geometry: solid truth, translucent ghosts (alpha in the low byte of the packed RGBA)
    assert "Cylinders3D:radii" in ents["/world/true/pole/rod"].static
    ghost = ents["/world/estimate/slow/pole/rod"].static["Cylinders3D:colors"][0]
    assert 0 < ghost & 0xFF < 255
    assert "/world/estimate/slow/world" not in " ".join(ents)  # fixed parts have no ghost
    # metadata and metrics as text documents
    scenario = ents["/scenario"].static["TextDocument:text"][0]
    assert "test_pendulum" in scenario and "mujoco" in scenario and '"k": 60.0' in scenario
    metrics = ents["/metrics"].static["TextDocument:text"][0]
    assert "rmse" in metrics and "slow" in metrics and "fast" in metrics


def test_rows_and_values_equal_the_trajectory(recorded):
    _, traj, ents, _ = recorded
    T = len(traj)
    assert T == 2001
    df = read(recorded[0])
    np.testing.assert_allclose(df["sim_time"], traj.t, atol=1e-9)
    for s, name in enumerate(traj.state_names):
        e = ents[f"/state/{name}"]
        assert e.rows == T
        np.testing.assert_array_equal(e["step"], np.arange(T))
        np.testing.assert_array_equal(e.scalars(f"{name} true"), traj.x[:, s])
        np.testing.assert_array_equal(df[f"/state/{name}[{name} true]"], traj.x[:, s])
        for ob in ("slow", "fast"):  # one column per observer and state
            np.testing.assert_array_equal(df[f"/state/{name}[{name} {ob}]"],
                                          traj.observers[ob].x_hat[:, s])
            np.testing.assert_array_equal(df[f"/error/{name}[{name} error {ob}]"],
                                          traj.error(ob)[:, s])
    np.testing.assert_array_equal(df["/sensor/angle[angle clean]"], traj.y_clean[:, 0])
    np.testing.assert_array_equal(df["/sensor/angle[angle measured]"], traj.y_meas[:, 0])
    assert np.isnan(traj.y_meas[:, 0]).any()  # dropouts are recorded as NaN
    np.testing.assert_array_equal(df["/input/torque"], traj.u[:, 0])


def test_diagnostics_logged_where_they_change(recorded):
    _, traj, ents, _ = recorded
    gain = ents["/observer/fast/gain"]
    assert np.all(gain["Scalars:scalars"] == 60.0)
    assert gain.rows < 10 and gain["step"][-1] == len(traj) - 1
    drops = ents["/observer/slow/diagnostics/dropouts"]
    d = traj.observers["slow"].diagnostics["dropouts"]
    changes = np.flatnonzero(np.diff(d)) + 1
    assert set(changes) <= set(drops["step"].tolist())
    np.testing.assert_array_equal(drops["Scalars:scalars"][:, 0], d[drops["step"]])


def test_poses_follow_mj_kinematics(recorded):
    _, traj, ents, _ = recorded
    plant = make_plant("pendulum", 0.001)
    m, d = plant.model, mujoco.MjData(plant.model)
    pole = ents["/world/true/pole"]
    steps = pole["step"]
    assert 0 < pole.rows < len(traj) and steps[0] == 0 and steps[-1] == len(traj) - 1
    bob = m.body("pole").id
    for k in steps[:: max(len(steps) // 7, 1)]:
        for root, q in (("/world/true/pole", traj.x[k, 0]),
                        ("/world/estimate/fast/pole", traj.observers["fast"].x_hat[k, 0])):
            row = int(np.flatnonzero(ents[root]["step"] == k)[0])
            d.qpos[0] = q
            mujoco.mj_kinematics(m, d)
            quat = ents[root]["Transform3D:quaternion"][row]  # x, y, z, w
            np.testing.assert_allclose(ents[root]["Transform3D:translation"][row], d.xpos[bob],
                                       atol=1e-6)
            np.testing.assert_allclose(np.abs(np.dot(quat, np.roll(d.xquat[bob], -1))), 1.0,
                                       atol=1e-6)


def test_rerun_command_line_reads_it(recorded):
    path = recorded[0]
    res = rerun_cli("rrd", "verify", str(path))
    assert res.returncode == 0, res.stderr
    stats = rerun_cli("rrd", "stats", str(path))
    assert stats.returncode == 0, stats.stderr
    for word in ("/state/angle", "/world/estimate/fast/pole", "sim_time", "step",
                 "Transform3D:quaternion", "ViewBlueprint:class_identifier"):
        assert word in stats.stdout


def test_global_recording_is_untouched(tmp_path):
    assert rr.get_global_data_recording() is None
    record_trajectory(pendulum_run(0.2), tmp_path / "a.rrd")
    assert rr.get_global_data_recording() is None
    assert rr.get_thread_local_data_recording() is None


def test_post_run_recording_equals_live_one(recorded, tmp_path):
    _, traj, live, _ = recorded
    path = record_trajectory(traj, tmp_path / "post.rrd")
    post, blueprints = read_rrd(path)
    assert blueprints == 1
    for name in ("/state/angle", "/error/angle", "/sensor/angle"):
        np.testing.assert_array_equal(post[name]["Scalars:scalars"], live[name]["Scalars:scalars"])
    # poses at 50 Hz (every 20th sample) and at the end of each block (the live one has 4)
    assert post["/world/true/pole"].rows == 2000 // 20 + 1
    assert set(post["/world/true/pole"]["step"]) < set(live["/world/true/pole"]["step"])
    # the same in blocks of 0.3 s
    with Recorder.for_trajectory(tmp_path / "blocks.rrd", traj) as rec:
        rec.record_trajectory(traj, chunk_seconds=0.3)
    blocks, _ = read_rrd(tmp_path / "blocks.rrd")
    for name, index in (("/state/angle", "step"), ("/error/angular_velocity", "sim_time"),
                        ("/observer/slow/diagnostics/dropouts", "step")):
        np.testing.assert_array_equal(blocks[name][index], post[name][index])
        np.testing.assert_array_equal(blocks[name]["Scalars:scalars"], post[name]["Scalars:scalars"])
    # the states carry step and sim_time, the other per-sample series sim_time alone
    # (read() gives them the states' step)
    assert "step" not in blocks["/error/angular_velocity"]._rows()
    np.testing.assert_array_equal(blocks["/error/angular_velocity"]["sim_time"],
                                  blocks["/state/angle"]["sim_time"])


def test_ode_plant_has_no_3d_view(tmp_path, chain):
    from hgo_mj.plants import OdePlant

    plant = OdePlant(chain(2)(), 0.01)
    obs = {"hgo": make_observer("high_gain", plant.system, k=5.0)}
    traj = simulate(plant, None, obs, make_signal("constant", value=[0.1]), 1.0, x0=[1.0, 0.0])
    ents, blueprints = read_rrd(record_trajectory(traj, tmp_path / "ode.rrd"))
    assert blueprints == 1
    assert not any(e.startswith("/world") for e in ents)
    assert ents[f"/state/{traj.state_names[0]}"].rows == len(traj)
    # no sensor chain, so no dropout stage: no dropout series
    assert not any(e.endswith("/dropouts") for e in ents), sorted(ents)


def test_record_episode_from_arrays(tmp_path):
    """The environments' entry point: whole episodes from numpy arrays, with an episode timeline."""
    plant = make_plant("elastic_joint", 0.002)
    path = tmp_path / "env.rrd"
    rng = np.random.default_rng(0)
    lengths = (50, 30)
    with Recorder.for_plant(path, plant, ["hgo"]) as rec:
        for ep, T in enumerate(lengths):
            t = np.arange(T) * 0.002
            x = rng.normal(size=(T, 4))
            rec.record_episode(ep, t, x, x[:, :1] + 0.01, rng.normal(size=(T, 1)),
                               y_clean=x[:, :1], estimates={"hgo": x + 0.1},
                               diagnostics={"hgo": {"k": np.full(T, 30.0),
                                                    "theta_link_inertia": np.linspace(0, 1, T)}},
                               extra={"reward": -np.abs(x[:, 0])})
    ents, _ = read_rrd(path)
    e = ents["/state/link_angle"]
    assert e.rows == sum(lengths)
    np.testing.assert_array_equal(e["episode"], np.repeat([0, 1], lengths))
    np.testing.assert_array_equal(e["step"], np.arange(sum(lengths)))
    assert np.all(np.diff(e["sim_time"]) > 0)  # episodes follow each other
    np.testing.assert_allclose(ents["/error/link_angle"].scalars("link_angle error hgo"), -0.1)
    assert ents["/env/reward"].rows == sum(lengths)
    # a parameter estimate goes next to the true parameter
    theta = ents["/observer/hgo/theta/link_inertia"]
    assert theta.rows == sum(lengths)
    true = ents["/plant/param/link_inertia"]["Scalars:scalars"]
    np.testing.assert_allclose(true, plant.system.params["link_inertia"])
    for body in ("link", "rotor"):
        assert f"/world/estimate/hgo/{body}" in ents


def test_episode_without_estimates(tmp_path):
    """An environment whose observer gives no full-state estimate passes ``estimates=None``."""
    plant = make_plant("pendulum", 0.001)
    path = tmp_path / "noest.rrd"
    with Recorder.for_plant(path, plant, ["hgo"]) as rec:
        x = np.ones((4, 2))
        rec.record_episode(0, np.arange(4) * 1e-3, x, x[:, :1], np.zeros((4, 1)))
        rec.record_episode(1, np.arange(4) * 1e-3, x, x[:, :1], np.zeros((4, 1)),
                           estimates={"hgo": 2 * x})
    ents, _ = read_rrd(path)
    df = read(path)
    est, true = df["/state/angle[angle hgo]"].to_numpy(), df["/state/angle[angle true]"].to_numpy()
    assert np.isnan(est[:4]).all() and np.all(est[4:] == 2.0) and np.all(true == 1.0)
    assert ents["/world/estimate/hgo/pole"].rows < ents["/world/true/pole"].rows


@pytest.mark.parametrize("key, path", [
    ("k", "/observer/o/gain"),
    ("gamma", "/observer/o/gain"),
    ("k_fast", "/observer/o/gain/fast"),
    ("theta_hat_a1", "/observer/o/theta/a1"),
    ("theta_mu_max", "/observer/o/theta/mu_max"),
    ("a2", "/observer/o/theta/a2"),
    ("theta", "/observer/o/theta/theta"),
    ("dropouts", "/observer/o/diagnostics/dropouts"),
    ("excitation", "/observer/o/diagnostics/excitation"),
])
def test_diagnostic_paths(key, path):
    assert diagnostic_path("o", key, ("a1", "a2"))[0] == path


def _mj_poses(m, joints, q):
    """MuJoCo's own body poses: the joint positions ``q`` set into qpos (the rest at qpos0)."""
    d = mujoco.MjData(m)
    d.qpos[:] = m.qpos0
    for c, j in enumerate(joints):
        d.qpos[m.jnt_qposadr[m.joint(j).id]] = q[c]
    mujoco.mj_kinematics(m, d)
    return d.xpos.copy(), d.xquat.copy()


def test_poses_match_mj_kinematics():
    """Slide and hinge joints with anchors (and springrefs: ``qpos0`` not 0) on nested
    bodies, a ball joint at ``qpos0`` on a moving body, a free body beside them; all driven
    or some only: the rows posed together equal MuJoCo's poses of each row alone (to
    rounding), and ``moving`` marks the bodies the driven joints move."""
    xml = """<mujoco><worldbody>
      <geom name="floor" type="plane" size="1 1 .1"/>
      <body name="free" pos="1 0 1" euler="0.1 0.2 0.3"><joint type="free"/>
        <geom size=".1"/></body>
      <body name="a" pos="0.1 0.2 0.3" euler="0.3 0.2 0.1">
        <joint name="s" type="slide" axis="1 1 0" ref="0.2"/>
        <joint name="h1" type="hinge" axis="0 0 1" pos="0.05 0 0" ref="30"/>
        <geom type="box" size=".1 .1 .1"/>
        <body name="b" pos="0 0 -0.4" quat="0.9 0.1 0.3 0.2">
          <joint name="h2" type="hinge" axis="0.3 1 0" pos="0 0.1 0.2"/>
          <joint name="h3" type="hinge" axis="1 0 0"/>
          <joint name="ball" type="ball" pos="0.1 0 0"/>
          <geom type="capsule" size=".02 .2"/>
        </body>
      </body></worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    rng = np.random.default_rng(1)
    for joints, moving in ((("s", "h1", "h2", "h3"), [False, False, True, True]),
                           (("h3", "s"), [False, False, True, True]),
                           (("h2",), [False, False, False, True])):
        poses = Poses(m, joints)
        assert poses.moving.tolist() == moving
        q = rng.uniform(-2, 2, size=(6, len(joints)))
        pos, quat = poses.poses(q)
        assert pos.shape == (6, m.nbody, 3) and quat.shape == (6, m.nbody, 4)
        for k in range(6):
            xpos, xquat = _mj_poses(m, joints, q[k])
            np.testing.assert_allclose(pos[k], xpos, rtol=0, atol=1e-14)
            np.testing.assert_allclose(quat[k], xquat, rtol=0, atol=1e-14)
    with pytest.raises(DesignError, match="joint 'free' must be a hinge or slide joint"):
        Poses(mujoco.MjModel.from_xml_string(
            '<mujoco><worldbody><body><joint name="free" type="free"/><geom size=".1"/>'
            '</body></worldbody></mujoco>'), ("free",))


@pytest.mark.parametrize("model", ["pendulum.xml", "elastic_joint.xml", "elastic_joint_2link.xml",
                                   "cart_pendulum.xml"])
def test_poses_of_shipped_models(model):
    """Every shipped model posed at random joint positions of its system: MuJoCo's xpos and
    xquat, every body; the geometry drawn is the bodies' visible geoms."""
    from hgo_mj.systems import SYSTEMS

    joints = next(c.joints for c in SYSTEMS.values() if c.model_file == model)
    m = mujoco.MjModel.from_xml_path(str(model_path(model)))
    q = np.random.default_rng(2).uniform(-3, 3, size=(5, len(joints)))
    poses = Poses(m, joints)
    pos, quat = poses.poses(q)
    for k in range(5):
        xpos, xquat = _mj_poses(m, joints, q[k])
        np.testing.assert_allclose(pos[k], xpos, atol=1e-12)
        np.testing.assert_allclose(quat[k], xquat, atol=1e-12)
    assert poses.moving[1:].any() and not poses.moving[0]
    assert set(poses.posed_bodies()) <= set(np.flatnonzero(poses.moving))
    true = dict(poses.geometry())
    ghost = dict(poses.geometry("/world/estimate/o", (1, 2, 3)))
    assert len(true) >= len(ghost) > 0
    assert all(p.startswith("/world/estimate/o/") for p in ghost)


def test_scenario_metadata_is_strict_json(tmp_path):
    """A non-finite value in the metadata is written as null: the /scenario document's JSON
    block parses with a strict parser."""
    import json

    path = tmp_path / "md.rrd"
    with Recorder.for_plant(path, make_plant("pendulum", 0.001)) as rec:
        rec.log_metadata({"scenario": "nan", "x0": [float("nan"), 0.0],
                          "observers": {"a": {"k": float("inf"), "p": Path("p")}}})
    text = read_rrd(path)[0]["/scenario"].static["TextDocument:text"][0]
    block = text.split("```json\n")[1].split("\n```")[0]
    md = json.loads(block, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))
    assert md["x0"] == [None, 0.0] and md["observers"]["a"] == {"k": None, "p": "p"}


# ----------------------------------------------------------------------------- layout (pure)
def _views(container):
    """(class, origin, name, contents) of every view below a blueprint container, in order."""
    import rerun.blueprint as rrb

    out = []
    for item in container.contents:
        if isinstance(item, rrb.Container):
            out += _views(item)
        else:
            out.append((item.class_identifier, str(item.origin), item.name, item.contents))
    return out


def _style(archetype):
    return {name: getattr(archetype, name).as_arrow_array().to_pylist()
            for name in ("names", "colors", "widths", "interpolation_mode")
            if getattr(archetype, name) is not None}


def test_layout_matches_estimates_by_name():
    from hgo_mj.record import layout

    lay = layout.estimate_layout(("angle", "rate", "motor"), ("a", "b"),
                                 {"a": ("angle", "rate", "motor"), "b": ("rate", "y_d2", "angle")})
    assert lay.est_of == ((("a", 0), ("b", 2)), (("a", 1), ("b", 0)), (("a", 2),))
    assert lay.own == {"a": (), "b": (("y_d2", 1),)}
    assert lay.joint_observers(1) == {"a", "b"} and lay.joint_columns("b", 2) == [2, 0]
    assert layout.default_names(("p", "v"), 2) == ("p", "v")
    assert layout.default_names(("p", "v"), 3) == ("x_hat_1", "x_hat_2", "x_hat_3")
    with pytest.raises(DesignError, match="must be distinct and not empty"):
        layout.check_names("a", ["x", "x"])
    units = {"angle": "rad", "rate": "rad/s", "torque": "N m", "motor": ""}
    styles = dict(layout.signal_styles(lay, ("angle",), ("torque",), units))
    assert list(styles) == [
        "/state/angle", "/error/angle", "/state/rate", "/error/rate", "/state/motor",
        "/error/motor", "/observer/b/estimate/y_d2", "/sensor/angle", "/input/torque"]
    angle = _style(styles["/state/angle"])  # the truth, then the observers estimating it
    assert angle["names"] == ["angle true [rad]", "angle a [rad]", "angle b [rad]"]
    assert angle["widths"] == [2, 1, 1] and len(set(angle["colors"])) == 3
    assert _style(styles["/state/motor"])["names"] == ["motor true [-]", "motor a [-]"]
    assert _style(styles["/error/motor"])["names"] == ["motor error a [-]"]  # dimensionless
    assert _style(styles["/error/angle"])["colors"] == angle["colors"][1:]
    assert _style(styles["/sensor/angle"])["names"] == ["angle clean [rad]",
                                                        "angle measured [rad]"]
    assert _style(styles["/observer/b/estimate/y_d2"])["names"] == ["y_d2 b"]  # unit unknown
    assert _style(styles["/input/torque"])["names"] == ["torque [N m]"]
    assert layout.has_dropout_stage([{"stage": "gaussian"}, {"stage": "dropout", "p": 0.1}])
    assert not layout.has_dropout_stage([{"stage": "gaussian"}]) and not layout.has_dropout_stage(None)
    # a parameter estimate gets the true value next to it, both drawn as steps
    theta = dict(layout.diagnostic_styles("b", 1, "theta_hat_mass", {"mass": 1.0}))
    assert list(theta) == ["/observer/b/theta/mass", "/plant/param/mass"]
    assert _style(theta["/plant/param/mass"])["names"] == ["mass true"]
    assert all(_style(a)["interpolation_mode"] == [2] for a in theta.values())  # StepAfter
    assert layout.part("a/b c") == r"a\/b\ c"  # one path part


def test_blueprint_is_a_pure_function_of_the_layout():
    from hgo_mj.record import layout

    lay = layout.estimate_layout(("angle", "rate"), ("a", "z"),
                                 {"a": ("angle", "rate"), "z": ("z1", "z2")})
    diags = [layout.diagnostic_path("a", k, ("mass",)) for k in ("k", "mass", "dropouts")]
    bp = layout.blueprint(lay, diags, {"mass": 1.0}, extras=True, world=True,
                          units={"angle": "rad", "torque": "N m"}, output_names=("angle",),
                          input_names=("torque",))
    views = _views(bp.root_container)
    kinds = [(v[0], v[1]) for v in views]
    for view in [("3D", "/world"), ("TextDocument", "/metrics"), ("TextDocument", "/scenario"),
                 ("TimeSeries", "/state/angle"), ("TimeSeries", "/state/rate"),
                 ("TimeSeries", "/error/angle"), ("TimeSeries", "/observer/z/estimate"),
                 ("TimeSeries", "/input"), ("TimeSeries", "/sensor"), ("TimeSeries", "/env")]:
        assert view in kinds, (view, kinds)
    by_name = {v[2]: v for v in views}
    assert {"angle [rad]: true vs estimated", "rate: true vs estimated",
            "angle [rad]: error x - x_hat", "inputs: torque [N m]",
            "outputs, clean and measured: angle [rad]"} <= set(by_name)
    assert [str(c) for c in by_name["mass: true vs estimated"][3]] == [
        "/plant/param/mass", "/observer/a/theta/mass"]
    assert [str(c) for c in by_name["gains"][3]] == ["/observer/a/gain"]
    assert [str(c) for c in by_name["other diagnostics"][3]] == ["/observer/a/diagnostics/dropouts"]
    assert bp.time_panel is not None
    # no 3D view for an ODE plant, no error column when no plant state is estimated
    lay = layout.estimate_layout(("x1",), ("z",), {"z": ("z1",)})
    kinds = [(v[0], v[1]) for v in _views(layout.blueprint(lay).root_container)]
    assert ("3D", "/world") not in kinds and not any(o.startswith("/error") for _, o in kinds)
    assert ("TimeSeries", "/env") not in kinds


def test_documents_are_markdown_with_strict_json():
    import json

    from hgo_mj.record import documents

    md = {"scenario": "s", "plant": "Pendulum", "seed": 3, "x0": [float("nan"), 0.0],
          "observers": {"a": {"k": 2.0}}, "versions": {"mujoco": "4"}}
    text = documents.scenario_document(md)
    assert text.startswith("# s\n") and "- **seed**: `3`" in text and "- mujoco 4" in text
    assert json.loads(text.split("```json\n")[1].split("\n```")[0])["x0"] == [None, 0.0]
    assert documents.scenario_properties(md) == {
        "scenario": "s", "plant": "Pendulum", "seed": "3", "observers": '{"a": {"k": 2.0}}',
        "versions": '{"mujoco": "4"}'}
    eps = [{"episode": 0, "seed": 1, "steps": 10, "return": -1.5, "terminated": False,
            "rmse": {"angle": 0.25}}, {"episode": 1, "seed": None, "rmse": {"rate": float("inf")}}]
    text = documents.episode_metrics_document(eps)
    assert "| episode | seed | steps | return | terminated | rmse angle | rmse rate |" in text
    assert "| 0 | 1 | 10 | -1.5 | False | 0.25 | - |" in text
    assert json.loads(text.split("```json\n")[1].split("\n```")[0])[1]["rmse"] == {"rate": None}


# ----------------------------------------------------------------------------- errors
def test_validation_errors(tmp_path):
    plant = make_plant("pendulum", 0.001)
    with pytest.raises(DesignError, match=r"must end in \.rrd; found '.*x\.txt'"):
        Recorder.for_plant(tmp_path / "x.txt", plant)
    with pytest.raises(DesignError, match="give a path"):
        Recorder(None, state_names=["a"], output_names=["y"], input_names=["u"])
    with pytest.raises(DesignError, match="no joint named 'nope'"):
        Recorder.for_plant(tmp_path / "x.rrd", plant, joints=("nope",))
    with pytest.raises(DesignError, match="an observer cannot be named 'true' in a recording"):
        Recorder.for_plant(tmp_path / "x.rrd", plant, ["hgo", "true"])
    with pytest.raises(DesignError, match="stream must be a rerun.RecordingStream; found str"):
        Recorder(None, state_names=["a"], output_names=["y"], input_names=["u"], stream="s")
    with Recorder.for_plant(tmp_path / "y.rrd", plant, ["hgo"]) as rec:
        T = 5
        good = dict(t=np.arange(T) * 1e-3, x=np.zeros((T, 2)), y_clean=np.zeros((T, 1)),
                    y_meas=np.zeros((T, 1)), u=np.zeros((T, 1)))
        with pytest.raises(DimensionError, match=r"x must have shape \(5, 2\); found \(5, 3\)"):
            rec.record(**{**good, "x": np.zeros((T, 3))}, estimates={"hgo": np.zeros((T, 2))})
        with pytest.raises(DesignError, match=r"estimates of unknown observer\(s\) \['other'\]; "
                                              r"observers: \['hgo'\]"):
            rec.record(**good, estimates={"other": np.zeros((T, 2))})
        with pytest.raises(DimensionError, match="diagnostic 'k' of 'hgo' must have 5 rows; found 4"):
            rec.record(**good, estimates={"hgo": np.zeros((T, 2))},
                       diagnostics={"hgo": {"k": np.zeros(4)}})
        with pytest.raises(DimensionError, match=r"extra 'reward' must have shape \(5,\) or \(5, k\); "
                                                 r"found \(6,\)"):
            rec.record(**good, extra={"reward": np.zeros(6)})
    assert read_rrd(tmp_path / "y.rrd")[0].get("/state/angle") is None  # nothing half-written


def test_sigint_waits_for_the_block():
    """Ctrl-C while a block is sent is held until the block is complete, then raised."""
    import os

    from hgo_mj.record.recorder import _DeferSigint

    done = []
    # Python's own Ctrl-C handler, whatever a library imported earlier installed (the block
    # defers only that one); the signal may reach another thread first: wait until it is seen
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            with _DeferSigint() as block:
                os.kill(os.getpid(), signal.SIGINT)
                end = time.monotonic() + 5.0
                while not block._hit and time.monotonic() < end:
                    time.sleep(0.001)
                done.append(True)
        assert done == [True]
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, before)


def test_simulate_on_chunk_validation():
    plant = make_plant("pendulum", 0.001)
    with pytest.raises(DesignError, match=r"on_chunk must be a tuple \(seconds, callback\)"):
        simulate(plant, None, None, make_signal("constant", value=[0.0]), 0.1, on_chunk=print)
    with pytest.raises(DesignError, match="on_chunk seconds must be > 0"):
        simulate(plant, None, None, make_signal("constant", value=[0.0]), 0.1,
                 on_chunk=(0.0, print))


def test_simulate_chunks_cover_the_run_and_change_nothing():
    seen: list[tuple[int, Trajectory]] = []
    whole = pendulum_run(1.0, on_chunk=(0.3, lambda k, c: seen.append((k, c))))
    plain = pendulum_run(1.0)
    np.testing.assert_array_equal(whole.x, plain.x)
    # the tail of 101 rows (less than half a chunk) joins the last chunk
    assert [k for k, _ in seen] == [0, 300, 600]
    assert [len(c) for _, c in seen] == [300, 300, 401]
    np.testing.assert_array_equal(np.concatenate([c.x for _, c in seen]), whole.x)
    np.testing.assert_array_equal(
        np.concatenate([c.observers["fast"].diagnostics["k"] for _, c in seen]),
        whole.observers["fast"].diagnostics["k"])
    np.testing.assert_array_equal(np.concatenate([c.t for _, c in seen]), whole.t)


# ----------------------------------------------------------------------------- command line
RUN = ["run", "--plant", "pendulum", "--observer", "high_gain:name=slow,k=15",
       "--observer", "high_gain:name=fast,k=60", "--sensor", "gaussian:std=1e-3",
       "--input", "multisine:amplitudes=[0.2],frequencies=[0.5]", "--seed", "4"]


def test_cli_run_rrd(tmp_path, capsys):
    path = tmp_path / "r.rrd"
    assert main([*RUN, "--duration", "1.5", "--out", str(tmp_path / "o"), "--rrd", str(path)]) == 0
    assert str(path) in capsys.readouterr().out
    traj = Trajectory.load(tmp_path / "o" / "trajectory.npz")
    df = read(path)
    assert len(df) == len(traj) == 1501 and read_rrd(path)[1] == 1  # one blueprint
    np.testing.assert_array_equal(df["/state/angle[angle true]"], traj.x[:, 0])
    np.testing.assert_array_equal(df["/state/angle[angle slow]"],
                                  traj.observers["slow"].x_hat[:, 0])
    assert df.attrs["units"]["/state/angular_velocity[angular_velocity fast]"] == "rad/s"
    # no dropout stage in the sensor chain: no dropout series
    assert not any(c.endswith("/dropouts") for c in df.columns), list(df.columns)
    assert "rmse" in df.attrs["static"]["/metrics"]["TextDocument:text"][0]
    assert '"seed": 4' in df.attrs["static"]["/scenario"]["TextDocument:text"][0]


def test_cli_reproduce_rrd_contract(tmp_path, capsys, monkeypatch):
    import types

    from hgo_mj import reproduce

    seen = {}

    def run(out, *, rrd=None):
        seen["rrd"] = rrd
        return {"ok": 1}

    def old_run(out):
        return {"ok": 1}

    for name, fn in (("fake_rec", run), ("fake_old", old_run)):
        monkeypatch.setitem(sys.modules, f"hgo_mj.reproduce.{name}",
                            types.SimpleNamespace(run=fn))
        monkeypatch.setitem(reproduce.REPRODUCTIONS, name, (f"hgo_mj.reproduce.{name}", "fake"))
    assert main(["reproduce", "fake_rec", "--out", str(tmp_path)]) == 0
    assert seen["rrd"] is None
    assert main(["reproduce", "fake_rec", "--out", str(tmp_path), "--rrd",
                 str(tmp_path / "f.rrd")]) == 0
    assert seen["rrd"] == tmp_path / "f.rrd"
    assert main(["reproduce", "fake_old", "--out", str(tmp_path), "--rrd", "x.rrd"]) == 2
    assert "cannot record: expected run(out, *, rrd=None)" in capsys.readouterr().err


def test_cli_sigint_leaves_a_readable_recording(tmp_path):
    """Ctrl-C during ``hgo-mj run --rrd``: exit 130 and a file holding every whole chunk, equal
    to the same run's first rows."""
    path = tmp_path / "cut.rrd"
    argv = [*RUN, "--duration", "600", "--out", str(tmp_path / "o")]  # ~6 s: time to interrupt
    proc = subprocess.Popen(
        [sys.executable, "-m", "hgo_mj.cli", *argv, "--rrd", str(path)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        # a shell's background job may have inherited an ignored SIGINT
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    t0 = time.monotonic()
    try:
        while time.monotonic() - t0 < 25 and proc.poll() is None:
            # the recording is written to a hidden temporary, renamed onto path at close
            if any(p.stat().st_size > 1_200_000 for p in tmp_path.glob(".cut.rrd.*.tmp")):
                break  # a few chunks
            time.sleep(0.05)
        proc.send_signal(signal.SIGINT)
        rc = proc.wait(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert rc == 130, proc.stderr.read()
    assert "holds the run up to its last chunk" in proc.stderr.read()
    assert rerun_cli("rrd", "verify", str(path)).returncode == 0
    ents, blueprints = read_rrd(path)
    rows = ents["/state/angle"].rows
    chunk = round(RRD_CHUNK_SECONDS / 1e-3)
    assert blueprints == 1 and rows >= chunk and rows % chunk == 0  # whole chunks
    for name in ("/state/angular_velocity", "/error/angle", "/sensor/angle", "/input/torque"):
        assert ents[name].rows == rows
    df = read(path)
    assert len(df) == rows and not df["/input/torque"].isna().any()
    # the same scenario, run to the recorded length, gives the recorded values
    assert main([*argv[:-4], "--duration", f"{(rows - 1) * 1e-3:.3f}",
                 "--out", str(tmp_path / "ref")]) == 0
    ref = Trajectory.load(tmp_path / "ref" / "trajectory.npz")
    np.testing.assert_array_equal(df["/state/angle[angle true]"], ref.x[:, 0])
    np.testing.assert_array_equal(df["/state/angle[angle fast]"],
                                  ref.observers["fast"].x_hat[:, 0])


# ----------------------------------------------------------------------------- estimate layout
def test_partial_estimate_is_recorded_by_name(tmp_path):
    """The model-free multi-output observer on the two-link arm: its link angles and velocities
    go next to the truth and get errors, its accelerations and jerks go under its own names,
    the motor states have the truth only and no error; the same live (``write_chunk``) and
    after the run (``record_trajectory``)."""
    from hgo_mj.observers import MultiOutputHighGainObserver

    plant = make_plant("elastic_joint_2link")
    obs = {"multi": MultiOutputHighGainObserver(plant.system, orders=(4, 4), k=120.0),
           "ekf": make_observer("ekf", plant.system)}
    s1, s2 = (make_signal("multisine", amplitudes=[0.5], frequencies=[0.5]),
              make_signal("multisine", amplitudes=[0.15], frequencies=[0.8]))
    live = tmp_path / "live.rrd"
    with Recorder.for_plant(live, plant, list(obs)) as rec:
        traj = simulate(plant, None, obs, lambda t: np.concatenate([s1(t), s2(t)]), 0.3,
                        on_chunk=(0.1, rec.write_chunk))
    post = record_trajectory(traj, tmp_path / "post.rrd")
    rec_multi = traj.observers["multi"]
    for path in (live, post):
        ents, _ = read_rrd(path)
        df = read(path)
        # a plant state both estimate: the truth, multi and ekf, errors of both
        s = "link1_velocity"
        i, j = traj.state_names.index(s), rec_multi.state_names.index(s)
        assert ents[f"/state/{s}"].static["SeriesLines:names"] == [
            f"{s} true [rad/s]", f"{s} multi [rad/s]", f"{s} ekf [rad/s]"]
        np.testing.assert_array_equal(df[f"/state/{s}[{s} multi]"], rec_multi.x_hat[:, j])
        np.testing.assert_array_equal(df[f"/error/{s}[{s} error multi]"],
                                      traj.error("multi")[:, i])
        # a motor state: the truth and the ekf only
        m = "motor1_angle"
        assert ents[f"/state/{m}"].series == [f"{m} true", f"{m} ekf"]
        assert ents[f"/error/{m}"].series == [f"{m} error ekf"]
        # what is not a plant state: under the observer's own names, not under /state, /error
        for extra in ("link1_acceleration", "link2_jerk"):
            np.testing.assert_array_equal(df[f"/observer/multi/estimate/{extra}"],
                                          rec_multi.x_hat[:, rec_multi.state_names.index(extra)])
            assert not any(e.startswith((f"/state/{extra}", f"/error/{extra}")) for e in ents)
        assert df.attrs["units"]["/observer/multi/estimate/link1_acceleration"] == "rad/s^2"
        assert not any(p.startswith("/observer/ekf/estimate") for p in ents)
        views = blueprint_views(path)
        assert ("TimeSeries", "/observer/multi/estimate") in views
        # the ghost of the multi-output observer: its link joints estimated, motors on the truth
        assert "/world/estimate/multi/link1" in " ".join(ents)


def test_an_observer_estimating_no_plant_state(tmp_path, chain):
    """An order-only observer on a plant whose states it does not name: its estimate goes
    under ``/observer/<obs>/estimate``, the plant's states have the truth only, no errors."""
    from hgo_mj.observers import HighGainObserver
    from hgo_mj.plants import OdePlant

    plant = OdePlant(chain(2)(), 0.01)
    obs = {"order": HighGainObserver(order=2, k=5.0)}
    traj = simulate(plant, None, obs, make_signal("constant", value=[0.1]), 0.5, x0=[1.0, 0.0])
    assert traj.observers["order"].state_names == ("z1", "z2")
    ents, _ = read_rrd(record_trajectory(traj, tmp_path / "o.rrd"))
    assert [e for e in ents if e.startswith("/state/x1")] == ["/state/x1"]
    assert ents["/state/x1"].series == ["x1 true"]
    assert not any(e.startswith("/error") for e in ents)
    np.testing.assert_array_equal(ents["/observer/order/estimate/z2"]["Scalars:scalars"][:, 0],
                                  traj.observers["order"].x_hat[:, 1])
    assert not any(v[1].startswith("/error") for v in blueprint_views(tmp_path / "o.rrd"))
    assert "not estimated" in ents["/metrics"].static["TextDocument:text"][0]


def test_record_estimate_names_validation(tmp_path):
    plant = make_plant("pendulum", 0.001)
    T = 4
    good = dict(t=np.arange(T) * 1e-3, x=np.zeros((T, 2)), y_clean=np.zeros((T, 1)),
                y_meas=np.zeros((T, 1)), u=np.zeros((T, 1)))
    with pytest.raises(DesignError, match="observer_states names an unknown observer 'x'"):
        Recorder.for_plant(tmp_path / "a.rrd", plant, ["hgo"], observer_states={"x": ["a"]})
    with Recorder.for_plant(tmp_path / "b.rrd", plant, ["hgo"],
                            observer_states={"hgo": ["angle", "y_d1", "theta"]}) as rec:
        with pytest.raises(DimensionError, match=r"estimate of 'hgo' must have shape \(4, 3\) "
                                                 r"\(columns \['angle', 'y_d1', 'theta'\]\)"):
            rec.record(**good, estimates={"hgo": np.zeros((T, 2))})
        rec.record(**good, estimates={"hgo": np.ones((T, 3))})
        with pytest.raises(DesignError, match="estimate_names of 'hgo' changed"):
            rec.record(**good, estimates={"hgo": np.ones((T, 3))},
                       estimate_names={"hgo": ["a", "b", "c"]})
    ents, _ = read_rrd(tmp_path / "b.rrd")
    assert ents["/state/angular_velocity"].series == ["angular_velocity true"]
    assert ents["/state/angle"].series == ["angle true", "angle hgo"]
    assert ents["/observer/hgo/estimate/theta"].rows == T


def test_recordings_in_one_process_reuse_converted_styles(tmp_path):
    """Styles and geometry are built once per process and logged again: a second recording
    holds the same static data, ghosts and views as the first, with poses sent in batches of
    queued rows (and the rest at close)."""
    traj = pendulum_run(1.2)
    paths = [tmp_path / f"r{i}.rrd" for i in range(2)]
    for p in paths:
        with Recorder.for_trajectory(p, traj) as rec:
            rec.record_trajectory(traj, chunk_seconds=0.3)
    (a, na), (b, nb) = read_rrd(paths[0]), read_rrd(paths[1])
    assert na == nb == 1 and sorted(blueprint_views(paths[0])) == sorted(blueprint_views(paths[1]))
    assert sorted(a) == sorted(b)
    for name in set(a) - {"/__properties"}:  # the properties hold the start time
        assert a[name].static.keys() == b[name].static.keys(), name
        for comp, value in a[name].static.items():
            if "TextDocument" not in comp:
                assert b[name].static[comp] == value, (name, comp)
    for ghost in ("/world/estimate/slow/pole", "/world/estimate/fast/pole", "/world/true/pole"):
        steps = b[ghost]["step"]
        assert steps[0] == 0 and steps[-1] == len(traj) - 1  # every block, the last row too
        assert np.all(np.diff(steps) > 0)
    assert b["/state/angle"].rows == len(traj)


def test_recordings_in_one_process_have_unique_chunk_ids(tmp_path):
    """Two recordings of the same run written in one process (styles, geometry, blueprint and
    rows alike) share no chunk id, and no file repeats one."""
    traj = pendulum_run(0.6)
    ids = []
    for name in ("a.rrd", "b.rrd"):
        with Recorder.for_trajectory(tmp_path / name, traj) as rec:
            rec.record_trajectory(traj, chunk_seconds=0.2)
        ids.append(chunk_ids(tmp_path / name))
    a, b = ids
    assert len(a) > 20 and len(set(a)) == len(a) and len(set(b)) == len(b)
    assert not set(a) & set(b)


@pytest.mark.filterwarnings("ignore:RRD file has no footer")
def test_footer_false_reads_as_a_stream(tmp_path):
    """``footer=False``: the same data, read as a stream; ``rerun rrd verify`` rejects it."""
    traj = pendulum_run(0.5)
    with Recorder.for_trajectory(tmp_path / "f.rrd", traj, footer=False) as rec:
        rec.record_trajectory(traj)
    with Recorder.for_trajectory(tmp_path / "t.rrd", traj) as rec:
        rec.record_trajectory(traj)
    nofoot, foot = read_rrd(tmp_path / "f.rrd"), read_rrd(tmp_path / "t.rrd")
    assert nofoot[1] == foot[1] == 1 and sorted(nofoot[0]) == sorted(foot[0])
    np.testing.assert_array_equal(nofoot[0]["/state/angle"]["Scalars:scalars"],
                                  foot[0]["/state/angle"]["Scalars:scalars"])
    assert (tmp_path / "f.rrd").stat().st_size < (tmp_path / "t.rrd").stat().st_size
    assert rerun_cli("rrd", "verify", str(tmp_path / "t.rrd")).returncode == 0
    out = rerun_cli("rrd", "verify", str(tmp_path / "f.rrd"))  # verify wants the manifest
    assert out.returncode != 0 and "Missing RRD footer" in out.stderr
