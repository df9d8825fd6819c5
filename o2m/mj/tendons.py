"""Tendon lengths and moment arms of a converted model, with equality-driven joints following.

Moment arms are ``-dL/dq`` (metres, or dimensionless about a translational coordinate), the
sign convention of OpenSim's ``computeMomentArm``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import mujoco
import numpy as np

from o2m.mj.posing import JointEquality, joint_equality_plan, joint_qpos_address, pose_mujoco

__all__ = ["FD_STEP", "coordinate_direction", "mujoco_moment_arms", "mujoco_tendon_lengths", "qpos_to_dof",
           "tendon_jacobian", "tendon_length_jumps"]

#: Central-difference step of the MuJoCo moment arms (radians or metres).
FD_STEP = 1e-6

def mujoco_tendon_lengths(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    values: Mapping[str, float],
    *,
    plan: list[JointEquality] | None = None,
) -> np.ndarray:
    """Tendon lengths (ntendon,), metres, in the pose of joint ``values`` (see
    :func:`o2m.mj.posing.pose_mujoco`; equality-driven joints follow their drivers).
    Leaves ``data`` posed with ``ten_length`` and ``ten_J`` computed."""
    pose_mujoco(model, data, values, plan=plan)
    mujoco.mj_tendon(model, data)
    return np.array(data.ten_length, dtype=float)


def tendon_jacobian(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """Dense tendon Jacobian (ntendon, nv) from ``data.ten_J`` (sparse in MuJoCo >= 3.3)."""
    nt, nv = model.ntendon, model.nv
    tj = np.asarray(data.ten_J, dtype=float).ravel()
    if not hasattr(model, "ten_J_rownnz"):  # dense ten_J (MuJoCo < 3.3)
        return tj.reshape(nt, nv)
    out = np.zeros((nt, nv))
    rownnz, rowadr, colind = model.ten_J_rownnz, model.ten_J_rowadr, model.ten_J_colind
    for t in range(nt):
        a, n = int(rowadr[t]), int(rownnz[t])
        out[t, colind[a:a + n]] = tj[a:a + n]
    return out


def coordinate_direction(
    model: mujoco.MjModel, qpos: np.ndarray, qadr: int, plan: Sequence[JointEquality]
) -> np.ndarray:
    """d qpos / d qpos[qadr] (nq,) when the equality-driven joints follow their drivers."""
    dq = np.zeros(model.nq)
    dq[qadr] = 1.0
    for e in plan:
        if e.qadr2 is None:
            dq[e.qadr1] = 0.0
            continue
        _, c1, c2, c3, c4 = e.coef
        x = float(qpos[e.qadr2]) - e.ref2
        dq[e.qadr1] = (c1 + x * (2 * c2 + x * (3 * c3 + x * 4 * c4))) * dq[e.qadr2]
    return dq


def qpos_to_dof(model: mujoco.MjModel, dq: np.ndarray) -> np.ndarray:
    """Map a qpos-space direction of hinge/slide joints to dof space (nv,)."""
    dv = np.zeros(model.nv)
    for j in range(model.njnt):
        if int(model.jnt_type[j]) in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
            dv[model.jnt_dofadr[j]] = dq[model.jnt_qposadr[j]]
    return dv


def mujoco_moment_arms(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    values: Mapping[str, float],
    coordinates: Sequence[str],
    *,
    plan: list[JointEquality] | None = None,
    method: str = "fd",
    h: float = FD_STEP,
) -> np.ndarray:
    """MuJoCo moment arms (ntendon, len(coordinates)), metres (or dimensionless for a
    translational coordinate): ``-dL/dq`` of every tendon about every named joint, at the pose of
    joint ``values``, with equality-driven joints following (OpenSim's sign convention).

    ``method="fd"``: central differences with step ``h`` through :func:`pose_mujoco`;
    ``method="jacobian"``: the tendon Jacobian ``ten_J`` projected on the coordinate's direction
    in joint space, whose equality-driven components come from the derivatives of the equality
    polynomials. Leaves ``data`` in a perturbed pose (fd) or at ``values`` (jacobian).
    """
    plan = joint_equality_plan(model) if plan is None else plan
    out = np.zeros((model.ntendon, len(coordinates)))
    base = {k: float(v) for k, v in values.items()}
    if method == "fd":
        for k, c in enumerate(coordinates):
            q0 = base.get(c, float(model.qpos0[joint_qpos_address(model, c)]))
            up = mujoco_tendon_lengths(model, data, {**base, c: q0 + h}, plan=plan)
            dn = mujoco_tendon_lengths(model, data, {**base, c: q0 - h}, plan=plan)
            out[:, k] = -(up - dn) / (2 * h)
        return out
    if method != "jacobian":
        raise ValueError(f"method must be 'fd' or 'jacobian', not {method!r}")
    mujoco_tendon_lengths(model, data, base, plan=plan)
    jac = tendon_jacobian(model, data)
    qpos = np.array(data.qpos, dtype=float)
    for k, c in enumerate(coordinates):
        dv = qpos_to_dof(model, coordinate_direction(model, qpos, joint_qpos_address(model, c), plan))
        out[:, k] = -(jac @ dv)
    return out


def tendon_length_jumps(model: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How far each tendon's length change over a step is from what its rate explains.

    A path that flips to the other side of a wrap geom between two steps changes length by
    millimetres to centimetres in one step; a smooth path changes by the trapezoid of its rate
    ``ten_J @ qvel`` at the two ends, within O(dt^3).

    Args:
        qpos: shape (T, nq), the states of a trajectory at steps of ``model.opt.timestep``.
        qvel: shape (T, nv), the velocities at the same samples.
    Returns:
        ``(excess, at)``: shape (ntendon,) each, the largest ``|dL - dt (v_k + v_k+1) / 2|`` over
        the steps (metres) and the index k of the step where it occurs.
    """
    qpos, qvel = np.atleast_2d(qpos), np.atleast_2d(qvel)
    data = mujoco.MjData(model)
    lengths = np.empty((len(qpos), model.ntendon))
    rates = np.empty_like(lengths)
    for k, (q, v) in enumerate(zip(qpos, qvel, strict=True)):
        data.qpos[:], data.qvel[:] = q, v
        mujoco.mj_fwdPosition(model, data)
        lengths[k] = data.ten_length
        rates[k] = tendon_jacobian(model, data) @ v
    dt = model.opt.timestep
    excess = np.abs(np.diff(lengths, axis=0) - 0.5 * dt * (rates[1:] + rates[:-1]))
    if len(excess) == 0:
        return np.zeros(model.ntendon), np.zeros(model.ntendon, dtype=int)
    return excess.max(axis=0), excess.argmax(axis=0)
