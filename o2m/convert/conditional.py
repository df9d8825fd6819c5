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
is nearest OpenSim's over the sampled poses; the report names each point so treated. Two
consecutive points of one body that one coordinate switches on in disjoint ranges (the wrist
flexors' pair on the radius, one on in flexion and one in extension) may instead share one
sphere (:func:`shared_geom`): a carrier moves it from one point to the other while both are
off, and its side site is out of it exactly there, so the run needs one geom fewer.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable

import mujoco
import numpy as np

from o2m.convert.carriers import CARRIER_ARMATURE, Carriers
from o2m.convert.pathpoints import PathContext
from o2m.convert.records import Approximation, JointRecord
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
#: choices, more with shared spheres); a longer run keeps one sphere (the best) and leaves out the
#: others.
MAX_RUN_SEARCH = 6
#: A run's roles are chosen by how far each puts the straight path from OpenSim's against the
#: issue's per-muscle targets: the worst length error over the sampled poses over LENGTH_TARGET
#: (a fraction of the path's length), or the worst RMS moment-arm error about a coordinate over
#: MOMENT_ARM_TARGET (m), whichever is larger (by length alone, the wrist flexors kept roles whose
#: moment arms were millimetres off where another choice was within the targets).
LENGTH_TARGET = 0.01
MOMENT_ARM_TARGET = 0.002
#: Central-difference step (rad or m) of those moment arms, and the pose samples (the first ones)
#: they are taken at: their RMS over a quarter of the samples, at a quarter of the cost.
MOMENT_ARM_STEP = 1e-4
MOMENT_ARM_SAMPLES = 50
#: Roles that put a wrap geom on the path: a point's own sphere, or one shared with the next point.
GEOM_ROLES = ("conditional", "shared")
#: The shared sphere's carrier follows a quartic of the coordinate fitted to each point's place over
#: its range; its slope, weighted by this (rad or m), is fitted to 0 there too, since the slope is a
#: moment-arm error wherever the tendon bends at the sphere.
SHARED_SLOPE_WEIGHT = 0.5


def conditional_roles(ctx: PathContext, path: Path) -> list[str]:
    """For each point of ``path``: ``"site"`` (always on the path), ``"conditional"`` (a
    ConditionalPathPoint made a wrap sphere) or ``"dropped"`` (a conditional point left out:
    its coordinate is locked outside its range, or its range has no width
    (:data:`MIN_RANGE_WIDTH`)), or ``"shared"`` / ``"joined"`` (a point and the next one of
    its run sharing one sphere, :func:`shared_geom`). In a run of consecutive conditional
    points, MuJoCo needs a site between two wrap geoms: :func:`_run_roles` chooses which of them
    are spheres, which are kept always on (sites) and which are left out. First and last points
    stay sites."""
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
    sphere (``"conditional"``), always on (``"site"``), left out (``"dropped"``) and one
    sphere for two (``"shared"`` then ``"joined"``, :func:`can_share`), with a site between
    any two spheres, whose path (points joined straight) is nearest OpenSim's over the sampled
    poses: in length and moment arms against the targets (:data:`LENGTH_TARGET`,
    :data:`MOMENT_ARM_TARGET`), then in RMS length. Keeping one sphere and leaving out the
    others is one of the choices, and the only kind tried for a run longer than
    :data:`MAX_RUN_SEARCH`."""
    pts = path.points
    before = max(i for i in range(run[0]) if roles[i] == "site")
    after = min(i for i in range(run[-1] + 1, len(pts)) if roles[i] == "site")
    span = [before] + run + [after]
    where, active = _span_samples(ctx, path, span)
    moved = _span_moved(ctx, path, span)
    truth = _polyline(where, active)
    truth_arms = {c: _moment_arms(plus, minus, active[:MOMENT_ARM_SAMPLES]) for c, (plus, minus) in moved.items()}
    full = np.array([ctx.straight_length(path, n) for n in range(len(where))])
    shareable = {j for j in range(len(run) - 1) if can_share(ctx, pts[run[j]], pts[run[j + 1]])}
    best = None
    choices = _run_choices(len(run), shareable)
    for choice in choices:
        on, at = _choice_path(ctx, path, span, choice, where, active)
        rel = np.abs(_polyline(at, on) - truth) / np.maximum(full, 1e-12)
        few = active[:MOMENT_ARM_SAMPLES]
        arms = [np.sqrt(np.mean((_moment_arms(_choice_path(ctx, path, span, choice, plus, few, c, 1)[1],
                                               _choice_path(ctx, path, span, choice, minus, few, c, -1)[1],
                                               on[:MOMENT_ARM_SAMPLES]) - truth_arms[c]) ** 2))
                for c, (plus, minus) in moved.items()]
        arm = float(max(arms, default=0.0))
        key = (max(float(rel.max()) / LENGTH_TARGET, arm / MOMENT_ARM_TARGET), float(np.sqrt(np.mean(rel**2))))
        if best is None or key < best[0]:
            best = (key, choice, float(rel.max()), arm)
    (score, rms), choice, worst, arm = best
    for k, c in zip(run, choice, strict=True):
        roles[k] = c
    spheres = [pts[k].name for k, c in zip(run, choice, strict=True) if c in GEOM_ROLES]
    ctx.b.result.approximations.append(Approximation(
        "ConditionalPathPoint", path.owner, f"consecutive conditional points {[pts[k].name for k in run]} as "
        f"roles {list(choice)}, the best of {len(choices)} choices", 100 * worst, "%",
        f"the straight path over {len(where)} sampled poses, moment arms within {1e3 * arm:.2g} mm RMS; "
        + ("no choice is within the length and moment-arm targets" if score > 1 else "within the targets"),
        floor=score > 1))
    for k, c in zip(run, choice, strict=True):
        if c in ("site", "dropped"):
            what = "left out" if c == "dropped" else "kept always on the path"
            ctx.b.result.notes.append(
                f"{path.owner}: ConditionalPathPoint '{pts[k].name}' {what} (consecutive conditional points: "
                f"MuJoCo needs a site between two wrap geoms; spheres {spheres or 'none'}, the straight path so "
                f"chosen is within {100 * worst:.2g} % of OpenSim's over the sampled poses, {100 * rms:.2g} % RMS, "
                f"its moment arms within {1e3 * arm:.2g} mm RMS)")


def _choice_path(ctx: PathContext, path: Path, span: list[int], choice: tuple[str, ...], where: np.ndarray,
                 active: np.ndarray, coordinate: str | None = None, sign: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Which points of ``span`` (a run and the sites around it) are on the path with the roles
    ``choice``, and where (``where``: their places (P, len(span), 3), m), at the sampled poses
    (``coordinate`` moved by ``sign`` :data:`MOMENT_ARM_STEP`, for a shared sphere's carrier)."""
    on, at = active.copy(), where
    for j, c in enumerate(choice, start=1):
        on[:, j] = {"conditional": active[:, j], "site": True, "dropped": False, "joined": False,
                    "shared": active[:, j] | active[:, min(j + 1, len(span) - 1)]}[c]
        if c == "shared":
            a, b = path.points[span[j]], path.points[span[j + 1]]
            shift = sign * MOMENT_ARM_STEP if coordinate == a.condition[0] else 0.0
            at = at.copy()
            at[:, j] = _shared_places(ctx, a, b, where[:, j], where[:, j + 1], shift)
    return on, at


def _moment_arms(plus: np.ndarray, minus: np.ndarray, on: np.ndarray) -> np.ndarray:
    """Moment arms (m, per sample) of the straight path through the points ``on`` from their
    places with a coordinate moved up (``plus``) and down (``minus``) by :data:`MOMENT_ARM_STEP`."""
    return -(_polyline(plus, on) - _polyline(minus, on)) / (2 * MOMENT_ARM_STEP)


def _span_moved(ctx: PathContext, path: Path, span: list[int]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """For each free coordinate that changes the distances between the points ``span`` of
    ``path`` (at the reference pose): their ground places (n, len(span), 3) at the first
    :data:`MOMENT_ARM_SAMPLES` pose samples with it moved up and down by :data:`MOMENT_ARM_STEP`."""
    pts = [path.points[k] for k in span]
    samples = ctx.pose_samples()

    def places(coordinate: str, step: float, n: int) -> np.ndarray:
        frames = ctx.moved_frames(coordinate, step, n)
        out = np.zeros((n, len(pts), 3))
        for i, (base, values) in enumerate(samples[:n]):
            if any(p.moving for p in pts):  # a moving point's place follows the moved coordinate too
                values = ctx.b.coordinate_values({**base, coordinate: base[coordinate] + step})
            out[i] = [frames[i][p.body].apply(ctx.location_at(p, values)) for p in pts]
        return out

    def shape(x: np.ndarray) -> np.ndarray:  # distances between the points at the first pose
        return np.linalg.norm(x[0][:, None] - x[0][None], axis=-1)

    return {c: (places(c, MOMENT_ARM_STEP, MOMENT_ARM_SAMPLES), places(c, -MOMENT_ARM_STEP, MOMENT_ARM_SAMPLES))
            for c in samples[0][0]
            if np.abs(shape(places(c, MOMENT_ARM_STEP, 1)) - shape(places(c, -MOMENT_ARM_STEP, 1))).max() > 1e-12}


def _run_choices(n: int, shareable: set[int]):
    """Role tuples for a run of ``n`` conditional points (see :func:`_run_roles`); a pair
    ``(j, j + 1)`` with ``j`` in ``shareable`` may share a sphere."""
    if n > MAX_RUN_SEARCH:
        return [tuple("conditional" if i == j else "dropped" for i in range(n)) for j in range(n)]
    kinds = ("conditional", "site", "dropped") + (("shared", "joined") if shareable else ())
    out = []
    for choice in itertools.product(kinds, repeat=n):
        if any(c == "shared" and (j not in shareable or choice[j + 1] != "joined") for j, c in enumerate(choice)):
            continue
        if any(c == "joined" and (j == 0 or choice[j - 1] != "shared") for j, c in enumerate(choice)):
            continue
        kept = [c for c in choice if c not in ("dropped", "joined")]
        if any(a in GEOM_ROLES and b in GEOM_ROLES for a, b in zip(kept[:-1], kept[1:], strict=True)):
            continue
        out.append(choice)
    return out


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
    sit on the step). A point whose role is ``"shared"`` gets :func:`shared_geom`."""
    if roles[k] == "shared":
        return shared_geom(ctx, carriers, path, k, roles)
    point = path.points[k]
    cname, lo, hi = point.condition
    r = CONDITIONAL_RADIUS
    centre = _sphere_centre(ctx, path, k, [q == "site" for q in roles])
    u = _off_direction(ctx, path, k, roles, lambda _: centre)
    gname = ctx.unique(f"{path.owner}-{point.name}_cond" if not point.name.startswith(path.owner)
                       else f"{point.name}_cond")
    pos = ctx.in_world(point.body, Transform(pos=centre)).pos
    ctx.b.bodies[point.body].add_geom(name=gname, type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[r, 0, 0], pos=pos,
                                      contype=0, conaffinity=0, group=3, density=0, rgba=[0.9, 0.6, 0.2, 0.5])
    ctx.exact[("geom", gname)] = {"pos": pos, "size": np.array([r])}
    base = ctx.b.drivers[cname].base
    clo, chi = _coordinate_range(ctx, cname)
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
    rlo, rhi = _coordinate_range(ctx, cname)
    a, b = max(lo, rlo), min(hi, rhi)
    return ctx.b.coordinate_values({ctx.b.drivers[cname].base: 0.5 * (a + b) if a <= b else 0.5 * (lo + hi)})


def _bend_normal(ctx: PathContext, path: Path, k: int, keep: list[bool]) -> np.ndarray:
    """Unit direction (body frame of point ``k``) from the straight segment between its kept
    neighbours to the point, at the reference pose with the point on
    (:func:`_reference_active_values`)."""
    pts = path.points
    values = _reference_active_values(ctx, pts[k])
    frames = ctx.b.ground_frames_at(values)

    def world(p: PathPoint) -> np.ndarray:
        return frames[p.body].apply(ctx.location_at(p, values))

    before = next(p for p, kp in zip(pts[k - 1::-1], keep[k - 1::-1], strict=True) if kp)
    after = next(p for p, kp in zip(pts[k + 1:], keep[k + 1:], strict=True) if kp)
    a, p, c = world(before), world(pts[k]), world(after)
    ac = c - a
    t = float(np.clip((p - a) @ ac / max(ac @ ac, 1e-18), 0.0, 1.0))
    off = p - (a + t * ac)
    n = float(np.linalg.norm(off))
    if n < 1e-9:  # on the straight line: any direction perpendicular to it
        helper = np.eye(3)[int(np.argmin(np.abs(ac)))]
        off = np.cross(ac, helper)
        n = float(np.linalg.norm(off))
    return frames[pts[k].body].rot.T @ (off / n)


def _sphere_centre(ctx: PathContext, path: Path, k: int, keep: list[bool]) -> np.ndarray:
    """Where (body frame, m) the sphere standing for conditional point ``k`` is: one radius
    beyond the point, on the side the straight segment between its kept neighbours passes, so
    the tendon touching it goes through the point when it bends as at the reference pose."""
    return np.asarray(path.points[k].location, dtype=float) + CONDITIONAL_RADIUS * _bend_normal(ctx, path, k, keep)


def _off_direction(ctx: PathContext, path: Path, k: int, roles: list[str],
                   centre_at: Callable[[dict[str, float]], np.ndarray],
                   active: Callable[[dict[str, float]], bool] | None = None) -> np.ndarray:
    """Unit direction (body frame of point ``k``) from the sphere's centre (``centre_at`` the
    coordinates' values, body frame, m) towards which the straight segment between its
    neighbouring sites passes in the sampled poses where OpenSim has the point inactive (each
    pose weighted by the length the point would add there); for a shared sphere ``active``
    says when it is on."""
    pts = path.points
    keep = [r == "site" for r in roles]
    before = next(i for i in range(k - 1, -1, -1) if keep[i])
    after = next(i for i in range(k + 1, len(pts)) if keep[i])
    point = pts[k]
    feet, weights = [], []
    for j, (_, values) in enumerate(ctx.pose_samples()):
        if (active(values) if active is not None else ctx.active(point, values)):
            continue
        centre = centre_at(values)
        frames = ctx.sample_frames(j)
        to_body = frames[point.body].inverse()
        a = to_body.apply(frames[pts[before].body].apply(ctx.location_at(pts[before], values)))
        b = to_body.apply(frames[pts[after].body].apply(ctx.location_at(pts[after], values)))
        ab = b - a
        t = float(np.clip((centre - a) @ ab / max(ab @ ab, 1e-18), 0.0, 1.0))
        feet.append(a + t * ab - centre)
        weights.append(float(np.linalg.norm(centre - a) + np.linalg.norm(b - centre) - np.linalg.norm(ab)))
    n_body = _bend_normal(ctx, path, k, keep)
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


def _coordinate_range(ctx: PathContext, cname: str) -> tuple[float, float]:
    """The range (rad or m) coordinate ``cname``'s base is fitted over."""
    base = ctx.b.drivers[cname].base
    kind = ctx.b.coord_joint[base][1].kind if base in ctx.b.coord_joint else "rotation"
    return ctx.b.fit_range(base, kind)


def _in_range(ctx: PathContext, point: PathPoint) -> tuple[float, float] | None:
    """The part of ``point``'s active range inside its coordinate's fitted range, if any."""
    cname, lo, hi = point.condition
    clo, chi = _coordinate_range(ctx, cname)
    a, b = max(lo, clo), min(hi, chi)
    return (a, b) if b - a > MIN_RANGE_WIDTH else None


def can_share(ctx: PathContext, a: PathPoint, b: PathPoint) -> bool:
    """Whether consecutive ConditionalPathPoints ``a`` and ``b`` may share one sphere: fixed
    points of one body, switched by the same independent coordinate in ranges that do not
    meet (so at most one is on), each within the coordinate's range."""
    if a.condition is None or b.condition is None or a.body != b.body or a.moving or b.moving:
        return False
    cname = a.condition[0]
    if b.condition[0] != cname or ctx.b.drivers[cname].base != cname or ctx.fixed(cname):
        return False
    lower, upper = sorted((a.condition, b.condition), key=lambda c: c[1])
    return (upper[1] - lower[2] > 4 * SWITCH_MARGIN and _in_range(ctx, a) is not None
            and _in_range(ctx, b) is not None)


def _shared_fraction(ctx: PathContext, a: PathPoint, b: PathPoint) -> np.polynomial.Polynomial:
    """Where a sphere shared by ``a`` and ``b`` is, as the fraction of the way from ``b`` to
    ``a``: a quartic of their coordinate, least squares 1 over ``a``'s range and 0 over ``b``'s
    (within the coordinate's range), its slope 0 there (weight :data:`SHARED_SLOPE_WEIGHT`).
    Between the ranges both points are off and the sphere's place does not matter."""
    xa, xb = (np.linspace(*_in_range(ctx, p), 200) for p in (a, b))
    x = np.r_[xa, xb]
    target = np.r_[np.ones_like(xa), np.zeros_like(xb)]
    mid, half = 0.5 * (x.max() + x.min()), 0.5 * (x.max() - x.min())
    t = (x - mid) / half  # scaled: a well-conditioned Vandermonde
    value = np.vander(t, 5, increasing=True)
    slope = np.c_[np.zeros(len(t)), value[:, :-1] * np.arange(1, 5)] / half
    coef = np.linalg.lstsq(np.r_[value, SHARED_SLOPE_WEIGHT * slope], np.r_[target, np.zeros_like(t)],
                           rcond=None)[0]
    return np.polynomial.Polynomial(coef, domain=[x.min(), x.max()], window=[-1, 1])


def _shared_places(ctx: PathContext, a: PathPoint, b: PathPoint, wa: np.ndarray, wb: np.ndarray,
                   shift: float = 0.0) -> np.ndarray:
    """Ground places (P, 3) of the sphere shared by ``a`` and ``b`` at the pose samples (their
    coordinate moved by ``shift``), given the points' own ground places ``wa`` and ``wb`` there."""
    frac = _shared_fraction(ctx, a, b)
    q = np.array([values[a.condition[0]] for _, values in ctx.pose_samples()[:len(wa)]]) + shift
    return wb + frac(q)[:, None] * (wa - wb)


def shared_geom(ctx: PathContext, carriers: Carriers, path: Path, k: int, roles: list[str]) -> tuple[str, str]:
    """One wrap sphere for ConditionalPathPoints ``k`` and ``k + 1`` of ``path`` (one body, one
    coordinate, disjoint ranges: :func:`can_share`), and its side site.

    The sphere rides a carrier that slides from the second point's place to the first's as a
    quartic of the coordinate (:func:`_shared_fraction`; each place one radius beyond its point
    as in :func:`conditional_geom`); its side site rides a carrier on that one, along ``u``,
    inside the sphere while either point is on and out of it in the gap between their ranges
    (its distance from the centre a quadratic: the radius at the gap's ends, :data:`SWITCH_MARGIN`
    inside them, more between, less beyond, and never a radius on the far side within the
    coordinate's range). The report gives how far the sphere is from the active point."""
    a, b = path.points[k], path.points[k + 1]
    cname = a.condition[0]
    r = CONDITIONAL_RADIUS
    keep = [q == "site" for q in roles]
    ca, cb = _sphere_centre(ctx, path, k, keep), _sphere_centre(ctx, path, k + 1, keep)
    span = float(np.linalg.norm(ca - cb))
    e = (ca - cb) / span
    frac = _shared_fraction(ctx, a, b)

    def carry(x, span=span, frac=frac):  # distance (m) along e from b's place
        return span * frac(np.asarray(x, dtype=float))

    def vec(v: np.ndarray) -> np.ndarray:  # a direction of the point's body as MuJoCo places it
        return ctx.in_world(a.body, Transform(pos=v)).pos if a.body == "ground" else v

    gname = ctx.unique(f"{path.owner}-{a.name}_{b.name}_cond")
    ref = float(carry(ctx.b.ref[cname]))
    body = carriers.body(a.body, f"{gname}_carrier", ctx.in_world(a.body, Transform(pos=cb + ref * e)).pos)
    _slide(ctx, body, f"{gname}_carry", vec(e), ref, path, f"{a.name}/carry", cname, carry, a)
    body.add_geom(name=gname, type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[r, 0, 0], pos=[0, 0, 0],
                  contype=0, conaffinity=0, group=3, density=0, rgba=[0.9, 0.6, 0.2, 0.5])
    ctx.exact[("geom", gname)] = {"pos": np.zeros(3), "size": np.array([r])}

    lower, upper = sorted((a.condition, b.condition), key=lambda c: c[1])
    glo, ghi = lower[2] + SWITCH_MARGIN, upper[1] - SWITCH_MARGIN
    mid, half = 0.5 * (glo + ghi), 0.5 * (ghi - glo)
    clo, chi = _coordinate_range(ctx, cname)
    zmax = max(abs(clo - mid), abs(chi - mid), half) / half
    bump = min(1.0, 1.5 / (zmax**2 - 1)) if zmax > 1 else 1.0

    def side(x, r=r, mid=mid, half=half, bump=bump):  # out (> r) in the gap, in (|d| < r) beyond
        return r * (1 + bump * (1 - ((np.asarray(x, dtype=float) - mid) / half) ** 2))

    u = _off_direction(ctx, path, k, roles, lambda v: cb + float(carry(v[cname])) * e,
                       active=lambda v: ctx.active(a, v) or ctx.active(b, v))
    dref = float(side(ctx.b.ref[cname]))
    sbody = carriers.body(body, f"{gname}_side_carrier", vec(dref * u))
    _slide(ctx, sbody, f"{gname}_switch", vec(u), dref, path, f"{a.name}/switch", cname, side, a)
    sname = ctx.unique(f"{gname}_side")
    sbody.add_site(name=sname, pos=[0, 0, 0], size=[0.001, 0, 0], group=5)
    grid = np.concatenate([np.linspace(*_in_range(ctx, p), 101) for p in (a, b)])
    want = np.where(np.array([ctx.active(a, {cname: x}) for x in grid]), span, 0.0)
    off = np.abs(carry(grid) - want)
    ctx.b.result.notes.append(
        f"{path.owner}: ConditionalPathPoints '{a.name}' and '{b.name}' (one body, on for '{cname}' in "
        f"[{a.condition[1]:g}, {a.condition[2]:g}] and [{b.condition[1]:g}, {b.condition[2]:g}]) share a wrap "
        f"sphere of radius {r:g} m that a quartic of '{cname}' carries between them, within {1e3 * off.max():.2g} mm "
        f"of the point that is on (RMS {1e3 * np.sqrt(np.mean(off**2)):.2g} mm); its side site leaves it "
        f"between the ranges")
    return gname, sname


def _slide(ctx: PathContext, body, name: str, axis: np.ndarray, ref: float, path: Path, what: str, cname: str,
           fn, point: PathPoint) -> None:
    """A carrier slide on ``body`` along ``axis`` (MuJoCo frame), ``fn`` (m) of coordinate
    ``cname``, through a joint equality."""
    jname = ctx.unique(name)
    body.add_joint(name=jname, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis, ref=ref, armature=CARRIER_ARMATURE)
    ctx.b.exact[("joint", jname)] = {"axis": np.asarray(axis, dtype=float), "pos": np.zeros(3), "ref": ref}
    rec = JointRecord(jname, "slide", path.owner, what, None, None, "coordinate")
    ctx.b.couple(rec, ctx.b.drivers[cname].then(fn), ref, point.element)
    ctx.b.result.joints.append(rec)
