"""Every OpenSim joint type, TransformAxis function and coordinate option, converted and checked.

Each test builds a small OpenSim model with the opensim API (bodies with mass, an off-centre
COM and a full inertia; joints with translated *and* rotated parent and child offset frames),
prints it into ``tmp_path``, converts it with :func:`o2m.convert.convert` and measures the
MuJoCo model against OpenSim with :func:`o2m.validate.compare_kinematics`.

* When every joint function is linear or constant, the MuJoCo model is exact: body frames
  agree to 1e-9 m and 1e-9 rad, total mass and whole-model COM to 1e-9.
* When a function is a spline, the converter fits a quartic and records it in the report's
  ``approximations`` with its worst error; the measured body errors must stay within that
  recorded error (times the lever arm for rotations) plus 1e-7.

The TransformAxis and coupler functions are written into the printed XML (the opensim
Python wrappers of ``setFunction`` take ownership of the function and crash on exit), so
each test uses exactly the XML a user's file would hold.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
import opensim as osim
import pytest
from lxml import etree

from o2m.convert.converter import convert
from o2m.transforms import OSIM_TO_MJ
from o2m.validate.kinematics import compare_kinematics
from tests.helpers import add_coupler, convert_options

osim.Logger.setLevelString("error")

EXACT = 1e-9
SLACK = 1e-7
N_POSES = 50
G = 9.80665

# ---------------------------------------------------------------------------------------------
# Model description
# ---------------------------------------------------------------------------------------------

#: name -> (mass kg, COM in the body frame m, inertia about the COM: xx yy zz xy xz yz kg m^2).
BODIES = {
    "b1": (2.0, (0.05, -0.2, 0.01), (0.030, 0.012, 0.028, 0.0015, -0.0008, 0.002)),
    "b2": (1.5, (-0.02, -0.15, 0.03), (0.020, 0.009, 0.021, -0.001, 0.0012, 0.0007)),
    "b3": (0.7, (0.01, -0.1, -0.02), (0.010, 0.004, 0.011, 0.0004, 0.0002, -0.0005)),
}

#: Offset frames of the 1st, 2nd and 3rd joint of a chain: (lp, op, lc, oc) - location and
#: body-fixed XYZ orientation of the parent frame in the parent body, then of the child frame
#: in the child body. All non-zero.
OFFSETS = [
    ((0.1, 0.8, -0.05), (0.3, -0.2, 0.5), (0.02, 0.3, 0.01), (0.1, 0.4, -0.3)),
    ((0.03, -0.4, 0.02), (-0.6, 0.2, 0.1), (0.01, 0.25, -0.01), (0.2, -0.1, 0.7)),
    ((0.0, -0.3, 0.04), (0.1, 0.5, -0.2), (0.01, 0.2, 0.03), (0.3, 0.2, -0.4)),
]

ROT_RANGE = (-1.2, 1.0)
TRANS_RANGE = (-0.2, 0.3)


@dataclass
class Coord:
    """Coordinate settings; None keeps OpenSim's default (the property is then not printed)."""

    name: str
    range: tuple[float, float] | None = None
    default: float | None = None
    clamped: bool | None = None
    locked: bool = False


@dataclass
class Axis:
    """One TransformAxis of a CustomJoint: ``function`` is the XML of its function element."""

    name: str  # rotation1..3, translation1..3
    axis: tuple[float, float, float]
    coord: str | None
    function: str


@dataclass
class JointSpec:
    name: str
    type: str
    parent: str
    child: str
    offsets: tuple
    coords: list[Coord] = field(default_factory=list)
    axes: list[Axis] = field(default_factory=list)  # CustomJoint only: all six


@dataclass
class CouplerSpec:
    name: str
    dependent: str
    independent: str
    function: str  # XML
    enforced: bool = True


# -- function XML -------------------------------------------------------------------------------


def _v(values) -> str:
    return " ".join(repr(float(v)) for v in np.ravel(values))


def linear(slope: float, intercept: float) -> str:
    return f'<LinearFunction name="function"><coefficients>{_v([slope, intercept])}</coefficients></LinearFunction>'


def constant(value: float) -> str:
    return f'<Constant name="function"><value>{value!r}</value></Constant>'


def xy_function(tag: str, x, y, extra: str = "") -> str:
    return f'<{tag} name="function">{extra}<x>{_v(x)}</x><y>{_v(y)}</y></{tag}>'


def gcv(x, y, half_order: int = 3) -> str:
    w = np.ones(len(x))
    return (f'<GCVSpline name="function"><half_order>{half_order}</half_order><error_variance>0</error_variance>'
            f"<x>{_v(x)}</x><y>{_v(y)}</y><weights>{_v(w)}</weights></GCVSpline>")


def multiplier(inner: str, scale: float) -> str:
    inner = inner.replace(' name="function"', "", 1)
    return (f'<MultiplierFunction name="function"><function>{inner}</function><scale>{scale!r}</scale>'
            "</MultiplierFunction>")


def polynomial(coefs_high_first) -> str:
    return (f'<PolynomialFunction name="function"><coefficients>{_v(coefs_high_first)}</coefficients>'
            "</PolynomialFunction>")


IDENTITY = linear(1.0, 0.0)
ZERO = constant(0.0)

# Knee-like data (OpenSim gait models): translations of the tibia in the femur frame (m) and a
# small coupled ab/adduction (rad) against the knee angle (rad).
KNEE_RANGE = (-2.0944, 0.174533)
KNEE_X = [-2.0944, -1.74533, -1.39626, -1.0472, -0.698132, -0.349066, -0.174533, 0.197344, 0.337395,
          0.490178, 1.52146, 2.0944]
KNEE_TX = [-0.0032, 0.00179, 0.00411, 0.0041, 0.00212, -0.001, -0.0031, -0.005227, -0.005435, -0.005574,
           -0.005435, -0.00525]
KNEE_TY = [-0.4226, -0.4082, -0.399, -0.3976, -0.3966, -0.3953, -0.396, -0.3966, -0.3976, -0.399, -0.4082,
           -0.4226]
KNEE_RX = [0.05 * math.sin(1.3 * x) for x in KNEE_X]


def knee_axes(coord: str, kind: str) -> list[Axis]:
    """A knee: rotation1 = identity of ``coord`` about z; rotation2 (x) and translation1-2 are
    functions of ``coord`` of type ``kind``; rotation3 and translation3 zero."""

    def f(x, y):
        if kind in ("SimmSpline", "NaturalCubicSpline", "PiecewiseLinearFunction"):
            return xy_function(kind, x, y)
        if kind == "GCVSpline":
            return gcv(x, y)  # half_order 3: quintic
        if kind == "GCVSpline-cubic":
            return gcv(x, y, half_order=2)
        if kind == "MultiplierFunction":
            return multiplier(xy_function("SimmSpline", x, np.asarray(y) / 1.5), 1.5)
        raise ValueError(kind)

    return [
        Axis("rotation1", (0.0, 0.0, 1.0), coord, IDENTITY),
        Axis("rotation2", (1.0, 0.0, 0.0), coord, f(KNEE_X, KNEE_RX)),
        Axis("rotation3", (0.0, 1.0, 0.0), None, ZERO),
        Axis("translation1", (1.0, 0.0, 0.0), coord, f(KNEE_X, KNEE_TX)),
        Axis("translation2", (0.0, 1.0, 0.0), coord, f(KNEE_X, KNEE_TY)),
        Axis("translation3", (0.0, 0.0, 1.0), None, ZERO),
    ]


