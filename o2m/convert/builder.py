"""Building the MuJoCo model (an ``mujoco.MjSpec``) from a :class:`~o2m.osim.skeleton.Skeleton`: bodies and joints.

How an OpenSim joint becomes MuJoCo joints (see :mod:`o2m.osim.skeleton` for the canonical form):

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
  the same axis, planned by :mod:`o2m.convert.coupling_plan`. Where a body would need more than
  MuJoCo's 6 degrees of freedom, its joint's slides (main and extra joints) go on an
  intermediate body ``<body>_couplings`` (1e-12 kg, no geometry) between the parent and the
  body, at the body's reference frame, and the hinges stay on the body: translations along the
  parent frame's axes come first in a CustomJoint, so the two compose as one joint. The report's
  notes name each such body.
* CoordinateCouplerConstraints become joint equalities the same way.
* EllipsoidJoint and ScapulothoracicJoint become exact chains of hinges driven by linear joint
  equalities (:mod:`o2m.convert.ellipsoid_joints`).
* A body that only translates relative to an ancestor as one coordinate moves (its chain's
  rotations cancel) hangs from that ancestor by slides of the coordinate
  (:mod:`o2m.convert.shortcuts`); the bodies in between keep their joints.
* Joints added by other builders (path-point carriers, :mod:`o2m.convert.carriers`) can be
  planned the same way (:meth:`MjcfBuilder.plan_extra_couplings`); every coupling's approximation
  records the errors of its value and of its derivative (d joint / d coordinate).
* A locked coordinate, and every axis or coupled coordinate that depends only on locked
  coordinates, is folded into the fixed body transforms at its default value: exact, and
  stiffer in simulation than a soft MuJoCo equality would be. It then has no MuJoCo joint.
* OpenSim ground (Y-up) maps to MuJoCo's world (Z-up) by :data:`o2m.transforms.OSIM_TO_MJ`;
  angles are radians, lengths metres.
"""

from __future__ import annotations

import mujoco
import numpy as np
from lxml import etree

from o2m.convert.coordinates import (
    Driver,
    as_linear,
    choose_coordinate_axes,
    coordinate_drivers,
    fit_range,
    is_fixed,
    joint_limited,
    relative,
)
from o2m.convert.coupling_plan import (
    COUPLING_SLOPE_TARGET,
    COUPLING_TARGET,
    MAX_BODY_DOFS,
    CoupledAxis,
    ExtraJoint,
    PlannedAxis,
    added_inertia,
    chunks_by_key,
    plan_group,
    plan_skeleton,
    planned_axes,
    planned_coupling,
    quartic_coupling,
)
from o2m.convert.couplings import AxisFit, CouplingFit
from o2m.convert.ellipsoid_joints import add_surface_joint
from o2m.convert.inertials import (
    COMPLEMENT_ARMATURE,
    COUPLINGS_BODY_INERTIA,
    COUPLINGS_BODY_MASS,
    main_inertias,
    set_complement_armature,
    set_extra_armature,
    set_inertial,
)
from o2m.convert.polyfit import FitError
from o2m.convert.records import Approximation, BuildResult, JointRecord
from o2m.convert.shortcuts import shorten_chains
from o2m.mj import mjcf_text
from o2m.osim.skeleton import Joint, Skeleton, TransformAxis
from o2m.transforms import OSIM_TO_MJ, Transform, axis_angle_matrix, matrix_to_quat

#: Softness of every joint equality o2m writes (couplers, coupled axes, path-point carriers): the
#: shortest time constant MuJoCo allows at the default 2 ms step, critically damped, and MuJoCo's
#: largest impedance, 0.9999, whose regularisation (proportional to (1 - d) / d) is a tenth of
#: 0.999's. OpenSim's constraints are exact, and a soft one is not only an error in the pose: a
#: path carrier that lags its equality lengthens and shortens the muscles over it, which their
#: force-velocity curves answer (docs/paper.md, the biceps over pro_sup).
EQUALITY_SOLREF = (0.004, 1.0)
EQUALITY_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)


