"""Muscle paths read from an OpenSim 4.x document: path points, moving and conditional points,
and the wrap objects a path uses. Units: metres, radians, in the OpenSim body frames.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from lxml import etree

from o2m.osim.document import _floats
from o2m.osim.function_reader import parse_function
from o2m.osim.functions import Function
from o2m.osim.kinds import MUSCLE_TYPES, PATH_TYPES
from o2m.osim.skeleton import FRAME_TYPES, SkeletonReader
from o2m.transforms import Transform, body_fixed_xyz

#: Path actuators and forces whose GeometryPath o2m turns into a MuJoCo spatial tendon.
WRAP_TYPES = frozenset({"WrapSphere", "WrapCylinder", "WrapEllipsoid", "WrapTorus"})
#: A muscle's numbers o2m reads, and the interval each must lie in when given: (low, high, whether
#: low itself is allowed). A negative max isometric force would become MuJoCo's "compute the force
#: automatically", a NaN length or angle MuJoCo's defaults; OpenSim itself rejects a pennation angle
#: outside [0, pi/2) and fails to equilibrate the others.
MUSCLE_NUMBERS = {
    "max_isometric_force": (0.0, math.inf, False),
    "optimal_fiber_length": (0.0, math.inf, False),
    "tendon_slack_length": (0.0, math.inf, True),
    "pennation_angle_at_optimal": (0.0, math.pi / 2, True),
    "activation_time_constant": (0.0, math.inf, False),
    "deactivation_time_constant": (0.0, math.inf, False),
}


@dataclass
class PathPoint:
    """A point of a path. ``location`` (3,) is in ``body``'s frame (for a moving point, at the
    coordinates' default values). ``moving`` maps axis 0/1/2 to (coordinate, function of it);
    ``condition`` is (coordinate, lo, hi) for a ConditionalPathPoint. ``designed`` marks a point
    o2m adds (:mod:`o2m.lengthvia`), which OpenSim's path does not have."""

    name: str
    body: str
    location: np.ndarray
    element: etree._Element
    moving: dict[int, tuple[str, Function]] = field(default_factory=dict)
    condition: tuple[str, float, float] | None = None
    designed: bool = False


@dataclass
class WrapObject:
    """A wrap surface fixed to ``body``: its frame (rotation and translation in the body frame),
    kind (sphere, cylinder, ellipsoid, torus), sizes in metres and OpenSim's quadrant."""

    name: str
    kind: str
    body: str
    frame: Transform
    radius: float = 0.0
    length: float = 0.0
    dimensions: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inner_radius: float = 0.0
    outer_radius: float = 0.0
    quadrant: str = "all"
    active: bool = True
    element: etree._Element | None = None


@dataclass
class PathWrap:
    """A wrap object applied to a path, between path points ``range`` (1-based, -1 = all)."""

    wrap: str
    range: tuple[int, int]


@dataclass
class Path:
    """The GeometryPath of a force element (a muscle, a path actuator, a ligament)."""

    owner: str
    owner_type: str
    points: list[PathPoint]
    wraps: list[PathWrap]
    element: etree._Element


def _coordinate_name(reader: SkeletonReader, socket: etree._Element | None) -> str | None:
    if socket is None or not (socket.text or "").strip():
        return None
    return reader.coordinate_of(reader.doc.resolve(socket))


def read_point(reader: SkeletonReader, el: etree._Element, coords: dict[str, float]) -> PathPoint:
    """One path point element (PathPoint, MovingPathPoint, ConditionalPathPoint)."""
    doc = reader.doc
    body, x_frame, _ = reader.socket_frame(el, "socket_parent_frame")
    if el.tag in ("PathPoint", "ConditionalPathPoint"):
        loc = _floats(el.find("location"), 3, doc, "location", np.zeros(3))
        point = PathPoint(el.get("name"), body, x_frame.apply(loc), el)
        if el.tag == "ConditionalPathPoint":
            cname = _coordinate_name(reader, el.find("socket_coordinate"))
            lo, hi = _floats(el.find("range"), 2, doc, "range")
            if cname is None:
                raise doc.error(el, "has no <socket_coordinate>")
            point.condition = (cname, float(lo), float(hi))
        return point
    if el.tag == "MovingPathPoint":
        moving: dict[int, tuple[str, Function]] = {}
        local = np.zeros(3)
        for i, ax in enumerate("xyz"):
            holder = el.find(f"{ax}_location")
            fn_el = next((c for c in holder if isinstance(c.tag, str)), None) if holder is not None else None
            if fn_el is None:
                continue
            fn = parse_function(fn_el)
            cname = _coordinate_name(reader, el.find(f"socket_{ax}_coordinate"))
            if cname is None:
                local[i] = float(fn(np.array([0.0]))[0])
                continue
            local[i] = float(fn(np.array([coords[cname]]))[0])
            lin = fn.is_linear(-1e3, 1e3)
            if lin is not None and lin[0] == 0.0:
                continue
            moving[i] = (cname, fn)
        if not np.allclose(x_frame.rot, np.eye(3)):
            raise doc.error(el, "is a MovingPathPoint on a rotated offset frame, which o2m does not convert")
        return PathPoint(el.get("name"), body, x_frame.apply(local), el, moving=moving)
    raise doc.error(el, "is not a path point o2m knows (PathPoint, MovingPathPoint, ConditionalPathPoint)")


