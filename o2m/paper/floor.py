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
- with every elbow-crossing moment arm 0.1 mm longer (:func:`arm_corrected_run`), live and frozen:
  how strongly each run amplifies a path difference;
- with the recorded forces answering MuJoCo's deviation as the converted muscles would
  (:func:`muscle_feedback_run`): the force-length-velocity feedback the replay lacks;

and splits the elbow's error between the sets on which OpenSim extends the elbow to its limit and
the others. ``--moment-arms`` (needs OpenSim) also compares both models' moment arms of every muscle
crossing the elbow or pro_sup at OpenSim's recorded states (:func:`arms_along`) and runs the
tendon-force run with OpenSim's moment arms, computed at MuJoCo's pose each step, for the muscles
whose arms differ.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.stats import spearmanr

from o2m import models
from o2m.mj.posing import joint_equality_plan, joint_qpos_address, pose_mujoco
from o2m.mj.simulate import controls_from_forces, force_driven, initial_state, rollout
from o2m.mj.tendons import mujoco_moment_arms
from o2m.osim.pair import ModelPair
from o2m.paper.passive_stage import crossing
from o2m.paper.pipeline import DATA_DIR, Experiment, load_experiment

__all__ = ["EXTENDED", "ArmFunction", "ArmsAlong", "Feedback", "arm_corrected_run", "arm_slopes", "arms_along",
           "exact_carrier_run", "generalized_force_run", "generalized_forces", "mujoco_arms",
           "muscle_feedback_run", "opensim_arms", "opensim_pair", "replay_instability", "tendon_force_run"]

EXTENDED = 0.1
"""A set extends the elbow to its limit when OpenSim's elbow_flexion goes below this (rad)."""


def _forces(exp: Experiment, sets: list[int]) -> np.ndarray:
    """OpenSim's recorded tendon forces of ``sets`` in ``exp.muscles`` order, (B, T, M) N."""
    ds = exp.dataset
    cols = [ds.muscle_names.index(m) for m in exp.muscles]
    return ds.tendon_forces[sets][:, :, cols].astype(float)


def recorded_state(model: mujoco.MjModel, exp: Experiment, i: int, k: int, plan) -> np.ndarray:
    """``model``'s full physics state at OpenSim's recorded state ``k`` of set ``i`` (coordinates
    and speeds; the equality-driven joints from ``plan``, :func:`o2m.mj.posing.joint_equality_plan`)."""
    ds = exp.dataset
    return initial_state(model, dict(zip(ds.coordinate_names, ds.coordinates[i, k], strict=True)),
                         speeds=dict(zip(ds.coordinate_names, ds.speeds[i, k], strict=True)), plan=plan)


def tendon_force_run(exp: Experiment, model: mujoco.MjModel, sets: list[int]) -> np.ndarray:
    """Joint trajectories (B, T, n_dofs) of the force-driven ``model`` under OpenSim's tendon forces."""
    plan = joint_equality_plan(model)
    init = np.stack([recorded_state(model, exp, i, 0, plan) for i in sets])
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
        mujoco.mj_setState(model, data, recorded_state(model, exp, i, k, plan), spec)
        data.ctrl[:] = ctrl[k]
        mujoco.mj_forward(model, data)
        out[k] = data.qfrc_actuator
    return out


Feedback = Callable[[mujoco.MjData, int], None]
"""Changes the live ``data``'s controls or applied forces before step k, from its state."""


def _applied_run(exp: Experiment, model: mujoco.MjModel, i: int, ctrl: np.ndarray, applied: np.ndarray,
                 feedback: Feedback | None = None) -> np.ndarray:
    """Joint trajectory (T, n_dofs) of ``model`` from OpenSim's state 0 of set ``i`` under controls
    ``ctrl`` (T - 1, nu) and joint forces ``applied`` (T - 1, nv) N·m or N, changed by ``feedback``."""
    adr = [joint_qpos_address(model, d) for d in exp.dofs]
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, recorded_state(model, exp, i, 0, joint_equality_plan(model)),
                       mujoco.mjtState.mjSTATE_FULLPHYSICS)
    q = [data.qpos[adr].copy()]
    for k in range(len(ctrl)):
        data.ctrl[:] = ctrl[k]
        data.qfrc_applied[:] = applied[k]
        if feedback is not None:
            feedback(data, k)
        mujoco.mj_step(model, data)
        q.append(data.qpos[adr].copy())
    return np.array(q)


