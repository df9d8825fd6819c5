"""StationDefinedFrames: a frame built from four Stations (or Markers) on one body, as OpenSim 4.6
builds it. Read through a :class:`~o2m.osim.skeleton.SkeletonReader` (``reader``), which resolves
the stations' own frames and records the components it used."""

from __future__ import annotations

import numpy as np
from lxml import etree

from o2m.osim.document import _floats
from o2m.transforms import Transform

__all__ = ["station", "station_defined_frame"]


def station(reader, el: etree._Element, socket: str, _depth: int) -> tuple[str, np.ndarray]:
    """(body, position (3,) m in it) of the Station or Marker that socket ``socket`` of ``el`` names."""
    sock = el.find(socket)
    if sock is None:
        raise reader.doc.error(el, f"has no <{socket}>")
    st = reader.doc.resolve(sock)
    if st.tag not in ("Station", "Marker"):
        raise reader.doc.error(el, f"<{socket}> names a <{st.tag}>, not a Station or Marker")
    reader.used_components.add(id(st))
    parent = st.find("socket_parent_frame")
    if parent is None:
        raise reader.doc.error(st, "has no <socket_parent_frame>")
    body, x, _ = reader.frame(reader.doc.resolve(parent), _depth + 1)
    return body, x.apply(_floats(st.find("location"), 3, reader.doc, "location", np.zeros(3)))

def station_defined_frame(reader, el: etree._Element, _depth: int) -> tuple[str, Transform, str]:
    """A StationDefinedFrame as OpenSim 4.6 builds it: ``ab_axis`` (default +x) along b - a,
    ``ab_x_ac_axis`` (default +y) along (b - a) x (c - a), the third axis completing a
    right-handed frame, its origin at ``origin_point``; all four stations on one body."""
    ends = [station(reader, el, f"socket_{s}", _depth) for s in ("point_a", "point_b", "point_c", "origin_point")]
    bodies = {b for b, _ in ends}
    if len(bodies) != 1:
        raise reader.doc.error(el, f"has stations on several bodies ({', '.join(sorted(bodies))})")
    a, b, c, origin = (p for _, p in ends)
    ab, ab_x_ac = b - a, np.cross(b - a, c - a)
    if np.linalg.norm(ab) < 1e-12 or np.linalg.norm(ab_x_ac) < 1e-12:
        raise reader.doc.error(el, "has stations a, b and c on one line: they define no frame")
    rot = np.zeros((3, 3))
    axes = []
    for prop, default, vec in (("ab_axis", "+x", ab), ("ab_x_ac_axis", "+y", ab_x_ac)):
        text = (el.findtext(prop) or "").strip() or default
        if text not in ("+x", "-x", "+y", "-y", "+z", "-z", "x", "y", "z"):
            raise reader.doc.error(el, f"<{prop}> is '{text}', not one of +x, -x, +y, -y, +z, -z")
        k = "xyz".index(text[-1])
        rot[:, k] = (-1.0 if text[0] == "-" else 1.0) * vec / np.linalg.norm(vec)
        axes.append(k)
    if axes[0] == axes[1]:
        raise reader.doc.error(el, "has <ab_axis> and <ab_x_ac_axis> along one axis")
    k = 3 - sum(axes)
    rot[:, k] = np.cross(rot[:, (k + 1) % 3], rot[:, (k + 2) % 3])
    return ends[0][0], Transform(rot, origin), el.get("name")

