"""Every bundled model converts, and its skeleton matches OpenSim 4.6 over 200 random poses.

Two measurements per model:
* structure: every MuJoCo joint set from OpenSim's own values (no equality used). This checks
  bodies, frames, axes, inertia and the Y-up to Z-up mapping, and must be exact.
* the model as a user runs it: dependent joints follow the model's own equality constraints.
  Bodies whose motion involves no approximated coupling must be within 0.1 mm and 0.05 deg.
  Bodies below a coupling that MuJoCo can only approximate (a quartic fitted to a spline)
  must be within the same tolerance plus the fit errors recorded in the conversion report.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from o2m import models
from o2m.convert import convert
from o2m.validate import compare_kinematics

from .conftest import approximation_budget, require_mirror

POSES = 200
POS_TOL = 1e-4  # m (0.1 mm)
ANG_TOL = np.deg2rad(0.05)  # rad
EXACT_TOL = 1e-6  # m and rad: what "exact" means after the MJCF's printed precision

NAMES = [n for n in models.BUNDLED if n != "mobl_arms_no_wrap"] + ["mobl_arms_no_wrap"]


@pytest.fixture(scope="module", params=NAMES)
def converted(request, tmp_path_factory):
    require_mirror()
    fetched = models.fetch_model_with_geometry(request.param, progress=False)
    out = tmp_path_factory.mktemp(request.param)
    conv = convert(fetched.osim, out, geometry_dirs=[fetched.geometry_dir])
    return request.param, fetched.osim, conv


def test_structure_is_exact(converted):
    name, osim, conv = converted
    rep = compare_kinematics(osim, conv.xml, n_poses=POSES, seed=1, dependents="opensim")
    assert rep.n_poses == POSES
    assert not rep.missing_bodies
    assert rep.max_pos_error < EXACT_TOL, rep.summary()
    assert rep.max_ang_error < EXACT_TOL, rep.summary()


def test_kinematics_match_opensim(converted):
    name, osim, conv = converted
    rep = compare_kinematics(osim, conv.xml, n_poses=POSES, seed=0)
    budget = approximation_budget(conv.xml, conv.report.approximations)
    assert rep.n_poses == POSES and not rep.missing_bodies
    for body, err in rep.bodies.items():
        pos_extra, ang_extra = budget[body]
        assert err.max_pos <= POS_TOL + pos_extra, f"{name}/{body}: {err.max_pos * 1e3:.4f} mm\n{rep.summary()}"
        assert err.max_ang <= ANG_TOL + ang_extra, f"{name}/{body}: {np.rad2deg(err.max_ang):.4f} deg"
    if not any(a.joint for a in conv.report.approximations):
        assert rep.ok(), rep.summary()


def test_mass_and_centre_of_mass(converted):
    name, osim, conv = converted
    rep = compare_kinematics(osim, conv.xml, n_poses=20, seed=2, dependents="opensim")
    assert rep.mass_mujoco == pytest.approx(rep.mass_opensim, rel=1e-7, abs=1e-7)
    assert rep.com_max_error < EXACT_TOL


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
