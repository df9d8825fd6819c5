"""Contact: ContactSphere and ContactHalfSpace with a HuntCrossleyForce as MuJoCo geoms and pairs.

* **Geometry.** A ContactSphere becomes a ``sphere`` geom, a ContactHalfSpace a ``plane`` geom,
  in the body of the geometry's ``socket_frame`` at its ``location`` and ``orientation``
  (body-fixed XYZ). OpenSim's half space is x > 0 of its own frame (outward normal -x), so the
  plane's +z is the frame's -x. MuJoCo allows planes only on static bodies: a half space on a
  moving body becomes a box :data:`BOX_HALF` m deep and wide whose face is the half space.
  Contact geoms never collide by themselves (``contype`` = ``conaffinity`` = 0, like every o2m
  geom), have no mass, and are in geom group 2. Only geometry that a converted force uses is
  added; the rest is listed as skipped.
* **HuntCrossleyForce.** Simbody puts every geometry of the force (over all its ContactParameters)
  in one contact set and lets every pair of them touch; o2m writes an explicit ``<pair>`` for
  each pair that can move against each other and that MuJoCo can collide (sphere-plane,
  sphere-sphere; not two geometries fixed to one rigid body, where the force would cancel, nor
  two static ones), with the two surfaces' parameters combined as Simbody combines them:
  ``condim`` 3, and ``friction``, ``solref``, ``solreffriction`` and ``solimp`` from stiffness,
  dissipation, friction coefficients and transition velocity as :mod:`o2m.convert.contact_fit`
  explains (a spring-damper fitted to the Hunt-Crossley impact at 1 m/s, the Coulomb coefficient
  of a slide from 2 m/s). Models with contact pairs use MuJoCo's elliptic friction cone.
  ``solref`` needs the compiled model (its effective masses), so :func:`fit_contacts` sets it
  after the first compilation; :func:`measure_contacts` records the fit's measured errors.
* **SmoothSphereHalfSpaceForce** (one ContactSphere against one ContactHalfSpace) is the same
  Hunt-Crossley law of its one surface against itself, smoothed
  (:mod:`o2m.convert.contact_smooth`): the same geoms and pair, with a spring-damper and a pair
  ``margin`` fitted to the smooth law's impact and resting point; the report measures it
  against that law.
* **Not converted**, each listed as skipped with what that changes: ContactMesh (Simbody's
  Hunt-Crossley applies no force to mesh contacts), the other ContactGeometry types and
  ElasticFoundationForce (mesh contact).

Units: SI (m, kg, s, N); OpenSim frames are Y-up, the MuJoCo world Z-up (:data:`o2m.transforms.OSIM_TO_MJ`).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
from lxml import etree

from o2m.convert.builder import Approximation, MjcfBuilder
from o2m.convert.contact_fit import (
    IMPEDANCE,
    REFERENCE_SPEED,
    SLIDE_SPEED,
    SPEEDS,
    STOPPED,
    HuntCrossley,
    Impact,
    Surface,
    fit_linear,
    measure_impacts,
    measure_slide,
)
from o2m.convert.contact_smooth import SmoothHuntCrossley, fit_smooth, measure_falls, measure_smooth_slide
from o2m.convert.force_context import (
    ContactConversion,
    ContactGeom,
    ContactPair,
    ForceConversion,
    _Context,
    _number,
    _text,
    _vector,
)
from o2m.osim.skeleton import Skipped
from o2m.transforms import OSIM_TO_MJ, Transform, body_fixed_xyz, matrix_to_quat

__all__ = ["BOX_HALF", "CONTACT_SKIPS", "FALL_DEEPEST", "IMPACT_DURATION", "IMPACT_PEAK", "IMPACT_RESTITUTION",
           "SLIDE_DISTANCE", "SOLIMP", "convert_hunt_crossley", "convert_smooth_sphere", "fit_contacts",
           "measure_contacts", "skip_force", "skip_unused_geometry"]

#: Half size (m) of the box that stands for a half space on a moving body.
BOX_HALF = 5.0
#: MuJoCo ``solimp`` of every contact pair: constant impedance :data:`IMPEDANCE` (the penalty regime).
SOLIMP = (IMPEDANCE, IMPEDANCE, 0.001, 0.5, 2.0)
#: Geom group of contact geometry (shown by MuJoCo's viewer by default).
GROUP = 2
#: Plane (z) of a half space: the frame's -x, i.e. the frame rotated -90 degrees about y.
_PLANE_IN_FRAME = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
#: Why each force type that touches contact geometry is not converted (what the skip changes).
CONTACT_SKIPS = {
    "ElasticFoundationForce": "elastic foundation (mesh) contact is not converted: its geometry gets no MuJoCo "
                              "contact, so these bodies pass through each other in MuJoCo",
}


# -- reading --------------------------------------------------------------------------------
def _geometry(ctx: _Context) -> dict[str, etree._Element]:
    return {g.get("name", ""): g for g in ctx.reader.set_objects("ContactGeometrySet")}


def _parameter_sets(el: etree._Element) -> list[etree._Element]:
    """The ContactParameters of a HuntCrossleyForce (tag ``HuntCrossleyForce__ContactParameters``)."""
    return [p for p in el.iter() if isinstance(p.tag, str) and p.tag.split("__")[-1] == "ContactParameters"]


def _surface(ctx: _Context, p: etree._Element) -> Surface:
    vals = [_number(p, prop, 0.0, ctx) for prop in ("stiffness", "dissipation", "static_friction",
                                                    "dynamic_friction", "viscous_friction")]
    if vals[0] < 0 or vals[1] < 0 or min(vals[2:]) < 0:
        raise ctx.builder.doc.error(p, "has a negative stiffness, dissipation or friction")
    return Surface(*vals)


def _color(el: etree._Element) -> list[float]:
    try:
        rgb = [float(v) for v in (el.findtext("Appearance/color") or "0 1 1").split()][:3]
    except ValueError:
        rgb = [0.0, 1.0, 1.0]
    return rgb + [0.4] if len(rgb) == 3 else [0.0, 1.0, 1.0, 0.4]


# -- geoms ----------------------------------------------------------------------------------
def _weld_root(body: mujoco.MjsBody, world: mujoco.MjsBody) -> str:
    """The body ``body`` moves with: itself or the nearest body it hangs from that has a joint
    (the world's name for a static body)."""
    while body.name != world.name and not body.joints:
        body = body.parent
    return body.name


def _add_geom(ctx: _Context, el: etree._Element) -> ContactGeom:
    """The MuJoCo geom of ContactSphere or ContactHalfSpace ``el`` (added once)."""
    store: ContactConversion = ctx.out.contact
    name = el.get("name", "")
    if name in store.geoms:
        return store.geoms[name]
    body, x_frame, _ = ctx.reader.socket_frame(el, "socket_frame")
    local = x_frame @ Transform(body_fixed_xyz(_vector(el, "orientation", (0.0, 0.0, 0.0), ctx)),
                                _vector(el, "location", (0.0, 0.0, 0.0), ctx))
    if body == "ground":
        local = Transform(OSIM_TO_MJ) @ local
    mj_body = ctx.builder.bodies[body]
    weld = _weld_root(mj_body, ctx.spec.worldbody)
    static = weld == ctx.spec.worldbody.name
    geom = ctx.unique("geom", name or el.tag)
    common = dict(name=geom, contype=0, conaffinity=0, density=0, group=GROUP, rgba=_color(el))
    if el.tag == "ContactSphere":
        radius = _number(el, "radius", 0.0, ctx)
        if radius <= 0:
            raise ctx.builder.doc.error(el, f"has radius {radius:g}; a contact sphere needs a positive radius")
        mj_body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[radius, 0, 0], pos=local.pos,
                         quat=matrix_to_quat(local.rot), **common)
        kind = "sphere"
    else:
        radius, kind = math.inf, "plane"
        rot = local.rot @ _PLANE_IN_FRAME
        if static:
            mj_body.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05], pos=local.pos,
                             quat=matrix_to_quat(rot), **common)
        else:
            mj_body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[BOX_HALF] * 3, pos=local.pos - BOX_HALF * rot[:, 2],
                             quat=matrix_to_quat(rot), **common)
            ctx.builder.result.notes.append(f"ContactHalfSpace '{name}' is on moving body '{body}', where MuJoCo "
                                            f"allows no plane: a box {2 * BOX_HALF:g} m wide and deep stands for it")
    ctx.out.handled.add((el.tag, name))
    store.geoms[name] = ContactGeom(name, geom, kind, body, radius, weld, static)
    return store.geoms[name]


