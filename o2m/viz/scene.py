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
mujoco 4.0.0 / meshcat 0.3.2 (``tests/viz/test_scene.py`` re-measures the arm26 and MoBL-ARMS
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

import math
import os
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

try:
    import meshcat
    import meshcat.geometry as mg
    from meshcat.animation import Animation, AnimationClip, AnimationTrack
except ImportError as _exc:  # pragma: no cover - meshcat is in environment.txt
    raise ImportError("o2m.viz needs meshcat: pip install meshcat") from _exc

from o2m.viz.frames import (
    Frame,
    ViewerError,
    _as_2d,
    activation_colors,
    mujoco_frames,
    opensim_frames,
    tendon_activations,
)
from o2m.viz.geometry import (
    _capsule,
    _cylinder,
    _icosahedron,
    _Lines,
    _material,
    _quat_mat,
    _Sphere,
    _transform,
    _TriMesh,
    decimate_mesh,
)
from o2m.viz.window import _Window

__all__ = ["DEFAULT_VIEW", "ModelScene", "Viewer", "animate_qpos", "notebook_iframe", "show_pose", "side_by_side"]

#: Default view direction (MuJoCo world, from the models' centre towards the camera):
#: in front of, right of and a little above a model that faces +x (OpenSim's anterior).
DEFAULT_VIEW = (1.0, -0.9, 0.35)


def _clean(name: str | None, fallback: str) -> str:
    s = (name or "").replace("/", "_").strip()
    return s or fallback


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
