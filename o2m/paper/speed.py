"""Side-by-side speed of OpenSim and MuJoCo on the same excitation sets (a benchmark, not a test).

:func:`measure_speed` runs ``n_sets`` sets of the dataset in OpenSim (in this process, timing the
integration only, not model loading) and, on the same sets, every MuJoCo model given (the
converted paper model first; e.g. also an earlier conversion or the wrapped MoBL-ARMS):

* a plain ``mj_step`` loop on one thread, each set ``repeats`` times: median and 10th-90th
  percentile of the wall-clock time of one 1-s simulation, and the median thread CPU time (what a
  busy machine's other processes do not inflate); and the same simulation as one
  :func:`mujoco.rollout.rollout` on the calling thread (``c_loop_*``: MuJoCo's own C loop over the
  steps, without Python's per-step call and control copy, about 3.5 % of a MoBL-ARMS step). The
  models' loops are interleaved, set by set (:func:`interleaved_loops`), so that a load that
  comes and goes weighs on all of them alike, and each other model's thread CPU time is also
  given as the median ratio to the converted model's on the same set and repeat
  (``cpu_vs_converted``);
* the per-step time and its breakdown by MuJoCo's own timers (``mjData.timer``, microseconds);
* their ratio to OpenSim's, by wall clock and by thread CPU time;
* batched :func:`o2m.mj.simulate.rollout` throughput (simulations per second) on 1 thread and on
  every core, per core, and per CPU second of the process (what a loaded machine does not lower).

The paper measured OpenSim 15.50 s and MuJoCo 0.025 s, about 600x.
"""

from __future__ import annotations

import os
import platform
import time
from collections.abc import Mapping

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

__all__ = ["format_speed", "interleaved_loops", "measure_model", "measure_speed"]

#: MuJoCo timers reported in the per-step breakdown (``mjtTimer`` names without the prefix):
#: kinematics includes the tendons (``mj_tendon``), constraint the solver.
BREAKDOWN = ("STEP", "POS_KINEMATICS", "POS_INERTIA", "POS_MAKE", "VELOCITY", "ACTUATION", "CONSTRAINT", "ADVANCE")


def _one_loop(model: mujoco.MjModel, data: mujoco.MjData, state: np.ndarray,
              controls: np.ndarray) -> tuple[float, float]:
    """Wall and thread CPU seconds of one ``mj_step`` loop from ``state`` (nstate,) over
    ``controls`` (T - 1, nu)."""
    mujoco.mj_resetData(model, data)
    mujoco.mj_setState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    wall, cpu = time.perf_counter(), time.thread_time()
    for ctrl in controls:
        data.ctrl[:] = ctrl
        mujoco.mj_step(model, data)
    return time.perf_counter() - wall, time.thread_time() - cpu


def _one_c_loop(model: mujoco.MjModel, data: mujoco.MjData, state: np.ndarray,
                controls: np.ndarray) -> tuple[float, float]:
    """Wall and thread CPU seconds of the same simulation as :func:`_one_loop`, stepped by
    :func:`mujoco.rollout.rollout` on this thread (MuJoCo's C loop)."""
    wall, cpu = time.perf_counter(), time.thread_time()
    mj_rollout.rollout(model, data, state[None], controls[None])
    return time.perf_counter() - wall, time.thread_time() - cpu


def interleaved_loops(cases: Mapping[str, tuple[mujoco.MjModel, np.ndarray, np.ndarray]],
                      repeats: int) -> dict[str, np.ndarray]:
    """Seconds, shape (repeats * S, 4), of every set of every case (name -> (model, init (S,
    nstate), controls (S, T - 1, nu)); the same S for all): the ``mj_step`` loop's wall and thread
    CPU time, then the C loop's (:func:`_one_c_loop`); the cases' loops taking turns set by set,
    each case warmed up once first."""
    datas = {name: mujoco.MjData(model) for name, (model, _, _) in cases.items()}
    for name, (model, init, controls) in cases.items():
        _one_loop(model, datas[name], init[0], controls[0])
    n_sets = {len(init) for _, init, _ in cases.values()}
    if len(n_sets) != 1:
        raise ValueError(f"interleaved_loops needs the same number of sets for every case, not {sorted(n_sets)}")
    runs: dict[str, list[tuple[float, ...]]] = {name: [] for name in cases}
    for _ in range(repeats):
        for i in range(next(iter(n_sets))):
            for name, (model, init, controls) in cases.items():
                runs[name].append(_one_loop(model, datas[name], init[i], controls[i])
                                  + _one_c_loop(model, datas[name], init[i], controls[i]))
    return {name: np.array(r) for name, r in runs.items()}


