"""Building MuJoCo spatial tendons and their actuators from OpenSim paths.

* A PathPoint is a site on its body.
* A MovingPathPoint is a site on a small child body that slides along its body's axes; each
  slide follows its coordinate through a joint equality (exact when the location function is
  linear, else a quartic fit whose worst error the report records).
* A ConditionalPathPoint is approximated as always active (MuJoCo sites cannot switch); the
  report names it, and :mod:`o2m.validate_muscles` measures the length error this leaves.
* Wrap objects become wrap geoms: spheres and cylinders as they are; an ellipsoid as the sphere
  or cylinder nearest to it; a torus is left out. Each is placed on the path segment that
  passes closest to it at the reference pose, with a side site on the side that segment passes
  (MuJoCo 4.0: the tendon wraps the way the straight line through the side site goes).
* Each muscle becomes a MuJoCo muscle actuator on its tendon, named as the muscle.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from .mjcf import Approximation, JointRecord, MjcfBuilder
from .paths import MUSCLE_TYPES, Path, PathPoint, WrapObject
from .skeleton import Skipped
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


@dataclass
class _PlacedWrap:
    segment: int  # the path segment (between points segment and segment+1) it wraps
    geom: str
    sidesite: str


class TendonBuilder:
    """Adds the paths of a skeleton to an :class:`MjcfBuilder`'s spec."""

    def __init__(self, builder: MjcfBuilder, wraps: dict[str, WrapObject]):
        self.b = builder
        self.spec = builder.spec
        self.wraps = wraps
        self.geoms: dict[str, str | None] = {}  # wrap object -> MuJoCo geom name (None: not converted)
        self.names: set[str] = set()

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

    def conditional_motion(self, point: PathPoint, points: list[PathPoint]) -> dict[int, tuple]:
        """Location functions that reproduce a ConditionalPathPoint's switching.

        Inside its range the point stays where it is; outside, it moves to the closest point of
        the straight segment between the nearest points before and after it that are active
        then, where it leaves the path length unchanged. Tabulated over the coordinate's range
        with the other coordinates at the reference pose."""
        cname, lo, hi = point.condition
        kind = self.b.coord_joint[cname][1].kind if cname in self.b.coord_joint else "rotation"
        flo, fhi = self.b.fit_range(cname, kind)
        grid = np.linspace(min(flo, lo), max(fhi, hi), 241)
        k0 = points.index(point)
        table = np.empty((grid.size, 3))
        for k, q in enumerate(grid):
            if lo <= q <= hi:
                table[k] = point.location
                continue
            values = self.b.coordinate_values({cname: q})

            on = [p.condition is None or p.condition[1] <= values[p.condition[0]] <= p.condition[2] for p in points]
            before = next((p for p, a in zip(points[k0 - 1::-1], on[k0 - 1::-1], strict=True) if a), None) \
                if k0 > 0 else None
            after = next((p for p, a in zip(points[k0 + 1:], on[k0 + 1:], strict=True) if a), None)
            if before is None or after is None:
                raise self.b.doc.error(point.element, "is a ConditionalPathPoint with no active point on one side")
            frames = self.b.ground_frames_at(values)

            def world(p: PathPoint) -> np.ndarray:
                return frames[p.body].apply(self.location_at(p, values))  # noqa: B023

            a, c = world(before), world(after)
            ab = c - a
            # inactive points between the same two active ones keep their order along the segment
            t = 0.0
            for p in points[points.index(before) + 1:k0 + 1]:
                t = max(t, float(np.clip((world(p) - a) @ ab / max(ab @ ab, 1e-18), 0.0, 1.0)))
            table[k] = frames[point.body].inverse().apply(a + t * ab)
        return {i: (cname, lambda x, i=i: np.interp(x, grid, table[:, i]))
                for i in range(3) if np.ptp(table[:, i]) > 1e-9}

    def add_point(self, path: Path, point: PathPoint) -> str:
        """Add the site of ``point``; returns its name."""
        name = self._unique(point.name if point.name.startswith(path.owner) else f"{path.owner}-{point.name}")
        moving = {i: m for i, m in point.moving.items() if not self._fixed(m[0])}
        if point.condition is not None and not self._fixed(point.condition[0]):
            moving = self.conditional_motion(point, path.points)
            self.b.result.notes.append(
                f"ConditionalPathPoint '{point.name}' moves onto the segment between its neighbours outside "
                f"[{point.condition[1]:g}, {point.condition[2]:g}] of '{point.condition[0]}'")
        loc0 = point.location.copy()  # the location at the reference pose, in the body frame
        if point.condition is not None:
            for i, (cname, fn) in moving.items():
                loc0[i] = float(fn(np.array([self.b.ref[cname]]))[0])
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
        """The MuJoCo geom of a wrap object (added once), or None when it has no MuJoCo twin."""
        if wrap.name in self.geoms:
            return self.geoms[wrap.name]
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
            self.b.result.approximations.append(Approximation("WrapEllipsoid", wrap.name, what, err, "m",
                                                              "largest semi-axis difference"))
        else:
            self.b.result.notes.append(f"WrapTorus '{wrap.name}' is not converted (MuJoCo cannot wrap a torus)")
            self.geoms[wrap.name] = None
            return None
        x = x @ Transform(extra_rot)
        name = self._unique(f"wrap_{wrap.name}")
        gtype = mujoco.mjtGeom.mjGEOM_SPHERE if kind == "sphere" else mujoco.mjtGeom.mjGEOM_CYLINDER
        self.b.bodies[wrap.body].add_geom(name=name, type=gtype, size=size, pos=x.pos, quat=matrix_to_quat(x.rot),
                                          contype=0, conaffinity=0, group=3, density=0, rgba=[0.3, 0.7, 0.9, 0.4])
        self.geoms[wrap.name] = name
        return name

    def place_wraps(self, path: Path, sites_ground: np.ndarray) -> list[tuple[int, WrapObject]]:
        """Choose, for each wrap of ``path``, the segment it acts on (closest at the reference pose)."""
        chosen: dict[int, tuple[float, WrapObject]] = {}
        n = len(path.points)
        for pw in path.wraps:
            wrap = self.wraps.get(pw.wrap)
            if wrap is None:
                raise self.b.doc.error(path.element, f"wraps over '{pw.wrap}', which no body defines")
            if not wrap.active:
                continue
            lo, hi = pw.range
            first = 0 if lo < 1 else lo - 1
            last = n - 2 if hi < 1 else min(hi - 1, n - 1) - 1
            centre = (self.b.ground_frames[wrap.body] @ wrap.frame).pos
            best = None
            for seg in range(first, last + 1):
                d = _segment_distance(sites_ground[seg], sites_ground[seg + 1], centre)
                if best is None or d < best[0]:
                    best = (d, seg)
            if best is None:
                continue
            d, seg = best
            if seg in chosen:  # MuJoCo wraps one geom per segment: keep the closer one
                keep, drop = (chosen[seg][1], wrap) if chosen[seg][0] <= d else (wrap, chosen[seg][1])
                self.b.result.notes.append(f"{path.owner}: wrap object '{drop.name}' left out (MuJoCo wraps one "
                                           f"object per path segment; '{keep.name}' kept)")
                if keep is chosen[seg][1]:
                    continue
            chosen[seg] = (d, wrap)
        return sorted(((seg, w) for seg, (_, w) in chosen.items()), key=lambda t: t[0])

    def side_site(self, wrap: WrapObject, geom: str, a: np.ndarray, b: np.ndarray) -> str:
        """A side site for ``geom``, on the side the segment a-b (ground, reference pose) passes."""
        x_ground = self.b.ground_frames[wrap.body] @ wrap.frame
        local_a, local_b = x_ground.inverse().apply(a), x_ground.inverse().apply(b)
        seg = local_b - local_a
        t = np.clip(-local_a @ seg / max(seg @ seg, 1e-18), 0.0, 1.0)
        closest = local_a + t * seg
        if wrap.quadrant not in ("all", ""):
            sign = -1.0 if wrap.quadrant.startswith("-") else 1.0
            direction = sign * np.eye(3)["xyz".index(wrap.quadrant[-1].lower())]
        else:
            direction = closest
        if wrap.kind == "cylinder":
            direction = direction * np.array([1.0, 1.0, 0.0])
        if np.linalg.norm(direction) < 1e-12:
            direction = np.array([1.0, 0.0, 0.0])
        direction = direction / np.linalg.norm(direction)
        radius = wrap.radius if wrap.kind in ("sphere", "cylinder") else float(np.max(wrap.dimensions))
        local = direction * radius * SIDE_SITE_DISTANCE
        if wrap.kind == "cylinder":
            local[2] = closest[2]
        pos = self._in_world(wrap.body, wrap.frame).apply(local)
        name = self._unique(f"{geom}_side")
        self.b.bodies[wrap.body].add_site(name=name, pos=pos, size=[0.001, 0, 0], group=5)
        self.b.exact[("site", name)] = {"pos": pos}
        return name

    # -- tendons and actuators -----------------------------------------------------------
    def add_path(self, path: Path) -> None:
        sites = [self.add_point(path, p) for p in path.points]
        sites_ground = np.array([(self.b.ground_frames[p.body] @ Transform(pos=p.location)).pos for p in path.points])
        placed = []
        for seg, wrap in self.place_wraps(path, sites_ground):
            geom = self.wrap_geom(wrap)
            if geom is None:
                continue
            placed.append(_PlacedWrap(seg, geom, self.side_site(wrap, geom, sites_ground[seg], sites_ground[seg + 1])))
        tendon = self.spec.add_tendon(name=path.owner)
        by_seg = {p.segment: p for p in placed}
        for i, site in enumerate(sites):
            tendon.wrap_site(site)
            if i in by_seg:
                tendon.wrap_geom(by_seg[i].geom, by_seg[i].sidesite)
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


def add_paths(builder: MjcfBuilder, paths: list[Path], wraps: dict[str, WrapObject]) -> list[Skipped]:
    """Add every path (tendon, sites, wrap geoms, actuator) to ``builder``'s spec."""
    tb = TendonBuilder(builder, wraps)
    for path in paths:
        tb.add_path(path)
    return []


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
