"""PointOnLineConstraint: a body slides along a tilted line in OpenSim and in MuJoCo alike."""

from __future__ import annotations

import mujoco
import numpy as np
import opensim as osim

from o2m import compare_kinematics
from o2m.convert import convert
from o2m.transforms import OSIM_TO_MJ
from tests.helpers import convert_options

DIRECTION = np.array([1.0, 1.0, 0.3]) / np.linalg.norm([1.0, 1.0, 0.3])
LINE_POINT = np.array([0.1, 0.5, -0.2])


def _model(path) -> str:
    """A 2-kg block on a FreeJoint whose centre stays on a tilted line through the ground."""
    m = osim.Model()
    m.setName("point_on_line")
    block = osim.Body("block", 2.0, osim.Vec3(0), osim.Inertia(0.01, 0.02, 0.03))
    m.addBody(block)
    joint = osim.FreeJoint("free", m.getGround(), osim.Vec3(0), osim.Vec3(0), block, osim.Vec3(0), osim.Vec3(0))
    m.addJoint(joint)
    for i, v in enumerate((0.3, 0.2, 0.1, *(LINE_POINT + 0.4 * DIRECTION))):
        joint.upd_coordinates(i).setDefaultValue(float(v))
    c = osim.PointOnLineConstraint(m.getGround(), osim.Vec3(*DIRECTION), osim.Vec3(*LINE_POINT), block, osim.Vec3(0))
    c.setName("on_line")
    m.addConstraint(c)
    m.finalizeConnections()
    m.printToXML(str(path))
    return str(path)


def _opensim_fall(path: str, seconds: float, step: float) -> np.ndarray:
    """The block's position (OpenSim ground frame) every ``step`` seconds as it slides under gravity."""
    m = osim.Model(path)
    state = m.initSystem()
    manager = osim.Manager(m)
    manager.setIntegratorAccuracy(1e-9)
    manager.initialize(state)
    out = []
    for t in np.arange(step, seconds + step / 2, step):
        state = manager.integrate(float(t))
        m.realizePosition(state)
        out.append(m.getBodySet().get("block").getPositionInGround(state).to_numpy())
    return np.array(out)


def test_point_on_line_is_exact_and_slides_as_in_opensim(tmp_path):
    path = _model(tmp_path / "on_line.osim")
    conv = convert(path, tmp_path / "out", convert_options())
    rep = compare_kinematics(path, conv.xml, n_poses=30)
    assert rep.max_pos_error < 1e-9 and rep.max_ang_error < 1e-9, rep.summary()
    assert any("PointOnLineConstraint 'on_line'" in n for n in conv.report.notes)

    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    seconds, every = 0.5, 0.05
    steps = int(round(every / m.opt.timestep))
    positions = []
    for _ in range(int(round(seconds / every))):
        for _ in range(steps):
            mujoco.mj_step(m, d)
        positions.append(OSIM_TO_MJ.T @ d.body("block").xpos)
    mj = np.array(positions)
    ref = _opensim_fall(path, seconds, every)
    # on the line in MuJoCo too (the distance from it, m) ...
    rel = mj - LINE_POINT
    off_line = np.linalg.norm(rel - np.outer(rel @ DIRECTION, DIRECTION), axis=1)
    assert off_line.max() < 1e-4, off_line
    # ... and sliding down it as in OpenSim: the block falls about 0.35 m along the line in 0.5 s
    travelled = np.linalg.norm(ref[-1] - ref[0])
    assert travelled > 0.1
    assert np.abs(mj - ref).max() < 0.01 * travelled, (np.abs(mj - ref).max(), travelled)
