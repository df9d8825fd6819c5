"""What OpenSim's passive muscles do that MuJoCo's cannot: the Schutte fibre ratchet.

In the dataset's excitation sets about two thirds of the muscles are never excited. OpenSim's
Schutte1993 muscles then keep their fibres as long as they have ever been in the set
(:mod:`o2m.osim.fibres`): after the elbow extends to its limit and flexes back, the biceps'
tendon goes slack while a rigid-tendon MuJoCo muscle (and o2m's fitted passive spring) keeps
pulling. This module measures what that costs, with OpenSim's curves on MuJoCo's tendon lengths:

- :func:`fibre_forces_along`: the passive muscles' forces along OpenSim's recorded trajectory,
  against the recorded tendon forces (does the ratchet explain them?);
- :func:`fibre_run`: the fitted MuJoCo model with the passive muscles' forces taken over by the
  fibres, stepped beside it (what would a MuJoCo muscle with this memory give?).

``python -m o2m.paper.passive`` prints both on the test and fresh sets.
"""

from __future__ import annotations

import argparse
import copy
from pathlib import Path

import mujoco
import numpy as np
from tqdm.auto import tqdm

from o2m import models
from o2m.errors import O2MError
from o2m.mj.fibre_plugin import load as load_plugin
from o2m.mj.posing import joint_equality_plan
from o2m.osim.fibres import PassiveFibre, passive_fibres
from o2m.paper.floor import recorded_state
from o2m.paper.passive_stage import fibre_muscles, initial_fibre_lengths, passive_muscles
from o2m.paper.pipeline import (
    DATA_DIR,
    Experiment,
    joint_mae,
    load_experiment,
    load_fresh_experiment,
    write_forces_xml,
)

__all__ = ["figure", "fibre_forces_along", "fibre_run", "fitted_passive_force", "plugin_run"]


def _along(model: mujoco.MjModel, exp: Experiment, i: int):
    """``model``'s data at each of OpenSim's recorded states of set ``i`` in turn, forward-computed
    (one ``mjData``, overwritten)."""
    plan, data = joint_equality_plan(model), mujoco.MjData(model)
    for k in range(exp.dataset.coordinates.shape[1]):
        mujoco.mj_setState(model, data, recorded_state(model, exp, i, k, plan), mujoco.mjtState.mjSTATE_FULLPHYSICS)
        mujoco.mj_forward(model, data)
        yield data


def fibre_forces_along(exp: Experiment, model: mujoco.MjModel, fibres: dict[str, PassiveFibre], i: int,
                       start: dict[str, float], ratchet: bool = True) -> np.ndarray:
    """Tendon forces (T, len(fibres)) N of ``fibres`` along OpenSim's recorded poses of set ``i``
    (MuJoCo's tendon lengths there), from the fibre lengths ``start``; ``ratchet`` False: each
    at its static equilibrium instead (what a memoryless passive force gives)."""
    names = list(fibres)
    acts = [model.actuator(n).id for n in names]
    L = np.array([data.actuator_length[acts] for data in _along(model, exp, i)])
    out = np.zeros_like(L)
    for j, n in enumerate(names):
        lf = start[n]
        for t in range(len(L)):
            lf = fibres[n].ratchet(L[t, j], lf) if ratchet else fibres[n].equilibrium(L[t, j])
            out[t, j] = fibres[n].tendon_force(L[t, j], lf)
    return out