def _split_controls(exp: Experiment, model: mujoco.MjModel, i: int, frozen: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Set ``i``'s controls of the live muscles (T - 1, nu) and joint forces of the ``frozen`` ones (T - 1, nv)."""
    live = _forces(exp, [i])
    live[..., [m in frozen for m in exp.muscles]] = 0.0
    ctrl = controls_from_forces(model, exp.muscles, live)[0]
    applied = generalized_forces(exp, model, i, frozen) if frozen else np.zeros((len(ctrl), model.nv))
    return ctrl, applied


def generalized_force_run(exp: Experiment, model: mujoco.MjModel, sets: list[int],
                          frozen: list[str] | None = None) -> np.ndarray:
    """Joint trajectories (B, T, n_dofs) of ``model`` (force-driven) under OpenSim's tendon forces,
    those of the ``frozen`` muscles (default all) as :func:`generalized_forces` at OpenSim's states,
    the others on their tendons. Were MuJoCo's trajectory OpenSim's, every step would apply the
    same joint forces as the tendon-force run."""
    frozen = list(exp.muscles) if frozen is None else frozen
    return np.array([_applied_run(exp, model, i, *_split_controls(exp, model, i, frozen)) for i in sets])


def arm_corrected_run(exp: Experiment, model: mujoco.MjModel, sets: list[int], muscles: list[str],
                      correction: ArmFunction, frozen: list[str] | None = None) -> np.ndarray:
    """:func:`generalized_force_run` (``frozen`` default none: the tendon-force run) with ``muscles``'
    moment arms about ``exp.dofs`` changed by ``correction`` (M, n_dofs) m at MuJoCo's live pose each
    step (e.g. OpenSim's minus MuJoCo's, or a constant): ``Σ F·correction`` (N·m) added to each dof.
    Joint trajectories (B, T, n_dofs)."""
    dofadr = [model.jnt_dofadr[model.joint(d).id] for d in exp.dofs]
    qadr = [joint_qpos_address(model, d) for d in exp.dofs]
    out = []
    for i in sets:
        ctrl, applied = _split_controls(exp, model, i, frozen or [])
        f = _forces(exp, [i])[0][:, [exp.muscles.index(m) for m in muscles]]
        step_force = 0.5 * (f[:-1] + f[1:])  # the step's mean force, as the controls apply it

        def feedback(data: mujoco.MjData, k: int, step_force=step_force) -> None:
            pose = {d: float(data.qpos[a]) for d, a in zip(exp.dofs, qadr, strict=True)}
            data.qfrc_applied[dofadr] += step_force[k] @ correction(pose)
        out.append(_applied_run(exp, model, i, ctrl, applied, feedback))
    return np.array(out)


def muscle_feedback_run(exp: Experiment, model: mujoco.MjModel, muscle_model: mujoco.MjModel,
                        sets: list[int]) -> np.ndarray:
    """The tendon-force run with each recorded force F (N) changed by how ``muscle_model``'s muscles
    (the converted ones, at OpenSim's recorded activations) answer MuJoCo's deviation from OpenSim:
    ``F + F_model(MuJoCo's live state) - F_model(OpenSim's state)``. OpenSim's own forces follow
    OpenSim's state this way (force-length-velocity); the recorded ones replayed do not.
    Joint trajectories (B, T, n_dofs)."""
    ds, plan = exp.dataset, joint_equality_plan(muscle_model)
    ids = np.array([muscle_model.actuator(m).id for m in exp.muscles])
    act_cols = [ds.muscle_names.index(m) for m in exp.muscles]
    live, recorded = mujoco.MjData(muscle_model), mujoco.MjData(muscle_model)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    out = []
    for i in sets:
        ctrl, applied = _split_controls(exp, model, i, [])

        def feedback(data: mujoco.MjData, k: int, i=i, ctrl=ctrl) -> None:
            act = ds.opensim_activations[i, k, act_cols].astype(float)
            mujoco.mj_setState(muscle_model, recorded, recorded_state(muscle_model, exp, i, k, plan), spec)
            live.qpos[:], live.qvel[:] = data.qpos, data.qvel
            for d in (live, recorded):
                d.act[muscle_model.actuator_actadr[ids]] = act
                mujoco.mj_forward(muscle_model, d)
            # controls are actuator forces (negative when pulling), as actuator_force
            data.ctrl[:] = ctrl[k]
            data.ctrl[ids] += live.actuator_force[ids] - recorded.actuator_force[ids]
        out.append(_applied_run(exp, model, i, ctrl, applied, feedback))
    return np.array(out)


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
        mujoco.mj_setState(model, data, recorded_state(model, exp, i, 0, plan), spec)
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


ArmFunction = Callable[[dict[str, float]], np.ndarray]
"""Moment arms (M, C) m of fixed muscles about fixed coordinates at a pose {coordinate: rad}."""


def mujoco_arms(model: mujoco.MjModel, muscles: list[str], dofs: list[str]) -> ArmFunction:
    """MuJoCo's moment arms ``-ten_J·dq/dq_c`` (equality-driven joints following their drivers, the
    sign of OpenSim's computeMomentArm) of ``muscles`` about ``dofs``, as an :data:`ArmFunction`."""
    plan, data = joint_equality_plan(model), mujoco.MjData(model)
    rows = [model.tendon(m).id for m in muscles]

    def arms(pose: dict[str, float]) -> np.ndarray:
        known = {n: v for n, v in pose.items() if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) >= 0}
        return mujoco_moment_arms(model, data, known, dofs, plan=plan, method="jacobian")[rows]
    return arms


