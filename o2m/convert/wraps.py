"""Wrap objects: a MuJoCo wrap geom, with a side site, for each path that uses one.

Wrap objects become wrap geoms, one per path that uses them (so :mod:`o2m.convert.wrapfit` can fit
each path's own): spheres and cylinders as they are; an ellipsoid as a sphere or a cylinder,
the wrap fit keeping per path the one nearer OpenSim (:mod:`o2m.convert.ellipsoid_standins`); a
torus as the cylinder OpenSim wraps over at the reference pose (:func:`torus_cylinder`). Each is
placed on the path segment (within the wrap's OpenSim range) that passes closest to it at the
reference pose, with a side site on the side that segment passes or that the quadrant names
(MuJoCo 4.0: the tendon wraps the way the straight path through the side site goes). Sizes are
metres; on ground, OpenSim's Y-up frame is mapped to MuJoCo's Z-up.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from o2m.convert.ellipsoid_standins import first_kind, standins
from o2m.convert.pathpoints import PathContext
from o2m.convert.records import Approximation
from o2m.mj import mjcf_text
from o2m.osim.paths import Path, WrapObject
from o2m.transforms import Transform, matrix_to_quat

#: Distance of a side site from a wrap geom's centre, in radii.
SIDE_SITE_DISTANCE = 2.0


@dataclass
class _PlacedWrap:
    segment: int  # the path segment (between points segment and segment+1) it wraps
    geom: str
    sidesite: str


@dataclass
class PathGeom:
    """A wrap geom of one tendon (MuJoCo names), for :mod:`o2m.convert.wrapfit`: ``kind`` is the OpenSim
    element it stands for (``WrapSphere``, ``WrapCylinder`` or ``WrapEllipsoid``; a
    ConditionalPathPoint's sphere is not fitted), ``source`` its OpenSim name and ``body`` the OpenSim body it is on;
    ``kind_mj`` the MuJoCo geom type it starts as and, for an ellipsoid, ``alternative`` its other
    stand-in (kind, size, quat; :mod:`o2m.convert.ellipsoid_standins`), which the wrap fit tries too."""

    tendon: str
    geom: str
    sidesite: str
    kind: str
    source: str
    body: str = ""
    kind_mj: str = ""
    alternative: dict | None = None


class WrapGeoms:
    """The wrap geoms of a model's paths and their side sites."""

    def __init__(self, ctx: PathContext, wraps: dict[str, WrapObject]):
        self.ctx = ctx
        self.b = ctx.b
        self.wraps = wraps
        self.geoms: dict[str, str | None] = {}  # wrap object -> MuJoCo geom name (None: not converted)
        #: geom name -> (its frame in its OpenSim body, MuJoCo kind, radius)
        self.geom_frames: dict[str, tuple[Transform, str, float]] = {}
        #: ellipsoid geom name -> its other stand-in (:mod:`o2m.convert.ellipsoid_standins`)
        self.alternatives: dict[str, dict] = {}

    def geom(self, wrap: WrapObject, a: np.ndarray | None = None, b: np.ndarray | None = None) -> str | None:
        """A new MuJoCo geom for a wrap object (each path gets its own, so fitting one path's wrap
        leaves the others alone), or None when it has no MuJoCo twin (a torus whose path segment
        ``a``-``b``, ground frame at the reference pose, is not given)."""
        if self.geoms.get(wrap.name, "") is None:
            return None
        first_use = wrap.name not in self.geoms
        self._check_size(wrap)
        x = self.ctx.in_world(wrap.body, wrap.frame)
        kind, size, extra_rot = wrap.kind, None, np.eye(3)
        frame = wrap.frame
        if kind == "torus":
            if a is None or b is None:
                self.b.result.notes.append(f"WrapTorus '{wrap.name}' is not converted (no path segment to place it on)")
                return None
            frame = wrap.frame @ self._torus_cylinder(wrap, a, b, first_use)
            x = self.ctx.in_world(wrap.body, frame)
            kind, size = "cylinder", [wrap.inner_radius, wrap.inner_radius, 0]
        elif kind == "sphere":
            size = [wrap.radius, 0, 0]
        elif kind == "cylinder":
            size = [wrap.radius, max(wrap.length, 1e-6) / 2, 0]
        elif kind == "ellipsoid":
            kind, size, extra_rot = self._ellipsoid(wrap, first_use)
        x = x @ Transform(extra_rot)
        name = self.ctx.unique(f"wrap_{wrap.name}")
        gtype = mujoco.mjtGeom.mjGEOM_SPHERE if kind == "sphere" else mujoco.mjtGeom.mjGEOM_CYLINDER
        quat = matrix_to_quat(x.rot)
        self.b.bodies[wrap.body].add_geom(name=name, type=gtype, size=size, pos=x.pos, quat=quat,
                                          contype=0, conaffinity=0, group=3, density=0, rgba=[0.3, 0.7, 0.9, 0.4])
        self.ctx.exact[("geom", name)] = {"pos": x.pos, "quat": np.asarray(quat, dtype=float),
                                          "size": np.asarray(size[:2] if kind == "cylinder" else size[:1],
                                                             dtype=float)}
        self.geoms[wrap.name] = name
        self.geom_frames[name] = (frame @ Transform(extra_rot), kind, float(size[0]))
        if wrap.kind == "ellipsoid":
            self.alternatives[name] = self._alternative(wrap, kind)
        return name

    def _ellipsoid(self, wrap: WrapObject, first_use: bool) -> tuple[str, list[float], np.ndarray]:
        """The stand-in an ellipsoid starts as (MuJoCo kind, size, rotation from its frame), its
        approximation recorded on first use (the wrap fit measures it against OpenSim)."""
        kind = first_kind(wrap.dimensions)
        size, rot, gap, what = standins(wrap.dimensions)[kind]
        if first_use:
            dims = [float(v) for v in wrap.dimensions]
            self.b.result.approximations.append(Approximation(
                "WrapEllipsoid", wrap.name, f"ellipsoid {dims} wrapped as {what}", gap, "m",
                "largest gap between the two surfaces along any semi-axis"))
        return kind, size, rot

    def _alternative(self, wrap: WrapObject, kind: str) -> dict:
        """The other stand-in of an ellipsoid (kind, size, quat in its MuJoCo body) for the wrap fit."""
        other = "sphere" if kind == "cylinder" else "cylinder"
        size, rot, _, _ = standins(wrap.dimensions)[other]
        x = self.ctx.in_world(wrap.body, wrap.frame) @ Transform(rot)
        return {"kind": other, "size": [float(v) for v in size], "quat": [float(v) for v in matrix_to_quat(x.rot)]}

    def _torus_cylinder(self, wrap: WrapObject, a: np.ndarray, b: np.ndarray, first_use: bool) -> Transform:
        """The frame (in the torus's) of the cylinder standing for torus ``wrap`` on the segment
        ``a``-``b`` (ground, reference pose), recorded as an approximation on first use."""
        to_torus = (self.b.ground_frames[wrap.body] @ wrap.frame).inverse()
        if first_use:
            self.b.result.approximations.append(Approximation(
                "WrapTorus", wrap.name, f"torus (tube radius {wrap.inner_radius:.4g} m, ring radius "
                f"{wrap.outer_radius:.4g} m) wrapped as the cylinder OpenSim wraps over at the reference pose (of "
                "the tube's radius, on the ring where the path passes nearest it, the path on its side toward the "
                "torus axis); OpenSim moves it with the path, the wrap fit places it", wrap.inner_radius, "m",
                "the cylinder's radius"))
        return torus_cylinder(to_torus.apply(a), to_torus.apply(b), wrap.outer_radius)

    def _check_size(self, wrap: WrapObject) -> None:
        """Raise an error naming the wrap object when a size its MuJoCo geom takes is not positive."""
        sizes = {"sphere": {"radius": wrap.radius}, "cylinder": {"radius": wrap.radius},
                 "ellipsoid": {"dimensions": float(np.min(wrap.dimensions))}}.get(wrap.kind, {})
        for prop, v in sizes.items():
            if not v > 0:
                raise self.b.doc.error(wrap.element, f"has <{prop}> {v:g}: a MuJoCo wrap geom needs a positive size")

    def place(self, path: Path, sites_ground: np.ndarray) -> list[tuple[int, WrapObject]]:
        """Choose, for each wrap of ``path``, the segment (within the wrap's OpenSim range) it acts
        on at the reference pose. MuJoCo wraps one geom per segment, so wraps are assigned closest
        first: a wrap whose closest segment is taken goes to its next closest free one when that
        passes within two of its sizes of it, and is left out (noted) otherwise."""
        n = len(path.points)
        candidates = []  # (distance, wrap order, segment, wrap, size)
        for order, pw in enumerate(path.wraps):
            wrap = self.wraps.get(pw.wrap)
            if wrap is None:
                raise self.b.doc.error(path.element, f"wraps over '{pw.wrap}', which no body defines")
            if not wrap.active:
                continue
            first, last = wrap_segments(pw.range, n)
            centre = (self.b.ground_frames[wrap.body] @ wrap.frame).pos
            size = max(wrap.radius, float(np.max(wrap.dimensions)), wrap.outer_radius)
            for seg in range(first, last + 1):
                d = segment_distance(sites_ground[seg], sites_ground[seg + 1], centre)
                candidates.append((d, order, seg, wrap, size))
        candidates.sort(key=lambda c: (c[0], c[1]))
        best = {}
        for d, order, _, _, _ in candidates:
            best.setdefault(order, d)
        chosen: dict[int, WrapObject] = {}
        placed: set[int] = set()
        for d, order, seg, wrap, size in candidates:
            if order in placed or seg in chosen or d > best[order] + 2.0 * size:
                continue
            chosen[seg] = wrap
            placed.add(order)
        for order, pw in enumerate(path.wraps):
            if order in best and order not in placed:
                self.b.result.notes.append(f"{path.owner}: wrap object '{pw.wrap}' left out (MuJoCo wraps one "
                                           f"geom per path segment and the segments near it are taken)")
        return sorted(chosen.items(), key=lambda t: t[0])

    def side_site(self, wrap: WrapObject, geom: str, a: np.ndarray, b: np.ndarray) -> str:
        """A side site for ``geom`` of a wrap with a quadrant, on the side the quadrant names (for a
        cylinder, at the height along its axis where the segment a-b (ground, reference pose)
        passes closest); "" (none) for a wrap without one: MuJoCo then wraps, as OpenSim does, only
        a straight path that cuts the geom, the shorter way round, where a side site would also
        wrap a path clearing the geom on its far side, and always round the side site's side (a
        pendulum over a sphere: 75 mm too long where the path clears it below,
        tests/convert/test_wrapping.py)."""
        frame, kind, radius = self.geom_frames[geom]
        if wrap.kind == "torus":  # OpenSim wraps its cylinder on its +x side, toward the torus axis
            return self._add_side_site(wrap, geom, frame, np.array([radius * SIDE_SITE_DISTANCE, 0.0, 0.0]))
        if wrap.quadrant in ("all", ""):
            return ""
        x_ground = self.b.ground_frames[wrap.body] @ frame
        local_a, local_b = x_ground.inverse().apply(a), x_ground.inverse().apply(b)
        seg = local_b - local_a
        t = np.clip(-local_a @ seg / max(seg @ seg, 1e-18), 0.0, 1.0)
        closest = local_a + t * seg
        sign = -1.0 if wrap.quadrant.startswith("-") else 1.0
        axis_wrap = sign * np.eye(3)["xyz".index(wrap.quadrant[-1].lower())]  # in the wrap object's frame
        direction = (frame.rot.T @ wrap.frame.rot) @ axis_wrap
        if kind == "cylinder":
            direction = direction * np.array([1.0, 1.0, 0.0])
        if np.linalg.norm(direction) < 1e-12:
            direction = closest * np.array([1.0, 1.0, 0.0]) if kind == "cylinder" else closest.copy()
        if np.linalg.norm(direction) < 1e-12:
            direction = np.array([1.0, 0.0, 0.0])
        direction = direction / np.linalg.norm(direction)
        local = direction * radius * SIDE_SITE_DISTANCE
        if kind == "cylinder":
            local[2] = closest[2]
        return self._add_side_site(wrap, geom, frame, local)

    def _add_side_site(self, wrap: WrapObject, geom: str, frame: Transform, local: np.ndarray) -> str:
        """A side site of ``geom`` at ``local`` in its ``frame`` (in ``wrap``'s body)."""
        pos = self.ctx.in_world(wrap.body, frame).apply(local)
        name = self.ctx.unique(f"{geom}_side")
        self.b.bodies[wrap.body].add_site(name=name, pos=pos, size=[0.001, 0, 0], group=5)
        self.b.exact[("site", name)] = {"pos": pos}
        return name


def torus_cylinder(a: np.ndarray, b: np.ndarray, ring_radius: float, samples: int = 2001) -> Transform:
    """The frame, in a torus's frame (ring about its z axis), of the cylinder OpenSim's WrapTorus
    wraps the line ``a``-``b`` (torus frame, m) over, as WrapTorus::wrapLine builds it: centred on
    the ring (the circle of ``ring_radius`` in z = 0) at its point nearest the line, its x axis
    from there toward the torus axis (OpenSim wraps it on its +x side), its z axis the ring's
    tangent (x cross -z). (OpenSim searches the infinite line; the segment here, sampled.)"""
    t = np.linspace(0.0, 1.0, samples)[:, None]
    pts = a + t * (b - a)
    dist = np.hypot(np.hypot(pts[:, 0], pts[:, 1]) - ring_radius, pts[:, 2])
    nearest = pts[int(np.argmin(dist))]
    radial = np.array([nearest[0], nearest[1], 0.0])
    radial = radial / np.linalg.norm(radial) if np.linalg.norm(radial) > 1e-12 else np.array([1.0, 0.0, 0.0])
    x, y = -radial, np.array([0.0, 0.0, -1.0])
    return Transform(np.column_stack([x, y, np.cross(x, y)]), ring_radius * radial)


def wrap_segments(wrap_range: tuple[int, int], n_points: int) -> tuple[int, int]:
    """The first and last path segment (0-based; segment k joins points k and k+1) that a wrap
    with OpenSim's 1-based point ``range`` (-1: all) may act on, of a path of ``n_points``."""
    lo, hi = wrap_range
    first = 0 if lo < 1 else lo - 1
    last = n_points - 2 if hi < 1 else min(hi - 1, n_points - 1) - 1
    return first, last


def segment_distance(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
    """Distance (m) from point ``c`` to the segment a-b."""
    ab = b - a
    t = np.clip((c - a) @ ab / max(ab @ ab, 1e-18), 0.0, 1.0)
    return float(np.linalg.norm(a + t * ab - c))


def restore_geom_precision(xml: str, exact: dict[tuple[str, str], dict[str, np.ndarray]]) -> str:
    """MJCF text with the listed geoms' attributes written in full (:mod:`o2m.mj.mjcf_text`)."""
    return mjcf_text.restore_numbers(xml, exact, ("geom",))
