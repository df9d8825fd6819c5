"""Tests of o2m.validate against small OpenSim models and hand-derived MuJoCo twins.

Each OpenSim model is built with the opensim API from a small spec. Its MuJoCo twin is derived
here, independently of the converter: an OpenSim joint with parent offset frame P (location
lp, body-fixed XYZ orientation op, in the parent body) and child offset frame C (lc, oc, in the
child body) puts the child body, at q = 0, at rotation R(op) R(oc)^T and position
lp - R(op) R(oc)^T lc in the parent body. A PinJoint then rotates about the z axis of C (a
hinge at lc, axis R(oc) e_z in the child body), a SliderJoint translates along the x axis of C
(a slide along R(oc) e_x). Bodies whose parent is ground are further rotated by the Y-up to
Z-up map (x, y, z) -> (x, -z, y).
"""

from __future__ import annotations

import json
import math

import mujoco
import numpy as np
import opensim as osim
import pytest

from o2m.errors import MissingJointError, ValidationError
from o2m.mj.posing import joint_equality_plan, pose_mujoco
from o2m.validate.kinematics import compare_kinematics, format_table, rotation_angle
from tests.helpers import add_coupler

osim.Logger.setLevelString("error")

#: OpenSim ground (Y up) -> MuJoCo world (Z up), written out by hand.
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
TIGHT = 1e-9
N_POSES = 50


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _xyz(angles) -> np.ndarray:
    """OpenSim body-fixed X-Y-Z orientation (radians) as a rotation matrix."""
    return _rx(angles[0]) @ _ry(angles[1]) @ _rz(angles[2])


def _v(x) -> str:
    return " ".join(repr(float(c)) for c in np.ravel(x))


# Bodies: name -> (mass kg, COM m (body frame), inertia about COM xx yy zz xy xz yz).
BODIES = {
    "b1": (2.0, (0.05, -0.2, 0.01), (0.03, 0.01, 0.03, 0.001, 0.0, 0.002)),
    "b2": (1.5, (0.0, -0.15, 0.02), (0.02, 0.008, 0.02, 0.0, 0.001, 0.0)),
    "b3": (0.7, (0.01, -0.1, 0.0), (0.01, 0.004, 0.01, 0.0, 0.0, 0.0005)),
}

# Joints: (name, kind, parent, child, lp, op, lc, oc, coordinate, range).
J1 = ("j1", "pin", "ground", "b1", (0.1, 1.2, -0.05), (0.3, -0.2, 0.5), (0.02, 0.3, 0.0), (0.1, 0.4, -0.3),
      "q1", (-1.5, 1.2))
J2 = ("j2", "pin", "b1", "b2", (0.03, -0.4, 0.02), (-0.6, 0.2, 0.1), (0.0, 0.25, -0.01), (0.2, 0.0, 0.7),
      "q2", (-0.5, 2.0))
J3 = ("j3", "pin", "b2", "b3", (0.0, -0.3, 0.0), (0.0, 0.5, 0.0), (0.01, 0.2, 0.0), (0.3, 0.0, 0.0),
      "q3", (-1.0, 1.0))
SLIDE = ("js", "slider", "ground", "b1", (0.1, 1.0, 0.2), (0.0, 0.4, 0.9), (0.0, 0.1, 0.05), (0.2, -0.3, 0.1),
         "tx", (-0.3, 0.4))


def build_osim(path, joints, *, couplers=(), locked=()) -> str:
    """Write an OpenSim model with gravity along -Y.

    ``couplers``: (dependent, independent, function); ``locked``: (coordinate, value).
    """
    m = osim.Model()
    m.setName(path.stem)
    m.setGravity(osim.Vec3(0, -9.80665, 0))
    bodies = {}
    for _name, _kind, _parent, child, *_ in joints:
        mass, com, inertia = BODIES[child]
        bodies[child] = osim.Body(child, mass, osim.Vec3(*com), osim.Inertia(*inertia))
        m.addBody(bodies[child])
    for name, kind, parent, child, lp, op, lc, oc, coord, rng in joints:
        pframe = m.getGround() if parent == "ground" else bodies[parent]
        cls = osim.PinJoint if kind == "pin" else osim.SliderJoint
        j = cls(name, pframe, osim.Vec3(*lp), osim.Vec3(*op), bodies[child], osim.Vec3(*lc), osim.Vec3(*oc))
        c = j.updCoordinate()
        c.setName(coord)
        c.setRangeMin(rng[0])
        c.setRangeMax(rng[1])
        m.addJoint(j)
    for k, (dep, ind, func) in enumerate(couplers):
        add_coupler(m, f"coupler{k}", ind, dep, func)
    for coord, value in locked:
        c = m.getCoordinateSet().get(coord)
        c.setDefaultValue(value)
        c.setDefaultLocked(True)
    m.finalizeConnections()
    m.printToXML(str(path))
    return str(path)


