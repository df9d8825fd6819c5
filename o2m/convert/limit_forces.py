"""CoordinateLimitForce as MuJoCo joint springs, dead-band tendons and joint damping, fitted to
OpenSim's torque and measured against OpenSim's own ``calcLimitForce``.

OpenSim (``CoordinateLimitForce::calcLimitForce``): for a Rotational coordinate the limits and
the transition are degrees, stiffnesses N m/deg and damping N m/(deg/s); for any other motion type
(Translational, and Coupled — a coordinate whose joint axes are not all LinearFunctions of slope
±1) OpenSim reads them in the coordinate's own units, and so does o2m. The force is ``τ = -K_up(q) (q - q_up) +
K_lo(q) (q_lo - q) - c (K_up(q)/K_up + K_lo(q)/K_lo) q̇``, each ``K(q)`` a quintic
SimTK::Step over the transition width. Each side (upper, lower) becomes:

- nothing, when its torque stays below :data:`NEGLIGIBLE` over the grid (the coordinate's
  range and :data:`RANGE_MARGIN` of it beyond each end);
- the joint's linear spring (``stiffness``, ``springref``), when its step is fully on over
  the whole range (the side is then exactly linear there: MoBL's ``*_damping`` forces);
- else a fixed tendon on the joint with a one-sided dead band (``springlength``) and a
  polynomial stiffness ``a d + b d² + c d³`` (MuJoCo 4's polynomial springs; non-decreasing
  from 0 on the active side), edge and coefficients fitted minimax to OpenSim's torque over the grid.
  Measured on MoBL-ARMS' ``elbow_flexion_ligaments`` (peak 143 N m over the grid) this leaves
  0.19 N m (0.13 %), where the best linear joint spring leaves 62 N m, the best cubic joint
  spring 31 N m and the best joint limit in solref's direct (stiffness) form 38 N m.

The damping becomes joint damping, the constant that halves the worst error over the range:
exact when the step weight is constant there (the ``*_damping`` forces, whose limits never
bind inside the range). Joint limits are not used: their force is a constraint force, which
depends on the other forces, and the joint's ``range`` belongs to the coordinate's clamping.
The error is measured over the grid at speeds -1, 0, 1 against OpenSim's own
``calcLimitForce`` and MuJoCo's ``qfrc_passive`` (only that force's springs and damping
active) and recorded per force.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path

import mujoco
import numpy as np
from lxml import etree

from o2m.convert.builder import MjcfBuilder
from o2m.convert.force_context import (
    FAR,
    N_GRID,
    ForceConversion,
    LimitForce,
    SideFit,
    _Context,
    _coordinate,
    _isolated,
    _number,
)
from o2m.convert.records import Approximation
from o2m.osim import runtime
from o2m.osim.names import opensim_coordinate
from o2m.osim.skeleton import Skeleton, Skipped

__all__ = ["convert_coordinate_limit_force", "fit_deadband", "measure_limit_forces", "motion_type"]

#: Beyond the coordinate's range, limit forces are fitted and measured over this fraction of it.
RANGE_MARGIN = 0.1
#: Speeds (rad/s or m/s) at which the limit-force error is measured.
SPEEDS = (-1.0, 0.0, 1.0)
#: A side of a limit force whose torque stays below this (N m or N) over the grid is left out.
NEGLIGIBLE = 1e-5
#: A damping step weight (0 to 2) no larger than this over the range is round-off: no joint damping
#: (a symmetric force's weights left -1.8e-15 N m s/rad of it, a negative damping, on a walker's hips).
WEIGHT_ROUNDOFF = 1e-12


def motion_type(skel: Skeleton, coordinate: str) -> str:
    """OpenSim's MotionType of ``coordinate``: "rotational", "translational" or "coupled".

    As OpenSim 4.6 decides it: a CustomJoint coordinate is Rotational (Translational) when a
    rotation (translation) axis uses it through a LinearFunction of slope ±1, the last such
    axis deciding; else Coupled (also when no axis uses it). Other joint types give their
    coordinates' kinds."""
    coord = skel.coordinates[coordinate]
    joint = next(j for j in skel.joints if j.name == coord.joint)
    if joint.type != "CustomJoint":  # one identity axis per coordinate
        kind = next(ax.kind for ax in joint.rotations + joint.translations if ax.coordinate == coordinate)
        return "rotational" if kind == "rotation" else "translational"
    out = None
    for ax in joint.rotations + joint.translations:  # OpenSim's order: rotation1-3, translation1-3
        if ax.coordinate != coordinate:
            continue
        fn = next((c for c in ax.element if isinstance(c.tag, str) and c.tag[:1].isupper()), None)
        slope = None
        if fn is not None and fn.tag == "LinearFunction":
            coefs = (fn.findtext("coefficients") or "1 0").split()
            slope = float(coefs[0]) if coefs else None
        if slope in (1.0, -1.0):
            out = "rotational" if ax.kind == "rotation" else "translational"
        elif out is None:
            out = "coupled"
    return out or "coupled"


