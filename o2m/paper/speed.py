"""Side-by-side speed of OpenSim and MuJoCo on the same excitation sets (a benchmark, not a test).

:func:`measure_speed` runs ``n_sets`` sets of the dataset one after another in OpenSim (in this
process, timing the integration only, not model loading) and in MuJoCo (a plain ``mj_step``
loop on one thread, and a batched :func:`o2m.mujoco_sim.rollout` on all cores), and returns the
median time of one 1-s simulation in each, their ratio, and the rollout throughput. The paper
measured OpenSim 15.50 s and MuJoCo 0.025 s, about 600x.
"""

from __future__ import annotations

import os
import platform
import time

import numpy as np

__all__ = ["measure_speed"]


def measure_speed(data_dir: str = "data/mobl_arms", *, n_sets: int = 5, model_dir: str = "out/paper",
                  batch: int = 64, progress: bool = True) -> dict:
    """Time both simulators on the first ``n_sets`` successful sets; returns a dict of seconds and ratios."""
    import mujoco
    from tqdm.auto import tqdm

    from o2m import models
    from o2m.mj.simulate import rollout, step_loop
    from o2m.osim.simulate import IntegratorSettings, read_initial_state, simulate
    from o2m.paper.pipeline import load_experiment

    exp = load_experiment(data_dir, model_dir)
    ds = exp.dataset
    sets = [int(i) for i in np.flatnonzero(ds.ok)[:n_sets]]
    osim_path = models.fetch_model(ds.meta["model"], progress=False)
    init = read_initial_state(models.fetch(ds.meta["initial_state"]))
    settings = IntegratorSettings(**ds.meta["integrator"])
    os_times, mj_times = [], []
    for i in tqdm(sets, desc="OpenSim (timed)", unit="run", disable=not progress):
        run = simulate(osim_path, ds.times, ds.activations.values[i], list(ds.activations.muscles),
                       initial_state=init, settings=settings)
        os_times.append(run.integration_time if run.ok else np.nan)
    for i in sets:
        t0 = time.perf_counter()
        step_loop(exp.model, exp.init[i], exp.controls[i], joint_names=exp.dofs)
        mj_times.append(time.perf_counter() - t0)
    idx = np.resize(np.array(sets), batch)
    rollout(exp.model, exp.init[idx[:2]], exp.controls[idx[:2]], joint_names=exp.dofs)  # warm up
    t0 = time.perf_counter()
    rollout(exp.model, exp.init[idx], exp.controls[idx], joint_names=exp.dofs)
    batch_s = time.perf_counter() - t0
    os_med, mj_med = float(np.nanmedian(os_times)), float(np.median(mj_times))
    return {"sets": sets, "opensim_s": os_times, "mujoco_s": mj_times, "opensim_median_s": os_med,
            "mujoco_median_s": mj_med, "ratio": os_med / mj_med,
            "rollout_batch": batch, "rollout_s": batch_s, "rollout_per_s": batch / batch_s,
            "rollout_threads": os.cpu_count(), "opensim_dataset_median_wall_s": float(np.median(ds.wall_time[ds.ok])),
            "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
            "mujoco_version": mujoco.__version__, "opensim_version": ds.meta.get("opensim_version")}
