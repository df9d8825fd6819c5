"""What limits how closely MuJoCo can follow OpenSim on MoBL-ARMS (the floor), measured.

``python -m o2m.paper.floor [--data data/mobl_arms] [--out out/paper]`` prints, on the test sets,
the mean absolute joint error (rad) of the converted model driven

- by OpenSim's recorded tendon forces (N) on its muscle tendons (:func:`o2m.mj.simulate.force_driven`):
  the skeleton, the paths' moment arms along MuJoCo's own trajectory and the passive forces;
- by the same forces mapped to joint forces at OpenSim's own states, ``J(q_OpenSim)ᵀ f`` (N·m,
  applied as ``qfrc_applied``): the moment arms are frozen along OpenSim's trajectory, so what
  is left is the skeleton, the constraints and the passive forces, not the paths;

- by the tendon forces mapped to joint forces at MuJoCo's own pose each step, with every
  equality-driven joint (carriers, conditional-point switches) placed exactly: the tendon-force
  run without those joints' lag;

and splits the elbow's error between the sets on which OpenSim extends the elbow to its limit and
the others.
"""

from __future__ import annotations

import argparse

import mujoco
import numpy as np

from o2m.mj.posing import joint_equality_plan, joint_qpos_address, pose_mujoco
from o2m.mj.simulate import controls_from_forces, force_driven, initial_state, rollout
from o2m.paper.pipeline import DATA_DIR, Experiment, load_experiment

__all__ = ["EXTENDED", "crossing", "exact_carrier_run", "generalized_force_run", "generalized_forces",
           "tendon_force_run"]

EXTENDED = 0.1
"""A set extends the elbow to its limit when OpenSim's elbow_flexion goes below this (rad)."""


def _forces(exp: Experiment, sets: list[int]) -> np.ndarray:
    """OpenSim's recorded tendon forces of ``sets`` in ``exp.muscles`` order, (B, T, M) N."""
    ds = exp.dataset
    cols = [ds.muscle_names.index(m) for m in exp.muscles]
    return ds.tendon_forces[sets][:, :, cols].astype(float)


def _state(model: mujoco.MjModel, exp: Experiment, i: int, k: int, plan) -> np.ndarray:
    ds = exp.dataset
    return initial_state(model, dict(zip(ds.coordinate_names, ds.coordinates[i, k], strict=True)),
                         speeds=dict(zip(ds.coordinate_names, ds.speeds[i, k], strict=True)), plan=plan)


def tendon_force_run(exp: Experiment, model: mujoco.MjModel, sets: list[int]) -> np.ndarray:
    """Joint trajectories (B, T, n_dofs) of the force-driven ``model`` under OpenSim's tendon forces."""
    plan = joint_equality_plan(model)
    init = np.stack([_state(model, exp, i, 0, plan) for i in sets])
    tr = rollout(model, init, controls_from_forces(model, exp.muscles, _forces(exp, sets)), joint_names=exp.dofs)
    return tr.coordinates


def generalized_forces(exp: Experiment, model: mujoco.MjModel, i: int,
                       muscles: list[str] | None = None) -> np.ndarray:
    """OpenSim's tendon forces of set ``i`` as joint forces at OpenSim's states, (T - 1, nv) N·m or N.

    ``model`` is :func:`force_driven`; step ``k``'s ``qfrc_actuator`` at OpenSim's state ``k`` with
    the step's controls (the mean force over the step, as the tendon-force run applies it) of
    ``muscles`` (default all): MuJoCo's moment arms, within 1.55 mm of OpenSim's.
    """
    plan = joint_equality_plan(model)
    forces = _forces(exp, [i])
    if muscles is not None:
        forces[..., [m not in muscles for m in exp.muscles]] = 0.0
    ctrl = controls_from_forces(model, exp.muscles, forces)[0]
    data = mujoco.MjData(model)
    out = np.empty((len(ctrl), model.nv))
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    for k in range(len(ctrl)):
        mujoco.mj_setState(model, data, _state(model, exp, i, k, plan), spec)
        data.ctrl[:] = ctrl[k]
        mujoco.mj_forward(model, data)
        out[k] = data.qfrc_actuator
    return out


def generalized_force_run(exp: Experiment, model: mujoco.MjModel, sets: list[int],
                          frozen: list[str] | None = None) -> np.ndarray:
    """Joint trajectories (B, T, n_dofs) of ``model`` (force-driven) under OpenSim's tendon forces,
    those of the ``frozen`` muscles (default all) as :func:`generalized_forces` at OpenSim's states,
    the others on their tendons. Were MuJoCo's trajectory OpenSim's, every step would apply the
    same joint forces as the tendon-force run."""
    frozen = list(exp.muscles) if frozen is None else frozen
    plan = joint_equality_plan(model)
    adr = [joint_qpos_address(model, d) for d in exp.dofs]
    data = mujoco.MjData(model)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    out = []
    for i in sets:
        g = generalized_forces(exp, model, i, frozen)
        live = _forces(exp, [i])
        live[..., [m in frozen for m in exp.muscles]] = 0.0
        ctrl = controls_from_forces(model, exp.muscles, live)[0]
        mujoco.mj_setState(model, data, _state(model, exp, i, 0, plan), spec)
        q = [data.qpos[adr].copy()]
        for k in range(len(g)):
            data.ctrl[:] = ctrl[k]
            data.qfrc_applied[:] = g[k]
            mujoco.mj_step(model, data)
            q.append(data.qpos[adr].copy())
        out.append(np.array(q))
    return np.array(out)


