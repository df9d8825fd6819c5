"""Path forces: the tendon as OpenSim's length or as OpenSim's force transmission (``path_forces``).

OpenSim 4.6 applies a path's tension only along segments whose two points are on different bodies
(``GeometryPath::addInEquivalentForces`` skips a segment on one body, and with it the generalized
force of a MovingPathPoint moving along it), while its ``getLength`` sums every segment. Where a
MovingPathPoint sits next to a point of its own body, OpenSim's dynamic moment arm
(``computeMomentArm``) is therefore not ``-dL/dq`` of its length. A MuJoCo tendon has one length
for both, so each such path chooses: ``"kinematic"`` (the tendon is OpenSim's length; its moment
arm is ``-dL/dq``) or ``"opensim"`` (the same-body segments become a MuJoCo pulley branch of
constant length, the midrange of their summed length over the sampled poses, so the tendon's
moment arm is OpenSim's ``computeMomentArm`` and its length OpenSim's within half the segments'
variation). ``"auto"`` (default) takes ``"opensim"`` for a path whose same-body segments vary by
at most :data:`PATH_FORCES_AUTO_VARIATION` of its length, else ``"kinematic"``. Each choice is
recorded with the length (mm) and moment-arm (mm) differences it implies
(:attr:`PathForces.records`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from o2m.convert.conditional import GEOM_ROLES
from o2m.convert.pathpoints import PathContext
from o2m.convert.records import Approximation
from o2m.osim.paths import Path, PathPoint
from o2m.transforms import Transform

#: The choices of ``path_forces`` (see the module notes).
PATH_FORCE_MODES = ("auto", "opensim", "kinematic")
#: ``path_forces="auto"``: a path's same-body MovingPathPoint segments are held constant
#: ("opensim") when their summed length varies (peak to peak, over the sampled poses) by at most
#: this fraction of the path's shortest length, so that the tendon length stays within half that
#: (1 %, the length target) of OpenSim's; else the tendon keeps them ("kinematic").
PATH_FORCES_AUTO_VARIATION = 0.02
#: Central-difference step (rad or m) of the moment-arm difference the two choices imply.
PATH_FORCE_FD_STEP = 1e-6


@dataclass
class PathForceRecord:
    """What ``path_forces`` chose for one path with same-body MovingPathPoint segments.

    ``segments``: the OpenSim point pairs (one body, at least one moving) OpenSim applies no
    tension along; ``mode``: ``"opensim"`` (held at ``held_length`` m in a pulley branch) or
    ``"kinematic"`` (kept in the tendon); ``variation_mm``/``variation_pct``: peak-to-peak change
    of their summed length over the sampled poses (percent of ``shortest_mm``, a lower bound of
    the path's length: its points joined straight); ``length_error_mm``/``length_error_pct``: the
    tendon length error the choice implies against OpenSim's ``getLength`` (half the variation for
    ``"opensim"``, 0 for ``"kinematic"``); ``moment_arm_mm``: per independent coordinate, the
    largest difference between ``computeMomentArm`` and ``-dL/dq`` that the segments cause: the
    moment-arm error against ``computeMomentArm`` for ``"kinematic"`` and against ``-dL/dq`` for
    ``"opensim"``; ``blocked``: same-body segments kept because a wrap or conditional point of
    another body acts on them."""

    path: str
    kind: str
    mode: str
    requested: str
    segments: list[tuple[str, str]]
    held_length: float
    variation_mm: float
    variation_pct: float
    shortest_mm: float
    length_error_mm: float
    length_error_pct: float
    moment_arm_mm: dict[str, float]
    blocked: list[tuple[str, str]]


class PathForces:
    """The ``path_forces`` choice of each path with same-body MovingPathPoint segments."""

    def __init__(self, ctx: PathContext, mode: str = "auto"):
        if mode not in PATH_FORCE_MODES:
            raise ValueError(f"path_forces must be one of {', '.join(PATH_FORCE_MODES)}, not {mode!r}")
        self.ctx = ctx
        self.b = ctx.b
        self.mode = mode
        #: One :class:`PathForceRecord` per path with same-body MovingPathPoint segments.
        self.records: list[PathForceRecord] = []
        #: Paths whose same-body segments are held ("opensim"): name -> {"pairs": [(OpenSim point,
        #: point)], "length": held length (m)}, for :mod:`o2m.convert.wrapfit`'s targets.
        self.held: dict[str, dict] = {}

    def _moves(self, point: PathPoint) -> bool:
        return any(not self.ctx.fixed(c) for c, _ in point.moving.values())

    def _candidates(self, path: Path, roles: list[str], site_point: list[int], planned: dict[int, tuple]
                    ) -> tuple[list[tuple[int, PathPoint, PathPoint]], list[tuple[str, str]]]:
        """The site segments of ``path`` that may be held, (site segment, point, point), and the
        same-body segments kept because a wrap or conditional point of another body acts on them."""
        pts = path.points
        cands: list[tuple[int, PathPoint, PathPoint]] = []
        blocked: list[tuple[str, str]] = []
        for i in range(len(site_point) - 1):
            a, b = pts[site_point[i]], pts[site_point[i + 1]]
            if a.body != b.body or not (self._moves(a) or self._moves(b)) or a.designed or b.designed:
                continue  # (a designed point stands for OpenSim's wraps there, whose forces act)
            others = [pts[k].name for k in range(site_point[i] + 1, site_point[i + 1])
                      if roles[k] in GEOM_ROLES and pts[k].body != a.body]
            item = planned.get(i)
            if item is not None and item[0] == "wrap" and item[1].body != a.body:
                others.append(item[1].name)
            if others:
                blocked.append((a.name, b.name))
                self.b.result.notes.append(f"{path.owner}: same-body segment {a.name}-{b.name} kept in the tendon "
                                           f"({', '.join(others)} of another body acts on it)")
            else:
                cands.append((i, a, b))
        return cands, blocked

    def plan(self, path: Path, roles: list[str], site_point: list[int],
             planned: dict[int, tuple]) -> tuple[list[int], float]:
        """The site segments of ``path`` to leave out of its tendon (``path_forces``) and the
        length (m) to hold them at; records the choice (:class:`PathForceRecord`, an
        :class:`Approximation`). A candidate is a segment between two sites on one body, one of
        them a moving point, that no wrap or conditional point of another body acts on."""
        cands, blocked = self._candidates(path, roles, site_point, planned)
        if not cands:
            return [], 0.0
        ctx = self.ctx
        samples = ctx.pose_samples()

        def held(values: dict[str, np.ndarray]) -> np.ndarray:
            """Summed length (P,) of the candidate segments at P poses (each coordinate's values (P,))."""
            return sum(np.linalg.norm(ctx.locations(a, values, n) - ctx.locations(b, values, n), axis=1)
                       for _, a, b in cands)

        bases, n = ctx.sample_bases(), len(samples)
        lengths = held(ctx.coordinate_arrays(bases, n))
        shortest = min(ctx.straight_length(path, k) for k in range(len(samples)))
        moved = sorted({self.b.drivers[c].base for _, a, b in cands for p in (a, b) for c, _ in p.moving.values()
                        if not ctx.fixed(c)})
        h = PATH_FORCE_FD_STEP
        arms = {}
        for c in moved:
            d = np.abs(held(ctx.coordinate_arrays({**bases, c: bases[c] + h}, n))
                       - held(ctx.coordinate_arrays({**bases, c: bases[c] - h}, n))) / (2 * h)
            arms[c] = float(max(d)) * 1e3
        variation = float(lengths.max() - lengths.min())
        pct = 100.0 * variation / max(shortest, 1e-12)
        mode = self.mode
        if mode == "auto":
            mode = "opensim" if variation <= PATH_FORCES_AUTO_VARIATION * shortest else "kinematic"
        c_held = 0.5 * float(lengths.max() + lengths.min())
        opensim = mode == "opensim"
        segs = [(a.name, b.name) for _, a, b in cands]
        held_frac = 0.5 if opensim else 0.0  # the length error: half the variation when held
        self.records.append(PathForceRecord(path.owner, path.owner_type, mode, self.mode, segs,
                                            c_held if opensim else 0.0, variation * 1e3, pct, shortest * 1e3,
                                            held_frac * variation * 1e3, held_frac * pct, arms, blocked))
        self._approximation(path, segs, arms, opensim, c_held, variation, pct)
        return ([i for i, _, _ in cands], c_held) if opensim else ([], 0.0)

    def _approximation(self, path: Path, segs: list[tuple[str, str]], arms: dict[str, float], opensim: bool,
                       c_held: float, variation: float, pct: float) -> None:
        """Record the choice made for ``path`` as an :class:`Approximation` (and its held segments)."""
        seg_txt = ", ".join(f"{a}-{b}" for a, b in segs)
        worst_arm = max(arms.values(), default=0.0)
        arm_txt = ", ".join(f"{v:.3g} mm ({c})" for c, v in arms.items())
        if opensim:
            self.held[path.owner] = {"pairs": segs, "length": c_held}
            self.b.result.approximations.append(Approximation(
                path.owner_type, path.owner,
                f"tendon is OpenSim's force transmission: same-body segment(s) {seg_txt} (OpenSim applies no "
                f"tension along them) held at {c_held * 1e3:.4g} mm in a pulley branch",
                0.5 * pct, "% of the path length (vs getLength)",
                f"length error up to {0.5 * variation * 1e3:.3g} mm; moment arm = computeMomentArm, differs from "
                f"OpenSim's -dL/dq by up to {arm_txt}"))
        else:
            self.b.result.approximations.append(Approximation(
                path.owner_type, path.owner,
                f"tendon is OpenSim's length, same-body segment(s) {seg_txt} included: its moment arm is -dL/dq, "
                f"not OpenSim's computeMomentArm (OpenSim applies no tension along them)",
                worst_arm, "mm moment arm (vs computeMomentArm)",
                f"by coordinate {arm_txt}; holding them would change the length by {pct:.3g} % peak to peak"
                + (f" (> {100 * PATH_FORCES_AUTO_VARIATION:g} %)" if self.mode == "auto" else "")))

    def held_branch(self, path: Path, a: PathPoint, b: PathPoint, length: float) -> list[str]:
        """Two sites on ``a``'s body, ``length`` apart along the segment a-b at the reference pose:
        a constant-length pulley branch standing for the segments held (drawn where they are)."""
        pa, pb = np.asarray(a.location, dtype=float), np.asarray(b.location, dtype=float)
        u = pb - pa
        u = u / np.linalg.norm(u) if np.linalg.norm(u) > 1e-12 else np.array([1.0, 0.0, 0.0])
        names = []
        for tag, loc in (("a", pa), ("b", pa + length * u)):
            name = self.ctx.unique(f"{path.owner}-held_{tag}")
            pos = self.ctx.in_world(a.body, Transform(pos=loc)).pos
            self.b.bodies[a.body].add_site(name=name, pos=pos, size=[0.001, 0, 0], group=5)
            self.b.exact[("site", name)] = {"pos": pos}
            names.append(name)
        return names