#: How far above the minimax error (relative) :func:`_minimax` looks for its smallest coefficients.
MINIMAX_SLACK = 1e-6
#: :func:`fit_deadband` locates its edge to this fraction of the searched interval: closely enough
#: that two machines' roundings give the same spring.
DEADBAND_XTOL = 1e-10
#: Weight of the RMS error beside the worst error when :func:`fit_deadband` chooses its edge.
DEADBAND_TIE = 1e-3


def _minimax(d: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float]:
    """(a, b, c) minimising max |h(d) - y| for h(d) = a d + b d² + c d³ (d >= 0 samples), with h
    non-decreasing from 0 (a >= 0, c >= 0, h' >= 0 up to 10 times the largest d): a linear programme."""
    from scipy.optimize import linprog

    basis = np.column_stack([d, d * d, d ** 3])
    scale = np.maximum(np.max(np.abs(basis), axis=0), 1e-300)
    a = basis / scale
    n = a.shape[0]
    ones = np.ones((n, 1))
    dd = np.linspace(0.0, 10.0 * max(float(d.max()), 1e-12), 201)
    slope = -np.column_stack([np.ones_like(dd), 2 * dd, 3 * dd * dd]) / scale * scale[0]  # -h'(dd) <= 0
    slope /= np.maximum(np.max(np.abs(slope), axis=1, keepdims=True), 1e-300)
    a_ub = np.block([[a, -ones], [-a, -ones], [slope, np.zeros((dd.size, 1))]])
    b_ub = np.r_[y, -y, np.zeros(dd.size)]
    res = linprog(np.r_[0.0, 0.0, 0.0, 1.0], A_ub=a_ub, b_ub=b_ub,
                  bounds=[(0, None), (None, None), (0, None), (0, None)], method="highs")
    if not res.success:
        return np.zeros(3), float(np.max(np.abs(y)))
    # The minimax optimum is often a face, not a point, and the vertex the solver returns then
    # depends on rounding (docs/conversion.md, "Fits with a flat optimum"): among the
    # coefficients within MINIMAX_SLACK of the optimum, take the smallest (scaled) ones.
    worst = res.x[3] * (1.0 + MINIMAX_SLACK) + 1e-12 * max(float(np.max(np.abs(y))), 1e-300)
    # variables a, b+, b-, c (scaled), all >= 0
    split = np.column_stack([a[:, 0], a[:, 1], -a[:, 1], a[:, 2]])
    slope4 = np.column_stack([slope[:, 0], slope[:, 1], -slope[:, 1], slope[:, 2]])
    small = linprog(np.ones(4), A_ub=np.vstack([split, -split, slope4]),
                    b_ub=np.r_[y + worst, -y + worst, np.zeros(dd.size)], bounds=[(0, None)] * 4, method="highs")
    x = res.x[:3] if not small.success else np.array([small.x[0], small.x[1] - small.x[2], small.x[3]])
    p = x / scale
    return p, float(np.max(np.abs(basis @ p - y)))


