"""Rigid-transform helpers shared by the converter and the validator.

OpenSim is Y-up, MuJoCo is Z-up. o2m maps OpenSim ground into MuJoCo's world by one fixed
rotation, +90 degrees about x: (x, y, z)_OpenSim -> (x, -z, y)_MuJoCo. Every position in
metres and every direction in the world frame goes through ``OSIM_TO_MJ``.
"""

from __future__ import annotations

import numpy as np

#: Rotation matrix (3, 3) taking OpenSim ground coordinates to MuJoCo world coordinates.
OSIM_TO_MJ = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def axis_angle_matrix(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix (3, 3) for ``angle`` radians about the unit vector ``axis`` (3,)."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k)


def body_fixed_xyz(angles: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) of OpenSim's frame-fixed (intrinsic) X-Y-Z sequence, radians (3,)."""
    rx, ry, rz = (float(v) for v in angles)
    return (
        axis_angle_matrix(np.array([1.0, 0.0, 0.0]), rx)
        @ axis_angle_matrix(np.array([0.0, 1.0, 0.0]), ry)
        @ axis_angle_matrix(np.array([0.0, 0.0, 1.0]), rz)
    )


def matrix_to_quat(r: np.ndarray) -> np.ndarray:
    """Unit quaternion (4,) in MuJoCo's (w, x, y, z) order for a rotation matrix (3, 3)."""
    import mujoco

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(r, dtype=float).reshape(9))
    return q / np.linalg.norm(q)


class Transform:
    """A rigid transform: rotation ``rot`` (3, 3) and translation ``pos`` (3,), metres.

    ``a @ b`` composes: a point expressed in b's frame, mapped by ``b`` then ``a``.
    """

    __slots__ = ("rot", "pos")

    def __init__(self, rot: np.ndarray | None = None, pos: np.ndarray | None = None):
        self.rot = np.eye(3) if rot is None else np.asarray(rot, dtype=float)
        self.pos = np.zeros(3) if pos is None else np.asarray(pos, dtype=float)

    def __matmul__(self, other: Transform) -> Transform:
        return Transform(self.rot @ other.rot, self.rot @ other.pos + self.pos)

    def inverse(self) -> Transform:
        return Transform(self.rot.T, -self.rot.T @ self.pos)

    def apply(self, point: np.ndarray) -> np.ndarray:
        return self.rot @ np.asarray(point, dtype=float) + self.pos

    def __repr__(self) -> str:
        return f"Transform(rot={self.rot.tolist()}, pos={self.pos.tolist()})"


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion (4,) in MuJoCo's (w, x, y, z) order."""
    import mujoco

    r = np.zeros(9)
    mujoco.mju_quat2Mat(r, np.asarray(q, dtype=float) / np.linalg.norm(q))
    return r.reshape(3, 3)
