"""Benchmark: OpenSim's Hunt-Crossley contact against the converted MuJoCo contact.

    python benchmarks/contact.py [--out out/contact] [--corpus] [--mirror ../shared/models]

A 1-kg ball of radius 5 cm on a PlanarJoint with its rotation locked (o2m.validate.contact),
stiffness 1e7, dissipation 0.5 s/m, friction 0.8 static / 0.6 dynamic / 0.2 s/m viscous,
transition velocity 0.1 m/s, is dropped on the half space from 0.05, 0.2 and 0.5 m (impacts at
about 1, 2 and 3.1 m/s) and slid from 1 and 2 m/s, in OpenSim 4.6 and in the converted model at
its own 2-ms step and at 0.5 ms (which separates MuJoCo's discretisation from the mapping).
Prints each metric in both simulators and the conversion report's contact approximations.

With ``--corpus`` it also converts the corpus models with contact (ToyLanding, SoccerKick,
DynamicJumper, Walker; ``quick``, no muscle or wrap fits), loads each in MuJoCo and steps it 1 s
from its default pose: pairs, contacts made, NaN or not, and the report's contact records.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import mujoco
import numpy as np

from o2m.convert import ConvertOptions, convert
from o2m.validate.contact import BallModel, compare_drop, compare_slide, write_ball_model

FAST = ConvertOptions(quick=True, fit_mechanics=False, fit_wraps=False)
BALL = BallModel(viscous_friction=0.2)
DROPS = (0.05, 0.2, 0.5)
SLIDES = (1.0, 2.0)
CORPUS = ("ToyLanding/ToyLandingModel.osim", "SoccerKick/SoccerKickingModel.osim",
          "Jumper/DynamicJumperModel.osim", "WalkerModel/WalkerModel.osim")


def ball(out: Path) -> None:
    osim = write_ball_model(out / "ball.osim", BALL)
    conv = convert(osim, out / "ball", FAST)
    print(f"ball: {BALL}")
    _print_contact_records(conv.report)
    for step in (None, 0.0005):
        label = "the model's 2-ms step" if step is None else f"a {1e3 * step:g}-ms step"
        print(f"\n== MuJoCo at {label}")
        for drop in DROPS:
            print(compare_drop(osim, conv.xml, BALL, drop, timestep=step).summary())
        for speed in SLIDES:
            print(compare_slide(osim, conv.xml, BALL, speed, timestep=step).summary())


def _print_contact_records(report) -> None:
    for a in report.approximations:
        if a.element == "HuntCrossleyForce":
            print(f"  report <{a.name}> {a.what}: {a.max_error:.3g} {a.units}  ({a.detail})")


def corpus(mirror: Path, out: Path) -> None:
    for name in CORPUS:
        src = mirror / "opensim-models" / "Models" / name
        t0 = time.perf_counter()
        conv = convert(src, out / Path(name).stem, FAST)
        seconds = time.perf_counter() - t0
        m = mujoco.MjModel.from_xml_path(str(conv.xml))
        d = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, d, 0)
        touched, first = 0, None
        for k in range(int(round(1.0 / m.opt.timestep))):
            mujoco.mj_step(m, d)
            if d.ncon and first is None:
                first = (k + 1) * m.opt.timestep
            touched = max(touched, d.ncon)
        finite = bool(np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all())
        skipped = sorted({f"{s.element} {s.name}" for s in conv.report.skipped
                          if s.element.startswith("Contact") or s.element.endswith(("CrossleyForce", "FoundationForce",
                                                                                    "HalfSpaceForce"))})
        print(f"\n== {name}: converted in {seconds:.1f} s; {m.ngeom} geoms, {m.npair} pairs; 1 s in MuJoCo: "
              f"{'finite' if finite else 'NaN'}, most contacts at once {touched}, first at "
              f"{'-' if first is None else f'{first:.3f} s'}")
        print(f"  contact elements skipped: {', '.join(skipped) or 'none'}")
        for note in conv.report.notes:
            if "contact" in note:
                print(f"  note: {note}")
        _print_contact_records(conv.report)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out/contact")
    ap.add_argument("--corpus", action="store_true", help="also convert and step the corpus contact models")
    ap.add_argument("--mirror", default=os.environ.get("O2M_MODEL_MIRROR", "../shared/models"))
    a = ap.parse_args()
    out = Path(a.out)
    ball(out)
    if a.corpus:
        corpus(Path(a.mirror), out)


if __name__ == "__main__":
    main()
