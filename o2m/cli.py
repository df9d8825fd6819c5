"""Command-line interface: ``python -m o2m convert|validate|fetch|run``.

Exit status is 0 on success, 1 for bad input (the message names the element and line) and 2
for wrong usage.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from .errors import O2MError


def _osim_path(arg: str, geometry: list[str]) -> tuple[Path, list[str]]:
    """A path, or the name of a bundled model (fetched into the cache with its meshes)."""
    from . import models

    if arg in models.BUNDLED:
        fetched = models.fetch_model_with_geometry(arg)
        return fetched.osim, [str(fetched.geometry_dir), *geometry]
    return Path(arg), geometry


def cmd_convert(a: argparse.Namespace) -> int:
    from .convert import convert

    osim, geometry = _osim_path(a.model, a.geometry)
    result = convert(osim, a.output, geometry_dirs=geometry)
    print(result.report.summary() if a.verbose else
          f"wrote {result.xml} ({result.report.seconds:.2f} s; {len(result.report.approximations)} "
          f"approximations, {len(result.report.skipped)} elements skipped; see "
          f"{result.xml.with_suffix('.report.txt')})")
    return 0


def cmd_validate(a: argparse.Namespace) -> int:
    from .validate import compare_kinematics

    rep = compare_kinematics(a.osim, a.xml, n_poses=a.poses, seed=a.seed, progress=True)
    print(rep.summary())
    return 0


def cmd_fetch(a: argparse.Namespace) -> int:
    from . import models

    if a.all or not a.names:
        paths = models.fetch_all()
        print(f"{len(paths)} files in {models.cache_dir()}")
    for name in a.names:
        print(models.fetch_model(name))
    return 0


def cmd_run(a: argparse.Namespace) -> int:
    """The main job: fetch every bundled model, convert it, and measure it against OpenSim."""
    from . import models
    from .convert import convert
    from .validate import compare_kinematics, format_table

    out = Path(a.out)
    poses = 20 if a.quick else a.poses
    reports, times = {}, {}
    for name in models.BUNDLED:
        fetched = models.fetch_model_with_geometry(name, progress=False)
        t0 = time.perf_counter()
        conv = convert(fetched.osim, out / name, geometry_dirs=[fetched.geometry_dir])
        times[name] = time.perf_counter() - t0
        print(f"converted {name:18s} in {times[name]:5.2f} s -> {conv.xml}")
        reports[name] = compare_kinematics(fetched.osim, conv.xml, n_poses=poses, seed=a.seed, progress=False)
    print()
    print(f"Fidelity against OpenSim over {poses} random poses per model (seed {a.seed}):")
    print(format_table(reports))
    return 0


def cmd_dataset(a: argparse.Namespace) -> int:
    """Generate the MoBL-ARMS excitation sets and their OpenSim reference trajectories."""
    from .dataset import make_dataset

    ds = make_dataset(a.out, n_sets=a.sets, seed=a.seed, timeout=a.timeout, max_workers=a.workers)
    fails = ds.failures()
    print(f"{len(ds.ok)} sets, {int(ds.ok.sum())} succeeded, {len(fails)} failed; "
          f"split {len(ds.train)} train / {len(ds.test)} test -> {a.out}")
    for i, status, reason in fails:
        print(f"  set {i}: {status}: {reason}")
    ok_times = ds.wall_time[ds.ok]
    if len(ok_times):
        print(f"OpenSim wall time per 1-s run: median {np.median(ok_times):.1f} s "
              f"(min {ok_times.min():.1f}, max {ok_times.max():.1f})")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="o2m", description="Convert OpenSim models to MuJoCo and measure their fidelity.")
    sub = p.add_subparsers(dest="command", required=True)
    c = sub.add_parser("convert", help="convert an .osim file (or a bundled model name) to MuJoCo MJCF")
    c.add_argument("model", help="path to an .osim file, or a bundled model name (see `o2m fetch --help`)")
    c.add_argument("-o", "--output", required=True, help="output folder")
    c.add_argument("--geometry", action="append", default=[], metavar="DIR", help="extra folder to search for meshes")
    c.add_argument("-v", "--verbose", action="store_true", help="print the whole conversion report")
    c.set_defaults(func=cmd_convert)
    v = sub.add_parser("validate", help="compare a converted model with OpenSim over random poses")
    v.add_argument("osim")
    v.add_argument("xml")
    v.add_argument("--poses", type=int, default=200)
    v.add_argument("--seed", type=int, default=0)
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
    d.set_defaults(func=cmd_dataset)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except O2MError as exc:
        print(f"o2m: error: {exc}", file=sys.stderr)
        return 1
