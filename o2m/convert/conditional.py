"""ConditionalPathPoints: a small wrap sphere on the point, with a side site that leaves it where
OpenSim has the point off.

A ConditionalPathPoint becomes a small wrap sphere (radius :data:`CONDITIONAL_RADIUS`, metres)
whose surface passes through the point, with a side site on a carrier that slides out of it as
the point's coordinate (radians or metres) leaves the point's range (see
:func:`conditional_geom`). MuJoCo 4.0 wraps a tendon round a geom whenever the straight segment
cuts it *or passes on the side opposite the side site*, and then goes round on the side-site
side; so the tendon is pulled through the point exactly while the point lies outside the
straight line between its neighbours (OpenSim's via point makes the path bend there) and runs
straight otherwise. The switch is geometric, depends on every coordinate, and leaves the length
continuous (OpenSim's own length jumps where its coordinate leaves the range; the README gives by
how much). Consecutive conditional points between the same two sites keep the one that bends the
path most (MuJoCo needs a site between two wrap geoms); the report names the others.
"""

from __future__ import annotations

import mujoco
import numpy as np

from o2m.convert.carriers import CARRIER_ARMATURE, Carriers
from o2m.convert.pathpoints import PathContext
from o2m.convert.records import JointRecord
from o2m.osim.paths import Path, PathPoint
from o2m.transforms import Transform

#: Radius (m) of the wrap sphere that stands for a ConditionalPathPoint: the tendon passes within
#: this of the point (exactly through it when it bends as at the reference pose).
CONDITIONAL_RADIUS = 0.001
#: A ConditionalPathPoint whose range is no wider than this (rad or m) is active at one value of its
#: coordinate at most: it is left out (the switch of :func:`conditional_geom` needs a range to fit).
MIN_RANGE_WIDTH = 1e-9


def conditional_roles(ctx: PathContext, path: Path) -> list[str]:
    """For each point of ``path``: ``"site"`` (always on the path), ``"conditional"`` (a
    ConditionalPathPoint made a wrap cylinder) or ``"dropped"`` (a conditional point left out:
    its coordinate is locked outside its range, its range has no width (:data:`MIN_RANGE_WIDTH`),
    or it is not the one of a run of consecutive conditional points that bends the path most).
    First and last points stay sites."""
    pts = path.points
    roles = []
    for i, p in enumerate(pts):
        if p.condition is None or i in (0, len(pts) - 1):
            if p.condition is not None:
                ctx.b.result.notes.append(f"{path.owner}: ConditionalPathPoint '{p.name}' ends the path; "
                                          f"kept always active")
            roles.append("site")
        elif ctx.fixed(p.condition[0]):
            roles.append("site" if ctx.active(p, ctx.b.coordinate_values()) else "dropped")
        elif p.condition[2] - p.condition[1] <= MIN_RANGE_WIDTH:
            roles.append("dropped")
            ctx.b.result.notes.append(
                f"{path.owner}: ConditionalPathPoint '{p.name}' left out: its range [{p.condition[1]:g}, "
                f"{p.condition[2]:g}] of '{p.condition[0]}' has no width, so OpenSim's path has it at that one "
                f"value only" + (" (the reference pose is there)" if ctx.active(p, ctx.b.coordinate_values()) else ""))
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
        if j > i:  # a run: keep the point whose path alone (points joined straight) is nearest OpenSim's
            errs = []
            for k in range(i, j + 1):
                drop = set(range(i, j + 1)) - {k}
                errs.append(max(abs(ctx.straight_length(path, n, drop) / ctx.straight_length(path, n) - 1.0)
                                for n in range(len(ctx.pose_samples()))))
            best = i + int(np.argmin(errs))
            for k in range(i, j + 1):
                if k != best:
                    roles[k] = "dropped"
                    ctx.b.result.notes.append(
                        f"{path.owner}: ConditionalPathPoint '{pts[k].name}' left out (it follows or precedes "
                        f"another conditional point, and MuJoCo needs a site between two wrap geoms; "
                        f"'{pts[best].name}' kept: the straight path without the others is within "
                        f"{100 * min(errs):.2g} % of OpenSim's over the sampled poses)")
        i = j + 1
    return roles


