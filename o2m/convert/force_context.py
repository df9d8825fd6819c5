"""What the force handlers share: the conversion context, the records of what each force became,
reading an element's properties, and the poses forces are measured at.

Units: SI (rad, m, N, N m, s). A :class:`ForceConversion` records one conversion; each handler
(:mod:`o2m.convert.limit_forces`, :mod:`o2m.convert.ligaments`, :mod:`o2m.convert.actuators`,
:mod:`o2m.convert.contact`)
gets a :class:`_Context` holding it and the :class:`~o2m.convert.builder.MjcfBuilder`.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass, field

import mujoco
import numpy as np
from lxml import etree

from o2m.convert.builder import MjcfBuilder
from o2m.convert.contact_fit import HuntCrossley, LinearContact
from o2m.convert.coordinates import is_mobility_rotation
from o2m.osim.functions import Function
from o2m.osim.skeleton import SkeletonReader, Skipped

__all__ = ["FAR", "N_GRID", "N_POSES", "BushingFit", "ContactConversion", "ContactGeom", "ContactPair",
           "ForceConversion", "Ligament", "LimitForce", "PoseDrift", "SideFit"]

#: Samples of the coordinate (or tendon length) a fit and a measurement use.
N_GRID = 241
#: Random poses used to measure pose-dependent errors (ligament force, global axes and points).
N_POSES = 200
#: A length o2m uses for "no end" in a one-sided dead band (m or rad).
FAR = 1e6


def _step(x: np.ndarray, x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    """SimTK::Function::Step: y0 below x0, y1 above x1, a quintic (10t³ - 15t⁴ + 6t⁵) between."""
    t = np.clip((np.asarray(x, dtype=float) - x0) / (x1 - x0), 0.0, 1.0)
    # clipped: the quintic's round-off can pass 1 by an ulp, and a stiffness must not go negative
    s = np.clip(t ** 3 * (10.0 + t * (6.0 * t - 15.0)), 0.0, 1.0)
    return y0 * (1.0 - s) + y1 * s


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
    element: str = "Ligament"  # the OpenSim type, for the report

    def tension(self, length: np.ndarray) -> np.ndarray:
        """OpenSim's tension (N) at path ``length`` (m): 0 when not longer than the resting length."""
        length = np.asarray(length, dtype=float)
        f = self.pcsa_force * np.asarray(self.curve(length / self.resting_length), dtype=float)
        return np.where(length <= self.resting_length, 0.0, f)


@dataclass
class Spring:
    """A PointToPointSpring or PathSpring: its tendon, stiffness (N/m) and rest length (m);
    ``slack``: no force below the rest length (PathSpring); ``dissipation`` (s/m): PathSpring's
    damping factor, not converted."""

    name: str
    tendon: str
    stiffness: float
    rest_length: float
    element: str = "PointToPointSpring"
    slack: bool = False
    dissipation: float = 0.0

    def tension(self, length: float) -> float:
        """OpenSim's tension (N, positive pulling) at ``length`` (m), at rest."""
        stretch = length - self.rest_length
        return self.stiffness * (max(stretch, 0.0) if self.slack else stretch)


@dataclass
class JointSpring:
    """A force that is its joint's linear spring and damper (a BushingForce on one joint, a linear
    ExpressionBasedCoordinateForce): coordinate ``joint``, stiffness (N m/rad or N/m), springref
    (rad or m) and damping (N m s/rad or N s/m)."""

    name: str
    joint: str
    stiffness: float
    springref: float
    damping: float


