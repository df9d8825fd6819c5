"""Command-line interface: ``python -m o2m convert|validate|fetch|run``.

Exit status is 0 on success, 1 for bad input (the message names the element and line) and 2
for wrong usage.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

from o2m.errors import O2MError


def _osim_path(arg: str, geometry: list[str]) -> tuple[Path, list[str]]:
    """A path, or the name of a bundled model (fetched into the cache with its meshes)."""
    from o2m import models

    if arg in models.BUNDLED:
        fetched = models.fetch_model_with_geometry(arg)
        return fetched.osim, [str(fetched.geometry_dir), *geometry]
    return Path(arg), geometry


def _quick(a: argparse.Namespace) -> bool:
    """Quick mode: ``--quick``, or ``O2M_QUICK`` set to anything but 0 (as CI does)."""
    return bool(getattr(a, "quick", False)) or os.environ.get("O2M_QUICK", "") not in ("", "0")


def cmd_convert(a: argparse.Namespace) -> int:
    from o2m.convert import ConvertOptions, convert
    from o2m.validate.sweeps import format_moment_arm_report, moment_arm_report

    osim, geometry = _osim_path(a.model, a.geometry)
    quick = _quick(a)
    try:
        options = ConvertOptions(path_forces=a.path_forces, length_vias=not a.no_length_vias, quick=quick,
                                 workers=a.workers, bushing_tolerance=a.bushing_tolerance,
                                 clamped_limits=a.clamped_limits,
                                 **({} if a.carrier_tolerance is None else {"carrier_tolerance": a.carrier_tolerance}))
    except ValueError as exc:
        raise SystemExit(f"o2m convert: {exc}") from None
    result = convert(osim, a.output, options, geometry_dirs=geometry)
    print(result.report.summary() if a.verbose else
          f"wrote {result.xml} ({result.report.seconds:.2f} s; {len(result.report.approximations)} "
          f"approximations, {len(result.report.skipped)} elements skipped, {len(result.report.warnings)} "
          f"warnings; see {result.xml.with_suffix('.report.txt')})")
    if not a.verbose:
        _print_warnings(result.report.warnings)
    if a.opensim_muscles:
        from o2m.convert.opensim_muscles import write_opensim_muscles
        from o2m.mj.schutte_plugin import load

        lib = load(result.xml.parent)
        own = write_opensim_muscles(osim, result.xml)
        print(f"wrote {own.xml}: {len(own.muscles)} muscles are OpenSim's own (the o2m.schutte plugin, {lib}; "
              "load it with o2m.mj.schutte_plugin.load before opening the file)"
              + (f"; {len(own.kept)} stay MuJoCo muscles ({', '.join(sorted(set(own.kept.values())))})"
                 if own.kept else "")
              + (f"; {len(own.disabled)} that OpenSim disables stay disabled MuJoCo muscles" if own.disabled else "")
              + (f"; {len(own.offsets)} tendons are not OpenSim's length at the default pose (up to "
                 f"{1e3 * max(map(abs, own.offsets.values())):.3g} mm), their fibres start in equilibrium on MuJoCo's"
                 if own.offsets else ""))
    if a.moment_arm_plots:
        pdf = result.xml.with_suffix(".moment_arms.pdf")
        rows = moment_arm_report(osim, result.xml, pdf, n=21 if quick else 41,
                                 title=f"{result.report.model}: moment arms (mm)")
        if rows:
            print(f"moment arms over one-coordinate sweeps -> {pdf}; each path's worst pair, max |MuJoCo - OpenSim| "
                  "in mm:" if a.verbose else f"moment-arm plots -> {pdf}")
            if a.verbose:
                print("\n".join(format_moment_arm_report(rows)))
    return 0


#: The conversion's warnings printed after its one-line summary; the report lists them all.
SHOWN_WARNINGS = 5


def _print_warnings(warnings: list[str]) -> None:
    """The first :data:`SHOWN_WARNINGS` of a conversion's ``warnings`` on stderr."""
    for w in warnings[:SHOWN_WARNINGS]:
        print(f"warning: {w}", file=sys.stderr)
    if len(warnings) > SHOWN_WARNINGS:
        print(f"warning: ... and {len(warnings) - SHOWN_WARNINGS} more (see the report)", file=sys.stderr)


