"""Converting an .osim file into a MuJoCo model folder, with a conversion report.

``convert("arm26.osim", "out/")`` writes ``out/arm26.xml``, its meshes in ``out/meshes/``, and
``out/arm26.report.json`` plus ``out/arm26.report.txt``. Output is assembled in a temporary
folder and moved into place only after MuJoCo has compiled it, so a failed conversion leaves
no half-written model behind.
"""

from __future__ import annotations

import hashlib
import math
import shutil
import tempfile
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import mujoco
import numpy as np
from threadpoolctl import threadpool_limits

from o2m.convert import forces
from o2m.convert.builder import MjcfBuilder
from o2m.convert.bushing_ghost import ghosts_posed
from o2m.convert.carriers import CARRIER_AXIS_TOLERANCE
from o2m.convert.constraints import add_constraints
from o2m.convert.coordinates import unenforced_clamps
from o2m.convert.default_pose import assembled_pose, default_velocity
from o2m.convert.ellipsoid_standins import record_errors
from o2m.convert.islands import disable_single_island
from o2m.convert.lengthvia import add_length_vias
from o2m.convert.massless import check_massless
from o2m.convert.muscles import fit_muscles
from o2m.convert.pathforces import PATH_FORCE_MODES
from o2m.convert.records import Approximation
from o2m.convert.report import ConversionReport
from o2m.convert.step_options import choose_step_options
from o2m.convert.tendons import DISABLED_MUSCLE_GROUP, add_paths, tendon_length_ranges
from o2m.convert.visuals import add_geometry
from o2m.convert.wrap_choice import split_variants
from o2m.convert.wrap_split import add_wrap_splits, describe_kept, narrow_wrap_ranges, split_sites
from o2m.convert.wrapfit import apply_fits, fit_paths
from o2m.convert.wraps import restore_geom_precision
from o2m.errors import O2MError
from o2m.mj import mjcf_text
from o2m.osim.document import load_document
from o2m.osim.paths import MUSCLE_TYPES, read_paths, read_wrap_objects
from o2m.osim.skeleton import SkeletonReader, Skipped, read_skeleton

MESH_FOLDER = "meshes"


@dataclass
class Conversion:
    """Result of :func:`convert`: the written MJCF path and the report."""

    xml: Path
    report: ConversionReport


