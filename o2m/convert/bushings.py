"""BushingForce as joint springs, fixed tendons or a spatial tendon, where MuJoCo can give its force.

OpenSim's BushingForce deflects frame 2 against frame 1 by X-Y-Z body-fixed angles and a
translation in frame 1, θ (6,), and applies ``-K θ - D θ̇`` (diagonal K, D: N m/rad, N/m; N m s/rad,
N s/m) as generalized forces on those six deflections: on the model's coordinates q that is
``-Jᵀ (K θ + D J q̇)``, J = ∂θ/∂q. Only the free, independent coordinates of the joints on the tree
path between its two bodies move θ. Where every stiff or damped deflection is linear in them over
their ranges, θ = C q + θ0 (checked within :data:`BUSHING_LINEAR_TOLERANCE` on samples), the force
is exactly ``-Cᵀ K (C q + θ0) - Cᵀ D C q̇``, which MuJoCo gives as:

- one coordinate: that joint's spring (``stiffness`` Σ K_i c_i², ``springref``) and ``damping``
  Σ D_i c_i², added to the joint's others (:func:`o2m.convert.limit_forces.set_joint_passive`);
- several: one fixed tendon per stiff or damped deflection i, on the coordinates' MuJoCo joints
  (each named as its coordinate and carrying its value) with coefficients C_i, ``stiffness`` K_i,
  ``springlength`` -θ0_i and ``damping`` D_i (a 3-coordinate joint whose axes are the bushing's
  X-Y-Z axes; frames several joints apart whose axes stay aligned);
- none (every coordinate between the frames locked, or both frames on one body): nothing, since
  a force between two rigidly joined frames moves no coordinate.

The angles and the offsets are separate terms of the force, each converted on its own. An
isotropic translational stiffness k is, whatever the offsets do, a zero-length spring between the
frame origins: ½ k |p|², |p| their distance, which a spatial tendon between sites there gives
exactly (``stiffness`` k, ``springlength`` 0). Its isotropic damping d resists all relative motion
of the origins, a tendon's only motion along the line, so a damped one needs a tolerance.
Deflections not linear otherwise (rotations composed across joints about different axes), and an
isotropic spring's damping across the line between the origins, become a ghost body welded to
frame 2 whose joints are the deflection (:mod:`o2m.convert.bushing_ghost`), the report giving the
best linear fit's worst deflection error over the coordinates' ranges; with a
``bushing_tolerance`` (rad or m, :class:`o2m.convert.converter.ConvertOptions`) a fit within it
converts as above instead. The report records every converted bushing's measured
generalized-force error (:func:`measure_bushings`).
Angles in radians, lengths in metres.
"""

from __future__ import annotations

import itertools

import mujoco
import numpy as np
from lxml import etree
from scipy.optimize import linprog
from scipy.spatial.transform import Rotation

from o2m.convert.actuators import _body_site
from o2m.convert.builder import MjcfBuilder
from o2m.convert.bushing_ghost import add_ghost, pose_ghost
from o2m.convert.force_context import (
    N_POSES,
    BushingFit,
    ForceConversion,
    JointSpring,
    _Context,
    _isolated,
    _random_values,
    _vector,
)
from o2m.convert.limit_forces import set_joint_passive
from o2m.convert.records import Approximation
from o2m.osim.skeleton import Joint, Skipped

__all__ = ["BUSHING_LINEAR_TOLERANCE", "bushing_generalized_force", "convert_bushing", "convert_bushing_gains",
           "fit_deflection",
           "measure_bushings"]

#: A deflection counts as linear in its coordinates when a linear function fits it within this
#: (rad or m) at every sample of their ranges.
BUSHING_LINEAR_TOLERANCE = 1e-9
#: The names of the six deflections (frame 2's X-Y-Z angles and offset in frame 1), for tendons.
DEFLECTIONS = ("rx", "ry", "rz", "tx", "ty", "tz")
#: Samples of one coordinate's range (a line fitted through them).
_SAMPLES = 41
#: Seeded random samples per coordinate when there are several (plus the range's corners).
_SAMPLES_PER_COORDINATE = 60
#: Corners of the coordinates' box are sampled up to this many coordinates (2^n corners).
_MAX_CORNER_COORDINATES = 8
#: A coefficient whose effect over its coordinate's range stays below this (rad or m) is zero.
_ZERO_EFFECT = 1e-12
#: Step of the five-point central differences giving J = ∂θ/∂q when measuring (rad or m).
_STEP = 1e-4


