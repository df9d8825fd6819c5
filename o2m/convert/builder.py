"""Building the MuJoCo model (an ``mujoco.MjSpec``) from a :class:`~o2m.skeleton.Skeleton`.

How an OpenSim joint becomes MuJoCo joints (see :mod:`o2m.skeleton` for the canonical form):

* The MuJoCo body is the OpenSim body: same name, same frame. Its fixed ``pos``/``quat`` is
  the OpenSim transform at the reference pose (every coordinate at its default value), so
  MuJoCo's ``qpos0`` is OpenSim's default pose.
* Each moving translation axis becomes a slide joint and each moving rotation axis a hinge.
  Slides come first, along the joint's parent-frame axes; hinges follow in OpenSim's order,
  about body-fixed axes through the child joint frame's origin. Constant axes at the
  reference pose are folded into the body's fixed transform, so the joint axes are rotated
  by the constant rotations that come after them in the sequence.
* A joint's value is the axis value ``f(q)``. The first axis whose function is the identity
  of a coordinate becomes *the* joint of that coordinate and carries its name, range and
  limits. Every other moving axis is driven by a MuJoCo joint equality (a quartic in the
  deviation of the driving coordinate from its reference value). When ``f`` is not linear,
  the quartic is fitted over the coordinate's range and its worst error is recorded; when that
  quartic misses :data:`COUPLING_TARGET`, the axis also gets extra joints of the same body on
  the same axis (inner joints, quartics of the coordinate, and outer joints, quartics of an
  inner joint), whose values add to the axis's, fitted with the coordinate's other coupled
  axes by :func:`o2m.functions.fit_couplings` within MuJoCo's 6 degrees of freedom per body.
  Where a body would need more, its joint's slides (main and extra joints) go on an
  intermediate body ``<body>_couplings`` (1e-12 kg, no geometry) between the parent and the
  body, at the body's reference frame, and the hinges stay on the body: translations along the
  parent frame's axes come first in a CustomJoint, so the two compose as one joint. The report's
  notes name each such body.
* CoordinateCouplerConstraints become joint equalities the same way.
* Joints added by other builders (path-point carriers, :mod:`o2m.tendons`) can be planned the
  same way (:meth:`MjcfBuilder.plan_extra_couplings`); every coupling's approximation records
  the errors of its value and of its derivative (d joint / d coordinate).
* A locked coordinate, and every axis or coupled coordinate that depends only on locked
  coordinates, is folded into the fixed body transforms at its default value: exact, and
  stiffer in simulation than a soft MuJoCo equality would be. It then has no MuJoCo joint.
* OpenSim ground (Y-up) maps to MuJoCo's world (Z-up) by :data:`o2m.transforms.OSIM_TO_MJ`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
from lxml import etree

from o2m.convert import geometry
from o2m.osim.functions import (
    COUPLING_GAIN,
    AxisFit,
    CouplingFit,
    fit_couplings,
    fit_polynomial,
    polynomial_slope_errors,
)
from o2m.osim.skeleton import Joint, Skeleton, Skipped, TransformAxis
from o2m.transforms import OSIM_TO_MJ, Transform, axis_angle_matrix, matrix_to_quat, quat_to_matrix

#: Mass (kg) and principal inertia (kg m²) given to massless moving bodies, which MuJoCo rejects.
MIN_MASS = 1e-8
MIN_INERTIA = 1e-12
#: Softness of every joint equality o2m writes (couplers, coupled axes, path-point carriers): the
#: shortest time constant MuJoCo allows at the default 2 ms step, critically damped, and an
#: impedance of 0.999, so a load deflects a coupling by about 1e-3 of what MuJoCo's default
#: (0.02 s, 0.9..0.95) allows. OpenSim's constraints are exact.
EQUALITY_SOLREF = (0.004, 1.0)
EQUALITY_SOLIMP = (0.999, 0.999, 0.001, 0.5, 2.0)
#: Range over which a coupling with an unbounded driving coordinate is fitted (rad or m).
UNBOUNDED_FIT_RANGE = {"rotation": (-np.pi, np.pi), "translation": (-1.0, 1.0)}
#: Samples used to decide whether a function is linear over a range.
_LINEAR_SAMPLES = 401
#: Worst error a skeleton coupling (a coupled transform axis or a coupler) is fitted to, per
#: unit: 0.01 mm and 0.005 deg, a tenth of the skeleton's 0.1 mm / 0.05 deg budget. A plain
#: quartic within it stays a plain quartic; otherwise the coordinate's coupled axes get inner
#: and outer joints (:func:`o2m.functions.fit_couplings`) until they are within it, until more
#: joints stop helping, or until their bodies are full (:data:`MAX_BODY_DOFS`).
COUPLING_TARGET = {"m": 1e-5, "rad": float(np.deg2rad(0.005))}
#: Derivative target of a skeleton coupling (per unit of the axis, per unit of its coordinate), or
#: None: fitted to the value only (see :func:`o2m.functions.fit_couplings`'s ``slope_targets``).
#: A knee translation's derivative error is a moment-arm error of every knee muscle. None,
#: measured: with 2e-4 m/rad on the slides, Gait10dof18musc's knee translations reach 0.69 and
#: 0.51 mm/rad worst (1.16 and 1.44 fitted to the value) for 0.041 mm (0.035) and its
#: hamstrings' and gastrocnemius' moment-arm RMS falls from 0.24-0.32 to 0.19-0.24 mm (p95 of all
#: pairs 0.51 -> 0.50 mm); but Leg6Dof9Musc's plan changes (no intermediate bodies: 40 -> 33 dofs)
#: and its patella translations miss 0.1 mm (0.13 and 0.22 mm at 2e-4 and 1e-4 m/rad).
COUPLING_SLOPE_TARGET: dict[str, float | None] = {"m": None, "rad": None}
#: Skeleton couplings with extra joints are also fitted this fraction of their coordinate's range
#: beyond each end, with :data:`o2m.functions.COUPLING_MARGIN_SLACK` times the error allowed
#: there: a joint pressing into a soft limit leaves its range a little (Leg6Dof9Musc's knee,
#: swinging into its limit, went 0.026 rad past it), and a degree-16 fit of the range alone
#: leaves the spline fast (0.8 mm 0.05 rad beyond a knee's range). Farther out the extra
#: joints diverge much faster than a plain quartic: keep such coordinates within their range.
COUPLING_MARGIN = 0.02
#: Degrees of freedom MuJoCo allows one body ("more than 6 dofs in body" otherwise).
MAX_BODY_DOFS = 6
#: A coordinate's couplings are planned with a joint's translations and rotations on bodies of
#: their own (:meth:`MjcfBuilder._couplings_body`) when that brings the worst error, relative to
#: :data:`COUPLING_TARGET`, below this fraction of what the joints fit on one body reach.
COUPLING_SPLIT_GAIN = 0.5
#: Mass (kg) and principal inertia (kg m²) of an intermediate body carrying a joint's
#: translations: just above what MuJoCo accepts, so the model's mass and centre of mass stay
#: OpenSim's. Its slides move the OpenSim body hanging from it, so their inertia is that body's.
COUPLINGS_BODY_MASS = 1e-12
COUPLINGS_BODY_INERTIA = 1e-14
#: Armature of each extra joint of a coupled axis, as a multiple of its main joint's own inertia
#: at the reference pose (the mass, or moment of inertia about the axis, of everything the joint
#: moves). Several joints along one axis of one body make the mass matrix singular without
#: armature, and an armature much lighter than the body makes their equalities soft: in
#: Gait2354 hanging under gravity, 0.01 kg let the knee translations sag 0.2 mm off their
#: equalities, the body's own inertia (5.3 kg) 0.01 mm, as the plain quartic's single joint.
#: The extra joints move a few millimetres (or a few hundredths of a radian) over their
#: coordinate's range, so this adds little to the coordinate's inertia (the report gives it).
COUPLING_ARMATURE = 1.0


@dataclass
class Approximation:
    """A place where the MuJoCo model only approximates OpenSim, with the measured error."""

    element: str
    name: str
    what: str
    max_error: float
    units: str
    detail: str = ""
    joint: str = ""  # the MuJoCo joint whose motion is approximated, if any
    #: For a coupling: the worst and RMS error of d joint / d coordinate over the coordinate's
    #: range, in ``slope_units`` (for a path point's location against an angle, m/rad: a
    #: moment-arm error); None otherwise.
    slope_error: float | None = None
    slope_rms: float | None = None
    slope_units: str = ""


@dataclass
class JointRecord:
    """One MuJoCo joint: what drives it and how."""

    name: str
    kind: str  # "hinge" or "slide"
    opensim_joint: str
    axis: str
    coordinate: str | None  # the OpenSim coordinate whose value this joint is, if any
    driven_by: str | None  # MuJoCo joint of the equality that drives it, if any
    relation: str  # "coordinate", "linear", "quartic fit"


@dataclass
class BuildResult:
    spec: mujoco.MjSpec
    joints: list[JointRecord] = field(default_factory=list)
    approximations: list[Approximation] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


@dataclass
class _CoupledAxis:
    """A skeleton axis (or coupled coordinate) that a non-linear function of a coordinate moves."""

    name: str  # its MuJoCo joint
    body: str
    kind: str  # "hinge" or "slide"
    base: str  # the independent coordinate driving it
    rel: Callable[[np.ndarray], np.ndarray]  # its value minus its reference value, of the base's value

    @property
    def units(self) -> str:
        return "rad" if self.kind == "hinge" else "m"


@dataclass
class _PlannedAxis:
    """One coupled axis of a coordinate's :class:`~o2m.functions.CouplingFit`."""

    fit: CouplingFit
    index: int  # the axis's index in the fit
    axes: list[_CoupledAxis]  # every axis of the fit, in order
    inner_names: list[str]  # the fit's inner joints, in order
    lo: float
    hi: float
    #: armature (kg or kg m²) of each extra joint, set when planned (path-point carriers); None:
    #: set by :meth:`MjcfBuilder._set_extra_armature` once the skeleton is built
    armature: float | None = None


