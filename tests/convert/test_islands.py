"""Constraint islands are switched off only when a model can never have more than one."""

from __future__ import annotations

import mujoco
import pytest

from o2m.convert.islands import always_one_island, disable_single_island

TWO_ARMS = """<mujoco><worldbody>
  <body name="a"><joint name="qa" type="hinge"/><geom size="0.1" contype="0" conaffinity="0"/></body>
  <body name="b" pos="1 0 0"><joint name="qb" type="hinge"/><geom size="0.1" contype="0" conaffinity="0"/>
    <body name="b2" pos="0 0 1"><joint name="qb2" type="slide"/><geom size="0.1" contype="0" conaffinity="0"/></body>
  </body></worldbody>{equality}</mujoco>"""


@pytest.mark.parametrize(("equality", "one"), [
    ("", False),  # two trees, nothing ties them: two islands when both have constraints
    ('<equality><joint joint1="qa" joint2="qb2"/></equality>', True),
    ('<equality><joint joint1="qa" joint2="qb2" active="false"/></equality>', False),
    ('<equality><joint joint1="qb" joint2="qb2"/></equality>', False),  # within one tree only
    ('<equality><joint joint1="qa"/></equality>', False),  # a joint held alone ties no trees
])
def test_trees_tied_by_joint_equalities_make_one_island(equality, one):
    assert always_one_island(mujoco.MjModel.from_xml_string(TWO_ARMS.format(equality=equality))) is one


def test_one_tree_is_one_island_and_no_dofs_none():
    one_tree = '<mujoco><worldbody><body><joint type="hinge"/><geom size="0.1"/></body></worldbody></mujoco>'
    assert always_one_island(mujoco.MjModel.from_xml_string(one_tree))
    no_dofs = '<mujoco><worldbody><geom size="1"/></worldbody></mujoco>'
    assert not always_one_island(mujoco.MjModel.from_xml_string(no_dofs))


def test_the_flag_is_set_on_the_spec_only_for_one_island():
    for equality, one in (("", False), ('<equality><joint joint1="qa" joint2="qb2"/></equality>', True)):
        spec = mujoco.MjSpec.from_string(TWO_ARMS.format(equality=equality))
        assert disable_single_island(spec, spec.compile()) is one
        flags = mujoco.MjModel.from_xml_string(spec.to_xml()).opt.disableflags
        assert bool(flags & mujoco.mjtDisableBit.mjDSBL_ISLAND) is one


def test_a_converted_one_tree_model_has_islands_off_and_says_so(tmp_path):
    from o2m.convert.converter import convert
    from tests.helpers import convert_options, pin_pendulum

    model, _ = pin_pendulum("islands")
    model.finalizeConnections()
    model.initSystem()
    model.printToXML(str(tmp_path / "islands.osim"))
    conv = convert(tmp_path / "islands.osim", tmp_path / "out", convert_options(fit_wraps=False, fit_mechanics=False))
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    assert m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_ISLAND
    assert any("constraint islands disabled" in note for note in conv.report.notes)
