"""Benchmark: wall time to convert each bundled model (median of several runs).

    python benchmarks/conversion_time.py [--repeat 3]

Prints one row per model: median and best conversion time in seconds. Every run converts
into a fresh folder, so the time includes writing the meshes' STL files.
Models come from the cache (fetched first from $O2M_MODEL_MIRROR or the registry URLs).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from o2m import models
from o2m.convert import convert


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    print(f"{'model':18s} {'median s':>9s} {'best s':>8s} {'runs':>5s}")
    for name in models.BUNDLED:
        fetched = models.fetch_model_with_geometry(name, progress=False)
        times = []
        for _ in range(a.repeat):
            with tempfile.TemporaryDirectory() as tmp:
                t0 = time.perf_counter()
                convert(fetched.osim, Path(tmp) / name, geometry_dirs=[fetched.geometry_dir])
                times.append(time.perf_counter() - t0)
        print(f"{name:18s} {statistics.median(times):9.3f} {min(times):8.3f} {len(times):5d}")


if __name__ == "__main__":
    main()
