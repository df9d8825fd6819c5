"""Forms of .osim documents the corpus does not use, met in public models from elsewhere:
bodies, joints and forces in the model's ``<components>`` list, muscles on a path o2m cannot
convert, and joints OpenSim reverses (the child nearer ground than the parent)."""

from __future__ import annotations

import mujoco
import numpy as np
import opensim as osim
import pytest

from o2m import compare_kinematics
from o2m.convert.converter import convert
from o2m.errors import UnsupportedElementError
from tests.helpers import convert_options, slider_model

_MUSCLE_PATH = """<GeometryPath name="path"><PathPointSet><objects>
<PathPoint name="origin"><socket_parent_frame>/hook</socket_parent_frame><location>0 0 0</location></PathPoint>
<PathPoint name="insertion"><socket_parent_frame>/body</socket_parent_frame><location>0 0 0</location></PathPoint>
</objects></PathPointSet></GeometryPath>"""


def _components_model(path_xml: str = _MUSCLE_PATH) -> str:
    """A body hanging from a muscle, the body and its slider in the model's <components>."""
    return f"""<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40600">
<Model name="hanging">
<components>
<Body name="body"><mass>0.5</mass><mass_center>0 0 0</mass_center><inertia>0.01 0.01 0.01 0 0 0</inertia></Body>
<SliderJoint name="joint"><socket_parent_frame>/ground</socket_parent_frame>
<socket_child_frame>/body</socket_child_frame>
<coordinates><Coordinate name="height"><range>-0.1 0.1</range></Coordinate></coordinates></SliderJoint>
<Station name="mark"><socket_parent_frame>/body</socket_parent_frame><location>0 0 0</location></Station>
<PhysicalOffsetFrame name="hook"><socket_parent>/ground</socket_parent>
<translation>0 0.3 0</translation></PhysicalOffsetFrame>
</components>
<Ground name="ground"/>
<ForceSet name="forceset"><objects>
<Thelen2003Muscle name="muscle">{path_xml}<max_isometric_force>10</max_isometric_force>
<optimal_fiber_length>0.2</optimal_fiber_length><tendon_slack_length>0.1</tendon_slack_length></Thelen2003Muscle>
</objects></ForceSet>
</Model>
</OpenSimDocument>
"""


def test_bodies_and_joints_in_the_components_list_convert(tmp_path):
    src = tmp_path / "hanging.osim"
    src.write_text(_components_model())
    conv = convert(src, tmp_path / "out", convert_options())
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    assert m.body("body").id > 0 and m.joint("height").type == mujoco.mjtJoint.mjJNT_SLIDE
    assert m.actuator("muscle").id >= 0
    # the station is a generic component: listed as skipped, not silently dropped; the frame is
    # used (the muscle's origin), not skipped
    assert any(s.name == "mark" and "generic components" in s.reason for s in conv.report.skipped)
    assert not any(s.name == "hook" for s in conv.report.skipped)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    assert d.ten_length[m.tendon("muscle").id] == pytest.approx(0.3, abs=1e-12)  # from the frame 0.3 m up


def test_a_muscle_on_another_path_type_names_it(tmp_path):
    src = tmp_path / "fbp.osim"
    src.write_text(_components_model("<FunctionBasedPath name=\"path\"/>"))
    with pytest.raises(UnsupportedElementError, match=r"line 15: <Thelen2003Muscle name=\"muscle\"> has a "
                                                      r"<FunctionBasedPath>, a path o2m cannot convert"):
        convert(src, tmp_path / "out", convert_options())


def _reversed_model(path, kind: str) -> str:
    """ground -pin1-> rod1, then a ``kind`` joint whose parent is rod2 and child rod1: OpenSim
    reverses it (rod2 hangs from rod1). Offsets and orientations on both sides."""
    m = osim.Model()
    m.setName(f"reversed_{kind}")
    rod1 = osim.Body("rod1", 1.0, osim.Vec3(0, -0.2, 0), osim.Inertia(0.01, 0.002, 0.01))
    rod2 = osim.Body("rod2", 0.7, osim.Vec3(0.02, -0.1, 0), osim.Inertia(0.004, 0.001, 0.005))
    m.addBody(rod1)
    m.addBody(rod2)
    m.addJoint(osim.PinJoint("pin1", m.getGround(), osim.Vec3(0), osim.Vec3(0), rod1, osim.Vec3(0, 0.5, 0),
                             osim.Vec3(0)))
    joint_type = {"pin": osim.PinJoint, "slider": osim.SliderJoint, "free": osim.FreeJoint}[kind]
    j = joint_type("j2", rod2, osim.Vec3(0.05, 0.4, -0.02), osim.Vec3(0.2, -0.1, 0.3), rod1,
                   osim.Vec3(0.01, -0.3, 0.02), osim.Vec3(-0.3, 0.4, 0.1))
    m.addJoint(j)
    m.finalizeConnections()
    m.printToXML(str(path))
    return str(path)


@pytest.mark.parametrize("kind", ["pin", "slider"])
def test_a_joint_opensim_reverses_converts_exactly(tmp_path, kind):
    path = _reversed_model(tmp_path / f"{kind}.osim", kind)
    conv = convert(path, tmp_path / "out", convert_options())
    assert any("joint 'j2' reversed" in n for n in conv.report.notes)
    rep = compare_kinematics(path, conv.xml, n_poses=20)
    assert rep.max_pos_error < 1e-9 and rep.max_ang_error < 1e-9, rep.summary()


