"""EllipsoidJoint and ScapulothoracicJoint: converted to exact hinge chains, checked against OpenSim.

Each test builds ground -E-> b1 -Pin-> b2 with the opensim API (E the ellipsoid joint type,
translated and rotated offset frames on both sides, bodies with an off-centre COM and a full
inertia), converts it and compares the MuJoCo model with OpenSim over random poses with
:func:`o2m.validate.compare_kinematics`: body frames agree to 1e-9 m and 1e-9 rad for every
set of radii, because the chain (:mod:`o2m.convert.ellipsoid_joints`) is exact.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import opensim as osim
import pytest

from o2m.convert.converter import convert
from o2m.convert.ellipsoid_joints import surface_steps
from o2m.osim import load_document, read_skeleton
from o2m.validate.dynamics import compare_dynamics
from o2m.validate.kinematics import compare_kinematics
from tests.convert.test_joint_types import (
    BODIES,
    EXACT,
    OFFSETS,
    Result,
    _steps_cleanly,
    assert_inertia,
    assert_within_recorded,
    jid,
)
from tests.helpers import add_coupler, convert_options

osim.Logger.setLevelString("error")

N_POSES = 60
#: Seth et al.'s thoracoscapular model: thorax ellipsoid about 0.07 x 0.15 x 0.07 m, scapula
#: abduction, elevation, upward rotation and winging within about ±0.5 rad.
SETH_RADII = (0.07, 0.15, 0.07)
SETH_RANGE = (-0.5, 0.5)
WIDE_RANGE = (-1.2, 1.0)


def build(path: Path, jtype: str, radii, rng=SETH_RANGE, *, locked: int | None = None,
          winging=((0.01, -0.02), 0.4), coupled: bool = False) -> str:
    """Print ground -``jtype``-> b1 -Pin-> b2 to ``path``; coordinates ``e0``.. in ``rng``;
    ``coupled``: a CoordinateCouplerConstraint makes e1 = 0.5 e0 + 0.05."""
    m = osim.Model()
    m.setName(path.stem)
    bodies = {}
    for name in ("b1", "b2"):
        mass, com, inertia = BODIES[name]
        bodies[name] = osim.Body(name, mass, osim.Vec3(*com), osim.Inertia(*inertia))
        m.addBody(bodies[name])
    lp, op, lc, oc = (osim.Vec3(*v) for v in OFFSETS[0])
    if jtype == "EllipsoidJoint":
        joint = osim.EllipsoidJoint("e", m.getGround(), lp, op, bodies["b1"], lc, oc, osim.Vec3(*radii))
    else:
        joint = osim.ScapulothoracicJoint("e", m.getGround(), lp, op, bodies["b1"], lc, oc, osim.Vec3(*radii),
                                          osim.Vec2(*winging[0]), winging[1])
    m.addJoint(joint)
    lp, op, lc, oc = (osim.Vec3(*v) for v in OFFSETS[1])
    m.addJoint(osim.PinJoint("pin", bodies["b1"], lp, op, bodies["b2"], lc, oc))
    for i in range(joint.numCoordinates()):
        c = joint.upd_coordinates(i)
        c.setName(f"e{i}")
        c.setRangeMin(rng[0])
        c.setRangeMax(rng[1])
        c.setDefaultValue(0.1 * (i + 1))
        if i == locked:
            c.setDefaultLocked(True)
    if coupled:
        joint.upd_coordinates(1).setDefaultValue(0.5 * 0.1 + 0.05)
        add_coupler(m, "couple", "e0", "e1", osim.LinearFunction(0.5, 0.05))
    m.finalizeConnections()
    m.printToXML(str(path))
    return str(path)


def run(osim_path: str, tmp_path: Path) -> Result:
    conv = convert(osim_path, tmp_path / "out", convert_options())
    rep = compare_kinematics(osim_path, conv.xml, n_poses=N_POSES, seed=1)
    assert rep.n_poses == N_POSES and rep.skipped_poses == 0
    assert rep.missing_bodies == [] and all(b.startswith("b1_ellipsoid") for b in rep.extra_bodies)
    r = Result(osim_path, conv, rep, mujoco.MjModel.from_xml_path(str(conv.xml)))
    assert_inertia(r)
    return r


def hinge_count(jtype: str, radii) -> int:
    mobilizer = np.array(radii) if jtype == "EllipsoidJoint" else np.array(radii)[[1, 0, 2]]
    steps = surface_steps(mobilizer)
    return sum(not isinstance(s, float) for s in steps) + (jtype == "ScapulothoracicJoint")


CASES = [
    ("EllipsoidJoint", (0.1, 0.1, 0.1), WIDE_RANGE, 3),  # a sphere: three hinges, nothing driven
    ("EllipsoidJoint", (0.15, 0.07, 0.07), WIDE_RANGE, 4),  # b = c
    ("EllipsoidJoint", (0.07, 0.15, 0.07), WIDE_RANGE, 6),  # a = c
    ("EllipsoidJoint", (0.08, 0.08, 0.12), WIDE_RANGE, 6),  # a = b
    ("EllipsoidJoint", (0.05, 0.08, 0.12), WIDE_RANGE, 7),  # general: an intermediate body
    ("ScapulothoracicJoint", SETH_RADII, SETH_RANGE, 5),  # thorax x = z: b = c after the swap
    ("ScapulothoracicJoint", (0.07, 0.15, 0.09), WIDE_RANGE, 8),
]


@pytest.mark.parametrize(("jtype", "radii", "rng", "hinges"), CASES)
def test_ellipsoid_joint_exact(jtype, radii, rng, hinges, tmp_path):
    """The chain follows OpenSim to 1e-9 over random poses; each coordinate's MuJoCo hinge carries
    its value (compare_kinematics writes OpenSim's values to them); the model steps cleanly."""
    r = run(build(tmp_path / f"{jtype}.osim", jtype, radii, rng), tmp_path)
    rep = r.rep
    assert rep.max_pos_error <= EXACT and rep.max_ang_error <= EXACT, rep.summary()
    assert rep.com_max_error <= EXACT and abs(rep.mass_mujoco - rep.mass_opensim) <= EXACT
    assert hinge_count(jtype, radii) == hinges
    names = [mujoco.mj_id2name(r.mj, mujoco.mjtObj.mjOBJ_JOINT, i) for i in range(r.mj.njnt)]
    assert len(names) == hinges + 1  # and the pin
    coords = [f"e{i}" for i in range(3 if jtype == "EllipsoidJoint" else 4)]
    for c in coords:
        assert r.mj.jnt_type[jid(r.mj, c)] == mujoco.mjtJoint.mjJNT_HINGE
    records = {j.name: j for j in r.conv.report.joints}
    assert sorted(n for n, j in records.items() if j.coordinate) == sorted(coords + ["pin_coord_0"])
    driven = [n for n in names if n.startswith("e_ellipsoid")]
    assert len(driven) == hinges - len(coords) == r.mj.neq
    assert all(records[n].relation == "linear" for n in driven)
    # the report notes the chain and its measured error; driven hinges' armature is recorded
    note = next(n for n in r.conv.report.notes if n.startswith("joint 'e'"))
    assert f"chain of {hinges} hinges, {len(driven)} of them driven" in note and "exact" in note
    assert float(note.split("worst ")[1].split(" mm")[0]) <= EXACT * 1e3
    # only a chain with a three-hinge turn (6 hinges and more) needs armature, recorded as an approximation
    approx = [a for a in r.conv.report.approximations if a.name == "e"]
    assert len(approx) == (1 if hinges >= 6 else 0)
    assert sum(r.mj.dof_armature > 0) == (len(driven) if hinges >= 6 else 0)
    assert (hinges > 6) == bool(rep.extra_bodies)
    _steps_cleanly(r.mj)


def test_coordinate_joints_carry_values(tmp_path):
    """Setting the coordinate joints to OpenSim's values (and resolving the equalities) puts b1
    where OpenSim does, and qpos0 holds each coordinate's default value."""
    path = build(tmp_path / "carry.osim", "ScapulothoracicJoint", (0.07, 0.15, 0.09), WIDE_RANGE)
    r = run(path, tmp_path)
    for i in range(4):
        assert r.mj.qpos0[r.mj.jnt_qposadr[jid(r.mj, f"e{i}")]] == pytest.approx(0.1 * (i + 1), abs=1e-15)
    assert r.rep.worst_pose is not None and r.rep.max_pos_error <= EXACT


def test_locked_coordinate_folded(tmp_path):
    """A locked coordinate's hinges are fixed at its default: no MuJoCo joint, still exact."""
    r = run(build(tmp_path / "locked.osim", "EllipsoidJoint", (0.05, 0.08, 0.12), WIDE_RANGE, locked=1), tmp_path)
    assert r.rep.max_pos_error <= EXACT and r.rep.max_ang_error <= EXACT, r.rep.summary()
    assert mujoco.mj_name2id(r.mj, mujoco.mjtObj.mjOBJ_JOINT, "e1") == -1
    assert not any("e1" == j.driven_by for j in r.conv.report.joints)
    note = next(n for n in r.conv.report.notes if n.startswith("joint 'e'"))
    assert float(note.split("worst ")[1].split(" mm")[0]) <= EXACT * 1e3, note


@pytest.mark.parametrize("jtype", ["EllipsoidJoint", "ScapulothoracicJoint"])
def test_reader_follows_opensim(jtype, tmp_path):
    """The skeleton's joint transform (o2m.osim.skeleton.EllipsoidSurface) is OpenSim's to 1e-12."""
    path = build(tmp_path / f"{jtype}.osim", jtype, (0.05, 0.08, 0.12), WIDE_RANGE)
    joint = next(j for j in read_skeleton(load_document(path)).joints if j.name == "e")
    model = osim.Model(path)
    state = model.initSystem()
    coords = model.getCoordinateSet()
    body = model.getBodySet().get("b1")
    rng = np.random.default_rng(3)
    for _ in range(20):
        values = {coords.get(i).getName(): rng.uniform(*WIDE_RANGE) for i in range(coords.getSize())}
        for name, v in values.items():
            coords.get(name).setValue(state, v, False)
        model.realizePosition(state)
        x = body.getTransformInGround(state)
        want_rot = np.array([[x.R().get(i, k) for k in range(3)] for i in range(3)])
        got = joint.transform(values)
        np.testing.assert_allclose(got.pos, x.p().to_numpy(), rtol=0, atol=1e-12)
        np.testing.assert_allclose(got.rot, want_rot, rtol=0, atol=1e-12)


def test_coupled_coordinate(tmp_path):
    """A coordinate coupled to another (linearly): its hinges, the coordinate's own and the
    driven ones, follow the independent coordinate exactly."""
    path = build(tmp_path / "coupled.osim", "ScapulothoracicJoint", (0.07, 0.15, 0.09), WIDE_RANGE, coupled=True)
    r = run(path, tmp_path)
    assert r.rep.dependent_coordinates == ["e1"]
    assert r.rep.max_pos_error <= EXACT and r.rep.max_ang_error <= EXACT, r.rep.summary()
    records = {j.name: j for j in r.conv.report.joints}
    assert records["e1"].coordinate == "e1" and records["e1"].driven_by == "e0"
    assert all(j.driven_by == "e0" for n, j in records.items() if n.startswith("e_ellipsoid"))


def test_spline_coupled_coordinate(tmp_path):
    """A coordinate coupled by a spline: its hinges follow minimax quartics (no extra joints are
    planned in a chain), each recorded; the bodies stay within what the records allow."""
    path = Path(build(tmp_path / "spline.osim", "ScapulothoracicJoint", (0.07, 0.15, 0.09), WIDE_RANGE,
                      coupled=True))
    x = np.linspace(*WIDE_RANGE, 9)
    spline = ('<SimmSpline name="function"><x>' + " ".join(repr(float(v)) for v in x) + "</x><y>"
              + " ".join(repr(float(0.3 * np.sin(1.5 * v) + 0.05)) for v in x) + "</y></SimmSpline>")
    text = path.read_text()
    start = text.index("<LinearFunction", text.index("<coupled_coordinates_function>"))
    end = text.index("</LinearFunction>", start) + len("</LinearFunction>")
    path.write_text(text[:start] + spline + text[end:])
    r = run(str(path), tmp_path)
    fits = [a for a in r.conv.report.approximations if a.units == "rad"]
    assert len(fits) == 4 and all(0 < a.max_error < 0.005 for a in fits)  # e1 and its three +-1/2 hinges
    assert r.rep.max_pos_error > 1e-4  # not exact: the check below can fail
    assert_within_recorded(r, lever=1.5)  # joint centre to any body point: radii, offsets and COMs, < 1.3 m


@pytest.mark.parametrize(("case", "bound"), [(4, 0.01), (5, 0.02)])
def test_falls_like_opensim(case, bound, tmp_path):
    """Falling from the default pose for 0.2 s, the coordinates stay near OpenSim's (mean absolute
    error over them, rad): a GimbalJoint in place of the sphere gives 0.0019 rad, the 7-hinge
    chain (with armature) 0.0032, the Seth-like thorax (4 + 1 hinges, no armature) 0.0071; ten times
    the armature put the 7-hinge chain 0.024 rad off."""
    jtype, radii, rng, _ = CASES[case]
    path = build(tmp_path / "fall.osim", jtype, radii, rng)
    conv = convert(path, tmp_path / "out", convert_options())
    rep = compare_dynamics(path, conv.xml, n_sets=1, duration=0.2, max_workers=1, progress=False)
    assert rep.mean_rotational_error() <= bound, rep.summary()
