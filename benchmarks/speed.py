"""Benchmark: one 1-s MoBL-ARMS simulation in OpenSim 4.6 and in MuJoCo, side by side.

    python benchmarks/speed.py [--sets 5] [--repeats 5] [--other NAME=MODEL.xml ...] [--no-opensim]
                               [--save data/mobl_arms/speed.json]

On the same excitation sets: OpenSim's time (integration only), each MuJoCo model's single-thread
time (median and 10th-90th percentile over sets and repeats, and thread CPU time), their ratio,
batched rollout throughput on 1 thread and on every core (and per core), and the per-step time
broken down by MuJoCo's timers. The converted paper model comes first; ``--other`` adds models of
the same muscles, e.g. an earlier conversion or the wrapped MoBL-ARMS
(``python -m o2m convert /path/MoBL_ARMS_model_for_testing_opensim.osim out/wrapped``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from o2m.paper.speed import format_speed, measure_speed


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default="data/mobl_arms")
    ap.add_argument("--model-dir", default="out/paper")
    ap.add_argument("--sets", type=int, default=5)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--other", action="append", default=[], metavar="NAME=XML")
    ap.add_argument("--no-opensim", action="store_true", help="skip OpenSim (ratios then are nan)")
    ap.add_argument("--save")
    a = ap.parse_args(argv)
    others = dict(o.split("=", 1) for o in a.other)
    speed = measure_speed(a.data, n_sets=a.sets, model_dir=a.model_dir, batch=a.batch, repeats=a.repeats,
                          others=others, opensim=not a.no_opensim)
    print(format_speed(speed))
    if a.save:
        Path(a.save).write_text(json.dumps(speed, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