def test_a_reversed_joint_moving_rotations_and_translations_is_refused(tmp_path):
    path = _reversed_model(tmp_path / "free.osim", "free")
    with pytest.raises(UnsupportedElementError, match=r"<FreeJoint name=\"j2\"> is reversed \(its child 'rod1' is "
                                                      r"nearer ground than its parent 'rod2'\)"):
        convert(path, tmp_path / "out", convert_options())


def test_path_forces_o2m_does_not_convert_are_listed_as_skipped(tmp_path):
    """A force with a path that is not one o2m converts (ClutchedPathSpring, McKibbenActuator) is
    left out with its reason in the report, not dropped without a word."""
    m = osim.Model()
    m.setName("path_forces")
    b = osim.Body("b", 1.0, osim.Vec3(0), osim.Inertia(0.01))
    m.addBody(b)
    m.addJoint(osim.SliderJoint("s", m.getGround(), osim.Vec3(0), osim.Vec3(0), b, osim.Vec3(0), osim.Vec3(0)))
    forces = [osim.ClutchedPathSpring("clutch", 100.0, 1.0, 0.1, 0.0), osim.McKibbenActuator("mck", 0.01, 10.0)]
    for f in forces:
        f.updGeometryPath().appendNewPathPoint("p1", m.getGround(), osim.Vec3(0, 0, 0))
        f.updGeometryPath().appendNewPathPoint("p2", b, osim.Vec3(0, 0.1, 0))
        m.addForce(f)
    m.finalizeConnections()
    m.printToXML(str(tmp_path / "path_forces.osim"))
    conv = convert(tmp_path / "path_forces.osim", tmp_path / "out", convert_options())
    skipped = {(s.element, s.name): s.reason for s in conv.report.skipped}
    why = "this force is not converted yet (its path too: no tendon, no force)"
    assert skipped.get(("ClutchedPathSpring", "clutch")) == why and skipped.get(("McKibbenActuator", "mck")) == why


def test_the_muscle_types_once_skipped_convert(tmp_path):
    """Delp1990Muscle_Deprecated, Thelen2003Muscle_Deprecated and MeyerFregly2016Muscle (once
    listed as skipped) become MuJoCo muscles on their tendons, fitted to OpenSim's forces."""
    m, b = slider_model("muscle_types")
    types = ("Delp1990Muscle_Deprecated", "Thelen2003Muscle_Deprecated", "MeyerFregly2016Muscle")
    for i in range(len(types)):
        mus = osim.Thelen2003Muscle(f"m{i}", 200.0, 0.1, 0.2, 0.0)
        mus.addNewPathPoint("p1", m.getGround(), osim.Vec3(-0.3, 0.01 * i, 0))
        mus.addNewPathPoint("p2", b, osim.Vec3(0, 0.01 * i, 0))
        m.addForce(mus)
    m.finalizeConnections()
    m.printToXML(str(tmp_path / "built.osim"))
    text = (tmp_path / "built.osim").read_text()
    for i, tag in enumerate(types):  # the same muscle, of each type (MeyerFregly2016Muscle needs a rigid tendon)
        start = text.index(f'<Thelen2003Muscle name="m{i}">')
        end = text.index("</Thelen2003Muscle>", start) + len("</Thelen2003Muscle>")
        body = text[start:end].replace("Thelen2003Muscle", tag)
        if tag == "MeyerFregly2016Muscle":
            body = body.replace("<ignore_tendon_compliance>false", "<ignore_tendon_compliance>true")
        text = text[:start] + body + text[end:]
    (tmp_path / "muscle_types.osim").write_text(text)
    conv = convert(tmp_path / "muscle_types.osim", tmp_path / "out", convert_options())
    assert not any(s.element in types for s in conv.report.skipped)
    # each mapping's approximation and its measured error are in the report's notes
    for i, what in enumerate(("Schutte activation dynamics", "constant time constants", "rates blended by 0.5 tanh")):
        assert any(n.startswith(f"m{i}: ") and what in n and "activation RMS error" in n for n in conv.report.notes)
    model = mujoco.MjModel.from_xml_path(str(conv.xml))
    for i in range(len(types)):
        act = model.actuator(f"m{i}")
        assert model.tendon(int(act.trnid[0])).name and act.gainprm[2] == pytest.approx(200.0)  # force


def test_old_type_names_opensim_still_reads_convert_as_their_current_types(tmp_path):
    """A 4.x file may use a type's old name (``<Schutte1993Muscle>``, ``<MuscleViaPoint>``), which
    OpenSim reads as the current type: o2m converts it as OpenSim reads it, not as unknown."""
    m, b = slider_model("old_names")
    mus = osim.Thelen2003Muscle("m", 200.0, 0.1, 0.2, 0.0)  # retyped below (no Python class for Schutte)
    mus.addNewPathPoint("p1", m.getGround(), osim.Vec3(-0.3, 0, 0))
    mus.addNewPathPoint("p2", b, osim.Vec3(0, 0, 0))
    m.addForce(mus)
    m.finalizeConnections()
    m.printToXML(str(tmp_path / "built.osim"))
    built = (tmp_path / "built.osim").read_text().replace("<optimal_force>1</optimal_force>", "")
    old, current = tmp_path / "old" / "model.osim", tmp_path / "current" / "model.osim"
    for path, tag in ((old, "Schutte1993Muscle"), (current, "Schutte1993Muscle_Deprecated")):
        path.parent.mkdir()
        path.write_text(built.replace("Thelen2003Muscle", tag))
    assert "<Schutte1993Muscle " in old.read_text()
    assert osim.Model(str(old)).getMuscles().get("m").getConcreteClassName() == "Schutte1993Muscle_Deprecated"
    conv = convert(old, tmp_path / "old" / "out", convert_options())
    model = mujoco.MjModel.from_xml_path(str(conv.xml))
    assert model.actuator("m").gainprm[2] == pytest.approx(200.0)
    ref = convert(current, tmp_path / "current" / "out", convert_options())
    assert conv.xml.read_text() == ref.xml.read_text()