def fibre_run(exp: Experiment, model: mujoco.MjModel, fibres: dict[str, PassiveFibre], i: int,
              start: dict[str, float], ratchet: bool = True) -> np.ndarray:
    """Joint trajectory (T, n_dofs) rad of ``model`` on set ``i`` with the muscles of ``fibres`` (all
    passive in the set) pulling as those fibres, on MuJoCo's own tendon lengths, instead of as their
    actuators and tendon springs and dampers; stepped with ``mj_step`` (the fibre updated before
    each step, its force applied through the actuator's moment arms)."""
    m = copy.copy(model)
    acts = [model.actuator(n).id for n in fibres]
    for a in acts:  # the fitted passive spring and damping belong to the muscle being replaced
        t = m.actuator_trnid[a, 0]
        m.tendon_stiffness[t], m.tendon_stiffnesspoly[t], m.tendon_damping[t] = 0.0, 0.0, 0.0
    d = mujoco.MjData(m)
    mujoco.mj_setState(m, d, exp.init[i], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    qadr = [m.jnt_qposadr[m.joint(n).id] for n in exp.dofs]
    lf = {n: start[n] for n in fibres}
    moment = np.zeros((m.nu, m.nv))
    out = [d.qpos[qadr].copy()]
    for ctrl in exp.controls[i]:
        d.ctrl[:] = ctrl
        mujoco.mj_fwdPosition(m, d)
        mujoco.mju_sparse2dense(moment, d.actuator_moment, d.moment_rownnz, d.moment_rowadr, d.moment_colind)
        pull = np.zeros(len(acts))
        for j, (n, f) in enumerate(fibres.items()):
            L = d.actuator_length[acts[j]]
            lf[n] = f.ratchet(L, lf[n]) if ratchet else f.equilibrium(L)
            pull[j] = f.tendon_force(L, lf[n])
        d.qfrc_applied[:] = -pull @ moment[acts]
        mujoco.mj_step(m, d)
        out.append(d.qpos[qadr].copy())
    return np.array(out[: exp.reference.shape[1]])


def plugin_run(exp: Experiment, fitted_xml: str | Path, fibres: dict[str, PassiveFibre], i: int,
               start: dict[str, float]) -> np.ndarray:
    """:func:`fibre_run`'s trajectory (T, n_dofs) rad, with the fibres inside MuJoCo as ``o2m.fibre``
    plugins (:mod:`o2m.mj.fibre_plugin`, loaded by the caller) on ``fitted_xml``, stepped by
    ``mujoco.rollout``."""
    from mujoco import rollout

    from o2m.mj.fibre_plugin import fibre_state, with_fibres

    xml = with_fibres(fitted_xml, Path(fitted_xml).with_name(Path(fitted_xml).stem + "_fibres.xml"), fibres)
    m = mujoco.MjModel.from_xml_path(str(xml))
    init = fibre_state(m, exp.init[i], {n: start[n] for n in fibres})
    cols = [1 + m.jnt_qposadr[m.joint(n).id] for n in exp.dofs]  # after the time
    states, _ = rollout.rollout(m, mujoco.MjData(m), init[None], exp.controls[i][None])
    return np.vstack([init[cols], states[0][:, cols]])[: exp.reference.shape[1]]


def _replay_table(exp: Experiment, model: mujoco.MjModel, fibres: dict[str, PassiveFibre], sets: list[int],
                  start: dict[str, float], label: str) -> None:
    """Per muscle, RMS (N) of the fibre's force minus OpenSim's recorded one along the sets where it is passive."""
    ds, errors = exp.dataset, {}
    for i in tqdm(sets, desc=f"{label}, along OpenSim", unit="set"):
        own = {n: fibres[n] for n in passive_muscles(exp, i, list(fibres))}
        recorded = ds.tendon_forces[i][:, [ds.muscle_names.index(n) for n in own]].astype(float)
        for kind in ("ratchet", "memoryless"):
            forces = fibre_forces_along(exp, model, own, i, start, ratchet=kind == "ratchet")
            for j, n in enumerate(own):  # the first sample is OpenSim's state before its first step
                errors.setdefault(n, {}).setdefault(kind, []).append(forces[1:, j] - recorded[1:, j])
    print(f"{label}: passive muscles' force along OpenSim's trajectories minus the recorded one, RMS N "
          "(ratchet / memoryless), largest first:")
    rms = {n: {k: float(np.sqrt(np.mean(np.concatenate(v) ** 2))) for k, v in e.items()} for n, e in errors.items()}
    for n in sorted(rms, key=lambda n: -rms[n]["memoryless"])[:8]:
        print(f"  {n:10s} {rms[n]['ratchet']:7.2f} / {rms[n]['memoryless']:7.2f}")


def _table(exp: Experiment, model: mujoco.MjModel, fitted_xml: Path | None, sets: list[int], among: list[str],
           label: str) -> None:
    """The closed-loop table; with the plugin's row too unless ``fitted_xml`` is None."""
    start = initial_fibre_lengths(exp)
    fibres = passive_fibres(models.fetch(exp.dataset.meta["model"]), among)
    _replay_table(exp, model, fibres, sets, start, label)
    rows = ({"passive muscles as memoryless fibres": [], "passive muscles as ratchet fibres": []}
            | ({"the same, inside MuJoCo (o2m.fibre plugin)": []} if fitted_xml else {}))
    for i in tqdm(sets, desc=label, unit="set"):
        own = {n: fibres[n] for n in passive_muscles(exp, i, among)}
        for kind in rows:
            q = (plugin_run(exp, fitted_xml, own, i, start) if "plugin" in kind
                 else fibre_run(exp, model, own, i, start, ratchet="ratchet" in kind))
            rows[kind].append(np.mean(np.abs(q - exp.reference[i]), axis=0))
    base = joint_mae(exp, model, sets)[0]
    print(f"{label}: {len(sets)} sets, mean absolute joint error (rad): " + " ".join(exp.dofs) + " mean")
    for name, err in [("fitted model", base)] + [(k, np.array(v)) for k, v in rows.items()]:
        print(f"  {name:44s}" + "".join(f"{e:8.3f}" for e in err.mean(0)) + f"{err.mean():8.4f}"
              f"  (median set {np.median(err.mean(1)):.4f})")


def fitted_passive_force(exp: Experiment, model: mujoco.MjModel, i: int, muscle: str) -> np.ndarray:
    """The force (T,) N ``model``'s ``muscle`` pulls with, at zero activation, in OpenSim's recorded
    states of set ``i`` (its passive force: the fitted tendon spring and damping)."""
    from o2m.paper.force_fit import pulling_force

    a = model.actuator(muscle).id
    return np.array([pulling_force(model, muscle, data.actuator_length[a], data.actuator_velocity[a], 0.0)
                     for data in _along(model, exp, i)])

def figure(exp: Experiment, model: mujoco.MjModel, i: int, muscle: str, path: str | Path, where: str = "set") -> None:
    """``path``: ``muscle``'s force over set ``i`` (never excited there), OpenSim's recorded one
    against the ratchet fibre, the memoryless one and ``model``'s fitted muscle, with the elbow."""
    from o2m.paper.figures import passive_forces

    fibre = passive_fibres(models.fetch(exp.dataset.meta["model"]), [muscle])
    start = initial_fibre_lengths(exp)
    ds = exp.dataset
    forces = {"ratchet fibre (o2m.osim.fibres)": fibre_forces_along(exp, model, fibre, i, start)[:, 0],
              "memoryless fibre (static equilibrium)": fibre_forces_along(exp, model, fibre, i, start, False)[:, 0],
              "MuJoCo, fitted muscle at activation 0": fitted_passive_force(exp, model, i, muscle)}
    recorded = ds.tendon_forces[i][:, ds.muscle_names.index(muscle)].astype(float)
    elbow = ds.coordinates[i][:, ds.coordinate_names.index("elbow_flexion")]
    # the first sample is OpenSim's state before its first step (its force not yet the fibre's)
    fig = passive_forces(ds.times[1:], elbow[1:], recorded[1:], {k: v[1:] for k, v in forces.items()},
                         title=f"{muscle}, never excited, {where} {i}: OpenSim's fibre cannot shorten")
    fig.savefig(path, dpi=150, metadata={"Software": None})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(DATA_DIR))
    ap.add_argument("--out", default="out/paper", help="folder of the converted model (converted if missing)")
    ap.add_argument("--figure", help="only draw BIClong's force over fresh set 4 into this PNG")
    a = ap.parse_args()
    from o2m.paper.force_fit import ForceFit

    exp = load_experiment(a.data, a.out)
    forces = ForceFit.load(Path(a.data) / "results" / "muscle_forces.json")
    model = forces.apply(exp.model)
    if a.figure:
        fresh = load_fresh_experiment(Path(a.data), a.out)
        figure(fresh[0], model, 4, "BIClong", a.figure, where="fresh set")
        return
    among = fibre_muscles(exp, model)
    print("fibres for the passive ones among:", " ".join(among))
    fitted_xml = write_forces_xml(exp, forces)
    try:
        load_plugin(Path(a.out))
    except O2MError as err:  # no C compiler here: the tables without the plugin's row
        print(f"without the plugin: {err}")
        fitted_xml = None
    _table(exp, model, fitted_xml, list(exp.dataset.test), among, "test sets")
    fresh = load_fresh_experiment(Path(a.data), a.out)
    if fresh:
        _table(fresh[0], model, fitted_xml, fresh[1], among, "fresh sets")


if __name__ == "__main__":
    main()