def build_mjcf(path, joints, *, equalities="", ground=Y_UP_TO_Z_UP, flip=(), offset=None, rename=None,
               extra="") -> str:
    """Write the MuJoCo twin of ``build_osim(joints)``.

    Deliberate mistakes: ``ground`` replaces the Y-up to Z-up map, ``flip`` negates the axes of
    these joints, ``offset`` = (body, vector) shifts a body, ``rename`` = {joint: new name}.
    """
    rename = rename or {}
    children: dict[str, list] = {}
    for j in joints:
        children.setdefault(j[2], []).append(j)

    def body_xml(j, indent: str) -> str:
        name, kind, parent, child, lp, op, lc, oc, coord, rng = j
        rot = _xyz(op) @ _xyz(oc).T
        pos = np.asarray(lp) - rot @ np.asarray(lc)
        if parent == "ground":
            rot, pos = ground @ rot, ground @ pos
        if offset and offset[0] == child:
            pos = pos + np.asarray(offset[1])
        roc = _xyz(oc)
        axis = roc[:, 2] if kind == "pin" else roc[:, 0]
        if coord in flip:
            axis = -axis
        jtype = "hinge" if kind == "pin" else "slide"
        mass, com, inertia = BODIES[child]
        inner = "".join(body_xml(c, indent + "  ") for c in children.get(child, []))
        return (
            f'{indent}<body name="{child}" pos="{_v(pos)}" xyaxes="{_v(rot[:, 0])} {_v(rot[:, 1])}">\n'
            f'{indent}  <joint name="{rename.get(coord, coord)}" type="{jtype}" pos="{_v(lc)}" '
            f'axis="{_v(axis)}" range="{rng[0]} {rng[1]}"/>\n'
            f'{indent}  <inertial pos="{_v(com)}" mass="{mass}" fullinertia="{_v(inertia)}"/>\n'
            f"{inner}{indent}</body>\n"
        )

    world = "".join(body_xml(j, "    ") for j in children["ground"])
    xml = (
        '<mujoco model="twin">\n  <compiler angle="radian" autolimits="true"/>\n'
        f"  <worldbody>\n{world}{extra}  </worldbody>\n"
        f"  <equality>\n{equalities}  </equality>\n</mujoco>\n"
    )
    path.write_text(xml)
    return str(path)


# --------------------------------------------------------------------------------------------
# Double pendulum
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def pendulum(tmp_path_factory):
    d = tmp_path_factory.mktemp("pendulum")
    return build_osim(d / "pendulum.osim", [J1, J2]), d


def test_double_pendulum_twin_matches(pendulum):
    osim_path, d = pendulum
    mjcf = build_mjcf(d / "good.xml", [J1, J2])
    r = compare_kinematics(osim_path, mjcf, n_poses=N_POSES, seed=1)
    assert r.n_poses == N_POSES
    assert r.coordinates == ["q1", "q2"]
    assert set(r.bodies) == {"b1", "b2"}
    assert r.missing_bodies == [] and r.extra_bodies == []
    assert r.max_pos_error < TIGHT and r.max_ang_error < TIGHT
    assert r.com_max_error < TIGHT
    assert r.mass_opensim == pytest.approx(3.5, abs=1e-12)
    assert r.mass_mujoco == pytest.approx(r.mass_opensim, abs=1e-12)
    assert r.ok()
    for e in r.bodies.values():
        assert e.rms_pos <= e.max_pos < TIGHT
    # JSON-safe and readable.
    d2 = json.loads(json.dumps(r.to_dict()))
    assert d2["ok"] is True and d2["n_poses"] == N_POSES and "b2" in d2["bodies"]
    assert "b2" in r.summary() and "OK" in r.summary()
    table = format_table({"pendulum": r})
    assert "pendulum" in table.splitlines()[2] and "mass OpenSim" in table


