"""Path-point carriers: small bodies whose slides move a MovingPathPoint's site.

* A PathPoint is a site on its body, or on the nearest ancestor with joints when its body has
  none (:meth:`Carriers.host`: MuJoCo then skips the segments within that rigid body).
* A MovingPathPoint is a site on a small child body (a carrier) that slides along its body's axes
  (metres; on ground, OpenSim's Y-up axes mapped to MuJoCo's Z-up); each slide follows its
  coordinate through a joint equality (exact when the location function is linear, else a
  quartic fit whose worst error, of the location and of its derivative, the report records). A
  slide whose quartic leaves a derivative error (a moment-arm error) above
  :data:`CARRIER_SLOPE_GATE` RMS gets extra slides on its carrier along the same axis (inner and
  outer joints, as the skeleton's spline couplings: :meth:`Carriers.plan`).
* A carrier has as few slides as its point's locus needs (:meth:`Carriers.slides`): a point whose
  moving axes follow one coordinate and whose locus lies on a line (or a plane) to within
  :data:`CARRIER_AXIS_TOLERANCE` slides along that line (its two principal directions) only, and
  points of one body that move alike (the same displacement, to that tolerance, at every value
  of the coordinate) share one carrier (:meth:`Carriers.add_point`). Each slide is a degree of
  freedom and a joint equality of every simulation step (MoBL-ARMS: 63 carrier slides, 41 after).
* A ConditionalPathPoint's side site rides a carrier too (:mod:`o2m.convert.conditional`).
* A carrier on a body welded to the world gets some mass once the model is compiled
  (:meth:`Carriers.weigh_static`).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from o2m.convert.coordinates import Driver, as_linear, relative
from o2m.convert.coupling_plan import MAX_BODY_DOFS, CoupledAxis
from o2m.convert.couplings import polynomial_slope_errors
from o2m.convert.pathpoints import PathContext
from o2m.convert.polyfit import FitError, fit_polynomial
from o2m.convert.records import JointRecord
from o2m.osim.paths import Path, PathPoint
from o2m.transforms import Transform, quat_to_matrix

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
#: :meth:`Carriers.weigh_static`): the armature's worth, so that MuJoCo's constraint
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
#: quartic, inner and outer joints, :func:`o2m.convert.couplings.fit_couplings`, derivative-aware), all the
#: carriers of one coordinate planned together (inner joints shared between carriers), each
#: carrier within MuJoCo's 6 dofs.
CARRIER_SLOPE_GATE = 2e-3
#: Target (m) of a carrier slide with extra joints: its joints are added while an axis misses it
#: and each brings a gain (:func:`o2m.convert.coupling_plan.plan_group`), within the carrier's 6 dofs.
CARRIER_TARGET = 1e-5
#: Derivative target (m per coordinate unit) of those fits, or None: minimax on the location only.
#: None, measured: these splines' curvature jumps at the knee's default angle (knots 0, 1.7e-4 and
#: 3.5e-4 rad), so a derivative-aware minimax (:func:`o2m.convert.couplings.fit_couplings`, slope targets)
#: spends the fit there and loses elsewhere: with 0.5 mm/rad (the median moment-arm
#: target) Leg6Dof9Musc's moment-arm RMS p95 is 0.87 mm (0.77 at a 2e-5 m location target),
#: Gait10dof18musc's 0.53, against 0.50 and 0.51 mm fitted to the location alone, whose
#: derivative errors are 0.4-0.5 mm/rad RMS (1.8-2.8 mm/rad at worst, next to that knot).
CARRIER_SLOPE_TARGET: float | None = None
#: Largest distance (m) a carrier's site may leave its point's locus when the carrier gets fewer
#: slides than the point has moving axes (along the locus's principal directions), or shares
#: another point's carrier: 1 micrometre, ten times below :data:`CARRIER_TARGET` and far below the
#: quartics' own errors, so the default stays exact (MoBL-ARMS's straight loci are off their line
#: by 1e-17 m, its planar ones off their plane by 1e-11 m). ``ConvertOptions.carrier_tolerance``
#: passes a larger one: a faster, approximate model.
CARRIER_AXIS_TOLERANCE = 1e-6
#: Samples of the coordinate's range on which loci are compared (:meth:`Carriers.slides`).
LOCUS_SAMPLES = 201


@dataclass
class Slide:
    """One slide of a carrier: ``key`` names it (``"x"``, ``"y"``, ``"z"``: the body's axes;
    ``"u"``, ``"v"``: the locus's principal directions), ``axis`` (3,) is its unit direction in
    the OpenSim body frame, ``driver`` gives its value (m) from the base coordinate, ``ref`` its
    value at the reference pose."""

    key: str
    axis: np.ndarray
    driver: Driver
    ref: float


def _displacements(slides: list[Slide], x: np.ndarray) -> np.ndarray:
    """The carrier's displacement from the reference pose (m, body frame) at base coordinate
    values ``x``, shape (*x.shape, 3)."""
    x = np.asarray(x, float)
    return sum((np.asarray(s.driver.fn(x), float) - s.ref)[..., None] * s.axis for s in slides)


def _principal_slide(key: str, direction: np.ndarray, slides: list[Slide], location: np.ndarray) -> Slide:
    """The slide along unit ``direction`` (3,) whose value is the component along it of the
    location ``slides`` give (reference location ``location``, body frame)."""
    ref = float(direction @ location)

    def value(x: np.ndarray) -> np.ndarray:
        return ref + _displacements(slides, x) @ direction

    return Slide(key, direction, Driver(slides[0].driver.base, value), ref)


def site_name(path: Path, point: PathPoint) -> str:
    """The MuJoCo site name of ``point`` (before it is made unique): prefixed with its path's owner."""
    return point.name if point.name.startswith(path.owner) else f"{path.owner}-{point.name}"


class Carriers:
    """The carrier bodies of a model's paths, and the names reserved for those with extra joints."""

    def __init__(self, ctx: PathContext, tolerance: float = CARRIER_AXIS_TOLERANCE):
        self.ctx = ctx
        #: :data:`CARRIER_AXIS_TOLERANCE` or a larger one (m).
        self.tolerance = tolerance
        #: Carriers that another point of the same body may share: (body, base coordinate,
        #: displacement samples (LOCUS_SAMPLES, 3), carrier body, its position in the parent).
        self._shareable: list[tuple[str, str, np.ndarray, object, np.ndarray]] = []
        self.b = ctx.b
        #: Site names (by id of the PathPoint) and slide names (by (id, axis)) reserved by
        #: :meth:`plan` for carriers with extra joints.
        self._site_names: dict[int, str] = {}
        self._slide_names: dict[tuple[int, int], str] = {}
        #: Every carrier body added (see :meth:`weigh_static`).
        self.bodies: list = []

    def body(self, parent: str | mujoco.MjsBody, name: str, pos: np.ndarray):
        """A massless child body of ``parent`` (an OpenSim body's name, or a carrier) at ``pos``
        (MuJoCo frame of the parent), named ``name`` (made unique), to carry a moving point, a
        conditional point's side site or a shared sphere."""
        host = self.b.bodies[parent] if isinstance(parent, str) else parent
        body = host.add_body(name=self.ctx.unique(name), pos=pos)
        self.b.exact[("body", body.name)] = {"pos": pos, "quat": np.array([1.0, 0, 0, 0])}
        body.explicitinertial = True
        body.mass = CARRIER_MASS
        body.fullinertia = [CARRIER_INERTIA, CARRIER_INERTIA, CARRIER_INERTIA, 0, 0, 0]
        self.b.exact[("inertial", body.name)] = {"pos": np.zeros(3), "mass": CARRIER_MASS,
                                                 "fullinertia": np.array(body.fullinertia)}
        self.bodies.append(body)
        return body

    def weigh_static(self, model: mujoco.MjModel) -> list[str]:
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
        for body in self.bodies:
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

    def _moving_axes(self, point: PathPoint) -> dict[int, tuple[str, object]]:
        return {i: m for i, m in point.moving.items() if not self.ctx.fixed(m[0])}

    def _slide_driver(self, point: PathPoint, i: int, cname: str, fn) -> tuple[Driver, float]:
        """The driver of ``point``'s slide along axis ``i`` (its location, a function of the
        coordinate's base) and the slide's reference value."""
        ref = float(point.location[i])
        offset = ref - float(fn(np.array([self.b.ref[cname]]))[0])  # the frame offset of the point
        return self.b.drivers[cname].then(lambda x, fn=fn, offset=offset: fn(x) + offset), ref

    def _locus_grid(self, slides: list[Slide]) -> np.ndarray | None:
        """Samples (LOCUS_SAMPLES,) of the base coordinate all ``slides`` follow, or None when they
        follow several (or one without a MuJoCo joint: :meth:`MjcfBuilder.couple` reports it)."""
        bases = {s.driver.base for s in slides}
        if len(bases) != 1 or next(iter(bases)) not in self.b.coord_joint:
            return None
        return np.linspace(*self.b.coupling_range(next(iter(bases))), LOCUS_SAMPLES)

    def slides(self, point: PathPoint) -> list[Slide]:
        """The slides of ``point``'s carrier: one per moving axis whose location is not constant, or, when the point's
        displacement (m, body frame) over its coordinate's range lies within
        :attr:`tolerance` of its reference location (none: the point is fixed there), of a line
        or of a plane through it, one along each principal direction that line or plane needs
        (uncentred SVD of the sampled displacements; each slide's value is the location's
        component along it)."""
        slides = [Slide("xyz"[i], np.eye(3)[i], *self._slide_driver(point, i, cname, fn))
                  for i, (cname, fn) in self._moving_axes(point).items()]
        grid = self._locus_grid(slides) if slides else None
        if grid is None:
            return slides
        disp = _displacements(slides, grid)
        directions = np.linalg.svd(disp, full_matrices=False)[2]
        # axes along which the point does not move at all (a Constant location) go first, and the
        # others stay as they are when the locus needs them all (their fits and extra joints unchanged)
        moving = [s for s in slides if np.any(np.asarray(s.driver.fn(grid), float) != s.ref)]
        for rank in range(len(moving)):
            basis = directions[:rank]
            if np.linalg.norm(disp - disp @ basis.T @ basis, axis=1).max() > self.tolerance:
                continue
            return [_principal_slide(key, v if v[np.argmax(np.abs(v))] > 0 else -v, slides, point.location)
                    for key, v in zip("uv", basis, strict=False)]  # a sign that does not depend on the SVD
        return moving

    def plan(self, paths: list[Path]) -> None:
        """Choose the carrier slides that get extra joints (:data:`CARRIER_SLOPE_GATE`; none when the
        builder plans no couplings, ``ConvertOptions.plain_quartics``) and plan
        them, every coordinate's together (:meth:`MjcfBuilder.plan_extra_couplings`), before any
        point is added (their site and slide names are reserved here). Each carrier keeps within
        MuJoCo's 6 dofs. The report's approximation of each slide gives its value and derivative
        errors (and, with extra joints, the plain quartic's)."""
        groups: dict[str, list[CoupledAxis]] = {}
        room: dict[object, int] = {}
        for path in paths:
            for point in path.points:
                slides = self.slides(point)
                gated = []
                for slide in slides:
                    driver, ref = slide.driver, slide.ref
                    base = driver.base
                    if base not in self.b.coord_joint:
                        continue  # couple() reports it
                    lo, hi = self.b.coupling_range(base)
                    rel = relative(driver, ref)
                    if as_linear(rel, lo, hi) is not None:
                        continue
                    try:
                        quartic = fit_polynomial(rel, lo, hi, self.b.ref[base], degree=4, exact_at_x0=True)
                    except FitError as exc:
                        raise self.b.doc.error(point.element, f"moves in a way MuJoCo's joint equalities "
                                                              f"cannot follow: {exc}") from None
                    s_rms = polynomial_slope_errors(rel, quartic.coef, lo, hi, self.b.ref[base])[1]
                    if s_rms > CARRIER_SLOPE_GATE and self.b.plan_couplings:
                        gated.append((slide.key, base, rel))
                if not gated:
                    continue
                site = self.ctx.unique(site_name(path, point))
                self._site_names[id(point)] = site
                for slide in slides:
                    self._slide_names[id(point), slide.key] = self.ctx.unique(f"{site}_{slide.key}")
                room[site] = MAX_BODY_DOFS - len(slides)
                for key, base, rel in gated:
                    groups.setdefault(base, []).append(CoupledAxis(self._slide_names[id(point), key], site, "slide",
                                                                    base, rel))
        for group in groups.values():
            self.b.plan_extra_couplings(group, [a.body for a in group], room,
                                        targets=[CARRIER_TARGET] * len(group),
                                        slope_targets=None if CARRIER_SLOPE_TARGET is None
                                        else [CARRIER_SLOPE_TARGET] * len(group), armature=CARRIER_ARMATURE)

    def add_point(self, path: Path, point: PathPoint) -> str:
        """Add the site of ``point`` (a path point, a moving point, or a conditional point kept
        always on the path); returns its name. A moving point rides the carrier of an earlier
        point of its body that moves alike (:meth:`_shared_carrier`), else a carrier of its own."""
        name = self._site_names.get(id(point)) or self.ctx.unique(site_name(path, point))
        slides = self.slides(point)
        loc0 = point.location.copy()  # the location at the reference pose, in the body frame
        pos = self.ctx.in_world(point.body, Transform(pos=loc0)).pos
        if len(slides) < len(self._moving_axes(point)):
            self.b.result.notes.append(
                f"{path.owner}: MovingPathPoint '{point.name}' moves within {self.tolerance:g} m of "
                f"{['its reference location', 'a line', 'a plane'][len(slides)]}: {len(slides)} carrier slides "
                f"instead of {len(self._moving_axes(point))}")
        if not slides:
            host, host_pos = self.host(point.body, pos)
            host.add_site(name=name, pos=host_pos, size=[0.002, 0, 0], group=3)
            self.b.exact[("site", name)] = {"pos": host_pos}
            return name
        shared = self._shared_carrier(point, slides)
        if shared is not None:
            body, offset = shared[0], pos - shared[1]
            body.add_site(name=name, pos=offset, size=[0.002, 0, 0], group=3)
            self.b.exact[("site", name)] = {"pos": offset}
            self.b.result.notes.append(f"{path.owner}: MovingPathPoint '{point.name}' rides carrier '{body.name}' "
                                       f"(it moves as that carrier's point, within {self.tolerance:g} m)")
            return name
        body = self.body(point.body, f"{name}_carrier", pos)
        for slide in slides:
            self._add_slide(path, point, name, body, slide)
        body.add_site(name=name, pos=[0, 0, 0], size=[0.002, 0, 0], group=3)
        if not any((id(point), s.key) in self._slide_names for s in slides):  # planned ones are not shared
            grid = self._locus_grid(slides)
            if grid is not None:
                self._shareable.append((point.body, slides[0].driver.base, _displacements(slides, grid), body, pos))
        return name

    def host(self, body: str, pos: np.ndarray) -> tuple[mujoco.MjsBody, np.ndarray]:
        """The body a site fixed at ``pos`` (3,) (m, MuJoCo frame of ``body``) goes on, and its
        position (3,) there: ``body``, or when ``body`` has no joints the nearest ancestor that
        has some (the same rigid body in every pose: a body welded to a moving one, e.g. a hand
        whose wrist coordinates are locked); ``body`` itself when no ancestor short of the world has joints.

        Why: MuJoCo computes the Jacobian of every tendon segment whose two ends are on different
        bodies, even when they are welded together and the segment's length cannot change (its
        Jacobian is zero). MoBL-ARMS no-wrap: 24 of the 90 segments between bodies run between
        the radius and the welded hand; hosted on the radius they cost nothing, 1-s simulations
        take about 8 % less CPU time, and tendon lengths and moment arms stay the same (1e-15 m)."""
        start = self.b.bodies[body]
        mj, x = start, np.asarray(pos, float)
        while not mj.joints:
            parent = mj.parent
            if parent is None or parent.name == self.b.spec.worldbody.name:
                return start, np.asarray(pos, float)
            frame = self.b.exact.get(("body", mj.name), {"pos": mj.pos, "quat": mj.quat})
            x = np.asarray(frame["pos"], float) + quat_to_matrix(frame["quat"]) @ x
            mj = parent
        return mj, x

    def _shared_carrier(self, point: PathPoint, slides: list[Slide]):
        """(carrier body, its position in the parent) of an earlier point of ``point``'s body whose
        displacement is ``point``'s within :attr:`tolerance` over the coordinate's range, or None."""
        if any((id(point), s.key) in self._slide_names for s in slides):
            return None
        grid = self._locus_grid(slides)
        if grid is None:
            return None
        disp = _displacements(slides, grid)
        for body_name, base, other, carrier, pos in self._shareable:
            if (body_name == point.body and base == slides[0].driver.base
                    and np.linalg.norm(disp - other, axis=1).max() <= self.tolerance):
                return carrier, pos
        return None

    def _add_slide(self, path: Path, point: PathPoint, site: str, body, slide: Slide) -> None:
        """Add ``slide`` to carrier ``body`` of ``point`` (site ``site``), tied to its coordinate."""
        axis = self.ctx.in_world(point.body, Transform(pos=slide.axis)).pos
        jname = self._slide_names.get((id(point), slide.key)) or self.ctx.unique(f"{site}_{slide.key}")
        body.add_joint(name=jname, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis, ref=slide.ref,
                       armature=CARRIER_ARMATURE)
        self.b.exact[("joint", jname)] = {"axis": axis, "pos": np.zeros(3), "ref": slide.ref}
        self.b.register_joint(jname, body, mujoco.mjtJoint.mjJNT_SLIDE, axis, np.zeros(3))
        rec = JointRecord(jname, "slide", path.owner, f"{point.name}/{slide.key}", None, None, "coordinate")
        self.b.couple(rec, slide.driver, slide.ref, point.element, high_order=True)
        self.b.result.joints.append(rec)
        self.b.result.joints.extend(self.b.pop_extra_records(jname))