# -- the force ------------------------------------------------------------------------------
def _members(ctx: _Context, el: etree._Element) -> list[tuple[etree._Element, Surface]]:
    """(geometry element, its surface parameters) for every geometry the force names."""
    known = _geometry(ctx)
    out = []
    for p in _parameter_sets(el):
        surface = _surface(ctx, p)
        for gname in _text(p, "geometry").split():
            if gname not in known:
                raise ctx.builder.doc.error(p, f"names contact geometry '{gname}', which the ContactGeometrySet "
                                               "does not hold")
            out.append((known[gname], surface))
    return out


def _pairable(member_a: tuple[ContactGeom, Surface], member_b: tuple[ContactGeom, Surface]) -> str:
    """Why MuJoCo gets no pair for these two members of a force ("" when it does)."""
    (a, sa), (b, sb) = member_a, member_b
    if a.name == b.name:
        return "one geometry"
    if sa.stiffness == 0 or sb.stiffness == 0:
        return "a zero stiffness makes Simbody's force zero"
    if a.kind == "plane" and b.kind == "plane":
        return "two half spaces never touch in Simbody"
    if a.weld == b.weld:
        return "both static" if a.static else "on one rigid body, where the force would cancel"
    return ""


def _add_pair(ctx: _Context, force: str, a: tuple[ContactGeom, Surface], b: tuple[ContactGeom, Surface],
              transition: float, smoothing: dict[str, float] | None = None) -> None:
    """A ``<pair>`` of ``a`` and ``b`` (the plane first); ``smoothing``: the keyword arguments of
    :class:`~o2m.convert.contact_smooth.SmoothHuntCrossley` for a smooth force."""
    (ga, sa), (gb, sb) = (a, b) if a[0].kind == "plane" or b[0].kind != "plane" else (b, a)
    radius = gb.radius if ga.kind == "plane" else ga.radius * gb.radius / (ga.radius + gb.radius)
    law = HuntCrossley.combine(sa, sb, radius, transition)
    if smoothing is not None:
        law = SmoothHuntCrossley(**vars(law), **smoothing)
    name = ctx.unique("pair", f"{force}_{ga.name}_{gb.name}")
    pair = ctx.spec.add_pair(name=name, geomname1=ga.geom, geomname2=gb.geom, solimp=list(SOLIMP))  # fit_contacts
    # sets its friction and solref
    element = "HuntCrossleyForce" if smoothing is None else "SmoothSphereHalfSpaceForce"
    ctx.out.contact.pairs.append(ContactPair(force, name, ga, gb, law, pair, element=element))


