"""Visual geoms: the skeleton's attached geometry (meshes and analytic shapes) on the MuJoCo bodies.

Geometry hangs from its OpenSim body's frame (metres); on ground it is mapped from OpenSim's Y-up
to MuJoCo's Z-up. Meshes are written as STL files; visual geoms have no contact and no mass.
"""

from __future__ import annotations

from pathlib import Path

import mujoco

from o2m.convert import geometry
from o2m.convert.records import BuildResult, unique_name
from o2m.errors import ModelFileError, UnsupportedElementError
from o2m.osim.meshes import read_mesh, write_stl
from o2m.osim.skeleton import Geometry, Skeleton, Skipped
from o2m.transforms import OSIM_TO_MJ, Transform, matrix_to_quat, quat_to_matrix


def add_geometry(result: BuildResult, skel: Skeleton, bodies: dict[str, mujoco.MjsBody], mesh_dir: Path,
                 search_dirs: list[Path]) -> list[Skipped]:
    """Add the skeleton's attached geometry as visual geoms; meshes are written to ``mesh_dir`` as STL.

    Returns what was left out (mesh files missing or unreadable, decorations without a MuJoCo
    twin). A geometry element with unreadable properties raises an error naming it, its file and line.
    """
    mesh_dir.mkdir(parents=True, exist_ok=True)
    adder = _GeometryAdder(result.spec, bodies, mesh_dir, search_dirs)
    for g in skel.geometry:
        try:
            adder.add(g)
        except UnsupportedElementError as exc:
            if exc.path is not None or skel.document is None:
                raise
            raise skel.document.error(g.element, exc.message) from None
    return adder.skipped


class _GeometryAdder:
    """Adds geometry elements to the spec, each mesh file written once per scale, names unique."""

    def __init__(self, spec: mujoco.MjSpec, bodies: dict[str, mujoco.MjsBody], mesh_dir: Path,
                 search_dirs: list[Path]):
        self.spec, self.bodies, self.mesh_dir, self.search_dirs = spec, bodies, mesh_dir, search_dirs
        self.skipped: list[Skipped] = []
        self.meshes: dict[tuple[str, tuple[float, ...]], str] = {}
        self.failed: dict[tuple[str, tuple[float, ...]], str] = {}  # mesh files that could not be written, why
        self.used_names: set[str] = {g.name for g in spec.geoms}  # contact and wrap geoms come first

    def unique(self, name: str) -> str:
        """``name``, or ``name_1``, ``name_2``, ... when taken."""
        return unique_name(name, self.used_names)

    def add(self, g: Geometry) -> None:
        """Add geometry ``g`` on its body (a mesh, an analytic shape, or a skip with the reason)."""
        el = g.element
        to_world = Transform(OSIM_TO_MJ) if g.body == "ground" else Transform()
        if el.tag == "Mesh":
            self.add_mesh(g, to_world)
            return
        why: list[str] = []
        prim = geometry.analytic_geom(el, why)
        if prim is None:
            self.skipped.append(Skipped(el.tag, el.get("name", ""), "; ".join(why) or "no MuJoCo twin"))
            return
        x = to_world @ g.frame @ Transform(quat_to_matrix(prim.quat), prim.pos)
        gtype = getattr(mujoco.mjtGeom, f"mjGEOM_{prim.type.upper()}")
        self.bodies[g.body].add_geom(name=self.unique(el.get("name") or el.tag.lower()), type=gtype,
                                     size=prim.size, pos=x.pos, quat=matrix_to_quat(x.rot), contype=0,
                                     conaffinity=0, group=1, density=0,
                                     rgba=prim.rgba if prim.rgba is not None else [0.8, 0.8, 0.8, 1])

    def add_mesh(self, g: Geometry, to_world: Transform) -> None:
        """A mesh geom, its file written as STL; a file that cannot be found or read is skipped."""
        el = g.element
        fname = (el.findtext("mesh_file") or "").strip()
        scale = tuple(float(v) for v in geometry.geometry_scale_factors(el))
        rgba = _rgba(el)
        asset = self.mesh_asset(el, fname, scale)
        if asset is None:
            return
        x = to_world @ g.frame
        self.bodies[g.body].add_geom(name=self.unique(el.get("name") or asset), type=mujoco.mjtGeom.mjGEOM_MESH,
                                     meshname=asset, pos=x.pos, quat=matrix_to_quat(x.rot),
                                     contype=0, conaffinity=0, group=1, density=0, rgba=rgba)

    def mesh_asset(self, el, fname: str, scale: tuple[float, ...]) -> str | None:
        """The mesh asset of file ``fname`` at ``scale`` (written on first use), or None when the
        file is missing, unreadable or has no surface (the reason goes to ``skipped``)."""
        src = geometry.find_geometry_file(fname, self.search_dirs) if fname else None
        label = el.get("name", fname)
        if src is None:
            self.skipped.append(Skipped("Mesh", label, f"mesh file '{fname}' not found in "
                                        f"{', '.join(str(d) for d in self.search_dirs)}"))
            return None
        key = (str(src), scale)
        if key in self.meshes:
            return self.meshes[key]
        if key not in self.failed:
            self.failed[key] = self.write_mesh(src, fname, scale)
        if self.failed[key]:
            self.skipped.append(Skipped("Mesh", label, self.failed[key]))
            return None
        return self.meshes[key]

    def write_mesh(self, src: Path, fname: str, scale: tuple[float, ...]) -> str:
        """Write mesh file ``src`` scaled as an STL asset; returns why it could not ("" when it could)."""
        asset = self.unique(Path(fname).stem)
        stl = self.mesh_dir / f"{asset}.stl"
        try:
            write_stl(stl, read_mesh(src), scale=scale)
        except ModelFileError as exc:  # unreadable, or not a mesh file o2m reads
            self.used_names.discard(asset)
            return f"mesh file '{fname}' cannot be read: {exc}"
        except ValueError as exc:  # a mesh with no surface (lines only, or scaled flat)
            self.used_names.discard(asset)
            return f"mesh file '{fname}' has no surface: {exc}"
        self.spec.add_mesh(name=asset, file=f"{self.mesh_dir.name}/{stl.name}",
                           inertia=mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL)
        self.meshes[(str(src), scale)] = asset
        return ""


def _rgba(el) -> list[float]:
    """A mesh's colour: its <Appearance>'s colour (bone when it has none) and opacity, clipped to
    [0, 1]; transparent when not visible. Unreadable numbers raise an error naming the mesh."""
    app = el.find("Appearance")
    rgba = [0.89, 0.85, 0.79, 1.0]  # bone
    if app is not None:
        if (app.findtext("color") or "").strip():
            rgba[:3] = [float(v) for v in geometry._vector(app, "color", 3, owner=el)]
        if (app.findtext("opacity") or "").strip():
            rgba[3] = float(geometry._vector(app, "opacity", 1, owner=el)[0])
        vis = app.findtext("visible")
        if vis is not None and vis.strip().lower() == "false":
            rgba[3] = 0.0
    return [min(max(v, 0.0), 1.0) for v in rgba]