def read_wrap_objects(reader: SkeletonReader) -> dict[str, WrapObject]:
    """Every wrap object of every body (and ground), by name."""
    doc = reader.doc
    out: dict[str, WrapObject] = {}
    for owner in list(reader.model.iter(*FRAME_TYPES)):
        if owner.tag not in ("Body", "Ground") and owner.find("WrapObjectSet/objects/*") is None:
            continue  # a frame holds wrap objects too (OpenSim 4 moved the set from Body to Frame)
        body, x_body, _ = reader.frame(owner)
        for el in owner.iterfind("WrapObjectSet/objects/*"):
            if not isinstance(el.tag, str):
                continue
            if el.tag not in WRAP_TYPES:
                raise doc.error(el, "is not a wrap object o2m knows")
            rot = body_fixed_xyz(_floats(el.find("xyz_body_rotation"), 3, doc, "xyz_body_rotation", np.zeros(3)))
            pos = _floats(el.find("translation"), 3, doc, "translation", np.zeros(3))
            w = WrapObject(el.get("name"), el.tag[4:].lower(), body, x_body @ Transform(rot, pos), element=el)
            w.quadrant = _quadrant(doc, el)
            w.active = (el.findtext("active") or "true").strip().lower() != "false"
            for prop in ("radius", "length", "inner_radius", "outer_radius"):
                setattr(w, prop, float(_floats(el.find(prop), 1, doc, prop, (getattr(w, prop),))[0]))
            w.dimensions = _floats(el.find("dimensions"), 3, doc, "dimensions", w.dimensions)
            if w.name in out:
                raise doc.error(el, "is a second wrap object with this name")
            out[w.name] = w
    return out


#: OpenSim's wrap quadrants, each as o2m writes it ("all", or the sign and the axis).
QUADRANTS = {"all": "all", "": "all", **{f"{a}{s}": f"{s}{a}" for a in "xyz" for s in "+-"},
             **{f"{s}{a}": f"{s}{a}" for a in "xyz" for s in "+-"}, **{a: f"+{a}" for a in "xyz"}}


def _quadrant(doc, el: etree._Element) -> str:
    """The wrap object's quadrant ("all", "+x", "-y", ...); an error naming it for another word."""
    text = (el.findtext("quadrant") or "all").strip()
    if text.lower() not in QUADRANTS:
        raise doc.error(el, f"has <quadrant> '{text}', not one of OpenSim's (all, +x, -x, +y, -y, +z, -z)")
    return QUADRANTS[text.lower()]


#: OpenSim's wrapping methods (a PathWrap's <method>, any case).
WRAP_METHODS = ("hybrid", "midpoint", "axial")


def _path_wrap(doc, pw: etree._Element) -> PathWrap:
    """A PathWrap element: its wrap object and point range; an error naming it for a range that is not
    two whole numbers or a method OpenSim does not know (OpenSim refuses the model then)."""
    method = (pw.findtext("method") or "hybrid").strip()
    if method.lower() not in WRAP_METHODS:
        raise doc.error(pw, f"has <method> '{method}', not one of OpenSim's ({', '.join(WRAP_METHODS)})")
    text = (pw.findtext("range") or "-1 -1").strip()
    try:
        rng = tuple(int(v) for v in text.split())
    except ValueError:
        rng = ()
    if len(rng) != 2:
        raise doc.error(pw, f"has <range> '{text}', not two whole numbers (point indices, -1 for all)")
    return PathWrap((pw.findtext("wrap_object") or "").strip(), rng)


def read_paths(reader: SkeletonReader, coords: dict[str, float]) -> list[Path]:
    """The paths of every enabled path force in the ForceSet, in document order."""
    doc = reader.doc
    paths: list[Path] = []
    for el in reader.set_objects("ForceSet"):
        if el.tag not in PATH_TYPES:
            continue
        if el.tag in MUSCLE_TYPES:
            check_muscle_numbers(reader, el)
        gp = el.find("GeometryPath")
        if gp is None:
            other = next((c.tag for c in el if isinstance(c.tag, str) and c.tag.endswith("Path")), None)
            if other is not None:  # FunctionBasedPath, Scholz2015GeometryPath: no points to place
                raise doc.error(el, f"has a <{other}>, a path o2m cannot convert (only GeometryPath, "
                                    "a path of points and wrap objects)")
            raise doc.error(el, "has no <GeometryPath>")
        points = [read_point(reader, p, coords) for p in gp.iterfind("PathPointSet/objects/*")
                  if isinstance(p.tag, str)]
        if len(points) < 2:
            raise doc.error(el, f"has a path of {len(points)} point(s); a path needs two")
        wraps = []
        for pw in gp.iterfind("PathWrapSet/objects/PathWrap"):
            wraps.append(_path_wrap(doc, pw))
        paths.append(Path(el.get("name"), el.tag, points, wraps, el))
    return paths


def check_muscle_numbers(reader: SkeletonReader, el: etree._Element) -> None:
    """Raise an error naming muscle ``el`` when one of its :data:`MUSCLE_NUMBERS` is not a number in
    its interval (negative or zero forces and lengths, NaN, a pennation angle of pi/2 or more)."""
    for prop, (lo, hi, closed) in MUSCLE_NUMBERS.items():
        child = el.find(prop)
        if child is None:
            continue
        v = float(_floats(child, 1, reader.doc, prop)[0])
        if not ((v >= lo if closed else v > lo) and v < hi):
            where = f"[{lo:g}, {hi:g})" if closed else f"({lo:g}, {hi:g})"
            raise reader.doc.error(el, f"has <{prop}> {v:g}, outside {where}")
