"""Showing models: meshcat scenes of MuJoCo and OpenSim kinematics, HTML export, motion replay."""

from o2m.viz.motion import Motion, load_motion, resample_motion
from o2m.viz.scene import ModelScene, Viewer, animate_qpos, notebook_iframe, show_pose, side_by_side

__all__ = ["ModelScene", "Motion", "Viewer", "animate_qpos", "load_motion", "notebook_iframe", "resample_motion",
           "show_pose", "side_by_side"]
