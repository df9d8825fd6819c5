"""The multibody part of an OpenSim model, read from a 4.x document into plain dataclasses.

Everything a MuJoCo model needs besides muscles: bodies (mass, centre of mass, inertia),
frames, joints reduced to one canonical form, coordinates, coupler constraints, markers and
attached geometry. Units are OpenSim's: metres, kilograms, radians, in OpenSim's Y-up frames.

Joints are in the canonical form of :mod:`o2m.osim.joints`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from lxml import etree

from o2m.errors import UnsupportedElementError
from o2m.osim.document import OsimDocument, _floats
from o2m.osim.function_reader import parse_function
from o2m.osim.functions import Constant, Function
from o2m.osim.joints import EllipsoidSurface, Joint, TransformAxis, loop_welds, orient_joints
from o2m.osim.kinds import BODY_CONSTRAINTS, MODEL_SETS, PATH_TYPES, SKIP_REASONS, refuse_unknown, set_of_type
from o2m.osim.names import CoordinateNames
from o2m.osim.stations import station_defined_frame
from o2m.transforms import Transform, axis_angle_matrix, body_fixed_xyz

#: Joint types o2m converts, with the canonical axes of their coordinates in order:
#: (kind, axis) with kind "rotation" or "translation" and the axis in the joint frames.
_X, _Y, _Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
JOINT_AXES: dict[str, list[tuple[str, tuple[float, float, float]]]] = {
    "WeldJoint": [],
    "PinJoint": [("rotation", _Z)],
    "SliderJoint": [("translation", _X)],
    "UniversalJoint": [("rotation", _X), ("rotation", _Y)],
    "GimbalJoint": [("rotation", _X), ("rotation", _Y), ("rotation", _Z)],
    "BallJoint": [("rotation", _X), ("rotation", _Y), ("rotation", _Z)],
    "FreeJoint": [("rotation", _X), ("rotation", _Y), ("rotation", _Z),
                  ("translation", _X), ("translation", _Y), ("translation", _Z)],
    "PlanarJoint": [("rotation", _Z), ("translation", _X), ("translation", _Y)],
}
#: Joint types built on Simbody's Ellipsoid mobilizer (:class:`EllipsoidSurface`), with their
#: number of coordinates.
SURFACE_JOINTS = {"EllipsoidJoint": 3, "ScapulothoracicJoint": 4}
SUPPORTED_JOINTS = frozenset(JOINT_AXES) | {"CustomJoint"} | frozenset(SURFACE_JOINTS)
#: The frame types a socket, a wrap object or attached geometry may name (:meth:`SkeletonReader.frame`).
FRAME_TYPES = ("Body", "Ground", "PhysicalOffsetFrame", "StationDefinedFrame")
#: The six axes of a CustomJoint's SpatialTransform.
TRANSFORM_AXES = frozenset({"rotation1", "rotation2", "rotation3", "translation1", "translation2", "translation3"})


def _bool(el: etree._Element | None, default: bool = False) -> bool:
    if el is None or el.text is None:
        return default
    return el.text.strip().lower() in ("true", "1")


def _zero_function() -> Function:
    return parse_function(etree.fromstring("<Constant name=\"function\"><value>0</value></Constant>"))


def _identity_function() -> Function:
    el = etree.fromstring("<LinearFunction name=\"function\"><coefficients>1 0</coefficients></LinearFunction>")
    return parse_function(el)


@dataclass
class Geometry:
    """A geometry element attached to a frame; ``frame`` is that frame's transform in ``body``."""

    element: etree._Element
    body: str
    frame: Transform
    frame_name: str


@dataclass
class Body:
    """A rigid body: mass (kg), centre of mass (3,) m and inertia (3, 3) kg m² about it, in the body frame."""

    name: str
    mass: float
    com: np.ndarray
    inertia: np.ndarray
    element: etree._Element


@dataclass
class Coordinate:
    """A generalized coordinate: radians or metres, with OpenSim's range and flags.

    A prescribed coordinate (``prescribed_function``, a function of time in seconds) starts at its
    function's value at time 0 (``default``); a constant one is ``locked`` there, where OpenSim
    holds it."""

    name: str
    joint: str
    default: float
    range: tuple[float, float]
    clamped: bool
    locked: bool
    prescribed: bool
    element: etree._Element
    prescribed_function: Function | None = None
    #: ``default_speed_value`` (rad/s or m/s; for a Ball, Free or Ellipsoid joint's rotation the
    #: angular velocity's component about the parent frame's axis, Simbody's mobility).
    default_speed: float = 0.0


