"""Every bundled model converts, and its skeleton matches OpenSim 4.6 over 200 random poses.

Two measurements per model:
* structure: every MuJoCo joint set from OpenSim's own values (no equality used). This checks
  bodies, frames, axes, inertia and the Y-up to Z-up mapping, and must be exact.
* the model as a user runs it: dependent joints follow the model's own equality constraints.
  Issue #2's targets: every body within 0.1 mm and 0.05 deg of OpenSim over 200 random poses
  (seed 0), with no allowance for fitted couplings. Spline couplings are sums of joints
  (a main quartic plus inner and outer joints, o2m.functions.fit_couplings).

Where the extra joints would give a body more than MuJoCo's 6 degrees of freedom (Leg6Dof9Musc's
tibia and patella, five spline axes of the knee angle), the joint's translations sit on an
intermediate body ``<body>_couplings`` (nearly massless, no geometry) and its rotations on the
body itself.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from o2m import models
from o2m.convert.builder import MjcfBuilder
from o2m.mj.simulate import welded_at_default_pose
from o2m.osim.document import load_document
from o2m.osim.skeleton import read_skeleton
from o2m.validate.kinematics import compare_kinematics

POSES = 200
POS_TOL = 1e-4  # m (0.1 mm)
ANG_TOL = np.deg2rad(0.05)  # rad
EXACT_TOL = 1e-6  # m and rad: what "exact" means after the MJCF's printed precision
#: Worst violation of a coupling's equalities while a model hangs under gravity (m, rad).
HANGING_VIOLATION = {"slide": 2e-5, "hinge": 1e-3}
#: Models whose knee coupling plan rounding decides (docs/fidelity.md, "The knee fits depend on
#: round-off"): a hanging equality over HANGING_VIOLATION there is an expected failure, not a pass.
ROUNDOFF_SENSITIVE_KNEES = {"leg6dof9musc"}

NAMES = [n for n in models.BUNDLED if n != "mobl_arms_no_wrap"] + ["mobl_arms_no_wrap"]
#: The bodies given an intermediate body for the translations of their joint's couplings.
COUPLINGS_BODIES = {"leg6dof9musc": {"tibia_r", "patella_r"}}


@pytest.fixture(scope="module", params=NAMES)
def converted(request, bundled_conversion):
    fetched, conv = bundled_conversion(request.param)
    return request.param, fetched.osim, conv


@pytest.fixture(scope="module")
def kinematics(converted):
    name, osim, conv = converted
    rep = compare_kinematics(osim, conv.xml, n_poses=POSES, seed=0)
    assert rep.n_poses == POSES and not rep.missing_bodies
    return rep


def _moved_by_shortcuts(m: mujoco.MjModel) -> set[str]:
    """Bodies a chain shortcut's slides move (``<joint>_shortcut<k>``, :mod:`o2m.convert.shortcuts`):
    OpenSim has no transform axis whose value they carry."""
    tops = {int(m.jnt_bodyid[j]) for j in range(m.njnt) if "_shortcut" in m.joint(j).name}
    moved = set()
    for b in range(1, m.nbody):
        a = b
        while a > 0 and a not in tops:
            a = int(m.body_parentid[a])
        if a > 0:
            moved.add(m.body(b).name)
    return moved


def test_structure_is_exact(converted):
    """Every body placed by OpenSim's own coordinate and axis values is exact; bodies a chain
    shortcut moves are checked against their fits by the 0.1 mm test."""
    name, osim, conv = converted
    rep = compare_kinematics(osim, conv.xml, n_poses=POSES, seed=1, dependents="opensim")
    assert rep.n_poses == POSES
    assert not rep.missing_bodies
    moved = _moved_by_shortcuts(mujoco.MjModel.from_xml_path(str(conv.xml)))
    assert bool(moved) == name.startswith("mobl_arms"), sorted(moved)  # its shoulder rhythm
    for body, err in rep.bodies.items():
        if body not in moved:
            assert err.max_pos < EXACT_TOL and err.max_ang < EXACT_TOL, f"{name}/{body}\n{rep.summary()}"


def test_every_body_within_0_1_mm(converted, kinematics):
    name = converted[0]
    for body, err in kinematics.bodies.items():
        assert err.max_pos <= POS_TOL, f"{name}/{body}: {err.max_pos * 1e3:.4f} mm\n{kinematics.summary()}"


def test_every_body_within_0_05_deg(converted, kinematics):
    name = converted[0]
    for body, err in kinematics.bodies.items():
        assert err.max_ang <= ANG_TOL, f"{name}/{body}: {np.rad2deg(err.max_ang):.4f} deg\n{kinematics.summary()}"


def test_mass_and_centre_of_mass(converted):
    """Mass exact; centre of mass exact from OpenSim's own values, or (where a chain shortcut
    moves bodies, which OpenSim has no values for) within the bodies' 0.1 mm."""
    name, osim, conv = converted
    moved = _moved_by_shortcuts(mujoco.MjModel.from_xml_path(str(conv.xml)))
    rep = compare_kinematics(osim, conv.xml, n_poses=20, seed=2, dependents="mujoco" if moved else "opensim")
    assert rep.mass_mujoco == pytest.approx(rep.mass_opensim, rel=1e-7, abs=1e-7)
    assert rep.com_max_error < (POS_TOL if moved else EXACT_TOL), rep.summary()