def test_a_blankevoort_ligament_pulls_as_in_opensim(tmp_path):
    """Blankevoort1991Ligament: a spring on its tendon with OpenSim's toe region and linear part."""
    m = osim.Model()
    m.setName("blankevoort")
    b = osim.Body("b", 1.0, osim.Vec3(0), osim.Inertia(0.01))
    m.addBody(b)
    joint = osim.SliderJoint("s", m.getGround(), osim.Vec3(0), osim.Vec3(0, 0, 1.5708), b, osim.Vec3(0),
                             osim.Vec3(0, 0, 1.5708))  # slides along ground Y
    joint.upd_coordinates(0).setName("y")
    joint.upd_coordinates(0).setRangeMin(-0.05)
    joint.upd_coordinates(0).setRangeMax(0.1)
    m.addJoint(joint)
    lig = osim.Blankevoort1991Ligament("lig", m.getGround(), osim.Vec3(0, -0.2, 0), b, osim.Vec3(0, 0, 0))
    lig.set_slack_length(0.2)
    lig.set_linear_stiffness(800.0)
    lig.set_transition_strain(0.1)
    m.addForce(lig)
    m.finalizeConnections()
    path = tmp_path / "blankevoort.osim"
    m.printToXML(str(path))
    conv = convert(path, tmp_path / "out", convert_options())
    recorded = next(a.max_error for a in conv.report.approximations if a.element == "Blankevoort1991Ligament")
    mj = mujoco.MjModel.from_xml_path(str(conv.xml))
    d = mujoco.MjData(mj)
    m = osim.Model(str(path))
    state = m.initSystem()
    lig = osim.Blankevoort1991Ligament.safeDownCast(m.getForceSet().get("lig"))
    ys = np.linspace(-0.05, 0.1, 31)
    ours, theirs = [], []
    for y in ys:
        m.getCoordinateSet().get("y").setValue(state, float(y))
        m.realizeVelocity(state)
        theirs.append(lig.getSpringForce(state))
        d.qpos[mj.joint("y").qposadr[0]] = y
        mujoco.mj_forward(mj, d)
        ours.append(-d.qfrc_passive[mj.joint("y").dofadr[0]])  # the ligament pulls the body down: -Y
    theirs, ours = np.array(theirs), np.array(ours)
    assert theirs.max() > 300.0 and theirs[ys < 0].max() == 0.0  # stretched up to 50 %, slack below
    # the dead band and polynomial fit: within 2 % of the largest force (a spring without the toe
    # region would be 40 N, 11 % off), and no worse than the report says
    worst = np.abs(ours - theirs).max()
    assert worst < 0.02 * theirs.max(), np.c_[ys, theirs, ours]
    assert worst < recorded * 1.05 + 1e-6, (worst, recorded)


def test_a_spring_generalized_force_is_its_joints_spring_and_damper(tmp_path):
    m = osim.Model()
    m.setName("spring_generalized")
    m.setGravity(osim.Vec3(0))
    b = osim.Body("b", 2.0, osim.Vec3(0), osim.Inertia(0.1))
    m.addBody(b)
    j = osim.PinJoint("p", m.getGround(), osim.Vec3(0), osim.Vec3(0), b, osim.Vec3(0), osim.Vec3(0))
    j.upd_coordinates(0).setName("q")
    m.addJoint(j)
    f = osim.SpringGeneralizedForce("q")
    f.setName("spring")
    f.setStiffness(3.0)
    f.setRestLength(0.2)
    f.setViscosity(0.5)
    m.addForce(f)
    m.finalizeConnections()
    path = tmp_path / "spring.osim"
    m.printToXML(str(path))
    conv = convert(path, tmp_path / "out", convert_options())
    assert not any(s.name == "spring" for s in conv.report.skipped)
    mj = mujoco.MjModel.from_xml_path(str(conv.xml))
    d = mujoco.MjData(mj)
    m = osim.Model(str(path))
    state = m.initSystem()
    c = m.getCoordinateSet().get("q")
    for q, u in [(0.0, 0.0), (0.5, 0.0), (-0.4, 2.0)]:
        c.setValue(state, q)
        c.setSpeedValue(state, u)
        m.realizeAcceleration(state)
        theirs = c.getAccelerationValue(state) * 0.1  # the only force on a 0.1 kg m² body
        d.qpos[:], d.qvel[:] = q, u
        mujoco.mj_forward(mj, d)
        assert d.qfrc_passive[0] == pytest.approx(theirs, abs=1e-9), (q, u)


