"""Benchmark: mutation testing of the converter at scale, counts by outcome.

    python benchmarks/mutations.py [-n 300] [--seed 1] [--timeout 120] [--out DIR] [--show refused]

Mutates Tug_of_War and a two-body model with a muscle and a wrap cylinder (built with the OpenSim
API, as ``tests/convert/test_bad_input.py`` builds it) ``-n`` times (see ``tests/mutations.py``:
numbers made NaN, infinite, 1e300, negative or zero, words for numbers, elements removed or
duplicated, components renamed), converts each in a worker process and prints the count of each
outcome (converted and simulated, refused with an O2MError, or a bug: crashed, unstable, left
files, or hung: not done in ``--timeout`` seconds), by mutation kind, then every bug, and with
``--show`` the messages of the outcomes named. CI runs a few dozen of these
(``tests/convert/test_mutations.py``); the models come from ``$O2M_MODEL_MIRROR``.
"""

from __future__ import annotations

import argparse
import collections
import multiprocessing
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the tests' helpers

from tests.mutations import GOOD, Mutation, Outcome, describe, mutations, run, sources  # noqa: E402


def run_all(todo: list[Mutation], folder: Path, timeout: float) -> list[Outcome]:
    """Each mutation's outcome, converted in one worker process; a conversion that takes more than
    ``timeout`` seconds is ``hung`` (its worker is ended and another started)."""
    ctx = multiprocessing.get_context("fork")
    pool = ctx.Pool(1)
    out = []
    try:
        for i, m in enumerate(todo):
            job = pool.apply_async(run, (m, folder / f"m{i:04d}"))
            try:
                out.append(job.get(timeout))
            except multiprocessing.TimeoutError:
                out.append(Outcome(m, "hung", f"not done in {timeout:g} s"))
                pool.terminate()
                pool = ctx.Pool(1)
    finally:
        pool.terminate()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-n", type=int, default=300, help="mutated documents")
    ap.add_argument("--seed", type=int, default=1, help="seed of the mutations (CI uses 0)")
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds a conversion may take")
    ap.add_argument("--out", default=None, help="folder for the conversions (default: a temporary one)")
    ap.add_argument("--show", nargs="*", default=[], help="outcome kinds whose messages to print")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="o2m-mutations-") as tmp:
        folder = Path(args.out or tmp)
        docs = sources(folder / "sources")
        t0 = time.perf_counter()
        outcomes = run_all(mutations(docs, args.n, args.seed), folder, args.timeout)
        seconds = time.perf_counter() - t0
    counts = collections.Counter(o.kind for o in outcomes)
    by_kind = collections.Counter((o.mutation.kind, o.kind) for o in outcomes)
    print(f"{len(outcomes)} mutations (seed {args.seed}) in {seconds:.0f} s:",
          ", ".join(f"{k} {v}" for k, v in counts.most_common()))
    for kind in sorted({o.mutation.kind for o in outcomes}):
        print(f"  {kind:10s}", ", ".join(f"{o} {n}" for (k, o), n in sorted(by_kind.items()) if k == kind))
    for o in outcomes:
        if o.kind not in GOOD or o.kind in args.show:
            print(describe(o))


if __name__ == "__main__":
    main()
