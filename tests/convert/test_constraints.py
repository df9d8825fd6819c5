"""Body-to-body constraints: PointOnLineConstraint slides along a tilted line, and Weld, Point and
ConstantDistance constraints hold a swinging pair, in OpenSim and in MuJoCo alike."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import opensim as osim
import pytest

from o2m import compare_kinematics
from o2m.convert import convert
from o2m.transforms import OSIM_TO_MJ
from tests.helpers import arm_and_block, convert_options

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


ARM_ANGLE = 0.6  # rad, the arm's default angle about Z
ARM_POINT = np.array([0.0, -0.5, 0.0])  # the constrained point on the arm (m, arm frame)


def _rz(a: float) -> np.ndarray:
    return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])


def _pendulum_with(path, kind: str) -> str:
    """An arm pinned to the ground and a free block held to its end by a ``kind`` constraint, the
    default pose satisfying it (OpenSim's and MuJoCo's first poses agree)."""
    end = _rz(ARM_ANGLE) @ ARM_POINT
    offset = np.array([0.3, 0.0, 0.0]) if kind == "ConstantDistanceConstraint" else np.zeros(3)
    rot = (0.0, 0.0, ARM_ANGLE) if kind == "WeldConstraint" else (0.0, 0.0, 0.0)
    m, arm, block = arm_and_block(f"pendulum_{kind}", ARM_ANGLE, (*rot, *(end + offset)))
    p = osim.Vec3(*ARM_POINT)
    if kind == "WeldConstraint":
        c = osim.WeldConstraint("held", arm, osim.Transform(p), block, osim.Transform())
    elif kind == "PointConstraint":
        c = osim.PointConstraint(arm, p, block, osim.Vec3(0))
    else:
        c = osim.ConstantDistanceConstraint(arm, p, block, osim.Vec3(0), 0.3)
    c.setName("held")
    m.addConstraint(c)
    m.finalizeConnections()
    m.printToXML(str(path))
    return str(path)


def _opensim_swing(path: str, seconds: float) -> np.ndarray:
    """The block's position (OpenSim ground frame) after ``seconds`` of swinging under gravity."""
    m = osim.Model(path)
    state = m.initSystem()
    manager = osim.Manager(m)
    manager.setIntegratorAccuracy(1e-9)
    manager.initialize(state)
    state = manager.integrate(seconds)
    m.realizePosition(state)
    return m.getBodySet().get("block").getPositionInGround(state).to_numpy()


@pytest.mark.parametrize("kind", ["WeldConstraint", "PointConstraint", "ConstantDistanceConstraint"])
def test_body_constraints_hold_and_swing_as_in_opensim(tmp_path, kind):
    path = _pendulum_with(tmp_path / f"{kind}.osim", kind)
    conv = convert(path, tmp_path / "out", convert_options())
    assert any(n.startswith(f"{kind} 'held'") for n in conv.report.notes)
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    worst = 0.0
    for _ in range(int(round(0.4 / m.opt.timestep))):
        mujoco.mj_step(m, d)
        a, b = d.site("held_frame1"), d.site("held_frame2")
        gap = float(np.linalg.norm(a.xpos - b.xpos))
        err = abs(gap - 0.3) if kind == "ConstantDistanceConstraint" else gap
        if kind == "WeldConstraint":  # the frames' orientations too (rad)
            err = max(err, float(np.linalg.norm(a.xmat.reshape(3, 3) - b.xmat.reshape(3, 3))))
        worst = max(worst, err)
    # held while the pair swings (a free block would fall 0.78 m in 0.4 s) ...
    assert worst < 1e-3, worst
    # ... and the block swings where OpenSim's does
    ref = _opensim_swing(path, 0.4)
    start = OSIM_TO_MJ.T @ d.body("block").xpos  # MuJoCo, now in OpenSim's frame
    moved = np.linalg.norm(ref - (_rz(ARM_ANGLE) @ ARM_POINT + (0.3 * np.eye(3)[0] if kind ==
                                                                   "ConstantDistanceConstraint" else 0)))
    assert moved > 0.05
    assert np.linalg.norm(start - ref) < 0.05 * moved, (start, ref, moved)


def test_validation_gives_coordinates_held_by_body_equalities_opensims_values(tmp_path):
    """A block slides along a swinging arm, held at 0.6 m from a ground point by a
    ConstantDistanceConstraint: its slide coordinate is OpenSim's to solve (free to satisfy
    constraints); validation writes OpenSim's value and measures the equality's residual."""
    m = osim.Model()
    m.setName("held_slide")
    arm = osim.Body("arm", 1.0, osim.Vec3(0, -0.25, 0), osim.Inertia(0.02, 0.002, 0.02))
    block = osim.Body("block", 0.5, osim.Vec3(0), osim.Inertia(0.001, 0.002, 0.003))
    m.addBody(arm)
    m.addBody(block)
    pin = osim.PinJoint("pin", m.getGround(), osim.Vec3(0), osim.Vec3(0), arm, osim.Vec3(0), osim.Vec3(0))
    pin.upd_coordinates(0).setRangeMin(-0.5)
    pin.upd_coordinates(0).setRangeMax(0.5)
    slide = osim.SliderJoint("slide", arm, osim.Vec3(0), osim.Vec3(0, 0, -1.5708), block, osim.Vec3(0),
                             osim.Vec3(0, 0, -1.5708))  # along the arm's -Y
    slide.upd_coordinates(0).setName("s")
    slide.upd_coordinates(0).set_is_free_to_satisfy_constraints(True)
    slide.upd_coordinates(0).setDefaultValue(0.5)
    m.addJoint(pin)
    m.addJoint(slide)
    c = osim.ConstantDistanceConstraint(m.getGround(), osim.Vec3(0.3, -0.2, 0), block, osim.Vec3(0), 0.6)
    c.setName("held")
    m.addConstraint(c)
    m.finalizeConnections()
    path = str(tmp_path / "held_slide.osim")
    m.printToXML(path)
    conv = convert(path, tmp_path / "out", convert_options())
    rep = compare_kinematics(path, conv.xml, n_poses=20)
    assert rep.held_coordinates == ["s"], rep.summary()
    assert rep.max_pos_error < 1e-9 and rep.constraint_residual < 1e-6, rep.summary()


def test_unnamed_body_constraints_get_names_of_their_own(tmp_path):
    """Two unnamed PointConstraints (a 4.x document may leave names out) become two equalities."""
    text = Path(_pendulum_with(tmp_path / "named.osim", "PointConstraint")).read_text()
    start, end = text.index("<PointConstraint"), text.index("</PointConstraint>") + len("</PointConstraint>")
    unnamed = text[start:end].replace(' name="held"', "")
    path = tmp_path / "unnamed.osim"
    path.write_text(text[:start] + unnamed + "\n" + unnamed + text[end:])
    conv = convert(path, tmp_path / "out", convert_options())
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    names = {m.equality(i).name for i in range(m.neq)}
    assert {"pointconstraint", "pointconstraint_0"} <= names, names