def _bushed(path, kind: str, mx: str = "10*theta_x") -> str:
    """A body on a PinJoint about Z held by a bushing (frames offset and turned on both sides):
    a BushingForce, or the ExpressionBasedBushingForce of the same stiffness and damping."""
    m = osim.Model()
    m.setName("bushed")
    b = osim.Body("b", 1.0, osim.Vec3(0, -0.2, 0), osim.Inertia(0.1, 0.2, 0.3))
    m.addBody(b)
    m.addJoint(osim.PinJoint("p", m.getGround(), osim.Vec3(0), osim.Vec3(0), b, osim.Vec3(0), osim.Vec3(0)))
    x1, x2 = ((0.1, 0, 0), (0.2, 0, 0)), ((0, 0.1, 0), (0, 0, 0.3))
    if kind == "BushingForce":
        def tf(p, o):
            r = osim.Rotation()
            r.setRotationToBodyFixedXYZ(osim.Vec3(*o))
            return osim.Transform(r, osim.Vec3(*p))
        f = osim.BushingForce("bush", m.getGround(), tf(*x1), b, tf(*x2), osim.Vec3(100, 200, 300),
                              osim.Vec3(10, 20, 30), osim.Vec3(4, 5, 6), osim.Vec3(1, 2, 3))
    else:
        f = osim.ExpressionBasedBushingForce("bush", m.getGround(), osim.Vec3(*x1[0]), osim.Vec3(*x1[1]), b,
                                             osim.Vec3(*x2[0]), osim.Vec3(*x2[1]))
        for setter, text in (("setMxExpression", mx), ("setMyExpression", "20*theta_y"),
                             ("setMzExpression", "theta_z*30"), ("setFxExpression", "100*delta_x"),
                             ("setFyExpression", "200*delta_y"), ("setFzExpression", "300*delta_z")):
            getattr(f, setter)(text)
        f.set_rotational_damping(osim.Vec3(1, 2, 3))
        f.set_translational_damping(osim.Vec3(4, 5, 6))
    m.addForce(f)
    m.finalizeConnections()
    m.printToXML(str(path))
    return str(path)


def test_a_linear_expression_bushing_converts_as_its_bushing_force(tmp_path):
    """OpenSim gives the two the same forces; o2m gives them the same MuJoCo model."""
    ours = convert(_bushed(tmp_path / "ebbf.osim", "ExpressionBasedBushingForce"), tmp_path / "a", convert_options())
    theirs = convert(_bushed(tmp_path / "bf.osim", "BushingForce"), tmp_path / "b", convert_options())
    assert ours.xml.read_text() == theirs.xml.read_text()
    assert any(a.element == "ExpressionBasedBushingForce" for a in ours.report.approximations)
    assert not any(s.element == "ExpressionBasedBushingForce" for s in ours.report.skipped)


def test_a_coupled_expression_bushing_is_skipped_with_the_reason(tmp_path):
    path = _bushed(tmp_path / "ebbf.osim", "ExpressionBasedBushingForce", mx="10*theta_x + 3*theta_y")
    conv = convert(path, tmp_path / "out", convert_options())
    why = next(s.reason for s in conv.report.skipped if s.element == "ExpressionBasedBushingForce")
    assert why.startswith("<Mx_expression> '10*theta_x+3*theta_y' is not a constant times theta_x")


def _bare_document(bodies: str, joints: str, ground: bool = True) -> str:
    """A 4.x document with ``bodies`` and ``joints`` (XML), a <Ground> only when ``ground``."""
    return f"""<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40000"><Model name="bare">
{'<Ground name="ground"/>' if ground else ''}
<BodySet name="bodyset"><objects>{bodies}</objects></BodySet>
<JointSet name="jointset"><objects>{joints}</objects></JointSet>
</Model></OpenSimDocument>
"""


def _pin(name: str, parent: str, child: str, coordinates: str = "", offset: str = "0 -0.3 0") -> str:
    parent_path = "/ground" if parent == "ground" else f"/bodyset/{parent}"
    return f"""<PinJoint name="{name}"><socket_parent_frame>{parent}_offset</socket_parent_frame>
<socket_child_frame>{child}_offset</socket_child_frame>{coordinates}<frames>
<PhysicalOffsetFrame name="{parent}_offset"><socket_parent>{parent_path}</socket_parent>
<translation>{offset}</translation></PhysicalOffsetFrame>
<PhysicalOffsetFrame name="{child}_offset"><socket_parent>/bodyset/{child}</socket_parent></PhysicalOffsetFrame>
</frames></PinJoint>"""


def test_empty_property_elements_keep_opensims_defaults(tmp_path):
    """OpenSim ignores a property element that holds no value ("Failed to read ... ignored") and
    keeps the default; o2m refused it ("lacks <default_value>") before."""
    body = """<Body name="rod"><mass>1</mass><mass_center></mass_center><inertia>0.1 0.1 0.1 0 0 0</inertia></Body>"""
    coord = """<coordinates><Coordinate name="rz"><default_value></default_value><range> </range>
</Coordinate></coordinates>"""
    src = tmp_path / "empty.osim"
    src.write_text(_bare_document(body, _pin("pin", "ground", "rod", coord)))
    conv = convert(src, tmp_path / "out", convert_options())
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    assert m.qpos0[m.joint("rz").qposadr[0]] == 0.0
    assert np.allclose(m.body_ipos[m.body("rod").id], 0.0)
    rep = compare_kinematics(src, conv.xml, n_poses=10)
    assert rep.max_pos_error < 1e-9 and rep.max_ang_error < 1e-9, rep.summary()


