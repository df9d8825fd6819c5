"""The model corpus: which OpenSim element types each model uses, and whether it converts.

    python benchmarks/corpus.py [--mirror DIR] [--inventory] [--fast] [--out out/corpus]

Every ``.osim`` of opensim-models (``<mirror>/opensim-models/Models``) and the MoBL-ARMS files
(``<mirror>/mobl-arms``). ``--inventory`` lists each element type and the models it occurs in
(read with lxml, nothing converted). Otherwise each model is converted in its own process, with
``--fast`` skipping the muscle and wrap fits (to find what stops a conversion, not to measure
it), and one line per model says: converted in how many seconds, or the error. The mirror
defaults to ``$O2M_MODEL_MIRROR``.
"""

from __future__ import annotations

import argparse
import collections
import os
import subprocess
import sys
import time
from pathlib import Path

from lxml import etree

_CHILD = """
import sys
from o2m.convert import ConvertOptions, convert
fast = sys.argv[3] == "1"
opts = ConvertOptions(quick=True, fit_mechanics=not fast, fit_wraps=not fast, length_vias=not fast)
conv = convert(sys.argv[1], sys.argv[2], opts)
r = conv.report
print(f"OK {r.seconds:.1f} s; {len(r.approximations)} approximations, {len(r.skipped)} skipped")
"""


def corpus(mirror: Path) -> list[Path]:
    """Every .osim of the corpus, sorted."""
    models = mirror / "opensim-models" / "Models"
    return sorted(models.rglob("*.osim")) + sorted((mirror / "mobl-arms").glob("*.osim"))


def inventory(paths: list[Path]) -> dict[str, list[str]]:
    """Element type (tag) -> the models it occurs in."""
    seen: dict[str, set[str]] = collections.defaultdict(set)
    parser = etree.XMLParser(remove_comments=True, recover=True, huge_tree=False)
    for p in paths:
        text = p.read_bytes().replace(b"::", b"__")  # OpenSim writes tags like <A::B>, not XML names
        root = etree.fromstring(text, parser)
        for el in root.iter():
            if isinstance(el.tag, str) and el.tag[:1].isupper() and (el.get("name") is not None or len(el)):
                seen[el.tag].add(p.stem)
    return {k: sorted(v) for k, v in sorted(seen.items())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mirror", default=os.environ.get("O2M_MODEL_MIRROR", "../shared/models"))
    ap.add_argument("--inventory", action="store_true", help="list element types and where they occur")
    ap.add_argument("--fast", action="store_true", help="skip the muscle and wrap fits")
    ap.add_argument("--out", default="out/corpus")
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per model")
    args = ap.parse_args()
    paths = corpus(Path(args.mirror))
    if args.inventory:
        for tag, models in inventory(paths).items():
            print(f"{tag:40s} {len(models):3d}  {', '.join(models[:6])}{' ...' if len(models) > 6 else ''}")
        return
    ok = 0
    for p in paths:
        t0 = time.perf_counter()
        try:
            res = subprocess.run([sys.executable, "-c", _CHILD, str(p), str(Path(args.out) / p.stem),
                                  "1" if args.fast else "0"], capture_output=True, text=True, timeout=args.timeout)
            lines = (res.stdout + res.stderr).strip().splitlines()
            msg = next((ln for ln in reversed(lines) if ln.startswith(("OK", "o2m.", "ValueError", "Error"))),
                       lines[-1] if lines else "")
        except subprocess.TimeoutExpired:
            msg = f"timeout after {args.timeout:.0f} s"
        ok += msg.startswith("OK")
        print(f"{p.stem:48s} {time.perf_counter() - t0:7.1f} s  {msg[:160]}", flush=True)
    print(f"{ok} of {len(paths)} converted")


if __name__ == "__main__":
    main()
