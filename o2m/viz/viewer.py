"""3-D views of a converted model with meshcat: poses, animations, OpenSim side by side, HTML.

A :class:`Viewer` owns a ``meshcat.Visualizer``. Each model added with :meth:`Viewer.add_model`
becomes a :class:`ModelScene` under ``/meshcat/o2m/<name>``:

* ``bodies/<body>`` — one node per MuJoCo body, posed in the MuJoCo world (metres). Under it,
  ``g<i>_<geom>`` holds each geom in the body frame: bone meshes (from ``model.mesh_vert`` /
  ``mesh_face``, in the geom's ``rgba``), spheres, capsules, cylinders, boxes and ellipsoids;
  the geoms a tendon wraps over are drawn translucent. ``sites`` holds the body's sites
  (markers, path points) as small spheres of the sites' radii and colours, in one mesh.
* ``tendons`` — every tendon path (``data.wrap_xpos`` after ``mj_tendon``) as line segments
  coloured by activation, blue (0) to red (1); grey for a tendon no activation is given for.
  The arc a path makes over a wrapping sphere or cylinder is drawn as such (``arc_points``).

No meshcat server is needed to build a scene or export it: the viewer records every meshcat
command in-process (as the meshcat server would) and :meth:`Viewer.export_html` writes a
self-contained HTML file (the meshcat viewer's JavaScript inlined, nothing fetched). The server
is started only by :meth:`Viewer.url`, :meth:`Viewer.open` or :meth:`Viewer.jupyter_cell` (or
``Viewer(server=True)``); it is then sent the whole recorded scene, and :meth:`Viewer.close`
(or leaving a ``with Viewer() as v:`` block) deletes the scene and stops the server process.

Animations (:func:`animate_qpos`, :func:`side_by_side`) are meshcat animations, so they play in
the exported HTML too (controls: "Open Controls" > Animations). Body poses are keyframe tracks
(interpolated). meshcat cannot animate line vertices, so tendon paths are a flip-book: one line
object per drawn frame (every ``tendon_stride``-th), shown by a discrete ``visible`` track from
its frame to the next drawn one. Between keyframes the bodies move smoothly while the lines hold
their keyframe positions. The flip-book is what makes long animations large; raise
``tendon_stride`` to shrink it.

File size. The meshcat JavaScript alone is 0.85 MB. Bone meshes dominate the rest: triangle
indices are stored as 16-bit when a mesh has < 65536 vertices, and ``decimate`` (a vertex
clustering cell, metres; see :func:`decimate_mesh`) removes detail below that size (vertex
rounding would not help: the data are binary float32, not text). An animation adds its body
tracks and one line object per drawn frame (``tendon_stride`` thins those). Measured with
mujoco 4.0.0 / meshcat 0.3.2 (``tests/test_viewer.py`` re-measures the arm26 and MoBL-ARMS
pages; the 50-frame motions move the shoulder and elbow):

==========================================================  ==========  ==================
page                                                        full mesh   ``decimate=0.003``
==========================================================  ==========  ==================
arm26, one pose                                              3.24 MB     1.46 MB
arm26, 50 frames with activations                            3.43 MB     1.65 MB
MoBL-ARMS (``mobl_arms_no_wrap``, 50 muscles), one pose      2.68 MB     1.33 MB (1.16 without sites)
MoBL-ARMS, 50 frames with activations                        3.41 MB     2.05 MB (1.58 ``tendon_stride=5``)
MoBL-ARMS, OpenSim and MuJoCo side by side, 50 frames        5.96 MB     3.24 MB
==========================================================  ==========  ==================

Coordinates: everything is in the MuJoCo world frame (z up) of the converted model; the
OpenSim side of :func:`side_by_side` maps OpenSim ground into it with
:data:`o2m.transforms.OSIM_TO_MJ`. :meth:`Viewer.frame_camera` shifts the whole drawing so that
the models' centre is at the origin, the point meshcat's camera orbits.
"""

from __future__ import annotations

import html as _html
import math
import os
import warnings
import webbrowser
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from o2m.errors import O2MError
from o2m.osim import runtime
from o2m.transforms import OSIM_TO_MJ

try:
    import meshcat
    import meshcat.geometry as mg
    import umsgpack
    from meshcat.animation import Animation, AnimationClip, AnimationTrack
except ImportError as _exc:  # pragma: no cover - meshcat is in environment.txt
    raise ImportError("o2m.viewer needs meshcat: pip install meshcat") from _exc

__all__ = [
    "Frame",
    "ModelScene",
    "Viewer",
    "ViewerError",
    "activation_colors",
    "animate_qpos",
    "decimate_mesh",
    "mujoco_frames",
    "notebook_iframe",
    "opensim_frames",
    "show_pose",
    "side_by_side",
    "tendon_activations",
    "tendon_segments",
]

#: Colour (RGB in [0, 1]) of a tendon that no activation is given for.
NO_ACTIVATION_RGB = (0.55, 0.55, 0.55)
#: Default view direction (MuJoCo world, from the models' centre towards the camera):
#: in front of, right of and a little above a model that faces +x (OpenSim's anterior).
DEFAULT_VIEW = (1.0, -0.9, 0.35)

