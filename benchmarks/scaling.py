"""Benchmark: conversion time against model size, on synthetic models of N muscles.

    python benchmarks/scaling.py [--sizes 10 50 200 500] [--modes quick default] [--workers 1]
    python benchmarks/scaling.py --profile 200 [--modes quick]    # cProfile of one conversion

A synthetic model is Gait10dof18musc (a full-body lower-limb model: both legs, wrap objects,
ConditionalPathPoints and MovingPathPoints) with its 18 muscles replaced by N copies, taken in
turn, each renamed, with its fixed path-point locations moved by seeded noise (sd 2 mm) and its
splines (a moving point's coordinates) scaled by 1 + N(0, 0.05), so the copies keep the
full-body model's proportions of moving points, conditional points and wraps but are distinct
paths (no fit can be reused from an identical one: o2m caches coupling fits by value).

Each conversion runs in a fresh process (``spawn``) into a fresh folder. The table gives the
seconds, the seconds per path, and the marginal seconds per path between consecutive sizes; the
last lines fit a power law t = c N^k to all sizes, and to the time above the smallest model's
(what the paths themselves cost). Linear conversion means k close to 1.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import multiprocessing
import pstats
import resource
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from lxml import etree

from o2m import models
from o2m.convert import ConvertOptions, convert

SOURCE = "gait10dof18musc"
FIXED_POINTS = ("PathPoint", "ConditionalPathPoint")
"""Path points whose ``<location>`` is perturbed (a MovingPathPoint's location is its functions)."""


def _muscles(force_set: etree._Element) -> list[etree._Element]:
    """The forces of a ForceSet's ``<objects>`` that have a path (muscles, path actuators)."""
    return [f for f in force_set.find("objects") if f.find("GeometryPath") is not None]


def synthetic_model(n_muscles: int, out: Path, *, seed: int = 0, noise: float = 0.002) -> Path:
    """Write ``out`` (.osim): the source model with its path forces replaced by ``n_muscles``
    perturbed copies (see the module docstring); ``noise`` is the location sd in metres."""
    source = models.fetch_model_with_geometry(SOURCE, progress=False).osim
    tree = etree.parse(str(source), etree.XMLParser(remove_comments=True))
    force_set = tree.getroot().find(".//ForceSet")
    originals = _muscles(force_set)
    objects = force_set.find("objects")
    for muscle in originals:
        objects.remove(muscle)
    rng = np.random.default_rng(seed)
    for k in range(n_muscles):
        copy = etree.fromstring(etree.tostring(originals[k % len(originals)]))
        suffix = f"_{k:04d}"
        copy.set("name", copy.get("name") + suffix)
        for point in copy.iter(*FIXED_POINTS):
            point.set("name", point.get("name") + suffix)
            loc = point.find("location")
            values = np.array(loc.text.split(), float) + rng.normal(0.0, noise, 3)
            loc.text = " ".join(f"{v:.6f}" for v in values)
        for point in copy.iter("MovingPathPoint", "PathWrap"):
            point.set("name", point.get("name") + suffix)
        for values in copy.iter("y"):  # a moving point's spline values, scaled by 1 + N(0, 0.05)
            if values.getparent().tag == "SimmSpline":
                scaled = np.array(values.text.split(), float) * (1.0 + rng.normal(0.0, 0.05))
                values.text = " ".join(f"{v:.8g}" for v in scaled)
        objects.append(copy)
    out.parent.mkdir(parents=True, exist_ok=True)
    tree.write(str(out), xml_declaration=True, encoding="UTF-8")
    return out


def _cpu_seconds() -> float:
    """CPU time (user + system, s) of this process and its finished children."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def _timed_conversion(osim: str, geometry_dir: str, out: str, quick: bool, workers: int) -> tuple[float, float]:
    t0, c0 = time.perf_counter(), _cpu_seconds()
    convert(osim, out, ConvertOptions(quick=quick, workers=workers), geometry_dirs=[geometry_dir])
    return time.perf_counter() - t0, _cpu_seconds() - c0


def time_conversion(osim: Path, quick: bool, workers: int) -> tuple[float, float]:
    """Wall and CPU seconds to convert ``osim`` in a fresh process (o2m's in-process caches do not
    help). On a shared machine the CPU time is the steadier measure."""
    geometry = models.fetch_model_with_geometry(SOURCE, progress=False).geometry_dir
    with (tempfile.TemporaryDirectory() as tmp,
          ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool):
        return pool.submit(_timed_conversion, str(osim), str(geometry), str(Path(tmp) / "model"),
                           quick, workers).result()


def power_law_exponent(sizes: np.ndarray, seconds: np.ndarray) -> float:
    """k of the least-squares fit log t = log c + k log N."""
    return float(np.polyfit(np.log(sizes), np.log(seconds), 1)[0])


def report(mode: str, sizes: list[int], seconds: list[float]) -> None:
    """Print one mode's table and exponents (``seconds``: one measure, wall or CPU, per size)."""
    n, t = np.array(sizes, float), np.array(seconds)
    print(f"\n{mode}")
    print(f"{'paths':>6s} {'seconds':>9s} {'s/path':>8s} {'marginal s/path':>16s}")
    for i in range(len(n)):
        marginal = (t[i] - t[i - 1]) / (n[i] - n[i - 1]) if i else float("nan")
        print(f"{int(n[i]):6d} {t[i]:9.1f} {t[i] / n[i]:8.3f} {marginal:16.3f}")
    if len(n) >= 2:
        print(f"power-law exponent, all sizes: {power_law_exponent(n, t):.2f}")
    if len(n) >= 3 and np.all(t[1:] > t[0]):
        print(f"power-law exponent of the time above the {int(n[0])}-path model: "
              f"{power_law_exponent(n[1:] - n[0], t[1:] - t[0]):.2f}")


def profile(osim: Path, quick: bool, workers: int, top: int = 30) -> None:
    """cProfile one conversion in this process; prints the top functions by own and total time."""
    geometry = models.fetch_model_with_geometry(SOURCE, progress=False).geometry_dir
    with tempfile.TemporaryDirectory() as tmp:
        profiler = cProfile.Profile()
        profiler.runcall(convert, osim, Path(tmp) / "model", ConvertOptions(quick=quick, workers=workers),
                         geometry_dirs=[geometry])
    for order in ("cumulative", "tottime"):
        text = io.StringIO()
        pstats.Stats(profiler, stream=text).sort_stats(order).print_stats(top)
        print(text.getvalue())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 50, 200, 500])
    ap.add_argument("--modes", nargs="+", choices=["quick", "default"], default=["quick", "default"])
    ap.add_argument("--workers", type=int, default=1, help="processes for the wrap fits (default 1)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--profile", type=int, metavar="N", help="profile one conversion of N paths instead")
    ap.add_argument("--keep", type=Path, help="folder to keep the synthetic models in")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = a.keep or Path(tmp)
        if a.profile:
            osim = synthetic_model(a.profile, folder / f"synthetic_{a.profile}.osim", seed=a.seed)
            profile(osim, a.modes[0] == "quick", a.workers)
            return
        files = {n: synthetic_model(n, folder / f"synthetic_{n}.osim", seed=a.seed) for n in a.sizes}
        for mode in a.modes:
            wall, cpu = [], []
            for n in a.sizes:
                w, c = time_conversion(files[n], mode == "quick", a.workers)
                wall.append(w)
                cpu.append(c)
                print(f"  {mode}: {n} paths in {w:.1f} s wall, {c:.1f} s CPU", flush=True)
            report(f"{mode} mode, wall time", a.sizes, wall)
            report(f"{mode} mode, CPU time", a.sizes, cpu)


if __name__ == "__main__":
    main()