@pytest.mark.parametrize(
    "mistake",
    [
        {"flip": ("q2",)},
        {"flip": ("q1",)},
        {"offset": ("b2", (0.0, 0.001, 0.0))},
        {"ground": np.eye(3)},
    ],
    ids=["axis-sign-q2", "axis-sign-q1", "offset-1mm", "no-y-to-z"],
)
def test_double_pendulum_wrong_twin_detected(pendulum, mistake):
    osim_path, d = pendulum
    mjcf = build_mjcf(d / "bad.xml", [J1, J2], **mistake)
    r = compare_kinematics(osim_path, mjcf, n_poses=N_POSES, seed=2)
    assert not r.ok()
    assert r.max_pos_error > 1e-4 or r.max_ang_error > np.deg2rad(0.05)
    assert r.worst_pose is not None and r.worst_pose.body in ("b1", "b2")
    assert "FAIL" in r.summary()
    if "offset" in mistake:  # a pure 1 mm shift of b2: b1 exact, b2 off by 1 mm in every pose
        assert r.bodies["b1"].max_pos < TIGHT
        assert r.bodies["b2"].max_pos == pytest.approx(1e-3, rel=1e-6)
        assert r.bodies["b2"].max_ang < TIGHT
    if "ground" in mistake:  # the default pose already shows it
        assert r.bodies["b1"].max_ang > 1.0


def test_missing_joint_raises(pendulum):
    osim_path, d = pendulum
    mjcf = build_mjcf(d / "renamed.xml", [J1, J2], rename={"q2": "knee"})
    with pytest.raises(MissingJointError, match="q2") as exc:
        compare_kinematics(osim_path, mjcf, n_poses=2)
    assert exc.value.missing == ["q2"]


def test_missing_and_extra_bodies(pendulum, tmp_path):
    osim_path, _ = pendulum
    # b2 absent from MuJoCo (its joint q2 too, so q2 is reported missing first) ...
    with pytest.raises(MissingJointError):
        compare_kinematics(osim_path, build_mjcf(tmp_path / "a.xml", [J1]), n_poses=1)
    # ... and a twin with an extra massless body and b2 renamed: reported, not ok.
    extra = '    <body name="marker" pos="0 0 1"/>\n'
    xml = build_mjcf(tmp_path / "b.xml", [J1, J2], extra=extra)
    (tmp_path / "b.xml").write_text((tmp_path / "b.xml").read_text().replace('name="b2"', 'name="shank"'))
    r = compare_kinematics(osim_path, xml, n_poses=3)
    assert r.missing_bodies == ["b2"]
    assert sorted(r.extra_bodies) == ["marker", "shank"]
    assert r.max_pos_error < TIGHT and r.com_max_error < TIGHT
    assert not r.ok()


def test_mujoco_load_failure_is_clear(pendulum, tmp_path):
    osim_path, _ = pendulum
    extra = '    <geom type="mesh" mesh="nomesh"/>\n'
    xml = build_mjcf(tmp_path / "m.xml", [J1, J2], extra=extra)
    asset = '<asset><mesh name="nomesh" file="missing.stl"/></asset>\n  <worldbody>'
    (tmp_path / "m.xml").write_text((tmp_path / "m.xml").read_text().replace("<worldbody>", asset))
    with pytest.raises(ValidationError, match="MuJoCo could not load"):
        compare_kinematics(osim_path, xml, n_poses=1)


# --------------------------------------------------------------------------------------------
# Coupled coordinates (a chain of two couplers) and a slider with a locked pin
# --------------------------------------------------------------------------------------------

# q2 = 0.5 q1^2 + 0.8 q1 + 0.1 ; q3 = -0.7 q2 + 0.2
POLY = (0.5, 0.8, 0.1)  # OpenSim PolynomialFunction: highest power first
LIN = (-0.7, 0.2)  # slope, intercept
# MuJoCo lists the equalities in the reverse of their dependency order on purpose.
COUPLER_EQ = (
    f'    <joint joint1="q3" joint2="q2" polycoef="{LIN[1]} {LIN[0]} 0 0 0"/>\n'
    f'    <joint joint1="q2" joint2="q1" polycoef="{POLY[2]} {POLY[1]} {POLY[0]} 0 0"/>\n'
)


