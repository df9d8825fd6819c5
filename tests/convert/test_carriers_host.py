"""Path-point sites on a body without joints go on the nearest ancestor that has some.

ground -> "base" (WeldJoint, offset and rotated) and ground -> arm (PinJoint q) -> "hand" (WeldJoint,
offset and rotated) -> "finger" (WeldJoint). A PathActuator runs base P1 -> arm P2 -> hand P3 ->
finger P4: P3 and P4 are sites on the arm (MuJoCo then computes no Jacobian for the segments
between them and P2), P1 stays on the base (no ancestor short of the world has joints), and every
site keeps its OpenSim location in its OpenSim body at every q.
"""

from __future__ import annotations

import mujoco
import numpy as np
import opensim as osim
import pytest

from o2m.convert.converter import convert
from tests.helpers import convert_options, pin_pendulum

osim.Logger.setLevelString("error")

#: Each path point: (OpenSim body, location in it, m).
POINTS = {"P1": ("base", (0.02, 0.05, 0.01)), "P2": ("arm", (0.1, 0.03, 0.0)),
          "P3": ("hand", (0.05, -0.02, 0.01)), "P4": ("finger", (0.03, 0.01, -0.02))}


def _model(path) -> None:
    m, arm = pin_pendulum("hosts")
    bodies = {"arm": arm}
    for name, parent, offset, rot in (("base", None, (0.0, -0.1, 0.05), (0.3, 0.0, 0.2)),
                                      ("hand", "arm", (0.35, 0.0, 0.0), (0.1, 0.2, 0.3)),
                                      ("finger", "hand", (0.08, 0.01, 0.0), (0.0, 0.4, -0.1))):
        body = osim.Body(name, 0.5, osim.Vec3(0.02, 0, 0), osim.Inertia(0.001, 0.001, 0.001))
        m.addBody(body)
        frame = m.getGround() if parent is None else bodies[parent]
        m.addJoint(osim.WeldJoint(f"{name}_weld", frame, osim.Vec3(*offset), osim.Vec3(*rot),
                                  body, osim.Vec3(0), osim.Vec3(0)))
        bodies[name] = body
    pa = osim.PathActuator()
    pa.setName("act")
    pa.setOptimalForce(100)
    for point, (body, loc) in POINTS.items():
        pa.addNewPathPoint(f"act-{point}", m.getGround() if body == "ground" else bodies[body], osim.Vec3(*loc))
    m.addForce(pa)
    m.finalizeConnections()
    m.initSystem()
    m.printToXML(str(path))


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    folder = tmp_path_factory.mktemp("hosts")
    _model(folder / "hosts.osim")
    conv = convert(folder / "hosts.osim", folder / "out",
                   convert_options(path_forces="kinematic", fit_wraps=False, fit_mechanics=False))
    return mujoco.MjModel.from_xml_path(str(conv.xml))


def test_sites_of_welded_bodies_go_on_the_moving_ancestor(model):
    m = model
    host = {p: m.body(int(m.site_bodyid[m.site(f"act-{p}").id])).name for p in POINTS}
    assert host == {"P1": "base", "P2": "arm", "P3": "arm", "P4": "arm"}


def test_sites_keep_their_opensim_location(model):
    m = model
    d = mujoco.MjData(m)
    for q in np.linspace(-1.0, 1.5, 6):
        d.qpos[m.jnt_qposadr[m.joint("q").id]] = q
        mujoco.mj_kinematics(m, d)
        for p, (body, loc) in POINTS.items():
            b = m.body(body).id
            got = d.xmat[b].reshape(3, 3).T @ (d.site_xpos[m.site(f"act-{p}").id] - d.xpos[b])
            np.testing.assert_allclose(got, loc, atol=1e-12, err_msg=f"{p} at q={q}")