def fit_deadband(u: np.ndarray, target: np.ndarray, lo: float, hi: float) -> tuple[float, np.ndarray, float]:
    """Fit ``target(u) >= 0`` by ``h(u - e)`` for ``u > e`` (0 below), ``h(d) = a d + b d² + c d³``
    non-decreasing from 0 (see :func:`_minimax`), minimax over the samples ``u``, the edge ``e``
    searched in [lo, hi].

    Returns (e, (a, b, c), worst error)."""
    from scipy.optimize import minimize_scalar

    def solve(e: float) -> tuple[np.ndarray, float]:
        return _minimax(np.maximum(u - e, 0.0), target)

    def score(e: float) -> float:
        # the worst error is often flat over a range of edges, where the search would stop
        # wherever rounding led it; DEADBAND_TIE times the RMS error picks one edge there
        d = np.maximum(u - e, 0.0)
        p, worst = _minimax(d, target)
        rms = math.sqrt(float(np.mean((d * (p[0] + d * (p[1] + d * p[2])) - target) ** 2)))
        return worst + DEADBAND_TIE * rms

    edges = np.linspace(lo, hi, 13)
    scores = [score(e) for e in edges]
    i = int(np.argmin(scores))
    a, b = edges[max(i - 1, 0)], edges[min(i + 1, len(edges) - 1)]
    best_e, best = float(edges[i]), scores[i]
    if b > a:
        res = minimize_scalar(score, bounds=(a, b), method="bounded",
                              options={"xatol": DEADBAND_XTOL * max(hi - lo, 1e-9)})
        if res.fun < best:
            best_e = float(res.x)
    p, err = solve(best_e)
    return best_e, p, err


def _fit_side(f: LimitForce, side: str, q: np.ndarray) -> SideFit | None:
    """The MuJoCo spring for one side of a limit force over the samples ``q`` (None: nothing)."""
    k_up, k_lo = f.stiffness_steps(q)
    in_range = np.linspace(*f.range, N_GRID)
    if side == "lower":
        target, k, limit = k_lo * (f.q_lo - q), f.k_lo, f.q_lo
        full = np.all(f.stiffness_steps(in_range)[1] == f.k_lo)
    else:
        target, k, limit = k_up * (q - f.q_up), f.k_up, f.q_up
        full = np.all(f.stiffness_steps(in_range)[0] == f.k_up)
    if not np.any(target != 0.0):
        return None
    if full:  # the step is on over the whole range: exactly a linear spring about the limit there
        return SideFit("spring", side, k=k, ref=limit)
    if np.max(np.abs(target)) <= NEGLIGIBLE:
        return SideFit("none", side, max_error=float(np.max(np.abs(target))))
    g0, g1 = f.grid
    span = g1 - g0
    if side == "lower":  # active below the edge: fit in u = -q
        e, p, err = fit_deadband(-q, target, -min(limit, g1 + span), -g0)
        edge, coef = -e, (p[0], 0.0 - p[1], p[2])  # MuJoCo: force -(a x + b x² + c x³), x = q - edge < 0
    else:
        e, p, err = fit_deadband(q, target, max(limit, g0 - span), g1)
        edge, coef = e, (p[0], p[1], p[2])
    if not np.any(p != 0):
        return SideFit("none", side, max_error=err)
    return SideFit("tendon", side, edge=edge, coef=tuple(float(c) for c in coef), max_error=err)


