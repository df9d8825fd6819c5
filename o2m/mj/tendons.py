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
           "tendon_jacobian", "tendon_length_jumps", "tendon_length_steps"]

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


def tendon_length_steps(model: mujoco.MjModel, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each tendon's length change between neighbouring samples, and the part of it its
    Jacobian explains.

    Along a smooth path the change is the trapezoid ``(J_k + J_k+1) / 2 @ dq`` of the tendon
    Jacobians at the two ends, within O(|dq|^3), whatever the integrator; a path that flips to
    the other side of a wrap geom changes by millimetres to centimetres more.

    Args:
        qpos: shape (T, nq), the samples of a trajectory or a sweep.
    Returns:
        ``(change, explained)``: shape (T - 1, ntendon) each, metres.
    """
    qpos = np.atleast_2d(qpos)
    data = mujoco.MjData(model)
    lengths = np.empty((len(qpos), model.ntendon))
    jacobians = np.empty((len(qpos), model.ntendon, model.nv))
    for k, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_fwdPosition(model, data)
        lengths[k] = data.ten_length
        jacobians[k] = tendon_jacobian(model, data)
    dq = np.empty((max(len(qpos) - 1, 0), model.nv))
    for k in range(len(qpos) - 1):
        mujoco.mj_differentiatePos(model, dq[k], 1.0, qpos[k], qpos[k + 1])
    explained = 0.5 * np.einsum("ktv,kv->kt", jacobians[1:] + jacobians[:-1], dq)
    return np.diff(lengths, axis=0), explained


def tendon_length_jumps(model: mujoco.MjModel, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The largest jump of each tendon's length along ``qpos`` (T, nq): ``(excess, at)``, shape
    (ntendon,) each, the largest ``|change - explained|`` of :func:`tendon_length_steps` (metres)
    and the index k of the first sample of that pair."""
    change, explained = tendon_length_steps(model, qpos)
    if len(change) == 0:
        return np.zeros(model.ntendon), np.zeros(model.ntendon, dtype=int)
    excess = np.abs(change - explained)
    return excess.max(axis=0), excess.argmax(axis=0)
