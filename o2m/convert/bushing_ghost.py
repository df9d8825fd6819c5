"""A BushingForce no fixed tendon gives, as a ghost body welded to its second frame.

OpenSim's bushing deflection θ (6,: frame 2's X-Y-Z body-fixed angles in frame 1, rad, and its
origin's offset in frame 1, m) is not linear in the coordinates where rotations about different
axes compose (ToyLandingModel's ankle, across the ankle and subtalar joints; its lumbar bushing,
across a Z-X-Y joint): no fixed tendon follows it. A *ghost* body, a child of frame 1's body placed
at frame 1, carries three slides along frame 1's X, Y, Z axes and then three hinges about X, Y, Z
(MuJoCo composes one body's joints in order, body-fixed: translation t, then Rx Ry Rz), and a weld
equality holds it on frame 2. Its six joint values are then θ exactly, and their springs and
dampers (stiffness K_i, damping D_i, spring reference 0) apply OpenSim's -K θ - D θ̇ on θ at every
pose, through the weld, to the bodies (where the X-Y-Z angles are singular, as OpenSim's are).

The ghost sits at frame 1 in ``qpos0`` (its joints at 0: a joint's ``ref`` would offset its
motion, MuJoCo moving a joint by qpos - ref), so there the weld holds only where the frames
coincide; :func:`pose_ghost` puts the ghost where the weld holds at any pose (the converted
model's ``default-pose`` keyframe has every ghost posed: :func:`ghosts_posed`), and a simulation
started elsewhere begins with the weld pulling it there. The weld is as stiff as o2m's joint
equalities, but MuJoCo scales a constraint's stiffness with the inertia it moves: under the
spring's load it slips, and the slip times K is the force's error in motion. The ghost's mass
and inertia (:data:`GHOST_MASS`, :data:`GHOST_INERTIA`, its weight cancelled by ``gravcomp``) and
its joints' armature (:data:`GHOST_ARMATURE`, :data:`GHOST_ARMATURE_PER_STIFFNESS`) trade that
slip against the inertia they add to the bodies: with 1e-6 kg m² of armature a 30 N m/rad ghost
diverged within 1.3 s of falling; uniform 1e-4 left the test model's accelerations within 5.3 %
of OpenSim's and the weld slipping up to 0.028 m or rad in a 2-s fall (ToyLandingModel, 1 s
from its default pose: 0.054 rad); 1e-2 gave 26 % and 0.0014 rad. With the armature in
proportion to the stiffness (now): 7.0 % and 0.011 on the test model (tests/convert/test_bushings.py),
ToyLandingModel's right ankle bushing slipping up to 0.0062 rad, its back bushing 0.021 rad on its
angles of K 50 N m/rad and 0.069 rad on its Z angle (K 10).
Angles in radians, lengths in metres.
"""

from __future__ import annotations

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from o2m.convert.builder import EQUALITY_SOLIMP, EQUALITY_SOLREF
from o2m.convert.force_context import BushingFit, _Context
from o2m.transforms import OSIM_TO_MJ, Transform, matrix_to_quat, quat_to_matrix

__all__ = ["GHOST_ARMATURE", "GHOST_ARMATURE_PER_STIFFNESS", "GHOST_INERTIA", "GHOST_MASS", "add_ghost", "deflection",
           "ghost_joint_names", "ghosts_posed", "pose_ghost"]

#: The ghost body's mass (kg, its weight cancelled by ``gravcomp``) and inertia (kg m², each axis).
GHOST_MASS = 1e-3
GHOST_INERTIA = 1e-7
#: Armature of each ghost joint (kg on a slide, kg m² on a hinge): at least GHOST_ARMATURE and
#: GHOST_ARMATURE_PER_STIFFNESS (s²) times its stiffness, since the weld slips by about K θ /
#: armature times a constant (ToyLandingModel, 1 s from its default pose, every joint 1e-4:
#: 0.054 rad; 1e-3: 0.0055; 1e-2: 0.0014).
GHOST_ARMATURE = 1e-4
GHOST_ARMATURE_PER_STIFFNESS = 2e-5
#: The ghost's joints, in their order in its body: slides then hinges.
_AXES = (("tx", "slide", 0), ("ty", "slide", 1), ("tz", "slide", 2),
         ("rx", "hinge", 0), ("ry", "hinge", 1), ("rz", "hinge", 2))


def ghost_joint_names(fit: BushingFit) -> list[str]:
    """The ghost's six MuJoCo joints, in the order of θ (rx, ry, rz, tx, ty, tz)."""
    by_axis = dict(zip([a for a, _, _ in _AXES], fit.ghost_joints, strict=True))
    return [by_axis[a] for a in ("rx", "ry", "rz", "tx", "ty", "tz")]


def _mj_frame(body: str, frame: Transform) -> Transform:
    """A frame given in OpenSim body ``body``'s frame, in its MuJoCo body's frame (ground: the world)."""
    return Transform(OSIM_TO_MJ) @ frame if body == "ground" else frame


