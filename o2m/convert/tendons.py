"""Building MuJoCo spatial tendons and their actuators from OpenSim paths.

* A PathPoint is a site on its body.
* A MovingPathPoint is a site on a small child body that slides along its body's axes; each
  slide follows its coordinate through a joint equality (exact when the location function is
  linear, else a quartic fit whose worst error, of the location and of its derivative, the
  report records). A slide whose quartic leaves a derivative error (a moment-arm error) above
  :data:`CARRIER_SLOPE_GATE` RMS gets extra slides on its carrier along the same axis (inner and
  outer joints, as the skeleton's spline couplings: :meth:`TendonBuilder.plan_carriers`).
* A ConditionalPathPoint becomes a small wrap cylinder, its axis normal to the path's bend
  there, whose surface passes through the point, with a side site outside it (see
  :meth:`TendonBuilder.conditional_geom`). MuJoCo 4.0
  wraps a tendon round a geom whenever the straight segment cuts it *or passes on the side
  opposite the side site*, and then goes round on the side-site side; so the tendon is pulled
  through the point exactly while the point lies outside the straight line between its
  neighbours (OpenSim's via point makes the path bend there) and runs straight otherwise. The
  switch is geometric, depends on every coordinate, and leaves the length continuous (OpenSim's
  own length jumps where its coordinate leaves the range; the README gives by how much).
  Consecutive conditional points between the same two sites keep the one that bends the path
  most (MuJoCo needs a site between two wrap geoms); the report names the others.
* Wrap objects become wrap geoms, one per path that uses them (so :mod:`o2m.wrapfit` can fit
  each path's own): spheres and cylinders as they are; an ellipsoid as the sphere or cylinder
  nearest to it; a torus is left out. Each is placed on the path segment (within the wrap's
  OpenSim range) that passes closest to it at the reference pose, with a side site on the side
  that segment passes or that the quadrant names (MuJoCo 4.0: the tendon wraps the way the
  straight path through the side site goes).
* Path forces (``path_forces``). OpenSim 4.6 applies a path's tension only along segments whose
  two points are on different bodies (``GeometryPath::addInEquivalentForces`` skips a segment on
  one body, and with it the generalized force of a MovingPathPoint moving along it), while its
  ``getLength`` sums every segment. Where a MovingPathPoint sits next to a point of its own body,
  OpenSim's dynamic moment arm (``computeMomentArm``) is therefore not ``-dL/dq`` of its length.
  A MuJoCo tendon has one length for both, so each such path chooses: ``"kinematic"`` (the tendon
  is OpenSim's length; its moment arm is ``-dL/dq``) or ``"opensim"`` (the same-body segments
  become a MuJoCo pulley branch of constant length, the midrange of their summed length over the
  sampled poses, so the tendon's moment arm is OpenSim's ``computeMomentArm`` and its length
  OpenSim's within half the segments' variation). ``"auto"`` (default) takes ``"opensim"`` for
  a path whose same-body segments vary by at most :data:`PATH_FORCES_AUTO_VARIATION` of its
  length, else ``"kinematic"``. Each choice is recorded with the length and moment-arm
  differences it implies (:attr:`TendonBuilder.path_forces`).
* Each muscle becomes a MuJoCo muscle actuator on its tendon, named as the muscle.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from o2m.convert.builder import MAX_BODY_DOFS, Approximation, JointRecord, MjcfBuilder, _CoupledAxis, _linear, _relative
from o2m.osim.functions import fit_polynomial, polynomial_slope_errors
from o2m.osim.paths import MUSCLE_TYPES, Path, PathPoint, WrapObject
from o2m.transforms import OSIM_TO_MJ, Transform, matrix_to_quat

#: A path-point carrier body: mass (kg) and inertia (kg m²) just above what MuJoCo accepts, so the
#: model's mass and centre of mass stay OpenSim's. Armature (kg) on its slides, without adding body
#: mass, keeps a muscle's pull and its force-velocity damping (~1e4 N·s/m) from whipping the
#: carrier about its soft equality: on 16 MoBL-ARMS excitation sets, 1e-6 kg diverged within 3
#: steps and 1e-2 kg diverged in 5 sets, 0.1 kg in none. The inertia a carrier slide adds to its
#: coordinate, armature x (dx/dq)^2, is at most 1.3e-4 kg m^2 in MoBL-ARMS (dx/dq <= 0.037 m/rad).
CARRIER_MASS = 1e-12
CARRIER_INERTIA = 1e-14
CARRIER_ARMATURE = 0.1
#: Mass (kg) and inertia (kg m²) of a carrier on a body welded to the world (see
#: :meth:`TendonBuilder.weigh_static_carriers`): the armature's worth, so that MuJoCo's constraint
#: softness sees the inertia its slides have.
STATIC_CARRIER_MASS = CARRIER_ARMATURE
STATIC_CARRIER_INERTIA = 1e-6
#: A carrier slide whose location is a non-linear function of a coordinate follows it by a plain
#: quartic when that quartic's derivative error (d location / d coordinate: m/rad against an angle,
#: directly a moment-arm error along the slide) has an RMS over the coordinate's range (what the
#: issue's RMS over random poses sees) of at most this (m per coordinate unit): 2 mm/rad, the
#: issue's 95th-percentile moment-arm target, so the quartic alone cannot put a pair beyond it.
#: Measured (plain quartics): MoBL-ARMS's DELT2 1.13 mm/rad (0.88 mm RMS about shoulder_elv),
#: BIClong/BICshort 0.57, below it, kept; the knee extensors' patella emulation of the leg and gait
#: models 2.4-4.1 mm/rad (worst 8-20), above it. Those slides get extra joints instead (main
#: quartic, inner and outer joints, :func:`o2m.functions.fit_couplings`, derivative-aware), all the
#: carriers of one coordinate planned together (inner joints shared between carriers), each
#: carrier within MuJoCo's 6 dofs.
CARRIER_SLOPE_GATE = 2e-3
#: Target (m) of a carrier slide with extra joints: its joints are added while an axis misses it
#: and each brings a gain (:meth:`MjcfBuilder._plan_group`), within the carrier's 6 dofs.
CARRIER_TARGET = 1e-5
#: Derivative target (m per coordinate unit) of those fits, or None: minimax on the location only.
#: None, measured: these splines' curvature jumps at the knee's default angle (knots 0, 1.7e-4 and
#: 3.5e-4 rad), so a derivative-aware minimax (:func:`o2m.functions.fit_couplings`, slope targets)
#: spends the fit there and loses elsewhere: with 0.5 mm/rad (the issue's median moment-arm
#: target) Leg6Dof9Musc's moment-arm RMS p95 is 0.87 mm (0.77 at a 2e-5 m location target),
#: Gait10dof18musc's 0.53, against 0.50 and 0.51 mm fitted to the location alone, whose
#: derivative errors are 0.4-0.5 mm/rad RMS (1.8-2.8 mm/rad at worst, next to that knot).
CARRIER_SLOPE_TARGET: float | None = None
#: Distance of a side site from a wrap geom's centre, in radii.
SIDE_SITE_DISTANCE = 2.0
#: Radius (m) of the wrap sphere that stands for a ConditionalPathPoint: the tendon passes within
#: this of the point (exactly through it when it bends there as at the reference pose).
CONDITIONAL_RADIUS = 0.001
#: The choices of ``path_forces`` (see the module notes).
PATH_FORCE_MODES = ("auto", "opensim", "kinematic")
#: ``path_forces="auto"``: a path's same-body MovingPathPoint segments are held constant
#: ("opensim") when their summed length varies (peak to peak, over the sampled poses) by at most
#: this fraction of the path's shortest length, so that the tendon length stays within half that
#: (1 %, the length target) of OpenSim's; else the tendon keeps them ("kinematic").
PATH_FORCES_AUTO_VARIATION = 0.02
#: Random poses (seeded, plus the reference pose) over which a path's same-body segments are measured.
PATH_FORCE_POSES = 200
#: Central-difference step (rad or m) of the moment-arm difference the two choices imply.
PATH_FORCE_FD_STEP = 1e-6


@dataclass
class _PlacedWrap:
    segment: int  # the path segment (between points segment and segment+1) it wraps
    geom: str
    sidesite: str


@dataclass
class PathGeom:
    """A wrap geom of one tendon (MuJoCo names), for :mod:`o2m.wrapfit`: ``kind`` is the OpenSim
    element it stands for (``WrapSphere``, ``WrapCylinder`` or ``WrapEllipsoid``; a
    ConditionalPathPoint's sphere is not fitted), ``source`` its OpenSim name and ``body`` the OpenSim body it is on."""

    tendon: str
    geom: str
    sidesite: str
    kind: str
    source: str
    body: str = ""


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


class TendonBuilder:
    """Adds the paths of a skeleton to an :class:`MjcfBuilder`'s spec."""

    def __init__(self, builder: MjcfBuilder, wraps: dict[str, WrapObject], path_forces: str = "auto"):
        if path_forces not in PATH_FORCE_MODES:
            raise ValueError(f"path_forces must be one of {', '.join(PATH_FORCE_MODES)}, not {path_forces!r}")
        self.path_forces_mode = path_forces
        #: One :class:`PathForceRecord` per path with same-body MovingPathPoint segments.
        self.path_forces: list[PathForceRecord] = []
        #: Paths whose same-body segments are held ("opensim"): name -> {"pairs": [(OpenSim point,
        #: point)], "length": held length (m)}, for :mod:`o2m.wrapfit`'s targets.
        self.held: dict[str, dict] = {}
        self._samples: list[tuple[dict[str, float], dict[str, float]]] | None = None
        self._frames: dict[int, dict[str, Transform]] = {}
        self.b = builder
        self.spec = builder.spec
        self.wraps = wraps
        self.geoms: dict[str, str | None] = {}  # wrap object -> MuJoCo geom name (None: not converted)
        self.names: set[str] = set()
        #: Exact attribute values of the geoms added here, by ("geom", name) (see :func:`restore_geom_precision`).
        self.exact: dict[tuple[str, str], dict[str, np.ndarray]] = {}
        #: Every wrap geom of every tendon, in the order added.
        self.path_geoms: list[PathGeom] = []
        #: geom name -> (its frame in its OpenSim body, MuJoCo kind, radius)
        self.geom_frames: dict[str, tuple[Transform, str, float]] = {}
        #: Site names (by id of the PathPoint) and slide names (by (id, axis)) reserved by
        #: :meth:`plan_carriers` for carriers with extra joints.
        self._carrier_names: dict[int, str] = {}
        self._slide_names: dict[tuple[int, int], str] = {}
        #: Every carrier body added (see :meth:`weigh_static_carriers`).
        self.carriers: list = []

    def _unique(self, name: str) -> str:
        out, k = name, 1
        while out in self.names:
            out, k = f"{name}_{k}", k + 1
        self.names.add(out)
        return out

    def _in_world(self, body: str, x: Transform) -> Transform:
        """Frame ``x`` of ``body`` as MuJoCo places it in the body (ground: mapped to Z-up)."""
        return Transform(OSIM_TO_MJ) @ x if body == "ground" else x

    def _carrier(self, parent: str, name: str, pos: np.ndarray):
        """A massless child body of ``parent`` at ``pos`` (MuJoCo frame of the parent), named
        ``name`` (made unique), to carry a moving point or a conditional point's side site."""
        body = self.b.bodies[parent].add_body(name=self._unique(name), pos=pos)
        self.b.exact[("body", body.name)] = {"pos": pos, "quat": np.array([1.0, 0, 0, 0])}
        body.explicitinertial = True
        body.mass = CARRIER_MASS
        body.fullinertia = [CARRIER_INERTIA, CARRIER_INERTIA, CARRIER_INERTIA, 0, 0, 0]
        self.b.exact[("inertial", body.name)] = {"pos": np.zeros(3), "mass": CARRIER_MASS,
                                                 "fullinertia": np.array(body.fullinertia)}
        self.carriers.append(body)
        return body

    def weigh_static_carriers(self, model: mujoco.MjModel) -> list[str]:
        """Give every carrier on a body welded to the world (``model``: the compiled spec) the
        mass :data:`STATIC_CARRIER_MASS`, its weight cancelled (``gravcomp`` 1); returns their names.

        Why: MuJoCo scales a constraint's softness by the inverse inertia of its degrees of
        freedom at ``qpos0`` (``dof_invweight0``), and for slides on a body welded to the world
        it takes that from the body's mass alone, not its armature (measured, MuJoCo 4.0: a 1e-12
        kg carrier there gets 1e12, one on a moving body 1/armature = 10). Its joint equalities
        then apply no force: MoBL-ARMS's PECM and LAT carriers, on the thorax, were left behind by
        their coordinates by up to 51 mm in 1 s of random excitation. With the mass they follow;
        their parent does not move, so the mass changes nothing else, and gravcomp keeps its
        weight off the coordinates."""
        out = []
        for body in self.carriers:
            bid = model.body(body.name).id
            if model.body_weldid[model.body_parentid[bid]] != 0:
                continue
            body.mass = STATIC_CARRIER_MASS
            body.fullinertia = [STATIC_CARRIER_INERTIA] * 3 + [0, 0, 0]
            body.gravcomp = 1.0
            self.b.exact[("inertial", body.name)] = {"pos": np.zeros(3), "mass": STATIC_CARRIER_MASS,
                                                     "fullinertia": np.array(body.fullinertia)}
            out.append(body.name)
        return out

    # -- points --------------------------------------------------------------------------
    def location_at(self, point: PathPoint, values: dict[str, float]) -> np.ndarray:
        """Location (3,) of ``point`` in its body frame when the coordinates have ``values``."""
        loc = point.location.copy()
        for i, (cname, fn) in point.moving.items():
            ref = float(fn(np.array([self.b.ref[cname]]))[0])
            loc[i] += float(fn(np.array([values[cname]]))[0]) - ref
        return loc

    def _active(self, point: PathPoint, values: dict[str, float]) -> bool:
        if point.condition is None:
            return True
        cname, lo, hi = point.condition
        return lo <= values[cname] <= hi

    def _reference_active_values(self, point: PathPoint) -> dict[str, float]:
        """Coordinate values at the reference pose, with a conditional point's coordinate moved
        into the point's active range when it is outside it (to the middle of the part of that
        range inside the coordinate's range)."""
        cname, lo, hi = point.condition
        if lo <= self.b.ref[cname] <= hi:
            return self.b.coordinate_values()
        base = self.b.drivers[cname].base
        kind = self.b.coord_joint[base][1].kind if base in self.b.coord_joint else "rotation"
        rlo, rhi = self.b.fit_range(base, kind)
        a, b = max(lo, rlo), min(hi, rhi)
        return self.b.coordinate_values({base: 0.5 * (a + b) if a <= b else 0.5 * (lo + hi)})

    def _bend(self, path: Path, k: int, values: dict[str, float], keep: list[bool]
              ) -> tuple[np.ndarray, float, np.ndarray]:
        """Unit direction (ground) from the straight segment between the kept neighbours of point
        ``k`` to the point, the length (m) the point adds to the path, in pose ``values``, and
        the unit direction of that segment."""
        pts = path.points
        frames = self.b.ground_frames_at(values)

        def world(p: PathPoint) -> np.ndarray:
            return frames[p.body].apply(self.location_at(p, values))

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

    def conditional_roles(self, path: Path) -> list[str]:
        """For each point of ``path``: ``"site"`` (always on the path), ``"conditional"`` (a
        ConditionalPathPoint made a wrap cylinder) or ``"dropped"`` (a conditional point left out:
        its coordinate is locked outside its range, or it is not the one of a run of consecutive
        conditional points that bends the path most). First and last points stay sites."""
        pts = path.points
        roles = []
        for i, p in enumerate(pts):
            if p.condition is None or i in (0, len(pts) - 1):
                if p.condition is not None:
                    self.b.result.notes.append(f"{path.owner}: ConditionalPathPoint '{p.name}' ends the path; "
                                               f"kept always active")
                roles.append("site")
            elif self._fixed(p.condition[0]):
                roles.append("site" if self._active(p, self.b.coordinate_values()) else "dropped")
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
                    errs.append(max(abs(self._straight_length(path, n, drop) / self._straight_length(path, n) - 1.0)
                                    for n in range(len(self._pose_samples()))))
                best = i + int(np.argmin(errs))
                for k in range(i, j + 1):
                    if k != best:
                        roles[k] = "dropped"
                        self.b.result.notes.append(
                            f"{path.owner}: ConditionalPathPoint '{pts[k].name}' left out (it follows or precedes "
                            f"another conditional point, and MuJoCo needs a site between two wrap geoms; "
                            f"'{pts[best].name}' kept: the straight path without the others is within "
                            f"{100 * min(errs):.2g} % of OpenSim's over the sampled poses)")
            i = j + 1
        return roles

    def conditional_geom(self, path: Path, k: int, roles: list[str]) -> tuple[str, str]:
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
        values = self._reference_active_values(point)
        n_ground, _, _ = self._bend(path, k, values, [q == "site" for q in roles])
        n_body = self.b.ground_frames_at(values)[point.body].rot.T @ n_ground
        # the tendon touches the sphere on the straight segment's side: through the point when it bends as here
        centre = np.asarray(point.location, dtype=float) + r * n_body
        u = self._off_direction(path, k, roles, centre)
        gname = self._unique(f"{path.owner}-{point.name}_cond" if not point.name.startswith(path.owner)
                             else f"{point.name}_cond")
        pos = self._in_world(point.body, Transform(pos=centre)).pos
        self.b.bodies[point.body].add_geom(name=gname, type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[r, 0, 0], pos=pos,
                                           contype=0, conaffinity=0, group=3, density=0, rgba=[0.9, 0.6, 0.2, 0.5])
        self.exact[("geom", gname)] = {"pos": pos, "size": np.array([r])}
        base = self.b.drivers[cname].base
        kind = self.b.coord_joint[base][1].kind if base in self.b.coord_joint else "rotation"
        clo, chi = self.b.fit_range(base, kind)
        slo, shi = lo, hi  # where the switch is
        if base == cname:  # a range end at (or beyond) the coordinate's limit never switches there
            tol = 1e-6 * max(1.0, chi - clo)
            slo = lo - (hi - lo) if lo <= clo + tol else lo
            shi = hi + (hi - lo) if hi >= chi - tol else hi
        half = 0.5 * (shi - slo)
        mid = 0.5 * (shi + slo)

        def slide(x, r=r, mid=mid, half=half):  # r at slo and shi, 0 between them, beyond r outside
            return r * ((np.asarray(x, dtype=float) - mid) / half) ** 2

        ref = float(slide(self.b.ref[cname]))
        pos = self._in_world(point.body, Transform(pos=centre + ref * u)).pos  # the side site at slide(q) along u
        body = self._carrier(point.body, f"{gname}_carrier", pos)
        axis = self._in_world(point.body, Transform(pos=u)).pos if point.body == "ground" else u
        jname = self._unique(f"{gname}_switch")
        body.add_joint(name=jname, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis, ref=ref, armature=CARRIER_ARMATURE)
        self.b.exact[("joint", jname)] = {"axis": np.asarray(axis, dtype=float), "pos": np.zeros(3), "ref": ref}
        rec = JointRecord(jname, "slide", path.owner, f"{point.name}/switch", None, None, "coordinate")
        self.b.couple(rec, self.b.drivers[cname].then(slide), ref, point.element)
        self.b.result.joints.append(rec)
        sname = self._unique(f"{gname}_side")
        body.add_site(name=sname, pos=[0, 0, 0], size=[0.001, 0, 0], group=5)
        self.b.result.notes.append(
            f"{path.owner}: ConditionalPathPoint '{point.name}' (active for '{cname}' in [{lo:g}, {hi:g}]) is a "
            f"wrap sphere of radius {r:g} m on the point whose side site '{cname}' moves out of it beyond the range")
        # not fitted (o2m.wrapfit): it is OpenSim's point to within its radius, and moving it can put the
        # straight path through it where OpenSim has the point off (Leg6Dof9Musc vas_int_r: 0.35 -> 2.0 %)
        return gname, sname

    def _off_direction(self, path: Path, k: int, roles: list[str], centre: np.ndarray) -> np.ndarray:
        """Unit direction (body frame of point ``k``) from the point towards which the straight
        segment between its neighbouring sites passes in the sampled poses where OpenSim has the
        point inactive (each pose weighted by the length the point would add there)."""
        pts = path.points
        keep = [r == "site" for r in roles]
        before = next(i for i in range(k - 1, -1, -1) if keep[i])
        after = next(i for i in range(k + 1, len(pts)) if keep[i])
        point = pts[k]
        feet, weights = [], []
        for j, (_, values) in enumerate(self._pose_samples()):
            if self._active(point, values):
                continue
            frames = self._sample_frames(j)
            to_body = frames[point.body].inverse()
            a = to_body.apply(frames[pts[before].body].apply(self.location_at(pts[before], values)))
            b = to_body.apply(frames[pts[after].body].apply(self.location_at(pts[after], values)))
            ab = b - a
            t = float(np.clip((centre - a) @ ab / max(ab @ ab, 1e-18), 0.0, 1.0))
            feet.append(a + t * ab - centre)
            weights.append(float(np.linalg.norm(centre - a) + np.linalg.norm(b - centre) - np.linalg.norm(ab)))
        values = self._reference_active_values(point)
        n_ground, _, _ = self._bend(path, k, values, keep)
        n_body = self.b.ground_frames_at(values)[point.body].rot.T @ n_ground
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

    def _site_name(self, path: Path, point: PathPoint) -> str:
        return point.name if point.name.startswith(path.owner) else f"{path.owner}-{point.name}"

    def _moving_axes(self, point: PathPoint) -> dict[int, tuple[str, object]]:
        return {i: m for i, m in point.moving.items() if not self._fixed(m[0])}

    def _slide_driver(self, point: PathPoint, i: int, cname: str, fn) -> tuple[object, float]:
        """The driver of ``point``'s slide along axis ``i`` (its location, a function of the
        coordinate's base) and the slide's reference value."""
        ref = float(point.location[i])
        offset = ref - float(fn(np.array([self.b.ref[cname]]))[0])  # the frame offset of the point
        return self.b.drivers[cname].then(lambda x, fn=fn, offset=offset: fn(x) + offset), ref

    def plan_carriers(self, paths: list[Path]) -> None:
        """Choose the carrier slides that get extra joints (:data:`CARRIER_SLOPE_GATE`) and plan
        them, every coordinate's together (:meth:`MjcfBuilder.plan_extra_couplings`), before any
        point is added (their site and slide names are reserved here). Each carrier keeps within
        MuJoCo's 6 dofs. The report's approximation of each slide gives its value and derivative
        errors (and, with extra joints, the plain quartic's)."""
        groups: dict[str, list[_CoupledAxis]] = {}
        room: dict[object, int] = {}
        for path in paths:
            for point in path.points:
                moving = self._moving_axes(point)
                gated = []
                for i, (cname, fn) in moving.items():
                    driver, ref = self._slide_driver(point, i, cname, fn)
                    base = driver.base
                    if base not in self.b.coord_joint:
                        continue  # couple() reports it
                    lo, hi = self.b._coupling_range(base)
                    rel = _relative(driver, ref)
                    if _linear(rel, lo, hi) is not None:
                        continue
                    quartic = fit_polynomial(rel, lo, hi, self.b.ref[base], degree=4, exact_at_x0=True)
                    s_rms = polynomial_slope_errors(rel, quartic.coef, lo, hi, self.b.ref[base])[1]
                    if s_rms > CARRIER_SLOPE_GATE:
                        gated.append((i, base, rel))
                if not gated:
                    continue
                site = self._unique(self._site_name(path, point))
                self._carrier_names[id(point)] = site
                for i in moving:
                    self._slide_names[id(point), i] = self._unique(f"{site}_{'xyz'[i]}")
                room[site] = MAX_BODY_DOFS - len(moving)
                for i, base, rel in gated:
                    groups.setdefault(base, []).append(_CoupledAxis(self._slide_names[id(point), i], site, "slide",
                                                                    base, rel))
        for group in groups.values():
            self.b.plan_extra_couplings(group, [a.body for a in group], room,
                                        targets=[CARRIER_TARGET] * len(group),
                                        slope_targets=None if CARRIER_SLOPE_TARGET is None
                                        else [CARRIER_SLOPE_TARGET] * len(group), armature=CARRIER_ARMATURE)

    def add_point(self, path: Path, point: PathPoint) -> str:
        """Add the site of ``point`` (a path point, a moving point, or a conditional point kept
        always on the path); returns its name."""
        name = self._carrier_names.get(id(point)) or self._unique(self._site_name(path, point))
        moving = self._moving_axes(point)
        loc0 = point.location.copy()  # the location at the reference pose, in the body frame
        pos = self._in_world(point.body, Transform(pos=loc0)).pos
        if not moving:
            self.b.bodies[point.body].add_site(name=name, pos=pos, size=[0.002, 0, 0], group=3)
            self.b.exact[("site", name)] = {"pos": pos}
            return name
        body = self._carrier(point.body, f"{name}_carrier", pos)
        for i, (cname, fn) in moving.items():
            axis = np.zeros(3)
            axis[i] = 1.0
            axis = self._in_world(point.body, Transform(pos=axis)).pos
            driver, ref = self._slide_driver(point, i, cname, fn)
            jname = self._slide_names.get((id(point), i)) or self._unique(f"{name}_{'xyz'[i]}")
            body.add_joint(name=jname, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis, ref=ref,
                           armature=CARRIER_ARMATURE)
            self.b.exact[("joint", jname)] = {"axis": axis, "pos": np.zeros(3), "ref": ref}
            self.b.register_joint(jname, body, mujoco.mjtJoint.mjJNT_SLIDE, axis, np.zeros(3))
            rec = JointRecord(jname, "slide", path.owner, f"{point.name}/{'xyz'[i]}", None, None, "coordinate")
            self.b.couple(rec, driver, ref, point.element, high_order=True)
            self.b.result.joints.append(rec)
            self.b.result.joints.extend(self.b.pop_extra_records(jname))
        body.add_site(name=name, pos=[0, 0, 0], size=[0.002, 0, 0], group=3)
        return name

    def _fixed(self, coordinate: str) -> bool:
        return self.b.skel.coordinates[self.b.drivers[coordinate].base].locked

    # -- wraps ---------------------------------------------------------------------------
    def wrap_geom(self, wrap: WrapObject) -> str | None:
        """A new MuJoCo geom for a wrap object (each path gets its own, so fitting one path's wrap
        leaves the others alone), or None when it has no MuJoCo twin (a torus)."""
        if self.geoms.get(wrap.name, "") is None:
            return None
        first_use = wrap.name not in self.geoms
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
            if first_use:
                self.b.result.approximations.append(Approximation("WrapEllipsoid", wrap.name, what, err, "m",
                                                                  "largest semi-axis difference"))
        else:
            self.b.result.notes.append(f"WrapTorus '{wrap.name}' is not converted (MuJoCo cannot wrap a torus)")
            self.geoms[wrap.name] = None
            return None
        x = x @ Transform(extra_rot)
        name = self._unique(f"wrap_{wrap.name}")
        gtype = mujoco.mjtGeom.mjGEOM_SPHERE if kind == "sphere" else mujoco.mjtGeom.mjGEOM_CYLINDER
        quat = matrix_to_quat(x.rot)
        self.b.bodies[wrap.body].add_geom(name=name, type=gtype, size=size, pos=x.pos, quat=quat,
                                          contype=0, conaffinity=0, group=3, density=0, rgba=[0.3, 0.7, 0.9, 0.4])
        self.exact[("geom", name)] = {"pos": x.pos, "quat": np.asarray(quat, dtype=float),
                                      "size": np.asarray(size[:2] if kind == "cylinder" else size[:1], dtype=float)}
        self.geoms[wrap.name] = name
        self.geom_frames[name] = (wrap.frame @ Transform(extra_rot), kind, float(size[0]))
        return name

    def place_wraps(self, path: Path, sites_ground: np.ndarray) -> list[tuple[int, WrapObject]]:
        """Choose, for each wrap of ``path``, the segment (within the wrap's OpenSim range) it acts
        on at the reference pose. MuJoCo wraps one geom per segment, so wraps are assigned closest
        first: a wrap whose closest segment is taken goes to its next closest free one when that
        passes within two of its sizes of it, and is left out (noted) otherwise."""
        n = len(path.points)
        candidates = []  # (distance, wrap order, segment, wrap, size)
        for order, pw in enumerate(path.wraps):
            wrap = self.wraps.get(pw.wrap)
            if wrap is None:
                raise self.b.doc.error(path.element, f"wraps over '{pw.wrap}', which no body defines")
            if not wrap.active:
                continue
            first, last = wrap_segments(pw.range, n)
            centre = (self.b.ground_frames[wrap.body] @ wrap.frame).pos
            size = max(wrap.radius, float(np.max(wrap.dimensions)), wrap.outer_radius)
            for seg in range(first, last + 1):
                d = _segment_distance(sites_ground[seg], sites_ground[seg + 1], centre)
                candidates.append((d, order, seg, wrap, size))
        candidates.sort(key=lambda c: (c[0], c[1]))
        best = {}
        for d, order, _, _, _ in candidates:
            best.setdefault(order, d)
        chosen: dict[int, WrapObject] = {}
        placed: set[int] = set()
        for d, order, seg, wrap, size in candidates:
            if order in placed or seg in chosen or d > best[order] + 2.0 * size:
                continue
            chosen[seg] = wrap
            placed.add(order)
        for order, pw in enumerate(path.wraps):
            if order in best and order not in placed:
                self.b.result.notes.append(f"{path.owner}: wrap object '{pw.wrap}' left out (MuJoCo wraps one "
                                           f"geom per path segment and the segments near it are taken)")
        return sorted(chosen.items(), key=lambda t: t[0])

    def side_site(self, wrap: WrapObject, geom: str, a: np.ndarray, b: np.ndarray) -> str:
        """A side site for ``geom``, on the side the segment a-b (ground, reference pose) passes,
        or, for a wrap with a quadrant, on the side the quadrant names (for a cylinder, at the
        height along its axis where that segment passes closest)."""
        frame, kind, radius = self.geom_frames[geom]
        x_ground = self.b.ground_frames[wrap.body] @ frame
        local_a, local_b = x_ground.inverse().apply(a), x_ground.inverse().apply(b)
        seg = local_b - local_a
        t = np.clip(-local_a @ seg / max(seg @ seg, 1e-18), 0.0, 1.0)
        closest = local_a + t * seg
        if wrap.quadrant not in ("all", ""):
            sign = -1.0 if wrap.quadrant.startswith("-") else 1.0
            axis_wrap = sign * np.eye(3)["xyz".index(wrap.quadrant[-1].lower())]  # in the wrap object's frame
            direction = (frame.rot.T @ wrap.frame.rot) @ axis_wrap
        else:
            direction = closest.copy()
        if kind == "cylinder":
            direction = direction * np.array([1.0, 1.0, 0.0])
        if np.linalg.norm(direction) < 1e-12:
            direction = closest * np.array([1.0, 1.0, 0.0]) if kind == "cylinder" else closest.copy()
        if np.linalg.norm(direction) < 1e-12:
            direction = np.array([1.0, 0.0, 0.0])
        direction = direction / np.linalg.norm(direction)
        local = direction * radius * SIDE_SITE_DISTANCE
        if kind == "cylinder":
            local[2] = closest[2]
        pos = self._in_world(wrap.body, frame).apply(local)
        name = self._unique(f"{geom}_side")
        self.b.bodies[wrap.body].add_site(name=name, pos=pos, size=[0.001, 0, 0], group=5)
        self.b.exact[("site", name)] = {"pos": pos}
        return name

    # -- path forces ---------------------------------------------------------------------
    def _moves(self, point: PathPoint) -> bool:
        return any(not self._fixed(c) for c, _ in point.moving.values())

    def _pose_samples(self) -> list[tuple[dict[str, float], dict[str, float]]]:
        """(independent values, every coordinate's value) of the reference pose and of
        :data:`PATH_FORCE_POSES` random poses (seed 0) with every free coordinate uniform in its range."""
        if self._samples is None:
            rng = np.random.default_rng(0)
            free = [n for n, d in self.b.drivers.items() if d.base == n and not self._fixed(n)]
            ranges = [self.b.fit_range(n, self.b.coord_joint[n][1].kind if n in self.b.coord_joint else "rotation")
                      for n in free]
            bases = [{n: self.b.ref[n] for n in free}]
            bases += [{n: float(rng.uniform(lo, hi)) for n, (lo, hi) in zip(free, ranges, strict=True)}
                      for _ in range(PATH_FORCE_POSES)]
            self._samples = [(b, self.b.coordinate_values(b)) for b in bases]
        return self._samples

    def _sample_frames(self, k: int) -> dict[str, Transform]:
        if k not in self._frames:
            self._frames[k] = self.b.ground_frames_at(self._pose_samples()[k][1])
        return self._frames[k]

    def _straight_length(self, path: Path, k: int, drop: set[int] | frozenset[int] = frozenset()) -> float:
        """Length (m) of ``path`` at pose sample ``k`` with its active points (but those in
        ``drop``) joined straight (a lower bound of OpenSim's length, which wrapping only lengthens)."""
        values = self._pose_samples()[k][1]
        frames = self._sample_frames(k)
        pts = [frames[p.body].apply(self.location_at(p, values)) for i, p in enumerate(path.points)
               if i not in drop and self._active(p, values)]
        return float(sum(np.linalg.norm(b - a) for a, b in zip(pts[:-1], pts[1:], strict=True)))

    def plan_path_forces(self, path: Path, roles: list[str], site_point: list[int],
                         planned: dict[int, tuple]) -> tuple[list[int], float]:
        """The site segments of ``path`` to leave out of its tendon (``path_forces``) and the
        length (m) to hold them at; records the choice (:class:`PathForceRecord`, an
        :class:`Approximation`). A candidate is a segment between two sites on one body, one of
        them a moving point, that no wrap or conditional point of another body acts on."""
        pts = path.points
        cands: list[tuple[int, PathPoint, PathPoint]] = []
        blocked: list[tuple[str, str]] = []
        for i in range(len(site_point) - 1):
            a, b = pts[site_point[i]], pts[site_point[i + 1]]
            if a.body != b.body or not (self._moves(a) or self._moves(b)) or a.designed or b.designed:
                continue  # (a designed point stands for OpenSim's wraps there, whose forces act)
            others = [pts[k].name for k in range(site_point[i] + 1, site_point[i + 1])
                      if roles[k] == "conditional" and pts[k].body != a.body]
            item = planned.get(i)
            if item is not None and item[0] == "wrap" and item[1].body != a.body:
                others.append(item[1].name)
            if others:
                blocked.append((a.name, b.name))
                self.b.result.notes.append(f"{path.owner}: same-body segment {a.name}-{b.name} kept in the tendon "
                                           f"({', '.join(others)} of another body acts on it)")
            else:
                cands.append((i, a, b))
        if not cands:
            return [], 0.0
        samples = self._pose_samples()

        def held(values: dict[str, float]) -> float:
            return float(sum(np.linalg.norm(self.location_at(a, values) - self.location_at(b, values))
                             for _, a, b in cands))

        lengths = np.array([held(v) for _, v in samples])
        shortest = min(self._straight_length(path, k) for k in range(len(samples)))
        bases = sorted({self.b.drivers[c].base for _, a, b in cands for p in (a, b) for c, _ in p.moving.values()
                        if not self._fixed(c)})
        h = PATH_FORCE_FD_STEP
        arms = {}
        for c in bases:
            d = [abs(held(self.b.coordinate_values({**base, c: base[c] + h}))
                     - held(self.b.coordinate_values({**base, c: base[c] - h}))) / (2 * h) for base, _ in samples]
            arms[c] = float(max(d)) * 1e3
        variation = float(lengths.max() - lengths.min())
        pct = 100.0 * variation / max(shortest, 1e-12)
        mode = self.path_forces_mode
        if mode == "auto":
            mode = "opensim" if variation <= PATH_FORCES_AUTO_VARIATION * shortest else "kinematic"
        c_held = 0.5 * float(lengths.max() + lengths.min())
        opensim = mode == "opensim"
        segs = [(a.name, b.name) for _, a, b in cands]
        held_frac = 0.5 if opensim else 0.0  # the length error: half the variation when held
        rec = PathForceRecord(path.owner, path.owner_type, mode, self.path_forces_mode, segs,
                              c_held if opensim else 0.0, variation * 1e3, pct, shortest * 1e3,
                              held_frac * variation * 1e3, held_frac * pct, arms, blocked)
        self.path_forces.append(rec)
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
                + (f" (> {100 * PATH_FORCES_AUTO_VARIATION:g} %)" if self.path_forces_mode == "auto" else "")))
        return ([i for i, _, _ in cands], c_held) if opensim else ([], 0.0)

    def _held_branch(self, path: Path, a: PathPoint, b: PathPoint, length: float) -> list[str]:
        """Two sites on ``a``'s body, ``length`` apart along the segment a-b at the reference pose:
        a constant-length pulley branch standing for the segments held (drawn where they are)."""
        pa, pb = np.asarray(a.location, dtype=float), np.asarray(b.location, dtype=float)
        u = pb - pa
        u = u / np.linalg.norm(u) if np.linalg.norm(u) > 1e-12 else np.array([1.0, 0.0, 0.0])
        names = []
        for tag, loc in (("a", pa), ("b", pa + length * u)):
            name = self._unique(f"{path.owner}-held_{tag}")
            pos = self._in_world(a.body, Transform(pos=loc)).pos
            self.b.bodies[a.body].add_site(name=name, pos=pos, size=[0.001, 0, 0], group=5)
            self.b.exact[("site", name)] = {"pos": pos}
            names.append(name)
        return names

    # -- tendons and actuators -----------------------------------------------------------
    def add_path(self, path: Path) -> None:
        roles = self.conditional_roles(path)
        site_point = [k for k, r in enumerate(roles) if r == "site"]
        site_of_point: list[int] = []  # for each point, the index of the last site at or before it
        for role in roles:
            site_of_point.append((site_of_point[-1] if site_of_point else -1) + (role == "site"))
        sites_ground = np.array([(self.b.ground_frames[p.body] @ Transform(pos=p.location)).pos for p in path.points])
        # what each site segment wraps, decided before any geom is made
        planned: dict[int, tuple] = {}  # site segment -> ("conditional", point) or ("wrap", WrapObject, segment)
        for k, role in enumerate(roles):
            if role == "conditional":
                planned[site_of_point[k]] = ("conditional", k)
        for seg, wrap in self.place_wraps(path, sites_ground):
            sseg = site_of_point[seg]
            if sseg in planned:
                kind, other = planned[sseg][0], planned[sseg][1]
                what = (f"ConditionalPathPoint '{path.points[other].name}'" if kind == "conditional"
                        else f"'{other.name}'")
                self.b.result.notes.append(f"{path.owner}: wrap object '{wrap.name}' left out (its path segment "
                                           f"already wraps {what}; MuJoCo wraps one geom there)")
                continue
            planned[sseg] = ("wrap", wrap, seg)
        dropped, held_length = self.plan_path_forces(path, roles, site_point, planned)
        sites = [self.add_point(path, path.points[k]) for k in site_point]
        on_segment: dict[int, tuple[str, str]] = {}  # site segment -> (geom, side site)
        for sseg, item in sorted(planned.items(), key=lambda kv: (kv[1][0] != "conditional", kv[0])):
            if sseg in dropped:
                self.b.result.notes.append(f"{path.owner}: {item[0]} on the held segment "
                                           f"{sites[sseg]}-{sites[sseg + 1]} left out with it")
                continue
            if item[0] == "conditional":
                on_segment[sseg] = self.conditional_geom(path, item[1], roles)
                continue
            wrap, seg = item[1], item[2]
            geom = self.wrap_geom(wrap)
            if geom is None:
                continue
            side = self.side_site(wrap, geom, sites_ground[seg], sites_ground[seg + 1])
            on_segment[sseg] = (geom, side)
            self.path_geoms.append(PathGeom(path.owner, geom, side, "Wrap" + wrap.kind.capitalize(), wrap.name,
                                            wrap.body))
        branches: list[list[int]] = [[0]]
        for i in range(len(sites) - 1):
            if i in dropped:
                branches.append([i + 1])
            else:
                branches[-1].append(i + 1)
        runs = [[sites[i] for i in br] for br in branches if len(br) > 1]
        if dropped:
            first = dropped[0]
            runs.append(self._held_branch(path, path.points[site_point[first]], path.points[site_point[first + 1]],
                                          held_length))
        tendon = self.spec.add_tendon(name=path.owner)
        index = {name: i for i, name in enumerate(sites)}
        for r, run in enumerate(runs):
            if r:
                tendon.wrap_pulley(1.0)
            for k, site in enumerate(run):
                tendon.wrap_site(site)
                i = index.get(site)
                if k + 1 < len(run) and i is not None and i in on_segment:
                    tendon.wrap_geom(*on_segment[i])
        if path.owner_type in MUSCLE_TYPES:
            act = self.spec.add_actuator(name=path.owner, trntype=mujoco.mjtTrn.mjTRN_TENDON, target=path.owner)
            fmax = float(path.element.findtext("max_isometric_force") or 1000.0)
            act.set_to_muscle(timeconst=[0.01, 0.04], tausmooth=0.0, force=fmax)
        elif path.owner_type != "Ligament":  # a ligament's spring is added by o2m.forces
            self.b.result.notes.append(f"{path.owner_type} '{path.owner}': tendon only (no actuator yet)")