@pytest.fixture(scope="module")
def coupled(tmp_path_factory):
    d = tmp_path_factory.mktemp("coupled")
    couplers = [
        ("q2", "q1", osim.PolynomialFunction(osim.Vector(list(POLY)))),
        ("q3", "q2", osim.LinearFunction(*LIN)),
    ]
    # q2 stays inside its range over q1's range, so OpenSim need not move q1 to assemble.
    j1 = J1[:-1] + ((-1.0, 0.6),)
    joints = [j1, J2, J3]
    return build_osim(d / "coupled.osim", joints, couplers=couplers), d, joints


def test_coupled_twin_matches(coupled):
    osim_path, d, joints = coupled
    mjcf = build_mjcf(d / "good.xml", joints, equalities=COUPLER_EQ)
    r = compare_kinematics(osim_path, mjcf, n_poses=N_POSES)
    assert r.coordinates == ["q1"]
    assert r.dependent_coordinates == ["q2", "q3"]
    assert r.max_pos_error < TIGHT and r.max_ang_error < TIGHT and r.com_max_error < TIGHT
    assert r.mass_mujoco == pytest.approx(r.mass_opensim, abs=1e-12)
    assert r.ok()
    wp = r.worst_pose.values
    assert wp["q2"] == pytest.approx(POLY[0] * wp["q1"] ** 2 + POLY[1] * wp["q1"] + POLY[2], abs=1e-10)


def test_coupled_wrong_coefficient_detected(coupled):
    osim_path, d, joints = coupled
    good_coef = f'polycoef="{LIN[1]} {LIN[0]} 0 0 0"'
    bad = COUPLER_EQ.replace(good_coef, f'polycoef="{LIN[1]} {LIN[0] * 1.01} 0 0 0"')
    assert bad != COUPLER_EQ
    r = compare_kinematics(osim_path, build_mjcf(d / "bad.xml", joints, equalities=bad), n_poses=N_POSES)
    assert r.bodies["b1"].max_pos < TIGHT and r.bodies["b2"].max_pos < TIGHT
    assert r.bodies["b3"].max_ang > np.deg2rad(0.05)
    assert not r.ok()


def test_coupled_missing_equality_detected(coupled):
    osim_path, d, joints = coupled
    r = compare_kinematics(osim_path, build_mjcf(d / "noeq.xml", joints), n_poses=10)
    assert not r.ok()


@pytest.fixture(scope="module")
def locked(tmp_path_factory):
    d = tmp_path_factory.mktemp("locked")
    joints = [SLIDE, J2, J3]
    return build_osim(d / "locked.osim", joints, locked=[("q2", 0.3)]), d, joints


def test_locked_twin_matches(locked):
    osim_path, d, joints = locked
    eq = '    <joint joint1="q2" polycoef="0.3 0 0 0 0"/>\n'
    r = compare_kinematics(osim_path, build_mjcf(d / "good.xml", joints, equalities=eq), n_poses=N_POSES,
                           progress=True)
    assert r.coordinates == ["tx", "q3"]
    assert r.locked_coordinates == ["q2"]
    assert r.max_pos_error < TIGHT and r.max_ang_error < TIGHT and r.com_max_error < TIGHT
    assert r.ok()


def test_locked_wrong_value_detected(locked):
    osim_path, d, joints = locked
    eq = '    <joint joint1="q2" polycoef="0.29 0 0 0 0"/>\n'
    r = compare_kinematics(osim_path, build_mjcf(d / "bad.xml", joints, equalities=eq), n_poses=5)
    assert r.bodies["b1"].max_pos < TIGHT
    assert r.bodies["b2"].max_ang == pytest.approx(0.01, abs=1e-9)
    assert not r.ok()


def test_format_table_several(pendulum, locked):
    osim_path, d = pendulum
    good = compare_kinematics(osim_path, build_mjcf(d / "t1.xml", [J1, J2]), n_poses=3)
    bad = compare_kinematics(osim_path, build_mjcf(d / "t2.xml", [J1, J2], flip=("q1",)), n_poses=3)
    lines = format_table({"good": good, "bad": bad}).splitlines()
    assert len(lines) == 4
    assert lines[2].startswith("good") and lines[2].rstrip().endswith("yes")
    assert lines[3].startswith("bad") and lines[3].rstrip().endswith("NO")


