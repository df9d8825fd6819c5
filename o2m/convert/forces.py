"""The non-muscle OpenSim forces: limit forces, ligaments and the simple actuators.

One handler per OpenSim type (:data:`HANDLERS`); each reads its element and adds MuJoCo
elements to the spec of an :class:`~o2m.mjcf.MjcfBuilder`, recording in a per-conversion
:class:`ForceConversion` what it did. Units: SI (rad, m, N, N m, s).

* **CoordinateLimitForce** (OpenSim: ``CoordinateLimitForce::calcLimitForce``). For a
  Rotational coordinate the limits and the transition are degrees, stiffnesses N m/deg and
  damping N m/(deg/s); for any other motion type (Translational, and Coupled — a coordinate
  whose joint axes are not all LinearFunctions of slope ±1) OpenSim reads them in the
  coordinate's own units, and so does o2m. The force is ``τ = -K_up(q) (q - q_up) +
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
* **Ligament**: its GeometryPath is the spatial tendon :mod:`o2m.tendons` builds; the tension
  ``pcsa_force · curve(L / resting_length)`` (0 when slack) becomes the tendon's spring: a dead
  band ``[0, edge]`` and a polynomial stiffness fitted minimax over the tendon's length range.
* **CoordinateActuator**: a motor on the coordinate's joint, ``gear = optimal_force``.
* **TorqueActuator**: a site transmission with ``refsite``: the torque ``optimal_force ·
  axis`` on bodyA, its opposite on bodyB. Exact when the axis is fixed in bodyA
  (``torque_is_global`` false) or when one body is ground; a global axis between two moving
  bodies is fixed in bodyA as at the default pose (the report gives how far it turns away).
* **PointActuator**: a site at the point with a force gear, in the body frame, or in the world
  frame through a ``refsite`` on the world when ``force_is_global``. A global point (fixed in
  ground, sliding over the body) is fixed in the body where it is at the default pose (the
  report gives how far it moves).

Actuators are added after the muscle actuators, named as in OpenSim; ``min_control`` and
``max_control`` become ``ctrlrange`` when both are finite.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

import mujoco
import numpy as np
from lxml import etree

from o2m.convert.builder import Approximation, MjcfBuilder
from o2m.osim import runtime
from o2m.osim.functions import Function, parse_function
from o2m.osim.skeleton import JOINT_AXES, Skeleton, SkeletonReader, Skipped
from o2m.transforms import OSIM_TO_MJ, Transform

#: Beyond the coordinate's range, limit forces are fitted and measured over this fraction of it.
RANGE_MARGIN = 0.1
#: Samples of the coordinate (or tendon length) a fit and a measurement use.
N_GRID = 241
#: Speeds (rad/s or m/s) at which the limit-force error is measured.
SPEEDS = (-1.0, 0.0, 1.0)
#: Extra strain beyond rest over which a ligament is fitted when its length range stays short of it.
LIGAMENT_MIN_STRAIN = 0.05
#: Random poses used to measure pose-dependent errors (ligament force, global axes and points).
N_POSES = 200
#: A length o2m uses for "no end" in a one-sided dead band (m or rad).
FAR = 1e6
#: OpenSim's default Ligament force-length curve (used when the document leaves it out).
DEFAULT_LIGAMENT_CURVE = (
    '<SimmSpline name="force_length_curve"><x>-5 0.998 0.999 1 1.1 1.2 1.3 1.4 1.5 1.6 1.601 1.602 5</x>'
    '<y>0 0 0 0 0.035 0.12 0.26 0.55 1.17 2 2 2 2</y></SimmSpline>')
#: A side of a limit force whose torque stays below this (N m or N) over the grid is left out.
NEGLIGIBLE = 1e-5


@dataclass
class SideFit:
    """One side of a limit force (or a ligament) as a MuJoCo spring.

    ``kind`` is "spring" (joint linear spring: ``k`` about ``ref``) or "tendon" (dead band edge
    ``edge`` and stiffness polynomial ``coef`` (a, b, c) in the tendon's own sign convention).
    ``max_error`` is the fit's worst error over the grid (N m, N)."""

    kind: str
    side: str  # "lower", "upper" (or "tension" for a ligament)
    k: float = 0.0
    ref: float = 0.0
    edge: float = 0.0
    coef: tuple[float, float, float] = (0.0, 0.0, 0.0)
    max_error: float = 0.0
    tendon: str = ""


@dataclass
class LimitForce:
    """A CoordinateLimitForce in SI units, and what it became."""

    name: str
    coordinate: str
    joint: str  # the MuJoCo joint (named as the coordinate)
    motion: str  # OpenSim motion type: rotational, translational, coupled
    q_up: float
    k_up: float
    q_lo: float
    k_lo: float
    damping: float
    transition: float
    range: tuple[float, float]  # the coordinate's range (its fit range when unbounded)
    grid: tuple[float, float]  # where it is fitted and measured: the range and RANGE_MARGIN of it beyond
    hinge: bool = True  # the MuJoCo joint is a hinge (torques in N m), else a slide (N)
    sides: list[SideFit] = field(default_factory=list)
    joint_damping: float = 0.0
    damping_error: float = 0.0  # per unit speed

    def stiffness_steps(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """OpenSim's stepped stiffnesses (K_up(q), K_lo(q))."""
        k_up = _step(q, self.q_up, self.q_up + self.transition, 0.0, self.k_up)
        k_lo = _step(q, self.q_lo - self.transition, self.q_lo, self.k_lo, 0.0)
        return k_up, k_lo

    def torque(self, q: np.ndarray, qdot: np.ndarray | float = 0.0) -> np.ndarray:
        """OpenSim's generalized force (N m or N) at ``q``, ``qdot``."""
        q = np.asarray(q, dtype=float)
        k_up, k_lo = self.stiffness_steps(q)
        return -k_up * (q - self.q_up) + k_lo * (self.q_lo - q) - self.damping * self.weight(q) * qdot

    def weight(self, q: np.ndarray) -> np.ndarray:
        """The damping's step weight ``K_up(q)/K_up + K_lo(q)/K_lo`` (a side of zero stiffness adds 0)."""
        k_up, k_lo = self.stiffness_steps(np.asarray(q, dtype=float))
        w = np.zeros_like(k_up)
        if self.k_up != 0.0:
            w = w + k_up / self.k_up
        if self.k_lo != 0.0:
            w = w + k_lo / self.k_lo
        return w

    def unit(self) -> str:
        return "N m" if self.hinge else "N"


@dataclass
class Ligament:
    """A Ligament: its tendon, resting length (m), pcsa force (N) and force-length curve."""

    name: str
    tendon: str
    resting_length: float
    pcsa_force: float
    curve: Function
    fit: SideFit | None = None
    length_range: tuple[float, float] = (0.0, 0.0)

    def tension(self, length: np.ndarray) -> np.ndarray:
        """OpenSim's tension (N) at path ``length`` (m): 0 when not longer than the resting length."""
        length = np.asarray(length, dtype=float)
        f = self.pcsa_force * np.asarray(self.curve(length / self.resting_length), dtype=float)
        return np.where(length <= self.resting_length, 0.0, f)


@dataclass
class PoseDrift:
    """A global axis or point fixed in a body as at the default pose; measured after building."""

    element: str
    name: str
    what: str
    body: str  # OpenSim body it is fixed in
    value: np.ndarray  # the ground axis (unit) or ground point (m) OpenSim uses
    local: np.ndarray  # what the MuJoCo model fixes in the body
    kind: str  # "axis" or "point"


@dataclass
class ForceConversion:
    """What the force handlers did in one conversion."""

    handled: set[tuple[str, str]] = field(default_factory=set)  # (tag, name) of every element handled
    skipped: list[Skipped] = field(default_factory=list)
    limit_forces: list[LimitForce] = field(default_factory=list)
    ligaments: list[Ligament] = field(default_factory=list)
    drifts: list[PoseDrift] = field(default_factory=list)
    actuators: list[str] = field(default_factory=list)
    #: Full-precision attribute values by (MJCF tag, name), written over MuJoCo's 6-digit output.
    exact: dict[tuple[str, str], dict[str, np.ndarray]] = field(default_factory=dict)

    @property
    def converted(self) -> int:
        return len(self.limit_forces) + len(self.ligaments) + len(self.actuators)


@dataclass
class _Context:
    builder: MjcfBuilder
    reader: SkeletonReader
    out: ForceConversion
    names: dict[str, set[str]]  # MJCF tag -> names in use

    @property
    def spec(self) -> mujoco.MjSpec:
        return self.builder.spec

    def unique(self, tag: str, name: str) -> str:
        used = self.names.setdefault(tag, set())
        out, k = name, 1
        while out in used:
            out, k = f"{name}_{k}", k + 1
        used.add(out)
        return out


# -- reading --------------------------------------------------------------------------------
def _number(el: etree._Element, prop: str, default: float, ctx: _Context) -> float:
    child = el.find(prop)
    if child is None or not (child.text or "").strip():
        return default
    text = child.text.strip()
    try:
        return float(text.replace("Inf", "inf"))
    except ValueError:
        raise ctx.builder.doc.error(el, f"<{prop}> holds '{text}', not a number") from None


def _vector(el: etree._Element, prop: str, default: tuple[float, float, float], ctx: _Context) -> np.ndarray:
    child = el.find(prop)
    if child is None or not (child.text or "").strip():
        return np.array(default, dtype=float)
    try:
        v = np.array([float(x) for x in child.text.split()])
    except ValueError:
        raise ctx.builder.doc.error(el, f"<{prop}> holds '{child.text.strip()}', not numbers") from None
    if v.size != 3 or not np.all(np.isfinite(v)):
        raise ctx.builder.doc.error(el, f"<{prop}> must hold 3 finite numbers")
    return v


def _text(el: etree._Element, prop: str) -> str:
    return (el.findtext(prop) or "").strip()


def _flag(el: etree._Element, prop: str, default: bool) -> bool:
    t = _text(el, prop).lower()
    return default if not t else t in ("true", "1")


def _applies_force(el: etree._Element) -> bool:
    return _flag(el, "appliesForce", True) and not _flag(el, "isDisabled", False)


def motion_type(skel: Skeleton, coordinate: str) -> str:
    """OpenSim's MotionType of ``coordinate``: "rotational", "translational" or "coupled".

    As OpenSim 4.6 decides it: a CustomJoint coordinate is Rotational (Translational) when a
    rotation (translation) axis uses it through a LinearFunction of slope ±1, the last such
    axis deciding; else Coupled (also when no axis uses it). Other joint types give their
    coordinates' kinds."""
    coord = skel.coordinates[coordinate]
    joint = next(j for j in skel.joints if j.name == coord.joint)
    if joint.type != "CustomJoint":
        kind = JOINT_AXES[joint.type][joint.coordinates.index(coordinate)][0]
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


def _frame_by_name(ctx: _Context, el: etree._Element, prop: str) -> tuple[str, Transform]:
    """(body, frame in body) of the PhysicalFrame a TorqueActuator/PointActuator property names."""
    target = _text(el, prop)
    if not target:
        raise ctx.builder.doc.error(el, f"has no <{prop}>")
    last = target.rstrip("/").split("/")[-1]
    if last == "ground":
        return "ground", Transform()
    found = [f for f in ctx.reader.model.iter("Body", "PhysicalOffsetFrame", "Ground") if f.get("name") == last]
    bodies = [f for f in found if f.tag == "Body"]
    pick = bodies if len(bodies) == 1 else found
    if len(pick) != 1:
        why = "no frame has that name" if not pick else f"{len(pick)} frames share that name"
        raise ctx.builder.doc.error(el, f"<{prop}> names '{target}', which cannot be resolved: {why}")
    body, x, _ = ctx.reader.frame(pick[0])
    return body, x


def _body_site(ctx: _Context, body: str, name: str, pos: np.ndarray, quat: np.ndarray | None = None) -> str:
    """Add a site to ``body`` (OpenSim body frame; ground: the world); returns its name."""
    name = ctx.unique("site", name)
    quat = np.array([1.0, 0, 0, 0]) if quat is None else np.asarray(quat, dtype=float)
    pos = OSIM_TO_MJ @ pos if body == "ground" else np.asarray(pos, dtype=float)
    ctx.builder.bodies[body].add_site(name=name, pos=pos, quat=quat, size=[0.004, 0, 0], group=5,
                                      rgba=[0.9, 0.6, 0.1, 1])
    ctx.builder.exact[("site", name)] = {"pos": pos, "quat": quat}
    return name


def _add_actuator(ctx: _Context, el: etree._Element, gear: np.ndarray, **target) -> None:
    name = el.get("name")
    act = ctx.spec.add_actuator(name=name, **target)
    act.gear = [float(g) for g in gear]
    lo, hi = _number(el, "min_control", -np.inf, ctx), _number(el, "max_control", np.inf, ctx)
    if np.isfinite(lo) and np.isfinite(hi):
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.ctrlrange = [lo, hi]
    else:
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        if np.isfinite(lo) or np.isfinite(hi):
            ctx.builder.result.notes.append(f"{el.tag} '{name}': one-sided control range [{lo:g}, {hi:g}] left "
                                            "unlimited (MuJoCo's ctrlrange has two ends)")
    ctx.out.exact[("actuator", name)] = {"gear": np.asarray(gear, dtype=float)}
    ctx.out.actuators.append(name)


# -- CoordinateLimitForce ---------------------------------------------------------------------
def _step(x: np.ndarray, x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    """SimTK::Function::Step: y0 below x0, y1 above x1, a quintic (10t³ - 15t⁴ + 6t⁵) between."""
    t = np.clip((np.asarray(x, dtype=float) - x0) / (x1 - x0), 0.0, 1.0)
    return y0 + (y1 - y0) * t ** 3 * (10.0 + t * (6.0 * t - 15.0))


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
    p = res.x[:3] / scale if res.success else np.zeros(3)
    return p, float(np.max(np.abs(basis @ p - y)))


def fit_deadband(u: np.ndarray, target: np.ndarray, lo: float, hi: float) -> tuple[float, np.ndarray, float]:
    """Fit ``target(u) >= 0`` by ``h(u - e)`` for ``u > e`` (0 below), ``h(d) = a d + b d² + c d³``
    non-decreasing from 0 (see :func:`_minimax`), minimax over the samples ``u``, the edge ``e``
    searched in [lo, hi].

    Returns (e, (a, b, c), worst error)."""
    from scipy.optimize import minimize_scalar

    def solve(e: float) -> tuple[np.ndarray, float]:
        return _minimax(np.maximum(u - e, 0.0), target)

    edges = np.linspace(lo, hi, 13)
    errs = [solve(e)[1] for e in edges]
    i = int(np.argmin(errs))
    a, b = edges[max(i - 1, 0)], edges[min(i + 1, len(edges) - 1)]
    best_e, best_err = float(edges[i]), errs[i]
    if b > a:
        res = minimize_scalar(lambda e: solve(e)[1], bounds=(a, b), method="bounded",
                              options={"xatol": 1e-5 * max(hi - lo, 1e-9)})
        if res.fun < best_err:
            best_e, best_err = float(res.x), float(res.fun)
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
    cname = _text(el, "coordinate")
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
    if f.damping != 0.0 and np.any(weight != 0.0):
        f.joint_damping = f.damping * 0.5 * (float(weight.max()) + float(weight.min()))
        f.damping_error = abs(f.damping) * 0.5 * float(np.ptp(weight))
    ctx.out.limit_forces.append(f)
    _set_joint_passive(ctx, joint, f.joint)


def _set_joint_passive(ctx: _Context, joint: mujoco.MjsJoint, name: str) -> None:
    """The joint's spring and damping: the sums of those of its limit forces."""
    springs = [s for f in ctx.out.limit_forces if f.joint == name for s in f.sides if s.kind == "spring"]
    k = sum(s.k for s in springs)
    ref = sum(s.k * s.ref for s in springs) / k if springs and k != 0.0 else 0.0
    damping = sum(f.joint_damping for f in ctx.out.limit_forces if f.joint == name)
    joint.stiffness = [k, 0.0, 0.0]
    joint.springref = ref
    joint.damping = [damping, 0.0, 0.0]
    exact = ctx.builder.exact.setdefault(("joint", name), {})
    if k != 0.0:
        exact.update({"stiffness": np.array([k]), "springref": np.array([ref])})
    if damping != 0.0:
        exact["damping"] = np.array([damping])


# -- Ligament -------------------------------------------------------------------------------------
def convert_ligament(ctx: _Context, el: etree._Element) -> None:
    """Ligament -> a spring on the spatial tendon of its path (fitted after the model compiles)."""
    b = ctx.builder
    name = el.get("name")
    if name not in [t.name for t in ctx.spec.tendons]:
        raise b.doc.error(el, "has no MuJoCo tendon (its GeometryPath was not converted)")
    rest = _number(el, "resting_length", 0.0, ctx)
    if not rest > 0.0:
        raise b.doc.error(el, f"has resting_length {rest:g}; OpenSim needs it positive")
    curve_el = next((c for c in el if isinstance(c.tag, str) and c.get("name") == "force_length_curve"), None)
    if curve_el is None:
        holder = el.find("force_length_curve")
        curve_el = next((c for c in holder if isinstance(c.tag, str)), None) if holder is not None else None
    if curve_el is None:
        curve_el = etree.fromstring(DEFAULT_LIGAMENT_CURVE)
    ctx.out.ligaments.append(Ligament(name, name, rest, _number(el, "pcsa_force", 0.0, ctx), parse_function(curve_el)))


def fit_ligaments(out: ForceConversion, spec: mujoco.MjSpec, model: mujoco.MjModel, builder: MjcfBuilder) -> None:
    """Fit each ligament's tendon spring to its force-length curve over the tendon's length range
    (``model`` is the compiled model; the spring is set in ``spec``)."""
    if not out.ligaments:
        return
    from o2m.convert.tendons import tendon_length_ranges

    ranges = tendon_length_ranges(model, _independent_ranges(builder))
    for lig in out.ligaments:
        lo, hi = (float(v) for v in ranges[model.tendon(lig.tendon).id])
        hi = max(hi, lig.resting_length * (1.0 + LIGAMENT_MIN_STRAIN))
        lig.length_range = (lo, hi)
        length = np.linspace(lo, hi, N_GRID)
        target = lig.tension(length)
        tendon = spec.tendon(lig.tendon)
        if not np.any(target != 0.0):
            builder.result.notes.append(f"Ligament '{lig.name}': no tension over lengths [{lo:.4g}, {hi:.4g}] m; "
                                        "its tendon has no spring")
            continue
        e, p, err = fit_deadband(length, target, min(lo, lig.resting_length), hi)
        lig.fit = SideFit("tendon", "tension", edge=e, coef=tuple(float(c) for c in p), max_error=err,
                          tendon=lig.tendon)
        tendon.springlength = [0.0, e]
        tendon.stiffness = list(lig.fit.coef)
        out.exact[("tendon", lig.tendon)] = {"springlength": np.array([0.0, e]), "stiffness": np.array(lig.fit.coef)}


def _independent_ranges(builder: MjcfBuilder) -> dict[str, tuple[float, float]]:
    coords = {}
    for name, (_, ax) in builder.coord_joint.items():
        if builder.drivers[name].base == name and not builder.skel.coordinates[name].locked:
            coords[name] = builder.fit_range(name, ax.kind)
    return coords


# -- actuators ------------------------------------------------------------------------------------
def convert_coordinate_actuator(ctx: _Context, el: etree._Element) -> None:
    """CoordinateActuator -> a motor on the coordinate's joint, gear = optimal_force."""
    b = ctx.builder
    cname = _text(el, "coordinate")
    if cname not in b.skel.coordinates:
        raise b.doc.error(el, f"actuates coordinate '{cname}', which no joint defines")
    if cname not in b.coord_joint or b.skel.coordinates[cname].locked:
        ctx.out.skipped.append(Skipped(el.tag, el.get("name"), f"coordinate '{cname}' is locked, so the actuator "
                                       "cannot move it (no MuJoCo joint)"))
        return
    gear = np.array([_number(el, "optimal_force", 1.0, ctx), 0, 0, 0, 0, 0])
    _add_actuator(ctx, el, gear, trntype=mujoco.mjtTrn.mjTRN_JOINT, target=cname)


def convert_torque_actuator(ctx: _Context, el: etree._Element) -> None:
    """TorqueActuator -> a site transmission with a refsite (torque on bodyA, reaction on bodyB)."""
    b = ctx.builder
    name = el.get("name")
    body_a, x_a = _frame_by_name(ctx, el, "bodyA")
    body_b, _ = _frame_by_name(ctx, el, "bodyB")
    axis = _vector(el, "axis", (0.0, 0.0, 1.0), ctx)
    if np.linalg.norm(axis) < 1e-12:
        raise b.doc.error(el, "has a zero <axis>")
    axis = axis / np.linalg.norm(axis)
    force = _number(el, "optimal_force", 1.0, ctx)
    is_global = _flag(el, "torque_is_global", True)
    if body_a == body_b:
        ctx.out.skipped.append(Skipped(el.tag, name, f"bodyA and bodyB are both '{body_a}' (no net torque)"))
        return
    local_axis = x_a.rot @ axis  # in bodyA's body frame, when not global
    if not is_global and body_a != "ground":
        # axis fixed in bodyA: refsite on A; MuJoCo puts +R_ref·gear on the site's body (B), so negate
        ref = _body_site(ctx, body_a, f"{name}_refsite", np.zeros(3))
        site = _body_site(ctx, body_b, f"{name}_site", np.zeros(3))
        gear_rot = -force * local_axis
    else:
        ground_axis = axis if is_global else local_axis  # bodyA is ground when not global here
        if body_b == "ground" or body_a == "ground":
            ref = _body_site(ctx, "ground", f"{name}_refsite", np.zeros(3))
            on, sign = (body_a, 1.0) if body_b == "ground" else (body_b, -1.0)
            site = _body_site(ctx, on, f"{name}_site", np.zeros(3))
            gear_rot = sign * force * (OSIM_TO_MJ @ ground_axis)
        else:  # a ground-fixed axis between two moving bodies: fixed in bodyA as at the default pose
            local = b.ground_frames[body_a].rot.T @ ground_axis
            ref = _body_site(ctx, body_a, f"{name}_refsite", np.zeros(3))
            site = _body_site(ctx, body_b, f"{name}_site", np.zeros(3))
            gear_rot = -force * local
            ctx.out.drifts.append(PoseDrift(el.tag, name, f"ground-fixed torque axis fixed in '{body_a}' as at the "
                                            "default pose", body_a, ground_axis, local, "axis"))
    _add_actuator(ctx, el, np.r_[np.zeros(3), gear_rot], trntype=mujoco.mjtTrn.mjTRN_SITE, target=site, refsite=ref)


def convert_point_actuator(ctx: _Context, el: etree._Element) -> None:
    """PointActuator -> a site transmission with a force gear (world frame via a world refsite)."""
    b = ctx.builder
    name = el.get("name")
    body, x = _frame_by_name(ctx, el, "body")
    if body == "ground":
        ctx.out.skipped.append(Skipped(el.tag, name, "acts on ground (no effect)"))
        return
    point = _vector(el, "point", (0.0, 0.0, 0.0), ctx)
    direction = _vector(el, "direction", (1.0, 0.0, 0.0), ctx)
    if np.linalg.norm(direction) < 1e-12:
        raise b.doc.error(el, "has a zero <direction>")
    direction = direction / np.linalg.norm(direction)
    force = _number(el, "optimal_force", 1.0, ctx)
    if _flag(el, "point_is_global", False):
        local = b.ground_frames[body].inverse().apply(point)
        ctx.out.drifts.append(PoseDrift(el.tag, name, "ground-fixed application point fixed in the body as at the "
                                        "default pose", body, point, local, "point"))
    else:
        local = x.apply(point)
    site = _body_site(ctx, body, f"{name}_site", local)
    if _flag(el, "force_is_global", False):
        ref = _body_site(ctx, "ground", f"{name}_refsite", np.zeros(3))
        gear = np.r_[force * (OSIM_TO_MJ @ direction), np.zeros(3)]
        _add_actuator(ctx, el, gear, trntype=mujoco.mjtTrn.mjTRN_SITE, target=site, refsite=ref)
    else:
        gear = np.r_[force * (x.rot @ direction), np.zeros(3)]
        _add_actuator(ctx, el, gear, trntype=mujoco.mjtTrn.mjTRN_SITE, target=site)


#: The converter of each OpenSim force type o2m converts here (Ligament: its spring; the tendon
#: of its path is built by :mod:`o2m.tendons`).
HANDLERS: Mapping[str, Callable[[_Context, etree._Element], None]] = MappingProxyType({
    "CoordinateLimitForce": convert_coordinate_limit_force,
    "Ligament": convert_ligament,
    "CoordinateActuator": convert_coordinate_actuator,
    "TorqueActuator": convert_torque_actuator,
    "PointActuator": convert_point_actuator,
})
FORCE_TYPES = frozenset(HANDLERS)


def add_forces(builder: MjcfBuilder, reader: SkeletonReader) -> ForceConversion:
    """Convert every force of the ForceSet that has a handler; call after the muscle paths (so the
    actuators come after the muscles' and the ligaments' tendons exist)."""
    spec = builder.spec
    names = {"site": {s.name for s in spec.sites}, "tendon": {t.name for t in spec.tendons}}
    ctx = _Context(builder, reader, ForceConversion(), names)
    for el in reader.set_objects("ForceSet"):
        handler = HANDLERS.get(el.tag)
        if handler is None:
            continue
        ctx.out.handled.add((el.tag, el.get("name", "")))
        if not _applies_force(el):
            ctx.out.skipped.append(Skipped(el.tag, el.get("name", ""), "disabled in OpenSim (appliesForce false)"
                                           + ("; its path is a tendon without spring" if el.tag == "Ligament" else "")))
            continue
        handler(ctx, el)
    return ctx.out


# -- precision and measurement --------------------------------------------------------------------
def restore_precision(xml: str, out: ForceConversion) -> str:
    """MJCF text with the tendon springs and actuator gears written in full (17 digits)."""
    if not out.exact:
        return xml
    root = etree.fromstring(xml.encode())
    for parent_tag, tag in (("tendon", "tendon"), ("actuator", "actuator")):
        for holder in root.iter(parent_tag):
            for el in holder:
                vals = out.exact.get((tag, el.get("name"))) if isinstance(el.tag, str) else None
                for attr, v in (vals or {}).items():
                    el.set(attr, " ".join(f"{float(x):.17g}" for x in np.atleast_1d(v)))
    return etree.tostring(root, encoding="unicode", pretty_print=True)


def _isolated(model: mujoco.MjModel) -> mujoco.MjModel:
    """A copy of ``model`` with every spring and damper off."""
    m = copy.deepcopy(model)
    for arr in (m.jnt_stiffness, m.jnt_stiffnesspoly, m.dof_damping, m.dof_dampingpoly, m.tendon_stiffness,
                m.tendon_stiffnesspoly, m.tendon_damping, m.tendon_dampingpoly):
        arr[...] = 0.0
    return m


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
        coord = model.getCoordinateSet().get(f.coordinate)
        vals = np.empty((N_GRID, len(SPEEDS)))
        for i, q in enumerate(np.linspace(*f.grid, N_GRID)):
            for k, v in enumerate(SPEEDS):
                coord.setValue(state, float(q), False)
                coord.setSpeedValue(state, float(v))
                vals[i, k] = clf.calcLimitForce(state)
        out[f.name] = vals
    return out


def measure(out: ForceConversion, model: mujoco.MjModel, osim: str | Path, builder: MjcfBuilder) -> None:
    """Measure every converted force against OpenSim in ``model`` (the MJCF as written) and record
    the errors in ``builder.result.approximations``."""
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
    for lig in out.ligaments:
        if lig.fit is None:
            continue
        err_pose = _measure_ligament(lig, model, builder)
        result.approximations.append(Approximation(
            "Ligament", lig.name,
            f"tension as a tendon spring: dead band to {lig.fit.edge:.6g} m, stiffness "
            + " ".join(f"{c:.4g}" for c in lig.fit.coef),
            float(max(lig.fit.max_error, err_pose)), "N",
            f"force-length fit over [{lig.length_range[0]:.4g}, {lig.length_range[1]:.4g}] m: worst "
            f"{lig.fit.max_error:.3g} N; MuJoCo's tendon force at {N_POSES} poses: worst {err_pose:.3g} N; "
            f"pcsa_force {lig.pcsa_force:g} N"))
    for dr in out.drifts:
        result.approximations.append(Approximation(
            dr.element, dr.name, dr.what, _measure_drift(dr, builder), "rad" if dr.kind == "axis" else "m",
            f"worst over {N_POSES} poses"))


def _random_values(builder: MjcfBuilder, n: int, seed: int = 0) -> list[dict[str, float]]:
    coords = _independent_ranges(builder)
    rng = np.random.default_rng(seed)
    return [{c: float(rng.uniform(lo, hi)) for c, (lo, hi) in coords.items()} for _ in range(n)]


def _measure_ligament(lig: Ligament, model: mujoco.MjModel, builder: MjcfBuilder) -> float:
    """Worst |MuJoCo tendon force - OpenSim tension at MuJoCo's tendon length| (N) over random poses."""
    from o2m.mj.posing import joint_equality_plan, pose_mujoco

    m = _isolated(model)
    t = model.tendon(lig.tendon).id
    m.tendon_stiffness[t] = model.tendon_stiffness[t]
    m.tendon_stiffnesspoly[t] = model.tendon_stiffnesspoly[t]
    d = mujoco.MjData(m)
    plan = joint_equality_plan(m)
    worst = 0.0
    for values in _random_values(builder, N_POSES):
        pose_mujoco(m, d, values, plan=plan)
        d.qvel[:] = 0.0
        mujoco.mj_fwdPosition(m, d)
        mujoco.mj_fwdVelocity(m, d)
        jac = _tendon_row(m, d, t)
        jj = float(jac @ jac)
        if jj < 1e-12:
            continue
        tension = -float(jac @ d.qfrc_passive) / jj  # qfrc_passive = J^T f, f < 0 when pulling
        worst = max(worst, abs(tension - float(lig.tension(np.array([d.ten_length[t]]))[0])))
    return worst


def _tendon_row(m: mujoco.MjModel, d: mujoco.MjData, t: int) -> np.ndarray:
    """Row ``t`` (nv,) of the tendon Jacobian (``ten_J`` is sparse in MuJoCo >= 3.3)."""
    tj = np.asarray(d.ten_J, dtype=float).ravel()
    if not hasattr(m, "ten_J_rownnz"):
        return tj.reshape(m.ntendon, m.nv)[t].copy()
    row = np.zeros(m.nv)
    a, n = int(m.ten_J_rowadr[t]), int(m.ten_J_rownnz[t])
    row[m.ten_J_colind[a:a + n]] = tj[a:a + n]
    return row


def _measure_drift(dr: PoseDrift, builder: MjcfBuilder) -> float:
    worst = 0.0
    for values in _random_values(builder, N_POSES):
        frame = builder.ground_frames_at(builder.coordinate_values(values))[dr.body]
        if dr.kind == "axis":
            c = float(np.clip((frame.rot @ dr.local) @ dr.value, -1.0, 1.0))
            worst = max(worst, float(np.arccos(c)))
        else:
            worst = max(worst, float(np.linalg.norm(frame.apply(dr.local) - dr.value)))
    return worst


__all__ = ["FORCE_TYPES", "HANDLERS", "ForceConversion", "LimitForce", "Ligament", "SideFit", "add_forces",
           "fit_deadband", "fit_ligaments", "measure", "motion_type", "restore_precision"]