def _inner_names(fit: CouplingFit, group: list[_CoupledAxis]) -> list[str]:
    """The MuJoCo names of a fit's inner joints: ``<host joint>_inner<k>``."""
    counts: dict[str, int] = {}
    names = []
    for h in fit.hosts:
        counts[group[h].name] = counts.get(group[h].name, 0) + 1
        names.append(f"{group[h].name}_inner{counts[group[h].name]}")
    return names


def _extra_slopes(planned: _PlannedAxis, x: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, int]]:
    """d joint / d coordinate at x of every extra joint of a coordinate's plan, by name, and the
    inner joint (index) each outer joint is driven by."""
    poly = np.polynomial.polynomial
    fit = planned.fit
    inner = fit.inner_values(x)
    dinner = [poly.polyval(x - fit.x0, poly.polyder(c)) for c in fit.inners]
    slopes: dict[str, np.ndarray] = {}
    driver: dict[str, int] = {}
    for i, a in enumerate(planned.axes):
        for n, (k, c) in enumerate(fit.axes[i].outers):
            name = f"{a.name}_outer{n + 1}"
            slopes[name] = poly.polyval(inner[k], poly.polyder(c)) * dinner[k]
            driver[name] = k
    for k, name in enumerate(planned.inner_names):
        slopes[name] = dinner[k]
    return slopes, driver


def _linear(fn: Callable[[np.ndarray], np.ndarray], lo: float, hi: float) -> tuple[float, float] | None:
    """(slope, intercept) when ``fn`` is linear on [lo, hi] to 1e-12 (relative), else None."""
    x = np.linspace(lo, hi, _LINEAR_SAMPLES)
    y = np.asarray(fn(x), dtype=float)
    if hi - lo < 1e-15:
        return 0.0, float(y[0])
    slope = (y[-1] - y[0]) / (hi - lo)
    icpt = y[0] - slope * lo
    scale = max(1.0, float(np.max(np.abs(y))))
    if np.max(np.abs(y - (slope * x + icpt))) <= 1e-12 * scale:
        return float(slope), float(icpt)
    return None


class _Driver:
    """An independent coordinate and a function of it: the value of a coordinate or an axis."""

    def __init__(self, base: str, fn: Callable[[np.ndarray], np.ndarray]):
        self.base, self.fn = base, fn

    def then(self, f: Callable[[np.ndarray], np.ndarray]) -> _Driver:
        inner = self.fn
        return _Driver(self.base, lambda x: f(inner(x)))


def _relative(driver: _Driver, ref: float) -> Callable[[np.ndarray], np.ndarray]:
    """x -> driver.fn(x) - ref: a joint's value relative to its reference value."""
    return lambda x: np.asarray(driver.fn(np.asarray(x, dtype=float)), dtype=float) - ref