def cmd_validate(a: argparse.Namespace) -> int:
    if a.dynamics:
        return _validate_dynamics(a)
    from o2m.validate import compare_kinematics

    rep = compare_kinematics(a.osim, a.xml, n_poses=a.poses, seed=a.seed, progress=True)
    print(rep.summary())
    return 0


def _validate_dynamics(a: argparse.Namespace) -> int:
    """``validate --dynamics``: the same excitations in both simulators; exit 1 if no set compares."""
    from o2m.errors import ValidationError
    from o2m.osim.simulate import read_initial_state
    from o2m.validate.dynamics import compare_dynamics

    try:
        start = read_initial_state(a.initial_state) if a.initial_state else None
    except ValueError as exc:  # a states file in degrees
        raise ValidationError(str(exc)) from None
    rep = compare_dynamics(a.osim, a.xml, n_sets=a.sets, duration=a.duration, seed=a.seed, motion=a.motion,
                           initial_state=start, timeout=a.timeout, max_workers=a.workers, progress=True)
    print(rep.summary())
    if a.plot:
        print(f"plot -> {rep.plot(a.plot)}")
    if not rep.compared().any():
        print("o2m: error: no OpenSim run gave a sample to compare", file=sys.stderr)
        return 1
    return 0


def cmd_fetch(a: argparse.Namespace) -> int:
    from o2m import models

    if a.all or not a.names:
        paths = models.fetch_all()
        print(f"{len(paths)} files in {models.cache_dir()}")
    for name in a.names:
        print(models.fetch_model(name))
    return 0


def cmd_run(a: argparse.Namespace) -> int:
    """The main job: fetch every bundled model, convert it, and measure it against OpenSim."""
    from o2m import models
    from o2m.convert import ConvertOptions, convert
    from o2m.validate import compare_kinematics, format_table

    out = Path(a.out)
    options = ConvertOptions(quick=_quick(a))
    poses = 20 if a.quick else a.poses
    reports, times = {}, {}
    for name in models.BUNDLED:
        fetched = models.fetch_model_with_geometry(name, progress=False)
        t0 = time.perf_counter()
        conv = convert(fetched.osim, out / name, options, geometry_dirs=[fetched.geometry_dir])
        times[name] = time.perf_counter() - t0
        print(f"converted {name:18s} in {times[name]:5.2f} s -> {conv.xml}")
        reports[name] = compare_kinematics(fetched.osim, conv.xml, n_poses=poses, seed=a.seed, progress=False)
    print()
    print(f"Fidelity against OpenSim over {poses} random poses per model (seed {a.seed}):")
    print(format_table(reports))
    return 0


def cmd_dataset(a: argparse.Namespace) -> int:
    """Generate the MoBL-ARMS excitation sets and their OpenSim reference trajectories."""
    from o2m.paper.dataset import make_dataset

    ds = make_dataset(a.out, n_sets=a.sets, seed=a.seed, timeout=a.timeout, max_workers=a.workers,
                      opensim_log=a.opensim_log)
    fails = ds.failures()
    print(f"{len(ds.ok)} sets, {int(ds.ok.sum())} succeeded, {len(fails)} failed; "
          f"split {len(ds.train)} train / {len(ds.test)} test / {len(ds.validation)} validation -> {a.out}")
    for i, status, reason in fails:
        print(f"  set {i}: {status}: {reason}")
    ok_times = ds.wall_time[ds.ok]
    if len(ok_times):
        print(f"OpenSim wall time per 1-s run: median {np.median(ok_times):.1f} s "
              f"(min {ok_times.min():.1f}, max {ok_times.max():.1f})")
    return 0