def test_a_model_without_ground_or_coordinates_gets_opensims(tmp_path):
    """No <Ground> element and joints that list no coordinates: OpenSim gives the model its ground
    and each joint coordinates named ``_coord_0`` ...; two joints sharing that name convert as
    ``<joint>__coord_0`` (shared coordinate names), the bodies where OpenSim puts them."""
    bodies = "".join(f'<Body name="{b}"><mass>1</mass><mass_center>0 -0.1 0</mass_center>'
                     f'<inertia>0.01 0.01 0.01 0 0 0</inertia></Body>' for b in ("upper", "lower"))
    src = tmp_path / "bare.osim"
    src.write_text(_bare_document(bodies, _pin("hip", "ground", "upper") + _pin("knee", "upper", "lower"),
                                  ground=False))
    conv = convert(src, tmp_path / "out", convert_options())
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    assert {m.joint(i).name for i in range(m.njnt)} == {"hip__coord_0", "knee__coord_0"}
    rep = compare_kinematics(src, conv.xml, n_poses=20)
    assert rep.max_pos_error < 1e-9 and rep.max_ang_error < 1e-9, rep.summary()
    # an empty <coordinates/> list is not an absent one: OpenSim refuses it ("more mobilities than
    # declared Coordinates"), and so does o2m
    src.write_text(src.read_text().replace('<PinJoint name="knee">', '<PinJoint name="knee"><coordinates/>'))
    with pytest.raises(UnsupportedElementError, match="has 0 coordinates; a PinJoint has 1"):
        convert(src, tmp_path / "out2", convert_options())


def test_a_weld_joint_closing_a_loop_becomes_a_weld_equality(tmp_path):
    """ground -pin-> a -pin-> b, and b also welded to ground where the pins put it at q = 0: the
    weld closes a loop (a body the child of two joints, refused before). It becomes a weld
    equality, met at q = 0 and violated when a pin turns; the two pins stay in the tree."""
    bodies = "".join(f'<Body name="{b}"><mass>1</mass><mass_center>0 -0.1 0</mass_center>'
                     f'<inertia>0.01 0.01 0.01 0 0 0</inertia></Body>' for b in ("a", "b"))
    coords = '<coordinates><Coordinate name="{}"/></coordinates>'
    weld = """<WeldJoint name="tie"><socket_parent_frame>tie_offset</socket_parent_frame>
<socket_child_frame>/bodyset/b</socket_child_frame><frames><PhysicalOffsetFrame name="tie_offset">
<socket_parent>/ground</socket_parent><translation>0 0.3 0</translation></PhysicalOffsetFrame></frames></WeldJoint>"""
    joints = _pin("p1", "ground", "a", coords.format("q1"), "0 0.6 0") \
        + _pin("p2", "a", "b", coords.format("q2"), "0 -0.3 0") + weld
    src = tmp_path / "loop.osim"
    src.write_text(_bare_document(bodies, joints))
    conv = convert(src, tmp_path / "out", convert_options())
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    assert m.neq == 1 and m.eq_type[0] == mujoco.mjtEq.mjEQ_WELD
    assert m.body_parentid[m.body("b").id] == m.body("a").id
    d = mujoco.MjData(m)

    def violation(q1: float) -> float:
        d.qpos[:] = 0.0
        d.qpos[m.joint("q1").qposadr[0]] = q1
        mujoco.mj_forward(m, d)
        return float(np.abs(d.efc_pos[d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY]).max())

    assert violation(0.0) < 1e-12
    assert violation(0.4) > 0.05


def _station_frame_model() -> str:
    """Two bodies hinged at StationDefinedFrames built from markers in the bodies' <components>
    (the parent's axes at their defaults, the child's given), and a muscle over a WrapCylinder held
    by a PhysicalOffsetFrame, as OpenSim Creator writes them."""
    markers = {"thigh": [("a", "0.01 0.02 0.0"), ("b", "0.03 0.15 0.01"), ("c", "0.02 0.01 0.12"),
                         ("o", "0.0 -0.3 0.02")],
               "shank": [("a", "0.0 0.0 0.0"), ("b", "0.01 0.1 0.0"), ("c", "0.1 0.0 0.02"), ("o", "0.0 0.25 0.0")]}

    def frame(body: str, name: str, axes: str) -> str:
        pts = "".join(f"<socket_{s}>/bodyset/{body}/{m}</socket_{s}>"
                      for s, m in (("point_a", "a"), ("point_b", "b"), ("point_c", "c"), ("origin_point", "o")))
        shape = (f'<attached_geometry><Sphere name="{name}_ball"><socket_frame>..</socket_frame><radius>0.01</radius>'
                 '</Sphere></attached_geometry>')
        return f'<StationDefinedFrame name="{name}">{shape}{pts}{axes}</StationDefinedFrame>'

    def body(name: str, extra: str) -> str:
        ms = "".join(f'<Marker name="{m}"><socket_parent_frame>..</socket_parent_frame>'
                     f'<location>{loc}</location></Marker>'
                     for m, loc in markers[name])
        return (f'<Body name="{name}"><components>{ms}{extra}</components><mass>1</mass>'
                f'<mass_center>0 -0.1 0</mass_center><inertia>0.01 0.01 0.01 0 0 0</inertia></Body>')

    wrap_frame = """<PhysicalOffsetFrame name="wrap_frame"><WrapObjectSet><objects><WrapCylinder name="roll">
<radius>0.03</radius><length>0.2</length><quadrant>+x</quadrant></WrapCylinder></objects></WrapObjectSet>
<socket_parent>..</socket_parent><translation>0 -0.3 0</translation></PhysicalOffsetFrame>"""
    thigh = body("thigh", frame("thigh", "knee_frame", "") + wrap_frame)
    shank = body("shank", frame("shank", "shank_frame", "<ab_axis>-y</ab_axis><ab_x_ac_axis>+z</ab_x_ac_axis>"))
    joints = """<PinJoint name="hip"><socket_parent_frame>/ground</socket_parent_frame>
<socket_child_frame>/bodyset/thigh</socket_child_frame><coordinates><Coordinate name="hip_q"><range>-1 1</range>
</Coordinate>
</coordinates></PinJoint>
<PinJoint name="knee"><socket_parent_frame>/bodyset/thigh/knee_frame</socket_parent_frame>
<socket_child_frame>/bodyset/shank/shank_frame</socket_child_frame><coordinates><Coordinate name="knee_q">
<range>-1.5 0.5</range></Coordinate></coordinates></PinJoint>"""
    muscle = """<Thelen2003Muscle name="quad"><GeometryPath name="path"><PathPointSet><objects>
<PathPoint name="p1"><socket_parent_frame>/bodyset/thigh</socket_parent_frame><location>0.04 -0.1 0</location>
</PathPoint>
<PathPoint name="p2"><socket_parent_frame>/bodyset/shank</socket_parent_frame><location>0.04 0.15 0</location>
</PathPoint>
</objects></PathPointSet><PathWrapSet><objects><PathWrap name="w"><wrap_object>roll</wrap_object></PathWrap></objects>
</PathWrapSet></GeometryPath><max_isometric_force>100</max_isometric_force><optimal_fiber_length>0.1</optimal_fiber_length>
<tendon_slack_length>0.2</tendon_slack_length></Thelen2003Muscle>"""
    return f"""<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40600"><Model name="stations"><Ground name="ground"/>
<BodySet name="bodyset"><objects>{thigh}{shank}</objects></BodySet>
<JointSet name="jointset"><objects>{joints}</objects></JointSet>
<ForceSet name="forceset"><objects>{muscle}</objects></ForceSet>
</Model></OpenSimDocument>
"""