def convert_coordinate_limit_force(ctx: _Context, el: etree._Element) -> None:
    """CoordinateLimitForce -> joint spring, fixed dead-band tendons and joint damping."""
    b = ctx.builder
    name = el.get("name")
    cname = _coordinate(ctx, el)
    if cname not in b.skel.coordinates:
        raise b.doc.error(el, f"limits coordinate '{cname}', which no joint defines")
    if cname not in b.coord_joint or b.skel.coordinates[cname].locked:
        ctx.out.skipped.append(Skipped(el.tag, name, f"coordinate '{cname}' is locked, so the force cannot move it "
                                       "(no MuJoCo joint)"))
        return
    motion = motion_type(b.skel, cname)
    w = np.pi / 180.0 if motion == "rotational" else 1.0
    transition = _number(el, "transition", 0.1, ctx) * w
    if not transition > 0.0:
        ctx.out.skipped.append(Skipped(el.tag, name, "transition width is not positive (OpenSim's step is undefined)"))
        return
    kind = b.coord_joint[cname][1].kind
    lo, hi = b.fit_range(cname, kind)
    margin = RANGE_MARGIN * (hi - lo)
    f = LimitForce(name, cname, cname, motion,
                   q_up=_number(el, "upper_limit", 0.0, ctx) * w, k_up=_number(el, "upper_stiffness", 1.0, ctx) / w,
                   q_lo=_number(el, "lower_limit", 0.0, ctx) * w, k_lo=_number(el, "lower_stiffness", 1.0, ctx) / w,
                   damping=_number(el, "damping", 0.001, ctx) / w, transition=transition,
                   range=(lo, hi), grid=(lo - margin, hi + margin), hinge=kind == "rotation")
    if motion == "coupled" and kind == "rotation":
        b.result.notes.append(f"CoordinateLimitForce '{name}': coordinate '{cname}' is Coupled in OpenSim, which then "
                              "reads its limits in rad, stiffness in N m/rad and damping in N m s/rad; so does o2m")
    q = np.linspace(*f.grid, N_GRID)
    joint = ctx.spec.joint(f.joint)
    for side in ("lower", "upper"):
        s = _fit_side(f, side, q)
        if s is None:
            continue
        if s.kind == "tendon":
            s.tendon = ctx.unique("tendon", f"{name}_{side}")
            t = ctx.spec.add_tendon(name=s.tendon, group=5)
            t.wrap_joint(f.joint, 1.0)
            t.springlength = [s.edge, FAR] if side == "lower" else [-FAR, s.edge]
            t.stiffness = list(s.coef)
            ctx.out.exact[("tendon", s.tendon)] = {"springlength": np.array(t.springlength),
                                                   "stiffness": np.array(s.coef)}
        f.sides.append(s)
    weight = f.weight(np.linspace(lo, hi, N_GRID))  # damping: the constant best over the range itself
    if f.damping != 0.0 and float(weight.max()) > WEIGHT_ROUNDOFF:
        f.joint_damping = f.damping * 0.5 * (float(weight.max()) + float(weight.min()))
        f.damping_error = abs(f.damping) * 0.5 * float(np.ptp(weight))
    ctx.out.limit_forces.append(f)
    set_joint_passive(ctx, joint, f.joint)


def set_joint_passive(ctx: _Context, joint: mujoco.MjsJoint, name: str) -> None:
    """The joint's spring and damping: the sums of those of its limit forces and joint springs
    (k1 (q - r1) + k2 (q - r2) is one spring of k1 + k2 about their stiffness-weighted mean)."""
    springs = [(s.k, s.ref) for f in ctx.out.limit_forces if f.joint == name for s in f.sides if s.kind == "spring"]
    springs += [(js.stiffness, js.springref) for js in ctx.out.joint_springs if js.joint == name and js.stiffness]
    k = sum(sk for sk, _ in springs)
    ref = sum(sk * sr for sk, sr in springs) / k if springs and k != 0.0 else 0.0
    damping = sum(f.joint_damping for f in ctx.out.limit_forces if f.joint == name)
    damping += sum(js.damping for js in ctx.out.joint_springs if js.joint == name)
    joint.stiffness = [k, 0.0, 0.0]
    joint.springref = ref
    joint.damping = [damping, 0.0, 0.0]
    exact = ctx.builder.exact.setdefault(("joint", name), {})
    if k != 0.0:
        exact.update({"stiffness": np.array([k]), "springref": np.array([ref])})
    if damping != 0.0:
        exact["damping"] = np.array([damping])


def _passive_at(m: mujoco.MjModel, d: mujoco.MjData, qadr: int, dof: int, q: float, v: float) -> float:
    d.qpos[:] = m.qpos0
    d.qpos[qadr] = q
    d.qvel[:] = 0.0
    d.qvel[dof] = v
    mujoco.mj_fwdPosition(m, d)
    mujoco.mj_fwdVelocity(m, d)
    return float(d.qfrc_passive[dof])