_MESHCAT_JS = Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js"
# msgpack extension codes of typed arrays understood by the meshcat viewer (msgpack-lite).
_EXT = {np.dtype(np.uint8): ("Uint8Array", 0x12), np.dtype(np.uint16): ("Uint16Array", 0x14),
        np.dtype(np.uint32): ("Uint32Array", 0x16), np.dtype(np.float32): ("Float32Array", 0x17)}


class ViewerError(O2MError):
    """The viewer cannot draw what it was given (array shapes, names, missing OpenSim parts)."""


# --------------------------------------------------------------------------------------------
# Poses
# --------------------------------------------------------------------------------------------


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
    coords = {cset.get(i).getName(): cset.get(i) for i in range(cset.getSize())}
    unknown = [n for n in coordinate_names if n not in coords]
    if unknown:
        raise ViewerError(f"{osim_path}: no coordinate(s) named {', '.join(unknown)}")
    given = [coords[n] for n in coordinate_names]
    if assemble is None:
        assemble = any(c.isDependent(state) and not c.getLocked(state) and n not in coordinate_names
                       for n, c in coords.items())

    bset = os_model.getBodySet()
    os_bodies = {bset.get(i).getName(): bset.get(i) for i in range(bset.getSize())}
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


# --------------------------------------------------------------------------------------------
# Geometry
# --------------------------------------------------------------------------------------------