# -- building ---------------------------------------------------------------------------------

_AXIS_INDEX = {"rotation1": 0, "rotation2": 1, "rotation3": 2, "translation1": 3, "translation2": 4,
               "translation3": 5}


def build_model(path: Path, joints: list[JointSpec], *, couplers: list[CouplerSpec] = (),
                bodies: dict | None = None, gravity=(0.0, -G, 0.0)) -> str:
    """Print an OpenSim model made of ``joints`` (and couplers) to ``path``; returns the path."""
    bodies = BODIES if bodies is None else bodies
    m = osim.Model()
    m.setName(path.stem)
    m.setGravity(osim.Vec3(*gravity))
    objs = {}
    for j in joints:
        mass, com, inertia = bodies[j.child]
        objs[j.child] = osim.Body(j.child, mass, osim.Vec3(*com), osim.Inertia(*inertia))
        m.addBody(objs[j.child])
    for j in joints:
        parent = m.getGround() if j.parent == "ground" else objs[j.parent]
        lp, op, lc, oc = (osim.Vec3(*v) for v in j.offsets)
        if j.type == "CustomJoint":
            assert len(j.axes) == 6
            st = osim.SpatialTransform()
            for ax in j.axes:
                ta = st.updTransformAxis(_AXIS_INDEX[ax.name])
                names = osim.ArrayStr()
                if ax.coord:
                    names.append(ax.coord)
                ta.setCoordinateNames(names)
                ta.setAxis(osim.Vec3(*ax.axis))
                ta.set_function(osim.LinearFunction(1.0, 0.0) if ax.coord else osim.Constant(0.0))
            joint = osim.CustomJoint(j.name, parent, lp, op, objs[j.child], lc, oc, st)
        else:
            joint = getattr(osim, j.type)(j.name, parent, lp, op, objs[j.child], lc, oc)
        m.addJoint(joint)  # a CustomJoint creates its coordinates here
        existing = [joint.get_coordinates(i).getName() for i in range(joint.numCoordinates())]
        assert len(existing) == len(j.coords), (j.name, existing)
        for i, c in enumerate(j.coords):
            coord = joint.upd_coordinates(existing.index(c.name) if j.type == "CustomJoint" else i)
            coord.setName(c.name)
            if c.range is not None:
                coord.setRangeMin(c.range[0])
                coord.setRangeMax(c.range[1])
            if c.default is not None:
                coord.setDefaultValue(c.default)
            if c.clamped is not None:
                coord.setDefaultClamped(c.clamped)
            if c.locked:
                coord.setDefaultLocked(True)
    for cp in couplers:
        add_coupler(m, cp.name, cp.independent, cp.dependent, osim.LinearFunction(1.0, 0.0))
    m.finalizeConnections()
    m.printToXML(str(path))
    _write_functions(path, joints, couplers)
    return str(path)


def _write_functions(path: Path, joints: list[JointSpec], couplers: list[CouplerSpec]) -> None:
    """Put the XML functions of the specs into the printed document."""
    tree = etree.parse(str(path))
    model = tree.getroot().find("Model")
    for j in joints:
        for ax in j.axes:
            (ta,) = model.xpath(f"JointSet/objects/CustomJoint[@name='{j.name}']/SpatialTransform/"
                                f"TransformAxis[@name='{ax.name}']")
            for ch in list(ta):
                if isinstance(ch.tag, str) and ch.tag[:1].isupper():
                    ta.remove(ch)
            ta.append(etree.fromstring(ax.function))
    for cp in couplers:
        (holder,) = model.xpath(f"ConstraintSet/objects/CoordinateCouplerConstraint[@name='{cp.name}']/"
                                "coupled_coordinates_function")
        for ch in list(holder):
            holder.remove(ch)
        holder.append(etree.fromstring(cp.function))
        if not cp.enforced:
            flag = etree.SubElement(holder.getparent(), "isEnforced")
            flag.text = "false"
    tree.write(str(path), xml_declaration=True, encoding="UTF-8")


# -- converting and checking --------------------------------------------------------------------


@dataclass
class Result:
    osim: str
    conv: object  # o2m.convert.Conversion
    rep: object  # o2m.validate.KinematicsReport
    mj: mujoco.MjModel


def run(osim_path: str, tmp_path: Path, *, n_poses: int = N_POSES, seed: int = 0) -> Result:
    conv = convert(osim_path, tmp_path / "out", convert_options())
    rep = compare_kinematics(osim_path, conv.xml, n_poses=n_poses, seed=seed)
    assert rep.n_poses == n_poses and rep.skipped_poses == 0
    # an intermediate body carries a joint's translations where its spline couplings need more dofs
    assert rep.missing_bodies == [] and all(b.endswith("_couplings") for b in rep.extra_bodies)
    r = Result(osim_path, conv, rep, mujoco.MjModel.from_xml_path(str(conv.xml)))
    assert_inertia(r)
    return r


def assert_inertia(r: Result) -> None:
    """Each MuJoCo body's COM and inertia tensor (about the COM, body frame) are OpenSim's,
    except where the report records an inertia approximation."""
    changed = {a.name for a in r.conv.report.approximations if a.units == "kg m^2"}
    model = osim.Model(r.osim)
    bodies = model.getBodySet()
    for i in range(bodies.getSize()):
        b = bodies.get(i)
        bid = mujoco.mj_name2id(r.mj, mujoco.mjtObj.mjOBJ_BODY, b.getName())
        np.testing.assert_allclose(r.mj.body_ipos[bid], b.getMassCenter().to_numpy(), rtol=0, atol=1e-15)
        if b.getName() in changed:
            continue
        inertia = b.getInertia()
        (ixx, iyy, izz), (ixy, ixz, iyz) = inertia.getMoments().to_numpy(), inertia.getProducts().to_numpy()
        want = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, r.mj.body_iquat[bid])
        rot = rot.reshape(3, 3)
        got = rot @ np.diag(r.mj.body_inertia[bid]) @ rot.T
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * max(1.0, np.abs(want).max()),
                                   err_msg=b.getName())


def assert_exact(r: Result, *, allow_approx: bool = False) -> None:
    """Exactly representable model: body frames, COM and mass to 1e-9."""
    rep = r.rep
    assert rep.max_pos_error <= EXACT, rep.summary()
    assert rep.max_ang_error <= EXACT, rep.summary()
    assert rep.com_max_error <= EXACT, rep.summary()
    assert abs(rep.mass_mujoco - rep.mass_opensim) <= EXACT
    if not allow_approx:
        assert r.conv.report.approximations == []