def conditional_geom(ctx: PathContext, carriers: Carriers, path: Path, k: int, roles: list[str]) -> tuple[str, str]:
    """The wrap sphere (and its side site) standing for ConditionalPathPoint ``k`` of ``path``.

    MuJoCo wraps a tendon round a sphere whose side site is *inside* it by making it touch
    the sphere (``wrap_inside``): the tendon passes within the radius
    (:data:`CONDITIONAL_RADIUS`) of the centre from whichever side, as OpenSim's path passes
    through an active point, or runs straight when the straight segment already crosses the
    sphere. The centre is one radius beyond the point, away from the straight segment between
    its neighbouring sites at the reference pose, so the tendon goes through the point when
    it bends as there. The side site sits on a carrier body that slides along ``u`` as a
    quadratic of the point's coordinate (a joint equality, exact): inside the sphere while
    the coordinate is in the point's range, on its surface at the range's ends and outside
    beyond them, where MuJoCo's ordinary rule applies (no wrap while the straight segment
    passes on the side-site side). ``u`` is the direction that leaves unwrapped the most of
    the sampled poses where OpenSim has the point inactive (each weighted by the length the
    point would add). So the tendon switches where OpenSim does, by OpenSim's own step. A
    range end at the coordinate's limit is no switch (a default pose there would otherwise
    sit on the step)."""
    point = path.points[k]
    cname, lo, hi = point.condition
    r = CONDITIONAL_RADIUS
    values = _reference_active_values(ctx, point)
    n_ground, _, _ = _bend(ctx, path, k, values, [q == "site" for q in roles])
    n_body = ctx.b.ground_frames_at(values)[point.body].rot.T @ n_ground
    # the tendon touches the sphere on the straight segment's side: through the point when it bends as here
    centre = np.asarray(point.location, dtype=float) + r * n_body
    u = _off_direction(ctx, path, k, roles, centre)
    gname = ctx.unique(f"{path.owner}-{point.name}_cond" if not point.name.startswith(path.owner)
                       else f"{point.name}_cond")
    pos = ctx.in_world(point.body, Transform(pos=centre)).pos
    ctx.b.bodies[point.body].add_geom(name=gname, type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[r, 0, 0], pos=pos,
                                      contype=0, conaffinity=0, group=3, density=0, rgba=[0.9, 0.6, 0.2, 0.5])
    ctx.exact[("geom", gname)] = {"pos": pos, "size": np.array([r])}
    base = ctx.b.drivers[cname].base
    kind = ctx.b.coord_joint[base][1].kind if base in ctx.b.coord_joint else "rotation"
    clo, chi = ctx.b.fit_range(base, kind)
    slo, shi = lo, hi  # where the switch is
    if base == cname:  # a range end at (or beyond) the coordinate's limit never switches there
        tol = 1e-6 * max(1.0, chi - clo)
        slo = lo - (hi - lo) if lo <= clo + tol else lo
        shi = hi + (hi - lo) if hi >= chi - tol else hi
    half = 0.5 * (shi - slo)
    mid = 0.5 * (shi + slo)

    def slide(x, r=r, mid=mid, half=half):  # r at slo and shi, 0 between them, beyond r outside
        return r * ((np.asarray(x, dtype=float) - mid) / half) ** 2

    ref = float(slide(ctx.b.ref[cname]))
    pos = ctx.in_world(point.body, Transform(pos=centre + ref * u)).pos  # the side site at slide(q) along u
    body = carriers.body(point.body, f"{gname}_carrier", pos)
    axis = ctx.in_world(point.body, Transform(pos=u)).pos if point.body == "ground" else u
    jname = ctx.unique(f"{gname}_switch")
    body.add_joint(name=jname, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis, ref=ref, armature=CARRIER_ARMATURE)
    ctx.b.exact[("joint", jname)] = {"axis": np.asarray(axis, dtype=float), "pos": np.zeros(3), "ref": ref}
    rec = JointRecord(jname, "slide", path.owner, f"{point.name}/switch", None, None, "coordinate")
    ctx.b.couple(rec, ctx.b.drivers[cname].then(slide), ref, point.element)
    ctx.b.result.joints.append(rec)
    sname = ctx.unique(f"{gname}_side")
    body.add_site(name=sname, pos=[0, 0, 0], size=[0.001, 0, 0], group=5)
    ctx.b.result.notes.append(
        f"{path.owner}: ConditionalPathPoint '{point.name}' (active for '{cname}' in [{lo:g}, {hi:g}]) is a "
        f"wrap sphere of radius {r:g} m on the point whose side site '{cname}' moves out of it beyond the range")
    # not fitted (o2m.wrapfit): it is OpenSim's point to within its radius, and moving it can put the
    # straight path through it where OpenSim has the point off (Leg6Dof9Musc vas_int_r: 0.35 -> 2.0 %)
    return gname, sname