@dataclass
class BushingFit:
    """A BushingForce whose deflection θ (6,: frame 2's X-Y-Z angles, rad, and offset, m, in frame 1)
    is taken as linear in its free coordinates, θ ≈ C q + θ0, and what it became: the joint spring
    of its one coordinate, the fixed ``tendons`` of several, or nothing when none moves its frames."""

    name: str
    coordinates: list[str]  # the independent coordinates (each one's MuJoCo joint is named as it)
    ends: list  # each frame's (body, Transform in the body)
    stiffness: np.ndarray  # (6,) K: N m/rad (angles), N/m (offsets)
    damping: np.ndarray  # (6,) D: N m s/rad, N s/m
    slopes: np.ndarray  # (6, n) C
    offsets: np.ndarray  # (6,) θ0
    residual: np.ndarray  # (6,) each deflection's worst |C q + θ0 - θ| over the fit's samples
    linear: np.ndarray = field(default_factory=lambda: np.zeros(6, bool))  # (6,) the deflections taken as C q + θ0
    fit_error: float = 0.0  # their worst residual (rad or m)
    joint_spring: bool = False  # they are its one coordinate's joint spring (else fixed tendons)
    tendons: list[str] = field(default_factory=list)
    form: str = ""  # what it became, for the report
    ghost_body: str = ""  # a ghost body welded to frame 2 (o2m.convert.bushing_ghost), else ""
    ghost_weld: str = ""  # its weld equality
    ghost_joints: list[str] = field(default_factory=list)  # its joints: tx, ty, tz, rx, ry, rz
    element: str = "BushingForce"  # the OpenSim type, for the report


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
class ContactGeom:
    """A ContactGeometry as a MuJoCo geom: ``kind`` "sphere" or "plane", ``radius`` (m)."""

    name: str  # the OpenSim name
    geom: str  # the MuJoCo geom
    kind: str
    body: str
    radius: float
    weld: str  # the MuJoCo body it moves with (the world's name when static)
    static: bool


@dataclass
class ContactPair:
    """A pair of contact geoms of one contact force and the MuJoCo contact it became."""

    force: str
    name: str  # the MuJoCo pair
    first: ContactGeom  # the plane, when there is one (MuJoCo's contact normal points from it)
    second: ContactGeom
    law: HuntCrossley
    pair: mujoco.MjsPair
    fit: LinearContact | None = None
    inverse_weight: float = 0.0  # 1/kg, MuJoCo's scale of solref for this pair
    element: str = "HuntCrossleyForce"  # the force's OpenSim type


@dataclass
class ContactConversion:
    """The contact part of a :class:`~o2m.convert.force_context.ForceConversion`."""

    geoms: dict[str, ContactGeom] = field(default_factory=dict)
    pairs: list[ContactPair] = field(default_factory=list)
    forces: list[str] = field(default_factory=list)
    unused: dict[str, str] = field(default_factory=dict)  # geometry name -> why it has no geom


@dataclass
class ForceConversion:
    """What the force handlers did in one conversion."""

    handled: set[tuple[str, str]] = field(default_factory=set)  # (tag, name) of every element handled
    skipped: list[Skipped] = field(default_factory=list)
    limit_forces: list[LimitForce] = field(default_factory=list)
    ligaments: list[Ligament] = field(default_factory=list)
    springs: list[Spring] = field(default_factory=list)
    joint_springs: list[JointSpring] = field(default_factory=list)
    bushings: list[BushingFit] = field(default_factory=list)  # those with a joint spring are joint_springs too
    drifts: list[PoseDrift] = field(default_factory=list)
    actuators: list[str] = field(default_factory=list)
    contact: ContactConversion = field(default_factory=ContactConversion)
    #: Full-precision attribute values by (MJCF tag, name), written over MuJoCo's 6-digit output.
    exact: dict[tuple[str, str], dict[str, np.ndarray]] = field(default_factory=dict)

    @property
    def converted(self) -> int:
        return (len(self.limit_forces) + len(self.ligaments) + len(self.springs) + len(self.joint_springs)
                + sum(not b.joint_spring for b in self.bushings) + len(self.actuators)
                + len(self.contact.forces))


@dataclass
class _Context:
    builder: MjcfBuilder
    reader: SkeletonReader
    out: ForceConversion
    names: dict[str, set[str]]  # MJCF tag -> names in use
    #: The worst deflection error (rad or m) of a BushingForce's linear fit that still converts;
    #: None: only linear ones (:data:`o2m.convert.bushings.BUSHING_LINEAR_TOLERANCE`).
    bushing_tolerance: float | None = None

    @property
    def spec(self) -> mujoco.MjSpec:
        return self.builder.spec

    def path_tendon(self, el: etree._Element) -> str | None:
        """The spatial tendon of path force ``el``'s GeometryPath (named as the force, built by
        :mod:`o2m.convert.tendons` before the forces), None where its path became none."""
        name = el.get("name")
        return name if name in {t.name for t in self.spec.tendons} else None

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