def convert_hunt_crossley(ctx: _Context, el: etree._Element) -> None:
    """HuntCrossleyForce -> geoms for its spheres and half spaces and a ``<pair>`` per touching pair."""
    name = el.get("name", "")
    transition = _number(el, "transition_velocity", 0.01, ctx)
    if transition <= 0:
        raise ctx.builder.doc.error(el, f"has transition_velocity {transition:g}; it must be positive")
    members: list[tuple[ContactGeom, Surface]] = []
    for gel, surface in _members(ctx, el):
        if gel.tag in ("ContactSphere", "ContactHalfSpace"):
            members.append((_add_geom(ctx, gel), surface))
        else:
            why = ("Simbody's Hunt-Crossley force applies no force to mesh contact" if gel.tag == "ContactMesh"
                   else f"{gel.tag} is not converted")
            ctx.out.contact.unused.setdefault(gel.get("name", ""), f"{why} (force '{name}')")
    before = len(ctx.out.contact.pairs)
    for i, a in enumerate(members):
        for b in members[i + 1:]:
            if not _pairable(a, b):
                _add_pair(ctx, name, a, b, transition)
    if len(ctx.out.contact.pairs) == before:
        ctx.out.skipped.append(Skipped(el.tag, name, "no pair of its geometry can touch in MuJoCo (half spaces only, "
                                       "one body, static bodies or zero stiffness): it applies no force"))
        return
    ctx.out.contact.forces.append(name)


#: SmoothSphereHalfSpaceForce's smoothing properties, OpenSim's defaults, and their names in
#: :class:`~o2m.convert.contact_fit.SmoothHuntCrossley`.
_SMOOTHING = (("hertz_smoothing", 300.0, "hertz_smoothing"),
              ("hunt_crossley_smoothing", 50.0, "hunt_crossley_smoothing"),
              ("constant_contact_force", 1e-5, "constant_contact_force"))


