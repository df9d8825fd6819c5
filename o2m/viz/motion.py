"""Replay OpenSim coordinate motions (``.mot`` / ``.sto``) on a converted MuJoCo model.

An OpenSim motion is a table of coordinate values over time. Its columns are named either by
the coordinate (``r_shoulder_elev``, OpenSim 3 and IK output) or by the coordinate's state path
(``/jointset/r_shoulder/r_shoulder_elev/value``, OpenSim 4 states files). A converted model has
a MuJoCo hinge or slide joint named as each converted coordinate, whose ``qpos`` is the
coordinate's value (radians or metres), and joint equalities for the rest, so
:func:`load_motion` reads the columns that name such joints, converts degrees to radians for
hinges when the file says ``inDegrees=yes``, and poses the model frame by frame with
:func:`o2m.validate.pose_mujoco` (joints not in the file stay at ``qpos0``; equality-driven
joints follow their drivers).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from o2m.errors import O2MError
from o2m.mj.posing import joint_equality_plan, pose_mujoco
from o2m.osim.storage import read_sto

__all__ = ["Motion", "MotionError", "coordinate_of_column", "load_motion", "motion_from_values", "resample_motion"]

_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
_SCALAR = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


class MotionError(O2MError):
    """A motion cannot be applied to a model (no column names one of its joints, bad shapes)."""


@dataclass(frozen=True)
class Motion:
    """A coordinate motion on a MuJoCo model.

    Attributes:
        times: (T,) seconds.
        qpos: (T, nq) MuJoCo ``qpos``, radians / metres, joint equalities resolved.
        coordinates: names of the coordinates (MuJoCo hinge/slide joints) read, length C.
        values: (T, C) their values, radians / metres (after any degree conversion).
        unmatched: column labels that name no hinge or slide joint of the model (ignored).
        source: the file read, or None.
        in_degrees: whether the file said rotations were in degrees.
    """

    times: np.ndarray
    qpos: np.ndarray
    coordinates: tuple[str, ...]
    values: np.ndarray
    unmatched: tuple[str, ...] = ()
    source: str | None = None
    in_degrees: bool = False

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame."""
        return float(self.times[-1] - self.times[0]) if len(self.times) else 0.0

    def value_dicts(self) -> list[dict[str, float]]:
        """Per frame, ``{coordinate: value}`` (radians / metres)."""
        return [dict(zip(self.coordinates, map(float, row), strict=True)) for row in self.values]


def coordinate_of_column(label: str) -> str | None:
    """The coordinate a column label names, or None if it holds something else.

    ``r_elbow_flex`` -> ``r_elbow_flex``; ``/jointset/r_elbow/r_elbow_flex/value`` ->
    ``r_elbow_flex``; a state path ending in anything but ``/value`` (``/speed``,
    ``/forceset/BIClong/activation``) -> None.
    """
    label = label.strip()
    if not label.startswith("/"):
        return label or None
    parts = [p for p in label.split("/") if p]
    if len(parts) >= 2 and parts[-1] == "value":
        return parts[-2]
    return None


def _column_joint(label: str, mj_model: mujoco.MjModel) -> str | None:
    """The hinge or slide joint of ``mj_model`` a column label names, or None.

    A state path ``/jointset/<joint>/<coordinate>/value`` whose coordinate name is shared by several
    joints names MuJoCo joint ``<joint>_<coordinate>`` (:mod:`o2m.osim.names`).
    """
    name = coordinate_of_column(label)
    if name is None or _joint_kind(mj_model, name) is not None:
        return name
    parts = [p for p in label.strip().split("/") if p]
    if label.strip().startswith("/") and len(parts) >= 3:
        renamed = f"{parts[-3]}_{parts[-2]}"
        return renamed if _joint_kind(mj_model, renamed) is not None else None
    return None


def _joint_kind(model: mujoco.MjModel, name: str) -> int | None:
    jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
    if jid < 0 or int(model.jnt_type[jid]) not in _SCALAR:
        return None
    return int(model.jnt_type[jid])


