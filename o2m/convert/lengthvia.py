"""Length via points: a path segment that several wrap objects act on, given a designed length.

MuJoCo wraps one geom per segment between two sites, and a tendon's moment arm is ``-dL/dq`` of
its length. OpenSim can wrap a segment over several objects at once (Arm26's TRIlong over
TRIlonghh and TRIlongglen), and then its length can step (a wrap switching on or off) and its
dynamic moment arm (``computeMomentArm``) need not be ``-dL/dq`` of its length. Where two or more
wraps are closest to the same segment at the reference pose, its two end points are fixed points,
and the bodies they are on move relative to each other through one coordinate ``q`` only, that
segment's wraps are replaced by one moving via point ``V`` on the first point's body:

* **Designed length** ``T(q)``: over a sweep of ``q`` (:data:`SWEEP_POSES` poses, the other
  coordinates at their defaults) OpenSim gives the segment's length (its straight parts and wrap
  arcs) and the path's ``computeMomentArm`` less the rest of the path's ``-dL/dq``. ``T`` is the
  continuous length whose ``-dT/dq`` is nearest (least squares) to that moment arm while staying
  within ``p`` % of OpenSim's path length at every pose (bounded least squares,
  :func:`scipy.optimize.lsq_linear`; OpenSim's one-pose length spikes and the poses where its path
  fails, :func:`o2m.osim.spikes.path_failure`, are no target). ``p`` is the
  least that any continuous length can reach, half the largest step of OpenSim's segment length
  over the sweep (as :func:`o2m.validate_muscles.opensim_length_steps` finds them for the whole
  path), plus :data:`MARGIN_PCT`, and at least :data:`MIN_PCT`.
* **Via point**: ``V(q)``, in the first point's body frame, is a quartic of ``q`` per axis (so
  that its carrier's slides follow ``q`` by MuJoCo joint equalities exactly, :mod:`o2m.tendons`),
  fitted (:func:`scipy.optimize.least_squares`, :data:`FIT_STARTS` seeded starts) so that
  ``|P1 V| + |V P2|`` has the moment arm above, OpenSim's length (weight :data:`LENGTH_WEIGHT`)
  and stays within the tolerance (weight :data:`TOLERANCE_WEIGHT`). It starts from ``T`` itself:
  ``V = P1 + a(q) u`` with ``u`` the direction (perpendicular to the segment) in which OpenSim's
  path bulges most and ``a = (T^2 - |w|^2) / (2 (T - u.w))``, ``w = P2 - P1``, which gives
  ``|P1 V| + |V P2| = T`` exactly.

The segment then has the designed length and moment arm in statics and in dynamics (MuJoCo's
tendon force on the carrier reaches ``q`` through its joint equalities, as ``-dT/dq``). Each
replacement is recorded (:class:`LengthVia`): the length error and moment-arm RMS the via point
reaches on the sweep, and OpenSim's own steps and inconsistency that bound it. :mod:`o2m.wrapfit`
then fits the path's other wrap geoms to the designed length (:func:`designed_correction`).

Measured on Arm26's TRIlong (200 random poses, quick mode): the length within 1.31 % of OpenSim
(the floor of OpenSim's -7.9 mm step at shoulder elevation 2.52 rad is 1.21 %) and the moment
arm about the shoulder 1.91 mm RMS from ``computeMomentArm``, where keeping TRIlongglen alone
(fitted) gave 2.70 % and 3.44 mm.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from o2m.convert.builder import MjcfBuilder
from o2m.convert.records import Approximation
from o2m.convert.wraps import segment_distance as _segment_distance
from o2m.convert.wraps import wrap_segments
from o2m.osim import runtime
from o2m.osim.couplers import coupler_chain, set_coupled
from o2m.osim.functions import PolynomialFunction
from o2m.osim.names import opensim_coordinate
from o2m.osim.paths import Path, PathPoint, WrapObject
from o2m.osim.spikes import one_pose_spikes, outlying_changes, path_failure
from o2m.transforms import Transform

#: Poses of the sweep over the coordinate (its range, evenly spaced).
SWEEP_POSES = 361
#: Length tolerance above the floor of OpenSim's largest step, in % of the path's length.
MARGIN_PCT = 0.1
#: Smallest length tolerance (%), for a path without steps.
MIN_PCT = 0.5
#: Weights of the design's length rows (per rad: 1 mm of length counts as 1 mm of moment arm)
#: and of its curvature rows (rad^2), against its moment-arm rows.
LENGTH_WEIGHT = 0.3
#: Weight (per rad) of a length beyond the tolerance in the quartic fit: 30 mm of moment arm per mm.
TOLERANCE_WEIGHT = 30.0
#: Starts of the quartic fit (the design, then seeded perturbations of its coefficients, in m).
FIT_STARTS = 3
FIT_SPREAD = 0.003


@dataclass
class LengthVia:
    """One segment given a designed length: the path, its end points, the coordinate, the wraps
    it replaces, the tolerance used and what the design reaches on the sweep (length error in %
    of the path's length, moment-arm RMS against ``computeMomentArm`` in mm)."""

    path: str
    points: tuple[str, str]
    coordinate: str
    wraps: list[str]
    tolerance_pct: float
    floor_pct: float
    length_error_pct: float
    moment_arm_rms_mm: float
    opensim_inconsistency_mm: float  # RMS of computeMomentArm - (-dL/dq) away from OpenSim's steps
    steps_mm: list[float] = field(default_factory=list)
    body: str = ""  # the via point's body (the first point's)
    p1: list[float] = field(default_factory=list)  # the first point in that body's frame (m)
    coefficients: list[list[float]] = field(default_factory=list)  # (5, 3) V's quartic, highest power first


def shared_segments(path: Path, wraps: dict[str, WrapObject], ground_frames: dict[str, Transform]
                    ) -> dict[int, list[str]]:
    """Segment index -> the names of the active wraps (two or more) whose closest segment (within
    their OpenSim range, at the reference pose) it is."""
    pts = np.array([(ground_frames[p.body] @ Transform(pos=p.location)).pos for p in path.points])
    n = len(path.points)
    out: dict[int, list[str]] = {}
    for pw in path.wraps:
        wrap = wraps.get(pw.wrap)
        if wrap is None or not wrap.active:
            continue
        first, last = wrap_segments(pw.range, n)
        if last < first:
            continue
        centre = (ground_frames[wrap.body] @ wrap.frame).pos
        d = [_segment_distance(pts[s], pts[s + 1], centre) for s in range(first, last + 1)]
        out.setdefault(first + int(np.argmin(d)), []).append(pw.wrap)
    return {s: names for s, names in out.items() if len(names) > 1}


def coordinates_between(builder: MjcfBuilder, a: str, b: str) -> set[str]:
    """The free independent coordinates that move body ``b`` relative to body ``a``."""
    parent = {j.child: j for j in builder.skel.joints}

    def chain(body: str) -> list[str]:
        out = []
        while body in parent:
            out.append(parent[body].name)
            body = parent[body].parent
        return out

    ja, jb = chain(a), chain(b)
    joints = set(ja) ^ set(jb)
    coords = set()
    for j in builder.skel.joints:
        if j.name in joints:
            for c in j.coordinates:
                if not builder.skel.coordinates[c].locked:
                    coords.add(builder.drivers[c].base)
    return {c for c in coords if not builder.skel.coordinates[c].locked}


def segment(model, gp, state, a_name: str, b_name: str, body: str) -> tuple[float, list[np.ndarray]]:
    """OpenSim's length (m) of the part of path ``gp`` between its points ``a_name`` and
    ``b_name`` in a realised ``state`` (straight parts plus wrap arcs, as ``getLength`` sums them),
    and the current path's points after ``a_name`` up to ``b_name`` in ``body``'s frame."""
    opensim = runtime.opensim()

    frame = model.getComponent(_frame_path(model, body))
    ground = model.getGround()
    cp = gp.getCurrentPath(state)
    names = [cp.get(i).getName() for i in range(cp.getSize())]
    i0, i1 = names.index(a_name), names.index(b_name)
    length, local = 0.0, []
    for i in range(i0 + 1, i1 + 1):
        p, r = cp.get(i - 1), cp.get(i)
        wp, wr = opensim.PathWrapPoint.safeDownCast(p), opensim.PathWrapPoint.safeDownCast(r)
        if wp is not None and wr is not None and wp.getWrapObject().getName() == wr.getWrapObject().getName():
            length += wr.getWrapLength(state)
        else:
            length += float(np.linalg.norm(r.getLocationInGround(state).to_numpy()
                                           - p.getLocationInGround(state).to_numpy()))
        local.append(ground.findStationLocationInAnotherFrame(state, r.getLocationInGround(state), frame).to_numpy())
    return length, local


def designed_correction(model, state, via: LengthVia) -> float:
    """What the tendon with ``via`` differs from OpenSim's ``getLength`` in a realised ``state``
    (m): the designed length of the segment minus OpenSim's."""
    gp = runtime.geometry_path(model, via.path)
    length, local = segment(model, gp, state, via.points[0], via.points[1], via.body)
    q = opensim_coordinate(model, via.coordinate).getValue(state)
    v = np.vander(np.array([q]), 5)[0] @ np.asarray(via.coefficients, dtype=float)
    p1 = np.asarray(via.p1, dtype=float)
    return float(np.linalg.norm(v - p1) + np.linalg.norm(local[-1] - v)) - length


def _sweep(osim_path: str, path: Path, seg: int, cname: str, qs: np.ndarray) -> dict[str, np.ndarray]:
    """OpenSim over the sweep: the path's length, the segment's length, the path's
    computeMomentArm about ``cname``, the second point in the first point's body frame, the
    points of the current path between the two (first point's body frame), and whether OpenSim's
    path fails there (:func:`o2m.osim.spikes.path_failure`)."""
    model, state = runtime.load_model(osim_path, 1e-12)
    coord = opensim_coordinate(model, cname)
    gp = runtime.geometry_path(model, path.owner)
    a, b = path.points[seg], path.points[seg + 1]
    couplers = coupler_chain(model, state)
    total, part, arm, p2, bulge, failed = [], [], [], [], [], []
    for q in qs:
        coord.setValue(state, float(q), couplers is None)  # coupled coordinates follow it
        if couplers is not None:
            set_coupled(couplers, state)
        model.realizePosition(state)
        total.append(gp.getLength(state))
        failed.append(path_failure(model, state, path.owner) is not None)
        arm.append(gp.computeMomentArm(state, coord))
        length, local = segment(model, gp, state, a.name, b.name, a.body)
        part.append(length)
        p2.append(local[-1])
        bulge.append(local[:-1])
    return {"total": np.array(total), "part": np.array(part), "arm": np.array(arm), "p2": np.array(p2),
            "bulge": bulge, "failed": np.array(failed, dtype=bool)}


def _frame_path(model, body: str) -> str:
    if body == model.getGround().getName():
        return "/ground"
    return f"/bodyset/{body}"


@dataclass(frozen=True)
class _ViaFit:
    """The least-squares problem of a via point V whose location is a quartic of q per axis,
    ``V = basis @ x.reshape(5, 3)`` (body frame, m): over the sweep's poses (n,), the moment arm
    of ``|P1 V| + |V P2|`` against ``arm_mid`` (between poses, m) where no step is ``spiky``, its
    length against ``part`` (m) and beyond ``allowed`` (m) where no pose is a ``spike``. The
    Jacobian is exact (a path of two straight lines), so that ``least_squares`` spends no 15
    residual evaluations per step on finite differences."""

    basis: np.ndarray  # (n, 5)
    p1: np.ndarray  # (3,)
    p2: np.ndarray  # (n, 3)
    part: np.ndarray  # (n,)
    allowed: np.ndarray  # (n,)
    arm_mid: np.ndarray  # (n - 1,)
    h: float
    spike: np.ndarray  # (n,) bool
    spiky: np.ndarray  # (n - 1,) bool

    def lengths(self, x: np.ndarray) -> np.ndarray:
        v = self.basis @ x.reshape(5, 3)
        return np.linalg.norm(v - self.p1, axis=1) + np.linalg.norm(self.p2 - v, axis=1)

    def residuals(self, x: np.ndarray) -> np.ndarray:
        length = self.lengths(x)
        over = np.maximum(np.abs(length - self.part) - self.allowed, 0.0)
        return np.concatenate([(-np.diff(length) / self.h - self.arm_mid)[~self.spiky],
                               LENGTH_WEIGHT * (length - self.part)[~self.spike], TOLERANCE_WEIGHT * over[~self.spike]])

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """d residuals / d x, (rows, 15)."""
        v = self.basis @ x.reshape(5, 3)
        a, b = v - self.p1, self.p2 - v
        na, nb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
        grad_v = a / na[:, None] - b / nb[:, None]  # d length / d V, (n, 3)
        dlength = (self.basis[:, :, None] * grad_v[:, None, :]).reshape(len(v), 15)
        beyond = np.abs(na + nb - self.part) > self.allowed
        dover = np.where(beyond, np.sign(na + nb - self.part), 0.0)[:, None] * dlength
        return np.concatenate([(-np.diff(dlength, axis=0) / self.h)[~self.spiky], LENGTH_WEIGHT * dlength[~self.spike],
                               TOLERANCE_WEIGHT * dover[~self.spike]])


def design(osim_path: str, builder: MjcfBuilder, path: Path, seg: int, cname: str, wraps: list[str]
           ) -> tuple[PathPoint, LengthVia] | None:
    """The via point for segment ``seg`` of ``path`` over coordinate ``cname`` and its record, or
    None when OpenSim's path never leaves the straight line there (nothing to stand for)."""
    from scipy.optimize import least_squares, lsq_linear
    from threadpoolctl import threadpool_limits

    coord = builder.skel.coordinates[cname]
    lo, hi = coord.range
    qs = np.linspace(lo, hi, SWEEP_POSES)
    h = float(qs[1] - qs[0])
    s = _sweep(osim_path, path, seg, cname, qs)
    p1 = np.asarray(path.points[seg].location, dtype=float)
    w = s["p2"] - p1
    straight = np.linalg.norm(w, axis=1)
    rest = s["total"] - s["part"]
    arm_part = s["arm"] - (-np.gradient(rest, h))  # less the rest of the path's own -dL/dq
    arm_mid = 0.5 * (arm_part[1:] + arm_part[:-1])

    d = np.diff(s["part"])
    odd = outlying_changes(d)
    # OpenSim's failing paths (a detour past a path point, a loop, a winding) are no target
    # either: osim-rl's MoBL-ARMS variant's ECRL, its wrist torus acting on the elbow segment,
    # runs 0.9 m where its path is 0.33 m, which set a 32 % "step" tolerance
    spike = one_pose_spikes(d, odd) | s["failed"]
    spiky = spike[:-1] | spike[1:]
    steps = [float(x) for x, o, sp in zip(d, odd, spiky, strict=True) if o and not sp]
    floor = max((100.0 * abs(d[k]) / 2.0 / float(max(s["total"][k], s["total"][k + 1]))
                 for k in np.flatnonzero(odd & ~spiky)), default=0.0)
    tol = max(floor + MARGIN_PCT, MIN_PCT)

    excess = s["part"] - straight
    if float(np.max(np.where(spike, 0.0, excess))) < 1e-6:
        return None
    k = int(np.argmax(np.where(spike, -np.inf, excess)))
    line = w[k] / straight[k]
    far, u = -1.0, np.zeros(3)
    for pt in s["bulge"][k]:
        v = pt - p1
        perp = v - (v @ line) * line
        if np.linalg.norm(perp) > far:
            far, u = float(np.linalg.norm(perp)), perp
    u = u / np.linalg.norm(u)

    n = len(qs)
    D = (np.eye(n, k=1) - np.eye(n))[:-1] / h
    lo_b = np.where(spike, 0.0, s["part"] - tol / 100 * s["total"])
    hi_b = np.where(spike, 2.0 * s["part"] + 1.0, s["part"] + tol / 100 * s["total"])
    lo_b = np.maximum(lo_b, np.minimum(straight, hi_b - 1e-9))
    fit = lsq_linear(-D[~spiky], arm_mid[~spiky], bounds=(lo_b, hi_b))
    target = np.maximum(fit.x, straight)
    a = (target**2 - straight**2) / (2.0 * (target - w @ u))
    a = np.where(target - straight > 1e-12, a, 0.0)
    start = p1 + a[:, None] * u[None, :]  # the designed length, along u: the start of the quartic fit

    basis = np.vander(qs, 5)  # V's location: a quartic of q per axis (a MuJoCo joint equality, exactly)
    via = _ViaFit(basis, p1, s["p2"], s["part"], tol / 100 * s["total"], arm_mid, h, spike, spiky)
    x0 = np.linalg.lstsq(basis[~spike], start[~spike], rcond=None)[0].ravel()  # spikes' targets are free
    rng = np.random.default_rng(0)
    best = None
    # one BLAS thread: thousands of SVDs of a (3 SWEEP_POSES, 15) Jacobian, 25 times faster than
    # on two threads, and the fit, which may stop at max_nfev, then ends where it does on any machine
    with threadpool_limits(limits=1, user_api="blas"):
        for trial in range(FIT_STARTS):
            guess = x0 if trial == 0 else x0 + rng.normal(0.0, FIT_SPREAD, x0.size)
            r = least_squares(via.residuals, guess, jac=via.jacobian, x_scale=0.01, max_nfev=4000)
            if best is None or r.cost < best.cost:
                best = r
    coef = best.x.reshape(5, 3)
    target = via.lengths(best.x)
    length_err = np.abs(target - s["part"]) / s["total"]
    res = (-np.diff(target) / h - arm_mid)[~spiky]
    rest_ok = ~spiky & ~odd
    inconsistency = (arm_mid - (-np.diff(s["part"]) / h))[rest_ok]
    name = f"{path.owner}-length_via"
    moving = {i: (cname, PolynomialFunction(coefficients=coef[:, i])) for i in range(3)}
    location = np.array([float(moving[i][1](np.array([builder.ref[cname]]))[0]) for i in range(3)])
    point = PathPoint(name, path.points[seg].body, location, path.points[seg].element, moving=moving, designed=True)
    rec = LengthVia(path.owner, (path.points[seg].name, path.points[seg + 1].name), cname, list(wraps), tol, floor,
                    100.0 * float(np.max(length_err[~spike])), 1e3 * float(np.sqrt(np.mean(res**2))),
                    1e3 * float(np.sqrt(np.mean(inconsistency**2))), [1e3 * x for x in steps],
                    path.points[seg].body, p1.tolist(), coef.tolist())
    return point, rec


def add_length_vias(builder: MjcfBuilder, paths: list[Path], wraps: dict[str, WrapObject],
                    osim_path: str) -> list[LengthVia]:
    """Give every segment that two or more wraps share (see the module notes) a designed length
    via point, in place in ``paths`` (the point inserted, those wraps removed, later wrap ranges
    shifted); returns the records and adds an :class:`~o2m.mjcf.Approximation` for each."""
    out = []
    for path in paths:
        for seg, names in sorted(shared_segments(path, wraps, builder.ground_frames).items(), reverse=True):
            a, b = path.points[seg], path.points[seg + 1]
            if a.moving or b.moving or a.condition or b.condition:
                continue
            coords = coordinates_between(builder, a.body, b.body)
            if len(coords) != 1:
                builder.result.notes.append(f"{path.owner}: wraps {', '.join(names)} share segment {a.name}-{b.name}, "
                                            f"which {len(coords)} coordinates move: split (o2m.convert.wrap_split)")
                continue
            made = design(osim_path, builder, path, seg, next(iter(coords)), names)
            if made is None:
                continue
            point, rec = made
            path.points.insert(seg + 1, point)
            kept = []
            for pw in path.wraps:
                if pw.wrap in names:
                    continue
                lo, hi = pw.range
                pw.range = (lo + (lo > seg + 1), hi + (hi > seg + 1))
                kept.append(pw)
            path.wraps = kept
            builder.result.approximations.append(Approximation(
                "PathWrap", f"{path.owner}:{'+'.join(names)}",
                f"wraps {', '.join(names)} on {a.name}-{b.name} replaced by a length via point moving with "
                f"{rec.coordinate}: length within {rec.length_error_pct:.3g} % (tolerance {rec.tolerance_pct:.3g} %, "
                f"OpenSim's steps leave {rec.floor_pct:.3g} %), moment arm {rec.moment_arm_rms_mm:.3g} mm RMS vs "
                f"computeMomentArm (OpenSim's own -dL/dq differs from it by {rec.opensim_inconsistency_mm:.3g} mm RMS)",
                rec.length_error_pct, "%", "length error on the sweep"))
            out.append(rec)
    return out
