"""ConditionalPathPoints: a small wrap sphere on the point, with a side site that leaves it where
OpenSim has the point off.

A ConditionalPathPoint becomes a small wrap sphere (radius :data:`CONDITIONAL_RADIUS`, metres)
whose surface passes through the point, with a side site on a carrier that slides out of it as
the point's coordinate (radians or metres) leaves the point's range (see
:func:`conditional_geom`): inside, MuJoCo 4.0 makes the tendon touch the sphere (through the
point); outside, its ordinary rule leaves the tendon straight. So the tendon switches where
OpenSim's does, by OpenSim's own step, just beyond the range's ends (:data:`SWITCH_MARGIN`).

MuJoCo needs a site between two wrap geoms, so in a run of consecutive conditional points some
are kept always on (sites) or left out: :func:`conditional_roles` takes the choice whose path
is nearest OpenSim's over the sampled poses; the report names each point so treated.
"""

from __future__ import annotations

import itertools

import mujoco
import numpy as np

from o2m.convert.carriers import CARRIER_ARMATURE, Carriers
from o2m.convert.pathpoints import PathContext
from o2m.convert.records import JointRecord
from o2m.osim.paths import Path, PathPoint
from o2m.transforms import Transform

#: Radius (m) of the wrap sphere that stands for a ConditionalPathPoint: the tendon passes through
#: the point when it bends as at the reference pose, and up to two radii from it (the sphere's far
#: side) where the bend has turned the other way, cutting the corner by about that much.
CONDITIONAL_RADIUS = 0.0001
#: A ConditionalPathPoint whose range is no wider than this (rad or m) is active at one value of its
#: coordinate at most: it is left out (the switch of :func:`conditional_geom` needs a range to fit).
MIN_RANGE_WIDTH = 1e-9
#: How far (rad or m) beyond each end of a point's range its side site leaves the sphere. OpenSim's
#: range is closed (a pose at an end has the point on); ten times the finite-difference step of
#: :func:`o2m.mj.tendons.mujoco_moment_arms`, so such a pose has it on within that step too.
SWITCH_MARGIN = 1e-5
#: Runs of consecutive conditional points up to this long try every role per point (3**n
#: choices); a longer run keeps one sphere (the best) and leaves out the others.
MAX_RUN_SEARCH = 6


def conditional_roles(ctx: PathContext, path: Path) -> list[str]:
    """For each point of ``path``: ``"site"`` (always on the path), ``"conditional"`` (a
    ConditionalPathPoint made a wrap sphere) or ``"dropped"`` (a conditional point left out:
    its coordinate is locked outside its range, or its range has no width
    (:data:`MIN_RANGE_WIDTH`)). In a run of consecutive conditional points, MuJoCo needs a site
    between two wrap geoms: :func:`_run_roles` chooses which of them are spheres, which are
    kept always on (sites) and which are left out. First and last points stay sites."""
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
    for run in _conditional_runs(roles):
        if len(run) > 1:
            _run_roles(ctx, path, roles, run)
    return roles


def _conditional_runs(roles: list[str]) -> list[list[int]]:
    """Indices of the runs of conditional points with no site between them (left-out points
    do not separate two conditional points: MuJoCo would see two wrap geoms in a row)."""
    runs: list[list[int]] = [[]]
    for k, role in enumerate(roles):
        if role == "conditional":
            runs[-1].append(k)
        elif role == "site" and runs[-1]:
            runs.append([])
    return [r for r in runs if r]


