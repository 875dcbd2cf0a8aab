"""The one MuJoCo name binding (hgo_mj._binding.Binding): names to ids and addresses, one
error for an unknown name listing the known ones, and every module that reads MjData by name
going through it."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from hgo_mj._binding import KINDS, Binding
from hgo_mj.exceptions import DesignError, ModelError
from hgo_mj.observers import make_observer
from hgo_mj.plants import make_plant
from hgo_mj.plants.mujoco import MujocoPlant
from hgo_mj.record.poses import Poses
from hgo_mj.systems import Pendulum

XML = """<mujoco><worldbody>
  <body name="a"><joint name="slide" type="slide"/><geom name="ga" size=".1"/>
    <body name="b"><joint name="ball" type="ball"/><geom size=".1"/>
      <body name="c"><joint name="hinge"/><geom size=".1"/><site name="tip"/></body>
    </body>
  </body></worldbody>
  <actuator><motor name="push" joint="slide"/><motor name="turn" joint="hinge"/></actuator>
  <sensor><jointpos name="q" joint="hinge"/><framepos name="p" objtype="site" objname="tip"/>
    <jointvel name="v" joint="hinge"/></sensor></mujoco>"""


@pytest.fixture(scope="module")
def names():
    return Binding(mujoco.MjModel.from_xml_string(XML), "toy.xml")


def test_ids_and_addresses_are_mujocos(names):
    m = names.model
    assert names.id("joint", "hinge") == m.joint("hinge").id == 2
    assert names.ids("actuator", ["turn", "push"]).tolist() == [1, 0]
    # a ball joint before the hinge: qpos (4 wide) and qvel (3 wide) addresses differ
    assert names.qpos(["hinge", "slide", "ball"]).tolist() == [5, 0, 1]
    assert names.dofs(["hinge", "slide", "ball"]).tolist() == [4, 0, 1]
    assert names.qpos([]).dtype == np.intp and names.qpos([]).size == 0


def test_sensor_channels(names):
    assert names.sensor("q") == (0, 0) and names.sensordata("q") == 0
    assert names.sensor("p[2]") == (1, 2) and names.sensordata("p[2]") == 3
    assert names.sensordata("v") == 4
    with pytest.raises(ModelError, match=r"toy.xml has no sensor named 'p\[3\]'; its sensor names: "
                                         r"\['q', 'p', 'v'\]"):
        names.sensor("p[3]")


@pytest.mark.parametrize("kind,known", [("joint", ["slide", "ball", "hinge"]),
                                        ("actuator", ["push", "turn"]),
                                        ("body", ["world", "a", "b", "c"]), ("site", ["tip"]),
                                        ("geom", ["ga"]), ("tendon", [])])
def test_an_unknown_name_is_one_error_listing_the_known(names, kind, known):
    with pytest.raises(ModelError) as e:
        names.id(kind, "nope")
    assert str(e.value) == f"toy.xml has no {kind} named 'nope'; its {kind} names: {known}"
    assert isinstance(e.value, DesignError)


def test_bad_kind_and_model(names):
    with pytest.raises(DesignError, match=r"unknown element kind 'joints'; known: "
                                          + r"\['" + "', '".join(KINDS) + r"'\]"):
        names.id("joints", "hinge")
    with pytest.raises(DesignError, match="expected a mujoco.MjModel; found str"):
        Binding("toy.xml")


def test_every_reader_by_name_goes_through_it():
    """The plant, the MuJoCo filters' model, the MJCF systems and their errors: one binding."""
    plant = make_plant("pendulum", 0.01)
    assert isinstance(plant.binding, Binding)
    assert plant._qadr.tolist() == plant.binding.qpos(plant.system.joints).tolist()
    f = make_observer("ekf_mujoco", Pendulum(), R=1e-4)
    assert isinstance(f.model.binding, Binding)
    assert f.model.aid == f.model.binding.ids("actuator", Pendulum.actuators).tolist()
    with pytest.raises(ModelError, match=r"cannot estimate 'body_mass\[nope\]' .*: the model has "
                                         r"no body named 'nope'; its body names: \['world', "
                                         r"'pole'\]"):
        make_observer("ekf_mujoco", Pendulum(), estimate=("body_mass[nope]",), theta_hat0=[1.0])
    with pytest.raises(ModelError, match=r"the model has no joint named 'elbow'; its joint names: "
                                         r"\['hinge'\]"):
        MujocoPlant(Pendulum, model_fields={"dof_frictionloss[elbow]": 0.1})
    with pytest.raises(ModelError, match="pendulum.xml has no sensor named 'speed'; its sensor "
                                         "names: \\['angle'"):
        MujocoPlant(Pendulum, outputs=("angle", "speed"))
    with pytest.raises(ModelError, match="the model has no joint named 'elbow'"):
        Poses(plant.model, ["elbow"])