def crossing(exp: Experiment, model: mujoco.MjModel, dof: str, i: int = 0) -> list[str]:
    """The muscles whose length changes with ``dof`` (moment arm above 1 mm) at set ``i``'s initial pose."""
    plan = joint_equality_plan(model)
    data = mujoco.MjData(model)
    pose = {n: v for n, v in zip(exp.dataset.coordinate_names, exp.dataset.coordinates[i, 0], strict=True)
            if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) >= 0}
    lengths = []
    for dq in (-1e-4, 1e-4):
        pose_mujoco(model, data, {**pose, dof: pose[dof] + dq}, plan=plan)
        mujoco.mj_tendon(model, data)
        mujoco.mj_transmission(model, data)
        lengths.append(data.actuator_length.copy())
    arm = (lengths[1] - lengths[0]) / 2e-4
    return [m for m in exp.muscles if abs(arm[model.actuator(m).id]) > 1e-3]


def exact_carrier_run(exp: Experiment, model: mujoco.MjModel, sets: list[int]) -> np.ndarray:
    """Joint trajectories (B, T, n_dofs) of ``model`` (force-driven, controls at zero) under OpenSim's
    tendon forces mapped to joint forces at MuJoCo's own pose each step, with every equality-driven
    joint (carriers of moving path points, conditional-point switches) put exactly where its
    equality says: the tendon-force run without the lag of those joints."""
    plan = joint_equality_plan(model)
    names = [n for n in exp.dataset.coordinate_names if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) >= 0]
    adr = {n: joint_qpos_address(model, n) for n in names}
    data, posed = mujoco.MjData(model), mujoco.MjData(model)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    out = []
    for i in sets:
        f = _forces(exp, [i])
        ctrl = controls_from_forces(model, exp.muscles, f)[0]
        mujoco.mj_setState(model, data, _state(model, exp, i, 0, plan), spec)
        data.ctrl[:] = 0.0
        q = [data.qpos[[adr[d] for d in exp.dofs]].copy()]
        for k in range(len(ctrl)):
            pose_mujoco(model, posed, {n: float(data.qpos[a]) for n, a in adr.items()}, plan=plan)
            posed.ctrl[:] = ctrl[k]
            mujoco.mj_forward(model, posed)
            data.qfrc_applied[:] = posed.qfrc_actuator
            mujoco.mj_step(model, data)
            q.append(data.qpos[[adr[d] for d in exp.dofs]].copy())
        out.append(np.array(q))
    return np.array(out)


def _row(label: str, err: np.ndarray) -> str:
    per = np.mean(err, axis=tuple(range(err.ndim - 1)))
    return f"{label:52s}" + "".join(f"{e:9.4f}" for e in per) + f"{np.mean(per):9.4f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(DATA_DIR))
    ap.add_argument("--out", default="out/paper", help="folder of the converted model (converted if missing)")
    a = ap.parse_args()
    exp = load_experiment(a.data, a.out)
    sets = exp.dataset.test
    model = force_driven(exp.xml, exp.muscles)
    ref = exp.reference[sets]
    q_tendon = tendon_force_run(exp, model, sets)
    q_joint = generalized_force_run(exp, model, sets)
    q_exact = exact_carrier_run(exp, model, sets)
    elbow_muscles = crossing(exp, model, "elbow_flexion", sets[0])
    q_elbow_frozen = generalized_force_run(exp, model, sets, frozen=elbow_muscles)
    q_others_frozen = generalized_force_run(exp, model, sets, frozen=[m for m in exp.muscles if m not in elbow_muscles])
    print(f"MoBL-ARMS, {len(sets)} test sets, mean absolute joint error (rad)")
    print(f"{'':52s}" + "".join(f"{d[:8]:>9s}" for d in exp.dofs) + f"{'mean':>9s}")
    print(_row("OpenSim's tendon forces on the tendons", np.abs(q_tendon - ref)))
    print(_row("the same as joint forces at OpenSim's states", np.abs(q_joint - ref)))
    print(_row("  joint-force run vs tendon-force run", np.abs(q_joint - q_tendon)))
    print(_row("tendon forces at MuJoCo's pose, carriers exact", np.abs(q_exact - ref)))
    print(_row(f"the {len(elbow_muscles)} elbow muscles frozen, the rest on tendons", np.abs(q_elbow_frozen - ref)))
    print(_row("the other muscles frozen, elbow muscles on tendons", np.abs(q_others_frozen - ref)))
    print("elbow muscles:", " ".join(elbow_muscles))
    elbow = exp.dofs.index("elbow_flexion")
    extended = ref[:, :, elbow].min(axis=1) < EXTENDED
    for label, q in (("tendon forces", q_tendon), ("joint forces", q_joint), ("carriers exact", q_exact),
                     ("elbow muscles frozen", q_elbow_frozen), ("other muscles frozen", q_others_frozen)):
        e = np.mean(np.abs(q[:, :, elbow] - ref[:, :, elbow]), axis=1)
        print(f"elbow, {label}: {e[extended].mean():.4f} rad on the {int(extended.sum())} sets OpenSim extends to "
              f"< {EXTENDED} rad, {e[~extended].mean():.4f} on the other {int((~extended).sum())}")


if __name__ == "__main__":
    main()
