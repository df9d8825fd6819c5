"""Benchmark: wall and CPU time to convert each bundled model (median of several runs).

    python benchmarks/conversion_time.py [--repeat 3] [--workers N] [--models NAME_OR_PATH ...]

Prints one row per model: median and best wall seconds and median CPU seconds. Every run is a
fresh process (o2m caches some fits within a process, which would make repeats look faster) and
converts into a fresh folder, so the time includes writing the meshes' STL files; it excludes
importing o2m, OpenSim and MuJoCo. CPU seconds are the converting process's user and system
time plus those of the worker processes it waited for (the wrap and muscle fits'), so on a
machine shared with other jobs they move less than wall seconds. Quick-mode wrap fits when
O2M_QUICK is set. ``--models`` takes short names (default: every bundled model) or registry
paths (``opensim-models/Models/Rajagopal/Rajagopal2016.osim``). Models come from the cache
(fetched first from $O2M_MODEL_MIRROR or the registry URLs).
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import resource
import statistics
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from o2m import models
from o2m.convert import ConvertOptions, convert

#: The converter's quick wrap-fit sizes, as CI runs it (O2M_QUICK=1).
QUICK = os.environ.get("O2M_QUICK", "") not in ("", "0")


def _cpu_seconds() -> float:
    """User and system seconds of this process and of the children it has waited for."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def _timed_conversion(osim: str, geometry_dir: str, out: str, workers: int | None) -> tuple[float, float]:
    """(wall s, CPU s) of one conversion."""
    t0, c0 = time.perf_counter(), _cpu_seconds()
    convert(osim, out, ConvertOptions(quick=QUICK, workers=workers), geometry_dirs=[geometry_dir])
    return time.perf_counter() - t0, _cpu_seconds() - c0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--workers", type=int, default=None, help="processes for the wrap fits (default: all cores)")
    ap.add_argument("--models", nargs="+", default=list(models.BUNDLED), help="short names or registry paths")
    a = ap.parse_args()
    print(f"{'model':24s} {'median s':>9s} {'best s':>8s} {'CPU s':>8s} {'runs':>5s}")
    for name in a.models:
        fetched = models.fetch_model_with_geometry(name, progress=False)
        walls, cpus = [], []
        for _ in range(a.repeat):
            with (tempfile.TemporaryDirectory() as tmp,
                  ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool):
                wall, cpu = pool.submit(_timed_conversion, str(fetched.osim), str(fetched.geometry_dir),
                                        str(Path(tmp) / Path(name).stem), a.workers).result()
            walls.append(wall)
            cpus.append(cpu)
        label = Path(name).stem if name.endswith(".osim") else name
        print(f"{label:24s} {statistics.median(walls):9.3f} {min(walls):8.3f} {statistics.median(cpus):8.2f} "
              f"{len(walls):5d}", flush=True)


if __name__ == "__main__":
    main()
