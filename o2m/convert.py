"""Converting an .osim file into a MuJoCo model folder, with a conversion report.

``convert("arm26.osim", "out/")`` writes ``out/arm26.xml``, its meshes in ``out/meshes/``, and
``out/arm26.report.json`` plus ``out/arm26.report.txt``. Output is assembled in a temporary
folder and moved into place only after MuJoCo has compiled it, so a failed conversion leaves
no half-written model behind.
"""

from __future__ import annotations

import json
import shutil
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import mujoco
import numpy as np
from lxml import etree

from . import forces
from .document import load_document
from .errors import O2MError
from .lengthvia import add_length_vias
from .mjcf import Approximation, JointRecord, MjcfBuilder, add_geometry
from .paths import MUSCLE_TYPES, read_paths, read_wrap_objects
from .skeleton import SkeletonReader, Skipped, read_skeleton
from .tendons import add_paths, restore_geom_precision, tendon_length_ranges

MESH_FOLDER = "meshes"


@dataclass
class ConversionReport:
    """What a conversion did: every element converted, approximated (with its error) or skipped."""

    model: str
    source: str
    source_version: int
    xml: str
    seconds: float
    counts: dict[str, int]
    joints: list[JointRecord] = field(default_factory=list)
    approximations: list[Approximation] = field(default_factory=list)
    skipped: list[Skipped] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    #: One :class:`o2m.wrapfit.PathFit` (as a dict) per tendon whose wrap geoms were fitted.
    path_fits: list[dict] = field(default_factory=list)
    #: Seconds spent fitting wrap geoms (part of ``seconds``).
    path_fit_seconds: float = 0.0
    #: The ``path_forces`` option, and one :class:`o2m.tendons.PathForceRecord` (as a dict) per
    #: path with same-body MovingPathPoint segments: which tendon it got and what that implies.
    path_forces_mode: str = "auto"
    path_forces: list[dict] = field(default_factory=list)
    #: The moment-arm plots (``<stem>.moment_arms.pdf``: each path's worst coordinate swept, the
    #: others at their defaults) and, per path, that pair's largest error (mm) against OpenSim's
    #: computeMomentArm and against OpenSim's -dL/dq.
    moment_arm_plots: str = ""
    moment_arm_worst: list[dict] = field(default_factory=list)
    #: One :class:`o2m.lengthvia.LengthVia` (as a dict) per segment given a designed length.
    length_vias: list[dict] = field(default_factory=list)

    def to_dict(self) -> dict:
        return asdict(self)

    def summary(self) -> str:
        """A readable account of the conversion (what the .report.txt file holds)."""
        lines = [f"o2m conversion report: {self.model}",
                 f"  source   {self.source} (OpenSim document version {self.source_version})",
                 f"  output   {self.xml}",
                 f"  time     {self.seconds:.2f} s",
                 "  converted: " + ", ".join(f"{v} {k}" for k, v in self.counts.items())]
        lines.append("")
        lines.append("MuJoCo joints:")
        for j in self.joints:
            via = f" <- {j.driven_by}" if j.driven_by else ""
            lines.append(f"  {j.name:32s} {j.kind:5s} {j.opensim_joint}/{j.axis:12s} {j.relation}{via}")
        lines.extend(f"  note: {n}" for n in self.notes)
        lines.append("")
        lines.append(f"Approximations ({len(self.approximations)}):")
        for a in self.approximations:
            lines.append(f"  <{a.element} {a.name}> {a.what}: worst error {a.max_error:.3g} {a.units}"
                         + (f" ({a.detail})" if a.detail else ""))
        if not self.approximations:
            lines.append("  none: the MuJoCo kinematics are exact")
        lines.append("")
        lines.append(f"Skipped ({len(self.skipped)}):")
        by_reason: dict[str, list[str]] = {}
        for s in self.skipped:
            by_reason.setdefault(s.reason, []).append(f"{s.element} {s.name}".strip())
        for reason, items in by_reason.items():
            shown = ", ".join(items[:8]) + (f", ... ({len(items)} in all)" if len(items) > 8 else "")
            lines.append(f"  {reason}: {shown}")
        if self.path_forces:
            lines.append("")
            lines.append(f"Path forces ({self.path_forces_mode}; same-body MovingPathPoint segments, along which "
                         f"OpenSim applies no tension):")
            for r in self.path_forces:
                arms = ", ".join(f"{c} {v:.3g}" for c, v in r["moment_arm_mm"].items())
                lines.append(f"  {r['path']:12s} {r['mode']:9s} segments vary {r['variation_mm']:.3g} mm "
                             f"({r['variation_pct']:.3g} % of {r['shortest_mm']:.4g} mm); length error "
                             f"{r['length_error_mm']:.3g} mm ({r['length_error_pct']:.3g} %); computeMomentArm - "
                             f"(-dL/dq) up to [mm] {arms}")
        if self.moment_arm_worst:
            lines.append("")
            lines.append(f"Moment arms over one-coordinate sweeps ({self.moment_arm_plots}), each path's worst pair, "
                         f"max |MuJoCo - OpenSim| in mm (or dimensionless for a translation):")
            for r in self.moment_arm_worst:
                lines.append(f"  {r['muscle']:16s} {r['coordinate']:22s} vs computeMomentArm "
                             f"{r['max_error_mm']:8.3g}   vs -dL/dq {r['max_error_vs_dldq_mm']:8.3g}")
        if self.path_fits:
            from .wrapfit import PathFit, format_fits

            fits = [PathFit(**f) for f in self.path_fits]
            lines.append("")
            lines.append(f"Wrap fits ({len(fits)} tendons, {sum(f.accepted for f in fits)} improved, "
                         f"{self.path_fit_seconds:.1f} s; OpenSim -dL/dq over {fits[0].poses} poses):")
            lines.extend(format_fits(fits))
        if self.warnings:
            lines.append("")
            lines.append("Warnings:")
            lines.extend(f"  {w}" for w in self.warnings)
        return "\n".join(lines) + "\n"

    def write(self, folder: Path, stem: str) -> None:
        (folder / f"{stem}.report.json").write_text(json.dumps(self.to_dict(), indent=1, default=float))
        (folder / f"{stem}.report.txt").write_text(self.summary())