@dataclass
class Coupler:
    """CoordinateCouplerConstraint: ``dependent = function(independent)``."""

    name: str
    dependent: str
    independent: str
    function: Function
    element: etree._Element


@dataclass
class PointOnLine:
    """PointOnLineConstraint: a point of the follower body stays on a line of the line body.

    Points (m) and the unit direction are in the bodies' own frames (OpenSim's, Y-up for ground).
    """

    name: str
    line_body: str
    line_point: np.ndarray  # (3,)
    direction: np.ndarray  # (3,) unit
    follower_body: str
    follower_point: np.ndarray  # (3,)
    element: etree._Element


@dataclass
class BodyConstraint:
    """WeldConstraint (frame 1 on ``body1`` coincides with frame 2 on ``body2``), PointConstraint
    (their origins coincide) or ConstantDistanceConstraint (their origins stay ``distance`` m apart).

    The frames are in the bodies' own frames (OpenSim's, Y-up for ground); for the two point
    constraints only their positions count.
    """

    name: str
    type: str
    body1: str
    frame1: Transform
    body2: str
    frame2: Transform
    distance: float | None
    element: etree._Element


@dataclass
class Marker:
    name: str
    body: str
    position: np.ndarray  # (3,) metres in the body frame
    element: etree._Element


@dataclass
class Skipped:
    """An element o2m leaves out of the MuJoCo model, and why."""

    element: str
    name: str
    reason: str


@dataclass
class Skeleton:
    """The multibody model read from an .osim document."""

    name: str
    gravity: np.ndarray  # (3,) m/s², OpenSim ground frame
    bodies: dict[str, Body]
    joints: list[Joint]
    coordinates: dict[str, Coordinate]
    couplers: list[Coupler]
    markers: list[Marker]
    geometry: list[Geometry]
    skipped: list[Skipped] = field(default_factory=list)
    document: OsimDocument | None = None
    point_on_lines: list[PointOnLine] = field(default_factory=list)
    body_constraints: list[BodyConstraint] = field(default_factory=list)
    names: CoordinateNames = field(default_factory=lambda: CoordinateNames([]))


