"""Building MuJoCo spatial tendons and their actuators from OpenSim paths.

* A PathPoint is a site on its body.
* A MovingPathPoint is a site on a small child body that slides along its body's axes; each
  slide follows its coordinate through a joint equality (exact when the location function is
  linear, else a quartic fit whose worst error the report records).
* A ConditionalPathPoint becomes a small wrap sphere whose outer surface passes through the
  point, with a side site outside it (see :meth:`TendonBuilder.conditional_geom`). MuJoCo 4.0
  wraps a tendon round a geom whenever the straight segment cuts it *or passes on the side
  opposite the side site*, and then goes round on the side-site side; so the tendon is pulled
  through the point exactly while the point lies outside the straight line between its
  neighbours (OpenSim's via point makes the path bend there) and runs straight otherwise. The
  switch is geometric, depends on every coordinate, and leaves the length continuous (OpenSim's
  own length jumps where its coordinate leaves the range; :func:`conditional_jumps` measures by
  how much). Consecutive conditional points between the same two sites keep the one that bends
  the path most (MuJoCo needs a site between two wrap geoms); the report names the others.
* Wrap objects become wrap geoms, one per path that uses them (so :mod:`o2m.wrapfit` can fit
  each path's own): spheres and cylinders as they are; an ellipsoid as the sphere or cylinder
  nearest to it; a torus is left out. Each is placed on the path segment (within the wrap's
  OpenSim range) that passes closest to it at the reference pose, with a side site on the side
  that segment passes or that the quadrant names (MuJoCo 4.0: the tendon wraps the way the
  straight path through the side site goes).
* Each muscle becomes a MuJoCo muscle actuator on its tendon, named as the muscle.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from .mjcf import Approximation, JointRecord, MjcfBuilder
from .paths import MUSCLE_TYPES, Path, PathPoint, WrapObject
from .transforms import OSIM_TO_MJ, Transform, matrix_to_quat

#: A path-point carrier body: mass (kg) and inertia (kg m²) just above what MuJoCo accepts, so the
#: model's mass and centre of mass stay OpenSim's. Armature (kg) on its slides, without adding body
#: mass, keeps a muscle's pull and its force-velocity damping (~1e4 N·s/m) from whipping the
#: carrier about its soft equality: on 16 MoBL-ARMS excitation sets, 1e-6 kg diverged within 3
#: steps and 1e-2 kg diverged in 5 sets, 0.1 kg in none. The inertia a carrier slide adds to its
#: coordinate, armature x (dx/dq)^2, is at most 1.3e-4 kg m^2 in MoBL-ARMS (dx/dq <= 0.037 m/rad).
CARRIER_MASS = 1e-12
CARRIER_INERTIA = 1e-14
CARRIER_ARMATURE = 0.1
#: Distance of a side site from a wrap geom's centre, in radii.
SIDE_SITE_DISTANCE = 2.0
#: Radius (m) of the wrap sphere that stands for a ConditionalPathPoint.
CONDITIONAL_RADIUS = 0.002


@dataclass
class _PlacedWrap:
    segment: int  # the path segment (between points segment and segment+1) it wraps
    geom: str
    sidesite: str


@dataclass
class PathGeom:
    """A wrap geom of one tendon (MuJoCo names), for :mod:`o2m.wrapfit`: ``kind`` is the OpenSim
    element it stands for (``WrapSphere``, ``WrapCylinder``, ``WrapEllipsoid`` or
    ``ConditionalPathPoint``) and ``source`` its OpenSim name."""

    tendon: str
    geom: str
    sidesite: str
    kind: str
    source: str


class TendonBuilder:
    """Adds the paths of a skeleton to an :class:`MjcfBuilder`'s spec."""

    def __init__(self, builder: MjcfBuilder, wraps: dict[str, WrapObject]):
        self.b = builder
        self.spec = builder.spec
        self.wraps = wraps
        self.geoms: dict[str, str | None] = {}  # wrap object -> MuJoCo geom name (None: not converted)
        self.names: set[str] = set()
        #: Exact attribute values of the geoms added here, by ("geom", name) (see :func:`restore_geom_precision`).
        self.exact: dict[tuple[str, str], dict[str, np.ndarray]] = {}
        #: Every wrap geom of every tendon, in the order added.
        self.path_geoms: list[PathGeom] = []
        #: geom name -> (its frame in its OpenSim body, MuJoCo kind, radius)
        self.geom_frames: dict[str, tuple[Transform, str, float]] = {}

    def _unique(self, name: str) -> str:
        out, k = name, 1
        while out in self.names:
            out, k = f"{name}_{k}", k + 1
        self.names.add(out)
        return out

    def _in_world(self, body: str, x: Transform) -> Transform:
        """Frame ``x`` of ``body`` as MuJoCo places it in the body (ground: mapped to Z-up)."""
        return Transform(OSIM_TO_MJ) @ x if body == "ground" else x

    # -- points --------------------------------------------------------------------------
    def location_at(self, point: PathPoint, values: dict[str, float]) -> np.ndarray:
        """Location (3,) of ``point`` in its body frame when the coordinates have ``values``."""
        loc = point.location.copy()
        for i, (cname, fn) in point.moving.items():
            ref = float(fn(np.array([self.b.ref[cname]]))[0])
            loc[i] += float(fn(np.array([values[cname]]))[0]) - ref
        return loc

    def _active(self, point: PathPoint, values: dict[str, float]) -> bool:
        if point.condition is None:
            return True
        cname, lo, hi = point.condition
        return lo <= values[cname] <= hi

    def _reference_active_values(self, point: PathPoint) -> dict[str, float]:
        """Coordinate values at the reference pose, with a conditional point's coordinate moved
        into the point's active range when it is outside it (to the middle of the part of that
        range inside the coordinate's range)."""
        cname, lo, hi = point.condition
        if lo <= self.b.ref[cname] <= hi:
            return self.b.coordinate_values()
        base = self.b.drivers[cname].base
        kind = self.b.coord_joint[base][1].kind if base in self.b.coord_joint else "rotation"
        rlo, rhi = self.b.fit_range(base, kind)
        a, b = max(lo, rlo), min(hi, rhi)
        return self.b.coordinate_values({base: 0.5 * (a + b) if a <= b else 0.5 * (lo + hi)})

    def _bend(self, path: Path, k: int, values: dict[str, float], keep: list[bool]) -> tuple[np.ndarray, float]:
        """Unit direction (ground) from the straight segment between the kept neighbours of point
        ``k`` to the point, and the length (m) the point adds to the path, in pose ``values``."""
        pts = path.points
        frames = self.b.ground_frames_at(values)

        def world(p: PathPoint) -> np.ndarray:
            return frames[p.body].apply(self.location_at(p, values))

        before = next(p for p, kp in zip(pts[k - 1::-1], keep[k - 1::-1], strict=True) if kp)
        after = next(p for p, kp in zip(pts[k + 1:], keep[k + 1:], strict=True) if kp)
        a, p, c = world(before), world(pts[k]), world(after)
        ac = c - a
        t = float(np.clip((p - a) @ ac / max(ac @ ac, 1e-18), 0.0, 1.0))
        off = p - (a + t * ac)
        detour = float(np.linalg.norm(p - a) + np.linalg.norm(c - p) - np.linalg.norm(ac))
        n = float(np.linalg.norm(off))
        if n < 1e-9:  # on the straight line: any direction perpendicular to it
            helper = np.eye(3)[int(np.argmin(np.abs(ac)))]
            off = np.cross(ac, helper)
            n = float(np.linalg.norm(off))
        return off / n, detour

    def conditional_roles(self, path: Path) -> list[str]:
        """For each point of ``path``: ``"site"`` (always on the path), ``"conditional"`` (a
        ConditionalPathPoint made a wrap sphere) or ``"dropped"`` (a conditional point left out:
        its coordinate is locked outside its range, or it is not the one of a run of consecutive
        conditional points that bends the path most). First and last points stay sites."""
        pts = path.points
        roles = []
        for i, p in enumerate(pts):
            if p.condition is None or i in (0, len(pts) - 1):
                if p.condition is not None:
                    self.b.result.notes.append(f"{path.owner}: ConditionalPathPoint '{p.name}' ends the path; "
                                               f"kept always active")
                roles.append("site")
            elif self._fixed(p.condition[0]):
                roles.append("site" if self._active(p, self.b.coordinate_values()) else "dropped")
            else:
                roles.append("conditional")
        i = 0
        while i < len(pts):
            if roles[i] != "conditional":
                i += 1
                continue
            j = i
            while j + 1 < len(pts) and roles[j + 1] == "conditional":
                j += 1
            if j > i:  # a run: keep the point that bends the path most when it is active
                keep = [r == "site" for r in roles]
                bends = []
                for k in range(i, j + 1):
                    _, detour = self._bend(path, k, self._reference_active_values(pts[k]), keep)
                    bends.append(detour)
                best = i + int(np.argmax(bends))
                for k in range(i, j + 1):
                    if k != best:
                        roles[k] = "dropped"
                        self.b.result.notes.append(
                            f"{path.owner}: ConditionalPathPoint '{pts[k].name}' left out (it follows or precedes "
                            f"another conditional point, and MuJoCo needs a site between two wrap geoms; "
                            f"'{pts[best].name}' kept)")
            i = j + 1
        return roles

    def conditional_geom(self, path: Path, k: int, roles: list[str]) -> tuple[str, str]:
        """The wrap sphere (and its side site) standing for ConditionalPathPoint ``k`` of ``path``.

        The sphere, of radius :data:`CONDITIONAL_RADIUS`, lies just inside the point on the side
        of the straight segment between its neighbouring sites, found at the reference pose (its
        coordinate moved into its range if needed), so its outer surface passes through the
        point; the side site sits outside it on that side. The tendon is pulled over the sphere
        (through the point) while the point lies outside the straight line, and runs straight
        when the line passes outside the point."""
        point = path.points[k]
        values = self._reference_active_values(point)
        n_ground, _ = self._bend(path, k, values, [r == "site" for r in roles])
        frames = self.b.ground_frames_at(values)
        n_body = frames[point.body].rot.T @ n_ground
        r = CONDITIONAL_RADIUS
        centre = point.location - r * n_body
        side = centre + SIDE_SITE_DISTANCE * r * n_body
        cname, lo, hi = point.condition
        gname = self._unique(f"{path.owner}-{point.name}_cond" if not point.name.startswith(path.owner)
                             else f"{point.name}_cond")
        pos = self._in_world(point.body, Transform(pos=centre)).pos
        self.b.bodies[point.body].add_geom(name=gname, type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[r, 0, 0], pos=pos,
                                           contype=0, conaffinity=0, group=3, density=0, rgba=[0.9, 0.6, 0.2, 0.5])
        self.exact[("geom", gname)] = {"pos": pos, "size": np.array([r])}
        sname = self._unique(f"{gname}_side")
        spos = self._in_world(point.body, Transform(pos=side)).pos
        self.b.bodies[point.body].add_site(name=sname, pos=spos, size=[0.001, 0, 0], group=5)
        self.b.exact[("site", sname)] = {"pos": spos}
        self.b.result.notes.append(
            f"{path.owner}: ConditionalPathPoint '{point.name}' (active for '{cname}' in [{lo:g}, {hi:g}]) is a "
            f"wrap sphere of radius {r:g} m at the point: the tendon passes through it while it lies outside the "
            f"straight line between its neighbours")
        self.path_geoms.append(PathGeom(path.owner, gname, sname, "ConditionalPathPoint", point.name))
        return gname, sname

    def add_point(self, path: Path, point: PathPoint) -> str:
        """Add the site of ``point`` (a path point, a moving point, or a conditional point kept
        always on the path); returns its name."""
        name = self._unique(point.name if point.name.startswith(path.owner) else f"{path.owner}-{point.name}")
        moving = {i: m for i, m in point.moving.items() if not self._fixed(m[0])}
        loc0 = point.location.copy()  # the location at the reference pose, in the body frame
        pos = self._in_world(point.body, Transform(pos=loc0)).pos
        if not moving:
            self.b.bodies[point.body].add_site(name=name, pos=pos, size=[0.002, 0, 0], group=3)
            self.b.exact[("site", name)] = {"pos": pos}
            return name
        body = self.b.bodies[point.body].add_body(name=self._unique(f"{name}_carrier"), pos=pos)
        self.b.exact[("body", body.name)] = {"pos": pos, "quat": np.array([1.0, 0, 0, 0])}
        body.explicitinertial = True
        body.mass = CARRIER_MASS
        body.fullinertia = [CARRIER_INERTIA, CARRIER_INERTIA, CARRIER_INERTIA, 0, 0, 0]
        self.b.exact[("inertial", body.name)] = {"pos": np.zeros(3), "mass": CARRIER_MASS,
                                                 "fullinertia": np.array(body.fullinertia)}
        for i, (cname, fn) in moving.items():
            axis = np.zeros(3)
            axis[i] = 1.0
            axis = self._in_world(point.body, Transform(pos=axis)).pos
            ref = float(loc0[i])
            jname = self._unique(f"{name}_{'xyz'[i]}")
            body.add_joint(name=jname, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis, ref=ref,
                           armature=CARRIER_ARMATURE)
            self.b.exact[("joint", jname)] = {"axis": axis, "pos": np.zeros(3), "ref": ref}
            rec = JointRecord(jname, "slide", path.owner, f"{point.name}/{'xyz'[i]}", None, None, "coordinate")
            offset = ref - float(fn(np.array([self.b.ref[cname]]))[0])  # the frame offset of the point
            driver = self.b.drivers[cname].then(lambda x, fn=fn, offset=offset: fn(x) + offset)
            self.b.couple(rec, driver, ref, point.element)
            self.b.result.joints.append(rec)
        body.add_site(name=name, pos=[0, 0, 0], size=[0.002, 0, 0], group=3)
        return name

    def _fixed(self, coordinate: str) -> bool:
        return self.b.skel.coordinates[self.b.drivers[coordinate].base].locked

    # -- wraps ---------------------------------------------------------------------------
    def wrap_geom(self, wrap: WrapObject) -> str | None:
        """A new MuJoCo geom for a wrap object (each path gets its own, so fitting one path's wrap
        leaves the others alone), or None when it has no MuJoCo twin (a torus)."""
        if self.geoms.get(wrap.name, "") is None:
            return None
        first_use = wrap.name not in self.geoms
        x = self._in_world(wrap.body, wrap.frame)
        kind, size, extra_rot = wrap.kind, None, np.eye(3)
        if kind == "sphere":
            size = [wrap.radius, 0, 0]
        elif kind == "cylinder":
            size = [wrap.radius, max(wrap.length, 1e-6) / 2, 0]
        elif kind == "ellipsoid":
            d = np.asarray(wrap.dimensions, dtype=float)
            order = np.argsort(d)
            if d[order[2]] > 1.5 * d[order[1]]:  # elongated: a cylinder along its long axis
                kind, r = "cylinder", float((d[order[0]] + d[order[1]]) / 2)
                size = [r, float(d[order[2]]), 0]
                long_axis = np.eye(3)[order[2]]
                extra_rot = _rotation_taking_z_to(long_axis)
                what = f"ellipsoid {d.tolist()} wrapped as a cylinder of radius {r:.4g} m"
                err = float(np.max(np.abs(d[order[:2]] - r)))
            else:
                kind, r = "sphere", float(d.mean())
                size = [r, 0, 0]
                what = f"ellipsoid {d.tolist()} wrapped as a sphere of radius {r:.4g} m"
                err = float(np.max(np.abs(d - r)))
            if first_use:
                self.b.result.approximations.append(Approximation("WrapEllipsoid", wrap.name, what, err, "m",
                                                                  "largest semi-axis difference"))
        else:
            self.b.result.notes.append(f"WrapTorus '{wrap.name}' is not converted (MuJoCo cannot wrap a torus)")
            self.geoms[wrap.name] = None
            return None
        x = x @ Transform(extra_rot)
        name = self._unique(f"wrap_{wrap.name}")
        gtype = mujoco.mjtGeom.mjGEOM_SPHERE if kind == "sphere" else mujoco.mjtGeom.mjGEOM_CYLINDER
        quat = matrix_to_quat(x.rot)
        self.b.bodies[wrap.body].add_geom(name=name, type=gtype, size=size, pos=x.pos, quat=quat,
                                          contype=0, conaffinity=0, group=3, density=0, rgba=[0.3, 0.7, 0.9, 0.4])
        self.exact[("geom", name)] = {"pos": x.pos, "quat": np.asarray(quat, dtype=float),
                                      "size": np.asarray(size[:2] if kind == "cylinder" else size[:1], dtype=float)}
        self.geoms[wrap.name] = name
        self.geom_frames[name] = (wrap.frame @ Transform(extra_rot), kind, float(size[0]))
        return name

    def place_wraps(self, path: Path, sites_ground: np.ndarray) -> list[tuple[int, WrapObject]]:
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
            lo, hi = pw.range
            first = 0 if lo < 1 else lo - 1
            last = n - 2 if hi < 1 else min(hi - 1, n - 1) - 1
            centre = (self.b.ground_frames[wrap.body] @ wrap.frame).pos
            size = max(wrap.radius, float(np.max(wrap.dimensions)), wrap.outer_radius)
            for seg in range(first, last + 1):
                d = _segment_distance(sites_ground[seg], sites_ground[seg + 1], centre)
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
        """A side site for ``geom``, on the side the segment a-b (ground, reference pose) passes,
        or, for a wrap with a quadrant, on the side the quadrant names (for a cylinder, at the
        height along its axis where that segment passes closest)."""
        frame, kind, radius = self.geom_frames[geom]
        x_ground = self.b.ground_frames[wrap.body] @ frame
        local_a, local_b = x_ground.inverse().apply(a), x_ground.inverse().apply(b)
        seg = local_b - local_a
        t = np.clip(-local_a @ seg / max(seg @ seg, 1e-18), 0.0, 1.0)
        closest = local_a + t * seg
        if wrap.quadrant not in ("all", ""):
            sign = -1.0 if wrap.quadrant.startswith("-") else 1.0
            axis_wrap = sign * np.eye(3)["xyz".index(wrap.quadrant[-1].lower())]  # in the wrap object's frame
            direction = (frame.rot.T @ wrap.frame.rot) @ axis_wrap
        else:
            direction = closest.copy()
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
        pos = self._in_world(wrap.body, frame).apply(local)
        name = self._unique(f"{geom}_side")
        self.b.bodies[wrap.body].add_site(name=name, pos=pos, size=[0.001, 0, 0], group=5)
        self.b.exact[("site", name)] = {"pos": pos}
        return name

    # -- tendons and actuators -----------------------------------------------------------
    def add_path(self, path: Path) -> None:
        roles = self.conditional_roles(path)
        sites: list[str] = []
        site_of_point: list[int] = []  # for each point, the index of the last site at or before it
        for p, role in zip(path.points, roles, strict=True):
            if role == "site":
                sites.append(self.add_point(path, p))
            site_of_point.append(len(sites) - 1)
        on_segment: dict[int, tuple[str, str]] = {}  # site segment -> (geom, side site)
        for k, role in enumerate(roles):
            if role == "conditional":
                on_segment[site_of_point[k]] = self.conditional_geom(path, k, roles)
        sites_ground = np.array([(self.b.ground_frames[p.body] @ Transform(pos=p.location)).pos for p in path.points])
        for seg, wrap in self.place_wraps(path, sites_ground):
            sseg = site_of_point[seg]
            if sseg in on_segment:
                self.b.result.notes.append(f"{path.owner}: wrap object '{wrap.name}' left out (its path segment "
                                           f"already wraps '{on_segment[sseg][0]}'; MuJoCo wraps one geom there)")
                continue
            geom = self.wrap_geom(wrap)
            if geom is None:
                continue
            side = self.side_site(wrap, geom, sites_ground[seg], sites_ground[seg + 1])
            on_segment[sseg] = (geom, side)
            self.path_geoms.append(PathGeom(path.owner, geom, side, "Wrap" + wrap.kind.capitalize(), wrap.name))
        tendon = self.spec.add_tendon(name=path.owner)
        for i, site in enumerate(sites):
            tendon.wrap_site(site)
            if i in on_segment and i + 1 < len(sites):
                tendon.wrap_geom(*on_segment[i])
        if path.owner_type in MUSCLE_TYPES:
            act = self.spec.add_actuator(name=path.owner, trntype=mujoco.mjtTrn.mjTRN_TENDON, target=path.owner)
            fmax = float(path.element.findtext("max_isometric_force") or 1000.0)
            act.set_to_muscle(timeconst=[0.01, 0.04], tausmooth=0.0, force=fmax)
        elif path.owner_type != "Ligament":  # a ligament's spring is added by o2m.forces
            self.b.result.notes.append(f"{path.owner_type} '{path.owner}': tendon only (no actuator yet)")