# --------------------------------------------------------------------------------------------
# pose_mujoco on its own
# --------------------------------------------------------------------------------------------

CHAIN = """
<mujoco>
  <compiler angle="radian"/>
  <worldbody>
    <body name="a"><joint name="j1" type="hinge" ref="0.2"/><geom size="0.1" mass="1"/>
      <body name="b" pos="0 0 1"><joint name="j2" type="hinge" axis="0 1 0" ref="-0.1"/><geom size="0.1"/>
        <body name="c" pos="0 0 1"><joint name="j3" type="slide" ref="0.05"/><geom size="0.1"/>
          <body name="d" pos="0 0 1"><joint name="j4" type="hinge"/><geom size="0.1"/></body>
        </body>
      </body>
    </body>
  </worldbody>
  <equality>
    <joint joint1="j3" joint2="j2" polycoef="0.01 0.5 -0.2 0.1 0.03"/>
    <joint joint1="j2" joint2="j1" polycoef="0.3 2 0.5 0 0"/>
    <joint joint1="j4" polycoef="0.7 0 0 0 0"/>
    <joint joint1="j4" joint2="j1" polycoef="9 0 0 0 0" active="false"/>
  </equality>
</mujoco>
"""


def test_pose_mujoco_resolves_equality_chain():
    m = mujoco.MjModel.from_xml_string(CHAIN)
    d = mujoco.MjData(m)
    plan = joint_equality_plan(m)
    assert [e.joint1 for e in plan].index("j2") < [e.joint1 for e in plan].index("j3")
    assert len(plan) == 3  # the inactive equality is ignored
    q1 = 0.4
    pose_mujoco(m, d, {"j1": q1}, plan=plan)
    x1 = q1 - 0.2
    q2 = -0.1 + 0.3 + 2 * x1 + 0.5 * x1**2
    x2 = q2 - (-0.1)
    q3 = 0.05 + 0.01 + 0.5 * x2 - 0.2 * x2**2 + 0.1 * x2**3 + 0.03 * x2**4
    assert d.qpos[0] == q1
    assert d.qpos[1] == pytest.approx(q2, abs=1e-14)
    assert d.qpos[2] == pytest.approx(q3, abs=1e-14)
    assert d.qpos[3] == pytest.approx(0.7, abs=1e-15)
    # Every equality holds, so MuJoCo's own constraint residuals vanish.
    mujoco.mj_forward(m, d)
    assert np.abs(d.efc_pos[d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY]).max() < 1e-12
    # Kinematics are fresh: body c sits where the chain puts it.
    assert np.isfinite(d.subtree_com[0]).all()
    ref = mujoco.MjData(m)
    ref.qpos[:] = d.qpos
    mujoco.mj_kinematics(m, ref)
    np.testing.assert_allclose(d.xpos, ref.xpos, atol=0)
    # Without a plan (computed on the fly) and with default values.
    pose_mujoco(m, d, {})
    assert d.qpos[0] == pytest.approx(0.2)
    assert d.qpos[1] == pytest.approx(-0.1 + 0.3)
    with pytest.raises(KeyError, match="nope"):
        pose_mujoco(m, d, {"nope": 1.0})


def test_pose_mujoco_cycle_raises():
    xml = CHAIN.replace('polycoef="0.7 0 0 0 0"', 'joint2="j3" polycoef="0 1 0 0 0"').replace(
        'joint1="j2" joint2="j1"', 'joint1="j2" joint2="j4"'
    )
    m = mujoco.MjModel.from_xml_string(xml)
    with pytest.raises(ValidationError, match="cyclic"):
        joint_equality_plan(m)


def test_rotation_angle_small_and_large():
    for a in (1e-12, 1e-6, 0.3, 3.0):
        r = _xyz((0.0, 0.0, a)) @ _xyz((0.2, -0.4, 0.1)).T @ _xyz((0.2, -0.4, 0.1))
        assert rotation_angle(r) == pytest.approx(a, rel=1e-9, abs=1e-15)
    assert rotation_angle(np.stack([np.eye(3), _rx(0.5)])).shape == (2,)
