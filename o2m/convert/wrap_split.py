"""Splitting a path segment that several wrap objects act on, so MuJoCo wraps each of them.

MuJoCo wraps at most one geom between two sites; OpenSim can wrap one segment over several
objects (MoBL-ARMS's TMAJ and LAT1-3 over TMAJ_LAThum, LAT_TMAJhh and LAT_TMAJ2hh). Where
:mod:`o2m.convert.lengthvia` does not apply (more than one coordinate moves the segment's ends
apart, or an end moves), the segment is split: between each two consecutive wraps a fixed via
point goes where OpenSim's path runs from one wrap to the next, so each wrap gets a segment of its
own (its ``range`` narrowed to it, later wraps' ranges shifted).

* Order of the wraps along the segment: the order OpenSim's current path touches them over
  sampled poses (mean rank); a wrap never touched goes by where its centre projects on the
  segment at the reference pose.
* Via point: the midpoint of OpenSim's straight run from one wrap's last contact point to the
  next one's first, over the sampled poses where both are touched, in the frame of the body
  (either wrap's, or either end point's) in which those midpoints scatter least (their mean
  there). Where the two are never touched together, the point of the straight segment nearest
  the two wraps' centres, at the reference pose, on the first wrap's body.

A via point forces the path through it also where OpenSim's path leaves one of the wraps (then
straight) alone; the wrap fit (:mod:`o2m.convert.wrapfit`) fits the geoms around it, fits each
contiguous run of the wraps alone too and keeps the one nearest OpenSim
(:mod:`o2m.convert.wrap_choice`; without the fit every wrap touched is kept), and each
split is recorded with the via points' scatter (how far OpenSim's path runs from them where both
wraps act).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from o2m.convert.builder import MjcfBuilder
from o2m.convert.lengthvia import shared_segments
from o2m.convert.records import Approximation
from o2m.convert.wraps import wrap_segments
from o2m.osim import runtime
from o2m.osim.couplers import coupler_chain, satisfy_constraints
from o2m.osim.paths import Path, PathPoint, WrapObject
from o2m.transforms import Transform

#: Random poses (besides the reference pose) over which OpenSim's path is read for each split.
SPLIT_POSES = 24


@dataclass
class WrapSplit:
    """One split segment: the path, its end points, the wraps in path order, and per via point its
    body, location in that body's frame (m) and scatter (RMS distance, m, of OpenSim's between-wrap
    midpoints from it over the ``together`` poses where both neighbouring wraps act)."""

    path: str
    points: tuple[str, str]
    wraps: list[str]
    bodies: list[str] = field(default_factory=list)
    locations: list[list[float]] = field(default_factory=list)
    scatter_mm: list[float] = field(default_factory=list)
    together: list[int] = field(default_factory=list)
    sites: list[str] = field(default_factory=list)  # the via points' names (their MuJoCo sites')
    dropped: list[str] = field(default_factory=list)  # wraps left out: never touched, or alternatives
    order: list[str] = field(default_factory=list)  # every wrap of the segment, in path order
    touched: list[int] = field(default_factory=list)  # poses OpenSim touches each of ``order`` at
    n_poses: int = 0  # poses sampled (the reference pose and the random ones that assembled)
    #: the report's entry for this split, rewritten by :func:`describe_kept` once the wrap fit has
    #: chosen which wraps the tendon keeps
    approximation: Approximation | None = field(default=None, repr=False, compare=False)


class _OpenSimPaths:
    """OpenSim's model at the reference pose and at seeded random poses (realised states)."""

    def __init__(self, osim_path: str, n_poses: int, seed: int = 0):
        self.model, state0 = runtime.load_model(osim_path, 1e-12)
        self.opensim = runtime.opensim()
        self.states = [state0]
        rng = np.random.default_rng(seed)
        cs = self.model.getCoordinateSet()
        free = [cs.get(i) for i in range(cs.getSize()) if not runtime.is_held(cs.get(i), state0)
                and not cs.get(i).isDependent(state0)]
        couplers = coupler_chain(self.model, state0)
        for _ in range(n_poses):
            st = self.opensim.State(state0)
            for c in free:
                lo, hi = runtime.sample_bounds(c)
                c.setValue(st, float(rng.uniform(lo, hi)), False)
            try:
                satisfy_constraints(self.model, couplers, st)
                self.model.realizePosition(st)
            except Exception:  # an assembly failure: a pose fewer
                continue
            self.states.append(st)

    def frame(self, body: str):
        if body == self.model.getGround().getName():
            return self.model.getGround()
        return self.model.getComponent(f"/bodyset/{body}")

    def in_body(self, state, point_ground: np.ndarray, body: str) -> np.ndarray:
        vec = self.opensim.Vec3(*[float(x) for x in point_ground])
        return self.model.getGround().findStationLocationInAnotherFrame(state, vec, self.frame(body)).to_numpy()

    def contacts(self, state, owner: str, a: str, b: str) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """The wraps OpenSim's path of ``owner`` touches between its points ``a`` and ``b``, in
        path order: (wrap name, first contact, last contact), ground frame (m)."""
        cp = runtime.geometry_path(self.model, owner).getCurrentPath(state)
        names = [cp.get(i).getName() for i in range(cp.getSize())]
        if a not in names or b not in names:
            return []
        out: list[tuple[str, np.ndarray, np.ndarray]] = []
        for i in range(names.index(a) + 1, names.index(b)):
            pw = self.opensim.PathWrapPoint.safeDownCast(cp.get(i))
            if pw is None:
                continue
            name = pw.getWrapObject().getName()
            p = cp.get(i).getLocationInGround(state).to_numpy()
            if out and out[-1][0] == name:
                out[-1] = (name, out[-1][1], p)
            else:
                out.append((name, p, p))
        return out


    def wrapped_segments(self, state, path: Path) -> dict[str, int]:
        """Wrap name -> the segment of ``path`` (0-based, between its points k and k+1) OpenSim's
        current path wraps it on in ``state``."""
        cp = runtime.geometry_path(self.model, path.owner).getCurrentPath(state)
        index = {p.name: k for k, p in enumerate(path.points)}
        out: dict[str, int] = {}
        last = None
        for i in range(cp.getSize()):
            pw = self.opensim.PathWrapPoint.safeDownCast(cp.get(i))
            if pw is None:
                last = index.get(cp.get(i).getName(), last)
            elif last is not None:
                out.setdefault(pw.getWrapObject().getName(), last)
        return out


