"""BushingForce as joint springs or fixed tendons, where its deflections are linear in coordinates.

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

Deflections not linear (rotations composed across joints about different axes) are skipped, the
reason giving the best linear fit's worst deflection error over the coordinates' ranges; with a
``bushing_tolerance`` (rad or m, :class:`o2m.convert.converter.ConvertOptions`) a fit within it
converts as above and the report records its measured generalized-force error. Angles in
radians, lengths in metres.
"""

from __future__ import annotations

import itertools

import mujoco
import numpy as np
from lxml import etree
from scipy.spatial.transform import Rotation

from o2m.convert.builder import MjcfBuilder
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

__all__ = ["BUSHING_LINEAR_TOLERANCE", "convert_bushing", "fit_deflection", "measure_bushings"]

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
    """BushingForce -> joint springs or fixed tendons, or a skip with the reason (see the module)."""
    name = el.get("name")
    if el.find("socket_frame1") is None or el.find("socket_frame2") is None:
        _skip(ctx, el, "an OpenSim 3.x bushing (no socket_frame1/2) is not converted")
        return
    ends = [ctx.reader.socket_frame(el, s)[:2] for s in ("socket_frame1", "socket_frame2")]
    gains = np.concatenate([_vector(el, "rotational_stiffness", (0.0, 0.0, 0.0), ctx),
                            _vector(el, "translational_stiffness", (0.0, 0.0, 0.0), ctx)])
    damps = np.concatenate([_vector(el, "rotational_damping", (0.0, 0.0, 0.0), ctx),
                            _vector(el, "translational_damping", (0.0, 0.0, 0.0), ctx)])
    coords = _bushing_coordinates(ctx.builder, ends[0][0], ends[1][0])
    fit = BushingFit(name, coords, ends, gains, damps, *fit_deflection(ctx.builder, ends, coords))
    acting = (gains != 0.0) | (damps != 0.0)
    worst = float(fit.residual[acting].max()) if acting.any() else 0.0
    allowed = BUSHING_LINEAR_TOLERANCE if ctx.bushing_tolerance is None else ctx.bushing_tolerance
    if worst > max(allowed, BUSHING_LINEAR_TOLERANCE):
        names = ", ".join(f"'{c}'" for c in coords)
        _skip(ctx, el, f"its deflections are not linear in {names} (the best linear fit is up to {worst:.3g} rad "
                       f"or m off over their ranges; ConvertOptions.bushing_tolerance would accept it): MuJoCo has "
                       "no such spring")
        return
    fit.fit_error = worst
    if not coords:
        ctx.builder.result.notes.append(
            f"BushingForce '{name}': its frames do not move relative to each other (every coordinate between them "
            "is locked, or they are on one body), so it moves no coordinate and needs no MuJoCo element")
    elif len(coords) == 1:
        _joint_spring(ctx, fit)
    else:
        _fixed_tendons(ctx, fit, acting)
    ctx.out.bushings.append(fit)


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
    """The least-squares linear fit θ ≈ C q + θ0 of a bushing's deflection over its coordinates'
    ranges: C (6, n), θ0 (6,) and each deflection's worst error at the samples (6,) (rad or m).
    ``ends``: each frame's (body, transform in the body)."""
    if not coords:
        return np.zeros((6, 0)), _deflection(builder, {}, ends), np.zeros(6)
    ranges = _ranges(builder, coords)
    qs = _samples(ranges)
    defl = np.array([_deflection(builder, dict(zip(coords, map(float, q), strict=True)), ends) for q in qs])  # (m, 6)
    if len(coords) == 1:  # the fit of the one-joint conversion, kept bit for bit
        slope, offset = np.polyfit(qs[:, 0], defl, 1)
        slopes = slope[:, None]
    else:
        design = np.hstack([qs, np.ones((qs.shape[0], 1))])
        sol = np.linalg.lstsq(design, defl, rcond=None)[0]  # (n + 1, 6)
        slopes, offset = sol[:-1].T, sol[-1]
    residual = np.max(np.abs(qs @ slopes.T + offset - defl), axis=0)
    slopes = np.where(np.abs(slopes) * (ranges[:, 1] - ranges[:, 0]) <= _ZERO_EFFECT, 0.0, slopes)
    return slopes, offset, residual


def _deflection(builder: MjcfBuilder, changes: dict[str, float], ends) -> np.ndarray:
    """(6,): frame 2's X-Y-Z body-fixed angles (rad) and origin (m) in frame 1 at a pose."""
    frames = builder.ground_frames_at(builder.coordinate_values(changes))
    f1 = frames[ends[0][0]] @ ends[0][1]
    f2 = frames[ends[1][0]] @ ends[1][1]
    angles = Rotation.from_matrix(f1.rot.T @ f2.rot).as_euler("XYZ")
    return np.concatenate([angles, f1.rot.T @ (f2.pos - f1.pos)])