def lever_arm(joints: list[JointSpec], extra: float = 0.5) -> float:
    """Upper bound (m) on the distance from any joint centre to any body origin or COM."""
    total = extra
    for j in joints:
        lp, _op, lc, _oc = j.offsets
        total += float(np.linalg.norm(lp) + np.linalg.norm(lc))
    return total + max(float(np.linalg.norm(b[1])) for b in BODIES.values())


def assert_within_recorded(r: Result, lever: float) -> None:
    """Measured errors no more than the recorded approximation errors allow."""
    approx = [a for a in r.conv.report.approximations if a.units in ("rad", "m")]
    rot = sum(a.max_error for a in approx if a.units == "rad")
    trans = sum(a.max_error for a in approx if a.units == "m")
    rep = r.rep
    assert rep.max_ang_error <= rot + SLACK, (rot, rep.summary())
    assert rep.max_pos_error <= trans + lever * rot + SLACK, (trans, rot, rep.summary())
    assert rep.com_max_error <= trans + lever * rot + SLACK, (trans, rot, rep.summary())
    assert abs(rep.mass_mujoco - rep.mass_opensim) <= EXACT


def jid(model: mujoco.MjModel, name: str) -> int:
    i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
    assert i >= 0, f"no MuJoCo joint {name}"
    return i


def qpos0(model: mujoco.MjModel, name: str) -> float:
    return float(model.qpos0[model.jnt_qposadr[jid(model, name)]])


# ---------------------------------------------------------------------------------------------
# Every joint type
# ---------------------------------------------------------------------------------------------

#: Coordinate kinds of each joint type, in OpenSim's coordinate order.
KINDS = {
    "PinJoint": "r",
    "SliderJoint": "t",
    "UniversalJoint": "rr",
    "BallJoint": "rrr",
    "GimbalJoint": "rrr",
    "FreeJoint": "rrrttt",
    "PlanarJoint": "rtt",
    "WeldJoint": "",
}


def typed_joint(jtype: str, name: str, parent: str, child: str, offsets, defaults=None) -> JointSpec:
    if jtype == "CustomJoint":
        names = [f"{name}_{s}" for s in ("ra", "rb", "rc", "tx", "ty", "tz")]
        axes = [
            Axis("rotation1", (0.3, 0.2, 1.0), names[0], IDENTITY),
            Axis("rotation2", (1.0, 0.0, 0.2), names[1], IDENTITY),
            Axis("rotation3", (0.0, 1.0, 0.0), names[2], IDENTITY),
            Axis("translation1", (1.0, 0.0, 0.0), names[3], IDENTITY),
            Axis("translation2", (0.2, 1.0, 0.0), names[4], IDENTITY),
            Axis("translation3", (0.0, 0.1, 1.0), names[5], IDENTITY),
        ]
        kinds = "rrrttt"
    else:
        kinds = KINDS[jtype]
        names = [f"{name}_{k}{i}" for i, k in enumerate(kinds)]
        axes = []
    coords = [Coord(n, ROT_RANGE if k == "r" else TRANS_RANGE, None if defaults is None else defaults[i])
              for i, (n, k) in enumerate(zip(names, kinds, strict=True))]
    return JointSpec(name, jtype, parent, child, offsets, coords, axes)


ALL_TYPES = [*KINDS, "CustomJoint"]


@pytest.mark.parametrize("jtype", ALL_TYPES)
def test_joint_type(jtype, tmp_path):
    """ground -T-> b1 -T-> b2 -Pin-> b3, T every joint type: exact, no approximation."""
    joints = [
        typed_joint(jtype, "j1", "ground", "b1", OFFSETS[0]),
        typed_joint(jtype, "j2", "b1", "b2", OFFSETS[1]),
        typed_joint("PinJoint", "j3", "b2", "b3", OFFSETS[2]),
    ]
    r = run(build_model(tmp_path / f"{jtype}.osim", joints), tmp_path)
    assert_exact(r)
    coords = [c.name for j in joints for c in j.coords]
    assert sorted(r.rep.coordinates) == sorted(coords)
    # One MuJoCo hinge/slide per coordinate, carrying its name; nothing else moves.
    names = [mujoco.mj_id2name(r.mj, mujoco.mjtObj.mjOBJ_JOINT, i) for i in range(r.mj.njnt)]
    assert sorted(names) == sorted(coords)
    assert r.mj.neq == 0
    for j in joints:
        for c, k in zip(j.coords, KINDS.get(j.type, "rrrttt"), strict=True):
            want = mujoco.mjtJoint.mjJNT_HINGE if k == "r" else mujoco.mjtJoint.mjJNT_SLIDE
            assert r.mj.jnt_type[jid(r.mj, c.name)] == want


# ---------------------------------------------------------------------------------------------
# CustomJoint functions
# ---------------------------------------------------------------------------------------------


def test_custom_constant_in_middle_of_rotations(tmp_path):
    """rotation2 Constant 0.3 rad between two moving rotations, and a constant translation."""
    axes = [
        Axis("rotation1", (0.0, 0.0, 1.0), "c_a", IDENTITY),
        Axis("rotation2", (1.0, 0.0, 0.0), None, constant(0.3)),
        Axis("rotation3", (0.0, 1.0, 0.0), "c_b", IDENTITY),
        Axis("translation1", (1.0, 0.0, 0.0), None, constant(0.05)),
        Axis("translation2", (0.0, 1.0, 0.0), "c_t", IDENTITY),
        Axis("translation3", (0.0, 0.0, 1.0), None, constant(-0.02)),
    ]
    coords = [Coord("c_a", ROT_RANGE), Coord("c_b", ROT_RANGE), Coord("c_t", TRANS_RANGE)]
    joints = [
        JointSpec("j1", "CustomJoint", "ground", "b1", OFFSETS[0], coords, axes),
        typed_joint("PinJoint", "j2", "b1", "b2", OFFSETS[1]),
    ]
    r = run(build_model(tmp_path / "const.osim", joints), tmp_path)
    assert_exact(r)
    assert r.mj.njnt == 4 and r.mj.neq == 0


