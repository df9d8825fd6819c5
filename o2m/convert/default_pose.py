"""The ``default-pose`` keyframe's ``qpos``: OpenSim's assembled default state.

``qpos0`` holds the coordinates' default values, which need not satisfy a PointConstraint,
WeldConstraint, ConstantDistanceConstraint, PointOnLineConstraint or a loop's weld; OpenSim's
``initSystem`` assembles them first (:func:`o2m.osim.assembly.assembled_defaults`), and a
simulation there starts with the constraints met. The keyframe poses MuJoCo at those values as
the validation does (coordinates by name, the joint equalities resolved by
:func:`~o2m.mj.posing.pose_mujoco`), with each point-on-line slide where its follower's point
now projects. ``qpos0`` stays the default values: it is the reference of
every joint equality. Where every constraint is a coupler, nothing is assembled: ``qpos0`` is
OpenSim's default state already.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from o2m.convert.records import BuildResult
from o2m.mj.posing import equality_residual, joint_equality_plan, pose_mujoco
from o2m.osim.assembly import assembled_defaults
from o2m.osim.skeleton import Skeleton

__all__ = ["MOVED", "assembled_pose"]

#: A coordinate that assembly moved by more than this (rad or m) changes the keyframe; less is
#: round-off of a default pose that already satisfies its constraints.
MOVED = 1e-12
#: At most this many moved coordinates are named in the note.
NAMED = 8


def assembled_pose(model: mujoco.MjModel, skel: Skeleton, osim: Path, result: BuildResult,
                   equalities: list[str]) -> np.ndarray:
    """The keyframe ``qpos`` (nq,): ``model.qpos0`` where the skeleton has no body constraint or
    OpenSim's assembly moves no coordinate, else OpenSim's assembled default state (module
    docstring), with a note naming the coordinates moved and the residual of the constraints'
    ``equalities`` (their names) before and after (m, or rad for a weld's rotation)."""
    if not (skel.point_on_lines or skel.body_constraints):
        return model.qpos0.copy()
    coords = assembled_defaults(osim)
    moved = [c for c in coords if abs(c.moved) > MOVED]
    if not moved:
        return model.qpos0.copy()
    data = mujoco.MjData(model)
    given = {c.name: c.value for c in coords if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, c.name) >= 0}
    pose_mujoco(model, data, given, plan=joint_equality_plan(model))
    _slide_onto_lines(model, data, skel)
    after = equality_residual(model, data, equalities)
    qpos = data.qpos.copy()
    data.qpos[:] = model.qpos0
    before = equality_residual(model, data, equalities)
    moved.sort(key=lambda c: -abs(c.moved))
    listed = ", ".join(f"{c.name} {c.moved:+.4g}" for c in moved[:NAMED])
    more = f" and {len(moved) - NAMED} more" if len(moved) > NAMED else ""
    result.notes.append(
        f"the 'default-pose' keyframe is OpenSim's assembled default state (initSystem), not the coordinates' "
        f"default values: assembly moved {len(moved)} coordinate(s) by more than {MOVED:g} ({listed}{more}; rad "
        f"or m); the constraints' "
        f"equalities' largest residual there {after:.3g} (at qpos0, the default values, {before:.3g}; m, or rad "
        f"for a weld's rotation); mj_resetData starts at qpos0, mj_resetDataKeyframe at the assembled state")
    return qpos


def _slide_onto_lines(model: mujoco.MjModel, data: mujoco.MjData, skel: Skeleton) -> None:
    """Move each point-on-line slide (at 0 in ``data``, posed) to where its follower's point
    projects onto the line (:mod:`o2m.convert.constraints` names the joint and sites); then
    recompute the kinematics."""
    for c in skel.point_on_lines:
        jnt = model.joint(f"{c.name}_slide")
        gap = data.site(f"{c.name}_point").xpos - data.site(f"{c.name}_on_line").xpos
        data.qpos[jnt.qposadr[0]] = float(np.dot(gap, data.xaxis[jnt.id]))
    mujoco.mj_kinematics(model, data)