def _rest(fn, q: np.ndarray) -> np.ndarray:
    """f(q) - q: what a complement joint adds to its coordinate's joint on the same axis."""
    q = np.asarray(q, dtype=float)
    return np.asarray(fn(q), dtype=float) - q


class MjcfBuilder:
    """Builds an ``MjSpec`` from a skeleton; :func:`o2m.convert.visuals.add_geometry` adds its geometry after."""

    def __init__(self, skel: Skeleton, *, plan_couplings: bool = True, shortcuts: bool = True,
                 clamped_limits: bool = False):
        #: Notes for the report on chains shortened (:func:`o2m.convert.shortcuts.shorten_chains`).
        self.shortcut_notes: list[str] = []
        if shortcuts:
            skel, self.shortcut_notes = shorten_chains(skel, coordinate_drivers(skel))
        #: The skeleton as built: ``skel`` with its chain shortcuts, if any.
        self.skel = skel
        #: Whether skeleton couplings get extra joints (:meth:`_plan_couplings`); else plain quartics.
        self.plan_couplings = plan_couplings
        #: Whether clamped coordinates get MuJoCo hard limits (:func:`~o2m.convert.coordinates.joint_limited`).
        self.clamped_limits = clamped_limits
        #: Coordinate -> (its complement joint, the axis), for coordinates that reach their axes
        #: only through functions (:meth:`_add_complement`).
        self._complements: dict[str, tuple[str, TransformAxis]] = {}
        #: Coupling fits of this conversion by their inputs' digest: the same spline on two
        #: sides (left and right knee) is fitted once.
        self.fit_cache: dict = {}
        self.doc = skel.document
        self.spec = mujoco.MjSpec()
        self.result = BuildResult(self.spec)
        self.result.notes.extend(self.shortcut_notes)
        self.drivers = coordinate_drivers(skel)
        self.ref = {name: float(np.asarray(d.fn(np.array([skel.coordinates[d.base].default])))[0])
                    for name, d in self.drivers.items()}
        self.coord_joint: dict[str, tuple[Joint, TransformAxis]] = choose_coordinate_axes(skel, self.drivers)
        self.bodies: dict[str, mujoco.MjsBody] = {"ground": self.spec.worldbody}
        self._order: list[Joint] | None = None
        self._chain_cache: dict[tuple[str, ...], list[Joint]] = {}
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
        self._planned: dict[str, PlannedAxis] = {}
        #: Bodies whose joint's translations go on an intermediate body: (slides, hinges) they get.
        self._split: dict[str, tuple[int, int]] = {}
        #: Each intermediate body made for couplings, by its OpenSim body.
        self.couplings_bodies: dict[str, str] = {}

    # -- coordinates -------------------------------------------------------------------
    def coordinate_values(self, changes: dict[str, float] | None = None) -> dict[str, float]:
        """Every coordinate's value with independent coordinates at the reference pose except
        ``changes``; dependent coordinates follow their couplers."""
        base = {name: self.ref[name] for name, d in self.drivers.items() if d.base == name}
        base.update(changes or {})
        return {name: float(np.asarray(d.fn(np.array([base[d.base]])))[0]) for name, d in self.drivers.items()}

    def ground_frames_at(self, values: dict[str, float], bodies: tuple[str, ...] | None = None
                         ) -> dict[str, Transform]:
        """Each body's frame in OpenSim ground when the coordinates have ``values`` (all of them);
        with ``bodies``, only theirs and their ancestors' (a large tree's two ends cost a chain each)."""
        frames = {"ground": Transform()}
        if self._order is None:
            self._order = self._ordered_joints()
        for joint in self._order if bodies is None else self._chains(bodies):
            frames[joint.child] = frames[joint.parent] @ joint.transform(values)
        return frames

    def _chains(self, bodies: tuple[str, ...]) -> list[Joint]:
        """The joints from ground to each of ``bodies``, parents first (cached)."""
        key = tuple(sorted(set(bodies)))
        if key not in self._chain_cache:
            parent = {j.child: j.parent for j in self._order}
            needed: set[str] = set()
            for b in key:
                while b != "ground" and b not in needed:
                    needed.add(b)
                    b = parent[b]
            self._chain_cache[key] = [j for j in self._order if j.child in needed]
        return self._chain_cache[key]

    def is_fixed(self, ax: TransformAxis) -> bool:
        """True when the axis does not move: no coordinate, or it depends on a locked coordinate only."""
        return is_fixed(self.skel, self.drivers, ax)

    def fit_range(self, name: str, kind: str) -> tuple[float, float]:
        """The range coordinate ``name``'s couplings are fitted over (:func:`o2m.convert.coordinates.fit_range`)."""
        return fit_range(self.skel, name, kind)

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
            note = f"joint '{j.name}' reversed as OpenSim reverses it: '{j.child}' hangs from '{j.parent}'"
            if j.reversed and note not in self.result.notes:
                self.result.notes.append(note)
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
                why = "prescribed constant" if c.prescribed else "locked"
                self.result.notes.append(f"{why} coordinate '{c.name}' folded into fixed transforms at {c.default:g}")
            elif c.prescribed:
                self.result.notes.append(
                    f"prescribed coordinate '{c.name}': OpenSim moves it as a function of time "
                    f"({type(c.prescribed_function).__name__}), MuJoCo's joint is free, starting at the "
                    f"function's value at time 0, {c.default:g}: drive it yourself (e.g. a position actuator)")
        set_extra_armature(self)
        set_complement_armature(self)
        for marker in self.skel.markers:
            body = self.bodies[marker.body]
            pos = marker.position if marker.body != "ground" else OSIM_TO_MJ @ marker.position
            body.add_site(name=marker.name, pos=pos, size=[0.005, 0, 0], rgba=[0.9, 0.2, 0.9, 1], group=4)
            self.exact[("site", marker.name)] = {"pos": pos}
        return self.result

    def _axis_driver(self, ax: TransformAxis) -> Driver:
        return self.drivers[ax.coordinate].then(ax.function)

    def _add_joint(self, joint: Joint) -> None:
        if joint.surface is not None:
            add_surface_joint(self, joint)
            return
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
        set_inertial(self, body, joint)
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

    def coupled_axes(self) -> tuple[list[CoupledAxis], dict[tuple[str, str], int]]:
        """Every moving skeleton axis that a non-linear function of an independent coordinate
        drives (transform axes and coupled coordinates), in build order; and each body's number
        of moving axes of each kind, by (body, "slide" or "hinge")."""
        q0 = {name: self.ref[name] for name in self.skel.coordinates}
        out, dofs = [], {}
        for joint in self._ordered_joints():
            if joint.surface is not None:
                continue  # its hinges' couplings are quartics (o2m.convert.ellipsoid_joints)
            moving = [(ax, "slide") for ax in joint.translations] + [(ax, "hinge") for ax in joint.rotations]
            moving = [(ax, kind) for ax, kind in moving if not self.is_fixed(ax)]
            complements = [(ax, k) for ax, k in moving if self._mj_joint_name(joint, ax)[1]
                           and self.coord_joint[ax.coordinate].form == "complement"]  # a second joint each
            for kind in ("slide", "hinge"):
                dofs[joint.child, kind] = sum(k == kind for _, k in moving + complements)
            for ax, kind in moving:
                name, is_coord = self._mj_joint_name(joint, ax)
                axes = [] if is_coord and self.drivers[ax.coordinate].base == ax.coordinate else \
                    [(name, self.drivers[ax.coordinate] if is_coord else self._axis_driver(ax), ax.value(q0))]
                if any(c is ax for c, _ in complements):  # its second joint adds f(q) - q (_add_complement)
                    axes.append((f"{joint.name}_{ax.name}", self._complement_driver(ax),
                                 ax.value(q0) - self.ref[ax.coordinate]))
                for joint_name, driver, ref in axes:
                    if driver.base not in self.coord_joint:
                        continue  # couple() reports it
                    lo, hi = self.coupling_range(driver.base)
                    rel = relative(driver, ref)
                    if as_linear(rel, lo, hi) is None:
                        out.append(CoupledAxis(joint_name, joint.child, kind, driver.base, rel))
        return out, dofs

    def _complement_driver(self, ax: TransformAxis) -> Driver:
        """What the complement joint of coordinate axis ``ax`` carries, f(q) - q, from the base coordinate."""
        return self.drivers[ax.coordinate].then(lambda q, fn=ax.function: _rest(fn, q))

    def coupling_fit(self, joint: str) -> AxisFit | None:
        """The fit of skeleton coupled joint ``joint`` (after :meth:`build`): its main joint, outer
        joints and errors; None for a joint that is not a non-linear skeleton coupling."""
        planned = self._planned.get(joint)
        return None if planned is None else planned.fit.axes[planned.index]

    def coupling_range(self, base: str) -> tuple[float, float]:
        """Where a coupling driven by coordinate ``base`` is fitted: its range, with its reference."""
        lo, hi = self.fit_range(base, self.coord_joint[base][1].kind)
        return min(lo, self.ref[base]), max(hi, self.ref[base])

    def _plan_couplings(self) -> None:
        """Plan every coordinate's non-linear skeleton couplings (:func:`o2m.convert.coupling_plan.plan_skeleton`,
        each axis weighed by its main joint's own inertia) and the joints whose translations get a
        body of their own (:meth:`_couplings_body`)."""
        axes, dofs = self.coupled_axes()
        weights = main_inertias(self, [a.name for a in axes]) if axes else {}
        ranges = {a.base: self.coupling_range(a.base) for a in axes}
        try:
            planned, split = plan_skeleton(axes, dofs, weights, ranges, self.ref, targets=COUPLING_TARGET,
                                           slope_targets=COUPLING_SLOPE_TARGET, cache=self.fit_cache)
        except FitError as exc:
            raise self.doc.error(self.skel.coordinates[exc.coordinate].element,
                                 f"drives couplings MuJoCo's joint equalities cannot follow: {exc}") from None
        self._planned.update(planned)
        self._split.update(split)

    def plan_extra_couplings(self, group: list[CoupledAxis], keys: list[object], room: dict[object, int], *,
                             targets: list[float], slope_targets: list[float] | None,
                             armature: float) -> list[CouplingFit]:
        """Plan couplings beyond a quartic for axes that callers outside this class add (path-point
        carriers): the axes ``group`` of one coordinate, all equally heavy, axis i's extra joints
        counted against ``room[keys[i]]``, fitted to ``targets`` and ``slope_targets`` as
        :func:`~o2m.convert.coupling_plan.plan_group` does: a group of up to
        :data:`~o2m.convert.coupling_plan.CARRIER_CHUNK` axes together, a larger one in chunks of at
        most :data:`~o2m.convert.coupling_plan.CARRIER_SPLIT_CHUNK`
        (:func:`~o2m.convert.coupling_plan.chunks_by_key`; one plan's cost grows with the square of
        its axes). Each joint then follows its plan when
        :meth:`couple` is called with ``high_order=True`` after :meth:`register_joint`; every extra
        joint gets ``armature``. Returns each chunk's fit."""
        base = group[0].base
        lo, hi = self.coupling_range(base)
        fits = []
        for chunk in chunks_by_key(keys):
            axes = [group[i] for i in chunk]
            try:
                best = plan_group(axes, [keys[i] for i in chunk], room, lo, hi, self.ref[base], [1.0] * len(chunk),
                                  [targets[i] for i in chunk],
                                  None if slope_targets is None else [slope_targets[i] for i in chunk],
                                  cheaper_too=True, cache=self.fit_cache)
            except FitError as exc:
                raise self.doc.error(self.skel.coordinates[base].element,
                                     f"moves path points MuJoCo's joint equalities cannot follow: {exc}") from None
            self._planned.update(planned_axes(best, axes, lo, hi, armature))
            fits.append(best)
        return fits

    def register_joint(self, name: str, body: mujoco.MjsBody, jtype: mujoco.mjtJoint, axis: np.ndarray,
                       pos: np.ndarray) -> None:
        """Record a joint added outside this class (body, type, axis, anchor), so that the extra
        joints of its planned coupling can be added beside it."""
        self._joint_frames[name] = (body, jtype, np.asarray(axis, dtype=float), np.asarray(pos, dtype=float))

    def pop_extra_records(self, joint: str) -> list[JointRecord]:
        """The records of the extra joints :meth:`couple` made for ``joint`` (a caller outside
        this class lists them after the joint's own), once."""
        return self._extra_records.pop(joint, [])

    def _add_mj_joint(self, body: mujoco.MjsBody, joint: Joint, ax: TransformAxis, kind: str,
                      axis: np.ndarray, pos: np.ndarray, ref: float) -> None:
        """Add the MuJoCo joint of a moving axis (value ``ref`` at the reference pose): its
        coordinate's joint, or a joint driven by an equality. A coordinate's joint on a mirrored
        axis turns about the reversed axis; on an axis with any other function it is complemented
        by a second joint on the same axis (:class:`~o2m.convert.coordinates.CoordinateAxis`)."""
        coord = self.skel.coordinates[ax.coordinate]
        name, is_coord = self._mj_joint_name(joint, ax)
        unit = axis / np.linalg.norm(axis)
        if not is_coord:
            rec = self._new_mj_joint(body, name, kind, unit, pos, ref, joint, ax, None)
            self.couple(rec, self._axis_driver(ax), ref, ax.element, high_order=True)
            self._close_joint(rec)
            return
        form = self.coord_joint[coord.name]
        joint_ref = ref if form.form == "identity" else self.ref[coord.name]  # the joint carries q itself
        if form.form == "mirrored":
            unit = -unit
        rec = self._new_mj_joint(body, name, kind, unit, pos, joint_ref, joint, ax, coord.name)
        if form.form != "identity":
            rec.relation = f"coordinate ({form.form})"
        self.exact[("joint", name)]["range"] = np.array(coord.range)
        mj = self.spec.joint(name)
        mj.range = list(coord.range)
        clamped, note = joint_limited(coord, self.clamped_limits)
        self.result.notes.extend([note] if note else [])
        mj.limited = mujoco.mjtLimited.mjLIMITED_TRUE if clamped else mujoco.mjtLimited.mjLIMITED_FALSE
        if self.drivers[coord.name].base != coord.name:
            self.couple(rec, self.drivers[coord.name], joint_ref, coord.element, high_order=True)
        self._close_joint(rec)
        if form.form == "complement":
            self._add_complement(body, joint, ax, kind, unit, pos, ref - joint_ref)

    def _new_mj_joint(self, body: mujoco.MjsBody, name: str, kind: str, unit: np.ndarray, pos: np.ndarray,
                      ref: float, joint: Joint, ax: TransformAxis, coordinate: str | None) -> JointRecord:
        if name in self._joint_frames or any(r.name == name for r in self.result.joints):
            raise self.doc.error(ax.element, f"would make a second MuJoCo joint named '{name}'")
        jtype = mujoco.mjtJoint.mjJNT_SLIDE if kind == "slide" else mujoco.mjtJoint.mjJNT_HINGE
        body.add_joint(name=name, type=jtype, axis=unit, pos=pos, ref=ref)
        self.exact[("joint", name)] = {"axis": unit, "pos": pos, "ref": ref}
        self._joint_frames[name] = (body, jtype, unit, pos)
        return JointRecord(name, kind, joint.name, ax.name, coordinate, None, "coordinate")

    def _close_joint(self, rec: JointRecord) -> None:
        self.result.joints.append(rec)
        self.result.joints.extend(self._extra_records.pop(rec.name, []))

    def _add_complement(self, body: mujoco.MjsBody, joint: Joint, ax: TransformAxis, kind: str, unit: np.ndarray,
                        pos: np.ndarray, ref: float) -> None:
        """The joint that turns (slides) axis ``ax`` by f(q) - q after its coordinate's joint turned
        it by q: right after it, on the same axis and anchor, so the two add to f(q)."""
        coord = ax.coordinate
        name = f"{joint.name}_{ax.name}"
        rec = self._new_mj_joint(body, name, kind, unit, pos, ref, joint, ax, None)
        self.spec.joint(name).armature = COMPLEMENT_ARMATURE  # until set_complement_armature scales it
        self.couple(rec, self._complement_driver(ax), ref, ax.element, high_order=True)
        self._close_joint(rec)
        self._complements[coord] = (name, ax)
        self.result.notes.append(
            f"coordinate '{coord}' reaches axis {joint.name}/{ax.name} only through a function f: joint '{coord}' "
            f"moves that axis by q and joint '{name}' by f(q) - q, so '{coord}' still carries the coordinate's value")


    def couple(self, rec: JointRecord, driver: Driver, ref: float, source: etree._Element, *,
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
        rel = relative(driver, ref)
        lin = as_linear(rel, lo, hi)
        units = "rad" if rec.kind == "hinge" else "m"
        base_units = "rad" if base_kind == "rotation" else "m"
        extra: list[ExtraJoint] = []
        planned = self._planned.get(rec.name) if high_order else None
        if lin is not None:
            slope, icpt = lin
            coef = np.array([icpt + slope * base_ref, slope, 0.0, 0.0, 0.0])
            rec.relation = "linear"
        elif planned is None:
            try:
                coef, fields = quartic_coupling(rel, lo, hi, base_ref, rec.name, base, units, base_units)
            except FitError as exc:
                raise self.doc.error(source, f"cannot be followed by a MuJoCo joint equality: {exc}") from None
            rec.relation = "quartic fit"
            self.result.approximations.append(Approximation(source.tag, source.get("name", rec.name), **fields))
        else:
            coef, extra, fields = planned_coupling(planned, rec.name, base, lo, hi, units, base_units)
            rec.relation = f"quartic fit + {len(extra)} extra joints" if extra else "quartic fit"
            self.result.approximations.append(Approximation(source.tag, source.get("name", rec.name), **fields))
        rec.driven_by = base
        self._equality(rec.name, base, coef, f"{rec.name}_from_{base}")
        if extra:
            self._add_extra_joints(rec, extra, source, planned.armature)
            if planned.armature is not None:  # planned with its armature: what it adds to the coordinate, now
                added = added_inertia(planned, [e[0] for e in extra])
                coord_unit = "kg m^2" if base_kind == "rotation" else "kg"
                unit = "kg" if rec.kind == "slide" else "kg m^2"
                self.result.approximations[-1].detail += (
                    f"; armature {planned.armature:.3g} {unit} each, adding at most {added:.3g} {coord_unit} to "
                    f"'{base}'")

    def _add_extra_joints(self, rec: JointRecord, extra: list[ExtraJoint],
                          source: etree._Element, armature: float | None = None) -> None:
        """Add ``extra`` right after joint ``rec`` on its body, with its type, axis and anchor (so
        that their values add to its value), and their equalities. Each extra joint is 0 at the
        reference pose and is a real degree of freedom of the body; its armature is ``armature``,
        or when None set by :func:`~o2m.convert.inertials.set_extra_armature` once the skeleton is built."""
        body, jtype, axis, pos = self._joint_frames[rec.name]
        for name, driver, coef, role in extra:
            if name in self._joint_frames or any(r.name == name for r in self.result.joints):
                raise self.doc.error(source, f"would make a second MuJoCo joint named '{name}'")
            body.add_joint(name=name, type=jtype, axis=axis, pos=pos, ref=0.0,
                           armature=1.0 if armature is None else armature)  # None: see set_extra_armature
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
        """MJCF text with every number o2m computed for the bodies, joints, sites and joint
        equalities written in full (:func:`o2m.mj.mjcf_text.restore_tree_numbers`).

        MuJoCo's writer prints about 6 digits, which alone would put 1e-6 m errors into the
        skeleton and can break the inertia triangle inequality of a borderline body.
        """
        return mjcf_text.restore_tree_numbers(xml, self.exact)