def opensim_arms(pair: ModelPair, muscles: list[str], dofs: list[str]) -> ArmFunction:
    """OpenSim's ``computeMomentArm`` of ``muscles`` about ``dofs`` at the pose (the independent
    coordinates set, the coupled ones assembled), as an :data:`ArmFunction`."""
    forces, coords = [pair.force(m) for m in muscles], [pair.coord(c) for c in dofs]

    def arms(pose: dict[str, float]) -> np.ndarray:
        state = pair.os_state({c: pose[c] for c in pair.indep_names})
        return np.array([[f.computeMomentArm(state, c) for c in coords] for f in forces])
    return arms


def arm_slopes(arms: ArmFunction, pose: dict[str, float], dofs: list[str], h: float = 1e-3) -> np.ndarray:
    """Central differences of ``arms`` (M, C) about each of ``dofs`` at ``pose``: (M, C, len(dofs)) m/rad."""
    return np.stack([(arms({**pose, d: pose[d] + h}) - arms({**pose, d: pose[d] - h})) / (2 * h) for d in dofs],
                    axis=-1)


@dataclass
class ArmsAlong:
    """Both models' moment arms at OpenSim's recorded states: ``samples`` [(set, step)], ``poses``
    (S, n_dofs) rad at them, ``opensim`` and ``mujoco`` (S, M, C) m, ``forces`` (S, M) N OpenSim's
    tendon forces there, for ``muscles`` about ``dofs``."""

    muscles: list[str]
    dofs: list[str]
    samples: list[tuple[int, int]]
    poses: np.ndarray
    opensim: np.ndarray
    mujoco: np.ndarray
    forces: np.ndarray

    def rows(self) -> list[tuple[str, str, float, float, dict[str, float]]]:
        """(muscle, coordinate, RMS mm, max mm, the pose of the max {dof: rad}) of every pair either model
        moves by more than 1 mm, largest RMS first."""
        diff = (self.mujoco - self.opensim) * 1e3
        out = []
        for m, c in np.ndindex(diff.shape[1:]):
            if max(np.abs(self.opensim[:, m, c]).max(), np.abs(self.mujoco[:, m, c]).max()) > 1e-3:
                k = int(np.argmax(np.abs(diff[:, m, c])))
                out.append((self.muscles[m], self.dofs[c], float(np.sqrt(np.mean(diff[:, m, c] ** 2))),
                            float(np.abs(diff[k, m, c])), dict(zip(self.dofs, self.poses[k].round(3), strict=True))))
        return sorted(out, key=lambda r: -r[2])

    def torques(self) -> tuple[np.ndarray, np.ndarray]:
        """``Σ F·r`` over the muscles per coordinate (S, C) N·m, OpenSim's and MuJoCo's."""
        return np.einsum("sm,smc->sc", self.forces, self.opensim), np.einsum("sm,smc->sc", self.forces, self.mujoco)


