"""ModelPair.os_state on a model with a coordinate coupler: an assembly OpenSim cannot satisfy
(an independent coordinate set beyond its clamped range) must not change later assemblies.

OpenSim's ``Model::assemble`` relaxes the constraints (weight 20 instead of infinite) when one
assembly fails, and keeps them relaxed: every later assembled coordinate then moved 1/21 of its
step (Rajagopal2016's knee after a spike test's neighbour below its range: every later
``-dL/dq`` about it in the wrap fit 21 times too small)."""

from __future__ import annotations

import opensim as osim
import pytest

from o2m.convert.converter import convert
from o2m.osim.pair import ModelPair
from tests.helpers import add_coupler, convert_options

osim.Logger.setLevelString("off")


def _coupled_arm(path) -> None:
    """Ground -> arm1 (pin q1, range [0, 1] rad, clamped) -> arm2 (pin q2 at arm1's (0.2, 0, 0)),
    q2 = q1 by a CoordinateCouplerConstraint."""
    m = osim.Model()
    m.setName("coupled_arm")
    bodies = [osim.Body(f"arm{k}", 1.0, osim.Vec3(0.1, 0, 0), osim.Inertia(0.01, 0.01, 0.01)) for k in (1, 2)]
    for b in bodies:
        m.addBody(b)
    for k, (parent, at) in enumerate(((m.getGround(), osim.Vec3(0)), (bodies[0], osim.Vec3(0.2, 0, 0))), start=1):
        j = osim.PinJoint(f"pin{k}", parent, at, osim.Vec3(0), bodies[k - 1], osim.Vec3(0), osim.Vec3(0))
        c = j.updCoordinate()
        c.setName(f"q{k}")
        c.setRangeMin(0.0 if k == 1 else -2.0)
        c.setRangeMax(1.0 if k == 1 else 2.0)
        c.setDefaultClamped(k == 1)
        m.addJoint(j)
    add_coupler(m, "couple", "q1", "q2", osim.LinearFunction(1.0, 0.0))
    m.finalizeConnections()
    m.printToXML(str(path))


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    folder = tmp_path_factory.mktemp("coupled")
    _coupled_arm(folder / "coupled.osim")
    conv = convert(folder / "coupled.osim", folder / "out", convert_options(fit_wraps=False, fit_mechanics=False))
    return ModelPair(folder / "coupled.osim", conv.xml)


def _moved(pair: ModelPair, step: float = 1e-5) -> float:
    """How far q1 moves, in steps, when set 0.5 + step rather than 0.5 - step and assembled."""
    q1 = pair.coord("q1")
    up, dn = pair.os_state({"q1": 0.5 + step}), pair.os_state({"q1": 0.5 - step})
    return (q1.getValue(up) - q1.getValue(dn)) / (2 * step)


def test_a_failed_assembly_leaves_later_ones_exact(pair):
    assert _moved(pair) == pytest.approx(1.0, abs=1e-6)
    pair.os_state({"q1": -0.1})  # below q1's clamped range: OpenSim relaxes its constraints
    assert _moved(pair) == pytest.approx(1.0, abs=1e-6)  # 1/21 while the relaxation stayed
    state = pair.os_state({"q1": 0.3})
    assert pair.os_model.getCoordinateSet().get("q2").getValue(state) == pytest.approx(0.3, abs=1e-9)


def _held_block(path) -> None:
    """Ground -> arm (pin q1) with a free block held at its end by a PointConstraint; ground ->
    tail (pin q2 = q1 by a coupler); ground -> other (pin q3, clamped to [-1, 1]), which no
    constraint involves."""
    m = osim.Model()
    m.setName("held_block")
    bodies = {n: osim.Body(n, 1.0, osim.Vec3(0, -0.1, 0), osim.Inertia(0.01, 0.01, 0.01))
              for n in ("arm", "tail", "other", "block")}
    for b in bodies.values():
        m.addBody(b)
    for k, name in ((1, "arm"), (2, "tail"), (3, "other")):
        j = osim.PinJoint(f"pin{k}", m.getGround(), osim.Vec3(0.3 * k, 0, 0), osim.Vec3(0), bodies[name],
                          osim.Vec3(0), osim.Vec3(0))
        j.updCoordinate().setName(f"q{k}")
        j.updCoordinate().setRangeMin(-1.0)
        j.updCoordinate().setRangeMax(1.0)
        j.updCoordinate().setDefaultClamped(k == 3)
        m.addJoint(j)
    m.addJoint(osim.FreeJoint("free", m.getGround(), osim.Vec3(0), osim.Vec3(0), bodies["block"], osim.Vec3(0),
                              osim.Vec3(0)))
    add_coupler(m, "couple", "q1", "q2", osim.LinearFunction(1.0, 0.0))
    m.addConstraint(osim.PointConstraint(bodies["arm"], osim.Vec3(0, -0.5, 0), bodies["block"], osim.Vec3(0)))
    m.finalizeConnections()
    m.printToXML(str(path))


class _Counted:
    """An OpenSim model that counts its ``assemble`` calls."""

    def __init__(self, model):
        self.model, self.calls = model, 0

    def __getattr__(self, name):
        return getattr(self.model, name)

    def assemble(self, state):
        self.calls += 1
        return self.model.assemble(state)


def test_a_step_no_other_constraint_involves_skips_the_assembler(tmp_path):
    _held_block(tmp_path / "held.osim")
    conv = convert(tmp_path / "held.osim", tmp_path / "out", convert_options(fit_wraps=False, fit_mechanics=False))
    pair = ModelPair(tmp_path / "held.osim", conv.xml)
    pair.os_model = counted = _Counted(pair.os_model)
    values = pair.os_indep_values(pair.os_state({"q1": 0.4, "q3": 0.2}))
    assert counted.calls == 1
    cs = pair.os_model.getCoordinateSet()
    for step in (0.3, 0.9):  # q3 to 0.5 and 1.1 (beyond its clamped range: the assembler's to keep)
        state = pair.os_state({**values, "q3": 0.2 + step})
        assert counted.calls == (1 if step < 0.5 else 2)
        reference = osim.State(pair.init_state)  # as os_state assembles: from the initial state
        for c in pair.indep:
            c.setValue(reference, values[pair.name(c)] + (step if pair.name(c) == "q3" else 0.0), False)
        pair.os_model.updateAssemblyConditions(reference)
        pair.os_model.model.assemble(reference)
        for c in pair.coords:  # the assembler's pose, the coupler's dependent included
            assert c.getValue(state) == pytest.approx(c.getValue(reference), abs=1e-9), c.getName()
    assert cs.get("q2").getValue(state) == pytest.approx(values["q1"], abs=1e-12)
    pair.os_state({**values, "q1": values["q1"] + 1e-5})  # moves the held point: assembled
    assert counted.calls == 3