def cmd_paper(a: argparse.Namespace) -> int:
    """The whole paper (:func:`o2m.paper.reproduce`); prints the measured numbers."""
    from o2m.paper.reproduce import format_summary, reproduce

    executor = None
    if a.dask:
        from distributed import Client  # pip install -e .[cluster]

        executor = Client(a.dask).get_executor()
        print(f"      OpenSim runs and CMA-ES candidates go to the Dask scheduler at {a.dask}")
    run = reproduce(a.data, a.out, a.figures, quick=a.quick, regenerate_opensim=a.regenerate_opensim,
                    refit=a.refit, executor=executor, n_sets=a.sets, seed=a.seed, timeout=a.timeout)
    print()
    print(format_summary(run))
    return 0


def cmd_gallery(a: argparse.Namespace) -> int:
    """Convert the whole public corpus and write docs/models.md (:mod:`o2m.gallery`)."""
    from o2m.gallery import run_gallery

    rows = run_gallery(a.out, a.docs, quick=_quick(a), poses=a.poses, timeout=a.timeout, only=a.only or None)
    ok = sum(r.status == "converted" for r in rows)
    print(f"{ok} of {len(rows)} models convert -> {Path(a.docs) / 'models.md'}")
    for r in rows:
        if r.status != "converted":
            print(f"  {r.model}: {r.status}")
    return 0


def cmd_figures(a: argparse.Namespace) -> int:
    from o2m.paper.figures import make_figures

    written = make_figures(a.results, a.figures)
    print("\n".join(map(str, written)) or "no results found")
    return 0 if written else 1


def cmd_speed(a: argparse.Namespace) -> int:
    import json

    from o2m.osim.runtime import opensim_log
    from o2m.paper.speed import measure_speed

    Path(a.opensim_log).unlink(missing_ok=True)
    with opensim_log(a.opensim_log) as log_file:
        speed = measure_speed(a.data, n_sets=a.sets)
    print(json.dumps({k: v for k, v in speed.items() if not isinstance(v, list)}, indent=1))
    print(f"OpenSim's log: {log_file}")
    if a.save:
        Path(a.save).write_text(json.dumps(speed, indent=1) + "\n")
    return 0