def wrap_segments(wrap_range: tuple[int, int], n_points: int) -> tuple[int, int]:
    """The first and last path segment (0-based; segment k joins points k and k+1) that a wrap
    with OpenSim's 1-based point ``range`` (-1: all) may act on, of a path of ``n_points``."""
    lo, hi = wrap_range
    first = 0 if lo < 1 else lo - 1
    last = n_points - 2 if hi < 1 else min(hi - 1, n_points - 1) - 1
    return first, last


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


def add_paths(builder: MjcfBuilder, paths: list[Path], wraps: dict[str, WrapObject], *,
              path_forces: str = "auto") -> TendonBuilder:
    """Add every path (tendon, sites, wrap geoms, actuator) to ``builder``'s spec; returns the
    :class:`TendonBuilder` (its ``path_geoms``, ``exact`` geom values, ``path_forces`` records and
    ``held`` segments). ``path_forces``: see the module notes."""
    tb = TendonBuilder(builder, wraps, path_forces)
    tb.plan_carriers(paths)
    for path in paths:
        tb.add_path(path)
    return tb


def restore_geom_precision(xml: str, exact: dict[tuple[str, str], dict[str, np.ndarray]]) -> str:
    """MJCF text with the listed geoms' attributes written in full (17 significant digits)."""
    from lxml import etree

    root = etree.fromstring(xml.encode())
    for el in root.iter("geom"):
        vals = exact.get(("geom", el.get("name")))
        if vals is None:
            continue
        for attr, v in vals.items():
            el.set(attr, " ".join(f"{float(x):.17g}" for x in np.atleast_1d(np.asarray(v, dtype=float))))
    return etree.tostring(root, encoding="unicode", pretty_print=True)


def tendon_length_ranges(model: mujoco.MjModel, coordinates: dict[str, tuple[float, float]], *,
                         n_poses: int = 500, seed: int = 0) -> np.ndarray:
    """(ntendon, 2) smallest and largest tendon lengths (m) over random poses.

    ``coordinates`` maps each independent coordinate joint to the range it is sampled in; every
    other joint follows the model's equalities. The default pose and the range corners of one
    coordinate at a time are included, so extremes at the limits are not missed.
    """
    from o2m.mj.posing import joint_equality_plan, pose_mujoco

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