def convert_smooth_sphere(ctx: _Context, el: etree._Element) -> None:
    """SmoothSphereHalfSpaceForce -> the sphere's and half space's geoms and one ``<pair>``."""
    name = el.get("name", "")
    if el.find("socket_sphere") is None:  # Moco's form before OpenSim 4.3: the geometry inline
        ctx.out.skipped.append(Skipped(el.tag, name, "written in the pre-4.3 form (sphere and half space given "
                                       "inline, not as contact geometry): not converted; its sphere passes "
                                       "through the half space in MuJoCo (open and save it in OpenSim 4.6)"))
        return
    sphere = ctx.builder.doc.resolve(el.find("socket_sphere"))
    half_space = ctx.builder.doc.resolve(el.find("socket_half_space"))
    if sphere.tag != "ContactSphere" or half_space.tag != "ContactHalfSpace":
        raise ctx.builder.doc.error(el, f"connects a {sphere.tag} and a {half_space.tag}; it needs a ContactSphere "
                                        "and a ContactHalfSpace")
    vals = [_number(el, prop, default, ctx) for prop, default in (
        ("stiffness", 1.0), ("dissipation", 0.0), ("static_friction", 0.0), ("dynamic_friction", 0.0),
        ("viscous_friction", 0.0), ("transition_velocity", 0.01))]
    smoothing = {key: _number(el, prop, default, ctx) for prop, default, key in _SMOOTHING}
    if min(vals) < 0 or vals[-1] <= 0 or min(smoothing.values()) < 0:
        raise ctx.builder.doc.error(el, "has a negative stiffness, dissipation, friction or smoothing, or a "
                                        "transition_velocity that is not positive")
    surface = Surface(*vals[:5])
    a, b = (_add_geom(ctx, half_space), surface), (_add_geom(ctx, sphere), surface)
    why = _pairable(a, b)
    if why:
        ctx.out.skipped.append(Skipped(el.tag, name, f"its sphere and half space cannot touch in MuJoCo ({why}): "
                                                     "it applies no force"))
        return
    _add_pair(ctx, name, a, b, vals[-1], smoothing)
    ctx.out.contact.forces.append(name)


def skip_force(ctx: _Context, el: etree._Element) -> None:
    """ElasticFoundationForce: listed as skipped with what that changes."""
    ctx.out.skipped.append(Skipped(el.tag, el.get("name", ""), CONTACT_SKIPS[el.tag]))


def skip_unused_geometry(ctx: _Context) -> None:
    """List every ContactGeometry without a geom as skipped, with why (call after every force)."""
    store: ContactConversion = ctx.out.contact
    for el in ctx.reader.set_objects("ContactGeometrySet"):
        name = el.get("name", "")
        if name in store.geoms:
            continue
        ctx.out.handled.add((el.tag, name))
        why = store.unused.get(name, "no converted force uses this contact geometry, so it has no MuJoCo geom")
        ctx.out.skipped.append(Skipped(el.tag, name, why))


# -- after compiling ------------------------------------------------------------------------
def _effective_mass(model: mujoco.MjModel, data: mujoco.MjData, cp: ContactPair) -> float:
    """Mass (kg) the contact moves along its normal at the default pose: 1 / (n·J M⁻¹ Jᵀ·n)."""
    g1, g2 = model.geom(cp.first.geom).id, model.geom(cp.second.geom).id
    c1, c2 = data.geom_xpos[g1].copy(), data.geom_xpos[g2].copy()
    if cp.first.kind == "plane":
        normal = data.geom_xmat[g1].reshape(3, 3)[:, 2].copy()
        point = c2 - cp.second.radius * normal
    else:
        d = c2 - c1
        normal = d / np.linalg.norm(d) if np.linalg.norm(d) > 1e-12 else np.array([0.0, 0.0, 1.0])
        point = 0.5 * (c1 + cp.first.radius * normal + c2 - cp.second.radius * normal)
    rows = np.zeros(model.nv)
    for gid, sign in ((g1, -1.0), (g2, 1.0)):
        jac = np.zeros((3, model.nv))
        mujoco.mj_jac(model, data, jac, None, point, int(model.geom_bodyid[gid]))
        rows += sign * (normal @ jac)
    x = np.zeros(model.nv)
    mujoco.mj_solveM(model, data, x.reshape(1, -1), rows.reshape(1, -1))
    inv = float(rows @ x)
    return 1.0 / inv if inv > 1e-12 else float(np.sum(model.body_mass))


