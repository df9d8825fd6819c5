"""The non-muscle OpenSim forces: limit forces, ligaments and the simple actuators.

One handler per OpenSim type (:data:`HANDLERS`); each reads its element and adds MuJoCo
elements to the spec of an :class:`~o2m.mjcf.MjcfBuilder`, recording in a per-conversion
:class:`ForceConversion` what it did. Units: SI (rad, m, N, N m, s).

* **CoordinateLimitForce**: joint springs, dead-band tendons and joint damping
  (:mod:`o2m.convert.limit_forces`).
* **Ligament**: a spring on the spatial tendon of its path (:mod:`o2m.convert.ligaments`).
* **PointToPointSpring**: an exact spring on a two-site spatial tendon; **PathSpring**: the spring
  of its path's tendon, without its damping (:mod:`o2m.convert.springs`).
* **BushingForce**: where its deflections are linear in the coordinates between its frames, the
  spring and damping of its one coordinate's joint or fixed tendons on several
  (:mod:`o2m.convert.bushings`); skipped otherwise, unless within a given tolerance.
* **ExpressionBasedCoordinateForce**: its joint's spring and damping when the expression is linear
  in q and qdot (:mod:`o2m.convert.expression_forces`); skipped otherwise.
* **CoordinateActuator**, **ActivationCoordinateActuator**, **TorqueActuator**, **PointActuator**,
  **PointToPointActuator**, **PathActuator**: motors on joints, sites and tendons (:mod:`o2m.convert.actuators`).
* **HuntCrossleyForce**, **SmoothSphereHalfSpaceForce**: geoms for their ContactSpheres and
  ContactHalfSpaces and explicit contact pairs (:mod:`o2m.convert.contact`); ElasticFoundationForce
  is listed as skipped, and so is contact geometry no converted force uses.

Actuators are added after the muscle actuators, named as in OpenSim; ``min_control`` and
``max_control`` become ``ctrlrange`` when both are finite.

:func:`measure` measures every converted force against OpenSim once the model is written.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from types import MappingProxyType

import mujoco
from lxml import etree

from o2m.convert.actuators import (
    convert_activation_coordinate_actuator,
    convert_coordinate_actuator,
    convert_path_actuator,
    convert_point_actuator,
    convert_point_to_point_actuator,
    convert_torque_actuator,
    measure_drifts,
)
from o2m.convert.builder import MjcfBuilder
from o2m.convert.bushings import convert_bushing, measure_bushings
from o2m.convert.contact import (
    convert_hunt_crossley,
    convert_smooth_sphere,
    fit_contacts,
    measure_contacts,
    skip_force,
    skip_unused_geometry,
)
from o2m.convert.expression_forces import (
    convert_expression_bushing,
    convert_expression_force,
    convert_spring_generalized_force,
)
from o2m.convert.force_context import ForceConversion, Ligament, LimitForce, SideFit, _applies_force, _Context
from o2m.convert.ligaments import convert_blankevoort, convert_ligament, fit_ligaments, measure_ligaments
from o2m.convert.limit_forces import convert_coordinate_limit_force, fit_deadband, measure_limit_forces, motion_type
from o2m.convert.springs import convert_path_spring, convert_point_to_point_spring, measure_springs
from o2m.mj import mjcf_text
from o2m.osim.kinds import LIGAMENT_TYPES
from o2m.osim.skeleton import SkeletonReader, Skipped

__all__ = ["FORCE_TYPES", "HANDLERS", "ForceConversion", "LimitForce", "Ligament", "SideFit", "add_forces",
           "fit_contacts", "fit_deadband", "fit_ligaments", "measure", "motion_type", "restore_precision"]


#: The converter of each OpenSim force type o2m converts here (Ligament: its spring; the tendon
#: of its path is built by :mod:`o2m.tendons`).
HANDLERS: Mapping[str, Callable[[_Context, etree._Element], None]] = MappingProxyType({
    "CoordinateLimitForce": convert_coordinate_limit_force,
    "Ligament": convert_ligament,
    "Blankevoort1991Ligament": convert_blankevoort,
    "PointToPointSpring": convert_point_to_point_spring,
    "PathSpring": convert_path_spring,
    "BushingForce": convert_bushing,
    "ExpressionBasedCoordinateForce": convert_expression_force,
    "SpringGeneralizedForce": convert_spring_generalized_force,
    "ExpressionBasedBushingForce": convert_expression_bushing,
    "CoordinateActuator": convert_coordinate_actuator,
    "ActivationCoordinateActuator": convert_activation_coordinate_actuator,
    "PointToPointActuator": convert_point_to_point_actuator,
    "PathActuator": convert_path_actuator,
    "TorqueActuator": convert_torque_actuator,
    "PointActuator": convert_point_actuator,
    "HuntCrossleyForce": convert_hunt_crossley,
    "ElasticFoundationForce": skip_force,
    "SmoothSphereHalfSpaceForce": convert_smooth_sphere,
})
FORCE_TYPES = frozenset(HANDLERS)


def add_forces(builder: MjcfBuilder, reader: SkeletonReader, *, bushing_tolerance: float | None = None
               ) -> ForceConversion:
    """Convert every force of the ForceSet that has a handler; call after the muscle paths (so the
    actuators come after the muscles' and the ligaments' tendons exist). ``bushing_tolerance``:
    the worst deflection error (rad or m) of a non-linear BushingForce's linear fit that still
    converts (None: only linear ones)."""
    spec = builder.spec
    names = {"site": {s.name for s in spec.sites}, "tendon": {t.name for t in spec.tendons},
             "geom": {g.name for g in spec.geoms}, "pair": {p.name for p in spec.pairs}}
    ctx = _Context(builder, reader, ForceConversion(), names, bushing_tolerance)
    for el in reader.set_objects("ForceSet"):
        handler = HANDLERS.get(el.tag)
        if handler is None:
            continue
        ctx.out.handled.add((el.tag, el.get("name", "")))
        if not _applies_force(el):
            spring = "; its path is a tendon without spring" if el.tag in LIGAMENT_TYPES else ""
            why = f"disabled in OpenSim (appliesForce false){spring}"
            ctx.out.skipped.append(Skipped(el.tag, el.get("name", ""), why))
            continue
        handler(ctx, el)
    skip_unused_geometry(ctx)
    return ctx.out


# -- precision and measurement --------------------------------------------------------------------
def restore_precision(xml: str, out: ForceConversion) -> str:
    """MJCF text with the tendon springs and actuator gears written in full (17 digits)."""
    if not out.exact:
        return xml
    root = mjcf_text.parse(xml)
    for tag in ("tendon", "actuator"):
        for holder in root.iter(tag):
            for el in holder:
                vals = out.exact.get((tag, el.get("name"))) if isinstance(el.tag, str) else None
                mjcf_text.set_numbers(el, vals or {})
                for part in el.findall("joint") if tag == "tendon" else []:  # a fixed tendon's coefficients
                    key = ("tendon joint", f"{el.get('name')}/{part.get('joint')}")
                    mjcf_text.set_numbers(part, out.exact.get(key, {}))
    return mjcf_text.to_text(root)


def measure(out: ForceConversion, model: mujoco.MjModel, osim: str | Path, builder: MjcfBuilder) -> None:
    """Measure every converted force against OpenSim in ``model`` (the MJCF as written) and record
    the errors in ``builder.result.approximations``."""
    measure_limit_forces(out, model, osim, builder)
    measure_ligaments(out, model, builder)
    measure_springs(out, model, builder)
    measure_bushings(out, model, builder)
    measure_drifts(out, builder)
    measure_contacts(out, model, builder)