def test_custom_linear_slope(tmp_path):
    """One coordinate: identity rotation, a LinearFunction rotation (slope 0.5, offset 0.1) and
    a linear translation; a second coordinate drives a translation with slope -2."""
    axes = [
        Axis("rotation1", (0.0, 0.0, 1.0), "c_a", IDENTITY),
        Axis("rotation2", (1.0, 0.0, 0.0), "c_a", linear(0.5, 0.1)),
        Axis("rotation3", (0.0, 1.0, 0.0), None, ZERO),
        Axis("translation1", (1.0, 0.0, 0.0), "c_a", linear(0.02, 0.01)),
        Axis("translation2", (0.0, 1.0, 0.0), "c_t", IDENTITY),
        Axis("translation3", (0.0, 0.0, 1.0), "c_t", linear(-2.0, 0.0)),
    ]
    coords = [Coord("c_a", ROT_RANGE), Coord("c_t", TRANS_RANGE)]
    joints = [
        JointSpec("j1", "CustomJoint", "ground", "b1", OFFSETS[0], coords, axes),
        typed_joint("PinJoint", "j2", "b1", "b2", OFFSETS[1]),
    ]
    r = run(build_model(tmp_path / "linear.osim", joints), tmp_path)
    assert_exact(r)
    rel = {j.name: j.relation for j in r.conv.report.joints}
    assert rel["c_a"] == "coordinate" and rel["c_t"] == "coordinate"
    assert sorted(v for k, v in rel.items() if k not in ("c_a", "c_t", "j2_r0")) == ["linear"] * 3


def test_custom_polynomial(tmp_path):
    """PolynomialFunction (cubic and quadratic): a quartic represents it exactly."""
    axes = [
        Axis("rotation1", (0.0, 0.0, 1.0), "knee", IDENTITY),
        Axis("rotation2", (1.0, 0.0, 0.0), "knee", polynomial([0.02, -0.01, 0.05])),
        Axis("rotation3", (0.0, 1.0, 0.0), None, ZERO),
        Axis("translation1", (1.0, 0.0, 0.0), "knee", polynomial([0.001, -0.002, 0.003, 0.004])),
        Axis("translation2", (0.0, 1.0, 0.0), "knee", polynomial([0.01, 0.0, -0.4])),
        Axis("translation3", (0.0, 0.0, 1.0), None, ZERO),
    ]
    joints = [
        typed_joint("PinJoint", "j1", "ground", "b1", OFFSETS[0]),
        JointSpec("knee", "CustomJoint", "b1", "b2", OFFSETS[1], [Coord("knee", KNEE_RANGE)], axes),
    ]
    r = run(build_model(tmp_path / "poly.osim", joints), tmp_path)
    assert_exact(r, allow_approx=True)
    for a in r.conv.report.approximations:
        assert a.max_error <= 1e-12, a


def test_custom_identity_not_first(tmp_path):
    """The coordinate's identity axis comes after an axis it drives with slope 2."""
    axes = [
        Axis("rotation1", (0.0, 0.0, 1.0), "c_a", linear(2.0, -0.1)),
        Axis("rotation2", (1.0, 0.0, 0.0), "c_a", IDENTITY),
        Axis("rotation3", (0.0, 1.0, 0.0), "c_b", IDENTITY),
        Axis("translation1", (1.0, 0.0, 0.0), None, ZERO),
        Axis("translation2", (0.0, 1.0, 0.0), "c_b", linear(0.1, 0.0)),
        Axis("translation3", (0.0, 0.0, 1.0), None, ZERO),
    ]
    joints = [
        JointSpec("j1", "CustomJoint", "ground", "b1", OFFSETS[0], [Coord("c_a", ROT_RANGE), Coord("c_b", ROT_RANGE)],
                  axes),
        typed_joint("PinJoint", "j2", "b1", "b2", OFFSETS[1]),
    ]
    r = run(build_model(tmp_path / "late_identity.osim", joints), tmp_path)
    assert_exact(r)
    rec = {j.name: j for j in r.conv.report.joints}
    assert rec["c_a"].axis == "rotation2" and rec["j1_rotation1"].relation == "linear"


def test_custom_linear_in_disguise(tmp_path):
    """Splines through collinear points, a 2-point PiecewiseLinearFunction and a
    MultiplierFunction of a LinearFunction are linear: exact, no quartic fit."""
    x = np.linspace(-2.5, 0.5, 6)
    axes = [
        Axis("rotation1", (0.0, 0.0, 1.0), "knee", IDENTITY),
        Axis("rotation2", (1.0, 0.0, 0.0), "knee", xy_function("SimmSpline", x, 0.1 * x + 0.02)),
        Axis("rotation3", (0.0, 1.0, 0.0), "knee", multiplier(linear(0.3, 0.01), -0.5)),
        Axis("translation1", (1.0, 0.0, 0.0), "knee", xy_function("PiecewiseLinearFunction", [-3, 1], [0.01, -0.02])),
        Axis("translation2", (0.0, 1.0, 0.0), "knee", xy_function("NaturalCubicSpline", x, -0.01 * x - 0.4)),
        Axis("translation3", (0.0, 0.0, 1.0), None, multiplier(constant(0.02), 1.5)),
    ]
    joints = [
        typed_joint("PinJoint", "j1", "ground", "b1", OFFSETS[0]),
        JointSpec("knee", "CustomJoint", "b1", "b2", OFFSETS[1], [Coord("knee", KNEE_RANGE)], axes),
    ]
    r = run(build_model(tmp_path / "disguise.osim", joints), tmp_path)
    assert_exact(r)
    assert sorted(j.relation for j in r.conv.report.joints if j.opensim_joint == "knee") == (
        ["coordinate"] + ["linear"] * 4)


def _steps_cleanly(model: mujoco.MjModel, seconds: float = 0.5) -> None:
    """Falls under gravity for ``seconds`` without a NaN or a solver warning."""
    data = mujoco.MjData(model)
    for _ in range(int(seconds / model.opt.timestep)):
        mujoco.mj_step(model, data)
    assert np.all(np.isfinite(data.qpos)) and not data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number


def test_mirrored_coordinates(tmp_path):
    """Coordinates that reach their only axes through -q + c (the left side of a mirrored model):
    their joints turn and slide about reversed axes and still carry the coordinates' values,
    exactly, with no extra joint or equality."""
    axes = [
        Axis("rotation1", (0.0, 0.0, 1.0), "c_a", linear(-1.0, 0.2)),
        Axis("rotation2", (1.0, 0.0, 0.0), "c_b", linear(-1.0, 0.0)),
        Axis("rotation3", (0.0, 1.0, 0.0), None, ZERO),
        Axis("translation1", (1.0, 0.0, 0.0), None, ZERO),
        Axis("translation2", (0.0, 1.0, 0.0), "c_t", linear(-1.0, 0.05)),
        Axis("translation3", (0.0, 0.0, 1.0), None, ZERO),
    ]
    coords = [Coord("c_a", ROT_RANGE, default=0.3), Coord("c_b", ROT_RANGE), Coord("c_t", TRANS_RANGE)]
    joints = [
        JointSpec("j1", "CustomJoint", "ground", "b1", OFFSETS[0], coords, axes),
        typed_joint("PinJoint", "j2", "b1", "b2", OFFSETS[1]),
    ]
    r = run(build_model(tmp_path / "mirrored.osim", joints), tmp_path)
    assert_exact(r)
    rel = {j.name: j.relation for j in r.conv.report.joints}
    assert rel["c_a"] == rel["c_b"] == rel["c_t"] == "coordinate (mirrored)"
    assert r.mj.njnt == 4 and r.mj.neq == 0
    assert qpos0(r.mj, "c_a") == pytest.approx(0.3)
    _steps_cleanly(r.mj)