def test_station_defined_frames_and_wraps_on_frames_convert_as_in_opensim(tmp_path):
    """A joint between StationDefinedFrames (refused before: "not a Body, Ground or
    PhysicalOffsetFrame") puts the bodies where OpenSim does; a wrap object held by a frame other
    than a body (unknown to the muscle before) becomes a cylinder at that frame."""
    src = tmp_path / "stations.osim"
    src.write_text(_station_frame_model())
    conv = convert(src, tmp_path / "out", convert_options())
    rep = compare_kinematics(src, conv.xml, n_poses=20)
    assert rep.max_pos_error < 1e-9 and rep.max_ang_error < 1e-9, rep.summary()
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    roll = [g for g in range(m.ngeom) if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_CYLINDER
            and m.geom_bodyid[g] == m.body("thigh").id]
    assert len(roll) == 1 and np.allclose(m.geom_size[roll[0]][0], 0.03)
    # geometry attached to a StationDefinedFrame is drawn at its origin (on the body its stations are on)
    ball = [g for g in range(m.ngeom) if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE
            and m.geom_bodyid[g] == m.body("thigh").id]
    assert len(ball) == 1 and np.allclose(m.geom_pos[ball[0]], [0.0, -0.3, 0.02], atol=1e-12)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    os_model = osim.Model(str(src))
    state = os_model.initSystem()
    quad = osim.Muscle.safeDownCast(os_model.getForceSet().get("quad"))
    assert d.ten_length[m.tendon("quad").id] == pytest.approx(quad.getLength(state), abs=2e-3)


def _coupler_model(function: str) -> str:
    """A block on two sliders (x, then y), y = ``function``(x) by a CoordinateCouplerConstraint."""
    slider = """<SliderJoint name="{j}"><socket_parent_frame>{p}</socket_parent_frame>
<socket_child_frame>/bodyset/{c}</socket_child_frame><coordinates><Coordinate name="{q}"><range>-0.5 0.5</range>
</Coordinate></coordinates>{frames}</SliderJoint>"""
    turned = """<frames><PhysicalOffsetFrame name="up"><socket_parent>/bodyset/cart</socket_parent>
<orientation>0 0 1.5707963267948966</orientation></PhysicalOffsetFrame></frames>"""
    bodies = "".join(f'<Body name="{b}"><mass>1</mass><inertia>0.01 0.01 0.01 0 0 0</inertia></Body>'
                     for b in ("cart", "block"))
    joints = slider.format(j="sx", p="/ground", c="cart", q="x", frames="") \
        + slider.format(j="sy", p="up", c="block", q="y", frames=turned)
    return f"""<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40000"><Model name="coupled"><Ground name="ground"/>
<BodySet name="bodyset"><objects>{bodies}</objects></BodySet>
<JointSet name="jointset"><objects>{joints}</objects></JointSet>
<ConstraintSet name="constraintset"><objects><CoordinateCouplerConstraint name="couple">
<coupled_coordinates_function>{function}</coupled_coordinates_function>
<independent_coordinate_names>x</independent_coordinate_names><dependent_coordinate_name>y</dependent_coordinate_name>
</CoordinateCouplerConstraint></objects></ConstraintSet>
</Model></OpenSimDocument>
"""