def step_breakdown(model: mujoco.MjModel, state: np.ndarray, controls: np.ndarray, loops: int = 3) -> dict[str, float]:
    """Microseconds per step of each :data:`BREAKDOWN` timer (wall clock), the least over ``loops``
    loops (what other processes add only ever lengthens a loop)."""
    data = mujoco.MjData(model)
    out: dict[str, float] = {}
    for _ in range(loops):
        mujoco.mj_resetData(model, data)  # also zeroes the timers
        _one_loop(model, data, state, controls)
        for name in BREAKDOWN:
            us = data.timer[int(getattr(mujoco.mjtTimer, f"mjTIMER_{name}"))].duration / len(controls) * 1e6
            out[name.lower()] = min(us, out.get(name.lower(), us))
    return out


def rollout_throughput(model: mujoco.MjModel, init: np.ndarray, controls: np.ndarray,
                       nthread: int) -> tuple[float, float]:
    """Simulations per second of one batched :func:`o2m.mj.simulate.rollout` of ``init`` (B, nstate)
    and ``controls`` (B, T - 1, nu) on ``nthread`` threads (after a warm-up of two), by wall clock
    and per CPU second of this process (per core busy, what a loaded machine does not lower)."""
    from o2m.mj.simulate import rollout

    rollout(model, init[:2], controls[:2], nthread=nthread)
    wall, cpu = time.perf_counter(), time.process_time()
    rollout(model, init, controls, nthread=nthread)
    return len(init) / (time.perf_counter() - wall), len(init) / (time.process_time() - cpu)


def measure_model(model: mujoco.MjModel, init: np.ndarray, controls: np.ndarray, *, repeats: int = 5,
                  batch: int = 64, runs: np.ndarray | None = None) -> dict:
    """Speed of ``model`` on the sets ``init`` (S, nstate) and ``controls`` (S, T - 1, nu): see the
    module docstring; seconds per 1-s simulation, microseconds per step, simulations per second.
    ``runs``: its loops' seconds (n, 4) already timed (:func:`interleaved_loops`), else timed here,
    each set ``repeats`` times."""
    if runs is None:
        runs = interleaved_loops({"model": (model, init, controls)}, repeats)["model"]
    idx = np.resize(np.arange(len(init)), batch)
    cores = os.cpu_count() or 1
    rates = {n: rollout_throughput(model, init[idx], controls[idx], n) for n in sorted({1, cores})}
    per_s = {n: wall for n, (wall, _) in rates.items()}
    return {"nv": int(model.nv), "equalities": int(model.neq), "tendons": int(model.ntendon),
            "wrap_items": int(model.nwrap), "runs": len(runs),
            "median_s": float(np.median(runs[:, 0])), "p10_s": float(np.percentile(runs[:, 0], 10)),
            "p90_s": float(np.percentile(runs[:, 0], 90)), "cpu_median_s": float(np.median(runs[:, 1])),
            "c_loop_median_s": float(np.median(runs[:, 2])), "c_loop_cpu_median_s": float(np.median(runs[:, 3])),
            "step_us": step_breakdown(model, init[0], controls[0]),
            "rollout_per_s": {str(n): v for n, v in per_s.items()},
            "rollout_per_s_per_core": per_s[cores] / cores, "rollout_scaling": per_s[cores] / per_s[1],
            "rollout_per_cpu_s": {str(n): per_cpu for n, (_, per_cpu) in rates.items()}}


def initial_states(model: mujoco.MjModel, ds, sets: list[int]) -> np.ndarray:
    """Full physics states (len(sets), nstate) of ``model`` at the first sample of the dataset's ``sets``."""
    from o2m.mj.simulate import initial_state

    return np.array([initial_state(model, dict(zip(ds.coordinate_names, ds.coordinates[i, 0], strict=False)),
                                   speeds=dict(zip(ds.coordinate_names, ds.speeds[i, 0], strict=False)),
                                   activations=dict(zip(ds.muscle_names, ds.opensim_activations[i, 0], strict=False)))
                     for i in sets])