def convert_bushing(ctx: _Context, el: etree._Element) -> None:
    """BushingForce -> a joint spring, fixed tendons, a spatial tendon, a ghost body or nothing; an
    OpenSim 3.x one is skipped (see the module)."""
    if el.find("socket_frame1") is None or el.find("socket_frame2") is None:
        _skip(ctx, el, "an OpenSim 3.x bushing (no socket_frame1/2) is not converted")
        return
    gains = np.concatenate([_vector(el, "rotational_stiffness", (0.0, 0.0, 0.0), ctx),
                            _vector(el, "translational_stiffness", (0.0, 0.0, 0.0), ctx)])
    damps = np.concatenate([_vector(el, "rotational_damping", (0.0, 0.0, 0.0), ctx),
                            _vector(el, "translational_damping", (0.0, 0.0, 0.0), ctx)])
    convert_bushing_gains(ctx, el, gains, damps)


def convert_bushing_gains(ctx: _Context, el: etree._Element, gains: np.ndarray, damps: np.ndarray) -> None:
    """A bushing between ``el``'s socket_frame1/2 with stiffness ``gains`` and damping ``damps``
    (6,): about x y z (N m/rad, N m s/rad), then along x y z (N/m, N s/m)."""
    name = el.get("name")
    ends = [ctx.reader.socket_frame(el, s)[:2] for s in ("socket_frame1", "socket_frame2")]
    coords = _bushing_coordinates(ctx.builder, ends[0][0], ends[1][0])
    fit = BushingFit(name, coords, ends, gains, damps, *fit_deflection(ctx.builder, ends, coords))
    fit.element = el.tag
    plan = _plan(fit, ctx.bushing_tolerance)
    if isinstance(plan, str):
        fit.form = add_ghost(ctx, fit, plan)
        ctx.out.bushings.append(fit)
        return
    fit.linear, spatial = plan
    fit.fit_error = float(fit.residual[fit.linear].max(initial=0.0))
    forms = []
    if not coords:
        ctx.builder.result.notes.append(
            f"{el.tag} '{name}': its frames do not move relative to each other (every coordinate between them "
            "is locked, or they are on one body), so it moves no coordinate and needs no MuJoCo element")
    elif len(coords) == 1 and fit.linear.any():
        forms.append(_joint_spring(ctx, fit))
    elif fit.linear.any():
        forms.append(_fixed_tendons(ctx, fit))
    if spatial:
        forms.append(_spatial_tendon(ctx, fit))
    fit.form = "; ".join(forms)
    ctx.out.bushings.append(fit)


def _plan(fit: BushingFit, tolerance: float | None) -> tuple[np.ndarray, bool] | str:
    """Which stiff or damped deflections become C q + θ0 (6,) and whether the translations become a
    zero-length spatial tendon; or why neither does (it then becomes a ghost body). The angles and the offsets are
    separate terms of the force, each block taken the first way that fits: linear within
    :data:`BUSHING_LINEAR_TOLERANCE`, an isotropic translational spring, linear within ``tolerance``."""
    acting = (fit.stiffness != 0.0) | (fit.damping != 0.0)
    linear, spatial, failures = np.zeros(6, bool), False, []
    for block, unit in ((slice(0, 3), "rad"), (slice(3, 6), "m")):
        act = np.zeros(6, bool)
        act[block] = acting[block]
        worst = float(fit.residual[act].max(initial=0.0))
        point = unit == "m" and _point_spring(fit.stiffness[block], fit.damping[block])
        if not act.any() or worst <= BUSHING_LINEAR_TOLERANCE:
            linear |= act
        elif point and (fit.damping[3] == 0.0 or tolerance is not None):
            spatial = True
        elif point:
            return (f"its translational damping ({fit.damping[3]:g} N s/m) also resists motion across the line "
                    "between its frame origins, which a tendon's damping cannot (with any "
                    "ConvertOptions.bushing_tolerance it converts, that part left out)")
        elif tolerance is not None and worst <= tolerance:
            linear |= act
        else:
            failures.append((worst, unit))
    if failures:
        worst, unit = max(failures)
        names = ", ".join(f"'{c}'" for c in fit.coordinates)
        return (f"its deflections are not linear in {names} (the best linear fit is up to {worst:.3g} {unit} off "
                "over their ranges; a ConvertOptions.bushing_tolerance that large converts it approximately): MuJoCo "
                "has no such spring")
    return linear, spatial


