"""o2m.paper.model_key: a compiled model identified up to rounding."""

import copy

import mujoco
import numpy as np

from o2m.paper.model_key import FIELD_RTOL, model_structure, model_values, same_values, value_difference

MODEL = """
<mujoco><worldbody><body pos="0 0 1"><joint name="j" type="hinge" damping="0.5"/>
<geom size="0.1" mass="1"/></body></worldbody></mujoco>"""


def _model():
    return mujoco.MjModel.from_xml_string(MODEL)


def test_values_within_rounding_are_the_same_model():
    m = _model()
    other = copy.copy(m)
    other.dof_damping[0] *= 1 + 1e-12
    other.body_pos[1, 0] = 1e-18  # a 0 that rounding left a little off, beside values of order 1
    assert model_structure(other) == model_structure(m)
    assert same_values(model_values(m), model_values(other))


def test_a_value_changed_beyond_the_tolerance_is_another_model():
    m = _model()
    other = copy.copy(m)
    other.dof_damping[0] *= 1 + 10 * FIELD_RTOL
    assert not same_values(model_values(m), model_values(other))
    changed = f"dof_damping: 0.5 -> {0.5 * (1 + 10 * FIELD_RTOL):.6g}"
    assert value_difference(model_values(m), model_values(other)) == changed
    small = copy.copy(m)
    small.body_mass[1] *= 1 + 10 * FIELD_RTOL  # relative to the value itself, not to the array's largest
    assert not same_values(model_values(m), model_values(small))


def test_the_structure_and_the_fields_must_match():
    m = _model()
    other = mujoco.MjModel.from_xml_string(MODEL.replace('type="hinge"', 'type="slide"'))
    assert model_structure(other) != model_structure(m)
    values = model_values(m)
    assert not same_values({k: v for k, v in values.items() if k != "dof_damping"}, values)
    assert not same_values({**values, "dof_damping": np.zeros(2)}, values)
    with_nan = {**values, "dof_damping": np.array([np.nan])}
    assert same_values(with_nan, with_nan) and not same_values(values, with_nan)
