"""Tendon lengths along trajectories: a smooth path has no jump, a discontinuity is found."""

from __future__ import annotations

import mujoco
import numpy as np

from o2m.mj.tendons import tendon_length_jumps

WRAPPED = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <site name="origin" pos="-0.3 0 0.2"/>
    <body name="upper">
      <joint name="shoulder" type="hinge" axis="0 1 0"/>
      <geom name="drum" type="cylinder" size="0.05 0.05" euler="90 0 0" mass="1"/>
      <site name="side" pos="0 0 0.1"/>
      <body name="lower" pos="0.4 0 0">
        <joint name="elbow" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="1"/>
        <site name="insertion" pos="0.2 0 0"/>
      </body>
    </body>
  </worldbody>
  <tendon>
    <spatial name="over_drum">
      <site site="origin"/><geom geom="drum" sidesite="side"/><site site="insertion"/>
    </spatial>
  </tendon>
  <actuator>
    <motor joint="shoulder" gear="1"/><motor joint="elbow" gear="1"/>
  </actuator>
</mujoco>
"""


def _sweep(model: mujoco.MjModel, shoulder: tuple[float, float], steps: int) -> np.ndarray:
    """qpos (steps + 1, 2): the shoulder swept over ``shoulder`` (radians), the elbow bending."""
    return np.column_stack([np.linspace(*shoulder, steps + 1), np.linspace(0.2, 1.1, steps + 1)])


def test_a_smooth_wrapped_path_has_no_jump():
    model = mujoco.MjModel.from_xml_string(WRAPPED)
    excess, _ = tendon_length_jumps(model, _sweep(model, (0.0, 1.5), 300))
    assert excess[0] < 1e-5, excess


def test_a_path_flipping_round_its_wrap_is_found():
    """Swept further, MuJoCo's path jumps to the drum's other side (its side site has turned
    with the drum): centimetres in one step."""
    model = mujoco.MjModel.from_xml_string(WRAPPED)
    qpos = _sweep(model, (0.0, 3.0), 300)
    excess, at = tendon_length_jumps(model, qpos)
    assert excess[0] > 0.01, excess
    assert 1.5 < qpos[at[0], 0] < 3.0
