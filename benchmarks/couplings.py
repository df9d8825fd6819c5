"""Benchmark: what the extra joints of spline couplings cost and how they behave in simulation.

    python benchmarks/couplings.py [--models gait2354 leg6dof9musc ...] [--steps 2000]

Converts each model twice: with every skeleton coupling and path-point carrier a plain quartic
(``ConvertOptions(plain_quartics=True)``) and as o2m converts it (inner
and outer joints where a quartic misses the target or the carrier gate). For each version it
prints the degrees of freedom (nv), bodies (intermediate bodies that carry a joint's
translations, ``<body>_couplings``, included), joints and equalities, and the mean ``mj_step``
time over ``--steps`` steps of constant random muscle excitation (seed 0, from the default pose,
one thread; the best of three runs), flagged when MuJoCo found the simulation unstable. Then it
simulates each version hanging under gravity for 1 s (pelvis welded to the world, no excitation,
from the default pose) and prints, for every coupled axis, the worst difference between the
axis's MuJoCo value (the sum of its joints) and OpenSim's function of the coordinate during the
simulation, and the worst equality violation (MuJoCo's ``efc_pos`` of the equality rows) in m
or rad.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np

from o2m import models
from o2m.convert import ConvertOptions, convert
from o2m.convert.builder import MjcfBuilder
from o2m.mj.simulate import welded_at_default_pose
from o2m.osim.document import load_document
from o2m.osim.skeleton import read_skeleton

#: The converter's quick wrap-fit sizes, as CI runs it (O2M_QUICK=1).
QUICK = os.environ.get("O2M_QUICK", "") not in ("", "0")


def _convert(name: str, folder: Path, quartic: bool) -> Path:
    fetched = models.fetch_model_with_geometry(name, progress=False)
    options = ConvertOptions(plain_quartics=quartic, quick=QUICK)
    return convert(fetched.osim, folder, options, geometry_dirs=[fetched.geometry_dir]).xml


def _step_time(xml: Path, steps: int) -> tuple[float, bool]:
    """Best of three runs of ``steps`` steps from the default pose: (seconds per step, whether
    MuJoCo reported an unstable simulation in any of them)."""
    m = mujoco.MjModel.from_xml_path(str(xml))
    d = mujoco.MjData(m)
    excitation = np.random.default_rng(0).uniform(0, 1, size=m.nu)
    best, unstable = float("inf"), False
    for _ in range(3):  # the best of three runs: the machine may be busy
        mujoco.mj_resetDataKeyframe(m, d, m.key("default-pose").id)
        d.ctrl[:] = excitation
        t0 = time.perf_counter()
        for _ in range(steps):
            mujoco.mj_step(m, d)
        best = min(best, (time.perf_counter() - t0) / steps)
        unstable |= bool(d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number)
    return best, unstable


def _hanging(name: str, xml: Path) -> dict[str, tuple[float, float]]:
    """Per coupled axis: (worst |axis value - OpenSim's function|, worst equality violation)."""
    m, d = welded_at_default_pose(xml, "pelvis")
    fetched = models.fetch_model_with_geometry(name, progress=False)
    axes, _ = MjcfBuilder(read_skeleton(load_document(fetched.osim))).coupled_axes()
    names = [m.joint(i).name for i in range(m.njnt)]
    rows = {}
    for a in axes:
        parts = [a.name] + [n for n in names if n.startswith((a.name + "_inner", a.name + "_outer"))]
        rows[a.name] = (a, [m.joint(p).id for p in parts], m.joint(a.base).id)
    axis_of_eq = {e: k for e in range(m.neq) for k, (_, ids, _) in rows.items() if m.eq_obj1id[e] in ids}
    worst = {k: [0.0, 0.0] for k in rows}
    for _ in range(int(round(1.0 / m.opt.timestep))):
        mujoco.mj_step(m, d)
        for k, (a, ids, base) in rows.items():
            val = sum(d.qpos[m.jnt_qposadr[i]] - m.qpos0[m.jnt_qposadr[i]] for i in ids)
            q = d.qpos[m.jnt_qposadr[base]]
            worst[k][0] = max(worst[k][0], abs(val - float(a.rel(np.array([q]))[0])))
        for r in np.flatnonzero(d.efc_type[: d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY):
            k = axis_of_eq.get(int(d.efc_id[r]))
            if k is not None:
                worst[k][1] = max(worst[k][1], abs(float(d.efc_pos[r])))
    return {k: (v[0], v[1]) for k, v in worst.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="*", default=list(models.BUNDLED))
    ap.add_argument("--hanging", nargs="*", default=["gait2354", "leg6dof9musc"])
    ap.add_argument("--steps", type=int, default=2000)
    a = ap.parse_args()
    print(f"{'model':18s} {'version':13s} {'nv':>4s} {'bodies':>6s} {'joints':>6s} {'eqs':>4s} {'step us':>8s}")
    with tempfile.TemporaryDirectory() as tmp:
        xmls = {}
        for name in sorted(set(a.models) | set(a.hanging)):
            for quartic in (True, False):
                label = "quartic" if quartic else "extra joints"
                xml = _convert(name, Path(tmp) / f"{name}-{'q' if quartic else 'x'}", quartic)
                xmls[name, label] = xml
                if name in a.models:
                    m = mujoco.MjModel.from_xml_path(str(xml))
                    sec, unstable = _step_time(xml, a.steps)
                    print(f"{name:18s} {label:13s} {m.nv:4d} {m.nbody:6d} {m.njnt:6d} {m.neq:4d} {sec * 1e6:8.1f}"
                          + ("  (unstable: MuJoCo reset it)" if unstable else ""))
        for name in a.hanging:
            print(f"\n{name} hanging 1 s under gravity (pelvis welded): worst |axis - OpenSim(q)| / worst "
                  "equality violation")
            res = {label: _hanging(name, xmls[name, label]) for label in ("quartic", "extra joints")}
            for axis in res["quartic"]:
                q, x = res["quartic"][axis], res["extra joints"][axis]
                print(f"  {axis:28s} quartic {q[0]:.3g} / {q[1]:.3g}   extra joints {x[0]:.3g} / {x[1]:.3g}")


if __name__ == "__main__":
    main()