class MjcfBuilder:
    """Builds an ``MjSpec`` from a skeleton; :func:`add_geometry` adds its geometry after."""

    def __init__(self, skel: Skeleton, *, plan_couplings: bool = True):
        self.skel = skel
        #: Whether skeleton couplings get extra joints (:meth:`_plan_couplings`); else plain quartics.
        self.plan_couplings = plan_couplings
        self.doc = skel.document
        self.spec = mujoco.MjSpec()
        self.result = BuildResult(self.spec)
        self.drivers = self._coordinate_drivers()
        self.ref = {name: float(np.asarray(d.fn(np.array([self._base_ref(d.base)])))[0])
                    for name, d in self.drivers.items()}
        self.coord_joint: dict[str, tuple[Joint, TransformAxis]] = self._choose_coordinate_axes()
        self.bodies: dict[str, mujoco.MjsBody] = {"ground": self.spec.worldbody}
        self._order: list[Joint] | None = None
        #: Each body's frame in OpenSim ground at the reference pose.
        self.ground_frames: dict[str, Transform] = {"ground": Transform()}
        #: Exact attribute values by (MJCF tag, name): MuJoCo's XML writer prints 6 digits.
        self.exact: dict[tuple[str, str], dict[str, np.ndarray | float]] = {}
        #: Each skeleton joint's body, type, axis and anchor, for the extra joints of its coupling.
        self._joint_frames: dict[str, tuple[mujoco.MjsBody, mujoco.mjtJoint, np.ndarray, np.ndarray]] = {}
        #: Records of the extra joints made for a coupled joint, listed after it.
        self._extra_records: dict[str, list[JointRecord]] = {}
        #: The extra joints of each coupled joint, by its name.
        self._extras_of: dict[str, list[str]] = {}
        #: The fitted couplings of the skeleton's coupled axes, by MuJoCo joint name.
        self._planned: dict[str, _PlannedAxis] = {}
        #: Bodies whose joint's translations go on an intermediate body: (slides, hinges) they get.
        self._split: dict[str, tuple[int, int]] = {}
        #: Each intermediate body made for couplings, by its OpenSim body.
        self.couplings_bodies: dict[str, str] = {}

    # -- coordinates -------------------------------------------------------------------
    def _base_ref(self, name: str) -> float:
        return self.skel.coordinates[name].default

    def _coordinate_drivers(self) -> dict[str, _Driver]:
        """Each coordinate as a function of an independent coordinate (couplers resolved)."""
        couplers = {c.dependent: c for c in self.skel.couplers}
        drivers: dict[str, _Driver] = {}

        def resolve(name: str, seen: tuple[str, ...]) -> _Driver:
            if name in drivers:
                return drivers[name]
            if name in seen:
                raise self.doc.error(couplers[name].element, "is part of a circular chain of couplers")
            cp = couplers.get(name)
            if cp is None:
                d = _Driver(name, lambda x: np.asarray(x, dtype=float))
            else:
                d = resolve(cp.independent, seen + (name,)).then(cp.function)
            drivers[name] = d
            return d

        for name in self.skel.coordinates:
            resolve(name, ())
        return drivers

    def _choose_coordinate_axes(self) -> dict[str, tuple[Joint, TransformAxis]]:
        chosen: dict[str, tuple[Joint, TransformAxis]] = {}
        for joint in self.skel.joints:
            for ax in joint.translations + joint.rotations:
                c = ax.coordinate
                if c is None or c in chosen or self.is_fixed(ax):
                    continue
                if self._is_identity(ax, *self.fit_range(c, ax.kind)):
                    chosen[c] = (joint, ax)
        for name, coord in self.skel.coordinates.items():
            if name not in chosen and self.drivers[name].base == name and not coord.locked:
                users = [j for j in self.skel.joints if any(a.coordinate == name for a in j.rotations + j.translations)]
                if users:
                    raise self.doc.error(coord.element, "drives no transform axis through the identity function, so "
                                         "no MuJoCo joint can carry its value; o2m cannot convert this coordinate")
        return chosen

    def coordinate_values(self, changes: dict[str, float] | None = None) -> dict[str, float]:
        """Every coordinate's value with independent coordinates at the reference pose except
        ``changes``; dependent coordinates follow their couplers."""
        base = {name: self.ref[name] for name, d in self.drivers.items() if d.base == name}
        base.update(changes or {})
        return {name: float(np.asarray(d.fn(np.array([base[d.base]])))[0]) for name, d in self.drivers.items()}

    def ground_frames_at(self, values: dict[str, float]) -> dict[str, Transform]:
        """Each body's frame in OpenSim ground when the coordinates have ``values`` (all of them)."""
        frames = {"ground": Transform()}
        if self._order is None:
            self._order = self._ordered_joints()
        for joint in self._order:
            frames[joint.child] = frames[joint.parent] @ joint.transform(values)
        return frames

    def is_fixed(self, ax: TransformAxis) -> bool:
        """True when the axis does not move: no coordinate, or it depends on a locked coordinate only."""
        return ax.coordinate is None or self.skel.coordinates[self.drivers[ax.coordinate].base].locked

    @staticmethod
    def _is_identity(ax: TransformAxis, lo: float, hi: float) -> bool:
        lin = _linear(ax.function, lo, hi)
        return lin is not None and abs(lin[0] - 1.0) < 1e-12 and abs(lin[1]) < 1e-12

    def fit_range(self, name: str, kind: str) -> tuple[float, float]:
        lo, hi = self.skel.coordinates[name].range
        ulo, uhi = UNBOUNDED_FIT_RANGE[kind]
        if hi - lo > 1e3:  # OpenSim writes ±99999.9 for "no range"
            lo, hi = ulo, uhi
        return float(lo), float(hi)

    # -- the tree ----------------------------------------------------------------------
    def _ordered_joints(self) -> list[Joint]:
        by_child: dict[str, Joint] = {}
        for j in self.skel.joints:
            if j.child in by_child:
                raise self.doc.error(j.element, f"makes body '{j.child}' the child of a second joint "
                                                f"('{by_child[j.child].name}'); closed loops are not supported")
            if j.child == "ground":
                raise self.doc.error(j.element, "has ground as its child; reversed joints are not supported")
            if j.child not in self.skel.bodies:
                raise self.doc.error(j.element, f"connects a child frame on '{j.child}', which is not a body")
            by_child[j.child] = j
        for name, body in self.skel.bodies.items():
            if name not in by_child:
                raise self.doc.error(body.element, "is connected to the model by no joint")
        order: list[Joint] = []
        placed = {"ground"}
        pending = list(self.skel.joints)
        while pending:
            ready = [j for j in pending if j.parent in placed]
            if not ready:
                j = pending[0]
                raise self.doc.error(j.element, f"hangs from '{j.parent}', which is not connected to ground")
            for j in ready:
                order.append(j)
                placed.add(j.child)
                pending.remove(j)
        return order

    def build(self) -> BuildResult:
        spec = self.spec
        spec.modelname = self.skel.name
        spec.compiler.degree = False
        spec.compiler.autolimits = True
        spec.option.timestep = 0.002
        spec.option.gravity = OSIM_TO_MJ @ self.skel.gravity
        if self.plan_couplings:
            self._plan_couplings()
        for joint in self._ordered_joints():
            self._add_joint(joint)
        for c in self.skel.coordinates.values():
            if c.locked:
                self.result.notes.append(f"locked coordinate '{c.name}' folded into fixed transforms at {c.default:g}")
        self._set_extra_armature()
        for marker in self.skel.markers:
            body = self.bodies[marker.body]
            pos = marker.position if marker.body != "ground" else OSIM_TO_MJ @ marker.position
            body.add_site(name=marker.name, pos=pos, size=[0.005, 0, 0], rgba=[0.9, 0.2, 0.9, 1], group=4)
            self.exact[("site", marker.name)] = {"pos": pos}
        return self.result

    def _axis_driver(self, ax: TransformAxis) -> _Driver:
        return self.drivers[ax.coordinate].then(ax.function)

    def _add_joint(self, joint: Joint) -> None:
        q0 = {name: self.ref[name] for name in self.skel.coordinates}
        r0 = [ax.value(q0) for ax in joint.rotations]
        consts = [axis_angle_matrix(ax.axis, v) for ax, v in zip(joint.rotations, r0, strict=True)]
        c_all = np.eye(3)
        for c in consts:
            c_all = c_all @ c
        t0 = sum((ax.value(q0) * ax.axis for ax in joint.translations), np.zeros(3))
        x_pb0 = joint.parent_frame @ Transform(pos=t0) @ Transform(rot=c_all) @ joint.child_frame.inverse()
        x_world = Transform(OSIM_TO_MJ) @ x_pb0 if joint.parent == "ground" else x_pb0
        parent = self.bodies[joint.parent]
        if joint.child in self._split:
            slides = self._couplings_body(joint, x_world)
            body = slides.add_body(name=joint.child, pos=np.zeros(3), quat=np.array([1.0, 0, 0, 0]))
            self.exact[("body", joint.child)] = {"pos": np.zeros(3), "quat": np.array([1.0, 0, 0, 0])}
        else:
            body = slides = parent.add_body(name=joint.child, pos=x_world.pos, quat=matrix_to_quat(x_world.rot))
            self.exact[("body", joint.child)] = {"pos": x_world.pos, "quat": matrix_to_quat(x_world.rot)}
        self.bodies[joint.child] = body
        self.ground_frames[joint.child] = self.ground_frames[joint.parent] @ x_pb0
        self._set_inertial(body, joint)
        moving = [(ax, "slide") for ax in joint.translations] + [(ax, "hinge") for ax in joint.rotations]
        for ax, kind in moving:
            if self.is_fixed(ax):
                continue
            if kind == "slide":
                axis = x_pb0.rot.T @ joint.parent_frame.rot @ ax.axis
                pos = np.zeros(3)
                ref = ax.value(q0)
            else:
                i = joint.rotations.index(ax)
                after = np.eye(3)
                for c in consts[i + 1:]:
                    after = after @ c
                axis = joint.child_frame.rot @ (after.T @ ax.axis)
                pos = joint.child_frame.pos
                ref = r0[i]
            self._add_mj_joint(slides if kind == "slide" else body, joint, ax, kind, axis, pos, ref)

    def _couplings_body(self, joint: Joint, x_world: Transform) -> mujoco.MjsBody:
        """An intermediate body between ``joint``'s parent and its child, at the child's frame at
        the reference pose, to carry the joint's translations (slides along the parent frame's
        axes come before the rotations in OpenSim's CustomJoint, so they compose the same way)
        when the joints of its spline couplings would give the child more than
        :data:`MAX_BODY_DOFS`. The child hangs from it with no offset and keeps the rotations,
        its inertial, geometry and sites. Named ``<child>_couplings``; nearly massless
        (:data:`COUPLINGS_BODY_MASS`)."""
        names = set(self.skel.bodies) | set(self.couplings_bodies.values())
        name, k = f"{joint.child}_couplings", 1
        while name in names:
            name, k = f"{joint.child}_couplings{k}", k + 1
        body = self.bodies[joint.parent].add_body(name=name, pos=x_world.pos, quat=matrix_to_quat(x_world.rot))
        self.exact[("body", name)] = {"pos": x_world.pos, "quat": matrix_to_quat(x_world.rot)}
        body.explicitinertial = True
        body.mass = COUPLINGS_BODY_MASS
        body.ipos = np.zeros(3)
        body.fullinertia = [COUPLINGS_BODY_INERTIA] * 3 + [0.0] * 3
        self.exact[("inertial", name)] = {"pos": np.zeros(3), "mass": COUPLINGS_BODY_MASS,
                                          "fullinertia": np.array(body.fullinertia)}
        self.couplings_bodies[joint.child] = name
        slides, hinges = self._split[joint.child]
        self.result.notes.append(
            f"body '{name}' ({COUPLINGS_BODY_MASS:g} kg) carries the translations of joint '{joint.name}' between "
            f"'{joint.parent}' and '{joint.child}' (slides: {slides}; '{joint.child}' keeps the hinges: {hinges}): "
            f"with the extra joints of its spline couplings one body would have {slides + hinges} degrees of "
            f"freedom, MuJoCo allows {MAX_BODY_DOFS}")
        return body

    # -- couplings beyond a quartic ------------------------------------------------------
    def _mj_joint_name(self, joint: Joint, ax: TransformAxis) -> tuple[str, bool]:
        """The MuJoCo joint name of a moving axis, and whether it is its coordinate's joint."""
        is_coord = self.coord_joint.get(ax.coordinate, (None, None))[1] is ax
        return (ax.coordinate if is_coord else f"{joint.name}_{ax.name}"), is_coord

    def coupled_axes(self) -> tuple[list[_CoupledAxis], dict[tuple[str, str], int]]:
        """Every moving skeleton axis that a non-linear function of an independent coordinate
        drives (transform axes and coupled coordinates), in build order; and each body's number
        of moving axes of each kind, by (body, "slide" or "hinge")."""
        q0 = {name: self.ref[name] for name in self.skel.coordinates}
        out, dofs = [], {}
        for joint in self._ordered_joints():
            moving = [(ax, "slide") for ax in joint.translations] + [(ax, "hinge") for ax in joint.rotations]
            moving = [(ax, kind) for ax, kind in moving if not self.is_fixed(ax)]
            for kind in ("slide", "hinge"):
                dofs[joint.child, kind] = sum(k == kind for _, k in moving)
            for ax, kind in moving:
                name, is_coord = self._mj_joint_name(joint, ax)
                if is_coord and self.drivers[ax.coordinate].base == ax.coordinate:
                    continue
                driver = self.drivers[ax.coordinate] if is_coord else self._axis_driver(ax)
                base = driver.base
                if base not in self.coord_joint:
                    continue  # couple() reports it
                ref = ax.value(q0)
                lo, hi = self._coupling_range(base)
                rel = _relative(driver, ref)
                if _linear(rel, lo, hi) is None:
                    out.append(_CoupledAxis(name, joint.child, kind, base, rel))
        return out, dofs

    def coupling_fit(self, joint: str) -> AxisFit | None:
        """The fit of skeleton coupled joint ``joint`` (after :meth:`build`): its main joint, outer
        joints and errors; None for a joint that is not a non-linear skeleton coupling."""
        planned = self._planned.get(joint)
        return None if planned is None else planned.fit.axes[planned.index]

    def _coupling_range(self, base: str) -> tuple[float, float]:
        """Where a coupling driven by coordinate ``base`` is fitted: its range, with its reference."""
        lo, hi = self.fit_range(base, self.coord_joint[base][1].kind)
        return min(lo, self.ref[base]), max(hi, self.ref[base])

    def _plan_couplings(self) -> None:
        """Fit every coordinate's non-linear skeleton couplings together (they may share inner
        joints) and choose their joints, within :data:`MAX_BODY_DOFS` per body; then choose the
        joints whose translations get a body of their own (:meth:`_couplings_body`).

        Each coordinate is planned first with every body's joints on that body
        (:meth:`_plan_group`). When an axis then still misses :data:`COUPLING_TARGET`, it is planned
        again with a joint's translations and its rotations counted apart, each within
        :data:`MAX_BODY_DOFS` (an intermediate body would then carry the translations), and
        that plan is kept when its worst error relative to the target is below
        :data:`COUPLING_SPLIT_GAIN` times the first plan's. A joint whose body then has more
        than :data:`MAX_BODY_DOFS` is split."""
        axes, dofs = self.coupled_axes()
        by_base: dict[str, list[_CoupledAxis]] = {}
        for a in axes:
            by_base.setdefault(a.base, []).append(a)
        weights = self._main_inertias([a.name for a in axes]) if axes else {}
        used: dict[tuple[str, str], int] = {}  # extra joints planned so far, per (body, joint kind)
        for base, group in by_base.items():
            lo, hi = self._coupling_range(base)

            def room(split: bool, group=group) -> tuple[list[object], dict[object, int]]:
                keys: list[object] = [(a.body, a.kind) if split else a.body for a in group]
                free = {}
                for a, key in zip(group, keys, strict=True):
                    kinds = (a.kind,) if split else ("slide", "hinge")
                    free[key] = MAX_BODY_DOFS - sum(dofs.get((a.body, k), 0) + used.get((a.body, k), 0) for k in kinds)
                return keys, free

            weight = [weights.get(a.name, 1.0) for a in group]
            slopes = [COUPLING_SLOPE_TARGET[a.units] for a in group]
            slopes = None if all(v is None for v in slopes) else [math.inf if v is None else v for v in slopes]

            def worst_of(f: CouplingFit, group=group, slopes=slopes) -> float:
                return max(max(ax.max_error / COUPLING_TARGET[a.units], ax.slope_error / slopes[i] if slopes else 0.0)
                           for i, (ax, a) in enumerate(zip(f.axes, group, strict=True)))

            best = self._plan_group(group, *room(False), lo, hi, weight, slope_targets=slopes)
            worst = worst_of(best)
            if worst > 1:
                split = self._plan_group(group, *room(True), lo, hi, weight, slope_targets=slopes)
                split_worst = worst_of(split)
                if split_worst < COUPLING_SPLIT_GAIN * worst:
                    best = split
            for i, a in enumerate(group):
                used[a.body, a.kind] = used.get((a.body, a.kind), 0) + best.extra_joints(i)
            inner_names = _inner_names(best, group)
            for i, a in enumerate(group):
                self._planned[a.name] = _PlannedAxis(best, i, group, inner_names, lo, hi)
        for body in {b for b, _ in dofs}:
            total = sum(dofs.get((body, k), 0) + used.get((body, k), 0) for k in ("slide", "hinge"))
            if total > MAX_BODY_DOFS:
                self._split[body] = (dofs.get((body, "slide"), 0) + used.get((body, "slide"), 0),
                                     dofs.get((body, "hinge"), 0) + used.get((body, "hinge"), 0))

    def plan_extra_couplings(self, group: list[_CoupledAxis], keys: list[object], room: dict[object, int], *,
                             targets: list[float], slope_targets: list[float] | None,
                             armature: float) -> CouplingFit:
        """Plan couplings beyond a quartic for axes that callers outside this class add (path-point
        carriers): the axes ``group`` of one coordinate, all equally heavy, axis i's extra joints
        counted against ``room[keys[i]]``, fitted to ``targets`` and ``slope_targets`` as
        :meth:`_plan_group` does. Each joint then follows its plan when :meth:`couple` is called
        with ``high_order=True`` after :meth:`register_joint`; every extra joint gets ``armature``."""
        lo, hi = self._coupling_range(group[0].base)
        best = self._plan_group(group, keys, room, lo, hi, [1.0] * len(group), targets, slope_targets,
                                cheaper_too=True)
        inner_names = _inner_names(best, group)
        for i, a in enumerate(group):
            self._planned[a.name] = _PlannedAxis(best, i, group, inner_names, lo, hi, armature)
        return best

    def register_joint(self, name: str, body: mujoco.MjsBody, jtype: mujoco.mjtJoint, axis: np.ndarray,
                       pos: np.ndarray) -> None:
        """Record a joint added outside this class (body, type, axis, anchor), so that the extra
        joints of its planned coupling can be added beside it."""
        self._joint_frames[name] = (body, jtype, np.asarray(axis, dtype=float), np.asarray(pos, dtype=float))

    def pop_extra_records(self, joint: str) -> list[JointRecord]:
        """The records of the extra joints :meth:`couple` made for ``joint`` (a caller outside
        this class lists them after the joint's own), once."""
        return self._extra_records.pop(joint, [])

    def _plan_group(self, group: list[_CoupledAxis], keys: list[object], room: dict[object, int],
                    lo: float, hi: float, weight: list[float], targets: list[float] | None = None,
                    slope_targets: list[float] | None = None, cheaper_too: bool = False) -> CouplingFit:
        """The coupling fit of one coordinate's coupled axes ``group``, axis i's extra joints
        counted against ``room[keys[i]]`` (the degrees of freedom left where they would go).

        MuJoCo softens a joint equality by the sum of its two joints' inverse weights
        (``dof_invweight0``, whatever their units), so an inner joint needs at least the
        armature of the outer joints it drives (:meth:`_set_extra_armature`): an outer slide of
        the tibia driven by an inner hinge of the light patella sagged 1.5 mm under the tibia's
        weight. That costs little on a slide, which moves millimetres (6 kg on a knee's inner
        slide adds 1e-5 kg m² to the knee), but much on a hinge, which moves a tenth of a radian:
        so an axis drives outer joints only from inner slides or from inner hinges of axes at
        least as heavy (``weight``: each main joint's own inertia, :meth:`_main_inertias`).

        Start (when a plain quartic misses :data:`COUPLING_TARGET`): one inner joint on the
        heaviest axis that misses and has room (the most room on ties) and one outer joint for
        each axis that misses, worst first, while there is room. Then, while an axis still misses
        and has room: a new inner joint on it with an outer joint (two joints), else an outer
        joint of an inner joint it has none of yet (one joint); kept only if that axis's error
        drops below COUPLING_GAIN times what it was and no axis of the coordinate gets worse than
        the worst was.

        ``targets`` (default :data:`COUPLING_TARGET` by unit) and ``slope_targets`` (derivative
        targets, None: the value only): an axis misses when its value error exceeds its target
        or its derivative error its slope target, by the larger ratio (the fits are then
        derivative-aware, :func:`o2m.functions.fit_couplings`). With ``cheaper_too``, an axis whose
        new inner/outer pair is not kept tries an outer joint of an inner joint it has none of yet
        before it is given up (path-point carriers; the skeleton's plans stay as they were)."""
        room = dict(room)

        def may_use(i: int, host: int) -> bool:
            return group[host].kind == "slide" or weight[host] >= (1 - 1e-6) * weight[i]

        x0 = self.ref[group[0].base]
        fns = [a.rel for a in group]
        if targets is None:
            targets = [COUPLING_TARGET[a.units] for a in group]

        def fit(uses, hosts, start=()):
            return fit_couplings(fns, lo, hi, x0, targets=targets, uses=uses, hosts=hosts, start_shapes=start,
                                 margin=COUPLING_MARGIN, slope_targets=slope_targets)

        def ratios(f: CouplingFit) -> list[float]:
            if slope_targets is None:
                return [ax.max_error / tg for ax, tg in zip(f.axes, targets, strict=True)]
            return [max(ax.max_error / tg, ax.slope_error / st)
                    for ax, tg, st in zip(f.axes, targets, slope_targets, strict=True)]

        best = fit([[] for _ in group], [])
        uses: list[list[int]] = [[] for _ in group]
        hosts: list[int] = []
        missing = sorted((i for i, r in enumerate(ratios(best)) if r > 1), key=lambda i: -ratios(best)[i])
        candidates = [i for i in missing if room[keys[i]] >= 1]
        if candidates:
            need = {b: sum(keys[i] == b for i in missing) for b in room}
            heaviest = max(weight[i] for i in candidates)
            candidates = [i for i in candidates if weight[i] >= (1 - 1e-6) * heaviest]
            host = max(candidates, key=lambda i: room[keys[i]] - need[keys[i]])  # the worst on ties
            hosts.append(host)
            room[keys[host]] -= 1
            for i in missing:
                if room[keys[i]] >= 1 and may_use(i, host):
                    uses[i].append(0)
                    room[keys[i]] -= 1
            if any(uses):
                best = fit(uses, hosts)
            else:
                hosts = []
        done: set[int] = set()
        while hosts:
            r = ratios(best)
            order = sorted((i for i in range(len(group)) if r[i] > 1 and i not in done), key=lambda i: -r[i])
            moves: list[tuple[int, list[int], int, int]] = []
            for i in order:
                b = keys[i]
                if room[b] >= 2:
                    moves.append((i, [*hosts, i], len(hosts), 2))
                unused = [k for k in range(len(hosts)) if k not in uses[i] and may_use(i, hosts[k])]
                if room[b] >= 1 and unused:
                    moves.append((i, hosts, unused[0], 1))
                if moves:
                    break
            if not moves:
                break
            for i, new_hosts, k, cost in moves if cheaper_too else moves[:1]:
                new_uses = [list(u) + ([k] if j == i else []) for j, u in enumerate(uses)]
                trial = fit(new_uses, new_hosts, best.shapes)
                if ratios(trial)[i] <= COUPLING_GAIN * r[i] and max(ratios(trial)) <= max(r):
                    best, uses, hosts = trial, new_uses, list(new_hosts)
                    room[keys[i]] -= cost
                    break
            else:
                done.add(i)
        return best

    def _main_inertias(self, joints: list[str]) -> dict[str, float]:
        """Each of ``joints``' own inertia (kg or kg m², the diagonal of the mass matrix) at the
        reference pose in the skeleton with plain quartic couplings; {} if it does not compile."""
        plain = MjcfBuilder(self.skel, plan_couplings=False)
        plain.build()
        try:
            m = plain.spec.compile()
        except ValueError:
            return {}
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        inertia = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, inertia)
        dofs = {j: int(m.jnt_dofadr[m.joint(j).id]) for j in joints}
        return {j: float(inertia[k, k]) for j, k in dofs.items()}

    def _set_extra_armature(self) -> None:
        """Give every extra joint of a coupled axis :data:`COUPLING_ARMATURE` times the main
        joint's own inertia at the reference pose (the skeleton compiled as built so far), and
        an inner joint at least the largest armature of the outer joints it drives (MuJoCo
        softens their equalities by the inner joint's inverse weight; see :meth:`_plan_group`).
        Add to each axis's approximation how much its extra joints add to the inertia of its
        coordinate at most: Σ armature (d joint / d coordinate)² over the coordinate's range."""
        mains = self._extras_of
        if not mains:
            return
        try:
            m = self.spec.compile()
        except ValueError:
            return  # the conversion's own compile reports what is wrong
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        inertia = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, inertia)
        armature: dict[str, float] = {}
        for main, recs in mains.items():
            dof = int(m.jnt_dofadr[m.joint(main).id])
            for name in recs:
                armature[name] = COUPLING_ARMATURE * float(inertia[dof, dof] - m.dof_armature[dof])
        slopes: dict[str, np.ndarray] = {}  # each extra joint's d joint / d coordinate over the range
        for planned in {id(p.axes): p for p in self._planned.values()}.values():  # each coordinate's once
            own, driver = _extra_slopes(planned, np.linspace(planned.lo, planned.hi, 2001))
            slopes.update(own)
            driven = [0.0] * planned.fit.n_inner  # the largest armature of each inner joint's outer joints
            for name, k in driver.items():
                driven[k] = max(driven[k], armature[name])
            for k, name in enumerate(planned.inner_names):
                armature[name] = max(armature[name], driven[k])
        for name, value in armature.items():
            self.spec.joint(name).armature = value
        approx = {a.joint: a for a in self.result.approximations if a.joint}
        for main, recs in mains.items():
            planned = self._planned[main]
            added = float(np.max(sum(armature[n] * slopes[n] ** 2 for n in recs)))
            a = approx.get(main)
            if a is not None:
                unit = "kg" if m.jnt_type[m.joint(main).id] == mujoco.mjtJoint.mjJNT_SLIDE else "kg m^2"
                base = planned.axes[planned.index].base
                coord_unit = "kg m^2" if self.coord_joint[base][1].kind == "rotation" else "kg"
                arms = ", ".join(f"{armature[n]:.3g}" for n in recs)
                a.detail += f"; armature {arms} {unit}, adding at most {added:.3g} {coord_unit} to '{base}'"

    def _set_inertial(self, body: mujoco.MjsBody, joint: Joint) -> None:
        b = self.skel.bodies[joint.child]
        mass, inertia = b.mass, b.inertia.copy()
        if mass == 0.0:  # OpenSim ignores the inertia of a massless body
            inertia[:] = 0.0
        moving = not all(self.is_fixed(ax) for ax in joint.rotations + joint.translations)
        if moving and mass < MIN_MASS:
            self.result.approximations.append(Approximation(
                "Body", b.name, f"massless moving body given {MIN_MASS:g} kg (MuJoCo needs mass)", MIN_MASS, "kg"))
            mass = MIN_MASS
        eig = np.linalg.eigvalsh(inertia)
        if eig.min() < MIN_INERTIA:  # MuJoCo needs positive inertia, also on welded bodies
            inertia = inertia + np.eye(3) * (MIN_INERTIA - min(0.0, eig.min()))
            self.result.approximations.append(Approximation(
                "Body", b.name, f"inertia raised by {MIN_INERTIA:g} kg m² (MuJoCo needs positive inertia)",
                MIN_INERTIA, "kg m^2"))
        inertia = self._physical_inertia(b.name, inertia)
        body.explicitinertial = True
        body.mass = mass
        body.ipos = b.com
        body.fullinertia = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
        self.exact[("inertial", b.name)] = {"pos": b.com, "mass": mass, "fullinertia": np.array(body.fullinertia)}

    def _physical_inertia(self, name: str, inertia: np.ndarray) -> np.ndarray:
        """``inertia`` (3, 3), with its largest principal moment lowered to the sum of the other two
        when it breaks the triangle inequality A + B >= C, which MuJoCo enforces."""
        eig, vec = np.linalg.eigh(inertia)
        if eig[0] + eig[1] >= eig[2] * (1 - 1e-12):
            return inertia
        fixed = eig.copy()
        fixed[2] = (eig[0] + eig[1]) * (1 - 1e-5)  # inside by more than the MJCF's printed precision
        self.result.approximations.append(Approximation(
            "Body", name, "largest principal inertia lowered to the sum of the other two (A + B >= C)",
            float(eig[2] - fixed[2]), "kg m^2", f"from {eig[2]:.4g} to {fixed[2]:.4g}"))
        return vec @ np.diag(fixed) @ vec.T

    def _add_mj_joint(self, body: mujoco.MjsBody, joint: Joint, ax: TransformAxis, kind: str,
                      axis: np.ndarray, pos: np.ndarray, ref: float) -> None:
        coord = self.skel.coordinates[ax.coordinate]
        name, is_coord = self._mj_joint_name(joint, ax)
        if name in self._joint_frames or any(r.name == name for r in self.result.joints):
            raise self.doc.error(ax.element, f"would make a second MuJoCo joint named '{name}'")
        jtype = mujoco.mjtJoint.mjJNT_SLIDE if kind == "slide" else mujoco.mjtJoint.mjJNT_HINGE
        mj = body.add_joint(name=name, type=jtype,
                            axis=axis / np.linalg.norm(axis), pos=pos, ref=ref)
        rec = JointRecord(name, kind, joint.name, ax.name, coord.name if is_coord else None, None, "coordinate")
        self.exact[("joint", name)] = {"axis": axis / np.linalg.norm(axis), "pos": pos, "ref": ref}
        self._joint_frames[name] = (body, jtype, axis / np.linalg.norm(axis), pos)
        if is_coord:
            self.exact[("joint", name)]["range"] = np.array(coord.range)
        if is_coord:
            mj.range = list(coord.range)
            clamped = coord.clamped and coord.range[1] - coord.range[0] < 1e3
            mj.limited = mujoco.mjtLimited.mjLIMITED_TRUE if clamped else mujoco.mjtLimited.mjLIMITED_FALSE
            if self.drivers[coord.name].base != coord.name:
                self.couple(rec, self.drivers[coord.name], ref, coord.element, high_order=True)
        else:
            self.couple(rec, self._axis_driver(ax), ref, ax.element, high_order=True)
        self.result.joints.append(rec)
        self.result.joints.extend(self._extra_records.pop(name, []))

    def couple(self, rec: JointRecord, driver: _Driver, ref: float, source: etree._Element, *,
               high_order: bool = False) -> None:
        """Drive MuJoCo joint ``rec`` (value = driver.fn(base)) from the base coordinate's joint.

        ``ref`` is the joint's reference value; ``source`` is the OpenSim element the coupling
        comes from (named in errors and in the approximation it records). A non-linear coupling
        is a minimax quartic; with ``high_order`` (skeleton axes and couplers, which this builder
        adds itself and has planned in :meth:`_plan_couplings`), it is the planned main quartic,
        and the joint's extra joints follow it on the same body and axis
        (:meth:`_add_extra_joints`). Callers outside this class (path-point carriers) get the
        plain quartic unless they planned the joint (:meth:`plan_extra_couplings`,
        :meth:`register_joint`) and pass ``high_order``. The approximation recorded gives the
        value's and the derivative's (d joint / d coordinate) errors."""
        base = driver.base
        if base not in self.coord_joint:
            raise self.doc.error(source, f"depends on coordinate '{base}', which has no MuJoCo joint")
        base_ref = self.ref[base]
        base_kind = self.coord_joint[base][1].kind
        lo, hi = self.fit_range(base, base_kind)
        lo, hi = min(lo, base_ref), max(hi, base_ref)
        rel = _relative(driver, ref)
        lin = _linear(rel, lo, hi)
        units = "rad" if rec.kind == "hinge" else "m"
        base_units = "rad" if base_kind == "rotation" else "m"
        slope_units = f"{units}/{base_units}"
        extra: list[tuple[str, str, np.ndarray, str]] = []
        planned = self._planned.get(rec.name) if high_order else None
        if lin is not None:
            slope, icpt = lin
            coef = np.array([icpt + slope * base_ref, slope, 0.0, 0.0, 0.0])
            rec.relation = "linear"
        elif planned is None:
            fit = fit_polynomial(rel, lo, hi, base_ref, degree=4, exact_at_x0=True)
            coef = np.asarray(fit.coef, dtype=float)
            rec.relation = "quartic fit"
            s_max, s_rms = polynomial_slope_errors(rel, coef, lo, hi, base_ref)
            self.result.approximations.append(Approximation(
                source.tag, source.get("name", rec.name),
                f"MuJoCo joint '{rec.name}' follows '{base}' by a quartic fitted over [{lo:.4g}, {hi:.4g}]",
                float(fit.max_error), units, f"rms {fit.rms_error:.3g} {units}; slope error {s_max:.3g} "
                f"(rms {s_rms:.3g}) {slope_units}", joint=rec.name, slope_error=s_max, slope_rms=s_rms,
                slope_units=slope_units))
        else:
            cfit, ax = planned.fit, planned.fit.axes[planned.index]
            coef = np.asarray(ax.main, dtype=float)
            rec.relation = "quartic fit"
            what = f"MuJoCo joint '{rec.name}' follows '{base}' by a quartic fitted over [{lo:.4g}, {hi:.4g}]"
            detail = f"rms {ax.rms_error:.3g} {units}; slope error {ax.slope_error:.3g} (rms {ax.slope_rms:.3g}) " \
                     f"{slope_units}"
            extra = self._extra_joints(rec, planned)
            if extra:
                rec.relation = f"quartic fit + {len(extra)} extra joints"
                what = (f"MuJoCo joint '{rec.name}' and its extra joints {', '.join(e[0] for e in extra)} follow "
                        f"'{base}' by a {cfit.structure(planned.index)}, fitted over [{lo:.4g}, {hi:.4g}]"
                        + (f" to {ax.target:.3g} {units} and a slope error of {ax.slope_target:.3g} {slope_units}"
                           if np.isfinite(ax.slope_target) else ""))
                margin = planned.fit.margin
                detail += (f"; a plain quartic: {ax.quartic_error:.3g} {units}, slope error "
                           f"{ax.quartic_slope_error:.3g} (rms {ax.quartic_slope_rms:.3g}) {slope_units}; up to "
                           f"{margin:.3g} {base_units} beyond the range: {ax.margin_error:.3g} {units}; the extra "
                           f"joints move through at most {ax.amplitude:.3g} {units}")
            self.result.approximations.append(Approximation(
                source.tag, source.get("name", rec.name), what, float(ax.max_error), units, detail, joint=rec.name,
                slope_error=float(ax.slope_error), slope_rms=float(ax.slope_rms), slope_units=slope_units))
        rec.driven_by = base
        self._equality(rec.name, base, coef, f"{rec.name}_from_{base}")
        if extra:
            self._add_extra_joints(rec, extra, source, planned.armature)
            if planned.armature is not None:  # planned with its armature: what it adds to the coordinate, now
                x = np.linspace(planned.lo, planned.hi, 2001)
                slopes = _extra_slopes(planned, x)[0]
                added = float(np.max(sum(planned.armature * slopes[e[0]] ** 2 for e in extra)))
                coord_unit = "kg m^2" if base_kind == "rotation" else "kg"
                unit = "kg" if rec.kind == "slide" else "kg m^2"
                self.result.approximations[-1].detail += (
                    f"; armature {planned.armature:.3g} {unit} each, adding at most {added:.3g} {coord_unit} to "
                    f"'{base}'")

    def _extra_joints(self, rec: JointRecord, planned: _PlannedAxis) -> list[tuple[str, str, np.ndarray, str]]:
        """The extra joints of coupled joint ``rec``: (name, driving joint, equality
        coefficients, role) for each inner joint it carries (``<joint>_inner<k>``, driven by the
        coordinate) and each outer joint (``<joint>_outer<k>``, driven by an inner joint)."""
        fit, i = planned.fit, planned.index
        base = planned.axes[i].base
        out = [(planned.inner_names[k], base, fit.inners[k], "inner") for k in range(fit.n_inner) if fit.hosts[k] == i]
        out += [(f"{rec.name}_outer{n + 1}", planned.inner_names[k], c, "outer")
                for n, (k, c) in enumerate(fit.axes[i].outers)]
        return out

    def _add_extra_joints(self, rec: JointRecord, extra: list[tuple[str, str, np.ndarray, str]],
                          source: etree._Element, armature: float | None = None) -> None:
        """Add ``extra`` right after joint ``rec`` on its body, with its type, axis and anchor (so
        that their values add to its value), and their equalities. Each extra joint is 0 at the
        reference pose and is a real degree of freedom of the body; its armature is ``armature``,
        or when None set by :meth:`_set_extra_armature` once the skeleton is built."""
        body, jtype, axis, pos = self._joint_frames[rec.name]
        for name, driver, coef, role in extra:
            if name in self._joint_frames or any(r.name == name for r in self.result.joints):
                raise self.doc.error(source, f"would make a second MuJoCo joint named '{name}'")
            body.add_joint(name=name, type=jtype, axis=axis, pos=pos, ref=0.0,
                           armature=1.0 if armature is None else armature)  # None: see _set_extra_armature
            self.exact[("joint", name)] = {"axis": axis, "pos": pos, "ref": 0.0}
            self._joint_frames[name] = (body, jtype, axis, pos)
            self._extras_of.setdefault(rec.name, []).append(name)
            self._extra_records.setdefault(rec.name, []).append(JointRecord(
                name, rec.kind, rec.opensim_joint, f"{rec.axis}/{role}", None, driver, f"{role} quartic"))
            self._equality(name, driver, np.asarray(coef, dtype=float), f"{name}_from_{driver}")

    def _equality(self, joint1: str, joint2: str | None, coef: np.ndarray, name: str) -> None:
        eq = self.spec.add_equality(name=name, type=mujoco.mjtEq.mjEQ_JOINT, objtype=mujoco.mjtObj.mjOBJ_JOINT,
                                    name1=joint1, name2=joint2 or "")
        data = np.zeros(eq.data.shape)
        data[:5] = coef
        eq.data = data
        eq.solref = list(EQUALITY_SOLREF)
        eq.solimp = list(EQUALITY_SOLIMP)
        self.exact[("equality", name)] = {"polycoef": np.asarray(coef, dtype=float)}

    def restore_precision(self, xml: str) -> str:
        """MJCF text with every number o2m computed written in full (17 significant digits).

        MuJoCo's writer prints about 6 digits, which alone would put 1e-6 m errors into the
        skeleton and can break the inertia triangle inequality of a borderline body.
        """
        root = etree.fromstring(xml.encode())
        for el in root.iter("body", "joint", "site"):
            name = el.get("name")
            tag = "equality" if el.getparent().tag == "equality" else el.tag
            vals = self.exact.get((tag, name))
            if vals is None:
                continue
            for attr, v in vals.items():
                el.set(attr, _num(v))
            if el.tag == "body" and ("inertial", name) in self.exact:
                inertial = el.find("inertial")
                if inertial is None:  # MuJoCo's writer leaves out tiny inertials
                    inertial = etree.Element("inertial")
                    el.insert(0, inertial)
                for attr in ("quat", "diaginertia", "fullinertia"):
                    inertial.attrib.pop(attr, None)
                for attr, v in self.exact[("inertial", name)].items():
                    inertial.set(attr, _num(v))
        return etree.tostring(root, encoding="unicode", pretty_print=True)