def _joint_spring(ctx: _Context, fit: BushingFit) -> None:
    """One coordinate: Σ K_i (c_i q + θ0_i) c_i = k (q - ref), its joint's spring and damping."""
    q, slope = fit.coordinates[0], fit.slopes[:, 0]
    k = float(np.sum(fit.stiffness * slope ** 2))
    ref = float(-np.sum(fit.stiffness * slope * fit.offsets) / k) if k != 0.0 else 0.0
    ctx.out.joint_springs.append(JointSpring(fit.name, q, k, ref, float(np.sum(fit.damping * slope ** 2))))
    set_joint_passive(ctx, ctx.spec.joint(q), q)


def _fixed_tendons(ctx: _Context, fit: BushingFit, acting: np.ndarray) -> None:
    """Several coordinates: one fixed tendon per stiff or damped deflection that they move."""
    for i in np.flatnonzero(acting):
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


# -- measurement ----------------------------------------------------------------------------------
def bushing_generalized_force(builder: MjcfBuilder, fit: BushingFit, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
    """(n,): OpenSim's generalized force -Jᵀ (K θ + D J q̇) of a bushing on its coordinates at
    values ``q`` and speeds ``qdot`` (n,), J by five-point central differences of the skeleton's kinematics."""
    def theta(values: np.ndarray) -> np.ndarray:
        return _deflection(builder, dict(zip(fit.coordinates, map(float, values), strict=True)), fit.ends)

    eye = np.eye(len(q)) * _STEP
    jac = np.array([(8 * (theta(q + e) - theta(q - e)) - theta(q + 2 * e) + theta(q - 2 * e)) / (12 * _STEP)
                    for e in eye]).T  # (6, n)
    return -jac.T @ (fit.stiffness * theta(q) + fit.damping * (jac @ qdot))


def _converted_force(model: mujoco.MjModel, d: mujoco.MjData, fit: BushingFit, dofs: list[int],
                     q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
    """(n,): the converted bushing's force: its tendons' passive force in ``model`` (posed in ``d``),
    or its joint spring's -Cᵀ K (C q + θ0) - Cᵀ D C q̇ (the joint's own spring also holds others)."""
    if fit.tendons:
        d.qvel[:] = 0.0
        d.qvel[dofs] = qdot
        mujoco.mj_fwdPosition(model, d)
        mujoco.mj_fwdVelocity(model, d)
        return d.qfrc_passive[dofs].copy()
    c = fit.slopes
    return -c.T @ (fit.stiffness * (c @ q + fit.offsets) + fit.damping * (c @ qdot))


def measure_bushings(out: ForceConversion, model: mujoco.MjModel, builder: MjcfBuilder) -> None:
    """Record each converted bushing's worst generalized-force error (N m or N) against OpenSim's
    formula at :data:`~o2m.convert.force_context.N_POSES` random poses and speeds (up to 1 rad/s
    or m/s), its tendons alone acting, in ``builder.result.approximations``."""
    from o2m.mj.posing import joint_equality_plan, pose_mujoco

    for fit in out.bushings:
        if not fit.coordinates:
            continue
        only = _isolated(model)
        for t in fit.tendons:
            tid = model.tendon(t).id
            only.tendon_stiffness[tid] = model.tendon_stiffness[tid]
            only.tendon_damping[tid] = model.tendon_damping[tid]
        d = mujoco.MjData(only)
        plan = joint_equality_plan(only)
        dofs = [int(only.jnt_dofadr[only.joint(c).id]) for c in fit.coordinates]
        speeds = np.random.default_rng(1).uniform(-1.0, 1.0, size=(N_POSES, len(dofs)))
        worst = peak = 0.0
        for values, qdot in zip(_random_values(builder, N_POSES), speeds, strict=True):
            pose_mujoco(only, d, values, plan=plan)
            q = np.array([values[c] for c in fit.coordinates])
            expected = bushing_generalized_force(builder, fit, q, qdot)
            worst = max(worst, float(np.max(np.abs(_converted_force(only, d, fit, dofs, q, qdot) - expected))))
            peak = max(peak, float(np.max(np.abs(expected))))
        form = (f"{len(fit.tendons)} fixed tendons ({', '.join(fit.tendons)}) on joints {', '.join(fit.coordinates)}"
                if fit.tendons else f"the spring and damping of joint '{fit.coordinates[0]}'")
        kinds = {builder.coord_joint[c][1].kind for c in fit.coordinates}
        units = {frozenset({"rotation"}): "N m", frozenset({"translation"}): "N"}.get(frozenset(kinds), "N m or N")
        builder.result.approximations.append(Approximation(
            "BushingForce", fit.name, f"{form}: its deflection as C q + θ0 in its coordinates, the fit's worst "
            f"deflection error {fit.fit_error:.3g} rad or m", worst, units,
            f"the converted force against -Jᵀ(K θ + D θ̇) from the skeleton's kinematics at {N_POSES} poses "
            f"(largest {peak:.3g})"))
