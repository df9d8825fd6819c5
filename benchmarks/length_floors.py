"""Benchmark: each missed length of a converted model against the floor OpenSim's own steps set.

    python benchmarks/length_floors.py [--model mobl_arms] [--quick] [--seed 0] [--poses 100]
                                       [--xml CONVERTED.xml]

Converts the model (full size unless ``--quick``; or takes ``--xml``, a conversion of it), compares
its muscle-tendon lengths with OpenSim's (:func:`o2m.validate.compare_muscles`, ``--poses`` poses
drawn with ``--seed``) and prints, for each path over the 1 % target, its worst error and the
floor no continuous tendon can beat: half the largest step of OpenSim's length found along one
coordinate from the defaults, through the path's worst pose, or along lines from it
(:mod:`o2m.validate.floors`). docs/muscle-paths.md's table of the wrapped MoBL-ARMS is its output.
"""

from __future__ import annotations

import argparse
import tempfile
import time

from o2m import models
from o2m.convert import ConvertOptions, convert
from o2m.validate import compare_muscles
from o2m.validate.floors import length_misses


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", default="mobl_arms")
    ap.add_argument("--quick", action="store_true", help="the quick wrap fit, as CI converts")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--poses", type=int, default=100)
    ap.add_argument("--xml", help="an existing conversion of the model (no conversion then)")
    args = ap.parse_args()

    fetched = models.fetch_model_with_geometry(args.model, progress=False)
    with tempfile.TemporaryDirectory() as tmp:
        xml = args.xml or convert(fetched.osim, tmp, ConvertOptions(quick=args.quick, workers=2),
                                  geometry_dirs=[fetched.geometry_dir]).xml
        report = compare_muscles(fetched.osim, xml, n_poses=args.poses, seed=args.seed, ma_poses=0)
        t0 = time.perf_counter()
        misses = length_misses(fetched.osim, xml, report)
    print(f"{args.model}, {'quick' if args.quick else 'full size'}, {args.poses} poses, seed {args.seed}: "
          f"length floors in {time.perf_counter() - t0:.0f} s")
    print("| muscle | worst length % | floor % | along | at the floor |")
    print("|---|---|---|---|---|")
    for m in misses:
        where = m.floor_coordinate or ""
        if m.floor_through_worst and where != "a line":
            where += " (through the worst pose)"
        floor = f"{m.floor:.3g}" if m.floor is not None else "none"
        print(f"| {m.path} | {m.value:.3g} | {floor} | {where} | {'yes' if m.at_floor else ''} |")


if __name__ == "__main__":
    main()