def _num(v) -> str:
    return " ".join(f"{float(x):.17g}" for x in np.atleast_1d(np.asarray(v, dtype=float)))


def add_geometry(result: BuildResult, skel: Skeleton, bodies: dict[str, mujoco.MjsBody], mesh_dir: Path,
                 search_dirs: list[Path]) -> list[Skipped]:
    """Add the skeleton's attached geometry as visual geoms; meshes are written to ``mesh_dir`` as STL.

    Returns what was left out (missing mesh files, decorations without a MuJoCo twin).
    """
    spec = result.spec
    skipped: list[Skipped] = []
    meshes: dict[tuple[str, tuple[float, ...]], str] = {}
    used_names: set[str] = set()
    mesh_dir.mkdir(parents=True, exist_ok=True)

    def unique(name: str) -> str:
        out, k = name, 1
        while out in used_names:
            out, k = f"{name}_{k}", k + 1
        used_names.add(out)
        return out

    for g in skel.geometry:
        el = g.element
        body = bodies[g.body]
        to_world = Transform(OSIM_TO_MJ) if g.body == "ground" else Transform()
        if el.tag == "Mesh":
            fname = (el.findtext("mesh_file") or "").strip()
            scale = tuple(float(v) for v in (el.findtext("scale_factors") or "1 1 1").split())
            src = geometry.find_geometry_file(fname, search_dirs) if fname else None
            if src is None:
                skipped.append(Skipped("Mesh", el.get("name", fname), f"mesh file '{fname}' not found in "
                                       f"{', '.join(str(d) for d in search_dirs)}"))
                continue
            key = (str(src), scale)
            if key not in meshes:
                asset = unique(Path(fname).stem)
                stl = mesh_dir / f"{asset}.stl"
                try:
                    geometry.write_stl(stl, geometry.read_mesh(src), scale=scale)
                except ValueError as exc:  # a mesh with no surface (lines only)
                    used_names.discard(asset)
                    skipped.append(Skipped("Mesh", el.get("name", fname), f"mesh file '{fname}' has no surface: {exc}"))
                    continue
                spec.add_mesh(name=asset, file=f"{mesh_dir.name}/{stl.name}",
                              inertia=mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL)
                meshes[key] = asset
            x = to_world @ g.frame
            body.add_geom(name=unique(el.get("name") or meshes[key]), type=mujoco.mjtGeom.mjGEOM_MESH,
                          meshname=meshes[key], pos=x.pos, quat=matrix_to_quat(x.rot),
                          contype=0, conaffinity=0, group=1, density=0,
                          rgba=_rgba(el))
            continue
        why: list[str] = []
        prim = geometry.analytic_geom(el, why)
        if prim is None:
            skipped.append(Skipped(el.tag, el.get("name", ""), "; ".join(why) or "no MuJoCo twin"))
            continue
        x = to_world @ g.frame @ Transform(quat_to_matrix(prim.quat), prim.pos)
        gtype = getattr(mujoco.mjtGeom, f"mjGEOM_{prim.type.upper()}")
        body.add_geom(name=unique(el.get("name") or el.tag.lower()), type=gtype,
                      size=prim.size, pos=x.pos, quat=matrix_to_quat(x.rot), contype=0, conaffinity=0, group=1,
                      density=0, rgba=prim.rgba if prim.rgba is not None else [0.8, 0.8, 0.8, 1])
    return skipped


def _rgba(el) -> list[float]:
    app = el.find("Appearance")
    rgba = [0.89, 0.85, 0.79, 1.0]  # bone
    if app is not None:
        col = app.findtext("color")
        if col:
            rgba[:3] = [float(v) for v in col.split()[:3]]
        op = app.findtext("opacity")
        if op:
            rgba[3] = float(op)
        vis = app.findtext("visible")
        if vis is not None and vis.strip().lower() == "false":
            rgba[3] = 0.0
    return rgba
