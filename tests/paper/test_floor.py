"""The floor's runs (o2m.paper.floor) on a pendulum whose muscle's moment arm changes with the pose."""

from __future__ import annotations

from types import SimpleNamespace

import mujoco
import numpy as np

from o2m.mj.simulate import controls_from_forces, force_driven
from o2m.paper.floor import (
    arm_corrected_run,
    arm_slopes,
    arms_along,
    generalized_force_run,
    mujoco_arms,
    muscle_feedback_run,
    replay_instability,
    tendon_force_run,
)
from o2m.paper.passive_stage import crossing
from tests.helpers import MUSCLE_PENDULUM


def _experiment(tmp_path):
    """A one-muscle 'OpenSim' dataset made by the force-driven model itself: its own tendon forces and trajectory."""
    xml = tmp_path / "pendulum.xml"
    xml.write_text(MUSCLE_PENDULUM)
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
                         coordinates=np.array(q)[None, :, None], speeds=np.array(v)[None, :, None],
                         opensim_activations=np.full((1, len(t), 1), 0.5))
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


def _shifted(exp, dq: float):
    """``exp`` with its recorded trajectory started ``dq`` rad off (the rest unchanged)."""
    shifted = SimpleNamespace(**{**vars(exp), "dataset": SimpleNamespace(**vars(exp.dataset))})
    start = exp.dataset.coordinates.copy()
    start[:, 0] += dq
    shifted.dataset.coordinates = np.concatenate([start[:, :1], exp.dataset.coordinates[:, 1:]], axis=1)
    return shifted


def test_frozen_moment_arms_ignore_the_pose_the_live_ones_follow(tmp_path):
    """Started 0.2 rad off, the live run's torque changes with its pose, the frozen run's does not."""
    exp, model = _experiment(tmp_path)
    shifted = _shifted(exp, 0.2)
    live, frozen = tendon_force_run(shifted, model, [0]), generalized_force_run(shifted, model, [0])
    assert np.abs(live - frozen).max() > 1e-3
    assert crossing(exp, model, "swing") == ["lifter"]


def test_moment_arms_along_the_recorded_states_report_an_offset_and_its_torque(tmp_path):
    exp, model = _experiment(tmp_path)
    arms = mujoco_arms(model, ["lifter"], ["swing"])
    along = arms_along(exp, ["lifter"], [0], 10, lambda pose: arms(pose) - 1e-4, arms)  # "OpenSim" 0.1 mm shorter
    assert len(along.samples) == 26 and along.mujoco.shape == (26, 1, 1)
    (muscle, dof, rms, worst, _), = along.rows()
    assert (muscle, dof) == ("lifter", "swing") and abs(rms - 0.1) < 1e-9 and abs(worst - 0.1) < 1e-9
    opensim, mujoco_ = along.torques()
    assert np.allclose(mujoco_ - opensim, 1e-4 * along.forces)
    h = 1e-6  # the Jacobian moment arm is -dL/dq
    q0 = float(exp.dataset.coordinates[0, 0, 0])
    data = mujoco.MjData(model)
    lengths = []
    for q in (q0 - h, q0 + h):
        data.qpos[0] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_tendon(model, data)
        lengths.append(data.ten_length[0])
    assert abs(along.mujoco[0, 0, 0] + (lengths[1] - lengths[0]) / (2 * h)) < 1e-8


def test_arm_slopes_are_central_differences_about_each_coordinate():
    def arms(pose):  # (M=2, C=1): x² y and sin x
        return np.array([[pose["x"] ** 2 * pose["y"]], [np.sin(pose["x"])]])
    slopes = arm_slopes(arms, {"x": 0.3, "y": 2.0}, ["x", "y"], h=1e-5)
    assert slopes.shape == (2, 1, 2)
    assert np.allclose(slopes[:, 0], [[1.2, 0.09], [np.cos(0.3), 0.0]], atol=1e-8)


def test_a_moment_arm_correction_changes_the_live_run_by_its_torque(tmp_path):
    exp, model = _experiment(tmp_path)
    live = tendon_force_run(exp, model, [0])
    unchanged = arm_corrected_run(exp, model, [0], ["lifter"], lambda pose: np.zeros((1, 1)))
    assert np.abs(unchanged - live).max() < 1e-12
    arms = mujoco_arms(model, ["lifter"], ["swing"])
    cancelled = arm_corrected_run(exp, model, [0], ["lifter"], lambda pose: -arms(pose))  # no muscle torque left
    unpowered = tendon_force_run(SimpleNamespace(**{**vars(exp), "dataset": SimpleNamespace(
        **{**vars(exp.dataset), "tendon_forces": 0 * exp.dataset.tendon_forces})}), model, [0])
    assert np.abs(cancelled - unpowered).max() < 1e-9 < np.abs(live - unpowered).max()
    longer = arm_corrected_run(exp, model, [0], ["lifter"], lambda pose: np.full((1, 1), 1e-3))
    assert np.abs(longer - live).max() > 1e-3


def test_muscle_feedback_vanishes_on_the_recorded_trajectory_and_a_stiff_muscle_pulls_back_to_it(tmp_path):
    """A 'muscle' pulling harder the longer and the faster-lengthening its tendon (2000 N/m, 50 N s/m
    at activation 0.5) answers a start 0.2 rad off: the run ends nearer the recorded trajectory than
    the replay of the recorded forces, which nothing pulls back."""
    exp, model = _experiment(tmp_path)
    stiff = MUSCLE_PENDULUM.replace('<muscle name="lifter" tendon="lifter" force="40" lengthrange="0.3 0.9"/>',
                             '<general name="lifter" tendon="lifter" dyntype="filter" dynprm="0.01" '
                             'gaintype="affine" gainprm="0 -4000 -100"/>')
    muscle_model = mujoco.MjModel.from_xml_string(stiff)
    ref = exp.dataset.coordinates
    assert np.abs(muscle_feedback_run(exp, model, muscle_model, [0]) - ref).max() < 1e-9
    shifted = _shifted(exp, 0.2)
    replay, answered = tendon_force_run(shifted, model, [0]), muscle_feedback_run(shifted, model, muscle_model, [0])
    end = slice(-50, None)
    assert np.abs(answered[0, end] - ref[0, end]).mean() < 0.2 * np.abs(replay[0, end] - ref[0, end]).mean()


def test_replay_instability_is_the_force_times_the_moment_arm_slope_over_the_inertia(tmp_path):
    exp, model = _experiment(tmp_path)
    slopes, rates = replay_instability(exp, model, [0], 50, dof="swing")
    assert slopes.shape == rates.shape == (6,)
    data, h = mujoco.MjData(model), 1e-4
    for j, k in enumerate(range(0, 251, 50)):
        lengths = []
        for dq in (-h, 0.0, h):
            data.qpos[0] = exp.dataset.coordinates[0, k, 0] + dq
            mujoco.mj_forward(model, data)
            lengths.append(data.ten_length[0])
        arm_slope = -(lengths[0] - 2 * lengths[1] + lengths[2]) / h**2  # moment arm -dL/dq, its derivative
        assert abs(slopes[j] - exp.dataset.tendon_forces[0, k, 0] * arm_slope) < 1e-4 * (1 + abs(slopes[j]))
        inertia = np.zeros(1)  # one hinge: the mass matrix is its moment of inertia (kg m²)
        mujoco.mj_mulM(model, data, inertia, np.ones(1))
        assert abs(rates[j] ** 2 * inertia[0] - max(slopes[j], 0.0)) < 1e-6 * (1 + abs(slopes[j]))