def test_report_lists_every_element(converted):
    name, osim, conv = converted
    rep = conv.report
    assert conv.xml.exists() and conv.xml.with_suffix(".report.txt").exists()
    assert conv.xml.with_name(conv.xml.stem + ".report.json").exists()
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    assert rep.counts["mujoco joints"] == m.njnt
    assert m.key("default-pose").qpos.tolist() == m.qpos0.tolist()
    assert all(np.isfinite(a.max_error) for a in rep.approximations)


def test_default_pose_satisfies_every_equality(converted):
    """At qpos0 (OpenSim's default pose) no equality is violated, so a simulation starts at rest."""
    name, osim, conv = converted
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    eq_rows = d.efc_type[: d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    assert np.all(np.abs(d.efc_pos[: d.nefc][eq_rows]) < 1e-12)


def _extra_joints(m: mujoco.MjModel) -> dict[str, str]:
    """Extra coupling joints of ``m``: name -> the coupled joint they belong to."""
    out = {}
    for i in range(m.njnt):
        name = m.joint(i).name
        for role in ("_inner", "_outer"):
            head, _, k = name.rpartition(role)
            if head and k.isdigit():
                out[name] = head
    return out


def test_extra_joints_add_to_their_axis(converted):
    """Every extra joint of a coupling sits on its coupled joint's body, right after it, with its
    type, axis and anchor, is 0 at the default pose and follows an equality: inner joints the
    coordinate, outer joints an inner joint. A path-point carrier has them only on slides whose
    plain quartic's derivative error exceeds CARRIER_SLOPE_GATE (the leg and gait models' knee
    extensors), and keeps within 6 dofs."""
    name, osim, conv = converted
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    extra = _extra_joints(m)
    if name in ("gait10dof18musc", "gait2354", "gait2392", "leg6dof9musc"):
        assert extra, "the knee splines get extra joints"
    drivers = {m.joint(int(m.eq_obj1id[e])).name: m.joint(int(m.eq_obj2id[e])).name
               for e in range(m.neq) if m.eq_type[e] == mujoco.mjtEq.mjEQ_JOINT and m.eq_obj2id[e] >= 0}
    records = {j.name: j for j in conv.report.joints}
    for joint, main in extra.items():
        j, k = m.joint(joint), m.joint(main)
        assert j.bodyid[0] == k.bodyid[0] and j.type[0] == k.type[0], joint
        np.testing.assert_allclose(j.axis, k.axis, atol=1e-15)
        np.testing.assert_allclose(j.pos, k.pos, atol=1e-15)
        assert m.qpos0[j.qposadr[0]] == 0.0
        if "_inner" in joint:
            assert drivers[joint] == drivers[main] == records[main].driven_by
        else:
            assert "_inner" in drivers[joint] and drivers[joint] in extra
    for main in set(extra.values()):  # right after their main joint (hinges must be, to add up)
        ids = sorted(m.joint(n).id for n, k in extra.items() if k == main)
        assert ids == list(range(m.joint(main).id + 1, m.joint(main).id + 1 + len(ids))), main
    carriers = [r for r in conv.report.joints if m.body(int(m.joint(r.name).bodyid[0])).name.endswith("_carrier")]
    gated = {a.joint for a in conv.report.approximations if a.element == "MovingPathPoint"
             and "extra joints" in a.what}
    for r in carriers:
        if r.name in gated:
            assert r.relation.startswith("quartic fit + "), r
        elif r.name not in extra:
            assert r.relation in ("linear", "quartic fit"), r
    assert bool(gated) == (name in ("gait10dof18musc", "gait2354", "gait2392", "leg6dof9musc")), sorted(gated)


def test_coupled_axes_follow_opensim_hanging_under_gravity(converted):
    """With the pelvis welded to the world, 1 s under gravity from the default pose: each coupled
    axis (its joints' sum) stays within its fit (inside the range or in its margin) plus a small
    equality violation of OpenSim's function of the coordinate; every coupling equality holds
    within HANGING_VIOLATION (extra joints much lighter than their body made them sag 0.2 mm).
    Clamped coordinates get MuJoCo's limits here (``clamped_limits``): the fits cover the range
    and its margins only, and OpenSim's forward dynamics lets a knee swing past (docs/fidelity.md)."""
    name, osim, conv = converted
    full = mujoco.MjModel.from_xml_path(str(conv.xml))
    if not _extra_joints(full):
        pytest.skip("no extra coupling joints")
    m, d = welded_at_default_pose(conv.xml, "pelvis")
    skel = read_skeleton(load_document(osim))
    for c in skel.coordinates.values():
        if c.clamped and mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, c.name) >= 0:
            m.jnt_limited[m.joint(c.name).id] = 1
    builder = MjcfBuilder(skel)
    builder.build()
    extra = _extra_joints(m)
    axes = []
    for a in builder.coupled_axes()[0]:
        fit = builder.coupling_fit(a.name)
        ids = [m.joint(a.name).id] + [m.joint(n).id for n, main in extra.items() if main == a.name]
        axes.append((a, fit, ids, m.joint(a.base).id))
    axis_of_eq = {e: i for e in range(m.neq) for i, (_, _, ids, _) in enumerate(axes) if m.eq_obj1id[e] in ids}
    worst = np.zeros(len(axes))
    violation = np.zeros(len(axes))
    for _ in range(500):
        mujoco.mj_step(m, d)
        for i, (a, _, ids, base) in enumerate(axes):
            value = sum(d.qpos[m.jnt_qposadr[j]] - m.qpos0[m.jnt_qposadr[j]] for j in ids)
            truth = float(a.rel(np.array([d.qpos[m.jnt_qposadr[base]]]))[0])
            worst[i] = max(worst[i], abs(value - truth))
        for r in np.flatnonzero(d.efc_type[: d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY):
            i = axis_of_eq.get(int(d.efc_id[r]))
            if i is not None:
                violation[i] = max(violation[i], abs(float(d.efc_pos[r])))
    assert np.all(np.isfinite(d.qpos))
    sensitive = []
    for i, (a, fit, _, _) in enumerate(axes):
        tol = HANGING_VIOLATION[a.kind]
        if violation[i] > tol and name in ROUNDOFF_SENSITIVE_KNEES:
            sensitive.append(f"{a.name} {violation[i]:.3g}")
            continue
        assert violation[i] <= tol, f"{name}/{a.name}: equality violated by {violation[i]:.3g}"
        allowed = max(fit.max_error, fit.margin_error) + tol
        assert worst[i] <= allowed, f"{name}/{a.name}: {worst[i]:.3g} off OpenSim (fit {allowed - tol:.3g})"
    if sensitive:
        pytest.xfail(f"{name}: equalities violated ({', '.join(sensitive)}); the knee's coupling search "
                     "depends on round-off (docs/fidelity.md, 'The knee fits depend on round-off')")


def test_couplings_bodies_carry_translations_only(converted):
    """An intermediate body ``<body>_couplings`` exists only where a body would exceed MuJoCo's 6
    dofs: it hangs from the OpenSim parent, carries only slides (the joint's translations, main
    and extra joints), no geoms or sites, and is nearly massless; the OpenSim body hangs from it
    with no offset and keeps the hinges, its inertial, geometry and sites. The report notes it."""
    name, osim, conv = converted
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    skel = read_skeleton(load_document(osim))
    parent_of = {j.child: j.parent for j in skel.joints}
    found = set()
    for b in range(1, m.nbody):
        assert m.body_dofnum[b] <= 6
        body = m.body(b).name
        if body in skel.bodies or body.endswith("_carrier"):
            continue
        assert body.endswith("_couplings"), body
        child = body.removesuffix("_couplings")
        found.add(child)
        kids = [k for k in range(m.nbody) if m.body_parentid[k] == b]
        assert [m.body(k).name for k in kids] == [child]
        assert m.body(int(m.body_parentid[b])).name == parent_of[child].replace("ground", "world")
        assert m.body_dofnum[b] + m.body_dofnum[kids[0]] > 6
        assert all(m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE for j in range(m.njnt) if m.jnt_bodyid[j] == b)
        assert not any(m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE for j in range(m.njnt)
                       if m.jnt_bodyid[j] == kids[0])
        assert m.body_geomnum[b] == 0 and not np.any(m.site_bodyid == b)
        assert m.body_mass[b] < 1e-10
        np.testing.assert_array_equal(m.body_pos[kids[0]], 0.0)
        np.testing.assert_array_equal(m.body_quat[kids[0]], [1, 0, 0, 0])
        assert any(f"body '{body}'" in n for n in conv.report.notes)
    assert found == COUPLINGS_BODIES.get(name, set())
