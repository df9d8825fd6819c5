"""Which OpenSim types o2m converts, and where the model keeps each: type-name sets and lookups
through OpenSim's registry (no document reading here)."""

from __future__ import annotations

from functools import cache

from o2m.osim import runtime

__all__ = [
    "BODY_CONSTRAINTS", "LIGAMENT_TYPES", "MODEL_SETS", "MUSCLE_TYPES", "PATH_TYPES", "SKIP_REASONS",
    "count_text", "default_coordinates", "opensim_typenames", "refuse_unknown", "renamed_type", "set_of_type",
    "unknown_classes",
]

#: Constraints between two bodies that become MuJoCo equalities (:mod:`o2m.convert.constraints`).
BODY_CONSTRAINTS = frozenset({"WeldConstraint", "PointConstraint", "ConstantDistanceConstraint"})


@cache
def opensim_typenames() -> frozenset[str]:
    """Every object type OpenSim 4.6 registers: a tag outside this set is unknown to OpenSim."""
    opensim = runtime.opensim()
    names = opensim.ArrayStr()
    opensim.OpenSimObject.getRegisteredTypenames(names)
    return frozenset(names.get(i) for i in range(names.getSize()))


@cache
def renamed_type(tag: str) -> str | None:
    """The type OpenSim reads an element ``tag`` as, where it is an old name OpenSim still accepts
    (``Delp1990Muscle`` is read as ``Delp1990Muscle_Deprecated``, ``MuscleViaPoint`` as
    ``ConditionalPathPoint``); None for a current type name or any other tag. OpenSim keeps this
    table itself (``Object::renameType``), so o2m asks it rather than copying it."""
    if tag in opensim_typenames():
        return None
    instance = runtime.opensim().OpenSimObject.getDefaultInstanceOfType(tag)
    name = instance.getConcreteClassName() if instance is not None else None
    return name if name and name != tag else None


#: The muscles and other path forces o2m converts (their paths are read by :mod:`o2m.osim.paths`).
MUSCLE_TYPES = frozenset({
    "Thelen2003Muscle", "Millard2012EquilibriumMuscle", "Millard2012AccelerationMuscle",
    "Schutte1993Muscle_Deprecated", "DeGrooteFregly2016Muscle", "RigidTendonMuscle",
    "Delp1990Muscle_Deprecated", "Thelen2003Muscle_Deprecated", "MeyerFregly2016Muscle",
})
#: Ligaments: a spring on the path's tendon (:mod:`o2m.convert.ligaments`).
LIGAMENT_TYPES = frozenset({"Ligament", "Blankevoort1991Ligament"})
PATH_TYPES = MUSCLE_TYPES | LIGAMENT_TYPES | {"PathActuator", "PathSpring"}

#: The model set each OpenSim base class belongs to, in the order they are tried (a component of
#: the model's ``<components>`` list is read with the objects of its base class's set).
_SET_OF_BASE = (("Body", "BodySet"), ("Joint", "JointSet"), ("Constraint", "ConstraintSet"),
                ("Force", "ForceSet"), ("Marker", "MarkerSet"), ("ContactGeometry", "ContactGeometrySet"),
                ("Controller", "ControllerSet"), ("Probe", "ProbeSet"),
                ("PhysicalOffsetFrame", "frames"))  # read where a socket names it, never skipped


@cache
def set_of_type(tag: str) -> str:
    """The model set ("BodySet", "ForceSet", ...) that holds objects of OpenSim type ``tag``;
    "frames" for a PhysicalOffsetFrame; "ComponentSet" for any other component and for a
    type OpenSim 4.6 does not know."""
    if tag not in opensim_typenames():
        return "ComponentSet"
    opensim = runtime.opensim()
    obj = opensim.OpenSimObject.newInstanceOfType(tag)
    for base, set_tag in _SET_OF_BASE:
        if obj is not None and getattr(opensim, base).safeDownCast(obj) is not None:
            return set_tag
    return "ComponentSet"


@cache
def default_coordinates(tag: str) -> tuple[str, ...]:
    """The names of the coordinates OpenSim gives a joint of type ``tag`` whose document lists none
    (``_coord_0``, ...; none for a CustomJoint, whose SpatialTransform names them, or a non-joint)."""
    if set_of_type(tag) != "JointSet":
        return ()
    opensim = runtime.opensim()
    joint = opensim.Joint.safeDownCast(opensim.OpenSimObject.newInstanceOfType(tag))
    return tuple(joint.get_coordinates(i).getName() for i in range(joint.numCoordinates()))


#: A model's sets of components, in the order o2m reads them.
MODEL_SETS = ("BodySet", "JointSet", "ConstraintSet", "ForceSet", "ContactGeometrySet", "ControllerSet", "ProbeSet",
              "ComponentSet")
#: Why an element of each of the last sets is skipped when nothing converts it.
SKIP_REASONS = {
    "ForceSet": "this force is not converted yet",
    "ContactGeometrySet": "contact geometry is not converted",
    "ControllerSet": "controllers are not part of a MuJoCo model",
    "ProbeSet": "probes are analysis tools, not part of a MuJoCo model",
    "ComponentSet": "generic components are not converted",
}


def unknown_classes(elements) -> dict[str, list]:
    """Tag -> the elements of ``elements`` (lxml) of that tag, in their order, for each tag that
    OpenSim 4.6 registers neither as a type nor as an old name of one (misspelt, or a plugin's)."""
    known = opensim_typenames()
    found: dict[str, list] = {}
    for el in elements:
        if isinstance(el.tag, str) and el.tag not in known and renamed_type(el.tag) is None:
            found.setdefault(el.tag, []).append(el)
    return found


def count_text(found: dict[str, list]) -> str:
    """``unknown_classes``'s result for a message: "Tag (count), ..."."""
    return ", ".join(f"{tag} ({len(els)})" for tag, els in found.items())


def refuse_unknown(doc, elements: list) -> None:
    """Raise one error (``doc.error``) naming the first of ``elements`` (lxml elements of
    ``doc``) by line whose tag OpenSim 4.6 does not know, and every unknown class with its count;
    nothing when all are known."""
    in_order = sorted({id(el): el for el in elements}.values(), key=lambda el: doc.line_of(el) or 0)
    found = unknown_classes(in_order)
    if not found:
        return
    first = next(iter(found.values()))[0]
    raise doc.error(first, f"is not an element OpenSim 4.6 knows (misspelt, or from a plugin); unknown "
                           f"classes in this model: {count_text(found)}")