@dataclass(frozen=True)
class ConvertOptions:
    """How :func:`convert` converts; the defaults give the most faithful model.

    Attributes:
        fit_mechanics: fit each muscle actuator's force-length-velocity parameters to OpenSim's
            forces (:func:`o2m.convert.muscles.fit_muscles`); without it muscles get MuJoCo's defaults.
        fit_wraps: fit the wrap geoms and side sites of every path with wrapping or conditional
            points to OpenSim's lengths and moment arms (:func:`o2m.convert.wrapfit.fit_paths`).
        length_vias: replace the wraps that share one path segment, where one coordinate moves it,
            by a moving via point of designed length (:mod:`o2m.convert.lengthvia`), and split
            the other shared segments by fixed via points (:mod:`o2m.convert.wrap_split`).
        path_forces: for a path with a MovingPathPoint next to a point of its own body, whether the
            tendon is OpenSim's length or OpenSim's force transmission (``"auto"``, ``"opensim"``,
            ``"kinematic"``; see :mod:`o2m.convert.tendons`). The report records each choice.
        quick: the wrap fits' small sizes (:data:`o2m.convert.wrapfit.QUICK`), for tests and CI.
        workers: processes for the wrap fits (None: every core).
        plain_quartics: every coupling (skeleton splines, moving path points) one quartic joint
            equality, without the extra joints that bring it within its target: fewer degrees
            of freedom, larger recorded errors (``benchmarks/couplings.py`` compares both).
        carrier_tolerance: how far (m) a moving path point may leave its locus so that its
            carrier needs fewer slides (a line or a plane; none: the point fixed) or shares
            another point's carrier (:mod:`o2m.convert.carriers`). The default, 1 micrometre,
            is exact; a larger one gives a faster, approximate model (the report's notes name
            every point it changed).
        bushing_tolerance: the worst deflection error (rad or m) a BushingForce's best linear fit
            in its coordinates may have and still convert to fixed tendons or a joint spring
            (:mod:`o2m.convert.bushings`). None, the default, converts linear ones to those and
            the others to a ghost body welded to the bushing's second frame
            (:mod:`o2m.convert.bushing_ghost`); the report records each bushing's measured error.
        chain_shortcuts: hang a body that only translates relative to an ancestor as one
            coordinate moves (its chain's rotations cancel: MoBL-ARMS's scapphant) from that
            ancestor by slides of the coordinate (:mod:`o2m.convert.shortcuts`): the same poses
            within the skeleton couplings' target, fewer joints above its subtree.
        clamped_limits: give clamped coordinates MuJoCo hard limits at their range. OpenSim
            enforces a clamped range only when it sets or assembles values, not in forward
            dynamics, so the default (False) leaves every joint unlimited, as OpenSim simulates.
        blas_threads: BLAS threads per process while converting (None: the library's own, one
            per core). The fits' matrices are small (a length via point's least squares solves a
            1083 x 15 SVD thousands of times), where threads only wait on each other: one SVD
            took 0.19 ms on one thread and 4.7 ms on two of a shared 2-core machine.
    """

    fit_mechanics: bool = True
    fit_wraps: bool = True
    length_vias: bool = True
    path_forces: str = "auto"
    quick: bool = False
    workers: int | None = None
    plain_quartics: bool = False
    carrier_tolerance: float = CARRIER_AXIS_TOLERANCE
    bushing_tolerance: float | None = None
    chain_shortcuts: bool = True
    clamped_limits: bool = False
    blas_threads: int | None = 1

    def __post_init__(self):
        if self.path_forces not in PATH_FORCE_MODES:
            raise ValueError(f"path_forces must be one of {', '.join(PATH_FORCE_MODES)}, not {self.path_forces!r}")
        if not 0.0 <= self.carrier_tolerance < float("inf"):
            raise ValueError(f"carrier_tolerance must be a distance in metres >= 0, not {self.carrier_tolerance!r}")
        if self.bushing_tolerance is not None and not 0.0 <= self.bushing_tolerance < float("inf"):
            raise ValueError(f"bushing_tolerance must be None or >= 0 (rad or m), not {self.bushing_tolerance!r}")
        if self.blas_threads is not None and self.blas_threads < 1:
            raise ValueError(f"blas_threads must be None or >= 1, not {self.blas_threads!r}")


def convert(osim: str | Path, out_dir: str | Path, options: ConvertOptions = ConvertOptions(),  # noqa: B008 (frozen)
            *, geometry_dirs: Sequence[str | Path] = (), name: str | None = None) -> Conversion:
    """Convert ``osim`` into ``out_dir/<stem>.xml`` (MuJoCo 4.0 MJCF) with its meshes and report.

    ``geometry_dirs`` are extra folders searched for mesh files after the model's own folder and
    its ``Geometry/`` subfolder, as OpenSim searches; ``name`` replaces the file's stem. Raises an
    :class:`~o2m.errors.O2MError` subclass for bad input; nothing is written then.
    """
    with threadpool_limits(limits=options.blas_threads, user_api="blas"):  # forked workers inherit it
        return _convert(osim, out_dir, options, geometry_dirs, name)