def decimate_mesh(vertices: np.ndarray, faces: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Simplify a triangle mesh by vertex clustering (Rossignac & Borrel).

    Vertices (V, 3) falling in the same cube of side ``cell`` (the mesh's units, metres here)
    merge into their mean; faces (F, 3) that collapse, and duplicates, are dropped. Returns
    ``(vertices (V', 3) float, faces (F', 3) int)``. Detail below ``cell`` is lost: 2-4 mm
    keeps the shape of the bones of an arm and cuts its triangle count several-fold.
    """
    v = np.asarray(vertices, dtype=float).reshape(-1, 3)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if not cell or cell <= 0 or len(v) == 0:
        return v.copy(), f.copy()
    keys = np.floor((v - v.min(axis=0)) / float(cell)).astype(np.int64)
    _, inv = np.unique(keys, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    n = int(inv.max()) + 1
    sums = np.zeros((n, 3))
    np.add.at(sums, inv, v)
    merged = sums / np.bincount(inv, minlength=n)[:, None]
    nf = inv[f]
    nf = nf[(nf[:, 0] != nf[:, 1]) & (nf[:, 1] != nf[:, 2]) & (nf[:, 0] != nf[:, 2])]
    if len(nf) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    _, first = np.unique(np.sort(nf, axis=1), axis=0, return_index=True)
    nf = nf[np.sort(first)]
    used = np.unique(nf)
    remap = np.full(n, -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return merged[used], remap[nf]


def _pack(a: np.ndarray, normalized: bool = False) -> dict[str, Any]:
    arr = np.ascontiguousarray(a)
    typename, code = _EXT[arr.dtype]
    return {"itemSize": int(arr.shape[1]) if arr.ndim == 2 else 1, "type": typename,
            "array": umsgpack.Ext(code, arr.tobytes()), "normalized": normalized}


class _Lines(mg.Geometry):
    """Line segment end points (2S, 3) float32 with 8-bit RGB vertex colours (2S, 3)."""

    def __init__(self, points: np.ndarray, rgb: np.ndarray):
        super().__init__()
        self.points = np.asarray(points, dtype=np.float32).reshape(-1, 3)
        self.rgb = np.round(255 * np.clip(np.asarray(rgb, dtype=float), 0, 1)).astype(np.uint8).reshape(-1, 3)

    def lower(self, object_data: Any) -> dict[str, Any]:
        return {"uuid": self.uuid, "type": "BufferGeometry",
                "data": {"attributes": {"position": _pack(self.points), "color": _pack(self.rgb, True)}}}


class _TriMesh(mg.Geometry):
    """Indexed triangle mesh: float32 vertices, 16-bit indices when they fit, optional 8-bit
    RGB vertex colours ``rgb`` (V, 3) in [0, 1] (draw with ``vertexColors=True``)."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, rgb: np.ndarray | None = None):
        super().__init__()
        self.vertices = np.asarray(vertices, dtype=np.float32).reshape(-1, 3)
        self.faces = np.asarray(faces).reshape(-1, 3).astype(np.uint16 if len(self.vertices) < 65536 else np.uint32)
        self.rgb = None if rgb is None else np.round(255 * np.clip(np.asarray(rgb, float), 0, 1)).astype(np.uint8)

    def lower(self, object_data: Any) -> dict[str, Any]:
        attributes = {"position": _pack(self.vertices)}
        if self.rgb is not None:
            attributes["color"] = _pack(self.rgb.reshape(-1, 3), True)
        return {"uuid": self.uuid, "type": "BufferGeometry",
                "data": {"attributes": attributes, "index": _pack(self.faces.reshape(-1, 1))}}


class _Sphere(mg.Geometry):
    """three.js SphereGeometry with few segments; ``radii`` (3,) makes it an ellipsoid."""

    def __init__(self, radius: float, segments: int = 12, radii: Sequence[float] | None = None):
        super().__init__()
        self.radius, self.segments = float(radius), int(segments)
        self.radii = None if radii is None else np.asarray(radii, dtype=float)

    def intrinsic_transform(self) -> np.ndarray:
        return np.eye(4) if self.radii is None else np.diag(np.hstack([self.radii, 1.0]))

    def lower(self, object_data: Any) -> dict[str, Any]:
        return {"uuid": self.uuid, "type": "SphereGeometry", "radius": self.radius,
                "widthSegments": self.segments, "heightSegments": max(self.segments // 2, 4)}


def _lathe(r: np.ndarray, z: np.ndarray, n: int = 24) -> _TriMesh:
    """Surface of revolution about z of the profile (r_i, z_i)."""
    th = 2 * np.pi * np.arange(n) / n
    verts = np.stack([np.outer(r, np.cos(th)), np.outer(r, np.sin(th)), np.repeat(z[:, None], n, 1)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(len(r) - 1), np.arange(n), indexing="ij")
    a, b = i * n + j, i * n + (j + 1) % n
    c, d = a + n, b + n
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    return _TriMesh(verts, faces)


def _icosahedron() -> _TriMesh:
    """Regular icosahedron inscribed in the unit sphere."""
    p = (1 + 5**0.5) / 2
    v = np.array([[-1, p, 0], [1, p, 0], [-1, -p, 0], [1, -p, 0], [0, -1, p], [0, 1, p],
                  [0, -1, -p], [0, 1, -p], [p, 0, -1], [p, 0, 1], [-p, 0, -1], [-p, 0, 1]], dtype=float)
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
         [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11],
         [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    return _TriMesh(v / np.linalg.norm(v, axis=1, keepdims=True), np.array(f))


def _cylinder(radius: float, half: float) -> _TriMesh:
    return _lathe(np.array([0, radius, radius, radius, radius, 0]), np.array([-half, -half, -half, half, half, half]))


def _capsule(radius: float, half: float, k: int = 6) -> _TriMesh:
    a = np.linspace(-np.pi / 2, 0, k + 1)
    r = np.concatenate([radius * np.cos(a), radius * np.cos(a[::-1])])
    z = np.concatenate([-half + radius * np.sin(a), half - radius * np.sin(a[::-1])])
    return _lathe(r, z)


def _hex(rgb: Sequence[float]) -> int:
    r, g, b = (int(round(255 * min(max(float(c), 0.0), 1.0))) for c in rgb[:3])
    return (r << 16) | (g << 8) | b


def _material(rgba: Sequence[float], opacity: float | None = None) -> mg.MeshPhongMaterial:
    alpha = float(rgba[3]) if opacity is None else float(opacity)
    extra = {"depthWrite": False} if alpha < 1 else {}
    return mg.MeshPhongMaterial(color=_hex(rgba), opacity=alpha, transparent=alpha < 1, **extra)


def _transform(pos: np.ndarray, rot: np.ndarray | None = None) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = pos
    if rot is not None:
        m[:3, :3] = rot
    return m


def _quat_mat(q: np.ndarray) -> np.ndarray:
    r = np.zeros(9)
    mujoco.mju_quat2Mat(r, np.asarray(q, dtype=float))
    return r.reshape(3, 3)


def _clean(name: str | None, fallback: str) -> str:
    s = (name or "").replace("/", "_").strip()
    return s or fallback


# --------------------------------------------------------------------------------------------
# Recording window (stands in for meshcat's server until one is needed)
# --------------------------------------------------------------------------------------------


class _Node:
    __slots__ = ("object", "properties", "transform")

    def __init__(self) -> None:
        self.object: bytes | None = None
        self.properties: dict[str, bytes] = {}
        self.transform: bytes | None = None


class _Window:
    """A meshcat window that records the scene (as the meshcat server does) in-process.

    Commands are packed with single-precision floats. A meshcat server is started (or joined,
    with ``zmq_url``) by :meth:`connect`, which replays the recorded scene; from then on every
    command also goes to the server.
    """

    def __init__(self) -> None:
        self.nodes: dict[tuple[str, ...], _Node] = {}
        self.animation: bytes | None = None
        self.server_proc: Any = None
        self.zmq_socket: Any = None
        self.web_url: str | None = None

    # meshcat's ViewerWindow interface
    def send(self, command: Any) -> None:
        data = command.lower()
        packed = umsgpack.packb(data, force_float_precision="single")
        kind, path = data["type"], tuple(p for p in data["path"].split("/") if p)
        if kind == "set_animation":
            self.animation = packed
        elif kind == "delete":
            for key in [k for k in self.nodes if k[:len(path)] == path]:
                del self.nodes[key]
        else:
            node = self.nodes.setdefault(path, _Node())
            if kind == "set_object":
                node.object, node.properties = packed, {}
            elif kind == "set_transform":
                node.transform = packed
            elif kind == "set_property":
                node.properties[data["property"]] = packed
        if self.zmq_socket is not None:
            self._forward(kind, data["path"], packed)

    def _forward(self, kind: str, path: str, packed: bytes) -> None:
        self.zmq_socket.send_multipart([kind.encode("utf-8"), path.encode("utf-8"), packed])
        self.zmq_socket.recv()

    def commands(self) -> Iterable[tuple[str, str, bytes]]:
        """(type, path, packed command) of the recorded scene, animation last."""
        for path, node in self.nodes.items():
            p = "/" + "/".join(path)
            if node.object is not None:
                yield "set_object", p, node.object
            for packed in node.properties.values():
                yield "set_property", p, packed
            if node.transform is not None:
                yield "set_transform", p, node.transform
        if self.animation is not None:
            yield "set_animation", "", self.animation

    def get_scene(self, title: str = "o2m") -> str:
        import base64

        cmds = "".join(
            f'fetch("data:application/octet-binary;base64,{base64.b64encode(packed).decode("ascii")}")'
            ".then(r => r.arrayBuffer()).then(b => viewer.handle_command_bytearray(new Uint8Array(b)));\n"
            for _, _, packed in self.commands())
        js = _MESHCAT_JS.read_text(encoding="utf-8")
        return (
            "<!DOCTYPE html>\n<html>\n<head><meta charset=utf-8><title>" + _html.escape(title) + "</title>\n"
            "<style>body {margin: 0;} #meshcat-pane {width: 100vw; height: 100vh; overflow: hidden;}</style>\n"
            "</head>\n<body>\n<div id=\"meshcat-pane\"></div>\n<script>\n" + js + "\n</script>\n<script>\n"
            "var viewer = new MeshCat.Viewer(document.getElementById(\"meshcat-pane\"));\n" + cmds +
            "</script>\n</body>\n</html>\n"
        )

    def connect(self, zmq_url: str | None = None) -> None:
        """Start a meshcat server (or connect to ``zmq_url``) and send it the recorded scene."""
        if self.zmq_socket is not None:
            return
        import zmq

        if zmq_url is None:
            from meshcat.servers.zmqserver import start_zmq_server_as_subprocess

            self.server_proc, zmq_url, self.web_url = start_zmq_server_as_subprocess()
        sock = zmq.Context.instance().socket(zmq.REQ)
        sock.connect(zmq_url)
        if self.web_url is None:
            sock.send(b"url")
            self.web_url = sock.recv().decode("utf-8")
        self.zmq_socket = sock
        for kind, path, packed in self.commands():
            self._forward(kind, path, packed)

    def open(self) -> None:
        self.connect()
        webbrowser.open(str(self.web_url), new=2)

    def wait(self) -> str:
        self.connect()
        self.zmq_socket.send(b"wait")
        return self.zmq_socket.recv().decode("utf-8")

    def get_image(self) -> Any:
        raise ViewerError("images need a browser connected to a meshcat server: use Viewer.open() "
                          "and meshcat's own Visualizer.get_image, or screenshot the exported HTML")

    def close(self) -> None:
        if self.zmq_socket is not None:
            self.zmq_socket.close(linger=0)
            self.zmq_socket = None
        if self.server_proc is not None:
            self.server_proc.kill()
            self.server_proc.wait()
            for stream in (self.server_proc.stdout, self.server_proc.stderr):
                if stream is not None:
                    stream.close()
            self.server_proc = None


# --------------------------------------------------------------------------------------------
# Scenes
# --------------------------------------------------------------------------------------------


class ModelScene:
    """The drawing of one MuJoCo model in a :class:`Viewer` (create with :meth:`Viewer.add_model`).

    Args:
        viewer: the viewer drawing it.
        model: the MuJoCo model (its meshes, geoms, sites and tendons are drawn).
        name: node name under ``/meshcat/o2m``.
        offset: (3,) translation of the whole drawing, metres, MuJoCo world frame.
        decimate: vertex clustering cell (metres) applied to every mesh; None keeps them whole.
        show_sites: draw sites whose group is in ``site_groups`` (o2m puts markers in group 4,
            path points in 3 and wrap helper sites in 5).
        show_wraps: draw the geoms tendons wrap over (translucent, ``wrap_opacity``).
        show_tendons: draw tendon paths.
        mesh_rgba: (4,) colour replacing every mesh geom's ``rgba`` (e.g. to tint one side of a
            comparison); None keeps the model's colours.
        arc_points: points drawn inside each arc over a wrapping geom (see :func:`tendon_segments`).
    """

    def __init__(
        self,
        viewer: Viewer,
        model: mujoco.MjModel,
        *,
        name: str = "mujoco",
        offset: Sequence[float] = (0.0, 0.0, 0.0),
        decimate: float | None = None,
        show_sites: bool = True,
        site_groups: Sequence[int] = (0, 1, 2, 3, 4),
        show_wraps: bool = True,
        wrap_opacity: float = 0.3,
        show_tendons: bool = True,
        mesh_rgba: Sequence[float] | None = None,
        arc_points: int = 6,
    ):
        self.viewer, self.model = viewer, model
        self.name = _clean(name, "model")
        self.offset = np.asarray(offset, dtype=float).reshape(3)
        self.node = viewer.root[self.name]
        self.show_tendons = show_tendons and model.ntendon > 0
        self.arc_points = int(arc_points)
        self.bounds: tuple[np.ndarray, np.ndarray] | None = None
        self.body_paths = [f"bodies/{_clean(model.body(b).name, f'body{b}')}" for b in range(model.nbody)]
        self.node.delete()  # a scene of the same name is replaced
        self.node.set_transform(_transform(self.offset))
        wrap_kinds = (int(mujoco.mjtWrap.mjWRAP_SPHERE), int(mujoco.mjtWrap.mjWRAP_CYLINDER))
        wrap_geoms = {int(model.wrap_objid[w]) for w in range(model.nwrap) if int(model.wrap_type[w]) in wrap_kinds}
        self._draw_geoms(decimate, wrap_geoms, show_wraps, wrap_opacity, mesh_rgba)
        if show_sites:
            self._draw_sites(set(int(g) for g in site_groups))
        self._drawn_geoms = [g for g in range(model.ngeom)
                             if int(model.geom_type[g]) != int(mujoco.mjtGeom.mjGEOM_PLANE)]
        self.show(mujoco_frames(model, model.qpos0, arc_points=self.arc_points)[0])

    # ---- static content
    def _draw_geoms(self, decimate: float | None, wrap_geoms: set[int], show_wraps: bool, wrap_opacity: float,
                    mesh_rgba: Sequence[float] | None) -> None:
        m = self.model
        gt = mujoco.mjtGeom
        skipped = []
        for g in range(m.ngeom):
            kind = int(m.geom_type[g])
            is_wrap = g in wrap_geoms
            if is_wrap and not show_wraps:
                continue
            size = m.geom_size[g]
            rgba = m.mat_rgba[m.geom_matid[g]] if int(m.geom_matid[g]) >= 0 else m.geom_rgba[g]
            if kind == int(gt.mjGEOM_MESH):
                mid = int(m.geom_dataid[g])
                va, vn = int(m.mesh_vertadr[mid]), int(m.mesh_vertnum[mid])
                fa, fn = int(m.mesh_faceadr[mid]), int(m.mesh_facenum[mid])
                verts, faces = m.mesh_vert[va:va + vn], m.mesh_face[fa:fa + fn]
                if decimate:
                    verts, faces = decimate_mesh(verts, faces, decimate)
                geom: Any = _TriMesh(verts, faces)
                if mesh_rgba is not None:
                    rgba = np.asarray(mesh_rgba, dtype=float)
            elif kind == int(gt.mjGEOM_SPHERE):
                geom = _Sphere(size[0], 24)
            elif kind == int(gt.mjGEOM_ELLIPSOID):
                geom = _Sphere(1.0, 24, radii=size[:3])
            elif kind == int(gt.mjGEOM_CAPSULE):
                geom = _capsule(size[0], size[1])
            elif kind == int(gt.mjGEOM_CYLINDER):
                geom = _cylinder(size[0], size[1])
            elif kind == int(gt.mjGEOM_BOX):
                geom = mg.Box(2 * size[:3])
            else:  # plane (the grid stands in), hfield, sdf, ...
                skipped.append(m.geom(g).name or f"geom{g}")
                continue
            if rgba[3] <= 0:
                continue
            path = f"{self.body_paths[int(m.geom_bodyid[g])]}/g{g}_{_clean(m.geom(g).name, 'geom')}"
            self.node[path].set_object(geom, _material(rgba, min(wrap_opacity, float(rgba[3])) if is_wrap else None))
            self.node[path].set_transform(_transform(m.geom_pos[g], _quat_mat(m.geom_quat[g])))
        if skipped:
            warnings.warn(f"not drawn (geom type not supported): {', '.join(skipped)}", stacklevel=3)

    def _draw_sites(self, groups: set[int]) -> None:
        """The sites of each body as one mesh of small spheres (one draw call per body)."""
        m = self.model
        unit = _icosahedron()  # 12 vertices, 20 triangles: enough for spheres of a few mm
        by_body: dict[int, list[int]] = {}
        for s in range(m.nsite):
            if int(m.site_group[s]) in groups and m.site_rgba[s][3] > 0:
                by_body.setdefault(int(m.site_bodyid[s]), []).append(s)
        nv = len(unit.vertices)
        for b, sites in by_body.items():
            verts = np.concatenate([m.site_pos[s] + float(m.site_size[s][0]) * unit.vertices for s in sites])
            faces = np.concatenate([unit.faces.astype(np.int64) + k * nv for k in range(len(sites))])
            rgb = np.repeat(m.site_rgba[sites, :3], nv, axis=0)
            self.node[f"{self.body_paths[b]}/sites"].set_object(
                _TriMesh(verts, faces, rgb), mg.MeshPhongMaterial(color=0xFFFFFF, vertexColors=True))

    # ---- poses
    def _update_bounds(self, frames: Sequence[Frame]) -> None:
        m = self.model
        b = m.geom_bodyid[self._drawn_geoms]
        pts = [f.body_pos[b] + np.einsum("gij,gj->gi", f.body_rot[b], m.geom_pos[self._drawn_geoms])
               for f in frames[:: max(1, len(frames) // 10)]]
        pts += [f.body_pos[1:] for f in frames[:1]]
        allp = np.concatenate([p.reshape(-1, 3) for p in pts]) + self.offset
        if len(allp):
            self.bounds = (allp.min(axis=0), allp.max(axis=0))

    def _check(self, frame: Frame) -> None:
        if frame.body_pos.shape != (self.model.nbody, 3) or len(frame.tendon_segments) != self.model.ntendon:
            raise ViewerError(f"frame has {frame.body_pos.shape[0]} bodies and {len(frame.tendon_segments)} tendons; "
                              f"the model has {self.model.nbody} and {self.model.ntendon}")

    def _lines(self, frame: Frame, act: np.ndarray) -> Any:
        """meshcat LineSegments of all tendon paths of ``frame``, coloured by ``act`` (ntendon,)."""
        segs = [s.reshape(-1, 3) for s in frame.tendon_segments]
        if not any(len(s) for s in segs):
            return None
        colors = activation_colors(act)
        col = np.concatenate([np.repeat(colors[t][None], len(s), 0) for t, s in enumerate(segs)])
        return mg.LineSegments(_Lines(np.concatenate(segs), col), mg.LineBasicMaterial(vertexColors=True, linewidth=2))

    def _set_bodies(self, frame: Frame) -> None:
        for b in range(1, self.model.nbody):
            self.node[self.body_paths[b]].set_transform(_transform(frame.body_pos[b], frame.body_rot[b]))

    def show(self, frame: Frame, activations: np.ndarray | None = None) -> None:
        """Draw one pose: body transforms, and tendon paths coloured by ``activations``
        ((nu,) or (ntendon,), see :func:`tendon_activations`)."""
        self._check(frame)
        self._set_bodies(frame)
        if self.show_tendons:
            self.node["tendons"].delete()
            lines = self._lines(frame, tendon_activations(self.model, activations, 1)[0])
            if lines is not None:
                self.node["tendons/pose"].set_object(lines)
        self._update_bounds([frame])

    def show_qpos(self, qpos: np.ndarray | None = None, activations: np.ndarray | None = None) -> None:
        """Draw MuJoCo's pose of ``qpos`` (nq,) (``model.qpos0`` when None)."""
        q = self.model.qpos0 if qpos is None else qpos
        self.show(mujoco_frames(self.model, q, arc_points=self.arc_points)[0], activations)

    def add_to_animation(self, animation: Animation, frames: Sequence[Frame], activations: np.ndarray | None = None,
                         *, tendon_stride: int = 1) -> None:
        """Add the tracks of ``frames`` (one per animation frame) to a meshcat ``animation``.

        Body poses become position/quaternion tracks (keys dropped where the body does not
        move); tendon paths, every ``tendon_stride``-th frame, become line objects shown by a
        ``visible`` track (the flip-book of the module docstring). ``activations``: (T, nu)
        or (T, ntendon), T = len(frames), or None.
        """
        T = len(frames)
        if T == 0:
            raise ViewerError("no frames to animate")
        for f in frames:
            self._check(f)
        fps = animation.default_framerate
        base = self.node.path
        pos = np.stack([f.body_pos for f in frames])  # (T, nbody, 3)
        rot = np.stack([f.body_rot for f in frames])
        for b in range(1, self.model.nbody):
            quats = np.empty((T, 4))
            for k in range(T):
                mujoco.mju_mat2Quat(quats[k], np.ascontiguousarray(rot[k, b]).reshape(9))
            quats = quats[:, [1, 2, 3, 0]]  # three.js order x, y, z, w
            sign = np.sign(np.sum(quats[1:] * quats[:-1], axis=1))
            quats[1:] *= np.cumprod(np.where(sign == 0, 1, sign))[:, None]
            clip = AnimationClip(fps=fps)
            for prop, jstype, vals in (("position", "vector3", pos[:, b]), ("quaternion", "quaternion", quats)):
                keep = _keys_to_keep(vals)
                clip.tracks[prop] = AnimationTrack(prop, jstype, [int(k) for k in keep], vals[keep].tolist())
            animation.clips[base.append(self.body_paths[b])] = clip
        act = tendon_activations(self.model, activations, T)
        self._set_bodies(frames[0])
        if self.show_tendons:
            self.node["tendons"].delete()
            stride = max(1, int(tendon_stride))
            for k in range(0, T, stride):
                lines = self._lines(frames[k], act[k])
                if lines is None:
                    continue
                path = f"tendons/f{k:05d}"
                self.node[path].set_object(lines)
                self.node[path].set_property("visible", k == 0)
                keys: list[tuple[int, bool]] = ([(0, False)] if k > 0 else []) + [(k, True)]
                if k + stride < T:
                    keys.append((k + stride, False))
                clip = AnimationClip(fps=fps)
                clip.tracks["visible"] = AnimationTrack("visible", "boolean", [t for t, _ in keys],
                                                        [v for _, v in keys])
                animation.clips[base.append(path)] = clip
        self._update_bounds(frames)


def _keys_to_keep(vals: np.ndarray, tol: float = 1e-7) -> np.ndarray:
    """Indices of keyframes needed for linear interpolation of ``vals`` (T, k) to be exact:
    the ends and every key whose value differs from a neighbour's."""
    if len(vals) <= 2:
        return np.arange(len(vals))
    diff = np.any(np.abs(np.diff(vals, axis=0)) > tol, axis=1)  # (T-1,) change between k and k+1
    keep = np.zeros(len(vals), dtype=bool)
    keep[[0, -1]] = True
    keep[1:] |= diff
    keep[:-1] |= diff
    return np.flatnonzero(keep)


# --------------------------------------------------------------------------------------------
# Viewer
# --------------------------------------------------------------------------------------------


class Viewer:
    """A meshcat visualizer for converted models, exportable to a self-contained HTML file.

    Args:
        server: start the meshcat server now (otherwise only when a live view is asked for).
        zmq_url: join an already running meshcat server instead of starting one.
        background: (3,) uniform background colour (RGB in [0, 1]); None keeps meshcat's gradient.
        grid: show meshcat's floor grid (moved to the models' lowest point by :meth:`frame_camera`).
        axes: show meshcat's world axes.
        title: title of the exported HTML page.

    ``vis`` is the underlying ``meshcat.Visualizer`` (anything meshcat can do works on it, and is
    exported); ``root`` is its node ``/meshcat/o2m`` holding the models.
    """

    def __init__(self, *, server: bool = False, zmq_url: str | None = None,
                 background: Sequence[float] | None = None, grid: bool = False, axes: bool = False,
                 title: str = "o2m"):
        self._window = _Window()
        self.vis = meshcat.Visualizer(window=self._window)
        self.root = self.vis["o2m"]
        self.scenes: list[ModelScene] = []
        self.title = title
        if background is not None:
            for key in ("top_color", "bottom_color"):
                self.vis["/Background"].set_property(key, [float(c) for c in background[:3]])
        if not grid:
            self.vis["/Grid"].set_property("visible", False)
        if not axes:
            self.vis["/Axes"].set_property("visible", False)
        if server or zmq_url:
            self._window.connect(zmq_url)

    # ---- content
    def add_model(self, model: mujoco.MjModel, **kwargs: Any) -> ModelScene:
        """Draw ``model`` in its default pose; keyword arguments go to :class:`ModelScene`."""
        scene = ModelScene(self, model, **kwargs)
        self.scenes = [s for s in self.scenes if s.name != scene.name] + [scene]
        return scene

    def set_animation(self, animation: Animation, *, play: bool = True, repetitions: int = 1) -> None:
        """Send a meshcat ``animation`` (it replaces any earlier one)."""
        self.vis.set_animation(animation, play=play, repetitions=repetitions)

    def frame_camera(self, direction: Sequence[float] = DEFAULT_VIEW, distance: float | None = None) -> None:
        """Centre the drawing on the origin and put the camera along ``direction``.

        ``direction`` (3,) is from the models' centre towards the camera, MuJoCo world frame;
        ``distance`` (m) defaults to one that fits the models' bounding box (box of the geom
        centres over the drawn frames) in a 4:3 window. The floor grid is moved to the lowest point.
        """
        boxes = [s.bounds for s in self.scenes if s.bounds is not None]
        if not boxes:
            return
        lo = np.min([b[0] for b in boxes], axis=0)
        hi = np.max([b[1] for b in boxes], axis=0)
        center = (lo + hi) / 2
        d = np.asarray(direction, dtype=float)
        d = d / np.linalg.norm(d)
        if distance is None:  # fit the box in meshcat's 75-degree vertical field of view (4:3 window)
            right = np.cross(d, [0.0, 0.0, 1.0])
            right = right / np.linalg.norm(right) if np.linalg.norm(right) > 1e-9 else np.array([0.0, 1.0, 0.0])
            up = np.cross(right, d)
            corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
            rel = corners - center
            half_w, half_h = np.abs(rel @ right).max(), np.abs(rel @ up).max()
            tan_v = math.tan(math.radians(37.5))
            distance = 1.15 * max(half_w / (tan_v * 4 / 3), half_h / tan_v, 0.2) + np.abs(rel @ d).max()
        dist = float(distance)
        self.root.set_transform(_transform(-center))
        cam = d * dist  # meshcat's camera node is in three.js coordinates: y up
        self.vis["/Cameras/default/rotated/<object>"].set_property("position", [cam[0], cam[2], -cam[1]])
        self.vis["/Grid"].set_transform(_transform([0.0, 0.0, lo[2] - center[2] - 0.05]))

    # ---- output
    def static_html(self) -> str:
        """The scene (and animation) as one self-contained HTML page."""
        return self._window.get_scene(self.title)

    def export_html(self, path: str | os.PathLike[str]) -> Path:
        """Write :meth:`static_html` to ``path`` (folders created); returns the path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(self.static_html(), encoding="utf-8")
        return path

    def url(self) -> str:
        """URL of the live view (starts the meshcat server if none is running)."""
        self._window.connect()
        return str(self._window.web_url)

    def open(self) -> Viewer:
        """Open the live view in a web browser (starts the meshcat server if needed)."""
        self._window.open()
        return self

    def jupyter_cell(self, height: int = 480) -> Any:
        """An IPython IFrame showing the live view (starts the meshcat server if needed)."""
        from IPython.display import IFrame

        return IFrame(self.url(), width="100%", height=height)

    @property
    def server_running(self) -> bool:
        """Whether a meshcat server process was started and is alive."""
        proc = self._window.server_proc
        return proc is not None and proc.poll() is None

    def close(self) -> None:
        """Delete the drawing (``vis.delete()``) and stop the meshcat server process, if any."""
        self.vis.delete()
        self._window.close()

    def __enter__(self) -> Viewer:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def notebook_iframe(path: str | os.PathLike[str], *, height: int = 480, width: str | int = "100%",
                    start: str | os.PathLike[str] | None = None) -> Any:
    """An ``IPython.display.IFrame`` showing an exported HTML file, without embedding it.

    The notebook then holds a few bytes, not the megabytes of the file. The file is addressed
    relative to ``start`` (default: the current directory, which is the notebook's in Jupyter),
    so it must lie inside the folder the Jupyter server serves.
    """
    from IPython.display import IFrame

    rel = os.path.relpath(os.fspath(path), os.fspath(start) if start is not None else os.getcwd())
    return IFrame(Path(rel).as_posix(), width=width, height=height)


# --------------------------------------------------------------------------------------------
# One-call helpers
# --------------------------------------------------------------------------------------------


def _viewer(viewer: Viewer | None, background: Sequence[float] | None, grid: bool) -> Viewer:
    return viewer if viewer is not None else Viewer(background=background, grid=grid)


def show_pose(model: mujoco.MjModel, qpos: np.ndarray | None = None, activations: np.ndarray | None = None, *,
              viewer: Viewer | None = None, background: Sequence[float] | None = None, grid: bool = False,
              html: str | os.PathLike[str] | None = None, **scene: Any) -> Viewer:
    """Draw ``model`` in the pose ``qpos`` (nq,) (default ``qpos0``), tendons coloured by
    ``activations`` ((nu,) or (ntendon,)); frame the camera; write ``html`` if given.

    ``scene`` keywords go to :class:`ModelScene` (e.g. ``decimate=0.003``). Returns the viewer.
    """
    v = _viewer(viewer, background, grid)
    s = v.add_model(model, **scene)
    s.show_qpos(qpos, activations)
    v.frame_camera()
    if html is not None:
        v.export_html(html)
    return v


def animate_qpos(model: mujoco.MjModel, qpos: np.ndarray, fps: float = 30.0, activations: np.ndarray | None = None,
                 *, viewer: Viewer | None = None, background: Sequence[float] | None = None, grid: bool = False,
                 tendon_stride: int = 1, html: str | os.PathLike[str] | None = None, **scene: Any) -> Viewer:
    """Animate MuJoCo ``qpos`` (T, nq) at ``fps`` frames per second.

    ``activations`` (T, nu) or (T, ntendon) colour the tendons frame by frame. ``scene``
    keywords go to :class:`ModelScene`. The animation plays once on load (meshcat's controls
    replay it); ``html`` writes the exported page. Returns the viewer.
    """
    q = _as_2d(qpos, model.nq, "qpos")
    v = _viewer(viewer, background, grid)
    s = v.add_model(model, **scene)
    anim = Animation(default_framerate=float(fps))
    s.add_to_animation(anim, mujoco_frames(model, q, arc_points=s.arc_points), activations,
                       tendon_stride=tendon_stride)
    v.set_animation(anim)
    v.frame_camera()
    if html is not None:
        v.export_html(html)
    return v


def side_by_side(
    model: mujoco.MjModel,
    osim_path: str | os.PathLike[str],
    coordinate_names: Sequence[str],
    coordinate_values: np.ndarray,
    qpos: np.ndarray,
    fps: float = 30.0,
    activations: np.ndarray | None = None,
    *,
    offset: Sequence[float] = (0.0, 0.6, 0.0),
    viewer: Viewer | None = None,
    background: Sequence[float] | None = None,
    grid: bool = False,
    tendon_stride: int = 1,
    html: str | os.PathLike[str] | None = None,
    assemble: bool | None = None,
    opensim_rgba: Sequence[float] | None = (0.93, 0.87, 0.78, 1.0),
    view: Sequence[float] | None = None,
    **scene: Any,
) -> Viewer:
    """OpenSim's motion (shifted by ``offset``) next to MuJoCo's (at the origin), one animation.

    The OpenSim side is posed by OpenSim itself (:func:`opensim_frames` of
    ``coordinate_values`` (T, C) for the OpenSim coordinates ``coordinate_names``, radians /
    metres) and drawn with the MuJoCo model's meshes in ``opensim_rgba`` (None: the model's
    colours), with OpenSim's own muscle paths; the MuJoCo side by MuJoCo from ``qpos`` (T, nq),
    e.g. :attr:`o2m.motion.Motion.qpos`. Both play the same ``activations`` ((T, nu) or
    (T, ntendon)) at ``fps``. ``offset`` (3,) metres, MuJoCo world frame (+y is the left of an
    OpenSim model facing +x). ``view`` is the camera direction (default: across the offset,
    from slightly above). Returns the viewer; ``html`` writes the page.
    """
    q = _as_2d(qpos, model.nq, "qpos")
    vals = _as_2d(coordinate_values, len(coordinate_names), "coordinate_values")
    if len(vals) != len(q):
        raise ViewerError(f"{len(vals)} OpenSim frames but {len(q)} MuJoCo frames")
    v = _viewer(viewer, background, grid)
    anim = Animation(default_framerate=float(fps))
    os_scene = v.add_model(model, name="opensim", offset=offset, mesh_rgba=opensim_rgba, **scene)
    os_frames = opensim_frames(osim_path, model, coordinate_names, vals, assemble=assemble, qpos=q)
    os_scene.add_to_animation(anim, os_frames, activations, tendon_stride=tendon_stride)
    mj_scene = v.add_model(model, name="mujoco", **scene)
    mj_scene.add_to_animation(anim, mujoco_frames(model, q, arc_points=mj_scene.arc_points), activations,
                              tendon_stride=tendon_stride)
    v.set_animation(anim)
    if view is None:  # look across the offset, so that both models are seen alike
        off = np.asarray(offset, dtype=float)
        across = np.cross(off, [0.0, 0.0, 1.0])
        across = across / np.linalg.norm(across) if np.linalg.norm(across) > 1e-9 else np.array([1.0, 0.0, 0.0])
        view = tuple(across + [0.0, 0.0, 0.35])
    v.frame_camera(view)
    if html is not None:
        v.export_html(html)
    return v
