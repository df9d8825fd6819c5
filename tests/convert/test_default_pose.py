"""The ``default-pose`` keyframe is OpenSim's assembled default state: a body constraint the
coordinates' default values leave open starts closed in MuJoCo, as in OpenSim."""

from __future__ import annotations

import re

import mujoco
import numpy as np
import opensim as osim
import pytest

from o2m.convert import convert
from o2m.transforms import OSIM_TO_MJ
from tests.helpers import arm_and_block, convert_options

osim.Logger.setLevelString("off")

ARM_POINT = np.array([0.0, -0.5, 0.0])  # the arm's constrained point (m, arm frame)
GAP = np.array([0.08, 0.05, -0.03])  # where the block's default position leaves it (m)


def _open_pendulum(path, kind: str, gap: np.ndarray) -> str:
    """An arm pinned to the ground (0.4 rad) and a free block whose centre a ``kind`` constraint
    holds at the arm's end; the block's default position is ``gap`` away from it."""
    end = np.array([[np.cos(0.4), -np.sin(0.4), 0], [np.sin(0.4), np.cos(0.4), 0], [0, 0, 1]]) @ ARM_POINT
    m, arm, block = arm_and_block(f"open_{kind}", 0.4, (0.0, 0.0, 0.0, *(end + gap)))
    if kind == "PointConstraint":
        c = osim.PointConstraint(arm, osim.Vec3(*ARM_POINT), block, osim.Vec3(0))
    else:
        c = osim.PointOnLineConstraint(arm, osim.Vec3(1, 0, 0), osim.Vec3(*ARM_POINT), block, osim.Vec3(0))
    c.setName("held")
    m.addConstraint(c)
    m.finalizeConnections()
    m.printToXML(str(path))
    return str(path)


def _opensim_block(path: str) -> np.ndarray:
    """The block's centre (MuJoCo world frame, m) in OpenSim's initSystem state."""
    m = osim.Model(path)
    s = m.initSystem()
    return OSIM_TO_MJ @ m.getBodySet().get("block").getPositionInGround(s).to_numpy()