@pytest.mark.parametrize("second", ["none", "spline"])
def test_coordinate_through_functions_only(second, tmp_path):
    """A coordinate that moves its joint's axes only through other functions (MoBL-ARMS's wrist:
    half the flexion on one axis; here a slope-0.5 line, and a spline on a second axis): its
    MuJoCo joint still carries its value, a second joint on the same axis adds f(q) - q, and the
    frames match OpenSim (exactly where the functions are linear)."""
    x = np.linspace(-1.3, 1.1, 7)
    spline = xy_function("SimmSpline", x, 0.3 * np.sin(x))
    axes = [
        Axis("rotation1", (0.0, 0.0, 1.0), "c_a", linear(0.5, 0.1)),
        Axis("rotation2", (1.0, 0.0, 0.0), "c_a" if second == "spline" else None,
             spline if second == "spline" else ZERO),
        Axis("rotation3", (0.0, 1.0, 0.0), None, ZERO),
        Axis("translation1", (1.0, 0.0, 0.0), "c_t", linear(2.0, 0.0)),
        Axis("translation2", (0.0, 1.0, 0.0), None, ZERO),
        Axis("translation3", (0.0, 0.0, 1.0), None, ZERO),
    ]
    coords = [Coord("c_a", ROT_RANGE, default=0.2), Coord("c_t", TRANS_RANGE)]
    joints = [
        JointSpec("j1", "CustomJoint", "ground", "b1", OFFSETS[0], coords, axes),
        typed_joint("PinJoint", "j2", "b1", "b2", OFFSETS[1]),
    ]
    r = run(build_model(tmp_path / "through.osim", joints), tmp_path)
    if second == "none":
        assert_exact(r, allow_approx=True)
        assert {a.what.split("'")[1] for a in r.conv.report.approximations} == {"j1_rotation1", "j1_translation1"}
    else:
        assert_within_recorded(r, lever_arm(joints))
    rec = {j.name: j for j in r.conv.report.joints}
    assert rec["c_a"].relation == rec["c_t"].relation == "coordinate (complement)"
    assert rec["c_a"].axis == "rotation1" and rec["j1_rotation1"].driven_by == "c_a"
    assert rec["j1_rotation1"].relation == "linear" and rec["j1_translation1"].relation == "linear"
    assert qpos0(r.mj, "c_a") == pytest.approx(0.2)
    # the coordinate joint and its complement share axis and anchor, so their angles add
    a, b = jid(r.mj, "c_a"), jid(r.mj, "j1_rotation1")
    assert np.allclose(r.mj.jnt_axis[a], r.mj.jnt_axis[b]) and np.allclose(r.mj.jnt_pos[a], r.mj.jnt_pos[b])
    _steps_cleanly(r.mj)


def test_coordinate_through_a_bent_spline_gets_extra_joints(tmp_path):
    """A coordinate that reaches its only axis through a spline no quartic follows (a patella's
    tilt against its knee-driven coordinate: a sharp bend): the complement joint, which adds
    f(q) - q, is planned as the skeleton's couplings are (inner and outer joints), so the body
    turns within 0.05 degrees of OpenSim where a plain quartic is off by a degree or more."""
    x = np.linspace(ROT_RANGE[0], ROT_RANGE[1], 9)
    bent = xy_function("SimmSpline", x, 0.6 * x + 0.25 * np.tanh(6.0 * (x + 0.3)))
    axes = [
        Axis("rotation1", (0.0, 0.0, 1.0), "c_a", bent),
        Axis("rotation2", (1.0, 0.0, 0.0), None, ZERO),
        Axis("rotation3", (0.0, 1.0, 0.0), None, ZERO),
        Axis("translation1", (1.0, 0.0, 0.0), None, ZERO),
        Axis("translation2", (0.0, 1.0, 0.0), None, ZERO),
        Axis("translation3", (0.0, 0.0, 1.0), None, ZERO),
    ]
    joints = [
        JointSpec("j1", "CustomJoint", "ground", "b1", OFFSETS[0], [Coord("c_a", ROT_RANGE, default=0.2)], axes),
        typed_joint("PinJoint", "j2", "b1", "b2", OFFSETS[1]),
    ]
    r = run(build_model(tmp_path / "bent.osim", joints), tmp_path)
    rec = {j.name: j for j in r.conv.report.joints}
    assert rec["c_a"].relation == "coordinate (complement)"
    assert rec["j1_rotation1"].relation.startswith("quartic fit + ")
    fit = next(a for a in r.conv.report.approximations if "'j1_rotation1'" in a.what)
    plain = float(re.search(r"a plain quartic: ([0-9.e+-]+) rad", f"{fit.what} {fit.detail}").group(1))
    assert fit.max_error < 0.1 * plain and np.degrees(plain) > 1.0
    assert r.rep.max_ang_error <= 0.05, r.rep.summary()
    assert_within_recorded(r, lever_arm(joints))
    _steps_cleanly(r.mj)


def test_zero_width_range_coordinate(tmp_path):
    """A coordinate whose range has no width still has its identity axis recognised."""
    axes = [
        Axis("rotation1", (0.0, 0.0, 1.0), "c_a", IDENTITY),
        Axis("rotation2", (1.0, 0.0, 0.0), None, ZERO),
        Axis("rotation3", (0.0, 1.0, 0.0), None, ZERO),
        Axis("translation1", (1.0, 0.0, 0.0), None, ZERO),
        Axis("translation2", (0.0, 1.0, 0.0), None, ZERO),
        Axis("translation3", (0.0, 0.0, 1.0), None, ZERO),
    ]
    joints = [JointSpec("j1", "CustomJoint", "ground", "b1", OFFSETS[0], [Coord("c_a", (0.4, 0.4), default=0.4)],
                        axes)]
    conv = convert(build_model(tmp_path / "flat.osim", joints), tmp_path / "out", convert_options())
    assert {j.name: j.relation for j in conv.report.joints}["c_a"] == "coordinate"


