"""Coordinates of the same name in several joints (OpenSim addresses them by path, as OpenSim
Creator models do): each becomes MuJoCo joint ``<joint>_<coordinate>``; unique names are kept."""

from __future__ import annotations

import mujoco
import numpy as np
import opensim as osim
import pytest
from lxml import etree

from o2m import compare_kinematics
from o2m.convert.converter import convert
from o2m.osim.names import CoordinateNames
from o2m.osim.pair import ModelPair
from o2m.osim.storage import write_sto
from o2m.validate.muscles import compare_muscles
from o2m.viz.motion import load_motion
from tests.helpers import convert_options

_MOVING = """<MovingPathPoint name="moving"><socket_parent_frame>/bodyset/link2</socket_parent_frame>
<socket_x_coordinate>/jointset/j2/rz</socket_x_coordinate><socket_y_coordinate>/jointset/j2/rz</socket_y_coordinate>
<socket_z_coordinate>/jointset/j2/rz</socket_z_coordinate>
<x_location><LinearFunction><coefficients>0.05 -0.04</coefficients></LinearFunction></x_location>
<y_location><Constant><value>-0.15</value></Constant></y_location>
<z_location><Constant><value>0</value></Constant></z_location></MovingPathPoint>"""


def _chain(path) -> str:
    """Three links on PinJoints j1-j3, each coordinate named ``rz``, a fourth on a slider with a
    unique name; a muscle from ground to the tip, another through a point moving with j2's ``rz``,
    and a CoordinateActuator and CoordinateLimitForce naming ``rz`` (OpenSim takes the first
    coordinate of that name, j1's)."""
    m = osim.Model()
    m.setName("shared_rz")
    prev = m.getGround()
    for i in range(3):
        b = osim.Body(f"link{i + 1}", 1.0, osim.Vec3(0, -0.15, 0), osim.Inertia(0.01, 0.002, 0.01))
        m.addBody(b)
        j = osim.PinJoint(f"j{i + 1}", prev, osim.Vec3(0, -0.3 if i else 0, 0), osim.Vec3(0, 0, 0.1 * i),
                          b, osim.Vec3(0), osim.Vec3(0))
        c = j.upd_coordinates(0)
        c.setName("rz")
        c.setRangeMin(-1.0)
        c.setRangeMax(1.0 + 0.1 * i)
        m.addJoint(j)
        prev = b
    tip = osim.Body("tip", 0.2, osim.Vec3(0), osim.Inertia(0.001, 0.001, 0.001))
    m.addBody(tip)
    slide = osim.SliderJoint("slide", prev, osim.Vec3(0, -0.3, 0), osim.Vec3(0), tip, osim.Vec3(0), osim.Vec3(0))
    slide.upd_coordinates(0).setName("reach")
    slide.upd_coordinates(0).setRangeMin(0.0)
    slide.upd_coordinates(0).setRangeMax(0.1)
    m.addJoint(slide)
    mus = osim.Thelen2003Muscle("mus", 100.0, 0.2, 0.2, 0.0)
    mus.addNewPathPoint("origin", m.getGround(), osim.Vec3(0.05, -0.1, 0))
    mus.addNewPathPoint("via", m.getBodySet().get("link2"), osim.Vec3(0.04, -0.1, 0))
    mus.addNewPathPoint("insertion", tip, osim.Vec3(0.03, 0.0, 0))
    m.addForce(mus)
    mover = osim.Thelen2003Muscle("mover", 100.0, 0.2, 0.2, 0.0)
    mover.addNewPathPoint("origin", m.getGround(), osim.Vec3(-0.05, -0.1, 0))
    mover.addNewPathPoint("insertion", tip, osim.Vec3(-0.03, 0.0, 0))
    m.addForce(mover)
    act = osim.CoordinateActuator("rz")
    act.setName("motor")
    act.setOptimalForce(7.0)
    m.addForce(act)
    m.addForce(osim.CoordinateLimitForce("rz", 30.0, 5.0, -30.0, 5.0, 0.5, 5.0))
    m.finalizeConnections()
    m.printToXML(str(path))
    # a MovingPathPoint whose sockets name the coordinate by path, /jointset/j2/rz (as 4.x writes it)
    doc = etree.parse(str(path))
    points = doc.find(".//Thelen2003Muscle[@name='mover']//PathPointSet/objects")
    points.insert(1, etree.fromstring(_MOVING))
    doc.write(str(path))
    return str(path)