def _reference_active_values(ctx: PathContext, point: PathPoint) -> dict[str, float]:
    """Coordinate values at the reference pose, with a conditional point's coordinate moved
    into the point's active range when it is outside it (to the middle of the part of that
    range inside the coordinate's range)."""
    cname, lo, hi = point.condition
    if lo <= ctx.b.ref[cname] <= hi:
        return ctx.b.coordinate_values()
    base = ctx.b.drivers[cname].base
    kind = ctx.b.coord_joint[base][1].kind if base in ctx.b.coord_joint else "rotation"
    rlo, rhi = ctx.b.fit_range(base, kind)
    a, b = max(lo, rlo), min(hi, rhi)
    return ctx.b.coordinate_values({base: 0.5 * (a + b) if a <= b else 0.5 * (lo + hi)})


def _bend(ctx: PathContext, path: Path, k: int, values: dict[str, float], keep: list[bool]
          ) -> tuple[np.ndarray, float, np.ndarray]:
    """Unit direction (ground) from the straight segment between the kept neighbours of point
    ``k`` to the point, the length (m) the point adds to the path, in pose ``values``, and
    the unit direction of that segment."""
    pts = path.points
    frames = ctx.b.ground_frames_at(values)

    def world(p: PathPoint) -> np.ndarray:
        return frames[p.body].apply(ctx.location_at(p, values))

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
    return off / n, detour, ac / max(float(np.linalg.norm(ac)), 1e-18)


def _off_direction(ctx: PathContext, path: Path, k: int, roles: list[str], centre: np.ndarray) -> np.ndarray:
    """Unit direction (body frame of point ``k``) from the point towards which the straight
    segment between its neighbouring sites passes in the sampled poses where OpenSim has the
    point inactive (each pose weighted by the length the point would add there)."""
    pts = path.points
    keep = [r == "site" for r in roles]
    before = next(i for i in range(k - 1, -1, -1) if keep[i])
    after = next(i for i in range(k + 1, len(pts)) if keep[i])
    point = pts[k]
    feet, weights = [], []
    for j, (_, values) in enumerate(ctx.pose_samples()):
        if ctx.active(point, values):
            continue
        frames = ctx.sample_frames(j)
        to_body = frames[point.body].inverse()
        a = to_body.apply(frames[pts[before].body].apply(ctx.location_at(pts[before], values)))
        b = to_body.apply(frames[pts[after].body].apply(ctx.location_at(pts[after], values)))
        ab = b - a
        t = float(np.clip((centre - a) @ ab / max(ab @ ab, 1e-18), 0.0, 1.0))
        feet.append(a + t * ab - centre)
        weights.append(float(np.linalg.norm(centre - a) + np.linalg.norm(b - centre) - np.linalg.norm(ab)))
    values = _reference_active_values(ctx, point)
    n_ground, _, _ = _bend(ctx, path, k, values, keep)
    n_body = ctx.b.ground_frames_at(values)[point.body].rot.T @ n_ground
    if not feet:
        return -n_body
    f, w = np.array(feet), np.array(weights)
    m = 2000
    i = np.arange(m) + 0.5
    phi, theta = np.arccos(1 - 2 * i / m), np.pi * (1 + 5**0.5) * i
    cand = np.vstack([-n_body, np.c_[np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)]])
    cost = (((cand @ f.T) < 0) * w[None, :]).sum(axis=1)
    best = np.flatnonzero(cost <= cost.min() + 1e-9)
    u = cand[best[np.argmax(cand[best] @ -n_body)]]
    return u / np.linalg.norm(u)