def test_nested_offset_frames_and_joint_order(tmp_path):
    """A joint whose parent is an offset frame of an offset frame on a body (component paths
    '..' and '/bodyset/b1/f1'), a child offset frame owned by the child body, and a JointSet
    listing the child joint before its parent."""
    m = osim.Model()
    m.setName("nested")
    m.setGravity(osim.Vec3(0, -G, 0))
    bodies = {n: osim.Body(n, BODIES[n][0], osim.Vec3(*BODIES[n][1]), osim.Inertia(*BODIES[n][2]))
              for n in ("b1", "b2")}
    for b in bodies.values():
        m.addBody(b)

    def frame(name, parent, owner, t, o):
        f = osim.PhysicalOffsetFrame()
        f.setName(name)
        f.setParentFrame(parent)
        f.set_translation(osim.Vec3(*t))
        f.set_orientation(osim.Vec3(*o))
        owner.addComponent(f)
        return f

    f1 = frame("f1", bodies["b1"], bodies["b1"], (0.1, -0.2, 0.3), (0.3, 0.2, -0.1))
    f2 = frame("f2", f1, bodies["b1"], (-0.1, 0.05, 0.02), (-0.3, 0.5, 0.1))
    g1 = frame("g1", bodies["b2"], bodies["b2"], (0.02, 0.2, -0.01), (0.4, -0.2, 0.6))
    j2 = osim.PinJoint("j2", f2, g1)
    m.addJoint(j2)  # before j1, which connects its parent body
    j2.upd_coordinates(0).setName("q2")
    lp, op, lc, oc = (osim.Vec3(*v) for v in OFFSETS[0])
    j1 = osim.GimbalJoint("j1", m.getGround(), lp, op, bodies["b1"], lc, oc)
    m.addJoint(j1)
    m.finalizeConnections()
    path = tmp_path / "nested.osim"
    m.printToXML(str(path))
    assert "<socket_parent>..</socket_parent>" in path.read_text()
    r = run(str(path), tmp_path)
    assert_exact(r)


SPLINES = ["SimmSpline", "NaturalCubicSpline", "GCVSpline", "GCVSpline-cubic", "PiecewiseLinearFunction",
           "MultiplierFunction"]


@pytest.mark.parametrize("kind", SPLINES)
def test_custom_knee_splines(kind, tmp_path):
    """A knee: one coordinate drives an identity rotation, a spline rotation and two spline
    translations. Each spline axis is a quartic fit recorded with its error; the body errors
    stay within it."""
    joints = [
        typed_joint("PinJoint", "hip", "ground", "b1", OFFSETS[0]),
        JointSpec("knee", "CustomJoint", "b1", "b2", OFFSETS[1], [Coord("knee", KNEE_RANGE)],
                  knee_axes("knee", kind)),
        typed_joint("PinJoint", "ankle", "b2", "b3", OFFSETS[2]),
    ]
    r = run(build_model(tmp_path / f"knee_{kind}.osim", joints), tmp_path)
    check_knee_fits(r, joints)


def check_knee_fits(r: Result, joints: list[JointSpec], max_recorded: float | None = 2e-3) -> None:
    fits = {j.name: j for j in r.conv.report.joints if j.relation.startswith("quartic fit")}
    assert set(fits) == {"knee_rotation2", "knee_translation1", "knee_translation2"}
    assert all(j.driven_by == "knee" for j in fits.values())
    approx = r.conv.report.approximations
    assert len(approx) == 3
    assert sorted(a.units for a in approx) == ["m", "m", "rad"]
    for a in approx:
        assert 0 < a.max_error < (max_recorded or np.inf), a
    assert_within_recorded(r, lever_arm(joints))
    # The check has bite: the spline is not reproduced exactly.
    assert r.rep.max_pos_error > EXACT


def test_custom_knee_splines_default_range(tmp_path):
    """The knee of test_custom_knee_splines with no <range> (OpenSim: [-10, 10] rad)."""
    joints = [
        typed_joint("PinJoint", "hip", "ground", "b1", OFFSETS[0]),
        JointSpec("knee", "CustomJoint", "b1", "b2", OFFSETS[1], [Coord("knee")], knee_axes("knee", "SimmSpline")),
    ]
    r = run(build_model(tmp_path / "knee_norange.osim", joints), tmp_path)
    check_knee_fits(r, joints, max_recorded=None)  # a quartic over [-10, 10] rad is poor, but recorded


# ---------------------------------------------------------------------------------------------
# Constraints and coordinate options
# ---------------------------------------------------------------------------------------------

SPLINE_X = np.linspace(-1.2, 1.0, 7)


@pytest.mark.parametrize("case", ["linear", "chained-linear", "spline", "custom-spline"])
def test_coordinate_coupler(case, tmp_path):
    """CoordinateCouplerConstraint: q2 (pin) and t3 (slider) follow q1. In "custom-spline" j2 is
    a knee whose coordinate (coupled linearly to q1, as a patella's) drives spline axes."""
    joints = [
        typed_joint("PinJoint", "j1", "ground", "b1", OFFSETS[0]),
        typed_joint("PinJoint", "j2", "b1", "b2", OFFSETS[1]),
        typed_joint("SliderJoint", "j3", "b2", "b3", OFFSETS[2]),
    ]
    if case == "custom-spline":
        joints[1] = JointSpec("j2", "CustomJoint", "b1", "b2", OFFSETS[1], [Coord("j2_r0", KNEE_RANGE)],
                              knee_axes("j2_r0", "SimmSpline"))
    q1, q2, t3 = "j1_r0", "j2_r0", "j3_t0"
    if case == "linear":
        couplers = [CouplerSpec("c2", q2, q1, linear(0.5, 0.1)), CouplerSpec("c3", t3, q1, linear(-0.1, 0.02))]
    elif case == "chained-linear":
        couplers = [CouplerSpec("c2", q2, q1, linear(0.5, 0.1)), CouplerSpec("c3", t3, q2, linear(-0.1, 0.02))]
    elif case == "custom-spline":
        couplers = [CouplerSpec("c2", q2, q1, linear(0.5, -0.5)), CouplerSpec("c3", t3, q1, linear(-0.1, 0.02))]
    else:
        couplers = [
            CouplerSpec("c2", q2, q1, xy_function("SimmSpline", SPLINE_X, 0.6 * np.sin(2 * SPLINE_X))),
            CouplerSpec("c3", t3, q1, xy_function("SimmSpline", SPLINE_X, 0.05 * np.cos(3 * SPLINE_X))),
        ]
    r = run(build_model(tmp_path / f"coupler_{case}.osim", joints, couplers=couplers), tmp_path)
    assert r.rep.coordinates == [q1]
    assert sorted(r.rep.dependent_coordinates) == sorted([q2, t3])
    # The dependent coordinates are MuJoCo joints of their own name, driven by joint equalities.
    rec = {j.name: j for j in r.conv.report.joints}
    assert rec[q2].coordinate == q2 and rec[t3].coordinate == t3
    assert rec[q2].driven_by == q1 and rec[t3].driven_by == q1
    extra = [j for j in r.conv.report.joints if j.relation in ("inner quartic", "outer quartic")]
    assert r.mj.neq == (5 if case == "custom-spline" else 2) + len(extra)
    assert not extra or case in ("spline", "custom-spline")
    assert all(r.mj.eq_type == mujoco.mjtEq.mjEQ_JOINT) and all(r.mj.eq_active0)
    if case == "custom-spline":
        fits = {j.name for j in r.conv.report.joints if j.relation.startswith("quartic fit")}
        assert fits == {"j2_rotation2", "j2_translation1", "j2_translation2"}
        assert all(rec[f].driven_by == q1 for f in fits)
        assert_within_recorded(r, lever_arm(joints))
    elif case == "spline":
        assert {a.units for a in r.conv.report.approximations} == {"rad", "m"}
        assert_within_recorded(r, lever_arm(joints))
        assert r.rep.max_pos_error > EXACT
    else:
        assert_exact(r)