def narrow_wrap_ranges(builder: MjcfBuilder, paths: list[Path], wraps: dict[str, WrapObject], osim_path: str,
                       n_poses: int = SPLIT_POSES) -> dict[str, dict[str, int]]:
    """Narrow the ``range`` of every wrap that may act on several segments of its path to the one
    OpenSim wraps it on most often over the sampled poses (OpenSim picks, per pose, the segment
    it intersects, else the one it lengthens least; the reference pose's nearest segment need not
    be it: MoBL-ARMS's SUP is wrapped on SUP-P2-P3, not on the nearer SUP-P1-P2). In place;
    returns path -> wrap -> the segment chosen, for the wraps whose range changed."""
    multi = []
    for path in paths:
        n = len(path.points)
        for pw in path.wraps:
            wrap = wraps.get(pw.wrap)
            lo, hi = wrap_segments(pw.range, n)
            if wrap is not None and wrap.active and hi > lo:
                multi.append((path, pw))
    if not multi:
        return {}
    os_paths = _OpenSimPaths(osim_path, n_poses)
    used: dict[str, list[dict[str, int]]] = {}
    out: dict[str, dict[str, int]] = {}
    for path, pw in multi:
        if path.owner not in used:
            used[path.owner] = [os_paths.wrapped_segments(st, path) for st in os_paths.states]
        segs = [u[pw.wrap] for u in used[path.owner] if pw.wrap in u]
        if not segs:
            continue
        seg = int(np.bincount(segs).argmax())
        pw.range = (seg + 1, seg + 2)
        out.setdefault(path.owner, {})[pw.wrap] = seg
        builder.result.notes.append(
            f"{path.owner}: wrap object '{pw.wrap}' on segment {path.points[seg].name}-{path.points[seg + 1].name}, "
            f"where OpenSim wraps it at {segs.count(seg)} of the {len(segs)} sampled poses it wraps it at all")
    return out


def _order(names: list[str], seen: list[list[str]], centre_t: dict[str, float]) -> list[str]:
    """``names`` in path order: mean rank where OpenSim touches them, else their centre's
    position along the segment (``centre_t``, 0 at its first point, 1 at its second)."""
    def key(n: str) -> tuple[float, float]:
        ranks = [s.index(n) / max(len(s) - 1, 1) for s in seen if n in s]
        return (float(np.mean(ranks)) if ranks else centre_t[n], centre_t[n])
    return sorted(names, key=key)