def _convert(osim: str | Path, out_dir: str | Path, options: ConvertOptions, geometry_dirs: Sequence[str | Path],
             name: str | None) -> Conversion:
    """:func:`convert`, within its BLAS thread limit."""
    t0 = time.perf_counter()
    osim = Path(osim)
    out_dir = Path(out_dir)
    stem = name or osim.stem
    doc = load_document(osim)
    skel = read_skeleton(doc)
    builder = MjcfBuilder(skel, plan_couplings=not options.plain_quartics, shortcuts=options.chain_shortcuts,
                          clamped_limits=options.clamped_limits)
    result = builder.build()
    result.notes += unenforced_clamps(skel, options.clamped_limits)
    result.notes += [f"coordinate '{c}' of joint '{j}' is MuJoCo joint '{n}' (another joint has a coordinate "
                     f"'{c}'; MuJoCo names are unique)" for j, c, n in skel.names.renamed()]
    constraint_eqs = add_constraints(builder)
    massless = check_massless(skel, builder, osim)
    reader = SkeletonReader(doc)
    reader.names = skel.names
    paths = read_paths(reader, builder.ref)
    wraps = read_wrap_objects(reader)
    wrap_skipped = _unused_wraps(wraps, paths)
    narrow_wrap_ranges(builder, paths, wraps, str(osim))
    vias = add_length_vias(builder, paths, wraps, str(osim)) if options.length_vias else []
    splits = add_wrap_splits(builder, paths, wraps, str(osim)) if options.length_vias else []
    tendons = add_paths(builder, paths, wraps, path_forces=options.path_forces,
                        carrier_tolerance=options.carrier_tolerance)
    # after the muscles: their actuators stay first
    force_conv = forces.add_forces(builder, reader, bushing_tolerance=options.bushing_tolerance)
    muscle_skipped, muscle_warnings = _fit_mechanics(result, osim, paths, doc) if options.fit_mechanics and any(
        p.owner_type in MUSCLE_TYPES for p in paths) else ([], [])
    search = [osim.parent, osim.parent / "Geometry"] + [Path(d) for d in geometry_dirs]
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
        if options.fit_wraps and tendons.path_geoms:
            t_fit = time.perf_counter()
            xml0 = restore_geom_precision(builder.restore_precision(spec.to_xml()), tendons.exact)
            designed: dict[str, list] = {}
            for v in vias:
                designed.setdefault(v.path, []).append(v)
            fits = fit_paths(osim, xml0, tendons.path_geoms, workers=options.workers, held=tendons.held,
                             quick=options.quick,
                             designed=designed, vias=split_sites(splits),
                             variants=split_variants(splits, tendons.path_geoms))
            apply_fits(spec, fits, builder.exact, tendons.exact)
            record_errors(result.approximations, fits, tendons.path_geoms)
            describe_kept(splits, {f.tendon: set(f.dropped) for f in fits},
                          {(g.tendon, g.source): g.geom for g in tendons.path_geoms})
            model = spec.compile()
            fit_seconds = time.perf_counter() - t_fit
        _set_length_ranges(spec, model, builder)
        forces.fit_ligaments(force_conv, spec, model, builder)
        forces.fit_contacts(force_conv, spec, model, builder)
        key_qpos = assembled_pose(model, skel, osim, result, constraint_eqs)
        key_qvel = default_velocity(model, builder, key_qpos, result)
        spec.add_key(name="default-pose", qpos=key_qpos, qvel=key_qvel, act=_default_activations(model, result))
        final = spec.compile()
        if disable_single_island(spec, final):
            result.notes.append("constraint islands disabled (<flag island=\"disable\"/>): the degrees of freedom "
                                "are one kinematic tree, or trees tied together by joint equalities, so MuJoCo's "
                                "island search would always find one island")
        result.notes += choose_step_options(spec, final, mujoco.__version__)
        xml_path = stage / f"{stem}.xml"
        xml_text = forces.restore_precision(builder.restore_precision(_relative_meshdir(spec.to_xml())), force_conv)
        xml_text = _default_pose(restore_geom_precision(xml_text, tendons.exact), key_qpos, key_qvel)
        _check_finite(xml_text, osim)
        xml_path.write_text(xml_text)
        written = _load_written(xml_path, osim)
        if any(b.ghost_body for b in force_conv.bushings):  # posed on the written numbers, to round-off
            xml_path.write_text(_default_pose(xml_text, ghosts_posed(written, force_conv.bushings, key_qpos)))
            written = _load_written(xml_path, osim)
        forces.measure(force_conv, written, osim, builder)
        warnings = massless + [f"{s.element} {s.name}: {s.reason}" for s in geom_skipped if s.element == "Mesh"]
        warnings += [f"Coordinate {c.name}: prescribed motion (a function of time) not converted; its MuJoCo "
                     "joint is free" for c in skel.coordinates.values() if c.prescribed and not c.locked]
        warnings += _divergence(written) + muscle_warnings
        report = ConversionReport(
            model=skel.name, source=str(osim), source_version=doc.version, xml=str(out_dir / f"{stem}.xml"),
            seconds=time.perf_counter() - t0,
            counts={"bodies": len(skel.bodies), "joints": len(skel.joints), "coordinates": len(skel.coordinates),
                    "couplers": len(skel.couplers), "markers": len(skel.markers),
                    "mujoco joints": model.njnt, "mujoco equalities": model.neq, "meshes": model.nmesh,
                    "geoms": model.ngeom, "other forces": force_conv.converted},
            joints=result.joints, approximations=result.approximations,
            skipped=[s for s in skel.skipped if (s.element, s.name) not in force_conv.handled]
            + force_conv.skipped + geom_skipped + muscle_skipped + wrap_skipped, notes=result.notes,
            warnings=warnings,
            path_fits=[f.to_dict() for f in fits], path_fit_seconds=fit_seconds, path_forces_mode=options.path_forces,
            path_forces=[asdict(r) for r in tendons.path_forces],
            length_vias=[asdict(v) for v in vias])
        report.write(stage, stem)
        _publish(stage, out_dir, stem)
    return Conversion(out_dir / f"{stem}.xml", report)


