"""Visual geometry: OpenSim's mesh files located as OpenSim finds them, and its analytic shapes
mapped to MuJoCo primitives.

Lengths are in metres throughout. OpenSim keeps bone meshes as VTK XML PolyData (.vtp); MuJoCo
reads only STL, OBJ and MSH, so the converter reads each mesh with :func:`read_mesh` and writes
it with :func:`write_stl` (both :mod:`o2m.osim.meshes`), applying the OpenSim ``scale_factors``
on the way. OpenSim frames are Y-up: a cylinder's axis is its frame's y.

MuJoCo 4.0 and visual meshes: the real bone meshes tested compile with MuJoCo's defaults,
but open or flat meshes (the floor/plane .vtp files) do not: a colliding mesh geom needs a convex hull
("mesh has coplanar vertices, cannot compute convex hull"), and the default
``inertia="convex"`` needs a non-zero volume ("mesh volume is too small ... Try setting inertia
to shell"). A visual-only mesh geom therefore gets ``<mesh inertia="shell">`` (inertia of the
surface, needs only a non-zero area) and ``<geom contype="0" conaffinity="0">`` (no collision, so
no hull); both are needed for the flat ones. Mass properties come from OpenSim's <mass>/<inertia>
through an explicit <inertial>, which makes MuJoCo ignore geom masses. See
:data:`MUJOCO_VISUAL_MESH_ATTRS`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from lxml import etree

from o2m.errors import UnsupportedElementError
from o2m.osim.document import MAX_MAGNITUDE

__all__ = [
    "GeomSpec",
    "MUJOCO_VISUAL_MESH_ATTRS",
    "geometry_search_dirs",
    "find_geometry_file",
    "analytic_geom",
    "geometry_appearance",
    "geometry_scale_factors",
]

#: Attributes that let MuJoCo 4.0 compile open or flat meshes used as visual-only geoms:
#: the "mesh" ones go on ``<mesh>``, the "geom" ones on the ``<geom>`` using it.
MUJOCO_VISUAL_MESH_ATTRS: dict[str, dict[str, str]] = {
    "mesh": {"inertia": "shell"},
    "geom": {"contype": "0", "conaffinity": "0"},
}


# --------------------------------------------------------------------------------------------
# Locating mesh files
# --------------------------------------------------------------------------------------------


def geometry_search_dirs(model_path: str | Path, extra_dirs: list[str | Path] | tuple = ()) -> list[Path]:
    """OpenSim's mesh search folders, in order: the model file's folder, its ``Geometry/``
    subfolder, then ``extra_dirs`` (the user's geometry paths) in the order given."""
    folder = Path(model_path).resolve().parent
    return [folder, folder / "Geometry", *(Path(d) for d in extra_dirs)]


def find_geometry_file(name: str, search_dirs: list[str | Path] | tuple) -> Path | None:
    """Locate the ``mesh_file`` ``name`` as OpenSim does: an absolute path is taken as is,
    otherwise the first of ``search_dirs`` (see :func:`geometry_search_dirs`) holding it wins.

    Windows separators in ``name`` are accepted. Returns None when no folder has the file.
    """
    name = name.strip().replace("\\", "/")
    if not name:
        return None
    p = Path(name)
    if p.is_absolute():
        return p if p.is_file() else None
    for d in search_dirs:
        cand = Path(d) / p
        if cand.is_file():
            return cand
    return None


# --------------------------------------------------------------------------------------------
# Analytic geometry
# --------------------------------------------------------------------------------------------

#: Rotation (w, x, y, z) of -90 degrees about x: takes MuJoCo's cylinder axis (local z) onto
#: OpenSim's cylinder axis (the frame's y).
_CYLINDER_QUAT = np.array([np.sqrt(0.5), -np.sqrt(0.5), 0.0, 0.0])

#: Geometry OpenSim draws that has no MuJoCo counterpart, with the reason reported when skipped.
_SKIPPED = {
    "Cone": "MuJoCo has no cone primitive",
    "Torus": "MuJoCo has no torus primitive",
    "FrameGeometry": "frame axes are a visual decoration, not body geometry",
    "Arrow": "arrows are a visual decoration, not body geometry",
    "Line": "lines are a visual decoration, not body geometry",
    "LineGeometry": "lines are a visual decoration, not body geometry",
    "Mesh": "Mesh is not analytic; convert it with read_mesh/write_stl",
}

#: The smallest size (m) of a MuJoCo primitive o2m writes (MuJoCo's mjMINVAL: its XML writer leaves
#: out a smaller size as if it were the default 0, and the written model does not load).
MIN_SIZE = 1e-15

#: OpenSim 4.6 default property values, used when the element omits them.
_DEFAULTS = {
    ("Sphere", "radius"): [1.0],
    ("Cylinder", "radius"): [0.5],
    ("Cylinder", "half_height"): [0.5],
    ("Brick", "half_lengths"): [0.1, 0.2, 0.3],
    ("Ellipsoid", "radii"): [0.5, 1.0, 2.0],
}


@dataclass
class GeomSpec:
    """A MuJoCo primitive standing in for an OpenSim analytic geometry.

    ``type`` is the MuJoCo geom type name, ``size`` (3,) MuJoCo's size in metres, ``pos`` (3,)
    and ``quat`` (4, w-x-y-z) place it in the OpenSim frame holding the geometry (``frame`` is
    that element's socket_frame path, e.g. ".."), ``rgba`` (4,) comes from <Appearance> (None
    when absent), ``visible`` from <Appearance><visible>.
    """

    type: str
    size: np.ndarray
    pos: np.ndarray = field(default_factory=lambda: np.zeros(3))
    quat: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    rgba: np.ndarray | None = None
    name: str | None = None
    frame: str | None = None
    visible: bool = True


def _err(el: etree._Element, msg: str) -> UnsupportedElementError:
    return UnsupportedElementError(msg, element=str(el.tag), name=el.get("name"), line=el.sourceline)


def _vector(el: etree._Element, prop: str, n: int, default: list[float] | None = None,
            owner: etree._Element | None = None) -> np.ndarray:
    """Property ``prop`` of ``el`` as a float array (n,), or ``default`` when absent; errors name
    ``owner`` (default ``el``), the geometry element a property of its <Appearance> belongs to."""
    what = prop if owner is None else f"{el.tag}/{prop}"
    owner = el if owner is None else owner
    child = el.find(prop)
    if child is None or not (child.text or "").strip():
        if default is None:
            raise _err(owner, f"has no <{what}>")
        return np.array(default, dtype=np.float64)
    text = re.sub(r"[(),~\[\]]", " ", child.text)
    try:
        vals = np.array([float(t) for t in text.split()], dtype=np.float64)
    except ValueError:
        raise _err(owner, f"<{what}> is not numeric: {child.text.strip()!r}") from None
    if len(vals) != n or not np.all(np.isfinite(vals)):
        raise _err(owner, f"<{what}> needs {n} finite number(s), got {child.text.strip()!r}")
    if np.any(np.abs(vals) > MAX_MAGNITUDE):
        raise _err(owner, f"<{what}> holds {vals[np.argmax(np.abs(vals))]:g}, beyond {MAX_MAGNITUDE:g}, "
                          f"MuJoCo's largest value")
    return vals


def geometry_scale_factors(element: etree._Element) -> np.ndarray:
    """The ``scale_factors`` (3,) of any OpenSim Geometry element (default 1 1 1)."""
    default = [0.2, 0.2, 0.2] if element.tag == "FrameGeometry" else [1.0, 1.0, 1.0]
    return _vector(element, "scale_factors", 3, default)


def geometry_appearance(element: etree._Element) -> tuple[np.ndarray | None, bool]:
    """``(rgba (4,) or None, visible)`` from a Geometry's <Appearance>.

    rgba is None when there is no <Appearance>; missing <color>/<opacity> take OpenSim's
    defaults (white, opaque).
    """
    app = element.find("Appearance")
    if app is None:
        return None, True
    color = _vector(app, "color", 3, [1.0, 1.0, 1.0], owner=element)
    opacity = _vector(app, "opacity", 1, [1.0], owner=element)
    vis = app.find("visible")
    visible = vis is None or (vis.text or "true").strip().lower() not in ("false", "0")
    return np.clip(np.concatenate([color, opacity]), 0.0, 1.0), visible


def analytic_geom(element: etree._Element, skipped: list[str] | None = None) -> GeomSpec | None:
    """MuJoCo primitive for an OpenSim 4.x geometry element from <attached_geometry>.

    Sphere -> sphere (ellipsoid if scaled non-uniformly), Cylinder -> cylinder (OpenSim's axis
    is the frame's y, so ``quat`` turns MuJoCo's z onto it), Brick -> box, Ellipsoid ->
    ellipsoid; ``scale_factors`` are applied as OpenSim does when drawing. Cone, Torus,
    FrameGeometry, Arrow, Line, LineGeometry and Mesh give None, and the reason
    ('<Tag name="n">: why') is appended to ``skipped`` when given; so do a Cylinder scaled
    differently in x and z and a shape of zero size. XML comments give None without a reason.
    Unknown tags raise UnsupportedElementError.
    """
    if not isinstance(element.tag, str):  # an XML comment or processing instruction
        return None
    tag = element.tag
    name = element.get("name")

    def skip(reason: str) -> None:
        if skipped is not None:
            label = f'<{tag} name="{name}">' if name else f"<{tag}>"
            skipped.append(f"{label}: {reason}")

    if tag in _SKIPPED:
        skip(_SKIPPED[tag])
        return None
    if tag not in ("Sphere", "Cylinder", "Brick", "Ellipsoid"):
        raise _err(element, "is not a geometry type o2m knows")
    scale = np.abs(geometry_scale_factors(element))
    quat = np.array([1.0, 0.0, 0.0, 0.0])
    if tag == "Sphere":
        r = _vector(element, "radius", 1, _DEFAULTS[tag, "radius"])[0] * scale
        if np.allclose(r, r[0], rtol=1e-12, atol=0.0):
            gtype, size = "sphere", np.array([r[0], 0.0, 0.0])
        else:
            gtype, size = "ellipsoid", r
    elif tag == "Cylinder":
        r = _vector(element, "radius", 1, _DEFAULTS[tag, "radius"])[0]
        hh = _vector(element, "half_height", 1, _DEFAULTS[tag, "half_height"])[0]
        if not np.isclose(scale[0], scale[2], rtol=1e-12, atol=0.0):
            skip(f"scale_factors {scale.tolist()} make an elliptic cylinder, which MuJoCo lacks")
            return None
        gtype, size, quat = "cylinder", np.array([r * scale[0], hh * scale[1], 0.0]), _CYLINDER_QUAT.copy()
    elif tag == "Brick":
        gtype, size = "box", _vector(element, "half_lengths", 3, _DEFAULTS[tag, "half_lengths"]) * scale
    else:
        gtype, size = "ellipsoid", _vector(element, "radii", 3, _DEFAULTS[tag, "radii"]) * scale
    used = size[:1] if gtype == "sphere" else size[:2] if gtype == "cylinder" else size
    if np.any(used <= 0):
        skip(f"non-positive size {used.tolist()}")
        return None
    if np.any(used < MIN_SIZE):
        skip(f"size {used.tolist()} below {MIN_SIZE:g} m, which MuJoCo's XML writer leaves out (as 0)")
        return None
    rgba, visible = geometry_appearance(element)
    frame = element.findtext("socket_frame")
    return GeomSpec(type=gtype, size=size, quat=quat, rgba=rgba, name=name,
                    frame=frame.strip() if frame is not None else None, visible=visible)
