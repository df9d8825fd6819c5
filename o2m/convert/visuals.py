"""Visual geoms: the skeleton's attached geometry (meshes and analytic shapes) on the MuJoCo bodies.

Geometry hangs from its OpenSim body's frame (metres); on ground it is mapped from OpenSim's Y-up
to MuJoCo's Z-up. Meshes are written as STL files; visual geoms have no contact and no mass.
"""

from __future__ import annotations

from pathlib import Path

import mujoco

from o2m.convert import geometry
from o2m.convert.records import BuildResult
from o2m.osim.meshes import read_mesh, write_stl
from o2m.osim.skeleton import Skeleton, Skipped
from o2m.transforms import OSIM_TO_MJ, Transform, matrix_to_quat, quat_to_matrix


def add_geometry(result: BuildResult, skel: Skeleton, bodies: dict[str, mujoco.MjsBody], mesh_dir: Path,
                 search_dirs: list[Path]) -> list[Skipped]:
    """Add the skeleton's attached geometry as visual geoms; meshes are written to ``mesh_dir`` as STL.

    Returns what was left out (missing mesh files, decorations without a MuJoCo twin).
    """
    spec = result.spec
    skipped: list[Skipped] = []
    meshes: dict[tuple[str, tuple[float, ...]], str] = {}
    used_names: set[str] = {g.name for g in spec.geoms}  # contact and wrap geoms are added before
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
                    write_stl(stl, read_mesh(src), scale=scale)
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
