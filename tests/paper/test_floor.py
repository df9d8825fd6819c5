"""The floor's runs (o2m.paper.floor) on a pendulum whose muscle's moment arm changes with the pose."""

from __future__ import annotations

from types import SimpleNamespace

import mujoco
import numpy as np

from o2m.mj.simulate import controls_from_forces, force_driven
from o2m.paper.floor import crossing, generalized_force_run, tendon_force_run

PENDULUM = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <body name="link" pos="0 0 1">
      <joint name="swing" type="hinge" axis="0 1 0" damping="0.05"/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.03" mass="1"/>
      <site name="tip" pos="0.5 0 0"/>
    </body>
    <site name="anchor" pos="0.3 0 1.4"/>
  </worldbody>
  <tendon><spatial name="lifter"><site site="anchor"/><site site="tip"/></spatial></tendon>
  <actuator><muscle name="lifter" tendon="lifter" force="40" lengthrange="0.3 0.9"/></actuator>
</mujoco>
"""


def _experiment(tmp_path):
    """A one-muscle 'OpenSim' dataset made by the force-driven model itself: its own tendon forces and trajectory."""
    xml = tmp_path / "pendulum.xml"
    xml.write_text(PENDULUM)
    model = force_driven(xml, ["lifter"])
    t = np.arange(251) * model.opt.timestep
    forces = (15.0 + 10.0 * np.sin(2 * np.pi * 2 * t))[None, :, None]  # (1, T, 1) N
    ctrl = controls_from_forces(model, ["lifter"], forces)[0]
    data = mujoco.MjData(model)
    data.qpos[0] = 0.3
    q, v = [data.qpos[0]], [data.qvel[0]]
    for k in range(len(ctrl)):
        data.ctrl[:] = ctrl[k]
        mujoco.mj_step(model, data)
        q.append(data.qpos[0])
        v.append(data.qvel[0])
    ds = SimpleNamespace(muscle_names=["lifter"], tendon_forces=forces, coordinate_names=["swing"],
                         coordinates=np.array(q)[None, :, None], speeds=np.array(v)[None, :, None])
    exp = SimpleNamespace(dataset=ds, muscles=["lifter"], dofs=["swing"], xml=xml)
    return exp, model


def test_both_runs_follow_the_trajectory_their_own_forces_made(tmp_path):
    exp, model = _experiment(tmp_path)
    ref = exp.dataset.coordinates
    live = tendon_force_run(exp, model, [0])
    assert np.abs(live - ref).max() < 1e-9
    frozen = generalized_force_run(exp, model, [0])
    assert np.abs(frozen - ref).max() < 1e-9  # at the very states the live run visits, the same joint forces
    none_frozen = generalized_force_run(exp, model, [0], frozen=[])
    assert np.abs(none_frozen - live).max() < 1e-9


def test_frozen_moment_arms_ignore_the_pose_the_live_ones_follow(tmp_path):
    """Started 0.2 rad off, the live run's torque changes with its pose, the frozen run's does not."""
    exp, model = _experiment(tmp_path)
    shifted = SimpleNamespace(**{**vars(exp), "dataset": SimpleNamespace(**vars(exp.dataset))})
    start = exp.dataset.coordinates.copy()
    start[:, 0] += 0.2
    shifted.dataset.coordinates = np.concatenate([start[:, :1], exp.dataset.coordinates[:, 1:]], axis=1)
    live, frozen = tendon_force_run(shifted, model, [0]), generalized_force_run(shifted, model, [0])
    assert np.abs(live - frozen).max() > 1e-3
    assert crossing(exp, model, "swing") == ["lifter"]
