"""Benchmark: wall time to convert each bundled model (median of several runs).

    python benchmarks/conversion_time.py [--repeat 3]

Prints one row per model: median and best conversion time in seconds. Every run is a fresh
process (o2m caches some fits within a process, which would make repeats look faster) and
converts into a fresh folder, so the time includes writing the meshes' STL files; it excludes
importing o2m, OpenSim and MuJoCo. Quick-mode wrap fits when O2M_QUICK is set.
Models come from the cache (fetched first from $O2M_MODEL_MIRROR or the registry URLs).
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import statistics
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from o2m import models
from o2m.convert import ConvertOptions, convert

#: The converter's quick wrap-fit sizes, as CI runs it (O2M_QUICK=1).
QUICK = os.environ.get("O2M_QUICK", "") not in ("", "0")


def _timed_conversion(osim: str, geometry_dir: str, out: str) -> float:
    t0 = time.perf_counter()
    convert(osim, out, ConvertOptions(quick=QUICK), geometry_dirs=[geometry_dir])
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    print(f"{'model':18s} {'median s':>9s} {'best s':>8s} {'runs':>5s}")
    for name in models.BUNDLED:
        fetched = models.fetch_model_with_geometry(name, progress=False)
        times = []
        for _ in range(a.repeat):
            with (tempfile.TemporaryDirectory() as tmp,
                  ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool):
                times.append(pool.submit(_timed_conversion, str(fetched.osim), str(fetched.geometry_dir),
                                         str(Path(tmp) / name)).result())
        print(f"{name:18s} {statistics.median(times):9.3f} {min(times):8.3f} {len(times):5d}")


if __name__ == "__main__":
    main()
