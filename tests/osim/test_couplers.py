"""o2m.osim.couplers: dependent coordinates set from their couplers, as OpenSim assembles them."""

from __future__ import annotations

import opensim as osim
import pytest

from o2m.osim.couplers import coupler_chain, set_coupled
from tests.helpers import add_coupler

osim.Logger.setLevelString("off")


def _chain_of_three(path, extra_constraint: bool = False) -> None:
    """Ground -> b1 (pin q1) -> b2 (pin q2) -> b3 (pin q3); q3 = 0.5 (q2 + 0.2)² (a polynomial
    of q2 with scale factor 0.5) and q2 = 2 q1 + 0.1, the coupler of q3 added first; with
    ``extra_constraint`` also a WeldConstraint of b3 to ground, not enforced."""
    m = osim.Model()
    m.setName("chain")
    parent = m.getGround()
    for k in (1, 2, 3):
        body = osim.Body(f"b{k}", 1.0, osim.Vec3(0.1, 0, 0), osim.Inertia(0.01, 0.01, 0.01))
        m.addBody(body)
        j = osim.PinJoint(f"pin{k}", parent, osim.Vec3(0.2 if k > 1 else 0, 0, 0), osim.Vec3(0),
                          body, osim.Vec3(0), osim.Vec3(0))
        j.updCoordinate().setName(f"q{k}")
        j.updCoordinate().setRangeMin(-3.0)
        j.updCoordinate().setRangeMax(3.0)
        m.addJoint(j)
        parent = body
    poly = osim.PolynomialFunction(osim.Vector([1.0, 0.4, 0.04]))  # x^2 + 0.4 x + 0.04
    add_coupler(m, "q3_from_q2", "q2", "q3", poly)
    osim.PropertyHelper.setValueDouble(0.5, m.getConstraintSet().get("q3_from_q2").updPropertyByName("scale_factor"))
    add_coupler(m, "q2_from_q1", "q1", "q2", osim.LinearFunction(2.0, 0.1))
    if extra_constraint:
        weld = osim.WeldConstraint("weld", m.getGround(), osim.Transform(), m.getBodySet().get("b3"), osim.Transform())
        weld.set_isEnforced(False)  # not enforced: still only couplers
        m.addConstraint(weld)
    m.finalizeConnections()
    m.printToXML(str(path))


def test_dependents_follow_their_couplers_in_order_as_assembly_sets_them(tmp_path):
    _chain_of_three(tmp_path / "chain.osim")
    model = osim.Model(str(tmp_path / "chain.osim"))
    state = model.initSystem()
    chain = coupler_chain(model, state)
    assert [dep.getName() for dep, _, _, _ in chain] == ["q2", "q3"]
    assert chain[1][3] == 0.5
    cs = model.getCoordinateSet()
    for q1 in (-0.7, 0.0, 0.45):
        explicit, assembled = osim.State(state), osim.State(state)
        for st in (explicit, assembled):
            cs.get("q1").setValue(st, q1, False)
        set_coupled(chain, explicit)
        model.assemble(assembled)
        q2 = 2 * q1 + 0.1
        assert cs.get("q2").getValue(explicit) == pytest.approx(q2, abs=1e-14)
        assert cs.get("q3").getValue(explicit) == pytest.approx(0.5 * (q2 + 0.2) ** 2, abs=1e-14)
        for name in ("q1", "q2", "q3"):
            assert cs.get(name).getValue(explicit) == pytest.approx(cs.get(name).getValue(assembled), abs=1e-7)


def test_an_enforced_constraint_of_another_kind_needs_the_assembler(tmp_path):
    _chain_of_three(tmp_path / "weld.osim", extra_constraint=True)
    model = osim.Model(str(tmp_path / "weld.osim"))
    state = model.initSystem()
    assert coupler_chain(model, state) is not None  # the weld is not enforced
    model.getConstraintSet().get("weld").setIsEnforced(state, True)
    assert coupler_chain(model, state) is None
