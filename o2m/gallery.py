"""The model gallery: convert the whole public corpus and write ``docs/models.md`` from what was measured.

``python -m o2m gallery`` converts every ``.osim`` of opensim-models and MoBL-ARMS with its
wrist free (fetched from the registry), each in its own process with a time limit, compares it
with OpenSim (K1: body frames; K2: muscle-tendon lengths; K3: moment arms, RMS per muscle and
coordinate), renders a thumbnail, and writes one table and one section per model. The page is
generated; it is never edited by hand. Its numbers are those of the options it states.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path, PurePosixPath

from o2m import models

__all__ = ["CORPUS_EXTRA", "GalleryRow", "corpus", "model_names", "run_gallery", "targets_verdict", "write_page"]

#: Corpus files beyond opensim-models' Models folder (registry paths).
CORPUS_EXTRA = ("mobl-arms/MoBL_ARMS_model_for_mujoco.osim",)

#: One model, in a fresh process: convert, compare, write the row as JSON on the last line.
_WORKER = r"""
import json, sys, time
from pathlib import Path
from o2m import compare_kinematics, compare_muscles, models
from o2m.convert import ConvertOptions, convert
from o2m.validate.floors import target_misses
from o2m.validate.muscles import MA_MEDIAN_MM
registry_path, out, quick, poses = sys.argv[1], Path(sys.argv[2]), sys.argv[3] == "1", int(sys.argv[4])
fetched = models.fetch_model_with_geometry(registry_path, progress=False)
cache = str(fetched.osim)[: -len(registry_path)]  # this machine's model cache, not for the page
t0 = time.perf_counter()
conv = convert(fetched.osim, out, ConvertOptions(quick=quick), geometry_dirs=[fetched.geometry_dir])
row = {"seconds": time.perf_counter() - t0, "xml": str(conv.xml), "approximations": len(conv.report.approximations),
       "skipped": sorted({f"{s.element}: {s.reason}".replace(cache, "<cache>/") for s in conv.report.skipped}),
       "notes": conv.report.notes[:6], "counts": conv.report.counts}
k = compare_kinematics(fetched.osim, conv.xml, n_poses=poses, seed=0)
row.update(k1_mm=k.max_pos_error * 1e3, k1_deg=float(k.max_ang_error) * 57.29577951308232, k1_ok=bool(k.ok()))
try:
    m = compare_muscles(fetched.osim, conv.xml, n_poses=poses, seed=0)
    if m.muscles:
        row.update(k2_pct=m.max_len_pct, k3_median_mm=m.ma_median * 1e3, k3_p95_mm=m.ma_p95 * 1e3,
                   k3_max_mm=m.ma_max * 1e3, muscles=len(m.muscles), spikes_left_out=len(m.opensim_spikes),
                   k3_median_ok=m.ma_median * 1e3 <= MA_MEDIAN_MM)
        misses = target_misses(fetched.osim, conv.xml, m)
        built = {a.name for a in conv.report.approximations if a.floor}  # no construction o2m tried meets them
        row["misses"] = [{"text": x.describe(), "at_floor": x.at_floor, "value": x.value, "target": x.target,
                          "floor": x.floor, "construction": not x.at_floor and x.path in built} for x in misses]
except Exception as exc:  # a model without paths, or a comparison that cannot run: say so
    row["k2_error"] = f"{type(exc).__name__}: {exc}"[:300]
print("ROW " + json.dumps(row, default=float))
"""

#: Render a thumbnail offscreen (EGL): a fresh process, so the GL backend is chosen before MuJoCo loads.
_THUMB = r"""
import sys
import mujoco, numpy as np
from PIL import Image
m = mujoco.MjModel.from_xml_path(sys.argv[1])
d = mujoco.MjData(m)
mujoco.mj_forward(m, d)
r = mujoco.Renderer(m, 240, 320)
cam = mujoco.MjvCamera()
mujoco.mjv_defaultFreeCamera(m, cam)
cam.azimuth, cam.elevation = 135.0, -15.0
opt = mujoco.MjvOption()
# frame what is drawn (bodies and the geoms of groups 0-2), not the extent MuJoCo computes
# from every geom: a fitted wrap sphere of metres would leave the model a speck
shown = m.geom_group <= 2
pts = np.vstack([d.xpos[1:], d.geom_xpos[shown]]) if m.nbody > 1 else d.geom_xpos[shown]
if len(pts):
    lo, hi = pts.min(0), pts.max(0)
    cam.lookat[:] = (lo + hi) / 2
    reach = np.linalg.norm(pts - cam.lookat, axis=1).max() + (m.geom_rbound[shown].max() if shown.any() else 0.0)
    cam.distance = 2.5 * max(reach, 0.05)