def _point_spring(stiffness: np.ndarray, damping: np.ndarray) -> bool:
    """An isotropic translational stiffness k > 0 and damping d (3,): -k p - d ṗ, a zero-length
    spring between the two frame origins (d: its radial part)."""
    return bool(stiffness[0] > 0.0 and np.all(stiffness == stiffness[0]) and np.all(damping == damping[0]))


def _spatial_tendon(ctx: _Context, fit: BushingFit) -> str:
    """A spatial tendon between sites at the two frame origins, ``stiffness`` k and ``springlength``
    0: its force -k L ∂L/∂q is -k (∂p/∂q)ᵀ p (L = |p|), exactly; ``damping`` d gives -d L̇ along the line."""
    sites = [_body_site(ctx, body, f"{fit.name}_frame{i}", frame.pos) for i, (body, frame) in enumerate(fit.ends, 1)]
    tendon = ctx.spec.add_tendon(name=ctx.unique("tendon", fit.name), group=5, rgba=[0.9, 0.6, 0.1, 1.0])
    for site in sites:
        tendon.wrap_site(site)
    k, d = float(fit.stiffness[3]), float(fit.damping[3])
    tendon.stiffness = [k, 0.0, 0.0]
    tendon.damping = [d, 0.0, 0.0]
    tendon.springlength = [0.0, 0.0]
    ctx.out.exact[("tendon", tendon.name)] = {"stiffness": np.array([k, 0.0, 0.0]), "damping": np.array([d, 0.0, 0.0]),
                                              "springlength": np.zeros(2)}
    fit.tendons.append(tendon.name)
    return (f"a zero-length spring on spatial tendon '{tendon.name}' between its frame origins (stiffness {k:g} N/m"
            + (f", damping {d:g} N s/m along the line only)" if d else ")"))


def _skip(ctx: _Context, el: etree._Element, why: str) -> None:
    ctx.out.skipped.append(Skipped(el.tag, el.get("name"), f"{why}; its bodies move without its spring and damping"))


def _path_joints(builder: MjcfBuilder, body1: str, body2: str) -> list[Joint]:
    """The joints on the tree path between ``body1`` and ``body2`` (none when they are one body)."""
    by_child = {j.child: j for j in builder.skel.joints}

    def up(body: str) -> list[Joint]:
        chain = []
        while body in by_child and len(chain) <= len(by_child):
            chain.append(by_child[body])
            body = by_child[body].parent
        return chain

    chain1, chain2 = up(body1), up(body2)
    common = {j.name for j in chain1} & {j.name for j in chain2}
    return [j for j in chain1 + chain2 if j.name not in common]


def _bushing_coordinates(builder: MjcfBuilder, body1: str, body2: str) -> list[str]:
    """The free independent coordinates that move the frames of ``body1`` and ``body2`` relative to
    each other, in the skeleton's order: the bases of the coordinates of the joints between them
    that have a MuJoCo joint (a free coordinate without one moves no axis)."""
    bases = {builder.drivers[c].base for j in _path_joints(builder, body1, body2) for c in j.coordinates}
    return [c for c, coord in builder.skel.coordinates.items()
            if c in bases and not coord.locked and c in builder.coord_joint]


