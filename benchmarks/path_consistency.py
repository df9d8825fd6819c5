"""Benchmark: what OpenSim's own path lets a MuJoCo tendon reach, for one muscle and coordinate.

    python benchmarks/path_consistency.py [--model arm26] [--muscle TRIlong]
                                          [--coordinate r_shoulder_elev] [--n 600]

A MuJoCo tendon has one length, and its moment arm is ``-dL/dq`` of it. OpenSim's length can
step (a wrap switching on or off) and its dynamic moment arm (``computeMomentArm``, the forces
it applies) need not be ``-dL/dq`` of its length (several wraps on one segment). This sweeps the
coordinate over its range (``--n`` poses, the other coordinates at their defaults) and prints:

* OpenSim's length steps and the RMS of ``computeMomentArm - (-dL/dq)`` away from them, and the
  front of any continuous tendon: for each length tolerance p (% of OpenSim's length at every
  sweep pose), the least moment-arm error against ``computeMomentArm`` it can have
  (:func:`o2m.validate_muscles.continuous_tendon_front`);
* where o2m's conversion (quick mode when ``O2M_QUICK`` is set) sits on the same sweep.
"""

from __future__ import annotations

import argparse
import os
import tempfile

import mujoco
import numpy as np

from o2m import models
from o2m.convert import ConvertOptions, convert
from o2m.mj.posing import joint_equality_plan, pose_mujoco
from o2m.osim.pair import ModelPair
from o2m.osim.spikes import outlying_changes
from o2m.validate import continuous_tendon_front

#: The converter's quick wrap-fit sizes, as CI runs it (O2M_QUICK=1).
QUICK = os.environ.get("O2M_QUICK", "") not in ("", "0")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", default="arm26")
    ap.add_argument("--muscle", default="TRIlong")
    ap.add_argument("--coordinate", default="r_shoulder_elev")
    ap.add_argument("--n", type=int, default=600)
    args = ap.parse_args()

    fetched = models.fetch_model_with_geometry(args.model, progress=False)
    pcts = (1.0, 1.1, 1.2, 1.3, 1.5, 2.0, 3.0)
    with tempfile.TemporaryDirectory() as tmp:
        options = ConvertOptions(quick=QUICK, workers=2)
        xml = convert(fetched.osim, tmp, options, geometry_dirs=[fetched.geometry_dir]).xml
        front = continuous_tendon_front(fetched.osim, xml, args.muscle, args.coordinate, pcts=pcts, n=args.n)
        m = mujoco.MjModel.from_xml_path(str(xml))
        data, plan, tid = mujoco.MjData(m), joint_equality_plan(m), m.tendon(args.muscle).id
        pair = ModelPair(fetched.osim, xml)
        l_mj = []
        for q in front["q"]:
            pose_mujoco(m, data, {**pair.defaults, args.coordinate: float(q)}, plan=plan)
            mujoco.mj_tendon(m, data)
            l_mj.append(float(data.ten_length[tid]))
    qs, length, arm = front["q"], front["length"], front["moment_arm"]
    h = qs[1] - qs[0]
    print(f"{args.model} {args.muscle} about {args.coordinate}, {args.n} poses over [{qs[0]:.3f}, {qs[-1]:.3f}]")
    print("OpenSim length steps:")
    for s in front["steps"]:
        print(f"  at {s['at']:+.4f}: {s['height'] * 1e3:+.2f} mm (any continuous tendon >= {s['floor_pct']:.2f} % off)")
    for q in front["spikes"]:
        print(f"OpenSim length spike at {q:+.4f} (left out)")
    rms, worst = front["inconsistency_rms"] * 1e3, front["inconsistency_max"] * 1e3
    print(f"OpenSim computeMomentArm - (-dL/dq), away from steps and spikes: RMS {rms:.2f} mm, max {worst:.2f} mm")
    print("Any continuous tendon: length within p % at every pose -> least moment-arm error vs computeMomentArm")
    for p in pcts:
        f = front["front"][p]
        if f is None:
            print(f"  p = {p:.1f} %: none (below the {front['floor_pct']:.2f} % floor of the largest step)")
        else:
            print(f"  p = {p:.1f} %: {f['rms'] * 1e3:.2f} mm RMS (max {f['max'] * 1e3:.1f} mm)")
    l_mj = np.array(l_mj)
    spike = np.isin(qs, front["spikes"])
    spiky = spike[:-1] | spike[1:]
    d_mj = np.diff(l_mj)
    own = outlying_changes(d_mj)
    for k in np.flatnonzero(own):
        at = 0.5 * (qs[k] + qs[k + 1])
        print(f"o2m's tendon steps by {d_mj[k] * 1e3:+.2f} mm at {at:+.4f} (interval left out below)")
    keep = ~spiky & ~own
    err = (-d_mj / h - 0.5 * (arm[1:] + arm[:-1]))[keep]
    print(f"o2m's tendon: length within {np.max((np.abs(l_mj - length) / length)[~spike]) * 100:.2f} %, moment arm "
          f"{np.sqrt(np.mean(err**2)) * 1e3:.2f} mm RMS vs computeMomentArm")


if __name__ == "__main__":
    main()