def _unused_wraps(wraps: dict, paths: list) -> list[Skipped]:
    """The wrap objects no converted path wraps over, each a :class:`Skipped` (a wrap object only
    bends the paths that list it, so leaving it out changes nothing)."""
    used = {w.wrap for p in paths for w in p.wraps}
    return [Skipped(w.element.tag if w.element is not None else "WrapObject", name,
                    "no converted path wraps over it (it bends only the paths that list it): nothing changes")
            for name, w in wraps.items() if name not in used]


#: The muscle properties an error about a fit out of scale quotes.
_MUSCLE_SCALE = ("max_isometric_force", "optimal_fiber_length", "tendon_slack_length")


def _fit_mechanics(result, osim: Path, paths: list, doc) -> tuple[list[Skipped], list[str]]:
    """Fit every muscle actuator to OpenSim's muscle forces; record each fit's error. A fit MuJoCo
    would refuse is an error naming the muscle (of ``paths``) and its line. Returns the muscles
    skipped and a warning for each fit no better than a guess (:func:`_doubtful_fit`)."""
    fits = fit_muscles(osim)
    elements = {p.owner: p.element for p in paths}
    by_note: dict[str, list[str]] = {}  # the fits' notes (activation and force-velocity mappings), muscles sharing one
    damped: dict[str, float] = {}
    for act in result.spec.actuators:
        p = fits.get(act.name)
        if p is None:
            continue
        why = p.unloadable()
        if why:
            el = elements[p.name]
            props = ", ".join(f"{k} {el.findtext(k).strip()}" for k in _MUSCLE_SCALE if el.find(k) is not None)
            raise doc.error(el, f"fits a MuJoCo muscle MuJoCo cannot load ({why}): its properties are out of "
                                f"scale ({props})")
        p.apply_to(act)
        if p.damping > 0.0 and act.group != DISABLED_MUSCLE_GROUP:
            result.spec.tendon(act.target).damping = [p.damping, 0.0, 0.0]
            damped[p.name] = p.damping
        if math.isfinite(p.default_activation) and p.default_activation > 0.0:
            result.activations[act.name] = float(np.clip(p.default_activation, p.min_activation, 1.0))
        result.approximations.append(Approximation(
            p.type, p.name, "MuJoCo muscle force-length fitted to OpenSim's tendon force (rigid tendon)",
            float(max(p.err_active_max_pct, p.err_passive_max_pct)), "% of max isometric force",
            f"active rms {p.err_active_rms_pct:.2f} %, passive rms {p.err_passive_rms_pct:.2f} %"))
        for note in p.notes:
            by_note.setdefault(note, []).append(p.name)
    result.notes += [f"{_muscle_list(names)}: {note}" for note, names in by_note.items()]
    if damped:
        result.notes.append(
            f"{_muscle_list(sorted(damped))}: OpenSim's fiber damping (a passive force, Millard's default 0.1) is "
            f"their tendons' damping, {min(damped.values()):.4g} to {max(damped.values()):.4g} N s/m (fiber_damping "
            f"F cos²α / (vmax lopt), rigid tendon, α at the optimal fiber length)")
    started = sorted(n for n in result.activations if n in fits)
    if started:
        result.notes.append(f"{_muscle_list(started)}: the 'default-pose' keyframe's act starts each at its "
                            "activation in OpenSim's default state (mj_resetDataKeyframe; mj_resetData starts "
                            "every activation at 0)")
    doubtful = [w for w in (_doubtful_fit(p) for p in fits.values()) if w]
    return list(fits.skipped), doubtful