def _via(os_paths: _OpenSimPaths, path: Path, seg: int, first: WrapObject, second: WrapObject,
         runs: list[tuple[object, np.ndarray]], fallback_ground: np.ndarray) -> tuple[str, np.ndarray, float]:
    """Body, location in its frame and scatter (m) of the via point between ``first`` and
    ``second`` from OpenSim's between-wrap midpoints ``runs`` ((state, ground point))."""
    a, b = path.points[seg], path.points[seg + 1]
    if not runs:
        return first.body, os_paths.in_body(os_paths.states[0], fallback_ground, first.body), float("nan")
    best = None
    for body in dict.fromkeys([first.body, second.body, a.body, b.body]):
        local = np.array([os_paths.in_body(st, p, body) for st, p in runs])
        mean = local.mean(axis=0)
        scatter = float(np.sqrt(np.mean(np.sum((local - mean) ** 2, axis=1))))
        if best is None or scatter < best[2]:
            best = (body, mean, scatter)
    return best


def _keep(order: list[str], seen: list[list[str]]) -> list[str]:
    """The wraps (in path order) given a segment of their own: those OpenSim touches at some
    sampled pose. Which of them the tendon keeps is then chosen by measured error
    (:mod:`o2m.convert.wrap_choice`): a via point between two wraps OpenSim touches together at
    few poses bends the path where OpenSim keeps it straight (MoBL-ARMS's TMAJ, together at 4 of
    22: 27 % alone, 63 % split), while one between two it touches together often pays (INFSP:
    2.5 % split, 22 % alone)."""
    return [n for n in order if any(n in s for s in seen)]


def split_path(os_paths: _OpenSimPaths, builder: MjcfBuilder, path: Path, seg: int, names: list[str],
               wraps: dict[str, WrapObject]) -> WrapSplit | None:
    """Split segment ``seg`` of ``path`` for the wraps ``names`` (in place: wraps OpenSim never
    touches there or only as an alternative to a neighbour removed, via points inserted between
    the others, ranges narrowed and shifted); returns the record, or None (nothing changed) when
    OpenSim touches none of them at the sampled poses."""
    a, b = path.points[seg], path.points[seg + 1]
    ga = (builder.ground_frames[a.body] @ Transform(pos=a.location)).pos
    gb = (builder.ground_frames[b.body] @ Transform(pos=b.location)).pos
    ab = gb - ga
    centre_t = {n: float(np.clip(((builder.ground_frames[wraps[n].body] @ wraps[n].frame).pos - ga) @ ab
                                 / max(ab @ ab, 1e-18), 0.0, 1.0)) for n in names}
    per_state = [(st, os_paths.contacts(st, path.owner, a.name, b.name)) for st in os_paths.states]
    seen = [[c[0] for c in cs if c[0] in names] for _, cs in per_state]
    order = _order(names, seen, centre_t)
    kept = _keep(order, seen)
    if not kept:
        return None
    rec = WrapSplit(path.owner, (a.name, b.name), kept, dropped=[n for n in order if n not in kept],
                    order=order, touched=[sum(n in s for s in seen) for n in order])
    vias: list[PathPoint] = []
    for k in range(len(kept) - 1):
        first, second = wraps[kept[k]], wraps[kept[k + 1]]
        runs = []
        for st, cs in per_state:
            touched = {c[0]: c for c in cs}
            if first.name in touched and second.name in touched:
                runs.append((st, 0.5 * (touched[first.name][2] + touched[second.name][1])))
        t = 0.5 * (centre_t[first.name] + centre_t[second.name])
        fallback = _ground_point(os_paths, path, seg, t)  # OpenSim's ground frame, as its contact points
        body, loc, scatter = _via(os_paths, path, seg, first, second, runs, fallback)
        rec.bodies.append(body)
        rec.locations.append([float(x) for x in loc])
        rec.scatter_mm.append(1e3 * scatter)
        rec.together.append(len(runs))
        vias.append(PathPoint(f"{path.owner}-split{k + 1}_{a.name}", body, np.asarray(loc, dtype=float), a.element,
                              designed=True))
        rec.sites.append(vias[-1].name)
    n_new = len(vias)
    path.points[seg + 1:seg + 1] = vias
    path.wraps = [pw for pw in path.wraps if pw.wrap not in rec.dropped]
    for pw in path.wraps:
        if pw.wrap in kept:
            s = seg + kept.index(pw.wrap)  # its own sub-segment, 0-based
            pw.range = (s + 1, s + 2)
        else:
            lo, hi = pw.range
            pw.range = (lo + n_new * (lo > seg + 1), hi + n_new * (hi > seg + 1))
    return rec


