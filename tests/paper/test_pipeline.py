"""Pieces of the paper's pipeline that need no dataset: the corrections' cache key."""

from __future__ import annotations

import copy

import mujoco

from o2m.paper.pipeline import FULL, QUICK, correction_key

MODEL = """
<mujoco><worldbody><body><joint name="j" type="hinge" damping="{d}"/><geom size="0.1" mass="1"/></body></worldbody>
</mujoco>"""


def test_correction_key_changes_with_any_model_field_sets_or_budget():
    m = mujoco.MjModel.from_xml_string(MODEL.format(d=0.5))
    key = correction_key(m, [1, 2], FULL, True)
    assert correction_key(copy.copy(m), [1, 2], FULL, True) == key
    other = copy.copy(m)
    other.dof_damping[0] = 0.5 + 1e-12
    assert correction_key(other, [1, 2], FULL, True) != key
    assert correction_key(m, [1, 3], FULL, True) != key
    assert correction_key(m, [1, 2], QUICK, True) != key
    assert correction_key(m, [1, 2], FULL, False) != key