#: A muscle's force-length fit whose worst error is over this (% of max isometric force) is no
#: better than a guess, and the conversion says so (a rigid tendon's curves leave less on any
#: muscle of the corpus; docs/conversion.md).
DOUBTFUL_FIT_PCT = 100.0


def _doubtful_fit(p) -> str | None:
    """A warning for the fitted muscle ``p`` (:class:`~o2m.convert.muscles.MuscleParams`) where OpenSim
    gave forces at under half the lengths fitted, or the fit's worst error passes :data:`DOUBTFUL_FIT_PCT`:
    a MuJoCo muscle written from that is no model of OpenSim's (a muscle on a slider with OpenSim's
    default ±10 m range, its length 0 at rest)."""
    finite = int(np.sum(np.isfinite(p.opensim_active))) if p.opensim_active is not None else 0
    worst = max(p.err_active_max_pct, p.err_passive_max_pct)
    if p.opensim_active is not None and finite < 0.5 * len(p.opensim_active):
        why = f"OpenSim gave its force at only {finite} of the {len(p.opensim_active)} lengths fitted"
    elif worst > DOUBTFUL_FIT_PCT:
        why = f"its force-length fit is {worst:.3g} % of max isometric force off OpenSim's at worst"
    else:
        return None
    return (f"{p.type} {p.name}: {why} over its lengthrange {p.lengthrange[0]:.4g}-{p.lengthrange[1]:.4g} m: "
            "check its properties and its coordinates' ranges (see the report's notes)")


def _muscle_list(names: list[str], shown: int = 4) -> str:
    """``names`` for a note: all of them, or the first few and how many there are."""
    if len(names) <= shown:
        return ", ".join(names)
    return f"{len(names)} muscles ({', '.join(names[:shown])}, ...)"


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
    root = mjcf_text.parse(xml)
    for comp in root.iter("compiler"):
        if comp.get("meshdir") is not None:
            comp.set("meshdir", ".")
    return mjcf_text.to_text(root)


def _default_pose(xml: str, qpos0, qvel=None) -> str:
    """MJCF text whose ``default-pose`` keyframe holds ``qpos0`` (nq,) and, if given and not all
    zero, ``qvel`` (nv,) in full precision."""
    root = mjcf_text.parse(xml)
    for key in root.iter("key"):
        if key.get("name") == "default-pose":
            key.set("qpos", mjcf_text.number_text(qpos0))
            if qvel is not None and np.any(qvel):
                key.set("qvel", mjcf_text.number_text(qvel))
    return mjcf_text.to_text(root)


def _default_activations(model: mujoco.MjModel, result) -> np.ndarray:
    """The ``default-pose`` keyframe's ``act`` (na,): each muscle's activation in OpenSim's default
    state (``result.activations``), 0 for every other activation state."""
    act = np.zeros(model.na)
    for name, a in result.activations.items():
        aid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
        if aid >= 0 and model.actuator_actadr[aid] >= 0:
            act[model.actuator_actadr[aid]] = a
    return act


def _load_written(xml_path: Path, osim: Path) -> mujoco.MjModel:
    """The written file, as a user will load it."""
    try:
        return mujoco.MjModel.from_xml_path(str(xml_path))
    except Exception as exc:
        raise O2MError(f"{osim}: the written MJCF does not load in MuJoCo: {exc}") from exc