def _ranges(builder: MjcfBuilder, coords: list[str]) -> np.ndarray:
    """(n, 2): each coordinate's fit range (rad or m)."""
    return np.array([builder.fit_range(c, builder.coord_joint[c][1].kind) for c in coords]).reshape(-1, 2)


def _samples(ranges: np.ndarray, seed: int = 0) -> np.ndarray:
    """(m, n) coordinate values: a line over one range; seeded random points and the corners of several."""
    n = ranges.shape[0]
    if n == 1:
        return np.linspace(ranges[0, 0], ranges[0, 1], _SAMPLES)[:, None]
    unit = np.random.default_rng(seed).uniform(size=(_SAMPLES_PER_COORDINATE * n, n))
    if n <= _MAX_CORNER_COORDINATES:
        unit = np.vstack([unit, np.array(list(itertools.product((0.0, 1.0), repeat=n)))])
    return ranges[:, 0] + unit * (ranges[:, 1] - ranges[:, 0])


def fit_deflection(builder: MjcfBuilder, ends, coords: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The linear fit θ ≈ C q + θ0 of a bushing's deflection over its coordinates' ranges: C (6, n),
    θ0 (6,) and each deflection's worst error at the samples (6,) (rad or m). Least squares, which
    is exact for a linear deflection; a deflection it leaves more than
    :data:`BUSHING_LINEAR_TOLERANCE` off gets the minimax fit (the least worst error) instead.
    ``ends``: each frame's (body, transform in the body)."""
    if not coords:
        return np.zeros((6, 0)), _deflection(builder, {}, ends), np.zeros(6)
    ranges = _ranges(builder, coords)
    qs = _samples(ranges)
    defl = np.array([_deflection(builder, dict(zip(coords, map(float, q), strict=True)), ends) for q in qs])  # (m, 6)
    design = np.hstack([qs, np.ones((qs.shape[0], 1))])
    if len(coords) == 1:  # the fit of the one-joint conversion, kept bit for bit
        sol = np.polyfit(qs[:, 0], defl, 1)
    else:
        sol = np.linalg.lstsq(design, defl, rcond=None)[0]  # (n + 1, 6)
    residual = np.max(np.abs(design @ sol - defl), axis=0)
    for i in np.flatnonzero(residual > BUSHING_LINEAR_TOLERANCE):
        sol[:, i], residual[i] = _minimax_line(design, defl[:, i])
    slopes, offset = sol[:-1].T, sol[-1]
    slopes = np.where(np.abs(slopes) * (ranges[:, 1] - ranges[:, 0]) <= _ZERO_EFFECT, 0.0, slopes)
    return slopes, offset, residual


def _minimax_line(design: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, float]:
    """The coefficients x (k,) minimising max |design @ x - values| (design (m, k)), and that maximum:
    a linear programme in (x, t), min t with -t <= design @ x - values <= t."""
    m, k = design.shape
    ones = np.ones((m, 1))
    bounds = [(None, None)] * k + [(0.0, None)]
    res = linprog(np.r_[np.zeros(k), 1.0], A_ub=np.block([[design, -ones], [-design, -ones]]),
                  b_ub=np.r_[values, -values], bounds=bounds, method="highs")
    if not res.success:  # keep least squares (HiGHS solves this small, always feasible programme)
        x = np.linalg.lstsq(design, values, rcond=None)[0]
        return x, float(np.max(np.abs(design @ x - values)))
    x = res.x[:k]
    return x, float(np.max(np.abs(design @ x - values)))


def _deflection(builder: MjcfBuilder, changes: dict[str, float], ends) -> np.ndarray:
    """(6,): frame 2's X-Y-Z body-fixed angles (rad) and origin (m) in frame 1 at a pose."""
    frames = builder.ground_frames_at(builder.coordinate_values(changes), bodies=(ends[0][0], ends[1][0]))
    f1 = frames[ends[0][0]] @ ends[0][1]
    f2 = frames[ends[1][0]] @ ends[1][1]
    angles = Rotation.from_matrix(f1.rot.T @ f2.rot).as_euler("XYZ")
    return np.concatenate([angles, f1.rot.T @ (f2.pos - f1.pos)])


def _joint_spring(ctx: _Context, fit: BushingFit) -> str:
    """One coordinate: Σ K_i (c_i q + θ0_i) c_i = k (q - ref) over the linear deflections i, its
    joint's spring and damping."""
    q, slope = fit.coordinates[0], fit.slopes[:, 0]
    gains, damps = np.where(fit.linear, fit.stiffness, 0.0), np.where(fit.linear, fit.damping, 0.0)
    k = float(np.sum(gains * slope ** 2))
    ref = float(-np.sum(gains * slope * fit.offsets) / k) if k != 0.0 else 0.0
    ctx.out.joint_springs.append(JointSpring(fit.name, q, k, ref, float(np.sum(damps * slope ** 2))))
    set_joint_passive(ctx, ctx.spec.joint(q), q)
    fit.joint_spring = True
    return f"the spring and damping of joint '{q}'{_linear_note(fit)}"


def _fixed_tendons(ctx: _Context, fit: BushingFit) -> str:
    """Several coordinates: one fixed tendon per linear deflection that they move."""
    for i in np.flatnonzero(fit.linear):
        coefs, length0 = fit.slopes[i], -float(fit.offsets[i])
        if not np.any(coefs):
            continue  # a constant deflection: a force that moves no coordinate
        if length0 == -1.0:  # MuJoCo reads springlength -1 as "the length at qpos0": flip the tendon
            coefs, length0 = -coefs, 1.0
        tendon = ctx.spec.add_tendon(name=ctx.unique("tendon", f"{fit.name}_{DEFLECTIONS[i]}"), group=5)
        for c, coef in zip(fit.coordinates, coefs, strict=True):
            if coef != 0.0:
                tendon.wrap_joint(c, float(coef))
                ctx.out.exact[("tendon joint", f"{tendon.name}/{c}")] = {"coef": np.array([coef])}
        tendon.stiffness = [float(fit.stiffness[i]), 0.0, 0.0]
        tendon.damping = [float(fit.damping[i]), 0.0, 0.0]
        tendon.springlength = [length0, length0]
        ctx.out.exact[("tendon", tendon.name)] = {"stiffness": np.array([fit.stiffness[i], 0.0, 0.0]),
                                                  "damping": np.array([fit.damping[i], 0.0, 0.0]),
                                                  "springlength": np.array([length0, length0])}
        fit.tendons.append(tendon.name)
    count = f"{len(fit.tendons)} fixed tendon" + ("s" if len(fit.tendons) != 1 else "")
    return f"{count} ({', '.join(fit.tendons)}) on joints {', '.join(fit.coordinates)}{_linear_note(fit)}"


def _linear_note(fit: BushingFit) -> str:
    return (f": its deflection as C q + θ0 in its coordinates, the fit's worst deflection error {fit.fit_error:.3g} "
            "rad or m")


# -- measurement ----------------------------------------------------------------------------------
def _five_point(f, x: np.ndarray) -> np.ndarray:
    """(m, n): ∂f/∂x of ``f`` (n,) -> (m,) at ``x`` by five-point central differences (step :data:`_STEP`)."""
    cols = []
    for e in np.eye(len(x)) * _STEP:
        cols.append((8.0 * (f(x + e) - f(x - e)) - f(x + 2 * e) + f(x - 2 * e)) / (12.0 * _STEP))
    return np.array(cols).T


def bushing_generalized_force(builder: MjcfBuilder, fit: BushingFit, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
    """(n,): OpenSim's generalized force -Jᵀ (K θ + D J q̇) of a bushing on its coordinates at
    values ``q`` and speeds ``qdot`` (n,), J = ∂θ/∂q from the skeleton's kinematics."""
    def theta(values: np.ndarray) -> np.ndarray:
        return _deflection(builder, dict(zip(fit.coordinates, map(float, values), strict=True)), fit.ends)

    jac = _five_point(theta, q)  # (6, n)
    return -jac.T @ (fit.stiffness * theta(q) + fit.damping * (jac @ qdot))


def _mujoco_force(model: mujoco.MjModel, d: mujoco.MjData, plan, values: dict[str, float], fit: BushingFit,
                  qdot: np.ndarray) -> np.ndarray:
    """(n,): the generalized force on the bushing's coordinates of ``model``'s passive forces (its
    tendons alone), at coordinate ``values`` and speeds ``qdot``: Gᵀ qfrc_passive with G = ∂qvel/∂q̇
    (nv, n), so that joints driven by equalities count through their coordinates."""
    from o2m.mj.posing import pose_mujoco

    def qpos_at(q: np.ndarray) -> np.ndarray:
        pose_mujoco(model, d, {**values, **dict(zip(fit.coordinates, map(float, q), strict=True))}, plan=plan)
        pose_ghost(model, d, fit)
        return d.qpos.copy()

    q = np.array([values[c] for c in fit.coordinates])
    base = qpos_at(q)
    step = np.zeros(model.nv)

    def displacement(x: np.ndarray) -> np.ndarray:
        mujoco.mj_differentiatePos(model, step, 1.0, base, qpos_at(x))
        return step.copy()

    g = _five_point(displacement, q)  # (nv, n)
    qpos_at(q)
    d.qvel[:] = g @ qdot
    mujoco.mj_fwdPosition(model, d)
    mujoco.mj_fwdVelocity(model, d)
    return g.T @ d.qfrc_passive


def measure_bushings(out: ForceConversion, model: mujoco.MjModel, builder: MjcfBuilder) -> None:
    """Record each converted bushing's worst generalized-force error against OpenSim's formula
    (N m or N) at :data:`~o2m.convert.force_context.N_POSES` random poses and speeds (up to 1 rad/s
    or m/s) in ``builder.result.approximations``: its MuJoCo tendons alone acting, and for a joint
    spring (which also holds the joint's other springs) -Cᵀ K (C q + θ0) - Cᵀ D C q̇."""
    from o2m.mj.posing import joint_equality_plan

    for fit in out.bushings:
        if not fit.coordinates:
            continue
        only = _isolated(model)
        only.body_gravcomp[:] = 0.0  # a ghost's weight cancelled is no part of the bushing's force
        for t in fit.tendons:
            tid = model.tendon(t).id
            only.tendon_stiffness[tid] = model.tendon_stiffness[tid]
            only.tendon_damping[tid] = model.tendon_damping[tid]
        for j in fit.ghost_joints:
            jid = model.joint(j).id
            only.jnt_stiffness[jid] = model.jnt_stiffness[jid]
            only.dof_damping[model.jnt_dofadr[jid]] = model.dof_damping[model.jnt_dofadr[jid]]
        d = mujoco.MjData(only)
        plan = joint_equality_plan(only)
        speeds = np.random.default_rng(1).uniform(-1.0, 1.0, size=(N_POSES, len(fit.coordinates)))
        worst = peak = 0.0
        for values, qdot in zip(_random_values(builder, N_POSES), speeds, strict=True):
            q = np.array([values[c] for c in fit.coordinates])
            expected = bushing_generalized_force(builder, fit, q, qdot)
            acting = fit.tendons or fit.ghost_joints
            got = _mujoco_force(only, d, plan, values, fit, qdot) if acting else np.zeros(len(q))
            if fit.joint_spring:
                c, gains, damps = fit.slopes, fit.stiffness * fit.linear, fit.damping * fit.linear
                got = got - c.T @ (gains * (c @ q + fit.offsets) + damps * (c @ qdot))
            worst = max(worst, float(np.max(np.abs(got - expected))))
            peak = max(peak, float(np.max(np.abs(expected))))
        kinds = {builder.coord_joint[c][1].kind for c in fit.coordinates}
        units = {frozenset({"rotation"}): "N m", frozenset({"translation"}): "N"}.get(frozenset(kinds), "N m or N")
        builder.result.approximations.append(Approximation(
            fit.element, fit.name, fit.form, worst, units,
            f"the converted force against -Jᵀ(K θ + D θ̇) from the skeleton's kinematics (J = ∂θ/∂q) at {N_POSES} "
            f"poses (largest {peak:.3g})"))
