"""What the parts of a model's tendons share: the names taken, the geoms' exact values, and where
path points are in a pose.

A path point's location is in its OpenSim body's frame (metres); coordinate values are radians or
metres. MuJoCo places a frame of ground in its world, OpenSim's Y-up mapped to MuJoCo's Z-up.
"""

from __future__ import annotations

import numpy as np

from o2m.convert.builder import MjcfBuilder
from o2m.convert.records import unique_name
from o2m.osim.paths import Path, PathPoint
from o2m.transforms import OSIM_TO_MJ, Transform

#: Random poses (seeded, plus the reference pose) over which paths are measured: their same-body
#: segments (:mod:`o2m.convert.pathforces`) and their conditional points (:mod:`o2m.convert.conditional`).
POSE_SAMPLES = 200


class PathContext:
    """The state shared while a model's paths are added to an :class:`MjcfBuilder`'s spec."""

    def __init__(self, builder: MjcfBuilder):
        self.b = builder
        self.names: set[str] = set()
        #: Exact attribute values of the geoms added, by ("geom", name)
        #: (see :func:`o2m.convert.wraps.restore_geom_precision`).
        self.exact: dict[tuple[str, str], dict[str, np.ndarray]] = {}
        self._samples: list[tuple[dict[str, float], dict[str, float]]] | None = None
        self._frames: dict[int, dict[str, Transform]] = {}
        #: Each point's locations (P, 3) at the pose samples, by ``id(point)`` (the point kept
        #: beside them, so that its id stays its own).
        self._sample_locations: dict[int, tuple[PathPoint, np.ndarray]] = {}
        #: Frames at the first pose samples with a coordinate moved, by (coordinate, step, n).
        self._moved_frames: dict[tuple[str, float, int], list[dict[str, Transform]]] = {}
        #: Each location function's value at the reference pose, by ``id(function)`` (likewise).
        self._reference_offsets: dict[int, tuple[object, float]] = {}

    def unique(self, name: str) -> str:
        """``name``, or ``name_<k>`` when it is taken; taken from now on."""
        return unique_name(name, self.names)

    @staticmethod
    def in_world(body: str, x: Transform) -> Transform:
        """Frame ``x`` of ``body`` as MuJoCo places it in the body (ground: mapped to Z-up)."""
        return Transform(OSIM_TO_MJ) @ x if body == "ground" else x

    def fixed(self, coordinate: str) -> bool:
        """True when ``coordinate`` depends on a locked coordinate only."""
        return self.b.skel.coordinates[self.b.drivers[coordinate].base].locked

    def _reference_offset(self, cname: str, fn) -> float:
        """``fn`` (a location function of coordinate ``cname``) at the reference pose (m)."""
        key = id(fn)
        if key not in self._reference_offsets:
            self._reference_offsets[key] = (fn, float(fn(np.array([self.b.ref[cname]]))[0]))
        return self._reference_offsets[key][1]

    def location_at(self, point: PathPoint, values: dict[str, float]) -> np.ndarray:
        """Location (3,) of ``point`` in its body frame when the coordinates have ``values``."""
        return self.locations(point, {c: np.array([values[c]]) for c, _ in point.moving.values()}, 1)[0]

    def locations(self, point: PathPoint, values: dict[str, np.ndarray], n: int) -> np.ndarray:
        """Locations (n, 3) of ``point`` in its body frame at n poses, ``values`` each coordinate's
        (n,) values: :meth:`location_at` evaluated once per function over all n poses."""
        loc = np.tile(np.asarray(point.location, dtype=float), (n, 1))
        for i, (cname, fn) in point.moving.items():
            loc[:, i] += np.asarray(fn(values[cname]), dtype=float) - self._reference_offset(cname, fn)
        return loc

    def coordinate_arrays(self, bases: dict[str, np.ndarray], n: int) -> dict[str, np.ndarray]:
        """Every coordinate's values (n,) at n poses whose free independent coordinates have
        ``bases`` (each (n,)), the others at the reference pose: the builder's
        ``coordinate_values`` evaluated once per coordinate over all n poses."""
        base = {name: np.full(n, self.b.ref[name]) for name, d in self.b.drivers.items() if d.base == name}
        base.update(bases)
        return {name: np.asarray(d.fn(base[d.base]), dtype=float) for name, d in self.b.drivers.items()}

    def sample_bases(self) -> dict[str, np.ndarray]:
        """The free independent coordinates' values (P,) at the P pose samples (:meth:`pose_samples`);
        P = ``len(self.pose_samples())``."""
        samples = self.pose_samples()
        return {name: np.array([v[name] for v, _ in samples]) for name in samples[0][0]}

    def sample_locations(self, point: PathPoint) -> np.ndarray:
        """Locations (P, 3) of ``point`` in its body frame at the P pose samples (cached)."""
        key = id(point)
        if key not in self._sample_locations:
            samples = self.pose_samples()
            if point.moving:
                values = {c: np.array([v[c] for _, v in samples]) for c, _ in point.moving.values()}
                locs = self.locations(point, values, len(samples))
            else:
                locs = np.tile(np.asarray(point.location, dtype=float), (len(samples), 1))
            self._sample_locations[key] = (point, locs)
        return self._sample_locations[key][1]

    @staticmethod
    def active(point: PathPoint, values: dict[str, float]) -> bool:
        """Whether ``point`` is on its path when the coordinates have ``values`` (always, unless conditional)."""
        if point.condition is None:
            return True
        cname, lo, hi = point.condition
        return lo <= values[cname] <= hi

    def pose_samples(self) -> list[tuple[dict[str, float], dict[str, float]]]:
        """(independent values, every coordinate's value) of the reference pose and of
        :data:`POSE_SAMPLES` random poses (seed 0) with every free coordinate uniform in its range."""
        if self._samples is None:
            b = self.b
            rng = np.random.default_rng(0)
            free = [n for n, d in b.drivers.items() if d.base == n and not self.fixed(n)]
            ranges = [b.fit_range(n, b.coord_joint[n][1].kind if n in b.coord_joint else "rotation") for n in free]
            bases = [{n: b.ref[n] for n in free}]
            bases += [{n: float(rng.uniform(lo, hi)) for n, (lo, hi) in zip(free, ranges, strict=True)}
                      for _ in range(POSE_SAMPLES)]
            self._samples = [(v, b.coordinate_values(v)) for v in bases]
        return self._samples

    def sample_frames(self, k: int) -> dict[str, Transform]:
        """Each body's frame in OpenSim ground at pose sample ``k``."""
        if k not in self._frames:
            self._frames[k] = self.b.ground_frames_at(self.pose_samples()[k][1])
        return self._frames[k]

    def moved_frames(self, coordinate: str, step: float, n: int) -> list[dict[str, Transform]]:
        """Each body's frame in OpenSim ground at each of the first ``n`` pose samples with
        independent ``coordinate`` moved by ``step`` (rad or m; cached)."""
        key = (coordinate, step, n)
        if key not in self._moved_frames:
            self._moved_frames[key] = [
                self.b.ground_frames_at(self.b.coordinate_values({**base, coordinate: base[coordinate] + step}))
                for base, _ in self.pose_samples()[:n]]
        return self._moved_frames[key]

    def straight_length(self, path: Path, k: int, drop: set[int] | frozenset[int] = frozenset()) -> float:
        """Length (m) of ``path`` at pose sample ``k`` with its active points (but those in
        ``drop``) joined straight (a lower bound of OpenSim's length, which wrapping only lengthens)."""
        values = self.pose_samples()[k][1]
        frames = self.sample_frames(k)
        pts = [frames[p.body].apply(self.sample_locations(p)[k]) for i, p in enumerate(path.points)
               if i not in drop and self.active(p, values)]
        return float(sum(np.linalg.norm(b - a) for a, b in zip(pts[:-1], pts[1:], strict=True)))
