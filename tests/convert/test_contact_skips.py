"""Contact o2m does not convert (none of it is in the corpus): a model that OpenSim 4.6 loads, with a
ContactMesh (a cube written by the test) in an ElasticFoundationForce against a ContactHalfSpace
and a SmoothSphereHalfSpaceForce between a ContactSphere and that half space, converts; the
elastic foundation and its mesh are listed as skipped with what that changes, the smooth force
becomes a pair, and the model steps: the ball lands on the floor, the block falls through it."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from o2m.convert.converter import ConvertOptions, convert
from o2m.osim import runtime

FAST = ConvertOptions(quick=True, fit_mechanics=False, fit_wraps=False)
#: A 10-cm cube around its body's origin (OBJ, outward faces).
CUBE = ("v -0.05 -0.05 -0.05\nv 0.05 -0.05 -0.05\nv 0.05 0.05 -0.05\nv -0.05 0.05 -0.05\n"
        "v -0.05 -0.05 0.05\nv 0.05 -0.05 0.05\nv 0.05 0.05 0.05\nv -0.05 0.05 0.05\n"
        "f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\n"
        "f 4 1 5\nf 4 5 8\n")


def _write_model(folder: Path) -> Path:
    """ground (half space 'floor', normal +y) with a free 'ball' (sphere, smooth contact) and a free
    'block' (the cube mesh, elastic foundation); OpenSim must load it and realize its forces."""
    osim = runtime.opensim()
    (folder / "cube.obj").write_text(CUBE)
    m = osim.Model()
    m.setName("contacts")
    for name, mass, y in (("ball", 1.0, 0.2), ("block", 2.0, 0.4)):
        body = osim.Body(name, mass, osim.Vec3(0), osim.Inertia(1e-3 * mass))
        m.addBody(body)
        joint = osim.FreeJoint(f"{name}_free", m.getGround(), body)
        m.addJoint(joint)
        joint.upd_coordinates(4).setDefaultValue(y)  # its height
    floor = osim.ContactHalfSpace(osim.Vec3(0), osim.Vec3(0, 0, -np.pi / 2), m.getGround(), "floor")
    sphere = osim.ContactSphere(0.05, osim.Vec3(0), m.getBodySet().get("ball"), "ball_sphere")
    mesh = osim.ContactMesh("cube.obj", osim.Vec3(0), osim.Vec3(0), m.getBodySet().get("block"), "block_mesh")
    for geometry in (floor, sphere, mesh):
        m.addContactGeometry(geometry)
    foundation = osim.ElasticFoundationForce()
    foundation.setName("foundation")
    for geometry in ("block_mesh", "floor"):
        foundation.addGeometry(geometry)
    foundation.setStiffness(1e6)
    foundation.setDissipation(1.0)
    m.addForce(foundation)
    smooth = osim.SmoothSphereHalfSpaceForce("smooth", sphere, floor)
    smooth.set_stiffness(1e7)  # OpenSim's default, 1 N/m², holds nothing up
    smooth.set_dissipation(0.5)
    m.addForce(smooth)
    m.finalizeConnections()
    path = folder / "contacts.osim"
    m.printToXML(str(path))
    loaded = osim.Model(str(path))
    loaded.realizeDynamics(loaded.initSystem())  # OpenSim 4.6 loads it and computes its contact
    return path


def test_unconverted_contact_is_skipped_smooth_contact_converted(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # OpenSim's ContactMesh reads its file from the working folder when made
    conv = convert(_write_model(tmp_path), tmp_path / "out", FAST)
    skipped = {(s.element, s.name): s.reason for s in conv.report.skipped}
    assert set(skipped) == {("ElasticFoundationForce", "foundation"), ("ContactMesh", "block_mesh")}
    assert "pass through each other" in skipped[("ElasticFoundationForce", "foundation")]
    assert "no converted force uses" in skipped[("ContactMesh", "block_mesh")]
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    assert m.ngeom == 2 and m.npair == 1 and conv.report.counts["other forces"] == 1
    d = mujoco.MjData(m)
    for _ in range(500):
        mujoco.mj_step(m, d)
    assert np.isfinite(d.qpos).all()
    assert d.qpos[m.jnt_qposadr[m.joint("ball_free_coord_4").id]] > 0.0  # the ball rests on the floor
    assert d.qpos[m.jnt_qposadr[m.joint("block_free_coord_4").id]] < 0.0  # the block falls through it