def measure_speed(data_dir: str = "data/mobl_arms", *, n_sets: int = 5, model_dir: str = "out/paper",
                  batch: int = 64, repeats: int = 5, others: Mapping[str, str] | None = None,
                  opensim: bool = True, progress: bool = True) -> dict:
    """Time OpenSim and the converted model (and ``others``: name -> MJCF path, the same muscles)
    on the first ``n_sets`` successful sets; returns a dict of seconds, ratios and throughputs."""
    from tqdm.auto import tqdm

    from o2m import models
    from o2m.mj.simulate import controls_from_excitations
    from o2m.osim.simulate import IntegratorSettings, read_initial_state, simulate
    from o2m.paper.pipeline import load_experiment

    exp = load_experiment(data_dir, model_dir)
    ds = exp.dataset
    sets = [int(i) for i in np.flatnonzero(ds.ok)[:n_sets]]
    os_times, os_cpu = [], []
    if opensim:
        osim_path = models.fetch_model(ds.meta["model"], progress=False)
        init = read_initial_state(models.fetch(ds.meta["initial_state"]))
        settings = IntegratorSettings(**ds.meta["integrator"])
        for i in tqdm(sets, desc="OpenSim (timed)", unit="run", disable=not progress):
            cpu = time.thread_time()  # this thread's CPU time, model loading included
            run = simulate(osim_path, ds.times, ds.activations.values[i], list(ds.activations.muscles),
                           initial_state=init, settings=settings)
            os_times.append(run.integration_time if run.ok else np.nan)
            os_cpu.append(time.thread_time() - cpu if run.ok else np.nan)
    os_med = float(np.nanmedian(os_times)) if os_times else float("nan")
    os_cpu_med = float(np.nanmedian(os_cpu)) if os_cpu else float("nan")
    cases = {"converted": (exp.model, exp.init[sets], exp.controls[sets])}
    for name, xml in (others or {}).items():
        model = mujoco.MjModel.from_xml_path(str(xml))
        cases[name] = (model, initial_states(model, ds, sets),
                       controls_from_excitations(model, exp.muscles, ds.activations.values[sets]))
    runs = interleaved_loops(cases, repeats)
    measured = {name: measure_model(*case, batch=batch, runs=runs[name]) for name, case in cases.items()}
    for name, m in measured.items():
        m["ratio"] = os_med / m["median_s"]
        m["cpu_ratio"] = os_cpu_med / m["cpu_median_s"]
        m["c_loop_ratio"] = os_med / m["c_loop_median_s"]
        m["cpu_vs_converted"] = float(np.median(runs[name][:, 1] / runs["converted"][:, 1]))
    main = measured["converted"]
    return {"sets": sets, "opensim_s": os_times, "opensim_median_s": os_med, "opensim_cpu_s": os_cpu,
            "opensim_cpu_median_s": os_cpu_med,
            "mujoco_median_s": main["median_s"], "ratio": main["ratio"], "rollout_batch": batch,
            "mujoco_c_loop_median_s": main["c_loop_median_s"], "c_loop_ratio": main["c_loop_ratio"],
            "rollout_per_s": main["rollout_per_s"][str(max(1, os.cpu_count() or 1))], "models": measured,
            "rollout_threads": os.cpu_count(), "opensim_dataset_median_wall_s": float(np.median(ds.wall_time[ds.ok])),
            "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
            "load_average": os.getloadavg()[0],
            "mujoco_version": mujoco.__version__, "opensim_version": ds.meta.get("opensim_version")}


def format_speed(speed: dict) -> str:
    """A plain-text table of :func:`measure_speed`'s result, ratios beside absolute times."""
    lines = [f"OpenSim {speed.get('opensim_version')}: {speed['opensim_median_s']:.2f} s per 1-s simulation "
             f"(integration only, median of {len(speed['opensim_s'])} sets; thread CPU time, loading included: "
             f"{speed.get('opensim_cpu_median_s', float('nan')):.2f} s); {speed['machine']}, "
             f"load average {speed.get('load_average', float('nan')):.1f}, MuJoCo {speed['mujoco_version']}",
             f"{'model':>12} {'nv':>4} {'eq':>4} {'1-s sim ms (p10-p90)':>22} {'cpu ms':>7} {'/conv':>6} "
             f"{'ratio':>6} {'cpu':>6} {'C loop ms (cpu)':>15} {'ratio':>6} "
             f"{'rollout/s 1 thr':>15} {'all':>6} {'/core':>6} {'scaling':>7} {'/cpu-s 1 thr':>12} {'all':>6}"]
    for name, m in speed["models"].items():
        per = m["rollout_per_s"]
        lines.append(f"{name:>12} {m['nv']:>4} {m['equalities']:>4} {m['median_s'] * 1e3:>8.1f} "
                     f"({m['p10_s'] * 1e3:5.1f}-{m['p90_s'] * 1e3:5.1f}) {m['cpu_median_s'] * 1e3:>7.1f} "
                     f"{m.get('cpu_vs_converted', float('nan')):>6.3f} "
                     f"{m['ratio']:>6.0f} {m.get('cpu_ratio', float('nan')):>6.0f} "
                     f"{m['c_loop_median_s'] * 1e3:>8.1f} ({m['c_loop_cpu_median_s'] * 1e3:>4.1f}) "
                     f"{m.get('c_loop_ratio', float('nan')):>6.0f} "
                     f"{per['1']:>15.1f} "
                     f"{per[max(per, key=int)]:>6.1f} "
                     f"{m['rollout_per_s_per_core']:>6.1f} {m['rollout_scaling']:>7.2f} "
                     f"{m['rollout_per_cpu_s']['1']:>12.1f} {m['rollout_per_cpu_s'][max(per, key=int)]:>6.1f}")
    lines.append("per step, microseconds (MuJoCo timers; kinematics includes the tendons):")
    for name, m in speed["models"].items():
        lines.append(f"{name:>12} " + "  ".join(f"{k} {v:.1f}" for k, v in m["step_us"].items()))
    return "\n".join(lines)
