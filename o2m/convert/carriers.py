"""Path-point carriers: small bodies whose slides move a MovingPathPoint's site.

* A PathPoint is a site on its body.
* A MovingPathPoint is a site on a small child body (a carrier) that slides along its body's axes
  (metres; on ground, OpenSim's Y-up axes mapped to MuJoCo's Z-up); each slide follows its
  coordinate through a joint equality (exact when the location function is linear, else a
  quartic fit whose worst error, of the location and of its derivative, the report records). A
  slide whose quartic leaves a derivative error (a moment-arm error) above
  :data:`CARRIER_SLOPE_GATE` RMS gets extra slides on its carrier along the same axis (inner and
  outer joints, as the skeleton's spline couplings: :meth:`Carriers.plan`).
* A ConditionalPathPoint's side site rides a carrier too (:mod:`o2m.convert.conditional`).
* A carrier on a body welded to the world gets some mass once the model is compiled
  (:meth:`Carriers.weigh_static`).
"""

from __future__ import annotations

import mujoco
import numpy as np

from o2m.convert.coordinates import Driver, as_linear, relative
from o2m.convert.coupling_plan import MAX_BODY_DOFS, CoupledAxis
from o2m.convert.couplings import polynomial_slope_errors
from o2m.convert.pathpoints import PathContext
from o2m.convert.polyfit import FitError, fit_polynomial
from o2m.convert.records import JointRecord
from o2m.osim.paths import Path, PathPoint
from o2m.transforms import Transform

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


def site_name(path: Path, point: PathPoint) -> str:
    """The MuJoCo site name of ``point`` (before it is made unique): prefixed with its path's owner."""
    return point.name if point.name.startswith(path.owner) else f"{path.owner}-{point.name}"


class Carriers:
    """The carrier bodies of a model's paths, and the names reserved for those with extra joints."""

    def __init__(self, ctx: PathContext):
        self.ctx = ctx
        self.b = ctx.b
        #: Site names (by id of the PathPoint) and slide names (by (id, axis)) reserved by
        #: :meth:`plan` for carriers with extra joints.
        self._site_names: dict[int, str] = {}
        self._slide_names: dict[tuple[int, int], str] = {}
        #: Every carrier body added (see :meth:`weigh_static`).
        self.bodies: list = []

    def body(self, parent: str, name: str, pos: np.ndarray):
        """A massless child body of ``parent`` at ``pos`` (MuJoCo frame of the parent), named
        ``name`` (made unique), to carry a moving point or a conditional point's side site."""
        body = self.b.bodies[parent].add_body(name=self.ctx.unique(name), pos=pos)
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
                moving = self._moving_axes(point)
                gated = []
                for i, (cname, fn) in moving.items():
                    driver, ref = self._slide_driver(point, i, cname, fn)
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
                        gated.append((i, base, rel))
                if not gated:
                    continue
                site = self.ctx.unique(site_name(path, point))
                self._site_names[id(point)] = site
                for i in moving:
                    self._slide_names[id(point), i] = self.ctx.unique(f"{site}_{'xyz'[i]}")
                room[site] = MAX_BODY_DOFS - len(moving)
                for i, base, rel in gated:
                    groups.setdefault(base, []).append(CoupledAxis(self._slide_names[id(point), i], site, "slide",
                                                                    base, rel))
        for group in groups.values():
            self.b.plan_extra_couplings(group, [a.body for a in group], room,
                                        targets=[CARRIER_TARGET] * len(group),
                                        slope_targets=None if CARRIER_SLOPE_TARGET is None
                                        else [CARRIER_SLOPE_TARGET] * len(group), armature=CARRIER_ARMATURE)

    def add_point(self, path: Path, point: PathPoint) -> str:
        """Add the site of ``point`` (a path point, a moving point, or a conditional point kept
        always on the path); returns its name."""
        name = self._site_names.get(id(point)) or self.ctx.unique(site_name(path, point))
        moving = self._moving_axes(point)
        loc0 = point.location.copy()  # the location at the reference pose, in the body frame
        pos = self.ctx.in_world(point.body, Transform(pos=loc0)).pos
        if not moving:
            self.b.bodies[point.body].add_site(name=name, pos=pos, size=[0.002, 0, 0], group=3)
            self.b.exact[("site", name)] = {"pos": pos}
            return name
        body = self.body(point.body, f"{name}_carrier", pos)
        for i, (cname, fn) in moving.items():
            axis = np.zeros(3)
            axis[i] = 1.0
            axis = self.ctx.in_world(point.body, Transform(pos=axis)).pos
            driver, ref = self._slide_driver(point, i, cname, fn)
            jname = self._slide_names.get((id(point), i)) or self.ctx.unique(f"{name}_{'xyz'[i]}")
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
