"""Posing a converted model: joint values in, MuJoCo kinematics out, joint equalities resolved.

Every converted OpenSim coordinate is a MuJoCo hinge or slide joint of the same name whose
``qpos`` equals the coordinate value (radians or metres). Dependent and locked coordinates, and
helper joints without an OpenSim name, are driven by active joint equalities (``mjEQ_JOINT``,
a quartic of another joint). :func:`pose_mujoco` sets named joints and resolves those
equalities explicitly, in dependency order, so a pose is exact without running the solver.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from o2m.errors import ValidationError
from o2m.mj.plugins import load_used

__all__ = [
    "JointEquality",
    "equality_residual",
    "joint_equality_plan",
    "joint_qpos_address",
    "load_mjcf",
    "pose_mujoco",
    "resolve_joint_equalities",
]

SCALAR_JOINTS = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
"""MuJoCo joint types that carry one OpenSim coordinate (hinge: radians, slide: metres)."""


@dataclass(frozen=True)
class JointEquality:
    """One active ``mjEQ_JOINT`` equality, ready to be evaluated on a ``qpos`` vector.

    ``qpos[qadr1] - ref1 = c0 + c1*x + c2*x**2 + c3*x**3 + c4*x**4`` with
    ``x = qpos[qadr2] - ref2``; without a second joint (``qadr2`` is None),
    ``qpos[qadr1] = ref1 + c0``. ``ref`` is ``model.qpos0`` of the joint (radians or metres).
    """

    eq_id: int
    joint1: str
    joint2: str | None
    qadr1: int
    qadr2: int | None
    ref1: float
    ref2: float
    coef: tuple[float, float, float, float, float]

    def value(self, qpos: np.ndarray) -> float:
        """Value the equality imposes on joint1, read from ``qpos`` (nq,)."""
        c0, c1, c2, c3, c4 = self.coef
        if self.qadr2 is None:
            return self.ref1 + c0
        x = float(qpos[self.qadr2]) - self.ref2
        return self.ref1 + c0 + x * (c1 + x * (c2 + x * (c3 + x * c4)))


def _joint_name(model: mujoco.MjModel, jnt_id: int) -> str:
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, jnt_id) or f"<joint {jnt_id}>"


def joint_equality_plan(model: mujoco.MjModel) -> list[JointEquality]:
    """The active (``eq_active0``) joint equalities of ``model``, in dependency order.

    An equality whose joint2 is driven by another equality comes after it, so evaluating the
    list once, in order, resolves chains. Several equalities driving the same joint are kept
    in id order (the last one wins). Raises :class:`ValidationError` on a cycle.
    """
    eqs: list[JointEquality] = []
    for i in range(model.neq):
        if int(model.eq_type[i]) != int(mujoco.mjtEq.mjEQ_JOINT) or not model.eq_active0[i]:
            continue
        j1 = int(model.eq_obj1id[i])
        j2 = int(model.eq_obj2id[i])
        a1 = int(model.jnt_qposadr[j1])
        a2 = int(model.jnt_qposadr[j2]) if j2 >= 0 else None
        eqs.append(
            JointEquality(
                eq_id=i,
                joint1=_joint_name(model, j1),
                joint2=_joint_name(model, j2) if j2 >= 0 else None,
                qadr1=a1,
                qadr2=a2,
                ref1=float(model.qpos0[a1]),
                ref2=float(model.qpos0[a2]) if a2 is not None else 0.0,
                coef=tuple(float(c) for c in model.eq_data[i, :5]),  # type: ignore[arg-type]
            )
        )

    drivers: dict[int, list[int]] = {}
    for k, e in enumerate(eqs):
        drivers.setdefault(e.qadr1, []).append(k)

    order: list[int] = []
    state = [0] * len(eqs)  # 0 unvisited, 1 on the stack, 2 done

    def visit(k: int, path: list[int]) -> None:
        if state[k] == 2:
            return
        if state[k] == 1:
            cycle = [eqs[i].joint1 for i in path[path.index(k):]] + [eqs[k].joint1]
            raise ValidationError("cyclic joint equalities: " + " <- ".join(cycle))
        state[k] = 1
        q2 = eqs[k].qadr2
        for dep in drivers.get(q2, []) if q2 is not None else []:
            visit(dep, path + [k])
        state[k] = 2
        order.append(k)

    for k in range(len(eqs)):
        visit(k, [])
    return [eqs[k] for k in order]


def resolve_joint_equalities(
    model: mujoco.MjModel, qpos: np.ndarray, plan: list[JointEquality] | None = None
) -> np.ndarray:
    """Overwrite, in place, every equality-driven joint of ``qpos`` (nq,) and return it.

    ``plan`` is :func:`joint_equality_plan` of ``model`` (computed when None; pass it when
    posing many times).
    """
    for e in joint_equality_plan(model) if plan is None else plan:
        qpos[e.qadr1] = e.value(qpos)
    return qpos


def joint_qpos_address(model: mujoco.MjModel, name: str) -> int:
    """``qpos`` index of the hinge or slide joint ``name``; KeyError if there is none."""
    jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
    if jid < 0:
        raise KeyError(f"MuJoCo model has no joint named {name!r}")
    if int(model.jnt_type[jid]) not in SCALAR_JOINTS:
        raise KeyError(f"MuJoCo joint {name!r} is not a hinge or slide joint")
    return int(model.jnt_qposadr[jid])


def pose_mujoco(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    values: Mapping[str, float],
    *,
    plan: list[JointEquality] | None = None,
) -> None:
    """Put ``data`` in the pose given by joint ``values`` and compute its kinematics.

    ``qpos`` starts from ``model.qpos0``; each named hinge/slide joint gets its value
    (radians or metres); then every joint driven by an active joint equality is resolved, in
    dependency order (an equality overrides a value given for its joint1). Finally
    ``mj_kinematics`` and ``mj_comPos`` run, so ``data.xpos`` (nbody, 3), ``data.xmat``
    (nbody, 9), ``data.subtree_com`` (nbody, 3) and the site/geom frames are valid.

    ``plan`` is :func:`joint_equality_plan` of ``model`` (computed when None). Raises KeyError
    for a name that is not a hinge or slide joint.
    """
    qpos = np.array(model.qpos0, dtype=float)
    for name, v in values.items():
        qpos[joint_qpos_address(model, name)] = float(v)
    resolve_joint_equalities(model, qpos, plan)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)


def equality_residual(model: mujoco.MjModel, data: mujoco.MjData, names: Sequence[str] | None = None) -> float:
    """Largest violation of the active equalities other than joint equalities (weld, connect,
    tendon), or of the equalities ``names`` only, at ``data.qpos`` (m, or rad for a weld's
    rotation); runs ``mj_fwdPosition``."""
    mujoco.mj_fwdPosition(model, data)
    rows = data.efc_type[:data.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    ids = data.efc_id[:data.nefc][rows]
    if names is None:
        chosen = model.eq_type[ids] != mujoco.mjtEq.mjEQ_JOINT
    else:
        chosen = np.isin(ids, [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, n) for n in names])
    return float(np.abs(data.efc_pos[:data.nefc][rows][chosen]).max(initial=0.0))


def load_mjcf(mjcf_path: str | os.PathLike) -> mujoco.MjModel:
    """A converted model from its MJCF file, o2m's plugins it uses loaded first
    (:func:`o2m.mj.plugins.load_used`); :class:`~o2m.errors.ValidationError` if it does not load."""
    mjcf_path = os.fspath(mjcf_path)
    if not os.path.isfile(mjcf_path):
        raise ValidationError(f"{mjcf_path}: no such file")
    try:
        load_used(mjcf_path)
        return mujoco.MjModel.from_xml_path(mjcf_path)
    except ValueError as exc:
        raise ValidationError(f"{mjcf_path}: MuJoCo could not load the model: {exc}") from exc