r.update_scene(d, cam, opt)
Image.fromarray(r.render()).save(sys.argv[2])
"""


@dataclass
class GalleryRow:
    """One model of the gallery: where it came from and what was measured (units in the names)."""

    model: str
    source: str
    status: str  # "converted", or the error that stopped it
    seconds: float = 0.0
    measured: dict = field(default_factory=dict)
    thumbnail: str = ""


def corpus(registry: models.Registry | None = None) -> list[str]:
    """Registry paths of every corpus model: opensim-models' Models folder, then :data:`CORPUS_EXTRA`."""
    registry = registry or models.get_registry()
    osm = sorted(p for p in registry.paths if p.startswith("opensim-models/Models/") and p.endswith(".osim"))
    return osm + [p for p in CORPUS_EXTRA if p in registry]


def _last_line(text: str, prefix: str) -> str | None:
    return next((ln[len(prefix):] for ln in reversed(text.splitlines()) if ln.startswith(prefix)), None)


def _error_line(text: str) -> str:
    lines = [ln for ln in text.strip().splitlines() if ln.strip()]
    hit = next((ln for ln in reversed(lines) if "Error" in ln.split(":")[0]), lines[-1] if lines else "no output")
    return hit.strip()[:300]


def model_names(paths: list[str]) -> dict[str, str]:
    """A unique name per registry path: the file's stem, with its folder where two stems agree
    (``Gait2392_Simbody-subject01``)."""
    stems = [PurePosixPath(p).stem for p in paths]
    return {p: (f"{PurePosixPath(p).parent.name}-{s}" if stems.count(s) > 1 else s)
            for p, s in zip(paths, stems, strict=True)}