class SkeletonReader:
    """Reads an :class:`OsimDocument` into a :class:`Skeleton`; one instance per document."""

    def __init__(self, doc: OsimDocument):
        self.doc = doc
        self.model = doc.model
        self._frames: dict[int, tuple[str, Transform, str]] = {}
        #: Components read as part of a frame (StationDefinedFrames and their Stations, by ``id``):
        #: converted there, so not listed as skipped generic components.
        self.used_components: set[int] = set()
        self.names = CoordinateNames([])

    def coordinate_names(self, joints: list[etree._Element]) -> CoordinateNames:
        """The MuJoCo names of the coordinates of ``joints`` (JointSet order), see :mod:`o2m.osim.names`."""
        owners = [(j.get("name"), c.get("name")) for j in joints for h in j.findall("coordinates")
                  for c in h if c.tag == "Coordinate"]
        try:
            return CoordinateNames(owners)
        except ValueError as exc:
            raise self.doc.error(joints[0], str(exc)) from None

    def coordinate_of(self, el: etree._Element) -> str:
        """The MuJoCo name of the Coordinate element ``el`` (in its joint's <coordinates>)."""
        owner = el.getparent().getparent() if el.getparent() is not None else None
        return self.names(owner.get("name") if owner is not None else "", el.get("name"))

    # -- frames ------------------------------------------------------------------------
    def frame(self, el: etree._Element, _depth: int = 0) -> tuple[str, Transform, str]:
        """(body name, transform of frame ``el`` in that body, frame name)."""
        key = id(el)
        if key in self._frames:
            return self._frames[key]
        if _depth > 64:
            raise self.doc.error(el, "frame chain is circular")
        if el.tag == "Body":
            out = (el.get("name"), Transform(), el.get("name"))
        elif el.tag == "Ground":
            out = ("ground", Transform(), "ground")
        elif el.tag == "PhysicalOffsetFrame":
            sock = el.find("socket_parent")
            if sock is None:
                raise self.doc.error(el, "has no <socket_parent>")
            body, x_parent, _ = self.frame(self.doc.resolve(sock), _depth + 1)
            t = el.find("translation")
            o = el.find("orientation")
            trans = _floats(t, 3, self.doc, "translation", np.zeros(3))
            orient = _floats(o, 3, self.doc, "orientation", np.zeros(3))
            out = (body, x_parent @ Transform(body_fixed_xyz(orient), trans), el.get("name"))
        elif el.tag == "StationDefinedFrame":
            out = station_defined_frame(self, el, _depth)
            self.used_components.add(key)
        else:
            raise self.doc.error(el, "is used as a frame but is not a Body, Ground, PhysicalOffsetFrame or "
                                     "StationDefinedFrame")
        self._frames[key] = out
        return out

    def socket_frame(self, owner: etree._Element, socket: str) -> tuple[str, Transform, str]:
        sock = owner.find(socket)
        if sock is None:
            raise self.doc.error(owner, f"has no <{socket}>")
        return self.frame(self.doc.resolve(sock))

    def point_on_line(self, el: etree._Element) -> PointOnLine:
        """A PointOnLineConstraint, its points and direction moved into its sockets' bodies."""
        line_body, x_line, _ = self.socket_frame(el, "socket_line_body")
        follower, x_follow, _ = self.socket_frame(el, "socket_follower_body")
        direction = _floats(el.find("line_direction_vec"), 3, self.doc, "line_direction_vec")
        norm = float(np.linalg.norm(direction))
        if not np.isfinite(norm) or norm < 1e-12:
            raise self.doc.error(el, "has a line direction of zero length")
        on_line = el.find("point_on_line")
        on_follower = el.find("point_on_follower")
        line_point = _floats(on_line, 3, self.doc, "point_on_line", np.zeros(3))
        follower_point = _floats(on_follower, 3, self.doc, "point_on_follower", np.zeros(3))
        return PointOnLine(el.get("name", ""), line_body, x_line.apply(line_point), x_line.rot @ (direction / norm),
                           follower, x_follow.apply(follower_point), el)

    def body_constraint(self, el: etree._Element) -> BodyConstraint:
        """A :data:`BODY_CONSTRAINTS` element, its frames or points moved into its sockets' bodies."""
        if el.tag == "WeldConstraint":
            (b1, x1, _), (b2, x2, _) = (self.socket_frame(el, f"socket_frame{i}") for i in (1, 2))
            return BodyConstraint(el.get("name", ""), el.tag, b1, x1, b2, x2, None, el)
        ends = []
        for i in (1, 2):
            body, x, _ = self.socket_frame(el, f"socket_body_{i}")
            loc = el.find(f"location_body_{i}")
            point = _floats(loc, 3, self.doc, f"location_body_{i}", np.zeros(3))
            ends.append((body, Transform(pos=x.apply(point))))
        distance = None
        if el.tag == "ConstantDistanceConstraint":
            d = el.find("constant_distance")
            distance = float(_floats(d, 1, self.doc, "constant_distance", (1.0,))[0])
            if distance < 0:
                raise self.doc.error(el, f"has a negative <constant_distance> {distance:g}")
        return BodyConstraint(el.get("name", ""), el.tag, *ends[0], *ends[1], distance, el)

    # -- elements ----------------------------------------------------------------------
    def set_objects(self, set_tag: str) -> list[etree._Element]:
        """The objects of the model's ``set_tag`` sets, then those of its ``<components>`` list that
        belong to that set (:func:`set_of_type`: OpenSim 4.x may keep bodies, joints and forces
        there); one sharing its path with an earlier one (two muscles of one name, say) raises an
        error naming both (:meth:`OsimDocument.check_unique`)."""
        objs: list[etree._Element] = []
        for s in self.model.findall(set_tag):
            holder = s.find("objects")
            if holder is not None:
                objs.extend(c for c in holder if isinstance(c.tag, str))
        for holder in self.model.findall("components"):
            objs.extend(c for c in holder if isinstance(c.tag, str) and set_of_type(c.tag) == set_tag)
        for el in objs:
            self.doc.check_unique(el)
        return objs

    def check_known(self, el: etree._Element) -> None:
        refuse_unknown(self.doc, [el])

    def check_all_known(self) -> None:
        """One error for every element of the model's sets (and ``<components>``) OpenSim 4.6
        does not know: a model using plugins is refused once, not once per class."""
        listed = [el for tag in MODEL_SETS for el in self.set_objects(tag)]
        refuse_unknown(self.doc, listed + [c for h in self.model.findall("components") for c in h
                                           if isinstance(c.tag, str)])

    def body(self, el: etree._Element) -> Body:
        mass = float(_floats(el.find("mass"), 1, self.doc, "mass", (0.0,))[0])
        if mass < 0:
            raise self.doc.error(el, f"has negative mass {mass}")
        com = _floats(el.find("mass_center"), 3, self.doc, "mass_center", np.zeros(3))
        inertia = np.zeros((3, 3))
        ixx, iyy, izz, ixy, ixz, iyz = _floats(el.find("inertia"), 6, self.doc, "inertia", np.zeros(6))
        inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        return Body(el.get("name"), mass, com, inertia, el)

    def coordinate(self, el: etree._Element, joint: str) -> Coordinate:
        rng = el.find("range")
        # OpenSim 4.x omits properties at their default: range [-10, 10], not clamped, not locked.
        lo, hi = _floats(rng, 2, self.doc, "range", (-10.0, 10.0))
        if lo > hi:
            raise self.doc.error(el, f"has range [{lo}, {hi}] with minimum above maximum")
        default = float(_floats(el.find("default_value"), 1, self.doc, "default_value", (0.0,))[0])
        locked = _bool(el.find("locked"))
        holder = el.find("prescribed_function")
        function = None
        if _bool(el.find("prescribed")) and holder is not None and len(holder) > 0:
            function = self.function_of(holder)
            default = float(function(0.0))  # OpenSim's value at time 0, whatever default_value says
            locked = locked or isinstance(function, Constant)
        return Coordinate(
            name=el.get("name"), joint=joint, default=default, range=(float(lo), float(hi)),
            clamped=_bool(el.find("clamped"), False), locked=locked, prescribed=function is not None,
            element=el, prescribed_function=function,
            default_speed=float(_floats(el.find("default_speed_value"), 1, self.doc, "default_speed_value", (0.0,))[0]),
        )

    def function_of(self, holder: etree._Element, default: Function | None = None) -> Function:
        """The function element inside ``holder`` (first child element that is a function);
        ``default`` when it holds none (an error when None)."""
        for child in holder:
            if isinstance(child.tag, str) and child.tag[:1].isupper():
                try:
                    return parse_function(child)
                except UnsupportedElementError as exc:
                    owner = self.doc.owner_of(holder)
                    where = f" (in {owner.tag} '{owner.get('name')}')" if owner is not self.model else ""
                    bad = child if exc.element == child.tag else next(
                        (e for e in child.iter(exc.element or child.tag)), child)
                    msg = str(exc).split("> ", 1)[-1]
                    raise self.doc.error(bad, f"{msg}{where}") from None
        if default is not None:
            return default
        raise self.doc.error(holder, "holds no function")

    def joint(self, el: etree._Element, coords: dict[str, Coordinate]) -> Joint:
        self.check_known(el)
        if el.tag not in SUPPORTED_JOINTS:
            raise self.doc.error(el, f"is a joint type o2m cannot convert (supported: "
                                     f"{', '.join(sorted(SUPPORTED_JOINTS))})")
        if _bool(el.find("reverse")):
            raise self.doc.error(el, "is a reversed joint, which o2m does not convert")
        parent, x_pf, _ = self.socket_frame(el, "socket_parent_frame")
        child, x_bm, _ = self.socket_frame(el, "socket_child_frame")
        names: list[str] = []
        local: dict[str, str] = {}  # OpenSim name in this joint -> MuJoCo name
        holder = el.find("coordinates")
        for cel in holder if holder is not None else []:
            if cel.tag != "Coordinate":
                continue
            c = self.coordinate(cel, el.get("name"))
            if c.name in local:
                raise self.doc.error(cel, "is a second coordinate with this name in its joint")
            local[c.name] = c.name = self.names(el.get("name"), c.name)
            coords[c.name] = c
            names.append(c.name)
        rotations: list[TransformAxis] = []
        translations: list[TransformAxis] = []
        if el.tag == "CustomJoint":
            st = el.find("SpatialTransform")
            if st is None:
                raise self.doc.error(el, "has no <SpatialTransform>")
            seen: set[str] = set()
            for ta in st.findall("TransformAxis"):
                axname = ta.get("name", "")
                kind = "rotation" if axname.startswith("rotation") else "translation"
                if axname not in TRANSFORM_AXES:
                    raise self.doc.error(ta, "is not named rotation1-3 or translation1-3")
                if axname in seen:
                    raise self.doc.error(ta, f"is a second {axname} of this SpatialTransform")
                seen.add(axname)
                axis = _floats(ta.find("axis"), 3, self.doc, "axis")
                norm = np.linalg.norm(axis)
                if norm < 1e-12:
                    raise self.doc.error(ta, "has a zero <axis>")
                cnames = (ta.findtext("coordinates") or "").split()
                if len(cnames) > 1:
                    raise self.doc.error(ta, f"depends on {len(cnames)} coordinates; o2m supports one")
                cname = cnames[0] if cnames else None
                if cname is not None and cname not in local:
                    raise self.doc.error(ta, f"uses coordinate '{cname}', which its joint does not define")
                cname = local[cname] if cname is not None else None
                func = self.function_of(ta, _zero_function())  # OpenSim's default: Constant 0
                axobj = TransformAxis(axname, kind, axis / norm, cname, func, ta)
                (rotations if kind == "rotation" else translations).append(axobj)
            rotations.sort(key=lambda a: a.name)
            translations.sort(key=lambda a: a.name)
        elif el.tag in SURFACE_JOINTS:
            return self.surface_joint(el, parent, child, x_pf, x_bm, names)
        else:
            spec = JOINT_AXES[el.tag]
            if len(names) != len(spec):
                raise self.doc.error(el, f"has {len(names)} coordinates; a {el.tag} has {len(spec)}")
            ident = _identity_function()
            for i, (cname, (kind, axis)) in enumerate(zip(names, spec, strict=True)):
                axobj = TransformAxis(f"{kind}{i + 1}", kind, np.array(axis), cname, ident, el)
                (rotations if kind == "rotation" else translations).append(axobj)
        return Joint(el.get("name"), el.tag, parent, child, x_pf, x_bm, rotations, translations, names, el)

    def surface_joint(self, el: etree._Element, parent: str, child: str, x_pf: Transform, x_bm: Transform,
                      names: list[str]) -> Joint:
        """An EllipsoidJoint or ScapulothoracicJoint (:class:`EllipsoidSurface`), as OpenSim 4.6 builds it."""
        if len(names) != SURFACE_JOINTS[el.tag]:
            raise self.doc.error(el, f"has {len(names)} coordinates; a {el.tag} has {SURFACE_JOINTS[el.tag]}")
        axes = [np.array(_X), np.array(_Y), np.array(_Z)]
        tag = "radii_x_y_z" if el.tag == "EllipsoidJoint" else "thoracic_ellipsoid_radii_x_y_z"
        if el.find(tag) is None:  # OpenSim's default is NaN
            raise self.doc.error(el, f"lacks <{tag}>")
        radii = _floats(el.find(tag), 3, self.doc, tag)
        if el.tag == "EllipsoidJoint":
            surface = EllipsoidSurface(radii, Transform(), Transform())
        else:
            ox, oy = _floats(el.find("scapula_winging_axis_origin"), 2, self.doc, "scapula_winging_axis_origin",
                             (0.0, 0.0))
            wd = float(_floats(el.find("scapula_winging_axis_direction"), 1, self.doc,
                               "scapula_winging_axis_direction", (0.0,))[0])
            quarter = axis_angle_matrix(np.array(_Z), np.pi / 2)
            wing = np.array([-np.sin(wd), np.cos(wd), 0.0])
            surface = EllipsoidSurface(radii[[1, 0, 2]], Transform(quarter), Transform(quarter.T), wing,
                                       np.array([ox, oy, 0.0]))
            axes.append(wing)
        ident = _identity_function()
        rotations = [TransformAxis(f"rotation{i + 1}", "rotation", ax, c, ident, el)
                     for i, (ax, c) in enumerate(zip(axes, names, strict=True))]
        return Joint(el.get("name"), el.tag, parent, child, x_pf, x_bm, rotations, [], names, el, surface)

    def read(self) -> Skeleton:
        doc = self.doc
        self.check_all_known()
        skipped: list[Skipped] = []
        bodies: dict[str, Body] = {}
        for el in self.set_objects("BodySet"):
            self.check_known(el)
            if el.tag != "Body":
                raise doc.error(el, "is in the BodySet but is not a Body")
            b = self.body(el)
            if b.name in bodies or b.name == "ground":
                raise doc.error(el, "is a second body with this name")
            bodies[b.name] = b
        coords: dict[str, Coordinate] = {}
        self.names = self.coordinate_names(self.set_objects("JointSet"))
        joints = [self.joint(el, coords) for el in self.set_objects("JointSet")]
        cut = loop_welds(joints)
        body_constraints = [BodyConstraint(j.name, "WeldConstraint", j.parent, j.parent_frame, j.child,
                                           j.child_frame, None, j.element) for j in cut]
        joints = orient_joints([j for j in joints if not any(j is c for c in cut)], doc)
        couplers: list[Coupler] = []
        point_on_lines: list[PointOnLine] = []
        for el in self.set_objects("ConstraintSet"):
            self.check_known(el)
            enforced = _bool(el.find("isEnforced"), True) and not _bool(el.find("isDisabled"), False)
            if el.tag != "CoordinateCouplerConstraint":
                if not enforced:
                    skipped.append(Skipped(el.tag, el.get("name", ""), "constraint is not enforced"))
                    continue
                if el.tag == "PointOnLineConstraint":
                    point_on_lines.append(self.point_on_line(el))
                    continue
                if el.tag in BODY_CONSTRAINTS:
                    body_constraints.append(self.body_constraint(el))
                    continue
                raise doc.error(el, "is a constraint o2m cannot convert (only CoordinateCouplerConstraint, "
                                f"PointOnLineConstraint, {', '.join(sorted(BODY_CONSTRAINTS))})")
            if not enforced:
                skipped.append(Skipped(el.tag, el.get("name", ""), "constraint is not enforced"))
                continue
            ind = [self.names.resolve(c) for c in (el.findtext("independent_coordinate_names") or "").split()]
            dep = self.names.resolve(el.findtext("dependent_coordinate_name") or "")
            if len(ind) != 1:
                raise doc.error(el, f"couples {len(ind)} independent coordinates; o2m supports one")
            for c in ind + [dep]:
                if c not in coords:
                    raise doc.error(el, f"names coordinate '{c}', which no joint defines")
            fholder = el.find("coupled_coordinates_function")
            if fholder is None:
                raise doc.error(el, "has no <coupled_coordinates_function>")
            couplers.append(Coupler(el.get("name", dep), dep, ind[0], self.function_of(fholder), el))
        markers: list[Marker] = []
        for el in self.set_objects("MarkerSet"):
            if el.tag != "Marker":
                skipped.append(Skipped(el.tag, el.get("name", ""), "not a Marker"))
                continue
            body, x, _ = self.socket_frame(el, "socket_parent_frame")
            loc = _floats(el.find("location"), 3, doc, "location", np.zeros(3))
            markers.append(Marker(el.get("name"), body, x.apply(loc), el))
        geometry: list[Geometry] = []
        for holder in self.model.iter("attached_geometry"):
            owner = holder.getparent()
            if owner.tag not in FRAME_TYPES:
                continue
            body, x, fname = self.frame(owner)
            for g in holder:
                if isinstance(g.tag, str):
                    geometry.append(Geometry(g, body, x, fname))
        for set_tag in MODEL_SETS[3:]:
            for el in self.set_objects(set_tag):
                self.check_known(el)
                if set_tag == "ForceSet" and el.tag in PATH_TYPES:
                    continue  # paths are read by o2m.osim.paths (other path forces are skipped, listed)
                if id(el) in self.used_components:
                    continue  # a frame's part, converted with it
                reason = SKIP_REASONS[set_tag]
                if set_tag == "ForceSet" and el.find("GeometryPath") is not None:
                    reason += " (its path too: no tendon, no force)"
                skipped.append(Skipped(el.tag, el.get("name", ""), reason))
        grav = self.model.find("gravity")
        gravity = _floats(grav, 3, doc, "gravity", (0.0, -9.80665, 0.0))
        return Skeleton(self.model.get("name", doc.path.stem), gravity, bodies, joints, coords, couplers,
                        markers, geometry, skipped, doc, point_on_lines, body_constraints, self.names)


def read_skeleton(doc: OsimDocument) -> Skeleton:
    """Read the multibody part of ``doc``."""
    return SkeletonReader(doc).read()