def test_locked_coordinates(tmp_path):
    """A locked pin, a locked knee (whose splines then are constants) and a pin coupled to the
    locked pin: exact. A locked coordinate is either folded into the fixed body transforms (no
    MuJoCo joint, a report note) or a MuJoCo joint at its locked value held by a one-joint
    equality."""
    bodies = dict(BODIES)
    bodies["b4"] = BODIES["b1"]
    joints = [
        typed_joint("PinJoint", "j1", "ground", "b1", OFFSETS[0]),
        JointSpec("j2", "PinJoint", "b1", "b2", OFFSETS[1], [Coord("q2", ROT_RANGE, 0.4, locked=True)]),
        JointSpec("knee", "CustomJoint", "b2", "b3", OFFSETS[2], [Coord("knee", KNEE_RANGE, -0.7, locked=True)],
                  knee_axes("knee", "SimmSpline")),
        JointSpec("j4", "PinJoint", "b3", "b4", OFFSETS[0], [Coord("q4", ROT_RANGE)]),
    ]
    couplers = [CouplerSpec("c4", "q4", "q2", xy_function("SimmSpline", SPLINE_X, np.sin(SPLINE_X)))]
    r = run(build_model(tmp_path / "locked.osim", joints, couplers=couplers, bodies=bodies), tmp_path)
    assert_exact(r)
    assert sorted(r.rep.locked_coordinates) == ["knee", "q2"]
    assert r.rep.dependent_coordinates == ["q4"]
    assert r.rep.coordinates == ["j1_r0"]
    held = {mujoco.mj_id2name(r.mj, mujoco.mjtObj.mjOBJ_JOINT, int(r.mj.eq_obj1id[i]))
            for i in range(r.mj.neq) if r.mj.eq_obj2id[i] < 0 and r.mj.eq_active0[i]}
    for name, value in (("q2", 0.4), ("knee", -0.7)):
        if mujoco.mj_name2id(r.mj, mujoco.mjtObj.mjOBJ_JOINT, name) < 0:  # folded
            assert any(name in n and "locked" in n for n in r.conv.report.notes), r.conv.report.notes
        else:
            assert qpos0(r.mj, name) == pytest.approx(value, abs=1e-15)
            assert name in held
    # Nothing but j1 moves freely: every other MuJoCo joint is driven by an equality.
    free = {mujoco.mj_id2name(r.mj, mujoco.mjtObj.mjOBJ_JOINT, i) for i in range(r.mj.njnt)}
    free -= {mujoco.mj_id2name(r.mj, mujoco.mjtObj.mjOBJ_JOINT, int(r.mj.eq_obj1id[i])) for i in range(r.mj.neq)}
    assert free == {"j1_r0"}


def test_coupler_not_enforced(tmp_path):
    """A CoordinateCouplerConstraint with isEnforced false is skipped (reported): both
    coordinates stay independent, as in OpenSim."""
    joints = [
        typed_joint("PinJoint", "j1", "ground", "b1", OFFSETS[0]),
        typed_joint("PinJoint", "j2", "b1", "b2", OFFSETS[1]),
    ]
    couplers = [CouplerSpec("c2", "j2_r0", "j1_r0", linear(0.5, 0.1), enforced=False)]
    r = run(build_model(tmp_path / "off.osim", joints, couplers=couplers), tmp_path)
    assert_exact(r)
    assert sorted(r.rep.coordinates) == ["j1_r0", "j2_r0"] and r.rep.dependent_coordinates == []
    assert r.mj.neq == 0
    assert [(s.element, s.name) for s in r.conv.report.skipped] == [("CoordinateCouplerConstraint", "c2")]


CLAMP_CASES = {
    "clamped": Coord("q", ROT_RANGE, clamped=True),
    "unclamped": Coord("q", (-2.0, 2.5), clamped=False),
    "clamped-slider": Coord("q", TRANS_RANGE, clamped=True),
    # Range given, <clamped> left at OpenSim's default (false): OpenSim does not print it.
    "range-only": Coord("q", (-1.5, 0.5)),
    # Every property at OpenSim's default: range [-10, 10], not clamped.
    "all-default": Coord("q"),
    # A range that needs all 17 digits (as -2.0943951 rad = -120 deg in OpenSim's models).
    "precise-range": Coord("q", (-2.0943951023931953, 1.3962634015954636), clamped=True),
}


@pytest.mark.parametrize("case", list(CLAMP_CASES))
def test_clamped_and_range(case, tmp_path):
    """MuJoCo jnt_range is OpenSim's range; the joint is unlimited, as OpenSim's forward dynamics
    leaves a clamped coordinate, unless ``clamped_limits`` asks for limits where OpenSim clamps."""
    c = CLAMP_CASES[case]
    jtype = "SliderJoint" if "slider" in case else "PinJoint"
    joints = [JointSpec("j1", jtype, "ground", "b1", OFFSETS[0], [c]),
              typed_joint("PinJoint", "j2", "b1", "b2", OFFSETS[1])]
    path = build_model(tmp_path / f"clamp_{case}.osim", joints)
    model = osim.Model(path)
    model.initSystem()
    oc = model.getCoordinateSet().get("q")
    r = run(path, tmp_path, n_poses=5)
    assert_exact(r)
    j = jid(r.mj, "q")
    np.testing.assert_allclose(r.mj.jnt_range[j], [oc.getRangeMin(), oc.getRangeMax()], rtol=0, atol=1e-12)
    assert not r.mj.jnt_limited[j]
    assert any("have unlimited MuJoCo joints" in n for n in r.conv.report.notes) == (
        bool(oc.get_clamped()) and oc.getRangeMax() - oc.getRangeMin() < 1e3)
    hard = mujoco.MjModel.from_xml_path(str(convert(path, tmp_path / "hard", convert_options(clamped_limits=True)).xml))
    assert bool(hard.jnt_limited[jid(hard, "q")]) == bool(oc.get_clamped())