def _coordinate(ctx: _Context, el: etree._Element) -> str:
    """The MuJoCo name of the coordinate ``el``'s <coordinate> names (bare name or path)."""
    return ctx.builder.skel.names.resolve(_text(el, "coordinate"))


def note_force_on_hinge(ctx: _Context, el: etree._Element, coord: str, what: str = "a force") -> None:
    """Say in the report that ``el``'s force on ``coord`` stays on MuJoCo's hinge ``coord``
    (``what`` it is there) where OpenSim's is a torque about the parent frame's axis (a Ball,
    Free or Ellipsoid rotation: :func:`angular_velocity_coordinate`)."""
    mobility = angular_velocity_coordinate(ctx, coord)
    if mobility is not None:
        ctx.builder.result.notes.append(
            f"{el.tag} '{el.get('name')}': {what} on hinge '{coord}'; OpenSim's force on this "
            f"{mobility[0].type} coordinate is a torque about its parent frame's axis, which the hinge "
            "follows only while the hinges before it are at 0")


def angular_velocity_coordinate(ctx: _Context, coord: str) -> tuple[object, int] | None:
    """(joint, i) when ``coord`` is rotational coordinate i of a Ball, Free or Ellipsoid joint
    (:func:`~o2m.convert.coordinates.is_mobility_rotation`), else None."""
    found = ctx.builder.coord_joint.get(coord)
    if found is None or not is_mobility_rotation(found.joint, coord):
        return None
    return found.joint, [ax.coordinate for ax in found.joint.rotations].index(coord)


def _flag(el: etree._Element, prop: str, default: bool) -> bool:
    t = _text(el, prop).lower()
    return default if not t else t in ("true", "1")


def _applies_force(el: etree._Element) -> bool:
    return _flag(el, "appliesForce", True) and not _flag(el, "isDisabled", False)


def _independent_ranges(builder: MjcfBuilder) -> dict[str, tuple[float, float]]:
    coords = {}
    for name, (_, ax) in builder.coord_joint.items():
        if builder.drivers[name].base == name and not builder.skel.coordinates[name].locked:
            coords[name] = builder.fit_range(name, ax.kind)
    return coords


def _random_values(builder: MjcfBuilder, n: int, seed: int = 0) -> list[dict[str, float]]:
    coords = _independent_ranges(builder)
    rng = np.random.default_rng(seed)
    return [{c: float(rng.uniform(lo, hi)) for c, (lo, hi) in coords.items()} for _ in range(n)]


def _isolated(model: mujoco.MjModel) -> mujoco.MjModel:
    """A copy of ``model`` with every spring and damper off."""
    m = copy.deepcopy(model)
    for arr in (m.jnt_stiffness, m.jnt_stiffnesspoly, m.dof_damping, m.dof_dampingpoly, m.tendon_stiffness,
                m.tendon_stiffnesspoly, m.tendon_damping, m.tendon_dampingpoly):
        arr[...] = 0.0
    return m


def _tendon_row(m: mujoco.MjModel, d: mujoco.MjData, t: int) -> np.ndarray:
    """Row ``t`` (nv,) of the tendon Jacobian (``ten_J`` is sparse in MuJoCo >= 3.3)."""
    tj = np.asarray(d.ten_J, dtype=float).ravel()
    if not hasattr(m, "ten_J_rownnz"):
        return tj.reshape(m.ntendon, m.nv)[t].copy()
    row = np.zeros(m.nv)
    a, n = int(m.ten_J_rowadr[t]), int(m.ten_J_rownnz[t])
    row[m.ten_J_colind[a:a + n]] = tj[a:a + n]
    return row


def worst_tendon_spring_error(model: mujoco.MjModel, builder: MjcfBuilder, tendon: str,
                              expected_tension: Callable[[float], float]) -> float:
    """Worst |MuJoCo's spring tension of ``tendon`` - ``expected_tension(length)``| (N) over
    :data:`N_POSES` random poses, with every other spring and damper off; the tension is read
    from ``qfrc_passive`` through the tendon's Jacobian (positive when pulling), lengths in m."""
    from o2m.mj.posing import joint_equality_plan, pose_mujoco

    m = _isolated(model)
    t = model.tendon(tendon).id
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
        worst = max(worst, abs(tension - expected_tension(float(d.ten_length[t]))))
    return worst
