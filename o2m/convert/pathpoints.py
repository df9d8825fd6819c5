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

    def location_at(self, point: PathPoint, values: dict[str, float]) -> np.ndarray:
        """Location (3,) of ``point`` in its body frame when the coordinates have ``values``."""
        loc = point.location.copy()
        for i, (cname, fn) in point.moving.items():
            ref = float(fn(np.array([self.b.ref[cname]]))[0])
            loc[i] += float(fn(np.array([values[cname]]))[0]) - ref
        return loc

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

    def straight_length(self, path: Path, k: int, drop: set[int] | frozenset[int] = frozenset()) -> float:
        """Length (m) of ``path`` at pose sample ``k`` with its active points (but those in
        ``drop``) joined straight (a lower bound of OpenSim's length, which wrapping only lengthens)."""
        values = self.pose_samples()[k][1]
        frames = self.sample_frames(k)
        pts = [frames[p.body].apply(self.location_at(p, values)) for i, p in enumerate(path.points)
               if i not in drop and self.active(p, values)]
        return float(sum(np.linalg.norm(b - a) for a, b in zip(pts[:-1], pts[1:], strict=True)))