@dataclass
class Conversion:
    """Result of :func:`convert`: the written MJCF path and the report."""

    xml: Path
    report: ConversionReport


def convert(osim: str | Path, out_dir: str | Path, *, geometry_dirs: list[str | Path] | None = None,
            name: str | None = None, fit_mechanics: bool = True, fit_wraps: bool = True,
            workers: int | None = None, path_forces: str = "auto", quick: bool | None = None,
            moment_arm_plots: bool = True, length_vias: bool = True) -> Conversion:
    """Convert ``osim`` into ``out_dir/<stem>.xml`` (MuJoCo 4.0 MJCF) with its meshes and report.

    ``geometry_dirs`` are extra folders searched for mesh files after the model's own folder and
    its ``Geometry/`` subfolder, as OpenSim searches. ``fit_wraps`` fits the wrap geoms and side
    sites of every path with wrapping or conditional points to OpenSim's lengths and moment arms
    (:func:`o2m.wrapfit.fit_paths`, ``workers`` processes; its quick sizes when ``quick``, by
    default when ``O2M_QUICK`` is set).
    ``fit_mechanics`` fits each muscle
    actuator's force-length parameters to OpenSim's forces (:func:`o2m.muscles.fit_muscles`);
    without it muscles get MuJoCo's defaults. ``path_forces`` (``"auto"``, ``"opensim"``,
    ``"kinematic"``) chooses, for a path with a MovingPathPoint next to a point of its own body,
    whether the tendon is OpenSim's length or OpenSim's force transmission (see
    :mod:`o2m.tendons`); the report records each choice. ``moment_arm_plots`` writes
    ``<stem>.moment_arms.pdf`` (:func:`o2m.validate_muscles.plot_moment_arm_sweeps`; 21 values a
    sweep in quick mode, else 41) and lists each path's worst pair in the report.
    ``length_vias`` replaces the wraps that share one path segment, where one coordinate moves
    it, by a moving via point of designed length (:mod:`o2m.lengthvia`). Raises an
    :class:`~o2m.errors.O2MError`
    subclass for bad input; nothing is written then.
    """
    t0 = time.perf_counter()
    osim = Path(osim)
    out_dir = Path(out_dir)
    stem = name or osim.stem
    doc = load_document(osim)
    skel = read_skeleton(doc)
    builder = MjcfBuilder(skel)
    result = builder.build()
    reader = SkeletonReader(doc)
    paths = read_paths(reader, builder.ref)
    wraps = read_wrap_objects(reader)
    vias = add_length_vias(builder, paths, wraps, str(osim)) if length_vias else []
    tendons = add_paths(builder, paths, wraps, path_forces=path_forces)
    force_conv = forces.add_forces(builder, reader)  # after the muscles: their actuators stay first
    muscle_skipped = _fit_mechanics(result, osim) if fit_mechanics and any(
        p.owner_type in MUSCLE_TYPES for p in paths) else []
    search = [osim.parent, osim.parent / "Geometry"] + [Path(d) for d in geometry_dirs or []]
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=".o2m-", dir=out_dir.parent) as tmp:
        stage = Path(tmp)
        geom_skipped = add_geometry(result, skel, builder.bodies, stage / MESH_FOLDER, search)
        spec = result.spec
        spec.meshdir = str(stage)
        spec.compiler.LRopt.mode = mujoco.mjtLRMode.mjLRMODE_NONE  # o2m sets the length ranges itself
        try:
            model = spec.compile()
            if tendons.weigh_static_carriers(model):
                model = spec.compile()
        except Exception as exc:
            raise O2MError(f"{osim}: MuJoCo could not compile the converted model: {exc}") from exc
        fits, fit_seconds = [], 0.0
        if fit_wraps and tendons.path_geoms:
            from .wrapfit import apply_fits, fit_paths

            t_fit = time.perf_counter()
            xml0 = restore_geom_precision(builder.restore_precision(spec.to_xml()), tendons.exact)
            designed: dict[str, list] = {}
            for v in vias:
                designed.setdefault(v.path, []).append(v)
            fits = fit_paths(osim, xml0, tendons.path_geoms, workers=workers, held=tendons.held, quick=quick,
                             designed=designed)
            apply_fits(spec, fits, builder.exact, tendons.exact)
            model = spec.compile()
            fit_seconds = time.perf_counter() - t_fit
        _set_length_ranges(spec, model, builder)
        forces.fit_ligaments(force_conv, spec, model, builder)
        spec.add_key(name="default-pose", qpos=model.qpos0.copy())
        spec.compile()
        xml_path = stage / f"{stem}.xml"
        xml_text = forces.restore_precision(builder.restore_precision(_relative_meshdir(spec.to_xml())), force_conv)
        xml_text = restore_geom_precision(xml_text, tendons.exact)
        xml_path.write_text(_default_pose(xml_text, model.qpos0))
        try:  # the written file, as a user will load it
            written = mujoco.MjModel.from_xml_path(str(xml_path))
        except Exception as exc:
            raise O2MError(f"{osim}: the written MJCF does not load in MuJoCo: {exc}") from exc
        forces.measure(force_conv, written, osim, builder)
        plots, worst = "", []
        if moment_arm_plots and written.ntendon:
            from .validate_muscles import moment_arm_sweeps, plot_moment_arm_sweeps
            from .wrapfit import quick_mode

            fast = quick_mode() if quick is None else quick
            drawn = plot_moment_arm_sweeps(moment_arm_sweeps(osim, xml_path, n=21 if fast else 41),
                                           stage / f"{stem}.moment_arms.pdf", title=f"{skel.name}: moment arms (mm)")
            plots = str(out_dir / f"{stem}.moment_arms.pdf")
            scale = {True: 1.0, False: 1e3}
            worst = [{"muscle": r["muscle"], "coordinate": r["coordinate"],
                      "max_error_mm": r["max_error"] * scale[r["linear"]],
                      "max_error_vs_dldq_mm": r["max_error_vs_dldq"] * scale[r["linear"]]} for r in drawn]
        warnings = [f"{s.element} {s.name}: {s.reason}" for s in geom_skipped if s.element == "Mesh"]
        report = ConversionReport(
            model=skel.name, source=str(osim), source_version=doc.version, xml=str(out_dir / f"{stem}.xml"),
            seconds=time.perf_counter() - t0,
            counts={"bodies": len(skel.bodies), "joints": len(skel.joints), "coordinates": len(skel.coordinates),
                    "couplers": len(skel.couplers), "markers": len(skel.markers),
                    "mujoco joints": model.njnt, "mujoco equalities": model.neq, "meshes": model.nmesh,
                    "geoms": model.ngeom, "other forces": force_conv.converted},
            joints=result.joints, approximations=result.approximations,
            skipped=[s for s in skel.skipped if (s.element, s.name) not in force_conv.handled]
            + force_conv.skipped + geom_skipped + muscle_skipped, notes=result.notes, warnings=warnings,
            path_fits=[f.to_dict() for f in fits], path_fit_seconds=fit_seconds, path_forces_mode=path_forces,
            path_forces=[asdict(r) for r in tendons.path_forces], moment_arm_plots=plots, moment_arm_worst=worst,
            length_vias=[asdict(v) for v in vias])
        report.write(stage, stem)
        _publish(stage, out_dir, stem)
    return Conversion(out_dir / f"{stem}.xml", report)


