"""Poses to draw: MuJoCo's and OpenSim's kinematics as frames, tendon paths, activation colours.

A :class:`Frame` is one pose in the MuJoCo world frame (z up, metres) of a converted model: body
origins and orientations, and each tendon's path as straight segments. OpenSim's poses (ground
Y-up) are mapped into it with :data:`o2m.transforms.OSIM_TO_MJ`. Activations colour tendons
blue (0) to red (1).
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from o2m.errors import O2MError
from o2m.osim import runtime
from o2m.osim.names import opensim_coordinate_names
from o2m.transforms import OSIM_TO_MJ

__all__ = [
    "NO_ACTIVATION_RGB",
    "Frame",
    "ViewerError",
    "activation_colors",
    "mujoco_frames",
    "opensim_frames",
    "tendon_activations",
    "tendon_segments",
]

#: Colour (RGB in [0, 1]) of a tendon that no activation is given for.
NO_ACTIVATION_RGB = (0.55, 0.55, 0.55)


class ViewerError(O2MError):
    """The viewer cannot draw what it was given (array shapes, names, missing OpenSim parts)."""


@dataclass(frozen=True)
class Frame:
    """One pose to draw, in the MuJoCo world frame of the converted model.

    Attributes:
        body_pos: (nbody, 3) body frame origins, metres (row 0 is the world body).
        body_rot: (nbody, 3, 3) body frame orientations (columns are the body axes).
        tendon_segments: one (S_i, 2, 3) array per tendon (``model.ntendon`` of them): the
            start and end points (metres) of the S_i straight segments of its path.
    """

    body_pos: np.ndarray
    body_rot: np.ndarray
    tendon_segments: tuple[np.ndarray, ...]


def _arc(p0: np.ndarray, p1: np.ndarray, center: np.ndarray, rot: np.ndarray, kind: int,
         n: int) -> np.ndarray:
    """Points (n + 2, 3) from p0 to p1 over a wrapping sphere or cylinder (world frame)."""
    a, b = rot.T @ (p0 - center), rot.T @ (p1 - center)
    t = np.linspace(0.0, 1.0, n + 2)[:, None]
    if kind == int(mujoco.mjtGeom.mjGEOM_SPHERE):
        ra, rb = np.linalg.norm(a), np.linalg.norm(b)
        if ra < 1e-12 or rb < 1e-12:
            return np.array([p0, p1])
        ua, ub = a / ra, b / rb
        ang = math.atan2(np.linalg.norm(np.cross(ua, ub)), float(ua @ ub))
        if ang < 1e-6 or ang > math.pi - 1e-6:
            return np.array([p0, p1])
        w = np.sin((1 - t) * ang) / math.sin(ang), np.sin(t * ang) / math.sin(ang)
        local = (w[0] * ua + w[1] * ub) * ((1 - t) * ra + t * rb)
    else:  # cylinder about the geom's z axis: a helix
        th0, th1 = math.atan2(a[1], a[0]), math.atan2(b[1], b[0])
        dth = (th1 - th0 + math.pi) % (2 * math.pi) - math.pi
        r = (1 - t) * math.hypot(a[0], a[1]) + t * math.hypot(b[0], b[1])
        th = th0 + t * dth
        local = np.hstack([r * np.cos(th), r * np.sin(th), (1 - t) * a[2] + t * b[2]])
    return center + local @ rot.T


def tendon_segments(model: mujoco.MjModel, data: mujoco.MjData, *, arc_points: int = 6) -> tuple[np.ndarray, ...]:
    """The path of every tendon as straight segments, from ``data`` after ``mj_tendon``.

    Reads ``data.ten_wrapadr`` / ``ten_wrapnum`` / ``wrap_obj`` / ``wrap_xpos``: consecutive
    path points are joined unless either is a pulley (``wrap_obj == -2``, which starts a new
    branch). Two consecutive tangent points on the same wrapping geom are joined by
    ``arc_points`` intermediate points on its surface (a great circle on a sphere, a helix on
    a cylinder); ``arc_points=0`` joins them straight, as MuJoCo's own renderer does.

    Returns ``model.ntendon`` arrays of shape (S_i, 2, 3), metres, MuJoCo world frame.
    """
    objs = np.asarray(data.wrap_obj).reshape(-1)
    pts = np.asarray(data.wrap_xpos).reshape(-1, 3)
    out = []
    for t in range(model.ntendon):
        adr, num = int(data.ten_wrapadr[t]), int(data.ten_wrapnum[t])
        segs: list[np.ndarray] = []
        for j in range(adr, adr + num - 1):
            o0, o1 = int(objs[j]), int(objs[j + 1])
            if o0 == -2 or o1 == -2:
                continue
            if arc_points > 0 and o0 >= 0 and o0 == o1 and int(model.geom_type[o0]) in (
                    int(mujoco.mjtGeom.mjGEOM_SPHERE), int(mujoco.mjtGeom.mjGEOM_CYLINDER)):
                line = _arc(pts[j], pts[j + 1], data.geom_xpos[o0], data.geom_xmat[o0].reshape(3, 3),
                            int(model.geom_type[o0]), arc_points)
                segs.extend(np.stack([line[:-1], line[1:]], axis=1))
            else:
                segs.append(np.stack([pts[j], pts[j + 1]]))
        out.append(np.asarray(segs, dtype=float).reshape(-1, 2, 3))
    return tuple(out)


def _as_2d(a: Any, width: int, what: str) -> np.ndarray:
    arr = np.asarray(a, dtype=float)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != width:
        raise ViewerError(f"{what} must have shape (T, {width}) or ({width},), got {np.shape(a)}")
    return arr


def mujoco_frames(model: mujoco.MjModel, qpos: np.ndarray, *, arc_points: int = 6) -> list[Frame]:
    """MuJoCo's kinematics of ``qpos`` (T, nq) or (nq,): one :class:`Frame` per row.

    Runs ``mj_kinematics``, ``mj_comPos`` and ``mj_tendon`` on a scratch ``MjData``; ``qpos``
    is used as given (resolve joint equalities first, e.g. with :func:`o2m.motion.load_motion`
    or :func:`o2m.validate.pose_mujoco`).
    """
    q = _as_2d(qpos, model.nq, "qpos")
    data = mujoco.MjData(model)
    frames = []
    for row in q:
        data.qpos[:] = row
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_tendon(model, data)
        frames.append(Frame(data.xpos.copy(), data.xmat.reshape(-1, 3, 3).copy(),
                            tendon_segments(model, data, arc_points=arc_points)))
    return frames


def _opensim_path(force: Any) -> Any:
    """The GeometryPath of an OpenSim force, or None."""
    obj = runtime.path_force(force)
    if obj is None:
        return None
    try:
        return obj.getGeometryPath()
    except Exception:  # a path that is not a GeometryPath (e.g. FunctionBasedPath)
        return None


def _osim_polyline(path: Any, state: Any) -> np.ndarray:
    """Ground-frame points (P, 3) of an OpenSim GeometryPath, wrap arcs included."""
    opensim = runtime.opensim()

    pts: list[np.ndarray] = []
    cur = path.getCurrentPath(state)
    for i in range(cur.getSize()):
        p = cur.get(i)
        w = opensim.PathWrapPoint.safeDownCast(p)
        if w is not None:
            arc = w.getWrapPath(state)
            if arc.getSize():
                frame = p.getParentFrame()
                pts.extend(frame.findStationLocationInGround(state, arc.get(k)).to_numpy()
                           for k in range(arc.getSize()))
        pts.append(p.getLocationInGround(state).to_numpy())
    return np.asarray(pts, dtype=float).reshape(-1, 3)


def opensim_frames(
    osim_path: str | os.PathLike[str],
    model: mujoco.MjModel,
    coordinate_names: Sequence[str],
    coordinate_values: np.ndarray,
    *,
    assemble: bool | None = None,
    qpos: np.ndarray | None = None,
) -> list[Frame]:
    """OpenSim's own kinematics of coordinate trajectories, as frames of the MuJoCo ``model``.

    ``coordinate_values`` (T, C) or (C,) holds the values (radians or metres, not degrees) of
    the OpenSim coordinates ``coordinate_names`` (length C). For each row, every coordinate is
    set with ``coord.setValue(state, v, False)``; then, if ``assemble`` (default: only when a
    dependent coordinate of a constraint is missing from the names), ``model.assemble(state)``
    makes constrained coordinates follow; then ``realizePosition``.

    Body poses are ``body.getTransformInGround(state)`` mapped by ``OSIM_TO_MJ`` and put in the
    rows of the MuJoCo bodies of the same name. A MuJoCo body without an OpenSim namesake (e.g.
    the carrier of a moving path point) keeps its MuJoCo transform relative to its nearest
    ancestor that has one: from MuJoCo's kinematics of ``qpos`` (T, nq) when given (the same
    motion in MuJoCo), else from ``qpos0`` (with a warning).
    Tendon paths are the current paths of the OpenSim path forces named as MuJoCo tendons,
    wrap arcs included (an empty path if there is none).

    Raises :class:`ViewerError` for a name that is not a coordinate of the model, and
    :class:`o2m.errors.ModelFileError` if OpenSim cannot load it.
    """
    values = _as_2d(coordinate_values, len(coordinate_names), "coordinate_values")
    os_model, state = runtime.load_model(osim_path)

    cset = os_model.getCoordinateSet()
    mj_names = opensim_coordinate_names(os_model)  # coordinates go by their MuJoCo joint names
    coords = {mj_names[cset.get(i).getAbsolutePathString()]: cset.get(i) for i in range(cset.getSize())}
    unknown = [n for n in coordinate_names if n not in coords]
    if unknown:
        raise ViewerError(f"{osim_path}: no coordinate(s) named {', '.join(unknown)}")
    given = [coords[n] for n in coordinate_names]
    if assemble is None:
        assemble = any(c.isDependent(state) and not runtime.is_held(c, state) and n not in coordinate_names
                       for n, c in coords.items())

    os_bodies = {b.getName(): b for b in os_model.getBodyList()}  # the BodySet's and any in <components>
    names = [model.body(b).name for b in range(model.nbody)]
    mapped = [b for b in range(1, model.nbody) if names[b] in os_bodies]
    # Bodies without an OpenSim namesake follow their nearest mapped ancestor ("anchor") with
    # the relative transform MuJoCo gives them.
    anchors: dict[int, int] = {}
    for b in range(1, model.nbody):
        if b not in mapped:
            a = int(model.body_parentid[b])
            while a > 0 and names[a] not in os_bodies:
                a = int(model.body_parentid[a])
            anchors[b] = a
    mj_rows: np.ndarray | None = None
    if anchors:
        if qpos is not None:
            mj_rows = _as_2d(qpos, model.nq, "qpos")
            if len(mj_rows) != len(values):
                raise ViewerError(f"qpos has {len(mj_rows)} frames, coordinate_values {len(values)}")
        else:
            mj_rows = model.qpos0[None, :]
            warnings.warn(f"{osim_path}: MuJoCo bodies without an OpenSim body of the same name are placed as in "
                          f"MuJoCo's default pose relative to their parent (pass qpos to follow the motion): "
                          f"{', '.join(names[b] for b in anchors)}", stacklevel=2)
    d_mj = mujoco.MjData(model)

    fset = os_model.getForceSet()
    paths = []
    for t in range(model.ntendon):
        name = model.tendon(t).name
        paths.append(_opensim_path(fset.get(name)) if name and fset.contains(name) else None)

    frames = []
    for k, row in enumerate(values):
        for c, v in zip(given, row, strict=True):
            c.setValue(state, float(v), False)
        if assemble:
            os_model.assemble(state)
        os_model.realizePosition(state)
        pos = np.zeros((model.nbody, 3))
        rot = np.tile(np.eye(3), (model.nbody, 1, 1))
        for b in mapped:
            xf = os_bodies[names[b]].getTransformInGround(state)
            r = xf.R()
            pos[b] = OSIM_TO_MJ @ xf.p().to_numpy()
            rot[b] = OSIM_TO_MJ @ np.array([[r.get(i, j) for j in range(3)] for i in range(3)])
        if mj_rows is not None and (k == 0 or len(mj_rows) > 1):
            d_mj.qpos[:] = mj_rows[min(k, len(mj_rows) - 1)]
            mujoco.mj_kinematics(model, d_mj)
        for b, a in anchors.items():  # parents come first in MuJoCo's body order
            ra = d_mj.xmat[a].reshape(3, 3)
            pos[b] = pos[a] + rot[a] @ (ra.T @ (d_mj.xpos[b] - d_mj.xpos[a]))
            rot[b] = rot[a] @ (ra.T @ d_mj.xmat[b].reshape(3, 3))
        segs = []
        for gp in paths:
            if gp is None:
                segs.append(np.zeros((0, 2, 3)))
                continue
            line = _osim_polyline(gp, state) @ OSIM_TO_MJ.T
            segs.append(np.stack([line[:-1], line[1:]], axis=1) if len(line) > 1 else np.zeros((0, 2, 3)))
        frames.append(Frame(pos, rot, tuple(segs)))
    return frames


def tendon_activations(model: mujoco.MjModel, activations: np.ndarray | None, n_frames: int) -> np.ndarray:
    """Per-tendon activations (n_frames, ntendon) in [0, 1], NaN where none is given.

    ``activations`` is (T, nu) or (nu,) — one per actuator, put on the tendon the actuator
    pulls — or (T, ntendon) / (ntendon,), one per tendon (when ``nu == ntendon`` it is read as
    per actuator). None gives zeros on actuated tendons. A 1-D array is used for every frame.
    """
    nt, nu = model.ntendon, model.nu
    act_tendon = {int(model.actuator_trnid[i, 0]): i for i in range(nu)
                  if int(model.actuator_trntype[i]) == int(mujoco.mjtTrn.mjTRN_TENDON)}
    out = np.full((n_frames, nt), np.nan)
    if activations is None:
        out[:, list(act_tendon)] = 0.0
        return out
    a = np.asarray(activations, dtype=float)
    if a.ndim == 1:
        a = np.broadcast_to(a, (n_frames, a.shape[0]))
    if a.ndim != 2 or a.shape[0] != n_frames or a.shape[1] not in (nu, nt) or a.shape[1] == 0:
        raise ViewerError(f"activations must have shape ({n_frames}, nu={nu}) or ({n_frames}, ntendon={nt}), "
                          f"got {np.shape(activations)}")
    if a.shape[1] == nu:
        for t, i in act_tendon.items():
            out[:, t] = a[:, i]
    else:
        out[:] = a
    return np.clip(out, 0.0, 1.0)


def activation_colors(activation: np.ndarray) -> np.ndarray:
    """RGB (..., 3) in [0, 1] for activations (...): blue at 0, red at 1, grey for NaN."""
    a = np.asarray(activation, dtype=float)
    rgb = np.stack([a, np.zeros_like(a), 1.0 - a], axis=-1)
    rgb[np.isnan(a)] = NO_ACTIVATION_RGB
    return np.clip(rgb, 0.0, 1.0)