def _run_roles(ctx: PathContext, path: Path, roles: list[str], run: list[int]) -> None:
    """Give the points ``run`` (consecutive conditional points of ``path``) the roles, among
    sphere (``"conditional"``), always on (``"site"``) and left out (``"dropped"``), with a site
    between any two spheres, whose path (points joined straight) is nearest OpenSim's: smallest
    largest relative error over the sampled poses, then smallest RMS. Keeping one sphere and
    leaving out the others is one of the choices, and the only kind tried for a run longer than
    :data:`MAX_RUN_SEARCH`."""
    pts = path.points
    before = max(i for i in range(run[0]) if roles[i] == "site")
    after = min(i for i in range(run[-1] + 1, len(pts)) if roles[i] == "site")
    span = [before] + run + [after]
    where, active = _span_samples(ctx, path, span)
    truth = _polyline(where, active)
    full = np.array([ctx.straight_length(path, n) for n in range(len(where))])
    best = None
    if len(run) <= MAX_RUN_SEARCH:
        choices = itertools.product(("conditional", "site", "dropped"), repeat=len(run))
    else:
        choices = [tuple("conditional" if i == j else "dropped" for i in range(len(run))) for j in range(len(run))]
    for choice in choices:
        kept = [c for c in choice if c != "dropped"]
        if any(a == b == "conditional" for a, b in zip(kept[:-1], kept[1:], strict=True)):
            continue
        on = active.copy()
        for j, c in enumerate(choice, start=1):
            on[:, j] = {"conditional": active[:, j], "site": True, "dropped": False}[c]
        rel = np.abs(_polyline(where, on) - truth) / np.maximum(full, 1e-12)
        key = (float(rel.max()), float(np.sqrt(np.mean(rel**2))))
        if best is None or key < best[0]:
            best = (key, choice)
    (worst, rms), choice = best
    for k, c in zip(run, choice, strict=True):
        roles[k] = c
    spheres = [pts[k].name for k, c in zip(run, choice, strict=True) if c == "conditional"]
    for k, c in zip(run, choice, strict=True):
        if c != "conditional":
            what = "left out" if c == "dropped" else "kept always on the path"
            ctx.b.result.notes.append(
                f"{path.owner}: ConditionalPathPoint '{pts[k].name}' {what} (consecutive conditional points: "
                f"MuJoCo needs a site between two wrap geoms; spheres {spheres or 'none'}, the straight path so "
                f"chosen is within {100 * worst:.2g} % of OpenSim's over the sampled poses, {100 * rms:.2g} % RMS)")


def _span_samples(ctx: PathContext, path: Path, span: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Ground positions (n_samples, len(span), 3) of the points ``span`` of ``path`` at the
    sampled poses (m), and whether OpenSim has each on its path there (n_samples, len(span))."""
    samples = ctx.pose_samples()
    where = np.zeros((len(samples), len(span), 3))
    active = np.zeros((len(samples), len(span)), dtype=bool)
    for n, (_, values) in enumerate(samples):
        frames = ctx.sample_frames(n)
        for j, k in enumerate(span):
            p = path.points[k]
            where[n, j] = frames[p.body].apply(ctx.sample_locations(p)[n])
            active[n, j] = ctx.active(p, values)
    return where, active


def _polyline(where: np.ndarray, on: np.ndarray) -> np.ndarray:
    """Length (m) per sample of the polyline through the points of ``where`` (n, k, 3) that
    are ``on`` (n, k); the first and last are always on."""
    total = np.zeros(len(where))
    prev = where[:, 0]
    for j in range(1, where.shape[1]):
        step = np.linalg.norm(where[:, j] - prev, axis=1)
        total += np.where(on[:, j], step, 0.0)
        prev = np.where(on[:, j, None], where[:, j], prev)
    return total


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
    # where the switch is: just beyond each end, as OpenSim's range is closed and a side site on
    # the surface is in or out by rounding (WristModel FDPM, range end 0 at the default flexion:
    # MuJoCo's finite-difference moment arms 0.4 m there about every coordinate)
    slo, shi = lo - SWITCH_MARGIN, hi + SWITCH_MARGIN
    if base == cname:  # a range end at (or beyond) the coordinate's limit never switches there
        tol = 1e-6 * max(1.0, chi - clo)
        slo = lo - (hi - lo) if lo <= clo + tol else slo
        shi = hi + (hi - lo) if hi >= chi - tol else shi
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
    side = cand @ f.T
    cost = ((side < 0) * w[None, :]).sum(axis=1)
    best = np.flatnonzero(cost <= cost.min() + 1e-9)
    # of the ties, the widest angular margin: a pose between the samples whose straight path
    # passes a little further round must still leave the side site on its side
    norm = np.linalg.norm(f, axis=1)
    far = norm > 1e-12
    if far.any():
        margin = (side[np.ix_(best, far)] / norm[far]).min(axis=1)
        u = cand[best[np.argmax(margin)]]
    else:
        u = cand[best[np.argmax(cand[best] @ -n_body)]]
    return u / np.linalg.norm(u)