def test_a_one_dimensional_multivariate_polynomial_couples_as_in_opensim(tmp_path):
    """MultivariatePolynomialFunction (OpenSim 4.4+; coefficients from the lowest power up) was an
    unknown function type; of one dimension it is a polynomial of the independent coordinate."""
    poly = ("<MultivariatePolynomialFunction><coefficients>0.1 0.5 2</coefficients><dimension>1</dimension>"
            "<order>2</order></MultivariatePolynomialFunction>")
    src = tmp_path / "coupled.osim"
    src.write_text(_coupler_model(poly))
    conv = convert(src, tmp_path / "out", convert_options())
    rep = compare_kinematics(src, conv.xml, n_poses=20)
    assert rep.max_pos_error < 1e-9, rep.summary()
    two = poly.replace("<dimension>1", "<dimension>2")
    src.write_text(_coupler_model(two))
    with pytest.raises(UnsupportedElementError, match="MultivariatePolynomialFunction.*<dimension> 2"):
        convert(src, tmp_path / "out2", convert_options())


def test_point_to_point_and_activation_coordinate_actuators_push_as_in_opensim(tmp_path):
    """PointToPointActuator and ActivationCoordinateActuator were "not converted yet": a motor on a
    two-point tendon and a motor with first-order activation. At a pose, with OpenSim's actuation
    (the point-to-point force overridden, the activation state set) and MuJoCo's (ctrl, act), the
    accelerations agree, gravity off."""
    m = osim.Model()
    m.setName("actuated")
    m.setGravity(osim.Vec3(0))
    block = osim.Body("block", 2.0, osim.Vec3(0), osim.Inertia(0.01))
    arm = osim.Body("arm", 1.0, osim.Vec3(0, -0.2, 0), osim.Inertia(0.02, 0.005, 0.02))
    for b in (block, arm):
        m.addBody(b)
    m.addJoint(osim.SliderJoint("slide", m.getGround(), osim.Vec3(0), osim.Vec3(0), block, osim.Vec3(0), osim.Vec3(0)))
    m.addJoint(osim.PinJoint("pin", m.getGround(), osim.Vec3(0, 1, 0), osim.Vec3(0), arm, osim.Vec3(0), osim.Vec3(0)))
    p2p = osim.PointToPointActuator("arm", "block")
    p2p.setName("push")
    p2p.set_pointA(osim.Vec3(-0.5, 0.3, 0.1))
    p2p.set_pointB(osim.Vec3(0.05, 0.02, 0))
    p2p.setOptimalForce(40.0)
    m.addForce(p2p)
    act = osim.ActivationCoordinateActuator()
    act.setName("drive")
    act.set_coordinate("pin_coord_0")
    act.setOptimalForce(3.0)
    act.set_activation_time_constant(0.03)
    m.addForce(act)
    m.finalizeConnections()
    src = tmp_path / "actuated.osim"
    m.printToXML(str(src))
    conv = convert(src, tmp_path / "out", convert_options())
    mj = mujoco.MjModel.from_xml_path(str(conv.xml))
    drive = mj.actuator("drive").id
    assert mj.actuator_dyntype[drive] == mujoco.mjtDyn.mjDYN_FILTER and mj.actuator_dynprm[drive][0] == 0.03

    model = osim.Model(str(src))
    state = model.initSystem()
    q = {"slide_coord_0": 0.2, "pin_coord_0": 0.7}
    for name, v in q.items():
        model.getCoordinateSet().get(name).setValue(state, v)
    push = osim.ScalarActuator.safeDownCast(model.getForceSet().get("push"))
    push.overrideActuation(state, True)
    push.setOverrideActuation(state, 0.6 * 40.0)
    model.getForceSet().get("drive").setStateVariableValue(state, "activation", 0.8)
    model.realizeAcceleration(state)
    theirs = {n: model.getCoordinateSet().get(n).getAccelerationValue(state) for n in q}

    d = mujoco.MjData(mj)
    for name, v in q.items():
        d.qpos[mj.joint(name).qposadr[0]] = v
    d.ctrl[mj.actuator("push").id] = 0.6
    d.act[mj.actuator_actadr[drive]] = 0.8
    mujoco.mj_forward(mj, d)
    for name, acc in theirs.items():
        assert d.qacc[mj.joint(name).dofadr[0]] == pytest.approx(acc, rel=1e-9, abs=1e-9), name
    assert abs(theirs["slide_coord_0"]) > 1.0 and abs(theirs["pin_coord_0"]) > 1.0


def test_a_transform_axis_without_a_function_is_constant_zero(tmp_path):
    """OpenSim gives a TransformAxis that holds no function a Constant 0, even one naming a
    coordinate (which then moves nothing); o2m refused it ("holds no function") before. One axis
    with a function keeps the body moving, so the comparison is not of a body at rest."""
    axes = "".join(f'<TransformAxis name="{n}"><coordinates>{c}</coordinates><axis>{a}</axis>{f}</TransformAxis>'
                   for n, c, a, f in (
                       ("rotation1", "q", "0 0 1", ""), ("rotation2", "", "1 0 0", ""),
                       ("rotation3", "q", "0 1 0", "<LinearFunction><coefficients>0.5 0</coefficients>"
                                                   "</LinearFunction>"),
                       ("translation1", "q", "1 0 0", ""), ("translation2", "", "0 1 0", ""),
                       ("translation3", "", "0 0 1", "")))
    joint = f"""<CustomJoint name="j"><socket_parent_frame>/ground</socket_parent_frame>
<socket_child_frame>/bodyset/b</socket_child_frame><coordinates><Coordinate name="q"><range>-1 1</range>
</Coordinate></coordinates><SpatialTransform>{axes}</SpatialTransform></CustomJoint>"""
    body = ('<Body name="b"><mass>1</mass><mass_center>0.1 0.2 0</mass_center>'
            '<inertia>0.1 0.1 0.1 0 0 0</inertia></Body>')
    src = tmp_path / "nofunction.osim"
    src.write_text(_bare_document(body, joint))
    conv = convert(src, tmp_path / "out", convert_options())
    rep = compare_kinematics(src, conv.xml, n_poses=20)
    assert rep.max_pos_error < 1e-9 and rep.max_ang_error < 1e-9, rep.summary()
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    d = mujoco.MjData(m)
    d.qpos[m.joint("q").qposadr[0]] = 0.8
    mujoco.mj_kinematics(m, d)
    assert np.allclose(d.xpos[m.body("b").id], 0.0, atol=1e-12)  # no translation, the body origin stays
    assert not np.allclose(d.xmat[m.body("b").id], np.eye(3).ravel())  # but rotation3 turns it