def test_default_values(tmp_path):
    """Non-zero default values (ball, knee with splines, slider, coupled pin): qpos0 and the
    'default-pose' keyframe are OpenSim's default pose."""
    joints = [
        typed_joint("BallJoint", "j1", "ground", "b1", OFFSETS[0], defaults=[0.3, -0.2, 0.5]),
        JointSpec("knee", "CustomJoint", "b1", "b2", OFFSETS[1], [Coord("knee", KNEE_RANGE, -0.8)],
                  knee_axes("knee", "SimmSpline")),
        JointSpec("j3", "FreeJoint", "b2", "b3", OFFSETS[2],
                  [Coord(f"f{i}", ROT_RANGE if i < 3 else TRANS_RANGE, d)
                   for i, d in enumerate([0.2, -0.4, 0.6, 0.05, -0.1, 0.15])]),
    ]
    # f2 follows the knee (its own default, 0.6, is overridden by the coupler at assembly).
    couplers = [CouplerSpec("cf2", "f2", "knee", linear(0.5, 0.1))]
    path = build_model(tmp_path / "defaults.osim", joints, couplers=couplers)
    model = osim.Model(path)
    state = model.initSystem()
    want = {c.getName(): c.getValue(state) for c in
            (model.getCoordinateSet().get(i) for i in range(model.getCoordinateSet().getSize()))}
    assert want["f2"] == pytest.approx(0.5 * -0.8 + 0.1, abs=1e-9)

    conv = convert(path, tmp_path / "out", convert_options())
    mj = mujoco.MjModel.from_xml_path(str(conv.xml))
    for name, value in want.items():
        assert qpos0(mj, name) == pytest.approx(value, abs=1e-9), name
    k = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_KEY, "default-pose")
    assert k >= 0
    np.testing.assert_allclose(mj.key_qpos[k], mj.qpos0, rtol=0, atol=1e-12)

    # Pose 0 of compare_kinematics is the default pose, with every equality resolved: exact,
    # since each quartic is fitted through the function's value at the reference.
    rep = compare_kinematics(path, conv.xml, n_poses=1)
    assert rep.n_poses == 1
    r = Result(path, conv, rep, mj)
    assert r.conv.report.approximations  # the knee's splines are fitted ...
    assert_exact(r, allow_approx=True)  # ... but exact at the default pose
    # With qpos = qpos0 (no equality resolved) MuJoCo's bodies are exactly OpenSim's default pose.
    data = mujoco.MjData(mj)
    mujoco.mj_kinematics(mj, data)
    for b in ("b1", "b2", "b3"):
        xf = model.getBodySet().get(b).getTransformInGround(state)
        p = OSIM_TO_MJ @ xf.p().to_numpy()
        rot = OSIM_TO_MJ @ np.array([[xf.R().get(i, j) for j in range(3)] for i in range(3)])
        bid = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, b)
        np.testing.assert_allclose(data.xpos[bid], p, rtol=0, atol=EXACT)
        np.testing.assert_allclose(data.xmat[bid].reshape(3, 3), rot, rtol=0, atol=EXACT)


@pytest.mark.parametrize("gravity", [(0.0, -G, 0.0), (0.5, -9.0, 1.5)])
def test_gravity(gravity, tmp_path):
    """OpenSim gravity (Y up) becomes MuJoCo's opt.gravity (Z up)."""
    joints = [typed_joint("PinJoint", "j1", "ground", "b1", OFFSETS[0])]
    path = build_model(tmp_path / "gravity.osim", joints, gravity=gravity)
    conv = convert(path, tmp_path / "out", convert_options())
    mj = mujoco.MjModel.from_xml_path(str(conv.xml))
    gx, gy, gz = gravity
    np.testing.assert_allclose(mj.opt.gravity, [gx, -gz, gy], rtol=0, atol=1e-12)
    if gravity == (0.0, -G, 0.0):
        np.testing.assert_allclose(mj.opt.gravity, [0.0, 0.0, -G], rtol=0, atol=1e-12)


def test_massless_intermediate_bodies(tmp_path):
    """Massless, inertia-less bodies between two pins (as in many OpenSim models): MuJoCo needs
    mass on moving bodies, so each gets a tiny recorded mass; kinematics stay exact."""
    bodies = dict(BODIES)
    bodies["m1"] = (0.0, (0.0, 0.0, 0.0), (0.0,) * 6)
    bodies["m2"] = (0.0, (0.0, 0.0, 0.0), (0.0,) * 6)
    # (OpenSim itself rejects two massless bodies in a row: "terminal massless body".)
    joints = [
        typed_joint("PinJoint", "j1", "ground", "m1", OFFSETS[0]),
        typed_joint("UniversalJoint", "j2", "m1", "b2", OFFSETS[1]),
        typed_joint("PinJoint", "j3", "b2", "m2", OFFSETS[2]),
        typed_joint("PinJoint", "j4", "m2", "b3", OFFSETS[0]),
    ]
    r = run(build_model(tmp_path / "massless.osim", joints, bodies=bodies), tmp_path)
    rep = r.rep
    assert rep.max_pos_error <= EXACT and rep.max_ang_error <= EXACT, rep.summary()
    added = sum(a.max_error for a in r.conv.report.approximations if a.units == "kg")
    assert {a.name for a in r.conv.report.approximations if a.units == "kg"} == {"m1", "m2"}
    assert rep.mass_opensim == pytest.approx(bodies["b2"][0] + bodies["b3"][0], abs=1e-15)
    assert rep.mass_mujoco - rep.mass_opensim == pytest.approx(added, abs=1e-15)
    assert added <= 1e-7
    # The added masses sit at the massless bodies' origins, less than a metre from b3's COM.
    assert rep.com_max_error <= added / rep.mass_opensim * 2.0 + EXACT


# ---------------------------------------------------------------------------------------------
# An OpenSim 3.x document
# ---------------------------------------------------------------------------------------------

def test_opensim3_document(bundled_conversion):
    """A 3.x document (MoBL-ARMS, Version 30000) is upgraded and converted: orientations exact,
    positions within the quartics of its shoulder's chain shortcut (:mod:`o2m.convert.shortcuts`)."""
    fetched, conv = bundled_conversion("mobl_arms_no_wrap")
    assert conv.xml.exists()
    assert conv.report.source_version < 40000
    mj = mujoco.MjModel.from_xml_path(str(conv.xml))
    assert mj.nbody > 10 and mj.njnt > 10
    assert mj.nmesh > 0
    k = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_KEY, "default-pose")
    assert k >= 0
    np.testing.assert_allclose(mj.key_qpos[k], mj.qpos0, rtol=0, atol=0)
    # Kinematics against OpenSim (couplers, locked coordinates, 3.x upgrade): the couplers are
    # linear, so only the slides that move scapphant from the thorax are approximated
    slides = [a for a in conv.report.approximations if a.element == "CustomJoint" and a.units == "m"]
    assert sorted(a.joint for a in slides) == [f"unrothum_shortcut{k}" for k in (1, 2, 3)]
    bound = sum(a.max_error for a in slides)
    rep = compare_kinematics(fetched.osim, conv.xml, n_poses=10)
    assert rep.n_poses == 10 and rep.missing_bodies == []
    assert rep.max_ang_error <= EXACT, rep.summary()
    assert rep.max_pos_error <= bound + EXACT and rep.com_max_error <= bound + EXACT, rep.summary()
    assert abs(rep.mass_mujoco - rep.mass_opensim) <= EXACT