def test_shared_names_become_joint_prefixed_and_validate(tmp_path):
    src = _chain(tmp_path / "shared.osim")
    conv = convert(src, tmp_path / "out", convert_options())
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    names = [m.joint(i).name for i in range(m.njnt)]
    assert names[:4] == ["j1_rz", "j2_rz", "j3_rz", "reach"]  # the unique name is kept
    assert m.actuator("motor").trnid[0] == m.joint("j1_rz").id  # OpenSim's CoordinateActuator takes j1's
    assert m.jnt_range[m.joint("j3_rz").id][1] == pytest.approx(1.2)
    assert m.dof_damping[m.joint("j1_rz").dofadr[0]] > 0.0  # the limit force's damping: on j1 only
    assert m.dof_damping[m.joint("j2_rz").dofadr[0]] == 0.0
    assert sum("is MuJoCo joint 'j2_rz'" in n for n in conv.report.notes) == 1

    rep = compare_kinematics(src, conv.xml, n_poses=20)
    assert rep.coordinates == ["j1_rz", "j2_rz", "j3_rz", "reach"]
    assert rep.max_pos_error < 1e-9 and rep.max_ang_error < 1e-9, rep.summary()
    mus = compare_muscles(src, conv.xml, n_poses=20, ma_poses=5)
    assert mus.max_len_error < 1e-9
    assert set(mus.muscles["mus"].moment_arms) >= {"j1_rz", "j2_rz"}
    eq = m.equality("mover-moving_x_from_j2_rz")  # the moving point follows j2's coordinate
    assert m.joint(int(eq.obj2id[0])).name == "j2_rz"

    # the renamed joints carry their own coordinate's value, in OpenSim and in a replayed motion
    pair = ModelPair(src, conv.xml)
    st = pair.os_state({"j2_rz": 0.3, "j3_rz": -0.2})
    js = pair.os_model.getJointSet()
    assert [js.get(f"j{k}").get_coordinates(0).getValue(st) for k in (1, 2, 3)] == pytest.approx([0.0, 0.3, -0.2])
    t = np.array([0.0, 0.1])
    cols = ["/jointset/j2/rz/value", "/jointset/j3/rz/value", "reach"]
    motion = load_motion(write_sto(tmp_path / "m.mot", t, cols, np.array([[0.3, -0.2, 0.05]] * 2)), m)
    assert motion.coordinates == ("j2_rz", "j3_rz", "reach")
    assert motion.qpos[0, m.jnt_qposadr[m.joint("j2_rz").id]] == pytest.approx(0.3)
    assert motion.qpos[0, m.jnt_qposadr[m.joint("j1_rz").id]] == 0.0


def test_naming_rule():
    names = CoordinateNames([("j1", "rz"), ("j2", "rz"), ("j2", "tx"), ("j3", "rz")])
    assert [names(j, c) for j, c in names.owners] == ["j1_rz", "j2_rz", "tx", "j3_rz"]
    assert names.resolve("rz") == "j1_rz"  # a bare shared name: the first, as OpenSim's CoordinateSet.get
    assert names.resolve("/jointset/j3/rz") == "j3_rz" and names.resolve("tx") == "tx"
    assert names.renamed() == [("j1", "rz", "j1_rz"), ("j2", "rz", "j2_rz"), ("j3", "rz", "j3_rz")]
    with pytest.raises(ValueError, match="would be renamed 'j1_rz', which another coordinate already uses"):
        CoordinateNames([("j1", "rz"), ("j2", "rz"), ("j3", "j1_rz")])