def test_a_path_actuator_pulls_and_a_path_spring_pulls_when_stretched_as_in_opensim(tmp_path):
    """PathActuator and PathSpring were tendons without force: a motor (gear -optimal_force) and
    a slack-below-rest spring on their paths' tendons. At poses where the spring is stretched and
    where it is slack, with OpenSim's actuation overridden and MuJoCo's ctrl, at rest and gravity
    off, the accelerations agree; the spring's left-out damping is in its approximation."""
    m, b = slider_model("path_forces_converted", gravity=False)
    pa = osim.PathActuator()
    pa.setName("pull")
    pa.setOptimalForce(30.0)
    pa.addNewPathPoint("a1", m.getGround(), osim.Vec3(-0.3, 0.05, 0))
    pa.addNewPathPoint("a2", b, osim.Vec3(0, 0.02, 0))
    m.addForce(pa)
    ps = osim.PathSpring("spring", 0.32, 500.0, 0.01)
    ps.updGeometryPath().appendNewPathPoint("s1", m.getGround(), osim.Vec3(0.3, 0.0, 0.02))
    ps.updGeometryPath().appendNewPathPoint("s2", b, osim.Vec3(0, 0, 0))
    m.addForce(ps)
    m.finalizeConnections()
    src = tmp_path / "path_forces_converted.osim"
    m.printToXML(str(src))
    conv = convert(src, tmp_path / "out", convert_options())
    mj = mujoco.MjModel.from_xml_path(str(conv.xml))
    assert mj.actuator_gear[mj.actuator("pull").id][0] == -30.0
    spring = next(a for a in conv.report.approximations if a.element == "PathSpring")
    assert spring.max_error < 1e-9 and "dissipation 0.01 s/m is left out" in spring.what
    model = osim.Model(str(src))
    state = model.initSystem()
    pull = osim.ScalarActuator.safeDownCast(model.getForceSet().get("pull"))
    pull.overrideActuation(state, True)
    d = mujoco.MjData(mj)
    for x, control in ((-0.04, 0.7), (0.03, -0.4), (-0.05, 1.0)):  # spring stretched 20.6 mm, slack, 30.6 mm
        model.getCoordinateSet().get("s_coord_0").setValue(state, x)
        pull.setOverrideActuation(state, control * 30.0)
        model.realizeAcceleration(state)
        d.qpos[0], d.ctrl[0] = x, control
        mujoco.mj_forward(mj, d)
        theirs = model.getCoordinateSet().get("s_coord_0").getAccelerationValue(state)
        assert d.qacc[0] == pytest.approx(theirs, rel=1e-9, abs=1e-9), x


def test_stations_that_define_a_joint_frame_are_not_listed_as_skipped(tmp_path):
    """Stations and a StationDefinedFrame in the model's <components>, the frame a joint's parent:
    converted with the joint, so not listed as skipped generic components; a station nothing uses is."""
    stations = "".join(f'<Station name="s{i}"><socket_parent_frame>/ground</socket_parent_frame>'
                       f'<location>{x} {y} {z}</location></Station>'
                       for i, (x, y, z) in enumerate([(0, 1, 0), (0.2, 1, 0), (0, 1.1, 0.1), (0, 1, 0.05)]))
    src = tmp_path / "sdf.osim"
    src.write_text(f"""<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40500"><Model name="sdf"><components>{stations}
<Station name="unused"><socket_parent_frame>/ground</socket_parent_frame><location>0 0 0</location></Station>
<StationDefinedFrame name="top"><socket_point_a>/s0</socket_point_a><socket_point_b>/s1</socket_point_b>
<socket_point_c>/s2</socket_point_c><socket_origin_point>/s3</socket_origin_point></StationDefinedFrame>
</components><Ground name="ground"/>
<BodySet><objects><Body name="bob"><mass>1</mass><mass_center>0 -0.5 0</mass_center>
<inertia>0.01 0.01 0.01 0 0 0</inertia></Body></objects></BodySet>
<JointSet><objects><PinJoint name="pin"><socket_parent_frame>/top</socket_parent_frame>
<socket_child_frame>/bodyset/bob</socket_child_frame><coordinates><Coordinate name="swing">
<default_value>0.3</default_value></Coordinate></coordinates></PinJoint></objects></JointSet>
</Model></OpenSimDocument>
""")
    conv = convert(src, tmp_path / "out", convert_options())
    assert [s.name for s in conv.report.skipped] == ["unused"]
    rep = compare_kinematics(src, conv.xml, n_poses=10)
    assert rep.max_pos_error < 1e-9 and rep.max_ang_error < 1e-9, rep.summary()