def _ground_point(os_paths: _OpenSimPaths, path: Path, seg: int, t: float) -> np.ndarray:
    """The point at fraction ``t`` of OpenSim's straight segment ``seg`` of ``path`` at the
    reference pose (OpenSim ground frame, m)."""
    st = os_paths.states[0]
    pts = []
    for p in (path.points[seg], path.points[seg + 1]):
        vec = os_paths.opensim.Vec3(*[float(x) for x in p.location])
        pts.append(os_paths.frame(p.body).findStationLocationInGround(st, vec).to_numpy())
    return pts[0] + t * (pts[1] - pts[0])


def add_wrap_splits(builder: MjcfBuilder, paths: list[Path], wraps: dict[str, WrapObject], osim_path: str,
                    n_poses: int = SPLIT_POSES) -> list[WrapSplit]:
    """Split every segment that two or more active wraps share (after
    :func:`o2m.convert.lengthvia.add_length_vias`), in place in ``paths``; returns the records and
    adds an :class:`~o2m.convert.records.Approximation` for each."""
    todo = [(p, shared_segments(p, wraps, builder.ground_frames)) for p in paths]
    todo = [(p, s) for p, s in todo if s]
    if not todo:
        return []
    os_paths = _OpenSimPaths(osim_path, n_poses)
    out = []
    for path, shared in todo:
        for seg, names in sorted(shared.items(), reverse=True):  # last first: earlier indices stay valid
            rec = split_path(os_paths, builder, path, seg, names, wraps)
            if rec is None:
                continue
            rec.n_poses = len(os_paths.states)
            worst = max((x for x in rec.scatter_mm if np.isfinite(x)), default=0.0)
            rec.approximation = Approximation(
                "PathWrap", f"{path.owner}:{'+'.join(names)}", _describe(rec, rec.wraps, rec.sites),
                worst, "mm", "RMS distance of OpenSim's between-wrap run from the via point")
            builder.result.approximations.append(rec.approximation)
            out.append(rec)
    return out


def _describe(rec: WrapSplit, kept: list[str], sites: list[str]) -> str:
    """The report's words for split ``rec`` whose tendon keeps the wraps ``kept`` and the via
    points ``sites`` (of ``rec.wraps`` and ``rec.sites``)."""
    idx = [k for k, s in enumerate(rec.sites) if s in sites]
    if idx:
        scatter = ", ".join(f"{rec.scatter_mm[k]:.3g}" for k in idx)
        how = (f"split by {len(idx)} via point(s) on {', '.join(rec.bodies[k] for k in idx)} between "
               f"{' and '.join(kept)} (touched together at {', '.join(str(rec.together[k]) for k in idx)} poses; "
               f"OpenSim's path between them runs {scatter} mm RMS from them)")
    else:
        how = f"{' and '.join(kept) or 'no wrap'} kept, no via point"
    out = [f"wraps {', '.join(rec.order or rec.wraps)} share {rec.points[0]}-{rec.points[1]}: {how}"]
    alternatives = [w for w in rec.wraps if w not in kept]
    if alternatives:
        out.append(f"left out by the wrap fit (measured error): {', '.join(alternatives)}")
    if rec.dropped:
        counts = ", ".join(f"{n} {c}" for n, c in zip(rec.order, rec.touched, strict=True))
        out.append(f"left out (touched at {counts} of {rec.n_poses} poses): {', '.join(rec.dropped)}")
    return "; ".join(out)


def split_sites(splits: list[WrapSplit]) -> dict[str, list[str]]:
    """Path -> the via sites of all its splits, in path order of the records (a path may have
    several split segments; the wrap fit fits all their via sites)."""
    out: dict[str, list[str]] = {}
    for rec in splits:
        out.setdefault(rec.path, []).extend(rec.sites)
    return out


def describe_kept(splits: list[WrapSplit], dropped: dict[str, set[str]], geom_of: dict[tuple[str, str], str]) -> None:
    """Rewrite each split's report entry to say what its tendon finally keeps, given tendon -> the
    MuJoCo sites and geoms the wrap fit left out (``dropped``) and (tendon, OpenSim wrap) -> its
    MuJoCo geom (``geom_of``)."""
    for rec in splits:
        if rec.approximation is None:
            continue
        gone = dropped.get(rec.path, set())
        kept = [w for w in rec.wraps if geom_of.get((rec.path, w)) not in gone]
        rec.approximation.what = _describe(rec, kept, [s for s in rec.sites if s not in gone])


__all__ = ["SPLIT_POSES", "WrapSplit", "add_wrap_splits", "describe_kept", "narrow_wrap_ranges", "split_path",
           "split_sites"]
