"""Benchmark: OpenSim's Schutte1993 muscles stepped as the o2m.schutte plugin steps them, against
the tendon forces OpenSim recorded, on MoBL-ARMS's test sets.

    python benchmarks/schutte_forces.py [--sets 4]

Each muscle starts from OpenSim's initial activation and fibre length and takes the plugin's
2-ms steps (:meth:`o2m.osim.schutte.SchutteMuscle.step`) on MuJoCo's muscle-tendon lengths at
OpenSim's recorded poses, with the dataset's excitations. What is left is the muscle model's
share of the dynamics error (the path's share shows where MuJoCo's length is not OpenSim's).
Prints, per muscle, the RMS force error in % of max isometric force, largest first, and the mean.
"""

from __future__ import annotations

import argparse

import numpy as np
from tqdm.auto import tqdm

from o2m import models
from o2m.osim.schutte import schutte_muscles
from o2m.paper.passive import _along
from o2m.paper.passive_stage import initial_fibre_lengths
from o2m.paper.pipeline import DATA_DIR, load_experiment


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(DATA_DIR))
    ap.add_argument("--out", default="out/paper", help="folder of the converted model (converted if missing)")
    ap.add_argument("--sets", type=int, default=4, help="the first so many test sets")
    a = ap.parse_args()
    exp = load_experiment(a.data, a.out)
    ds, h = exp.dataset, float(exp.model.opt.timestep)
    muscles = schutte_muscles(models.fetch(ds.meta["model"]), exp.muscles)
    start = initial_fibre_lengths(exp)
    ids = [exp.model.actuator(n).id for n in exp.muscles]
    errors: dict[str, list[np.ndarray]] = {n: [] for n in exp.muscles}
    for i in tqdm(ds.test[: a.sets], desc="test sets", unit="set"):
        lengths = np.array([d.actuator_length[ids] for d in _along(exp.model, exp, i)])
        excitation = ds.activations.values[i][:, [list(ds.activations.muscles).index(n) for n in exp.muscles]]
        for j, n in enumerate(exp.muscles):
            k = ds.muscle_names.index(n)
            a_, lf, force = float(ds.opensim_activations[i, 0, k]), start[n], []
            for t in range(len(lengths) - 1):
                a_, lf = muscles[n].step(a_, lf, 0.5 * (excitation[t, j] + excitation[t + 1, j]), lengths[t + 1, j], h)
                force.append(float(muscles[n].tendon_force(lengths[t + 1, j], lf)))
            errors[n].append(np.array(force) - ds.tendon_forces[i, 1:, k].astype(float))
    rms = {n: 100 * float(np.sqrt(np.mean(np.concatenate(e) ** 2))) / muscles[n].max_isometric_force
           for n, e in errors.items()}
    print(f"{a.sets} test sets: tendon force minus OpenSim's recorded one, RMS % of max isometric force")
    for n in sorted(rms, key=rms.get, reverse=True)[:10]:
        print(f"  {n:10s} {rms[n]:7.3f}")
    values = list(rms.values())
    print(f"  mean over {len(values)} muscles {np.mean(values):.3f}, median {np.median(values):.3f}")


if __name__ == "__main__":
    main()