def _opensim_limit_torques(osim: Path, forces: list[LimitForce]) -> dict[str, np.ndarray] | None:
    """OpenSim's calcLimitForce of each force on its grid x SPEEDS (None when OpenSim cannot load the model)."""
    opensim = runtime.opensim()
    try:
        model, state = runtime.load_model(osim)
    except Exception:  # noqa: BLE001 - measured with o2m's copy of OpenSim's formula instead
        return None
    out = {}
    for f in forces:
        clf = opensim.CoordinateLimitForce.safeDownCast(model.getForceSet().get(f.name))
        coord = opensim_coordinate(model, f.coordinate)
        vals = np.empty((N_GRID, len(SPEEDS)))
        for i, q in enumerate(np.linspace(*f.grid, N_GRID)):
            for k, v in enumerate(SPEEDS):
                coord.setValue(state, float(q), False)
                coord.setSpeedValue(state, float(v))
                vals[i, k] = clf.calcLimitForce(state)
        out[f.name] = vals
    return out


def measure_limit_forces(out: ForceConversion, model: mujoco.MjModel, osim: str | Path, builder: MjcfBuilder) -> None:
    """Measure every converted limit force against OpenSim in ``model`` (the MJCF as written) and
    record the errors in ``builder.result.approximations``."""
    result = builder.result
    if out.limit_forces:
        reference = _opensim_limit_torques(Path(osim), out.limit_forces)
        if reference is None:
            result.notes.append("limit forces measured against o2m's copy of OpenSim's formula (OpenSim could not "
                                "load the model)")
        base = _isolated(model)
        data = mujoco.MjData(base)
        for f in out.limit_forces:
            m = copy.deepcopy(base)
            j = model.joint(f.joint).id
            qadr, dof = int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
            springs = [s for s in f.sides if s.kind == "spring"]
            if springs:
                m.jnt_stiffness[j] = sum(s.k for s in springs)
                if m.jnt_stiffness[j] != 0.0:
                    m.qpos_spring[qadr] = sum(s.k * s.ref for s in springs) / m.jnt_stiffness[j]
            for s in f.sides:
                if s.kind == "tendon":
                    t = model.tendon(s.tendon).id
                    m.tendon_stiffness[t] = model.tendon_stiffness[t]
                    m.tendon_stiffnesspoly[t] = model.tendon_stiffnesspoly[t]
            m.dof_damping[dof] = f.joint_damping
            q = np.linspace(*f.grid, N_GRID)
            mj = np.array([[_passive_at(m, data, qadr, dof, qi, v) for v in SPEEDS] for qi in q])
            os_vals = reference[f.name] if reference is not None else \
                np.column_stack([f.torque(q, v) for v in SPEEDS])
            err = np.abs(mj - os_vals)
            unit = f.unit()
            speed = "rad/s" if f.hinge else "m/s"
            parts = []
            for s in f.sides:
                if s.kind == "none":
                    parts.append(f"{s.side}: left out (at most {s.max_error:.2g} {unit})")
                    continue
                parts.append(f"{s.side}: joint spring {s.k:.6g} about {s.ref:.6g}" if s.kind == "spring" else
                             f"{s.side}: tendon '{s.tendon}' dead band from {s.edge:.6g}, stiffness "
                             + " ".join(f"{c:.4g}" for c in s.coef))
            if f.joint_damping:
                exact = " (exact over the range)" if f.damping_error == 0 else ""
                parts.append(f"joint damping {f.joint_damping:.6g}{exact}")
            what = "limit torque as " + ("; ".join(parts) if parts else "nothing (zero over the range)")
            result.approximations.append(Approximation(
                "CoordinateLimitForce", f.name, what, float(err.max()), unit,
                f"on '{f.coordinate}' ({f.motion}) over [{f.grid[0]:.4g}, {f.grid[1]:.4g}] (range ± "
                f"{RANGE_MARGIN:.0%}), |speed| <= 1 {speed}; OpenSim's largest |force| there "
                f"{float(np.abs(os_vals).max()):.4g} {unit}; rms error {float(np.sqrt(np.mean(err ** 2))):.3g}"))
