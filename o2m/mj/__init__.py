"""The MuJoCo side: posing a converted model, its tendons, its muscle curves, and simulating it.

Nothing here knows OpenSim. MuJoCo is Z-up; joint values are radians or metres.
"""

from o2m.mj.muscle import mujoco_muscle_force
from o2m.mj.posing import JointEquality, joint_equality_plan, joint_qpos_address, load_mjcf, pose_mujoco
from o2m.mj.simulate import Trajectories, controls_from_excitations, initial_state, rollout, step_loop
from o2m.mj.tendons import mujoco_moment_arms, mujoco_tendon_lengths

__all__ = [
    "JointEquality",
    "Trajectories",
    "controls_from_excitations",
    "initial_state",
    "joint_equality_plan",
    "joint_qpos_address",
    "load_mjcf",
    "mujoco_moment_arms",
    "mujoco_muscle_force",
    "mujoco_tendon_lengths",
    "pose_mujoco",
    "rollout",
    "step_loop",
]
