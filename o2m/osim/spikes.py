"""OpenSim's own one-pose failures: a path length that jumps at one pose and not at its neighbours.

OpenSim's wrapping can take the wrong way round in a narrow band of poses. Such a pose is no
fair test of a converted model, so comparisons detect it here and leave it out with the
evidence (the length at the pose and at its two neighbours).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from o2m.osim import runtime
from o2m.osim.pair import ModelPair
from o2m.osim.runtime import TRANSLATIONAL
from o2m.transforms import body_fixed_xyz

__all__ = ["BAND_FRACTION", "BAND_GATE", "BAND_STEPS", "DETOUR_FRACTION", "DLDQ_CONSISTENCY", "FULL_TURN",
           "LOOP_KINDS", "OUTLIER", "SPIKE_LINEAR_STEP", "SPIKE_STEP", "SPIKE_TOL", "arc_turn", "band_suspects",
           "current_path_points", "drawn_length", "length_inconsistency", "one_pose_spikes", "opensim_detours",
           "opensim_failures", "opensim_inconsistencies", "opensim_loops", "opensim_spikes", "opensim_windings",
           "outlying_changes", "path_detour", "path_failure", "path_loop", "path_winding", "runs_cross", "unfair_path",
           "wrap_arcs", "wrap_contacts", "wrap_runs"]

#: OpenSim spike test (see :func:`opensim_spikes`): coordinate step (radians, metres) and size (m).
SPIKE_STEP = 0.01
SPIKE_LINEAR_STEP = 1e-3
SPIKE_TOL = 1e-3
#: Failure bands (see :func:`opensim_spikes`): wider coordinate steps (in units of the spike
#: test's), the size of a band's departure and its neighbours' disagreement (fractions of the
#: neighbours' mean length), and the error (fraction of OpenSim's length) a converted length must
#: be off for the band test to run (it costs 4 OpenSim poses per coordinate).
BAND_STEPS = (3.0, 10.0)
BAND_FRACTION = 0.05
BAND_GATE = 0.05
#: A wrap contact point of OpenSim's current path beyond an inner path point, along the segment
#: the wrap acts on, by more than this fraction of the segment's length (see :func:`path_detour`).
#: Measured on MoBL-ARMS: overshoots a converted tendon follows stay under it (EDCM's wrist torus
#: past EDCM-P3 at every pose, 0.10-0.13, fitted within 1.2 %; at a path's first point, where no
#: detour is possible, LAT1-3 0.084), the detours a tendon cannot follow are above it (ECRL
#: 0.38-0.68, LAT2 1.21 at 0.94 m for ~0.33 m, EDCM 3.3). At 0.1 EDCM's overshoot counted as a
#: detour: the wrap fit left those poses out and the tendon drifted 5 % off everywhere.
DETOUR_FRACTION = 0.25
#: Wrap objects whose runs :func:`path_loop` checks: MuJoCo wraps their stand-ins (a cylinder
#: across its axis, a sphere in the plane of its centre and the two run ends) in one plane.
LOOP_KINDS = ("WrapCylinder", "WrapSphere", "WrapEllipsoid")
#: A wrap arc that turns further than this (radians) round its wrap object winds round it: one
#: whole turn could be taken off, so it is no shortest path, and MuJoCo's wraps turn less.
FULL_TURN = 2.0 * np.pi
#: OpenSim -dL/dq estimates at two steps that differ by more than this (m) are no moment arm.
DLDQ_CONSISTENCY = 1e-3

#: A length change between sweep neighbours that departs from its neighbours' by more than this
#: (m) marks a step or, with an opposite one next to it, a spike of OpenSim's length.
OUTLIER = 2.5e-4

def one_pose_spikes(d: np.ndarray, odd: np.ndarray) -> np.ndarray:
    """(n + 1,) bool: the sweep poses where a length leaves and comes back within one interval
    either side (two opposite outlying changes next to each other), from its changes ``d`` (n,)
    and their :func:`outlying_changes` ``odd`` (n,)."""
    spike = np.zeros(len(d) + 1, bool)
    spike[1:-1] = odd[:-1] & odd[1:] & (np.sign(d[:-1]) != np.sign(d[1:]))
    return spike


def outlying_changes(d: np.ndarray, tol: float = OUTLIER) -> np.ndarray:
    """(n,) bool: the changes ``d`` (n,) between sweep neighbours that depart by more than ``tol``
    from the median of the two changes either side: a step or a spike of a swept length."""
    pad = np.pad(d, 2, mode="edge")
    around = np.median(np.stack([pad[:-4], pad[1:-3], pad[3:-1], pad[4:]]), axis=0)
    return np.abs(d - around) > tol


def band_suspects(converted: np.ndarray, opensim: np.ndarray) -> np.ndarray:
    """Indices of the paths whose ``converted`` length (n,) is off ``opensim``'s (n,) by more
    than :data:`BAND_GATE` of it: the only ones an OpenSim failure band can explain."""
    return np.flatnonzero(np.abs(converted - opensim) > BAND_GATE * np.maximum(np.abs(opensim), 1e-12))


def opensim_spikes(pair: ModelPair, values: Mapping[str, float], muscles: Sequence[int],
                   lengths: np.ndarray | None = None, banded: Sequence[int] = ()) -> dict[int, dict[str, Any]]:
    """The muscles (indices into ``pair.matched``) whose OpenSim length is an isolated spike at
    the pose of independent ``values``: for some independent coordinate one of ``muscles`` spans
    (:meth:`ModelPair.spanned`; no other moves their lengths), moving it by
    :data:`SPIKE_STEP` radians (:data:`SPIKE_LINEAR_STEP` m) either way gives two lengths that
    agree with each other within :data:`SPIKE_TOL` while the length at the pose differs from
    their mean by more than :data:`SPIKE_TOL`. A smooth path cannot do that (its second
    difference over 0.01 rad is ~1e-5 m), nor can a conditional point's switch (a step, where
    the two neighbours differ); it is OpenSim's wrapping taking a wrong way round in a narrow band
    of poses (Arm26's BIClong round BIClonghh: 86 mm longer for shoulder elevation in 0.515-0.518
    rad). Also flagged: a length more than :data:`SPIKE_TOL` beyond both neighbours even where
    they differ (a failure band at a step between two ways round: MoBL-ARMS's TMAJ, 2.42 m between
    0.157 and 0.220 m). For the muscles ``banded`` (see :func:`band_suspects`) also a failure band
    a few steps wide, which the one-step test misses where a neighbour is in it too (MoBL-ARMS's
    TRIlong: 0.66 m for 0.33 m, its neighbours 0.05 rad away 0.35 and 1.48 m): at the wider steps
    :data:`BAND_STEPS`, two neighbours that agree within :data:`BAND_FRACTION` of their length
    while the length at the pose lies beyond both by more than that (no smooth path bends so far
    within 0.1 rad, and a step between two ways round leaves the pose at one of them). Returns
    muscle index -> {"coordinate", "step", "length", "neighbours"} (m; step in radians or metres)."""
    out: dict[int, dict[str, Any]] = {}
    if not len(muscles):
        return out
    idx = np.asarray(list(muscles), dtype=int)
    base = pair.os_lengths(pair.os_state(values)) if lengths is None else np.asarray(lengths)
    for c in _spanned_coordinates(pair, list(idx)):
        name = pair.name(c)
        h = SPIKE_LINEAR_STEP if int(c.getMotionType()) == TRANSLATIONAL else SPIKE_STEP
        up, dn = _neighbours(pair, values, name, h)
        if up is None:
            continue
        for i in idx:
            if int(i) in out:
                continue
            isolated = abs(up[i] - dn[i]) < SPIKE_TOL and abs(base[i] - 0.5 * (up[i] + dn[i])) > SPIKE_TOL
            # beyond both neighbours: no smooth path nor a step between two ways round does that
            # (MoBL-ARMS's TMAJ: 2.42 m between neighbours of 0.157 and 0.220 m)
            beyond = base[i] - max(up[i], dn[i]) > SPIKE_TOL or min(up[i], dn[i]) - base[i] > SPIKE_TOL
            if isolated or beyond:
                out[int(i)] = _evidence(name, h, base[i], dn[i], up[i])
    banded = [int(i) for i in banded if int(i) not in out]
    for c in _spanned_coordinates(pair, banded) if banded else []:
        name = pair.name(c)
        h0 = SPIKE_LINEAR_STEP if int(c.getMotionType()) == TRANSLATIONAL else SPIKE_STEP
        for h in (h0 * k for k in BAND_STEPS):
            up, dn = _neighbours(pair, values, name, h)
            for i in banded if up is not None else []:
                tol = BAND_FRACTION * 0.5 * (abs(up[i]) + abs(dn[i]))
                beyond = max(base[i] - max(up[i], dn[i]), min(up[i], dn[i]) - base[i]) > tol
                if i not in out and abs(up[i] - dn[i]) < tol and beyond:
                    out[i] = _evidence(name, h, base[i], dn[i], up[i])
    return out


def path_detour(points: Sequence[tuple[str, str | None, np.ndarray]]) -> dict[str, Any] | None:
    """Where OpenSim's current path ``points`` ((name, wrap object or None for a path point, ground
    position (3,) m) in path order) runs past one of its inner path points to a wrap contact and
    back: a contact point of a wrap on segment A-B that lies beyond A or B along A-B by more than
    :data:`DETOUR_FRACTION` of the segment, where that end is no end of the path. A wrap on a
    segment bends it between its ends; OpenSim applies some wraps to the segment's infinite line
    (MoBL_ARMS_model_for_mujoco.osim's ECRL: its wrist torus acting on ECRL-P1-P2, the path running
    0.256 m from the elbow to the wrist and back to P2, 0.164 m from P1; its length 0.52 m for
    0.30 m), so the muscle passes the same place twice; no tendon does that, and MuJoCo wraps only
    a segment that meets the geom. Returns {"wrap", "segment", "beyond"} (beyond: fraction of the
    segment) for the largest such overshoot, or None."""
    fixed = [k for k, p in enumerate(points) if p[1] is None]
    worst: dict[str, Any] | None = None
    for ia, ib in zip(fixed[:-1], fixed[1:], strict=True):
        a, b = points[ia][2], points[ib][2]
        ab = b - a
        span = float(ab @ ab)
        if span < 1e-18:
            continue
        for _, wrap, c in points[ia + 1:ib]:
            t = float((c - a) @ ab) / span
            # past B (an inner point) or before A (an inner point)
            beyond = max(t - 1.0 if ib != fixed[-1] else 0.0, -t if ia != fixed[0] else 0.0)
            if beyond > DETOUR_FRACTION and (worst is None or beyond > worst["beyond"]):
                worst = {"wrap": wrap, "segment": f"{points[ia][0]}-{points[ib][0]}", "beyond": beyond}
    return worst


def runs_cross(kind: str, runs: np.ndarray) -> bool:
    """Whether the two straight runs of a wrapped path, ``runs`` (4, 3): the point before the wrap,
    the first and last contact and the point after (wrap object frame, m), cross where MuJoCo
    wraps: projected across a cylinder's axis (z), or on the plane of a sphere's (ellipsoid's)
    centre and the two outer points. A path that wraps a convex object and crosses itself there
    loops round it (OpenSim's quadrant rule can take the long way round, over half a turn);
    MuJoCo's circle wrap refuses any wrap whose runs cross (``wrap_circle``: no wrap), so no
    wrap geom there follows it."""
    pts = np.asarray(runs, dtype=float)
    if kind == "WrapCylinder":
        flat = pts[:, :2]
    else:
        normal = np.cross(pts[0], pts[3])
        if np.linalg.norm(normal) < 1e-12:
            return False
        u = pts[0] / np.linalg.norm(pts[0])
        v = np.cross(normal / np.linalg.norm(normal), u)
        flat = np.c_[pts @ u, pts @ v]
    (a, b), (c, d) = flat[[0, 1]], flat[[2, 3]]
    det = (b[0] - a[0]) * (d[1] - c[1]) - (b[1] - a[1]) * (d[0] - c[0])
    if abs(det) < 1e-18:
        return False
    s = ((c[0] - a[0]) * (d[1] - c[1]) - (c[1] - a[1]) * (d[0] - c[0])) / det
    t = ((c[0] - a[0]) * (b[1] - a[1]) - (c[1] - a[1]) * (b[0] - a[0])) / det
    return bool(0.0 < s < 1.0 and 0.0 < t < 1.0)


def path_loop(runs: Sequence[tuple[str, str, np.ndarray]]) -> dict[str, Any] | None:
    """The first wrap of ``runs`` ((wrap object name, its class name, (4, 3) runs in its frame),
    :func:`wrap_runs`) whose runs cross (:func:`runs_cross`): {"wrap", "kind"}, or None."""
    for wrap, kind, pts in runs:
        if kind in LOOP_KINDS and runs_cross(kind, pts):
            return {"wrap": wrap, "kind": kind}
    return None


def arc_turn(kind: str, arc: np.ndarray) -> float:
    """The angle (radians) a wrap arc ``arc`` (n, 3) (points in path order, in the wrap object's
    frame, m) turns round its object: about a cylinder's axis (z), or as seen from the centre of
    a sphere or ellipsoid (the sum of the angles between successive points)."""
    pts = np.asarray(arc, dtype=float)
    if len(pts) < 2:
        return 0.0
    if kind == "WrapCylinder":
        return float(np.abs(np.diff(np.unwrap(np.arctan2(pts[:, 1], pts[:, 0])))).sum())
    unit = pts / np.maximum(np.linalg.norm(pts, axis=1, keepdims=True), 1e-12)
    return float(np.arccos(np.clip(np.sum(unit[:-1] * unit[1:], axis=1), -1.0, 1.0)).sum())


def path_winding(arcs: Sequence[tuple[str, str, np.ndarray]]) -> dict[str, Any] | None:
    """The first wrap of ``arcs`` ((wrap object name, its class name, (n, 3) arc in its frame),
    :func:`wrap_arcs`) whose arc turns more than :data:`FULL_TURN` round it (:func:`arc_turn`):
    {"wrap", "kind", "turn" (radians)}, or None. OpenSim's spiral round a cylinder with a
    quadrant can go the long way round in the wrong sense, adding a whole turn (MoBL-ARMS's SUP
    when supinated; docs/muscle-paths.md)."""
    for wrap, kind, arc in arcs:
        if kind in LOOP_KINDS:
            turn = arc_turn(kind, arc)
            if turn > FULL_TURN:
                return {"wrap": wrap, "kind": kind, "turn": turn}
    return None


def wrap_arcs(os_model: Any, state: Any, name: str) -> list[tuple[str, str, np.ndarray]]:
    """For each wrap on OpenSim's current path of the path force ``name`` in realised ``state``
    that draws an arc (``getWrapPath``): (wrap object name, its class name, (n, 3) the arc's
    points in the wrap object's frame, m)."""
    opensim = runtime.opensim()
    current = runtime.geometry_path(os_model, name).getCurrentPath(state)
    out = []
    for k in range(current.getSize()):
        point = opensim.PathWrapPoint.safeDownCast(current.get(k))
        arc = point.getWrapPath(state) if point is not None else None
        if arc is None or arc.getSize() < 2:
            continue
        wrap = point.getWrapObject()
        in_body = np.array([arc.get(j).to_numpy() for j in range(arc.getSize())])
        out.append((wrap.getName(), wrap.getConcreteClassName(), _in_wrap_frame(wrap, in_body)))
    return out


def _in_wrap_frame(wrap: Any, in_body: np.ndarray) -> np.ndarray:
    """Points (n, 3) given in the frame of ``wrap``'s body, in the wrap object's own frame (m)."""
    rot = body_fixed_xyz(wrap.get_xyz_body_rotation().to_numpy())
    return (np.asarray(in_body, dtype=float) - wrap.get_translation().to_numpy()) @ rot


def wrap_runs(os_model: Any, state: Any, name: str) -> list[tuple[str, str, np.ndarray]]:
    """For each wrap on OpenSim's current path of the path force ``name`` in realised ``state``:
    (wrap object name, its class name, (4, 3) the points before and after it and its first and
    last contact, in the wrap object's frame, m)."""
    opensim = runtime.opensim()
    current = runtime.geometry_path(os_model, name).getCurrentPath(state)
    ground = os_model.getGround()
    out = []
    for k in range(1, current.getSize() - 2):
        first = opensim.PathWrapPoint.safeDownCast(current.get(k))
        last = opensim.PathWrapPoint.safeDownCast(current.get(k + 1))
        if first is None or last is None or first.getWrapObject().getName() != last.getWrapObject().getName():
            continue
        wrap = first.getWrapObject()
        in_body = [ground.findStationLocationInAnotherFrame(state, current.get(j).getLocationInGround(state),
                                                            wrap.getFrame()).to_numpy()
                   for j in (k - 1, k, k + 1, k + 2)]
        out.append((wrap.getName(), wrap.getConcreteClassName(), _in_wrap_frame(wrap, np.array(in_body))))
    return out


def current_path_points(os_model: Any, state: Any, name: str) -> list[tuple[str, str | None, np.ndarray]]:
    """OpenSim's current path of the path force ``name`` in realised ``state``: (point name, wrap
    object name or None for a path point, ground position (3,) m, OpenSim's Y-up ground)."""
    opensim = runtime.opensim()
    current = runtime.geometry_path(os_model, name).getCurrentPath(state)
    out = []
    for k in range(current.getSize()):
        pw = opensim.PathWrapPoint.safeDownCast(current.get(k))
        out.append((current.get(k).getName(), pw.getWrapObject().getName() if pw is not None else None,
                    current.get(k).getLocationInGround(state).to_numpy()))
    return out


def _path_test(pair: ModelPair, values: Mapping[str, float], muscles: Sequence[int], lengths: np.ndarray | None,
               test: str, find: Callable[[Any, Any, str], dict[str, Any] | None]) -> dict[int, dict[str, Any]]:
    """Muscle index -> {"test": ``test``, what ``find(os_model, state, name)`` found, "length" (m)}
    for each of ``muscles`` (indices into ``pair.matched``) whose OpenSim path at the pose of
    independent ``values`` ``find`` flags (``lengths``: OpenSim's, read again where None)."""
    out: dict[int, dict[str, Any]] = {}
    if not len(muscles):
        return out
    state = pair.os_state(values)
    for i in muscles:
        name, _, force = pair.matched[int(i)]
        found = find(pair.os_model, state, name)
        if found is not None:
            length = float(lengths[int(i)]) if lengths is not None else float(force.getLength(state))
            out[int(i)] = {"test": test, **found, "length": length}
    return out


def _detour(os_model: Any, state: Any, name: str) -> dict[str, Any] | None:
    return path_detour(current_path_points(os_model, state, name))


def _loop(os_model: Any, state: Any, name: str) -> dict[str, Any] | None:
    return path_loop(wrap_runs(os_model, state, name))


def _winding(os_model: Any, state: Any, name: str) -> dict[str, Any] | None:
    return path_winding(wrap_arcs(os_model, state, name))


def opensim_detours(pair: ModelPair, values: Mapping[str, float], muscles: Sequence[int],
                    lengths: np.ndarray | None = None) -> dict[int, dict[str, Any]]:
    """The muscles (indices into ``pair.matched``) whose OpenSim path at the pose of independent
    ``values`` makes a detour (:func:`path_detour`): muscle index -> {"test": "detour", "wrap",
    "segment", "beyond", "length" (m)}."""
    return _path_test(pair, values, muscles, lengths, "detour", _detour)


def opensim_loops(pair: ModelPair, values: Mapping[str, float], muscles: Sequence[int],
                  lengths: np.ndarray | None = None) -> dict[int, dict[str, Any]]:
    """The muscles (indices into ``pair.matched``) whose OpenSim path at the pose of independent
    ``values`` loops round a wrap (:func:`path_loop`): muscle index -> {"test": "loop", "wrap",
    "kind", "length" (m)}."""
    return _path_test(pair, values, muscles, lengths, "loop", _loop)


def opensim_windings(pair: ModelPair, values: Mapping[str, float], muscles: Sequence[int],
                     lengths: np.ndarray | None = None) -> dict[int, dict[str, Any]]:
    """The muscles (indices into ``pair.matched``) whose OpenSim path at the pose of independent
    ``values`` winds round a wrap (:func:`path_winding`): muscle index -> {"test": "winding",
    "wrap", "kind", "turn" (radians), "length" (m)}."""
    return _path_test(pair, values, muscles, lengths, "winding", _winding)


def drawn_length(os_model: Any, state: Any, name: str) -> float:
    """Length (m) of the path OpenSim draws for the path force ``name`` in realised ``state``: its
    current path points joined straight, through the points of each wrap arc (``getWrapPath``, in
    the wrap's body frame). Where OpenSim's ``getLength`` is consistent it is this to the arcs'
    chords (0.2 mm on MoBL-ARMS's SUP)."""
    opensim = runtime.opensim()
    current = runtime.geometry_path(os_model, name).getCurrentPath(state)
    pts = []
    for k in range(current.getSize()):
        wrap_point = opensim.PathWrapPoint.safeDownCast(current.get(k))
        if wrap_point is not None:
            arc, body = wrap_point.getWrapPath(state), wrap_point.getParentFrame()
            pts += [body.findStationLocationInGround(state, arc.get(j)).to_numpy() for j in range(arc.getSize())]
        pts.append(current.get(k).getLocationInGround(state).to_numpy())
    return float(np.linalg.norm(np.diff(np.array(pts), axis=0), axis=1).sum()) if len(pts) > 1 else 0.0


def wrap_contacts(pair: Any, state: Any, tendon: str, wraps: set[str]) -> dict[str, list[np.ndarray]]:
    """OpenSim's wrap-arc points (in the wrap object's body frame) of ``tendon`` on each of ``wraps``."""
    opensim = runtime.opensim()
    out: dict[str, list[np.ndarray]] = {}
    cp = pair.force(tendon).getGeometryPath().getCurrentPath(state)
    for i in range(cp.getSize()):
        pw = opensim.PathWrapPoint.safeDownCast(cp.get(i))
        if pw is None or pw.getWrapObject().getName() not in wraps:
            continue
        arc = pw.getWrapPath(state)
        out.setdefault(pw.getWrapObject().getName(), []).extend(arc.get(k).to_numpy() for k in range(arc.getSize()))
    return out


def opensim_inconsistencies(pair: ModelPair, values: Mapping[str, float], muscles: Sequence[int],
                            lengths: np.ndarray | None = None) -> dict[int, dict[str, Any]]:
    """The muscles (indices into ``pair.matched``) whose OpenSim length at the pose of independent
    ``values`` is not that of the path it draws (:func:`drawn_length`) by more than
    :data:`BAND_FRACTION` of it: OpenSim's wrap iterations over several wraps on one segment can
    keep an arc length from an earlier iteration (MoBL-ARMS's CORB: 183.7 mm for a drawn path of
    253.6 mm). No tendon has a length other than that of its path. Muscle index -> {"test":
    "inconsistent", "length", "drawn" (m)}."""
    out: dict[int, dict[str, Any]] = {}
    if not len(muscles):
        return out
    state = pair.os_state(values)
    for i in muscles:
        name, _, force = pair.matched[int(i)]
        length = float(lengths[int(i)]) if lengths is not None else float(force.getLength(state))
        found = length_inconsistency(pair.os_model, state, name, length)
        if found is not None:
            out[int(i)] = found
    return out


def length_inconsistency(os_model: Any, state: Any, name: str, length: float) -> dict[str, Any] | None:
    """{"test": "inconsistent", "length", "drawn" (m)} where OpenSim's ``length`` of the path
    force ``name`` in realised ``state`` differs from that of the path it draws
    (:func:`drawn_length`) by over :data:`BAND_FRACTION` of it, else None."""
    drawn = drawn_length(os_model, state, name)
    if abs(drawn - length) > BAND_FRACTION * abs(length):
        return {"test": "inconsistent", "length": float(length), "drawn": drawn}
    return None


def path_failure(os_model: Any, state: Any, name: str) -> dict[str, Any] | None:
    """How OpenSim's path of the path force ``name`` in realised ``state`` fails as a path, the
    tests of :func:`opensim_failures` that look at the path it draws: {"test": "detour" | "loop" |
    "winding", and what the test found}, or None. A length that is not that of its drawn path is
    left to :func:`opensim_inconsistencies`: it can still be continuous with its neighbours'
    (Arm26's TRIlong over its two wraps, drawn 8 % longer at shoulder elevation 1.96-2.03 rad)."""
    for test, find in (("detour", _detour), ("loop", _loop), ("winding", _winding)):
        found = find(os_model, state, name)
        if found is not None:
            return {"test": test, **found}
    return None


def unfair_path(os_model: Any, state: Any, name: str, length: float) -> dict[str, Any] | None:
    """:func:`path_failure`, else :func:`length_inconsistency` of OpenSim's ``length`` (m): why
    OpenSim's path of the path force ``name`` in realised ``state`` is no fair test of a tendon
    (no tendon has that length), or None."""
    return path_failure(os_model, state, name) or length_inconsistency(os_model, state, name, length)


def opensim_failures(pair: ModelPair, values: Mapping[str, float], muscles: Sequence[int],
                     lengths: np.ndarray | None = None, banded: Sequence[int] = ()) -> dict[int, dict[str, Any]]:
    """:func:`opensim_spikes`, and for the ``banded`` muscles it does not flag,
    :func:`opensim_detours`, :func:`opensim_loops`, :func:`opensim_windings` and
    :func:`opensim_inconsistencies`: every (muscle, pose) sample that is no fair test of a
    converted path."""
    out = opensim_spikes(pair, values, muscles, lengths, banded)
    for test in (opensim_detours, opensim_loops, opensim_windings, opensim_inconsistencies):
        rest = [int(i) for i in banded if int(i) not in out]
        out.update(test(pair, values, rest, lengths) if rest else {})
    return out


def _spanned_coordinates(pair: ModelPair, muscles: Sequence[int]) -> list[Any]:
    """The independent OpenSim coordinates (in ``pair.indep`` order) that any of ``muscles``
    (indices into ``pair.matched``) spans (:meth:`ModelPair.spanned`): no other coordinate moves
    their lengths, so only these can show a spike (each costs two OpenSim assemblies)."""
    spans = pair.spanned()
    wanted = set().union(*(spans.get(pair.matched[int(i)][0], set()) for i in muscles))
    return [c for c in pair.indep if pair.name(c) in wanted]


def _neighbours(pair: ModelPair, values: Mapping[str, float], name: str,
                h: float) -> tuple[np.ndarray | None, np.ndarray | None]:
    """OpenSim's lengths with coordinate ``name`` moved by ``+h`` and ``-h`` (None where it fails)."""
    try:
        up = pair.os_lengths(pair.os_state({**values, name: values[name] + h}))
        dn = pair.os_lengths(pair.os_state({**values, name: values[name] - h}))
    except Exception:
        return None, None
    return up, dn


def _evidence(coordinate: str, step: float, length: float, down: float, up: float) -> dict[str, Any]:
    return {"coordinate": coordinate, "step": float(step), "length": float(length),
            "neighbours": [float(down), float(up)]}