def fit_contacts(out: ForceConversion, spec: mujoco.MjSpec, model: mujoco.MjModel, builder: MjcfBuilder) -> None:
    """Set every contact pair's ``solref``, ``solreffriction`` from its Hunt-Crossley law and the
    compiled ``model`` (effective masses at the default pose); elliptic cones when there is a pair."""
    pairs: list[ContactPair] = out.contact.pairs
    if not pairs:
        return
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    gravity = float(np.linalg.norm(model.opt.gravity)) or 9.80665
    dt = float(model.opt.timestep)
    for cp in pairs:
        bodies = [int(model.geom_bodyid[model.geom(g.geom).id]) for g in (cp.first, cp.second)]
        cp.inverse_weight = float(sum(model.body_invweight0[b, 0] for b in bodies))
        fit = fit_smooth if isinstance(cp.law, SmoothHuntCrossley) else fit_linear
        cp.fit = fit(cp.law, _effective_mass(model, data, cp), gravity, dt)
        if cp.fit.margin > 0:
            cp.pair.margin = cp.fit.margin
        mu = max(cp.fit.friction, 1e-5)
        cp.pair.friction = [mu, mu, 0.005, 0.0001, 0.0001]
        cp.pair.condim = 3 if cp.fit.friction > 0 else 1
        cp.pair.solref = list(cp.fit.solref(cp.inverse_weight))
        cp.pair.solreffriction = list(cp.fit.solreffriction(cp.inverse_weight))
        if math.pi / cp.fit.omega < 4 * dt:
            builder.result.notes.append(f"contact pair '{cp.name}': an impact lasts {1e3 * math.pi / cp.fit.omega:.3g}"
                                        f" ms, under 4 steps of {1e3 * dt:g} ms (use a smaller timestep)")
    builder.result.notes.append(f"{len(pairs)} contact pairs: MuJoCo's elliptic friction cone (opt.cone)")


def measure_contacts(out: ForceConversion, model: mujoco.MjModel, builder: MjcfBuilder) -> None:
    """Record each HuntCrossleyForce's measured errors in ``builder.result.approximations``: MuJoCo's
    contact (at the model's timestep, on each pair's effective mass, under the model's gravity)
    against Simbody's law, for impacts at :data:`~o2m.convert.contact_fit.SPEEDS` and a slide from
    :data:`~o2m.convert.contact_fit.SLIDE_SPEED`."""
    gravity = float(np.linalg.norm(model.opt.gravity))
    dt = float(model.opt.timestep)
    by_force: dict[str, list[ContactPair]] = {}
    for cp in out.contact.pairs:
        by_force.setdefault(cp.force, []).append(cp)
    for force, pairs in by_force.items():
        smooth = isinstance(pairs[0].law, SmoothHuntCrossley)
        if smooth:
            falls = [(cp, measure_falls(cp.law, cp.fit, dt, SOLIMP, gravity)) for cp in pairs]
            builder.result.approximations.extend(_fall_records(force, falls))
        else:
            impacts = [(cp, measure_impacts(cp.law, cp.fit, dt, SOLIMP, gravity)) for cp in pairs]
            builder.result.approximations.extend(_impact_records(force, impacts, gravity))
        slide = measure_smooth_slide if smooth else measure_slide
        slides = [(cp, slide(cp.law, cp.fit, dt, SOLIMP, gravity)) for cp in pairs
                  if cp.fit.friction > 0 and gravity > 0]
        if slides:
            builder.result.approximations.append(_slide_record(force, slides))


#: The ``what`` of each contact approximation (tests and benchmarks find them by it).
IMPACT_PEAK = "peak penetration of an impact"
IMPACT_RESTITUTION = "coefficient of restitution of an impact"
IMPACT_DURATION = "contact time of an impact"
FALL_DEEPEST = "deepest point of an impact"
SLIDE_DISTANCE = f"stopping distance of a slide from {SLIDE_SPEED:g} m/s"


