"""o2m.convert.reduced: the reduced models the wrap fit evaluates."""

import mujoco
import numpy as np

from o2m.convert.reduced import reduced_xml, without_unused

_XML = """
<mujoco>
  <worldbody>
    <site name="origin" pos="0 0 0.3"/>
    <site name="unused_world"/>
    <body name="upper">
      <joint name="shoulder" type="hinge" axis="0 1 0"/>
      <inertial pos="0 0 -0.1" mass="1" diaginertia="0.01 0.01 0.01"/>
      <geom name="bone" type="capsule" fromto="0 0 0 0 0 -0.3" size="0.02"/>
      <geom name="wrap" type="cylinder" size="0.03 0.05" pos="0 0 -0.3" euler="1.5708 0 0"/>
      <site name="side" pos="0.08 0 -0.3"/>
      <site name="unused_upper" pos="0 0.1 0"/>
      <body name="lower" pos="0 0 -0.3">
        <joint name="elbow" type="hinge" axis="0 1 0"/>
        <geom name="massive" type="sphere" size="0.05" pos="0 0 -0.2"/>
        <site name="insertion" pos="0.02 0 -0.2"/>
        <frame pos="0 0 -0.1"><site name="unused_frame"/></frame>
      </body>
    </body>
  </worldbody>
  <tendon>
    <spatial name="muscle">
      <site site="origin"/>
      <geom geom="wrap" sidesite="side"/>
      <site site="insertion"/>
    </spatial>
    <spatial name="other">
      <site site="origin"/>
      <site site="unused_upper"/>
    </spatial>
  </tendon>
</mujoco>
"""


def _length_and_jacobian(xml: str, qpos: np.ndarray) -> tuple[float, np.ndarray]:
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qpos[:] = qpos
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)
    mujoco.mj_tendon(m, d)
    jac = np.zeros(m.nv)
    adr, nnz = int(m.ten_J_rowadr[0]), int(m.ten_J_rownnz[0])
    jac[m.ten_J_colind[adr:adr + nnz]] = d.ten_J[adr:adr + nnz]
    return float(d.ten_length[0]), jac


def test_without_unused_keeps_what_the_tendon_names_and_its_values():
    one = reduced_xml(_XML, "muscle")
    pruned = without_unused(one)
    m = mujoco.MjModel.from_xml_string(pruned)
    assert sorted(m.site(i).name for i in range(m.nsite)) == ["insertion", "origin", "side"]
    # the bone goes (its body has an <inertial>); the wrap stays; the lower body, without an
    # <inertial>, keeps its geom and with it its mass
    assert sorted(m.geom(i).name for i in range(m.ngeom)) == ["massive", "wrap"]
    full = mujoco.MjModel.from_xml_string(one)
    assert np.array_equal(m.body_mass, full.body_mass)
    for q in np.random.default_rng(0).uniform(-1.5, 1.5, (20, 2)):
        length, jac = _length_and_jacobian(one, q)
        length_pruned, jac_pruned = _length_and_jacobian(pruned, q)
        assert length_pruned == length and np.array_equal(jac_pruned, jac)


def test_without_unused_keeps_names_asked_for():
    pruned = without_unused(reduced_xml(_XML, "muscle"), keep=["unused_frame"])
    m = mujoco.MjModel.from_xml_string(pruned)
    assert "unused_frame" in [m.site(i).name for i in range(m.nsite)]
