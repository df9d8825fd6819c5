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

from o2m.convert.coordinates import is_mobility_rotation
from o2m.convert.records import BuildResult
from o2m.mj.posing import equality_residual, joint_equality_plan, pose_mujoco
from o2m.osim.assembly import assembled_defaults
from o2m.osim.skeleton import Skeleton
from o2m.transforms import OSIM_TO_MJ

__all__ = ["MOVED", "SPEED_STEP", "assembled_pose", "default_velocity"]

#: A coordinate that assembly moved by more than this (rad or m) changes the keyframe; less is
#: round-off of a default pose that already satisfies its constraints.
MOVED = 1e-12
#: At most this many moved coordinates are named in the note.
NAMED = 8
#: Time step (s) of the central difference that carries the default speeds through the joint
#: equalities (:func:`default_velocity`); the equalities are polynomials, so round-off dominates.
SPEED_STEP = 1e-6


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


def default_velocity(model: mujoco.MjModel, builder, qpos: np.ndarray, result: BuildResult) -> np.ndarray:
    """The keyframe ``qvel`` (nv,): OpenSim's default speeds (``default_speed_value``) at pose
    ``qpos`` (nq,), carried to every joint the joint equalities drive (a central difference of
    :func:`~o2m.mj.posing.pose_mujoco` along the speeds); zeros when every default speed is 0. A
    rotation of a Ball or Free joint has as its speed the angular velocity's component about the
    parent frame's axis (Simbody's mobility), turned into its hinges' rates here."""
    speeds = {n: c.default_speed for n, c in builder.skel.coordinates.items()
              if c.default_speed and not c.locked and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) >= 0}
    listed = ", ".join(f"{n} {v:+.4g}" for n, v in list(speeds.items())[:NAMED])
    unset = [n for n in speeds if (cj := builder.coord_joint.get(n)) is not None and is_mobility_rotation(cj.joint, n)
             and (cj.joint.type == "EllipsoidJoint" or cj.joint.reversed)]
    for n in unset:  # an ellipsoid's rotations are no hinges of their own, a reversed joint's mobility is the child's
        del speeds[n]
        result.notes.append(f"coordinate '{n}': its default speed is an angular velocity component of a "
                            f"{builder.coord_joint[n].joint.type} o2m does not map to joint rates; the keyframe "
                            "leaves it at 0")
    if not speeds:
        return np.zeros(model.nv)
    plan = joint_equality_plan(model)
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    speeds.update(_hinge_rates(model, data, builder, speeds))
    given = {n: float(qpos[model.jnt_qposadr[model.joint(n).id]]) for n in builder.skel.coordinates
             if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) >= 0}
    ends = []
    for sign in (1.0, -1.0):
        pose_mujoco(model, data, {n: v + sign * SPEED_STEP * speeds.get(n, 0.0) for n, v in given.items()}, plan=plan)
        ends.append(data.qpos.copy())
    qvel = np.zeros(model.nv)
    mujoco.mj_differentiatePos(model, qvel, 2.0 * SPEED_STEP, ends[1], ends[0])
    result.notes.append(f"the 'default-pose' keyframe's qvel holds OpenSim's default speeds ({listed}; rad/s or "
                        "m/s, the joints the equalities drive moving along); mj_resetData starts at rest")
    return qvel


def _hinge_rates(model: mujoco.MjModel, data: mujoco.MjData, builder, speeds: dict[str, float]) -> dict[str, float]:
    """The hinge rates (rad/s), by joint name, that give each Ball or Free joint's default angular
    velocity, whose components about its parent frame's axes are its rotations' ``speeds``."""
    out: dict[str, float] = {}
    for joint in {id(cj.joint): cj.joint for n in speeds if (cj := builder.coord_joint.get(n)) is not None}.values():
        names = [ax.coordinate for ax in joint.rotations]
        if not any(is_mobility_rotation(joint, n) and n in speeds for n in names):
            continue
        parent = np.eye(3) if joint.parent == "ground" else data.xmat[model.body(joint.parent).id].reshape(3, 3)
        frame = (OSIM_TO_MJ if joint.parent == "ground" else np.eye(3)) @ joint.parent_frame.rot
        omega = parent @ frame @ np.array([speeds.get(n, 0.0) for n in names])
        axes = np.stack([data.xaxis[model.joint(n).id] for n in names], axis=1)
        out.update(zip(names, np.linalg.solve(axes, omega), strict=True))
    return out