def _impact_records(force: str, rows: list[tuple[ContactPair, list]], gravity: float) -> list[Approximation]:
    """Worst errors over the pairs and speeds: peak penetration (%), restitution (absolute), contact time (%)."""
    element = rows[0][0].element
    triples = [(hc, mj) for _, ms in rows for _, hc, mj in ms]
    masses = sorted(cp.fit.mass for cp, _ in rows)
    where = (f"{len(rows)} pairs, effective masses {masses[0]:.3g}-{masses[-1]:.3g} kg falling at "
             f"{', '.join(f'{v:g}' for v in SPEEDS)} m/s; spring-damper fitted at {REFERENCE_SPEED:g} m/s")
    resting = max(abs(cp.fit.mass * gravity / cp.fit.stiffness / cp.law.resting(cp.fit.mass * gravity) - 1)
                  for cp, _ in rows) if gravity > 0 else 0.0
    hc_e = [hc.restitution for _, ms in rows for _, hc, _ in ms]
    mj_e = [mj.restitution for _, ms in rows for _, _, mj in ms]
    peak = max(abs(mj.peak / hc.peak - 1) for hc, mj in triples)
    stays = sum(hc.stays for hc, _ in triples), sum(mj.stays for _, mj in triples)
    if any(stays):  # gravity holds the body on the surface: no rebound, no end of contact
        where += (f"; the body stays on the surface at {stays[0]} of {len(triples)} impacts in Hunt-Crossley, "
                  f"{stays[1]} in MuJoCo")
    return [
        Approximation(element, force, IMPACT_PEAK, 100 * peak, "%",
                      f"{where}; resting penetration off by up to {100 * resting:.3g} %"),
        Approximation(element, force, IMPACT_RESTITUTION,
                      max(abs(mj.restitution - hc.restitution) for hc, mj in triples), "",
                      f"{where}; Hunt-Crossley {min(hc_e):.3g}-{max(hc_e):.3g}, MuJoCo {min(mj_e):.3g}-{max(mj_e):.3g} "
                      "(a spring-damper's restitution does not fall with speed)"),
        Approximation(element, force, IMPACT_DURATION,
                      100 * max(_duration_error(hc, mj) for hc, mj in triples), "%", where)]


def _duration_error(hc: Impact, mj: Impact) -> float:
    """MuJoCo's contact time relative to Hunt-Crossley's, less 1 (0 where both stay on the
    surface, ``inf`` where only one does)."""
    if hc.stays and mj.stays:
        return 0.0
    return math.inf if hc.stays or mj.stays else abs(mj.duration / hc.duration - 1)


def _fall_records(force: str, rows: list[tuple[ContactPair, list]]) -> list[Approximation]:
    """A smooth force's worst errors over pairs and speeds: deepest point (mm), restitution (absolute)."""
    triples = [(cp, law, mj) for cp, ms in rows for _, law, mj in ms]
    margins = sorted(cp.fit.margin for cp, _ in rows)
    where = (f"{len(rows)} pairs, margins {1e3 * margins[0]:.3g}-{1e3 * margins[-1]:.3g} mm, falling from where "
             f"neither pushes at {', '.join(f'{v:g}' for v in SPEEDS)} m/s; fitted at {REFERENCE_SPEED:g} m/s")
    depth = ", ".join(f"{1e3 * law.deepest:.3g}/{1e3 * mj.deepest:.3g}" for _, law, mj in triples[:len(SPEEDS)])
    return [
        Approximation("SmoothSphereHalfSpaceForce", force, FALL_DEEPEST,
                      1e3 * max(abs(mj.deepest - law.deepest) for _, law, mj in triples), "mm",
                      f"{where}; smooth law/MuJoCo {depth} mm (negative: above the surface)"),
        Approximation("SmoothSphereHalfSpaceForce", force, IMPACT_RESTITUTION,
                      max(abs(mj.restitution - law.restitution) for _, law, mj in triples), "", where)]


def _slide_record(force: str, rows: list[tuple[ContactPair, tuple]]) -> Approximation:
    err = max(abs(mj.distance / hc.distance - 1) for _, (hc, mj) in rows)
    laws = {(cp.fit.friction, cp.law.static_friction, cp.law.dynamic_friction, cp.law.viscous_friction)
            for cp, _ in rows}
    mu = ", ".join(f"mu = {m:.3g} for static {s:.3g}, dynamic {d:.3g}, viscous {v:.3g} s/m"
                   for m, s, d, v in sorted(laws))
    dist = ", ".join(sorted({f"{hc.distance:.3g}/{mj.distance:.3g}" for _, (hc, mj) in rows}))
    return Approximation(rows[0][0].element, force, SLIDE_DISTANCE, 100 * err, "%",
                         f"{len(rows)} pairs, stopped below {100 * STOPPED:g} % of the speed; Hunt-Crossley/MuJoCo "
                         f"{dist} m; friction {mu}")