def _one(registry_path: str, name: str, out: Path, *, quick: bool, poses: int, timeout: float) -> GalleryRow:
    row = GalleryRow(name, registry_path, "converted")
    t0 = time.perf_counter()
    try:
        res = subprocess.run([sys.executable, "-c", _WORKER, registry_path, str(out / name), "1" if quick else "0",
                              str(poses)], capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        row.status, row.seconds = f"stopped after the {timeout:.0f} s limit", timeout
        return row
    found = _last_line(res.stdout, "ROW ")
    if found is None:
        row.status, row.seconds = _error_line(res.stderr or res.stdout), time.perf_counter() - t0
        return row
    row.measured = json.loads(found)
    row.seconds = float(row.measured.pop("seconds"))
    return row


def _thumbnail(xml: str, png: Path) -> str:
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    png.parent.mkdir(parents=True, exist_ok=True)
    res = subprocess.run([sys.executable, "-c", _THUMB, xml, str(png)], capture_output=True, text=True, env=env,
                         timeout=300)
    return str(png) if res.returncode == 0 and png.exists() else ""


def run_gallery(out: str | os.PathLike = "out/gallery", docs: str | os.PathLike = "docs", *, quick: bool = False,
                poses: int = 50, timeout: float = 1800.0, only: list[str] | None = None,
                progress: bool = True) -> list[GalleryRow]:
    """Convert and measure every corpus model (or those whose names are in ``only``), render the
    thumbnails into ``docs/models/`` and write ``docs/models.md``; returns the rows."""
    from tqdm.auto import tqdm

    out, docs = Path(out), Path(docs)
    names = model_names(corpus())
    paths = [p for p, n in names.items() if only is None or n in only or PurePosixPath(p).stem in only]
    rows = []
    for registry_path in tqdm(paths, desc="gallery", unit="model", disable=not progress):
        row = _one(registry_path, names[registry_path], out, quick=quick, poses=poses, timeout=timeout)
        if row.measured.get("xml"):
            row.thumbnail = _thumbnail(row.measured["xml"], docs / "models" / f"{row.model}.png")
        rows.append(row)
    settings = {"quick": quick, "poses": poses}
    if only is not None:  # a partial run updates its models in the last run's rows, in corpus order
        rows = _merged(out / "gallery.json", rows, list(names.values()), settings)
    (out / "gallery.json").parent.mkdir(parents=True, exist_ok=True)
    (out / "gallery.json").write_text(json.dumps({**settings, "rows": [asdict(r) for r in rows]}, indent=1,
                                                 default=float))
    write_page(rows, docs / "models.md", quick=quick, poses=poses)
    return rows


def _merged(previous: Path, rows: list[GalleryRow], order: list[str], settings: dict) -> list[GalleryRow]:
    """``rows`` in place of the same models' rows of an earlier run's ``gallery.json`` made with the
    same ``settings`` (none if there is no such run: the page then lists ``rows`` alone)."""
    earlier = json.loads(previous.read_text()) if previous.exists() else {}
    if not isinstance(earlier, dict):  # a run from before the settings were kept: which ones is unknown
        earlier = {}
    made_with = {k: earlier.get(k) for k in settings}
    if earlier and made_with != settings:
        raise ValueError(f"{previous} was made with {made_with}, not {settings}: run the whole gallery, or the "
                         "same settings")
    by_name = {r["model"]: GalleryRow(**r) for r in earlier.get("rows", [])}
    by_name.update({r.model: r for r in rows})
    return [by_name[n] for n in order if n in by_name]


def _fmt(v, spec: str = ".3g") -> str:
    return "" if v is None else format(v, spec)


def targets_verdict(measured: dict) -> str:
    """``met``, ``OpenSim floors`` (every miss is one no tendon can avoid) or ``missed`` (some
    miss is o2m's, counted apart where the converter found no construction within the targets),
    from a gallery row's measurements; empty for a model that did not convert."""
    if "k1_ok" not in measured:
        return ""
    misses = measured.get("misses", [])
    if not measured["k1_ok"] or not measured.get("k3_median_ok", True):
        return "**missed**"
    if not misses:
        return "met"
    own = sum(not x["at_floor"] for x in misses)
    built = sum(x.get("construction", False) for x in misses)
    if own == 0:
        return "OpenSim floors"
    floor = f", {built} of them its constructions' floor" if built else ""
    return f"**missed** ({own} of {len(misses)} o2m's{floor})"


def write_page(rows: list[GalleryRow], page: Path, *, quick: bool, poses: int) -> None:
    """``docs/models.md``: the table (K1 to K3, seconds) and one section per model."""
    ok = sum(r.status == "converted" for r in rows)
    lines = ["# The model gallery", "",
             "Generated by `python -m o2m gallery`: every model of the public corpus converted with "
             f"`ConvertOptions(quick={quick})` and compared with OpenSim 4.6 over {poses} random poses (seed 0). "
             "Do not edit by hand.", "",
             f"{ok} of {len(rows)} models convert.", "",
             "K1: worst body position (mm) and orientation (°) error. K2: worst muscle-tendon length error (%). "
             "K3: moment-arm RMS error per muscle and coordinate, median / p95 / max (mm). OpenSim's own failures "
             "(one-pose spikes, short bands, detours past a path point, loops round a wrap, lengths not of the "
             "path OpenSim draws) are left out and counted. Targets: K1 within 0.1 mm and 0.05°, K2 within "
             "1 %, K3 within 0.5 / 2 / 5 mm; `OpenSim floors` where every miss is one OpenSim's own path "
             "forces on any tendon (its length steps, or its moment arm is not the derivative of its "
             "length; `o2m.validate.floors`), listed in the model's section with o2m's own; of o2m's, those "
             "of a path for which the converter found no construction within the targets (the report's "
             "approximations marked `floor`) are counted apart. Seconds: "
             "wall-clock conversion time on the machine that generated this page.", "",
             "| model | converts | K1 mm | K1 ° | K2 % | K3 median / p95 / max mm | OpenSim failures left out "
             "| targets | seconds |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        m = r.measured
        k3 = (f"{_fmt(m.get('k3_median_mm'))} / {_fmt(m.get('k3_p95_mm'))} / {_fmt(m.get('k3_max_mm'))}"
              if "k3_median_mm" in m else "no muscles")
        status = "yes" if r.status == "converted" else "**no**"
        lines.append(f"| [{r.model}](#{r.model.lower()}) | {status} | {_fmt(m.get('k1_mm'))} | {_fmt(m.get('k1_deg'))} "
                     f"| {_fmt(m.get('k2_pct'))} | {k3} | {m.get('spikes_left_out', '')} | {targets_verdict(m)} "
                     f"| {r.seconds:.1f} |")
    for r in rows:
        lines += ["", f"## {r.model}", "", f"`{r.source}`", ""]
        if r.thumbnail:
            lines += [f"![{r.model}](models/{Path(r.thumbnail).name})", ""]
        if r.status != "converted":
            lines += [f"Does not convert: `{r.status}`"]
            continue
        m = r.measured
        lines.append(f"Converted in {r.seconds:.1f} s: {', '.join(f'{v} {k}' for k, v in m['counts'].items())}; "
                     f"{m['approximations']} approximations (each with its measured error in the report).")
        if m.get("skipped"):
            lines += ["", "Skipped (what the report says each skip changes):"]
            lines += [f"- {s}" for s in m["skipped"]]
        if m.get("misses"):
            lines += ["", "Targets missed, each with the floor OpenSim's own path sets:"]
            lines += [f"- {x['text']}" + (" (no construction o2m tried is within the targets: see the report's "
                                          "approximations)" if x.get("construction") else "") for x in m["misses"]]
        if m.get("k2_error"):
            lines += ["", f"Muscle comparison did not run: `{m['k2_error']}`"]
    page.parent.mkdir(parents=True, exist_ok=True)
    page.write_text("\n".join(lines) + "\n")