def motion_from_values(
    mj_model: mujoco.MjModel,
    times: np.ndarray,
    coordinates: Sequence[str],
    values: np.ndarray,
    *,
    unmatched: Sequence[str] = (),
    source: str | None = None,
    in_degrees: bool = False,
) -> Motion:
    """A :class:`Motion` from coordinate ``values`` (T, C) in radians / metres.

    Every name in ``coordinates`` must be a hinge or slide joint of ``mj_model``
    (:class:`MotionError` otherwise); each frame is posed with :func:`o2m.validate.pose_mujoco`.
    """
    times = np.asarray(times, dtype=float).reshape(-1)
    values = np.asarray(values, dtype=float).reshape(len(times), -1)
    if values.shape[1] != len(coordinates):
        raise MotionError(f"values have {values.shape[1]} columns for {len(coordinates)} coordinates")
    bad = [c for c in coordinates if _joint_kind(mj_model, c) is None]
    if bad:
        raise MotionError(f"not hinge or slide joints of the model: {', '.join(bad)}")
    plan = joint_equality_plan(mj_model)
    data = mujoco.MjData(mj_model)
    qpos = np.empty((len(times), mj_model.nq))
    for k, row in enumerate(values):
        pose_mujoco(mj_model, data, dict(zip(coordinates, row, strict=True)), plan=plan)
        qpos[k] = data.qpos
    return Motion(times, qpos, tuple(coordinates), values, tuple(unmatched), source, in_degrees)


def load_motion(path: str | os.PathLike[str], mj_model: mujoco.MjModel, *, warn: bool = True) -> Motion:
    """Read an OpenSim ``.mot`` / ``.sto`` coordinate motion onto a converted MuJoCo model.

    Columns naming a hinge or slide joint of ``mj_model`` (plainly or as
    ``/jointset/<joint>/<coordinate>/value``) are read; with ``inDegrees=yes`` hinge values are
    converted to radians (slides stay in metres). A coordinate given twice is read from its
    first column. Other columns are listed in :attr:`Motion.unmatched` and, when ``warn``,
    reported by a :class:`UserWarning`.

    Raises :class:`o2m.errors.ModelFileError` if the file is not a storage file and
    :class:`MotionError` if no column names a joint of the model.
    """
    table = read_sto(path)
    cols: list[int] = []
    names: list[str] = []
    unmatched: list[str] = []
    for i, label in enumerate(table.columns):
        name = _column_joint(label, mj_model)
        if name is None or name in names:
            unmatched.append(label)
            continue
        cols.append(i)
        names.append(name)
    if not names:
        joints = [mj_model.joint(j).name for j in range(mj_model.njnt) if int(mj_model.jnt_type[j]) in _SCALAR]
        raise MotionError(
            f"{os.fspath(path)}: none of its {len(table.columns)} columns names a hinge or slide joint of the model "
            f"(columns: {', '.join(table.columns[:8])}{', ...' if len(table.columns) > 8 else ''}; "
            f"joints: {', '.join(joints[:8])}{', ...' if len(joints) > 8 else ''})")
    values = table.data[:, cols].copy()
    if table.in_degrees:
        hinge = np.array([_joint_kind(mj_model, n) == _HINGE for n in names])
        values[:, hinge] = np.deg2rad(values[:, hinge])
    if unmatched and warn:
        warnings.warn(f"{os.fspath(path)}: {len(unmatched)} column(s) name no hinge or slide joint of the model "
                      f"and are ignored: {', '.join(unmatched[:10])}{', ...' if len(unmatched) > 10 else ''}",
                      stacklevel=2)
    return motion_from_values(mj_model, table.times, names, values, unmatched=unmatched,
                              source=os.fspath(path), in_degrees=table.in_degrees)


def resample_motion(motion: Motion, mj_model: mujoco.MjModel, fps: float) -> Motion:
    """``motion`` at a fixed rate of ``fps`` frames per second (e.g. for an animation).

    Coordinate values are interpolated linearly over the motion's time span and the model is
    posed again (so equality-driven joints stay consistent).
    """
    if fps <= 0:
        raise MotionError(f"fps must be positive, got {fps}")
    t0 = float(motion.times[0])
    n = int(np.floor(motion.duration * fps + 1e-9)) + 1
    times = t0 + np.arange(n) / fps
    values = np.column_stack([np.interp(times, motion.times, motion.values[:, c])
                              for c in range(len(motion.coordinates))])
    return motion_from_values(mj_model, times, motion.coordinates, values, unmatched=motion.unmatched,
                              source=motion.source, in_degrees=motion.in_degrees)