def _fit_mechanics(result, osim: Path) -> list[Skipped]:
    """Fit every muscle actuator to OpenSim's muscle forces; record each fit's error."""
    from .muscles import fit_muscles

    fits = fit_muscles(osim)
    for act in result.spec.actuators:
        p = fits.get(act.name)
        if p is None:
            continue
        p.apply_to(act)
        result.approximations.append(Approximation(
            p.type, p.name, "MuJoCo muscle force-length fitted to OpenSim's tendon force (rigid tendon)",
            float(max(p.err_active_max_pct, p.err_passive_max_pct)), "% of max isometric force",
            f"active rms {p.err_active_rms_pct:.2f} %, passive rms {p.err_passive_rms_pct:.2f} %"))
    return list(fits.skipped)


def _set_length_ranges(spec: mujoco.MjSpec, model: mujoco.MjModel, builder: MjcfBuilder) -> None:
    """Give every tendon actuator without one the length range of its tendon over the coordinates' ranges."""
    todo = [a for a in spec.actuators if a.trntype == mujoco.mjtTrn.mjTRN_TENDON and not np.any(a.lengthrange)]
    if not todo:
        return
    coords = {}
    for name, (_, ax) in builder.coord_joint.items():
        if builder.drivers[name].base == name:
            coords[name] = builder.fit_range(name, ax.kind)
    ranges = tendon_length_ranges(model, coords)
    for act in todo:  # actuators whose length range no muscle fit gave
        lo, hi = ranges[model.tendon(act.target).id]
        if hi - lo < 1e-4 * max(lo, 1e-3):  # spans no free coordinate (e.g. only locked ones)
            builder.result.notes.append(f"{act.name}: tendon length constant at {lo:.6g} m over the free "
                                        f"coordinates; length range set to ±1% around it")
            lo, hi = 0.99 * lo, 1.01 * hi
        act.lengthrange = [lo, hi]