def arms_along(exp: Experiment, muscles: list[str], sets: list[int], stride: int,
               opensim: ArmFunction, mujoco_: ArmFunction) -> ArmsAlong:
    """:class:`ArmsAlong` every ``stride``-th recorded step of ``sets`` (``opensim`` and ``mujoco_``
    give the moment arms of ``muscles`` about ``exp.dofs``)."""
    ds = exp.dataset
    cols = [ds.muscle_names.index(m) for m in muscles]
    samples = [(i, k) for i in sets for k in range(0, ds.coordinates.shape[1], stride)]
    poses = [dict(zip(ds.coordinate_names, ds.coordinates[i, k].astype(float), strict=True)) for i, k in samples]
    return ArmsAlong(muscles, list(exp.dofs), samples, np.array([[p[d] for d in exp.dofs] for p in poses]),
                     np.array([opensim(p) for p in poses]), np.array([mujoco_(p) for p in poses]),
                     np.array([ds.tendon_forces[i, k, cols] for i, k in samples], dtype=float))


def replay_instability(exp: Experiment, model: mujoco.MjModel, sets: list[int], stride: int,
                       dof: str = "elbow_flexion", h: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """How the replayed forces push ``dof`` further the way it moves, every ``stride``-th step of ``sets``.

    Returns the torque slope ``Σ F·∂r/∂q`` (S,) N·m/rad of OpenSim's recorded forces F with MuJoCo's
    moment arms r about ``dof`` (positive: a deviation grows, as nothing in fixed forces resists it)
    and the growth rate ``sqrt(slope / I)`` (S,) 1/s where the slope is positive (0 elsewhere), with
    ``1 / I`` the diagonal of the inverse mass matrix at ``dof`` (the other joints free)."""
    arms = mujoco_arms(model, list(exp.muscles), [dof])
    data, plan = mujoco.MjData(model), joint_equality_plan(model)
    unit = np.zeros(model.nv)
    unit[model.jnt_dofadr[model.joint(dof).id]] = 1.0
    ds = exp.dataset
    slopes, rates = [], []
    for i in sets:
        for k in range(0, ds.coordinates.shape[1], stride):
            pose = dict(zip(ds.coordinate_names, ds.coordinates[i, k].astype(float), strict=True))
            slope = float(_forces(exp, [i])[0, k] @ arm_slopes(arms, pose, [dof], h)[:, 0, 0])
            mujoco.mj_setState(model, data, recorded_state(model, exp, i, k, plan), mujoco.mjtState.mjSTATE_FULLPHYSICS)
            mujoco.mj_forward(model, data)
            inverse_mass = np.zeros(model.nv)
            mujoco.mj_solveM(model, data, inverse_mass[None], unit[None])
            slopes.append(slope)
            rates.append(np.sqrt(max(slope, 0.0) * float(inverse_mass @ unit)))
    return np.array(slopes), np.array(rates)


def opensim_pair(exp: Experiment) -> ModelPair:
    """The dataset's OpenSim model beside ``exp``'s conversion."""
    return ModelPair(models.fetch_model_with_geometry(exp.dataset.meta["model"], progress=False).osim, exp.xml)


def _row(label: str, err: np.ndarray) -> str:
    per = np.mean(err, axis=tuple(range(err.ndim - 1)))
    return f"{label:52s}" + "".join(f"{e:9.4f}" for e in per) + f"{np.mean(per):9.4f}"


def _elbow_split(exp: Experiment, ref: np.ndarray, runs: dict[str, np.ndarray]) -> None:
    """Each run's elbow error on the sets OpenSim extends to its limit, the others, its median over sets."""
    elbow = exp.dofs.index("elbow_flexion")
    extended = ref[:, :, elbow].min(axis=1) < EXTENDED
    for label, q in runs.items():
        e = np.mean(np.abs(q[:, :, elbow] - ref[:, :, elbow]), axis=1)
        worst = ", ".join(f"set {exp.dataset.test[j]} {e[j]:.3f}" for j in np.argsort(-e)[:3])
        print(f"elbow, {label}: {e[extended].mean():.4f} rad on the {int(extended.sum())} sets OpenSim extends to "
              f"< {EXTENDED} rad, {e[~extended].mean():.4f} on the other {int((~extended).sum())}; "
              f"median {np.median(e):.4f}; worst {worst}")


def _moment_arm_report(exp: Experiment, model: mujoco.MjModel, sets: list[int], ref: np.ndarray,
                       q_tendon: np.ndarray, stride: int = 5) -> None:
    """Both models' moment arms at OpenSim's states (every ``stride``-th step), and the tendon-force run
    with OpenSim's arms for the muscles whose arms differ by more than 0.1 mm."""
    pair = opensim_pair(exp)
    spans = pair.spanned()
    muscles = [m for m in exp.muscles if spans[m] & {"elbow_flexion", "pro_sup"}]
    along = arms_along(exp, muscles, sets, stride, opensim_arms(pair, muscles, exp.dofs),
                       mujoco_arms(model, muscles, exp.dofs))
    print(f"moment arms of the {len(muscles)} muscles crossing the elbow or pro_sup at {len(along.samples)} "
          "OpenSim states, MuJoCo - OpenSim (mm):")
    rows = along.rows()
    for muscle, dof, rms, worst, pose in rows:
        if worst > 1e-3:
            print(f"  {muscle:9s} {dof:14s} RMS {rms:.3f} max {worst:.3f} at " +
                  " ".join(f"{d}={v:.3f}" for d, v in pose.items()))
    print(f"  the other {sum(r[3] <= 1e-3 for r in rows)} (muscle, coordinate) pairs with an arm over 1 mm: "
          "within 0.001 mm")
    opensim, mujoco_ = along.torques()
    for c, dof in enumerate(exp.dofs):
        err = mujoco_[:, c] - opensim[:, c]
        print(f"  Σ F·r about {dof}: OpenSim's RMS {np.sqrt(np.mean(opensim[:, c] ** 2)):.3f} N·m, "
              f"MuJoCo - OpenSim RMS {np.sqrt(np.mean(err ** 2)):.4f}, max {np.abs(err).max():.4f}")
    differ = sorted({r[0] for r in rows if r[3] > 0.1})
    osa, mja = opensim_arms(pair, differ, exp.dofs), mujoco_arms(model, differ, exp.dofs)
    q = arm_corrected_run(exp, model, sets, differ, lambda pose: osa(pose) - mja(pose))
    print(_row(f"OpenSim's arms for {' '.join(differ)}", np.abs(q - ref)))
    print(_row("  vs the tendon-force run", np.abs(q - q_tendon)))


def _sensitivity(exp: Experiment, model: mujoco.MjModel, sets: list[int], elbow_muscles: list[str],
                 q_tendon: np.ndarray, q_joint: np.ndarray) -> dict[str, np.ndarray]:
    """Every elbow-crossing arm 0.1 mm longer, live and frozen; the muscle-feedback run."""
    longer = np.zeros((len(elbow_muscles), len(exp.dofs)))
    longer[:, exp.dofs.index("elbow_flexion")] = 1e-4
    q_live = arm_corrected_run(exp, model, sets, elbow_muscles, lambda pose: longer)
    q_frozen = arm_corrected_run(exp, model, sets, elbow_muscles, lambda pose: longer, frozen=list(exp.muscles))
    print(_row("elbow arms +0.1 mm, live: vs the tendon-force run", np.abs(q_live - q_tendon)))
    print(_row("elbow arms +0.1 mm, frozen: vs the joint-force run", np.abs(q_frozen - q_joint)))
    q_feedback = muscle_feedback_run(exp, model, exp.model, sets)
    print(_row("recorded forces + converted muscles' answer", np.abs(q_feedback - exp.reference[sets])))
    return {"muscle feedback": q_feedback}


def _instability_report(exp: Experiment, model: mujoco.MjModel, sets: list[int], ref: np.ndarray,
                        q_tendon: np.ndarray, stride: int = 10) -> None:
    """The elbow's :func:`replay_instability` along OpenSim's trajectories, and how each set's mean growth
    rate ranks with its tendon-force-run error (Spearman), over all sets and those OpenSim keeps off the limit."""
    slopes, rates = replay_instability(exp, model, sets, stride)
    elbow = exp.dofs.index("elbow_flexion")
    err = np.mean(np.abs(q_tendon[:, :, elbow] - ref[:, :, elbow]), axis=1)
    per_set = rates.reshape(len(sets), -1).mean(axis=1)
    flexed = ref[:, :, elbow].min(axis=1) >= EXTENDED
    print(f"elbow torque slope Σ F·∂r/∂q of the replayed forces: median {np.median(slopes):.2f} N·m/rad, positive "
          f"{100 * np.mean(slopes > 0):.0f} % of the time; growth rate median {np.median(rates):.1f} 1/s; "
          f"Spearman (set's mean rate, its elbow error) {spearmanr(per_set, err)[0]:.2f} over all "
          f"{len(sets)} sets, {spearmanr(per_set[flexed], err[flexed])[0]:.2f} over the {int(flexed.sum())} "
          f"OpenSim keeps above {EXTENDED} rad")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(DATA_DIR))
    ap.add_argument("--out", default="out/paper", help="folder of the converted model (converted if missing)")
    ap.add_argument("--moment-arms", action="store_true", help="compare the moment arms with OpenSim's (needs OpenSim)")
    a = ap.parse_args()
    exp = load_experiment(a.data, a.out)
    sets = exp.dataset.test
    model = force_driven(exp.xml, exp.muscles)
    ref = exp.reference[sets]
    elbow_muscles = crossing(exp, model, "elbow_flexion", sets[0])
    others = [m for m in exp.muscles if m not in elbow_muscles]
    runs = {"tendon forces": tendon_force_run(exp, model, sets),
            "joint forces": generalized_force_run(exp, model, sets),
            "carriers exact": exact_carrier_run(exp, model, sets),
            "elbow muscles frozen": generalized_force_run(exp, model, sets, frozen=elbow_muscles),
            "other muscles frozen": generalized_force_run(exp, model, sets, frozen=others)}
    print(f"MoBL-ARMS, {len(sets)} test sets, mean absolute joint error (rad)")
    print(f"{'':52s}" + "".join(f"{d[:8]:>9s}" for d in exp.dofs) + f"{'mean':>9s}")
    print(_row("OpenSim's tendon forces on the tendons", np.abs(runs["tendon forces"] - ref)))
    print(_row("the same as joint forces at OpenSim's states", np.abs(runs["joint forces"] - ref)))
    print(_row("  joint-force run vs tendon-force run", np.abs(runs["joint forces"] - runs["tendon forces"])))
    print(_row("tendon forces at MuJoCo's pose, carriers exact", np.abs(runs["carriers exact"] - ref)))
    print(_row(f"the {len(elbow_muscles)} elbow muscles frozen, the rest on tendons",
               np.abs(runs["elbow muscles frozen"] - ref)))
    print(_row("the other muscles frozen, elbow muscles on tendons", np.abs(runs["other muscles frozen"] - ref)))
    runs |= _sensitivity(exp, model, sets, elbow_muscles, runs["tendon forces"], runs["joint forces"])
    _instability_report(exp, model, sets, ref, runs["tendon forces"])
    if a.moment_arms:
        _moment_arm_report(exp, model, sets, ref, runs["tendon forces"])
    print("elbow muscles:", " ".join(elbow_muscles))
    _elbow_split(exp, ref, runs)


if __name__ == "__main__":
    main()
