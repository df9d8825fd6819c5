"""Comparing a converted model with its OpenSim original: body frames, muscle paths, moment arms, jumps,
and motion under the same muscle excitations.

Every comparison is a number measured against OpenSim 4.6 on the same poses. This subpackage
never imports :mod:`o2m.convert`.
"""

from o2m.validate.dynamics import DynamicsReport, compare_dynamics
from o2m.validate.floors import TargetMiss, target_misses
from o2m.validate.jumps import continuous_tendon_front, opensim_length_steps, sweep_jumps
from o2m.validate.kinematics import KinematicsReport, compare_kinematics, format_table
from o2m.validate.muscles import MuscleReport, compare_muscles, format_muscle_table
from o2m.validate.sweeps import moment_arm_curve, moment_arm_report, plot_moment_arms

__all__ = [
    "DynamicsReport",
    "KinematicsReport",
    "MuscleReport",
    "TargetMiss",
    "compare_dynamics",
    "compare_kinematics",
    "compare_muscles",
    "continuous_tendon_front",
    "format_muscle_table",
    "format_table",
    "moment_arm_curve",
    "moment_arm_report",
    "opensim_length_steps",
    "plot_moment_arms",
    "sweep_jumps",
    "target_misses",
]
