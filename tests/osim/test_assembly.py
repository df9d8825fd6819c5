"""o2m.osim.assembly: the coordinates of OpenSim's assembled default state, without the held
ones and the couplers' dependents."""

from __future__ import annotations

import opensim as osim
import pytest

from o2m.osim.assembly import assembled_defaults
from tests.helpers import add_coupler

osim.Logger.setLevelString("off")


def _arm_with_block(path) -> None:
    """Ground -> arm (pin q1, default 0.3) -> forearm (pin q2 = 2 q1 by a coupler; pin q3
    locked); a free block whose default centre is 0.05 m off the forearm's end, where a
    PointConstraint holds it."""
    m = osim.Model()
    m.setName("arm_with_block")
    parent = m.getGround()
    for k, name in ((1, "arm"), (2, "forearm"), (3, "hand")):
        body = osim.Body(name, 1.0, osim.Vec3(0, -0.1, 0), osim.Inertia(0.01, 0.01, 0.01))
        m.addBody(body)
        j = osim.PinJoint(f"pin{k}", parent, osim.Vec3(0, -0.2 if k > 1 else 0, 0), osim.Vec3(0),
                          body, osim.Vec3(0), osim.Vec3(0))
        j.updCoordinate().setName(f"q{k}")
        j.updCoordinate().setDefaultValue(0.3 if k == 1 else 0.6 if k == 2 else 0.1)
        j.updCoordinate().setDefaultLocked(k == 3)
        m.addJoint(j)
        parent = body
    add_coupler(m, "q2_from_q1", "q1", "q2", osim.LinearFunction(2.0, 0.0))
    block = osim.Body("block", 0.5, osim.Vec3(0), osim.Inertia(0.001, 0.001, 0.001))
    m.addBody(block)
    free = osim.FreeJoint("free", m.getGround(), osim.Vec3(0), osim.Vec3(0), block, osim.Vec3(0), osim.Vec3(0))
    m.addJoint(free)
    for i, v in enumerate((0.0, 0.0, 0.0, 0.05, -0.5, 0.0)):
        free.upd_coordinates(i).setDefaultValue(v)
    m.addConstraint(osim.PointConstraint(m.getBodySet().get("hand"), osim.Vec3(0, -0.2, 0), block, osim.Vec3(0)))
    m.finalizeConnections()
    m.printToXML(str(path))


def test_assembled_defaults_are_opensims_initial_state(tmp_path):
    path = tmp_path / "arm.osim"
    _arm_with_block(path)
    coords = {c.name: c for c in assembled_defaults(path)}
    assert "q2" not in coords and "q3" not in coords  # the coupler's dependent; locked
    m = osim.Model(str(path))
    s = m.initSystem()
    cs = m.getCoordinateSet()
    for name, c in coords.items():
        assert c.value == pytest.approx(cs.get(name).getValue(s), abs=1e-14)
        assert c.default_value == cs.get(name).getDefaultValue()
    assert max(abs(c.moved) for c in coords.values()) > 0.01  # the block's 0.05 m, shared out
