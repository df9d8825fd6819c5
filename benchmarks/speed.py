"""Benchmark: one 1-s MoBL-ARMS simulation in OpenSim 4.6 and in MuJoCo, side by side.

    python benchmarks/speed.py [--sets 5] [--save data/mobl_arms/speed.json]

Prints the median time of one simulation in each simulator (OpenSim: integration only; MuJoCo: a
plain step loop on one thread), their ratio (the paper measured about 600x), and the throughput
of batched MuJoCo rollouts on all cores. The same as ``python -m o2m speed``.
"""

from __future__ import annotations

import sys

from o2m.cli import main

if __name__ == "__main__":
    sys.exit(main(["speed", *sys.argv[1:]]))