def _relative_meshdir(xml: str) -> str:
    """MJCF text with ``compiler/@meshdir`` made relative to the file (meshes sit beside it)."""
    root = etree.fromstring(xml.encode())
    for comp in root.iter("compiler"):
        if comp.get("meshdir") is not None:
            comp.set("meshdir", ".")
    return etree.tostring(root, encoding="unicode", pretty_print=True)


def _default_pose(xml: str, qpos0) -> str:
    """MJCF text whose ``default-pose`` keyframe holds ``qpos0`` in full precision."""
    root = etree.fromstring(xml.encode())
    for key in root.iter("key"):
        if key.get("name") == "default-pose":
            key.set("qpos", " ".join(f"{float(v):.17g}" for v in qpos0))
    return etree.tostring(root, encoding="unicode", pretty_print=True)


def _publish(stage: Path, out_dir: Path, stem: str) -> None:
    """Move the staged files into ``out_dir``; the MJCF goes last so it appears only when complete."""
    out_dir.mkdir(parents=True, exist_ok=True)
    if (stage / MESH_FOLDER).exists():
        (out_dir / MESH_FOLDER).mkdir(exist_ok=True)
        for f in (stage / MESH_FOLDER).iterdir():
            shutil.move(str(f), out_dir / MESH_FOLDER / f.name)
    for suffix in (".moment_arms.pdf", ".report.json", ".report.txt", ".xml"):
        if (stage / f"{stem}{suffix}").exists():
            shutil.move(str(stage / f"{stem}{suffix}"), out_dir / f"{stem}{suffix}")