def _segment_distance(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
    ab = b - a
    t = np.clip((c - a) @ ab / max(ab @ ab, 1e-18), 0.0, 1.0)
    return float(np.linalg.norm(a + t * ab - c))


def _rotation_taking_z_to(axis: np.ndarray) -> np.ndarray:
    """A rotation matrix (3, 3) whose third column is the unit vector ``axis``."""
    z = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def add_paths(builder: MjcfBuilder, paths: list[Path], wraps: dict[str, WrapObject]) -> TendonBuilder:
    """Add every path (tendon, sites, wrap geoms, actuator) to ``builder``'s spec; returns the
    :class:`TendonBuilder` (its ``path_geoms`` and ``exact`` geom values)."""
    tb = TendonBuilder(builder, wraps)
    for path in paths:
        tb.add_path(path)
    return tb


def restore_geom_precision(xml: str, exact: dict[tuple[str, str], dict[str, np.ndarray]]) -> str:
    """MJCF text with the listed geoms' attributes written in full (17 significant digits)."""
    from lxml import etree

    root = etree.fromstring(xml.encode())
    for el in root.iter("geom"):
        vals = exact.get(("geom", el.get("name")))
        if vals is None:
            continue
        for attr, v in vals.items():
            el.set(attr, " ".join(f"{float(x):.17g}" for x in np.atleast_1d(np.asarray(v, dtype=float))))
    return etree.tostring(root, encoding="unicode", pretty_print=True)


def tendon_length_ranges(model: mujoco.MjModel, coordinates: dict[str, tuple[float, float]], *,
                         n_poses: int = 500, seed: int = 0) -> np.ndarray:
    """(ntendon, 2) smallest and largest tendon lengths (m) over random poses.

    ``coordinates`` maps each independent coordinate joint to the range it is sampled in; every
    other joint follows the model's equalities. The default pose and the range corners of one
    coordinate at a time are included, so extremes at the limits are not missed.
    """
    from .validate import joint_equality_plan, pose_mujoco

    data = mujoco.MjData(model)
    plan = joint_equality_plan(model)
    rng = np.random.default_rng(seed)
    names = list(coordinates)
    lo = np.array([coordinates[n][0] for n in names])
    hi = np.array([coordinates[n][1] for n in names])
    defaults = np.array([model.qpos0[model.joint(n).qposadr[0]] for n in names])
    poses = [defaults] + [np.where(np.arange(len(names)) == i, v, defaults)
                          for i in range(len(names)) for v in (lo[i], hi[i])]
    poses += list(rng.uniform(lo, hi, size=(n_poses, len(names))))
    out = np.full((model.ntendon, 2), [np.inf, -np.inf])
    for q in poses:
        pose_mujoco(model, data, dict(zip(names, q, strict=True)), plan=plan)
        mujoco.mj_tendon(model, data)
        out[:, 0] = np.minimum(out[:, 0], data.ten_length)
        out[:, 1] = np.maximum(out[:, 1], data.ten_length)
    return out
