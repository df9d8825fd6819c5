"""Benchmark: how close MuJoCo can follow OpenSim on MoBL-ARMS when it is given OpenSim's own
muscle forces, and how much a small force error moves the joints.

    python benchmarks/force_sensitivity.py [--data data/mobl_arms] [--sets test]

The converted model's muscles become force motors (:func:`o2m.mujoco_sim.force_driven`) driven
by the tendon forces OpenSim recorded (N, linear between the 2-ms samples), from each set's
OpenSim initial state. What is left against OpenSim's joint trajectories is what the skeleton,
the muscle paths (moment arms) and the passive forces leave: the floor that no fit of the muscle
model can go below. Then the same runs with the forces perturbed (all 1 % and 3 % stronger, each
muscle 1 % off at random with seed 0, 1 N more on every muscle), against the unperturbed
force-driven run: how strongly a 1-s open-loop trajectory amplifies a force error.
Prints mean absolute joint errors (rad) per DoF and their mean.
"""

from __future__ import annotations

import argparse

import numpy as np

from o2m.mj.simulate import controls_from_forces, force_driven, initial_state, rollout
from o2m.paper.pipeline import DATA_DIR, load_experiment


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(DATA_DIR))
    ap.add_argument("--out", default="out/paper", help="folder of the converted model (converted if missing)")
    ap.add_argument("--sets", choices=["test", "train", "all"], default="test")
    a = ap.parse_args()
    exp = load_experiment(a.data, a.out)
    ds = exp.dataset
    sets = {"test": ds.test, "train": ds.train, "all": [int(i) for i in np.flatnonzero(ds.ok)]}[a.sets]
    model = force_driven(exp.xml, exp.muscles)
    cols = [ds.muscle_names.index(m) for m in exp.muscles]
    forces = ds.tendon_forces[sets][:, :, cols].astype(float)  # (B, T, muscles), N
    init = np.stack([initial_state(model, dict(zip(ds.coordinate_names, ds.coordinates[i, 0], strict=True)),
                                   speeds=dict(zip(ds.coordinate_names, ds.speeds[i, 0], strict=True)))
                     for i in sets])

    def run(f: np.ndarray) -> np.ndarray:
        tr = rollout(model, init, controls_from_forces(model, exp.muscles, f), joint_names=exp.dofs)
        if tr.diverged.any():
            print(f"  ({int(tr.diverged.sum())} runs diverged)")
        return tr.coordinates

    def row(label: str, err: np.ndarray) -> None:
        per = np.mean(err, axis=(0, 1))
        print(f"{label:34s}" + "".join(f"{e:9.4f}" for e in per) + f"{np.mean(per):9.4f}")

    print(f"MoBL-ARMS, {len(sets)} {a.sets} sets, mean absolute joint error (rad)")
    print(f"{'':34s}" + "".join(f"{d[:8]:>9s}" for d in exp.dofs) + f"{'mean':>9s}")
    base = run(forces)
    ref = exp.reference[sets]
    row("OpenSim's forces vs OpenSim", np.abs(base - ref))
    for horizon in (0.1, 0.25, 0.5):
        k = int(round(horizon / (ds.times[1] - ds.times[0]))) + 1
        row(f"  ... over the first {horizon} s", np.abs(base[:, :k] - ref[:, :k]))
    rng = np.random.default_rng(0)
    for label, f in [("forces x 1.01 vs unperturbed", forces * 1.01),
                     ("forces x 1.03 vs unperturbed", forces * 1.03),
                     ("each muscle 1 % off vs unperturbed", forces * (1 + 0.01 * rng.standard_normal(forces.shape[2]))),
                     ("forces + 1 N vs unperturbed", forces + 1.0)]:
        row(label, np.abs(run(f) - base))


if __name__ == "__main__":
    main()