def _check_finite(xml: str, osim: Path) -> None:
    """Raise an O2MError when a number of the MJCF text ``xml`` is NaN or infinite (the checks on
    the input should have refused what led there; MuJoCo would load it and fail in simulation)."""
    bad = mjcf_text.non_finite(xml)
    if bad:
        tag, name, attr, text = bad[0]
        what = f'<{tag} name="{name}">' if name else f"<{tag}>"
        raise O2MError(f"{osim}: the converted model has a number that is not finite ({what} {attr}=\"{text}\", "
                       f"{len(bad)} attribute(s) in all); o2m should have refused the input that led there: "
                       f"please report it")


#: Steps (MuJoCo's 2 ms each) the written model is simulated for, without controls, to check that it does not diverge.
STABILITY_STEPS = 100
_DIVERGED = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQACC)


def _divergence(model: mujoco.MjModel) -> list[str]:
    """A warning (in a list) when ``model`` diverges within :data:`STABILITY_STEPS` steps from its
    default pose without controls (MuJoCo then resets it); none when it does not. A number of the
    input far out of scale (a default value of 1e7 m, a max isometric force of 1e8 N) passes
    every check on the input and gives such a model; so does a massless model."""
    data = mujoco.MjData(model)
    for _ in range(STABILITY_STEPS):
        mujoco.mj_step(model, data)
        bad = [w.name for w in _DIVERGED if data.warning[int(w)].number]
        if bad:
            return [f"the converted model diverges in MuJoCo {data.time:.3f} s after its default pose without "
                    f"controls ({', '.join(bad)}): a number of the input may be far out of scale"]
    return []


def _publish(stage: Path, out_dir: Path, stem: str) -> None:
    """Move the staged files into ``out_dir``; the MJCF goes last so it appears only when complete."""
    out_dir.mkdir(parents=True, exist_ok=True)
    if (stage / MESH_FOLDER).exists():
        (out_dir / MESH_FOLDER).mkdir(exist_ok=True)
        for f in (stage / MESH_FOLDER).iterdir():
            shutil.move(str(f), out_dir / MESH_FOLDER / f.name)
    for suffix in (".report.json", ".report.txt", ".xml"):
        if (stage / f"{stem}{suffix}").exists():
            shutil.move(str(stage / f"{stem}{suffix}"), out_dir / f"{stem}{suffix}")


#: The sources whose change changes a conversion (with o2m's version): what :func:`conversion_key` hashes.
_CONVERTER_SOURCES = ("convert", "osim", "mj", "transforms.py", "errors.py")


def conversion_key(osim: str | Path, options: ConvertOptions) -> str:
    """A hash of what decides a conversion's output: the ``.osim`` file's bytes, ``options``, o2m's
    and MuJoCo's versions (:mod:`o2m.convert.step_options` depends on the latter) and the
    converter's source files (sha256, hex)."""
    import o2m

    h = hashlib.sha256()
    h.update(Path(osim).read_bytes())
    h.update(repr(options).encode())
    h.update(o2m.__version__.encode())
    h.update(mujoco.__version__.encode())
    root = Path(__file__).resolve().parents[1]
    for name in _CONVERTER_SOURCES:
        for f in sorted((root / name).rglob("*.py")) if (root / name).is_dir() else [root / name]:
            h.update(f.read_bytes())
    return h.hexdigest()


def convert_once(osim: str | Path, out_dir: str | Path, options: ConvertOptions = ConvertOptions(),  # noqa: B008
                 *, geometry_dirs: Sequence[str | Path] = ()) -> Path:
    """:func:`convert`, unless ``out_dir`` already holds this conversion (same :func:`conversion_key`,
    kept in ``<stem>.key`` beside the MJCF); returns the MJCF path either way."""
    osim, out_dir = Path(osim), Path(out_dir)
    xml, key_file = out_dir / f"{osim.stem}.xml", out_dir / f"{osim.stem}.key"
    key = conversion_key(osim, options)
    if xml.exists() and key_file.exists() and key_file.read_text().strip() == key:
        return xml
    xml = convert(osim, out_dir, options, geometry_dirs=geometry_dirs).xml
    key_file.write_text(key + "\n")
    return xml
