"""meshcat geometry for MuJoCo models: meshes (16-bit indices, vertex colours), line segments,
primitives, materials and transforms; mesh decimation by vertex clustering.

Sizes and positions are metres, in the frame of the MuJoCo body holding the geom (z up).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

try:
    import meshcat.geometry as mg
    import umsgpack
except ImportError as _exc:  # pragma: no cover - meshcat is in environment.txt
    raise ImportError("o2m.viz needs meshcat: pip install meshcat") from _exc

__all__ = ["decimate_mesh"]

# msgpack extension codes of typed arrays understood by the meshcat viewer (msgpack-lite).
_EXT = {np.dtype(np.uint8): ("Uint8Array", 0x12), np.dtype(np.uint16): ("Uint16Array", 0x14),
        np.dtype(np.uint32): ("Uint32Array", 0x16), np.dtype(np.float32): ("Float32Array", 0x17)}


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