def _residual(m: mujoco.MjModel, d: mujoco.MjData) -> float:
    """The largest equality row's violation (m) at ``d.qpos``."""
    mujoco.mj_forward(m, d)
    rows = d.efc_type[:d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    return float(np.abs(d.efc_pos[:d.nefc][rows]).max(initial=0.0))


@pytest.mark.parametrize("kind", ["PointConstraint", "PointOnLineConstraint"])
def test_keyframe_is_opensims_assembled_state(tmp_path, kind):
    path = _open_pendulum(tmp_path / f"{kind}.osim", kind, GAP)
    conv = convert(path, tmp_path / "out", convert_options(fit_wraps=False, fit_mechanics=False))
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    d = mujoco.MjData(m)
    assert _residual(m, d) > 0.02  # qpos0 keeps the default values: open
    mujoco.mj_resetDataKeyframe(m, d, m.key("default-pose").id)
    assert _residual(m, d) < 1e-8
    assert np.linalg.norm(d.body("block").xpos - _opensim_block(path)) < 1e-8
    note = next(n for n in conv.report.notes if n.startswith("the 'default-pose' keyframe is OpenSim's assembled"))
    assert "pin_coord_0" in note and "free_coord_5 +0.03" in note, note
    after, before = (float(x) for x in re.search(r"residual there (\S+) \(at qpos0, the default values, (\S+);",
                                                 note).groups())
    assert after < 1e-8 and before > 0.02, note


def test_keyframe_is_qpos0_where_the_defaults_are_assembled(tmp_path):
    path = _open_pendulum(tmp_path / "closed.osim", "PointConstraint", np.zeros(3))
    conv = convert(path, tmp_path / "out", convert_options(fit_wraps=False, fit_mechanics=False))
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    assert np.array_equal(m.key("default-pose").qpos, m.qpos0)
    assert not any("assembled default state" in n for n in conv.report.notes)


def _spinning(path, joint_type: str) -> str:
    """A link on a ``joint_type`` from a turned ground frame and a pin-jointed tip, every coordinate
    with a default speed (a Ball's and a Free's rotations: angular velocity components). After a
    PinJoint the tip's angle is tied to the first by a coupler (0.7 q + 0.1), its default speed
    consistent with it."""
    m = osim.Model()
    m.setName(path.stem)
    link = osim.Body("link", 1.0, osim.Vec3(0.05, -0.3, 0.02), osim.Inertia(0.02, 0.015, 0.025))
    tip = osim.Body("tip", 0.5, osim.Vec3(0, -0.2, 0), osim.Inertia(0.01, 0.005, 0.01))
    m.addBody(link)
    m.addBody(tip)
    joint = getattr(osim, joint_type)("j", m.getGround(), osim.Vec3(0.1, 0.2, 0), osim.Vec3(0.3, -0.2, 0.5), link,
                                      osim.Vec3(0, 0.1, 0), osim.Vec3(-0.4, 0.1, 0.2))
    pin = osim.PinJoint("pin", link, osim.Vec3(0, -0.5, 0), osim.Vec3(0), tip, osim.Vec3(0, 0.1, 0), osim.Vec3(0))
    m.addJoint(joint)
    m.addJoint(pin)
    for i in range(joint.numCoordinates()):
        c = joint.upd_coordinates(i)
        c.setDefaultValue([0.5, -0.7, 0.9, 0.1, 0.2, -0.1][i])
        c.setDefaultSpeedValue([0.8, -1.5, 2.0, 0.3, -0.2, 0.4][i])
    tip_q = pin.upd_coordinates(0)
    tip_q.setName("tip_q")
    tip_q.setDefaultSpeedValue(1.1)
    if joint_type == "PinJoint":
        tip_q.setDefaultValue(0.7 * 0.5 + 0.1)
        tip_q.setDefaultSpeedValue(0.7 * 0.8)
        coupler = osim.CoordinateCouplerConstraint()
        coupler.setName("coupler")
        coupler.setIndependentCoordinateNames(osim.ArrayStr(joint.get_coordinates(0).getName(), 1))
        coupler.setDependentCoordinateName("tip_q")
        coupler.setFunction(osim.LinearFunction(0.7, 0.1))  # exact in MuJoCo, as its derivative
        m.addConstraint(coupler)
    m.finalizeConnections()
    m.printToXML(str(path))
    return str(path)


@pytest.mark.parametrize("joint_type", ["PinJoint", "BallJoint", "FreeJoint"])
def test_keyframe_holds_opensims_default_speeds(tmp_path, joint_type):
    """OpenSim's default state moves: the keyframe's qvel gives both links OpenSim's angular and
    linear velocities (the coupled pin through its equality); it was left at rest."""
    path = _spinning(tmp_path / f"{joint_type}.osim", joint_type)
    conv = convert(path, tmp_path / "out", convert_options(quick=True))
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("default-pose").id)
    mujoco.mj_forward(m, d)
    model = osim.Model(path)
    state = model.initSystem()
    model.realizeVelocity(state)
    moving = 0
    for body in ("link", "tip"):
        v = model.getBodySet().get(body).getVelocityInGround(state)
        expected = np.r_[OSIM_TO_MJ @ v.get(0).to_numpy(), OSIM_TO_MJ @ v.get(1).to_numpy()]
        jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        mujoco.mj_jacBody(m, d, jacp, jacr, m.body(body).id)  # at the body frame's origin, as OpenSim's
        got = np.r_[jacr @ d.qvel, jacp @ d.qvel]
        moving += np.abs(expected).max() > 0.1
        np.testing.assert_allclose(got, expected, atol=1e-7, err_msg=body)
    assert moving == 2