def deflection(f1: Transform, f2: Transform) -> np.ndarray:
    """(6,): frame 2's X-Y-Z body-fixed angles (rad) and origin (m) in frame 1 (both in one frame)."""
    angles = Rotation.from_matrix(f1.rot.T @ f2.rot).as_euler("XYZ")
    return np.concatenate([angles, f1.rot.T @ (f2.pos - f1.pos)])


def add_ghost(ctx: _Context, fit: BushingFit, why: str) -> str:
    """Build ``fit``'s ghost body, joints and weld (see the module); returns what it became for the
    report, ``why`` saying why no tendon or joint spring does."""
    (body1, frame1), (body2, frame2) = fit.ends
    f1, f2 = _mj_frame(body1, frame1), _mj_frame(body2, frame2)
    ghost = ctx.builder.bodies[body1].add_body(name=ctx.unique("body", f"{fit.name}_ghost"), pos=f1.pos,
                                               quat=matrix_to_quat(f1.rot))
    ghost.explicitinertial = True
    ghost.mass, ghost.gravcomp = GHOST_MASS, 1.0
    ghost.fullinertia = [GHOST_INERTIA] * 3 + [0.0] * 3
    ctx.builder.exact[("body", ghost.name)] = {"pos": f1.pos, "quat": matrix_to_quat(f1.rot)}
    ctx.builder.exact[("inertial", ghost.name)] = {"pos": np.zeros(3), "mass": GHOST_MASS,
                                                   "fullinertia": np.array(ghost.fullinertia)}
    for axis_name, kind, k in _AXES:
        i = ("rx", "ry", "rz", "tx", "ty", "tz").index(axis_name)
        joint = ghost.add_joint(name=ctx.unique("joint", f"{fit.name}_ghost_{axis_name}"),
                                type=mujoco.mjtJoint.mjJNT_SLIDE if kind == "slide" else mujoco.mjtJoint.mjJNT_HINGE,
                                axis=np.eye(3)[k])
        joint.springref = 0.0  # a ref would offset the joint's motion too (MuJoCo moves a joint by qpos - ref)
        joint.stiffness, joint.damping = [float(fit.stiffness[i]), 0.0, 0.0], [float(fit.damping[i]), 0.0, 0.0]
        joint.armature = max(GHOST_ARMATURE, GHOST_ARMATURE_PER_STIFFNESS * float(fit.stiffness[i]))
        joint.limited = mujoco.mjtLimited.mjLIMITED_FALSE
        fit.ghost_joints.append(joint.name)
    inverse = f2.inverse()  # body 2's pose in the ghost's frame when the ghost is on frame 2
    eq = ctx.spec.add_equality(name=ctx.unique("equality", ghost.name), type=mujoco.mjtEq.mjEQ_WELD,
                               objtype=mujoco.mjtObj.mjOBJ_BODY, name1=ghost.name,
                               name2=ctx.builder.bodies[body2].name or "world")
    # anchor at body 2's origin (MuJoCo then holds body 2 at relpose in the ghost), torquescale 1
    eq.data = np.concatenate([np.zeros(3), inverse.pos, matrix_to_quat(inverse.rot), [1.0, 0.0]])
    eq.solref, eq.solimp = list(EQUALITY_SOLREF), list(EQUALITY_SOLIMP)
    fit.ghost_body, fit.ghost_weld = ghost.name, eq.name
    return (f"ghost body '{ghost.name}' at frame 1 welded to frame 2, its six joints ({', '.join(fit.ghost_joints)}) "
            f"the deflection, with its stiffness and damping (the weld slips under load: the error in motion, "
            f"o2m.convert.bushing_ghost); {why.removesuffix(': MuJoCo has no such spring')}")


def pose_ghost(model: mujoco.MjModel, data: mujoco.MjData, fit: BushingFit) -> None:
    """Set ``fit``'s ghost joints in ``data.qpos`` so that its weld holds at the current pose
    (``mj_kinematics`` must have run for the other bodies); runs ``mj_kinematics`` again."""
    if not fit.ghost_body:
        return
    eq = model.equality(fit.ghost_weld)
    ghost = model.body(fit.ghost_body)
    parent = int(model.body_parentid[ghost.id])
    f1 = _world(data, parent) @ Transform(quat_to_matrix(model.body_quat[ghost.id]), model.body_pos[ghost.id])
    rel = eq.data[3:10]
    body2 = int(model.eq_obj2id[eq.id])
    f2 = _world(data, body2) @ Transform(quat_to_matrix(rel[3:7]), rel[:3]).inverse()
    theta = deflection(f1, f2)
    for name, value in zip(ghost_joint_names(fit), theta, strict=True):
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = value
    mujoco.mj_kinematics(model, data)


def ghosts_posed(model: mujoco.MjModel, fits: list[BushingFit], qpos: np.ndarray | None = None) -> np.ndarray:
    """``qpos`` (nq; default ``qpos0``) with every ghost of ``fits`` where its weld holds."""
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0 if qpos is None else qpos
    mujoco.mj_kinematics(model, data)
    for fit in fits:
        pose_ghost(model, data, fit)
    return data.qpos.copy()


def _world(data: mujoco.MjData, body: int) -> Transform:
    return Transform(data.xmat[body].reshape(3, 3).copy(), data.xpos[body].copy())