def cmd_replay(a: argparse.Namespace) -> int:
    """Replay an OpenSim .mot/.sto coordinate motion on a converted model, as a meshcat HTML page."""
    import mujoco

    from o2m.viz.motion import load_motion, resample_motion
    from o2m.viz.scene import animate_qpos

    model = mujoco.MjModel.from_xml_path(a.xml)
    motion = resample_motion(load_motion(a.motion, model), model, a.fps)
    animate_qpos(model, motion.qpos, fps=a.fps, html=a.output, decimate=a.decimate or None).close()
    print(f"{len(motion.times)} frames over {motion.duration:.2f} s of {len(motion.coordinates)} coordinates "
          f"-> {a.output}" + (f" (ignored columns: {', '.join(motion.unmatched[:5])}...)" if motion.unmatched else ""))
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="o2m", description="Convert OpenSim models to MuJoCo and measure their fidelity.")
    sub = p.add_subparsers(dest="command", required=True)
    c = sub.add_parser("convert", help="convert an .osim file (or a bundled model name) to MuJoCo MJCF")
    c.add_argument("model", help="path to an .osim file, or a bundled model name (see `o2m fetch --help`)")
    c.add_argument("-o", "--output", required=True, help="output folder")
    c.add_argument("--geometry", action="append", default=[], metavar="DIR", help="extra folder to search for meshes")
    c.add_argument("-v", "--verbose", action="store_true", help="print the whole conversion report")
    c.add_argument("--path-forces", choices=["auto", "opensim", "kinematic"], default="auto",
                   help="for a MovingPathPoint next to a point of its own body (along which OpenSim applies no "
                        "tension): tendon = OpenSim's length ('kinematic'), OpenSim's force transmission "
                        "('opensim'), or per muscle by how much holding the segment changes its length ('auto', "
                        "default)")
    c.add_argument("--no-length-vias", action="store_true",
                   help="keep one wrap per segment where several share it, instead of a length via point "
                        "(o2m.convert.lengthvia)")
    c.add_argument("--quick", action="store_true", help="the wrap fits' small sizes (also with O2M_QUICK=1)")
    c.add_argument("--workers", type=int, default=None, help="processes for the wrap fits (default: all cores)")
    c.add_argument("--carrier-tolerance", type=float, default=None, metavar="M",
                   help="how far (m) a moving path point may leave its locus to get a simpler carrier; above "
                        "the default (1e-6, exact) the model is faster and approximate, and the report names each "
                        "point changed")
    c.add_argument("--bushing-tolerance", type=float, default=None, metavar="RAD_OR_M",
                   help="convert a non-linear BushingForce whose best linear fit deflects at most this much "
                        "wrong to fixed tendons (default: linear ones only; the others become a ghost body "
                        "welded to the bushing's second frame); the report records each error")
    c.add_argument("--clamped-limits", action="store_true",
                   help="give clamped coordinates MuJoCo hard limits at their range (default: unlimited, as in "
                        "OpenSim's forward dynamics, which enforces a clamped range only when setting values)")
    c.add_argument("--opensim-muscles", action="store_true",
                   help="also write <stem>_opensim_muscles.xml, with each Schutte1993 muscle OpenSim's own (the "
                        "o2m.schutte MuJoCo plugin, compiled with the machine's C compiler)")
    c.add_argument("--no-moment-arm-plots", dest="moment_arm_plots", action="store_false",
                   help="skip the moment-arm sweeps against OpenSim (<stem>.moment_arms.pdf)")
    c.set_defaults(func=cmd_convert)
    v = sub.add_parser("validate", help="compare a converted model with OpenSim over random poses, or over time "
                       "under the same muscle excitations (--dynamics)")
    v.add_argument("osim")
    v.add_argument("xml")
    v.add_argument("--poses", type=int, default=200)
    v.add_argument("--seed", type=int, default=0)
    v.add_argument("--dynamics", action="store_true",
                   help="forward-simulate random excitation sets (or --motion) in both and compare coordinates")
    v.add_argument("--sets", type=int, default=3, help="random excitation sets (--dynamics)")
    v.add_argument("--duration", type=float, default=1.0, help="seconds per set (--dynamics)")
    v.add_argument("--motion", default=None, metavar="FILE",
                   help="a controls file (.sto/.mot; muscle columns = excitations, coordinate columns = initial "
                        "pose) instead of random sets (--dynamics)")
    v.add_argument("--initial-state", default=None, metavar="STO",
                   help="start from the first row of this states file (e.g. MoBL-ARMS' initial_states.sto) instead "
                        "of the default pose (--dynamics)")
    v.add_argument("--plot", default=None, metavar="PNG", help="plot OpenSim vs MuJoCo per coordinate (--dynamics)")
    v.add_argument("--timeout", type=float, default=300.0, help="wall-clock limit per OpenSim run, s (--dynamics)")
    v.add_argument("--workers", type=int, default=None, help="parallel OpenSim processes (default: all cores)")
    v.set_defaults(func=cmd_validate)
    f = sub.add_parser("fetch", help="fetch bundled models into the cache (all files when no name is given)")
    f.add_argument("names", nargs="*")
    f.add_argument("--all", action="store_true")
    f.set_defaults(func=cmd_fetch)
    r = sub.add_parser("run", help="the main job: convert every bundled model and print its fidelity table")
    r.add_argument("--out", default="out", help="output folder (default: out/)")
    r.add_argument("--poses", type=int, default=200)
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--quick", action="store_true", help="20 poses per model instead of --poses")
    r.set_defaults(func=cmd_run)
    d = sub.add_parser("dataset", help="generate the MoBL-ARMS excitation sets and OpenSim reference trajectories")
    d.add_argument("--out", default="data/mobl_arms", help="output folder (default: data/mobl_arms)")
    d.add_argument("--sets", type=int, default=100)
    d.add_argument("--seed", type=int, default=2020)
    d.add_argument("--timeout", type=float, default=600.0, help="wall-clock limit per OpenSim run, s")
    d.add_argument("--workers", type=int, default=None, help="parallel OpenSim processes (default: all cores)")
    d.add_argument("--opensim-log", default=None, help="OpenSim's log file (default: OUT/runs/opensim.log)")
    d.set_defaults(func=cmd_dataset)
    pp = sub.add_parser("paper", help="the whole paper: references, conversion, fitting, corrections, speed, figures")
    pp.add_argument("--quick", action="store_true", help="small budgets (minutes); results go to OUT/quick/")
    pp.add_argument("--data", default="data/mobl_arms", help="dataset folder (default: data/mobl_arms)")
    pp.add_argument("--out", default="out", help="scratch folder for converted models (default: out/)")
    pp.add_argument("--figures", default="figures", help="figure folder in full mode (default: figures/)")
    pp.add_argument("--regenerate-opensim", action="store_true",
                    help="rerun the OpenSim reference simulations instead of using the stored ones")
    pp.add_argument("--refit", action="store_true", help="refit even if DATA/results/parameters.json exists")
    pp.add_argument("--dask", metavar="SCHEDULER", help="a Dask scheduler address (tcp://host:8786) for the OpenSim "
                    "runs and CMA-ES candidates; every worker needs o2m and the model cache at the same path")
    pp.add_argument("--sets", type=int, default=100)
    pp.add_argument("--seed", type=int, default=2020)
    pp.add_argument("--timeout", type=float, default=600.0)
    pp.set_defaults(func=cmd_paper)
    g = sub.add_parser("gallery", help="convert the whole model corpus and write docs/models.md")
    g.add_argument("--out", default="out/gallery", help="converted models (default: out/gallery/)")
    g.add_argument("--docs", default="docs", help="where models.md and the thumbnails go (default: docs/)")
    g.add_argument("--quick", action="store_true", help="the converter's quick wrap-fit sizes")
    g.add_argument("--poses", type=int, default=50, help="random poses per comparison")
    g.add_argument("--timeout", type=float, default=1800.0, help="seconds per model")
    g.add_argument("--only", nargs="*", help="model names (file stems) to do")
    g.set_defaults(func=cmd_gallery)
    fg = sub.add_parser("figures", help="redraw the figures from stored results")
    fg.add_argument("--results", default="data/mobl_arms/results")
    fg.add_argument("--figures", default="figures")
    fg.set_defaults(func=cmd_figures)
    sp = sub.add_parser("speed", help="benchmark: one 1-s simulation in OpenSim and in MuJoCo")
    sp.add_argument("--data", default="data/mobl_arms")
    sp.add_argument("--sets", type=int, default=5)
    sp.add_argument("--save", default=None, help="write the measurements to this JSON file")
    sp.add_argument("--opensim-log", default="out/opensim-speed.log", help="OpenSim's log (default: %(default)s)")
    sp.set_defaults(func=cmd_speed)
    rp = sub.add_parser("replay", help="replay an OpenSim .mot/.sto motion on a converted model (meshcat HTML)")
    rp.add_argument("xml", help="the converted model (.xml)")
    rp.add_argument("motion", help="an OpenSim motion (.mot or .sto) with coordinate columns")
    rp.add_argument("-o", "--output", default="replay.html", help="HTML page to write (default: replay.html)")
    rp.add_argument("--fps", type=float, default=30.0, help="frames per second of the animation")
    rp.add_argument("--decimate", type=float, default=0.003, help="mesh simplification grid, m (0: none)")
    rp.set_defaults(func=cmd_replay)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except O2MError as exc:
        print(f"o2m: error: {exc}", file=sys.stderr)
        return 1
