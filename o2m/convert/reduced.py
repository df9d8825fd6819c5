"""Reduced copies of a converted model (MJCF text) for evaluating tendon lengths fast.

The wrap fit (:mod:`o2m.convert.wrapfit`) evaluates one tendon's length and Jacobian at a
hundred poses per candidate, hundreds of thousands of times per tendon. What that needs is the
kinematic tree and the tendon's own sites and geoms; ``mj_kinematics`` otherwise places every
other site and geom of the model at every pose, for a tendon that uses a few of them. Removing
them changes no length or Jacobian entry: each site and geom is placed from its own body alone,
and every body keeps its ``<inertial>`` (a body without one keeps its geoms, which would give it
its mass).
"""

from __future__ import annotations

from collections.abc import Iterable

from lxml import etree

__all__ = ["reduced_xml", "without_unused"]


def reduced_xml(xml: str, tendon: str | None = None) -> str:
    """MJCF text of ``xml`` without meshes, actuators, sensors or keyframes, and with only
    ``tendon`` (every tendon when None): what tendon lengths depend on, cheap to evaluate."""
    root = etree.fromstring(xml.encode())
    for asset in root.iter("asset"):
        for el in list(asset):
            if el.tag in ("mesh", "hfield", "skin"):
                asset.remove(el)
    for g in list(root.iter("geom")):
        if g.get("mesh") is not None or g.get("type") in ("mesh", "hfield", "sdf"):
            g.getparent().remove(g)
    for tag in ("actuator", "sensor", "keyframe", "contact", "custom"):
        for el in list(root.iter(tag)):
            el.getparent().remove(el)
    for ten in list(root.iter("tendon")):
        for el in list(ten):
            if tendon is not None and el.get("name") != tendon:
                ten.remove(el)
    for eq in list(root.iter("equality")):
        for el in list(eq):
            if el.tag == "tendon":
                eq.remove(el)
    return etree.tostring(root, encoding="unicode")


def _names_used(root: etree._Element, body: etree._Element) -> set[str]:
    """Every attribute value outside ``body`` (the ``<worldbody>``): the names that tendons,
    equalities and the rest refer to."""
    used: set[str] = set()
    for section in root:
        if section is not body:
            for el in section.iter():
                used.update(el.attrib.values())
    return used


def without_unused(xml: str, keep: Iterable[str] = ()) -> str:
    """MJCF text ``xml`` without the sites and geoms nothing outside the ``<worldbody>`` names
    (a tendon, an equality), except those in ``keep``; a geom stays where its body has no
    ``<inertial>``."""
    root = etree.fromstring(xml.encode())
    world = root.find("worldbody")
    if world is None:
        return xml
    used = _names_used(root, world) | set(keep)
    for el in list(world.iter("site", "geom")):
        if el.get("name") in used:
            continue
        body = next(el.iterancestors("body", "worldbody"))
        if el.tag == "geom" and body.tag == "body" and body.find("inertial") is None:
            continue
        el.getparent().remove(el)
    return etree.tostring(root, encoding="unicode")
